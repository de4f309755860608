//! The one shape every representation has for the pipeline (docs/design.md §12): `Spec` (the
//! manifest's parameters, serde with documented defaults) → [`Representation::plan`] from the
//! scene's needs → [`Representation::build`] → `Data` + report → [`Representation::write`] /
//! [`Representation::read`] an asset folder → [`Representation::measure`] against the ray-cast
//! ground truth. The pipeline drives every representation through these verbs alone.

use std::time::Instant;

use altrep_data_gen::{Light, RgbaImage, Shape, TruthParams, render_truth};
use serde::{Deserialize, Serialize};

use super::manifest::{Lighting, Needs};
use super::{PipelineError, Plan};
use crate::asset::{AssetReader, AssetWriter};

/// What a representation is built from: the asset's geometry (a shape or mesh, ray-cast by
/// data-gen) or its texture, and the scene's light.
pub struct Source<'a> {
    /// Asset name.
    pub name: &'a str,
    /// The geometry, for assets given by `shape` or `mesh`.
    pub geometry: Option<&'a (dyn Shape + Sync)>,
    /// The texture, for assets given by `texture` (pyramids).
    pub texture: Option<&'a crate::pyramid::Texture>,
    /// The scene's light (baked lighting and every measured image).
    pub light: Light,
}

impl<'a> Source<'a> {
    /// The geometry. Errors: the asset is a texture ([`PipelineError::WrongSource`]).
    pub fn shape(&self) -> Result<&'a (dyn Shape + Sync), PipelineError> {
        self.geometry.ok_or_else(|| PipelineError::WrongSource {
            asset: self.name.into(),
            needed: "a shape or mesh",
        })
    }

    /// The texture. Errors: the asset is a shape or mesh ([`PipelineError::WrongSource`]).
    pub fn texture(&self) -> Result<&'a crate::pyramid::Texture, PipelineError> {
        self.texture.ok_or_else(|| PipelineError::WrongSource {
            asset: self.name.into(),
            needed: "a texture",
        })
    }
}

/// Error figures of a representation against the ray-cast ground truth.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// What was compared (renderer, sizes, angles).
    pub method: String,
    /// Mean PSNR (dB) over the angles.
    pub psnr_db: f64,
    /// Worst PSNR (dB) over the angles.
    pub worst_psnr_db: f64,
    /// Mean silhouette IoU.
    pub iou: f64,
    /// Mean shader steps per fragment, where the representation marches.
    pub mean_steps: Option<f64>,
}

/// A picture for the report: the representation beside its ground truth.
pub struct Picture {
    /// File name (PNG) inside the report's folder.
    pub file: String,
    /// Caption.
    pub caption: String,
    /// The image (premultiplied linear RGBA).
    pub image: RgbaImage,
}

/// The verbs the pipeline drives. Implemented by one zero-sized type per representation.
pub trait Representation {
    /// Name of the representation: folder name and `asset.json` key.
    const NAME: &'static str;
    /// Whether [`Representation::plan`] or [`Representation::build`] casts rays on the source's
    /// geometry. For scheduling only: the pipeline builds the representations that do not
    /// while the geometry prepares its ray queries ([`Shape::prepare_rays`]); a ray cast by one
    /// declared `false` waits for that preparation, and the result is the same.
    const CASTS_RAYS: bool;
    /// Manifest parameters.
    type Spec: Clone + Serialize + Sync;
    /// The representation as loaded from (or written to) files.
    type Data: Send;
    /// What the planner decided (sizes, parts kept); hashed into the cache key.
    type Decisions: Clone + Serialize + Send + Sync;

    /// The parts of `needs` that change the output (hashed into the cache key).
    fn relevant_needs(needs: &Needs) -> serde_json::Value;

    /// Decides what to compute and what to skip, each with its reason. May capture a little to
    /// decide (e.g. a coverage check); a representation that cannot hold the object returns a
    /// plan whose [`Plan::refused`] says why.
    fn plan(
        spec: &Self::Spec,
        needs: &Needs,
        source: &Source,
    ) -> Result<(Plan, Self::Decisions), PipelineError>;

    /// Builds the data the plan asks for. Returns the data and a JSON report of its costs.
    fn build(
        spec: &Self::Spec,
        needs: &Needs,
        decisions: &Self::Decisions,
        source: &Source,
    ) -> Result<(Self::Data, serde_json::Value), PipelineError>;

    /// Writes the data's files; returns the metadata a loader needs.
    fn write(data: &Self::Data, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError>;

    /// Reads the data back from a verified asset folder.
    fn read(r: &AssetReader) -> Result<Self::Data, PipelineError>;

    /// Measures the (loaded) data against the ray-cast ground truth at angles the scene needs,
    /// returning the figures and pictures for the report.
    fn measure(
        data: &Self::Data,
        needs: &Needs,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError>;
}

/// Azimuths (radians) at which to measure: `count` angles spread over the needed range, away
/// from the stored view angles' exact positions.
pub fn measure_angles(needs: &Needs, count: usize) -> Vec<f64> {
    let [a0, a1] = needs.azimuth_deg;
    let span = (a1 - a0).min(360.0);
    (0..count)
        .map(|k| (a0 + span * (k as f64 + 0.37) / count as f64).to_radians())
        .collect()
}

/// Ground-truth render of the source at `angle`, `size` pixels square, `k×k` supersampled.
/// Errors: nothing of the object is visible (the typed error every command gives).
pub fn truth(
    source: &Source,
    angle: f64,
    size: usize,
    k: usize,
) -> Result<RgbaImage, PipelineError> {
    let img = render_truth(
        source.shape()?,
        &TruthParams {
            angle,
            width: size,
            height: size,
            supersample: k,
            light: source.light,
            cylinder: altrep_data_gen::BoundingCylinder::default(),
        },
    )?;
    if img.pixels.iter().all(|p| p[3] <= 0.0) {
        return Err(PipelineError::Invisible {
            asset: source.name.to_string(),
            what: format!("the ground truth at azimuth {:.1}°", angle.to_degrees()),
        });
    }
    Ok(img)
}

/// PSNR and IoU of `image` against `reference`.
pub fn score(image: &RgbaImage, reference: &RgbaImage) -> Result<(f64, f64), PipelineError> {
    let psnr = crate::metrics::psnr(image, reference)?;
    let iou = crate::metrics::silhouette_iou(image, reference, 0.5)?;
    Ok((psnr, iou))
}

/// Folds per-angle `(psnr, iou)` into a measurement.
pub fn fold(method: String, scores: &[(f64, f64)], steps: Option<f64>) -> Measurement {
    let n = scores.len().max(1) as f64;
    Measurement {
        method,
        psnr_db: scores.iter().map(|s| s.0).sum::<f64>() / n,
        worst_psnr_db: scores.iter().map(|s| s.0).fold(f64::INFINITY, f64::min),
        iou: scores.iter().map(|s| s.1).sum::<f64>() / n,
        mean_steps: steps,
    }
}

/// The light a baked asset was shaded with, or the scene's light for dynamic lighting.
pub fn lighting_note(needs: &Needs) -> &'static str {
    match needs.lighting {
        Lighting::Baked => "baked (colour shaded at build time, no normals stored)",
        Lighting::Dynamic => "dynamic (albedo + normals stored)",
    }
}

/// Seconds since `t0`.
pub fn secs(t0: Instant) -> f64 {
    t0.elapsed().as_secs_f64()
}
