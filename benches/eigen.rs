//! Time per 3×3 symmetric eigen-decomposition: altrep's hybrid solver against nalgebra's
//! `SymmetricEigen`, in f64 and f32, over 1024 random symmetric matrices and over the adversarial
//! suite. `cargo bench -p altrep-benches --bench eigen`; criterion reports time per matrix (throughput = 1 element).

use std::hint::black_box;

use altrep::ellipsoid::eigen::{adversarial_suite, sym_eigen3, sym_eigen3_nalgebra};
use altrep::ellipsoid::report::timing_set;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Matrix3;

fn bench_set<T: altrep::ellipsoid::eigen::EigenScalar>(
    c: &mut Criterion,
    group: &str,
    mats: &[Matrix3<T>],
) {
    let mut g = c.benchmark_group(group);
    g.throughput(Throughput::Elements(mats.len() as u64));
    g.bench_function("altrep", |b| {
        b.iter(|| {
            for m in mats {
                let _ = black_box(sym_eigen3(black_box(m)));
            }
        })
    });
    g.bench_function("nalgebra", |b| {
        b.iter(|| {
            for m in mats {
                let _ = black_box(sym_eigen3_nalgebra(black_box(m)));
            }
        })
    });
    g.finish();
}

fn eigen(c: &mut Criterion) {
    let random = timing_set(1, 1024);
    let random32: Vec<Matrix3<f32>> = random.iter().map(|m| m.map(|x| x as f32)).collect();
    let suite: Vec<Matrix3<f64>> = adversarial_suite(1).into_iter().map(|c| c.matrix).collect();
    bench_set(c, "eigen3/random/f64", &random);
    bench_set(c, "eigen3/random/f32", &random32);
    bench_set(c, "eigen3/adversarial/f64", &suite);
}

criterion_group!(benches, eigen);
criterion_main!(benches);
