//! Images with parallax from any direction (docs/design.md §7b): a frame warped at its own
//! direction reproduces it; a new direction against a fresh capture there; the cone bounds on a
//! sweep ten times finer than the evaluation; the engine baseline measured, not assumed. Procedural
//! shapes, and for one test the beetle of `../shared/data/meshes/` (skipped with a visible message
//! without it, a failure under `CI=true`). Each floor derived from a measurement has the measured
//! value and its date written beside it.

use altrep::data_gen::{Light, OrthoFrame, capture_frame, scene_shape};
use altrep::metrics::{psnr, silhouette_iou};
use altrep::sphere::{
    Coverage, HoleFill, SphereError, SphereImages, SphereMeasureParams, SphereParams,
    SphereRenderParams, Storage, SurfaceModel, ViewSet, check_bounds, fibonacci_directions,
    measure, measure_stored, render, render_engine_baseline, truth_images,
};
use altrep_data_gen::Supersample;
use approx::assert_abs_diff_eq;
use glam::DVec3;

fn images(shape: &str, grid: usize, size: usize) -> SphereImages {
    let shape = scene_shape(shape).unwrap();
    SphereImages::capture(&shape, &SphereParams::hemisphere(grid, size).unwrap()).unwrap()
}

#[test]
fn a_frame_warped_at_its_own_direction_reproduces_it() {
    let light = Light::default();
    for name in ["truck", "tree"] {
        let img = images(name, 4, 32);
        let params = SphereRenderParams {
            size: 32,
            supersample: Supersample::ONE,
            ..SphereRenderParams::default()
        };
        for k in [0, 5, 6, 15] {
            let frame = &img.frames[k];
            let dir = img.params.set.direction(k);
            let out = render(&img, dir, &params).unwrap();
            let shape = scene_shape(name).unwrap();
            let cap = capture_frame(&shape, &frame.frame, 32, 32).unwrap();
            let (mut covered, mut worst) = (0usize, 0.0f32);
            for (p, (px, s)) in out.image.pixels.iter().zip(&cap.samples).enumerate() {
                let (i, j) = (p % 32, p / 32);
                let (x, y) = OrthoFrame::screen_at(i as f64 + 0.5, j as f64 + 0.5, 32, 32);
                if x * x + y * y >= 1.0 {
                    continue;
                }
                assert_eq!(
                    px[3] > 0.0,
                    s.is_some(),
                    "{name} frame {k} pixel {p}: coverage"
                );
                if let Some(s) = s {
                    covered += 1;
                    // The stored texel, shaded: the warp at t = 0 reads the texel centre.
                    let stored = frame_colour(&img, k, p, &light);
                    for c in 0..3 {
                        worst = worst.max((px[c] - stored[c]).abs());
                    }
                    let z = out.depth[p].unwrap();
                    assert_abs_diff_eq!(z, f64::from(s.depth), epsilon = 2.0 / 65534.0 + 1e-9);
                }
            }
            assert!(covered > 50, "{name} frame {k}: only {covered} texels");
            assert!(worst <= 1e-5, "{name} frame {k}: colour differs by {worst}");
        }
    }
}

/// At a frame's own direction the warp draws that frame's texels (above), so against the truth
/// cast at the same rays it loses only what the stored codes lose (8-bit colour and normals);
/// against the truth of 3 × 3 rays per pixel it also loses the difference in sampling, most of
/// it at the outline. `psnr_same_positions_mean` is the first figure.
#[test]
fn at_a_frames_own_rays_the_warp_meets_the_truth_cast_there() {
    for name in ["truck", "tree"] {
        let shape = scene_shape(name).unwrap();
        let img = images(name, 4, 32);
        let params = SphereMeasureParams {
            directions: 4,
            render: SphereRenderParams {
                size: 32,
                supersample: Supersample::ONE,
                ..SphereRenderParams::default()
            },
            truth_supersample: Supersample::of(3),
        };
        let dirs: Vec<DVec3> = [0, 5, 6, 15].map(|k| img.params.set.direction(k)).to_vec();
        let light = params.render.light;
        let truths = truth_images(&shape, &dirs, 32, Supersample::of(3), &light).unwrap();
        let same = truth_images(&shape, &dirs, 32, Supersample::ONE, &light).unwrap();
        let m = measure(&img, &dirs, &truths, Some(&same), &params).unwrap();
        let at_rays = m.ours.psnr_same_positions_mean.unwrap();
        println!(
            "{name}: at the frames' own rays {at_rays:.2} dB against the truth there, {:.2} dB \
             against the truth of 3 × 3 rays",
            m.ours.psnr_mean
        );
        assert!(
            at_rays >= 0.0,
            "{name}: {at_rays:.2} dB at the frames' own rays"
        );
        assert!(
            at_rays >= m.ours.psnr_mean + 3.0,
            "{name}: sampling costs under 3 dB"
        );
        // Without the truth at the drawing's rays there is no such figure.
        let without = measure(&img, &dirs, &truths, None, &params).unwrap();
        assert_eq!(without.ours.psnr_same_positions_mean, None);
        assert_eq!(without.ours.psnr_mean, m.ours.psnr_mean);
    }
}

/// Block compression as each method ships it (docs/design.md §7b, "Compressed memory"): the
/// bytes fall to 6/10 (exact warp) and 2/8 (baseline), and the pictures, measured against the
/// truth, lose little: the warp keeps its depth and loses its 8-bit colour and normals' last
/// bits; the baseline's colour shares its blocks with the coverage and its depth drops to 8 bits.
#[test]
fn compressed_frames_cost_their_blocks_and_lose_little_against_the_truth() {
    for name in ["truck", "tree"] {
        let shape = scene_shape(name).unwrap();
        let img = images(name, 4, 64);
        let params = SphereMeasureParams {
            directions: 8,
            render: SphereRenderParams {
                size: 64,
                ..SphereRenderParams::default()
            },
            truth_supersample: Supersample::of(3),
        };
        let dirs = fibonacci_directions(8, Coverage::Hemisphere);
        let light = params.render.light;
        let truths = truth_images(&shape, &dirs, 64, Supersample::of(3), &light).unwrap();
        let raw = measure(&img, &dirs, &truths, None, &params).unwrap();
        let c = measure_stored(&img, Storage::Compressed, &dirs, &truths, None, &params).unwrap();
        println!(
            "{name}: exact warp {:.2} → {:.2} dB, {} → {} bytes; one-step baseline {:.2} → {:.2} \
             dB, two-step {:.2} → {:.2} dB, {} → {} bytes; encoding {:.2} s",
            raw.ours.psnr_mean,
            c.ours.psnr_mean,
            raw.bytes_ours,
            c.bytes_ours,
            raw.baseline.psnr_mean,
            c.baseline.psnr_mean,
            raw.baseline_two_step.psnr_mean,
            c.baseline_two_step.psnr_mean,
            raw.bytes_baseline,
            c.bytes_baseline,
            c.encode_s
        );
        assert_eq!(c.storage, Storage::Compressed);
        // 64 is a whole number of blocks: no padding.
        assert_eq!(c.bytes_ours * 10, raw.bytes_ours * 6);
        assert_eq!(c.bytes_baseline * 8, raw.bytes_baseline * 2);
        // Measured: the warp loses 0.00–0.01 dB, the baselines −0.17 to +0.11 dB (the print).
        for (what, before, after, most) in [
            ("exact warp", raw.ours.psnr_mean, c.ours.psnr_mean, 0.25),
            (
                "one-step",
                raw.baseline.psnr_mean,
                c.baseline.psnr_mean,
                1.0,
            ),
            (
                "two-step",
                raw.baseline_two_step.psnr_mean,
                c.baseline_two_step.psnr_mean,
                1.0,
            ),
        ] {
            assert!(
                after >= before - most && after <= before + 0.25,
                "{name}, {what}: {before:.2} → {after:.2} dB"
            );
        }
        // The warp's depth in 8 bits (the baseline's precision): one byte per texel less, the
        // baseline unchanged, and the warp loses little more against the truth.
        let c8 = measure_stored(
            &img,
            Storage::CompressedDepth8,
            &dirs,
            &truths,
            None,
            &params,
        )
        .unwrap();
        println!(
            "{name}: exact warp with 8-bit depth {:.2} dB ({} bytes)",
            c8.ours.psnr_mean, c8.bytes_ours
        );
        assert_eq!(c8.bytes_ours * 10, raw.bytes_ours * 5);
        assert_eq!(c8.baseline.psnr_mean, c.baseline.psnr_mean);
        // Measured 2026-12-08: truck 26.38 → 26.35 dB, tree 30.53 → 30.43 dB; 0.3 dB allowed.
        assert!(
            c8.ours.psnr_mean >= c.ours.psnr_mean - 0.3,
            "{name}: {:.2} → {:.2} dB",
            c.ours.psnr_mean,
            c8.ours.psnr_mean
        );
    }
}

/// A cap on each ray's fetches (`SphereRenderParams::max_steps`): a cap at the longest ray
/// changes nothing; lower caps bound every ray (to the cap plus two fetches per frame asked),
/// stop more rays the lower they are, and cost quality against the truth, measured here.
#[test]
fn a_cap_on_fetches_bounds_every_ray_at_a_measured_cost() {
    let shape = scene_shape("truck").unwrap();
    let img = images("truck", 4, 64);
    let dirs = fibonacci_directions(6, Coverage::Hemisphere);
    let light = SphereRenderParams::default().light;
    let truths = truth_images(&shape, &dirs, 64, Supersample::of(3), &light).unwrap();
    let run = |cap: Option<u32>| {
        let params = SphereMeasureParams {
            directions: dirs.len(),
            render: SphereRenderParams {
                size: 64,
                max_steps: cap,
                ..SphereRenderParams::default()
            },
            truth_supersample: Supersample::of(3),
        };
        measure(&img, &dirs, &truths, None, &params).unwrap().ours
    };
    let free = run(None);
    let loose = run(Some(free.steps_max));
    assert_eq!(loose.psnr_per_direction, free.psnr_per_direction);
    assert_eq!(loose.steps_mean, free.steps_mean);
    assert_eq!(loose.capped_share, 0.0);
    println!(
        "no cap: {:.2} dB, {:.2} fetches per ray, longest {}",
        free.psnr_mean, free.steps_mean, free.steps_max
    );
    // Measured 2026-12-08 on 4 × 4 frames of 64² (28.93 fetches per ray, the longest 124): 0.32,
    // 2.82 and 6.26 dB lost at caps of 64, 32 and 16, with 4.3, 23 and 57 % of the rays capped.
    // A capped ray, and a ray past its cap that no frame sees, is drawn from the enclosing
    // frames' one-step offsets, read where its march stopped. Coloured instead where it stopped
    // (from the texels below that point, where there may be none on the true ray), the same
    // rays lost 1.26, 5.87 and 10.33 dB.
    let mut share = 0.0;
    for (cap, most_lost) in [(64, 0.6), (32, 3.1), (16, 6.6)] {
        let c = run(Some(cap));
        println!(
            "cap {cap}: {:.2} dB, {:.2} fetches per ray, longest {}, rays capped {:.4}",
            c.psnr_mean, c.steps_mean, c.steps_max, c.capped_share
        );
        let asked = 3 + altrep::sphere::DEFAULT_EXTRA_FRAMES as u32;
        assert!(c.steps_max <= cap + 2 * asked, "cap {cap}: {}", c.steps_max);
        assert!(c.capped_share > share, "cap {cap}: no more rays capped");
        share = c.capped_share;
        assert!(
            c.psnr_mean >= free.psnr_mean - most_lost,
            "cap {cap}: {:.2} dB against {:.2}",
            c.psnr_mean,
            free.psnr_mean
        );
    }
}

/// A flat sign seen exactly edge-on shows nothing: the measurement refuses that direction by
/// name instead of scoring it (two empty pictures are not a perfect match).
#[test]
fn a_direction_with_nothing_to_compare_is_named() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cutout.obj");
    let sign = altrep::data_gen::Mesh::load(&path, &Default::default()).unwrap();
    let img = SphereImages::capture(&sign, &SphereParams::hemisphere(4, 32).unwrap()).unwrap();
    let params = SphereMeasureParams {
        directions: 2,
        render: SphereRenderParams {
            size: 32,
            ..SphereRenderParams::default()
        },
        truth_supersample: Supersample::of(3),
    };
    // The sign's plane holds x and y: along x it is seen edge-on.
    let dirs = [DVec3::new(0.6, 0.3, 0.74).normalize(), DVec3::X];
    let light = params.render.light;
    let truths = truth_images(&sign, &dirs, 32, Supersample::of(3), &light).unwrap();
    assert!(truths[1].pixels.iter().all(|p| p[3] == 0.0));
    let err = measure(&img, &dirs, &truths, None, &params).unwrap_err();
    match &err {
        SphereError::EmptyView {
            elevation_deg,
            azimuth_deg,
            size,
            ..
        } => {
            assert_abs_diff_eq!(*elevation_deg, 0.0, epsilon = 1e-9);
            assert_abs_diff_eq!(*azimuth_deg, 0.0, epsilon = 1e-9);
            assert_eq!(*size, 32);
        }
        e => panic!("expected the empty direction named, got {e}"),
    }
    let text = err.to_string();
    assert!(text.contains("elevation 0.0°, azimuth 0.0°"), "{text}");
    // Along the other direction alone it is measured.
    let m = measure(&img, &dirs[..1], &truths[..1], None, &params).unwrap();
    assert!(m.ours.psnr_mean.is_finite());
}

/// The stored texel `p` of frame `k` (32 texels per side), shaded.
fn frame_colour(img: &SphereImages, k: usize, p: usize, light: &Light) -> [f32; 3] {
    let (_, albedo, normal) = img.frames[k].texel(p % 32, p / 32).expect("defined texel");
    light.shade(albedo, normal).to_array()
}

/// Per shape and direction: measured colour PSNR (dB) and IoU against the 1-ray capture along
/// the direction, 2026-12-04; the floors are the measured values less 0.5 dB and 0.01, never
/// below the 24 dB and 0.95 asserted before. Depth errors measured at the same time: medians
/// 0.004, 0.005, 0.007, 0.004 texel pitches (ceiling 0.25), p90 1.115, 0.928, 0.263, 0.250
/// (ceiling 1.5).
const NEW_DIRECTION_MEASURED: [(&str, usize, f64, f64); 4] = [
    ("truck", 0, 24.88, 0.978),
    ("truck", 1, 27.27, 0.981),
    ("pear", 0, 29.73, 0.985),
    ("pear", 1, 34.26, 0.996),
];

#[test]
fn a_new_direction_matches_a_fresh_capture_there() {
    // Directions between frames: depth and colour of the warp against a capture along the
    // direction itself (an independent ray cast; floors in `NEW_DIRECTION_MEASURED`).
    let light = Light::default();
    for name in ["truck", "pear"] {
        let img = images(name, 6, 64);
        let shape = scene_shape(name).unwrap();
        for (which, d) in [
            DVec3::new(0.5, 0.6, 0.3).normalize(),
            DVec3::new(-0.8, 0.25, 0.4).normalize(),
        ]
        .into_iter()
        .enumerate()
        {
            let params = SphereRenderParams {
                size: 64,
                supersample: Supersample::ONE,
                ..SphereRenderParams::default()
            };
            let out = render(&img, d, &params).unwrap();
            let display =
                OrthoFrame::new(img.frames[0].frame.centre, img.frames[0].frame.radius, d).unwrap();
            let cap = capture_frame(&shape, &display, 64, 64).unwrap();
            let mut errs: Vec<f64> = Vec::new();
            for (z, s) in out.depth.iter().zip(&cap.samples) {
                if let (Some(z), Some(s)) = (z, s) {
                    errs.push((z - f64::from(s.depth)).abs());
                }
            }
            errs.sort_by(f64::total_cmp);
            let pitch = 2.0 / 64.0;
            let median = errs[errs.len() / 2];
            let p90 = errs[errs.len() * 9 / 10];
            println!(
                "{name} {d:?}: depth error median {:.3}, p90 {:.3} texel pitches",
                median / pitch,
                p90 / pitch
            );
            assert!(
                median <= 0.25 * pitch,
                "{name}: median depth error {median}"
            );
            assert!(p90 <= 1.5 * pitch, "{name}: p90 depth error {p90}");
            let truth = cap_shaded(&cap, &light);
            let p = psnr(&out.image, &truth).unwrap();
            let iou = silhouette_iou(&out.image, &truth, 0.5).unwrap();
            println!("{name}: colour PSNR {p:.2} dB, IoU {iou:.3} against a 1-ray capture");
            let &(_, _, p_measured, iou_measured) = NEW_DIRECTION_MEASURED
                .iter()
                .find(|m| m.0 == name && m.1 == which)
                .unwrap();
            let (p_floor, iou_floor) = (
                (p_measured - 0.5).max(24.0),
                (iou_measured - 0.01).max(0.95),
            );
            assert!(iou >= iou_floor, "{name} {d}: IoU {iou} below {iou_floor}");
            assert!(p >= p_floor, "{name} {d}: PSNR {p} below {p_floor}");
        }
    }
}

fn cap_shaded(cap: &altrep::data_gen::FrameCapture, light: &Light) -> altrep::data_gen::RgbaImage {
    let mut img = altrep::data_gen::RgbaImage::new(cap.width, cap.height);
    for (px, s) in img.pixels.iter_mut().zip(&cap.samples) {
        if let Some(s) = s {
            let c = light.shade(s.albedo, s.normal);
            *px = [c.x, c.y, c.z, 1.0];
        }
    }
    img
}

#[test]
fn cone_bounds_hold_on_a_sweep_ten_times_finer_than_the_evaluation() {
    for (name, model) in [
        ("truck", SurfaceModel::DEFAULT),
        ("tree", SurfaceModel::DEFAULT),
        ("chair", SurfaceModel::Flat),
    ] {
        let shape = scene_shape(name).unwrap();
        let p = SphereParams {
            set: ViewSet::hemisphere(4).unwrap(),
            size: 32,
            model,
            bounds_block: 1,
        };
        let img = SphereImages::capture(&shape, &p).unwrap();
        let dirs = fibonacci_directions(300, Coverage::Hemisphere);
        let c = check_bounds(&img, &dirs, 32).unwrap();
        println!("{name} {model:?}: {c:?}");
        // Measured 2026-12-04: 629 436, 629 550, 629 362 marches; the floor only guards that
        // the sweep ran.
        assert!(c.marches > 50_000, "{name}: only {} marches", c.marches);
        assert_eq!(c.violations, 0, "{name}: {c:?}");
    }
}

#[test]
fn the_bounds_change_the_cost_not_the_picture() {
    let img = images("chair", 4, 32);
    let d = DVec3::new(0.3, 0.7, -0.5).normalize();
    let with = render(&img, d, &SphereRenderParams::default()).unwrap();
    let without = render(
        &img,
        d,
        &SphereRenderParams {
            use_bounds: false,
            ..SphereRenderParams::default()
        },
    )
    .unwrap();
    assert_eq!(with.image, without.image);
    // Measured 2026-12-04: 16.51 steps with the bounds, 17.26 without.
    println!(
        "mean steps with bounds {:.2}, without {:.2}",
        with.mean_steps(),
        without.mean_steps()
    );
    assert!(with.mean_steps() < without.mean_steps());
    // Counted in full, the bounds cost a read per frame: on this chair they cost more than the
    // march saves (measured 2026-12-07: 25.93 reads per ray with the bounds, 24.02 without).
    println!(
        "mean texel reads with bounds {:.2}, without {:.2}",
        with.mean_reads(),
        without.mean_reads()
    );
}

/// Bounds over 2 × 2 and 4 × 4 texels (`SphereParams::bounds_block`, docs/design.md §7b,
/// "Coarser bounds") on frames whose side is a multiple of neither: they hold on a sweep
/// (no violation), every picture is the one of per-texel bounds bit for bit, and only the
/// march's fetches grow (no fewer than with finer bounds on any direction), for 1/4 and 1/16
/// of the bounds' bytes.
#[test]
fn coarser_bounds_hold_and_change_only_the_cost() {
    let shape = scene_shape("truck").unwrap();
    let at = |block| {
        let p = SphereParams {
            bounds_block: block,
            ..SphereParams::hemisphere(4, 37).unwrap()
        };
        SphereImages::capture(&shape, &p).unwrap()
    };
    let fine = at(1);
    let dirs = fibonacci_directions(12, Coverage::Hemisphere);
    let params = SphereRenderParams {
        size: 64,
        ..SphereRenderParams::default()
    };
    let draw = |img: &SphereImages| -> Vec<altrep::sphere::RenderOutput> {
        dirs.iter()
            .map(|&d| render(img, d, &params).unwrap())
            .collect()
    };
    let base = draw(&fine);
    let mut previous: Vec<f64> = base.iter().map(|o| o.mean_steps()).collect();
    for block in [2, 4] {
        let img = at(block);
        let side = 37usize.div_ceil(block);
        assert_eq!(img.bounds[0].zmin.len(), side * side);
        // 16 frames, 2 bytes per bounds texel: 43,808 bytes per texel, 10,952 and 3,200.
        assert_eq!(img.params.bounds_bytes(), 16 * side * side * 2);
        assert_eq!(fine.params.bounds_bytes(), 16 * 37 * 37 * 2);
        let c = check_bounds(&img, &fibonacci_directions(300, Coverage::Hemisphere), 32).unwrap();
        println!("block {block}: {c:?}");
        assert!(c.marches > 50_000, "block {block}: {c:?}");
        assert_eq!(c.violations, 0, "block {block}: {c:?}");
        let outs = draw(&img);
        let mut steps = Vec::new();
        for (k, (o, b)) in outs.iter().zip(&base).enumerate() {
            assert_eq!(o.image, b.image, "block {block}, direction {k}");
            assert!(
                o.mean_steps() >= previous[k],
                "block {block}, direction {k}"
            );
            steps.push(o.mean_steps());
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        // Measured 2026-12-08: 20.68 fetches per ray with per-texel bounds, 20.69 with either
        // coarser block (on this small grid the outline's reach leaves the bounds little to cut).
        println!(
            "block {block}: march fetches per ray {:.2} (bounds per texel: {:.2})",
            mean(&steps),
            mean(&base.iter().map(|o| o.mean_steps()).collect::<Vec<_>>())
        );
        previous = steps;
    }
}

/// Every texel read is counted (docs/design.md §7b): per ray, the march's fetches, one bounds
/// texel per enclosing frame where bounds are used (at most one per frame), and 9 texels per
/// frame asked for the colour (its depth texel, the four bilinear texels of the colour and of
/// the normal) — every enclosing frame at least for a ray that found a surface, none for a ray
/// the march found free. The engine baseline reads 4 texels per bilinear read, 4·(1 + 3) per
/// frame, on every ray.
#[test]
fn texel_reads_count_the_bounds_the_march_and_the_colour() {
    let img = images("chair", 4, 32);
    let d = DVec3::new(0.3, 0.7, -0.5).normalize();
    let frames = altrep::sphere::enclosing_frames(&img, d).unwrap().len() as u32;
    assert_eq!(frames, 3);
    for use_bounds in [false, true] {
        let params = SphereRenderParams {
            use_bounds,
            ..SphereRenderParams::default()
        };
        let out = render(&img, d, &params).unwrap();
        assert_eq!(out.reads.len(), out.steps.len());
        let (mut hits, mut free) = (0, 0);
        for ((&reads, &steps), &hit) in out.reads.iter().zip(&out.steps).zip(&out.hit) {
            let other = reads - steps;
            let bounds = other % 9;
            assert!(bounds <= if use_bounds { frames } else { 0 }, "{other}");
            if hit {
                hits += 1;
                assert!(other - bounds >= 9 * frames, "{reads} reads, {steps} steps");
            } else if other == bounds {
                free += 1;
            }
        }
        assert!(hits > 100 && free > 100, "{hits} hits, {free} free");
        assert!(out.mean_reads_over_hits() > out.mean_reads());
        assert!(f64::from(out.max_reads()) >= out.mean_reads_over_hits());
        let base = altrep::sphere::render_engine_baseline(&img, d, &params).unwrap();
        assert!(base.reads.iter().all(|&r| r == 4 * 4 * frames));
    }
}

#[test]
fn the_exact_warp_beats_the_engine_baseline_built_from_the_same_frames() {
    // Both measured against the ray-cast truth over 24 directions of the hemisphere, 4 × 4 frames
    // of 48² (the budgets where engine impostors ghost). Measured 2026-12-04: truck ours
    // 28.05 dB (IoU 0.953), baseline 16.66 dB (IoU 0.682); building ours 27.87 dB (IoU 0.954),
    // baseline 16.76 dB (IoU 0.753). Floors against the truth: ours at the measured value less
    // 0.5 dB and 0.01; ours at least 2 dB above the baseline (measured: 11.39 and 11.11 dB).
    for (name, psnr_floor, iou_floor) in [("truck", 27.55, 0.943), ("building", 27.37, 0.944)] {
        let shape = scene_shape(name).unwrap();
        let img = SphereImages::capture(&shape, &SphereParams::hemisphere(4, 48).unwrap()).unwrap();
        let params = SphereMeasureParams {
            directions: 24,
            render: SphereRenderParams {
                size: 64,
                supersample: Supersample::of(2),
                ..SphereRenderParams::default()
            },
            truth_supersample: Supersample::of(3),
        };
        let dirs = fibonacci_directions(params.directions, Coverage::Hemisphere);
        let truths =
            truth_images(&shape, &dirs, 64, Supersample::of(3), &params.render.light).unwrap();
        let m = measure(&img, &dirs, &truths, None, &params).unwrap();
        println!(
            "{name}: ours {:.2} dB (IoU {:.3}, {:.1} steps), baseline {:.2} dB (IoU {:.3})",
            m.ours.psnr_mean,
            m.ours.iou_mean,
            m.ours.steps_mean,
            m.baseline.psnr_mean,
            m.baseline.iou_mean
        );
        assert!(m.baseline.psnr_mean.is_finite() && m.baseline.psnr_mean > 10.0);
        assert!(
            m.ours.psnr_mean >= psnr_floor && m.ours.iou_mean >= iou_floor,
            "{name}: ours {} dB, IoU {} below the floors {psnr_floor} dB, {iou_floor}",
            m.ours.psnr_mean,
            m.ours.iou_mean
        );
        assert!(
            m.ours.psnr_mean >= m.baseline.psnr_mean + 2.0,
            "{name}: ours {} vs baseline {}",
            m.ours.psnr_mean,
            m.baseline.psnr_mean
        );
    }
}

#[test]
fn bad_input_gets_typed_errors() {
    let img = images("pear", 3, 16);
    let below = DVec3::new(0.2, -0.5, 0.1);
    assert!(matches!(
        render(&img, below, &SphereRenderParams::default()),
        Err(SphereError::InvalidParameter { .. })
    ));
    assert!(render_engine_baseline(&img, DVec3::ZERO, &SphereRenderParams::default()).is_err());
    let zero = SphereRenderParams {
        size: 0,
        ..SphereRenderParams::default()
    };
    assert!(render(&img, DVec3::Y, &zero).is_err());
    assert!(SphereParams::hemisphere(4, 1).is_err());
    assert!(SphereParams::hemisphere(1, 32).is_err());
    // Output is finite everywhere, also straight down from the zenith.
    let out = render(&img, DVec3::Y, &SphereRenderParams::default()).unwrap();
    assert!(out.image.pixels.iter().flatten().all(|c| c.is_finite()));
}

#[test]
fn the_engine_baseline_at_a_frames_own_direction_shows_that_frame() {
    // Sanity of the baseline: along a frame's own direction the one-step offset is zero and the
    // blend has one frame, so it must show the stored frame (alpha-tested, bilinear at centres).
    let light = Light::default();
    let img = images("truck", 4, 32);
    let params = SphereRenderParams {
        size: 32,
        supersample: Supersample::ONE,
        ..SphereRenderParams::default()
    };
    for k in [0, 5, 6] {
        let out = render_engine_baseline(&img, img.params.set.direction(k), &params).unwrap();
        let mut stored = altrep::data_gen::RgbaImage::new(32, 32);
        for (p, px) in stored.pixels.iter_mut().enumerate() {
            let (i, j) = ((p % 32) as f64 + 0.5, (p / 32) as f64 + 0.5);
            let (x, y) = OrthoFrame::screen_at(i, j, 32, 32);
            if x * x + y * y >= 1.0 {
                continue;
            }
            if img.frames[k].texel(p % 32, p / 32).is_some() {
                let c = frame_colour(&img, k, p, &light);
                *px = [c[0], c[1], c[2], 1.0];
            }
        }
        let p = psnr(&out.image, &stored).unwrap();
        println!("frame {k}: baseline vs stored frame {p:.2} dB");
        // Measured 2026-12-04: frames 0, 5, 6 at ∞, 184.37 and 192.15 dB (f32 rounding only).
        assert!(p >= 60.0, "frame {k}: {p}");
    }
}

/// An open box (a cup): a floor and four walls 1.1 deep around a 1.0-wide well, checkered so
/// that a phantom surface in the well shows.
fn cup() -> altrep::data_gen::Csg {
    use altrep::data_gen::{Albedo, Csg, Part, Primitive};
    use glam::Vec3;
    let checker = Albedo::Checker {
        a: Vec3::new(0.85, 0.8, 0.7),
        b: Vec3::new(0.2, 0.3, 0.6),
        cell: 0.2,
    };
    let block = |c: DVec3, h: DVec3| Part {
        primitive: Primitive::Box {
            center: c,
            half: h,
            yaw: 0.0,
        },
        albedo: checker.clone(),
    };
    let v = DVec3::new;
    Csg::new(
        "cup",
        vec![
            block(v(0.0, 0.1, 0.0), v(0.6, 0.1, 0.6)),
            block(v(0.55, 0.75, 0.0), v(0.05, 0.55, 0.6)),
            block(v(-0.55, 0.75, 0.0), v(0.05, 0.55, 0.6)),
            block(v(0.0, 0.75, 0.55), v(0.6, 0.55, 0.05)),
            block(v(0.0, 0.75, -0.55), v(0.6, 0.55, 0.05)),
        ],
    )
    .unwrap()
}

/// Where a view set fails: looking (almost) straight down into a concave object, the cup, at 8
/// directions 84–89° up, 64² with 2 × 2 rays, truth 3 × 3, frames of 50². Even grids have no
/// frame at the zenith; the enclosing frames there are tilted (G = 4: 26.6°, G = 8: 9.5°), so
/// the floor along the walls is hidden from all of them. The extra frames (the default, 8) see
/// most of it: holes (points no frame asked sees) fall to at most 0.13 % on every grid (without
/// them: 0.94 %, 0.17 %, 0.82 %, 0.33 %).
///
/// Known loss, not diagnosed: the even grids still score below the odd ones, G = 8 by about
/// 3 dB below G = 9 (21.28 against 24.26 dB, measured 2026-12-04), and the hole share no longer
/// explains it (0.0000 at G = 8). An odd grid puts a frame at the zenith, for (G + 1)²/G² of
/// the memory. The test asserts each grid's floor against the ray-cast truth and does not
/// require the loss to persist: a fix of the 8 × 8 case passes it.
///
/// Measured 2026-12-04 (ours against the truth, hole share, engine blend of the same frames):
///   G = 4: 23.75 dB, holes 0.0013, blend 18.25 dB | G = 5: 24.14 dB, holes 0.0000, blend 19.02 dB
///   G = 8: 21.28 dB, holes 0.0000, blend 19.92 dB | G = 9: 24.26 dB, holes 0.0006, blend 20.38 dB
/// (without extra frames, with the default hole depth: 21.93, 24.06, 21.26, 24.19 dB). Floors:
/// the measured PSNR less 0.5 dB; holes below 0.2 % on every grid; ours at least 1 dB above the
/// blend (measured: 5.50, 5.12, 1.36, 3.88 dB).
#[test]
fn straight_down_into_a_cup_needs_a_frame_at_the_zenith() {
    let shape = cup();
    let dirs: Vec<DVec3> = (0..8)
        .map(|k| {
            let (e, a) = ((84.0 + k as f64 * 0.75).to_radians(), k as f64 * 0.9);
            DVec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
        })
        .collect();
    let params = SphereMeasureParams {
        directions: dirs.len(),
        render: SphereRenderParams {
            size: 64,
            supersample: Supersample::of(2),
            ..SphereRenderParams::default()
        },
        truth_supersample: Supersample::of(3),
    };
    let truths = truth_images(&shape, &dirs, 64, Supersample::of(3), &params.render.light).unwrap();
    let mut holes = Vec::new();
    for (g, floor) in [(4, 23.25), (5, 23.64), (8, 20.78), (9, 23.76)] {
        let img = SphereImages::capture(&shape, &SphereParams::hemisphere(g, 50).unwrap()).unwrap();
        let r = measure(&img, &dirs, &truths, None, &params).unwrap();
        println!(
            "cup from 84–89° elevation, {g}×{g} frames of 50²: ours {:.2} dB (holes {:.4}), baseline {:.2} dB",
            r.ours.psnr_mean, r.ours.hole_share, r.baseline.psnr_mean
        );
        assert!(
            r.ours.psnr_mean >= floor,
            "G = {g}: {:.2} dB against the truth, below the floor {floor}",
            r.ours.psnr_mean
        );
        assert!(r.ours.psnr_mean > r.baseline.psnr_mean + 1.0, "G = {g}");
        assert!(
            r.ours.hole_share < 0.002,
            "G = {g}: holes {} with the extra frames",
            r.ours.hole_share
        );
        holes.push(r.ours.hole_share);
    }
    assert!(
        holes[1] <= holes[0],
        "G = 5 holes {} vs G = 4 {}",
        holes[1],
        holes[0]
    );
}

#[test]
fn a_hole_depth_empties_only_holes_deeper_than_it() {
    // Holes coloured from the nearest frame surface (`HoleFill::Nearest`). Straight down into
    // the cup with 4 × 4 frames: some rays reach floor points no frame sees (holes). With a hole
    // depth larger than any possible gap (the sphere's diameter) the picture is the one with
    // every hole coloured; with a tiny one every hole ray is empty and nothing else changes.
    let img = SphereImages::capture(&cup(), &SphereParams::hemisphere(4, 50).unwrap()).unwrap();
    let d = DVec3::new(0.05, 1.0, 0.03).normalize();
    let rp = SphereRenderParams {
        size: 64,
        holes: HoleFill::Nearest,
        hole_depth: None,
        ..SphereRenderParams::default()
    };
    let base = render(&img, d, &rp).unwrap();
    assert!(base.holes > 0, "the view must have holes");
    let wide = render(
        &img,
        d,
        &SphereRenderParams {
            hole_depth: Some(2.5),
            ..rp
        },
    )
    .unwrap();
    assert_eq!(wide.image, base.image);
    let tiny = render(
        &img,
        d,
        &SphereRenderParams {
            hole_depth: Some(1e-12),
            ..rp
        },
    )
    .unwrap();
    assert_eq!(tiny.holes, base.holes, "holes are still counted");
    assert_eq!(tiny.steps, base.steps, "the march is the same");
    let covered =
        |o: &altrep::sphere::RenderOutput| o.image.pixels.iter().filter(|p| p[3] > 0.0).count();
    // One ray per pixel: each hole ray empties its pixel.
    assert_eq!(covered(&base) - covered(&tiny), base.holes);
    for (a, b) in tiny.image.pixels.iter().zip(&base.image.pixels) {
        assert!(
            a == b || a[3] == 0.0,
            "only hole pixels change, and only to empty"
        );
    }
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(
            render(
                &img,
                d,
                &SphereRenderParams {
                    hole_depth: Some(bad),
                    ..rp
                }
            )
            .is_err(),
            "hole depth {bad}"
        );
    }
}

#[test]
fn extra_frames_change_only_rays_no_enclosing_frame_sees_and_gain_against_the_truth() {
    // The truck seen low over the horizon and the chair from below the seat on 4 × 4 frames:
    // some rays reach points none of the three enclosing frames sees (holes). Asking more
    // frames changes those rays only (one ray per pixel: a pixel changes only if its ray was a
    // hole without them), leaves fewer holes, and draws closer to the ray-cast truth. Measured
    // 2026-12-04: truck 23.15 → 23.55 dB (74 → 0 holes), chair 22.70 → 24.05 dB (389 → 119).
    let light = Light::default();
    for (shape, coverage) in [("truck", Coverage::Hemisphere), ("chair", Coverage::Sphere)] {
        let s = scene_shape(shape).unwrap();
        let params = SphereParams {
            set: ViewSet::new(coverage, 4).unwrap(),
            size: 48,
            model: SurfaceModel::DEFAULT,
            bounds_block: 1,
        };
        let img = SphereImages::capture(&s, &params).unwrap();
        let dirs: Vec<DVec3> = (0..6)
            .map(|k| {
                let e = if shape == "chair" { -0.25 } else { 0.2 };
                let a = 0.4 + k as f64 * 1.05;
                DVec3::new(a.cos(), e, a.sin()).normalize()
            })
            .collect();
        let truths = truth_images(&s, &dirs, 64, Supersample::ONE, &light).unwrap();
        let (mut db0, mut db8, mut holes0, mut holes8) = (0.0, 0.0, 0, 0);
        for (d, truth) in dirs.iter().zip(&truths) {
            let rp = SphereRenderParams {
                size: 64,
                extra_frames: 0,
                ..SphereRenderParams::default()
            };
            let without = render(&img, *d, &rp).unwrap();
            let with = render(
                &img,
                *d,
                &SphereRenderParams {
                    extra_frames: altrep::sphere::MAX_EXTRA_FRAMES,
                    ..rp
                },
            )
            .unwrap();
            let changed = without
                .image
                .pixels
                .iter()
                .zip(&with.image.pixels)
                .filter(|(a, b)| a != b)
                .count();
            assert!(
                changed <= without.holes,
                "{shape}: {changed} pixels changed, {} holes",
                without.holes
            );
            holes0 += without.holes;
            holes8 += with.holes;
            db0 += psnr(&without.image, truth).unwrap() / dirs.len() as f64;
            db8 += psnr(&with.image, truth).unwrap() / dirs.len() as f64;
        }
        println!(
            "{shape}, 4 × 4 frames of 48², 6 low directions: no extra frames {db0:.2} dB ({holes0} holes), 8 extra frames {db8:.2} dB ({holes8} holes)"
        );
        assert!(holes0 > 0, "{shape}: the directions must have holes");
        assert!(holes8 < holes0, "{shape}: holes {holes8} against {holes0}");
        assert!(db8 >= db0, "{shape}: {db8} dB against {db0}");
    }
}

/// Holes drawn from the one-step offsets (`HoleFill::Offsets`, the default) against holes
/// coloured from the nearest frame surface within the hole depth (`HoleFill::Nearest`): on the
/// beetle, an open shell whose windows show space no enclosing frame looks into, the offsets
/// gain; over the upper hemisphere of opaque subjects, whose few holes lie in concavities, they
/// change little; the chair seen from below loses a little. The march is the same either way.
/// Needs `../shared` for the beetle (skipped loudly without it, a failure under `CI=true`).
#[test]
fn holes_drawn_from_the_offsets_gain_on_a_see_through_shell() {
    let run = |shape: &dyn altrep::data_gen::Shape, coverage: Coverage, grid: usize| {
        let params = SphereParams {
            set: ViewSet::new(coverage, grid).unwrap(),
            ..SphereParams::hemisphere(grid, 64).unwrap()
        };
        let img = SphereImages::capture(shape, &params).unwrap();
        let dirs = fibonacci_directions(12, coverage);
        let light = SphereRenderParams::default().light;
        let truths = truth_images(shape, &dirs, 64, Supersample::of(3), &light).unwrap();
        let m = |holes: HoleFill| {
            let params = SphereMeasureParams {
                directions: dirs.len(),
                render: SphereRenderParams {
                    size: 64,
                    holes,
                    ..SphereRenderParams::default()
                },
                truth_supersample: Supersample::of(3),
            };
            measure(&img, &dirs, &truths, None, &params).unwrap().ours
        };
        let (offsets, nearest) = (m(HoleFill::Offsets), m(HoleFill::Nearest));
        assert_eq!(offsets.steps_mean, nearest.steps_mean);
        assert_eq!(offsets.hole_share, nearest.hole_share);
        (offsets.psnr_mean, nearest.psnr_mean, offsets.hole_share)
    };
    let tree = scene_shape("tree").unwrap();
    for (name, shape) in [
        ("tree", &tree as &dyn altrep::data_gen::Shape),
        ("cup", &cup()),
    ] {
        let (o, n, holes) = run(shape, Coverage::Hemisphere, 4);
        println!(
            "{name}, 4 × 4 frames of 64²: offsets {o:.2} dB, nearest {n:.2} dB, holes {holes:.4}"
        );
        assert!(holes > 0.0, "{name}: no hole to draw");
        // Measured 2026-12-08: within 0.1 dB either way; 0.2 allowed.
        assert_abs_diff_eq!(o, n, epsilon = 0.2);
    }
    // The chair from every side: under its seat the nearest surface is the better guess.
    // Measured 2026-12-08: 0.21 dB below it; 0.4 allowed.
    let (o, n, holes) = run(&scene_shape("chair").unwrap(), Coverage::Sphere, 4);
    println!(
        "chair, whole sphere, 4 × 4 frames of 64²: offsets {o:.2} dB, nearest {n:.2} dB, holes {holes:.4}"
    );
    assert!(holes > 0.0, "chair: no hole to draw");
    assert!(o >= n - 0.4, "offsets {o:.2} dB against nearest {n:.2}");
    let Some(beetle) = altrep::data_gen::shared_mesh("beetle", "the see-through shell's holes")
    else {
        return;
    };
    let (o, n, holes) = run(&beetle, Coverage::Hemisphere, 8);
    println!("beetle, 8 × 8 frames of 64²: offsets {o:.2} dB, nearest {n:.2} dB, holes {holes:.4}");
    assert!(holes > 0.001, "the beetle must show holes: {holes}");
    // Measured 2026-12-08: 24.01 against 23.53 dB (+0.48); at least +0.3 asked.
    assert!(o >= n + 0.3, "offsets {o:.2} dB against nearest {n:.2}");
}
