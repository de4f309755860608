//! Speed of two precompute stages against their goals (bench/RESULTS.md, speed work): the parallax
//! bounds (best c, 8 views of 64², default parameters) on every shipped mesh, and the octree build
//! at 256³ (the `tree` scene voxelised once in the setup; only the build is timed).
//!
//! The shipped meshes are read from `../shared/data/meshes` (or `$ALTREP_MESHES`); without them
//! the bounds group prints that it is skipped and times nothing.
//!
//! Run: `cargo bench -p altrep-benches --bench precompute_speed` (add `-- --quick` for a short run).

use std::hint::black_box;
use std::time::Duration;

use altrep_data_gen::Supersample;

use altrep::data_gen::{
    Mesh, MeshLoadOptions, VoxelParams, scene_shape, shared_mesh_paths, voxelize,
};
use altrep::ellipsoid::octree::{Octree, OctreeParams};
use altrep::parallax::{BoundKind, BoundParams, ParallaxImages, ParallaxParams, build_bounds};
use criterion::{Criterion, criterion_group, criterion_main};

fn bounds(c: &mut Criterion) {
    let paths = shared_mesh_paths("the bounds group");
    if paths.is_empty() {
        return;
    }
    let mut g = c.benchmark_group("parallax_bounds_best_c_N8_64");
    g.sample_size(10).measurement_time(Duration::from_secs(3));
    for path in &paths {
        let mesh = Mesh::load_obj(path, &MeshLoadOptions::default()).expect("mesh loads");
        let images =
            ParallaxImages::capture(&mesh, &ParallaxParams::default()).expect("capture succeeds");
        let name = path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into());
        g.bench_function(name, |b| {
            b.iter(|| {
                build_bounds(
                    black_box(&images),
                    BoundKind::BestC,
                    &BoundParams::default(),
                )
                .expect("bounds")
            })
        });
    }
    g.finish();
}

fn octree(c: &mut Criterion) {
    let shape = scene_shape("tree").expect("bundled shape");
    let volume = voxelize(
        &shape,
        &VoxelParams {
            dims: [256; 3],
            min: glam::DVec3::new(-1.0, 0.0, -1.0),
            max: glam::DVec3::new(1.0, 2.0, 1.0),
            periodic: [false; 3],
            supersample: Supersample::ONE,
            fill: altrep_data_gen::Fill::Auto,
        },
    )
    .expect("voxelises");
    let mut g = c.benchmark_group("octree_build");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("tree_256", |b| {
        b.iter(|| Octree::build(black_box(&volume), &OctreeParams::default()).expect("builds"))
    });
    g.finish();
}

criterion_group!(benches, bounds, octree);
criterion_main!(benches);
