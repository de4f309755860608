//! Measurements: march steps per bound type, and image quality against the ground truth.
//!
//! **Step definition** (fixed; tables never change it): every fragment of the impostor quad — the
//! `Lx × Ly` pixel centres of the views' own grid — at `angles` evenly spaced display angles
//! `α_m = 2πm/angles`, counted **per warped view** (a frame warps two views; each counts as one
//! sample). One step = one cell (one new texel fetch) visited by the march; an empty stored bound
//! costs 0.

use std::f64::consts::TAU;

use altrep_data_gen::{Light, RgbaImage, Shape, Supersample, TruthParams, render_truth};
use rayon::prelude::*;
use serde::Serialize;

use super::baselines::{render_blend_baseline, render_blend_baseline_with, render_offset_baseline};
use super::bounds::{BoundKind, Bounds, dense_sweep};
use super::images::{Brim, ParallaxImages, ParallaxParams};
use super::warp::{
    Reconstruction, RenderParams, RowFilter, WarpMethod, cylinder_range, march_row, render,
    render_with,
};
use super::{ParallaxError, invalid};
use crate::metrics::{
    CompareOptions, ErrorSplit, compare, error_split, psnr_from_mse, silhouette_iou,
};

/// Step statistics of one bound type.
#[derive(Clone, Debug, Serialize)]
pub struct StepStats {
    /// Bound name ([`BoundKind::name`]).
    pub method: String,
    /// The bound.
    pub kind: BoundKind,
    /// Mean steps per fragment and warped view.
    pub mean_steps: f64,
    /// Largest steps of any fragment.
    pub max_steps: u32,
    /// Mean steps over the fragments whose ray meets the height field (per warped view).
    pub mean_steps_hit: f64,
    /// Mean steps over the fragments in the object's footprint: pixels whose ray meets the view's
    /// height field for some θ of its range (non-empty zmin/zmax bound), the area a tight
    /// impostor mesh would rasterise. `None` when no zmin/zmax bound is measured.
    pub mean_steps_footprint: Option<f64>,
    /// Crossings outside the stored bounds in the dense sweep ([`dense_sweep`]); `None` if not run.
    pub violations: Option<u64>,
    /// Fragments of the step sweep where the bounded march found another crossing than the
    /// unbounded one (0 expected).
    pub mismatches: u64,
    /// Precompute time of the bounds (ms).
    pub precompute_ms: f64,
    /// Bytes per object: the views plus the bounds.
    pub bytes: usize,
}

/// Result of [`measure_steps`].
#[derive(Clone, Debug, Serialize)]
pub struct StepsReport {
    /// One entry per bound, in the order given.
    pub stats: Vec<StepStats>,
    /// Display angles swept.
    pub angles: usize,
    /// Samples counted: fragments × 2 views × angles.
    pub samples: u64,
    /// Share of samples whose ray meets the height field.
    pub hit_share: f64,
    /// Share of samples in the footprint (see [`StepStats::mean_steps_footprint`]).
    pub footprint_share: Option<f64>,
    /// Per bound: mean steps per warped view of each screen pixel (row-major `Lx × Ly`), for heat
    /// maps.
    #[serde(skip)]
    pub heat: Vec<Vec<f64>>,
    /// Dense-sweep angles per view (0 if not run).
    pub sweep_angles: usize,
}

struct Acc {
    sum: Vec<u64>,
    max: Vec<u32>,
    sum_hit: Vec<u64>,
    sum_foot: Vec<u64>,
    mismatches: Vec<u64>,
    hits: u64,
    foot: u64,
    heat: Vec<Vec<u32>>,
}

impl Acc {
    fn new(m: usize, px: usize) -> Self {
        Self {
            sum: vec![0; m],
            max: vec![0; m],
            sum_hit: vec![0; m],
            sum_foot: vec![0; m],
            mismatches: vec![0; m],
            hits: 0,
            foot: 0,
            heat: vec![vec![0; px]; m],
        }
    }
    fn merge(mut self, o: Self) -> Self {
        for b in 0..self.sum.len() {
            self.sum[b] += o.sum[b];
            self.max[b] = self.max[b].max(o.max[b]);
            self.sum_hit[b] += o.sum_hit[b];
            self.sum_foot[b] += o.sum_foot[b];
            self.mismatches[b] += o.mismatches[b];
            for (h, g) in self.heat[b].iter_mut().zip(&o.heat[b]) {
                *h += g;
            }
        }
        self.hits += o.hits;
        self.foot += o.foot;
        self
    }
}

/// Measures march steps for each of `bounds` (see the module docs for the definition) and, when
/// `sweep_factor > 0`, runs [`dense_sweep`] at `sweep_factor` times the finest build grid.
/// Cost: `angles · 2 · Lx · Ly` marches per bound, angles in parallel.
///
/// Errors: `angles == 0`, bounds built for other images (size mismatch).
pub fn measure_steps(
    images: &ParallaxImages,
    bounds: &[Bounds],
    angles: usize,
    sweep_factor: usize,
) -> Result<StepsReport, ParallaxError> {
    if angles == 0 {
        return Err(invalid("angles", angles, "must be at least 1"));
    }
    let p = &images.params;
    let (w, h) = (p.width, p.height);
    for b in bounds {
        b.check(images)?;
    }
    let grid = images.pixel_grid();
    let xs: Vec<f64> = (0..w).map(|i| grid.x_at(i as f64 + 0.5)).collect();
    let r = images.march_radius();
    let nb = bounds.len();
    let footprint = bounds.iter().find(|b| b.kind == BoundKind::ZMinMax);
    let acc = (0..angles)
        .into_par_iter()
        .fold(
            || Acc::new(nb, w * h),
            |mut acc, m| {
                let alpha = TAU * m as f64 / angles as f64;
                for (k, theta, _) in images.bracket(alpha) {
                    let (co, si) = (theta.cos(), theta.sin());
                    let view = &images.views[k];
                    for j in 0..h {
                        let row = &view.geom[j * w..(j + 1) * w];
                        for (i, &x) in xs.iter().enumerate() {
                            let (x1, x2) = cylinder_range(x, co, si, r);
                            let reference = march_row(&grid, row, x, co, si, x1, x2);
                            acc.hits += u64::from(reference.hit.is_some());
                            let in_foot = footprint
                                .is_some_and(|f| f.pixel(k, i, j).is_ok_and(|p| p[0].is_some()));
                            acc.foot += u64::from(in_foot);
                            for (b, bound) in bounds.iter().enumerate() {
                                let res = match bound.range_cs(k, j * w + i, x, co, si) {
                                    Some((a1, a2)) => march_row(&grid, row, x, co, si, a1, a2),
                                    None => super::warp::MarchResult {
                                        hit: None,
                                        steps: 0,
                                    },
                                };
                                acc.sum[b] += u64::from(res.steps);
                                acc.max[b] = acc.max[b].max(res.steps);
                                if reference.hit.is_some() {
                                    acc.sum_hit[b] += u64::from(res.steps);
                                }
                                if in_foot {
                                    acc.sum_foot[b] += u64::from(res.steps);
                                }
                                acc.mismatches[b] += u64::from(res.hit != reference.hit);
                                acc.heat[b][j * w + i] += res.steps;
                            }
                        }
                    }
                }
                acc
            },
        )
        .reduce(|| Acc::new(nb, w * h), Acc::merge);
    let samples = (angles * 2 * w * h) as u64;
    let refs: Vec<&Bounds> = bounds.iter().collect();
    let violations = if sweep_factor > 0 {
        Some(dense_sweep(images, &refs, sweep_factor)?)
    } else {
        None
    };
    let sweep_angles = if sweep_factor > 0 {
        2 * bounds
            .iter()
            .map(|b| b.params.subdivisions)
            .max()
            .unwrap_or(1)
            * sweep_factor
            + 1
    } else {
        0
    };
    let stats = bounds
        .iter()
        .enumerate()
        .map(|(b, bound)| StepStats {
            method: bound.kind.name().to_string(),
            kind: bound.kind,
            mean_steps: acc.sum[b] as f64 / samples as f64,
            max_steps: acc.max[b],
            mean_steps_hit: acc.sum_hit[b] as f64 / acc.hits.max(1) as f64,
            mean_steps_footprint: footprint
                .map(|_| acc.sum_foot[b] as f64 / acc.foot.max(1) as f64),
            violations: violations.as_ref().map(|v| v[b]),
            mismatches: acc.mismatches[b],
            precompute_ms: bound.precompute.as_secs_f64() * 1e3,
            bytes: images.bytes() + bound.bytes(images),
        })
        .collect();
    let norm = 1.0 / (2 * angles) as f64;
    Ok(StepsReport {
        stats,
        angles,
        samples,
        hit_share: acc.hits as f64 / samples as f64,
        footprint_share: footprint.map(|_| acc.foot as f64 / samples as f64),
        heat: acc
            .heat
            .iter()
            .map(|hm| hm.iter().map(|&s| f64::from(s) * norm).collect())
            .collect(),
        sweep_angles,
    })
}

/// What [`measure_quality`] sweeps.
#[derive(Clone, Debug)]
pub struct QualityParams {
    /// Display angles, `α_a = 2π(a + ½)/angles + 0.05` (between the capture angles of every N
    /// used). Default 16.
    pub angles: usize,
    /// Rays per pixel edge ([`Supersample`]): the reconstructions take `k` across the pixel
    /// (see [`RenderParams::supersample`]), the ground truth `k × k`. Default 3.
    pub supersample: Supersample,
    /// Numbers of views of the inverse warp and the offset baseline. Default `[4, 8, 16]`.
    pub views: Vec<usize>,
    /// View sizes (square; the screen has the same size). Default `[32, 64, 128]`.
    pub sizes: Vec<usize>,
    /// Views of the blending baseline. Default 64.
    pub blend_views: usize,
    /// The light.
    pub light: Light,
    /// Everything else of the representation (views and size are overridden).
    pub base: ParallaxParams,
}

impl Default for QualityParams {
    fn default() -> Self {
        Self {
            angles: 16,
            supersample: Supersample::of(3),
            views: vec![4, 8, 16],
            sizes: vec![32, 64, 128],
            blend_views: 64,
            light: Light::default(),
            base: ParallaxParams::default(),
        }
    }
}

/// One row of the quality table.
#[derive(Clone, Debug, Serialize)]
pub struct QualityRow {
    /// `"inverse warp"`, `"blend 64 views"` (no parallax) or `"one-step offset"`.
    pub method: String,
    /// Views stored.
    pub views: usize,
    /// View (and screen) size, pixels per side.
    pub size: usize,
    /// PSNR (dB, peak 1) of premultiplied RGBA against the ground truth, from the mean squared
    /// error over all angles and pixels.
    pub psnr_db: f64,
    /// Mean silhouette IoU (alpha > ½) over the angles.
    pub iou: f64,
    /// Bytes of the stored views (bounds excluded: they do not change the image).
    pub bytes: usize,
}

fn score(images: &[RgbaImage], truth: &[RgbaImage]) -> Result<(f64, f64), ParallaxError> {
    let mut mse = 0.0;
    let mut iou = 0.0;
    for (img, t) in images.iter().zip(truth) {
        let e = compare(img, t, &CompareOptions::default())?;
        mse += e.rmse * e.rmse;
        iou += silhouette_iou(img, t, 0.5)?;
    }
    let n = images.len().max(1) as f64;
    Ok((psnr_from_mse(mse / n), iou / n))
}

/// The display angles of a quality measurement (offset from the view angles). Errors: no
/// angle or no supersampling.
fn quality_angles(params: &QualityParams) -> Result<Vec<f64>, ParallaxError> {
    if params.angles == 0 {
        return Err(invalid(
            "quality sweep",
            format!("{} angles ×{}", params.angles, params.supersample),
            "must be positive",
        ));
    }
    Ok((0..params.angles)
        .map(|a| TAU * (a as f64 + 0.5) / params.angles as f64 + 0.05)
        .collect())
}

/// The supersampled ground truth of `shape` at every angle, `size` pixels square.
fn quality_truths(
    shape: &dyn Shape,
    params: &QualityParams,
    alphas: &[f64],
    size: usize,
) -> Result<Vec<RgbaImage>, ParallaxError> {
    Ok(alphas
        .iter()
        .map(|&angle| {
            render_truth(
                shape,
                &TruthParams {
                    angle,
                    width: size,
                    height: size,
                    supersample: params.supersample,
                    light: params.light,
                    cylinder: params.base.cylinder,
                },
            )
        })
        .collect::<Result<Vec<_>, _>>()?)
}

/// Image quality of inverse warping with the default reconstruction ([`render`]; for every N and
/// size of `params`) and of the two baselines against the supersampled ground truth. Inverse warping marches from the cylinder: stored bounds
/// never change the image (checked by the mismatch counts of [`measure_steps`]).
///
/// Errors: invalid parameters, capture or comparison errors.
pub fn measure_quality(
    shape: &dyn Shape,
    params: &QualityParams,
) -> Result<Vec<QualityRow>, ParallaxError> {
    let alphas = quality_angles(params)?;
    let mut rows = Vec::new();
    for &size in &params.sizes {
        let truth = quality_truths(shape, params, &alphas, size)?;
        let screen = RenderParams {
            width: size,
            height: size,
            supersample: params.supersample,
            light: params.light,
            mip: true,
        };
        let run =
            |images: &ParallaxImages,
             f: &dyn Fn(&ParallaxImages, f64) -> Result<RgbaImage, ParallaxError>| {
                let imgs = alphas
                    .iter()
                    .map(|&a| f(images, a))
                    .collect::<Result<Vec<_>, _>>()?;
                score(&imgs, &truth)
            };
        for &views in &params.views {
            let p = ParallaxParams {
                views,
                width: size,
                height: size,
                ..params.base
            };
            let images = ParallaxImages::capture(shape, &p)?;
            let (psnr_db, iou) = run(&images, &|im, a| {
                render(im, a, WarpMethod::Inverse, &screen)
            })?;
            rows.push(QualityRow {
                method: "inverse warp".into(),
                views,
                size,
                psnr_db,
                iou,
                bytes: images.bytes(),
            });
            let (psnr_db, iou) = run(&images, &|im, a| render_offset_baseline(im, a, &screen))?;
            rows.push(QualityRow {
                method: "one-step offset".into(),
                views,
                size,
                psnr_db,
                iou,
                bytes: images.bytes(),
            });
        }
        let p = ParallaxParams {
            views: params.blend_views,
            width: size,
            height: size,
            ..params.base
        };
        let images = ParallaxImages::capture(shape, &p)?;
        let (psnr_db, iou) = run(&images, &|im, a| render_blend_baseline(im, a, &screen))?;
        rows.push(QualityRow {
            method: format!("blend {} views", params.blend_views),
            views: params.blend_views,
            size,
            psnr_db,
            iou,
            bytes: images.bytes(),
        });
    }
    Ok(rows)
}

/// One reconstruction measured by [`measure_quality_sweep`]: a surface model at silhouettes and
/// the options of [`render_with`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Variant {
    /// Label in tables.
    pub name: String,
    /// Surface model at unjoined texel ends.
    pub brim: Brim,
    /// Reconstruction options.
    pub rec: Reconstruction,
}

impl Variant {
    /// The original path, as in the report (flat brims, nearest row, two views, hard coverage).
    pub fn original() -> Self {
        Self {
            name: "original inverse warp".into(),
            brim: Brim::Flat,
            rec: Reconstruction::ORIGINAL,
        }
    }

    /// The best combination measured (docs/design.md §7.6), the default: tangent brims (max slope
    /// 4, [`Brim::DEFAULT`]), linear row filter, fallback to the next views out (doubtful hits at
    /// half coverage), soft edges, hole filling, brim carving ([`Reconstruction::DEFAULT`]; the
    /// depth test, measured alone at ±0.05 dB, is left out).
    pub fn best() -> Self {
        Self {
            name: "inverse warp (default)".into(),
            brim: Brim::DEFAULT,
            rec: Reconstruction::DEFAULT,
        }
    }

    /// The original path, each option alone, and all of them together.
    pub fn standard() -> Vec<Self> {
        let base = Self::original();
        let with = |name: &str, f: &dyn Fn(&mut Self)| {
            let mut v = Self {
                name: name.into(),
                ..base.clone()
            };
            f(&mut v);
            v
        };
        vec![
            base.clone(),
            with("+ tangent brim", &|v| {
                v.brim = Brim::Tangent { max_slope: 4.0 }
            }),
            with("+ row filter", &|v| v.rec.rows = RowFilter::Linear),
            with("+ depth test", &|v| v.rec.depth_test = true),
            with("+ fallback views", &|v| v.rec.fallback = true),
            with("+ soft edges", &|v| v.rec.soft_edges = true),
            with("+ hole filling", &|v| v.rec.fill_holes = true),
            with("+ brim carving", &|v| {
                // Carving acts on brim hits: with the tangent brim of the default.
                v.brim = Brim::DEFAULT;
                v.rec.carve_brims = true
            }),
            with("+ fallback, doubtful hits halved", &|v| {
                // Acts on fallback brim hits: with the fallback and the tangent brim.
                v.brim = Brim::DEFAULT;
                v.rec.fallback = true;
                v.rec.soft_fallback = true
            }),
            Self::best(),
        ]
    }
}

/// One row of [`measure_quality_sweep`].
#[derive(Clone, Debug, Serialize)]
pub struct SweepRow {
    /// Variant name, `"one-step offset"`, `"blend N views"` or `"blend N views, row filter"`.
    pub method: String,
    /// Views stored.
    pub views: usize,
    /// View (and screen) size.
    pub size: usize,
    /// PSNR (dB) of premultiplied RGBA against the ground truth over all angles.
    pub psnr_db: f64,
    /// Mean silhouette IoU (alpha > ½).
    pub iou: f64,
    /// Error split by distance to the true outline, averaged over the angles.
    pub split: ErrorSplit,
    /// Bytes of the stored views.
    pub bytes: usize,
}

/// The reconstruction quality table (bench/RESULTS.md): for every size and N of `params`, each of
/// `variants` (inverse warping with a surface model and reconstruction options), the one-step
/// offset at the same N, and the blend of `blend_views` views without and with the row filter,
/// against the supersampled ground truth, with the error split by distance to the outline. Cost: as
/// [`measure_quality`] times the variants.
///
/// Errors: invalid parameters, capture or comparison errors.
pub fn measure_quality_sweep(
    shape: &dyn Shape,
    params: &QualityParams,
    variants: &[Variant],
) -> Result<Vec<SweepRow>, ParallaxError> {
    let alphas = quality_angles(params)?;
    let mut rows = Vec::new();
    for &size in &params.sizes {
        let truth = quality_truths(shape, params, &alphas, size)?;
        let screen = RenderParams {
            width: size,
            height: size,
            supersample: params.supersample,
            light: params.light,
            mip: true,
        };
        let run = |method: String,
                   images: &ParallaxImages,
                   f: &dyn Fn(&ParallaxImages, f64) -> Result<RgbaImage, ParallaxError>|
         -> Result<SweepRow, ParallaxError> {
            let imgs = alphas
                .iter()
                .map(|&a| f(images, a))
                .collect::<Result<Vec<_>, _>>()?;
            let (psnr_db, iou) = score(&imgs, &truth)?;
            let mut split = ErrorSplit::default();
            for (img, t) in imgs.iter().zip(&truth) {
                split.add(&error_split(img, t)?);
            }
            split.scale(1.0 / imgs.len().max(1) as f64);
            Ok(SweepRow {
                method,
                views: images.params.views,
                size,
                psnr_db,
                iou,
                split,
                bytes: images.bytes(),
            })
        };
        for &views in &params.views {
            let p = ParallaxParams {
                views,
                width: size,
                height: size,
                ..params.base
            };
            let images = ParallaxImages::capture(shape, &p)?;
            for v in variants {
                let im = images.with_brim(v.brim)?;
                rows.push(run(v.name.clone(), &im, &|im, a| {
                    render_with(im, a, WarpMethod::Inverse, &screen, &v.rec)
                })?);
            }
            rows.push(run("one-step offset".into(), &images, &|im, a| {
                render_offset_baseline(im, a, &screen)
            })?);
        }
        let p = ParallaxParams {
            views: params.blend_views,
            width: size,
            height: size,
            ..params.base
        };
        let images = ParallaxImages::capture(shape, &p)?;
        rows.push(run(
            format!("blend {} views", params.blend_views),
            &images,
            &|im, a| render_blend_baseline(im, a, &screen),
        )?);
        rows.push(run(
            format!("blend {} views, row filter", params.blend_views),
            &images,
            &|im, a| render_blend_baseline_with(im, a, &screen, RowFilter::Linear),
        )?);
    }
    Ok(rows)
}
