//! Ray-cast capture: orthographic views and cylindrical textures (docs/design.md §3.3).
//!
//! Both produce a [`SampleGrid`]: per pixel an optional [`Sample`] (albedo, normal, depth).
//! For a **view** at angle `α`, the ray of pixel `(i, j)` starts at `x·right(α) + y·ŷ + 2R·d(α)`
//! and runs along `−d(α)`; `depth = (p·d(α))/R`, positive toward the camera.
//! For a **cylindrical texture** of `Lx × Ly`, column `i` has angle `α_i = 2πi/Lx` and row `j`
//! height `y = H − (j + ½)H/Ly`; its ray starts outside the cylinder on `+d(α_i)` and runs along
//! `−d(α_i)` through the axis; `depth` is then the **signed radius** `r = (p·d(α_i))/R`
//! (positive on the camera's side of the axis, negative beyond it).
//!
//! Cost: one ray per sample, rows in parallel (rayon).

use std::path::Path;

use glam::{DVec3, Vec3};

use crate::error::{DataGenError, finite, nonzero};
use crate::geometry::{BoundingCylinder, Hit, PixelGrid, RadialRays, Ray, ViewGrid};
use crate::image_io::{RgbaImage, write_image};
use crate::shape::{Shape, trace_grid_in_groups, trace_in_groups};
use crate::truth::Light;

/// What a captured pixel holds when its ray hits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Linear RGB albedo.
    pub albedo: Vec3,
    /// Unit surface normal in the object frame, facing the capture ray's origin.
    pub normal: Vec3,
    /// Depth along the capture direction divided by `R` (view depth toward the camera, or the
    /// signed radius of a cylindrical texture), in `[−1, 1]`.
    pub depth: f32,
}

/// How a [`SampleGrid`] was projected.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Projection {
    /// Orthographic view at this angle (radians).
    Orthographic {
        /// View angle `α`.
        angle: f64,
    },
    /// Cylindrical texture: column `i` at angle `2πi/width`.
    Cylindrical,
}

/// A grid of optional samples, row-major, row 0 at the top (`index = j·width + i`).
#[derive(Clone, Debug, PartialEq)]
pub struct SampleGrid {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The cylinder the grid spans.
    pub cylinder: BoundingCylinder,
    /// How it was captured.
    pub projection: Projection,
    /// `width × height` samples; `None` where the ray missed.
    pub samples: Vec<Option<Sample>>,
}

/// Parameters of an orthographic view capture.
#[derive(Clone, Copy, Debug)]
pub struct ViewParams {
    /// View angle `α` (radians); the camera looks along `−d(α)`.
    pub angle: f64,
    /// Columns `Lx`.
    pub width: usize,
    /// Rows `Ly`.
    pub height: usize,
    /// The bounding cylinder.
    pub cylinder: BoundingCylinder,
}

/// Parameters of a cylindrical-texture capture.
#[derive(Clone, Copy, Debug)]
pub struct CylinderParams {
    /// Columns (angles) `Lx`; default 256.
    pub columns: usize,
    /// Rows (heights) `Ly`; default 64.
    pub rows: usize,
    /// The bounding cylinder.
    pub cylinder: BoundingCylinder,
}

impl Default for CylinderParams {
    fn default() -> Self {
        Self {
            columns: 256,
            rows: 64,
            cylinder: BoundingCylinder::default(),
        }
    }
}

impl SampleGrid {
    /// The pixel grid (pitches and centres) of this capture.
    pub fn pixel_grid(&self) -> PixelGrid {
        PixelGrid {
            width: self.width,
            height: self.height,
            cylinder: self.cylinder,
        }
    }

    /// Sample at column `i`, row `j` (`None` if undefined or out of range).
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> Option<&Sample> {
        if i < self.width && j < self.height {
            self.samples[j * self.width + i].as_ref()
        } else {
            None
        }
    }

    /// Share of defined samples.
    pub fn coverage(&self) -> f64 {
        self.samples.iter().filter(|s| s.is_some()).count() as f64
            / self.samples.len().max(1) as f64
    }

    /// The samples shaded by `light` as an RGBA image (alpha 1 where defined, 0 elsewhere).
    pub fn shade(&self, light: &Light) -> RgbaImage {
        let pixels = self
            .samples
            .iter()
            .map(|s| match s {
                Some(s) => {
                    let c = light.shade(s.albedo, s.normal);
                    [c.x, c.y, c.z, 1.0]
                }
                None => [0.0; 4],
            })
            .collect();
        RgbaImage {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// Writes the albedo as an sRGB RGBA8 PNG (alpha 0 where undefined).
    pub fn write_albedo_png(&self, path: &Path) -> Result<(), DataGenError> {
        let img = RgbaImage {
            width: self.width,
            height: self.height,
            pixels: self
                .samples
                .iter()
                .map(|s| s.map_or([0.0; 4], |s| [s.albedo.x, s.albedo.y, s.albedo.z, 1.0]))
                .collect(),
        };
        img.write_png(path)
    }

    /// Writes normals as an RGBA8 PNG, `rgb = (n + 1)/2` (not sRGB-encoded), alpha 0 where
    /// undefined.
    pub fn write_normal_png(&self, path: &Path) -> Result<(), DataGenError> {
        let mut buf = image::RgbaImage::new(self.width as u32, self.height as u32);
        for (px, s) in buf.pixels_mut().zip(&self.samples) {
            if let Some(s) = s {
                let q = |c: f32| ((c * 0.5 + 0.5).clamp(0.0, 1.0) * 255.0).round() as u8;
                *px = image::Rgba([q(s.normal.x), q(s.normal.y), q(s.normal.z), 255]);
            }
        }
        write_image(path, &image::DynamicImage::ImageRgba8(buf))
    }

    /// Writes depth as a 16-bit grey PNG: `value = round(1 + (depth + 1)/2 · 65534)`, so depth
    /// `−1 → 1`, `+1 → 65535`, and **0 means undefined**. Quantisation step: `2/65534 ≈ 3.1e-5 R`.
    pub fn write_depth_png16(&self, path: &Path) -> Result<(), DataGenError> {
        let mut buf: image::ImageBuffer<image::Luma<u16>, Vec<u16>> =
            image::ImageBuffer::new(self.width as u32, self.height as u32);
        for (px, s) in buf.pixels_mut().zip(&self.samples) {
            if let Some(s) = s {
                let v = 1.0 + (f64::from(s.depth).clamp(-1.0, 1.0) + 1.0) * 0.5 * 65534.0;
                *px = image::Luma([v.round() as u16]);
            }
        }
        write_image(path, &image::DynamicImage::ImageLuma16(buf))
    }
}

fn check_grid(
    width: usize,
    height: usize,
    cylinder: &BoundingCylinder,
) -> Result<(), DataGenError> {
    nonzero(width, "capture width")?;
    nonzero(height, "capture height")?;
    cylinder.validate()
}

/// The sample of `hit` on `ray`, which travels along `−dir_out`: `depth = (p·dir_out)/R`.
fn sample_of(ray: &Ray, hit: &Hit, dir_out: DVec3, radius: f64) -> Sample {
    let p = ray.at(hit.t);
    Sample {
        albedo: hit.albedo,
        normal: hit.normal.as_vec3(),
        depth: (p.dot(dir_out) / radius) as f32,
    }
}

/// Captures an orthographic view of `shape` (docs/design.md §3.3). Cost: `width × height` rays,
/// traced together by [`Shape::parallel_tracer`] in bands of rows (each ray starts `2R` in front of
/// its pixel centre, as a single cast would).
///
/// Errors: zero sizes, a non-finite angle or an invalid cylinder.
pub fn capture_view(shape: &dyn Shape, params: &ViewParams) -> Result<SampleGrid, DataGenError> {
    check_grid(params.width, params.height, &params.cylinder)?;
    finite(params.angle, "view angle", 0)?;
    let grid = PixelGrid {
        width: params.width,
        height: params.height,
        cylinder: params.cylinder,
    };
    // One ray per pixel, through its centre (`grid.center`, bit for bit).
    let view = ViewGrid::new(&grid, params.angle, 1);
    let ray = |i: usize, j: usize| view.ray(i, j);
    let rays = view.parallel_rays(&ray);
    let (d, r) = (view.d(), params.cylinder.radius);
    let w = params.width;
    let mut samples = vec![None; w * params.height];
    trace_in_groups(shape, &rays, 1, w, &mut samples, |first, hits, samples| {
        for (j, (samples, hits)) in samples.chunks_mut(w).zip(hits.chunks(w)).enumerate() {
            for (i, (s, hit)) in samples.iter_mut().zip(hits).enumerate() {
                *s = hit.map(|hit| sample_of(&ray(i, first + j), &hit, d, r));
            }
        }
    });
    Ok(SampleGrid {
        width: params.width,
        height: params.height,
        cylinder: params.cylinder,
        projection: Projection::Orthographic {
            angle: params.angle,
        },
        samples,
    })
}

/// Captures a cylindrical texture of `shape` (docs/design.md §3.3, §6). Cost: `columns × rows`
/// rays, traced together by [`Shape::radial_tracer`] in bands of rows (each ray starts `2R` outside
/// the axis at its row's height and runs through the axis, as a single cast would).
pub fn capture_cylinder(
    shape: &dyn Shape,
    params: &CylinderParams,
) -> Result<SampleGrid, DataGenError> {
    check_grid(params.columns, params.rows, &params.cylinder)?;
    let grid = PixelGrid {
        width: params.columns,
        height: params.rows,
        cylinder: params.cylinder,
    };
    let r = params.cylinder.radius;
    let w = params.columns;
    let heights: Vec<f64> = (0..params.rows)
        .map(|j| grid.y_at(j as f64 + 0.5))
        .collect();
    let rays = RadialRays {
        rows: &heights,
        columns: w,
        radius: r,
    };
    let outward: Vec<DVec3> = (0..w).map(|c| rays.outward(c)).collect();
    let tracer = shape.radial_tracer(&rays);
    let mut samples = vec![None; w * params.rows];
    trace_grid_in_groups(
        &*tracer,
        w,
        params.rows,
        1,
        w,
        &mut samples,
        |first, hits, samples| {
            for (j, (samples, hits)) in samples.chunks_mut(w).zip(hits.chunks(w)).enumerate() {
                for ((s, hit), d) in samples.iter_mut().zip(hits).zip(&outward) {
                    *s = hit.map(|hit| sample_of(&rays.ray_along(*d, first + j), &hit, *d, r));
                }
            }
        },
    );
    Ok(SampleGrid {
        width: params.columns,
        height: params.rows,
        cylinder: params.cylinder,
        projection: Projection::Cylindrical,
        samples,
    })
}
