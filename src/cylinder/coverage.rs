//! Coverage check: can a cylindrical texture hold this object at all?
//!
//! A capture ray is horizontal and radial (it travels from the bounding cylinder toward the axis),
//! so it sees a slice only where the slice is star-shaped around the axis. A flat cut-out whose
//! plane holds the axis is met by every such ray at the axis only: the texture is "defined"
//! almost everywhere (radius 0), yet every reconstruction is a vertical line. Nothing in the
//! texture itself shows the failure; the ground truth does.
//!
//! The check renders the object's true silhouette (ray-cast: the ground truth's alpha,
//! [`render_silhouette`]) at `angles` camera angles `α_n = (n + 0.37)·2π/angles` (never a
//! capture column) and the texture's exact reconstruction (direct warping, identical to inverse
//! warping) at the same angles, and measures the **reproduced share** of the silhouette:
//!
//! ```text
//! share = Σ_pixels min(a_texture, a_truth) / Σ_pixels a_truth
//! ```
//!
//! with `a` the pixel alpha (sub-sample coverage), summed over all angles. Below
//! [`CoverageParams::min_share`] the texture cannot represent the object and
//! [`check_coverage`] returns [`CylinderError::NotRepresentable`]; an object that no view sees
//! (empty truth at every angle, e.g. a horizontal square seen edge-on) is
//! [`CylinderError::NothingVisible`], never a perfect score. The pipeline calls [`coverage`]
//! and skips the representation with the same reason.
//!
//! Cost: `angles` silhouettes (`size²·k²` occlusion rays each) and `angles` direct warps.

use std::f64::consts::TAU;

use altrep_data_gen::{Light, RgbaImage, Shape, TruthParams, render_silhouette};
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
    /// Sub-samples per pixel side (≥ 1). Default 2.
    pub supersample: usize,
    /// Smallest reproduced share of the true silhouette accepted, in `[0, 1]`. Default 0.5:
    /// the evaluation shapes and meshes reproduce 0.75 (chair, its legs lost; beetle) to 0.99
    /// (pear) of their silhouette, a flat cut-out holding the axis 0.00 (see the README).
    pub min_share: f64,
}

impl Default for CoverageParams {
    fn default() -> Self {
        Self {
            angles: 8,
            size: 48,
            supersample: 2,
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
            (self.supersample, "coverage supersampling"),
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

/// Measures the share of `shape`'s true silhouette that `texture` reproduces (see the module
/// docs). Errors: invalid parameters, ray-casting errors, [`CylinderError::NothingVisible`]
/// when no angle sees the object. A low share is not an error here (see [`check_coverage`]).
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

/// [`coverage`], then refuses a share below `params.min_share` with
/// [`CylinderError::NotRepresentable`] (which says to use images with parallax instead).
pub fn check_coverage(
    shape: &dyn Shape,
    texture: &CylindricalTexture,
    params: &CoverageParams,
) -> Result<CoverageReport, CylinderError> {
    let c = coverage(shape, texture, params)?;
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
