//! Pyramids for minification (docs/design.md §10): every prefilter against a brute-force integral
//! on sizes that are not powers of two, wrap modes against explicitly extended textures,
//! linear-light sRGB, premultiplied alpha, alpha coverage, normal maps, ripmap / fipmap / EWA
//! lookups against the supersampled truth, the mip/rip/fip decision, quad-tree fusion, and property
//! tests.

use altrep::pyramid::fusion::{fusion_experiment, psnr};
use altrep::pyramid::truth::{PlaneView, SweepParams, measure_view, test_texture};
use altrep::pyramid::{
    AlphaMode, ColourSpace, Filter, FipMap, MipError, Pyramid, PyramidKind, PyramidParams, RipMap,
    Scheme, ShearAxis, Texture, WrapMode, build, ewa_into,
};
use altrep_data_gen::SplitMix64;
use approx::{assert_abs_diff_eq, assert_relative_eq};
use proptest::prelude::*;

const FILTERS: [Filter; 4] = [
    Filter::Box,
    Filter::Triangle,
    Filter::Kaiser,
    Filter::Lanczos,
];

fn random_texture(w: usize, h: usize, c: usize, seed: u64) -> Texture {
    let mut rng = SplitMix64::new(seed);
    Texture::new(
        w,
        h,
        c,
        (0..w * h * c).map(|_| rng.next_f64() as f32).collect(),
    )
    .unwrap()
}

// ---------------------------------------------------------------------------------------------
// Brute-force reference, written independently of the library: kernels from their formulas
// (I₀ by its integral representation), the per-texel weight by a 256-point midpoint rule.

fn sinc(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        (std::f64::consts::PI * x).sin() / (std::f64::consts::PI * x)
    }
}

/// I₀(x) = (1/π) ∫₀^π e^{x cos t} dt (midpoint rule: spectrally accurate for this periodic,
/// smooth integrand).
fn bessel_i0_integral(x: f64) -> f64 {
    let n = 256;
    (0..n)
        .map(|i| (x * ((i as f64 + 0.5) * std::f64::consts::PI / n as f64).cos()).exp())
        .sum::<f64>()
        / n as f64
}

fn kernel_ref(f: Filter, t: f64, i0_alpha: f64) -> f64 {
    match f {
        Filter::Box => f64::from(u8::from(t.abs() <= 0.5)),
        Filter::Triangle => (1.0 - t.abs()).max(0.0),
        Filter::Kaiser => {
            if t.abs() >= 3.0 {
                0.0
            } else {
                let q = t / 3.0;
                sinc(t) * bessel_i0_integral(4.0 * (1.0 - q * q).sqrt()) / i0_alpha
            }
        }
        Filter::Lanczos => {
            if t.abs() >= 3.0 {
                0.0
            } else {
                sinc(t) * sinc(t / 3.0)
            }
        }
        _ => unreachable!("no other filters"),
    }
}

/// Weights `n → m` over source indices `-pad .. n + pad` (before wrapping), brute force: a
/// midpoint rule per source texel, 65 536 points for the discontinuous box, 1024 for the tent's
/// kink, 64 for the smooth windowed sincs.
fn brute_weights(f: Filter, n: usize, m: usize, i: usize, pad: i64) -> Vec<(i64, f64)> {
    if m == n {
        // Same size: the axis is copied (the definition's ripmap level-0 axis).
        return vec![(i as i64, 1.0)];
    }
    let i0_alpha = bessel_i0_integral(4.0);
    let s = n as f64 / m as f64;
    let c = (i as f64 + 0.5) * s;
    let q = match f {
        Filter::Box => 65_536,
        Filter::Triangle => 1024,
        _ => 64,
    };
    (-pad..n as i64 + pad)
        .filter(|&k| (k as f64 - c).abs() <= 3.0 * s + 2.0)
        .map(|k| {
            let w = (0..q)
                .map(|j| {
                    let x = k as f64 + (j as f64 + 0.5) / q as f64;
                    kernel_ref(f, (x - c) / s, i0_alpha) / s
                })
                .sum::<f64>()
                / q as f64;
            (k, w)
        })
        .filter(|(_, w)| *w != 0.0)
        .collect()
}

fn fold(wrap: WrapMode, k: i64, n: usize) -> usize {
    let n = n as i64;
    match wrap {
        WrapMode::Clamp => k.clamp(0, n - 1) as usize,
        WrapMode::Repeat => k.rem_euclid(n) as usize,
        WrapMode::Mirror => {
            let r = k.rem_euclid(2 * n);
            (if r < n { r } else { 2 * n - 1 - r }) as usize
        }
    }
}

/// Brute-force level `w2 × h2` of `t` for filter `f` and wrap modes.
fn brute_level(t: &Texture, w2: usize, h2: usize, f: Filter, wrap: [WrapMode; 2]) -> Vec<f64> {
    let c = t.channels;
    let wx: Vec<Vec<(i64, f64)>> = (0..w2)
        .map(|i| brute_weights(f, t.width, w2, i, 3 * t.width as i64))
        .collect();
    let wy: Vec<Vec<(i64, f64)>> = (0..h2)
        .map(|j| brute_weights(f, t.height, h2, j, 3 * t.height as i64))
        .collect();
    let mut out = vec![0.0; w2 * h2 * c];
    for j in 0..h2 {
        let sy: f64 = wy[j].iter().map(|e| e.1).sum();
        for i in 0..w2 {
            let sx: f64 = wx[i].iter().map(|e| e.1).sum();
            for &(ky, wyk) in &wy[j] {
                for &(kx, wxk) in &wx[i] {
                    let texel = t.texel(fold(wrap[0], kx, t.width), fold(wrap[1], ky, t.height));
                    for ch in 0..c {
                        out[(j * w2 + i) * c + ch] += wxk * wyk * f64::from(texel[ch]) / (sx * sy);
                    }
                }
            }
        }
    }
    out
}

#[test]
fn every_filter_matches_its_brute_force_integral_on_odd_sizes() {
    // Tolerance 2e-4: the 256-point midpoint rule against Gauss–Legendre / closed forms.
    for (n, f) in FILTERS.iter().enumerate() {
        for &(w, h, wrap) in &[
            (13usize, 7usize, [WrapMode::Clamp, WrapMode::Repeat]),
            (10, 9, [WrapMode::Mirror, WrapMode::Clamp]),
        ] {
            let base = random_texture(w, h, 2, 100 + n as u64);
            let params = PyramidParams {
                filter: *f,
                wrap,
                ..Default::default()
            };
            let pyr = Pyramid::build(base.clone(), params).unwrap();
            for level in &pyr.levels()[1..] {
                let want = brute_level(&base, level.width, level.height, *f, wrap);
                for (g, w) in level.data.iter().zip(&want) {
                    assert!(
                        (f64::from(*g) - w).abs() <= 2e-4,
                        "{f:?} {w}×{h} level {}×{}: {g} vs {w}",
                        level.width,
                        level.height
                    );
                }
            }
            // A ripmap level reduced on one axis only, same definition.
            let rip = RipMap::build(base.clone(), params).unwrap();
            let l = rip.level(2, 0);
            let want = brute_level(&base, l.width, l.height, *f, wrap);
            for (g, w) in l.data.iter().zip(&want) {
                assert_abs_diff_eq!(f64::from(*g), *w, epsilon = 2e-4);
            }
        }
    }
}

#[test]
fn wrap_modes_equal_explicitly_extended_textures() {
    // Mirror on a width-10 texture = Repeat on the texture followed by its reverse (width 20);
    // Repeat = three tiles side by side; Clamp = edge texels replicated 8 times each side
    // (Lanczos reaches 6 source texels at scale 2). Level 1 compared texel by texel.
    let (w, h) = (10usize, 6usize);
    let t = random_texture(w, h, 1, 5);
    let extended = |cols: &dyn Fn(i64) -> usize, width: usize| {
        let data = (0..h)
            .flat_map(|j| (0..width).map(move |i| (i, j)))
            .map(|(i, j)| t.texel(cols(i as i64), j)[0])
            .collect();
        Texture::new(width, h, 1, data).unwrap()
    };
    let level1 = |tex: Texture, wrap_u: WrapMode| {
        let p = PyramidParams {
            filter: Filter::Lanczos,
            wrap: [wrap_u, WrapMode::Clamp],
            ..Default::default()
        };
        Pyramid::build(tex, p).unwrap().levels()[1].clone()
    };
    let cases: [(WrapMode, Texture, usize); 3] = [
        (
            WrapMode::Mirror,
            extended(
                &|i| {
                    if i < w as i64 {
                        i as usize
                    } else {
                        2 * w - 1 - i as usize
                    }
                },
                2 * w,
            ),
            0,
        ),
        (
            WrapMode::Repeat,
            extended(&|i| i as usize % w, 3 * w),
            w / 2,
        ),
        (
            WrapMode::Clamp,
            extended(&|i| (i - 8).clamp(0, w as i64 - 1) as usize, w + 16),
            4,
        ),
    ];
    for (mode, ext, offset) in cases {
        let a = level1(t.clone(), mode);
        let b = level1(ext, WrapMode::Repeat);
        for j in 0..a.height {
            for i in 0..a.width {
                assert_abs_diff_eq!(a.texel(i, j)[0], b.texel(i + offset, j)[0], epsilon = 1e-5);
            }
        }
    }
}

#[test]
fn srgb_checkerboard_averages_in_linear_light_to_188() {
    // Black/white 2×2 checkerboard: linear mean 0.5, sRGB-encoded 0.7354 → 188 of 255; averaging
    // the encoded values would give 128.
    let data = [0.0, 1.0, 1.0, 0.0]
        .iter()
        .flat_map(|&x| [x, x, x])
        .collect();
    let t = Texture::new(2, 2, 3, data).unwrap();
    for f in FILTERS {
        let srgb = Pyramid::build(
            t.clone(),
            PyramidParams {
                colour: ColourSpace::Srgb,
                filter: f,
                wrap: [WrapMode::Repeat; 2],
                ..Default::default()
            },
        )
        .unwrap();
        let v = srgb.levels()[1].texel(0, 0);
        assert_eq!((v[0] * 255.0).round() as u32, 188, "{f:?}");
        let lin = Pyramid::build(t.clone(), PyramidParams::default()).unwrap();
        assert_abs_diff_eq!(lin.levels()[1].texel(0, 0)[0], 0.5, epsilon = 1e-6);
    }
}

#[test]
fn straight_alpha_is_premultiplied_for_filtering() {
    // One opaque red texel among transparent green ones: the filtered colour is pure red (the
    // transparent colour must not bleed in), alpha the mean coverage 1/4.
    let mut data = vec![0.0f32; 16];
    for k in 0..4 {
        data[k * 4..k * 4 + 4].copy_from_slice(&[0.0, 1.0, 0.0, 0.0]);
    }
    data[0..4].copy_from_slice(&[1.0, 0.0, 0.0, 1.0]);
    let t = Texture::new(2, 2, 4, data).unwrap();
    for (mode, colour) in [
        (AlphaMode::Straight, ColourSpace::Linear),
        (AlphaMode::Straight, ColourSpace::Srgb),
    ] {
        let p = Pyramid::build(
            t.clone(),
            PyramidParams {
                alpha: mode,
                colour,
                ..Default::default()
            },
        )
        .unwrap();
        let v = p.levels()[1].texel(0, 0);
        assert_abs_diff_eq!(v[0], 1.0, epsilon = 1e-5);
        assert_abs_diff_eq!(v[1], 0.0, epsilon = 1e-6);
        assert_abs_diff_eq!(v[3], 0.25, epsilon = 1e-6);
    }
    // Premultiplied input: stored colour stays premultiplied (red · 1/4).
    let mut pm = t.clone();
    for k in 1..4 {
        pm.data[k * 4..k * 4 + 4].copy_from_slice(&[0.0, 0.0, 0.0, 0.0]);
    }
    let p = Pyramid::build(
        pm,
        PyramidParams {
            alpha: AlphaMode::Premultiplied,
            ..Default::default()
        },
    )
    .unwrap();
    let v = p.levels()[1].texel(0, 0);
    assert_abs_diff_eq!(v[0], 0.25, epsilon = 1e-6);
    assert_abs_diff_eq!(v[3], 0.25, epsilon = 1e-6);
}

/// A foliage-like cut-out: thin blades of alpha 1 on alpha 0, soft edges.
fn cutout(n: usize) -> Texture {
    let mut rng = SplitMix64::new(9);
    let blades: Vec<(f64, f64, f64)> = (0..40)
        .map(|_| (rng.next_f64(), rng.next_f64(), rng.range(0.004, 0.012)))
        .collect();
    let data = (0..n * n)
        .flat_map(|k| {
            let (u, v) = (
                (k % n) as f64 / n as f64 + 0.5 / n as f64,
                (k / n) as f64 / n as f64 + 0.5 / n as f64,
            );
            // Vertical blades: distance in u to the nearest blade, tapering with v.
            let a = blades
                .iter()
                .map(|&(bu, bv, width)| {
                    let d = (u - bu - 0.05 * (v - bv)).abs();
                    let w = width * (1.0 - (v - bv).abs().min(0.4) / 0.4);
                    (1.0 - ((d - w) * n as f64).max(0.0)).clamp(0.0, 1.0)
                })
                .fold(0.0, f64::max);
            [0.2, 0.6, 0.1, a as f32]
        })
        .collect();
    Texture::new(n, n, 4, data).unwrap()
}

#[test]
fn alpha_coverage_is_kept_within_one_percent_per_level() {
    let t = cutout(128);
    let mut params = PyramidParams {
        alpha: AlphaMode::Straight,
        filter: Filter::Kaiser,
        coverage_reference: Some(0.5),
        ..Default::default()
    };
    let (_, with) = build(&t, &params).unwrap();
    assert!(
        with.coverage[0] > 0.02 && with.coverage[0] < 0.5,
        "{:?}",
        with.coverage
    );
    // Stated tolerance: 1 % of the area, every level of at least 4 × 4 texels.
    assert!(with.max_coverage_error <= 0.01, "{:?}", with.coverage);
    // Without preservation the thin blades fade away: the check can fail.
    params.coverage_reference = None;
    let (data, _) = build(&t, &params).unwrap();
    let altrep::pyramid::PyramidData::Mip(p) = data else {
        panic!("a mipmap was asked for")
    };
    let level3 = &p.levels()[3];
    let cov3 = altrep::pyramid::levels::alpha_coverage(level3, 3, 0.5, 1.0, params.wrap);
    assert!(
        (cov3 - with.coverage[0]).abs() > 0.01,
        "{cov3} vs {}",
        with.coverage[0]
    );
}

#[test]
fn normal_map_levels_are_unit_vectors() {
    let mut rng = SplitMix64::new(3);
    let data = (0..37 * 21)
        .flat_map(|_| {
            let (x, y) = (rng.range(-0.6, 0.6), rng.range(-0.6, 0.6));
            let z = (1.0 - x * x - y * y).sqrt();
            [x as f32, y as f32, z as f32]
        })
        .collect();
    let t = Texture::new(37, 21, 3, data).unwrap();
    let p = Pyramid::build(
        t,
        PyramidParams {
            normal_map: true,
            filter: Filter::Lanczos,
            ..Default::default()
        },
    )
    .unwrap();
    for level in p.levels() {
        for n in level.data.chunks(3) {
            let len = n.iter().map(|x| x * x).sum::<f32>().sqrt();
            assert_relative_eq!(len, 1.0, max_relative = 1e-5);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Lookups against the supersampled truth.

fn sweep_params() -> SweepParams {
    SweepParams {
        pixels: 8,
        max_samples_per_pixel: 4096,
        ..Default::default()
    }
}

fn fipmap(tex: &Texture) -> FipMap {
    FipMap::build(
        tex.clone(),
        PyramidParams {
            wrap: [WrapMode::Repeat; 2],
            ..Default::default()
        },
    )
    .unwrap()
}

fn view(d: f64, tilt: f64, az: f64) -> PlaneView {
    PlaneView {
        texels_per_pixel: d,
        tilt_deg: tilt,
        azimuth_deg: az,
    }
}

#[test]
fn on_a_smooth_texture_every_lookup_meets_the_truth() {
    // Two cycles per tile (values in [0.2, 0.8], amplitude 0.3): a wrong shear, level or
    // coordinate would miss by up to the amplitude. Stated tolerances (RMS): EWA 0.005
    // everywhere; ripmap (along an axis) and the decision's lookup 0.04 — a ripmap lookup blurs
    // up to twice the footprint along its major axis (the level's box plus the bilinear tent),
    // and the shear raises the wave's frequency along that axis; mipmap 0.01 at normal
    // incidence, 0.1 when oblique (its isotropic level over-blurs the minor axis).
    let n = 64;
    let data = (0..n * n)
        .map(|k| {
            let (u, v) = (
                ((k % n) as f64 + 0.5) / n as f64,
                ((k / n) as f64 + 0.5) / n as f64,
            );
            (0.5 + 0.3 * (std::f64::consts::TAU * (2.0 * u + v)).sin()) as f32
        })
        .collect();
    let tex = Texture::new(n, n, 1, data).unwrap();
    let fip = fipmap(&tex);
    let mut rows = Vec::new();
    for (d, tilt, az) in [
        (1.0, 0.0, 0.0),
        (1.0, 70.0, 0.0),
        (1.0, 80.0, 30.0),
        (0.5, 85.0, 60.0),
        (0.5, 80.0, 45.0),
    ] {
        rows.push(measure_view(
            &fip,
            &tex,
            &view(d, tilt, az),
            &sweep_params(),
        ));
    }
    for r in &rows {
        let tol_mip = if r.view.tilt_deg == 0.0 { 0.01 } else { 0.1 };
        let ok = r.rms[0] <= tol_mip && r.rms[2] <= 0.04 && r.rms[3] <= 0.005;
        let ok = ok && (r.view.azimuth_deg != 0.0 || r.rms[1] <= 0.04);
        assert!(ok, "{rows:#?}");
    }
}

#[test]
fn ripmap_beats_mipmap_at_oblique_angles() {
    let tex = test_texture(128, 11);
    let fip = fipmap(&tex);
    let (mut mip, mut rip) = (0.0, 0.0);
    for d in [2.0, 8.0] {
        for tilt in [80.0, 85.0, 89.0] {
            let row = measure_view(&fip, &tex, &view(d, tilt, 0.0), &sweep_params());
            mip += row.rms[0];
            rip += row.rms[1];
        }
    }
    // Stated margin: the ripmap's summed RMS is at most 80 % of the mipmap's.
    assert!(rip <= 0.8 * mip, "rip {rip} mip {mip}");
}

#[test]
fn fipmap_beats_ripmap_on_skewed_grazing_views() {
    let tex = test_texture(128, 11);
    let fip = fipmap(&tex);
    let (mut rip, mut fipe) = (0.0, 0.0);
    for d in [1.0, 2.0] {
        for tilt in [80.0, 85.0, 89.0] {
            for az in [30.0, 60.0] {
                let row = measure_view(&fip, &tex, &view(d, tilt, az), &sweep_params());
                assert!(matches!(row.scheme, Scheme::Fip(_)), "{:?}", row.scheme);
                rip += row.rms[1];
                fipe += row.rms[2];
            }
        }
    }
    // Stated margin: the fipmap's summed RMS is at most 90 % of the ripmap's.
    assert!(fipe <= 0.9 * rip, "fip {fipe} rip {rip}");
}

#[test]
fn ewa_is_nearest_to_the_truth_on_average() {
    let tex = test_texture(128, 11);
    let fip = fipmap(&tex);
    let mut sums = [0.0; 4];
    for d in [1.0, 4.0] {
        for tilt in [0.0, 45.0, 75.0, 85.0] {
            for az in [0.0, 30.0] {
                let row = measure_view(&fip, &tex, &view(d, tilt, az), &sweep_params());
                sums.iter_mut().zip(row.rms).for_each(|(s, e)| *s += e);
            }
        }
    }
    for k in 0..3 {
        assert!(
            sums[3] < sums[k],
            "EWA {} vs method {k} {}",
            sums[3],
            sums[k]
        );
    }
}

#[test]
fn decision_at_the_three_canonical_directions() {
    let tex = test_texture(32, 1);
    let fip = fipmap(&tex);
    let deg = f64::to_radians;
    // Along the normal: mipmap.
    assert_eq!(fip.decide([0.0, 1.0, 0.0]), Scheme::Mip);
    // Grazing along the u axis (and along v): ripmap.
    assert_eq!(
        fip.decide([deg(85.0).sin(), deg(85.0).cos(), 0.0]),
        Scheme::Rip
    );
    assert_eq!(
        fip.decide([0.0, deg(85.0).cos(), deg(85.0).sin()]),
        Scheme::Rip
    );
    // Grazing and skewed by 30° from u: the v-shear c = −½ (closest to −tan 30°).
    let dir = |az: f64| {
        let (t, a) = (deg(85.0), deg(az));
        [t.sin() * a.cos(), t.cos(), t.sin() * a.sin()]
    };
    let Scheme::Fip(i) = fip.decide(dir(30.0)) else {
        panic!("expected a fipmap")
    };
    let s = fip.shears()[i];
    assert_eq!((s.axis, s.value()), (ShearAxis::V, -0.5));
    // Skewed by 60°: the u-shear b = −½ (closest to −cot 60°).
    let Scheme::Fip(i) = fip.decide(dir(60.0)) else {
        panic!("expected a fipmap")
    };
    let s = fip.shears()[i];
    assert_eq!((s.axis, s.value()), (ShearAxis::U, -0.5));
    // Moderate tilt, skewed: still the ripmap (fip_min_tilt_deg = 80°).
    let (t, a) = (deg(50.0), deg(30.0));
    assert_eq!(
        fip.decide([t.sin() * a.cos(), t.cos(), t.sin() * a.sin()]),
        Scheme::Rip
    );
}

#[test]
fn fusion_removes_the_occluder_and_fails_without_rejection() {
    let e = fusion_experiment(64, 3).unwrap();
    // Stated floors: ≥ 40 dB with rejection (noise 0.01 only), ≤ 30 dB without.
    assert!(e.psnr_with_rejection >= 40.0, "{e:?}");
    assert!(e.psnr_without_rejection <= 30.0, "{e:?}");
    assert!(e.report.rejected.iter().sum::<usize>() > 0);
    let t = test_texture(8, 1);
    assert!(psnr(&t, &t).is_infinite());
}

#[test]
fn bad_input_gets_typed_errors() {
    let t = random_texture(8, 8, 4, 1);
    let fip_clamp = FipMap::build(t.clone(), PyramidParams::default());
    assert!(matches!(fip_clamp, Err(MipError::Unsupported(_))));
    let p = PyramidParams {
        coverage_reference: Some(0.5),
        ..Default::default()
    };
    assert!(matches!(
        Pyramid::build(t.clone(), p),
        Err(MipError::InvalidParams {
            name: "coverage_reference",
            ..
        })
    ));
    let p = PyramidParams {
        normal_map: true,
        colour: ColourSpace::Srgb,
        ..Default::default()
    };
    assert!(matches!(
        Pyramid::build(t.clone(), p),
        Err(MipError::InvalidParams {
            name: "normal_map",
            ..
        })
    ));
    let p = PyramidParams {
        ewa_max_anisotropy: f64::NAN,
        kind: PyramidKind::Rip,
        ..Default::default()
    };
    assert!(build(&t, &p).is_err());
    let sweep = SweepParams {
        tilts_deg: vec![90.0],
        ..Default::default()
    };
    assert!(matches!(
        sweep.validate(),
        Err(MipError::InvalidParams {
            name: "tilts_deg",
            ..
        })
    ));
    assert!(altrep::pyramid::fuse(&[], 8, &Default::default()).is_err());
}

/// The fipmap decision of `altrep::pyramid::fip`'s module docs (Bornik & Ferko's colour-cube
/// rule), written from the docs and not from the code: the mipmap within `mip_max_tilt_deg` of
/// the normal (`g`) or for a zero or non-finite direction; the ripmap where the stretch
/// direction `φ = atan2(b, r)` lies within `rip_max_skew_deg` of a texture axis, below
/// `fip_min_tilt_deg` or without shears; otherwise the shear that leaves `φ` closest to the axis
/// it aligns with ([`shear_residual`]).
fn colour_cube_rule(d: [f64; 3], shears: &[altrep::pyramid::Shear], p: &PyramidParams) -> Scheme {
    use std::f64::consts::FRAC_PI_2;
    let n = d.iter().map(|c| c * c).sum::<f64>().sqrt();
    if !n.is_finite() || n == 0.0 {
        return Scheme::Mip;
    }
    let tilt = (d[1].abs() / n).min(1.0).acos().to_degrees();
    if tilt <= p.mip_max_tilt_deg {
        return Scheme::Mip;
    }
    let phi = d[2].atan2(d[0]);
    let a = phi.rem_euclid(FRAC_PI_2);
    if a.min(FRAC_PI_2 - a).to_degrees() <= p.rip_max_skew_deg
        || tilt < p.fip_min_tilt_deg
        || shears.is_empty()
    {
        return Scheme::Rip;
    }
    let mut best = 0;
    for (i, s) in shears.iter().enumerate() {
        if shear_residual(phi, s) < shear_residual(phi, &shears[best]) {
            best = i;
        }
    }
    Scheme::Fip(best)
}

/// The angle between the stretch direction `φ` after shear `s` and the texture axis the shear
/// aligns it with (`V`: `v' = v + c·u`, onto `u`; `U`: `u' = u + c·v`, onto `v`), in `[0, π/2]`.
fn shear_residual(phi: f64, s: &altrep::pyramid::Shear) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    let c = f64::from(s.num) / f64::from(s.den);
    let (u, v) = (phi.cos(), phi.sin());
    let (angle, axis) = match s.axis {
        ShearAxis::V => ((v + c * u).atan2(u), 0.0),
        ShearAxis::U => (v.atan2(u + c * v), FRAC_PI_2),
    };
    let off = (angle.rem_euclid(PI) - axis).abs();
    off.min(PI - off)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
    /// Any size, filter, wrap, colour and alpha handling and huge values: no panic, finite levels
    /// of every kind; lookups with degenerate derivatives stay finite.
    #[test]
    fn any_input_gives_finite_levels_and_lookups(
        w in 1usize..24, h in 1usize..24, c in 2usize..5, seed in any::<u64>(),
        scale in prop_oneof![Just(1.0f32), Just(1e30f32), Just(-1e-30f32)],
        f in 0usize..4, wrap in 0usize..3, srgb in any::<bool>(), alpha in 0usize..3,
        deriv in prop_oneof![Just(0.0f64), Just(f64::NAN), Just(f64::INFINITY), Just(1e-12), Just(3.7), Just(1e9)],
        dir in prop::array::uniform3(-1.0f64..1.0),
    ) {
        let mut t = random_texture(w, h, c, seed);
        t.data.iter_mut().for_each(|x| *x *= scale);
        let wrap = [WrapMode::Clamp, WrapMode::Repeat, WrapMode::Mirror][wrap];
        let params = PyramidParams {
            filter: FILTERS[f],
            wrap: [wrap, WrapMode::Repeat],
            colour: if srgb { ColourSpace::Srgb } else { ColourSpace::Linear },
            alpha: [AlphaMode::None, AlphaMode::Straight, AlphaMode::Premultiplied][alpha],
            coverage_reference: (alpha > 0).then_some(0.5),
            ..Default::default()
        };
        let pyr = Pyramid::build(t.clone(), params).unwrap();
        prop_assert!(pyr.levels().iter().all(|l| l.data.iter().all(|x| x.is_finite())));
        let rip = RipMap::build(t.clone(), params).unwrap();
        let mut out = vec![0.0f32; c];
        rip.sample_lod_into(0.3, 0.9, rip.lod(deriv, 0.1, 0.0, deriv), &mut out);
        prop_assert!(out.iter().all(|x| x.is_finite()));
        ewa_into(&pyr, 0.3, -2.5, deriv, 0.0, 0.2, deriv, 64.0, &mut out);
        prop_assert!(out.iter().all(|x| x.is_finite()), "{out:?}");
        let fp = PyramidParams { wrap: [WrapMode::Repeat; 2], ..params };
        let fip = FipMap::build(t, fp).unwrap();
        for scheme in [Scheme::Mip, Scheme::Rip, Scheme::Fip(0), Scheme::Fip(5)] {
            fip.sample_into(scheme, 7.1, -0.2, deriv, deriv, 0.5, deriv, None, &mut out);
            prop_assert!(out.iter().all(|x| x.is_finite()), "{scheme:?} {out:?}");
        }
        // The decision against the colour-cube rule of the module docs, restated here: a zero
        // or non-finite direction and the degenerate derivatives give the mipmap or the ripmap
        // the rule names, and a random direction the scheme the rule picks.
        for d in [[deriv, deriv, 0.0], dir] {
            let (got, want) = (fip.decide(d), colour_cube_rule(d, fip.shears(), &fp));
            if let (Scheme::Fip(i), Scheme::Fip(j)) = (got, want) {
                // Shears whose residuals tie within rounding are equally right.
                let phi = d[2].atan2(d[0]);
                let residual = |k: usize| shear_residual(phi, &fip.shears()[k]);
                prop_assert!(
                    i < fip.shears().len() && residual(i) <= residual(j) + 1e-12,
                    "direction {:?}: shear {} (residual {}) instead of {} ({})",
                    d, i, residual(i.min(fip.shears().len() - 1)), j, residual(j)
                );
            } else {
                prop_assert_eq!(got, want, "direction {:?}", d);
            }
        }
    }

    /// Fusion of arbitrary (possibly inconsistent) views: a fused texture with finite values or
    /// a typed error, never a panic.
    #[test]
    fn fusion_of_any_views_is_finite_or_refused(
        log_n in 0u32..6, scales in proptest::collection::vec(0u32..7, 0..6),
        tol in prop_oneof![Just(0.1f64), Just(0.0), Just(f64::NAN), Just(1e-9)],
        reject in any::<bool>(), seed in any::<u64>(),
    ) {
        let n = 1usize << log_n;
        let mut rng = SplitMix64::new(seed);
        let views: Vec<altrep::pyramid::FusionView> = scales
            .iter()
            .map(|&m| {
                let s = (n >> m.min(log_n)).max(1);
                altrep::pyramid::FusionView {
                    image: Texture::new(s, s, 2, (0..s * s * 2).map(|_| rng.next_f64() as f32).collect()).unwrap(),
                    scale_log2: m,
                }
            })
            .collect();
        let params = altrep::pyramid::FusionParams { reject, tolerance: tol };
        match altrep::pyramid::fuse(&views, n, &params) {
            Ok((t, _)) => prop_assert!(t.data.iter().all(|x| x.is_finite())),
            Err(e) => prop_assert!(matches!(e, MipError::InvalidParams { .. }), "{}", e),
        }
    }

    /// Texture input with a NaN or infinity is refused, naming the float.
    #[test]
    fn non_finite_texels_are_refused(k in 0usize..12, bad in prop_oneof![Just(f32::NAN), Just(f32::INFINITY)]) {
        let mut data = vec![0.5f32; 12];
        data[k] = bad;
        prop_assert_eq!(Texture::new(3, 2, 2, data), Err(MipError::NonFinite { index: k }));
    }
}
