//! Krylov solvers on small systems: the serial/parallel split of the kernels and the default
//! offset system (15×8×16 cells, z periodic: 2304 unknowns, 45 344 non-zeros) solved with
//! PCG+Jacobi, with the machine's multiply-add throughput for the lower bound.
//!
//! Groups:
//! - `csr_product_split`: the CSR product serially and split over rayon threads, on the default
//!   normal matrix and on 27-point stencils of growing size — where the split starts to pay is
//!   [`altrep::solvers::operator::PAR_MIN_NNZ`];
//! - `vecops_split`: a dot product serially and split, over growing lengths
//!   ([`altrep::solvers::vecops::PAR_MIN_LEN`]);
//! - `csr_product_split` also times the lane-blocked product ([`BlockedCsr`], bitwise the same
//!   results) on the same matrices, serially and split;
//! - `pcg_default_system`: the default offset system, default (auto) split, forced serial and
//!   forced parallel (same iterates bit for bit), and as the fit solves it: the lane-blocked
//!   matrix built from the CSR matrix and PCG through it (`blocked_build_and_solve`; the
//!   matrix copy it starts from is made outside the timing);
//! - `throughput`: a serial in-cache dense dot product of 45 344 entries, the machine's
//!   multiply-add rate used for the lower bound (bench/RESULTS.md: multiply-adds of the solve
//!   ÷ this rate).
//!
//! Run: `cargo bench -p altrep-benches --bench solvers` (add `-- --quick` for a short run).

use std::hint::black_box;
use std::time::Duration;

use altrep::cli::fit_bench::test_function;
use altrep::fit::{DEFAULT_LAMBDA, FitSamples, NormalEquations};
use altrep::solvers::operator::csr_apply_raw;
use altrep::solvers::vecops::dot;
use altrep::solvers::{
    BlockedCsr, LinearOperator, Method, Parallelism, SolveParams, solve, with_parallelism,
};
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use sprs::{CsMat, TriMat};

const CELLS: [usize; 3] = [15, 8, 16];
const PERIODIC: [bool; 3] = [false, false, true];
const SAMPLES: [usize; 3] = [128, 64, 256];

fn normal_matrix() -> (CsMat<f64>, Vec<f64>) {
    let s = FitSamples::from_fn(SAMPLES, test_function).expect("test function samples are finite");
    let ne = NormalEquations::assemble(&s, CELLS, PERIODIC).expect("assembles");
    (ne.matrix(DEFAULT_LAMBDA), ne.rhs().to_vec())
}

/// A 27-point stencil on an `m³` grid (the sparsity of a trilinear fit's normal matrix).
fn stencil(m: usize) -> CsMat<f64> {
    let n = m * m * m;
    let mut t = TriMat::new((n, n));
    let id = |x: usize, y: usize, z: usize| x + m * (y + m * z);
    for z in 0..m {
        for y in 0..m {
            for x in 0..m {
                let i = id(x, y, z);
                for dz in -1i64..=1 {
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let (a, b, c) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                            if [a, b, c].iter().all(|&v| v >= 0 && v < m as i64) {
                                let j = id(a as usize, b as usize, c as usize);
                                let v = if i == j { 27.0 } else { -1.0 + 1e-3 * j as f64 };
                                t.add_triplet(i, j, v);
                            }
                        }
                    }
                }
            }
        }
    }
    t.to_csr()
}

fn products(c: &mut Criterion) {
    let (a, _) = normal_matrix();
    let mut g = c.benchmark_group("csr_product_split");
    g.warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    let mut mats = vec![("normal_45k".to_string(), a)];
    for m in [16, 22, 28, 36] {
        let s = stencil(m);
        mats.push((format!("stencil_{}k", s.nnz() / 1000), s));
    }
    for (name, a) in &mats {
        let x: Vec<f64> = (0..a.cols()).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut y = vec![0.0; a.rows()];
        let ip = a.proper_indptr();
        for (mode, label) in [
            (Parallelism::Serial, "serial"),
            (Parallelism::Parallel, "parallel"),
        ] {
            g.bench_function(format!("{name}/{label}"), |b| {
                b.iter(|| {
                    with_parallelism(mode, || {
                        csr_apply_raw(&ip, a.indices(), a.data(), black_box(&x), &mut y)
                    })
                })
            });
        }
        let blocked = BlockedCsr::new(a.clone()).expect("finite matrix");
        for (mode, label) in [
            (Parallelism::Serial, "blocked_serial"),
            (Parallelism::Parallel, "blocked_parallel"),
        ] {
            g.bench_function(format!("{name}/{label}"), |b| {
                b.iter(|| with_parallelism(mode, || blocked.apply(black_box(&x), &mut y)))
            });
        }
    }
    g.finish();
}

fn vecops(c: &mut Criterion) {
    let mut g = c.benchmark_group("vecops_split");
    g.warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for n in [1 << 16, 1 << 18, 1 << 20] {
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos()).collect();
        for (mode, label) in [
            (Parallelism::Serial, "serial"),
            (Parallelism::Parallel, "parallel"),
        ] {
            g.bench_function(format!("dot_{n}/{label}"), |b| {
                b.iter(|| with_parallelism(mode, || dot(black_box(&x), black_box(&y))))
            });
        }
    }
    g.finish();
}

fn pcg_default(c: &mut Criterion) {
    let (a, rhs) = normal_matrix();
    let p = SolveParams::default();
    let mut g = c.benchmark_group("pcg_default_system");
    g.sample_size(30)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    let probe = solve(Method::Pcg, &a, &rhs, &p).expect("solves");
    eprintln!(
        "pcg+jacobi on the default system: {} unknowns, {} non-zeros, {} iterations, {} products, relative residual {:.3e}",
        a.rows(),
        a.nnz(),
        probe.report.iterations,
        probe.report.operator_applications,
        probe.report.relative_residual
    );
    g.bench_function("pcg_jacobi/blocked_build_and_solve", |b| {
        b.iter_batched(
            || a.clone(),
            |m| {
                let op = BlockedCsr::new(m).expect("finite matrix");
                solve(Method::Pcg, &op, black_box(&rhs), &p).expect("solves")
            },
            BatchSize::LargeInput,
        )
    });
    let op = BlockedCsr::new(a.clone()).expect("finite matrix");
    g.bench_function("pcg_jacobi/blocked_solve", |b| {
        b.iter(|| solve(Method::Pcg, &op, black_box(&rhs), &p).expect("solves"))
    });
    for (mode, label) in [
        (Parallelism::Auto, "auto"),
        (Parallelism::Serial, "serial"),
        (Parallelism::Parallel, "parallel"),
    ] {
        g.bench_function(format!("pcg_jacobi/{label}"), |b| {
            b.iter(|| {
                with_parallelism(mode, || {
                    solve(Method::Pcg, &a, black_box(&rhs), &p).expect("solves")
                })
            })
        });
    }
    g.finish();
}

fn throughput(c: &mut Criterion) {
    let n = 45_344;
    let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos()).collect();
    let mut g = c.benchmark_group("throughput");
    g.warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    g.bench_function("dense_dot_45344_madds", |b| {
        b.iter(|| with_parallelism(Parallelism::Serial, || dot(black_box(&x), black_box(&y))))
    });
    g.finish();
}

criterion_group!(benches, throughput, pcg_default, products, vecops);
criterion_main!(benches);
