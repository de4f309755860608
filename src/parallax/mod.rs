//! # Images with parallax (docs/design.md §7, chapter 4 of Baboud's report)
//!
//! An object is stored as `N` orthographic views `I_k` at `α_k = 2πk/N` (default 8 views of
//! 64 × 64), each texel holding colour + alpha, a normal and a depth (a height field per view).
//! At display angle `α` the two views whose angles bracket `α` are **warped** (each texel moves
//! horizontally by its parallax) and combined. This module captures the views
//! ([`ParallaxImages`]), warps them on the CPU directly ([`warp_row_direct`]) and inversely, one
//! ray per pixel as a fragment shader would ([`march`]), combines them ([`render`]), provides two
//! baselines ([`render_blend_baseline`], [`render_offset_baseline`]), and precomputes per-pixel
//! **march bounds** ([`build_bounds`]) whose step counts, memory and conservativeness are measured
//! by [`measure_steps`] and [`dense_sweep`]; [`render_bounded`] is the shader's path with stored
//! bounds. Each view carries a mip pyramid ([`ParallaxImages::pyramids`]); a minified impostor
//! warps a coarser level ([`ParallaxImages::level`], [`RenderParams::mip`]).
//!
//! Measured (`altrep parallax --shape truck`, 64², N = 8, 8-bit bounds, 360 angles, every
//! fragment of the quad, per warped view): mean steps 16.0 (cylinder), 1.98 (zmin/zmax), 1.41
//! (pair), 1.04 (best c), 0.67 (best c, split θ); zero violations on the dense sweep.
//! bench/RESULTS.md has all six shapes and the report's ÷5 / ÷12.
//!
//! **Reconstruction** (docs/design.md §7.6): the surface at unjoined texel ends ([`Brim`],
//! [`ParallaxImages::with_brim`]: along the stored normal's tangent by default, or flat as
//! originally), and in [`render_with`] / [`render_bounded_with`] a linear filter between view
//! rows, a fallback to the next views out where both miss (doubtful fallback hits at half
//! coverage), soft coverage at silhouette brims, hole filling, brim carving (all on by default,
//! [`Reconstruction::DEFAULT`]) and a depth test between the two views (off). [`Brim::Flat`]
//! with [`Reconstruction::ORIGINAL`] is the original path.
//! [`measure_quality_sweep`] measures each option alone and all together, with the error split
//! by distance to the true outline ([`error_split`]).
//!
//! ## Sign conventions (derived once from data-gen's; the report's slip: docs/design.md §14)
//!
//! data-gen's view at angle `α` has screen abscissa `x = p·right(α)`, `right(α) = (sin α, 0,
//! −cos α)`, and depth `z = p·d(α)` (toward the camera). Write the view `k` frame `(x_t, z_t)` =
//! `(p·right(α_k), p·d(α_k))` and the display angle `α = α_k + θ` (**θ is the display angle minus
//! the view's angle**, as in the report). Since `right(α_k + θ) = right(α_k) cos θ + d(α_k) sin θ`
//! and `d(α_k + θ) = d(α_k) cos θ − right(α_k) sin θ`, a texel moves to
//!
//! * `x_e = x_t cos θ + z_t sin θ` (screen abscissa; the report writes `− z_t sin θ`: its θ turns
//!   the other way), `z_e = z_t cos θ − x_t sin θ` (screen depth, toward the camera);
//! * conversely `x_t = x_e cos θ − z_e sin θ`, `z_t = x_e sin θ + z_e cos θ`.
//!
//! The ray of screen abscissa `X`, seen in the view frame, is the line `x_t cos θ + z_t sin θ = X`.
//! Leaving the camera (`z_e` decreasing) it moves by `(+sin θ, −cos θ)` in `(x_t, z_t)`:
//!
//! * **the march runs toward +x_t for θ ≥ 0 and toward −x_t for θ < 0**; along one ray, nearer
//!   points have smaller `x_t` when θ > 0 (larger when θ < 0);
//! * hence back-to-front direct warping visits texels by **decreasing** `x_t` for θ ≥ 0 and by
//!   increasing `x_t` for θ < 0 (the report's orders, mirrored with its θ);
//! * a height-field piece is seen from the front (its upward normal faces the camera) exactly when
//!   its projection keeps its orientation, `dx_e/dx_t = cos θ + s·sin θ > 0` (`s` its slope).
//!
//! Bounds of the march, `x1` where it starts and `x2` where it gives up:
//!
//! * bounding cylinder (radius `R'`, see [`ParallaxImages::march_radius`]): `h = √(R'² − X²)`,
//!   `x1 = X cos θ − h sin θ`, `x2 = X cos θ + h sin θ`;
//! * the family `x_t = f_θ(v) = (1 + c(1 − cos θ))·X − v·sin θ` with
//!   `v(θ) = z_e(θ) + (1 + c)·X·tan(θ/2)`, identically (`tan(θ/2)·sin θ = 1 − cos θ`);
//!   `f_θ` decreases in `v` for θ > 0 and increases for θ < 0, so `x1 = f_θ(v_max)`,
//!   `x2 = f_θ(v_min)` bracket the crossing whenever `v_min ≤ v(θ) ≤ v_max`. `c = −1` gives
//!   `v = z_e` (**zmin/zmax**), `c = +1` the report's `(2 − cos θ)·x_e` function.
//!
//! ## The height field each view stands for
//!
//! Row by row, texel `i` (centre `x_i = −R + (i + ½)δx`, `δx = 2R/Lx`) owns the abscissae
//! `[x_i − δx/2, x_i + δx/2]`. On a side where its neighbour is defined and the depth jump is at
//! most the continuity threshold, the surface is the straight segment between the two texel centres
//! (split at the cell boundary, attributes interpolated linearly); on a side without such a
//! neighbour it is flat at `z_i` (so isolated texels and silhouettes keep their half texel; with
//! [`Brim::Tangent`] that half piece drops along the normal's tangent instead). Walls
//! between disconnected texels are **not** surface: a ray that passes under a front piece through
//! a gap goes on to what lies behind, exactly as direct warping leaves the gap undrawn. A ray hits
//! a piece `(a, b)` (`x_a < x_b`) iff `x_e(a) ≤ X < x_e(b)` — the same half-open test in both
//! warps, so direct and inverse warping agree exactly, and at θ = 0 pixel centres fall on texel
//! centres and reproduce the capture bit for bit.
//!
//! ## Steps
//!
//! The march visits the **cells** `[x_c, x_{c+1}]` between consecutive texel centres (the two end
//! cells are half cells reaching `±R`), one cell — one new texel fetch — per step, from the cell of
//! `x1` toward the cell of `x2`, and stops in the cell where the ray first crosses a front-facing
//! piece (the crossing is then exact, by intersecting the ray with the piece). A fragment whose
//! stored bounds are empty costs 0 steps.
//!
//! Geometry, warping and bounds run in `f64`; stored data are quantised (colour and normal 8 bits,
//! depth 8 or 16 bits, bounds 8, 16 or 32 bits) and every warp uses the stored values.

pub mod asset;
mod baselines;
mod bounds;
mod images;
mod measure;
mod warp;

pub use baselines::{render_blend_baseline, render_blend_baseline_with, render_offset_baseline};
pub use bounds::{
    BoundKind, BoundParams, Bounds, PixelBound, ViewStorage, build_bounds, dense_sweep,
};
pub use images::{Brim, ParallaxImages, ParallaxParams, View, ViewCodes, normal_code};
pub use measure::{
    QualityParams, QualityRow, StepStats, StepsReport, SweepRow, Variant, measure_quality,
    measure_quality_sweep, measure_steps,
};
pub use warp::{
    BoundedRender, CARVE_DEPTH_TEXELS, Crossing, DOUBTFUL_FALLBACK_COVERAGE, MarchResult,
    Reconstruction, RenderParams, RowFilter, WarpMethod, cylinder_range, march, render,
    render_bounded, render_bounded_with, render_with, warp_row_direct, warp_view,
};

use altrep_data_gen::DataGenError;

use crate::metrics::MetricsError;
pub use crate::metrics::{ErrorSplit, error_split};

/// What went wrong while building, warping or measuring images with parallax.
#[derive(Debug, thiserror::Error)]
pub enum ParallaxError {
    /// A parameter is outside its valid range.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value, as given.
        value: String,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// The captured grids handed to [`ParallaxImages::from_grids`] do not fit the parameters.
    #[error("view {view}: {reason}")]
    InconsistentView {
        /// Index of the offending view.
        view: usize,
        /// What does not fit.
        reason: String,
    },
    /// No view sees the object: every captured view is empty (for example a horizontal flat
    /// object seen edge-on by horizontal views). Nothing can be represented or measured.
    #[error(
        "nothing visible: all {views} captured views are empty (is the object flat and horizontal?), so there is nothing to represent or measure"
    )]
    NothingVisible {
        /// Views captured.
        views: usize,
    },
    /// Capture or ground truth failed.
    #[error(transparent)]
    DataGen(#[from] DataGenError),
    /// An image comparison failed.
    #[error(transparent)]
    Metrics(#[from] MetricsError),
    /// A mip pyramid could not be built.
    #[error(transparent)]
    Mip(#[from] crate::mip::MipError),
}

/// Checks that `x` is finite.
fn finite(name: &'static str, x: f64) -> Result<f64, ParallaxError> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(invalid(name, x, "must be finite"))
    }
}

/// Checks that `index < len`.
fn in_range(name: &'static str, index: usize, len: usize) -> Result<usize, ParallaxError> {
    if index < len {
        Ok(index)
    } else {
        Err(ParallaxError::InvalidParameter {
            name,
            value: index.to_string(),
            reason: "is out of range",
        })
    }
}

fn invalid(
    name: &'static str,
    value: impl std::fmt::Display,
    reason: &'static str,
) -> ParallaxError {
    ParallaxError::InvalidParameter {
        name,
        value: value.to_string(),
        reason,
    }
}
