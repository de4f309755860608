//! What happens around the resampler when a level is built: decoding sRGB to linear light and
//! premultiplying alpha before filtering; alpha-coverage preservation, normal renormalisation,
//! un-premultiplying and re-encoding after it.
//!
//! Every level is `finish(resample(prepare(level 0)))`: level 0 is prepared once, every coarser
//! level is resampled from it directly (see [`super::mip`] for why not from the level above).
//!
//! Alpha coverage (NVIDIA Texture Tools' `alphaTestCoverage` / `scaleAlphaToCoverage`): the
//! coverage of a level at reference `r` and scale `σ` is the fraction of `4 × 4` bilinear samples
//! per texel cell (cells between texel centres, neighbours by the wrap mode) with
//! `min(1, σ·α) > r`; the scale that brings a level's coverage to level 0's is found by bisection
//! on `σ ∈ [0, 8]` (coverage is non-decreasing in `σ`), 30 halvings.

use rayon::prelude::*;

use super::filter::{resample_skipping, wrap_index};
use super::mip::{AlphaMode, ColourSpace, PyramidParams, Texture, WrapMode};
use altrep_data_gen::{linear_to_srgb, srgb_to_linear};

/// Index of the alpha channel, if the parameters say there is one.
pub fn alpha_channel(p: &PyramidParams, channels: usize) -> Option<usize> {
    (p.alpha != AlphaMode::None).then(|| channels - 1)
}

/// Number of colour channels subject to sRGB decoding: the first three, not counting alpha.
fn colour_channels(p: &PyramidParams, channels: usize) -> usize {
    let non_alpha = channels - usize::from(p.alpha != AlphaMode::None);
    non_alpha.min(3)
}

/// Level 0 turned into the working form: linear light, premultiplied alpha.
pub fn prepare(t: &Texture, p: &PyramidParams) -> Texture {
    let c = t.channels;
    let ai = alpha_channel(p, c);
    let nc = colour_channels(p, c);
    let mut out = t.clone();
    out.data.par_chunks_mut(c).for_each(|texel| {
        let a = ai.map(|i| texel[i].clamp(0.0, 1.0));
        if let Some(i) = ai {
            texel[i] = a.unwrap_or(1.0);
        }
        for x in texel.iter_mut().take(nc) {
            let mut straight = match (p.alpha, a) {
                (AlphaMode::Premultiplied, Some(a)) if a > 0.0 => *x / a,
                (AlphaMode::Premultiplied, _) => 0.0,
                _ => *x,
            };
            if p.colour == ColourSpace::Srgb {
                straight = srgb_to_linear(straight.clamp(0.0, 1.0));
            }
            *x = straight * a.unwrap_or(1.0);
        }
    });
    out
}

/// A working-form level turned back into the stored form; `coverage` is `(reference, level-0
/// coverage)` when coverage is to be preserved.
pub fn finish(mut t: Texture, p: &PyramidParams, coverage: Option<(f32, f64)>) -> Texture {
    let c = t.channels;
    let ai = alpha_channel(p, c);
    let nc = colour_channels(p, c);
    let scale = match (ai, coverage) {
        (Some(i), Some((r, target))) => {
            // The working alpha may overshoot [0, 1] after a sinc-like filter: clamp first.
            t.data
                .par_chunks_mut(c)
                .for_each(|x| x[i] = x[i].clamp(0.0, 1.0));
            coverage_scale(&t, i, r, target, p.wrap)
        }
        _ => 1.0,
    };
    t.data.par_chunks_mut(c).for_each(|texel| {
        let a0 = ai.map(|i| texel[i].clamp(0.0, 1.0));
        let a = a0.map(|a| (a * scale).min(1.0));
        if p.normal_map {
            let n = &mut texel[0..3];
            let len = n.iter().map(|x| x * x).sum::<f32>().sqrt();
            if len > 1e-12 {
                n.iter_mut().for_each(|x| *x /= len);
            } else {
                n.copy_from_slice(&[0.0, 0.0, 1.0]);
            }
        }
        for x in texel.iter_mut().take(nc) {
            let mut straight = match a0 {
                Some(a0) if a0 > 1e-12 => *x / a0,
                Some(_) => 0.0,
                None => *x,
            };
            if p.colour == ColourSpace::Srgb {
                straight = linear_to_srgb(straight.clamp(0.0, 1.0));
            }
            *x = match (p.alpha, a) {
                (AlphaMode::Premultiplied, Some(a)) => straight * a,
                _ => straight,
            };
        }
        if let (Some(i), Some(a)) = (ai, a) {
            texel[i] = a;
        }
    });
    t
}

/// Fraction of the texture's area where the bilinearly interpolated `min(1, scale·α) > r`,
/// measured with `4 × 4` samples per cell between texel centres (see the module docs).
pub fn alpha_coverage(t: &Texture, ai: usize, r: f32, scale: f32, wrap: [WrapMode; 2]) -> f64 {
    const N: usize = 4;
    let (w, h, c) = (t.width, t.height, t.channels);
    let a = |i: usize, j: usize| (t.data[(j * w + i) * c + ai] * scale).clamp(0.0, 1.0);
    let hits: usize = (0..h)
        .into_par_iter()
        .map(|y| {
            let y1 = wrap_index(wrap[1], y as i64 + 1, h);
            let mut n = 0;
            for x in 0..w {
                let x1 = wrap_index(wrap[0], x as i64 + 1, w);
                let (a00, a10, a01, a11) = (a(x, y), a(x1, y), a(x, y1), a(x1, y1));
                for sy in 0..N {
                    let fy = (sy as f32 + 0.5) / N as f32;
                    for sx in 0..N {
                        let fx = (sx as f32 + 0.5) / N as f32;
                        let v = a00 * (1.0 - fx) * (1.0 - fy)
                            + a10 * fx * (1.0 - fy)
                            + a01 * (1.0 - fx) * fy
                            + a11 * fx * fy;
                        n += usize::from(v > r);
                    }
                }
            }
            n
        })
        .sum();
    hits as f64 / (w * h * N * N) as f64
}

/// The alpha scale that brings the coverage of `t` closest to `target` (bisection).
fn coverage_scale(t: &Texture, ai: usize, r: f32, target: f64, wrap: [WrapMode; 2]) -> f32 {
    let (mut lo, mut hi) = (0.0f32, 8.0f32);
    let mut best = (f64::INFINITY, 1.0f32);
    let mut s = 1.0f32;
    for _ in 0..30 {
        let cov = alpha_coverage(t, ai, r, s, wrap);
        let err = (cov - target).abs();
        if err < best.0 {
            best = (err, s);
        }
        if cov < target {
            lo = s;
        } else if cov > target {
            hi = s;
        } else {
            break;
        }
        s = 0.5 * (lo + hi);
    }
    best.1
}

/// One level of size `w2 × h2` from the prepared level 0 (see the module docs), whose all-zero
/// rows are `zero_rows` ([`super::filter::zero_rows`]`(work0)`, found once for all its levels).
pub fn build_level(
    work0: &Texture,
    zero_rows: &[bool],
    w2: usize,
    h2: usize,
    p: &PyramidParams,
    coverage: Option<(f32, f64)>,
) -> Texture {
    let level = resample_skipping(work0, zero_rows, w2, h2, p.filter, p.wrap);
    finish(level, p, coverage)
}

/// `(reference, coverage of level 0)` when the parameters ask to preserve coverage.
pub fn coverage_target(base: &Texture, p: &PyramidParams) -> Option<(f32, f64)> {
    let ai = alpha_channel(p, base.channels)?;
    let r = p.coverage_reference?;
    Some((r, alpha_coverage(base, ai, r, 1.0, p.wrap)))
}
