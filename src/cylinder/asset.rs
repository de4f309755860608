//! The cylindrical texture (docs/design.md §6) in the pipeline: the texture and its per-cell march
//! bounds, so a shader draws the exact inverse warp in a few sector tests.
//!
//! Files: `texture-albedo.png` (RGBA8: sRGB albedo, or the baked colour; alpha 255 = defined),
//! `texture-geometry.png` (RGBA8: normal `(n + 1)/2` and radius `(r + 1)/2`; with baked lighting
//! the normal channels hold the light direction), `march-start.png` / `march-stop.png` (L16: per
//! bound cell the codes of the least and greatest candidate sector, layout and meaning in
//! [`crate::cylinder::MarchBounds::start`]). Column `c` of the texture is captured at
//! `α_c = 2πc/L`; row `j` at height `y_j = H − (j + ½)H/Ly`.
//!
//! The planner refuses an object the texture cannot hold: the share of the visible surface that
//! radial capture rays hold ([`crate::cylinder::radial_visibility`], the check of `altrep
//! cylinder`, the same at every texture size) below `min_coverage` skips the representation
//! with that reason (use images with parallax instead).

use std::time::Instant;

use altrep_data_gen::{BoundingCylinder, CylinderParams, Supersample};
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::asset::{AssetReader, AssetWriter, Channel, CodeImage, Encoding};
use crate::cylinder::{
    BoundsParams, CoverageParams, CylinderError, CylinderRenderParams, CylindricalTexture,
    ExactMethod, MarchBounds, RadiusModel, radial_visibility, render_exact,
};
use crate::representation::{
    Estimate, InputSize, Lighting, Measurement, Needs, Picture, PipelineError, Plan,
    Representation, Source, Window, elevation_note, fold, linear_bytes, mean_psnr, measure_views,
    secs,
};

/// Manifest parameters of the cylindrical texture (`[asset.cylinder]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CylinderSpec {
    /// Columns `L` (angles; even, ≥ 4). Default 256.
    pub columns: usize,
    /// Rows `Ly`. Default 64; the planner lowers it to the largest screen size.
    pub rows: usize,
    /// Rays per texel side for the albedo prefilter (odd). Default 3.
    pub prefilter: usize,
    /// Cells of the march bounds.
    pub bounds: BoundsParams,
    /// Smallest share of the object's visible surface the radial capture rays must hold,
    /// `[0, 1]`, whatever the texture size. Default 0.5 (see [`CoverageParams::min_share`]).
    pub min_coverage: f64,
}

impl Default for CylinderSpec {
    fn default() -> Self {
        Self {
            columns: 256,
            rows: 64,
            prefilter: 3,
            bounds: BoundsParams::default(),
            min_coverage: 0.5,
        }
    }
}

impl CylinderSpec {
    /// Checks ranges; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if self.columns < 4 || !self.columns.is_multiple_of(2) || self.columns > 8192 {
            return Err(format!(
                "cylinder.columns = {} must be even, in 4..=8192",
                self.columns
            ));
        }
        if !(2..=4096).contains(&self.rows) {
            return Err(format!("cylinder.rows = {} must be in 2..=4096", self.rows));
        }
        if self.prefilter.is_multiple_of(2) || self.prefilter > 7 {
            return Err(format!(
                "cylinder.prefilter = {} must be odd, at most 7",
                self.prefilter
            ));
        }
        self.bounds
            .validate()
            .map_err(|e| format!("cylinder.bounds: {e}"))?;
        if !(0.0..=1.0).contains(&self.min_coverage) {
            return Err(format!(
                "cylinder.min_coverage = {} must be in [0, 1]",
                self.min_coverage
            ));
        }
        Ok(())
    }
}

/// What the planner decided for the cylindrical texture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CylinderDecisions {
    /// Columns captured.
    pub columns: usize,
    /// Rows captured.
    pub rows: usize,
    /// Whether normals are stored (dynamic lighting).
    pub normals: bool,
    /// Share of the object's visible surface the radial capture rays hold (the coverage check,
    /// [`crate::cylinder::radial_visibility`]).
    pub coverage: f64,
    /// Light direction and ambient share (baked colour; relighting of loaded baked data).
    pub light: [f32; 4],
}

/// The cylindrical texture as loaded: the 8-bit texture and its march bounds.
pub struct CylinderData {
    /// The texture (as its 8-bit storage restores it).
    pub texture: CylindricalTexture,
    /// Per-cell march bounds.
    pub bounds: MarchBounds,
}

/// The cylindrical texture for the pipeline.
pub struct Cylinder;

fn texture_params(columns: usize, rows: usize) -> CylinderParams {
    CylinderParams {
        columns,
        rows,
        cylinder: BoundingCylinder::default(),
    }
}

/// The texture size the largest screen size needs: rows a power of two at or above it, at most
/// those asked for, columns in proportion (nothing is skipped when the rows are those asked for).
fn needed_texels(spec: &CylinderSpec, needs: &Needs) -> (usize, usize) {
    let max_px = needs.screen_px[1].ceil() as usize;
    let needed = max_px.next_power_of_two().clamp(2, spec.rows);
    if needed < spec.rows {
        (
            (spec.columns * needed / spec.rows)
                .max(4)
                .next_multiple_of(2),
            needed,
        )
    } else {
        (spec.columns, spec.rows)
    }
}

impl Representation for Cylinder {
    const NAME: &'static str = "cylinder";
    const CASTS_RAYS: bool = true;
    type Spec = CylinderSpec;
    type Data = CylinderData;
    type Decisions = CylinderDecisions;

    fn validate(spec: &Self::Spec) -> Result<(), String> {
        spec.validate()
    }

    fn relevant_needs(needs: &Needs) -> serde_json::Value {
        json!({ "screen_px_max": needs.screen_px[1], "lighting": needs.lighting,
                "azimuth_deg": needs.azimuth_deg, "elevation_deg": needs.elevation_deg })
    }

    fn estimate(spec: &CylinderSpec, needs: &Needs, _input: &InputSize) -> Estimate {
        // ~610 B per texel (capture, offsets, bounds, the read-back copy) measured
        // from 64 × 16 to 1024 × 256.
        let (columns, rows) = needed_texels(spec, needs);
        let texels = (columns * rows) as f64;
        let per_texel = 4.0 + 2.0 + 4.0 * f64::from(needs.lighting == Lighting::Dynamic) + 4.0;
        Estimate {
            peak_bytes: linear_bytes(1.5e6, 610.0, texels),
            output_bytes: linear_bytes(0.0, per_texel, texels),
        }
    }

    fn plan(
        spec: &CylinderSpec,
        needs: &Needs,
        source: &Source,
    ) -> Result<(Plan, CylinderDecisions), PipelineError> {
        let mut plan = Plan::default();
        crate::representation::plan_elevations(
            &mut plan,
            needs,
            source,
            48,
            "cylindrical textures",
        )?;
        // The coverage check answers for the object, not for a texture: the same share at
        // every size, and the same as `altrep cylinder`'s.
        let cov = match radial_visibility(
            source.shape()?,
            BoundingCylinder::default(),
            &CoverageParams::default(),
        ) {
            Ok(c) => c.share,
            Err(CylinderError::NothingVisible { .. }) => 0.0,
            Err(e) => return Err(e.into()),
        };
        if cov < spec.min_coverage {
            plan.refuse(format!(
                "radial capture rays hold {:.1} % of the surface the views see (minimum {:.0} %): \
                 the object is not star-shaped around its axis; use images with parallax",
                100.0 * cov,
                100.0 * spec.min_coverage
            ));
        } else {
            plan.build(format!(
                "coverage check: capture rays hold {:.1} % of the visible surface",
                100.0 * cov
            ));
        }
        let (columns, rows) = needed_texels(spec, needs);
        if rows < spec.rows {
            plan.skip(
                format!("texels above {columns} × {rows}"),
                format!(
                    "the largest screen size is {} px: texture {columns} × {rows} instead of {} × {}",
                    needs.screen_px[1], spec.columns, spec.rows
                ),
            );
        } else {
            plan.build(format!("texture {columns} × {rows}"));
        }
        let normals = needs.lighting == Lighting::Dynamic;
        if !normals {
            plan.skip("normals".into(), "lighting is baked".into());
        }
        plan.build("march bounds".into());
        let d = source.light.direction;
        Ok((
            plan,
            CylinderDecisions {
                columns,
                rows,
                normals,
                coverage: cov,
                light: [d.x, d.y, d.z, source.light.ambient],
            },
        ))
    }

    fn build(
        spec: &CylinderSpec,
        _needs: &Needs,
        d: &CylinderDecisions,
        source: &Source,
    ) -> Result<(CylinderData, serde_json::Value), PipelineError> {
        let t0 = Instant::now();
        let capturing = crate::profile::timer("capture");
        let params = texture_params(d.columns, d.rows);
        let texture = if d.normals {
            CylindricalTexture::capture(source.shape()?, &params, spec.prefilter)?
        } else {
            CylindricalTexture::capture_baked(
                source.shape()?,
                &params,
                spec.prefilter,
                &source.light,
            )?
        };
        capturing.stop();
        let texture = crate::profile::stage("quantisation", || texture.quantized_rgba8());
        let capture_s = secs(t0);
        let (bounds, report) =
            crate::profile::stage("bounds", || MarchBounds::build(&texture, &spec.bounds))?;
        Ok((
            CylinderData { texture, bounds },
            json!({ "capture_s": capture_s, "bounds_s": report.build_s,
                    "bounds_bytes": report.bytes, "texture_defined": d.coverage }),
        ))
    }

    fn write(data: &CylinderData, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError> {
        let t = &data.texture;
        let (cols, rows) = (t.columns(), t.rows());
        let (albedo, geometry) = t.codes();
        let flat = |v: Vec<[u8; 4]>| CodeImage {
            width: cols,
            height: rows,
            channels: 4,
            data: v.into_iter().flatten().collect(),
        };
        let ch = |name: &str, encoding: Encoding| Channel {
            name: name.into(),
            encoding,
        };
        let signed = || Encoding::Linear {
            scale: 2.0 / 255.0,
            offset: -1.0,
        };
        w.png8(
            "texture/albedo",
            "texture-albedo.png",
            &flat(albedo),
            vec![
                ch("albedo.r", Encoding::Srgb),
                ch("albedo.g", Encoding::Srgb),
                ch("albedo.b", Encoding::Srgb),
                ch("defined", Encoding::Mask),
            ],
        )?;
        w.png8(
            "texture/geometry",
            "texture-geometry.png",
            &flat(geometry),
            vec![
                ch("normal.x", signed()),
                ch("normal.y", signed()),
                ch("normal.z", signed()),
                ch("radius", signed()),
            ],
        )?;
        let [bx, ry, ba] = data.bounds.cells();
        for (role, file, codes) in [
            ("bounds/start", "march-start.png", data.bounds.start()),
            ("bounds/stop", "march-stop.png", data.bounds.stop()),
        ] {
            w.png16(
                role,
                file,
                &CodeImage {
                    width: bx,
                    height: ry * ba,
                    channels: 1,
                    data: codes.to_vec(),
                },
                vec![ch(
                    "sector code (see docs/asset-format.md)",
                    Encoding::Integer,
                )],
            )?;
        }
        Ok(json!({
            "columns": cols,
            "rows": rows,
            "column_angle": "column c at α_c = 2πc/columns",
            "bounds": data.bounds.params(),
            "bound_cells": [bx, ry, ba],
        }))
    }

    fn read(r: &AssetReader) -> Result<CylinderData, PipelineError> {
        r.expect_representation(Self::NAME)?;
        let m = &r.description().metadata;
        let get = |k: &str| -> Result<usize, PipelineError> {
            m[k].as_u64()
                .map(|v| v as usize)
                .ok_or_else(|| r.content(format!("metadata.{k} missing")).into())
        };
        let (cols, rows) = (get("columns")?, get("rows")?);
        let params: BoundsParams = serde_json::from_value(m["bounds"].clone())
            .map_err(|e| r.content(format!("metadata.bounds: {e}")))?;
        let quad = |role: &str| -> Result<Vec<[u8; 4]>, PipelineError> {
            let img = r.png8(role)?;
            if (img.width, img.height, img.channels) != (cols, rows, 4) {
                return Err(r
                    .content(format!("{role}: size differs from metadata"))
                    .into());
            }
            Ok(img
                .data
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect())
        };
        let texture = CylindricalTexture::from_codes(
            cols,
            rows,
            BoundingCylinder::default(),
            &quad("texture/albedo")?,
            &quad("texture/geometry")?,
        )?;
        let start = r.png16("bounds/start")?.data;
        let stop = r.png16("bounds/stop")?.data;
        let bounds = MarchBounds::from_codes(&texture, params, start, stop)?;
        Ok(CylinderData { texture, bounds })
    }

    fn measure_size(d: &CylinderDecisions) -> usize {
        d.rows.min(64)
    }

    fn measure(
        data: &CylinderData,
        needs: &Needs,
        size: usize,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError> {
        let mut scores = Vec::new();
        let mut pictures = Vec::new();
        let (mut steps, mut samples) = (0u64, 0u64);
        let mut exact = Vec::new();
        let window = Window::for_needs(needs, size);
        for (i, &view) in measure_views(needs, 4).iter().enumerate() {
            let angle = view.azimuth;
            let reference = window.truth(source, view, Supersample::of(3))?;
            let params = CylinderRenderParams {
                angle,
                width: size,
                height: size,
                supersample: Supersample::ONE,
                light: source.light,
            };
            let mut render = data.bounds.render(&data.texture, &params)?;
            render.image = window.place(&render.image);
            steps += render.steps;
            samples += (render.sub_width * render.sub_height) as u64;
            scores.push(window.score(&render.image, &reference)?);
            let exact_image = render_exact(
                &data.texture,
                ExactMethod::Inverse(RadiusModel::General),
                &params,
            )?
            .image;
            exact.push(window.score(&window.place(&exact_image), &reference)?);
            if i == 0 {
                pictures.push(Picture {
                    file: format!("{}-cylinder.png", source.name),
                    caption: format!(
                        "{}: ground truth | cylindrical texture (bounded exact march), azimuth {:.0}°, elevation {:.0}°",
                        source.name,
                        angle.to_degrees(),
                        view.elevation.to_degrees()
                    ),
                    image: altrep_data_gen::RgbaImage::side_by_side(&[&reference, &render.image]),
                });
            }
        }
        let method = format!(
            "bounded exact march of the {} × {} texture, 1 ray per pixel at {size}², vs truth 3×3 supersampled{}; sector tests per pixel; exact inverse warping at the same views beside it",
            data.texture.columns(),
            data.texture.rows(),
            elevation_note(needs, window)
        );
        let mean = (samples > 0).then(|| steps as f64 / samples as f64);
        let mut m = fold(method, &scores, mean);
        m.exact_psnr_db = mean_psnr(&exact);
        m.size = size;
        Ok((m, pictures))
    }
}
