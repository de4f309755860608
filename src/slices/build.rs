//! Builders of texel volumes (Meyer & Neyret 1998, §3): a height field (grey image or cyclic Perlin
//! noise; columns filled to the height, shading from the gradient normal), an implicit function
//! (evaluated per voxel), a data-gen shape (voxelised by [`altrep_data_gen::voxelize`], the
//! interior filled with the colour of the boundary so that nothing looks hollow at oblique
//! views), and the four test tiles of the measurements ([`test_tile`]).
//!
//! Every builder bakes diffuse lighting (`albedo·(ambient + (1 − ambient)·max(0, n·l))`, data-gen's
//! [`Light`]) and makes the volume periodic in `x` and `z`.

use std::collections::VecDeque;

use altrep_data_gen::{
    Fill, Light, Shape, SplitMix64, Supersample, VoxelParams, scene_shape, voxelize,
};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{SliceError, TexelVolume};

/// Baked lighting shared by the builders.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SliceLighting {
    /// Direction toward the light (normalised on use).
    pub direction: [f32; 3],
    /// Ambient share in `[0, 1]`.
    pub ambient: f32,
}

impl Default for SliceLighting {
    /// data-gen's default light: from `(0.5, 0.8, 0.35)`, ambient 0.3.
    fn default() -> Self {
        let l = Light::default();
        Self {
            direction: l.direction.to_array(),
            ambient: l.ambient,
        }
    }
}

impl SliceLighting {
    fn light(&self) -> Result<Light, SliceError> {
        let d = Vec3::from_array(self.direction);
        if !d.is_finite() || d.length_squared() < 1e-12 {
            return Err(SliceError::InvalidParameter {
                name: "light direction",
                value: format!("{:?}", self.direction),
                reason: "must be finite and non-zero",
            });
        }
        super::check_range("ambient", f64::from(self.ambient), 0.0, 1.0, "in [0, 1]")?;
        Ok(Light {
            direction: d.normalize(),
            ambient: self.ambient,
        })
    }
}

fn check_grid(dims: [usize; 3], voxel: f64) -> Result<(), SliceError> {
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
        "finite and > 0",
    )
}

/// A height field: heights as fractions of the tile height `ny·s`, in `[0, 1]`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum HeightField {
    /// A grey image, row-major, `width × height` values in `[0, 1]`, sampled bilinearly and
    /// periodically at the column centres (image `u` along `x`, `v` along `z`).
    Image {
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
        /// Heights.
        values: Vec<f32>,
    },
    /// Cyclic Perlin noise ([`perlin_periodic`]): `base + amplitude·noise`, clamped to `[0, 1]`.
    Perlin {
        /// Lattice cells per tile of the first octave.
        cells: usize,
        /// Octaves (each twice the frequency, half the amplitude).
        octaves: usize,
        /// Seed of the gradients.
        seed: u64,
        /// Mean height.
        base: f64,
        /// Scale of the noise (about `[−0.7, 0.7]` before scaling).
        amplitude: f64,
    },
}

/// Parameters of [`from_height_field`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeightFieldParams {
    /// Voxels along `x, y, z`.
    pub dims: [usize; 3],
    /// Voxel edge (world units).
    pub voxel: f64,
    /// Linear RGB albedo of the ground.
    pub albedo: [f32; 3],
    /// Baked light.
    pub lighting: SliceLighting,
}

impl Default for HeightFieldParams {
    /// 32³ voxels of 1/32 (a unit tile), earthy albedo, default light.
    fn default() -> Self {
        Self {
            dims: [32; 3],
            voxel: 1.0 / 32.0,
            albedo: [0.55, 0.45, 0.3],
            lighting: SliceLighting::default(),
        }
    }
}

/// Hash of lattice point `(i, j)` of octave `o` to a gradient angle.
fn lattice_angle(seed: u64, o: usize, i: i64, j: i64) -> f64 {
    let mut h = seed ^ 0x9E37_79B9_7F4A_7C15;
    for x in [o as u64, i as u64, j as u64] {
        h = (h ^ x).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 29;
    }
    (h >> 11) as f64 / (1u64 << 53) as f64 * std::f64::consts::TAU
}

/// Cyclic 2D Perlin gradient noise at `(u, v)` (tile coordinates, period 1 in both): the sum of
/// `octaves` octaves, octave `o` on a lattice of `cells·2^o` cells per tile with amplitude `2^−o`.
/// Gradients are unit vectors of hashed angles; the quintic fade `6t⁵ − 15t⁴ + 10t³`. Values
/// lie in about `[−0.7, 0.7]·(2 − 2^(1−octaves))`. At most 24 octaves and `2^30` cells are
/// used (larger values are clamped); zero cells give 0.
pub fn perlin_periodic(u: f64, v: f64, cells: usize, octaves: usize, seed: u64) -> f64 {
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let mut sum = 0.0;
    let cells = cells.min(1 << 30) as i64;
    if cells == 0 || !u.is_finite() || !v.is_finite() {
        return 0.0;
    }
    for o in 0..octaves.min(24) {
        let p = cells << o;
        let (u, v) = (u.rem_euclid(1.0), v.rem_euclid(1.0));
        let (x, y) = (u * p as f64, v * p as f64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (i0, j0) = (x0 as i64, y0 as i64);
        let corner = |di: i64, dj: i64| {
            let a = lattice_angle(seed, o, (i0 + di).rem_euclid(p), (j0 + dj).rem_euclid(p));
            a.cos() * (fx - di as f64) + a.sin() * (fy - dj as f64)
        };
        let (sx, sy) = (fade(fx), fade(fy));
        let a = corner(0, 0) + sx * (corner(1, 0) - corner(0, 0));
        let b = corner(0, 1) + sx * (corner(1, 1) - corner(0, 1));
        sum += (a + sy * (b - a)) / (1u64 << o) as f64;
    }
    sum
}

/// Builds a texel from a height field: column `(x, z)` of height fraction `f` has opacity
/// `clamp(f·ny − y, 0, 1)` in voxel `y` (the top voxel partly covered) and every voxel of the
/// column carries the shaded colour of its top, the normal from the periodic central-difference
/// gradient of the heights. Cost: `nx·nz` height evaluations, `nx·ny·nz` writes.
///
/// Errors: zero sizes, a NaN or out-of-range height, image size mismatch, bad light.
pub fn from_height_field(
    field: &HeightField,
    params: &HeightFieldParams,
) -> Result<TexelVolume, SliceError> {
    check_grid(params.dims, params.voxel)?;
    let light = params.lighting.light()?;
    let [nx, ny, nz] = params.dims;
    let heights: Vec<f64> = match field {
        HeightField::Image {
            width,
            height,
            values,
        } => {
            let (w, h) = (*width, *height);
            if w == 0 || h == 0 {
                return Err(SliceError::ZeroSize {
                    what: "height image size",
                });
            }
            if values.len() != w * h {
                return Err(SliceError::InvalidParameter {
                    name: "height image",
                    value: format!("{} values", values.len()),
                    reason: "must hold width × height values",
                });
            }
            if let Some(index) = values.iter().position(|x| !x.is_finite()) {
                return Err(SliceError::NonFinite {
                    what: "height",
                    index,
                });
            }
            if let Some(index) = values.iter().position(|x| !(0.0..=1.0).contains(x)) {
                return Err(SliceError::InvalidParameter {
                    name: "height",
                    value: format!("{} at index {index}", values[index]),
                    reason: "heights are fractions of the tile height in [0, 1]",
                });
            }
            let at = |i: i64, j: i64| {
                f64::from(
                    values[(j.rem_euclid(h as i64) * w as i64 + i.rem_euclid(w as i64)) as usize],
                )
            };
            (0..nx * nz)
                .map(|c| {
                    let (x, z) = (c % nx, c / nx);
                    let s = (x as f64 + 0.5) / nx as f64 * w as f64 - 0.5;
                    let t = (z as f64 + 0.5) / nz as f64 * h as f64 - 0.5;
                    let (i0, j0) = (s.floor(), t.floor());
                    let (fx, fy) = (s - i0, t - j0);
                    let (i0, j0) = (i0 as i64, j0 as i64);
                    let a = at(i0, j0) * (1.0 - fx) + at(i0 + 1, j0) * fx;
                    let b = at(i0, j0 + 1) * (1.0 - fx) + at(i0 + 1, j0 + 1) * fx;
                    a * (1.0 - fy) + b * fy
                })
                .collect()
        }
        HeightField::Perlin {
            cells,
            octaves,
            seed,
            base,
            amplitude,
        } => {
            if *cells == 0 || *octaves == 0 {
                return Err(SliceError::ZeroSize {
                    what: "Perlin cells or octaves",
                });
            }
            if *octaves > 16 {
                return Err(SliceError::InvalidParameter {
                    name: "Perlin octaves",
                    value: format!("{octaves}"),
                    reason: "at most 16",
                });
            }
            super::check_range("Perlin base", *base, 0.0, 1.0, "in [0, 1]")?;
            super::check_range(
                "Perlin amplitude",
                *amplitude,
                -1e3,
                1e3,
                "finite, |a| ≤ 1000",
            )?;
            (0..nx * nz)
                .into_par_iter()
                .map(|c| {
                    let (x, z) = (c % nx, c / nx);
                    let u = (x as f64 + 0.5) / nx as f64;
                    let v = (z as f64 + 0.5) / nz as f64;
                    (base + amplitude * perlin_periodic(u, v, *cells, *octaves, *seed))
                        .clamp(0.0, 1.0)
                })
                .collect()
        }
    };
    let s = params.voxel;
    let tile_h = ny as f64 * s;
    let hgt = |x: i64, z: i64| {
        heights[(z.rem_euclid(nz as i64) * nx as i64 + x.rem_euclid(nx as i64)) as usize] * tile_h
    };
    let albedo = Vec3::from_array(params.albedo);
    let colours: Vec<[f32; 3]> = (0..nx * nz)
        .map(|c| {
            let (x, z) = ((c % nx) as i64, (c / nx) as i64);
            let dhdx = (hgt(x + 1, z) - hgt(x - 1, z)) / (2.0 * s);
            let dhdz = (hgt(x, z + 1) - hgt(x, z - 1)) / (2.0 * s);
            let n = DVec3::new(-dhdx, 1.0, -dhdz).normalize().as_vec3();
            light.shade(albedo, n).min(Vec3::ONE).to_array()
        })
        .collect();
    let mut rgba = vec![[0.0f32; 4]; nx * ny * nz];
    rgba.par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(z, slab)| {
            for y in 0..ny {
                for x in 0..nx {
                    let c = z * nx + x;
                    let a = (heights[c] * ny as f64 - y as f64).clamp(0.0, 1.0) as f32;
                    let col = colours[c];
                    slab[x + nx * y] = [col[0] * a, col[1] * a, col[2] * a, a];
                }
            }
        });
    TexelVolume::new(params.dims, params.voxel, rgba)
}

/// Parameters of [`from_implicit`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImplicitParams {
    /// Voxels along `x, y, z`.
    pub dims: [usize; 3],
    /// Voxel edge (world units).
    pub voxel: f64,
    /// Sign tests per voxel edge for the coverage ([`Supersample`]: `k³` per voxel).
    pub supersample: Supersample,
    /// A Lipschitz bound `K` of `f` when known (`|f(p) − f(q)| ≤ K·|p − q|`, `K = 1` for a
    /// signed distance): voxels with `|f(centre)| > K·(√3/2)·s` are wholly in or out and skip
    /// the sub-samples. `None` samples every voxel.
    pub lipschitz: Option<f64>,
    /// Take the minimum over the nine periodic images of `f` (`false` when `f` is periodic in
    /// `x` and `z` already: nine times faster).
    pub periodic_images: bool,
    /// Baked light.
    pub lighting: SliceLighting,
}

impl Default for ImplicitParams {
    /// 32³ voxels of 1/32, 3³ sub-samples, no Lipschitz bound, periodic images, default light.
    fn default() -> Self {
        Self {
            dims: [32; 3],
            voxel: 1.0 / 32.0,
            supersample: Supersample::of(3),
            lipschitz: None,
            periodic_images: true,
            lighting: SliceLighting::default(),
        }
    }
}

/// Colours the filled voxels: boundary voxels (partly covered, or next to a voxel that is not
/// fully covered) get `lit(index)`; interior voxels get the colour of the nearest boundary voxel
/// (breadth-first through filled voxels, periodic in `x` and `z`). Returns premultiplied RGBA.
fn fill_interior(
    dims: [usize; 3],
    coverage: &[f32],
    lit: impl Fn(usize) -> [f32; 3] + Sync,
) -> Vec<[f32; 4]> {
    let [nx, ny, nz] = dims;
    let neighbours = |idx: usize| {
        let (x, y, z) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
        let mut out = [None; 6];
        out[0] = Some((x + 1) % nx + nx * (y + ny * z));
        out[1] = Some((x + nx - 1) % nx + nx * (y + ny * z));
        out[2] = Some(x + nx * (y + ny * ((z + 1) % nz)));
        out[3] = Some(x + nx * (y + ny * ((z + nz - 1) % nz)));
        out[4] = (y + 1 < ny).then(|| x + nx * (y + 1 + ny * z));
        out[5] = (y > 0).then(|| x + nx * (y - 1 + ny * z));
        out
    };
    let n = coverage.len();
    let boundary: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| {
            coverage[i] > 0.0
                && (coverage[i] < 1.0
                    || neighbours(i)
                        .iter()
                        .any(|nb| nb.is_none_or(|j| coverage[j] < 1.0)))
        })
        .collect();
    let mut colour: Vec<Option<[f32; 3]>> = (0..n)
        .into_par_iter()
        .map(|i| boundary[i].then(|| lit(i)))
        .collect();
    let mut queue: VecDeque<usize> = (0..n).filter(|i| boundary[*i]).collect();
    while let Some(i) = queue.pop_front() {
        let c = colour[i];
        for j in neighbours(i).into_iter().flatten() {
            if coverage[j] > 0.0 && colour[j].is_none() {
                colour[j] = c;
                queue.push_back(j);
            }
        }
    }
    (0..n)
        .map(|i| {
            let a = coverage[i];
            let c = colour[i].unwrap_or_else(|| lit(i));
            [c[0] * a, c[1] * a, c[2] * a, a]
        })
        .collect()
}

/// Builds a texel from an implicit function `f` (inside where `f < 0`) made periodic in `x` and
/// `z` by taking the minimum over the nine images `p + (a·L_x, 0, c·L_z)`, `a, c ∈ {−1, 0, 1}`
/// (unless [`ImplicitParams::periodic_images`] is off).
/// Opacity is the share of `s³` sub-samples inside; the normal the normalised gradient of the
/// periodic `f` (central differences of a quarter voxel); the colour `albedo` at the image that
/// gives the minimum, shaded; the interior takes the colour of its nearest boundary voxel.
/// Cost: `9·s³` evaluations of `f` per voxel (9 where a Lipschitz bound proves the voxel wholly
/// in or out) plus 6 per boundary voxel; voxels in parallel.
///
/// Errors: zero sizes or sub-samples, bad light, `f` or `albedo` returning NaN.
pub fn from_implicit(
    f: &(dyn Fn(DVec3) -> f64 + Sync),
    albedo: &(dyn Fn(DVec3) -> [f32; 3] + Sync),
    params: &ImplicitParams,
) -> Result<TexelVolume, SliceError> {
    check_grid(params.dims, params.voxel)?;
    let light = params.lighting.light()?;
    if let Some(k) = params.lipschitz {
        super::check_range("Lipschitz bound", k, f64::MIN_POSITIVE, 1e6, "in (0, 1e6]")?;
    }
    let [nx, ny, nz] = params.dims;
    let s = params.voxel;
    let (lx, lz) = (nx as f64 * s, nz as f64 * s);
    let images: i32 = if params.periodic_images { 1 } else { 0 };
    let periodic = |p: DVec3| -> (f64, DVec3) {
        if images == 0 {
            return (f(p), p);
        }
        let mut best = (f64::INFINITY, p);
        for a in -1..=1 {
            for c in -1..=1 {
                let q = p + DVec3::new(a as f64 * lx, 0.0, c as f64 * lz);
                let v = f(q);
                if v < best.0 || v.is_nan() {
                    best = (v, q);
                }
            }
        }
        best
    };
    let ss = params.supersample.get();
    let n = nx * ny * nz;
    let coverage: Vec<f32> = (0..n)
        .into_par_iter()
        .map(|idx| {
            let (x, y, z) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
            let corner = DVec3::new(x as f64, y as f64, z as f64) * s;
            if let Some(k) = params.lipschitz {
                let fc = periodic(corner + 0.5 * s).0;
                if fc.abs() > k * 0.8661 * s {
                    return if fc < 0.0 { 1.0 } else { 0.0 };
                }
            }
            let mut inside = 0usize;
            let mut nan = false;
            for a in 0..ss {
                for b in 0..ss {
                    for c in 0..ss {
                        let o = (DVec3::new(a as f64, b as f64, c as f64) + 0.5) / ss as f64;
                        let v = periodic(corner + o * s).0;
                        nan |= v.is_nan();
                        inside += usize::from(v < 0.0);
                    }
                }
            }
            if nan {
                f32::NAN
            } else {
                inside as f32 / (ss * ss * ss) as f32
            }
        })
        .collect();
    if let Some(index) = coverage.iter().position(|c| c.is_nan()) {
        return Err(SliceError::NonFinite {
            what: "implicit function value",
            index,
        });
    }
    let centre = |i: usize| {
        DVec3::new(
            (i % nx) as f64 + 0.5,
            ((i / nx) % ny) as f64 + 0.5,
            (i / (nx * ny)) as f64 + 0.5,
        ) * s
    };
    let lit = |i: usize| -> [f32; 3] {
        let p = centre(i);
        let e = 0.25 * s;
        let mut g = DVec3::ZERO;
        for k in 0..3 {
            let mut d = DVec3::ZERO;
            d[k] = e;
            g[k] = periodic(p + d).0 - periodic(p - d).0;
        }
        let nrm = g.normalize_or(DVec3::Y).as_vec3();
        let alb = Vec3::from_array(albedo(periodic(p).1));
        if !alb.is_finite() {
            return [0.0; 3];
        }
        light
            .shade(alb.clamp(Vec3::ZERO, Vec3::ONE), nrm)
            .min(Vec3::ONE)
            .to_array()
    };
    let rgba = fill_interior(params.dims, &coverage, lit);
    TexelVolume::new(params.dims, s, rgba)
}

/// Parameters of [`from_shape`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShapeParams {
    /// Voxels along `x, y, z`.
    pub dims: [usize; 3],
    /// Voxel edge (world units of the shape).
    pub voxel: f64,
    /// Lower corner of the tile in the shape's frame (the tile spans `min + dims·voxel`).
    pub min: [f64; 3],
    /// Inside tests per voxel edge of data-gen's voxelisation ([`Supersample`]: `k³` per voxel).
    pub supersample: Supersample,
    /// Baked light.
    pub lighting: SliceLighting,
    /// The shape repeats along `x` and `z` (a tile: voxelised periodically); off for one object
    /// in its box (docs/design.md §9.4).
    pub tiled: bool,
    /// Solid or shell voxelisation ([`Fill`]; default [`Fill::Auto`]: the shape decides).
    pub fill: Fill,
}

impl Default for ShapeParams {
    /// The bounding cylinder of the data-gen shapes (`R = 1`, `H = 2`) as a 32³ tile:
    /// `[−1, 1] × [0, 2] × [−1, 1]`, voxel 1/16, 3³ sub-samples, data-gen's light, tiled.
    fn default() -> Self {
        Self {
            dims: [32; 3],
            voxel: 1.0 / 16.0,
            min: [-1.0, 0.0, -1.0],
            supersample: Supersample::of(3),
            lighting: SliceLighting::default(),
            tiled: true,
            fill: Fill::Auto,
        }
    }
}

/// Builds a texel from a data-gen shape: [`voxelize`] (periodic in `x` and `z` when
/// [`ShapeParams::tiled`]) gives coverage, albedo and normals; boundary voxels are shaded, the
/// interior takes the colour of its nearest boundary voxel (Meyer & Neyret's §3.2 fill). A shell
/// voxelisation ([`Fill::Shell`]) also gives each voxel its opacity per crossing axis
/// ([`TexelVolume::with_axis_alpha`]), so the stacks along an axis see a leaf face on as opaque.
/// Cost: data-gen's voxelisation plus one pass.
///
/// Errors: data-gen's (zero sizes, non-finite box), zero voxel size, bad light.
pub fn from_shape(shape: &dyn Shape, params: &ShapeParams) -> Result<TexelVolume, SliceError> {
    check_grid(params.dims, params.voxel)?;
    let light = params.lighting.light()?;
    let min = DVec3::from_array(params.min);
    let d = params.dims;
    let max = min + DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64) * params.voxel;
    let vol = voxelize(
        shape,
        &VoxelParams {
            dims: d,
            min,
            max,
            periodic: [params.tiled, false, params.tiled],
            supersample: params.supersample,
            fill: params.fill,
        },
    )?;
    let lit = |i: usize| -> [f32; 3] {
        let alb = Vec3::from_array(vol.color[i]).clamp(Vec3::ZERO, Vec3::ONE);
        let n = vol.normal[i].unwrap_or(Vec3::Y);
        light.shade(alb, n).min(Vec3::ONE).to_array()
    };
    let rgba = fill_interior(d, &vol.density, lit);
    let volume = TexelVolume::new(d, params.voxel, rgba)?;
    match vol.axis_coverage {
        Some(axis) => volume.with_axis_alpha(axis),
        None => Ok(volume),
    }
}

/// The test tiles of the slice measurements (`altrep slices`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum TestTile {
    /// 40 tapered, leaning grass blades rooted at `y = 0`, no soil (the surface under the
    /// texel is drawn apart), implicit.
    Grass,
    /// 120 thin, slightly leaning cylinders of radius 0.4 voxel at 32³ rooted at `y = 0`, no
    /// skin, implicit.
    Fur,
    /// A cyclic Perlin height field (4 cells, 3 octaves).
    Perlin,
    /// data-gen's `tree` voxelised in its bounding cylinder (mesh-like input, interior filled).
    Tree,
}

impl TestTile {
    /// All four.
    pub const ALL: [TestTile; 4] = [
        TestTile::Grass,
        TestTile::Fur,
        TestTile::Perlin,
        TestTile::Tree,
    ];

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            TestTile::Grass => "grass",
            TestTile::Fur => "fur",
            TestTile::Perlin => "perlin",
            TestTile::Tree => "tree",
        }
    }
}

/// Distance from `p` to segment `a–b` and the segment parameter of the closest point.
fn segment(p: DVec3, a: DVec3, b: DVec3) -> (f64, f64) {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    ((p - (a + t * ab)).length(), t)
}

/// A test tile of `n³` voxels (`n` a power of two for slicing), unit tile (`s = 1/n`) except the
/// tree (`s = 2/n`, data-gen's bounding cylinder), seeded, lit by data-gen's default light.
pub fn test_tile(tile: TestTile, n: usize, seed: u64) -> Result<TexelVolume, SliceError> {
    test_tile_lit(tile, n, seed, &SliceLighting::default())
}

/// [`test_tile`] with its colours shaded by `lighting` (the same tile for
/// [`SliceLighting::default`]).
pub fn test_tile_lit(
    tile: TestTile,
    n: usize,
    seed: u64,
    lighting: &SliceLighting,
) -> Result<TexelVolume, SliceError> {
    let mut rng = SplitMix64::new(seed);
    let implicit = ImplicitParams {
        lighting: lighting.clone(),
        dims: [n; 3],
        voxel: 1.0 / n.max(1) as f64,
        // Union of tapered capsules: the taper (at most 0.022 over 0.5) keeps K ≤ 1.001.
        lipschitz: Some(1.01),
        // Each blade is measured at its nearest periodic image below.
        periodic_images: false,
        ..ImplicitParams::default()
    };
    match tile {
        TestTile::Grass | TestTile::Fur => {
            let grass = tile == TestTile::Grass;
            let count = if grass { 40 } else { 120 };
            let blades: Vec<(DVec3, DVec3, f64, f64)> = (0..count)
                .map(|_| {
                    let base = DVec3::new(rng.next_f64(), 0.0, rng.next_f64());
                    let (height, lean, r0, r1) = if grass {
                        (rng.range(0.5, 0.9), 0.25, 0.03, 0.008)
                    } else {
                        (rng.range(0.6, 0.85), 0.08, 0.0125, 0.0125)
                    };
                    let tip =
                        base + DVec3::new(rng.range(-lean, lean), height, rng.range(-lean, lean));
                    (base, tip, r0, r1)
                })
                .collect();
            let f = move |p: DVec3| {
                let mut d = f64::INFINITY;
                for (a, b, r0, r1) in &blades {
                    // Minimum image in x and z (blades span well under half a tile).
                    let w = |d: f64| d - d.round();
                    let q = *a + DVec3::new(w(p.x - a.x), p.y - a.y, w(p.z - a.z));
                    let (dist, t) = segment(q, *a, *b);
                    d = d.min(dist - (r0 + t * (r1 - r0)));
                }
                d
            };
            let albedo = move |p: DVec3| {
                let t = (p.y as f32).clamp(0.0, 1.0);
                if grass {
                    [0.1 + 0.3 * t, 0.35 + 0.5 * t, 0.08 + 0.1 * t]
                } else {
                    [0.35 + 0.5 * t, 0.22 + 0.45 * t, 0.12 + 0.35 * t]
                }
            };
            from_implicit(&f, &albedo, &implicit)
        }
        TestTile::Perlin => from_height_field(
            &HeightField::Perlin {
                cells: 4,
                octaves: 3,
                seed,
                base: 0.45,
                amplitude: 0.6,
            },
            &HeightFieldParams {
                dims: [n; 3],
                voxel: 1.0 / n.max(1) as f64,
                lighting: lighting.clone(),
                ..HeightFieldParams::default()
            },
        ),
        TestTile::Tree => from_shape(
            &scene_shape("tree")?,
            &ShapeParams {
                dims: [n; 3],
                voxel: 2.0 / n.max(1) as f64,
                supersample: Supersample::of(2),
                lighting: lighting.clone(),
                ..ShapeParams::default()
            },
        ),
    }
}
