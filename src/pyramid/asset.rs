//! Texture pyramids (docs/design.md §10) in the pipeline: a mipmap or a ripmap of a texture asset,
//! only the levels the scene's screen sizes use.
//!
//! **Kind.** Views that never tilt beyond `mip_max_tilt_deg` from the polygon normal
//! (`needs.grazing_deg ≤ mip_max_tilt_deg`) get a mipmap; more grazing views a ripmap, whose
//! axis-separate levels follow the foreshortened footprint. Views that reach `fip_min_tilt_deg`
//! (or `kind = "Fip"` in the manifest, with views beyond the mipmap's range) get the fipmap
//! database (mipmap, ripmap and the ripmaps of the sheared copies, [`crate::pyramid::fip`]),
//! chosen per lookup by the camera direction; fipmaps shear periodic textures only, so a texture
//! that does not wrap on both axes gets the ripmap and the plan says why.
//!
//! **Levels.** Level `l` of an axis has `n_l = max(1, ⌊n/2^l⌋)` texels; trilinear (and the
//! ripmap's bilinear-in-λ) lookups read it while the texture covers between `n_l/2` and `2·n_l`
//! pixels along that axis. The texture covers at most `screen_px[1]` pixels (face on) and at
//! least `screen_px[0]·cos(grazing_deg)` (foreshortened), so levels with `n_l ≥ 2·screen_px[1]`
//! (finer than the largest screen size) and levels with `2·n_l ≤ screen_px[0]·cos(grazing)`
//! (coarser than the smallest) are skipped. For a mipmap `n` is the larger side.
//!
//! **Files.** One OpenEXR (32-bit float RGBA, lossless) per kept level, named as
//! [`crate::pyramid::PyramidData::textures`] names the level in the full pyramid: `mip{l}.exr`,
//! `rip_u{lu}_v{lv}.exr`, and for a fipmap also `fip_{axis}{num}over{den}_u{lu}_v{lv}.exr` per
//! shear (the same kept level indices as the ripmap: a sheared copy has the texel density of the
//! original); a texture of fewer than 4 channels fills the rest with 0.
//!
//! **Measurement.** The loaded levels are looked up (mip: trilinear with Heckbert's level;
//! rip: four bilinear levels; fip: the per-pixel mip/rip/fip decision from the camera direction) at every pixel of the textured plane of
//! [`crate::pyramid::truth`] at tilts `0, g/2, g` (`g = grazing_deg`, azimuth 30°) and screen
//! sizes `screen_px[1]` and `√(screen_px[0]·screen_px[1])`, against the stratified supersampled
//! truth of the original texture (periodic). PSNR with peak 1 over pixels and channels.

use std::time::Instant;

use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::asset::{AssetReader, AssetWriter, Channel, Encoding, FloatImage};
use crate::pyramid::fip::shear_set;
use crate::pyramid::rip::halvings;
use crate::pyramid::truth::{PlaneView, footprints, supersampled_truth};
use crate::pyramid::{
    FipMap, Pyramid, PyramidData, PyramidKind, PyramidParams, RipMap, Texture, WrapMode,
    shear_prefix,
};
use crate::representation::{
    Estimate, InputSize, Measurement, Needs, Picture, PipelineError, Plan, Representation, Source,
    fold, linear_bytes, secs,
};

/// Side of the measured images (pixels).
const MEASURE_PIXELS: usize = 16;
/// Cap on truth samples per pixel.
const MEASURE_SAMPLES: usize = 1024;
/// Azimuth of the measured views from the texture's `u` axis (degrees): skewed, so neither
/// axis-aligned case flatters the ripmap.
const MEASURE_AZIMUTH_DEG: f64 = 30.0;

/// What the planner decided for a pyramid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PyramidDecisions {
    /// `Mip`, `Rip` or `Fip`.
    pub kind: PyramidKind,
    /// First and last kept level along `u` (for a mipmap: the levels).
    pub levels_u: [usize; 2],
    /// First and last kept level along `v` (for a mipmap: equal to `levels_u`).
    pub levels_v: [usize; 2],
    /// First and last kept level of a fipmap's mipmap (unused otherwise).
    #[serde(default)]
    pub levels_mip: [usize; 2],
}

/// A pyramid as loaded: the kept levels as a lookup structure and where they start.
pub struct PyramidAsset {
    /// The kept levels (`Mip` or `Rip`; the first kept level acts as level 0 in lookups).
    pub data: PyramidData,
    /// Index, in the full pyramid, of the first kept level along `u` and `v`.
    pub first: [usize; 2],
    /// Size of the original texture (level 0 of the full pyramid).
    pub base: [usize; 2],
    /// Index, in the full pyramid, of the first kept level of a fipmap's mipmap (0 otherwise).
    pub first_mip: usize,
}

impl PyramidAsset {
    /// Every stored level with its file stem (its name in the full pyramid) and texture.
    pub fn levels(&self) -> Vec<(String, &Texture)> {
        let [fu, fv] = self.first;
        match &self.data {
            PyramidData::Mip(p) => p
                .levels()
                .iter()
                .enumerate()
                .map(|(l, t)| (format!("mip{}", fu + l), t))
                .collect(),
            PyramidData::Rip(r) => {
                let (nu, nv) = r.level_counts();
                (0..nv)
                    .flat_map(|lv| (0..nu).map(move |lu| (lu, lv)))
                    .map(|(lu, lv)| (format!("rip_u{}_v{}", fu + lu, fv + lv), r.level(lu, lv)))
                    .collect()
            }
            PyramidData::Fip(f) => {
                fn rip<'a>(
                    prefix: &str,
                    r: &'a RipMap,
                    fu: usize,
                    fv: usize,
                ) -> Vec<(String, &'a Texture)> {
                    let (nu, nv) = r.level_counts();
                    (0..nv)
                        .flat_map(|lv| (0..nu).map(move |lu| (lu, lv)))
                        .map(|(lu, lv)| {
                            (
                                format!("{prefix}_u{}_v{}", fu + lu, fv + lv),
                                r.level(lu, lv),
                            )
                        })
                        .collect()
                }
                let mut v: Vec<(String, &Texture)> = f
                    .mip()
                    .levels()
                    .iter()
                    .enumerate()
                    .map(|(l, t)| (format!("mip{}", self.first_mip + l), t))
                    .collect();
                v.extend(rip("rip", f.rip(), fu, fv));
                for (i, sh) in f.shears().iter().enumerate() {
                    v.extend(rip(&shear_prefix(sh), f.sheared(i), fu, fv));
                }
                v
            }
        }
    }

    /// Looks up `(u, v)` with screen derivatives and the direction to the camera in the frame
    /// of the textured polygon (`(r, g, b)`: `u`, normal, `v`) into `out`: a fipmap picks mip,
    /// rip or a sheared ripmap by [`FipMap::decide`]; a mipmap or ripmap ignores `dir`.
    pub fn sample_dir_into(&self, u: f64, v: f64, d: [f64; 4], dir: [f64; 3], out: &mut [f32]) {
        match &self.data {
            PyramidData::Fip(f) => {
                let [ux, vx, uy, vy] = d;
                f.sample_into(f.decide(dir), u, v, ux, vx, uy, vy, None, out);
            }
            _ => self.sample_into(u, v, d, out),
        }
    }

    /// Looks up `(u, v)` with screen derivatives into `out` (trilinear mip or ripmap).
    pub fn sample_into(&self, u: f64, v: f64, d: [f64; 4], out: &mut [f32]) {
        let [ux, vx, uy, vy] = d;
        match &self.data {
            PyramidData::Mip(p) => out.copy_from_slice(&p.sample_grad(u, v, ux, vx, uy, vy)),
            PyramidData::Rip(r) => r.sample_lod_into(u, v, r.lod(ux, vx, uy, vy), out),
            PyramidData::Fip(f) => {
                f.sample_into(crate::pyramid::Scheme::Rip, u, v, ux, vx, uy, vy, None, out);
            }
        }
    }

    /// Channels per texel.
    pub fn channels(&self) -> usize {
        self.levels().first().map_or(0, |(_, t)| t.channels)
    }
}

/// The texture pyramid for the pipeline.
pub struct PyramidRepr;

/// Kept levels `[first, last]` of an axis of `n` texels (module docs), and the skipped ones
/// with their reasons.
fn keep_levels(n: usize, needs: &Needs, axis: &str, plan: &mut Plan, record: bool) -> [usize; 2] {
    let sizes = halvings(n);
    let s_max = needs.screen_px[1];
    let cos_g = needs.grazing_deg.to_radians().cos();
    let s_min = needs.screen_px[0] * cos_g;
    let first = sizes
        .iter()
        .position(|&nl| (nl as f64) < 2.0 * s_max)
        .unwrap_or(sizes.len() - 1);
    let last = sizes
        .iter()
        .rposition(|&nl| 2.0 * nl as f64 > s_min)
        .unwrap_or(first)
        .max(first);
    if record {
        for (l, &nl) in sizes.iter().enumerate() {
            let what = format!("{axis}level {l} ({nl} texels)");
            if l < first {
                plan.skip(
                    what,
                    format!(
                        "finer than the largest screen size: the texture covers at most {s_max} px, \
                         level {l} is read only above {} px",
                        nl / 2
                    ),
                );
            } else if l > last {
                plan.skip(
                    what,
                    format!(
                        "coarser than the smallest screen size: the texture covers at least \
                         {:.2} px ({} px at up to {}° from the normal), level {l} is read only below {} px",
                        s_min,
                        needs.screen_px[0],
                        needs.grazing_deg,
                        2 * nl
                    ),
                );
            } else {
                plan.build(what);
            }
        }
    }
    [first, last]
}

impl Representation for PyramidRepr {
    const NAME: &'static str = "pyramid";
    const FROM_TEXTURE: bool = true;
    const CASTS_RAYS: bool = false;
    type Spec = PyramidParams;
    type Data = PyramidAsset;
    type Decisions = PyramidDecisions;

    fn validate(spec: &Self::Spec) -> Result<(), String> {
        spec.validate(4).map_err(|e| format!("pyramid: {e}"))
    }

    fn relevant_needs(needs: &Needs) -> serde_json::Value {
        json!({ "screen_px": needs.screen_px, "grazing_deg": needs.grazing_deg })
    }

    fn estimate(spec: &PyramidParams, needs: &Needs, input: &InputSize) -> Estimate {
        // ~45–55 B per texel and channel (the texture, the pyramid, the measuring, the read-back
        // copy) measured on one-channel textures of 64² to 1024², mipmaps to fipmaps.
        let Some((w, h, c)) = input.texture else {
            return Estimate::default();
        };
        let texels = (w * h * c.max(1)) as f64;
        let g = needs.grazing_deg;
        let layers = if g <= spec.mip_max_tilt_deg {
            4.0 / 3.0
        } else if spec.kind == PyramidKind::Fip || g >= spec.fip_min_tilt_deg {
            4.0 * (1 + shear_set(spec.fip_shear_steps).len()) as f64
        } else {
            4.0
        };
        Estimate {
            peak_bytes: linear_bytes(1.5e6, 55.0, texels),
            output_bytes: linear_bytes(0.0, 4.0 * layers, texels),
        }
    }

    fn plan(
        spec: &PyramidParams,
        needs: &Needs,
        source: &Source,
    ) -> Result<(Plan, PyramidDecisions), PipelineError> {
        let tex = source.texture()?;
        spec.validate(tex.channels)?;
        let mut plan = Plan::default();
        let g = needs.grazing_deg;
        let wants_fip = spec.kind == PyramidKind::Fip || g >= spec.fip_min_tilt_deg;
        let periodic = spec.wrap == [WrapMode::Repeat; 2];
        let kind = if g <= spec.mip_max_tilt_deg {
            plan.build(format!(
                "mipmap: views tilt at most {g}° from the normal (mip_max_tilt_deg {}°)",
                spec.mip_max_tilt_deg
            ));
            PyramidKind::Mip
        } else if wants_fip && periodic {
            plan.build(format!(
                "fipmap: views tilt up to {g}° from the normal (fip_min_tilt_deg {}°): mipmap, \
                 ripmap and {} sheared ripmaps, chosen per view",
                spec.fip_min_tilt_deg,
                shear_set(spec.fip_shear_steps).len()
            ));
            PyramidKind::Fip
        } else {
            plan.build(format!(
                "ripmap: views tilt up to {g}° from the normal, beyond mip_max_tilt_deg {}°: \
                 footprints are anisotropic",
                spec.mip_max_tilt_deg
            ));
            PyramidKind::Rip
        };
        if wants_fip && kind != PyramidKind::Fip {
            plan.skip(
                "fipmap (sheared ripmaps)".into(),
                if periodic {
                    "views stay within mip_max_tilt_deg: the mipmap serves them".into()
                } else {
                    "fipmaps shear periodic textures only (wrap is not Repeat on both axes): \
                     the ripmap serves the skewed grazing views (more blur along the skew)"
                        .into()
                },
            );
        }
        let (levels_u, levels_v, levels_mip) = match kind {
            PyramidKind::Mip => {
                let l = keep_levels(tex.width.max(tex.height), needs, "", &mut plan, true);
                (l, l, l)
            }
            _ => {
                let lm = if kind == PyramidKind::Fip {
                    keep_levels(tex.width.max(tex.height), needs, "mip ", &mut plan, true)
                } else {
                    [0, 0]
                };
                (
                    keep_levels(tex.width, needs, "u ", &mut plan, true),
                    keep_levels(tex.height, needs, "v ", &mut plan, true),
                    lm,
                )
            }
        };
        Ok((
            plan,
            PyramidDecisions {
                kind,
                levels_u,
                levels_v,
                levels_mip,
            },
        ))
    }

    fn build(
        spec: &PyramidParams,
        _needs: &Needs,
        d: &PyramidDecisions,
        source: &Source,
    ) -> Result<(PyramidAsset, serde_json::Value), PipelineError> {
        let tex = source.texture()?;
        let t0 = Instant::now();
        let _building = crate::profile::timer("pyramids");
        let params = PyramidParams {
            kind: d.kind,
            ..*spec
        };
        let (full, report) = crate::pyramid::build(tex, &params)?;
        let [u0, u1] = d.levels_u;
        let [v0, v1] = d.levels_v;
        let [m0, m1] = d.levels_mip;
        let trim = |r: &RipMap| {
            RipMap::from_levels(
                (v0..=v1)
                    .map(|lv| (u0..=u1).map(|lu| r.level(lu, lv).clone()).collect())
                    .collect(),
                params,
            )
        };
        let (data, first_mip) = match &full {
            PyramidData::Mip(p) => (
                PyramidData::Mip(Pyramid::from_levels(p.levels()[u0..=u1].to_vec(), params)?),
                0,
            ),
            PyramidData::Rip(r) => (PyramidData::Rip(trim(r)?), 0),
            PyramidData::Fip(f) => (
                PyramidData::Fip(FipMap::from_parts(
                    Pyramid::from_levels(f.mip().levels()[m0..=m1].to_vec(), params)?,
                    trim(f.rip())?,
                    (0..f.shears().len())
                        .map(|i| trim(f.sheared(i)))
                        .collect::<Result<_, _>>()?,
                    params,
                )?),
                m0,
            ),
        };
        let asset = PyramidAsset {
            data,
            first: [u0, v0],
            base: [tex.width, tex.height],
            first_mip,
        };
        let kept = asset.levels().len();
        Ok((
            asset,
            json!({ "build_s": secs(t0), "full_textures": report.textures,
                    "full_bytes_f32": report.bytes_f32, "kept_textures": kept }),
        ))
    }

    fn write(data: &PyramidAsset, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError> {
        let channels = data.channels();
        let names = ["r", "g", "b", "a"];
        for (stem, t) in data.levels() {
            let image = FloatImage {
                width: t.width,
                height: t.height,
                data: t
                    .data
                    .chunks_exact(channels)
                    .map(|c| std::array::from_fn(|k| c.get(k).copied().unwrap_or(0.0)))
                    .collect(),
            };
            let ch = names[..channels.min(4)]
                .iter()
                .map(|n| Channel {
                    name: format!("value.{n}"),
                    encoding: Encoding::Float,
                })
                .collect();
            w.exr(&stem, &format!("{stem}.exr"), &image, ch)?;
        }
        let params = match &data.data {
            PyramidData::Mip(p) => *p.params(),
            PyramidData::Rip(r) => *r.params(),
            PyramidData::Fip(f) => *f.params(),
        };
        let rip_counts = |r: &RipMap| {
            let (nu, nv) = r.level_counts();
            [nu, nv]
        };
        let counts = match &data.data {
            PyramidData::Rip(r) => rip_counts(r),
            PyramidData::Mip(p) => [p.levels().len(), p.levels().len()],
            PyramidData::Fip(f) => rip_counts(f.rip()),
        };
        let mut meta = json!({
            "kind": params.kind,
            "channels": channels,
            "base_size": data.base,
            "first_level": data.first,
            "level_counts": counts,
            "params": params,
        });
        if let PyramidData::Fip(f) = &data.data {
            meta["first_mip_level"] = json!(data.first_mip);
            meta["mip_level_count"] = json!(f.mip().levels().len());
            meta["shears"] = json!(f.shears());
            meta["sheared_level_counts"] = json!(
                (0..f.shears().len())
                    .map(|i| rip_counts(f.sheared(i)))
                    .collect::<Vec<_>>()
            );
        }
        Ok(meta)
    }

    fn read(r: &AssetReader) -> Result<PyramidAsset, PipelineError> {
        r.expect_representation(Self::NAME)?;
        let params: PyramidParams = meta(r, "params")?;
        let channels: usize = meta(r, "channels")?;
        let first: [usize; 2] = meta(r, "first_level")?;
        let base: [usize; 2] = meta(r, "base_size")?;
        let [nu, nv]: [usize; 2] = meta(r, "level_counts")?;
        if !(1..=4).contains(&channels) || nu == 0 || nv == 0 || nu > 64 || nv > 64 {
            return Err(r
                .content(format!("metadata: {channels} channels, {nu} × {nv} levels"))
                .into());
        }
        let load = |role: String| -> Result<Texture, PipelineError> {
            let img = r.exr(&role)?;
            let data = img
                .data
                .iter()
                .flat_map(|p| p[..channels].iter().copied())
                .collect();
            Ok(Texture::new(img.width, img.height, channels, data)?)
        };
        let load_rip = |prefix: &str, [nu, nv]: [usize; 2]| -> Result<RipMap, PipelineError> {
            Ok(RipMap::from_levels(
                (0..nv)
                    .map(|lv| {
                        (0..nu)
                            .map(|lu| {
                                load(format!("{prefix}_u{}_v{}", first[0] + lu, first[1] + lv))
                            })
                            .collect::<Result<Vec<_>, _>>()
                    })
                    .collect::<Result<_, _>>()?,
                params,
            )?)
        };
        let load_mip = |first: usize, n: usize| -> Result<Pyramid, PipelineError> {
            Ok(Pyramid::from_levels(
                (0..n)
                    .map(|l| load(format!("mip{}", first + l)))
                    .collect::<Result<_, _>>()?,
                params,
            )?)
        };
        let mut first_mip = 0;
        let data = match params.kind {
            PyramidKind::Mip => PyramidData::Mip(load_mip(first[0], nu)?),
            PyramidKind::Rip => PyramidData::Rip(load_rip("rip", [nu, nv])?),
            PyramidKind::Fip => {
                first_mip = meta(r, "first_mip_level")?;
                let n_mip: usize = meta(r, "mip_level_count")?;
                let shears: Vec<crate::pyramid::Shear> = meta(r, "shears")?;
                let counts: Vec<[usize; 2]> = meta(r, "sheared_level_counts")?;
                if shears != shear_set(params.fip_shear_steps)
                    || counts.len() != shears.len()
                    || n_mip == 0
                    || n_mip > 64
                    || counts.iter().flatten().any(|&n| n == 0 || n > 64)
                {
                    return Err(r
                        .content(
                            "metadata: the shears or level counts do not match fip_shear_steps"
                                .into(),
                        )
                        .into());
                }
                PyramidData::Fip(FipMap::from_parts(
                    load_mip(first_mip, n_mip)?,
                    load_rip("rip", [nu, nv])?,
                    shears
                        .iter()
                        .zip(&counts)
                        .map(|(sh, &c)| load_rip(&shear_prefix(sh), c))
                        .collect::<Result<_, _>>()?,
                    params,
                )?)
            }
        };
        Ok(PyramidAsset {
            data,
            first,
            base,
            first_mip,
        })
    }

    fn measure_size(_: &PyramidDecisions) -> usize {
        0
    }

    fn measure(
        data: &PyramidAsset,
        needs: &Needs,
        _size: usize,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError> {
        let tex = source.texture()?;
        let g = needs.grazing_deg.min(89.0);
        let [s0, s1] = needs.screen_px;
        let sizes = [s1, (s0 * s1).sqrt()];
        let ch = tex.channels;
        let mut scores = Vec::new();
        let mut pictures = Vec::new();
        for &size in &sizes {
            for tilt in [0.0, 0.5 * g, g] {
                let view = PlaneView {
                    texels_per_pixel: tex.width as f64 / size,
                    tilt_deg: tilt,
                    azimuth_deg: MEASURE_AZIMUTH_DEG,
                };
                let truth = supersampled_truth(&view, tex, MEASURE_PIXELS, MEASURE_SAMPLES, 1);
                let fps = footprints(&view, tex, MEASURE_PIXELS);
                let mut got = vec![0.0f64; truth.len()];
                let mut buf = vec![0.0f32; ch];
                for (k, fp) in fps.iter().enumerate() {
                    let Some(fp) = fp else { continue };
                    data.sample_dir_into(fp.uv[0], fp.uv[1], fp.derivs, fp.dir, &mut buf);
                    for (o, x) in got[k * ch..(k + 1) * ch].iter_mut().zip(&buf) {
                        *o = f64::from(*x);
                    }
                }
                let mse = got
                    .iter()
                    .zip(&truth)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    / truth.len().max(1) as f64;
                // Peak 1; an exact match is capped at 100 dB rather than infinite.
                let psnr = (-10.0 * mse.max(1e-10).log10()).min(100.0);
                // The plane covers every pixel in both images: the silhouette IoU is 1.
                scores.push(crate::representation::Score {
                    psnr_db: psnr,
                    iou: 1.0,
                    coverage_error: 0.0,
                });
                if pictures.is_empty() && tilt == g {
                    let image = |v: &[f64]| altrep_data_gen::RgbaImage {
                        width: MEASURE_PIXELS,
                        height: MEASURE_PIXELS,
                        pixels: v
                            .chunks_exact(ch)
                            .map(|c| {
                                let grey = |k: usize| c.get(k).copied().unwrap_or(c[0]) as f32;
                                let a = if ch == 4 { c[3] as f32 } else { 1.0 };
                                [grey(0), grey(1), grey(2), a]
                            })
                            .collect(),
                    };
                    pictures.push(Picture {
                        file: format!("{}-pyramid.png", source.name),
                        caption: format!(
                            "{}: supersampled truth | {} lookup, tilt {tilt:.0}°, texture at {size:.0} px",
                            source.name,
                            kind_name(&data.data)
                        ),
                        image: altrep_data_gen::RgbaImage::side_by_side(&[
                            &image(&truth),
                            &image(&got),
                        ]),
                    });
                }
            }
        }
        let method = format!(
            "{} lookups of the loaded levels vs the supersampled truth ({MEASURE_PIXELS}² px, ≤ {MEASURE_SAMPLES} samples/px) at tilts 0, {:.0}, {:.0}° (azimuth {MEASURE_AZIMUTH_DEG}°), texture at {:.0} and {:.0} px; PSNR peak 1; IoU 1 by construction",
            kind_name(&data.data),
            0.5 * g,
            g,
            sizes[0],
            sizes[1]
        );
        // Coverage is the plane's, whole in both: no figure of its own.
        let m = Measurement {
            coverage_error: None,
            ..fold(method, &scores, None)
        };
        Ok((m, pictures))
    }
}

/// `metadata.key` of the asset, parsed. Errors: missing or of the wrong shape (naming the key).
fn meta<T: serde::de::DeserializeOwned>(r: &AssetReader, key: &str) -> Result<T, PipelineError> {
    let v = r
        .description()
        .metadata
        .get(key)
        .cloned()
        .ok_or_else(|| r.content(format!("metadata.{key} missing")))?;
    serde_json::from_value(v).map_err(|e| r.content(format!("metadata.{key}: {e}")).into())
}

fn kind_name(d: &PyramidData) -> &'static str {
    match d {
        PyramidData::Mip(_) => "trilinear mipmap",
        PyramidData::Rip(_) => "ripmap",
        PyramidData::Fip(_) => "fipmap",
    }
}
