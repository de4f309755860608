//! Fast, robust eigen-decomposition of 3×3 real symmetric matrices, in `f32` and `f64`.
//!
//! # Method
//!
//! A hybrid of the closed-form (trigonometric) eigenvalue formula and one exact plane rotation, in the
//! spirit of D. Eberly, *A Robust Eigensolver for 3×3 Symmetric Matrices* (Geometric Tools, 2014) and
//! of J. Kopp, *Efficient numerical diagonalization of hermitian 3×3 matrices* (Int. J. Mod. Phys. C
//! 19, 2008). Written from the papers' mathematics; no code was ported.
//!
//! 1. **Diagonal input** (off-diagonal entries exactly zero): the answer is read off, exactly.
//! 2. **Scale.** Multiply `A` by the power of two `2^k` that brings its largest absolute entry into
//!    `[1, 2)` (exact: no rounding), so entries from 1e-300 to 1e300 behave alike.
//! 3. **Normalise.** `B = (A − qI)/p` with `q = tr(A)/3` and `p² = tr((A − qI)²)/6`, so the
//!    eigenvalues `β` of `B` satisfy `Σβ = 0`, `Σβ² = 6`: they are the roots of
//!    `β³ − 3β − det B` (the closed form is `β_k = 2 cos(φ + 2πk/3)`, `cos 3φ = det(B)/2`).
//! 4. **One well-separated eigenvector.** If `det(B) ≥ 0` the largest `β` is at least `√3` away from
//!    the other two, else the smallest is (Eberly's observation). That root lies in `[√3, 2]` (up to
//!    sign) and is found by Newton's method from a quadratic fit, which replaces `acos` and `cos`.
//!    Its eigenvector is the largest of the three cross products of rows of `B − βI` — well
//!    conditioned because of that gap, whatever the other two eigenvalues do. Its eigenvalue is then
//!    re-read as the Rayleigh quotient `vᵀBv`.
//! 5. **The other two from an exact 2×2 problem.** Build an orthonormal basis `(u, w)` of `v⊥`,
//!    project `B` onto it, and diagonalise that 2×2 symmetric matrix with one Jacobi rotation
//!    (closed form, backward stable). This replaces Eberly's second cross-product step and Kopp's QL
//!    fallback: the near-double pair is never computed from the (ill-conditioned) trigonometric values,
//!    so gaps of 1e-15 and exact double or triple eigenvalues need no special case.
//!
//! Every vector is a normalised cross product or a rotation of an orthonormal pair, so `VᵀV = I` to a
//! few ulps, and the residual `A − VΛVᵀ` is `O(ε‖A‖)` (measured by [`adversarial_suite`] and
//! `tests/ellipsoid.rs`: worst relative reconstruction below 1e-14 in `f64`).
//!
//! # Conventions
//!
//! - Only the **upper triangle** of the input is read (`a00 a01 a02 a11 a12 a22`).
//! - Eigenvalues are returned in **ascending** order: `values[0] ≤ values[1] ≤ values[2]`.
//! - Eigenvectors are the **columns** of `vectors`, unit length, mutually orthogonal.
//! - **Sign**: each eigenvector's component of largest magnitude is positive (first such index on a
//!   tie). `det(vectors)` may therefore be −1; [`SymEigen3::rotation`] gives a proper rotation.
//!
//! # Cost
//!
//! Three or four Newton steps, four square roots, a few divisions and about 200 flops; no
//! transcendental function, no branch on the data except the diagonal shortcut. See `benches/eigen.rs` and
//! `altrep ellipsoid-bench` for the time per decomposition against nalgebra's `SymmetricEigen`.

use nalgebra::{Matrix3, RealField, Vector3};

use super::error::EllipsoidError;
use super::rng::{RandomGeometry, SplitMix64};

/// Scalar types the solver runs in (`f32`, `f64`): a real field plus exact power-of-two scaling.
pub trait EigenScalar: RealField + Copy {
    /// The literal `x` in this type (rounded).
    fn lit(x: f64) -> Self;
    /// `x` as `f64`.
    fn to_f64(self) -> f64;
    /// The binary exponent `e` with `2^e ≤ |self| < 2^(e+1)`, subnormals included; `self` must be
    /// finite and non-zero.
    fn exponent(self) -> i32;
    /// `2^k`, for `k` within the normal exponent range of the type.
    fn pow2(k: i32) -> Self;
}

impl EigenScalar for f64 {
    #[inline(always)]
    fn lit(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn exponent(self) -> i32 {
        let bits = self.to_bits();
        let e = ((bits >> 52) & 0x7ff) as i32;
        if e == 0 {
            let mantissa = bits & ((1u64 << 52) - 1);
            -1074 + (63 - mantissa.leading_zeros() as i32)
        } else {
            e - 1023
        }
    }
    #[inline(always)]
    fn pow2(k: i32) -> Self {
        f64::from_bits(((k + 1023) as u64) << 52)
    }
}

impl EigenScalar for f32 {
    #[inline(always)]
    fn lit(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn exponent(self) -> i32 {
        let bits = self.to_bits();
        let e = ((bits >> 23) & 0xff) as i32;
        if e == 0 {
            let mantissa = bits & ((1u32 << 23) - 1);
            -149 + (31 - mantissa.leading_zeros() as i32)
        } else {
            e - 127
        }
    }
    #[inline(always)]
    fn pow2(k: i32) -> Self {
        f32::from_bits(((k + 127) as u32) << 23)
    }
}

/// Eigen-decomposition `A = V diag(values) Vᵀ` of a 3×3 symmetric matrix.
///
/// `values` ascending; `vectors` columns are the unit eigenvectors, largest-magnitude component
/// positive (see the module docs for the conventions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SymEigen3<T: EigenScalar> {
    /// Eigenvalues, ascending.
    pub values: Vector3<T>,
    /// Unit eigenvectors as columns, `vectors.column(i)` belongs to `values[i]`.
    pub vectors: Matrix3<T>,
}

impl<T: EigenScalar> SymEigen3<T> {
    /// `V diag(values) Vᵀ`: the matrix this decomposition stands for.
    pub fn reconstruct(&self) -> Matrix3<T> {
        self.vectors * Matrix3::from_diagonal(&self.values) * self.vectors.transpose()
    }

    /// The eigenvectors as a proper rotation (determinant +1): the third column is negated when the
    /// sign convention made `det(vectors) = −1`. Column `i` still belongs to `values[i]`.
    pub fn rotation(&self) -> Matrix3<T> {
        let mut r = self.vectors;
        if r.determinant() < T::zero() {
            r.set_column(2, &(-r.column(2)));
        }
        r
    }
}

#[inline(always)]
fn cross<T: EigenScalar>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn dot<T: EigenScalar>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Symmetric matrix (upper triangle `c00 c01 c02 c11 c12 c22`) times a vector.
#[inline(always)]
fn sym_mul<T: EigenScalar>(c: [T; 6], x: [T; 3]) -> [T; 3] {
    [
        c[0] * x[0] + c[1] * x[1] + c[2] * x[2],
        c[1] * x[0] + c[3] * x[1] + c[4] * x[2],
        c[2] * x[0] + c[4] * x[1] + c[5] * x[2],
    ]
}

/// Flips `v` so that its component of largest magnitude is positive (first index on a tie).
#[inline(always)]
fn canonical_sign<T: EigenScalar>(v: [T; 3]) -> [T; 3] {
    let (a0, a1, a2) = (v[0].abs(), v[1].abs(), v[2].abs());
    let big = if a0 >= a1 && a0 >= a2 {
        v[0]
    } else if a1 >= a2 {
        v[1]
    } else {
        v[2]
    };
    if big < T::zero() {
        [-v[0], -v[1], -v[2]]
    } else {
        v
    }
}

/// Decomposes the symmetric 3×3 matrix `a` (upper triangle read) into ascending eigenvalues and
/// orthonormal eigenvectors; see the module docs for the method and the conventions.
///
/// Errors: [`EllipsoidError::MatrixNotFinite`] if an upper-triangle entry is NaN or infinite;
/// [`EllipsoidError::EigenOverflow`] if an eigenvalue overflows (entries near the largest float).
/// Cost: constant, about 200 flops, four square roots and a few divisions.
pub fn sym_eigen3<T: EigenScalar>(a: &Matrix3<T>) -> Result<SymEigen3<T>, EllipsoidError> {
    let upper = [
        (0, 0, a[(0, 0)]),
        (0, 1, a[(0, 1)]),
        (0, 2, a[(0, 2)]),
        (1, 1, a[(1, 1)]),
        (1, 2, a[(1, 2)]),
        (2, 2, a[(2, 2)]),
    ];
    let mut max_abs = T::zero();
    for &(row, col, x) in &upper {
        if !x.is_finite() {
            return Err(EllipsoidError::MatrixNotFinite {
                row,
                col,
                value: x.to_f64(),
            });
        }
        max_abs = max_abs.max(x.abs());
    }
    if max_abs == T::zero() {
        return Ok(SymEigen3 {
            values: Vector3::zeros(),
            vectors: Matrix3::identity(),
        });
    }

    // Step 1: exactly diagonal input: read off, unscaled (scaling could flush a tiny
    // diagonal entry to zero).
    let zero = T::zero();
    let one = T::one();
    if upper[1].2 == zero && upper[2].2 == zero && upper[4].2 == zero {
        let pairs = [
            (upper[0].2, [one, zero, zero]),
            (upper[3].2, [zero, one, zero]),
            (upper[5].2, [zero, zero, one]),
        ];
        return Ok(assemble(pairs, 0, 0));
    }

    // Step 2: exact power-of-two scaling (two factors so that each stays a normal number).
    let k = -max_abs.exponent();
    let (k1, k2) = (k / 2, k - k / 2);
    let s = |x: T| x * T::pow2(k1) * T::pow2(k2);
    let c = [
        s(upper[0].2),
        s(upper[1].2),
        s(upper[2].2),
        s(upper[3].2),
        s(upper[4].2),
        s(upper[5].2),
    ];

    let off = c[1] * c[1] + c[2] * c[2] + c[4] * c[4];
    let pairs: [(T, [T; 3]); 3] = if off == zero {
        // Off-diagonal entries below √(min positive) of the largest: diagonal to working precision.
        [
            (c[0], [one, zero, zero]),
            (c[3], [zero, one, zero]),
            (c[5], [zero, zero, one]),
        ]
    } else {
        general_case(c)
    };
    let out = assemble(pairs, k1, k2);
    if out.values.iter().any(|v| !v.is_finite()) {
        return Err(EllipsoidError::EigenOverflow {
            max_abs: max_abs.to_f64(),
        });
    }
    Ok(out)
}

/// Sorts (value, vector) pairs ascending, applies the sign convention and undoes the scaling
/// `2^(k1 + k2)`.
#[inline(always)]
fn assemble<T: EigenScalar>(mut pairs: [(T, [T; 3]); 3], k1: i32, k2: i32) -> SymEigen3<T> {
    if pairs[1].0 < pairs[0].0 {
        pairs.swap(0, 1);
    }
    if pairs[2].0 < pairs[1].0 {
        pairs.swap(1, 2);
    }
    if pairs[1].0 < pairs[0].0 {
        pairs.swap(0, 1);
    }
    let (u1, u2) = (T::pow2(-k1), T::pow2(-k2));
    let mut values = Vector3::zeros();
    let mut vectors = Matrix3::zeros();
    for (i, (lambda, v)) in pairs.iter().enumerate() {
        values[i] = *lambda * u1 * u2;
        let v = canonical_sign(*v);
        vectors[(0, i)] = v[0];
        vectors[(1, i)] = v[1];
        vectors[(2, i)] = v[2];
    }
    SymEigen3 { values, vectors }
}

/// Coefficient of `d²` in the starting guess `r(d) ≈ √3 + d/6 + C2 d²` (exact at `d = 2`).
const C2: f64 = (2.0 - 1.732_050_807_568_877_2 - 1.0 / 3.0) / 4.0;

/// Steps 3–5 on a scaled matrix with a non-zero off-diagonal part. Returns (eigenvalue, unit
/// eigenvector) pairs in the scaled units, unsorted.
#[inline(always)]
fn general_case<T: EigenScalar>(c: [T; 6]) -> [(T, [T; 3]); 3] {
    let zero = T::zero();
    let one = T::one();
    let two = T::lit(2.0);
    let three = T::lit(3.0);
    // Step 3: B = (A − qI)/p.
    let q = (c[0] + c[3] + c[5]) / three;
    let (d0, d1, d2) = (c[0] - q, c[3] - q, c[5] - q);
    let off = c[1] * c[1] + c[2] * c[2] + c[4] * c[4];
    let p = ((d0 * d0 + d1 * d1 + d2 * d2 + two * off) / T::lit(6.0)).sqrt();
    let inv_p = one / p;
    let b = [
        d0 * inv_p,
        c[1] * inv_p,
        c[2] * inv_p,
        d1 * inv_p,
        c[4] * inv_p,
        d2 * inv_p,
    ];
    let det_b = b[0] * (b[3] * b[5] - b[4] * b[4]) - b[1] * (b[1] * b[5] - b[4] * b[2])
        + b[2] * (b[1] * b[4] - b[3] * b[2]);
    // Step 4: the eigenvalue farthest from the other two, and its eigenvector. The eigenvalues of B
    // are the roots of β³ − 3β − det B; for det B ≥ 0 the farthest is the largest, r ∈ [√3, 2],
    // else minus the largest root of β³ − 3β + det B. Newton from a quadratic fit of r(d) (exact
    // at d = 0 and d = 2, error < 3e-3) converges monotonically (g convex and increasing on
    // [√3, 2]); three to four steps reach the last ulp — cheaper than acos + cos.
    let d = det_b.abs().min(two);
    let mut r = T::lit(3f64.sqrt()) + d * (T::lit(1.0 / 6.0) + d * T::lit(C2));
    for _ in 0..8 {
        let g = r * r * r - three * r - d;
        let gp = three * (r * r - one);
        let step = g / gp;
        r -= step;
        if step.abs() <= T::lit(4.0) * T::default_epsilon() * r {
            break;
        }
    }
    let beta = if det_b >= zero { r } else { -r };
    let r0 = [b[0] - beta, b[1], b[2]];
    let r1 = [b[1], b[3] - beta, b[4]];
    let r2 = [b[2], b[4], b[5] - beta];
    let x01 = cross(r0, r1);
    let x02 = cross(r0, r2);
    let x12 = cross(r1, r2);
    let (n01, n02, n12) = (dot(x01, x01), dot(x02, x02), dot(x12, x12));
    let (x, n) = if n01 >= n02 && n01 >= n12 {
        (x01, n01)
    } else if n02 >= n12 {
        (x02, n02)
    } else {
        (x12, n12)
    };
    let v = if n > zero {
        let inv = one / n.sqrt();
        [x[0] * inv, x[1] * inv, x[2] * inv]
    } else {
        // Unreachable in exact arithmetic (B − βI has rank 2 because β is at least √3 from the
        // other eigenvalues); keep an orthonormal answer if rounding ever says otherwise.
        [one, zero, zero]
    };
    // Step 5: orthonormal complement (u, w) of v, and the 2×2 problem on it.
    let u = if v[0].abs() > v[1].abs() {
        let inv = one / (v[0] * v[0] + v[2] * v[2]).sqrt();
        [-v[2] * inv, zero, v[0] * inv]
    } else {
        let inv = one / (v[1] * v[1] + v[2] * v[2]).sqrt();
        [zero, v[2] * inv, -v[1] * inv]
    };
    let w = cross(v, u);
    let mu_v = dot(v, sym_mul(b, v));
    let bu = sym_mul(b, u);
    let bw = sym_mul(b, w);
    let m00 = dot(u, bu);
    let m01 = dot(u, bw);
    let m11 = dot(w, bw);
    // One Jacobi rotation: t = tan of the angle, the smaller root of t² + 2θt − 1 = 0.
    let (cs, sn, mu0, mu1) = if m01 == zero {
        (one, zero, m00, m11)
    } else {
        let theta = (m11 - m00) / (two * m01);
        let t = one / (theta.abs() + (theta * theta + one).sqrt());
        let t = if theta < zero { -t } else { t };
        let cs = one / (t * t + one).sqrt();
        (cs, t * cs, m00 - t * m01, m11 + t * m01)
    };
    let e0 = [
        cs * u[0] - sn * w[0],
        cs * u[1] - sn * w[1],
        cs * u[2] - sn * w[2],
    ];
    let e1 = [
        sn * u[0] + cs * w[0],
        sn * u[1] + cs * w[1],
        sn * u[2] + cs * w[2],
    ];
    [(q + p * mu_v, v), (q + p * mu0, e0), (q + p * mu1, e1)]
}

/// The reference: nalgebra's `SymmetricEigen` (Householder tridiagonalisation + implicit QR), brought
/// to this module's conventions (ascending values, sign rule) so results compare column by column.
///
/// nalgebra reads the lower triangle; the input is symmetrised from the upper triangle first so both
/// solvers see the same matrix. Errors as [`sym_eigen3`] for non-finite input.
pub fn sym_eigen3_nalgebra<T: EigenScalar>(a: &Matrix3<T>) -> Result<SymEigen3<T>, EllipsoidError> {
    for (row, col) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)] {
        if !a[(row, col)].is_finite() {
            return Err(EllipsoidError::MatrixNotFinite {
                row,
                col,
                value: a[(row, col)].to_f64(),
            });
        }
    }
    let sym = Matrix3::new(
        a[(0, 0)],
        a[(0, 1)],
        a[(0, 2)],
        a[(0, 1)],
        a[(1, 1)],
        a[(1, 2)],
        a[(0, 2)],
        a[(1, 2)],
        a[(2, 2)],
    );
    let e = nalgebra::SymmetricEigen::new(sym);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&i, &j| {
        e.eigenvalues[i]
            .partial_cmp(&e.eigenvalues[j])
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut values = Vector3::zeros();
    let mut vectors = Matrix3::zeros();
    for (out, &i) in idx.iter().enumerate() {
        values[out] = e.eigenvalues[i];
        let col = e.eigenvectors.column(i);
        let v = canonical_sign([col[0], col[1], col[2]]);
        vectors.set_column(out, &Vector3::new(v[0], v[1], v[2]));
    }
    Ok(SymEigen3 { values, vectors })
}

/// `‖A − VΛVᵀ‖_F / ‖A‖_F`, computed in `f64` after scaling by the largest entry (so 1e±150 inputs
/// do not over- or underflow). Zero for the zero matrix decomposed exactly.
pub fn reconstruction_error<T: EigenScalar>(a: &Matrix3<T>, e: &SymEigen3<T>) -> f64 {
    let a64 = a.map(|x| x.to_f64());
    // Symmetrise from the upper triangle: the solver reads only that.
    let a64 = Matrix3::from_fn(|i, j| if i <= j { a64[(i, j)] } else { a64[(j, i)] });
    let scale = a64.amax();
    let v = e.vectors.map(|x| x.to_f64());
    let values = e.values.map(|x| x.to_f64());
    if scale == 0.0 {
        return values.amax();
    }
    let r = v * Matrix3::from_diagonal(&(values / scale)) * v.transpose();
    (a64 / scale - r).norm() / (a64 / scale).norm()
}

/// `‖VᵀV − I‖_F` in `f64`.
pub fn orthogonality_error<T: EigenScalar>(e: &SymEigen3<T>) -> f64 {
    let v = e.vectors.map(|x| x.to_f64());
    (v.transpose() * v - Matrix3::identity()).norm()
}

/// One named matrix of the adversarial suite.
#[derive(Debug, Clone)]
pub struct EigenCase {
    /// What the case exercises, e.g. `"gap-1e-12 x 1e100 rot3"`.
    pub name: String,
    /// The symmetric matrix (f64).
    pub matrix: Matrix3<f64>,
}

/// `R diag(d) Rᵀ`, symmetrised.
fn rotated(r: &Matrix3<f64>, d: [f64; 3]) -> Matrix3<f64> {
    let m = r * Matrix3::from_diagonal(&Vector3::from(d)) * r.transpose();
    (m + m.transpose()) * 0.5
}

/// The adversarial suite (docs/design.md §8), seeded: exact diagonal input; zero; multiples of
/// the identity; triple and double eigenvalues under random rotations; near-degenerate gaps from
/// 1e-8 to 1e-15 (pairs and near-triples); anisotropy ratios 1e-2 to 1e-12 (flat, cylinder, graded);
/// indefinite spectra; random symmetric matrices; and every structured case scaled by 10^s for
/// s ∈ {−150, −100, −50, −30, 0, 30, 50, 100, 150}. About 1500 matrices; cost to build: ~1 ms.
pub fn adversarial_suite(seed: u64) -> Vec<EigenCase> {
    let mut rng = SplitMix64::new(seed);
    // (name, spectrum, rotate?)
    let mut base: Vec<(String, [f64; 3], bool)> =
        vec![("diag-distinct".into(), [3.0, -1.0, 2.0], false)];
    base.push(("diag-repeated".into(), [2.0, 2.0, -5.0], false));
    base.push(("diag-wide".into(), [1e100, 1.0, -1e-100], false));
    base.push(("diag-tiny-entry".into(), [1.0, 1e-300, 0.5], false));
    base.push(("identity".into(), [1.0, 1.0, 1.0], false));
    base.push(("triple".into(), [-3.5, -3.5, -3.5], true));
    base.push(("double-low".into(), [1.0, 1.0, 2.0], true));
    base.push(("double-high".into(), [-1.0, 2.0, 2.0], true));
    base.push(("double-zero".into(), [0.0, 0.0, 1.0], true));
    base.push(("indefinite".into(), [-2.0, 0.5, 3.0], true));
    for e in 8..=15 {
        let g = 10f64.powi(-e);
        base.push((format!("gap-1e-{e}"), [1.0, 1.0 + g, 3.0], true));
        base.push((
            format!("near-triple-1e-{e}"),
            [1.0, 1.0 + g, 1.0 + 2.0 * g],
            true,
        ));
        base.push((format!("gap-top-1e-{e}"), [-2.0, 1.0, 1.0 + g], true));
    }
    for e in (2..=12).step_by(2) {
        let r = 10f64.powi(-e);
        base.push((format!("flat-1e-{e}"), [r, 1.0, 1.0], true));
        base.push((format!("cylinder-1e-{e}"), [r, r, 1.0], true));
        base.push((format!("graded-1e-{e}"), [r, r.sqrt(), 1.0], true));
    }
    let scales = [-150, -100, -50, -30, 0, 30, 50, 100, 150];
    let mut out = vec![EigenCase {
        name: "zero".into(),
        matrix: Matrix3::zeros(),
    }];
    for (name, d, rotate) in &base {
        let rotations: Vec<(String, Matrix3<f64>)> = if *rotate {
            (0..3)
                .map(|i| (format!("rot{i}"), rng.rotation()))
                .collect()
        } else {
            vec![("axes".into(), Matrix3::identity())]
        };
        for (rname, r) in &rotations {
            let m = rotated(r, *d);
            for &s in &scales {
                let f = 10f64.powi(s);
                let scaled = m * f;
                if scaled.iter().all(|x| x.is_finite()) {
                    out.push(EigenCase {
                        name: format!("{name} {rname} x1e{s}"),
                        matrix: scaled,
                    });
                }
            }
        }
    }
    for i in 0..60 {
        let mut m = Matrix3::zeros();
        for r in 0..3 {
            for c in r..3 {
                let x = rng.range(-1.0, 1.0);
                m[(r, c)] = x;
                m[(c, r)] = x;
            }
        }
        out.push(EigenCase {
            name: format!("random-{i}"),
            matrix: m,
        });
    }
    out
}

/// The cases of [`adversarial_suite`] that `f32` can hold: largest entry within `[1e-30, 1e30]`
/// (or zero), cast to `f32`.
pub fn adversarial_suite_f32(seed: u64) -> Vec<(String, Matrix3<f32>)> {
    adversarial_suite(seed)
        .into_iter()
        .filter(|c| {
            let m = c.matrix.amax();
            m == 0.0 || (1e-30..=1e30).contains(&m)
        })
        .map(|c| (c.name, c.matrix.map(|x| x as f32)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponent_and_pow2_round_trip() {
        for x in [1.0f64, 1.5, 3.0, 1e-300, 1e300, 5e-324, 2.2e-308] {
            let e = x.exponent();
            assert!(f64::powi(2.0, e) <= x * 1.0000001 || e < -1022, "{x}");
            if (-1022..=1023).contains(&e) {
                assert!(x / f64::pow2(e) >= 1.0 && x / f64::pow2(e) < 2.0, "{x}");
            }
        }
        assert_eq!(5e-324f64.exponent(), -1074);
        assert_eq!(1e-45f32.exponent(), -149);
        assert_eq!(3.0f32.exponent(), 1);
        assert_eq!(f32::pow2(-3), 0.125);
    }

    #[test]
    fn diagonal_is_exact_and_sorted() {
        let a = Matrix3::from_diagonal(&Vector3::new(3.0, -1.0, 2.0));
        let e = sym_eigen3(&a).unwrap();
        assert_eq!(e.values, Vector3::new(-1.0, 2.0, 3.0));
        assert_eq!(
            e.vectors,
            Matrix3::new(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0)
        );
    }

    #[test]
    fn sign_convention_holds() {
        let mut rng = SplitMix64::new(3);
        for _ in 0..50 {
            let r = rng.rotation();
            let a = rotated(&r, [1.0, 2.0, 4.0]);
            let e = sym_eigen3(&a).unwrap();
            for i in 0..3 {
                let c = e.vectors.column(i);
                let k = c.iamax();
                assert!(c[k] > 0.0);
            }
            assert!((e.rotation().determinant() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn matches_nalgebra_on_well_separated_spectra() {
        let mut rng = SplitMix64::new(11);
        for _ in 0..200 {
            let r = rng.rotation();
            let d = [
                rng.range(-3.0, -1.0),
                rng.range(0.0, 1.0),
                rng.range(2.0, 5.0),
            ];
            let a = rotated(&r, d);
            let ours = sym_eigen3(&a).unwrap();
            let reference = sym_eigen3_nalgebra(&a).unwrap();
            assert!((ours.values - reference.values).amax() < 1e-13);
            assert!((ours.vectors - reference.vectors).amax() < 1e-12);
        }
    }

    #[test]
    fn non_finite_is_an_error() {
        let mut a = Matrix3::<f64>::identity();
        a[(1, 2)] = f64::NAN;
        assert!(matches!(
            sym_eigen3(&a),
            Err(EllipsoidError::MatrixNotFinite { row: 1, col: 2, .. })
        ));
        let b = Matrix3::<f64>::identity() * f64::MAX;
        let mut b2 = b;
        b2[(0, 1)] = f64::MAX;
        assert!(matches!(
            sym_eigen3(&b2),
            Err(EllipsoidError::EigenOverflow { .. })
        ));
    }
}
