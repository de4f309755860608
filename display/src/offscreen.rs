//! One headless draw, shared by every display: a full-screen quad of 6 vertices drawn by a
//! pipeline of a [`Shader`] with one bind group of storage buffers (the last the read-write
//! per-fragment steps buffer) into an offscreen target, then the colour, the depth and the steps
//! read back.
//!
//! The targets work on every backend wgpu offers (Vulkan, Metal, DX12, GL): the colour goes to
//! an `Rgba32Uint` target holding the shader's `f32` bits (GL cannot render to `Rgba32Float`),
//! and the depth, besides the `Depth32Float` attachment of the depth test, to an `R32Uint` target
//! holding its bits (GL cannot copy a depth texture to a buffer). The read-back is therefore the
//! shader's exact `f32` output on every adapter.
//!
//! Pipelines are built once per device and (shader, precision) and kept in the [`Gpu`]
//! ([`pipeline`]): building one costs seconds on a software adapter, drawing milliseconds.

use std::sync::Arc;
use std::time::Instant;

use altrep_data_gen::RgbaImage;

use crate::shader::{Precision, Shader, compose};
use crate::{DisplayError, Gpu, read_buffer};

/// The colour target: the `f32` bits of premultiplied linear RGBA.
pub(crate) const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;
/// The depth's bits, beside the depth attachment.
pub(crate) const DEPTH_BITS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// The depth attachment of the depth test.
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A built pipeline and whether it writes depth.
#[derive(Clone, Debug)]
pub(crate) struct Pipeline {
    pub pipeline: wgpu::RenderPipeline,
    pub depth: bool,
}

/// The pipeline of `shader` in `precision` on `gpu`'s device: taken from the device's cache, or
/// built (entry points `vs_main`, `fs_main`, layout inferred from the shader) and cached.
/// Errors: [`Precision::F64`] on a device without `SHADER_F64`; the device rejects the shader or
/// the pipeline ([`DisplayError::Gpu`]).
pub(crate) fn pipeline(
    gpu: &Gpu,
    shader: Shader,
    precision: Precision,
) -> Result<Arc<Pipeline>, DisplayError> {
    if precision == Precision::F64 && !gpu.has_f64 {
        return Err(crate::invalid(
            "precision",
            "f64",
            "needs an adapter with SHADER_F64",
        ));
    }
    let mut cache = gpu
        .pipelines
        .lock()
        .map_err(|_| DisplayError::Gpu("the pipeline cache was poisoned by a panic".into()))?;
    if let Some(p) = cache.get(&(shader, precision)) {
        return Ok(p.clone());
    }
    let built = {
        let _gl = gpu.exclusive();
        Arc::new(build(gpu, shader, precision)?)
    };
    cache.insert((shader, precision), built.clone());
    Ok(built)
}

fn build(gpu: &Gpu, shader: Shader, precision: Precision) -> Result<Pipeline, DisplayError> {
    let dev = &gpu.device;
    let label = shader.label(precision);
    let depth = shader.writes_depth();
    let scope = dev.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(&label),
        source: wgpu::ShaderSource::Wgsl(compose(shader, precision).into()),
    });
    let colour = Some(wgpu::ColorTargetState {
        format: COLOUR_FORMAT,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    });
    let depth_bits = Some(wgpu::ColorTargetState {
        format: DEPTH_BITS_FORMAT,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    });
    let targets = if depth {
        vec![colour, depth_bits]
    } else {
        vec![colour]
    };
    let pipeline = dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(&label),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: depth.then_some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::LessEqual),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &targets,
        }),
        multiview_mask: None,
        cache: None,
    });
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(DisplayError::Gpu(e.to_string()));
    }
    Ok(Pipeline { pipeline, depth })
}

/// A storage buffer initialised with `bytes` (read-only in the shaders).
pub(crate) fn storage(gpu: &Gpu, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    let _gl = gpu.exclusive();
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytes,
            usage: wgpu::BufferUsages::STORAGE,
        })
}

/// What one draw read back.
pub(crate) struct Drawn {
    /// Premultiplied linear RGBA, row 0 at the top; transparent where nothing was drawn.
    pub image: RgbaImage,
    /// Per fragment (row-major) the depth written; 1 where nothing was drawn; empty for a
    /// pipeline without depth.
    pub depth: Vec<f32>,
    /// The steps buffer, one `u32` per element.
    pub steps: Vec<u32>,
    /// Wall time from `t0` to the end of the read-back (milliseconds).
    pub millis: f64,
}

/// Draws `pipeline` with `buffers` bound at bindings `0..n` of group 0 and a read-write steps
/// buffer of `steps_words` `u32`s (cleared before the draw) at binding `n`, into a
/// `width × height` target, and reads everything back. `t0` is when the caller started the
/// frame (host-side tables count in the frame time). Cost: one draw, two or three copies and
/// their mapping; GPU memory `(16 + 8)·width·height` bytes for the targets.
pub(crate) fn draw(
    gpu: &Gpu,
    pipeline: &Pipeline,
    buffers: &[&wgpu::Buffer],
    steps_words: usize,
    (width, height): (usize, usize),
    t0: Instant,
) -> Result<Drawn, DisplayError> {
    let _gl = gpu.exclusive();
    let dev = &gpu.device;
    let steps_bytes = (steps_words * 4) as u64;
    let steps = dev.create_buffer(&wgpu::BufferDescriptor {
        label: Some("steps"),
        size: steps_bytes,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let layout = pipeline.pipeline.get_bind_group_layout(0);
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .copied()
        .chain(std::iter::once(&steps))
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    let scope = dev.push_error_scope(wgpu::ErrorFilter::Validation);
    let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("display"),
        layout: &layout,
        entries: &entries,
    });
    let size = wgpu::Extent3d {
        width: width as u32,
        height: height as u32,
        depth_or_array_layers: 1,
    };
    let target = |format, label| {
        dev.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        })
    };
    let colour = target(COLOUR_FORMAT, "colour");
    let depth = pipeline.depth.then(|| {
        (
            target(DEPTH_BITS_FORMAT, "depth bits"),
            target(DEPTH_FORMAT, "depth"),
        )
    });
    let cview = colour.create_view(&Default::default());
    let dviews = depth.as_ref().map(|(bits, att)| {
        (
            bits.create_view(&Default::default()),
            att.create_view(&Default::default()),
        )
    });
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as usize;
    let pad = |b: usize| b.div_ceil(align) * align;
    let (crow, drow) = (width * 16, width * 4);
    let readback = |bytes: usize, label| {
        dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes.max(4) as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        })
    };
    let cbuf = readback(pad(crow) * height, "colour read-back");
    let dbuf = readback(pad(drow) * height, "depth read-back");
    let sbuf = readback(steps_bytes as usize, "steps read-back");
    let mut enc = dev.create_command_encoder(&Default::default());
    enc.clear_buffer(&steps, 0, None);
    {
        let clear = |c: f64| wgpu::Operations {
            load: wgpu::LoadOp::Clear(wgpu::Color {
                r: c,
                g: c,
                b: c,
                a: c,
            }),
            store: wgpu::StoreOp::Store,
        };
        let mut attachments = vec![Some(wgpu::RenderPassColorAttachment {
            view: &cview,
            depth_slice: None,
            resolve_target: None,
            // 0 is the bits of 0.0: transparent.
            ops: clear(0.0),
        })];
        if let Some((bits, _)) = &dviews {
            attachments.push(Some(wgpu::RenderPassColorAttachment {
                view: bits,
                depth_slice: None,
                resolve_target: None,
                // The bits of the cleared depth, 1.0.
                ops: clear(f64::from(1.0f32.to_bits())),
            }));
        }
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("display"),
            color_attachments: &attachments,
            depth_stencil_attachment: dviews.as_ref().map(|(_, att)| {
                wgpu::RenderPassDepthStencilAttachment {
                    view: att,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..6, 0..1);
    }
    let copy = |enc: &mut wgpu::CommandEncoder, tex: &wgpu::Texture, buf: &wgpu::Buffer, row| {
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: tex,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: buf,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(pad(row) as u32),
                    rows_per_image: Some(height as u32),
                },
            },
            size,
        );
    };
    copy(&mut enc, &colour, &cbuf, crow);
    if let Some((bits, _)) = &depth {
        copy(&mut enc, bits, &dbuf, drow);
    }
    enc.copy_buffer_to_buffer(&steps, 0, &sbuf, 0, steps_bytes);
    gpu.queue.submit([enc.finish()]);
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(DisplayError::Gpu(e.to_string()));
    }
    let cbytes = read_buffer(gpu, &cbuf, crow, pad(crow), height)?;
    let dbytes = match depth {
        Some(_) => read_buffer(gpu, &dbuf, drow, pad(drow), height)?,
        None => Vec::new(),
    };
    let sbytes = read_buffer(gpu, &sbuf, steps_bytes as usize, steps_bytes as usize, 1)?;
    let millis = t0.elapsed().as_secs_f64() * 1e3;
    let floats = f32s(&cbytes);
    Ok(Drawn {
        image: RgbaImage {
            width,
            height,
            pixels: floats
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect(),
        },
        depth: f32s(&dbytes),
        steps: u32s(&sbytes),
        millis,
    })
}

/// Little-endian `f32`s of `bytes`.
fn f32s(bytes: &[u8]) -> Vec<f32> {
    u32s(bytes).into_iter().map(f32::from_bits).collect()
}

/// Little-endian `u32`s of `bytes`.
fn u32s(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}
