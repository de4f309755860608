//! The data generator's integration tests, one binary (a fresh clone links it once and the
//! modules run side by side). Run one module with
//! `cargo test -p altrep-data-gen --test integration MODULE::` (for example `gltf::`).

mod capture;
mod gltf;
mod mesh;
mod parallel_rays;
mod shell;
mod simplify;
mod stress;
mod voxel_rows;
