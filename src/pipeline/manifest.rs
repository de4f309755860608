//! The scene manifest (TOML): assets, the representations wanted, and what the scene needs.
//!
//! ```toml
//! [scene]
//! light = [0.5, 0.8, 0.35]   # direction toward the light (object frame), for baked lighting
//! ambient = 0.3
//!
//! [[asset]]
//! name = "truck"               # folder name of the asset
//! shape = "truck"              # a procedural shape, or: mesh = "meshes/truck.obj" (relative to the
//!                              # manifest; .obj, .gltf or .glb)
//! # up = "z"                   # a mesh's up axis: x, -x, y (default), -y, z, -z
//! # node = "Tree_01"           # glTF: load this node's subtree instead of the default scene
//! [asset.needs]
//! azimuth_deg = [0, 360]       # range of view azimuths α (degrees)
//! elevation_deg = [0, 0]       # range of view elevations (degrees); off the horizontal, parallax
//!                              # and cylinder are refused where their horizontal views miss the
//!                              # quality target (the sphere frames hold every elevation)
//! quality_db = 20              # PSNR target against the ray-cast truth; below it: flagged, exit ≠ 0
//! screen_px = [16, 128]        # range of on-screen sizes of the object (pixels)
//! lighting = "dynamic"         # or "baked"
//! [asset.parallax]             # presence = wanted; every key optional (documented defaults)
//! views = 8
//! [asset.cylinder]            # cylindrical texture (refused when it cannot hold the object)
//! columns = 256
//! [asset.octree]
//! resolution = 64
//! [asset.sphere]              # images with parallax from any direction (views from above)
//! grid = 8
//! [asset.slices]              # stacks of alpha slices of the object; needs lighting = "baked"
//! resolution = 64
//!
//! [[asset]]
//! name = "lawn"
//! tile = { kind = "grass", size = 32, seed = 1 }  # a procedural volume tile (grass, fur, perlin,
//!                              # tree), repeated over a surface: slices only
//! [asset.needs]
//! screen_px = [16, 64]         # on-screen size of one tile
//! grazing_deg = 80             # views from the surface normal up to this angle
//! lighting = "baked"
//! [asset.slices]
//!
//! [[asset]]
//! name = "bark"
//! texture = "bark.png"         # a texture (PNG/EXR, relative to the manifest), or:
//!                              # test_texture = { size = 256, seed = 1 } (procedural, no file)
//! [asset.needs]
//! screen_px = [8, 64]
//! grazing_deg = 75
//! [asset.pyramid]              # texture assets ask for pyramids only; shapes may not
//! wrap = ["Repeat", "Repeat"]
//! ```
//!
//! Unknown keys, wrong types, duplicate asset names and impossible ranges are errors that name the
//! key and its line, before any work starts.

use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::PipelineError;
use crate::representation::registry::for_each_representation;
use crate::representation::{Needs, Representation};

/// Scene-wide settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneSettings {
    /// Direction toward the light in the object frame (any length), used to bake lighting and
    /// for every image of the report.
    pub light: [f32; 3],
    /// Ambient share of the shading in `[0, 1]`.
    pub ambient: f32,
}

impl Default for SceneSettings {
    /// data-gen's default light: `(0.5, 0.8, 0.35)`, ambient 0.3.
    fn default() -> Self {
        Self {
            light: [0.5, 0.8, 0.35],
            ambient: 0.3,
        }
    }
}

/// The manifest's asset structures and their per-representation parts, generated from the one
/// list of representations ([`crate::representation::registry`]).
macro_rules! asset_structs {
    ($(($key:ident, $variant:ident, $repr:ty, $doc:literal)),* $(,)?) => {
        /// One asset of the manifest, as written.
        #[derive(Clone, Debug, Deserialize)]
        #[serde(deny_unknown_fields)]
        struct RawAsset {
            name: Spanned<String>,
            #[serde(default)]
            shape: Option<String>,
            #[serde(default)]
            mesh: Option<PathBuf>,
            #[serde(default)]
            up: Option<Spanned<String>>,
            #[serde(default)]
            node: Option<Spanned<String>>,
            #[serde(default)]
            texture: Option<PathBuf>,
            #[serde(default)]
            test_texture: Option<TestTexture>,
            #[serde(default)]
            tile: Option<Spanned<TileSource>>,
            #[serde(default)]
            needs: Option<Spanned<Needs>>,
            $(
                #[serde(default)]
                $key: Option<Spanned<<$repr as Representation>::Spec>>,
            )*
        }

        /// One asset: its source, needs and the representations wanted.
        #[derive(Clone, Debug, PartialEq)]
        pub struct AssetSpec {
            /// Name (also the folder name).
            pub name: String,
            /// Geometry.
            pub source: SourceSpec,
            /// What the scene needs.
            pub needs: Needs,
            $(
                #[doc = $doc]
                pub $key: Option<<$repr as Representation>::Spec>,
            )*
        }

        impl RawAsset {
            /// The representations asked for, in the registry's order: the key, the span of
            /// its table, and whether it is built from a texture and whether from a tile.
            fn asked(&self) -> Vec<(&'static str, Range<usize>, bool, bool)> {
                let mut v = Vec::new();
                $(
                    if let Some(s) = &self.$key {
                        v.push((
                            stringify!($key),
                            s.span(),
                            <$repr>::FROM_TEXTURE,
                            <$repr>::FROM_TILE,
                        ));
                    }
                )*
                v
            }

            /// Checks every representation's parameters and moves them into the asset. An
            /// error comes with the span of the representation's table.
            fn into_spec(
                self,
                name: String,
                source: SourceSpec,
                needs: Needs,
            ) -> Result<AssetSpec, (Range<usize>, String)> {
                $(
                    let $key = match self.$key {
                        Some(s) => {
                            <$repr>::validate(s.get_ref()).map_err(|m| (s.span(), m))?;
                            Some(s.into_inner())
                        }
                        None => None,
                    };
                )*
                Ok(AssetSpec { name, source, needs, $($key,)* })
            }
        }

        /// The keys of the representations built from a texture, as `[asset.KEY]`.
        fn texture_keys() -> Vec<String> {
            let mut v = Vec::new();
            $(
                if <$repr>::FROM_TEXTURE {
                    v.push(format!("[asset.{}]", stringify!($key)));
                }
            )*
            v
        }

        /// The keys of the representations built from a tile, as `[asset.KEY]`.
        fn tile_keys() -> Vec<String> {
            let mut v = Vec::new();
            $(
                if <$repr>::FROM_TILE {
                    v.push(format!("[asset.{}]", stringify!($key)));
                }
            )*
            v
        }
    };
}
for_each_representation!(asset_structs);

/// A procedural test texture ([`crate::pyramid::truth::test_texture`]): periodic grey
/// checkerboard, sinusoid and noise, one channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TestTexture {
    /// Texels per side (4 to 4096).
    pub size: usize,
    /// Noise seed.
    #[serde(default)]
    pub seed: u64,
}

/// A procedural volume tile ([`crate::slices::test_tile_lit`]), repeated over a surface:
/// `grass`, `fur`, `perlin` or `tree`, `size³` voxels, seeded.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileSource {
    /// Which tile: `grass`, `fur`, `perlin` or `tree`.
    pub kind: String,
    /// Voxels per side (a power of two, 4 to 128). Default 32.
    #[serde(default = "TileSource::default_size")]
    pub size: usize,
    /// Seed of its random placement.
    #[serde(default)]
    pub seed: u64,
}

impl TileSource {
    fn default_size() -> usize {
        32
    }

    /// The tile named by `kind`, if any.
    pub fn tile(&self) -> Option<crate::slices::TestTile> {
        crate::slices::TestTile::ALL
            .into_iter()
            .find(|t| t.name() == self.kind)
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawManifest {
    #[serde(default)]
    scene: RawScene,
    #[serde(default)]
    asset: Vec<RawAsset>,
}

/// `[scene]` as written: each key with its span, so an error names the key's line.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    #[serde(default)]
    light: Option<Spanned<[f32; 3]>>,
    #[serde(default)]
    ambient: Option<Spanned<f32>>,
}

/// Where an asset's geometry comes from.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum SourceSpec {
    /// A procedural shape of data-gen by name.
    Shape(String),
    /// A mesh file, OBJ or glTF 2.0 (`.gltf`, `.glb`; path resolved against the manifest's
    /// folder).
    Mesh {
        /// The file.
        path: PathBuf,
        /// The source's up axis.
        up: altrep_data_gen::UpAxis,
        /// glTF: the node whose subtree is loaded (default: the whole default scene).
        node: Option<String>,
    },
    /// A texture image, PNG or EXR (path resolved against the manifest's folder), loaded as
    /// RGBA f32 (8- and 16-bit codes divided by 255 or 65535, values as stored: sRGB stays sRGB).
    Texture(PathBuf),
    /// The procedural test texture.
    TestTexture(TestTexture),
    /// A procedural volume tile (slices).
    Tile(TileSource),
}

impl SourceSpec {
    /// Whether the asset is a texture (pyramids) rather than geometry.
    pub fn is_texture(&self) -> bool {
        matches!(self, Self::Texture(_) | Self::TestTexture(_))
    }

    /// Whether the asset is a volume tile (slices).
    pub fn is_tile(&self) -> bool {
        matches!(self, Self::Tile(_))
    }
}

/// A parsed, checked manifest.
#[derive(Clone, Debug, PartialEq)]
pub struct Manifest {
    /// Scene-wide settings.
    pub scene: SceneSettings,
    /// The assets, in file order.
    pub assets: Vec<AssetSpec>,
}

/// Names an output folder holds besides the asset folders: no asset may take them (ignoring
/// case, for case-insensitive file systems).
const RESERVED_NAMES: [&str; 3] = ["report.md", "report.json", "pictures"];

/// The span of the key a representation's validation message names (`"parallax.size = …"`,
/// `"cylinder.bounds: …"`) within the table spanning `table`: the line of `key = …` up to the
/// next table header. The table's own span when the key is not written there (a default).
fn key_span(text: &str, table: Range<usize>, message: &str) -> Range<usize> {
    let key: String = message
        .split_once('.')
        .map(|(_, rest)| {
            rest.chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect()
        })
        .unwrap_or_default();
    if key.is_empty() || table.start >= text.len() {
        return table;
    }
    let mut at = table.start;
    for (k, line) in text[table.start..].split_inclusive('\n').enumerate() {
        let t = line.trim_start();
        if k > 0 && t.starts_with('[') {
            break;
        }
        if let Some(rest) = t.strip_prefix(key.as_str())
            && rest.trim_start().starts_with('=')
        {
            return at..at + line.len();
        }
        at += line.len();
    }
    table
}

/// 1-based line of byte offset `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text[..at.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

fn err(file: &Path, text: &str, span: Range<usize>, message: String) -> PipelineError {
    PipelineError::Manifest {
        path: file.to_path_buf(),
        line: line_of(text, span.start),
        message,
    }
}

impl Manifest {
    /// Reads and checks the manifest at `path`.
    pub fn load(path: &Path) -> Result<Self, PipelineError> {
        let bytes = std::fs::read(path).map_err(|source| PipelineError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let text = String::from_utf8(bytes).map_err(|e| PipelineError::Manifest {
            path: path.to_path_buf(),
            line: 0,
            message: format!("not UTF-8 text ({e})"),
        })?;
        Self::parse(&text, path)
    }

    /// Parses and checks manifest `text`; `path` names it in errors and resolves relative mesh
    /// paths. Errors name the key and the line.
    pub fn parse(text: &str, path: &Path) -> Result<Self, PipelineError> {
        let raw: RawManifest = toml::from_str(text).map_err(|e| {
            let line = e.span().map_or(0, |s| line_of(text, s.start));
            PipelineError::Manifest {
                path: path.to_path_buf(),
                line,
                message: e.message().to_string(),
            }
        })?;
        let defaults = SceneSettings::default();
        let scene = SceneSettings {
            light: raw
                .scene
                .light
                .as_ref()
                .map_or(defaults.light, |l| *l.get_ref()),
            ambient: raw
                .scene
                .ambient
                .as_ref()
                .map_or(defaults.ambient, |a| *a.get_ref()),
        };
        let l = scene.light;
        if l.iter().any(|c| !c.is_finite()) || l.iter().all(|&c| c == 0.0) {
            let span = raw.scene.light.as_ref().map_or(0..0, Spanned::span);
            return Err(err(
                path,
                text,
                span,
                "scene.light must be a finite, non-zero direction".into(),
            ));
        }
        if !(0.0..=1.0).contains(&scene.ambient) {
            let span = raw.scene.ambient.as_ref().map_or(0..0, Spanned::span);
            return Err(err(
                path,
                text,
                span,
                format!("scene.ambient = {} must be in [0, 1]", scene.ambient),
            ));
        }
        let base = path.parent().unwrap_or(Path::new("."));
        let mut assets: Vec<AssetSpec> = Vec::new();
        for mut a in raw.asset {
            let name_span = a.name.span();
            let name = a.name.get_ref().clone();
            if !crate::asset::valid_name(&name) {
                return Err(err(
                    path,
                    text,
                    name_span,
                    format!(
                        "asset.name '{name}' must be a folder name (letters, digits, '-', '_', '.')"
                    ),
                ));
            }
            if let Some(b) = assets
                .iter()
                .find(|b: &&AssetSpec| b.name.eq_ignore_ascii_case(&name))
            {
                let message = if b.name == name {
                    format!("duplicate asset name '{name}'")
                } else {
                    format!(
                        "asset name '{name}' differs from '{}' only by case: one folder on a case-insensitive file system",
                        b.name
                    )
                };
                return Err(err(path, text, name_span, message));
            }
            if let Some(taken) = RESERVED_NAMES
                .iter()
                .find(|r| r.eq_ignore_ascii_case(&name))
            {
                return Err(err(
                    path,
                    text,
                    name_span,
                    format!(
                        "asset name '{name}' is taken by the output folder's own '{taken}' (reserved: {})",
                        RESERVED_NAMES.join(", ")
                    ),
                ));
            }
            let source = match (
                a.shape.take(),
                a.mesh.take(),
                a.texture.take(),
                a.test_texture.take(),
                a.tile.take(),
            ) {
                (None, None, None, None, Some(t)) => {
                    let tile = t.get_ref();
                    if tile.tile().is_none() {
                        return Err(err(
                            path,
                            text,
                            t.span(),
                            format!(
                                "asset.tile.kind = '{}' must be grass, fur, perlin or tree",
                                tile.kind
                            ),
                        ));
                    }
                    if !tile.size.is_power_of_two() || !(4..=128).contains(&tile.size) {
                        return Err(err(
                            path,
                            text,
                            t.span(),
                            format!(
                                "asset.tile.size = {} must be a power of two in 4..=128",
                                tile.size
                            ),
                        ));
                    }
                    SourceSpec::Tile(t.into_inner())
                }
                (Some(s), None, None, None, None) => {
                    altrep_data_gen::scene_shape(&s).map_err(|e| {
                        err(path, text, name_span.clone(), format!("asset.shape: {e}"))
                    })?;
                    SourceSpec::Shape(s)
                }
                (None, Some(m), None, None, None) => {
                    let up = match a.up.take() {
                        Some(u) => u.get_ref().parse().map_err(|e: String| {
                            err(path, text, u.span(), format!("asset.up: {e}"))
                        })?,
                        None => altrep_data_gen::UpAxis::default(),
                    };
                    SourceSpec::Mesh {
                        path: base.join(m),
                        up,
                        node: a.node.take().map(Spanned::into_inner),
                    }
                }
                (None, None, Some(t), None, None) => SourceSpec::Texture(base.join(t)),
                (None, None, None, Some(t), None) => {
                    if !(4..=4096).contains(&t.size) {
                        return Err(err(
                            path,
                            text,
                            name_span,
                            format!("asset.test_texture.size = {} must be in 4..=4096", t.size),
                        ));
                    }
                    SourceSpec::TestTexture(t)
                }
                _ => {
                    return Err(err(
                        path,
                        text,
                        name_span,
                        format!(
                            "asset '{name}': give exactly one of `shape`, `mesh`, `texture`, `test_texture` or `tile`"
                        ),
                    ));
                }
            };
            if let Some(key) = [a.up.as_ref(), a.node.as_ref()].iter().flatten().next() {
                return Err(err(
                    path,
                    text,
                    key.span(),
                    format!("asset '{name}': `up` and `node` apply to a `mesh` only"),
                ));
            }
            let (needs_span, needs) = match a.needs.take() {
                Some(n) => (n.span(), n.into_inner()),
                None => (name_span.clone(), Needs::default()),
            };
            check_needs(&needs).map_err(|m| err(path, text, needs_span, m))?;
            let asked = a.asked();
            if source.is_tile()
                && let Some((key, span, _, _)) = asked.iter().find(|(_, _, _, tile)| !*tile)
            {
                return Err(err(
                    path,
                    text,
                    span.clone(),
                    format!(
                        "asset '{name}' is a volume tile: it may only ask for {}; [asset.{key}] \
                         needs a `shape` or `mesh`",
                        tile_keys().join(", ")
                    ),
                ));
            }
            if let Some((key, span, from_texture, _)) = asked
                .iter()
                .find(|(_, _, t, _)| !source.is_tile() && *t != source.is_texture())
            {
                let message = if *from_texture {
                    format!(
                        "asset '{name}' is a shape or mesh: [asset.{key}] needs a `texture` or `test_texture`"
                    )
                } else {
                    format!(
                        "asset '{name}' is a texture: it may only ask for {}; \
                         [asset.{key}] needs a `shape` or `mesh`",
                        texture_keys().join(", ")
                    )
                };
                return Err(err(path, text, span.clone(), message));
            }
            if asked.is_empty() {
                return Err(err(
                    path,
                    text,
                    name_span,
                    format!("asset '{name}' asks for no representation"),
                ));
            }
            let spec = a
                .into_spec(name.clone(), source, needs)
                .map_err(|(span, m)| {
                    let span = key_span(text, span, &m);
                    err(path, text, span, format!("{name}: {m}"))
                })?;
            assets.push(spec);
        }
        if assets.is_empty() {
            return Err(PipelineError::Manifest {
                path: path.to_path_buf(),
                line: 0,
                message: "no [[asset]] in the manifest".into(),
            });
        }
        Ok(Self { scene, assets })
    }
}

/// Checks the ranges of `needs`; the message names the key.
fn check_needs(n: &Needs) -> Result<(), String> {
    let range = |key: &str, r: [f64; 2], lo: f64, hi: f64| {
        if !(r[0].is_finite() && r[1].is_finite()) || r[0] > r[1] || r[0] < lo || r[1] > hi {
            Err(format!(
                "needs.{key} = [{}, {}] is impossible: need finite min ≤ max within [{lo}, {hi}]",
                r[0], r[1]
            ))
        } else {
            Ok(())
        }
    };
    range("azimuth_deg", n.azimuth_deg, -720.0, 720.0)?;
    range("elevation_deg", n.elevation_deg, -90.0, 90.0)?;
    range("screen_px", n.screen_px, 1.0, 16384.0)?;
    if !(n.grazing_deg.is_finite() && (0.0..90.0).contains(&n.grazing_deg)) {
        return Err(format!(
            "needs.grazing_deg = {} must be in [0, 90)",
            n.grazing_deg
        ));
    }
    if !(n.quality_db.is_finite() && n.quality_db > 0.0) {
        return Err(format!(
            "needs.quality_db = {} must be positive",
            n.quality_db
        ));
    }
    Ok(())
}
