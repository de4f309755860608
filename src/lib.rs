//! # altrep — alternative representations of complex geometry
//!
//! altrep precomputes and fits compact stand-ins for complex geometry (images with parallax,
//! cylindrical textures, volumetric textures of ellipsoid micro-primitives, texture pyramids) so a
//! real-time renderer can draw them at a fraction of the cost of the polygons.
//!
//! Data flows one way: [`altrep_data_gen`] (shape → samples) → a representation module
//! (samples → fitted data, using [`altrep_solvers`] where a system must be solved) → files →
//! display / evaluation. A representation module never reads a mesh and never renders with the GPU.
//!
//! Conventions (shared with `altrep-data-gen`, see its crate docs): object frame right-handed,
//! `y` vertical, horizontal direction `d(α) = (cos α, 0, sin α)`, every object normalised into a
//! bounding cylinder of radius `R` about the `y` axis and height `H`.

pub mod asset;
pub mod auto;
pub mod cli;
pub mod cylinder;
pub mod ellipsoid;
pub mod fit;
pub mod mesh_lod;
pub mod metrics;
pub mod parallax;
pub mod pipeline;
pub mod profile;
pub mod pyramid;

/// The mip pyramid, kept at its old path (`crate::mip::…`); it lives in [`pyramid::mip`].
pub use pyramid::mip;
pub mod report;
pub mod representation;
pub mod slices;
pub mod sphere;
pub mod stats;

pub use altrep_data_gen as data_gen;
pub use altrep_solvers as solvers;
