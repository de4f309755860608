//! Shell voxelisation against closed-form answers: an alpha-masked card covers, per voxel and
//! axis, exactly the share of the voxel's rays that land on its opaque texels, with the texels'
//! colour; the card's own plane is clear; the solid fill misses it; `Fill::Auto` picks the shell
//! for cut-out and open meshes and the solid fill (bit for bit) for a closed one.

use std::path::Path;

use altrep_data_gen::gltf_write::TestGltf;
use altrep_data_gen::{
    Fill, Mesh, MeshLoadOptions, Shape, Supersample, Volume, VoxelParams, srgb_to_linear, voxelize,
};
use approx::assert_abs_diff_eq;
use glam::DVec3;
use proptest::prelude::*;

fn load_glb(doc: &TestGltf) -> Mesh {
    Mesh::from_gltf_bytes(
        &doc.to_glb().unwrap(),
        Path::new("test.glb"),
        &MeshLoadOptions::default(),
    )
    .unwrap()
}

/// Texels per side of the card's mask.
const TEXELS: u32 = 6;
/// Voxels per side of the card (each texel edge falls between sub-rays: see the test).
const VOXELS: usize = 12;
/// Rays per voxel edge.
const RAYS: usize = 4;

/// The masked card of [`TestGltf::masked_quad`] alone (its opaque backing removed).
fn card() -> Mesh {
    let mut doc = TestGltf::masked_quad(TEXELS);
    doc.meshes[0].truncate(1);
    load_glb(&doc)
}

/// One layer of voxels over the card, the card's plane through the middle of the layer.
fn card_params(mesh: &Mesh, fill: Fill) -> VoxelParams {
    let (lo, hi) = mesh.bounds();
    let h = (hi.x - lo.x) / VOXELS as f64;
    VoxelParams {
        dims: [VOXELS, VOXELS, 1],
        min: DVec3::new(lo.x, lo.y, lo.z - 0.5 * h),
        max: DVec3::new(hi.x, hi.y, lo.z + 0.5 * h),
        periodic: [false; 3],
        supersample: Supersample::of(RAYS),
        fill,
    }
}

/// The share of voxel `(i, j)`'s rays along `z` that land on an opaque texel, from the mask's
/// definition: ray `(a, b)` crosses the layer at `min + (i + (a + ½)/s, j + (b + ½)/s)·h`, which
/// the recorded placement maps back to the source square, `uv = (x, 1 − y)`.
fn expected_cover(mesh: &Mesh, v: &Volume, i: usize, j: usize) -> f64 {
    let to_source = mesh.placement().to_source();
    let mut opaque = 0;
    for a in 0..RAYS {
        for b in 0..RAYS {
            let p = v.min
                + DVec3::new(
                    (i as f64 + (a as f64 + 0.5) / RAYS as f64) * v.voxel_size.x,
                    (j as f64 + (b as f64 + 0.5) / RAYS as f64) * v.voxel_size.y,
                    0.5 * v.voxel_size.z,
                );
            let s = to_source.transform_point3(p);
            let (u, w) = (s.x, 1.0 - s.y);
            let texel = |t: f64| ((t * TEXELS as f64).floor() as u32).min(TEXELS - 1);
            opaque += usize::from(!TestGltf::hole(texel(u), texel(w)));
        }
    }
    opaque as f64 / (RAYS * RAYS) as f64
}

#[test]
fn a_shell_covers_a_masked_card_exactly_where_its_rays_meet_opaque_texels() {
    let mesh = card();
    assert!(!mesh.encloses_volume(), "a cut-out card encloses nothing");
    let v = voxelize(&mesh, &card_params(&mesh, Fill::Auto)).unwrap();
    assert_eq!(
        v.fill,
        Fill::Shell,
        "Auto takes the shell for a cut-out card"
    );
    let axis = v.axis_coverage.as_ref().expect("a shell records its axes");
    // Rays along z: the exact share; along x and y (in the card's plane, never on it): none.
    // Sub-rays sit at odd multiples of 1/96 of the card and texel edges at multiples of 16/96,
    // so no ray lands on an edge.
    let colour = [230.0f32, 120.0, 40.0].map(|c| srgb_to_linear(c / 255.0));
    let mut covered = 0;
    for j in 0..VOXELS {
        for i in 0..VOXELS {
            let k = v.index(i, j, 0);
            let want = expected_cover(&mesh, &v, i, j);
            assert_abs_diff_eq!(f64::from(axis[k][2]), want, epsilon = 1e-6);
            assert_eq!(axis[k][0], 0.0);
            assert_eq!(axis[k][1], 0.0);
            assert_abs_diff_eq!(f64::from(v.density[k]), want / 3.0, epsilon = 1e-6);
            if want > 0.0 {
                covered += 1;
                for (got, want) in v.color[k].iter().zip(colour) {
                    assert_abs_diff_eq!(*got, want, epsilon = 1e-5);
                }
                let n = v.normal[k].expect("a covered voxel has a normal");
                assert_abs_diff_eq!(n.z.abs(), 1.0, epsilon = 1e-6);
            } else {
                assert!(v.normal[k].is_none());
            }
        }
    }
    // Two texels in three are opaque: most voxels are covered, and some are not.
    assert!((VOXELS * VOXELS / 2..VOXELS * VOXELS).contains(&covered));

    // The solid fill sees no inside in a card: nearly nothing.
    let solid = voxelize(&mesh, &card_params(&mesh, Fill::Solid)).unwrap();
    let solid_total: f32 = solid.density.iter().sum();
    let shell_total: f32 = v.density.iter().sum();
    assert!(
        solid_total < 0.05 * shell_total,
        "solid {solid_total} against shell {shell_total}"
    );
}

#[test]
fn auto_keeps_the_solid_fill_for_a_closed_mesh_and_takes_the_shell_for_open_ones() {
    let closed = load_glb(&TestGltf::textured_box(2));
    assert!(closed.encloses_volume());
    let (lo, hi) = closed.bounds();
    let params = |fill| VoxelParams {
        dims: [10, 10, 10],
        min: lo - 0.05,
        max: hi + 0.05,
        periodic: [false; 3],
        supersample: Supersample::of(2),
        fill,
    };
    let auto = voxelize(&closed, &params(Fill::Auto)).unwrap();
    let solid = voxelize(&closed, &params(Fill::Solid)).unwrap();
    assert_eq!(
        auto, solid,
        "Auto on a closed mesh is the solid fill, bit for bit"
    );
    assert!(auto.axis_coverage.is_none());

    // The shrub: cut-out leaves and an open trunk.
    let shrub = load_glb(&TestGltf::leaf_shrub(40, 3));
    assert!(!shrub.encloses_volume());
    // The box with one face gone: open, though no material cuts rays.
    let mut doc = TestGltf::textured_box(2);
    let prim = &mut doc.meshes[0][0];
    prim.indices.truncate(prim.indices.len() - 6);
    assert!(!load_glb(&doc).encloses_volume());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Any box over the shrub, any sizes, periodic or not: coverage in [0, 1] per axis, density
    /// their mean, colours finite in [0, 1], a unit normal exactly where something is covered.
    #[test]
    fn shell_volumes_are_finite_and_in_range(
        seed in 0u64..1000,
        nx in 1usize..9, ny in 1usize..9, nz in 1usize..9,
        rays in 1usize..4,
        lo in prop::array::uniform3(-1.5f64..0.5),
        size in prop::array::uniform3(0.05f64..3.0),
        periodic in prop::array::uniform3(any::<bool>()),
    ) {
        let shrub = load_glb(&TestGltf::leaf_shrub(12, seed));
        let min = DVec3::from_array(lo);
        let v = voxelize(&shrub, &VoxelParams {
            dims: [nx, ny, nz],
            min,
            max: min + DVec3::from_array(size),
            periodic,
            supersample: Supersample::of(rays),
            fill: Fill::Shell,
        }).unwrap();
        let axis = v.axis_coverage.as_ref().unwrap();
        for (k, cover) in axis.iter().enumerate() {
            for c in cover {
                prop_assert!((0.0..=1.0).contains(c));
            }
            let mean = (cover[0] + cover[1] + cover[2]) / 3.0;
            prop_assert!((v.density[k] - mean).abs() <= 1e-6);
            prop_assert!(v.color[k].iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c)));
            match v.normal[k] {
                Some(n) => prop_assert!(v.density[k] > 0.0 && (n.length() - 1.0).abs() < 1e-4),
                None => prop_assert!(v.density[k] == 0.0),
            }
        }
    }
}
