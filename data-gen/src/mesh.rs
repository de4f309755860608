//! Triangle meshes from Wavefront OBJ (`tobj`) and glTF 2.0 (the `gltf_file` module), normalised
//! into the bounding cylinder and ray-cast through a compressed wide BVH (`obvhs`'s CWBVH, built
//! with PLOC).
//!
//! The BVH is built once, on the first ray query or on [`Mesh::prepare_rays`], not at load: the
//! inside test of voxelisation ([`Shape::contains_row`]) needs no BVH, so a pipeline can voxelise
//! while another thread builds it, and a mesh that is only voxelised never builds one. Ray
//! queries see the triangles in the BVH's leaf order (ties between equal distances follow it);
//! the inside test counts crossings, which no order changes.
//!
//! Normalisation: rotate the source's up axis to `+y` ([`UpAxis`]); translate so that the centre
//! of the bounding box's x–z extent lies on the `y` axis and the lowest vertex at `y = 0`; scale
//! uniformly by the largest factor that keeps every vertex within radius `R` of the axis and below
//! `H`; then centre vertically in `[0, H]`. The whole map is kept ([`Mesh::placement`]).
//!
//! Colour: a textured material (glTF, or OBJ with `map_Kd` / `map_d` / `d < 1`) is read through
//! the `surface` module (factor × texture × vertex colour, with alpha); otherwise the per-vertex
//! colour of the OBJ when present (interpolated), else the material's diffuse colour when the
//! MTL file is found, else a procedural albedo (stripes by azimuth and height) so that warping
//! errors show in images.
//!
//! Alpha: where a material's alpha stops no ray ([`MaterialAlpha`]), every tracer (the BVH walk, the
//! binned and radial tracers, the inside tests) passes through the hit as if the triangle were
//! not there, with the same test, so the truth and every capture agree.
//!
//! Ray casting runs in `f32` inside the BVH (relative precision about 1e-6 of the object size);
//! the hit parameter is returned in `f64`.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use glam::{DVec3, Vec3, Vec3A, Vec4Swizzles};
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
use crate::geometry::{BoundingCylinder, Footprint, Hit, ParallelRays, RadialRays, Ray};
use crate::placement::{Placement, UpAxis};
use crate::radial::RadialTracer;
use crate::shape::{OneByOne, ParallelTracer, RadialOneByOne, Shape};
use crate::surface::{Material, SurfaceTri, barycentric, stops, uv_axes};
use crate::surface::{TextureImage, TextureRef};
use crate::truth::Light;
use crate::watertight::Shear;
use crate::yz_grid::YzGrid;

/// How to load and normalise a mesh.
#[derive(Clone, Debug)]
pub struct MeshLoadOptions {
    /// The cylinder to normalise into (default `R = 1`, `H = 2`).
    pub cylinder: BoundingCylinder,
    /// Colour when the file has neither vertex colours nor materials.
    pub fallback_albedo: Albedo,
    /// The source's up axis (default `+y`).
    pub up: UpAxis,
    /// glTF only: the name of the node whose subtree is loaded, in the scene's world
    /// coordinates (default: the whole default scene).
    pub node: Option<String>,
    /// The placement to take instead of normalising (default: none, normalise): the source's
    /// coordinates go to the object frame through its `to_normalised`, and `up` and `cylinder`
    /// are not used. For reading back a mesh altrep wrote ([`Mesh::to_glb`], with
    /// [`Placement::of_written`]), which must come back exactly where it was.
    pub frame: Option<Placement>,
    /// The light a surface that is unlit or gives off light is seen under (default
    /// [`Light::default`]): such a surface's hit albedo is the one this light shades to its
    /// radiance ([`Light::albedo_giving`]), so every renderer that shades albedo shows it. Take
    /// the light the scene is drawn and measured with.
    pub light: Light,
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
            up: UpAxis::PosY,
            node: None,
            frame: None,
            light: Light::default(),
        }
    }
}

/// Where a triangle's colour comes from.
#[derive(Clone, Debug)]
pub(crate) enum TriColor {
    /// Per-vertex colours.
    Vertex([Vec3; 3]),
    /// One colour for the face.
    Flat(Vec3),
    /// The procedural fallback.
    Procedural,
    /// A material of the mesh's list, read with the triangle's attributes.
    Surface(SurfaceTri),
}

/// A loader's triangles (corners in source coordinates), their colours, and the rest.
pub(crate) type Loaded = (Vec<[[f64; 3]; 3]>, Vec<TriColor>, Extras);

/// What a loader hands to the normalisation besides the triangles.
pub(crate) struct Extras {
    pub(crate) materials: Vec<Material>,
    pub(crate) notes: Vec<String>,
    pub(crate) inputs: Vec<(PathBuf, blake3::Hash)>,
    pub(crate) units: &'static str,
}

impl Extras {
    fn none(units: &'static str) -> Self {
        Self {
            materials: Vec::new(),
            notes: Vec::new(),
            inputs: Vec::new(),
            units,
        }
    }
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
    /// The materials [`TriColor::Surface`] refers to.
    materials: Arc<[Material]>,
    /// The light emissive and unlit surfaces are folded into albedo under
    /// ([`MeshLoadOptions::light`]).
    light: Light,
    /// Whether some material's alpha can let a ray through (every tracer then tests it).
    cut_out: bool,
    /// Whether some material is single-sided (every tracer but the inside tests then lets rays
    /// through its back faces).
    culls: bool,
    placement: Placement,
    notes: Vec<String>,
    inputs: Vec<(PathBuf, blake3::Hash)>,
    pub(crate) bounds: (DVec3, DVec3),
    /// The BVH and the triangles in its leaf order, built on the first ray query.
    traced: OnceLock<Traced>,
    /// Triangles binned across the parity ray, built on the first [`Shape::contains_row`].
    yz_grid: OnceLock<YzGrid>,
}

/// The axis-aligned bounds of `triangles`, in `f64`.
fn triangle_bounds(triangles: &[Triangle]) -> (DVec3, DVec3) {
    triangles.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), t| {
            let (a, b) = (t.aabb().min, t.aabb().max);
            (
                lo.min(DVec3::new(a.x.into(), a.y.into(), a.z.into())),
                hi.max(DVec3::new(b.x.into(), b.y.into(), b.z.into())),
            )
        },
    )
}

/// The material of a triangle coloured by one (`None` for vertex, flat or procedural colours).
fn surface_material<'a>(materials: &'a [Material], color: &TriColor) -> Option<&'a Material> {
    match color {
        TriColor::Surface(s) => materials.get(s.material as usize),
        _ => None,
    }
}

/// What ray queries read: the BVH and the triangles, normals and colours in its leaf order.
pub(crate) struct Traced {
    pub(crate) triangles: Vec<Triangle>,
    /// Each triangle's unit geometric normal (`obvhs`'s `compute_normal`, widened to `f64`).
    normals: Vec<DVec3>,
    /// Each triangle's colour; empty when every triangle takes the fallback (a mesh without
    /// colours then reads no colour record per hit).
    colors: Vec<TriColor>,
    /// Whether each triangle's material is single-sided (its back face lets rays through);
    /// empty when none is. One byte per triangle, so the tracers' test of every candidate hit
    /// reads no colour record.
    single_sided: Vec<bool>,
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
    fn build(triangles: &[Triangle], colors: &[TriColor], single_sided: &[bool]) -> Self {
        let start = Instant::now();
        let mut bvh = build_padded_cwbvh(triangles);
        let build_time = start.elapsed();
        let order = &bvh.primitive_indices;
        let mut seen = vec![false; triangles.len()];
        let permutation = order.len() == triangles.len()
            && order.iter().all(|&i| {
                (i as usize) < seen.len() && !std::mem::replace(&mut seen[i as usize], true)
            });
        let (triangles, colors, single_sided) = if permutation {
            let t: Vec<Triangle> = order.iter().map(|&i| triangles[i as usize]).collect();
            let c = if colors.is_empty() {
                Vec::new()
            } else {
                order.iter().map(|&i| colors[i as usize].clone()).collect()
            };
            let s = if single_sided.is_empty() {
                Vec::new()
            } else {
                order.iter().map(|&i| single_sided[i as usize]).collect()
            };
            bvh.primitive_indices = (0..order.len() as u32).collect();
            (t, c, s)
        } else {
            (triangles.to_vec(), colors.to_vec(), single_sided.to_vec())
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
            single_sided,
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
        let (positions, colors, extras) = crate::obj_file::load(bytes, path, options)?;
        let name = path
            .file_stem()
            .map_or_else(|| "mesh".into(), |s| s.to_string_lossy().into_owned());
        Self::from_triangles(name, positions, colors, extras, options)
    }

    /// Loads a mesh by its file's extension: `.obj` ([`Mesh::load_obj`]), `.gltf` or `.glb`
    /// ([`Mesh::from_gltf_bytes`]), case-insensitive.
    ///
    /// Errors: [`DataGenError::MeshFormat`] for another extension, else the loader's.
    pub fn load(path: impl AsRef<Path>, options: &MeshLoadOptions) -> Result<Self, DataGenError> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|source| DataGenError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path, options)
    }

    /// Parses a mesh file already read from `path`, by `path`'s extension (as [`Mesh::load`]).
    pub fn from_bytes(
        bytes: &[u8],
        path: &Path,
        options: &MeshLoadOptions,
    ) -> Result<Self, DataGenError> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("obj") => Self::from_obj_bytes(bytes, path, options),
            Some("gltf" | "glb") => Self::from_gltf_bytes(bytes, path, options),
            _ => Err(DataGenError::MeshFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// Parses a glTF 2.0 document (`.gltf` JSON or `.glb` binary) already read from `path`: the
    /// default scene, or the subtree of `options.node`, in the scene's world coordinates, with
    /// its materials (see the `gltf_file` module for what is read and what is named in
    /// [`Mesh::notes`]). External buffers and images are read from `path`'s folder. Cost: the
    /// parse, the decoding of every base-colour image (in parallel), one pass over the
    /// vertices.
    ///
    /// Errors: [`DataGenError::Gltf`] naming the glTF path of what is malformed or not
    /// supported, else as [`Mesh::load_obj`].
    pub fn from_gltf_bytes(
        bytes: &[u8],
        path: &Path,
        options: &MeshLoadOptions,
    ) -> Result<Self, DataGenError> {
        let scene = crate::gltf_file::load(bytes, path, options.node.as_deref())?;
        let name = path
            .file_stem()
            .map_or_else(|| "mesh".into(), |s| s.to_string_lossy().into_owned());
        let fallback = scene.fallback;
        let colors = scene
            .surfaces
            .into_iter()
            .map(|s| {
                if fallback.get(s.material as usize).is_some_and(|f| *f) {
                    TriColor::Procedural
                } else {
                    TriColor::Surface(s)
                }
            })
            .collect();
        let extras = Extras {
            materials: scene.materials,
            notes: scene.notes,
            inputs: scene.inputs,
            units: "metre",
        };
        Self::from_triangles(name, scene.positions, colors, extras, options)
    }

    /// Builds a mesh from raw triangles (`[[x, y, z]; 3]` each, any scale), normalising it.
    /// All triangles take the fallback albedo of `options`.
    pub fn from_raw_triangles(
        name: impl Into<String>,
        triangles: Vec<[[f64; 3]; 3]>,
        options: &MeshLoadOptions,
    ) -> Result<Self, DataGenError> {
        let colors = vec![TriColor::Procedural; triangles.len()];
        Self::from_triangles(
            name.into(),
            triangles,
            colors,
            Extras::none("file unit"),
            options,
        )
    }

    fn from_triangles(
        name: String,
        mut positions: Vec<[[f64; 3]; 3]>,
        mut colors: Vec<TriColor>,
        extras: Extras,
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
        if let Some(placement) = options.frame {
            return Self::placed(name, positions, colors, extras, options, placement);
        }
        // The source's up axis to `+y` (entries 0 and ±1: exact).
        if options.up != UpAxis::PosY {
            let u = options.up.rotation();
            let uf = u.as_mat3();
            positions
                .par_iter_mut()
                .flatten()
                .for_each(|v| *v = (u * DVec3::from(*v)).to_array());
            colors.par_iter_mut().for_each(|c| {
                if let TriColor::Surface(s) = c {
                    if let Some(n) = &mut s.normal {
                        *n = n.map(|v| uf * v);
                    }
                    // A rotation keeps the tangent frame's handedness (w).
                    if let Some(t) = &mut s.tangent {
                        **t = t.map(|v| (uf * v.truncate()).extend(v.w));
                    }
                }
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
        let bounds = triangle_bounds(&triangles);
        if kept_colors
            .iter()
            .all(|c| matches!(c, TriColor::Procedural))
        {
            kept_colors = Vec::new();
        }
        let materials: Arc<[Material]> = extras.materials.into();
        let uses = |f: fn(&Material) -> bool| {
            kept_colors
                .iter()
                .any(|c| surface_material(&materials, c).is_some_and(f))
        };
        let cut_out = uses(Material::is_cut_out);
        let culls = uses(|m| m.single_sided);
        let translation = DVec3::new(0.0, lift, 0.0) - centre * scale;
        Ok(Self {
            name,
            input: triangles,
            input_colors: kept_colors,
            fallback: options.fallback_albedo.clone(),
            materials,
            light: options.light,
            cut_out,
            culls,
            placement: Placement::new(options.up, scale, translation, extras.units),
            notes: extras.notes,
            inputs: extras.inputs,
            bounds,
            traced: OnceLock::new(),
            yz_grid: OnceLock::new(),
        })
    }

    /// [`Mesh::from_triangles`] with a given placement instead of the normalisation.
    fn placed(
        name: String,
        positions: Vec<[[f64; 3]; 3]>,
        colors: Vec<TriColor>,
        extras: Extras,
        options: &MeshLoadOptions,
        placement: Placement,
    ) -> Result<Self, DataGenError> {
        let m = placement.to_normalised;
        let linear = m.matrix3.as_mat3();
        let to_f32 = |v: &[f64; 3]| {
            let p = m.transform_point3(DVec3::from(*v));
            Vec3A::new(p.x as f32, p.y as f32, p.z as f32)
        };
        let triangles: Vec<Triangle> = positions
            .par_iter()
            .map(|t| Triangle {
                v0: to_f32(&t[0]),
                v1: to_f32(&t[1]),
                v2: to_f32(&t[2]),
            })
            .collect();
        let colors = colors
            .into_par_iter()
            .map(|mut c| {
                if let TriColor::Surface(s) = &mut c {
                    if let Some(n) = &mut s.normal {
                        *n = n.map(|v| (linear * v).normalize_or_zero());
                    }
                    if let Some(t) = &mut s.tangent {
                        **t = t.map(|v| (linear * v.truncate()).normalize_or_zero().extend(v.w));
                    }
                }
                c
            })
            .collect();
        let template = Self {
            name,
            input: Vec::new(),
            input_colors: Vec::new(),
            fallback: options.fallback_albedo.clone(),
            materials: extras.materials.into(),
            light: options.light,
            cut_out: false,
            culls: false,
            placement,
            notes: extras.notes,
            inputs: extras.inputs,
            bounds: (DVec3::ZERO, DVec3::ZERO),
            traced: OnceLock::new(),
            yz_grid: OnceLock::new(),
        };
        template.with_parts(triangles, colors)
    }

    /// The largest side (texels) of any texture its materials read; `None` without textures.
    pub fn largest_texture_side(&self) -> Option<usize> {
        self.materials
            .iter()
            .flat_map(|m| {
                [
                    m.base_texture.as_ref().map(|(t, _)| t),
                    m.alpha_texture.as_ref(),
                    m.normal_map.as_ref().map(|n| &n.texture),
                    m.emissive_texture.as_ref().map(|(t, _)| t),
                ]
            })
            .flatten()
            .map(|t| t.image.width().max(t.image.height()))
            .max()
    }

    /// This mesh with every texture of its materials larger than `max_side` texels on a side
    /// replaced by the first level of its mip chain that fits, snapped to 8-bit codes as the
    /// texture is read (colour through the sRGB curve; [`TextureImage::reduced`]):
    /// textures for a mesh drawn no larger than a few hundred pixels. Images shared between
    /// materials stay shared. Returns the mesh and the largest side of any texture it keeps
    /// (`None` without textures). Cost: a copy of the triangles and of the reduced texels.
    pub fn with_textures_at_most(
        &self,
        max_side: usize,
    ) -> Result<(Self, Option<usize>), DataGenError> {
        use std::collections::HashMap;
        let mut mesh = self.with_parts(self.input.clone(), self.input_colors.clone())?;
        let mut done: HashMap<(usize, bool), Arc<TextureImage>> = HashMap::new();
        let mut largest: Option<usize> = None;
        let mut reduce = |t: &mut TextureRef, srgb: bool| {
            let key = (Arc::as_ptr(&t.image) as usize, srgb);
            let image = done
                .entry(key)
                .or_insert_with(|| {
                    t.image
                        .reduced(max_side, srgb)
                        .map_or_else(|| t.image.clone(), Arc::new)
                })
                .clone();
            largest = Some(largest.unwrap_or(0).max(image.width().max(image.height())));
            t.image = image;
        };
        let mut materials: Vec<Material> = mesh.materials.to_vec();
        for m in &mut materials {
            if let Some((t, _)) = &mut m.base_texture {
                reduce(t, true);
            }
            if let Some(t) = &mut m.alpha_texture {
                reduce(t, false);
            }
            if let Some(n) = &mut m.normal_map {
                reduce(&mut n.texture, false);
            }
            if let Some((t, _)) = &mut m.emissive_texture {
                reduce(t, true);
            }
        }
        mesh.materials = materials.into();
        Ok((mesh, largest))
    }

    /// The kept triangles (normalised frame, input order) and their colours (empty when every
    /// triangle takes the fallback).
    pub(crate) fn input_parts(&self) -> (&[Triangle], &[TriColor]) {
        (&self.input, &self.input_colors)
    }

    /// A mesh of other triangles, already in this mesh's normalised frame, with this mesh's
    /// materials, fallback colour, placement, notes and inputs: what a simplification of it
    /// returns. `colors` is empty (every triangle takes the fallback) or one per triangle;
    /// degenerate triangles are dropped. Errors: [`DataGenError::EmptyMesh`] when none is left.
    pub(crate) fn with_parts(
        &self,
        triangles: Vec<Triangle>,
        colors: Vec<TriColor>,
    ) -> Result<Self, DataGenError> {
        let keep = |t: &Triangle| (t.v1 - t.v0).cross(t.v2 - t.v0).length_squared() > 0.0;
        let (input, mut input_colors): (Vec<Triangle>, Vec<TriColor>) = if colors.is_empty() {
            (triangles.into_iter().filter(keep).collect(), Vec::new())
        } else {
            triangles
                .into_iter()
                .zip(colors)
                .filter(|(t, _)| keep(t))
                .unzip()
        };
        if input.is_empty() {
            return Err(DataGenError::EmptyMesh {
                name: self.name.clone(),
            });
        }
        if input_colors
            .iter()
            .all(|c| matches!(c, TriColor::Procedural))
        {
            input_colors = Vec::new();
        }
        let bounds = triangle_bounds(&input);
        let uses = |f: fn(&Material) -> bool| {
            input_colors
                .iter()
                .any(|c| surface_material(&self.materials, c).is_some_and(f))
        };
        Ok(Self {
            name: self.name.clone(),
            cut_out: uses(Material::is_cut_out),
            culls: uses(|m| m.single_sided),
            input,
            input_colors,
            fallback: self.fallback.clone(),
            materials: self.materials.clone(),
            light: self.light,
            placement: self.placement,
            notes: self.notes.clone(),
            inputs: self.inputs.clone(),
            bounds,
            traced: OnceLock::new(),
            yz_grid: OnceLock::new(),
        })
    }

    /// The kept triangles' corners in the normalised frame (`f32`, as ray casting reads them),
    /// in input order. Cost: one copy.
    pub fn triangles_f32(&self) -> Vec<[[f32; 3]; 3]> {
        self.input
            .iter()
            .map(|t| [t.v0.to_array(), t.v1.to_array(), t.v2.to_array()])
            .collect()
    }

    /// The colour fallback of triangles without one (procedural albedo).
    pub fn fallback_albedo(&self) -> &Albedo {
        &self.fallback
    }

    /// Number of triangles kept (degenerate ones are dropped).
    pub fn triangle_count(&self) -> usize {
        self.input.len()
    }

    /// The map from the source's coordinates (glTF: world space of the loaded scene or node;
    /// OBJ: file space) to the normalised frame, and its units.
    pub fn placement(&self) -> &Placement {
        &self.placement
    }

    /// The light its emissive and unlit surfaces are folded into albedo under
    /// ([`MeshLoadOptions::light`]).
    pub fn light(&self) -> Light {
        self.light
    }

    /// What the source holds that altrep does not read or reads differently (glTF features,
    /// an OBJ's assumed up axis), one sentence each; empty for a fully read source.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The files read besides the mesh file itself (MTL files, textures, glTF buffers and
    /// images) with the BLAKE3 hash of the bytes read, in reading order: a cache key over the
    /// mesh's bytes and these covers everything the mesh depends on.
    pub fn inputs(&self) -> &[(PathBuf, blake3::Hash)] {
        &self.inputs
    }

    /// The materials of textured or alpha-tested triangles (empty for meshes coloured by
    /// vertex, flat or procedural colours).
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// Whether some material lets rays through (alpha mask or blend).
    pub fn is_cut_out(&self) -> bool {
        self.cut_out
    }

    /// Whether the hit at distance `d` of a ray from `origin` along `dir` on triangle `tri`
    /// (coloured by `color`) stops the ray: always, unless its material's alpha says otherwise.
    #[inline]
    pub(crate) fn stops_at(
        &self,
        tri: &Triangle,
        color: Option<&TriColor>,
        origin: Vec3A,
        dir: Vec3A,
        d: f32,
    ) -> bool {
        let Some(TriColor::Surface(s)) = color else {
            return true;
        };
        let Some(m) = self.materials.get(s.material as usize) else {
            return true;
        };
        if !m.is_cut_out() {
            return true;
        }
        let p = origin + dir * d;
        let (uv, vc) = s.at(barycentric(tri, p.as_dvec3()));
        let alpha = m.color(uv, vc).w;
        let key = u64::from(p.x.to_bits())
            ^ u64::from(p.y.to_bits()).rotate_left(21)
            ^ u64::from(p.z.to_bits()).rotate_left(42);
        stops(m.alpha_mode, alpha, key)
    }

    /// Whether the hit at distance `d` of `f32` ray `r` on triangle `k` of the BVH's order stops
    /// it in a tracer: not on the back face of a single-sided material (its winding's normal
    /// along the ray), and then as [`Mesh::stops_at`] says.
    #[inline]
    pub(crate) fn traced_stops(&self, tr: &Traced, k: usize, r: &BvhRay, d: f32) -> bool {
        if tr.single_sided.get(k).is_some_and(|s| *s) {
            // The winding's normal from the triangle just tested (in cache), in `f32`.
            let t = &tr.triangles[k];
            if (t.v1 - t.v0).cross(t.v2 - t.v0).dot(r.direction) > 0.0 {
                return false;
            }
        }
        self.traced_alpha_stops(tr, k, r, d)
    }

    /// [`Mesh::stops_at`] for triangle `k` of the BVH's order, on `f32` ray `r`: alpha only, as
    /// the inside tests count crossings (both faces of a surface bound its inside).
    #[inline]
    pub(crate) fn traced_alpha_stops(&self, tr: &Traced, k: usize, r: &BvhRay, d: f32) -> bool {
        !self.cut_out || self.stops_at(&tr.triangles[k], tr.colors.get(k), r.origin, r.direction, d)
    }

    /// Time spent building the BVH, `None` before it is built.
    pub fn bvh_build_time(&self) -> Option<Duration> {
        self.traced.get().map(|t| t.build_time)
    }

    /// The BVH and the triangles in its leaf order, built on first use.
    pub(crate) fn traced(&self) -> &Traced {
        self.traced.get_or_init(|| {
            let single_sided: Vec<bool> = if self.culls {
                self.input_colors
                    .iter()
                    .map(|c| surface_material(&self.materials, c).is_some_and(|m| m.single_sided))
                    .collect()
            } else {
                Vec::new()
            };
            Traced::build(&self.input, &self.input_colors, &single_sided)
        })
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
        let shear = Shear::new(bray.direction);
        // Among hits at the same distance (a ray through an edge meets both triangles), the
        // first in triangle order, as the binned tracers choose: every tracer then reports the
        // same triangle, whatever order the walk visits the leaves in.
        let mut best: Option<(usize, f32)> = None;
        tr.bvh.ray_traverse(bray, &mut hit, |r, id| {
            let k = idx[id] as usize;
            let d = shear.intersect_ray(&tris[k], r);
            if d.is_finite() && self.traced_stops(tr, k, r, d) {
                if !best.is_some_and(|(bk, bd)| bd < d || (bd == d && bk < k)) {
                    best = Some((k, d));
                }
                d
            } else {
                f32::INFINITY
            }
        });
        best
    }

    /// The hit record of `ray` meeting triangle `tri_id` at distance `t`: the geometric normal
    /// turned toward the ray (or the interpolated shading normal on its side) and the
    /// triangle's colour at the hit point. For a ray that stands for the cell `footprint`, a
    /// base-colour texture is read over the cell's image on the triangle (projected along the
    /// ray), through the texture's mip chain (`surface` module); without one, at the point.
    pub(crate) fn hit_over(
        &self,
        ray: &Ray,
        tri_id: usize,
        t: f32,
        footprint: Option<Footprint>,
    ) -> Hit {
        let tr = self.traced();
        let tri = &tr.triangles[tri_id];
        let t = f64::from(t);
        let n = tr.normals[tri_id];
        // Winding is not trusted: the normal faces the incoming ray.
        let n = if n.dot(ray.dir) > 0.0 { -n } else { n };
        let p = ray.at(t);
        let (albedo, normal) = match tr.colors.get(tri_id) {
            Some(TriColor::Vertex(c)) => {
                let w = barycentric(tri, p);
                (c[0] * w[0] + c[1] * w[1] + c[2] * w[2], n)
            }
            Some(TriColor::Flat(c)) => (*c, n),
            Some(TriColor::Procedural) | None => (self.fallback.at(p), n),
            Some(TriColor::Surface(s)) => {
                let w = barycentric(tri, p);
                let (uv, vc) = s.at(w);
                let axes = footprint.and_then(|f| uv_axes(tri, s, f.at(p, ray.dir), ray.dir));
                let material = self.materials.get(s.material as usize);
                let albedo = material.map_or(Vec3::ONE, |m| match axes {
                    Some(axes) => m.color_over(uv, axes, vc).xyz(),
                    None => m.color(uv, vc).xyz(),
                });
                // The interpolated shading normal (the winding's where there is none), turned by
                // the normal map in the tangent frame, then put on the side the geometric one
                // faces.
                let mut shading = s.normal.map_or(DVec3::ZERO, |v| {
                    (v[0] * w[0] + v[1] * w[1] + v[2] * w[2])
                        .as_dvec3()
                        .normalize_or_zero()
                });
                if let (Some(map), Some(t)) =
                    (material.and_then(|m| m.normal_map.as_ref()), &s.tangent)
                {
                    let base = if shading == DVec3::ZERO {
                        tr.normals[tri_id]
                    } else {
                        shading
                    };
                    let set = (map.set as usize).min(1);
                    let texel = match axes {
                        Some(a) => map.texture.sample_footprint(uv[set], a[set]),
                        None => map.texture.sample(uv[set]),
                    };
                    let tangent = t[0] * w[0] + t[1] * w[1] + t[2] * w[2];
                    if let Some(m) = map.perturb(texel, base.as_vec3(), tangent) {
                        shading = m.as_dvec3();
                    }
                }
                let normal = if shading == DVec3::ZERO {
                    n
                } else if shading.dot(n) < 0.0 {
                    -shading
                } else {
                    shading
                };
                // A surface that is unlit or gives off light: the albedo the mesh's light
                // shades to what it shows (docs/real-assets.md).
                let albedo = match material.filter(|m| m.emits()) {
                    None => albedo,
                    Some(m) => {
                        let n = normal.as_vec3();
                        if m.unlit {
                            self.light.albedo_giving(albedo, n)
                        } else {
                            albedo + self.light.albedo_giving(m.emission(uv, axes), n)
                        }
                    }
                };
                (albedo, normal)
            }
        };
        Hit {
            t,
            normal,
            geometric: n,
            albedo,
        }
    }
}

impl Shape for Mesh {
    fn name(&self) -> &str {
        &self.name
    }

    fn as_mesh(&self) -> Option<&Mesh> {
        Some(self)
    }

    /// Builds the BVH now if no ray query has built it yet (about 0.8 µs per triangle on one
    /// core, serial: the Stanford bunny's 69 k triangles take 50–70 ms), so that the first ray
    /// query does not pay for it. Threads that query rays meanwhile wait for this build.
    fn prepare_rays(&self) {
        self.traced();
    }

    fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        self.intersect_over(ray, t_min, t_max, None)
    }

    fn intersect_over(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        footprint: Option<Footprint>,
    ) -> Option<Hit> {
        self.first_hit(ray, t_min, t_max)
            .map(|(tri, t)| self.hit_over(ray, tri, t, footprint))
    }

    /// The BVH walk stopped at the first triangle whose test accepts the ray, without shading.
    /// Until its first hit the nearest-hit walk is exactly this walk (its window shrinks only
    /// at a hit), so both agree.
    fn occluded(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        let bray = Self::to_bvh_ray(ray, t_min, t_max);
        let tr = self.traced();
        let (tris, idx) = (&tr.triangles, &tr.bvh.primitive_indices);
        let shear = Shear::new(bray.direction);
        !tr.bvh.ray_traverse_miss(bray, |r, id| {
            let k = idx[id] as usize;
            let d = shear.intersect_ray(&tris[k], r);
            if d.is_finite() && !self.traced_stops(tr, k, r, d) {
                f32::INFINITY
            } else {
                d
            }
        })
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
            let k = idx[id] as usize;
            let d = tris[k].intersect(r);
            if d.is_finite() && self.traced_alpha_stops(tr, k, r, d) {
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
                    let tri = &self.input[t as usize];
                    x_max >= origin.x && {
                        let d = tri.intersect(&ray);
                        d.is_finite()
                            && (!self.cut_out
                                || self.stops_at(
                                    tri,
                                    self.input_colors.get(t as usize),
                                    ray.origin,
                                    ray.direction,
                                    d,
                                ))
                    }
                })
                .count();
            *o = crossings % 2 == 1;
        }
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        self.bounds
    }

    /// True when no material's alpha lets rays through and at most 1 % of the edges are open.
    /// Edges are matched by their end points' exact positions (a glTF mesh splits its vertices
    /// along texture seams; they stay closed); an edge met once is open. The 1 % lets a scanned
    /// mesh with a few holes (the Stanford bunny's base) keep its inside. Cost: one hash map
    /// over the edges, `O(triangles)`.
    fn single_sided(&self) -> bool {
        self.culls
    }

    fn encloses_volume(&self) -> bool {
        if self.cut_out {
            return false;
        }
        let key = |v: Vec3A| v.to_array().map(f32::to_bits);
        let mut edges: std::collections::HashMap<([u32; 3], [u32; 3]), u32> =
            std::collections::HashMap::with_capacity(self.input.len() * 3 / 2 + 1);
        for t in &self.input {
            let v = [key(t.v0), key(t.v1), key(t.v2)];
            for (a, b) in [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])] {
                *edges
                    .entry(if a < b { (a, b) } else { (b, a) })
                    .or_insert(0) += 1;
            }
        }
        let open = edges.values().filter(|c| **c == 1).count();
        open * 100 <= edges.len()
    }

    /// The colour of the surface nearest to `p` along 26 directions (the axes, the face and
    /// the cube diagonals): vertex, material and texture colours reach the voxels. A mesh
    /// coloured by the procedural fallback alone (or with no surface along any of them)
    /// gives the fallback at `p`. Cost: 26 ray casts.
    fn albedo_at(&self, p: DVec3) -> Vec3 {
        if self.input_colors.is_empty() {
            return self.fallback.at(p);
        }
        let mut best: Option<Hit> = None;
        for dx in -1i32..=1 {
            for dy in -1i32..=1 {
                for dz in -1i32..=1 {
                    if (dx, dy, dz) == (0, 0, 0) {
                        continue;
                    }
                    let dir = DVec3::new(dx.into(), dy.into(), dz.into()).normalize();
                    let t_max = best.map_or(f64::INFINITY, |b| b.t);
                    if let Some(h) = self.intersect(&Ray::new(p, dir), 0.0, t_max) {
                        best = Some(h);
                    }
                }
            }
        }
        best.map_or_else(|| self.fallback.at(p), |h| h.albedo)
    }
}

/// Direction of the parity rays of [`Shape::contains`]: `+x`, tilted a little so that rays
/// along mesh rows and columns do not graze edges.
fn parity_dir() -> Vec3A {
    Vec3A::new(1.0, 1.3e-4, 2.7e-4).normalize()
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
