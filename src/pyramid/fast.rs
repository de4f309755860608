//! The fast path for 8-bit RGBA mip chains: the same levels as [`super::Pyramid::build`] (the
//! definition in [`super::filter`], colour and alpha handled as in [`super::levels`]), from and to
//! RGBA8, without going through an `f32` copy of level 0.
//!
//! ## How
//! * Resampling weights are the exact ones of [`super::filter::weights`] (kernel integrated over
//!   each source texel, wrap folded, normalised), converted to `f32` once per level and axis.
//!   A run of consecutive source texels (every output texel away from the edges) is stored as a
//!   start index and a weight table expanded to the four channels, so the inner loop is a plain
//!   dot product of two contiguous `f32` slices with four independent accumulators
//!   (vectorisable); outputs whose taps fold over an edge keep `(index, weight)` pairs.
//! * sRGB decoding is a 256-entry table; encoding is a table of the 255 decision thresholds
//!   `decode((v + ½)/255)` with a 4096-entry first guess, so the 8-bit result is exactly
//!   `round(255·encode(x))` of the `f32` value.
//! * Source rows are decoded (linear light, premultiplied) in blocks of [`ROW_BLOCK`] rows; each
//!   block is filtered horizontally for every level at once, so level 0 is read once whatever the
//!   number of levels. The vertical pass then runs per level over the horizontal results, output
//!   rows in parallel, and un-premultiplies and encodes each output row.
//!
//! ## Cost
//! Horizontal: `H·Σ_l w_l·t_l·4` multiply-adds with `t_l ≈ 2·radius·s_l + 2` taps (about
//! `H·W·4·2·radius` per level); vertical: `Σ_l w_l·h_l·t_l·4` (a factor `s_l` less). Memory: the
//! horizontal results, `H·Σ_l w_l·4` floats (about `4·W·H·4` bytes for a square texture).
//!
//! The output matches [`super::Pyramid::build`] of the same texels (`u8 / 255` as floats) to
//! within one 8-bit step (the `f64` and `f32` sums round differently); tested on sizes that are
//! not powers of two, every filter and wrap mode.

use rayon::prelude::*;

use super::filter::weights;
use super::mip::{AlphaMode, ColourSpace, MipError, PyramidParams, WrapMode};
use altrep_data_gen::{linear_to_srgb, srgb_to_linear};

/// Rows decoded and filtered together by one task of the horizontal pass.
pub const ROW_BLOCK: usize = 16;

/// One 8-bit RGBA level, row-major, 4 bytes per texel (colour encoded and alpha handled as the
/// [`PyramidParams`] that built it say).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rgba8Level {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height × 4` bytes.
    pub data: Vec<u8>,
}

/// The taps of one output texel along one axis.
enum Taps {
    /// Consecutive source texels from `start`; `w4` holds each weight four times (per channel).
    Run { start: usize, w4: Vec<f32> },
    /// Taps folded over an edge: `(source index, weight)`.
    Gather(Vec<(usize, f32)>),
}

fn taps_of(filter: super::Filter, n: usize, m: usize, wrap: WrapMode) -> Vec<Taps> {
    weights(filter, n, m, wrap)
        .into_iter()
        .map(|pairs| {
            let start = pairs.first().map_or(0, |p| p.0);
            let run = pairs.iter().enumerate().all(|(i, p)| p.0 == start + i);
            if run {
                let w4 = pairs
                    .iter()
                    .flat_map(|p| [p.1 as f32; 4])
                    .collect::<Vec<_>>();
                Taps::Run { start, w4 }
            } else {
                Taps::Gather(pairs.iter().map(|p| (p.0, p.1 as f32)).collect())
            }
        })
        .collect()
}

/// `Σ a_i·b_i` per channel over two equal-length slices of RGBA floats (four taps at a time in
/// independent accumulators).
#[inline]
fn dot4(a: &[f32], b: &[f32]) -> [f32; 4] {
    let mut acc = [0.0f32; 16];
    let (ca, cb) = (a.chunks_exact(16), b.chunks_exact(16));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for ((a, xv), yv) in acc.iter_mut().zip(x).zip(y) {
            *a += xv * yv;
        }
    }
    let mut out = [0.0f32; 4];
    for (k, (x, y)) in ra.iter().zip(rb).enumerate() {
        out[k % 4] += x * y;
    }
    for c in 0..4 {
        out[c] += (acc[c] + acc[c + 4]) + (acc[c + 8] + acc[c + 12]);
    }
    out
}

/// Horizontal resampling of one working row (RGBA floats) into `out` (`taps.len() × 4`).
fn filter_row(row: &[f32], taps: &[Taps], out: &mut [f32]) {
    for (o, t) in out.chunks_exact_mut(4).zip(taps) {
        let v = match t {
            Taps::Run { start, w4 } => dot4(&row[start * 4..start * 4 + w4.len()], w4),
            Taps::Gather(pairs) => {
                let mut acc = [0.0f32; 4];
                for &(k, w) in pairs {
                    for c in 0..4 {
                        acc[c] += w * row[k * 4 + c];
                    }
                }
                acc
            }
        };
        o.copy_from_slice(&v);
    }
}

/// Decoding and encoding tables for one parameter set.
struct Codec {
    /// Byte → value of a colour channel in linear light (`v/255` when not sRGB).
    decode: [f32; 256],
    /// `thresholds[v]`: the smallest linear value that encodes to `v + 1` (sRGB), or
    /// `(v + ½)/255` (linear).
    thresholds: [f32; 255],
    /// First guess of the code for `x`: the code of `⌊x·4095⌋/4095`.
    guess: Vec<u8>,
    srgb: bool,
    alpha: AlphaMode,
}

const GUESS_STEPS: usize = 4096;

impl Codec {
    fn new(p: &PyramidParams) -> Self {
        let srgb = p.colour == ColourSpace::Srgb;
        let dec = |x: f32| if srgb { srgb_to_linear(x) } else { x };
        let decode = std::array::from_fn(|v| dec(v as f32 / 255.0));
        // The code of x is round(255·encode(x)): it exceeds v where encode(x) ≥ (v + ½)/255.
        // Found by bisection on the f32 encoder itself so the table agrees with it exactly.
        let enc = |x: f32| {
            let e = if srgb { linear_to_srgb(x) } else { x };
            (e.clamp(0.0, 1.0) * 255.0).round() as u8
        };
        let thresholds = std::array::from_fn(|v| {
            // Smallest f32 x ≥ 0 with enc(x) > v: bisection on the bit patterns (monotone for
            // non-negative floats).
            let (mut lb, mut hb) = (0.0f32.to_bits(), 1.0f32.to_bits());
            while hb - lb > 1 {
                let mb = lb + (hb - lb) / 2;
                if enc(f32::from_bits(mb)) > v as u8 {
                    hb = mb;
                } else {
                    lb = mb;
                }
            }
            f32::from_bits(hb)
        });
        let guess = (0..GUESS_STEPS)
            .map(|i| {
                let x = i as f32 / (GUESS_STEPS - 1) as f32;
                thresholds.iter().filter(|&&t| t <= x).count() as u8
            })
            .collect();
        Self {
            decode,
            thresholds,
            guess,
            srgb,
            alpha: p.alpha,
        }
    }

    /// `round(255·encode(clamp(x, 0, 1)))`.
    #[inline]
    fn encode(&self, x: f32) -> u8 {
        let x = x.clamp(0.0, 1.0);
        let mut v = self.guess[(x * (GUESS_STEPS - 1) as f32) as usize];
        while v < 255 && x >= self.thresholds[v as usize] {
            v += 1;
        }
        v
    }

    /// One RGBA8 row into the working form (linear light, premultiplied when there is alpha).
    fn decode_row(&self, src: &[u8], out: &mut [f32]) {
        for (o, s) in out.chunks_exact_mut(4).zip(src.chunks_exact(4)) {
            let a = f32::from(s[3]) / 255.0;
            match self.alpha {
                AlphaMode::None => {
                    for (oc, sc) in o.iter_mut().zip(s).take(3) {
                        *oc = self.decode[usize::from(*sc)];
                    }
                    o[3] = a;
                }
                AlphaMode::Straight => {
                    for (oc, sc) in o.iter_mut().zip(s).take(3) {
                        *oc = self.decode[usize::from(*sc)] * a;
                    }
                    o[3] = a;
                }
                AlphaMode::Premultiplied => {
                    for (oc, sc) in o.iter_mut().zip(s).take(3) {
                        let straight = if a > 0.0 {
                            f32::from(*sc) / 255.0 / a
                        } else {
                            0.0
                        };
                        let lin = if self.srgb {
                            srgb_to_linear(straight.clamp(0.0, 1.0))
                        } else {
                            straight
                        };
                        *oc = lin * a;
                    }
                    o[3] = a;
                }
            }
        }
    }

    /// One working row back to RGBA8 (un-premultiplied, encoded; premultiplied again when the
    /// stored form is premultiplied).
    fn encode_row(&self, src: &[f32], out: &mut [u8]) {
        for (o, s) in out.chunks_exact_mut(4).zip(src.chunks_exact(4)) {
            let a0 = s[3].clamp(0.0, 1.0);
            match self.alpha {
                AlphaMode::None => {
                    for (oc, sc) in o.iter_mut().zip(s).take(3) {
                        *oc = self.encode(*sc);
                    }
                }
                AlphaMode::Straight => {
                    for (oc, sc) in o.iter_mut().zip(s).take(3) {
                        *oc = if a0 > 1e-12 { self.encode(sc / a0) } else { 0 };
                    }
                }
                AlphaMode::Premultiplied => {
                    for (oc, sc) in o.iter_mut().zip(s).take(3) {
                        let straight = if a0 > 1e-12 { sc / a0 } else { 0.0 };
                        let e = if self.srgb {
                            linear_to_srgb(straight.clamp(0.0, 1.0))
                        } else {
                            straight
                        };
                        *oc = ((e * a0).clamp(0.0, 1.0) * 255.0).round() as u8;
                    }
                }
            }
            o[3] = (a0 * 255.0).round() as u8;
        }
    }
}

/// The mip chain of an RGBA8 image (`width × height × 4` bytes, row-major): level 0 (a copy of
/// the input) and every coarser level down to `1 × 1`, as [`super::Pyramid::build`] defines them
/// for `params` (filter, wrap, colour space, alpha mode). Cost: see the module docs.
///
/// Errors: a zero size, a buffer of the wrong length, or parameters this path does not handle
/// (alpha coverage preservation, normal maps: use [`super::Pyramid::build`]), or invalid
/// parameters ([`PyramidParams::validate`]).
pub fn mip_chain_rgba8(
    data: &[u8],
    width: usize,
    height: usize,
    params: &PyramidParams,
) -> Result<Vec<Rgba8Level>, MipError> {
    if width == 0 {
        return Err(MipError::ZeroSize { what: "width" });
    }
    if height == 0 {
        return Err(MipError::ZeroSize { what: "height" });
    }
    let expected = width * height * 4;
    if data.len() != expected {
        return Err(MipError::DataSize {
            got: data.len(),
            expected,
        });
    }
    params.validate(4)?;
    if params.coverage_reference.is_some() {
        return Err(MipError::Unsupported(
            "alpha coverage preservation on the RGBA8 fast path (use Pyramid::build)",
        ));
    }
    if params.normal_map {
        return Err(MipError::Unsupported(
            "normal maps on the RGBA8 fast path (use Pyramid::build)",
        ));
    }
    let codec = Codec::new(params);
    let mut sizes = Vec::new();
    let (mut w, mut h) = (width, height);
    while w > 1 || h > 1 {
        (w, h) = ((w / 2).max(1), (h / 2).max(1));
        sizes.push((w, h));
    }
    let mut levels = vec![Rgba8Level {
        width,
        height,
        data: data.to_vec(),
    }];
    if sizes.is_empty() {
        return Ok(levels);
    }
    let hx: Vec<Vec<Taps>> = sizes
        .par_iter()
        .map(|&(w2, _)| taps_of(params.filter, width, w2, params.wrap[0]))
        .collect();
    // Offsets of each level's columns in a horizontal-result row.
    let mut offsets = Vec::with_capacity(sizes.len());
    let mut stride = 0;
    for &(w2, _) in &sizes {
        offsets.push(stride);
        stride += w2 * 4;
    }
    // Horizontal pass: every level from each decoded block of rows.
    let mut tmp = vec![0.0f32; height * stride];
    let row_bytes = width * 4;
    tmp.par_chunks_mut(ROW_BLOCK * stride)
        .zip(data.par_chunks(ROW_BLOCK * row_bytes))
        .for_each_init(
            || vec![0.0f32; ROW_BLOCK * width * 4],
            |work, (dst, src)| {
                let rows = src.len() / row_bytes;
                for r in 0..rows {
                    codec.decode_row(
                        &src[r * row_bytes..(r + 1) * row_bytes],
                        &mut work[r * width * 4..(r + 1) * width * 4],
                    );
                }
                for (l, taps) in hx.iter().enumerate() {
                    let (off, n) = (offsets[l], sizes[l].0 * 4);
                    for r in 0..rows {
                        filter_row(
                            &work[r * width * 4..(r + 1) * width * 4],
                            taps,
                            &mut dst[r * stride + off..r * stride + off + n],
                        );
                    }
                }
            },
        );
    // Vertical pass per level, output rows in parallel.
    for (l, &(w2, h2)) in sizes.iter().enumerate() {
        let wy = weights(params.filter, height, h2, params.wrap[1]);
        let (off, n) = (offsets[l], w2 * 4);
        let mut out = vec![0u8; h2 * n];
        out.par_chunks_mut(n).zip(wy.par_iter()).for_each_init(
            || vec![0.0f32; n],
            |acc, (orow, taps)| {
                acc.fill(0.0);
                for &(k, w) in taps {
                    let w = w as f32;
                    let src = &tmp[k * stride + off..k * stride + off + n];
                    for (a, x) in acc.iter_mut().zip(src) {
                        *a += w * x;
                    }
                }
                codec.encode_row(acc, orow);
            },
        );
        levels.push(Rgba8Level {
            width: w2,
            height: h2,
            data: out,
        });
    }
    Ok(levels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pyramid::{Filter, Pyramid, Texture};

    fn bytes(w: usize, h: usize, seed: usize) -> Vec<u8> {
        (0..w * h * 4)
            .map(|k| ((k * 7919 + seed * 104_729) % 251) as u8)
            .collect()
    }

    #[test]
    fn encoder_table_matches_the_encoder() {
        for colour in [ColourSpace::Srgb, ColourSpace::Linear] {
            let c = Codec::new(&PyramidParams {
                colour,
                ..Default::default()
            });
            for i in 0..=200_000 {
                let x = i as f32 / 200_000.0;
                let e = if colour == ColourSpace::Srgb {
                    linear_to_srgb(x)
                } else {
                    x
                };
                assert_eq!(
                    c.encode(x),
                    (e.clamp(0.0, 1.0) * 255.0).round() as u8,
                    "{x}"
                );
            }
            assert_eq!(c.encode(-1.0), 0);
            assert_eq!(c.encode(2.0), 255);
        }
    }

    /// Every level against the exact definition ([`Pyramid::build`] in f64 on the same texels):
    /// at most one 8-bit step apart.
    #[test]
    fn matches_the_exact_definition_within_one_step() {
        let (w, h) = (37, 23);
        for (i, filter) in [
            Filter::Box,
            Filter::Triangle,
            Filter::Kaiser,
            Filter::Lanczos,
        ]
        .into_iter()
        .enumerate()
        {
            for (j, (colour, alpha, wrap)) in [
                (ColourSpace::Srgb, AlphaMode::Straight, WrapMode::Clamp),
                (ColourSpace::Srgb, AlphaMode::None, WrapMode::Repeat),
                (
                    ColourSpace::Linear,
                    AlphaMode::Premultiplied,
                    WrapMode::Mirror,
                ),
                (
                    ColourSpace::Srgb,
                    AlphaMode::Premultiplied,
                    WrapMode::Repeat,
                ),
            ]
            .into_iter()
            .enumerate()
            {
                let mut src = bytes(w, h, i * 4 + j);
                if alpha == AlphaMode::Premultiplied {
                    // Premultiplied input: colour ≤ alpha.
                    src.chunks_exact_mut(4).for_each(|t| {
                        let a = t[3];
                        t.iter_mut().take(3).for_each(|x| *x = (*x).min(a));
                    });
                }
                let p = PyramidParams {
                    filter,
                    colour,
                    alpha,
                    wrap: [wrap, WrapMode::Clamp],
                    ..Default::default()
                };
                let fast = mip_chain_rgba8(&src, w, h, &p).unwrap();
                let tex =
                    Texture::new(w, h, 4, src.iter().map(|&b| f32::from(b) / 255.0).collect())
                        .unwrap();
                let exact = Pyramid::build(tex, p).unwrap();
                assert_eq!(fast.len(), exact.levels().len());
                assert_eq!(fast[0].data, src);
                let mut worst = 0i32;
                for (a, b) in fast.iter().zip(exact.levels()) {
                    assert_eq!((a.width, a.height), (b.width, b.height));
                    for (x, y) in a.data.iter().zip(b.to_u8()) {
                        worst = worst.max((i32::from(*x) - i32::from(y)).abs());
                    }
                }
                assert!(
                    worst <= 1,
                    "{filter:?} {colour:?} {alpha:?} {wrap:?}: {worst}"
                );
            }
        }
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let p = PyramidParams::default();
        assert!(matches!(
            mip_chain_rgba8(&[0; 12], 2, 2, &p),
            Err(MipError::DataSize { .. })
        ));
        assert!(matches!(
            mip_chain_rgba8(&[], 0, 2, &p),
            Err(MipError::ZeroSize { .. })
        ));
        let cov = PyramidParams {
            alpha: AlphaMode::Straight,
            coverage_reference: Some(0.5),
            ..Default::default()
        };
        assert!(matches!(
            mip_chain_rgba8(&[0; 16], 2, 2, &cov),
            Err(MipError::Unsupported(_))
        ));
        // A 1 × 1 image is its own chain.
        assert_eq!(mip_chain_rgba8(&[1, 2, 3, 4], 1, 1, &p).unwrap().len(), 1);
    }
}
