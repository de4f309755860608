//! Ground truth for minification and the error/time sweep of mip, rip, fip and EWA lookups.
//!
//! ## Scene
//! A periodic texture (`W × H` texels per unit square, `(u, v) = (x, y)`) on the plane `z = 0`,
//! seen by a pinhole camera of `P × P` square pixels, each subtending `α_p = 10⁻⁴` rad (a narrow
//! view, so every pixel has nearly the same footprint). The camera looks at the point
//! `(0.3, 0.7, 0)` from the direction `(sin θ cos φ, sin θ sin φ, cos θ)` (tilt `θ` from the
//! normal, azimuth `φ` from the `u` axis) at the distance where one pixel covers
//! `texels_per_pixel` texels at normal incidence, `d = D₀ / (W α_p)`. The footprint is stretched by
//! `1/cos θ` along `(cos φ, sin φ)`.
//!
//! ## Truth
//! A pixel's true value is the mean of the texture (bilinear reconstruction of level 0) over the
//! pixel square on screen: stratified jittered samples, `n_x × n_y` strata with about two
//! strata per texel along each side of the footprint (at least 4, at most 512 per side and
//! `max_samples_per_pixel` in all). The truth is computed twice with independent jitter; their
//! mean is the reference and `rms(t₁ − t₂)/2` (the noise of the mean) is reported beside every
//! error, so an error below it means "indistinguishable from the truth".
//!
//! ## Lookups
//! Every method gets the pixel-centre `(u, v)` and the exact screen derivatives
//! `∂(u, v)/∂(x, y)` (per pixel). Errors are RMS over pixels and channels, in texel-value units;
//! times are single-threaded nanoseconds per lookup (median of 3 passes).

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::ewa::ewa_into;
use super::fip::{FipMap, Scheme};
use super::mip::{MipError, PyramidParams, Texture, WrapMode};
use crate::stats::{EvenMedian, median};
use altrep_data_gen::SplitMix64;

/// Angle subtended by one pixel, radians.
pub const PIXEL_ANGLE: f64 = 1e-4;

/// One view of the textured plane (module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlaneView {
    /// Texels per pixel at normal incidence (`D₀`), > 0.
    pub texels_per_pixel: f64,
    /// Angle between the view direction and the plane normal, degrees in `[0, 89.9]`.
    pub tilt_deg: f64,
    /// Azimuth of the camera about the normal from the `u` axis, degrees.
    pub azimuth_deg: f64,
}

/// Per-pixel lookup input: texture coordinates, derivatives, and the unit direction to the camera
/// in the polygon frame `(R = u, G = normal, B = v)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelFootprint {
    /// Texture coordinates of the pixel centre.
    pub uv: [f64; 2],
    /// `[∂u/∂x, ∂v/∂x, ∂u/∂y, ∂v/∂y]` per pixel.
    pub derivs: [f64; 4],
    /// Direction to the camera, `(r, g, b)`.
    pub dir: [f64; 3],
}

/// Pinhole camera of a [`PlaneView`].
struct Camera {
    p: DVec3,
    f: DVec3,
    r: DVec3,
    up: DVec3,
}

impl Camera {
    fn new(view: &PlaneView, width: usize) -> Self {
        let (th, ph) = (view.tilt_deg.to_radians(), view.azimuth_deg.to_radians());
        let d = view.texels_per_pixel / (width as f64 * PIXEL_ANGLE);
        let target = DVec3::new(0.3, 0.7, 0.0);
        let back = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
        let p = target + d * back;
        let f = -back;
        let r = DVec3::new(-ph.sin(), ph.cos(), 0.0);
        let up = r.cross(f);
        Self { p, f, r, up }
    }

    /// Ray direction through screen offset `(sx, sy)` pixels from the image centre.
    fn dir(&self, sx: f64, sy: f64) -> DVec3 {
        self.f + PIXEL_ANGLE * (sx * self.r + sy * self.up)
    }

    /// Plane hit `(u, v)`; `None` if the ray misses the plane.
    fn hit(&self, sx: f64, sy: f64) -> Option<(f64, f64, DVec3, f64)> {
        let d = self.dir(sx, sy);
        if d.z >= -1e-15 {
            return None;
        }
        let t = -self.p.z / d.z;
        let q = self.p + t * d;
        Some((q.x, q.y, d, t))
    }

    fn footprint(&self, sx: f64, sy: f64) -> Option<PixelFootprint> {
        let (u, v, d, t) = self.hit(sx, sy)?;
        // dq/ds = t α_p (a − (a_z / d_z) d) for the screen axis a.
        let dq = |a: DVec3| t * PIXEL_ANGLE * (a - (a.z / d.z) * d);
        let (qx, qy) = (dq(self.r), dq(self.up));
        let to_cam = (self.p - DVec3::new(u, v, 0.0)).normalize();
        Some(PixelFootprint {
            uv: [u, v],
            derivs: [qx.x, qx.y, qy.x, qy.y],
            dir: [to_cam.x, to_cam.z, to_cam.y],
        })
    }
}

/// Bilinear sample of `t` (repeating) at `(u, v)`, one channel `ch`.
fn bilinear(t: &Texture, u: f64, v: f64, out: &mut [f64]) {
    let (s, r) = (u * t.width as f64 - 0.5, v * t.height as f64 - 0.5);
    let (i0, j0) = (s.floor(), r.floor());
    let (fx, fy) = (s - i0, r - j0);
    let (w, h) = (t.width as i64, t.height as i64);
    let i = [(i0 as i64).rem_euclid(w), (i0 as i64 + 1).rem_euclid(w)];
    let j = [(j0 as i64).rem_euclid(h), (j0 as i64 + 1).rem_euclid(h)];
    let wts = [
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    ];
    out.iter_mut().for_each(|o| *o = 0.0);
    for (k, (ii, jj)) in [(i[0], j[0]), (i[1], j[0]), (i[0], j[1]), (i[1], j[1])]
        .into_iter()
        .enumerate()
    {
        for (o, x) in out.iter_mut().zip(t.texel(ii as usize, jj as usize)) {
            *o += wts[k] * f64::from(*x);
        }
    }
}

/// The footprints of the `pixels × pixels` image of `view` (row-major).
pub fn footprints(view: &PlaneView, tex: &Texture, pixels: usize) -> Vec<Option<PixelFootprint>> {
    let cam = Camera::new(view, tex.width);
    let half = pixels as f64 / 2.0;
    (0..pixels * pixels)
        .map(|k| {
            let (x, y) = (
                (k % pixels) as f64 + 0.5 - half,
                (k / pixels) as f64 + 0.5 - half,
            );
            cam.footprint(x, y)
        })
        .collect()
}

/// The supersampled truth of `view` (module docs) with jitter seed `seed`: `pixels² × channels`
/// values, row-major.
pub fn supersampled_truth(
    view: &PlaneView,
    tex: &Texture,
    pixels: usize,
    max_samples_per_pixel: usize,
    seed: u64,
) -> Vec<f64> {
    let cam = Camera::new(view, tex.width);
    let half = pixels as f64 / 2.0;
    let ch = tex.channels;
    let (w, h) = (tex.width as f64, tex.height as f64);
    let mut out = vec![0.0; pixels * pixels * ch];
    out.par_chunks_mut(ch).enumerate().for_each(|(k, px)| {
        let (x0, y0) = ((k % pixels) as f64 - half, (k / pixels) as f64 - half);
        let Some(fp) = cam.footprint(x0 + 0.5, y0 + 0.5) else {
            return;
        };
        let [ux, vx, uy, vy] = fp.derivs;
        let ext = |a: f64, b: f64| ((a * w).hypot(b * h) * 2.0).ceil().clamp(4.0, 512.0);
        let (mut nx, mut ny) = (ext(ux, vx), ext(uy, vy));
        let cap = max_samples_per_pixel.max(16) as f64;
        if nx * ny > cap {
            let s = (cap / (nx * ny)).sqrt();
            nx = (nx * s).floor().max(1.0);
            ny = (ny * s).floor().max(1.0);
        }
        let (nx, ny) = (nx as usize, ny as usize);
        let mut rng = SplitMix64::new(seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let mut s = vec![0.0; ch];
        let mut n = 0usize;
        for j in 0..ny {
            for i in 0..nx {
                let sx = x0 + (i as f64 + rng.next_f64()) / nx as f64;
                let sy = y0 + (j as f64 + rng.next_f64()) / ny as f64;
                if let Some((u, v, _, _)) = cam.hit(sx, sy) {
                    bilinear(tex, u, v, &mut s);
                    px.iter_mut().zip(&s).for_each(|(p, x)| *p += x);
                    n += 1;
                }
            }
        }
        if n > 0 {
            px.iter_mut().for_each(|p| *p /= n as f64);
        }
    });
    out
}

/// Lookup methods compared by the sweep.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum LookupMethod {
    /// Trilinear mipmap with Heckbert's level.
    Mip,
    /// Ripmap, four bilinear levels.
    Rip,
    /// Fipmap database with the per-pixel mip/rip/fip decision.
    Fip,
    /// Elliptical weighted average on the mipmap.
    Ewa,
}

/// All methods, in table order.
pub const METHODS: [LookupMethod; 4] = [
    LookupMethod::Mip,
    LookupMethod::Rip,
    LookupMethod::Fip,
    LookupMethod::Ewa,
];

/// Values of `method` for every footprint (`pixels² × channels`), and ns per lookup.
pub fn lookup_all(
    fip: &FipMap,
    method: LookupMethod,
    fps: &[Option<PixelFootprint>],
    channels: usize,
) -> (Vec<f64>, f64) {
    let max_aniso = fip.mip().params().ewa_max_anisotropy;
    let mut out = vec![0.0f64; fps.len() * channels];
    let mut buf = vec![0.0f32; channels];
    let mut times = Vec::new();
    for _ in 0..3 {
        let start = Instant::now();
        for (k, fp) in fps.iter().enumerate() {
            let Some(fp) = fp else { continue };
            let [u, v] = fp.uv;
            let [ux, vx, uy, vy] = fp.derivs;
            match method {
                LookupMethod::Mip => {
                    fip.sample_into(Scheme::Mip, u, v, ux, vx, uy, vy, None, &mut buf)
                }
                LookupMethod::Rip => {
                    fip.sample_into(Scheme::Rip, u, v, ux, vx, uy, vy, None, &mut buf)
                }
                LookupMethod::Fip => {
                    let scheme = fip.decide(fp.dir);
                    fip.sample_into(scheme, u, v, ux, vx, uy, vy, None, &mut buf)
                }
                LookupMethod::Ewa => ewa_into(fip.mip(), u, v, ux, vx, uy, vy, max_aniso, &mut buf),
            }
            for (o, x) in out[k * channels..(k + 1) * channels].iter_mut().zip(&buf) {
                *o = f64::from(*x);
            }
        }
        times.push(start.elapsed().as_secs_f64() * 1e9 / fps.len().max(1) as f64);
    }
    // Median of the three passes.
    let ns = median(&mut times, EvenMedian::Upper).unwrap_or(0.0);
    (out, ns)
}

/// RMS difference of two equally long value lists ([`crate::stats::rms`] of `a − b`).
pub fn rms(a: &[f64], b: &[f64]) -> f64 {
    crate::stats::rms(a.iter().zip(b).map(|(x, y)| x - y))
}

/// Parameters of [`measure_sweep`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SweepParams {
    /// `D₀` values (texels per pixel at normal incidence), each > 0 and ≤ 4096.
    pub texels_per_pixel: Vec<f64>,
    /// Tilts in degrees, each in `[0, 89.9]`.
    pub tilts_deg: Vec<f64>,
    /// Azimuths in degrees (finite).
    pub azimuths_deg: Vec<f64>,
    /// Image side in pixels (1 to 256).
    pub pixels: usize,
    /// Cap on truth samples per pixel (16 to 1 048 576).
    pub max_samples_per_pixel: usize,
    /// Jitter seed of the truth.
    pub seed: u64,
}

impl Default for SweepParams {
    /// `D₀ ∈ {1, 4, 16}`, tilts `{0, 45, 60, 75, 85, 89}°`, azimuths `{0, 30}°`, 16 × 16 pixels,
    /// at most 8192 truth samples per pixel, seed 1.
    fn default() -> Self {
        Self {
            texels_per_pixel: vec![1.0, 4.0, 16.0],
            tilts_deg: vec![0.0, 45.0, 60.0, 75.0, 85.0, 89.0],
            azimuths_deg: vec![0.0, 30.0],
            pixels: 16,
            max_samples_per_pixel: 8192,
            seed: 1,
        }
    }
}

impl SweepParams {
    /// Checks ranges.
    pub fn validate(&self) -> Result<(), MipError> {
        let bad = |name, reason| Err(MipError::InvalidParams { name, reason });
        if self.texels_per_pixel.is_empty()
            || self
                .texels_per_pixel
                .iter()
                .any(|d| !(d.is_finite() && *d > 0.0 && *d <= 4096.0))
        {
            return bad("texels_per_pixel", "needs values in (0, 4096]");
        }
        if self.tilts_deg.is_empty()
            || self
                .tilts_deg
                .iter()
                .any(|t| !(t.is_finite() && (0.0..=89.9).contains(t)))
        {
            return bad("tilts_deg", "needs values in [0, 89.9]");
        }
        if self.azimuths_deg.is_empty() || self.azimuths_deg.iter().any(|a| !a.is_finite()) {
            return bad("azimuths_deg", "needs finite values");
        }
        if !(1..=256).contains(&self.pixels) {
            return bad("pixels", "must be 1 to 256");
        }
        if !(16..=1 << 20).contains(&self.max_samples_per_pixel) {
            return bad("max_samples_per_pixel", "must be 16 to 1048576");
        }
        Ok(())
    }
}

/// One row of the sweep: a view, the truth's noise, and per method its RMS error and time.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PyramidSweepRow {
    /// The view.
    pub view: PlaneView,
    /// What the decision picked at the image centre.
    pub scheme: Scheme,
    /// RMS noise of the reference truth (module docs).
    pub truth_noise: f64,
    /// RMS error against the truth, in [`METHODS`] order.
    pub rms: [f64; 4],
    /// Nanoseconds per lookup, in [`METHODS`] order.
    pub ns_per_sample: [f64; 4],
}

/// The sweep's result.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SweepReport {
    /// One row per (D₀, tilt, azimuth).
    pub rows: Vec<PyramidSweepRow>,
    /// Bytes of the fipmap database (which holds the mipmap and the ripmap) at 4 bytes/channel.
    pub fip_bytes: usize,
    /// Bytes of the mipmap alone and of the ripmap alone.
    pub mip_bytes: usize,
    /// Bytes of the ripmap.
    pub rip_bytes: usize,
    /// Seconds to build the fipmap database.
    pub build_seconds: f64,
}

/// Measures one view: the reference truth, its noise, and every method's error and time.
pub fn measure_view(
    fip: &FipMap,
    tex: &Texture,
    view: &PlaneView,
    sweep: &SweepParams,
) -> PyramidSweepRow {
    let t1 = supersampled_truth(
        view,
        tex,
        sweep.pixels,
        sweep.max_samples_per_pixel,
        sweep.seed,
    );
    let t2 = supersampled_truth(
        view,
        tex,
        sweep.pixels,
        sweep.max_samples_per_pixel,
        sweep.seed.wrapping_add(0x5151),
    );
    let truth: Vec<f64> = t1.iter().zip(&t2).map(|(a, b)| 0.5 * (a + b)).collect();
    let fps = footprints(view, tex, sweep.pixels);
    let centre = fps[(sweep.pixels / 2) * sweep.pixels + sweep.pixels / 2];
    let scheme = centre.map_or(Scheme::Mip, |f| fip.decide(f.dir));
    let mut rms_v = [0.0; 4];
    let mut ns = [0.0; 4];
    for (k, m) in METHODS.iter().enumerate() {
        let (vals, t) = lookup_all(fip, *m, &fps, tex.channels);
        rms_v[k] = rms(&vals, &truth);
        ns[k] = t;
    }
    PyramidSweepRow {
        view: *view,
        scheme,
        truth_noise: 0.5 * rms(&t1, &t2),
        rms: rms_v,
        ns_per_sample: ns,
    }
}

/// Builds the fipmap database of `tex` (wrap forced to `Repeat`) and measures every view of the
/// sweep. Cost: the build plus, per view, two truths of up to `pixels² × max_samples` bilinear
/// samples (parallel) and `3 × 4 × pixels²` lookups (single-threaded, for timing).
pub fn measure_sweep(
    tex: &Texture,
    params: &PyramidParams,
    sweep: &SweepParams,
) -> Result<SweepReport, MipError> {
    sweep.validate()?;
    let params = PyramidParams {
        wrap: [WrapMode::Repeat; 2],
        ..*params
    };
    let start = Instant::now();
    let fip = FipMap::build(tex.clone(), params)?;
    let build_seconds = start.elapsed().as_secs_f64();
    let mut rows = Vec::new();
    for &d in &sweep.texels_per_pixel {
        for &tilt in &sweep.tilts_deg {
            for &az in &sweep.azimuths_deg {
                let view = PlaneView {
                    texels_per_pixel: d,
                    tilt_deg: tilt,
                    azimuth_deg: az,
                };
                rows.push(measure_view(&fip, tex, &view, sweep));
            }
        }
    }
    Ok(SweepReport {
        rows,
        fip_bytes: fip.bytes(4),
        mip_bytes: fip.mip().bytes(4),
        rip_bytes: fip.rip().bytes(4),
        build_seconds,
    })
}

/// A periodic grey test texture `n × n` (one channel, values in `[0, 1]`): a checkerboard of
/// 8 × 8 squares, a diagonal sinusoid (24 and 16 cycles per tile), and hashed value noise.
pub fn test_texture(n: usize, seed: u64) -> Texture {
    let mut rng = SplitMix64::new(seed);
    let noise: Vec<f64> = (0..n * n).map(|_| rng.next_f64() - 0.5).collect();
    let data = (0..n * n)
        .map(|k| {
            let (i, j) = (k % n, k / n);
            let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            let checker = if ((u * 8.0).floor() as i64 + (v * 8.0).floor() as i64) % 2 == 0 {
                0.25
            } else {
                -0.25
            };
            let wave = 0.15 * (std::f64::consts::TAU * (24.0 * u + 16.0 * v)).sin();
            (0.5 + checker + wave + 0.2 * noise[k]).clamp(0.0, 1.0) as f32
        })
        .collect();
    Texture {
        width: n,
        height: n,
        channels: 1,
        data,
    }
}
