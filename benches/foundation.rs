//! Foundation benchmarks: ray-casting throughput of captures (procedural and mesh), the
//! coverage check's silhouettes against full truths, and the mip pyramid's build and trilinear
//! sampling. `cargo bench -p altrep-benches --bench foundation`.

use altrep::cylinder::CoverageParams;
use altrep::mip::{Pyramid, PyramidParams, Texture, WrapMode};
use altrep_data_gen::{
    BoundingCylinder, CylinderParams, Light, RayByRay, Shape, TruthParams, ViewParams,
    capture_cylinder, capture_view, render_silhouette, render_truth, scene_shape, shared_mesh,
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
    for m in ["beetle", "stanford-bunny"] {
        if let Some(mesh) = shared_mesh(m, "a capture_view_128 mesh") {
            shapes.push(Box::new(mesh));
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

/// A pool of one thread: the per-core rates.
fn one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
}

/// The views of `altrep capture --views 8 --size 512`: angles `2πk/8`, 512².
fn eight_views_512() -> impl Iterator<Item = ViewParams> {
    (0..8).map(|k| ViewParams {
        angle: std::f64::consts::TAU * k as f64 / 8.0,
        ..view_params(512)
    })
}

/// `altrep capture --views 8 --size 512` without the files: 8 orthographic views of 512² (hit
/// distance, normal, colour per ray), traced as grids (`grid`) or ray by ray through the BVH
/// (`walk`), on 1 thread (the per-core rate) and on all threads.
fn ray_casting(c: &mut Criterion) {
    let mut g = c.benchmark_group("ray_casting_8x512");
    g.throughput(Throughput::Elements(8 * 512 * 512));
    g.sample_size(10);
    let one = one_thread();
    for m in ["teapot", "beetle", "stanford-bunny"] {
        let Some(mesh) = shared_mesh(m, "a ray_casting_8x512 mesh") else {
            continue;
        };
        let walk = RayByRay(&mesh);
        let views = |shape: &dyn Shape| {
            for view in eight_views_512() {
                std::hint::black_box(capture_view(shape, &view).unwrap());
            }
        };
        for (name, shape) in [("grid", &mesh as &dyn Shape), ("walk", &walk as &dyn Shape)] {
            g.bench_function(format!("{m}/{name}/1_thread"), |b| {
                b.iter(|| one.install(|| views(shape)))
            });
            g.bench_function(format!("{m}/{name}/all_threads"), |b| {
                b.iter(|| views(shape))
            });
        }
    }
    g.finish();
}

/// The rays of the pipeline's cylindrical capture (256 × 64 texels, prefilter 3: 768 × 192
/// radial rays) without the texture: binned by height and angle (`grid`) or ray by ray through
/// the BVH (`walk`), on 1 thread.
fn cylinder_rays(c: &mut Criterion) {
    let mut g = c.benchmark_group("cylinder_rays_768x192");
    g.throughput(Throughput::Elements(768 * 192));
    g.sample_size(10);
    let one = one_thread();
    let params = CylinderParams {
        columns: 768,
        rows: 192,
        cylinder: BoundingCylinder::default(),
    };
    for m in ["teapot", "beetle", "stanford-bunny"] {
        let Some(mesh) = shared_mesh(m, "a cylinder_rays_768x192 mesh") else {
            continue;
        };
        mesh.prepare_rays();
        let walk = RayByRay(&mesh);
        for (name, shape) in [("grid", &mesh as &dyn Shape), ("walk", &walk as &dyn Shape)] {
            g.bench_function(format!("{m}/{name}/1_thread"), |b| {
                b.iter(|| one.install(|| capture_cylinder(shape, &params).unwrap()))
            });
        }
    }
    g.finish();
}

/// The cylinder coverage check's ground truths (8 angles of 48² pixels, 2 × 2 sub-samples,
/// `CoverageParams::default()`): the shaded truth it rendered before against the silhouette it
/// renders now (`render_silhouette`, the same alpha bitwise), on one thread.
fn coverage_truths(c: &mut Criterion) {
    let p = CoverageParams::default();
    let rays = p.angles * (p.size * p.supersample.get()).pow(2);
    let mut g = c.benchmark_group("coverage_truths_8x48x48k2");
    g.throughput(Throughput::Elements(rays as u64));
    g.sample_size(10);
    let one = one_thread();
    for m in ["teapot", "stanford-bunny"] {
        let Some(mesh) = shared_mesh(m, "a coverage_truths mesh") else {
            continue;
        };
        mesh.prepare_rays();
        let params = |n: usize| TruthParams {
            angle: p.angle(n),
            width: p.size,
            height: p.size,
            supersample: p.supersample,
            light: Light::default(),
            cylinder: BoundingCylinder::default(),
        };
        g.bench_function(format!("{m}/truth/1_thread"), |b| {
            b.iter(|| {
                one.install(|| {
                    (0..p.angles)
                        .map(|n| render_truth(&mesh, &params(n)).unwrap().pixels.len())
                        .sum::<usize>()
                })
            })
        });
        g.bench_function(format!("{m}/silhouette/1_thread"), |b| {
            b.iter(|| {
                one.install(|| {
                    (0..p.angles)
                        .map(|n| render_silhouette(&mesh, &params(n)).unwrap().len())
                        .sum::<usize>()
                })
            })
        });
    }
    g.finish();
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

/// The two costs every ray-cast view pays at least, for the lower bound of `ray_casting_8x512`
/// (`bench/RESULTS.md`): one triangle test per hit (`obvhs`'s Möller–Trumbore, the test of both
/// tracers, on 65 536 rays that each hit their own triangle) and the output grid of one view of
/// 512² (a fresh `Vec<Option<Sample>>`, a third of it empty). One thread. Also prints each
/// shipped mesh's hits over the 8 views (the count the bound multiplies).
fn ray_casting_bound(c: &mut Criterion) {
    use altrep_data_gen::{Sample, SplitMix64};
    use glam::{Vec3, Vec3A};
    use obvhs::{ray::Ray, triangle::Triangle};
    let one = one_thread();
    for m in ["teapot", "beetle", "stanford-bunny"] {
        let Some(mesh) = shared_mesh(m, "a ray_casting_bound mesh") else {
            continue;
        };
        let hits: usize = one.install(|| {
            eight_views_512()
                .map(|view| {
                    let grid = capture_view(&mesh, &view).unwrap();
                    grid.samples.iter().filter(|s| s.is_some()).count()
                })
                .sum()
        });
        eprintln!("ray_casting_bound: {m}: {hits} hits in 8 views of 512²");
    }
    let mut g = c.benchmark_group("ray_casting_bound");
    let n = 65_536;
    let mut rng = SplitMix64::new(7);
    let mut r = || rng.next_f64() as f32;
    let (tris, rays): (Vec<Triangle>, Vec<Ray>) = (0..n)
        .map(|_| {
            let v0 = Vec3A::new(r(), r(), r());
            let tri = Triangle {
                v0,
                v1: v0 + Vec3A::new(0.01 + r() * 0.01, r() * 0.002, 0.0),
                v2: v0 + Vec3A::new(r() * 0.002, 0.01 + r() * 0.01, 0.001),
            };
            let target = (tri.v0 + tri.v1 + tri.v2) / 3.0;
            let dir = Vec3A::new(0.0, 0.0, -1.0);
            (tri, Ray::new(target - 2.0 * dir, dir, 0.0, 4.0))
        })
        .unzip();
    assert!(
        tris.iter()
            .zip(&rays)
            .all(|(t, r)| t.intersect(r).is_finite())
    );
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("triangle_test_hits", |b| {
        b.iter(|| {
            tris.iter()
                .zip(&rays)
                .map(|(t, r)| t.intersect(std::hint::black_box(r)))
                .sum::<f32>()
        })
    });
    let cells = 512 * 512;
    g.throughput(Throughput::Elements(cells as u64));
    let sample = Sample {
        albedo: Vec3::new(0.5, 0.25, 0.125),
        normal: Vec3::Z,
        depth: 0.5,
    };
    g.bench_function("view_grid_512_writes", |b| {
        b.iter(|| {
            let v: Vec<Option<Sample>> = (0..cells)
                .map(|i| (i % 3 != 0).then_some(std::hint::black_box(sample)))
                .collect();
            v
        })
    });
    g.finish();
}

criterion_group!(
    benches,
    capture,
    ray_casting,
    ray_casting_bound,
    cylinder_rays,
    coverage_truths,
    mip
);
criterion_main!(benches);
