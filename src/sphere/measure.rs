//! Measurement against the ray-cast ground truth over many directions, and the memory-against-
//! PSNR table.

use std::time::Instant;

use altrep_data_gen::{OrthoFrame, RgbaImage, Shape, Supersample, render_truth_frame};
use glam::DVec3;
use rayon::prelude::*;

use super::baseline::{EngineSteps, render_engine};
use super::compress::{Storage, compress};
use super::warp::{RenderOutput, SphereRenderParams, render};
use super::{Coverage, SphereError, SphereImages, SphereParams, check};
use crate::metrics::{
    ErrorSplit, MetricsError, colour_psnr, coverage_error, error_split, flip_mean, psnr,
    silhouette_iou,
};

/// `n` directions spread evenly over the upper hemisphere or the sphere (Fibonacci spiral:
/// heights uniform, azimuths stepped by the golden angle). Elevations stay strictly inside
/// `(0°, 90°)` for the hemisphere.
pub fn fibonacci_directions(n: usize, coverage: Coverage) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let u = (i as f64 + 0.5) / n as f64;
            let y = match coverage {
                Coverage::Hemisphere => u,
                Coverage::Sphere => 1.0 - 2.0 * u,
            };
            let r = (1.0 - y * y).max(0.0).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), y, r * phi.sin())
        })
        .collect()
}

/// What is measured and how.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SphereMeasureParams {
    /// Test directions (Fibonacci spiral over the view set's coverage).
    pub directions: usize,
    /// How both methods draw (size, samples per pixel, thresholds, light).
    pub render: SphereRenderParams,
    /// Rays per pixel edge of the ground truth ([`Supersample`]: `k × k` per pixel).
    pub truth_supersample: Supersample,
}

impl Default for SphereMeasureParams {
    /// 100 directions, 128² with 2 × 2 rays per pixel, truth 4 × 4.
    fn default() -> Self {
        Self {
            directions: 100,
            render: SphereRenderParams {
                supersample: Supersample::of(2),
                ..SphereRenderParams::default()
            },
            truth_supersample: Supersample::of(4),
        }
    }
}

/// Error and cost of one method over the test directions.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct MethodStats {
    /// Mean PSNR (dB) over the directions.
    pub psnr_mean: f64,
    /// Lowest PSNR of a direction.
    pub psnr_min: f64,
    /// Mean silhouette IoU (alpha > ½).
    pub iou_mean: f64,
    /// Mean coverage error ([`coverage_error`]: mean absolute alpha difference over the pixels
    /// either picture covers).
    pub coverage_error_mean: f64,
    /// Mean colour PSNR (dB) over the directions ([`crate::metrics::colour_psnr`]: the colour
    /// error alone, over the pixels both the picture and the truth cover fully), over the
    /// directions that have such pixels; `None` where none has (thin or sparse objects at a
    /// small size).
    pub colour_psnr_mean: Option<f64>,
    /// Mean FLIP error over the directions ([`crate::metrics::flip_mean`]: in `[0, 1]`, lower
    /// is better; what a viewer flipping between the picture and the truth sees).
    pub flip_mean: f64,
    /// Mean PSNR (dB) against a truth cast at the drawing's own rays (the same sub-pixel
    /// positions, `render.supersample`), where one was given: the error left once the
    /// difference between the truth's and the drawing's sampling is taken out. A drawing that
    /// finds the truth's colour on every ray scores infinity here, not against the truth cast
    /// with more rays.
    pub psnr_same_positions_mean: Option<f64>,
    /// Mean texel fetches per ray (all enclosing frames together).
    pub steps_mean: f64,
    /// Largest texel fetches of one ray.
    pub steps_max: u32,
    /// Mean texel reads per ray, every read counted ([`super::RenderOutput::reads`]: the march,
    /// the bounds, colour and normal; the baseline's bilinear reads), over the rays inside the
    /// bounding sphere's disc.
    pub reads_mean: f64,
    /// The same over the rays that found a surface.
    pub reads_hit_mean: f64,
    /// Largest texel reads of one ray.
    pub reads_max: u32,
    /// Mean wall time of one image (ms, CPU, all cores).
    pub ms_per_image: f64,
    /// Rays whose surface point no frame sees, per ray (exact warp only).
    pub hole_share: f64,
    /// Rays unresolved after the carving rounds, per ray (exact warp only).
    pub unresolved_share: f64,
    /// Rays stopped by the cap on fetches, per ray (exact warp with
    /// [`SphereRenderParams::max_steps`] only).
    pub capped_share: f64,
    /// PSNR (dB) of each direction, in the order measured.
    pub psnr_per_direction: Vec<f64>,
    /// Share of rays whose surface point no frame sees, per direction (exact warp only).
    pub holes_per_direction: Vec<f64>,
    /// Where the error lies, by distance to the true silhouette (outline band, interior,
    /// false coverage outside, alpha bias), averaged over the directions.
    pub split: ErrorSplit,
}

/// One configuration (grid and frame size) measured for both methods.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SphereMeasurement {
    /// Frames per side `G`.
    pub grid: usize,
    /// Texels per frame side `F`.
    pub size: usize,
    /// How the frames were held when counted and drawn.
    pub storage: Storage,
    /// Bytes of the exact warp (frames and bounds) in that storage.
    pub bytes_ours: usize,
    /// Bytes of the engine baseline (frames only) in that storage.
    pub bytes_baseline: usize,
    /// Block compression and decoding of both layouts (s; zero for raw storage).
    pub encode_s: f64,
    /// Capture and quantisation time (s).
    pub capture_s: f64,
    /// Cone bounds time (s; for compressed storage, the bounds built again from the decoded
    /// frames).
    pub bounds_s: f64,
    /// Mean stored bound interval (frame depth units, texels where an event is possible).
    pub bound_interval: f64,
    /// The exact warp.
    pub ours: MethodStats,
    /// The engine baseline (one-step offset, padded depth: [`render_engine_baseline`](super::render_engine_baseline)).
    pub baseline: MethodStats,
    /// The engine baseline with the two-step offset.
    pub baseline_two_step: MethodStats,
    /// The directions measured (unit, toward the camera).
    pub directions: Vec<[f64; 3]>,
}

/// The ground truth of `shape` along each direction (`size²`, `k × k` rays per pixel), over the
/// same bounding sphere as the frames. Cost: `directions × size² × k²` rays.
pub fn truth_images(
    shape: &dyn Shape,
    directions: &[DVec3],
    size: usize,
    supersample: Supersample,
    light: &altrep_data_gen::Light,
) -> Result<Vec<RgbaImage>, SphereError> {
    let (centre, radius) = OrthoFrame::bounding_sphere(shape);
    directions
        .iter()
        .map(|&d| {
            let f = OrthoFrame::new(centre, radius, d)?;
            Ok(render_truth_frame(
                shape,
                &f,
                size,
                size,
                supersample,
                light,
            )?)
        })
        .collect()
}

/// A metric's error for the pictures along `dir` (`size²`): nothing to compare there (the
/// metric's [`MetricsError::NothingVisible`]) is named by its direction
/// ([`SphereError::EmptyView`], `what` saying what was missing beyond any pixel at all).
fn along(dir: DVec3, size: usize, what: &'static str, e: MetricsError) -> SphereError {
    match e {
        MetricsError::NothingVisible => SphereError::EmptyView {
            elevation_deg: dir.y.clamp(-1.0, 1.0).asin().to_degrees(),
            azimuth_deg: dir.z.atan2(dir.x).to_degrees(),
            size,
            what,
        },
        e => e.into(),
    }
}

fn stats(
    outs: &[(RenderOutput, f64)],
    directions: &[DVec3],
    truths: &[RgbaImage],
    same_positions: Option<&[RgbaImage]>,
) -> Result<MethodStats, SphereError> {
    let mut s = MethodStats {
        psnr_min: f64::INFINITY,
        ..Default::default()
    };
    let at = |k: usize| {
        let size = truths[k].width;
        move |e| along(directions[k], size, "", e)
    };
    if let Some(same) = same_positions {
        let mut sum = 0.0;
        for (k, ((out, _), truth)) in outs.iter().zip(same).enumerate() {
            sum += psnr(&out.image, truth).map_err(at(k))?;
        }
        s.psnr_same_positions_mean = Some(sum / outs.len().max(1) as f64);
    }
    let (mut rays, mut steps, mut holes, mut unresolved) = (0usize, 0.0f64, 0usize, 0usize);
    let mut capped = 0usize;
    let (mut reads, mut hit_reads, mut hits) = (0.0f64, 0.0f64, 0usize);
    let mut colour = (0.0f64, 0u32);
    // FLIP, the costliest figure (its spatial filters), over the directions in parallel.
    let flips: Vec<f64> = outs
        .par_iter()
        .zip(truths)
        .enumerate()
        .map(|(k, ((out, _), truth))| flip_mean(&out.image, truth).map_err(at(k)))
        .collect::<Result<_, _>>()?;
    s.flip_mean = flips.iter().sum();
    for (k, ((out, ms), truth)) in outs.iter().zip(truths).enumerate() {
        let p = psnr(&out.image, truth).map_err(at(k))?;
        s.psnr_per_direction.push(p);
        s.holes_per_direction
            .push(out.holes as f64 / out.steps.len().max(1) as f64);
        s.psnr_mean += p;
        s.psnr_min = s.psnr_min.min(p);
        // Both silhouettes empty (no pixel covered by more than half) where the pictures are
        // not.
        s.iou_mean += silhouette_iou(&out.image, truth, 0.5)
            .map_err(|e| along(directions[k], truth.width, " by more than half", e))?;
        s.coverage_error_mean += coverage_error(&out.image, truth).map_err(at(k))?;
        match colour_psnr(&out.image, truth) {
            Ok(p) => {
                colour.0 += p;
                colour.1 += 1;
            }
            Err(MetricsError::NothingToCompare) => {}
            Err(e) => return Err(e.into()),
        }
        s.split.add(&error_split(&out.image, truth).map_err(at(k))?);
        steps += out.steps.iter().map(|&v| f64::from(v)).sum::<f64>();
        rays += out.steps.len();
        s.steps_max = s.steps_max.max(out.max_steps());
        reads += out.reads.iter().map(|&v| f64::from(v)).sum::<f64>();
        for (&r, &h) in out.reads.iter().zip(&out.hit) {
            if h {
                hit_reads += f64::from(r);
                hits += 1;
            }
        }
        s.reads_max = s.reads_max.max(out.max_reads());
        s.ms_per_image += ms;
        holes += out.holes;
        unresolved += out.unresolved;
        capped += out.capped;
    }
    let n = outs.len().max(1) as f64;
    s.psnr_mean /= n;
    s.iou_mean /= n;
    s.coverage_error_mean /= n;
    s.flip_mean /= n;
    s.colour_psnr_mean = (colour.1 > 0).then(|| colour.0 / f64::from(colour.1));
    s.split.scale(1.0 / n);
    s.ms_per_image /= n;
    s.steps_mean = steps / rays.max(1) as f64;
    s.reads_mean = reads / rays.max(1) as f64;
    s.reads_hit_mean = hit_reads / hits.max(1) as f64;
    s.hole_share = holes as f64 / rays.max(1) as f64;
    s.unresolved_share = unresolved as f64 / rays.max(1) as f64;
    s.capped_share = capped as f64 / rays.max(1) as f64;
    Ok(s)
}

/// Each direction's drawing by `draw`, with its time (ms).
fn timed(
    directions: &[DVec3],
    draw: &dyn Fn(DVec3) -> Result<RenderOutput, SphereError>,
) -> Result<Vec<(RenderOutput, f64)>, SphereError> {
    directions
        .iter()
        .map(|&d| {
            let t = Instant::now();
            let out = draw(d)?;
            Ok((out, t.elapsed().as_secs_f64() * 1e3))
        })
        .collect()
}

/// The exact warp's and the one-step engine baseline's figures of [`measure`], without the
/// two-step baseline: what a caller choosing between them needs. Same arguments, errors and
/// figures; two drawings per direction instead of three.
pub fn measure_one_step(
    images: &SphereImages,
    directions: &[DVec3],
    truths: &[RgbaImage],
    same_positions: Option<&[RgbaImage]>,
    params: &SphereMeasureParams,
) -> Result<(MethodStats, MethodStats), SphereError> {
    measure_pair(images, images, directions, truths, same_positions, params)
}

/// The exact warp drawn from `warp` and the one-step baseline from `baseline` (the same frames,
/// or each method's decoding of them), with the arguments checked.
fn measure_pair(
    warp: &SphereImages,
    baseline: &SphereImages,
    directions: &[DVec3],
    truths: &[RgbaImage],
    same_positions: Option<&[RgbaImage]>,
    params: &SphereMeasureParams,
) -> Result<(MethodStats, MethodStats), SphereError> {
    check(
        directions.len() == truths.len() && !directions.is_empty(),
        "truth images",
        truths.len(),
        "need one per direction, and at least one direction",
    )?;
    if let Some(same) = same_positions {
        check(
            same.len() == directions.len(),
            "truth images at the drawing's positions",
            same.len(),
            "need one per direction",
        )?;
    }
    let ours = timed(directions, &|d| render(warp, d, &params.render))?;
    let base = timed(directions, &|d| {
        render_engine(baseline, d, &params.render, EngineSteps::One)
    })?;
    Ok((
        stats(&ours, directions, truths, same_positions)?,
        stats(&base, directions, truths, same_positions)?,
    ))
}

/// Measures `images` (exact warp) and the engine baseline built from the same frames along
/// `directions`, against `truths` (from [`truth_images`] at `params.render.size`), and, where
/// given, against `same_positions`: the truths cast at the drawing's own rays ([`truth_images`]
/// with `params.render.supersample`; see [`MethodStats::psnr_same_positions_mean`]). The frames
/// are held raw ([`measure_stored`] with [`Storage::Raw`]).
///
/// Errors: mismatched lengths or sizes, a direction the view set does not cover, or an empty
/// picture (both the drawing and the truth empty: nothing to compare).
pub fn measure(
    images: &SphereImages,
    directions: &[DVec3],
    truths: &[RgbaImage],
    same_positions: Option<&[RgbaImage]>,
    params: &SphereMeasureParams,
) -> Result<SphereMeasurement, SphereError> {
    measure_stored(
        images,
        Storage::Raw,
        directions,
        truths,
        same_positions,
        params,
    )
}

/// [`measure`] with the frames held in `storage`: compressed, each method draws from its own
/// layout's decoded blocks ([`compress`]) and is counted in its compressed bytes. Same
/// arguments and errors; the compression adds its encoding and a second build of the bounds.
pub fn measure_stored(
    images: &SphereImages,
    storage: Storage,
    directions: &[DVec3],
    truths: &[RgbaImage],
    same_positions: Option<&[RgbaImage]>,
    params: &SphereMeasureParams,
) -> Result<SphereMeasurement, SphereError> {
    let compressed = match storage {
        Storage::Raw => None,
        Storage::Compressed | Storage::CompressedDepth8 => Some(compress(images, storage)?),
    };
    let (warp, base, encode_s) = match &compressed {
        None => (images, images, 0.0),
        Some(c) => (&c.warp, &c.baseline, c.encode_s),
    };
    let (ours, baseline) = measure_pair(warp, base, directions, truths, same_positions, params)?;
    let base2 = timed(directions, &|d| {
        render_engine(base, d, &params.render, EngineSteps::Two)
    })?;
    let p = &images.params;
    let (interval, _) = warp
        .bounds
        .iter()
        .map(|b| b.stats())
        .fold((0.0, 0.0), |acc, s| (acc.0 + s.0, acc.1 + s.1));
    Ok(SphereMeasurement {
        grid: p.set.grid,
        size: p.size,
        storage,
        bytes_ours: p.warp_bytes(storage),
        bytes_baseline: p.baseline_bytes(storage),
        encode_s,
        capture_s: images.capture_time.as_secs_f64(),
        bounds_s: warp.bounds_time.as_secs_f64(),
        bound_interval: interval / warp.bounds.len().max(1) as f64,
        ours,
        baseline,
        baseline_two_step: stats(&base2, directions, truths, same_positions)?,
        directions: directions.iter().map(|d| d.to_array()).collect(),
    })
}

/// One memory budget: the best mean PSNR each method reaches within it, and with which
/// configuration `(G, F, PSNR)`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BudgetRow {
    /// The budget (MiB).
    pub budget_mib: f64,
    /// The exact warp's best configuration within the budget.
    pub ours: Option<(usize, usize, f64)>,
    /// The engine baseline's best configuration within the budget.
    pub baseline: Option<(usize, usize, f64)>,
    /// The two-step engine baseline's best configuration within the budget.
    pub baseline_two_step: Option<(usize, usize, f64)>,
}

/// For each budget (MiB), the best measured configuration of each method that fits in it
/// (the same selection rule for both).
pub fn budget_table(rows: &[SphereMeasurement], budgets_mib: &[f64]) -> Vec<BudgetRow> {
    let best = |budget: f64,
                bytes: &dyn Fn(&SphereMeasurement) -> usize,
                psnr: &dyn Fn(&SphereMeasurement) -> f64| {
        rows.iter()
            .filter(|r| bytes(r) as f64 <= budget * 1024.0 * 1024.0)
            .max_by(|a, b| psnr(a).total_cmp(&psnr(b)))
            .map(|r| (r.grid, r.size, psnr(r)))
    };
    budgets_mib
        .iter()
        .map(|&b| BudgetRow {
            budget_mib: b,
            ours: best(b, &|r| r.bytes_ours, &|r| r.ours.psnr_mean),
            baseline: best(b, &|r| r.bytes_baseline, &|r| r.baseline.psnr_mean),
            baseline_two_step: best(b, &|r| r.bytes_baseline, &|r| r.baseline_two_step.psnr_mean),
        })
        .collect()
}

impl SphereParams {
    /// The parameters of a `grid × grid` hemisphere set of `size²` frames with the default
    /// surface model.
    pub fn hemisphere(grid: usize, size: usize) -> Result<Self, SphereError> {
        let p = Self {
            set: super::ViewSet::hemisphere(grid)?,
            size,
            model: super::SurfaceModel::DEFAULT,
            bounds_block: 1,
        };
        p.validate()?;
        Ok(p)
    }
}
