//! OBJ meshes: loading, normalisation into the cylinder, ray casting, bad input.

use std::io::Write;

use altrep_data_gen::{
    BoundingCylinder, DataGenError, Mesh, MeshLoadOptions, Ray, Shape, ViewParams, capture_view,
    shared_mesh,
};
use approx::assert_abs_diff_eq;
use glam::DVec3;

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.path().join(name);
    std::fs::File::create(&path)
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    path
}

/// A 4 × 6 × 2 box (x × y × z) centred at (10, 3, −5): after normalisation into R = 1, H = 2 the
/// scale is min(1/√(2²+1²), 2/6) = 1/3, so it spans x ∈ [−2/3, 2/3], y ∈ [0, 2], z ∈ [−1/3, 1/3].
const BOX_OBJ: &str = "\
# a box
v 8 0 -6\nv 12 0 -6\nv 12 6 -6\nv 8 6 -6\nv 8 0 -4\nv 12 0 -4\nv 12 6 -4\nv 8 6 -4
f 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 2 6 7 3\nf 3 7 8 4\nf 4 8 5 1
";

/// A ray along −x at height 1, meeting [`BOX_OBJ`]'s face x = 2/3 (after normalisation).
fn front_ray() -> Ray {
    Ray::new(DVec3::new(3.0, 1.0, 0.1), DVec3::new(-1.0, 0.0, 0.0))
}

#[test]
fn small_box_mesh_is_normalised_and_ray_cast() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, "box.obj", BOX_OBJ);
    let mesh = Mesh::load_obj(&path, &MeshLoadOptions::default()).unwrap();
    assert_eq!(mesh.triangle_count(), 12);
    let (lo, hi) = mesh.bounds();
    let tol = 1e-5;
    assert!(
        (lo - DVec3::new(-2.0 / 3.0, 0.0, -1.0 / 3.0))
            .abs()
            .max_element()
            < tol,
        "{lo:?}"
    );
    assert!(
        (hi - DVec3::new(2.0 / 3.0, 2.0, 1.0 / 3.0))
            .abs()
            .max_element()
            < tol,
        "{hi:?}"
    );
    // A ray along −x at height 1 hits the face x = 2/3 with normal +x.
    let hit = mesh.intersect(&front_ray(), 0.0, 10.0).unwrap();
    assert!((hit.t - (3.0 - 2.0 / 3.0)).abs() < tol, "t = {}", hit.t);
    assert!((hit.normal - DVec3::X).length() < 1e-5);
    // Inside test by parity.
    assert!(mesh.contains(DVec3::new(0.0, 1.0, 0.0)));
    assert!(!mesh.contains(DVec3::new(0.9, 1.0, 0.0)));
    // A view along −x: depth 2/3 where covered, coverage = (2/3 wide of 2) × (full height).
    let view = capture_view(
        &mesh,
        &ViewParams {
            angle: 0.0,
            width: 60,
            height: 30,
            cylinder: BoundingCylinder::default(),
        },
    )
    .unwrap();
    let cov = view.coverage();
    assert!((cov - 1.0 / 3.0).abs() < 0.02, "coverage {cov}");
    assert!(
        view.samples
            .iter()
            .flatten()
            .all(|s| (f64::from(s.depth) - 2.0 / 3.0).abs() < tol)
    );
}

/// OBJ coordinates are read in f64: [`BOX_OBJ`] shrunk 100 times and moved a million units
/// away (where f32 steps by 0.0625, more than the box) keeps its shape, and its placement maps
/// back to where it was.
#[test]
fn a_box_far_from_the_origin_keeps_its_shape() {
    let far = |v: f64| 1.0e6 + 0.01 * v;
    let mut text = String::new();
    for line in BOX_OBJ.lines() {
        match line.strip_prefix("v ") {
            Some(v) => {
                let c: Vec<f64> = v.split(' ').map(|x| far(x.parse().unwrap())).collect();
                text += &format!("v {} {} {}\n", c[0], c[1], c[2]);
            }
            None => text += &format!("{line}\n"),
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let mesh = Mesh::load_obj(write(&dir, "far.obj", &text), &MeshLoadOptions::default()).unwrap();
    let near =
        Mesh::load_obj(write(&dir, "box.obj", BOX_OBJ), &MeshLoadOptions::default()).unwrap();
    assert_eq!(mesh.triangle_count(), 12);
    let ((lo, hi), (lo0, hi0)) = (mesh.bounds(), near.bounds());
    assert_abs_diff_eq!(lo.to_array()[..], lo0.to_array()[..], epsilon = 1e-6);
    assert_abs_diff_eq!(hi.to_array()[..], hi0.to_array()[..], epsilon = 1e-6);
    // The normalised frame's origin (the base's centre) is the source's (10, 0, −5), moved.
    let origin = mesh.placement().to_source().transform_point3(DVec3::ZERO);
    let expected = [far(10.0), far(0.0), far(-5.0)];
    assert_abs_diff_eq!(origin.to_array()[..], expected[..], epsilon = 1e-6);
}

/// Materials are read from the file beside the OBJ (as `tobj::load_obj` reads them), whether
/// the mesh is loaded from its path or from bytes already read; the BVH is built on the first
/// ray query, and the inside test needs none.
#[test]
fn materials_beside_the_file_colour_the_hits_and_the_bvh_waits_for_a_ray() {
    let dir = tempfile::tempdir().unwrap();
    write(&dir, "box.mtl", "newmtl red\nKd 0.8 0.1 0.25\n");
    let text = format!("mtllib box.mtl\nusemtl red\n{BOX_OBJ}");
    let path = write(&dir, "box.obj", &text);
    let from_path = Mesh::load_obj(&path, &MeshLoadOptions::default()).unwrap();
    let from_bytes =
        Mesh::from_obj_bytes(text.as_bytes(), &path, &MeshLoadOptions::default()).unwrap();
    for mesh in [&from_path, &from_bytes] {
        let mut inside = [false; 3];
        mesh.contains_row(1.0, 0.0, &[-0.9, 0.0, 0.9], &mut inside);
        assert_eq!(inside, [false, true, false]);
        assert!(mesh.bvh_build_time().is_none());
        let hit = mesh.intersect(&front_ray(), 0.0, 10.0).unwrap();
        for (got, want) in hit.albedo.to_array().into_iter().zip([0.8, 0.1, 0.25]) {
            approx::assert_abs_diff_eq!(got, want, epsilon = 1e-6);
        }
        assert!(mesh.bvh_build_time().is_some());
    }
    // Without its material file the mesh loads (fallback colours), from the path as from bytes.
    let elsewhere = tempfile::tempdir().unwrap();
    let moved = write(&elsewhere, "box.obj", &text);
    let a = Mesh::load_obj(&moved, &MeshLoadOptions::default()).unwrap();
    let b = Mesh::from_obj_bytes(text.as_bytes(), &moved, &MeshLoadOptions::default()).unwrap();
    let albedo = |m: &Mesh| m.intersect(&front_ray(), 0.0, 10.0).map(|h| h.albedo);
    assert_eq!(albedo(&a), albedo(&b));
    assert!(albedo(&a).is_some());
    assert_ne!(albedo(&a), albedo(&from_path));
}

#[test]
fn teapot_loads_when_shared_meshes_exist() {
    let Some(mesh) = shared_mesh("teapot", "teapot_loads_when_shared_meshes_exist") else {
        return;
    };
    assert!(
        mesh.triangle_count() > 1000,
        "{} triangles",
        mesh.triangle_count()
    );
    let (lo, hi) = mesh.bounds();
    assert!(lo.y > -1e-5 && hi.y < 2.0 + 1e-5);
    let r = lo.x.abs().max(hi.x.abs()).max(lo.z.abs()).max(hi.z.abs());
    assert!(r <= 1.0 + 1e-5);
    let view = capture_view(
        &mesh,
        &ViewParams {
            angle: 0.3,
            width: 32,
            height: 32,
            cylinder: BoundingCylinder::default(),
        },
    )
    .unwrap();
    assert!(view.coverage() > 0.2, "coverage {}", view.coverage());
}

#[test]
fn bad_mesh_input_gives_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let opts = MeshLoadOptions::default();
    // Missing file.
    let e = Mesh::load_obj(dir.path().join("missing.obj"), &opts).unwrap_err();
    assert!(matches!(e, DataGenError::Io { .. }), "{e}");
    assert!(e.to_string().contains("missing.obj"));
    // Text that is not OBJ: no geometry at all.
    let p = write(
        &dir,
        "prose.obj",
        "This is a letter, not a mesh.\nRegards.\n",
    );
    let e = Mesh::load_obj(&p, &opts).unwrap_err();
    assert!(
        matches!(
            e,
            DataGenError::EmptyMesh { .. } | DataGenError::ObjParse { .. }
        ),
        "{e}"
    );
    // Binary garbage.
    let p = dir.path().join("binary.obj");
    std::fs::write(&p, [0xffu8, 0xfe, 0x00, 0x81, 0x92]).unwrap();
    let e = Mesh::load_obj(&p, &opts).unwrap_err();
    assert!(matches!(e, DataGenError::ObjParse { .. }), "{e}");
    // NaN coordinates.
    let p = write(&dir, "nan.obj", "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nf 1 2 3\n");
    let e = Mesh::load_obj(&p, &opts).unwrap_err();
    assert!(
        matches!(
            e,
            DataGenError::NonFinite { .. } | DataGenError::ObjParse { .. }
        ),
        "{e}"
    );
    // Vertices but no faces.
    let p = write(&dir, "empty.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    let e = Mesh::load_obj(&p, &opts).unwrap_err();
    assert!(matches!(e, DataGenError::EmptyMesh { .. }), "{e}");
    // Only degenerate faces.
    let p = write(&dir, "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
    let e = Mesh::load_obj(&p, &opts).unwrap_err();
    assert!(matches!(e, DataGenError::EmptyMesh { .. }), "{e}");
    // A face referring to a vertex that does not exist.
    let p = write(&dir, "dangling.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    assert!(Mesh::load_obj(&p, &opts).is_err());
    // Raw triangles with infinity.
    let e = Mesh::from_raw_triangles(
        "inf",
        vec![[[0.0; 3], [1.0, 0.0, 0.0], [0.0, f64::INFINITY, 0.0]]],
        &opts,
    )
    .unwrap_err();
    assert!(matches!(e, DataGenError::NonFinite { .. }), "{e}");
}
