//! An asset's source: the shape, mesh or texture the manifest names, loaded, with the hash of every
//! byte it read (the cache key's input part).

use std::path::Path;

use altrep_data_gen::{Light, Mesh, MeshLoadOptions, Shape, scene_shape};

use super::manifest::{AssetSpec, SourceSpec};
use super::output::io;
use crate::representation::{PipelineError, Source};

/// What an asset is made of, once loaded.
pub(super) enum Loaded {
    /// A shape or mesh, with a mesh's placement and the notes of its loader.
    Geometry(
        Box<dyn Shape + Send + Sync>,
        Option<altrep_data_gen::Placement>,
        Vec<String>,
    ),
    /// A texture.
    Texture(crate::pyramid::Texture),
    /// A volume tile.
    Tile(crate::slices::TexelVolume),
}

impl Loaded {
    /// The [`Source`] of asset `name` lit by `light`.
    pub(super) fn source<'a>(&'a self, name: &'a str, light: Light) -> Source<'a> {
        let (geometry, texture, tile, placement) = match self {
            Self::Geometry(g, p, _) => (Some(g.as_ref() as &(dyn Shape + Sync)), None, None, *p),
            Self::Texture(t) => (None, Some(t), None, None),
            Self::Tile(v) => (None, None, Some(v), None),
        };
        Source {
            name,
            geometry,
            texture,
            tile,
            light,
            placement,
        }
    }

    /// What the source's loader noted (features of the file not read).
    pub(super) fn notes(&self) -> &[String] {
        match self {
            Self::Geometry(_, _, n) => n,
            Self::Texture(_) | Self::Tile(_) => &[],
        }
    }
}

/// Reads a texture file (PNG or EXR) as RGBA f32: 8- and 16-bit codes scaled to `[0, 1]`,
/// values as stored (no colour conversion).
pub(super) fn load_texture(
    path: &Path,
) -> Result<(crate::pyramid::Texture, Vec<u8>), PipelineError> {
    let bytes = std::fs::read(path).map_err(io(path))?;
    let bad = |reason: String| PipelineError::TextureFile {
        path: path.to_path_buf(),
        reason,
    };
    let img = image::load_from_memory(&bytes)
        .map_err(|e| bad(e.to_string()))?
        .into_rgba32f();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let tex =
        crate::pyramid::Texture::new(w, h, 4, img.into_raw()).map_err(|e| bad(e.to_string()))?;
    Ok((tex, bytes))
}

/// The geometry, texture or tile of an asset and the hash of its input bytes; a tile is shaded
/// with `light` (the scene's), which its hash covers.
pub(super) fn load_source(
    spec: &AssetSpec,
    light: &Light,
) -> Result<(Loaded, String), PipelineError> {
    match &spec.source {
        SourceSpec::Shape(name) => Ok((
            Loaded::Geometry(Box::new(scene_shape(name)?), None, Vec::new()),
            crate::asset::hash_hex(format!("shape:{name}").as_bytes()),
        )),
        SourceSpec::Mesh { path, up, node } => {
            let bytes = std::fs::read(path).map_err(io(path))?;
            let options = MeshLoadOptions {
                up: *up,
                node: node.clone(),
                light: *light,
                ..MeshLoadOptions::default()
            };
            let mesh = Mesh::from_bytes(&bytes, path, &options)?;
            // The key covers the mesh file, every file it read (materials, buffers, images)
            // and how it was read. A plain y-up OBJ without other files keeps the key of the
            // mesh bytes alone.
            let hash = if mesh.inputs().is_empty() && *up == Default::default() && node.is_none() {
                crate::asset::hash_hex(&bytes)
            } else {
                let mut h = blake3::Hasher::new();
                h.update(blake3::hash(&bytes).as_bytes());
                h.update(format!("up:{up};node:{node:?}").as_bytes());
                for (file, digest) in mesh.inputs() {
                    let name = file
                        .strip_prefix(path.parent().unwrap_or(path))
                        .unwrap_or(file);
                    h.update(name.to_string_lossy().as_bytes());
                    h.update(digest.as_bytes());
                }
                h.finalize().to_hex().to_string()
            };
            let placement = Some(*mesh.placement());
            let notes = mesh.notes().to_vec();
            Ok((Loaded::Geometry(Box::new(mesh), placement, notes), hash))
        }
        SourceSpec::Texture(path) => {
            let (tex, bytes) = load_texture(path)?;
            Ok((Loaded::Texture(tex), crate::asset::hash_hex(&bytes)))
        }
        SourceSpec::TestTexture(t) => Ok((
            Loaded::Texture(crate::pyramid::truth::test_texture(t.size, t.seed)),
            crate::asset::hash_hex(format!("test_texture:{}:{}", t.size, t.seed).as_bytes()),
        )),
        SourceSpec::Tile(t) => {
            let kind = t
                .tile()
                .ok_or_else(|| PipelineError::Spec(format!("tile '{}'", t.kind)))?;
            let lighting = crate::slices::SliceLighting {
                direction: light.direction.to_array(),
                ambient: light.ambient,
            };
            let volume = crate::slices::test_tile_lit(kind, t.size, t.seed, &lighting)?;
            let key = format!("tile:{}:{}:{}:{:?}", t.kind, t.size, t.seed, lighting);
            Ok((Loaded::Tile(volume), crate::asset::hash_hex(key.as_bytes())))
        }
    }
}
