//! # The one shape of every representation (docs/design.md §12)
//!
//! Every representation (images with parallax, cylindrical textures, the ellipsoid octree, texture
//! pyramids, frames over the sphere, slices) lives in its own module folder and implements
//! [`Representation`] there: its `Spec` (the manifest's parameters, serde with documented defaults)
//! → [`Representation::plan`] from the scene's [`Needs`] → [`Representation::build`] → `Data` and a
//! report → [`Representation::write`] / [`Representation::read`] of an asset folder (through
//! [`crate::asset`]) → [`Representation::measure`] against the ray-cast ground truth. The pipeline
//! (`altrep::pipeline`) drives them through these verbs alone, from the one list in
//! [`registry`]; this module depends on nothing above the asset format.

use std::path::PathBuf;
use std::time::Instant;

use altrep_data_gen::{
    Light, OrthoFrame, RgbaImage, Shape, Supersample, TruthParams, render_truth,
    render_truth_frame, screen_right,
};
use glam::DVec3;
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
    /// The memory plan's estimate exceeds the run's limit (`--max-memory`): refused before
    /// any work.
    #[error(
        "the run needs about {estimate} of memory (estimate; the largest part: {largest}), above the limit of {limit}: \
         lower the largest representation's sizes (views, size, columns/rows, resolution, grid) or the asset's \
         screen_px, run fewer assets at once (--shard i/n), or raise --max-memory"
    )]
    Memory {
        /// The estimated peak.
        estimate: String,
        /// The limit.
        limit: String,
        /// The representation with the largest estimate, with it.
        largest: String,
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
    /// Slices failed.
    #[error(transparent)]
    Slices(#[from] crate::slices::SliceError),
    /// The frames over the sphere failed.
    #[error(transparent)]
    Sphere(#[from] crate::sphere::SphereError),
    /// An image comparison failed.
    #[error(transparent)]
    Metrics(#[from] crate::metrics::MetricsError),
    /// A plot of the report could not be drawn.
    #[error(transparent)]
    Report(#[from] crate::report::ReportError),
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

/// What a representation is expected to cost before it is built (see
/// [`Representation::estimate`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Estimate {
    /// Peak memory while it is built, written, read back and measured (bytes): a linear model in
    /// the texels, voxels or frames it holds, fitted to the peaks a counting allocator measured
    /// (`tests/memory.rs` checks it within 2×).
    pub peak_bytes: u64,
    /// Bytes of its files, at most: every data file uncompressed (PNG compresses them).
    pub output_bytes: u64,
}

/// What the estimates know of an asset's source before loading it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InputSize {
    /// A texture's `(width, height, channels)`, from its file's header (or the procedural size).
    pub texture: Option<(usize, usize, usize)>,
    /// A volume tile's voxels per side.
    pub tile: Option<usize>,
    /// A mesh's memory once loaded (bytes; the plan's coarse rule on its file sizes).
    pub mesh: Option<u64>,
}

/// `bytes_per · count` plus a fixed `base`, saturating, as an [`Estimate`] field.
pub fn linear_bytes(base: f64, bytes_per: f64, count: f64) -> u64 {
    let b = base + bytes_per * count;
    if b.is_finite() && b < u64::MAX as f64 {
        b.ceil() as u64
    } else {
        u64::MAX
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
    /// The volume tile, for assets given by `tile` (slices), lit by the scene's light.
    pub tile: Option<&'a crate::slices::TexelVolume>,
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
    /// Mean coverage error ([`crate::metrics::coverage_error`]: mean absolute alpha difference
    /// over the pixels either picture covers), `None` in files written before it was measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coverage_error: Option<f64>,
    /// Mean shader steps per pixel, where the representation marches: every march counted.
    pub mean_steps: Option<f64>,
    /// Where those steps go, per pixel (for example the bracketing views, the fallback views and
    /// hole filling of images with parallax); empty when there is one kind of march.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub steps_split: Vec<(String, f64)>,
    /// Picture side (pixels) the figures were measured at, before any widening for views off the
    /// horizontal ([`Representation::measure_size`]; 0 for pyramids, measured at the needs'
    /// screen sizes).
    #[serde(default)]
    pub size: usize,
    /// Mean PSNR (dB) of the representation's exact renderer over the same views, where the
    /// figures above come from the renderer a display runs (a bounded march): the two draw the
    /// same image by design, so a gap of more than [`EXACT_GAP_DB`] flags a broken renderer or
    /// damaged data ([`crate::pipeline::RunSummary::below_exact`]). `None` where the measured
    /// renderer is the only one (octree, slices, frames over the sphere, pyramids).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exact_psnr_db: Option<f64>,
}

/// Largest gap (dB) accepted between a representation's exact renderer and the renderer its
/// figures come from ([`Measurement::exact_psnr_db`]): they draw the same image by design, so
/// anything beyond rounding is a defect to flag, not a figure to report as a success.
pub const EXACT_GAP_DB: f64 = 0.5;

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
    /// Whether the representation is also built from a procedural volume tile (assets given by
    /// `tile`, [`Source::tile`]), repeated over a surface.
    const FROM_TILE: bool = false;
    /// Whether the representation can follow a moving light (stores normals, or shades from
    /// its data at draw time). One that cannot stores colour shaded with the scene's light: its
    /// plan refuses dynamic lighting, and `--everything` (which builds for dynamic lighting)
    /// keeps the asset's own lighting for it.
    const RELIGHTS: bool = true;
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

    /// What building, writing, reading back and measuring the representation will cost, from
    /// the parameters, the needs and what is known of the source before loading it: no ray is
    /// cast. The memory plan refuses a run whose estimate exceeds its limit before any work.
    fn estimate(spec: &Self::Spec, needs: &Needs, input: &InputSize) -> Estimate;

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

    /// The picture side (pixels) at which data built with `decisions` is measured: the view,
    /// texture or voxel size the plan chose, as [`Representation::measure`] draws it. A run
    /// that ignores the needs (`--everything`) measures its larger data at the size the plan
    /// for the needs would have chosen, so the two runs' figures compare. Pyramids, measured at
    /// the needs' screen sizes, return 0.
    fn measure_size(decisions: &Self::Decisions) -> usize;

    /// A markdown section for the run's report, written from the build report `build` (what
    /// [`Representation::build`] returned, or what a cached folder's `asset.json` holds): the
    /// tables a reader wants beside the figures. Default: none.
    fn details(build: &serde_json::Value) -> Option<String> {
        let _ = build;
        None
    }

    /// Plots for the run's report, drawn from the build report `build` (as
    /// [`Representation::details`]) for the asset named `asset`, and written beside the pictures
    /// of [`Representation::measure`] when the run measures. Default: none.
    ///
    /// Errors: a plot that cannot be drawn ([`PipelineError::Report`]).
    fn plots(build: &serde_json::Value, asset: &str) -> Result<Vec<Picture>, PipelineError> {
        let _ = (build, asset);
        Ok(Vec::new())
    }

    /// Measures the (loaded) data against the ray-cast ground truth at the directions `needs`
    /// asks for, drawn `size` pixels across ([`Representation::measure_size`]; data larger than
    /// that is drawn minified, as a display would at that screen size), returning the figures
    /// and pictures for the report.
    fn measure(
        data: &Self::Data,
        needs: &Needs,
        size: usize,
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

/// Ground-truth render of the source at `angle`, `size` pixels square, `k × k` rays per pixel.
/// Errors: nothing of the object is visible (the typed error every command gives).
pub fn truth(
    source: &Source,
    angle: f64,
    size: usize,
    k: Supersample,
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

/// A direction the scene needs the object from: the camera lies toward
/// `(cos e cos α, sin e, cos e sin α)` for azimuth `α` and elevation `e` (radians), the azimuth
/// convention of [`Needs::azimuth_deg`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewDir {
    /// Azimuth `α` (radians).
    pub azimuth: f64,
    /// Elevation `e` above the horizontal (radians).
    pub elevation: f64,
}

/// Whether the needs ask for any view off the horizontal.
pub fn needs_elevation(needs: &Needs) -> bool {
    needs.elevation_deg != [0.0, 0.0]
}

/// `count` directions at which to measure: the azimuths of [`measure_angles`], paired in order
/// with elevations running from the lowest needed to the highest (both ends when `count ≥ 2`).
pub fn measure_views(needs: &Needs, count: usize) -> Vec<ViewDir> {
    let [e0, e1] = needs.elevation_deg;
    measure_angles(needs, count)
        .into_iter()
        .enumerate()
        .map(|(k, azimuth)| {
            let u = if count > 1 {
                k as f64 / (count - 1) as f64
            } else {
                0.5
            };
            ViewDir {
                azimuth,
                elevation: (e0 + (e1 - e0) * u).to_radians(),
            }
        })
        .collect()
}

/// The square window in which a representation's drawing and the ground truth are compared.
///
/// For horizontal needs it is the view window of the bounding cylinder (`x ∈ [−1, 1]` across,
/// `y ∈ [0, 2]`), `size` pixels square: the truth of [`truth`]. For needs off the horizontal the
/// same pixel grid is widened by `pad` pixels on every side, to a window at least as wide as the
/// sphere of radius `√2` around `(0, 1, 0)` that holds the cylinder: every view of the object
/// falls inside it, and a drawing confined to the cylinder's window is charged for what it
/// leaves out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// The representation's own image size (pixels).
    pub size: usize,
    /// Pixels added on every side (0 for horizontal needs).
    pub pad: usize,
}

impl Window {
    /// The window for `needs` around a drawing of `size²` pixels.
    pub fn for_needs(needs: &Needs, size: usize) -> Self {
        let pad = if needs_elevation(needs) {
            (size as f64 * (std::f64::consts::SQRT_2 - 1.0) / 2.0).ceil() as usize
        } else {
            0
        };
        Self { size, pad }
    }

    /// Side of the compared images (pixels).
    pub fn side(&self) -> usize {
        self.size + 2 * self.pad
    }

    /// The orthographic frame of the window along `view` (object frame): centre `(0, 1, 0)`,
    /// screen right horizontal (`screen_right(α)`, also straight above or below), up completing
    /// the frame. At elevation 0 it is the frame of [`truth`].
    pub fn frame(&self, view: ViewDir) -> OrthoFrame {
        let (a, e) = (view.azimuth, view.elevation);
        let dir = DVec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin());
        let right = screen_right(a);
        OrthoFrame {
            centre: DVec3::Y,
            radius: self.side() as f64 / self.size as f64,
            dir,
            right,
            up: dir.cross(right),
        }
    }

    /// Ground truth along `view` in this window, `k × k` rays per pixel. For the horizontal
    /// window at elevation 0 it is exactly [`truth`]. Errors: nothing of the object is visible.
    /// Cost: `side² · k²` rays.
    pub fn truth(
        &self,
        source: &Source,
        view: ViewDir,
        k: Supersample,
    ) -> Result<RgbaImage, PipelineError> {
        if self.pad == 0 && view.elevation == 0.0 {
            return truth(source, view.azimuth, self.size, k);
        }
        let side = self.side();
        let img = render_truth_frame(
            source.shape()?,
            &self.frame(view),
            side,
            side,
            k,
            &source.light,
        )?;
        if img.pixels.iter().all(|p| p[3] <= 0.0) {
            return Err(PipelineError::Invisible {
                asset: source.name.to_string(),
                what: format!(
                    "the ground truth at azimuth {:.1}°, elevation {:.1}°",
                    view.azimuth.to_degrees(),
                    view.elevation.to_degrees()
                ),
            });
        }
        Ok(img)
    }

    /// PSNR and IoU of `image` against `reference` (both `side²`), with the PSNR's squared error
    /// summed over the whole window but divided by the pixel count of the cylinder's window
    /// (`size²`): a horizontal view, empty outside the cylinder's window, scores exactly as in
    /// [`score`], and error outside it still counts.
    pub fn score(&self, image: &RgbaImage, reference: &RgbaImage) -> Result<Score, PipelineError> {
        let s = score(image, reference)?;
        Ok(Score {
            psnr_db: s.psnr_db - 20.0 * (self.side() as f64 / self.size as f64).log10(),
            ..s
        })
    }

    /// A drawing of the cylinder's window (`size²`) placed at the centre of this window, empty
    /// around: how a renderer shows a representation that draws horizontal views only, facing
    /// the camera.
    pub fn place(&self, image: &RgbaImage) -> RgbaImage {
        if self.pad == 0 {
            return image.clone();
        }
        let side = self.side();
        let mut out = RgbaImage::new(side, side);
        let n = image.width.min(self.size);
        for (j, row) in image.pixels.chunks(image.width).take(self.size).enumerate() {
            let start = (j + self.pad) * side + self.pad;
            out.pixels[start..start + n].copy_from_slice(&row[..n]);
        }
        out
    }
}

/// The words a measurement's method adds for needs off the horizontal: the elevations and the
/// window (empty for horizontal needs).
pub fn elevation_note(needs: &Needs, window: Window) -> String {
    if !needs_elevation(needs) {
        return String::new();
    }
    let [e0, e1] = needs.elevation_deg;
    format!(
        ", at elevations {e0}° to {e1}° in a {0}² window holding every view ({1} px added on each side)",
        window.side(),
        window.pad
    )
}

/// For a representation that draws horizontal views only (images with parallax, the
/// cylindrical texture), shown facing the camera at other elevations: the worst PSNR (dB), over
/// 4 needed azimuths, between the object's horizontal view and its view from the needed
/// elevation farthest from the horizontal, with that elevation (degrees). No such
/// representation can do much better there, since it holds only the horizontal view. `None`
/// for horizontal needs. Cost: 8 truth images of the window of [`Window::for_needs`] around
/// `size²`, 2 × 2 rays per pixel.
pub fn horizontal_ceiling(
    needs: &Needs,
    source: &Source,
    size: usize,
) -> Result<Option<(f64, f64)>, PipelineError> {
    if !needs_elevation(needs) {
        return Ok(None);
    }
    let [e0, e1] = needs.elevation_deg;
    let worst = if e0.abs() > e1.abs() { e0 } else { e1 };
    let window = Window::for_needs(needs, size);
    let mut ceiling = f64::INFINITY;
    for azimuth in measure_angles(needs, 4) {
        let flat = window.truth(
            source,
            ViewDir {
                azimuth,
                elevation: 0.0,
            },
            Supersample::of(2),
        )?;
        let view = ViewDir {
            azimuth,
            elevation: worst.to_radians(),
        };
        let tilted = window.truth(source, view, Supersample::of(2))?;
        ceiling = ceiling.min(window.score(&tilted, &flat)?.psnr_db);
    }
    Ok(Some((ceiling, worst)))
}

/// The plan's decision for a representation that draws horizontal views only: refused, naming
/// the frames over the sphere, when [`horizontal_ceiling`] is below the quality target; else a
/// plan item saying how the elevated views are drawn and measured. Nothing for horizontal needs.
pub fn plan_elevations(
    plan: &mut Plan,
    needs: &Needs,
    source: &Source,
    size: usize,
    what: &str,
) -> Result<(), PipelineError> {
    let Some((ceiling, worst)) = horizontal_ceiling(needs, source, size)? else {
        return Ok(());
    };
    let [e0, e1] = needs.elevation_deg;
    if ceiling < needs.quality_db {
        plan.refuse(format!(
            "{what} hold horizontal views only: seen from {worst}° of elevation the object differs \
             from its horizontal view by {ceiling:.1} dB, below the quality target of {} dB; the \
             frames over the sphere ([asset.sphere]) hold every elevation",
            needs.quality_db
        ));
    } else {
        plan.build(format!(
            "views from {e0}° to {e1}° of elevation: the horizontal view facing the camera \
             ({ceiling:.1} dB at {worst}° at best), measured there"
        ));
    }
    Ok(())
}

/// One view of a representation against its truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Score {
    /// PSNR (dB, peak 1) over RGBA ([`crate::metrics::psnr`]).
    pub psnr_db: f64,
    /// Silhouette IoU at alpha ½ ([`crate::metrics::silhouette_iou`]).
    pub iou: f64,
    /// Mean absolute alpha difference over the covered pixels
    /// ([`crate::metrics::coverage_error`]).
    pub coverage_error: f64,
}

/// PSNR, IoU and coverage error of `image` against `reference`.
pub fn score(image: &RgbaImage, reference: &RgbaImage) -> Result<Score, PipelineError> {
    Ok(Score {
        psnr_db: crate::metrics::psnr(image, reference)?,
        iou: crate::metrics::silhouette_iou(image, reference, 0.5)?,
        coverage_error: crate::metrics::coverage_error(image, reference)?,
    })
}

/// Folds per-angle scores into a measurement (means, and the worst PSNR).
pub fn fold(method: String, scores: &[Score], steps: Option<f64>) -> Measurement {
    let n = scores.len().max(1) as f64;
    Measurement {
        method,
        psnr_db: scores.iter().map(|s| s.psnr_db).sum::<f64>() / n,
        worst_psnr_db: scores
            .iter()
            .map(|s| s.psnr_db)
            .fold(f64::INFINITY, f64::min),
        iou: scores.iter().map(|s| s.iou).sum::<f64>() / n,
        coverage_error: Some(scores.iter().map(|s| s.coverage_error).sum::<f64>() / n),
        mean_steps: steps,
        steps_split: Vec::new(),
        size: 0,
        exact_psnr_db: None,
    }
}

/// The mean of the PSNRs in `scores`, for [`Measurement::exact_psnr_db`].
pub fn mean_psnr(scores: &[Score]) -> Option<f64> {
    (!scores.is_empty())
        .then(|| scores.iter().map(|s| s.psnr_db).sum::<f64>() / scores.len() as f64)
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

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// The widened window's grid continues the cylinder's: the horizontal truth placed in it
    /// equals the truth rendered along the window's frame, pixel for pixel, and scores as in the
    /// narrow window.
    #[test]
    fn the_widened_window_continues_the_cylinder_window() {
        let shape = altrep_data_gen::scene_shape("chair").unwrap();
        let source = Source {
            name: "chair",
            geometry: Some(&shape),
            texture: None,
            tile: None,
            light: Light::default(),
            placement: None,
        };
        let tilted = Needs {
            elevation_deg: [0.0, 40.0],
            ..Needs::default()
        };
        let window = Window::for_needs(&tilted, 24);
        assert_eq!((window.pad, window.side()), (5, 34));
        for azimuth in [0.3, 2.0, 4.4] {
            let narrow = truth(&source, azimuth, 24, Supersample::of(2)).unwrap();
            let view = ViewDir {
                azimuth,
                elevation: 0.0,
            };
            let wide = window.truth(&source, view, Supersample::of(2)).unwrap();
            let placed = window.place(&narrow);
            for (p, q) in placed.pixels.iter().zip(&wide.pixels) {
                for c in 0..4 {
                    assert_abs_diff_eq!(p[c], q[c], epsilon = 1e-5);
                }
            }
            let flat = truth(&source, azimuth + 0.2, 24, Supersample::of(2)).unwrap();
            let a = score(&flat, &narrow).unwrap().psnr_db;
            let b = window.score(&window.place(&flat), &placed).unwrap().psnr_db;
            assert_abs_diff_eq!(a, b, epsilon = 1e-9);
        }
        // Straight above, the frame stays a right-handed basis with a horizontal right.
        let f = window.frame(ViewDir {
            azimuth: 1.0,
            elevation: std::f64::consts::FRAC_PI_2,
        });
        assert_abs_diff_eq!(f.right.cross(f.up).distance(f.dir), 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(f.right.y, 0.0);
    }

    #[test]
    fn measured_views_span_the_needed_elevations() {
        let needs = Needs {
            elevation_deg: [-10.0, 50.0],
            ..Needs::default()
        };
        let e: Vec<f64> = measure_views(&needs, 4)
            .iter()
            .map(|v| v.elevation.to_degrees())
            .collect();
        assert_abs_diff_eq!(e[0], -10.0, epsilon = 1e-9);
        assert_abs_diff_eq!(e[3], 50.0, epsilon = 1e-9);
        assert!(
            measure_views(&Needs::default(), 4)
                .iter()
                .all(|v| v.elevation == 0.0)
        );
    }
}
