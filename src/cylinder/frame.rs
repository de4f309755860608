//! The conventions of cylindrical textures as small named functions (see the module docs for the
//! derivation). Every other file of the module calls these instead of repeating the formulas.
//!
//! Units: angles in radians; radii, screen abscissae and depths in units of the cylinder radius
//! `R` (so in `[−1, 1]`); columns and offsets in texels (columns of the texture).

use std::f64::consts::{PI, TAU};

use altrep_data_gen::BoundingCylinder;

/// Angular pitch between columns, `dα = 2π / L`.
#[inline]
pub fn angular_pitch(columns: usize) -> f64 {
    TAU / columns as f64
}

/// Angle of the (fractional) column `u`: `α_u = u·dα`.
#[inline]
pub fn column_angle(u: f64, columns: usize) -> f64 {
    u * angular_pitch(columns)
}

/// Screen abscissa, in units of `R`, of the sample of signed radius `r` captured at angle `beta`,
/// seen by the camera at angle `alpha`: `x = r·sin(α − β)` (the data-gen convention
/// `x = p·right(α)`, `right(α) = (sin α, 0, −cos α)`).
#[inline]
pub fn screen_x(r: f64, beta: f64, alpha: f64) -> f64 {
    r * (alpha - beta).sin()
}

/// Depth toward the camera, in units of `R`, of the same sample: `z = r·cos(α − β)` (larger is
/// nearer).
#[inline]
pub fn depth(r: f64, beta: f64, alpha: f64) -> f64 {
    r * (alpha - beta).cos()
}

/// Column offset `k = u − α/dα`, wrapped into `[−L/2, L/2)` texels: 0 for the column that faces
/// the camera, negative on the right half of the screen for positive radii.
#[inline]
pub fn column_offset(u: f64, alpha: f64, columns: usize) -> f64 {
    let l = columns as f64;
    (u - alpha / angular_pitch(columns) + 0.5 * l).rem_euclid(l) - 0.5 * l
}

/// The column named by offset `k` seen from `alpha`: `u = (α/dα + k) mod L`, in `[0, L)`.
#[inline]
pub fn offset_column(k: f64, alpha: f64, columns: usize) -> f64 {
    let l = columns as f64;
    let u = (alpha / angular_pitch(columns) + k).rem_euclid(l);
    // rem_euclid can round up to `l` for tiny negative inputs.
    if u >= l { 0.0 } else { u }
}

/// Continuous row coordinate of height `y` (world units): `v = (H − y)/Δy − ½`, so that row
/// `j`'s centre `y_j = H − (j + ½)Δy` has `v = j`. Not clamped.
#[inline]
pub fn row_coordinate(y: f64, cylinder: &BoundingCylinder, rows: usize) -> f64 {
    (cylinder.height - y) * rows as f64 / cylinder.height - 0.5
}

/// The sectors a screen ray crosses inside the bounding cylinder, front to back.
///
/// The ray at abscissa `x` (units of `R`) meets the points of polar angle `β` from
/// `β_front = α − asin x` to `β_back = α − π + asin x` (right half, `x ≥ 0`, `β` decreasing) or
/// `β_back = α + π + asin x` (left half, `x < 0`, `β` increasing). Sector `s` is the wedge
/// `[α_s, α_{s+1}]`; along the ray the sectors come in order `first, first + step, …`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RaySectors {
    /// The first sector (may be any integer; reduce it modulo `L` with [`sector_index`]).
    pub first: i64,
    /// `−1` on the right half (`x ≥ 0`), `+1` on the left half.
    pub step: i64,
    /// Number of sectors the ray crosses (0 when `|x| > 1`).
    pub count: usize,
}

/// The sectors crossed by the ray at abscissa `x` seen from `alpha` (see [`RaySectors`]).
/// This is the source's `k0 = ⌈asin(x/R)/dα⌉` in our sign conventions. Cost: O(1).
pub fn ray_sectors(x: f64, alpha: f64, columns: usize) -> RaySectors {
    if x.is_nan() || x.abs() > 1.0 {
        return RaySectors {
            first: 0,
            step: 1,
            count: 0,
        };
    }
    let da = angular_pitch(columns);
    let front = alpha - x.asin();
    let (back, step) = if x >= 0.0 {
        (alpha - PI + x.asin(), -1)
    } else {
        (alpha + PI + x.asin(), 1)
    };
    let first = (front / da).floor() as i64;
    let last = (back / da).floor() as i64;
    RaySectors {
        first,
        step,
        count: ((last - first) * step) as usize + 1,
    }
}

/// Reduces a sector or column number modulo `L` into `[0, L)`.
#[inline]
pub fn sector_index(s: i64, columns: usize) -> usize {
    s.rem_euclid(columns as i64) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn screen_x_matches_data_gen_right_vector() {
        let (r, beta, alpha) = (0.7, 1.1, 0.3);
        let p = r * altrep_data_gen::direction(beta);
        let x = p.dot(altrep_data_gen::screen_right(alpha));
        assert!((x - screen_x(r, beta, alpha)).abs() < 1e-12);
        let z = p.dot(altrep_data_gen::direction(alpha));
        assert!((z - depth(r, beta, alpha)).abs() < 1e-12);
    }

    #[test]
    fn offsets_wrap_and_invert() {
        for &(u, alpha) in &[(3.25, 0.0), (250.5, 0.1), (0.0, 6.2), (128.0, 3.0)] {
            let k = column_offset(u, alpha, 256);
            assert!((-128.0..128.0).contains(&k));
            assert!((offset_column(k, alpha, 256) - u).abs() < 1e-9);
        }
    }

    #[test]
    fn ray_sectors_cover_the_chord() {
        let l = 256;
        // Through the axis: half a turn, L/2 + 1 sectors, front sector the camera's.
        let s = ray_sectors(0.0, 0.5 * angular_pitch(l), l);
        assert_eq!((s.first, s.step, s.count), (0, -1, 129));
        // Near the silhouette the chord is short.
        let s = ray_sectors(-0.999, 0.0, l);
        assert_eq!(s.step, 1);
        assert!(s.count < 16);
        assert_eq!(ray_sectors(1.5, 0.0, l).count, 0);
        assert_eq!(ray_sectors(f64::NAN, 0.0, l).count, 0);
    }
}
