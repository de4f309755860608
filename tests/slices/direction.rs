//! The direction chosen by measured error ([`DirectionTable`], docs/design.md §9.6): the table
//! holds what the ray-marched truth says at its nodes, and between nodes its choice falls less
//! far below the best direction than the direction rule's.

use super::*;
use altrep::slices::{DirectionGrid, DirectionTable};

fn render(p: f64) -> SliceRenderParams {
    let px = (24.0 / p).round().max(1.0) as usize;
    SliceRenderParams {
        width: px,
        height: px,
        pixel_voxels: p,
        supersample: Supersample::of((2.0 * p).ceil() as usize),
        filter: SliceReconstruction::Linear,
        ..SliceRenderParams::default()
    }
}

/// At a node the table's prediction is the PSNR of that stack against the truth, drawn again
/// here; the choice there is the best of the three directions at their criterion levels.
#[test]
fn at_its_nodes_the_table_is_the_measured_error() {
    let vol = test_tile(TestTile::Fur, 8, 3).unwrap();
    let (data, _) = build_slices(&vol, &SliceParams::default()).unwrap();
    let grid = DirectionGrid {
        polar_deg: vec![0.0, 40.0, 70.0],
        azimuth_deg: vec![0.0, 90.0],
        pixel_voxels: vec![1.0, 2.0],
    };
    let truth = VolumeTruthParams {
        steps_per_voxel: 4,
        filter: SliceReconstruction::Linear,
    };
    let both = |p: f64| (render(p), render(p));
    let table = DirectionTable::measure(&vol, &data, &grid, 1.0, &both, &truth).unwrap();
    for &p in &grid.pixel_voxels {
        for &polar in &grid.polar_deg {
            for &azimuth in &grid.azimuth_deg {
                let view = StackView::degrees(polar, azimuth);
                let rp = render(p);
                let reference = render_truth(&vol, &view, &rp, &truth).unwrap();
                let depth = p * vol.voxel_size();
                let mut measured = [0.0; 3];
                for axis in Axis::ALL {
                    let mut only = [false; 3];
                    only[axis.index()] = true;
                    let c = choose(&vol, view.vector(), depth, only).unwrap();
                    let img = render_slices(&data, axis, c.level, &view, &rp).unwrap();
                    measured[axis.index()] = psnr(&img, &reference).unwrap().min(99.0);
                    let predicted = table.predict(axis, c.level, &view, p).unwrap();
                    assert_relative_eq!(predicted, measured[axis.index()], max_relative = 1e-9);
                }
                let chosen = table.choose(&data, &view, p, [true; 3]).unwrap();
                let best = measured.iter().copied().fold(f64::MIN, f64::max);
                assert_relative_eq!(measured[chosen.axis.index()], best, max_relative = 1e-12);
                // The level stays the criterion's.
                let mut only = [false; 3];
                only[chosen.axis.index()] = true;
                let c = choose(&vol, view.vector(), p * vol.voxel_size(), only).unwrap();
                assert_eq!((chosen.level, chosen.slices), (c.level, c.slices));
            }
        }
    }
    // Slices of another size are refused, naming them.
    let other = test_tile(TestTile::Fur, 16, 3).unwrap();
    let (other, _) = build_slices(&other, &SliceParams::default()).unwrap();
    let e = table
        .choose(&other, &StackView::degrees(30.0, 0.0), 1.0, [true; 3])
        .unwrap_err();
    assert!(e.to_string().contains("slice data"), "{e}");
}

/// Between the nodes (views at the centres of 10° × 30° cells), on the 16³ fur tile at 2 voxels
/// per pixel, from above: the table's choice falls 1.28 dB below the best direction at worst and
/// 0.14 dB on mean, where the direction rule falls 9.35 and 2.30 dB (mean below 0.5 dB and worst
/// below half the rule's asserted). The grass tile, measured the same way (`tiles: [Fur, Grass]`,
/// 2026-12-07): table 1.61 / 0.31 dB against the rule's 6.84 / 1.70 dB; left out of the test
/// command, where it took 9 of the test's 17.5 s.
#[test]
fn between_its_nodes_the_table_chooses_closer_to_the_best_than_the_rule() {
    let params = SliceMeasureParams {
        size: 16,
        tiles: vec![TestTile::Fur],
        angles_deg: vec![0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0],
        pixel_voxels: vec![2.0],
        both_sides: false,
        direction_table: true,
        table_azimuth_step_deg: 30.0,
        ..SliceMeasureParams::default()
    };
    let report = measure(&params).unwrap();
    for t in &report.tiles {
        let worst = t.table_shortfall_max_db.unwrap();
        let mean = t.table_shortfall_mean_db.unwrap();
        eprintln!(
            "{} 16³: below the best direction, rule {:.2} / {:.2} dB, table {worst:.2} / {mean:.2} dB (worst / mean); slices drawn {:.1} → {:.1}",
            t.tile.name(),
            t.direction_shortfall_max_db,
            t.direction_shortfall_mean_db,
            t.slices_drawn_mean,
            t.table_slices_drawn_mean.unwrap(),
        );
        assert!(mean < 0.5, "{}: {mean}", t.tile.name());
        assert!(
            worst < 0.5 * t.direction_shortfall_max_db,
            "{}: {worst} vs {}",
            t.tile.name(),
            t.direction_shortfall_max_db
        );
    }
}
