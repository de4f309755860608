//! Fipmaps (Bornik & Ferko 2002): ripmaps of sheared copies of the texture, chosen per view, for
//! oblique views whose footprint is skewed with respect to the texture axes, where both the
//! mipmap (isotropic) and the ripmap (axis-aligned box) over-blur.
//!
//! ## The transform
//! The paper's PIFS transform on `(x, y, z)` (position, grey level) is
//! `[x̄ ȳ]ᵀ = [a b; c d]·[x y]ᵀ + [e f]ᵀ`, `z̄ = s·z + o` ([`FipTransform`]). As the paper
//! prescribes, `a = d = 1`, `e = f = 0` and one of `b`, `c` is a shear:
//! * [`ShearAxis::V`], `c ≠ 0`: `u' = u`, `v' = v + c·u` — aligns a footprint whose major axis
//!   points along `(cos φ, sin φ)` in `(u, v)` with the `u'` axis when `c = −tan φ`;
//! * [`ShearAxis::U`], `b ≠ 0`: `u' = u + b·v`, `v' = v` — aligns it with `v'` when
//!   `b = −cot φ`.
//!
//! After the shear the footprint is nearly axis-aligned, so the ripmap of the sheared texture
//! filters it with little excess blur. `s` and `o` (contrast and brightness) are the paper's
//! depth cue: `1` and `0` without atmosphere ([`FipTransform::with_depth_cue`] sets them from the
//! viewing distance); the lookup returns `s·value + o`.
//!
//! ## Periodicity and storage
//! Only periodic textures ([`WrapMode::Repeat`] on both axes) are sheared: a shear `c = p/q`
//! (in lowest terms) maps the unit lattice to a lattice of period `q` along the other axis, so the
//! sheared texture is stored over `q` periods (`q·W × H` for a `V` shear) and stays periodic. Its
//! texels are the mean of level 0 (box-reconstructed) over their pre-image parallelogram,
//! estimated with `8 × 8` point samples per texel in linear light. The database holds the shears
//! `±k/n` for `k = 1 … n` (`n = fip_shear_steps`) on both axes, plus the plain ripmap and mipmap.
//!
//! ## The decision (the paper's colour-cube rule)
//! In the frame of the textured polygon — `R` the image of the texture's `u` axis, `G` the
//! normal, `B` the image of `v` — let `(r, g, b)` be the unit direction from the surface point to
//! the camera. If its angle to `G` is at most `mip_max_tilt_deg`: mipmap ("greenish"). Otherwise
//! `φ = atan2(b, r)` is the direction in which the footprint is stretched; if `φ` lies within
//! `rip_max_skew_deg` of a texture axis ("too red or too blue"), or the tilt is below
//! `fip_min_tilt_deg` (not yet "the lower part of the triangle"): ripmap; otherwise the fipmap
//! whose shear leaves the smallest angle between the sheared `φ` and a texture axis.
//!
//! Cost: build `≈ (1 + Σ q)·2` ripmaps' worth of resampling for `2n` shears; storage
//! `≈ 4·W·H·(1 + 2Σ_k q_k)` texels; a lookup reads 16 texels (rip, fip) or 8 (mip).

use super::levels::{finish, prepare};
use super::mip::{MipError, Pyramid, PyramidParams, Texture, WrapMode};
use super::rip::RipMap;

/// Which texture axis a shear moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ShearAxis {
    /// `v' = v + c·u` (Bornik & Ferko's `c`).
    V,
    /// `u' = u + b·v` (Bornik & Ferko's `b`).
    U,
}

/// A rational shear `num/den` along `axis`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Shear {
    /// Moved axis.
    pub axis: ShearAxis,
    /// Numerator.
    pub num: i32,
    /// Denominator (> 0).
    pub den: u32,
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a.max(1) } else { gcd(b, a % b) }
}

impl Shear {
    /// The shear value.
    pub fn value(&self) -> f64 {
        f64::from(self.num) / f64::from(self.den)
    }

    /// Period (in texture repeats) of the sheared texture along the unsheared axis: the reduced
    /// denominator.
    pub fn period(&self) -> usize {
        (self.den / gcd(self.num.unsigned_abs(), self.den)) as usize
    }

    /// The sheared coordinates `(u', v')`.
    pub fn apply(&self, u: f64, v: f64) -> (f64, f64) {
        let c = self.value();
        match self.axis {
            ShearAxis::V => (u, v + c * u),
            ShearAxis::U => (u + c * v, v),
        }
    }

    /// Bornik & Ferko's transform for this shear (`a = d = 1`, `s = 1`, `o = 0`).
    pub fn transform(&self) -> FipTransform {
        let c = self.value();
        let (b, c) = match self.axis {
            ShearAxis::V => (0.0, c),
            ShearAxis::U => (c, 0.0),
        };
        FipTransform {
            a: 1.0,
            b,
            c,
            d: 1.0,
            s: 1.0,
            o: 0.0,
        }
    }

    /// Angle (radians, in `[0, π/2]`) between the direction `φ` after this shear and the texture
    /// axis it is meant to align with.
    pub fn residual(&self, phi: f64) -> f64 {
        let (du, dv) = self.apply(phi.cos(), phi.sin());
        let ang = dv.atan2(du).rem_euclid(std::f64::consts::PI);
        let target = match self.axis {
            ShearAxis::V => 0.0,
            ShearAxis::U => std::f64::consts::FRAC_PI_2,
        };
        let d = (ang - target).abs();
        d.min(std::f64::consts::PI - d)
    }
}

/// Bornik & Ferko's PIFS transform: `[x̄ ȳ] = [a b; c d][x y]`, `z̄ = s·z + o` (module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FipTransform {
    /// `x̄ = a x + b y`.
    pub a: f64,
    /// See `a`.
    pub b: f64,
    /// `ȳ = c x + d y`.
    pub c: f64,
    /// See `c`.
    pub d: f64,
    /// Contrast.
    pub s: f64,
    /// Brightness.
    pub o: f64,
}

impl FipTransform {
    /// Contrast and brightness of exponential depth cueing: `s = exp(−density·distance)`,
    /// `o = (1 − s)·haze`, Bornik & Ferko's "atmospheric perspective" (distance and density in any
    /// reciprocal units).
    pub fn with_depth_cue(mut self, distance: f64, density: f64, haze: f64) -> Self {
        self.s = (-density * distance).exp();
        self.o = (1.0 - self.s) * haze;
        self
    }
}

/// The scheme the decision picks for a view.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Scheme {
    /// Trilinear mipmap lookup.
    Mip,
    /// Ripmap lookup.
    Rip,
    /// Fipmap lookup with shear number `.0` of [`FipMap::shears`].
    Fip(usize),
}

/// The shears of the database: `±k/n`, `k = 1 … n`, on both axes.
pub fn shear_set(n: u32) -> Vec<Shear> {
    let n = n.max(1);
    let mut v = Vec::new();
    for axis in [ShearAxis::V, ShearAxis::U] {
        for k in 1..=n as i32 {
            for sign in [1, -1] {
                v.push(Shear {
                    axis,
                    num: sign * k,
                    den: n,
                });
            }
        }
    }
    v
}

/// The decision of the module docs for the unit direction `(r, g, b)` from the surface point to
/// the camera in the polygon frame (`g` along the normal; a camera behind the polygon is
/// mirrored). A zero or non-finite direction gives the mipmap.
pub fn decide(dir: [f64; 3], shears: &[Shear], p: &PyramidParams) -> Scheme {
    let n = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    if !(n.is_finite() && n > 0.0) {
        return Scheme::Mip;
    }
    let tilt = (dir[1].abs() / n).clamp(0.0, 1.0).acos().to_degrees();
    if tilt <= p.mip_max_tilt_deg {
        return Scheme::Mip;
    }
    let phi = dir[2].atan2(dir[0]);
    let skew = {
        let a = phi.rem_euclid(std::f64::consts::FRAC_PI_2);
        a.min(std::f64::consts::FRAC_PI_2 - a).to_degrees()
    };
    if skew <= p.rip_max_skew_deg || tilt < p.fip_min_tilt_deg || shears.is_empty() {
        return Scheme::Rip;
    }
    let best = shears
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.residual(phi).total_cmp(&b.1.residual(phi)))
        .map(|(i, _)| i)
        .unwrap_or(0);
    Scheme::Fip(best)
}

/// A fipmap database: the mipmap, the ripmap and one ripmap per shear (module docs).
#[derive(Clone, Debug)]
pub struct FipMap {
    mip: Pyramid,
    rip: RipMap,
    shears: Vec<Shear>,
    sheared: Vec<RipMap>,
    params: PyramidParams,
}

/// Level 0 of the texture sheared by `shear` (module docs), in stored form.
pub fn shear_texture(base: &Texture, shear: Shear, p: &PyramidParams) -> Texture {
    use rayon::prelude::*;
    const N: usize = 8;
    let work = prepare(base, p);
    let q = shear.period();
    let (w, h, ch) = (base.width, base.height, base.channels);
    let (w2, h2) = match shear.axis {
        ShearAxis::V => (q * w, h),
        ShearAxis::U => (w, q * h),
    };
    let c = shear.value();
    let mut data = vec![0.0f32; w2 * h2 * ch];
    data.par_chunks_mut(w2 * ch)
        .enumerate()
        .for_each(|(j, row)| {
            let mut acc = vec![0.0f64; ch];
            for i in 0..w2 {
                acc.iter_mut().for_each(|a| *a = 0.0);
                for sj in 0..N {
                    // v' in texture units of the unsheared texture (u' likewise).
                    let vp = (j as f64 + (sj as f64 + 0.5) / N as f64) / h as f64;
                    for si in 0..N {
                        let up = (i as f64 + (si as f64 + 0.5) / N as f64) / w as f64;
                        let (u, v) = match shear.axis {
                            ShearAxis::V => (up, vp - c * up),
                            ShearAxis::U => (up - c * vp, vp),
                        };
                        let x = ((u * w as f64).floor() as i64).rem_euclid(w as i64) as usize;
                        let y = ((v * h as f64).floor() as i64).rem_euclid(h as i64) as usize;
                        for (a, t) in acc.iter_mut().zip(work.texel(x, y)) {
                            *a += f64::from(*t);
                        }
                    }
                }
                for (o, a) in row[i * ch..(i + 1) * ch].iter_mut().zip(&acc) {
                    *o = (a / (N * N) as f64) as f32;
                }
            }
        });
    let t = Texture {
        width: w2,
        height: h2,
        channels: ch,
        data,
    };
    finish(t, p, None)
}

impl FipMap {
    /// Builds the database of `base` (needs [`WrapMode::Repeat`] on both axes). Cost: module docs.
    pub fn build(base: Texture, params: PyramidParams) -> Result<Self, MipError> {
        let base = Texture::new(base.width, base.height, base.channels, base.data)?;
        params.validate(base.channels)?;
        if params.wrap != [WrapMode::Repeat; 2] {
            return Err(MipError::Unsupported(
                "fipmaps shear periodic textures only: use WrapMode::Repeat on both axes",
            ));
        }
        let shears = shear_set(params.fip_shear_steps);
        let sheared = shears
            .iter()
            .map(|&s| RipMap::build(shear_texture(&base, s, &params), params))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            mip: Pyramid::build(base.clone(), params)?,
            rip: RipMap::build(base, params)?,
            shears,
            sheared,
            params,
        })
    }

    /// A database from stored parts (e.g. read back from files, possibly only the levels a
    /// scene needs): the mipmap, the plain ripmap and one ripmap per shear of
    /// [`shear_set`]`(params.fip_shear_steps)`, in that order. Errors: wrap not `Repeat` on both
    /// axes, another number of sheared ripmaps, a part with another channel count, invalid
    /// parameters.
    pub fn from_parts(
        mip: Pyramid,
        rip: RipMap,
        sheared: Vec<RipMap>,
        params: PyramidParams,
    ) -> Result<Self, MipError> {
        let channels = rip.level(0, 0).channels;
        params.validate(channels)?;
        if params.wrap != [WrapMode::Repeat; 2] {
            return Err(MipError::Unsupported(
                "fipmaps shear periodic textures only: use WrapMode::Repeat on both axes",
            ));
        }
        let shears = shear_set(params.fip_shear_steps);
        if sheared.len() != shears.len() {
            return Err(MipError::InvalidParams {
                name: "fip_shear_steps",
                reason: "the number of sheared ripmaps differs from the shear set's",
            });
        }
        if mip.levels()[0].channels != channels
            || sheared.iter().any(|r| r.level(0, 0).channels != channels)
        {
            return Err(MipError::InvalidParams {
                name: "channels",
                reason: "the parts of a fipmap differ in channel count",
            });
        }
        Ok(Self {
            mip,
            rip,
            shears,
            sheared,
            params,
        })
    }

    /// The parameters the database was built with.
    pub fn params(&self) -> &PyramidParams {
        &self.params
    }

    /// The mipmap.
    pub fn mip(&self) -> &Pyramid {
        &self.mip
    }

    /// The plain ripmap.
    pub fn rip(&self) -> &RipMap {
        &self.rip
    }

    /// The shears, in the order of [`Scheme::Fip`] indices.
    pub fn shears(&self) -> &[Shear] {
        &self.shears
    }

    /// The ripmap of shear `i`.
    pub fn sheared(&self, i: usize) -> &RipMap {
        &self.sheared[i]
    }

    /// Bytes of every stored level at `bytes_per_channel`.
    pub fn bytes(&self, bytes_per_channel: usize) -> usize {
        self.mip.bytes(bytes_per_channel)
            + self.rip.bytes(bytes_per_channel)
            + self
                .sheared
                .iter()
                .map(|r| r.bytes(bytes_per_channel))
                .sum::<usize>()
    }

    /// [`decide`] with this database's shears and parameters.
    pub fn decide(&self, dir: [f64; 3]) -> Scheme {
        decide(dir, &self.shears, &self.params)
    }

    /// Sample with scheme `scheme` at `(u, v)` with screen derivatives, applying the transform's
    /// contrast `s` and brightness `o` (`transform = None`: `s = 1`, `o = 0`), into `out`.
    #[allow(clippy::too_many_arguments)]
    pub fn sample_into(
        &self,
        scheme: Scheme,
        u: f64,
        v: f64,
        dudx: f64,
        dvdx: f64,
        dudy: f64,
        dvdy: f64,
        transform: Option<FipTransform>,
        out: &mut [f32],
    ) {
        match scheme {
            Scheme::Mip => {
                let lod = self.mip.lod(dudx, dvdx, dudy, dvdy);
                out.copy_from_slice(&self.mip.trilinear(u, v, lod));
            }
            Scheme::Rip => {
                let lod = self.rip.lod(dudx, dvdx, dudy, dvdy);
                self.rip.sample_lod_into(u, v, lod, out);
            }
            Scheme::Fip(i) => {
                let i = i.min(self.shears.len().saturating_sub(1));
                let (sh, rip) = (self.shears[i], &self.sheared[i]);
                let q = sh.period() as f64;
                let c = sh.value();
                // Stored coordinates (ũ, ṽ) of the sheared texture and their derivatives.
                let map = |du: f64, dv: f64| match sh.axis {
                    ShearAxis::V => (du / q, dv + c * du),
                    ShearAxis::U => (du + c * dv, dv / q),
                };
                let (su, sv) = map(u, v);
                let (sux, svx) = map(dudx, dvdx);
                let (suy, svy) = map(dudy, dvdy);
                let lod = rip.lod(sux, svx, suy, svy);
                rip.sample_lod_into(su, sv, lod, out);
            }
        }
        if let Some(t) = transform {
            out.iter_mut()
                .for_each(|x| *x = (t.s * f64::from(*x) + t.o) as f32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sheared_lookups_magnified_match_the_texture() {
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
        let fip = FipMap::build(
            tex,
            PyramidParams {
                wrap: [WrapMode::Repeat; 2],
                ..Default::default()
            },
        )
        .unwrap();
        let mut rng = altrep_data_gen::SplitMix64::new(1);
        for i in 0..fip.shears().len() {
            let mut worst: f64 = 0.0;
            for _ in 0..200 {
                let (u, v) = (rng.range(-2.0, 3.0), rng.range(-2.0, 3.0));
                let want = 0.5 + 0.3 * (std::f64::consts::TAU * (2.0 * u + v)).sin();
                let mut out = [0.0f32];
                fip.sample_into(Scheme::Fip(i), u, v, 1e-6, 0.0, 0.0, 1e-6, None, &mut out);
                worst = worst.max((f64::from(out[0]) - want).abs());
            }
            // Stated tolerance: bilinear reconstruction of a 32-texel wave plus the shear's
            // resampling, 0.01.
            assert!(worst < 0.01, "shear {:?}: worst {worst}", fip.shears()[i]);
        }
    }
}
