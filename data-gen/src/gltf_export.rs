//! A [`Mesh`] written as a glTF 2.0 binary file (`.glb`): what altrep's simplified meshes are
//! stored as, readable by any engine and by altrep itself ([`Mesh::from_gltf_bytes`] with
//! [`MeshLoadOptions::frame`] set to [`Placement::of_written`]).
//!
//! Layout: one mesh under a child node, in the normalised frame, below a root node whose matrix
//! is the placement's inverse ([`Placement::to_source`], rounded to `f32`): an engine that loads
//! the file finds the mesh where the source asset was, in the source's units.
//!
//! One primitive per kind of colour: each material of the mesh (split further by whether the
//! triangles carry shading normals and tangents), with `TEXCOORD_0`, `TEXCOORD_1` where set 1
//! differs from set 0, `COLOR_0` where a vertex colour is not white, `NORMAL` and `TANGENT`;
//! the OBJ's flat and per-vertex colours as `COLOR_0` on a white double-sided material; the
//! procedural albedo of meshes without colours on a material marked
//! `extras.altrep_fallback_albedo` (altrep's reader colours its triangles with its fallback
//! albedo again; an engine draws them white). Vertices are welded per primitive, bit for bit.
//!
//! Materials keep what altrep reads: base colour factor and texture (its coordinate set,
//! sampler wrap modes and magnification filter, `KHR_texture_transform`), alpha mode and
//! cutoff, normal map with its scale, `doubleSided`, emissive factor and texture (a factor above
//! 1 as `KHR_materials_emissive_strength`), `KHR_materials_unlit`. An OBJ alpha texture (`map_d`) goes into
//! the base colour texture's alpha (the same product at texel centres; bilinear filtering
//! between texels may differ slightly). Metallic and roughness are written as 0 and 1: altrep
//! does not read them. Images are the source's own PNG or JPEG files where a texture was decoded
//! from one and is written unchanged; otherwise PNG, 8 bits per channel where every texel
//! survives the round trip through 8 bits exactly, else 16. They go inside the file ([`Mesh::to_glb`]) or beside it, shared
//! by every file written through one [`ExternalImages`] store ([`Mesh::to_glb_beside`]: the levels
//! of a simplified mesh share the source's textures).

use std::collections::HashMap;
use std::sync::Arc;

use glam::{DAffine3, DMat4, Vec3A, Vec4};
use serde_json::{Value, json};

use crate::error::DataGenError;
use crate::gltf_write::{BinBuilder, emissive_json, glb, png_bytes};
use crate::mesh::{Mesh, TriColor};
use crate::placement::Placement;
use crate::shape::Shape;
use crate::surface::{Material, MaterialAlpha, SamplerFilter, TextureImage, TextureRef, Wrap};

/// The key under a material's `extras` that marks triangles coloured by the fallback albedo.
pub(crate) const FALLBACK_MARK: &str = "altrep_fallback_albedo";

impl Placement {
    /// [`Placement::to_source`] as the column-major `f32` matrix of the root node of a file
    /// written by [`Mesh::to_glb`].
    pub fn to_source_f32(&self) -> [f32; 16] {
        DMat4::from(self.to_source())
            .to_cols_array()
            .map(|v| v as f32)
    }

    /// The placement to read a file written by [`Mesh::to_glb`] with (as
    /// [`crate::MeshLoadOptions::frame`]): the exact inverse, in `f64`, of the root node's `f32`
    /// matrix, so that every vertex comes back to the `f32` it was written as. Up axis and units
    /// are this placement's.
    pub fn of_written(&self) -> Placement {
        let m = DMat4::from_cols_array(&self.to_source_f32().map(f64::from));
        Placement {
            to_normalised: DAffine3::from_mat4(m).inverse(),
            ..*self
        }
    }
}

/// What a primitive holds: one material (or a colour kind) and which attributes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum PrimKey {
    /// Triangles coloured by the fallback albedo.
    Fallback,
    /// OBJ flat or per-vertex colours.
    VertexColour,
    /// A material of the mesh, with or without normals and tangents.
    Surface {
        material: u32,
        normals: bool,
        tangents: bool,
    },
}

/// One welded vertex of a primitive.
#[derive(Clone, Copy, Debug, Default)]
struct Corner {
    position: [f32; 3],
    uv: [[f32; 2]; 2],
    color: [f32; 4],
    normal: [f32; 3],
    tangent: [f32; 4],
}

impl Corner {
    fn bits(&self) -> [u32; 19] {
        let mut b = [0u32; 19];
        let all = self
            .position
            .iter()
            .chain(self.uv.iter().flatten())
            .chain(&self.color)
            .chain(&self.normal)
            .chain(&self.tangent);
        for (o, v) in b.iter_mut().zip(all) {
            *o = v.to_bits();
        }
        b
    }
}

#[derive(Default)]
struct Primitive {
    vertices: Vec<Corner>,
    index: HashMap<[u32; 19], u32>,
    indices: Vec<u32>,
}

impl Primitive {
    fn push(&mut self, c: Corner) {
        let next = self.vertices.len() as u32;
        let v = *self.index.entry(c.bits()).or_insert_with(|| {
            self.vertices.push(c);
            next
        });
        self.indices.push(v);
    }
}

/// Image files written beside `.glb` files instead of inside them ([`Mesh::to_glb_beside`]),
/// each once for every file written through the same store: the levels of one mesh share their
/// textures. The caller writes [`ExternalImages::files`] into the folder of the `.glb` files.
#[derive(Default)]
pub struct ExternalImages {
    /// `(image pointer, sRGB)` → index into `files`.
    seen: HashMap<(usize, bool), usize>,
    /// BLAKE3 of the PNG bytes → index into `files` (images equal by content, built apart).
    by_content: HashMap<[u8; 32], usize>,
    /// The images to write, in the order first referenced.
    pub files: Vec<ImageFile>,
    /// Put before each file's name in the `.glb` files' image URIs (not in
    /// [`ImageFile::name`]): for files the caller writes under a prefixed name.
    pub uri_prefix: String,
}

/// One image file of an [`ExternalImages`] store.
pub struct ImageFile {
    /// File name, relative to the `.glb` files that reference it.
    pub name: String,
    /// The file's bytes: the source's own PNG or JPEG, or a PNG altrep encoded (RGBA).
    pub bytes: Vec<u8>,
    /// `"image/png"` or `"image/jpeg"`.
    pub mime: &'static str,
    /// Width and height in texels.
    pub size: (usize, usize),
    /// A PNG of 16 bits per channel (else 8).
    pub sixteen_bit: bool,
}

impl ExternalImages {
    /// The file name of `img` read as sRGB (`srgb`) or linear, encoding it on first use.
    fn name_of(&mut self, img: &Arc<TextureImage>, srgb: bool) -> Result<String, DataGenError> {
        let key = (Arc::as_ptr(img) as usize, srgb);
        if let Some(&i) = self.seen.get(&key) {
            return Ok(self.files[i].name.clone());
        }
        let (bytes, mime, sixteen_bit) = payload(img, srgb)?;
        let hash = *blake3::hash(&bytes).as_bytes();
        let i = match self.by_content.get(&hash) {
            Some(&i) => i,
            None => {
                let ext = if mime == "image/jpeg" { "jpg" } else { "png" };
                self.files.push(ImageFile {
                    name: format!("texture{}.{ext}", self.files.len()),
                    bytes,
                    mime,
                    size: (img.width(), img.height()),
                    sixteen_bit,
                });
                self.by_content.insert(hash, self.files.len() - 1);
                self.files.len() - 1
            }
        };
        self.seen.insert(key, i);
        Ok(self.files[i].name.clone())
    }
}

/// The images of a document, each written once per way it is read.
#[derive(Default)]
struct Images<'s> {
    /// Where images go when they are written beside the file.
    external: Option<&'s mut ExternalImages>,
    /// `(image pointer, sRGB)` → image index.
    seen: HashMap<(usize, bool), usize>,
    images: Vec<Value>,
    samplers: Vec<Value>,
    textures: Vec<Value>,
    /// Bytes of the encoded images.
    bytes: usize,
}

/// The file of an image: the source's own PNG or JPEG bytes when it was decoded from one (the
/// same decode gives the same texels back), else [`encode`]d as PNG. Returns the bytes, the
/// MIME type and whether the PNG is 16-bit.
fn payload(img: &TextureImage, srgb: bool) -> Result<(Vec<u8>, &'static str, bool), DataGenError> {
    if let Some(e) = img.encoded() {
        // A PNG's bit depth is byte 24: after the signature (8), the IHDR chunk's length and
        // type (8), width and height (8).
        let sixteen = e.mime == "image/png" && e.bytes.get(24) == Some(&16);
        return Ok((e.bytes.to_vec(), e.mime, sixteen));
    }
    let (png, sixteen) = encode(img, srgb)?;
    Ok((png, "image/png", sixteen))
}

/// PNG bytes of `img`, RGB through the sRGB curve when `srgb`: 8 bits per channel when every
/// texel comes back exactly through 8 bits (as the loader decodes them), else 16 (`true`).
fn encode(img: &TextureImage, srgb: bool) -> Result<(Vec<u8>, bool), DataGenError> {
    let (w, h) = (img.width(), img.height());
    let curve = |c: f32, k: usize| {
        if srgb && k < 3 {
            crate::image_io::linear_to_srgb(c.clamp(0.0, 1.0))
        } else {
            c.clamp(0.0, 1.0)
        }
    };
    let back = |code: f32, k: usize| {
        if srgb && k < 3 {
            crate::image_io::srgb_to_linear(code)
        } else {
            code
        }
    };
    let texels: Vec<Vec4> = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| img.texel(i, j))
        .collect();
    let bytes8: Vec<u8> = texels
        .iter()
        .flat_map(|t| (0..4).map(move |k| (curve(t[k], k) * 255.0).round() as u8))
        .collect();
    let exact = texels
        .iter()
        .enumerate()
        .all(|(n, t)| (0..4).all(|k| back(f32::from(bytes8[4 * n + k]) / 255.0, k) == t[k]));
    if exact {
        return Ok((
            png_bytes(&bytes8, w as u32, h as u32, image::ExtendedColorType::Rgba8)?,
            false,
        ));
    }
    let bytes16: Vec<u8> = texels
        .iter()
        .flat_map(|t| {
            (0..4).flat_map(move |k| (((curve(t[k], k) * 65535.0).round()) as u16).to_ne_bytes())
        })
        .collect();
    Ok((
        png_bytes(
            &bytes16,
            w as u32,
            h as u32,
            image::ExtendedColorType::Rgba16,
        )?,
        true,
    ))
}

impl Images<'_> {
    /// The texture index of `t` read as sRGB colour (`srgb`) or as linear data.
    fn texture(
        &mut self,
        t: &TextureRef,
        srgb: bool,
        b: &mut BinBuilder,
    ) -> Result<usize, DataGenError> {
        let key = (Arc::as_ptr(&t.image) as usize, srgb);
        let image = match self.seen.get(&key) {
            Some(i) => *i,
            None => {
                let entry = match &mut self.external {
                    Some(store) => {
                        let name = store.name_of(&t.image, srgb)?;
                        json!({"uri": format!("{}{name}", store.uri_prefix)})
                    }
                    None => {
                        let (bytes, mime, _) = payload(&t.image, srgb)?;
                        self.bytes += bytes.len();
                        let v = b.view(&bytes);
                        json!({"bufferView": v, "mimeType": mime})
                    }
                };
                self.images.push(entry);
                self.seen.insert(key, self.images.len() - 1);
                self.images.len() - 1
            }
        };
        let wrap = |w: Wrap| match w {
            Wrap::Repeat => 10497,
            Wrap::MirroredRepeat => 33648,
            Wrap::ClampToEdge => 33071,
        };
        let filter = match t.filter {
            SamplerFilter::Nearest => 9728,
            SamplerFilter::Linear => 9729,
        };
        self.samplers
            .push(json!({"magFilter": filter, "wrapS": wrap(t.wrap[0]), "wrapT": wrap(t.wrap[1])}));
        self.textures
            .push(json!({"source": image, "sampler": self.samplers.len() - 1}));
        Ok(self.textures.len() - 1)
    }
}

/// `KHR_texture_transform` of `t` (offset, rotation, scale), `None` for the identity.
fn transform_extension(t: &TextureRef) -> Option<Value> {
    let [a, b] = t.transform.rows;
    if t.transform == crate::surface::UvTransform::default() {
        return None;
    }
    // rows = [[c·sx, s·sy, ox], [−s·sx, c·sy, oy]].
    let sx = a[0].hypot(b[0]);
    let rotation = (-b[0]).atan2(a[0]);
    let (s, c) = rotation.sin_cos();
    let sy = if c.abs() > s.abs() {
        b[1] / c
    } else {
        a[1] / s
    };
    Some(json!({"offset": [a[2], b[2]], "rotation": rotation, "scale": [sx, sy]}))
}

/// The base colour texture to write for `m`: its own, with the alpha texture multiplied into
/// its alpha when it has one (module docs). Errors: an alpha texture beside a base texture of
/// another size, sampler, transform or coordinate set.
fn base_texture(m: &Material) -> Result<Option<(TextureRef, u32)>, DataGenError> {
    let Some(alpha) = &m.alpha_texture else {
        return Ok(m.base_texture.clone());
    };
    let a_of = |t: Vec4| if t.w < 1.0 { t.w } else { t.x };
    let (w, h) = (alpha.image.width(), alpha.image.height());
    let (base, set) = match &m.base_texture {
        None => (None, 0),
        Some((t, set)) => {
            let same = t.image.width() == w
                && t.image.height() == h
                && t.filter == alpha.filter
                && t.wrap == alpha.wrap
                && t.transform == alpha.transform
                && *set == 0;
            if !same {
                return Err(DataGenError::InvalidParameter {
                    name: "material",
                    value: m.name.clone(),
                    reason: "an alpha texture (map_d) beside a base colour texture of another size, sampler or \
                             coordinate set cannot be written to glTF",
                });
            }
            (Some(t), *set)
        }
    };
    let texels = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| {
            let c = base.map_or(Vec4::ONE, |t| t.image.texel(i, j));
            c.truncate().extend(c.w * a_of(alpha.image.texel(i, j)))
        })
        .collect();
    let image = TextureImage::new(w, h, texels).ok_or(DataGenError::InvalidParameter {
        name: "material",
        value: m.name.clone(),
        reason: "its alpha texture is empty",
    })?;
    Ok(Some((
        TextureRef {
            image: Arc::new(image),
            ..alpha.clone()
        },
        set,
    )))
}

/// A `.glb` file written by [`Mesh::to_glb_file`].
pub struct GlbFile {
    /// The file's bytes.
    pub bytes: Vec<u8>,
    /// How many of them are images (PNG): what levels of one mesh share.
    pub image_bytes: usize,
}

impl Mesh {
    /// The mesh as a `.glb` file's bytes ([`Mesh::to_glb_file`]).
    pub fn to_glb(&self) -> Result<Vec<u8>, DataGenError> {
        self.to_glb_file().map(|f| f.bytes)
    }

    /// The mesh as a `.glb` file (module docs: layout, what is kept), with the bytes its
    /// images take. Cost: one pass over the triangles with a hash map per primitive, and one
    /// PNG encoding per image.
    ///
    /// Errors: an OBJ alpha texture that cannot join its base colour texture
    /// ([`DataGenError::InvalidParameter`]), an image the PNG encoder refuses
    /// ([`DataGenError::ImageWrite`]).
    pub fn to_glb_file(&self) -> Result<GlbFile, DataGenError> {
        self.glb_with(None)
    }

    /// The mesh as a `.glb` file whose images are PNG files beside it, named and encoded once
    /// by `images` for every file written through it ([`ExternalImages`]); the file's
    /// `image_bytes` is 0. Errors and cost as [`Mesh::to_glb_file`], each image encoded once
    /// per store.
    pub fn to_glb_beside(&self, images: &mut ExternalImages) -> Result<GlbFile, DataGenError> {
        self.glb_with(Some(images))
    }

    fn glb_with(&self, external: Option<&mut ExternalImages>) -> Result<GlbFile, DataGenError> {
        let (triangles, colors) = self.input_parts();
        let materials = self.materials();
        let mut prims: std::collections::BTreeMap<PrimKey, Primitive> = Default::default();
        for (t, tri) in triangles.iter().enumerate() {
            let p = [tri.v0, tri.v1, tri.v2].map(|v: Vec3A| v.to_array());
            let (key, corners): (PrimKey, [Corner; 3]) = match colors.get(t) {
                None | Some(TriColor::Procedural) => (
                    PrimKey::Fallback,
                    p.map(|position| Corner {
                        position,
                        ..Corner::default()
                    }),
                ),
                Some(TriColor::Flat(c)) => (
                    PrimKey::VertexColour,
                    p.map(|position| Corner {
                        position,
                        color: c.extend(1.0).to_array(),
                        ..Corner::default()
                    }),
                ),
                Some(TriColor::Vertex(c)) => {
                    let mut k = 0;
                    (
                        PrimKey::VertexColour,
                        p.map(|position| {
                            k += 1;
                            Corner {
                                position,
                                color: c[k - 1].extend(1.0).to_array(),
                                ..Corner::default()
                            }
                        }),
                    )
                }
                Some(TriColor::Surface(s)) => {
                    let mut k = 0;
                    (
                        PrimKey::Surface {
                            material: s.material,
                            normals: s.normal.is_some(),
                            tangents: s.tangent.is_some(),
                        },
                        p.map(|position| {
                            k += 1;
                            let k = k - 1;
                            Corner {
                                position,
                                uv: [s.uv[0][k].to_array(), s.uv[1][k].to_array()],
                                color: s.color[k].to_array(),
                                normal: s.normal.map_or([0.0; 3], |n| n[k].to_array()),
                                tangent: s.tangent.as_ref().map_or([0.0; 4], |t| t[k].to_array()),
                            }
                        }),
                    )
                }
            };
            let prim = prims.entry(key).or_default();
            for c in corners {
                prim.push(c);
            }
        }

        let mut b = BinBuilder::default();
        let mut images = Images {
            external,
            ..Images::default()
        };
        let mut out_materials: Vec<Value> = Vec::new();
        let mut material_index: HashMap<PrimKey, usize> = HashMap::new();
        let mut uses_transform = false;
        let mut uses_unlit = false;
        let mut uses_strength = false;
        let mut primitives = Vec::new();
        for (key, prim) in &prims {
            // The primitive's material.
            let mat_key = match key {
                PrimKey::Surface { material, .. } => PrimKey::Surface {
                    material: *material,
                    normals: false,
                    tangents: false,
                },
                k => *k,
            };
            let mi = match material_index.get(&mat_key) {
                Some(i) => *i,
                None => {
                    let value = match key {
                        PrimKey::Fallback => json!({
                            "name": "altrep fallback albedo",
                            "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0},
                            "doubleSided": true,
                            "extras": {FALLBACK_MARK: true},
                        }),
                        PrimKey::VertexColour => json!({
                            "name": "vertex colour",
                            "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0},
                            "doubleSided": true,
                        }),
                        PrimKey::Surface { material, .. } => {
                            let m = materials.get(*material as usize).ok_or(
                                DataGenError::InvalidParameter {
                                    name: "material",
                                    value: material.to_string(),
                                    reason: "a triangle names a material the mesh does not have",
                                },
                            )?;
                            let mut pbr = json!({
                                "baseColorFactor": m.base_color.to_array(),
                                "metallicFactor": 0.0,
                                "roughnessFactor": 1.0,
                            });
                            if let Some((t, set)) = base_texture(m)? {
                                let index = images.texture(&t, true, &mut b)?;
                                let mut info = json!({"index": index, "texCoord": set});
                                if let Some(ext) = transform_extension(&t) {
                                    info["extensions"] = json!({"KHR_texture_transform": ext});
                                    uses_transform = true;
                                }
                                pbr["baseColorTexture"] = info;
                            }
                            let mut v = json!({
                                "name": m.name,
                                "pbrMetallicRoughness": pbr,
                                "doubleSided": !m.single_sided,
                            });
                            match m.alpha_mode {
                                MaterialAlpha::Opaque => v["alphaMode"] = json!("OPAQUE"),
                                MaterialAlpha::Mask { cutoff } => {
                                    v["alphaMode"] = json!("MASK");
                                    v["alphaCutoff"] = json!(cutoff);
                                }
                                MaterialAlpha::Blend => v["alphaMode"] = json!("BLEND"),
                            }
                            if let Some(n) = &m.normal_map {
                                let index = images.texture(&n.texture, false, &mut b)?;
                                v["normalTexture"] =
                                    json!({"index": index, "texCoord": n.set, "scale": n.scale});
                            }
                            if m.unlit {
                                v["extensions"] = json!({"KHR_materials_unlit": {}});
                                uses_unlit = true;
                            } else if m.emissive != glam::Vec3::ZERO {
                                let (factor, strength) = emissive_json(m.emissive.to_array());
                                v["emissiveFactor"] = factor;
                                if let Some(strength) = strength {
                                    v["extensions"] =
                                        json!({"KHR_materials_emissive_strength": strength});
                                    uses_strength = true;
                                }
                                if let Some((t, set)) = &m.emissive_texture {
                                    let index = images.texture(t, true, &mut b)?;
                                    let mut info = json!({"index": index, "texCoord": set});
                                    if let Some(ext) = transform_extension(t) {
                                        info["extensions"] = json!({"KHR_texture_transform": ext});
                                        uses_transform = true;
                                    }
                                    v["emissiveTexture"] = info;
                                }
                            }
                            v
                        }
                    };
                    out_materials.push(value);
                    material_index.insert(mat_key, out_materials.len() - 1);
                    out_materials.len() - 1
                }
            };
            // The primitive's attributes.
            let positions: Vec<[f32; 3]> = prim.vertices.iter().map(|c| c.position).collect();
            let mut attributes = json!({"POSITION": b.floats(&positions, "VEC3", true)});
            if let PrimKey::Surface {
                normals, tangents, ..
            } = key
            {
                let uv0: Vec<[f32; 2]> = prim.vertices.iter().map(|c| c.uv[0]).collect();
                attributes["TEXCOORD_0"] = json!(b.floats(&uv0, "VEC2", false));
                if prim.vertices.iter().any(|c| c.uv[1] != c.uv[0]) {
                    let uv1: Vec<[f32; 2]> = prim.vertices.iter().map(|c| c.uv[1]).collect();
                    attributes["TEXCOORD_1"] = json!(b.floats(&uv1, "VEC2", false));
                }
                if *normals {
                    let n: Vec<[f32; 3]> = prim.vertices.iter().map(|c| c.normal).collect();
                    attributes["NORMAL"] = json!(b.floats(&n, "VEC3", false));
                }
                if *tangents {
                    let t: Vec<[f32; 4]> = prim.vertices.iter().map(|c| c.tangent).collect();
                    attributes["TANGENT"] = json!(b.floats(&t, "VEC4", false));
                }
            }
            let white = |c: &Corner| c.color == [1.0; 4];
            if *key == PrimKey::VertexColour
                || (matches!(key, PrimKey::Surface { .. }) && !prim.vertices.iter().all(white))
            {
                let c: Vec<[f32; 4]> = prim.vertices.iter().map(|c| c.color).collect();
                attributes["COLOR_0"] = json!(b.floats(&c, "VEC4", false));
            }
            let indices = b.indices(&prim.indices);
            primitives.push(json!({"attributes": attributes, "indices": indices, "material": mi}));
        }
        let (bin, views, accessors) = b.padded();
        let mut doc = json!({
            "asset": {"version": "2.0", "generator": "altrep"},
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [
                {"name": "placement", "matrix": self.placement().to_source_f32(), "children": [1]},
                {"name": self.name(), "mesh": 0},
            ],
            "meshes": [{"name": self.name(), "primitives": primitives}],
            "materials": out_materials,
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{"byteLength": bin.len()}],
        });
        if !images.images.is_empty() {
            doc["images"] = json!(images.images);
            doc["samplers"] = json!(images.samplers);
            doc["textures"] = json!(images.textures);
        }
        let used: Vec<&str> = [
            (uses_transform, "KHR_texture_transform"),
            (uses_unlit, "KHR_materials_unlit"),
            (uses_strength, "KHR_materials_emissive_strength"),
        ]
        .into_iter()
        .filter_map(|(used, name)| used.then_some(name))
        .collect();
        if !used.is_empty() {
            doc["extensionsUsed"] = json!(used);
        }
        Ok(GlbFile {
            bytes: glb(&doc, &bin),
            image_bytes: images.bytes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Texels off the 8-bit grid go into a 16-bit PNG and come back within a 16-bit step,
    /// through the sRGB curve for colour and straight for data.
    #[test]
    fn sixteen_bit_textures_come_back_within_a_step() {
        let texels: Vec<Vec4> = (0..12)
            .map(|k| {
                let x = k as f32 / 11.0;
                Vec4::new(
                    x * 0.37 + 0.001,
                    1.0 - x * 0.61,
                    (x * 7.3).fract(),
                    0.5 + x * 0.123,
                )
            })
            .collect();
        let img = TextureImage::new(4, 3, texels).unwrap();
        for srgb in [true, false] {
            let (png, sixteen) = encode(&img, srgb).unwrap();
            assert!(sixteen);
            let back = TextureImage::decode(&png, srgb).unwrap();
            for j in 0..3 {
                for i in 0..4 {
                    let d = (img.texel(i, j) - back.texel(i, j)).abs().max_element();
                    assert!(d < 1e-4, "srgb {srgb}, texel ({i}, {j}) off by {d}");
                }
            }
        }
    }
}
