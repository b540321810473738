//! The wgpu cloud renderer (DESIGN §2–4): a CloudMap becomes volumetric cloud shells over a
//! spherical Earth, lit by the Sun or Moon of the forecast's valid time.
//!
//! Stages, one module and one WGSL file each: `noise` (3D noise textures, once), `shadow` (the
//! full-column light volume, when the Sun or the map changes), `atmosphere` (the sky's tables),
//! `march` (compute ray march into a cloud texture), `exposure` (meters the frame), `present`
//! (sky + composite + tone map), `reproject` (a full frame from a subset march and the last
//! frame: the window, `flight`), `section` (the march's cloud on a vertical curtain). What the
//! stages read: `weather` uploads the map (`blend` a second forecast step), `structure` its
//! per-column base, top, type and wind, `ground` the terrain and surface, `cells` the cumulus
//! cell field, `profile` the per-type vertical profiles. Around them: `frame` forms the
//! uniforms, `camera` holds the geometry, `preset` the quality levels, `gpu` the adapter,
//! `shader` assembles the WGSL, `contract` the Rust↔WGSL contract, `stats` a frame's cost,
//! `readback` brings pictures back to the CPU.

pub mod atmosphere;
pub mod blend;
pub mod camera;
pub mod cells;
pub mod contract;
pub mod exposure;
pub mod frame;
pub mod gpu;
pub mod ground;
pub mod march;
pub mod noise;
pub mod present;
pub mod preset;
pub mod profile;
pub mod readback;
pub mod reproject;
pub mod section;
pub mod shader;
pub mod shadow;
pub mod stats;
pub mod structure;
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
pub use stats::{FrameStats, Stats};

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
    /// An error the GPU reported (a validation error, a lost device).
    #[error("GPU error: {0}")]
    Gpu(String),
    #[error("reading back from the GPU: {0}")]
    Readback(String),
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
    /// Exposure in stops: over the scene-adapted exposure when `exposure_auto`, else over
    /// [`frame::FIXED_EXPOSURE`] (fixed, for luminance comparisons).
    pub exposure_ev: f64,
    /// The exposure adapts to the scene (metered by the exposure stage).
    pub exposure_auto: bool,
    /// Share of the way (in stops) toward the metered exposure a frame goes: 1 for a single
    /// picture, less in the window so the eye adapts over a second or two.
    pub exposure_rate: f32,
    /// Meteorological visibility (m) for the aerial haze (Koschmieder: β = 3.912 / V).
    pub visibility_m: f64,
    pub frame_index: u32,
    /// How far each layer's noise has drifted with its wind since the series' reference time
    /// (east, north m; low, middle, high): zero for a plain map (crate::timeline).
    pub drift_m: [[f64; 2]; 3],
    /// The wind cirrus is streaked along, per layer (east, north m/s; low, middle, high): one
    /// direction for the whole region, fixed for a flight through a series
    /// (`Timeline::streak_wind`); `None` takes the map's mean wind.
    pub streak_wind: Option<[[f64; 2]; 3]>,
    /// Whether a perspective frame marches a subset of its pixels and reprojects the rest from
    /// the previous frame (render::reproject): the window and `flight`; a single picture
    /// marches every pixel.
    pub reprojection: Reprojection,
}

/// How frames are made from the ones before them (render::reproject).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Reprojection {
    /// Every pixel marched, every frame.
    #[default]
    Off,
    /// One pixel of each subset cell marched, the rest reprojected. Where the history does not
    /// fit (the first frame, a teleport, a new map), `full_reset` marches every pixel that frame;
    /// else the fresh subset, upsampled, stands in until the history fills again.
    On { full_reset: bool },
}

/// The look's defaults, defined once: [`Settings::new`], the command line and the window's
/// panel start from these.
pub mod defaults {
    pub const COVERAGE_MUL: f32 = 1.0;
    pub const DENSITY_MUL: f32 = 1.0;
    /// Extinction per unit of DESIGN's density d (1/m).
    pub const EXTINCTION: f32 = 0.04;
    pub const HG_G: f32 = 0.6;
    pub const BEER_CLAMP: f32 = 0.5;
    pub const EXPOSURE_EV: f64 = 0.0;
    pub const VISIBILITY_M: f64 = 60_000.0;
}

impl Settings {
    pub fn new(preset: Preset, time: DateTime<Utc>) -> Settings {
        Settings {
            march: preset.params(),
            time,
            sun_override: None,
            layers_on: [true; 3],
            coverage_mul: defaults::COVERAGE_MUL,
            density_mul: defaults::DENSITY_MUL,
            extinction: defaults::EXTINCTION,
            hg_g: defaults::HG_G,
            beer_clamp: defaults::BEER_CLAMP,
            exposure_ev: defaults::EXPOSURE_EV,
            exposure_auto: true,
            exposure_rate: 1.0,
            visibility_m: defaults::VISIBILITY_M,
            frame_index: 0,
            drift_m: [[0.0; 2]; 3],
            streak_wind: None,
            reprojection: Reprojection::Off,
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
        if !(self.exposure_rate > 0.0 && self.exposure_rate <= 1.0) {
            return bad(format!(
                "exposure adaptation rate {} must be in (0, 1]",
                self.exposure_rate
            ));
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
        if !(m.subset.is_power_of_two() && m.subset <= 8) {
            return bad(format!(
                "reprojection subset {} must be 1, 2, 4 or 8 pixels a side",
                m.subset
            ));
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

/// One full-size frame's textures: what the march (or the reproject stage) writes and the
/// exposure and present stages read.
struct FrameSet {
    /// Premultiplied linear cloud radiance and opacity.
    cloud: wgpu::Texture,
    /// The background's linear radiance and each pixel's distance (km).
    scene: wgpu::Texture,
    /// The march writing this set at full size (every pixel).
    march_bind: wgpu::BindGroup,
    present_bind: wgpu::BindGroup,
    exposure_bind: wgpu::BindGroup,
}

impl FrameSet {
    fn new(r: Stages<'_>, size: (u32, u32), cut_mask: &wgpu::Buffer) -> FrameSet {
        let (cloud, scene) = frame_textures(r.gpu, size);
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (cv, sv) = (view(&cloud), view(&scene));
        FrameSet {
            march_bind: r.march.bind_target(r.gpu, &cv, &sv, cut_mask),
            present_bind: r.present.bind_target(r.gpu, &cv, &sv),
            exposure_bind: r.exposure.bind_target(r.gpu, &cv, &sv),
            cloud,
            scene,
        }
    }
}

/// The cloud and scene textures of one frame (or subset march) of `size`.
fn frame_textures(gpu: &Gpu, size: (u32, u32)) -> (wgpu::Texture, wgpu::Texture) {
    let tex = |label| {
        texture_2d(
            &gpu.device,
            label,
            size,
            march::CLOUD_FORMAT,
            wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        )
    };
    (tex("cloud"), tex("scene"))
}

/// The stages that bind a frame's textures.
#[derive(Clone, Copy)]
struct Stages<'a> {
    gpu: &'a Gpu,
    march: &'a march::MarchPass,
    present: &'a present::PresentPass,
    exposure: &'a exposure::ExposurePass,
    reproject: &'a reproject::ReprojectPass,
}

/// A reprojected frame's extra textures: the subset march and a second full-size frame, so
/// each frame is made from the one before (ping-pong).
struct History {
    /// Subset cell side (px).
    n: u32,
    /// The subset march: one texel per cell.
    fresh_march_bind: wgpu::BindGroup,
    cells: (u32, u32),
    /// The second full-size frame (the first is `Targets::frame`).
    other: FrameSet,
    /// `reproject_bind[k]` writes frame k from the fresh subset and frame 1 − k.
    reproject_bind: [wgpu::BindGroup; 2],
    /// The frame the last reprojected frame wrote, and what it was made of.
    shown: usize,
    last: Option<reproject::FrameKey>,
    /// Reprojected frames made: the subset order's position.
    frames: u32,
    /// Why the last frame did not use its history (`None`: it did).
    last_reset: Option<&'static str>,
}

impl History {
    fn new(
        r: Stages<'_>,
        (width, height): (u32, u32),
        n: u32,
        first: &FrameSet,
        cut_mask: &wgpu::Buffer,
    ) -> History {
        let cells = (width.div_ceil(n), height.div_ceil(n));
        let (fc, fs) = frame_textures(r.gpu, cells);
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let other = FrameSet::new(r, (width, height), cut_mask);
        let fresh = [view(&fc), view(&fs)];
        let sets = [
            [view(&first.cloud), view(&first.scene)],
            [view(&other.cloud), view(&other.scene)],
        ];
        let reproject_bind = [0, 1].map(|k| {
            let (h, o) = (&sets[1 - k], &sets[k]);
            r.reproject.bind_target(
                r.gpu,
                [&fresh[0], &fresh[1]],
                [&h[0], &h[1]],
                [&o[0], &o[1]],
            )
        });
        History {
            n,
            fresh_march_bind: r.march.bind_target(r.gpu, &fresh[0], &fresh[1], cut_mask),
            cells,
            other,
            reproject_bind,
            shown: 0,
            last: None,
            frames: 0,
            last_reset: Some("first frame"),
        }
    }
}

/// Everything whose lifetime is the output size: made again only when the size changes.
struct Targets {
    width: u32,
    height: u32,
    /// The full-size frame a frame that marches every pixel writes.
    frame: FrameSet,
    /// Headless output; made on first use.
    color: Option<wgpu::Texture>,
    /// One bit per march pixel: the ray was cut short (see `Stats::cut_rays`).
    cut_mask: wgpu::Buffer,
    /// Made on the first reprojected frame at this size.
    history: Option<History>,
    /// Whether the last frame was reprojected (it then shows `history`'s frame `shown`).
    reprojected: bool,
    /// Whether the last frame marched a subset of its pixels (its cut mask is per cell).
    subset_marched: bool,
}

impl Targets {
    fn new(r: Stages<'_>, (width, height): (u32, u32)) -> Targets {
        let cut_mask = march::cut_mask_buffer(r.gpu, width, height);
        Targets {
            width,
            height,
            frame: FrameSet::new(r, (width, height), &cut_mask),
            color: None,
            cut_mask,
            history: None,
            reprojected: false,
            subset_marched: false,
        }
    }

    /// The frame the last encoded frame showed.
    fn shown(&self) -> &FrameSet {
        match &self.history {
            Some(h) if self.reprojected && h.shown == 1 => &h.other,
            _ => &self.frame,
        }
    }
}

/// How a reprojected frame is made (`Renderer::plan_reprojection`).
struct ReprojectionPlan {
    /// The history does not fit and every pixel is marched.
    full: bool,
    params: reproject::ReprojectParams,
}

/// A single-level 2D texture.
pub(crate) fn texture_2d(
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

/// How many GPU resources of each lifetime the renderer has made so far: a settings change
/// makes none, a new map of the same size none, a new output size one set of targets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Made {
    /// Render-target sets (cloud texture, cut mask and their bind groups).
    pub targets: u32,
    /// Map texture pairs (weather + coarse) and their bind group.
    pub map_textures: u32,
}

/// The renderer for one CloudMap on one GPU. Resources are held by lifetime: the device's
/// (noise, pipelines, uniforms), the map's (`weather`, `map_bind`) and the output size's
/// (`targets`).
pub struct Renderer {
    pub gpu: Gpu,
    pub meta: CloudMapMeta,
    pub weather: weather::WeatherMap,
    march: march::MarchPass,
    present: present::PresentPass,
    shadow: shadow::ShadowPass,
    atmosphere: atmosphere::AtmospherePass,
    exposure: exposure::ExposurePass,
    reproject: reproject::ReprojectPass,
    /// Counts the maps set, so the shadow volume knows when its map changed.
    map_generation: u64,
    map_bind: wgpu::BindGroup,
    targets: Option<Targets>,
    timer: Option<stats::PassTimer>,
    stats: stats::StatsReader,
    made: Made,
    /// Made on the first section asked for (`stratus section`); the views never need it.
    section: Option<section::SectionPass>,
}

/// Largest output side (and the limit the adapter sets, whichever is smaller).
pub const MAX_OUTPUT_SIDE: u32 = 8192;

/// The headless output's format.
const HEADLESS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

impl Renderer {
    pub fn new(gpu: Gpu, map: &CloudMap) -> Renderer {
        let noise = noise::NoiseTextures::generate(&gpu);
        let weather = weather::WeatherMap::upload(&gpu, map);
        let scene_layout = shadow::scene_layout(&gpu.device);
        let march = march::MarchPass::new(&gpu, &noise, &scene_layout);
        let exposure = exposure::ExposurePass::new(&gpu, &march.uniforms, &scene_layout);
        let present =
            present::PresentPass::new(&gpu, &march.uniforms, &exposure.state, &scene_layout);
        let map_bind = march.bind_map(&gpu, &weather);
        let atmosphere = atmosphere::AtmospherePass::new(&gpu, &march.uniforms);
        let reproject = reproject::ReprojectPass::new(&gpu, &march.uniforms);
        let mut shadow = shadow::ShadowPass::new(
            &gpu,
            &march,
            scene_layout,
            &map.meta.region,
            shadow::SkyViews {
                sky_view: atmosphere.sky_view().create_view(&Default::default()),
                aerial: atmosphere.aerial().create_view(&Default::default()),
            },
        );
        shadow.set_ground(&gpu, map.ground());
        let timer = gpu.timestamps.then(|| stats::PassTimer::new(&gpu));
        let stats = stats::StatsReader::new(&gpu);
        Renderer {
            meta: map.meta.clone(),
            weather,
            march,
            present,
            shadow,
            atmosphere,
            exposure,
            reproject,
            map_generation: 0,
            map_bind,
            targets: None,
            timer,
            stats,
            made: Made {
                map_textures: 1,
                targets: 0,
            },
            section: None,
            gpu,
        }
    }

    /// The march's variants compiled so far: a frame needing one compiles it (tests check that
    /// a map's genera pick the right one).
    pub fn march_variants_compiled(&self) -> Vec<march::Variant> {
        self.march.compiled()
    }

    /// Swap in another CloudMap. One of the same size goes into the textures already there
    /// (every rh_cr slider move); the render targets stay whatever the map.
    pub fn set_map(&mut self, map: &CloudMap) {
        if !self.weather.replace(&self.gpu, map) {
            self.map_bind = self.march.bind_map(&self.gpu, &self.weather);
            self.made.map_textures += 1;
        }
        if map.meta.region != self.meta.region {
            self.shadow.set_region(&self.gpu, &map.meta.region);
        }
        self.shadow.set_ground(&self.gpu, map.ground());
        self.map_generation += 1;
        self.meta = map.meta.clone();
    }

    /// Hold two forecast steps of one series, `a` before `b`, and blend them at each frame's
    /// time (render::blend); [`set_map`](Self::set_map) goes back to one map. Only these two
    /// steps' textures are on the GPU.
    pub fn set_pair(&mut self, a: &CloudMap, b: &CloudMap) -> Result<(), RenderError> {
        let kept = self
            .weather
            .set_pair(&self.gpu, a, b)
            .map_err(RenderError::BadSetting)?;
        if !kept {
            self.map_bind = self.march.bind_map(&self.gpu, &self.weather);
            self.made.map_textures += 1;
        }
        if a.meta.region != self.meta.region {
            self.shadow.set_region(&self.gpu, &a.meta.region);
        }
        if self.map_generation == 0 || a.meta != self.meta {
            self.shadow.set_ground(&self.gpu, a.ground());
        }
        self.map_generation += 1;
        self.meta = a.meta.clone();
        Ok(())
    }

    /// Bytes of the map textures resident on the GPU (one map, or the two blended steps).
    pub fn map_gpu_bytes(&self) -> u64 {
        self.weather.gpu_bytes()
    }

    /// Bring a held pair of steps to the frame's time (nothing without one).
    fn blend_at(&mut self, settings: &Settings) {
        let w = &mut self.weather;
        w.blend.at(&self.gpu, settings.time, &mut w.structure);
    }

    /// The largest output side: [`MAX_OUTPUT_SIDE`] or the adapter's limit, whichever is less.
    pub fn max_side(&self) -> u32 {
        MAX_OUTPUT_SIDE.min(self.gpu.device.limits().max_texture_dimension_2d)
    }

    fn check_size(&self, width: u32, height: u32) -> Result<(), RenderError> {
        let max = self.max_side();
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::BadSize(width, height, max));
        }
        Ok(())
    }

    /// What has been made so far (see [`Made`]).
    pub fn made(&self) -> Made {
        self.made
    }

    /// The targets for a `width`×`height` march, made when the size changes.
    fn targets(&mut self, width: u32, height: u32) -> &mut Targets {
        let fits = self
            .targets
            .as_ref()
            .is_some_and(|t| t.width == width && t.height == height);
        if !fits {
            self.made.targets += 1;
            self.targets = None;
        }
        let (stages, targets) = self.split();
        targets.get_or_insert_with(|| Targets::new(stages, (width, height)))
    }

    /// The stages that bind frame textures, beside the targets they bind.
    fn split(&mut self) -> (Stages<'_>, &mut Option<Targets>) {
        let Renderer {
            gpu,
            march,
            present,
            exposure,
            reproject,
            targets,
            ..
        } = self;
        let stages = Stages {
            gpu,
            march,
            present,
            exposure,
            reproject,
        };
        (stages, targets)
    }

    /// Why the last reprojected frame did not use its history (`None`: it did, or no frame
    /// was reprojected): "first frame", "size", "map", "time", "teleport", "settings".
    pub fn last_reset(&self) -> Option<&'static str> {
        self.targets
            .as_ref()
            .filter(|t| t.reprojected)
            .and_then(|t| t.history.as_ref())
            .and_then(|h| h.last_reset)
    }

    /// Record one frame into `enc`: the march at `width`×`height` (a subset of its pixels and
    /// the rest reprojected, when the settings ask for it and the view is a perspective), then
    /// the present pass into `target` (any size: the cloud image is scaled to it). Times the
    /// passes when it can.
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
        self.check_size(width, height)?;
        if target_width == 0 {
            return Err(RenderError::BadSize(target_width, height, self.max_side()));
        }
        settings.validate()?;
        self.blend_at(settings);
        let mut uniforms = self.uniforms(view, (width, height, target_width), settings)?;
        let pipeline = self
            .present
            .prepare(&self.gpu, target_format, settings.march.wide_upsample);
        let plan = self.plan_reprojection(view, (width, height), settings);
        let Renderer {
            gpu,
            march,
            present,
            shadow,
            atmosphere,
            exposure,
            reproject,
            map_bind,
            targets: Some(t),
            timer,
            map_generation,
            ..
        } = self
        else {
            unreachable!("targets were made by plan_reprojection");
        };
        // Which frame set this frame writes, and how its march is dispatched.
        let (set, march_bind, dispatch, reproject_step) = match (&plan, t.history.as_ref()) {
            (Some(p), Some(h)) if !p.full => {
                let k = 1 - h.shown;
                let [ox, oy] = reproject::subset_offset(h.n, h.frames);
                uniforms.subset_n = h.n as f32;
                uniforms.subset_offset = [ox as f32, oy as f32];
                (k, &h.fresh_march_bind, h.cells, Some((k, p.params)))
            }
            (Some(_), Some(h)) => {
                let k = 1 - h.shown;
                let bind = if k == 0 {
                    &t.frame.march_bind
                } else {
                    &h.other.march_bind
                };
                (k, bind, (width, height), None)
            }
            _ => (0, &t.frame.march_bind, (width, height), None),
        };
        gpu.queue
            .write_buffer(&march.uniforms, 0, bytemuck::bytes_of(&uniforms));
        gpu.queue.write_buffer(
            &march.counters,
            0,
            bytemuck::bytes_of(&march::Counters::default()),
        );
        atmosphere.update(enc, &uniforms);
        shadow.update(
            gpu,
            enc,
            march,
            map_bind,
            &uniforms,
            (
                settings.march.column_light,
                settings.march.terrain,
                settings.march.aerial,
            ),
            *map_generation,
        );
        enc.clear_buffer(&t.cut_mask, 0, None);
        let timer = timer.as_ref();
        let split = reproject_step.is_some();
        march.encode(
            gpu,
            march::Variant::of(uniforms.flags),
            enc,
            map_bind,
            march_bind,
            shadow.scene_bind(),
            dispatch,
            timer.map(|q| {
                if split {
                    q.compute_start()
                } else {
                    q.compute_writes()
                }
            }),
        );
        if let (Some((k, params)), Some(h)) = (reproject_step, t.history.as_ref()) {
            reproject.encode(
                gpu,
                enc,
                &params,
                &h.reproject_bind[k],
                (width, height),
                timer.map(|q| q.compute_end()),
            );
        }
        t.reprojected = plan.is_some();
        t.subset_marched = split;
        if let Some(h) = t.history.as_mut().filter(|_| plan.is_some()) {
            h.shown = set;
            h.frames = h.frames.wrapping_add(1);
        }
        let shown = t.shown();
        let params = exposure::ExposureParams {
            ev_mul: 2f64.powf(settings.exposure_ev) as f32,
            rate: settings.exposure_rate,
            auto_on: u32::from(settings.exposure_auto),
            _pad: 0,
        };
        exposure.encode(gpu, enc, &params, &shown.exposure_bind, shadow.scene_bind());
        present.encode(
            enc,
            pipeline,
            &shown.present_bind,
            shadow.scene_bind(),
            target,
            timer.map(|q| q.render_writes()),
        );
        if let Some(q) = timer {
            q.resolve(enc);
        }
        Ok(())
    }

    /// Make the targets for this frame and decide how it is made: `None` marches every pixel;
    /// else a reprojected frame, `full` when its history does not fit and the settings ask
    /// for a full march then. Records the frame as the next one's history.
    fn plan_reprojection(
        &mut self,
        view: &View,
        size: (u32, u32),
        settings: &Settings,
    ) -> Option<ReprojectionPlan> {
        let generation = self.map_generation;
        self.targets(size.0, size.1);
        let (stages, targets) = self.split();
        let t = targets.as_mut()?;
        let n = settings.march.subset;
        let (Reprojection::On { full_reset }, View::Perspective(camera), true) =
            (settings.reprojection, view, n > 1)
        else {
            // This frame writes the first frame set: the history's next frame starts afresh.
            if let Some(h) = t.history.as_mut() {
                h.last = None;
            }
            return None;
        };
        if t.history.as_ref().is_none_or(|h| h.n != n) {
            t.history = Some(History::new(stages, size, n, &t.frame, &t.cut_mask));
        }
        let h = t.history.as_mut()?;
        let now = reproject::FrameKey {
            camera: *camera,
            size,
            subset: n,
            map_generation: generation,
            time: settings.time,
            settings: settings.clone(),
        };
        let misfit = match &h.last {
            None => Some("first frame"),
            Some(last) => reproject::misfit(last, &now),
        };
        let params = reproject::params(h.last.as_ref(), camera, misfit.is_none());
        h.last_reset = misfit;
        h.last = Some(now);
        Some(ReprojectionPlan {
            full: misfit.is_some() && full_reset,
            params,
        })
    }

    /// The cloud's extinction (1/m) on a vertical curtain: one image column over each unit
    /// ECEF ground direction in `columns`, `height` rows from `top_m` (row 0) down to sea level,
    /// evaluated by the march's own density at the preset's detail (row-major).
    pub fn section(
        &mut self,
        columns: &[glam::DVec3],
        height: u32,
        top_m: f32,
        settings: &Settings,
    ) -> Result<Vec<f32>, RenderError> {
        let width = u32::try_from(columns.len()).unwrap_or(u32::MAX);
        self.check_size(width, height)?;
        if !(top_m.is_finite() && top_m > 0.0) {
            return Err(RenderError::BadSetting(format!(
                "section top {top_m} m must be a positive altitude"
            )));
        }
        settings.validate()?;
        self.blend_at(settings);
        let uniforms = self.uniforms(&View::TopDown, (width, height, width), settings)?;
        let scope = self
            .gpu
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        let pass = self
            .section
            .get_or_insert_with(|| section::SectionPass::new(&self.gpu, &self.march));
        self.gpu
            .queue
            .write_buffer(&self.march.uniforms, 0, bytemuck::bytes_of(&uniforms));
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        let out = pass.encode(
            &self.gpu,
            march::Variant::of(uniforms.flags),
            &mut enc,
            (self.march.device_bind(), &self.map_bind),
            columns,
            height,
            top_m,
        );
        let pending = readback::Pending::buffer(&self.gpu, &mut enc, &out);
        self.gpu.queue.submit([enc.finish()]);
        let bytes = pending.finish(&self.gpu)?;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(e.to_string()));
        }
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// Queue a copy of the last encoded frame's counters and pass times, to be read by
    /// [`Renderer::poll_stats`] once the GPU is done with it: the window never waits for them.
    /// Call [`Renderer::after_submit`] once `enc` is submitted.
    pub fn request_stats(&mut self, enc: &mut wgpu::CommandEncoder) {
        self.stats
            .record(enc, &self.march.counters, self.timer.as_ref());
    }

    /// Start mapping what [`Renderer::request_stats`] copied (call after the submit).
    pub fn after_submit(&mut self) {
        self.stats.after_submit();
    }

    /// The newest frame statistics the GPU has finished, without waiting; `None` when no newer
    /// ones are ready since the last call.
    pub fn poll_stats(&mut self) -> Option<FrameStats> {
        self.stats.poll(&self.gpu, self.timer.as_ref())
    }

    /// The exposure the last submitted frame was shown with (waits for it).
    pub fn read_exposure(&self) -> Result<exposure::ExposureState, RenderError> {
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        let rb = readback::Pending::buffer(&self.gpu, &mut enc, &self.exposure.state);
        self.gpu.queue.submit([enc.finish()]);
        let bytes = rb.finish(&self.gpu)?;
        Ok(bytemuck::pod_read_unaligned(&bytes))
    }

    /// The background the last frame laid its cloud over, per pixel: linear radiance (sky,
    /// Sun, Moon, stars, terrain in the clouds' shadows, aerial haze) and distance in km (0 for
    /// sky). With the cloud layer and the exposure it is everything the present stage's
    /// composite is made of (waits for the frame).
    pub fn read_scene(&self) -> Result<Vec<[f32; 4]>, RenderError> {
        let t = self
            .targets
            .as_ref()
            .ok_or(RenderError::Readback("no frame".into()))?;
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        let rb = readback::Pending::texture(&self.gpu, &mut enc, &t.shown().scene, 8);
        self.gpu.queue.submit([enc.finish()]);
        let raw = rb.finish(&self.gpu)?;
        Ok(readback::rgba16f(&raw))
    }

    /// Wall time (ms) of the per-change work for a view, each made again alone after a frame:
    /// the sky-view table, then the full-column light volume (they are not per frame: `bench`).
    pub fn time_per_change(
        &mut self,
        view: &View,
        width: u32,
        height: u32,
        settings: &Settings,
    ) -> Result<(f64, f64), RenderError> {
        self.render(view, width, height, settings)?;
        let u = self.uniforms(view, (width, height, width), settings)?;
        let timed = |r: &mut Renderer, which: u8| -> Result<f64, RenderError> {
            let start = Instant::now();
            let mut enc = r.gpu.device.create_command_encoder(&Default::default());
            if which == 0 {
                r.atmosphere.invalidate();
                r.atmosphere.update(&mut enc, &u);
            } else {
                r.shadow.invalidate();
                let light = (
                    settings.march.column_light,
                    settings.march.terrain,
                    settings.march.aerial,
                );
                r.shadow.update(
                    &r.gpu,
                    &mut enc,
                    &r.march,
                    &r.map_bind,
                    &u,
                    light,
                    r.map_generation,
                );
            }
            r.gpu.queue.submit([enc.finish()]);
            r.gpu.wait()?;
            Ok(start.elapsed().as_secs_f64() * 1e3)
        };
        let sky_ms = timed(self, 0)?;
        let volume_ms = timed(self, 1)?;
        Ok((sky_ms, volume_ms))
    }

    /// How many times the full-column light volume and the sky-view table have been made
    /// (they are per change of the Sun or the map, not per frame).
    pub fn light_builds(&self) -> (u32, u32) {
        (self.shadow.builds, self.atmosphere.builds)
    }

    /// Read the work counters and pass times of the last submitted frame (waits for it).
    pub fn read_stats(&self) -> Result<FrameStats, RenderError> {
        stats::read_now(&self.gpu, &self.march.counters, self.timer.as_ref())
    }

    /// The frame's uniforms for a view marched at width × height and presented `target_width`
    /// wide (the weather already blended for the settings' time).
    fn uniforms(
        &self,
        view: &View,
        (width, height, target_width): (u32, u32, u32),
        settings: &Settings,
    ) -> Result<frame::FrameUniforms, RenderError> {
        frame::build(&frame::FrameInput {
            view: *view,
            width,
            height,
            target_width,
            sky: self.sky(view, settings)?,
            region: &self.meta.region,
            weather: &self.weather,
            settings,
        })
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
        self.check_size(width, height)?;
        let scope = self
            .gpu
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        let start = Instant::now();
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        // The headless target lives with the cloud texture (same size).
        let color = {
            let dev = self.gpu.device.clone();
            let t = self.targets(width, height);
            let size = (t.width, t.height);
            t.color
                .get_or_insert_with(|| {
                    texture_2d(
                        &dev,
                        "frame",
                        size,
                        HEADLESS_FORMAT,
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
            HEADLESS_FORMAT,
            width,
        )?;
        let (cloud_tex, cut_mask, subset) = {
            let t = self
                .targets
                .as_ref()
                .ok_or(RenderError::Readback("no frame".into()))?;
            (
                t.shown().cloud.clone(),
                t.cut_mask.clone(),
                t.subset_marched,
            )
        };
        let gpu = &self.gpu;
        let rb_color = readback::Pending::texture(gpu, &mut enc, &color, 4);
        let rb_cloud = readback::Pending::texture(gpu, &mut enc, &cloud_tex, 8);
        gpu.queue.submit([enc.finish()]);
        let pixels = rb_color.finish(gpu)?;
        let wall_ms = start.elapsed().as_secs_f64() * 1e3;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(e.to_string()));
        }
        let cloud_raw = rb_cloud.finish(gpu)?;
        let cloud = readback::rgba16f(&cloud_raw);
        let FrameStats {
            stats,
            march_ms,
            present_ms,
        } = self.read_stats()?;
        let mut cut = Vec::new();
        // A subset march's cut rays are counted, not mapped to pixels.
        if stats.cut_rays > 0 && !subset {
            tracing::warn!(
                "{} of {} rays were stopped by the driver before their march ended (a CPU driver's cap on shader loop iterations): the frame is incomplete where rays are longest",
                stats.cut_rays,
                stats.rays
            );
            let mut enc = gpu.device.create_command_encoder(&Default::default());
            let rb = readback::Pending::buffer(gpu, &mut enc, &cut_mask);
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
