//! Opening an asset folder, checking every file, and decoding them.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageFormat};

use super::{
    AssetDescription, AssetError, CodeImage, DESCRIPTION_FILE, FORMAT_MAJOR, FileEntry, FileFormat,
    FloatImage, hash_hex,
};

/// An opened, verified asset folder: [`Self::open`] has read `asset.json` and every file it
/// lists and checked sizes and hashes; the typed accessors decode a file by role.
#[derive(Debug)]
pub struct AssetReader {
    dir: PathBuf,
    description: AssetDescription,
    bytes: HashMap<String, Vec<u8>>,
}

impl AssetReader {
    /// Opens the asset folder `dir`. Errors: a missing or malformed `asset.json`, a newer major
    /// format version, a listed file that is missing, truncated or altered (each naming the
    /// file). Cost: reads and hashes every file once.
    pub fn open(dir: &Path) -> Result<Self, AssetError> {
        let path = dir.join(DESCRIPTION_FILE);
        let text = std::fs::read(&path).map_err(|source| {
            if source.kind() == std::io::ErrorKind::NotFound {
                AssetError::MissingFile { path: path.clone() }
            } else {
                AssetError::Io {
                    path: path.clone(),
                    source,
                }
            }
        })?;
        // Read the version first, so a newer format with other fields says so clearly.
        let probe: serde_json::Value =
            serde_json::from_slice(&text).map_err(|e| AssetError::Malformed {
                path: path.clone(),
                reason: e.to_string(),
            })?;
        let version = probe
            .get("format_version")
            .and_then(|v| v.as_array())
            .and_then(|a| {
                Some((
                    u32::try_from(a.first()?.as_u64()?).ok()?,
                    u32::try_from(a.get(1)?.as_u64()?).ok()?,
                ))
            })
            .ok_or_else(|| AssetError::Malformed {
                path: path.clone(),
                reason: "format_version must be [major, minor]".into(),
            })?;
        if version.0 > FORMAT_MAJOR {
            return Err(AssetError::NewerVersion {
                path,
                major: version.0,
                minor: version.1,
            });
        }
        let description: AssetDescription =
            serde_json::from_value(probe).map_err(|e| AssetError::Malformed {
                path: path.clone(),
                reason: e.to_string(),
            })?;
        if let Some(recorded) = &description.description_blake3 {
            let hash = description.own_hash().map_err(|e| AssetError::Malformed {
                path: path.clone(),
                reason: e.to_string(),
            })?;
            if &hash != recorded {
                return Err(AssetError::Altered {
                    path,
                    what: "its own recorded hash",
                });
            }
        }
        let mut bytes = HashMap::new();
        for f in &description.files {
            if !super::write::valid_name(&f.path) {
                return Err(AssetError::Malformed {
                    path: path.clone(),
                    reason: format!("file name '{}' is not a plain name", f.path),
                });
            }
            let fp = dir.join(&f.path);
            let data = std::fs::read(&fp).map_err(|source| {
                if source.kind() == std::io::ErrorKind::NotFound {
                    AssetError::MissingFile { path: fp.clone() }
                } else {
                    AssetError::Io {
                        path: fp.clone(),
                        source,
                    }
                }
            })?;
            if data.len() as u64 != f.bytes {
                return Err(AssetError::Altered {
                    path: fp,
                    what: "size",
                });
            }
            if hash_hex(&data) != f.blake3 {
                return Err(AssetError::Altered {
                    path: fp,
                    what: "content hash",
                });
            }
            if bytes.insert(f.role.clone(), data).is_some() {
                return Err(AssetError::Malformed {
                    path: path.clone(),
                    reason: format!("role '{}' listed twice", f.role),
                });
            }
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            description,
            bytes,
        })
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The parsed `asset.json`.
    pub fn description(&self) -> &AssetDescription {
        &self.description
    }

    /// The member written under `prefix` ([`super::AssetWriter::member`]) as an asset of its
    /// own: the files whose roles start with `prefix`, the prefix taken off their roles (their
    /// file names keep it), described as `representation` with `metadata` (what the member's
    /// writer returned, stored by the outer representation). Errors: no file with that prefix.
    /// Cost: a copy of the member's bytes.
    pub fn member(
        &self,
        prefix: &str,
        representation: &str,
        metadata: serde_json::Value,
    ) -> Result<AssetReader, AssetError> {
        let mut description = self.description.clone();
        description.representation = representation.into();
        description.metadata = metadata;
        description.files.retain(|f| f.role.starts_with(prefix));
        let mut bytes = HashMap::new();
        for f in &mut description.files {
            bytes.insert(
                f.role[prefix.len()..].to_string(),
                self.bytes[&f.role].clone(),
            );
            f.role = f.role[prefix.len()..].to_string();
        }
        if description.files.is_empty() {
            return Err(self.content(format!("no file of the member '{prefix}'")));
        }
        Ok(Self {
            dir: self.dir.clone(),
            description,
            bytes,
        })
    }

    /// Errors unless the asset holds `representation`.
    pub fn expect_representation(&self, representation: &str) -> Result<(), AssetError> {
        if self.description.representation == representation {
            Ok(())
        } else {
            Err(self.content(format!(
                "holds a '{}' asset, not '{representation}'",
                self.description.representation
            )))
        }
    }

    /// A content error about this asset.
    pub fn content(&self, reason: String) -> AssetError {
        AssetError::Content {
            path: self.dir.clone(),
            reason,
        }
    }

    /// Whether the asset has a file with `role`.
    pub fn has(&self, role: &str) -> bool {
        self.description.file(role).is_some()
    }

    fn entry(&self, role: &str, format: FileFormat) -> Result<(&FileEntry, &[u8]), AssetError> {
        let e = self
            .description
            .file(role)
            .ok_or_else(|| self.content(format!("no file with role '{role}'")))?;
        if e.format != format {
            return Err(AssetError::Decode {
                path: self.dir.join(&e.path),
                reason: format!("format {:?}, expected {format:?}", e.format),
            });
        }
        Ok((e, &self.bytes[role]))
    }

    fn decode_image(&self, e: &FileEntry, bytes: &[u8]) -> Result<DynamicImage, AssetError> {
        let format = match e.format {
            FileFormat::Exr32 => ImageFormat::OpenExr,
            _ => ImageFormat::Png,
        };
        let img = image::load_from_memory_with_format(bytes, format).map_err(|err| {
            AssetError::Decode {
                path: self.dir.join(&e.path),
                reason: err.to_string(),
            }
        })?;
        if (img.width() as usize, img.height() as usize) != (e.width, e.height) {
            return Err(AssetError::Decode {
                path: self.dir.join(&e.path),
                reason: format!(
                    "image is {}×{}, asset.json says {}×{}",
                    img.width(),
                    img.height(),
                    e.width,
                    e.height
                ),
            });
        }
        Ok(img)
    }

    fn channel_mismatch(&self, e: &FileEntry, found: usize) -> AssetError {
        AssetError::Decode {
            path: self.dir.join(&e.path),
            reason: format!(
                "image has {found} channels, asset.json lists {}",
                e.channels.len()
            ),
        }
    }

    /// Decodes the PNG with `role` into codes of its depth (`u8` for `png8`, `u16` for
    /// `png16`). Errors: another format or depth, a size or channel count that differs from
    /// `asset.json`.
    pub fn png<T: PngDecode>(&self, role: &str) -> Result<CodeImage<T>, AssetError> {
        let (e, bytes) = self.entry(role, T::FORMAT)?;
        let img = self.decode_image(e, bytes)?;
        let color = img.color();
        let (channels, data) = T::raw(img).ok_or_else(|| AssetError::Decode {
            path: self.dir.join(&e.path),
            reason: format!("{color:?} is not a {:?} image", T::FORMAT),
        })?;
        if channels != e.channels.len() {
            return Err(self.channel_mismatch(e, channels));
        }
        Ok(CodeImage {
            width: e.width,
            height: e.height,
            channels,
            data,
        })
    }

    /// Decodes the 8-bit PNG with `role` (see [`Self::png`]).
    pub fn png8(&self, role: &str) -> Result<CodeImage<u8>, AssetError> {
        self.png(role)
    }

    /// Decodes the 16-bit PNG with `role` (see [`Self::png`]).
    pub fn png16(&self, role: &str) -> Result<CodeImage<u16>, AssetError> {
        self.png(role)
    }

    /// Decodes the EXR with `role` as RGBA f32.
    pub fn exr(&self, role: &str) -> Result<FloatImage, AssetError> {
        let (e, bytes) = self.entry(role, FileFormat::Exr32)?;
        let img = self.decode_image(e, bytes)?.into_rgba32f();
        let data = img
            .into_raw()
            .chunks_exact(4)
            .map(|p| [p[0], p[1], p[2], p[3]])
            .collect();
        Ok(FloatImage {
            width: e.width,
            height: e.height,
            data,
        })
    }

    /// The raw records of the `bin` file with `role` and its record size.
    pub fn bin(&self, role: &str) -> Result<(&[u8], usize), AssetError> {
        let (e, bytes) = self.entry(role, FileFormat::Bin)?;
        if e.record_bytes == 0 || !bytes.len().is_multiple_of(e.record_bytes) {
            return Err(AssetError::Decode {
                path: self.dir.join(&e.path),
                reason: format!(
                    "{} bytes is not a whole number of {}-byte records",
                    bytes.len(),
                    e.record_bytes
                ),
            });
        }
        Ok((bytes, e.record_bytes))
    }

    /// The bytes of the `.glb` file with `role` and the triangle count `asset.json` gives it.
    pub fn glb(&self, role: &str) -> Result<(&[u8], usize), AssetError> {
        let (e, bytes) = self.entry(role, FileFormat::Glb)?;
        Ok((bytes, e.width))
    }

    /// The channels listed for `role`.
    pub fn channels(&self, role: &str) -> Result<&[super::Channel], AssetError> {
        self.description
            .file(role)
            .map(|e| e.channels.as_slice())
            .ok_or_else(|| self.content(format!("no file with role '{role}'")))
    }
}

/// A code type a PNG decodes to: `u8` or `u16`.
pub trait PngDecode: Sized {
    /// The file format of this depth.
    const FORMAT: FileFormat;
    /// `(channels, codes)` of an image of this depth, `None` for another depth.
    fn raw(img: DynamicImage) -> Option<(usize, Vec<Self>)>;
}

impl PngDecode for u8 {
    const FORMAT: FileFormat = FileFormat::Png8;
    fn raw(img: DynamicImage) -> Option<(usize, Vec<Self>)> {
        match img {
            DynamicImage::ImageLuma8(b) => Some((1, b.into_raw())),
            DynamicImage::ImageLumaA8(b) => Some((2, b.into_raw())),
            DynamicImage::ImageRgb8(b) => Some((3, b.into_raw())),
            DynamicImage::ImageRgba8(b) => Some((4, b.into_raw())),
            _ => None,
        }
    }
}

impl PngDecode for u16 {
    const FORMAT: FileFormat = FileFormat::Png16;
    fn raw(img: DynamicImage) -> Option<(usize, Vec<Self>)> {
        match img {
            DynamicImage::ImageLuma16(b) => Some((1, b.into_raw())),
            DynamicImage::ImageLumaA16(b) => Some((2, b.into_raw())),
            DynamicImage::ImageRgb16(b) => Some((3, b.into_raw())),
            DynamicImage::ImageRgba16(b) => Some((4, b.into_raw())),
            _ => None,
        }
    }
}
