//! Reading an octree: the level for a footprint, point lookup, and the CPU ray-marched picture
//! of one level ([`Octree::render_level`]).

use nalgebra::Vector3;
use rayon::prelude::*;

use super::storage::{NodeSample, Octree};
use crate::ellipsoid::error::EllipsoidError;

impl Octree {
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
    /// padded cube — Neyret 1995's volume rendering reduced to local illumination:
    ///
    /// - extinction `σ = τ ρ A(v)/π` per voxel length (density modulated by the micro-primitive's
    ///   projected area along the view, `π` being a normalised primitive's mean);
    /// - emitted colour `albedo × (ambient + (1 − ambient) π ρ_d(l, v))`, with `ρ_d` the diffuse
    ///   reflectance of the node's ellipsoid ([`Ellipsoid::reflectance_apparent_ellipse`](crate::ellipsoid::primitive::Ellipsoid::reflectance_apparent_ellipse), 72
    ///   samples per node, computed once per node);
    /// - front-to-back compositing, `steps_per_voxel` samples per voxel length; no shadow rays.
    ///
    /// Returns a premultiplied linear-RGB image. Errors: bad parameters. Cost: one reflectance per
    /// stored node plus `side² × side × steps_per_voxel` lookups (rayon over rows).
    pub fn render_level(
        &self,
        level: u32,
        params: &OctreeRenderParams,
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
        let lambert = crate::ellipsoid::primitive::Phong {
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
pub struct OctreeRenderParams {
    /// Direction toward the light (object frame, any length).
    pub light: Vector3<f64>,
    /// Ambient share of the shading in `[0, 1]`.
    pub ambient: f64,
    /// Optical depth per voxel length at density 1 (`τ` of Neyret 1995's `e^{−τρL}`).
    pub tau: f64,
    /// Samples per voxel length along a ray (≥ 1).
    pub steps_per_voxel: usize,
}

impl Default for OctreeRenderParams {
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
