//! Tests of the trilinear least-squares fit: exact recovery, dense min-norm reference, singular
//! systems, periodic seams, quantisation, property tests and bad input.

use altrep::fit::{
    DataStats, DesignMatrix, FitError, FitParams, FitSamples, Fitter, TrilinearGrid,
    dense_min_norm, fit, node_count, quantize,
};
use altrep::solvers::{Method, PreconditionerKind, StopReason};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn params(cells: [usize; 3], periodic: [bool; 3], lambda: f64, solver: Method) -> FitParams {
    FitParams {
        cells,
        periodic,
        lambda,
        solver,
        ..FitParams::default()
    }
}

fn random_grid(cells: [usize; 3], periodic: [bool; 3], seed: u64) -> TrilinearGrid {
    let n: usize = (0..3).map(|a| node_count(cells[a], periodic[a])).product();
    let mut rng = Lcg(seed);
    TrilinearGrid::new(
        cells,
        periodic,
        (0..n).map(|_| 4.0 * rng.next() - 2.0).collect(),
    )
    .unwrap()
}

#[test]
fn trilinear_function_is_recovered_exactly_by_every_solver() {
    // A global trilinear function (non-periodic) and a random node grid (periodic in z):
    // both lie in the fit's function space, so λ = 0 recovers them to solver tolerance.
    let cells = [4, 3, 5];
    let f = |p: [f64; 3]| 1.0 + 2.0 * p[0] - p[1] + 0.5 * p[2] + 3.0 * p[0] * p[1] * p[2];
    let samples = FitSamples::from_fn([13, 9, 16], |p| Some(f(p))).unwrap();
    let per = [false, false, true];
    let g_true = random_grid(cells, per, 7);
    let samples_per = FitSamples::from_fn([13, 9, 16], |p| Some(g_true.eval(p))).unwrap();
    for m in Method::ALL {
        let r = fit(&samples, &params(cells, [false; 3], 0.0, m)).unwrap();
        assert!(r.report.solver.converged, "{m:?}");
        assert!(r.report.error.max < 1e-8, "{m:?}: {:?}", r.report.error);
        for k in 0..=5 {
            for j in 0..=3 {
                for i in 0..=4 {
                    let p = [i as f64 / 4.0, j as f64 / 3.0, k as f64 / 5.0];
                    assert!((r.grid.node(i, j, k) - f(p)).abs() < 1e-7, "{m:?}");
                }
            }
        }
        let r = fit(&samples_per, &params(cells, per, 0.0, m)).unwrap();
        let diff = r
            .grid
            .values()
            .iter()
            .zip(g_true.values())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-7, "{m:?} periodic: {diff}");
    }
}

/// Samples of a piecewise-smooth function with undefined regions: a hole of whole cells
/// (untouched nodes), a random mask and a jump.
fn holey_samples(dims: [usize; 3], seed: u64) -> FitSamples {
    let mut rng = Lcg(seed);
    let mask: Vec<bool> = (0..dims.iter().product::<usize>())
        .map(|_| rng.next() < 0.8)
        .collect();
    let [nx, ny, _] = dims;
    let values = (0..mask.len())
        .map(|idx| {
            let (i, j, k) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
            let p = [
                (i as f64 + 0.5) / dims[0] as f64,
                (j as f64 + 0.5) / dims[1] as f64,
                (k as f64 + 0.5) / dims[2] as f64,
            ];
            let hole = p[0] > 0.55 && p[1] > 0.5;
            (mask[idx] && !hole).then(|| {
                (3.0 * p[0]).sin() + p[1] * p[2] + if p[0] + p[2] > 1.0 { 0.7 } else { 0.0 }
            })
        })
        .collect();
    FitSamples::new(dims, values).unwrap()
}

/// Minimum-norm least-squares solution and null-space projector diagonal, by SVD of the dense
/// design matrix.
fn dense_reference(
    samples: &FitSamples,
    cells: [usize; 3],
    per: [bool; 3],
) -> (Vec<f64>, Vec<f64>) {
    let dm = DesignMatrix::build(samples, cells, per, 0.0).unwrap();
    let (m, n) = (dm.matrix.rows(), dm.matrix.cols());
    let mut a = DMatrix::<f64>::zeros(m, n);
    for (v, (i, j)) in dm.matrix.iter() {
        a[(i as usize, j as usize)] += *v;
    }
    let svd = a.svd(true, true);
    let smax = svd.singular_values.max();
    let x = svd
        .solve(&DVector::from_column_slice(&dm.rhs), 1e-10 * smax)
        .unwrap();
    // Σ over null vectors of v_i²: 0 for a node whose value every LS solution shares.
    let vt = svd.v_t.as_ref().unwrap();
    let mut null = vec![0.0; n];
    for (k, &s) in svd.singular_values.iter().enumerate() {
        if s <= 1e-10 * smax {
            for (i, z) in null.iter_mut().enumerate() {
                *z += vt[(k, i)].powi(2);
            }
        }
    }
    // Rank-deficient SVD of a tall matrix returns min(m, n) vectors: nodes beyond them
    // (when m < n) are free as well.
    if vt.nrows() < n {
        null.iter_mut().for_each(|z| *z = z.max(1.0));
    }
    (x.iter().copied().collect(), null)
}

#[test]
fn fit_agrees_with_dense_min_norm_solution_on_small_grids() {
    for (cells, per, seed) in [
        ([3, 2, 3], [false, false, false], 1),
        ([4, 3, 3], [false, false, true], 2),
        ([4, 2, 3], [true, false, true], 3),
    ] {
        let samples = holey_samples([11, 9, 10], seed);
        let (x_ref, null) = dense_reference(&samples, cells, per);
        let g_ref = TrilinearGrid::new(cells, per, x_ref.clone()).unwrap();
        let e_ref = altrep::fit::error_stats(&samples, &g_ref).rms;
        let fitter = Fitter::new(&samples, cells, per).unwrap();
        assert!(
            null.iter().any(|&z| z > 0.5),
            "test needs a singular system"
        );
        for m in Method::ALL {
            let r = fitter.fit(&params(cells, per, 0.0, m)).unwrap();
            assert!(r.report.solver.converged, "{m:?} {cells:?}");
            let e = r.report.error.rms;
            assert!(
                (e - e_ref).abs() <= 1e-6 * e_ref,
                "{m:?} {cells:?}: rms {e} vs dense {e_ref}"
            );
            for (i, (&a, &b)) in r.grid.values().iter().zip(&x_ref).enumerate() {
                if null[i] < 1e-10 {
                    assert!((a - b).abs() < 1e-6, "{m:?} {cells:?} node {i}: {a} vs {b}");
                }
            }
        }
        // Regularised: the system is nonsingular and every node matches the dense solution.
        let x_reg = dense_min_norm(fitter.normal_equations(), 1e-3).unwrap();
        for m in Method::ALL {
            let r = fitter.fit(&params(cells, per, 1e-3, m)).unwrap();
            for (&a, &b) in r.grid.values().iter().zip(&x_reg) {
                assert!((a - b).abs() < 1e-6, "{m:?} {cells:?} λ: {a} vs {b}");
            }
        }
    }
}

#[test]
fn singular_systems_converge_or_say_they_did_not() {
    // Big undefined blocks, λ = 0: many empty rows.
    let dims = [24, 16, 20];
    let values = (0..dims.iter().product::<usize>())
        .map(|idx| {
            let (i, k) = (idx % 24, idx / (24 * 16));
            (i < 8 || k > 14).then_some((idx % 13) as f64 * 0.1)
        })
        .collect();
    let samples = FitSamples::new(dims, values).unwrap();
    let cells = [6, 4, 5];
    let fitter = Fitter::new(&samples, cells, [false; 3]).unwrap();
    assert!(fitter.normal_equations().untouched_nodes() > 20);
    for m in Method::ALL {
        for pc in [PreconditionerKind::None, PreconditionerKind::Jacobi] {
            let p = FitParams {
                preconditioner: pc,
                max_iterations: 2_000,
                ..params(cells, [false; 3], 0.0, m)
            };
            let r = fitter.fit(&p).unwrap();
            let rep = &r.report;
            assert!(r.grid.values().iter().all(|v| v.is_finite()));
            if rep.solver.converged {
                assert!(
                    rep.normal_residual < 1e-6,
                    "{m:?} {pc:?}: {}",
                    rep.normal_residual
                );
                assert!(rep.error.rms <= rep.data.std_dev);
            } else {
                assert!(!matches!(
                    rep.solver.stop_reason,
                    StopReason::Tolerance | StopReason::LeastSquares
                ));
            }
        }
    }
}

#[test]
fn periodic_axis_has_no_seam() {
    // Data with a seam-free angle axis z.
    let f = |p: [f64; 3]| Some((std::f64::consts::TAU * p[2]).cos() * (1.0 + p[0]) + p[1]);
    let samples = FitSamples::from_fn([20, 10, 32], f).unwrap();
    let r = fit(
        &samples,
        &params([5, 3, 8], [false, false, true], 1e-3, Method::Pcg),
    )
    .unwrap();
    let mut rng = Lcg(9);
    for _ in 0..200 {
        let (x, y) = (rng.next(), rng.next());
        let g0 = r.grid.eval([x, y, 0.0]);
        let g1 = r.grid.eval([x, y, 1.0]);
        assert!((g0 - g1).abs() < 1e-12, "seam: {g0} vs {g1}");
        // Continuity across the seam.
        let e = 1e-9;
        assert!((r.grid.eval([x, y, 1.0 - e]) - r.grid.eval([x, y, e])).abs() < 1e-6);
    }
    assert!(r.report.error.rms < 0.05, "{:?}", r.report.error);
}

#[test]
fn regularisation_keeps_coefficients_near_the_data_range() {
    // A steep ramp sampled only in a thin slab: unregularised, the free slopes overshoot.
    let dims = [40, 20, 20];
    let values = (0..dims.iter().product::<usize>())
        .map(|idx| {
            let (i, j) = (idx % 40, (idx / 40) % 20);
            let x = (i as f64 + 0.5) / 40.0;
            (j < 3 || (i % 7 == 0 && j < 10)).then_some(if x > 0.5 { 1.0 } else { 0.0 } + x)
        })
        .collect();
    let samples = FitSamples::new(dims, values).unwrap();
    let fitter = Fitter::new(&samples, [10, 4, 4], [false; 3]).unwrap();
    let p0 = fitter
        .fit(&params([10, 4, 4], [false; 3], 0.0, Method::Pcg))
        .unwrap();
    let p1 = fitter
        .fit(&params([10, 4, 4], [false; 3], 1e-2, Method::Pcg))
        .unwrap();
    let span = |r: &altrep::fit::TrilinearFit| r.report.coef_max - r.report.coef_min;
    let data_span = p0.report.data.max - p0.report.data.min;
    assert!(span(&p1) < span(&p0), "{} vs {}", span(&p1), span(&p0));
    assert!(span(&p1) < 1.5 * data_span);
}

#[test]
fn quantisation_error_is_reported_and_refit_never_hurts() {
    let samples = holey_samples([30, 20, 24], 5);
    let cells = [6, 4, 5];
    let r = fit(&samples, &params(cells, [false; 3], 1e-3, Method::Pcg)).unwrap();
    let q8 = &r.report.quantized[0];
    let q16 = &r.report.quantized[1];
    assert_eq!((q8.bits, q16.bits), (8, 16));
    assert!(q16.error.rms <= q8.error.rms);
    assert!((q16.error.rms - r.report.error.rms).abs() < 1e-3 * r.report.error.rms);
    // Min/max mapping without the refit is never better.
    let mm = altrep::fit::Quantized::min_max(&r.grid, 8).unwrap();
    let e_mm = altrep::fit::error_stats(&samples, &mm.to_grid(&r.grid).unwrap()).rms;
    let (_, e_best) = quantize(&r.grid, &samples, 8).unwrap();
    assert!(
        e_best.rms <= e_mm * (1.0 + 1e-12),
        "{} vs {e_mm}",
        e_best.rms
    );
    assert!(q8.quantized.codes.iter().all(|&c| c <= 255));
    assert!(matches!(
        quantize(&r.grid, &samples, 17),
        Err(FitError::InvalidParameter { .. })
    ));
}

#[test]
fn bad_input_gives_typed_errors() {
    assert!(matches!(
        FitSamples::new([0, 2, 2], vec![]),
        Err(FitError::ZeroSize { axis: 0, .. })
    ));
    assert!(matches!(
        FitSamples::new([2, 2, 2], vec![Some(1.0); 7]),
        Err(FitError::InconsistentSize {
            expected: 8,
            found: 7,
            ..
        })
    ));
    let mut v = vec![Some(1.0); 8];
    v[5] = Some(f64::NAN);
    assert!(matches!(
        FitSamples::new([2, 2, 2], v),
        Err(FitError::NonFiniteSample {
            index: [1, 0, 1],
            ..
        })
    ));
    assert!(matches!(
        FitSamples::from_fn([3, 3, 3], |_| Some(f64::INFINITY)),
        Err(FitError::NonFiniteSample { .. })
    ));
    assert!(matches!(
        FitSamples::with_coordinates([vec![0.5], vec![1.5], vec![0.5]], vec![Some(1.0)]),
        Err(FitError::CoordinateOutOfRange { axis: 1, .. })
    ));
    let none = FitSamples::new([2, 2, 2], vec![None; 8]).unwrap();
    assert!(matches!(
        fit(&none, &FitParams::default()),
        Err(FitError::NoDefinedSample)
    ));
    let ok = FitSamples::new([2, 2, 2], vec![Some(1.0); 8]).unwrap();
    assert!(matches!(
        fit(&ok, &params([2, 0, 2], [false; 3], 0.0, Method::Pcg)),
        Err(FitError::ZeroSize {
            what: "coarse grid",
            axis: 1
        })
    ));
    assert!(matches!(
        fit(&ok, &params([2, 2, 2], [false; 3], -1.0, Method::Pcg)),
        Err(FitError::InvalidParameter { name: "lambda", .. })
    ));
    assert!(matches!(
        fit(&ok, &params([2, 2, 2], [false; 3], f64::NAN, Method::Pcg)),
        Err(FitError::InvalidParameter { name: "lambda", .. })
    ));
    let bad_tol = FitParams {
        tolerance: -1.0,
        ..params([2, 2, 2], [false; 3], 0.0, Method::Pcg)
    };
    assert!(matches!(fit(&ok, &bad_tol), Err(FitError::Solver(_))));
    assert!(matches!(
        TrilinearGrid::new([2, 2, 2], [false; 3], vec![0.0; 26]),
        Err(FitError::InconsistentSize { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]

    /// Random grids, masks and values: no panic, no NaN, and never worse than the constant
    /// (mean) fit, for every solver and λ.
    #[test]
    fn never_worse_than_the_mean_fit(
        cells in prop::array::uniform3(1usize..5),
        periodic in prop::array::uniform3(any::<bool>()),
        dims in prop::array::uniform3(1usize..9),
        density in 0.0f64..1.0,
        seed in any::<u64>(),
        lambda in prop::sample::select(vec![0.0, 1e-4, 1e-1]),
        solver in prop::sample::select(Method::ALL.to_vec()),
        scale_exp in -3i32..4,
    ) {
        let mut rng = Lcg(seed);
        let n: usize = dims.iter().product();
        let scale = 10f64.powi(scale_exp);
        let values: Vec<Option<f64>> = (0..n)
            .map(|_| (rng.next() < density).then(|| scale * (rng.next() - 0.5)))
            .collect();
        let samples = FitSamples::new(dims, values).unwrap();
        match fit(&samples, &params(cells, periodic, lambda, solver)) {
            Err(FitError::NoDefinedSample) => prop_assert_eq!(samples.defined_count(), 0),
            Err(e) => prop_assert!(false, "unexpected error {e}"),
            Ok(r) => {
                prop_assert!(r.grid.values().iter().all(|v| v.is_finite()));
                let rep = &r.report;
                prop_assert!(rep.error.rms.is_finite() && rep.error.max.is_finite());
                if rep.solver.converged {
                    prop_assert!(
                        rep.error.rms <= rep.data.std_dev * (1.0 + 1e-6) + 1e-9 * scale,
                        "rms {} > mean-fit {}", rep.error.rms, rep.data.std_dev
                    );
                } else {
                    // Honest non-convergence is allowed for the non-symmetric methods only:
                    // BiCGSTAB can stagnate on near-singular systems with a handful of samples
                    // (seen: 1 defined sample on a 4×4×5 node grid). The symmetric methods, the
                    // default among them, must converge on every draw.
                    prop_assert!(
                        matches!(solver, Method::Bicgstab | Method::Pbicg),
                        "{solver:?} did not converge: {:?}", rep.solver.stop_reason
                    );
                    let honest = matches!(
                        rep.solver.stop_reason,
                        StopReason::MaxIterations | StopReason::Breakdown { .. }
                    );
                    prop_assert!(honest, "stop reason {:?}", rep.solver.stop_reason);
                }
            }
        }
    }
}

/// The data statistics do not depend on the number of threads (ordered chunk sums), and agree with
/// a serial two-pass computation.
#[test]
fn data_stats_are_the_same_on_any_thread_count() {
    let dims = [61, 37, 29];
    let samples = FitSamples::from_fn(dims, |p| {
        let v = (p[0] * 17.3).sin() * 1e3 + p[1] * 1e-3 + (p[2] * 5.1).cos();
        ((p[0] + p[1]) < 1.7).then_some(v)
    })
    .unwrap();
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| DataStats::of(&samples).unwrap())
    };
    let one = on(1);
    for threads in [2, 3, 7] {
        assert_eq!(on(threads), one, "{threads} threads");
    }
    let defined: Vec<f64> = samples.values().iter().filter_map(|v| *v).collect();
    assert_eq!(one.count, defined.len());
    let mean = defined.iter().sum::<f64>() / defined.len() as f64;
    let var = defined.iter().map(|d| (d - mean) * (d - mean)).sum::<f64>() / defined.len() as f64;
    approx::assert_relative_eq!(one.mean, mean, max_relative = 1e-12);
    approx::assert_relative_eq!(one.std_dev, var.sqrt(), max_relative = 1e-12);
}
