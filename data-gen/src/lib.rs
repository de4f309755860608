//! # altrep-data-gen — shapes, meshes, ray-cast capture and ground truth
//!
//! The first stage of altrep's pipeline: it turns a shape (procedural or an OBJ mesh) into samples
//! (orthographic views, cylindrical textures, voxel volumes) and renders the ray-cast **ground truth**
//! that every accuracy figure of the project is measured against.
//!
//! ## Conventions (fixed once, here; every other crate refers to them)
//!
//! * Object frame: right-handed, **`y` is the vertical axis**. Horizontal angles are measured in the
//!   x–z plane: [`direction`]`(α) = (cos α, 0, sin α)`.
//! * Every object lives in a [`BoundingCylinder`] of radius `R` about the `y` axis and height `H`
//!   (`y ∈ [0, H]`). Procedural shapes are built for `R = 1`, `H = 2`; meshes are normalised into it.
//! * A **view at angle α** is orthographic and looks along `−d(α)` (the camera sits on the `+d(α)`
//!   side). Its screen basis is `right(α) = (sin α, 0, −cos α)` ([`screen_right`]), `up = +y`, and
//!   `right × up = d(α)` (right-handed). A point `p` has screen abscissa `x = p·right(α)`, screen
//!   ordinate `y = p.y`, and **depth** `z = p·d(α)` (positive toward the camera). For
//!   `p = r·d(β)`, `x = r·sin(α − β)`.
//! * Pixel grids cover the cylinder's silhouette `[−R, R] × [0, H]`: pixel `(i, j)` of a
//!   `W × Hpx` grid has its centre at `x = −R + (i + ½)·2R/W` and `y = H − (j + ½)·H/Hpx`
//!   (row 0 at the **top**, as in image files). See [`PixelGrid`].
//! * Stored depths and radii are divided by `R`, so they lie in `[−1, 1]`.
//! * Colours are linear RGB in `[0, 1]`; images are RGBA with **premultiplied** alpha; files are
//!   written sRGB-encoded.
//! * A sample whose ray misses is **undefined** (`None`), never a magic number.
//! * Every random choice takes a seed ([`SplitMix64`]).
//!
//! ## Ray casting
//!
//! [`Shape::intersect`] casts one ray. The orthographic images (views, frames, ground truths) cast
//! grids of parallel rays ([`ParallelRays`]) through [`Shape::parallel_tracer`]: a [`Mesh`] bins
//! its triangles over grids with at least ¾ as many rays as triangles and runs the BVH walk's own
//! triangle test on each ray's few candidates (exactly the nearest hit over all triangles; see
//! the `binned` module), and walks its BVH per ray on smaller grids. Criterion
//! (`cargo bench -p altrep-benches --bench foundation -- ray_casting`) times both on the shipped meshes. The
//! cylindrical captures cast grids of radial rays ([`RadialRays`]) through
//! [`Shape::radial_tracer`], which a [`Mesh`] bins by height and angle in the same way (the
//! `radial` module; `cargo bench -p altrep-benches --bench foundation -- cylinder_rays`).

mod albedo;
mod analytic;
pub mod binned;
mod capture;
mod error;
mod frame;
mod geometry;
mod gltf_export;
mod gltf_file;
pub mod gltf_write;
mod image_io;
mod mesh;
mod obj_file;
mod placement;
pub mod radial;
mod rng;
mod shape;
mod shapes;
mod shared;
mod shell;
mod simplify;
mod supersample;
mod surface;
#[cfg(test)]
mod test_meshes;
mod truth;
mod volume;
mod watertight;
mod yz_grid;

pub use albedo::Albedo;
pub use analytic::{AnalyticShape, AnalyticVolume};
pub use capture::{
    CylinderParams, Projection, Sample, SampleGrid, ViewParams, capture_cylinder, capture_view,
};
pub use error::DataGenError;
pub use frame::{FrameCapture, OrthoFrame, capture_frame, render_truth_frame};
pub use geometry::{
    BoundingCylinder, Footprint, Hit, ParallelRays, PixelGrid, RadialRays, Ray, direction,
    screen_right,
};
pub use gltf_export::{ExternalImages, GlbFile, ImageFile};
pub use image_io::{RgbaImage, linear_to_srgb, srgb_to_linear};
pub use mesh::{Mesh, MeshLoadOptions};
pub use placement::{Placement, UpAxis};
pub use rng::SplitMix64;
pub use shape::{Csg, ParallelTracer, Part, Primitive, RayByRay, Shape, intersect_parallel};
pub use shapes::{SCENE_SHAPES, scene_shape};
pub use shared::{shared_mesh, shared_mesh_paths, shared_meshes, skip, under_ci};
#[doc(hidden)]
pub use simplify::{Simplified, SimplifyParams};
pub use supersample::Supersample;
pub use surface::{
    EncodedImage, Material, MaterialAlpha, SamplerFilter, TextureImage, TextureRef, UvTransform,
    Wrap,
};
pub use truth::{Light, TruthParams, render_silhouette, render_truth, render_truth_at_points};
pub use volume::{Fill, Volume, Voxel, VoxelParams, voxelize};
