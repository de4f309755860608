//! # The precompute pipeline (docs/design.md §12)
//!
//! `altrep precompute SCENE.toml --out DIR` reads a [`Manifest`], and for every asset and every
//! representation it wants: **plans** what the scene needs (and what to skip, with the reason),
//! computes a **cache key** (BLAKE3 of the input bytes, the parameters, the planner's decisions
//! and the tool and format versions), reuses the asset folder when its key matches and every file
//! verifies, and otherwise **builds**, **writes** (staged, renamed into place — see
//! [`crate::asset`]), **reads back** and **measures** the loaded files against the ray-cast
//! ground truth. Assets run in parallel (rayon); one lock file keeps two runs out of one folder.
//!
//! Output layout: `DIR/ASSET/REPR/asset.json` + data files, `DIR/report.json`, `DIR/report.md`,
//! `DIR/pictures/*.png`. Format: `docs/asset-format.md`.

pub mod cylinder;
pub mod manifest;
pub mod octree;
pub mod parallax;
pub mod pyramid;
pub mod repr;
mod run;
pub mod sphere;

use std::path::PathBuf;

use serde::Serialize;

pub use manifest::{AssetSpec, Lighting, Manifest, Needs, SceneSettings, SourceSpec, TestTexture};
pub use repr::{Measurement, Representation, Source};
pub use run::{
    AssetOutcome, LOCK_FILE, Outcome, RunOptions, RunSummary, Shard, plan_scene, run_scene,
};

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
