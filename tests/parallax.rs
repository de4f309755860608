//! Images with parallax (docs/design.md §7): warping against the capture and the ground truth,
//! direct against inverse warping, conservativeness of every bound type, and the best-c family
//! against the report's pair. Meshes from `../shared/data/meshes/` are used when present; without
//! them their checks are skipped with a visible message, and fail under `CI=true`
//! (`altrep_data_gen::skip`). Each floor derived from a measurement has the measured value and
//! its date written beside it.

use altrep::data_gen::{
    BoundingCylinder, Light, Mesh, RgbaImage, Shape, TruthParams, ViewParams, capture_view,
    render_truth, scene_shape, shared_mesh,
};
use altrep::metrics::{CompareOptions, compare, psnr, silhouette_iou};
use altrep::parallax::{
    BoundKind, BoundParams, Bounds, Brim, ParallaxError, ParallaxImages, ParallaxParams,
    QualityParams, Reconstruction, RenderParams, RowFilter, Variant, WarpMethod, build_bounds,
    dense_sweep, error_split, march, measure_quality_sweep, measure_steps, render,
    render_bounded_with, render_with, warp_row_direct, warp_view,
};
use approx::assert_abs_diff_eq;

const PROCEDURAL: [&str; 3] = ["truck", "tree", "building"];

fn small(views: usize, size: usize) -> ParallaxParams {
    ParallaxParams {
        views,
        width: size,
        height: size,
        ..ParallaxParams::default()
    }
}

fn mesh(name: &str) -> Option<Mesh> {
    shared_mesh(name, &format!("the {name} checks"))
}

#[test]
fn a_view_seen_at_theta_zero_reproduces_its_capture() {
    let light = Light::default();
    for name in PROCEDURAL {
        let shape = scene_shape(name).unwrap();
        let p = small(8, 32);
        let images = ParallaxImages::capture(&shape, &p).unwrap();
        let screen = RenderParams::native(&images);
        for k in 0..p.views {
            let stored = images.views[k].shade(&light);
            for method in [WarpMethod::Inverse, WarpMethod::Direct] {
                let (crossings, img) = warp_view(&images, k, 0.0, method, &screen).unwrap();
                assert_eq!(
                    img, stored,
                    "{name} view {k} {method:?}: θ = 0 must reproduce the stored view bit for bit"
                );
                for (idx, c) in crossings.iter().enumerate() {
                    if let Some(c) = c {
                        assert_eq!(
                            (c.texel, c.t),
                            (idx % p.width, 0.0),
                            "{name} view {k}: pixel {idx} reads another texel"
                        );
                    }
                }
            }
            // The stored view is the capture up to 8-bit quantisation; coverage is identical.
            let raw = capture_view(
                &shape,
                &ViewParams {
                    angle: p.view_angle(k),
                    width: 32,
                    height: 32,
                    cylinder: p.cylinder,
                },
            )
            .unwrap()
            .shade(&light);
            for (a, b) in stored.pixels.iter().zip(&raw.pixels) {
                assert_eq!(
                    a[3], b[3],
                    "{name} view {k}: coverage differs from the capture"
                );
                for c in 0..3 {
                    assert!(
                        (a[c] - b[c]).abs() < 0.02,
                        "{name} view {k}: colour {a:?} vs capture {b:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn warped_depths_follow_data_gen_conventions() {
    // Warp view k by θ and compare the crossing depth z_e with a capture made at α_k + θ: only a
    // correct sign convention makes them agree (a wrong sign mirrors the parallax).
    for name in ["sphere", "box", "truck"] {
        let shape = scene_shape(name).unwrap();
        let p = small(8, 64);
        let images = ParallaxImages::capture(&shape, &p).unwrap();
        let screen = RenderParams::native(&images);
        let dx = 2.0 / 64.0;
        for (k, theta) in [(0, 0.3), (3, -0.5), (5, 0.7)] {
            let (crossings, _) =
                warp_view(&images, k, theta, WarpMethod::Inverse, &screen).unwrap();
            let truth = capture_view(
                &shape,
                &ViewParams {
                    angle: p.view_angle(k) + theta,
                    width: 64,
                    height: 64,
                    cylinder: p.cylinder,
                },
            )
            .unwrap();
            let mut errors: Vec<f64> = crossings
                .iter()
                .zip(&truth.samples)
                .filter_map(|(c, s)| Some((c.as_ref()?.z_e - f64::from(s.as_ref()?.depth)).abs()))
                .collect();
            assert!(errors.len() > 200, "{name}: too few common pixels");
            errors.sort_by(f64::total_cmp);
            let median = errors[errors.len() / 2];
            assert!(
                median < 0.5 * dx,
                "{name} view {k} θ {theta}: median depth error {median:.4} R ≥ half a texel"
            );
        }
    }
}

#[test]
fn inverse_warping_equals_direct_warping_within_one_texel() {
    // Images of both methods within 40 dB of each other at every angle (measured 2026-12-04:
    // identical, ∞ dB, at every angle and supersampling).
    let mut worst = f64::INFINITY;
    for name in ["truck", "tree", "building", "sphere"] {
        let shape = scene_shape(name).unwrap();
        let p = small(8, 32);
        let images = ParallaxImages::capture(&shape, &p).unwrap();
        let dx = 2.0 / 32.0;
        for supersample in [1, 3] {
            let screen = RenderParams {
                supersample,
                ..RenderParams::native(&images)
            };
            let n = p.width * supersample;
            for k in [0, 3, 6] {
                for step in -6..=6 {
                    let theta = p.delta_theta() * step as f64 / 6.0;
                    let (inv, img_i) =
                        warp_view(&images, k, theta, WarpMethod::Inverse, &screen).unwrap();
                    let (dir, img_d) =
                        warp_view(&images, k, theta, WarpMethod::Direct, &screen).unwrap();
                    for (idx, (a, b)) in inv.iter().zip(&dir).enumerate() {
                        match (a, b) {
                            (Some(a), Some(b)) => assert!(
                                (a.x_t - b.x_t).abs() <= dx,
                                "{name} view {k} θ {theta:.3}: crossings {a:?} and {b:?} more than a texel apart"
                            ),
                            (None, None) => {}
                            _ => {
                                // Coverage may differ only next to a ray where the two agree.
                                let (row, s) = (idx / n, idx % n);
                                let near = [s.wrapping_sub(supersample), s + supersample]
                                    .iter()
                                    .filter(|&&t| t < n)
                                    .any(|&t| {
                                        inv[row * n + t].is_some() == dir[row * n + s].is_some()
                                    });
                                assert!(
                                    near,
                                    "{name} view {k} θ {theta:.3}: coverage differs at ray {idx}"
                                );
                            }
                        }
                    }
                    let e = compare(&img_i, &img_d, &CompareOptions::default()).unwrap();
                    worst = worst.min(e.psnr_db);
                    assert!(
                        e.psnr_db > 40.0,
                        "{name} view {k} θ {theta:.3}: images differ ({:.1} dB)",
                        e.psnr_db
                    );
                }
            }
        }
    }
    eprintln!("inverse against direct warping: worst {worst:.2} dB");
}

fn all_bounds(images: &ParallaxImages, params: &BoundParams) -> Vec<Bounds> {
    BoundKind::ALL
        .iter()
        .map(|&k| build_bounds(images, k, params).unwrap())
        .collect()
}

/// Both surface models: the default (tangent brims) and the original flat brims.
fn check_no_violations(label: &str, shape: &dyn Shape, bit_depths: &[u32]) {
    for brim in [Brim::DEFAULT, Brim::Flat] {
        check_no_violations_with(&format!("{label}, {brim:?}"), shape, bit_depths, brim);
    }
}

fn check_no_violations_with(label: &str, shape: &dyn Shape, bit_depths: &[u32], brim: Brim) {
    let p = small(8, 32);
    let images = ParallaxImages::capture(shape, &p)
        .unwrap()
        .with_brim(brim)
        .unwrap();
    for &bits in bit_depths {
        let params = BoundParams {
            subdivisions: 8,
            bits,
            ..BoundParams::default()
        };
        let bounds = all_bounds(&images, &params);
        let refs: Vec<&Bounds> = bounds.iter().collect();
        let violations = dense_sweep(&images, &refs, 10).unwrap();
        for (b, v) in bounds.iter().zip(&violations) {
            assert_eq!(
                *v,
                0,
                "{label}: {} ({bits} bits) has {v} violations on the dense sweep",
                b.kind.name()
            );
        }
        let report = measure_steps(&images, &bounds, 36, 0).unwrap();
        for s in &report.stats {
            assert_eq!(
                s.mismatches, 0,
                "{label}: {} changes the crossing of some fragment",
                s.method
            );
        }
        // The sweep can fail: bounds narrowed by one texel are caught.
        if bits == 8 {
            let narrowed: Vec<Bounds> = bounds[1..]
                .iter()
                .map(|b| b.with_margin(-2.0 / 32.0))
                .collect();
            let refs: Vec<&Bounds> = narrowed.iter().collect();
            let caught = dense_sweep(&images, &refs, 10).unwrap();
            assert!(
                caught.iter().all(|&v| v > 0),
                "{label}: narrowed bounds went unnoticed: {caught:?}"
            );
        }
    }
}

#[test]
fn every_bound_type_is_conservative_on_the_dense_sweep() {
    for name in PROCEDURAL {
        let bits: &[u32] = if name == "truck" { &[8, 32] } else { &[8] };
        check_no_violations(name, &scene_shape(name).unwrap(), bits);
    }
    for name in ["teapot", "beetle", "fandisk"] {
        if let Some(m) = mesh(name) {
            check_no_violations(name, &m, &[8]);
        }
    }
}

#[test]
fn best_c_is_never_worse_than_the_pair() {
    for name in PROCEDURAL {
        let shape = scene_shape(name).unwrap();
        let p = small(8, 32);
        let images = ParallaxImages::capture(&shape, &p).unwrap();
        let params = BoundParams {
            subdivisions: 16,
            bits: 32,
            ..BoundParams::default()
        };
        let pair = build_bounds(&images, BoundKind::FPair, &params).unwrap();
        let best = build_bounds(&images, BoundKind::BestC, &params).unwrap();
        let mut better = 0;
        for k in 0..p.views {
            for j in 0..p.height {
                for i in 0..p.width {
                    let [a, b] = pair.pixel(k, i, j).unwrap();
                    let [c, _] = best.pixel(k, i, j).unwrap();
                    assert_eq!(a.is_some(), c.is_some(), "{name}: emptiness differs");
                    let (Some(a), Some(b), Some(c)) = (a, b, c) else {
                        continue;
                    };
                    let pair_len = (a.v_max - a.v_min).min(b.v_max - b.v_min);
                    let best_len = c.v_max - c.v_min;
                    // f32 storage rounds each value outward by at most one ulp.
                    assert!(
                        best_len <= pair_len + 1e-6,
                        "{name} view {k} pixel ({i},{j}): best c {best_len} > pair {pair_len}"
                    );
                    better += usize::from(best_len < pair_len - 1e-6);
                }
            }
        }
        assert!(better > 0, "{name}: best c never improved on the pair");
        let report = measure_steps(&images, &[pair, best], 90, 0).unwrap();
        assert!(
            report.stats[1].mean_steps <= report.stats[0].mean_steps,
            "{name}: best c costs more steps than the pair"
        );
    }
}

#[test]
fn best_c_saves_at_least_15_percent_of_the_pairs_steps_on_the_teapot() {
    let Some(teapot) = mesh("teapot") else { return };
    // The measured definition: 64², N = 8, 8-bit bounds, 360 angles, every fragment, per view.
    let images = ParallaxImages::capture(&teapot, &ParallaxParams::default()).unwrap();
    let params = BoundParams::default();
    let pair = build_bounds(&images, BoundKind::FPair, &params).unwrap();
    let best = build_bounds(&images, BoundKind::BestC, &params).unwrap();
    let report = measure_steps(&images, &[pair, best], 360, 0).unwrap();
    let (p, b) = (report.stats[0].mean_steps, report.stats[1].mean_steps);
    // Measured 2026-12-04: pair 0.751, best c 0.592 steps per fragment, 21.1 % saved.
    eprintln!(
        "teapot: pair {p:.3}, best c {b:.3} steps per fragment ({:.1} % saved)",
        100.0 * (1.0 - b / p)
    );
    assert!(
        b <= 0.85 * p,
        "teapot: best c {b:.3} steps vs pair {p:.3}: less than 15 % saved"
    );
}

#[test]
fn inverse_warping_matches_the_ground_truth_between_views() {
    // Measured: truck 64², N = 8, α = α_1 + 0.45 Δθ, 3×3 rays, default reconstruction:
    // 28.59 dB, IoU 0.9873 (2026-12-04; 24.42 dB and 0.969 when the floors were first set).
    // Floors: 0.5 dB and 0.02 below.
    let shape = scene_shape("truck").unwrap();
    let p = small(8, 64);
    let images = ParallaxImages::capture(&shape, &p).unwrap();
    let light = Light::default();
    let alpha = p.view_angle(1) + 0.45 * p.delta_theta();
    let screen = RenderParams {
        width: 64,
        height: 64,
        supersample: 3,
        light,
        mip: true,
    };
    let img = render(&images, alpha, WarpMethod::Inverse, &screen).unwrap();
    let truth = render_truth(
        &shape,
        &TruthParams {
            angle: alpha,
            width: 64,
            height: 64,
            supersample: 3,
            light,
            cylinder: BoundingCylinder::default(),
        },
    )
    .unwrap();
    let db = psnr(&img, &truth).unwrap();
    let iou = silhouette_iou(&img, &truth, 0.5).unwrap();
    eprintln!("truck inverse warp at α = {alpha:.3}: {db:.2} dB, IoU {iou:.4}");
    assert!(db >= 28.09, "PSNR {db:.2} dB below threshold");
    assert!(iou >= 0.9673, "IoU {iou:.4} below threshold");
}

#[test]
fn bad_input_gets_typed_errors() {
    let shape = scene_shape("sphere").unwrap();
    let bad = ParallaxParams {
        views: 1,
        ..ParallaxParams::default()
    };
    assert!(matches!(
        ParallaxImages::capture(&shape, &bad),
        Err(ParallaxError::InvalidParameter { .. })
    ));
    let bad = ParallaxParams {
        width: 0,
        ..ParallaxParams::default()
    };
    assert!(matches!(
        ParallaxImages::capture(&shape, &bad),
        Err(ParallaxError::InvalidParameter { .. })
    ));
    let p = small(4, 16);
    let images = ParallaxImages::capture(&shape, &p).unwrap();
    let other = ParallaxImages::capture(&shape, &small(4, 8)).unwrap();
    let b = build_bounds(&other, BoundKind::ZMinMax, &BoundParams::default()).unwrap();
    assert!(measure_steps(&images, std::slice::from_ref(&b), 10, 0).is_err());
    assert!(dense_sweep(&images, &[&b], 2).is_err());
    let bad_bits = BoundParams {
        bits: 12,
        ..BoundParams::default()
    };
    assert!(build_bounds(&images, BoundKind::BestC, &bad_bits).is_err());
    assert!(
        warp_view(
            &images,
            9,
            0.0,
            WarpMethod::Inverse,
            &RenderParams::native(&images)
        )
        .is_err()
    );
    let zero = RenderParams {
        width: 0,
        ..RenderParams::native(&images)
    };
    assert!(render(&images, 0.3, WarpMethod::Direct, &zero).is_err());
    // Indices and angles.
    assert!(
        render(
            &images,
            f64::NAN,
            WarpMethod::Inverse,
            &RenderParams::native(&images)
        )
        .is_err()
    );
    assert!(images.bracketing(f64::INFINITY).is_err());
    assert!(march(&images, 0, 16, 0.0, 0.1, (-1.0, 1.0)).is_err());
    assert!(march(&images, 0, 3, f64::NAN, 0.1, (-1.0, 1.0)).is_err());
    assert!(march(&images, 0, 3, 0.1, 0.1, (-1.0, 1.0)).is_ok());
    let mut out = vec![None; 2];
    assert!(warp_row_direct(&images, 0, 3, 0.1, &[0.5, 0.1], &mut out).is_err());
    assert!(warp_row_direct(&images, 0, 3, 0.1, &[0.1, 0.2, 0.3], &mut out).is_err());
    let zb = build_bounds(&images, BoundKind::ZMinMax, &BoundParams::default()).unwrap();
    assert!(
        zb.pixel(4, 0, 0).is_err() && zb.pixel(0, 16, 0).is_err() && zb.pixel(0, 0, 16).is_err()
    );
    assert!(zb.range(0, 1, 1, 0.0, f64::NAN).is_err());
    assert!(zb.range(0, 1, 1, 0.0, 0.2).is_ok());
    assert!(images.views[0].depth(99, 0).is_none() && !images.views[0].defined(0, 99));
    // Grids that do not fit the parameters.
    let g = capture_view(
        &shape,
        &ViewParams {
            angle: 0.1,
            width: 16,
            height: 16,
            cylinder: BoundingCylinder::default(),
        },
    )
    .unwrap();
    let grids = vec![g; 4];
    assert!(matches!(
        ParallaxImages::from_grids(&grids, &p),
        Err(ParallaxError::InconsistentView { view: 0, .. })
    ));
    // Right angles but a NaN normal and a truncated sample list.
    let mut grids: Vec<_> = (0..4)
        .map(|k| {
            capture_view(
                &shape,
                &ViewParams {
                    angle: p.view_angle(k),
                    width: 16,
                    height: 16,
                    cylinder: BoundingCylinder::default(),
                },
            )
            .unwrap()
        })
        .collect();
    assert!(ParallaxImages::from_grids(&grids, &p).is_ok());
    let hit = grids[2].samples.iter().position(|s| s.is_some()).unwrap();
    grids[2].samples[hit].as_mut().unwrap().normal.x = f32::NAN;
    assert!(matches!(
        ParallaxImages::from_grids(&grids, &p),
        Err(ParallaxError::InconsistentView { view: 2, .. })
    ));
    grids[2].samples.truncate(10);
    assert!(matches!(
        ParallaxImages::from_grids(&grids, &p),
        Err(ParallaxError::InconsistentView { view: 2, .. })
    ));
}

#[test]
fn minified_impostors_warp_a_mip_level_and_alias_less() {
    // 128² views drawn on a 32² screen: the mip path warps level 2 (32² filtered texels); point
    // sampling level 0 aliases. Both against a 4×4-supersampled truth. Measured on the tree (fine
    // detail): +0.63 dB on average (2026-12-04: +1.25, +0.71 and −0.06 dB at the three angles,
    // mean +0.633; floor 0.3 dB). (On coarse-detail shapes — truck, building, pear — the mip
    // path loses 1–3 dB instead: box-filtered depth mixes front and back surfaces and the warp's
    // linear interpolation blurs once more; see `RenderParams::mip`.) The gain is asserted for
    // the original reconstruction (flat brims, nearest row) it was measured with; the default
    // reconstruction's row filter already averages the rows the point-sampled path skips, and
    // there the mip level loses 0.95 dB on the tree (2026-12-04; printed, not asserted).
    let shape = scene_shape("tree").unwrap();
    let default_images = ParallaxImages::capture(&shape, &small(8, 128)).unwrap();
    let images = default_images.with_brim(Brim::Flat).unwrap();
    let original = Reconstruction::ORIGINAL;
    assert_eq!(images.mip_levels(), 8);
    let l2 = images.level(2).unwrap();
    assert_eq!(
        (l2.params.width, l2.params.height, l2.views.len()),
        (32, 32, 8)
    );
    assert!(images.level(8).is_err());
    assert!(
        images.bytes_with_mips() > images.bytes()
            && images.bytes_with_mips() < images.bytes() * 4 / 3 + 1
    );
    let light = Light::default();
    let mut gain = 0.0;
    for alpha in [0.4, 1.9, 4.1] {
        let truth = render_truth(
            &shape,
            &TruthParams {
                angle: alpha,
                width: 32,
                height: 32,
                supersample: 4,
                light,
                cylinder: BoundingCylinder::default(),
            },
        )
        .unwrap();
        let screen = RenderParams {
            width: 32,
            height: 32,
            supersample: 1,
            light,
            mip: true,
        };
        assert_eq!(screen.mip_level(128, 128), 2);
        let point_screen = RenderParams {
            mip: false,
            ..screen
        };
        let db = |images: &ParallaxImages, screen: &RenderParams, rec: &Reconstruction| {
            let img = render_with(images, alpha, WarpMethod::Inverse, screen, rec).unwrap();
            psnr(&img, &truth).unwrap()
        };
        let mip = db(&images, &screen, &original);
        let point = db(&images, &point_screen, &original);
        let default_mip = db(&default_images, &screen, &Reconstruction::DEFAULT);
        let default_point = db(&default_images, &point_screen, &Reconstruction::DEFAULT);
        eprintln!(
            "tree α = {alpha}: original mip {mip:.2} dB, point-sampled {point:.2} dB; \
             default mip {default_mip:.2} dB, point-sampled {default_point:.2} dB"
        );
        gain += (mip - point) / 3.0;
    }
    assert!(
        gain > 0.3,
        "the mip level gains only {gain:.2} dB over point sampling"
    );
}

const TANGENT: Brim = Brim::Tangent { max_slope: 4.0 };

#[test]
fn tangent_brims_keep_the_bounds_conservative_and_theta_zero_exact() {
    let light = Light::default();
    for name in PROCEDURAL {
        let shape = scene_shape(name).unwrap();
        check_no_violations_with(&format!("{name}, tangent brim"), &shape, &[8], TANGENT);
        let images = ParallaxImages::capture(&shape, &small(8, 32))
            .unwrap()
            .with_brim(TANGENT)
            .unwrap();
        let screen = RenderParams::native(&images);
        for k in 0..8 {
            for method in [WarpMethod::Inverse, WarpMethod::Direct] {
                let (_, img) = warp_view(&images, k, 0.0, method, &screen).unwrap();
                assert_eq!(
                    img,
                    images.views[k].shade(&light),
                    "{name} view {k} {method:?}: tangent brims must still reproduce the view at θ = 0"
                );
            }
        }
    }
    if let Some(m) = mesh("teapot") {
        check_no_violations_with("teapot, tangent brim", &m, &[8], TANGENT);
    }
}

#[test]
fn tangent_brims_change_only_unjoined_ends_and_reject_bad_slopes() {
    let images = ParallaxImages::capture(&scene_shape("truck").unwrap(), &small(8, 32)).unwrap();
    assert_eq!(images.brim(), Brim::DEFAULT);
    let flat0 = images.with_brim(Brim::Tangent { max_slope: 0.0 }).unwrap();
    let tangent = images.with_brim(TANGENT).unwrap();
    assert_eq!(tangent.brim(), TANGENT);
    // The stored data are untouched, and slope 0 is the flat model.
    assert_eq!(tangent.codes(), images.codes());
    let flat = images.with_brim(Brim::Flat).unwrap();
    assert_eq!(flat.brim(), Brim::Flat);
    assert_abs_diff_eq!(flat0.march_radius(), flat.march_radius(), epsilon = 1e-12);
    // A mip level keeps the model.
    assert_eq!(tangent.level(1).unwrap().brim(), TANGENT);
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            images.with_brim(Brim::Tangent { max_slope: bad }),
            Err(ParallaxError::InvalidParameter { .. })
        ));
    }
}

#[test]
fn row_weights_interpolate_linearly_between_view_rows() {
    let images = ParallaxImages::capture(&scene_shape("sphere").unwrap(), &small(8, 16)).unwrap();
    let mut screen = RenderParams::native(&images);
    assert_eq!(screen.row_weights(5, 16, RowFilter::Linear), vec![(5, 1.0)]);
    screen.supersample = 3;
    let w = screen.row_weights(5, 16, RowFilter::Linear);
    let get = |j: usize| w.iter().find(|e| e.0 == j).map_or(0.0, |e| e.1);
    assert_abs_diff_eq!(get(4), 1.0 / 9.0, epsilon = 1e-6);
    assert_abs_diff_eq!(get(5), 7.0 / 9.0, epsilon = 1e-6);
    assert_abs_diff_eq!(get(6), 1.0 / 9.0, epsilon = 1e-6);
    // Rows outside the view are transparent: the top row loses its upper neighbour's weight.
    let top: f32 = screen
        .row_weights(0, 16, RowFilter::Linear)
        .iter()
        .map(|e| e.1)
        .sum();
    assert_abs_diff_eq!(top, 8.0 / 9.0, epsilon = 1e-6);
    assert_eq!(
        screen.row_weights(5, 16, RowFilter::Nearest),
        vec![(5, 1.0)]
    );
}

#[test]
fn every_reconstruction_option_gives_finite_premultiplied_images() {
    let shape = scene_shape("tree").unwrap();
    let images = ParallaxImages::capture(&shape, &small(6, 24))
        .unwrap()
        .with_brim(TANGENT)
        .unwrap();
    let screen = RenderParams {
        supersample: 3,
        ..RenderParams::native(&images)
    };
    let plain = render(&images, 0.7, WarpMethod::Inverse, &screen).unwrap();
    let same = render_with(
        &images,
        0.7,
        WarpMethod::Inverse,
        &screen,
        &Reconstruction::DEFAULT,
    );
    assert_eq!(
        same.unwrap(),
        plain,
        "render is render_with the default reconstruction"
    );
    assert_eq!(Reconstruction::default(), Reconstruction::DEFAULT);
    for bits in 0..128u32 {
        let rec = Reconstruction {
            rows: if bits & 1 == 1 {
                RowFilter::Linear
            } else {
                RowFilter::Nearest
            },
            depth_test: bits & 2 != 0,
            fallback: bits & 4 != 0,
            soft_edges: bits & 8 != 0,
            fill_holes: bits & 16 != 0,
            carve_brims: bits & 32 != 0,
            soft_fallback: bits & 64 != 0,
        };
        for method in [WarpMethod::Inverse, WarpMethod::Direct] {
            let img = render_with(&images, 0.7, method, &screen, &rec).unwrap();
            for p in &img.pixels {
                assert!(p.iter().all(|c| c.is_finite()), "{rec:?}: non-finite pixel");
                assert!(
                    (0.0..=1.0 + 1e-5).contains(&p[3]) && p[..3].iter().all(|&c| c <= p[3] + 1e-5),
                    "{rec:?} {method:?}: pixel {p:?} is not premultiplied with alpha in [0, 1]"
                );
            }
        }
    }
}

#[test]
fn the_error_split_adds_up_to_the_mse() {
    let shape = scene_shape("chair").unwrap();
    let images = ParallaxImages::capture(&shape, &small(8, 32)).unwrap();
    let screen = RenderParams {
        supersample: 3,
        ..RenderParams::native(&images)
    };
    let img = render(&images, 1.0, WarpMethod::Inverse, &screen).unwrap();
    let truth = render_truth(
        &shape,
        &TruthParams {
            angle: 1.0,
            width: 32,
            height: 32,
            supersample: 3,
            light: Light::default(),
            cylinder: BoundingCylinder::default(),
        },
    )
    .unwrap();
    let split = error_split(&img, &truth).unwrap();
    let e = compare(&img, &truth, &CompareOptions::default()).unwrap();
    assert_abs_diff_eq!(split.mse(), e.rmse * e.rmse, epsilon = 1e-9);
    assert!(
        split.band1_mse > 0.0,
        "a warp has some error at the outline"
    );
    assert!(error_split(&img, &RgbaImage::new(8, 8)).is_err());
}

/// The default reconstruction (docs/design.md §7.6: tangent brims, row filter, fallback views with
/// doubtful hits at half coverage, soft edges, hole filling, brim carving) against the original,
/// 64², 3×3-ray truth, 16 angles.
///
/// Sixteen views beat eight on the truck, the chair and the tree. On the smooth shapes they lose
/// a little, a known loss not yet diagnosed: at these 16 angles, measured 2026-12-04, torus
/// 33.74 against 33.78 dB (−0.04), capsule 37.47 against 37.21 (+0.26), and over denser angle
/// sets (the same day, 64 angles) torus −0.21, capsule −0.09 dB, so the loss is not an
/// accident of the sampling. It is bounded here at 0.1 dB at the test's 16 angles.
#[test]
fn the_improved_reconstruction_beats_the_original_and_16_views_lose_at_most_0_1_db() {
    // Floors: the measured PSNR less 0.5 dB (see the constants). Torus and capsule scored 0.6
    // and 0.2 dB lower at N = 16 than at N = 8 before brim carving (bench/RESULTS.md).
    let floors = [
        ("truck", FLOOR_TRUCK, MoreViews::Gain),
        ("chair", FLOOR_CHAIR, MoreViews::Gain),
        ("tree", FLOOR_TREE, MoreViews::Gain),
        ("torus", FLOOR_TORUS, MoreViews::KnownLoss),
        ("capsule", FLOOR_CAPSULE, MoreViews::KnownLoss),
    ];
    for (name, floor, more_views) in floors {
        let shape = scene_shape(name).unwrap();
        let qp = QualityParams {
            views: vec![8, 16],
            sizes: vec![64],
            ..QualityParams::default()
        };
        let rows =
            measure_quality_sweep(&shape, &qp, &[Variant::original(), Variant::best()]).unwrap();
        let db = |method: &str, views: usize| {
            rows.iter()
                .find(|r| r.method == method && r.views == views)
                .unwrap()
                .psnr_db
        };
        let best = Variant::best().name;
        let original = Variant::original().name;
        let (orig8, best8, best16) = (db(&original, 8), db(&best, 8), db(&best, 16));
        eprintln!("{name}: original N=8 {orig8:.2}, improved N=8 {best8:.2}, N=16 {best16:.2} dB");
        assert!(
            best8 >= floor,
            "{name}: improved N = 8 {best8:.2} dB below the floor {floor}"
        );
        assert!(
            best8 >= orig8 + 0.5,
            "{name}: improved {best8:.2} dB does not beat the original {orig8:.2} by 0.5 dB"
        );
        more_views.check(name, best8, best16);
    }
}

/// What 16 views do against 8 on a shape (measured 2026-12-04, default reconstruction, 64²).
#[derive(Clone, Copy)]
enum MoreViews {
    /// At least as good: truck +1.52, chair +1.65, tree +0.29 dB at the 16 angles.
    Gain,
    /// The known loss on smooth shapes (see the tests that use it): at most 0.1 dB.
    KnownLoss,
}

impl MoreViews {
    fn check(self, name: &str, n8: f64, n16: f64) {
        match self {
            Self::Gain => assert!(
                n16 >= n8,
                "{name}: N = 16 ({n16:.3} dB) looks worse than N = 8 ({n8:.3} dB)"
            ),
            Self::KnownLoss => assert!(
                n16 >= n8 - 0.1,
                "{name}: N = 16 ({n16:.3} dB) loses more than 0.1 dB to N = 8 ({n8:.3} dB)"
            ),
        }
    }
}

/// The fandisk, the last of the 15 evaluation shapes whose N = 16 scored below N = 8 by more
/// than 0.1 dB (31.43 against 31.76 dB before doubtful fallback hits counted at half coverage).
/// It still scores below: 31.686 against 31.778 dB (−0.092) at these 16 angles, measured
/// 2026-12-04, and −0.29 dB over 64 angles the same day; the loss is known, not yet diagnosed,
/// and bounded here at 0.1 dB. Floor 0.5 dB under its measured N = 8. Needs `../shared`
/// (skipped without it, a failure under `CI=true`).
#[test]
fn the_fandisk_loses_at_most_0_1_db_with_16_views() {
    let Some(fandisk) = mesh("fandisk") else {
        return;
    };
    let qp = QualityParams {
        views: vec![8, 16],
        sizes: vec![64],
        ..QualityParams::default()
    };
    let best = Variant::best();
    let rows = measure_quality_sweep(&fandisk, &qp, std::slice::from_ref(&best)).unwrap();
    let db = |views: usize| {
        rows.iter()
            .find(|r| r.method == best.name && r.views == views)
            .unwrap()
            .psnr_db
    };
    let (best8, best16) = (db(8), db(16));
    eprintln!("fandisk: N=8 {best8:.3}, N=16 {best16:.3} dB");
    assert!(
        best8 >= FLOOR_FANDISK,
        "fandisk: N = 8 {best8:.2} dB below the floor {FLOOR_FANDISK}"
    );
    MoreViews::KnownLoss.check("fandisk", best8, best16);
}

/// The fandisk's default reconstruction at N = 8, 64², 16 angles (31.78 dB measured, again on
/// 2026-12-04) less 0.5.
const FLOOR_FANDISK: f64 = 31.2;

// The default reconstruction (with hole filling and brim carving), N = 8, 64², 16 angles
// (`altrep parallax --shape NAME --quality-sweep`): measured PSNR minus 0.5 dB.
// Measured 31.05 (truck), 28.89 (chair), 33.40 (tree; 28.49 before hole filling, blend of 64
// views 33.29), 33.78 (torus; N = 16 33.72), 37.20 (capsule; N = 16 37.46); before brim
// carving 30.82, 27.65, 33.28, 33.76, 37.22; the original path: 25.87, 21.09, 26.27, 27.83,
// 30.16. With doubtful fallback hits at half coverage (`Reconstruction::soft_fallback`): 31.07,
// 28.89, 33.40, 33.78, 37.21 (N = 16: 32.59, 30.54, 33.69, 33.74, 37.47), remeasured unchanged
// on 2026-12-04.
const FLOOR_TRUCK: f64 = 30.5;
const FLOOR_CHAIR: f64 = 28.4;
const FLOOR_TREE: f64 = 32.9;
const FLOOR_TORUS: f64 = 33.2;
const FLOOR_CAPSULE: f64 = 36.7;

#[test]
fn hole_filling_and_fallback_marches_are_counted_apart_from_the_bracketing_steps() {
    // The tree at N = 8, 64² has pixels hidden in both bracketing views (hole filling took it
    // from 28.49 to 33.28 dB): their wall scans are steps too, counted in `hole_steps`, and
    // without hole filling they are 0 while the bracketing views' steps do not change.
    // Measured per pixel over 16 angles: 1.806 bracketing steps; fallback 56.15 and hole
    // filling 23.64 when they marched the whole cylinder chord, 3.17 and 1.32 within each
    // row's radius (same picture).
    let shape = scene_shape("tree").unwrap();
    let images = ParallaxImages::capture(&shape, &small(8, 64)).unwrap();
    let bounds = build_bounds(&images, BoundKind::BestC, &BoundParams::default()).unwrap();
    let light = Light::default();
    let no_fill = Reconstruction {
        fill_holes: false,
        ..Reconstruction::DEFAULT
    };
    let (mut filled, mut hole_steps, mut fallback_steps, mut steps) = (0usize, 0u64, 0u64, 0u64);
    for k in 0..16 {
        let alpha = (k as f64 + 0.37) * std::f64::consts::TAU / 16.0;
        let with =
            render_bounded_with(&images, &bounds, alpha, &light, &Reconstruction::DEFAULT).unwrap();
        let without = render_bounded_with(&images, &bounds, alpha, &light, &no_fill).unwrap();
        // The shader's path skips the fallback marches and wall scans beyond each row's stored
        // geometry (`ParallaxImages::row_radius`) and marches the rest within it; the picture
        // is still the full path's, whose fallback views march the whole cylinder chord.
        let screen = RenderParams {
            light,
            mip: false,
            ..RenderParams::native(&images)
        };
        let full = render_with(
            &images,
            alpha,
            WarpMethod::Inverse,
            &screen,
            &Reconstruction::DEFAULT,
        )
        .unwrap();
        for (p, (a, b)) in with.image.pixels.iter().zip(&full.pixels).enumerate() {
            for c in 0..4 {
                assert_abs_diff_eq!(a[c], b[c], epsilon = 1e-6);
            }
            assert!(a.iter().all(|v| v.is_finite()), "α = {alpha}, pixel {p}");
        }
        assert_eq!(with.steps, without.steps, "α = {alpha}: bracketing steps");
        assert_eq!(with.fallback_steps, without.fallback_steps, "α = {alpha}");
        assert_eq!(
            without.hole_steps, 0,
            "α = {alpha}: no hole filling, no scans"
        );
        let newly: usize = with
            .image
            .pixels
            .iter()
            .zip(&without.image.pixels)
            .filter(|(a, b)| a[3] > 0.0 && b[3] == 0.0)
            .count();
        assert!(
            newly == 0 || with.hole_steps >= newly as u64,
            "α = {alpha}: {newly} pixels filled with {} steps",
            with.hole_steps
        );
        filled += newly;
        hole_steps += with.hole_steps;
        fallback_steps += with.fallback_steps;
        steps += with.steps;
    }
    let fragments = (16 * 64 * 64) as f64;
    eprintln!(
        "tree N = 8, 64², 16 angles: {filled} pixels filled; per pixel {:.3} bracketing steps, {:.4} fallback, {:.4} hole filling",
        steps as f64 / fragments,
        fallback_steps as f64 / fragments,
        hole_steps as f64 / fragments
    );
    assert!(filled > 0 && hole_steps > 0 && fallback_steps > 0);
}

/// Regression: codes the random-codes property test below found (normals facing away, steep
/// brims of slope 16.9), where a ray passes through a piece's end point exactly at θ = Δθ. The
/// event angle, computed at or just past Δθ, was dropped, so the exact evaluation at Δθ did not
/// consider the pieces it bounds, and the best-c and split best-c bounds each missed that one
/// crossing of the dense sweep (`[0, 0, 0, 1, 1]`). Events within the sweep's window of ±Δθ
/// are now kept at the end.
#[test]
fn best_c_bounds_on_adversarial_steep_brims_regression() {
    let texels: Vec<Option<(u8, [u8; 3])>> = vec![
        None,
        None,
        None,
        None,
        None,
        None,
        None,
        None,
        None,
        None,
        Some((0, [34, 117, 103])),
        Some((177, [24, 224, 237])),
        None,
        Some((247, [184, 248, 3])),
        Some((250, [120, 149, 104])),
        None,
        Some((71, [128, 15, 154])),
        None,
        None,
        None,
        None,
        None,
        Some((119, [201, 36, 175])),
        None,
        None,
        None,
        Some((66, [13, 120, 17])),
        None,
        None,
        Some((84, [252, 155, 23])),
        None,
        None,
        None,
        Some((170, [183, 77, 183])),
        Some((100, [63, 215, 201])),
        Some((85, [199, 183, 109])),
        Some((105, [34, 49, 69])),
        None,
        None,
        Some((180, [144, 24, 116])),
        Some((245, [218, 20, 156])),
        None,
        None,
        None,
        None,
        Some((67, [254, 177, 193])),
        Some((106, [165, 176, 96])),
        None,
        None,
        None,
        None,
        Some((124, [224, 201, 186])),
        None,
        Some((176, [199, 26, 121])),
        None,
        None,
        None,
        None,
        None,
        None,
        None,
        Some((210, [193, 68, 134])),
        Some((112, [227, 5, 71])),
        None,
        None,
        Some((150, [227, 144, 116])),
        None,
        None,
        Some((89, [50, 59, 57])),
        Some((119, [181, 26, 87])),
        None,
        Some((250, [194, 23, 231])),
        None,
        Some((221, [54, 0, 175])),
        Some((238, [196, 111, 42])),
        None,
        None,
        None,
        Some((183, [232, 253, 97])),
        Some((211, [91, 104, 65])),
        Some((241, [22, 62, 230])),
        Some((105, [220, 180, 156])),
        Some((231, [228, 178, 123])),
        Some((130, [139, 35, 28])),
        Some((224, [158, 245, 35])),
        Some((37, [101, 141, 240])),
        None,
        Some((75, [82, 135, 230])),
        Some((167, [32, 132, 154])),
        Some((157, [4, 191, 222])),
        Some((90, [176, 181, 172])),
        Some((17, [107, 187, 148])),
        None,
        None,
        None,
        None,
        Some((182, [150, 180, 236])),
        Some((153, [111, 87, 234])),
        None,
        Some((79, [125, 222, 25])),
        None,
        Some((104, [40, 143, 69])),
        None,
        Some((9, [187, 57, 176])),
        Some((1, [28, 226, 231])),
        None,
        Some((210, [135, 162, 151])),
        Some((237, [234, 20, 37])),
        Some((168, [169, 115, 110])),
        None,
        Some((223, [249, 229, 189])),
        None,
        None,
        None,
        Some((192, [219, 176, 162])),
        None,
        None,
        Some((184, [255, 164, 82])),
        Some((112, [44, 82, 247])),
        None,
        Some((165, [220, 14, 144])),
        None,
        Some((116, [198, 4, 24])),
        None,
        Some((216, [110, 234, 150])),
        None,
        Some((16, [195, 167, 139])),
        None,
        Some((74, [54, 121, 153])),
        None,
        Some((181, [208, 16, 161])),
        None,
        Some((49, [21, 121, 61])),
        None,
        Some((48, [134, 114, 32])),
        Some((53, [223, 63, 177])),
        None,
        Some((50, [70, 152, 38])),
        Some((4, [39, 20, 131])),
        Some((89, [198, 197, 227])),
        Some((107, [13, 20, 183])),
        Some((59, [46, 123, 215])),
        None,
        None,
    ];
    let images = tangent_brim_images(&texels, 16.926427495976476);
    let violations = brim_bound_violations(&images);
    assert!(
        violations.iter().all(|&v| v == 0),
        "violations {violations:?}"
    );
}

/// Four views of 12 × 3 texels from `texels` (view-major; `None` undefined, else a depth code
/// and any normal code), with tangent brims of `max_slope`.
fn tangent_brim_images(texels: &[Option<(u8, [u8; 3])>], max_slope: f64) -> ParallaxImages {
    use altrep::parallax::ViewCodes;
    let p = ParallaxParams {
        views: 4,
        width: 12,
        height: 3,
        ..ParallaxParams::default()
    };
    let codes: Vec<ViewCodes> = (0..4)
        .map(|k| {
            let mut c = ViewCodes::empty(12, 3);
            for idx in 0..36 {
                if let Some((d, n)) = texels[k * 36 + idx] {
                    c.defined[idx] = true;
                    c.depth[idx] = u16::from(d);
                    c.normal[idx] = n; // any code, including zero and facing away
                    c.albedo[idx] = [200, 100, 50];
                }
            }
            c
        })
        .collect();
    ParallaxImages::from_codes(&p, &codes)
        .unwrap()
        .with_brim(Brim::Tangent { max_slope })
        .unwrap()
}

/// Dense-sweep violations of every bound kind (4 subdivisions) on `images`.
fn brim_bound_violations(images: &ParallaxImages) -> Vec<u64> {
    let params = BoundParams {
        subdivisions: 4,
        ..BoundParams::default()
    };
    let bounds: Vec<Bounds> = BoundKind::ALL
        .iter()
        .map(|&k| build_bounds(images, k, &params).unwrap())
        .collect();
    let refs: Vec<&Bounds> = bounds.iter().collect();
    dense_sweep(images, &refs, 4).unwrap()
}

/// Random codes (4 views of 12 × 3 texels, half undefined, any normal code, brims of slope 0,
/// 1e6 or up to 20) keep every bound kind conservative on the dense sweep and give finite
/// pictures. This property once failed about one run in five: it found the codes of the
/// regression case above (an event at exactly ±Δθ dropped by the sweep, fixed in
/// `pixel_points`). With that fix reverted it fails again within 2000 cases on two seeds of
/// four (2026-12-04); with the fix, 1.34 million cases from 70 seeds and 60 000 cases of a wider
/// variant (3 to 16 views, 2 to 19 columns, 1 to 3 rows, 1 to 8 subdivisions, sweeps 1 to 10
/// times finer) passed on 2026-12-04. Seeded, with its failures kept in
/// `tests/parallax.proptest-regressions`.
#[test]
fn tangent_brims_on_random_codes_stay_conservative_and_finite() {
    use proptest::prelude::*;
    let config = ProptestConfig {
        cases: 24,
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261204),
        ..ProptestConfig::default()
    };
    proptest!(config, |(
        texels in proptest::collection::vec(
            prop_oneof![Just(None), (any::<u8>(), any::<[u8; 3]>()).prop_map(Some)], 4 * 12 * 3),
        slope in prop_oneof![Just(0.0), Just(1e6), 0.0f64..20.0],
        alpha in -7.0f64..7.0,
    )| {
        let images = tangent_brim_images(&texels, slope);
        prop_assert!(images.march_radius().is_finite());
        let violations = brim_bound_violations(&images);
        prop_assert!(violations.iter().all(|&v| v == 0), "violations {:?}", violations);
        let screen = RenderParams { supersample: 3, ..RenderParams::native(&images) };
        let img = render_with(&images, alpha, WarpMethod::Inverse, &screen, &Variant::best().rec).unwrap();
        prop_assert!(img.pixels.iter().flatten().all(|c| c.is_finite() && *c <= 1.0 + 1e-5));
    });
}
