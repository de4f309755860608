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

pub mod manifest;
pub mod memory;
mod output;
mod run;
mod source;

pub use crate::representation::{
    Lighting, Measurement, Needs, PipelineError, Plan, PlanItem, Representation, Source,
};
pub use manifest::{AssetSpec, Manifest, SceneSettings, SourceSpec, TestTexture};
pub use memory::{MemoryPlan, plan_memory};
pub use run::{
    AssetOutcome, LOCK_FILE, Outcome, RunOptions, RunSummary, Shard, plan_scene, run_scene,
};
