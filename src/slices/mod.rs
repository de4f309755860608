//! # Volumetric textures as stacks of alpha slices (docs/design.md §9; Meyer & Neyret 1998)
//!
//! A **texel** is a small tileable reference volume (premultiplied RGBA, lighting baked) that is
//! repeated over a surface. It is drawn as a stack of alpha-blended textured slices composited
//! back to front. This module builds texel volumes ([`build`]), cuts them into stacks along the
//! three axes with **mipmapped slice merges** ([`build_slices`]: level `k` holds `N/2^k` slices,
//! each the composite of `2^k` layers, each slice also mip-mapped in 2D), chooses a direction and
//! a level per view ([`stack`]: the paper's criterion `h·tan a / d ≤ 1` and its direction rule
//! `argmin (1/c_i² − 1)·h_i²`), draws them on the CPU over a flat patch ([`render_slices`]) or
//! a curved one ([`curved`]: shells over a cylinder) and measures them against a ray-marched
//! ground truth of the same volume ([`render_truth`], [`measure()`]). A volume may also hold one
//! object instead of a tile ([`object`]): the pipeline's `[asset.slices]` ([`asset`]) voxelises
//! an asset's shape or mesh, writes its stacks as files and measures them against the object's
//! ray-cast ground truth.
//!
//! ## Conventions (written once here)
//!
//! * **Texel frame.** `y` is the height above the surface (docs/design.md §2: `y` vertical); `x`
//!   and `z` are the surface directions. Voxels are cubes of edge `s` (world units); a volume of
//!   `nx × ny × nz` voxels spans `[0, nx·s] × [0, ny·s] × [0, nz·s]`. Voxel `(x, y, z)` covers
//!   `[x·s, (x+1)·s] × …`, its centre is at `(x + ½, y + ½, z + ½)·s`, storage index
//!   `x + nx·(y + ny·z)` (as data-gen's voxel volumes). The volume **tiles** (is periodic) along
//!   `x` and `z`, never along `y`; the field is clamped below `y = s/2` and above `(ny − ½)·s`
//!   and is empty outside `y ∈ [0, ny·s]`.
//! * **Voxel values** are linear premultiplied RGBA `[r·a, g·a, b·a, a]`, where `a` is the opacity
//!   of a path of length `s` through the voxel's material. The continuous medium is the
//!   **trilinear** interpolation of these values between voxel centres; at a point with opacity
//!   `a` and premultiplied colour `C` the extinction is `σ = −ln(1 − a)/s` and the emitted colour
//!   `C/a` (emission–absorption model). That continuous medium is the ground truth
//!   ([`render_truth`] marches it with `truth_steps` samples per voxel length).
//! * **Slices.** Axis `i` ([`Axis`]) has `N_i` slices at level 0: slice `j` is voxel layer `j`,
//!   a 2D texture lying in the plane `q_i = (j + ½)·s`. Level `k` has `N_i/2^k` slices of spacing
//!   `h_k = 2^k·s`; slice `j` lies in the plane `q_i = (j + ½)·h_k` (the middle of the slab it
//!   replaces) and its alpha is the opacity of the whole slab at normal incidence. Volume
//!   dimensions must be powers of two.
//! * **Sides.** A viewer on the **plus side** of axis `i` (view vector `v` with `v_i > 0`, the
//!   camera looks along `−v`) sees higher slice indices in front. [`MergeRule::FrontOverBack`]
//!   composites a slab as seen from the plus side (upper layers over lower for the height axis:
//!   the view from above), [`MergeRule::BackOverFront`] as seen from the minus side,
//!   [`MergeRule::PerSide`] stores both and the renderer reads the one of the viewer's side,
//!   [`MergeRule::Symmetric`] stores the mean of the two (valid from both sides to first order).
//!   [`MergeRule::Drop`] is the baseline that keeps one layer in `2^k` (its opacity raised to the
//!   slab's thickness, `1 − (1 − a)^(2^k)`), not a merge. Every merge rule preserves opacity
//!   exactly: the alpha of `over` does not depend on the order.
//! * **Views** are orthographic ([`StackView`]): `polar` is the angle from `+y` (the surface normal),
//!   `azimuth` turns about `y` from `+x` toward `+z`: `v = (sin θ cos φ, cos θ, sin θ sin φ)`.
//!   Polar angles beyond 90° look from below. The screen basis is `right = (sin φ, 0, −cos φ)`,
//!   `up = v × right` (so `right × up = v`, data-gen's convention); pixel `(i, j)`, row 0 at the
//!   top, is centred at `centre + (−W/2 + (i + ½)·p)·right + (H/2 − (j + ½)·p)·up`.
//! * **Opacity correction.** A slice of alpha `a` (for thickness `h`) crossed at cosine `c`
//!   between the view and its normal is drawn with `a' = 1 − (1 − a)^(1/|c|)` and its colour
//!   scaled by `a'/a` (the path through the slab is `h/|c|`); [`SliceRenderParams::opacity_correction`]
//!   turns it off to draw as the paper's fixed-function hardware did.
//! * **Compositing.** The slices a ray crosses are composited with `over`, nearest last in the
//!   back-to-front formulation; the CPU renderer accumulates the equivalent front-to-back sum.
//!
//! ## Cost
//!
//! Bytes (RGBA8): level 0 of one axis is `4·nx·ny·nz` bytes; all levels of one axis about twice
//! that; 2D mip-maps add a third; [`MergeRule::PerSide`] doubles the merged levels. Building is
//! one pass over the volume per level (each merged texel composites `2^k` layers). Rendering: per
//! pixel sample, one bilinear fetch (or two with 2D mip-maps) per slice crossed; a view draws
//! `N_i/2^k` slice polygons per tile.

pub mod asset;
pub mod build;
pub mod curved;
pub mod direction;
pub(crate) mod filtered;
pub mod measure;
pub mod merge;
pub mod object;
pub mod render;
pub mod stack;
pub mod truth;
pub mod volume;

pub use build::{
    HeightField, HeightFieldParams, ImplicitParams, ShapeParams, SliceLighting, TestTile,
    from_height_field, from_implicit, from_shape, perlin_periodic, test_tile, test_tile_lit,
};
pub use curved::{CurvedParams, render_curved_slices, render_curved_truth};
pub use direction::{DirectionGrid, DirectionTable};
pub use measure::{
    CurvedRow, LevelRow, MeasureReport, RuleSummary, SliceMeasureParams, SliceSweepRow,
    TileSummary, ViewError, measure, view_errors,
};
pub use merge::{
    MergeRule, Side, SliceData, SliceParams, SliceReport, Stack, StoredStack, build_slices,
};
pub use object::{ObjectImage, choose_stored, render_object};
pub use render::{SliceRenderParams, StackView, render_slices};
pub use stack::{Axis, ViewChoice, choose, choose_direction, level_for_slices, slices_needed};
pub use truth::{VolumeTruthParams, render_truth};
pub use volume::{SliceReconstruction, TexelVolume};

use altrep_data_gen::DataGenError;

/// What went wrong in building, slicing, rendering or measuring a slice volume.
#[derive(Debug, thiserror::Error)]
pub enum SliceError {
    /// Voxelisation of a shape failed.
    #[error(transparent)]
    DataGen(#[from] DataGenError),
    /// A 2D pyramid could not be built.
    #[error(transparent)]
    Mip(#[from] crate::mip::MipError),
    /// An image comparison failed.
    #[error(transparent)]
    Metrics(#[from] crate::metrics::MetricsError),
    /// A size (volume dimension, image size, sample count) is zero.
    #[error("{what} must be at least 1, got 0")]
    ZeroSize {
        /// Which size.
        what: &'static str,
    },
    /// A volume dimension is not a power of two (slice merges halve it).
    #[error("volume dimension {axis:?} = {value} is not a power of two")]
    NotPowerOfTwo {
        /// The axis.
        axis: Axis,
        /// Its voxel count.
        value: usize,
    },
    /// A value (voxel, height, parameter) is NaN or infinite.
    #[error("{what} is not finite (index {index})")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// Index of the first offending element.
        index: usize,
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
    /// More slices were asked for than the axis has voxels.
    #[error("{slices} slices asked along {axis:?}, which has only {voxels} voxels")]
    TooManySlices {
        /// The axis.
        axis: Axis,
        /// Slices asked for.
        slices: usize,
        /// Voxels along that axis.
        voxels: usize,
    },
    /// The stack asked for was not built (axis or level left out by the parameters).
    #[error("no stack along {axis:?} at level {level} was built")]
    MissingStack {
        /// The axis.
        axis: Axis,
        /// The level.
        level: usize,
    },
}

/// `Err(InvalidParameter)` unless `value` is finite and inside `[lo, hi]`.
pub(crate) fn check_range(
    name: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    reason: &'static str,
) -> Result<(), SliceError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(SliceError::InvalidParameter {
            name,
            value: format!("{value}"),
            reason,
        })
    }
}
