//! # Asset folders: the files a renderer loads (docs/design.md §12)
//!
//! Every representation is written as one **asset folder**: the data files (PNG for 8- and
//! 16-bit images, EXR for 32-bit float images, little-endian `.bin` for records) and one
//! `asset.json` that describes every file — its role, pixel format, size, channel encodings
//! (the scale and offset of every quantised channel), byte count and BLAKE3 hash — plus the
//! conventions the data follow and the report of the run that made it. The format is documented
//! for renderer authors in `docs/asset-format.md`; this module is its one implementation.
//!
//! * [`AssetWriter`] builds a folder under a temporary name inside the output directory and
//!   [`AssetWriter::commit`] renames it into place, so an interrupted run never leaves a
//!   half-written asset, and a rerun never leaves stale files beside new ones.
//! * [`AssetReader`] opens a folder, refuses a newer major format version, and checks every
//!   file's presence, size and hash before decoding it: a missing, truncated or altered file is a
//!   typed error naming the file.
//!
//! Cost: writing and reading are linear in the bytes; hashing runs at several GB/s.

mod claim;
mod read;
mod write;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

pub use claim::OutputClaim;
pub use read::{AssetReader, PngDecode};
pub(crate) use write::encode_png;
pub use write::{
    AssetWriter, PngCode, STAGING_DIR, check_owned, replace_dir, stop_commits, temporary_of,
    valid_name, write_atomic,
};

/// Major version of the asset format. A reader refuses a file of a newer major version; minor
/// versions only add optional fields.
pub const FORMAT_MAJOR: u32 = 1;
/// Minor version of the asset format.
pub const FORMAT_MINOR: u32 = 4;
/// Name of the description file in every asset folder.
pub const DESCRIPTION_FILE: &str = "asset.json";

/// What went wrong while writing or reading an asset folder.
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    /// An I/O operation failed on `path`.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// `asset.json` is not valid JSON of the expected shape.
    #[error("{path}: malformed asset description: {reason}")]
    Malformed {
        /// The description file.
        path: PathBuf,
        /// The parser's message.
        reason: String,
    },
    /// The folder was written by a newer major version of the format.
    #[error(
        "{path}: asset format {major}.{minor} is newer than this altrep reads ({FORMAT_MAJOR}.x); update altrep"
    )]
    NewerVersion {
        /// The description file.
        path: PathBuf,
        /// Major version found.
        major: u32,
        /// Minor version found.
        minor: u32,
    },
    /// A file listed in `asset.json` is missing.
    #[error("{path}: file listed in asset.json is missing")]
    MissingFile {
        /// The missing file.
        path: PathBuf,
    },
    /// A file's size or hash differs from `asset.json`: it was truncated or altered.
    #[error("{path}: {what} differs from asset.json (truncated or altered file)")]
    Altered {
        /// The file.
        path: PathBuf,
        /// `"size"` or `"content hash"`.
        what: &'static str,
    },
    /// A file decodes to something other than what `asset.json` says.
    #[error("{path}: {reason}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// What did not match.
        reason: String,
    },
    /// The asset holds another representation than the one asked for, or lacks a role.
    #[error("{path}: {reason}")]
    Content {
        /// The asset folder.
        path: PathBuf,
        /// What is missing or unexpected.
        reason: String,
    },
    /// A path altrep would write or replace exists and is not altrep's (a folder without
    /// altrep's `asset.json`, a file, a symbolic link): altrep never writes through it, replaces
    /// it or removes it.
    /// The process was interrupted ([`stop_commits`]) before this folder was renamed into place;
    /// its files stay in the staging folder, which the next run clears.
    #[error("{path}: not written: the run was interrupted")]
    Interrupted {
        /// The asset folder that was not written.
        path: PathBuf,
    },
    #[error(
        "{path}: {reason}; altrep writes only what it wrote itself: move it aside or choose another --out"
    )]
    NotOurs {
        /// The path at fault.
        path: PathBuf,
        /// What it is.
        reason: String,
    },
    /// Data handed to the writer is inconsistent (sizes, non-finite values).
    #[error("cannot write {role}: {reason}")]
    BadData {
        /// The file role.
        role: String,
        /// What is wrong.
        reason: String,
    },
}

/// How the stored integer (or float) of one channel maps to its value:
/// `value = offset + scale · code` for the linear encodings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Encoding {
    /// `value = offset + scale · code`, `code` an unsigned integer of the file's bit depth.
    Linear {
        /// Scale per code step.
        scale: f64,
        /// Value of code 0.
        offset: f64,
    },
    /// 8-bit sRGB-encoded colour, decoded to linear with the IEC 61966-2-1 curve.
    Srgb,
    /// 0 = false (undefined / absent), any other code = true.
    Mask,
    /// 32-bit IEEE float, stored as is.
    Float,
    /// An integer index or count stored as is.
    Integer,
}

/// One channel of a file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Channel {
    /// What the channel holds, e.g. `"albedo.r"`, `"depth"`, `"v_min"`.
    pub name: String,
    /// How codes map to values.
    pub encoding: Encoding,
}

/// Pixel or record format of a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FileFormat {
    /// PNG, 8 bits per channel (1, 2, 3 or 4 channels).
    Png8,
    /// PNG, 16 bits per channel (1, 2, 3 or 4 channels).
    Png16,
    /// OpenEXR, 32-bit float, RGBA (channels beyond the listed ones are zero).
    Exr32,
    /// Little-endian records of `record_bytes` bytes; layout in `docs/asset-format.md`.
    Bin,
    /// A glTF 2.0 binary file (`.glb`): a mesh with its materials (width: its triangles,
    /// height 1).
    Glb,
    /// A JPEG image, 8 bits per channel, as a source asset held it (a `.glb`'s texture).
    Jpeg8,
}

/// The description of one file of an asset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileEntry {
    /// File name inside the asset folder.
    pub path: String,
    /// What the file is for, unique in the asset, e.g. `"view3/colour"`, `"bounds/best-c"`.
    pub role: String,
    /// Pixel or record format.
    pub format: FileFormat,
    /// Width in pixels (record count for `bin`).
    pub width: usize,
    /// Height in pixels (1 for `bin`).
    pub height: usize,
    /// The channels, in storage order (for `bin`: the record fields).
    pub channels: Vec<Channel>,
    /// Bytes per record (`bin` only, else 0).
    #[serde(default)]
    pub record_bytes: usize,
    /// File size in bytes.
    pub bytes: u64,
    /// BLAKE3 hash of the file, hex.
    pub blake3: String,
}

/// The conventions every asset's data follow (docs/design.md §2), written into each `asset.json` so
/// a renderer author does not have to read altrep's code.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Conventions {
    /// Axes of the object frame.
    pub axes: String,
    /// Where horizontal angles start and which way they turn.
    pub angles: String,
    /// Length units of stored radii and depths.
    pub units: String,
    /// Image rows and texel centres.
    pub images: String,
    /// Radius `R` of the bounding cylinder, in the source's units after normalisation (1).
    pub cylinder_radius: f64,
    /// Height `H` of the bounding cylinder, in units of `R`.
    pub cylinder_height: f64,
    /// For an asset made from a mesh file: where the object frame sits in the file's
    /// coordinates (absent for procedural shapes and textures). Since format 1.1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<SourcePlacement>,
}

/// The exact affine maps between a mesh file's coordinates and the object frame, as 4 × 4
/// matrices in **row-major** order acting on column vectors `(x, y, z, 1)`: a renderer draws a
/// stand-in where the mesh was by applying `to_source` (then the mesh's own world transform,
/// if it is drawn inside a larger scene).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourcePlacement {
    /// Source coordinates → object frame: `p_object = s·U·p_source + t`.
    pub to_object: [[f64; 4]; 4],
    /// Object frame → source coordinates (the inverse).
    pub to_source: [[f64; 4]; 4],
    /// The uniform scale `s` (object-frame units per source unit).
    pub scale: f64,
    /// The source's up axis (`U` takes it to the object frame's `+y`).
    pub up: String,
    /// The source's length unit ("metre" for glTF, "file unit" for OBJ).
    pub units: String,
    /// What "source coordinates" are.
    pub frame: String,
}

impl SourcePlacement {
    /// The record of `p`.
    pub fn new(p: &altrep_data_gen::Placement) -> Self {
        // The columns of the transpose are the rows.
        let rows = |m: glam::DAffine3| glam::DMat4::from(m).transpose().to_cols_array_2d();
        Self {
            to_object: rows(p.to_normalised),
            to_source: rows(p.to_source()),
            scale: p.scale(),
            up: p.up.name().into(),
            units: p.units.into(),
            frame: "glTF: world space of the loaded scene or node; OBJ: the file's coordinates"
                .into(),
        }
    }
}

impl Conventions {
    /// The project's conventions for a bounding cylinder of radius `radius` and height `height`.
    pub fn new(radius: f64, height: f64) -> Self {
        Self {
            axes: "object frame right-handed, y up (the axis of every horizontal capture)".into(),
            angles: "azimuth α in radians in the x-z plane, d(α) = (cos α, 0, sin α); a view at α \
                     looks along -d(α); screen right = (sin α, 0, -cos α)"
                .into(),
            units: "lengths (radii, depths, screen abscissae) in units of the bounding cylinder \
                    radius R, so stored radii and depths lie in [-1, 1]; depth grows toward the \
                    camera"
                .into(),
            images: "row-major, row 0 at the top (y = H), texel (i, j) centred at ((i + 1/2)/w, \
                     (j + 1/2)/h) in texture coordinates; colour is straight (not premultiplied) \
                     alpha in files"
                .into(),
            cylinder_radius: radius,
            cylinder_height: height,
            source: None,
        }
    }

    /// These conventions with the placement of the mesh the asset was made from, if any.
    pub fn placed(mut self, placement: Option<&altrep_data_gen::Placement>) -> Self {
        self.source = placement.map(SourcePlacement::new);
        self
    }
}

/// The contents of `asset.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AssetDescription {
    /// `[major, minor]` of the asset format.
    pub format_version: [u32; 2],
    /// The representation, e.g. `"parallax"`, `"cylinder"`, `"octree"`.
    pub representation: String,
    /// Name of the asset in the scene manifest.
    pub asset: String,
    /// altrep version that wrote it.
    pub tool_version: String,
    /// Hash of everything that determines the output (inputs, parameters, needs, versions).
    pub cache_key: String,
    /// Conventions of the data.
    pub conventions: Conventions,
    /// Representation-specific metadata a loader needs (sizes, angles, parameters).
    pub metadata: serde_json::Value,
    /// Costs and errors of the run that wrote it (for summaries of cached runs).
    pub report: serde_json::Value,
    /// Every file of the asset.
    pub files: Vec<FileEntry>,
    /// BLAKE3 (hex) of this description written without this key (format 1.1 on), so an edit of
    /// `asset.json` itself is detected like an edit of a data file. Absent in format 1.0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description_blake3: Option<String>,
}

impl AssetDescription {
    /// The BLAKE3 (hex) of `asset.json` for this description without its own hash (pretty
    /// JSON): what [`AssetDescription::description_blake3`] records.
    pub fn own_hash(&self) -> Result<String, serde_json::Error> {
        let bare = Self {
            description_blake3: None,
            ..self.clone()
        };
        Ok(hash_hex(&serde_json::to_vec_pretty(&bare)?))
    }

    /// This description as `asset.json` bytes (pretty JSON) with `description_blake3` set to
    /// the hash of the rest ([`AssetDescription::own_hash`]): what every write of `asset.json`
    /// stores, so that a reader can tell an edit.
    pub fn sealed_json(&self) -> Result<Vec<u8>, serde_json::Error> {
        let hash = self.own_hash()?;
        serde_json::to_vec_pretty(&Self {
            description_blake3: Some(hash),
            ..self.clone()
        })
    }

    /// The entry with `role`, if any.
    pub fn file(&self, role: &str) -> Option<&FileEntry> {
        self.files.iter().find(|f| f.role == role)
    }

    /// Total bytes of the data files (without `asset.json`).
    pub fn data_bytes(&self) -> u64 {
        self.files.iter().map(|f| f.bytes).sum()
    }
}

/// The BLAKE3 hash of `bytes`, hex.
pub fn hash_hex(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

/// A decoded image of integer codes, row-major, `channels` codes per pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CodeImage<T> {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Channels per pixel (1–4).
    pub channels: usize,
    /// `width · height · channels` codes.
    pub data: Vec<T>,
}

impl<T: Copy + Default> CodeImage<T> {
    /// An image of zeros.
    pub fn new(width: usize, height: usize, channels: usize) -> Self {
        Self {
            width,
            height,
            channels,
            data: vec![T::default(); width * height * channels],
        }
    }

    /// The codes of pixel `idx` (row-major).
    pub fn pixel(&self, idx: usize) -> &[T] {
        &self.data[idx * self.channels..(idx + 1) * self.channels]
    }

    /// The codes of pixel `idx`, mutable.
    pub fn pixel_mut(&mut self, idx: usize) -> &mut [T] {
        &mut self.data[idx * self.channels..(idx + 1) * self.channels]
    }
}

impl CodeImage<u8> {
    /// Premultiplied linear RGBA (`channels ≥ 4` floats per pixel, the first four read) as
    /// RGBA8: straight colour in sRGB codes, alpha (coverage or opacity) linear. The encoding
    /// of every colour atlas of the asset format (`docs/asset-format.md`); a pixel whose alpha
    /// code is 0 stores colour 0. Cost: one pass.
    pub fn from_premultiplied(width: usize, height: usize, channels: usize, data: &[f32]) -> Self {
        let mut img = CodeImage::<u8>::new(width, height, 4);
        for idx in 0..width * height {
            let px = &data[idx * channels..idx * channels + 4];
            let a = px[3].clamp(0.0, 1.0);
            let alpha = (a * 255.0).round() as u8;
            let out = img.pixel_mut(idx);
            for c in 0..3 {
                // A pixel whose alpha code is 0 stores no colour: it decodes to 0 whatever the
                // colour codes, and rewriting what was read gives the same bytes.
                let straight = if alpha > 0 { px[c] / a } else { 0.0 };
                out[c] = (altrep_data_gen::linear_to_srgb(straight.clamp(0.0, 1.0)) * 255.0).round()
                    as u8;
            }
            out[3] = alpha;
        }
        img
    }

    /// The inverse of [`Self::from_premultiplied`] for an RGBA image: premultiplied linear
    /// RGBA floats, 4 per pixel (sRGB codes decoded by the IEC 61966-2-1 curve, then multiplied
    /// by alpha). Errors: an image without 4 channels (the count is returned).
    pub fn to_premultiplied(&self) -> Result<Vec<f32>, usize> {
        if self.channels != 4 {
            return Err(self.channels);
        }
        let lut: [f32; 256] =
            std::array::from_fn(|v| altrep_data_gen::srgb_to_linear(v as f32 / 255.0));
        Ok(self
            .data
            .chunks_exact(4)
            .flat_map(|c| {
                let a = f32::from(c[3]) / 255.0;
                [
                    lut[usize::from(c[0])] * a,
                    lut[usize::from(c[1])] * a,
                    lut[usize::from(c[2])] * a,
                    a,
                ]
            })
            .collect())
    }
}

/// A 32-bit float RGBA image (EXR files), row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct FloatImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width · height` RGBA pixels.
    pub data: Vec<[f32; 4]>,
}
