//! The ellipsoid micro-primitive: basis + lengths, quadratic form, projected area, normal
//! distribution, Phong reflectance (two independent methods).
//!
//! # Coordinate systems and formulas
//!
//! An ellipsoid is centred at the origin of the voxel's frame (position does not matter: it models
//! the distribution of normals in the voxel). Basis `R` (columns = unit semi-axes, proper rotation)
//! and lengths `L = diag(l₀, l₁, l₂)` (semi-axis lengths, same unit as the voxel frame):
//!
//! - quadratic form `Q = R L⁻² Rᵀ`, surface `MᵀQM = 1`; inverse form `Q⁻¹ = R L² Rᵀ`;
//! - projected (apparent) area along a unit `ω`: `A(ω) = π √(det(Q⁻¹) · ωᵀQω)
//!   = π l₀l₁l₂ √(Σ (rᵢ·ω)²/lᵢ²)`;
//! - normal distribution (surface area per unit solid angle of normals):
//!   `f_Q(N) = det(Q⁻¹) / (NᵀQ⁻¹N)²`, which integrates over the sphere to the surface area, and
//!   satisfies `∫ f_Q(n) max(0, n·ω) dn = A(ω)`;
//! - SGGX matrix (Heitz et al. 2015, see [`super::filter`](mod@super::filter)): `S = π² det(Q⁻¹) Q
//!   = π² R diag((l₁l₂)², (l₀l₂)², (l₀l₁)²) Rᵀ`, so that `√(ωᵀSω) = A(ω)` and the SGGX
//!   distribution `D(m) = 1/(π√|S| (mᵀS⁻¹m)²)` equals `f_Q(m)` exactly.
//!
//! Formulas are evaluated in the ellipsoid's own frame and divided by the largest length first, so
//! they neither overflow nor underflow over the supported range.
//!
//! # Normalisation
//!
//! Neyret 1995 removes size: "the mean apparent surface, approximated by evaluating the apparent
//! surface in the three axis directions". We take the ellipsoid's own three **principal** axes,
//! which makes the normalisation rotation-invariant: `π (l₀l₁ + l₁l₂ + l₂l₀)/3 = π` (the unit
//! sphere's), i.e. `l₀l₁ + l₁l₂ + l₂l₀ = 3`. ([`Ellipsoid::mean_projected_area`] gives the exact
//! mean over all directions, `S/4` by Cauchy's formula, for comparison.)
//!
//! # Supported range
//!
//! Lengths in [`MIN_LENGTH`], [`MAX_LENGTH`] and aspect `min/max ≥` [`MIN_ASPECT`] (so `Q` and `Q⁻¹`
//! have condition numbers ≤ 1e12, which the eigen-solver resolves). Outside: a typed error.

use std::f64::consts::PI;

use nalgebra::{Matrix2, Matrix3, Vector3};
use rayon::prelude::*;

use super::eigen::sym_eigen3;
use super::error::EllipsoidError;
use super::quadrature::SphereQuadrature;

/// Smallest supported semi-axis length.
pub const MIN_LENGTH: f64 = 1e-50;
/// Largest supported semi-axis length.
pub const MAX_LENGTH: f64 = 1e50;
/// Smallest supported ratio `min length / max length` (flat and thin ellipsoids down to 1e-6).
pub const MIN_ASPECT: f64 = 1e-6;

/// An ellipsoid micro-primitive: orthonormal basis (columns, determinant +1) and semi-axis lengths.
///
/// Invariants (checked by every constructor): lengths finite, in [`MIN_LENGTH`], [`MAX_LENGTH`],
/// aspect ≥ [`MIN_ASPECT`]; basis orthonormal and right-handed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid {
    basis: Matrix3<f64>,
    lengths: Vector3<f64>,
}

fn check_lengths(lengths: &Vector3<f64>) -> Result<(), EllipsoidError> {
    for (axis, &value) in lengths.iter().enumerate() {
        if !value.is_finite() {
            return Err(EllipsoidError::NonFiniteLength { axis, value });
        }
        if value <= 0.0 {
            return Err(EllipsoidError::NonPositiveLength { axis, value });
        }
        if !(MIN_LENGTH..=MAX_LENGTH).contains(&value) {
            return Err(EllipsoidError::LengthOutOfRange { axis, value });
        }
    }
    let ratio = lengths.min() / lengths.max();
    if ratio < MIN_ASPECT {
        return Err(EllipsoidError::TooAnisotropic { ratio });
    }
    Ok(())
}

/// Any unit vector orthogonal to the unit vector `n` (stable for every `n`).
pub fn orthogonal_unit(n: &Vector3<f64>) -> Vector3<f64> {
    let u = if n.x.abs() > n.y.abs() {
        Vector3::new(-n.z, 0.0, n.x)
    } else {
        Vector3::new(0.0, n.z, -n.y)
    };
    u / u.norm()
}

impl Ellipsoid {
    /// An ellipsoid from a basis (columns = semi-axes) and lengths.
    ///
    /// The basis must be orthonormal (`‖RᵀR − I‖_F ≤ 1e-9`); a left-handed one has its third column
    /// negated (same ellipsoid). Errors: non-finite entries, non-orthonormal basis, bad lengths.
    pub fn new(basis: Matrix3<f64>, lengths: Vector3<f64>) -> Result<Self, EllipsoidError> {
        check_lengths(&lengths)?;
        if basis.iter().any(|x| !x.is_finite()) {
            return Err(EllipsoidError::NonFiniteMatrix { what: "basis" });
        }
        let deviation = (basis.transpose() * basis - Matrix3::identity()).norm();
        if deviation > 1e-9 {
            return Err(EllipsoidError::NotOrthonormal { deviation });
        }
        let mut basis = basis;
        if basis.determinant() < 0.0 {
            basis.set_column(2, &(-basis.column(2)));
        }
        Ok(Self { basis, lengths })
    }

    /// The axis-aligned ellipsoid with the given lengths.
    pub fn axis_aligned(lengths: Vector3<f64>) -> Result<Self, EllipsoidError> {
        Self::new(Matrix3::identity(), lengths)
    }

    /// The sphere of radius `radius`.
    pub fn sphere(radius: f64) -> Result<Self, EllipsoidError> {
        Self::axis_aligned(Vector3::repeat(radius))
    }

    /// A spheroid with symmetry axis `axis` (any non-zero vector, normalised here): semi-axis `along`
    /// on it and `across` in the two other directions. `along < across` is a flat piece with normal
    /// `axis` (a surface element); `along > across` is a cylinder-like needle along `axis`.
    pub fn spheroid(axis: Vector3<f64>, along: f64, across: f64) -> Result<Self, EllipsoidError> {
        let norm = axis.norm();
        if !norm.is_finite() || norm == 0.0 {
            return Err(EllipsoidError::BadDirection);
        }
        let a = axis / norm;
        let t = orthogonal_unit(&a);
        let b = a.cross(&t);
        Self::new(
            Matrix3::from_columns(&[t, b, a]),
            Vector3::new(across, across, along),
        )
    }

    /// The ellipsoid of the quadratic form `Q` (symmetric positive definite; upper triangle read):
    /// lengths `λ^{-1/2}` of the eigenvalues of `Q` (not Neyret 1995's `λ^{-2}`: docs/design.md
    /// §14).
    pub fn from_quadratic_form(q: &Matrix3<f64>) -> Result<Self, EllipsoidError> {
        let e = sym_eigen3(q)?;
        if e.values[0] <= 0.0 {
            return Err(EllipsoidError::NotPositiveDefinite {
                what: "quadratic form",
                eigenvalue: e.values[0],
            });
        }
        Self::new(e.rotation(), e.values.map(|l| 1.0 / l.sqrt()))
    }

    /// The ellipsoid of the inverse form `Q⁻¹ = R L² Rᵀ`: lengths are `√λ` of its eigenvalues.
    pub fn from_inverse_form(q_inv: &Matrix3<f64>) -> Result<Self, EllipsoidError> {
        let e = sym_eigen3(q_inv)?;
        if e.values[0] <= 0.0 {
            return Err(EllipsoidError::NotPositiveDefinite {
                what: "inverse quadratic form",
                eigenvalue: e.values[0],
            });
        }
        Self::new(e.rotation(), e.values.map(f64::sqrt))
    }

    /// The ellipsoid of an SGGX matrix `S = π² det(Q⁻¹) Q` (see the module docs): with `σᵢ = √sᵢ`
    /// the projected areas along the eigenvectors, `lᵢ = √(σⱼσₖ / (π σᵢ))`.
    pub fn from_sggx(s: &Matrix3<f64>) -> Result<Self, EllipsoidError> {
        let e = sym_eigen3(s)?;
        if e.values[0] <= 0.0 {
            return Err(EllipsoidError::NotPositiveDefinite {
                what: "SGGX matrix",
                eigenvalue: e.values[0],
            });
        }
        let sigma = e.values.map(f64::sqrt);
        let l = Vector3::new(
            (sigma[1] * sigma[2] / (PI * sigma[0])).sqrt(),
            (sigma[0] * sigma[2] / (PI * sigma[1])).sqrt(),
            (sigma[0] * sigma[1] / (PI * sigma[2])).sqrt(),
        );
        Self::new(e.rotation(), l)
    }

    /// Basis `R`: column `i` is the unit direction of semi-axis `i` (right-handed).
    pub fn basis(&self) -> &Matrix3<f64> {
        &self.basis
    }

    /// Semi-axis lengths `(l₀, l₁, l₂)`, in the order of the basis columns.
    pub fn lengths(&self) -> &Vector3<f64> {
        &self.lengths
    }

    /// `Q = R L⁻² Rᵀ`.
    pub fn quadratic_form(&self) -> Matrix3<f64> {
        let d = self.lengths.map(|l| 1.0 / (l * l));
        self.basis * Matrix3::from_diagonal(&d) * self.basis.transpose()
    }

    /// `Q⁻¹ = R L² Rᵀ` (the 1995 rule averages this).
    pub fn inverse_form(&self) -> Matrix3<f64> {
        let d = self.lengths.map(|l| l * l);
        self.basis * Matrix3::from_diagonal(&d) * self.basis.transpose()
    }

    /// `S = π² det(Q⁻¹) Q = π² R diag((l₁l₂)², (l₀l₂)², (l₀l₁)²) Rᵀ` (the SGGX rule averages this).
    pub fn sggx_matrix(&self) -> Matrix3<f64> {
        let l = &self.lengths;
        let d = Vector3::new(
            (PI * l[1] * l[2]).powi(2),
            (PI * l[0] * l[2]).powi(2),
            (PI * l[0] * l[1]).powi(2),
        );
        self.basis * Matrix3::from_diagonal(&d) * self.basis.transpose()
    }

    /// `det(Q⁻¹) = (l₀l₁l₂)²`.
    pub fn det_inverse_form(&self) -> f64 {
        (self.lengths.x * self.lengths.y * self.lengths.z).powi(2)
    }

    /// The same ellipsoid scaled by `factor` (> 0). Errors if the result leaves the supported range.
    pub fn scaled(&self, factor: f64) -> Result<Self, EllipsoidError> {
        Self::new(self.basis, self.lengths * factor)
    }

    /// Mean of the projected areas along the three principal axes, `π(l₀l₁ + l₁l₂ + l₂l₀)/3`.
    pub fn mean_axis_projected_area(&self) -> f64 {
        let l = &self.lengths;
        PI * (l[0] * l[1] + l[1] * l[2] + l[2] * l[0]) / 3.0
    }

    /// The normalised ellipsoid: same shape and basis, scaled so that
    /// [`Self::mean_axis_projected_area`] is `π` (the unit sphere's).
    pub fn normalized(&self) -> Result<Self, EllipsoidError> {
        let l = &self.lengths;
        let m = l.max();
        let (a, b, c) = (l[0] / m, l[1] / m, l[2] / m);
        let factor = (3.0 / (a * b + b * c + c * a)).sqrt() / m;
        Self::new(self.basis, self.lengths * factor)
    }

    /// Projected area along `omega`: `π √(det(Q⁻¹) ωᵀQω)`. `omega` should be unit; the formula is
    /// homogeneous of degree 1 in `ω`, so a non-unit `omega` scales the result by `|ω|`.
    /// Cost: ~20 flops.
    #[inline]
    pub fn projected_area(&self, omega: &Vector3<f64>) -> f64 {
        let l = &self.lengths;
        let m = l.max();
        let (a, b, c) = (l[0] / m, l[1] / m, l[2] / m);
        let w = self.basis.tr_mul(omega);
        PI * m
            * m
            * a
            * b
            * c
            * ((w[0] / a).powi(2) + (w[1] / b).powi(2) + (w[2] / c).powi(2)).sqrt()
    }

    /// Normal distribution `f_Q(N) = det(Q⁻¹)/(NᵀQ⁻¹N)²`: surface area per unit solid angle of
    /// normals around the unit `normal` (area unit = length unit²). Homogeneous of degree −4 in `N`.
    /// Cost: ~20 flops.
    #[inline]
    pub fn normal_density(&self, normal: &Vector3<f64>) -> f64 {
        let l = &self.lengths;
        let m = l.max();
        let (a, b, c) = (l[0] / m, l[1] / m, l[2] / m);
        let w = self.basis.tr_mul(normal);
        let s = (a * w[0]).powi(2) + (b * w[1]).powi(2) + (c * w[2]).powi(2);
        m * m * (a * b * c).powi(2) / (s * s)
    }

    /// Exact surface area `4π l₀l₁l₂ R_G(l₀⁻², l₁⁻², l₂⁻²)` (DLMF 19.33.1) with Carlson's symmetric
    /// elliptic integrals. Relative accuracy ~1e-15. Cost: a few dozen square roots.
    pub fn surface_area(&self) -> f64 {
        let l = &self.lengths;
        let m = l.max();
        let (a, b, c) = (l[0] / m, l[1] / m, l[2] / m);
        4.0 * PI * m * m * a * b * c * carlson_rg(1.0 / (a * a), 1.0 / (b * b), 1.0 / (c * c))
    }

    /// Exact mean projected area over all directions: `S/4` (Cauchy's surface-area formula).
    pub fn mean_projected_area(&self) -> f64 {
        self.surface_area() / 4.0
    }

    /// The apparent ellipse along the unit view direction `v`: an orthonormal pair `(e₁, e₂)` of the
    /// screen plane `v⊥` and the 2×2 form `K` such that a screen point `p = x e₁ + y e₂` is covered
    /// by the ellipsoid iff `(x, y) K (x, y)ᵀ ≤ 1`. Its area `π/√det K` equals
    /// [`Self::projected_area`]`(v)` (an independent check of that formula).
    pub fn apparent_ellipse(&self, v: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>, Matrix2<f64>) {
        let q = self.quadratic_form();
        let e1 = orthogonal_unit(v);
        let e2 = v.cross(&e1);
        let qv = q * v;
        let vqv = v.dot(&qv);
        let e = [e1, e2];
        let k =
            Matrix2::from_fn(|i, j| e[i].dot(&(q * e[j])) - e[i].dot(&qv) * e[j].dot(&qv) / vqv);
        (e1, e2, k)
    }
}

/// Carlson's `R_F(x, y, z)` by duplication (Carlson 1995), `x, y, z ≥ 0`, at most one zero.
fn carlson_rf(x: f64, y: f64, z: f64) -> f64 {
    let (mut x, mut y, mut z) = (x, y, z);
    for _ in 0..100 {
        let (sx, sy, sz) = (x.sqrt(), y.sqrt(), z.sqrt());
        let lambda = sx * (sy + sz) + sy * sz;
        x = 0.25 * (x + lambda);
        y = 0.25 * (y + lambda);
        z = 0.25 * (z + lambda);
        let avg = (x + y + z) / 3.0;
        let (dx, dy, dz) = ((avg - x) / avg, (avg - y) / avg, (avg - z) / avg);
        if dx.abs().max(dy.abs()).max(dz.abs()) < 1e-3 {
            let e2 = dx * dy - dz * dz;
            let e3 = dx * dy * dz;
            return (1.0 + (e2 / 24.0 - 0.1 - 3.0 * e3 / 44.0) * e2 + e3 / 14.0) / avg.sqrt();
        }
    }
    f64::NAN
}

/// Carlson's `R_D(x, y, z)` by duplication (Carlson 1995), `z > 0`.
fn carlson_rd(x: f64, y: f64, z: f64) -> f64 {
    let (mut x, mut y, mut z) = (x, y, z);
    let mut sum = 0.0;
    let mut fac = 1.0;
    for _ in 0..100 {
        let (sx, sy, sz) = (x.sqrt(), y.sqrt(), z.sqrt());
        let lambda = sx * (sy + sz) + sy * sz;
        sum += fac / (sz * (z + lambda));
        fac *= 0.25;
        x = 0.25 * (x + lambda);
        y = 0.25 * (y + lambda);
        z = 0.25 * (z + lambda);
        let avg = 0.2 * (x + y + 3.0 * z);
        let (dx, dy, dz) = ((avg - x) / avg, (avg - y) / avg, (avg - z) / avg);
        if dx.abs().max(dy.abs()).max(dz.abs()) < 1e-3 {
            let (c1, c2, c3, c4) = (3.0 / 14.0, 1.0 / 6.0, 9.0 / 22.0, 3.0 / 26.0);
            let (c5, c6) = (0.25 * c3, 1.5 * c4);
            let ea = dx * dy;
            let eb = dz * dz;
            let ec = ea - eb;
            let ed = ea - 6.0 * eb;
            let ee = ed + ec + ec;
            return 3.0 * sum
                + fac
                    * (1.0
                        + ed * (-c1 + c5 * ed - c6 * dz * ee)
                        + dz * (c2 * ee + dz * (-c3 * ec + dz * c4 * ea)))
                    / (avg * avg.sqrt());
        }
    }
    f64::NAN
}

/// Carlson's `R_G(x, y, z)` (DLMF 19.21.10), arguments permuted so that `z` is the middle one and the
/// `(x − z)(y − z)` term cannot cancel.
fn carlson_rg(x: f64, y: f64, z: f64) -> f64 {
    let mut v = [x, y, z];
    v.sort_by(|a, b| a.total_cmp(b));
    let (x, z, y) = (v[0], v[1], v[2]);
    0.5 * (z * carlson_rf(x, y, z) - (x - z) * (y - z) * carlson_rd(x, y, z) / 3.0
        + (x * y / z).sqrt())
}

/// Normalised Phong BRDF: `k_d/π + k_s (e + 2)/(2π) max(0, r·v)^e`, `r = 2(n·l)n − l` the mirror
/// direction of the light about the micro-normal `n`. Units: 1/sr.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Phong {
    /// Diffuse albedo `k_d` in [0, 1].
    pub diffuse: f64,
    /// Specular albedo `k_s` in [0, 1].
    pub specular: f64,
    /// Phong exponent `e ≥ 0`.
    pub exponent: f64,
}

impl Phong {
    /// The BRDF value for micro-normal `n`, light `l`, view `v` (unit vectors pointing away).
    #[inline]
    pub fn eval(&self, n: &Vector3<f64>, l: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
        let nl = n.dot(l);
        let r = n * (2.0 * nl) - l;
        let rv = r.dot(v).max(0.0);
        self.diffuse / PI
            + self.specular * (self.exponent + 2.0) / (2.0 * PI) * rv.powf(self.exponent)
    }

    fn check(&self) -> Result<(), EllipsoidError> {
        for (name, x) in [
            ("diffuse", self.diffuse),
            ("specular", self.specular),
            ("exponent", self.exponent),
        ] {
            if !x.is_finite() || x < 0.0 {
                return Err(EllipsoidError::BadParameter {
                    name,
                    reason: format!("must be finite and ≥ 0, got {x}"),
                });
            }
        }
        Ok(())
    }
}

fn unit(v: &Vector3<f64>) -> Result<Vector3<f64>, EllipsoidError> {
    let n = v.norm();
    if !n.is_finite() || n == 0.0 {
        return Err(EllipsoidError::BadDirection);
    }
    Ok(v / n)
}

impl Ellipsoid {
    /// Reflectance of the micro-primitive for light `l` and view `v` (any non-zero vectors,
    /// normalised here), by integration over the normal sphere:
    /// `ρ(l, v) = ∫ f_Q(n) max(0, n·l) max(0, n·v) brdf(n, l, v) dn / A(v)` — the light scattered
    /// towards `v` per unit apparent area, per unit irradiance (exact for a convex ellipsoid: no
    /// self-shadowing). Uses the adaptive [`SphereQuadrature`] `quad`.
    pub fn reflectance_normal_integral(
        &self,
        l: &Vector3<f64>,
        v: &Vector3<f64>,
        brdf: &Phong,
        quad: &SphereQuadrature,
    ) -> Result<f64, EllipsoidError> {
        brdf.check()?;
        let (l, v) = (unit(l)?, unit(v)?);
        let area = self.projected_area(&v);
        let r = quad.integrate_scalar(|n| {
            let nl = n.dot(&l);
            let nv = n.dot(&v);
            if nl <= 0.0 || nv <= 0.0 {
                0.0
            } else {
                self.normal_density(n) * nl * nv * brdf.eval(n, &l, &v) / area
            }
        });
        Ok(r.value[0])
    }

    /// The same reflectance by Neyret 1995's method: sample the apparent ellipse along `v`
    /// uniformly, find the visible surface point under each sample and its normal, average
    /// `brdf(n, l, v) max(0, n·l)`. Independent of `f_Q` and of the sphere quadrature.
    ///
    /// The unit disk is mapped onto the ellipse linearly (`K = C Cᵀ`, `p = C⁻ᵀ d`), and `d` is
    /// parameterised by `|d| = sin α`, `α ∈ [0, π/2]`, so that the visible point's depth
    /// `∝ cos α` is smooth; midpoint rule with `n_alpha × 2 n_alpha` samples (rayon over rings).
    pub fn reflectance_apparent_ellipse(
        &self,
        l: &Vector3<f64>,
        v: &Vector3<f64>,
        brdf: &Phong,
        n_alpha: usize,
    ) -> Result<f64, EllipsoidError> {
        brdf.check()?;
        let (l, v) = (unit(l)?, unit(v)?);
        if n_alpha == 0 {
            return Err(EllipsoidError::BadParameter {
                name: "n_alpha",
                reason: "must be ≥ 1".into(),
            });
        }
        let q = self.quadratic_form();
        let (e1, e2, k) = self.apparent_ellipse(&v);
        let chol = k.cholesky().ok_or(EllipsoidError::NotPositiveDefinite {
            what: "apparent ellipse form",
            eigenvalue: k.determinant(),
        })?;
        // p = C⁻ᵀ d with K = C Cᵀ: pᵀKp = |d|².
        let c_inv_t = chol
            .l()
            .transpose()
            .try_inverse()
            .ok_or(EllipsoidError::BadDirection)?;
        let qv = q * v;
        let vqv = v.dot(&qv);
        let n_phi = 2 * n_alpha;
        let d_alpha = 0.5 * PI / n_alpha as f64;
        let d_phi = 2.0 * PI / n_phi as f64;
        let (num, den): (f64, f64) = (0..n_alpha)
            .into_par_iter()
            .map(|i| {
                let alpha = (i as f64 + 0.5) * d_alpha;
                let (s, c) = alpha.sin_cos();
                // Disk area element: ρ dρ dφ = sin α cos α dα dφ.
                let w = s * c * d_alpha * d_phi;
                let mut num = 0.0;
                for j in 0..n_phi {
                    let phi = (j as f64 + 0.5) * d_phi;
                    let d = nalgebra::Vector2::new(s * phi.cos(), s * phi.sin());
                    let xy = c_inv_t * d;
                    let p = e1 * xy.x + e2 * xy.y;
                    // Visible root of (p + t v)ᵀQ(p + t v) = 1: discriminant = vᵀQv (1 − |d|²).
                    let t = (-p.dot(&qv) + (vqv * c * c).sqrt()) / vqv;
                    let m = p + v * t;
                    let n = (q * m).normalize();
                    let nl = n.dot(&l);
                    if nl > 0.0 {
                        num += w * brdf.eval(&n, &l, &v) * nl;
                    }
                }
                (num, w * n_phi as f64)
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        Ok(num / den)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn carlson_matches_closed_forms() {
        // Sphere.
        assert!((carlson_rg(4.0, 4.0, 4.0) - 2.0).abs() < 1e-15);
        // Oblate spheroid a = b = 1, c = 0.3: S = 2π a² (1 + (1 − e²)/e atanh e).
        let c: f64 = 0.3;
        let e = (1.0 - c * c).sqrt();
        let s_exact = 2.0 * PI * (1.0 + (1.0 - e * e) / e * e.atanh());
        let s = Ellipsoid::axis_aligned(Vector3::new(1.0, 1.0, c))
            .unwrap()
            .surface_area();
        assert!((s / s_exact - 1.0).abs() < 1e-13, "{s} {s_exact}");
        // Prolate spheroid a = b = 0.3, c = 1: S = 2π a² (1 + c/(a e) asin e).
        let a: f64 = 0.3;
        let e = (1.0 - a * a).sqrt();
        let s_exact = 2.0 * PI * a * a * (1.0 + 1.0 / (a * e) * e.asin());
        let s = Ellipsoid::axis_aligned(Vector3::new(a, a, 1.0))
            .unwrap()
            .surface_area();
        assert!((s / s_exact - 1.0).abs() < 1e-13, "{s} {s_exact}");
    }

    #[test]
    fn forms_round_trip() {
        let e = Ellipsoid::spheroid(Vector3::new(1.0, 2.0, 3.0), 0.2, 1.5).unwrap();
        let q = e.quadratic_form();
        assert!((q * e.inverse_form() - Matrix3::identity()).norm() < 1e-13);
        let back = Ellipsoid::from_quadratic_form(&q).unwrap();
        assert!((back.quadratic_form() - q).norm() < 1e-12 * q.norm());
        let back = Ellipsoid::from_sggx(&e.sggx_matrix()).unwrap();
        assert!((back.quadratic_form() - q).norm() < 1e-12 * q.norm());
    }

    #[test]
    fn normalisation_gives_unit_sphere_mean() {
        let e = Ellipsoid::axis_aligned(Vector3::new(3.0, 0.1, 0.5))
            .unwrap()
            .normalized()
            .unwrap();
        assert!((e.mean_axis_projected_area() - PI).abs() < 1e-14);
        let mean_axes: f64 = (0..3)
            .map(|i| e.projected_area(&e.basis().column(i).into_owned()))
            .sum::<f64>()
            / 3.0;
        assert!((mean_axes - PI).abs() < 1e-13);
    }
}
