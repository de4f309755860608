//! Whole runs of the command: the cache, measuring or not, stale files and locks, typed errors,
//! manifest errors, interrupted runs, and manifests drawn at random.

use super::*;
use altrep_data_gen::Supersample;

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
        // The chair's 16³ octree, seen from 4 azimuths around it, loses its legs (thinner than
        // a voxel) from the oblique views: 0.54 mean silhouette IoU; the pear's views 0.99.
        let iou = if o.representation == "octree" {
            0.5
        } else {
            0.8
        };
        assert!(m.iou > iou, "{o:?}");
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
    assert_abs_diff_eq!(
        stored.coverage_error.unwrap(),
        pear.coverage_error.unwrap(),
        epsilon = 1e-12
    );
    let chair_shape = scene_shape("chair").unwrap();
    let chair_files = AssetReader::open(&dir.path().join("chair/octree")).unwrap();
    let chair_tree = OctreeRepr::read(&chair_files).unwrap();
    let (chair, _) = OctreeRepr::measure(
        &chair_tree,
        &m.assets[1].needs,
        1 << chair_tree.depth(),
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
    let (mut psnr, mut worst, mut iou, mut coverage) = (0.0, f64::INFINITY, 0.0, 0.0);
    for k in 0..4 {
        let angle = (200.0 * (k as f64 + 0.37) / 4.0f64).to_radians();
        let truth = altrep_data_gen::render_truth(
            &shape,
            &altrep_data_gen::TruthParams {
                angle,
                width: size,
                height: size,
                supersample: Supersample::of(3),
                light,
                cylinder: altrep_data_gen::BoundingCylinder::default(),
            },
        )
        .unwrap();
        let screen = RenderParams {
            supersample: Supersample::ONE,
            light,
            mip: false,
            ..RenderParams::native(&data.images)
        };
        let img = render(&data.images, angle, WarpMethod::Inverse, &screen).unwrap();
        let p = altrep::metrics::psnr(&img, &truth).unwrap();
        psnr += p / 4.0;
        worst = worst.min(p);
        iou += altrep::metrics::silhouette_iou(&img, &truth, 0.5).unwrap() / 4.0;
        coverage += altrep::metrics::coverage_error(&img, &truth).unwrap() / 4.0;
    }
    altrep::pipeline::Measurement {
        method: String::new(),
        psnr_db: psnr,
        worst_psnr_db: worst,
        iou,
        coverage_error: Some(coverage),
        mean_steps: None,
        steps_split: Vec::new(),
        size: 0,
        exact_psnr_db: None,
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
            5,
            "unknown kind",
        ),
        (
            "[scene]\nlight = [0.5, 0.8, 0.35]\nambient = 3\n[[asset]]\nname = \"a\"\nshape = \"pear\"\n[asset.octree]\n",
            3,
            "scene.ambient",
        ),
        (
            "[scene]\n\nlight = [0, 0, 0]\n[[asset]]\nname = \"a\"\nshape = \"pear\"\n[asset.octree]\n",
            3,
            "scene.light",
        ),
        (
            "[[asset]]\nname = \"a\"\nshape = \"pear\"\n[asset.cylinder]\n\ncolumns = 3\n",
            6,
            "columns",
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

/// Spawns a precompute, kills it with `signal` while it is writing the chair's octree (a file
/// seen in its staging folder: the largest write, so the signal has time to land within it), and
/// checks that every asset folder present is complete and that the kill left a half-written
/// asset behind in `.staging`: the check saw an interrupted write, not a run killed before it
/// wrote anything (tried up to eight times, then a failure; an interrupt handler takes a few
/// milliseconds to stop the writers, and one write in three finishes within them). A SIGINT
/// ends with status 130 and says what was finished and how to resume. Then the rerun completes
/// and equals the clean run's files in `clean`.
fn kill_mid_run(signal: &str, scene: &Path, clean: &Path) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let staging = out.join(".staging");
    // Files of an asset being written: in a folder of `.staging` (ASSET.REPR.PID.N), or in an
    // asset folder that has no asset.json yet.
    let files_in = |d: &Path| std::fs::read_dir(d).map_or(0, |f| f.count());
    let being_written = || -> usize {
        let staged: usize = std::fs::read_dir(&staging).map_or(0, |d| {
            d.filter_map(|e| e.ok())
                .filter(|e| e.file_name().to_string_lossy().starts_with("chair."))
                .map(|e| files_in(&e.path()))
                .sum()
        });
        let unfinished = Some(out.join("chair/octree"))
            .filter(|d| !d.join(DESCRIPTION_FILE).exists())
            .map_or(0, |d| files_in(&d));
        staged + unfinished
    };
    let mut interrupted = Vec::new();
    for attempt in 1..=8 {
        let _ = std::fs::remove_dir_all(&out);
        let mut child = Command::new(BIN)
            .arg("precompute")
            .arg(scene)
            .arg("--out")
            .arg(&out)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
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
        if status.success() {
            // The run ended between the last poll and the signal (a loaded machine): this
            // attempt did not land; the next one tries again.
            eprintln!("{signal}, attempt {attempt}: the run finished before the signal");
            continue;
        }
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        if signal == "INT" {
            // What was finished, and how to resume.
            assert_eq!(status.code(), Some(130), "{stderr}");
            assert!(
                stderr.contains("interrupted: ") && stderr.contains("run the same command again"),
                "{stderr}"
            );
            // Exactly what is on disk: no folder lands after the list is made.
            let listed: Vec<&str> = stderr
                .lines()
                .find_map(|l| l.split("written in this run: ").nth(1))
                .map_or(Vec::new(), |l| l.split(", ").collect());
            let present: Vec<&str> = ["chair/octree", "pear/parallax"]
                .into_iter()
                .filter(|a| out.join(a).join(DESCRIPTION_FILE).exists())
                .collect();
            assert_eq!(listed, present, "{stderr}");
        }
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
        "no {signal} in eight attempts landed while an asset was being written"
    );
    let rerun = Command::new(BIN)
        .arg("precompute")
        .arg(scene)
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
    for asset in ["pear/parallax", "chair/octree"] {
        let a = AssetReader::open(&out.join(asset)).unwrap();
        let b = AssetReader::open(&clean.join(asset)).unwrap();
        assert_eq!(a.description().files, b.description().files, "{asset}");
        assert_eq!(a.description().cache_key, b.description().cache_key);
    }
}

/// SIGINT, then SIGKILL, each landing mid-run ([`kill_mid_run`]); both resumed runs are
/// compared with one clean run.
#[test]
fn a_signal_mid_run_leaves_no_half_written_asset() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    // Enough work for a kill to land mid-run.
    let big = SCENE
        .replace("size = 32", "size = 64")
        .replace("screen_px = [8, 32]", "screen_px = [8, 64]")
        .replace("resolution = 32", "resolution = 128")
        .replace("screen_px = [4, 16]", "screen_px = [4, 128]");
    std::fs::write(&scene, &big).unwrap();
    let clean = dir.path().join("clean");
    let o = Command::new(BIN)
        .arg("precompute")
        .arg(&scene)
        .arg("--out")
        .arg(&clean)
        .output()
        .unwrap();
    assert!(o.status.success());
    for signal in ["INT", "KILL"] {
        kill_mid_run(signal, &scene, &clean);
    }
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
    // The folder is replaced whole, so only one the command wrote: a file of the user's in a
    // capture folder, a folder of the user's, a file at --out and a link are refused before any
    // work, naming the path, and left as they are.
    let refused = |at: &Path, what: &str| {
        let o = Command::new(BIN)
            .args([
                "capture", "--shape", "pear", "--size", "8", "--views", "2", "--out",
            ])
            .arg(at)
            .output()
            .unwrap();
        assert!(!o.status.success(), "{what}: the capture ran");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("replaces only a folder it wrote"),
            "{what}: {err}"
        );
    };
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    refused(&out, "a file of the user's in a capture folder");
    assert_eq!(std::fs::read(out.join("notes.txt")).unwrap(), b"mine");
    assert!(out.join("view001.albedo.png").exists());
    let theirs = dir.path().join("theirs");
    std::fs::create_dir(&theirs).unwrap();
    std::fs::write(theirs.join("holiday.png"), "mine").unwrap();
    refused(&theirs, "a folder of the user's");
    assert_eq!(std::fs::read(theirs.join("holiday.png")).unwrap(), b"mine");
    let file = dir.path().join("file");
    std::fs::write(&file, "mine").unwrap();
    refused(&file, "a file at --out");
    assert_eq!(std::fs::read(&file).unwrap(), b"mine");
    #[cfg(unix)]
    {
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&theirs, &link).unwrap();
        refused(&link, "a link at --out");
        assert_eq!(std::fs::read(theirs.join("holiday.png")).unwrap(), b"mine");
    }
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

/// Every entry under `dir`, symbolic links not followed: files with their bytes, links with
/// their targets, folders as empty entries.
fn snapshot(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let t = std::fs::symlink_metadata(&p).unwrap().file_type();
            let v = if t.is_symlink() {
                std::fs::read_link(&p)
                    .unwrap()
                    .into_os_string()
                    .into_encoded_bytes()
            } else if t.is_dir() {
                stack.push(p.clone());
                Vec::new()
            } else {
                std::fs::read(&p).unwrap()
            };
            out.insert(p, v);
        }
    }
    out
}

/// What the user put where altrep writes is refused before any work, named in the error, and
/// left as it was, as is everything outside `--out`: a folder without altrep's `asset.json`, an
/// asset folder or a `pictures` folder that is a symbolic link to a folder outside, an
/// `asset.json` that is a link, a file where a folder goes, and a `report.md` in a folder altrep
/// has never run in. An asset folder altrep wrote is still replaced on a rerun.
#[cfg(unix)]
#[test]
fn paths_altrep_did_not_write_are_refused_and_left_untouched() {
    use std::os::unix::fs::symlink;
    let m = Manifest::parse(SCENE, Path::new("scene.toml")).unwrap();
    type Trap = fn(&Path, &Path) -> PathBuf;
    let traps: [(&str, Trap); 7] = [
        ("a folder without asset.json", |out, _| {
            let p = out.join("pear/parallax");
            std::fs::create_dir_all(&p).unwrap();
            std::fs::write(p.join("notes.txt"), "mine").unwrap();
            p
        }),
        ("an asset folder linked outside", |out, outside| {
            std::fs::create_dir_all(outside.join("elsewhere/parallax")).unwrap();
            std::fs::write(outside.join("elsewhere/parallax/notes.txt"), "mine").unwrap();
            std::fs::create_dir_all(out).unwrap();
            symlink(outside.join("elsewhere"), out.join("pear")).unwrap();
            out.join("pear")
        }),
        ("a representation folder linked outside", |out, outside| {
            std::fs::create_dir_all(outside.join("octree")).unwrap();
            std::fs::write(outside.join("octree/asset.json"), "{}").unwrap();
            std::fs::create_dir_all(out.join("chair")).unwrap();
            symlink(outside.join("octree"), out.join("chair/octree")).unwrap();
            out.join("chair/octree")
        }),
        ("asset.json as a link", |out, outside| {
            std::fs::create_dir_all(out.join("chair/octree")).unwrap();
            std::fs::write(outside.join("asset.json"), "mine").unwrap();
            symlink(
                outside.join("asset.json"),
                out.join("chair/octree/asset.json"),
            )
            .unwrap();
            out.join("chair/octree/asset.json")
        }),
        ("a file where an asset folder goes", |out, _| {
            std::fs::create_dir_all(out).unwrap();
            std::fs::write(out.join("pear"), "mine").unwrap();
            out.join("pear")
        }),
        ("pictures linked outside", |out, outside| {
            std::fs::create_dir_all(outside.join("photos")).unwrap();
            std::fs::write(outside.join("photos/holiday.png"), "mine").unwrap();
            std::fs::create_dir_all(out).unwrap();
            symlink(outside.join("photos"), out.join("pictures")).unwrap();
            out.join("pictures")
        }),
        ("a report.md of the user's", |out, _| {
            std::fs::create_dir_all(out).unwrap();
            std::fs::write(out.join("report.md"), "my notes").unwrap();
            out.join("report.md")
        }),
    ];
    for (what, trap) in traps {
        let root = tempfile::tempdir().unwrap();
        let (out, outside) = (root.path().join("out"), root.path().join("outside"));
        std::fs::create_dir_all(&outside).unwrap();
        let named = trap(&out, &outside);
        let before = snapshot(root.path());
        let e = run_scene(&m, &options(&out)).expect_err(what);
        let msg = e.to_string();
        assert!(
            msg.contains(&named.display().to_string()) && msg.contains("altrep writes only"),
            "{what}: {msg}"
        );
        let mut after = snapshot(root.path());
        // The run's lock file is the one thing it may leave in `--out`.
        after.remove(&out.join(altrep::pipeline::LOCK_FILE));
        assert_eq!(
            before, after,
            "{what}: the file system around --out changed"
        );
    }
    // An asset folder altrep wrote, with a stray file in it, is replaced on a rerun.
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("out");
    run_scene(&m, &options(&out)).unwrap();
    std::fs::write(out.join("pear/parallax/stray.txt"), "x").unwrap();
    let mut o = options(&out);
    o.force = true;
    run_scene(&m, &o).unwrap();
    assert!(!out.join("pear/parallax/stray.txt").exists());
}

/// Asset names that would collide in the output folder are manifest errors with their line:
/// the names of the run's own files (any case), and two names that differ only by case (one
/// folder on a case-insensitive file system).
#[test]
fn asset_names_that_collide_in_the_output_folder_are_manifest_errors() {
    let asset =
        |name: &str| format!("[[asset]]\nname = \"{name}\"\nshape = \"pear\"\n[asset.octree]\n");
    for (text, want, line) in [
        (
            asset("report.md"),
            "taken by the output folder's own 'report.md'",
            2,
        ),
        (
            asset("Report.JSON"),
            "taken by the output folder's own 'report.json'",
            2,
        ),
        (
            asset("pictures"),
            "taken by the output folder's own 'pictures'",
            2,
        ),
        (
            format!("{}{}", asset("a"), asset("A")),
            "differs from 'a' only by case",
            6,
        ),
        (
            format!("{}{}", asset("a"), asset("a")),
            "duplicate asset name 'a'",
            6,
        ),
    ] {
        let e = Manifest::parse(&text, Path::new("m.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{e}");
        assert!(e.starts_with(&format!("m.toml:{line}:")), "{e}");
    }
}

/// The cache trusts neither an edited `asset.json` nor a folder holding files it does not list:
/// both are rebuilt, with the reason in the report; an untouched folder stays cached.
#[test]
fn an_edited_description_or_a_stray_file_is_rebuilt_not_trusted() {
    let dir = tempfile::tempdir().unwrap();
    let m = Manifest::parse(SCENE, Path::new("scene.toml")).unwrap();
    let first = run_scene(&m, &options(dir.path())).unwrap();
    assert!(first.ok(), "{}", first.table());
    let pear = dir.path().join("pear/parallax");
    // An edit of the description's metadata (a value a renderer would read).
    let desc_path = pear.join(DESCRIPTION_FILE);
    let text = std::fs::read_to_string(&desc_path).unwrap();
    let edited = text.replacen(
        "\"representation\": \"parallax\"",
        "\"representation\": \"parallax\" ",
        1,
    );
    let mut value: serde_json::Value = serde_json::from_str(&edited).unwrap();
    value["metadata"]["edited_by_hand"] = true.into();
    std::fs::write(&desc_path, serde_json::to_vec_pretty(&value).unwrap()).unwrap();
    // A stray file beside the chair's octree.
    let chair = dir.path().join("chair/octree");
    std::fs::write(chair.join("notes.txt"), "mine").unwrap();
    let second = run_scene(&m, &options(dir.path())).unwrap();
    assert!(second.ok(), "{}", second.table());
    let note = |asset: &str| {
        let o = second.outcomes.iter().find(|o| o.asset == asset).unwrap();
        assert_eq!(o.outcome, Outcome::Built, "{asset}: {o:?}");
        o.cache_note.clone().unwrap_or_default()
    };
    assert!(
        note("pear").contains("altered") || note("pear").contains("hash"),
        "{}",
        note("pear")
    );
    assert!(note("chair").contains("notes.txt"), "{}", note("chair"));
    // Rebuilt folders are altrep's again: a third run caches both.
    let third = run_scene(&m, &options(dir.path())).unwrap();
    assert!(
        third.outcomes.iter().all(|o| o.outcome == Outcome::Cached),
        "{}",
        third.table()
    );
}
