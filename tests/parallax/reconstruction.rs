//! Tangent brims, the row filter and the default reconstruction against the original; the
//! bounds on adversarial brims.

use super::*;
use altrep_data_gen::Supersample;

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
    screen.supersample = Supersample::of(3);
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
        supersample: Supersample::of(3),
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
        supersample: Supersample::of(3),
        ..RenderParams::native(&images)
    };
    let img = render(&images, 1.0, WarpMethod::Inverse, &screen).unwrap();
    let truth = render_truth(
        &shape,
        &TruthParams {
            angle: 1.0,
            width: 32,
            height: 32,
            supersample: Supersample::of(3),
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
        let screen = RenderParams { supersample: Supersample::of(3), ..RenderParams::native(&images) };
        let img = render_with(&images, alpha, WarpMethod::Inverse, &screen, &Variant::best().rec).unwrap();
        prop_assert!(img.pixels.iter().flatten().all(|c| c.is_finite() && *c <= 1.0 + 1e-5));
    });
}
