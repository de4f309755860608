//! Conservative march bounds: the exact inverse warp at a few sector tests (beyond the source:
//! the fit is a start, not an answer; docs/design.md §6.5).
//!
//! Exact inverse warping marches, per pixel, the sectors a screen ray crosses front to back
//! (march positions `n = 0, 1, …` from the sector holding `β_front = α − asin x`) and stops at
//! the first sector `n*` holding a front-facing edge that covers the pixel: 50–72 tests per
//! sub-sample on the evaluation shapes. [`MarchBounds`] stores, per cell of `Bx` abscissae ×
//! row groups × `Bα` angles, the smallest and largest **sector number** that any edge able to
//! be a first hit in that cell can have. A pixel turns them into march positions with its own
//! ray (`n = first − s` on the right half, `s − first` on the left), so that for **every**
//! pixel of the cell the first hit lies at `start ≤ n* ≤ stop`. The march then runs from
//! `start` and gives up after `stop`: it tests the same sectors in the same order as the exact
//! march from `start` on, so its result is the exact one, fragment for fragment, at
//! `n* − start + 1` tests (a miss costs at most `stop − start + 1`, an empty cell 0).
//!
//! ## Why the range is conservative (derived, not sampled)
//!
//! Write `θ = α − β` (right half, `x ≥ 0`) or `θ = β − α` (left half) for a point of polar angle
//! `β` on the ray at abscissa `x`: `θ ∈ [asin|x|, π − asin|x|]`. Sector numbers are unwrapped in
//! the frame of the reduced angle `α ∈ [0, 2π)`: the sector of a point is `⌊β/dα⌋` with
//! `β = α ∓ θ`, and the ray's sectors run from `first = ⌊(α − asin x)/dα⌋` one by one, so the
//! first hit, in sector `s*`, sits at `n* = first − s*` (right) or `s* − first` (left). The
//! first hit lies on an edge of the slice that covers `x` and faces the camera. For each sector
//! edge the build bounds, over the whole cell:
//! * which rows hold it: a slice between two rows interpolates the radii of an edge present in
//!   both, and the two quantities below are linear in the radii for a fixed angle, so their
//!   extremes over the cell's rows are reached at the rows themselves;
//! * whether it can face the camera: `σ·(x_a − x_b)` is a sinusoid in `α`, its maximum over the
//!   cell's angles is exact;
//! * where it can project: `x` is linear along the edge between `ρ·sin(α − β)` of its endpoints
//!   (interval sine);
//! * which unwrapped sector numbers it takes: its points have `θ ∈ [α₀ − β_{s+1}, α₁ − β_s]`
//!   (right half), and the turn that brings this interval into `[asin|x|, π − asin|x|]` fixes
//!   the number;
//!
//! and the cell keeps the least and greatest number over its candidate edges. Occlusion is
//! ignored, which keeps the range conservative; its price is a later `stop` for misses and an
//! earlier `start` where the surface moves across the cell. The tests check the range against
//! the exact march on a sweep four times finer than the cells, the rendered fragments against
//! exact inverse warping on three shapes, and the march on random textures (proptest).
//!
//! ## Cost
//!
//! Build: `O(rows · Bα · L)` edge tests plus the cells each edge reaches (0.1–0.6 s on two
//! shared cores at the defaults). Storage: two codes per cell, one byte each (codes below
//! `L/2 + w + 6`, `w` sectors per angle cell; two bytes past 255): the default 64 × 32 × 64
//! cells are 256 KiB at 256 × 64 texels, twice the texture (the README sweeps the cell counts
//! against the steps). Per pixel: one fetch and `n* − start + 1` sector tests.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::CylinderError;
use super::frame::{angular_pitch, ray_sectors, row_coordinate};
use super::render::{CylinderRender, CylinderRenderParams, render_rows};
use super::texture::CylindricalTexture;
use super::warp::{Fragment, RadiusModel, SliceView};

/// Cells of the march bounds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BoundsParams {
    /// Abscissa cells `Bx` over `[−R, R]` (even, so that `x = 0` is a cell boundary). Default 64.
    pub cells_x: usize,
    /// Texture rows per row cell (≥ 1). Default 2.
    pub rows_per_cell: usize,
    /// Angle cells `Bα` over `[0, 2π)` (≥ 1). Default 64.
    pub cells_alpha: usize,
}

impl Default for BoundsParams {
    fn default() -> Self {
        Self {
            cells_x: 64,
            rows_per_cell: 2,
            cells_alpha: 64,
        }
    }
}

impl BoundsParams {
    /// Errors on zero sizes or an odd `cells_x`.
    pub fn validate(&self) -> Result<(), CylinderError> {
        for (n, what) in [
            (self.cells_x, "bound cells along x"),
            (self.rows_per_cell, "rows per bound cell"),
            (self.cells_alpha, "bound cells along the angle"),
        ] {
            if n == 0 {
                return Err(CylinderError::ZeroSize { what });
            }
        }
        if !self.cells_x.is_multiple_of(2) || self.cells_x > 4096 || self.cells_alpha > 4096 {
            return Err(CylinderError::InvalidParameter {
                name: "bound cells",
                value: format!("{} × {}", self.cells_x, self.cells_alpha),
                reason: "cells_x must be even; both at most 4096",
            });
        }
        Ok(())
    }
}

/// What building the bounds cost and how tight they are.
#[derive(Clone, Debug, Serialize)]
pub struct BoundsReport {
    /// The parameters.
    pub params: BoundsParams,
    /// `[Bx, row cells, Bα]`.
    pub cells: [usize; 3],
    /// Bytes stored (two values per cell).
    pub bytes: usize,
    /// Bytes per stored value (1 or 2).
    pub bytes_per_value: usize,
    /// Cells with at least one candidate edge.
    pub nonempty_cells: usize,
    /// Mean spread (greatest − least candidate sector) over the non-empty cells, in sectors.
    pub mean_span: f64,
    /// Build time (s).
    pub build_s: f64,
}

/// Per cell the least and greatest sector number of the edges that can be a first hit there,
/// from which each pixel gets a conservative range of march positions (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct MarchBounds {
    params: BoundsParams,
    columns: usize,
    rows: usize,
    row_cells: usize,
    /// Code of the least candidate sector, `start[i + Bx·(r + row_cells·a)]`; 0 in empty cells.
    start: Vec<u16>,
    /// Code of the greatest candidate sector; 0 marks an empty cell (a non-empty one has ≥ 1).
    stop: Vec<u16>,
}

/// `(min, max)` of `sin` over `[lo, hi]` (`hi ≥ lo`).
fn sin_range(lo: f64, hi: f64) -> (f64, f64) {
    if hi - lo >= TAU {
        return (-1.0, 1.0);
    }
    let (a, b) = (lo.sin(), hi.sin());
    let (mut mn, mut mx) = (a.min(b), a.max(b));
    // Does [lo, hi] contain π/2 + 2πk (max) or −π/2 + 2πk (min)?
    let contains = |c: f64| {
        let k = ((lo - c) / TAU).ceil();
        c + k * TAU <= hi
    };
    if contains(FRAC_PI_2) {
        mx = 1.0;
    }
    if contains(-FRAC_PI_2) {
        mn = -1.0;
    }
    (mn, mx)
}

impl MarchBounds {
    /// Builds the bounds of `texture` (see the module docs). Errors: invalid parameters.
    pub fn build(
        texture: &CylindricalTexture,
        params: &BoundsParams,
    ) -> Result<(Self, BoundsReport), CylinderError> {
        params.validate()?;
        let t0 = Instant::now();
        let (l, ly) = (texture.columns(), texture.rows());
        let g = params.rows_per_cell;
        let row_cells = (ly - 1).div_ceil(g).max(1);
        let (bx, ba) = (params.cells_x, params.cells_alpha);
        let (start, stop) = build_codes(texture, params);
        let nonempty: Vec<f64> = start
            .iter()
            .zip(&stop)
            .filter(|(_, b)| **b > 0)
            .map(|(a, b)| f64::from(*b) - f64::from(*a))
            .collect();
        let max_code = start.iter().chain(&stop).copied().max().unwrap_or(0);
        let bytes_per_value = if max_code < 256 { 1 } else { 2 };
        let report = BoundsReport {
            params: params.clone(),
            cells: [bx, row_cells, ba],
            bytes: 2 * start.len() * bytes_per_value,
            bytes_per_value,
            nonempty_cells: nonempty.len(),
            mean_span: nonempty.iter().sum::<f64>() / nonempty.len().max(1) as f64,
            build_s: t0.elapsed().as_secs_f64(),
        };
        Ok((
            Self {
                params: params.clone(),
                columns: l,
                rows: ly,
                row_cells,
                start,
                stop,
            },
            report,
        ))
    }

    /// The parameters the bounds were built with.
    pub fn params(&self) -> &BoundsParams {
        &self.params
    }

    /// Bounds of `texture` from stored codes (as a loader decodes [`Self::start`] and
    /// [`Self::stop`]). Errors: invalid parameters, code arrays of another length.
    pub fn from_codes(
        texture: &CylindricalTexture,
        params: BoundsParams,
        start: Vec<u16>,
        stop: Vec<u16>,
    ) -> Result<Self, CylinderError> {
        params.validate()?;
        let (l, ly) = (texture.columns(), texture.rows());
        let row_cells = (ly - 1).div_ceil(params.rows_per_cell).max(1);
        let n = params.cells_x * row_cells * params.cells_alpha;
        if start.len() != n || stop.len() != n {
            return Err(CylinderError::InvalidParameter {
                name: "stored march bounds",
                value: format!("{} and {} codes", start.len(), stop.len()),
                reason: "must hold one start and one stop code per cell",
            });
        }
        Ok(Self {
            params,
            columns: l,
            rows: ly,
            row_cells,
            start,
            stop,
        })
    }

    /// `[Bx, row cells, Bα]`.
    pub fn cells(&self) -> [usize; 3] {
        [self.params.cells_x, self.row_cells, self.params.cells_alpha]
    }

    /// Texture rows per row cell.
    pub fn rows_per_cell(&self) -> usize {
        self.params.rows_per_cell
    }

    /// Per cell the code of the least candidate sector, layout `i + Bx·(r + row_cells·a)` (x
    /// fastest; `r` = row cell, `a` = angle cell). Code `q` stands for sector `q + base`, with
    /// `base = ⌊α₀/dα⌋ − L/2 − 4` on the right half (`i ≥ Bx/2`) and `⌊α₀/dα⌋ − 3` on the left
    /// (`α₀ = 2πa/Bα`); fits in [`BoundsReport::bytes_per_value`] bytes.
    pub fn start(&self) -> &[u16] {
        &self.start
    }

    /// Per cell the code of the greatest candidate sector (see [`Self::start`]); 0 marks an
    /// empty cell.
    pub fn stop(&self) -> &[u16] {
        &self.stop
    }

    /// The cell of abscissa `x` (units of `R`), continuous row `v` and angle `alpha`; `None`
    /// outside `[−1, 1]` or for a non-finite input. A cell lies on one half of the screen, the
    /// half [`ray_sectors`] gives `x` (`x ≥ 0` right).
    pub fn cell(&self, x: f64, v: f64, alpha: f64) -> Option<usize> {
        if !(x.is_finite() && v.is_finite() && alpha.is_finite()) || x.abs() > 1.0 {
            return None;
        }
        let [bx, ry, ba] = self.cells();
        let mut i = (((x + 1.0) * 0.5 * bx as f64).floor() as usize).min(bx - 1);
        // Rounding must not move a pixel across x = 0.
        if x < 0.0 {
            i = i.min(bx / 2 - 1);
        } else {
            i = i.max(bx / 2);
        }
        let vc = v.clamp(0.0, (self.rows - 1) as f64);
        let r = ((vc / self.params.rows_per_cell as f64).floor() as usize).min(ry - 1);
        let a = (((alpha / TAU).rem_euclid(1.0) * ba as f64).floor() as usize).min(ba - 1);
        Some(i + bx * (r + ry * a))
    }

    /// The range `[start, stop]` of march positions (0 = the first sector the ray meets) where
    /// the first hit can lie for this pixel; `None` when none can (empty cell, or no candidate
    /// on the ray). Cost: O(1).
    pub fn range(&self, x: f64, v: f64, alpha: f64) -> Option<(usize, usize)> {
        let c = self.cell(x, v, alpha)?;
        if self.stop[c] == 0 {
            return None;
        }
        let l = self.columns;
        let rs = ray_sectors(x, alpha, l);
        if rs.count == 0 {
            return None;
        }
        let [bx, ry, ba] = self.cells();
        let (i, a) = (c % bx, c / (bx * ry));
        let base = code_base(a, i, bx, ba, l);
        let (s_min, s_max) = (
            base + i64::from(self.start[c]),
            base + i64::from(self.stop[c]),
        );
        // The ray's first sector in the frame of the reduced angle (the build's frame): the
        // march's own `first` shifted by whole turns.
        let li = l as i64;
        let guess = ((alpha.rem_euclid(TAU) - x.asin()) / angular_pitch(l)).floor() as i64;
        let first = rs.first - li * (rs.first - guess + li / 2).div_euclid(li);
        let (start, stop) = if rs.step < 0 {
            (first - s_max, first - s_min)
        } else {
            (s_min - first, s_max - first)
        };
        let stop = stop.min(rs.count as i64 - 1);
        let start = start.max(0);
        (start <= stop).then_some((start as usize, stop as usize))
    }

    /// The exact first hit at abscissa `x` of the slice `view` (at continuous row `v`), marching
    /// only the pixel's range. Returns the fragment and the sectors tested.
    pub fn march(&self, view: &SliceView, x: f64, v: f64) -> (Option<Fragment>, u32) {
        let Some((start, stop)) = self.range(x, v, view.alpha) else {
            return (None, 0);
        };
        let rs = ray_sectors(x, view.alpha, self.columns);
        view.march(
            x,
            rs.first + rs.step * start as i64,
            rs.step,
            stop + 1 - start,
        )
    }

    /// Renders `texture` by the bounded exact march (same image as exact inverse warping);
    /// `steps` counts the sector tests. Errors: a texture of another size, bad render parameters.
    pub fn render(
        &self,
        texture: &CylindricalTexture,
        params: &CylinderRenderParams,
    ) -> Result<CylinderRender, CylinderError> {
        if (texture.columns(), texture.rows()) != (self.columns, self.rows) {
            return Err(CylinderError::InvalidParameter {
                name: "texture",
                value: format!("{} × {}", texture.columns(), texture.rows()),
                reason: "must be the size of the texture the bounds were built on",
            });
        }
        let cyl = texture.cylinder();
        render_rows(texture, params, false, |row, out, _| {
            let v = row_coordinate(row.y, &cyl, self.rows);
            let slice = texture.slice(v);
            let view = SliceView::new(&slice, params.angle, RadiusModel::General);
            let mut steps = 0u64;
            for (x, o) in row.xs.iter().zip(out.iter_mut()) {
                let (f, n) = self.march(&view, *x, v);
                *o = f;
                steps += u64::from(n);
            }
            (steps, row.xs.len() as u64)
        })
    }
}

/// The cell codes `(start, stop)` of [`MarchBounds`] (module docs), angle cells in parallel.
///
/// Per angle cell, every edge (texture row `j`, sector `s`, outer or inner) is evaluated once —
/// whether it can face the camera over the cell's angles and the abscissae it can reach — and
/// the row cells then combine the rows they hold. What does not depend on the angle cell (the
/// amplitude and phase of each edge's facing sinusoid) is computed once per build, and the
/// interval sines of the sectors' half-lines once per angle cell and sector: the same numbers
/// from the same operations as the per-cell evaluation it replaces (`build_codes_reference`,
/// test `fast_codes_are_bitwise_the_first_codes`).
fn build_codes(texture: &CylindricalTexture, params: &BoundsParams) -> (Vec<u16>, Vec<u16>) {
    let (l, ly) = (texture.columns(), texture.rows());
    let g = params.rows_per_cell;
    let row_cells = (ly - 1).div_ceil(g).max(1);
    let (bx, ba) = (params.cells_x, params.cells_alpha);
    let da = angular_pitch(l);
    let (cos_da, sin_da) = (da.cos(), da.sin());
    let sample = |c: usize, j: usize| {
        texture
            .get(c % l, j)
            .map(|t| (f64::from(t.radius).abs(), t.is_negative()))
    };
    // Edge `2·(s + L·j) + k` (k = 0 outer: columns s, s + 1, radii ≥ 0; k = 1 inner: columns
    // s + L/2, s + L/2 + 1, radii < 0): endpoint distances and the facing sinusoid
    // σ·f = σ·(A·sin u + B·cos u), amplitude √(A² + B²), phase atan2(B, A).
    let edges: Vec<Option<SectorEdge>> = (0..ly * l * 2)
        .map(|e| {
            let (k, s, j) = (e % 2, (e / 2) % l, e / (2 * l));
            let negative = k == 1;
            let col = if negative { s + l / 2 } else { s };
            let ((ra, na), (rb, nb)) = (sample(col, j)?, sample(col + 1, j)?);
            if na != negative || nb != negative {
                return None;
            }
            let (a, b) = (ra - rb * cos_da, rb * sin_da);
            Some(SectorEdge {
                ra,
                rb,
                amp: a.hypot(b),
                psi: b.atan2(a),
            })
        })
        .collect();
    let mut start = vec![0u16; bx * row_cells * ba];
    let mut stop = vec![0u16; bx * row_cells * ba];
    start
        .par_chunks_mut(bx * row_cells)
        .zip(stop.par_chunks_mut(bx * row_cells))
        .enumerate()
        .for_each(|(a, (start, stop))| {
            let (alpha0, alpha1) = cell_angles(a, ba);
            // Per sector: interval sines over the cell's angles of its two half-lines.
            let sines: Vec<SectorSines> = (0..l)
                .map(|s| {
                    let (beta_a, beta_b) = (s as f64 * da, (s + 1) as f64 * da);
                    let (u0, u1) = (alpha0 - beta_a, alpha1 - beta_a);
                    (
                        (u0, u1),
                        sin_range(u0, u1),
                        sin_range(alpha0 - beta_b, alpha1 - beta_b),
                    )
                })
                .collect();
            // Per edge: whether it can face the camera, and its abscissa reach.
            let reach: Vec<Option<(bool, (f64, f64))>> = edges
                .iter()
                .enumerate()
                .map(|(e, edge)| {
                    let edge = edge.as_ref()?;
                    let ((u0, u1), sa, sb) = sines[(e / 2) % l];
                    let (mn, mx) = sin_range(u0 + edge.psi, u1 + edge.psi);
                    let best = if e % 2 == 0 {
                        edge.amp * mx
                    } else {
                        -edge.amp * mn
                    };
                    let lo = (edge.ra * sa.0).min(edge.rb * sb.0);
                    let hi = (edge.ra * sa.1).max(edge.rb * sb.1);
                    // The margin covers the f32 interpolation of radii between rows.
                    Some((best > -1e-9, (lo - 1e-6, hi + 1e-6)))
                })
                .collect();
            let mut lo = vec![i64::MAX; bx];
            let mut hi = vec![i64::MIN; bx];
            for r in 0..row_cells {
                lo.iter_mut().for_each(|v| *v = i64::MAX);
                hi.iter_mut().for_each(|v| *v = i64::MIN);
                let (j0, j1) = (r * g, ((r + 1) * g).min(ly - 1));
                for s in 0..l {
                    let mut x_range: [Option<(f64, f64)>; 2] = [None, None];
                    let mut faces = [false; 2];
                    for j in j0..=j1 {
                        for k in 0..2 {
                            let Some((f, (x0, x1))) = reach[2 * (s + l * j) + k] else {
                                continue;
                            };
                            faces[k] |= f;
                            x_range[k] =
                                Some(x_range[k].map_or((x0, x1), |(a, b)| (a.min(x0), b.max(x1))));
                        }
                    }
                    for (reach, _) in x_range.into_iter().zip(faces).filter(|(_, f)| *f) {
                        let Some(reach) = reach else { continue };
                        widen_cells(reach, s, l, (alpha0, alpha1), bx, &mut lo, &mut hi);
                    }
                }
                store_codes(
                    (&lo, &hi),
                    (a, bx, ba, l),
                    &mut start[r * bx..(r + 1) * bx],
                    &mut stop[r * bx..(r + 1) * bx],
                );
            }
        });
    (start, stop)
}

/// Per sector of an angle cell: its `(u₀, u₁)` and the interval sines of its two half-lines.
type SectorSines = ((f64, f64), (f64, f64), (f64, f64));

/// One sector edge of one texture row (see [`build_codes`]).
struct SectorEdge {
    ra: f64,
    rb: f64,
    amp: f64,
    psi: f64,
}

/// The cell codes `(start, stop)` as the build first computed them (every edge's facing
/// sinusoid and interval sines recomputed per cell): [`build_codes`] must give the same codes.
#[cfg(test)]
fn build_codes_reference(
    texture: &CylindricalTexture,
    params: &BoundsParams,
) -> (Vec<u16>, Vec<u16>) {
    let (l, ly) = (texture.columns(), texture.rows());
    let g = params.rows_per_cell;
    let row_cells = (ly - 1).div_ceil(g).max(1);
    let (bx, ba) = (params.cells_x, params.cells_alpha);
    let da = angular_pitch(l);
    let sample = |c: usize, j: usize| {
        texture
            .get(c % l, j)
            .map(|t| (f64::from(t.radius).abs(), t.is_negative()))
    };
    let mut start = vec![0u16; bx * row_cells * ba];
    let mut stop = vec![0u16; bx * row_cells * ba];
    start
        .par_chunks_mut(bx)
        .zip(stop.par_chunks_mut(bx))
        .enumerate()
        .for_each(|(n, (start, stop))| {
            let (r, a) = (n % row_cells, n / row_cells);
            let (alpha0, alpha1) = cell_angles(a, ba);
            let mut lo = vec![i64::MAX; bx];
            let mut hi = vec![i64::MIN; bx];
            let (j0, j1) = (r * g, ((r + 1) * g).min(ly - 1));
            for s in 0..l {
                // The edges of sector s in each row of the cell: outer (columns s, s + 1,
                // radii ≥ 0) and inner (columns s + L/2, s + L/2 + 1, radii < 0). A slice
                // between two rows interpolates the radii of an edge present in both, and
                // everything bounded below is linear in those radii for a fixed angle, so
                // its extremes are reached at the rows themselves.
                // An interpolated edge that faces the camera may lie between a row where it
                // faces and one where it does not: take the reach of every row once any faces.
                let mut x_range: [Option<(f64, f64)>; 2] = [None, None];
                let mut faces = [false; 2];
                for j in j0..=j1 {
                    for (k, (a, negative)) in
                        [(s, false), (s + l / 2, true)].into_iter().enumerate()
                    {
                        let (Some((ra, na)), Some((rb, nb))) = (sample(a, j), sample(a + 1, j))
                        else {
                            continue;
                        };
                        if na != negative || nb != negative {
                            continue;
                        }
                        let sigma = if negative { -1.0 } else { 1.0 };
                        let (f, (x0, x1)) = edge_reach(ra, rb, sigma, s, da, (alpha0, alpha1));
                        faces[k] |= f;
                        x_range[k] =
                            Some(x_range[k].map_or((x0, x1), |(a, b)| (a.min(x0), b.max(x1))));
                    }
                }
                for (reach, _) in x_range.into_iter().zip(faces).filter(|(_, f)| *f) {
                    let Some(reach) = reach else { continue };
                    widen_cells(reach, s, l, (alpha0, alpha1), bx, &mut lo, &mut hi);
                }
            }
            store_codes((&lo, &hi), (a, bx, ba, l), start, stop);
        });
    (start, stop)
}

/// Whether the edge of sector `s` with endpoint distances `ra` (on half-line `β_s`) and `rb`
/// (on `β_{s+1}`), outer (`sigma = 1`) or inner (`−1`), can face the camera for an angle in
/// `alpha`, and the abscissa range it can cover there (with a margin for rounding).
#[cfg(test)]
fn edge_reach(
    ra: f64,
    rb: f64,
    sigma: f64,
    s: usize,
    da: f64,
    alpha: (f64, f64),
) -> (bool, (f64, f64)) {
    let (beta_a, beta_b) = (s as f64 * da, (s + 1) as f64 * da);
    let (u0, u1) = (alpha.0 - beta_a, alpha.1 - beta_a);
    // Facing: σ·f(α) > 0 for some α, with f = ρ_a·sin u − ρ_b·sin(u − dα), u = α − β_s,
    // = A·sin u + B·cos u, A = ρ_a − ρ_b·cos dα, B = ρ_b·sin dα: a sinusoid, exact extremes.
    let (a, b) = (ra - rb * da.cos(), rb * da.sin());
    let (amp, psi) = (a.hypot(b), b.atan2(a));
    let (mn, mx) = sin_range(u0 + psi, u1 + psi);
    let best = if sigma > 0.0 { amp * mx } else { -amp * mn };
    // Abscissa range of the edge over the cell's angles: x is linear along the edge between
    // its endpoints' abscissae ρ·sin(α − β).
    let (sa, sb) = (
        sin_range(u0, u1),
        sin_range(alpha.0 - beta_b, alpha.1 - beta_b),
    );
    let lo = (ra * sa.0).min(rb * sb.0);
    let hi = (ra * sa.1).max(rb * sb.1);
    // The margin covers the f32 interpolation of radii between rows (a few ulps).
    (best > -1e-9, (lo - 1e-6, hi + 1e-6))
}

/// Angles `[α₀, α₁]` of angle cell `a` of `ba`.
fn cell_angles(a: usize, ba: usize) -> (f64, f64) {
    (a as f64 * TAU / ba as f64, (a + 1) as f64 * TAU / ba as f64)
}

/// The sector number that code 0 stands for in angle cell `a`, abscissa cell `i`. Candidate
/// sectors lie, on the right half, in `[⌊α₀/dα⌋ − L/2 − 3, ⌊α₁/dα⌋ + 1]` and, on the left half,
/// in `[⌊α₀/dα⌋ − 2, ⌊α₁/dα⌋ + L/2 + 2]`, so the codes are ≥ 1 and below `L/2 + w + 6`
/// (`w` = sectors per angle cell): one byte at the defaults.
/// Writes the codes of one row of cells of angle cell `a` from their step ranges `lo..=hi`
/// (`lo > hi`: empty cell, code left 0). Codes are ≥ 1 by construction (see [`code_base`]).
fn store_codes(
    (lo, hi): (&[i64], &[i64]),
    (a, bx, ba, l): (usize, usize, usize, usize),
    start: &mut [u16],
    stop: &mut [u16],
) {
    for i in 0..bx {
        if lo[i] <= hi[i] {
            let base = code_base(a, i, bx, ba, l);
            start[i] = (lo[i] - base).clamp(1, i64::from(u16::MAX)) as u16;
            stop[i] = (hi[i] - base).clamp(1, i64::from(u16::MAX)) as u16;
        }
    }
}

fn code_base(a: usize, i: usize, bx: usize, ba: usize, l: usize) -> i64 {
    let a_ref = (cell_angles(a, ba).0 / angular_pitch(l)).floor() as i64;
    if i >= bx / 2 {
        a_ref - (l / 2) as i64 - 4
    } else {
        a_ref - 3
    }
}

/// Records, for every abscissa cell that an edge of sector `s` reaching abscissae `reach` can
/// cover for angles in `alpha`, the sector numbers (unwrapped, see the module docs) the edge
/// can take along the rays of the cell.
fn widen_cells(
    reach: (f64, f64),
    s: usize,
    l: usize,
    alpha: (f64, f64),
    bx: usize,
    lo: &mut [i64],
    hi: &mut [i64],
) {
    let da = angular_pitch(l);
    let (beta_a, beta_b) = (s as f64 * da, (s + 1) as f64 * da);
    let (ex0, ex1) = reach;
    if ex1 < -1.0 || ex0 > 1.0 {
        return;
    }
    let cell_x = |i: usize| -1.0 + 2.0 * i as f64 / bx as f64;
    let i0 = (((ex0.max(-1.0) + 1.0) * 0.5 * bx as f64).floor() as usize).min(bx - 1);
    let i1 = (((ex1.min(1.0) + 1.0) * 0.5 * bx as f64).floor() as usize).min(bx - 1);
    for i in i0..=i1 {
        let right = i >= bx / 2;
        let (x0, x1) = (cell_x(i).max(ex0), cell_x(i + 1).min(ex1));
        if x0 > x1 {
            continue;
        }
        // Smallest |x| over the part of the cell the edge reaches.
        let ax0 = if right { x0.max(0.0) } else { (-x1).max(0.0) };
        let asin0 = ax0.min(1.0).asin();
        // θ of the edge's points: right half θ = α − β, left half θ = β − α; shifting θ by a
        // turn shifts the sector number by L.
        let (t_lo, t_hi, sign) = if right {
            (alpha.0 - beta_b, alpha.1 - beta_a, 1)
        } else {
            (beta_a - alpha.1, beta_b - alpha.0, -1)
        };
        let m = (t_lo / TAU).floor();
        let t0 = t_lo - m * TAU;
        let t1 = t0 + (t_hi - t_lo);
        let m = m as i64;
        for (p0, p1, turns) in [(t0, t1, m), (t0 - TAU, t1 - TAU, m + 1)] {
            // A point on the ray has θ ∈ [asin|x|, π − asin|x|].
            if p1 < asin0 - 1e-9 || p0 > PI - asin0 + 1e-9 {
                continue;
            }
            let rep = s as i64 + sign * turns * l as i64;
            lo[i] = lo[i].min(rep);
            hi[i] = hi[i].max(rep);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The build's codes are bit for bit those of the per-cell evaluation it replaced, on shapes
    /// with holes, negative radii and parts off the axis, at the default and at odd cell counts.
    #[test]
    fn fast_codes_are_bitwise_the_first_codes() {
        use crate::cylinder::CylindricalTexture;
        use altrep_data_gen::CylinderParams;
        for name in ["pear", "tree", "truck", "chair"] {
            let shape = altrep_data_gen::scene_shape(name).unwrap();
            let p = CylinderParams {
                columns: 128,
                rows: 32,
                ..CylinderParams::default()
            };
            let tex = CylindricalTexture::capture(&shape, &p, 1).unwrap();
            for params in [
                BoundsParams::default(),
                BoundsParams {
                    cells_x: 18,
                    rows_per_cell: 3,
                    cells_alpha: 25,
                },
            ] {
                let fast = build_codes(&tex, &params);
                assert!(fast.1.iter().any(|c| *c > 0), "{name}: no code");
                assert!(
                    fast == build_codes_reference(&tex, &params),
                    "{name}: codes differ"
                );
            }
        }
    }

    #[test]
    fn sine_ranges() {
        assert_eq!(sin_range(0.0, 0.1).0, 0.0);
        assert_eq!(sin_range(1.0, 2.0).1, 1.0);
        assert_eq!(sin_range(4.0, 5.0).0, -1.0);
        assert_eq!(sin_range(-2.0, -1.0).0, -1.0);
        assert_eq!(sin_range(0.0, 7.0), (-1.0, 1.0));
        let (mn, mx) = sin_range(2.0, 3.0);
        assert!((mn - 3f64.sin()).abs() < 1e-15 && (mx - 2f64.sin()).abs() < 1e-15);
    }
}
