//! What the slices' measurements report: the criterion's choice drawn against the ray-marched
//! truth, per view and over the sweep of every direction.

use super::*;

#[test]
fn view_errors_pick_the_criterion_level_and_measure_it() {
    let vol = test_tile(TestTile::Perlin, 16, 4).unwrap();
    let (data, _) = build_slices(&vol, &SliceParams::default()).unwrap();
    let views = [
        StackView::degrees(0.0, 30.0),
        StackView::degrees(75.0, 30.0),
    ];
    let rp = small_render(16);
    let rows = view_errors(
        &vol,
        &data,
        &views,
        vol.voxel_size(),
        &rp,
        &VolumeTruthParams::default(),
    )
    .unwrap();
    assert_eq!(rows[0].choice.axis, Axis::Y);
    assert_eq!(rows[0].choice.slices, 1);
    assert_ne!(rows[1].choice.axis, Axis::Y);
    for (r, view) in rows.iter().zip(&views) {
        assert!(r.psnr_db.is_finite() && r.psnr_db > 15.0, "{r:?}");
        assert_eq!(r.view, *view);
        // The figures are those of the criterion's choice, made and drawn here without
        // `view_errors`: the level `choose` picks, that stack drawn against the ray-marched truth.
        let allowed = Axis::ALL.map(|a| data.stack(a, 0).is_ok());
        let choice = choose(&vol, view.vector(), vol.voxel_size(), allowed).unwrap();
        assert_eq!(r.choice, choice, "{view:?}");
        let truth = render_truth(&vol, view, &rp, &VolumeTruthParams::default()).unwrap();
        let drawn = render_slices(&data, choice.axis, choice.level, view, &rp).unwrap();
        let want = psnr(&drawn, &truth).unwrap();
        assert_relative_eq!(r.psnr_db, want.min(99.0), max_relative = 1e-9);
        assert_relative_eq!(
            r.psnr_db,
            (-20.0 * r.rmse.log10()).min(99.0),
            max_relative = 1e-9
        );
    }
    let other = uniform(8, [0.0; 4]);
    assert!(
        view_errors(
            &other,
            &data,
            &views,
            0.1,
            &rp,
            &VolumeTruthParams::default()
        )
        .is_err()
    );
}

/// The sweep's per-direction figures: each direction drawn at the level the criterion picks for
/// it, against the ray-marched truth, drawn again here without the sweep (at the sweep's
/// documented render settings); the rule's choice is one of them, and its shortfall below the
/// best is what the summary reports.
#[test]
fn the_sweep_measures_every_direction_the_rule_chooses_among() {
    let params = SliceMeasureParams {
        size: 16,
        tiles: vec![TestTile::Fur],
        angles_deg: vec![0.0, 50.0, 85.0],
        pixel_voxels: vec![1.0],
        direction_table: false,
        ..SliceMeasureParams::default()
    };
    let report = measure(&params).unwrap();
    let vol = test_tile(TestTile::Fur, 16, params.seed).unwrap();
    let (data, _) = build_slices(&vol, &SliceParams::default()).unwrap();
    // `SliceMeasureParams`' render settings at one voxel per pixel: 48 pixels, 2 × 2 rays.
    let rp = SliceRenderParams {
        width: 48,
        height: 48,
        pixel_voxels: 1.0,
        supersample: Supersample::of(2),
        filter: params.filter,
        ..SliceRenderParams::default()
    };
    let truth = VolumeTruthParams {
        steps_per_voxel: params.truth_steps,
        filter: params.filter,
    };
    assert_eq!(report.sweep.len(), 6);
    let mut worst: f64 = 0.0;
    for row in &report.sweep {
        let polar = if row.side == "above" {
            row.angle_deg
        } else {
            180.0 - row.angle_deg
        };
        let azimuth = params.azimuth_deg + if row.side == "above" { 0.0 } else { 180.0 };
        let view = StackView::degrees(polar, azimuth);
        let reference = render_truth(&vol, &view, &rp, &truth).unwrap();
        for axis in Axis::ALL {
            let mut only = [false; 3];
            only[axis.index()] = true;
            let c = choose(&vol, view.vector(), vol.voxel_size(), only).unwrap();
            let drawn = render_slices(&data, c.axis, c.level, &view, &rp).unwrap();
            let want = psnr(&drawn, &reference).unwrap().min(99.0);
            assert_relative_eq!(row.psnr_axis[axis.index()], want, max_relative = 1e-9);
        }
        assert_eq!(row.psnr_three, row.psnr_axis[row.three.axis.index()]);
        worst = worst.max(row.direction_shortfall_db());
    }
    let summary = &report.tiles[0];
    assert_abs_diff_eq!(summary.direction_shortfall_max_db, worst, epsilon = 1e-12);
    eprintln!("fur 16³: the direction rule falls {worst:.2} dB below the best direction at worst");
}
