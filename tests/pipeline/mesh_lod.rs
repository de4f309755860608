//! Simplified meshes (`[asset.mesh_lod]`): the chain of levels meets the quality target at both
//! edges of every band, seen from directions neither its preview nor its verification used;
//! the levels read back bit for bit with the source's materials; sources and parameters it
//! cannot take are refused by name.

use super::*;
use altrep::mesh_lod::asset::{MeshLodRepr, MeshLodSpec};
use altrep_data_gen::gltf_write::TestGltf;
use altrep_data_gen::{Mesh, MeshLoadOptions, RgbaImage, Shape, TruthParams, render_truth};

fn load(doc: &TestGltf, name: &str) -> Mesh {
    Mesh::from_gltf_bytes(
        &doc.to_glb().unwrap(),
        Path::new(name),
        &MeshLoadOptions::default(),
    )
    .unwrap()
}

fn corners(mesh: &Mesh) -> Vec<[[u32; 3]; 3]> {
    let mut v: Vec<_> = mesh
        .triangles_f32()
        .iter()
        .map(|t| t.map(|p| p.map(f32::to_bits)))
        .collect();
    v.sort_unstable();
    v
}

fn picture(shape: &dyn Shape, angle: f64, size: usize) -> RgbaImage {
    render_truth(shape, &TruthParams::square(angle, size, Supersample::of(3))).unwrap()
}

/// The rock of the bundled scene (coarser: 1,280 triangles, one texture) at a 24 dB target
/// from 4 to 128 px. Every band's level is drawn at both its edges from three azimuths the
/// preview (3 directions) and the verification (4) never used, against the source's truth:
/// each PSNR is at least the target less 1 dB (the chain was chosen on other directions; a
/// level just meeting the target there may miss it by a little here). Measured 2026-12-07:
/// see the figures printed.
#[test]
fn the_chain_meets_the_target_at_both_edges_of_every_band_from_unseen_directions() {
    let mesh = load(&TestGltf::textured_rock(3, 11), "rock.glb");
    let src = placed("rock", &mesh);
    let needs = Needs {
        screen_px: [4.0, 128.0],
        quality_db: 24.0,
        ..Needs::default()
    };
    let spec = MeshLodSpec::default();
    let (plan, decisions) = MeshLodRepr::plan(&spec, &needs, &src).unwrap();
    assert!(plan.refused.is_none(), "{plan:?}");
    let (lod, report) = MeshLodRepr::build(&spec, &needs, &decisions, &src).unwrap();
    println!("{}", serde_json::to_string_pretty(&report).unwrap());
    let dir = tempfile::tempdir().unwrap();
    let (back, desc) = round_trip::<MeshLodRepr>(dir.path(), "rock", &lod);
    // The files hold the chain and its levels bit for bit, with the source's materials.
    assert_eq!(back.chain, lod.chain);
    assert_eq!(back.levels.len(), lod.levels.len());
    for (a, b) in back.levels.iter().zip(&lod.levels) {
        assert_eq!(a.info, b.info);
        assert_eq!(corners(&a.mesh), corners(&b.mesh));
        assert_eq!(a.mesh.materials().len(), mesh.materials().len());
        assert!(a.mesh.materials()[0].base_texture.is_some());
    }
    // One file per level, and the rock's one texture once, beside them.
    let glbs = desc
        .files
        .iter()
        .filter(|f| f.path.ends_with(".glb"))
        .count();
    let pngs: Vec<&str> = desc
        .files
        .iter()
        .filter(|f| f.path.ends_with(".png"))
        .map(|f| f.path.as_str())
        .collect();
    assert_eq!(glbs, back.levels.len());
    // One texture file, the levels sharing it: the source's or one reduced for them all.
    assert_eq!(pngs, ["texture0.png"]);
    assert_eq!(glbs + pngs.len(), desc.files.len());
    // Finest first, coarser after; bands cover the needs from end to end, meeting.
    for w in back.levels.windows(2) {
        assert!(w[1].info.triangles < w[0].info.triangles);
    }
    assert_abs_diff_eq!(back.chain[0].from_px, needs.screen_px[0]);
    assert_abs_diff_eq!(back.chain.last().unwrap().to_px, needs.screen_px[1]);
    for w in back.chain.windows(2) {
        assert_abs_diff_eq!(w[0].to_px, w[1].from_px);
    }
    let drawn = back.chain.iter().filter(|b| b.level.is_some()).count();
    assert!(
        drawn >= 1,
        "no simplified level in the chain: {:?}",
        back.chain
    );
    for band in &back.chain {
        let Some(l) = band.level else { continue };
        let level = &back.levels[l];
        assert!(level.info.triangles < mesh.triangle_count());
        for size in [band.from_px.max(8.0), band.to_px] {
            let size = size.round() as usize;
            for azimuth in [0.9, 2.6, 5.1] {
                let truth = picture(&mesh, azimuth, size);
                let img = picture(&level.mesh, azimuth, size);
                let psnr = altrep::metrics::psnr(&img, &truth).unwrap();
                println!(
                    "level {l} ({} triangles) at {size} px, azimuth {azimuth}: {psnr:.2} dB",
                    level.info.triangles
                );
                assert!(
                    psnr >= needs.quality_db - 1.0,
                    "level {l} at {size} px, azimuth {azimuth}: {psnr:.2} dB"
                );
            }
        }
    }
    // The measurement is the verification at the band edges: it meets the target there.
    let (m, pictures) =
        MeshLodRepr::measure(&back, &needs, MeshLodRepr::measure_size(&decisions), &src).unwrap();
    println!("{m:?}");
    assert!(m.worst_psnr_db >= needs.quality_db, "{m:?}");
    assert_eq!(m.size, 128);
    assert_eq!(pictures.len(), 1);
}

/// Shapes without triangles are refused by the plan, naming what is needed; parameters out of
/// range are refused naming the key.
#[test]
fn simplified_meshes_refuse_procedural_shapes_and_bad_parameters() {
    refuses_shapes_and_bad_keys::<MeshLodRepr>(&[
        (
            MeshLodSpec {
                ratios: vec![0.5, 0.6],
                ..MeshLodSpec::default()
            },
            "ratios",
        ),
        (
            MeshLodSpec {
                ratios: vec![1.5],
                ..MeshLodSpec::default()
            },
            "ratios",
        ),
        (
            MeshLodSpec {
                ratios: vec![],
                ..MeshLodSpec::default()
            },
            "ratios",
        ),
        (
            MeshLodSpec {
                min_triangles: 0,
                ..MeshLodSpec::default()
            },
            "min_triangles",
        ),
        (
            MeshLodSpec {
                attribute_weight: f32::NAN,
                ..MeshLodSpec::default()
            },
            "attribute_weight",
        ),
    ]);
}

/// Leaf cards do not simplify: a collapse inside a card tears it. The shrub's levels all miss
/// the target, the chain draws the source everywhere, and the measurement reports the finest
/// level's figures, below the target (flagged by the run, never a zero error on nothing).
/// Measured 2026-12-07: 18.49 dB (worst 17.26), IoU 0.62 over 8 and 32 px.
#[test]
fn foliage_that_does_not_simplify_keeps_the_source_in_its_chain() {
    let mesh = load(&TestGltf::leaf_shrub(300, 7), "shrub.glb");
    let src = placed("shrub", &mesh);
    let needs = Needs {
        screen_px: [4.0, 32.0],
        ..Needs::default()
    };
    let spec = MeshLodSpec::default();
    let (_, decisions) = MeshLodRepr::plan(&spec, &needs, &src).unwrap();
    let (lod, _) = MeshLodRepr::build(&spec, &needs, &decisions, &src).unwrap();
    assert_eq!(lod.chain.len(), 1);
    assert_eq!(lod.chain[0].level, None);
    // The finest level is kept, undrawn, and measured: below the target, by a finite margin.
    assert_eq!(lod.levels.len(), 1);
    let (m, _) = MeshLodRepr::measure(&lod, &needs, 32, &src).unwrap();
    println!("{m:?}");
    assert!(m.method.contains("no level met the target"), "{}", m.method);
    assert!(m.psnr_db.is_finite() && m.psnr_db > 5.0 && m.worst_psnr_db < needs.quality_db);
    assert!(m.iou > 0.3 && m.iou < 1.0, "{m:?}");
}

/// A chain chosen on a wrong preview (a 40-triangle level said to reach every size) is
/// repaired by its verification: the level's reach is lowered until every band meets the
/// target at both edges at the measured directions, and the sizes it gave up go to the finer
/// level or to the source.
#[test]
fn a_chain_chosen_on_a_wrong_preview_is_repaired_by_its_verification() {
    let mesh = load(&TestGltf::textured_rock(3, 11), "rock.glb");
    let src = placed("rock", &mesh);
    let needs = Needs {
        screen_px: [4.0, 64.0],
        quality_db: 26.0,
        ..Needs::default()
    };
    let level = |n| {
        mesh.simplified(&altrep_data_gen::SimplifyParams {
            target_triangles: n,
            ..Default::default()
        })
        .unwrap()
        .mesh
    };
    let (fine, coarse) = (level(640), level(40));
    let levels = [&fine, &coarse];
    let sizes = altrep::mesh_lod::preview_sizes(&needs, 512.0);
    let claimed = [Some(64.0), Some(64.0)];
    let altrep::mesh_lod::Verified {
        chain,
        reach,
        repairs,
    } = altrep::mesh_lod::verified_chain(&levels, &claimed, &sizes, &needs, &src).unwrap();
    println!("{chain:?} {reach:?} {repairs}");
    assert!(repairs >= 1);
    assert!(reach[1].is_none_or(|r| r < 64.0), "{reach:?}");
    for (b, size, scores) in altrep::mesh_lod::verify(&levels, &chain, &needs, &src).unwrap() {
        let worst = scores
            .iter()
            .map(|s| s.psnr_db)
            .fold(f64::INFINITY, f64::min);
        assert!(
            worst >= needs.quality_db,
            "band {b} at {size} px: {worst:.2} dB"
        );
    }
}

/// A chain drawn no larger than 16 px needs no 64² texture: the levels share one reduced to
/// the smallest power of two (from 16) with which every band still meets the target; the file
/// holds that image, and the files read back still meet the target at every band edge.
#[test]
fn textures_are_reduced_to_the_sizes_the_chain_draws() {
    let mesh = load(&TestGltf::textured_rock(3, 11), "rock.glb");
    let src = placed("rock", &mesh);
    let needs = Needs {
        screen_px: [4.0, 16.0],
        ..Needs::default()
    };
    let spec = MeshLodSpec::default();
    let (_, decisions) = MeshLodRepr::plan(&spec, &needs, &src).unwrap();
    let (lod, report) = MeshLodRepr::build(&spec, &needs, &decisions, &src).unwrap();
    println!("{}", report["texture_sizes_tried"]);
    let kept: Vec<Option<usize>> = lod.levels.iter().map(|l| l.info.texture_px).collect();
    let side = kept[0].expect("textures reduced");
    assert!((16..64).contains(&side), "{kept:?}");
    assert!(kept.iter().all(|k| *k == Some(side)), "{kept:?}");
    let dir = tempfile::tempdir().unwrap();
    let (back, desc) = round_trip::<MeshLodRepr>(dir.path(), "rock", &lod);
    let pngs: Vec<_> = desc
        .files
        .iter()
        .filter(|f| f.path.ends_with(".png"))
        .collect();
    assert_eq!(pngs.len(), 1);
    assert_eq!((pngs[0].width, pngs[0].height), (side, side));
    let (m, _) =
        MeshLodRepr::measure(&back, &needs, MeshLodRepr::measure_size(&decisions), &src).unwrap();
    println!("{m:?}");
    assert!(m.worst_psnr_db >= needs.quality_db, "{m:?}");
}
