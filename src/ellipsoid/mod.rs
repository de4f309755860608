//! Ellipsoid micro-primitives and multiscale volumes (Neyret 1995, docs/design.md §8).
//!
//! - [`primitive`]: the [`Ellipsoid`] (basis + lengths ⇄ quadratic form), projected area, normal
//!   distribution `f_Q`, Phong reflectance by two independent methods.
//! - [`eigen`]: fast robust 3×3 symmetric eigen-decomposition (`f32`, `f64`), adversarial suite.
//! - [`filter`](mod@filter): merging weighted ellipsoids by the 1995 rule and the SGGX rule, and their errors
//!   against the true summed normal distribution and projected area.
//! - [`octree`]: the multiscale octree volume (leaves from voxels, levels by filtering, pruning,
//!   lookup by footprint).
//! - [`quadrature`]: adaptive quadrature over the sphere used by the error measures.
//! - [`report`]: the measurements printed by `altrep ellipsoid-bench`.
//! - [`rng`]: a seeded generator for reproducible cases.

pub mod asset;
pub mod eigen;
pub mod error;
pub mod filter;
pub mod octree;
pub mod primitive;
pub mod quadrature;
pub mod report;
pub mod rng;

pub use eigen::{SymEigen3, sym_eigen3};
pub use error::EllipsoidError;
pub use filter::{FilterErrors, FilterRule, filter, filter_errors};
pub use octree::{Octree, OctreeParams, OctreeReport, VoxelGrid, VoxelSource};
pub use primitive::{Ellipsoid, MAX_LENGTH, MIN_ASPECT, MIN_LENGTH, Phong};
pub use quadrature::SphereQuadrature;
