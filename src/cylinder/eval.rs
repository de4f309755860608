//! Measurements against the ray-cast ground truth: image error, silhouette, offset error in
//! texels (near and away from discontinuities), cost (precompute, bytes, steps) per renderer,
//! and the sweep of the offset grid.
//!
//! Protocol: `angles` camera angles `α_n = (n + 0.37)·2π/angles` (never a capture column, never a
//! fine sample of the offset fit), images of `size × size` pixels with `k × k` sub-samples, the
//! same light as the truth. Image errors average the MSE over the angles before taking the PSNR.
//! Offset errors are over the sub-samples where exact inverse warping is defined: the column a
//! renderer read (or, for the fitted renderers, the column its offset named, after refinement)
//! against the column inverse warping read, wrapped, in texels. A sub-sample is **near** a
//! discontinuity when it lies within one pixel (`k` sub-samples) of a sub-sample where the exact
//! offset is undefined (silhouette) or jumps by more than [`EvalParams::jump_texels`] between
//! neighbouring sub-samples (occlusion boundary); the others are **away**.

use std::f64::consts::TAU;
use std::time::Instant;

use altrep_data_gen::{
    CylinderParams, Light, RgbaImage, Shape, Supersample, TruthParams, render_truth,
};
use serde::Serialize;

use super::CylinderError;
use super::bounds::{BoundsParams, BoundsReport, MarchBounds};
use super::coverage::{CoverageParams, CoverageReport, check_coverage, coverage};
use super::offset::{
    OffsetMode, OffsetParams, OffsetReport, OffsetSamples, OffsetTexture, sample_offsets,
};
use super::render::{CylinderRender, CylinderRenderParams, ExactMethod, render_exact};
use super::texture::{CylindricalTexture, RowPyramid};
use super::warp::{DrawOrder, RadiusModel};
use crate::metrics::{CompareOptions, compare, psnr_from_mse, silhouette_iou};
use crate::stats::ErrorStats;

/// Parameters of [`evaluate`] and [`sweep`].
#[derive(Clone, Debug, Serialize)]
pub struct EvalParams {
    /// Texture size and cylinder. Default 256 × 64, `R = 1`, `H = 2`.
    #[serde(skip)]
    pub texture: CylinderParams,
    /// Albedo prefilter of the capture (odd). Default 3.
    pub prefilter: usize,
    /// The offset fit. Default [`OffsetParams::default`].
    pub offset: OffsetParams,
    /// The coverage check run before anything else ([`check_coverage`]); below its threshold
    /// [`evaluate`] refuses the object (the same parameters give the silhouette figure). Default [`CoverageParams::default`].
    pub coverage: CoverageParams,
    /// The march bounds of the `bounded` row. Default [`BoundsParams::default`].
    pub bounds: BoundsParams,
    /// Camera angles. Default 8.
    pub angles: usize,
    /// Image size in pixels. Default 64.
    pub size: usize,
    /// Rays per pixel edge of the truth and the renderers ([`Supersample`]: `k × k` per pixel).
    /// Default 3.
    pub supersample: Supersample,
    /// Step budgets `m` of the hybrid rows. Default `[1, 2, 4]`.
    pub hybrid_steps: Vec<usize>,
    /// Validation tolerance of the fitted renderers, output pixels. Default 1.
    pub tolerance_px: f64,
    /// Offset jump between neighbouring sub-samples that marks an occlusion boundary (texels).
    /// Default 2.
    pub jump_texels: f64,
    /// Image sizes of the vertical-minification measurement ([`MinificationRow`]). Default
    /// `[32, 16, 8]`.
    pub minify_sizes: Vec<usize>,
    /// The light.
    #[serde(skip)]
    pub light: Light,
}

impl Default for EvalParams {
    fn default() -> Self {
        Self {
            texture: CylinderParams::default(),
            prefilter: 3,
            offset: OffsetParams::default(),
            coverage: CoverageParams::default(),
            bounds: BoundsParams::default(),
            angles: 8,
            size: 64,
            supersample: Supersample::of(3),
            hybrid_steps: vec![1, 2, 4],
            tolerance_px: 1.0,
            jump_texels: 2.0,
            minify_sizes: vec![32, 16, 8],
            light: Light::default(),
        }
    }
}

/// Error statistics of offsets, texels ([`ErrorStats`] conventions, plus the share above one
/// texel).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct OffsetError {
    /// Root mean square.
    pub rms: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Share of sub-samples wrong by more than one texel.
    pub share_above_one: f64,
    /// Sub-samples measured.
    pub count: usize,
}

impl OffsetError {
    fn of(errors: Vec<f64>) -> Self {
        let count = errors.len();
        if count == 0 {
            return Self::default();
        }
        let above = errors.iter().filter(|e| **e > 1.0).count() as f64 / count as f64;
        let stats = ErrorStats::of(errors);
        Self {
            rms: stats.rms,
            p99: stats.p99,
            share_above_one: above,
            count,
        }
    }
}

/// One renderer's row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct MethodRow {
    /// `mesh`, `direct-btf`, `direct-ftb`, `direct-simple`, `inverse`, `inverse-rgba8`,
    /// `fitted`, `hybrid-m<m>`, `bounded` (the exact march within [`MarchBounds`]).
    pub method: String,
    /// PSNR against the ground truth (dB; MSE averaged over the angles).
    pub psnr_db: f64,
    /// PSNR against exact inverse warping (dB; infinite when identical).
    pub psnr_vs_inverse_db: f64,
    /// Mean silhouette IoU against the ground truth (alpha > ½).
    pub iou: f64,
    /// Offset error over every sub-sample where the exact offset is defined.
    pub offset: OffsetError,
    /// The same, away from discontinuities.
    pub offset_away: OffsetError,
    /// The same, near discontinuities.
    pub offset_near: OffsetError,
    /// Mean sector tests per sub-sample (inverse warping, hybrid refinement; 0 for one fetch);
    /// `None` for the mesh and direct warping.
    pub mean_steps: Option<f64>,
    /// Mean writes per sub-sample (overdraw of direct warping, depth-test passes of the mesh).
    pub mean_writes: f64,
    /// Precompute: capture (+ sampling, assembly and solve of the offsets), milliseconds.
    pub precompute_ms: f64,
    /// Bytes: texture (+ offset coefficients).
    pub bytes: usize,
    /// Mean CPU render time per image (ms, this machine, not a shader's).
    pub render_ms: f64,
}

impl MethodRow {
    /// The JSON object of the CLI: `method, psnr_db, iou, offset_rms_texels, offset_p99_texels,
    /// mean_steps, precompute_ms, bytes`, plus the near/away split and PSNR against inverse
    /// warping.
    pub fn json(&self) -> serde_json::Value {
        let finite = |v: f64| if v.is_finite() { Some(v) } else { None };
        serde_json::json!({
            "method": self.method,
            "psnr_db": finite(self.psnr_db),
            "iou": self.iou,
            "offset_rms_texels": self.offset.rms,
            "offset_p99_texels": self.offset.p99,
            "mean_steps": self.mean_steps,
            "precompute_ms": self.precompute_ms,
            "bytes": self.bytes,
            "psnr_vs_inverse_db": finite(self.psnr_vs_inverse_db),
            "offset_share_above_one_texel": self.offset.share_above_one,
            "offset_rms_texels_away": self.offset_away.rms,
            "offset_p99_texels_away": self.offset_away.p99,
            "offset_rms_texels_near": self.offset_near.rms,
            "offset_p99_texels_near": self.offset_near.p99,
            "near_share": self.offset_near.count as f64
                / (self.offset.count.max(1)) as f64,
            "mean_writes": self.mean_writes,
            "render_ms": self.render_ms,
        })
    }
}

/// Everything [`evaluate`] measured on one shape.
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    /// Shape name.
    pub shape: String,
    /// Texture columns and rows.
    pub texture_size: [usize; 2],
    /// Share of defined texels.
    pub coverage: f64,
    /// Share of defined texels with a negative radius.
    pub negative_share: f64,
    /// Capture time (ms).
    pub capture_ms: f64,
    /// The coverage check: share of the visible surface the radial capture rays hold
    /// ([`super::radial_visibility`]), whatever the texture size.
    pub held: CoverageReport,
    /// Share of the true silhouette this texture reproduces ([`coverage`]; a figure).
    pub silhouette: CoverageReport,
    /// The march bounds of the `bounded` row.
    pub bounds: BoundsReport,
    /// Texture bytes (two RGBA8 textures).
    pub texture_bytes: usize,
    /// The offset precomputation (split times, fit report).
    pub offset: OffsetReport,
    /// One row per renderer.
    pub rows: Vec<MethodRow>,
    /// Vertical minification with and without the row pyramid.
    pub minification: Vec<MinificationRow>,
}

/// Vertical minification at one image size: exact inverse warping with one sample per pixel (as
/// a shader draws), from the full texture and from the pyramid level chosen for the size,
/// against the 4 × 4 supersampled ground truth (MSE averaged over the angles).
#[derive(Clone, Debug, Serialize)]
pub struct MinificationRow {
    /// Image size (pixels, square).
    pub size: usize,
    /// Pyramid level chosen ([`RowPyramid::level_for`]).
    pub level: usize,
    /// Rows of that level.
    pub rows: usize,
    /// PSNR reading level 0 (dB).
    pub psnr_level0_db: f64,
    /// PSNR reading the chosen level (dB).
    pub psnr_pyramid_db: f64,
}

/// Measures vertical minification (see [`MinificationRow`]). Cost: per size and angle one
/// ground-truth image (16 rays per pixel) and two inverse warps.
pub fn minification(
    shape: &dyn Shape,
    texture: &CylindricalTexture,
    params: &EvalParams,
) -> Result<Vec<MinificationRow>, CylinderError> {
    let pyramid = RowPyramid::build(texture)?;
    params
        .minify_sizes
        .iter()
        .map(|&size| {
            let level = pyramid.level_for(size);
            let (mut mse0, mut mse) = (0.0, 0.0);
            for n in 0..params.angles {
                let angle = (n as f64 + 0.37) * TAU / params.angles as f64;
                let truth = render_truth(
                    shape,
                    &TruthParams {
                        angle,
                        width: size,
                        height: size,
                        supersample: Supersample::of(4),
                        light: params.light,
                        cylinder: texture.cylinder(),
                    },
                )?;
                let p = CylinderRenderParams {
                    angle,
                    width: size,
                    height: size,
                    supersample: Supersample::ONE,
                    light: params.light,
                };
                let m = ExactMethod::Inverse(RadiusModel::General);
                for (tex, acc) in [(texture, &mut mse0), (&pyramid.levels()[level], &mut mse)] {
                    let e = compare(
                        &render_exact(tex, m, &p)?.image,
                        &truth,
                        &CompareOptions::default(),
                    )?;
                    *acc += e.rmse * e.rmse;
                }
            }
            let a = params.angles.max(1) as f64;
            Ok(MinificationRow {
                size,
                level,
                rows: pyramid.levels()[level].rows(),
                psnr_level0_db: psnr_from_mse(mse0 / a),
                psnr_pyramid_db: psnr_from_mse(mse / a),
            })
        })
        .collect()
}

impl EvalReport {
    /// The row of `method`, if measured.
    pub fn row(&self, method: &str) -> Option<&MethodRow> {
        self.rows.iter().find(|r| r.method == method)
    }

    /// A Markdown table of the rows.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "**{}** — capture rays hold {:.1} % of the visible surface; texture {}×{} ({:.1} % \
             defined, {:.1} % negative radii, {:.1} % of the true silhouette reproduced), \
             capture {:.0} ms; \
             offsets {}×{}×{} cells ({} coefficients, {} B with the mask): sampling {:.0} ms, \
             assembly {:.1} ms, solve {:.1} ms, quantisation {:.1} ms, {} of {} samples fitted; \
             λ = {:.1e} ({} tried), coefficients {:.1}…{:.1} for data {:.1}…{:.1} ({:.2}× the \
             half range), offset RMS {:.2} float / {:.2} stored / {:.2} at 8 bits; march bounds \
             {}×{}×{} cells, {} B, mean span {:.1}, built in {:.0} ms\n\n",
            self.shape,
            100.0 * self.held.share,
            self.texture_size[0],
            self.texture_size[1],
            100.0 * self.coverage,
            100.0 * self.negative_share,
            100.0 * self.silhouette.share,
            self.capture_ms,
            self.offset.params.cells[0],
            self.offset.params.cells[1],
            self.offset.params.cells[2],
            self.offset.nodes,
            self.offset.bytes,
            self.offset.sampling_s * 1e3,
            self.offset.assembly_s * 1e3,
            self.offset.solve_s * 1e3,
            self.offset.quantization_s * 1e3,
            self.offset.fitted,
            self.offset.defined,
            self.offset.lambda,
            self.offset.lambda_trials.len().max(1),
            self.offset.fit.coef_min,
            self.offset.fit.coef_max,
            self.offset.fit.data.min,
            self.offset.fit.data.max,
            self.offset.coef_excursion,
            self.offset.error_defined_float.rms,
            self.offset.error_defined.rms,
            self.offset.error_defined_8bit.rms,
            self.bounds.cells[0],
            self.bounds.cells[1],
            self.bounds.cells[2],
            self.bounds.bytes,
            self.bounds.mean_span,
            self.bounds.build_s * 1e3,
        );
        s += "| method | PSNR dB | vs inverse dB | IoU | offset RMS / p99 (texels) | away RMS / p99 | near RMS / p99 | >1 texel | steps | precompute ms | bytes |\n";
        s += "|---|---|---|---|---|---|---|---|---|---|---|\n";
        for r in &self.rows {
            s += &format!(
                "| {} | {:.2} | {} | {:.4} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} % | {} | {:.0} | {} |\n",
                r.method,
                r.psnr_db,
                if r.psnr_vs_inverse_db.is_finite() {
                    format!("{:.2}", r.psnr_vs_inverse_db)
                } else {
                    "=".into()
                },
                r.iou,
                r.offset.rms,
                r.offset.p99,
                r.offset_away.rms,
                r.offset_away.p99,
                r.offset_near.rms,
                r.offset_near.p99,
                100.0 * r.offset.share_above_one,
                r.mean_steps.map_or("–".into(), |s| format!("{s:.1}")),
                r.precompute_ms,
                r.bytes,
            );
        }
        if !self.minification.is_empty() {
            s += "\nVertical minification (inverse warping, 1 sample per pixel, vs 4×4 truth):\n\n\
                  | size | level (rows) | PSNR level 0 dB | PSNR pyramid dB |\n|---|---|---|---|\n";
            for m in &self.minification {
                s += &format!(
                    "| {0}² | {1} ({2}) | {3:.2} | {4:.2} |\n",
                    m.size, m.level, m.rows, m.psnr_level0_db, m.psnr_pyramid_db
                );
            }
        }
        s
    }
}

/// The references every renderer is compared with, per angle.
struct References {
    params: Vec<CylinderRenderParams>,
    truth: Vec<RgbaImage>,
    inverse: Vec<CylinderRender>,
    /// Per sub-sample: `Some(near)` where the exact offset is defined.
    near: Vec<Vec<Option<bool>>>,
    inverse_ms: f64,
}

impl References {
    fn new(
        shape: &dyn Shape,
        texture: &CylindricalTexture,
        p: &EvalParams,
    ) -> Result<Self, CylinderError> {
        if p.angles == 0 {
            return Err(CylinderError::ZeroSize {
                what: "evaluation angles",
            });
        }
        let params: Vec<CylinderRenderParams> = (0..p.angles)
            .map(|n| CylinderRenderParams {
                angle: (n as f64 + 0.37) * TAU / p.angles as f64,
                width: p.size,
                height: p.size,
                supersample: p.supersample,
                light: p.light,
            })
            .collect();
        let truth = params
            .iter()
            .map(|r| {
                render_truth(
                    shape,
                    &TruthParams {
                        angle: r.angle,
                        width: r.width,
                        height: r.height,
                        supersample: r.supersample,
                        light: r.light,
                        cylinder: texture.cylinder(),
                    },
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        let t0 = Instant::now();
        let inverse = params
            .iter()
            .map(|r| render_exact(texture, ExactMethod::Inverse(RadiusModel::General), r))
            .collect::<Result<Vec<_>, _>>()?;
        let inverse_ms = t0.elapsed().as_secs_f64() * 1e3 / params.len() as f64;
        let near = inverse
            .iter()
            .map(|r| near_discontinuity(r, texture.columns(), p.jump_texels, p.supersample.get()))
            .collect();
        Ok(Self {
            params,
            truth,
            inverse,
            near,
            inverse_ms,
        })
    }

    /// Measures one renderer: `render(params)` for every angle.
    fn measure(
        &self,
        method: &str,
        columns: usize,
        precompute_ms: f64,
        bytes: usize,
        render: impl Fn(&CylinderRenderParams) -> Result<CylinderRender, CylinderError>,
    ) -> Result<MethodRow, CylinderError> {
        let (mut mse, mut mse_inv, mut iou) = (0.0, 0.0, 0.0);
        let (mut all, mut away, mut near) = (Vec::new(), Vec::new(), Vec::new());
        let (mut steps, mut writes, mut samples, mut ms) = (0u64, 0u64, 0usize, 0.0);
        let mut has_steps = false;
        for (n, p) in self.params.iter().enumerate() {
            let t0 = Instant::now();
            let r = if method == "inverse" {
                self.inverse[n].clone()
            } else {
                render(p)?
            };
            ms += if method == "inverse" {
                self.inverse_ms
            } else {
                t0.elapsed().as_secs_f64() * 1e3
            };
            let e = compare(&r.image, &self.truth[n], &CompareOptions::default())?;
            mse += e.rmse * e.rmse;
            let e = compare(&r.image, &self.inverse[n].image, &CompareOptions::default())?;
            mse_inv += e.rmse * e.rmse;
            iou += silhouette_iou(&r.image, &self.truth[n], 0.5)?;
            steps += r.steps;
            has_steps |= r.steps > 0 || !r.named.is_empty();
            writes += r.writes;
            samples += r.fragments.len();
            for (s, exact) in self.inverse[n].fragments.iter().enumerate() {
                let (Some(exact), Some(is_near)) = (exact, self.near[n][s]) else {
                    continue;
                };
                let read = if r.named.is_empty() {
                    r.fragments[s].map(|f| f.column)
                } else {
                    r.named[s]
                };
                let Some(read) = read else {
                    continue;
                };
                let l = columns as f64;
                let d = (read - exact.column).rem_euclid(l);
                let e = d.min(l - d);
                all.push(e);
                if is_near {
                    near.push(e);
                } else {
                    away.push(e);
                }
            }
        }
        let a = self.params.len() as f64;
        let is_inverse = method.starts_with("inverse");
        Ok(MethodRow {
            method: method.to_string(),
            psnr_db: psnr_from_mse(mse / a),
            psnr_vs_inverse_db: psnr_from_mse(mse_inv / a),
            iou: iou / a,
            offset: OffsetError::of(all),
            offset_away: OffsetError::of(away),
            offset_near: OffsetError::of(near),
            mean_steps: (has_steps || is_inverse).then(|| steps as f64 / samples as f64),
            mean_writes: writes as f64 / samples as f64,
            precompute_ms,
            bytes,
            render_ms: ms / a,
        })
    }
}

/// Marks, per sub-sample where the exact offset is defined, whether it is near a discontinuity
/// (see the module docs).
fn near_discontinuity(
    inverse: &CylinderRender,
    columns: usize,
    jump: f64,
    reach: usize,
) -> Vec<Option<bool>> {
    let (w, h) = (inverse.sub_width, inverse.sub_height);
    let l = columns as f64;
    let col = |i: usize, j: usize| inverse.fragments[j * w + i].map(|f| f.column);
    let mut edge = vec![false; w * h];
    for j in 0..h {
        for i in 0..w {
            let Some(c) = col(i, j) else { continue };
            let neighbours = [
                (i > 0).then(|| (i - 1, j)),
                (i + 1 < w).then(|| (i + 1, j)),
                (j > 0).then(|| (i, j - 1)),
                (j + 1 < h).then(|| (i, j + 1)),
            ];
            edge[j * w + i] = neighbours.into_iter().flatten().any(|(a, b)| {
                col(a, b).is_none_or(|d| {
                    let diff = (c - d).rem_euclid(l);
                    diff.min(l - diff) > jump
                })
            });
        }
    }
    // Dilate by `reach` sub-samples (separable max filter).
    let dilate = |src: &[bool], horizontal: bool| -> Vec<bool> {
        (0..w * h)
            .map(|n| {
                let (i, j) = (n % w, n / w);
                let (p, len) = if horizontal { (i, w) } else { (j, h) };
                let lo = p.saturating_sub(reach);
                let hi = (p + reach).min(len - 1);
                (lo..=hi).any(|q| {
                    if horizontal {
                        src[j * w + q]
                    } else {
                        src[q * w + i]
                    }
                })
            })
            .collect()
    };
    let near = dilate(&dilate(&edge, true), false);
    (0..w * h)
        .map(|n| inverse.fragments[n].map(|_| near[n]))
        .collect()
}

/// Checks that radial capture rays hold enough of `shape`'s visible surface ([`check_coverage`];
/// [`CylinderError::NotRepresentable`] or [`CylinderError::NothingVisible`] otherwise; the
/// planner's check, with the same answer), captures it, fits
/// its offsets, builds its march bounds and measures every renderer against the ground truth
/// (see the module docs). Cost: the capture (`L·Ly·prefilter²` rays), `angles` ground-truth images,
/// the offset sampling and fit, and `angles` images per renderer.
pub fn evaluate(shape: &dyn Shape, params: &EvalParams) -> Result<EvalReport, CylinderError> {
    let held = check_coverage(shape, params.texture.cylinder, &params.coverage)?;
    let t0 = Instant::now();
    let texture = CylindricalTexture::capture(shape, &params.texture, params.prefilter)?;
    let capture_ms = t0.elapsed().as_secs_f64() * 1e3;
    let silhouette = coverage(shape, &texture, &params.coverage)?;
    let offsets = OffsetTexture::fit(&texture, &params.offset)?;
    let (bounds, bounds_report) = MarchBounds::build(&texture, &params.bounds)?;
    let refs = References::new(shape, &texture, params)?;
    let l = texture.columns();
    let tex_bytes = texture.storage_bytes();
    let mut rows = Vec::new();
    let exact = [
        ExactMethod::Mesh,
        ExactMethod::Direct(DrawOrder::BackToFront, RadiusModel::General),
        ExactMethod::Direct(DrawOrder::FrontToBack, RadiusModel::General),
        ExactMethod::Direct(DrawOrder::BackToFront, RadiusModel::Simple),
        ExactMethod::Inverse(RadiusModel::General),
    ];
    for m in exact {
        rows.push(refs.measure(m.name(), l, capture_ms, tex_bytes, |p| {
            render_exact(&texture, m, p)
        })?);
    }
    let q8 = texture.quantized_rgba8();
    rows.push(
        refs.measure("inverse-rgba8", l, capture_ms, tex_bytes, |p| {
            render_exact(&q8, ExactMethod::Inverse(RadiusModel::General), p)
        })?,
    );
    let pre = capture_ms + offsets.report.precompute_ms();
    let bytes = tex_bytes + offsets.report.bytes;
    let modes = std::iter::once(OffsetMode::Plain).chain(
        params
            .hybrid_steps
            .iter()
            .map(|&steps| OffsetMode::Hybrid { steps }),
    );
    for mode in modes {
        rows.push(refs.measure(&mode.name(), l, pre, bytes, |p| {
            offsets.render(&texture, mode, params.tolerance_px, p)
        })?);
    }
    rows.push(refs.measure(
        "bounded",
        l,
        capture_ms + bounds_report.build_s * 1e3,
        tex_bytes + bounds_report.bytes,
        |p| bounds.render(&texture, p),
    )?);
    let minification = minification(shape, &texture, params)?;
    Ok(EvalReport {
        shape: shape.name().to_string(),
        texture_size: [texture.columns(), texture.rows()],
        coverage: texture.coverage(),
        negative_share: texture.negative_share(),
        capture_ms,
        held,
        silhouette,
        bounds: bounds_report,
        texture_bytes: tex_bytes,
        offset: offsets.report,
        rows,
        minification,
    })
}

/// One grid of the sweep.
#[derive(Clone, Debug, Serialize)]
pub struct CylinderSweepRow {
    /// `[Ax, Ay, Aα]`.
    pub cells: [usize; 3],
    /// Coefficients.
    pub nodes: usize,
    /// Offset bytes.
    pub bytes: usize,
    /// Sampling (shared by every grid of the sweep), assembly and solve, milliseconds.
    pub sampling_ms: f64,
    /// Assembly (ms).
    pub assembly_ms: f64,
    /// Solve (ms).
    pub solve_ms: f64,
    /// Quantisation to 16 bits (ms).
    pub quantization_ms: f64,
    /// Solver iterations.
    pub iterations: usize,
    /// Fit RMS over the fine samples where `k` is defined (texels).
    pub fit_rms: f64,
    /// Plain fitted offsets at the evaluation sub-samples.
    pub plain: MethodRow,
    /// Hybrid with `m = 2`.
    pub hybrid: MethodRow,
}

/// The default sweep of the offset grid, from 8×4×8 to 31×16×32.
pub const SWEEP_GRIDS: [[usize; 3]; 5] = [
    [8, 4, 8],
    [11, 6, 12],
    [15, 8, 16],
    [23, 12, 24],
    [31, 16, 32],
];

/// Fits the offsets of `shape` on each grid (one shared sampling) and measures the plain and
/// hybrid (`m = 2`) renderers as [`evaluate`] does. Cost: one capture, one sampling, one fit and
/// `2·angles` images per grid.
pub fn sweep(
    shape: &dyn Shape,
    params: &EvalParams,
    grids: &[[usize; 3]],
) -> Result<Vec<CylinderSweepRow>, CylinderError> {
    let texture = CylindricalTexture::capture(shape, &params.texture, params.prefilter)?;
    let samples: OffsetSamples =
        sample_offsets(&texture, params.offset.samples, params.offset.mask)?;
    let refs = References::new(shape, &texture, params)?;
    let l = texture.columns();
    grids
        .iter()
        .map(|&cells| {
            let op = OffsetParams {
                cells,
                ..params.offset
            };
            let off = OffsetTexture::fit_samples(&texture, &samples, &op)?;
            let pre = off.report.precompute_ms();
            let bytes = off.report.bytes;
            let measure = |mode: OffsetMode| {
                refs.measure(&mode.name(), l, pre, bytes, |p| {
                    off.render(&texture, mode, params.tolerance_px, p)
                })
            };
            Ok(CylinderSweepRow {
                cells,
                nodes: off.report.nodes,
                bytes,
                sampling_ms: off.report.sampling_s * 1e3,
                assembly_ms: off.report.assembly_s * 1e3,
                solve_ms: off.report.solve_s * 1e3,
                quantization_ms: off.report.quantization_s * 1e3,
                iterations: off.report.fit.solver.iterations,
                fit_rms: off.report.error_defined.rms,
                plain: measure(OffsetMode::Plain)?,
                hybrid: measure(OffsetMode::Hybrid { steps: 2 })?,
            })
        })
        .collect()
}

/// A Markdown table of a sweep.
pub fn sweep_markdown(shape: &str, rows: &[CylinderSweepRow]) -> String {
    let mut s = format!(
        "**{shape}** — offset grid sweep (sampling {:.0} ms shared)\n\n| grid | coefficients | bytes | assembly ms | solve ms | quantisation ms | iterations | fit RMS | offset RMS / p99 | away RMS | near RMS | PSNR plain | PSNR hybrid m=2 | vs inverse (plain / m=2) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        rows.first().map_or(0.0, |r| r.sampling_ms)
    );
    for r in rows {
        s += &format!(
            "| {}×{}×{} | {} | {} | {:.1} | {:.1} | {:.1} | {} | {:.2} | {:.2} / {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} / {:.2} |\n",
            r.cells[0],
            r.cells[1],
            r.cells[2],
            r.nodes,
            r.bytes,
            r.assembly_ms,
            r.solve_ms,
            r.quantization_ms,
            r.iterations,
            r.fit_rms,
            r.plain.offset.rms,
            r.plain.offset.p99,
            r.plain.offset_away.rms,
            r.plain.offset_near.rms,
            r.plain.psnr_db,
            r.hybrid.psnr_db,
            r.plain.psnr_vs_inverse_db,
            r.hybrid.psnr_vs_inverse_db,
        );
    }
    s
}
