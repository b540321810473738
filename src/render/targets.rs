//! Render targets, by the output size's lifetime: the frame sets the march (or the reproject
//! stage) writes and the exposure and present stages read, the cut-ray mask, the headless
//! output, and a reprojected frame's history (the subset march and a second frame set, ping-
//! pong). Made again only when the output size (or the subset cell) changes
//! (`Renderer::targets`), and a reprojected frame's plan (`Renderer::plan_reprojection`).

use super::camera::View;
use super::frame::FrameUniforms;
use super::gpu::Gpu;
use super::settings::{Reprojection, Settings};
use super::texture::texture_2d;
use super::{exposure, march, present, reproject, resolve, Renderer};

/// One full-size frame's textures: what the march (or the reproject stage) writes and the
/// exposure and present stages read.
pub(super) struct FrameSet {
    /// Premultiplied linear cloud radiance and opacity.
    pub(super) cloud: wgpu::Texture,
    /// The background's linear radiance and each pixel's distance (km).
    pub(super) scene: wgpu::Texture,
    /// The march writing this set at full size (every pixel).
    pub(super) march_bind: wgpu::BindGroup,
    pub(super) present_bind: wgpu::BindGroup,
    pub(super) exposure_bind: wgpu::BindGroup,
    /// Made on the first frame that enlarges this set into its target.
    pub(super) enlarged: Option<Enlarged>,
}

/// A frame set enlarged into its target: its march resolved and composited at its own size
/// (render::resolve: linear radiance as shown, before the exposure)
/// and the present stage's bind group reading that picture instead of the march's.
pub(super) struct Enlarged {
    /// Held for the bind groups.
    _resolved: wgpu::Texture,
    pub(super) resolve_bind: [wgpu::BindGroup; 2],
    pub(super) present_bind: wgpu::BindGroup,
}

impl FrameSet {
    pub(super) fn new(
        r: Stages<'_>,
        size: (u32, u32),
        rays: march::RayBuffers<'_>,
        far: &wgpu::Buffer,
    ) -> FrameSet {
        let (cloud, scene) = frame_textures(r.gpu, size);
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (cv, sv) = (view(&cloud), view(&scene));
        FrameSet {
            march_bind: r
                .march
                .bind_target(r.gpu, (&cv, &sv), rays, far, &r.exposure.state),
            present_bind: r.present.bind_target(r.gpu, &cv, &sv),
            exposure_bind: r.exposure.bind_target(r.gpu, &cv, &sv),
            cloud,
            scene,
            enlarged: None,
        }
    }

    /// This set's [`Enlarged`] textures and bind groups, made on first use.
    pub(super) fn enlarged(
        &mut self,
        gpu: &Gpu,
        resolve: &resolve::ResolvePass,
        present: &present::PresentPass,
        size: (u32, u32),
    ) -> &Enlarged {
        let FrameSet {
            cloud,
            scene,
            enlarged,
            ..
        } = self;
        enlarged.get_or_insert_with(|| {
            let resolved = texture_2d(
                &gpu.device,
                "resolved cloud",
                size,
                march::CLOUD_FORMAT,
                wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
            );
            let view = |t: &wgpu::Texture| t.create_view(&Default::default());
            let (cv, sv, rv) = (view(cloud), view(scene), view(&resolved));
            Enlarged {
                resolve_bind: resolve.bind_target(gpu, &cv, &sv, &rv),
                present_bind: present.bind_target(gpu, &rv, &sv),
                _resolved: resolved,
            }
        })
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
pub(super) struct Stages<'a> {
    pub(super) gpu: &'a Gpu,
    pub(super) march: &'a march::MarchPass,
    pub(super) present: &'a present::PresentPass,
    pub(super) exposure: &'a exposure::ExposurePass,
    pub(super) reproject: &'a reproject::ReprojectPass,
}

/// A reprojected frame's extra textures: the subset march and a second full-size frame, so
/// each frame is made from the one before (ping-pong).
pub(super) struct History {
    /// Subset cell side (px).
    pub(super) n: u32,
    /// The subset march: one texel per cell.
    pub(super) fresh_march_bind: wgpu::BindGroup,
    pub(super) cells: (u32, u32),
    /// The second full-size frame (the first is `Targets::frame`).
    pub(super) other: FrameSet,
    /// `reproject_bind[k]` writes frame k from the fresh subset and frame 1 − k.
    pub(super) reproject_bind: [wgpu::BindGroup; 2],
    /// The frame the last reprojected frame wrote, and what it was made of.
    pub(super) shown: usize,
    pub(super) last: Option<reproject::FrameKey>,
    /// Reprojected frames made: the subset order's position.
    pub(super) frames: u32,
    /// Why the last frame did not use its history (`None`: it did).
    pub(super) last_reset: Option<&'static str>,
    /// Frames the camera has stood still (0: it moved this frame; see
    /// `reproject::ReprojectParams::still`).
    pub(super) still: u32,
    /// The last full march (every pixel) was at this still view's camera.
    pub(super) whole: bool,
}

impl History {
    pub(super) fn new(
        r: Stages<'_>,
        (width, height): (u32, u32),
        n: u32,
        first: &FrameSet,
        rays: march::RayBuffers<'_>,
        far: &wgpu::Buffer,
    ) -> History {
        let cells = (width.div_ceil(n), height.div_ceil(n));
        let (fc, fs) = frame_textures(r.gpu, cells);
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let other = FrameSet::new(r, (width, height), rays, far);
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
            // A subset march's pixels are full-size pixels: the same reach per pixel.
            fresh_march_bind: r.march.bind_target(
                r.gpu,
                (&fresh[0], &fresh[1]),
                rays,
                far,
                &r.exposure.state,
            ),
            cells,
            other,
            reproject_bind,
            shown: 0,
            last: None,
            frames: 0,
            last_reset: Some("first frame"),
            still: 0,
            whole: false,
        }
    }
}

/// Everything whose lifetime is the output size: made again only when the size changes.
pub(super) struct Targets {
    pub(super) width: u32,
    pub(super) height: u32,
    /// The full-size frame a frame that marches every pixel writes.
    pub(super) frame: FrameSet,
    /// Headless output; made on first use.
    pub(super) color: Option<wgpu::Texture>,
    /// One bit per march pixel: the ray was cut short (see `Stats::cut_rays`).
    pub(super) cut_mask: wgpu::Buffer,
    /// The pixels the march leaves for its second dispatch (march::rework_buffer).
    pub(super) rework: wgpu::Buffer,
    /// Each pixel's farthest reach (m): a host's depth (render::embed) or the one unlimited
    /// value.
    pub(super) far: wgpu::Buffer,
    /// Made on the first reprojected frame at this size.
    pub(super) history: Option<History>,
    /// Whether the last frame was reprojected (it then shows `history`'s frame `shown`).
    pub(super) reprojected: bool,
    /// Whether the last frame marched a subset of its pixels (its cut mask is per cell).
    pub(super) subset_marched: bool,
}

impl Targets {
    pub(super) fn new(r: Stages<'_>, size: (u32, u32)) -> Targets {
        Targets::with_far(r, size, r.march.unlimited.clone())
    }

    /// Targets whose rays stop at `far` (m per pixel, row-major at this size).
    pub(super) fn with_far(
        r: Stages<'_>,
        (width, height): (u32, u32),
        far: wgpu::Buffer,
    ) -> Targets {
        let cut_mask = march::cut_mask_buffer(r.gpu, width, height);
        let rework = march::rework_buffer(r.gpu, width, height);
        let rays = march::RayBuffers {
            cut_mask: &cut_mask,
            rework: &rework,
        };
        Targets {
            width,
            height,
            frame: FrameSet::new(r, (width, height), rays, &far),
            color: None,
            cut_mask,
            rework,
            far,
            history: None,
            reprojected: false,
            subset_marched: false,
        }
    }

    /// The march's bind group writing frame set `set` (0: `frame`, 1: the history's other),
    /// or the history's subset march when `fresh`.
    pub(super) fn march_bind(&self, set: usize, fresh: bool) -> &wgpu::BindGroup {
        match &self.history {
            Some(h) if fresh => &h.fresh_march_bind,
            Some(h) if set == 1 => &h.other.march_bind,
            _ => &self.frame.march_bind,
        }
    }

    /// The frame the last encoded frame showed.
    pub(super) fn shown(&self) -> &FrameSet {
        match &self.history {
            Some(h) if self.reprojected && h.shown == 1 => &h.other,
            _ => &self.frame,
        }
    }

    pub(super) fn shown_mut(&mut self) -> &mut FrameSet {
        match &mut self.history {
            Some(h) if self.reprojected && h.shown == 1 => &mut h.other,
            _ => &mut self.frame,
        }
    }
}

/// How a reprojected frame is made (`Renderer::plan_reprojection`).
pub(super) struct ReprojectionPlan {
    /// The history does not fit and every pixel is marched.
    pub(super) full: bool,
    pub(super) params: reproject::ReprojectParams,
}

/// How a frame's march is dispatched (`Renderer::march_step`).
pub(super) struct MarchStep {
    /// The frame set it writes (0: `Targets::frame`, 1: the history's other).
    pub(super) set: usize,
    /// A subset march (one pixel per cell), the rest reprojected with these parameters.
    pub(super) reproject: Option<reproject::ReprojectParams>,
    /// Invocations: the pixels, or the subset cells.
    pub(super) dispatch: (u32, u32),
}

/// The targets' lifetimes: made for an output size, a history for a reprojected frame.
impl Renderer {
    /// The targets for a `width`×`height` march, made when the size changes.
    pub(super) fn targets(&mut self, width: u32, height: u32) -> &mut Targets {
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
    pub(super) fn split(&mut self) -> (Stages<'_>, &mut Option<Targets>) {
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

    /// Which frame set this frame writes and how its march is dispatched; a subset march puts
    /// its cell and offset in `uniforms`.
    pub(super) fn march_step(
        &self,
        plan: Option<&ReprojectionPlan>,
        uniforms: &mut FrameUniforms,
        size: (u32, u32),
    ) -> MarchStep {
        let history = self.targets.as_ref().and_then(|t| t.history.as_ref());
        match (plan, history) {
            (Some(p), Some(h)) if !p.full => {
                let rank = reproject::rank(h.still, h.frames);
                let [ox, oy] = reproject::subset_offset(h.n, rank);
                uniforms.subset_n = h.n as f32;
                uniforms.subset_offset = [ox as f32, oy as f32];
                // An enlarged march's pixel stands for several of the view's: a still view's
                // later marches of it spread over it. At the view's own size the march keeps
                // its pixel's centre, as the full march does.
                // (A params without history is a moving view's: still 0, the centre.)
                let q = &p.params;
                if uniforms.march_scale < super::frame::ENLARGED_BELOW {
                    [uniforms.sample_dx, uniforms.sample_dy] =
                        reproject::still_sample_offset(h.n, q.still, q.max_age, q.whole != 0);
                }
                // No grazing rays in a subset march at the target's size: its workgroup's
                // neighbours are n pixels apart and differ more often, so nearly every grazing
                // pixel took them (the East Asia cruise at `balanced`: a third more steps and
                // wall time a frame). An enlarged one keeps them (frame::build): there a march
                // pixel is several target pixels tall, and a frame marches few rays.
                if uniforms.march_scale >= super::frame::ENLARGED_BELOW {
                    uniforms.flags &= !super::frame::flags::GRAZE;
                }
                MarchStep {
                    set: 1 - h.shown,
                    reproject: Some(p.params),
                    dispatch: h.cells,
                }
            }
            (Some(_), Some(h)) => MarchStep {
                set: 1 - h.shown,
                reproject: None,
                dispatch: size,
            },
            _ => MarchStep {
                set: 0,
                reproject: None,
                dispatch: size,
            },
        }
    }

    /// Make the targets for this frame and decide how it is made: `None` marches every pixel;
    /// else a reprojected frame, `full` when its history does not fit and the settings ask
    /// for a full march then. Records the frame as the next one's history.
    pub(super) fn plan_reprojection(
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
            let rays = march::RayBuffers {
                cut_mask: &t.cut_mask,
                rework: &t.rework,
            };
            t.history = Some(History::new(stages, size, n, &t.frame, rays, &t.far));
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
        let mut age = u32::MAX;
        h.still = match &h.last {
            Some(last) if misfit.is_none() && reproject::same_view(&last.camera, camera) => {
                let dt = (settings.time - last.time).num_milliseconds() as f64 * 1e-3;
                age = reproject::max_age(dt);
                h.still.saturating_add(1)
            }
            // A frame without history marches rank 0: a still view goes on from it.
            _ if misfit.is_some() => 1,
            _ => 0,
        };
        let full = misfit.is_some() && full_reset;
        if full {
            h.whole = true;
        } else if misfit.is_some() || h.still == 0 {
            h.whole = false;
        }
        let params = reproject::params(
            h.last.as_ref(),
            camera,
            misfit.is_none(),
            (h.still, age, h.whole),
        );
        h.last_reset = misfit;
        h.last = Some(now);
        Some(ReprojectionPlan { full, params })
    }
}
