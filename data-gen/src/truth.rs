//! Ground truth: the original shape ray-cast orthographically, shaded, supersampled.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::error::{DataGenError, finite, nonzero};
use crate::geometry::{BoundingCylinder, PixelGrid, Ray, direction, screen_right};
use crate::image_io::RgbaImage;
use crate::shape::Shape;

/// A directional light with an ambient term: `colour = albedo·(ambient + (1 − ambient)·max(0, n·l))`.
///
/// Every renderer of the project (ground truth, reconstructions, display) shades with this one
/// function, so images differ only by what the representation lost.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Light {
    /// Unit vector toward the light, object frame.
    pub direction: Vec3,
    /// Ambient share in `[0, 1]`.
    pub ambient: f32,
}

impl Default for Light {
    /// From the upper right front (`(0.5, 0.8, 0.35)` normalised), ambient 0.3.
    fn default() -> Self {
        Self {
            direction: Vec3::new(0.5, 0.8, 0.35).normalize(),
            ambient: 0.3,
        }
    }
}

impl Light {
    /// Diffuse shading of `albedo` with unit `normal`.
    #[inline]
    pub fn shade(&self, albedo: Vec3, normal: Vec3) -> Vec3 {
        albedo * (self.ambient + (1.0 - self.ambient) * normal.dot(self.direction).max(0.0))
    }
}

/// Parameters of a ground-truth render.
#[derive(Clone, Copy, Debug)]
pub struct TruthParams {
    /// View angle `α` (radians).
    pub angle: f64,
    /// Image width (pixels).
    pub width: usize,
    /// Image height (pixels).
    pub height: usize,
    /// Supersampling `k`: `k × k` stratified rays per pixel (k ≥ 1).
    pub supersample: usize,
    /// The light.
    pub light: Light,
    /// The bounding cylinder the image spans.
    pub cylinder: BoundingCylinder,
}

/// Renders the ground truth: premultiplied linear RGBA, alpha = coverage of the `k × k`
/// sub-samples. Cost: `width × height × k²` rays, rows in parallel.
pub fn render_truth(shape: &dyn Shape, params: &TruthParams) -> Result<RgbaImage, DataGenError> {
    nonzero(params.width, "truth width")?;
    nonzero(params.height, "truth height")?;
    nonzero(params.supersample, "supersampling factor")?;
    finite(params.angle, "view angle", 0)?;
    params.cylinder.validate()?;
    let grid = PixelGrid {
        width: params.width,
        height: params.height,
        cylinder: params.cylinder,
    };
    let d = direction(params.angle);
    let right = screen_right(params.angle);
    let r = params.cylinder.radius;
    let k = params.supersample;
    let mut pixels = vec![[0.0f32; 4]; params.width * params.height];
    pixels
        .par_chunks_mut(params.width)
        .enumerate()
        .for_each(|(j, row)| {
            for (i, px) in row.iter_mut().enumerate() {
                *px = supersampled(i, j, k, |u, v| {
                    let (x, y) = (grid.x_at(u), grid.y_at(v));
                    let ray = Ray::new(x * right + DVec3::Y * y + 2.0 * r * d, -d);
                    shape
                        .intersect(&ray, 0.0, 4.0 * r)
                        .map(|hit| params.light.shade(hit.albedo, hit.normal.as_vec3()))
                });
            }
        });
    Ok(RgbaImage {
        width: params.width,
        height: params.height,
        pixels,
    })
}

/// Premultiplied linear RGBA of pixel `(i, j)` from `k × k` stratified rays: `shade_at(u, v)`
/// gives the shaded colour at fractional pixel position `(u, v)` (`u = i + ½` at the centre), or
/// `None` for a miss; alpha is the share of hits. Shared by every ground-truth renderer.
pub(crate) fn supersampled(
    i: usize,
    j: usize,
    k: usize,
    shade_at: impl Fn(f64, f64) -> Option<Vec3>,
) -> [f32; 4] {
    let mut acc = [0.0f32; 4];
    for a in 0..k {
        for b in 0..k {
            let u = i as f64 + (a as f64 + 0.5) / k as f64;
            let v = j as f64 + (b as f64 + 0.5) / k as f64;
            if let Some(c) = shade_at(u, v) {
                acc[0] += c.x;
                acc[1] += c.y;
                acc[2] += c.z;
                acc[3] += 1.0;
            }
        }
    }
    let inv = 1.0 / (k * k) as f32;
    acc.map(|v| v * inv)
}
