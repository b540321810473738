//! The wgpu cloud renderer (DESIGN §2–4): a CloudMap becomes volumetric cloud shells over a
//! spherical Earth, lit by the Sun or Moon of the forecast's valid time.
//!
//! Stages, one module and one WGSL file each: `noise` (3D noise textures, once), `march`
//! (compute ray march into a cloud texture), `present` (sky + composite + tone map). `weather`
//! uploads the map, `frame` forms the uniforms, `camera` holds the geometry, `preset` the
//! quality levels, `gpu` the adapter, `readback` brings pictures back to the CPU.

pub mod camera;
pub mod frame;
pub mod gpu;
pub mod march;
pub mod noise;
pub mod present;
pub mod preset;
pub mod readback;
pub mod shader;
pub mod weather;

use std::time::Instant;

use chrono::{DateTime, Utc};
use glam::DVec3;
use serde::Serialize;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::CloudMapMeta;

pub use camera::{Camera, View};
pub use gpu::Gpu;
pub use preset::{MarchParams, Preset, Shortcuts};

use crate::sun::Sky;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(
        "no GPU adapter found: install a Vulkan driver (on Debian: apt-get install mesa-vulkan-drivers for the CPU driver lavapipe)"
    )]
    NoAdapter,
    #[error("no adapter matches \"{want}\"; available: {available}")]
    AdapterNotFound { want: String, available: String },
    #[error("could not open the GPU device: {0}")]
    Device(String),
    #[error("camera: {0}")]
    BadCamera(String),
    #[error("sun direction: {0}")]
    BadSun(String),
    #[error("setting {0}")]
    BadSetting(String),
    #[error("output size {0}×{1} is outside 1..={2} per side")]
    BadSize(u32, u32, u32),
    #[error("GPU error: {0}")]
    Gpu(String),
}

/// Everything about a frame except where the camera is.
#[derive(Clone, Debug)]
pub struct Settings {
    pub march: MarchParams,
    /// UTC time the Sun and Moon are placed for.
    pub time: DateTime<Utc>,
    /// Sun direction in the camera's local east/north/up frame, instead of the computed one.
    pub sun_override: Option<DVec3>,
    /// Low, middle, high layers drawn.
    pub layers_on: [bool; 3],
    pub coverage_mul: f32,
    pub density_mul: f32,
    /// Extinction per unit of DESIGN's density d (1/m).
    pub extinction: f32,
    /// Henyey–Greenstein asymmetry g of the dual-lobe phase.
    pub hg_g: f32,
    /// Beer clamp ac (eq. 22) in 0..1: the floor ac·exp(−τ/4) under exp(−τ).
    pub beer_clamp: f32,
    /// Exposure correction in stops over the automatic exposure.
    pub exposure_ev: f64,
    /// Meteorological visibility (m) for the aerial haze (Koschmieder: β = 3.912 / V).
    pub visibility_m: f64,
    pub frame_index: u32,
}

impl Settings {
    pub fn new(preset: Preset, time: DateTime<Utc>) -> Settings {
        Settings {
            march: preset.params(),
            time,
            sun_override: None,
            layers_on: [true; 3],
            coverage_mul: 1.0,
            density_mul: 1.0,
            extinction: 0.04,
            hg_g: 0.6,
            beer_clamp: 0.5,
            exposure_ev: 0.0,
            visibility_m: 60_000.0,
            frame_index: 0,
        }
    }

    pub fn validate(&self) -> Result<(), RenderError> {
        let bad = |m: String| Err(RenderError::BadSetting(m));
        let finite_nonneg = [
            ("coverage multiplier", self.coverage_mul),
            ("density multiplier", self.density_mul),
            ("extinction", self.extinction),
        ];
        for (name, v) in finite_nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} {v} must be a finite number ≥ 0"));
            }
        }
        if !(self.hg_g > -0.99 && self.hg_g < 0.99) {
            return bad(format!("HG g {} must be inside -0.99..0.99", self.hg_g));
        }
        if !(0.0..=1.0).contains(&self.beer_clamp) {
            return bad(format!("Beer clamp ac {} must be in 0..1", self.beer_clamp));
        }
        if !self.exposure_ev.is_finite() || self.exposure_ev.abs() > 30.0 {
            return bad(format!(
                "exposure {} EV must be within ±30",
                self.exposure_ev
            ));
        }
        if !(self.visibility_m.is_finite() && self.visibility_m > 0.0) {
            return bad(format!("visibility {} m must be > 0", self.visibility_m));
        }
        let m = &self.march;
        if !(m.step_min_m >= 1.0 && m.step_max_m >= m.step_min_m && m.step_max_m <= 1.0e5) {
            return bad(format!(
                "steps {}..{} m must satisfy 1 ≤ min ≤ max ≤ 100000",
                m.step_min_m, m.step_max_m
            ));
        }
        if !(m.step_growth.is_finite() && m.step_growth >= 0.0)
            || m.max_steps == 0
            || m.max_steps > 100_000
        {
            return bad("step growth must be ≥ 0 and max steps in 1..=100000".into());
        }
        if m.light_steps == 0
            || m.light_steps > 16
            || m.light_reach_m.is_nan()
            || m.light_reach_m <= 0.0
        {
            return bad("light steps must be in 1..=16 with a positive reach".into());
        }
        if let Some(s) = self.sun_override {
            if !s.is_finite() || s.length() < 1e-9 {
                return Err(RenderError::BadSun("has zero length".into()));
            }
        }
        Ok(())
    }
}

/// Work the march did, from the GPU's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Stats {
    pub rays: u64,
    pub steps: u64,
    pub density_samples: u64,
    pub detail_samples: u64,
    pub light_samples: u64,
    /// Density samples taken outside the map's region (zero with region culling on).
    pub outside_samples: u64,
    pub skipped_steps: u64,
    pub early_exits: u64,
    /// Rays the driver stopped before their march ended (Mesa llvmpipe's cap on a shader's loop
    /// iterations; only `reference`'s long rays reach it). Zero on a GPU.
    pub cut_rays: u64,
}

/// GPU time per pass from timestamp queries where the adapter has them, and wall time.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Timings {
    pub march_ms: Option<f64>,
    pub present_ms: Option<f64>,
    pub wall_ms: f64,
}

/// A rendered frame, back on the CPU.
pub struct Output {
    pub width: u32,
    pub height: u32,
    /// Tone-mapped sRGB RGBA8, what the PNG holds.
    pub pixels: Vec<u8>,
    /// The cloud layer: premultiplied linear radiance and opacity per pixel.
    pub cloud: Vec<[f32; 4]>,
    /// Per pixel, whether its ray was cut short (`Stats::cut_rays`); empty when none was.
    pub cut: Vec<bool>,
    pub stats: Stats,
    pub timings: Timings,
}

impl Output {
    /// Whether pixel `i`'s ray was cut short, so the pixel is incomplete.
    pub fn is_cut(&self, i: usize) -> bool {
        self.cut.get(i).copied().unwrap_or(false)
    }

    pub fn alpha(&self) -> Vec<f32> {
        self.cloud.iter().map(|c| c[3]).collect()
    }

    pub fn to_image(&self) -> image::RgbaImage {
        image::RgbaImage::from_raw(self.width, self.height, self.pixels.clone())
            .unwrap_or_else(|| image::RgbaImage::new(self.width, self.height))
    }
}

struct Targets {
    width: u32,
    height: u32,
    cloud: wgpu::Texture,
    cloud_view: wgpu::TextureView,
    /// Headless output; made on first use.
    color: Option<wgpu::Texture>,
    march_bind: wgpu::BindGroup,
    /// One bit per march pixel: the ray was cut short (see `Stats::cut_rays`).
    cut_mask: wgpu::Buffer,
    /// Present bind groups, by index into `Renderer::presents`; made on first use.
    present_binds: Vec<Option<wgpu::BindGroup>>,
}

/// A single-level 2D texture.
fn texture_2d(
    dev: &wgpu::Device,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    dev.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

struct Queries {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    period_ns: f64,
}

/// The renderer for one CloudMap on one GPU.
pub struct Renderer {
    pub gpu: Gpu,
    pub meta: CloudMapMeta,
    pub weather: weather::WeatherMap,
    noise: noise::NoiseTextures,
    march: march::MarchPass,
    /// One present pipeline per target format (headless sRGB, the window's surface format).
    presents: Vec<present::PresentPass>,
    targets: Option<Targets>,
    queries: Option<Queries>,
}

/// Largest output side (and the limit the adapter sets, whichever is smaller).
pub const MAX_OUTPUT_SIDE: u32 = 8192;

impl Renderer {
    pub fn new(gpu: Gpu, map: &CloudMap) -> Renderer {
        let noise = noise::NoiseTextures::generate(&gpu);
        let weather = weather::WeatherMap::upload(&gpu, map);
        let march = march::MarchPass::new(&gpu);
        let queries = gpu.timestamps.then(|| Queries {
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass times"),
                ty: wgpu::QueryType::Timestamp,
                count: 4,
            }),
            resolve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pass times"),
                size: 32,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period_ns: gpu.queue.get_timestamp_period() as f64,
        });
        Renderer {
            gpu,
            meta: map.meta.clone(),
            weather,
            noise,
            march,
            presents: Vec::new(),
            targets: None,
            queries,
        }
    }

    /// Swap in another CloudMap (keeps the device, noise and pipelines).
    pub fn set_map(&mut self, map: &CloudMap) {
        self.weather = weather::WeatherMap::upload(&self.gpu, map);
        self.meta = map.meta.clone();
        self.targets = None;
    }

    fn ensure_targets(&mut self, width: u32, height: u32) {
        if self
            .targets
            .as_ref()
            .is_some_and(|t| t.width == width && t.height == height)
        {
            return;
        }
        let cloud = texture_2d(
            &self.gpu.device,
            "cloud",
            (width, height),
            march::CLOUD_FORMAT,
            wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let cloud_view = cloud.create_view(&Default::default());
        let cut_mask = march::cut_mask_buffer(&self.gpu, width, height);
        let march_bind = self.march.bind(
            &self.gpu,
            &self.weather,
            &self.noise,
            &cloud_view,
            &cut_mask,
        );
        self.targets = Some(Targets {
            width,
            height,
            cloud,
            cloud_view,
            color: None,
            march_bind,
            cut_mask,
            present_binds: Vec::new(),
        });
    }

    fn present_for(&mut self, format: wgpu::TextureFormat) -> usize {
        if let Some(i) = self.presents.iter().position(|p| p.format == format) {
            return i;
        }
        self.presents
            .push(present::PresentPass::new(&self.gpu, format));
        self.presents.len() - 1
    }

    /// Record one frame into `enc`: the march at `width`×`height`, then the present pass into
    /// `target` (any size: the cloud image is scaled to it). Times the passes when it can.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        view: &View,
        width: u32,
        height: u32,
        settings: &Settings,
        target: &wgpu::TextureView,
        target_format: wgpu::TextureFormat,
        target_width: u32,
    ) -> Result<(), RenderError> {
        let max = MAX_OUTPUT_SIDE.min(self.gpu.device.limits().max_texture_dimension_2d);
        if width == 0 || height == 0 || width > max || height > max || target_width == 0 {
            return Err(RenderError::BadSize(width, height, max));
        }
        settings.validate()?;
        let sky = self.sky(view, settings)?;
        let mut uniforms = frame::build(&frame::FrameInput {
            view: *view,
            width,
            height,
            sky,
            region: &self.meta.region,
            weather: &self.weather,
            settings,
            frame_index: settings.frame_index,
        })?;
        uniforms.misc[3] = width as f32 / target_width as f32;
        self.ensure_targets(width, height);
        let pi = self.present_for(target_format);
        let Some(t) = self.targets.as_mut() else {
            return Err(RenderError::Gpu("no render targets".into()));
        };
        if t.present_binds.len() <= pi {
            t.present_binds.resize(pi + 1, None);
        }
        if t.present_binds[pi].is_none() {
            let b = self.presents[pi].bind(&self.gpu, &self.march.uniforms, &t.cloud_view);
            t.present_binds[pi] = Some(b);
        }
        let t = &*t;
        let present = &self.presents[pi];
        let Some(bind) = t.present_binds[pi].as_ref() else {
            return Err(RenderError::Gpu("no present bind group".into()));
        };
        let gpu = &self.gpu;
        gpu.queue
            .write_buffer(&self.march.uniforms, 0, bytemuck::bytes_of(&uniforms));
        gpu.queue
            .write_buffer(&self.march.counters, 0, &[0u8; march::COUNTERS * 4]);
        enc.clear_buffer(&t.cut_mask, 0, None);
        let q = self.queries.as_ref();
        self.march.encode(
            enc,
            &t.march_bind,
            width,
            height,
            q.map(|q| wgpu::ComputePassTimestampWrites {
                query_set: &q.set,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            }),
        );
        present.encode(
            enc,
            bind,
            target,
            q.map(|q| wgpu::RenderPassTimestampWrites {
                query_set: &q.set,
                beginning_of_pass_write_index: Some(2),
                end_of_pass_write_index: Some(3),
            }),
        );
        if let Some(q) = q {
            enc.resolve_query_set(&q.set, 0..4, &q.resolve, 0);
        }
        Ok(())
    }

    /// Read the work counters and pass times of the last submitted frame (waits for it).
    pub fn read_stats(&self) -> Result<(Stats, Option<f64>, Option<f64>), RenderError> {
        let gpu = &self.gpu;
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let rb_count = readback::Pending::buffer(gpu, &mut enc, &self.march.counters);
        let rb_time = self
            .queries
            .as_ref()
            .map(|q| readback::Pending::buffer(gpu, &mut enc, &q.resolve));
        gpu.queue.submit([enc.finish()]);
        let counts = rb_count.finish(gpu)?;
        let c: Vec<u64> = bytemuck::cast_slice::<u8, u32>(&counts)
            .iter()
            .map(|&v| v as u64)
            .collect();
        let stats = Stats {
            rays: c[0],
            steps: c[1],
            density_samples: c[2],
            detail_samples: c[3],
            light_samples: c[4],
            outside_samples: c[5],
            skipped_steps: c[6],
            early_exits: c[7],
            cut_rays: c[8],
        };
        let (mut m, mut p) = (None, None);
        if let (Some(rb), Some(q)) = (rb_time, self.queries.as_ref()) {
            let raw = rb.finish(gpu)?;
            let ts: &[u64] = bytemuck::cast_slice(&raw);
            let ms = |a: u64, b: u64| (b > a).then(|| (b - a) as f64 * q.period_ns / 1e6);
            m = ms(ts[0], ts[1]);
            p = ms(ts[2], ts[3]);
        }
        Ok((stats, m, p))
    }

    /// The sky for a view: computed from the time and place, or the override.
    pub fn sky(&self, view: &View, settings: &Settings) -> Result<Sky, RenderError> {
        let (lat, lon) = match view {
            View::Perspective(c) => (c.lat_deg, c.lon_deg),
            View::TopDown => self.meta.region.centre(),
        };
        Ok(match settings.sun_override {
            Some(enu) => {
                if !enu.is_finite() || enu.length() < 1e-9 {
                    return Err(RenderError::BadSun("has zero length".into()));
                }
                let (e, n, u) = camera::enu_basis(lat, lon);
                let d = enu.normalize();
                Sky::with_sun((e * d.x + n * d.y + u * d.z).normalize(), lat, lon)
            }
            None => Sky::at(settings.time, lat, lon),
        })
    }

    /// Render one frame and read it back.
    pub fn render(
        &mut self,
        view: &View,
        width: u32,
        height: u32,
        settings: &Settings,
    ) -> Result<Output, RenderError> {
        const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
        let scope = self
            .gpu
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        let start = Instant::now();
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        // The headless target lives with the cloud texture (same size).
        let color = {
            self.ensure_targets(width.max(1), height.max(1));
            let dev = &self.gpu.device;
            let t = self
                .targets
                .as_mut()
                .ok_or_else(|| RenderError::Gpu("no targets".into()))?;
            let size = (t.width, t.height);
            t.color
                .get_or_insert_with(|| {
                    texture_2d(
                        dev,
                        "frame",
                        size,
                        FORMAT,
                        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                    )
                })
                .clone()
        };
        let color_view = color.create_view(&Default::default());
        self.encode(
            &mut enc,
            view,
            width,
            height,
            settings,
            &color_view,
            FORMAT,
            width,
        )?;
        let gpu = &self.gpu;
        let Some(t) = self.targets.as_ref() else {
            return Err(RenderError::Gpu("no render targets".into()));
        };
        let rb_color = readback::Pending::texture(gpu, &mut enc, &color, 4);
        let rb_cloud = readback::Pending::texture(gpu, &mut enc, &t.cloud, 8);
        gpu.queue.submit([enc.finish()]);
        let pixels = rb_color.finish(gpu)?;
        let wall_ms = start.elapsed().as_secs_f64() * 1e3;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(e.to_string()));
        }
        let cloud_raw = rb_cloud.finish(gpu)?;
        let cloud: Vec<[f32; 4]> = bytemuck::cast_slice::<u8, half::f16>(&cloud_raw)
            .chunks_exact(4)
            .map(|c| [c[0].to_f32(), c[1].to_f32(), c[2].to_f32(), c[3].to_f32()])
            .collect();
        let (stats, march_ms, present_ms) = self.read_stats()?;
        let mut cut = Vec::new();
        if stats.cut_rays > 0 {
            tracing::warn!(
                "{} of {} rays were stopped by the driver before their march ended (a CPU driver's cap on shader loop iterations): the frame is incomplete where rays are longest",
                stats.cut_rays,
                stats.rays
            );
            let mut enc = gpu.device.create_command_encoder(&Default::default());
            let rb = readback::Pending::buffer(gpu, &mut enc, &t.cut_mask);
            gpu.queue.submit([enc.finish()]);
            let words: Vec<u32> = bytemuck::pod_collect_to_vec(&rb.finish(gpu)?);
            cut = (0..(width * height) as usize)
                .map(|i| words.get(i / 32).is_some_and(|w| w >> (i % 32) & 1 == 1))
                .collect();
        }
        Ok(Output {
            width,
            height,
            pixels,
            cloud,
            cut,
            stats,
            timings: Timings {
                march_ms,
                present_ms,
                wall_ms,
            },
        })
    }
}
