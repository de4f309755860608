//! Slice directions and how many slices a view needs (Meyer & Neyret 1998, §4.1–4.2).
//!
//! * **Criterion.** With slice spacing `h`, view angle `a` from the slice normal and the depth
//!   `d` (world units) the user accepts to see into an object (`d ≤ e/2`, `e` the feature
//!   width), the view is right when `h·tan a / d ≤ 1`: a stack of length `L` needs
//!   `n ≥ L·tan a / d` slices ([`slices_needed`]).
//! * **Direction.** With `c_i = |v·e_i|` and `h_i = L_i/N_i`, draw the axis minimising
//!   `(1/c_i² − 1)·h_i²` (that is `tan² a_i · h_i²`; [`choose_direction`]).
//! * **Level.** The coarsest merged level that still has at least the needed slices
//!   ([`level_for_slices`]).

use glam::DVec3;

use super::{SliceError, TexelVolume};

/// A slice direction: the axis normal to the slices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Axis {
    /// Slices normal to `x` (vertical, across the surface).
    X,
    /// Slices normal to `y` (parallel to the surface: Meyer & Neyret's default stack).
    Y,
    /// Slices normal to `z` (vertical, across the surface).
    Z,
}

impl Axis {
    /// All three, in index order.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// `0`, `1`, `2`.
    #[inline]
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }

    /// The two in-plane axes `(u, v)` of a slice texture: `(x, z)` for `Y`, `(z, y)` for `X`,
    /// `(x, y)` for `Z`. Texture column `i` is voxel `u = i`, row `j` is voxel `v = j`.
    #[inline]
    pub fn plane_axes(self) -> (usize, usize) {
        match self {
            Axis::X => (2, 1),
            Axis::Y => (0, 2),
            Axis::Z => (0, 1),
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        }
    }
}

/// Slices a stack of length `length` needs at view angle `angle` (radians, from the slice
/// normal; only `|cos|` matters) so that at most `depth` world units are seen into an object:
/// `max(1, ⌈length·tan a / depth⌉)`. A view in the slice planes (`cos a = 0`) needs
/// `usize::MAX`. Errors: non-finite or non-positive `length` or `depth`, non-finite angle.
pub fn slices_needed(length: f64, angle: f64, depth: f64) -> Result<usize, SliceError> {
    super::check_range("stack length", length, f64::MIN_POSITIVE, f64::MAX, "> 0")?;
    super::check_range("visible depth d", depth, f64::MIN_POSITIVE, f64::MAX, "> 0")?;
    super::check_range("view angle", angle, f64::MIN, f64::MAX, "finite")?;
    let c = angle.cos().abs();
    if c < 1e-12 {
        return Ok(usize::MAX);
    }
    let tan = (1.0 - c * c).max(0.0).sqrt() / c;
    let n = (length * tan / depth * (1.0 - 1e-12)).ceil();
    Ok(if n >= usize::MAX as f64 {
        usize::MAX
    } else {
        (n as usize).max(1)
    })
}

/// The largest level `k` (coarsest) whose `stored/2^k` slices are at least `needed`; 0 when even
/// level 0 has too few. `stored` is a power of two. Errors: `needed` above the voxel count
/// `stored` is [`SliceError::TooManySlices`] only when `strict`; otherwise level 0 is returned.
pub fn level_for_slices(
    axis: Axis,
    stored: usize,
    needed: usize,
    strict: bool,
) -> Result<usize, SliceError> {
    if stored == 0 {
        return Err(SliceError::ZeroSize {
            what: "stored slices",
        });
    }
    if needed > stored {
        if strict {
            return Err(SliceError::TooManySlices {
                axis,
                slices: needed,
                voxels: stored,
            });
        }
        return Ok(0);
    }
    let needed = needed.max(1);
    let mut k = 0;
    while (stored >> (k + 1)) >= needed && (stored >> (k + 1)) > 0 {
        k += 1;
    }
    Ok(k)
}

/// Errors: a view vector that is not finite or is (nearly) zero.
pub(crate) fn check_view(view: DVec3) -> Result<(), SliceError> {
    if !view.is_finite() || view.length_squared() < 1e-24 {
        return Err(SliceError::InvalidParameter {
            name: "view vector",
            value: format!("{view:?}"),
            reason: "must be finite and non-zero",
        });
    }
    Ok(())
}

/// Meyer & Neyret's direction rule: the axis minimising `(1/c_i² − 1)·h_i²`, `c_i = |view_i|` (view
/// a unit vector), `h_i = L_i/N_i` from `spacing`. Among `allowed` axes only; ties go to the
/// earliest allowed axis in `Y, X, Z` order. Errors: a non-finite or zero view vector, no allowed
/// axis.
pub fn choose_direction(
    view: DVec3,
    spacing: [f64; 3],
    allowed: [bool; 3],
) -> Result<Axis, SliceError> {
    check_view(view)?;
    let v = view.normalize();
    let mut best: Option<(Axis, f64)> = None;
    for axis in [Axis::Y, Axis::X, Axis::Z] {
        let i = axis.index();
        if !allowed[i] {
            continue;
        }
        let c = v[i].abs();
        let cost = if c < 1e-12 {
            f64::INFINITY
        } else {
            (1.0 / (c * c) - 1.0).max(0.0) * spacing[i] * spacing[i]
        };
        if best.is_none_or(|(_, b)| cost < b) {
            best = Some((axis, cost));
        }
    }
    best.map(|(a, _)| a).ok_or(SliceError::InvalidParameter {
        name: "allowed axes",
        value: format!("{allowed:?}"),
        reason: "at least one axis must be allowed",
    })
}

/// What a view draws: the axis, the level, the slices per tile and what the criterion asked.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ViewChoice {
    /// Slice direction.
    pub axis: Axis,
    /// Merge level (`N/2^level` slices).
    pub level: usize,
    /// Slices drawn per tile along that axis.
    pub slices: usize,
    /// Slices the criterion asked for (`usize::MAX` for a view in the slice planes).
    pub needed: usize,
}

/// Direction (by [`choose_direction`] among `allowed`) and level (by the criterion with visible
/// depth `depth`, world units) for the view vector `view`.
pub fn choose(
    volume: &TexelVolume,
    view: DVec3,
    depth: f64,
    allowed: [bool; 3],
) -> Result<ViewChoice, SliceError> {
    let dims = volume.dims();
    let s = volume.voxel_size();
    let axis = choose_direction(view, [s; 3], allowed)?;
    let v = view.normalize();
    let i = axis.index();
    let n = dims[i];
    let needed = slices_needed(n as f64 * s, v[i].abs().min(1.0).acos(), depth)?;
    let level = level_for_slices(axis, n, needed, false)?;
    Ok(ViewChoice {
        axis,
        level,
        slices: n >> level,
        needed,
    })
}
