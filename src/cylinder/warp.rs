//! Exact 1D warping of one slice seen from one camera angle: the sectors and their edges (the nine
//! configurations), the per-pixel inverse march, and direct warping of a scanline in both orders.

use std::f64::consts::PI;

use glam::Vec3;

use super::frame::{RaySectors, angular_pitch, depth, ray_sectors, screen_x, sector_index};
use super::texture::{Slice, Texel};

/// What a renderer found for one screen sample: the visible point of the slice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment {
    /// Fractional column `u ∈ [0, L)` the colour is read at.
    pub column: f64,
    /// Depth toward the camera (units of `R`, larger is nearer).
    pub depth: f64,
    /// Interpolated albedo.
    pub albedo: Vec3,
    /// Interpolated (not renormalised) normal.
    pub normal: Vec3,
}

/// An edge of a slice: columns `a` and `b = a + 1 (mod L)`, both defined, radii of one sign.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Edge {
    /// First column.
    pub a: usize,
    /// Second column, `a + 1` modulo `L`.
    pub b: usize,
    /// Whether the radii are negative (an inner edge, facing the axis).
    pub negative: bool,
}

/// Which edges warping may draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum RadiusModel {
    /// The source's simple case: negative radii are treated as undefined (only outer edges).
    Simple,
    /// The general case: outer and inner edges (the nine sector configurations).
    General,
}

/// A slice projected for the camera at angle `alpha`: screen abscissa and depth per defined
/// column. Cost to build: `O(L)` (one sine and cosine per column).
#[derive(Clone, Debug)]
pub struct SliceView<'a> {
    slice: &'a Slice,
    /// Camera angle (radians).
    pub alpha: f64,
    proj: Vec<Option<(f64, f64)>>,
    model: RadiusModel,
    /// Per sector, its front-facing edges with their projected intervals `[lo, hi]`.
    visible: Vec<[Option<VisibleEdge>; 2]>,
}

/// A front-facing edge and its projected interval.
#[derive(Clone, Copy, Debug, PartialEq)]
struct VisibleEdge {
    edge: Edge,
    lo: f64,
    hi: f64,
}

impl<'a> SliceView<'a> {
    /// Projects `slice` for the camera at `alpha` (radians).
    pub fn new(slice: &'a Slice, alpha: f64, model: RadiusModel) -> Self {
        let l = slice.columns();
        let da = angular_pitch(l);
        let proj = slice
            .texels
            .iter()
            .enumerate()
            .map(|(c, t)| {
                t.as_ref().and_then(|t| {
                    if model == RadiusModel::Simple && t.is_negative() {
                        return None;
                    }
                    let (r, beta) = (f64::from(t.radius), c as f64 * da);
                    Some((screen_x(r, beta, alpha), depth(r, beta, alpha)))
                })
            })
            .collect();
        let mut view = Self {
            slice,
            alpha,
            proj,
            model,
            visible: Vec::new(),
        };
        view.visible = (0..l)
            .map(|s| {
                view.sector_edges(s).map(|e| {
                    e.filter(|e| view.front_facing(e)).map(|edge| {
                        let (lo, hi) = view.interval(&edge);
                        VisibleEdge { edge, lo, hi }
                    })
                })
            })
            .collect();
        view
    }

    /// Columns `L`.
    #[inline]
    pub fn columns(&self) -> usize {
        self.proj.len()
    }

    /// Screen abscissa and depth of column `c` (units of `R`), if defined.
    #[inline]
    pub fn projection(&self, c: usize) -> Option<(f64, f64)> {
        self.proj[c % self.proj.len()]
    }

    #[inline]
    fn texel(&self, c: usize) -> &Texel {
        self.slice
            .get(c)
            .expect("projected columns are defined texels")
    }

    /// The edge from column `a` to `a + 1` if both are defined (under the radius model) with
    /// radii of one sign.
    #[inline]
    pub fn edge(&self, a: usize) -> Option<Edge> {
        let l = self.columns();
        let (a, b) = (a % l, (a + 1) % l);
        self.proj[a]?;
        self.proj[b]?;
        let (ta, tb) = (self.texel(a), self.texel(b));
        ta.same_side(tb).then_some(Edge {
            a,
            b,
            negative: ta.is_negative(),
        })
    }

    /// The edges of sector `s` (the wedge between the half-lines at `α_s` and `α_{s+1}`):
    /// `[outer, inner]`.
    ///
    /// Each bounding half-line holds 0, 1 (an outer sample: column `h` with `r > 0`) or 2 (also an
    /// inner sample: column `h + L/2` with `r < 0`, nearer the axis) samples: nine configurations
    /// per sector. The outer edge exists when both half-lines hold an outer sample, the inner
    /// edge when both hold an inner one; a sample whose neighbour is of the other kind starts no
    /// edge (radii of both signs are never joined). So `(0, ·)` and `(·, 0)` draw nothing, `(1, 1)`,
    /// `(1, 2)` and `(2, 1)` the outer edge, `(2, 2)` both.
    pub fn sector_edges(&self, s: usize) -> [Option<Edge>; 2] {
        let l = self.columns();
        let s = s % l;
        let outer = self.edge(s).filter(|e| !e.negative);
        let inner = if self.model == RadiusModel::General {
            self.edge(s + l / 2).filter(|e| e.negative)
        } else {
            None
        };
        [outer, inner]
    }

    /// Whether edge `e` faces the camera: `σ·(x_a − x_b) > 0` with `σ = −1` for inner edges (the
    /// outward normal of the counter-clockwise edge `e` is `σ·(e_z, −e_x)`, and its dot product
    /// with `d(α)` is `σ·(x_a − x_b)`).
    #[inline]
    pub fn front_facing(&self, e: &Edge) -> bool {
        let (xa, xb) = (self.x(e.a), self.x(e.b));
        if e.negative { xb > xa } else { xa > xb }
    }

    #[inline]
    fn x(&self, c: usize) -> f64 {
        self.proj[c].map_or(f64::NAN, |p| p.0)
    }

    /// Projected interval `[lo, hi]` of edge `e`.
    #[inline]
    pub fn interval(&self, e: &Edge) -> (f64, f64) {
        let (xa, xb) = (self.x(e.a), self.x(e.b));
        (xa.min(xb), xa.max(xb))
    }

    /// The point of edge `e` that projects to abscissa `x` (no coverage test): parameter
    /// `t = (x − x_a)/(x_b − x_a)`, exact for an orthographic view; attributes interpolated.
    pub fn point_on_edge(&self, e: &Edge, x: f64) -> Fragment {
        let (pa, pb) = (
            self.proj[e.a].unwrap_or_default(),
            self.proj[e.b].unwrap_or_default(),
        );
        let dx = pb.0 - pa.0;
        let t = if dx == 0.0 {
            0.0
        } else {
            ((x - pa.0) / dx).clamp(0.0, 1.0)
        };
        self.fragment(e, t)
    }

    /// The point at parameter `t ∈ [0, 1]` along edge `e`.
    pub fn fragment(&self, e: &Edge, t: f64) -> Fragment {
        let (pa, pb) = (
            self.proj[e.a].unwrap_or_default(),
            self.proj[e.b].unwrap_or_default(),
        );
        let texel = self.texel(e.a).lerp(self.texel(e.b), t as f32);
        Fragment {
            column: e.a as f64 + t,
            depth: pa.1 + t * (pb.1 - pa.1),
            albedo: texel.albedo,
            normal: texel.normal,
        }
    }

    /// The visible point of sector `s` at abscissa `x`: the nearer of its front-facing edges whose
    /// projection covers `x`.
    pub fn hit_in_sector(&self, s: usize, x: f64) -> Option<Fragment> {
        let [e0, e1] = &self.visible[s];
        let covers = |v: &&VisibleEdge| x >= v.lo && x <= v.hi;
        match (e0.as_ref().filter(covers), e1.as_ref().filter(covers)) {
            (None, None) => None,
            (Some(v), None) | (None, Some(v)) => Some(self.point_on_edge(&v.edge, x)),
            (Some(v0), Some(v1)) => {
                let (f0, f1) = (
                    self.point_on_edge(&v0.edge, x),
                    self.point_on_edge(&v1.edge, x),
                );
                Some(if f1.depth > f0.depth { f1 } else { f0 })
            }
        }
    }

    /// The interval `[lo, hi]` covered by the visible edges (the silhouette's extent), or
    /// `None` when no edge is visible.
    pub fn silhouette(&self) -> Option<(f64, f64)> {
        self.visible
            .iter()
            .flatten()
            .flatten()
            .fold(None, |acc: Option<(f64, f64)>, v| {
                Some(acc.map_or((v.lo, v.hi), |(lo, hi)| (lo.min(v.lo), hi.max(v.hi))))
            })
    }

    /// A Newton step of the march: for sector `s` crossed in direction `step` (see
    /// [`RaySectors`]), where abscissa `x` lies along its visible edge (the one whose interval is
    /// nearest `x`), counted in sectors from the sector's front half-line:
    /// `t = (x − x_front)/(x_back − x_front)`, `t ∈ [0, 1]` inside this sector, `t ≥ 1` behind
    /// it. `None` when the sector has no visible edge or the edge is parallel to the screen.
    pub fn sectors_to(&self, s: usize, x: f64, step: i64) -> Option<f64> {
        let dist = |v: &VisibleEdge| (v.lo - x).max(x - v.hi).max(0.0);
        let v = self.visible[s % self.columns()]
            .iter()
            .flatten()
            .min_by(|a, b| dist(a).total_cmp(&dist(b)))?;
        let (xa, xb) = (self.x(v.edge.a), self.x(v.edge.b));
        // Column `a` lies on half-line `s`, column `b` on `s + 1`: the front one is `b` when the
        // march goes down the sectors (right half), `a` otherwise.
        let (front, back) = if step < 0 { (xb, xa) } else { (xa, xb) };
        let slope = back - front;
        (slope != 0.0).then(|| (x - front) / slope)
    }

    /// Inverse warping of one screen sample at abscissa `x` (units of `R`): march the sectors the
    /// ray crosses front to back ([`ray_sectors`]), stop at the first with a visible edge
    /// covering `x`. Returns the fragment (if any) and the number of sectors examined (the cost).
    pub fn inverse(&self, x: f64) -> (Option<Fragment>, u32) {
        let rs = ray_sectors(x, self.alpha, self.columns());
        self.march(x, rs.first, rs.step, rs.count)
    }

    /// Marches at most `count` sectors from sector `first` in direction `step`; see
    /// [`Self::inverse`].
    pub fn march(&self, x: f64, first: i64, step: i64, count: usize) -> (Option<Fragment>, u32) {
        let l = self.columns();
        for n in 0..count {
            let s = sector_index(first + step * n as i64, l);
            if let Some(f) = self.hit_in_sector(s, x) {
                return (Some(f), n as u32 + 1);
            }
        }
        (None, count as u32)
    }

    /// The sectors of one half of the slice, back to front: the right half (`x ≥ 0`, polar angles
    /// `[α − π, α]`) when `right`, else the left half (`[α, α + π]`). The sectors straddling the
    /// dividing line belong to both halves (drawing clips them).
    pub fn half_sectors_back_to_front(&self, right: bool) -> RaySectors {
        let da = angular_pitch(self.columns());
        let front = (self.alpha / da).floor() as i64;
        let (back, step) = if right {
            (((self.alpha - PI) / da).floor() as i64, 1)
        } else {
            (((self.alpha + PI) / da).floor() as i64, -1)
        };
        RaySectors {
            first: back,
            step,
            count: ((front - back) * step) as usize + 1,
        }
    }

    /// Direct warping of the slice onto a scanline of sub-samples at abscissae `xs` (increasing,
    /// units of `R`): per half, the visible edges of each sector are drawn in sector order,
    /// interpolating attributes. `order` chooses painter's order (back to front, overwriting) or
    /// front to back with a per-sample coverage flag (a sample once covered is final, which also
    /// handles holes). Returns the number of sample writes (overdraw).
    pub fn direct(&self, xs: &[f64], out: &mut [Option<Fragment>], order: DrawOrder) -> u64 {
        let l = self.columns();
        let split = xs.partition_point(|&x| x < 0.0);
        let mut writes = 0;
        for right in [false, true] {
            let (range_lo, range_hi) = if right { (split, xs.len()) } else { (0, split) };
            let mut rs = self.half_sectors_back_to_front(right);
            if order == DrawOrder::FrontToBack {
                rs.first += rs.step * (rs.count as i64 - 1);
                rs.step = -rs.step;
            }
            for n in 0..rs.count {
                let s = sector_index(rs.first + rs.step * n as i64, l);
                let mut edges = self.visible[s];
                // Within a sector, farther edge first for painter's order, nearer first otherwise
                // (visible edges of one sector do not overlap, but ties are resolved safely).
                let mean_depth = |v: &Option<VisibleEdge>| {
                    v.map_or(f64::NEG_INFINITY, |v| {
                        let (pa, pb) = (self.proj[v.edge.a], self.proj[v.edge.b]);
                        pa.map_or(0.0, |p| p.1) + pb.map_or(0.0, |p| p.1)
                    })
                };
                let farther_first = mean_depth(&edges[0]) < mean_depth(&edges[1]);
                if farther_first != (order == DrawOrder::BackToFront) {
                    edges.swap(0, 1);
                }
                for v in edges.into_iter().flatten() {
                    let i0 = range_lo + xs[range_lo..range_hi].partition_point(|&x| x < v.lo);
                    let i1 = range_lo + xs[range_lo..range_hi].partition_point(|&x| x <= v.hi);
                    for (x, o) in xs[i0..i1].iter().zip(&mut out[i0..i1]) {
                        if order == DrawOrder::FrontToBack && o.is_some() {
                            continue;
                        }
                        *o = Some(self.point_on_edge(&v.edge, *x));
                        writes += 1;
                    }
                }
            }
        }
        writes
    }

    /// The point of the slice named by the fractional column `u` (as a fetched offset names it),
    /// with its screen abscissa: on the edge `(⌊u⌋, ⌊u⌋ + 1)` when it exists, else the nearer
    /// of the two samples when it is defined. `None` when neither is.
    pub fn point_at_column(&self, u: f64) -> Option<(f64, Fragment)> {
        let l = self.columns();
        let a = (u.floor() as i64).rem_euclid(l as i64) as usize;
        let t = u - u.floor();
        if let Some(e) = self.edge(a) {
            let x = self.x(e.a) + t * (self.x(e.b) - self.x(e.a));
            return Some((x, self.fragment(&e, t)));
        }
        let c = if t < 0.5 { a } else { (a + 1) % l };
        let (x, depth) = self.projection(c)?;
        let texel = self.texel(c);
        Some((
            x,
            Fragment {
                column: c as f64,
                depth,
                albedo: texel.albedo,
                normal: texel.normal,
            },
        ))
    }

    /// The sector that holds the sample of column `c`: `c` for a positive radius, `c + L/2` for a
    /// negative one (its point lies on the opposite half-line); `c` when undefined.
    pub fn sector_of_column(&self, c: usize) -> usize {
        let l = self.columns();
        match self.slice.get(c) {
            Some(t) if t.is_negative() && self.model == RadiusModel::General => (c + l / 2) % l,
            _ => c % l,
        }
    }
}

/// Drawing order of direct warping.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum DrawOrder {
    /// Painter's order: sectors from the back to the front, later edges overwrite.
    BackToFront,
    /// Sectors from the front to the back; a covered sample is never written again.
    FrontToBack,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn slice(radii: &[Option<f32>]) -> Slice {
        Slice {
            row: 0.0,
            texels: radii
                .iter()
                .map(|r| {
                    r.map(|radius| Texel {
                        albedo: Vec3::ONE,
                        normal: Vec3::X,
                        radius,
                    })
                })
                .collect(),
        }
    }

    /// The nine configurations of a sector: 0, 1 or 2 samples on each bounding half-line.
    #[test]
    fn nine_sector_configurations() {
        let l = 8;
        // Half-line h holds: 0 → nothing (column h undefined, column h+4 not negative),
        // 1 → outer sample only, 2 → outer and inner samples.
        let config = |h: usize, n: u8, radii: &mut Vec<Option<f32>>| match n {
            0 => {
                radii[h] = None;
                radii[h + 4] = Some(0.5);
            }
            1 => {
                radii[h] = Some(0.8);
                radii[h + 4] = Some(0.5);
            }
            _ => {
                radii[h] = Some(0.8);
                radii[h + 4] = Some(-0.3);
            }
        };
        for n0 in 0..3u8 {
            for n1 in 0..3u8 {
                let mut radii = vec![Some(0.5); l];
                config(0, n0, &mut radii);
                config(1, n1, &mut radii);
                let s = slice(&radii);
                let v = SliceView::new(&s, 0.3, RadiusModel::General);
                let [outer, inner] = v.sector_edges(0);
                assert_eq!(outer.is_some(), n0 >= 1 && n1 >= 1, "outer ({n0},{n1})");
                assert_eq!(inner.is_some(), n0 == 2 && n1 == 2, "inner ({n0},{n1})");
                if let Some(i) = inner {
                    assert_eq!((i.a, i.b, i.negative), (4, 5, true));
                }
                let simple = SliceView::new(&s, 0.3, RadiusModel::Simple);
                assert!(simple.sector_edges(0)[1].is_none());
            }
        }
    }

    #[test]
    fn circle_front_faces_the_camera() {
        let l = 64;
        let s = slice(&vec![Some(0.5); l]);
        let alpha = 0.37;
        let v = SliceView::new(&s, alpha, RadiusModel::General);
        for x in [-0.45, -0.2, 0.0, 0.1, 0.49] {
            let (f, steps) = v.inverse(x);
            let f = f.expect("inside the circle");
            // The visible point of a circle of radius 0.5 has depth √(0.25 − x²).
            let z = (0.25f64 - x * x).sqrt();
            assert!(
                (f.depth - z).abs() < 0.01,
                "x {x}: depth {} vs {z}",
                f.depth
            );
            // The march starts where the ray enters the bounding cylinder (β = α − asin x) and
            // stops at the circle (β = α − asin 2x).
            let sectors = ((2.0 * x).asin() - x.asin()).abs() / (TAU / l as f64);
            assert!(f64::from(steps) <= sectors + 2.0, "x {x}: {steps} steps");
            // Its column is at polar angle α − asin(x/0.5).
            let beta = f.column * TAU / l as f64;
            let want = (alpha - (x / 0.5).asin()).rem_euclid(TAU);
            assert!((beta - want).abs() < TAU / l as f64);
        }
        assert!(v.inverse(0.6).0.is_none());
        // Direct warping in both orders agrees with inverse warping.
        let xs: Vec<f64> = (0..50).map(|i| -1.0 + (i as f64 + 0.5) / 25.0).collect();
        for order in [DrawOrder::BackToFront, DrawOrder::FrontToBack] {
            let mut out = vec![None; xs.len()];
            v.direct(&xs, &mut out, order);
            for (x, o) in xs.iter().zip(&out) {
                let inv = v.inverse(*x).0;
                assert_eq!(o.is_some(), inv.is_some(), "{order:?} x {x}");
                if let (Some(a), Some(b)) = (o, inv) {
                    assert!((a.column - b.column).abs() < 1e-9);
                }
            }
        }
    }

    #[test]
    fn negative_radii_show_an_off_axis_object() {
        // A small disc off the axis at angle π: columns near 0 see it beyond the axis (r < 0),
        // columns near L/2 see it in front (r > 0).
        let l = 64;
        let (cx, rad) = (-0.6f64, 0.2f64);
        let radii: Vec<Option<f32>> = (0..l)
            .map(|c| {
                let a = c as f64 * TAU / l as f64;
                // Ray from R·d(a) toward the axis: p = t·d(a), first hit with the disc.
                let b = cx * a.cos();
                let disc = b * b - (cx * cx - rad * rad);
                (disc >= 0.0).then(|| (b + disc.sqrt()) as f32)
            })
            .collect();
        assert!(radii.iter().flatten().any(|r| *r < 0.0));
        let s = slice(&radii);
        // Seen from α = 0 (camera on +x) the disc is beyond the axis: only negative samples.
        let v = SliceView::new(&s, 0.0, RadiusModel::General);
        let (f, _) = v.inverse(0.05);
        let f = f.expect("the disc is visible");
        assert!((f.depth - (cx + (rad * rad - 0.05 * 0.05).sqrt())).abs() < 0.01);
        let simple = SliceView::new(&s, 0.0, RadiusModel::Simple);
        assert!(simple.inverse(0.05).0.is_none(), "the simple case loses it");
    }
}
