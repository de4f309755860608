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
        .arg(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("prose"), "{err}");
}
