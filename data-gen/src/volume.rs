//! Voxelisation of a shape into a density + colour + normal volume (docs/design.md §3.4), periodic
//! (tileable) along the axes asked for.
//!
//! Voxel `(x, y, z)` covers `[min + (x, y, z)·voxel_size, min + (x+1, y+1, z+1)·voxel_size]`;
//! storage index `x + nx·(y + ny·z)`. Two fills ([`Fill`]): a solid's density is the share of
//! `s³` stratified sub-samples inside the shape; a shell's is the share of `s²` axis-parallel
//! rays per axis the surface stops within the voxel, averaged over the axes (the `shell`
//! module). On a periodic axis the shape is tiled with the period of the box, so a shape that
//! sticks out of one side comes back in on the other.

use crate::Supersample;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::error::{DataGenError, finite, nonzero};
use crate::shape::Shape;

/// One voxel sample (density, colour, normal), as the octree takes it as input
/// ([`crate::AnalyticVolume::sample`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Voxel {
    /// Coverage in `[0, 1]`.
    pub density: f32,
    /// Linear RGB albedo (ignored where `density = 0`).
    pub color: [f32; 3],
    /// Outward surface normal (any non-zero length; the octree normalises it), `None` where no surface.
    pub normal: Option<[f32; 3]>,
}

impl Voxel {
    /// The empty voxel.
    pub const EMPTY: Voxel = Voxel {
        density: 0.0,
        color: [0.0; 3],
        normal: None,
    };
}

/// How [`voxelize`] decides what a voxel holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Fill {
    /// [`Fill::Solid`] for shapes that enclose a volume ([`Shape::encloses_volume`]),
    /// [`Fill::Shell`] for the others.
    #[default]
    Auto,
    /// The share of the voxel inside the solid (parity of ray crossings for meshes): for closed
    /// shapes. An open surface has no inside, and its voxels come out nearly empty.
    Solid,
    /// The share of axis-parallel rays the surface stops within the voxel, per axis
    /// ([`Volume::axis_coverage`]): for open meshes, leaf cards cut by alpha masks, single walls.
    /// The inside of a closed shape stays empty.
    Shell,
}

impl Fill {
    /// The fill used for `shape`: [`Fill::Auto`] resolved by [`Shape::encloses_volume`].
    pub fn resolve(self, shape: &dyn Shape) -> Fill {
        match self {
            Fill::Auto if shape.encloses_volume() => Fill::Solid,
            Fill::Auto => Fill::Shell,
            other => other,
        }
    }

    /// Lower-case name (`auto`, `solid`, `shell`), as manifests write it.
    pub fn name(self) -> &'static str {
        match self {
            Fill::Auto => "auto",
            Fill::Solid => "solid",
            Fill::Shell => "shell",
        }
    }
}

/// Parameters of [`voxelize`].
#[derive(Clone, Copy, Debug)]
pub struct VoxelParams {
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// Lower corner of the box (world units).
    pub min: DVec3,
    /// Upper corner of the box (world units).
    pub max: DVec3,
    /// Periodic (tileable) axes.
    pub periodic: [bool; 3],
    /// Inside tests per voxel edge ([`Supersample`]: `k³` per voxel for a solid, `k²` rays per
    /// axis for a shell).
    pub supersample: Supersample,
    /// Solid, shell, or chosen by the shape ([`Fill::Auto`]).
    pub fill: Fill,
}

/// A voxelised shape.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// Lower corner (world units).
    pub min: DVec3,
    /// Voxel size (world units).
    pub voxel_size: DVec3,
    /// Periodic axes.
    pub periodic: [bool; 3],
    /// Coverage in `[0, 1]`, index `x + nx·(y + ny·z)`.
    pub density: Vec<f32>,
    /// Linear RGB albedo of the nearest surface (zero where empty).
    pub color: Vec<[f32; 3]>,
    /// Outward unit surface normal where `density > 0` and it is defined.
    pub normal: Vec<Option<Vec3>>,
    /// The fill used ([`Fill::Solid`] or [`Fill::Shell`], never [`Fill::Auto`]).
    pub fill: Fill,
    /// A shell's coverage along `x`, `y` and `z` per voxel (the share of the voxel's rays along
    /// that axis the surface stops inside it; `density` is their mean); `None` for a solid.
    pub axis_coverage: Option<Vec<[f32; 3]>>,
}

impl Volume {
    /// Storage index of voxel `(x, y, z)`.
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// Centre of voxel `(x, y, z)` (world units).
    #[inline]
    pub fn center(&self, x: usize, y: usize, z: usize) -> DVec3 {
        self.min + (DVec3::new(x as f64, y as f64, z as f64) + 0.5) * self.voxel_size
    }
}

/// The periodic images of `p` to test (the point itself first).
pub(crate) fn images(p: DVec3, period: DVec3, periodic: [bool; 3]) -> impl Iterator<Item = DVec3> {
    let range = move |k: usize| if periodic[k] { -1..=1 } else { 0..=0 };
    range(0).flat_map(move |a| {
        range(1).flat_map(move |b| {
            range(2).map(move |c| p + DVec3::new(a as f64, b as f64, c as f64) * period)
        })
    })
}

/// Voxelises `shape`. Cost, solid: `nx·ny·nz·s³` inside tests (×3^k on k periodic axes), plus
/// SDF or density-gradient normals; z-slabs in parallel. Shell: per axis `s²` rays per column of
/// voxels, each `hits + 1` ray casts (×3^k); columns in parallel.
///
/// Errors: zero dimensions or supersampling, a non-finite or empty box.
pub fn voxelize(shape: &dyn Shape, params: &VoxelParams) -> Result<Volume, DataGenError> {
    for (k, n) in params.dims.iter().enumerate() {
        nonzero(*n, ["volume dims x", "volume dims y", "volume dims z"][k])?;
    }
    let s = params.supersample.get();
    for k in 0..3 {
        finite(params.min[k], "volume min", k)?;
        finite(params.max[k], "volume max", k)?;
    }
    let extent = params.max - params.min;
    if extent.min_element() <= 0.0 {
        return Err(DataGenError::InvalidParameter {
            name: "volume box",
            value: format!("min {:?} max {:?}", params.min, params.max),
            reason: "max must exceed min on every axis",
        });
    }
    let [nx, ny, nz] = params.dims;
    let voxel = extent / DVec3::new(nx as f64, ny as f64, nz as f64);
    let periodic = params.periodic;
    if params.fill.resolve(shape) == Fill::Shell {
        let shell = crate::shell::shell(shape, params.dims, params.min, voxel, periodic, s);
        let density = shell
            .axis_coverage
            .iter()
            .map(|c| (c[0] + c[1] + c[2]) / 3.0)
            .collect();
        return Ok(Volume {
            dims: params.dims,
            min: params.min,
            voxel_size: voxel,
            periodic,
            density,
            color: shell.color,
            normal: shell.normal,
            fill: Fill::Shell,
            axis_coverage: Some(shell.axis_coverage),
        });
    }
    // The periodic images to test, as offsets in periods (the point itself first).
    let offsets: Vec<DVec3> = images(DVec3::ZERO, DVec3::ONE, periodic).collect();
    let n = nx * ny * nz;
    let mut density = vec![0.0f32; n];
    let mut color = vec![[0.0f32; 3]; n];
    let slab = nx * ny;
    density
        .par_chunks_mut(slab)
        .zip(color.par_chunks_mut(slab))
        .enumerate()
        .for_each(|(z, (dens, col))| {
            // One row of sub-samples at a time (fixed y and z: every x of every voxel of the
            // voxel row), so that shapes can share work along it (`Shape::contains_row`); each
            // point is the same number as `corner + f·voxel` per voxel and sub-sample.
            let row_len = nx * s;
            let mut xs = vec![0.0f64; row_len];
            let mut qx = vec![0.0f64; row_len];
            let mut inside = vec![false; row_len];
            let mut part = vec![false; row_len];
            let mut hits = vec![0usize; nx];
            for y in 0..ny {
                hits.iter_mut().for_each(|h| *h = 0);
                for b in 0..s {
                    for c in 0..s {
                        let mut yz = DVec3::ZERO;
                        for x in 0..nx {
                            let corner =
                                params.min + DVec3::new(x as f64, y as f64, z as f64) * voxel;
                            for a in 0..s {
                                let f = (DVec3::new(a as f64, b as f64, c as f64) + 0.5) / s as f64;
                                let p = corner + f * voxel;
                                xs[x * s + a] = p.x;
                                yz = p;
                            }
                        }
                        inside.iter_mut().for_each(|v| *v = false);
                        for o in &offsets {
                            let shift = *o * extent;
                            for (q, x) in qx.iter_mut().zip(&xs) {
                                *q = x + shift.x;
                            }
                            shape.contains_row(yz.y + shift.y, yz.z + shift.z, &qx, &mut part);
                            for (v, p) in inside.iter_mut().zip(&part) {
                                *v |= *p;
                            }
                        }
                        for (x, h) in hits.iter_mut().enumerate() {
                            *h += inside[x * s..(x + 1) * s].iter().filter(|v| **v).count();
                        }
                    }
                }
                for (x, &h) in hits.iter().enumerate() {
                    let i = x + nx * y;
                    dens[i] = h as f32 / (s * s * s) as f32;
                    if h > 0 {
                        let corner = params.min + DVec3::new(x as f64, y as f64, z as f64) * voxel;
                        let centre = corner + 0.5 * voxel;
                        let q = nearest_image(shape, centre, extent, periodic);
                        col[i] = shape.albedo_at(q).to_array();
                    }
                }
            }
        });
    let mut volume = Volume {
        dims: params.dims,
        min: params.min,
        voxel_size: voxel,
        periodic,
        density,
        color,
        normal: vec![None; n],
        fill: Fill::Solid,
        axis_coverage: None,
    };
    let normals: Vec<Option<Vec3>> = (0..n)
        .into_par_iter()
        .map(|idx| {
            if volume.density[idx] <= 0.0 {
                return None;
            }
            let (x, y, z) = (idx % nx, (idx / nx) % ny, idx / slab);
            let centre = volume.center(x, y, z);
            let q = nearest_image(shape, centre, extent, periodic);
            sdf_normal(shape, q, voxel.min_element() * 0.25)
                .or_else(|| density_normal(&volume, x, y, z))
        })
        .collect();
    volume.normal = normals;
    Ok(volume)
}

/// The periodic image of `p` nearest to the surface (by SDF when the shape has one).
fn nearest_image(shape: &dyn Shape, p: DVec3, period: DVec3, periodic: [bool; 3]) -> DVec3 {
    images(p, period, periodic)
        .map(|q| (q, shape.sdf(q).map_or(f64::INFINITY, f64::abs)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(p, |(q, _)| q)
}

/// Normal from the SDF gradient (central differences of step `h`).
fn sdf_normal(shape: &dyn Shape, p: DVec3, h: f64) -> Option<Vec3> {
    let mut g = DVec3::ZERO;
    for k in 0..3 {
        let mut e = DVec3::ZERO;
        e[k] = h;
        g[k] = shape.sdf(p + e)? - shape.sdf(p - e)?;
    }
    let n = g.normalize_or_zero();
    (n != DVec3::ZERO).then(|| n.as_vec3())
}

/// Normal as minus the density gradient (central differences, wrapped on periodic axes,
/// clamped on the others).
fn density_normal(v: &Volume, x: usize, y: usize, z: usize) -> Option<Vec3> {
    let at = |c: [isize; 3]| -> f32 {
        let mut idx = [0usize; 3];
        for k in 0..3 {
            let n = v.dims[k] as isize;
            idx[k] = if v.periodic[k] {
                c[k].rem_euclid(n) as usize
            } else {
                c[k].clamp(0, n - 1) as usize
            };
        }
        v.density[v.index(idx[0], idx[1], idx[2])]
    };
    let c = [x as isize, y as isize, z as isize];
    let mut g = Vec3::ZERO;
    for k in 0..3 {
        let (mut a, mut b) = (c, c);
        a[k] += 1;
        b[k] -= 1;
        g[k] = (at(a) - at(b)) / v.voxel_size[k] as f32;
    }
    let n = (-g).normalize_or_zero();
    (n != Vec3::ZERO).then_some(n)
}
