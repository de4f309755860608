//! Per-texel bounds of the march valid for a whole cone of directions (module docs), and the
//! check that they hold.

use glam::DVec2;
use rayon::prelude::*;

use super::frames::Frame;
use super::warp::{FrameMap, display_frame, enclosing_maps, first_event, hidden};
use super::{SphereError, SphereImages};
use altrep_data_gen::OrthoFrame;

/// The bounds of one frame for its cone (module docs): per texel `Q`, for every ray through `Q`
/// (at `Z = 0`) with a direction of the cone, every event lies in `[zmin, zmax]`. Stored as
/// 8-bit codes `round_out((Z + 1)/2 · 255)` (`zmin` rounded down, `zmax` up). A texel where no
/// event is possible stores `zmin = 255`, `zmax = 0`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConeBounds {
    /// Texels per side.
    pub size: usize,
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
    /// Builds the bounds of `frame` for the cone of half-angle `beta` (radians, below 90°).
    /// Exact interval reasoning (module docs), quantised outward. Cost: per texel, the cells
    /// within `tan β` (frame units) — `O(F² · (F·tan β)²)`, texel rows in parallel.
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
        // Tiles of TILE² cells with their extreme values prune the gather exactly: a tile is
        // skipped when none of its cells can raise zmax or lower zmin further (out of reach,
        // or nothing to add at the `need` of its nearest cell); the same over sub-tiles of
        // SUB² cells inside a tile that passed.
        const TILE: i64 = 8;
        const SUB: i64 = 2;
        // Per block of `b²` cells, `(max hi, min lo_ext, max |Z|)` over its defined cells, and
        // the blocks per side.
        let blocks = |b: i64| {
            let n = (fi + b - 1) / b;
            let mut out = vec![(f64::NEG_INFINITY, f64::INFINITY, 0.0f64); (n * n) as usize];
            for j in 0..fi {
                for i in 0..fi {
                    let k = (j * fi + i) as usize;
                    if frame.defined[k] {
                        let t = &mut out[((j / b) * n + i / b) as usize];
                        t.0 = t.0.max(hi[k]);
                        t.1 = t.1.min(lo_ext[k]);
                        t.2 = t.2.max(hi[k].abs().max(lo_ext[k].abs()));
                    }
                }
            }
            (out, n)
        };
        let ((tiles, nt), (subs, ns)) = (blocks(TILE), blocks(SUB));
        let reach = (tan / pitch).ceil() as i64 + 1;
        // `need` of every cell gap within the frame, as the gather computes it.
        let span = f;
        let needs: Vec<f64> = (0..span * span)
            .map(|g| {
                let (gx, gy) = ((g % span) as f64, (g / span) as f64);
                pitch * (gx * gx + gy * gy).sqrt() / tan
            })
            .collect();
        // The tiles within reach, nearest first: near cells widen the interval most (their
        // `need` is smallest), so the far tiles that follow are mostly skipped as unable to
        // widen it further. The order changes which tiles are skipped, not the result.
        let rt = reach / TILE + 1;
        let mut offsets: Vec<(i64, i64)> = (-rt..=rt)
            .flat_map(|dj| (-rt..=rt).map(move |di| (dj, di)))
            .collect();
        offsets.sort_by_key(|&(dj, di)| (dj * dj + di * di, dj, di));
        let rows: Vec<(Vec<u8>, Vec<u8>)> = (0..fi)
            .into_par_iter()
            .map(|jq| {
                let mut zmin_row = vec![255u8; f];
                let mut zmax_row = vec![0u8; f];
                // Cell-gap distance (in texels) between Q and the span [a, b] along one axis.
                let gap = |q: i64, a: i64, b: i64| ((a - q).max(q - b) - 1).max(0) as f64;
                for iq in 0..fi {
                    let (mut zmin, mut zmax) = (f64::INFINITY, f64::NEG_INFINITY);
                    let (tj0, tj1) = ((jq - reach).max(0) / TILE, (jq + reach).min(fi - 1) / TILE);
                    let (ti0, ti1) = ((iq - reach).max(0) / TILE, (iq + reach).min(fi - 1) / TILE);
                    let (tq, tp) = (jq / TILE, iq / TILE);
                    // Whether a block of cells `[i0, i1] × [j0, j1]` with these extremes can
                    // widen the interval. The least `need` of its cells bounds what they can
                    // give: zmax at most `thi` where some cell may reach `need`, else at most
                    // `-need`; zmin likewise at least `tlo` or `need`.
                    let widens = |(thi, tlo, tabs): (f64, f64, f64),
                                  (i0, i1, j0, j1): (i64, i64, i64, i64),
                                  zmin: f64,
                                  zmax: f64| {
                        if thi < tlo {
                            return false; // no defined cell
                        }
                        let (gx, gy) = (gap(iq, i0, i1), gap(jq, j0, j1));
                        let need = pitch * (gx * gx + gy * gy).sqrt() / tan;
                        if tabs < need {
                            return false; // out of reach
                        }
                        let most = if thi >= need { thi } else { -need };
                        let least = if tlo <= -need { tlo } else { need };
                        most > zmax || least < zmin
                    };
                    for &(dj, di) in &offsets {
                        let (tj, ti) = (tq + dj, tp + di);
                        if tj < tj0 || tj > tj1 || ti < ti0 || ti > ti1 {
                            continue;
                        }
                        let (j0, i0) = (tj * TILE, ti * TILE);
                        let (j1, i1) = ((j0 + TILE - 1).min(fi - 1), (i0 + TILE - 1).min(fi - 1));
                        if !widens(tiles[(tj * nt + ti) as usize], (i0, i1, j0, j1), zmin, zmax) {
                            continue;
                        }
                        for sj in (j0..=j1).step_by(SUB as usize) {
                            for si in (i0..=i1).step_by(SUB as usize) {
                                let (sj1, si1) =
                                    ((sj + SUB - 1).min(fi - 1), (si + SUB - 1).min(fi - 1));
                                let sub = subs[((sj / SUB) * ns + si / SUB) as usize];
                                if !widens(sub, (si, si1, sj, sj1), zmin, zmax) {
                                    continue;
                                }
                                for j in sj..=sj1 {
                                    let gy = ((j - jq).abs() - 1).max(0) as usize;
                                    for i in si..=si1 {
                                        let k = (j * fi + i) as usize;
                                        // An undefined cell holds (+∞, −∞): it gives nothing.
                                        let (l, h) = (lo_ext[k], hi[k]);
                                        let gx = ((i - iq).abs() - 1).max(0) as usize;
                                        let need = needs[gy * span + gx];
                                        // Largest and smallest Z in [l, h] with |Z| ≥ need.
                                        if h >= need {
                                            zmax = zmax.max(h);
                                        } else if l <= -need {
                                            zmax = zmax.max(h.min(-need));
                                        }
                                        if l <= -need {
                                            zmin = zmin.min(l);
                                        } else if h >= need {
                                            zmin = zmin.min(l.max(need));
                                        }
                                    }
                                }
                            }
                        }
                    }
                    if zmin <= zmax {
                        zmin_row[iq as usize] = code_down(zmin);
                        zmax_row[iq as usize] = code_up(zmax);
                    }
                }
                (zmin_row, zmax_row)
            })
            .collect();
        let (mut zmin, mut zmax) = (Vec::with_capacity(f * f), Vec::with_capacity(f * f));
        for (a, b) in rows {
            zmin.extend(a);
            zmax.extend(b);
        }
        Self {
            size: f,
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
        let k = t.y as usize * self.size + t.x as usize;
        Some(
            (self.zmin[k] <= self.zmax[k])
                .then(|| (code_value(self.zmin[k]), code_value(self.zmax[k]))),
        )
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

    /// The gather over every cell within reach, without tiles: the definition the pruned
    /// build must reproduce code for code.
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

    #[test]
    fn the_pruned_build_equals_the_full_gather() {
        // Small frames, and frames of several tiles whose cones reach across tiles (the
        // pruning by each tile's least `need` and the nearest-first order at work).
        for (name, grid, size, frames) in [
            ("chair", 3, 24, &[0usize, 4, 7][..]),
            ("tree", 3, 64, &[0, 5][..]),
            ("truck", 2, 72, &[1][..]),
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
