//! Building an octree from voxels: leaf micro-primitives, moment sums filtered level by level,
//! pruning of uniform regions (see the module docs of [`super`]).

use std::num::NonZeroU32;
use std::time::Instant;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::storage::{Octree, OctreeNode, PackedEllipsoid};
use super::voxels::VoxelSource;
use crate::ellipsoid::error::EllipsoidError;
use crate::ellipsoid::filter::FilterRule;

/// Parameters of [`Octree::build`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OctreeParams {
    /// Filter rule for the coarser levels. Default [`FilterRule::Sggx`]: closer to the true summed
    /// normal distribution and projected area on every case of `altrep ellipsoid-bench`.
    pub rule: FilterRule,
    /// Aspect `a/b` of the flat spheroid given to a surface voxel, in `[1e-6, 1]`. Default 0.05.
    pub leaf_flatness: f64,
    /// Give the unit sphere to full voxels whose six face-neighbours are full. Default true.
    pub isotropic_interior: bool,
    /// Pruning tolerance (absolute on density and colour, relative on moments), ≥ 0. Default 1e-4.
    pub tolerance: f64,
}

impl Default for OctreeParams {
    fn default() -> Self {
        Self {
            rule: FilterRule::Sggx,
            leaf_flatness: 0.05,
            isotropic_interior: true,
            tolerance: 1e-4,
        }
    }
}

/// Costs and sizes of a built octree.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OctreeReport {
    /// Name of the volume (set by the caller; empty by default).
    pub volume: String,
    /// Input dimensions.
    pub dims: [usize; 3],
    /// Filter rule.
    pub rule: FilterRule,
    /// Levels below the root (the padded cube has side `2^depth`).
    pub depth: u32,
    /// Stored nodes (all levels).
    pub nodes: usize,
    /// Leaves among them.
    pub leaves: usize,
    /// Nodes per level, index = level (0 = voxel).
    pub nodes_per_level: Vec<usize>,
    /// Input voxels `nx·ny·nz`.
    pub voxels: usize,
    /// `1 − nodes / voxels`: Neyret 1995's "compression" (91–93 % at 128³ in the paper).
    pub compression: f64,
    /// Bytes of the node array (`nodes × 52`).
    pub bytes: usize,
    /// Bytes of the finest level stored densely with the same per-voxel fields (`voxels × 48`).
    pub dense_bytes: usize,
    /// Eigen-decompositions performed (one per non-empty node).
    pub eigen_calls: usize,
    /// Wall-clock build time, seconds.
    pub build_seconds: f64,
}

/// Running sums over a region: Σρ, Σρc, Σρ·moment (upper triangle).
#[derive(Debug, Clone, Copy, Default)]
struct Agg {
    density: f64,
    color: [f64; 3],
    moment: [f64; 6],
}

impl Agg {
    fn add(&mut self, o: &Agg) {
        self.density += o.density;
        for k in 0..3 {
            self.color[k] += o.color[k];
        }
        for k in 0..6 {
            self.moment[k] += o.moment[k];
        }
    }
}

enum Build {
    Leaf(Agg),
    Inner(Agg, Box<[Build; 8]>),
}

impl Build {
    fn agg(&self) -> &Agg {
        match self {
            Build::Leaf(a) | Build::Inner(a, _) => a,
        }
    }
}

/// Closed-form moment of a spheroid `α I + β n nᵀ` (unit `n`), returned as the upper triangle.
fn spheroid_moment(n: &Vector3<f64>, alpha: f64, beta: f64) -> [f64; 6] {
    [
        alpha + beta * n.x * n.x,
        beta * n.x * n.y,
        beta * n.x * n.z,
        alpha + beta * n.y * n.y,
        beta * n.y * n.z,
        alpha + beta * n.z * n.z,
    ]
}

struct LeafRules {
    rule: FilterRule,
    /// (α, β) of the flat leaf's moment `α I + β n nᵀ`.
    flat: (f64, f64),
    /// Moment of the unit sphere (α I).
    sphere: f64,
    isotropic_interior: bool,
    tolerance: f64,
}

impl LeafRules {
    fn new(p: &OctreeParams) -> Result<Self, EllipsoidError> {
        if !(1e-6..=1.0).contains(&p.leaf_flatness) {
            return Err(EllipsoidError::BadParameter {
                name: "leaf_flatness",
                reason: format!("must be in [1e-6, 1], got {}", p.leaf_flatness),
            });
        }
        if !(p.tolerance >= 0.0 && p.tolerance.is_finite()) {
            return Err(EllipsoidError::BadParameter {
                name: "tolerance",
                reason: format!("must be finite and ≥ 0, got {}", p.tolerance),
            });
        }
        // Normalised flat spheroid: lengths (b, b, a), a = f b, b² + 2ab = 3.
        let f = p.leaf_flatness;
        let b2 = 3.0 / (1.0 + 2.0 * f);
        let a2 = f * f * b2;
        let pi2 = std::f64::consts::PI.powi(2);
        let (flat, sphere) = match p.rule {
            // Q⁻¹ = b² I + (a² − b²) n nᵀ; sphere: I.
            FilterRule::Seed1995 => ((b2, a2 - b2), 1.0),
            // S = π² [a²b² I + (b⁴ − a²b²) n nᵀ]; sphere: π² I.
            FilterRule::Sggx => ((pi2 * a2 * b2, pi2 * (b2 * b2 - a2 * b2)), pi2),
        };
        Ok(Self {
            rule: p.rule,
            flat,
            sphere,
            isotropic_interior: p.isotropic_interior,
            tolerance: p.tolerance,
        })
    }
}

fn bad_voxel(x: usize, y: usize, z: usize, what: &str) -> EllipsoidError {
    EllipsoidError::BadVolume(format!("voxel ({x}, {y}, {z}): {what}"))
}

fn leaf<S: VoxelSource + ?Sized>(
    src: &S,
    dims: [usize; 3],
    [x, y, z]: [usize; 3],
    rules: &LeafRules,
) -> Result<Agg, EllipsoidError> {
    if x >= dims[0] || y >= dims[1] || z >= dims[2] {
        return Ok(Agg::default());
    }
    let density = src.density(x, y, z);
    if !(density.is_finite() && (0.0..=1.0).contains(&density)) {
        return Err(bad_voxel(x, y, z, &format!("density {density}")));
    }
    if density == 0.0 {
        return Ok(Agg::default());
    }
    let v = src.voxel(x, y, z);
    if v.color.iter().any(|c| !c.is_finite()) {
        return Err(bad_voxel(x, y, z, "colour is not finite"));
    }
    let rho = f64::from(density);
    let mut normal = None;
    if let Some(n) = v.normal {
        let n = Vector3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2]));
        let len = n.norm();
        if !len.is_finite() || len == 0.0 {
            return Err(bad_voxel(x, y, z, "normal is zero or not finite"));
        }
        normal = Some(n / len);
    }
    if normal.is_some() && rules.isotropic_interior && density >= 1.0 {
        let periodic = src.periodic();
        // Neighbour coordinate along `axis` shifted by ±1, wrapped on periodic axes.
        let step = |c: usize, axis: usize, up: bool| -> Option<usize> {
            let n = dims[axis];
            match (up, periodic[axis]) {
                (true, _) if c + 1 < n => Some(c + 1),
                (true, true) => Some(0),
                (false, _) if c > 0 => Some(c - 1),
                (false, true) => Some(n - 1),
                _ => None,
            }
        };
        let p = [x, y, z];
        let interior = (0..3).all(|axis| {
            [false, true].iter().all(|&up| {
                step(p[axis], axis, up).is_some_and(|c| {
                    let mut q = p;
                    q[axis] = c;
                    src.density(q[0], q[1], q[2]) >= 1.0
                })
            })
        });
        if interior {
            normal = None;
        }
    }
    let m = match normal {
        Some(n) => spheroid_moment(&n, rules.flat.0, rules.flat.1),
        None => spheroid_moment(&Vector3::x(), rules.sphere, 0.0),
    };
    Ok(Agg {
        density: rho,
        color: v.color.map(|c| rho * f64::from(c)),
        moment: m.map(|x| rho * x),
    })
}

/// Do eight leaf children of level `child_level` agree within the tolerance? Empty and non-empty
/// children never merge (so "no micro-primitive" stays exact).
fn uniform(children: &[Build; 8], child_level: u32, rules: &LeafRules) -> bool {
    let mut aggs = [Agg::default(); 8];
    for (a, c) in aggs.iter_mut().zip(children) {
        match c {
            Build::Leaf(x) => *a = *x,
            Build::Inner(..) => return false,
        }
    }
    let tol = rules.tolerance;
    let voxels = (1u64 << (3 * child_level)) as f64;
    let first = &aggs[0];
    let moment_scale = first.moment.iter().fold(0.0f64, |m, x| m.max(x.abs())) / first.density;
    aggs.iter().all(|a| {
        if (a.density - first.density).abs() > tol * voxels {
            return false;
        }
        if a.density == 0.0 || first.density == 0.0 {
            return a.density == first.density;
        }
        let colour_ok =
            (0..3).all(|k| (a.color[k] / a.density - first.color[k] / first.density).abs() <= tol);
        let moment_ok = (0..6).all(|k| {
            (a.moment[k] / a.density - first.moment[k] / first.density).abs() <= tol * moment_scale
        });
        colour_ok && moment_ok
    })
}

const PARALLEL_LEVEL: u32 = 4;

/// Blocks of side `2^OCCUPANCY_LEVEL` voxels are the finest unit of [`Occupancy`].
const OCCUPANCY_LEVEL: u32 = 3;

/// Which aligned blocks of side `2^level` (`level ≥ OCCUPANCY_LEVEL`) hold a voxel whose density
/// is not exactly 0 (NaN and out-of-range densities count as occupied, so the build still visits
/// and reports them).
///
/// An empty block builds to `Leaf(Agg::default())` however it is recursed into (empty leaves,
/// all uniform, sums of zeros), so the build returns that at once: one density read per voxel
/// in a flat scan replaces the recursion over the block's voxels, which the profile of a 256³
/// build showed as the hot spot (`build_region` itself, mostly on empty voxels).
struct Occupancy {
    /// Per level from `OCCUPANCY_LEVEL` up: blocks per axis and flags (`x + n (y + n z)`).
    levels: Vec<(usize, Vec<bool>)>,
}

impl Occupancy {
    fn new<S: VoxelSource + ?Sized>(src: &S, dims: [usize; 3], depth: u32) -> Self {
        if depth < OCCUPANCY_LEVEL {
            return Self { levels: Vec::new() };
        }
        let b = 1usize << OCCUPANCY_LEVEL;
        let n = 1usize << (depth - OCCUPANCY_LEVEL);
        let mut flags = vec![false; n * n * n];
        flags
            .par_chunks_mut(n * n)
            .enumerate()
            .for_each(|(bz, slab)| {
                for z in bz * b..((bz + 1) * b).min(dims[2]) {
                    for y in 0..dims[1] {
                        let row = &mut slab[(y / b) * n..(y / b + 1) * n];
                        for x in 0..dims[0] {
                            if !row[x / b] && src.density(x, y, z) != 0.0 {
                                row[x / b] = true;
                            }
                        }
                    }
                }
            });
        let mut levels = vec![(n, flags)];
        while let Some((n, f)) = levels.last().filter(|(n, _)| *n > 1) {
            let m = n / 2;
            let mut up = vec![false; m * m * m];
            for (i, u) in up.iter_mut().enumerate() {
                let (x, y, z) = (2 * (i % m), 2 * ((i / m) % m), 2 * (i / (m * m)));
                *u = (0..8).any(|o| {
                    f[(x + (o & 1)) + n * ((y + ((o >> 1) & 1)) + n * (z + ((o >> 2) & 1)))]
                });
            }
            levels.push((m, up));
        }
        Self { levels }
    }

    /// Whether the block of side `2^level` at `origin` may hold a non-empty voxel.
    #[inline]
    fn occupied(&self, level: u32, origin: [usize; 3]) -> bool {
        if level < OCCUPANCY_LEVEL {
            return true;
        }
        match self.levels.get((level - OCCUPANCY_LEVEL) as usize) {
            Some((n, f)) => {
                let [x, y, z] = origin.map(|c| c >> level);
                f[x + n * (y + n * z)]
            }
            None => true,
        }
    }
}

fn build_region<S: VoxelSource + ?Sized>(
    src: &S,
    dims: [usize; 3],
    origin: [usize; 3],
    level: u32,
    rules: &LeafRules,
    occupancy: &Occupancy,
) -> Result<Build, EllipsoidError> {
    if level == 0 {
        return Ok(Build::Leaf(leaf(src, dims, origin, rules)?));
    }
    if origin[0] >= dims[0]
        || origin[1] >= dims[1]
        || origin[2] >= dims[2]
        || !occupancy.occupied(level, origin)
    {
        return Ok(Build::Leaf(Agg::default()));
    }
    let half = 1usize << (level - 1);
    let child_origin = |o: usize| {
        [
            origin[0] + (o & 1) * half,
            origin[1] + ((o >> 1) & 1) * half,
            origin[2] + ((o >> 2) & 1) * half,
        ]
    };
    let mut children: [Build; 8] = std::array::from_fn(|_| Build::Leaf(Agg::default()));
    if level >= PARALLEL_LEVEL {
        let built: Vec<Build> = (0..8)
            .into_par_iter()
            .map(|o| build_region(src, dims, child_origin(o), level - 1, rules, occupancy))
            .collect::<Result<_, _>>()?;
        for (slot, b) in children.iter_mut().zip(built) {
            *slot = b;
        }
    } else {
        for (o, slot) in children.iter_mut().enumerate() {
            *slot = build_region(src, dims, child_origin(o), level - 1, rules, occupancy)?;
        }
    }
    let mut agg = Agg::default();
    for c in &children {
        agg.add(c.agg());
    }
    if uniform(&children, level - 1, rules) {
        Ok(Build::Leaf(agg))
    } else {
        Ok(Build::Inner(agg, Box::new(children)))
    }
}

impl Octree {
    /// Builds the octree of `src` (rayon over the top levels) and reports its costs.
    ///
    /// Errors: zero-size volume, more than 2^20 voxels per side, a voxel with density outside
    /// `[0, 1]` or NaN, a non-finite colour, a zero or non-finite normal (each error names the
    /// voxel), or bad parameters. Cost: one sample per voxel (seven for full voxels with
    /// `isotropic_interior`), one eigen-decomposition per non-empty stored node.
    pub fn build<S: VoxelSource + ?Sized>(
        src: &S,
        params: &OctreeParams,
    ) -> Result<(Self, OctreeReport), EllipsoidError> {
        Self::build_impl(src, params, true)
    }

    /// [`Octree::build`], with or without the skip of empty blocks ([`Occupancy`]); the result
    /// is the same either way (checked by a test).
    fn build_impl<S: VoxelSource + ?Sized>(
        src: &S,
        params: &OctreeParams,
        skip_empty: bool,
    ) -> Result<(Self, OctreeReport), EllipsoidError> {
        let start = Instant::now();
        let rules = LeafRules::new(params)?;
        let dims = src.dims();
        let side = dims.iter().copied().max().unwrap_or(0);
        if dims.contains(&0) || side > 1 << 20 {
            return Err(EllipsoidError::BadVolume(format!(
                "dimensions {dims:?} must be in 1..=2^20"
            )));
        }
        let depth = side.next_power_of_two().trailing_zeros();
        let occupancy = if skip_empty {
            Occupancy::new(src, dims, depth)
        } else {
            Occupancy { levels: Vec::new() }
        };
        let root = build_region(src, dims, [0, 0, 0], depth, &rules, &occupancy)?;

        // Flatten breadth-first so the 8 children of a node are consecutive; filter each node.
        let mut nodes: Vec<OctreeNode> = Vec::new();
        let mut levels: Vec<u32> = Vec::new();
        let mut queue: std::collections::VecDeque<(&Build, u32)> = Default::default();
        queue.push_back((&root, depth));
        let mut pending: Vec<(usize, &Build, u32)> = Vec::new();
        // First pass: assign indices.
        while let Some((b, level)) = queue.pop_front() {
            let index = nodes.len();
            nodes.push(OctreeNode {
                density: 0.0,
                color: [0.0; 3],
                ellipsoid: None,
                first_child: None,
            });
            levels.push(level);
            pending.push((index, b, level));
            if let Build::Inner(_, children) = b {
                for c in children.iter() {
                    queue.push_back((c, level - 1));
                }
            }
        }
        // Children of node i (in BFS order) start right after all nodes queued before them.
        let mut next_child = 1usize;
        for (index, b, _) in &pending {
            if let Build::Inner(..) = b {
                let first = u32::try_from(next_child)
                    .ok()
                    .and_then(NonZeroU32::new)
                    .ok_or_else(|| EllipsoidError::BadVolume("more than 2^32 nodes".into()))?;
                nodes[*index].first_child = Some(first);
                next_child += 8;
            }
        }
        let filled: Vec<(f32, [f32; 3], Option<PackedEllipsoid>)> = pending
            .par_iter()
            .map(|(_, b, level)| {
                let a = b.agg();
                let voxels = (1u64 << (3 * level)) as f64;
                if a.density <= 0.0 {
                    return Ok((0.0, [0.0; 3], None));
                }
                let m = &a.moment;
                let mean =
                    Matrix3::new(m[0], m[1], m[2], m[1], m[3], m[4], m[2], m[4], m[5]) / a.density;
                let e = rules.rule.ellipsoid_from_moment(&mean)?;
                Ok((
                    (a.density / voxels) as f32,
                    a.color.map(|c| (c / a.density) as f32),
                    Some(PackedEllipsoid::pack(&e)),
                ))
            })
            .collect::<Result<_, EllipsoidError>>()?;
        let mut eigen_calls = 0;
        for (node, (d, c, e)) in nodes.iter_mut().zip(filled) {
            node.density = d;
            node.color = c;
            eigen_calls += usize::from(e.is_some());
            node.ellipsoid = e;
        }
        let mut nodes_per_level = vec![0usize; depth as usize + 1];
        for &l in &levels {
            nodes_per_level[l as usize] += 1;
        }
        let leaves = nodes.iter().filter(|n| n.first_child.is_none()).count();
        drop(pending);
        drop(root);
        let voxels = dims[0] * dims[1] * dims[2];
        let report = OctreeReport {
            volume: String::new(),
            dims,
            rule: params.rule,
            depth,
            nodes: nodes.len(),
            leaves,
            nodes_per_level,
            voxels,
            compression: 1.0 - nodes.len() as f64 / voxels as f64,
            bytes: nodes.len() * std::mem::size_of::<OctreeNode>(),
            dense_bytes: voxels * (std::mem::size_of::<OctreeNode>() - 4),
            eigen_calls,
            build_seconds: start.elapsed().as_secs_f64(),
        };
        Ok((
            Self {
                nodes,
                depth,
                dims,
                rule: params.rule,
            },
            report,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ellipsoid::primitive::Ellipsoid;
    use altrep_data_gen::Supersample;

    /// Skipping empty blocks changes nothing: same nodes (density, colour, packed ellipsoid,
    /// children) and the same counts, on voxelised scene shapes whose sides are not powers of two
    /// (padding), on a periodic volume and for both filter rules; and a NaN density inside an
    /// otherwise empty block is still reported.
    #[test]
    fn empty_block_skip_gives_the_same_octree() {
        use altrep_data_gen::{AnalyticVolume, VoxelParams, scene_shape, voxelize};
        let mut volumes: Vec<(&str, Box<dyn VoxelSource>)> = Vec::new();
        for (name, dims, periodic) in [
            ("tree", [40, 72, 36], [false; 3]),
            ("building", [64, 64, 64], [false; 3]),
            ("truck", [48, 20, 48], [true, false, true]),
        ] {
            let shape = scene_shape(name).unwrap();
            let volume = voxelize(
                &shape,
                &VoxelParams {
                    dims,
                    min: glam::DVec3::new(-1.0, 0.0, -1.0),
                    max: glam::DVec3::new(1.0, 2.0, 1.0),
                    periodic,
                    supersample: Supersample::ONE,
                    fill: altrep_data_gen::Fill::Solid,
                },
            )
            .unwrap();
            volumes.push((name, Box::new(volume)));
        }
        let lawn = super::super::voxels::VoxelGrid::from_source(&AnalyticVolume::lawn(48, 1));
        volumes.push(("lawn", Box::new(lawn.unwrap())));
        for (name, volume) in &volumes {
            let volume = &**volume;
            for rule in FilterRule::ALL {
                let params = OctreeParams {
                    rule,
                    ..Default::default()
                };
                let (fast, rf) = Octree::build_impl(volume, &params, true).unwrap();
                let (slow, rs) = Octree::build_impl(volume, &params, false).unwrap();
                assert!(
                    rf.nodes > 8 && rf.leaves < rf.voxels,
                    "{name}: trivial tree"
                );
                assert_eq!(fast.nodes(), slow.nodes(), "{name} {rule:?}");
                assert_eq!(
                    (rf.nodes, rf.leaves, &rf.nodes_per_level, rf.eigen_calls),
                    (rs.nodes, rs.leaves, &rs.nodes_per_level, rs.eigen_calls)
                );
                assert_eq!(rf.compression.to_bits(), rs.compression.to_bits());
            }
        }
        // A NaN in a far corner of an empty volume is still found.
        let n = 32;
        let mut density = vec![0.0f32; n * n * n];
        density[n * n * n - 1] = f32::NAN;
        let grid = super::super::voxels::VoxelGrid::new(
            [n; 3],
            density,
            vec![[0.5; 3]; n * n * n],
            vec![None; n * n * n],
        )
        .unwrap();
        assert!(matches!(
            Octree::build(&grid, &OctreeParams::default()),
            Err(EllipsoidError::BadVolume(_))
        ));
    }

    #[test]
    fn closed_form_leaf_moments_match_the_general_path() {
        for rule in FilterRule::ALL {
            let params = OctreeParams {
                rule,
                ..Default::default()
            };
            let rules = LeafRules::new(&params).unwrap();
            let n = Vector3::new(0.3, -0.5, 0.8).normalize();
            let m = spheroid_moment(&n, rules.flat.0, rules.flat.1);
            let e = Ellipsoid::spheroid(n, params.leaf_flatness, 1.0)
                .unwrap()
                .normalized()
                .unwrap();
            let full = rule.moment(&e);
            let upper = [
                full[(0, 0)],
                full[(0, 1)],
                full[(0, 2)],
                full[(1, 1)],
                full[(1, 2)],
                full[(2, 2)],
            ];
            for k in 0..6 {
                assert!((m[k] - upper[k]).abs() < 1e-12 * full.amax(), "{rule:?}");
            }
            let sphere = rule.moment(&Ellipsoid::sphere(1.0).unwrap());
            assert!((sphere - Matrix3::identity() * rules.sphere).amax() < 1e-12);
        }
    }
}
