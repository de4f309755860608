//! Pyramid lookups on the GPU, side by side: the fragment-shader twins of the trilinear mipmap
//! with Heckbert's level (`altrep::pyramid::Pyramid::sample_grad`), the ripmap's anisotropic
//! lookup (`RipMap::sample_grad`) and the fipmap database with its per-pixel mip/rip/fip
//! decision (`FipMap::decide` + `FipMap::sample_into`), drawn on the minified textured plane of
//! `altrep::pyramid::truth` (same camera, same pixel grid, so every GPU pixel has a CPU twin and
//! a supersampled truth).
//!
//! The shader (`pyramid.wgsl`) computes each pixel's plane hit and its exact screen derivatives
//! itself, chooses levels and filters by hand from those derivatives (no hardware sampler: its
//! level-of-detail rule and filter weights vary between implementations), in the CPU's order of
//! operations, in `f32`. Per fragment it writes the scheme used and the number of bilinear
//! lookups to a storage buffer ([`PyramidFrame::scheme`], [`PyramidFrame::lookups`]).
//!
//! Data: mipmaps and ripmaps come from pyramid asset folders written by the pipeline, loaded only
//! through the library's loader ([`load`](crate::load): `AssetReader::open` + `PyramidRepr::read`).
//! The pipeline does not write fipmaps yet (its asset format has no sheared levels), so the fip
//! panel takes an in-memory `FipMap` built by the caller with the library
//! (`FipMap::build`); the display itself builds and fits nothing.

use std::time::Instant;

use altrep::pyramid::asset::PyramidAsset;
use altrep::pyramid::truth::{PIXEL_ANGLE, PlaneView};
use altrep::pyramid::{
    FipMap, Pyramid, PyramidData, PyramidParams, RipMap, Scheme, ShearAxis, WrapMode,
};
use altrep_data_gen::RgbaImage;
use glam::DVec3;

use crate::offscreen::{self, Pipeline, storage};
use crate::shader::{Precision, Shader};
use crate::{DisplayError, Gpu, invalid};

/// The point of the plane the camera looks at (`altrep::pyramid::truth`).
const TARGET: [f64; 2] = [0.3, 0.7];

/// Largest image side (pixels) [`PyramidDisplay::render`] draws.
pub const MAX_PIXELS: usize = 4096;

/// Which lookup a panel shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sampler {
    /// Trilinear mipmap, level from Heckbert's `D`.
    Mip,
    /// Ripmap, four bilinear levels from the axis-aligned footprint.
    Rip,
    /// Fipmap database: mip, rip or a sheared ripmap, decided per pixel.
    Fip,
}

impl Sampler {
    /// Every sampler, in panel order.
    pub const ALL: [Sampler; 3] = [Sampler::Mip, Sampler::Rip, Sampler::Fip];

    /// Lower-case name (`mip`, `rip`, `fip`).
    pub fn name(self) -> &'static str {
        match self {
            Sampler::Mip => "mip",
            Sampler::Rip => "rip",
            Sampler::Fip => "fip",
        }
    }
}

/// One drawn panel read back from the GPU.
#[derive(Clone, Debug)]
pub struct PyramidFrame {
    /// The image (`pixels × pixels`): grey textures as `(x, x, x, 1)`, two channels as
    /// `(x₀, x₁, x₀, 1)`, three as `(x₀, x₁, x₂, 1)`, four as stored (premultiplied RGBA) —
    /// [`values_to_image`]'s mapping.
    pub image: RgbaImage,
    /// Per fragment (row-major): the scheme used, `None` where the pixel's ray missed the plane.
    pub scheme: Vec<Option<Scheme>>,
    /// Per fragment: bilinear lookups made (1 or 2 for a mipmap, 1 to 4 for a ripmap).
    pub lookups: Vec<u32>,
    /// Wall time of the draw and read-back (milliseconds; on lavapipe this is CPU emulation).
    pub millis: f64,
}

/// `pixels × pixels` lookup values (`channels` per pixel, row-major, as
/// `altrep::pyramid::truth::supersampled_truth` returns them) as an image with
/// [`PyramidFrame::image`]'s channel mapping. Errors: a length that does not match.
pub fn values_to_image(
    values: &[f64],
    channels: usize,
    pixels: usize,
) -> Result<RgbaImage, DisplayError> {
    if channels == 0 || channels > 4 || values.len() != pixels * pixels * channels {
        return Err(invalid(
            "values",
            format!("{} values, {channels} channels", values.len()),
            "need pixels² × channels values, 1 to 4 channels",
        ));
    }
    Ok(RgbaImage {
        width: pixels,
        height: pixels,
        pixels: values
            .chunks_exact(channels)
            .map(|c| {
                let g = |k: usize| c.get(k).copied().unwrap_or(c[0]) as f32;
                let a = if channels == 4 { c[3] as f32 } else { 1.0 };
                [g(0), g(1), g(2), a]
            })
            .collect(),
    })
}

/// PSNR (dB, peak 1) of the lookup values of `image` against `reference`, both in
/// [`values_to_image`]'s mapping: over the first `channels` of R, G, B (and alpha when
/// `channels` is 4), so that the duplicated grey channels and a constant alpha do not count.
/// Infinite for equal values. Errors: sizes differ, a channel count outside 1 to 4.
pub fn value_psnr(
    image: &RgbaImage,
    reference: &RgbaImage,
    channels: usize,
) -> Result<f64, DisplayError> {
    if (image.width, image.height) != (reference.width, reference.height) {
        return Err(invalid(
            "image sizes",
            format!(
                "{}×{} vs {}×{}",
                image.width, image.height, reference.width, reference.height
            ),
            "must be equal",
        ));
    }
    if !(1..=4).contains(&channels) {
        return Err(invalid("channels", channels, "must be 1 to 4"));
    }
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (p, q) in image.pixels.iter().zip(&reference.pixels) {
        for c in 0..channels {
            let e = f64::from(p[c] - q[c]);
            sum += e * e;
            n += 1;
        }
    }
    let mse = sum / n.max(1) as f64;
    Ok(if mse <= 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    })
}

/// Levels packed into one texel buffer with a level table.
#[derive(Default)]
struct Packer {
    table: Vec<[u32; 4]>,
    texels: Vec<[f32; 4]>,
}

impl Packer {
    /// Appends one level; returns its table index.
    fn push(&mut self, t: &altrep::pyramid::Texture) -> u32 {
        let idx = self.table.len() as u32;
        self.table
            .push([self.texels.len() as u32, t.width as u32, t.height as u32, 0]);
        self.texels.extend(
            t.data
                .chunks_exact(t.channels)
                .map(|c| std::array::from_fn(|k| c.get(k).copied().unwrap_or(0.0))),
        );
        idx
    }

    /// Appends a mipmap: (base, levels).
    fn mip(&mut self, p: &Pyramid) -> [u32; 2] {
        let base = self.table.len() as u32;
        for t in p.levels() {
            self.push(t);
        }
        [base, p.levels().len() as u32]
    }

    /// Appends a ripmap, row `l_v` after row: (base, levels along u, levels along v).
    fn rip(&mut self, r: &RipMap) -> [u32; 3] {
        let base = self.table.len() as u32;
        let (nu, nv) = r.level_counts();
        for lv in 0..nv {
            for lu in 0..nu {
                self.push(r.level(lu, lv));
            }
        }
        [base, nu as u32, nv as u32]
    }
}

fn wrap_code(w: WrapMode) -> u32 {
    match w {
        WrapMode::Clamp => 0,
        WrapMode::Repeat => 1,
        WrapMode::Mirror => 2,
    }
}

/// Per sampler, what the shader needs: integers 3..=10 of its `I` buffer and the parameters.
#[derive(Clone, Copy)]
struct Slot {
    wrap: [u32; 2],
    mip: [u32; 2],
    rip: [u32; 3],
    shears: u32,
    params: PyramidParams,
}

/// Mipmap, ripmap and fipmap uploaded to the GPU, with the pipeline that draws the plane.
pub struct PyramidDisplay {
    pipeline: std::sync::Arc<Pipeline>,
    levels: wgpu::Buffer,
    texels: wgpu::Buffer,
    shear_f: wgpu::Buffer,
    shear_i: wgpu::Buffer,
    slots: [Option<Slot>; 3],
    channels: usize,
    base_width: usize,
}

impl PyramidDisplay {
    /// Uploads the pyramids: each asset gives the mip or the rip panel (by its kind), `fip` the
    /// fip panel; the levels are uploaded as they are stored (the first stored level acts as
    /// level 0, as in the CPU lookups of a loaded asset). Cost: one pass over every level; GPU
    /// memory 16 bytes per texel of every level.
    ///
    /// Errors: no pyramid; two assets of the same kind; assets of other kinds; pyramids of
    /// different channel counts or original widths; a shader or pipeline the device rejects.
    pub fn new(
        gpu: &Gpu,
        assets: &[&PyramidAsset],
        fip: Option<&FipMap>,
    ) -> Result<Self, DisplayError> {
        let mut pk = Packer::default();
        let mut slots: [Option<Slot>; 3] = [None; 3];
        let mut channels = None;
        let mut base_width = None;
        let mut agree = |c: usize, w: usize| -> Result<(), DisplayError> {
            if *channels.get_or_insert(c) != c {
                return Err(invalid("channels", c, "must be equal in every pyramid"));
            }
            if *base_width.get_or_insert(w) != w {
                return Err(invalid(
                    "original width",
                    w,
                    "must be equal in every pyramid (one texture)",
                ));
            }
            Ok(())
        };
        let mut shear_f: Vec<[f32; 4]> = Vec::new();
        let mut shear_i: Vec<[u32; 4]> = Vec::new();
        for a in assets {
            agree(a.channels(), a.base[0])?;
            let (k, slot) = match &a.data {
                PyramidData::Mip(p) => (
                    0,
                    Slot {
                        wrap: p.params().wrap.map(wrap_code),
                        mip: pk.mip(p),
                        rip: [0, 1, 1],
                        shears: 0,
                        params: *p.params(),
                    },
                ),
                PyramidData::Rip(r) => (
                    1,
                    Slot {
                        wrap: r.params().wrap.map(wrap_code),
                        mip: [0, 1],
                        rip: pk.rip(r),
                        shears: 0,
                        params: *r.params(),
                    },
                ),
                PyramidData::Fip(_) => {
                    return Err(invalid(
                        "asset kind",
                        "fip",
                        "the pipeline writes mip and rip assets only",
                    ));
                }
            };
            if slots[k].is_some() {
                return Err(invalid(
                    "assets",
                    Sampler::ALL[k].name(),
                    "two assets of the same kind",
                ));
            }
            slots[k] = Some(slot);
        }
        if let Some(f) = fip {
            let l0 = &f.mip().levels()[0];
            agree(l0.channels, l0.width)?;
            let mip = pk.mip(f.mip());
            let rip = pk.rip(f.rip());
            for (i, s) in f.shears().iter().enumerate() {
                let [base, nu, nv] = pk.rip(f.sheared(i));
                let axis = match s.axis {
                    ShearAxis::V => 0,
                    ShearAxis::U => 1,
                };
                shear_f.push([s.value() as f32, s.period() as f32, 0.0, 0.0]);
                shear_i.push([base, nu, nv, axis]);
            }
            slots[2] = Some(Slot {
                wrap: f.mip().params().wrap.map(wrap_code),
                mip,
                rip,
                shears: f.shears().len() as u32,
                params: *f.mip().params(),
            });
        }
        let (Some(channels), Some(base_width)) = (channels, base_width) else {
            return Err(invalid("pyramids", "none", "need at least one"));
        };
        if shear_f.is_empty() {
            shear_f.push([0.0; 4]);
            shear_i.push([0; 4]);
        }
        let pipeline = offscreen::pipeline(gpu, Shader::Pyramid, Precision::F32)?;
        let levels = storage(gpu, "pyramid level table", bytemuck::cast_slice(&pk.table));
        let texels = storage(gpu, "pyramid texels", bytemuck::cast_slice(&pk.texels));
        let shear_f = storage(gpu, "fip shears (f32)", bytemuck::cast_slice(&shear_f));
        let shear_i = storage(gpu, "fip shears (u32)", bytemuck::cast_slice(&shear_i));
        Ok(Self {
            pipeline,
            levels,
            texels,
            shear_f,
            shear_i,
            slots,
            channels,
            base_width,
        })
    }

    /// The samplers that have data.
    pub fn samplers(&self) -> Vec<Sampler> {
        Sampler::ALL
            .into_iter()
            .zip(&self.slots)
            .filter(|(_, s)| s.is_some())
            .map(|(s, _)| s)
            .collect()
    }

    /// Channels of the uploaded texture.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Width of the original texture (texels), which sets the camera distance of a
    /// [`PlaneView`].
    pub fn base_width(&self) -> usize {
        self.base_width
    }

    /// Draws the `pixels × pixels` image of `view` with `sampler` and reads back the image, the
    /// schemes and the lookup counts. Cost: one draw of `pixels²` fragments (at most 2 bilinear
    /// lookups each for the mipmap, 4 for the ripmap and fipmap) plus the read-back.
    ///
    /// Errors: a sampler without data, a view outside `altrep::pyramid::truth`'s ranges
    /// (`D₀ > 0`, tilt in `[0, 89.9]°`, finite azimuth), `pixels` outside `1..=MAX_PIXELS`, a GPU
    /// error.
    pub fn render(
        &self,
        gpu: &Gpu,
        sampler: Sampler,
        view: &PlaneView,
        pixels: usize,
    ) -> Result<PyramidFrame, DisplayError> {
        let k = Sampler::ALL.iter().position(|s| *s == sampler).unwrap_or(0);
        let slot = self.slots[k]
            .ok_or_else(|| invalid("sampler", sampler.name(), "has no pyramid uploaded for it"))?;
        if !(view.texels_per_pixel.is_finite() && view.texels_per_pixel > 0.0) {
            return Err(invalid(
                "texels_per_pixel",
                view.texels_per_pixel,
                "must be finite and > 0",
            ));
        }
        if !(view.tilt_deg.is_finite() && (0.0..=89.9).contains(&view.tilt_deg)) {
            return Err(invalid("tilt_deg", view.tilt_deg, "must be in [0, 89.9]"));
        }
        if !view.azimuth_deg.is_finite() {
            return Err(invalid("azimuth_deg", view.azimuth_deg, "must be finite"));
        }
        if pixels == 0 || pixels > MAX_PIXELS {
            return Err(invalid("pixels", pixels, "must be in 1..=4096"));
        }
        let t0 = Instant::now();
        // The camera of truth.rs `Camera::new`, in f64, handed to the shader in f32.
        let (th, ph) = (view.tilt_deg.to_radians(), view.azimuth_deg.to_radians());
        let dist = view.texels_per_pixel / (self.base_width as f64 * PIXEL_ANGLE);
        let back = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
        let right = DVec3::new(-ph.sin(), ph.cos(), 0.0);
        let up = right.cross(-back);
        let p = &slot.params;
        let floats: Vec<f32> = [
            back.x,
            back.y,
            back.z,
            right.x,
            right.y,
            right.z,
            up.x,
            up.y,
            up.z,
            dist,
            TARGET[0],
            TARGET[1],
            PIXEL_ANGLE,
            pixels as f64 / 2.0,
            p.mip_max_tilt_deg,
            p.fip_min_tilt_deg,
            p.rip_max_skew_deg,
        ]
        .iter()
        .map(|&x| x as f32)
        .collect();
        let ints: [u32; 11] = [
            k as u32,
            pixels as u32,
            self.channels as u32,
            slot.wrap[0],
            slot.wrap[1],
            slot.mip[0],
            slot.mip[1],
            slot.rip[0],
            slot.rip[1],
            slot.rip[2],
            slot.shears,
        ];
        let fbuf = storage(gpu, "F", bytemuck::cast_slice(&floats));
        let ibuf = storage(gpu, "I", bytemuck::cast_slice(&ints));
        let drawn = offscreen::draw(
            gpu,
            &self.pipeline,
            &[
                &fbuf,
                &ibuf,
                &self.levels,
                &self.texels,
                &self.shear_f,
                &self.shear_i,
            ],
            2 * pixels * pixels,
            (pixels, pixels),
            t0,
        )?;
        let (image, words, millis) = (drawn.image, drawn.steps, drawn.millis);
        let scheme = words
            .chunks_exact(2)
            .map(|c| match c[0] {
                0 => None,
                1 => Some(Scheme::Mip),
                2 => Some(Scheme::Rip),
                n => Some(Scheme::Fip((n - 3) as usize)),
            })
            .collect();
        let lookups = words.chunks_exact(2).map(|c| c[1]).collect();
        Ok(PyramidFrame {
            image,
            scheme,
            lookups,
            millis,
        })
    }
}
