//! The library's integration tests, one binary: each module below was its own test binary, and
//! every binary relinks the library and runs alone, one after another. As modules they build
//! once and run side by side. `tests/memory.rs` stays apart: it counts every allocation of its
//! process through its own global allocator, so nothing else may run beside it.
//!
//! Run one module with `cargo test --test integration MODULE::` (for example `slices::`).

mod cli;
mod cylinder;
mod ellipsoid;
mod fit;
mod mip;
mod parallax;
mod pipeline;
mod pyramid;
mod real_assets;
mod report;
mod slices;
mod sphere;
mod sphere_pipeline;
