//! Per-texel bounds of the march valid for a whole cone of directions (module docs), and the
//! check that they hold.

use glam::DVec2;
use rayon::prelude::*;

use super::frames::Frame;
use super::warp::{FrameMap, display_frame, enclosing_maps, first_event, hidden};
use super::{SphereError, SphereImages};
use altrep_data_gen::OrthoFrame;

/// The bounds of one frame for its cone (module docs): per bounds texel `Q` (a square of
/// `block × block` frame texels; `block = 1`, one per frame texel, as built), for every ray
/// through `Q` (at `Z = 0`) with a direction of the cone, every event lies in `[zmin, zmax]`.
/// Stored as 8-bit codes `round_out((Z + 1)/2 · 255)` (`zmin` rounded down, `zmax` up),
/// row-major over `side()²` bounds texels. A bounds texel where no event is possible stores
/// `zmin = 255`, `zmax = 0`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConeBounds {
    /// Texels per side of the frame they bound.
    pub size: usize,
    /// Frame texels per side of one bounds texel (1, 2, 4, …): coarser bounds take
    /// `1/block²` of the bytes and leave the march longer intervals, never another picture.
    pub block: usize,
    /// Lower bound codes.
    pub zmin: Vec<u8>,
    /// Upper bound codes.
    pub zmax: Vec<u8>,
}

fn code_down(z: f64) -> u8 {
    ((z.clamp(-1.0, 1.0) + 1.0) * 0.5 * 255.0).floor() as u8
}

fn code_up(z: f64) -> u8 {
    ((z.clamp(-1.0, 1.0) + 1.0) * 0.5 * 255.0).ceil() as u8
}

fn code_value(c: u8) -> f64 {
    f64::from(c) / 255.0 * 2.0 - 1.0
}

impl ConeBounds {
    /// The bounds of each of `frames` for its cone of half-angle `cones[k]` ([`Self::build`]).
    /// Frames in parallel as well as each frame's tiles: frames' costs differ (their cones and
    /// coverage), and one frame's tiles alone leave cores idle at its end.
    /// Bounds texels of `block × block` frame texels ([`Self::coarsened`]).
    pub(crate) fn build_all(frames: &[Frame], cones: &[f64], block: usize) -> Vec<Self> {
        frames
            .par_iter()
            .zip(cones)
            .map(|(fr, &beta)| {
                let b = Self::build(fr, beta);
                if block > 1 { b.coarsened(block) } else { b }
            })
            .collect()
    }

    /// Bounds texels per side, `⌈size / block⌉` (a `block` of 0 is taken as 1).
    pub fn side(&self) -> usize {
        self.size.div_ceil(self.block.max(1))
    }

    /// The codes `(zmin, zmax)` that bound frame texel `(i, j)` (`i, j < size`; codes of the
    /// length `side()²` the constructors and the loader give).
    #[inline]
    pub fn codes_at(&self, i: usize, j: usize) -> (u8, u8) {
        let b = self.block.max(1);
        let k = (j / b) * self.side() + i / b;
        (self.zmin[k], self.zmax[k])
    }

    /// The same bounds over bounds texels `factor` times wider: each holds the union of the
    /// intervals of the `factor × factor` texels it covers (clipped at the frame's edge). The
    /// union bounds every ray through any of them, so it stays conservative; it is the interval
    /// the build's walk would give over that span (quantisation outward is monotone). Cost:
    /// one pass over the codes. A `factor` of 0 is taken as 1.
    pub fn coarsened(&self, factor: usize) -> Self {
        let b = self.block.max(1);
        let block = b * factor.max(1);
        let (old, side) = (self.side(), self.size.div_ceil(block));
        let (mut zmin, mut zmax) = (vec![255u8; side * side], vec![0u8; side * side]);
        for j in 0..old {
            for i in 0..old {
                // Old bounds texel (i, j) starts at frame texel (b·i, b·j).
                let (k, n) = (j * old + i, (j * b / block) * side + i * b / block);
                zmin[n] = zmin[n].min(self.zmin[k]);
                zmax[n] = zmax[n].max(self.zmax[k]);
            }
        }
        Self {
            size: self.size,
            block,
            zmin,
            zmax,
        }
    }

    /// Builds the bounds of `frame` for the cone of half-angle `beta` (radians, below 90°).
    /// Exact interval reasoning (module docs), quantised outward. Cost: per texel, at worst
    /// the cells within `tan β` (frame units), `O(F² · (F·tan β)²)`; the pruned walk visits a
    /// few tiles per texel (docs/design.md §7b, "Cone bounds"). Tiles of texels in parallel.
    pub fn build(frame: &Frame, beta: f64) -> Self {
        let f = frame.size;
        let fi = f as i64;
        let tan = beta.min(1.5).tan();
        let pitch = frame.pitch();
        // Per cell: the plane's range over the cell, and the extended low end.
        let half = 0.5 * pitch;
        let mut lo = vec![f64::INFINITY; f * f];
        let mut hi = vec![f64::NEG_INFINITY; f * f];
        for k in 0..f * f {
            if frame.defined[k] {
                let r = (frame.slope[k].x.abs() + frame.slope[k].y.abs()) * half;
                lo[k] = frame.depth[k] - r;
                hi[k] = frame.depth[k] + r;
            }
        }
        let mut lo_ext = lo.clone();
        for j in 0..fi {
            for i in 0..fi {
                let k = (j * fi + i) as usize;
                if !frame.defined[k] {
                    continue;
                }
                for (di, dj) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                    match frame.cell(i + di, j + dj) {
                        Some(n) => lo_ext[k] = lo_ext[k].min(lo[n]),
                        None => lo_ext[k] = -1.0,
                    }
                }
            }
        }
        // Every march runs inside the bounding sphere's chord, `|Z| ≤ 1`: a cell's plane
        // beyond it holds no event. Clipped there, a cell whose `need` exceeds 1 gives nothing,
        // so the window of reach below leaves out no event.
        for k in (0..f * f).filter(|&k| frame.defined[k]) {
            hi[k] = hi[k].min(1.0);
            lo_ext[k] = lo_ext[k].max(-1.0);
        }
        // zmax gathers the largest event over one side; zmin is the same gather over the
        // mirrored side (`Z → −Z` swaps `hi` and `lo_ext`), negated. Negation is exact, so
        // both are found by one walk.
        let geometry = Geometry::new(fi, pitch, tan);
        let upper = Side::new(&geometry, hi.clone(), lo_ext.clone());
        let lower = Side::new(
            &geometry,
            lo_ext.iter().map(|&l| -l).collect(),
            hi.iter().map(|&h| -h).collect(),
        );
        let nt = geometry.tiles;
        let blocks: Vec<Vec<(u8, u8)>> = (0..nt * nt)
            .into_par_iter()
            .map(|b| {
                let (tq, tp) = (b / nt, b % nt);
                let candidates = geometry.candidates(&upper, tq, tp);
                let up = upper.by_highest(&geometry, &candidates);
                let down = lower.by_highest(&geometry, &candidates);
                let ((qi0, qi1), (qj0, qj1)) = (geometry.span(tp, TILE), geometry.span(tq, TILE));
                // What every texel of the tile has: each texel's walk starts from it and
                // stops sooner.
                let (upper0, lower0) = (
                    upper.highest(&geometry, &up, (qi0, qi1), (qj0, qj1), f64::NEG_INFINITY),
                    lower.highest(&geometry, &down, (qi0, qi1), (qj0, qj1), f64::NEG_INFINITY),
                );
                let mut out = Vec::with_capacity((TILE * TILE) as usize);
                for jq in qj0..=qj1 {
                    for iq in qi0..=qi1 {
                        let zmax = upper.highest(&geometry, &up, (iq, iq), (jq, jq), upper0);
                        let zmin = -lower.highest(&geometry, &down, (iq, iq), (jq, jq), lower0);
                        out.push(if zmin <= zmax {
                            (code_down(zmin), code_up(zmax))
                        } else {
                            (255, 0)
                        });
                    }
                }
                out
            })
            .collect();
        let (mut zmin, mut zmax) = (vec![255u8; f * f], vec![0u8; f * f]);
        for (b, codes) in blocks.iter().enumerate() {
            let (tq, tp) = (b as i64 / nt, b as i64 % nt);
            let (qj0, qi0) = (tq * TILE, tp * TILE);
            let w = (TILE.min(fi - qi0)) as usize;
            for (n, &(lo_code, hi_code)) in codes.iter().enumerate() {
                let k = (qj0 as usize + n / w) * f + qi0 as usize + n % w;
                zmin[k] = lo_code;
                zmax[k] = hi_code;
            }
        }
        Self {
            size: f,
            block: 1,
            zmin,
            zmax,
        }
    }

    /// The interval for a ray crossing `Z = 0` at frame position `q`: `None` when `q` lies
    /// outside the frame (no bound: march the chord), `Some(None)` when no event is possible,
    /// else `Some(Some((zmin, zmax)))`.
    pub fn interval(&self, frame: &Frame, q: DVec2) -> Option<Option<(f64, f64)>> {
        let t = frame.texel_coords(q);
        let f = self.size as f64;
        if !(0.0..f).contains(&t.x) || !(0.0..f).contains(&t.y) {
            return None;
        }
        let (lo, hi) = self.codes_at(t.x as usize, t.y as usize);
        Some((lo <= hi).then(|| (code_value(lo), code_value(hi))))
    }

    /// Mean stored interval length `zmax − zmin` over the texels where an event is possible
    /// (frame depth units), and the share of texels where none is.
    pub fn stats(&self) -> (f64, f64) {
        let (mut sum, mut n) = (0.0, 0usize);
        for (&a, &b) in self.zmin.iter().zip(&self.zmax) {
            if a <= b {
                sum += code_value(b) - code_value(a);
                n += 1;
            }
        }
        (
            sum / n.max(1) as f64,
            1.0 - n as f64 / self.zmin.len().max(1) as f64,
        )
    }
}

/// Tiles of `TILE²` cells with their extreme values prune the gather exactly: a tile is
/// skipped when none of its cells can widen the interval further (out of reach, or nothing to
/// add at the `need` of its nearest cell); the same over sub-tiles of `SUB²` cells inside a
/// tile that passed.
const TILE: i64 = 8;
const SUB: i64 = 2;

/// A frame's sizes, cone and the `need` table the gather shares between its two sides.
struct Geometry {
    /// Texels per side.
    fi: i64,
    /// Texel pitch (frame units).
    pitch: f64,
    /// `tan β` of the cone.
    tan: f64,
    /// The window of reach around a texel, in texels: `⌈tan β / pitch⌉ + 1` (a cell farther
    /// needs `|Z| > 1`, where the clipped planes hold no event); tiles are visited when they
    /// meet it.
    reach: i64,
    /// Tiles and sub-tiles per side.
    tiles: i64,
    subs: i64,
    /// `need` of every cell gap `(gx, gy)` within the frame, at `gy · fi + gx`.
    needs: Vec<f64>,
}

impl Geometry {
    fn new(fi: i64, pitch: f64, tan: f64) -> Self {
        let f = fi as usize;
        Self {
            fi,
            pitch,
            tan,
            reach: (tan / pitch).ceil() as i64 + 1,
            tiles: (fi + TILE - 1) / TILE,
            subs: (fi + SUB - 1) / SUB,
            needs: (0..f * f)
                .map(|g| {
                    let (gx, gy) = ((g % f) as f64, (g / f) as f64);
                    pitch * (gx * gx + gy * gy).sqrt() / tan
                })
                .collect(),
        }
    }

    /// The cells `[a, a + side − 1]` (clipped to the frame) of block `t` along one axis.
    fn span(&self, t: i64, side: i64) -> (i64, i64) {
        (t * side, (t * side + side - 1).min(self.fi - 1))
    }

    /// The tiles of cells that may widen the interval of some texel of texel tile `(tq, tp)`:
    /// those with a defined cell, meeting some texel's window, and whose largest `|Z|` reaches
    /// the tile's nearest texel. Both sides share the list (`|Z|` is the same).
    fn candidates(&self, side: &Side, tq: i64, tp: i64) -> Vec<(i64, i64)> {
        let ((qi0, qi1), (qj0, qj1)) = (self.span(tp, TILE), self.span(tq, TILE));
        let window = |q0: i64, q1: i64| {
            (
                (q0 - self.reach).max(0) / TILE,
                (q1 + self.reach).min(self.fi - 1) / TILE,
            )
        };
        let ((ti0, ti1), (tj0, tj1)) = (window(qi0, qi1), window(qj0, qj1));
        let mut list = Vec::new();
        for tj in tj0..=tj1 {
            for ti in ti0..=ti1 {
                let (thi, tlo, tabs) = side.tiles[(tj * self.tiles + ti) as usize];
                if thi < tlo {
                    continue; // no defined cell
                }
                let ((i0, i1), (j0, j1)) = (self.span(ti, TILE), self.span(tj, TILE));
                let gx = ((i0 - qi1).max(qi0 - i1) - 1).max(0) as f64;
                let gy = ((j0 - qj1).max(qj0 - j1) - 1).max(0) as f64;
                if tabs >= self.pitch * (gx * gx + gy * gy).sqrt() / self.tan {
                    list.push((tj, ti));
                }
            }
        }
        list
    }
}

/// One side of the gather: per cell the range `[lo, hi]` of `Z` an event may take (`hi` the
/// plane's top over the cell, `lo` the extended low end; undefined cells hold `(+∞, −∞)`),
/// and per tile and sub-tile `(max hi, min lo, max |Z|)`. The upper side finds zmax; the
/// lower side is the mirror image (`hi = −lo_ext`, `lo = −hi`) and finds `−zmin`.
struct Side {
    hi: Vec<f64>,
    lo: Vec<f64>,
    tiles: Vec<(f64, f64, f64)>,
    subs: Vec<(f64, f64, f64)>,
    /// Per tile, its sub-tiles with a defined cell (top-left cell `(j, i)`), highest `hi`
    /// first: within a tile the walk stops at the first that cannot raise the maximum.
    sub_order: Vec<Vec<(i64, i64)>>,
}

impl Side {
    fn new(g: &Geometry, hi: Vec<f64>, lo: Vec<f64>) -> Self {
        let fi = g.fi;
        // Per block of `b²` cells, `(max hi, min lo, max |Z|)` over its defined cells.
        let blocks = |b: i64, n: i64| {
            let mut out = vec![(f64::NEG_INFINITY, f64::INFINITY, 0.0f64); (n * n) as usize];
            for j in 0..fi {
                for i in 0..fi {
                    let k = (j * fi + i) as usize;
                    if hi[k] >= lo[k] {
                        let t = &mut out[((j / b) * n + i / b) as usize];
                        t.0 = t.0.max(hi[k]);
                        t.1 = t.1.min(lo[k]);
                        t.2 = t.2.max(hi[k].abs().max(lo[k].abs()));
                    }
                }
            }
            out
        };
        let (tiles, subs) = (blocks(TILE, g.tiles), blocks(SUB, g.subs));
        let sub_order = (0..g.tiles * g.tiles)
            .map(|t| {
                let ((i0, i1), (j0, j1)) = (g.span(t % g.tiles, TILE), g.span(t / g.tiles, TILE));
                let sub = |(sj, si): (i64, i64)| subs[((sj / SUB) * g.subs + si / SUB) as usize];
                let mut order: Vec<(i64, i64)> = (j0..=j1)
                    .step_by(SUB as usize)
                    .flat_map(|sj| (i0..=i1).step_by(SUB as usize).map(move |si| (sj, si)))
                    .filter(|&s| sub(s).0 >= sub(s).1)
                    .collect();
                order.sort_by(|&x, &y| sub(y).0.total_cmp(&sub(x).0));
                order
            })
            .collect();
        Self {
            hi,
            lo,
            tiles,
            subs,
            sub_order,
        }
    }

    /// `list` ordered by the tiles' highest `hi`, highest first.
    fn by_highest(&self, g: &Geometry, list: &[(i64, i64)]) -> Vec<(i64, i64)> {
        let top = |(tj, ti): (i64, i64)| self.tiles[(tj * g.tiles + ti) as usize].0;
        let mut out = list.to_vec();
        out.sort_by(|&x, &y| top(y).total_cmp(&top(x)));
        out
    }

    /// The largest event `Z` over this side's cells for the texels `[qi0, qi1] × [qj0, qj1]`
    /// that every one of them has, at least `start`: per cell the largest `Z` in `[lo, hi]`
    /// with `|Z| ≥ need`, `need` taken at the farthest texel (for one texel, exactly its
    /// gather; `−∞` where no cell has one). Only tiles within every texel's window count.
    /// `order` is the candidate tiles by [`Side::by_highest`]: every value a tile can give is
    /// at most its highest `hi`, so the walk stops at the first tile whose `hi` does not
    /// exceed the maximum found so far. A block can give at most its highest `hi` where some
    /// cell may reach `need`, else at most `−need`.
    fn highest(
        &self,
        g: &Geometry,
        order: &[(i64, i64)],
        (qi0, qi1): (i64, i64),
        (qj0, qj1): (i64, i64),
        start: f64,
    ) -> f64 {
        let fi = g.fi;
        let window = |q0: i64, q1: i64| {
            (
                (q1 - g.reach).max(0) / TILE,
                (q0 + g.reach).min(fi - 1) / TILE,
            )
        };
        let ((ti0, ti1), (tj0, tj1)) = (window(qi0, qi1), window(qj0, qj1));
        // Least `need` of a block's cells from the nearest texel; what a block of extremes
        // `(top, abs)` can give, if it can reach at all.
        let block_need = |(i0, i1): (i64, i64), (j0, j1): (i64, i64)| {
            let gap = |q0: i64, q1: i64, a: i64, b: i64| ((a - q1).max(q0 - b) - 1).max(0) as f64;
            let (gx, gy) = (gap(qi0, qi1, i0, i1), gap(qj0, qj1, j0, j1));
            g.pitch * (gx * gx + gy * gy).sqrt() / g.tan
        };
        let most = |top: f64, abs: f64, need: f64| {
            (abs >= need).then_some(if top >= need { top } else { -need })
        };
        let mut zmax = start;
        for &(tj, ti) in order {
            let (thi, _, tabs) = self.tiles[(tj * g.tiles + ti) as usize];
            if thi <= zmax {
                break;
            }
            if tj < tj0 || tj > tj1 || ti < ti0 || ti > ti1 {
                continue; // outside a window of reach
            }
            let need = block_need(g.span(ti, TILE), g.span(tj, TILE));
            if most(thi, tabs, need).is_none_or(|m| m <= zmax) {
                continue;
            }
            for &(sj, si) in &self.sub_order[(tj * g.tiles + ti) as usize] {
                let (shi, _, sabs) = self.subs[((sj / SUB) * g.subs + si / SUB) as usize];
                if shi <= zmax {
                    break;
                }
                let (sj1, si1) = ((sj + SUB - 1).min(fi - 1), (si + SUB - 1).min(fi - 1));
                if most(shi, sabs, block_need((si, si1), (sj, sj1))).is_none_or(|m| m <= zmax) {
                    continue;
                }
                for j in sj..=sj1 {
                    let gy = ((j - qj0).abs().max((j - qj1).abs()) - 1).max(0);
                    for i in si..=si1 {
                        let k = (j * fi + i) as usize;
                        // An undefined cell holds (+∞, −∞): it gives nothing.
                        let (l, h) = (self.lo[k], self.hi[k]);
                        let gx = ((i - qi0).abs().max((i - qi1).abs()) - 1).max(0);
                        let need = g.needs[(gy * fi + gx) as usize];
                        if h >= need {
                            zmax = zmax.max(h);
                        } else if l <= -need {
                            zmax = zmax.max(h.min(-need));
                        }
                    }
                }
            }
        }
        zmax
    }
}

/// What [`check_bounds`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct BoundsCheck {
    /// Directions swept.
    pub directions: usize,
    /// Frame marches checked (rays × enclosing frames, rays crossing `Z = 0` inside the frame).
    pub marches: usize,
    /// Marches whose first event (found by marching the whole chord) lies outside the stored
    /// interval, or that have an event where the bounds say none is possible.
    pub violations: usize,
    /// Largest distance of a violating event outside its interval (frame depth units).
    pub worst_excess: f64,
}

/// Checks the bounds of `images` along `directions`: for every ray of a `size × size` grid and
/// every enclosing frame, the first event of the unbounded march must lie in the stored interval.
/// Cost: one unbounded march per ray and frame.
pub fn check_bounds(
    images: &SphereImages,
    directions: &[glam::DVec3],
    size: usize,
) -> Result<BoundsCheck, SphereError> {
    let mut total = BoundsCheck {
        directions: directions.len(),
        ..Default::default()
    };
    for &d in directions {
        let display = display_frame(images, d)?;
        let maps: Vec<(usize, f64, FrameMap)> = enclosing_maps(images, &display)?;
        let parts: Vec<(usize, usize, f64)> = (0..size)
            .into_par_iter()
            .map(|j| {
                let (mut marches, mut bad, mut worst) = (0, 0, 0.0f64);
                for i in 0..size {
                    let (x, y) = OrthoFrame::screen_at(i as f64 + 0.5, j as f64 + 0.5, size, size);
                    let r2 = x * x + y * y;
                    if r2 >= 1.0 {
                        continue;
                    }
                    let zs = (1.0 - r2).sqrt();
                    for &(k, _, ref map) in &maps {
                        let frame = &images.frames[k];
                        let line = map.line(x, y);
                        let Some(iv) = images.bounds[k].interval(frame, line.q) else {
                            continue;
                        };
                        let entry = line.a + line.c * zs;
                        if hidden(frame, line.q + entry * line.t, entry) {
                            // Hidden from the sphere's entry on: not a transition, and the
                            // render checks it before using the bounds.
                            continue;
                        }
                        marches += 1;
                        let mut steps = 0;
                        let ev = first_event(
                            frame,
                            line.q,
                            line.t,
                            entry,
                            line.a - line.c * zs,
                            &mut steps,
                            u32::MAX,
                        );
                        match (ev, iv) {
                            (None, _) => {}
                            (Some(_), None) => {
                                bad += 1;
                                worst = worst.max(2.0);
                            }
                            (Some(z), Some((lo, hi))) => {
                                let excess = (lo - z).max(z - hi);
                                if excess > 1e-9 {
                                    bad += 1;
                                    worst = worst.max(excess);
                                }
                            }
                        }
                    }
                }
                (marches, bad, worst)
            })
            .collect();
        for (m, b, w) in parts {
            total.marches += m;
            total.violations += b;
            total.worst_excess = total.worst_excess.max(w);
        }
    }
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::{SphereImages, SphereParams};
    use altrep_data_gen::scene_shape;

    /// The gather over every cell, without tiles or window: the definition the pruned build
    /// must reproduce code for code.
    fn brute(frame: &Frame, beta: f64) -> (Vec<u8>, Vec<u8>) {
        let f = frame.size as i64;
        let tan = beta.min(1.5).tan();
        let pitch = frame.pitch();
        let range = |k: usize| {
            let r = (frame.slope[k].x.abs() + frame.slope[k].y.abs()) * 0.5 * pitch;
            (frame.depth[k] - r, frame.depth[k] + r)
        };
        let (mut zmin_c, mut zmax_c) = (vec![255u8; (f * f) as usize], vec![0u8; (f * f) as usize]);
        for jq in 0..f {
            for iq in 0..f {
                let (mut zmin, mut zmax) = (f64::INFINITY, f64::NEG_INFINITY);
                for j in 0..f {
                    for i in 0..f {
                        let Some(k) = frame.cell(i, j) else { continue };
                        let (mut l, h) = range(k);
                        for (di, dj) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                            match frame.cell(i + di, j + dj) {
                                Some(n) => l = l.min(range(n).0),
                                None => l = -1.0,
                            }
                        }
                        // Inside the box `|Z| ≤ 1`, where every march runs.
                        let (l, h) = (l.max(-1.0), h.min(1.0));
                        let gx = ((i - iq).abs() - 1).max(0) as f64;
                        let gy = ((j - jq).abs() - 1).max(0) as f64;
                        let need = pitch * (gx * gx + gy * gy).sqrt() / tan;
                        for z in [h, h.min(-need), l, l.max(need)] {
                            if z >= l && z <= h && z.abs() >= need {
                                zmax = zmax.max(z);
                                zmin = zmin.min(z);
                            }
                        }
                    }
                }
                if zmin <= zmax {
                    zmin_c[(jq * f + iq) as usize] = code_down(zmin);
                    zmax_c[(jq * f + iq) as usize] = code_up(zmax);
                }
            }
        }
        (zmin_c, zmax_c)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 300, rng_seed: proptest::test_runner::RngSeed::Fixed(20261207), ..proptest::prelude::ProptestConfig::default() })]
        /// The walks reproduce the full gather code for code on random frames: sizes that are
        /// and are not multiples of the tiles, holes, depths drawn from few values (ties
        /// between tiles and sub-tiles, values at ±1 and 0), slopes up to the model's limit,
        /// cones from narrow to the 1.5 rad clamp.
        #[test]
        fn the_walks_equal_the_full_gather_on_random_frames(
            f in 2usize..27,
            hole_share in 0.0f64..0.9,
            levels in proptest::prop_oneof![proptest::strategy::Just(0usize), 2usize..6],
            beta in 0.02f64..1.6,
            cells in proptest::collection::vec((0.0f64..1.0, -1.0f64..1.0, -4.0f64..4.0, -4.0f64..4.0), 26 * 26),
        ) {
            let mut frame = Frame::empty_for_tests(f);
            for (k, &(u, z, sx, sy)) in cells.iter().enumerate().take(f * f) {
                frame.defined[k] = u >= hole_share;
                // With `levels`, depths snap to a few values (ties everywhere).
                frame.depth[k] = if levels == 0 {
                    z
                } else {
                    let n = levels as f64 - 1.0;
                    ((z + 1.0) * 0.5 * n).round() / n * 2.0 - 1.0
                };
                frame.slope[k] = DVec2::new(sx, sy);
            }
            let built = ConeBounds::build(&frame, beta);
            let (zmin, zmax) = brute(&frame, beta);
            proptest::prop_assert_eq!(&built.zmin, &zmin);
            proptest::prop_assert_eq!(&built.zmax, &zmax);
        }
    }

    /// A coarser bounds texel holds the union of the intervals of the texels it covers, a
    /// partial block at the frame's edge included, and coarsening twice by 2 is coarsening
    /// once by 4.
    #[test]
    fn coarser_bounds_are_the_union_of_the_texels_they_cover() {
        let shape = scene_shape("truck").unwrap();
        let img = SphereImages::capture(&shape, &SphereParams::hemisphere(3, 19).unwrap()).unwrap();
        for fine in &img.bounds {
            for block in [2, 4] {
                let coarse = fine.coarsened(block);
                assert_eq!(
                    (coarse.block, coarse.side()),
                    (block, 19usize.div_ceil(block))
                );
                for bj in 0..coarse.side() {
                    for bi in 0..coarse.side() {
                        let (mut lo, mut hi) = (255u8, 0u8);
                        for j in bj * block..((bj + 1) * block).min(19) {
                            for i in bi * block..((bi + 1) * block).min(19) {
                                let (l, h) = fine.codes_at(i, j);
                                (lo, hi) = (lo.min(l), hi.max(h));
                                assert_eq!(
                                    coarse.codes_at(i, j),
                                    coarse.codes_at(bi * block, bj * block)
                                );
                            }
                        }
                        assert_eq!(coarse.codes_at(bi * block, bj * block), (lo, hi));
                    }
                }
            }
            assert_eq!(fine.coarsened(2).coarsened(2), fine.coarsened(4));
        }
    }

    #[test]
    fn the_pruned_build_equals_the_full_gather() {
        // Small frames, and frames of several tiles whose cones reach across tiles (the
        // walks by highest value, their stops and the tiles' starting values at work).
        for (name, grid, size, frames) in [
            ("chair", 3, 24, &[0usize, 4, 7][..]),
            ("tree", 3, 64, &[0, 5][..]),
            ("truck", 2, 72, &[1][..]),
            // A size that is not a multiple of the tiles: clipped tiles of texels and cells.
            ("pear", 3, 37, &[0, 2][..]),
        ] {
            let shape = scene_shape(name).unwrap();
            let img = SphereImages::capture(&shape, &SphereParams::hemisphere(grid, size).unwrap())
                .unwrap();
            for &k in frames {
                let (zmin, zmax) = brute(&img.frames[k], img.cones[k]);
                assert_eq!(img.bounds[k].zmin, zmin, "{name}, frame {k}");
                assert_eq!(img.bounds[k].zmax, zmax, "{name}, frame {k}");
            }
        }
    }
}
