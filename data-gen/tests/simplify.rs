//! Meshes written to `.glb` ([`Mesh::to_glb`]) and read back where they were, and meshes
//! simplified by meshoptimizer ([`Mesh::simplified`]) keeping their materials and placement:
//! checked against the source mesh's own ray-cast pictures.

use std::path::Path;

use altrep_data_gen::gltf_write::TestGltf;
use altrep_data_gen::{
    Mesh, MeshLoadOptions, RgbaImage, Shape, SimplifyParams, Supersample, TruthParams, render_truth,
};
use approx::assert_abs_diff_eq;

fn load_glb(bytes: &[u8], options: &MeshLoadOptions) -> Mesh {
    Mesh::from_gltf_bytes(bytes, Path::new("test.glb"), options).unwrap()
}

/// The truth of `shape` at `angle`, `size²` pixels, 2 × 2 rays per pixel.
fn picture(shape: &dyn Shape, angle: f64, size: usize) -> RgbaImage {
    render_truth(shape, &TruthParams::square(angle, size, Supersample::of(2))).unwrap()
}

/// Mean squared difference over every channel of two pictures of the same size.
fn mse(a: &RgbaImage, b: &RgbaImage) -> f64 {
    let n = a.pixels.len() as f64 * 4.0;
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..4).map(move |c| f64::from(p[c] - q[c]).powi(2)))
        .sum::<f64>()
        / n
}

/// The sorted bit patterns of a mesh's triangle corners (the file groups triangles by material,
/// so the order changes; the set must not).
fn corner_bits(mesh: &Mesh) -> Vec<[u32; 3]> {
    let mut v: Vec<[u32; 3]> = mesh
        .triangles_f32()
        .iter()
        .flatten()
        .map(|p| p.map(f32::to_bits))
        .collect();
    v.sort_unstable();
    v
}

/// The written file, read with the placement it was written with, gives back every vertex bit
/// for bit and the same pictures (to float rounding of the shading normals): for textured,
/// alpha-masked, normal-mapped, z-up and procedurally coloured meshes. The root node holds the
/// placement's inverse, so a plain read (normalising anew) puts the file's source-frame
/// vertices where the source's were.
#[test]
fn a_mesh_written_to_glb_reads_back_where_it_was() {
    let z_up = MeshLoadOptions {
        up: altrep_data_gen::UpAxis::PosZ,
        ..MeshLoadOptions::default()
    };
    let cases: Vec<(&str, Mesh)> = vec![
        (
            "textured box",
            load_glb(&TestGltf::textured_box(8).to_glb().unwrap(), &z_up),
        ),
        (
            "leaf shrub",
            load_glb(
                &TestGltf::leaf_shrub(40, 3).to_glb().unwrap(),
                &MeshLoadOptions::default(),
            ),
        ),
        (
            "normal-mapped quad",
            load_glb(
                &TestGltf::normal_mapped_quad(
                    &[[200, 128, 230, 255], [60, 128, 230, 255]],
                    1.0,
                    true,
                    false,
                )
                .to_glb()
                .unwrap(),
                &MeshLoadOptions::default(),
            ),
        ),
        (
            "rock (normals, single-sided)",
            load_glb(
                &TestGltf::textured_rock(2, 5).to_glb().unwrap(),
                &MeshLoadOptions::default(),
            ),
        ),
        (
            "procedural",
            Mesh::from_raw_triangles(
                "tetra",
                vec![
                    [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                    [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]],
                    [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                    [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
                ],
                &MeshLoadOptions::default(),
            )
            .unwrap(),
        ),
    ];
    for (what, mesh) in cases {
        let bytes = mesh.to_glb().unwrap();
        let back = load_glb(
            &bytes,
            &MeshLoadOptions {
                frame: Some(mesh.placement().of_written()),
                ..MeshLoadOptions::default()
            },
        );
        assert_eq!(corner_bits(&back), corner_bits(&mesh), "{what}: vertices");
        assert_eq!(back.is_cut_out(), mesh.is_cut_out(), "{what}");
        assert_eq!(back.single_sided(), mesh.single_sided(), "{what}");
        for angle in [0.4, 2.1, 4.0] {
            let (a, b) = (picture(&mesh, angle, 48), picture(&back, angle, 48));
            assert!(a.pixels.iter().any(|p| p[3] > 0.0), "{what}: empty picture");
            for (p, q) in a.pixels.iter().zip(&b.pixels) {
                for c in 0..4 {
                    assert_abs_diff_eq!(p[c], q[c], epsilon = 1e-4);
                }
            }
        }
        // Read as any file (normalised anew), it lands where the source was: the same
        // normalised frame, to float rounding.
        let plain = load_glb(&bytes, &MeshLoadOptions::default());
        let (lo, hi) = (plain.bounds(), mesh.bounds());
        assert_abs_diff_eq!(lo.0.distance(hi.0), 0.0, epsilon = 1e-5);
        assert_abs_diff_eq!(lo.1.distance(hi.1), 0.0, epsilon = 1e-5);
    }
}

/// Simplification keeps the placement and the materials, meets its triangle target, keeps
/// its vertices a subset of the input's, and its pictures approach the source's as the target
/// rises (the error is measured, not assumed).
#[test]
fn simplified_meshes_keep_their_materials_and_approach_the_source() {
    let mesh = load_glb(
        &TestGltf::leaf_shrub(300, 7).to_glb().unwrap(),
        &MeshLoadOptions::default(),
    );
    let n = mesh.triangle_count();
    let source: std::collections::HashSet<[u32; 3]> = corner_bits(&mesh).into_iter().collect();
    let truth: Vec<RgbaImage> = [0.3, 1.9, 3.6]
        .iter()
        .map(|a| picture(&mesh, *a, 64))
        .collect();
    let mut last = f64::INFINITY;
    for ratio in [0.1, 0.3, 0.6] {
        let target = (n as f64 * ratio) as usize;
        let s = mesh
            .simplified(&SimplifyParams {
                target_triangles: target,
                ..SimplifyParams::default()
            })
            .unwrap();
        assert!(s.mesh.triangle_count() <= target, "{ratio}");
        assert_eq!(s.mesh.placement(), mesh.placement());
        assert_eq!(s.mesh.materials(), mesh.materials());
        assert!(s.mesh.is_cut_out());
        assert!(corner_bits(&s.mesh).iter().all(|c| source.contains(c)));
        let err: f64 = [0.3, 1.9, 3.6]
            .iter()
            .zip(&truth)
            .map(|(a, t)| mse(&picture(&s.mesh, *a, 64), t))
            .sum();
        println!(
            "ratio {ratio}: {} triangles, error {:.4}, picture MSE {err:.5}",
            s.mesh.triangle_count(),
            s.error
        );
        assert!(err < last, "ratio {ratio}: {err} after {last}");
        last = err;
    }
}

#[test]
fn simplification_refuses_impossible_parameters() {
    let mesh = load_glb(
        &TestGltf::textured_box(4).to_glb().unwrap(),
        &MeshLoadOptions::default(),
    );
    for p in [
        SimplifyParams {
            target_triangles: 0,
            ..SimplifyParams::default()
        },
        SimplifyParams {
            target_triangles: 4,
            max_error: f64::NAN,
            ..SimplifyParams::default()
        },
        SimplifyParams {
            target_triangles: 4,
            attribute_weight: -1.0,
            ..SimplifyParams::default()
        },
    ] {
        let e = mesh.simplified(&p).err().expect("refused");
        assert!(matches!(
            e,
            altrep_data_gen::DataGenError::InvalidParameter { .. }
        ));
    }
}

/// The rock of the bundled scene is closed, wound counter-clockwise from outside (every face's
/// winding normal points away from the axis through its centre) and textured.
#[test]
fn the_textured_rock_is_closed_and_wound_outward() {
    let doc = TestGltf::textured_rock(3, 11);
    let mesh = load_glb(&doc.to_glb().unwrap(), &MeshLoadOptions::default());
    assert_eq!(mesh.triangle_count(), 20 * 4usize.pow(3));
    assert!(mesh.encloses_volume());
    assert!(mesh.single_sided());
    let (lo, hi) = mesh.bounds();
    let centre = 0.5 * (lo + hi);
    for t in mesh.triangles_f32() {
        let p = t.map(|v| glam::DVec3::from(v.map(f64::from)));
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let c = (p[0] + p[1] + p[2]) / 3.0 - centre;
        assert!(n.dot(c) > 0.0, "a face wound inward at {c}");
    }
    // Seen from outside, the single-sided surface shows: a picture is not empty.
    let img = picture(&mesh, 0.7, 32);
    assert!(img.pixels.iter().filter(|p| p[3] > 0.5).count() > 200);
}

use altrep_data_gen::gltf_write::TestPrimitive;
use proptest::prelude::*;

/// A random glTF soup: `n` triangles with corners in `[−1, 1]³` drawn from `coords` (so corners
/// repeat, slivers and degenerate triangles occur), random texture coordinates, in the masked
/// quad's alpha-cut material or in a plain one.
fn soup(coords: &[[f32; 3]], picks: &[usize], uvs: &[[f32; 2]], masked: bool) -> Option<Mesh> {
    let mut doc = TestGltf::masked_quad(8);
    if !masked {
        doc.materials[0] = altrep_data_gen::gltf_write::TestMaterial::plain([0.5, 0.6, 0.7, 1.0]);
    }
    let n = picks.len() / 3 * 3;
    doc.meshes = vec![vec![TestPrimitive {
        positions: picks[..n]
            .iter()
            .map(|&i| coords[i % coords.len()])
            .collect(),
        uvs: (0..n).map(|k| uvs[k % uvs.len()]).collect(),
        indices: (0..n as u32).collect(),
        ..TestPrimitive::empty(0)
    }]];
    Mesh::from_gltf_bytes(
        &doc.to_glb().ok()?,
        Path::new("soup.glb"),
        &MeshLoadOptions::default(),
    )
    .ok()
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 300,
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261207),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]
    /// Random soups (repeated corners, slivers, degenerate and duplicate triangles, cut-out or
    /// plain) simplified at any target, border lock and weight: a mesh or a typed error, never
    /// a panic; no more triangles than the source, every corner one of the source's, the
    /// placement kept; and the simplified mesh written to `.glb` reads back bit for bit.
    #[test]
    fn random_soups_simplify_and_write_without_panic(
        coords in proptest::collection::vec(proptest::array::uniform3(-1.0f32..1.0), 3..40),
        picks in proptest::collection::vec(0usize..64, 3..300),
        uvs in proptest::collection::vec(proptest::array::uniform2(-2.0f32..2.0), 1..20),
        masked in any::<bool>(),
        target in 1usize..120,
        lock_border in any::<bool>(),
        weight in prop_oneof![Just(0.0f32), 0.0f32..4.0],
        bound in prop_oneof![Just(f64::INFINITY), 0.0f64..0.5],
    ) {
        let Some(mesh) = soup(&coords, &picks, &uvs, masked) else { return Ok(()) };
        let source: std::collections::HashSet<[u32; 3]> = corner_bits(&mesh).into_iter().collect();
        let params = SimplifyParams { target_triangles: target, max_error: bound, lock_border, attribute_weight: weight };
        match mesh.simplified(&params) {
            Err(altrep_data_gen::DataGenError::EmptyMesh { .. }) => {}
            Err(e) => prop_assert!(false, "unexpected error {e}"),
            Ok(s) => {
                prop_assert!(s.mesh.triangle_count() <= mesh.triangle_count());
                prop_assert!(s.error.is_finite() && s.error >= 0.0);
                prop_assert!(corner_bits(&s.mesh).iter().all(|c| source.contains(c)));
                prop_assert_eq!(s.mesh.placement(), mesh.placement());
                let back = Mesh::from_gltf_bytes(
                    &s.mesh.to_glb().unwrap(),
                    Path::new("level.glb"),
                    &MeshLoadOptions { frame: Some(s.mesh.placement().of_written()), ..MeshLoadOptions::default() },
                ).unwrap();
                prop_assert_eq!(corner_bits(&back), corner_bits(&s.mesh));
                prop_assert_eq!(back.is_cut_out(), s.mesh.is_cut_out());
            }
        }
    }
}

/// Two simplified levels written with their images beside them share one PNG per texture, and
/// read back from that folder bit for bit with the same pictures as the levels in memory.
#[test]
fn levels_written_beside_their_shared_textures_read_back_from_the_folder() {
    let mesh = load_glb(
        &TestGltf::textured_rock(3, 2).to_glb().unwrap(),
        &MeshLoadOptions::default(),
    );
    let dir = tempfile::tempdir().unwrap();
    let mut images = altrep_data_gen::ExternalImages::default();
    let levels: Vec<Mesh> = [400, 100]
        .iter()
        .map(|&n| {
            mesh.simplified(&SimplifyParams {
                target_triangles: n,
                ..SimplifyParams::default()
            })
            .unwrap()
            .mesh
        })
        .collect();
    for (k, level) in levels.iter().enumerate() {
        let file = level.to_glb_beside(&mut images).unwrap();
        assert_eq!(file.image_bytes, 0);
        std::fs::write(dir.path().join(format!("level{k}.glb")), file.bytes).unwrap();
    }
    assert_eq!(images.files.len(), 1, "one texture, shared");
    for f in &images.files {
        std::fs::write(dir.path().join(&f.name), &f.bytes).unwrap();
    }
    for (k, level) in levels.iter().enumerate() {
        let back = Mesh::load(
            dir.path().join(format!("level{k}.glb")),
            &MeshLoadOptions {
                frame: Some(level.placement().of_written()),
                ..MeshLoadOptions::default()
            },
        )
        .unwrap();
        assert_eq!(corner_bits(&back), corner_bits(level));
        assert_eq!(
            back.inputs().len(),
            1,
            "the texture read from beside the file"
        );
        let (a, b) = (picture(level, 1.3, 40), picture(&back, 1.3, 40));
        for (p, q) in a.pixels.iter().zip(&b.pixels) {
            for c in 0..4 {
                assert_abs_diff_eq!(p[c], q[c], epsilon = 1e-4);
            }
        }
    }
}

/// Textures reduced for a mesh drawn small: every image larger than the bound is replaced by
/// the first level of its mip chain that fits, shared images stay shared, and a bound the
/// images already fit changes nothing.
#[test]
fn textures_are_reduced_to_the_first_mip_level_that_fits() {
    let mesh = load_glb(
        &TestGltf::textured_rock(2, 3).to_glb().unwrap(),
        &MeshLoadOptions::default(),
    );
    let side = |m: &Mesh| {
        let t = &m.materials()[0].base_texture.as_ref().unwrap().0.image;
        (t.width(), t.height())
    };
    assert_eq!(side(&mesh), (64, 64));
    let (small, largest) = mesh.with_textures_at_most(20).unwrap();
    assert_eq!(largest, Some(16));
    assert_eq!(side(&small), (16, 16));
    assert_eq!(small.triangle_count(), mesh.triangle_count());
    // Level 2 of the chain: each texel the mean of a 4 × 4 block of the source's, snapped to
    // the 8-bit sRGB code a file holds (within half a code).
    let (src, red) = (
        &mesh.materials()[0].base_texture.as_ref().unwrap().0.image,
        &small.materials()[0].base_texture.as_ref().unwrap().0.image,
    );
    let mut mean = glam::Vec4::ZERO;
    for j in 0..4 {
        for i in 0..4 {
            mean += src.texel(4 + i, 8 + j) / 16.0;
        }
    }
    assert_abs_diff_eq!(red.texel(1, 2).x, mean.x, epsilon = 2.5e-3);
    assert!(
        red.encoded().is_none(),
        "a reduced image is no longer the source's file"
    );
    // Written and read back: the snapped texels go into an 8-bit PNG and come back exactly.
    let back = load_glb(&small.to_glb().unwrap(), &MeshLoadOptions::default());
    let tb = &back.materials()[0].base_texture.as_ref().unwrap().0.image;
    assert_eq!((tb.width(), tb.height()), (16, 16));
    let mut worst: f32 = 0.0;
    for j in 0..16 {
        for i in 0..16 {
            worst = worst.max((red.texel(i, j) - tb.texel(i, j)).abs().max_element());
        }
    }
    assert_eq!(worst, 0.0, "texels differ by up to {worst}");
    let (same, largest) = mesh.with_textures_at_most(64).unwrap();
    assert_eq!(largest, Some(64));
    assert!(std::sync::Arc::ptr_eq(
        &same.materials()[0].base_texture.as_ref().unwrap().0.image,
        &mesh.materials()[0].base_texture.as_ref().unwrap().0.image
    ));
}
