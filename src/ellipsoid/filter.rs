//! Filtering: one ellipsoid standing for `k` weighted ellipsoids (building coarser octree levels).
//!
//! # The two rules
//!
//! Both average a symmetric positive-definite **moment matrix** `M(E)` with the weights (densities)
//! and turn the mean back into an ellipsoid with the eigen-solver:
//!
//! - [`FilterRule::Seed1995`]: `M = Q⁻¹ = R L² Rᵀ`, lengths `√λ` of the eigenvalues of the mean
//!   (Neyret 1995 writes `λ^{-2}` of `Q`'s eigenvalues; it is `λ^{-1/2}`, the same thing:
//!   docs/design.md §14).
//!   Motivation (Neyret 1995, §3.3.2): `f_Q` is homogeneous of degree 1 in `Q⁻¹`, so the sum of
//!   identical shapes is exact, and for two similar ellipsoids at angle θ the error is `O(sin² θ)`.
//! - [`FilterRule::Sggx`]: `M = S = π² det(Q⁻¹) Q = π² adj(Q⁻¹)`, the SGGX microflake matrix of
//!   Heitz, Dupuy, Crassin & Dachsbacher, *The SGGX Microflake Distribution* (SIGGRAPH 2015).
//!
//! # The mapping between SGGX and the ellipsoid
//!
//! SGGX defines `S = [ω₁ ω₂ ω₃] diag(σ₁², σ₂², σ₃²) [ω₁ ω₂ ω₃]ᵀ` where `σ(ω) = √(ωᵀSω)` is the
//! projected area of the microflakes along `ω`, and the distribution of normals
//! `D(m) = 1/(π √|S| (mᵀS⁻¹m)²)`. Our ellipsoid's projected area is `A(ω)² = π² det(Q⁻¹) ωᵀQω`, so
//! with `S = π² det(Q⁻¹) Q`:
//! - `σ(ω) = A(ω)` for every ω (σᵢ = π lⱼlₖ: the area seen along axis i);
//! - `|S| = π⁶ det(Q⁻¹)²`, `S⁻¹ = Q⁻¹/(π² det Q⁻¹)`, hence `D(m) = det(Q⁻¹)/(mᵀQ⁻¹m)² = f_Q(m)`:
//!   the SGGX distribution of that `S` *is* the ellipsoid's normal distribution, unnormalised
//!   (it integrates to the surface area). SGGX is homogeneous of degree ½ in `S` (`D` and `σ` scale
//!   by `√k` when `S` scales by `k`), so averaging `S` preserves identical shapes exactly too.
//! - Back: `det Q⁻¹ = √|S|/π³`, `Q = π S/√|S|`; in eigen terms `lᵢ = √(σⱼσₖ/(π σᵢ))`.
//!
//! The 1995 rule averages the shape's second moments (`Q⁻¹`); SGGX averages the squared projected
//! areas (`σ²`). Both keep the scale the average gives: a filtered ellipsoid is **not** renormalised,
//! so the result carries how much area the children present (densities × areas).
//!
//! # Degenerate means
//!
//! A mean of valid moments is positive definite, but its smallest eigenvalues can fall below what
//! the solver resolves (`ε λ_max`); they are floored at `MIN_ASPECT² λ_max` (= 1e-12 λ_max), the
//! anisotropy limit of [`Ellipsoid`].

use std::f64::consts::PI;

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use super::eigen::sym_eigen3;
use super::error::EllipsoidError;
use super::primitive::{Ellipsoid, MIN_ASPECT};
use super::quadrature::SphereQuadrature;
use super::rng::SplitMix64;

/// How to merge ellipsoids: which moment matrix is averaged. See the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FilterRule {
    /// Neyret 1995: weighted mean of `Q⁻¹`.
    Seed1995,
    /// SGGX (Heitz et al. 2015): weighted mean of `S = π² det(Q⁻¹) Q`.
    Sggx,
}

impl FilterRule {
    /// Both rules, in report order.
    pub const ALL: [FilterRule; 2] = [FilterRule::Seed1995, FilterRule::Sggx];

    /// Short name used in reports and JSON (`"seed1995"`, `"sggx"`).
    pub fn name(self) -> &'static str {
        match self {
            FilterRule::Seed1995 => "seed1995",
            FilterRule::Sggx => "sggx",
        }
    }

    /// The moment matrix this rule averages (`Q⁻¹` or `S`).
    pub fn moment(self, e: &Ellipsoid) -> Matrix3<f64> {
        match self {
            FilterRule::Seed1995 => e.inverse_form(),
            FilterRule::Sggx => e.sggx_matrix(),
        }
    }

    /// The ellipsoid of a (mean) moment matrix, eigenvalues floored at `1e-12 λ_max`.
    /// Errors: non-finite entries, `λ_max ≤ 0`, or a result outside the supported length range.
    /// Cost: one [`sym_eigen3`].
    pub fn ellipsoid_from_moment(self, m: &Matrix3<f64>) -> Result<Ellipsoid, EllipsoidError> {
        let e = sym_eigen3(m)?;
        let lmax = e.values[2];
        if lmax <= 0.0 {
            return Err(EllipsoidError::NotPositiveDefinite {
                what: "mean moment",
                eigenvalue: e.values[0],
            });
        }
        let floor = lmax * MIN_ASPECT * MIN_ASPECT;
        let lam = e.values.map(|x| x.max(floor));
        let lengths = match self {
            FilterRule::Seed1995 => lam.map(f64::sqrt),
            FilterRule::Sggx => {
                let s = lam.map(f64::sqrt);
                Vector3::new(
                    (s[1] * s[2] / (PI * s[0])).sqrt(),
                    (s[0] * s[2] / (PI * s[1])).sqrt(),
                    (s[0] * s[1] / (PI * s[2])).sqrt(),
                )
            }
        };
        // Rounding can push the floored aspect a hair below MIN_ASPECT: clamp before validation.
        let lmax_len = lengths.max();
        let lengths = lengths.map(|l| l.max(lmax_len * MIN_ASPECT));
        Ellipsoid::new(e.rotation(), lengths)
    }
}

/// Checks weights: same count as ellipsoids, finite and ≥ 0, positive sum. Returns the sum.
fn check_weights(n: usize, weights: &[f64]) -> Result<f64, EllipsoidError> {
    if n == 0 {
        return Err(EllipsoidError::Empty);
    }
    if weights.len() != n {
        return Err(EllipsoidError::CountMismatch {
            ellipsoids: n,
            weights: weights.len(),
        });
    }
    let mut total = 0.0;
    for (index, &w) in weights.iter().enumerate() {
        if !w.is_finite() || w < 0.0 {
            return Err(EllipsoidError::BadWeight { index, value: w });
        }
        total += w;
    }
    if total <= 0.0 || !total.is_finite() {
        return Err(EllipsoidError::ZeroTotalWeight);
    }
    Ok(total)
}

/// Filters `ellipsoids` with `weights` (densities, ≥ 0, positive sum) by `rule`:
/// `M̄ = Σ wᵢ M(Eᵢ) / Σ wᵢ`, then [`FilterRule::ellipsoid_from_moment`].
///
/// Errors: empty input, count mismatch, negative / non-finite weight, zero total weight.
/// Cost: `k` moment matrices (~30 flops each) and one eigen-decomposition.
pub fn filter(
    ellipsoids: &[Ellipsoid],
    weights: &[f64],
    rule: FilterRule,
) -> Result<Ellipsoid, EllipsoidError> {
    let total = check_weights(ellipsoids.len(), weights)?;
    let mut m = Matrix3::zeros();
    for (e, &w) in ellipsoids.iter().zip(weights) {
        if w > 0.0 {
            m += rule.moment(e) * (w / total);
        }
    }
    rule.ellipsoid_from_moment(&m)
}

/// How far a filtered ellipsoid is from what it stands for.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FilterErrors {
    /// `∫ |f_Q(n) − F̄(n)| dn / ∫ F̄(n) dn`, with `F̄ = Σ wᵢ f_Qᵢ / Σ wᵢ` the true weighted mean of the
    /// normal distributions (relative L1 over the sphere; 0 = exact, 2 = disjoint supports).
    pub l1_error: f64,
    /// `∫ |A_Q(ω) − Ā(ω)| dω / ∫ Ā(ω) dω`, with `Ā = Σ wᵢ A_Qᵢ / Σ wᵢ` the true weighted mean
    /// projected area (relative L1 over directions).
    pub area_error: f64,
    /// Scale-free version of `l1_error`: `∫ |f_Q/S_Q − F̄/S̄|`, both distributions divided by their
    /// total area (in [0, 2]); it measures the shape of the distribution only, so a rule that gets the
    /// lobes right but the size wrong shows a small `l1_shape_error` and a large `l1_error`.
    pub l1_shape_error: f64,
    /// Integrand evaluations the adaptive quadrature spent.
    pub evaluations: usize,
}

/// Measures `filtered` against the weighted set (all errors in one adaptive pass of `quad`, whose
/// tolerance applies to the relative errors). The refinement is driven by the smooth functions
/// (`F̄`, `f_Q`, `Ā`, `A_Q`); the kinked absolute differences are integrated on the cells they
/// choose (see [`SphereQuadrature::integrate_driven`]). Errors as [`filter`] for bad weights.
///
/// Normalisers are exact: `∫ F̄ = Σ wᵢ Sᵢ / Σ wᵢ` (surface areas) and `∫ Ā = π ∫ F̄` (Cauchy).
/// Cost: `2(k + 1)` closed-form evaluations per quadrature node.
pub fn filter_errors(
    ellipsoids: &[Ellipsoid],
    weights: &[f64],
    filtered: &Ellipsoid,
    quad: &SphereQuadrature,
) -> Result<FilterErrors, EllipsoidError> {
    let total = check_weights(ellipsoids.len(), weights)?;
    let w: Vec<f64> = weights.iter().map(|x| x / total).collect();
    let mean_area: f64 = ellipsoids
        .iter()
        .zip(&w)
        .map(|(e, w)| w * e.surface_area())
        .sum();
    let inv_f = 1.0 / mean_area;
    let inv_a = 1.0 / (PI * mean_area);
    let inv_own = 1.0 / filtered.surface_area();
    let r = quad.integrate_driven(
        |n| {
            let mut f = 0.0;
            let mut a = 0.0;
            for (e, wi) in ellipsoids.iter().zip(&w) {
                if *wi > 0.0 {
                    f += wi * e.normal_density(n);
                    a += wi * e.projected_area(n);
                }
            }
            let fq = filtered.normal_density(n);
            let aq = filtered.projected_area(n);
            [
                f * inv_f,
                fq * inv_f,
                a * inv_a,
                aq * inv_a,
                (fq - f).abs() * inv_f,
                (aq - a).abs() * inv_a,
                (fq * inv_own - f * inv_f).abs(),
            ]
        },
        4,
    );
    Ok(FilterErrors {
        l1_error: r.value[4],
        area_error: r.value[5],
        l1_shape_error: r.value[6],
        evaluations: r.evaluations,
    })
}

/// A named set of weighted ellipsoids to filter.
#[derive(Debug, Clone)]
pub struct FilterCase {
    /// Case name used in reports (`"rotated-pair-30deg"`, `"grass"`, …).
    pub name: String,
    /// The ellipsoids (normalised).
    pub ellipsoids: Vec<Ellipsoid>,
    /// Their weights (densities).
    pub weights: Vec<f64>,
}

/// Rotation by `theta` radians about the unit `axis` (Rodrigues).
pub fn rotation_about(axis: &Vector3<f64>, theta: f64) -> Matrix3<f64> {
    let a = axis.normalize();
    let k = a.cross_matrix();
    Matrix3::identity() + k * theta.sin() + k * k * (1.0 - theta.cos())
}

/// Rotates an ellipsoid's basis by `rot` (a proper rotation).
pub fn rotate(e: &Ellipsoid, rot: &Matrix3<f64>) -> Result<Ellipsoid, EllipsoidError> {
    Ellipsoid::new(rot * e.basis(), *e.lengths())
}

impl FilterCase {
    /// The triaxial ellipsoid used by the pair cases: lengths ∝ (1, 0.3, 0.1), normalised.
    pub fn pair_base() -> Result<Ellipsoid, EllipsoidError> {
        Ellipsoid::axis_aligned(Vector3::new(1.0, 0.3, 0.1))?.normalized()
    }

    /// Two equal ellipsoids ([`Self::pair_base`]), the second rotated by `theta` about the shortest
    /// axis (z), equal weights.
    pub fn rotated_pair(theta: f64) -> Result<Self, EllipsoidError> {
        let base = Self::pair_base()?;
        let second = rotate(&base, &rotation_about(&Vector3::z(), theta))?;
        Ok(Self {
            name: format!("rotated-pair-{:.0}deg", theta.to_degrees()),
            ellipsoids: vec![base, second],
            weights: vec![1.0, 1.0],
        })
    }

    /// Neyret 1995's worst case: the pair at 90°, i.e. longest axes orthogonal.
    pub fn orthogonal_pair() -> Result<Self, EllipsoidError> {
        let mut c = Self::rotated_pair(std::f64::consts::FRAC_PI_2)?;
        c.name = "orthogonal-pair".into();
        Ok(c)
    }

    /// Grass: `n` thin cylinder-like needles (aspect 0.05, normalised) along `y` tilted by up to
    /// 25° in a random azimuth, weights in [0.5, 1]; seeded.
    pub fn grass(seed: u64, n: usize) -> Result<Self, EllipsoidError> {
        let mut rng = SplitMix64::new(seed);
        let mut ellipsoids = Vec::with_capacity(n);
        let mut weights = Vec::with_capacity(n);
        for _ in 0..n {
            let tilt = rng.range(0.0, 25f64.to_radians());
            let az = rng.range(0.0, std::f64::consts::TAU);
            let axis = Vector3::new(tilt.sin() * az.cos(), tilt.cos(), tilt.sin() * az.sin());
            ellipsoids.push(Ellipsoid::spheroid(axis, 1.0, 0.05)?.normalized()?);
            weights.push(rng.range(0.5, 1.0));
        }
        Ok(Self {
            name: "grass".into(),
            ellipsoids,
            weights,
        })
    }

    /// A large cylinder (axis `y`) made of `n` flat pieces (aspect 0.05, normalised) tangent to it:
    /// normals `(cos φ, 0, sin φ)`, `φ = 2πk/n`, equal weights. Neyret 1995 says this must filter
    /// into one cylinder-like ellipsoid (long along `y`).
    pub fn cylinder_pieces(n: usize) -> Result<Self, EllipsoidError> {
        let mut ellipsoids = Vec::with_capacity(n);
        for k in 0..n {
            let phi = std::f64::consts::TAU * k as f64 / n as f64;
            let normal = Vector3::new(phi.cos(), 0.0, phi.sin());
            ellipsoids.push(Ellipsoid::spheroid(normal, 0.05, 1.0)?.normalized()?);
        }
        Ok(Self {
            name: "cylinder-pieces".into(),
            ellipsoids,
            weights: vec![1.0; n],
        })
    }

    /// The report's cases: rotated pair at 30°, orthogonal pair, grass (32 blades), cylinder of 32
    /// flat pieces.
    pub fn standard(seed: u64) -> Result<Vec<Self>, EllipsoidError> {
        Ok(vec![
            Self::rotated_pair(30f64.to_radians())?,
            Self::orthogonal_pair()?,
            Self::grass(seed, 32)?,
            Self::cylinder_pieces(32)?,
        ])
    }
}

/// Least-squares slope of `ln y` against `ln x` (the exponent `k` of `y ∝ x^k`); `None` with fewer
/// than two usable points (positive, finite).
pub fn log_log_slope(points: &[(f64, f64)]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx == 0.0 {
        return None;
    }
    Some(sxy / sxx)
}

/// The sin²θ test of Neyret 1995's claim, for one rule.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sin2Fit {
    /// Rule name.
    pub rule: FilterRule,
    /// `(θ in radians, L1 error)` of the rotated pair at each angle.
    pub points: Vec<(f64, f64)>,
    /// `k` in `error ∝ (sin² θ)^k`: the claim holds when `k ≈ 1`.
    pub exponent: f64,
}

/// Fits the exponent `k` of `L1 error ∝ (sin² θ)^k` for the rotated pair over `thetas` (radians,
/// small), by log-log regression. Errors from filtering or a fit with < 2 positive errors.
pub fn fit_sin2_exponent(
    rule: FilterRule,
    thetas: &[f64],
    quad: &SphereQuadrature,
) -> Result<Sin2Fit, EllipsoidError> {
    let mut points = Vec::with_capacity(thetas.len());
    for &theta in thetas {
        let case = FilterCase::rotated_pair(theta)?;
        let f = filter(&case.ellipsoids, &case.weights, rule)?;
        let err = filter_errors(&case.ellipsoids, &case.weights, &f, quad)?;
        points.push((theta, err.l1_error));
    }
    let xy: Vec<(f64, f64)> = points.iter().map(|(t, e)| (t.sin().powi(2), *e)).collect();
    let exponent = log_log_slope(&xy).ok_or(EllipsoidError::BadParameter {
        name: "thetas",
        reason: "fewer than two angles with a positive error".into(),
    })?;
    Ok(Sin2Fit {
        rule,
        points,
        exponent,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_power_law() {
        let pts: Vec<(f64, f64)> = (1..6)
            .map(|i| (i as f64, 3.0 * (i as f64).powf(1.7)))
            .collect();
        assert!((log_log_slope(&pts).unwrap() - 1.7).abs() < 1e-12);
        assert!(log_log_slope(&[(1.0, 1.0)]).is_none());
    }

    #[test]
    fn weights_are_checked() {
        let e = Ellipsoid::sphere(1.0).unwrap();
        assert_eq!(
            filter(&[], &[], FilterRule::Sggx),
            Err(EllipsoidError::Empty)
        );
        assert_eq!(
            filter(&[e, e], &[0.0, 0.0], FilterRule::Sggx),
            Err(EllipsoidError::ZeroTotalWeight)
        );
        assert!(matches!(
            filter(&[e, e], &[1.0, -1.0], FilterRule::Seed1995),
            Err(EllipsoidError::BadWeight { index: 1, .. })
        ));
        assert!(matches!(
            filter(&[e, e], &[1.0, f64::NAN], FilterRule::Seed1995),
            Err(EllipsoidError::BadWeight { index: 1, .. })
        ));
        assert!(matches!(
            filter(&[e], &[1.0, 1.0], FilterRule::Seed1995),
            Err(EllipsoidError::CountMismatch { .. })
        ));
    }
}
