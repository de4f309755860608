//! The offset texture: the column offset `k(x, y, α)` that inverse warping finds, sampled on a
//! fine grid and fitted by the trilinear least-squares fit ([`crate::fit`]), so that a shader
//! reads it with one 3D-texture fetch; then validated and, in hybrid mode, refined by a few
//! exact sector tests.
//!
//! ## Fit coordinates
//!
//! The fit's unit cube maps to the screen and the view angle as `w_y = (v + ½)/Ly` (continuous
//! row coordinate `v`, so `w_y = (H − y)/H`, 0 at the top), `w_α = α/2π` (periodic: node `Aα` is
//! node 0, no seam at `α = 0`) and, for the screen abscissa `x` (units of `R`):
//! * without a mask, `w_x = (x + 1)/2`, the cylinder's width (the source);
//! * with the [`SilhouetteMask`], `w_x = (x − x_lo)/(x_hi − x_lo)`, the slice's silhouette
//!   interval at that row and angle.
//!
//! Fine sample `(i, j, n)` sits at the cell centre `((i + ½)/Nx, (j + ½)/Ny, (n + ½)/Nα)`; with
//! `Ny = Ly` each fine row is a texture row. Offsets are stored with 16 bits (the fit's best
//! scale and offset); renders use the dequantised values.
//!
//! ## What the fit cannot follow, and what is done about it
//!
//! `k` is smooth on a visible surface and jumps at silhouettes (to undefined) and at occlusion
//! boundaries (to another surface); near a silhouette it also has a square-root singularity
//! (`k ≈ −asin(x/ρ)/dα` for a disc of radius `ρ`). A trilinear fit smears every jump over a
//! cell, and the smeared samples pull the fit away from the smooth parts too. The remedies,
//! each measured by [`super::evaluate`]:
//! * **validation** — the fetched offset names a column; the point it names is accepted only if
//!   it projects within `tolerance` pixels of the pixel;
//! * **silhouette mask** ([`OffsetParams::mask`]) — pixels outside the slice's silhouette
//!   interval are discarded, and the interval normalises the abscissa, so that the fit no
//!   longer spends its cells on where the silhouette lies (it moves with the row and the angle);
//! * **fitting only where `k` is continuous** ([`FitSupport::Continuous`]) — samples next to an
//!   undefined sample or a jump of more than `jump` texels to a grid neighbour are left out of
//!   the fit (the regularisation fills the nodes they leave free);
//! * **λ chosen per fit** ([`LambdaRule::Bounded`]) — the smallest regularisation that keeps
//!   every coefficient within twice the data range, so that 8-bit storage and extrapolation stay
//!   sane (the fixed λ = 10⁻⁴ reached 7.7× on the tree and 17× on the beetle); the chosen λ,
//!   the rungs tried and the float, stored and 8-bit errors are in the [`OffsetReport`];
//! * **hybrid refinement** ([`OffsetMode::Hybrid`]) — from the sector the offset names, at most
//!   `m` exact sector tests, each followed by a Newton jump along the tested edge (see
//!   `refine`); a hit is an exact intersection. Measured against a front-to-back window of `m`
//!   sectors centred on the named one, Newton gains 1.4 dB (pear) to 3 dB (truck, tree) at
//!   `m = 4` and needs fewer tests.

use std::f64::consts::TAU;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use super::CylinderError;
use super::frame::{column_offset, offset_column, ray_sectors, row_coordinate, sector_index};
use super::render::{CylinderRender, CylinderRenderParams, render_rows};
use super::texture::CylindricalTexture;
use super::warp::{Fragment, RadiusModel, SliceView};
use crate::fit::{self, FitParams, FitReport, TrilinearGrid};
use crate::stats::ErrorStats;

/// Which fine samples enter the fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum FitSupport {
    /// Every defined sample (the source's choice).
    All,
    /// Only samples whose grid neighbours along the three axes are all defined and differ by at
    /// most `jump` texels (wrapped): the samples where `k` is continuous.
    Continuous {
        /// Largest offset difference between grid neighbours still called continuous (texels).
        jump: f64,
    },
}

/// How the regularisation weight λ of the offset fit is chosen (dimensionless, see
/// [`crate::fit`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub enum LambdaRule {
    /// This λ for every fit.
    Fixed(f64),
    /// The smallest λ of the ladder `λ_k = 10⁻⁴·10^(k/2)`, `k = 0, …, 12` (10⁻⁴ to 10²), whose
    /// coefficients all lie within `multiple` times the data range about its centre:
    /// `|a − c| ≤ multiple·h` with `c`, `h` the centre and half-width of the fitted samples'
    /// range. When none does, the last (the smoothest). The membrane penalty pulls coefficients
    /// toward their neighbours, so the range shrinks as λ grows; the first rung is the old fixed
    /// default ([`fit::DEFAULT_LAMBDA`]), kept wherever it already satisfies the bound.
    Bounded {
        /// Largest coefficient excursion, in half data ranges about the centre (≥ 1).
        multiple: f64,
    },
}

impl LambdaRule {
    /// The ladder of [`LambdaRule::Bounded`].
    pub fn ladder() -> impl Iterator<Item = f64> {
        (0..=12).map(|k| fit::DEFAULT_LAMBDA * 10f64.powf(0.5 * k as f64))
    }
}

/// One rung of the λ choice: the coefficient range it gave.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LambdaTrial {
    /// λ tried.
    pub lambda: f64,
    /// Largest `|a − c|/h` over the coefficients (see [`LambdaRule::Bounded`]).
    pub excursion: f64,
}

/// Parameters of [`OffsetTexture::fit`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct OffsetParams {
    /// Cells of the fitted grid `[Ax, Ay, Aα]`. Default `[15, 8, 16]`, the source's: in the
    /// [`super::sweep`] over the six evaluation shapes it is the knee (mean 18.7 dB plain, 19.9
    /// dB hybrid m = 2, against 16.9 / 18.4 at 8×4×8 and 19.7 / 20.9 at 31×16×32 for 7.5× the
    /// coefficients and 6× the fit time).
    pub cells: [usize; 3],
    /// Fine samples `[Nx, Ny, Nα]`; `Ny = 0` means one per texture row. Default `[64, 0, 64]`.
    pub samples: [usize; 3],
    /// How λ is chosen. Default `Bounded { multiple: 2 }`: coefficients within twice the data
    /// range (the fixed 10⁻⁴ reached 17× on the beetle); measured in the README.
    pub lambda: LambdaRule,
    /// Which samples are fitted. Default `Continuous { jump: 8.0 }`: measured against `All` and
    /// jumps of 4 and 16 texels, it gives the best image on truck, tree and chair (+0.4 to +0.7
    /// dB) and within 0.2 dB of the best on the pear.
    pub support: FitSupport,
    /// Store the silhouette mask ([`SilhouetteMask`]) and fit `k` against the abscissa
    /// normalised within it. Default `true`: on the pear it lifts the plain fitted image from
    /// 22.7 to 32.2 dB against the ground truth and the offset RMS from 3.4 to 1.4 texels, for
    /// 16 KiB more.
    pub mask: bool,
    /// Bits per stored coefficient (8 or 16); renders use the dequantised values. Default 16.
    pub bits: u32,
}

impl Default for OffsetParams {
    fn default() -> Self {
        Self {
            cells: [15, 8, 16],
            samples: [64, 0, 64],
            lambda: LambdaRule::Bounded { multiple: 2.0 },
            support: FitSupport::Continuous { jump: 8.0 },
            mask: true,
            bits: 16,
        }
    }
}

/// What the precomputation of an offset texture cost and how well it fits its samples.
#[derive(Clone, Debug, Serialize)]
pub struct OffsetReport {
    /// The parameters.
    pub params: OffsetParams,
    /// Fine samples `[Nx, Ny, Nα]` actually used.
    pub samples: [usize; 3],
    /// Coefficients stored (`Ax·(Ay + 1)·Aα`).
    pub nodes: usize,
    /// Bytes stored: `nodes · ⌈bits/8⌉`, plus the mask when there is one.
    pub bytes: usize,
    /// Bytes of the silhouette mask (0 without one).
    pub mask_bytes: usize,
    /// Fine samples where `k` is defined.
    pub defined: usize,
    /// Defined samples that entered the fit (see [`FitSupport`]).
    pub fitted: usize,
    /// Mean march steps of the sampling (inverse warping on the fine grid).
    pub mean_sampling_steps: f64,
    /// Sampling time (s).
    pub sampling_s: f64,
    /// Choosing the fitted samples ([`FitSupport`]) and assembling the normal equations (s).
    pub assembly_s: f64,
    /// Solve (s).
    pub solve_s: f64,
    /// Quantisation of the coefficients (with the fit's own error statistics) (s).
    pub quantization_s: f64,
    /// Error of the stored (dequantised) offsets over every defined fine sample, texels.
    pub error_defined: ErrorStats,
    /// The same with unquantised (f64) coefficients.
    pub error_defined_float: ErrorStats,
    /// The same with 8-bit coefficients (min/max codes, refitted scale and offset): the honest
    /// figure of 8-bit storage beside the float one.
    pub error_defined_8bit: ErrorStats,
    /// λ chosen.
    pub lambda: f64,
    /// The rungs tried by [`LambdaRule::Bounded`] (empty for a fixed λ).
    pub lambda_trials: Vec<LambdaTrial>,
    /// Largest `|a − c|/h` of the chosen coefficients: 1 means within the data range.
    pub coef_excursion: f64,
    /// The fit's own report (error over the fitted samples, coefficient range, quantisation,
    /// solver).
    pub fit: FitReport,
}

impl OffsetReport {
    /// Precomputation time: sampling + assembly + solve + quantisation, milliseconds.
    pub fn precompute_ms(&self) -> f64 {
        (self.sampling_s + self.assembly_s + self.solve_s + self.quantization_s) * 1e3
    }
}

/// The fitted offset function of one cylindrical texture (see the module docs).
#[derive(Clone, Debug)]
pub struct OffsetTexture {
    grid: TrilinearGrid,
    mask: Option<SilhouetteMask>,
    columns: usize,
    rows: usize,
    /// How it was made.
    pub report: OffsetReport,
}

/// The exact offsets `k` of a texture on a fine grid, as the fit takes them.
#[derive(Clone, Debug)]
pub struct OffsetSamples {
    /// `k` per fine sample (texels), `None` outside the silhouette; layout of
    /// [`fit::FitSamples`] (x fastest, then rows, then angles).
    pub grid: fit::FitSamples,
    /// The silhouette mask at the fine grid's rows and angles, when the abscissa was normalised
    /// within it.
    pub mask: Option<SilhouetteMask>,
    /// Total march steps.
    pub steps: u64,
    /// Wall time (s).
    pub sampling_s: f64,
}

/// Per slice and camera angle, the interval `[x_lo, x_hi]` (units of `R`) that the slice's
/// visible edges cover: the silhouette's horizontal extent, `None` for an empty slice. Stored at
/// `Ny` rows × `Nα` angles (the fine grid's), two 16-bit values each, and read with bilinear
/// filtering (periodic in the angle); a pixel outside the interval is outside the silhouette.
#[derive(Clone, Debug, PartialEq)]
pub struct SilhouetteMask {
    rows: usize,
    angles: usize,
    texture_rows: usize,
    /// `intervals[j + rows·a]`.
    intervals: Vec<Option<(f64, f64)>>,
}

impl SilhouetteMask {
    /// Bytes stored: two 16-bit bounds per (row, angle).
    pub fn bytes(&self) -> usize {
        4 * self.rows * self.angles
    }

    /// `[Ny, Nα]`.
    pub fn size(&self) -> [usize; 2] {
        [self.rows, self.angles]
    }

    /// The interpolated interval at continuous texture row `v` and angle `alpha`: bilinear over
    /// the four nearest samples, renormalised over the defined ones; `None` when none is.
    pub fn interval(&self, v: f64, alpha: f64) -> Option<(f64, f64)> {
        let ty = ((v + 0.5) / self.texture_rows as f64 * self.rows as f64 - 0.5)
            .clamp(0.0, (self.rows - 1) as f64);
        let j0 = (ty.floor() as usize).min(self.rows.saturating_sub(2));
        let fy = (ty - j0 as f64).clamp(0.0, 1.0);
        let j1 = (j0 + 1).min(self.rows - 1);
        let ta = (alpha / TAU).rem_euclid(1.0) * self.angles as f64 - 0.5;
        let a0f = ta.floor();
        let fa = ta - a0f;
        let a0 = (a0f as i64).rem_euclid(self.angles as i64) as usize;
        let a1 = (a0 + 1) % self.angles;
        let (mut lo, mut hi, mut w) = (0.0, 0.0, 0.0);
        for (j, a, wt) in [
            (j0, a0, (1.0 - fy) * (1.0 - fa)),
            (j1, a0, fy * (1.0 - fa)),
            (j0, a1, (1.0 - fy) * fa),
            (j1, a1, fy * fa),
        ] {
            if let Some((l, h)) = self.intervals[j + self.rows * a] {
                lo += wt * l;
                hi += wt * h;
                w += wt;
            }
        }
        (w > 0.0).then(|| (lo / w, hi / w))
    }
}

/// Samples `k(x, y, α)` by exact inverse warping on a fine `Nx × Ny × Nα` grid (`Ny = 0`: one
/// per texture row). Without a mask the abscissae span the cylinder, `x = 2w_x − 1`; with one
/// they span the slice's silhouette interval at that row and angle, `x = x_lo + w_x·(x_hi −
/// x_lo)`, and the intervals form the [`SilhouetteMask`]. Cost: `Nx·Ny·Nα` marches of up to
/// `L/2 + 1` sector tests, in parallel over (angle, row) pairs.
pub fn sample_offsets(
    texture: &CylindricalTexture,
    samples: [usize; 3],
    mask: bool,
) -> Result<OffsetSamples, CylinderError> {
    let t0 = Instant::now();
    let (l, rows) = (texture.columns(), texture.rows());
    let [nx, ny, na] = [
        samples[0],
        if samples[1] == 0 { rows } else { samples[1] },
        samples[2],
    ];
    if nx == 0 || na == 0 {
        return Err(CylinderError::ZeroSize {
            what: "offset sample grid",
        });
    }
    let coord = |i: usize, n: usize| fit::sample_coordinate(i, n);
    let slices: Vec<_> = (0..ny)
        .map(|j| texture.slice(coord(j, ny) * rows as f64 - 0.5))
        .collect();
    let mut values = vec![None; nx * ny * na];
    let mut intervals = vec![None; ny * na];
    let steps: u64 = values
        .par_chunks_mut(nx)
        .zip(intervals.par_iter_mut())
        .enumerate()
        .map(|(n, (out, interval))| {
            let (j, a) = (n % ny, n / ny);
            let alpha = TAU * coord(a, na);
            let view = SliceView::new(&slices[j], alpha, RadiusModel::General);
            *interval = view.silhouette();
            let (lo, hi) = match (mask, *interval) {
                (false, _) => (-1.0, 1.0),
                (true, Some(i)) => i,
                (true, None) => return 0,
            };
            let mut steps = 0u64;
            for (i, o) in out.iter_mut().enumerate() {
                let (f, s) = view.inverse(lo + coord(i, nx) * (hi - lo));
                steps += u64::from(s);
                *o = f.map(|f| column_offset(f.column, alpha, l));
            }
            steps
        })
        .sum();
    Ok(OffsetSamples {
        grid: fit::FitSamples::new([nx, ny, na], values)?,
        mask: mask.then_some(SilhouetteMask {
            rows: ny,
            angles: na,
            texture_rows: rows,
            intervals,
        }),
        steps,
        sampling_s: t0.elapsed().as_secs_f64(),
    })
}

/// Error (texels, wrapped) of the fitted offsets over the defined samples.
fn offset_error(samples: &fit::FitSamples, grid: &TrilinearGrid, columns: usize) -> ErrorStats {
    let [nx, ny, _] = samples.dims();
    let l = columns as f64;
    let errors: Vec<f64> = samples
        .values()
        .par_iter()
        .enumerate()
        .filter_map(|(n, k)| {
            let k = (*k)?;
            let p = samples.position(n % nx, (n / nx) % ny, n / (nx * ny));
            let d = (grid.eval(p) - k).rem_euclid(l);
            Some(d.min(l - d))
        })
        .collect();
    ErrorStats::of(errors)
}

/// Keeps the samples where `k` is continuous (see [`FitSupport::Continuous`]).
fn continuous_only(samples: &fit::FitSamples, jump: f64, columns: usize) -> Vec<Option<f64>> {
    let [nx, ny, na] = samples.dims();
    let l = columns as f64;
    let values = samples.values();
    (0..values.len())
        .into_par_iter()
        .map(|n| {
            let d = values[n]?;
            let (i, j, a) = (n % nx, (n / nx) % ny, n / (nx * ny));
            let neighbours = [
                (i > 0).then(|| n - 1),
                (i + 1 < nx).then(|| n + 1),
                (j > 0).then(|| n - nx),
                (j + 1 < ny).then(|| n + nx),
                // The angle axis is periodic.
                Some(((a + na - 1) % na) * nx * ny + i + nx * j),
                Some(((a + 1) % na) * nx * ny + i + nx * j),
            ];
            let smooth = neighbours.into_iter().flatten().all(|m| {
                values[m].is_some_and(|e| {
                    let diff = (d - e).rem_euclid(l);
                    diff.min(l - diff) <= jump
                })
            });
            smooth.then_some(d)
        })
        .collect()
}

/// How a fitted offset is used per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum OffsetMode {
    /// One fetch; the named point is accepted if it projects within the tolerance.
    Plain,
    /// One fetch, then at most `steps` exact sector tests around the named sector; when none
    /// hits, the plain result.
    Hybrid {
        /// Largest number of sector tests `m`.
        steps: usize,
    },
}

impl OffsetMode {
    /// `fitted` or `hybrid-m<m>`.
    pub fn name(&self) -> String {
        match self {
            Self::Plain => "fitted".into(),
            Self::Hybrid { steps } => format!("hybrid-m{steps}"),
        }
    }
}

impl OffsetTexture {
    /// Samples the offsets of `texture` by inverse warping and fits them (see the module docs).
    /// Cost: [`sample_offsets`] plus one sparse solve of `Ax·(Ay + 1)·Aα` unknowns.
    ///
    /// Errors: zero sizes, `bits` not in `1..=16`, no defined sample (an empty texture), a
    /// failed solve.
    pub fn fit(texture: &CylindricalTexture, params: &OffsetParams) -> Result<Self, CylinderError> {
        let samples = sample_offsets(texture, params.samples, params.mask)?;
        Self::fit_samples(texture, &samples, params)
    }

    /// Fits already sampled offsets (for sweeps over the grid that reuse one sampling); the
    /// report counts the sampling time of `samples`. `params.samples` and `params.mask` are
    /// ignored (the samples decide).
    pub fn fit_samples(
        texture: &CylindricalTexture,
        samples: &OffsetSamples,
        params: &OffsetParams,
    ) -> Result<Self, CylinderError> {
        if !(1..=16).contains(&params.bits) {
            return Err(CylinderError::InvalidParameter {
                name: "offset bits",
                value: params.bits.to_string(),
                reason: "must be in 1..=16",
            });
        }
        let l = texture.columns();
        let data = &samples.grid;
        let t0 = Instant::now();
        let kept = match params.support {
            FitSupport::All => data.values().to_vec(),
            FitSupport::Continuous { jump } => continuous_only(data, jump, l),
        };
        let fitted_grid = fit::FitSamples::new(data.dims(), kept)?;
        let support_s = t0.elapsed().as_secs_f64();
        let fitter = fit::Fitter::new(&fitted_grid, params.cells, [false, false, true])?;
        let mut fit_params = FitParams {
            cells: params.cells,
            periodic: [false, false, true],
            lambda: fit::DEFAULT_LAMBDA,
            quantize_bits: Vec::new(),
            ..FitParams::default()
        };
        let stats = *fitter.normal_equations().data();
        let (centre, half) = (
            0.5 * (stats.max + stats.min),
            (0.5 * (stats.max - stats.min)).max(1e-9),
        );
        let excursion = |g: &TrilinearGrid| {
            let (lo, hi) = g.value_range();
            (centre - lo).max(hi - centre) / half
        };
        let mut trials = Vec::new();
        let mut solve_s = 0.0;
        match params.lambda {
            LambdaRule::Fixed(lambda) => fit_params.lambda = lambda,
            LambdaRule::Bounded { multiple } => {
                if !(multiple >= 1.0 && multiple.is_finite()) {
                    return Err(CylinderError::InvalidParameter {
                        name: "lambda multiple",
                        value: multiple.to_string(),
                        reason: "must be finite and ≥ 1",
                    });
                }
                for lambda in LambdaRule::ladder() {
                    fit_params.lambda = lambda;
                    let f = fitter.fit(&fit_params)?;
                    solve_s += f.report.timing.solve_s;
                    let e = excursion(&f.grid);
                    trials.push(LambdaTrial {
                        lambda,
                        excursion: e,
                    });
                    if e <= multiple {
                        break;
                    }
                }
            }
        }
        let mut bits = vec![params.bits];
        if params.bits != 8 {
            bits.push(8);
        }
        fit_params.quantize_bits = bits;
        let fitted = fitter.fit(&fit_params)?;
        let grid = fitted.report.quantized[0].quantized.to_grid(&fitted.grid)?;
        let grid8 = fitted
            .report
            .quantized
            .iter()
            .find(|q| q.bits == 8)
            .map(|q| q.quantized.to_grid(&fitted.grid))
            .transpose()?
            .unwrap_or_else(|| grid.clone());
        let nodes = grid.values().len();
        let mask_bytes = samples.mask.as_ref().map_or(0, SilhouetteMask::bytes);
        let report = OffsetReport {
            params: OffsetParams {
                samples: data.dims(),
                mask: samples.mask.is_some(),
                ..*params
            },
            samples: data.dims(),
            nodes,
            bytes: nodes * (params.bits as usize).div_ceil(8) + mask_bytes,
            mask_bytes,
            defined: data.defined_count(),
            fitted: fitted_grid.defined_count(),
            mean_sampling_steps: samples.steps as f64 / data.values().len() as f64,
            sampling_s: samples.sampling_s,
            assembly_s: support_s + fitter.assembly_s(),
            solve_s: solve_s + fitted.report.timing.solve_s,
            quantization_s: fitted.report.timing.evaluation_s,
            error_defined: offset_error(data, &grid, l),
            error_defined_float: offset_error(data, &fitted.grid, l),
            error_defined_8bit: offset_error(data, &grid8, l),
            lambda: fit_params.lambda,
            lambda_trials: trials,
            coef_excursion: excursion(&fitted.grid),
            fit: fitted.report,
        };
        Ok(Self {
            grid,
            mask: samples.mask.clone(),
            columns: l,
            rows: texture.rows(),
            report,
        })
    }

    /// The stored coefficients (dequantised) as a trilinear grid, for a 3D texture.
    pub fn grid(&self) -> &TrilinearGrid {
        &self.grid
    }

    /// The silhouette mask, when the texture has one.
    pub fn mask(&self) -> Option<&SilhouetteMask> {
        self.mask.as_ref()
    }

    /// The fitted offset `k̂` (texels) at screen abscissa `x` (units of `R`), continuous row
    /// coordinate `v` and camera angle `alpha`, and whether `x` lies inside the silhouette mask
    /// (always `true` without a mask): one trilinear fetch (plus one bilinear fetch of the mask),
    /// clamped to the range of the fitted samples.
    /// Outside the mask the fetch is clamped to its edge. `None` when the mask says the slice is
    /// empty.
    #[inline]
    pub fn offset(&self, x: f64, v: f64, alpha: f64) -> Option<(f64, bool)> {
        let (w_x, inside) = match &self.mask {
            None => (0.5 * (x + 1.0), true),
            Some(m) => {
                let (lo, hi) = m.interval(v, alpha)?;
                let w = if hi > lo { (x - lo) / (hi - lo) } else { 0.5 };
                (w.clamp(0.0, 1.0), (lo..=hi).contains(&x))
            }
        };
        let k = self.grid.eval([
            w_x,
            (v + 0.5) / self.rows as f64,
            (alpha / TAU).rem_euclid(1.0),
        ]);
        // With a fixed small λ the coefficients overshot the data (up to 17× its range on the
        // beetle, the source's 8-bit problem); the default λ rule keeps them within 2×, but
        // past ±L/2 a fetched offset would still wrap to the far side of the object. A clamp
        // to the fitted data's range is free in a shader.
        let data = &self.report.fit.data;
        Some((k.clamp(data.min, data.max), inside))
    }

    /// Renders `texture` as a shader would with this offset texture: per sub-sample one fetch
    /// gives `k̂`, hence the column `u = α/dα + k̂`; the point of the slice at `u` is validated
    /// (it must project within `tolerance_px` output pixels of the sub-sample) and, in hybrid
    /// mode, refined by at most `m` sector tests. `steps` of the result counts those tests.
    ///
    /// Errors: the texture is not the one fitted (size), bad render parameters.
    pub fn render(
        &self,
        texture: &CylindricalTexture,
        mode: OffsetMode,
        tolerance_px: f64,
        params: &CylinderRenderParams,
    ) -> Result<CylinderRender, CylinderError> {
        if (texture.columns(), texture.rows()) != (self.columns, self.rows) {
            return Err(CylinderError::InvalidParameter {
                name: "texture",
                value: format!("{} × {}", texture.columns(), texture.rows()),
                reason: "must be the size of the texture the offsets were fitted on",
            });
        }
        if tolerance_px.is_nan() || tolerance_px < 0.0 {
            return Err(CylinderError::InvalidParameter {
                name: "validation tolerance",
                value: tolerance_px.to_string(),
                reason: "must be ≥ 0",
            });
        }
        let tolerance = tolerance_px * 2.0 / params.width as f64;
        let cyl = texture.cylinder();
        let alpha = params.angle;
        render_rows(texture, params, true, |row, out, named| {
            let v = row_coordinate(row.y, &cyl, self.rows);
            let slice = texture.slice(v);
            let view = SliceView::new(&slice, alpha, RadiusModel::General);
            let mut steps = 0u64;
            for ((x, o), nm) in row.xs.iter().zip(out.iter_mut()).zip(named.iter_mut()) {
                let (f, u, n) = self.sample(&view, *x, v, mode, tolerance);
                *o = f;
                *nm = u;
                steps += u64::from(n);
            }
            (steps, row.xs.len() as u64)
        })
    }

    /// One screen sample of [`Self::render`]: at abscissa `x` (units of `R`) of the slice `view`
    /// (taken at continuous row `v`, seen from `view.alpha`), the fragment, the column the
    /// fetched (and, in hybrid mode, refined) offset names, and the sector tests of the
    /// refinement. `tolerance` is the validation tolerance in units of `R` (`tolerance_px·2/W`).
    /// Cost: one fetch, plus at most `m` sector tests in hybrid mode.
    pub fn sample(
        &self,
        view: &SliceView,
        x: f64,
        v: f64,
        mode: OffsetMode,
        tolerance: f64,
    ) -> (Option<Fragment>, Option<f64>, u32) {
        let Some((k, inside)) = self.offset(x, v, view.alpha) else {
            return (None, None, 0);
        };
        let u = offset_column(k, view.alpha, self.columns);
        if !inside {
            return (None, Some(u), 0);
        }
        let plain = || {
            view.point_at_column(u)
                .filter(|(xh, _)| (xh - x).abs() <= tolerance)
                .map(|(_, f)| f)
        };
        match mode {
            OffsetMode::Plain => (plain(), Some(u), 0),
            OffsetMode::Hybrid { steps: m } => {
                let (hit, n) = refine(view, x, u, m);
                let named = hit.map_or(u, |h| h.column);
                (hit.or_else(plain), Some(named), n)
            }
        }
    }
}

/// Hybrid refinement: Newton iterations along the ray's sectors, at most `m` sector tests. Start
/// at the sector holding the point that column `u` names (clamped to the sectors the ray
/// crosses); test it; if no visible edge covers `x`, extend the visible edge nearest `x` as a
/// line and jump to the sector where it reaches `x` ([`SliceView::sectors_to`]). Stops at the
/// first hit (an exact intersection with a front-facing edge), or when a tested sector has no
/// visible edge or the jump goes nowhere. On a smooth surface this converges in one or two
/// tests from a fit that is several sectors off, where a march would need as many tests as the
/// error (measured by [`super::evaluate`]).
fn refine(view: &SliceView, x: f64, u: f64, m: usize) -> (Option<Fragment>, u32) {
    let l = view.columns();
    let rs = ray_sectors(x, view.alpha, l);
    if rs.count == 0 || m == 0 {
        return (None, 0);
    }
    let named = view.sector_of_column(u.floor() as usize % l) as i64;
    // Position of the named sector along the march (0 = the first sector the ray meets).
    let along = ((named - rs.first) * rs.step).rem_euclid(l as i64) as usize;
    let mut n = if along < rs.count {
        along
    } else if along - rs.count < l - along {
        // Behind the last sector the ray crosses.
        rs.count - 1
    } else {
        0
    } as i64;
    for it in 0..m {
        let tests = it as u32 + 1;
        let s = sector_index(rs.first + rs.step * n, l);
        if let Some(f) = view.hit_in_sector(s, x) {
            return (Some(f), tests);
        }
        let Some(t) = view.sectors_to(s, x, rs.step) else {
            return (None, tests);
        };
        // `t ∉ [0, 1]` here (no hit): jump at least one sector toward `x`.
        let jump = if t >= 1.0 {
            t.floor().max(1.0)
        } else {
            t.floor().min(-1.0)
        };
        let next = (n + jump.clamp(-(l as f64), l as f64) as i64).clamp(0, rs.count as i64 - 1);
        if next == n {
            return (None, tests);
        }
        n = next;
    }
    (None, m as u32)
}
