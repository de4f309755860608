//! The row inside test of meshes (`Shape::contains_row`, used by voxelisation) against the
//! per-point parity test (`Shape::contains`): the same answer for every point, and voxelisation
//! gives the same densities as the per-point loop it replaced, bit for bit. On a generated torus
//! always, and on the evaluation meshes of `../shared/data/meshes`: without them that part is
//! skipped with a visible message, and fails under `CI=true` (`altrep_data_gen::skip`).

use std::f64::consts::TAU;

use altrep_data_gen::{
    Mesh, MeshLoadOptions, Shape, Supersample, VoxelParams, shared_meshes, voxelize,
};
use glam::DVec3;

/// A closed torus (a hole through it, so parity rays cross up to four faces) of `n × m` quads.
fn torus(n: usize, m: usize) -> Mesh {
    let at = |i: usize, j: usize| {
        let (u, v) = (TAU * i as f64 / n as f64, TAU * j as f64 / m as f64);
        let r = 1.0 + 0.4 * v.cos();
        [r * u.cos(), 0.4 * v.sin(), r * u.sin()]
    };
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (a, b) = (at(i, j), at(i + 1, j));
            let (c, d) = (at(i + 1, j + 1), at(i, j + 1));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    Mesh::from_raw_triangles("torus", tris, &MeshLoadOptions::default()).unwrap()
}

/// Rows over and beyond the mesh's box, with points far to the left (the per-point fallback)
/// and exactly on grid lines of the voxelisation.
fn check_rows(mesh: &Mesh) {
    let (mut inside, mut total) = (0usize, 0usize);
    let xs: Vec<f64> = (0..=160).map(|i| -1.25 + 2.5 * i as f64 / 160.0).collect();
    let far: Vec<f64> = vec![-40.0, -3.0, 0.0, 0.5];
    let mut out = vec![false; xs.len()];
    for jy in 0..=60 {
        for jz in 0..=60 {
            let (y, z) = (-0.1 + 2.2 * jy as f64 / 60.0, -1.1 + 2.2 * jz as f64 / 60.0);
            for row in [&xs, &far] {
                mesh.contains_row(y, z, row, &mut out);
                for (x, o) in row.iter().zip(&out) {
                    assert_eq!(
                        *o,
                        mesh.contains(DVec3::new(*x, y, z)),
                        "{}: point ({x}, {y}, {z})",
                        mesh.name()
                    );
                    inside += usize::from(*o);
                    total += 1;
                }
            }
        }
    }
    assert!(
        inside > 0 && inside < total,
        "{}: {inside} of {total} inside",
        mesh.name()
    );
}

/// Densities by the per-point loop voxelisation used before rows (one `contains` per sub-sample
/// and periodic image).
fn per_point_density(shape: &dyn Shape, p: &VoxelParams) -> Vec<f32> {
    let [nx, ny, nz] = p.dims;
    let s = p.supersample.get();
    let extent = p.max - p.min;
    let voxel = extent / DVec3::new(nx as f64, ny as f64, nz as f64);
    let range = |k: usize| if p.periodic[k] { -1..=1 } else { 0..=0 };
    let inside = |q: DVec3| {
        range(0).any(|a| {
            range(1).any(|b| {
                range(2)
                    .any(|c| shape.contains(q + DVec3::new(a as f64, b as f64, c as f64) * extent))
            })
        })
    };
    let mut out = Vec::with_capacity(nx * ny * nz);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let corner = p.min + DVec3::new(x as f64, y as f64, z as f64) * voxel;
                let mut hits = 0usize;
                for a in 0..s {
                    for b in 0..s {
                        for c in 0..s {
                            let f = (DVec3::new(a as f64, b as f64, c as f64) + 0.5) / s as f64;
                            hits += usize::from(inside(corner + f * voxel));
                        }
                    }
                }
                out.push(hits as f32 / (s * s * s) as f32);
            }
        }
    }
    out
}

#[test]
fn mesh_row_inside_test_matches_the_point_test() {
    check_rows(&torus(48, 24));
    for mesh in shared_meshes("the shipped meshes") {
        check_rows(&mesh);
    }
}

#[test]
fn voxelisation_by_rows_gives_the_per_point_densities() {
    let mut meshes = vec![torus(40, 20)];
    meshes.extend(shared_meshes("the shipped meshes"));
    for mesh in &meshes {
        for (supersample, periodic) in [(2, [false; 3]), (1, [true, false, true])] {
            let params = VoxelParams {
                dims: [24, 20, 16],
                min: DVec3::new(-1.0, 0.0, -1.0),
                max: DVec3::new(1.0, 2.0, 0.9),
                periodic,
                supersample: Supersample::of(supersample),
                fill: altrep_data_gen::Fill::Solid,
            };
            let v = voxelize(mesh, &params).unwrap();
            let want = per_point_density(mesh, &params);
            assert!(want.iter().any(|d| *d > 0.0), "{}: empty", mesh.name());
            let same = v
                .density
                .iter()
                .zip(&want)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                same,
                "{}: densities differ from the per-point loop",
                mesh.name()
            );
        }
    }
}
