//! The texel volume: premultiplied RGBA voxels, cubic voxels of edge `s`, periodic in `x` and `z`
//! (see the module conventions in [`crate::slices`]).

use glam::DVec3;

use super::{Axis, SliceError};

/// Largest opacity used when converting to extinction (`σ = −ln(1 − a)/s` stays finite).
pub(crate) const MAX_ALPHA: f64 = 1.0 - 1e-7;

/// A tileable texel volume (see the module conventions).
#[derive(Clone, Debug, PartialEq)]
pub struct TexelVolume {
    dims: [usize; 3],
    voxel: f64,
    rgba: Vec<[f32; 4]>,
    /// Per voxel `(x, y, z)`: the trilinear cell spanning voxels `{x, x+1} × {y, min(y+1, ny−1)}
    /// × {z, z+1}` (wrapped) is fully transparent, so [`TexelVolume::sample`] can skip it.
    empty_cell: Vec<bool>,
    /// A surface's opacity per voxel when crossed along `x`, `y` and `z` (a shell voxelisation:
    /// a leaf seen face on is opaque, edge on clear); `None` when it is the same along every
    /// axis, `rgba`'s alpha.
    axis_alpha: Option<Vec<[f32; 3]>>,
}

impl TexelVolume {
    /// A volume of `dims` voxels of edge `voxel` (world units) with premultiplied RGBA values,
    /// index `x + nx·(y + ny·z)`. Checks: non-zero dimensions, `rgba.len() = nx·ny·nz`, a finite
    /// positive voxel size, finite values with `a ∈ [0, 1]` and colour channels in `[0, a]`
    /// (premultiplied, colour ≤ 1), within `1e-5`.
    pub fn new(dims: [usize; 3], voxel: f64, rgba: Vec<[f32; 4]>) -> Result<Self, SliceError> {
        for (k, n) in dims.iter().enumerate() {
            if *n == 0 {
                return Err(SliceError::ZeroSize {
                    what: ["volume dims x", "volume dims y", "volume dims z"][k],
                });
            }
        }
        super::check_range(
            "voxel size",
            voxel,
            f64::MIN_POSITIVE,
            f64::MAX,
            "must be finite and positive",
        )?;
        let n = dims[0] * dims[1] * dims[2];
        if rgba.len() != n {
            return Err(SliceError::InvalidParameter {
                name: "voxel count",
                value: format!("{}", rgba.len()),
                reason: "must equal nx·ny·nz",
            });
        }
        const TOL: f32 = 1e-5;
        for (index, v) in rgba.iter().enumerate() {
            if v.iter().any(|c| !c.is_finite()) {
                return Err(SliceError::NonFinite {
                    what: "voxel value",
                    index,
                });
            }
            let a = v[3];
            if !(-TOL..=1.0 + TOL).contains(&a) || v[..3].iter().any(|c| *c < -TOL || *c > a + TOL)
            {
                return Err(SliceError::InvalidParameter {
                    name: "voxel value",
                    value: format!("{v:?} at index {index}"),
                    reason: "premultiplied RGBA needs 0 ≤ colour ≤ alpha ≤ 1",
                });
            }
        }
        let rgba: Vec<[f32; 4]> = rgba
            .into_iter()
            .map(|v| {
                let a = v[3].clamp(0.0, 1.0);
                [
                    v[0].clamp(0.0, a),
                    v[1].clamp(0.0, a),
                    v[2].clamp(0.0, a),
                    a,
                ]
            })
            .collect();
        let [nx, ny, nz] = dims;
        let empty_cell = (0..n)
            .map(|i| {
                let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
                [x, (x + 1) % nx].iter().all(|&a| {
                    [y, (y + 1).min(ny - 1)].iter().all(|&b| {
                        [z, (z + 1) % nz]
                            .iter()
                            .all(|&c| rgba[a + nx * (b + ny * c)][3] == 0.0)
                    })
                })
            })
            .collect();
        Ok(Self {
            dims,
            voxel,
            rgba,
            empty_cell,
            axis_alpha: None,
        })
    }

    /// The volume with an opacity per crossing axis (`[a_x, a_y, a_z]` per voxel, index as
    /// [`TexelVolume::rgba`]): the stacks along an axis are cut from [`TexelVolume::along`]
    /// that axis. For a surface voxelised as a shell, whose opacity depends on how a ray crosses
    /// it (docs/design.md §3.4); `rgba`'s alpha stays the isotropic opacity the ray-marched
    /// volume uses. Checks: one triple per voxel, each in `[0, 1]` within `1e-5`, and zero
    /// exactly where the voxel's alpha is zero (the colour comes from `rgba`).
    pub fn with_axis_alpha(mut self, axis_alpha: Vec<[f32; 3]>) -> Result<Self, SliceError> {
        if axis_alpha.len() != self.rgba.len() {
            return Err(SliceError::InvalidParameter {
                name: "axis alpha count",
                value: format!("{}", axis_alpha.len()),
                reason: "must equal nx·ny·nz",
            });
        }
        const TOL: f32 = 1e-5;
        for (index, (t, v)) in axis_alpha.iter().zip(&self.rgba).enumerate() {
            let bad_range = t
                .iter()
                .any(|a| !a.is_finite() || *a < -TOL || *a > 1.0 + TOL);
            let bad_support = (v[3] == 0.0) != t.iter().all(|a| *a <= 0.0);
            if bad_range || bad_support {
                return Err(SliceError::InvalidParameter {
                    name: "axis alpha",
                    value: format!("{t:?} at index {index} (alpha {})", v[3]),
                    reason: "needs 0 ≤ a ≤ 1 per axis, all zero exactly where alpha is zero",
                });
            }
        }
        self.axis_alpha = Some(
            axis_alpha
                .into_iter()
                .map(|t| t.map(|a| a.clamp(0.0, 1.0)))
                .collect(),
        );
        Ok(self)
    }

    /// Whether the opacity depends on the crossing axis ([`TexelVolume::with_axis_alpha`]).
    pub fn has_axis_alpha(&self) -> bool {
        self.axis_alpha.is_some()
    }

    /// The volume a stack along `axis` is cut from: itself, or, with an opacity per axis, the
    /// same colours at that axis's opacity (premultiplied again). Cost: a copy of the voxels
    /// when the opacity depends on the axis.
    pub fn along(&self, axis: Axis) -> std::borrow::Cow<'_, TexelVolume> {
        let Some(axis_alpha) = &self.axis_alpha else {
            return std::borrow::Cow::Borrowed(self);
        };
        let k = axis.index();
        let rgba = self
            .rgba
            .iter()
            .zip(axis_alpha)
            .map(|(v, t)| {
                let (a, b) = (v[3], t[k]);
                if a <= 0.0 {
                    [0.0; 4]
                } else {
                    let c = |x: f32| (x / a).min(1.0) * b;
                    [c(v[0]), c(v[1]), c(v[2]), b]
                }
            })
            .collect();
        let along = TexelVolume::new(self.dims, self.voxel, rgba)
            .expect("colours unpremultiplied and scaled by an opacity in [0, 1] stay valid");
        std::borrow::Cow::Owned(along)
    }

    /// Voxels along `x`, `y`, `z`.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Voxels along `axis`.
    pub fn len(&self, axis: Axis) -> usize {
        self.dims[axis.index()]
    }

    /// Voxel edge `s` (world units).
    pub fn voxel_size(&self) -> f64 {
        self.voxel
    }

    /// Size of the tile, `dims·s` (world units).
    pub fn extent(&self) -> DVec3 {
        DVec3::new(
            self.dims[0] as f64,
            self.dims[1] as f64,
            self.dims[2] as f64,
        ) * self.voxel
    }

    /// The voxels, premultiplied RGBA, index `x + nx·(y + ny·z)`.
    pub fn rgba(&self) -> &[[f32; 4]] {
        &self.rgba
    }

    /// Storage index of voxel `(x, y, z)`.
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// Voxel `(x, y, z)`.
    #[inline]
    pub fn get(&self, x: usize, y: usize, z: usize) -> [f32; 4] {
        self.rgba[self.index(x, y, z)]
    }

    /// Bytes at RGBA8.
    pub fn bytes_rgba8(&self) -> usize {
        4 * self.rgba.len()
    }

    /// Trilinear sample of the premultiplied RGBA field at `p` (world units), wrapped in `x` and
    /// `z`, clamped in `y` (the caller keeps `p.y` inside `[0, ny·s]`). Cost: 8 voxel reads.
    pub fn sample(&self, p: DVec3) -> [f64; 4] {
        let g = p / self.voxel - 0.5;
        let (fx, fy, fz) = (g.x.floor(), g.y.floor(), g.z.floor());
        let (tx, ty, tz) = (g.x - fx, g.y - fy, g.z - fz);
        let [nx, ny, nz] = self.dims;
        let wrap = |i: f64, n: usize| (i as i64).rem_euclid(n as i64) as usize;
        let xs = [wrap(fx, nx), wrap(fx + 1.0, nx)];
        let zs = [wrap(fz, nz), wrap(fz + 1.0, nz)];
        let clamp = |i: f64| (i.max(0.0) as usize).min(ny - 1);
        let ys = [clamp(fy), clamp(fy + 1.0)];
        let mut out = [0.0f64; 4];
        if self.empty_cell[self.index(xs[0], ys[0], zs[0])] {
            return out;
        }
        for (a, wz) in [(0, 1.0 - tz), (1, tz)] {
            for (b, wy) in [(0, 1.0 - ty), (1, ty)] {
                for (c, wx) in [(0, 1.0 - tx), (1, tx)] {
                    let w = wx * wy * wz;
                    if w == 0.0 {
                        continue;
                    }
                    let v = self.get(xs[c], ys[b], zs[a]);
                    for k in 0..4 {
                        out[k] += w * f64::from(v[k]);
                    }
                }
            }
        }
        out
    }
}

impl TexelVolume {
    /// The voxel containing `p` (world units; box reconstruction), wrapped in `x` and `z`,
    /// clamped in `y`. Cost: one voxel read.
    pub fn sample_nearest(&self, p: DVec3) -> [f64; 4] {
        let g = p / self.voxel;
        let [nx, ny, nz] = self.dims;
        let wrap = |i: f64, n: usize| (i.floor() as i64).rem_euclid(n as i64) as usize;
        let y = (g.y.floor().max(0.0) as usize).min(ny - 1);
        self.get(wrap(g.x, nx), y, wrap(g.z, nz)).map(f64::from)
    }
}

/// How the voxels (and the slice texels) are reconstructed between their centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum SliceReconstruction {
    /// Trilinear in the volume, bilinear within a slice (as a GPU's linear filtering).
    #[default]
    Linear,
    /// Box: each voxel (texel) constant over its cell (a GPU's nearest filtering). Compositing
    /// commutes with it, so merged slices are exact straight on.
    Nearest,
}

/// Opacity of a path of `ratio` times the reference thickness through material of opacity `a`
/// (for the reference thickness): `1 − (1 − a)^ratio`, with `a` capped at [`MAX_ALPHA`].
#[inline]
pub(crate) fn alpha_for_thickness(a: f64, ratio: f64) -> f64 {
    if a <= 0.0 {
        return 0.0;
    }
    1.0 - (1.0 - a.min(MAX_ALPHA)).powf(ratio)
}

/// A premultiplied RGBA value re-expressed for `ratio` times its thickness: alpha by
/// [`alpha_for_thickness`], colour scaled by the same factor (the emitted colour is unchanged).
#[inline]
pub(crate) fn rescale_thickness(v: [f64; 4], ratio: f64) -> [f64; 4] {
    let a = v[3];
    if a <= 0.0 {
        return [0.0; 4];
    }
    let a2 = alpha_for_thickness(a, ratio);
    let f = a2 / a;
    [v[0] * f, v[1] * f, v[2] * f, a2]
}

/// `front over back` for premultiplied RGBA.
#[inline]
pub(crate) fn over(front: [f64; 4], back: [f64; 4]) -> [f64; 4] {
    let t = 1.0 - front[3];
    std::array::from_fn(|k| front[k] + t * back[k])
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// Two slabs of thickness ratios `r1` and `r2` of one material composite to one slab of
    /// `r1 + r2`, colour included; `over` is associative.
    #[test]
    fn thickness_rescaling_composes_and_over_associates() {
        let v = [0.3, 0.2, 0.1, 0.6];
        for (r1, r2) in [(0.5, 1.5), (1.0, 1.0), (3.0, 0.25)] {
            let a = over(rescale_thickness(v, r1), rescale_thickness(v, r2));
            let b = rescale_thickness(v, r1 + r2);
            for k in 0..4 {
                assert_abs_diff_eq!(a[k], b[k], epsilon = 1e-12);
            }
        }
        let (x, y, z) = (
            [0.1, 0.0, 0.2, 0.3],
            [0.0, 0.4, 0.0, 0.5],
            [0.2, 0.2, 0.2, 0.9],
        );
        let (l, r) = (over(over(x, y), z), over(x, over(y, z)));
        for k in 0..4 {
            assert_abs_diff_eq!(l[k], r[k], epsilon = 1e-12);
        }
        assert_eq!(rescale_thickness([0.0; 4], 2.0), [0.0; 4]);
        assert!(alpha_for_thickness(1.0, 1e9) <= 1.0);
    }

    /// The trilinear sample reproduces the voxel values at voxel centres and wraps in x and z.
    #[test]
    fn sample_hits_voxel_centres_and_wraps() {
        let rgba: Vec<[f32; 4]> = (0..8)
            .map(|i| {
                let a = 0.1 * (i + 1) as f32;
                [0.5 * a, 0.0, 0.0, a]
            })
            .collect();
        let vol = TexelVolume::new([2, 2, 2], 0.5, rgba).unwrap();
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..2 {
                    let c = (DVec3::new(x as f64, y as f64, z as f64) + 0.5) * 0.5;
                    let v = vol.get(x, y, z);
                    for shift in [DVec3::ZERO, DVec3::new(1.0, 0.0, -1.0)] {
                        let s = vol.sample(c + shift);
                        assert_abs_diff_eq!(s[3], f64::from(v[3]), epsilon = 1e-6);
                        let n = vol.sample_nearest(c + shift);
                        assert_abs_diff_eq!(n[3], f64::from(v[3]), epsilon = 1e-6);
                    }
                }
            }
        }
    }

    /// An opacity per axis: checked (count, range, zero exactly where the voxel is empty), and
    /// each axis's volume keeps the voxel's colour at that axis's opacity.
    #[test]
    fn axis_alpha_is_checked_and_recolours_per_axis() {
        let rgba = vec![[0.25, 0.125, 0.0, 0.5], [0.0; 4]];
        let vol = || TexelVolume::new([2, 1, 1], 0.5, rgba.clone()).unwrap();
        for bad in [
            vec![[0.5; 3]],
            vec![[0.5, 1.5, 0.5], [0.0; 3]],
            vec![[0.5, f32::NAN, 0.5], [0.0; 3]],
            vec![[0.0; 3], [0.0; 3]],
            vec![[0.5; 3], [0.0, 0.1, 0.0]],
        ] {
            assert!(vol().with_axis_alpha(bad).is_err());
        }
        assert!(!vol().has_axis_alpha());
        let v = vol()
            .with_axis_alpha(vec![[1.0, 0.0, 0.25], [0.0; 3]])
            .unwrap();
        assert!(v.has_axis_alpha());
        // Unpremultiplied colour (0.5, 0.25, 0) at alpha 1, 0 and 0.25.
        assert_eq!(v.along(Axis::X).get(0, 0, 0), [0.5, 0.25, 0.0, 1.0]);
        assert_eq!(v.along(Axis::Y).get(0, 0, 0), [0.0; 4]);
        assert_eq!(v.along(Axis::Z).get(0, 0, 0), [0.125, 0.0625, 0.0, 0.25]);
        assert_eq!(v.along(Axis::Z).get(1, 0, 0), [0.0; 4]);
        // Without one, every axis is the volume itself.
        assert_eq!(*vol().along(Axis::Y), vol());
    }
}
