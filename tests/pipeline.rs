//! The precompute pipeline end to end: files read back bit for bit, loaders refuse damaged or
//! newer files, the planner's skips, the cache, the lock, interrupted runs, manifest errors.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use altrep::asset::{AssetError, AssetReader, AssetWriter, Conventions, DESCRIPTION_FILE};
use altrep::parallax::render_bounded;
use altrep::pipeline::cylinder::{Cylinder, CylinderSpec};
use altrep::pipeline::octree::{OctreeRepr, OctreeSpec};
use altrep::pipeline::parallax::{Parallax, ParallaxSpec};
use altrep::pipeline::pyramid::PyramidRepr;
use altrep::pipeline::{
    Lighting, Manifest, Needs, Outcome, PipelineError, Representation, RunOptions, Source,
    run_scene,
};
use altrep::pyramid::{
    MipError, Pyramid, PyramidData, PyramidKind, PyramidParams, RipMap, WrapMode,
};
use altrep_data_gen::{Light, scene_shape};
use approx::assert_abs_diff_eq;
use proptest::prelude::*;

const BIN: &str = env!("CARGO_BIN_EXE_altrep");

fn source<'a>(name: &'a str, shape: &'a (dyn altrep_data_gen::Shape + Sync)) -> Source<'a> {
    Source {
        name,
        geometry: Some(shape),
        texture: None,
        light: Light::default(),
    }
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
        light: Light::default(),
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
        let (m, _) = PyramidRepr::measure(&loaded, &needs, &src).unwrap();
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
    let r = AssetReader::open(&dir.path().join("fip/pyramid"));
    let refused = match r {
        Ok(r) => PyramidRepr::read(&r).is_err(),
        Err(_) => true,
    };
    assert!(refused, "damaged fipmap metadata must be refused");
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
        let params = altrep::cylinder::RenderParams {
            angle: 0.7,
            width: 24,
            height: 24,
            supersample: 1,
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

const SCENE: &str = r#"
[[asset]]
name = "pear"
shape = "pear"
[asset.needs]
azimuth_deg = [0, 200]
screen_px = [8, 32]
[asset.parallax]
views = 6
size = 32
[[asset]]
name = "chair"
shape = "chair"
[asset.needs]
screen_px = [4, 16]
[asset.octree]
resolution = 32
"#;

fn options(out: &Path) -> RunOptions {
    RunOptions::new(out)
}

#[test]
fn second_run_is_cached_and_one_changed_parameter_rebuilds_one_asset() {
    let dir = tempfile::tempdir().unwrap();
    let m = Manifest::parse(SCENE, Path::new("scene.toml")).unwrap();
    let first = run_scene(&m, &options(dir.path())).unwrap();
    assert!(first.ok(), "{}", first.table());
    assert!(first.outcomes.iter().all(|o| o.outcome == Outcome::Built));
    for o in &first.outcomes {
        let m = o.measurement.as_ref().unwrap();
        assert!(m.psnr_db.is_finite() && m.psnr_db > 15.0, "{o:?}");
        assert!(m.iou > 0.8, "{o:?}");
    }
    let second = run_scene(&m, &options(dir.path())).unwrap();
    assert!(second.outcomes.iter().all(|o| o.outcome == Outcome::Cached));
    for (a, b) in first.outcomes.iter().zip(&second.outcomes) {
        assert_eq!(a.bytes, b.bytes);
    }
    // The figures a cached run reports are those of the files on disk, measured again here
    // rather than compared with the copy the first run stored in asset.json.
    let cached = |asset: &str| {
        second
            .outcomes
            .iter()
            .find(|o| o.asset == asset)
            .and_then(|o| o.measurement.clone())
            .unwrap()
    };
    let pear = remeasure_pear_parallax(&m, &dir.path().join("pear/parallax"));
    let stored = cached("pear");
    assert_abs_diff_eq!(stored.psnr_db, pear.psnr_db, epsilon = 1e-9);
    assert_abs_diff_eq!(stored.worst_psnr_db, pear.worst_psnr_db, epsilon = 1e-9);
    assert_abs_diff_eq!(stored.iou, pear.iou, epsilon = 1e-12);
    let chair_shape = scene_shape("chair").unwrap();
    let chair_files = AssetReader::open(&dir.path().join("chair/octree")).unwrap();
    let (chair, _) = OctreeRepr::measure(
        &OctreeRepr::read(&chair_files).unwrap(),
        &m.assets[1].needs,
        &source("chair", &chair_shape),
    )
    .unwrap();
    assert_eq!(
        cached("chair"),
        chair,
        "chair: cached figures vs the files measured again"
    );
    let changed = SCENE.replace("views = 6", "views = 8");
    let m2 = Manifest::parse(&changed, Path::new("scene.toml")).unwrap();
    let third = run_scene(&m2, &options(dir.path())).unwrap();
    let by = |a: &str| {
        third
            .outcomes
            .iter()
            .find(|o| o.asset == a)
            .unwrap()
            .outcome
            .clone()
    };
    assert_eq!(by("pear"), Outcome::Built);
    assert_eq!(by("chair"), Outcome::Cached);
    // A corrupted cached file is detected and rebuilt.
    let f = dir.path().join("chair/octree/octree.bin");
    let mut bytes = std::fs::read(&f).unwrap();
    bytes[10] ^= 1;
    std::fs::write(&f, bytes).unwrap();
    let fourth = run_scene(&m2, &options(dir.path())).unwrap();
    let chair = fourth.outcomes.iter().find(|o| o.asset == "chair").unwrap();
    assert_eq!(chair.outcome, Outcome::Built);
    assert!(chair.cache_note.as_deref().unwrap().contains("octree.bin"));
}

/// The pear's images with parallax in `folder` (the first asset of `m`, azimuths 0–200°),
/// measured as `Parallax::measure` documents it but without calling it: the inverse warp of the
/// loaded views at the native size, one ray per pixel, no mip level, against the 3×3-ray truth,
/// at the four azimuths `200° · (k + 0.37) / 4`.
fn remeasure_pear_parallax(m: &Manifest, folder: &Path) -> altrep::pipeline::Measurement {
    use altrep::parallax::{RenderParams, WarpMethod, render};
    let spec = &m.assets[0];
    assert_eq!(
        (spec.name.as_str(), spec.needs.azimuth_deg),
        ("pear", [0.0, 200.0])
    );
    let light = Light {
        direction: glam::Vec3::from_array(m.scene.light).normalize(),
        ambient: m.scene.ambient,
    };
    let data = Parallax::read(&AssetReader::open(folder).unwrap()).unwrap();
    let size = data.images.params.width;
    let shape = scene_shape("pear").unwrap();
    let (mut psnr, mut worst, mut iou) = (0.0, f64::INFINITY, 0.0);
    for k in 0..4 {
        let angle = (200.0 * (k as f64 + 0.37) / 4.0f64).to_radians();
        let truth = altrep_data_gen::render_truth(
            &shape,
            &altrep_data_gen::TruthParams {
                angle,
                width: size,
                height: size,
                supersample: 3,
                light,
                cylinder: altrep_data_gen::BoundingCylinder::default(),
            },
        )
        .unwrap();
        let screen = RenderParams {
            supersample: 1,
            light,
            mip: false,
            ..RenderParams::native(&data.images)
        };
        let img = render(&data.images, angle, WarpMethod::Inverse, &screen).unwrap();
        let p = altrep::metrics::psnr(&img, &truth).unwrap();
        psnr += p / 4.0;
        worst = worst.min(p);
        iou += altrep::metrics::silhouette_iou(&img, &truth, 0.5).unwrap() / 4.0;
    }
    altrep::pipeline::Measurement {
        method: String::new(),
        psnr_db: psnr,
        worst_psnr_db: worst,
        iou,
        mean_steps: None,
    }
}

/// `--no-measure`: the same files as a measured run, no figures and no pictures; a second
/// run without measuring reuses them, a run with measuring rebuilds and measures them.
#[test]
fn a_run_without_measuring_writes_the_same_files_and_a_measuring_run_rebuilds_them() {
    let dir = tempfile::tempdir().unwrap();
    let m = Manifest::parse(SCENE, Path::new("scene.toml")).unwrap();
    let files_only = RunOptions {
        measure: false,
        ..options(&dir.path().join("files"))
    };
    let t0 = Instant::now();
    let first = run_scene(&m, &files_only).unwrap();
    let wall = t0.elapsed().as_secs_f64();
    assert!(first.ok(), "{}", first.table());
    for o in &first.outcomes {
        assert_eq!(o.outcome, Outcome::Built, "{o:?}");
        assert!(o.measurement.is_none() && o.pictures.is_empty(), "{o:?}");
        // The build time is a part of the asset's own time, itself a part of the run's, and
        // asset.json keeps the same figure; the bytes are those of the data files on disk.
        assert!(
            0.0 < o.build_seconds && o.build_seconds <= o.seconds && o.seconds <= wall,
            "{}: build {} s, asset {} s, run {wall} s",
            o.asset,
            o.build_seconds,
            o.seconds
        );
        let folder = dir
            .path()
            .join("files")
            .join(&o.asset)
            .join(&o.representation);
        let r = AssetReader::open(&folder).unwrap();
        assert_eq!(
            r.description().report["build_seconds"].as_f64(),
            Some(o.build_seconds),
            "{}",
            o.asset
        );
        let on_disk: u64 = r
            .description()
            .files
            .iter()
            .map(|f| std::fs::metadata(folder.join(&f.path)).unwrap().len())
            .sum();
        assert_eq!(o.bytes, on_disk, "{}: bytes reported vs on disk", o.asset);
    }
    let pictures = std::fs::read_dir(dir.path().join("files/pictures")).unwrap();
    assert_eq!(pictures.count(), 0, "pictures written without measuring");
    // The files are those of a measured run, byte for byte (their hashes in asset.json).
    let measured = run_scene(&m, &options(&dir.path().join("measured"))).unwrap();
    assert!(measured.ok(), "{}", measured.table());
    for (name, repr) in [("pear", "parallax"), ("chair", "octree")] {
        let files = |root: &str| {
            let r = AssetReader::open(&dir.path().join(root).join(name).join(repr)).unwrap();
            assert_eq!(
                r.description().report.get("measurement").is_some(),
                root == "measured"
            );
            r.description()
                .files
                .iter()
                .map(|f| (f.path.clone(), f.blake3.clone()))
                .collect::<Vec<_>>()
        };
        let (a, b) = (files("files"), files("measured"));
        assert!(!a.is_empty());
        assert_eq!(a, b, "{name}/{repr}");
    }
    let second = run_scene(&m, &files_only).unwrap();
    for (o, built) in second.outcomes.iter().zip(&first.outcomes) {
        assert_eq!(o.outcome, Outcome::Cached, "{o:?}");
        assert!(o.measurement.is_none());
        assert_eq!(
            o.build_seconds, built.build_seconds,
            "{}: build time of the files",
            o.asset
        );
    }
    let third = run_scene(&m, &options(&dir.path().join("files"))).unwrap();
    for o in &third.outcomes {
        assert_eq!(o.outcome, Outcome::Built, "{o:?}");
        assert!(o.cache_note.as_deref().unwrap().contains("no measurement"));
        let figures = o.measurement.as_ref().unwrap();
        assert!(
            figures.psnr_db.is_finite() && figures.psnr_db > 15.0,
            "{o:?}"
        );
    }
}

#[test]
fn a_rerun_leaves_no_stale_file_and_a_locked_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let m = Manifest::parse(SCENE, Path::new("scene.toml")).unwrap();
    run_scene(&m, &options(dir.path())).unwrap();
    let stale = dir.path().join("pear/parallax/view4-albedo.png");
    assert!(stale.exists());
    // Fewer views now: view 4 must not survive beside the new files.
    let m2 = Manifest::parse(
        &SCENE.replace("views = 6", "views = 4"),
        Path::new("scene.toml"),
    )
    .unwrap();
    run_scene(&m2, &options(dir.path())).unwrap();
    assert!(!stale.exists());
    let lock = std::fs::File::options()
        .write(true)
        .open(dir.path().join(".altrep.lock"))
        .unwrap();
    lock.try_lock().unwrap();
    match run_scene(&m2, &options(dir.path())) {
        Err(PipelineError::Locked { path }) => assert!(path.ends_with(".altrep.lock")),
        other => panic!("expected a lock error, got {other:?}"),
    }
}

#[test]
fn an_object_no_view_sees_is_a_typed_error() {
    let dir = tempfile::tempdir().unwrap();
    // A horizontal square at y = 0: every horizontal ray misses it.
    std::fs::write(
        dir.path().join("flat.obj"),
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let scene =
        "[[asset]]\nname = \"flat\"\nmesh = \"flat.obj\"\n[asset.parallax]\nviews = 4\nsize = 16\n";
    let m = Manifest::parse(scene, &dir.path().join("scene.toml")).unwrap();
    let s = run_scene(&m, &options(&dir.path().join("out"))).unwrap();
    match &s.outcomes[0].outcome {
        Outcome::Failed(msg) => assert!(msg.contains("not visible"), "{msg}"),
        other => panic!("an invisible object must fail, got {other:?}"),
    }
    assert!(!dir.path().join("out/flat/parallax").exists());
    // The same from every command that takes a mesh.
    for cmd in ["capture", "parallax", "cylinder"] {
        let mut c = Command::new(BIN);
        c.args([cmd, "--mesh"]).arg(dir.path().join("flat.obj"));
        if cmd == "capture" {
            c.arg("--out").arg(dir.path().join("cli-capture"));
        }
        let o = c.output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{cmd} accepted an invisible object");
        assert!(
            err.contains("not visible")
                || err.contains("nothing visible")
                || err.contains("no view sees"),
            "{cmd}: {err}"
        );
    }
}

#[test]
fn manifest_errors_name_the_key_and_line() {
    let p = Path::new("scene.toml");
    let cases = [
        (
            "[[asset]]\nname = \"a\"\nshape = \"pear\"\ncolour = 3\n[asset.parallax]\n",
            4,
            "colour",
        ),
        (
            "[[asset]]\nname = \"a\"\nshape = \"pear\"\n[asset.parallax]\nviews = \"eight\"\n",
            5,
            "invalid type",
        ),
        (
            "[[asset]]\nname = \"a\"\nshape = \"pear\"\n[asset.octree]\n\n[[asset]]\nname = \"a\"\nshape = \"tree\"\n[asset.octree]\n",
            7,
            "duplicate asset name",
        ),
        (
            "[[asset]]\nname = \"a\"\nshape = \"pear\"\n[asset.needs]\nscreen_px = [64, 8]\n[asset.octree]\n",
            4,
            "needs.screen_px",
        ),
        (
            "[[asset]]\nname = \"a\"\nshape = \"pear\"\n[asset.parallax]\nbounds = [\"best\"]\n",
            2,
            "unknown kind",
        ),
        (
            "[[asset]]\nname = \"a\"\nshape = \"nope\"\n[asset.octree]\n",
            2,
            "nope",
        ),
        (
            "[[asset]]\nname = \"t\"\ntest_texture = { size = 64 }\n[asset.pyramid]\n[asset.parallax]\nviews = 4\n",
            5,
            "[asset.parallax] needs a `shape` or `mesh`",
        ),
        (
            "[[asset]]\nname = \"a\"\nshape = \"pear\"\n\n[asset.pyramid]\n",
            5,
            "[asset.pyramid] needs a `texture`",
        ),
        (
            "[[asset]]\nname = \"a\"\nshape = \"pear\"\ntexture = \"x.png\"\n[asset.pyramid]\n",
            2,
            "exactly one of",
        ),
    ];
    for (text, line, needle) in cases {
        match Manifest::parse(text, p) {
            Err(PipelineError::Manifest {
                line: l, message, ..
            }) => {
                assert_eq!(l, line, "line for {needle}: {message}");
                assert!(message.contains(needle), "'{message}' lacks '{needle}'");
            }
            other => panic!("{needle}: expected a manifest error, got {other:?}"),
        }
    }
}

#[test]
fn json_output_path_is_checked_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let out = dir.path().join("out");
    let t0 = Instant::now();
    let o = Command::new(BIN)
        .args(["precompute"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args(["--json", "no/such/dir/x.json"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no/such/dir"), "{err}");
    assert!(!out.join("pear").exists(), "work started before the check");
    let _ = t0;
}

/// Spawns a precompute, kills it with `signal` while it is writing an asset's files (a file
/// seen in a staging folder), and checks that every asset folder present is complete and that
/// the kill left a half-written asset behind in `.staging`: the check saw an interrupted write,
/// not a run killed before it wrote anything (tried up to five times, then a failure). Then the
/// rerun completes and equals a clean run's files.
fn kill_mid_run(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    // Enough work for a kill to land mid-run.
    let big = SCENE
        .replace("size = 32", "size = 64")
        .replace("screen_px = [8, 32]", "screen_px = [8, 64]")
        .replace("resolution = 32", "resolution = 128")
        .replace("screen_px = [4, 16]", "screen_px = [4, 128]");
    std::fs::write(&scene, &big).unwrap();
    let out = dir.path().join("out");
    let staging = out.join(".staging");
    // Files of an asset being written: in a folder of `.staging` (ASSET.REPR.PID.N), or in an
    // asset folder that has no asset.json yet.
    let files_in = |d: &Path| std::fs::read_dir(d).map_or(0, |f| f.count());
    let being_written = || -> usize {
        let staged: usize = std::fs::read_dir(&staging).map_or(0, |d| {
            d.filter_map(|e| e.ok()).map(|e| files_in(&e.path())).sum()
        });
        let unfinished: usize = ["pear/parallax", "chair/octree"]
            .iter()
            .map(|a| out.join(a))
            .filter(|d| !d.join(DESCRIPTION_FILE).exists())
            .map(|d| files_in(&d))
            .sum();
        staged + unfinished
    };
    let mut interrupted = Vec::new();
    for attempt in 1..=5 {
        let _ = std::fs::remove_dir_all(&out);
        let mut child = Command::new(BIN)
            .arg("precompute")
            .arg(&scene)
            .arg("--out")
            .arg(&out)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let t0 = Instant::now();
        while being_written() == 0
            && child.try_wait().unwrap().is_none()
            && t0.elapsed() < Duration::from_secs(120)
        {
            std::thread::sleep(Duration::from_millis(1));
        }
        Command::new("kill")
            .arg(format!("-{signal}"))
            .arg(child.id().to_string())
            .status()
            .unwrap();
        let status = child.wait().unwrap();
        assert!(!status.success(), "the run finished before the {signal}");
        for asset in ["pear/parallax", "chair/octree"] {
            let d = out.join(asset);
            if d.exists() {
                AssetReader::open(&d).unwrap_or_else(|e| panic!("half-written {asset}: {e}"));
            }
        }
        // What the kill interrupted: staging folders holding files (a write in progress).
        interrupted = std::fs::read_dir(&staging).map_or(Vec::new(), |d| {
            d.filter_map(|e| e.ok())
                .filter(|e| std::fs::read_dir(e.path()).is_ok_and(|mut f| f.next().is_some()))
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        });
        if !interrupted.is_empty() {
            eprintln!("{signal}, attempt {attempt}: interrupted {interrupted:?}");
            break;
        }
    }
    assert!(
        !interrupted.is_empty(),
        "no {signal} in five attempts landed while an asset was being written"
    );
    let rerun = Command::new(BIN)
        .arg("precompute")
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        rerun.status.success(),
        "{}",
        String::from_utf8_lossy(&rerun.stderr)
    );
    assert!(!staging.read_dir().is_ok_and(|mut d| d.next().is_some()));
    let clean = dir.path().join("clean");
    let o = Command::new(BIN)
        .arg("precompute")
        .arg(&scene)
        .arg("--out")
        .arg(&clean)
        .output()
        .unwrap();
    assert!(o.status.success());
    for asset in ["pear/parallax", "chair/octree"] {
        let a = AssetReader::open(&out.join(asset)).unwrap();
        let b = AssetReader::open(&clean.join(asset)).unwrap();
        assert_eq!(a.description().files, b.description().files, "{asset}");
        assert_eq!(a.description().cache_key, b.description().cache_key);
    }
}

#[test]
fn sigkill_mid_run_leaves_no_half_written_asset() {
    kill_mid_run("KILL");
}

#[test]
fn sigint_mid_run_leaves_no_half_written_asset() {
    kill_mid_run("INT");
}

const VALID: &str = "[scene]\nambient = 0.3\n[[asset]]\nname = \"a\"\nshape = \"pear\"\n[asset.needs]\nazimuth_deg = [0, 90]\nscreen_px = [4, 32]\nlighting = \"baked\"\n[asset.parallax]\nviews = 8\nbounds = [\"best_c\"]\n[asset.octree]\nresolution = 16\n";

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]

    #[test]
    fn manifest_parser_never_panics_on_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = Manifest::parse(&text, Path::new("fuzz.toml"));
    }

    #[test]
    fn manifest_parser_never_panics_on_mutated_valid_files(
        at in 0usize..VALID.len(), len in 0usize..12, insert in "[ -~\n]{0,12}"
    ) {
        let mut s = VALID.to_string();
        let end = (at + len).min(s.len());
        if s.is_char_boundary(at) && s.is_char_boundary(end) {
            s.replace_range(at..end, &insert);
        }
        let _ = Manifest::parse(&s, Path::new("fuzz.toml"));
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]

    /// One byte of a written folder's asset.json or PNGs changed or the file cut short: a
    /// changed PNG is refused as altered (named), an unchanged folder loads as written, and an
    /// edited asset.json that still opens gives a typed error or a representation that keeps to
    /// its own metadata and draws finite pixels.
    #[test]
    fn loader_never_panics_on_mutated_asset_files(
        file in 0usize..4, at in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<bool>()
    ) {
        let dir = tempfile::tempdir().unwrap();
        let asset = written_asset(dir.path());
        let original = Parallax::read(&AssetReader::open(&asset).unwrap()).unwrap();
        let names = ["asset.json", "view0-albedo.png", "view1-bounds-best_c-v.png", "view2-depth.png"];
        let p = asset.join(names[file]);
        let before = std::fs::read(&p).unwrap();
        let mut bytes = before.clone();
        let i = at.index(bytes.len());
        if cut { bytes.truncate(i); } else { bytes[i] = byte; }
        let changed = bytes != before;
        std::fs::write(&p, &bytes).unwrap();
        match AssetReader::open(&asset) {
            Err(e) => {
                prop_assert!(changed, "the unchanged folder was refused: {}", e);
                if file > 0 {
                    prop_assert!(
                        matches!(&e, AssetError::Altered { path, .. } if *path == p),
                        "{} damaged: {}", names[file], e
                    );
                }
            }
            Ok(r) => {
                prop_assert!(file == 0 || !changed, "{} changed, yet it opened", names[file]);
                // asset.json edited without a hash change is accepted by open() and must still
                // decode to a typed error or a consistent representation.
                match Parallax::read(&r) {
                    Err(e) => prop_assert!(changed, "the unchanged folder did not decode: {}", e),
                    Ok(data) => {
                        if !changed {
                            prop_assert!(data.images.codes() == original.images.codes());
                            prop_assert_eq!(data.bounds.len(), original.bounds.len());
                        }
                        let m = &r.description().metadata;
                        let p = &data.images.params;
                        prop_assert_eq!(
                            [p.views, p.width, p.height, p.depth_bits as usize].map(|v| Some(v as u64)),
                            ["views", "width", "height", "depth_bits"].map(|k| m[k].as_u64()),
                            "the loaded sizes are not those of asset.json"
                        );
                        prop_assert_eq!(data.images.views.len(), p.views);
                        let screen = altrep::parallax::RenderParams::native(&data.images);
                        if let Ok(img) = altrep::parallax::render(
                            &data.images, 0.7, altrep::parallax::WarpMethod::Inverse, &screen,
                        ) {
                            prop_assert!(img.pixels.iter().flatten().all(|c| c.is_finite()));
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn capture_rerun_leaves_no_stale_views() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cap");
    let run = |views: &str| {
        let o = Command::new(BIN)
            .args([
                "capture", "--shape", "pear", "--size", "8", "--views", views, "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run("8");
    assert!(out.join("view007.albedo.png").exists());
    run("2");
    assert!(out.join("view001.albedo.png").exists());
    assert!(
        !out.join("view007.albedo.png").exists(),
        "a view of the earlier run survived"
    );
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers, vec![std::ffi::OsString::from("cap")]);
}

#[test]
fn every_json_output_is_checked_before_the_work() {
    for cmd in [
        vec!["parallax", "--shape", "pear"],
        vec!["cylinder", "--shape", "pear"],
        vec!["fit-bench"],
        vec!["ellipsoid-bench"],
        vec!["pyramid"],
        vec!["slices"],
    ] {
        let t0 = Instant::now();
        let o = Command::new(BIN)
            .args(&cmd)
            .args(["--json", "no/such/dir/x.json"])
            .output()
            .unwrap();
        assert!(!o.status.success(), "{cmd:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("no/such/dir"), "{cmd:?}: {err}");
        // Failing before the work: the message says the folder is missing (no output of a run).
        assert!(
            String::from_utf8_lossy(&o.stdout).trim().is_empty(),
            "{cmd:?} printed results before failing"
        );
        let _ = t0;
    }
}

#[test]
fn shards_split_the_assets_once() {
    use altrep::pipeline::Shard;
    let names: Vec<String> = (0..40).map(|i| format!("asset{i}")).collect();
    let shards: Vec<Shard> = (0..3)
        .map(|i| Shard::parse(&format!("{i}/3")).unwrap())
        .collect();
    for n in &names {
        assert_eq!(shards.iter().filter(|s| s.owns(n)).count(), 1, "{n}");
    }
    let sizes: Vec<usize> = shards
        .iter()
        .map(|s| names.iter().filter(|n| s.owns(n)).count())
        .collect();
    assert!(sizes.iter().all(|&k| k >= 5), "unbalanced shards {sizes:?}");
    for bad in ["3/3", "1", "a/2", "0/0"] {
        assert!(Shard::parse(bad).is_err(), "{bad}");
    }
}
