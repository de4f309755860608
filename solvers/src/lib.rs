//! # altrep-solvers — sparse iterative solvers on `sprs` matrices
//!
//! The trilinear least-squares fit of altrep (docs/design.md §5) produces a sparse symmetric
//! positive **semi**-definite system (normal equations, at most 27 non-zeros per row), singular
//! where nodes are not touched by any defined sample. Baboud's report solved it with a
//! preconditioned biconjugate gradient (PBiCG). This crate implements PBiCG and the methods a
//! numerical analyst holds it against:
//!
//! | method | for | per iteration |
//! |---|---|---|
//! | [`pbicg`] | general square `A` | `A·p`, `Aᵀ·p̃`, 2 preconditioner solves |
//! | [`pcg`] | symmetric positive (semi-)definite `A` | `A·p`, 1 preconditioner solve |
//! | [`bicgstab`] | general square `A` | 2 × `A·p`, 2 preconditioner solves |
//! | [`lsqr`], [`lsmr`] | rectangular `A`, `min ‖A·x − b‖` | `A·v`, `Aᵀ·u` |
//!
//! Solvers take any [`LinearOperator`] (implemented for `sprs` CSR/CSC matrices with a
//! rayon-parallel product, [`par_mul_vec`]; [`BlockedCsr`] wraps a CSR matrix for a product
//! 3.5× faster on the fit's stencil sparsity, with bitwise the same results) and a
//! [`Preconditioner`] ([`Identity`], [`Jacobi`], [`Ssor`]; zero-diagonal rows get the
//! identity). Every solve takes [`SolveParams`] and returns a
//! [`Solution`] whose [`SolveReport`] says how many iterations and operator products it took,
//! the relative-residual history, the time, whether it converged and why it stopped
//! ([`StopReason`]): non-convergence and breakdown are reported, never hidden. Bad input
//! (mismatched sizes, NaN) is a [`SolverError`]. [`io`] reads and writes MatrixMarket files so
//! external solvers can be compared on the same system.
//!
//! ```
//! use altrep_solvers::{pcg, SolveParams};
//! use sprs::TriMat;
//! // 1-D Laplacian with a Dirichlet end: SPD.
//! let n = 50;
//! let mut t = TriMat::new((n, n));
//! for i in 0..n {
//!     t.add_triplet(i, i, 2.0);
//!     if i + 1 < n {
//!         t.add_triplet(i, i + 1, -1.0);
//!         t.add_triplet(i + 1, i, -1.0);
//!     }
//! }
//! let a: sprs::CsMat<f64> = t.to_csr();
//! let b = vec![1.0; n];
//! let sol = pcg(&a, &b, &SolveParams::default()).unwrap();
//! assert!(sol.report.converged && sol.report.relative_residual <= 1e-10);
//! ```

pub mod blocked;
pub mod error;
pub mod io;
pub mod krylov;
pub mod lsq;
pub mod operator;
pub mod parallel;
pub mod precond;
pub mod report;
pub mod vecops;

pub use blocked::BlockedCsr;
pub use error::SolverError;
pub use krylov::{bicgstab, bicgstab_with, pbicg, pbicg_with, pcg, pcg_with};
pub use lsq::{lsmr, lsqr};
pub use operator::{LinearOperator, par_mul_vec, par_mul_vec_transpose};
pub use parallel::{Parallelism, parallelism, with_parallelism};
pub use precond::{
    Identity, Jacobi, Preconditioner, PreconditionerKind, Ssor, build_preconditioner,
};
pub use report::{Method, Solution, SolveParams, SolveReport, StopReason};

/// Runs `method` on `A·x = b` (square methods) or `min ‖A·x − b‖` (LSQR/LSMR) with the
/// preconditioner `params.preconditioner`. Cost: that of the method (see the crate table).
pub fn solve<Op: LinearOperator + ?Sized>(
    method: Method,
    a: &Op,
    b: &[f64],
    params: &SolveParams,
) -> Result<Solution, SolverError> {
    match method {
        Method::Pbicg => pbicg(a, b, params),
        Method::Pcg => pcg(a, b, params),
        Method::Bicgstab => bicgstab(a, b, params),
        Method::Lsqr => lsqr(a, b, params),
        Method::Lsmr => lsmr(a, b, params),
    }
}
