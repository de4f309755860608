//! # Trilinear least-squares fit (docs/design.md §5, appendix of Baboud's report)
//!
//! Approximate `f : [0,1]³ → R`, known by samples `d` on a fine `Nx × Ny × Nz` grid (some
//! undefined), by `g`, the trilinear interpolant of node values `a[i,j,k]` on a coarse grid of
//! `Ax × Ay × Az` cells, minimising
//!
//! ```text
//! E(a) = Σ_defined (d − g)²  +  c · Σ_edges (a_p − a_q)²,     c = λ · tr(AᵀA) / tr(L)
//! ```
//!
//! where `A` is the design matrix (row = the 8 trilinear weights of a sample) and `L` the graph
//! Laplacian of the node grid (`aᵀLa` = the edge sum). Dividing by `tr(L)` and multiplying by
//! `tr(AᵀA)` makes `λ` dimensionless: the penalty is `λ` times as strong as the data term per
//! node, whatever the sample count. The normal equations `(AᵀA + c·L)·a = Aᵀd` are sparse
//! (27 non-zeros per row), symmetric positive semi-definite, and singular when `λ = 0` and some
//! node is touched by no defined sample; they are assembled in parallel without the design
//! matrix ([`NormalEquations`]) and solved with `altrep-solvers`. The design matrix is built
//! only for LSQR/LSMR ([`DesignMatrix`]).
//!
//! Why `λ > 0` by default: unregularised least squares lets weakly supported nodes (a corner
//! touched by a few samples with tiny weights) take values far outside the data range, which
//! is what broke 8-bit storage in the source. The membrane penalty pulls such nodes towards
//! their neighbours (for `λ > 0`, a node touched by no sample is the average of its
//! neighbours), so the coefficients stay near the data range. It also biases slopes slightly;
//! [`DEFAULT_LAMBDA`] was chosen from the `altrep fit-bench` sweep.
//!
//! ## Conventions (written once, here and in [`grid`])
//!
//! - **Axes**: `x, y, z` = axis 0, 1, 2; arrays are stored x fastest (`i + N_x·(j + N_y·k)`).
//! - **Samples**: sample `(i, j, k)` sits at `((i + ½)/Nx, (j + ½)/Ny, (k + ½)/Nz)`, the cell
//!   centres, on periodic and non-periodic axes alike ([`grid::sample_coordinate`]); other
//!   positions can be given with [`FitSamples::with_coordinates`].
//! - **Nodes**: node `i` of an axis of `A` cells sits at `u = i/A`. A non-periodic axis has
//!   `A + 1` nodes (`i = 0..=A`); a periodic axis has `A` nodes, node `A` being node 0, so `g`
//!   has period 1 along it and no seam.
//! - **Evaluation** ([`TrilinearGrid::eval`]): node coordinate `t = u·A`; non-periodic axes clamp
//!   `u` to `[0, 1]`, periodic axes wrap `t` modulo `A`; `g` blends the 8 nodes around `t` with
//!   weights `(1 − α, α)` per axis.
//! - **GPU texture**: store node `(i, j, k)` in texel `(i, j, k)` of a 3D texture of
//!   `nodes = (A+1 or A)` texels per axis, with linear filtering, clamp-to-edge addressing on
//!   non-periodic axes and repeat on periodic ones. Texel centre `i` is at `s = (i + ½)/N`; fetch
//!   at `s = (u·A + ½)/N` ([`TrilinearGrid::texture_coordinate`]). The hardware then computes
//!   `t = s·N − ½ = u·A`, exactly `eval`'s node coordinate, so one fetch returns `g(u)` (up to
//!   the GPU's 8-bit sub-texel weight precision, modelled by [`TrilinearGrid::eval_texture`]).
//!
//! ## Cost (15 × 8 × 16 cells, z periodic, 128 × 64 × 256 samples of which 1.26 million defined,
//! 2 shared cores; `altrep fit-bench`, figures in `bench/RESULTS.md`)
//! Assembly of the normal equations ≈ 35–40 ms; solve with PCG + Jacobi ≈ 6 ms (60 iterations);
//! error and quantisation report ≈ 0.15–0.35 s. LSQR/LSMR need the 1.26 M × 2304 design matrix
//! (≈ 0.4 s to build, 120 MB) and take ≈ 0.5–2 s per solve: use them as a cross-check only.

pub mod assemble;
pub mod dense;
pub mod grid;
pub mod quantize;

use std::time::Instant;

use altrep_solvers::{
    BlockedCsr, Method, PreconditionerKind, SolveParams, SolveReport, SolverError, par_mul_vec,
    solve,
};
use rayon::prelude::*;
use serde::Serialize;
use thiserror::Error;

/// The error statistics of a fit ([`error_stats`]), kept at their old path `fit::ErrorStats`;
/// they live in [`crate::stats`].
pub use crate::stats::ErrorStats;
pub use assemble::{DataStats, DesignMatrix, NodeLayout, NormalEquations};
pub use dense::{DENSE_MAX_NODES, dense_min_norm};
pub use grid::{FitSamples, TrilinearGrid, axis_weight, node_count, sample_coordinate};
pub use quantize::{Quantized, quantize};

/// Default regularisation weight λ (dimensionless; see the module docs), chosen from the
/// `altrep fit-bench` sweeps (15×8×16 cells, 128×64×256 samples, 430 untouched nodes):
///
/// | λ | smooth: RMS / max err | smooth: coef range | smooth: RMS 8-bit | step: coef range |
/// |---|---|---|---|---|
/// | 0 | 0.00620 / 0.0350 | [−195, 72] | 0.178 | [−141, 77] |
/// | 1e-4 | 0.00621 / 0.0349 | [−1.98, 3.47] | 0.00706 | [−1.49, 6.30] |
/// | 1e-3 | 0.00622 / 0.0375 | [−1.82, 3.47] | 0.00707 | [−1.49, 6.16] |
/// | 1e-2 | 0.00639 / 0.0867 | [−1.74, 3.44] | 0.00732 | [−1.48, 5.64] |
///
/// (data ranges: smooth [−1.68, 3.35], step [−1.22, 5.35]). `1e-4` brings the coefficients
/// back near the data range (8-bit error 25× lower than at λ = 0) at no measurable cost in
/// fit error; from `1e-3` the slope bias starts to raise the maximum error on smooth data.
pub const DEFAULT_LAMBDA: f64 = 1e-4;

/// Everything that makes a fit impossible.
#[derive(Debug, Error)]
pub enum FitError {
    /// A grid has zero size along an axis.
    #[error("{what} has zero size along axis {axis}")]
    ZeroSize {
        /// `"sample grid"` or `"coarse grid"`.
        what: &'static str,
        /// 0 = x, 1 = y, 2 = z.
        axis: usize,
    },
    /// Sizes that must agree do not.
    #[error("inconsistent size of {what}: expected {expected}, found {found}")]
    InconsistentSize {
        /// The operand.
        what: &'static str,
        /// What the dimensions imply.
        expected: usize,
        /// What was given.
        found: usize,
    },
    /// A defined sample is NaN or infinite.
    #[error("sample {index:?} is {value} (defined samples must be finite; use None for undefined)")]
    NonFiniteSample {
        /// `[i, j, k]` of the sample.
        index: [usize; 3],
        /// Its value.
        value: f64,
    },
    /// A sample position is outside `[0, 1]` or not finite.
    #[error("sample coordinate {value} at index {index} of axis {axis} is outside [0, 1]")]
    CoordinateOutOfRange {
        /// 0 = x, 1 = y, 2 = z.
        axis: usize,
        /// Index along the axis.
        index: usize,
        /// The position.
        value: f64,
    },
    /// Every sample is undefined: there is nothing to fit.
    #[error("no defined sample: nothing to fit")]
    NoDefinedSample,
    /// A parameter is outside its documented range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// The accepted range.
        reason: &'static str,
    },
    /// A problem too large for a dense method.
    #[error("{what}: {nodes} nodes exceed the limit of {limit}")]
    TooLarge {
        /// The method.
        what: &'static str,
        /// Nodes of the grid.
        nodes: usize,
        /// The limit.
        limit: usize,
    },
    /// The solver rejected its input.
    #[error(transparent)]
    Solver(#[from] SolverError),
}

/// Parameters of a fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitParams {
    /// Cells per axis `[Ax, Ay, Az]` (each ≥ 1). Default `[15, 8, 16]`, the source's grid.
    pub cells: [usize; 3],
    /// Periodic flag per axis (an angle axis must be periodic). Default all `false`.
    pub periodic: [bool; 3],
    /// Regularisation weight λ ≥ 0, dimensionless. Default [`DEFAULT_LAMBDA`].
    pub lambda: f64,
    /// Solver. Default [`Method::Pcg`]: the normal matrix is symmetric, and CG does BiCG's
    /// iterations with half the products (`altrep fit-bench`: 60 iterations each, 62 vs 122
    /// products, ≈ 6 vs 13 ms).
    pub solver: Method,
    /// Preconditioner. Default Jacobi (for LSQR/LSMR: column scaling).
    pub preconditioner: PreconditionerKind,
    /// Solver tolerance on the relative residual. Default `1e-10`.
    pub tolerance: f64,
    /// Solver iteration limit. Default `10_000`.
    pub max_iterations: usize,
    /// Bit depths for which to report the error after quantisation. Default `[8, 16]`.
    pub quantize_bits: Vec<u32>,
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            cells: [15, 8, 16],
            periodic: [false; 3],
            lambda: DEFAULT_LAMBDA,
            solver: Method::Pcg,
            preconditioner: PreconditionerKind::Jacobi,
            tolerance: 1e-10,
            max_iterations: 10_000,
            quantize_bits: vec![8, 16],
        }
    }
}

/// Fit error `|d − g|` of `grid` against the defined samples of `samples` (in parallel over
/// z-slices; statistics as [`ErrorStats`]).
/// Cost: one pass over the samples and a selection for the percentile.
pub fn error_stats(samples: &FitSamples, grid: &TrilinearGrid) -> ErrorStats {
    let [nx, ny, _] = samples.dims();
    let w = grid::sample_weights(samples, grid.cells(), grid.periodic());
    // Per z-slice: the errors ([`ErrorStats::of_chunks`] sums them slice by slice).
    let slices: Vec<Vec<f64>> = samples
        .values()
        .par_chunks(nx * ny)
        .enumerate()
        .map(|(k, slice)| {
            let mut errs = Vec::with_capacity(slice.len());
            for (j, row) in slice.chunks_exact(nx).enumerate() {
                for (i, v) in row.iter().enumerate() {
                    if let Some(d) = v {
                        errs.push((d - grid.blend([w[0][i], w[1][j], w[2][k]])).abs());
                    }
                }
            }
            errs
        })
        .collect();
    ErrorStats::of_chunks(slices)
}

/// Wall time of each stage, in seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct FitTiming {
    /// Sampling the function ([`fit_fn`]; 0 when samples were given).
    pub sampling_s: f64,
    /// Assembling the normal equations (and the design matrix for LSQR/LSMR).
    pub assembly_s: f64,
    /// The iterative solve.
    pub solve_s: f64,
    /// Error evaluation and quantisation reports.
    pub evaluation_s: f64,
}

/// Error after quantising the node values to `bits` bits ([`quantize()`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QuantizedError {
    /// Bits per node value.
    pub bits: u32,
    /// The quantisation (scale, offset, codes).
    pub quantized: Quantized,
    /// Fit error with the dequantised values.
    pub error: ErrorStats,
}

/// What a fit reports.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    /// Fit error over the defined samples.
    pub error: ErrorStats,
    /// Error after quantisation, one entry per [`FitParams::quantize_bits`].
    pub quantized: Vec<QuantizedError>,
    /// Smallest node value.
    pub coef_min: f64,
    /// Largest node value.
    pub coef_max: f64,
    /// Statistics of the data (its `std_dev` is the RMS error of the constant fit).
    pub data: DataStats,
    /// λ used.
    pub lambda: f64,
    /// `tr(AᵀA)/tr(L)`.
    pub laplacian_scale: f64,
    /// Nodes touched by no defined sample.
    pub untouched_nodes: usize,
    /// `‖Aᵀd − (AᵀA + c·L)·a‖ / ‖Aᵀd‖` for the returned `a`, the same measure for every solver.
    pub normal_residual: f64,
    /// The solver's own report.
    pub solver: SolveReport,
    /// Time per stage.
    pub timing: FitTiming,
}

/// A fitted grid and its report.
#[derive(Debug, Clone)]
pub struct TrilinearFit {
    /// The fitted function.
    pub grid: TrilinearGrid,
    /// How well and how fast.
    pub report: FitReport,
}

/// Fits a trilinear grid to samples (assembly, solve, report). Errors: see [`FitError`].
/// Cost: see the module docs.
pub fn fit(samples: &FitSamples, params: &FitParams) -> Result<TrilinearFit, FitError> {
    Fitter::new(samples, params.cells, params.periodic)?.fit(params)
}

/// Samples `f` on a `dims` grid ([`FitSamples::from_fn`]) and fits it; the report's timing
/// includes the sampling. Returns the samples too, for further evaluation.
pub fn fit_fn(
    dims: [usize; 3],
    f: impl Fn([f64; 3]) -> Option<f64> + Sync,
    params: &FitParams,
) -> Result<(FitSamples, TrilinearFit), FitError> {
    let t0 = Instant::now();
    let samples = FitSamples::from_fn(dims, f)?;
    let sampling_s = t0.elapsed().as_secs_f64();
    let mut fitted = fit(&samples, params)?;
    fitted.report.timing.sampling_s = sampling_s;
    Ok((samples, fitted))
}

/// Assembled normal equations of one sample grid, ready to be solved for several λ or solvers
/// without re-assembly.
#[derive(Debug, Clone)]
pub struct Fitter<'a> {
    samples: &'a FitSamples,
    normal: NormalEquations,
    assembly_s: f64,
}

impl<'a> Fitter<'a> {
    /// Assembles the normal equations. Errors: zero cells, no defined sample.
    pub fn new(
        samples: &'a FitSamples,
        cells: [usize; 3],
        periodic: [bool; 3],
    ) -> Result<Self, FitError> {
        let t0 = Instant::now();
        let normal = NormalEquations::assemble(samples, cells, periodic)?;
        Ok(Self {
            samples,
            normal,
            assembly_s: t0.elapsed().as_secs_f64(),
        })
    }

    /// The assembled system.
    pub fn normal_equations(&self) -> &NormalEquations {
        &self.normal
    }

    /// Time the assembly took, in seconds.
    pub fn assembly_s(&self) -> f64 {
        self.assembly_s
    }

    /// Builds the system [`FitParams::solver`] needs (for LSQR/LSMR: the design matrix) and
    /// solves it for `params.lambda`. Errors: `params.cells`/`periodic` differ from the
    /// assembled ones, `λ < 0` or not finite, solver input errors.
    pub fn fit(&self, params: &FitParams) -> Result<TrilinearFit, FitError> {
        let layout = *self.normal.layout();
        if params.cells != layout.cells || params.periodic != layout.periodic {
            return Err(FitError::InvalidParameter {
                name: "cells/periodic",
                value: format!("{:?}/{:?}", params.cells, params.periodic),
                reason: "must match the grid the Fitter assembled",
            });
        }
        if !(params.lambda >= 0.0 && params.lambda.is_finite()) {
            return Err(FitError::InvalidParameter {
                name: "lambda",
                value: params.lambda.to_string(),
                reason: "must be finite and ≥ 0",
            });
        }
        let solve_params = SolveParams {
            tolerance: params.tolerance,
            max_iterations: params.max_iterations,
            preconditioner: params.preconditioner,
            initial_guess: None,
        };
        let mut timing = FitTiming {
            assembly_s: self.assembly_s,
            ..FitTiming::default()
        };
        let matrix = self.normal.matrix(params.lambda);
        let (solution, matrix) = if params.solver.is_least_squares() {
            let t0 = Instant::now();
            let c = params.lambda * self.normal.laplacian_scale();
            let design = DesignMatrix::build(self.samples, layout.cells, layout.periodic, c)?;
            timing.assembly_s += t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            let s = solve(params.solver, &design.matrix, &design.rhs, &solve_params)?;
            timing.solve_s = t1.elapsed().as_secs_f64();
            (s, matrix)
        } else {
            // The lane-blocked product: bitwise the CSR product's results, 3.5× faster on the
            // grid's stencil sparsity; its build is counted in the solve time.
            let t1 = Instant::now();
            let op = BlockedCsr::new(matrix)?;
            let s = solve(params.solver, &op, self.normal.rhs(), &solve_params)?;
            timing.solve_s = t1.elapsed().as_secs_f64();
            (s, op.into_csr())
        };
        let t2 = Instant::now();
        let grid = TrilinearGrid::new(layout.cells, layout.periodic, solution.x)?;
        let rhs = self.normal.rhs();
        let mut ax = vec![0.0; rhs.len()];
        par_mul_vec(matrix.view(), grid.values(), &mut ax)?;
        let bnorm = rhs.iter().map(|v| v * v).sum::<f64>().sqrt();
        let rnorm = rhs
            .iter()
            .zip(&ax)
            .map(|(b, a)| (b - a) * (b - a))
            .sum::<f64>()
            .sqrt();
        let error = error_stats(self.samples, &grid);
        let quantized = params
            .quantize_bits
            .iter()
            .map(|&bits| {
                quantize(&grid, self.samples, bits).map(|(q, e)| QuantizedError {
                    bits,
                    quantized: q,
                    error: e,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        timing.evaluation_s = t2.elapsed().as_secs_f64();
        let (coef_min, coef_max) = grid.value_range();
        Ok(TrilinearFit {
            report: FitReport {
                error,
                quantized,
                coef_min,
                coef_max,
                data: *self.normal.data(),
                lambda: params.lambda,
                laplacian_scale: self.normal.laplacian_scale(),
                untouched_nodes: self.normal.untouched_nodes(),
                normal_residual: if bnorm > 0.0 { rnorm / bnorm } else { 0.0 },
                solver: solution.report,
                timing,
            },
            grid,
        })
    }
}
