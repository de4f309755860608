//! Images with parallax: inverse-warping cost per bound type, and cost against error over the
//! number of views and the view size (docs/design.md §13). The bound type changes the cost only
//! (the image is the same); views and size change both. Setup prints steps per frame and PSNR
//! against the ground truth (one ray per pixel, as rendered) so each timing can be read against its
//! error.

use std::hint::black_box;

use altrep_data_gen::Supersample;

use altrep::data_gen::{BoundingCylinder, Light, TruthParams, render_truth, scene_shape};
use altrep::metrics::psnr;
use altrep::parallax::{
    BoundKind, BoundParams, ParallaxImages, ParallaxParams, build_bounds, render_bounded,
};
use criterion::{Criterion, criterion_group, criterion_main};

fn bench(c: &mut Criterion) {
    let shape = scene_shape("truck").expect("bundled shape");
    let light = Light::default();
    let alpha = 0.3;
    let truth = |size: usize| {
        render_truth(
            &shape,
            &TruthParams {
                angle: alpha,
                width: size,
                height: size,
                supersample: Supersample::ONE,
                light,
                cylinder: BoundingCylinder::default(),
            },
        )
        .expect("truth")
    };

    let images = ParallaxImages::capture(&shape, &ParallaxParams::default()).expect("capture");
    let reference = truth(64);
    let mut g = c.benchmark_group("parallax_frame_64x64_N8_by_bound");
    for kind in BoundKind::ALL {
        let b = build_bounds(&images, kind, &BoundParams::default()).expect("bounds");
        let (img, steps) = render_bounded(&images, &b, alpha, &light).expect("render");
        eprintln!(
            "bound {:>16}: {steps:>6} steps per frame, PSNR {:.2} dB, {} bytes",
            kind.name(),
            psnr(&img, &reference).expect("psnr"),
            images.bytes() + b.bytes(&images)
        );
        g.bench_function(kind.slug(), |bch| {
            bch.iter(|| render_bounded(&images, &b, black_box(alpha), &light).expect("render"))
        });
    }
    g.finish();

    let mut g = c.benchmark_group("parallax_frame_best_c_by_views_and_size");
    for (views, size) in [(4, 64), (8, 32), (8, 64), (8, 128), (16, 64)] {
        let p = ParallaxParams {
            views,
            width: size,
            height: size,
            ..ParallaxParams::default()
        };
        let images = ParallaxImages::capture(&shape, &p).expect("capture");
        let b = build_bounds(&images, BoundKind::BestC, &BoundParams::default()).expect("bounds");
        let (img, steps) = render_bounded(&images, &b, alpha, &light).expect("render");
        eprintln!(
            "N = {views:>2}, {size:>3}²: {steps:>7} steps per frame, PSNR {:.2} dB, {} bytes",
            psnr(&img, &truth(size)).expect("psnr"),
            images.bytes() + b.bytes(&images)
        );
        g.bench_function(format!("N{views}_{size}"), |bch| {
            bch.iter(|| render_bounded(&images, &b, black_box(alpha), &light).expect("render"))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
