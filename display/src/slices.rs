//! Slices on the GPU: the fragment-shader twin of `altrep::slices::render_object` (an object's
//! slices) and of `altrep::slices::render_slices` (a tile's slices over a ground patch) at one
//! sample per pixel, in `f32` (what an engine ships).
//!
//! Per fragment, the shader (`slices.wgsl`) clips the ray through the pixel centre to the
//! object's box or to the patch of tiles ([`SlicesDraw::patch`]; a tile repeats along `x` and
//! `z`, its slices wrap) and composites the slices of one stack it crosses, nearest first, each read with
//! trilinear 2D filtering and its opacity raised to the path length (docs/design.md §9.4). The
//! stack (axis and merge level) is chosen on the host as the library chooses it
//! ([`altrep::slices::asset::SlicesAsset::choose`]), and so are the two 2D levels read and their
//! blend weight, constant over an orthographic draw. Every slice's 2D pyramid is uploaded once:
//! GPU memory is 16 bytes per texel of every level, against the 4 bytes per level-0 texel of the
//! asset's files. The output is premultiplied linear RGBA; per fragment the slices read are read
//! back ([`SlicesFrame`]).

use std::time::Instant;

use altrep::slices::asset::{BOX_MIN, SlicesAsset};
use altrep::slices::{Axis, Side};
use altrep_data_gen::{OrthoFrame, RgbaImage};
use glam::DVec3;

use crate::offscreen::{self, Pipeline, storage};
use crate::shader::{Precision, Shader};
use crate::{DisplayError, Gpu, invalid};

/// What to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlicesDraw {
    /// The orthographic frame (data-gen's conventions: `dir` toward the camera, the square
    /// `[−1, 1]²` of screen units times `radius` around `centre`).
    pub frame: OrthoFrame,
    /// Screen width and height in pixels.
    pub size: usize,
    /// The stack drawn, `(axis, merge level)`; `None`: the one the library chooses for `dir` at
    /// the screen size `choose_px` ([`SlicesAsset::choose`]).
    pub stack: Option<(Axis, usize)>,
    /// The on-screen size of the box's width (pixels) at which the stack is chosen when `stack`
    /// is `None`: `size / radius` for a frame over the box.
    pub choose_px: f64,
    /// Tiles of a tiled asset drawn along `x` and `z`: the ground patch
    /// `[0, n_x·L_x] × [0, L_y] × [0, n_z·L_z]` (`L` one tile's extent); `0` leaves that direction
    /// unbounded, as `altrep::slices::render_slices` draws it. An object's slices take `[1, 1]`
    /// (its box).
    pub patch: [u32; 2],
}

impl SlicesDraw {
    /// The frame of the bounding cylinder's window along `dir` (centre `(0, 1, 0)`, radius 1,
    /// the horizontal screen right of data-gen's frames), `size²` pixels, the stack chosen at
    /// that size. Errors: a zero or non-finite direction.
    pub fn new(dir: DVec3, size: usize) -> Result<Self, DisplayError> {
        let frame = OrthoFrame::new(DVec3::Y, 1.0, dir).map_err(|e| {
            invalid(
                "direction",
                format!("{dir:?} ({e})"),
                "must be finite and non-zero",
            )
        })?;
        Ok(Self {
            frame,
            size,
            stack: None,
            choose_px: size as f64,
            patch: [1, 1],
        })
    }
}

impl SlicesDraw {
    /// A tile's slices over the unbounded ground patch, framed as the CPU renderer
    /// `altrep::slices::render_slices` frames `view` (its twin): `size²` pixels of `pixel_voxels`
    /// voxels round the tile's centre shifted by `offset` (`x`, `z` world units of the tile), the
    /// screen basis of the view, the stack chosen at that distance (a tile `N/pixel_voxels`
    /// pixels across). Errors: an asset that is not a tile, an invalid view, a pixel size that is
    /// not positive, an offset that is not finite.
    pub fn over_tile(
        asset: &SlicesAsset,
        view: &altrep::slices::StackView,
        size: usize,
        pixel_voxels: f64,
        offset: [f64; 2],
    ) -> Result<Self, DisplayError> {
        if !asset.slices.tiled() {
            return Err(invalid(
                "asset",
                "an object's slices",
                "must be a tile's (`tile = { … }` in the manifest) to draw over a ground patch",
            ));
        }
        view.validate()
            .map_err(|e| invalid("view", format!("{view:?} ({e})"), "must be valid"))?;
        if !(pixel_voxels.is_finite() && pixel_voxels > 0.0) {
            return Err(invalid(
                "pixel size",
                pixel_voxels,
                "must be finite and > 0 voxels",
            ));
        }
        if !offset.iter().all(|o| o.is_finite()) {
            return Err(invalid("offset", format!("{offset:?}"), "must be finite"));
        }
        let d = asset.slices.dims();
        let s = asset.slices.voxel_size();
        let (right, up) = view.basis();
        Ok(Self {
            frame: OrthoFrame {
                centre: DVec3::new(
                    0.5 * d[0] as f64 * s + offset[0],
                    0.5 * d[1] as f64 * s,
                    0.5 * d[2] as f64 * s + offset[1],
                ),
                radius: 0.5 * size as f64 * pixel_voxels * s,
                dir: view.vector(),
                right,
                up,
            },
            size,
            stack: None,
            choose_px: d[0] as f64 / pixel_voxels,
            patch: [0, 0],
        })
    }
}

/// One drawn frame read back from the GPU.
#[derive(Clone, Debug)]
pub struct SlicesFrame {
    /// Premultiplied linear RGBA.
    pub image: RgbaImage,
    /// Per fragment (row-major): slices read (0 where the ray crosses none).
    pub steps: Vec<u32>,
    /// Per fragment: the ray crossed at least one slice.
    pub covered: Vec<bool>,
    /// The stack drawn.
    pub stack: (Axis, usize),
    /// Wall time of the draw and read-back (milliseconds; on lavapipe this is CPU emulation).
    pub millis: f64,
}

impl SlicesFrame {
    /// Slices read per covered pixel, as `altrep::slices::ObjectImage::steps_per_pixel` counts
    /// them (0 when no pixel is covered).
    pub fn steps_per_pixel(&self) -> f64 {
        let (sum, n) = self
            .steps
            .iter()
            .zip(&self.covered)
            .filter(|(_, c)| **c)
            .fold((0u64, 0usize), |(s, n), (&x, _)| (s + u64::from(x), n + 1));
        if n == 0 { 0.0 } else { sum as f64 / n as f64 }
    }
}

/// Where one stack side's slices lie in the texel buffer.
struct StackSlot {
    axis: Axis,
    level: usize,
    side: Side,
    /// Offset of slice 0's level 0.
    base: usize,
    /// Texels per slice (every 2D level).
    stride: usize,
    /// Offset, width and height of each 2D level inside a slice.
    levels: Vec<(usize, usize, usize)>,
}

/// A slices asset uploaded to the GPU, with the pipeline that draws it.
pub struct SlicesDisplay {
    pipeline: std::sync::Arc<Pipeline>,
    asset: SlicesAsset,
    slots: Vec<StackSlot>,
    texels: wgpu::Buffer,
}

impl SlicesDisplay {
    /// Uploads every slice of every stack and side of `asset` with its 2D levels and builds the
    /// pipeline. Cost: one copy of the texels.
    ///
    /// Errors: texels beyond the device's storage-buffer limit; a shader or pipeline the device
    /// rejects ([`DisplayError::Gpu`]).
    pub fn new(gpu: &Gpu, asset: &SlicesAsset) -> Result<Self, DisplayError> {
        let pipeline = offscreen::pipeline(gpu, Shader::Slices, Precision::F32)?;
        let mut data: Vec<[f32; 4]> = Vec::new();
        let mut slots = Vec::new();
        for stack in asset.slices.stacks() {
            let sides: &[Side] = if stack.per_side() {
                &[Side::Plus, Side::Minus]
            } else {
                &[Side::Plus]
            };
            for &side in sides {
                let slices = stack.slices(side);
                let mut levels = Vec::new();
                let mut offset = 0;
                for t in slices[0].levels() {
                    levels.push((offset, t.width, t.height));
                    offset += t.width * t.height;
                }
                let base = data.len();
                for p in slices {
                    for t in p.levels() {
                        data.extend(t.data.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]));
                    }
                }
                slots.push(StackSlot {
                    axis: stack.axis(),
                    level: stack.level(),
                    side,
                    base,
                    stride: offset,
                    levels,
                });
            }
        }
        let bytes = (data.len() * 16) as u64;
        if bytes > gpu.device.limits().max_storage_buffer_binding_size
            || data.len() > u32::MAX as usize
        {
            return Err(invalid(
                "slices",
                format!("{bytes} bytes"),
                "exceed the device's storage-buffer size (16 bytes per texel of every 2D level)",
            ));
        }
        Ok(Self {
            pipeline,
            texels: storage(gpu, "slice texels", bytemuck::cast_slice(&data)),
            asset: asset.clone(),
            slots,
        })
    }

    /// The asset drawn.
    pub fn asset(&self) -> &SlicesAsset {
        &self.asset
    }

    /// Draws one frame and reads back the image and the slices read per fragment. Cost: one
    /// draw of `size²` fragments, each reading one or two 2D levels per slice it crosses.
    ///
    /// Errors: a zero or huge screen, a frame that is not finite, a stack the asset does not
    /// hold, a GPU error.
    pub fn render(&self, gpu: &Gpu, d: &SlicesDraw) -> Result<SlicesFrame, DisplayError> {
        if d.size == 0 || d.size > 8192 {
            return Err(invalid("screen size", d.size, "must be in 1..=8192"));
        }
        let f = &d.frame;
        if !(f.centre.is_finite()
            && f.dir.is_finite()
            && f.right.is_finite()
            && f.up.is_finite()
            && f.radius.is_finite()
            && f.radius > 0.0)
        {
            return Err(invalid("frame", format!("{f:?}"), "must be finite"));
        }
        if !self.asset.slices.tiled() && d.patch != [1, 1] {
            return Err(invalid(
                "patch",
                format!("{:?}", d.patch),
                "an object's slices draw one box: [1, 1] (a patch of tiles needs a tiled asset)",
            ));
        }
        let t0 = Instant::now();
        let stack = match d.stack {
            Some(s) => s,
            None => {
                let c = self.asset.choose(f.dir, d.choose_px).map_err(|e| {
                    invalid(
                        "direction or choice size",
                        format!("{:?} at {} px ({e})", f.dir, d.choose_px),
                        "must be finite, non-zero and positive",
                    )
                })?;
                (c.axis, c.level)
            }
        };
        let (axis, level) = stack;
        let i = axis.index();
        let side = if f.dir[i] > 0.0 {
            Side::Plus
        } else {
            Side::Minus
        };
        let slot = self
            .slots
            .iter()
            .find(|s| s.axis == axis && s.level == level && s.side == side)
            .or_else(|| {
                // One side stored: both sides read it (`Stack::slices`).
                self.slots
                    .iter()
                    .find(|s| s.axis == axis && s.level == level)
            })
            .ok_or_else(|| {
                invalid(
                    "stack",
                    format!("axis {} level {level}", axis.name()),
                    "is not in the asset",
                )
            })?;
        let slices = &self.asset.slices;
        let stored = slices.stack(axis, level).map_err(|e| {
            invalid(
                "stack",
                format!("axis {} level {level} ({e})", axis.name()),
                "is not in the asset",
            )
        })?;
        let dims = slices.dims();
        let extent =
            DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * slices.voxel_size();
        let (ua, va) = axis.plane_axes();
        // The 2D level of detail of object.rs: the footprint of one pixel on the slice plane.
        let dir = -f.dir;
        let foot = |e: DVec3| e - (e[i] / dir[i]) * dir;
        let fx = foot(f.right * (2.0 * f.radius / d.size as f64));
        let fy = foot(f.up * (2.0 * f.radius / d.size as f64));
        let pyramid = &stored.slices(side)[0];
        let lod = pyramid.lod(
            fx[ua] / extent[ua],
            fx[va] / extent[va],
            fy[ua] / extent[ua],
            fy[va] / extent[va],
        );
        // render.rs `trilinear_into`: the level clamped, 0 when not finite.
        let max = (slot.levels.len() - 1) as f64;
        let lod = if lod.is_finite() {
            lod.clamp(0.0, max)
        } else {
            0.0
        };
        let l0 = lod.floor() as usize;
        let blend = (lod - l0 as f64) as f32;
        let l1 = (l0 + 1).min(slot.levels.len() - 1);
        let min = if slices.tiled() {
            DVec3::ZERO
        } else {
            DVec3::from_array(BOX_MIN)
        };
        let c = f.centre - min;
        // The box rays are clipped to: the patch of tiles, unbounded along a direction of 0.
        let tiles = |n: u32| if n == 0 { 1.0 } else { f64::from(n) };
        let clip = extent * DVec3::new(tiles(d.patch[0]), 1.0, tiles(d.patch[1]));
        let scalars: Vec<f32> = [
            d.size as f64,
            c.x,
            c.y,
            c.z,
            f.radius,
            f.right.x,
            f.right.y,
            f.right.z,
            f.up.x,
            f.up.y,
            f.up.z,
            f.dir.x,
            f.dir.y,
            f.dir.z,
            extent.x,
            extent.y,
            extent.z,
            stored.spacing(),
            1.0 / f.dir[i].abs().max(1e-12),
        ]
        .iter()
        .map(|&v| v as f32)
        .chain([blend, (1.0f64 - 1e-7) as f32])
        .chain([clip.x as f32, clip.y as f32, clip.z as f32])
        .collect();
        let repeat = |a: usize| u32::from(slices.tiled() && a != 1);
        let ints: Vec<u32> = [
            i as u32,
            ua as u32,
            va as u32,
            stored.count() as u32,
            slot.base as u32,
            slot.stride as u32,
            slot.levels[l0].0 as u32,
            slot.levels[l0].1 as u32,
            slot.levels[l0].2 as u32,
            slot.levels[l1].0 as u32,
            slot.levels[l1].1 as u32,
            slot.levels[l1].2 as u32,
            repeat(ua),
            repeat(va),
            u32::from(d.patch[0] == 0),
            u32::from(d.patch[1] == 0),
            u32::from(slices.tiled() && axis != Axis::Y),
        ]
        .to_vec();
        let fbuf = storage(gpu, "slice scalars", bytemuck::cast_slice(&scalars));
        let ibuf = storage(gpu, "slice integers", bytemuck::cast_slice(&ints));
        let frags = d.size * d.size;
        let drawn = offscreen::draw(
            gpu,
            &self.pipeline,
            &[&fbuf, &ibuf, &self.texels],
            2 * frags,
            (d.size, d.size),
            t0,
        )?;
        let mut frame = SlicesFrame {
            image: drawn.image,
            steps: Vec::with_capacity(frags),
            covered: Vec::with_capacity(frags),
            stack,
            millis: drawn.millis,
        };
        for w in drawn.steps.chunks_exact(2) {
            frame.steps.push(w[0]);
            frame.covered.push(w[1] != 0);
        }
        Ok(frame)
    }
}
