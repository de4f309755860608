//! The winit event loop of [`super::run`] (feature `window`).

use std::sync::Arc;

use altrep_display::wgpu;
use altrep_display::{Gpu, RgbaImage, to_srgb8};
use winit::application::ApplicationHandler;
use winit::dpi::{LogicalSize, PhysicalPosition};
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use super::{Orbit, WindowError};

/// The loop itself: the display was checked by the caller.
pub(super) fn run<D>(
    title: &str,
    elevation: bool,
    setup: impl FnOnce(&Gpu) -> Result<D, String>,
    draw: impl FnMut(&Gpu, &D, Orbit) -> Result<RgbaImage, String>,
) -> Result<(), WindowError> {
    let event_loop = EventLoop::new().map_err(|e| WindowError::Window(e.to_string()))?;
    let mut app = App {
        title: title.to_string(),
        elevation,
        setup: Some(setup),
        draw,
        state: None,
        error: None,
        orbit: Orbit {
            azimuth: 0.0,
            elevation: 0.0,
            zoom: 1.0,
        },
        dragging: false,
        cursor: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| WindowError::Window(e.to_string()))?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

struct State<D> {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    gpu: Gpu,
    blit: wgpu::RenderPipeline,
    sampler: wgpu::Sampler,
    scene: D,
}

struct App<D, S, F> {
    title: String,
    elevation: bool,
    setup: Option<S>,
    draw: F,
    state: Option<State<D>>,
    error: Option<WindowError>,
    orbit: Orbit,
    dragging: bool,
    cursor: Option<PhysicalPosition<f64>>,
}

const BLIT: &str = r#"
@group(0) @binding(0) var img: texture_2d<f32>;
@group(0) @binding(1) var smp: sampler;
@group(0) @binding(2) var<uniform> scale: vec4<f32>;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    var c = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    var out: VsOut;
    out.pos = vec4<f32>(c[vi] * scale.xy, 0.0, 1.0);
    out.uv = vec2<f32>(c[vi].x * 0.5 + 0.5, 0.5 - c[vi].y * 0.5);
    return out;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    return textureSample(img, smp, in.uv);
}
"#;

impl<D, S, F> App<D, S, F>
where
    S: FnOnce(&Gpu) -> Result<D, String>,
    F: FnMut(&Gpu, &D, Orbit) -> Result<RgbaImage, String>,
{
    fn start(&mut self, el: &ActiveEventLoop) -> Result<(), WindowError> {
        let attrs = Window::default_attributes()
            .with_title(format!(
                "{} — drag: turn, wheel: zoom, Esc: quit",
                self.title
            ))
            .with_inner_size(LogicalSize::new(768.0, 768.0));
        let window = Arc::new(
            el.create_window(attrs)
                .map_err(|e| WindowError::Window(e.to_string()))?,
        );
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| WindowError::Gpu(e.to_string()))?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
            apply_limit_buckets: false,
        }))
        .map_err(|e| WindowError::Gpu(e.to_string()))?;
        let gpu = Gpu::with_adapter(&adapter).map_err(|e| WindowError::Gpu(e.to_string()))?;
        let device = &gpu.device;
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| {
                WindowError::Gpu("the surface is not supported by the adapter".into())
            })?;
        // An sRGB surface re-encodes the sRGB texture's linear samples.
        let caps = surface.get_capabilities(&adapter);
        if let Some(f) = caps.formats.iter().find(|f| f.is_srgb()) {
            config.format = *f;
        }
        surface.configure(device, &config);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("blit"),
            source: wgpu::ShaderSource::Wgsl(BLIT.into()),
        });
        let blit = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("blit"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(config.format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor::default());
        let setup = self
            .setup
            .take()
            .ok_or_else(|| WindowError::Draw("set up twice".into()))?;
        let scene = setup(&gpu).map_err(WindowError::Draw)?;
        self.state = Some(State {
            window,
            surface,
            config,
            gpu,
            blit,
            sampler,
            scene,
        });
        Ok(())
    }

    fn redraw(&mut self) -> Result<(), WindowError> {
        let Some(st) = &mut self.state else {
            return Ok(());
        };
        let img = (self.draw)(&st.gpu, &st.scene, self.orbit).map_err(WindowError::Draw)?;
        let rgba = to_srgb8(&img, [0.18, 0.2, 0.23], 1);
        let dev = &st.gpu.device;
        let extent = wgpu::Extent3d {
            width: rgba.width(),
            height: rgba.height(),
            depth_or_array_layers: 1,
        };
        let tex = dev.create_texture(&wgpu::TextureDescriptor {
            label: Some("frame"),
            size: extent,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8UnormSrgb,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        st.gpu.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &tex,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            rgba.as_raw(),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * rgba.width()),
                rows_per_image: Some(rgba.height()),
            },
            extent,
        );
        // Fit the image in the window (keeping its aspect), times the zoom.
        let (ww, wh) = (st.config.width as f64, st.config.height as f64);
        let (iw, ih) = (f64::from(rgba.width()), f64::from(rgba.height()));
        let fit = (ww / iw).min(wh / ih) * self.orbit.zoom;
        let scale = [(iw * fit / ww) as f32, (ih * fit / wh) as f32, 0.0, 0.0];
        let ubuf = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("scale"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bytes: Vec<u8> = scale.iter().flat_map(|v| v.to_le_bytes()).collect();
        st.gpu.queue.write_buffer(&ubuf, 0, &bytes);
        let view = tex.create_view(&Default::default());
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blit"),
            layout: &st.blit.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&st.sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: ubuf.as_entire_binding(),
                },
            ],
        });
        let frame = match st.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f)
            | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            other => {
                // Outdated or lost: reconfigure and try on the next redraw.
                st.surface.configure(dev, &st.config);
                st.window.request_redraw();
                let _ = other;
                return Ok(());
            }
        };
        let target = frame.texture.create_view(&Default::default());
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("window"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: 0.18,
                            g: 0.2,
                            b: 0.23,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&st.blit);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..6, 0..1);
        }
        st.gpu.queue.submit([enc.finish()]);
        st.window.pre_present_notify();
        st.gpu.queue.present(frame);
        Ok(())
    }

    fn fail(&mut self, el: &ActiveEventLoop, e: WindowError) {
        self.error.get_or_insert(e);
        el.exit();
    }
}

impl<D, S, F> ApplicationHandler for App<D, S, F>
where
    S: FnOnce(&Gpu) -> Result<D, String>,
    F: FnMut(&Gpu, &D, Orbit) -> Result<RgbaImage, String>,
{
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.state.is_none()
            && let Err(e) = self.start(el)
        {
            self.fail(el, e);
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let redraw = |s: &Option<State<D>>| {
            if let Some(st) = s {
                st.window.request_redraw();
            }
        };
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::KeyboardInput { event, .. }
                if event.state == ElementState::Pressed
                    && event.logical_key == Key::Named(NamedKey::Escape) =>
            {
                el.exit()
            }
            WindowEvent::Resized(size) => {
                if let Some(st) = &mut self.state
                    && size.width > 0
                    && size.height > 0
                {
                    st.config.width = size.width;
                    st.config.height = size.height;
                    st.surface.configure(&st.gpu.device, &st.config);
                    st.window.request_redraw();
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => self.dragging = state == ElementState::Pressed,
            WindowEvent::CursorMoved { position, .. } => {
                if self.dragging
                    && let Some(last) = self.cursor
                {
                    self.orbit.azimuth += 0.01 * (position.x - last.x);
                    if self.elevation {
                        self.orbit.elevation = (self.orbit.elevation
                            + 0.01 * (position.y - last.y))
                            .clamp(-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2);
                    }
                    redraw(&self.state);
                }
                self.cursor = Some(position);
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let notches = match delta {
                    MouseScrollDelta::LineDelta(_, y) => f64::from(y),
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                self.orbit.zoom = (self.orbit.zoom * 1.1f64.powf(notches)).clamp(0.25, 8.0);
                redraw(&self.state);
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw() {
                    self.fail(el, e);
                }
            }
            _ => {}
        }
    }
}
