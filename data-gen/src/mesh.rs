//! Triangle meshes from Wavefront OBJ (`tobj`), normalised into the bounding cylinder and
//! ray-cast through a compressed wide BVH (`obvhs`'s CWBVH, built with PLOC).
//!
//! The BVH is built once, on the first ray query or on [`Mesh::prepare_rays`], not at load: the
//! inside test of voxelisation ([`Shape::contains_row`]) needs no BVH, so a pipeline can voxelise
//! while another thread builds it, and a mesh that is only voxelised never builds one. Ray
//! queries see the triangles in the BVH's leaf order (ties between equal distances follow it);
//! the inside test counts crossings, which no order changes.
//!
//! Normalisation: translate so that the centre of the bounding box's x–z extent lies on the `y`
//! axis and the lowest vertex at `y = 0`; scale uniformly by the largest factor that keeps every
//! vertex within radius `R` of the axis and below `H`; then centre vertically in `[0, H]`.
//!
//! Colour: the per-vertex colour of the OBJ when present (interpolated), else the material's
//! diffuse colour when the MTL file is found, else a procedural albedo (stripes by azimuth and
//! height) so that warping errors show in images.
//!
//! Ray casting runs in `f32` inside the BVH (relative precision about 1e-6 of the object size);
//! the hit parameter is returned in `f64`.

use std::path::Path;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use glam::{DVec3, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    bvh2::reinsertion::ReinsertionOptimizer,
    cwbvh::{CwBvh, bvh2_to_cwbvh::bvh2_to_cwbvh},
    ploc::PlocBuilder,
    ray::{Ray as BvhRay, RayHit},
    triangle::Triangle,
};
use rayon::prelude::*;

use crate::albedo::Albedo;
use crate::binned::MeshTracer;
use crate::error::DataGenError;
use crate::geometry::{BoundingCylinder, Hit, ParallelRays, RadialRays, Ray};
use crate::radial::RadialTracer;
use crate::shape::{OneByOne, ParallelTracer, RadialOneByOne, Shape};

/// How to load and normalise a mesh.
#[derive(Clone, Debug)]
pub struct MeshLoadOptions {
    /// The cylinder to normalise into (default `R = 1`, `H = 2`).
    pub cylinder: BoundingCylinder,
    /// Colour when the file has neither vertex colours nor materials.
    pub fallback_albedo: Albedo,
}

impl Default for MeshLoadOptions {
    fn default() -> Self {
        Self {
            cylinder: BoundingCylinder::default(),
            fallback_albedo: Albedo::Stripes {
                a: Vec3::new(0.85, 0.55, 0.25),
                b: Vec3::new(0.35, 0.55, 0.8),
                count: 10,
            },
        }
    }
}

/// Where a triangle's colour comes from.
#[derive(Clone, Debug)]
enum TriColor {
    /// Per-vertex colours.
    Vertex([Vec3; 3]),
    /// One colour for the face.
    Flat(Vec3),
    /// The procedural fallback.
    Procedural,
}

/// A normalised triangle mesh. Implements [`Shape`]; its BVH is built on first need (module
/// docs).
pub struct Mesh {
    name: String,
    /// The kept (non-degenerate) triangles in input order: the inside test's.
    input: Vec<Triangle>,
    /// Each input triangle's colour; empty when every triangle takes the fallback.
    input_colors: Vec<TriColor>,
    fallback: Albedo,
    pub(crate) bounds: (DVec3, DVec3),
    /// The BVH and the triangles in its leaf order, built on the first ray query.
    traced: OnceLock<Traced>,
    /// Triangles binned across the parity ray, built on the first [`Shape::contains_row`].
    yz_grid: OnceLock<YzGrid>,
}

/// What ray queries read: the BVH and the triangles, normals and colours in its leaf order.
pub(crate) struct Traced {
    pub(crate) triangles: Vec<Triangle>,
    /// Each triangle's unit geometric normal (`obvhs`'s `compute_normal`, widened to `f64`).
    normals: Vec<DVec3>,
    /// Each triangle's colour; empty when every triangle takes the fallback (a mesh without
    /// colours then reads no colour record per hit).
    colors: Vec<TriColor>,
    bvh: CwBvh,
    /// Time spent building the BVH (the leaf reordering and normals excluded).
    build_time: Duration,
}

/// The BVH's boxes are padded by this fraction of the mesh's largest extent.
///
/// The walk's slab test takes `±2²³` for the inverse of a direction component of at most
/// `f32::EPSILON` (`obvhs::ray::safe_inverse`), so a ray lying in the face of a tight box (an
/// edge of a mesh symmetric about an axis plane, a flat mesh seen edge-on) leaves that box at
/// `t = 0` while the triangle test inside still accepts its hit: the walk would see through
/// the surface. A pad `p` of the largest extent `s` keeps every point the triangle test accepts
/// (within a few `f32` ulps of its triangle) strictly inside every box on its path, and the
/// clamped inverse still spans `p·2²³ ≈ 128·s` on either side, beyond any ray window
/// (`≤ 4·s`). Padding only adds candidates: the nearest hit is unchanged wherever the tight
/// boxes found it.
const BOX_PAD: f32 = 1.0 / 65536.0;

/// Builds `obvhs`'s CWBVH as its `build_cwbvh_from_tris` does with
/// [`BvhBuildParams::medium_build`] (PLOC, then reinsertion, then conversion with at most 3
/// triangles per leaf), with every binary node's box padded by [`BOX_PAD`] before the
/// conversion (the binary tree's topology is that of the tight boxes). Serial.
fn build_padded_cwbvh(triangles: &[Triangle]) -> CwBvh {
    let params = BvhBuildParams::medium_build();
    let mut bvh2 = PlocBuilder::with_capacity(triangles.len()).build(
        params.ploc_search_distance,
        triangles,
        (0..triangles.len() as u32).collect(),
        params.sort_precision,
        params.search_depth_threshold,
    );
    ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
    if let Some(root) = bvh2.nodes.first() {
        let root = *root.aabb();
        let pad = Vec3A::splat((root.max - root.min).max_element() * BOX_PAD);
        for node in &mut bvh2.nodes {
            let b = *node.aabb();
            node.set_aabb(Aabb {
                min: b.min - pad,
                max: b.max + pad,
            });
        }
    }
    bvh2_to_cwbvh(&bvh2, params.max_prims_per_leaf.clamp(1, 3), true, false)
}

impl Traced {
    /// Builds the BVH over `triangles` and stores them in its leaf order (spatially coherent,
    /// so that neighbouring rays read neighbouring triangles; the BVH then indexes them
    /// directly and each ray still tests the same triangles in the same order). The reordering
    /// is skipped if the leaves are not a permutation of the triangles. Serial (`obvhs`
    /// without its `parallel` feature): it never waits on the thread pool.
    fn build(triangles: &[Triangle], colors: &[TriColor]) -> Self {
        let start = Instant::now();
        let mut bvh = build_padded_cwbvh(triangles);
        let build_time = start.elapsed();
        let order = &bvh.primitive_indices;
        let mut seen = vec![false; triangles.len()];
        let permutation = order.len() == triangles.len()
            && order.iter().all(|&i| {
                (i as usize) < seen.len() && !std::mem::replace(&mut seen[i as usize], true)
            });
        let (triangles, colors) = if permutation {
            let t: Vec<Triangle> = order.iter().map(|&i| triangles[i as usize]).collect();
            let c = if colors.is_empty() {
                Vec::new()
            } else {
                order.iter().map(|&i| colors[i as usize].clone()).collect()
            };
            bvh.primitive_indices = (0..order.len() as u32).collect();
            (t, c)
        } else {
            (triangles.to_vec(), colors.to_vec())
        };
        let normals = triangles
            .iter()
            .map(|t| {
                let g = t.compute_normal();
                DVec3::new(g.x.into(), g.y.into(), g.z.into())
            })
            .collect();
        Self {
            triangles,
            normals,
            colors,
            bvh,
            build_time,
        }
    }
}

impl std::fmt::Debug for Mesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mesh")
            .field("name", &self.name)
            .field("triangles", &self.input.len())
            .field("bounds", &self.bounds)
            .finish()
    }
}

impl Mesh {
    /// Loads an OBJ file (triangulating polygons) and normalises it. Materials (`mtllib`) are
    /// read from files beside it. The BVH is not built yet (module docs).
    ///
    /// Errors: [`DataGenError::Io`] if the file cannot be read, [`DataGenError::ObjParse`] if it
    /// is not OBJ, [`DataGenError::NonFinite`] for NaN/infinite coordinates,
    /// [`DataGenError::EmptyMesh`] if no non-degenerate triangle remains.
    pub fn load_obj(
        path: impl AsRef<Path>,
        options: &MeshLoadOptions,
    ) -> Result<Self, DataGenError> {
        let path = path.as_ref();
        // Read the bytes ourselves first: a missing file is an I/O error, not a parse error.
        let bytes = std::fs::read(path).map_err(|source| DataGenError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_obj_bytes(&bytes, path, options)
    }

    /// Parses OBJ text already read from `path` (the file is not read again; `path` names the
    /// mesh, its errors, and the folder its materials are read from) and normalises it, as
    /// [`Mesh::load_obj`] does. For callers that also hash the bytes.
    ///
    /// Errors: as [`Mesh::load_obj`], except that nothing is read but the materials.
    pub fn from_obj_bytes(
        bytes: &[u8],
        path: &Path,
        options: &MeshLoadOptions,
    ) -> Result<Self, DataGenError> {
        if std::str::from_utf8(bytes).is_err() {
            return Err(DataGenError::ObjParse {
                path: path.to_path_buf(),
                message: "the file is not text (invalid UTF-8)".into(),
            });
        }
        let load = tobj::LoadOptions {
            triangulate: true,
            single_index: false,
            ..Default::default()
        };
        // As `tobj::load_obj` does, from the bytes: materials relative to the file's folder.
        let (models, materials) = tobj::load_obj_buf(&mut &bytes[..], &load, |mtl| {
            tobj::load_mtl(
                path.parent()
                    .map_or_else(|| mtl.to_owned(), |d| d.join(mtl)),
            )
        })
        .map_err(|e| DataGenError::ObjParse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let materials = materials.unwrap_or_default();
        let total: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
        let mut positions = Vec::with_capacity(total);
        let mut colors = Vec::with_capacity(total);
        for model in &models {
            let m = &model.mesh;
            let faces = m.indices.len() / 3;
            // The first face corner (in file order) that refers to a missing vertex.
            let vertices = m.positions.len() / 3;
            if let Some(&i) = m.indices[..3 * faces]
                .iter()
                .find(|&&i| i as usize >= vertices)
            {
                return Err(DataGenError::ObjParse {
                    path: path.to_path_buf(),
                    message: format!("face refers to vertex {} which does not exist", i + 1),
                });
            }
            let vertex = |k: usize| {
                let i = 3 * m.indices[k] as usize;
                let p = &m.positions[i..i + 3];
                [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]
            };
            let material_color = m
                .material_id
                .and_then(|id| materials.get(id))
                .and_then(|mat| mat.diffuse)
                .map(|d| Vec3::new(d[0], d[1], d[2]));
            let has_vc = m.vertex_color.len() == m.positions.len() && !m.vertex_color.is_empty();
            positions.par_extend(
                (0..faces)
                    .into_par_iter()
                    .map(|tri| [vertex(3 * tri), vertex(3 * tri + 1), vertex(3 * tri + 2)]),
            );
            colors.par_extend((0..faces).into_par_iter().map(|tri| {
                if has_vc {
                    let c = |k: usize| {
                        let i = m.indices[3 * tri + k] as usize;
                        Vec3::new(
                            m.vertex_color[3 * i],
                            m.vertex_color[3 * i + 1],
                            m.vertex_color[3 * i + 2],
                        )
                    };
                    TriColor::Vertex([c(0), c(1), c(2)])
                } else if let Some(c) = material_color {
                    TriColor::Flat(c)
                } else {
                    TriColor::Procedural
                }
            }));
        }
        let name = path
            .file_stem()
            .map_or_else(|| "mesh".into(), |s| s.to_string_lossy().into_owned());
        Self::from_triangles(name, positions, colors, options)
    }

    /// Builds a mesh from raw triangles (`[[x, y, z]; 3]` each, any scale), normalising it.
    /// All triangles take the fallback albedo of `options`.
    pub fn from_raw_triangles(
        name: impl Into<String>,
        triangles: Vec<[[f64; 3]; 3]>,
        options: &MeshLoadOptions,
    ) -> Result<Self, DataGenError> {
        let colors = vec![TriColor::Procedural; triangles.len()];
        Self::from_triangles(name.into(), triangles, colors, options)
    }

    fn from_triangles(
        name: String,
        positions: Vec<[[f64; 3]; 3]>,
        colors: Vec<TriColor>,
        options: &MeshLoadOptions,
    ) -> Result<Self, DataGenError> {
        options.cylinder.validate()?;
        let finite = |tri: &[[f64; 3]; 3]| tri.iter().flatten().all(|c| c.is_finite());
        if let Some(t) = positions.par_iter().position_first(|tri| !finite(tri)) {
            return Err(DataGenError::NonFinite {
                what: format!("vertex of triangle {t} in {name}"),
                index: t,
            });
        }
        // Bounds of the raw vertices, in file order (the sign of a zero bound may depend on
        // the order, so this stays serial).
        let (lo, hi) = positions.iter().flatten().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(DVec3::from(*v)), hi.max(DVec3::from(*v))),
        );
        if positions.is_empty() {
            return Err(DataGenError::EmptyMesh { name });
        }
        let centre = DVec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z));
        // Non-negative, never NaN: the maximum is the same in any order.
        let max_radius = positions
            .par_iter()
            .flatten()
            .map(|v| {
                let d = DVec3::from(*v) - centre;
                (d.x * d.x + d.z * d.z).sqrt()
            })
            .reduce(|| 0.0, f64::max);
        let height = hi.y - lo.y;
        let cyl = options.cylinder;
        let scale = match (max_radius > 0.0, height > 0.0) {
            (true, true) => (cyl.radius / max_radius).min(cyl.height / height),
            (true, false) => cyl.radius / max_radius,
            (false, true) => cyl.height / height,
            (false, false) => return Err(DataGenError::EmptyMesh { name }),
        };
        // A hair inside the cylinder so that capture rays starting on it see every vertex.
        let scale = scale * (1.0 - 1e-6);
        let lift = 0.5 * (cyl.height - height * scale);
        let to_f32 = |v: &[f64; 3]| {
            let p = (DVec3::from(*v) - centre) * scale + DVec3::new(0.0, lift, 0.0);
            Vec3A::new(p.x as f32, p.y as f32, p.z as f32)
        };
        // Degenerate triangles (zero area in `f32`) are dropped; the order is kept.
        let (triangles, mut kept_colors): (Vec<Triangle>, Vec<TriColor>) = positions
            .par_iter()
            .zip(colors)
            .filter_map(|(tri, color)| {
                let t = Triangle {
                    v0: to_f32(&tri[0]),
                    v1: to_f32(&tri[1]),
                    v2: to_f32(&tri[2]),
                };
                ((t.v1 - t.v0).cross(t.v2 - t.v0).length_squared() > 0.0).then_some((t, color))
            })
            .unzip();
        if triangles.is_empty() {
            return Err(DataGenError::EmptyMesh { name });
        }
        let bounds = triangles.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), t| {
                let (a, b) = (t.aabb().min, t.aabb().max);
                (
                    lo.min(DVec3::new(a.x.into(), a.y.into(), a.z.into())),
                    hi.max(DVec3::new(b.x.into(), b.y.into(), b.z.into())),
                )
            },
        );
        if kept_colors
            .iter()
            .all(|c| matches!(c, TriColor::Procedural))
        {
            kept_colors = Vec::new();
        }
        Ok(Self {
            name,
            input: triangles,
            input_colors: kept_colors,
            fallback: options.fallback_albedo.clone(),
            bounds,
            traced: OnceLock::new(),
            yz_grid: OnceLock::new(),
        })
    }

    /// Number of triangles kept (degenerate ones are dropped).
    pub fn triangle_count(&self) -> usize {
        self.input.len()
    }

    /// Time spent building the BVH, `None` before it is built.
    pub fn bvh_build_time(&self) -> Option<Duration> {
        self.traced.get().map(|t| t.build_time)
    }

    /// The BVH and the triangles in its leaf order, built on first use.
    pub(crate) fn traced(&self) -> &Traced {
        self.traced
            .get_or_init(|| Traced::build(&self.input, &self.input_colors))
    }

    pub(crate) fn to_bvh_ray(ray: &Ray, t_min: f64, t_max: f64) -> BvhRay {
        let o = ray.origin.as_vec3();
        // `+ 0.0` turns −0.0 into +0.0: the BVH's octant logic reads sign bits, and a view at
        // α = 0 has direction (−1, −0, −0).
        let d = ray.dir.as_vec3() + Vec3::ZERO;
        BvhRay::new(
            o.into(),
            d.into(),
            t_min.max(0.0) as f32,
            t_max.min(f64::from(f32::MAX)) as f32,
        )
    }

    /// The BVH walk of [`Shape::intersect`]: the nearest triangle on `ray` in `(t_min, t_max)`
    /// and its `f32` distance.
    pub(crate) fn first_hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<(usize, f32)> {
        let bray = Self::to_bvh_ray(ray, t_min, t_max);
        let mut hit = RayHit::none();
        let tr = self.traced();
        let tris = &tr.triangles;
        let idx = &tr.bvh.primitive_indices;
        tr.bvh
            .ray_traverse(bray, &mut hit, |r, id| tris[idx[id] as usize].intersect(r))
            .then(|| (idx[hit.primitive_id as usize] as usize, hit.t))
    }

    /// The hit record of `ray` meeting triangle `tri_id` at distance `t`: the geometric normal
    /// turned toward the ray and the triangle's colour at the hit point.
    pub(crate) fn hit_at(&self, ray: &Ray, tri_id: usize, t: f32) -> Hit {
        let tr = self.traced();
        let tri = &tr.triangles[tri_id];
        let t = f64::from(t);
        let n = tr.normals[tri_id];
        // Winding is not trusted: the normal faces the incoming ray.
        let n = if n.dot(ray.dir) > 0.0 { -n } else { n };
        let p = ray.at(t);
        let albedo = match tr.colors.get(tri_id) {
            Some(TriColor::Vertex(c)) => {
                let w = barycentric(tri, p);
                c[0] * w[0] + c[1] * w[1] + c[2] * w[2]
            }
            Some(TriColor::Flat(c)) => *c,
            Some(TriColor::Procedural) | None => self.fallback.at(p),
        };
        Hit {
            t,
            normal: n,
            albedo,
        }
    }
}

impl Shape for Mesh {
    fn name(&self) -> &str {
        &self.name
    }

    /// Builds the BVH now if no ray query has built it yet (about 0.8 µs per triangle on one
    /// core, serial: the Stanford bunny's 69 k triangles take 50–70 ms), so that the first ray
    /// query does not pay for it. Threads that query rays meanwhile wait for this build.
    fn prepare_rays(&self) {
        self.traced();
    }

    fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        self.first_hit(ray, t_min, t_max)
            .map(|(tri, t)| self.hit_at(ray, tri, t))
    }

    /// The BVH walk stopped at the first triangle whose test accepts the ray, without shading.
    /// Until its first hit the nearest-hit walk is exactly this walk (its window shrinks only
    /// at a hit), so both agree.
    fn occluded(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        let bray = Self::to_bvh_ray(ray, t_min, t_max);
        let tr = self.traced();
        let (tris, idx) = (&tr.triangles, &tr.bvh.primitive_indices);
        !tr.bvh
            .ray_traverse_miss(bray, |r, id| tris[idx[id] as usize].intersect(r))
    }

    /// Triangles binned over the grid ([`crate::binned`]) instead of a BVH walk per ray, when
    /// the grid has at least `3/4` as many rays as the mesh has triangles; smaller grids walk.
    ///
    /// Binning costs about 110 ns per triangle and 55 ns per ray on one core, a walk 250–700
    /// ns per ray (release build, 8 views): at 64² the Stanford bunny (69 k triangles) took
    /// 62 ms binned against 23 ms walked, the teapot (6.3 k) 9.7 against 8.3 ms; at 128² the
    /// rocker arm (20 k) 32 against 37 ms; at 512² binning is 1.6–2.2× faster on all three.
    fn parallel_tracer<'a>(&'a self, rays: &'a ParallelRays<'a>) -> Box<dyn ParallelTracer + 'a> {
        // Decided before building the tracer, which projects every triangle.
        let worth_it = 4 * rays.len() >= 3 * self.input.len();
        match worth_it.then(|| MeshTracer::new(self, rays)).flatten() {
            Some(t) => Box::new(t),
            None => Box::new(OneByOne { shape: self, rays }),
        }
    }

    /// Triangles binned by height and angle ([`crate::radial`]) instead of a BVH walk per ray,
    /// under the same rule as [`Shape::parallel_tracer`]: when the grid has at least `3/4` as
    /// many rays as the mesh has triangles; smaller grids walk.
    ///
    /// The pipeline's capture (768 × 192 rays, one core, release build): the Stanford bunny
    /// 39 ms binned against 81 ms walked, the teapot 13.4 against 42 ms. The binned rays also
    /// keep the hits the walk drops on columns along `x` or `z` (see [`crate::radial`]).
    fn radial_tracer<'a>(&'a self, rays: &'a RadialRays<'a>) -> Box<dyn ParallelTracer + 'a> {
        let worth_it = 4 * rays.len() >= 3 * self.input.len();
        match worth_it.then(|| RadialTracer::new(self, rays)).flatten() {
            Some(t) => Box::new(t),
            None => Box::new(RadialOneByOne { shape: self, rays }),
        }
    }

    /// Inside test by ray parity along `+x` (exact for closed meshes; meshes with holes may
    /// misclassify points whose parity ray leaves through a hole).
    fn contains(&self, p: DVec3) -> bool {
        let ray = BvhRay::new(p.as_vec3().into(), parity_dir(), 0.0, f32::MAX);
        let mut crossings = 0u32;
        let tr = self.traced();
        let tris = &tr.triangles;
        let idx = &tr.bvh.primitive_indices;
        tr.bvh.ray_traverse_anyhit(ray, |r, id| {
            if tris[idx[id] as usize].intersect(r).is_finite() {
                crossings += 1;
            }
        });
        crossings % 2 == 1
    }

    /// The same answers as [`Shape::contains`] point by point, at a fraction of the cost: the
    /// parity rays of a row of points `(x, y, z)` are parallel and nearly the same line, so the
    /// triangles they can cross are gathered once per row from a grid of the triangles binned by
    /// their y–z extent (widened by more than the rays' drift across the mesh), and each point's
    /// ray is tested against those only, with the same ray and the same triangle test as
    /// [`Shape::contains`]. Cost per row: one grid cell's list, then `O(candidates)` triangle
    /// tests per point (instead of one BVH traversal per point). Rows whose rays could drift out
    /// of a cell (points far to the left of the mesh) or with non-finite coordinates take the
    /// per-point path.
    fn contains_row(&self, y: f64, z: f64, xs: &[f64], inside: &mut [bool]) {
        let grid = self.yz_grid.get_or_init(|| YzGrid::new(&self.input));
        let (oy, oz) = (y as f32, z as f32);
        let x_lo = xs.iter().fold(f64::INFINITY, |m, &x| m.min(x));
        let finite = oy.is_finite() && oz.is_finite() && xs.iter().all(|x| (*x as f32).is_finite());
        let dir = parity_dir();
        let reach = (grid.x_max - x_lo as f32).max(0.0);
        let (my, mz) = (
            reach * dir.y / dir.x + YzGrid::SLOP,
            reach * dir.z / dir.x + YzGrid::SLOP,
        );
        if !finite || my > YzGrid::MARGIN || mz > YzGrid::MARGIN {
            for (x, o) in xs.iter().zip(inside.iter_mut()) {
                *o = self.contains(DVec3::new(*x, y, z));
            }
            return;
        }
        let Some(cell) = grid.cell(oy, oz) else {
            // No triangle's widened extent reaches the row: every parity ray misses.
            inside.iter_mut().take(xs.len()).for_each(|o| *o = false);
            return;
        };
        let candidates: Vec<(f32, u32)> = grid.tris
            [grid.start[cell] as usize..grid.start[cell + 1] as usize]
            .iter()
            .filter_map(|&t| {
                let b = &grid.boxes[t as usize];
                (b[1] - my <= oy && oy <= b[2] + my && b[3] - mz <= oz && oz <= b[4] + mz)
                    .then_some((b[0] + YzGrid::SLOP, t))
            })
            .collect();
        for (x, o) in xs.iter().zip(inside.iter_mut()) {
            let origin = DVec3::new(*x, y, z).as_vec3();
            let ray = BvhRay::new(origin.into(), dir, 0.0, f32::MAX);
            let crossings = candidates
                .iter()
                .filter(|&&(x_max, t)| {
                    x_max >= origin.x && self.input[t as usize].intersect(&ray).is_finite()
                })
                .count();
            *o = crossings % 2 == 1;
        }
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        self.bounds
    }

    /// The fallback albedo at `p` (vertex and material colours are not looked up off the surface).
    fn albedo_at(&self, p: DVec3) -> Vec3 {
        self.fallback.at(p)
    }
}

/// Direction of the parity rays of [`Shape::contains`]: `+x`, tilted a little so that rays
/// along mesh rows and columns do not graze edges.
fn parity_dir() -> Vec3A {
    Vec3A::new(1.0, 1.3e-4, 2.7e-4).normalize()
}

/// The triangles of a mesh binned on a uniform grid of the y–z plane by their y–z extent widened
/// by [`YzGrid::MARGIN`] (compressed rows: the triangles of cell `c` are
/// `tris[start[c]..start[c + 1]]`), with each triangle's `[x_max, y_min, y_max, z_min, z_max]`.
struct YzGrid {
    lo: [f32; 2],
    inv_cell: [f32; 2],
    cells: [usize; 2],
    start: Vec<u32>,
    tris: Vec<u32>,
    boxes: Vec<[f32; 5]>,
    x_max: f32,
}

impl YzGrid {
    /// Widening of each triangle's y–z extent when binning (world units; the object is
    /// normalised to radius 1): more than a parity ray drifts in y or z across the mesh
    /// (`2.7e-4` per unit of x) plus [`YzGrid::SLOP`].
    const MARGIN: f32 = 2e-3;
    /// Allowance for `f32` rounding in the triangle test (a ray the test accepts passes within
    /// ~1e-6 of the triangle).
    const SLOP: f32 = 1e-4;

    fn new(triangles: &[Triangle]) -> Self {
        let boxes: Vec<[f32; 5]> = triangles
            .iter()
            .map(|t| {
                let b = t.aabb();
                [b.max.x, b.min.y, b.max.y, b.min.z, b.max.z]
            })
            .collect();
        let m = Self::MARGIN;
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        let mut x_max = f32::NEG_INFINITY;
        for b in &boxes {
            lo = [lo[0].min(b[1] - m), lo[1].min(b[3] - m)];
            hi = [hi[0].max(b[2] + m), hi[1].max(b[4] + m)];
            x_max = x_max.max(b[0]);
        }
        let side = ((triangles.len() as f64).sqrt() as usize).clamp(8, 512);
        let cells = [side, side];
        let inv_cell = [0, 1].map(|k| side as f32 / (hi[k] - lo[k]).max(f32::MIN_POSITIVE));
        let index = |v: f32, k: usize| -> usize {
            (((v - lo[k]) * inv_cell[k]).floor().max(0.0) as usize).min(cells[k] - 1)
        };
        let range = |b: &[f32; 5]| {
            (
                index(b[1] - m, 0)..=index(b[2] + m, 0),
                index(b[3] - m, 1)..=index(b[4] + m, 1),
            )
        };
        let mut count = vec![0u32; side * side + 1];
        for b in &boxes {
            let (ry, rz) = range(b);
            for iz in rz {
                for iy in ry.clone() {
                    count[iy + side * iz + 1] += 1;
                }
            }
        }
        for c in 1..count.len() {
            count[c] += count[c - 1];
        }
        let start = count.clone();
        let mut tris = vec![0u32; *count.last().unwrap_or(&0) as usize];
        for (t, b) in boxes.iter().enumerate() {
            let (ry, rz) = range(b);
            for iz in rz {
                for iy in ry.clone() {
                    let c = iy + side * iz;
                    tris[count[c] as usize] = t as u32;
                    count[c] += 1;
                }
            }
        }
        Self {
            lo,
            inv_cell,
            cells,
            start,
            tris,
            boxes,
            x_max,
        }
    }

    /// The cell holding `(y, z)` (the last cell for points at or past the upper edge), `None`
    /// below the grid's lower edges, where no widened extent reaches.
    fn cell(&self, y: f32, z: f32) -> Option<usize> {
        let fy = (y - self.lo[0]) * self.inv_cell[0];
        let fz = (z - self.lo[1]) * self.inv_cell[1];
        if !(fy >= 0.0 && fz >= 0.0) {
            return None;
        }
        let iy = (fy as usize).min(self.cells[0] - 1);
        let iz = (fz as usize).min(self.cells[1] - 1);
        Some(iy + self.cells[0] * iz)
    }
}

/// Barycentric weights of point `p` (assumed in the triangle's plane) with respect to
/// `v0, v1, v2`, clamped to the triangle.
fn barycentric(tri: &Triangle, p: DVec3) -> [f32; 3] {
    let v = |a: Vec3A| DVec3::new(a.x.into(), a.y.into(), a.z.into());
    let (a, b, c) = (v(tri.v0), v(tri.v1), v(tri.v2));
    let n = (b - a).cross(c - a);
    let nn = n.length_squared();
    let w1 = ((p - a).cross(c - a)).dot(n) / nn;
    let w2 = ((b - a).cross(p - a)).dot(n) / nn;
    let w = [1.0 - w1 - w2, w1, w2].map(|x| x.clamp(0.0, 1.0));
    let s: f64 = w.iter().sum();
    w.map(|x| (x / s) as f32)
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::test_meshes::{mesh, nearest_of_all, soup};

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
        /// Rays along the axes through the mesh's own vertices lie in the faces of the BVH's
        /// leaf boxes (the adversarial case of `BOX_PAD`), on random soups of which a share is
        /// squashed onto the plane `z = 0.25`, and a random ray through each vertex: the walk's
        /// distance is bitwise the nearest of the triangle test over all triangles, and
        /// `occluded` is exactly whether the walk finds a hit.
        #[test]
        fn the_padded_walk_finds_the_nearest_hit_on_rays_in_box_faces(
            seed in any::<u64>(),
            n in 1usize..80,
            flat in 0.0f64..1.0,
            dx in -1.0f64..1.0, dy in -1.0f64..1.0, dz in -1.0f64..1.0,
        ) {
            let mut tris = soup(seed, n);
            for t in tris.iter_mut().take((flat * n as f64) as usize) {
                for v in t.iter_mut() {
                    v[2] = 0.25;
                }
            }
            let m = mesh(tris);
            let tr = m.traced();
            let random = DVec3::new(dx, dy, dz);
            prop_assume!(random.length() > 1e-3);
            let dirs = [
                DVec3::X,
                DVec3::NEG_X,
                DVec3::Y,
                DVec3::NEG_Y,
                DVec3::Z,
                DVec3::NEG_Z,
                random.normalize(),
            ];
            let vertices: Vec<DVec3> = tr
                .triangles
                .iter()
                .flat_map(|t| [t.v0, t.v1, t.v2])
                .map(|v| DVec3::new(v.x.into(), v.y.into(), v.z.into()))
                .collect();
            for (k, v) in vertices.iter().enumerate().take(90) {
                for dir in dirs {
                    let ray = Ray::new(*v - 3.0 * dir, dir);
                    let nearest = nearest_of_all(&m, &ray, (0.0, 6.0)).map(|(_, d)| d.to_bits());
                    let walked = m.first_hit(&ray, 0.0, 6.0).map(|(_, d)| d.to_bits());
                    prop_assert_eq!(walked, nearest, "vertex {}, direction {}", k, dir);
                    prop_assert_eq!(m.occluded(&ray, 0.0, 6.0), walked.is_some());
                }
            }
        }
    }
}
