//! Images with parallax from any direction on the GPU: the fragment-shader twin of
//! `altrep::sphere::render` at one ray per pixel (`SphereRenderParams::samples = 1`).
//!
//! Per fragment, the shader (`sphere.wgsl`) takes the display ray through the pixel centre,
//! marches it through each enclosing frame's depth map between the frame's stored cone bounds
//! (2D DDA, one fetch per cell), carves free space between the frames (at most
//! `altrep::sphere::MAX_CARVE_ROUNDS` rounds), and colours the surface point from the frames
//! that see it, relit from their normals with the diffuse light; where none of them sees it, it
//! asks the extra frames in turn as the CPU does, and draws a hole, like a ray stopped by the
//! cap on fetches, from the one-step offsets of the enclosing frames. The enclosing and extra
//! frames, their weights and their linear maps come from the library
//! (`altrep::sphere::enclosing_frames`, `altrep::sphere::extra_frames`), computed on the host
//! in `f64` as the CPU computes them; the shader repeats the CPU's
//! formulas in the same order, in `f32` ([`Precision::F32`], what an engine ships) or, where the
//! adapter has `SHADER_F64`, in `f64` ([`Precision::F64`]), where it is the CPU's computation
//! operation for operation.
//!
//! The stored codes are decoded on the host (depth, slope, linear albedo, unit normal, bound
//! codes): GPU memory is `G²·F²·(3·size(real) + 36)` bytes, against the 10 bytes per texel of the
//! asset's files. The output is premultiplied linear RGBA (alpha 1 where a surface was found),
//! the depth written is `(1 − z)/2` of the display depth `z` (0 at the front of the bounding
//! sphere, 1 at its back), and per fragment the texel fetches and flags are read back
//! ([`SphereFrame`]).

use std::time::Instant;

use altrep::sphere::{HoleFill, MAX_EXTRA_FRAMES, SphereImages, enclosing_frames, extra_frames};
use altrep_data_gen::{Light, RgbaImage};
use glam::DVec3;

use crate::offscreen::{self, Pipeline, storage};
use crate::parallax::reals;
use crate::shader::{Precision, Shader};
use crate::{DisplayError, Gpu, invalid};

/// What to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereDraw {
    /// Display direction, toward the camera, in the object frame (`y` up); any finite non-zero
    /// vector (it is normalised), inside the view set's coverage.
    pub dir: DVec3,
    /// Screen width and height in pixels; the square covers the bounding sphere.
    pub size: usize,
    /// A frame sees a surface point when its own surface lies within this many texel pitches
    /// above it (`altrep::sphere::SphereRenderParams::visibility`).
    pub visibility: f64,
    /// March between the stored cone bounds (`false`: the whole chord of the sphere).
    pub use_bounds: bool,
    /// How a ray whose surface point no frame sees (a hole) is drawn
    /// (`altrep::sphere::SphereRenderParams::holes`).
    pub holes: HoleFill,
    /// With [`HoleFill::Nearest`], holes farther than this from the nearest frame surface are
    /// drawn empty (`altrep::sphere::SphereRenderParams::hole_depth`; `None`: every hole is
    /// coloured).
    pub hole_depth: Option<f64>,
    /// Where no enclosing frame sees the point found, ask up to this many more frames
    /// (`altrep::sphere::SphereRenderParams::extra_frames`, at most
    /// `altrep::sphere::MAX_EXTRA_FRAMES`).
    pub extra_frames: usize,
    /// The light.
    pub light: Light,
    /// A cap on each ray's fetches (`altrep::sphere::SphereRenderParams::max_steps`; `None`:
    /// none).
    pub max_steps: Option<u32>,
}

impl SphereDraw {
    /// Along `dir` at `size²`, with the CPU's defaults: visibility 2, bounds on, default light.
    pub fn new(dir: DVec3, size: usize) -> Self {
        let d = altrep::sphere::SphereRenderParams::default();
        Self {
            dir,
            size,
            visibility: d.visibility,
            use_bounds: d.use_bounds,
            holes: d.holes,
            hole_depth: d.hole_depth,
            extra_frames: d.extra_frames,
            light: d.light,
            max_steps: d.max_steps,
        }
    }
}

/// One drawn frame read back from the GPU.
#[derive(Clone, Debug)]
pub struct SphereFrame {
    /// Premultiplied linear RGBA, alpha 1 where a surface was found, 0 elsewhere.
    pub image: RgbaImage,
    /// Per fragment (row-major): texel fetches of its ray, all frames together (0 outside the
    /// sphere's disc).
    pub steps: Vec<u32>,
    /// Per fragment: the ray was traced (its pixel centre lies inside the sphere's disc).
    pub traced: Vec<bool>,
    /// Rays whose surface point no frame sees (coloured by the nearest frame surface).
    pub holes: usize,
    /// Rays still unresolved after the carving rounds.
    pub unresolved: usize,
    /// Rays stopped by the cap on fetches.
    pub capped: usize,
    /// Per fragment, the depth written (1 where nothing was drawn).
    pub depth: Vec<f32>,
    /// Wall time of the draw and read-back (milliseconds; on lavapipe this is CPU emulation).
    pub millis: f64,
}

impl SphereFrame {
    /// Mean texel fetches per traced ray (0 when none was traced), as
    /// `altrep::sphere::RenderOutput::mean_steps` counts them.
    pub fn mean_steps(&self) -> f64 {
        let (sum, n) = self
            .steps
            .iter()
            .zip(&self.traced)
            .filter(|(_, t)| **t)
            .fold((0u64, 0usize), |(s, n), (&x, _)| (s + u64::from(x), n + 1));
        sum as f64 / n.max(1) as f64
    }
}

/// An any-direction asset uploaded to the GPU, with the pipeline that draws it.
pub struct SphereDisplay {
    precision: Precision,
    pipeline: std::sync::Arc<Pipeline>,
    images: SphereImages,
    tex: wgpu::Buffer,
    attr: wgpu::Buffer,
    code: wgpu::Buffer,
}

impl SphereDisplay {
    /// Uploads `images` (every frame decoded: depth, slope, albedo, normal, bound codes) and
    /// builds the pipeline in `precision`. Cost: one pass over the `G²·F²` texels.
    ///
    /// Errors: [`Precision::F64`] on a device without `SHADER_F64`; frames larger than the
    /// device's storage-buffer limit; a shader or pipeline the device rejects
    /// ([`DisplayError::Gpu`]).
    pub fn new(
        gpu: &Gpu,
        images: &SphereImages,
        precision: Precision,
    ) -> Result<Self, DisplayError> {
        let pipeline = offscreen::pipeline(gpu, Shader::Sphere, precision)?;
        let f = images.params.size;
        let frames = images.frames.len();
        let texels = frames * f * f;
        let attr_bytes = (texels * 32) as u64;
        let limit = gpu.device.limits().max_storage_buffer_binding_size;
        if attr_bytes > limit {
            return Err(invalid(
                "frames",
                format!("{frames} of {f}²"),
                "exceed the device's storage-buffer size (32 bytes per texel)",
            ));
        }
        let mut tex = Vec::with_capacity(3 * texels);
        let mut attr: Vec<f32> = Vec::with_capacity(8 * texels);
        let mut code: Vec<u32> = Vec::with_capacity(texels);
        for (frame, bounds) in images.frames.iter().zip(&images.bounds) {
            for j in 0..f {
                for i in 0..f {
                    // Coarser bounds (`ConeBounds::block` > 1) are spread over the frame
                    // texels they bound: the same interval read as on the CPU.
                    let (zmin, zmax) = bounds.codes_at(i, j);
                    let bound =
                        u32::from(zmin <= zmax) << 1 | u32::from(zmin) << 8 | u32::from(zmax) << 16;
                    match (frame.plane(i, j), frame.texel(i, j)) {
                        (Some((z, g)), Some((_, a, n))) => {
                            tex.extend_from_slice(&[z, g.x, g.y]);
                            attr.extend_from_slice(&[a.x, a.y, a.z, 0.0, n.x, n.y, n.z, 0.0]);
                            code.push(1 | bound);
                        }
                        _ => {
                            tex.extend_from_slice(&[0.0; 3]);
                            attr.extend_from_slice(&[0.0; 8]);
                            code.push(bound);
                        }
                    }
                }
            }
        }
        Ok(Self {
            precision,
            pipeline,
            tex: storage(gpu, "sphere planes", &reals(&tex, precision)),
            attr: storage(gpu, "sphere attributes", bytemuck::cast_slice(&attr)),
            code: storage(gpu, "sphere codes", bytemuck::cast_slice(&code)),
            images: images.clone(),
        })
    }

    /// The precision the shader runs in.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// The frames drawn.
    pub fn images(&self) -> &SphereImages {
        &self.images
    }

    /// Draws one frame and reads back the image, the fetches, the flags and the depth. Cost: one
    /// draw of `size²` fragments, each marching its enclosing frames (the CPU's steps), plus
    /// the read-back.
    ///
    /// Errors: a zero or huge screen, a visibility that is not finite and positive, a light
    /// that is not finite, a direction the view set does not cover (or zero, or not finite), a
    /// GPU error.
    pub fn render(&self, gpu: &Gpu, d: &SphereDraw) -> Result<SphereFrame, DisplayError> {
        if d.size == 0 || d.size > 8192 {
            return Err(invalid("screen size", d.size, "must be in 1..=8192"));
        }
        if let Some(h) = d.hole_depth
            && !(h.is_finite() && h > 0.0)
        {
            return Err(invalid("hole depth", h, "must be finite and positive"));
        }
        if d.extra_frames > MAX_EXTRA_FRAMES {
            return Err(invalid(
                "extra frames",
                d.extra_frames,
                "must be at most MAX_EXTRA_FRAMES (8)",
            ));
        }
        if d.max_steps == Some(0) {
            return Err(invalid("max steps", 0, "must be at least 1"));
        }
        if !(d.visibility.is_finite() && d.visibility > 0.0) {
            return Err(invalid(
                "visibility",
                d.visibility,
                "must be finite and positive",
            ));
        }
        let ldir = d.light.direction;
        if !(ldir.is_finite() && d.light.ambient.is_finite()) {
            return Err(invalid("light", format!("{:?}", d.light), "must be finite"));
        }
        let t0 = Instant::now();
        let direction_error = |e: altrep::sphere::SphereError| {
            invalid(
                "direction",
                format!("{:?} ({e})", d.dir),
                "must be a finite, non-zero direction the view set covers",
            )
        };
        let enclosing = enclosing_frames(&self.images, d.dir).map_err(direction_error)?;
        let extra = extra_frames(&self.images, d.dir, d.extra_frames).map_err(direction_error)?;
        let tiny = match self.precision {
            Precision::F64 => 1e-300,
            Precision::F32 => f64::from(f32::MIN_POSITIVE),
        };
        let inf = match self.precision {
            Precision::F64 => f64::MAX,
            Precision::F32 => f64::from(f32::MAX),
        };
        // A point within this of a frame's surface is hidden from it, and a carving candidate
        // is checked and coloured this far past it: the CPU's 1e-9 in `f64`; in `f32` that is
        // below rounding, so 16 ulps of the sphere radius (about 2e-6) stand in for it.
        let hidden_tol = match self.precision {
            Precision::F64 => 1e-9,
            Precision::F32 => 16.0 * f64::from(f32::EPSILON),
        };
        let slots = enclosing.len() + extra.len();
        let mut pv = vec![0.0f64; 8 + 10 * slots];
        pv[..8].copy_from_slice(&[
            self.images.params.size as f64,
            d.visibility,
            inf,
            tiny,
            d.size as f64,
            hidden_tol,
            // warp.rs `PROBE` (1e-9) in `f64`; the same 16 ulps in `f32`.
            hidden_tol,
            d.hole_depth.unwrap_or(inf),
        ]);
        // Slots: the enclosing frames, then the extra frames (sphere.wgsl's header).
        let mut u = vec![
            enclosing.len() as u32,
            extra.len() as u32,
            u32::from(d.use_bounds),
            d.max_steps.unwrap_or(u32::MAX),
            u32::from(d.holes == HoleFill::Offsets),
        ];
        for (s, e) in enclosing.iter().chain(&extra).enumerate() {
            for (r, row) in e.rows.iter().enumerate() {
                pv[8 + 10 * s + 3 * r..8 + 10 * s + 3 * r + 3].copy_from_slice(&row.to_array());
            }
            pv[8 + 10 * s + 9] = e.weight;
            u.push(e.frame as u32);
        }
        let light = [ldir.x, ldir.y, ldir.z, d.light.ambient];
        let pbuf = storage(gpu, "sphere reals", &reals(&pv, self.precision));
        let ubuf = storage(gpu, "sphere ints", bytemuck::cast_slice(&u));
        let lbuf = storage(gpu, "light", bytemuck::cast_slice(&light));
        let frags = d.size * d.size;
        let drawn = offscreen::draw(
            gpu,
            &self.pipeline,
            &[&pbuf, &ubuf, &lbuf, &self.tex, &self.attr, &self.code],
            2 * frags,
            (d.size, d.size),
            t0,
        )?;
        let mut frame = SphereFrame {
            image: drawn.image,
            steps: Vec::with_capacity(frags),
            traced: Vec::with_capacity(frags),
            holes: 0,
            unresolved: 0,
            capped: 0,
            depth: drawn.depth,
            millis: drawn.millis,
        };
        for w in drawn.steps.chunks_exact(2) {
            frame.steps.push(w[0]);
            frame.traced.push(w[1] & 4 != 0);
            frame.holes += usize::from(w[1] & 1 != 0);
            frame.unresolved += usize::from(w[1] & 2 != 0);
            frame.capped += usize::from(w[1] & 8 != 0);
        }
        Ok(frame)
    }
}
