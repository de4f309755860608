//! Merged slices fitted to the bilinear filter that draws them (docs/design.md §9.5).
//!
//! A merged slice composites `2^k` layers per texel. Read at a texel centre it is exact; read
//! between centres, bilinear filtering interpolates the composites, while the volume it stands
//! for composites the interpolated layers — and compositing is not linear, so the two differ
//! (a strand present in one layer and absent from the next is interpolated to a smaller opacity
//! in the volume than in the filtered composite). The fit replaces the composites by the texels
//! whose **bilinear reconstruction** is closest, in least squares over `Q × Q` positions per
//! texel, to the slab composited from the bilinearly read layers at those positions (straight
//! on, the view every merge level is drawn closest to). Bilinear reconstruction is linear in
//! the texels and separable, so the normal equations are `B_u · X · B_v = Φ_uᵀ · F · Φ_v` with
//! the small symmetric positive-definite `B = ΦᵀΦ` of each direction (tridiagonal, with corners
//! when the slice wraps): one Cholesky inverse per direction and stack, then two matrix products
//! per slice and channel. The fitted values are clamped to a valid premultiplied colour
//! (`0 ≤ a ≤ 1`, `0 ≤ c ≤ a`). A stack keeps its fitted slices only where they draw it closer to
//! its layers straight on than the composites do ([`StackChoice`]): each slab is fitted alone,
//! but a picture composites them.
//!
//! Cost per slice of a `w × h` plane and `g` layers: `2·Q²·w·h·g` bilinear reads of the layers,
//! plus `4·(w²·h + w·h²)` multiply-adds for the products.

use nalgebra::DMatrix;
use rayon::prelude::*;

use super::merge::{MergeRule, Side, merge_column};
use super::{SliceError, TexelVolume};
use crate::mip::WrapMode;
use crate::pyramid::filter::wrap_index;

/// Fitting positions per texel along each slice direction (at `(m + ½)/Q` of the texel).
pub(crate) const Q: usize = 4;

/// One direction of a slice: the bilinear taps of every fitting position and the inverse of
/// the normal matrix `ΦᵀΦ`.
pub(crate) struct Direction {
    taps: Vec<[(usize, f64); 2]>,
    inverse: DMatrix<f64>,
}

impl Direction {
    /// The taps of `n` texels read with `wrap` at `Q·n` positions, and `(ΦᵀΦ)⁻¹`.
    /// Errors: a normal matrix that is not positive definite (cannot happen for `n ≥ 1`: every
    /// texel is the nearer tap of some position).
    pub(crate) fn new(n: usize, wrap: WrapMode) -> Result<Self, SliceError> {
        let mut taps = Vec::with_capacity(n * Q);
        let mut normal = DMatrix::<f64>::zeros(n, n);
        for f in 0..n * Q {
            let t = (f as f64 + 0.5) / Q as f64 - 0.5;
            let i0 = t.floor();
            let frac = t - i0;
            let tap = [
                (wrap_index(wrap, i0 as i64, n), 1.0 - frac),
                (wrap_index(wrap, i0 as i64 + 1, n), frac),
            ];
            for (p, wp) in tap {
                for (q, wq) in tap {
                    normal[(p, q)] += wp * wq;
                }
            }
            taps.push(tap);
        }
        let inverse = normal
            .cholesky()
            .ok_or(SliceError::InvalidParameter {
                name: "slice fit",
                value: format!("{n} texels"),
                reason: "the bilinear normal matrix must be positive definite",
            })?
            .inverse();
        Ok(Self { taps, inverse })
    }

    /// Fitting positions along this direction.
    pub(crate) fn taps_len(&self) -> usize {
        self.taps.len()
    }
}

/// The target of the fit: the slab of `layers` (voxel indices along `axis`, lowest first) of
/// `volume` composited under `rule` for `side` from its bilinearly read layers, at every fitting
/// position (row-major: `v` positions outer, `u` positions inner). Rows in parallel.
pub(crate) fn slab_target(
    volume: &TexelVolume,
    axis: super::Axis,
    layers: std::ops::Range<usize>,
    (rule, side): (MergeRule, Side),
    (du, dv): (&Direction, &Direction),
) -> Vec<[f64; 4]> {
    let (ua, va) = axis.plane_axes();
    let (w, h) = (du.inverse.nrows(), dv.inverse.nrows());
    let g = layers.len();
    // The layers' texels, gathered once: layer l, texel (u, v).
    let mut planes = vec![[0.0f64; 4]; g * w * h];
    for (l, layer) in layers.enumerate() {
        for v in 0..h {
            for u in 0..w {
                let mut c = [0usize; 3];
                c[ua] = u;
                c[va] = v;
                c[axis.index()] = layer;
                planes[(l * h + v) * w + u] = volume.get(c[0], c[1], c[2]).map(f64::from);
            }
        }
    }
    let mut target = vec![[0.0f64; 4]; du.taps.len() * dv.taps.len()];
    target
        .par_chunks_mut(du.taps.len())
        .zip(&dv.taps)
        .for_each(|(row, tv)| {
            let mut column = vec![[0.0f64; 4]; g];
            for (out, tu) in row.iter_mut().zip(&du.taps) {
                for (l, value) in column.iter_mut().enumerate() {
                    let mut acc = [0.0f64; 4];
                    for &(v, wv) in tv {
                        for &(u, wu) in tu {
                            let texel = planes[(l * h + v) * w + u];
                            for k in 0..4 {
                                acc[k] += wu * wv * texel[k];
                            }
                        }
                    }
                    *value = acc;
                }
                *out = merge_column(&column, rule, side);
            }
        });
    target
}

/// The texels (`w × h × 4`, row-major in `u`) whose bilinear reconstruction is closest in least
/// squares to `target` at the fitting positions, clamped to a valid premultiplied colour.
pub(crate) fn fit_target(target: &[[f64; 4]], (du, dv): (&Direction, &Direction)) -> Vec<f32> {
    let (w, h) = (du.inverse.nrows(), dv.inverse.nrows());
    // The right-hand side Φ_uᵀ F Φ_v per channel.
    let mut rhs = [(); 4].map(|_| DMatrix::<f64>::zeros(w, h));
    for (row, tv) in target.chunks_exact(du.taps.len()).zip(&dv.taps) {
        for (f, tu) in row.iter().zip(&du.taps) {
            for &(v, wv) in tv {
                for &(u, wu) in tu {
                    for k in 0..4 {
                        rhs[k][(u, v)] += wu * wv * f[k];
                    }
                }
            }
        }
    }
    let fitted = rhs.map(|r| &du.inverse * r * &dv.inverse);
    let mut out = Vec::with_capacity(w * h * 4);
    for v in 0..h {
        for u in 0..w {
            let a = fitted[3][(u, v)].clamp(0.0, 1.0);
            for channel in &fitted[..3] {
                out.push(channel[(u, v)].clamp(0.0, a) as f32);
            }
            out.push(a as f32);
        }
    }
    out
}

/// The bilinear reconstruction of `texels` (`w × h × 4`, row-major in `u`) at every fitting
/// position, in the order of [`slab_target`]. Rows in parallel.
pub(crate) fn reconstruct(texels: &[f32], (du, dv): (&Direction, &Direction)) -> Vec<[f64; 4]> {
    let w = du.inverse.nrows();
    let mut out = vec![[0.0f64; 4]; du.taps.len() * dv.taps.len()];
    out.par_chunks_mut(du.taps.len())
        .zip(&dv.taps)
        .for_each(|(row, tv)| {
            for (o, tu) in row.iter_mut().zip(&du.taps) {
                let mut acc = [0.0f64; 4];
                for &(v, wv) in tv {
                    for &(u, wu) in tu {
                        let t = &texels[(v * w + u) * 4..][..4];
                        for c in 0..4 {
                            acc[c] += wu * wv * f64::from(t[c]);
                        }
                    }
                }
                *o = acc;
            }
        });
    out
}

/// Straight-on composites at the fitting positions, front to back, of a stack's target slabs,
/// of its fitted slices and of its composites: whether the fit draws the stack closer to its
/// layers than the composites do (docs/design.md §9.5).
pub(crate) struct StackChoice {
    target: Vec<[f64; 4]>,
    fitted: Vec<[f64; 4]>,
    composites: Vec<[f64; 4]>,
    row: usize,
}

impl StackChoice {
    /// Nothing composited yet; fitting positions in rows of `row`, `n` in all.
    pub(crate) fn new(row: usize, n: usize) -> Self {
        Self {
            target: vec![[0.0; 4]; n],
            fitted: vec![[0.0; 4]; n],
            composites: vec![[0.0; 4]; n],
            row,
        }
    }

    /// Adds the next slab behind the ones already added: its target and the reconstructions of
    /// its fitted slice and of its composites.
    pub(crate) fn add(
        &mut self,
        target: &[[f64; 4]],
        fitted: &[[f64; 4]],
        composites: &[[f64; 4]],
    ) {
        let under = |acc: &mut [f64; 4], x: [f64; 4]| {
            let t = 1.0 - acc[3];
            for k in 0..4 {
                acc[k] += t * x[k];
            }
        };
        for i in 0..target.len() {
            under(&mut self.target[i], target[i]);
            under(&mut self.fitted[i], fitted[i]);
            under(&mut self.composites[i], composites[i]);
        }
    }

    /// Whether the fitted slices' composite is closer to the layers' than the composites', in
    /// squared error of the means over each texel's `Q × Q` positions (a pixel of one texel, what
    /// a picture of the stack averages). Ties keep the fit.
    pub(crate) fn fit_is_better(&self) -> bool {
        let row = self.row;
        let (w, h) = (row / Q, self.target.len() / row / Q);
        let (e_fit, e_comp) = (0..w * h)
            .into_par_iter()
            .map(|texel| {
                let (tu, tv) = (texel % w, texel / w);
                let mut sums = [[0.0f64; 4]; 3];
                for fv in tv * Q..(tv + 1) * Q {
                    for fu in tu * Q..(tu + 1) * Q {
                        let i = fv * row + fu;
                        let images = [&self.target, &self.fitted, &self.composites];
                        for (sum, image) in sums.iter_mut().zip(images) {
                            for (s, x) in sum.iter_mut().zip(image[i]) {
                                *s += x;
                            }
                        }
                    }
                }
                let d = |s: [f64; 4]| -> f64 { (0..4).map(|k| (s[k] - sums[0][k]).powi(2)).sum() };
                (d(sums[1]), d(sums[2]))
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        e_fit <= e_comp
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_one_layer_slab_targets_its_own_reconstruction() {
        let n = 8;
        let rgba: Vec<[f32; 4]> = (0..n * n * n)
            .map(|i| {
                let a = ((i * 37) % 11) as f32 / 10.0;
                [0.3 * a, 0.5 * a, 0.1 * a, a]
            })
            .collect();
        let vol = TexelVolume::new([n; 3], 1.0 / n as f64, rgba).unwrap();
        let d = Direction::new(n, WrapMode::Repeat).unwrap();
        for axis in super::super::Axis::ALL {
            let (ua, va) = axis.plane_axes();
            // The texels of voxel layer `k` along the axis, as a slice stores them.
            let layer = |k: usize| -> Vec<f32> {
                let mut texels = Vec::new();
                for v in 0..n {
                    for u in 0..n {
                        let mut c = [0; 3];
                        c[ua] = u;
                        c[va] = v;
                        c[axis.index()] = k;
                        texels.extend(vol.get(c[0], c[1], c[2]));
                    }
                }
                texels
            };
            let t = slab_target(&vol, axis, 3..4, (MergeRule::PerSide, Side::Plus), (&d, &d));
            let r = reconstruct(&layer(3), (&d, &d));
            let worst = t
                .iter()
                .zip(&r)
                .map(|(a, b)| (0..4).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max))
                .fold(0.0, f64::max);
            assert!(worst < 1e-6, "{axis:?}: {worst}");
            // Two layers: the upper one's reconstruction over the lower one's.
            let t2 = slab_target(&vol, axis, 2..4, (MergeRule::PerSide, Side::Plus), (&d, &d));
            let r2 = reconstruct(&layer(2), (&d, &d));
            let worst = t2
                .iter()
                .zip(r.iter().zip(&r2))
                .map(|(a, (top, low))| {
                    let o = crate::slices::volume::over(*top, *low);
                    (0..4).map(|k| (a[k] - o[k]).abs()).fold(0.0, f64::max)
                })
                .fold(0.0, f64::max);
            assert!(worst < 1e-6, "{axis:?} two layers: {worst}");
        }
    }
}
