//! The multiscale octree volume of the 1995 seed: leaves from a voxelised RGBA + density volume,
//! coarser levels by filtering, uniform and empty regions pruned, level lookup by footprint.
//!
//! # Levels and coordinates
//!
//! Voxel `(x, y, z)` covers `[x, x+1) × [y, y+1) × [z, z+1)` in **voxel units**. The volume is padded
//! with empty voxels to a cube of side `2^depth`. A node of **level** `ℓ` covers a cube of side `2^ℓ`
//! voxels: level 0 is a voxel, the root is level `depth`. A pruned (uniform) region is a leaf above
//! level 0 and stands for every finer level inside it.
//!
//! # What a node holds
//!
//! - `density`: mean coverage of its voxels (padding counts as empty), in `[0, 1]`;
//! - `color`: density-weighted mean of the voxels' linear RGB;
//! - `ellipsoid`: the filter ([`FilterRule`]) of its voxels' micro-primitives weighted by density,
//!   `None` where the density is zero. Because both rules average a moment matrix linearly, filtering
//!   children is exactly filtering all voxels below (the build keeps the `f64` moment sums; each
//!   node's ellipsoid comes from one eigen-decomposition of its own mean).
//!
//! # Leaves from voxels
//!
//! A voxel with a surface normal gets a flat spheroid along it (lengths `(b, b, a)`, `a/b =`
//! [`OctreeParams::leaf_flatness`], normalised: `b² + 2ab = 3`); a voxel without a normal, or a full
//! voxel whose six face-neighbours are full (hidden inside a solid,
//! [`OctreeParams::isotropic_interior`]), gets the unit sphere. Empty voxels have none.
//!
//! # Pruning
//!
//! Eight leaf children that agree — densities within `tolerance`, colours within `tolerance`,
//! mean moments within `tolerance` relative — are replaced by one leaf. `tolerance = 0` is lossless.

use std::num::NonZeroU32;
use std::time::Instant;

use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::error::EllipsoidError;
use super::filter::FilterRule;
use super::primitive::Ellipsoid;

/// One input voxel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Voxel {
    /// Coverage in `[0, 1]`.
    pub density: f32,
    /// Linear RGB albedo (ignored where `density = 0`).
    pub color: [f32; 3],
    /// Outward surface normal (any non-zero length; normalised here), `None` where no surface.
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

/// A voxelised volume the octree can be built from (random access, shared between threads).
pub trait VoxelSource: Sync {
    /// `[nx, ny, nz]`, each ≥ 1.
    fn dims(&self) -> [usize; 3];
    /// The voxel at `(x, y, z)`, `x < nx`, `y < ny`, `z < nz`.
    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel;
    /// Its density alone (the build reads colour and normal only where this is non-zero);
    /// override when it is cheaper than [`Self::voxel`].
    fn density(&self, x: usize, y: usize, z: usize) -> f32 {
        self.voxel(x, y, z).density
    }
    /// Axes along which the volume tiles (neighbours wrap around). Default: none.
    fn periodic(&self) -> [bool; 3] {
        [false; 3]
    }
}

/// `altrep_data_gen`'s voxelised shapes (density, colour, normal; periodic axes honoured).
impl VoxelSource for altrep_data_gen::Volume {
    fn dims(&self) -> [usize; 3] {
        self.dims
    }
    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel {
        let i = self.index(x, y, z);
        Voxel {
            density: self.density[i],
            color: self.color[i],
            normal: self.normal[i].map(|n| n.to_array()),
        }
    }
    fn density(&self, x: usize, y: usize, z: usize) -> f32 {
        self.density[self.index(x, y, z)]
    }
    fn periodic(&self) -> [bool; 3] {
        self.periodic
    }
}

/// A dense voxel grid, index `x + nx (y + ny z)` (the layout of `altrep_data_gen`'s volumes).
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelGrid {
    dims: [usize; 3],
    density: Vec<f32>,
    color: Vec<[f32; 3]>,
    normal: Vec<Option<[f32; 3]>>,
}

impl VoxelGrid {
    /// A grid from its arrays; errors if a dimension is 0 or an array has the wrong length.
    pub fn new(
        dims: [usize; 3],
        density: Vec<f32>,
        color: Vec<[f32; 3]>,
        normal: Vec<Option<[f32; 3]>>,
    ) -> Result<Self, EllipsoidError> {
        let n = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|&n| n > 0)
            .ok_or_else(|| EllipsoidError::BadVolume(format!("bad dimensions {dims:?}")))?;
        for (name, len) in [
            ("density", density.len()),
            ("color", color.len()),
            ("normal", normal.len()),
        ] {
            if len != n {
                return Err(EllipsoidError::BadVolume(format!(
                    "{name} has {len} entries, dims {dims:?} need {n}"
                )));
            }
        }
        Ok(Self {
            dims,
            density,
            color,
            normal,
        })
    }

    /// Samples every voxel of `src` into a dense grid (rayon over z-slices).
    pub fn from_source<S: VoxelSource + ?Sized>(src: &S) -> Result<Self, EllipsoidError> {
        let dims = src.dims();
        let voxels: Vec<Voxel> = (0..dims[2])
            .into_par_iter()
            .flat_map_iter(|z| {
                (0..dims[1]).flat_map(move |y| (0..dims[0]).map(move |x| src.voxel(x, y, z)))
            })
            .collect();
        Self::new(
            dims,
            voxels.iter().map(|v| v.density).collect(),
            voxels.iter().map(|v| v.color).collect(),
            voxels.iter().map(|v| v.normal).collect(),
        )
    }
}

impl VoxelSource for VoxelGrid {
    fn dims(&self) -> [usize; 3] {
        self.dims
    }
    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel {
        let i = x + self.dims[0] * (y + self.dims[1] * z);
        Voxel {
            density: self.density[i],
            color: self.color[i],
            normal: self.normal[i],
        }
    }
    fn density(&self, x: usize, y: usize, z: usize) -> f32 {
        self.density[x + self.dims[0] * (y + self.dims[1] * z)]
    }
}

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

/// An ellipsoid stored compactly: unit quaternion `(x, y, z, w)` of its basis and its lengths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackedEllipsoid {
    /// Unit quaternion `(x, y, z, w)` rotating the frame axes onto the ellipsoid's axes.
    pub rotation: [f32; 4],
    /// Semi-axis lengths along the rotated x, y, z axes.
    pub lengths: [f32; 3],
}

impl PackedEllipsoid {
    /// Packs `e` (rounding to `f32`).
    pub fn pack(e: &Ellipsoid) -> Self {
        let rot = Rotation3::from_matrix_unchecked(*e.basis());
        let q = UnitQuaternion::from_rotation_matrix(&rot);
        let c = q.coords;
        let l = e.lengths();
        Self {
            rotation: [c.x as f32, c.y as f32, c.z as f32, c.w as f32],
            lengths: [l.x as f32, l.y as f32, l.z as f32],
        }
    }

    /// Back to an [`Ellipsoid`] (quaternion renormalised in `f64`).
    pub fn unpack(&self) -> Result<Ellipsoid, EllipsoidError> {
        let [x, y, z, w] = self.rotation.map(f64::from);
        let q = Quaternion::new(w, x, y, z);
        if q.norm() == 0.0 || !q.norm().is_finite() {
            return Err(EllipsoidError::NonFiniteMatrix {
                what: "packed rotation",
            });
        }
        let r = UnitQuaternion::from_quaternion(q)
            .to_rotation_matrix()
            .into_inner();
        Ellipsoid::new(r, Vector3::from(self.lengths.map(f64::from)))
    }
}

/// A stored octree node (52 bytes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OctreeNode {
    /// Mean coverage over the node's cube, `[0, 1]`.
    pub density: f32,
    /// Density-weighted mean linear RGB (zero where empty).
    pub color: [f32; 3],
    /// Filtered micro-primitive; `None` where the density is zero.
    pub ellipsoid: Option<PackedEllipsoid>,
    /// Index of the first of 8 consecutive children (octant order `x + 2y + 4z`), `None` for a leaf.
    pub first_child: Option<NonZeroU32>,
}

/// What a lookup found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeSample {
    /// Level of the node that answered (≥ the level asked for when the region was pruned).
    pub level: u32,
    /// Mean coverage.
    pub density: f32,
    /// Density-weighted mean colour.
    pub color: [f32; 3],
    /// Micro-primitive (`None` where empty).
    pub ellipsoid: Option<Ellipsoid>,
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
    /// `1 − nodes / voxels`: the seed's "compression" (91–93 % at 128³ in the seed).
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

/// The multiscale octree. See the module docs for levels and contents.
#[derive(Debug, Clone)]
pub struct Octree {
    nodes: Vec<OctreeNode>,
    depth: u32,
    dims: [usize; 3],
    rule: FilterRule,
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

fn build_region<S: VoxelSource + ?Sized>(
    src: &S,
    dims: [usize; 3],
    origin: [usize; 3],
    level: u32,
    rules: &LeafRules,
) -> Result<Build, EllipsoidError> {
    if level == 0 {
        return Ok(Build::Leaf(leaf(src, dims, origin, rules)?));
    }
    if origin[0] >= dims[0] || origin[1] >= dims[1] || origin[2] >= dims[2] {
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
            .map(|o| build_region(src, dims, child_origin(o), level - 1, rules))
            .collect::<Result<_, _>>()?;
        for (slot, b) in children.iter_mut().zip(built) {
            *slot = b;
        }
    } else {
        for (o, slot) in children.iter_mut().enumerate() {
            *slot = build_region(src, dims, child_origin(o), level - 1, rules)?;
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
        let root = build_region(src, dims, [0, 0, 0], depth, &rules)?;

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

    /// An octree from stored nodes (as a loader decodes them). Errors
    /// ([`EllipsoidError::BadParameter`]): no node, a depth above 24, dimensions beyond
    /// `2^depth`, a child block out of range or not after its parent (which would loop), a
    /// non-finite or out-of-range density or colour. Cost: one pass over the nodes.
    pub fn from_nodes(
        nodes: Vec<OctreeNode>,
        depth: u32,
        dims: [usize; 3],
        rule: FilterRule,
    ) -> Result<Self, EllipsoidError> {
        let bad = |name: &'static str, value: String, reason: &'static str| {
            EllipsoidError::BadParameter {
                name,
                reason: format!("{value}: {reason}"),
            }
        };
        if nodes.is_empty() {
            return Err(bad("nodes", "0".into(), "an octree needs a root"));
        }
        if depth > 24 {
            return Err(bad("depth", depth.to_string(), "must be at most 24"));
        }
        if dims.iter().any(|&d| d == 0 || d as u64 > 1u64 << depth) {
            return Err(bad("dims", format!("{dims:?}"), "must be in 1..=2^depth"));
        }
        for (i, n) in nodes.iter().enumerate() {
            if let Some(first) = n.first_child {
                let f = first.get() as usize;
                if f <= i || f.checked_add(8).is_none_or(|end| end > nodes.len()) {
                    return Err(bad(
                        "first_child",
                        format!("{f} at node {i}"),
                        "must name 8 nodes after the parent",
                    ));
                }
            }
            if !(n.density.is_finite() && (0.0..=1.0).contains(&n.density))
                || n.color.iter().any(|c| !c.is_finite())
            {
                return Err(bad(
                    "node",
                    i.to_string(),
                    "density must be in [0, 1] and colour finite",
                ));
            }
        }
        Ok(Self {
            nodes,
            depth,
            dims,
            rule,
        })
    }

    /// The stored nodes, breadth-first; index 0 is the root.
    pub fn nodes(&self) -> &[OctreeNode] {
        &self.nodes
    }

    /// Levels below the root.
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// Input dimensions.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The filter rule the coarser levels were built with.
    pub fn rule(&self) -> FilterRule {
        self.rule
    }

    /// The level for a pixel footprint of `footprint` voxels (its width in voxel units, as a cone
    /// tracer estimates it): `round(log₂ footprint)` clamped to `[0, depth]` — the level whose node
    /// side is nearest the footprint in ratio, as mipmapping does. NaN or ≤ 1 gives level 0.
    pub fn level_for_footprint(&self, footprint: f64) -> u32 {
        if footprint.is_nan() || footprint <= 1.0 {
            return 0;
        }
        let l = footprint.log2().round();
        if l >= self.depth as f64 {
            self.depth
        } else {
            l as u32
        }
    }

    /// The node of level `level` (or the pruned leaf above it) containing the point `p` (voxel
    /// units). `None` outside the padded cube `[0, 2^depth)³` or for a NaN coordinate.
    /// Cost: `depth − level` steps.
    pub fn lookup(&self, p: [f64; 3], level: u32) -> Option<NodeSample> {
        let (index, node_level) = self.find(p, level)?;
        let node = &self.nodes[index];
        Some(NodeSample {
            level: node_level,
            density: node.density,
            color: node.color,
            ellipsoid: node.ellipsoid.and_then(|e| e.unpack().ok()),
        })
    }

    /// Index and level of the node [`Self::lookup`] answers with.
    fn find(&self, p: [f64; 3], level: u32) -> Option<(usize, u32)> {
        let side = (1u64 << self.depth) as f64;
        if p.iter().any(|&c| !(0.0..side).contains(&c)) {
            return None;
        }
        let mut index = 0usize;
        let mut node_level = self.depth;
        let mut origin = [0.0f64; 3];
        loop {
            let node = self.nodes.get(index)?;
            match node.first_child {
                Some(first) if node_level > level => {
                    let half = (1u64 << (node_level - 1)) as f64;
                    let mut octant = 0;
                    for (k, (pk, ok)) in p.iter().zip(origin.iter_mut()).enumerate() {
                        if *pk >= *ok + half {
                            octant |= 1 << k;
                            *ok += half;
                        }
                    }
                    index = first.get() as usize + octant;
                    node_level -= 1;
                }
                _ => return Some((index, node_level)),
            }
        }
    }

    /// Renders the volume as seen at `level` (orthographic, looking down −z: image column `i` is
    /// `x = i + ½`, row `j` is `y = 2^depth − j − ½`, so `y` is up), one pixel per voxel of the
    /// padded cube — the seed's volume rendering reduced to local illumination:
    ///
    /// - extinction `σ = τ ρ A(v)/π` per voxel length (density modulated by the micro-primitive's
    ///   projected area along the view, `π` being a normalised primitive's mean);
    /// - emitted colour `albedo × (ambient + (1 − ambient) π ρ_d(l, v))`, with `ρ_d` the diffuse
    ///   reflectance of the node's ellipsoid ([`Ellipsoid::reflectance_apparent_ellipse`], 72
    ///   samples per node, computed once per node);
    /// - front-to-back compositing, `steps_per_voxel` samples per voxel length; no shadow rays.
    ///
    /// Returns a premultiplied linear-RGB image. Errors: bad parameters. Cost: one reflectance per
    /// stored node plus `side² × side × steps_per_voxel` lookups (rayon over rows).
    pub fn render_level(
        &self,
        level: u32,
        params: &RenderParams,
    ) -> Result<altrep_data_gen::RgbaImage, EllipsoidError> {
        let light = params.light;
        let ln = light.norm();
        if !ln.is_finite() || ln == 0.0 {
            return Err(EllipsoidError::BadDirection);
        }
        let light = light / ln;
        for (name, x) in [("tau", params.tau), ("ambient", params.ambient)] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(EllipsoidError::BadParameter {
                    name,
                    reason: format!("must be finite and ≥ 0, got {x}"),
                });
            }
        }
        if params.steps_per_voxel == 0 {
            return Err(EllipsoidError::BadParameter {
                name: "steps_per_voxel",
                reason: "must be ≥ 1".into(),
            });
        }
        let view = Vector3::z();
        let lambert = super::primitive::Phong {
            diffuse: 1.0,
            specular: 0.0,
            exponent: 0.0,
        };
        let ambient = params.ambient.min(1.0);
        // Per node: (extinction per voxel length, emitted linear RGB).
        let shading: Vec<(f64, [f64; 3])> = self
            .nodes
            .par_iter()
            .map(|n| match n.ellipsoid.and_then(|e| e.unpack().ok()) {
                Some(e) if n.density > 0.0 => {
                    let sigma = params.tau * f64::from(n.density) * e.projected_area(&view)
                        / std::f64::consts::PI;
                    let rho = e
                        .reflectance_apparent_ellipse(&light, &view, &lambert, 6)
                        .unwrap_or(0.0);
                    let k = ambient + (1.0 - ambient) * std::f64::consts::PI * rho;
                    (sigma, n.color.map(|c| f64::from(c) * k))
                }
                _ => (0.0, [0.0; 3]),
            })
            .collect();
        let side = 1usize << self.depth;
        let steps = side * params.steps_per_voxel;
        let ds = 1.0 / params.steps_per_voxel as f64;
        let mut image = altrep_data_gen::RgbaImage::new(side, side);
        image
            .pixels
            .par_chunks_mut(side)
            .enumerate()
            .for_each(|(j, row)| {
                let y = side as f64 - j as f64 - 0.5;
                for (i, px) in row.iter_mut().enumerate() {
                    let x = i as f64 + 0.5;
                    let mut t = 1.0f64;
                    let mut c = [0.0f64; 3];
                    for k in 0..steps {
                        let z = side as f64 - (k as f64 + 0.5) * ds;
                        let Some((index, _)) = self.find([x, y, z], level) else {
                            continue;
                        };
                        let (sigma, emit) = shading[index];
                        if sigma <= 0.0 {
                            continue;
                        }
                        let alpha = 1.0 - (-sigma * ds).exp();
                        for (ck, ek) in c.iter_mut().zip(emit) {
                            *ck += t * alpha * ek;
                        }
                        t *= 1.0 - alpha;
                        if t < 1e-4 {
                            break;
                        }
                    }
                    *px = [c[0] as f32, c[1] as f32, c[2] as f32, (1.0 - t) as f32];
                }
            });
        Ok(image)
    }

    /// [`Self::lookup`] at the level chosen by [`Self::level_for_footprint`].
    pub fn lookup_footprint(&self, p: [f64; 3], footprint: f64) -> Option<NodeSample> {
        self.lookup(p, self.level_for_footprint(footprint))
    }
}

/// Parameters of [`Octree::render_level`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderParams {
    /// Direction toward the light (object frame, any length).
    pub light: Vector3<f64>,
    /// Ambient share of the shading in `[0, 1]`.
    pub ambient: f64,
    /// Optical depth per voxel length at density 1 (`τ` of the seed's `e^{−τρL}`).
    pub tau: f64,
    /// Samples per voxel length along a ray (≥ 1).
    pub steps_per_voxel: usize,
}

impl Default for RenderParams {
    /// Light from the upper right front `(0.5, 0.8, 0.35)`, ambient 0.3 (as `altrep_data_gen`'s
    /// default light), `τ = 4`, two samples per voxel.
    fn default() -> Self {
        Self {
            light: Vector3::new(0.5, 0.8, 0.35),
            ambient: 0.3,
            tau: 4.0,
            steps_per_voxel: 2,
        }
    }
}

/// An analytic signed-distance shape for procedural test volumes (unit-cube coordinates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnalyticShape {
    /// Sphere.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
    },
    /// Torus about the y axis.
    Torus {
        /// Centre.
        center: [f64; 3],
        /// Distance from the centre to the tube's axis.
        major: f64,
        /// Tube radius.
        minor: f64,
    },
    /// Capsule: the points within `radius` of the segment `a`–`b`.
    Capsule {
        /// One end of the axis.
        a: [f64; 3],
        /// Other end of the axis.
        b: [f64; 3],
        /// Radius.
        radius: f64,
    },
    /// Axis-aligned box.
    Slab {
        /// Minimum corner.
        min: [f64; 3],
        /// Maximum corner.
        max: [f64; 3],
    },
}

impl AnalyticShape {
    /// Signed distance (negative inside) and its gradient (outward unit normal) at `p`.
    pub fn sdf(&self, p: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let safe = |v: Vector3<f64>| {
            let n = v.norm();
            if n > 0.0 { v / n } else { Vector3::y() }
        };
        match *self {
            AnalyticShape::Sphere { center, radius } => {
                let d = p - Vector3::from(center);
                (d.norm() - radius, safe(d))
            }
            AnalyticShape::Torus {
                center,
                major,
                minor,
            } => {
                let d = p - Vector3::from(center);
                let radial = Vector3::new(d.x, 0.0, d.z);
                let ring = safe(radial) * major;
                let q = d - ring;
                (q.norm() - minor, safe(q))
            }
            AnalyticShape::Capsule { a, b, radius } => {
                let (a, b) = (Vector3::from(a), Vector3::from(b));
                let ab = b - a;
                let t = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                let d = p - (a + ab * t);
                (d.norm() - radius, safe(d))
            }
            AnalyticShape::Slab { min, max } => {
                let c = (Vector3::from(min) + Vector3::from(max)) * 0.5;
                let h = (Vector3::from(max) - Vector3::from(min)) * 0.5;
                let d = p - c;
                let q = d.abs() - h;
                let outside = q.map(|x| x.max(0.0));
                if outside.norm() > 0.0 {
                    let n = outside.component_mul(&d.map(|x| x.signum()));
                    (outside.norm(), safe(n))
                } else {
                    let k = q.imax();
                    let mut n = Vector3::zeros();
                    n[k] = d[k].signum();
                    (q.max(), n)
                }
            }
        }
    }
}

/// A procedural volume: a union of [`AnalyticShape`]s in the unit cube, sampled at voxel centres.
/// Coverage `clamp(0.5 − sd/h, 0, 1)` (a one-voxel ramp, `h` the voxel size), normal = gradient of
/// the nearest shape where `|sd| < h` (the surface shell), `None` deeper inside; each shape has a
/// colour. Cost per voxel: one distance per shape.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyticVolume {
    /// Name used in reports.
    pub name: String,
    /// Voxels per side (the volume is `n³`).
    pub n: usize,
    /// Shapes and their linear RGB colours.
    pub shapes: Vec<(AnalyticShape, [f32; 3])>,
}

impl AnalyticVolume {
    /// A sphere and a torus around it (smooth closed surfaces).
    pub fn sphere_torus(n: usize) -> Self {
        Self {
            name: "sphere-torus".into(),
            n,
            shapes: vec![
                (
                    AnalyticShape::Sphere {
                        center: [0.5, 0.5, 0.5],
                        radius: 0.25,
                    },
                    [0.8, 0.3, 0.2],
                ),
                (
                    AnalyticShape::Torus {
                        center: [0.5, 0.5, 0.5],
                        major: 0.36,
                        minor: 0.07,
                    },
                    [0.2, 0.6, 0.3],
                ),
            ],
        }
    }

    /// A lawn texel like the seed's: a ground slab and 16 tilted grass blades (capsules), seeded.
    pub fn lawn(n: usize, seed: u64) -> Self {
        let mut rng = super::rng::SplitMix64::new(seed);
        let mut shapes = vec![(
            AnalyticShape::Slab {
                min: [0.0, 0.0, 0.0],
                max: [1.0, 0.08, 1.0],
            },
            [0.35, 0.25, 0.15],
        )];
        for i in 0..16 {
            let (gx, gz) = ((i % 4) as f64, (i / 4) as f64);
            let base = [
                0.125 + 0.25 * gx + rng.range(-0.06, 0.06),
                0.08,
                0.125 + 0.25 * gz + rng.range(-0.06, 0.06),
            ];
            let tilt = rng.range(0.0, 0.35);
            let az = rng.range(0.0, std::f64::consts::TAU);
            let h = rng.range(0.6, 0.85);
            let tip = [
                (base[0] + h * tilt.sin() * az.cos()).clamp(0.03, 0.97),
                base[1] + h * tilt.cos(),
                (base[2] + h * tilt.sin() * az.sin()).clamp(0.03, 0.97),
            ];
            shapes.push((
                AnalyticShape::Capsule {
                    a: base,
                    b: tip,
                    radius: 0.018,
                },
                [0.2, 0.55 + 0.02 * i as f32, 0.15],
            ));
        }
        Self {
            name: "lawn".into(),
            n,
            shapes,
        }
    }
}

impl VoxelSource for AnalyticVolume {
    fn dims(&self) -> [usize; 3] {
        [self.n; 3]
    }

    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel {
        let h = 1.0 / self.n as f64;
        let p = Vector3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) * h;
        let mut best: Option<(f64, Vector3<f64>, [f32; 3])> = None;
        for (shape, color) in &self.shapes {
            let (d, g) = shape.sdf(&p);
            if best.is_none_or(|(bd, _, _)| d < bd) {
                best = Some((d, g, *color));
            }
        }
        let Some((d, g, color)) = best else {
            return Voxel::EMPTY;
        };
        let density = (0.5 - d / h).clamp(0.0, 1.0) as f32;
        if density == 0.0 {
            return Voxel::EMPTY;
        }
        Voxel {
            density,
            color,
            normal: (d.abs() < h).then(|| [g.x as f32, g.y as f32, g.z as f32]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn pack_round_trip() {
        let e = Ellipsoid::spheroid(Vector3::new(1.0, 2.0, -0.5), 0.1, 1.3).unwrap();
        let back = PackedEllipsoid::pack(&e).unpack().unwrap();
        let (q1, q2) = (e.quadratic_form(), back.quadratic_form());
        assert!((q1 - q2).amax() < 1e-5 * q1.amax());
    }
}
