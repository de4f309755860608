//! Foundation benchmarks: ray-casting throughput of captures (procedural and mesh) and the mip
//! pyramid's build and trilinear sampling. `cargo bench --bench foundation`.

use altrep::mip::{Pyramid, PyramidParams, Texture, WrapMode};
use altrep_data_gen::{
    BoundingCylinder, CylinderParams, Mesh, MeshLoadOptions, Shape, ViewParams, capture_cylinder,
    capture_view, scene_shape,
};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn view_params(size: usize) -> ViewParams {
    ViewParams {
        angle: 0.6,
        width: size,
        height: size,
        cylinder: BoundingCylinder::default(),
    }
}

fn capture(c: &mut Criterion) {
    let mut g = c.benchmark_group("capture_view_128");
    g.throughput(Throughput::Elements(128 * 128));
    let mut shapes: Vec<Box<dyn Shape>> = ["truck", "tree", "torus"]
        .iter()
        .map(|n| Box::new(scene_shape(n).unwrap()) as Box<dyn Shape>)
        .collect();
    let meshes = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/meshes/");
    for m in ["beetle", "stanford-bunny"] {
        match Mesh::load_obj(format!("{meshes}{m}.obj"), &MeshLoadOptions::default()) {
            Ok(mesh) => shapes.push(Box::new(mesh)),
            Err(e) => eprintln!("skipping {m}: {e}"),
        }
    }
    for shape in &shapes {
        g.bench_function(shape.name(), |b| {
            b.iter(|| capture_view(shape.as_ref(), &view_params(128)).unwrap())
        });
    }
    g.finish();
    let truck = scene_shape("truck").unwrap();
    c.bench_function("capture_cylinder_256x64_truck", |b| {
        b.iter(|| capture_cylinder(&truck, &CylinderParams::default()).unwrap())
    });
}

fn mip(c: &mut Criterion) {
    let tex = Texture::new(
        256,
        256,
        4,
        (0..256 * 256 * 4).map(|i| (i % 97) as f32 / 97.0).collect(),
    )
    .unwrap();
    let params = PyramidParams {
        wrap: [WrapMode::Repeat, WrapMode::Clamp],
        ..Default::default()
    };
    c.bench_function("mip_build_256x256x4", |b| {
        b.iter(|| Pyramid::build(tex.clone(), params).unwrap())
    });
    let pyr = Pyramid::build(tex, params).unwrap();
    c.bench_function("mip_trilinear_1000", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for k in 0..1000 {
                let t = k as f64 / 1000.0;
                acc += pyr.trilinear(t, 1.0 - t, 3.0 * t)[0];
            }
            acc
        })
    });
}

criterion_group!(benches, capture, mip);
criterion_main!(benches);
