//! The exact inverse warp of the enclosing frames and their combination by carving free space
//! (module docs).

use altrep_data_gen::Supersample;
use altrep_data_gen::{Light, OrthoFrame, RgbaImage};
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;

use super::frames::Frame;
use super::{SphereError, SphereImages, check};

/// Largest number of carving rounds per fragment (module docs); a fragment still unresolved
/// after them takes the last candidate and is counted in [`RenderOutput::unresolved`].
pub const MAX_CARVE_ROUNDS: usize = 8;

/// How far past a carving candidate (display depth, frame units) the other frames are asked
/// whether it is hidden, and the colour is looked up: a candidate where the ray enters a hidden
/// cell through its side lies on a texel edge, where the cell a lookup lands in would otherwise
/// be decided by rounding.
const PROBE: f64 = 1e-9;

/// The default [`SphereRenderParams::hole_depth`]: half the bounding sphere's radius. Measured over
/// the ten subjects of the README's budget table (every budget of every subject gains, 0.01–2.7
/// dB, against colouring every hole), it costs the worst single direction of some subjects
/// (truck, 4 × 4 frames of 64²: 21.72 → 19.96 dB at 20° of elevation, where a real surface no
/// frame sees lies deep below the frames' surfaces).
pub const DEFAULT_HOLE_DEPTH: f64 = 0.5;

fn default_hole_depth() -> Option<f64> {
    Some(DEFAULT_HOLE_DEPTH)
}

/// The default [`SphereRenderParams::extra_frames`]: the most the GPU twin holds. On the beetle (a
/// see-through shell, the subject with the most rays no enclosing frame sees) the budget
/// table's gains over the engine blend at 0.5–32 MiB were +0.86 to −0.24 dB without extra
/// frames, +0.56 to +1.67 with 3 and +1.35 to +2.29 with 8; the cost falls on those rays only
/// (mean fetches per ray +1 to +1.5; over the ten subjects the longest ray takes up to 881
/// fetches, against 293 without extra frames).
pub const DEFAULT_EXTRA_FRAMES: usize = MAX_EXTRA_FRAMES;

fn default_extra_frames() -> usize {
    DEFAULT_EXTRA_FRAMES
}

/// Largest [`SphereRenderParams::extra_frames`] (the GPU twin holds this many frame slots beside the
/// three enclosing frames).
pub const MAX_EXTRA_FRAMES: usize = 8;

/// Weight of an extra frame's colour beside the enclosing frames' barycentric weights: they
/// colour a point only where no enclosing frame sees it, or nearly so.
const EXTRA_WEIGHT: f64 = 1e-3;

/// An extra frame must face the display direction at least this much (`d·d_k`).
const EXTRA_MIN_FACING: f64 = 0.1;

/// How [`render`] draws a ray where no frame asked sees the surface point the carving found (a
/// hole: through the opening of a see-through shell, or deep in a concavity no frame looks
/// into).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum HoleFill {
    /// As the engine blend draws it, from the enclosing frames' one-step offsets, each frame's
    /// depth read where the march stopped (as a ray stopped by
    /// [`SphereRenderParams::max_steps`] is drawn): 16 texel reads per enclosing frame. On the
    /// beetle, a see-through shell, it gains 0.6–1.7 dB over [`HoleFill::Nearest`], which
    /// takes every hole near a frame surface as covered; in the budget tables it lifts the
    /// beetle above the engine blend at every budget. A hole in a closed object is always
    /// covered, which the offsets' alpha test may miss: the teapot loses up to 1.0 dB (4 × 4
    /// frames of 256²), the chair seen from every side up to 0.4 dB, while spot and the bunny
    /// gain up to 0.35 dB (bench/RESULTS.md, "Holes drawn from the offsets").
    #[default]
    Offsets,
    /// From the frame surface nearest above the point, where it lies within
    /// [`SphereRenderParams::hole_depth`]; farther, the ray is taken as empty.
    Nearest,
}

/// Parameters of [`render`] (and of the engine baseline, which uses `size`, `samples` and
/// `light`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SphereRenderParams {
    /// Output width and height in pixels; the image covers the bounding sphere's square.
    pub size: usize,
    /// Rays per pixel edge ([`Supersample`]: `k × k` stratified per pixel; alpha is their
    /// coverage).
    pub supersample: Supersample,
    /// A frame sees a surface point when its own surface lies within this many texel pitches
    /// above it.
    pub visibility: f64,
    /// Use the cone bounds (`false`: march the whole chord of the bounding sphere).
    pub use_bounds: bool,
    /// How a ray is drawn where no frame asked (the enclosing and the extra frames) sees the
    /// surface point found (a hole). Default [`HoleFill::Offsets`].
    #[serde(default)]
    pub holes: HoleFill,
    /// With [`HoleFill::Nearest`], a hole is coloured from the frame surface nearest to it only
    /// when that surface lies within this distance (frame units, the bounding sphere's radius
    /// is 1); farther, the ray is taken as empty: space seen through an opening that none of
    /// the frames looks into (a see-through shell) rather than a surface. `None`: every hole is
    /// coloured. Unused with [`HoleFill::Offsets`]. Default [`DEFAULT_HOLE_DEPTH`].
    #[serde(default = "default_hole_depth")]
    pub hole_depth: Option<f64>,
    /// Where no enclosing frame sees the surface point found, up to this many more frames, the
    /// nearest to the display direction first, are asked in turn: one that sees the point
    /// colours it, one that sees through it resumes the carving with its own line (marched
    /// along the whole chord: its bounds hold only for its own cone of directions). Default
    /// [`DEFAULT_EXTRA_FRAMES`]; 0 asks only the enclosing frames.
    #[serde(default = "default_extra_frames")]
    pub extra_frames: usize,
    /// The light (the one shading function of the project).
    pub light: Light,
    /// A cap on each ray's march fetches ([`RenderOutput::steps`]), `None` for none. A ray that
    /// reaches it stops marching: a frame's march takes the point it reached as its event, the
    /// round under way finishes its checks (so a ray's fetches stay below the cap plus two per
    /// frame asked), and no further carving round starts. The ray is then drawn as the engine
    /// blend draws it, from the enclosing frames' one-step offsets, each frame's depth read
    /// where the march stopped: 16 more texel reads per enclosing frame, counted in
    /// [`RenderOutput::reads`]. What the cap costs in quality is measured by `altrep sphere
    /// --max-steps` (docs/design.md §7b, "A cap on fetches").
    #[serde(default)]
    pub max_steps: Option<u32>,
}

impl Default for SphereRenderParams {
    /// 128², one ray per pixel, visibility 2, bounds on, holes drawn from the offsets (hole
    /// depth 0.5 for [`HoleFill::Nearest`]), the default light, no cap on the fetches.
    fn default() -> Self {
        Self {
            size: 128,
            supersample: Supersample::ONE,
            visibility: 2.0,
            use_bounds: true,
            holes: HoleFill::Offsets,
            hole_depth: Some(DEFAULT_HOLE_DEPTH),
            extra_frames: DEFAULT_EXTRA_FRAMES,
            light: Light::default(),
            max_steps: None,
        }
    }
}

impl SphereRenderParams {
    /// Checks the parameters. Errors: a zero size or sample count, sizes above 8192 or 16
    /// samples, thresholds that are not finite and positive, more than [`MAX_EXTRA_FRAMES`]
    /// extra frames.
    pub fn validate(&self) -> Result<(), SphereError> {
        check(
            (1..=8192).contains(&self.size),
            "output size",
            self.size,
            "must be 1 to 8192 pixels",
        )?;
        check(
            (1..=16).contains(&self.supersample.get()),
            "samples per pixel side",
            self.supersample.get(),
            "must be 1 to 16",
        )?;
        check(
            self.visibility.is_finite() && self.visibility > 0.0,
            "visibility",
            self.visibility,
            "must be finite and positive",
        )?;
        check(
            self.extra_frames <= MAX_EXTRA_FRAMES,
            "extra frames",
            self.extra_frames,
            "must be at most MAX_EXTRA_FRAMES (8)",
        )?;
        if let Some(m) = self.max_steps {
            check(m >= 1, "max steps", m, "must be at least 1")?;
        }
        if let Some(d) = self.hole_depth {
            check(
                d.is_finite() && d > 0.0,
                "hole depth",
                d,
                "must be finite and positive",
            )?;
        }
        Ok(())
    }
}

/// An image drawn by [`render`] or the engine baseline, with its costs.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Premultiplied linear RGBA, alpha = coverage of the samples.
    pub image: RgbaImage,
    /// Texel fetches of every ray (fragment sample) inside the bounding sphere's disc, all
    /// frames together: the march's depth reads (what the GPU twin counts per fragment).
    pub steps: Vec<u32>,
    /// Every texel read of each of those rays: the march's, plus one bounds
    /// texel per frame where bounds are used and, per frame asked for the colour, one depth
    /// texel and the four bilinear texels of the colour and of the normal; the engine
    /// baseline's four texels per bilinear read.
    pub reads: Vec<u32>,
    /// Whether each of those rays found a surface (coloured the pixel).
    pub hit: Vec<bool>,
    /// Per pixel, row-major: the texel reads of all its rays (as [`Self::reads`]), 0 outside
    /// the disc: the per-fragment cost picture's data ([`Self::cost_picture`]).
    pub pixel_reads: Vec<u32>,
    /// Rays still unresolved after [`MAX_CARVE_ROUNDS`] rounds.
    pub unresolved: usize,
    /// Rays whose surface point no frame asked sees (coloured by the nearest frame surface
    /// within the hole depth, else empty).
    pub holes: usize,
    /// Rays stopped by the cap on fetches ([`SphereRenderParams::max_steps`]).
    pub capped: usize,
    /// Per pixel, row-major: the display depth `z` (frame units, toward the camera) of the
    /// surface found by the pixel's first ray, `None` where it found none (everywhere for the
    /// engine baseline, which finds no depth).
    pub depth: Vec<Option<f64>>,
}

impl RenderOutput {
    /// The per-fragment cost as a picture: each pixel's texel reads ([`Self::pixel_reads`])
    /// on a logarithmic ramp, `ln(1 + reads) / ln(1 + max)`, from black (0) through red and
    /// yellow to white (`max` reads or more), opaque everywhere; `max` 0 is taken as 1 (the
    /// reads of a few long rays would leave a linear ramp dark). Cost: one pass over the pixels.
    pub fn cost_picture(&self, max: u32) -> RgbaImage {
        let w = self.image.width;
        let mut out = RgbaImage::new(w, self.image.height);
        let top = f64::from(max.max(1)).ln_1p();
        for (p, &r) in out.pixels.iter_mut().zip(&self.pixel_reads) {
            let t = (f64::from(r).ln_1p() / top).min(1.0) as f32;
            // Black → red (t = 1/3) → yellow (2/3) → white (1).
            let ramp = |a: f32| (3.0 * t - a).clamp(0.0, 1.0);
            *p = [ramp(0.0), ramp(1.0), ramp(2.0), 1.0];
        }
        out
    }

    /// Mean texel fetches per ray (0 when no ray was cast).
    pub fn mean_steps(&self) -> f64 {
        self.steps.iter().map(|&s| f64::from(s)).sum::<f64>() / self.steps.len().max(1) as f64
    }
    /// Largest texel fetches of one ray.
    pub fn max_steps(&self) -> u32 {
        self.steps.iter().copied().max().unwrap_or(0)
    }
    /// Mean texel reads per ray, all of them counted ([`RenderOutput::reads`]; 0 when no ray
    /// was cast).
    pub fn mean_reads(&self) -> f64 {
        self.reads.iter().map(|&s| f64::from(s)).sum::<f64>() / self.reads.len().max(1) as f64
    }
    /// Mean texel reads over the rays that found a surface (0 when none did).
    pub fn mean_reads_over_hits(&self) -> f64 {
        let (sum, n) = self
            .reads
            .iter()
            .zip(&self.hit)
            .filter(|(_, h)| **h)
            .fold((0.0, 0usize), |(s, n), (r, _)| (s + f64::from(*r), n + 1));
        sum / n.max(1) as f64
    }
    /// Largest texel reads of one ray.
    pub fn max_reads(&self) -> u32 {
        self.reads.iter().copied().max().unwrap_or(0)
    }
}

/// How [`RenderOutput::reads`] counts, in words for reports: a march fetch reads one depth
/// texel, a bounds lookup one texel (both bounds in it), a colour lookup the depth texel of its
/// cell and the four texels of a bilinear read of the colour and of the normal (9); the engine
/// baseline reads four texels per bilinear read (depth per step, colour, normal, coverage).
pub(crate) const TEXEL_READS: &str = "march fetches + 1 bounds texel per frame + 9 texels per frame asked for colour (depth, 4 colour, 4 normal); baseline 4 per bilinear read";

/// The line a display ray makes in one frame (module docs): `Z_k(z) = a + c·z` and
/// `P_k(Z) = q + Z·t`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FrameLine {
    pub a: f64,
    pub c: f64,
    pub q: DVec2,
    pub t: DVec2,
}

/// Per display direction and frame: the linear maps from display coordinates to the frame's.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FrameMap {
    /// Rows: frame `X`, `Y`, `Z` as functions of display `(x, y, z)`.
    m: [DVec3; 3],
}

impl FrameMap {
    pub fn new(display: &OrthoFrame, frame: &OrthoFrame) -> Self {
        let row = |axis: DVec3| {
            DVec3::new(
                display.right.dot(axis),
                display.up.dot(axis),
                display.dir.dot(axis),
            )
        };
        Self {
            m: [row(frame.right), row(frame.up), row(frame.dir)],
        }
    }

    /// `d·d_k` (positive when the frame faces the display direction's hemisphere).
    pub fn facing(&self) -> f64 {
        self.m[2].z
    }

    /// The line of display ray `(x, y)` in the frame.
    #[inline]
    pub fn line(&self, x: f64, y: f64) -> FrameLine {
        let [mx, my, mz] = self.m;
        let c = mz.z;
        let a = mz.x * x + mz.y * y;
        let z0 = -a / c;
        FrameLine {
            a,
            c,
            q: DVec2::new(
                mx.x * x + mx.y * y + mx.z * z0,
                my.x * x + my.y * y + my.z * z0,
            ),
            t: DVec2::new(mx.z / c, my.z / c),
        }
    }
}

/// Marches `P(Z) = q + Z·t` through `frame` from `Z = z_hi` down to `z_lo`, one texel fetch per
/// cell (added to `steps`), and returns the frame depth `Z` of the first point that is not free
/// (module docs); once `steps` reaches `cap`, the depth of the point reached
/// ([`SphereRenderParams::max_steps`]).
pub(crate) fn first_event(
    frame: &Frame,
    q: DVec2,
    t: DVec2,
    z_hi: f64,
    z_lo: f64,
    steps: &mut u32,
    cap: u32,
) -> Option<f64> {
    if z_hi < z_lo {
        return None;
    }
    let pitch = frame.pitch();
    let f = frame.size as f64;
    // Texel coordinates u(λ) = u0 + du·λ, v(λ) = v0 + dv·λ, λ = z_hi − Z ∈ [0, len].
    let start = frame.texel_coords(q + z_hi * t);
    let (du, dv) = (-t.x / pitch, t.y / pitch);
    let len = z_hi - z_lo;
    // Clip to the frame square [0, F]²: outside it everything is free.
    let (mut l0, mut l1) = (0.0f64, len);
    for (p0, d) in [(start.x, du), (start.y, dv)] {
        if d.abs() < 1e-300 {
            if !(0.0..=f).contains(&p0) {
                return None;
            }
        } else {
            let (a, b) = ((0.0 - p0) / d, (f - p0) / d);
            l0 = l0.max(a.min(b));
            l1 = l1.min(a.max(b));
        }
    }
    if l0 > l1 {
        return None;
    }
    let at = |l: f64| DVec2::new(start.x + du * l, start.y + dv * l);
    let p_in = at(l0);
    let fs = frame.size as i64;
    let mut i = (p_in.x.floor() as i64).clamp(0, fs - 1);
    let mut j = (p_in.y.floor() as i64).clamp(0, fs - 1);
    let (si, sj) = (if du > 0.0 { 1 } else { -1 }, if dv > 0.0 { 1 } else { -1 });
    let next = |cell: i64, p: f64, d: f64, s: i64| -> f64 {
        if d.abs() < 1e-300 {
            f64::INFINITY
        } else {
            let edge = if s > 0 { cell + 1 } else { cell } as f64;
            l0 + ((edge - p) / d).max(0.0)
        }
    };
    let mut tmax_x = next(i, p_in.x, du, si);
    let mut tmax_y = next(j, p_in.y, dv, sj);
    let (dx, dy) = (
        if du.abs() < 1e-300 {
            f64::INFINITY
        } else {
            1.0 / du.abs()
        },
        if dv.abs() < 1e-300 {
            f64::INFINITY
        } else {
            1.0 / dv.abs()
        },
    );
    let to_frame = |l: f64| {
        let p = at(l);
        DVec2::new(p.x * pitch - 1.0, 1.0 - p.y * pitch)
    };
    let mut l_in = l0;
    loop {
        if *steps >= cap {
            // The ray's fetches are spent: the point reached stands for the event.
            return Some(z_hi - l_in);
        }
        let l_out = tmax_x.min(tmax_y).min(l1);
        *steps += 1;
        if let Some(k) = frame.cell(i, j) {
            let (p_a, p_b) = (to_frame(l_in), to_frame(l_out));
            let f_in = frame.height(k, p_a) - (z_hi - l_in);
            let f_out = frame.height(k, p_b) - (z_hi - l_out);
            if f_in >= 0.0 {
                return Some(z_hi - l_in);
            }
            if f_out >= 0.0 {
                return Some(z_hi - (l_in + (l_out - l_in) * (-f_in) / (f_out - f_in)));
            }
        }
        if l_out >= l1 {
            return None;
        }
        if tmax_x <= tmax_y {
            i += si;
            tmax_x += dx;
        } else {
            j += sj;
            tmax_y += dy;
        }
        if i < 0 || j < 0 || i >= fs || j >= fs {
            return None;
        }
        l_in = l_out;
    }
}

/// Whether frame point `(P, Z)` is hidden from the frame (not free).
#[inline]
pub(crate) fn hidden(frame: &Frame, p: DVec2, z: f64) -> bool {
    frame.height_at(p).is_some_and(|h| h >= z - 1e-9)
}

/// A frame that draws a display direction, as [`render`] uses it (what a shader needs per
/// draw besides the stored frames).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnclosingFrame {
    /// Index of the frame, in the order of [`super::ViewSet::direction`].
    pub frame: usize,
    /// Its barycentric weight, renormalised over the frames kept (they sum to 1).
    pub weight: f64,
    /// Frame `X`, `Y`, `Z` as linear functions of display `(x, y, z)`: row `r` is
    /// `(right·a_r, up·a_r, dir·a_r)` with `(right, up, dir)` the display frame's axes and `a`
    /// the stored frame's axes (`right_k`, `up_k`, `d_k`), all in the object frame.
    pub rows: [DVec3; 3],
}

/// The enclosing frames that draw direction `dir` (unit, toward the camera): the corners of its
/// grid triangle with a weight above `1e-12` that face its hemisphere (`d·d_k > 1e-9`), with
/// their weights renormalised, as [`render`] uses them. Cost: `O(1)`.
///
/// Errors: a direction that is zero or not finite, or that the view set does not cover.
pub fn enclosing_frames(
    images: &SphereImages,
    dir: DVec3,
) -> Result<Vec<EnclosingFrame>, SphereError> {
    let display = display_frame(images, dir)?;
    Ok(enclosing_maps(images, &display)?
        .into_iter()
        .map(|(frame, weight, map)| EnclosingFrame {
            frame,
            weight,
            rows: map.m,
        })
        .collect())
}

/// The extra frames that [`render`] asks, in order, where no enclosing frame of direction
/// `dir` sees the point found ([`SphereRenderParams::extra_frames`]): up to `n` frames outside its
/// grid triangle that face it (`d·d_k ≥ 0.1`), the nearest to it first (the frame index breaks
/// ties), each with the small colour weight `render` gives them (1e-3: they colour a point
/// only where no enclosing frame sees it, or nearly so). Cost: `O(frames · log frames)`.
///
/// Errors: as [`enclosing_frames`].
pub fn extra_frames(
    images: &SphereImages,
    dir: DVec3,
    n: usize,
) -> Result<Vec<EnclosingFrame>, SphereError> {
    let display = display_frame(images, dir)?;
    let maps = enclosing_maps(images, &display)?;
    Ok(extra_maps(images, &display, &maps, n)
        .into_iter()
        .map(|(frame, map)| EnclosingFrame {
            frame,
            weight: EXTRA_WEIGHT,
            rows: map.m,
        })
        .collect())
}

/// The enclosing frames of `dir` with a positive weight: `(frame, weight, map)`.
pub(crate) fn enclosing_maps(
    images: &SphereImages,
    display: &OrthoFrame,
) -> Result<Vec<(usize, f64, FrameMap)>, SphereError> {
    let w = images.params.set.enclosing(display.dir)?;
    let total: f64 = w.iter().filter(|x| x.1 > 1e-12).map(|x| x.1).sum();
    Ok(w.iter()
        .filter(|x| x.1 > 1e-12)
        .map(|&(k, wt)| {
            (
                k,
                wt / total,
                FrameMap::new(display, &images.frames[k].frame),
            )
        })
        .filter(|(_, _, m)| m.facing() > 1e-9)
        .collect())
}

/// The display frame along `dir` over the images' bounding sphere.
pub(crate) fn display_frame(images: &SphereImages, dir: DVec3) -> Result<OrthoFrame, SphereError> {
    let f = &images.frames[0].frame;
    Ok(OrthoFrame::new(f.centre, f.radius, dir)?)
}

/// What one ray of a drawing found.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct RaySample {
    /// Shaded colour of the surface found, `None` for a miss.
    pub colour: Option<Vec3>,
    /// Display depth of that surface, when the method finds one.
    pub depth: Option<f64>,
    /// Texel fetches of the march.
    pub steps: u32,
    /// Texel reads besides the march's: bounds, colour and normal ([`RenderOutput::reads`]).
    pub other_reads: u32,
    /// No frame sees the surface point.
    pub hole: bool,
    /// Still unresolved after [`MAX_CARVE_ROUNDS`].
    pub unresolved: bool,
    /// Stopped by [`SphereRenderParams::max_steps`].
    pub capped: bool,
}

/// Draws a `size²` image over the unit disc of the display frame: `samples²` stratified rays
/// per pixel, each traced by `trace(x, y, x² + y²)` (rays outside the disc are not traced),
/// rows in parallel. Alpha is the share of rays that found a surface; the depth of a pixel is
/// that of its first ray.
pub(crate) fn draw(
    params: &SphereRenderParams,
    trace: impl Fn(f64, f64, f64) -> RaySample + Sync,
) -> RenderOutput {
    let (w, s) = (params.size, params.supersample.get());
    let inv = 1.0 / (s * s) as f32;
    // Per row: pixels, depths, texel reads per pixel, and every ray traced.
    type Row = (Vec<[f32; 4]>, Vec<Option<f64>>, Vec<u32>, Vec<RaySample>);
    let rows: Vec<Row> = (0..w)
        .into_par_iter()
        .map(|j| {
            let (mut row, mut depth, mut reads, mut rays) = (
                vec![[0.0f32; 4]; w],
                vec![None; w],
                vec![0u32; w],
                Vec::new(),
            );
            for i in 0..w {
                let mut acc = [0.0f32; 4];
                for a in 0..s {
                    for b in 0..s {
                        let (x, y) = OrthoFrame::screen_at(
                            i as f64 + (a as f64 + 0.5) / s as f64,
                            j as f64 + (b as f64 + 0.5) / s as f64,
                            w,
                            w,
                        );
                        let r2 = x * x + y * y;
                        if r2 >= 1.0 {
                            continue;
                        }
                        let ray = trace(x, y, r2);
                        reads[i] += ray.steps + ray.other_reads;
                        if let Some(c) = ray.colour {
                            acc = [acc[0] + c.x, acc[1] + c.y, acc[2] + c.z, acc[3] + 1.0];
                            if a == 0 && b == 0 {
                                depth[i] = ray.depth;
                            }
                        }
                        rays.push(ray);
                    }
                }
                row[i] = acc.map(|v| v * inv);
            }
            (row, depth, reads, rays)
        })
        .collect();
    let mut out = RenderOutput {
        image: RgbaImage::new(w, w),
        steps: Vec::new(),
        reads: Vec::new(),
        hit: Vec::new(),
        pixel_reads: Vec::with_capacity(w * w),
        unresolved: 0,
        holes: 0,
        capped: 0,
        depth: Vec::with_capacity(w * w),
    };
    for (j, (row, depth, reads, rays)) in rows.into_iter().enumerate() {
        out.image.pixels[j * w..(j + 1) * w].copy_from_slice(&row);
        out.depth.extend(depth);
        out.pixel_reads.extend(reads);
        for r in rays {
            out.steps.push(r.steps);
            out.reads.push(r.steps + r.other_reads);
            out.hit.push(r.colour.is_some());
            out.unresolved += usize::from(r.unresolved);
            out.holes += usize::from(r.hole);
            out.capped += usize::from(r.capped);
        }
    }
    out
}

/// Draws the object along display direction `dir` (unit, toward the camera) by the exact warp
/// of its enclosing frames (module docs). Cost: per ray, per enclosing frame, the cells between
/// its bounds plus one fetch per carving check; pixels in parallel.
///
/// Errors: invalid parameters, or a direction the view set does not cover.
pub fn render(
    images: &SphereImages,
    dir: DVec3,
    params: &SphereRenderParams,
) -> Result<RenderOutput, SphereError> {
    params.validate()?;
    let display = display_frame(images, dir)?;
    let maps = enclosing_maps(images, &display)?;
    let extras = extra_maps(images, &display, &maps, params.extra_frames);
    Ok(draw(params, |x, y, r2| {
        trace(images, &maps, &extras, x, y, r2, params)
    }))
}

/// Up to `n` frames that do not enclose `display.dir` but face it (`d·d_k ≥
/// EXTRA_MIN_FACING`), the nearest to it first: `(frame, map)`.
pub(crate) fn extra_maps(
    images: &SphereImages,
    display: &OrthoFrame,
    enclosing: &[(usize, f64, FrameMap)],
    n: usize,
) -> Vec<(usize, FrameMap)> {
    if n == 0 {
        return Vec::new();
    }
    let mut all: Vec<(usize, FrameMap)> = (0..images.frames.len())
        .filter(|k| enclosing.iter().all(|e| e.0 != *k))
        .map(|k| (k, FrameMap::new(display, &images.frames[k].frame)))
        .filter(|(_, m)| m.facing() >= EXTRA_MIN_FACING)
        .collect();
    // Nearest first; the frame index breaks ties so the order is a function of the set only.
    all.sort_by(|a, b| b.1.facing().total_cmp(&a.1.facing()).then(a.0.cmp(&b.0)));
    all.truncate(n);
    all
}

/// One display ray through `(x, y)` (inside the unit disc): carve, then colour; where no frame
/// asked sees the point found, ask the next extra frame and carve again.
fn trace(
    images: &SphereImages,
    maps: &[(usize, f64, FrameMap)],
    extras: &[(usize, FrameMap)],
    x: f64,
    y: f64,
    r2: f64,
    params: &SphereRenderParams,
) -> RaySample {
    let mut ray = RaySample::default();
    let zs = (1.0 - r2).sqrt();
    // Per frame: the frame, the line, its march interval `[lo, hi]` in frame depth (the
    // sphere's chord, cut by the bounds) and its colour weight.
    let mut lines = Vec::with_capacity(3 + extras.len());
    for &(k, weight, ref map) in maps {
        let line = map.line(x, y);
        let (mut lo, mut hi) = (line.a - line.c * zs, line.a + line.c * zs);
        if params.use_bounds {
            let interval = images.bounds[k].interval(&images.frames[k], line.q);
            ray.other_reads += u32::from(interval.is_some());
            match interval {
                Some(Some((zmin, zmax))) => {
                    lo = lo.max(zmin);
                    hi = hi.min(zmax);
                }
                // No event is possible for any direction of the cone: the ray is free here.
                Some(None) => return ray,
                None => {}
            }
        }
        lines.push((&images.frames[k], line, lo, hi, weight));
    }
    let at = |line: &FrameLine, z: f64| {
        let zf = line.a + line.c * z;
        (line.q + zf * line.t, zf)
    };
    let mut z_cur = zs;
    let mut z_c = zs;
    let mut extra = extras.iter();
    let cap = params.max_steps.unwrap_or(u32::MAX);
    loop {
        ray.unresolved = true;
        for _ in 0..MAX_CARVE_ROUNDS {
            if ray.steps >= cap {
                // Spent: drawn from the enclosing frames' one-step offsets instead.
                ray.capped = true;
                ray.unresolved = false;
                return offset_sample(&lines[..maps.len()], z_cur, params, ray);
            }
            // The deepest of the frames' next events below `z_cur` (display depth), and the
            // frame whose event it is (the first such frame on ties).
            let mut deepest = f64::INFINITY;
            let mut owner = 0;
            for (s, &(frame, ref line, lo, hi, _)) in lines.iter().enumerate() {
                let (p, zf) = at(line, z_cur);
                // Hidden where the march resumes (or where the ray enters the sphere): the
                // event is here. Transitions start below `zmax` only, so this is checked
                // before the bounds.
                ray.steps += 1;
                let z = if hidden(frame, p, zf) {
                    z_cur
                } else {
                    match first_event(frame, line.q, line.t, zf.min(hi), lo, &mut ray.steps, cap) {
                        Some(z) => (z - line.a) / line.c,
                        // Free from here on, and no event below `lo`: the whole rest of the
                        // ray is free.
                        None => {
                            return RaySample {
                                unresolved: false,
                                ..ray
                            };
                        }
                    }
                };
                if z < deepest {
                    (deepest, owner) = (z, s);
                }
            }
            z_c = deepest;
            // The candidate is hidden from its owner by construction (it is the owner's first
            // point that is not free; asking again would decide a point on a cell edge by
            // rounding and stall the carving); every other frame is asked, one fetch each.
            if lines
                .iter()
                .enumerate()
                .all(|(s, &(frame, ref line, _, _, _))| {
                    if s == owner {
                        return true;
                    }
                    ray.steps += 1;
                    let (p, zf) = at(line, z_c - PROBE);
                    hidden(frame, p, zf)
                })
            {
                ray.unresolved = false;
                break;
            }
            z_cur = z_c;
        }
        // Colour: the frames that see the point, by weight; else the nearest surface above it.
        let (mut col, mut wsum) = (Vec3::ZERO, 0.0f64);
        let mut nearest: Option<(f64, Vec3)> = None;
        for &(frame, ref line, _, _, weight) in &lines {
            // The cell's depth texel, and the bilinear colour and normal (4 texels each).
            ray.other_reads += 9;
            let (p, zf) = at(line, z_c - PROBE);
            let (Some(h), Some((albedo, normal))) = (frame.height_at(p), frame.attributes_at(p))
            else {
                continue;
            };
            let c = params.light.shade(albedo, normal);
            let gap = h - zf;
            if gap <= params.visibility * frame.pitch() {
                col += c * weight as f32;
                wsum += weight;
            }
            if nearest.is_none_or(|(g, _)| gap.abs() < g) {
                nearest = Some((gap.abs(), c));
            }
        }
        if wsum > 0.0 {
            ray.colour = Some(col / wsum as f32);
            break;
        }
        // No frame asked sees the point: ask the next extra frame, carving again from the
        // candidate (if the new frame sees through it, the march goes on below it); a ray past
        // its cap asks none. With none left, the ray is a hole ([`HoleFill`]).
        if let Some(&(k, ref map)) = extra.next().filter(|_| ray.steps < cap) {
            let line = map.line(x, y);
            let (lo, hi) = (line.a - line.c * zs, line.a + line.c * zs);
            lines.push((&images.frames[k], line, lo, hi, EXTRA_WEIGHT));
            z_cur = z_c;
            continue;
        }
        if params.holes == HoleFill::Offsets {
            ray.hole = nearest.is_some();
            return offset_sample(&lines[..maps.len()], z_c, params, ray);
        }
        if let Some((gap, c)) = nearest {
            ray.hole = true;
            if params.hole_depth.is_some_and(|d| gap > d) {
                ray.unresolved = false;
                return ray;
            }
            ray.colour = Some(c);
            break;
        }
        ray.unresolved = false;
        return ray;
    }
    ray.depth = Some(z_c);
    ray
}

/// How far below ½ the blended coverage of [`offset_sample`] still counts as covered: a
/// direction on an edge of the view set's grid gives two frames weight ½ each, and where one of
/// them alone covers the ray the coverage is ½ up to rounding, which `f32` and `f64`, and the
/// order of the sums, would decide apart.
const ALPHA_TIE: f64 = 1e-6;

/// A ray whose march cannot finish — stopped by the cap on fetches
/// ([`SphereRenderParams::max_steps`]), or a hole with [`HoleFill::Offsets`] — drawn as the
/// engine blend draws it (src/sphere/baseline.rs) from `lines`, the enclosing frames' `(frame,
/// line, lo, hi, weight)`, but with its offset read where the march stopped: the ray is free in
/// front of display depth `z_free` (the last carving candidate), so in each frame the depth `D`
/// is read at the ray's point at `z_free` rather than where it crosses the frame plane
/// (bilinear over the defined texels, renormalised; a frame with none of the four defined there
/// adds nothing). Coverage `α`, colour and normal are read bilinearly at the offset `q + D·t`.
/// The frames are blended by weight and coverage and alpha-tested at ½; the depth is the same
/// blend of the offsets' display depths. The depth is not padded as the blend's is: the march's
/// frames store none. 16 texel reads per enclosing frame (depth 4, coverage with colour 8,
/// normal 4: the blend's count), added to `ray.other_reads`.
///
/// Measured on the truck (4 × 4 frames of 64², caps of 64, 32 and 16 fetches, holes still
/// coloured from the nearest surface): reading the depth at the frame plane as the blend does
/// lost 1.83, 5.91 and 9.12 dB against no cap; read at `z_free`, 0.56, 3.30 and 6.49 dB; a
/// second depth read (two steps) gained nothing. With holes drawn from the offsets too, 0.32,
/// 2.82 and 6.26 dB.
fn offset_sample(
    lines: &[(&Frame, FrameLine, f64, f64, f64)],
    z_free: f64,
    params: &SphereRenderParams,
    mut ray: RaySample,
) -> RaySample {
    let (mut alpha, mut col, mut z) = (0.0f64, Vec3::ZERO, 0.0f64);
    for &(frame, ref line, _, _, weight) in lines {
        ray.other_reads += 16;
        let (d, w) = frame.bilinear(line.q + (line.a + line.c * z_free) * line.t, |k| {
            frame.depth[k]
        });
        if w <= 0.0 {
            continue;
        }
        let depth = d / w;
        let p = line.q + depth * line.t;
        let (cov, _) = frame.bilinear(p, |_| 1.0);
        if cov <= 0.0 {
            continue;
        }
        if let Some((albedo, normal)) = frame.attributes_at(p) {
            let a = weight * cov;
            alpha += a;
            col += params.light.shade(albedo, normal) * a as f32;
            z += a * (depth - line.a) / line.c;
        }
    }
    if alpha >= 0.5 - ALPHA_TIE {
        ray.colour = Some(col / alpha as f32);
        ray.depth = Some(z / alpha);
    }
    ray
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::{SphereImages, SphereParams, azimuth_elevation, render_engine_baseline};
    use altrep_data_gen::scene_shape;

    /// Each pixel's reads are the reads of its rays: they sum to the rays' reads, are 0
    /// outside the disc, and the cost picture runs from black (no read) to white (the most).
    #[test]
    fn the_cost_picture_holds_every_read_of_its_pixels() {
        let shape = scene_shape("chair").unwrap();
        let img = SphereImages::capture(&shape, &SphereParams::hemisphere(3, 24).unwrap()).unwrap();
        let dir = azimuth_elevation(0.7, 0.4);
        for supersample in [1, 2] {
            let params = SphereRenderParams {
                size: 20,
                supersample: altrep_data_gen::Supersample::of(supersample),
                ..SphereRenderParams::default()
            };
            for out in [
                render(&img, dir, &params).unwrap(),
                render_engine_baseline(&img, dir, &params).unwrap(),
            ] {
                assert_eq!(out.pixel_reads.len(), 20 * 20);
                let total: u64 = out.pixel_reads.iter().map(|&r| u64::from(r)).sum();
                assert_eq!(total, out.reads.iter().map(|&r| u64::from(r)).sum::<u64>());
                // The corner pixel lies outside the disc: no ray, no read, black.
                assert_eq!(out.pixel_reads[0], 0);
                let max = *out.pixel_reads.iter().max().unwrap();
                assert!(max > 0);
                let pic = out.cost_picture(max);
                assert_eq!(pic.pixels[0], [0.0, 0.0, 0.0, 1.0]);
                let k = out.pixel_reads.iter().position(|&r| r == max).unwrap();
                assert_eq!(pic.pixels[k], [1.0, 1.0, 1.0, 1.0]);
            }
        }
    }

    /// A cap of one fetch stops every ray that no frame frees in its first round; each such
    /// ray is drawn from the one-step offsets and reads 16 texels per enclosing frame besides
    /// its fetches (no bounds and no extra frames here, so nothing else).
    #[test]
    fn a_capped_ray_reads_its_offsets_and_nothing_else() {
        let shape = scene_shape("chair").unwrap();
        let img = SphereImages::capture(&shape, &SphereParams::hemisphere(3, 24).unwrap()).unwrap();
        let dir = azimuth_elevation(0.7, 0.4);
        let display = display_frame(&img, dir).unwrap();
        let frames = enclosing_maps(&img, &display).unwrap().len() as u32;
        assert_eq!(frames, 3);
        let params = SphereRenderParams {
            size: 24,
            use_bounds: false,
            extra_frames: 0,
            max_steps: Some(1),
            ..SphereRenderParams::default()
        };
        let out = render(&img, dir, &params).unwrap();
        let capped: Vec<usize> = (0..out.steps.len())
            .filter(|&r| out.reads[r] > out.steps[r])
            .collect();
        assert_eq!(capped.len(), out.capped);
        assert!(out.capped > 0);
        for &r in &capped {
            assert_eq!(out.reads[r] - out.steps[r], 16 * frames, "ray {r}");
        }
        // Some capped rays are drawn, some are not (their blended coverage is below ½).
        let drawn = capped.iter().filter(|&&r| out.hit[r]).count();
        assert!(
            drawn > 0 && drawn < capped.len(),
            "{drawn} of {}",
            capped.len()
        );
    }
}
