//! Mip pyramids (Williams 1983) with level selection from texture-coordinate derivatives
//! (Heckbert), the one pyramid every representation uses (docs/design.md §10).
//!
//! ## Conventions
//! * A [`Texture`] is row-major, `channels` floats per texel, row 0 at the top. Colour textures
//!   with alpha store **premultiplied** alpha in the last channel, so that filtering averages
//!   colour by coverage (undefined texels are simply `0` in every channel).
//! * Texture coordinates `(u, v) ∈ [0, 1]²` span the whole texture; texel `(i, j)` covers
//!   `[i/w, (i+1)/w] × [j/h, (j+1)/h]` and its **centre** is at `((i + ½)/w, (j + ½)/h)`, as on a
//!   GPU.
//! * Level `l + 1` has `max(1, ⌊w_l/2⌋) × max(1, ⌊h_l/2⌋)` texels. The (default) box prefilter is the
//!   exact **area-weighted** mean of **level 0** over the coarse texel's footprint, with
//!   fractional weights where a footprint cuts a texel. Every level is computed from level 0, not
//!   from the level above it: for sizes that are not powers of two, filtering the level above
//!   would weight a cut texel's whole mean by the share of it inside the footprint, which is not
//!   the mean of that share.
//! * Wrap modes per axis: [`WrapMode::Repeat`] (periodic textures, e.g. the angle axis of a
//!   cylindrical texture), [`WrapMode::Clamp`] or [`WrapMode::Mirror`].
//! * Level of detail: `λ = log2 D`, `D = max(√((u_x w)² + (v_x h)²), √((u_y w)² + (v_y h)²))`
//!   with level-0 sizes `w, h`, clamped to `[0, levels − 1]`; trilinear sampling blends the two
//!   nearest levels linearly in `λ`.
//!
//! Other prefilters ([`Filter`]), sRGB decoding, alpha handling, coverage preservation and
//! normal renormalisation are chosen in [`PyramidParams`] and applied by
//! [`super::levels`] and [`super::filter`]; ripmaps and fipmaps are in [`super::rip`] and
//! [`super::fip`].
//!
//! Cost: building level `l` reads all of level 0 once (separable: `W·H·(1 + 1/ratio)` weighted
//! adds per channel), so the whole pyramid costs about `W·H·channels·2·log2(max(W, H))` multiply-
//! adds, rows in parallel; a trilinear sample reads 8 texels.

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
    /// A parameter is out of range or does not fit the texture.
    #[error("pyramid parameter {name}: {reason}")]
    InvalidParams {
        /// Field of [`PyramidParams`] (or of the fusion / evaluation parameters).
        name: &'static str,
        /// What is wrong.
        reason: &'static str,
    },
    /// A combination this implementation does not build.
    #[error("unsupported: {0}")]
    Unsupported(&'static str),
    /// Stored levels handed to a `from_levels` constructor do not form a pyramid: level
    /// `level` (counted from the first one given) has the wrong size or channel count.
    #[error(
        "level {level} is {got:?} (width, height, channels), expected {expected:?}: each level must halve the previous one (max(1, ⌊n/2⌋) per axis)"
    )]
    LevelSize {
        /// Index of the offending level among those given (for a ripmap: `l_v·n_u + l_u`).
        level: usize,
        /// Its `(width, height, channels)`.
        got: (usize, usize, usize),
        /// What the halvings of the first level require.
        expected: (usize, usize, usize),
    },
    /// A `from_levels` constructor got no level.
    #[error("no level given")]
    NoLevels,
}

/// How coordinates outside `[0, 1]` are treated along one axis (see
/// [`super::filter::wrap_index`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum WrapMode {
    /// Clamp to the edge texel.
    Clamp,
    /// Periodic: the texture tiles.
    Repeat,
    /// Mirrored repeat (period `2n`, as GL's `MIRRORED_REPEAT`).
    Mirror,
}

/// Prefilter used to build coarser levels (kernels in [`super::filter`]).
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Filter {
    /// Exact area-weighted box.
    #[default]
    Box,
    /// Tent of radius one output texel.
    Triangle,
    /// Kaiser-windowed sinc, radius 3 output texels, `α = 4` (NVIDIA Texture Tools).
    Kaiser,
    /// Lanczos-3 windowed sinc.
    Lanczos,
}

/// Which pyramid.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum PyramidKind {
    /// Mipmap: both axes halved per level.
    #[default]
    Mip,
    /// Ripmap: `u` and `v` halved independently ([`super::RipMap`]).
    Rip,
    /// Fipmap: ripmaps of sheared copies of the texture ([`super::FipMap`]).
    Fip,
}

/// How texel values encode colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum ColourSpace {
    /// Values are linear: filtered as they are.
    #[default]
    Linear,
    /// The colour channels (the first three, or fewer, not counting alpha) are sRGB-encoded in
    /// `[0, 1]`: decoded to linear light, filtered, encoded back (as NVTT does by default).
    Srgb,
}

/// Whether the last channel is alpha and how colour relates to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum AlphaMode {
    /// No alpha channel: every channel is filtered alike (this also averages premultiplied data
    /// correctly, as the module conventions require of RGBA textures).
    #[default]
    None,
    /// The last channel is alpha and colour is premultiplied by it (in linear light for sRGB:
    /// stored colour `= a · encode(c)`).
    Premultiplied,
    /// The last channel is alpha and colour is straight: premultiplied for filtering, divided
    /// back afterwards.
    Straight,
}

/// Parameters of [`Pyramid::build`] and of [`super::build`]. Lookup-time options (EWA
/// anisotropy, the mip/rip/fip decision thresholds) live here too so one struct describes a
/// pyramid and how it is read.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PyramidParams {
    /// Wrap mode along `u` (columns) and `v` (rows).
    pub wrap: [WrapMode; 2],
    /// Prefilter.
    pub filter: Filter,
    /// Pyramid kind (used by [`super::build`]; [`Pyramid::build`] always builds a mipmap).
    pub kind: PyramidKind,
    /// Colour encoding of the texel values.
    pub colour: ColourSpace,
    /// Alpha channel handling.
    pub alpha: AlphaMode,
    /// Alpha-test reference value: when set (and `alpha` is not `None`), each level's alpha is
    /// scaled so that the fraction of its area with `alpha > reference` (measured with 4×4
    /// bilinear samples per texel) matches level 0's, as NVTT's `scaleAlphaToCoverage`.
    pub coverage_reference: Option<f32>,
    /// The first three channels hold a unit normal in `[−1, 1]³`: renormalised after filtering
    /// (a zero mean becomes `(0, 0, 1)`).
    pub normal_map: bool,
    /// Fipmap shear denominators: shears `k / fip_shear_steps` for `k = ±1 … ±fip_shear_steps`
    /// along each axis (so `|shear| ≤ 1`); 1 to 8.
    pub fip_shear_steps: u32,
    /// EWA: longest allowed ratio of the footprint's major to minor axis (the minor axis is
    /// lengthened beyond it); 1 to 1024.
    pub ewa_max_anisotropy: f64,
    /// Mip/rip/fip decision: views within this angle of the polygon normal use the mipmap
    /// (degrees, 0 to 90).
    pub mip_max_tilt_deg: f64,
    /// Mip/rip/fip decision: views not handled by the mipmap but within this angle of the normal
    /// use the ripmap whatever their azimuth (degrees, 0 to 90): the fipmap pays one resampling
    /// of level 0 and only wins on strongly anisotropic footprints.
    pub fip_min_tilt_deg: f64,
    /// Mip/rip/fip decision: oblique views whose direction, projected into the polygon, lies
    /// within this angle of a texture axis use the ripmap; others the fipmap (degrees, 0 to 45).
    pub rip_max_skew_deg: f64,
}

impl Default for PyramidParams {
    /// Clamp on both axes, box filter, mipmap, linear colour, no alpha, no coverage
    /// preservation, not a normal map, fip shears `±½, ±1`, EWA anisotropy up to 64, mipmap
    /// within 30° of the normal, ripmap below 80° or within 10° of a texture axis, fipmap beyond.
    fn default() -> Self {
        Self {
            wrap: [WrapMode::Clamp; 2],
            filter: Filter::Box,
            kind: PyramidKind::Mip,
            colour: ColourSpace::Linear,
            alpha: AlphaMode::None,
            coverage_reference: None,
            normal_map: false,
            fip_shear_steps: 2,
            ewa_max_anisotropy: 64.0,
            mip_max_tilt_deg: 30.0,
            fip_min_tilt_deg: 80.0,
            rip_max_skew_deg: 10.0,
        }
    }
}

impl PyramidParams {
    /// Checks ranges and combinations against a texture of `channels` channels.
    pub fn validate(&self, channels: usize) -> Result<(), MipError> {
        let bad = |name: &'static str, reason: &'static str| {
            Err(MipError::InvalidParams { name, reason })
        };
        if !(1..=8).contains(&self.fip_shear_steps) {
            return bad("fip_shear_steps", "must be 1 to 8");
        }
        if !(self.ewa_max_anisotropy.is_finite()
            && (1.0..=1024.0).contains(&self.ewa_max_anisotropy))
        {
            return bad("ewa_max_anisotropy", "must be 1 to 1024");
        }
        if !(self.mip_max_tilt_deg.is_finite() && (0.0..=90.0).contains(&self.mip_max_tilt_deg)) {
            return bad("mip_max_tilt_deg", "must be 0 to 90");
        }
        if !(self.fip_min_tilt_deg.is_finite() && (0.0..=90.0).contains(&self.fip_min_tilt_deg)) {
            return bad("fip_min_tilt_deg", "must be 0 to 90");
        }
        if !(self.rip_max_skew_deg.is_finite() && (0.0..=45.0).contains(&self.rip_max_skew_deg)) {
            return bad("rip_max_skew_deg", "must be 0 to 45");
        }
        if let Some(r) = self.coverage_reference {
            if !(r.is_finite() && r > 0.0 && r < 1.0) {
                return bad("coverage_reference", "must lie strictly between 0 and 1");
            }
            if self.alpha == AlphaMode::None {
                return bad(
                    "coverage_reference",
                    "needs an alpha channel (alpha mode not None)",
                );
            }
        }
        let has_alpha = self.alpha != AlphaMode::None;
        if has_alpha && channels < 2 {
            return bad("alpha", "needs at least 2 channels (colour and alpha)");
        }
        if self.normal_map {
            if channels < 3 + usize::from(has_alpha) {
                return bad("normal_map", "needs 3 normal channels (plus alpha if any)");
            }
            if self.colour == ColourSpace::Srgb {
                return bad("normal_map", "normals are not sRGB colour");
            }
        }
        Ok(())
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

    /// The values quantised to 8 bits (`round(255·clamp(x, 0, 1))`), for PNG storage of colour
    /// (already sRGB-encoded when built with [`ColourSpace::Srgb`]) and alpha.
    pub fn to_u8(&self) -> Vec<u8> {
        self.data
            .iter()
            .map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect()
    }

    /// The values quantised to 16 bits (`round(65535·clamp(x, 0, 1))`).
    pub fn to_u16(&self) -> Vec<u16> {
        self.data
            .iter()
            .map(|x| (x.clamp(0.0, 1.0) * 65535.0).round() as u16)
            .collect()
    }

    /// The texel `(i, j)`.
    #[inline]
    pub fn texel(&self, i: usize, j: usize) -> &[f32] {
        let k = (j * self.width + i) * self.channels;
        &self.data[k..k + self.channels]
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
        params.validate(base.channels)?;
        let work0 = super::levels::prepare(&base, &params);
        let zero_rows = super::filter::zero_rows(&work0);
        let coverage = super::levels::coverage_target(&base, &params);
        let mut levels = vec![base];
        loop {
            let last = levels.last().expect("at least the base level");
            if last.width == 1 && last.height == 1 {
                break;
            }
            let (w2, h2) = ((last.width / 2).max(1), (last.height / 2).max(1));
            levels.push(super::levels::build_level(
                &work0, &zero_rows, w2, h2, &params, coverage,
            ));
        }
        Ok(Self { levels, params })
    }

    /// A pyramid from stored levels, finest first (e.g. read back from files). The first level
    /// need not be the original level 0 and the last need not be `1 × 1` (a planner may keep
    /// only the levels a scene uses): lookups treat the first level given as level 0 and clamp
    /// to the last. Errors: no level, a texture of zero size or with a non-finite value
    /// ([`Texture::new`]), a level that is not the halving (`max(1, ⌊n/2⌋)` per axis) of the
    /// previous one or has another channel count ([`MipError::LevelSize`]), invalid parameters.
    /// Cost: one pass over the data (the finiteness check).
    pub fn from_levels(levels: Vec<Texture>, params: PyramidParams) -> Result<Self, MipError> {
        let first = levels.first().ok_or(MipError::NoLevels)?;
        params.validate(first.channels)?;
        let mut expected = (first.width, first.height, first.channels);
        let mut checked = Vec::with_capacity(levels.len());
        for (level, t) in levels.into_iter().enumerate() {
            let t = Texture::new(t.width, t.height, t.channels, t.data)?;
            let got = (t.width, t.height, t.channels);
            // After the 1 × 1 level the halving repeats itself: no further level.
            let past_end = checked
                .last()
                .is_some_and(|p: &Texture| p.width == 1 && p.height == 1);
            if got != expected || past_end {
                return Err(MipError::LevelSize {
                    level,
                    got,
                    expected,
                });
            }
            expected = ((got.0 / 2).max(1), (got.1 / 2).max(1), got.2);
            checked.push(t);
        }
        Ok(Self {
            levels: checked,
            params,
        })
    }

    /// A pyramid holding only `level` (no coarser levels), for the ripmap and fipmap, which
    /// reuse its bilinear lookup.
    pub(crate) fn single_level(level: Texture, params: PyramidParams) -> Self {
        Self {
            levels: vec![level],
            params,
        }
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
        super::filter::wrap_index(self.params.wrap[axis], i, n)
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
