//! # altrep-display: the thin wgpu display (docs/design.md §11)
//!
//! Draws what the precompute pipeline wrote, on the GPU, headless by default: an asset folder is
//! loaded **only** through the library's loader ([`load`]: `AssetReader::open` then the
//! representation's `read`; [`open`] for any folder), uploaded, drawn into an offscreen texture
//! and read back. The module fits nothing and reads no mesh. Each shader is the GPU twin of a CPU
//! renderer of the library and can write its per-fragment march steps to a storage buffer, read
//! back by the tests.
//!
//! Representations drawn: images with parallax ([`parallax::ParallaxDisplay`], the twin of
//! `altrep::parallax::{render, render_bounded}`), cylindrical impostors
//! ([`cylinder::CylinderDisplay`]), texture pyramids ([`pyramid::PyramidDisplay`]), images with parallax from
//! any direction ([`sphere::SphereDisplay`], the twin of `altrep::sphere::render`), slices of
//! an object ([`slices::SlicesDisplay`], the twin of `altrep::slices::render_object`) and the
//! ellipsoid octree ([`octree::OctreeDisplay`], the twin of `Octree::render_view_counted`). A further
//! representation is one more module with its own WGSL file, taking the same [`Gpu`].
//!
//! ## Conventions
//!
//! * Images are `altrep_data_gen::RgbaImage`: premultiplied **linear** RGBA `f32`, row 0 at the
//!   top — the CPU renderers' format, so GPU and CPU images compare directly. The offscreen
//!   targets hold the shader's exact `f32` bits on every backend (an `Rgba32Uint` colour and an
//!   `R32Uint` depth target: no sRGB rounding, and GL cannot render to `Rgba32Float`); PNGs are
//!   written in sRGB by [`RgbaImage::write_png`](altrep_data_gen::RgbaImage::write_png).
//! * Angles and geometry follow `altrep::parallax` (y up, `α` the azimuth, orthographic views).
//! * Depth is written: orthographic, `0` at the front of the march cylinder, `1` at its back.
//! * Adapters: whatever wgpu offers — Vulkan, Metal, DX12 or GL — chosen by wgpu's defaults,
//!   overridable by `WGPU_BACKEND`, `WGPU_ADAPTER_NAME`, `WGPU_POWER_PREF`. The display needs
//!   writable storage buffers in the fragment stage ([`Gpu::headless`] checks, and names what is
//!   missing). On a machine without a GPU, Mesa's lavapipe (`mesa-vulkan-drivers`, Vulkan) or
//!   llvmpipe (GL) are software adapters; timings there are CPU emulation, not GPU time. The
//!   `f64` twins need `SHADER_F64` (lavapipe has it, GL has not).
//! * Pipelines are built once per [`Gpu`] and (shader, precision), then reused by every display
//!   drawn on that device: building costs seconds on a software adapter, drawing milliseconds.

#![warn(missing_docs)]

pub mod check;
pub mod cylinder;
pub mod octree;
mod offscreen;
pub mod parallax;
pub mod pyramid;
pub mod shader;
pub mod slices;
pub mod sphere;

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex};

use altrep::asset::AssetReader;
use altrep::representation::{AnyAsset, Representation};
pub use altrep_data_gen::RgbaImage;
pub use shader::Precision;
pub use wgpu;

/// What went wrong while loading, uploading or drawing.
#[derive(Debug, thiserror::Error)]
pub enum DisplayError {
    /// No adapter could be requested (no GPU and no software driver).
    #[error("no GPU adapter: {0} (install mesa-vulkan-drivers for a software adapter)")]
    NoAdapter(String),
    /// The adapter lacks something every display needs.
    #[error("adapter {adapter} cannot run the display: {missing}")]
    Incapable {
        /// Name, backend and type of the adapter.
        adapter: String,
        /// What it lacks.
        missing: String,
    },
    /// The adapter refused to create a device.
    #[error("device request failed: {0}")]
    Device(String),
    /// The asset folder could not be read by the library's loader.
    #[error("asset {path}: {reason}")]
    Asset {
        /// The folder.
        path: String,
        /// The loader's message.
        reason: String,
    },
    /// A drawing parameter is out of range.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: String,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// A file could not be written.
    #[error("file {path}: {reason}")]
    File {
        /// The file or folder.
        path: String,
        /// The system's message.
        reason: String,
    },
    /// The GPU reported an error (validation, out of memory, mapping).
    #[error("GPU error: {0}")]
    Gpu(String),
}

/// A typed error for a drawing or upload parameter `name` with `value` that fails `reason`.
pub(crate) fn invalid(
    name: &'static str,
    value: impl std::fmt::Display,
    reason: &'static str,
) -> DisplayError {
    DisplayError::InvalidParameter {
        name,
        value: value.to_string(),
        reason,
    }
}

/// Storage buffers the busiest display binds in its fragment stage (six inputs and the steps).
const STORAGE_BUFFERS: u32 = 7;

/// A headless wgpu device and queue, with the display pipelines built on it so far.
pub struct Gpu {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Name, backend and type of the adapter (e.g. `llvmpipe`, Vulkan, Cpu).
    pub info: wgpu::AdapterInfo,
    /// Whether the device has `SHADER_F64` (the exact `f64` twin of the CPU march).
    pub has_f64: bool,
    /// Pipelines built on this device, one per (shader, precision).
    pipelines: Mutex<HashMap<(shader::Shader, Precision), Arc<offscreen::Pipeline>>>,
    /// On GL, held by every use of the device: wgpu's GL backend shares one context between
    /// threads and gives up (a panic) after waiting 6 s for it, which concurrent draws on a
    /// software adapter exceed. Other backends run concurrently.
    serial: Option<Mutex<()>>,
}

impl Gpu {
    /// Requests an adapter without a display and creates a device (with `SHADER_F64` when the
    /// adapter has it). Honours wgpu's environment variables. Cost: 30–100 ms on lavapipe.
    /// Errors: [`DisplayError::NoAdapter`] when none exists, [`DisplayError::Incapable`] when
    /// the adapter cannot write storage buffers from the fragment stage or binds fewer than 7
    /// of them there (WebGL 2 and some GL ES drivers), [`DisplayError::Device`].
    pub fn headless() -> Result<Gpu, DisplayError> {
        pollster::block_on(Self::headless_async())
    }

    async fn headless_async() -> Result<Gpu, DisplayError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::from_env()
                    .unwrap_or(wgpu::PowerPreference::HighPerformance),
                force_fallback_adapter: false,
                compatible_surface: None,
                apply_limit_buckets: false,
            })
            .await
            .map_err(|e| DisplayError::NoAdapter(e.to_string()))?;
        Self::with_adapter_async(&adapter).await
    }

    /// Checks that `adapter` can run the display and creates its device (with `SHADER_F64`
    /// when the adapter has it): for a caller that chose the adapter itself, e.g. one
    /// compatible with a window's surface. Errors as [`Gpu::headless`].
    pub fn with_adapter(adapter: &wgpu::Adapter) -> Result<Gpu, DisplayError> {
        pollster::block_on(Self::with_adapter_async(adapter))
    }

    async fn with_adapter_async(adapter: &wgpu::Adapter) -> Result<Gpu, DisplayError> {
        let describe =
            |i: &wgpu::AdapterInfo| format!("{} {:?} {:?}", i.name, i.backend, i.device_type);
        let limits = adapter.limits();
        let downlevel = adapter.get_downlevel_capabilities();
        let mut missing = Vec::new();
        if !downlevel
            .flags
            .contains(wgpu::DownlevelFlags::FRAGMENT_WRITABLE_STORAGE)
        {
            missing.push("writable storage buffers in the fragment stage".to_string());
        }
        if limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS {
            missing.push(format!(
                "{STORAGE_BUFFERS} storage buffers per stage (it has {})",
                limits.max_storage_buffers_per_shader_stage
            ));
        }
        if !missing.is_empty() {
            return Err(DisplayError::Incapable {
                adapter: describe(&adapter.get_info()),
                missing: missing.join(", "),
            });
        }
        let has_f64 = adapter.features().contains(wgpu::Features::SHADER_F64);
        let required_features = if has_f64 {
            wgpu::Features::SHADER_F64
        } else {
            wgpu::Features::empty()
        };
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("altrep-display"),
                required_features,
                // Seven storage buffers in the fragment stage: above the downlevel defaults.
                required_limits: limits,
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|e| DisplayError::Device(e.to_string()))?;
        Ok(Gpu {
            device,
            queue,
            info: adapter.get_info(),
            has_f64,
            pipelines: Mutex::new(HashMap::new()),
            serial: (adapter.get_info().backend == wgpu::Backend::Gl).then(|| Mutex::new(())),
        })
    }

    /// On GL, a guard that keeps the device to the calling thread (see `serial`); `None`
    /// elsewhere. A panic in another holder does not stop later uses.
    pub(crate) fn exclusive(&self) -> Option<std::sync::MutexGuard<'_, ()>> {
        self.serial
            .as_ref()
            .map(|m| m.lock().unwrap_or_else(std::sync::PoisonError::into_inner))
    }

    /// One line naming the adapter, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) Vulkan Cpu`.
    pub fn describe(&self) -> String {
        format!(
            "{} {:?} {:?}",
            self.info.name, self.info.backend, self.info.device_type
        )
    }
}

/// Loads an asset folder of representation `R` (e.g. `load::<Parallax>("out/truck/parallax")`)
/// through the library's loader: [`AssetReader::open`] checks the description and every file's
/// hash, then [`Representation::read`] decodes the data the display draws. Errors:
/// [`DisplayError::Asset`] naming the folder, with the loader's message (a missing or altered
/// file, another representation's folder, a newer format). Cost: one read of every file.
pub fn load<R: Representation>(dir: &Path) -> Result<R::Data, DisplayError> {
    let reader = AssetReader::open(dir).map_err(|e| asset_error(dir, &e))?;
    R::read(&reader).map_err(|e| asset_error(dir, &e))
}

/// Loads any asset folder, whatever representation its `asset.json` names
/// ([`altrep::representation::open`], the library's one list of representations). Errors and
/// cost as [`load`].
pub fn open(dir: &Path) -> Result<AnyAsset, DisplayError> {
    altrep::representation::open(dir).map_err(|e| asset_error(dir, &e))
}

fn asset_error(dir: &Path, e: &dyn std::fmt::Display) -> DisplayError {
    DisplayError::Asset {
        path: dir.display().to_string(),
        reason: e.to_string(),
    }
}

/// One drawn frame read back from the GPU.
#[derive(Clone, Debug)]
pub struct DrawnFrame {
    /// The image (premultiplied linear RGBA, alpha 1 where drawn, 0 elsewhere).
    pub image: RgbaImage,
    /// Per fragment (row-major), the march steps of the two warped views (0 where a view's
    /// range was empty).
    pub steps: Vec<[u32; 2]>,
    /// Per fragment, the depth written (1 where nothing was drawn).
    pub depth: Vec<f32>,
    /// Wall time of the draw and read-back (milliseconds; on lavapipe this is CPU emulation).
    pub millis: f64,
}

/// Reads a mapped-after-copy buffer back as bytes, rows de-padded.
pub(crate) fn read_buffer(
    gpu: &Gpu,
    buffer: &wgpu::Buffer,
    row_bytes: usize,
    padded: usize,
    rows: usize,
) -> Result<Vec<u8>, DisplayError> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| DisplayError::Gpu(e.to_string()))?;
    rx.recv()
        .map_err(|e| DisplayError::Gpu(e.to_string()))?
        .map_err(|e| DisplayError::Gpu(e.to_string()))?;
    let mut out = Vec::with_capacity(row_bytes * rows);
    {
        let data = slice
            .get_mapped_range()
            .map_err(|e| DisplayError::Gpu(e.to_string()))?;
        for r in 0..rows {
            out.extend_from_slice(&data[r * padded..r * padded + row_bytes]);
        }
    }
    buffer.unmap();
    Ok(out)
}

/// `img` composited over the opaque linear `background`, as 8-bit sRGB, each pixel repeated
/// `scale × scale` times (nearest, so texels stay visible). For PNG and GIF frames.
pub fn to_srgb8(img: &RgbaImage, background: [f32; 3], scale: u32) -> image::RgbaImage {
    let s = scale.max(1);
    let flat = img.over(background);
    image::RgbaImage::from_fn(img.width as u32 * s, img.height as u32 * s, |x, y| {
        let p = flat.get((x / s) as usize, (y / s) as usize);
        let q = |c: f32| (altrep_data_gen::linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8;
        image::Rgba([q(p[0]), q(p[1]), q(p[2]), 255])
    })
}
