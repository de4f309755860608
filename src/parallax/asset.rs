//! Images with parallax in the pipeline: planning from the needs, files, loading, measuring.
//!
//! Files per present view `k` (absent views were skipped by the planner and load as empty):
//! `view{k}-albedo.png` (RGBA8: sRGB albedo, or the baked shaded colour; alpha 255 = defined),
//! `view{k}-normal.png` (RGB8, `(n + 1)/2`; absent when lighting is baked),
//! `view{k}-depth.png` (L8 or L16 unorm of `(z/R + 1)/2`), `view{k}-mip{l}.png` (RGBA8 colour mip
//! levels the screen sizes need, straight alpha = coverage), and per bound kind
//! `view{k}-bounds-{kind}-c.png` (L16 or LA16 per slot: 0 = empty, 1 = `c = −1`, 2 = `c = +1`,
//! `q + 3` = `c0 + q·step`) with `view{k}-bounds-{kind}-v.png` (`v_min`, `v_max` per slot, 8 or
//! 16 bits, `v = lo + q·step` per channel as listed in `asset.json`). The present views also
//! form an impostor atlas with gutters, `atlas-mip{l}.png` for level 0 and the kept mip levels
//! ([`crate::pyramid::atlas`]; layout in `asset.json`), checked against the views on reading.

use std::time::Instant;

use altrep_data_gen::{
    BoundingCylinder, Projection, SampleGrid, Supersample, ViewParams, capture_view,
};
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::asset::{AssetReader, AssetWriter, Channel, CodeImage, Encoding};
use crate::parallax::{
    BoundKind, BoundParams, Bounds, ParallaxImages, ParallaxParams, Reconstruction, RenderParams,
    ViewCodes, ViewStorage, WarpMethod, build_bounds, render, render_bounded_with,
};
use crate::representation::{
    Estimate, InputSize, Lighting, Measurement, Needs, Picture, PipelineError, Plan,
    Representation, Source, Window, elevation_note, fold, linear_bytes, mean_psnr, measure_views,
    secs,
};

mod format;
use format::{check_size, read_bounds, rgba8_of, verify_atlas, write_atlas, write_bounds};

/// Manifest parameters of images with parallax (`[asset.parallax]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ParallaxSpec {
    /// Number of views `N` around the vertical axis (default 8).
    pub views: usize,
    /// Width and height of each view in texels (default 64); the planner lowers it to the largest
    /// screen size.
    pub size: usize,
    /// Depth bits, 8 or 16 (default 8).
    pub depth_bits: u32,
    /// Bound kinds to precompute: `cylinder`, `zminmax`, `pair`, `best_c`, `best_c_split`
    /// (default `["best_c"]`).
    pub bounds: Vec<String>,
    /// Bits per bound channel, 8 or 16 (default 8).
    pub bound_bits: u32,
}

impl Default for ParallaxSpec {
    fn default() -> Self {
        Self {
            views: 8,
            size: 64,
            depth_bits: 8,
            bounds: vec!["best_c".into()],
            bound_bits: 8,
        }
    }
}

fn kind_of(slug: &str) -> Option<BoundKind> {
    BoundKind::ALL.into_iter().find(|k| k.slug() == slug)
}

impl ParallaxSpec {
    /// Checks ranges; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        let counts = ParallaxParams::VIEW_COUNTS;
        if !counts.contains(&self.views) {
            return Err(format!(
                "parallax.views = {} must be in {}..={}",
                self.views,
                counts.start(),
                counts.end()
            ));
        }
        if !(2..=4096).contains(&self.size) {
            return Err(format!("parallax.size = {} must be in 2..=4096", self.size));
        }
        if ![8, 16].contains(&self.depth_bits) {
            return Err(format!(
                "parallax.depth_bits = {} must be 8 or 16",
                self.depth_bits
            ));
        }
        if ![8, 16].contains(&self.bound_bits) {
            return Err(format!(
                "parallax.bound_bits = {} must be 8 or 16 (files store unorm codes)",
                self.bound_bits
            ));
        }
        for b in &self.bounds {
            if kind_of(b).is_none() {
                return Err(format!(
                    "parallax.bounds: unknown kind '{b}' (cylinder, zminmax, pair, best_c, best_c_split)"
                ));
            }
        }
        Ok(())
    }

    fn params(&self, size: usize) -> ParallaxParams {
        ParallaxParams {
            views: self.views,
            width: size,
            height: size,
            depth_bits: self.depth_bits,
            ..ParallaxParams::default()
        }
    }
}

/// What the planner decided for images with parallax.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParallaxDecisions {
    /// View size actually captured.
    pub size: usize,
    /// Indices of the views captured and stored.
    pub views: Vec<usize>,
    /// Whether normals are stored (dynamic lighting).
    pub normals: bool,
    /// Mip levels stored beside level 0.
    pub mip_levels: Vec<usize>,
    /// Bound kinds built.
    pub bounds: Vec<String>,
    /// Light direction (baked colour and relighting of loaded baked data).
    pub light: [f32; 3],
    /// Ambient share.
    pub ambient: f32,
}

/// Images with parallax, as loaded: the views and the bounds of every kind built.
pub struct ParallaxData {
    /// The views.
    pub images: ParallaxImages,
    /// Bounds per kind.
    pub bounds: Vec<Bounds>,
    /// The decisions they were built with.
    pub decisions: ParallaxDecisions,
}

/// Whether view `k` of `n` is used by some azimuth in the needed range: a display angle uses
/// the two views that bracket it, so view `k` serves `(α_k − Δ, α_k + Δ)`, `Δ = 2π/n`.
/// The view size the largest screen size needs: a power of two at or above it, at most `size`
/// (nothing is skipped when that is the size asked for).
fn needed_size(size: usize, needs: &Needs) -> usize {
    let max_px = needs.screen_px[1].ceil() as usize;
    max_px.next_power_of_two().clamp(2, size)
}

fn view_needed(k: usize, n: usize, needs: &Needs) -> bool {
    if needs.all_azimuths() {
        return true;
    }
    let delta = 360.0 / n as f64;
    let ak = delta * k as f64;
    let [a0, a1] = needs.azimuth_deg;
    // Distance from α_k to the range, on the circle.
    let mid = 0.5 * (a0 + a1);
    let half = 0.5 * (a1 - a0);
    let d = ((ak - mid).rem_euclid(360.0)).min((mid - ak).rem_euclid(360.0));
    d < half + delta
}

/// The screen-size interval (pixels) in which mip level `l` of a `size`-texel view is drawn:
/// level `round(log2(size/px))`.
fn level_needed(l: usize, size: usize, needs: &Needs) -> bool {
    let lo = size as f64 / 2f64.powf(l as f64 + 0.5);
    let hi = size as f64 / 2f64.powf(l as f64 - 0.5);
    let [p0, p1] = needs.screen_px;
    p1 >= lo && p0 < hi
}

/// The parallax representation for the pipeline.
pub struct Parallax;

impl Representation for Parallax {
    const NAME: &'static str = "parallax";
    const CASTS_RAYS: bool = true;
    type Spec = ParallaxSpec;
    type Data = ParallaxData;
    type Decisions = ParallaxDecisions;

    fn validate(spec: &Self::Spec) -> Result<(), String> {
        spec.validate()
    }

    fn relevant_needs(needs: &Needs) -> serde_json::Value {
        json!({ "azimuth_deg": needs.azimuth_deg, "elevation_deg": needs.elevation_deg,
                "screen_px": needs.screen_px, "lighting": needs.lighting })
    }

    fn estimate(spec: &ParallaxSpec, needs: &Needs, _input: &InputSize) -> Estimate {
        // Every view's grid is held during the capture, needed or not; ~730 B per view texel
        // (samples, images, mips, bounds, the read-back copy) measured at 32²–256², 4–16 views.
        let size = needed_size(spec.size, needs) as f64;
        let texels = spec.views as f64 * size * size;
        let kinds = spec.bounds.len().saturating_sub(1) as f64;
        let needed = (0..spec.views)
            .filter(|&k| view_needed(k, spec.views, needs))
            .count() as f64;
        let per_texel =
            6.0 + 4.0 * f64::from(needs.lighting == Lighting::Dynamic) + 4.0 * (kinds + 1.0);
        Estimate {
            peak_bytes: linear_bytes(1e6, 740.0 + 150.0 * kinds, texels),
            output_bytes: linear_bytes(0.0, per_texel * 4.0 / 3.0, needed * size * size),
        }
    }

    fn plan(
        spec: &ParallaxSpec,
        needs: &Needs,
        source: &Source,
    ) -> Result<(Plan, ParallaxDecisions), PipelineError> {
        let mut plan = Plan::default();
        crate::representation::plan_elevations(
            &mut plan,
            needs,
            source,
            48,
            "images with parallax",
        )?;
        let needed = needed_size(spec.size, needs);
        let size = if needed < spec.size {
            let s = needed;
            plan.skip(
                format!("texels above {s}² per view"),
                format!(
                    "the largest screen size is {} px: views captured at {s}² instead of {}²",
                    needs.screen_px[1], spec.size
                ),
            );
            s
        } else {
            plan.build(format!("{}² per view", spec.size));
            spec.size
        };
        let mut views = Vec::new();
        for k in 0..spec.views {
            let deg = 360.0 * k as f64 / spec.views as f64;
            if view_needed(k, spec.views, needs) {
                views.push(k);
            } else {
                plan.skip(
                    format!("view {k} ({deg:.0}°)"),
                    format!(
                        "outside the azimuth range [{}°, {}°] and its bracketing margin",
                        needs.azimuth_deg[0], needs.azimuth_deg[1]
                    ),
                );
            }
        }
        plan.build(format!("{} of {} views", views.len(), spec.views));
        let normals = needs.lighting == Lighting::Dynamic;
        if !normals {
            plan.skip("normals".into(), "lighting is baked".into());
        }
        let levels = (usize::BITS - size.leading_zeros()) as usize; // 1 + log2(size)
        let mut mip_levels = Vec::new();
        for l in 1..levels {
            if level_needed(l, size, needs) {
                mip_levels.push(l);
            } else {
                let s = size >> l;
                plan.skip(
                    format!("mip level {l} ({s}²)"),
                    if (s as f64) < needs.screen_px[0] / 2f64.sqrt() {
                        format!(
                            "coarser than any screen size: the smallest is {} px",
                            needs.screen_px[0]
                        )
                    } else {
                        format!(
                            "finer than any screen size: the largest is {} px",
                            needs.screen_px[1]
                        )
                    },
                );
            }
        }
        for b in &spec.bounds {
            if b == "cylinder" {
                plan.build("bounds cylinder (computed in the shader, no file)".into());
            } else {
                plan.build(format!("bounds {b}"));
            }
        }
        let d = source.light.direction;
        Ok((
            plan,
            ParallaxDecisions {
                size,
                views,
                normals,
                mip_levels,
                bounds: spec.bounds.clone(),
                light: [d.x, d.y, d.z],
                ambient: source.light.ambient,
            },
        ))
    }

    fn build(
        spec: &ParallaxSpec,
        _needs: &Needs,
        decisions: &ParallaxDecisions,
        source: &Source,
    ) -> Result<(ParallaxData, serde_json::Value), PipelineError> {
        let params = spec.params(decisions.size);
        let t0 = Instant::now();
        let capturing = crate::profile::timer("capture");
        let grids = (0..params.views)
            .into_par_iter()
            .map(|k| -> Result<SampleGrid, PipelineError> {
                let angle = params.view_angle(k);
                if !decisions.views.contains(&k) {
                    return Ok(SampleGrid {
                        width: params.width,
                        height: params.height,
                        cylinder: params.cylinder,
                        projection: Projection::Orthographic { angle },
                        samples: vec![None; params.width * params.height],
                    });
                }
                let mut g = capture_view(
                    source.shape()?,
                    &ViewParams {
                        angle,
                        width: params.width,
                        height: params.height,
                        cylinder: params.cylinder,
                    },
                )?;
                if !decisions.normals {
                    // Baked: the shaded colour in the albedo slot and the normal toward the
                    // light, so relighting with the same light is the identity.
                    let light = source.light;
                    for s in g.samples.iter_mut().flatten() {
                        s.albedo = light.shade(s.albedo, s.normal);
                        s.normal = light.direction;
                    }
                }
                Ok(g)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let capture_s = secs(t0);
        if grids.iter().all(|g| g.samples.iter().all(Option::is_none)) {
            return Err(PipelineError::Invisible {
                asset: source.name.into(),
                what: "every captured view of images with parallax".into(),
            });
        }
        let images = ParallaxImages::from_grids(&grids, &params)?;
        capturing.stop();
        let bound_params = BoundParams {
            bits: spec.bound_bits,
            ..BoundParams::default()
        };
        let mut bounds = Vec::new();
        let mut bound_report = Vec::new();
        for b in &decisions.bounds {
            let kind = kind_of(b).ok_or_else(|| PipelineError::Spec(format!("bound kind {b}")))?;
            let t = Instant::now();
            let bd =
                crate::profile::stage("bounds", || build_bounds(&images, kind, &bound_params))?;
            bound_report.push(json!({ "kind": b, "seconds": secs(t), "bytes": bd.bytes(&images) }));
            bounds.push(bd);
        }
        let report = json!({
            "capture_s": capture_s,
            "views_captured": decisions.views.len(),
            "bounds": bound_report,
        });
        Ok((
            ParallaxData {
                images,
                bounds,
                decisions: decisions.clone(),
            },
            report,
        ))
    }

    fn write(data: &ParallaxData, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError> {
        let p = &data.images.params;
        let d = &data.decisions;
        let codes = data.images.codes();
        let (wd, ht) = (p.width, p.height);
        let ch = |name: &str, encoding: Encoding| Channel {
            name: name.into(),
            encoding,
        };
        let unorm = |bits: u32, lo: f64, hi: f64| Encoding::Linear {
            scale: (hi - lo) / ((1u64 << bits) - 1) as f64,
            offset: lo,
        };
        for &k in &d.views {
            let c = &codes[k];
            let mut albedo = CodeImage::<u8>::new(wd, ht, 4);
            let mut normal = CodeImage::<u8>::new(wd, ht, 3);
            for idx in 0..wd * ht {
                if c.defined[idx] {
                    albedo.pixel_mut(idx)[..3].copy_from_slice(&c.albedo[idx]);
                    albedo.pixel_mut(idx)[3] = 255;
                    normal.pixel_mut(idx).copy_from_slice(&c.normal[idx]);
                }
            }
            w.png8(
                &format!("view{k}/albedo"),
                &format!("view{k}-albedo.png"),
                &albedo,
                vec![
                    ch("albedo.r", Encoding::Srgb),
                    ch("albedo.g", Encoding::Srgb),
                    ch("albedo.b", Encoding::Srgb),
                    ch("defined", Encoding::Mask),
                ],
            )?;
            if d.normals {
                let e = || unorm(8, -1.0, 1.0);
                w.png8(
                    &format!("view{k}/normal"),
                    &format!("view{k}-normal.png"),
                    &normal,
                    vec![
                        ch("normal.x", e()),
                        ch("normal.y", e()),
                        ch("normal.z", e()),
                    ],
                )?;
            }
            let depth_enc = vec![ch("depth", unorm(p.depth_bits, -1.0, 1.0))];
            let role = format!("view{k}/depth");
            let file = format!("view{k}-depth.png");
            if p.depth_bits == 16 {
                let img = CodeImage {
                    width: wd,
                    height: ht,
                    channels: 1,
                    data: c.depth.clone(),
                };
                w.png16(&role, &file, &img, depth_enc)?;
            } else {
                let img = CodeImage {
                    width: wd,
                    height: ht,
                    channels: 1,
                    data: c.depth.iter().map(|&v| v as u8).collect(),
                };
                w.png8(&role, &file, &img, depth_enc)?;
            }
            for &l in &d.mip_levels {
                // Colour and coverage of the level (its first four of eight channels).
                let img = rgba8_of(&data.images.pyramids()[k].levels()[l]);
                w.png8(
                    &format!("view{k}/mip{l}"),
                    &format!("view{k}-mip{l}.png"),
                    &img,
                    vec![
                        ch("colour.r", Encoding::Srgb),
                        ch("colour.g", Encoding::Srgb),
                        ch("colour.b", Encoding::Srgb),
                        ch("coverage", unorm(8, 0.0, 1.0)),
                    ],
                )?;
            }
            for b in &data.bounds {
                if b.kind == BoundKind::Cylinder {
                    continue;
                }
                write_bounds(w, b, k, wd, ht)?;
            }
        }
        let atlas = write_atlas(data, w)?;
        Ok(json!({
            "atlas": atlas,
            "views": p.views,
            "width": p.width,
            "height": p.height,
            "depth_bits": p.depth_bits,
            "continuity_texels": p.continuity_texels,
            "view_angle": "view k at α_k = 2πk/views",
            "present_views": d.views,
            "normals": d.normals,
            "mip_levels": d.mip_levels,
            "bounds": data.bounds.iter().map(|b| json!({
                "kind": b.kind.slug(),
                "bits": b.params.bits,
                "subdivisions": b.params.subdivisions,
                "c_limit": b.params.c_limit,
            })).collect::<Vec<_>>(),
            "light": d.light,
            "ambient": d.ambient,
            "decisions": d,
        }))
    }

    fn read(r: &AssetReader) -> Result<ParallaxData, PipelineError> {
        r.expect_representation(Self::NAME)?;
        let m = &r.description().metadata;
        let decisions: ParallaxDecisions = serde_json::from_value(m["decisions"].clone())
            .map_err(|e| r.content(format!("metadata.decisions: {e}")))?;
        let get = |key: &str| -> Result<u64, PipelineError> {
            m[key]
                .as_u64()
                .ok_or_else(|| r.content(format!("metadata.{key} missing")).into())
        };
        let params = ParallaxParams {
            views: get("views")? as usize,
            width: get("width")? as usize,
            height: get("height")? as usize,
            depth_bits: get("depth_bits")? as u32,
            continuity_texels: m["continuity_texels"]
                .as_f64()
                .ok_or_else(|| r.content("metadata.continuity_texels missing".into()))?,
            cylinder: BoundingCylinder::default(),
        };
        params.validate()?;
        let (wd, ht) = (params.width, params.height);
        let baked_normal = {
            let l = Vec3::from_array(decisions.light);
            let q = |c: f32| crate::parallax::normal_code(c);
            [q(l.x), q(l.y), q(l.z)]
        };
        let mut codes = vec![ViewCodes::empty(wd, ht); params.views];
        for &k in &decisions.views {
            if k >= params.views {
                return Err(r
                    .content(format!("present view {k} beyond {} views", params.views))
                    .into());
            }
            let albedo = r.png8(&format!("view{k}/albedo"))?;
            check_size(r, &albedo, wd, ht, 4, "albedo")?;
            let c = &mut codes[k];
            for idx in 0..wd * ht {
                let px = albedo.pixel(idx);
                c.defined[idx] = px[3] != 0;
                if c.defined[idx] {
                    c.albedo[idx] = [px[0], px[1], px[2]];
                    c.normal[idx] = baked_normal;
                }
            }
            if decisions.normals {
                let normal = r.png8(&format!("view{k}/normal"))?;
                check_size(r, &normal, wd, ht, 3, "normal")?;
                for idx in (0..wd * ht).filter(|&i| c.defined[i]) {
                    let px = normal.pixel(idx);
                    c.normal[idx] = [px[0], px[1], px[2]];
                }
            }
            let role = format!("view{k}/depth");
            let depth: Vec<u16> = if params.depth_bits == 16 {
                let d = r.png16(&role)?;
                check_size(r, &d, wd, ht, 1, "depth")?;
                d.data
            } else {
                let d = r.png8(&role)?;
                check_size(r, &d, wd, ht, 1, "depth")?;
                d.data.into_iter().map(u16::from).collect()
            };
            for idx in (0..wd * ht).filter(|&i| c.defined[i]) {
                c.depth[idx] = depth[idx];
            }
        }
        let images = ParallaxImages::from_codes(&params, &codes)?;
        verify_atlas(r, &images, &decisions)?;
        let mut bounds = Vec::new();
        let list = m["bounds"]
            .as_array()
            .ok_or_else(|| r.content("metadata.bounds missing".into()))?;
        for b in list {
            let slug = b["kind"].as_str().unwrap_or_default();
            let kind = kind_of(slug).ok_or_else(|| r.content(format!("bound kind '{slug}'")))?;
            let bp = BoundParams {
                bits: b["bits"].as_u64().unwrap_or(0) as u32,
                subdivisions: b["subdivisions"].as_u64().unwrap_or(0) as usize,
                c_limit: b["c_limit"].as_f64().unwrap_or(f64::NAN),
            };
            if kind == BoundKind::Cylinder {
                bounds.push(Bounds::from_slots(
                    &images,
                    kind,
                    bp,
                    Vec::new(),
                    Vec::new(),
                )?);
                continue;
            }
            let mut views = vec![vec![[None, None]; wd * ht]; params.views];
            let mut storage = vec![ViewStorage::default(); params.views];
            for &k in &decisions.views {
                (views[k], storage[k]) = read_bounds(r, kind, bp.bits, k, wd, ht)?;
            }
            bounds.push(Bounds::from_slots(&images, kind, bp, views, storage)?);
        }
        Ok(ParallaxData {
            images,
            bounds,
            decisions,
        })
    }

    fn measure_size(d: &ParallaxDecisions) -> usize {
        d.size
    }

    fn measure(
        data: &ParallaxData,
        needs: &Needs,
        size: usize,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError> {
        let images = &data.images;
        let native = images.params.width;
        // Views larger than the measured size (a run that ignored the needs) are drawn minified
        // through their mip levels, as a display draws them at that screen size; the bounded
        // march runs at the views' own size only, so its steps are counted there.
        let minified = size != native;
        let mut scores = Vec::new();
        let mut pictures = Vec::new();
        // Steps of the two bracketing views, the fallback views and hole filling, and pixels.
        let (mut steps, mut fallback, mut holes, mut pixels) = (0u64, 0u64, 0u64, 0u64);
        let mut exact = Vec::new();
        // Steps are counted with the tightest stored bound (the kinds are ordered (a)–(e)).
        let bounded = data
            .bounds
            .iter()
            .filter(|b| b.kind != BoundKind::Cylinder)
            .max_by_key(|b| BoundKind::ALL.iter().position(|&k| k == b.kind));
        let window = Window::for_needs(needs, size);
        for (i, &view) in measure_views(needs, 4).iter().enumerate() {
            let angle = view.azimuth;
            let reference = window.truth(source, view, Supersample::of(3))?;
            // At the views' own size this is `RenderParams::native`, point-sampled.
            let screen = RenderParams {
                width: size,
                height: size * images.params.height / native,
                supersample: Supersample::ONE,
                light: source.light,
                mip: minified,
            };
            // The exact inverse warp; where a bound is stored, the figures come from the
            // bounded march a display runs (the same image by design) and the warp's beside it.
            let warped = window.place(&render(images, angle, WarpMethod::Inverse, &screen)?);
            let img = match bounded {
                Some(b) => {
                    let r = render_bounded_with(
                        images,
                        b,
                        angle,
                        &source.light,
                        &Reconstruction::DEFAULT,
                    )?;
                    steps += r.steps;
                    fallback += r.fallback_steps;
                    holes += r.hole_steps;
                    pixels += (native * images.params.height) as u64;
                    if minified {
                        warped
                    } else {
                        exact.push(window.score(&warped, &reference)?);
                        window.place(&r.image)
                    }
                }
                None => warped,
            };
            scores.push(window.score(&img, &reference)?);
            if i == 0 {
                pictures.push(Picture {
                    file: format!("{}-parallax.png", source.name),
                    caption: format!(
                        "{}: ground truth | images with parallax, azimuth {:.0}°, elevation {:.0}°",
                        source.name,
                        angle.to_degrees(),
                        view.elevation.to_degrees()
                    ),
                    image: altrep_data_gen::RgbaImage::side_by_side(&[&reference, &img]),
                });
            }
        }
        let method = format!(
            "{} of {} views of {native}²{}, 1 ray per pixel, vs truth 3×3 supersampled{}; march steps per pixel with {}{}: the two bracketing views, the fallback views and hole filling where they miss",
            if bounded.is_some() && !minified {
                "bounded march (exact inverse warp beside it)"
            } else {
                "inverse warp"
            },
            images.params.views,
            if minified {
                format!(" drawn at {size}² through their mip levels")
            } else {
                String::new()
            },
            elevation_note(needs, window),
            bounded.map_or("no stored bound", |b| b.kind.name()),
            if minified {
                format!(" at {native}²")
            } else {
                String::new()
            },
        );
        let per_pixel = |n: u64| n as f64 / pixels as f64;
        let mean_steps = (pixels > 0).then(|| per_pixel(steps + fallback + holes));
        let mut m = fold(method, &scores, mean_steps);
        m.exact_psnr_db = mean_psnr(&exact);
        m.size = size;
        if pixels > 0 {
            m.steps_split = vec![
                ("bracketing views".into(), per_pixel(steps)),
                ("fallback views".into(), per_pixel(fallback)),
                ("hole filling".into(), per_pixel(holes)),
            ];
        }
        Ok((m, pictures))
    }
}
