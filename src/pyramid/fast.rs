//! The fast path for 8-bit RGBA mip chains: the same levels as [`super::Pyramid::build`] (the
//! definition in [`super::filter`], colour and alpha handled as in [`super::levels`]), from and to
//! RGBA8, without going through an `f32` copy of level 0.
//!
//! ## How
//! * **Box on power-of-two sizes: a cascade.** Level `l + 1` is the mean of `2 × 2` texels of
//!   level `l` (in linear light, premultiplied, kept in `f32`; `2 × 1` or `1 × 2` once an axis
//!   is down to one texel). This is exact, not an approximation: for a side `n = 2^k` every box
//!   output texel of level `l` covers exactly the `2^l` source texels `[i·2^l, (i + 1)·2^l)` with
//!   equal weights (the definition's overlap areas, no partial texel, nothing folded by the wrap
//!   mode), and the mean of four means of `2^l × 2^l` blocks is the mean of the `2^(l+1)` block.
//!   Only `f32` rounding differs from the `f64` definition. Cost: about `4/3` texel reads per
//!   level-0 texel; level 0 is read once. Other sizes (a non-integer or odd ratio somewhere in
//!   the chain) take the general path below, where every level comes from level 0.
//! * **General path** (every filter): separable, horizontal then vertical, every level resampled
//!   from level 0 with the exact weights of [`super::filter::weights`] (kernel integrated over
//!   each source texel, wrap folded, normalised) converted to `f32`. For an integer ratio the
//!   kernel integrals are the same for every output texel (same offsets from its centre): they
//!   are computed once per level and axis, folded per output near the edges, and the interior
//!   outputs share one shifted pattern.
//!   - Horizontal: [`ROW_BLOCK`] source rows are decoded into a *transposed* block (texel `x`
//!     of all the block's rows side by side: `ROW_BLOCK × 4` floats per column), so each tap is
//!     one broadcast weight times `ROW_BLOCK × 4` contiguous floats, accumulated in registers
//!     (one load per multiply-add, no horizontal reduction). Every level is filtered from the
//!     same decoded block, so level 0 is decoded once. Blocks run in parallel (rayon).
//!   - Vertical: per output row, [`VCHUNK`] floats at a time held in registers while the taps
//!     (rows of the horizontal result, weight broadcast) stream through; all rows of all levels
//!     in one parallel loop.
//!   - With AVX2 and FMA present (checked at run time, `is_x86_feature_detected!`) both passes
//!     run as code compiled for them (fused multiply-adds on 8 lanes); otherwise the portable
//!     build of the same code.
//! * sRGB decoding is a 256-entry table (and alpha `v/255` another); encoding is a table of the
//!   255 decision thresholds `decode((v + ½)/255)` with a 4096-entry first guess, so the 8-bit
//!   result is exactly `round(255·encode(x))` of the `f32` value (tested against the encoder).
//!
//! ## Cost
//! General path, horizontal: `H·Σ_l w_l·t_l·4` multiply-adds with `t_l ≈ 2·radius·s_l + 2` taps
//! (about `H·W·4·2·radius` per level); vertical: `Σ_l w_l·h_l·t_l·4` (a factor `s_l` less).
//! Memory: the horizontal results, `H·Σ_l w_l·4` floats (about `4·W·H·4` bytes for a square
//! texture). Box cascade: `W·H` decodes, `(4/3)·W·H·4` adds, `W·H·4` bytes of `f32` for level 1.
//!
//! The output matches [`super::Pyramid::build`] of the same texels (`u8 / 255` as floats) to
//! within one 8-bit step (the `f64` and `f32` sums round differently); tested on sizes that are
//! not powers of two (every filter and wrap mode), on power-of-two sizes (the cascade), and with
//! and without the SIMD kernels.

use rayon::prelude::*;

use super::filter::{fold_weights, kernel_integral, output_weights, tap_range};
use super::mip::{AlphaMode, ColourSpace, Filter, MipError, PyramidParams, WrapMode};
use altrep_data_gen::{linear_to_srgb, srgb_to_linear};

/// Source rows decoded and filtered together by one task of the horizontal pass; the pass's
/// vector lanes are these rows × 4 channels.
pub const ROW_BLOCK: usize = 16;
/// Floats per column of a transposed block.
const LANES: usize = ROW_BLOCK * 4;
/// Floats of an output row accumulated in registers at once by the vertical pass.
pub const VCHUNK: usize = 64;

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

/// Choices of [`mip_chain_rgba8_with`] that change speed, not the definition (every choice stays
/// within one 8-bit step of it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FastOptions {
    /// Run the AVX2 + FMA kernels when the CPU has both (checked at run time); `false`: the
    /// portable build of the same code.
    pub simd: bool,
    /// Build box levels of power-of-two textures by halving the level above (exact, see the
    /// module docs); `false`: every level from level 0 like the other filters.
    pub box_cascade: bool,
}

impl Default for FastOptions {
    fn default() -> Self {
        Self {
            simd: true,
            box_cascade: true,
        }
    }
}

/// Whether this CPU runs the AVX2 + FMA kernels.
pub fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Taps of every output texel along one axis, flattened: output `i` has
/// `taps[bounds[i]..bounds[i + 1]]` as `(source index, weight)`.
struct AxisTaps {
    bounds: Vec<usize>,
    taps: Vec<(usize, f32)>,
}

impl AxisTaps {
    /// The resampling `n → m` of `filter` (the weights of [`super::filter::weights`] in `f32`).
    /// For an integer ratio `s = n/m` the offsets `k − c` of the taps from the output centre
    /// are the same for every output, so the kernel integrals are computed once per level and
    /// axis and only folded and normalised per output (bit for bit what [`output_weights`]
    /// gives); interior outputs (no tap folded over an edge) then repeat one pattern shifted by
    /// `s`.
    fn new(filter: Filter, n: usize, m: usize, wrap: WrapMode) -> Self {
        let mut bounds = Vec::with_capacity(m + 1);
        let mut taps = Vec::new();
        bounds.push(0);
        if m == n {
            for i in 0..n {
                taps.push((i, 1.0));
                bounds.push(taps.len());
            }
            return Self { bounds, taps };
        }
        let ratio = n.is_multiple_of(m).then_some(n / m);
        // Raw kernel integrals by tap offset from k0 (integer ratio only).
        let raw: Option<Vec<f64>> = ratio.map(|_| {
            let ks = (n as f64 / m as f64).max(1.0);
            let c = 0.5 * (n as f64 / m as f64);
            let (k0, k1) = tap_range(filter, n, m, 0);
            (k0..k1)
                .map(|k| kernel_integral(filter, (k as f64 - c) / ks, (k as f64 + 1.0 - c) / ks))
                .collect()
        });
        let mut pattern: Option<(usize, Vec<(usize, f32)>)> = None;
        for i in 0..m {
            let (k0, k1) = tap_range(filter, n, m, i);
            let inside = k0 >= 0 && k1 <= n as i64;
            match (ratio, inside, &pattern) {
                (Some(s), true, Some((i0, p))) => {
                    let shift = (i - i0) * s;
                    taps.extend(p.iter().map(|&(k, w)| (k + shift, w)));
                }
                _ => {
                    let w = match &raw {
                        Some(raw) => fold_weights(n, wrap, k0, k1, |k| raw[(k - k0) as usize]),
                        None => output_weights(filter, n, m, wrap, i),
                    };
                    let p: Vec<(usize, f32)> = w.into_iter().map(|(k, w)| (k, w as f32)).collect();
                    taps.extend_from_slice(&p);
                    if ratio.is_some() && inside && pattern.is_none() {
                        pattern = Some((i, p));
                    }
                }
            }
            bounds.push(taps.len());
        }
        Self { bounds, taps }
    }

    #[inline(always)]
    fn of(&self, i: usize) -> &[(usize, f32)] {
        &self.taps[self.bounds[i]..self.bounds[i + 1]]
    }

    fn len(&self) -> usize {
        self.bounds.len() - 1
    }
}

/// `w·x + acc`, fused when `F` (only instantiated where the CPU has FMA).
#[inline(always)]
fn madd<const F: bool>(w: f32, x: f32, acc: f32) -> f32 {
    if F { w.mul_add(x, acc) } else { w * x + acc }
}

/// Horizontal pass of one transposed block (`n` columns of [`LANES`] floats): output `i` of
/// `taps` for every row of the block into `out[i·LANES ..]`.
#[inline(always)]
fn hpass<const F: bool>(block: &[f32], taps: &AxisTaps, out: &mut [f32]) {
    for (i, o) in out.chunks_exact_mut(LANES).enumerate() {
        let mut acc = [0.0f32; LANES];
        for &(k, w) in taps.of(i) {
            let col: &[f32; LANES] = block[k * LANES..(k + 1) * LANES]
                .try_into()
                .expect("a column is LANES floats");
            for (a, x) in acc.iter_mut().zip(col) {
                *a = madd::<F>(w, *x, *a);
            }
        }
        o.copy_from_slice(&acc);
    }
}

/// Vertical pass of one output row: `out[x] = Σ_(k, w) w·tmp[k·stride + off + x]` for
/// `x < out.len()`, [`VCHUNK`] floats at a time in registers.
#[inline(always)]
fn vpass<const F: bool>(
    tmp: &[f32],
    stride: usize,
    off: usize,
    taps: &[(usize, f32)],
    out: &mut [f32],
) {
    let n = out.len();
    let full = n - n % VCHUNK;
    for (x0, o) in (0..full).step_by(VCHUNK).zip(out.chunks_exact_mut(VCHUNK)) {
        let mut acc = [0.0f32; VCHUNK];
        for &(k, w) in taps {
            let base = k * stride + off + x0;
            let src: &[f32; VCHUNK] = tmp[base..base + VCHUNK]
                .try_into()
                .expect("a chunk is VCHUNK floats");
            for (a, x) in acc.iter_mut().zip(src) {
                *a = madd::<F>(w, *x, *a);
            }
        }
        o.copy_from_slice(&acc);
    }
    let rest = &mut out[full..];
    rest.fill(0.0);
    for &(k, w) in taps {
        let base = k * stride + off;
        for (a, x) in rest.iter_mut().zip(&tmp[base + full..base + n]) {
            *a = madd::<F>(w, *x, *a);
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn hpass_avx2(block: &[f32], taps: &AxisTaps, out: &mut [f32]) {
    hpass::<true>(block, taps, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn vpass_avx2(tmp: &[f32], stride: usize, off: usize, taps: &[(usize, f32)], out: &mut [f32]) {
    vpass::<true>(tmp, stride, off, taps, out);
}

/// The kernels to run: portable, or AVX2 + FMA (only constructed after detecting both).
#[derive(Clone, Copy, Debug)]
enum Isa {
    Portable,
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
}

impl Isa {
    fn pick(simd: bool) -> Self {
        #[cfg(target_arch = "x86_64")]
        if simd && simd_available() {
            return Isa::Avx2Fma;
        }
        let _ = simd;
        Isa::Portable
    }

    fn hpass(self, block: &[f32], taps: &AxisTaps, out: &mut [f32]) {
        match self {
            Isa::Portable => hpass::<false>(block, taps, out),
            // SAFETY: `Avx2Fma` is only built after `simd_available()` saw AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma => unsafe { hpass_avx2(block, taps, out) },
        }
    }

    fn vpass(self, tmp: &[f32], stride: usize, off: usize, taps: &[(usize, f32)], out: &mut [f32]) {
        match self {
            Isa::Portable => vpass::<false>(tmp, stride, off, taps, out),
            // SAFETY: as in `hpass`.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma => unsafe { vpass_avx2(tmp, stride, off, taps, out) },
        }
    }
}

/// Decoding and encoding tables for one parameter set.
struct Codec {
    /// Byte → value of a colour channel in linear light (`v/255` when not sRGB).
    decode: [f32; 256],
    /// Byte → `v/255` (alpha), a table so the hot loop does not divide.
    unit: [f32; 256],
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
            unit: std::array::from_fn(|v| v as f32 / 255.0),
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

    /// One RGBA8 row into the working form (linear light, premultiplied when there is alpha):
    /// texel `x` goes to `out[x·step .. x·step + 4]` (`step` 4: packed; larger: interleaved
    /// with other rows, as the horizontal pass wants them).
    fn decode_row(&self, src: &[u8], out: &mut [f32], step: usize) {
        for (o, s) in out.chunks_mut(step).zip(src.chunks_exact(4)) {
            let a = self.unit[usize::from(s[3])];
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
/// for `params` (filter, wrap, colour space, alpha mode), with the default [`FastOptions`]
/// (SIMD when present, box cascade). Cost: see the module docs.
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
    mip_chain_rgba8_with(data, width, height, params, FastOptions::default())
}

/// [`mip_chain_rgba8`] with explicit [`FastOptions`] (to time or test one path against another).
pub fn mip_chain_rgba8_with(
    data: &[u8],
    width: usize,
    height: usize,
    params: &PyramidParams,
    options: FastOptions,
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
    let cascade = options.box_cascade
        && params.filter == Filter::Box
        && width.is_power_of_two()
        && height.is_power_of_two();
    if cascade {
        levels.extend(box_cascade(data, width, height, &sizes, &codec));
    } else {
        let isa = Isa::pick(options.simd);
        levels.extend(general(data, width, height, &sizes, params, &codec, isa));
    }
    Ok(levels)
}

/// `out` texel `i` = mean of texels `2i, 2i + 1` of rows `a` and `b` (when `b` is present and
/// when `pair_x`; one texel / one row otherwise). RGBA floats.
#[inline]
fn halve_row(a: &[f32], b: Option<&[f32]>, pair_x: bool, out: &mut [f32]) {
    match (b, pair_x) {
        (Some(b), true) => {
            for ((o, x), y) in out
                .chunks_exact_mut(4)
                .zip(a.chunks_exact(8))
                .zip(b.chunks_exact(8))
            {
                for c in 0..4 {
                    o[c] = 0.25 * ((x[c] + x[c + 4]) + (y[c] + y[c + 4]));
                }
            }
        }
        (Some(b), false) => {
            for ((o, x), y) in out.iter_mut().zip(a).zip(b) {
                *o = 0.5 * (x + y);
            }
        }
        (None, true) => {
            for (o, x) in out.chunks_exact_mut(4).zip(a.chunks_exact(8)) {
                for c in 0..4 {
                    o[c] = 0.5 * (x[c] + x[c + 4]);
                }
            }
        }
        (None, false) => out.copy_from_slice(&a[..out.len()]),
    }
}

/// Levels 1… of a box chain on power-of-two sides by halving (see the module docs). Each task
/// makes one output row: from two decoded level-0 rows for level 1, from two `f32` rows of the
/// level above after that; the row is kept in `f32` for the next level and encoded at once.
fn box_cascade(
    data: &[u8],
    width: usize,
    height: usize,
    sizes: &[(usize, usize)],
    codec: &Codec,
) -> Vec<Rgba8Level> {
    let mut out = Vec::with_capacity(sizes.len());
    // The level above in the working form (None: level 0, decoded on the fly).
    let mut above: Option<Vec<f32>> = None;
    let (mut pw, mut ph) = (width, height);
    for &(w, h) in sizes {
        let (pair_x, pair_y) = (pw > 1, ph > 1);
        let mut next = vec![0.0f32; w * h * 4];
        let mut bytes = vec![0u8; w * h * 4];
        let prev = above.as_deref();
        next.par_chunks_mut(w * 4)
            .zip(bytes.par_chunks_mut(w * 4))
            .enumerate()
            .for_each_init(
                || vec![0.0f32; 2 * pw * 4],
                |buf, (j, (row, orow))| {
                    let (ya, yb) = if pair_y { (2 * j, 2 * j + 1) } else { (j, j) };
                    let n = pw * 4;
                    let (a, b): (&[f32], Option<&[f32]>) = match prev {
                        Some(p) => (
                            &p[ya * n..(ya + 1) * n],
                            pair_y.then(|| &p[yb * n..(yb + 1) * n]),
                        ),
                        None => {
                            let (ba, bb) = buf.split_at_mut(n);
                            codec.decode_row(&data[ya * n..(ya + 1) * n], ba, 4);
                            if pair_y {
                                codec.decode_row(&data[yb * n..(yb + 1) * n], bb, 4);
                            }
                            (&buf[..n], pair_y.then(|| &buf[n..2 * n]))
                        }
                    };
                    halve_row(a, b, pair_x, row);
                    codec.encode_row(row, orow);
                },
            );
        out.push(Rgba8Level {
            width: w,
            height: h,
            data: bytes,
        });
        above = Some(next);
        (pw, ph) = (w, h);
    }
    out
}

/// Levels 1… by the general separable path (see the module docs).
fn general(
    data: &[u8],
    width: usize,
    height: usize,
    sizes: &[(usize, usize)],
    params: &PyramidParams,
    codec: &Codec,
    isa: Isa,
) -> Vec<Rgba8Level> {
    let hx: Vec<AxisTaps> = sizes
        .par_iter()
        .map(|&(w2, _)| AxisTaps::new(params.filter, width, w2, params.wrap[0]))
        .collect();
    let wy: Vec<AxisTaps> = sizes
        .par_iter()
        .map(|&(_, h2)| AxisTaps::new(params.filter, height, h2, params.wrap[1]))
        .collect();
    // Offsets of each level's columns in a horizontal-result row.
    let mut offsets = Vec::with_capacity(sizes.len());
    let mut stride = 0;
    for &(w2, _) in sizes {
        offsets.push(stride);
        stride += w2 * 4;
    }
    let widest = sizes.iter().map(|s| s.0).max().unwrap_or(1);
    // Horizontal pass: every level from each decoded, transposed block of rows.
    let mut tmp = vec![0.0f32; height * stride];
    let row_bytes = width * 4;
    tmp.par_chunks_mut(ROW_BLOCK * stride)
        .zip(data.par_chunks(ROW_BLOCK * row_bytes))
        .for_each_init(
            || (vec![0.0f32; width * LANES], vec![0.0f32; widest * LANES]),
            |(block, hout), (dst, src)| {
                let rows = src.len() / row_bytes;
                for r in 0..rows {
                    codec.decode_row(
                        &src[r * row_bytes..(r + 1) * row_bytes],
                        &mut block[r * 4..],
                        LANES,
                    );
                }
                for (l, taps) in hx.iter().enumerate() {
                    let m = taps.len();
                    let hout = &mut hout[..m * LANES];
                    isa.hpass(block, taps, hout);
                    let off = offsets[l];
                    for r in 0..rows {
                        let drow = &mut dst[r * stride + off..r * stride + off + m * 4];
                        for (d, col) in drow.chunks_exact_mut(4).zip(hout.chunks_exact(LANES)) {
                            d.copy_from_slice(&col[r * 4..r * 4 + 4]);
                        }
                    }
                }
            },
        );
    // Vertical pass: every row of every level in one parallel loop.
    let mut bytes: Vec<Vec<u8>> = sizes.iter().map(|&(w, h)| vec![0u8; w * h * 4]).collect();
    let mut jobs: Vec<(usize, usize, &mut [u8])> = Vec::new();
    for (l, b) in bytes.iter_mut().enumerate() {
        let n = sizes[l].0 * 4;
        jobs.extend(b.chunks_mut(n).enumerate().map(|(j, row)| (l, j, row)));
    }
    jobs.into_par_iter().for_each_init(
        || vec![0.0f32; widest * 4],
        |acc, (l, j, orow)| {
            let acc = &mut acc[..orow.len()];
            isa.vpass(&tmp, stride, offsets[l], wy[l].of(j), acc);
            codec.encode_row(acc, orow);
        },
    );
    sizes
        .iter()
        .zip(bytes)
        .map(|(&(width, height), data)| Rgba8Level {
            width,
            height,
            data,
        })
        .collect()
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

    /// The configurations every path is tested under: colour space, alpha mode, horizontal wrap.
    const CONFIGS: [(ColourSpace, AlphaMode, WrapMode); 4] = [
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
    ];

    /// Largest difference in 8-bit steps between the fast chain of `(w, h)` and the exact
    /// definition ([`Pyramid::build`] in f64 on the same texels), over every level.
    fn worst_step(
        w: usize,
        h: usize,
        seed: usize,
        filter: Filter,
        (colour, alpha, wrap): (ColourSpace, AlphaMode, WrapMode),
        options: FastOptions,
    ) -> i32 {
        let mut src = bytes(w, h, seed);
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
        let fast = mip_chain_rgba8_with(&src, w, h, &p, options).unwrap();
        let tex =
            Texture::new(w, h, 4, src.iter().map(|&b| f32::from(b) / 255.0).collect()).unwrap();
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
        worst
    }

    const ALL_OPTIONS: [FastOptions; 4] = [
        FastOptions {
            simd: true,
            box_cascade: true,
        },
        FastOptions {
            simd: false,
            box_cascade: true,
        },
        FastOptions {
            simd: true,
            box_cascade: false,
        },
        FastOptions {
            simd: false,
            box_cascade: false,
        },
    ];

    /// Every level against the exact definition on a size that is not a power of two (the
    /// general path, SIMD kernels and portable ones): at most one 8-bit step apart. 37 columns
    /// also leave a remainder after the vertical pass's register chunks.
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
            for (j, config) in CONFIGS.into_iter().enumerate() {
                for options in &ALL_OPTIONS[..2] {
                    let worst = worst_step(w, h, i * 4 + j, filter, config, *options);
                    assert!(worst <= 1, "{filter:?} {config:?} {options:?}: {worst}");
                }
            }
        }
    }

    /// Power-of-two sides (square, wide, one texel high, one texel wide): the box cascade and
    /// the general path for box, and the general path for Kaiser with its shared interior
    /// weight pattern, each within one 8-bit step of the exact definition on every level.
    #[test]
    fn power_of_two_sizes_and_the_box_cascade_match_the_definition() {
        for (k, &(w, h)) in [(64, 64), (128, 16), (32, 1), (1, 16)].iter().enumerate() {
            for (j, config) in CONFIGS.into_iter().enumerate() {
                for options in ALL_OPTIONS {
                    let worst = worst_step(w, h, k * 4 + j, Filter::Box, config, options);
                    assert!(worst <= 1, "box {w}×{h} {config:?} {options:?}: {worst}");
                }
                let worst = worst_step(w, h, k, Filter::Kaiser, config, FastOptions::default());
                assert!(worst <= 1, "kaiser {w}×{h} {config:?}: {worst}");
            }
        }
    }

    /// The shared interior pattern gives the same weights as the definition computed output by
    /// output.
    #[test]
    fn interior_weight_pattern_equals_per_output_weights() {
        for filter in [Filter::Box, Filter::Kaiser, Filter::Triangle] {
            for (n, m) in [(256, 32), (96, 24), (37, 18)] {
                let t = AxisTaps::new(filter, n, m, WrapMode::Mirror);
                let exact = crate::pyramid::filter::weights(filter, n, m, WrapMode::Mirror);
                for (i, e) in exact.iter().enumerate() {
                    let got = t.of(i);
                    assert_eq!(got.len(), e.len(), "{filter:?} {n}→{m} #{i}");
                    for (g, x) in got.iter().zip(e) {
                        assert_eq!(g.0, x.0);
                        assert_eq!(g.1, x.1 as f32, "{filter:?} {n}→{m} #{i}");
                    }
                }
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
