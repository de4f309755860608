//! Parameters in, report out: what every solve takes and returns.

use serde::{Deserialize, Serialize};

use crate::precond::PreconditionerKind;

/// The iterative methods of this crate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Method {
    /// Preconditioned biconjugate gradient (the method of Baboud's report). Two operator products
    /// (`A·p`, `Aᵀ·p̃`) and two preconditioner applications per iteration.
    Pbicg,
    /// Preconditioned conjugate gradient: symmetric positive (semi-)definite systems. One
    /// product per iteration.
    Pcg,
    /// Preconditioned BiCGSTAB (van der Vorst): general square systems, no `Aᵀ`. Two products
    /// per iteration.
    Bicgstab,
    /// LSQR (Paige & Saunders) on a rectangular operator: `min ‖A·x − b‖₂`. One `A·v` and one
    /// `Aᵀ·u` per iteration.
    Lsqr,
    /// LSMR (Fong & Saunders) on a rectangular operator: `min ‖A·x − b‖₂` with `‖Aᵀr‖`
    /// decreasing monotonically. One `A·v` and one `Aᵀ·u` per iteration.
    Lsmr,
}

impl Method {
    /// All methods, in report order.
    pub const ALL: [Method; 5] = [
        Method::Pbicg,
        Method::Pcg,
        Method::Bicgstab,
        Method::Lsqr,
        Method::Lsmr,
    ];
    /// Lower-case name for tables and JSON (`"pbicg"`, `"pcg"`, `"bicgstab"`, `"lsqr"`, `"lsmr"`).
    pub fn name(&self) -> &'static str {
        match self {
            Self::Pbicg => "pbicg",
            Self::Pcg => "pcg",
            Self::Bicgstab => "bicgstab",
            Self::Lsqr => "lsqr",
            Self::Lsmr => "lsmr",
        }
    }
    /// Whether the method solves a least-squares problem on a rectangular operator.
    pub fn is_least_squares(&self) -> bool {
        matches!(self, Self::Lsqr | Self::Lsmr)
    }
    /// Parses a name as printed by [`Method::name`] (also accepts `"bicg"` and `"cg"`).
    pub fn from_name(s: &str) -> Option<Self> {
        Some(match s.to_ascii_lowercase().as_str() {
            "pbicg" | "bicg" => Self::Pbicg,
            "pcg" | "cg" => Self::Pcg,
            "bicgstab" => Self::Bicgstab,
            "lsqr" => Self::Lsqr,
            "lsmr" => Self::Lsmr,
            _ => return None,
        })
    }
}

/// Parameters of every solve.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolveParams {
    /// Stop when the relative residual `‖b − A·x‖₂ / ‖b‖₂` is at most this (square methods), or,
    /// for LSQR/LSMR, when either that or the least-squares test
    /// `‖Aᵀr‖ / (‖A‖·‖r‖)` is at most this. Default `1e-10`. Must be positive.
    pub tolerance: f64,
    /// Iteration limit. Default `10_000`.
    pub max_iterations: usize,
    /// Preconditioner built from the matrix by the plain entry points (`pcg`, …); ignored by
    /// the `*_with` entry points that take a preconditioner. Default [`PreconditionerKind::Jacobi`].
    pub preconditioner: PreconditionerKind,
    /// Initial guess `x₀` (length `ncols`). Default `None`: zeros, which makes CG-type methods
    /// on a consistent singular system converge to a solution whose null-space part is zero.
    pub initial_guess: Option<Vec<f64>>,
}

impl Default for SolveParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_iterations: 10_000,
            preconditioner: PreconditionerKind::Jacobi,
            initial_guess: None,
        }
    }
}

/// Why a solve stopped.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum StopReason {
    /// The relative residual reached the tolerance (the system was solved).
    Tolerance,
    /// LSQR/LSMR: the least-squares optimality test `‖Aᵀr‖/(‖A‖‖r‖) ≤ tol` was met while the
    /// residual itself stays large: the system is inconsistent and `x` is a least-squares
    /// solution. Counts as converged.
    LeastSquares,
    /// The iteration limit was reached first.
    MaxIterations,
    /// A scalar the recurrence divides by vanished (`quantity` names it, e.g. `"p̃ᵀAp"`):
    /// the method cannot go on. On a singular system this usually means inconsistency.
    Breakdown {
        /// The scalar that vanished.
        quantity: &'static str,
        /// Its value.
        value: f64,
        /// The iteration at which it happened (1-based).
        iteration: usize,
    },
}

/// What every solve returns besides `x`.
#[derive(Debug, Clone, Serialize)]
pub struct SolveReport {
    /// The method that ran.
    pub method: Method,
    /// The preconditioner's name (`"none"`, `"jacobi"`, `"ssor"`).
    pub preconditioner: &'static str,
    /// Iterations done.
    pub iterations: usize,
    /// Products with `A` and `Aᵀ` done, together (BiCG: two per iteration; CG: one).
    pub operator_applications: usize,
    /// Relative residual `‖b − A·x‖/‖b‖` after each iteration; entry 0 is the initial guess.
    /// Square methods: the recurrence's residual; LSQR/LSMR: their running estimate.
    pub residual_history: Vec<f64>,
    /// Relative residual `‖b − A·x‖/‖b‖` of the returned `x`, recomputed with a true product
    /// (0 when `b = 0`).
    pub relative_residual: f64,
    /// LSQR/LSMR only: `‖Aᵀr‖ / (‖A‖_F·‖r‖)` of the returned `x` (estimate), the least-squares
    /// optimality measure. `None` for square methods.
    pub normal_residual: Option<f64>,
    /// Wall time of the solve, setup (preconditioner) included, in seconds.
    pub time_s: f64,
    /// Whether the stop reason is [`StopReason::Tolerance`] or [`StopReason::LeastSquares`]
    /// and the recomputed residual confirms it.
    pub converged: bool,
    /// Why it stopped.
    pub stop_reason: StopReason,
}

/// A solution and its report.
#[derive(Debug, Clone)]
pub struct Solution {
    /// The computed `x` (length `ncols`).
    pub x: Vec<f64>,
    /// How it was obtained.
    pub report: SolveReport,
}
