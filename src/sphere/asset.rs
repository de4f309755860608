//! Images with parallax from any direction ([`crate::sphere`]) in the pipeline: planning from
//! the needed elevations and screen sizes, files, loading, measuring.
//!
//! The `G × G` frames of `F × F` texels are stored as atlases of `G·F × G·F` texels, frame
//! `k = j·G + i` (direction [`crate::sphere::ViewSet::direction`]) in tile column `i`, tile row
//! `j`, each tile row-major with row 0 at the top:
//! `albedo.png` (RGB8 sRGB albedo), `normal.png` (RGB8, object-frame normal `(n + 1)/2`),
//! `depth.png` (L16: 0 = undefined, else `Z = (code − 1)/65534 · 2 − 1` in the frame's depth
//! units, the bounding sphere's radius, toward the camera) and `bounds.png` (LA8: `zmin`, `zmax`
//! codes of the cone bounds, `Z = code/255 · 2 − 1`; `zmin > zmax` where no event is possible),
//! an atlas of `G·B × G·B` texels laid out the same way, `B = ⌈F / bounds_block⌉` bounds texels
//! per frame side, each bounding `bounds_block²` frame texels.
//! `asset.json`'s metadata holds the grid, its coverage, the frame size, the surface model, the
//! bounds block (absent: 1) and the bounding sphere (`centre`, `radius`, world units) every
//! frame was captured over.

use altrep_data_gen::RgbaImage;
use altrep_data_gen::Supersample;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::asset::{AssetReader, AssetWriter, Channel, CodeImage, Encoding};
use crate::representation::{
    Estimate, InputSize, Measurement, Needs, Picture, PipelineError, Plan, Representation, Source,
    linear_bytes,
};
use crate::sphere::{
    ConeBounds, Coverage, FrameCodes, MethodStats, SphereError, SphereImages, SphereMeasureParams,
    SphereParams, SphereRenderParams, SurfaceModel, ViewSet, azimuth_elevation,
    fibonacci_directions, measure, render, render_engine_baseline, truth_images,
};

/// Manifest parameters of images with parallax from any direction (`[asset.sphere]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SphereSpec {
    /// Frames per side `G` of the octahedral grid (2–32, default 8).
    pub grid: usize,
    /// Texels per frame side `F` (4–1024, default 64); the planner lowers it to the largest
    /// screen size.
    pub size: usize,
    /// Largest tangent-plane slope kept (default 4); 0 stores flat texel tops.
    pub max_slope: f64,
    /// Frame texels per side of one cone-bounds texel: 1 (default), 2 or 4. Coarser bounds
    /// store `1/block²` of the bounds' bytes and draw the same pictures; the march reads more
    /// texels (docs/design.md §7b, "Coarser bounds").
    pub bounds_block: usize,
}

impl Default for SphereSpec {
    fn default() -> Self {
        Self {
            grid: 8,
            size: 64,
            max_slope: 4.0,
            bounds_block: 1,
        }
    }
}

impl SphereSpec {
    /// Checks ranges; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if !(2..=32).contains(&self.grid) {
            return Err(format!("sphere.grid = {} must be in 2..=32", self.grid));
        }
        if !(4..=1024).contains(&self.size) {
            return Err(format!("sphere.size = {} must be in 4..=1024", self.size));
        }
        if !matches!(self.bounds_block, 1 | 2 | 4) {
            return Err(format!(
                "sphere.bounds_block = {} must be 1, 2 or 4 frame texels per side",
                self.bounds_block
            ));
        }
        if !(self.max_slope.is_finite() && self.max_slope >= 0.0) {
            return Err(format!(
                "sphere.max_slope = {} must be finite and ≥ 0 (0: flat texel tops)",
                self.max_slope
            ));
        }
        Ok(())
    }

    fn model(&self) -> SurfaceModel {
        if self.max_slope > 0.0 {
            SurfaceModel::Tangent {
                max_slope: self.max_slope,
            }
        } else {
            SurfaceModel::Flat
        }
    }
}

/// What the planner decided.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SphereDecisions {
    /// Upper hemisphere or whole sphere.
    pub coverage: Coverage,
    /// Frames per side.
    pub grid: usize,
    /// Texels per frame side actually captured.
    pub size: usize,
}

/// Images with parallax from any direction, for the pipeline.
pub struct SphereRepr;

/// The frame size the closest footprint needs: the largest screen size, at least 4.
fn closest_size(needs: &Needs) -> usize {
    (needs.screen_px[1].ceil() as usize).max(4)
}

/// Whether `d` lies in the needed azimuth and elevation ranges.
fn needed(needs: &Needs, d: DVec3) -> bool {
    let e = d.y.clamp(-1.0, 1.0).asin().to_degrees();
    let [e0, e1] = needs.elevation_deg;
    if e < e0 - 1e-9 || e > e1 + 1e-9 {
        return false;
    }
    if needs.all_azimuths() || d.x.hypot(d.z) < 1e-12 {
        return true;
    }
    let a = d.z.atan2(d.x).to_degrees();
    let [a0, a1] = needs.azimuth_deg;
    let rel = (a - a0).rem_euclid(360.0);
    rel <= a1 - a0 + 1e-9
}

/// `count` test directions in the needed ranges: a Fibonacci spiral over the set's coverage
/// filtered to the ranges, or, where the ranges are too narrow for it, a grid over them.
fn measure_directions(needs: &Needs, coverage: Coverage, count: usize) -> Vec<DVec3> {
    let mut n = count;
    while n <= 64 * count {
        let v: Vec<DVec3> = fibonacci_directions(n, coverage)
            .into_iter()
            .filter(|&d| needed(needs, d))
            .collect();
        if v.len() >= count {
            return v.into_iter().take(count).collect();
        }
        n *= 2;
    }
    let [a0, a1] = needs.azimuth_deg;
    let [e0, e1] = needs.elevation_deg;
    (0..count)
        .map(|k| {
            let u = (k as f64 + 0.37) / count as f64;
            let v = ((k * 7) % count) as f64 / count as f64;
            let e = (e0 + (e1 - e0) * v).clamp(-89.5, 89.5);
            azimuth_elevation((a0 + (a1 - a0).min(360.0) * u).to_radians(), e.to_radians())
        })
        .collect()
}

/// Index in a `grid·size`-wide atlas of texel `(x, y)` of frame `k` (tile column `k % grid`,
/// tile row `k / grid`): the one layout [`SphereRepr::write`] and [`SphereRepr::read`] share.
fn atlas_index(k: usize, grid: usize, size: usize, x: usize, y: usize) -> usize {
    let (ti, tj) = (k % grid, k / grid);
    (tj * size + y) * grid * size + ti * size + x
}

/// A failure of the frames' code as the pipeline reports it.
pub(crate) fn sphere_err(e: SphereError) -> PipelineError {
    PipelineError::Sphere(e)
}

impl Representation for SphereRepr {
    const NAME: &'static str = "sphere";
    const CASTS_RAYS: bool = true;
    type Spec = SphereSpec;
    type Data = SphereImages;
    type Decisions = SphereDecisions;

    fn validate(spec: &Self::Spec) -> Result<(), String> {
        spec.validate()
    }

    fn relevant_needs(needs: &Needs) -> serde_json::Value {
        // The azimuths decide nothing that is built, but the measured directions.
        json!({
            "azimuth_deg": needs.azimuth_deg,
            "elevation_deg": needs.elevation_deg,
            "screen_px_max": needs.screen_px[1],
        })
    }

    fn estimate(spec: &SphereSpec, needs: &Needs, _input: &InputSize) -> Estimate {
        // ~80 B per frame texel (the frames, their bounds, the measuring, the read-back copy)
        // measured from 4² frames of 32² to 16² frames of 64².
        let size = closest_size(needs).min(spec.size) as f64;
        let texels = (spec.grid * spec.grid) as f64 * size * size;
        let block = spec.bounds_block.max(1) as f64;
        Estimate {
            peak_bytes: linear_bytes(2e6, 82.0, texels),
            // Albedo 4 B, normal 4 B, depth 2 B per texel, bounds 2 B per bounds texel.
            output_bytes: linear_bytes(0.0, 10.0 + 2.0 / (block * block), texels),
        }
    }

    fn plan(
        spec: &SphereSpec,
        needs: &Needs,
        _source: &Source,
    ) -> Result<(Plan, SphereDecisions), PipelineError> {
        let mut plan = Plan::default();
        let coverage = if needs.elevation_deg[0] >= 0.0 {
            plan.skip(
                "frames below the horizon".into(),
                format!(
                    "the lowest needed elevation is {}° (≥ 0): the upper hemisphere suffices",
                    needs.elevation_deg[0]
                ),
            );
            Coverage::Hemisphere
        } else {
            Coverage::Sphere
        };
        let closest = closest_size(needs);
        let size = if closest < spec.size {
            plan.skip(
                format!("frame texels beyond {closest}²"),
                format!(
                    "finer than the closest footprint: the largest screen size is {} px",
                    needs.screen_px[1]
                ),
            );
            closest
        } else {
            spec.size
        };
        plan.build(format!(
            "{g}×{g} {} frames of {size}² (albedo, normal, depth, cone bounds{})",
            match coverage {
                Coverage::Hemisphere => "hemi-octahedral",
                Coverage::Sphere => "octahedral",
            },
            match spec.bounds_block {
                1 => String::new(),
                b => format!(" over {b} × {b} texels"),
            },
            g = spec.grid
        ));
        Ok((
            plan,
            SphereDecisions {
                coverage,
                grid: spec.grid,
                size,
            },
        ))
    }

    fn build(
        spec: &SphereSpec,
        _needs: &Needs,
        decisions: &SphereDecisions,
        source: &Source,
    ) -> Result<(SphereImages, serde_json::Value), PipelineError> {
        let params = SphereParams {
            set: ViewSet::new(decisions.coverage, decisions.grid).map_err(sphere_err)?,
            size: decisions.size,
            model: spec.model(),
            bounds_block: spec.bounds_block,
        };
        let images = match SphereImages::capture(source.shape()?, &params) {
            Err(SphereError::NothingVisible { frames }) => {
                return Err(PipelineError::Invisible {
                    asset: source.name.into(),
                    what: format!("any of the {frames} frames"),
                });
            }
            r => r.map_err(sphere_err)?,
        };
        let report = json!({
            "capture_s": images.capture_time.as_secs_f64(),
            "bounds_s": images.bounds_time.as_secs_f64(),
            "frames": params.set.len(),
            "bytes": params.total_bytes(),
        });
        Ok((images, report))
    }

    fn write(data: &SphereImages, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError> {
        let p = &data.params;
        let (g, f) = (p.set.grid, p.size);
        let side = g * f;
        let mut albedo = CodeImage::<u8>::new(side, side, 3);
        let mut normal = CodeImage::<u8>::new(side, side, 3);
        let mut depth = CodeImage::<u16>::new(side, side, 1);
        let bs = p.bounds_side();
        let mut bounds = CodeImage::<u8>::new(g * bs, g * bs, 2);
        for (k, (c, b)) in data.codes.iter().zip(&data.bounds).enumerate() {
            for y in 0..f {
                for x in 0..f {
                    let src = y * f + x;
                    let dst = atlas_index(k, g, f, x, y);
                    albedo.pixel_mut(dst).copy_from_slice(&c.albedo[src]);
                    normal.pixel_mut(dst).copy_from_slice(&c.normal[src]);
                    depth.pixel_mut(dst)[0] = c.depth[src];
                }
            }
            for y in 0..bs {
                for x in 0..bs {
                    let src = y * bs + x;
                    bounds
                        .pixel_mut(atlas_index(k, g, bs, x, y))
                        .copy_from_slice(&[b.zmin[src], b.zmax[src]]);
                }
            }
        }
        let ch = |name: &str, encoding: Encoding| Channel {
            name: name.into(),
            encoding,
        };
        let unorm = |bits: u32| Encoding::Linear {
            scale: 2.0 / ((1u64 << bits) - 1) as f64,
            offset: -1.0,
        };
        w.png8(
            "albedo",
            "albedo.png",
            &albedo,
            vec![
                ch("albedo.r", Encoding::Srgb),
                ch("albedo.g", Encoding::Srgb),
                ch("albedo.b", Encoding::Srgb),
            ],
        )?;
        w.png8(
            "normal",
            "normal.png",
            &normal,
            vec![
                ch("normal.x", unorm(8)),
                ch("normal.y", unorm(8)),
                ch("normal.z", unorm(8)),
            ],
        )?;
        w.png16(
            "depth",
            "depth.png",
            &depth,
            vec![ch(
                "depth (0 = undefined)",
                Encoding::Linear {
                    scale: 2.0 / 65534.0,
                    offset: -1.0 - 2.0 / 65534.0,
                },
            )],
        )?;
        w.png8(
            "bounds",
            "bounds.png",
            &bounds,
            vec![ch("zmin", unorm(8)), ch("zmax", unorm(8))],
        )?;
        let centre = data.frames[0].frame.centre;
        Ok(json!({
            "grid": g,
            "coverage": p.set.coverage,
            "size": f,
            "model": p.model,
            "bounds_block": p.bounds_block,
            "centre": [centre.x, centre.y, centre.z],
            "radius": data.frames[0].frame.radius,
            "cone_half_angles_rad": data.cones,
            "atlas": "frame k = j·grid + i in tile column i, tile row j",
        }))
    }

    fn read(r: &AssetReader) -> Result<SphereImages, PipelineError> {
        r.expect_representation(Self::NAME)?;
        let m = &r.description().metadata;
        let field = |name: &str| {
            m.get(name)
                .cloned()
                .ok_or_else(|| r.content(format!("metadata.{name} missing")))
        };
        let bad = |name: &str, e: serde_json::Error| r.content(format!("metadata.{name}: {e}"));
        let grid: usize = serde_json::from_value(field("grid")?).map_err(|e| bad("grid", e))?;
        let coverage: Coverage =
            serde_json::from_value(field("coverage")?).map_err(|e| bad("coverage", e))?;
        let size: usize = serde_json::from_value(field("size")?).map_err(|e| bad("size", e))?;
        let model: SurfaceModel =
            serde_json::from_value(field("model")?).map_err(|e| bad("model", e))?;
        let centre: [f64; 3] =
            serde_json::from_value(field("centre")?).map_err(|e| bad("centre", e))?;
        let radius: f64 = serde_json::from_value(field("radius")?).map_err(|e| bad("radius", e))?;
        // Assets written before coarser bounds existed hold one bound per texel.
        let bounds_block: usize = match m.get("bounds_block") {
            None => 1,
            Some(v) => serde_json::from_value(v.clone()).map_err(|e| bad("bounds_block", e))?,
        };
        let params = SphereParams {
            set: ViewSet::new(coverage, grid).map_err(sphere_err)?,
            size,
            model,
            bounds_block,
        };
        params.validate().map_err(sphere_err)?;
        let side = grid * size;
        let bs = params.bounds_side();
        let albedo = r.png8("albedo")?;
        let normal = r.png8("normal")?;
        let depth = r.png16("depth")?;
        let bounds = r.png8("bounds")?;
        for (what, (w, h, c), side, want) in [
            (
                "albedo",
                (albedo.width, albedo.height, albedo.channels),
                side,
                3,
            ),
            (
                "normal",
                (normal.width, normal.height, normal.channels),
                side,
                3,
            ),
            (
                "depth",
                (depth.width, depth.height, depth.channels),
                side,
                1,
            ),
            (
                "bounds",
                (bounds.width, bounds.height, bounds.channels),
                grid * bs,
                2,
            ),
        ] {
            if (w, h, c) != (side, side, want) {
                return Err(r
                    .content(format!(
                        "{what} atlas is {w}×{h}×{c}, expected {side}×{side}×{want}"
                    ))
                    .into());
            }
        }
        let n = params.set.len();
        let mut codes = Vec::with_capacity(n);
        let mut cone = Vec::with_capacity(n);
        for k in 0..n {
            let mut c = FrameCodes {
                size,
                albedo: vec![[0; 3]; size * size],
                normal: vec![[0; 3]; size * size],
                depth: vec![0; size * size],
            };
            let mut b = ConeBounds {
                size,
                block: bounds_block,
                zmin: vec![0; bs * bs],
                zmax: vec![0; bs * bs],
            };
            for y in 0..size {
                for x in 0..size {
                    let dst = y * size + x;
                    let src = atlas_index(k, grid, size, x, y);
                    let a = albedo.pixel(src);
                    c.albedo[dst] = [a[0], a[1], a[2]];
                    let nn = normal.pixel(src);
                    c.normal[dst] = [nn[0], nn[1], nn[2]];
                    c.depth[dst] = depth.pixel(src)[0];
                }
            }
            for y in 0..bs {
                for x in 0..bs {
                    let bb = bounds.pixel(atlas_index(k, grid, bs, x, y));
                    b.zmin[y * bs + x] = bb[0];
                    b.zmax[y * bs + x] = bb[1];
                }
            }
            codes.push(c);
            cone.push(b);
        }
        SphereImages::from_parts(&params, DVec3::from_array(centre), radius, codes, cone)
            .map_err(|e| r.content(format!("stored frames: {e}")).into())
    }

    fn measure_size(d: &SphereDecisions) -> usize {
        d.size.clamp(32, 256)
    }

    fn measure(
        data: &SphereImages,
        needs: &Needs,
        size: usize,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError> {
        let size = size.clamp(1, 4096);
        let (m, dirs, truths) = measured(data, needs, size, source, true, measure)?;
        let params = render_params(size, source);
        let ours = render(data, dirs[0], &params).map_err(sphere_err)?;
        let base = render_engine_baseline(data, dirs[0], &params).map_err(sphere_err)?;
        let e = dirs[0].y.clamp(-1.0, 1.0).asin().to_degrees();
        let mut pictures = vec![Picture {
            file: format!("{}-sphere.png", source.name),
            caption: format!(
                "{}: ground truth | exact warp ({:.1} dB) | engine impostor blend ({:.1} dB), elevation {e:.0}°",
                source.name, m.ours.psnr_per_direction[0], m.baseline.psnr_per_direction[0],
            ),
            image: RgbaImage::side_by_side(&[&truths[0], &ours.image, &base.image]),
        }];
        // The per-fragment cost: every texel read of each pixel, both on one scale.
        let max = ours
            .pixel_reads
            .iter()
            .chain(&base.pixel_reads)
            .copied()
            .max()
            .unwrap_or(0);
        pictures.push(Picture {
            file: format!("{}-sphere-reads.png", source.name),
            caption: format!(
                "{}: texel reads per pixel, exact warp (mean {:.1} per ray, {:.1} over rays that hit) | engine impostor blend (mean {:.1}), on a logarithmic scale from black (0) through red and yellow to white ({max}), elevation {e:.0}°",
                source.name,
                ours.mean_reads(),
                ours.mean_reads_over_hits(),
                base.mean_reads(),
            ),
            image: RgbaImage::side_by_side(&[&ours.cost_picture(max), &base.cost_picture(max)]),
        });
        let method = format!(
            "exact warp of {g}×{g} frames of {f}² at {n} directions in the needed ranges, {size}² with 1 ray per pixel, vs truth 3×3; engine impostor blend of the same frames {b:.2} dB (IoU {bi:.3}); against the truth cast at the drawing's own rays {os} dB, the blend {bs} dB; mean FLIP {of:.4} against the blend's {bf:.4}; colour PSNR where both cover {oc} dB against {bc}; texel reads per ray {r:.1} ({rh:.1} over rays that hit, at most {rm}) against the blend's {br:.1} ({what})",
            g = data.params.set.grid,
            f = data.params.size,
            n = dirs.len(),
            b = m.baseline.psnr_mean,
            bi = m.baseline.iou_mean,
            os = decibels(m.ours.psnr_same_positions_mean),
            bs = decibels(m.baseline.psnr_same_positions_mean),
            of = m.ours.flip_mean,
            bf = m.baseline.flip_mean,
            oc = decibels(m.ours.colour_psnr_mean),
            bc = decibels(m.baseline.colour_psnr_mean),
            r = m.ours.reads_mean,
            rh = m.ours.reads_hit_mean,
            rm = m.ours.reads_max,
            br = m.baseline.reads_mean,
            what = super::warp::TEXEL_READS,
        );
        Ok((exact_warp_measurement(&m.ours, method, size), pictures))
    }
}

/// A figure in dB that may be missing, as the reports print it: two decimals, `—` where not
/// measured.
pub(crate) fn decibels(db: Option<f64>) -> String {
    db.map_or("—".into(), |p| format!("{p:.2}"))
}

/// The exact warp's figures `ours` as the pipeline reports a representation's, measured at
/// `size` pixels, described by `method`.
pub(crate) fn exact_warp_measurement(
    ours: &MethodStats,
    method: String,
    size: usize,
) -> Measurement {
    Measurement {
        method,
        psnr_db: ours.psnr_mean,
        worst_psnr_db: ours.psnr_min,
        iou: ours.iou_mean,
        coverage_error: Some(ours.coverage_error_mean),
        mean_steps: Some(ours.steps_mean),
        steps_split: Vec::new(),
        size,
        exact_psnr_db: None,
    }
}

/// How the frames are drawn when measured at `size²` pixels: one ray per pixel, the source's
/// light.
pub(crate) fn render_params(size: usize, source: &Source) -> SphereRenderParams {
    SphereRenderParams {
        size,
        supersample: Supersample::ONE,
        light: source.light,
        ..SphereRenderParams::default()
    }
}

/// The frames measured by `measure` ([`measure`], or [`crate::sphere::measure_one_step`]:
/// the exact warp and the engines' octahedral impostor built from the same frames), drawn at
/// `size²` pixels (1 ray per pixel) along 8 directions in the needed ranges against the truth
/// (3 × 3 rays per pixel), with those directions and truths; with `same_positions`, also
/// against the truth cast at the drawing's own rays (one per pixel, the pixel centre). Errors:
/// nothing of the object visible along some direction (typed, named). Cost: 8 truths of
/// `9·size²` rays (and 8 of `size²` with `same_positions`), and `measure`'s drawings of `size²`
/// rays (2 or 3 per direction).
pub(crate) fn measured<T>(
    data: &SphereImages,
    needs: &Needs,
    size: usize,
    source: &Source,
    same_positions: bool,
    measure: impl FnOnce(
        &SphereImages,
        &[DVec3],
        &[RgbaImage],
        Option<&[RgbaImage]>,
        &SphereMeasureParams,
    ) -> Result<T, SphereError>,
) -> Result<(T, Vec<DVec3>, Vec<RgbaImage>), PipelineError> {
    let shape = source.shape()?;
    let dirs = measure_directions(needs, data.params.set.coverage, 8);
    let params = SphereMeasureParams {
        directions: dirs.len(),
        render: render_params(size, source),
        truth_supersample: Supersample::of(3),
    };
    let truths =
        truth_images(shape, &dirs, size, Supersample::of(3), &source.light).map_err(sphere_err)?;
    if let Some(k) = truths
        .iter()
        .position(|t| t.pixels.iter().all(|p| p[3] <= 0.0))
    {
        return Err(PipelineError::Invisible {
            asset: source.name.into(),
            what: format!("the ground truth along {:?}", dirs[k]),
        });
    }
    let same = same_positions
        .then(|| truth_images(shape, &dirs, size, params.render.supersample, &source.light))
        .transpose()
        .map_err(sphere_err)?;
    let m = measure(data, &dirs, &truths, same.as_deref(), &params).map_err(sphere_err)?;
    Ok((m, dirs, truths))
}
