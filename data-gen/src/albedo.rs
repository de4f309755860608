//! Surface colours of the procedural parts ([`Albedo`]): solid colours and the angular stripes,
//! with the fast stripe index and its bound.

use glam::{DVec3, Vec3};

/// Surface colour of a procedural part (linear RGB).
#[derive(Clone, Debug, PartialEq)]
pub enum Albedo {
    /// One colour.
    Solid(Vec3),
    /// A 3D checkerboard of cubic cells of side `cell` (world units).
    Checker {
        /// First colour.
        a: Vec3,
        /// Second colour.
        b: Vec3,
        /// Cell side.
        cell: f64,
    },
    /// `count` vertical stripes around the `y` axis (alternating by azimuth), which make angular
    /// warping errors visible.
    Stripes {
        /// First colour.
        a: Vec3,
        /// Second colour.
        b: Vec3,
        /// Number of stripe pairs around the axis.
        count: u32,
    },
    /// A façade: `glass` windows on a `wall`, storeys of height `storey`, windows every `pitch`
    /// along the horizontal coordinates.
    Windows {
        /// Wall colour.
        wall: Vec3,
        /// Window colour.
        glass: Vec3,
        /// Storey height (world units).
        storey: f64,
        /// Window pitch (world units).
        pitch: f64,
    },
}

impl Albedo {
    /// Colour at point `p`.
    pub fn at(&self, p: DVec3) -> Vec3 {
        match self {
            Albedo::Solid(c) => *c,
            Albedo::Checker { a, b, cell } => {
                let k = (p / *cell).floor();
                if (k.x + k.y + k.z).rem_euclid(2.0) < 0.5 {
                    *a
                } else {
                    *b
                }
            }
            Albedo::Stripes { a, b, count } => {
                if stripe(p.x, p.z, *count).rem_euclid(2) == 0 {
                    *a
                } else {
                    *b
                }
            }
            Albedo::Windows {
                wall,
                glass,
                storey,
                pitch,
            } => {
                let fy = (p.y / storey).fract();
                let fh = ((p.x + p.z) / pitch).rem_euclid(1.0);
                if (0.3..0.75).contains(&fy) && (0.25..0.75).contains(&fh) {
                    *glass
                } else {
                    *wall
                }
            }
        }
    }
}

/// The stripe of `(x, z)` among `2·count` equal sectors of azimuth: exactly
/// `⌊(atan2(z, x) + π)/τ · count · 2⌋`, the stripe index of [`Albedo::Stripes`].
///
/// Cost: a division and a polynomial where that is exact, a libm `atan2` elsewhere. The
/// polynomial [`atan_01`] is within [`ATAN_01_ERROR`] of `atan`; where the sector coordinate
/// it gives lies farther than the resulting error (×4) from a sector boundary, its floor is
/// the exact one. Closer to a boundary (one hit in about a thousand at `count = 10`), or for
/// non-finite input, the formula is evaluated as written.
#[inline]
fn stripe(x: f64, z: f64, count: u32) -> i64 {
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let exact = || (((z.atan2(x) + PI) / TAU) * f64::from(count) * 2.0).floor() as i64;
    let (ax, az) = (x.abs(), z.abs());
    // atan2(z, x) from atan on [0, 1]: the octant, then the quadrant by the signs.
    let mut phi = if az > ax {
        FRAC_PI_2 - atan_01(ax / az)
    } else {
        atan_01(az / ax)
    };
    if x < 0.0 {
        phi = PI - phi;
    }
    if z < 0.0 {
        phi = -phi;
    }
    let per_radian = f64::from(count) * 2.0 / TAU;
    let q = (phi + PI) * per_radian;
    // The polynomial's error in sector units, ×4 for the roundings of both formulas (each
    // far below 10⁻¹² of a sector at any count for which the margin is below ½).
    let margin = 4.0 * ATAN_01_ERROR * per_radian;
    // Truncation is the floor for `q ≥ 0`; a negative `q` gets `f < 0` and the exact path
    // (`floor` is a libm call without SSE4.1, the cast one instruction).
    let k = q as i64;
    let f = q - k as f64;
    // False for NaN (0/0 at the axis, non-finite input).
    if f > margin && f < 1.0 - margin {
        k
    } else {
        exact()
    }
}

/// A bound of `|atan_01(t) − atan(t)|` on `[0, 1]` (the fit's error is 1.14·10⁻⁵; the test
/// `atan_01_is_within_its_bound` samples it).
const ATAN_01_ERROR: f64 = 2e-5;

/// `atan(t)` for `t ∈ [0, 1]`, to within [`ATAN_01_ERROR`]: `t·P(t²)` with a least-squares
/// fit of degree 4 in `t²`.
#[inline]
fn atan_01(t: f64) -> f64 {
    let t2 = t * t;
    // Horner's scheme with separate products (`mul_add` is a libm call without the FMA target
    // feature).
    let p = 0.020845075041555403 * t2 - 0.08515628214383045;
    let p = p * t2 + 0.18015926445862113;
    let p = p * t2 - 0.3303047868422395;
    let p = p * t2 + 0.9998663310478215;
    t * p
}

#[cfg(test)]
mod tests {
    use std::f64::consts::{PI, TAU};

    use proptest::prelude::*;

    use super::*;

    /// The stripe index as [`Albedo::Stripes`] wrote it before the fast path.
    fn stripe_by_atan2(x: f64, z: f64, count: u32) -> i64 {
        let phi = z.atan2(x) + PI;
        (phi / TAU * f64::from(count) * 2.0).floor() as i64
    }

    #[test]
    fn atan_01_is_within_its_bound() {
        let n = 1_000_000;
        let worst = (0..=n)
            .map(|i| {
                let t = i as f64 / n as f64;
                (atan_01(t) - t.atan()).abs()
            })
            .fold(0.0, f64::max);
        println!("atan_01: largest error {worst:.3e} over {n} + 1 samples");
        assert!(worst <= 0.6 * ATAN_01_ERROR, "{worst:e}");
    }

    #[test]
    fn stripes_match_atan2_on_and_beside_every_boundary() {
        let mut checked = 0;
        for count in [1, 2, 3, 10, 64, 1000, 100_000] {
            for k in 0..=2 * count {
                // The boundary's angle and points a few roundings to ulps away either side.
                let phi = k as f64 * PI / f64::from(count) - PI;
                for eps in [-1e-4, -1e-7, -1e-12, -1e-15, 0.0, 1e-15, 1e-12, 1e-7, 1e-4] {
                    for r in [1e-300, 1e-3, 1.0, 7.5e5] {
                        let (x, z) = (r * (phi + eps).cos(), r * (phi + eps).sin());
                        assert_eq!(
                            stripe(x, z, count),
                            stripe_by_atan2(x, z, count),
                            "count {count}, ({x:e}, {z:e})"
                        );
                        checked += 1;
                    }
                }
            }
        }
        for (x, z) in [
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-0.0, -0.0),
            (-1.0, 0.0),
            (-1.0, -0.0),
            (1.0, 0.0),
            (f64::NAN, 1.0),
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, 1.0),
            (1.0, f64::INFINITY),
        ] {
            assert_eq!(stripe(x, z, 10), stripe_by_atan2(x, z, 10), "({x}, {z})");
        }
        assert!(checked > 100_000);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
        #[test]
        fn stripes_match_atan2_everywhere(
            x in prop_oneof![-1e3..1e3f64, any::<f64>()],
            z in prop_oneof![-1e3..1e3f64, any::<f64>()],
            count in prop_oneof![1..40u32, any::<u32>()],
        ) {
            prop_assert_eq!(stripe(x, z, count), stripe_by_atan2(x, z, count));
        }
    }
}
