//! RGBA8 sRGB mip-chain builds (linear light, straight alpha premultiplied for filtering, every
//! level from level 0), box and Kaiser: ours against `image` and `fast_image_resize` configured
//! alike ([`altrep::pyramid::speed`]). `cargo bench -p altrep-benches --bench pyramid`; the 4096² figures with the
//! exactness check come from `altrep pyramid-bench`.

use altrep::pyramid::Filter;
use altrep::pyramid::fast::{FastOptions, mip_chain_rgba8, mip_chain_rgba8_with};
use altrep::pyramid::speed::{bench_params, fir_chain, image_chain, test_image};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn chains(c: &mut Criterion) {
    let n = 1024;
    let src = test_image(n);
    for filter in [Filter::Box, Filter::Kaiser] {
        let mut g = c.benchmark_group(format!("mip_chain_rgba8_{n}_{filter:?}"));
        g.sample_size(10);
        g.throughput(Throughput::Bytes((n * n * 4) as u64));
        let p = bench_params(filter);
        g.bench_function("ours", |b| {
            b.iter(|| mip_chain_rgba8(&src, n, n, &p).unwrap())
        });
        // The same builder without the SIMD kernels, and (box) without the 2×2 cascade.
        g.bench_function("ours_portable", |b| {
            let o = FastOptions {
                simd: false,
                ..Default::default()
            };
            b.iter(|| mip_chain_rgba8_with(&src, n, n, &p, o).unwrap())
        });
        if filter == Filter::Box {
            g.bench_function("ours_every_level_from_0", |b| {
                let o = FastOptions {
                    box_cascade: false,
                    ..Default::default()
                };
                b.iter(|| mip_chain_rgba8_with(&src, n, n, &p, o).unwrap())
            });
        }
        g.bench_function("image", |b| {
            b.iter(|| image_chain(&src, n, filter).unwrap())
        });
        g.bench_function("fast_image_resize", |b| {
            b.iter(|| fir_chain(&src, n, filter).unwrap())
        });
        g.finish();
    }
}

criterion_group!(benches, chains);
criterion_main!(benches);
