//! Cylindrical textures against the ray-cast ground truth (docs/design.md §6).

use altrep::cylinder::{
    CylinderRender, CylinderRenderParams, CylindricalTexture, DrawOrder, ExactMethod, RadiusModel,
    render_exact,
};
use altrep::data_gen::{
    CylinderParams, Light, RgbaImage, Shape, TruthParams, render_truth, scene_shape,
};
use altrep::metrics::{psnr, silhouette_iou};
use altrep_data_gen::Supersample;

/// Albedo prefilter of the captures (3 × 3 rays per texel, the library default).
const PREFILTER: usize = 3;

fn texture(shape: &dyn Shape) -> CylindricalTexture {
    CylindricalTexture::capture(shape, &CylinderParams::default(), PREFILTER).unwrap()
}

fn truth(shape: &dyn Shape, p: &CylinderRenderParams) -> RgbaImage {
    render_truth(
        shape,
        &TruthParams {
            angle: p.angle,
            width: p.width,
            height: p.height,
            supersample: p.supersample,
            light: p.light,
            cylinder: Default::default(),
        },
    )
    .unwrap()
}

fn params(angle: f64, size: usize, supersample: usize) -> CylinderRenderParams {
    CylinderRenderParams {
        angle,
        width: size,
        height: size,
        supersample: Supersample::of(supersample),
        light: Light::default(),
    }
}

const EXACT: [ExactMethod; 4] = [
    ExactMethod::Mesh,
    ExactMethod::Direct(DrawOrder::BackToFront, RadiusModel::General),
    ExactMethod::Direct(DrawOrder::FrontToBack, RadiusModel::General),
    ExactMethod::Inverse(RadiusModel::General),
];

/// A sphere on the axis (radius 0.8, striped by azimuth) is star-shaped: every exact renderer
/// reconstructs it to ≥ 40 dB against the 4 × 4 supersampled ground truth at 64² pixels
/// (measured: 41.8–43.8 dB, IoU 1.0000; again 41.82–43.75 dB on 2026-12-04; without the albedo
/// prefilter 38.6–42.0 dB).
#[test]
fn sphere_on_axis_all_exact_renderers_reach_40_db() {
    let shape = scene_shape("sphere").unwrap();
    let tex = texture(&shape);
    for angle in [0.0, 0.7, 2.9] {
        let p = params(angle, 64, 4);
        let gt = truth(&shape, &p);
        for m in EXACT {
            let r = render_exact(&tex, m, &p).unwrap();
            let db = psnr(&r.image, &gt).unwrap();
            let iou = silhouette_iou(&r.image, &gt, 0.5).unwrap();
            eprintln!("{} at α = {angle}: {db:.2} dB, IoU {iou:.4}", m.name());
            assert!(db >= 40.0, "{} at α = {angle}: {db:.2} dB", m.name());
            assert!(iou > 0.995, "{} at α = {angle}: IoU {iou:.4}", m.name());
        }
    }
}

/// Wrapped difference of two columns, in texels.
fn column_distance(a: f64, b: f64, columns: usize) -> f64 {
    let l = columns as f64;
    let d = (a - b).rem_euclid(l);
    d.min(l - d)
}

/// Sub-samples covered by `a` but not `b` that have no sub-sample covered by `b` within `reach`
/// sub-samples (Chebyshev distance).
fn coverage_outliers(a: &CylinderRender, b: &CylinderRender, reach: i64) -> usize {
    let (w, h) = (a.sub_width as i64, a.sub_height as i64);
    let covered = |r: &CylinderRender, i: i64, j: i64| {
        i >= 0 && j >= 0 && i < w && j < h && r.fragments[(j * w + i) as usize].is_some()
    };
    let mut outliers = 0;
    for j in 0..h {
        for i in 0..w {
            if covered(a, i, j) && !covered(b, i, j) {
                let near = (-reach..=reach)
                    .any(|dj| (-reach..=reach).any(|di| covered(b, i + di, j + dj)));
                outliers += usize::from(!near);
            }
        }
    }
    outliers
}

/// On the truck (parts off the axis, negative radii, holes), direct warping draws what the mesh
/// reference draws to within one texel: where both cover a sub-sample they read columns at most
/// one texel apart (measured: ≥ 99.8 % of sub-samples; the rest are ties where an inner and an
/// outer surface meet), and every sub-sample covered by only one of them lies within one pixel of
/// the other's coverage (measured: within one sub-sample, but 2–4 of ~10⁴).
#[test]
fn truck_direct_warping_matches_the_mesh_within_one_texel() {
    let shape = scene_shape("truck").unwrap();
    let tex = texture(&shape);
    let k = 3;
    for angle in [0.0, 0.5, 2.2, 3.5, 5.0] {
        let p = params(angle, 64, k);
        let mesh = render_exact(&tex, ExactMethod::Mesh, &p).unwrap();
        for order in [DrawOrder::BackToFront, DrawOrder::FrontToBack] {
            let direct =
                render_exact(&tex, ExactMethod::Direct(order, RadiusModel::General), &p).unwrap();
            let (mut both, mut far) = (0usize, 0usize);
            for (a, b) in mesh.fragments.iter().zip(&direct.fragments) {
                if let (Some(a), Some(b)) = (a, b) {
                    both += 1;
                    far += usize::from(column_distance(a.column, b.column, tex.columns()) > 1.0);
                }
            }
            assert!(both > 5000);
            assert!(
                (far as f64) < 0.002 * both as f64,
                "α = {angle} {order:?}: {far} of {both} sub-samples read columns > 1 texel apart"
            );
            for (a, b) in [(&mesh, &direct), (&direct, &mesh)] {
                let outliers = coverage_outliers(a, b, k as i64);
                assert!(
                    outliers <= 4,
                    "α = {angle} {order:?}: {outliers} coverage outliers"
                );
            }
        }
    }
}

/// The three exact warps are one algorithm seen three ways: inverse warping and direct warping in
/// both orders give identical fragments, so their costs can be compared on equal terms.
#[test]
fn inverse_and_direct_warping_agree_exactly() {
    let shape = scene_shape("tree").unwrap();
    let tex = texture(&shape);
    let p = params(1.1, 48, 2);
    let inv = render_exact(&tex, ExactMethod::Inverse(RadiusModel::General), &p).unwrap();
    for m in &EXACT[1..3] {
        let r = render_exact(&tex, *m, &p).unwrap();
        let same = inv
            .fragments
            .iter()
            .zip(&r.fragments)
            .filter(|(a, b)| match (a, b) {
                (Some(a), Some(b)) => (a.column - b.column).abs() < 1e-9,
                (None, None) => true,
                _ => false,
            })
            .count();
        assert!(
            same as f64 >= 0.999 * inv.fragments.len() as f64,
            "{}: {same} of {}",
            m.name(),
            inv.fragments.len()
        );
    }
    assert!(inv.mean_steps() > 1.0);
}

/// No seam at α = 0: the angle just below 0 and the same angle plus 2π give the same image, and
/// the images at and on both sides of 0 are continuous.
#[test]
fn no_seam_at_alpha_zero_for_exact_renderers() {
    let shape = scene_shape("pear").unwrap();
    let tex = texture(&shape);
    let eps = 1e-3;
    for m in [
        ExactMethod::Mesh,
        ExactMethod::Inverse(RadiusModel::General),
    ] {
        let below = render_exact(&tex, m, &params(-eps, 48, 2)).unwrap();
        let wrapped = render_exact(&tex, m, &params(std::f64::consts::TAU - eps, 48, 2)).unwrap();
        let at = render_exact(&tex, m, &params(0.0, 48, 2)).unwrap();
        let above = render_exact(&tex, m, &params(eps, 48, 2)).unwrap();
        assert!(
            psnr(&below.image, &wrapped.image).unwrap() > 60.0,
            "{}",
            m.name()
        );
        for img in [&below, &above] {
            let db = psnr(&img.image, &at.image).unwrap();
            assert!(db > 40.0, "{}: {db:.1} dB across α = 0", m.name());
        }
    }
}

/// On the pear at the source's 15 × 8 × 16 grid (defaults: silhouette mask, fit where the offset
/// is continuous, 16-bit coefficients), 4 angles, 48² pixels with 3 × 3 sub-samples: the offset
/// error and the hybrid image against exact inverse warping, asserted at what was measured
/// (stated per line, remeasured 2026-12-04) with a margin of about 10 %. The error concentrates near silhouettes and
/// occlusion jumps: away from them the fitted offset is within a texel almost everywhere.
#[test]
fn pear_offset_error_and_hybrid_psnr_at_15x8x16() {
    use altrep::cylinder::{EvalParams, evaluate};
    let shape = scene_shape("pear").unwrap();
    let params = EvalParams {
        angles: 4,
        size: 48,
        ..EvalParams::default()
    };
    assert_eq!(params.offset.cells, [15, 8, 16]);
    let report = evaluate(&shape, &params).unwrap();
    let row = |m: &str| report.row(m).unwrap();
    let fitted = row("fitted");
    for m in ["fitted", "hybrid-m2", "hybrid-m4", "inverse"] {
        let r = row(m);
        eprintln!(
            "{m}: offset rms {:.3} p99 {:.3}, away rms {:.3} p99 {:.3}, near rms {:.3} p99 {:.3}; {:.2} dB vs inverse, {:.2} dB vs truth",
            r.offset.rms,
            r.offset.p99,
            r.offset_away.rms,
            r.offset_away.p99,
            r.offset_near.rms,
            r.offset_near.p99,
            r.psnr_vs_inverse_db,
            r.psnr_db
        );
    }
    // Measured: RMS 1.17, p99 4.46 texels over all defined sub-samples (2026-12-04: 1.172, 4.447).
    assert!(fitted.offset.rms <= 1.3, "{:?}", fitted.offset);
    assert!(fitted.offset.p99 <= 5.0, "{:?}", fitted.offset);
    // Measured: away RMS 0.21, p99 0.99; near RMS 1.78, p99 7.45 (2026-12-04: 0.210, 0.998;
    // 1.781, 7.527).
    assert!(fitted.offset_away.rms <= 0.25, "{:?}", fitted.offset_away);
    assert!(fitted.offset_away.p99 <= 1.1, "{:?}", fitted.offset_away);
    assert!(fitted.offset_near.rms <= 2.0, "{:?}", fitted.offset_near);
    assert!(fitted.offset_near.p99 <= 8.2, "{:?}", fitted.offset_near);
    assert!(fitted.offset_near.rms > 5.0 * fitted.offset_away.rms);
    // Measured against exact inverse warping: plain 42.23 dB, m = 2 42.53 dB, m = 4 42.90 dB
    // (2026-12-04: 42.10, 42.40, 42.76 dB); with m = 4 more than 99 % of the sub-samples read
    // the exact column (p99 = 0).
    assert!(
        fitted.psnr_vs_inverse_db >= 41.5,
        "{}",
        fitted.psnr_vs_inverse_db
    );
    assert!(row("hybrid-m2").psnr_vs_inverse_db >= 41.8);
    let m4 = row("hybrid-m4");
    assert!(m4.psnr_vs_inverse_db >= 42.2, "{}", m4.psnr_vs_inverse_db);
    assert!(m4.offset.p99 <= 0.05, "{:?}", m4.offset);
    assert!(m4.offset_away.rms <= 0.05, "{:?}", m4.offset_away);
    // The exact renderers it approximates: 33.91 dB against the ground truth (2026-12-04: 33.91;
    // the fitted offset 33.18).
    assert!(row("inverse").psnr_db >= 33.0);
    assert!(fitted.psnr_db >= row("inverse").psnr_db - 1.0);
}

/// The fitted offset has no seam at α = 0: its angle axis is periodic, so the offsets fetched
/// just below and just above 0 agree and the images at 2π − ε and −ε are the same.
#[test]
fn no_seam_at_alpha_zero_for_fitted_offsets() {
    use altrep::cylinder::{OffsetMode, OffsetParams, OffsetTexture};
    let shape = scene_shape("pear").unwrap();
    let tex = texture(&shape);
    let off = OffsetTexture::fit(&tex, &OffsetParams::default()).unwrap();
    let eps = 1e-4;
    let mut worst = 0.0f64;
    for x in [-0.5, -0.2, 0.0, 0.3, 0.55] {
        for v in [10.0, 30.5, 50.0] {
            let (below, _) = off.offset(x, v, -eps).unwrap();
            let (above, _) = off.offset(x, v, eps).unwrap();
            let (wrapped, _) = off.offset(x, v, std::f64::consts::TAU - eps).unwrap();
            assert!((below - wrapped).abs() < 1e-9);
            worst = worst.max((below - above).abs());
        }
    }
    assert!(worst < 0.05, "offsets jump by {worst} texels across α = 0");
    for mode in [OffsetMode::Plain, OffsetMode::Hybrid { steps: 2 }] {
        let render = |a: f64| off.render(&tex, mode, 1.0, &params(a, 48, 2)).unwrap();
        let (below, above) = (render(-eps), render(eps));
        let wrapped = render(std::f64::consts::TAU - eps);
        assert!(psnr(&below.image, &wrapped.image).unwrap() > 60.0);
        assert!(psnr(&below.image, &above.image).unwrap() > 40.0);
    }
}

/// The chair's known failure, stated rather than hidden: its four legs stand parallel to the
/// axis, two by two in line with it, so a column ray meets only a leg's outer face (about 3
/// columns of 256) and never the faces that turn toward the other legs. Exact inverse warping of
/// its texture covers (measured over 6 angles) only 34–67 % of the true coverage in the rows of
/// the legs, against 83–92 % in the rows of the seat and back, and the image stays below 24 dB.
#[test]
fn chair_legs_in_line_with_the_axis_are_lost() {
    let shape = scene_shape("chair").unwrap();
    let tex = texture(&shape);
    let (mut legs, mut legs_true, mut top, mut top_true) = (0.0, 0.0, 0.0, 0.0);
    for angle in [0.0, 0.3, std::f64::consts::FRAC_PI_4, 1.2, 2.0, 3.5] {
        let p = params(angle, 64, 3);
        let gt = truth(&shape, &p);
        let r = render_exact(&tex, ExactMethod::Inverse(RadiusModel::General), &p).unwrap();
        assert!(psnr(&r.image, &gt).unwrap() < 24.0);
        for j in 0..64 {
            // Pixel rows below y = 0.8 hold only legs (the seat starts at y = 0.85).
            let below_seat = 2.0 - (j as f64 + 0.5) / 32.0 < 0.8;
            for i in 0..64 {
                let (t, c) = (gt.get(i, j)[3] as f64, r.image.get(i, j)[3] as f64);
                if below_seat {
                    (legs, legs_true) = (legs + c.min(t), legs_true + t);
                } else {
                    (top, top_true) = (top + c.min(t), top_true + t);
                }
            }
        }
    }
    let (legs, top) = (legs / legs_true, top / top_true);
    // Measured: legs 0.400 of the true coverage, seat and back 0.909.
    assert!(legs < 0.5, "legs covered {legs:.3}");
    assert!(top > 0.85, "seat and back covered {top:.3}");
}

/// `altrep cylinder` end to end: the JSON holds one object per renderer with the documented keys;
/// bad input is a message and a failure, not a panic.
#[test]
fn cylinder_command_writes_its_json() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("cyl.json");
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_altrep"))
            .arg("cylinder")
            .args(args)
            .output()
            .unwrap()
    };
    let out = run(&[
        "--shape",
        "sphere",
        "--angles",
        "1",
        "--size",
        "16",
        "--grid",
        "8x4x8",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = v["renderers"].as_array().unwrap();
    let methods: Vec<&str> = rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
    for m in [
        "mesh",
        "direct-btf",
        "inverse",
        "fitted",
        "hybrid-m1",
        "hybrid-m2",
        "hybrid-m4",
    ] {
        assert!(methods.contains(&m), "{m} missing from {methods:?}");
    }
    for r in rows {
        for key in [
            "method",
            "psnr_db",
            "iou",
            "offset_rms_texels",
            "offset_p99_texels",
            "mean_steps",
            "precompute_ms",
            "bytes",
        ] {
            assert!(r.get(key).is_some(), "{key} missing in {r}");
        }
    }
    for bad in [
        &["--shape", "sphere", "--grid", "0x8x16"][..],
        &["--shape", "no-such-shape"],
        &["--mesh", "/no/such/file.obj"],
    ] {
        let out = run(bad);
        assert!(!out.status.success(), "{bad:?} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{bad:?}: {err}");
    }
}

/// The flat cut-out the coverage check must refuse: a 2 × 2 square in the plane z = 0, which holds
/// the axis.
fn flat_cut_out() -> altrep::data_gen::Mesh {
    altrep::data_gen::Mesh::from_raw_triangles(
        "flat",
        vec![
            [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0]],
            [[-1.0, 0.0, 0.0], [1.0, 2.0, 0.0], [-1.0, 2.0, 0.0]],
        ],
        &Default::default(),
    )
    .unwrap()
}

/// A horizontal square (y = 0): every horizontal view sees it edge-on.
fn horizontal_square() -> altrep::data_gen::Mesh {
    altrep::data_gen::Mesh::from_raw_triangles(
        "horizontal",
        vec![
            [[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0]],
            [[-1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]],
        ],
        &Default::default(),
    )
    .unwrap()
}

/// A flat cut-out whose plane holds the axis is met by every radial capture ray at the axis
/// only: its texture is almost fully "defined" (radius 0) yet reproduces almost none of the
/// true silhouette (measured 0.0 %), and the capture rays hold almost none of its visible
/// surface (they graze it). The check refuses it with a typed error that names the cause and
/// the alternative, from the library, from `evaluate` and from `altrep cylinder`.
#[test]
fn flat_cut_out_holding_the_axis_is_refused() {
    use altrep::cylinder::{CoverageParams, CylinderError, EvalParams, check_coverage, coverage};
    let shape = flat_cut_out();
    let tex = texture(&shape);
    assert!(tex.coverage() > 0.9, "the texture looks defined");
    let c = coverage(&shape, &tex, &CoverageParams::default()).unwrap();
    assert!(c.share < 0.05, "share {}", c.share);
    assert_eq!(c.per_angle.len(), 8);
    assert!(c.per_angle.iter().all(|a| a.truth_px > 10.0));
    let err = check_coverage(&shape, tex.cylinder(), &CoverageParams::default()).unwrap_err();
    let CylinderError::NotRepresentable { share, .. } = err else {
        panic!("{err}")
    };
    assert!(share < 0.1, "held share {share}");
    let msg = err.to_string();
    assert!(
        msg.contains("cannot represent") && msg.contains("parallax"),
        "{msg}"
    );
    let err = altrep::cylinder::evaluate(&shape, &EvalParams::default()).unwrap_err();
    assert!(
        matches!(err, CylinderError::NotRepresentable { .. }),
        "{err}"
    );

    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("flat.obj");
    std::fs::write(
        &obj,
        "v -1 0 0\nv 1 0 0\nv 1 2 0\nv -1 2 0\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_altrep"))
        .args(["cylinder", "--mesh", obj.to_str().unwrap(), "--angles", "2"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cannot represent this object"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// An object no view sees (a horizontal square seen edge-on) is "nothing visible", never a
/// perfect score: the coverage check, `altrep cylinder` and `altrep parallax` all refuse it.
#[test]
fn horizontal_square_is_nothing_visible() {
    use altrep::cylinder::{CoverageParams, CylinderError, coverage};
    let shape = horizontal_square();
    let tex = texture(&shape);
    let err = coverage(&shape, &tex, &CoverageParams::default()).unwrap_err();
    assert!(
        matches!(err, CylinderError::NothingVisible { angles: 8 }),
        "{err}"
    );
    let p = params(0.3, 16, 1);
    let gt = truth(&shape, &p);
    assert_eq!(
        psnr(&gt, &gt),
        Err(altrep::metrics::MetricsError::NothingVisible)
    );
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("horizontal.obj");
    std::fs::write(
        &obj,
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    for args in [
        &["cylinder", "--angles", "2"][..],
        &[
            "parallax",
            "--angles",
            "4",
            "--no-quality",
            "--sweep-factor",
            "0",
        ],
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_altrep"))
            .args(args)
            .args(["--mesh", obj.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("nothing visible"), "{args:?}: {err}");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(!stdout.contains("inf"), "{args:?}: {stdout}");
    }
}

/// Objects the texture can hold pass: the pear (star-shaped slices) has almost all of its visible
/// surface held by the capture rays (measured 0.99), the chair, whose legs stand in line with
/// the axis, much less (measured 0.60) but above the default threshold of one half. The share
/// answers for the object: it is the same whatever texture is captured later.
#[test]
fn star_shaped_objects_pass_the_coverage_check() {
    use altrep::cylinder::{CoverageParams, check_coverage};
    let p = CoverageParams::default();
    let pear = scene_shape("pear").unwrap();
    let c = check_coverage(&pear, texture(&pear).cylinder(), &p).unwrap();
    assert!(c.share > 0.97, "pear {}", c.share);
    let chair = scene_shape("chair").unwrap();
    let c = check_coverage(&chair, texture(&chair).cylinder(), &p).unwrap();
    assert!(c.share > 0.55 && c.share < 0.9, "chair {}", c.share);
}

/// The bounded march is exact: fragment for fragment the same visible point as exact inverse
/// warping (same sectors tested in the same order from a conservative start), on a star-shaped
/// shape, a multi-part one and one with holes and negative radii, at a fraction of the steps.
#[test]
fn bounded_march_matches_exact_inverse_warping() {
    use altrep::cylinder::{BoundsParams, MarchBounds};
    for name in ["pear", "tree", "truck"] {
        let shape = scene_shape(name).unwrap();
        let tex = texture(&shape);
        let (bounds, report) = MarchBounds::build(&tex, &BoundsParams::default()).unwrap();
        assert_eq!(report.bytes, 2 * 64 * 32 * 64);
        for angle in [0.4, 2.9, 5.5] {
            let p = params(angle, 40, 2);
            let exact = render_exact(&tex, ExactMethod::Inverse(RadiusModel::General), &p).unwrap();
            let fast = bounds.render(&tex, &p).unwrap();
            let hits = exact.fragments.iter().filter(|f| f.is_some()).count();
            assert!(hits > 500, "{name}: {hits} hits");
            for (n, (a, b)) in exact.fragments.iter().zip(&fast.fragments).enumerate() {
                assert_eq!(a, b, "{name} α = {angle}: sub-sample {n}");
            }
            // Measured: 3–5 tests per sub-sample against 50–80 for the full march.
            assert!(
                fast.mean_steps() * 8.0 < exact.mean_steps(),
                "{name} α = {angle}: {} vs {}",
                fast.mean_steps(),
                exact.mean_steps()
            );
        }
    }
}

/// The stored ranges are conservative on a sweep four times finer than the cells along the
/// abscissa and the angle and at four heights per row cell: wherever exact inverse warping
/// finds its first hit at march position `n*`, the pixel's cell holds `start ≤ n* ≤ stop`
/// (tree and truck: separate parts, holes, negative radii).
#[test]
fn march_bounds_are_conservative_on_a_finer_sweep() {
    use altrep::cylinder::{BoundsParams, MarchBounds, SliceView};
    let bp = BoundsParams {
        cells_x: 16,
        rows_per_cell: 4,
        cells_alpha: 16,
    };
    for name in ["tree", "truck"] {
        let shape = scene_shape(name).unwrap();
        let tex = texture(&shape);
        let (bounds, _) = MarchBounds::build(&tex, &bp).unwrap();
        let (mut hits, mut tight) = (0usize, 0usize);
        for ai in 0..4 * bp.cells_alpha {
            let alpha = (ai as f64 + 0.5) * std::f64::consts::TAU / (4 * bp.cells_alpha) as f64;
            for vi in 0..16 {
                let v = vi as f64 * 63.0 / 15.0;
                let slice = tex.slice(v);
                let view = SliceView::new(&slice, alpha, RadiusModel::General);
                for xi in 0..4 * bp.cells_x {
                    let x = -1.0 + (xi as f64 + 0.5) * 2.0 / (4 * bp.cells_x) as f64;
                    let (f, steps) = view.inverse(x);
                    if f.is_none() {
                        continue;
                    }
                    hits += 1;
                    let n = steps as usize - 1;
                    let (start, stop) = bounds.range(x, v, alpha).unwrap_or_else(|| {
                        panic!("{name}: hit in an empty cell at {x} {v} {alpha}")
                    });
                    assert!(
                        start <= n && n <= stop,
                        "{name}: {start} ≤ {n} ≤ {stop} fails"
                    );
                    tight += usize::from(n == start);
                }
            }
        }
        assert!(hits > 10_000, "{name}: {hits}");
        assert!(tight > 0);
    }
}

/// Random small textures (radii of both signs, holes, 8 to 24 columns, 1 to 4 rows) and random
/// cell counts: the bounded march always returns exactly what exact inverse warping returns.
#[test]
fn bounded_march_is_exact_on_random_textures() {
    use altrep::cylinder::{BoundsParams, MarchBounds, SliceView};
    use altrep::data_gen::{Projection, Sample, SampleGrid};
    use proptest::prelude::*;
    let config = ProptestConfig {
        cases: 64,
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261204),
        ..ProptestConfig::default()
    };
    proptest!(config, |(
        half in 4usize..12,
        rows in 1usize..5,
        radii in proptest::collection::vec(prop_oneof![Just(None), (-1.0f32..1.0).prop_map(Some)], 96),
        bx in 1usize..6,
        g in 1usize..4,
        ba in 1usize..9,
        probes in proptest::collection::vec((-1.0f64..1.0, -0.5f64..4.5, -7.0f64..14.0), 64),
    )| {
        let l = 2 * half;
        let samples = (0..l * rows)
            .map(|n| radii[n % radii.len()].map(|depth| Sample {
                albedo: glam::Vec3::ONE,
                normal: glam::Vec3::X,
                depth,
            }))
            .collect();
        let tex = CylindricalTexture::from_samples(&SampleGrid {
            width: l,
            height: rows,
            cylinder: Default::default(),
            projection: Projection::Cylindrical,
            samples,
        })
        .unwrap();
        let (bounds, _) = MarchBounds::build(&tex, &BoundsParams {
            cells_x: 2 * bx,
            rows_per_cell: g,
            cells_alpha: ba,
        })
        .unwrap();
        for (x, v, alpha) in probes {
            let slice = tex.slice(v);
            let view = SliceView::new(&slice, alpha, RadiusModel::General);
            let exact = view.inverse(x).0;
            let fast = bounds.march(&view, x, v).0;
            prop_assert_eq!(exact, fast, "x {} v {} α {}", x, v, alpha);
        }
    });
}

/// Bad bound parameters are typed errors.
#[test]
fn bound_parameters_are_validated() {
    use altrep::cylinder::{BoundsParams, CylinderError, MarchBounds};
    let tex = texture(&scene_shape("sphere").unwrap());
    for bp in [
        BoundsParams {
            cells_x: 15,
            ..BoundsParams::default()
        },
        BoundsParams {
            cells_alpha: 0,
            ..BoundsParams::default()
        },
        BoundsParams {
            rows_per_cell: 0,
            ..BoundsParams::default()
        },
    ] {
        assert!(matches!(
            MarchBounds::build(&tex, &bp),
            Err(CylinderError::InvalidParameter { .. } | CylinderError::ZeroSize { .. })
        ));
    }
}

/// λ is chosen per fit: on the tree (separate parts, jumps in the offset) the fixed λ = 10⁻⁴ lets
/// the coefficients reach several times the data range (measured 7.7× its half range), the
/// default rule takes the smallest rung of the ladder that keeps them within 2×, and a rung
/// below it does not. Bounded coefficients make 8-bit storage honest: its error stays within
/// half a code step of the float fit's, and the float fit loses little (offset RMS over all
/// defined samples within 10 % of the fixed λ's).
#[test]
fn lambda_choice_keeps_coefficients_within_twice_the_data_range() {
    use altrep::cylinder::{LambdaRule, OffsetParams, OffsetTexture};
    for name in ["tree", "truck"] {
        let tex = texture(&scene_shape(name).unwrap());
        let fixed = OffsetTexture::fit(
            &tex,
            &OffsetParams {
                lambda: LambdaRule::Fixed(1e-4),
                ..OffsetParams::default()
            },
        )
        .unwrap();
        let chosen = OffsetTexture::fit(&tex, &OffsetParams::default()).unwrap();
        let (f, c) = (&fixed.report, &chosen.report);
        println!(
            "{name}: fixed excursion {:.2} rms {:.3} / 8-bit {:.3}; chosen λ {:.1e} excursion {:.2} rms {:.3} / 8-bit {:.3}; trials {:?}",
            f.coef_excursion,
            f.error_defined_float.rms,
            f.error_defined_8bit.rms,
            c.lambda,
            c.coef_excursion,
            c.error_defined_float.rms,
            c.error_defined_8bit.rms,
            c.lambda_trials
        );
        assert!(f.lambda_trials.is_empty());
        assert!(f.coef_excursion > 2.0, "{name}: {}", f.coef_excursion);
        assert!(c.coef_excursion <= 2.0, "{name}: {}", c.coef_excursion);
        // The chosen rung is the first that satisfies the bound.
        let (last, before) = c.lambda_trials.split_last().unwrap();
        assert_eq!(last.lambda, c.lambda);
        assert!(before.iter().all(|t| t.excursion > 2.0));
        assert!(c.lambda > 1e-4);
        let (g, data) = (chosen.grid(), &c.fit.data);
        let (lo, hi) = g.value_range();
        let half = 0.5 * (data.max - data.min);
        assert!(lo >= data.min - half - 1e-9 && hi <= data.max + half + 1e-9);
        // 8-bit: half a code step of the 4·half coefficient range at most.
        let step = (hi - lo) / 255.0;
        assert!(
            c.error_defined_8bit.rms <= c.error_defined_float.rms + 0.5 * step,
            "{name}: {:?}",
            c.error_defined_8bit
        );
        assert!(c.error_defined_float.rms <= 1.1 * f.error_defined_float.rms);
    }
}
