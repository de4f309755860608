//! Dense reference solution: the minimum-norm least-squares solution by eigen-decomposition of
//! the (small) normal matrix, for checking the iterative solvers.

use nalgebra::{DMatrix, DVector};

use super::FitError;
use super::assemble::NormalEquations;

/// Largest node count [`dense_min_norm`] accepts (a 1500² eigen-decomposition takes seconds).
pub const DENSE_MAX_NODES: usize = 1500;

/// The minimum-norm solution of `(AᵀA + c·L)·a = Aᵀd` (`c = λ·tr(AᵀA)/tr(L)`), via the
/// symmetric eigen-decomposition `V·Λ·Vᵀ` of the dense matrix: `a = Σ_{λᵢ > τ} vᵢ (vᵢᵀ b)/λᵢ`
/// with `τ = 1e-12·max λᵢ`. For `λ = 0` this is the minimum-norm least-squares fit
/// (`pinv(AᵀA)·Aᵀd = pinv(A)·d`). Errors: more than [`DENSE_MAX_NODES`] nodes.
/// Cost: `O(n³)` time, `O(n²)` memory.
pub fn dense_min_norm(normal: &NormalEquations, lambda: f64) -> Result<Vec<f64>, FitError> {
    let n = normal.layout().node_count();
    if n > DENSE_MAX_NODES {
        return Err(FitError::TooLarge {
            what: "dense reference",
            nodes: n,
            limit: DENSE_MAX_NODES,
        });
    }
    let a = normal.matrix(lambda);
    let mut m = DMatrix::<f64>::zeros(n, n);
    for (v, (i, j)) in a.iter() {
        m[(i, j)] += *v;
    }
    let eig = m.symmetric_eigen();
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    let tau = 1e-12 * lmax;
    let b = DVector::from_column_slice(normal.rhs());
    let mut x = DVector::<f64>::zeros(n);
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        if l > tau {
            let v = eig.eigenvectors.column(k);
            x += v * (v.dot(&b) / l);
        }
    }
    Ok(x.iter().copied().collect())
}
