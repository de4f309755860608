//! The display's GPU tests, one binary: each module draws through the shaders of one family and
//! checks the pictures against the CPU renderers (and the ray-cast truth). As one binary a fresh
//! clone links it once, the modules share one device (`common::gpu`) and run side by side.
//!
//! Run one module with `cargo test -p altrep-display --test gpu MODULE::` (for example
//! `sphere_gpu::`).

mod common;
mod cylinder_gpu;
mod parallax_gpu;
mod pyramid_gpu;
mod sphere_gpu;
mod volumes_gpu;
