//! Triangle meshes from Wavefront OBJ (`tobj`), normalised into the bounding cylinder and
//! ray-cast through a compressed wide BVH (`obvhs`'s CWBVH, built with PLOC).
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
use std::time::Duration;

use glam::{DVec3, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    ray::{Ray as BvhRay, RayHit},
    triangle::Triangle,
};

use crate::error::DataGenError;
use crate::geometry::{BoundingCylinder, Hit, Ray};
use crate::shape::{Albedo, Shape};

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

/// A normalised triangle mesh with its BVH. Implements [`Shape`].
pub struct Mesh {
    name: String,
    triangles: Vec<Triangle>,
    colors: Vec<TriColor>,
    fallback: Albedo,
    bvh: CwBvh,
    bounds: (DVec3, DVec3),
    /// Time spent building the BVH.
    pub bvh_build_time: Duration,
}

impl std::fmt::Debug for Mesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mesh")
            .field("name", &self.name)
            .field("triangles", &self.triangles.len())
            .field("bounds", &self.bounds)
            .finish()
    }
}

impl Mesh {
    /// Loads an OBJ file (triangulating polygons) and normalises it.
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
        if std::str::from_utf8(&bytes).is_err() {
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
        let (models, materials) =
            tobj::load_obj(path, &load).map_err(|e| DataGenError::ObjParse {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
        let materials = materials.unwrap_or_default();
        let mut positions = Vec::new();
        let mut colors = Vec::new();
        for model in &models {
            let m = &model.mesh;
            let vertex = |k: usize| -> Result<[f64; 3], DataGenError> {
                let i = m.indices[k] as usize;
                let p =
                    m.positions
                        .get(3 * i..3 * i + 3)
                        .ok_or_else(|| DataGenError::ObjParse {
                            path: path.to_path_buf(),
                            message: format!(
                                "face refers to vertex {} which does not exist",
                                i + 1
                            ),
                        })?;
                Ok([f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
            };
            let material_color = m
                .material_id
                .and_then(|id| materials.get(id))
                .and_then(|mat| mat.diffuse)
                .map(|d| Vec3::new(d[0], d[1], d[2]));
            for tri in 0..m.indices.len() / 3 {
                positions.push([vertex(3 * tri)?, vertex(3 * tri + 1)?, vertex(3 * tri + 2)?]);
                let has_vc =
                    m.vertex_color.len() == m.positions.len() && !m.vertex_color.is_empty();
                colors.push(if has_vc {
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
                });
            }
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
        for (t, tri) in positions.iter().enumerate() {
            for v in tri {
                if v.iter().any(|c| !c.is_finite()) {
                    return Err(DataGenError::NonFinite {
                        what: format!("vertex of triangle {t} in {name}"),
                        index: t,
                    });
                }
            }
        }
        // Bounds of the raw vertices.
        let (lo, hi) = positions.iter().flatten().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(DVec3::from(*v)), hi.max(DVec3::from(*v))),
        );
        if positions.is_empty() {
            return Err(DataGenError::EmptyMesh { name });
        }
        let centre = DVec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z));
        let max_radius = positions
            .iter()
            .flatten()
            .map(|v| {
                let d = DVec3::from(*v) - centre;
                (d.x * d.x + d.z * d.z).sqrt()
            })
            .fold(0.0, f64::max);
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
        let mut triangles = Vec::with_capacity(positions.len());
        let mut kept_colors = Vec::with_capacity(positions.len());
        for (tri, color) in positions.iter().zip(colors) {
            let t = Triangle {
                v0: to_f32(&tri[0]),
                v1: to_f32(&tri[1]),
                v2: to_f32(&tri[2]),
            };
            if (t.v1 - t.v0).cross(t.v2 - t.v0).length_squared() > 0.0 {
                triangles.push(t);
                kept_colors.push(color);
            }
        }
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
        let mut bvh_build_time = Duration::ZERO;
        let bvh = build_cwbvh_from_tris(
            &triangles,
            BvhBuildParams::medium_build(),
            &mut bvh_build_time,
        );
        Ok(Self {
            name,
            triangles,
            colors: kept_colors,
            fallback: options.fallback_albedo.clone(),
            bvh,
            bounds,
            bvh_build_time,
        })
    }

    /// Number of triangles kept (degenerate ones are dropped).
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    fn to_bvh_ray(ray: &Ray, t_min: f64, t_max: f64) -> BvhRay {
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
}

impl Shape for Mesh {
    fn name(&self) -> &str {
        &self.name
    }

    fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        let bray = Self::to_bvh_ray(ray, t_min, t_max);
        let mut hit = RayHit::none();
        let tris = &self.triangles;
        let idx = &self.bvh.primitive_indices;
        if !self
            .bvh
            .ray_traverse(bray, &mut hit, |r, id| tris[idx[id] as usize].intersect(r))
        {
            return None;
        }
        let tri_id = idx[hit.primitive_id as usize] as usize;
        let tri = &tris[tri_id];
        let t = f64::from(hit.t);
        let g = tri.compute_normal();
        let n = DVec3::new(g.x.into(), g.y.into(), g.z.into());
        // Winding is not trusted: the normal faces the incoming ray.
        let n = if n.dot(ray.dir) > 0.0 { -n } else { n };
        let p = ray.at(t);
        let albedo = match &self.colors[tri_id] {
            TriColor::Vertex(c) => {
                let w = barycentric(tri, p);
                c[0] * w[0] + c[1] * w[1] + c[2] * w[2]
            }
            TriColor::Flat(c) => *c,
            TriColor::Procedural => self.fallback.at(p),
        };
        Some(Hit {
            t,
            normal: n,
            albedo,
        })
    }

    /// Inside test by ray parity along `+x` (exact for closed meshes; meshes with holes may
    /// misclassify points whose parity ray leaves through a hole).
    fn contains(&self, p: DVec3) -> bool {
        let ray = BvhRay::new(
            p.as_vec3().into(),
            Vec3A::new(1.0, 1.3e-4, 2.7e-4).normalize(),
            0.0,
            f32::MAX,
        );
        let mut crossings = 0u32;
        let tris = &self.triangles;
        let idx = &self.bvh.primitive_indices;
        self.bvh.ray_traverse_anyhit(ray, |r, id| {
            if tris[idx[id] as usize].intersect(r).is_finite() {
                crossings += 1;
            }
        });
        crossings % 2 == 1
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        self.bounds
    }

    /// The fallback albedo at `p` (vertex and material colours are not looked up off the surface).
    fn albedo_at(&self, p: DVec3) -> Vec3 {
        self.fallback.at(p)
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
