//! Ripmaps: levels reduced independently along `u` and `v`, for anisotropic footprints.
//!
//! Level `(l_u, l_v)` has `max(1, ⌊W/2^{l_u}⌋) × max(1, ⌊H/2^{l_v}⌋)` texels and is built from
//! level 0 with the prefilter, colour and alpha handling of [`super::mip`] (same definition, the
//! scales differ per axis). The diagonal `l_u = l_v` is the mipmap.
//!
//! Lookup ([`RipMap::sample_grad`]): the footprint's axis-aligned extent in level-0 texels,
//! `D_u = W·max(|u_x|, |u_y|)`, `D_v = H·max(|v_x|, |v_y|)`, gives `λ_u = log2 D_u`,
//! `λ_v = log2 D_v` (each clamped to its level range); the four nearest levels are sampled
//! bilinearly and blended bilinearly in `(λ_u, λ_v)` — 16 texel reads.
//!
//! Cost: `(log2 W + 1)(log2 H + 1)` resamplings of level 0; storage about `4 W H` texels.

use rayon::prelude::*;

use super::levels::{build_level, coverage_target, prepare};
use super::mip::{MipError, Pyramid, PyramidParams, Texture};

/// A ripmap (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct RipMap {
    /// `levels[l_v][l_u]`; each is a one-level [`Pyramid`] so that it shares the bilinear lookup.
    levels: Vec<Vec<Pyramid>>,
    params: PyramidParams,
}

/// Level sizes `n, ⌊n/2⌋, …, 1`.
pub fn halvings(n: usize) -> Vec<usize> {
    let mut v = vec![n];
    while *v.last().expect("non-empty") > 1 {
        v.push(v.last().expect("non-empty") / 2);
    }
    v
}

impl RipMap {
    /// Builds the ripmap of `base`. Cost: see the module docs.
    pub fn build(base: Texture, params: PyramidParams) -> Result<Self, MipError> {
        let base = Texture::new(base.width, base.height, base.channels, base.data)?;
        params.validate(base.channels)?;
        let work0 = prepare(&base, &params);
        let zero_rows = super::filter::zero_rows(&work0);
        let coverage = coverage_target(&base, &params);
        let (ws, hs) = (halvings(base.width), halvings(base.height));
        let pairs: Vec<(usize, usize)> = hs
            .iter()
            .enumerate()
            .flat_map(|(lv, _)| (0..ws.len()).map(move |lu| (lv, lu)))
            .collect();
        let mut flat: Vec<Texture> = pairs
            .par_iter()
            .map(|&(lv, lu)| {
                if lu == 0 && lv == 0 {
                    base.clone()
                } else {
                    build_level(&work0, &zero_rows, ws[lu], hs[lv], &params, coverage)
                }
            })
            .collect();
        let mut levels = Vec::with_capacity(hs.len());
        for _ in 0..hs.len() {
            let row: Vec<Texture> = flat.drain(..ws.len()).collect();
            levels.push(
                row.into_iter()
                    .map(|t| Pyramid::single_level(t, params))
                    .collect(),
            );
        }
        Ok(Self { levels, params })
    }

    /// A ripmap from stored levels, `levels[l_v][l_u]` (e.g. read back from files). The first
    /// level need not be the original `(0, 0)` and the last need not be 1 texel wide or high (a
    /// planner may keep only the levels a scene uses): lookups treat `levels[0][0]` as level
    /// `(0, 0)` and clamp to the last on each axis. Errors: no level, rows of unequal length, a
    /// texture of zero size or with a non-finite value, a level whose width is not the
    /// `l_u`-th halving (`max(1, ⌊n/2⌋)`) of `levels[0][0]`'s or whose height is not the
    /// `l_v`-th halving, another channel count ([`MipError::LevelSize`]), invalid parameters.
    /// Cost: one pass over the data.
    pub fn from_levels(levels: Vec<Vec<Texture>>, params: PyramidParams) -> Result<Self, MipError> {
        let first = levels
            .first()
            .and_then(|r| r.first())
            .ok_or(MipError::NoLevels)?;
        params.validate(first.channels)?;
        let nu = levels[0].len();
        let (ws, hs) = (halvings(first.width), halvings(first.height));
        let channels = first.channels;
        let mut rows = Vec::with_capacity(levels.len());
        for (lv, row) in levels.into_iter().enumerate() {
            let mut out = Vec::with_capacity(nu);
            if row.len() != nu {
                let t = row.first();
                return Err(MipError::LevelSize {
                    level: lv * nu,
                    got: t.map_or((0, 0, 0), |t| (t.width, t.height, t.channels)),
                    expected: (ws[0], hs.get(lv).copied().unwrap_or(1), channels),
                });
            }
            for (lu, t) in row.into_iter().enumerate() {
                let t = Texture::new(t.width, t.height, t.channels, t.data)?;
                let expected = (
                    ws.get(lu).copied().unwrap_or(1),
                    hs.get(lv).copied().unwrap_or(1),
                    channels,
                );
                let got = (t.width, t.height, t.channels);
                // Beyond the 1-texel level a halving would repeat 1: only one such level.
                if got != expected || lu >= ws.len() || lv >= hs.len() {
                    return Err(MipError::LevelSize {
                        level: lv * nu + lu,
                        got,
                        expected,
                    });
                }
                out.push(Pyramid::single_level(t, params));
            }
            rows.push(out);
        }
        Ok(Self {
            levels: rows,
            params,
        })
    }

    /// Level `(l_u, l_v)` (clamped to the last level on each axis).
    pub fn level(&self, lu: usize, lv: usize) -> &Texture {
        let row = &self.levels[lv.min(self.levels.len() - 1)];
        &row[lu.min(row.len() - 1)].levels()[0]
    }

    /// Number of levels along `u` and along `v`.
    pub fn level_counts(&self) -> (usize, usize) {
        (self.levels[0].len(), self.levels.len())
    }

    /// The parameters it was built with.
    pub fn params(&self) -> &PyramidParams {
        &self.params
    }

    /// Bytes of all levels at `bytes_per_channel` per stored channel.
    pub fn bytes(&self, bytes_per_channel: usize) -> usize {
        self.levels
            .iter()
            .flatten()
            .map(|p| p.bytes(bytes_per_channel))
            .sum()
    }

    /// Bilinear sample of level `(l_u, l_v)` at `(u, v)` into `out`.
    pub fn bilinear_into(&self, lu: usize, lv: usize, u: f64, v: f64, out: &mut [f32]) {
        let row = &self.levels[lv.min(self.levels.len() - 1)];
        row[lu.min(row.len() - 1)].bilinear_into(0, u, v, out);
    }

    /// Levels of detail `(λ_u, λ_v)` from the screen derivatives (module docs), unclamped.
    pub fn lod(&self, dudx: f64, dvdx: f64, dudy: f64, dvdy: f64) -> (f64, f64) {
        let t = self.level(0, 0);
        let du = t.width as f64 * dudx.abs().max(dudy.abs());
        let dv = t.height as f64 * dvdx.abs().max(dvdy.abs());
        (du.log2(), dv.log2())
    }

    /// Sample at levels of detail `(λ_u, λ_v)` (clamped, NaN read as 0), blending the four
    /// nearest levels; written into `out` (`channels` floats).
    pub fn sample_lod_into(&self, u: f64, v: f64, lod: (f64, f64), out: &mut [f32]) {
        let (nu, nv) = self.level_counts();
        let split = |l: f64, n: usize| {
            let l = if l.is_nan() {
                0.0
            } else {
                l.clamp(0.0, (n - 1) as f64)
            };
            let i = l.floor() as usize;
            (i, (l - i as f64) as f32)
        };
        let ((iu, fu), (iv, fv)) = (split(lod.0, nu), split(lod.1, nv));
        let c = out.len();
        let mut tmp = [0.0f32; 16];
        let mut tmp_vec;
        let buf: &mut [f32] = if c <= 16 {
            &mut tmp[..c]
        } else {
            tmp_vec = vec![0.0; c];
            &mut tmp_vec
        };
        out.iter_mut().for_each(|o| *o = 0.0);
        for (du, wu) in [(0, 1.0 - fu), (1, fu)] {
            for (dv, wv) in [(0, 1.0 - fv), (1, fv)] {
                let w = wu * wv;
                if w <= 0.0 {
                    continue;
                }
                self.bilinear_into(iu + du, iv + dv, u, v, buf);
                out.iter_mut()
                    .zip(buf.iter())
                    .for_each(|(o, x)| *o += w * x);
            }
        }
    }

    /// Anisotropic sample with the levels chosen from the derivatives (module docs).
    pub fn sample_grad(
        &self,
        u: f64,
        v: f64,
        dudx: f64,
        dvdx: f64,
        dudy: f64,
        dvdy: f64,
    ) -> Vec<f32> {
        let mut out = vec![0.0; self.level(0, 0).channels];
        self.sample_lod_into(u, v, self.lod(dudx, dvdx, dudy, dvdy), &mut out);
        out
    }
}
