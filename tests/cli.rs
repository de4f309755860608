//! End-to-end: the `altrep` binary's main job and its handling of bad input.

use std::process::Command;

fn altrep() -> Command {
    Command::new(env!("CARGO_BIN_EXE_altrep"))
}

#[test]
fn demo_writes_its_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = altrep()
        .args(["demo", "--quick", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "demo failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    let captures = report["captures"]["results"]
        .as_array()
        .expect("captures section");
    assert!(captures.len() >= 3, "at least truck, pear and tree");
    for shape in ["truck", "pear", "tree"] {
        assert!(
            captures.iter().any(|c| c["shape"] == shape),
            "{shape} missing"
        );
        assert!(
            dir.path()
                .join(format!("captures/{shape}_truth.png"))
                .exists()
        );
    }
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(md.contains("| truck |"));
    // The bundled scene shows every representation of the library's one list: each has at
    // least one asset folder in the demo's precomputed scene.
    let scene: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("scene/report.json")).unwrap(),
    )
    .unwrap();
    let text = scene.to_string();
    for name in altrep::representation::NAMES {
        assert!(
            text.contains(&format!("\"representation\":\"{name}\"")),
            "the demo scene has no {name} asset"
        );
    }
    // The user's own folder named like a section, where the demo never ran, is refused before
    // any work and left as it is.
    let theirs = tempfile::tempdir().unwrap();
    std::fs::create_dir(theirs.path().join("captures")).unwrap();
    std::fs::write(theirs.path().join("captures/holiday.png"), "mine").unwrap();
    let refused = altrep()
        .args(["demo", "--quick", "--out"])
        .arg(theirs.path())
        .output()
        .unwrap();
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        err.contains("captures") && err.contains("choose another --out"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(theirs.path().join("captures/holiday.png")).unwrap(),
        b"mine"
    );
    assert_eq!(std::fs::read_dir(theirs.path()).unwrap().count(), 1);
}

#[test]
fn capture_writes_views_with_depth_and_normals() {
    let dir = tempfile::tempdir().unwrap();
    let out = altrep()
        .args([
            "capture", "--shape", "truck", "--views", "3", "--size", "16", "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("rays/s"));
    for k in 0..3 {
        for kind in ["color", "albedo", "normal", "depth16"] {
            let p = dir.path().join(format!("view{k:03}.{kind}.png"));
            assert!(p.exists(), "{} missing", p.display());
        }
    }
    let depth = image::open(dir.path().join("view000.depth16.png")).unwrap();
    assert!(
        matches!(depth, image::DynamicImage::ImageLuma16(_)),
        "depth is 16-bit grey"
    );
    // capture.json names the files that were renamed into --out (relative to its folder), and
    // each view's coverage is the share of defined depths in its depth file.
    let desc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("capture.json")).unwrap())
            .unwrap();
    let files = desc["files"].as_array().unwrap();
    assert_eq!(files.len(), 3);
    for (k, f) in files.iter().enumerate() {
        for kind in ["color", "albedo", "normal", "depth16"] {
            let name = f[kind].as_str().unwrap();
            assert_eq!(name, format!("view{k:03}.{kind}.png"));
            assert!(dir.path().join(name).exists(), "{name} missing");
        }
        let depth = image::open(dir.path().join(f["depth16"].as_str().unwrap()))
            .unwrap()
            .into_luma16();
        let defined = depth.pixels().filter(|p| p.0[0] != 0).count();
        assert!(defined > 0, "view {k} sees nothing of the truck");
        approx::assert_relative_eq!(
            f["coverage"].as_f64().unwrap(),
            defined as f64 / (16.0 * 16.0),
            max_relative = 1e-12
        );
    }
}

#[test]
fn bad_input_is_reported_not_panicked() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "capture".into(),
                "--mesh".into(),
                dir.path().join("missing.obj").display().to_string(),
            ],
            "missing.obj",
        ),
        (
            vec![
                "capture".into(),
                "--shape".into(),
                "truck".into(),
                "--size".into(),
                "-5".into(),
            ],
            "--size",
        ),
        (
            vec![
                "capture".into(),
                "--shape".into(),
                "truck".into(),
                "--size".into(),
                "0".into(),
            ],
            "--size",
        ),
        (
            vec![
                "capture".into(),
                "--shape".into(),
                "truck".into(),
                "--views".into(),
                "0".into(),
            ],
            "--views",
        ),
        (
            vec!["capture".into(), "--shape".into(), "teapot2".into()],
            "unknown shape",
        ),
    ];
    for (args, needle) in cases {
        let out = altrep()
            .args(&args)
            .arg("--out")
            .arg(dir.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
        assert!(
            err.contains(needle),
            "{args:?}: error does not name {needle}: {err}"
        );
    }
    // Not OBJ at all.
    let p = dir.path().join("prose.obj");
    std::fs::write(&p, "Dear reader, this is no mesh.\n").unwrap();
    let out = altrep()
        .args(["capture", "--mesh"])
        .arg(&p)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("prose"), "{err}");
}

/// The commands that take `--mesh` read glTF too, with `--up` and `--node`; what the file holds
/// and altrep does not read is printed; a bad axis or node is an error naming it.
#[test]
fn capture_reads_gltf_with_an_up_axis_and_a_node() {
    use altrep_data_gen::gltf_write::TestGltf;
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("box.glb");
    std::fs::write(&glb, TestGltf::textured_box(4).to_glb().unwrap()).unwrap();
    let run = |extra: &[&str]| {
        let o = altrep()
            .args(["capture", "--views", "2", "--size", "16", "--mesh"])
            .arg(&glb)
            .arg("--out")
            .arg(dir.path().join("out"))
            .args(extra)
            .output()
            .unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let (ok, err) = run(&["--up", "z", "--node", "box"]);
    assert!(ok, "{err}");
    assert!(dir.path().join("out").read_dir().unwrap().count() > 0);
    let (ok, err) = run(&["--up", "q"]);
    assert!(!ok && err.contains("unknown up axis 'q'"), "{err}");
    let (ok, err) = run(&["--node", "tree"]);
    assert!(!ok && err.contains("no node named 'tree'"), "{err}");
}

/// `altrep slices --images DIR` replaces DIR whole, so only a folder it wrote (its images.json
/// lists every file): a rerun replaces its images, the user's file inside it or a folder of the
/// user's is refused before any work and left as it is.
#[test]
fn slice_images_replace_only_a_folder_they_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let images = dir.path().join("images");
    let run = |at: &std::path::Path| {
        altrep()
            .args([
                "slices",
                "--size",
                "8",
                "--tiles",
                "grass",
                "--angles",
                "0",
                "--distances",
                "1",
                "--one-side",
                "--no-direction-table",
                "--truth-steps",
                "2",
                "--images",
            ])
            .arg(at)
            .output()
            .unwrap()
    };
    for _ in 0..2 {
        let o = run(&images);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // No view lies at 70° or more: the grazing gains have nothing to average, and the
        // table says so rather than printing NaN.
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(
            stdout.contains("| grass |") && !stdout.contains("NaN"),
            "{stdout}"
        );
        assert!(images.join("images.json").is_file());
        assert!(images.join("grass-0deg-y1-vs-truth.png").is_file());
    }
    std::fs::write(images.join("notes.txt"), "mine").unwrap();
    let theirs = dir.path().join("theirs");
    std::fs::create_dir(&theirs).unwrap();
    std::fs::write(theirs.join("holiday.png"), "mine").unwrap();
    for (at, kept) in [
        (&images, images.join("notes.txt")),
        (&theirs, theirs.join("holiday.png")),
    ] {
        let o = run(at);
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("replaces only a folder it wrote"), "{err}");
        assert_eq!(std::fs::read(&kept).unwrap(), b"mine");
    }
    // Nothing was left beside the folders (no staging folder).
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["images", "theirs"]);
}
