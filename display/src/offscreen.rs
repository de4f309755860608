//! One headless draw: a pipeline of the impostor kind (full-screen quad of 6 vertices, one
//! bind group, `Rgba32Float` colour and `Depth32Float` depth) into an offscreen target, then the
//! colour, the depth and a per-fragment steps buffer read back. Shared by the representations
//! drawn after the parallax impostor.

use std::time::Instant;

use altrep_data_gen::RgbaImage;

use crate::{DisplayError, Gpu, read_buffer};

/// Builds the render pipeline of `source` (entry points `vs_main`, `fs_main`), with the
/// layout inferred from the shader. Errors: the device rejects the shader or the pipeline.
pub(crate) fn pipeline(
    gpu: &Gpu,
    label: &str,
    source: String,
) -> Result<wgpu::RenderPipeline, DisplayError> {
    let dev = &gpu.device;
    let scope = dev.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
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
            targets: &[Some(wgpu::ColorTargetState {
                format: wgpu::TextureFormat::Rgba32Float,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    });
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(DisplayError::Gpu(e.to_string()));
    }
    Ok(pipeline)
}

/// What one draw read back.
pub(crate) struct Drawn {
    pub image: RgbaImage,
    pub depth: Vec<f32>,
    /// The steps buffer, one `u32` per element.
    pub steps: Vec<u32>,
    pub millis: f64,
}

/// Draws `pipeline` with `buffers` bound at bindings `0..n` of group 0 (the last one the
/// read-write steps buffer of `steps_words` `u32`s, cleared before the draw) into a
/// `width × height` target, and reads everything back. `t0` is when the caller started the
/// frame (host-side tables count in the frame time).
pub(crate) fn draw(
    gpu: &Gpu,
    pipeline: &wgpu::RenderPipeline,
    buffers: &[&wgpu::Buffer],
    steps: &wgpu::Buffer,
    steps_words: usize,
    (width, height): (usize, usize),
    t0: Instant,
) -> Result<Drawn, DisplayError> {
    let dev = &gpu.device;
    let layout = pipeline.get_bind_group_layout(0);
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .chain(std::iter::once(&steps))
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    let scope = dev.push_error_scope(wgpu::ErrorFilter::Validation);
    let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("impostor"),
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
    let color = target(wgpu::TextureFormat::Rgba32Float, "colour");
    let depth = target(wgpu::TextureFormat::Depth32Float, "depth");
    let cview = color.create_view(&Default::default());
    let dview = depth.create_view(&Default::default());
    let pad = |b: usize| b.div_ceil(256) * 256;
    let (crow, drow) = (width * 16, width * 4);
    let readback = |bytes: usize, label| {
        dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        })
    };
    let steps_bytes = steps_words * 4;
    let cbuf = readback(pad(crow) * height, "colour read-back");
    let dbuf = readback(pad(drow) * height, "depth read-back");
    let sbuf = readback(steps_bytes, "steps read-back");
    let mut enc = dev.create_command_encoder(&Default::default());
    enc.clear_buffer(steps, 0, None);
    {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("impostor"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &cview,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &dview,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..6, 0..1);
    }
    let copy = |enc: &mut wgpu::CommandEncoder,
                tex: &wgpu::Texture,
                aspect: wgpu::TextureAspect,
                buf: &wgpu::Buffer,
                row: usize| {
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: tex,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect,
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
    copy(&mut enc, &color, wgpu::TextureAspect::All, &cbuf, crow);
    copy(
        &mut enc,
        &depth,
        wgpu::TextureAspect::DepthOnly,
        &dbuf,
        drow,
    );
    enc.copy_buffer_to_buffer(steps, 0, &sbuf, 0, steps_bytes as u64);
    gpu.queue.submit([enc.finish()]);
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(DisplayError::Gpu(e.to_string()));
    }
    let cbytes = read_buffer(gpu, &cbuf, crow, pad(crow), height)?;
    let dbytes = read_buffer(gpu, &dbuf, drow, pad(drow), height)?;
    let sbytes = read_buffer(gpu, &sbuf, steps_bytes, steps_bytes, 1)?;
    let millis = t0.elapsed().as_secs_f64() * 1e3;
    let words = |b: &[u8]| -> Vec<[u8; 4]> {
        b.chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect()
    };
    let floats: Vec<f32> = words(&cbytes).into_iter().map(f32::from_le_bytes).collect();
    Ok(Drawn {
        image: RgbaImage {
            width,
            height,
            pixels: floats
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect(),
        },
        depth: words(&dbytes).into_iter().map(f32::from_le_bytes).collect(),
        steps: words(&sbytes).into_iter().map(u32::from_le_bytes).collect(),
        millis,
    })
}
