use std::f64::consts::PI;

use altrep_data_gen::PixelGrid;

use super::*;

#[test]
fn event_sweep_matches_marching_sweep() {
    use crate::parallax::images::{ParallaxImages, ParallaxParams};
    for name in ["truck", "tree", "building", "torus"] {
        let shape = altrep_data_gen::scene_shape(name).unwrap();
        let p = ParallaxParams {
            views: 6,
            width: 24,
            height: 12,
            ..Default::default()
        };
        let images = ParallaxImages::capture(&shape, &p).unwrap();
        let grid = images.pixel_grid();
        let (mut a, mut b) = (
            [HalfPoints::default(), HalfPoints::default()],
            [HalfPoints::default(), HalfPoints::default()],
        );
        let mut sc = Scratch::default();
        let (mut ends, mut ev) = (Vec::new(), Vec::new());
        for view in &images.views {
            for j in 0..p.height {
                let row = &view.geom[j * p.width..(j + 1) * p.width];
                let rs = RowSweep::new(&grid, row, p.delta_theta());
                reference::row_endpoints(&grid, row, &mut ends);
                for i in 0..p.width {
                    let x = grid.x_at(i as f64 + 0.5);
                    let angles = AngleGrid::new(p.delta_theta(), 4);
                    a.iter_mut().for_each(HalfPoints::clear);
                    pixel_points(&grid, &rs, x, p.delta_theta(), &angles, &mut sc, &mut a);
                    reference::pixel_points_by_march(
                        &grid,
                        row,
                        &ends,
                        x,
                        p.delta_theta(),
                        4,
                        images.march_radius(),
                        &mut ev,
                        &mut b,
                    );
                    for h in 0..2 {
                        for (u, v) in [(&a[h].upper, &b[h].upper), (&a[h].lower, &b[h].lower)] {
                            let mut u = u.clone();
                            u.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.total_cmp(&q.1)));
                            let mut v = v.clone();
                            v.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.total_cmp(&q.1)));
                            v.dedup();
                            u.dedup();
                            if u != v {
                                let th = 0.0f64;
                                for (k, &e) in sc
                                    .events
                                    .iter()
                                    .enumerate()
                                    .filter(|(_, e)| e.0.abs() < 0.2)
                                {
                                    eprintln!(
                                        "event {k} {e:?} pieces {:?}",
                                        if e.1 == NONE {
                                            [NONE, NONE]
                                        } else {
                                            rs.ends[e.1 as usize].2
                                        }
                                    );
                                }
                                for &id in &rs.existing {
                                    if let Some(r) = rs.eval(id, x, th.cos(), th.sin()) {
                                        eprintln!(
                                            "met at 0: piece {id} {r:?} {:?}",
                                            rs.pieces[id as usize]
                                        );
                                    }
                                }
                                eprintln!("x = {x}");
                            }
                            assert_eq!(u, v, "{name} row {j} pixel {i} half {h}");
                        }
                    }
                }
            }
        }
    }
}

/// A list of points as bits, for bitwise comparisons.
fn bits(v: &[(f64, f64)]) -> Vec<(u64, u64)> {
    v.iter().map(|p| (p.0.to_bits(), p.1.to_bits())).collect()
}

/// Calls `f(shape, grid, row, X, Δθ, angle grid, subdivisions)` for every pixel of every
/// row of 8 views of 32 × 16 of the truck, tree, building and torus, at zmin/zmax's single
/// subdivision and at the default 64.
fn for_each_test_pixel(
    mut f: impl FnMut(&str, &PixelGrid, &RowSweep, f64, f64, &AngleGrid, usize),
) {
    use crate::parallax::images::{ParallaxImages, ParallaxParams};
    for name in ["truck", "tree", "building", "torus"] {
        let shape = altrep_data_gen::scene_shape(name).unwrap();
        let p = ParallaxParams {
            views: 8,
            width: 32,
            height: 16,
            ..Default::default()
        };
        let images = ParallaxImages::capture(&shape, &p).unwrap();
        let grid = images.pixel_grid();
        let delta = p.delta_theta();
        for subdivisions in [1, 64] {
            let angles = AngleGrid::new(delta, subdivisions);
            for view in &images.views {
                for j in 0..p.height {
                    let row = &view.geom[j * p.width..(j + 1) * p.width];
                    let rs = RowSweep::new(&grid, row, delta);
                    for i in 0..p.width {
                        let x = grid.x_at(i as f64 + 0.5);
                        f(name, &grid, &rs, x, delta, &angles, subdivisions);
                    }
                }
            }
        }
    }
}

/// The optimised sweep (trigonometry cached per event and per grid angle, one corner pushed
/// where two boxes meet) gives bit-for-bit the hulls of the corner points of the sweep as
/// first written (every box's four corners), per half and over both halves, at the default
/// subdivision count and for zmin/zmax's single subdivision.
#[test]
fn optimised_sweep_is_bitwise_the_first_sweep() {
    let mut compared = 0usize;
    let (mut sc, mut sc1) = (Scratch::default(), Scratch::default());
    let mut a = [HalfPoints::default(), HalfPoints::default()];
    let mut b = [HalfPoints::default(), HalfPoints::default()];
    for_each_test_pixel(|name, grid, rs, x, delta, angles, subdivisions| {
        a.iter_mut().for_each(HalfPoints::clear);
        pixel_points(grid, rs, x, delta, angles, &mut sc, &mut a);
        reference::pixel_points_v1(grid, rs, x, delta, subdivisions, &mut sc1, &mut b);
        for upper in [true, false] {
            let side = |hp: &HalfPoints| {
                if upper {
                    hp.upper.clone()
                } else {
                    hp.lower.clone()
                }
            };
            for h in 0..2 {
                let (ha, hb) = (hull(side(&a[h]), upper), hull(side(&b[h]), upper));
                assert_eq!(bits(&ha), bits(&hb), "{name}, half {h}");
                compared += ha.len();
            }
            let both =
                |p: &[HalfPoints; 2]| hull(side(&p[0]).into_iter().chain(side(&p[1])), upper);
            assert_eq!(bits(&both(&a)), bits(&both(&b)), "{name}, both halves");
        }
    });
    assert!(compared > 10_000, "only {compared} hull vertices compared");
}

/// The hulls built as the sweep pushes its points are bitwise [`hull`] over the points
/// listed (half 0's, then half 1's), for one slot over both halves and for one per half.
#[test]
fn hulls_built_during_the_sweep_are_bitwise_the_hulls_of_the_lists() {
    let mut compared = 0usize;
    let mut sc = Scratch::default();
    let mut lists = [HalfPoints::default(), HalfPoints::default()];
    let mut sweeps = [SlotHulls::new(false), SlotHulls::new(true)];
    for_each_test_pixel(|name, grid, rs, x, delta, angles, _| {
        lists.iter_mut().for_each(HalfPoints::clear);
        pixel_points(grid, rs, x, delta, angles, &mut sc, &mut lists);
        for hulls in &mut sweeps {
            hulls.clear();
            pixel_points(grid, rs, x, delta, angles, &mut sc, hulls);
            let slots: &[&[usize]] = if hulls.split {
                &[&[0], &[1]]
            } else {
                &[&[0, 1]]
            };
            for (s, halves) in slots.iter().enumerate() {
                let points = |upper: bool| -> Vec<(f64, f64)> {
                    halves
                        .iter()
                        .flat_map(|&h| {
                            let hp = &lists[h];
                            if upper { &hp.upper } else { &hp.lower }.clone()
                        })
                        .collect()
                };
                let (up, lo) = (points(true), points(false));
                match hulls.hulls_of(s) {
                    None => assert!(up.is_empty() && lo.is_empty()),
                    Some((u, l)) => {
                        assert_eq!(bits(&u), bits(&hull(up, true)), "{name}");
                        assert_eq!(bits(&l), bits(&hull(lo, false)), "{name}");
                        compared += u.len() + l.len();
                    }
                }
            }
            if !hulls.split {
                assert!(hulls.hulls_of(1).is_none());
            }
        }
    });
    assert!(compared > 10_000, "only {compared} hull vertices compared");
}

/// The events that [`pixel_points`] keeps for an end point `E` and a pixel `X`: those
/// within `WINDOW` of `[−delta, delta]`, computed as it computes them.
fn kept_events(rho: f64, psi: f64, x: f64, delta: f64) -> Vec<f64> {
    if rho < x.abs() {
        return Vec::new();
    }
    let phi = (x / rho).clamp(-1.0, 1.0).acos();
    [wrap(psi - phi), wrap(psi + phi)]
        .into_iter()
        .filter(|&th| th > -delta - WINDOW && th < delta + WINDOW)
        .collect()
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 4000, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..proptest::prelude::ProptestConfig::default() })]
    /// The prefilter never skips an end point with a kept event: random and adversarial
    /// end points (on the window's edges, at `ψ ± π`) and pixels (at `±|E|` and just
    /// inside, where `acos` is ill-conditioned, and at the window's edge values).
    #[test]
    fn the_event_prefilter_skips_no_kept_event(
        rho in 1e-6f64..2.0,
        psi_kind in 0usize..4,
        psi_raw in -3.2f64..3.2,
        psi_nudge in -1e-7f64..1e-7,
        views in 1usize..40,
        x_kind in 0usize..5,
        x_raw in -1.0f64..1.0,
        x_nudge in -1e-12f64..1e-12,
    ) {
        let delta = PI / views as f64;
        let psi = match psi_kind {
            0 => psi_raw,
            1 => delta + psi_nudge,
            2 => -delta + psi_nudge,
            _ => wrap(PI + psi_nudge),
        };
        let (ex, ez) = (rho * psi.cos(), rho * psi.sin());
        let (rho, psi) = (ex.hypot(ez), ez.atan2(ex));
        let edge = |th: f64| ex * th.cos() + ez * th.sin();
        let x = match x_kind {
            0 => x_raw * rho * 1.1,
            1 => rho * (1.0 - x_nudge.abs()),
            2 => -rho * (1.0 - x_nudge.abs()),
            3 => edge(delta) + x_nudge * rho,
            _ => edge(-delta) + x_nudge * rho,
        };
        let (lo, hi) = x_window((ex, ez), rho, psi, delta);
        if x < lo || x > hi {
            let kept = kept_events(rho, psi, x, delta);
            proptest::prop_assert!(
                kept.is_empty(),
                "skipped E = ({ex}, {ez}) at X = {x}: events {kept:?}, window [{lo}, {hi}]"
            );
        }
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 3000, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..proptest::prelude::ProptestConfig::default() })]
    /// [`push_piece_boxes`] pushes one corner per side where two boxes meet, the outer of
    /// the two: the hulls are bitwise those of pushing both corners of every box. Boxes
    /// over random ascending τ with repeated τ, z drawn from a few values (ties, ±0,
    /// collinear runs) or at random, and a hull already holding points.
    #[test]
    fn pushing_the_outer_corner_where_boxes_meet_keeps_the_hulls_bitwise(
        start in proptest::collection::vec((0usize..4, -2.0f64..2.0), 0..4),
        boxes in proptest::collection::vec(
            (0usize..3, 0usize..6, -2.0f64..2.0, 0usize..6, 0.0f64..1.0),
            1..40,
        ),
    ) {
        let pick = |k: usize, raw: f64| match k {
            0 => 0.0,
            1 => -0.0,
            2 => 1.0,
            3 => -1.0,
            4 => 0.5,
            _ => raw,
        };
        for upper in [true, false] {
            let (mut both, mut outer) = (HullBuilder::new(upper), HullBuilder::new(upper));
            let mut tau = -3.0;
            for &(k, raw) in &start {
                tau += [0.0, 0.25, 0.5, 1.0][k];
                both.push((tau, raw));
                outer.push((tau, raw));
            }
            // Box b spans [τ_b, τ_{b+1}] with value z_b (the side's corner value).
            let mut taus = vec![tau + 0.125];
            let mut zs = Vec::new();
            for &(dt, zk, zraw, _, _) in &boxes {
                let last = *taus.last().unwrap();
                taus.push(last + [0.0, 0.125, 0.375][dt]);
                zs.push(pick(zk, zraw));
            }
            for (b, &z) in zs.iter().enumerate() {
                both.push((taus[b], z));
                both.push((taus[b + 1], z));
            }
            let mut pending: Option<f64> = None;
            for (b, &z) in zs.iter().enumerate() {
                let at_a = match pending {
                    Some(p) if upper => if z > p { z } else { p },
                    Some(p) => if z < p { z } else { p },
                    None => z,
                };
                outer.push((taus[b], at_a));
                pending = Some(z);
            }
            outer.push((*taus.last().unwrap(), *zs.last().unwrap()));
            proptest::prop_assert_eq!(bits(&both.points), bits(&outer.points));
        }
    }
}

#[test]
fn hulls_keep_extremes() {
    let pts = [(0.0, 0.0), (1.0, 2.0), (2.0, 1.0), (3.0, 3.0), (3.0, 0.5)];
    let up = hull(pts, true);
    assert_eq!(up, vec![(0.0, 0.0), (1.0, 2.0), (3.0, 3.0)]);
    let low_pts = [(0.0, 0.0), (1.0, -2.0), (2.0, 1.0), (3.0, 0.5)];
    let lo = hull(low_pts, false);
    assert_eq!(lo, vec![(0.0, 0.0), (1.0, -2.0), (3.0, 0.5)]);
    for a in [-3.0, -0.5, 0.0, 0.7, 4.0] {
        let full = v_range(&pts, &low_pts, a);
        let hl = v_range(&up, &lo, a);
        assert!((full.0 - hl.0).abs() < 1e-12 && (full.1 - hl.1).abs() < 1e-12);
    }
}

#[test]
fn c_grid_holds_plus_minus_one() {
    for (lo, hi, bits) in [
        (-1.0, 1.0, 8),
        (-7.3, 3.1, 8),
        (-1.0, 31.9, 8),
        (-32.0, 32.0, 16),
    ] {
        let g = CGrid::new(lo, hi, bits);
        let q = |c: f64| (c - g.c0) / g.step;
        assert!((q(-1.0) - q(-1.0).round()).abs() < 1e-9 && (q(1.0) - q(1.0).round()).abs() < 1e-9);
        assert!(g.c0 <= lo + 1e-12 && g.c0 + g.levels as f64 * g.step >= hi - 1e-12);
    }
}

#[test]
fn f32_steps_are_adjacent() {
    for f in [1.0f32, -1.0, 0.3, -2.5e-7, 0.0] {
        let (u, d) = (f32_step(f, true), f32_step(f, false));
        assert!(u > f && d < f);
        assert!(f32_step(u, false) == f || f == 0.0);
        assert!(f32_step(d, true) == f || f == 0.0);
    }
}

#[test]
fn quantisation_is_outward() {
    let data = [0.1234, -0.7, 0.99, 0.5, -0.2];
    let orig = data;
    for bits in [8, 16, 32] {
        let mut up = data;
        let mut refs: Vec<&mut f64> = up.iter_mut().collect();
        quantize_channel(&mut refs, true, bits);
        let mut down = data;
        let mut refs: Vec<&mut f64> = down.iter_mut().collect();
        quantize_channel(&mut refs, false, bits);
        for k in 0..data.len() {
            assert!(up[k] >= orig[k] && down[k] <= orig[k], "bits {bits}");
        }
    }
}
