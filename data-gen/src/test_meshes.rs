//! Meshes and checks shared by the tests of the grid tracers ([`crate::binned`],
//! [`crate::radial`]).

use std::f64::consts::{PI, TAU};

use crate::binned::BandTracer;
use crate::geometry::Ray;
use crate::mesh::{Mesh, MeshLoadOptions};
use crate::rng::SplitMix64;
use crate::watertight::Shear;

pub(crate) fn mesh(tris: Vec<[[f64; 3]; 3]>) -> Mesh {
    Mesh::from_raw_triangles("test", tris, &MeshLoadOptions::default()).unwrap()
}

/// A UV sphere of `n` × `2n` quads (two triangles each), moved by `shift` along x.
pub(crate) fn sphere(n: usize, shift: f64) -> Vec<[[f64; 3]; 3]> {
    let p = |a: usize, b: usize| {
        let (th, ph) = (PI * a as f64 / n as f64, TAU * b as f64 / (2 * n) as f64);
        [th.sin() * ph.cos() + shift, th.cos(), th.sin() * ph.sin()]
    };
    let mut tris = Vec::new();
    for a in 0..n {
        for b in 0..2 * n {
            tris.push([p(a, b), p(a + 1, b), p(a + 1, b + 1)]);
            tris.push([p(a, b), p(a + 1, b + 1), p(a, b + 1)]);
        }
    }
    tris
}

/// `n` random triangles of [`soup`] with random texture coordinates, in one glTF material whose
/// alpha mask ([`TestGltf::masked_quad`]'s texture) cuts holes in about a third of each: every
/// tracer must pass through the same holes.
pub(crate) fn masked_soup(seed: u64, n: usize) -> Mesh {
    use crate::gltf_write::{TestGltf, TestPrimitive};
    let mut doc = TestGltf::masked_quad(8);
    let mut rng = SplitMix64::new(seed ^ 0x5eed);
    let tris = soup(seed, n);
    doc.meshes = vec![vec![TestPrimitive {
        positions: tris.iter().flatten().map(|v| v.map(|c| c as f32)).collect(),
        uvs: (0..3 * tris.len())
            .map(|_| [rng.range(0.0, 1.0) as f32, rng.range(0.0, 1.0) as f32])
            .collect(),
        indices: (0..3 * tris.len() as u32).collect(),
        normals: Vec::new(),
        tangents: Vec::new(),
        material: 0,
    }]];
    let glb = doc.to_glb().unwrap();
    Mesh::from_gltf_bytes(
        &glb,
        std::path::Path::new("soup.glb"),
        &MeshLoadOptions::default(),
    )
    .unwrap()
}

/// Random triangles, a third of them slivers (two vertices within 1e-4 of each other).
pub(crate) fn soup(seed: u64, n: usize) -> Vec<[[f64; 3]; 3]> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|k| {
            let mut p = || {
                [
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                ]
            };
            let (a, b) = (p(), p());
            let c = if k % 3 == 0 { a.map(|x| x + 1e-4) } else { p() };
            [a, b, c]
        })
        .collect()
}

/// Squashes the first `count` triangles of `tris` onto (within `1e-7` of) the plane `y = 0.5`:
/// edge-on from horizontal rays.
pub(crate) fn squash_flat(tris: &mut [[[f64; 3]; 3]], count: usize) {
    for t in tris.iter_mut().take(count) {
        for v in t.iter_mut() {
            v[1] = 0.5 + 1e-7 * v[1];
        }
    }
}

/// The nearest hit of `ray` in `(t_min, t_max)` over every triangle of `mesh`, by the BVH's own
/// `f32` triangle test without the BVH: the triangle (the first in triangle order among equal
/// distances) and its distance.
pub(crate) fn nearest_of_all(
    mesh: &Mesh,
    ray: &Ray,
    (t_min, t_max): (f64, f64),
) -> Option<(usize, f32)> {
    let mut bray = Mesh::to_bvh_ray(ray, t_min, t_max);
    let mut all = None;
    let tr = mesh.traced();
    let shear = Shear::new(bray.direction);
    for (t, tri) in tr.triangles.iter().enumerate() {
        let d = shear.intersect_ray(tri, &bray);
        if d < bray.tmax && mesh.traced_stops(tr, t, &bray, d) {
            bray.tmax = d;
            all = Some((t, d));
        }
    }
    all
}

/// Checks the binned hit `binned` of ray `k` (`ray`, window `(t_min, t_max)`) against every
/// triangle (the nearest hit of the same `f32` triangle test, the first in triangle order among
/// equal distances: exactly) and against the BVH walk (the same distance, bitwise; where the
/// triangles differ, both meet the ray there). Returns whether the walk reports another
/// triangle at the same distance (a tie).
pub(crate) fn check_ray(
    mesh: &Mesh,
    ray: &Ray,
    (t_min, t_max): (f64, f64),
    binned: Option<(usize, f32)>,
    k: usize,
) -> bool {
    let all = nearest_of_all(mesh, ray, (t_min, t_max));
    assert_eq!(
        binned, all,
        "ray {k}: binned {binned:?}, nearest of all triangles {all:?}"
    );
    match (mesh.first_hit(ray, t_min, t_max), binned) {
        (None, None) => false,
        (Some((ta, da)), Some((tb, db))) if da.to_bits() == db.to_bits() => {
            if ta != tb {
                let bray = Mesh::to_bvh_ray(ray, t_min, t_max);
                for t in [ta, tb] {
                    assert_eq!(
                        Shear::new(bray.direction)
                            .intersect_ray(&mesh.traced().triangles[t], &bray)
                            .to_bits(),
                        da.to_bits(),
                        "ray {k}: triangles {ta} / {tb} do not tie"
                    );
                }
            }
            ta != tb
        }
        (a, b) => panic!("ray {k}: walked {a:?}, binned {b:?}"),
    }
}

/// Traces the whole grid of `tracer` and checks it ray by ray ([`check_ray`]): ray `(c, r)` is
/// `ray(c, r)`, traced in `window`. Returns the number of ties: rays where the walk reports
/// another triangle at the same distance.
pub(crate) fn check_traced(
    mesh: &Mesh,
    tracer: &impl BandTracer,
    ray: impl Fn(usize, usize) -> Ray,
    window: (f64, f64),
) -> usize {
    let (w, h) = tracer.size();
    let mut binned = vec![None; w * h];
    tracer.trace(0..h, &mut binned, |_, hit| hit);
    binned
        .iter()
        .enumerate()
        .filter(|&(k, b)| check_ray(mesh, &ray(k % w, k / w), window, *b, k))
        .count()
}
