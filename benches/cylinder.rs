//! Cylindrical textures: run time against error (docs/design.md §13).
//! `cargo bench -p altrep-benches --bench cylinder`.
//!
//! * `cylinder_render/<method>` — one 64 × 64 image of the pear, one sample per pixel (as a
//!   shader draws it), per renderer; each renderer's PSNR against the ground truth and mean steps
//!   are printed beside it, so time and error read together.
//! * `cylinder_offset_fit/<grid>` — the offset precomputation (sampling shared, then assembly and
//!   solve) for the grids of the sweep, with the offset RMS error printed.
//! * `cylinder_capture` — the 256 × 64 capture with 3 × 3 prefilter rays per texel (truck, and
//!   the beetle mesh when `../shared/data/meshes/` is present).

use altrep::cylinder::{
    CylinderRenderParams, CylindricalTexture, DrawOrder, ExactMethod, OffsetMode, OffsetParams,
    OffsetTexture, RadiusModel, SWEEP_GRIDS, render_exact, sample_offsets,
};
use altrep::data_gen::{
    CylinderParams, Light, Shape, TruthParams, render_truth, scene_shape, shared_mesh,
};
use altrep::metrics::psnr;
use altrep_data_gen::Supersample;
use criterion::{Criterion, criterion_group, criterion_main};

fn params() -> CylinderRenderParams {
    CylinderRenderParams {
        angle: 0.9,
        width: 64,
        height: 64,
        supersample: Supersample::ONE,
        light: Light::default(),
    }
}

fn render(c: &mut Criterion) {
    let pear = scene_shape("pear").unwrap();
    let tex = CylindricalTexture::capture(&pear, &CylinderParams::default(), 3).unwrap();
    let off = OffsetTexture::fit(&tex, &OffsetParams::default()).unwrap();
    let p = params();
    let truth = render_truth(
        &pear,
        &TruthParams {
            angle: p.angle,
            width: p.width,
            height: p.height,
            supersample: Supersample::of(4),
            light: p.light,
            cylinder: tex.cylinder(),
        },
    )
    .unwrap();
    let mut g = c.benchmark_group("cylinder_render");
    let exact = [
        ExactMethod::Mesh,
        ExactMethod::Direct(DrawOrder::BackToFront, RadiusModel::General),
        ExactMethod::Direct(DrawOrder::FrontToBack, RadiusModel::General),
        ExactMethod::Inverse(RadiusModel::General),
    ];
    for m in exact {
        let r = render_exact(&tex, m, &p).unwrap();
        eprintln!(
            "{}: {:.2} dB, {:.1} steps/pixel",
            m.name(),
            psnr(&r.image, &truth).unwrap(),
            r.mean_steps()
        );
        g.bench_function(m.name(), |b| b.iter(|| render_exact(&tex, m, &p).unwrap()));
    }
    for mode in [
        OffsetMode::Plain,
        OffsetMode::Hybrid { steps: 2 },
        OffsetMode::Hybrid { steps: 4 },
    ] {
        let r = off.render(&tex, mode, 1.0, &p).unwrap();
        eprintln!(
            "{}: {:.2} dB, {:.2} steps/pixel",
            mode.name(),
            psnr(&r.image, &truth).unwrap(),
            r.mean_steps()
        );
        g.bench_function(mode.name(), |b| {
            b.iter(|| off.render(&tex, mode, 1.0, &p).unwrap())
        });
    }
    g.finish();
}

fn offset_fit(c: &mut Criterion) {
    let pear = scene_shape("pear").unwrap();
    let tex = CylindricalTexture::capture(&pear, &CylinderParams::default(), 3).unwrap();
    let defaults = OffsetParams::default();
    let samples = sample_offsets(&tex, defaults.samples, defaults.mask).unwrap();
    let mut g = c.benchmark_group("cylinder_offset_fit");
    g.sample_size(10);
    g.bench_function("sampling_64x64x64", |b| {
        b.iter(|| sample_offsets(&tex, defaults.samples, defaults.mask).unwrap())
    });
    for cells in SWEEP_GRIDS {
        let params = OffsetParams { cells, ..defaults };
        let off = OffsetTexture::fit_samples(&tex, &samples, &params).unwrap();
        let name = format!("{}x{}x{}", cells[0], cells[1], cells[2]);
        eprintln!(
            "{name}: fine-grid offset RMS {:.2} texels, {} B",
            off.report.error_defined.rms, off.report.bytes
        );
        g.bench_function(&name, |b| {
            b.iter(|| OffsetTexture::fit_samples(&tex, &samples, &params).unwrap())
        });
    }
    g.finish();
}

fn capture(c: &mut Criterion) {
    let mut shapes: Vec<Box<dyn Shape>> = vec![Box::new(scene_shape("truck").unwrap())];
    if let Some(mesh) = shared_mesh("beetle", "the cylinder_capture group's beetle") {
        shapes.push(Box::new(mesh));
    }
    let mut g = c.benchmark_group("cylinder_capture");
    g.sample_size(10);
    for shape in &shapes {
        g.bench_function(shape.name(), |b| {
            b.iter(|| {
                CylindricalTexture::capture(shape.as_ref(), &CylinderParams::default(), 3).unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, render, offset_fit, capture);
criterion_main!(benches);
