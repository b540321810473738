//! The wgpu cloud renderer (DESIGN §2–4): a CloudMap becomes volumetric cloud shells over a
//! spherical Earth, lit by the Sun or Moon of the forecast's valid time. This module holds the
//! [`Renderer`], which keeps the resources by lifetime and records a frame in steps (light,
//! march, present).
//!
//! Stages, one module and one WGSL file each: `noise` (3D noise textures, once), `shadow` (the
//! full-column light volume, when the Sun or the map changes), `atmosphere` (the sky's tables),
//! `march` (compute ray march into a cloud texture), `exposure` (meters the frame), `present`
//! (sky + composite + tone map), `resolve` (a smaller march's jitter resolved before the present
//! stage enlarges it), `reproject` (a full frame from a subset march and the last
//! frame: the window, `flight`), `section` (the march's cloud on a vertical curtain). What the
//! stages read: `weather` uploads the map (`blend` a second forecast step), `structure` its
//! per-column base, top, type and wind, `ground` the terrain and surface, `cells` the cumulus
//! cell field, `profile` the per-type vertical profiles, `scene` the group the lighting and
//! showing stages share (light volume, sky tables, ground). The shared plumbing: `pipeline`
//! (pipelines, feature variants, bind groups), `texture` (texture helpers), `contract` (the
//! Rust↔WGSL contract: shared structs, bindings, layouts), `shader` (assembles the WGSL).
//! Around them: `settings` (a frame's settings and their validation), `targets` (the render
//! targets, by the output size's lifetime), `frame` forms the uniforms, `camera` holds the
//! geometry, `preset` the quality levels, `gpu` the adapter, `stats` a frame's cost,
//! `readback` brings pictures back to the CPU. `embed` draws the clouds inside a host's own
//! wgpu renderer (its device, camera, colour and depth: issue 33).

pub mod atmosphere;
pub mod blend;
pub mod camera;
pub mod cells;
pub mod contract;
pub mod embed;
pub mod exposure;
pub mod frame;
pub mod gpu;
pub mod ground;
pub mod march;
pub mod noise;
pub mod pipeline;
pub mod present;
pub mod preset;
pub mod profile;
pub mod reach;
pub mod readback;
pub mod reproject;
pub mod resolve;
pub mod scene;
pub mod section;
pub mod settings;
pub mod shader;
pub mod shadow;
pub mod stats;
pub mod structure;
mod targets;
pub mod texture;
pub mod weather;

use std::time::Instant;

use serde::Serialize;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::CloudMapMeta;

pub use camera::{Camera, View};
pub use gpu::Gpu;
pub use preset::{MarchParams, Preset, Shortcuts};
pub use settings::{defaults, Reprojection, Settings};
pub use stats::{FrameStats, Stats};

use crate::sun::Sky;
use targets::{MarchStep, Targets};

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
    /// Made on the first march enlarged into its target (the window's render scale).
    resolve: Option<resolve::ResolvePass>,
    /// Counts the maps set, so the shadow volume knows when its map changed.
    map_generation: u64,
    map_bind: wgpu::BindGroup,
    targets: Option<Targets>,
    timer: Option<stats::PassTimer>,
    stats: stats::StatsReader,
    made: Made,
    /// Made on the first section asked for (`stratus section`); the views never need it.
    section: Option<section::SectionPass>,
    /// A frame never waits for a pipeline to compile ([`Renderer::set_realtime`]).
    realtime: bool,
    /// The variant the last frame marched with.
    last_variant: Option<pipeline::Variant>,
}

/// Largest output side (and the limit the adapter sets, whichever is smaller).
pub const MAX_OUTPUT_SIDE: u32 = 8192;

/// The headless output's format.
const HEADLESS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

impl Renderer {
    pub fn new(gpu: Gpu, map: &CloudMap) -> Renderer {
        let noise = noise::NoiseTextures::generate(&gpu);
        let weather = weather::WeatherMap::upload(&gpu, map);
        let scene_layout = scene::scene_layout(&gpu.device);
        let march = march::MarchPass::new(&gpu, &noise, &scene_layout);
        let exposure = exposure::ExposurePass::new(&gpu, &march.uniforms, &scene_layout);
        let present =
            present::PresentPass::new(&gpu, &march.uniforms, &exposure.state, &scene_layout);
        let map_bind = march.bind_map(&gpu, &weather);
        let atmosphere = atmosphere::AtmospherePass::new(&gpu, &march.uniforms);
        let reproject = reproject::ReprojectPass::new(&gpu, &march.uniforms);
        let scene = scene::Scene::new(
            &gpu,
            scene_layout,
            scene::SkyViews {
                sky_view: atmosphere.sky_view().create_view(&Default::default()),
                aerial: atmosphere.aerial().create_view(&Default::default()),
            },
        );
        let mut shadow = shadow::ShadowPass::new(&gpu, &march, scene, &map.meta.region);
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
            resolve: None,
            map_generation: 0,
            map_bind,
            targets: None,
            timer,
            stats,
            realtime: false,
            last_variant: None,
            made: Made {
                map_textures: 1,
                targets: 0,
            },
            section: None,
            gpu,
        }
    }

    /// Whether a frame may wait for a pipeline variant it has not compiled (`false`, the
    /// default: files and benches) or goes on with one it has (`true`: the window, a host
    /// engine). A view that turns away from the map's cumulus needs a narrower march
    /// (render::reach), several seconds' compile on a CPU driver: in real time the frame keeps
    /// the map's variant, which draws the same picture, until the narrower one is compiled on a
    /// thread.
    pub fn set_realtime(&mut self, on: bool) {
        self.realtime = on;
    }

    /// The variant the last frame's march ran (`None` before the first): the map's genera less
    /// those out of the view's reach (render::reach).
    pub fn last_march_variant(&self) -> Option<pipeline::Variant> {
        self.last_variant
    }

    /// The march's variants compiled so far: a frame needing one compiles it (tests check that
    /// a map's genera pick the right one).
    pub fn march_variants_compiled(&self) -> Vec<pipeline::Variant> {
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
    /// time along `motion`, the guarded motion between them (render::blend; `Series::motion`);
    /// [`set_map`](Self::set_map) goes back to one map. Only these two steps' textures are on
    /// the GPU.
    pub fn set_pair(
        &mut self,
        a: &CloudMap,
        b: &CloudMap,
        motion: &stratus_ingest::series::motion::Motion,
    ) -> Result<(), RenderError> {
        let kept = self
            .weather
            .set_pair(&self.gpu, (a, b), motion)
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
    /// the present pass into the top-left `target_size` of `target` (any size: the cloud image
    /// is scaled to it; the rest of a larger target is left black, e.g. under the window's
    /// panel). Times the
    /// passes when it can. In steps: the light (the sky's tables, the light volume), the march
    /// (and the reprojection), the present (the exposure, then the picture).
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
        target_size: (u32, u32),
    ) -> Result<(), RenderError> {
        self.check_size(width, height)?;
        let target_width = target_size.0;
        if target_width == 0 || target_size.1 == 0 {
            return Err(RenderError::BadSize(
                target_width,
                target_size.1,
                self.max_side(),
            ));
        }
        settings.validate()?;
        self.blend_at(settings);
        let mut uniforms = self.uniforms(view, (width, height, target_width), settings)?;
        let resample = present::Resample::of(uniforms.march_scale);
        let pipeline = self.present.prepare(&self.gpu, target_format, resample);
        let plan = self.plan_reprojection(view, (width, height), settings);
        let step = self.march_step(plan.as_ref(), &mut uniforms, (width, height));
        // A single picture (no history, its exposure its own at once): the same inputs make
        // the same picture in any order (the bench's reference and every row compared with
        // it, `render --repeat`, the footprint bench's views).
        let single = settings.exposure_rate >= 1.0 && settings.reprojection == Reprojection::Off;
        if single {
            // Lit by its own Sun: the sky table and the light volume made for exactly it, not
            // kept from the picture before within their tolerance or while a new one is made
            // a slice a frame.
            self.atmosphere.require_exact(&uniforms);
            self.shadow.require_exact(&uniforms, self.map_generation);
        }
        self.encode_light(enc, &uniforms, settings);
        let variant = self.march_variant(view, &uniforms, settings);
        if single {
            // Its split and grazing pixels averaged at the Sun's exposure, not at the exposure
            // of whatever frame this renderer showed before.
            enc.clear_buffer(&self.exposure.state, 0, None);
        }
        self.encode_march(enc, variant, &step, plan.is_some(), (width, height));
        let enlarged = resample == present::Resample::Enlarged;
        if enlarged {
            self.encode_resolve(enc);
        }
        self.encode_present(enc, settings, pipeline, (target, target_size), enlarged);
        Ok(())
    }

    /// The shown frame's march resolved at its own size (render::resolve), for the present
    /// stage to enlarge; its texture made on the first such frame at this size.
    fn encode_resolve(&mut self, enc: &mut wgpu::CommandEncoder) {
        let Renderer {
            gpu,
            march,
            present,
            resolve,
            targets: Some(t),
            ..
        } = self
        else {
            unreachable!("targets were made by plan_reprojection");
        };
        let resolve =
            resolve.get_or_insert_with(|| resolve::ResolvePass::new(gpu, &march.uniforms));
        let size = (t.width, t.height);
        let set = t.shown_mut();
        let e = set.enlarged(gpu, resolve, present, size);
        resolve.encode(enc, &e.resolve_bind, size);
    }

    /// A frame's light: its uniforms and zeroed counters written, the sky's tables and the
    /// full-column light volume made where they changed.
    fn encode_light(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        uniforms: &frame::FrameUniforms,
        settings: &Settings,
    ) {
        let Renderer {
            gpu,
            march,
            shadow,
            atmosphere,
            map_bind,
            map_generation,
            ..
        } = self;
        gpu.queue
            .write_buffer(&march.uniforms, 0, bytemuck::bytes_of(uniforms));
        gpu.queue.write_buffer(
            &march.counters,
            0,
            bytemuck::bytes_of(&march::Counters::default()),
        );
        atmosphere.update(enc, uniforms);
        shadow.update(
            gpu,
            enc,
            march,
            map_bind,
            uniforms,
            (
                settings.march.column_light,
                settings.march.terrain,
                settings.march.aerial,
            ),
            *map_generation,
        );
    }

    /// A frame's march into the frame set `step` names (a subset march reprojected into it),
    /// recorded as the frame shown.
    fn encode_march(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        variant: pipeline::Variant,
        step: &MarchStep,
        reprojected: bool,
        size: (u32, u32),
    ) {
        self.last_variant = Some(variant);
        let Renderer {
            gpu,
            march,
            shadow,
            reproject,
            map_bind,
            targets: Some(t),
            timer,
            ..
        } = self
        else {
            unreachable!("targets were made by plan_reprojection");
        };
        enc.clear_buffer(&t.cut_mask, 0, None);
        let timer = timer.as_ref();
        let split = step.reproject.is_some();
        march.encode(
            gpu,
            variant,
            enc,
            (map_bind, t.march_bind(step.set, split), shadow.scene_bind()),
            &t.rework,
            step.dispatch,
            timer.map(|q| {
                if split {
                    q.compute_start()
                } else {
                    q.compute_writes()
                }
            }),
        );
        if let (Some(params), Some(h)) = (step.reproject, t.history.as_ref()) {
            reproject.encode(
                gpu,
                enc,
                &params,
                &h.reproject_bind[step.set],
                size,
                timer.map(|q| q.compute_end()),
            );
        }
        t.reprojected = reprojected;
        t.subset_marched = split;
        if let Some(h) = t.history.as_mut().filter(|_| reprojected) {
            h.shown = step.set;
            h.frames = h.frames.wrapping_add(1);
        }
    }

    /// The march's pipeline variant: the frame's, less the genus features that no ray of a
    /// perspective view can reach (render::reach). Only with region culling: without it a ray
    /// past the region's edge draws the edge texels' genus.
    fn march_variant(
        &self,
        view: &View,
        u: &frame::FrameUniforms,
        settings: &Settings,
    ) -> pipeline::Variant {
        let sc = settings.march.shortcuts;
        let unreached = match view {
            View::Perspective(cam) if sc.feature_reach && sc.region_cull => {
                let shell = (f64::from(u.shell_base_m), f64::from(u.shell_top_m));
                let light = f64::from(settings.march.light_reach_m);
                let frustum = reach::Frustum::new(cam, f64::from(u.aspect), shell, light);
                self.weather.structure.columns.unreached(&frustum)
            }
            _ => 0,
        };
        let want = pipeline::Variant::of(u.flags & !unreached);
        if self.realtime && unreached & u.flags != 0 && !self.march.is_ready(want) {
            self.march.prepare(&self.gpu, want);
            return pipeline::Variant::of(u.flags);
        }
        want
    }

    /// The frame shown: metered by the exposure stage, then presented into `target`.
    fn encode_present(
        &self,
        enc: &mut wgpu::CommandEncoder,
        settings: &Settings,
        pipeline: present::PipelineId,
        (target, target_size): (&wgpu::TextureView, (u32, u32)),
        enlarged: bool,
    ) {
        let Some(t) = self.targets.as_ref() else {
            unreachable!("targets were made by plan_reprojection");
        };
        let shown = t.shown();
        // An enlarged march is read resolved (`encode_resolve`).
        let present_bind = match (&shown.enlarged, enlarged) {
            (Some(e), true) => &e.present_bind,
            _ => &shown.present_bind,
        };
        let params = exposure::ExposureParams {
            ev_mul: 2f64.powf(settings.exposure_ev) as f32,
            rate: settings.exposure_rate,
            auto_on: u32::from(settings.exposure_auto),
            _pad: 0,
        };
        let scene_bind = self.shadow.scene_bind();
        self.exposure
            .encode(&self.gpu, enc, &params, &shown.exposure_bind, scene_bind);
        let timer = self.timer.as_ref();
        self.present.encode(
            enc,
            pipeline,
            present_bind,
            scene_bind,
            (target, target_size),
            timer.map(|q| q.render_writes()),
        );
        if let Some(q) = timer {
            q.resolve(enc);
        }
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
            pipeline::Variant::of(uniforms.flags),
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
                    texture::texture_2d(
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
            (width, height),
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
