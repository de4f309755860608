//! `altrep report` (run time against error) and `altrep precompute --profile` (per-stage times):
//! the files a quick sweep writes, their numbers and axis labels; the stage table's consistency.
//! No timed assertion: times are only checked to be finite, non-negative and to add up.

use std::path::Path;
use std::process::Command;

use altrep::pipeline::{Manifest, RunOptions, run_scene};
use altrep::report::{REPRESENTATIONS, ReportParams, run, write};

fn altrep() -> Command {
    Command::new(env!("CARGO_BIN_EXE_altrep"))
}

/// The fields of one CSV line (double quotes around fields holding commas or quotes).
fn split_csv(line: &str) -> Vec<String> {
    let mut fields = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                fields.last_mut().unwrap().push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => fields.push(String::new()),
            (c, _) => fields.last_mut().unwrap().push(c),
        }
    }
    fields
}

/// `text` as an SVG writer escapes it inside an element.
fn svg_text(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}

#[test]
fn quick_report_writes_csv_json_svg_and_png_with_finite_numbers_and_labelled_axes() {
    let report = run(
        &ReportParams {
            quick: true,
            ..ReportParams::default()
        },
        false,
    )
    .unwrap();
    assert_eq!(report.representations.len(), REPRESENTATIONS.len());
    let dir = tempfile::tempdir().unwrap();
    let written = write(&report, dir.path()).unwrap();
    for f in ["report.json", "report.csv", "report.md"] {
        assert!(written.contains(&dir.path().join(f)), "{f} not written");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    let csv = std::fs::read_to_string(dir.path().join("report.csv")).unwrap();
    let mut csv_rows = csv.lines();
    assert_eq!(csv_rows.next(), Some(altrep::report::CSV_HEADER));
    let mut rows = 0;
    for line in csv_rows {
        rows += 1;
        // Numeric columns 3..=7: empty or a finite number.
        let cols = split_csv(line);
        assert_eq!(cols.len(), 9, "{line}");
        for c in &cols[3..8] {
            if !c.is_empty() {
                let v: f64 = c.parse().unwrap_or_else(|_| panic!("{c} in {line}"));
                assert!(v.is_finite(), "{line}");
            }
        }
    }
    for r in &report.representations {
        assert!(r.points.len() >= 2, "{}: {} points", r.name, r.points.len());
        let mut plotted = 0;
        for p in &r.points {
            for v in [p.precompute_ms, p.bytes, p.steps, p.psnr_db, p.error]
                .into_iter()
                .flatten()
            {
                assert!(v.is_finite() && v >= 0.0, "{}: {p:?}", r.name);
            }
            if r.error_of(p).is_some() && r.panels.iter().any(|&c| p.cost(c).is_some()) {
                plotted += 1;
            }
        }
        assert!(plotted >= 2, "{}: {plotted} plottable points", r.name);
        assert!(
            json["representations"]
                .as_array()
                .unwrap()
                .iter()
                .any(|j| j["name"] == r.name)
        );
        let own_csv = std::fs::read_to_string(dir.path().join(format!("{}.csv", r.name))).unwrap();
        assert_eq!(own_csv.lines().count(), r.points.len() + 1, "{}", r.name);
        // The SVG names both axes of every panel and the marked operating points.
        let svg = std::fs::read_to_string(dir.path().join(format!("{}.svg", r.name))).unwrap();
        assert!(svg.starts_with("<svg"), "{}", r.name);
        assert!(
            svg.contains(&svg_text(&r.error_label)),
            "{}: no y label",
            r.name
        );
        for &c in &r.panels {
            assert!(
                svg.contains(&svg_text(&r.cost_label(c))),
                "{}: no x label {}",
                r.name,
                r.cost_label(c)
            );
        }
        for p in r.points.iter().filter_map(|p| p.operating_point.as_ref()) {
            assert!(
                svg.contains(&svg_text(p)),
                "{}: operating point {p} not drawn",
                r.name
            );
        }
        // The PNG decodes at the plot's size and has drawn pixels (axes, curves, text).
        let png = image::open(dir.path().join(format!("{}.png", r.name)))
            .unwrap()
            .to_rgb8();
        assert_eq!(
            (png.width(), png.height()),
            altrep::report::plot::size(r),
            "{}",
            r.name
        );
        let dark = png
            .pixels()
            .filter(|p| p.0.iter().all(|&c| c < 100))
            .count();
        assert!(dark > 1000, "{}: {dark} dark pixels", r.name);
    }
    assert_eq!(
        rows,
        report
            .representations
            .iter()
            .map(|r| r.points.len())
            .sum::<usize>()
    );
    // The source's operating points are marked where the quick sweep reaches them.
    let fit = &report.representations[0];
    assert!(
        fit.points
            .iter()
            .any(|p| p.label == "15×8×16" && p.operating_point.is_some())
    );
    let cyl = report
        .representations
        .iter()
        .find(|r| r.name == "cylinder")
        .unwrap();
    assert!(cyl.points.iter().any(|p| p.operating_point.is_some()));
}

#[test]
fn report_command_writes_its_files_and_rejects_an_unknown_representation() {
    let dir = tempfile::tempdir().unwrap();
    let out = altrep()
        .args([
            "report",
            "--quick",
            "--only",
            "fit,pyramid",
            "--json",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(printed["representations"].as_array().unwrap().len(), 2);
    for f in [
        "fit.svg",
        "fit.png",
        "fit.csv",
        "pyramid.svg",
        "pyramid.png",
        "report.json",
    ] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
    let bad = altrep()
        .args(["report", "--quick", "--only", "voxels", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown representation 'voxels'"));
    // A rerun with fewer sweeps leaves no file of the older run's other sweeps; a file the
    // report does not write stays.
    std::fs::write(dir.path().join("notes.txt"), "mine").unwrap();
    let again = altrep()
        .args(["report", "--quick", "--only", "fit", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(again.status.success());
    assert!(dir.path().join("fit.png").is_file());
    assert!(!dir.path().join("pyramid.png").exists());
    assert_eq!(
        std::fs::read(dir.path().join("notes.txt")).unwrap(),
        b"mine"
    );
    // A report.md of the user's, in a folder the report never wrote to, is refused before any
    // sweep and left as it is.
    let theirs = tempfile::tempdir().unwrap();
    std::fs::write(theirs.path().join("report.md"), "my notes").unwrap();
    let refused = altrep()
        .args(["report", "--quick", "--only", "fit", "--out"])
        .arg(theirs.path())
        .output()
        .unwrap();
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        err.contains("report.md") && err.contains("choose another --out"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(theirs.path().join("report.md")).unwrap(),
        b"my notes"
    );
    assert_eq!(std::fs::read_dir(theirs.path()).unwrap().count(), 1);
}

const SCENE: &str = r#"
[[asset]]
name = "pear"
shape = "pear"
[asset.needs]
screen_px = [4, 16]
[asset.parallax]
views = 4
size = 16
bounds = ["zminmax", "best_c"]
[asset.cylinder]
columns = 64
rows = 16
[asset.octree]
resolution = 16

[[asset]]
name = "ground"
test_texture = { size = 64, seed = 1 }
[asset.needs]
screen_px = [4, 32]
[asset.pyramid]
"#;

fn options(out: &Path, profile: bool) -> RunOptions {
    RunOptions {
        profile,
        ..RunOptions::new(out)
    }
}

#[test]
fn profile_stages_are_finite_non_negative_and_add_up_to_at_most_the_wall_time() {
    let dir = tempfile::tempdir().unwrap();
    let m = Manifest::parse(SCENE, Path::new("scene.toml")).unwrap();
    let s = run_scene(&m, &options(dir.path(), true)).unwrap();
    assert!(s.ok(), "{}", s.table());
    let t = s.profile.as_ref().expect("--profile gives a table");
    assert_eq!(t.rows.len(), s.outcomes.len());
    for r in &t.rows {
        let sum: f64 = r.stages.values().sum();
        for (name, v) in &r.stages {
            assert!(v.is_finite() && *v >= 0.0, "{} {name} = {v}", r.asset);
        }
        assert!(
            sum <= r.total_seconds,
            "{}/{}: {sum} > {}",
            r.asset,
            r.representation,
            r.total_seconds
        );
        assert!(r.other_seconds >= 0.0);
    }
    let stage_sum: f64 = t.stage_sums.values().sum();
    assert!(stage_sum <= t.total_seconds);
    // Assets run one at a time under --profile: their wall times fit in the run's. Each asset's
    // representations run concurrently inside its own wall time: every row fits in it.
    let names: Vec<&str> = t.assets.iter().map(|a| a.asset.as_str()).collect();
    let mut expected: Vec<&str> = s.outcomes.iter().map(|o| o.asset.as_str()).collect();
    expected.dedup();
    assert_eq!(names, expected);
    let asset_sum: f64 = t.assets.iter().map(|a| a.total_seconds).sum();
    assert!(
        asset_sum <= s.wall_seconds,
        "{asset_sum} > {}",
        s.wall_seconds
    );
    for a in &t.assets {
        assert!(
            0.0 <= a.load_seconds
                && a.load_seconds <= a.files_seconds
                && a.files_seconds <= a.total_seconds,
            "{a:?}"
        );
        // The pear's parallax and cylinder cast rays, so its geometry prepared them (after the
        // load, before its files were done); the texture has no geometry.
        match (a.asset.as_str(), a.rays_seconds) {
            ("pear", Some(r)) => {
                assert!(0.0 <= r && a.load_seconds + r <= a.files_seconds, "{a:?}")
            }
            ("ground", None) => {}
            _ => panic!("ray set-up of {a:?}"),
        }
        for r in t.rows.iter().filter(|r| r.asset == a.asset) {
            assert!(
                r.total_seconds <= a.total_seconds,
                "{}/{}: {} > {}",
                r.asset,
                r.representation,
                r.total_seconds,
                a.total_seconds
            );
        }
    }
    // Rows in manifest order, whatever order the concurrent builds ended in.
    let rows: Vec<(&str, &str)> = t
        .rows
        .iter()
        .map(|r| (r.asset.as_str(), r.representation.as_str()))
        .collect();
    let outcomes: Vec<(&str, &str)> = s
        .outcomes
        .iter()
        .map(|o| (o.asset.as_str(), o.representation.as_str()))
        .collect();
    assert_eq!(rows, outcomes);
    for stage in [
        "plan",
        "capture",
        "quantisation",
        "bounds",
        "voxelise",
        "octree",
        "pyramids",
        "writing",
        "measure",
    ] {
        assert!(
            t.stage_names.iter().any(|n| n == stage),
            "no {stage} in {:?}",
            t.stage_names
        );
    }
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(md.contains("Per-stage profile") && md.contains("| pear | parallax |"));
    assert!(md.contains("| asset | load | ray set-up | mesh to files | total |"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(
        json["profile"]["rows"].as_array().unwrap().len(),
        t.rows.len()
    );

    // Without --profile: no table, nothing in the report.
    let again = run_scene(&m, &options(&dir.path().join("plain"), false)).unwrap();
    assert!(again.profile.is_none());
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("plain/report.json")).unwrap(),
    )
    .unwrap();
    assert!(json.get("profile").is_none());
}

#[test]
fn precompute_profile_prints_the_stage_table() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let out = altrep()
        .arg("precompute")
        .arg(&scene)
        .arg("--profile")
        // The stage table is the point here, not the scene's quality (its pyramid measures
        // below the default 20 dB target).
        .arg("--allow-below-quality")
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Per-stage profile"), "{text}");
    assert!(
        text.contains("| asset | representation | plan | capture |"),
        "{text}"
    );
    assert!(text.contains("| ground | pyramid |"), "{text}");
}
