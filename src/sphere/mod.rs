//! # Images with parallax from any direction (docs/design.md §7b)
//!
//! The views of [`crate::parallax`] turn about the vertical axis only. Here an object is stored
//! as orthographic **frames over the sphere or the upper hemisphere**, on the octahedral grids
//! that engine impostors use ([`ViewSet`]), each frame holding albedo, normal and depth per texel
//! ([`SphereImages`]). A new direction is drawn from its three enclosing frames by an **exact
//! inverse warp** ([`render`]): the viewing ray projects to a straight line in each frame, which
//! is marched texel by texel through the frame's depth map, between per-texel bounds valid for
//! every direction that uses the frame ([`ConeBounds`]); the three frames are combined by
//! carving free space (below). The engines' method is the baseline ([`render_engine_baseline`]):
//! the same three frames, blended with barycentric weights, each offset once by its depth, read
//! as engine bakers pad it (renormalised over defined texels, the nearest defined depth beyond
//! the outline); [`render_engine`] with [`EngineSteps::Two`] offsets twice.
//! [`measure`] compares both against the ray-cast ground truth over many directions.
//!
//! ## Conventions (written once, here)
//!
//! * Directions are unit vectors **toward the camera**, in the object frame of data-gen (`y`
//!   up). A frame along `d` is data-gen's [`OrthoFrame`] over the object's bounding sphere:
//!   screen `X` along `right = normalize(ŷ × d)`, `Y` along `up = d × right`, depth `Z` along
//!   `d`, all divided by the sphere radius, so the sphere is the unit ball and a frame of
//!   `F × F` texels covers `[−1, 1]²` (texel pitch `2/F`, row 0 at the top).
//! * **Octahedral coordinates** `e = (e₀, e₁) ∈ [−1, 1]²` of a direction `d = (x, y, z)`:
//!   with `a = x/s`, `b = z/s`, `s = |x| + |y| + |z|`,
//!   - upper hemisphere (hemi-octahedral, `y ≥ 0`): `e = (a + b, a − b)`; the square's border is
//!     the horizon and its centre the zenith;
//!   - whole sphere (octahedral): `e = (a, b)` for `y ≥ 0`, folded to
//!     `((1 − |b|)·sign a, (1 − |a|)·sign b)` for `y < 0`; the border is the nadir's diamond.
//! * A **grid** of `G × G` frames puts frame `(i, j)` at `e = (−1 + 2i/(G − 1), −1 + 2j/(G − 1))`
//!   (frames on the border included, as engines do); frame index `k = j·G + i`.
//! * **Enclosing frames** of a direction: its grid cell `(i, j)` and fractions `(f₀, f₁)`; the
//!   cell splits along its anti-diagonal: `f₀ + f₁ ≤ 1` uses the corners `(i, j)`, `(i+1, j)`,
//!   `(i, j+1)` with barycentric weights `(1 − f₀ − f₁, f₀, f₁)`, otherwise `(i+1, j+1)`,
//!   `(i, j+1)`, `(i+1, j)` with `(f₀ + f₁ − 1, 1 − f₀, 1 − f₁)`.
//! * The **cone** of frame `k` is the set of directions whose enclosing triangle has `k` as a
//!   corner; its half-angle `β_k` is measured from the triangles' edges ([`ViewSet::cone_angle`]).
//!
//! ## The line a viewing ray makes in a frame
//!
//! Take display direction `d` and a stored frame `(right_k, up_k, d_k)` with `c = d·d_k > 0`.
//! The display ray through screen point `(x, y)` is `p(z) = x·right + y·up + z·d` for display
//! depth `z` decreasing from the camera. In frame `k` its depth is `Z_k(z) = p(z)·d_k`, which
//! decreases with `z` at rate `c`, and its screen position is the straight line
//! `P_k(Z) = q_k + Z·t_k`, `t_k = (d·right_k, d·up_k)/c`, `|t_k| = tan ∠(d, d_k)`, `q_k` the
//! point where the ray crosses the frame's plane `Z = 0`.
//!
//! ## The surface each frame stands for, and the march
//!
//! Texel `(i, j)` (if defined) owns the square cell of its footprint and stands for the plane
//! `H(P) = h + g·(P − P_c)` over it: `h` the stored depth at the texel centre `P_c`, `g` the
//! slope from the stored normal (`g = −(n_X, n_Y)/n_Z` in frame axes, each component clamped to
//! `±max_slope`; `g = 0` for [`SurfaceModel::Flat`]). A point `(P, Z)` of frame `k` is **free**
//! when its cell is undefined or `Z > H(P)` (between the frame's camera and the surface it
//! stores); otherwise it is hidden from frame `k` (inside the object, or behind what the frame
//! sees).
//!
//! The march runs down the line from the upper bound to the lower bound (below), visiting the
//! cells the line crosses in order (2D DDA, one texel fetch — one **step** — per cell), and stops
//! at the first point that is not free: an **event**. Inside a defined cell the ray either crosses
//! the cell's plane from above (a point of the stored surface, found exactly by intersecting the
//! line with the plane) or enters the cell through a side already below its plane (it passes
//! behind an edge that occludes it from the frame, or meets a step of the staircase the planes
//! make on a slope).
//!
//! ## Combining the enclosing frames: carving free space
//!
//! A point that any frame sees as free is free (the frame's camera sees through it). Each frame
//! is marched to its first event; the deepest event along the display ray is a candidate, and
//! every other frame is asked (one fetch) whether the candidate is free for it (the frame whose
//! event it is holds it hidden by definition: asking it again would decide a point on a cell
//! edge by rounding, and the carving would stall there); if one is, the frames march on from
//! there, and so on (at most [`MAX_CARVE_ROUNDS`] rounds). A frame that meets no
//! event makes the whole ray free: the pixel is empty. At the surface point found, the colour is
//! the barycentric blend of the frames that **see** it (their surface lies within
//! `visibility` texel pitches of it), each bilinearly filtered at the hit and shaded from its
//! normal. Where none of the three sees it, up to [`SphereRenderParams::extra_frames`] more frames
//! are asked in turn, the nearest to the display direction first: one that sees the point
//! colours it (with a small weight, 1e-3, beside any enclosing frame that then sees it too); one
//! that sees through it joins the carving, marched along its whole chord (its bounds hold only
//! for its own cone of directions), and the carving resumes from the point. Where still no
//! frame sees it (a hole: through the openings of a see-through shell the ray reaches space
//! that no enclosing frame looks into, which carving cannot clear; or a point deep in a
//! concavity) the ray is drawn as the engine blend draws it, from the enclosing frames'
//! one-step offsets, each frame's depth read where the march stopped ([`HoleFill::Offsets`], the
//! default; a ray stopped by the cap on fetches is drawn so too). [`HoleFill::Nearest`] colours
//! it instead from the frame surface nearest above it, if that surface lies within the hole
//! depth (half the radius by default, [`SphereRenderParams::hole_depth`]); farther, the ray is
//! taken as empty.
//!
//! ## Bounds for a cone of directions
//!
//! An event at depth `Z` lies on the closure of some defined cell `c` with
//! `Z ∈ [lo_c, hi_c]`: `hi_c` is the largest value of the cell's plane; `lo_c` the smallest of it
//! and of its defined 4-neighbours' planes (a side entry comes from a neighbour where the ray was
//! above that neighbour's plane), or `−1` (the sphere) when a neighbour is undefined (the ray may
//! slip under a silhouette at any depth). Its point is `q + Z·t` with `|t| ≤ tan β_k`, so
//! `dist(q, c) ≤ |Z|·tan β_k`. Hence, for every direction of the cone and every `q` in texel
//! `Q`: `Z ∈ [zmin_Q, zmax_Q]`, the extreme values `Z ∈ [lo_c, hi_c]` with
//! `|Z| ≥ dist(Q, c)/tan β_k` over all cells `c`. Above `zmax` the ray is free; below `zmin` no
//! event can start. This is exact interval reasoning, not sampling: the bounds are conservative
//! by construction, and quantised outward to 8 bits. [`check_bounds`] confirms it on a sweep ten
//! times finer than the evaluation. The one exception, a ray already hidden where it enters the
//! bounding sphere, is not a transition: [`render`] checks it with one fetch before using the
//! bounds.
//!
//! Measured limit: the `−1` of silhouette cells reaches every texel within `tan β_k` of an
//! outline, which on small grids is most of the object, so the bounds save little (chair, 4 × 4
//! frames of 32²: 17.16 against 17.92 fetches per ray, `cargo test --test integration sphere:: --
//! --nocapture`). Bounding slips separately from surface events is the next step; a first
//! attempt that marched the rest of the ray only where needed changed the picture and was
//! withdrawn.

pub mod asset;
mod baseline;
mod bounds;
mod compress;
mod frames;
mod measure;
mod viewset;
mod warp;

pub use baseline::{EngineSteps, render_engine, render_engine_baseline};
pub use bounds::{BoundsCheck, ConeBounds, check_bounds};
pub use compress::{CompressedFrames, Storage, compress};
pub use frames::{Frame, FrameCodes, SphereImages, SphereParams, SurfaceModel};
pub use measure::{
    BudgetRow, MethodStats, SphereMeasureParams, SphereMeasurement, budget_table,
    fibonacci_directions, measure, measure_one_step, measure_stored, truth_images,
};
pub use viewset::{Coverage, ViewSet, azimuth_elevation};
pub use warp::{
    DEFAULT_EXTRA_FRAMES, DEFAULT_HOLE_DEPTH, EnclosingFrame, HoleFill, MAX_CARVE_ROUNDS,
    MAX_EXTRA_FRAMES, RenderOutput, SphereRenderParams, enclosing_frames, extra_frames, render,
};

use altrep_data_gen::DataGenError;
#[cfg(doc)]
use altrep_data_gen::OrthoFrame;

use crate::metrics::MetricsError;

/// What can go wrong with any-direction images.
#[derive(Debug, thiserror::Error)]
pub enum SphereError {
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
    /// No frame sees anything: the object is empty or outside its bounding sphere.
    #[error("nothing visible: all {frames} captured frames are empty")]
    NothingVisible {
        /// Frames captured.
        frames: usize,
    },
    /// Along one measured direction neither the truth nor the drawing shows anything (or, for
    /// the silhouette, covers a pixel by more than half): no error can be measured there.
    #[error(
        "nothing to compare at elevation {elevation_deg:.1}°, azimuth {azimuth_deg:.1}°: at {size}² \
         neither the truth nor the drawing covers a pixel{what}; the object is too small there or \
         seen edge-on (measure at a larger size or along other directions)"
    )]
    EmptyView {
        /// The direction's elevation (degrees, `y` up).
        elevation_deg: f64,
        /// Its azimuth (degrees, from `x` toward `z`).
        azimuth_deg: f64,
        /// The pictures' side (pixels).
        size: usize,
        /// What was missing beyond no pixel at all ("" or " by more than half").
        what: &'static str,
    },
    /// Capture or ground truth failed.
    #[error(transparent)]
    DataGen(#[from] DataGenError),
    /// An image comparison failed.
    #[error(transparent)]
    Metrics(#[from] MetricsError),
}

/// A typed error for a parameter that fails `ok`.
pub(crate) fn check(
    ok: bool,
    name: &'static str,
    value: impl std::fmt::Display,
    reason: &'static str,
) -> Result<(), SphereError> {
    if ok {
        Ok(())
    } else {
        Err(SphereError::InvalidParameter {
            name,
            value: value.to_string(),
            reason,
        })
    }
}
