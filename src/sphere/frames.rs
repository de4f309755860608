//! The stored frames: capture, quantisation and the surface model of each texel.

use std::time::{Duration, Instant};

use altrep_data_gen::{OrthoFrame, Shape, capture_frame, linear_to_srgb, srgb_to_linear};
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;

use super::bounds::ConeBounds;
use super::{SphereError, ViewSet, check};
use crate::parallax::normal_code;

/// The surface a texel stands for (module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum SurfaceModel {
    /// A flat top at the stored depth over the texel's cell (columns).
    Flat,
    /// The plane through the stored depth with the stored normal's slope, each slope component
    /// clamped to `±max_slope`.
    Tangent {
        /// Largest slope `|∂Z/∂X|`, `|∂Z/∂Y|` kept.
        max_slope: f64,
    },
}

impl SurfaceModel {
    /// The default: tangent planes with slopes up to 4 (as the parallax views' brims).
    pub const DEFAULT: Self = Self::Tangent { max_slope: 4.0 };
}

/// Parameters of [`SphereImages`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SphereParams {
    /// The frame directions.
    pub set: ViewSet,
    /// Texels per frame side `F`.
    pub size: usize,
    /// The surface each texel stands for.
    pub model: SurfaceModel,
    /// Frame texels per side of one cone-bounds texel: 1 (the default, a bound per texel), 2
    /// or 4. Coarser bounds store `2/block²` bytes per frame texel instead of 2 and draw the
    /// same picture; the march reads more texels between their looser intervals
    /// ([`ConeBounds::coarsened`]).
    #[serde(default = "one")]
    pub bounds_block: usize,
}

fn one() -> usize {
    1
}

impl SphereParams {
    /// Stored bytes per texel of a frame: sRGB8 albedo (3), normal 3 × 8 bits (3), depth 16
    /// bits (2, code 0 = undefined).
    pub const FRAME_TEXEL_BYTES: usize = 8;
    /// Bytes per texel of the cone bounds: `zmin`, `zmax` in 8 bits each.
    pub const BOUND_TEXEL_BYTES: usize = 2;

    /// Checks the parameters. Errors: `size` outside `2..=4096`, a slope limit that is not
    /// finite and positive, a bounds block other than 1, 2 or 4.
    pub fn validate(&self) -> Result<(), SphereError> {
        check(
            (2..=4096).contains(&self.size),
            "frame size",
            self.size,
            "must be 2 to 4096 texels",
        )?;
        check(
            matches!(self.bounds_block, 1 | 2 | 4),
            "bounds block",
            self.bounds_block,
            "must be 1, 2 or 4 frame texels per side",
        )?;
        ViewSet::new(self.set.coverage, self.set.grid)?;
        if let SurfaceModel::Tangent { max_slope } = self.model {
            check(
                max_slope.is_finite() && max_slope > 0.0,
                "max slope",
                max_slope,
                "must be finite and positive",
            )?;
        }
        Ok(())
    }

    /// Bytes of the frames alone (what the engine baseline stores).
    pub fn frame_bytes(&self) -> usize {
        self.set.len() * self.size * self.size * Self::FRAME_TEXEL_BYTES
    }

    /// Cone-bounds texels per frame side, `⌈size / bounds_block⌉`.
    pub fn bounds_side(&self) -> usize {
        self.size.div_ceil(self.bounds_block.max(1))
    }

    /// Bytes of the cone bounds alone: [`Self::BOUND_TEXEL_BYTES`] per bounds texel.
    pub fn bounds_bytes(&self) -> usize {
        self.set.len() * self.bounds_side().pow(2) * Self::BOUND_TEXEL_BYTES
    }

    /// Bytes of the frames and their cone bounds (what the exact warp stores).
    pub fn total_bytes(&self) -> usize {
        self.frame_bytes() + self.bounds_bytes()
    }
}

/// One stored frame, decoded from its quantised codes (row-major, row 0 at the top).
#[derive(Clone, Debug)]
pub struct Frame {
    /// The orthographic frame it was captured along.
    pub frame: OrthoFrame,
    /// Texels per side `F`.
    pub size: usize,
    pub(crate) defined: Vec<bool>,
    /// Stored depth `Z` at the texel centre (frame units, toward the camera).
    pub(crate) depth: Vec<f64>,
    /// Plane slope `(∂Z/∂X, ∂Z/∂Y)` (zero for the flat model).
    pub(crate) slope: Vec<DVec2>,
    /// Linear albedo decoded from sRGB8.
    pub(crate) albedo: Vec<Vec3>,
    /// Object-frame normal decoded from 8-bit codes and renormalised.
    pub(crate) normal: Vec<Vec3>,
}

pub(crate) fn depth_code(z: f64) -> u16 {
    (1.0 + (z.clamp(-1.0, 1.0) + 1.0) * 0.5 * 65534.0).round() as u16
}

pub(crate) fn depth_value(code: u16) -> f64 {
    f64::from(code - 1) / 65534.0 * 2.0 - 1.0
}

impl Frame {
    /// An `f × f` frame along `+z` with no texel defined (for unit tests).
    #[cfg(test)]
    pub(crate) fn empty_for_tests(f: usize) -> Self {
        Self {
            frame: OrthoFrame::new(glam::DVec3::ZERO, 1.0, glam::DVec3::Z)
                .expect("a unit frame along +z"),
            size: f,
            defined: vec![false; f * f],
            depth: vec![0.0; f * f],
            slope: vec![DVec2::ZERO; f * f],
            albedo: vec![Vec3::ZERO; f * f],
            normal: vec![Vec3::Z; f * f],
        }
    }

    /// Texel pitch `2/F` in frame units.
    #[inline]
    pub fn pitch(&self) -> f64 {
        2.0 / self.size as f64
    }

    /// Index of texel `(i, j)` if it is inside the frame and defined.
    #[inline]
    pub(crate) fn cell(&self, i: i64, j: i64) -> Option<usize> {
        let f = self.size as i64;
        if i < 0 || j < 0 || i >= f || j >= f {
            return None;
        }
        let k = (j * f + i) as usize;
        self.defined[k].then_some(k)
    }

    /// Frame position `(X, Y)` of the centre of texel `(i, j)`.
    #[inline]
    pub(crate) fn centre(&self, i: i64, j: i64) -> DVec2 {
        let p = self.pitch();
        DVec2::new(-1.0 + (i as f64 + 0.5) * p, 1.0 - (j as f64 + 0.5) * p)
    }

    /// Texel coordinates `(u, v)` of frame position `P` (`u = i + ½` at a centre).
    #[inline]
    pub(crate) fn texel_coords(&self, p: DVec2) -> DVec2 {
        DVec2::new((p.x + 1.0) / self.pitch(), (1.0 - p.y) / self.pitch())
    }

    /// The plane of texel `k = (i, j)` at frame position `P`.
    #[inline]
    pub(crate) fn height(&self, k: usize, p: DVec2) -> f64 {
        let (i, j) = ((k % self.size) as i64, (k / self.size) as i64);
        self.depth[k] + self.slope[k].dot(p - self.centre(i, j))
    }

    /// The plane of the texel containing `P`, if it is defined.
    #[inline]
    pub(crate) fn height_at(&self, p: DVec2) -> Option<f64> {
        let t = self.texel_coords(p);
        let k = self.cell(t.x.floor() as i64, t.y.floor() as i64)?;
        Some(self.height(k, p))
    }

    /// `(Σ w·value(k), Σ w)` over the defined texels `k` among the four nearest centres to `P`,
    /// `w` their bilinear weights: the second is the bilinear coverage at `P`, the ratio the
    /// value renormalised over the defined texels. Four texel reads.
    pub(crate) fn bilinear(&self, p: DVec2, value: impl Fn(usize) -> f64) -> (f64, f64) {
        let t = self.texel_coords(p) - 0.5;
        let (i0, j0) = (t.x.floor() as i64, t.y.floor() as i64);
        let (fx, fy) = (t.x - i0 as f64, t.y - j0 as f64);
        let (mut v, mut a) = (0.0, 0.0);
        for (di, dj, w) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            if let Some(k) = self.cell(i0 + di, j0 + dj) {
                v += w * value(k);
                a += w;
            }
        }
        (v, a)
    }

    /// Albedo and normal at `P`, bilinear over the defined texels among the four nearest
    /// centres (renormalised weights); `None` if none of them is defined.
    pub(crate) fn attributes_at(&self, p: DVec2) -> Option<(Vec3, Vec3)> {
        let t = self.texel_coords(p) - 0.5;
        let (i0, j0) = (t.x.floor() as i64, t.y.floor() as i64);
        let (fx, fy) = ((t.x - i0 as f64) as f32, (t.y - j0 as f64) as f32);
        let (mut a, mut n, mut w) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
        for (di, dj, wt) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            if let Some(k) = self.cell(i0 + di, j0 + dj)
                && wt > 0.0
            {
                a += self.albedo[k] * wt;
                n += self.normal[k] * wt;
                w += wt;
            }
        }
        if w <= 0.0 {
            // The nearest texel itself (the hit may sit in a texel whose neighbours are all
            // undefined and whose own bilinear weight is zero at the very border).
            let t = self.texel_coords(p);
            let k = self.cell(t.x.floor() as i64, t.y.floor() as i64)?;
            return Some((self.albedo[k], self.normal[k]));
        }
        Some((a / w, (n / w).normalize_or_zero()))
    }

    /// The stored (decoded) depth `Z`, linear albedo and unit normal of texel `(i, j)`,
    /// `None` if it is undefined or outside the frame.
    pub fn texel(&self, i: usize, j: usize) -> Option<(f64, Vec3, Vec3)> {
        let k = self.cell(i as i64, j as i64)?;
        Some((self.depth[k], self.albedo[k], self.normal[k]))
    }

    /// The plane of texel `(i, j)`: its stored (decoded) depth `Z` at the texel centre and its
    /// slope `(∂Z/∂X, ∂Z/∂Y)` in frame units (zero for [`SurfaceModel::Flat`]); `None` if it is
    /// undefined or outside the frame.
    pub fn plane(&self, i: usize, j: usize) -> Option<(f64, DVec2)> {
        let k = self.cell(i as i64, j as i64)?;
        Some((self.depth[k], self.slope[k]))
    }

    /// Share of defined texels.
    pub fn coverage(&self) -> f64 {
        self.defined.iter().filter(|d| **d).count() as f64 / self.defined.len().max(1) as f64
    }
}

/// An object stored as frames over the sphere or hemisphere, with their cone bounds: the
/// representation the exact warp draws (and the engine baseline, from the frames alone).
#[derive(Clone, Debug)]
pub struct SphereImages {
    /// The parameters it was built with.
    pub params: SphereParams,
    /// The frames, in the order of [`ViewSet::direction`].
    pub frames: Vec<Frame>,
    /// Their stored codes (what the files hold), same order.
    pub codes: Vec<FrameCodes>,
    /// Per frame, the half-angle of its cone (radians).
    pub cones: Vec<f64>,
    /// Per frame, its bounds for its cone.
    pub bounds: Vec<ConeBounds>,
    /// Wall time of the capture and quantisation.
    pub capture_time: Duration,
    /// Wall time of the bounds.
    pub bounds_time: Duration,
}

impl SphereImages {
    /// Captures the frames of `shape` over its bounding sphere (`G²·F²` rays), quantises them
    /// and builds their cone bounds. Errors: invalid parameters, capture errors, or
    /// [`SphereError::NothingVisible`] when every frame is empty.
    pub fn capture(shape: &dyn Shape, params: &SphereParams) -> Result<Self, SphereError> {
        params.validate()?;
        let t0 = Instant::now();
        let (centre, radius) = OrthoFrame::bounding_sphere(shape);
        let f = params.size;
        let captured = params
            .set
            .directions()
            .into_par_iter()
            .map(|d| -> Result<(Frame, FrameCodes), SphereError> {
                let frame = OrthoFrame::new(centre, radius, d)?;
                let cap = capture_frame(shape, &frame, f, f)?;
                let codes = FrameCodes::quantise(f, &cap.samples);
                Ok((Frame::decode(&frame, &codes, params.model)?, codes))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let (frames, codes): (Vec<Frame>, Vec<FrameCodes>) = captured.into_iter().unzip();
        if frames.iter().all(|fr| fr.coverage() == 0.0) {
            return Err(SphereError::NothingVisible {
                frames: frames.len(),
            });
        }
        let capture_time = t0.elapsed();
        let t1 = Instant::now();
        let cones = Self::cones(&params.set);
        let bounds = ConeBounds::build_all(&frames, &cones, params.bounds_block);
        Ok(Self {
            params: *params,
            frames,
            codes,
            cones,
            bounds,
            capture_time,
            bounds_time: t1.elapsed(),
        })
    }

    /// Rebuilds the representation from stored parts (what a loader reads): the parameters,
    /// the bounding sphere `(centre, radius)` the frames were captured over, one [`FrameCodes`]
    /// and one [`ConeBounds`] per frame in the order of [`ViewSet::direction`]. Decoding is the
    /// same as after a capture, so a loaded set draws bit for bit as the one written. Errors:
    /// invalid parameters, a frame count or size that does not match them, a radius that is not
    /// positive, [`SphereError::NothingVisible`].
    pub fn from_parts(
        params: &SphereParams,
        centre: DVec3,
        radius: f64,
        codes: Vec<FrameCodes>,
        bounds: Vec<ConeBounds>,
    ) -> Result<Self, SphereError> {
        params.validate()?;
        let n = params.set.len();
        check(
            codes.len() == n && bounds.len() == n,
            "stored frames",
            format!("{} frames and {} bounds", codes.len(), bounds.len()),
            "there must be one frame and one bounds per direction of the grid",
        )?;
        let f = params.size;
        let side = params.bounds_side();
        for (c, b) in codes.iter().zip(&bounds) {
            check(
                c.size == f
                    && b.size == f
                    && b.block == params.bounds_block
                    && b.zmin.len() == side * side
                    && b.zmax.len() == side * side,
                "stored frame size",
                format!("{} (bounds {}, block {})", c.size, b.size, b.block),
                "every frame and bounds must have the parameters' size and bounds block",
            )?;
        }
        let frames = params
            .set
            .directions()
            .into_par_iter()
            .zip(codes.par_iter())
            .map(|(d, c)| -> Result<Frame, SphereError> {
                let frame = OrthoFrame::new(centre, radius, d)?;
                Frame::decode(&frame, c, params.model)
            })
            .collect::<Result<Vec<_>, _>>()?;
        if frames.iter().all(|fr| fr.coverage() == 0.0) {
            return Err(SphereError::NothingVisible { frames: n });
        }
        Ok(Self {
            params: *params,
            frames,
            codes,
            cones: Self::cones(&params.set),
            bounds,
            capture_time: Duration::ZERO,
            bounds_time: Duration::ZERO,
        })
    }

    /// Per frame, the half-angle of its cone (radians).
    fn cones(set: &ViewSet) -> Vec<f64> {
        (0..set.len())
            .into_par_iter()
            .map(|k| set.cone_angle(k))
            .collect()
    }
}

/// The stored codes of one frame: what the files hold (row-major, row 0 at the top).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameCodes {
    /// Texels per side `F`.
    pub size: usize,
    /// sRGB8 albedo (zero where undefined).
    pub albedo: Vec<[u8; 3]>,
    /// Object-frame normal, `code = round((n + 1)/2 · 255)` per component (zero where
    /// undefined).
    pub normal: Vec<[u8; 3]>,
    /// Depth `Z` (frame units), `code = 1 + round((Z + 1)/2 · 65534)`; 0 = undefined.
    pub depth: Vec<u16>,
}

impl FrameCodes {
    /// Quantises one capture (`F × F` samples, row-major) to its codes.
    pub fn quantise(f: usize, samples: &[Option<altrep_data_gen::Sample>]) -> Self {
        let n = f * f;
        let mut c = Self {
            size: f,
            albedo: vec![[0; 3]; n],
            normal: vec![[0; 3]; n],
            depth: vec![0; n],
        };
        for (k, s) in samples.iter().enumerate().take(n) {
            let Some(s) = s else { continue };
            c.depth[k] = depth_code(f64::from(s.depth));
            let srgb = |v: f32| (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8;
            c.albedo[k] = [srgb(s.albedo.x), srgb(s.albedo.y), srgb(s.albedo.z)];
            c.normal[k] = [
                normal_code(s.normal.x),
                normal_code(s.normal.y),
                normal_code(s.normal.z),
            ];
        }
        c
    }
}

impl Frame {
    /// Decodes stored codes into the frame's surface (module docs of [`crate::sphere`]): depth,
    /// linear albedo, renormalised normal and, for tangent planes, the clamped slope from the
    /// normal. Errors: `codes` of another size than `codes.size²` texels.
    pub fn decode(
        frame: &OrthoFrame,
        codes: &FrameCodes,
        model: SurfaceModel,
    ) -> Result<Self, SphereError> {
        let f = codes.size;
        let n = f * f;
        check(
            f >= 1 && codes.albedo.len() == n && codes.normal.len() == n && codes.depth.len() == n,
            "frame codes",
            format!(
                "{} / {} / {} texels for size {f}",
                codes.albedo.len(),
                codes.normal.len(),
                codes.depth.len()
            ),
            "albedo, normal and depth must each hold size² texels",
        )?;
        let mut fr = Frame {
            frame: *frame,
            size: f,
            defined: vec![false; n],
            depth: vec![0.0; n],
            slope: vec![DVec2::ZERO; n],
            albedo: vec![Vec3::ZERO; n],
            normal: vec![Vec3::ZERO; n],
        };
        let lin = |c: u8| srgb_to_linear(f32::from(c) / 255.0);
        let dec = |c: u8| f32::from(c) / 255.0 * 2.0 - 1.0;
        for k in 0..n {
            if codes.depth[k] == 0 {
                continue;
            }
            fr.defined[k] = true;
            fr.depth[k] = depth_value(codes.depth[k]);
            let a = codes.albedo[k];
            fr.albedo[k] = Vec3::new(lin(a[0]), lin(a[1]), lin(a[2]));
            let c = codes.normal[k];
            let nrm = Vec3::new(dec(c[0]), dec(c[1]), dec(c[2])).normalize_or_zero();
            fr.normal[k] = nrm;
            fr.slope[k] = slope_of(frame, nrm, model);
        }
        Ok(fr)
    }

    /// The frame with its normals replaced by `normals` (unit, object frame; one per texel, read
    /// where defined) and its slopes recomputed from them: the surface a store that keeps
    /// normals in another code than [`FrameCodes::normal`] decodes to (block-compressed
    /// octahedral normals, [`super::compress`]). Errors: a length other than `F²`.
    pub(crate) fn with_normals(
        mut self,
        normals: &[Vec3],
        model: SurfaceModel,
    ) -> Result<Self, SphereError> {
        check(
            normals.len() == self.size * self.size,
            "frame normals",
            normals.len(),
            "need one per texel",
        )?;
        for (k, &n) in normals.iter().enumerate() {
            if self.defined[k] {
                self.normal[k] = n;
                self.slope[k] = slope_of(&self.frame, n, model);
            }
        }
        Ok(self)
    }
}

/// The slope `(∂Z/∂X, ∂Z/∂Y)` of the plane with object-frame normal `nrm` in `frame`'s axes, each
/// component clamped to the model's limit; zero for [`SurfaceModel::Flat`].
fn slope_of(frame: &OrthoFrame, nrm: Vec3, model: SurfaceModel) -> DVec2 {
    let SurfaceModel::Tangent { max_slope } = model else {
        return DVec2::ZERO;
    };
    let nd = nrm.as_dvec3();
    let nf = DVec3::new(nd.dot(frame.right), nd.dot(frame.up), nd.dot(frame.dir));
    let nz = nf.z.max(1e-6);
    DVec2::new(
        (-nf.x / nz).clamp(-max_slope, max_slope),
        (-nf.y / nz).clamp(-max_slope, max_slope),
    )
}

/// For each texel of an `f × f` grid, the index of its nearest defined texel by breadth-first
/// distance over the 4-neighbour grid (ties go to the first reached, sources in index order):
/// what engine bakers pad (dilate) empty texels with. `None` when no texel is defined. Cost: `f²`.
pub(crate) fn nearest_defined(defined: &[bool], f: usize) -> Option<Vec<usize>> {
    let mut nearest = vec![usize::MAX; f * f];
    let mut queue = std::collections::VecDeque::new();
    for (k, n) in nearest.iter_mut().enumerate() {
        if defined[k] {
            *n = k;
            queue.push_back(k);
        }
    }
    if queue.is_empty() {
        return None;
    }
    while let Some(k) = queue.pop_front() {
        let (i, j) = (k % f, k / f);
        let neighbours = [
            (i > 0).then(|| k - 1),
            (i + 1 < f).then(|| k + 1),
            (j > 0).then(|| k - f),
            (j + 1 < f).then(|| k + f),
        ];
        for n in neighbours.into_iter().flatten() {
            if nearest[n] == usize::MAX {
                nearest[n] = nearest[k];
                queue.push_back(n);
            }
        }
    }
    Some(nearest)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_codes_round_trip_within_half_a_step() {
        for z in [-1.0, -0.3, 0.0, 0.123456, 1.0] {
            let back = depth_value(depth_code(z));
            assert!((back - z).abs() <= 1.0 / 65534.0 + 1e-15, "{z} -> {back}");
        }
        assert!(depth_code(-1.0) >= 1);
    }
}
