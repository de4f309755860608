//! Shell voxelisation: the coverage of a surface within each voxel, for shapes whose inside
//! means nothing (open meshes, leaf cards cut out by an alpha mask, single walls) — docs/design.md
//! §3.4.
//!
//! Conventions. Along each axis `k`, a voxel is crossed by `s²` parallel rays along `+k`,
//! stratified over the voxel's face (the same offsets `(a + ½)/s` as the solid fill's
//! sub-samples), and along `−k` too where back faces let rays through ([`Shape::single_sided`]; a
//! ray stopped either way counts once). The voxel's coverage along `k`, `c_k`, is the share of
//! those rays that the surface stops inside the voxel, through [`Shape::intersect`] — so alpha
//! masks and hashed blending cut the rays exactly as they cut the truth's. A voxel holding a card seen face on
//! along `k` has `c_k = 1` and `c_j ≈ 0` along the card's own plane. The scalar density is the
//! mean `(c_x + c_y + c_z)/3`: for surface pieces of random orientation it is the mean over
//! directions of the share of rays stopped (both average `|n·d|` to ½).
//!
//! The colour is the mean albedo of every ray's first hit in the voxel (all three axes). The
//! normal is the mean of those hits' shading normals, each turned to face away from the centre
//! of the shape's bounds (seen from outside, the side of a leaf that faces out is the side a
//! viewer sees); a normal nearly tangent to that direction is turned to make its largest
//! component positive instead.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::geometry::Ray;
use crate::shape::Shape;

/// What a shell voxelisation gives, per voxel in storage order `x + nx·(y + ny·z)`.
pub(crate) struct Shell {
    /// Coverage along `x`, `y` and `z` (share of the voxel's `s²` rays stopped inside it).
    pub(crate) axis_coverage: Vec<[f32; 3]>,
    /// Mean albedo of the hits (zero where none).
    pub(crate) color: Vec<[f32; 3]>,
    /// Mean outward-turned shading normal of the hits, where defined.
    pub(crate) normal: Vec<Option<Vec3>>,
}

/// One column's sums along its axis: per voxel, the rays stopped and the sums of their hits'
/// albedo and turned normal.
struct Column {
    count: Vec<u32>,
    albedo: Vec<DVec3>,
    normal: Vec<DVec3>,
}

/// Shell voxelisation of `shape` over the box `min + [0, dims]·voxel` (periodic axes tiled with
/// the box as period: each ray also meets the shape's images one period away). Cost: per axis,
/// `s²` rays per column of voxels, each `hits + 1` calls of [`Shape::intersect`] per periodic
/// image (`3^p` on `p` periodic axes); columns in parallel.
pub(crate) fn shell(
    shape: &dyn Shape,
    dims: [usize; 3],
    min: DVec3,
    voxel: DVec3,
    periodic: [bool; 3],
    s: usize,
) -> Shell {
    let n = dims[0] * dims[1] * dims[2];
    let extent = voxel * DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
    let (lo, hi) = shape.bounds();
    let centre = 0.5 * (lo + hi);
    let offsets: Vec<DVec3> = crate::volume::images(DVec3::ZERO, DVec3::ONE, periodic)
        .map(|o| o * extent)
        .collect();
    let mut count = vec![[0u32; 3]; n];
    let mut albedo = vec![DVec3::ZERO; n];
    let mut normal = vec![DVec3::ZERO; n];
    let index = |c: [usize; 3]| c[0] + dims[0] * (c[1] + dims[1] * c[2]);
    for k in 0..3 {
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        let (nu, nv, nk) = (dims[u], dims[v], dims[k]);
        let h = voxel[k];
        // Both senses where back faces let rays through (the shape's surface then differs by
        // the side it is met from); one otherwise, which meets the same surfaces.
        let senses: &[f64] = if shape.single_sided() {
            &[1.0, -1.0]
        } else {
            &[1.0]
        };
        let columns: Vec<Column> = (0..nu * nv)
            .into_par_iter()
            .map(|col| {
                let (iu, iv) = (col % nu, col / nu);
                let mut acc = Column {
                    count: vec![0; nk],
                    albedo: vec![DVec3::ZERO; nk],
                    normal: vec![DVec3::ZERO; nk],
                };
                // The sub-ray that last counted each voxel: a ray counts a voxel once, whichever
                // periodic image stops it there.
                let mut counted = vec![usize::MAX; nk];
                for a in 0..s {
                    for b in 0..s {
                        let ray_id = a * s + b;
                        let mut across = min;
                        across[u] += (iu as f64 + (a as f64 + 0.5) / s as f64) * voxel[u];
                        across[v] += (iv as f64 + (b as f64 + 0.5) / s as f64) * voxel[v];
                        for (&sense, o) in senses
                            .iter()
                            .flat_map(|s| offsets.iter().map(move |o| (s, o)))
                        {
                            // One voxel before the box, so a surface lying on the box's face
                            // is met strictly inside the ray's range.
                            let mut origin = across;
                            let mut dir = DVec3::ZERO;
                            dir[k] = sense;
                            origin[k] = if sense > 0.0 {
                                min[k] - h
                            } else {
                                min[k] + extent[k] + h
                            };
                            let ray = Ray::new(origin - *o, dir);
                            walk(shape, &ray, h, nk, |walked, hit_albedo, hit_normal, p| {
                                let j = if sense > 0.0 { walked } else { nk - 1 - walked };
                                if counted[j] == ray_id {
                                    return;
                                }
                                counted[j] = ray_id;
                                acc.count[j] += 1;
                                acc.albedo[j] += hit_albedo;
                                acc.normal[j] += outward(hit_normal, p - centre);
                            });
                        }
                    }
                }
                acc
            })
            .collect();
        for (col, acc) in columns.into_iter().enumerate() {
            let (iu, iv) = (col % nu, col / nu);
            for j in 0..nk {
                if acc.count[j] == 0 {
                    continue;
                }
                let mut c = [0usize; 3];
                c[u] = iu;
                c[v] = iv;
                c[k] = j;
                let i = index(c);
                count[i][k] = acc.count[j];
                albedo[i] += acc.albedo[j];
                normal[i] += acc.normal[j];
            }
        }
    }
    let rays = (s * s) as f32;
    let axis_coverage = count
        .iter()
        .map(|c| [c[0] as f32 / rays, c[1] as f32 / rays, c[2] as f32 / rays])
        .collect();
    let color = count
        .iter()
        .zip(&albedo)
        .map(|(c, a)| {
            let hits = c.iter().sum::<u32>();
            if hits == 0 {
                [0.0; 3]
            } else {
                (*a / hits as f64).as_vec3().to_array()
            }
        })
        .collect();
    let normal = normal
        .iter()
        .map(|m| {
            let m = m.normalize_or_zero();
            (m != DVec3::ZERO).then(|| m.as_vec3())
        })
        .collect();
    Shell {
        axis_coverage,
        color,
        normal,
    }
}

/// `n` turned to face `away` (from the centre of the bounds to the hit); where `n` is nearly
/// tangent to it (a card through the centre), turned so that its largest component is positive,
/// so that the hits of one flat card add up instead of cancelling.
fn outward(n: DVec3, away: DVec3) -> DVec3 {
    let d = n.dot(away);
    let flip = if d.abs() > 1e-6 * away.length() {
        d < 0.0
    } else {
        let k = n.abs().max_position();
        n[k] < 0.0
    };
    if flip { -n } else { n }
}

/// Walks `ray` (starting one voxel of length `h` before a column of `nk` voxels along its unit
/// direction) through the column, calling `hit(j, albedo, normal, point)` for the first hit in
/// each voxel `j` the surface stops it in, and skipping the rest of that voxel.
fn walk(
    shape: &dyn Shape,
    ray: &Ray,
    h: f64,
    nk: usize,
    mut hit: impl FnMut(usize, DVec3, DVec3, DVec3),
) {
    let end = h * (nk as f64 + 1.0);
    // Exclusive lower bounds: start a hair before each voxel's entry, so a surface exactly on
    // a voxel face is met (and counted in the voxel it begins).
    let hair = h * 1e-9;
    let mut t = h - hair;
    let mut last = usize::MAX;
    while let Some(found) = shape.intersect(ray, t, end) {
        let j = (((found.t - h) / h).floor().max(0.0) as usize).min(nk - 1);
        if j != last {
            last = j;
            hit(
                j,
                found.albedo.as_dvec3(),
                found.normal,
                ray.origin + found.t * ray.dir,
            );
        }
        // On to the next voxel's entry (or past this hit, if it lay in the hair before it).
        t = found.t.max(h * (j as f64 + 2.0) - hair);
    }
}
