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
        let side = (1u64 << self.depth) as f64;
        let half = 0.5 * side;
        self.render_view(
            level,
            params,
            &OctreeView {
                dir: [0.0, 0.0, 1.0],
                right: [1.0, 0.0, 0.0],
                up: [0.0, 1.0, 0.0],
                centre: [half; 3],
                half_width: half,
                width: 1 << self.depth,
                height: 1 << self.depth,
            },
        )
    }

    /// Renders the volume as seen at `level` along any orthographic view (the shading and
    /// compositing of [`Self::render_level`], with the view direction `view.dir` in the
    /// micro-primitives' projected area and reflectance). Each pixel's ray enters the cube
    /// `[0, 2^depth]³` on the camera's side and takes `steps_per_voxel` samples per voxel length
    /// at half-step offsets until it leaves; [`Self::render_level`] is the view along +z.
    ///
    /// Returns a premultiplied linear-RGB image `view.width × view.height`. Errors: bad
    /// parameters or a view whose vectors are not finite, unit and orthogonal. Cost: one
    /// reflectance per stored node plus up to `√3 · 2^depth · steps_per_voxel` lookups per pixel
    /// (rayon over rows).
    pub fn render_view(
        &self,
        level: u32,
        params: &OctreeRenderParams,
        view: &OctreeView,
    ) -> Result<altrep_data_gen::RgbaImage, EllipsoidError> {
        Ok(self.render_view_counted(level, params, view)?.0)
    }

    /// The per-node shading of [`Self::render_view`] along `view_dir` (unit, toward the camera):
    /// per stored node, in node order, its extinction per voxel length `σ = τ ρ A(v)/π` and its
    /// emitted linear RGB `albedo × (ambient + (1 − ambient) π ρ_d(l, v))` (zero for a node
    /// without a micro-primitive). Constant over an orthographic view: a GPU twin uploads it per
    /// draw. Errors: a light that is not finite and non-zero, `tau` or `ambient` not finite and
    /// ≥ 0. Cost: one reflectance (72 samples) per stored node, in parallel.
    pub fn node_shading(
        &self,
        params: &OctreeRenderParams,
        view_dir: [f64; 3],
    ) -> Result<Vec<(f64, [f64; 3])>, EllipsoidError> {
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
        let dir = Vector3::from(view_dir);
        let lambert = crate::ellipsoid::primitive::Phong {
            diffuse: 1.0,
            specular: 0.0,
            exponent: 0.0,
        };
        let ambient = params.ambient.min(1.0);
        Ok(self
            .nodes
            .par_iter()
            .map(|n| match n.ellipsoid.and_then(|e| e.unpack().ok()) {
                Some(e) if n.density > 0.0 => {
                    let sigma = params.tau * f64::from(n.density) * e.projected_area(&dir)
                        / std::f64::consts::PI;
                    let rho = e
                        .reflectance_apparent_ellipse(&light, &dir, &lambert, 6)
                        .unwrap_or(0.0);
                    let k = ambient + (1.0 - ambient) * std::f64::consts::PI * rho;
                    (sigma, n.color.map(|c| f64::from(c) * k))
                }
                _ => (0.0, [0.0; 3]),
            })
            .collect())
    }

    /// [`Self::render_view`] with, per pixel (row-major), the samples its ray took (each a
    /// descent of the tree to `level`; the march stops when the transmittance falls below
    /// `10⁻⁴`): the steps a display's fragments take. Errors and cost: as
    /// [`Self::render_view`].
    pub fn render_view_counted(
        &self,
        level: u32,
        params: &OctreeRenderParams,
        view: &OctreeView,
    ) -> Result<(altrep_data_gen::RgbaImage, Vec<u32>), EllipsoidError> {
        if params.steps_per_voxel == 0 {
            return Err(EllipsoidError::BadParameter {
                name: "steps_per_voxel",
                reason: "must be ≥ 1".into(),
            });
        }
        view.validate()?;
        let shading = self.node_shading(params, view.dir)?;
        let [dir, right, up] = [view.dir, view.right, view.up].map(Vector3::from);
        let centre = Vector3::from(view.centre);
        let side = (1u64 << self.depth) as f64;
        let ds = 1.0 / params.steps_per_voxel as f64;
        let (w, h) = (view.width, view.height);
        let mut image = altrep_data_gen::RgbaImage::new(w, h);
        let mut counts = vec![0u32; w * h];
        image
            .pixels
            .par_chunks_mut(w)
            .zip(counts.par_chunks_mut(w))
            .enumerate()
            .for_each(|(j, (row, count))| {
                let y = 1.0 - 2.0 * (j as f64 + 0.5) / h as f64;
                for (i, (px, taken)) in row.iter_mut().zip(count.iter_mut()).enumerate() {
                    let x = -1.0 + 2.0 * (i as f64 + 0.5) / w as f64;
                    let p0 = centre + view.half_width * (x * right + y * up);
                    // The points p0 + s·dir inside the cube, s ∈ [s_min, s_max]; the camera is at +s.
                    let (mut s_min, mut s_max) = (f64::NEG_INFINITY, f64::INFINITY);
                    for a in 0..3 {
                        if dir[a] == 0.0 {
                            if !(0.0..=side).contains(&p0[a]) {
                                (s_min, s_max) = (1.0, 0.0);
                            }
                            continue;
                        }
                        let (t0, t1) = (-p0[a] / dir[a], (side - p0[a]) / dir[a]);
                        s_min = s_min.max(t0.min(t1));
                        s_max = s_max.min(t0.max(t1));
                    }
                    let steps = if s_max > s_min {
                        ((s_max - s_min) / ds - 0.5).ceil().max(0.0) as usize
                    } else {
                        0
                    };
                    let mut t = 1.0f64;
                    let mut c = [0.0f64; 3];
                    for k in 0..steps {
                        *taken += 1;
                        let p = p0 + (s_max - (k as f64 + 0.5) * ds) * dir;
                        let Some((index, _)) = self.find([p.x, p.y, p.z], level) else {
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
        Ok((image, counts))
    }

    /// [`Self::lookup`] at the level chosen by [`Self::level_for_footprint`].
    pub fn lookup_footprint(&self, p: [f64; 3], footprint: f64) -> Option<NodeSample> {
        self.lookup(p, self.level_for_footprint(footprint))
    }
}

/// An orthographic view of an octree's cube `[0, 2^depth]³` (voxel units) for
/// [`Octree::render_view`]. The cube is a uniform scaling of the box it was voxelised from, so a
/// direction in that box's frame serves unchanged. Pixel `(i, j)` of the `width × height` image
/// is centred on `centre + half_width · (X·right + Y·up)` with `X = −1 + 2(i + ½)/width` and
/// `Y = 1 − 2(j + ½)/height` (row 0 at the top), the screen convention of
/// [`altrep_data_gen::OrthoFrame`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OctreeView {
    /// Unit direction toward the camera; rays run along `−dir`.
    pub dir: [f64; 3],
    /// Unit screen right, orthogonal to `dir`.
    pub right: [f64; 3],
    /// Unit screen up, orthogonal to `dir` and `right`.
    pub up: [f64; 3],
    /// Centre of the window (voxel coordinates).
    pub centre: [f64; 3],
    /// Half the window's width and height (voxel units, > 0).
    pub half_width: f64,
    /// Image width (pixels, ≥ 1).
    pub width: usize,
    /// Image height (pixels, ≥ 1).
    pub height: usize,
}

impl OctreeView {
    /// Checks the view: finite values, unit orthogonal vectors (to 1e-6), a positive window and
    /// a non-empty image. Errors name the field.
    pub fn validate(&self) -> Result<(), EllipsoidError> {
        let bad =
            |name: &'static str, reason: String| Err(EllipsoidError::BadParameter { name, reason });
        let v = [self.dir, self.right, self.up].map(Vector3::from);
        for (name, x) in ["dir", "right", "up"].into_iter().zip(&v) {
            if !x.iter().all(|c| c.is_finite()) || (x.norm() - 1.0).abs() > 1e-6 {
                return bad(name, format!("must be a finite unit vector, got {x:?}"));
            }
        }
        if v[0].dot(&v[1]).abs() > 1e-6
            || v[0].dot(&v[2]).abs() > 1e-6
            || v[1].dot(&v[2]).abs() > 1e-6
        {
            return bad("dir, right, up", "must be orthogonal".into());
        }
        if !self.centre.iter().all(|c| c.is_finite()) {
            return bad("centre", format!("must be finite, got {:?}", self.centre));
        }
        if !(self.half_width.is_finite() && self.half_width > 0.0) {
            return bad(
                "half_width",
                format!("must be finite and > 0, got {}", self.half_width),
            );
        }
        if self.width == 0 || self.height == 0 {
            return bad("width, height", "must be ≥ 1".into());
        }
        Ok(())
    }
}

/// Parameters of [`Octree::render_level`] and [`Octree::render_view`].
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
