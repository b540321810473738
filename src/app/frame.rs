//! One window frame, step by step: move the pilot (or put it where the followed simulator's
//! aircraft is), build the panel and HUD, act on what the
//! user asked, record the clouds and egui into the surface, submit, then take whatever frame
//! statistics the GPU has finished (never waiting for them) and save a screenshot if asked.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::anyhow;
use chrono::Utc;

use super::panel::{self, Actions, Hud};
use super::pilot;
use super::{App, Running};
use crate::follow::Status;
use crate::render::readback::Pending;
use crate::render::{Settings, View};

/// What the UI step produced for the rest of the frame.
struct UiFrame {
    settings: Settings,
    output: egui::FullOutput,
    actions: Actions,
    /// Where the view beside the panel ends (px from the window's left edge).
    view_right_px: f32,
}

impl App {
    pub(super) fn frame(&mut self) -> anyhow::Result<()> {
        let frames_wanted = self.opts.frames;
        let Some(r) = self.run.as_mut() else {
            return Ok(());
        };
        let dt = r.clock.tick();
        let following = self
            .opts
            .follow
            .as_mut()
            .map(|f| pilot::follow(&mut r.pilot, f, Instant::now()));
        if let Some(path) = &self.opts.path {
            let start = *r.path_start.get_or_insert_with(Instant::now);
            let t = start.elapsed().as_secs_f64() % path.duration().max(1e-3);
            pilot::fly_path(&mut r.pilot, path, t);
        } else if !r.controls.paused && frames_wanted.is_none() && following.is_none() {
            r.pilot.step(&r.input.keys, dt);
        }
        r.controls.advance_time(dt);
        let mut ui = r.build_ui(following.as_ref().map(Status::line));
        r.act(&ui.actions, &mut self.opts);
        r.weather_at(&mut ui.settings);
        pilot::keep_above_ground(&mut r.pilot, &self.opts.map);
        let (tw, th) = (r.screen.config.width, r.screen.config.height);
        if tw == 0 || th == 0 {
            return Ok(());
        }
        let Some(surface) = r.acquire()? else {
            return Ok(());
        };
        let target = surface.texture.create_view(&Default::default());
        // The clouds are drawn beside the panel, not under it: the camera's view is what the
        // user sees, centred on its heading, and the panel's quarter is not marched.
        let tw = (ui.view_right_px.ceil() as u32).clamp(1, tw);
        let device = r.renderer.gpu.device.clone();
        let mut enc = device.create_command_encoder(&Default::default());
        let view = View::Perspective(r.pilot.camera());
        // At a render scale under 1: with --super-resolution a reprojected window marches in
        // cells of its own size, else the march at the scale is enlarged.
        let scale = r.controls.render_scale;
        let (march, settings) = if self.opts.super_resolution {
            crate::scaled::plan((tw, th), scale, &view, &ui.settings)
        } else {
            (
                crate::scaled::march_size((tw, th), scale),
                ui.settings.clone(),
            )
        };
        r.march_size = march;
        r.renderer.encode(
            &mut enc,
            &view,
            march.0,
            march.1,
            &settings,
            &target,
            r.screen.config.format,
            (tw, th),
        )?;
        r.renderer.request_stats(&mut enc);
        let extra = r.draw_ui(&mut enc, &target, ui.output);
        r.clock.frames += 1;
        let last = frames_wanted.is_some_and(|n| r.clock.frames >= n);
        let shot = r.queue_screenshot(&mut enc, &surface.texture, last, &self.opts.screenshot)?;
        r.renderer
            .gpu
            .queue
            .submit(extra.into_iter().chain([enc.finish()]));
        r.renderer.after_submit();
        if let Some(fs) = r.renderer.poll_stats() {
            r.clock.gpu_time(fs.gpu_ms());
        }
        if let Some((pending, path)) = shot {
            r.save_screenshot(pending, &path)?;
        }
        r.renderer.gpu.queue.present(surface);
        Ok(())
    }
}

impl Running {
    /// The panel and HUD for this frame, and the settings they give.
    fn build_ui(&mut self, follow: Option<String>) -> UiFrame {
        // The HUD shows what the last frame drew; the settings and march size are taken after
        // the panel, so a slider moved now is drawn this frame.
        let shown = self.controls.settings(self.valid_time, self.clock.frames);
        let hud = Hud {
            lat: self.pilot.lat,
            lon: self.pilot.lon,
            alt_m: self.pilot.alt_m,
            heading: self.pilot.heading,
            speed: self.pilot.speed,
            utc: shown.time,
            fps: self.clock.fps(),
            gpu_ms: self.clock.gpu_ms,
            frame_ms: self.clock.frame_ms,
            adapter: self.renderer.gpu.info.name.clone(),
            march_size: self.march_size,
            follow,
            weather: self.weather_line(shown.time),
            daylight: super::daylight::note(shown.time, self.pilot.lat, self.pilot.lon),
        };
        let input = self.ui.state.take_egui_input(&self.screen.window);
        let mut actions = Actions::default();
        let mut view_right = f32::MAX;
        let controls = &mut self.controls;
        let output = self.ui.ctx.run_ui(input, |ui| {
            actions = panel::panel(ui, controls);
            view_right = ui.available_rect_before_wrap().max.x;
            panel::hud(ui, &hud);
        });
        let view_right_px = view_right * output.pixels_per_point;
        let settings = self.controls.settings(self.valid_time, self.clock.frames);
        UiFrame {
            settings,
            output,
            actions,
            view_right_px,
        }
    }

    /// Teleport, re-derive the map for a new rh_cr, note a screenshot request.
    fn act(&mut self, actions: &Actions, opts: &mut super::FlyOptions) {
        if let Some((lat, lon, alt)) = actions.teleport {
            self.pilot.lat = lat;
            self.pilot.lon = lon;
            self.pilot.alt_m = alt;
        }
        if actions.rh_cr_changed {
            if let Some(plan) = opts.plan.as_mut() {
                match plan.set_rh_cr(self.controls.rh_cr) {
                    Ok(()) => {
                        let map = plan.build();
                        self.renderer.set_map(&map);
                        opts.map = map;
                    }
                    Err(e) => self.controls.status = e.to_string(),
                }
            }
        }
        self.want_shot |= actions.screenshot;
    }

    /// The surface's next texture; `None` when this frame is to be skipped.
    fn acquire(&mut self) -> anyhow::Result<Option<wgpu::SurfaceTexture>> {
        Ok(match self.screen.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f)
            | wgpu::CurrentSurfaceTexture::Suboptimal(f) => Some(f),
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => None,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.screen
                    .surface
                    .configure(&self.renderer.gpu.device, &self.screen.config);
                None
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(anyhow!("the window surface reported a validation error"));
            }
        })
    }

    /// Record the panel and HUD over the frame (app::overlay); returns egui's own command
    /// buffers.
    fn draw_ui(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        mut out: egui::FullOutput,
    ) -> Vec<wgpu::CommandBuffer> {
        let platform = std::mem::take(&mut out.platform_output);
        self.ui
            .state
            .handle_platform_output(&self.screen.window, platform);
        let gpu = &self.renderer.gpu;
        let size = [self.screen.config.width, self.screen.config.height];
        let (extra, _) = self.ui.overlay.draw(
            &gpu.device,
            &gpu.queue,
            enc,
            target,
            size,
            &self.ui.ctx,
            out,
        );
        extra
    }

    /// Queue a copy of the frame when a screenshot is due (F12, or the last `--frames` frame).
    fn queue_screenshot(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        frame: &wgpu::Texture,
        last: bool,
        scripted_path: &Option<PathBuf>,
    ) -> anyhow::Result<Option<(Pending, PathBuf)>> {
        let scripted = last && scripted_path.is_some();
        if !(scripted || self.want_shot) {
            return Ok(None);
        }
        if !self.screen.can_read {
            const NO: &str =
                "this window surface cannot be read back for a screenshot; use `stratus render`";
            if scripted {
                return Err(anyhow!(NO));
            }
            // F12 in a live window: say so on the panel, keep flying.
            self.controls.status = NO.into();
            self.want_shot = false;
            return Ok(None);
        }
        let path = match (scripted_path, last) {
            (Some(p), true) => p.clone(),
            _ => PathBuf::from(format!(
                "stratus-{}.png",
                Utc::now().format("%Y%m%d-%H%M%S")
            )),
        };
        Ok(Some((
            Pending::texture(&self.renderer.gpu, enc, frame, 4),
            path,
        )))
    }

    fn save_screenshot(&mut self, pending: Pending, path: &std::path::Path) -> anyhow::Result<()> {
        let mut px = pending.finish(&self.renderer.gpu)?;
        if matches!(
            self.screen.config.format,
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        ) {
            for c in px.chunks_exact_mut(4) {
                c.swap(0, 2);
            }
        }
        let (w, h) = (self.screen.config.width, self.screen.config.height);
        let img = image::RgbaImage::from_raw(w, h, px).ok_or_else(|| anyhow!("screenshot size"))?;
        crate::picture::save_png(path, &img)?;
        self.controls.status = format!("saved {}", path.display());
        self.want_shot = false;
        Ok(())
    }
}
