//! Criterion bench of the trilinear fit on the source's operating point: 15×8×16 cells (z
//! periodic), 128×64×256 ≈ 2.1 million samples of `altrep fit-bench`'s test function (≈ 1.26
//! million defined). Groups: assembly (normal equations, design matrix), one solve per solver
//! configuration, and the CSR product (sprs serial vs altrep parallel).
//!
//! Run: `cargo bench -p altrep-benches --bench fit` (add `-- --quick` for a short run).

use std::hint::black_box;
use std::time::Duration;

use altrep::cli::fit_bench::test_function;
use altrep::fit::{DEFAULT_LAMBDA, DesignMatrix, FitSamples, NormalEquations};
use altrep::solvers::{Method, PreconditionerKind, SolveParams, par_mul_vec, solve};
use criterion::{Criterion, criterion_group, criterion_main};

const CELLS: [usize; 3] = [15, 8, 16];
const PERIODIC: [bool; 3] = [false, false, true];
const SAMPLES: [usize; 3] = [128, 64, 256];

fn samples() -> FitSamples {
    FitSamples::from_fn(SAMPLES, test_function).expect("test function samples are finite")
}

fn assembly(c: &mut Criterion) {
    let s = samples();
    let mut g = c.benchmark_group("fit_assembly");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("normal_equations_15x8x16_2M", |b| {
        b.iter(|| NormalEquations::assemble(black_box(&s), CELLS, PERIODIC).expect("assembles"))
    });
    let ne = NormalEquations::assemble(&s, CELLS, PERIODIC).expect("assembles");
    g.bench_function("matrix_at_lambda", |b| {
        b.iter(|| ne.matrix(black_box(DEFAULT_LAMBDA)))
    });
    let cc = DEFAULT_LAMBDA * ne.laplacian_scale();
    g.bench_function("design_matrix_15x8x16_2M", |b| {
        b.iter(|| DesignMatrix::build(black_box(&s), CELLS, PERIODIC, cc).expect("builds"))
    });
    g.finish();
}

fn solvers(c: &mut Criterion) {
    let s = samples();
    let ne = NormalEquations::assemble(&s, CELLS, PERIODIC).expect("assembles");
    let a = ne.matrix(DEFAULT_LAMBDA);
    let cc = DEFAULT_LAMBDA * ne.laplacian_scale();
    let design = DesignMatrix::build(&s, CELLS, PERIODIC, cc).expect("builds");
    let mut g = c.benchmark_group("fit_solve");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    use PreconditionerKind::{Jacobi, None, Ssor};
    for (m, pc) in [
        (Method::Pbicg, Jacobi),
        (Method::Pcg, Jacobi),
        (Method::Pcg, Ssor { omega: 1.0 }),
        (Method::Pcg, None),
        (Method::Bicgstab, Jacobi),
        (Method::Lsqr, Jacobi),
        (Method::Lsmr, Jacobi),
    ] {
        let p = SolveParams {
            preconditioner: pc,
            ..SolveParams::default()
        };
        g.bench_function(format!("{}+{}", m.name(), pc.name()), |b| {
            b.iter(|| {
                if m.is_least_squares() {
                    solve(m, &design.matrix, black_box(&design.rhs), &p)
                } else {
                    solve(m, &a, black_box(ne.rhs()), &p)
                }
                .expect("solves")
            })
        });
    }
    g.finish();
}

fn products(c: &mut Criterion) {
    let s = samples();
    let ne = NormalEquations::assemble(&s, CELLS, PERIODIC).expect("assembles");
    let a = ne.matrix(DEFAULT_LAMBDA);
    let design = DesignMatrix::build(&s, CELLS, PERIODIC, 0.0).expect("builds");
    let mut g = c.benchmark_group("csr_product");
    let x = vec![1.0; a.cols()];
    let mut y = vec![0.0; a.rows()];
    g.bench_function("normal_sprs_serial", |b| {
        b.iter(|| sprs::prod::mul_acc_mat_vec_csr(a.view(), black_box(&x[..]), &mut y[..]))
    });
    g.bench_function("normal_altrep_parallel", |b| {
        b.iter(|| par_mul_vec(a.view(), black_box(&x), &mut y).expect("sizes match"))
    });
    let xd = vec![1.0; design.matrix.cols()];
    let mut yd = vec![0.0; design.matrix.rows()];
    g.bench_function("design_sprs_serial", |b| {
        b.iter(|| {
            sprs::prod::mul_acc_mat_vec_csr(design.matrix.view(), black_box(&xd[..]), &mut yd[..])
        })
    });
    g.bench_function("design_altrep_parallel", |b| {
        b.iter(|| par_mul_vec(design.matrix.view(), black_box(&xd), &mut yd).expect("sizes match"))
    });
    g.finish();
}

criterion_group!(benches, assembly, solvers, products);
criterion_main!(benches);
