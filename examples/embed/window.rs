//! The example's window: the same host and clouds as the headless run, drawn each frame into
//! the host's own targets and copied to a winit window's surface. The camera flies north at
//! 120 m/s with the aircraft box ahead of it; Esc or closing the window ends it.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{anyhow, Context};
use glam::Vec3;
use stratus::render::embed::EmbedOptions;
use stratus_ingest::cloudmap::CloudMap;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, KeyEvent, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use crate::{aircraft, camera, time, World, EYE};

/// The host's ground speed, m/s (a light aircraft's cruise).
const SPEED: f32 = 120.0;

struct Screen {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    world: World,
    started: Instant,
    frames: u32,
}

struct App {
    size: (u32, u32),
    frames: Option<u32>,
    map: CloudMap,
    options: EmbedOptions,
    screen: Option<Screen>,
    result: anyhow::Result<()>,
}

/// Open the window and fly until it closes (or after `frames` frames, when not 0).
pub fn run(
    size: (u32, u32),
    frames: Option<u32>,
    map: CloudMap,
    options: EmbedOptions,
) -> anyhow::Result<()> {
    let el = EventLoop::new()
        .map_err(|e| anyhow!("no display to open a window on ({e}); use --out F.png"))?;
    let mut app = App {
        size,
        frames,
        map,
        options,
        screen: None,
        result: Ok(()),
    };
    el.run_app(&mut app)
        .map_err(|e| anyhow!("window event loop: {e}"))?;
    app.result
}

/// An sRGB surface format the embedding takes, as the host's colour format too: the frame is
/// drawn into the host's target and copied to the surface, so both must be the same.
fn surface_format(caps: &wgpu::SurfaceCapabilities) -> Option<wgpu::TextureFormat> {
    [
        wgpu::TextureFormat::Bgra8UnormSrgb,
        wgpu::TextureFormat::Rgba8UnormSrgb,
    ]
    .into_iter()
    .find(|f| caps.formats.contains(f))
}

impl App {
    fn open(&self, el: &ActiveEventLoop) -> anyhow::Result<Screen> {
        let attrs = Window::default_attributes()
            .with_title("Stratus clouds in a wgpu host")
            .with_resizable(false)
            .with_inner_size(winit::dpi::PhysicalSize::new(self.size.0, self.size.1));
        let window = Arc::new(el.create_window(attrs).context("cannot open a window")?);
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| anyhow!("cannot draw into the window: {e}"))?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            compatible_surface: Some(&surface),
            ..Default::default()
        }))
        .map_err(|e| anyhow!("no adapter for the window: {e}"))?;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("host"),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| anyhow!("no device: {e}"))?;
        let caps = surface.get_capabilities(&adapter);
        let format = surface_format(&caps)
            .ok_or_else(|| anyhow!("the window offers no sRGB 8-bit surface format"))?;
        if !caps.usages.contains(wgpu::TextureUsages::COPY_DST) {
            return Err(anyhow!("the window's surface cannot be copied into"));
        }
        // The window's actual size (a window manager may not honour the request).
        let inner = window.inner_size();
        let size = (inner.width.max(1), inner.height.max(1));
        let mut config = surface
            .get_default_config(&adapter, size.0, size.1)
            .ok_or_else(|| anyhow!("the window's surface is not supported by this adapter"))?;
        config.format = format;
        config.usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_DST;
        surface.configure(&device, &config);
        let world = World::new(device, queue, size, format, &self.map, self.options)?;
        window.request_redraw();
        Ok(Screen {
            window,
            surface,
            world,
            started: Instant::now(),
            frames: 0,
        })
    }
}

impl Screen {
    /// One frame: the host's scene and the clouds into the host's target, copied to the surface.
    fn frame(&mut self) -> anyhow::Result<()> {
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f)
            | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(anyhow!("the window surface reported a validation error"))
            }
            // Lost, outdated, occluded or late: skip this frame; the next one asks again.
            _ => return Ok(()),
        };
        let t = self.started.elapsed().as_secs_f32();
        let eye = EYE + Vec3::new(0.0, 0.0, -SPEED * t);
        let size = (frame.texture.width(), frame.texture.height());
        let cam = camera(eye, size);
        let w = &mut self.world;
        w.host.update_mesh(&w.aircraft, &aircraft(eye));
        let mut enc = w.host.device.create_command_encoder(&Default::default());
        let when = time() + chrono::Duration::milliseconds((t * 1000.0) as i64);
        w.encode(&mut enc, &cam, when)?;
        enc.copy_texture_to_texture(
            w.host.color.as_image_copy(),
            frame.texture.as_image_copy(),
            frame.texture.size(),
        );
        w.host.queue.submit([enc.finish()]);
        self.window.pre_present_notify();
        w.host.queue.present(frame);
        self.frames += 1;
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.screen.is_some() {
            return;
        }
        match self.open(el) {
            Ok(s) => self.screen = Some(s),
            Err(e) => {
                self.result = Err(e);
                el.exit();
            }
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let Some(s) = self.screen.as_mut() else {
            return;
        };
        match event {
            WindowEvent::CloseRequested
            | WindowEvent::KeyboardInput {
                event:
                    KeyEvent {
                        logical_key: Key::Named(NamedKey::Escape),
                        state: ElementState::Pressed,
                        ..
                    },
                ..
            } => el.exit(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = s.frame() {
                    self.result = Err(e);
                    el.exit();
                } else if self.frames.is_some_and(|n| s.frames >= n) {
                    let secs = s.started.elapsed().as_secs_f64();
                    println!(
                        "window: {} frames in {secs:.1} s ({:.0} ms a frame)",
                        s.frames,
                        secs * 1e3 / s.frames as f64
                    );
                    el.exit();
                } else {
                    s.window.request_redraw();
                }
            }
            _ => {}
        }
    }
}
