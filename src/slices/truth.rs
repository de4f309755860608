//! Ray-marched ground truth of a texel volume: the emission–absorption integral through the
//! continuous medium of the module conventions (trilinear, or box with [`SliceReconstruction::Nearest`]), by the midpoint rule with
//! `steps_per_voxel` samples per voxel edge of path, over the same pixels and sub-samples as
//! [`super::render_slices`].

use altrep_data_gen::RgbaImage;

use super::render::{Camera, SliceRenderParams, StackView, accumulate};
use super::volume::{SliceReconstruction, alpha_for_thickness};
use super::{SliceError, TexelVolume};

/// Parameters of [`render_truth`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VolumeTruthParams {
    /// March samples per voxel edge of path length.
    pub steps_per_voxel: usize,
    /// Reconstruction of the medium between voxel centres.
    pub filter: SliceReconstruction,
}

impl Default for VolumeTruthParams {
    /// 8 samples per voxel edge (the midpoint rule's error is then far below the slices'),
    /// trilinear medium.
    fn default() -> Self {
        Self {
            steps_per_voxel: 8,
            filter: SliceReconstruction::Linear,
        }
    }
}

/// Renders the ground truth of `volume` seen from `view`. Cost: per sub-sample
/// `steps_per_voxel · path/s` trilinear samples (8 voxel reads each), rows in parallel.
///
/// Errors: invalid view or parameters, zero or more than 4096 steps.
pub fn render_truth(
    volume: &TexelVolume,
    view: &StackView,
    params: &SliceRenderParams,
    truth: &VolumeTruthParams,
) -> Result<RgbaImage, SliceError> {
    view.validate()?;
    params.validate()?;
    if truth.steps_per_voxel == 0 {
        return Err(SliceError::ZeroSize {
            what: "march steps per voxel",
        });
    }
    if truth.steps_per_voxel > 4096 {
        return Err(SliceError::InvalidParameter {
            name: "march steps per voxel",
            value: format!("{}", truth.steps_per_voxel),
            reason: "at most 4096",
        });
    }
    let s = volume.voxel_size();
    let cam = Camera::new(volume.extent(), s, view, params);
    Ok(cam.image(|ray| {
        let mut acc = [0.0f64; 4];
        let len = ray.t1 - ray.t0;
        let n = ((len / s) * truth.steps_per_voxel as f64).ceil().max(1.0) as usize;
        let dt = len / n as f64;
        let ratio = dt / s;
        for k in 0..n {
            let p = ray.o + (ray.t0 + (k as f64 + 0.5) * dt) * ray.dir;
            let v = match truth.filter {
                SliceReconstruction::Linear => volume.sample(p),
                SliceReconstruction::Nearest => volume.sample_nearest(p),
            };
            let a = v[3];
            if a <= 0.0 {
                continue;
            }
            let a2 = alpha_for_thickness(a, ratio);
            let f = a2 / a;
            if accumulate(&mut acc, [v[0] * f, v[1] * f, v[2] * f, a2]) {
                break;
            }
        }
        acc
    }))
}
