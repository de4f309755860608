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
//! (`0 ≤ a ≤ 1`, `0 ≤ c ≤ a`).
//!
//! Cost per slice of a `w × h` plane and `g` layers: `Q²·w·h·g` bilinear reads of the layers,
//! plus `4·(w²·h + w·h²)` multiply-adds for the products.

use nalgebra::DMatrix;

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
}

/// The fitted level-0 texels (`w × h × 4`, row-major in `u`) of the slice that merges the
/// `layers` (voxel indices along `axis`, lowest first) of `volume` under `rule` for `side`.
pub(crate) fn fit_slice(
    volume: &TexelVolume,
    axis: super::Axis,
    layers: std::ops::Range<usize>,
    (rule, side): (MergeRule, Side),
    (du, dv): (&Direction, &Direction),
    composites: Vec<f32>,
) -> Vec<f32> {
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
    // The target F at every fitting position, and the right-hand side Φ_uᵀ F Φ_v per channel.
    let mut rhs = [(); 4].map(|_| DMatrix::<f64>::zeros(w, h));
    let mut column = vec![[0.0f64; 4]; g];
    let mut target = Vec::with_capacity(du.taps.len() * dv.taps.len());
    for tv in &dv.taps {
        for tu in &du.taps {
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
            let f = merge_column(&column, rule, side);
            target.push(f);
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
    // The clamp can undo the fit near sharp opaque edges (a height field's surface): keep the
    // composites where they are closer to the target over the fitting positions.
    let error = |texels: &[f32]| {
        let mut sum = 0.0f64;
        let mut k = 0;
        for tv in &dv.taps {
            for tu in &du.taps {
                let mut acc = [0.0f64; 4];
                for &(v, wv) in tv {
                    for &(u, wu) in tu {
                        let t = &texels[(v * w + u) * 4..][..4];
                        for c in 0..4 {
                            acc[c] += wu * wv * f64::from(t[c]);
                        }
                    }
                }
                sum += (0..4).map(|c| (acc[c] - target[k][c]).powi(2)).sum::<f64>();
                k += 1;
            }
        }
        sum
    };
    if error(&out) <= error(&composites) {
        out
    } else {
        composites
    }
}
