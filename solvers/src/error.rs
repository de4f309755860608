//! The error type of `altrep-solvers`: bad input, said precisely.
//!
//! A solver that runs but does not reach its tolerance is **not** an error: it returns a
//! [`SolveReport`](crate::SolveReport) with `converged == false` and a
//! [`StopReason`](crate::StopReason). Errors are for input that no solve could use.

use thiserror::Error;

/// Everything that makes a solve or a MatrixMarket read/write impossible.
#[derive(Debug, Error)]
pub enum SolverError {
    /// Two sizes that must agree do not (`what` names the operand, e.g. `"right-hand side"`).
    #[error("dimension mismatch for {what}: expected {expected}, found {found}")]
    DimensionMismatch {
        /// The operand whose size is wrong.
        what: &'static str,
        /// The size the operator implies.
        expected: usize,
        /// The size that was given.
        found: usize,
    },
    /// A method for square systems (CG, BiCG, BiCGSTAB) was given a rectangular operator.
    #[error("{method} needs a square operator, got {nrows}×{ncols}")]
    NotSquare {
        /// The method that was asked for.
        method: &'static str,
        /// Rows of the operator.
        nrows: usize,
        /// Columns of the operator.
        ncols: usize,
    },
    /// A NaN or infinite value in the input (`what` names the operand, `index` the position).
    #[error("non-finite value {value} in {what} at index {index}")]
    NonFinite {
        /// The operand holding the value (`"matrix"`, `"right-hand side"`, `"initial guess"`).
        what: &'static str,
        /// Position in the operand's storage (the entry index for a matrix).
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A parameter out of its documented range (`tolerance <= 0`, SSOR `omega ∉ (0, 2)`, …).
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// Name of the parameter.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// What the accepted range is.
        reason: &'static str,
    },
    /// The preconditioner needs matrix entries (diagonal or CSR) the operator does not expose,
    /// or the method cannot use this kind of preconditioner.
    #[error("preconditioner {preconditioner} is not available here: {reason}")]
    PreconditionerUnavailable {
        /// The preconditioner that was asked for.
        preconditioner: &'static str,
        /// Why it cannot be used.
        reason: &'static str,
    },
    /// Reading or writing a file failed.
    #[error("I/O error on {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A MatrixMarket file is malformed or uses a variant this reader does not handle.
    #[error("MatrixMarket {path}, line {line}: {reason}")]
    MatrixMarket {
        /// The file (or `"<reader>"`).
        path: String,
        /// 1-based line number where the problem was found.
        line: usize,
        /// What was wrong.
        reason: String,
    },
}

/// Checks that every value of `v` is finite; `what` names the operand in the error.
///
/// Cost: one pass over `v` (branch-free over blocks of 64 values, so it vectorises; the search
/// for the index runs only when a block holds a non-finite value).
pub fn check_finite(what: &'static str, v: &[f64]) -> Result<(), SolverError> {
    // Exponent bits all ones ⇔ infinite or NaN.
    const EXP: u64 = 0x7ff0_0000_0000_0000;
    let clean = v.chunks(64).all(|c| {
        c.iter()
            .fold(0u64, |bad, x| bad | u64::from(x.to_bits() & EXP == EXP))
            == 0
    });
    if clean {
        return Ok(());
    }
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(SolverError::NonFinite {
            what,
            index,
            value: v[index],
        }),
        None => Ok(()),
    }
}

/// Checks `found == expected` for the operand `what`.
pub fn check_len(what: &'static str, expected: usize, found: usize) -> Result<(), SolverError> {
    if expected == found {
        Ok(())
    } else {
        Err(SolverError::DimensionMismatch {
            what,
            expected,
            found,
        })
    }
}
