//! `stratus fly`: the interactive window (winit + egui over the wgpu renderer).
//!
//! One frame (`frame.rs`): the pilot moves, egui builds the panel and HUD, the renderer marches
//! the clouds at the panel's render scale and presents them into the window's surface, egui
//! draws on top. The window never waits on the GPU for statistics: they arrive a frame or two
//! late. `--frames N --screenshot PATH` renders N frames, saves the last one and exits (CI
//! under Xvfb).

pub mod daylight;
mod frame;
pub mod moment;
pub mod overlay;
pub mod panel;
pub mod pilot;
pub mod start;

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{anyhow, Context};
use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::pipeline::Plan;
use stratus_ingest::region::Region;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use crate::render::{gpu, Gpu, Renderer};
use panel::Controls;
use pilot::Pilot;
pub use start::start_pilot;

/// Turns a dropped GRIB2 file into a map over the given region and size (and the RH plan that
/// lets rh_cr be edited live).
pub type IngestDropped = Box<dyn Fn(&Path, Region, (u32, u32)) -> anyhow::Result<(CloudMap, Plan)>>;

/// What `stratus fly` was asked to do.
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
    /// `--follow`: the camera takes a simulator's pose instead of the keyboard pilot's.
    pub follow: Option<crate::follow::Follower>,
    /// `--time`: the moment the window starts at (default: the map's valid time).
    pub time: Option<DateTime<Utc>>,
    /// `--time-rate`: how fast time runs from the start.
    pub time_rate: moment::Rate,
    /// A series: the window flies through its steps (the time slider spans them).
    pub timeline: Option<crate::timeline::Timeline>,
    /// `--reprojection`: march a subset of the pixels each frame and reproject the rest.
    pub reprojection: bool,
    /// `--render-scale`: the march's size relative to the window (default: 1 on a GPU, ¼ on a
    /// CPU adapter without reprojection, ½ with it).
    pub render_scale: Option<f32>,
    /// `--super-resolution`: at a render scale under 1, reproject at the window's own size
    /// (`scaled::plan`) instead of enlarging the march.
    pub super_resolution: bool,
    /// `--visibility-km`: the haze's meteorological visibility (the panel changes it).
    pub visibility_km: f64,
    /// `--path`: the camera plays this keyframed flight in real time, looping (the frame-time
    /// measurement's scripted flight).
    pub path: Option<crate::flight::FlightPath>,
}

/// The window's surface and how it is configured.
struct Screen {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    /// The surface can be copied from (screenshots).
    can_read: bool,
}

/// egui: its context, its winit glue and the layer its renderer draws into.
struct Ui {
    ctx: egui::Context,
    state: egui_winit::State,
    overlay: overlay::Overlay,
}

/// Keys held and the mouse-look drag.
#[derive(Default)]
struct Input {
    keys: HashSet<KeyCode>,
    looking: bool,
    cursor: Option<(f64, f64)>,
}

/// Frame timing: the smoothed frame time for the HUD and the logs for the `--frames` summary.
struct Clock {
    last: Instant,
    frames: u32,
    frame_ms: f64,
    gpu_ms: Option<f64>,
    /// Frame and GPU times after the first frames (start-up).
    frame_log: Vec<f64>,
    gpu_log: Vec<f64>,
}

impl Clock {
    fn new() -> Clock {
        Clock {
            last: Instant::now(),
            frames: 0,
            frame_ms: 0.0,
            gpu_ms: None,
            frame_log: Vec::new(),
            gpu_log: Vec::new(),
        }
    }

    /// Seconds since the last frame, logged and smoothed.
    fn tick(&mut self) -> f64 {
        let now = Instant::now();
        let dt = now.duration_since(self.last).as_secs_f64();
        self.last = now;
        // Smooth the frame time, not the rate: averaging rates overweights short frames.
        self.frame_ms = if self.frames < 2 {
            dt * 1e3
        } else {
            0.9 * self.frame_ms + 0.1 * dt * 1e3
        };
        // Frame k's interval is frame k-1's work: skip the first two (start-up, pipelines).
        if self.frames >= 2 {
            self.frame_log.push(dt * 1e3);
        }
        dt
    }

    fn fps(&self) -> f64 {
        1e3 / self.frame_ms.max(1e-3)
    }

    fn gpu_time(&mut self, ms: Option<f64>) {
        self.gpu_ms = ms;
        if let (Some(g), true) = (ms, self.frames >= 2) {
            self.gpu_log.push(g);
        }
    }
}

struct Running {
    screen: Screen,
    ui: Ui,
    renderer: Renderer,
    pilot: Pilot,
    controls: Controls,
    /// What the time slider counts from (a series' first step).
    valid_time: DateTime<Utc>,
    /// A series: the two steps around the moment are kept on the GPU (moment.rs).
    timeline: Option<crate::timeline::Timeline>,
    input: Input,
    clock: Clock,
    /// The march size of the last frame.
    march_size: (u32, u32),
    want_shot: bool,
    /// When `--path` started playing.
    path_start: Option<std::time::Instant>,
}

pub struct App {
    opts: FlyOptions,
    run: Option<Running>,
    pub result: anyhow::Result<()>,
}

fn valid_time(map: &CloudMap) -> DateTime<Utc> {
    map.meta.source.valid_time.unwrap_or_else(Utc::now)
}

/// The surface format: a plain 8-bit one egui prefers (the present pass encodes sRGB itself).
fn surface_format(caps: &wgpu::SurfaceCapabilities) -> Option<wgpu::TextureFormat> {
    caps.formats
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

    fn open_screen(&self, el: &ActiveEventLoop) -> anyhow::Result<(Screen, Gpu)> {
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
        let adapter = gpu
            .adapter
            .clone()
            .ok_or_else(|| anyhow!("no adapter for the window"))?;
        let caps = surface.get_capabilities(&adapter);
        let format = surface_format(&caps)
            .ok_or_else(|| anyhow!("this GPU cannot present to the window (no surface format)"))?;
        let can_read = caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| anyhow!("the window's surface is not supported by this adapter"))?;
        config.format = format;
        if can_read {
            config.usage |= wgpu::TextureUsages::COPY_SRC;
        }
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(&gpu.device, &config);
        let screen = Screen {
            window,
            surface,
            config,
            can_read,
        };
        Ok((screen, gpu))
    }

    fn start(&mut self, el: &ActiveEventLoop) -> anyhow::Result<Running> {
        let (screen, gpu) = self.open_screen(el)?;
        let cpu = gpu.is_cpu();
        let ctx = egui::Context::default();
        let state = egui_winit::State::new(
            ctx.clone(),
            egui::ViewportId::ROOT,
            &screen.window,
            Some(screen.window.scale_factor() as f32),
            None,
            Some(gpu.device.limits().max_texture_dimension_2d as usize),
        );
        let overlay = overlay::Overlay::new(&gpu.device, screen.config.format);
        let mut renderer = Renderer::new(gpu, &self.opts.map);
        renderer.set_realtime(true);
        let timeline = self.opts.timeline.take();
        let valid = moment::slider_base(valid_time(&self.opts.map), timeline.as_ref());
        let rh_cr = LayerKind::ALL.map(LayerKind::default_rh_cr);
        let mut controls = Controls::new(self.opts.preset, rh_cr, self.opts.plan.is_some(), cpu);
        controls.reproject = self.opts.reprojection;
        controls.render_scale = self
            .opts
            .render_scale
            .unwrap_or_else(|| panel::default_render_scale(cpu));
        controls.visibility_km = self.opts.visibility_km;
        controls.set_map(&self.opts.map);
        controls.set_time(valid, self.opts.time, timeline.as_ref().map(|t| t.span()));
        controls.time_rate = self.opts.time_rate;
        if cpu {
            controls.status = format!(
                "CPU adapter: marching at {:.0} % of the view's size (beside the panel)",
                controls.render_scale * 100.0
            );
        }
        screen.window.request_redraw();
        Ok(Running {
            screen,
            ui: Ui {
                ctx,
                state,
                overlay,
            },
            renderer,
            pilot: start_pilot(&self.opts.map, self.opts.time.unwrap_or(valid)),
            controls,
            valid_time: valid,
            timeline,
            input: Input::default(),
            clock: Clock::new(),
            march_size: (0, 0),
            want_shot: false,
            path_start: None,
        })
    }

    /// A GRIB2 file dropped on the window, ingested over the current map's region and size.
    fn dropped(&mut self, path: &Path) {
        let Some(r) = self.run.as_mut() else {
            return;
        };
        let meta = &self.opts.map.meta;
        let (region, size) = (meta.region, (meta.width, meta.height));
        match (self.opts.ingest_dropped)(path, region, size) {
            Ok((map, plan)) => {
                r.renderer.set_map(&map);
                r.valid_time = valid_time(&map);
                // A plain map now: the slider goes back to a day either side.
                r.timeline = None;
                r.controls.set_time(r.valid_time, None, None);
                r.controls.rh_cr_editable = true;
                r.controls.set_map(&map);
                r.controls.status = format!("loaded {}", path.display());
                self.opts.map = map;
                self.opts.plan = Some(plan);
            }
            Err(e) => r.controls.status = format!("{}: {e:#}", path.display()),
        }
    }
}

impl Running {
    fn key(&mut self, el: &ActiveEventLoop, code: KeyCode, state: ElementState, repeat: bool) {
        match state {
            ElementState::Pressed => {
                if !repeat {
                    match code {
                        KeyCode::Space => self.controls.paused = !self.controls.paused,
                        KeyCode::F12 => self.want_shot = true,
                        KeyCode::Escape => el.exit(),
                        _ => {}
                    }
                }
                self.input.keys.insert(code);
            }
            ElementState::Released => {
                self.input.keys.remove(&code);
            }
        }
    }

    fn mouse_moved(&mut self, x: f64, y: f64) {
        if let (true, Some((x0, y0))) = (self.input.looking, self.input.cursor) {
            self.pilot.look_yaw += (x - x0) * 0.2;
            self.pilot.look_pitch = (self.pilot.look_pitch - (y - y0) * 0.2).clamp(-80.0, 80.0);
        }
        self.input.cursor = Some((x, y));
    }

    fn resized(&mut self, size: winit::dpi::PhysicalSize<u32>) {
        // 0×0 when minimised: keep the old configuration and skip frames.
        if size.width > 0 && size.height > 0 {
            self.screen.config.width = size.width;
            self.screen.config.height = size.height;
            self.screen
                .surface
                .configure(&self.renderer.gpu.device, &self.screen.config);
        }
        self.screen.window.request_redraw();
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
        let egui_used =
            r.ui.state
                .on_window_event(&r.screen.window, &event)
                .consumed;
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(size) => r.resized(size),
            WindowEvent::KeyboardInput { event, .. } if !egui_used => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    r.key(el, code, event.state, event.repeat);
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Right,
                ..
            } if !egui_used => r.input.looking = state == ElementState::Pressed,
            WindowEvent::CursorMoved { position, .. } => r.mouse_moved(position.x, position.y),
            WindowEvent::DroppedFile(path) => self.dropped(&path),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame() {
                    self.fail(el, e);
                    return;
                }
                let Some(r) = self.run.as_mut() else {
                    return;
                };
                if self.opts.frames.is_some_and(|n| r.clock.frames >= n) {
                    el.exit();
                } else {
                    r.screen.window.request_redraw();
                }
            }
            _ => {}
        }
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
        // Not println!: a closed stdout must not panic the window's last step.
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), "{}", summary(r));
    }
    app.result
}

/// One line for `--frames` runs: the window's mean frame time after start-up.
fn summary(r: &Running) -> String {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let s = r.march_size;
    let c = &r.clock;
    let gpu = if c.gpu_log.is_empty() {
        "no timestamps".to_string()
    } else {
        format!("GPU {:.1} ms", mean(&c.gpu_log))
    };
    let now = r.controls.settings(r.valid_time, c.frames).time;
    let weather = r
        .weather_line(now)
        .map_or(String::new(), |w| format!("; {w}"));
    format!(
        "{} frames in a {}x{} window (march {}x{}, {}): mean frame {:.1} ms over the last {}, {gpu}{weather}",
        c.frames,
        r.screen.config.width,
        r.screen.config.height,
        s.0,
        s.1,
        r.controls.preset.name(),
        mean(&c.frame_log),
        c.frame_log.len(),
    )
}
