//! The measurements behind `altrep ellipsoid-bench`: eigen-solver speed and accuracy, filter-rule
//! errors, the sin²θ fit, and octree costs. Each function returns serialisable rows; the CLI only
//! prints them.

use std::collections::BTreeMap;
use std::hint::black_box;
use std::time::Instant;

use altrep_data_gen::Supersample;

use nalgebra::Matrix3;
use serde::Serialize;

use super::eigen::{
    EigenScalar, SymEigen3, adversarial_suite, adversarial_suite_f32, orthogonality_error,
    reconstruction_error, sym_eigen3, sym_eigen3_nalgebra,
};
use super::error::EllipsoidError;
use super::filter::{FilterCase, FilterRule, Sin2Fit, filter, filter_errors, fit_sin2_exponent};
use super::octree::{AnalyticVolume, Octree, OctreeParams, OctreeReport, VoxelGrid};
use super::quadrature::SphereQuadrature;
use super::rng::{RandomGeometry, SplitMix64};
use crate::stats::{EvenMedian, median};

/// One row of the eigen table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EigenRow {
    /// Solver and scalar type, e.g. `"altrep f64"`, `"nalgebra f64"`.
    pub method: String,
    /// Median time per decomposition over random symmetric matrices, nanoseconds.
    pub ns_per_op: f64,
    /// Fastest pass, nanoseconds per decomposition (the pass least disturbed by other load).
    pub ns_per_op_best: f64,
    /// nalgebra's time over this method's, same scalar type, from the fastest interleaved passes;
    /// 1 for nalgebra itself.
    pub speedup_vs_nalgebra: f64,
    /// Worst `‖A − VΛVᵀ‖_F/‖A‖_F` over the adversarial suite.
    pub worst_reconstruction: f64,
    /// Worst `‖VᵀV − I‖_F` over the adversarial suite.
    pub worst_orthogonality: f64,
    /// The case that gave the worst reconstruction.
    pub worst_case: String,
    /// Matrices in the suite for this scalar type.
    pub cases: usize,
}

type Solver<T> = fn(&Matrix3<T>) -> Result<SymEigen3<T>, EllipsoidError>;

fn accuracy<T: EigenScalar>(
    suite: &[(String, Matrix3<T>)],
    solve: Solver<T>,
) -> Result<(f64, f64, String), EllipsoidError> {
    let mut worst = (0.0f64, 0.0f64, String::new());
    for (name, m) in suite {
        let e = solve(m)?;
        let r = reconstruction_error(m, &e);
        let o = orthogonality_error(&e);
        if r >= worst.0 {
            worst.0 = r;
            worst.2 = name.clone();
        }
        worst.1 = worst.1.max(o);
    }
    Ok(worst)
}

/// Time per call of `solve` on `mats`, in ns (one pass).
fn one_pass<T: EigenScalar>(mats: &[Matrix3<T>], solve: Solver<T>) -> f64 {
    let start = Instant::now();
    for m in mats {
        let _ = black_box(solve(black_box(m)));
    }
    start.elapsed().as_nanos() as f64 / mats.len().max(1) as f64
}

/// Interleaved timings of two solvers (pass A, pass B, pass A, …) so both see the same machine
/// load.
struct PairTiming {
    median_a: f64,
    median_b: f64,
    best_a: f64,
    best_b: f64,
}

fn time_pair<T: EigenScalar>(
    mats: &[Matrix3<T>],
    a: Solver<T>,
    b: Solver<T>,
    batches: usize,
) -> PairTiming {
    let (mut ta, mut tb) = (Vec::new(), Vec::new());
    for _ in 0..batches.max(1) {
        ta.push(one_pass(mats, a));
        tb.push(one_pass(mats, b));
    }
    let best = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    PairTiming {
        best_a: best(&ta),
        best_b: best(&tb),
        // Upper median (a measured time); `batches.max(1)` passes, so never empty.
        median_a: median(&mut ta, EvenMedian::Upper).unwrap_or(0.0),
        median_b: median(&mut tb, EvenMedian::Upper).unwrap_or(0.0),
    }
}

/// Random symmetric matrices `R diag(d) Rᵀ` with `d` uniform in [−1, 1] (the timing set; the
/// adversarial suite holds many diagonal shortcuts and would flatter the timings).
pub fn timing_set(seed: u64, n: usize) -> Vec<Matrix3<f64>> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| {
            let r = rng.rotation();
            let d = Matrix3::from_diagonal(&nalgebra::Vector3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ));
            let m = r * d * r.transpose();
            (m + m.transpose()) * 0.5
        })
        .collect()
}

/// The eigen table: this module's solver and nalgebra's `SymmetricEigen`, in `f64` and `f32`.
/// Accuracy on [`adversarial_suite`] (f32: [`adversarial_suite_f32`]); speed on 4096 random
/// matrices, median of `batches` interleaved passes (single thread). Cost: ~`batches` × 10 ms.
pub fn eigen_table(seed: u64, batches: usize) -> Result<Vec<EigenRow>, EllipsoidError> {
    let suite64: Vec<(String, Matrix3<f64>)> = adversarial_suite(seed)
        .into_iter()
        .map(|c| (c.name, c.matrix))
        .collect();
    let suite32 = adversarial_suite_f32(seed);
    let t64 = timing_set(seed, 4096);
    let t32: Vec<Matrix3<f32>> = t64.iter().map(|m| m.map(|x| x as f32)).collect();
    let mut rows = Vec::new();
    let t = time_pair(&t64, sym_eigen3::<f64>, sym_eigen3_nalgebra::<f64>, batches);
    for (name, solve, ns, best, speedup) in [
        (
            "altrep f64",
            sym_eigen3::<f64> as Solver<f64>,
            t.median_a,
            t.best_a,
            t.best_b / t.best_a,
        ),
        (
            "nalgebra f64",
            sym_eigen3_nalgebra::<f64>,
            t.median_b,
            t.best_b,
            1.0,
        ),
    ] {
        let (r, o, case) = accuracy(&suite64, solve)?;
        rows.push(EigenRow {
            method: name.into(),
            ns_per_op: ns,
            ns_per_op_best: best,
            speedup_vs_nalgebra: speedup,
            worst_reconstruction: r,
            worst_orthogonality: o,
            worst_case: case,
            cases: suite64.len(),
        });
    }
    let t = time_pair(&t32, sym_eigen3::<f32>, sym_eigen3_nalgebra::<f32>, batches);
    for (name, solve, ns, best, speedup) in [
        (
            "altrep f32",
            sym_eigen3::<f32> as Solver<f32>,
            t.median_a,
            t.best_a,
            t.best_b / t.best_a,
        ),
        (
            "nalgebra f32",
            sym_eigen3_nalgebra::<f32>,
            t.median_b,
            t.best_b,
            1.0,
        ),
    ] {
        let (r, o, case) = accuracy(&suite32, solve)?;
        rows.push(EigenRow {
            method: name.into(),
            ns_per_op: ns,
            ns_per_op_best: best,
            speedup_vs_nalgebra: speedup,
            worst_reconstruction: r,
            worst_orthogonality: o,
            worst_case: case,
            cases: suite32.len(),
        });
    }
    Ok(rows)
}

/// One row of the filter table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FilterRow {
    /// Case name.
    pub case: String,
    /// Rule name.
    pub rule: String,
    /// Relative L1 error of the normal distribution (see [`super::FilterErrors`]).
    pub l1_error: f64,
    /// Relative L1 error of the projected area over directions.
    pub area_error: f64,
    /// Scale-free L1 error (both distributions normalised to unit integral).
    pub l1_shape_error: f64,
    /// Lengths of the filtered ellipsoid, ascending.
    pub lengths: [f64; 3],
}

/// The quadrature used by the report: base 16, depth 9, tolerance 1e-6 on relative errors.
pub fn report_quadrature() -> SphereQuadrature {
    SphereQuadrature {
        base: 16,
        max_depth: 9,
        tolerance: 1e-6,
    }
}

/// Filter table: every [`FilterCase::standard`] case by both rules. Cost: ~1–5 s.
pub fn filter_table(seed: u64, quad: &SphereQuadrature) -> Result<Vec<FilterRow>, EllipsoidError> {
    let mut rows = Vec::new();
    for case in FilterCase::standard(seed)? {
        for rule in FilterRule::ALL {
            let f = filter(&case.ellipsoids, &case.weights, rule)?;
            let e = filter_errors(&case.ellipsoids, &case.weights, &f, quad)?;
            let mut l = [f.lengths().x, f.lengths().y, f.lengths().z];
            l.sort_by(f64::total_cmp);
            rows.push(FilterRow {
                case: case.name.clone(),
                rule: rule.name().into(),
                l1_error: e.l1_error,
                area_error: e.area_error,
                l1_shape_error: e.l1_shape_error,
                lengths: l,
            });
        }
    }
    Ok(rows)
}

/// The angles of the sin²θ fit: 0.01 to 0.16 rad, doubling.
pub const SIN2_THETAS: [f64; 5] = [0.01, 0.02, 0.04, 0.08, 0.16];

/// The sin²θ fits of both rules over [`SIN2_THETAS`].
pub fn sin2_fits(quad: &SphereQuadrature) -> Result<Vec<Sin2Fit>, EllipsoidError> {
    FilterRule::ALL
        .iter()
        .map(|&rule| fit_sin2_exponent(rule, &SIN2_THETAS, quad))
        .collect()
}

/// One octree measurement: the report plus the time to sample the analytic volume into a grid.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OctreeRow {
    /// Seconds to sample the analytic volume into a dense grid (not part of the build).
    pub voxelize_seconds: f64,
    /// The build's report (volume name, nodes, compression, bytes, build time, …).
    #[serde(flatten)]
    pub report: OctreeReport,
}

/// Voxelises the named volume at `n³` and builds its octree with `params`.
///
/// Names: `"lawn"` and `"sphere-torus"` ([`AnalyticVolume`], sampled into a [`VoxelGrid`]), or any
/// `altrep_data_gen` scene shape (voxelised by `altrep_data_gen::voxelize`, one sample per voxel).
/// Memory: about 32 bytes per voxel (537 MB at 256³) while the build runs.
pub fn octree_row(
    name: &str,
    n: usize,
    seed: u64,
    params: &OctreeParams,
) -> Result<OctreeRow, EllipsoidError> {
    let start = Instant::now();
    let built = match name {
        "lawn" | "sphere-torus" => {
            let volume = if name == "lawn" {
                AnalyticVolume::lawn(n, seed)
            } else {
                AnalyticVolume::sphere_torus(n)
            };
            let grid = VoxelGrid::from_source(&volume)?;
            let voxelize_seconds = start.elapsed().as_secs_f64();
            (voxelize_seconds, Octree::build(&grid, params)?)
        }
        _ => {
            let shape = altrep_data_gen::scene_shape(name)
                .map_err(|e| EllipsoidError::BadVolume(e.to_string()))?;
            let vp = altrep_data_gen::VoxelParams {
                dims: [n; 3],
                min: glam::DVec3::new(-1.0, 0.0, -1.0),
                max: glam::DVec3::new(1.0, 2.0, 1.0),
                periodic: [false; 3],
                supersample: Supersample::ONE,
                fill: altrep_data_gen::Fill::Auto,
            };
            let volume = altrep_data_gen::voxelize(&shape, &vp)
                .map_err(|e| EllipsoidError::BadVolume(e.to_string()))?;
            let voxelize_seconds = start.elapsed().as_secs_f64();
            (voxelize_seconds, Octree::build(&volume, params)?)
        }
    };
    let (voxelize_seconds, (_octree, mut report)) = built;
    report.volume = format!("{name} {n}^3");
    Ok(OctreeRow {
        voxelize_seconds,
        report,
    })
}

/// Everything `altrep ellipsoid-bench` prints, as written to `--json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EllipsoidBenchReport {
    /// Eigen table.
    pub eigen: Vec<EigenRow>,
    /// Filter table.
    pub filter: Vec<FilterRow>,
    /// `k` of `L1 error ∝ (sin²θ)^k` per rule name (Neyret 1995's claim: `k = 1`).
    pub sin2_exponent: BTreeMap<String, f64>,
    /// The (θ, L1 error) points behind each fit.
    pub sin2_points: BTreeMap<String, Vec<(f64, f64)>>,
    /// Octree rows.
    pub octree: Vec<OctreeRow>,
}
