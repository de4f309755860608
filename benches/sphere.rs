//! Frames over the sphere: the cone bounds of a G = 8, 128² set over the whole sphere (the part
//! of a sphere asset's build that dominated it; docs/design.md §7b, "Cone bounds"), per frame set
//! and for the frame with the widest cone, and the exact warp's drawing of one 128² picture.
//! Setup prints the capture and bounds times of the build and the mean stored interval, so the
//! timing can be read against what the bounds save. Run with `-- --noplot` where criterion's plot
//! backend finds no font.

use std::hint::black_box;

use altrep::data_gen::scene_shape;
use altrep::sphere::{
    ConeBounds, Coverage, SphereImages, SphereParams, SphereRenderParams, SurfaceModel, ViewSet,
    render,
};
use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use rayon::prelude::*;

fn bench(c: &mut Criterion) {
    let shape = scene_shape("truck").expect("bundled shape");
    let params = SphereParams {
        set: ViewSet::new(Coverage::Sphere, 8).expect("view set"),
        size: 128,
        model: SurfaceModel::DEFAULT,
        bounds_block: 1,
    };
    let images = SphereImages::capture(&shape, &params).expect("capture");
    let interval = images.bounds.iter().map(|b| b.stats().0).sum::<f64>() / 64.0;
    eprintln!(
        "truck, 8 × 8 frames of 128² over the sphere: capture {:.3} s, bounds {:.3} s, mean \
         stored interval {interval:.3} (frame depth units)",
        images.capture_time.as_secs_f64(),
        images.bounds_time.as_secs_f64(),
    );
    let mut g = c.benchmark_group("sphere_bounds_truck_g8_128");
    g.sample_size(10);
    g.bench_function("all_frames", |b| {
        b.iter(|| {
            images
                .frames
                .par_iter()
                .zip(&images.cones)
                .map(|(f, &beta)| ConeBounds::build(f, black_box(beta)))
                .collect::<Vec<_>>()
        })
    });
    // The frame with the widest cone: the most cells within reach of each texel (not always
    // the costliest: what its texels see decides how soon their walks stop).
    let widest = (0..images.cones.len())
        .max_by(|&a, &b| images.cones[a].total_cmp(&images.cones[b]))
        .expect("frames");
    g.bench_function("widest_cone_frame", |b| {
        b.iter(|| ConeBounds::build(&images.frames[widest], black_box(images.cones[widest])))
    });
    g.finish();

    let mut g = c.benchmark_group("sphere_render_truck_g8_128");
    let dir = DVec3::new(0.6, 0.3, 0.74).normalize();
    let rp = SphereRenderParams::default();
    g.bench_function("exact_warp_128", |b| {
        b.iter(|| render(&images, black_box(dir), &rp).expect("render"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
