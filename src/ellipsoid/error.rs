//! Typed errors of the ellipsoid module, the eigen-solver's included: what was wrong, and where.

use thiserror::Error;

/// Why an ellipsoid, a filter or a volume was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EllipsoidError {
    /// A semi-axis length is NaN or infinite.
    #[error("length {axis} is not finite: {value}")]
    NonFiniteLength {
        /// Axis index (0, 1, 2).
        axis: usize,
        /// The offending value.
        value: f64,
    },
    /// A semi-axis length is zero or negative: the ellipsoid is degenerate.
    #[error("length {axis} is not positive: {value}")]
    NonPositiveLength {
        /// Axis index (0, 1, 2).
        axis: usize,
        /// The offending value.
        value: f64,
    },
    /// A length lies outside [`MIN_LENGTH`](super::MIN_LENGTH), [`MAX_LENGTH`](super::MAX_LENGTH).
    #[error("length {axis} = {value:e} is outside the supported range [1e-50, 1e50]")]
    LengthOutOfRange {
        /// Axis index (0, 1, 2).
        axis: usize,
        /// The offending value.
        value: f64,
    },
    /// The smallest length over the largest is below [`MIN_ASPECT`](super::MIN_ASPECT).
    #[error("aspect ratio min/max length = {ratio:e} is below the supported 1e-6")]
    TooAnisotropic {
        /// min length / max length.
        ratio: f64,
    },
    /// A basis or matrix entry is NaN or infinite.
    #[error("{what} has a non-finite entry")]
    NonFiniteMatrix {
        /// Which input ("basis", "quadratic form", "direction", …).
        what: &'static str,
    },
    /// The basis given is not orthonormal (‖RᵀR − I‖_F above 1e-9).
    #[error("basis is not orthonormal: ‖RᵀR − I‖ = {deviation:e}")]
    NotOrthonormal {
        /// ‖RᵀR − I‖_F.
        deviation: f64,
    },
    /// A quadratic form (or moment matrix) is not positive definite.
    #[error("{what} is not positive definite (eigenvalue {eigenvalue:e})")]
    NotPositiveDefinite {
        /// Which matrix.
        what: &'static str,
        /// Its smallest eigenvalue.
        eigenvalue: f64,
    },
    /// A direction has zero length (or is NaN).
    #[error("direction is zero or not finite")]
    BadDirection,
    /// Filtering was asked for with no ellipsoids.
    #[error("no ellipsoids to filter")]
    Empty,
    /// Ellipsoids and weights differ in number.
    #[error("{ellipsoids} ellipsoids but {weights} weights")]
    CountMismatch {
        /// Number of ellipsoids.
        ellipsoids: usize,
        /// Number of weights.
        weights: usize,
    },
    /// A weight is negative, NaN or infinite.
    #[error("weight {index} is invalid: {value}")]
    BadWeight {
        /// Index of the weight.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The weights sum to zero: there is nothing to average.
    #[error("total weight is zero")]
    ZeroTotalWeight,
    /// A parameter is out of its documented range.
    #[error("parameter {name} is invalid: {reason}")]
    BadParameter {
        /// Parameter name.
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// A voxel volume is inconsistent (sizes, non-finite samples).
    #[error("volume: {0}")]
    BadVolume(String),
    /// The eigen-solver refused a matrix: an entry of its upper triangle is NaN or infinite.
    #[error("matrix entry ({row}, {col}) is not finite: {value}")]
    MatrixNotFinite {
        /// Row of the entry (0-based).
        row: usize,
        /// Column of the entry (0-based).
        col: usize,
        /// The offending value, as f64.
        value: f64,
    },
    /// The eigen-solver refused a matrix: an eigenvalue overflowed when the matrix was scaled back
    /// (entries near the largest float).
    #[error("an eigenvalue overflows the scalar type (largest entry {max_abs:e})")]
    EigenOverflow {
        /// Largest absolute entry of the input, as f64.
        max_abs: f64,
    },
}
