//! Images with parallax on the GPU: the fragment-shader twin of `altrep::parallax::render_with`
//! (inverse warping bounded by the cylinder, any screen size, one ray per pixel, no mip) and of
//! `altrep::parallax::render_bounded_with` (stored per-pixel bounds of every kind, at the views'
//! own size), under any `Reconstruction` (the default: tangent brims as the asset's images
//! define them, linear row filter, fallback views (doubtful hits at half coverage), soft edges,
//! hole filling, brim carving; or the
//! original path). Two bracketing views are marched per fragment and view row read, combined by
//! angular proportion (the next views out, from the cylinder, where both miss), relit from the
//! stored normals with a diffuse light; the output is premultiplied RGBA and the depth of the
//! nearer crossing is written.
//!
//! The shader (`parallax.wgsl`) repeats the CPU's formulas in the same order; it runs in `f32`
//! ([`Precision::F32`], what an engine ships) or, where the adapter has `SHADER_F64`, in `f64`
//! ([`Precision::F64`]), in which it is the CPU's computation operation for operation (per-draw
//! constants `cos θ`, `sin θ` and the blend weights come from the host, in `f64`, as the CPU
//! computes them). Per-fragment march steps go to a storage buffer that [`DrawnFrame::steps`] returns.

use std::time::Instant;

use altrep::parallax::asset::ParallaxData;
use altrep::parallax::{BoundKind, Brim, ParallaxImages, Reconstruction, RowFilter};
use altrep_data_gen::Light;

use crate::offscreen::{self, Pipeline, storage};
use crate::shader::{Precision, Shader};
use crate::{DisplayError, DrawnFrame, Gpu, invalid};

/// What to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrawParams {
    /// Display azimuth `α` (radians, any finite value).
    pub alpha: f64,
    /// Which march bounds: [`BoundKind::Cylinder`] (always available, any screen size) or a kind
    /// stored in the asset (screen size must equal the views' size, where stored bounds hold).
    pub kind: BoundKind,
    /// Screen columns (the impostor quad `[−R, R]` fills them).
    pub width: usize,
    /// Screen rows (the quad `[0, H]`).
    pub height: usize,
    /// The light (direction toward it, ambient share).
    pub light: Light,
    /// How the views are combined: `Reconstruction::DEFAULT` (what `altrep::parallax::render`
    /// draws) or any other, e.g. `Reconstruction::ORIGINAL`. The surface model at silhouettes
    /// is the asset's (`ParallaxImages::brim`).
    pub rec: Reconstruction,
}

/// An images-with-parallax asset uploaded to the GPU, with the pipeline that draws it.
pub struct ParallaxDisplay {
    precision: Precision,
    pipeline: std::sync::Arc<Pipeline>,
    lx: usize,
    ly: usize,
    images: ParallaxImages,
    attr: wgpu::Buffer,
    code: wgpu::Buffer,
    /// Bound buffers per stored kind; the cylinder uses `dummy`.
    bounds: Vec<(BoundKind, wgpu::Buffer)>,
    dummy: wgpu::Buffer,
    fixed: [f64; 5],
}

/// Bytes of `values` in the shader's `real` type.
pub(crate) fn reals(values: &[f64], precision: Precision) -> Vec<u8> {
    match precision {
        Precision::F32 => values
            .iter()
            .flat_map(|&v| (v as f32).to_le_bytes())
            .collect(),
        Precision::F64 => values.iter().flat_map(|&v| v.to_le_bytes()).collect(),
    }
}

impl ParallaxDisplay {
    /// Uploads `data` (views as decoded albedo/normal and depth codes, every stored bound kind)
    /// and builds the pipeline in `precision`. Cost: one pass over the texels; GPU memory
    /// `N·Lx·Ly·(36 + 8·size(real)·kinds)` bytes.
    ///
    /// Errors: [`Precision::F64`] on a device without `SHADER_F64`; a shader or pipeline the
    /// device rejects ([`DisplayError::Gpu`]).
    pub fn new(gpu: &Gpu, data: &ParallaxData, precision: Precision) -> Result<Self, DisplayError> {
        let pipeline = offscreen::pipeline(gpu, Shader::Parallax, precision)?;
        let images = &data.images;
        let p = &images.params;
        let (lx, ly, n) = (p.width, p.height, p.views);
        let codes = images.codes();
        let mut attr = Vec::with_capacity(n * lx * ly * 8);
        let mut code = Vec::with_capacity(n * lx * ly);
        for (v, c) in images.views.iter().zip(&codes) {
            for j in 0..ly {
                for i in 0..lx {
                    let idx = j * lx + i;
                    let (a, nm) = v
                        .attributes(i, j)
                        .unwrap_or((glam::Vec3::ZERO, glam::Vec3::ZERO));
                    attr.extend_from_slice(&[a.x, a.y, a.z, 0.0, nm.x, nm.y, nm.z, 0.0]);
                    code.push(u32::from(c.depth[idx]) | (u32::from(c.defined[idx]) << 16));
                }
            }
        }
        let attr = storage(gpu, "parallax attributes", bytemuck::cast_slice(&attr));
        let code = storage(gpu, "parallax depth codes", bytemuck::cast_slice(&code));
        let mut bounds = Vec::new();
        for b in &data.bounds {
            if b.kind == BoundKind::Cylinder {
                continue;
            }
            let mut vals = Vec::with_capacity(n * lx * ly * 8);
            for k in 0..n {
                let slots = b.view_slots(k);
                if slots.len() != lx * ly {
                    return Err(invalid(
                        "stored bounds",
                        b.kind.name(),
                        "do not cover every pixel of every view",
                    ));
                }
                for s in slots {
                    for slot in s {
                        match slot {
                            Some(pb) => vals.extend_from_slice(&[pb.c, pb.v_min, pb.v_max, 1.0]),
                            None => vals.extend_from_slice(&[0.0; 4]),
                        }
                    }
                }
            }
            bounds.push((
                b.kind,
                storage(gpu, b.kind.slug(), &reals(&vals, precision)),
            ));
        }
        let dummy = storage(gpu, "no bounds", &reals(&[0.0; 8], precision));
        let grid = images.pixel_grid();
        Ok(Self {
            precision,
            pipeline,
            lx,
            ly,
            images: images.clone(),
            attr,
            code,
            bounds,
            dummy,
            fixed: [
                p.cylinder.radius,
                grid.pitch_x(),
                images.march_radius(),
                p.continuity_texels * grid.pitch_x(),
                ((1u64 << p.depth_bits) - 1) as f64,
            ],
        })
    }

    /// How far the march ends are widened so that an end lying on a cell boundary (a texel
    /// centre, e.g. every pixel at θ = 0) also visits the cell before it: the CPU's `1e-9·δx`
    /// in `f64`; in `f32` that is below rounding, so 16 ulps of the march radius (about
    /// `2e-6·R`) stand in for it. Ends closer than this to a boundary but farther than
    /// `1e-9·δx` then visit one cell more than on the CPU (rare; measured by the tests).
    fn eps(&self) -> f64 {
        match self.precision {
            Precision::F64 => 1e-9 * self.fixed[1],
            Precision::F32 => 16.0 * f64::from(f32::EPSILON) * self.fixed[2],
        }
    }

    /// The precision the shader runs in.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// Bound kinds this asset can be drawn with: the cylinder and every stored kind.
    pub fn kinds(&self) -> Vec<BoundKind> {
        std::iter::once(BoundKind::Cylinder)
            .chain(self.bounds.iter().map(|b| b.0))
            .collect()
    }

    /// Draws one frame and reads back the image, the steps (of the two bracketing views, summed
    /// over the view rows read; fallback marches not counted, as `render_bounded_with`) and the
    /// depth. Cost: one draw of `width × height` fragments, two bounded marches per view row
    /// read (one at the views' size, two with the linear row filter at other sizes) plus two
    /// cylinder marches where both views miss and `rec.fallback` is set, plus the read-back.
    ///
    /// Errors: a non-finite angle, a zero or huge screen, a kind not stored in the asset, stored
    /// bounds at a screen size other than the views', a GPU error.
    pub fn render(&self, gpu: &Gpu, d: &DrawParams) -> Result<DrawnFrame, DisplayError> {
        if !d.alpha.is_finite() {
            return Err(invalid("alpha", d.alpha, "must be finite"));
        }
        if d.width == 0 || d.height == 0 || d.width > 8192 || d.height > 8192 {
            return Err(invalid(
                "screen size",
                format!("{}×{}", d.width, d.height),
                "must be in 1..=8192",
            ));
        }
        let dir = d.light.direction;
        if !(dir.is_finite() && d.light.ambient.is_finite()) {
            return Err(invalid("light", format!("{:?}", d.light), "must be finite"));
        }
        let (kind_id, bounds) = match d.kind {
            BoundKind::Cylinder => (0u32, &self.dummy),
            k => {
                let b =
                    self.bounds.iter().find(|b| b.0 == k).ok_or_else(|| {
                        invalid("bound kind", k.name(), "is not stored in the asset")
                    })?;
                if (d.width, d.height) != (self.lx, self.ly) {
                    return Err(invalid(
                        "screen size",
                        format!("{}×{}", d.width, d.height),
                        "must equal the views' size with stored bounds (they hold at texel centres)",
                    ));
                }
                let id = match k {
                    BoundKind::ZMinMax => 1,
                    BoundKind::FPair => 2,
                    BoundKind::BestC => 3,
                    _ => 4,
                };
                (id, &b.1)
            }
        };
        let t0 = Instant::now();
        let [(k1, t1, w1), (k2, t2, w2)] = self
            .images
            .bracketing(d.alpha)
            .map_err(|_| invalid("alpha", d.alpha, "must be finite"))?;
        let [(k0, th0, w0), (k3, t3, w3)] = self
            .images
            .fallback_views(d.alpha)
            .map_err(|_| invalid("alpha", d.alpha, "must be finite"))?;
        let r = self.images.params.cylinder.radius;
        let max_slope = match self.images.brim() {
            Brim::Flat => 0.0,
            Brim::Tangent { max_slope } => max_slope,
        };
        let mut pv = self.fixed.to_vec();
        pv.extend_from_slice(&[
            t1.cos(),
            t1.sin(),
            t2.cos(),
            t2.sin(),
            2.0 * r / d.width as f64,
            self.eps(),
            th0.cos(),
            th0.sin(),
            t3.cos(),
            t3.sin(),
            max_slope,
        ]);
        for v in &self.images.views {
            let (sa, ca) = v.angle.sin_cos();
            pv.extend_from_slice(&[sa, ca]);
        }
        let pbuf = storage(gpu, "P", &reals(&pv, self.precision));
        let u = [
            self.lx as u32,
            self.ly as u32,
            k1 as u32,
            k2 as u32,
            kind_id,
            d.width as u32,
            d.height as u32,
            u32::from(d.rec.rows == RowFilter::Linear),
            u32::from(d.rec.fallback),
            u32::from(d.rec.soft_edges),
            u32::from(d.rec.depth_test),
            k0 as u32,
            k3 as u32,
            u32::from(d.rec.fill_holes),
            u32::from(d.rec.carve_brims),
            u32::from(d.rec.soft_fallback),
        ];
        let ubuf = storage(gpu, "U", bytemuck::cast_slice(&u));
        let l = [
            dir.x,
            dir.y,
            dir.z,
            d.light.ambient,
            w1 as f32,
            w2 as f32,
            w0 as f32,
            w3 as f32,
        ];
        let lbuf = storage(gpu, "L", bytemuck::cast_slice(&l));
        let drawn = offscreen::draw(
            gpu,
            &self.pipeline,
            &[&pbuf, &ubuf, &lbuf, &self.attr, &self.code, bounds],
            2 * d.width * d.height,
            (d.width, d.height),
            t0,
        )?;
        Ok(DrawnFrame {
            image: drawn.image,
            steps: drawn.steps.chunks_exact(2).map(|c| [c[0], c[1]]).collect(),
            depth: drawn.depth,
            millis: drawn.millis,
        })
    }
}
