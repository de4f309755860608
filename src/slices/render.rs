//! CPU renderer of slice stacks over a flat tiled patch: per pixel sample, the slices its ray
//! crosses inside `y ∈ [0, L_y]` are composited (nearest in front), each read from its 2D
//! pyramid by bilinear or trilinear filtering, with the opacity correction of the module
//! conventions. The patch is the texel tiled without end in `x` and `z`.

use altrep_data_gen::RgbaImage;
use altrep_data_gen::Supersample;
use glam::DVec3;
use rayon::prelude::*;

use super::merge::{Side, SliceData, Stack};
use super::volume::{SliceReconstruction, rescale_thickness};
use super::{Axis, SliceError};
use crate::mip::Pyramid;

/// An orthographic view of the patch (see the module conventions).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StackView {
    /// Angle from `+y` (radians); beyond `π/2` the view is from below.
    pub polar: f64,
    /// Angle about `y` from `+x` toward `+z` (radians).
    pub azimuth: f64,
}

impl StackView {
    /// A view from angles in degrees.
    pub fn degrees(polar: f64, azimuth: f64) -> Self {
        Self {
            polar: polar.to_radians(),
            azimuth: azimuth.to_radians(),
        }
    }

    /// Unit vector toward the viewer, `v = (sin θ cos φ, cos θ, sin θ sin φ)`.
    pub fn vector(&self) -> DVec3 {
        let (st, ct) = self.polar.sin_cos();
        let (sp, cp) = self.azimuth.sin_cos();
        DVec3::new(st * cp, ct, st * sp)
    }

    /// Screen right `(sin φ, 0, −cos φ)` and up `v × right`.
    pub fn basis(&self) -> (DVec3, DVec3) {
        let (sp, cp) = self.azimuth.sin_cos();
        let right = DVec3::new(sp, 0.0, -cp);
        (right, self.vector().cross(right))
    }

    /// Errors: non-finite angles, a view within 1° of the surface plane (the ray's path through
    /// the texel layer would be unbounded).
    pub fn validate(&self) -> Result<(), SliceError> {
        super::check_range("view polar angle", self.polar, f64::MIN, f64::MAX, "finite")?;
        super::check_range("view azimuth", self.azimuth, f64::MIN, f64::MAX, "finite")?;
        if self.polar.cos().abs() < 1f64.to_radians().sin() {
            return Err(SliceError::InvalidParameter {
                name: "view polar angle",
                value: format!("{}°", self.polar.to_degrees()),
                reason: "must be at least 1° away from the surface plane (90°)",
            });
        }
        Ok(())
    }
}

/// Parameters of an image of the patch (slices and ground truth alike).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SliceRenderParams {
    /// Image width (pixels).
    pub width: usize,
    /// Image height (pixels).
    pub height: usize,
    /// Pixel size in voxel edges (the distance: 1 is one pixel per voxel).
    pub pixel_voxels: f64,
    /// Sub-samples per pixel edge ([`Supersample`]: `k × k` stratified per pixel, averaged).
    pub supersample: Supersample,
    /// Read each slice with trilinear 2D mip filtering at the sub-sample's footprint (as a GPU);
    /// off: bilinear from the finest 2D level.
    pub mip_2d: bool,
    /// Raise each slice's opacity to the path length at the view's angle (module conventions).
    pub opacity_correction: bool,
    /// Texel reconstruction within a slice: bilinear (with [`SliceRenderParams::mip_2d`] trilinear)
    /// or nearest (finest level only).
    pub filter: SliceReconstruction,
    /// Shift of the image centre from the tile centre, `(x, z)` world units.
    pub offset: [f64; 2],
}

impl Default for SliceRenderParams {
    /// 64 × 64 pixels of one voxel, 2 × 2 sub-samples, 2D mip off, opacity correction on,
    /// bilinear texels, centred on the tile.
    fn default() -> Self {
        Self {
            width: 64,
            height: 64,
            pixel_voxels: 1.0,
            supersample: Supersample::of(2),
            mip_2d: false,
            opacity_correction: true,
            filter: SliceReconstruction::Linear,
            offset: [0.0; 2],
        }
    }
}

impl SliceRenderParams {
    /// Errors: zero sizes, more than 64 sub-samples per side, a pixel size outside
    /// `[1e-6, 1e6]` voxels, an offset that is not finite or beyond `1e9`.
    pub fn validate(&self) -> Result<(), SliceError> {
        for (n, what) in [
            (self.width, "image width"),
            (self.height, "image height"),
            (self.supersample.get(), "supersampling"),
        ] {
            if n == 0 {
                return Err(SliceError::ZeroSize { what });
            }
        }
        super::check_range(
            "pixel size",
            self.pixel_voxels,
            1e-6,
            1e6,
            "in [1e-6, 1e6] voxels",
        )?;
        for o in self.offset {
            super::check_range("image offset", o, f64::MIN, f64::MAX, "finite")?;
        }
        Ok(())
    }
}

/// One sub-sample ray: origin on the screen plane, the part inside the texel layer `[t0, t1]`
/// (direction `−v`, `t` grows away from the viewer) and the sub-sample spacing.
pub(crate) struct Ray {
    pub o: DVec3,
    pub dir: DVec3,
    pub t0: f64,
    pub t1: f64,
}

/// Camera of an image: the view, basis and pixel geometry.
pub(crate) struct Camera {
    pub v: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    centre: DVec3,
    pixel: f64,
    width: usize,
    height: usize,
    pub k: usize,
    height_y: f64,
}

impl Camera {
    pub fn new(extent: DVec3, voxel: f64, view: &StackView, p: &SliceRenderParams) -> Self {
        let (right, up) = view.basis();
        Self {
            v: view.vector(),
            right,
            up,
            centre: DVec3::new(
                0.5 * extent.x + p.offset[0],
                0.5 * extent.y,
                0.5 * extent.z + p.offset[1],
            ),
            pixel: p.pixel_voxels * voxel,
            width: p.width,
            height: p.height,
            k: p.supersample.get(),
            height_y: extent.y,
        }
    }

    /// Sub-sample spacing on screen (world units).
    pub fn step(&self) -> f64 {
        self.pixel / self.k as f64
    }

    /// Ray of sub-sample `(a, b)` of pixel `(i, j)`.
    pub fn ray(&self, i: usize, j: usize, a: usize, b: usize) -> Ray {
        let x = -0.5 * self.width as f64 * self.pixel
            + (i as f64 + (a as f64 + 0.5) / self.k as f64) * self.pixel;
        let y = 0.5 * self.height as f64 * self.pixel
            - (j as f64 + (b as f64 + 0.5) / self.k as f64) * self.pixel;
        let o = self.centre + x * self.right + y * self.up;
        let dir = -self.v;
        let ta = -o.y / dir.y;
        let tb = (self.height_y - o.y) / dir.y;
        Ray {
            o,
            dir,
            t0: ta.min(tb),
            t1: ta.max(tb),
        }
    }

    /// Renders an image, calling `shade` per sub-sample ray (pixels in parallel by rows).
    pub fn image<F>(&self, shade: F) -> RgbaImage
    where
        F: Fn(&Ray) -> [f64; 4] + Sync,
    {
        let mut img = RgbaImage::new(self.width, self.height);
        let norm = 1.0 / (self.k * self.k) as f64;
        img.pixels
            .par_chunks_mut(self.width)
            .enumerate()
            .for_each(|(j, row)| {
                for (i, px) in row.iter_mut().enumerate() {
                    let mut acc = [0.0f64; 4];
                    for b in 0..self.k {
                        for a in 0..self.k {
                            let c = shade(&self.ray(i, j, a, b));
                            for (s, x) in acc.iter_mut().zip(c) {
                                *s += x;
                            }
                        }
                    }
                    *px = acc.map(|x| (x * norm) as f32);
                }
            });
        img
    }
}

/// Front-to-back accumulation: `acc = acc over_under sample` (the sample lies behind `acc`).
/// Returns `true` once the accumulated opacity leaves less than `1e-6` to fill.
#[inline]
pub(crate) fn accumulate(acc: &mut [f64; 4], sample: [f64; 4]) -> bool {
    let t = 1.0 - acc[3];
    for k in 0..4 {
        acc[k] += t * sample[k];
    }
    acc[3] > 1.0 - 1e-6
}

/// Reads slice `pyr` at `(u, v)` (texture coordinates in `[0, 1]`) with trilinear filtering at
/// level of detail `lod` (clamped to the pyramid's levels; 0 when not finite), as a GPU's
/// mip-mapped sampler: bilinear in the two nearest 2D levels, blended linearly.
pub(crate) fn trilinear_into(pyr: &Pyramid, lod: f64, u: f64, v: f64, out: &mut [f32; 4]) {
    let max = (pyr.levels().len() - 1) as f64;
    let lod = if lod.is_finite() {
        lod.clamp(0.0, max)
    } else {
        0.0
    };
    let l0 = lod.floor() as usize;
    let f = (lod - l0 as f64) as f32;
    pyr.bilinear_into(l0, u, v, out);
    if f > 0.0 {
        let mut b = [0.0f32; 4];
        pyr.bilinear_into(l0 + 1, u, v, &mut b);
        for (x, y) in out.iter_mut().zip(b) {
            *x = (1.0 - f) * *x + f * y;
        }
    }
}

/// Composites the slices of `stack` that `ray` crosses.
fn shade_stack(
    stack: &Stack,
    extent: DVec3,
    cam: &Camera,
    ray: &Ray,
    p: &SliceRenderParams,
    out: &mut [f32; 4],
) -> [f64; 4] {
    let axis = stack.axis();
    let i = axis.index();
    let (ua, va) = axis.plane_axes();
    let d_i = ray.dir[i];
    let mut acc = [0.0f64; 4];
    if d_i.abs() < 1e-12 {
        return acc;
    }
    let side = if cam.v[i] > 0.0 {
        Side::Plus
    } else {
        Side::Minus
    };
    let slices = stack.slices(side);
    let n = slices.len() as i64;
    let h = stack.spacing();
    let qa = ray.o[i] + ray.t0 * d_i;
    let qb = ray.o[i] + ray.t1 * d_i;
    let (lo, hi) = (qa.min(qb), qa.max(qb));
    let mut m_lo = (lo / h - 0.5).ceil() as i64;
    let mut m_hi = (hi / h - 0.5).floor() as i64;
    if axis == Axis::Y {
        m_lo = m_lo.max(0);
        m_hi = m_hi.min(n - 1);
    }
    if m_lo > m_hi {
        return acc;
    }
    let ratio = if p.opacity_correction {
        1.0 / cam.v[i].abs()
    } else {
        1.0
    };
    // Footprint of one sub-sample on the slice plane (for the 2D level of detail).
    let foot = |e: DVec3| e - (e[i] / d_i) * ray.dir;
    let (dx, dy) = (foot(cam.right * cam.step()), foot(cam.up * cam.step()));
    let count = (m_hi - m_lo + 1) as usize;
    for step in 0..count {
        let m = if d_i > 0.0 {
            m_lo + step as i64
        } else {
            m_hi - step as i64
        };
        let t = ((m as f64 + 0.5) * h - ray.o[i]) / d_i;
        let hit = ray.o + t * ray.dir;
        let (u, v) = (hit[ua] / extent[ua], hit[va] / extent[va]);
        let pyr = &slices[m.rem_euclid(n) as usize];
        if p.filter == SliceReconstruction::Nearest {
            let t = &pyr.levels()[0];
            let index = |x: f64, len: usize, axis: usize| {
                let i = (x * len as f64).floor() as i64;
                if axis == 1 {
                    i.clamp(0, len as i64 - 1) as usize
                } else {
                    i.rem_euclid(len as i64) as usize
                }
            };
            out.copy_from_slice(t.texel(index(u, t.width, ua), index(v, t.height, va)));
        } else if p.mip_2d {
            let lod = pyr.lod(
                dx[ua] / extent[ua],
                dx[va] / extent[va],
                dy[ua] / extent[ua],
                dy[va] / extent[va],
            );
            trilinear_into(pyr, lod, u, v, out);
        } else {
            pyr.bilinear_into(0, u, v, out);
        }
        let s = rescale_thickness(out.map(f64::from), ratio);
        if accumulate(&mut acc, s) {
            break;
        }
    }
    acc
}

/// Draws the stack of `axis` at `level` of `data` over the flat tiled patch. Cost: per sub-sample
/// one (bilinear) or two (trilinear) fetches per slice crossed, rows in parallel.
///
/// Errors: invalid view or parameters, a stack not built.
pub fn render_slices(
    data: &SliceData,
    axis: Axis,
    level: usize,
    view: &StackView,
    params: &SliceRenderParams,
) -> Result<RgbaImage, SliceError> {
    view.validate()?;
    params.validate()?;
    let stack = data.stack(axis, level)?;
    let dims = data.dims();
    let s = data.voxel_size();
    let extent = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * s;
    let cam = Camera::new(extent, s, view, params);
    Ok(cam.image(|ray| {
        let mut out = [0.0f32; 4];
        shade_stack(stack, extent, &cam, ray, params, &mut out)
    }))
}
