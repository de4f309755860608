//! Coverage check: can a cylindrical texture hold this object at all?
//!
//! A capture ray is horizontal and radial (it travels from the bounding cylinder toward the axis),
//! so it sees a slice only where the slice is star-shaped around the axis. A flat cut-out whose
//! plane holds the axis is met by every such ray at the axis only: the texture is "defined"
//! almost everywhere (radius 0), yet every reconstruction is a vertical line. Nothing in the
//! texture itself shows the failure; the ground truth does.
//!
//! **The check** ([`radial_visibility`], [`check_coverage`]) answers for the object, not for a
//! texture: of the surface the ground-truth views see (at `angles` camera angles
//! `α_n = (n + 0.37)·2π/angles`, never a capture column), which share do the radial capture
//! rays hold, at its place and not grazing? That is the coverage of the ideal, infinitely fine
//! texture, so the answer is the same at every texture size and prefilter, in the planner and
//! in `altrep cylinder`. Below [`CoverageParams::min_share`] the texture cannot represent the
//! object ([`CylinderError::NotRepresentable`]); an object that no view sees (empty truth at
//! every angle, e.g. a horizontal square seen edge-on) is [`CylinderError::NothingVisible`],
//! never a perfect score. How well a texture of a given size then draws the object is the
//! measurement's business (its PSNR against the truth, gated by the needs' `quality_db`).
//!
//! **A figure** ([`coverage`]) measures what one captured texture reproduces: the
//! **reproduced share** of the true silhouette,
//!
//! ```text
//! share = Σ_pixels min(a_texture, a_truth) / Σ_pixels a_truth
//! ```
//!
//! with `a` the pixel alpha (sub-sample coverage) of the truth ([`render_silhouette`]) and of
//! the texture's exact reconstruction (direct warping) at the same angles, summed over all
//! angles. It falls as the texture coarsens (thin parts fall between texels) and counts a
//! surface drawn in the wrong place as reproduced, so it is reported, not used to refuse.
//!
//! Measured on 33 objects (the procedural shapes, six scanned meshes, 18 textured glTF assets;
//! the table is in docs/design.md §6.6): the 7 below one half are flat cards, their
//! arrangements and a cluster of trees, each with a worst view at or below 16.7 dB.
//!
//! Cost: the check traces `angles` views of `size² · k²` rays and one capture ray per hit; the
//! figure `angles` silhouettes
//! (`size²·k²` occlusion rays each) and `angles` direct warps.

use std::f64::consts::TAU;

use altrep_data_gen::{
    BoundingCylinder, Light, PixelGrid, Ray, RgbaImage, Shape, Supersample, TruthParams,
    ViewParams, capture_view, direction, render_silhouette, screen_right,
};
use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::CylinderError;
use super::render::{CylinderRenderParams, ExactMethod, render_exact};
use super::texture::CylindricalTexture;
use super::warp::{DrawOrder, RadiusModel};

/// Parameters of the coverage check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CoverageParams {
    /// Camera angles measured (≥ 1). Default 8.
    pub angles: usize,
    /// Image size in pixels, square (≥ 1). Default 48.
    pub size: usize,
    /// Rays per pixel edge ([`Supersample`]: `k × k` per pixel). Default 2.
    pub supersample: Supersample,
    /// Smallest share of the visible surface the capture rays must hold
    /// ([`radial_visibility`]), in `[0, 1]`. Default 0.5: the procedural shapes hold 0.60
    /// (chair, its legs in line with the axis) to 1.00, the scanned meshes 0.68–0.95, a flat
    /// cut-out holding the axis below 0.1 (see docs/design.md §6.6).
    pub min_share: f64,
}

impl Default for CoverageParams {
    fn default() -> Self {
        Self {
            angles: 8,
            size: 48,
            supersample: Supersample::of(2),
            min_share: 0.5,
        }
    }
}

impl CoverageParams {
    /// Errors on a zero count or size, or a threshold outside `[0, 1]`.
    pub fn validate(&self) -> Result<(), CylinderError> {
        for (n, what) in [
            (self.angles, "coverage angles"),
            (self.size, "coverage image size"),
            (self.supersample.get(), "coverage supersampling"),
        ] {
            if n == 0 {
                return Err(CylinderError::ZeroSize { what });
            }
        }
        if !(0.0..=1.0).contains(&self.min_share) {
            return Err(CylinderError::InvalidParameter {
                name: "coverage min_share",
                value: self.min_share.to_string(),
                reason: "must be in [0, 1]",
            });
        }
        Ok(())
    }

    /// The camera angles of the check (radians).
    pub fn angle(&self, n: usize) -> f64 {
        (n as f64 + 0.37) * TAU / self.angles as f64
    }
}

/// The silhouette at one camera angle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AngleCoverage {
    /// Camera angle (radians).
    pub angle: f64,
    /// True silhouette area (sum of the truth's alpha, in pixels).
    pub truth_px: f64,
    /// Part of it the texture reproduces (sum of `min(a_texture, a_truth)`, pixels).
    pub reproduced_px: f64,
    /// `reproduced_px / truth_px` (0 when the truth is empty at this angle).
    pub share: f64,
}

/// What [`coverage`] measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CoverageReport {
    /// Reproduced share of the true silhouette over all angles, in `[0, 1]`.
    pub share: f64,
    /// One entry per angle.
    pub per_angle: Vec<AngleCoverage>,
}

impl CoverageReport {
    /// Measures the reproduced share from pairs of (texture reconstruction, truth) images.
    /// Errors: sizes differ; [`CylinderError::NothingVisible`] when every truth is empty.
    pub fn from_images(
        pairs: &[(f64, &RgbaImage, &RgbaImage)],
    ) -> Result<CoverageReport, CylinderError> {
        for &(_, image, reference) in pairs {
            if (image.width, image.height) != (reference.width, reference.height) {
                return Err(crate::metrics::MetricsError::SizeMismatch {
                    a: (image.width, image.height),
                    b: (reference.width, reference.height),
                }
                .into());
            }
        }
        let alphas: Vec<(f64, Vec<f32>, Vec<f32>)> = pairs
            .iter()
            .map(|&(angle, image, reference)| {
                let alpha = |i: &RgbaImage| i.pixels.iter().map(|p| p[3]).collect();
                (angle, alpha(image), alpha(reference))
            })
            .collect();
        let pairs: Vec<_> = alphas
            .iter()
            .map(|(g, a, b)| (*g, &a[..], &b[..]))
            .collect();
        Self::from_alphas(&pairs)
    }

    /// [`CoverageReport::from_images`] from the alpha channels alone: per angle, the
    /// reconstruction's alpha and the truth's, one per pixel in the same order. Errors: the two
    /// differ in length ([`crate::metrics::MetricsError::SizeMismatch`], lengths as widths of
    /// one-row images); [`CylinderError::NothingVisible`] when every truth is empty.
    pub fn from_alphas(pairs: &[(f64, &[f32], &[f32])]) -> Result<CoverageReport, CylinderError> {
        let mut per_angle = Vec::with_capacity(pairs.len());
        let (mut truth, mut reproduced) = (0.0, 0.0);
        for &(angle, image, reference) in pairs {
            if image.len() != reference.len() {
                return Err(crate::metrics::MetricsError::SizeMismatch {
                    a: (image.len(), 1),
                    b: (reference.len(), 1),
                }
                .into());
            }
            let (mut t, mut r) = (0.0f64, 0.0f64);
            for (p, q) in image.iter().zip(reference) {
                let (a, b) = (f64::from(*p), f64::from(*q));
                if a.is_finite() && b.is_finite() {
                    t += b.max(0.0);
                    r += a.min(b).max(0.0);
                }
            }
            truth += t;
            reproduced += r;
            per_angle.push(AngleCoverage {
                angle,
                truth_px: t,
                reproduced_px: r,
                share: if t > 0.0 { r / t } else { 0.0 },
            });
        }
        if truth <= 0.0 {
            return Err(CylinderError::NothingVisible {
                angles: pairs.len(),
            });
        }
        Ok(CoverageReport {
            share: reproduced / truth,
            per_angle,
        })
    }

    /// `Ok` when the share reaches `min_share`, else [`CylinderError::NotRepresentable`].
    pub fn check(&self, min_share: f64) -> Result<(), CylinderError> {
        if self.share >= min_share {
            Ok(())
        } else {
            Err(CylinderError::NotRepresentable {
                share: self.share,
                min_share,
            })
        }
    }
}

/// Measures the share of `shape`'s true silhouette that `texture` reproduces (a figure, see the
/// module docs). Errors: invalid parameters, ray-casting errors,
/// [`CylinderError::NothingVisible`] when no angle sees the object. A low share is not an error
/// here; the check that refuses an object is [`check_coverage`].
pub fn coverage(
    shape: &dyn Shape,
    texture: &CylindricalTexture,
    params: &CoverageParams,
) -> Result<CoverageReport, CylinderError> {
    params.validate()?;
    let light = Light::default();
    let mut images = Vec::with_capacity(params.angles);
    for n in 0..params.angles {
        let angle = params.angle(n);
        let truth = render_silhouette(
            shape,
            &TruthParams {
                angle,
                width: params.size,
                height: params.size,
                supersample: params.supersample,
                light,
                cylinder: texture.cylinder(),
            },
        )?;
        let method = ExactMethod::Direct(DrawOrder::FrontToBack, RadiusModel::General);
        let render = render_exact(
            texture,
            method,
            &CylinderRenderParams {
                angle,
                width: params.size,
                height: params.size,
                supersample: params.supersample,
                light,
            },
        )?;
        let alpha: Vec<f32> = render.image.pixels.iter().map(|p| p[3]).collect();
        images.push((angle, alpha, truth));
    }
    let pairs: Vec<_> = images
        .iter()
        .map(|(a, i, t)| (*a, &i[..], &t[..]))
        .collect();
    CoverageReport::from_alphas(&pairs)
}

/// Smallest `|cos|` between a capture ray and the surface it holds (the geometric normal, not
/// a shading or normal-mapped one): a capture ray meeting the surface within ~11.5° of grazing
/// (a face nearly holding the axis) samples it too thinly to count.
pub const MIN_CAPTURE_COSINE: f64 = 0.2;

/// The share of the object's **visible surface that radial capture rays hold**, for a texture
/// of any size: the coverage of the ideal (infinitely fine) cylindrical texture.
///
/// At each check angle `α_n` (see [`CoverageParams::angle`]) every sub-sample ray of the view
/// (`size² · k²` rays, as the ground truth casts them) that meets the object at `p` asks whether
/// the capture ray through `p` — horizontal, radial, from the bounding cylinder toward the axis
/// at `p`'s angle and height — meets the object first within one check pixel (`2R/size`) of
/// `p`. If it does, a texture of any resolution holds `p` and its exact reconstruction draws
/// it at its place; if an outer surface stops the capture ray first, the texture holds that
/// surface instead and the view shows it in the wrong place (a cavity, an opening, the far side
/// of a thin part behind a near one). A point within one check pixel of the axis is held.
///
/// `share = held sub-samples / sub-samples meeting the object`, over all angles; in the report
/// `truth_px` counts the sub-samples meeting the object and `reproduced_px` those held, both in
/// pixels (divided by `k²`). Unlike [`coverage`] it does not depend on a captured texture's
/// size or prefilter: the planner and `altrep cylinder` check the object with it and agree.
///
/// Errors: invalid parameters or cylinder, [`CylinderError::NothingVisible`] when no angle
/// sees the object. Cost: `angles · size² · k²` view rays, traced together
/// ([`capture_view`]), and as many single capture rays ([`Shape::intersect`]), in parallel.
pub fn radial_visibility(
    shape: &dyn Shape,
    cylinder: BoundingCylinder,
    params: &CoverageParams,
) -> Result<CoverageReport, CylinderError> {
    use rayon::prelude::*;
    params.validate()?;
    cylinder.validate()?;
    let (k, size) = (params.supersample.get(), params.size);
    let radius = cylinder.radius;
    // One check pixel: the tolerance on where a capture ray meets the surface.
    let tol = 2.0 * radius / size as f64;
    // Whether the capture ray through `p` holds it: its first hit is `p`, not grazing.
    let holds = |p: DVec3| {
        let r_p = p.x.hypot(p.z);
        if r_p <= tol {
            return true;
        }
        let outward = DVec3::new(p.x / r_p, 0.0, p.z / r_p);
        let capture = Ray::new(DVec3::new(0.0, p.y, 0.0) + 2.0 * radius * outward, -outward);
        // The capture ray passes through `p` at `t = 2R − r_p`: a first hit before it is an
        // outer surface hiding `p`; none near it, a ray grazing the surface (a face holding the
        // axis), which the texture does not hold either.
        shape
            .intersect(&capture, 0.0, 4.0 * radius)
            .is_some_and(|f| {
                (f.t - (2.0 * radius - r_p)).abs() <= tol
                    && f.geometric.dot(outward).abs() >= MIN_CAPTURE_COSINE
            })
    };
    // The `k × k` sub-sample rays of a `size²` view are the pixel-centre rays of a view `k`
    // times finer: the truth's rays, captured together.
    let fine = PixelGrid {
        width: size * k,
        height: size * k,
        cylinder,
    };
    let mut per_angle = Vec::with_capacity(params.angles);
    let (mut seen, mut held) = (0u64, 0u64);
    for n in 0..params.angles {
        let angle = params.angle(n);
        let view = capture_view(
            shape,
            &ViewParams {
                angle,
                width: fine.width,
                height: fine.height,
                cylinder,
            },
        )?;
        let (d, right) = (direction(angle), screen_right(angle));
        let (s, h) = view
            .samples
            .par_iter()
            .enumerate()
            .filter_map(|(m, sample)| {
                let sample = sample.as_ref()?;
                let (x, y) = fine.center(m % fine.width, m / fine.width);
                // The hit point: the sample's depth is its distance toward the camera over R.
                let p = x * right + DVec3::Y * y + f64::from(sample.depth) * radius * d;
                Some((1u64, u64::from(holds(p))))
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        seen += s;
        held += h;
        let kk = (k * k) as f64;
        per_angle.push(AngleCoverage {
            angle,
            truth_px: s as f64 / kk,
            reproduced_px: h as f64 / kk,
            share: if s > 0 { h as f64 / s as f64 } else { 0.0 },
        });
    }
    if seen == 0 {
        return Err(CylinderError::NothingVisible {
            angles: params.angles,
        });
    }
    Ok(CoverageReport {
        share: held as f64 / seen as f64,
        per_angle,
    })
}

/// The coverage check: [`radial_visibility`], then refuses a share below `params.min_share`
/// with [`CylinderError::NotRepresentable`] (which says to use images with parallax instead).
pub fn check_coverage(
    shape: &dyn Shape,
    cylinder: BoundingCylinder,
    params: &CoverageParams,
) -> Result<CoverageReport, CylinderError> {
    let c = radial_visibility(shape, cylinder, params)?;
    c.check(params.min_share)?;
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, alpha: &[f32]) -> RgbaImage {
        RgbaImage {
            width: w,
            height: alpha.len() / w,
            pixels: alpha
                .iter()
                .map(|&a| [0.3 * a, 0.2 * a, 0.1 * a, a])
                .collect(),
        }
    }

    #[test]
    fn images_and_their_alpha_channels_measure_the_same_share() {
        let (texture, truth) = ([1.0, 0.5, 0.0, 0.25], [1.0, 1.0, 0.75, 0.0]);
        let (a, b) = (image(2, &texture), image(2, &truth));
        let from_images = CoverageReport::from_images(&[(0.1, &a, &b)]).unwrap();
        let from_alphas = CoverageReport::from_alphas(&[(0.1, &texture[..], &truth[..])]).unwrap();
        assert_eq!(from_images, from_alphas);
        // min(1, 1) + min(0.5, 1) + min(0, 0.75) + min(0.25, 0) over 1 + 1 + 0.75.
        approx::assert_relative_eq!(from_alphas.share, 1.5 / 2.75, max_relative = 1e-15);
        let c = image(4, &truth);
        assert!(matches!(
            CoverageReport::from_images(&[(0.1, &a, &c)]),
            Err(CylinderError::Metrics(
                crate::metrics::MetricsError::SizeMismatch { .. }
            ))
        ));
        assert!(matches!(
            CoverageReport::from_alphas(&[(0.1, &texture[..], &truth[..3])]),
            Err(CylinderError::Metrics(
                crate::metrics::MetricsError::SizeMismatch { .. }
            ))
        ));
        assert!(matches!(
            CoverageReport::from_alphas(&[(0.1, &texture[..], &[0.0; 4][..])]),
            Err(CylinderError::NothingVisible { angles: 1 })
        ));
    }
}
