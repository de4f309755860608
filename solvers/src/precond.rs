//! Preconditioners: identity, Jacobi (diagonal) and SSOR (symmetric successive over-relaxation).
//!
//! Rows whose diagonal is zero (in the trilinear fit: nodes that no defined sample touches, whose
//! whole row and column are zero) are given the identity: `z_i = r_i`. In a consistent system
//! such a row has `b_i = 0`, so the residual there stays zero and the solution keeps the initial
//! guess (0 by default: the minimum-norm value).

use crate::error::SolverError;
use crate::operator::LinearOperator;
use serde::{Deserialize, Serialize};
use sprs::CsMat;

/// A preconditioner `M ≈ A`, applied as `z = M⁻¹·r`.
pub trait Preconditioner: Sync {
    /// `z ← M⁻¹·r` (`z` is overwritten; both of length `n`).
    fn apply(&self, r: &[f64], z: &mut [f64]);
    /// `z ← M⁻ᵀ·r` (used by BiCG for the shadow system). Default: [`Preconditioner::apply`],
    /// right for a symmetric `M`.
    fn apply_transpose(&self, r: &[f64], z: &mut [f64]) {
        self.apply(r, z);
    }
    /// Short name for reports (`"none"`, `"jacobi"`, `"ssor"`).
    fn name(&self) -> &'static str;
    /// `z ← M⁻¹·r` and returns `rᵀz` (what CG does next). Default: [`Preconditioner::apply`]
    /// then [`crate::vecops::dot`]; [`Jacobi`] fuses both into one pass, with the same bits.
    fn apply_dot(&self, r: &[f64], z: &mut [f64]) -> f64 {
        self.apply(r, z);
        crate::vecops::dot(r, z)
    }
}

/// Which preconditioner a solver builds from the matrix (see [`build_preconditioner`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub enum PreconditionerKind {
    /// No preconditioning (`M = I`).
    None,
    /// `M = diag(A)` (identity on zero-diagonal rows). For LSQR/LSMR: columns scaled by their
    /// norms, which is Jacobi on `AᵀA`. The default: on the fit's normal equations, whose
    /// diagonal spans many orders of magnitude, it is what makes the system well conditioned.
    #[default]
    Jacobi,
    /// SSOR with relaxation `omega ∈ (0, 2)` (`omega = 1`: symmetric Gauss–Seidel). Square
    /// methods only; sequential triangular solves (O(nnz) each, not parallel).
    Ssor {
        /// Relaxation factor, in `(0, 2)`.
        omega: f64,
    },
}

impl PreconditionerKind {
    /// Short name for reports.
    pub fn name(&self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Jacobi => "jacobi",
            Self::Ssor { .. } => "ssor",
        }
    }
}

/// `M = I`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Identity;

impl Preconditioner for Identity {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
    }
    fn name(&self) -> &'static str {
        "none"
    }
}

/// `M = diag(A)`, identity where the diagonal is zero. Cost: `n` multiplications per apply.
#[derive(Debug, Clone)]
pub struct Jacobi {
    inv_diag: Vec<f64>,
    zero_rows: usize,
}

impl Jacobi {
    /// Builds from a diagonal (`diag[i] == 0` → identity on row `i`). Errors on a non-finite
    /// entry. Cost: O(n).
    pub fn from_diagonal(diag: &[f64]) -> Result<Self, SolverError> {
        crate::error::check_finite("diagonal", diag)?;
        let mut zero_rows = 0;
        let inv_diag = diag
            .iter()
            .map(|&d| {
                if d == 0.0 {
                    zero_rows += 1;
                    1.0
                } else {
                    1.0 / d
                }
            })
            .collect();
        Ok(Self {
            inv_diag,
            zero_rows,
        })
    }
    /// Builds from the diagonal of a square matrix. Cost: O(nnz).
    pub fn new(a: &CsMat<f64>) -> Result<Self, SolverError> {
        Self::from_diagonal(&diagonal(a))
    }
    /// Number of rows whose diagonal was zero (treated as identity).
    pub fn zero_rows(&self) -> usize {
        self.zero_rows
    }
}

impl Preconditioner for Jacobi {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        crate::vecops::scale_into(&self.inv_diag, r, z);
    }
    fn name(&self) -> &'static str {
        "jacobi"
    }
    fn apply_dot(&self, r: &[f64], z: &mut [f64]) -> f64 {
        crate::vecops::scale_dot(&self.inv_diag, r, z)
    }
}

/// The diagonal of a matrix (zeros where not stored; length `min(rows, cols)`). Cost: O(nnz).
pub fn diagonal(a: &CsMat<f64>) -> Vec<f64> {
    let n = a.rows().min(a.cols());
    let mut d = vec![0.0; n];
    for (i, lane) in a.outer_iterator().enumerate().take(n) {
        for (j, v) in lane.iter() {
            if j == i {
                d[i] += v;
            }
        }
    }
    d
}

/// SSOR: `M = ω/(2−ω) · (D/ω + L)·(D/ω)⁻¹·(D/ω + U)` with `A = L + D + U`.
///
/// Rows with a zero (or unstored) diagonal use `D_ii = 1`. Each apply is one forward and one
/// backward triangular sweep: `4·nnz` flops, sequential.
#[derive(Debug, Clone)]
pub struct Ssor {
    omega: f64,
    indptr: Vec<usize>,
    indices: Vec<usize>,
    data: Vec<f64>,
    /// Start of the diagonal/upper part within each row (`indptr[i] ≤ split[i] ≤ indptr[i+1]`).
    split: Vec<usize>,
    /// `D_ii/ω` (with `D_ii = 1` on zero-diagonal rows).
    dw: Vec<f64>,
    zero_rows: usize,
}

impl Ssor {
    /// Builds from a square matrix (CSR or CSC, any index type through
    /// [`LinearOperator::to_csr`]). Errors: `omega ∉ (0, 2)`, non-square, non-finite entries.
    /// Cost: a copy of the matrix.
    pub fn new(a: &CsMat<f64>, omega: f64) -> Result<Self, SolverError> {
        if !(omega > 0.0 && omega < 2.0) {
            return Err(SolverError::InvalidParameter {
                name: "omega",
                value: format!("{omega}"),
                reason: "SSOR relaxation must lie in (0, 2)",
            });
        }
        if a.rows() != a.cols() {
            return Err(SolverError::NotSquare {
                method: "SSOR",
                nrows: a.rows(),
                ncols: a.cols(),
            });
        }
        a.check_finite()?;
        let csr = if a.is_csr() { a.clone() } else { a.to_csr() };
        let n = csr.rows();
        let indptr: Vec<usize> = csr.proper_indptr().to_vec();
        let indices = csr.indices().to_vec();
        let data = csr.data().to_vec();
        let mut split = vec![0; n];
        let mut dw = vec![0.0; n];
        let mut zero_rows = 0;
        for i in 0..n {
            let (s, e) = (indptr[i], indptr[i + 1]);
            split[i] = s + indices[s..e].partition_point(|&j| j < i);
            let d: f64 = (s..e).filter(|&k| indices[k] == i).map(|k| data[k]).sum();
            dw[i] = if d == 0.0 {
                zero_rows += 1;
                1.0 / omega
            } else {
                d / omega
            };
        }
        Ok(Self {
            omega,
            indptr,
            indices,
            data,
            split,
            dw,
            zero_rows,
        })
    }
    /// Number of rows whose diagonal was zero (treated as `D_ii = 1`).
    pub fn zero_rows(&self) -> usize {
        self.zero_rows
    }
    fn lower(&self, i: usize) -> std::ops::Range<usize> {
        self.indptr[i]..self.split[i]
    }
    fn upper(&self, i: usize) -> std::ops::Range<usize> {
        // Skip the diagonal entry (if stored) at the start of the upper part.
        let mut s = self.split[i];
        while s < self.indptr[i + 1] && self.indices[s] == i {
            s += 1;
        }
        s..self.indptr[i + 1]
    }
    fn factor(&self) -> f64 {
        (2.0 - self.omega) / self.omega
    }
}

impl Preconditioner for Ssor {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        let n = r.len();
        // Forward: (D/ω + L) w = r, then w ← (D/ω) w.
        for i in 0..n {
            let mut s = r[i];
            for k in self.lower(i) {
                s -= self.data[k] * z[self.indices[k]];
            }
            z[i] = s / self.dw[i];
        }
        z.iter_mut().zip(&self.dw).for_each(|(zi, d)| *zi *= d);
        // Backward: (D/ω + U) z = w.
        for i in (0..n).rev() {
            let mut s = z[i];
            for k in self.upper(i) {
                s -= self.data[k] * z[self.indices[k]];
            }
            z[i] = s / self.dw[i];
        }
        let f = self.factor();
        z.iter_mut().for_each(|v| *v *= f);
    }
    fn apply_transpose(&self, r: &[f64], z: &mut [f64]) {
        let n = r.len();
        // (D/ω + U)ᵀ w = r, column-oriented over the rows of U.
        let mut t = r.to_vec();
        for i in 0..n {
            let wi = t[i] / self.dw[i];
            z[i] = wi;
            for k in self.upper(i) {
                t[self.indices[k]] -= self.data[k] * wi;
            }
        }
        for i in 0..n {
            t[i] = z[i] * self.dw[i];
        }
        // (D/ω + L)ᵀ z = t, column-oriented over the rows of L, backwards.
        for i in (0..n).rev() {
            let zi = t[i] / self.dw[i];
            z[i] = zi;
            for k in self.lower(i) {
                t[self.indices[k]] -= self.data[k] * zi;
            }
        }
        let f = self.factor();
        z.iter_mut().for_each(|v| *v *= f);
    }
    fn name(&self) -> &'static str {
        "ssor"
    }
}

/// Builds the preconditioner `kind` for the square operator `a`. Errors when `kind` needs
/// matrix entries and `a` exposes none ([`LinearOperator::to_csr`] is `None`), or on a bad
/// parameter. Cost: O(nnz).
pub fn build_preconditioner<Op: LinearOperator + ?Sized>(
    a: &Op,
    kind: PreconditionerKind,
) -> Result<Box<dyn Preconditioner>, SolverError> {
    a.check_finite()?;
    let need_csr = || {
        a.to_csr().ok_or(SolverError::PreconditionerUnavailable {
            preconditioner: kind.name(),
            reason: "the operator exposes no matrix entries (to_csr is None)",
        })
    };
    Ok(match kind {
        PreconditionerKind::None => Box::new(Identity),
        // Only the diagonal is needed: no copy of the matrix.
        PreconditionerKind::Jacobi => Box::new(Jacobi::from_diagonal(&a.diagonal().ok_or(
            SolverError::PreconditionerUnavailable {
                preconditioner: kind.name(),
                reason: "the operator exposes no matrix entries (diagonal is None)",
            },
        )?)?),
        PreconditionerKind::Ssor { omega } => Box::new(Ssor::new(&need_csr()?, omega)?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sprs::TriMat;

    /// Builds the dense matrix of `M` (SSOR) explicitly and checks `M·(M⁻¹ r) = r` and
    /// `Mᵀ·(M⁻ᵀ r) = r` on a nonsymmetric matrix with a zero-diagonal row.
    #[test]
    fn ssor_inverse_and_transpose_inverse_are_consistent() {
        let n = 6;
        let mut t = TriMat::new((n, n));
        for i in 0..n {
            if i != 3 {
                t.add_triplet(i, i, 4.0 + i as f64);
            }
            if i + 1 < n {
                t.add_triplet(i, i + 1, -1.0 - 0.1 * i as f64);
            }
            if i >= 2 {
                t.add_triplet(i, i - 2, 0.5);
            }
        }
        let a: CsMat<f64> = t.to_csr();
        let omega = 1.3;
        let m = Ssor::new(&a, omega).unwrap();
        assert_eq!(m.zero_rows(), 1);
        // Dense M = c (D/ω + L) (D/ω)^-1 (D/ω + U).
        let mut dense = vec![vec![0.0; n]; n];
        for (i, row) in a.outer_iterator().enumerate() {
            for (j, &v) in row.iter() {
                dense[i][j] = v;
            }
        }
        let dw: Vec<f64> = (0..n)
            .map(|i| if dense[i][i] == 0.0 { 1.0 } else { dense[i][i] } / omega)
            .collect();
        let mut lo = vec![vec![0.0; n]; n];
        let mut up = vec![vec![0.0; n]; n];
        for i in 0..n {
            for j in 0..n {
                if j < i {
                    lo[i][j] = dense[i][j];
                } else if j > i {
                    up[i][j] = dense[i][j];
                }
            }
            lo[i][i] = dw[i];
            up[i][i] = dw[i];
        }
        let c = omega / (2.0 - omega);
        let mut mm = vec![vec![0.0; n]; n];
        for i in 0..n {
            for j in 0..n {
                mm[i][j] = c * (0..n).map(|k| lo[i][k] * up[k][j] / dw[k]).sum::<f64>();
            }
        }
        let r: Vec<f64> = (0..n).map(|i| 1.0 + i as f64 * 0.7).collect();
        let mut z = vec![0.0; n];
        m.apply(&r, &mut z);
        for i in 0..n {
            let back: f64 = (0..n).map(|j| mm[i][j] * z[j]).sum();
            assert!((back - r[i]).abs() < 1e-12, "row {i}: {back} vs {}", r[i]);
        }
        m.apply_transpose(&r, &mut z);
        for i in 0..n {
            let back: f64 = (0..n).map(|j| mm[j][i] * z[j]).sum();
            assert!((back - r[i]).abs() < 1e-12, "row {i}: {back} vs {}", r[i]);
        }
    }

    #[test]
    fn jacobi_identity_on_zero_diagonal() {
        let j = Jacobi::from_diagonal(&[2.0, 0.0, -4.0]).unwrap();
        assert_eq!(j.zero_rows(), 1);
        let mut z = [0.0; 3];
        j.apply(&[1.0, 5.0, 1.0], &mut z);
        assert_eq!(z, [0.5, 5.0, -0.25]);
        assert!(Jacobi::from_diagonal(&[1.0, f64::NAN]).is_err());
    }

    #[test]
    fn ssor_rejects_bad_omega() {
        let a: CsMat<f64> = CsMat::eye(3);
        assert!(matches!(
            Ssor::new(&a, 2.0),
            Err(SolverError::InvalidParameter { .. })
        ));
    }
}
