//! The texel over a curved surface: a **cylindrical patch**, Meyer & Neyret's per-vertex height
//! vectors taken to the limit of a smooth surface (every height vector radial). Slices of the
//! height axis (`y`) become coaxial cylindrical shells; the other two directions are not defined
//! on a curved patch (the paper: "if the texel is not too deformed").
//!
//! ## Mapping (texel → world)
//!
//! The base cylinder has radius `R = tiles_around·L_x/(2π)` about the world `z` axis, so that
//! `tiles_around` tiles close the circle without a seam. Texel point `(x, y, z)` maps to
//! `θ = x/R`, `r = R + y`, world `(r·sin θ, r·cos θ, z)`: `x` runs around as arc length on the base
//! surface, `y` outward along the height vector, `z` along the axis. The medium lives in texel
//! space: a world path's optical depth is `∫ σ(p_tex)·|dp_tex|`, with the texel displacement of a
//! world direction `d` at radius `r` equal to `(d_t·R/r, d_r, d_z)` (`d_t`, `d_r` its tangential and
//! radial parts) — so the texel is stretched by `r/R` around the outside, as fur on a limb.
//!
//! ## Views
//!
//! Orthographic, `v = (0, cos t, sin t)` (`t` the tilt toward the axis, `|t| < 89°`); screen
//! `right = +x`, `up = v × right`; the image spans the cylinder's silhouette `|x| ≤ 1.05·(R + L_y)`
//! and one tile along the axis, centred on it.
//!
//! ## Drawing
//!
//! A ray meets each shell `r = R + (j + ½)·h_k` up to twice: entering (the viewer on the shell's
//! plus side, outside) and leaving (minus side, inside: there per-side merges matter). Crossings
//! are sorted along the ray and composited; each is read bilinearly at `(u, v) = (x/L_x, z/L_z)`
//! with the opacity correction `|d_tex| / |d_r|`. The base surface `r < R` is empty (the rays go
//! through), for slices and truth alike.

use altrep_data_gen::RgbaImage;
use altrep_data_gen::Supersample;
use glam::DVec3;
use rayon::prelude::*;

use super::merge::{Side, SliceData};
use super::render::accumulate;
use super::volume::{alpha_for_thickness, rescale_thickness};
use super::{Axis, SliceError, TexelVolume};

/// Parameters of the cylindrical patch and its images.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CurvedParams {
    /// Tiles around the circumference (sets the radius `R = tiles_around·L_x/(2π)`).
    pub tiles_around: usize,
    /// Tilt of the view toward the axis (degrees, `|t| < 89`).
    pub tilt_deg: f64,
    /// Image width (pixels); the height follows from one tile along the axis.
    pub width: usize,
    /// Sub-samples per pixel edge ([`Supersample`]: `k × k` per pixel).
    pub supersample: Supersample,
    /// Opacity correction by the texel-space path length (module conventions).
    pub opacity_correction: bool,
    /// Truth march samples per voxel edge of world path.
    pub truth_steps: usize,
}

impl Default for CurvedParams {
    /// 8 tiles around, no tilt, 96 pixels wide, 3 × 3 sub-samples, opacity correction, 8 truth
    /// steps per voxel.
    fn default() -> Self {
        Self {
            tiles_around: 8,
            tilt_deg: 0.0,
            width: 96,
            supersample: Supersample::of(3),
            opacity_correction: true,
            truth_steps: 8,
        }
    }
}

impl CurvedParams {
    /// Errors: zero sizes, a tilt at or beyond 89°.
    pub fn validate(&self) -> Result<(), SliceError> {
        for (n, what) in [
            (self.tiles_around, "tiles around"),
            (self.width, "image width"),
            (self.supersample.get(), "supersampling"),
            (self.truth_steps, "truth steps"),
        ] {
            if n == 0 {
                return Err(SliceError::ZeroSize { what });
            }
        }
        super::check_range("tilt", self.tilt_deg, -89.0, 89.0, "in [−89°, 89°]")
    }
}

/// Camera and geometry of a cylindrical-patch image.
struct Setup {
    radius: f64,
    extent: DVec3,
    dir: DVec3,
    right: DVec3,
    up: DVec3,
    pixel: f64,
    width: usize,
    height: usize,
    k: usize,
}

impl Setup {
    fn new(extent: DVec3, p: &CurvedParams) -> Self {
        let radius = p.tiles_around as f64 * extent.x / std::f64::consts::TAU;
        let (st, ct) = p.tilt_deg.to_radians().sin_cos();
        let v = DVec3::new(0.0, ct, st);
        let right = DVec3::X;
        let half = 1.05 * (radius + extent.y);
        let pixel = 2.0 * half / p.width as f64;
        Self {
            radius,
            extent,
            dir: -v,
            right,
            up: v.cross(right),
            pixel,
            width: p.width,
            height: (extent.z / pixel).ceil().max(1.0) as usize,
            k: p.supersample.get(),
        }
    }

    /// The `t` interval(s) where the ray `o + t·dir` is inside radius `rho` (none, or one).
    fn inside(&self, o: DVec3, rho: f64) -> Option<(f64, f64)> {
        let a = self.dir.x * self.dir.x + self.dir.y * self.dir.y;
        let b = 2.0 * (o.x * self.dir.x + o.y * self.dir.y);
        let c = o.x * o.x + o.y * o.y - rho * rho;
        let disc = b * b - 4.0 * a * c;
        if a <= 0.0 || disc < 0.0 {
            return None;
        }
        let q = disc.sqrt();
        Some(((-b - q) / (2.0 * a), (-b + q) / (2.0 * a)))
    }

    /// Texel point of world `p` and the texel displacement of the ray direction there.
    fn texel(&self, p: DVec3) -> (DVec3, DVec3) {
        let r = (p.x * p.x + p.y * p.y).sqrt().max(1e-300);
        let theta = p.x.atan2(p.y);
        let n = DVec3::new(p.x / r, p.y / r, 0.0);
        let t = DVec3::new(p.y / r, -p.x / r, 0.0);
        let d_tex = DVec3::new(
            self.dir.dot(t) * self.radius / r,
            self.dir.dot(n),
            self.dir.z,
        );
        (DVec3::new(self.radius * theta, r - self.radius, p.z), d_tex)
    }

    fn image<F>(&self, shade: F) -> RgbaImage
    where
        F: Fn(DVec3) -> [f64; 4] + Sync,
    {
        let mut img = RgbaImage::new(self.width, self.height);
        let norm = 1.0 / (self.k * self.k) as f64;
        let centre = DVec3::new(0.0, 0.0, 0.5 * self.extent.z);
        img.pixels
            .par_chunks_mut(self.width)
            .enumerate()
            .for_each(|(j, row)| {
                for (i, px) in row.iter_mut().enumerate() {
                    let mut acc = [0.0f64; 4];
                    for b in 0..self.k {
                        for a in 0..self.k {
                            let x = -0.5 * self.width as f64 * self.pixel
                                + (i as f64 + (a as f64 + 0.5) / self.k as f64) * self.pixel;
                            let y = 0.5 * self.height as f64 * self.pixel
                                - (j as f64 + (b as f64 + 0.5) / self.k as f64) * self.pixel;
                            let c = shade(centre + x * self.right + y * self.up);
                            for (s, v) in acc.iter_mut().zip(c) {
                                *s += v;
                            }
                        }
                    }
                    *px = acc.map(|x| (x * norm) as f32);
                }
            });
        img
    }
}

/// Draws the height-axis stack of `data` at `level` over the cylindrical patch. Cost: per
/// sub-sample up to two crossings per shell, sorted. Errors: invalid parameters, stack not built.
pub fn render_curved_slices(
    data: &SliceData,
    level: usize,
    params: &CurvedParams,
) -> Result<RgbaImage, SliceError> {
    params.validate()?;
    let stack = data.stack(Axis::Y, level)?;
    let d = data.dims();
    let extent = DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64) * data.voxel_size();
    let setup = Setup::new(extent, params);
    let h = stack.spacing();
    let n = stack.count();
    Ok(setup.image(|o| {
        let mut hits: Vec<(f64, usize)> = Vec::with_capacity(2 * n);
        for j in 0..n {
            if let Some((t0, t1)) = setup.inside(o, setup.radius + (j as f64 + 0.5) * h) {
                hits.push((t0, j));
                hits.push((t1, j));
            }
        }
        hits.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut acc = [0.0f64; 4];
        let mut out = [0.0f32; 4];
        for (t, j) in hits {
            let p = o + t * setup.dir;
            let (q, d_tex) = setup.texel(p);
            let side = if d_tex.y < 0.0 {
                Side::Plus
            } else {
                Side::Minus
            };
            let slice = &stack.slices(side)[j];
            slice.bilinear_into(0, q.x / extent.x, q.z / extent.z, &mut out);
            let ratio = if params.opacity_correction {
                (d_tex.length() / d_tex.y.abs()).min(1e6)
            } else {
                1.0
            };
            if accumulate(&mut acc, rescale_thickness(out.map(f64::from), ratio)) {
                break;
            }
        }
        acc
    }))
}

/// Ray-marched ground truth of `volume` over the cylindrical patch (module docs): midpoint rule
/// with `truth_steps` samples per voxel edge of world path inside the shell `R ≤ r ≤ R + L_y`,
/// optical depth measured in texel space. Errors: invalid parameters.
pub fn render_curved_truth(
    volume: &TexelVolume,
    params: &CurvedParams,
) -> Result<RgbaImage, SliceError> {
    params.validate()?;
    let extent = volume.extent();
    let s = volume.voxel_size();
    let setup = Setup::new(extent, params);
    Ok(setup.image(|o| {
        let mut acc = [0.0f64; 4];
        let Some((a0, a1)) = setup.inside(o, setup.radius + extent.y) else {
            return acc;
        };
        let segments = match setup.inside(o, setup.radius) {
            Some((b0, b1)) => [(a0, b0), (b1, a1)],
            None => [(a0, a1), (a1, a1)],
        };
        for (t0, t1) in segments {
            let len = t1 - t0;
            if len <= 0.0 {
                continue;
            }
            let steps = ((len / s) * params.truth_steps as f64).ceil().max(1.0) as usize;
            let dt = len / steps as f64;
            for k in 0..steps {
                let p = o + (t0 + (k as f64 + 0.5) * dt) * setup.dir;
                let (q, d_tex) = setup.texel(p);
                let v = volume.sample(q);
                let a = v[3];
                if a <= 0.0 {
                    continue;
                }
                let a2 = alpha_for_thickness(a, d_tex.length() * dt / s);
                let f = a2 / a;
                if accumulate(&mut acc, [v[0] * f, v[1] * f, v[2] * f, a2]) {
                    return acc;
                }
            }
        }
        acc
    }))
}
