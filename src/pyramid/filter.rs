//! Prefilter kernels and the separable resampler that builds every pyramid level.
//!
//! ## Definition (what every level is)
//! Level 0 is read as a piecewise-constant function (texel `k` is constant on `[k, k+1)`, in
//! level-0 texel units). An output texel `i` of a resampling `n → m` (scale `s = n/m ≥ 1`) has its
//! centre at `c = (i + ½)·s` and value
//!
//! `out_i = Σ_k w_k · in_k`, `w_k = ∫_k^{k+1} K((x − c)/s) / s dx`,
//!
//! the convolution of the box-reconstructed input with the kernel stretched to the output texel
//! size, sampled at the output texel centre (NVIDIA Texture Tools' definition). Taps outside
//! `[0, n)` are folded back by the [`WrapMode`]; the weights are finally divided by their sum, so a
//! constant stays constant. When `m = n` the axis is copied unchanged (a ripmap's level-0 axis).
//!
//! Kernels `K(t)` (support radius in output texels):
//! * [`Filter::Box`]: `1` on `[−½, ½]` — the exact area-weighted mean (the weights are the overlap
//!   areas; closed form).
//! * [`Filter::Triangle`]: `max(0, 1 − |t|)`, radius 1 (closed form CDF).
//! * [`Filter::Kaiser`]: `sinc(t) · I₀(α √(1 − (t/3)²)) / I₀(α)`, radius 3, `α = 4` (NVTT's
//!   Kaiser), integrated by 8-point Gauss–Legendre per source texel.
//! * [`Filter::Lanczos`]: `sinc(t) · sinc(t/3)`, radius 3 (Lanczos-3), same quadrature.
//!
//! Cost of one resampling of a `W × H × C` texture to `m_x × m_y`: `C·(H·m_x·t_x + m_x·m_y·t_y)`
//! multiply-adds with `t = 2·radius·s + 2` taps per axis, rows in parallel.

use rayon::prelude::*;

use super::mip::{Filter, Texture, WrapMode};

/// Support radius of the kernel in output texels.
pub fn radius(filter: Filter) -> f64 {
    match filter {
        Filter::Box => 0.5,
        Filter::Triangle => 1.0,
        Filter::Kaiser | Filter::Lanczos => 3.0,
    }
}

/// Normalised sinc, `sin(πx)/(πx)`.
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-8 {
        1.0
    } else {
        let p = std::f64::consts::PI * x;
        p.sin() / p
    }
}

/// Modified Bessel function of the first kind, order 0 (power series; exact to f64 for
/// arguments below 20).
fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term, q) = (1.0, 1.0, x * x / 4.0);
    for k in 1..60 {
        term *= q / (k * k) as f64;
        sum += term;
        if term < sum * 1e-17 {
            break;
        }
    }
    sum
}

/// Kaiser window parameter `α` (NVTT).
pub const KAISER_ALPHA: f64 = 4.0;

/// The kernel `K(t)` of `filter` at `t` output texels from the centre (not normalised).
pub fn kernel(filter: Filter, t: f64) -> f64 {
    let r = radius(filter);
    if t.abs() > r {
        return 0.0;
    }
    match filter {
        Filter::Box => 1.0,
        Filter::Triangle => 1.0 - t.abs(),
        Filter::Kaiser => {
            let q = t / r;
            sinc(t) * bessel_i0(KAISER_ALPHA * (1.0 - q * q).max(0.0).sqrt())
                / bessel_i0(KAISER_ALPHA)
        }
        Filter::Lanczos => sinc(t) * sinc(t / r),
    }
}

/// `∫_a^b K(t) dt` for `a ≤ b`: closed form for box and triangle, 8-point Gauss–Legendre for
/// Kaiser and Lanczos (smooth inside the support and zero at its ends).
pub fn kernel_integral(filter: Filter, a: f64, b: f64) -> f64 {
    let r = radius(filter);
    let (a, b) = (a.max(-r), b.min(r));
    if a >= b {
        return 0.0;
    }
    match filter {
        Filter::Box => b - a,
        Filter::Triangle => {
            // CDF of the tent: F(t) = t + t|t|/2·(−1)·sign … written piecewise.
            let cdf = |t: f64| {
                if t <= 0.0 {
                    0.5 * (1.0 + t) * (1.0 + t)
                } else {
                    1.0 - 0.5 * (1.0 - t) * (1.0 - t)
                }
            };
            cdf(b) - cdf(a)
        }
        Filter::Kaiser | Filter::Lanczos => {
            const X: [f64; 4] = [
                0.183_434_642_495_649_8,
                0.525_532_409_916_329,
                0.796_666_477_413_626_7,
                0.960_289_856_497_536_3,
            ];
            const W: [f64; 4] = [
                0.362_683_783_378_362,
                0.313_706_645_877_887_3,
                0.222_381_034_453_374_5,
                0.101_228_536_290_376_3,
            ];
            let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
            h * X
                .iter()
                .zip(W)
                .map(|(&x, w)| w * (kernel(filter, m - h * x) + kernel(filter, m + h * x)))
                .sum::<f64>()
        }
    }
}

/// Folds index `i` into `[0, n)` by `wrap`: clamp to the edge, repeat with period `n`, or mirror
/// with period `2n` (`…, 1, 0, 0, 1, …, n−1, n−1, n−2, …`, as GL's `MIRRORED_REPEAT`).
#[inline]
pub fn wrap_index(wrap: WrapMode, i: i64, n: usize) -> usize {
    let n = n as i64;
    match wrap {
        WrapMode::Clamp => i.clamp(0, n - 1) as usize,
        WrapMode::Repeat => i.rem_euclid(n) as usize,
        WrapMode::Mirror => {
            let k = i.rem_euclid(2 * n);
            (if k < n { k } else { 2 * n - 1 - k }) as usize
        }
    }
}

/// Resampling weights `n → m` along one axis: for each output texel, `(source index, weight)`
/// pairs after wrapping, weights summing to 1 (see the module docs for the definition).
pub fn weights(filter: Filter, n: usize, m: usize, wrap: WrapMode) -> Vec<Vec<(usize, f64)>> {
    if m == n {
        return (0..n).map(|i| vec![(i, 1.0)]).collect();
    }
    (0..m)
        .map(|i| output_weights(filter, n, m, wrap, i))
        .collect()
}

/// The unwrapped source range `[k0, k1)` scanned for output texel `i` of a resampling `n → m`
/// (`m < n`): the kernel's support around the centre `(i + ½)·n/m`. When `0 ≤ k0` and `k1 ≤ n`
/// no tap folds over an edge.
pub fn tap_range(filter: Filter, n: usize, m: usize, i: usize) -> (i64, i64) {
    let s = n as f64 / m as f64;
    let r = radius(filter) * s.max(1.0);
    let c = (i as f64 + 0.5) * s;
    ((c - r).floor() as i64, (c + r).ceil() as i64)
}

/// The weights of output texel `i` of a resampling `n → m` (`m ≠ n`): what [`weights`] returns
/// at index `i`. Cost: one kernel integral per source texel in [`tap_range`].
pub fn output_weights(
    filter: Filter,
    n: usize,
    m: usize,
    wrap: WrapMode,
    i: usize,
) -> Vec<(usize, f64)> {
    let s = n as f64 / m as f64;
    let ks = s.max(1.0);
    let c = (i as f64 + 0.5) * s;
    let (k0, k1) = tap_range(filter, n, m, i);
    fold_weights(n, wrap, k0, k1, |k| {
        kernel_integral(filter, (k as f64 - c) / ks, (k as f64 + 1.0 - c) / ks)
    })
}

/// The second half of [`output_weights`]: the raw weights `raw(k)` of the unwrapped taps
/// `k0..k1` (zeros dropped) folded into `[0, n)` by `wrap` (a texel met twice adds up, in tap
/// order) and divided by their sum. Callers that know `raw` already (the same offsets from the
/// centre recur) get bit for bit what [`output_weights`] gives.
pub fn fold_weights(
    n: usize,
    wrap: WrapMode,
    k0: i64,
    k1: i64,
    raw: impl Fn(i64) -> f64,
) -> Vec<(usize, f64)> {
    let mut acc: Vec<(usize, f64)> = Vec::with_capacity((k1 - k0).max(0) as usize);
    // Taps that fold over an edge may meet a source texel twice: their weights add up
    // (in tap order); `slot[idx]` is where texel `idx` sits in `acc`.
    let inside = k0 >= 0 && k1 <= n as i64;
    let mut slot = if inside {
        Vec::new()
    } else {
        vec![usize::MAX; n]
    };
    for k in k0..k1 {
        let w = raw(k);
        if w == 0.0 {
            continue;
        }
        let idx = wrap_index(wrap, k, n);
        if inside {
            acc.push((idx, w));
        } else if slot[idx] == usize::MAX {
            slot[idx] = acc.len();
            acc.push((idx, w));
        } else {
            acc[slot[idx]].1 += w;
        }
    }
    let sum: f64 = acc.iter().map(|e| e.1).sum();
    if sum.abs() > 1e-12 {
        acc.iter_mut().for_each(|e| e.1 /= sum);
    }
    acc
}

/// `t` resampled to `w2 × h2` by `filter` (separable: rows, then columns; f64 accumulation).
///
/// Source rows of zeros (an atlas's transparent gutters) are skipped in both passes: every sum
/// starts at `+0` and so is never `−0`, and adding a product with a zero (`±0`) leaves it bitwise
/// unchanged. Cost: `O((n + m)·c)` per row of each pass, rows in parallel.
pub fn resample(t: &Texture, w2: usize, h2: usize, filter: Filter, wrap: [WrapMode; 2]) -> Texture {
    resample_skipping(t, &zero_rows(t), w2, h2, filter, wrap)
}

/// Which rows of `t` hold only zeros (`±0`): what [`resample_skipping`] skips. Cost: one pass,
/// rows in parallel.
pub fn zero_rows(t: &Texture) -> Vec<bool> {
    let row_len = (t.width * t.channels).max(1);
    t.data
        .par_chunks(row_len)
        .map(|r| !r.iter().fold(false, |any, &x| any | (x != 0.0)))
        .collect()
}

/// [`resample`] with the all-zero rows of `t` given (`zero_row[j]` for row `j`, as
/// [`zero_rows`] finds them), so that the levels resampled from one texture find them once.
/// The result is bitwise that of [`resample`] whenever `zero_row` is [`zero_rows`]`(t)`.
///
/// # Panics
/// If `zero_row` has fewer entries than `t` has rows.
pub fn resample_skipping(
    t: &Texture,
    zero_row: &[bool],
    w2: usize,
    h2: usize,
    filter: Filter,
    wrap: [WrapMode; 2],
) -> Texture {
    assert!(
        zero_row.len() >= t.height,
        "{} zero-row flags for {} rows",
        zero_row.len(),
        t.height
    );
    let c = t.channels;
    let wx = weights(filter, t.width, w2, wrap[0]);
    let wy = weights(filter, t.height, h2, wrap[1]);
    let mut tmp = vec![0.0f64; t.height * w2 * c];
    tmp.par_chunks_mut(w2 * c).enumerate().for_each(|(j, row)| {
        if zero_row[j] {
            return;
        }
        let src = &t.data[j * t.width * c..(j + 1) * t.width * c];
        match c {
            1 => row_taps::<1>(src, row, &wx),
            2 => row_taps::<2>(src, row, &wx),
            3 => row_taps::<3>(src, row, &wx),
            4 => row_taps::<4>(src, row, &wx),
            _ => {
                for (i, taps) in wx.iter().enumerate() {
                    let out = &mut row[i * c..(i + 1) * c];
                    for &(k, wk) in taps {
                        for (o, x) in out.iter_mut().zip(&src[k * c..(k + 1) * c]) {
                            *o += wk * f64::from(*x);
                        }
                    }
                }
            }
        }
    });
    let mut data = vec![0.0f32; h2 * w2 * c];
    data.par_chunks_mut(w2 * c)
        .enumerate()
        .for_each(|(j, row)| {
            let mut acc = vec![0.0f64; w2 * c];
            for &(k, wk) in wy[j].iter().filter(|&&(k, _)| !zero_row[k]) {
                for (a, x) in acc.iter_mut().zip(&tmp[k * w2 * c..(k + 1) * w2 * c]) {
                    *a += wk * x;
                }
            }
            // Negative lobes can overshoot: keep huge inputs finite.
            row.iter_mut()
                .zip(acc)
                .for_each(|(o, a)| *o = a.clamp(-f64::from(f32::MAX), f64::from(f32::MAX)) as f32);
        });
    Texture {
        width: w2,
        height: h2,
        channels: c,
        data,
    }
}

/// The row pass of [`resample`] for `C` channels: output texel `i` of `row` is the sum over
/// `wx[i]`'s taps, in tap order from `+0`, of `wk · src[k]` per channel (accumulated in registers,
/// the same sums as one channel at a time).
#[inline]
fn row_taps<const C: usize>(src: &[f32], row: &mut [f64], wx: &[Vec<(usize, f64)>]) {
    for (out, taps) in row.chunks_exact_mut(C).zip(wx) {
        let mut acc = [0.0f64; C];
        for &(k, wk) in taps {
            let x = &src[k * C..k * C + C];
            for ch in 0..C {
                acc[ch] += wk * f64::from(x[ch]);
            }
        }
        out.copy_from_slice(&acc);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The resampler as first written: every row and tap, one channel at a time.
    fn resample_reference(
        t: &Texture,
        w2: usize,
        h2: usize,
        f: Filter,
        wrap: [WrapMode; 2],
    ) -> Vec<f32> {
        let c = t.channels;
        let (wx, wy) = (
            weights(f, t.width, w2, wrap[0]),
            weights(f, t.height, h2, wrap[1]),
        );
        let mut tmp = vec![0.0f64; t.height * w2 * c];
        for j in 0..t.height {
            for (i, taps) in wx.iter().enumerate() {
                for &(k, wk) in taps {
                    for ch in 0..c {
                        tmp[(j * w2 + i) * c + ch] +=
                            wk * f64::from(t.data[(j * t.width + k) * c + ch]);
                    }
                }
            }
        }
        let mut out = vec![0.0f32; h2 * w2 * c];
        for (j, taps) in wy.iter().enumerate() {
            let mut acc = vec![0.0f64; w2 * c];
            for &(k, wk) in taps {
                for (a, x) in acc.iter_mut().zip(&tmp[k * w2 * c..(k + 1) * w2 * c]) {
                    *a += wk * x;
                }
            }
            for (o, a) in out[j * w2 * c..(j + 1) * w2 * c].iter_mut().zip(acc) {
                *o = a.clamp(-f64::from(f32::MAX), f64::from(f32::MAX)) as f32;
            }
        }
        out
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..proptest::prelude::ProptestConfig::default() })]
        /// Skipping rows of zeros and accumulating a texel's channels together give bitwise the
        /// reference's levels: any channel count, filter and wrap, rows and columns of zeros
        /// (signed), negative values.
        #[test]
        fn resample_is_bitwise_the_reference(
            w in 1usize..40, h in 1usize..40, c in 1usize..6,
            seed in proptest::prelude::any::<u64>(),
            zero_share in 0.0f64..0.9,
            f in 0usize..4, wrap in 0usize..3, wx in 1usize..40, hx in 1usize..40,
        ) {
            let mut rng = altrep_data_gen::SplitMix64::new(seed);
            let zero_rows: Vec<bool> = (0..h).map(|_| rng.next_f64() < zero_share).collect();
            let zero_cols: Vec<bool> = (0..w).map(|_| rng.next_f64() < zero_share).collect();
            let data = (0..w * h * c)
                .map(|n| {
                    let (i, j) = ((n / c) % w, n / (c * w));
                    if zero_rows[j] || zero_cols[i] {
                        if rng.next_f64() < 0.5 { 0.0 } else { -0.0 }
                    } else {
                        (rng.next_f64() * 2.0 - 0.5) as f32
                    }
                })
                .collect();
            let t = Texture::new(w, h, c, data).unwrap();
            let filter = [Filter::Box, Filter::Triangle, Filter::Kaiser, Filter::Lanczos][f];
            let wrap = [[WrapMode::Clamp; 2], [WrapMode::Repeat; 2], [WrapMode::Mirror, WrapMode::Clamp]][wrap];
            let (w2, h2) = (wx.min(w), hx.min(h));
            let flagged = super::zero_rows(&t);
            for (j, row) in t.data.chunks(w * c).enumerate() {
                proptest::prop_assert_eq!(flagged[j], row.iter().all(|&x| x == 0.0));
                proptest::prop_assert!(!zero_rows[j] || flagged[j]);
            }
            let got = resample(&t, w2, h2, filter, wrap);
            let want = resample_reference(&t, w2, h2, filter, wrap);
            proptest::prop_assert_eq!(
                got.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                want.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
    }

    #[test]
    fn kernels_integrate_to_one_over_their_support() {
        for f in [
            Filter::Box,
            Filter::Triangle,
            Filter::Kaiser,
            Filter::Lanczos,
        ] {
            let r = radius(f);
            // Brute force: midpoint rule with 200 000 cells.
            let n = 200_000;
            let brute: f64 = (0..n)
                .map(|i| kernel(f, -r + (i as f64 + 0.5) * 2.0 * r / n as f64) * 2.0 * r / n as f64)
                .sum();
            // The quadrature is meant for intervals of at most one kernel unit (one source texel
            // at a scale ≥ 1): sum over unit pieces.
            let closed: f64 = (-3..3)
                .map(|k| kernel_integral(f, f64::from(k), f64::from(k + 1)))
                .sum();
            approx::assert_relative_eq!(closed, brute, max_relative = 1e-6);
            if matches!(f, Filter::Box | Filter::Triangle) {
                approx::assert_relative_eq!(closed, 1.0, max_relative = 1e-12);
            }
        }
    }

    #[test]
    fn wrap_modes_fold_indices() {
        let n = 4;
        let fold = |w| (-5..9).map(|i| wrap_index(w, i, n)).collect::<Vec<_>>();
        assert_eq!(
            fold(WrapMode::Clamp),
            [0, 0, 0, 0, 0, 0, 1, 2, 3, 3, 3, 3, 3, 3]
        );
        assert_eq!(
            fold(WrapMode::Repeat),
            [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]
        );
        assert_eq!(
            fold(WrapMode::Mirror),
            [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]
        );
    }
}
