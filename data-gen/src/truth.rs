//! Ground truth: the original shape ray-cast orthographically, shaded, supersampled.

use crate::Supersample;
use glam::Vec3;

use crate::error::{DataGenError, finite, nonzero};
use crate::geometry::{BoundingCylinder, Hit, PixelGrid, ViewGrid};
use crate::image_io::RgbaImage;
use crate::shape::{Groups, Shape, trace_in_groups};

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
        albedo * self.factor(normal)
    }

    /// The factor [`Light::shade`] multiplies albedo by at unit `normal`: in
    /// `[ambient, 1]`.
    #[inline]
    pub fn factor(&self, normal: Vec3) -> f32 {
        self.ambient + (1.0 - self.ambient) * normal.dot(self.direction).max(0.0)
    }

    /// The albedo this light shades at unit `normal` to `radiance` (linear RGB): how a surface
    /// that is unlit or gives off light enters renderers that shade albedo (docs/real-assets.md,
    /// "Emission and unlit materials"). Exact under this light; another light scales it by the
    /// ratio of the two factors. Where the factor is 0 (no ambient, facing away from the light)
    /// no albedo gives the radiance, and black is returned.
    #[inline]
    pub fn albedo_giving(&self, radiance: Vec3, normal: Vec3) -> Vec3 {
        let f = self.factor(normal);
        if f > 0.0 { radiance / f } else { Vec3::ZERO }
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
    /// Rays per pixel edge ([`Supersample`]: `k × k` stratified per pixel).
    pub supersample: Supersample,
    /// The light.
    pub light: Light,
    /// The bounding cylinder the image spans.
    pub cylinder: BoundingCylinder,
}

impl TruthParams {
    /// A square picture, `size × size` pixels at azimuth `angle`, `supersample` rays per pixel
    /// edge, with the default light and bounding cylinder.
    pub fn square(angle: f64, size: usize, supersample: Supersample) -> Self {
        Self {
            angle,
            width: size,
            height: size,
            supersample,
            light: Light::default(),
            cylinder: BoundingCylinder::default(),
        }
    }
}

/// Renders the ground truth: premultiplied linear RGBA, alpha = coverage of the `k × k`
/// sub-samples. Cost: `width × height × k²` rays, rows in parallel.
pub fn render_truth(shape: &dyn Shape, params: &TruthParams) -> Result<RgbaImage, DataGenError> {
    let view = truth_view(params)?;
    let (k, w, h) = (params.supersample.get(), params.width, params.height);
    let ray = |c: usize, r: usize| view.ray(c, r);
    let rays = view.parallel_rays(&ray);
    let mut pixels = vec![[0.0f32; 4]; w * h];
    trace_in_groups(shape, &rays, k, w, &mut pixels, |_, hits, pixels| {
        shade_groups(hits, pixels, w, k, &params.light);
    });
    Ok(RgbaImage {
        width: params.width,
        height: params.height,
        pixels,
    })
}

/// [`render_truth`] with every ray cast on its own and every texture read at the ray's point,
/// not over its cell (`docs/real-assets.md`): how captures and the truth read textures before
/// footprints, kept to measure what footprints change. Cost: that of [`render_truth`], one BVH
/// walk per ray.
#[doc(hidden)]
pub fn render_truth_at_points(
    shape: &dyn Shape,
    params: &TruthParams,
) -> Result<RgbaImage, DataGenError> {
    /// The shape traced ray by ray (the default tracers), each ray without its footprint.
    struct AtPoints<'a>(&'a dyn Shape);
    impl Shape for AtPoints<'_> {
        fn name(&self) -> &str {
            self.0.name()
        }
        fn intersect(&self, ray: &crate::Ray, t_min: f64, t_max: f64) -> Option<Hit> {
            self.0.intersect(ray, t_min, t_max)
        }
        fn contains(&self, p: glam::DVec3) -> bool {
            self.0.contains(p)
        }
        fn bounds(&self) -> (glam::DVec3, glam::DVec3) {
            self.0.bounds()
        }
        fn albedo_at(&self, p: glam::DVec3) -> Vec3 {
            self.0.albedo_at(p)
        }
    }
    render_truth(&AtPoints(shape), params)
}

/// The ground truth's alpha alone: `alpha[j·width + i]` is bitwise the alpha of pixel `(i, j)`
/// of [`render_truth`] with the same parameters (the light is not used). The rays are the
/// same; each only asks whether it meets the shape ([`Shape::occluded`],
/// [`crate::ParallelTracer::occluded_rows`]), so it skips shading and a mesh's BVH walk stops
/// at the first triangle met. Cost: `width × height × k²` occlusion rays, rows in parallel.
pub fn render_silhouette(
    shape: &dyn Shape,
    params: &TruthParams,
) -> Result<Vec<f32>, DataGenError> {
    let view = truth_view(params)?;
    let (k, w, h) = (params.supersample.get(), params.width, params.height);
    let ray = |c: usize, r: usize| view.ray(c, r);
    let rays = view.parallel_rays(&ray);
    let tracer = shape.parallel_tracer(&rays);
    let mut alpha = vec![0.0f32; w * h];
    let groups = Groups {
        w: w * k,
        h: h * k,
        rows_per_group: k,
        out_per_group: w,
    };
    let trace = |rows, met: &mut [bool]| tracer.occluded_rows(rows, met);
    groups.run(tracer.band_rows(), trace, &mut alpha, |_, met, alpha| {
        let wk = w * k;
        for (jl, row) in alpha.chunks_mut(w).enumerate() {
            for (i, a) in row.iter_mut().enumerate() {
                // `supersampled`'s alpha: the share of sub-samples that meet the shape.
                *a = supersampled(k, |sa, sb| {
                    met[(jl * k + sb) * wk + i * k + sa].then_some(Vec3::ZERO)
                })[3];
            }
        }
    });
    Ok(alpha)
}

/// The sub-sample rays of every pixel of a truth render as one grid of `w·k × h·k` parallel
/// rays, after checking the parameters.
fn truth_view(params: &TruthParams) -> Result<ViewGrid, DataGenError> {
    nonzero(params.width, "truth width")?;
    nonzero(params.height, "truth height")?;
    finite(params.angle, "view angle", 0)?;
    params.cylinder.validate()?;
    let grid = PixelGrid {
        width: params.width,
        height: params.height,
        cylinder: params.cylinder,
    };
    Ok(ViewGrid::new(&grid, params.angle, params.supersample.get()))
}

/// Shades the pixel rows of `pixels` (`w` per row) from the hits of their `k × k` sub-sample
/// rays (`hits` row-major, `w·k` per row, `k` rows per pixel row).
pub(crate) fn shade_groups(
    hits: &[Option<Hit>],
    pixels: &mut [[f32; 4]],
    w: usize,
    k: usize,
    light: &Light,
) {
    let wk = w * k;
    for (jl, row) in pixels.chunks_mut(w).enumerate() {
        for (i, px) in row.iter_mut().enumerate() {
            *px = supersampled(k, |a, b| {
                hits[(jl * k + b) * wk + i * k + a]
                    .map(|hit| light.shade(hit.albedo, hit.normal.as_vec3()))
            });
        }
    }
}

/// Premultiplied linear RGBA of one pixel from `k × k` stratified rays: `shade_at(a, b)` gives
/// the shaded colour of sub-sample column `a`, row `b` (at [`sub_sample`] positions), or `None`
/// for a miss; alpha is the share of hits. Shared by every ground-truth renderer.
pub(crate) fn supersampled(k: usize, shade_at: impl Fn(usize, usize) -> Option<Vec3>) -> [f32; 4] {
    let mut acc = [0.0f32; 4];
    for a in 0..k {
        for b in 0..k {
            if let Some(c) = shade_at(a, b) {
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
