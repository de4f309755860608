//! What a run measures and how it judges it: the quality target, the exact renderer beside the
//! display's, the conditions `--everything` measures at, the cylinder's coverage check, and the
//! plan's skips.

use super::*;

/// `needs.quality_db` gates every measured representation: a pear asked for at 60 dB is flagged
/// in the report and the command ends non-zero, naming it, unless `--allow-below-quality`; at
/// 10 dB the same run passes without a flag.
#[test]
fn a_representation_below_its_quality_target_is_flagged_and_fails_the_run() {
    let scene = |db: f64| {
        format!(
            "[[asset]]\nname = \"pear\"\nshape = \"pear\"\n[asset.needs]\nscreen_px = [8, 32]\nquality_db = {db}\n[asset.parallax]\nviews = 6\nsize = 32\n"
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let run = |db: f64, allow: bool| {
        let manifest = dir.path().join(format!("scene-{db}.toml"));
        std::fs::write(&manifest, scene(db)).unwrap();
        let out = dir.path().join(format!("out-{db}-{allow}"));
        let mut c = Command::new(BIN);
        c.arg("precompute").arg(&manifest).arg("--out").arg(&out);
        if allow {
            c.arg("--allow-below-quality");
        }
        let o = c.output().unwrap();
        let report = std::fs::read_to_string(out.join("report.md")).unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
            report,
        )
    };
    let (ok, err, report) = run(60.0, false);
    assert!(!ok, "a 60 dB target passed: {err}");
    assert!(
        err.contains("pear/parallax") && err.contains("< 60 dB"),
        "{err}"
    );
    assert!(
        report.contains("below the 60 dB quality target"),
        "{report}"
    );
    let (ok, err, report) = run(60.0, true);
    assert!(ok, "{err}");
    assert!(
        report.contains("below the 60 dB quality target"),
        "{report}"
    );
    let (ok, err, report) = run(10.0, false);
    assert!(ok, "{err}");
    assert!(!report.contains("quality target"), "{report}");
}

/// A screen size that needs the very texture asked for skips nothing: the plan lists no
/// "64² instead of 64²"; a smaller one still skips, with the sizes.
#[test]
fn the_plan_lists_no_skip_that_changes_nothing() {
    let scene = |px: u32| {
        format!(
            "[[asset]]\nname = \"pear\"\nshape = \"pear\"\n[asset.needs]\nscreen_px = [4, {px}]\n[asset.parallax]\nsize = 64\n[asset.cylinder]\ncolumns = 256\nrows = 64\n"
        )
    };
    let dir = tempfile::tempdir().unwrap();
    for (px, skips) in [(40, false), (64, false), (20, true)] {
        let m = Manifest::parse(&scene(px), Path::new("scene.toml")).unwrap();
        let plans = altrep::pipeline::plan_scene(&m, &options(dir.path())).unwrap();
        for (_, repr, plan) in &plans {
            let sized: Vec<&String> = plan
                .items
                .iter()
                .filter_map(|i| i.skipped.as_ref())
                .filter(|r| r.contains("instead of"))
                .collect();
            assert_eq!(!sized.is_empty(), skips, "{px} px, {repr}: {sized:?}");
            for r in sized {
                assert!(r.contains("32") && r.contains("64"), "{r}");
            }
        }
    }
}

/// The planner's coverage check answers for the object, as `altrep cylinder` does: the same
/// share at every texture size asked for (the old preview check answered 13 % at one size and
/// 74 % at another for the same object), equal to the share `evaluate` checks, and the same
/// refusal for a flat card holding the axis at every size.
#[test]
fn the_cylinder_coverage_check_answers_for_the_object_at_every_size() {
    use altrep::cylinder::{EvalParams, evaluate};
    let card = altrep_data_gen::Mesh::from_raw_triangles(
        "card",
        vec![
            [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0]],
            [[-1.0, 0.0, 0.0], [1.0, 2.0, 0.0], [-1.0, 2.0, 0.0]],
        ],
        &altrep_data_gen::MeshLoadOptions::default(),
    )
    .unwrap();
    let (truck, chair) = (scene_shape("truck").unwrap(), scene_shape("chair").unwrap());
    let shapes: [(&str, &(dyn altrep_data_gen::Shape + Sync)); 3] =
        [("truck", &truck), ("chair", &chair), ("card", &card)];
    let needs = Needs {
        screen_px: [4.0, 16.0],
        ..Needs::default()
    };
    for (name, shape) in shapes {
        let mut shares = Vec::new();
        for (columns, rows) in [(32, 8), (128, 32), (256, 64)] {
            let spec = CylinderSpec {
                columns,
                rows,
                ..CylinderSpec::default()
            };
            let (plan, decisions) = Cylinder::plan(&spec, &needs, &source(name, shape)).unwrap();
            assert_eq!(
                plan.refused.is_some(),
                decisions.coverage < spec.min_coverage,
                "{name} {columns} × {rows}: {:?}",
                plan.refused
            );
            shares.push(decisions.coverage);
        }
        assert!(shares.iter().all(|s| *s == shares[0]), "{name}: {shares:?}");
        let params = EvalParams {
            angles: 2,
            size: 24,
            ..EvalParams::default()
        };
        match evaluate(shape, &params) {
            Ok(report) => assert_eq!(report.held.share, shares[0], "{name}"),
            Err(altrep::cylinder::CylinderError::NotRepresentable { share, .. }) => {
                assert_eq!(share, shares[0], "{name}");
                assert!(share < 0.5, "{name}: {share}");
            }
            Err(e) => panic!("{name}: {e}"),
        }
    }
    // Measured: truck 0.86, chair 0.60, the card 0.05 (refused).
    assert!(shares_of(&truck) > 0.8 && shares_of(&card) < 0.1);
}

fn shares_of(shape: &(dyn altrep_data_gen::Shape + Sync)) -> f64 {
    altrep::cylinder::radial_visibility(
        shape,
        altrep_data_gen::BoundingCylinder::default(),
        &altrep::cylinder::CoverageParams::default(),
    )
    .unwrap()
    .share
}

/// Images with parallax are measured with the bounded march a display runs, the exact inverse
/// warp beside it: they draw the same image (measured: equal to the last bit on the truck and
/// the pear). Bounds that do not belong to the views (the pear's on the truck's views, as a
/// misbuilt or damaged bound would be) make the march miss what the views hold: the figures
/// fall far below the exact renderer's, and the run's summary flags it in the table and in
/// `below_exact` (which `altrep precompute` ends non-zero on).
#[test]
fn a_renderer_far_below_its_exact_renderer_is_flagged() {
    let spec = ParallaxSpec {
        views: 8,
        size: 32,
        bounds: vec!["zminmax".into()],
        ..ParallaxSpec::default()
    };
    let needs = Needs {
        screen_px: [4.0, 32.0],
        ..Needs::default()
    };
    let (truck, pear) = (scene_shape("truck").unwrap(), scene_shape("pear").unwrap());
    let build = |name: &str, shape: &(dyn altrep_data_gen::Shape + Sync)| {
        let src = source(name, shape);
        let (_, d) = Parallax::plan(&spec, &needs, &src).unwrap();
        Parallax::build(&spec, &needs, &d, &src).unwrap().0
    };
    let size = 32;
    let (mut data, pear_data) = (build("truck", &truck), build("pear", &pear));
    let (m, _) = Parallax::measure(&data, &needs, size, &source("truck", &truck)).unwrap();
    assert_eq!(m.exact_psnr_db, Some(m.psnr_db));
    data.bounds = pear_data.bounds;
    let (broken, _) = Parallax::measure(&data, &needs, size, &source("truck", &truck)).unwrap();
    let exact = broken.exact_psnr_db.unwrap();
    eprintln!(
        "truck: bounded march {:.2} dB = exact {:.2} dB; with the pear's bounds {:.2} dB",
        m.psnr_db, exact, broken.psnr_db
    );
    assert_abs_diff_eq!(exact, m.psnr_db, epsilon = 1e-12);
    assert!(
        broken.psnr_db < exact - altrep::representation::EXACT_GAP_DB,
        "{} vs {exact}",
        broken.psnr_db
    );

    let dir = tempfile::tempdir().unwrap();
    let scene = "[[asset]]\nname = \"pear\"\nshape = \"pear\"\n[asset.needs]\nscreen_px = [4, 16]\n[asset.parallax]\nviews = 4\nsize = 16\nbounds = [\"zminmax\"]\n";
    let manifest = Manifest::parse(scene, &dir.path().join("scene.toml")).unwrap();
    let mut summary = run_scene(&manifest, &options(&dir.path().join("out"))).unwrap();
    assert!(summary.below_exact().is_empty());
    let o = &mut summary.outcomes[0];
    let measured = o.measurement.as_mut().unwrap();
    assert_eq!(measured.exact_psnr_db, Some(measured.psnr_db));
    measured.psnr_db = broken.psnr_db;
    measured.exact_psnr_db = Some(exact);
    assert_eq!(summary.below_exact().len(), 1);
    let table = summary.table();
    assert!(
        table.contains(&format!("built, below its exact renderer's {exact:.2} dB")),
        "{table}"
    );
}

/// `--everything` builds every view, level and channel the needs would skip, but measures as the
/// plan for the needs would: at the needs' directions, drawn at the sizes the plan chooses
/// (larger data drawn minified, as a display draws it there). The two runs' figures therefore
/// compare, representation by representation: the same size, the same directions; what differs
/// is only what was built.
#[test]
fn everything_is_measured_at_the_planned_conditions() {
    let scene = "[[asset]]\nname = \"pear\"\nshape = \"pear\"\n[asset.needs]\nazimuth_deg = [0, 120]\nscreen_px = [4, 16]\nlighting = \"baked\"\n[asset.parallax]\nviews = 8\nsize = 64\nbounds = [\"zminmax\"]\n[asset.cylinder]\ncolumns = 128\nrows = 64\n[asset.octree]\nresolution = 64\n[asset.slices]\nresolution = 64\n\n[[asset]]\nname = \"truck\"\nshape = \"truck\"\n[asset.needs]\nelevation_deg = [20, 60]\nscreen_px = [4, 32]\n[asset.sphere]\ngrid = 4\nsize = 64\n\n[[asset]]\nname = \"grain\"\ntest_texture = { size = 64, seed = 2 }\n[asset.needs]\nscreen_px = [4, 16]\ngrazing_deg = 60\n[asset.pyramid]\nwrap = [\"Repeat\", \"Repeat\"]\n\n[[asset]]\nname = \"rock\"\nmesh = \"rock.glb\"\n[asset.needs]\nscreen_px = [4, 16]\n[asset.mesh_lod]\n[asset.auto]\n";
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("rock.glb"),
        altrep_data_gen::gltf_write::TestGltf::textured_rock(2, 3)
            .to_glb()
            .unwrap(),
    )
    .unwrap();
    let m = Manifest::parse(scene, &dir.path().join("scene.toml")).unwrap();
    let planned = run_scene(&m, &options(&dir.path().join("planned"))).unwrap();
    let mut all = options(&dir.path().join("all"));
    all.everything = true;
    let everything = run_scene(&m, &all).unwrap();
    let mut compared = 0;
    for (p, e) in planned.outcomes.iter().zip(&everything.outcomes) {
        assert_eq!((&p.asset, &p.representation), (&e.asset, &e.representation));
        let (Some(mp), Some(me)) = (&p.measurement, &e.measurement) else {
            panic!("{}/{}: not measured", p.asset, p.representation);
        };
        eprintln!(
            "{}/{}: planned {:.2} dB ({} B), everything {:.2} dB ({} B), at {}²",
            p.asset, p.representation, mp.psnr_db, p.bytes, me.psnr_db, e.bytes, mp.size
        );
        assert_eq!(mp.size, me.size, "{}/{}", p.asset, p.representation);
        if p.representation == "auto" {
            // Chosen by cost over the bands of the needs: wider needs may draw other members
            // (cheaper over more bands), so bytes have no order.
        } else if p.representation == "mesh_lod" {
            // A chain keeps the levels it draws, chosen by measurement: wider needs draw the
            // same levels over the planned sizes and perhaps more beyond, never fewer.
            assert!(e.bytes >= p.bytes, "{}/{}", p.asset, p.representation);
        } else {
            assert!(e.bytes > p.bytes, "{}/{}", p.asset, p.representation);
        }
        assert!(mp.psnr_db.is_finite() && me.psnr_db.is_finite());
        compared += 1;
    }
    assert_eq!(compared, 8);
    // The sizes are those a planned run picks, below what `--everything` built.
    let size = |o: &altrep::pipeline::AssetOutcome| o.measurement.as_ref().unwrap().size;
    let sizes: Vec<usize> = planned.outcomes.iter().map(size).collect();
    assert_eq!(sizes, [16, 16, 16, 16, 32, 0, 16, 16]);
    // Every folder opens as what it is through the one list of representations, whichever it
    // holds; a folder of something else is refused, naming it.
    let mut opened = Vec::new();
    for o in &planned.outcomes {
        let folder = dir
            .path()
            .join("planned")
            .join(&o.asset)
            .join(&o.representation);
        let any = altrep::representation::open(&folder).unwrap();
        assert_eq!(any.name(), o.representation);
        opened.push(any.name());
    }
    opened.sort_unstable();
    let mut names = altrep::representation::NAMES.to_vec();
    names.sort_unstable();
    assert_eq!(opened, names);
    let e = altrep::representation::open(&dir.path().join("planned"))
        .err()
        .unwrap();
    assert!(e.to_string().contains("asset.json"), "{e}");
}
