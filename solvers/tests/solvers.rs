//! Solver tests: manufactured solutions, singular consistent and inconsistent systems, dense
//! least-squares references (nalgebra SVD), bad input, MatrixMarket files.

use altrep_solvers::{
    BlockedCsr, LinearOperator, Method, PreconditionerKind, SolveParams, SolverError, StopReason,
    io, lsmr, lsqr, pbicg, pcg, solve,
};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use sprs::{CsMat, TriMat};

const SQUARE: [Method; 3] = [Method::Pbicg, Method::Pcg, Method::Bicgstab];
const PRECONDS: [PreconditionerKind; 3] = [
    PreconditionerKind::None,
    PreconditionerKind::Jacobi,
    PreconditionerKind::Ssor { omega: 1.2 },
];

/// Small deterministic generator (tests must not depend on a crate's RNG stream).
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

/// Graph Laplacian of an `nx × ny` grid with edge weights spanning 6 orders of magnitude, plus
/// `shift` on the diagonal (`shift = 0`: singular, null space = constants).
fn grid_laplacian(nx: usize, ny: usize, shift: f64, seed: u64) -> CsMat<f64> {
    grid_laplacian_span(nx, ny, shift, seed, 6.0)
}

/// [`grid_laplacian`] with edge weights `10^(span·(u − ½))`, `u` uniform in [0, 1).
fn grid_laplacian_span(nx: usize, ny: usize, shift: f64, seed: u64, span: f64) -> CsMat<f64> {
    let n = nx * ny;
    let mut rng = Lcg(seed);
    let mut t = TriMat::new((n, n));
    let add_edge = |t: &mut TriMat<f64>, p: usize, q: usize, w: f64| {
        t.add_triplet(p, p, w);
        t.add_triplet(q, q, w);
        t.add_triplet(p, q, -w);
        t.add_triplet(q, p, -w);
    };
    for j in 0..ny {
        for i in 0..nx {
            let p = i + nx * j;
            let w1 = 10f64.powf(span * (rng.next() - 0.5));
            let w2 = 10f64.powf(span * (rng.next() - 0.5));
            if i + 1 < nx {
                add_edge(&mut t, p, p + 1, w1);
            }
            if j + 1 < ny {
                add_edge(&mut t, p, p + nx, w2);
            }
            if shift > 0.0 {
                t.add_triplet(p, p, shift);
            }
        }
    }
    t.to_csr()
}

fn matvec(a: &CsMat<f64>, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; a.rows()];
    a.apply(x, &mut y);
    y
}

fn params(pc: PreconditionerKind) -> SolveParams {
    SolveParams {
        preconditioner: pc,
        max_iterations: 5_000,
        ..SolveParams::default()
    }
}

fn rel_err(x: &[f64], y: &[f64]) -> f64 {
    let num: f64 = x.iter().zip(y).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
    let den: f64 = y.iter().map(|b| b * b).sum::<f64>();
    (num / den.max(1e-300)).sqrt()
}

#[test]
fn manufactured_spd_solution_is_recovered_by_every_method_and_preconditioner() {
    let a = grid_laplacian_span(12, 10, 1e-2, 1, 2.0);
    let n = a.rows();
    let x_true: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin() + 0.5).collect();
    let b = matvec(&a, &x_true);
    for m in SQUARE {
        for pc in PRECONDS {
            let s = solve(m, &a, &b, &params(pc)).unwrap();
            assert!(
                s.report.converged,
                "{m:?} {pc:?}: {:?}",
                s.report.stop_reason
            );
            assert!(s.report.relative_residual <= 1e-10);
            assert_eq!(s.report.stop_reason, StopReason::Tolerance);
            assert!(rel_err(&s.x, &x_true) < 1e-4, "{m:?} {pc:?}");
            assert_eq!(s.report.residual_history.len(), s.report.iterations + 1);
        }
    }
}

#[test]
fn jacobi_pays_on_a_badly_scaled_diagonal() {
    // S·A·S with S spanning 8 orders of magnitude: the fit's normal matrix looks like this
    // (nodes with thousands of samples beside nodes with a handful). Jacobi undoes S.
    let a0 = grid_laplacian_span(20, 20, 1e-1, 2, 1.0);
    let mut rng = Lcg(3);
    let s: Vec<f64> = (0..a0.rows())
        .map(|_| 10f64.powf(8.0 * rng.next() - 4.0))
        .collect();
    let mut t = TriMat::new((a0.rows(), a0.cols()));
    for (v, (i, j)) in a0.iter() {
        t.add_triplet(i, j, s[i] * v * s[j]);
    }
    let a: CsMat<f64> = t.to_csr();
    let b = matvec(&a, &vec![1.0; a.rows()]);
    let plain = pcg(&a, &b, &params(PreconditionerKind::None)).unwrap();
    let jac = pcg(&a, &b, &params(PreconditionerKind::Jacobi)).unwrap();
    assert!(jac.report.converged);
    assert!(
        !plain.report.converged || jac.report.iterations * 4 < plain.report.iterations,
        "jacobi {} vs none {}",
        jac.report.iterations,
        plain.report.iterations
    );
}

#[test]
fn bicg_on_a_symmetric_system_does_cg_iterations_at_twice_the_products() {
    let a = grid_laplacian(15, 15, 1e-1, 3);
    let b: Vec<f64> = (0..a.rows()).map(|i| (i % 7) as f64 - 3.0).collect();
    let p = params(PreconditionerKind::Jacobi);
    let cg = pcg(&a, &b, &p).unwrap();
    let bi = pbicg(&a, &b, &p).unwrap();
    assert!(cg.report.converged && bi.report.converged);
    assert!(cg.report.iterations.abs_diff(bi.report.iterations) <= 1);
    let ratio = bi.report.operator_applications as f64 / cg.report.operator_applications as f64;
    assert!((1.8..=2.1).contains(&ratio), "ratio {ratio}");
    assert!(rel_err(&bi.x, &cg.x) < 1e-8);
}

#[test]
fn nonsymmetric_system_is_solved_by_bicg_and_bicgstab() {
    // Convection–diffusion on a 1-D grid: tridiagonal, nonsymmetric.
    let n = 200;
    let mut t = TriMat::new((n, n));
    for i in 0..n {
        t.add_triplet(i, i, 2.5);
        if i + 1 < n {
            t.add_triplet(i, i + 1, -1.0 + 0.4);
            t.add_triplet(i + 1, i, -1.0 - 0.4);
        }
    }
    let a: CsMat<f64> = t.to_csr();
    let x_true: Vec<f64> = (0..n).map(|i| (i as f64 / 10.0).cos()).collect();
    let b = matvec(&a, &x_true);
    for m in [Method::Pbicg, Method::Bicgstab] {
        for pc in PRECONDS {
            let s = solve(m, &a, &b, &params(pc)).unwrap();
            assert!(
                s.report.converged,
                "{m:?} {pc:?}: {:?}",
                s.report.stop_reason
            );
            assert!(rel_err(&s.x, &x_true) < 1e-7, "{m:?} {pc:?}");
        }
    }
}

/// A singular PSD system with zero rows (isolated nodes), consistent right-hand side.
fn singular_with_zero_rows() -> (CsMat<f64>, Vec<f64>) {
    let lap = grid_laplacian(8, 6, 0.0, 4);
    let n = lap.rows() + 5; // 5 extra isolated unknowns: zero row and column
    let mut t = TriMat::new((n, n));
    for (v, (i, j)) in lap.iter() {
        t.add_triplet(i, j, *v);
    }
    let a: CsMat<f64> = t.to_csr();
    let x_any: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).cos()).collect();
    let b = matvec(&a, &x_any);
    (a, b)
}

#[test]
fn singular_consistent_systems_converge_and_leave_free_unknowns_at_the_initial_guess() {
    let (a, b) = singular_with_zero_rows();
    let n = a.rows();
    for m in SQUARE {
        for pc in PRECONDS {
            let s = solve(m, &a, &b, &params(pc)).unwrap();
            assert!(
                s.report.converged,
                "{m:?} {pc:?}: {:?}",
                s.report.stop_reason
            );
            assert!(s.x.iter().all(|v| v.is_finite()));
            // Isolated unknowns keep x₀ = 0.
            assert!(s.x[n - 5..].iter().all(|&v| v == 0.0), "{m:?} {pc:?}");
        }
    }
    for m in [Method::Lsqr, Method::Lsmr] {
        let s = solve(m, &a, &b, &params(PreconditionerKind::Jacobi)).unwrap();
        assert!(s.report.converged, "{m:?}: {:?}", s.report.stop_reason);
        assert!(s.report.relative_residual < 1e-8, "{m:?}");
    }
}

#[test]
fn singular_inconsistent_systems_are_reported_not_hidden() {
    let (a, mut b) = singular_with_zero_rows();
    let n = a.rows();
    // A component in the null space (constants on the connected block, and an isolated row).
    for v in b.iter_mut().take(n - 5) {
        *v += 0.1;
    }
    b[n - 1] = 1.0;
    let p = SolveParams {
        max_iterations: 400,
        ..params(PreconditionerKind::Jacobi)
    };
    for m in SQUARE {
        let s = solve(m, &a, &b, &p).unwrap();
        assert!(!s.report.converged, "{m:?} claims convergence");
        assert!(
            matches!(
                s.report.stop_reason,
                StopReason::MaxIterations | StopReason::Breakdown { .. }
            ),
            "{m:?}: {:?}",
            s.report.stop_reason
        );
        assert!(s.report.relative_residual > 1e-3);
    }
    // The least-squares methods find the least-squares solution, and say so.
    let dense = dense(&a);
    let x_ref = dense_min_norm(&dense, &b);
    for m in [Method::Lsqr, Method::Lsmr] {
        let s = solve(m, &a, &b, &params(PreconditionerKind::None)).unwrap();
        assert_eq!(s.report.stop_reason, StopReason::LeastSquares, "{m:?}");
        assert!(s.report.converged);
        // Residual norm equals the optimal one.
        let r_opt = rel_err(&matvec(&a, &x_ref), &b);
        let r_got = rel_err(&matvec(&a, &s.x), &b);
        assert!(
            (r_got - r_opt).abs() <= 1e-6 * r_opt,
            "{m:?} {r_got} vs {r_opt}"
        );
    }
}

fn dense(a: &CsMat<f64>) -> DMatrix<f64> {
    let mut d = DMatrix::zeros(a.rows(), a.cols());
    for (v, (i, j)) in a.iter() {
        d[(i, j)] += *v;
    }
    d
}

fn dense_min_norm(a: &DMatrix<f64>, b: &[f64]) -> Vec<f64> {
    let svd = a.clone().svd(true, true);
    let x = svd
        .solve(
            &DVector::from_column_slice(b),
            1e-10 * svd.singular_values.max(),
        )
        .unwrap();
    x.iter().copied().collect()
}

fn random_rect(m: usize, n: usize, per_row: usize, seed: u64) -> CsMat<f64> {
    let mut rng = Lcg(seed);
    let mut t = TriMat::new((m, n));
    for i in 0..m {
        for _ in 0..per_row {
            let j = (rng.next() * n as f64) as usize % n;
            t.add_triplet(
                i,
                j,
                10f64.powf(3.0 * rng.next() - 1.5) * (rng.next() - 0.5),
            );
        }
    }
    t.to_csr()
}

#[test]
fn least_squares_methods_match_the_dense_min_norm_solution() {
    // Overdetermined, full column rank, inconsistent.
    let a = random_rect(300, 40, 5, 11);
    let mut rng = Lcg(5);
    let b: Vec<f64> = (0..300).map(|_| rng.next() - 0.5).collect();
    let x_ref = dense_min_norm(&dense(&a), &b);
    for pc in [PreconditionerKind::None, PreconditionerKind::Jacobi] {
        for f in [lsqr::<CsMat<f64>>, lsmr::<CsMat<f64>>] {
            let s = f(&a, &b, &params(pc)).unwrap();
            assert!(s.report.converged, "{pc:?}: {:?}", s.report.stop_reason);
            assert!(
                rel_err(&s.x, &x_ref) < 1e-6,
                "{pc:?}: {}",
                rel_err(&s.x, &x_ref)
            );
        }
    }
    // Underdetermined, consistent: LSQR/LSMR from 0 give the minimum-norm solution.
    let a = random_rect(20, 60, 6, 12);
    let b: Vec<f64> = (0..20).map(|_| rng.next() - 0.5).collect();
    let x_ref = dense_min_norm(&dense(&a), &b);
    for f in [lsqr::<CsMat<f64>>, lsmr::<CsMat<f64>>] {
        let s = f(&a, &b, &params(PreconditionerKind::None)).unwrap();
        assert_eq!(s.report.stop_reason, StopReason::Tolerance);
        assert!(rel_err(&s.x, &x_ref) < 1e-6, "{}", rel_err(&s.x, &x_ref));
    }
}

#[test]
fn zero_rhs_gives_zero_and_iteration_limit_is_honest() {
    let a = grid_laplacian(10, 10, 1e-3, 6);
    let n = a.rows();
    for m in Method::ALL {
        let p = SolveParams {
            initial_guess: Some(vec![1.0; n]),
            ..SolveParams::default()
        };
        let s = solve(m, &a, &vec![0.0; n], &p).unwrap();
        assert!(s.report.converged && s.x.iter().all(|&v| v == 0.0), "{m:?}");
    }
    let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
    for m in Method::ALL {
        let p = SolveParams {
            max_iterations: 2,
            ..params(PreconditionerKind::None)
        };
        let s = solve(m, &a, &b, &p).unwrap();
        assert_eq!(s.report.stop_reason, StopReason::MaxIterations, "{m:?}");
        assert!(!s.report.converged);
        assert_eq!(s.report.iterations, 2);
    }
}

#[test]
fn initial_guess_is_used() {
    let a = grid_laplacian(10, 10, 1e-1, 7);
    let x_true: Vec<f64> = (0..a.rows()).map(|i| i as f64).collect();
    let b = matvec(&a, &x_true);
    for m in Method::ALL {
        let p = SolveParams {
            initial_guess: Some(x_true.clone()),
            ..SolveParams::default()
        };
        let s = solve(m, &a, &b, &p).unwrap();
        assert!(s.report.converged, "{m:?}");
        assert_eq!(s.report.iterations, 0, "{m:?}");
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let a = grid_laplacian(4, 4, 1.0, 8);
    let b = vec![1.0; 16];
    let p = SolveParams::default();
    for m in Method::ALL {
        assert!(matches!(
            solve(m, &a, &b[..15], &p),
            Err(SolverError::DimensionMismatch { .. })
        ));
        let mut bn = b.clone();
        bn[3] = f64::NAN;
        assert!(matches!(
            solve(m, &a, &bn, &p),
            Err(SolverError::NonFinite { index: 3, .. })
        ));
        let px = SolveParams {
            initial_guess: Some(vec![0.0; 3]),
            ..SolveParams::default()
        };
        assert!(matches!(
            solve(m, &a, &b, &px),
            Err(SolverError::DimensionMismatch { .. })
        ));
        let pt = SolveParams {
            tolerance: 0.0,
            ..SolveParams::default()
        };
        assert!(matches!(
            solve(m, &a, &b, &pt),
            Err(SolverError::InvalidParameter { .. })
        ));
    }
    let mut bad = a.clone();
    bad.data_mut()[0] = f64::INFINITY;
    assert!(matches!(
        pcg(&bad, &b, &p),
        Err(SolverError::NonFinite { what: "matrix", .. })
    ));
    let rect = random_rect(5, 3, 2, 1);
    assert!(matches!(
        pcg(&rect, &[1.0; 5], &p),
        Err(SolverError::NotSquare { .. })
    ));
    let ps = params(PreconditionerKind::Ssor { omega: 1.0 });
    assert!(matches!(
        lsqr(&rect, &[1.0; 5], &ps),
        Err(SolverError::PreconditionerUnavailable { .. })
    ));
}

#[test]
fn matrix_market_files_round_trip() {
    let dir = std::env::temp_dir().join(format!("altrep-solvers-mm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let a = grid_laplacian(5, 4, 0.5, 9);
    let b: Vec<f64> = (0..a.rows()).map(|i| 1.0 / (i as f64 + 3.0)).collect();
    io::write_matrix_market(dir.join("a.mtx"), a.view()).unwrap();
    io::write_vector(dir.join("b.mtx"), &b).unwrap();
    assert_eq!(io::read_matrix_market(dir.join("a.mtx")).unwrap(), a);
    assert_eq!(io::read_vector(dir.join("b.mtx")).unwrap(), b);
    assert!(matches!(
        io::read_matrix_market(dir.join("b.mtx")),
        Err(SolverError::MatrixMarket { .. })
    ));
    assert!(matches!(
        io::read_matrix_market(dir.join("missing.mtx")),
        Err(SolverError::Io { .. })
    ));
    std::fs::remove_dir_all(&dir).ok();
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]

    /// Random sparse PSD systems `BᵀB + shift·I` (possibly singular) with a consistent
    /// right-hand side: every method ends without NaN and the converged ones have a small
    /// true residual; PCG always converges.
    #[test]
    fn random_psd_systems(m in 3usize..40, n in 2usize..30, seed in 0u64..1000, shift in prop::sample::select(vec![0.0, 1e-6, 1.0])) {
        let bm = random_rect(m, n, 3, seed);
        let btb = &bm.transpose_view() * &bm;
        let a: CsMat<f64> = (&btb + &(&CsMat::<f64>::eye(n) * shift)).to_csr();
        let mut rng = Lcg(seed + 1);
        let x: Vec<f64> = (0..n).map(|_| rng.next() - 0.5).collect();
        let b = matvec(&a, &x);
        for meth in Method::ALL {
            for pc in [PreconditionerKind::None, PreconditionerKind::Jacobi] {
                let s = solve(meth, &a, &b, &params(pc)).unwrap();
                prop_assert!(s.x.iter().all(|v| v.is_finite()), "{:?}", meth);
                prop_assert!(s.report.relative_residual.is_finite());
                if s.report.converged && !meth.is_least_squares() {
                    prop_assert!(s.report.relative_residual <= 1e-10);
                }
                if meth == Method::Pcg {
                    prop_assert!(s.report.converged, "{:?} {:?}", pc, s.report.stop_reason);
                }
            }
        }
    }
}

/// The serial and the parallel paths of the kernels (CSR products by row blocks, transpose
/// products by scatter blocks, chunked dot products) give bit-for-bit the same iterates: same
/// iteration count, same residual history, same solution, for every method. The system is big
/// enough for several row chunks and transpose blocks, and for chunked dot products (LSQR/LSMR's
/// sample-space vectors).
#[test]
fn serial_and_parallel_solves_are_bitwise_identical() {
    use altrep_solvers::{Parallelism, with_parallelism};
    // Square: 90 000 unknowns, ~450 000 non-zeros (several row chunks, dot products of
    // chunked shape).
    let a = grid_laplacian_span(300, 300, 1e-2, 11, 2.0);
    let n = a.rows();
    let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.013).sin()).collect();
    // Rectangular, for LSQR/LSMR: the square matrix stacked on a scaled identity.
    let mut t = TriMat::new((2 * n, n));
    for (v, (i, j)) in a.iter() {
        t.add_triplet(i, j, *v);
    }
    for i in 0..n {
        t.add_triplet(n + i, i, 0.5);
    }
    let d: CsMat<f64> = t.to_csr();
    let blocked = BlockedCsr::new(a.clone()).unwrap();
    assert!(blocked.blocked_share() > 0.9);
    let bd: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.007).cos()).collect();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    let configs = [
        (Method::Pcg, PreconditionerKind::Jacobi),
        (Method::Pcg, PreconditionerKind::Ssor { omega: 1.0 }),
        (Method::Pbicg, PreconditionerKind::Jacobi),
        (Method::Bicgstab, PreconditionerKind::Jacobi),
        (Method::Lsqr, PreconditionerKind::Jacobi),
        (Method::Lsmr, PreconditionerKind::Jacobi),
    ];
    for (m, pc) in configs {
        let p = SolveParams {
            preconditioner: pc,
            max_iterations: 40,
            ..SolveParams::default()
        };
        let run = |mode| {
            with_parallelism(mode, || {
                let s = if m.is_least_squares() {
                    solve(m, &d, &bd, &p)
                } else {
                    solve(m, &a, &b, &p)
                }
                .unwrap();
                (
                    s.report.iterations,
                    bits(&s.report.residual_history),
                    bits(&s.x),
                    s.report.relative_residual.to_bits(),
                )
            })
        };
        let serial = run(Parallelism::Serial);
        assert!(serial.0 > 10, "{m:?}: too few iterations to compare");
        assert_eq!(serial, run(Parallelism::Parallel), "{m:?}+{pc:?}");
        assert_eq!(serial, run(Parallelism::Auto), "{m:?}+{pc:?}");
        if !m.is_least_squares() {
            // The lane-blocked product: the same iterates as the CSR product, on both paths.
            for mode in [Parallelism::Serial, Parallelism::Parallel] {
                let s = with_parallelism(mode, || solve(m, &blocked, &b, &p).unwrap());
                let got = (
                    s.report.iterations,
                    bits(&s.report.residual_history),
                    bits(&s.x),
                    s.report.relative_residual.to_bits(),
                );
                assert_eq!(serial, got, "blocked {m:?}+{pc:?} {mode:?}");
            }
        }
    }
}

/// A 27-point stencil on an `nx × ny × nz` node grid, periodic in z, in the fit's node order
/// (`x + nx·(y + ny·z)`), with about a fifth of the off-diagonal pairs dropped at random (the
/// fit's normal matrix stores only the pairs some sample touches) and weights over 4 orders of
/// magnitude; diagonally dominant plus `shift`: SPD.
fn periodic_stencil(nx: usize, ny: usize, nz: usize, shift: f64, seed: u64) -> CsMat<f64> {
    let n = nx * ny * nz;
    let id = |x: usize, y: usize, z: usize| x + nx * (y + ny * z);
    let mut rng = Lcg(seed);
    let mut t = TriMat::new((n, n));
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let p = id(x, y, z);
                t.add_triplet(p, p, shift);
                for dz in -1i64..=1 {
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let (qx, qy) = (x as i64 + dx, y as i64 + dy);
                            let qz = (z as i64 + dz).rem_euclid(nz as i64);
                            if qx < 0 || qy < 0 || qx >= nx as i64 || qy >= ny as i64 {
                                continue;
                            }
                            let q = id(qx as usize, qy as usize, qz as usize);
                            if q <= p || rng.next() < 0.2 {
                                continue;
                            }
                            let w = 10f64.powf(4.0 * (rng.next() - 0.5));
                            t.add_triplet(p, p, w);
                            t.add_triplet(q, q, w);
                            t.add_triplet(p, q, -w);
                            t.add_triplet(q, p, -w);
                        }
                    }
                }
            }
        }
    }
    t.to_csr()
}

/// `BlockedCsr` on the fit's sparsity (periodic 27-point stencil with dropped pairs, the default
/// 16 × 9 × 16 node grid): nearly every row is lane-blocked, the padding stays small, the product
/// equals the CSR product bit for bit, and PCG+Jacobi gives the same iterates.
#[test]
fn blocked_product_on_the_fit_sparsity_is_bitwise_the_csr_product() {
    use altrep_solvers::{Parallelism, with_parallelism};
    let a = periodic_stencil(16, 9, 16, 1e-3, 5);
    let blocked = BlockedCsr::new(a.clone()).unwrap();
    let (share, slots) = (blocked.blocked_share(), blocked.slots());
    eprintln!(
        "{} rows, {} entries: {:.1} % of rows blocked, {} slots ({:.3} per entry)",
        a.rows(),
        a.nnz(),
        100.0 * share,
        slots,
        slots as f64 / a.nnz() as f64
    );
    assert!(share >= 0.9, "blocked share {share}");
    assert!(slots as f64 <= 1.35 * a.nnz() as f64, "{slots} slots");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    let mut rng = Lcg(9);
    let x: Vec<f64> = (0..a.cols()).map(|_| rng.next() - 0.5).collect();
    let (mut y0, mut y1) = (vec![0.0; a.rows()], vec![0.0; a.rows()]);
    a.apply(&x, &mut y0);
    blocked.apply(&x, &mut y1);
    assert_eq!(bits(&y0), bits(&y1));
    let b: Vec<f64> = (0..a.rows()).map(|i| (i as f64 * 0.37).sin()).collect();
    let p = SolveParams::default();
    for mode in [Parallelism::Serial, Parallelism::Parallel] {
        let (s0, s1) = with_parallelism(mode, || {
            (
                solve(Method::Pcg, &a, &b, &p).unwrap(),
                solve(Method::Pcg, &blocked, &b, &p).unwrap(),
            )
        });
        assert!(s0.report.converged && s0.report.iterations > 20);
        assert_eq!(s0.report.iterations, s1.report.iterations);
        assert_eq!(
            bits(&s0.report.residual_history),
            bits(&s1.report.residual_history)
        );
        assert_eq!(bits(&s0.x), bits(&s1.x));
    }
    // The other operator methods answer as the CSR matrix's.
    let mut t0 = vec![0.0; a.cols()];
    let mut t1 = vec![0.0; a.cols()];
    a.apply_transpose(&x, &mut t0);
    blocked.apply_transpose(&x, &mut t1);
    assert_eq!(bits(&t0), bits(&t1));
    assert_eq!(a.diagonal(), blocked.diagonal());
    assert_eq!(Some(a.clone()), blocked.to_csr());
    assert_eq!(blocked.csr(), &a);
}

/// A non-finite stored value is a typed error naming the matrix, not a NaN later.
#[test]
fn blocked_product_refuses_non_finite_matrices() {
    let mut t = TriMat::new((20, 20));
    for i in 0..20 {
        t.add_triplet(i, i, 1.0);
    }
    t.add_triplet(3, 4, f64::NAN);
    let err = BlockedCsr::new(t.to_csr()).unwrap_err();
    assert!(
        matches!(err, SolverError::NonFinite { what: "matrix", .. }),
        "{err}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
    /// On random sparsity (scattered rows, bands, empty rows, rectangular, sizes not a
    /// multiple of the block), the blocked product is the CSR product bit for bit, serially and
    /// through the parallel path, and never reads outside `x`.
    #[test]
    fn blocked_product_is_bitwise_the_csr_product(
        m in 0usize..70,
        n in 1usize..70,
        per_row in 0usize..6,
        band in prop::bool::ANY,
        seed in 0u64..10_000,
    ) {
        use altrep_solvers::{Parallelism, with_parallelism};
        let a: CsMat<f64> = if band {
            // Rows of a band, some left empty: many blocks share a pattern.
            let mut rng = Lcg(seed);
            let mut t = TriMat::new((m, n));
            for i in 0..m {
                for d in 0..per_row {
                    let j = i + d;
                    if j < n && rng.next() < 0.8 {
                        t.add_triplet(i, j, rng.next() - 0.5);
                    }
                }
            }
            t.to_csr()
        } else {
            random_rect(m, n, per_row, seed)
        };
        let blocked = BlockedCsr::new(a.clone()).unwrap();
        let mut rng = Lcg(seed + 7);
        let x: Vec<f64> = (0..n).map(|_| 1e3 * (rng.next() - 0.5)).collect();
        let mut y0 = vec![0.0; m];
        a.apply(&x, &mut y0);
        for mode in [Parallelism::Serial, Parallelism::Parallel] {
            let mut y1 = vec![1.0; m];
            with_parallelism(mode, || blocked.apply(&x, &mut y1));
            let (b0, b1): (Vec<u64>, Vec<u64>) =
                (y0.iter().map(|v| v.to_bits()).collect(), y1.iter().map(|v| v.to_bits()).collect());
            prop_assert_eq!(b0, b1);
        }
        prop_assert!(blocked.slots() >= a.nnz());
    }
}
