//! Mip pyramids (Williams 1983) with level selection from texture-coordinate derivatives
//! (Heckbert), the one pyramid every representation uses (SPEC §10).
//!
//! ## Conventions
//! * A [`Texture`] is row-major, `channels` floats per texel, row 0 at the top. Colour textures
//!   with alpha store **premultiplied** alpha in the last channel, so that filtering averages
//!   colour by coverage (undefined texels are simply `0` in every channel).
//! * Texture coordinates `(u, v) ∈ [0, 1]²` span the whole texture; texel `(i, j)` covers
//!   `[i/w, (i+1)/w] × [j/h, (j+1)/h]` and its **centre** is at `((i + ½)/w, (j + ½)/h)`, as on a
//!   GPU.
//! * Level `l + 1` has `max(1, ⌊w_l/2⌋) × max(1, ⌊h_l/2⌋)` texels. The box prefilter is the
//!   exact **area-weighted** mean of **level 0** over the coarse texel's footprint, with
//!   fractional weights where a footprint cuts a texel. Every level is computed from level 0, not
//!   from the level above it: for sizes that are not powers of two, filtering the level above
//!   would weight a cut texel's whole mean by the share of it inside the footprint, which is not
//!   the mean of that share.
//! * Wrap modes per axis: [`WrapMode::Repeat`] (periodic textures, e.g. the angle axis of a
//!   cylindrical texture) or [`WrapMode::Clamp`].
//! * Level of detail: `λ = log2 D`, `D = max(√((u_x w)² + (v_x h)²), √((u_y w)² + (v_y h)²))`
//!   with level-0 sizes `w, h`, clamped to `[0, levels − 1]`; trilinear sampling blends the two
//!   nearest levels linearly in `λ`.
//!
//! Room for later work: [`Filter`] and [`PyramidKind`] are non-exhaustive (better prefilters,
//! ripmaps, fipmaps); sRGB inputs are converted to linear before building (the caller's job,
//! with [`altrep_data_gen::srgb_to_linear`]).
//!
//! Cost: building level `l` reads all of level 0 once (separable: `W·H·(1 + 1/ratio)` weighted
//! adds per channel), so the whole pyramid costs about `W·H·channels·2·log2(max(W, H))` multiply-
//! adds, rows in parallel; a trilinear sample reads 8 texels.

use rayon::prelude::*;

/// Errors of pyramid construction.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MipError {
    /// Width, height or channel count is zero.
    #[error("texture {what} is zero")]
    ZeroSize {
        /// `"width"`, `"height"` or `"channels"`.
        what: &'static str,
    },
    /// `data.len() != width × height × channels`.
    #[error("texture data has {got} floats, expected {expected} (width × height × channels)")]
    DataSize {
        /// Floats given.
        got: usize,
        /// Floats expected.
        expected: usize,
    },
    /// A texel is NaN or infinite.
    #[error("texel value {index} is not finite")]
    NonFinite {
        /// Index of the first offending float.
        index: usize,
    },
}

/// How coordinates outside `[0, 1]` are treated along one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum WrapMode {
    /// Clamp to the edge texel.
    Clamp,
    /// Periodic: the texture tiles.
    Repeat,
}

/// Prefilter used to build coarser levels.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Filter {
    /// Exact area-weighted box.
    #[default]
    Box,
}

/// Which pyramid: levels reduced in both directions at once.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum PyramidKind {
    /// Mipmap: both axes halved per level.
    #[default]
    Mip,
}

/// Parameters of [`Pyramid::build`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PyramidParams {
    /// Wrap mode along `u` (columns) and `v` (rows).
    pub wrap: [WrapMode; 2],
    /// Prefilter.
    pub filter: Filter,
    /// Pyramid kind.
    pub kind: PyramidKind,
}

impl Default for PyramidParams {
    /// Clamp on both axes, box filter, mipmap.
    fn default() -> Self {
        Self {
            wrap: [WrapMode::Clamp; 2],
            filter: Filter::Box,
            kind: PyramidKind::Mip,
        }
    }
}

/// A multi-channel float texture (see the module conventions).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Floats per texel.
    pub channels: usize,
    /// `width × height × channels` floats, row-major.
    pub data: Vec<f32>,
}

impl Texture {
    /// A texture, checked for size and finiteness.
    pub fn new(
        width: usize,
        height: usize,
        channels: usize,
        data: Vec<f32>,
    ) -> Result<Self, MipError> {
        for (n, what) in [(width, "width"), (height, "height"), (channels, "channels")] {
            if n == 0 {
                return Err(MipError::ZeroSize { what });
            }
        }
        let expected = width * height * channels;
        if data.len() != expected {
            return Err(MipError::DataSize {
                got: data.len(),
                expected,
            });
        }
        if let Some(index) = data.iter().position(|x| !x.is_finite()) {
            return Err(MipError::NonFinite { index });
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
        })
    }

    /// The premultiplied RGBA image as a 4-channel texture.
    pub fn from_rgba(image: &altrep_data_gen::RgbaImage) -> Result<Self, MipError> {
        Self::new(
            image.width,
            image.height,
            4,
            image.pixels.iter().flatten().copied().collect(),
        )
    }

    /// Back to an RGBA image (4-channel textures only; other channel counts are padded with 0 or
    /// truncated).
    pub fn to_rgba(&self) -> altrep_data_gen::RgbaImage {
        let pixels = self
            .data
            .chunks(self.channels)
            .map(|t| std::array::from_fn(|c| t.get(c).copied().unwrap_or(0.0)))
            .collect();
        altrep_data_gen::RgbaImage {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// The texel `(i, j)`.
    #[inline]
    pub fn texel(&self, i: usize, j: usize) -> &[f32] {
        let k = (j * self.width + i) * self.channels;
        &self.data[k..k + self.channels]
    }
}

/// Weights of the area-weighted box resampling of `n` texels to `m ≤ n`: for each output texel,
/// the `(source index, weight)` pairs, weights summing to 1.
fn box_weights(n: usize, m: usize) -> Vec<Vec<(usize, f64)>> {
    let ratio = n as f64 / m as f64;
    (0..m)
        .map(|i| {
            let (a, b) = (i as f64 * ratio, (i + 1) as f64 * ratio);
            let mut w = Vec::new();
            let mut k = a.floor() as usize;
            while (k as f64) < b && k < n {
                let overlap = (b.min(k as f64 + 1.0) - a.max(k as f64)).max(0.0);
                if overlap > 0.0 {
                    w.push((k, overlap / ratio));
                }
                k += 1;
            }
            w
        })
        .collect()
}

/// Level 0 resampled to `w2 × h2` by the area-weighted box (separable: rows, then columns).
fn box_resample(t: &Texture, w2: usize, h2: usize) -> Texture {
    let c = t.channels;
    let wx = box_weights(t.width, w2);
    let wy = box_weights(t.height, h2);
    // Horizontal pass: height × w2.
    let mut tmp = vec![0.0f64; t.height * w2 * c];
    tmp.par_chunks_mut(w2 * c).enumerate().for_each(|(j, row)| {
        for (i, weights) in wx.iter().enumerate() {
            for &(k, wk) in weights {
                for ch in 0..c {
                    row[i * c + ch] += wk * f64::from(t.data[(j * t.width + k) * c + ch]);
                }
            }
        }
    });
    let mut data = vec![0.0f32; h2 * w2 * c];
    data.par_chunks_mut(w2 * c)
        .enumerate()
        .for_each(|(j, row)| {
            for &(k, wk) in &wy[j] {
                for (x, v) in row.iter_mut().enumerate() {
                    *v += (wk * tmp[k * w2 * c + x]) as f32;
                }
            }
        });
    Texture {
        width: w2,
        height: h2,
        channels: c,
        data,
    }
}

/// A mip pyramid: level 0 is the input, each next level halves both sizes (floor, at least 1)
/// until `1 × 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct Pyramid {
    levels: Vec<Texture>,
    params: PyramidParams,
}

impl Pyramid {
    /// Builds the pyramid of `base`. Cost: see the module docs.
    pub fn build(base: Texture, params: PyramidParams) -> Result<Self, MipError> {
        let base = Texture::new(base.width, base.height, base.channels, base.data)?;
        let mut levels = vec![base];
        loop {
            let last = levels.last().expect("at least the base level");
            if last.width == 1 && last.height == 1 {
                break;
            }
            let (w2, h2) = ((last.width / 2).max(1), (last.height / 2).max(1));
            let next = match params.filter {
                Filter::Box => box_resample(&levels[0], w2, h2),
            };
            levels.push(next);
        }
        Ok(Self { levels, params })
    }

    /// The levels, finest first.
    pub fn levels(&self) -> &[Texture] {
        &self.levels
    }

    /// The parameters it was built with.
    pub fn params(&self) -> &PyramidParams {
        &self.params
    }

    /// Bytes of all levels at `bytes_per_channel` per stored channel (4 for f32, 1 for RGBA8).
    pub fn bytes(&self, bytes_per_channel: usize) -> usize {
        self.levels
            .iter()
            .map(|l| l.width * l.height * l.channels * bytes_per_channel)
            .sum()
    }

    fn wrap(&self, axis: usize, i: i64, n: usize) -> usize {
        match self.params.wrap[axis] {
            WrapMode::Clamp => i.clamp(0, n as i64 - 1) as usize,
            WrapMode::Repeat => i.rem_euclid(n as i64) as usize,
        }
    }

    /// Bilinear sample of level `level` (clamped to the last level) at `(u, v)`, written into
    /// `out` (`channels` floats). Texel centres at `(i + ½)/w`.
    pub fn bilinear_into(&self, level: usize, u: f64, v: f64, out: &mut [f32]) {
        let t = &self.levels[level.min(self.levels.len() - 1)];
        let (s, r) = (u * t.width as f64 - 0.5, v * t.height as f64 - 0.5);
        let (i0, j0) = (s.floor(), r.floor());
        let (fx, fy) = ((s - i0) as f32, (r - j0) as f32);
        let (i0, j0) = (i0 as i64, j0 as i64);
        let ia = [self.wrap(0, i0, t.width), self.wrap(0, i0 + 1, t.width)];
        let ja = [self.wrap(1, j0, t.height), self.wrap(1, j0 + 1, t.height)];
        let w = [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ];
        out.iter_mut().for_each(|o| *o = 0.0);
        for (k, (i, j)) in [
            (ia[0], ja[0]),
            (ia[1], ja[0]),
            (ia[0], ja[1]),
            (ia[1], ja[1]),
        ]
        .into_iter()
        .enumerate()
        {
            for (o, x) in out.iter_mut().zip(t.texel(i, j)) {
                *o += w[k] * x;
            }
        }
    }

    /// Bilinear sample as a new vector.
    pub fn bilinear(&self, level: usize, u: f64, v: f64) -> Vec<f32> {
        let mut out = vec![0.0; self.levels[0].channels];
        self.bilinear_into(level, u, v, &mut out);
        out
    }

    /// Trilinear sample at level of detail `lod` (clamped to `[0, levels − 1]`).
    pub fn trilinear(&self, u: f64, v: f64, lod: f64) -> Vec<f32> {
        let max = (self.levels.len() - 1) as f64;
        let lod = if lod.is_nan() {
            0.0
        } else {
            lod.clamp(0.0, max)
        };
        let l0 = lod.floor() as usize;
        let f = (lod - l0 as f64) as f32;
        let mut a = self.bilinear(l0, u, v);
        if f > 0.0 {
            let b = self.bilinear(l0 + 1, u, v);
            for (x, y) in a.iter_mut().zip(b) {
                *x = (1.0 - f) * *x + f * y;
            }
        }
        a
    }

    /// Level of detail from the screen-space derivatives of `(u, v)` (Heckbert's `D`, see the
    /// module docs). Zero derivatives give `−∞` (magnification), which sampling clamps to 0.
    pub fn lod(&self, dudx: f64, dvdx: f64, dudy: f64, dvdy: f64) -> f64 {
        let (w, h) = (self.levels[0].width as f64, self.levels[0].height as f64);
        let dx = ((dudx * w).powi(2) + (dvdx * h).powi(2)).sqrt();
        let dy = ((dudy * w).powi(2) + (dvdy * h).powi(2)).sqrt();
        dx.max(dy).log2()
    }

    /// Trilinear sample with the level chosen from derivatives, as a GPU's `textureGrad`.
    pub fn sample_grad(
        &self,
        u: f64,
        v: f64,
        dudx: f64,
        dvdx: f64,
        dudy: f64,
        dvdy: f64,
    ) -> Vec<f32> {
        self.trilinear(u, v, self.lod(dudx, dvdx, dudy, dvdy))
    }
}
