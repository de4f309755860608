//! The memory plan: before any work, the peak memory and the output bytes of every
//! representation of every asset are estimated ([`Representation::estimate`], no ray cast, no
//! mesh loaded), summed per asset with its source, and a run whose estimate exceeds its limit
//! ([`RunOptions::max_memory`], `--max-memory`) is refused with the estimate and what to change.
//!
//! The run's peak is the sum of the peaks of the assets that can run at once: the largest
//! `concurrency` assets, `concurrency` being the rayon thread count (1 under `--profile`, which
//! runs assets one at a time). An asset's peak is its source plus all its representations (they
//! build concurrently).

use std::path::Path;

use serde::Serialize;

use super::manifest::{AssetSpec, Manifest, SourceSpec};
use super::run::{RunOptions, effective_needs};
use crate::representation::registry::for_each_representation;
use crate::representation::{Estimate, InputSize, PipelineError, Representation};

/// The estimates of one asset.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AssetEstimate {
    /// The asset.
    pub asset: String,
    /// Its source in memory (bytes): a mesh with its BVH and decoded textures, or a texture.
    pub source_bytes: u64,
    /// Each wanted representation's estimate, in the registry's order.
    pub representations: Vec<(String, Estimate)>,
}

impl AssetEstimate {
    /// Peak memory of the asset (bytes): its source and every representation at once.
    pub fn peak_bytes(&self) -> u64 {
        self.representations
            .iter()
            .fold(self.source_bytes, |a, (_, e)| {
                a.saturating_add(e.peak_bytes)
            })
    }
}

/// What a run is expected to cost, before any work.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MemoryPlan {
    /// Per asset of this shard, in manifest order.
    pub assets: Vec<AssetEstimate>,
    /// How many assets may run at once.
    pub concurrency: usize,
    /// The run's estimated peak memory (bytes).
    pub peak_bytes: u64,
    /// The run's estimated output (bytes, at most).
    pub output_bytes: u64,
    /// The limit the run was checked against (bytes), if any.
    pub limit: Option<u64>,
}

impl MemoryPlan {
    /// The representation with the largest estimated peak, as `ASSET/REPR`.
    pub fn largest(&self) -> Option<(String, u64)> {
        self.assets
            .iter()
            .flat_map(|a| {
                a.representations
                    .iter()
                    .map(move |(r, e)| (format!("{}/{r}", a.asset), e.peak_bytes))
            })
            .max_by_key(|(_, b)| *b)
    }

    /// The plan as lines of text (one per representation, then the run).
    pub fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        for a in &self.assets {
            if a.source_bytes > 0 {
                out.push(format!("{}/source: {}", a.asset, bytes(a.source_bytes)));
            }
            for (r, e) in &a.representations {
                out.push(format!(
                    "{}/{r}: peak {}, files at most {}",
                    a.asset,
                    bytes(e.peak_bytes),
                    bytes(e.output_bytes)
                ));
            }
        }
        out.push(format!(
            "run: peak {} ({} asset(s) at once), files at most {}{}",
            bytes(self.peak_bytes),
            self.concurrency,
            bytes(self.output_bytes),
            self.limit
                .map_or(String::new(), |l| format!("; limit {}", bytes(l)))
        ));
        out
    }

    /// Errors when the estimate exceeds the limit: [`PipelineError::Memory`] with the estimate,
    /// the limit, the largest representation and what to change.
    pub fn check(&self) -> Result<(), PipelineError> {
        match self.limit {
            Some(limit) if self.peak_bytes > limit => Err(PipelineError::Memory {
                estimate: bytes(self.peak_bytes),
                limit: bytes(limit),
                largest: self
                    .largest()
                    .map_or_else(String::new, |(n, b)| format!("{n} ({})", bytes(b))),
            }),
            _ => Ok(()),
        }
    }
}

/// `n` bytes in binary units (`1.5 GiB`).
pub fn bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// Parses a memory size: a number with an optional unit `B`, `K`/`KB`/`KiB`, `M`/`MB`/`MiB`,
/// `G`/`GB`/`GiB`, `T`/`TB`/`TiB` (all binary: `2G` = `2GiB` = 2³¹ bytes), case-insensitive,
/// spaces allowed (`1.5 GiB`). Errors name the text.
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("'{text}' is not a size (for example 2GiB, 512M)"))?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        _ => return Err(format!("'{text}': unknown unit (B, KiB, MiB, GiB, TiB)")),
    };
    let b = value * (1u64 << shift) as f64;
    if !(b.is_finite() && b >= 1.0 && b < u64::MAX as f64) {
        return Err(format!("'{text}' is not a usable size"));
    }
    Ok(b as u64)
}

/// The default limit: three quarters of the memory the system reports available
/// (`MemAvailable` of `/proc/meminfo`), or none where it says nothing.
pub fn default_max_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024) / 4 * 3)
}

/// What is known of an asset's source before loading it, and its memory (bytes): a mesh by a
/// coarse rule on its file sizes (16× an OBJ, 20× a GLB, 20× a `.gltf` and the files beside it:
/// triangles, BVH and decoded textures), a texture by its header.
fn source_size(spec: &AssetSpec) -> Result<(InputSize, u64), PipelineError> {
    let len = |p: &Path| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    Ok(match &spec.source {
        SourceSpec::Shape(_) => (InputSize::default(), 0),
        SourceSpec::Mesh { path, .. } => {
            let ext = path
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase())
                .unwrap_or_default();
            let bytes = match ext.as_str() {
                "obj" => 16 * len(path),
                "gltf" => {
                    let beside: u64 = path
                        .parent()
                        .and_then(|d| std::fs::read_dir(d).ok())
                        .map(|d| {
                            d.filter_map(Result::ok)
                                .filter(|e| e.path() != *path)
                                .map(|e| len(&e.path()))
                                .sum()
                        })
                        .unwrap_or(0);
                    20 * (len(path) + beside)
                }
                _ => 20 * len(path),
            };
            (
                InputSize {
                    mesh: Some(bytes),
                    ..InputSize::default()
                },
                bytes,
            )
        }
        SourceSpec::Texture(path) => {
            let texture_error = |e: &dyn std::fmt::Display| PipelineError::TextureFile {
                path: path.clone(),
                reason: e.to_string(),
            };
            let reader = image::ImageReader::open(path)
                .map_err(|e| texture_error(&e))?
                .with_guessed_format()
                .map_err(|e| texture_error(&e))?;
            let decoder = reader.into_decoder().map_err(|e| texture_error(&e))?;
            let (w, h) = image::ImageDecoder::dimensions(&decoder);
            let c = image::ImageDecoder::color_type(&decoder).channel_count() as usize;
            let (w, h) = (w as usize, h as usize);
            (
                InputSize {
                    texture: Some((w, h, c)),
                    ..InputSize::default()
                },
                (w * h * c * 4) as u64,
            )
        }
        SourceSpec::TestTexture(t) => (
            InputSize {
                texture: Some((t.size, t.size, 1)),
                ..InputSize::default()
            },
            (t.size * t.size * 4) as u64,
        ),
        // The tile's premultiplied RGBA f32 voxels.
        SourceSpec::Tile(t) => (
            InputSize {
                tile: Some(t.size),
                ..InputSize::default()
            },
            (t.size.pow(3) * 16) as u64,
        ),
    })
}

/// The memory plan of a run of `manifest` with `options` (its shard, `--everything`, the
/// limit). Errors: a texture whose header cannot be read. Cost: one header read per texture.
pub fn plan_memory(manifest: &Manifest, options: &RunOptions) -> Result<MemoryPlan, PipelineError> {
    let mut assets = Vec::new();
    for spec in manifest
        .assets
        .iter()
        .filter(|a| options.shard.is_none_or(|s| s.owns(&a.name)))
    {
        let (input, source_bytes) = source_size(spec)?;
        let mut representations = Vec::new();
        macro_rules! estimates {
            ($(($key:ident, $variant:ident, $repr:ty, $doc:literal)),* $(,)?) => {$(
                if let Some(s) = &spec.$key {
                    let needs = effective_needs(spec, options.everything, <$repr>::RELIGHTS);
                    representations.push((
                        <$repr>::NAME.to_string(),
                        <$repr>::estimate(s, &needs, &input),
                    ));
                }
            )*};
        }
        for_each_representation!(estimates);
        assets.push(AssetEstimate {
            asset: spec.name.clone(),
            source_bytes,
            representations,
        });
    }
    let concurrency = if options.profile {
        1
    } else {
        rayon::current_num_threads().clamp(1, assets.len().max(1))
    };
    let mut peaks: Vec<u64> = assets.iter().map(AssetEstimate::peak_bytes).collect();
    peaks.sort_unstable_by(|a, b| b.cmp(a));
    let peak_bytes = peaks
        .iter()
        .take(concurrency)
        .fold(0u64, |a, &b| a.saturating_add(b));
    let output_bytes = assets
        .iter()
        .flat_map(|a| &a.representations)
        .fold(0u64, |a, (_, e)| a.saturating_add(e.output_bytes));
    Ok(MemoryPlan {
        assets,
        concurrency,
        peak_bytes,
        output_bytes,
        limit: options.max_memory,
    })
}
