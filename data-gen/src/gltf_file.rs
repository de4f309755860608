//! glTF 2.0 input (`.gltf` with external or embedded buffers, and `.glb`) through the `gltf`
//! crate: the triangles of a scene (or of a node's subtree) in the scene's world coordinates, with
//! their materials' base colour, vertex colours, texture coordinates, shading normals and alpha.
//!
//! What is read, and how (see `docs/real-assets.md` for the whole list):
//! * The default scene (the first scene when none is marked default), or the subtree of the node
//!   named by the caller, with every node transform composed (`T·R·S`, or the node's matrix) from
//!   the root down. Under a mirroring transform (negative determinant) each triangle's second and
//!   third corners are swapped, so its winding still faces its front out (glTF §3.7.2.1: the
//!   determinant decides the winding); shading normals are carried by the inverse transpose.
//! * Triangle primitives, indexed or not; strips and fans are converted to triangles. Points and
//!   lines are refused with an error naming the primitive (`meshes[3].primitives[0]`).
//! * `TEXCOORD_0/1`, `COLOR_0` (linear RGB or RGBA) and `NORMAL`; without `NORMAL` a triangle is
//!   shaded flat, as the specification requires.
//! * `baseColorFactor` × `baseColorTexture` (sRGB decoded, the sampler's wrap modes and
//!   magnification filter, `KHR_texture_transform`), `alphaMode` and `alphaCutoff`.
//! * `normalTexture` with its `scale` (linear, read over the ray's footprint like the base colour)
//!   in the frame of `TANGENT`, or of MikkTSpace tangents generated in world coordinates when the
//!   primitive has none (the specification's rule), so a baked normal map shades as its baker meant.
//! * `doubleSided` (default false, as the specification says): a single-sided material's back
//!   faces let rays through in every tracer, the truth's and the captures' alike (the inside tests
//!   of voxelisation still count them).
//! * `emissiveFactor` × `emissiveTexture` (sRGB decoded; `KHR_materials_emissive_strength`
//!   scales the factor) and `KHR_materials_unlit` (the base
//!   colour shown whatever the light): such a surface's hit albedo is the one the mesh's light
//!   shades to what it shows ([`crate::Light::albedo_giving`]; named in the notes, since
//!   stand-ins relit by another light scale it).
//! * Everything else that changes how the asset looks is named in [`GltfScene::notes`]:
//!   occlusion maps, optional extensions altrep does not know, skins and
//!   morph targets (the bind pose).
//!
//! Every accessor is checked before it is read (element type, stride, count, range), so a
//! malformed file is an error naming the accessor, never a panic.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DMat3, DMat4, DVec3, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use rayon::prelude::*;

use crate::error::DataGenError;
use crate::surface::{
    Material, MaterialAlpha, NormalMap, SamplerFilter, SurfaceTri, TextureImage, TextureRef,
    UvTransform, Wrap,
};

/// Extensions whose `extensionsRequired` entry altrep accepts.
const UNDERSTOOD: &[&str] = &[
    "KHR_texture_transform",
    "KHR_materials_unlit",
    "KHR_materials_emissive_strength",
];

/// The triangles of a glTF scene in its world coordinates.
pub(crate) struct GltfScene {
    /// Triangle corners, world coordinates (metres by the specification).
    pub(crate) positions: Vec<[[f64; 3]; 3]>,
    /// Each triangle's surface attributes (shading normals in world coordinates).
    pub(crate) surfaces: Vec<SurfaceTri>,
    /// Materials, indexed by [`SurfaceTri::material`]; the last is glTF's default material.
    pub(crate) materials: Vec<Material>,
    /// For each material, whether altrep wrote it for triangles coloured by the fallback albedo
    /// (`extras.altrep_fallback_albedo`, see the `gltf_export` module).
    pub(crate) fallback: Vec<bool>,
    /// What the file holds and altrep does not read (sorted, without repeats).
    pub(crate) notes: Vec<String>,
    /// Files read besides the glTF file itself (external buffers and images), with their hash.
    pub(crate) inputs: Vec<(PathBuf, blake3::Hash)>,
}

/// An error at glTF path `at` of file `path`.
fn err(path: &Path, at: impl Into<String>, message: impl Into<String>) -> DataGenError {
    DataGenError::Gltf {
        path: path.to_path_buf(),
        at: at.into(),
        message: message.into(),
    }
}

/// Reads the data a URI names: a `data:` URI's base64 payload, or a file relative to `base`
/// (percent-decoded). Other schemes are refused. Files read are recorded in `inputs`.
fn read_uri(
    uri: &str,
    base: &Path,
    inputs: &mut Vec<(PathBuf, blake3::Hash)>,
) -> Result<Vec<u8>, String> {
    use base64::Engine as _;
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| "a data URI without ';base64,'".to_string())?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| format!("base64 data URI: {e}"));
    }
    if let Some((scheme, _)) = uri.split_once(':')
        && scheme.len() > 1
        && scheme
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
    {
        return Err(format!(
            "URI scheme '{scheme}:' is not supported (only relative files and data URIs)"
        ));
    }
    let decoded = urlencoding::decode(uri).map_err(|e| format!("URI '{uri}': {e}"))?;
    let file = base.join(&*decoded);
    let bytes = std::fs::read(&file).map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    inputs.push((file, blake3::hash(&bytes)));
    Ok(bytes)
}

/// Checks that accessor `acc` can be read as `dims` of one of `types` without going out of
/// range, and returns its count.
fn check_accessor(
    path: &Path,
    acc: &gltf::Accessor,
    dims: &[Dimensions],
    types: &[DataType],
    buffers: &[Vec<u8>],
) -> Result<usize, DataGenError> {
    let at = format!("accessors[{}]", acc.index());
    if !dims.contains(&acc.dimensions()) || !types.contains(&acc.data_type()) {
        return Err(err(
            path,
            at,
            format!(
                "{:?} of {:?} where {:?} of {:?} is needed",
                acc.dimensions(),
                acc.data_type(),
                dims,
                types
            ),
        ));
    }
    let count = acc.count();
    if count == 0 {
        return Err(err(path, at, "count is 0"));
    }
    let size = acc.size();
    let check_view = |view: &gltf::buffer::View, offset: usize, n: usize, elem: usize| {
        let stride = view.stride().unwrap_or(elem);
        let vat = format!("bufferViews[{}]", view.index());
        if stride < elem {
            return Err(err(
                path,
                &vat,
                format!("stride {stride} is below the element size {elem}"),
            ));
        }
        let end = stride
            .checked_mul(n - 1)
            .and_then(|x| x.checked_add(elem))
            .and_then(|x| x.checked_add(offset));
        if end.is_none_or(|e| e > view.length()) {
            return Err(err(path, &at, format!("{n} elements do not fit in {vat}")));
        }
        let buf = &buffers[view.buffer().index()];
        if view
            .offset()
            .checked_add(view.length())
            .is_none_or(|e| e > buf.len())
        {
            return Err(err(
                path,
                &vat,
                format!("extends past the end of buffers[{}]", view.buffer().index()),
            ));
        }
        Ok(())
    };
    if let Some(view) = acc.view() {
        check_view(&view, acc.offset(), count, size)?;
    }
    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(err(path, &at, format!("sparse count {n} (of {count})")));
        }
        let ind = sparse.indices();
        check_view(&ind.view(), ind.offset(), n, ind.index_type().size())?;
        let val = sparse.values();
        check_view(&val.view(), val.offset(), n, size)?;
    }
    Ok(count)
}

/// References the `gltf` crate follows before or without checking them (its validation indexes
/// the `POSITION` accessor unchecked; its image and sparse-index readers unwrap): checked here
/// first, so that a malformed file is an error, not a panic.
fn precheck(root: &gltf::json::Root) -> Result<(), (String, String)> {
    use gltf::json::validation::Checked;
    let n_acc = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let refs = prim
                .attributes
                .values()
                .map(|i| i.value())
                .chain(prim.indices.map(|i| i.value()));
            for i in refs {
                if i >= n_acc {
                    return Err((
                        format!("meshes[{m}].primitives[{p}]"),
                        format!(
                            "refers to accessors[{i}], which does not exist ({n_acc} accessors)"
                        ),
                    ));
                }
            }
        }
    }
    for (k, image) in root.images.iter().enumerate() {
        let at = format!("images[{k}]");
        match (&image.uri, image.buffer_view) {
            (Some(_), None) => {}
            (None, Some(v)) => {
                if image.mime_type.is_none() {
                    return Err((at, "bufferView without mimeType".into()));
                }
                if v.value() >= root.buffer_views.len() {
                    return Err((
                        at,
                        format!("refers to bufferViews[{}], which does not exist", v.value()),
                    ));
                }
            }
            _ => return Err((at, "needs exactly one of uri and bufferView".into())),
        }
    }
    for (k, acc) in root.accessors.iter().enumerate() {
        if let Some(sparse) = &acc.sparse {
            let ok = matches!(
                sparse.indices.component_type,
                Checked::Valid(gltf::json::accessor::IndexComponentType(
                    gltf::json::accessor::ComponentType::U8
                        | gltf::json::accessor::ComponentType::U16
                        | gltf::json::accessor::ComponentType::U32
                ))
            );
            if !ok {
                return Err((
                    format!("accessors[{k}].sparse.indices"),
                    "componentType must be an unsigned integer".into(),
                ));
            }
        }
    }
    Ok(())
}

/// The `T·R·S` or matrix transform of `node` in `f64`.
fn local(node: &gltf::Node) -> DMat4 {
    let m = node.transform().matrix();
    DMat4::from_cols_array_2d(&m.map(|c| c.map(f64::from)))
}

/// Loads the scene of the glTF document in `bytes` (read from `path`; external files are resolved
/// against its folder). `node` restricts it to the subtree of the first node of that name.
pub(crate) fn load(
    bytes: &[u8],
    path: &Path,
    node: Option<&str>,
) -> Result<GltfScene, DataGenError> {
    let base = path.parent().unwrap_or(Path::new("."));
    // Required extensions first, so that one altrep does not read is named as such.
    let raw = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| err(path, "document", e.to_string()))?;
    for (i, ext) in raw.extensions_required().enumerate() {
        if !UNDERSTOOD.contains(&ext) {
            return Err(err(
                path,
                format!("extensionsRequired[{i}]"),
                format!("required extension {ext} is not supported"),
            ));
        }
    }
    precheck(raw.as_json()).map_err(|(at, message)| err(path, at, message))?;
    // The `gltf` crate's own validation (what `Gltf::from_slice` runs), on the document
    // parsed once.
    let mut problems = Vec::new();
    {
        use gltf::json::validation::Validate;
        let root = raw.as_json();
        root.validate(root, gltf::json::Path::new, &mut |at, e| {
            problems.push((at().to_string(), e.to_string()));
        });
    }
    if let Some((at, what)) = problems.first() {
        return Err(err(
            path,
            at.clone(),
            format!("invalid: {what} ({} problems in all)", problems.len()),
        ));
    }
    let gltf::Gltf { document, blob } = raw;
    let mut notes = BTreeSet::new();
    let mut inputs = Vec::new();
    for ext in document.extensions_used() {
        if !UNDERSTOOD.contains(&ext) {
            notes.insert(format!("extension {ext} ignored"));
        }
    }

    // Buffers.
    let mut blob = blob;
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let at = format!("buffers[{}]", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob
                .take()
                .ok_or_else(|| err(path, &at, "refers to the GLB binary chunk, which is absent"))?,
            gltf::buffer::Source::Uri(uri) => {
                read_uri(uri, base, &mut inputs).map_err(|m| err(path, &at, m))?
            }
        };
        if data.len() < buffer.length() {
            return Err(err(
                path,
                &at,
                format!("holds {} bytes, {} declared", data.len(), buffer.length()),
            ));
        }
        buffers.push(data);
    }

    // The scene's root nodes with their parents' transform.
    let roots: Vec<(gltf::Node, DMat4)> = match node {
        Some(name) => {
            let found = document
                .nodes()
                .find(|n| n.name() == Some(name))
                .ok_or_else(|| {
                    let names: Vec<&str> =
                        document.nodes().filter_map(|n| n.name()).take(12).collect();
                    err(
                        path,
                        "nodes",
                        format!("no node named '{name}' (named nodes: {})", names.join(", ")),
                    )
                })?;
            // The parents' transforms, from the root down.
            let mut parent = vec![None; document.nodes().len()];
            for n in document.nodes() {
                for c in n.children() {
                    parent[c.index()] = Some(n.index());
                }
            }
            let all: Vec<gltf::Node> = document.nodes().collect();
            let mut m = DMat4::IDENTITY;
            let mut at = parent[found.index()];
            let mut guard = 0;
            while let Some(p) = at {
                m = local(&all[p]) * m;
                at = parent[p];
                guard += 1;
                if guard > all.len() {
                    return Err(err(path, "nodes", "the node hierarchy has a cycle"));
                }
            }
            vec![(found, m)]
        }
        None => {
            let scene = document
                .default_scene()
                .or_else(|| document.scenes().next())
                .ok_or_else(|| err(path, "scenes", "the file has no scene"))?;
            scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect()
        }
    };

    // Every (mesh, world transform) instance, depth first.
    let mut instances = Vec::new();
    let mut stack = roots;
    let mut visits = 0usize;
    while let Some((n, parent)) = stack.pop() {
        visits += 1;
        if visits > 4 * document.nodes().len() + 4 {
            return Err(err(path, "nodes", "the node hierarchy has a cycle"));
        }
        let world = parent * local(&n);
        if n.skin().is_some() {
            notes.insert("skins ignored: the bind pose is used".into());
        }
        if let Some(mesh) = n.mesh() {
            instances.push((mesh, world));
        }
        for c in n.children() {
            stack.push((c, world));
        }
    }
    instances.reverse();

    // Materials: glTF's, then the default material (index `materials.len()`).
    let mut materials = Vec::new();
    let mut fallback = Vec::new();
    // Decode the base-colour images (sRGB) and the normal maps (linear) in parallel, each once
    // per way it is read.
    let mut wanted: BTreeSet<(usize, bool)> = BTreeSet::new();
    for m in document.materials() {
        if let Some(info) = m.pbr_metallic_roughness().base_color_texture() {
            wanted.insert((info.texture().source().index(), true));
        }
        if let Some(n) = m.normal_texture() {
            wanted.insert((n.texture().source().index(), false));
        }
        if let Some(e) = m.emissive_texture()
            && !m.unlit()
            && m.emissive_factor() != [0.0; 3]
            && m.emissive_strength() != Some(0.0)
        {
            wanted.insert((e.texture().source().index(), true));
        }
    }
    let mut images: BTreeMap<(usize, bool), Arc<TextureImage>> = BTreeMap::new();
    let encoded: Vec<((usize, bool), String, Vec<u8>)> = {
        let mut encoded = Vec::new();
        for (image, srgb) in wanted
            .iter()
            .filter_map(|&(i, srgb)| document.images().nth(i).map(|im| (im, srgb)))
        {
            let at = format!("images[{}]", image.index());
            let data = match image.source() {
                gltf::image::Source::View { view, .. } => {
                    let buf = &buffers[view.buffer().index()];
                    let range = view.offset()..view.offset().saturating_add(view.length());
                    buf.get(range)
                        .ok_or_else(|| {
                            err(
                                path,
                                &at,
                                format!("bufferViews[{}] extends past its buffer", view.index()),
                            )
                        })?
                        .to_vec()
                }
                gltf::image::Source::Uri { uri, .. } => {
                    read_uri(uri, base, &mut inputs).map_err(|m| err(path, &at, m))?
                }
            };
            encoded.push(((image.index(), srgb), at, data));
        }
        encoded
    };
    // The images are decoded while the triangles are read: the two do not depend on each
    // other (a primitive needs to know only which coordinate set its material's normal map
    // reads), and one large texture would otherwise leave a core idle. Errors keep their
    // order: images, then materials, then triangles.
    let normal_sets: Vec<Option<usize>> = document
        .materials()
        .map(|m| m.normal_texture().map(|n| (n.tex_coord() as usize).min(1)))
        .collect();
    let default_material = normal_sets.len() as u32;
    let (decoded, triangles): (Vec<_>, _) = rayon::join(
        || {
            encoded
                .into_par_iter()
                .map(|(key, at, data)| {
                    let decoded = TextureImage::decode(&data, key.1).map_err(|m| err(path, &at, m));
                    (key, decoded)
                })
                .collect()
        },
        || read_triangles(path, instances, &buffers, &normal_sets, default_material),
    );
    for (key, d) in decoded {
        images.insert(key, Arc::new(d?));
    }
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
    };
    let filter = |s: &gltf::texture::Sampler| match s.mag_filter() {
        Some(gltf::texture::MagFilter::Nearest) => SamplerFilter::Nearest,
        _ => SamplerFilter::Linear,
    };
    // An sRGB-coded texture a material reads (`what`: its glTF key), with the coordinate set it
    // reads: the decoded image, the sampler's filter and wrap modes, `KHR_texture_transform`.
    let colour_texture = |info: &gltf::texture::Info,
                          what: &str,
                          at: &str|
     -> Result<(TextureRef, u32), DataGenError> {
        let tex = info.texture();
        let sampler = tex.sampler();
        let (transform, set) = match info.texture_transform() {
            Some(t) => (
                UvTransform::from_offset_rotation_scale(t.offset(), t.rotation(), t.scale()),
                t.tex_coord().unwrap_or(info.tex_coord()),
            ),
            None => (UvTransform::default(), info.tex_coord()),
        };
        if set > 1 {
            return Err(err(
                path,
                at,
                format!("{what} reads TEXCOORD_{set}; only sets 0 and 1 are read"),
            ));
        }
        let image = images
            .get(&(tex.source().index(), true))
            .cloned()
            .ok_or_else(|| err(path, at, format!("{what}: image missing")))?;
        Ok((
            TextureRef {
                image,
                filter: filter(&sampler),
                wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
                transform,
            },
            set,
        ))
    };
    for m in document.materials() {
        let at = format!("materials[{}]", m.index().unwrap_or(0));
        let pbr = m.pbr_metallic_roughness();
        let base_texture = match pbr.base_color_texture() {
            Some(info) => Some(colour_texture(&info, "baseColorTexture", &at)?),
            None => None,
        };
        let alpha_mode = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => MaterialAlpha::Opaque,
            gltf::material::AlphaMode::Mask => MaterialAlpha::Mask {
                cutoff: m.alpha_cutoff().unwrap_or(0.5),
            },
            gltf::material::AlphaMode::Blend => MaterialAlpha::Blend,
        };
        let normal_map = match m.normal_texture() {
            Some(info) => {
                let tex = info.texture();
                let sampler = tex.sampler();
                let set = info.tex_coord();
                if set > 1 {
                    return Err(err(
                        path,
                        &at,
                        format!("normalTexture reads TEXCOORD_{set}; only sets 0 and 1 are read"),
                    ));
                }
                let image = images
                    .get(&(tex.source().index(), false))
                    .cloned()
                    .ok_or_else(|| err(path, &at, "normal map image missing"))?;
                Some(NormalMap {
                    texture: TextureRef {
                        image,
                        filter: filter(&sampler),
                        wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
                        transform: UvTransform::default(),
                    },
                    set,
                    scale: info.scale(),
                })
            }
            None => None,
        };
        // Emission: the factor, times the texture where there is one (read only where the
        // factor is not black and the material is lit, as the specification's shading does).
        // `KHR_materials_emissive_strength` scales the factor past 1.
        let strength = m.emissive_strength().unwrap_or(1.0);
        if !(strength.is_finite() && strength >= 0.0) {
            return Err(err(
                path,
                &at,
                format!("KHR_materials_emissive_strength {strength} must be finite and ≥ 0"),
            ));
        }
        let emissive = Vec3::from(m.emissive_factor()) * strength;
        let emissive_texture = match m.emissive_texture() {
            Some(info) if !m.unlit() && emissive != Vec3::ZERO => {
                Some(colour_texture(&info, "emissiveTexture", &at)?)
            }
            _ => None,
        };
        if m.unlit() || emissive != Vec3::ZERO {
            notes.insert(
                "emissive or unlit materials: folded into albedo under the scene's light \
                 (exact when lighting is baked; relit stand-ins scale them with the light)"
                    .into(),
            );
        }
        if m.occlusion_texture().is_some() {
            notes.insert("occlusion maps ignored".into());
        }
        let [r, g, b, a] = pbr.base_color_factor();
        fallback.push(m.extras().as_ref().is_some_and(|e| {
            serde_json::from_str::<serde_json::Value>(e.get()).is_ok_and(|v| {
                v[crate::gltf_export::FALLBACK_MARK] == serde_json::Value::Bool(true)
            })
        }));
        materials.push(Material {
            name: m.name().unwrap_or_default().to_string(),
            base_color: Vec4::new(r, g, b, a),
            base_texture,
            alpha_texture: None,
            alpha_mode,
            normal_map,
            single_sided: !m.double_sided(),
            emissive,
            emissive_texture,
            unlit: m.unlit(),
        });
    }
    debug_assert_eq!(materials.len() as u32, default_material);
    // The specification's default material: white, opaque, single-sided.
    materials.push(Material {
        name: "default".into(),
        base_color: Vec4::ONE,
        single_sided: true,
        ..Material::default()
    });
    fallback.push(false);

    let (positions, surfaces, triangle_notes) = triangles?;
    notes.extend(triangle_notes);
    Ok(GltfScene {
        positions,
        surfaces,
        materials,
        fallback,
        notes: notes.into_iter().collect(),
        inputs,
    })
}

/// The triangles of the mesh `instances` (each with its world transform) over `buffers`: their
/// corners in world coordinates, their surface attributes, and the notes on what was not read.
/// `normal_sets[m]` is the texture coordinate set material `m`'s normal map reads (tangents are
/// made for those primitives); `default_material` the index primitives without a material take.
/// Cost: one pass over the vertices and corners, MikkTSpace where tangents are made.
#[allow(clippy::type_complexity)]
fn read_triangles(
    path: &Path,
    instances: Vec<(gltf::Mesh<'_>, DMat4)>,
    buffers: &[Vec<u8>],
    normal_sets: &[Option<usize>],
    default_material: u32,
) -> Result<(Vec<[[f64; 3]; 3]>, Vec<SurfaceTri>, BTreeSet<String>), DataGenError> {
    let mut notes = BTreeSet::new();
    let mut positions = Vec::new();
    let mut surfaces = Vec::new();
    let f32s = [DataType::F32];
    let uv_types = [DataType::F32, DataType::U8, DataType::U16];
    for (mesh, world) in instances {
        let normal_map = DMat3::from_mat4(world).inverse().transpose();
        for prim in mesh.primitives() {
            let at = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
            let mode = prim.mode();
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                return Err(err(
                    path,
                    &at,
                    format!(
                        "{mode:?} primitives are not supported (triangles, strips and fans only)"
                    ),
                ));
            }
            if prim.morph_targets().len() > 0 {
                notes.insert("morph targets ignored: the base shape is used".into());
            }
            let pos_acc = prim
                .get(&gltf::Semantic::Positions)
                .ok_or_else(|| err(path, &at, "no POSITION attribute"))?;
            let n = check_accessor(path, &pos_acc, &[Dimensions::Vec3], &f32s, buffers)?;
            let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let short = |what: &str| {
                err(
                    path,
                    &at,
                    format!("{what} could not be read (sparse data out of range?)"),
                )
            };
            let pos: Vec<DVec3> = reader
                .read_positions()
                .ok_or_else(|| short("POSITION"))?
                .map(|p| world.transform_point3(DVec3::from(p.map(f64::from))))
                .collect();
            let normals: Option<Vec<Vec3>> = match prim.get(&gltf::Semantic::Normals) {
                Some(acc) => {
                    check_accessor(path, &acc, &[Dimensions::Vec3], &f32s, buffers)?;
                    Some(
                        reader
                            .read_normals()
                            .ok_or_else(|| short("NORMAL"))?
                            .map(|v| {
                                (normal_map * DVec3::from(v.map(f64::from)))
                                    .normalize_or_zero()
                                    .as_vec3()
                            })
                            .collect(),
                    )
                }
                None => None,
            };
            let mut uvs: [Option<Vec<Vec2>>; 2] = [None, None];
            for (set, slot) in uvs.iter_mut().enumerate() {
                if let Some(acc) = prim.get(&gltf::Semantic::TexCoords(set as u32)) {
                    check_accessor(path, &acc, &[Dimensions::Vec2], &uv_types, buffers)?;
                    *slot = Some(
                        reader
                            .read_tex_coords(set as u32)
                            .ok_or_else(|| short("TEXCOORD"))?
                            .into_f32()
                            .map(Vec2::from)
                            .collect(),
                    );
                }
            }
            let colors: Option<Vec<Vec4>> = match prim.get(&gltf::Semantic::Colors(0)) {
                Some(acc) => {
                    check_accessor(
                        path,
                        &acc,
                        &[Dimensions::Vec3, Dimensions::Vec4],
                        &uv_types,
                        buffers,
                    )?;
                    Some(
                        reader
                            .read_colors(0)
                            .ok_or_else(|| short("COLOR_0"))?
                            .into_rgba_f32()
                            .map(Vec4::from)
                            .collect(),
                    )
                }
                None => None,
            };
            let lengths_ok = pos.len() == n
                && normals.as_ref().is_none_or(|v| v.len() == n)
                && uvs.iter().flatten().all(|v| v.len() == n)
                && colors.as_ref().is_none_or(|v| v.len() == n);
            if !lengths_ok {
                return Err(err(path, &at, "attributes have different counts"));
            }
            let indices: Vec<u32> = match prim.indices() {
                Some(acc) => {
                    check_accessor(
                        path,
                        &acc,
                        &[Dimensions::Scalar],
                        &[DataType::U8, DataType::U16, DataType::U32],
                        buffers,
                    )?;
                    let idx: Vec<u32> = reader
                        .read_indices()
                        .ok_or_else(|| short("indices"))?
                        .into_u32()
                        .collect();
                    if let Some(bad) = idx.iter().find(|&&i| i as usize >= n) {
                        return Err(err(
                            path,
                            format!("accessors[{}]", acc.index()),
                            format!("index {bad} out of range (POSITION has {n} vertices)"),
                        ));
                    }
                    idx
                }
                None => (0..n as u32).collect(),
            };
            let corners: Vec<[u32; 3]> = match mode {
                Mode::Triangles => indices
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect(),
                // glTF 2.0 §3.7.2.1: strip triangle i is (i, i + 1 + i%2, i + 2 − i%2).
                Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
                    .map(|i| {
                        let o = i % 2;
                        [indices[i], indices[i + 1 + o], indices[i + 2 - o]]
                    })
                    .collect(),
                _ => (1..indices.len().saturating_sub(1))
                    .map(|i| [indices[i], indices[i + 1], indices[0]])
                    .collect(),
            };
            let material = prim
                .material()
                .index()
                .map_or(default_material, |i| i as u32);
            // Tangents where the material has a normal map: the file's TANGENT (carried by the
            // node's linear part, the handedness flipped by a mirroring one), else MikkTSpace's
            // in world coordinates (glTF §3.7.2.1), from the normals and the map's coordinates.
            let normal_set = normal_sets.get(material as usize).copied().flatten();
            let tangents: Option<Vec<[Vec4; 3]>> = match normal_set {
                None => None,
                Some(set) => match prim.get(&gltf::Semantic::Tangents) {
                    Some(acc) => {
                        check_accessor(path, &acc, &[Dimensions::Vec4], &f32s, buffers)?;
                        let linear = DMat3::from_mat4(world);
                        let hand = linear.determinant().signum();
                        let t: Vec<Vec4> = reader
                            .read_tangents()
                            .ok_or_else(|| short("TANGENT"))?
                            .map(|[x, y, z, w]| {
                                let xyz = (linear * DVec3::new(x.into(), y.into(), z.into()))
                                    .normalize_or_zero()
                                    .as_vec3();
                                xyz.extend(w * hand as f32)
                            })
                            .collect();
                        if t.len() != n {
                            return Err(err(path, &at, "attributes have different counts"));
                        }
                        Some(corners.iter().map(|c| c.map(|i| t[i as usize])).collect())
                    }
                    None => match &uvs[set] {
                        Some(uv) => mikktspace(
                            &corners,
                            &pos,
                            normals.as_deref(),
                            uv,
                            world.determinant() < 0.0,
                        ),
                        None => {
                            notes.insert(format!(
                                "normal maps without their TEXCOORD_{set} ignored"
                            ));
                            None
                        }
                    },
                },
            };
            // Under a mirroring transform the file's counter-clockwise triangles are clockwise
            // in world space (glTF §3.7.2.1): their second and third corners are swapped, so
            // every triangle's winding faces its front out (single-sided materials cull by it).
            let flip = world.determinant() < 0.0;
            for (k, c) in corners.into_iter().enumerate() {
                let c = if flip { [c[0], c[2], c[1]] } else { c };
                let [a, b, d] = c.map(|i| i as usize);
                positions.push([a, b, d].map(|i| pos[i].to_array()));
                let uv = [0, 1].map(|s| match &uvs[s] {
                    Some(v) => [v[a], v[b], v[d]],
                    None => [Vec2::ZERO; 3],
                });
                surfaces.push(SurfaceTri {
                    material,
                    uv,
                    color: match &colors {
                        Some(v) => [v[a], v[b], v[d]],
                        None => [Vec4::ONE; 3],
                    },
                    normal: match (&normals, &tangents) {
                        (Some(v), _) => Some([v[a], v[b], v[d]]),
                        // A normal-mapped flat triangle: its face normal by glTF's winding rule
                        // (the corners are already in front-facing order), the frame
                        // MikkTSpace used.
                        (None, Some(_)) => {
                            let [p0, p1, p2] = [a, b, d].map(|i| pos[i]);
                            let f = (p1 - p0).cross(p2 - p0).normalize_or_zero().as_vec3();
                            Some([f; 3])
                        }
                        (None, None) => None,
                    },
                    tangent: tangents.as_ref().map(|t| {
                        let t = t[k];
                        Box::new(if flip { [t[0], t[2], t[1]] } else { t })
                    }),
                });
            }
        }
    }
    Ok((positions, surfaces, notes))
}

/// MikkTSpace tangents (`xyz`, handedness in `w`) of each corner of the triangles `corners` over
/// vertices `pos` with shading normals `normals` (the faces' own where there are none) and
/// texture coordinates `uv`, through `bevy_mikktspace`; `None` if it cannot make them (every face
/// degenerate). `mirrored`: the instance's transform has a negative determinant, which reverses
/// the triangles' winding (glTF §3.7.2.1); MikkTSpace reads handedness from the winding, so the
/// corners are handed to it in the reversed order. Cost: linear in the corners, one pass of the
/// reference algorithm.
fn mikktspace(
    corners: &[[u32; 3]],
    pos: &[DVec3],
    normals: Option<&[Vec3]>,
    uv: &[Vec2],
    mirrored: bool,
) -> Option<Vec<[Vec4; 3]>> {
    struct Faces<'a> {
        corners: &'a [[u32; 3]],
        order: [usize; 3],
        pos: &'a [DVec3],
        normals: Option<&'a [Vec3]>,
        uv: &'a [Vec2],
        out: Vec<[Vec4; 3]>,
    }
    impl Faces<'_> {
        fn vertex(&self, face: usize, vert: usize) -> usize {
            self.corners[face][self.order[vert]] as usize
        }
    }
    impl bevy_mikktspace::Geometry for Faces<'_> {
        fn num_faces(&self) -> usize {
            self.corners.len()
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.pos[self.vertex(face, vert)].as_vec3().to_array()
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            match self.normals {
                Some(n) => n[self.vertex(face, vert)].to_array(),
                None => {
                    let [a, b, c] = [0, 1, 2].map(|k| self.pos[self.vertex(face, k)]);
                    (b - a)
                        .cross(c - a)
                        .normalize_or_zero()
                        .as_vec3()
                        .to_array()
                }
            }
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            self.uv[self.vertex(face, vert)].to_array()
        }
        fn set_tangent(
            &mut self,
            tangent_space: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            if let Some(t) = tangent_space {
                self.out[face][self.order[vert]] = Vec4::from(t.tangent_encoded());
            }
        }
    }
    let mut faces = Faces {
        corners,
        order: if mirrored { [0, 2, 1] } else { [0, 1, 2] },
        pos,
        normals,
        uv,
        out: vec![[Vec4::ZERO; 3]; corners.len()],
    };
    bevy_mikktspace::generate_tangents(&mut faces).ok()?;
    Some(faces.out)
}
