//! Small glTF 2.0 files with known content, written by data-gen for tests and examples: a textured
//! box whose texel colours are known in closed form, an alpha-masked quad with a known hole
//! pattern, a mirrored node, a z-up asset ([`TestGltf`]). Written as `.glb` (one file) or as
//! `.gltf` with an external `.bin` buffer and PNG images beside it.
//!
//! Not a general exporter: one buffer, float positions and texture coordinates, `u32` indices,
//! one optional PNG per material.

use std::path::Path;

use serde_json::{Value, json};

use crate::error::DataGenError;

/// An 8-bit RGBA image, row 0 at the top (stored as PNG in the file).
#[derive(Clone, Debug, PartialEq)]
pub struct Rgba8 {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major RGBA bytes, `4·width·height` of them.
    pub data: Vec<u8>,
}

/// A material of a [`TestGltf`].
#[derive(Clone, Debug, PartialEq)]
pub struct TestMaterial {
    /// `baseColorFactor`.
    pub base_color: [f32; 4],
    /// `baseColorTexture` (sampled with `NEAREST` when `nearest`, else `LINEAR`).
    pub texture: Option<Rgba8>,
    /// Magnification filter `NEAREST` instead of `LINEAR`.
    pub nearest: bool,
    /// `"OPAQUE"`, `"MASK"` or `"BLEND"`.
    pub alpha_mode: &'static str,
    /// `alphaCutoff` (written for `MASK` only).
    pub alpha_cutoff: f32,
    /// `normalTexture` (bytes as stored: `(n + 1)/2` per channel, linear) and its `scale`.
    pub normal_texture: Option<(Rgba8, f32)>,
    /// `doubleSided`.
    pub double_sided: bool,
    /// `emissiveFactor` (linear RGB; not written when black; above 1, divided by its largest
    /// component, written as `KHR_materials_emissive_strength`).
    pub emissive: [f32; 3],
    /// `emissiveTexture` (sRGB-coded, like the base colour), if any.
    pub emissive_texture: Option<Rgba8>,
    /// `KHR_materials_unlit`.
    pub unlit: bool,
}

impl TestMaterial {
    /// A white, double-sided material cut out by the alpha of `texture` (`MASK`, cutoff ½),
    /// sampled `NEAREST` when `nearest`, else `LINEAR`.
    pub fn masked(texture: Rgba8, nearest: bool) -> Self {
        Self {
            base_color: [1.0; 4],
            texture: Some(texture),
            nearest,
            alpha_mode: "MASK",
            alpha_cutoff: 0.5,
            normal_texture: None,
            double_sided: true,
            emissive: [0.0; 3],
            emissive_texture: None,
            unlit: false,
        }
    }

    /// An opaque, untextured, double-sided material of linear base colour `base_color`.
    pub fn plain(base_color: [f32; 4]) -> Self {
        Self {
            base_color,
            texture: None,
            nearest: false,
            alpha_mode: "OPAQUE",
            alpha_cutoff: 0.5,
            normal_texture: None,
            double_sided: true,
            emissive: [0.0; 3],
            emissive_texture: None,
            unlit: false,
        }
    }
}

/// A triangle primitive of a [`TestGltf`] mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct TestPrimitive {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// `TEXCOORD_0` (same length as `positions`), or empty for none.
    pub uvs: Vec<[f32; 2]>,
    /// `NORMAL` (same length as `positions`), or empty for none.
    pub normals: Vec<[f32; 3]>,
    /// `TANGENT` (`xyz` and the bitangent's sign; same length as `positions`), or empty.
    pub tangents: Vec<[f32; 4]>,
    /// Triangle indices (`TRIANGLES` mode).
    pub indices: Vec<u32>,
    /// Index into [`TestGltf::materials`].
    pub material: usize,
}

impl TestPrimitive {
    /// A primitive without vertices or attributes, of material `material`.
    pub fn empty(material: usize) -> Self {
        Self {
            positions: Vec::new(),
            uvs: Vec::new(),
            normals: Vec::new(),
            tangents: Vec::new(),
            indices: Vec::new(),
            material,
        }
    }
}

/// A node: an optional mesh, a column-major 4 × 4 matrix, children.
#[derive(Clone, Debug, PartialEq)]
pub struct TestNode {
    /// The node's name.
    pub name: String,
    /// Index into [`TestGltf::meshes`].
    pub mesh: Option<usize>,
    /// Column-major local transform.
    pub matrix: [f32; 16],
    /// Indices of child nodes.
    pub children: Vec<usize>,
}

impl TestNode {
    /// A node named `name` holding mesh 0, untransformed, without children.
    pub fn mesh_at_origin(name: &str) -> Self {
        Self {
            name: name.into(),
            mesh: Some(0),
            matrix: IDENTITY,
            children: vec![],
        }
    }
}

/// A whole glTF document: meshes (lists of primitives), materials, nodes, the scene's roots.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct TestGltf {
    /// Meshes, each a list of primitives.
    pub meshes: Vec<Vec<TestPrimitive>>,
    /// Materials.
    pub materials: Vec<TestMaterial>,
    /// Nodes.
    pub nodes: Vec<TestNode>,
    /// The scene's root nodes.
    pub roots: Vec<usize>,
}

/// The identity as a column-major matrix.
pub const IDENTITY: [f32; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

/// PNG bytes of an 8-bit RGBA image.
fn png(img: &Rgba8) -> Result<Vec<u8>, DataGenError> {
    png_bytes(
        &img.data,
        img.width,
        img.height,
        image::ExtendedColorType::Rgba8,
    )
}

/// PNG bytes of `data` (`width × height` pixels of `color`, big-endian samples for 16 bits).
pub(crate) fn png_bytes(
    data: &[u8],
    width: u32,
    height: u32,
    color: image::ExtendedColorType,
) -> Result<Vec<u8>, DataGenError> {
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(data, width, height, color)
        .map_err(|e| DataGenError::ImageWrite {
            path: "<memory>".into(),
            message: e.to_string(),
        })?;
    Ok(out)
}

use image::ImageEncoder as _;

/// A glTF binary buffer being filled, with its buffer views and accessors (buffer 0).
#[derive(Default)]
pub(crate) struct BinBuilder {
    /// The buffer's bytes.
    pub(crate) bin: Vec<u8>,
    /// `bufferViews`.
    pub(crate) views: Vec<Value>,
    /// `accessors`.
    pub(crate) accessors: Vec<Value>,
}

impl BinBuilder {
    /// Appends `bytes` at a 4-byte boundary as a new buffer view; its index.
    pub(crate) fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        self.views.len() - 1
    }

    /// An accessor of `f32` elements of type `ty` (`"VEC2"`, `"VEC3"`, `"VEC4"`), `N` floats
    /// each, with `min` and `max` when `bounds` (required for positions); its index.
    pub(crate) fn floats<const N: usize>(
        &mut self,
        values: &[[f32; N]],
        ty: &str,
        bounds: bool,
    ) -> usize {
        let bytes: Vec<u8> = values
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let v = self.view(&bytes);
        let mut a =
            json!({"bufferView": v, "componentType": 5126, "count": values.len(), "type": ty});
        if bounds {
            let (lo, hi) = values.iter().fold(
                ([f32::INFINITY; N], [f32::NEG_INFINITY; N]),
                |(lo, hi), q| {
                    (
                        std::array::from_fn(|k| lo[k].min(q[k])),
                        std::array::from_fn(|k| hi[k].max(q[k])),
                    )
                },
            );
            a["min"] = json!(lo.to_vec());
            a["max"] = json!(hi.to_vec());
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// An accessor of `u32` triangle indices; its index.
    pub(crate) fn indices(&mut self, indices: &[u32]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|v| v.to_le_bytes()).collect();
        let v = self.view(&bytes);
        self.accessors.push(
            json!({"bufferView": v, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}),
        );
        self.accessors.len() - 1
    }

    /// The buffer padded to 4 bytes.
    pub(crate) fn padded(mut self) -> (Vec<u8>, Vec<Value>, Vec<Value>) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        (self.bin, self.views, self.accessors)
    }
}

/// An emission (linear RGB, finite, non-negative) as glTF writes it: `emissiveFactor`, whose
/// components stop at 1, and where the emission is brighter the `KHR_materials_emissive_strength`
/// object (`emissiveStrength`: its largest component) that scales the factor back.
pub(crate) fn emissive_json(emissive: [f32; 3]) -> (Value, Option<Value>) {
    let strength = emissive.iter().fold(1.0f32, |a, &b| a.max(b));
    (
        json!(emissive.map(|c| c / strength)),
        (strength > 1.0).then(|| json!({ "emissiveStrength": strength })),
    )
}

/// A `.glb` file of the JSON document `doc` and the binary chunk `bin` (padded to 4 bytes).
pub(crate) fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("a JSON value serialises");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(bin);
    out
}

impl TestGltf {
    /// The JSON document and the binary buffer; images go into the buffer (`external = None`)
    /// or are named `<stem>_<k>.png` (`external = Some(stem)`, returned as files to write).
    #[allow(clippy::type_complexity)]
    fn build(
        &self,
        external: Option<&str>,
    ) -> Result<(Value, Vec<u8>, Vec<(String, Vec<u8>)>), DataGenError> {
        let mut b = BinBuilder::default();
        let mut meshes = Vec::new();
        for mesh in &self.meshes {
            let mut prims = Vec::new();
            for p in mesh {
                let mut attributes = json!({"POSITION": b.floats(&p.positions, "VEC3", true)});
                if !p.uvs.is_empty() {
                    attributes["TEXCOORD_0"] = json!(b.floats(&p.uvs, "VEC2", false));
                }
                if !p.normals.is_empty() {
                    attributes["NORMAL"] = json!(b.floats(&p.normals, "VEC3", false));
                }
                if !p.tangents.is_empty() {
                    attributes["TANGENT"] = json!(b.floats(&p.tangents, "VEC4", false));
                }
                let indices = b.indices(&p.indices);
                prims.push(
                    json!({"attributes": attributes, "indices": indices, "material": p.material}),
                );
            }
            meshes.push(json!({"primitives": prims}));
        }
        let mut images = Vec::new();
        let mut textures = Vec::new();
        let mut samplers = Vec::new();
        let mut files = Vec::new();
        let mut materials = Vec::new();
        let mut used: Vec<&str> = Vec::new();
        for (k, m) in self.materials.iter().enumerate() {
            let mut pbr = json!({"baseColorFactor": m.base_color, "metallicFactor": 0.0});
            // One image, sampler and texture; the texture's index.
            let mut texture = |img: &Rgba8, name: String| -> Result<usize, DataGenError> {
                let bytes = png(img)?;
                match external {
                    Some(_) => {
                        images.push(json!({"uri": name}));
                        files.push((name, bytes));
                    }
                    None => {
                        let v = b.view(&bytes);
                        images.push(json!({"bufferView": v, "mimeType": "image/png"}));
                    }
                }
                let filter = if m.nearest { 9728 } else { 9729 };
                samplers.push(json!({"magFilter": filter, "minFilter": filter, "wrapS": 33071, "wrapT": 33071}));
                textures.push(json!({"source": images.len() - 1, "sampler": samplers.len() - 1}));
                Ok(textures.len() - 1)
            };
            let stem = external.unwrap_or("");
            if let Some(img) = &m.texture {
                let t = texture(img, format!("{stem}_{k}.png"))?;
                pbr["baseColorTexture"] = json!({"index": t});
            }
            let normal = match &m.normal_texture {
                Some((img, scale)) => {
                    Some((texture(img, format!("{stem}_{k}_normal.png"))?, *scale))
                }
                None => None,
            };
            let mut mat = json!({"pbrMetallicRoughness": pbr, "alphaMode": m.alpha_mode, "doubleSided": m.double_sided});
            if let Some((t, scale)) = normal {
                mat["normalTexture"] = json!({"index": t, "scale": scale});
            }
            if m.alpha_mode == "MASK" {
                mat["alphaCutoff"] = json!(m.alpha_cutoff);
            }
            if m.emissive != [0.0; 3] {
                let (factor, strength) = emissive_json(m.emissive);
                mat["emissiveFactor"] = factor;
                if let Some(strength) = strength {
                    mat["extensions"] = json!({"KHR_materials_emissive_strength": strength});
                    used.push("KHR_materials_emissive_strength");
                }
            }
            if let Some(img) = &m.emissive_texture {
                let t = texture(img, format!("{stem}_{k}_emissive.png"))?;
                mat["emissiveTexture"] = json!({"index": t});
            }
            if m.unlit {
                mat["extensions"] = json!({"KHR_materials_unlit": {}});
                used.push("KHR_materials_unlit");
            }
            materials.push(mat);
        }
        let nodes: Vec<Value> = self
            .nodes
            .iter()
            .map(|n| {
                let mut v = json!({"name": n.name, "matrix": n.matrix});
                if let Some(m) = n.mesh {
                    v["mesh"] = json!(m);
                }
                if !n.children.is_empty() {
                    v["children"] = json!(n.children);
                }
                v
            })
            .collect();
        let (bin, views, accessors) = b.padded();
        let mut buffer = json!({"byteLength": bin.len()});
        if let Some(stem) = external {
            buffer["uri"] = json!(format!("{stem}.bin"));
        }
        let mut doc = json!({
            "asset": {"version": "2.0", "generator": "altrep-data-gen test assets"},
            "scene": 0,
            "scenes": [{"nodes": self.roots}],
            "nodes": nodes,
            "meshes": meshes,
            "materials": materials,
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [buffer],
        });
        if !images.is_empty() {
            doc["images"] = json!(images);
            doc["textures"] = json!(textures);
            doc["samplers"] = json!(samplers);
        }
        used.sort_unstable();
        used.dedup();
        if !used.is_empty() {
            doc["extensionsUsed"] = json!(used);
        }
        Ok((doc, bin, files))
    }

    /// The document as one `.glb` file's bytes.
    pub fn to_glb(&self) -> Result<Vec<u8>, DataGenError> {
        let (doc, bin, _) = self.build(None)?;
        Ok(glb(&doc, &bin))
    }

    /// Writes `<dir>/<stem>.gltf` with `<stem>.bin` and `<stem>_<k>.png` beside it; returns the
    /// `.gltf` path.
    pub fn write_gltf(&self, dir: &Path, stem: &str) -> Result<std::path::PathBuf, DataGenError> {
        let (doc, bin, files) = self.build(Some(stem))?;
        let write = |name: &str, bytes: &[u8]| {
            let p = dir.join(name);
            std::fs::write(&p, bytes).map_err(|source| DataGenError::Io { path: p, source })
        };
        write(&format!("{stem}.bin"), &bin)?;
        for (name, bytes) in &files {
            write(name, bytes)?;
        }
        let path = dir.join(format!("{stem}.gltf"));
        write(
            &format!("{stem}.gltf"),
            &serde_json::to_vec_pretty(&doc).expect("a JSON value serialises"),
        )?;
        Ok(path)
    }

    /// A unit cube `[0, 1]³` whose six faces each map the whole texture (`uv` from `(0, 0)` at
    /// the face's corner of greatest `y`… see [`TestGltf::textured_box_texel`]), textured with an
    /// `n × n` image of sRGB codes `(32·i mod 256, 32·j mod 256, 200, 255)` at texel `(i, j)`,
    /// sampled `NEAREST`, base colour factor 1.
    pub fn textured_box(n: u32) -> Self {
        let data = (0..n)
            .flat_map(|j| (0..n).flat_map(move |i| Self::textured_box_texel(i, j)))
            .collect();
        let mut prim = TestPrimitive::empty(0);
        // Each face: corners a (uv 0,0), b (1,0), c (1,1), d (0,1) as (origin, u edge, v edge);
        // `u × v` points in, so the triangles run a, c, b and a, d, c: counter-clockwise seen
        // from outside, glTF's front faces.
        let faces: [([f32; 3], [f32; 3], [f32; 3]); 6] = [
            ([0.0, 1.0, 1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]), // +z
            ([1.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]), // −z
            ([1.0, 1.0, 1.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]), // +x
            ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]), // −x
            ([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]),  // +y
            ([0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]), // −y
        ];
        for (o, u, v) in faces {
            let base = prim.positions.len() as u32;
            for (s, t) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                prim.positions
                    .push([0, 1, 2].map(|k| o[k] + s * u[k] + t * v[k]));
                prim.uvs.push([s, t]);
            }
            prim.indices
                .extend([base, base + 2, base + 1, base, base + 3, base + 2]);
        }
        Self {
            meshes: vec![vec![prim]],
            materials: vec![TestMaterial {
                base_color: [1.0; 4],
                texture: Some(Rgba8 {
                    width: n,
                    height: n,
                    data,
                }),
                nearest: true,
                alpha_mode: "OPAQUE",
                alpha_cutoff: 0.5,
                normal_texture: None,
                double_sided: true,
                emissive: [0.0; 3],
                emissive_texture: None,
                unlit: false,
            }],
            nodes: vec![TestNode {
                name: "box".into(),
                mesh: Some(0),
                matrix: IDENTITY,
                children: vec![],
            }],
            roots: vec![0],
        }
    }

    /// The sRGB code of texel `(i, j)` of [`TestGltf::textured_box`]'s image.
    pub fn textured_box_texel(i: u32, j: u32) -> [u8; 4] {
        [((32 * i) % 256) as u8, ((32 * j) % 256) as u8, 200, 255]
    }

    /// A square `[0, 1]²` in the plane `z = 0` (`uv = (x, 1 − y)`), textured `n × n` with alpha
    /// 0 on the texels where [`TestGltf::hole`] is true and 255 elsewhere, `MASK` with cutoff ½,
    /// sampled `NEAREST`; behind it (at `z = −0.5`) an opaque untextured square of base colour
    /// `(0.2, 0.9, 0.2)`.
    pub fn masked_quad(n: u32) -> Self {
        let data = (0..n)
            .flat_map(|j| {
                (0..n).flat_map(move |i| {
                    let a = if Self::hole(i, j) { 0 } else { 255 };
                    [230, 120, 40, a]
                })
            })
            .collect();
        let square = |z: f32, material: usize| TestPrimitive {
            positions: vec![[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]],
            uvs: vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
            normals: Vec::new(),
            tangents: Vec::new(),
            indices: vec![0, 1, 2, 0, 2, 3],
            material,
        };
        Self {
            meshes: vec![vec![square(0.0, 0), square(-0.5, 1)]],
            materials: vec![
                TestMaterial::masked(
                    Rgba8 {
                        width: n,
                        height: n,
                        data,
                    },
                    true,
                ),
                TestMaterial::plain([0.2, 0.9, 0.2, 1.0]),
            ],
            nodes: vec![TestNode::mesh_at_origin("quad")],
            roots: vec![0],
        }
    }

    /// A square `[0, 1]²` in the plane `z = 0` (`uv = (x, 1 − y)`, so `+u` is `+x` and `+v` is
    /// `−y`), white, with a normal map of one row of `texels` (linear codes of `(n + 1)/2`) at
    /// `scale`. With `normals`, `NORMAL` is `+z`; with `tangents`, `TANGENT` is `(1, 0, 0, −1)`,
    /// the frame MikkTSpace gives this mapping (`B = w · N × T = −y`).
    pub fn normal_mapped_quad(
        texels: &[[u8; 4]],
        scale: f32,
        normals: bool,
        tangents: bool,
    ) -> Self {
        let n = texels.len() as u32;
        Self {
            meshes: vec![vec![TestPrimitive {
                positions: vec![
                    [0.0, 0.0, 0.0],
                    [1.0, 0.0, 0.0],
                    [1.0, 1.0, 0.0],
                    [0.0, 1.0, 0.0],
                ],
                uvs: vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
                normals: if normals {
                    vec![[0.0, 0.0, 1.0]; 4]
                } else {
                    Vec::new()
                },
                tangents: if tangents {
                    vec![[1.0, 0.0, 0.0, -1.0]; 4]
                } else {
                    Vec::new()
                },
                indices: vec![0, 1, 2, 0, 2, 3],
                material: 0,
            }]],
            materials: vec![TestMaterial {
                base_color: [1.0; 4],
                texture: None,
                nearest: true,
                alpha_mode: "OPAQUE",
                alpha_cutoff: 0.5,
                normal_texture: Some((
                    Rgba8 {
                        width: n,
                        height: 1,
                        data: texels.concat(),
                    },
                    scale,
                )),
                double_sided: true,
                emissive: [0.0; 3],
                emissive_texture: None,
                unlit: false,
            }],
            nodes: vec![TestNode::mesh_at_origin("quad")],
            roots: vec![0],
        }
    }

    /// A shrub of `leaves` alpha-masked leaf cards over a trunk: each card a square of side
    /// 0.25 (file units), centred at a random point of the crown (the ball of radius 1 about
    /// `(0, 1.5, 0)`), turned to a random orientation, textured 16² with a leaf-shaped mask
    /// (alpha 255 inside the ellipse `((u − ½)/0.48)² + ((v − ½)/0.3)² ≤ 1`, 0 outside; `MASK`,
    /// cutoff ½, `LINEAR`) and two greens; the trunk an open square tube of side 0.1 from `y = 0`
    /// to `y = 1`, brown. Nothing in it encloses a volume. Seeded ([`crate::SplitMix64`]).
    pub fn leaf_shrub(leaves: usize, seed: u64) -> Self {
        let mut rng = crate::SplitMix64::new(seed);
        let n = 16u32;
        let data = (0..n)
            .flat_map(|j| {
                (0..n).flat_map(move |i| {
                    let (u, v) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    let inside = ((u - 0.5) / 0.48).powi(2) + ((v - 0.5) / 0.3).powi(2) <= 1.0;
                    let g = if (i + j) % 5 == 0 { 150 } else { 110 };
                    [40, g, 30, if inside { 255 } else { 0 }]
                })
            })
            .collect();
        let mut cards = TestPrimitive::empty(0);
        for _ in 0..leaves {
            // A point of the ball by rejection, and an orthonormal pair from a random normal.
            let centre = loop {
                let p = [0, 1, 2].map(|_| rng.range(-1.0, 1.0) as f32);
                if p.iter().map(|c| c * c).sum::<f32>() <= 1.0 {
                    break [p[0], p[1] + 1.5, p[2]];
                }
            };
            let z = rng.range(-1.0, 1.0) as f32;
            let phi = rng.range(0.0, std::f64::consts::TAU) as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let normal = [r * phi.cos(), r * phi.sin(), z];
            let helper = if normal[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let cross = |a: [f32; 3], b: [f32; 3]| {
                [
                    a[1] * b[2] - a[2] * b[1],
                    a[2] * b[0] - a[0] * b[2],
                    a[0] * b[1] - a[1] * b[0],
                ]
            };
            let unit = |a: [f32; 3]| {
                let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
                a.map(|c| c / l)
            };
            let e1 = unit(cross(normal, helper));
            let e2 = cross(normal, e1);
            let base = cards.positions.len() as u32;
            for (s, t) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                cards
                    .positions
                    .push([0, 1, 2].map(|k| centre[k] + 0.125 * (s * e1[k] + t * e2[k])));
                cards.uvs.push([0.5 * (s + 1.0), 0.5 * (1.0 - t)]);
            }
            cards
                .indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        let mut trunk = TestPrimitive::empty(1);
        let corners = [
            [-0.05f32, -0.05f32],
            [0.05, -0.05],
            [0.05, 0.05],
            [-0.05, 0.05],
        ];
        // Corners counter-clockwise seen from above; each side's quad wound to face out.
        for side in 0..4 {
            let (a, b) = (corners[side], corners[(side + 1) % 4]);
            let base = trunk.positions.len() as u32;
            for [x, z, y] in [
                [a[0], a[1], 0.0],
                [b[0], b[1], 0.0],
                [b[0], b[1], 1.0],
                [a[0], a[1], 1.0],
            ] {
                trunk.positions.push([x, y, z]);
            }
            trunk
                .indices
                .extend([base, base + 2, base + 1, base, base + 3, base + 2]);
        }
        Self {
            meshes: vec![vec![cards, trunk]],
            materials: vec![
                TestMaterial::masked(
                    Rgba8 {
                        width: n,
                        height: n,
                        data,
                    },
                    false,
                ),
                TestMaterial::plain([0.35, 0.22, 0.1, 1.0]),
            ],
            nodes: vec![TestNode::mesh_at_origin("shrub")],
            roots: vec![0],
        }
    }

    /// A rock: an icosphere subdivided `subdivisions` times (`20·4^s` triangles), its radius
    /// displaced by ±25 % of seeded smooth noise (eight random plane waves) and its height
    /// scaled by 0.7, about `(0, 0.7, 0)` (file units). Texture coordinates are longitude and
    /// colatitude (`u = atan2(z, x)/2π + ½`, `v = colatitude/π`), the vertices split along the
    /// seam at `u = 0`; shading normals are the area-weighted means of the faces'. The base
    /// colour is a 64² texture of grey-brown strata with seeded speckle (`LINEAR`, repeated),
    /// the material single-sided and opaque; triangles are wound counter-clockwise from outside.
    /// A textured, closed, smooth asset for simplification and stand-ins. Seeded
    /// ([`crate::SplitMix64`]).
    pub fn textured_rock(subdivisions: u32, seed: u64) -> Self {
        let mut rng = crate::SplitMix64::new(seed);
        let (mut verts, mut faces) = icosahedron();
        for _ in 0..subdivisions {
            let mut mid: std::collections::HashMap<(usize, usize), usize> = Default::default();
            let mut next = Vec::with_capacity(faces.len() * 4);
            for f in &faces {
                let m = [0, 1, 2].map(|k| {
                    let (a, b) = (f[k], f[(k + 1) % 3]);
                    *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                        let p: [f64; 3] =
                            std::array::from_fn(|c| 0.5 * (verts[a][c] + verts[b][c]));
                        let l = p.iter().map(|c| c * c).sum::<f64>().sqrt();
                        verts.push(p.map(|c| c / l));
                        verts.len() - 1
                    })
                });
                next.extend([
                    [f[0], m[0], m[2]],
                    [m[0], f[1], m[1]],
                    [m[2], m[1], f[2]],
                    [m[0], m[1], m[2]],
                ]);
            }
            faces = next;
        }
        // Smooth noise: plane waves of random direction, frequency and phase.
        let waves: Vec<([f64; 3], f64, f64)> = (0..8)
            .map(|_| {
                let z = rng.range(-1.0, 1.0);
                let phi = rng.range(0.0, std::f64::consts::TAU);
                let r = (1.0 - z * z).sqrt();
                let f = rng.range(1.0, 4.0);
                (
                    [r * phi.cos(), r * phi.sin(), z],
                    f,
                    rng.range(0.0, std::f64::consts::TAU),
                )
            })
            .collect();
        let displaced: Vec<[f64; 3]> = verts
            .iter()
            .map(|p| {
                let n: f64 = waves
                    .iter()
                    .map(|(d, f, ph)| (f * (d[0] * p[0] + d[1] * p[1] + d[2] * p[2]) + ph).sin())
                    .sum::<f64>()
                    / 8f64.sqrt();
                let r = 1.0 + 0.25 * n.clamp(-1.0, 1.0);
                [p[0] * r, 0.7 + 0.7 * p[1] * r, p[2] * r]
            })
            .collect();
        // Area-weighted vertex normals.
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let mut normals = vec![[0.0f64; 3]; verts.len()];
        for f in &faces {
            let n = cross(
                sub(displaced[f[1]], displaced[f[0]]),
                sub(displaced[f[2]], displaced[f[0]]),
            );
            for &v in f {
                for c in 0..3 {
                    normals[v][c] += n[c];
                }
            }
        }
        let mut prim = TestPrimitive::empty(0);
        let mut index: std::collections::HashMap<(usize, bool), u32> = Default::default();
        for f in &faces {
            let u = f.map(|v| {
                let p = verts[v];
                p[2].atan2(p[0]) / std::f64::consts::TAU + 0.5
            });
            let wrap = u.iter().cloned().fold(f64::MIN, f64::max)
                - u.iter().cloned().fold(f64::MAX, f64::min)
                > 0.5;
            for (k, &v) in f.iter().enumerate() {
                let shifted = wrap && u[k] < 0.5;
                let i = *index.entry((v, shifted)).or_insert_with(|| {
                    let p = displaced[v];
                    let n = normals[v];
                    let l = n.iter().map(|c| c * c).sum::<f64>().sqrt().max(1e-30);
                    prim.positions.push(p.map(|c| c as f32));
                    prim.normals.push(n.map(|c| (c / l) as f32));
                    let colat = verts[v][1].clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
                    prim.uvs
                        .push([(u[k] + f64::from(u8::from(shifted))) as f32, colat as f32]);
                    (prim.positions.len() - 1) as u32
                });
                prim.indices.push(i);
            }
        }
        let n = 64u32;
        let data = (0..n)
            .flat_map(|j| (0..n).map(move |i| (i, j)))
            .flat_map(|(i, j)| {
                let strata = (f64::from(j) * 0.45 + (f64::from(i) * 0.2).sin() * 2.0).sin();
                let speckle = (i.wrapping_mul(73_856_093) ^ j.wrapping_mul(19_349_663)) % 23;
                let g = (120.0 + 40.0 * strata) as i32 + speckle as i32 - 11;
                let g = g.clamp(0, 255) as u8;
                [
                    g,
                    (f64::from(g) * 0.9) as u8,
                    (f64::from(g) * 0.75) as u8,
                    255,
                ]
            })
            .collect();
        Self {
            meshes: vec![vec![prim]],
            materials: vec![TestMaterial {
                texture: Some(Rgba8 {
                    width: n,
                    height: n,
                    data,
                }),
                double_sided: false,
                emissive: [0.0; 3],
                emissive_texture: None,
                unlit: false,
                ..TestMaterial::plain([1.0; 4])
            }],
            nodes: vec![TestNode::mesh_at_origin("rock")],
            roots: vec![0],
        }
    }

    /// The hole pattern of [`TestGltf::masked_quad`]: texel `(i, j)` is a hole when `i + 2·j`
    /// is a multiple of 3.
    pub fn hole(i: u32, j: u32) -> bool {
        (i + 2 * j).is_multiple_of(3)
    }
}

/// The regular icosahedron on the unit sphere: 12 vertices, 20 faces wound counter-clockwise
/// from outside.
fn icosahedron() -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let raw = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let verts = raw
        .iter()
        .map(|p: &[f64; 3]| {
            let l = p.iter().map(|c| c * c).sum::<f64>().sqrt();
            p.map(|c| c / l)
        })
        .collect();
    let faces = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    (verts, faces)
}
