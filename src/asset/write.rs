//! Writing an asset folder under a temporary name, then renaming it into place.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use exr::prelude::WritableImage;

use super::{
    AssetDescription, AssetError, Channel, CodeImage, Conventions, DESCRIPTION_FILE, FORMAT_MAJOR,
    FORMAT_MINOR, FileEntry, FileFormat, FloatImage, hash_hex,
};

/// Name of the folder, inside an output directory, where assets are built before the rename.
pub const STAGING_DIR: &str = ".staging";

/// Builds one asset folder. Files go into `OUT/.staging/ASSET.REPR.PID.N/`; [`Self::commit`]
/// writes `asset.json` last and renames the folder to `OUT/ASSET/REPR`, replacing an earlier one
/// whole. A
/// writer dropped without commit removes its staging folder; a killed process leaves it in
/// `.staging`, which the next run of the pipeline clears.
///
/// PNGs are encoded and written at [`Self::commit`], all of them in parallel (rayon): the adders
/// check their input and reserve the file's place in the description, so the description lists
/// files in the order they were added.
pub struct AssetWriter {
    staging: PathBuf,
    target: PathBuf,
    files: Vec<FileEntry>,
    /// PNGs still to encode and write: the index of their entry in `files` and the encoder.
    pending: Vec<(usize, PendingPng)>,
    /// Prepended to every role and file name added ([`Self::member`]).
    prefix: String,
    /// Whether files are only encoded and counted, never written ([`Self::sizing`]).
    dry: bool,
    committed: bool,
}

/// Encodes one added PNG (see [`AssetWriter::png`]).
type PendingPng = Box<dyn FnOnce() -> Result<Vec<u8>, String> + Send + Sync>;

impl std::fmt::Debug for AssetWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AssetWriter")
            .field("staging", &self.staging)
            .field("target", &self.target)
            .field("files", &self.files)
            .field("pending", &self.pending.len())
            .field("prefix", &self.prefix)
            .field("committed", &self.committed)
            .finish()
    }
}

pub(super) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> AssetError + '_ {
    move |source| AssetError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The name of [`write_atomic`]'s temporary file for a file named `name`, in this process.
fn temporary_name(name: &str) -> String {
    format!(".{name}.tmp{}", std::process::id())
}

/// The name of the file that `name` is a temporary file of, when `name` is one of
/// [`write_atomic`]'s temporary names (of any process): what a run killed while it wrote leaves.
pub fn temporary_of(name: &str) -> Option<&str> {
    let (target, pid) = name.strip_prefix('.')?.rsplit_once(".tmp")?;
    let ours = !target.is_empty() && !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit());
    ours.then_some(target)
}

/// Writes `bytes` to `path` through a temporary sibling and a rename, so a reader never sees a
/// partial file, and a link or another name of the file at `path` (a hard link) is replaced, not
/// written through. The temporary file is created new (an entry left at its name, a file or a
/// link, is removed first, never followed) and removed when the write fails. Cost: one write,
/// one rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), AssetError> {
    use std::io::Write;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = path.with_file_name(temporary_name(&name));
    let _ = std::fs::remove_file(&tmp);
    let mut file = std::fs::File::options()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(io(&tmp))?;
    if let Err(e) = file.write_all(bytes) {
        drop(file);
        let _ = std::fs::remove_file(&tmp);
        return Err(io(path)(e));
    }
    drop(file);
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        AssetError::Io {
            path: path.to_path_buf(),
            source: e,
        }
    })
}

impl AssetWriter {
    /// Starts representation `repr` of asset `asset` (folder names: letters, digits, `-`, `_`,
    /// `.`) in `out`. Errors: a bad name, a staging folder that cannot be created.
    pub fn new(out: &Path, asset: &str, repr: &str) -> Result<Self, AssetError> {
        for name in [asset, repr] {
            if !valid_name(name) {
                return Err(AssetError::BadData {
                    role: "asset name".into(),
                    reason: format!(
                        "'{name}' is not a folder name (letters, digits, '-', '_', '.'; not starting with '.')"
                    ),
                });
            }
        }
        static COUNTER: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let staging = out
            .join(STAGING_DIR)
            .join(format!("{asset}.{repr}.{}.{n}", std::process::id()));
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(io(&staging))?;
        }
        std::fs::create_dir_all(&staging).map_err(io(&staging))?;
        Ok(Self {
            staging,
            target: out.join(asset).join(repr),
            files: Vec::new(),
            pending: Vec::new(),
            prefix: String::new(),
            dry: false,
            committed: false,
        })
    }

    /// A writer that encodes what is added and counts its bytes without writing anything
    /// ([`Self::sized`]): what a representation's files would weigh, for a planner choosing
    /// between candidates by their cost. It cannot commit.
    pub fn sizing() -> Self {
        Self {
            staging: PathBuf::new(),
            target: PathBuf::new(),
            files: Vec::new(),
            pending: Vec::new(),
            prefix: String::new(),
            dry: true,
            committed: false,
        }
    }

    /// Encodes what is still pending and returns the bytes of every file added so far (what
    /// they weigh on disk, `asset.json` apart). Cost: the PNG encodings, in parallel.
    pub fn sized(&mut self) -> Result<u64, AssetError> {
        self.flush()?;
        Ok(self.files.iter().map(|f| f.bytes).sum())
    }

    /// As [`Self::sized`], file by file: each file's role (with its prefix) and bytes, in the
    /// order added.
    pub fn sized_files(&mut self) -> Result<Vec<(String, u64)>, AssetError> {
        self.flush()?;
        Ok(self
            .files
            .iter()
            .map(|f| (f.role.clone(), f.bytes))
            .collect())
    }

    /// The folder the asset will have once committed.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// What [`Self::member`] puts before the names added now (empty outside a member): for
    /// files that name each other (a `.glb`'s image URIs).
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// Runs `f` with every role and file name it adds prefixed by `prefix` (a plain name
    /// part, for example `impostor64-`): one representation written as a member of another in
    /// the same folder (a level-of-detail chain's members), read back through
    /// [`super::AssetReader::member`]. Prefixes nest.
    pub fn member<T>(&mut self, prefix: &str, f: impl FnOnce(&mut Self) -> T) -> T {
        let outer = self.prefix.clone();
        self.prefix = format!("{outer}{prefix}");
        let out = f(self);
        self.prefix = outer;
        out
    }

    /// Checks `role` and `file` (unique, plain names) and appends the file's entry, its size
    /// and hash left for [`Self::store`]; returns the entry's index.
    fn reserve(
        &mut self,
        role: &str,
        file: &str,
        format: FileFormat,
        (width, height): (usize, usize),
        channels: Vec<Channel>,
        record_bytes: usize,
    ) -> Result<usize, AssetError> {
        let (role, file) = (
            format!("{}{role}", self.prefix),
            format!("{}{file}", self.prefix),
        );
        let (role, file) = (role.as_str(), file.as_str());
        if self.files.iter().any(|f| f.role == role || f.path == file) {
            return Err(AssetError::BadData {
                role: role.into(),
                reason: format!("role or file name '{file}' used twice"),
            });
        }
        if !valid_name(file) {
            return Err(AssetError::BadData {
                role: role.into(),
                reason: format!("'{file}' is not a plain file name"),
            });
        }
        self.files.push(FileEntry {
            path: file.into(),
            role: role.into(),
            format,
            width,
            height,
            channels,
            record_bytes,
            bytes: 0,
            blake3: String::new(),
        });
        Ok(self.files.len() - 1)
    }

    /// Writes `bytes` as the file of `entry` in the staging folder (nowhere when `staging` is
    /// empty: a [`Self::sizing`] writer); returns its size and hash.
    fn store(staging: &Path, entry: &FileEntry, bytes: &[u8]) -> Result<(u64, String), AssetError> {
        if staging.as_os_str().is_empty() {
            return Ok((bytes.len() as u64, String::new()));
        }
        let path = staging.join(&entry.path);
        std::fs::write(&path, bytes).map_err(io(&path))?;
        Ok((bytes.len() as u64, hash_hex(bytes)))
    }

    #[allow(clippy::too_many_arguments)] // one private sink for the typed adders above
    fn add(
        &mut self,
        role: &str,
        file: &str,
        format: FileFormat,
        dims: (usize, usize),
        channels: Vec<Channel>,
        record_bytes: usize,
        bytes: Vec<u8>,
    ) -> Result<(), AssetError> {
        let i = self.reserve(role, file, format, dims, channels, record_bytes)?;
        let (len, hash) = Self::store(&self.staging, &self.files[i], &bytes)?;
        (self.files[i].bytes, self.files[i].blake3) = (len, hash);
        Ok(())
    }

    /// Encodes and writes every PNG added since the last call, in parallel; fills in their
    /// entries. Errors: the first failing encoding or write, in the order added.
    fn flush(&mut self) -> Result<(), AssetError> {
        use rayon::prelude::*;
        let pending = std::mem::take(&mut self.pending);
        let (staging, files) = (&self.staging, &self.files);
        let done: Vec<Result<(usize, u64, String), AssetError>> = pending
            .into_par_iter()
            .map(|(i, encode)| {
                let entry = &files[i];
                let bytes = encode().map_err(|reason| AssetError::BadData {
                    role: entry.role.clone(),
                    reason,
                })?;
                let (len, hash) = Self::store(staging, entry, &bytes)?;
                Ok((i, len, hash))
            })
            .collect();
        for d in done {
            let (i, len, hash) = d?;
            (self.files[i].bytes, self.files[i].blake3) = (len, hash);
        }
        Ok(())
    }

    /// Adds a PNG of `image.channels` (1–4) channels, 8 bits (`u8` codes) or 16 bits (`u16`).
    /// Errors here: sizes, channels, names; the encoding and the write happen at
    /// [`Self::commit`], in parallel with the other PNGs. Cost now: a copy of the codes.
    pub fn png<T: PngCode + Send + Sync + 'static>(
        &mut self,
        role: &str,
        file: &str,
        image: &CodeImage<T>,
        channels: Vec<Channel>,
    ) -> Result<(), AssetError> {
        check_image(role, image, &channels)?;
        let dims = (image.width, image.height);
        let i = self.reserve(role, file, T::FORMAT, dims, channels, 0)?;
        let image = image.clone();
        self.pending.push((i, Box::new(move || encode_png(&image))));
        Ok(())
    }

    /// Adds an 8-bit PNG (see [`Self::png`]).
    pub fn png8(
        &mut self,
        role: &str,
        file: &str,
        image: &CodeImage<u8>,
        channels: Vec<Channel>,
    ) -> Result<(), AssetError> {
        self.png(role, file, image, channels)
    }

    /// Adds a 16-bit PNG (see [`Self::png`]).
    pub fn png16(
        &mut self,
        role: &str,
        file: &str,
        image: &CodeImage<u16>,
        channels: Vec<Channel>,
    ) -> Result<(), AssetError> {
        self.png(role, file, image, channels)
    }

    /// Adds a 32-bit float RGBA EXR (lossless). Errors: a non-finite value, sizes.
    pub fn exr(
        &mut self,
        role: &str,
        file: &str,
        image: &FloatImage,
        channels: Vec<Channel>,
    ) -> Result<(), AssetError> {
        let bad = |reason: String| AssetError::BadData {
            role: role.into(),
            reason,
        };
        if image.width == 0 || image.height == 0 || image.data.len() != image.width * image.height {
            return Err(bad(format!(
                "{}×{} image with {} pixels",
                image.width,
                image.height,
                image.data.len()
            )));
        }
        if channels.is_empty() || channels.len() > 4 {
            return Err(bad(format!("{} channels listed", channels.len())));
        }
        if image.data.iter().flatten().any(|v| !v.is_finite()) {
            return Err(bad("a value is not finite".into()));
        }
        // The same image, channels and defaults as the `image` crate's encoder writes, but its
        // blocks compressed and written one after another, so the bytes are the same on every
        // run (the parallel writer stores them in completion order).
        let (width, data) = (image.width, &image.data);
        let channels_of = |p: exr::math::Vec2<usize>| {
            let [r, g, b, a] = data[p.y() * width + p.x()];
            (r, g, b, a)
        };
        let mut out = Cursor::new(Vec::new());
        exr::image::Image::from_channels(
            (image.width, image.height),
            exr::image::SpecificChannels::rgba(channels_of),
        )
        .write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| bad(e.to_string()))?;
        self.add(
            role,
            file,
            FileFormat::Exr32,
            (image.width, image.height),
            channels,
            0,
            out.into_inner(),
        )
    }

    /// Adds `count` little-endian records of `record_bytes` bytes each (`bytes.len()` must be
    /// `count · record_bytes`); `fields` name the record's fields for the description.
    pub fn bin(
        &mut self,
        role: &str,
        file: &str,
        record_bytes: usize,
        bytes: Vec<u8>,
        fields: Vec<Channel>,
    ) -> Result<(), AssetError> {
        if record_bytes == 0 || !bytes.len().is_multiple_of(record_bytes) {
            return Err(AssetError::BadData {
                role: role.into(),
                reason: format!(
                    "{} bytes is not a whole number of {record_bytes}-byte records",
                    bytes.len()
                ),
            });
        }
        let count = bytes.len() / record_bytes;
        self.add(
            role,
            file,
            FileFormat::Bin,
            (count, 1),
            fields,
            record_bytes,
            bytes,
        )
    }

    /// Adds an image file already encoded (`bytes`, `size` texels): a PNG (`png8` or `png16`)
    /// or a JPEG (`jpeg8`), for files another encoder made or a source held (the textures of
    /// `.glb` files). Errors: another format, or bytes without that format's signature.
    pub fn encoded_image(
        &mut self,
        role: &str,
        file: &str,
        format: FileFormat,
        size: (usize, usize),
        bytes: Vec<u8>,
        channels: Vec<Channel>,
    ) -> Result<(), AssetError> {
        let signature: &[u8] = match format {
            FileFormat::Png8 | FileFormat::Png16 => b"\x89PNG",
            FileFormat::Jpeg8 => b"\xFF\xD8\xFF",
            _ => {
                return Err(AssetError::BadData {
                    role: role.into(),
                    reason: format!("{format:?} is not an encoded image format"),
                });
            }
        };
        if !bytes.starts_with(signature) {
            return Err(AssetError::BadData {
                role: role.into(),
                reason: format!("not a {format:?} file (no signature)"),
            });
        }
        self.add(role, file, format, size, channels, 0, bytes)
    }

    /// Adds a glTF 2.0 binary file (`.glb`) holding a mesh of `triangles` triangles; its
    /// channels name what the file holds (for the description).
    pub fn glb(
        &mut self,
        role: &str,
        file: &str,
        triangles: usize,
        bytes: Vec<u8>,
        channels: Vec<Channel>,
    ) -> Result<(), AssetError> {
        if !bytes.starts_with(b"glTF") {
            return Err(AssetError::BadData {
                role: role.into(),
                reason: "not a glTF binary file (no 'glTF' magic)".into(),
            });
        }
        self.add(
            role,
            file,
            FileFormat::Glb,
            (triangles, 1),
            channels,
            0,
            bytes,
        )
    }

    /// Writes `asset.json` and renames the folder into place (an earlier folder of the same
    /// name is moved aside first and removed after). Returns the description written.
    pub fn commit(
        mut self,
        representation: &str,
        asset: &str,
        cache_key: &str,
        conventions: Conventions,
        metadata: serde_json::Value,
        report: serde_json::Value,
    ) -> Result<AssetDescription, AssetError> {
        if self.dry {
            return Err(AssetError::BadData {
                role: DESCRIPTION_FILE.into(),
                reason: "a sizing writer cannot commit".into(),
            });
        }
        self.flush()?;
        let desc = AssetDescription {
            format_version: [FORMAT_MAJOR, FORMAT_MINOR],
            representation: representation.into(),
            asset: asset.into(),
            tool_version: env!("CARGO_PKG_VERSION").into(),
            cache_key: cache_key.into(),
            conventions,
            metadata,
            report,
            files: std::mem::take(&mut self.files),
            description_blake3: None,
        };
        let bad = |e: serde_json::Error| AssetError::BadData {
            role: DESCRIPTION_FILE.into(),
            reason: e.to_string(),
        };
        let json = desc.sealed_json().map_err(bad)?;
        let path = self.staging.join(DESCRIPTION_FILE);
        std::fs::write(&path, json).map_err(io(&path))?;
        // No folder lands once the process is interrupted; one being renamed when the interrupt
        // comes lands whole before `stop_commits` returns.
        let stopped = COMMITS
            .read()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if *stopped {
            return Err(AssetError::Interrupted {
                path: self.target.clone(),
            });
        }
        // Checked again at the last moment: what is replaced below must still be altrep's.
        let name = |p: &Path| p.file_name().map(|n| n.to_string_lossy().into_owned());
        if let Some(parent) = self.target.parent() {
            if let (Some(out), Some(a), Some(r)) =
                (parent.parent(), name(parent), name(&self.target))
            {
                check_owned(out, &a, &r)?;
            }
            std::fs::create_dir_all(parent).map_err(io(parent))?;
        }
        replace_dir(&self.staging, &self.target)?;
        self.committed = true;
        Ok(desc)
    }
}

impl Drop for AssetWriter {
    fn drop(&mut self) {
        if !self.committed && !self.dry {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

/// Whether this process stopped committing asset folders ([`stop_commits`]); commits read it.
static COMMITS: std::sync::RwLock<bool> = std::sync::RwLock::new(false);

/// Stops every [`AssetWriter::commit`] of this process from renaming a folder into place, for an
/// interrupt handler: when it returns, a commit in progress has finished and none will follow
/// (they fail with [`AssetError::Interrupted`]), so the folders present are exactly what the run
/// finished. Cost: waits for a commit in progress (one rename).
pub fn stop_commits() {
    *COMMITS
        .write()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = true;
}

/// Renames folder `from` to `to`, moving an existing `to` aside first (into `from`'s parent)
/// and removing it after. A crash between the two renames leaves no folder at `to` (the next
/// run rebuilds it) and never a mixture of old and new files.
pub fn replace_dir(from: &Path, to: &Path) -> Result<(), AssetError> {
    if to.exists() {
        let parent = from.parent().unwrap_or(from);
        let aside = parent.join(format!(
            "{}.old",
            from.file_name()
                .map(|n| n.to_string_lossy())
                .unwrap_or_default()
        ));
        std::fs::rename(to, &aside).map_err(io(to))?;
        std::fs::rename(from, to).map_err(io(to))?;
        std::fs::remove_dir_all(&aside).map_err(io(&aside))?;
    } else {
        std::fs::rename(from, to).map_err(io(to))?;
    }
    Ok(())
}

/// Checks that writing representation `repr` of asset `asset` into `out` touches only what altrep
/// wrote: `out/asset` is absent or a real folder (not a symbolic link), and `out/asset/repr` is
/// absent or a real folder holding an `asset.json` (itself not a link) that parses as altrep's
/// asset description. Anything else is [`AssetError::NotOurs`] naming the path, and is left as it
/// is. Called before any work and again just before a folder is replaced. Cost: at most three
/// `lstat`s and one read of `asset.json`.
pub fn check_owned(out: &Path, asset: &str, repr: &str) -> Result<(), AssetError> {
    let not_ours = |path: &Path, reason: &str| AssetError::NotOurs {
        path: path.to_path_buf(),
        reason: reason.into(),
    };
    let kind = |path: &Path| match std::fs::symlink_metadata(path) {
        Ok(m) => Ok(Some(m.file_type())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(io(path)(e)),
    };
    let target = out.join(asset).join(repr);
    for folder in [out.join(asset), target.clone()] {
        match kind(&folder)? {
            None => return Ok(()),
            Some(t) if t.is_symlink() => {
                return Err(not_ours(
                    &folder,
                    "is a symbolic link, which altrep does not follow",
                ));
            }
            Some(t) if !t.is_dir() => {
                return Err(not_ours(&folder, "is a file, not an asset folder"));
            }
            Some(_) => {}
        }
    }
    let description = target.join(DESCRIPTION_FILE);
    match kind(&description)? {
        None => {
            return Err(not_ours(
                &target,
                "exists and holds no asset.json: it is not an asset altrep wrote",
            ));
        }
        Some(t) if !t.is_file() => {
            return Err(not_ours(
                &description,
                "is not a plain file (a link or a folder): the folder is not an asset altrep wrote",
            ));
        }
        Some(_) => {}
    }
    let bytes = std::fs::read(&description).map_err(io(&description))?;
    if serde_json::from_slice::<AssetDescription>(&bytes).is_err() {
        return Err(not_ours(
            &description,
            "is not an asset description altrep wrote (docs/asset-format.md)",
        ));
    }
    Ok(())
}

/// Whether `name` is a plain file or folder name: 1–128 ASCII letters, digits, `-`, `_`, `.`,
/// not starting with `.`.
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('.')
        && name.len() <= 128
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
}

fn check_image<T>(
    role: &str,
    image: &CodeImage<T>,
    channels: &[Channel],
) -> Result<(), AssetError> {
    let bad = |reason: String| AssetError::BadData {
        role: role.into(),
        reason,
    };
    if image.width == 0 || image.height == 0 {
        return Err(bad(format!("{}×{} image", image.width, image.height)));
    }
    if !(1..=4).contains(&image.channels) || channels.len() != image.channels {
        return Err(bad(format!(
            "{} image channels, {} described",
            image.channels,
            channels.len()
        )));
    }
    if image.data.len() != image.width * image.height * image.channels {
        return Err(bad(format!("{} codes for the size", image.data.len())));
    }
    Ok(())
}

/// A code type a PNG can store: `u8` or `u16`.
pub trait PngCode: Copy {
    /// The file format of this depth.
    const FORMAT: FileFormat;
    /// The PNG colour type of `channels` channels of this depth.
    fn color(channels: usize) -> Option<image::ExtendedColorType>;
    /// The codes as native-endian bytes (what `image`'s encoders take).
    fn to_ne_bytes(data: &[Self]) -> Vec<u8>;
}

impl PngCode for u8 {
    const FORMAT: FileFormat = FileFormat::Png8;
    fn color(channels: usize) -> Option<image::ExtendedColorType> {
        use image::ExtendedColorType as C;
        [C::L8, C::La8, C::Rgb8, C::Rgba8]
            .get(channels.checked_sub(1)?)
            .copied()
    }
    fn to_ne_bytes(data: &[Self]) -> Vec<u8> {
        data.to_vec()
    }
}

impl PngCode for u16 {
    const FORMAT: FileFormat = FileFormat::Png16;
    fn color(channels: usize) -> Option<image::ExtendedColorType> {
        use image::ExtendedColorType as C;
        [C::L16, C::La16, C::Rgb16, C::Rgba16]
            .get(channels.checked_sub(1)?)
            .copied()
    }
    fn to_ne_bytes(data: &[Self]) -> Vec<u8> {
        data.iter().flat_map(|v| v.to_ne_bytes()).collect()
    }
}

/// Encodes codes of `u8` or `u16` as a PNG of 1–4 channels.
pub(crate) fn encode_png<T: PngCode>(image: &CodeImage<T>) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let color = T::color(image.channels).ok_or_else(|| format!("{} channels", image.channels))?;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(
            &T::to_ne_bytes(&image.data),
            image.width as u32,
            image.height as u32,
            color,
        )
        .map_err(|e| e.to_string())?;
    Ok(out)
}
