//! Orthographic frames along **any** direction (docs/design.md §7b): the capture and the ground
//! truth of views over the sphere.
//!
//! ## Conventions
//!
//! A frame looks along `−d` (the camera sits on the `+d` side, `d` a unit vector). Its screen
//! basis is `right = normalize(ŷ × d)`, `up = d × right`, so `right × up = d` (right-handed) and
//! for a horizontal `d = direction(α)` it is the basis of the cylinder views ([`screen_right`],
//! `up = +y`). When `d` is within 10⁻⁹ of `±ŷ` the hint `ŷ` is replaced by `−ẑ` (for `d = +ŷ`:
//! `right = +x`, `up = −z`, the view from above with `−z` at the top of the image).
//!
//! Positions are measured from the frame's `centre` in units of its `radius` (the radius of the
//! bounding sphere): a point `p` has `X = (p − c)·right / r`, `Y = (p − c)·up / r` and **depth**
//! `Z = (p − c)·d / r` (toward the camera), all in `[−1, 1]` inside the sphere. A `W × H` frame
//! covers the square `[−1, 1]²`: pixel `(i, j)` has its centre at `X = −1 + (i + ½)·2/W`,
//! `Y = 1 − (j + ½)·2/H` (row 0 at the top).
//!
//! [`screen_right`]: crate::screen_right

use crate::Supersample;
use glam::DVec3;

use crate::capture::Sample;
use crate::error::{DataGenError, finite, nonzero};
use crate::geometry::{ParallelRays, Ray, sub_sample};
use crate::image_io::RgbaImage;
use crate::shape::{Shape, trace_in_groups};
use crate::truth::{Light, shade_groups};

/// An orthographic frame along any direction, over a bounding sphere (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrthoFrame {
    /// Centre of the bounding sphere (world units).
    pub centre: DVec3,
    /// Radius of the bounding sphere (world units).
    pub radius: f64,
    /// Unit direction toward the camera.
    pub dir: DVec3,
    /// Unit screen right.
    pub right: DVec3,
    /// Unit screen up.
    pub up: DVec3,
}

impl OrthoFrame {
    /// The frame looking along `−dir` (normalised here) over the sphere `(centre, radius)`.
    ///
    /// Errors: non-finite input, a zero direction or a radius that is not positive.
    pub fn new(centre: DVec3, radius: f64, dir: DVec3) -> Result<Self, DataGenError> {
        for (k, v) in centre
            .to_array()
            .into_iter()
            .chain(dir.to_array())
            .enumerate()
        {
            finite(v, "frame centre or direction", k)?;
        }
        finite(radius, "frame radius", 0)?;
        if radius <= 0.0 {
            return Err(DataGenError::InvalidParameter {
                name: "frame radius",
                value: radius.to_string(),
                reason: "must be positive",
            });
        }
        let len = dir.length();
        if len < 1e-12 {
            return Err(DataGenError::InvalidParameter {
                name: "frame direction",
                value: format!("{dir:?}"),
                reason: "must not be zero",
            });
        }
        let d = dir / len;
        let hint = if 1.0 - d.y.abs() < 1e-9 {
            DVec3::NEG_Z
        } else {
            DVec3::Y
        };
        let right = hint.cross(d).normalize();
        let up = d.cross(right);
        Ok(Self {
            centre,
            radius,
            dir: d,
            right,
            up,
        })
    }

    /// The sphere around a shape's axis-aligned bounds: centre at the box's centre, radius its
    /// half diagonal (times `1 + 1e-6`, so grazing hits stay inside).
    pub fn bounding_sphere(shape: &dyn Shape) -> (DVec3, f64) {
        let (lo, hi) = shape.bounds();
        ((lo + hi) * 0.5, (hi - lo).length() * 0.5 * (1.0 + 1e-6))
    }

    /// The frame coordinates `(X, Y, Z)` of the world point `p` (module docs).
    #[inline]
    pub fn to_frame(&self, p: DVec3) -> DVec3 {
        let q = (p - self.centre) / self.radius;
        DVec3::new(q.dot(self.right), q.dot(self.up), q.dot(self.dir))
    }

    /// The world point of frame coordinates `(X, Y, Z)`.
    #[inline]
    pub fn to_world(&self, f: DVec3) -> DVec3 {
        self.centre + self.radius * (f.x * self.right + f.y * self.up + f.z * self.dir)
    }

    /// Frame coordinates `(X, Y)` of the centre of pixel `(i, j)` of a `w × h` grid, or of any
    /// fractional pixel position `(u, v)` (`u = i + ½` at a centre).
    #[inline]
    pub fn screen_at(u: f64, v: f64, w: usize, h: usize) -> (f64, f64) {
        (-1.0 + 2.0 * u / w as f64, 1.0 - 2.0 * v / h as f64)
    }

    /// The ray through screen position `(X, Y)`, starting outside the sphere on the camera's
    /// side and running along `−dir`; `t` in world units, the sphere spans `t ∈ [0, 4r]`.
    #[inline]
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        Ray::new(self.to_world(DVec3::new(x, y, 2.0)), -self.dir)
    }

    /// Screen positions of the `k × k` sub-sample rays of a `width × height` frame, as world
    /// coordinates along `right` (columns) and `up` (rows): the grid of
    /// [`OrthoFrame::parallel_rays`].
    pub(crate) fn grid(&self, width: usize, height: usize, k: usize) -> (Vec<f64>, Vec<f64>) {
        let (cr, cu) = (self.centre.dot(self.right), self.centre.dot(self.up));
        let columns = (0..width * k)
            .map(|c| {
                cr + self.radius
                    * Self::screen_at(sub_sample(c / k, c % k, k), 0.0, width, height).0
            })
            .collect();
        let rows = (0..height * k)
            .map(|r| {
                cu + self.radius
                    * Self::screen_at(0.0, sub_sample(r / k, r % k, k), width, height).1
            })
            .collect();
        (columns, rows)
    }

    /// Ray `(c, r)` of the grid of [`OrthoFrame::grid`]: through sub-sample `(c mod k, r mod
    /// k)` of pixel `(c / k, r / k)` of a `width × height` frame.
    pub(crate) fn grid_ray(
        &self,
        c: usize,
        r: usize,
        width: usize,
        height: usize,
        k: usize,
    ) -> Ray {
        let (x, y) = Self::screen_at(
            sub_sample(c / k, c % k, k),
            sub_sample(r / k, r % k, k),
            width,
            height,
        );
        self.ray(x, y)
    }

    /// The grid of parallel rays of this frame with positions `columns × rows` and rays `ray`.
    pub(crate) fn parallel_rays<'a>(
        &self,
        columns: &'a [f64],
        rows: &'a [f64],
        ray: &'a (dyn Fn(usize, usize) -> Ray + Sync),
    ) -> ParallelRays<'a> {
        ParallelRays {
            dir: -self.dir,
            across: [self.right, self.up],
            columns,
            rows,
            t_min: 0.0,
            t_max: 4.0 * self.radius,
            ray,
        }
    }
}

/// One capture along an [`OrthoFrame`]: per pixel an optional [`Sample`] whose `depth` is the
/// frame depth `Z` (module docs), row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameCapture {
    /// The frame.
    pub frame: OrthoFrame,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height` samples; `None` where the ray missed.
    pub samples: Vec<Option<Sample>>,
}

/// Captures `shape` along `frame` at `width × height` (one ray per pixel centre, rows in
/// parallel). Errors: zero sizes.
pub fn capture_frame(
    shape: &dyn Shape,
    frame: &OrthoFrame,
    width: usize,
    height: usize,
) -> Result<FrameCapture, DataGenError> {
    nonzero(width, "frame width")?;
    nonzero(height, "frame height")?;
    let (columns, rows) = frame.grid(width, height, 1);
    let ray = |i: usize, j: usize| frame.grid_ray(i, j, width, height, 1);
    let rays = frame.parallel_rays(&columns, &rows, &ray);
    let mut samples = vec![None; width * height];
    trace_in_groups(
        shape,
        &rays,
        1,
        width,
        &mut samples,
        |first, hits, samples| {
            for (j, (samples, hits)) in samples
                .chunks_mut(width)
                .zip(hits.chunks(width))
                .enumerate()
            {
                for (i, (s, hit)) in samples.iter_mut().zip(hits).enumerate() {
                    *s = hit.map(|hit| Sample {
                        albedo: hit.albedo,
                        normal: hit.normal.as_vec3(),
                        depth: frame.to_frame(ray(i, first + j).at(hit.t)).z as f32,
                    });
                }
            }
        },
    );
    Ok(FrameCapture {
        frame: *frame,
        width,
        height,
        samples,
    })
}

/// The ground truth along `frame`: premultiplied linear RGBA, `k × k` stratified rays per pixel,
/// alpha = coverage, shaded by `light` (the one shading function of the project). Cost:
/// `width × height × k²` rays, rows in parallel. Errors: zero sizes or `k = 0`.
pub fn render_truth_frame(
    shape: &dyn Shape,
    frame: &OrthoFrame,
    width: usize,
    height: usize,
    supersample: Supersample,
    light: &Light,
) -> Result<RgbaImage, DataGenError> {
    nonzero(width, "truth width")?;
    nonzero(height, "truth height")?;
    let k = supersample.get();
    let (columns, rows) = frame.grid(width, height, k);
    let ray = |c: usize, r: usize| frame.grid_ray(c, r, width, height, k);
    let rays = frame.parallel_rays(&columns, &rows, &ray);
    let mut pixels = vec![[0.0f32; 4]; width * height];
    trace_in_groups(shape, &rays, k, width, &mut pixels, |_, hits, pixels| {
        shade_groups(hits, pixels, width, k, light);
    });
    Ok(RgbaImage {
        width,
        height,
        pixels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{direction, screen_right};
    use approx::assert_abs_diff_eq;

    #[test]
    fn horizontal_frames_match_the_cylinder_views_basis() {
        for alpha in [0.0, 0.7, 2.5, -1.2] {
            let f = OrthoFrame::new(DVec3::ZERO, 1.0, direction(alpha)).unwrap();
            assert_abs_diff_eq!(f.right.distance(screen_right(alpha)), 0.0, epsilon = 1e-12);
            assert_abs_diff_eq!(f.up.distance(DVec3::Y), 0.0, epsilon = 1e-12);
        }
    }

    #[test]
    fn frames_are_right_handed_and_orthonormal_everywhere() {
        for d in [
            DVec3::Y,
            DVec3::NEG_Y,
            DVec3::new(0.3, 0.9, -0.2),
            DVec3::new(1e-12, 1.0, 0.0),
        ] {
            let f = OrthoFrame::new(DVec3::new(0.1, 1.0, 0.0), 2.0, d).unwrap();
            assert_abs_diff_eq!(f.right.cross(f.up).distance(f.dir), 0.0, epsilon = 1e-12);
            assert_abs_diff_eq!(f.right.dot(f.up), 0.0, epsilon = 1e-12);
            let p = DVec3::new(0.4, -0.3, 0.8);
            assert_abs_diff_eq!(f.to_world(f.to_frame(p)).distance(p), 0.0, epsilon = 1e-12);
        }
        assert!(OrthoFrame::new(DVec3::ZERO, 1.0, DVec3::ZERO).is_err());
        assert!(OrthoFrame::new(DVec3::ZERO, 0.0, DVec3::Y).is_err());
        assert!(OrthoFrame::new(DVec3::ZERO, 1.0, DVec3::new(f64::NAN, 0.0, 1.0)).is_err());
    }
}
