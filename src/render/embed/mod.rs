//! Clouds inside a host's own renderer (issue 33): [`EmbeddedClouds`] draws Stratus' clouds on
//! the host's `wgpu::Device` and `Queue` into the host's colour target, stopping each ray at the
//! host's depth buffer, with the host's camera. No adapter or device of its own, nothing read
//! back, and nothing made on the frame path once the targets' size is known (counted:
//! [`Creations`]).
//!
//! A frame: the depth stage turns the host's depth into each pixel's farthest reach
//! (`stage`), the renderer's light and march run as for its own frames with the rays stopping
//! there, and the composite blends the cloud over the host's colour (premultiplied:
//! out = cloud + T·host). `camera` checks the host's camera and turns it into Stratus' own.
//! See docs/embedding.md.
//!
//! ```no_run
//! # fn frame(device: &wgpu::Device, queue: &wgpu::Queue, map: &stratus_ingest::cloudmap::CloudMap,
//! #          color: &wgpu::TextureView, depth: &wgpu::TextureView) -> Result<(), stratus::render::embed::EmbedError> {
//! use stratus::render::embed::*;
//! let mut clouds = EmbeddedClouds::new(
//!     device,
//!     queue,
//!     map,
//!     HostFormats { color: wgpu::TextureFormat::Rgba16Float, depth: wgpu::TextureFormat::Depth32Float },
//!     EmbedOptions::default(),
//! )?;
//! let anchor = GeoAnchor { lat_deg: 47.0, lon_deg: 8.0, alt_m: 0.0 };
//! let camera = HostCamera::look_at(
//!     anchor,
//!     glam::Vec3::new(0.0, 2000.0, 0.0),
//!     glam::Vec3::new(0.0, 1500.0, -10_000.0),
//!     glam::Vec3::Y,
//!     60.0,
//!     16.0 / 9.0,
//!     (1.0, f32::INFINITY),
//!     DepthConvention::ReversedZ,
//! );
//! let mut enc = device.create_command_encoder(&Default::default());
//! // ... the host draws its own scene into `color` and `depth` here ...
//! clouds.encode(&mut enc, &HostFrame { camera: &camera, color, depth, time: chrono::Utc::now() })?;
//! queue.submit([enc.finish()]);
//! # Ok(()) }
//! ```

mod camera;
mod stage;

pub use camera::{DepthConvention, GeoAnchor, HostCamera};
pub use stage::Creations;

use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;

use super::targets::Targets;
use super::{exposure, Gpu, Preset, RenderError, Renderer, Reprojection, Settings, View};

/// What can go wrong when embedding: every misuse is one of these, never a panic.
#[derive(Debug, thiserror::Error)]
pub enum EmbedError {
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("camera: {0}")]
    BadCamera(String),
    #[error("projection: {0}")]
    Projection(String),
    #[error("the {what} target's format {format:?} is not one the embedding takes ({accepted})")]
    UnsupportedFormat {
        what: &'static str,
        format: wgpu::TextureFormat,
        accepted: &'static str,
    },
    #[error("the depth target is {depth:?} but the colour target is {color:?}: they must be the same size")]
    SizeMismatch {
        color: (u32, u32),
        depth: (u32, u32),
    },
    #[error("the {what} target lacks the usage {missing:?}")]
    Usage {
        what: &'static str,
        missing: wgpu::TextureUsages,
    },
    #[error("the {what} target is multisampled ({samples}×): resolve it first")]
    Multisampled { what: &'static str, samples: u32 },
    /// An error the device reported (a resource of another device, a limit the host's device
    /// lacks).
    #[error("GPU: {0}")]
    Gpu(String),
}

/// The host's target formats, given at creation so the composite is ready for the first frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostFormats {
    pub color: wgpu::TextureFormat,
    pub depth: wgpu::TextureFormat,
}

/// How the cloud's radiance reaches the host's units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CloudExposure {
    /// Stratus' exposure stage (auto-metered or fixed, per [`Settings`]): display-referred,
    /// 1 is white; the host's target then shows it as the window does.
    Stratus,
    /// Stratus' linear radiance (the Sun's illuminance is `SUN_I` = 20) times this: for a host
    /// with an HDR pipeline and its own exposure and tone curve.
    Scale(f32),
}

/// What the host chooses once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmbedOptions {
    pub preset: Preset,
    pub exposure: CloudExposure,
    /// Stratus' own terrain under its clouds' shadows (the host draws its own: off).
    pub terrain: bool,
    /// Stratus' own sky (Sun, Moon, stars, the physical atmosphere) where the host's depth
    /// buffer holds nothing (the host draws its own: off).
    pub sky: bool,
}

impl Default for EmbedOptions {
    fn default() -> EmbedOptions {
        EmbedOptions {
            preset: Preset::Balanced,
            exposure: CloudExposure::Stratus,
            terrain: false,
            sky: false,
        }
    }
}

/// One frame of the host's.
pub struct HostFrame<'a> {
    pub camera: &'a HostCamera,
    /// The host's colour target, already drawn: the clouds are blended over it.
    pub color: &'a wgpu::TextureView,
    /// The host's depth buffer for the same frame (its texture needs `TEXTURE_BINDING`).
    pub depth: &'a wgpu::TextureView,
    /// The moment the Sun, the Moon and (with a pair of steps) the weather are placed for.
    pub time: DateTime<Utc>,
}

/// Colour formats the composite takes: blendable, and either linear float (HDR: the host tone
/// maps) or sRGB-encoded 8-bit (display-referred: the clouds are tone-mapped).
const COLOR_FORMATS: &[wgpu::TextureFormat] = &[
    wgpu::TextureFormat::Rgba16Float,
    wgpu::TextureFormat::Rg11b10Ufloat,
    wgpu::TextureFormat::Rgba8UnormSrgb,
    wgpu::TextureFormat::Bgra8UnormSrgb,
];
const COLOR_ACCEPTED: &str = "Rgba16Float, Rg11b10Ufloat, Rgba8UnormSrgb, Bgra8UnormSrgb";
const DEPTH_ACCEPTED: &str = "a depth format (Depth32Float, Depth24Plus, Depth16Unorm, …)";

/// Stratus' clouds on a host's device (see the module's documentation).
pub struct EmbeddedClouds {
    renderer: Renderer,
    stage: stage::EmbedStage,
    /// The frame's settings; the time is each frame's. Change them freely between frames.
    pub settings: Settings,
    pub exposure: CloudExposure,
    /// Stratus' sky where the host drew nothing ([`EmbedOptions::sky`]).
    pub sky: bool,
    made: Creations,
}

impl EmbeddedClouds {
    /// Make everything that lives as long as the device and the map on the host's device.
    /// Errors when a format is not one the embedding takes, or the device refuses what
    /// Stratus needs (its limits).
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        map: &CloudMap,
        formats: HostFormats,
        options: EmbedOptions,
    ) -> Result<EmbeddedClouds, EmbedError> {
        check_color_format(formats.color)?;
        check_depth_format(formats.depth)?;
        let gpu = Gpu::host(device, queue);
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut stage = stage::EmbedStage::new(&gpu);
        stage.prepare(&gpu, formats.color);
        let mut renderer = Renderer::new(gpu, map);
        // A host's frame never waits for a pipeline compile.
        renderer.set_realtime(true);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(EmbedError::Gpu(e.to_string()));
        }
        let mut settings = Settings::new(
            options.preset,
            map.meta.source.valid_time.unwrap_or_else(Utc::now),
        );
        settings.march.terrain = options.terrain;
        settings.reprojection = Reprojection::Off;
        Ok(EmbeddedClouds {
            renderer,
            stage,
            settings,
            exposure: options.exposure,
            sky: options.sky,
            made: Creations::default(),
        })
    }

    /// Swap in another CloudMap (one of the same size goes into the textures already there).
    pub fn set_map(&mut self, map: &CloudMap) {
        self.renderer.set_map(map);
    }

    /// Hold two forecast steps and blend them at each frame's time along `motion`, the guarded
    /// motion between them (render::blend; `Series::motion`).
    pub fn set_pair(
        &mut self,
        a: &CloudMap,
        b: &CloudMap,
        motion: &stratus_ingest::series::motion::Motion,
    ) -> Result<(), EmbedError> {
        Ok(self.renderer.set_pair(a, b, motion)?)
    }

    /// The GPU objects made so far, the renderer's frame targets included.
    pub fn creations(&self) -> Creations {
        let s = self.stage.made;
        Creations {
            buffers: s.buffers + self.made.buffers,
            textures: s.textures + self.made.textures,
            texture_views: s.texture_views + self.made.texture_views,
            bind_groups: s.bind_groups + self.made.bind_groups,
            pipelines: s.pipelines + self.made.pipelines,
        }
    }

    /// The renderer underneath (its `made()`, `section()` or `read_stats()`, which waits).
    pub fn renderer(&mut self) -> &mut Renderer {
        &mut self.renderer
    }

    /// Record the clouds of one host frame into `enc`, after the host's own drawing: the host's
    /// depth into each pixel's reach, the march (stopping there), the composite over `color`.
    pub fn encode(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        frame: &HostFrame<'_>,
    ) -> Result<(), EmbedError> {
        let (width, height) = check_targets(frame)?;
        let camera = frame.camera.to_stratus(width, height)?;
        self.settings.time = frame.time;
        self.settings.reprojection = Reprojection::Off;
        self.settings.validate()?;
        self.renderer.check_size(width, height)?;
        self.size_targets(width, height);
        self.stage
            .bind_depth(&self.renderer.gpu, frame.depth.texture())
            .map_err(EmbedError::Gpu)?;
        let pipeline = self
            .stage
            .prepare(&self.renderer.gpu, frame.color.texture().format());
        let view = View::Perspective(camera);
        let size = (width, height);
        let r = &mut self.renderer;
        r.blend_at(&self.settings);
        let mut uniforms = r.uniforms(&view, (width, height, width), &self.settings)?;
        let plan = r.plan_reprojection(&view, size, &self.settings);
        let step = r.march_step(plan.as_ref(), &mut uniforms, size);
        let (mul, stratus) = match self.exposure {
            CloudExposure::Stratus => (1.0, true),
            CloudExposure::Scale(s) => (s, false),
        };
        if !mul.is_finite() || mul < 0.0 {
            return Err(RenderError::BadSetting(format!("exposure scale {mul}")).into());
        }
        // A display-referred (8-bit sRGB) target takes the cloud tone-mapped; a float one linear.
        let look = stage::Look {
            exposure_mul: mul,
            stratus_exposure: stratus,
            tone: !is_float(frame.color.texture().format()),
            resolve: self.settings.march.shortcuts.jitter,
            step_growth: self.settings.march.effective().step_growth,
            sky: self.sky,
        };
        self.stage
            .encode_far(&r.gpu, enc, &frame.camera.depth_model(), look);
        r.encode_light(enc, &uniforms, &self.settings);
        let variant = r.march_variant(&view, &uniforms, &self.settings);
        r.encode_march(enc, variant, &step, false, size);
        if stratus {
            self.encode_exposure(enc);
        }
        self.stage.encode_composite(enc, pipeline, frame.color);
        Ok(())
    }

    /// The renderer's targets and the stage's reach buffer for a target size, made when the
    /// size changes: the march's rays then read the reach.
    fn size_targets(&mut self, width: u32, height: u32) {
        let gpu = &self.renderer.gpu;
        if !self.stage.resize(gpu, width, height) {
            return;
        }
        let Some(far) = self.stage.far().cloned() else {
            return;
        };
        let r = &mut self.renderer;
        let (stages, targets) = r.split();
        let t = Targets::with_far(stages, (width, height), far);
        // The frame set's cloud and scene textures, the cut mask, the march's, present's and
        // exposure's groups (render::targets).
        self.made.textures += 2;
        self.made.texture_views += 2;
        self.made.buffers += 1;
        self.made.bind_groups += 3;
        let (cloud, scene) = (t.frame.cloud.clone(), t.frame.scene.clone());
        *targets = Some(t);
        r.made.targets += 1;
        let exposure = r.exposure.state.clone();
        self.stage
            .bind_composite(&r.gpu, (&cloud, &scene), &exposure);
    }

    /// The exposure stage over the frame the march wrote (Stratus' own exposure).
    fn encode_exposure(&self, enc: &mut wgpu::CommandEncoder) {
        let r = &self.renderer;
        let Some(t) = r.targets.as_ref() else {
            return;
        };
        let params = exposure::ExposureParams {
            ev_mul: 2f64.powf(self.settings.exposure_ev) as f32,
            rate: self.settings.exposure_rate,
            auto_on: u32::from(self.settings.exposure_auto),
            _pad: 0,
        };
        r.exposure.encode(
            &r.gpu,
            enc,
            &params,
            &t.shown().exposure_bind,
            r.shadow.scene_bind(),
        );
    }
}

fn is_float(f: wgpu::TextureFormat) -> bool {
    matches!(
        f,
        wgpu::TextureFormat::Rgba16Float | wgpu::TextureFormat::Rg11b10Ufloat
    )
}

fn check_color_format(format: wgpu::TextureFormat) -> Result<(), EmbedError> {
    if COLOR_FORMATS.contains(&format) {
        Ok(())
    } else {
        Err(EmbedError::UnsupportedFormat {
            what: "colour",
            format,
            accepted: COLOR_ACCEPTED,
        })
    }
}

fn check_depth_format(format: wgpu::TextureFormat) -> Result<(), EmbedError> {
    if format.has_depth_aspect() {
        Ok(())
    } else {
        Err(EmbedError::UnsupportedFormat {
            what: "depth",
            format,
            accepted: DEPTH_ACCEPTED,
        })
    }
}

/// The frame's target size, after checking formats, usages, sample counts and sizes.
fn check_targets(frame: &HostFrame<'_>) -> Result<(u32, u32), EmbedError> {
    let (c, d) = (frame.color.texture(), frame.depth.texture());
    check_color_format(c.format())?;
    check_depth_format(d.format())?;
    for (what, t, usage) in [
        ("colour", c, wgpu::TextureUsages::RENDER_ATTACHMENT),
        ("depth", d, wgpu::TextureUsages::TEXTURE_BINDING),
    ] {
        if !t.usage().contains(usage) {
            return Err(EmbedError::Usage {
                what,
                missing: usage,
            });
        }
        if t.sample_count() != 1 {
            return Err(EmbedError::Multisampled {
                what,
                samples: t.sample_count(),
            });
        }
    }
    let (cs, ds) = ((c.width(), c.height()), (d.width(), d.height()));
    if cs != ds {
        return Err(EmbedError::SizeMismatch {
            color: cs,
            depth: ds,
        });
    }
    Ok(cs)
}
