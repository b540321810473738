//! `stratus fly`: the interactive window (winit + egui over the wgpu renderer).
//!
//! One frame: the pilot moves, egui builds the panel and HUD, the renderer marches the clouds at
//! the panel's render scale and presents them into the window's surface, egui draws on top.
//! `--frames N --screenshot PATH` renders N frames, saves the last one and exits (CI under Xvfb).

pub mod panel;
pub mod pilot;

use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{anyhow, Context};
use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::pipeline::Plan;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use crate::render::{gpu, Gpu, Renderer, View};
use panel::{Controls, Hud};
use pilot::Pilot;

/// What `stratus fly` was asked to do.
/// Turns a dropped GRIB2 file into a map (and the RH plan that lets rh_cr be edited live).
pub type IngestDropped = Box<dyn Fn(&std::path::Path) -> anyhow::Result<(CloudMap, Plan)>>;

pub struct FlyOptions {
    pub map: CloudMap,
    /// Present when the map came from a GRIB2 file: RH in memory, rh_cr editable.
    pub plan: Option<Plan>,
    pub size: (u32, u32),
    pub preset: crate::render::Preset,
    pub adapter: Option<String>,
    pub frames: Option<u32>,
    pub screenshot: Option<PathBuf>,
    /// Re-ingest a dropped GRIB2 file over the current region.
    pub ingest_dropped: IngestDropped,
}

struct Running {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    can_read_surface: bool,
    renderer: Renderer,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    pilot: Pilot,
    controls: Controls,
    valid_time: DateTime<Utc>,
    keys: HashSet<KeyCode>,
    looking: bool,
    cursor: Option<(f64, f64)>,
    last: Instant,
    fps: f64,
    frame_ms: f64,
    gpu_ms: Option<f64>,
    frames: u32,
    /// Frame and GPU times after the first frame (start-up), for the `--frames` summary.
    frame_log: Vec<f64>,
    gpu_log: Vec<f64>,
    renderer_size: (u32, u32),
    want_shot: bool,
}

pub struct App {
    opts: FlyOptions,
    run: Option<Running>,
    pub result: anyhow::Result<()>,
}

/// Where a flight starts: 60 km from the part of the region with the most broken cloud, above
/// the highest layer, looking at it with the Sun behind. A clear centre would show an empty sky,
/// an overcast one a featureless deck.
pub fn start_pilot(map: &CloudMap, valid: DateTime<Utc>) -> Pilot {
    let region = map.meta.region;
    let (lat, lon) = cloudiest(map).unwrap_or_else(|| region.centre());
    let top = map
        .meta
        .layers
        .iter()
        .map(|l| l.top_m)
        .fold(2000.0, f64::max);
    let base = map.meta.layers.iter().map(|l| l.base_m).fold(top, f64::min);
    let sky = crate::sun::Sky::at(valid, lat, lon);
    let (e, n, _) = crate::render::camera::enu_basis(lat, lon);
    let sun_az = sky.sun.dir.dot(e).atan2(sky.sun.dir.dot(n)).to_degrees();
    // Stand back towards the Sun, so the target is ahead and lit from behind the camera.
    let back_m = 60_000.0;
    let (clat, clon) = destination(lat, lon, sun_az, back_m);
    let alt = top + 3000.0;
    let look_at = 0.5 * (base + top);
    let pitch = -((alt - look_at) / back_m).atan().to_degrees();
    Pilot::at(clat, clon, alt, (sun_az + 180.0).rem_euclid(360.0), pitch)
}

/// Centre of the 1/8-region block whose cover is most broken (mean m maximising m·(1−m)),
/// `None` for an empty map.
fn cloudiest(map: &CloudMap) -> Option<(f64, f64)> {
    const BLOCKS: usize = 8;
    let (w, h) = (map.width(), map.height());
    let mut best = (0.0f64, None);
    for by in 0..BLOCKS {
        for bx in 0..BLOCKS {
            let (x0, x1) = (
                bx * w / BLOCKS,
                ((bx + 1) * w / BLOCKS).max(bx * w / BLOCKS + 1),
            );
            let (y0, y1) = (
                by * h / BLOCKS,
                ((by + 1) * h / BLOCKS).max(by * h / BLOCKS + 1),
            );
            let mut sum = 0.0f64;
            for j in y0..y1.min(h) {
                for i in x0..x1.min(w) {
                    sum += f64::from(map.total(i, j));
                }
            }
            let mean = sum / ((x1 - x0) * (y1 - y0)) as f64;
            let broken = mean * (1.0 - mean);
            if broken > best.0 {
                let r = &map.meta.region;
                let cx = (x0 + x1) / 2;
                let cy = (y0 + y1) / 2;
                best = (
                    broken,
                    Some((r.pixel_lat(cy.min(h - 1), h), r.pixel_lon(cx.min(w - 1), w))),
                );
            }
        }
    }
    best.1
}

/// The point `dist_m` from (lat, lon) along the initial bearing `bearing_deg` on a sphere.
fn destination(lat: f64, lon: f64, bearing_deg: f64, dist_m: f64) -> (f64, f64) {
    let d = dist_m / crate::render::camera::EARTH_R;
    let (p1, l1, b) = (lat.to_radians(), lon.to_radians(), bearing_deg.to_radians());
    let p2 = (p1.sin() * d.cos() + p1.cos() * d.sin() * b.cos()).asin();
    let l2 = l1 + (b.sin() * d.sin() * p1.cos()).atan2(d.cos() - p1.sin() * p2.sin());
    let lon2 = (l2.to_degrees() + 540.0).rem_euclid(360.0) - 180.0;
    (p2.to_degrees(), lon2)
}

fn valid_time(map: &CloudMap) -> DateTime<Utc> {
    crate::cmd::render::parse_time(&map.meta.source.valid_time).unwrap_or_else(|_| Utc::now())
}

impl App {
    pub fn new(opts: FlyOptions) -> App {
        App {
            opts,
            run: None,
            result: Ok(()),
        }
    }

    fn fail(&mut self, el: &ActiveEventLoop, e: anyhow::Error) {
        self.result = Err(e);
        el.exit();
    }

    fn start(&mut self, el: &ActiveEventLoop) -> anyhow::Result<Running> {
        let (w, h) = self.opts.size;
        let attrs = Window::default_attributes()
            .with_title("Stratus")
            .with_inner_size(winit::dpi::PhysicalSize::new(w, h));
        let window = Arc::new(el.create_window(attrs).context("cannot open a window")?);
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| anyhow!("cannot draw into the window: {e}"))?;
        let gpu = Gpu::with_instance(instance, self.opts.adapter.as_deref(), Some(&surface))?;
        eprintln!("stratus: adapter {}", gpu::describe(&gpu.info));
        let caps = surface.get_capabilities(&gpu.adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| {
                !f.is_srgb()
                    && matches!(
                        f,
                        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm
                    )
            })
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| anyhow!("this GPU cannot present to the window (no surface format)"))?;
        let can_read_surface = caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&gpu.adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| anyhow!("the window's surface is not supported by this adapter"))?;
        config.format = format;
        if can_read_surface {
            config.usage |= wgpu::TextureUsages::COPY_SRC;
        }
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(&gpu.device, &config);
        let cpu = gpu.is_cpu();
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(gpu.device.limits().max_texture_dimension_2d as usize),
        );
        let egui_renderer = egui_wgpu::Renderer::new(&gpu.device, format, Default::default());
        let renderer = Renderer::new(gpu, &self.opts.map);
        let valid = valid_time(&self.opts.map);
        let rh_cr = {
            let mut r = [0.80, 0.65, 0.80];
            for l in &self.opts.map.meta.layers {
                r[l.channel] = l.rh_cr;
            }
            r
        };
        let mut controls = Controls::new(self.opts.preset, rh_cr, self.opts.plan.is_some(), cpu);
        controls.set_map(&self.opts.map);
        if cpu {
            controls.status = "CPU adapter: marching at ¼ resolution".into();
        }
        window.request_redraw();
        Ok(Running {
            window,
            surface,
            config,
            can_read_surface,
            renderer,
            egui_ctx,
            egui_state,
            egui_renderer,
            pilot: start_pilot(&self.opts.map, valid),
            controls,
            valid_time: valid,
            keys: HashSet::new(),
            looking: false,
            cursor: None,
            last: Instant::now(),
            fps: 0.0,
            frame_ms: 0.0,
            gpu_ms: None,
            frames: 0,
            frame_log: Vec::new(),
            gpu_log: Vec::new(),
            renderer_size: (0, 0),
            want_shot: false,
        })
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.run.is_some() {
            return;
        }
        match self.start(el) {
            Ok(r) => self.run = Some(r),
            Err(e) => self.fail(el, e),
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(r) = self.run.as_mut() else {
            return;
        };
        let egui_used = r.egui_state.on_window_event(&r.window, &event).consumed;
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(size) => {
                // 0×0 when minimised: keep the old configuration and skip frames.
                if size.width > 0 && size.height > 0 {
                    r.config.width = size.width;
                    r.config.height = size.height;
                    r.surface.configure(&r.renderer.gpu.device, &r.config);
                }
                r.window.request_redraw();
            }
            WindowEvent::KeyboardInput { event, .. } if !egui_used => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    match event.state {
                        ElementState::Pressed => {
                            if !event.repeat {
                                match code {
                                    KeyCode::Space => r.controls.paused = !r.controls.paused,
                                    KeyCode::F12 => r.want_shot = true,
                                    KeyCode::Escape => el.exit(),
                                    _ => {}
                                }
                            }
                            r.keys.insert(code);
                        }
                        ElementState::Released => {
                            r.keys.remove(&code);
                        }
                    }
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Right,
                ..
            } if !egui_used => {
                r.looking = state == ElementState::Pressed;
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let (true, Some((x, y))) = (r.looking, r.cursor) {
                    r.pilot.look_yaw += (position.x - x) * 0.2;
                    r.pilot.look_pitch =
                        (r.pilot.look_pitch - (position.y - y) * 0.2).clamp(-80.0, 80.0);
                }
                r.cursor = Some((position.x, position.y));
            }
            WindowEvent::DroppedFile(path) => match (self.opts.ingest_dropped)(&path) {
                Ok((map, plan)) => {
                    r.renderer.set_map(&map);
                    r.valid_time = valid_time(&map);
                    r.controls.rh_cr_editable = true;
                    r.controls.set_map(&map);
                    r.controls.status = format!("loaded {}", path.display());
                    self.opts.map = map;
                    self.opts.plan = Some(plan);
                }
                Err(e) => r.controls.status = format!("{}: {e:#}", path.display()),
            },
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame() {
                    self.fail(el, e);
                    return;
                }
                let Some(r) = self.run.as_mut() else {
                    return;
                };
                if self.opts.frames.is_some_and(|n| r.frames >= n) {
                    el.exit();
                } else {
                    r.window.request_redraw();
                }
            }
            _ => {}
        }
    }
}

impl App {
    fn frame(&mut self) -> anyhow::Result<()> {
        let Some(r) = self.run.as_mut() else {
            return Ok(());
        };
        let now = Instant::now();
        let dt = now.duration_since(r.last).as_secs_f64();
        r.last = now;
        // Smooth the frame time, not the rate: averaging rates overweights short frames.
        r.frame_ms = if r.frames < 2 {
            dt * 1e3
        } else {
            0.9 * r.frame_ms + 0.1 * dt * 1e3
        };
        r.fps = 1e3 / r.frame_ms.max(1e-3);
        // Frame k's interval is frame k-1's work: skip the first two (start-up, pipelines).
        if r.frames >= 2 {
            r.frame_log.push(dt * 1e3);
        }
        if !r.controls.paused && self.opts.frames.is_none() {
            r.pilot.step(&r.keys, dt);
        }
        let settings = r.controls.settings(r.valid_time, r.frames);
        let (tw, th) = (r.config.width, r.config.height);
        let scale = r.controls.render_scale.clamp(0.05, 1.0);
        let (mw, mh) = (
            ((tw as f32 * scale) as u32).max(1),
            ((th as f32 * scale) as u32).max(1),
        );
        let hud = Hud {
            lat: r.pilot.lat,
            lon: r.pilot.lon,
            alt_m: r.pilot.alt_m,
            heading: r.pilot.heading,
            speed: r.pilot.speed,
            utc: settings.time,
            fps: r.fps,
            gpu_ms: r.gpu_ms,
            frame_ms: r.frame_ms,
            adapter: r.renderer.gpu.info.name.clone(),
            march_size: (mw, mh),
        };
        r.renderer_size = (mw, mh);
        let input = r.egui_state.take_egui_input(&r.window);
        let mut actions = panel::Actions::default();
        let controls = &mut r.controls;
        let out = r.egui_ctx.run_ui(input, |ui| {
            actions = panel::panel(ui, controls);
            panel::hud(ui, &hud);
        });
        r.egui_state
            .handle_platform_output(&r.window, out.platform_output);
        if let Some((lat, lon, alt)) = actions.teleport {
            r.pilot.lat = lat;
            r.pilot.lon = lon;
            r.pilot.alt_m = alt;
        }
        if actions.rh_cr_changed {
            if let Some(plan) = self.opts.plan.as_mut() {
                match plan.set_rh_cr(r.controls.rh_cr) {
                    Ok(()) => {
                        let map = plan.build();
                        r.renderer.set_map(&map);
                        self.opts.map = map;
                    }
                    Err(e) => r.controls.status = e.to_string(),
                }
            }
        }
        r.want_shot |= actions.screenshot;
        if tw == 0 || th == 0 {
            return Ok(());
        }
        let frame = match r.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f)
            | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(())
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                r.surface.configure(&r.renderer.gpu.device, &r.config);
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(anyhow!("the window surface reported a validation error"));
            }
        };
        let target = frame.texture.create_view(&Default::default());
        let device = r.renderer.gpu.device.clone();
        let queue = r.renderer.gpu.queue.clone();
        let mut enc = device.create_command_encoder(&Default::default());
        let view = View::Perspective(r.pilot.camera());
        r.renderer.encode(
            &mut enc,
            &view,
            mw,
            mh,
            &settings,
            &target,
            r.config.format,
            tw,
        )?;
        // egui on top.
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [tw, th],
            pixels_per_point: out.pixels_per_point,
        };
        let prims = r.egui_ctx.tessellate(out.shapes, out.pixels_per_point);
        for (id, deltas) in &out.textures_delta.set {
            for delta in deltas {
                r.egui_renderer.update_texture(&device, &queue, *id, delta);
            }
        }
        let extra = r
            .egui_renderer
            .update_buffers(&device, &queue, &mut enc, &prims, &screen);
        {
            let pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("egui"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            let mut pass = pass.forget_lifetime();
            r.egui_renderer.render(&mut pass, &prims, &screen);
        }
        for id in &out.textures_delta.free {
            r.egui_renderer.free_texture(id);
        }
        r.frames += 1;
        let last = self.opts.frames.is_some_and(|n| r.frames >= n);
        let scripted = last && self.opts.screenshot.is_some();
        if (scripted || r.want_shot) && !r.can_read_surface {
            const NO: &str =
                "this window surface cannot be read back for a screenshot; use `stratus render`";
            if scripted {
                return Err(anyhow!(NO));
            }
            // F12 in a live window: say so on the panel, keep flying.
            r.controls.status = NO.into();
            r.want_shot = false;
        }
        let shot = if (scripted || r.want_shot) && r.can_read_surface {
            Some(crate::render::readback::Pending::texture(
                &r.renderer.gpu,
                &mut enc,
                &frame.texture,
                4,
            ))
        } else {
            None
        };
        queue.submit(extra.into_iter().chain([enc.finish()]));
        let (_, march, present) = r.renderer.read_stats()?;
        r.gpu_ms = march.zip(present).map(|(a, b)| a + b);
        if let (Some(g), true) = (r.gpu_ms, r.frames >= 2) {
            r.gpu_log.push(g);
        }
        if let Some(p) = shot {
            let mut px = p.finish(&r.renderer.gpu)?;
            if matches!(
                r.config.format,
                wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
            ) {
                for c in px.chunks_exact_mut(4) {
                    c.swap(0, 2);
                }
            }
            let img =
                image::RgbaImage::from_raw(tw, th, px).ok_or_else(|| anyhow!("screenshot size"))?;
            let path = match (&self.opts.screenshot, last) {
                (Some(p), true) => p.clone(),
                _ => PathBuf::from(format!(
                    "stratus-{}.png",
                    Utc::now().format("%Y%m%d-%H%M%S")
                )),
            };
            crate::cmd::render::save_png(&path, &img)?;
            r.controls.status = format!("saved {}", path.display());
            r.want_shot = false;
        }
        queue.present(frame);
        Ok(())
    }
}

/// Open the window and fly until it closes (or `--frames` are done).
pub fn fly(opts: FlyOptions) -> anyhow::Result<()> {
    let el = EventLoop::new().map_err(|e| {
        anyhow!("no display to open a window on ({e}); for headless output use `stratus render` or `stratus flight`")
    })?;
    let mut app = App::new(opts);
    el.run_app(&mut app)
        .map_err(|e| anyhow!("window event loop: {e}"))?;
    if let (Some(r), Some(_)) = (&app.run, app.opts.frames) {
        println!("{}", summary(r));
    }
    app.result
}

/// One line for `--frames` runs: the window's mean frame time after start-up.
fn summary(r: &Running) -> String {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let s = r.renderer_size;
    let gpu = if r.gpu_log.is_empty() {
        "no timestamps".to_string()
    } else {
        format!("GPU {:.1} ms", mean(&r.gpu_log))
    };
    format!(
        "{} frames in a {}x{} window (march {}x{}, {}): mean frame {:.1} ms over the last {}, {gpu}",
        r.frames,
        r.config.width,
        r.config.height,
        s.0,
        s.1,
        r.controls.preset.name(),
        mean(&r.frame_log),
        r.frame_log.len(),
    )
}
