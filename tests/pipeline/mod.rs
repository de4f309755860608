//! The precompute pipeline end to end: files read back bit for bit, loaders refuse damaged or
//! newer files, the planner's skips, the cache, the lock, interrupted runs, manifest errors,
//! and the faults around the output folder that must do no harm.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use altrep::asset::{AssetError, AssetReader, AssetWriter, Conventions, DESCRIPTION_FILE};
use altrep::cylinder::asset::{Cylinder, CylinderSpec};
use altrep::ellipsoid::asset::{OctreeRepr, OctreeSpec};
use altrep::parallax::asset::{Parallax, ParallaxSpec};
use altrep::parallax::render_bounded;
use altrep::pipeline::{
    Lighting, Manifest, Needs, Outcome, PipelineError, Representation, RunOptions, Source,
    run_scene,
};
use altrep::pyramid::asset::PyramidRepr;
use altrep::pyramid::{
    MipError, Pyramid, PyramidData, PyramidKind, PyramidParams, RipMap, WrapMode,
};
use altrep::slices::asset::{SlicesRepr, SlicesSpec};
use altrep_data_gen::{Light, Supersample, scene_shape};
use approx::assert_abs_diff_eq;
use proptest::prelude::*;

const BIN: &str = env!("CARGO_BIN_EXE_altrep");

fn source<'a>(name: &'a str, shape: &'a (dyn altrep_data_gen::Shape + Sync)) -> Source<'a> {
    Source {
        name,
        geometry: Some(shape),
        texture: None,
        tile: None,
        light: Light::default(),
        placement: None,
    }
}

/// A mesh as a source, with its placement.
fn placed<'a>(name: &'a str, mesh: &'a altrep_data_gen::Mesh) -> Source<'a> {
    Source {
        placement: Some(*mesh.placement()),
        ..source(name, mesh)
    }
}

/// Representation `R` refuses a procedural shape in its plan, naming the mesh it needs, and
/// each spec of `bad` in its validation, naming the key given beside it.
fn refuses_shapes_and_bad_keys<R: Representation>(bad: &[(R::Spec, &str)])
where
    R::Spec: Default,
{
    let chair = scene_shape("chair").unwrap();
    let (plan, _) = R::plan(
        &R::Spec::default(),
        &Needs::default(),
        &source("chair", &chair),
    )
    .unwrap();
    let why = plan.refused.expect("refused");
    assert!(why.contains("mesh"), "{why}");
    for (spec, key) in bad {
        let e = R::validate(spec).unwrap_err();
        assert!(e.contains(key), "{e}");
    }
}

/// The run options every test starts from: defaults, output into `out`.
fn options(out: &Path) -> RunOptions {
    RunOptions::new(out)
}

/// Writes `data` of representation `R` into `out` and reads it back.
fn round_trip<R: Representation>(
    out: &Path,
    name: &str,
    data: &R::Data,
) -> (R::Data, altrep::asset::AssetDescription) {
    let mut w = AssetWriter::new(out, name, R::NAME).unwrap();
    let meta = R::write(data, &mut w).unwrap();
    let desc = w
        .commit(
            R::NAME,
            name,
            "key",
            Conventions::new(1.0, 2.0),
            meta,
            serde_json::Value::Null,
        )
        .unwrap();
    let r = AssetReader::open(&out.join(name).join(R::NAME)).unwrap();
    (R::read(&r).unwrap(), desc)
}

#[test]
fn parallax_files_read_back_bit_for_bit_for_every_bound_kind() {
    let dir = tempfile::tempdir().unwrap();
    let shape = scene_shape("truck").unwrap();
    let src = source("truck", &shape);
    for (lighting, depth_bits, bound_bits) in [(Lighting::Dynamic, 8, 8), (Lighting::Baked, 16, 16)]
    {
        let spec = ParallaxSpec {
            views: 6,
            size: 24,
            depth_bits,
            bound_bits,
            bounds: ["cylinder", "zminmax", "pair", "best_c", "best_c_split"]
                .map(String::from)
                .to_vec(),
        };
        let needs = Needs {
            lighting,
            azimuth_deg: [0.0, 150.0],
            ..Needs::default()
        };
        let (_, decisions) = Parallax::plan(&spec, &needs, &src).unwrap();
        assert!(
            decisions.views.len() < 6,
            "the azimuth range must skip a view"
        );
        let (data, _) = Parallax::build(&spec, &needs, &decisions, &src).unwrap();
        let name = format!("truck{depth_bits}");
        let (loaded, _) = round_trip::<Parallax>(dir.path(), &name, &data);
        assert_eq!(loaded.images.codes(), data.images.codes(), "view codes");
        assert_eq!(loaded.bounds.len(), data.bounds.len());
        for (a, b) in loaded.bounds.iter().zip(&data.bounds) {
            assert_eq!(a.kind, b.kind);
            for k in 0..6 {
                // Bit for bit: PixelBound compares its f64 fields exactly.
                assert_eq!(a.view_slots(k), b.view_slots(k), "{:?} view {k}", a.kind);
            }
            for angle in [0.3, 1.1, 2.0] {
                let (img_a, steps_a) =
                    render_bounded(&loaded.images, a, angle, &src.light).unwrap();
                let (img_b, steps_b) = render_bounded(&data.images, b, angle, &src.light).unwrap();
                assert_eq!(steps_a, steps_b, "{:?} steps at {angle}", a.kind);
                assert_eq!(img_a, img_b);
            }
        }
        if lighting == Lighting::Baked {
            let r = AssetReader::open(&dir.path().join(&name).join("parallax")).unwrap();
            assert!(!r.has("view1/normal"), "baked lighting stores no normals");
        }
    }
}

fn texture_source(tex: &altrep::pyramid::Texture) -> Source<'_> {
    Source {
        name: "grain",
        geometry: None,
        texture: Some(tex),
        tile: None,
        light: Light::default(),
        placement: None,
    }
}

#[test]
fn pyramid_files_read_back_bit_for_bit_and_measure_well() {
    let dir = tempfile::tempdir().unwrap();
    let tex = altrep::pyramid::truth::test_texture(64, 3);
    let src = texture_source(&tex);
    let spec = PyramidParams {
        wrap: [WrapMode::Repeat; 2],
        ..PyramidParams::default()
    };
    for (grazing, kind) in [
        (20.0, PyramidKind::Mip),
        (75.0, PyramidKind::Rip),
        (85.0, PyramidKind::Fip),
    ] {
        let needs = Needs {
            grazing_deg: grazing,
            screen_px: [4.0, 16.0],
            ..Needs::default()
        };
        let (_, dec) = PyramidRepr::plan(&spec, &needs, &src).unwrap();
        assert_eq!(dec.kind, kind);
        let (data, _) = PyramidRepr::build(&spec, &needs, &dec, &src).unwrap();
        let name = format!("grain-{grazing}");
        let (loaded, desc) = round_trip::<PyramidRepr>(dir.path(), &name, &data);
        assert_eq!(loaded.first, data.first);
        let (a, b) = (loaded.levels(), data.levels());
        assert_eq!(a.len(), b.len());
        assert_eq!(desc.files.len(), b.len());
        for ((na, ta), (nb, tb)) in a.iter().zip(&b) {
            assert_eq!(na, nb);
            assert_eq!(ta.data.len(), tb.data.len());
            // Bit for bit, not merely equal as floats.
            assert!(
                ta.data
                    .iter()
                    .zip(&tb.data)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            );
        }
        // The levels kept still serve every needed view: against the supersampled truth at
        // tilts up to the grazing angle, at least 20 dB (an RMS error of 0.1 on values in
        // [0, 1]; the texture's own standard deviation is about 0.25).
        let (m, _) = PyramidRepr::measure(&loaded, &needs, 0, &src).unwrap();
        assert!(m.worst_psnr_db > 20.0, "{kind:?}: {m:?}");
        assert!(m.psnr_db.is_finite());
    }
}

#[test]
fn a_test_texture_pyramid_runs_end_to_end_and_is_cached() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "[[asset]]\nname = \"grain\"\ntest_texture = { size = 64, seed = 2 }\n[asset.needs]\nscreen_px = [4, 16]\ngrazing_deg = 60\n[asset.pyramid]\nwrap = [\"Repeat\", \"Repeat\"]\n";
    let m = Manifest::parse(scene, &dir.path().join("scene.toml")).unwrap();
    let out = dir.path().join("out");
    let s = run_scene(&m, &options(&out)).unwrap();
    assert_eq!(s.outcomes.len(), 1);
    assert_eq!(s.outcomes[0].outcome, Outcome::Built, "{:?}", s.outcomes[0]);
    assert!(out.join("grain/pyramid/rip_u2_v2.exr").exists());
    assert!(
        !out.join("grain/pyramid/rip_u0_v0.exr").exists(),
        "64 texels are never read at 16 px"
    );
    let again = run_scene(&m, &options(&out)).unwrap();
    assert_eq!(again.outcomes[0].outcome, Outcome::Cached);
}

#[test]
fn pyramid_planner_skips_unused_levels_with_reasons() {
    let tex = altrep::pyramid::truth::test_texture(256, 1);
    let src = texture_source(&tex);
    let needs = Needs {
        screen_px: [16.0, 32.0],
        grazing_deg: 0.0,
        ..Needs::default()
    };
    let (plan, dec) = PyramidRepr::plan(&PyramidParams::default(), &needs, &src).unwrap();
    assert_eq!(dec.kind, PyramidKind::Mip);
    // Trilinear lookups read level l while the texture covers n_l/2 to 2·n_l px: 256, 128 and
    // 64 texels only above 32 px, 8, 4, 2 and 1 only below 16 px; kept: 32 and 16 texels.
    assert_eq!(dec.levels_u, [3, 4]);
    let skipped: Vec<_> = plan.skipped().collect();
    assert_eq!(skipped.len(), 7, "{:?}", plan.items);
    for (level, reason) in [
        (0, "finer than the largest"),
        (8, "coarser than the smallest"),
    ] {
        assert!(
            skipped
                .iter()
                .any(|i| i.what.starts_with(&format!("level {level} "))
                    && i.skipped.as_deref().unwrap().contains(reason)),
            "level {level}: {skipped:?}"
        );
    }
    // Grazing views of a texture that does not wrap: a ripmap (fipmaps shear periodic textures
    // only, and the plan says so), grazing keeps coarser levels.
    let grazing = Needs {
        grazing_deg: 85.0,
        ..needs
    };
    let (plan, dec) = PyramidRepr::plan(&PyramidParams::default(), &grazing, &src).unwrap();
    assert_eq!(dec.kind, PyramidKind::Rip);
    // 16 px at 85° from the normal: 16·cos 85° = 1.4 px, so every level down to 1 texel.
    assert_eq!(dec.levels_u, [3, 8]);
    assert!(plan.skipped().any(|i| {
        i.what.starts_with("fipmap")
            && i.skipped
                .as_deref()
                .unwrap()
                .contains("periodic textures only")
    }));
    // The same views of a periodic texture: the fipmap, with its own mipmap levels.
    let periodic = PyramidParams {
        wrap: [WrapMode::Repeat; 2],
        ..PyramidParams::default()
    };
    let (_, dec) = PyramidRepr::plan(&periodic, &grazing, &src).unwrap();
    assert_eq!(dec.kind, PyramidKind::Fip);
    assert_eq!(dec.levels_u, [3, 8]);
    assert_eq!(dec.levels_mip, [3, 8]);
    // Within the ripmap's range (below fip_min_tilt_deg): no fipmap.
    let oblique = Needs {
        grazing_deg: 60.0,
        ..needs
    };
    let (_, dec) = PyramidRepr::plan(&periodic, &oblique, &src).unwrap();
    assert_eq!(dec.kind, PyramidKind::Rip);
}

#[test]
fn fipmap_files_hold_every_shear_and_damaged_metadata_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let tex = altrep::pyramid::truth::test_texture(32, 5);
    let src = texture_source(&tex);
    let spec = PyramidParams {
        wrap: [WrapMode::Repeat; 2],
        ..PyramidParams::default()
    };
    let needs = Needs {
        grazing_deg: 88.0,
        screen_px: [4.0, 12.0],
        ..Needs::default()
    };
    let (_, dec) = PyramidRepr::plan(&spec, &needs, &src).unwrap();
    let (data, _) = PyramidRepr::build(&spec, &needs, &dec, &src).unwrap();
    let PyramidData::Fip(f) = &data.data else {
        panic!("a fipmap was planned")
    };
    // 12 px at most on screen: the 32-texel levels are skipped everywhere.
    assert_eq!(data.first, [1, 1]);
    assert_eq!(data.first_mip, 1);
    assert_eq!(f.shears().len(), 8);
    let (loaded, desc) = round_trip::<PyramidRepr>(dir.path(), "fip", &data);
    let names: Vec<String> = desc.files.iter().map(|f| f.path.clone()).collect();
    assert!(
        names.iter().any(|n| n == "fip_v-1over2_u1_v1.exr"),
        "{names:?}"
    );
    assert!(!names.iter().any(|n| n.contains("_u0_")), "{names:?}");
    let PyramidData::Fip(g) = &loaded.data else {
        panic!("read back as a fipmap")
    };
    assert_eq!(g.shears(), f.shears());
    // Lookups through the loaded database equal the built one's, bit for bit, for every
    // scheme the decision can pick.
    let mut a = vec![0.0f32; tex.channels];
    let mut b = a.clone();
    for (i, dir) in [
        [0.0, 1.0, 0.0],
        [0.99, 0.1, 0.0],
        [0.7, 0.05, 0.7],
        [0.3, 0.02, -0.95],
    ]
    .into_iter()
    .enumerate()
    {
        let (u, v) = (0.1 + 0.2 * i as f64, 0.7 - 0.1 * i as f64);
        let d = [0.05, 0.01, -0.02, 0.3];
        data.sample_dir_into(u, v, d, dir, &mut a);
        loaded.sample_dir_into(u, v, d, dir, &mut b);
        assert_eq!(a, b, "dir {dir:?}");
    }
    // A description whose shears do not match fip_shear_steps is refused with a typed error.
    let path = dir.path().join("fip/pyramid").join(DESCRIPTION_FILE);
    let text = std::fs::read_to_string(&path).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["metadata"]["shears"] = serde_json::json!([]);
    std::fs::write(&path, serde_json::to_string(&doc).unwrap()).unwrap();
    // Refused by the description's own hash first…
    assert!(matches!(
        AssetReader::open(&dir.path().join("fip/pyramid")),
        Err(AssetError::Altered { .. })
    ));
    // …and, without the hash (a format 1.0 description), by the pyramid reader's checks.
    doc.as_object_mut().unwrap().remove("description_blake3");
    std::fs::write(&path, serde_json::to_string(&doc).unwrap()).unwrap();
    let r = AssetReader::open(&dir.path().join("fip/pyramid")).unwrap();
    assert!(
        PyramidRepr::read(&r).is_err(),
        "damaged fipmap metadata must be refused"
    );
}

#[test]
fn pyramid_from_levels_refuses_levels_that_are_not_halvings() {
    let tex = altrep::pyramid::truth::test_texture(16, 1);
    let p = PyramidParams::default();
    let full = Pyramid::build(tex.clone(), p).unwrap();
    let ok = Pyramid::from_levels(full.levels()[1..].to_vec(), p).unwrap();
    assert_eq!(ok.levels(), &full.levels()[1..]);
    let mut gap = full.levels().to_vec();
    gap.remove(2);
    assert!(matches!(
        Pyramid::from_levels(gap, p),
        Err(MipError::LevelSize { level: 2, .. })
    ));
    let mut past = full.levels().to_vec();
    past.push(past.last().unwrap().clone());
    assert!(matches!(
        Pyramid::from_levels(past, p),
        Err(MipError::LevelSize { .. })
    ));
    assert!(matches!(
        Pyramid::from_levels(Vec::new(), p),
        Err(MipError::NoLevels)
    ));
    let rip = RipMap::build(tex, p).unwrap();
    let rows = |skip_u: usize| -> Vec<Vec<_>> {
        (0..2)
            .map(|lv| (skip_u..3).map(|lu| rip.level(lu, lv).clone()).collect())
            .collect()
    };
    assert!(RipMap::from_levels(rows(0), p).is_ok());
    let mut bad = rows(0);
    bad[1].swap(0, 1);
    assert!(matches!(
        RipMap::from_levels(bad, p),
        Err(MipError::LevelSize { .. })
    ));
    let mut ragged = rows(0);
    ragged[1].pop();
    assert!(RipMap::from_levels(ragged, p).is_err());
    let _ = PyramidData::Rip(rip);
}

#[test]
fn octree_files_read_back_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let shape = scene_shape("chair").unwrap();
    let src = source("chair", &shape);
    let spec = OctreeSpec {
        resolution: 16,
        ..OctreeSpec::default()
    };
    let (_, dec) = OctreeRepr::plan(&spec, &Needs::default(), &src).unwrap();
    let (tree, _) = OctreeRepr::build(&spec, &Needs::default(), &dec, &src).unwrap();
    let (loaded, desc) = round_trip::<OctreeRepr>(dir.path(), "chair", &tree);
    assert_eq!(loaded.nodes(), tree.nodes());
    assert_eq!(loaded.depth(), tree.depth());
    assert_eq!(desc.data_bytes() as usize, tree.nodes().len() * 52);
}

/// Slices of the tree: the files read back to slices that write the same files again (every
/// atlas byte for byte), and draw the same images; damaged metadata is refused by the reader.
#[test]
fn slices_files_read_back_bit_for_bit_and_damaged_metadata_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let shape = scene_shape("tree").unwrap();
    let src = source("tree", &shape);
    let spec = SlicesSpec {
        resolution: 16,
        ..SlicesSpec::default()
    };
    let needs = Needs {
        lighting: Lighting::Baked,
        elevation_deg: [0.0, 50.0],
        screen_px: [4.0, 16.0],
        ..Needs::default()
    };
    let (plan, dec) = SlicesRepr::plan(&spec, &needs, &src).unwrap();
    assert!(plan.refused.is_none(), "{plan:?}");
    let (data, _) = SlicesRepr::build(&spec, &needs, &dec, &src).unwrap();
    let (loaded, desc) = round_trip::<SlicesRepr>(dir.path(), "tree", &data);
    assert_eq!(loaded.slices.stacks().len(), data.slices.stacks().len());
    assert!(desc.files.iter().any(|f| f.path == "slices-y1-minus.png"));
    // Written again from what was read, every file is the same.
    let again = dir.path().join("again");
    let (_, desc2) = round_trip::<SlicesRepr>(&again, "tree", &loaded);
    let hashes = |d: &altrep::asset::AssetDescription| -> Vec<(String, String)> {
        d.files
            .iter()
            .map(|f| (f.path.clone(), f.blake3.clone()))
            .collect()
    };
    assert_eq!(hashes(&desc), hashes(&desc2));
    // What is read draws as what was written, up to the 8-bit codes: 8-bit colour in sRGB and
    // alpha within 1/255 of the built slices.
    let (m1, _) = SlicesRepr::measure(&loaded, &needs, 16, &src).unwrap();
    let (m0, _) = SlicesRepr::measure(&data, &needs, 16, &src).unwrap();
    assert_abs_diff_eq!(m1.psnr_db, m0.psnr_db, epsilon = 0.2);
    // A stack count that does not match its atlas is refused with a typed error naming it.
    let path = dir.path().join("tree/slices").join(DESCRIPTION_FILE);
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    doc.as_object_mut().unwrap().remove("description_blake3");
    let good = doc.clone();
    for (key, value) in [
        ("slices", serde_json::json!(3)),
        ("axis", serde_json::json!("w")),
        ("minus", serde_json::json!(null)),
    ] {
        let mut bad = good.clone();
        let stacks = bad["metadata"]["stacks"].as_array_mut().unwrap();
        let i = stacks.iter().position(|s| s["minus"].is_string()).unwrap();
        stacks[i][key] = value;
        std::fs::write(&path, serde_json::to_string(&bad).unwrap()).unwrap();
        let r = AssetReader::open(&dir.path().join("tree/slices")).unwrap();
        let err = SlicesRepr::read(&r).err().unwrap();
        assert!(
            matches!(
                &err,
                PipelineError::Asset(AssetError::Content { path, .. }) if path.ends_with("tree/slices")
            ),
            "{key}: {err}"
        );
    }
}

#[test]
fn cylinder_files_read_back_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let shape = scene_shape("truck").unwrap();
    let src = source("truck", &shape);
    for lighting in [Lighting::Dynamic, Lighting::Baked] {
        let spec = CylinderSpec {
            columns: 64,
            rows: 16,
            ..CylinderSpec::default()
        };
        let needs = Needs {
            lighting,
            ..Needs::default()
        };
        let (plan, dec) = Cylinder::plan(&spec, &needs, &src).unwrap();
        assert!(plan.refused.is_none(), "{plan:?}");
        let (data, _) = Cylinder::build(&spec, &needs, &dec, &src).unwrap();
        let name = format!("truck-{lighting:?}");
        let (loaded, _) = round_trip::<Cylinder>(dir.path(), &name, &data);
        assert_eq!(loaded.texture, data.texture);
        assert_eq!(loaded.bounds, data.bounds);
        let params = altrep::cylinder::CylinderRenderParams {
            angle: 0.7,
            width: 24,
            height: 24,
            supersample: Supersample::ONE,
            light: src.light,
        };
        let a = loaded.bounds.render(&loaded.texture, &params).unwrap();
        let b = data.bounds.render(&data.texture, &params).unwrap();
        assert_eq!(a.steps, b.steps);
        assert_eq!(a.image, b.image);
    }
}

#[test]
fn a_flat_cut_out_is_refused_for_the_cylinder_and_kept_for_parallax() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("cutout.obj"),
        "v -1 0 0\nv 1 0 0\nv 1 2 0\nv -1 2 0\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let scene = "[[asset]]\nname = \"sign\"\nmesh = \"cutout.obj\"\n[asset.needs]\nazimuth_deg = [45, 135]\n[asset.parallax]\nviews = 8\nsize = 16\n[asset.cylinder]\ncolumns = 64\nrows = 16\n";
    let m = Manifest::parse(scene, &dir.path().join("scene.toml")).unwrap();
    let out = dir.path().join("out");
    let s = run_scene(&m, &options(&out)).unwrap();
    let cyl = s
        .outcomes
        .iter()
        .find(|o| o.representation == "cylinder")
        .unwrap();
    match &cyl.outcome {
        Outcome::Refused(r) => assert!(r.contains("images with parallax"), "{r}"),
        other => panic!("the cut-out's cylinder must be refused, got {other:?}"),
    }
    assert!(!out.join("sign/cylinder").exists());
    let par = s
        .outcomes
        .iter()
        .find(|o| o.representation == "parallax")
        .unwrap();
    assert_eq!(par.outcome, Outcome::Built);
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("**Refused**"), "{report}");
}

/// A written asset folder to damage.
fn written_asset(dir: &Path) -> PathBuf {
    let shape = scene_shape("pear").unwrap();
    let src = source("pear", &shape);
    let spec = ParallaxSpec {
        views: 4,
        size: 16,
        ..ParallaxSpec::default()
    };
    let (_, dec) = Parallax::plan(&spec, &Needs::default(), &src).unwrap();
    let (data, _) = Parallax::build(&spec, &Needs::default(), &dec, &src).unwrap();
    round_trip::<Parallax>(dir, "pear", &data);
    dir.join("pear").join("parallax")
}

#[test]
fn loader_names_the_truncated_altered_missing_or_newer_file() {
    let dir = tempfile::tempdir().unwrap();
    let asset = written_asset(dir.path());
    let depth = asset.join("view2-depth.png");
    let original = std::fs::read(&depth).unwrap();

    std::fs::write(&depth, &original[..original.len() / 2]).unwrap();
    match AssetReader::open(&asset) {
        Err(AssetError::Altered { path, what }) => {
            assert_eq!(path, depth);
            assert_eq!(what, "size");
        }
        other => panic!("truncated file: {other:?}"),
    }
    let mut altered = original.clone();
    let last = altered.len() - 20;
    altered[last] ^= 0x5a;
    std::fs::write(&depth, &altered).unwrap();
    match AssetReader::open(&asset) {
        Err(AssetError::Altered { path, what }) => {
            assert_eq!(path, depth);
            assert_eq!(what, "content hash");
        }
        other => panic!("altered file: {other:?}"),
    }
    std::fs::remove_file(&depth).unwrap();
    assert!(
        matches!(AssetReader::open(&asset), Err(AssetError::MissingFile { path }) if path == depth)
    );
    std::fs::write(&depth, &original).unwrap();
    AssetReader::open(&asset).unwrap();

    let json_path = asset.join(DESCRIPTION_FILE);
    let text = std::fs::read_to_string(&json_path).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["format_version"] = serde_json::json!([2, 0]);
    v["a_field_of_format_2"] = serde_json::json!(true);
    std::fs::write(&json_path, v.to_string()).unwrap();
    let err = AssetReader::open(&asset).unwrap_err();
    assert!(
        matches!(err, AssetError::NewerVersion { major: 2, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("asset.json"), "{err}");

    std::fs::write(&json_path, "{ not json").unwrap();
    assert!(matches!(
        AssetReader::open(&asset),
        Err(AssetError::Malformed { .. })
    ));
}

#[test]
fn planner_skips_what_narrow_needs_do_not_use_with_reasons() {
    let shape = scene_shape("tree").unwrap();
    let src = source("tree", &shape);
    let needs = Needs {
        azimuth_deg: [80.0, 100.0],
        screen_px: [20.0, 30.0],
        lighting: Lighting::Baked,
        ..Needs::default()
    };
    let (plan, dec) = Parallax::plan(&ParallaxSpec::default(), &needs, &src).unwrap();
    // 8 views at 45° steps: 80–100° is bracketed by views 1, 2 and 3 only.
    assert_eq!(dec.views, vec![1, 2, 3]);
    assert_eq!(dec.size, 32, "the largest screen size is 30 px");
    assert!(!dec.normals);
    // Level 1 (16²) is drawn for 11.3–22.6 px: needed; level 2 and below are not.
    assert_eq!(dec.mip_levels, vec![1usize]);
    let skipped: Vec<_> = plan.skipped().collect();
    for reason in [
        "outside the azimuth range",
        "lighting is baked",
        "largest screen size",
    ] {
        assert!(
            skipped
                .iter()
                .any(|i| i.skipped.as_deref().unwrap().contains(reason)),
            "no skip saying '{reason}': {skipped:?}"
        );
    }
    assert_eq!(
        skipped
            .iter()
            .filter(|i| i.what.starts_with("view "))
            .count(),
        5
    );
    let (oplan, odec) = OctreeRepr::plan(&OctreeSpec::default(), &needs, &src).unwrap();
    assert_eq!(odec.resolution, 32);
    assert_eq!(oplan.skipped().count(), 1);
    // Wide needs skip nothing.
    let wide = Needs {
        screen_px: [1.0, 64.0],
        ..Needs::default()
    };
    let (plan, dec) = Parallax::plan(&ParallaxSpec::default(), &wide, &src).unwrap();
    assert_eq!(dec.views.len(), 8);
    assert_eq!(plan.skipped().count(), 0, "{:?}", plan.items);
}

/// The three places that take a number of parallax views (the library's parameters, the
/// manifest's `[asset.parallax]`, `altrep parallax --views`) accept exactly the same numbers, so
/// a manifest is never accepted only to fail after its rays are cast.
#[test]
fn the_library_the_manifest_and_the_command_accept_the_same_view_counts() {
    use altrep::parallax::ParallaxParams;
    use clap::Parser;
    #[derive(Parser)]
    struct Command {
        #[command(flatten)]
        args: altrep::cli::parallax::ParallaxArgs,
    }
    let mut accepted = Vec::new();
    for views in [0, 1, 2, 3, 4, 8, 1023, 1024, 1025, 4096, 4097] {
        let library = ParallaxParams {
            views,
            ..ParallaxParams::default()
        }
        .validate()
        .is_ok();
        let manifest = ParallaxSpec {
            views,
            ..ParallaxSpec::default()
        }
        .validate()
        .is_ok();
        let n = views.to_string();
        let command =
            Command::try_parse_from(["parallax", "--shape", "sphere", "--views", &n]).is_ok();
        assert_eq!((library, manifest), (command, command), "views = {views}");
        if library {
            accepted.push(views);
        }
    }
    assert_eq!(accepted, [3, 4, 8, 1023, 1024]);
}

mod auto;
#[cfg(unix)]
mod faults;
mod judged;
mod mesh_lod;
mod needs;
mod real_assets;
mod runs;
