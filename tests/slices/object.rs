//! Slices holding one object (docs/design.md §9.4): the renderer against a closed-form
//! composite of the voxels, merged levels against level 0 where merging is exact, the planner's
//! choice of axes and levels from the needs, and the pipeline's figures against the ray-cast
//! ground truth of the object.

use altrep::pipeline::{Lighting, Manifest, Needs, Outcome, Representation, RunOptions, Source};
use altrep::slices::asset::{SlicesRepr, SlicesSpec};
use altrep::slices::{
    MergeRule, ShapeParams, SliceParams, build_slices, choose_stored, from_shape, render_object,
};
use altrep_data_gen::{Light, OrthoFrame, Supersample, scene_shape};
use approx::assert_abs_diff_eq;
use glam::DVec3;

/// The chair voxelised as one object in its box `[−1, 1] × [0, 2] × [−1, 1]`, `n³` voxels.
fn chair_volume(n: usize) -> altrep::slices::TexelVolume {
    object_volume("chair", n)
}

/// data-gen's scene shape `shape` voxelised as one object in its box, `n³` voxels.
fn object_volume(shape: &str, n: usize) -> altrep::slices::TexelVolume {
    shape_volume(&scene_shape(shape).unwrap(), n)
}

/// [`object_volume`] of any shape (the fill chosen by the shape: [`altrep_data_gen::Fill::Auto`]).
fn shape_volume(shape: &dyn altrep_data_gen::Shape, n: usize) -> altrep::slices::TexelVolume {
    from_shape(
        shape,
        &ShapeParams {
            dims: [n; 3],
            voxel: 2.0 / n as f64,
            min: [-1.0, 0.0, -1.0],
            supersample: Supersample::of(2),
            tiled: false,
            ..ShapeParams::default()
        },
    )
    .unwrap()
}

/// Seen along an axis with one pixel per voxel, pixel centres on texel centres, every level of
/// a per-side merge (composites, not fitted to bilinear filtering) draws the composite of the
/// voxel column: level 0 equals the `over` composite of the voxels computed here (1e-5), and
/// every merged level equals level 0 (1e-5), from both sides of all three axes.
#[test]
fn seen_along_an_axis_every_level_draws_the_composite_of_the_voxel_column() {
    let n = 16;
    let volume = chair_volume(n);
    let (data, _) = build_slices(
        &volume,
        &SliceParams {
            tiled: false,
            fit_bilinear: false,
            ..SliceParams::default()
        },
    )
    .unwrap();
    let min = DVec3::new(-1.0, 0.0, -1.0);
    for (axis, sign) in [
        (0usize, 1.0),
        (0, -1.0),
        (1, 1.0),
        (1, -1.0),
        (2, 1.0),
        (2, -1.0),
    ] {
        let mut dir = DVec3::ZERO;
        dir[axis] = sign;
        let frame = OrthoFrame::new(DVec3::Y, 1.0, dir).unwrap();
        let a = altrep::slices::Axis::ALL[axis];
        let level0 = render_object(&data, (a, 0), &frame, min, (n, n), Supersample::ONE).unwrap();
        // The composite of the column under each pixel centre, nearest voxel first.
        for j in 0..n {
            for i in 0..n {
                let x = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
                let y = 1.0 - (j as f64 + 0.5) * 2.0 / n as f64;
                let p = frame.centre + x * frame.right + y * frame.up - min;
                let mut c = [
                    (p.x * n as f64 / 2.0) as usize,
                    (p.y * n as f64 / 2.0) as usize,
                    (p.z * n as f64 / 2.0) as usize,
                ];
                let mut acc = [0.0f64; 4];
                for k in 0..n {
                    c[axis] = if sign > 0.0 { n - 1 - k } else { k };
                    let v = volume.get(c[0], c[1], c[2]);
                    let t = 1.0 - acc[3];
                    for q in 0..4 {
                        acc[q] += t * f64::from(v[q]);
                    }
                }
                let got = level0.image.pixels[j * n + i];
                for q in 0..4 {
                    assert_abs_diff_eq!(f64::from(got[q]), acc[q], epsilon = 1e-5);
                }
            }
        }
        assert!(level0.covered_pixels > 0);
        assert!((1.0..=n as f64).contains(&level0.steps_per_pixel));
        for level in 1..=4 {
            let merged =
                render_object(&data, (a, level), &frame, min, (n, n), Supersample::ONE).unwrap();
            for (p, q) in merged.image.pixels.iter().zip(&level0.image.pixels) {
                for c in 0..4 {
                    assert_abs_diff_eq!(p[c], q[c], epsilon = 1e-5);
                }
            }
            // A merged level holds, and reads at most, 2^level times fewer slices per pixel.
            assert!(merged.steps_per_pixel <= (n >> level) as f64);
        }
    }
}

/// The level a view draws: the direction rule among the stored axes, the criterion's level,
/// else the coarsest stored one finer than it.
#[test]
fn a_view_draws_the_stored_stack_the_rule_and_the_criterion_pick() {
    let volume = chair_volume(16);
    let (data, _) = build_slices(
        &volume,
        &SliceParams {
            axes: [false, true, true],
            levels: Some(vec![0, 2]),
            rule: MergeRule::Symmetric,
            tiled: false,
            ..SliceParams::default()
        },
    )
    .unwrap();
    let s = 2.0 / 16.0;
    // Straight along z: one slice is enough; the coarsest stored level is 2.
    let c = choose_stored(&data, DVec3::Z, s).unwrap();
    assert_eq!((c.axis, c.level, c.needed), (altrep::slices::Axis::Z, 2, 1));
    // Along x, not stored: the rule falls back to z or y; 45° between x and z picks z.
    let v = DVec3::new(1.0, 0.0, 1.0).normalize();
    let c = choose_stored(&data, v, s).unwrap();
    assert_eq!(c.axis, altrep::slices::Axis::Z);
    // tan 45° · 2 / (1/8) = 16 slices needed: level 0.
    assert_eq!((c.level, c.needed), (0, 16));
    // Three slices needed: level 2 holds 4, level 1 is not stored, so level 0 (finer) is drawn.
    let v = DVec3::new(0.2, 0.0, 1.0).normalize();
    let c = choose_stored(&data, v, s).unwrap();
    assert_eq!((c.level, c.needed), (2, 4));
    let v = DVec3::new(0.3, 0.0, 1.0).normalize();
    let c = choose_stored(&data, v, s).unwrap();
    assert_eq!(c.needed, 5);
    assert_eq!(c.level, 0);
}

fn source<'a>(shape: &'a (dyn altrep_data_gen::Shape + Sync)) -> Source<'a> {
    Source {
        name: "tree",
        geometry: Some(shape),
        texture: None,
        tile: None,
        light: Light::default(),
        placement: None,
    }
}

/// Horizontal views round the z axis draw the z stack only; the planner skips the others and
/// the levels no needed view and screen size draws, each with its reason; views from above add
/// the y stack; dynamic lighting is refused, naming the way out.
#[test]
fn the_planner_builds_the_axes_and_levels_the_needs_draw() {
    let shape = scene_shape("tree").unwrap();
    let src = source(&shape);
    let spec = SlicesSpec::default();
    let road = Needs {
        azimuth_deg: [80.0, 100.0],
        screen_px: [4.0, 24.0],
        lighting: Lighting::Baked,
        ..Needs::default()
    };
    let (plan, d) = SlicesRepr::plan(&spec, &road, &src).unwrap();
    assert!(plan.refused.is_none());
    assert_eq!(d.resolution, 32);
    assert_eq!(d.axes, [false, false, true]);
    // At 80° from x, 24 px: ⌈2·tan 10° / (2/24)⌉ = 5 slices, level 2 (8 slices); at 90°, one.
    assert_eq!(d.levels, vec![2, 3, 4, 5]);
    let skipped: Vec<String> = plan.skipped().map(|i| i.what.clone()).collect();
    assert!(
        skipped.iter().any(|s| s.starts_with("x stack")),
        "{skipped:?}"
    );
    assert!(
        skipped.iter().any(|s| s.starts_with("y stack")),
        "{skipped:?}"
    );
    assert!(
        skipped.iter().any(|s| s.starts_with("levels 0–1")),
        "{skipped:?}"
    );
    assert!(skipped.iter().any(|s| s.starts_with("64³")), "{skipped:?}");
    let above = Needs {
        elevation_deg: [30.0, 90.0],
        ..road.clone()
    };
    let (_, d) = SlicesRepr::plan(&spec, &above, &src).unwrap();
    assert!(d.axes[1] && d.axes[2], "{:?}", d.axes);
    let lit = Needs {
        lighting: Lighting::Dynamic,
        ..road
    };
    let (plan, _) = SlicesRepr::plan(&spec, &lit, &src).unwrap();
    assert!(
        plan.refused
            .as_deref()
            .unwrap()
            .contains("lighting = \"baked\"")
    );
}

/// The pipeline's figures against the ray-cast ground truth of the object: the tree seen from a
/// road (45°–135°, up to 24 px) measures 27.75 dB mean PSNR at 32³ voxels and the chair from up to
/// 60° of elevation (up to 64 px) 26.87 dB at 64³ (1 dB of margin here), with silhouette IoUs
/// of 0.898 and 0.921 (0.88 asserted) and fewer slices per pixel than voxels across.
#[test]
fn slices_of_the_tree_and_the_chair_measure_against_the_object_truth() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"
[[asset]]
name = "tree"
shape = "tree"
[asset.needs]
azimuth_deg = [45, 135]
screen_px = [4, 24]
lighting = "baked"
[asset.slices]
[[asset]]
name = "chair"
shape = "chair"
[asset.needs]
screen_px = [8, 64]
elevation_deg = [0, 60]
lighting = "baked"
[asset.slices]
"#;
    let m = Manifest::parse(text, std::path::Path::new("scene.toml")).unwrap();
    let run = altrep::pipeline::run_scene(&m, &RunOptions::new(dir.path())).unwrap();
    assert!(run.ok(), "{}", run.table());
    for (asset, psnr, voxels) in [("tree", 27.75, 32.0), ("chair", 26.87, 64.0)] {
        let o = run.outcomes.iter().find(|o| o.asset == asset).unwrap();
        assert_eq!(o.outcome, Outcome::Built);
        let m = o.measurement.as_ref().unwrap();
        assert!(m.psnr_db > psnr - 1.0, "{asset}: {m:?}");
        assert!(m.iou > 0.88, "{asset}: {m:?}");
        let steps = m.mean_steps.unwrap();
        assert!(steps > 1.0 && steps < voxels, "{asset}: {m:?}");
    }
}

/// Merging beats dropping slices on a volume voxelised from a mesh (docs/design.md §9.5): the
/// chair in its box at 32³, seen from 8 directions 16 px across the box (every view merges),
/// the stack the rule and the criterion pick, 1 sample per pixel with trilinear 2D reads;
/// per-side merges fitted to bilinear filtering against one layer kept per slab, both measured
/// against the object's ray-cast truth (3 × 3 rays per pixel): mean gain ≥ 3 dB (3.90 dB
/// measured). Data-gen's leaf shrub (300 alpha-masked cards, voxelised as a shell) gains
/// +2.81 dB (+2.82 unfitted), short of 3 dB: 6.1–6.4 dB from 20° below, 0.9 dB from 55° above.
/// The solid tree loses instead (−1.30 dB; −0.71 dB unfitted): docs/design.md §9.5.
#[test]
fn merging_beats_dropping_on_a_volume_from_a_mesh() {
    let n = 32;
    let size = 16;
    let shrub = altrep_data_gen::Mesh::from_gltf_bytes(
        &altrep_data_gen::gltf_write::TestGltf::leaf_shrub(300, 7)
            .to_glb()
            .unwrap(),
        std::path::Path::new("shrub.glb"),
        &altrep_data_gen::MeshLoadOptions::default(),
    )
    .unwrap();
    // (shape, least mean gain): the goal on the chair; on the shrub the measured gain less a
    // margin (the goal is missed there).
    let objects: [(&str, Box<dyn altrep_data_gen::Shape>, f64); 2] = [
        ("chair", Box::new(scene_shape("chair").unwrap()), 3.0),
        ("shrub", Box::new(shrub), 2.5),
    ];
    for (shape, object, least) in &objects {
        let object = object.as_ref();
        let volume = shape_volume(object, n);
        let build = |rule| {
            let params = SliceParams {
                rule,
                tiled: false,
                ..SliceParams::default()
            };
            build_slices(&volume, &params).unwrap().0
        };
        let (merged, dropped) = (build(MergeRule::PerSide), build(MergeRule::Drop));
        let min = DVec3::new(-1.0, 0.0, -1.0);
        let mut gains = Vec::new();
        for k in 0..8 {
            let az = (f64::from(k) * 45.0 + 10.0).to_radians();
            let el = (f64::from(k % 4) * 25.0 - 20.0).to_radians();
            let dir = DVec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin());
            let frame = OrthoFrame::new(DVec3::Y, 1.0, dir).unwrap();
            let c = choose_stored(&merged, dir, 2.0 / size as f64).unwrap();
            assert!(c.level >= 1, "{shape} {k}: {c:?}");
            let truth = altrep_data_gen::render_truth_frame(
                object,
                &frame,
                size,
                size,
                Supersample::of(3),
                &Light::default(),
            )
            .unwrap();
            let db = |data| {
                let img = render_object(
                    data,
                    (c.axis, c.level),
                    &frame,
                    min,
                    (size, size),
                    Supersample::ONE,
                )
                .unwrap();
                altrep::metrics::psnr(&img.image, &truth).unwrap()
            };
            gains.push(db(&merged) - db(&dropped));
        }
        let mean = gains.iter().sum::<f64>() / gains.len() as f64;
        eprintln!("{shape}: merge − drop {mean:+.2} dB mean, per view {gains:.2?}");
        assert!(mean >= *least, "{shape}: merge − drop {mean:.2} dB");
    }
}

mod adversarial {
    use super::*;
    use altrep::slices::{Axis, SliceData, SliceError, StoredStack};
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(20261206), ..ProptestConfig::default() })]

        /// Random object volumes (empty and opaque voxels included), any frame, including
        /// directions along an axis or within rounding of a slice plane, any stored level: an
        /// image in [0, 1] with colour ≤ alpha and at most one read per slice per pixel, or a
        /// typed error — never a panic or NaN.
        #[test]
        fn random_object_volumes_and_frames_draw_finite(
            lx in 0u32..4, ly in 0u32..4, lz in 0u32..4, seed in any::<u64>(),
            dx in -1.0f64..1.0, dy in -1.0f64..1.0, dz in -1.0f64..1.0, snap in 0usize..4,
            radius in 0.01f64..4.0, level in 0usize..4, axis in 0usize..3, side in 1usize..6,
        ) {
            let vol = super::super::random_volume([1 << lx, 1 << ly, 1 << lz], seed);
            let (data, _) = build_slices(&vol, &SliceParams { tiled: false, ..SliceParams::default() }).unwrap();
            let mut dir = DVec3::new(dx, dy, dz);
            if snap < 3 {
                // Along an axis, up to a rounding error.
                dir = DVec3::ZERO;
                dir[snap] = if dx < 0.0 { -1.0 } else { 1.0 };
                dir[(snap + 1) % 3] = 1e-17 * dy;
            }
            let Ok(frame) = OrthoFrame::new(DVec3::new(0.0, 1.0, 0.0), radius, dir) else {
                return Ok(());
            };
            let min = DVec3::new(-1.0, 0.0, -1.0);
            match render_object(&data, (Axis::ALL[axis], level), &frame, min, (side, side), Supersample::of(2)) {
                Ok(out) => {
                    let count = data.dims()[axis] >> level;
                    for (p, s) in out.image.pixels.iter().zip(&out.steps) {
                        prop_assert!(p.iter().all(|c| c.is_finite()));
                        prop_assert!(p[3] >= -1e-6 && p[3] <= 1.0 + 1e-5);
                        prop_assert!(p[..3].iter().all(|c| *c >= -1e-6 && *c <= p[3] + 1e-5));
                        prop_assert!(*s as usize <= 4 * count);
                    }
                    prop_assert!(out.steps_per_pixel.is_finite());
                }
                Err(SliceError::MissingStack { .. }) => prop_assert!(level > data.dims()[axis].trailing_zeros() as usize),
                Err(e) => prop_assert!(false, "unexpected error {e}"),
            }
            let choice = choose_stored(&data, dir, 2.0 / side as f64);
            if let Ok(c) = choice {
                prop_assert!(c.level <= data.dims()[c.axis.index()].trailing_zeros() as usize);
            }
        }

        /// The reader's constructor given stacks of random counts, sizes, channels, levels and
        /// sides: slice data, or a typed error — never a panic.
        #[test]
        fn stored_stacks_of_any_shape_are_refused_or_read(
            n in 0usize..6, level in 0usize..4, count in 0usize..5, w in 0usize..5, h in 0usize..5,
            channels in 3usize..5, minus in any::<bool>(), rule in 0usize..5, axis in 0usize..3,
            twice in any::<bool>(), voxel in prop_oneof![Just(f64::NAN), Just(0.0), Just(-1.0), Just(0.25)],
            nan in any::<bool>(),
        ) {
            let dims = [n, 4, 4];
            let tex = || {
                let mut data = vec![0.5f32; w * h * channels];
                if nan && !data.is_empty() {
                    data[0] = f32::NAN;
                }
                altrep::mip::Texture::new(w, h, channels, data)
            };
            let Ok(t) = tex() else { return Ok(()) };
            let stack = StoredStack {
                axis: Axis::ALL[axis],
                level,
                plus: vec![t.clone(); count],
                minus: minus.then(|| vec![t.clone(); count]),
            };
            let mut stored = vec![stack.clone()];
            if twice {
                stored.push(stack);
            }
            if let Ok(d) = SliceData::from_stored(dims, voxel, MergeRule::ALL[rule], false, stored) {
                prop_assert!(n.is_power_of_two() && voxel > 0.0 && !twice && !nan);
                prop_assert_eq!(d.stacks().len(), 1);
            }
        }
    }
}

/// A procedural tile as an asset source (`tile = { … }`): slices only, measured against the
/// ray-marched tile; read back as a tiling volume that writes the same files again.
mod tiles {
    use super::*;
    use altrep::asset::AssetReader;
    use altrep::pipeline::PipelineError;

    const LAWN: &str = r#"
[[asset]]
name = "lawn"
tile = { kind = "grass", size = 32, seed = 1 }
[asset.needs]
screen_px = [16, 64]
grazing_deg = 80
lighting = "baked"
[asset.slices]
[[asset]]
name = "pelt"
tile = { kind = "fur", size = 32, seed = 1 }
[asset.needs]
screen_px = [8, 32]
grazing_deg = 60
lighting = "baked"
[asset.slices]
"#;

    /// The grass tile seen up to 64 px and 80° from its normal measures 40.04 dB mean PSNR
    /// against the ray-marched tile, the fur tile up to 32 px and 60° 35.57 dB (1 dB of margin
    /// here; 39.22 and 33.58 dB before the merged slices were fitted to bilinear filtering),
    /// silhouettes 0.987 and 0.975 (0.94 asserted); the folder opens as tiling slices
    /// (box from the origin) that write the same files again.
    #[test]
    fn tile_slices_measure_against_the_ray_marched_tile() {
        let dir = tempfile::tempdir().unwrap();
        let m = Manifest::parse(LAWN, std::path::Path::new("scene.toml")).unwrap();
        let run = altrep::pipeline::run_scene(&m, &RunOptions::new(dir.path())).unwrap();
        assert!(run.ok(), "{}", run.table());
        for (asset, psnr) in [("lawn", 40.04), ("pelt", 35.57)] {
            let o = run.outcomes.iter().find(|o| o.asset == asset).unwrap();
            assert_eq!(o.outcome, Outcome::Built);
            let m = o.measurement.as_ref().unwrap();
            assert!(m.psnr_db > psnr - 1.0, "{asset}: {m:?}");
            assert!(m.iou > 0.94, "{asset}: {m:?}");
        }
        let folder = dir.path().join("lawn/slices");
        let r = AssetReader::open(&folder).unwrap();
        assert_eq!(r.description().metadata["tiled"], true);
        let loaded = SlicesRepr::read(&r).unwrap();
        assert!(loaded.slices.tiled());
        let again = tempfile::tempdir().unwrap();
        let mut w = altrep::asset::AssetWriter::new(again.path(), "lawn", "slices").unwrap();
        let meta = SlicesRepr::write(&loaded, &mut w).unwrap();
        assert_eq!(meta, r.description().metadata);
        let desc = w
            .commit(
                "slices",
                "lawn",
                "key",
                altrep::asset::Conventions::new(1.0, 2.0),
                meta,
                serde_json::Value::Null,
            )
            .unwrap();
        let hashes = |d: &altrep::asset::AssetDescription| -> Vec<(String, String)> {
            d.files
                .iter()
                .map(|f| (f.path.clone(), f.blake3.clone()))
                .collect()
        };
        assert_eq!(hashes(&desc), hashes(r.description()));
    }

    /// The fur tile 8 px across, seen up to 80° from its normal over a quarter turn, as asset
    /// `name`, with `extra` under `[asset.slices]`.
    fn pelt(name: &str, extra: &str) -> String {
        format!(
            "[[asset]]\nname = \"{name}\"\ntile = {{ kind = \"fur\", size = 32, seed = 1 }}\n\
             [asset.needs]\nscreen_px = [8, 8]\ngrazing_deg = 80\nazimuth_deg = [0, 90]\n\
             lighting = \"baked\"\n[asset.slices]\n{extra}"
        )
    }

    /// `direction_table = true` measures the error of every built stack over the needed views
    /// and draws the direction it predicts closest to the truth: measured at the asset's four
    /// views (between the table's nodes), the fur tile 8 px across up to 80° from its normal is
    /// 30.42 dB from the ray-marched tile against 29.90 dB with the direction rule (at 50° the
    /// table draws `z1` where the rule draws `y1`; 0.25 dB asserted). The table is written in
    /// the metadata and read back bit for bit; an object cannot have one.
    #[test]
    fn a_measured_direction_table_draws_no_worse_than_the_rule() {
        let dir = tempfile::tempdir().unwrap();
        let text = pelt("rule", "") + &pelt("table", "direction_table = true\n");
        let m = Manifest::parse(&text, std::path::Path::new("scene.toml")).unwrap();
        let run = altrep::pipeline::run_scene(&m, &RunOptions::new(dir.path())).unwrap();
        assert!(run.ok(), "{}", run.table());
        let psnr = |asset: &str| {
            let o = run.outcomes.iter().find(|o| o.asset == asset).unwrap();
            assert_eq!(o.outcome, Outcome::Built);
            o.measurement.as_ref().unwrap().clone()
        };
        let (rule, table) = (psnr("rule"), psnr("table"));
        eprintln!(
            "fur tile, 4 views up to 80°, 8 px: rule {:.2} dB ({}), table {:.2} dB ({})",
            rule.psnr_db, rule.method, table.psnr_db, table.method
        );
        assert!(
            table.method.contains("measured direction table"),
            "{}",
            table.method
        );
        assert!(table.psnr_db >= rule.psnr_db + 0.25, "{rule:?} {table:?}");
        let r = AssetReader::open(&dir.path().join("table/slices")).unwrap();
        let loaded = SlicesRepr::read(&r).unwrap();
        let t = loaded.direction.as_ref().unwrap();
        assert_eq!(t.grid().polar_deg.len(), 9);
        assert_eq!(t.grid().azimuth_deg, vec![0.0, 30.0, 60.0, 90.0]);
        let again = tempfile::tempdir().unwrap();
        let mut w = altrep::asset::AssetWriter::new(again.path(), "table", "slices").unwrap();
        assert_eq!(
            SlicesRepr::write(&loaded, &mut w).unwrap(),
            r.description().metadata
        );
        let rule_folder = AssetReader::open(&dir.path().join("rule/slices")).unwrap();
        assert!(rule_folder.description().metadata["direction_table"].is_null());
        // An object's slices cannot have one.
        let object = "[[asset]]\nname = \"o\"\nshape = \"pear\"\n[asset.needs]\nlighting = \"baked\"\n\
                      [asset.slices]\ndirection_table = true\n";
        let m = Manifest::parse(object, std::path::Path::new("scene.toml")).unwrap();
        let run = altrep::pipeline::run_scene(&m, &RunOptions::new(dir.path())).unwrap();
        assert!(!run.ok());
        assert!(run.table().contains("direction_table"), "{}", run.table());
    }

    /// Views from straight above only (grazing 0°) draw the height stack at one slice (one
    /// composite is exact along the normal); the other stacks and levels are skipped.
    #[test]
    fn a_tile_seen_from_above_keeps_one_merged_height_slice() {
        let volume = altrep::slices::test_tile(altrep::slices::TestTile::Grass, 16, 1).unwrap();
        let src = Source {
            name: "lawn",
            geometry: None,
            texture: None,
            tile: Some(&volume),
            light: Light::default(),
            placement: None,
        };
        let needs = Needs {
            grazing_deg: 0.0,
            lighting: Lighting::Baked,
            ..Needs::default()
        };
        let (plan, d) = SlicesRepr::plan(&SlicesSpec::default(), &needs, &src).unwrap();
        assert!(plan.refused.is_none());
        assert_eq!(
            (d.resolution, d.axes, d.levels.clone()),
            (16, [false, true, false], vec![4])
        );
        assert!(d.tiled);
    }

    /// A tile asks for slices only; an unknown tile or a size that is not a power of two is
    /// refused with its line.
    #[test]
    fn the_manifest_refuses_what_a_tile_cannot_give() {
        let parse = |t: &str| Manifest::parse(t, std::path::Path::new("scene.toml"));
        let e = parse("[[asset]]\nname = \"a\"\ntile = { kind = \"grass\" }\n[asset.parallax]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("volume tile") && e.contains("[asset.slices]"),
            "{e}"
        );
        let e = parse("[[asset]]\nname = \"a\"\ntile = { kind = \"moss\" }\n[asset.slices]\n")
            .unwrap_err();
        assert!(
            matches!(&e, PipelineError::Manifest { line: 3, message, .. } if message.contains("moss")),
            "{e}"
        );
        let e = parse(
            "[[asset]]\nname = \"a\"\ntile = { kind = \"fur\", size = 24 }\n[asset.slices]\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("power of two"), "{e}");
        let e = parse(
            "[[asset]]\nname = \"a\"\ntile = { kind = \"fur\" }\nshape = \"pear\"\n[asset.slices]\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("exactly one"), "{e}");
    }
}
