//! # Cylindrical textures (docs/design.md §6; chapter 3 of Baboud's report)
//!
//! An object is stored as one column of samples per capture angle: column `c` of `L` holds, for
//! each of `Ly` heights, the first hit of a horizontal ray from the bounding cylinder toward the
//! axis — albedo, normal and **signed radius** — or undefined ([`CylindricalTexture`]). Drawing it
//! from a camera at angle `α` is a 1D warp of each row ("slice"):
//!
//! * [`ExactMethod::Mesh`] — the reference: the triangle mesh of the samples, rasterised;
//! * [`ExactMethod::Direct`] — direct warping, sector by sector, back to front or front to back
//!   with coverage, in the simple model (positive radii only) or the general one;
//! * [`ExactMethod::Inverse`] — per pixel, march the sectors front to back (the shader
//!   algorithm without precomputation), counting steps;
//! * [`OffsetTexture`] — the precomputation: the column offset `k(x, y, α)` the march finds,
//!   fitted by the trilinear least-squares fit ([`crate::fit`]) so that a shader gets it from one
//!   3D-texture fetch; validated and optionally refined by a few exact steps (hybrid).
//!
//! * [`MarchBounds`] — beyond the source: per cell of (abscissa, rows, angle) a conservative
//!   range of march positions where the first hit can lie, so that an exact march starts next
//!   to the surface and stops past the last candidate: the exact picture at a few steps.
//!
//! [`coverage`] refuses objects the representation cannot hold (a flat cut-out holding the axis);
//! [`evaluate`] measures all of them against the ray-cast ground truth.
//!
//! ## Conventions (derived once here; the tests against the ground truth decide)
//!
//! Units: radii, screen abscissae and depths in units of `R`; angles in radians; columns and
//! offsets in texels. The functions of [`frame`] hold every formula below.
//!
//! * Column `c` is captured at `α_c = c·dα`, `dα = 2π/L`; **`L` must be even**. Its sample of row
//!   `j` is the point `p = r·R·d(α_c) + y_j·ŷ` (`y_j = H − (j + ½)H/Ly`): a negative `r` lies on
//!   the opposite half-line `α_c + π`, beyond the axis.
//! * The camera at angle `α` looks along `−d(α)` (data-gen's convention). Screen abscissa
//!   `x = r·sin(α − α_c)`, depth toward the camera `z = r·cos(α − α_c)`.
//! * A screen ray at abscissa `x` (`|x| ≤ 1`) meets the points of polar angle `β` from
//!   `β_front = α − asin x` to `β_back = α − π + asin x` (`x ≥ 0`, the **right half**: `β`
//!   decreases along the ray) or `β_back = α + π + asin x` (`x < 0`, the **left half**: `β`
//!   increases). Because `β` is monotonic along every ray, the **sectors** (wedges
//!   `[α_s, α_{s+1}]`) are met in a fixed order: front to back is decreasing `s` on the right
//!   half and increasing `s` on the left half. The two halves cannot hide each other; the sectors
//!   that straddle the dividing line belong to both and are clipped. This is the report's `k0`:
//!   the march starts in the sector holding `β_front`.
//! * Sector `s` holds at most two edges: the **outer** edge between columns `s` and `s + 1` (both
//!   radii positive) and the **inner** edge between columns `s + L/2` and `s + L/2 + 1` (both
//!   negative). With 0, 1 or 2 samples on each bounding half-line this gives the report's nine
//!   configurations ([`SliceView::sector_edges`]). Samples with radii of both signs are never
//!   joined.
//! * **Facing.** An edge from column `a` to `b = a + 1` is traversed counter-clockwise; its
//!   outward normal is `σ·(e_z, −e_x)` with `σ = +1` for an outer edge and `−1` for an inner one
//!   (inner surfaces face the axis). Its dot product with `d(α)` is `σ·(x_a − x_b)`, so an edge
//!   is visible iff **`σ·(x_a − x_b) > 0`** — the same rule on both halves. An edge that covers
//!   abscissa `x` is crossed by the ray at `x` inside its sector, so the first visible covering
//!   edge in march order is the visible surface.
//! * **Offset.** `k(x, y, α) = u − α/dα`, wrapped into `[−L/2, L/2)`, where `u` is the fractional
//!   column (texture abscissa) of the visible point; `k = 0` is the column facing the camera,
//!   `k < 0` on the right half for positive radii (`k ≈ −asin(x/r)/dα` for a disc of radius
//!   `r`). Undefined outside the silhouette.
//! * **Rows.** A screen row at height `y` reads the continuous row `v = (H − y)/Δy − ½`, clamped
//!   to `[0, Ly − 1]`; between rows the slice interpolates radius, albedo and normal where both
//!   rows are defined with radii of one sign (exactly the vertical edges of the reference mesh).
//!
//! ## Cost
//!
//! Texture: `8·L·Ly` bytes (two RGBA8 textures, 128 KiB at 256 × 64). Inverse warping: up to
//! `L/2 + 1` sector tests per pixel. Offset texture: `Ax·(Ay + 1)·Aα` coefficients (α periodic),
//! 2 bytes each at 16 bits.

pub mod asset;
mod bounds;
mod coverage;
mod eval;
pub mod frame;
mod offset;
mod render;
mod texture;
mod warp;

pub use bounds::{BoundsParams, BoundsReport, MarchBounds};
pub use coverage::{
    AngleCoverage, CoverageParams, CoverageReport, check_coverage, coverage, radial_visibility,
};
pub use eval::{
    CylinderSweepRow, EvalParams, EvalReport, MethodRow, MinificationRow, OffsetError, SWEEP_GRIDS,
    evaluate, minification, sweep, sweep_markdown,
};
pub use offset::{
    FitSupport, LambdaRule, LambdaTrial, OffsetMode, OffsetParams, OffsetReport, OffsetSamples,
    OffsetTexture, SilhouetteMask, sample_offsets,
};
pub use render::{CylinderRender, CylinderRenderParams, ExactMethod, render_exact};
pub use texture::{CylindricalTexture, RowPyramid, Slice, Texel};
pub use warp::{DrawOrder, Edge, Fragment, RadiusModel, SliceView};

use altrep_data_gen::{DataGenError, Projection};

use crate::fit::FitError;
use crate::metrics::MetricsError;

/// What went wrong in building, fitting, rendering or measuring a cylindrical texture.
#[derive(Debug, thiserror::Error)]
pub enum CylinderError {
    /// Capture or ground truth failed.
    #[error(transparent)]
    DataGen(#[from] DataGenError),
    /// The row pyramid could not be built.
    #[error(transparent)]
    Mip(#[from] crate::mip::MipError),
    /// The offset fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// An image comparison failed.
    #[error(transparent)]
    Metrics(#[from] MetricsError),
    /// The column count is odd or below 4.
    #[error("a cylindrical texture needs an even number of columns, at least 4; got {columns}")]
    Columns {
        /// The column count given.
        columns: usize,
    },
    /// The sample grid is not a cylindrical capture.
    #[error("the sample grid is not a cylindrical capture (projection {projection:?})")]
    NotCylindrical {
        /// Its projection.
        projection: Projection,
    },
    /// A captured sample is NaN, infinite or has a radius outside `[−1, 1]`.
    #[error("sample at column {column}, row {row} is not finite or outside the cylinder")]
    BadSample {
        /// Column.
        column: usize,
        /// Row.
        row: usize,
    },
    /// A size is zero.
    #[error("{what} must be at least 1")]
    ZeroSize {
        /// Which size.
        what: &'static str,
    },
    /// Radial capture rays hold too little of the object's visible surface
    /// ([`radial_visibility`]): they see only the parts whose slices are star-shaped around the
    /// axis.
    #[error(
        "the cylindrical texture cannot represent this object: radial capture rays hold {:.1} % of the surface the views see (threshold {:.0} %); they see a slice only where it is star-shaped around the axis (a flat cut-out holding the axis is seen only at the axis). Use images with parallax instead (`altrep parallax`)",
        100.0 * share,
        100.0 * min_share
    )]
    NotRepresentable {
        /// Share of the visible surface the capture rays hold, `[0, 1]`.
        share: f64,
        /// The threshold it fell below.
        min_share: f64,
    },
    /// No camera angle sees the object: the ground truth is empty at every angle measured (for
    /// example a horizontal flat object seen edge-on by horizontal views).
    #[error(
        "nothing visible: the object's ground truth is empty at all {angles} horizontal view angles, so there is nothing to represent or measure (is it flat and horizontal?)"
    )]
    NothingVisible {
        /// Angles measured.
        angles: usize,
    },
    /// A parameter is outside its range.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: String,
        /// What it must satisfy.
        reason: &'static str,
    },
}
