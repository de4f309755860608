//! # The one shape of every representation (docs/design.md §12)
//!
//! Every representation (images with parallax, cylindrical textures, the ellipsoid octree, texture
//! pyramids, frames over the sphere) lives in its own module folder and implements
//! [`Representation`] there: its `Spec` (the manifest's parameters, serde with documented defaults)
//! → [`Representation::plan`] from the scene's [`Needs`] → [`Representation::build`] → `Data` and a
//! report → [`Representation::write`] / [`Representation::read`] of an asset folder (through
//! [`crate::asset`]) → [`Representation::measure`] against the ray-cast ground truth. The pipeline
//! (`altrep::pipeline`) drives them through these verbs alone, from the one list in
//! [`registry`]; this module depends on nothing above the asset format.

use std::path::PathBuf;
use std::time::Instant;

use altrep_data_gen::{Light, RgbaImage, Shape, TruthParams, render_truth};
use serde::{Deserialize, Serialize};

use crate::asset::{AssetReader, AssetWriter};

pub mod registry;
pub use registry::{AnyAsset, NAMES, open};

/// What went wrong in the pipeline. Every variant names the file, key or asset at fault.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The manifest is malformed (unknown key, wrong type, duplicate name, impossible range).
    #[error("{}:{line}: {message}", path.display())]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// 1-based line (0 when unknown).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// An I/O error on `path`.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Another run holds the output folder's lock (still held after half a second).
    #[error("{}: another altrep run is writing into this folder (lock held)", path.display())]
    Locked {
        /// The lock file.
        path: PathBuf,
    },
    /// Nothing of the object is visible where the representation looks.
    #[error("asset '{asset}': the object is not visible in {what}: nothing to represent")]
    Invisible {
        /// The asset.
        asset: String,
        /// Where it was looked for.
        what: String,
    },
    /// The representation needs another kind of source than the asset has.
    #[error("asset '{asset}': this representation needs {needed}")]
    WrongSource {
        /// The asset.
        asset: String,
        /// What it needs.
        needed: &'static str,
    },
    /// An inconsistent parameter reached the builder.
    #[error("invalid parameter: {0}")]
    Spec(String),
    /// An asset file could not be written or read.
    #[error(transparent)]
    Asset(#[from] crate::asset::AssetError),
    /// Capture or mesh loading failed.
    #[error(transparent)]
    DataGen(#[from] altrep_data_gen::DataGenError),
    /// The cylindrical texture failed.
    #[error(transparent)]
    Cylinder(#[from] crate::cylinder::CylinderError),
    /// Images with parallax failed.
    #[error(transparent)]
    Parallax(#[from] crate::parallax::ParallaxError),
    /// The octree failed.
    #[error(transparent)]
    Ellipsoid(#[from] crate::ellipsoid::EllipsoidError),
    /// An image comparison failed.
    #[error(transparent)]
    Metrics(#[from] crate::metrics::MetricsError),
    /// A pyramid could not be built or loaded.
    #[error(transparent)]
    Pyramid(#[from] crate::pyramid::MipError),
    /// A texture file could not be read or decoded.
    #[error("{}: cannot read the texture: {reason}", path.display())]
    TextureFile {
        /// The texture file.
        path: PathBuf,
        /// The decoder's message.
        reason: String,
    },
}

/// How the scene lights an asset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Lighting {
    /// Lights move: store albedo and normals and relight in the shader.
    Dynamic,
    /// Lighting is fixed: store the shaded colour, no normals.
    Baked,
}

/// What the scene needs of an asset. Angles in degrees, sizes in pixels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Needs {
    /// Range of view azimuths `α` (degrees, `d(α) = (cos α, 0, sin α)`); a span of 360 or more is
    /// every direction. Default `[0, 360]`.
    pub azimuth_deg: [f64; 2],
    /// Range of view elevations above the horizontal (degrees, in `[−90, 90]`). Default `[0, 0]`.
    pub elevation_deg: [f64; 2],
    /// Smallest and largest on-screen size of the object (pixels, ≥ 1). Default `[1, 256]`.
    pub screen_px: [f64; 2],
    /// Lighting. Default dynamic.
    pub lighting: Lighting,
    /// Most grazing view angle from the surface normal of textured polygons (degrees, `[0, 90)`),
    /// for pyramids and slices. Default 80.
    pub grazing_deg: f64,
    /// Quality target: the PSNR (dB) against the ray-cast ground truth below which the report
    /// flags the asset. Default 20.
    pub quality_db: f64,
}

impl Default for Needs {
    fn default() -> Self {
        Self {
            azimuth_deg: [0.0, 360.0],
            elevation_deg: [0.0, 0.0],
            screen_px: [1.0, 256.0],
            lighting: Lighting::Dynamic,
            grazing_deg: 80.0,
            quality_db: 20.0,
        }
    }
}

impl Needs {
    /// Whether the azimuth range covers every direction.
    pub fn all_azimuths(&self) -> bool {
        self.azimuth_deg[1] - self.azimuth_deg[0] >= 360.0
    }
}

/// One decision of the planner.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanItem {
    /// What the item is (a view, a level, a channel, a resolution).
    pub what: String,
    /// `None` when built; the reason when skipped.
    pub skipped: Option<String>,
}

/// What the planner decided for one representation of one asset.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Plan {
    /// Decisions, in order.
    pub items: Vec<PlanItem>,
    /// Set when the representation cannot hold the object: the whole representation is
    /// skipped, for this reason.
    pub refused: Option<String>,
}

impl Plan {
    /// Records a part that will be built.
    pub fn build(&mut self, what: String) {
        self.items.push(PlanItem {
            what,
            skipped: None,
        });
    }

    /// Records a part that is skipped, and why.
    pub fn skip(&mut self, what: String, reason: String) {
        self.items.push(PlanItem {
            what,
            skipped: Some(reason),
        });
    }

    /// Skips the whole representation: it cannot hold the object.
    pub fn refuse(&mut self, reason: String) {
        self.refused = Some(reason);
    }

    /// The skipped items.
    pub fn skipped(&self) -> impl Iterator<Item = &PlanItem> {
        self.items.iter().filter(|i| i.skipped.is_some())
    }
}

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
    /// For a mesh: the map from the source file's coordinates to the object frame, recorded
    /// in every `asset.json` so that a renderer can place the stand-in where the mesh was.
    pub placement: Option<altrep_data_gen::Placement>,
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
    /// Whether the representation is built from a texture (assets given by `texture` or
    /// `test_texture`) instead of geometry (`shape` or `mesh`).
    const FROM_TEXTURE: bool = false;
    /// Manifest parameters (the `[asset.NAME]` table).
    type Spec: Clone + std::fmt::Debug + PartialEq + Serialize + serde::de::DeserializeOwned + Sync;
    /// The representation as loaded from (or written to) files.
    type Data: Send;
    /// What the planner decided (sizes, parts kept); hashed into the cache key.
    type Decisions: Clone + Serialize + Send + Sync;

    /// Checks the manifest's parameters before any work; the message names the key.
    fn validate(spec: &Self::Spec) -> Result<(), String>;

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
