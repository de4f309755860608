//! Volumetric textures as slices (docs/design.md §9): merges, criterion, direction choice and the
//! CPU renderer against the ray-marched ground truth and closed forms.

use altrep::metrics::psnr;
use altrep::slices::{
    Axis, HeightField, HeightFieldParams, ImplicitParams, MergeRule, Side, SliceError, SliceParams,
    SliceReconstruction, SliceRenderParams, StackView, TestTile, TexelVolume, VolumeTruthParams,
    build_slices, choose, choose_direction, from_height_field, from_implicit, level_for_slices,
    render_slices, render_truth, slices_needed, test_tile, view_errors,
};
use altrep::slices::{
    CurvedParams, ShapeParams, SliceMeasureParams, from_shape, measure, render_curved_slices,
    render_curved_truth,
};
use altrep_data_gen::Supersample;
use altrep_data_gen::{Albedo, Csg, Part, Primitive, SplitMix64};
use approx::{assert_abs_diff_eq, assert_relative_eq};
use glam::DVec3;
use proptest::prelude::*;

mod direction;
mod fitted;
mod measured;
mod object;

/// A volume of `n³` voxels of edge `1/n` with `value` everywhere.
fn uniform(n: usize, value: [f32; 4]) -> TexelVolume {
    TexelVolume::new([n; 3], 1.0 / n as f64, vec![value; n * n * n]).unwrap()
}

/// Random premultiplied voxels, a share of them empty or opaque.
fn random_volume(dims: [usize; 3], seed: u64) -> TexelVolume {
    let mut rng = SplitMix64::new(seed);
    let n = dims[0] * dims[1] * dims[2];
    let rgba = (0..n)
        .map(|_| {
            let r = rng.next_f64();
            let a = if r < 0.3 {
                0.0
            } else if r < 0.4 {
                1.0
            } else {
                rng.next_f64() as f32
            };
            let c = |rng: &mut SplitMix64| rng.next_f64() as f32 * a;
            [c(&mut rng), c(&mut rng), c(&mut rng), a]
        })
        .collect();
    TexelVolume::new(dims, 1.0 / dims[1] as f64, rgba).unwrap()
}

fn small_render(width: usize) -> SliceRenderParams {
    SliceRenderParams {
        width,
        height: width,
        ..SliceRenderParams::default()
    }
}

#[test]
fn merge_conserves_opacity_of_every_column() {
    let vol = random_volume([8, 16, 4], 7);
    for rule in [
        MergeRule::FrontOverBack,
        MergeRule::BackOverFront,
        MergeRule::PerSide,
        MergeRule::Symmetric,
    ] {
        let params = SliceParams {
            rule,
            fit_bilinear: false,
            ..SliceParams::default()
        };
        let (data, report) = build_slices(&vol, &params).unwrap();
        assert!(
            report.opacity_error_max <= 1e-6,
            "{rule:?}: {}",
            report.opacity_error_max
        );
        // Independent check: every merged texel's alpha is 1 − Π(1 − a) of its column.
        for stack in data.stacks() {
            let axis = stack.axis();
            let (ua, va) = axis.plane_axes();
            let g = 1usize << stack.level();
            for side in [Side::Plus, Side::Minus] {
                for (j, slice) in stack.slices(side).iter().enumerate() {
                    let tex = &slice.levels()[0];
                    for tv in 0..tex.height {
                        for tu in 0..tex.width {
                            let mut c = [0usize; 3];
                            c[ua] = tu;
                            c[va] = tv;
                            let mut transmit = 1.0f64;
                            for l in 0..g {
                                c[axis.index()] = j * g + l;
                                transmit *= 1.0 - f64::from(vol.get(c[0], c[1], c[2])[3]);
                            }
                            let a = f64::from(tex.texel(tu, tv)[3]);
                            assert_abs_diff_eq!(a, 1.0 - transmit, epsilon = 1e-6);
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn dropping_slices_does_not_conserve_opacity() {
    let vol = random_volume([8, 16, 4], 8);
    let params = SliceParams {
        rule: MergeRule::Drop,
        ..SliceParams::default()
    };
    let (_, report) = build_slices(&vol, &params).unwrap();
    assert!(
        report.opacity_error_max > 0.1,
        "{}",
        report.opacity_error_max
    );
}

#[test]
fn merge_sides_composite_in_the_documented_order() {
    // Two layers along y: red opaque-ish below, green half above.
    let (lo, hi) = ([0.8f32, 0.0, 0.0, 0.8], [0.0f32, 0.5, 0.0, 0.5]);
    let rgba = vec![lo, hi];
    let vol = TexelVolume::new([1, 2, 1], 1.0, rgba).unwrap();
    let params = SliceParams {
        rule: MergeRule::PerSide,
        axes: [false, true, false],
        ..SliceParams::default()
    };
    let (data, _) = build_slices(&vol, &params).unwrap();
    let stack = data.stack(Axis::Y, 1).unwrap();
    let plus = stack.slices(Side::Plus)[0].levels()[0].texel(0, 0).to_vec();
    let minus = stack.slices(Side::Minus)[0].levels()[0]
        .texel(0, 0)
        .to_vec();
    // From above (plus side): green over red.
    assert_relative_eq!(plus[0], 0.5 * 0.8, epsilon = 1e-6);
    assert_relative_eq!(plus[1], 0.5, epsilon = 1e-6);
    // From below: red over green.
    assert_relative_eq!(minus[0], 0.8, epsilon = 1e-6);
    assert_relative_eq!(minus[1], 0.2 * 0.5, epsilon = 1e-6);
    assert_relative_eq!(plus[3], 0.9, epsilon = 1e-6);
    assert_relative_eq!(minus[3], 0.9, epsilon = 1e-6);
}

/// Closed form: a uniform slab of opacity `a` per voxel seen at polar angle θ has opacity
/// `1 − (1 − a)^(n/cos θ)` and premultiplied colour `c·A`. The truth is exact up to f32 rounding;
/// every merge level is exact too (a homogeneous slab composites to a homogeneous slab).
#[test]
fn uniform_slab_matches_the_closed_form_at_every_level_and_angle() {
    let n = 16;
    let (a, colour) = (0.15f32, [0.6f32, 0.3, 0.1]);
    let vol = uniform(n, [colour[0] * a, colour[1] * a, colour[2] * a, a]);
    let rp = small_render(8);
    for rule in MergeRule::ALL {
        let (data, _) = build_slices(
            &vol,
            &SliceParams {
                rule,
                ..SliceParams::default()
            },
        )
        .unwrap();
        for polar in [0.0, 30.0, 60.0, 80.0, 150.0] {
            let view = StackView::degrees(polar, 30.0);
            let cos = view.vector().y.abs();
            let opacity = 1.0 - (1.0 - f64::from(a)).powf(n as f64 / cos);
            let truth = render_truth(&vol, &view, &rp, &VolumeTruthParams::default()).unwrap();
            for level in 0..5 {
                let img = render_slices(&data, Axis::Y, level, &view, &rp).unwrap();
                for (p, q) in img.pixels.iter().zip(&truth.pixels) {
                    assert_abs_diff_eq!(f64::from(p[3]), opacity, epsilon = 1e-5);
                    assert_abs_diff_eq!(f64::from(q[3]), opacity, epsilon = 1e-5);
                    for c in 0..3 {
                        let expect = f64::from(colour[c]) * opacity;
                        assert_abs_diff_eq!(f64::from(p[c]), expect, epsilon = 1e-5);
                        assert_abs_diff_eq!(f64::from(q[c]), expect, epsilon = 1e-5);
                    }
                }
            }
        }
    }
}

/// Closed form: a ball of constant opacity `a` per voxel seen from above through its centre
/// has opacity `1 − (1 − a)^m`, `m` the voxel centres inside along the column. The slices sample
/// exactly those centres (1e-5); the truth's trilinear field ramps over one voxel at each end,
/// which moves the optical depth by less than 0.01.
#[test]
fn ball_of_constant_density_matches_the_closed_form_through_its_centre() {
    let n = 32;
    let (a, r) = (0.1f32, 0.3f64);
    let s = 1.0 / n as f64;
    let mut rgba = vec![[0.0f32; 4]; n * n * n];
    let centre = DVec3::splat(0.5);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let p = (DVec3::new(x as f64, y as f64, z as f64) + 0.5) * s;
                if (p - centre).length() <= r {
                    rgba[x + n * (y + n * z)] = [0.5 * a, 0.5 * a, 0.5 * a, a];
                }
            }
        }
    }
    let vol = TexelVolume::new([n; 3], s, rgba).unwrap();
    // The column x = 15 (and 16, z likewise) by symmetry: centres 0.5/32 off the axis.
    let off = 0.5 * s;
    let m = (0..n)
        .filter(|j| {
            let y = (*j as f64 + 0.5) * s - 0.5;
            y * y + 2.0 * off * off <= r * r
        })
        .count();
    let expect = 1.0 - (1.0 - f64::from(a)).powi(m as i32);
    let rp = SliceRenderParams {
        width: 1,
        height: 1,
        supersample: Supersample::ONE,
        pixel_voxels: 0.01,
        ..SliceRenderParams::default()
    };
    let view = StackView::degrees(0.0, 0.0);
    let truth = render_truth(&vol, &view, &rp, &VolumeTruthParams::default()).unwrap();
    assert_abs_diff_eq!(f64::from(truth.pixels[0][3]), expect, epsilon = 0.01);
    // The composites (not fitted to bilinear filtering, which trades exactness at the texel
    // centres for accuracy between them).
    let composites = SliceParams {
        fit_bilinear: false,
        ..SliceParams::default()
    };
    let (data, _) = build_slices(&vol, &composites).unwrap();
    let img = render_slices(&data, Axis::Y, 0, &view, &rp).unwrap();
    assert_abs_diff_eq!(f64::from(img.pixels[0][3]), expect, epsilon = 1e-5);
    // Merged to one slice: seen straight on, the composite is exact as well.
    let img = render_slices(&data, Axis::Y, 5, &view, &rp).unwrap();
    assert_abs_diff_eq!(f64::from(img.pixels[0][3]), expect, epsilon = 1e-5);
}

#[test]
fn truth_has_converged_at_eight_steps_per_voxel() {
    let vol = test_tile(TestTile::Grass, 16, 3).unwrap();
    let rp = small_render(24);
    for polar in [0.0, 60.0] {
        let view = StackView::degrees(polar, 30.0);
        let t8 = render_truth(
            &vol,
            &view,
            &rp,
            &VolumeTruthParams {
                steps_per_voxel: 8,
                ..VolumeTruthParams::default()
            },
        )
        .unwrap();
        let t32 = render_truth(
            &vol,
            &view,
            &rp,
            &VolumeTruthParams {
                steps_per_voxel: 32,
                ..VolumeTruthParams::default()
            },
        )
        .unwrap();
        let db = psnr(&t8, &t32).unwrap();
        assert!(db >= 55.0, "{polar}°: truth 8 vs 32 steps only {db:.1} dB");
    }
}

/// Error against slice count, level and angle on the grass tile (16³, 1 px per voxel).
#[test]
fn slice_error_against_truth_follows_level_and_angle() {
    let vol = test_tile(TestTile::Grass, 16, 3).unwrap();
    let rp = small_render(24);
    let (data, _) = build_slices(&vol, &SliceParams::default()).unwrap();
    let (dropped, _) = build_slices(
        &vol,
        &SliceParams {
            rule: MergeRule::Drop,
            ..SliceParams::default()
        },
    )
    .unwrap();
    let db = |data, axis, level, polar: f64| {
        let view = StackView::degrees(polar, 30.0);
        let truth = render_truth(&vol, &view, &rp, &VolumeTruthParams::default()).unwrap();
        psnr(
            &render_slices(data, axis, level, &view, &rp).unwrap(),
            &truth,
        )
        .unwrap()
    };
    // All slices near the normal: within 35 dB of the truth.
    for polar in [0.0, 20.0] {
        let e = db(&data, Axis::Y, 0, polar);
        assert!(e >= 35.0, "all slices at {polar}°: {e:.1} dB");
    }
    // Error grows with the angle for one stack (gaps between the slices).
    assert!(db(&data, Axis::Y, 0, 80.0) + 3.0 < db(&data, Axis::Y, 0, 20.0));
    // Error grows with the level (fewer, merged slices), looked at 20° off the normal.
    let by_level: Vec<f64> = (0..5).map(|k| db(&data, Axis::Y, k, 20.0)).collect();
    for k in 1..5 {
        assert!(by_level[k] <= by_level[k - 1] + 0.5, "{by_level:?}");
    }
    // At the level the criterion picks (d = one voxel), merged beats dropped by at least 3 dB,
    // from above and from below.
    for polar in [0.0, 10.0, 20.0, 160.0, 170.0] {
        let v = StackView::degrees(polar, 30.0).vector();
        let c = choose(&vol, v, vol.voxel_size(), [false, true, false]).unwrap();
        assert!(c.level > 0, "{polar}°: {c:?}");
        let (m, d) = (
            db(&data, Axis::Y, c.level, polar),
            db(&dropped, Axis::Y, c.level, polar),
        );
        assert!(
            m >= d + 3.0,
            "level {} at {polar}°: merged {m:.1} dB, dropped {d:.1} dB",
            c.level
        );
    }
    // Three directions beat one at a grazing angle by at least 3 dB.
    let view = StackView::degrees(80.0, 30.0);
    let c = choose(&vol, view.vector(), vol.voxel_size(), [true; 3]).unwrap();
    assert_eq!(c.axis, Axis::X);
    let (one, three) = (db(&data, Axis::Y, 0, 80.0), db(&data, c.axis, 0, 80.0));
    assert!(three >= one + 3.0, "three {three:.1} dB, one {one:.1} dB");
}

/// Unfitted composites seen straight on with samples at the texel centres: every merged level
/// equals all the slices. Merging is exact where it is sampled; elsewhere bilinear filtering
/// does not commute with compositing (what the fit to the filter addresses).
#[test]
fn merged_levels_are_exact_at_texel_centres_seen_straight_on() {
    let vol = test_tile(TestTile::Fur, 16, 5).unwrap();
    let unfitted = SliceParams {
        fit_bilinear: false,
        ..SliceParams::default()
    };
    let (data, _) = build_slices(&vol, &unfitted).unwrap();
    let rp = SliceRenderParams {
        supersample: Supersample::ONE,
        ..small_render(16)
    };
    for polar in [0.0, 180.0] {
        let view = StackView::degrees(polar, 0.0);
        let all = render_slices(&data, Axis::Y, 0, &view, &rp).unwrap();
        for level in 1..5 {
            let img = render_slices(&data, Axis::Y, level, &view, &rp).unwrap();
            for (p, q) in img.pixels.iter().zip(&all.pixels) {
                for c in 0..4 {
                    assert_abs_diff_eq!(p[c], q[c], epsilon = 1e-5);
                }
            }
        }
    }
}

/// With nearest (box) reconstruction in the truth and in the slices, compositing commutes with
/// the filter: straight on, every merged level equals the truth at any sub-sample position
/// (up to f32 rounding and the truth's quadrature of a box medium, exact at 8 steps per voxel).
#[test]
fn nearest_reconstruction_makes_merges_exact_straight_on() {
    let vol = test_tile(TestTile::Grass, 16, 6).unwrap();
    let composites = SliceParams {
        fit_bilinear: false,
        ..SliceParams::default()
    };
    let (data, _) = build_slices(&vol, &composites).unwrap();
    let rp = SliceRenderParams {
        filter: SliceReconstruction::Nearest,
        supersample: Supersample::of(3),
        ..small_render(16)
    };
    let truth_params = VolumeTruthParams {
        filter: SliceReconstruction::Nearest,
        ..VolumeTruthParams::default()
    };
    for polar in [0.0, 180.0] {
        let view = StackView::degrees(polar, 17.0);
        let truth = render_truth(&vol, &view, &rp, &truth_params).unwrap();
        for level in 0..5 {
            let img = render_slices(&data, Axis::Y, level, &view, &rp).unwrap();
            for (p, q) in img.pixels.iter().zip(&truth.pixels) {
                for c in 0..4 {
                    assert_abs_diff_eq!(p[c], q[c], epsilon = 1e-4);
                }
            }
        }
    }
}

/// Far away (4 voxels per pixel), one sample per pixel: 2D mip-mapped slices are closer to the
/// supersampled truth than the finest level read alone (aliasing), by at least 2 dB.
#[test]
fn slice_mipmaps_reduce_aliasing_at_a_distance() {
    let vol = test_tile(TestTile::Fur, 32, 5).unwrap();
    let (data, _) = build_slices(&vol, &SliceParams::default()).unwrap();
    let far = SliceRenderParams {
        width: 16,
        height: 16,
        pixel_voxels: 4.0,
        supersample: Supersample::of(8),
        ..SliceRenderParams::default()
    };
    let view = StackView::degrees(30.0, 30.0);
    let truth = render_truth(&vol, &view, &far, &VolumeTruthParams::default()).unwrap();
    let one = |mip_2d| SliceRenderParams {
        supersample: Supersample::ONE,
        mip_2d,
        ..far.clone()
    };
    let with = psnr(
        &render_slices(&data, Axis::Y, 0, &view, &one(true)).unwrap(),
        &truth,
    )
    .unwrap();
    let without = psnr(
        &render_slices(&data, Axis::Y, 0, &view, &one(false)).unwrap(),
        &truth,
    )
    .unwrap();
    assert!(
        with >= without + 2.0,
        "mip {with:.1} dB, no mip {without:.1} dB"
    );
}

#[test]
fn per_side_reads_the_composite_of_the_viewers_side() {
    let vol = random_volume([8, 8, 8], 11);
    let build = |rule| {
        build_slices(
            &vol,
            &SliceParams {
                rule,
                ..SliceParams::default()
            },
        )
        .unwrap()
        .0
    };
    let (per, fob, bof) = (
        build(MergeRule::PerSide),
        build(MergeRule::FrontOverBack),
        build(MergeRule::BackOverFront),
    );
    let rp = small_render(8);
    for (polar, other) in [(20.0, &fob), (160.0, &bof)] {
        let view = StackView::degrees(polar, 10.0);
        let a = render_slices(&per, Axis::Y, 2, &view, &rp).unwrap();
        let b = render_slices(other, Axis::Y, 2, &view, &rp).unwrap();
        assert_eq!(a, b);
    }
}

#[test]
fn criterion_counts_slices() {
    let d = 1.0 / 32.0;
    assert_eq!(slices_needed(1.0, 0.0, d).unwrap(), 1);
    assert_eq!(slices_needed(1.0, 45f64.to_radians(), d).unwrap(), 32);
    assert_eq!(slices_needed(1.0, 0.5f64.atan(), d).unwrap(), 16);
    // From the other side (angle beyond 90°) only |cos| counts.
    assert_eq!(slices_needed(1.0, 135f64.to_radians(), d).unwrap(), 32);
    assert_eq!(
        slices_needed(1.0, 90f64.to_radians(), d).unwrap(),
        usize::MAX
    );
    // The chosen level holds at least the needed slices, and the next one fewer.
    for needed in 1..=32 {
        let k = level_for_slices(Axis::Y, 32, needed, true).unwrap();
        assert!(32 >> k >= needed);
        assert!(k == 5 || (32 >> (k + 1)) < needed);
    }
    assert!(matches!(
        level_for_slices(Axis::Y, 32, 33, true),
        Err(SliceError::TooManySlices {
            slices: 33,
            voxels: 32,
            ..
        })
    ));
    assert_eq!(level_for_slices(Axis::Y, 32, 33, false).unwrap(), 0);
    // Meyer & Neyret's criterion for the views it picks: h·tan a / d ≤ 1.
    let vol = uniform(32, [0.0; 4]);
    for polar in [5.0f64, 10.0, 20.0, 40.0] {
        let c = choose(
            &vol,
            StackView::degrees(polar, 0.0).vector(),
            d,
            [false, true, false],
        )
        .unwrap();
        let h = 1.0 / c.slices as f64;
        assert!(
            h * polar.to_radians().tan() / d <= 1.0 + 1e-9,
            "{polar}°: {c:?}"
        );
    }
}

#[test]
fn direction_choice_at_axis_aligned_and_mixed_views() {
    let h = [0.1; 3];
    for (v, axis) in [
        (DVec3::X, Axis::X),
        (DVec3::NEG_X, Axis::X),
        (DVec3::Y, Axis::Y),
        (DVec3::NEG_Y, Axis::Y),
        (DVec3::Z, Axis::Z),
        (-DVec3::Z, Axis::Z),
    ] {
        assert_eq!(choose_direction(v, h, [true; 3]).unwrap(), axis);
    }
    // 50° from y toward x with equal spacing: x is closer.
    let v = DVec3::new(50f64.to_radians().sin(), 50f64.to_radians().cos(), 0.0);
    assert_eq!(choose_direction(v, h, [true; 3]).unwrap(), Axis::X);
    // The same view, but x slices four times sparser: (1/c²−1)·h² favours y.
    assert_eq!(
        choose_direction(v, [0.4, 0.1, 0.1], [true; 3]).unwrap(),
        Axis::Y
    );
    // Only allowed axes are chosen.
    assert_eq!(
        choose_direction(DVec3::X, h, [false, true, true]).unwrap(),
        Axis::Y
    );
    assert!(choose_direction(DVec3::ZERO, h, [true; 3]).is_err());
    assert!(choose_direction(DVec3::X, h, [false; 3]).is_err());
}

/// A ball across the tile corner, periodic, equals the ball at the tile centre shifted by half a
/// tile; its image across the seam matches the centred image.
#[test]
fn tiles_without_a_seam() {
    let n = 16;
    let params = ImplicitParams {
        dims: [n; 3],
        voxel: 1.0 / n as f64,
        ..ImplicitParams::default()
    };
    let ball = |c: DVec3| move |p: DVec3| (p - c).length() - 0.3;
    let albedo = |p: DVec3| [0.5 + 0.4 * (p.y as f32), 0.4, 0.3];
    let corner = from_implicit(&ball(DVec3::new(0.0, 0.5, 0.0)), &albedo, &params).unwrap();
    let centred = from_implicit(&ball(DVec3::new(0.5, 0.5, 0.5)), &albedo, &params).unwrap();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let a = corner.get((x + n / 2) % n, y, (z + n / 2) % n);
                let b = centred.get(x, y, z);
                // At most one of the 27 sub-samples may round the other way.
                assert_abs_diff_eq!(a[3], b[3], epsilon = 1.0 / 27.0 + 1e-6);
            }
        }
    }
    let (dc, _) = build_slices(&corner, &SliceParams::default()).unwrap();
    let (dm, _) = build_slices(&centred, &SliceParams::default()).unwrap();
    let view = StackView::degrees(40.0, 20.0);
    let shifted = SliceRenderParams {
        offset: [0.5, 0.5],
        ..small_render(24)
    };
    let a = render_slices(&dc, Axis::Y, 0, &view, &shifted).unwrap();
    let b = render_slices(&dm, Axis::Y, 0, &view, &small_render(24)).unwrap();
    let db = psnr(&a, &b).unwrap();
    assert!(db >= 40.0, "seam: {db:.1} dB");
}

#[test]
fn height_field_fills_columns_and_shades_from_the_gradient() {
    // A flat field at 0.5: columns half full, lit by the vertical normal.
    let n = 8;
    let field = HeightField::Image {
        width: 4,
        height: 4,
        values: vec![0.5; 16],
    };
    let params = HeightFieldParams {
        dims: [n; 3],
        voxel: 1.0 / n as f64,
        ..HeightFieldParams::default()
    };
    let vol = from_height_field(&field, &params).unwrap();
    let l = params.lighting.direction;
    let len = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
    let amb = params.lighting.ambient;
    for y in 0..n {
        let v = vol.get(3, y, 5);
        let a = if y < n / 2 { 1.0 } else { 0.0 };
        assert_abs_diff_eq!(v[3], a, epsilon = 1e-6);
        let shade = amb + (1.0 - amb) * l[1] / len;
        assert_abs_diff_eq!(v[0], params.albedo[0] * shade * a, epsilon = 1e-5);
    }
    // Perlin noise is periodic with period 1 in both coordinates.
    for (u, v) in [(0.13, 0.77), (0.5, 0.01), (0.99, 0.4)] {
        let a = altrep::slices::perlin_periodic(u, v, 4, 3, 9);
        let b = altrep::slices::perlin_periodic(u + 1.0, v - 1.0, 4, 3, 9);
        assert_abs_diff_eq!(a, b, epsilon = 1e-9);
    }
}

#[test]
fn shape_tile_fills_its_interior_with_the_boundary_colour() {
    // A data-gen ball of radius 0.6 in a 16³ tile of edge 2: its centre voxel is interior.
    let ball = Csg::new(
        "ball",
        vec![Part {
            primitive: Primitive::Sphere {
                center: DVec3::new(0.0, 1.0, 0.0),
                radius: 0.6,
            },
            albedo: Albedo::Solid(glam::Vec3::new(0.8, 0.5, 0.2)),
        }],
    )
    .unwrap();
    let params = ShapeParams {
        dims: [16; 3],
        voxel: 2.0 / 16.0,
        ..ShapeParams::default()
    };
    let vol = from_shape(&ball, &params).unwrap();
    let centre = vol.get(8, 8, 8);
    assert_abs_diff_eq!(centre[3], 1.0, epsilon = 1e-6);
    // Its colour is that of a boundary voxel (a partly covered one), not black or unlit.
    let boundary: Vec<[f32; 4]> = vol
        .rgba()
        .iter()
        .filter(|v| v[3] > 0.0 && v[3] < 1.0)
        .map(|v| v.map(|c| c / v[3]))
        .collect();
    assert!(!boundary.is_empty());
    let nearest = boundary
        .iter()
        .map(|b| {
            (0..3)
                .map(|c| (b[c] - centre[c]).abs())
                .fold(0.0f32, f32::max)
        })
        .fold(f32::INFINITY, f32::min);
    assert!(
        nearest <= 0.05,
        "interior colour {centre:?} is no boundary colour ({nearest})"
    );
    assert!(centre[0] > 0.2 && centre[0] > centre[2], "{centre:?}");
    // The tree tile (a data-gen scene shape) builds.
    let tree = test_tile(TestTile::Tree, 16, 1).unwrap();
    assert!(tree.rgba().iter().any(|v| v[3] > 0.5));
}

#[test]
fn bad_input_gives_typed_errors() {
    assert!(matches!(
        TexelVolume::new([0, 4, 4], 0.25, vec![]),
        Err(SliceError::ZeroSize { .. })
    ));
    assert!(matches!(
        TexelVolume::new([1, 1, 1], 1.0, vec![[0.0, 0.0, f32::NAN, 0.5]]),
        Err(SliceError::NonFinite { .. })
    ));
    assert!(matches!(
        TexelVolume::new([1, 1, 1], 1.0, vec![[0.9, 0.0, 0.0, 0.5]]),
        Err(SliceError::InvalidParameter { .. })
    ));
    let field = HeightField::Image {
        width: 2,
        height: 1,
        values: vec![0.5, f32::NAN],
    };
    assert!(matches!(
        from_height_field(&field, &HeightFieldParams::default()),
        Err(SliceError::NonFinite {
            what: "height",
            index: 1
        })
    ));
    let vol = uniform(8, [0.1, 0.1, 0.1, 0.2]);
    let (data, _) = build_slices(&vol, &SliceParams::default()).unwrap();
    assert!(matches!(
        data.stack_with(Axis::Y, 16),
        Err(SliceError::TooManySlices {
            slices: 16,
            voxels: 8,
            ..
        })
    ));
    assert_eq!(data.stack_with(Axis::Z, 2).unwrap().level(), 2);
    let odd = TexelVolume::new([6, 4, 4], 0.25, vec![[0.0; 4]; 96]).unwrap();
    assert!(matches!(
        build_slices(&odd, &SliceParams::default()),
        Err(SliceError::NotPowerOfTwo {
            axis: Axis::X,
            value: 6
        })
    ));
    assert!(
        SliceParams {
            axes: [false; 3],
            ..SliceParams::default()
        }
        .validate()
        .is_err()
    );
    assert!(
        render_slices(
            &data,
            Axis::Y,
            9,
            &StackView::degrees(0.0, 0.0),
            &small_render(4)
        )
        .is_err()
    );
    assert!(
        render_truth(
            &vol,
            &StackView::degrees(89.9, 0.0),
            &small_render(4),
            &VolumeTruthParams::default()
        )
        .is_err()
    );
    assert!(slices_needed(f64::NAN, 0.1, 0.1).is_err());
    assert!(slices_needed(1.0, 0.1, 0.0).is_err());
}

/// Only what the views select is built: directions and levels (docs/design.md §9).
#[test]
fn for_views_builds_only_the_selected_axes_and_levels() {
    let vol = uniform(16, [0.1, 0.1, 0.1, 0.2]);
    let views = [StackView::degrees(0.0, 0.0), StackView::degrees(80.0, 0.0)];
    let params =
        SliceParams::for_views(&vol, &views, vol.voxel_size(), &SliceParams::default()).unwrap();
    assert_eq!(params.axes, [true, true, false]);
    // 0°: y, one slice (level 4). 80° at azimuth 0: x is 10° off, 16·tan 10° = 2.8 → 4 slices.
    assert_eq!(params.levels, Some(vec![2, 4]));
    let (data, report) = build_slices(&vol, &params).unwrap();
    let built: Vec<(Axis, usize, usize)> = report.stacks.clone();
    assert_eq!(
        built,
        vec![
            (Axis::X, 2, 4),
            (Axis::X, 4, 1),
            (Axis::Y, 2, 4),
            (Axis::Y, 4, 1)
        ]
    );
    assert!(matches!(
        data.stack(Axis::Y, 0),
        Err(SliceError::MissingStack {
            axis: Axis::Y,
            level: 0
        })
    ));
    let (full, full_report) = build_slices(&vol, &SliceParams::default()).unwrap();
    assert!(report.bytes < full_report.bytes);
    assert_eq!(full.stacks().len(), 15);
    assert!(SliceParams::for_views(&vol, &[], 0.1, &SliceParams::default()).is_err());
    let beyond = SliceParams {
        levels: Some(vec![5]),
        ..SliceParams::default()
    };
    assert!(matches!(
        build_slices(&vol, &beyond),
        Err(SliceError::InvalidParameter { name: "level", .. })
    ));
}

#[test]
fn slice_params_round_trip_and_reject_unknown_fields() {
    let p = SliceParams::default();
    let json = serde_json::to_string(&p).unwrap();
    assert_eq!(serde_json::from_str::<SliceParams>(&json).unwrap(), p);
    assert_eq!(serde_json::from_str::<SliceParams>("{}").unwrap(), p);
    assert!(serde_json::from_str::<SliceParams>(r#"{"slices": 3}"#).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]

    /// Random small volumes (empty and opaque voxels included) and views from any side: an
    /// image in [0, 1] with colour ≤ alpha, or a typed error — never a panic or NaN.
    #[test]
    fn random_volumes_and_views_render_finite(
        lx in 0u32..3, ly in 0u32..3, lz in 0u32..3, seed in any::<u64>(),
        polar in -10.0f64..190.0, azimuth in -400.0f64..400.0, level in 0usize..3,
        rule in 0usize..5, axis in 0usize..3,
    ) {
        let vol = random_volume([1 << lx, 1 << ly, 1 << lz], seed);
        let params = SliceParams { rule: MergeRule::ALL[rule], ..SliceParams::default() };
        let (data, report) = build_slices(&vol, &params).unwrap();
        prop_assert!(report.opacity_error_max.is_finite());
        let view = StackView::degrees(polar, azimuth);
        let rp = SliceRenderParams { width: 4, height: 4, supersample: Supersample::ONE, ..SliceRenderParams::default() };
        let images = [
            render_slices(&data, Axis::ALL[axis], level, &view, &rp),
            render_truth(&vol, &view, &rp, &VolumeTruthParams { steps_per_voxel: 2, ..VolumeTruthParams::default() }),
        ];
        for img in images {
            match img {
                Ok(img) => {
                    for p in &img.pixels {
                        prop_assert!(p.iter().all(|c| c.is_finite()));
                        prop_assert!(p[3] >= -1e-6 && p[3] <= 1.0 + 1e-5);
                        prop_assert!(p[..3].iter().all(|c| *c >= -1e-6 && *c <= p[3] + 1e-5));
                    }
                }
                Err(
                    SliceError::InvalidParameter { .. } | SliceError::MissingStack { .. },
                ) => {}
                Err(e) => prop_assert!(false, "unexpected error {e}"),
            }
        }
    }

    /// Adversarial numbers for the criterion and the direction choice: a result or a typed error.
    #[test]
    fn criterion_and_direction_never_panic(
        length in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(0.0), Just(-1.0), 1e-300f64..1e300],
        angle in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), -10.0f64..10.0],
        depth in prop_oneof![Just(f64::NAN), Just(0.0), Just(-1.0), 1e-300f64..1e300],
        v in prop::array::uniform3(prop_oneof![Just(f64::NAN), Just(0.0), -1e300f64..1e300]),
    ) {
        match slices_needed(length, angle, depth) {
            Ok(n) => prop_assert!(n >= 1),
            Err(SliceError::InvalidParameter { .. }) => {}
            Err(e) => prop_assert!(false, "unexpected error {e}"),
        }
        let _ = choose_direction(DVec3::from_array(v), [0.1, 0.2, 0.3], [true; 3]);
    }

    /// Height images with NaN, out-of-range and extreme values: a volume or a typed error.
    #[test]
    fn height_fields_never_panic(values in prop::collection::vec(
        prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(-0.5f32), 0.0f32..=1.0], 1..20)
    ) {
        let field = HeightField::Image { width: values.len(), height: 1, values };
        let params = HeightFieldParams { dims: [4, 4, 2], voxel: 0.25, ..HeightFieldParams::default() };
        match from_height_field(&field, &params) {
            Ok(vol) => prop_assert!(vol.rgba().iter().flatten().all(|c| c.is_finite())),
            Err(SliceError::NonFinite { .. } | SliceError::InvalidParameter { .. }) => {}
            Err(e) => prop_assert!(false, "unexpected error {e}"),
        }
    }
}

/// Shells over a cylinder (a curved patch): all shells follow the curved truth; a merged level
/// read from the viewer's side of each shell crossing (rays leave the shells from inside near the
/// silhouette) stays within 0.5 dB of the best merge rule and beats dropping by 1 dB.
#[test]
fn curved_patch_shells_follow_the_curved_truth() {
    let vol = test_tile(TestTile::Fur, 16, 2).unwrap();
    let build = |rule| {
        build_slices(
            &vol,
            &SliceParams {
                rule,
                axes: [false, true, false],
                ..SliceParams::default()
            },
        )
        .unwrap()
        .0
    };
    let params = CurvedParams {
        width: 48,
        supersample: Supersample::of(2),
        tilt_deg: 20.0,
        ..CurvedParams::default()
    };
    let truth = render_curved_truth(&vol, &params).unwrap();
    let db =
        |data, level| psnr(&render_curved_slices(data, level, &params).unwrap(), &truth).unwrap();
    let per = build(MergeRule::PerSide);
    let others: Vec<_> = [
        MergeRule::FrontOverBack,
        MergeRule::BackOverFront,
        MergeRule::Symmetric,
    ]
    .into_iter()
    .map(build)
    .collect();
    let drop = build(MergeRule::Drop);
    let all = db(&per, 0);
    assert!(all >= 30.0, "all shells {all:.1} dB");
    for level in 1..4 {
        let (p, d) = (db(&per, level), db(&drop, level));
        let best = others.iter().map(|o| db(o, level)).fold(p, f64::max);
        assert!(
            p >= best - 0.5,
            "level {level}: per-side {p:.2} dB, best rule {best:.2} dB"
        );
        assert!(
            p >= d + 1.0,
            "level {level}: per-side {p:.2} dB, drop {d:.2} dB"
        );
    }
    // A flat-patch volume of opacity 0 renders fully transparent over the cylinder.
    let empty = uniform(8, [0.0; 4]);
    let (data, _) = build_slices(&empty, &SliceParams::default()).unwrap();
    let img = render_curved_slices(&data, 0, &params).unwrap();
    assert!(img.pixels.iter().all(|p| p[3] == 0.0));
    assert!(
        render_curved_truth(
            &empty,
            &CurvedParams {
                tilt_deg: 90.0,
                ..CurvedParams::default()
            }
        )
        .is_err()
    );
}
