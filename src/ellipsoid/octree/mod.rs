//! The multiscale octree volume of Neyret 1995: leaves from a voxelised RGBA + density volume,
//! coarser levels by filtering, uniform and empty regions pruned, level lookup by footprint.
//!
//! # Levels and coordinates
//!
//! Voxel `(x, y, z)` covers `[x, x+1) × [y, y+1) × [z, z+1)` in **voxel units**. The volume is padded
//! with empty voxels to a cube of side `2^depth`. A node of **level** `ℓ` covers a cube of side `2^ℓ`
//! voxels: level 0 is a voxel, the root is level `depth`. A pruned (uniform) region is a leaf above
//! level 0 and stands for every finer level inside it.
//!
//! # What a node holds
//!
//! - `density`: mean coverage of its voxels (padding counts as empty), in `[0, 1]`;
//! - `color`: density-weighted mean of the voxels' linear RGB;
//! - `ellipsoid`: the filter ([`FilterRule`](crate::ellipsoid::filter::FilterRule)) of its voxels' micro-primitives weighted by density,
//!   `None` where the density is zero. Because both rules average a moment matrix linearly, filtering
//!   children is exactly filtering all voxels below (the build keeps the `f64` moment sums; each
//!   node's ellipsoid comes from one eigen-decomposition of its own mean).
//!
//! # Leaves from voxels
//!
//! A voxel with a surface normal gets a flat spheroid along it (lengths `(b, b, a)`, `a/b =`
//! [`OctreeParams::leaf_flatness`], normalised: `b² + 2ab = 3`); a voxel without a normal, or a full
//! voxel whose six face-neighbours are full (hidden inside a solid,
//! [`OctreeParams::isotropic_interior`]), gets the unit sphere. Empty voxels have none.
//!
//! # Pruning
//!
//! Eight leaf children that agree — mean densities within `tolerance`, mean colours within
//! `tolerance`, mean moment matrices within `tolerance` relative to the first child's largest
//! entry — become one leaf, which stands for every finer level inside it. Empty and non-empty children
//! never merge, so "no micro-primitive" stays exact.
//!
//! # Files
//!
//! - `voxels`: the input ([`Voxel`], [`VoxelSource`], [`VoxelGrid`]);
//! - `storage`: the stored nodes ([`OctreeNode`], [`PackedEllipsoid`]), the [`Octree`] and
//!   [`Octree::from_nodes`], and what a lookup returns ([`NodeSample`]);
//! - `build`: [`Octree::build`] with its [`OctreeParams`] and [`OctreeReport`];
//! - `render`: level choice, [`Octree::lookup`], [`Octree::render_level`] and [`Octree::render_view`] ([`OctreeRenderParams`], [`OctreeView`]);
//!
//! The analytic test volumes ([`AnalyticShape`], [`AnalyticVolume`]) live in `altrep_data_gen`
//! with the other shapes; they are re-exported here at their old paths, and `voxels` makes an
//! [`AnalyticVolume`] a [`VoxelSource`].

mod build;
mod render;
mod storage;
mod voxels;

pub use altrep_data_gen::{AnalyticShape, AnalyticVolume};
pub use build::{OctreeParams, OctreeReport};
pub use render::{OctreeRenderParams, OctreeView};
pub use storage::{NodeSample, Octree, OctreeNode, PackedEllipsoid};
pub use voxels::{Voxel, VoxelGrid, VoxelSource};
