//! The radial rays of a cylindrical capture traced through a [`Mesh`] by binning its triangles
//! by height and angle: the tracer of [`crate::Shape::radial_tracer`] for meshes.
//!
//! ## Method
//!
//! A capture ray is horizontal and runs through the `y` axis at its row's height, along the
//! line of angle `α_c = 2πc/L` ([`RadialRays`]). A triangle can only meet the rays of the rows
//! its height range reaches and the columns whose line passes near its projection on the
//! horizontal plane. Each triangle goes to the rows within its height range (moved out by a
//! margin `m`, in bands of rows as [`crate::binned`] does), and per band to the columns of its
//! **angular footprint**: with `T'` its projection on the `x–z` plane and `ρ` the distance from
//! the axis to `T'`, every point `q` of `T'` within `m` of the line of angle `α` has
//! `|sin(φ_q − α)| ≤ m/ρ`, so `α` lies within `asin(m/ρ)` of the angles `[φ_lo, φ_hi]` that
//! `T'` spans seen from the axis, or of those plus `π` (a line through the axis meets both
//! sides). The columns of those two intervals (widened by `10⁻⁶` of a column for the rounding
//! of `α_c`) are the footprint; a triangle within `8m` of the axis reaches every column. On each
//! cell of its footprint the band runs the BVH walk's own `f32` triangle test (the watertight
//! test of `watertight`, one shear per column) against the cell's ray, and a depth buffer keeps the first strictly
//! nearer distance: triangles go in triangle order.
//!
//! ## Exactness
//!
//! As for parallel rays ([`crate::binned`]): the test accepts a ray within about `10⁻⁶·s` of a
//! triangle (`s` the largest coordinate of the mesh and of the rays' origins, `2R` and the row
//! heights), a point of the triangle at that distance from the ray projects to `T'` within that
//! distance of the ray's line and lies within it of the row's height, and the margin is
//! `m = 2·10⁻⁵·s`. So the result of a ray is exactly the nearest hit of that test over **all**
//! the triangles, the first in triangle order among equal distances. Against the BVH walk
//! ([`crate::Shape::intersect`]) the distance and the triangle are bitwise the same (the walk
//! keeps the first in triangle order among equal distances too). The tests count ties. Rows whose heights are not
//! strictly monotonic are not binned (the walk traces them).
//!
//! ## Cost
//!
//! Building the tracer finds each triangle's rows (one search per triangle) and sorts the
//! triangles into bands; a band computes each of its triangles' footprints (three `atan2` and
//! a distance) and tests the cells in them: the triangles of a row are few and narrow, so a
//! ray meets a handful of tests where a walk through the middle of the mesh tests boxes and
//! triangles along the whole chord.

use std::f64::consts::{PI, TAU};
use std::ops::Range;

use glam::DVec3;
use obvhs::triangle::Triangle;
use rayon::prelude::*;

use crate::binned::{Axis, BandTracer, Bands, inf};
use crate::geometry::{RadialRays, Ray};
use crate::mesh::Mesh;
use crate::watertight::Shear;

/// The binning tracer of a [`Mesh`] for one grid of radial rays.
pub(crate) struct RadialTracer<'a> {
    mesh: &'a Mesh,
    /// The mesh's triangles in the BVH's leaf order (the order of ray queries).
    triangles: &'a [Triangle],
    rays: &'a RadialRays<'a>,
    /// The outward direction of each column ([`RadialRays::outward`]).
    outward: Vec<DVec3>,
    /// The margin `m` (world units).
    margin: f64,
    /// Each triangle's rows (half-open; empty when it misses the grid's rows).
    row_spans: Vec<[u32; 2]>,
    /// The triangles of each band of rows.
    bands: Bands,
}

/// Up to four column ranges (two intervals of angles, each possibly wrapping around `L`).
type Columns = [Range<usize>; 4];

impl<'a> RadialTracer<'a> {
    /// `None` when the grid cannot be binned: no ray, row heights not strictly monotonic, a
    /// radius or scale that is not finite and positive. Cost: one row search per triangle.
    pub(crate) fn new(mesh: &'a Mesh, rays: &'a RadialRays<'a>) -> Option<Self> {
        let (w, h) = (rays.columns, rays.rows.len());
        let radius_ok = rays.radius.is_finite() && rays.radius > 0.0;
        if w == 0 || h == 0 || !radius_ok {
            return None;
        }
        let rows = Axis::new(rays.rows)?;
        let mesh_scale = inf(mesh.bounds.0).max(inf(mesh.bounds.1));
        let ray_scale = rays
            .rows
            .iter()
            .fold(2.0 * rays.radius, |m, y| m.max(y.abs()));
        let margin = 2e-5 * (mesh_scale + ray_scale);
        if !margin.is_finite() {
            return None;
        }
        let triangles = mesh.traced().triangles.as_slice();
        let row_spans: Vec<[u32; 2]> = triangles
            .par_iter()
            .map(|t| {
                let ys = [t.v0.y, t.v1.y, t.v2.y].map(f64::from);
                let r = rows.range(
                    ys[0].min(ys[1]).min(ys[2]) - margin,
                    ys[0].max(ys[1]).max(ys[2]) + margin,
                );
                [r.start as u32, r.end as u32]
            })
            .collect();
        let bands = Bands::new(&row_spans, h);
        Some(Self {
            mesh,
            triangles,
            rays,
            outward: (0..w).map(|c| rays.outward(c)).collect(),
            margin,
            row_spans,
            bands,
        })
    }

    /// The columns whose rays can meet `tri` (module docs): a superset of those within the
    /// margin of its projection.
    fn columns(&self, tri: &Triangle) -> Columns {
        let w = self.rays.columns;
        let all = [0..w, 0..0, 0..0, 0..0];
        let p = [tri.v0, tri.v1, tri.v2].map(|v| [f64::from(v.x), f64::from(v.z)]);
        let near = distance_to_origin(p);
        if near.is_nan() || near <= 8.0 * self.margin {
            return all;
        }
        // `T'` does not hold the axis, so it spans less than a half-turn seen from it: the
        // vertices' angles relative to the first one's bound it.
        let phi = p.map(|q| q[1].atan2(q[0]));
        let rel = |k: usize| {
            let d = phi[k] - phi[0];
            if d > PI {
                d - TAU
            } else if d <= -PI {
                d + TAU
            } else {
                d
            }
        };
        let (r1, r2) = (rel(1), rel(2));
        let widen = (self.margin / near).asin();
        let lo = phi[0] + r1.min(r2).min(0.0) - widen;
        let hi = phi[0] + r1.max(r2).max(0.0) + widen;
        let scale = w as f64 / TAU;
        let wi = w as i64;
        let mut out = [0..0, 0..0, 0..0, 0..0];
        for (k, shift) in [0.0, PI].into_iter().enumerate() {
            // The columns `c` with `2πc/L` in `[lo, hi]` (+ π), widened by far more than the
            // rounding of `2πc/L` and of the products (`10⁻⁶` of a column).
            let a = ((lo + shift) * scale - 1e-6).ceil() as i64;
            let b = ((hi + shift) * scale + 1e-6).floor() as i64;
            if b < a {
                continue;
            }
            if b - a + 1 >= wi {
                return all;
            }
            let (a, len) = (a.rem_euclid(wi) as usize, (b - a + 1) as usize);
            if a + len <= w {
                out[2 * k] = a..a + len;
            } else {
                out[2 * k] = a..w;
                out[2 * k + 1] = 0..a + len - w;
            }
        }
        out
    }
}

impl BandTracer for RadialTracer<'_> {
    fn mesh(&self) -> &Mesh {
        self.mesh
    }

    fn bands(&self) -> &Bands {
        &self.bands
    }

    fn size(&self) -> (usize, usize) {
        (self.rays.columns, self.rays.rows.len())
    }

    fn footprint(&self) -> Option<crate::geometry::Footprint> {
        self.rays.footprint()
    }

    fn trace_band<T>(
        &self,
        b: usize,
        rows: Range<usize>,
        out: &mut [T],
        emit: impl Fn(&Ray, Option<(usize, f32)>) -> T,
    ) {
        let w = self.rays.columns;
        let (r0, r1) = (rows.start, rows.end);
        let cells = (r1 - r0) * w;
        let t_max = self.rays.t_max();
        let mut band_rays = Vec::with_capacity(cells);
        let mut bvh_rays = Vec::with_capacity(cells);
        for r in r0..r1 {
            for d in &self.outward {
                let ray = self.rays.ray_along(*d, r);
                bvh_rays.push(Mesh::to_bvh_ray(&ray, 0.0, t_max));
                band_rays.push(ray);
            }
        }
        let Some(first) = bvh_rays.first() else {
            return;
        };
        // A depth buffer over the band's cells: each triangle, in triangle order, is tested on
        // the cells of its footprint and kept where strictly nearer (so the first in triangle
        // order wins among equal distances, as in the walk along one ray).
        let mut best_d = vec![first.tmax; cells];
        let mut best_t = vec![u32::MAX; cells];
        // Every row of a column has the same direction: one shear per column.
        let shears: Vec<Shear> = bvh_rays[..w]
            .iter()
            .map(|r| Shear::new(r.direction))
            .collect();
        let traced = self.mesh.traced();
        for &t in self.bands.of(b) {
            let span = self.row_spans[t as usize];
            let (s0, s1) = ((span[0] as usize).max(r0), (span[1] as usize).min(r1));
            if s0 >= s1 {
                continue;
            }
            let tri = &self.triangles[t as usize];
            let columns = self.columns(tri);
            for r in s0..s1 {
                let row = (r - r0) * w;
                for c in columns.iter().flat_map(Clone::clone) {
                    let k = row + c;
                    let d = shears[c].intersect_ray(tri, &bvh_rays[k]);
                    if d < best_d[k] && self.mesh.traced_stops(traced, t as usize, &bvh_rays[k], d)
                    {
                        best_d[k] = d;
                        best_t[k] = t;
                    }
                }
            }
        }
        for (k, o) in out.iter_mut().enumerate().take(cells) {
            *o = if best_t[k] == u32::MAX {
                emit(&band_rays[k], None)
            } else {
                emit(&band_rays[k], Some((best_t[k] as usize, best_d[k])))
            };
        }
    }
}

/// The distance from the origin to the triangle `p` of the plane (0 when it holds the origin,
/// or when the origin lies on the line of a triangle flattened to a segment).
fn distance_to_origin(p: [[f64; 2]; 3]) -> f64 {
    // The side of the origin of each edge `a → b`: the sign of (b − a) × (0 − a).
    let side = [0, 1, 2].map(|i| {
        let (a, b) = (p[i], p[(i + 1) % 3]);
        a[1] * (b[0] - a[0]) - a[0] * (b[1] - a[1])
    });
    if side.iter().all(|&s| s >= 0.0) || side.iter().all(|&s| s <= 0.0) {
        return 0.0;
    }
    [0, 1, 2]
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % 3]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let len2 = e[0] * e[0] + e[1] * e[1];
            // The point of the segment nearest the origin: a + u·e, u = clamp(−a·e / |e|²).
            let u = if len2 > 0.0 {
                (-(a[0] * e[0] + a[1] * e[1]) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (x, y) = (a[0] + u * e[0], a[1] + u * e[1]);
            (x * x + y * y).sqrt()
        })
        .into_iter()
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use glam::Vec3A;
    use obvhs::ray::Ray as BvhRay;

    use super::*;
    use crate::shape::Shape;
    use crate::test_meshes::{check_traced, masked_soup, mesh, soup, sphere, squash_flat};

    /// Checks the binned grid ray by ray ([`check_ray`]). Returns the number of ties: rays where
    /// the walk reports another triangle at the same distance.
    ///
    /// Rays along `x` or `z` (columns at multiples of `π/2`) lie in the faces of tight boxes
    /// where a mesh is symmetric about that plane; the walk's padded boxes keep their hits.
    fn check_grid(mesh: &Mesh, rays: &RadialRays) -> usize {
        let tracer = RadialTracer::new(mesh, rays).expect("the grid was not binned");
        check_traced(mesh, &tracer, |c, r| rays.ray(c, r), (0.0, rays.t_max()))
    }

    /// `h` row heights spread over `[y0, y1]`, from the top down as a capture lays them out.
    fn heights(h: usize, y0: f64, y1: f64) -> Vec<f64> {
        (0..h)
            .map(|j| y1 - (j as f64 + 0.5) * (y1 - y0) / h as f64)
            .collect()
    }

    /// Adversarial pieces for radial rays: a flat cut-out holding the axis (every ray meets it
    /// at the axis), a triangle straddling the axis, a sliver just off it, vertical walls seen
    /// edge-on from some columns, horizontal triangles, and a box whose faces are axis planes.
    fn awkward() -> Vec<[[f64; 3]; 3]> {
        let mut t = vec![
            [[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[-0.2, 0.1, -0.2], [0.3, 0.2, 0.1], [-0.1, 0.8, 0.3]],
            [[1e-6, 0.3, 1e-6], [0.4, 0.31, 2e-6], [0.4, 0.6, 3e-6]],
            [[0.3, 0.0, 0.3], [0.6, 0.0, 0.6], [0.45, 1.0, 0.45]],
            [[-0.7, 0.5, 0.1], [-0.2, 0.5, -0.6], [-0.4, 0.5, 0.5]],
        ];
        let v = |i: usize| {
            [
                -0.9 + 0.4 * (i & 1) as f64,
                0.2 + 0.5 * (i >> 1 & 1) as f64,
                0.1 + 0.3 * (i >> 2 & 1) as f64,
            ]
        };
        for q in [
            [0, 1, 3, 2],
            [4, 6, 7, 5],
            [0, 4, 5, 1],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 5, 7, 3],
        ] {
            t.push([v(q[0]), v(q[1]), v(q[2])]);
            t.push([v(q[0]), v(q[2]), v(q[3])]);
        }
        t
    }

    #[test]
    fn binned_radial_rays_find_the_hits_of_the_bvh_walk() {
        for (name, m) in [
            ("sphere", mesh(sphere(24, 0.0))),
            // The mesh is centred on its bounds: two spheres side by side sit off the axis.
            (
                "two spheres",
                mesh([sphere(12, 0.0), sphere(8, 2.5)].concat()),
            ),
            ("awkward", mesh(awkward())),
            ("soup", mesh(soup(7, 400))),
            ("alpha-masked soup", masked_soup(7, 400)),
        ] {
            let (lo, hi) = (m.bounds.0.y, m.bounds.1.y);
            let (mut ties, mut rays) = (0, 0);
            for (w, h) in [(64, 32), (37, 23), (2, 9), (256, 5)] {
                let ys = heights(h, lo - 0.1, hi + 0.1);
                let grid = RadialRays {
                    rows: &ys,
                    columns: w,
                    radius: 1.0,
                };
                (ties, rays) = (ties + check_grid(&m, &grid), rays + w * h);
            }
            eprintln!("{name}: {rays} rays, {ties} ties with the BVH walk");
            // Ties are exceptional: rays through a shared edge.
            assert!(ties * 100 <= rays, "{name}: {ties} ties in {rays} rays");
        }
    }

    /// Rows at the heights of horizontal triangles and vertices, and ascending rows: still
    /// exact.
    #[test]
    fn rows_through_vertices_and_ascending_rows_are_exact() {
        let m = mesh(awkward());
        let mut ys: Vec<f64> = m
            .traced()
            .triangles
            .iter()
            .flat_map(|t| [t.v0.y, t.v1.y, t.v2.y])
            .map(f64::from)
            .collect();
        ys.sort_by(f64::total_cmp);
        ys.dedup();
        let grid = RadialRays {
            rows: &ys,
            columns: 48,
            radius: 1.0,
        };
        check_grid(&m, &grid);
        let mut shuffled = ys.clone();
        shuffled.swap(0, 1);
        let bad = RadialRays {
            rows: &shuffled,
            ..grid
        };
        assert!(
            RadialTracer::new(&m, &bad).is_none(),
            "non-monotonic rows were binned"
        );
    }

    /// The shipped meshes (`../shared/data/meshes`), when present: every binned ray is exactly
    /// the nearest hit over all triangles.
    #[test]
    fn shipped_meshes_are_traced_exactly() {
        for m in crate::shared_meshes("the shipped meshes") {
            let ys = heights(11, m.bounds.0.y, m.bounds.1.y);
            let grid = RadialRays {
                rows: &ys,
                columns: 96,
                radius: 1.0,
            };
            let ties = check_grid(&m, &grid);
            eprintln!(
                "{}: {} rays, {ties} ties with the BVH walk",
                m.name(),
                grid.len()
            );
            assert!(ties * 100 <= grid.len(), "{}: {ties} ties", m.name());
        }
    }

    #[test]
    fn distance_to_origin_of_triangles() {
        let d = |p: [[f64; 2]; 3]| distance_to_origin(p);
        assert_eq!(d([[-1.0, -1.0], [1.0, -1.0], [0.0, 1.0]]), 0.0);
        assert_eq!(d([[1.0, -1.0], [-1.0, -1.0], [0.0, 1.0]]), 0.0);
        assert_eq!(d([[2.0, -1.0], [2.0, 1.0], [3.0, 0.0]]), 2.0);
        assert_eq!(d([[3.0, 4.0], [6.0, 8.0], [3.0, 8.0]]), 5.0);
        // A triangle flattened to a segment: off the origin's line, its distance; on it, 0.
        assert_eq!(d([[1.0, 1.0], [1.0, 2.0], [1.0, 3.0]]), 2f64.sqrt());
        assert_eq!(d([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]), 0.0);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
        /// The watertight test on slivers, degenerate and edge-on triangles and rays through
        /// vertices: a distance in the window or none, never NaN, and where Möller–Trumbore
        /// (`obvhs`'s test, an independent formula) also hits, the same distance to `f32`
        /// rounding of the object's size.
        #[test]
        fn watertight_test_agrees_with_moller_trumbore_where_both_hit(
            v in prop::array::uniform9(-2.0f32..2.0),
            o in prop::array::uniform3(-3.0f32..3.0),
            d in prop::array::uniform3(-1.0f32..1.0),
            kind in 0usize..4,
        ) {
            let mut v = v;
            match kind {
                // A sliver: two vertices nearly equal.
                1 => (v[3], v[4], v[5]) = (v[0] + 1e-6, v[1], v[2]),
                // Degenerate: the third vertex on the first edge.
                2 => (v[6], v[7], v[8]) = (0.5 * (v[0] + v[3]), 0.5 * (v[1] + v[4]), 0.5 * (v[2] + v[5])),
                // Flat in y, seen edge-on by a horizontal ray.
                3 => (v[1], v[4], v[7]) = (o[1], o[1], o[1]),
                _ => {}
            }
            let tri = Triangle {
                v0: Vec3A::new(v[0], v[1], v[2]),
                v1: Vec3A::new(v[3], v[4], v[5]),
                v2: Vec3A::new(v[6], v[7], v[8]),
            };
            let d = if kind == 3 { Vec3A::new(d[0], 0.0, d[2]) } else { Vec3A::from(d) };
            prop_assume!(d.length() > 1e-3);
            let check = |ray: &BvhRay| {
                let w = Shear::new(ray.direction).intersect_ray(&tri, ray);
                let m = tri.intersect(ray);
                assert!(!w.is_nan() && (w.is_infinite() || (0.0..=8.0).contains(&w)), "{w}");
                if w.is_finite() && m.is_finite() {
                    assert!((w - m).abs() <= 1e-4, "watertight {w}, Möller–Trumbore {m}");
                }
            };
            check(&BvhRay::new(Vec3A::from(o), d.normalize(), 0.0, 8.0));
            // Through a vertex.
            let to_vertex = tri.v1 - Vec3A::from(o);
            prop_assume!(to_vertex.length() > 1e-3);
            check(&BvhRay::new(Vec3A::from(o), to_vertex.normalize(), 0.0, 8.0));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
        /// Adversarial geometry: random soups with slivers, squashed flat at one height or
        /// onto a vertical plane through the axis, moved toward the axis, on grids of any size.
        #[test]
        fn binned_radial_rays_match_the_bvh_walk_on_random_soups(
            seed in any::<u64>(),
            n in 1usize..60,
            flat in 0.0f64..1.0,
            plane in 0.0f64..1.0,
            pull in 0.01f64..1.0,
            w in 1usize..40, h in 1usize..24,
        ) {
            let mut tris = soup(seed, n);
            let k = (flat * n as f64) as usize;
            squash_flat(&mut tris, k);
            for t in tris.iter_mut().skip(k).take((plane * n as f64) as usize) {
                for v in t.iter_mut() {
                    v[2] *= 1e-7;
                }
            }
            for t in &mut tris {
                for v in t.iter_mut() {
                    v[0] *= pull;
                    v[2] *= pull;
                }
            }
            let m = mesh(tris);
            let ys = heights(h, m.bounds.0.y - 0.05, m.bounds.1.y + 0.05);
            let grid = RadialRays { rows: &ys, columns: w, radius: 1.0 };
            check_grid(&m, &grid);
        }
    }
}
