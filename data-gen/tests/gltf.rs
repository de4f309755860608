//! glTF 2.0 and textured OBJ input against closed-form answers: texel colours of a textured box,
//! the holes of an alpha-masked quad, the placement map under a mirroring node and a z-up source,
//! and typed errors (never a panic) on malformed files.

use std::path::Path;

use altrep_data_gen::gltf_write::{IDENTITY, TestGltf};
use altrep_data_gen::{
    DataGenError, Mesh, MeshLoadOptions, Ray, Shape, Supersample, UpAxis, ViewParams, capture_view,
    srgb_to_linear,
};
use approx::assert_abs_diff_eq;
use glam::{DVec3, Vec3};
use proptest::prelude::*;

fn load_glb(doc: &TestGltf, options: &MeshLoadOptions) -> Result<Mesh, DataGenError> {
    Mesh::from_gltf_bytes(&doc.to_glb().unwrap(), Path::new("test.glb"), options)
}

/// The linear colour of an sRGB byte triple.
fn linear(c: [u8; 4]) -> Vec3 {
    Vec3::new(
        srgb_to_linear(f32::from(c[0]) / 255.0),
        srgb_to_linear(f32::from(c[1]) / 255.0),
        srgb_to_linear(f32::from(c[2]) / 255.0),
    )
}

/// Casts a ray at source point `p` (source coordinates) coming from `outward` (a unit source
/// direction) and returns the hit and the distance at which `p` lies along the ray.
fn hit_at_source_point(
    mesh: &Mesh,
    p: DVec3,
    outward: DVec3,
) -> (Option<altrep_data_gen::Hit>, f64) {
    let map = mesh.placement().to_normalised;
    let target = map.transform_point3(p);
    let dir = -map.transform_vector3(outward).normalize();
    let ray = Ray::new(target - 0.5 * dir, dir);
    (mesh.intersect(&ray, 0.0, 10.0), 0.5)
}

/// The centre of texel `(i, j)` of the box's `+z` face, in source coordinates. The centres with
/// `i = j` lie on the face's diagonal, the edge its two triangles share: the watertight triangle
/// test must not let those rays through.
fn plus_z_texel(i: u32, j: u32, n: u32) -> DVec3 {
    let s = (f64::from(i) + 0.5) / f64::from(n);
    let t = (f64::from(j) + 0.5) / f64::from(n);
    DVec3::new(s, 1.0 - t, 1.0)
}

#[test]
fn a_textured_box_shows_every_texel_colour_in_glb_and_in_gltf_with_external_files() {
    let n = 8;
    let doc = TestGltf::textured_box(n);
    let dir = tempfile::tempdir().unwrap();
    let gltf_path = doc.write_gltf(dir.path(), "box").unwrap();
    let from_files = Mesh::load(&gltf_path, &MeshLoadOptions::default()).unwrap();
    // The buffer and the image were read from beside the .gltf, and are listed for the cache.
    let read = file_names_read(&from_files);
    assert_eq!(read, ["box.bin", "box_0.png"]);
    let from_glb = load_glb(&doc, &MeshLoadOptions::default()).unwrap();
    for mesh in [&from_files, &from_glb] {
        assert_eq!(mesh.triangle_count(), 12);
        assert!(!mesh.is_cut_out());
        for j in 0..n {
            for i in 0..n {
                let (hit, t) = hit_at_source_point(mesh, plus_z_texel(i, j, n), DVec3::Z);
                let hit = hit.unwrap_or_else(|| panic!("texel ({i}, {j}) missed"));
                assert_abs_diff_eq!(hit.t, t, epsilon = 1e-5);
                let want = linear(TestGltf::textured_box_texel(i, j));
                assert_abs_diff_eq!(hit.albedo.x, want.x, epsilon = 1e-6);
                assert_abs_diff_eq!(hit.albedo.y, want.y, epsilon = 1e-6);
                assert_abs_diff_eq!(hit.albedo.z, want.z, epsilon = 1e-6);
            }
        }
    }
}

#[test]
fn an_alpha_mask_lets_rays_through_exactly_its_holes_in_every_tracer() {
    let n = 6;
    let mesh = load_glb(&TestGltf::masked_quad(n), &MeshLoadOptions::default()).unwrap();
    assert!(mesh.is_cut_out());
    let front = linear([230, 120, 40, 255]);
    let back = Vec3::new(0.2, 0.9, 0.2);
    let (mut holes, mut solid) = (0, 0);
    for j in 0..n {
        for i in 0..n {
            // Texel (i, j) of the quad: uv = (x, 1 − y).
            let p = DVec3::new(
                (f64::from(i) + 0.5) / f64::from(n),
                1.0 - (f64::from(j) + 0.5) / f64::from(n),
                0.0,
            );
            let (hit, t) = hit_at_source_point(&mesh, p, DVec3::Z);
            let hit = hit.expect("the back square stops every ray");
            if TestGltf::hole(i, j) {
                holes += 1;
                assert!(hit.t > t + 1e-3, "texel ({i}, {j}) is a hole");
                assert_abs_diff_eq!(hit.albedo.y, back.y, epsilon = 1e-6);
            } else {
                solid += 1;
                assert_abs_diff_eq!(hit.t, t, epsilon = 1e-5);
                assert_abs_diff_eq!(hit.albedo.x, front.x, epsilon = 1e-6);
            }
        }
    }
    assert!(holes > 0 && solid > 0);
    // The binned capture (a grid with more rays than triangles) sees the same holes as single
    // rays: its colours over the front square are the front colour where the texel is solid,
    // the back colour where it is a hole. The view at α = π/2 looks along −z.
    let grid = capture_view(
        &mesh,
        &ViewParams {
            angle: std::f64::consts::FRAC_PI_2,
            width: 96,
            height: 96,
            cylinder: Default::default(),
        },
    )
    .unwrap();
    let (mut front_px, mut back_px) = (0, 0);
    for j in 0..96 {
        for i in 0..96 {
            if let Some(s) = grid.get(i, j) {
                if (s.albedo - front).abs().max_element() < 1e-5 {
                    front_px += 1;
                } else if (s.albedo - back).abs().max_element() < 1e-5 {
                    back_px += 1;
                }
            }
        }
    }
    let (h, s) = (f64::from(holes), f64::from(solid));
    let share = f64::from(back_px) / f64::from(front_px + back_px);
    // The back square's rim shows around the front square in this view; the share of back
    // pixels is at least the hole share.
    assert!(
        share >= h / (h + s) - 0.02,
        "{back_px} back pixels of {}: holes are {h} of {}",
        front_px + back_px,
        h + s
    );
}

#[test]
fn a_mirrored_node_and_a_z_up_source_are_placed_exactly_by_the_recorded_map() {
    let n = 4;
    let mut doc = TestGltf::textured_box(n);
    // A parent translating by (5, 0, 0) over a child mirroring x and stretching z by 3.
    let mut mirror = IDENTITY;
    mirror[0] = -1.0;
    mirror[10] = 3.0;
    let mut shift = IDENTITY;
    shift[12] = 5.0;
    doc.nodes[0].matrix = mirror;
    doc.nodes.push(altrep_data_gen::gltf_write::TestNode {
        name: "parent".into(),
        mesh: None,
        matrix: shift,
        children: vec![0],
    });
    doc.roots = vec![1];
    let world = |p: DVec3| DVec3::new(5.0 - p.x, p.y, 3.0 * p.z);
    for up in [UpAxis::PosY, UpAxis::PosZ, UpAxis::NegX] {
        let options = MeshLoadOptions {
            up,
            ..MeshLoadOptions::default()
        };
        let mesh = load_glb(&doc, &options).unwrap();
        // The map takes the world box onto the mesh's bounds (to f32 rounding of the vertices).
        let map = mesh.placement().to_normalised;
        let corners: Vec<DVec3> = (0..8)
            .map(|k| {
                world(DVec3::new(
                    (k & 1) as f64,
                    (k >> 1 & 1) as f64,
                    (k >> 2 & 1) as f64,
                ))
            })
            .map(|p| map.transform_point3(p))
            .collect();
        let lo = corners.iter().fold(DVec3::INFINITY, |a, &b| a.min(b));
        let hi = corners.iter().fold(DVec3::NEG_INFINITY, |a, &b| a.max(b));
        let (blo, bhi) = mesh.bounds();
        let size = (bhi - blo).max_element();
        assert!(
            (lo - blo).abs().max_element() <= 1e-5 * size,
            "{up}: {lo} vs {blo}"
        );
        assert!(
            (hi - bhi).abs().max_element() <= 1e-5 * size,
            "{up}: {hi} vs {bhi}"
        );
        // Under z up the long (z) side stands upright.
        if up == UpAxis::PosZ {
            assert_abs_diff_eq!(bhi.y - blo.y, 2.0, epsilon = 1e-5);
        }
        // Every texel of the (mirrored) +z face is where the map puts it, with its colour.
        for j in 0..n {
            for i in 0..n {
                let (hit, t) = hit_at_source_point(&mesh, world(plus_z_texel(i, j, n)), DVec3::Z);
                let hit = hit.expect("hits");
                assert_abs_diff_eq!(hit.t, t, epsilon = 1e-5);
                let want = linear(TestGltf::textured_box_texel(i, j));
                assert_abs_diff_eq!(hit.albedo.x, want.x, epsilon = 1e-6);
            }
        }
        // The inverse map takes the normalised bounds back to the world box.
        let back = mesh
            .placement()
            .to_source()
            .transform_point3(map.transform_point3(DVec3::new(5.0, 1.0, 3.0)));
        assert_abs_diff_eq!(back.x, 5.0, epsilon = 1e-9);
        assert_abs_diff_eq!(back.z, 3.0, epsilon = 1e-9);
    }
}

/// The names of the files `mesh` read besides its own ([`Mesh::inputs`]), in order.
fn file_names_read(mesh: &Mesh) -> Vec<String> {
    mesh.inputs()
        .iter()
        .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect()
}

/// Writes the textured box's `n × n` texture ([`TestGltf::textured_box_texel`]) as a PNG.
fn save_box_texture(path: &Path, n: u32) {
    let data: Vec<u8> = (0..n)
        .flat_map(|j| (0..n).flat_map(move |i| TestGltf::textured_box_texel(i, j)))
        .collect();
    image::save_buffer(path, &data, n, n, image::ExtendedColorType::Rgba8).unwrap();
}

#[test]
fn a_textured_obj_reads_kd_times_map_kd_and_lists_the_files_it_read() {
    let dir = tempfile::tempdir().unwrap();
    let n = 4u32;
    save_box_texture(&dir.path().join("tex.png"), n);
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl t\nKd 0.5 1 1\nmap_Kd tex.png\n",
    )
    .unwrap();
    // A unit square at z = 0 with vt = (x, y): OBJ's v points up the image.
    std::fs::write(
        dir.path().join("q.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl t\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 1/1 2/2 5/1\n",
    )
    .unwrap();
    let mesh = Mesh::load(dir.path().join("q.obj"), &MeshLoadOptions::default()).unwrap();
    let read = file_names_read(&mesh);
    assert_eq!(read, ["m.mtl", "tex.png"]);
    assert!(mesh.notes().iter().any(|n| n.contains("up axis")));
    for j in 0..n {
        for i in 0..n {
            let p = DVec3::new(
                (f64::from(i) + 0.5) / f64::from(n),
                1.0 - (f64::from(j) + 0.5) / f64::from(n),
                0.0,
            );
            let (hit, _) = hit_at_source_point(&mesh, p, DVec3::Z);
            let want = linear(TestGltf::textured_box_texel(i, j));
            let got = hit.expect("hits").albedo;
            assert_abs_diff_eq!(got.x, 0.5 * want.x, epsilon = 1e-6);
            assert_abs_diff_eq!(got.y, want.y, epsilon = 1e-6);
        }
    }
    // A missing texture is an error naming it and its material.
    std::fs::remove_file(dir.path().join("tex.png")).unwrap();
    let e = Mesh::load(dir.path().join("q.obj"), &MeshLoadOptions::default()).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, DataGenError::Texture { .. }), "{text}");
    assert!(text.contains("tex.png") && text.contains("'t'"), "{text}");
}

/// OBJ/MTL emission: `Ke` on a flat material (no texture) and `Ke × map_Ke` on a textured one
/// add to the lit diffuse colour as glTF's emission does; a `Ke` out of range (negative, NaN,
/// infinite) is an error naming the material, one that is not three numbers an error on the file.
#[test]
fn an_obj_material_gives_off_ke_times_map_ke() {
    use altrep_data_gen::Light;
    let dir = tempfile::tempdir().unwrap();
    let n = 4u32;
    save_box_texture(&dir.path().join("glow.png"), n);
    // Two unit squares at z = 0: x in [0, 1] flat, x in [2, 3] textured emission.
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 3 0 0\nv 3 1 0\nv 2 1 0\n\
               vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl flat\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n\
               usemtl glow\nf 5/1 6/2 7/3\nf 5/1 7/3 8/4\n";
    std::fs::write(dir.path().join("q.obj"), obj).unwrap();
    let mtl = |ke: &str| {
        format!(
            "newmtl flat\nKd 0.2 0.4 0.6\nKe {ke}\nnewmtl glow\nKd 0.5 0.5 0.5\nKe 1 1 1\nmap_Ke glow.png\n"
        )
    };
    std::fs::write(dir.path().join("m.mtl"), mtl("0.3 0.1 0")).unwrap();
    let light = Light::default();
    let mesh = Mesh::load(dir.path().join("q.obj"), &MeshLoadOptions::default()).unwrap();
    let read = file_names_read(&mesh);
    assert_eq!(read, ["m.mtl", "glow.png"]);
    let shade = |p: DVec3| {
        let hit = hit_at_source_point(&mesh, p, DVec3::Z).0.expect("hits");
        let n = hit.normal.as_vec3();
        (light.shade(hit.albedo, n), light.factor(n))
    };
    let (got, f) = shade(DVec3::new(0.5, 0.5, 0.0));
    let want = Vec3::new(0.2, 0.4, 0.6) * f + Vec3::new(0.3, 0.1, 0.0);
    for k in 0..3 {
        assert_abs_diff_eq!(got[k], want[k], epsilon = 1e-5);
    }
    for j in 0..n {
        for i in 0..n {
            let p = DVec3::new(
                2.0 + (f64::from(i) + 0.5) / f64::from(n),
                1.0 - (f64::from(j) + 0.5) / f64::from(n),
                0.0,
            );
            let (got, f) = shade(p);
            let want = Vec3::splat(0.5) * f + linear(TestGltf::textured_box_texel(i, j));
            for k in 0..3 {
                assert_abs_diff_eq!(got[k], want[k], epsilon = 1e-5);
            }
        }
    }
    // Numbers out of range are named with their material; text that is not three numbers fails
    // the MTL parse (a typed error on the file).
    for (bad, named) in [
        ("0.3 -0.1 0", true),
        ("nan 0 0", true),
        ("inf 0 0", true),
        ("0.3 0.1", false),
        ("a b c", false),
    ] {
        // Kd as well: a short colour line is refused before the MTL parser, which panics on it.
        std::fs::write(dir.path().join("m.mtl"), mtl(bad)).unwrap();
        let e = Mesh::load(dir.path().join("q.obj"), &MeshLoadOptions::default()).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, DataGenError::ObjParse { .. }), "{bad}: {text}");
        if named {
            assert!(
                text.contains("'flat'") && text.contains("Ke"),
                "{bad}: {text}"
            );
        }
    }
    std::fs::write(dir.path().join("m.mtl"), "newmtl flat\nKd 0.2\n").unwrap();
    let e = Mesh::load(dir.path().join("q.obj"), &MeshLoadOptions::default()).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("m.mtl") && text.contains("line 2: Kd needs three numbers, found 1"),
        "{text}"
    );
}

/// Edits the JSON chunk of a `.glb` and returns the new file.
fn edit_glb(doc: &TestGltf, edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
    let glb = doc.to_glb().unwrap();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    edit(&mut json);
    let mut text = serde_json::to_vec(&json).unwrap();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let bin = &glb[20 + json_len..];
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((20 + text.len() + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(bin);
    out
}

fn error_of(bytes: &[u8]) -> String {
    match Mesh::from_gltf_bytes(bytes, Path::new("bad.glb"), &MeshLoadOptions::default()) {
        Ok(_) => "loaded".into(),
        Err(e) => e.to_string(),
    }
}

#[test]
fn malformed_gltf_is_a_typed_error_naming_the_gltf_path() {
    let doc = TestGltf::textured_box(2);
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (
            edit_glb(&doc, |j| j["meshes"][0]["primitives"][0]["mode"] = 0.into()),
            "meshes[0].primitives[0]: Points",
        ),
        (
            edit_glb(&doc, |j| j["meshes"][0]["primitives"][0]["mode"] = 1.into()),
            "meshes[0].primitives[0]: Lines",
        ),
        (
            edit_glb(&doc, |j| {
                j["extensionsRequired"] = serde_json::json!(["KHR_draco_mesh_compression"])
            }),
            "extensionsRequired[0]: required extension KHR_draco_mesh_compression",
        ),
        (
            edit_glb(&doc, |j| j["accessors"][0]["count"] = 1000.into()),
            "accessors[0]: 1000 elements do not fit",
        ),
        (
            edit_glb(&doc, |j| {
                j["materials"][0]["emissiveFactor"] = serde_json::json!([1.0, 0.5, 0.0]);
                j["materials"][0]["extensions"] = serde_json::json!({
                    "KHR_materials_emissive_strength": {"emissiveStrength": -2.0}
                });
            }),
            "materials[0]",
        ),
        (
            edit_glb(&doc, |j| j["accessors"][0]["count"] = 0.into()),
            "accessors[0]",
        ),
        (
            edit_glb(&doc, |j| j["accessors"][0]["type"] = "VEC2".into()),
            "accessors[0]: Vec2",
        ),
        (
            edit_glb(&doc, |j| j["bufferViews"][0]["byteStride"] = 4.into()),
            "bufferViews[0]",
        ),
        (
            edit_glb(&doc, |j| j["scenes"] = serde_json::json!([])),
            "scene",
        ),
        (
            edit_glb(&doc, |j| {
                j["images"][0] = serde_json::json!({"uri": "missing.png"})
            }),
            "images[0]",
        ),
        (
            edit_glb(&doc, |j| {
                j["buffers"][0]["uri"] = "https://example.com/a.bin".into()
            }),
            "buffers[0]: URI scheme 'https:'",
        ),
        (doc.to_glb().unwrap()[..40].to_vec(), "bad.glb"),
    ];
    for (bytes, want) in &cases {
        let got = error_of(bytes);
        assert!(got.contains(want), "want '{want}', got '{got}'");
    }
    // An index past the vertices names the index accessor and the index.
    let mut bad = doc.clone();
    bad.meshes[0][0].indices[5] = 9123;
    let got = error_of(&bad.to_glb().unwrap());
    assert!(
        got.contains("accessors[2]: index 9123 out of range"),
        "{got}"
    );
    // A node that is not there is named, with the names that are.
    let options = MeshLoadOptions {
        node: Some("tree".into()),
        ..MeshLoadOptions::default()
    };
    let got = load_glb(&doc, &options).unwrap_err().to_string();
    assert!(
        got.contains("no node named 'tree'") && got.contains("box"),
        "{got}"
    );
}

/// Every numeric leaf of a JSON value, by path.
fn numbers(
    v: &serde_json::Value,
    out: &mut Vec<Vec<serde_json::Value>>,
    path: &mut Vec<serde_json::Value>,
) {
    match v {
        serde_json::Value::Number(_) => out.push(path.clone()),
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                path.push(i.into());
                numbers(x, out, path);
                path.pop();
            }
        }
        serde_json::Value::Object(o) => {
            for (k, x) in o {
                path.push(k.as_str().into());
                numbers(x, out, path);
                path.pop();
            }
        }
        _ => {}
    }
}

fn at_path<'a>(
    v: &'a mut serde_json::Value,
    path: &[serde_json::Value],
) -> &'a mut serde_json::Value {
    path.iter().fold(v, |v, k| match k {
        serde_json::Value::Number(i) => &mut v[i.as_u64().unwrap() as usize],
        serde_json::Value::String(s) => &mut v[s.as_str()],
        _ => unreachable!(),
    })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 10_000,
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261205),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]
    /// Random byte edits of a valid `.glb` (its JSON and its binary chunk) load or fail with an
    /// error; a loaded mesh has finite bounds. Never a panic.
    #[test]
    fn mutated_glb_bytes_never_panic(edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6), cut in any::<prop::sample::Index>(), truncate in any::<bool>()) {
        let mut bytes = TestGltf::masked_quad(4).to_glb().unwrap();
        for (at, b) in edits {
            let i = at.index(bytes.len());
            bytes[i] = b;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len()));
        }
        if let Ok(m) = Mesh::from_gltf_bytes(&bytes, Path::new("m.glb"), &MeshLoadOptions::default()) {
            let (lo, hi) = m.bounds();
            prop_assert!(lo.is_finite() && hi.is_finite());
        }
    }

    /// Random numbers written into the numeric fields of a `.gltf` (counts, offsets, strides,
    /// indices, component types, factors, matrices) load or fail with an error, never a panic.
    #[test]
    fn mutated_gltf_numbers_never_panic(picks in proptest::collection::vec((any::<prop::sample::Index>(), prop_oneof![Just(0i64), Just(1), Just(-1), Just(2), Just(3), Just(4), Just(5), Just(7), Just(5121), Just(5123), Just(5125), Just(5126), Just(1 << 31), Just(i64::MAX), -20i64..200]), 1..4)) {
        let doc = TestGltf::masked_quad(4);
        let glb = doc.to_glb().unwrap();
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
        let mut leaves = Vec::new();
        numbers(&json, &mut leaves, &mut Vec::new());
        for (at, value) in picks {
            let path = &leaves[at.index(leaves.len())];
            *at_path(&mut json, path) = value.into();
        }
        let bytes = edit_glb(&doc, |j| *j = json);
        if let Ok(m) = Mesh::from_gltf_bytes(&bytes, Path::new("m.glb"), &MeshLoadOptions::default()) {
            let (lo, hi) = m.bounds();
            prop_assert!(lo.is_finite() && hi.is_finite());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 2_000,
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261206),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]
    /// A normal-mapped quad (with and without `TANGENT` and `NORMAL`, so the tangent reader and
    /// MikkTSpace both run) written as `.gltf` with its `.bin` and PNGs on disk: random numbers in
    /// the JSON's numeric fields and random byte edits of the `.bin` load or fail with an error,
    /// never a panic; a loaded mesh has finite bounds and finite shading normals.
    #[test]
    fn mutated_gltf_files_with_their_buffer_never_panic(
        variant in 0usize..3,
        picks in proptest::collection::vec((any::<prop::sample::Index>(), prop_oneof![Just(0i64), Just(1), Just(-1), Just(2), Just(3), Just(4), Just(5126), Just(1 << 31), -20i64..200]), 0..3),
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
    ) {
        let (normals, tangents) = [(true, true), (true, false), (false, false)][variant];
        let texels = [[204, 128, 230, 255], [128, 204, 230, 255]];
        let doc = TestGltf::normal_mapped_quad(&texels, 1.0, normals, tangents);
        let dir = tempfile::tempdir().unwrap();
        let path = doc.write_gltf(dir.path(), "q").unwrap();
        let mut json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let mut leaves = Vec::new();
        numbers(&json, &mut leaves, &mut Vec::new());
        for (at, value) in picks {
            let p = &leaves[at.index(leaves.len())];
            *at_path(&mut json, p) = value.into();
        }
        std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
        let bin = dir.path().join("q.bin");
        let mut bytes = std::fs::read(&bin).unwrap();
        for (at, b) in edits {
            let i = at.index(bytes.len());
            bytes[i] = b;
        }
        std::fs::write(&bin, bytes).unwrap();
        if let Ok(m) = Mesh::load(&path, &MeshLoadOptions::default()) {
            let (lo, hi) = m.bounds();
            prop_assert!(lo.is_finite() && hi.is_finite());
            let centre = 0.5 * (lo + hi);
            let ray = Ray::new(centre + DVec3::Z * 3.0, -DVec3::Z);
            if let Some(hit) = m.intersect(&ray, 0.0, 10.0) {
                prop_assert!(hit.normal.is_finite() && hit.albedo.is_finite());
            }
        }
    }
}

/// A square facing the view, textured with `n × n` random texels far finer than the pixels.
fn fine_quad(n: u32, seed: u64) -> TestGltf {
    let mut doc = TestGltf::masked_quad(2);
    let mut rng = altrep_data_gen::SplitMix64::new(seed);
    let data = (0..n * n)
        .flat_map(|_| {
            let mut c = || (rng.range(0.0, 255.0)) as u8;
            [c(), c(), c(), 255]
        })
        .collect();
    doc.materials[0].texture = Some(altrep_data_gen::gltf_write::Rgba8 {
        width: n,
        height: n,
        data,
    });
    doc.materials[0].alpha_mode = "OPAQUE";
    doc.materials[0].nearest = false;
    doc.meshes[0].truncate(1);
    doc
}

/// Mean squared error over the pixels both pictures cover fully, as PSNR in dB.
fn interior_psnr(a: &altrep_data_gen::RgbaImage, b: &altrep_data_gen::RgbaImage) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        if p[3] == 1.0 && q[3] == 1.0 {
            for k in 0..3 {
                sum += f64::from(p[k] - q[k]).powi(2);
            }
            n += 3;
        }
    }
    assert!(n > 0, "no pixel covered by both pictures");
    -10.0 * (sum / n as f64).log10()
}

/// A capture reads a texture over its pixel's footprint, the truth over each of its `k × k`
/// rays' smaller footprints: the two agree where a point lookup per ray aliases. A 512² random
/// texture seen at 32 × 64 pixels (16 texels per pixel across): the capture at the view's own
/// direction against the truth (k = 4) over the fully covered pixels, and the same with one
/// point lookup per ray in both (`Shape::intersect`, no footprint) — measured 2026-12-05:
/// 54.55 dB filtered, 21.65 dB point-sampled.
#[test]
fn a_capture_reads_fine_textures_over_its_pixel_as_the_truth_does() {
    use altrep_data_gen::{Light, TruthParams, render_truth, render_truth_at_points};
    let mesh = load_glb(&fine_quad(512, 3), &MeshLoadOptions::default()).unwrap();
    let angle = std::f64::consts::FRAC_PI_2;
    let (w, h, k) = (32usize, 64usize, 4usize);
    let light = Light::default();
    let capture = capture_view(
        &mesh,
        &ViewParams {
            angle,
            width: w,
            height: h,
            cylinder: Default::default(),
        },
    )
    .unwrap()
    .shade(&light);
    let params = |supersample: usize| TruthParams {
        angle,
        width: w,
        height: h,
        supersample: Supersample::of(supersample),
        light,
        cylinder: Default::default(),
    };
    let truth = render_truth(&mesh, &params(k)).unwrap();
    let filtered = interior_psnr(&capture, &truth);
    // One point lookup per ray, in the capture (one ray per pixel) and in the truth alike.
    let point = |k: usize| render_truth_at_points(&mesh, &params(k)).unwrap();
    let point_sampled = interior_psnr(&point(1), &point(k));
    eprintln!("filtered {filtered:.2} dB, point-sampled {point_sampled:.2} dB");
    assert!(filtered >= FILTERED_FLOOR_DB, "{filtered:.2} dB");
    assert!(
        filtered > point_sampled + 10.0,
        "{filtered:.2} against {point_sampled:.2} dB"
    );
}

/// The measured 54.55 dB less 0.5.
const FILTERED_FLOOR_DB: f64 = 54.05;

/// Voxels take the colour of the textured surface nearest them (not the procedural fallback):
/// a box whose every texel is one colour gives that colour to every occupied voxel.
#[test]
fn voxels_of_a_textured_mesh_take_its_texture_colour() {
    use altrep_data_gen::{VoxelParams, voxelize};
    let mut doc = TestGltf::textured_box(2);
    let texel = [200u8, 60, 30, 255];
    doc.materials[0].texture = Some(altrep_data_gen::gltf_write::Rgba8 {
        width: 2,
        height: 2,
        data: texel.repeat(4),
    });
    let mesh = load_glb(&doc, &MeshLoadOptions::default()).unwrap();
    let (lo, hi) = mesh.bounds();
    let vol = voxelize(
        &mesh,
        &VoxelParams {
            dims: [12, 12, 12],
            min: lo - 0.05,
            max: hi + 0.05,
            periodic: [false; 3],
            supersample: Supersample::of(2),
            fill: altrep_data_gen::Fill::Solid,
        },
    )
    .unwrap();
    let want = linear(texel);
    let occupied: Vec<usize> = (0..vol.density.len())
        .filter(|&i| vol.density[i] > 0.0)
        .collect();
    assert!(occupied.len() > 100);
    for i in occupied {
        let c = vol.color[i];
        assert_abs_diff_eq!(c[0], want.x, epsilon = 1e-5);
        assert_abs_diff_eq!(c[1], want.y, epsilon = 1e-5);
        assert_abs_diff_eq!(c[2], want.z, epsilon = 1e-5);
    }
}

/// The tangent-space vector a normal-map texel's code stands for, `2·code/255 − 1` per channel.
fn tangent_space(code: [u8; 4]) -> DVec3 {
    DVec3::new(
        2.0 * f64::from(code[0]) / 255.0 - 1.0,
        2.0 * f64::from(code[1]) / 255.0 - 1.0,
        2.0 * f64::from(code[2]) / 255.0 - 1.0,
    )
}

/// A normal map turns the shading normal in the surface's tangent frame, in closed form: on a
/// quad whose `+u` is `+x` and `+v` is `−y` (so `T = +x`, `B = −y`, `N = +z`), a texel tilted
/// along tangent-space `x` leans the normal toward `+x`, one tilted along `y` toward `−y`, with
/// `scale` multiplying both tilts. The same with the file's `TANGENT`, with MikkTSpace's
/// (no `TANGENT`), and with flat normals (no `NORMAL` either); under a node mirroring `x`, the
/// tilt along `x` is mirrored with the surface and MikkTSpace agrees with the carried `TANGENT`.
#[test]
fn a_normal_map_turns_the_normal_in_the_tangent_frame() {
    // Tilted along tangent-space x, then along y (codes of (±0.6, 0, 0.8) and (0, 0.6, 0.8)).
    let texels = [[204, 128, 230, 255], [128, 204, 230, 255]];
    let at = [DVec3::new(0.25, 0.5, 0.0), DVec3::new(0.75, 0.5, 0.0)];
    for scale in [1.0f32, 0.5] {
        for (normals, tangents) in [(true, true), (true, false), (false, false)] {
            for mirror in [false, true] {
                let mut doc = TestGltf::normal_mapped_quad(&texels, scale, normals, tangents);
                if mirror {
                    doc.nodes[0].matrix[0] = -1.0;
                }
                let mesh = load_glb(&doc, &MeshLoadOptions::default()).unwrap();
                for (k, code) in texels.iter().enumerate() {
                    let v = tangent_space(*code);
                    let s = f64::from(scale);
                    // World frame: T = ±x (mirrored with the node), B = −y, N = +z.
                    let t = if mirror { -DVec3::X } else { DVec3::X };
                    let want = (t * v.x * s - DVec3::Y * v.y * s + DVec3::Z * v.z).normalize();
                    let p = if mirror {
                        DVec3::new(-at[k].x, at[k].y, 0.0)
                    } else {
                        at[k]
                    };
                    let (hit, _) = hit_at_source_point(&mesh, p, DVec3::Z);
                    let got = hit.expect("the quad is hit").normal;
                    let case = format!(
                        "scale {scale}, NORMAL {normals}, TANGENT {tangents}, mirrored {mirror}, texel {k}"
                    );
                    // The loader normalises the mesh (a uniform scale and a shift), which keeps
                    // directions.
                    assert_abs_diff_eq!(got.x, want.x, epsilon = 1e-5);
                    assert_abs_diff_eq!(got.y, want.y, epsilon = 1e-5);
                    assert_abs_diff_eq!(got.z, want.z, epsilon = 1e-5);
                    assert!(got.z < 0.99, "{case}: the map changed nothing");
                }
                assert!(mesh.notes().iter().all(|n| !n.contains("normal map")));
            }
        }
    }
}

/// `doubleSided: false` (the glTF default): a ray meeting a back face passes through it, in the
/// BVH walk, the occlusion walk and the grid tracers alike; the inside test still counts both
/// faces. A closed box, single-sided, is seen from outside and invisible from inside; mirrored by
/// its node (negative determinant), its front faces still face out; double-sided, it stops rays
/// both ways.
#[test]
fn single_sided_materials_let_rays_through_their_back_faces() {
    let mut mirror = IDENTITY;
    mirror[0] = -1.0;
    for (double_sided, matrix) in [(false, IDENTITY), (false, mirror), (true, IDENTITY)] {
        let mut doc = TestGltf::textured_box(2);
        doc.materials[0].double_sided = double_sided;
        doc.nodes[0].matrix = matrix;
        let mesh = load_glb(&doc, &MeshLoadOptions::default()).unwrap();
        assert_eq!(mesh.single_sided(), !double_sided);
        let (lo, hi) = mesh.bounds();
        let centre = 0.5 * (lo + hi);
        let reach = 4.0 * (hi - lo).length();
        for axis in [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::X,
            -DVec3::Y,
            -DVec3::Z,
        ] {
            let inward = Ray::new(centre + axis * reach, -axis);
            let hit = mesh.intersect(&inward, 0.0, f64::INFINITY);
            assert!(hit.is_some(), "from outside along {axis}");
            assert!(mesh.occluded(&inward, 0.0, f64::INFINITY));
            let outward = Ray::new(centre, axis);
            let out_hit = mesh.intersect(&outward, 0.0, f64::INFINITY);
            assert_eq!(
                out_hit.is_some(),
                double_sided,
                "from inside along {axis}, double {double_sided}, mirrored {}",
                matrix[0] < 0.0
            );
            assert_eq!(mesh.occluded(&outward, 0.0, f64::INFINITY), double_sided);
        }
        assert!(mesh.contains(centre), "the inside test counts both faces");
    }
    // A lone quad facing +z, captured through the grid tracer from both sides (views about y a
    // half turn apart): single-sided, one side sees it and the other sees nothing.
    for double_sided in [false, true] {
        let mut doc = TestGltf::masked_quad(2);
        doc.meshes[0].truncate(1);
        doc.materials[0].alpha_mode = "OPAQUE";
        doc.materials[0].double_sided = double_sided;
        let mesh = load_glb(&doc, &MeshLoadOptions::default()).unwrap();
        let covered = |angle: f64| {
            let grid = capture_view(
                &mesh,
                &ViewParams {
                    angle,
                    width: 16,
                    height: 16,
                    cylinder: Default::default(),
                },
            )
            .unwrap();
            grid.samples.iter().filter(|s| s.is_some()).count()
        };
        let half_pi = std::f64::consts::FRAC_PI_2;
        let (a, b) = (covered(half_pi), covered(3.0 * half_pi));
        if double_sided {
            assert!(a > 16 && a == b, "{a} and {b}");
        } else {
            assert!(a.max(b) > 16 && a.min(b) == 0, "{a} and {b}");
        }
    }
}

/// Emission and `KHR_materials_unlit` (docs/real-assets.md, "Emission and unlit materials"): on
/// every face of the textured box, under the default light and under one from below with little
/// ambient, the hit shaded by the mesh's light shows what the material gives off — the base
/// colour for an unlit material, the lit base colour plus `emissiveFactor` (× `emissiveTexture`,
/// × `KHR_materials_emissive_strength`) for an emissive one — both as loaded and after altrep's
/// own `.glb` writer and reader.
#[test]
fn emissive_and_unlit_materials_show_what_they_give_off_under_the_light() {
    use altrep_data_gen::Light;
    let n = 4;
    let plain = TestGltf::textured_box(n);
    let variant = |f: &dyn Fn(&mut altrep_data_gen::gltf_write::TestMaterial)| {
        let mut doc = plain.clone();
        f(&mut doc.materials[0]);
        doc
    };
    let e = Vec3::new(0.25, 0.5, 0.0);
    let texture = plain.materials[0].texture.clone();
    let variants = [
        ("unlit", variant(&|m| m.unlit = true)),
        ("emissive factor", variant(&|m| m.emissive = e.to_array())),
        // Above 1: written as KHR_materials_emissive_strength 2.
        (
            "emissive strength",
            variant(&|m| m.emissive = (4.0 * e).to_array()),
        ),
        (
            "emissive texture",
            variant(&|m| {
                m.emissive = [1.0; 3];
                m.emissive_texture = texture.clone();
            }),
        ),
    ];
    let lights = [
        Light::default(),
        Light {
            direction: Vec3::new(-0.3, -0.8, -0.4).normalize(),
            ambient: 0.1,
        },
    ];
    for light in lights {
        let options = MeshLoadOptions {
            light,
            ..MeshLoadOptions::default()
        };
        let base = load_glb(&plain, &options).unwrap();
        for (what, doc) in &variants {
            let mesh = load_glb(doc, &options).unwrap();
            assert!(
                mesh.notes().iter().any(|n| n.contains("emissive or unlit")),
                "{what}: {:?}",
                mesh.notes()
            );
            // An emission above 1 goes through the strength extension, both ways.
            let written = mesh.to_glb().unwrap();
            let ext = b"KHR_materials_emissive_strength";
            let holds = |bytes: &[u8]| bytes.windows(ext.len()).any(|w| w == ext);
            let strong = *what == "emissive strength";
            assert_eq!(holds(&doc.to_glb().unwrap()), strong, "{what}");
            assert_eq!(holds(&written), strong, "{what}");
            let back = Mesh::from_gltf_bytes(
                &written,
                Path::new("back.glb"),
                &MeshLoadOptions {
                    frame: Some(mesh.placement().of_written()),
                    light,
                    ..MeshLoadOptions::default()
                },
            )
            .unwrap();
            let mut checked = 0;
            for axis in 0..3 {
                for sign in [-1.0, 1.0] {
                    let mut outward = DVec3::ZERO;
                    outward[axis] = sign;
                    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                    for j in 0..n {
                        for i in 0..n {
                            let mut p = DVec3::splat(0.5) + 0.5 * outward;
                            p[a] = (f64::from(i) + 0.5) / f64::from(n);
                            p[b] = (f64::from(j) + 0.5) / f64::from(n);
                            let lit = hit_at_source_point(&base, p, outward).0.unwrap();
                            let l = light.factor(lit.normal.as_vec3());
                            let want = match *what {
                                "unlit" => lit.albedo,
                                "emissive factor" => lit.albedo * l + e,
                                "emissive strength" => lit.albedo * l + 4.0 * e,
                                _ => lit.albedo * l + lit.albedo,
                            };
                            for m in [&mesh, &back] {
                                let hit = hit_at_source_point(m, p, outward).0.unwrap();
                                let got = light.shade(hit.albedo, hit.normal.as_vec3());
                                for k in 0..3 {
                                    assert_abs_diff_eq!(got[k], want[k], epsilon = 1e-5);
                                }
                                checked += 1;
                            }
                        }
                    }
                }
            }
            assert_eq!(checked, 2 * 6 * n * n, "{what}");
        }
    }
}
