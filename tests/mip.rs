//! Mip pyramid: exact footprint means, continuity of trilinear sampling, seamless wrapping,
//! level selection, bad input, and property tests.

use altrep::mip::{MipError, Pyramid, PyramidParams, Texture, WrapMode};
use altrep_data_gen::SplitMix64;
use proptest::prelude::*;

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

/// Brute-force mean of level 0 over `[x0, x1] × [y0, y1]` (in level-0 texel units), with
/// fractional overlaps.
fn footprint_mean(t: &Texture, x0: f64, x1: f64, y0: f64, y1: f64, ch: usize) -> f64 {
    let mut sum = 0.0;
    for j in 0..t.height {
        let oy = (y1.min(j as f64 + 1.0) - y0.max(j as f64)).max(0.0);
        for i in 0..t.width {
            let ox = (x1.min(i as f64 + 1.0) - x0.max(i as f64)).max(0.0);
            sum += ox * oy * f64::from(t.texel(i, j)[ch]);
        }
    }
    sum / ((x1 - x0) * (y1 - y0))
}

#[test]
fn every_level_is_the_exact_mean_of_its_footprint() {
    for &(w, h) in &[(16, 8), (13, 7), (5, 11), (1, 6), (33, 1)] {
        let base = random_texture(w, h, 2, (w * 31 + h) as u64);
        let pyr = Pyramid::build(base.clone(), PyramidParams::default()).unwrap();
        let last = pyr.levels().last().unwrap();
        assert_eq!(
            (last.width, last.height),
            (1, 1),
            "pyramid of {w}×{h} ends at 1×1"
        );
        for (l, level) in pyr.levels().iter().enumerate() {
            let (sx, sy) = (
                w as f64 / level.width as f64,
                h as f64 / level.height as f64,
            );
            for j in 0..level.height {
                for i in 0..level.width {
                    for ch in 0..2 {
                        let want = footprint_mean(
                            &base,
                            i as f64 * sx,
                            (i + 1) as f64 * sx,
                            j as f64 * sy,
                            (j + 1) as f64 * sy,
                            ch,
                        );
                        let got = f64::from(level.texel(i, j)[ch]);
                        assert!(
                            (got - want).abs() < 1e-5,
                            "{w}×{h} level {l} texel ({i},{j}) ch {ch}: {got} vs {want}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn trilinear_is_continuous_across_level_changes() {
    let pyr = Pyramid::build(
        random_texture(32, 20, 3, 7),
        PyramidParams {
            wrap: [WrapMode::Repeat, WrapMode::Clamp],
            ..Default::default()
        },
    )
    .unwrap();
    let mut rng = SplitMix64::new(3);
    for _ in 0..200 {
        let (u, v) = (rng.next_f64(), rng.next_f64());
        for k in 1..pyr.levels().len() {
            let a = pyr.trilinear(u, v, k as f64 - 1e-7);
            let b = pyr.trilinear(u, v, k as f64 + 1e-7);
            let exact = pyr.bilinear(k, u, v);
            for c in 0..3 {
                assert!(
                    (a[c] - b[c]).abs() < 1e-5,
                    "jump at level {k}: {} vs {}",
                    a[c],
                    b[c]
                );
                assert!(
                    (a[c] - exact[c]).abs() < 1e-5,
                    "level {k}: {} vs bilinear {}",
                    a[c],
                    exact[c]
                );
            }
        }
    }
}

#[test]
fn repeat_mode_tiles_seamlessly_and_clamp_does_not_wrap() {
    let base = random_texture(10, 6, 1, 11);
    let rep = Pyramid::build(
        base.clone(),
        PyramidParams {
            wrap: [WrapMode::Repeat; 2],
            ..Default::default()
        },
    )
    .unwrap();
    let clamp = Pyramid::build(base.clone(), PyramidParams::default()).unwrap();
    let mut rng = SplitMix64::new(5);
    for _ in 0..100 {
        let (u, v, lod) = (rng.next_f64(), rng.next_f64(), rng.range(0.0, 3.0));
        let a = rep.trilinear(u, v, lod)[0];
        assert!(
            (a - rep.trilinear(u + 1.0, v - 2.0, lod)[0]).abs() < 1e-5,
            "not periodic at ({u},{v})"
        );
        // Continuous across the seam at u = 0.
        let l = rep.trilinear(-1e-7, v, lod)[0];
        let r = rep.trilinear(1e-7, v, lod)[0];
        assert!((l - r).abs() < 1e-4, "seam at v={v}: {l} vs {r}");
    }
    // At u = 0 (the edge between the last and first texel) repeat averages both, clamp reads the first.
    let v = 0.5 / 6.0;
    let first = base.texel(0, 0)[0];
    let last = base.texel(9, 0)[0];
    assert!((rep.bilinear(0, 0.0, v)[0] - 0.5 * (first + last)).abs() < 1e-6);
    assert!((clamp.bilinear(0, 0.0, v)[0] - first).abs() < 1e-6);
}

#[test]
fn level_of_detail_follows_the_footprint() {
    let pyr = Pyramid::build(random_texture(64, 32, 1, 1), PyramidParams::default()).unwrap();
    // One texel per pixel along u → level 0; four texels per pixel → level 2.
    assert!((pyr.lod(1.0 / 64.0, 0.0, 0.0, 1.0 / 32.0)).abs() < 1e-12);
    assert!((pyr.lod(4.0 / 64.0, 0.0, 0.0, 1.0 / 32.0) - 2.0).abs() < 1e-12);
    // The larger of the two axes decides (Heckbert's D).
    assert!((pyr.lod(1.0 / 64.0, 0.0, 0.0, 8.0 / 32.0) - 3.0).abs() < 1e-12);
    // A footprint of the whole texture samples the mean (last level).
    let mean: f32 = pyr.levels()[0].data.iter().sum::<f32>() / (64.0 * 32.0);
    let s = pyr.sample_grad(0.3, 0.7, 4.0, 0.0, 0.0, 4.0)[0];
    assert!((s - mean).abs() < 1e-5, "{s} vs {mean}");
}

#[test]
fn bad_textures_are_typed_errors() {
    assert_eq!(
        Texture::new(0, 4, 1, vec![]),
        Err(MipError::ZeroSize { what: "width" })
    );
    assert_eq!(
        Texture::new(2, 2, 0, vec![]),
        Err(MipError::ZeroSize { what: "channels" })
    );
    assert_eq!(
        Texture::new(2, 2, 1, vec![0.0; 3]),
        Err(MipError::DataSize {
            got: 3,
            expected: 4
        })
    );
    assert_eq!(
        Texture::new(2, 1, 1, vec![0.0, f32::NAN]),
        Err(MipError::NonFinite { index: 1 })
    );
    let bad = Texture {
        width: 2,
        height: 2,
        channels: 1,
        data: vec![0.0, 1.0, f32::INFINITY, 0.0],
    };
    assert_eq!(
        Pyramid::build(bad, PyramidParams::default()),
        Err(MipError::NonFinite { index: 2 })
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
    /// Any size and values: no panic, finite levels, and every level keeps the mean of level 0
    /// (the area-weighted box conserves the integral).
    #[test]
    fn levels_conserve_the_mean(w in 1usize..40, h in 1usize..40, c in 1usize..5, seed in any::<u64>(), scale in -1e6f32..1e6) {
        let mut t = random_texture(w, h, c, seed);
        t.data.iter_mut().for_each(|x| *x *= scale);
        let pyr = Pyramid::build(t.clone(), PyramidParams { wrap: [WrapMode::Repeat, WrapMode::Clamp], ..Default::default() }).unwrap();
        let mean = |t: &Texture, ch: usize| t.data.iter().skip(ch).step_by(c).map(|&x| f64::from(x)).sum::<f64>() / (t.width * t.height) as f64;
        for level in pyr.levels() {
            prop_assert!(level.data.iter().all(|x| x.is_finite()));
            for ch in 0..c {
                let (a, b) = (mean(level, ch), mean(&t, ch));
                prop_assert!((a - b).abs() <= 1e-4 * (1.0 + f64::from(scale.abs())), "level {}×{} mean {a} vs {b}", level.width, level.height);
            }
        }
        let s = pyr.trilinear(0.37, 1.9, 1.5);
        prop_assert!(s.iter().all(|x| x.is_finite()));
    }
}
