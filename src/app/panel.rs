//! The operator's control panel (seed 002 §3.6) and the HUD, in egui.

use chrono::{DateTime, Duration, Utc};

use super::moment::Rate;
use crate::render::{Preset, Reprojection, Settings};

/// What the panel edits, kept between frames.
pub struct Controls {
    pub preset: Preset,
    /// Hours added to the forecast's valid time (a series' first step).
    pub time_offset_h: f64,
    /// The time slider's ends (hours, as `time_offset_h`) and its label (super::moment).
    pub time_range_h: (f64, f64),
    pub time_label: &'static str,
    /// How fast time runs.
    pub time_rate: Rate,
    pub layers_on: [bool; 3],
    /// Which layers the map has (only those get a checkbox and an rh_cr slider).
    pub present: [bool; 3],
    /// Critical humidity per layer; editable when RH is held in memory (a GRIB2 was loaded).
    pub rh_cr: [f64; 3],
    pub rh_cr_editable: bool,
    pub coverage: f32,
    pub density: f32,
    pub extinction: f32,
    pub hg_g: f32,
    pub sun_override: bool,
    pub sun_azimuth: f64,
    pub sun_elevation: f64,
    pub exposure: f64,
    /// March resolution relative to the window.
    pub render_scale: f32,
    /// March a subset of the pixels each frame and reproject the rest (render::reproject).
    pub reproject: bool,
    /// Meteorological visibility (km) for the haze.
    pub visibility_km: f64,
    pub paused: bool,
    pub teleport: String,
    pub status: String,
}

/// What the user asked for this frame.
#[derive(Default)]
pub struct Actions {
    pub teleport: Option<(f64, f64, f64)>,
    pub rh_cr_changed: bool,
    pub screenshot: bool,
}

/// Read-outs for the HUD.
pub struct Hud {
    pub lat: f64,
    pub lon: f64,
    pub alt_m: f64,
    pub heading: f64,
    pub speed: f64,
    pub utc: DateTime<Utc>,
    pub fps: f64,
    pub gpu_ms: Option<f64>,
    pub frame_ms: f64,
    pub adapter: String,
    pub march_size: (u32, u32),
    /// `--follow`'s status line.
    pub follow: Option<String>,
    /// A series: the valid time and the steps around it.
    pub weather: Option<String>,
    /// Why the picture is dark: the Sun low or down here (super::daylight).
    pub daylight: Option<String>,
}

impl Controls {
    /// Take the layers and their critical humidities from a (new) map.
    pub fn set_map(&mut self, map: &stratus_ingest::cloudmap::CloudMap) {
        self.present = [false; 3];
        for l in &map.meta.layers {
            self.present[l.channel] = true;
            self.rh_cr[l.channel] = l.rh_cr;
        }
    }

    pub fn new(preset: Preset, rh_cr: [f64; 3], rh_cr_editable: bool, cpu: bool) -> Controls {
        // The look starts at the renderer's defaults (defined once, in Settings::new).
        let d = Settings::new(preset, DateTime::<Utc>::UNIX_EPOCH);
        Controls {
            preset,
            time_offset_h: 0.0,
            time_range_h: (-24.0, 24.0),
            time_label: "time (h from valid)",
            time_rate: Rate::Paused,
            layers_on: d.layers_on,
            present: [true; 3],
            rh_cr,
            rh_cr_editable,
            coverage: d.coverage_mul,
            density: d.density_mul,
            extinction: d.extinction,
            hg_g: d.hg_g,
            sun_override: false,
            sun_azimuth: 135.0,
            sun_elevation: 45.0,
            exposure: d.exposure_ev,
            render_scale: default_render_scale(cpu),
            reproject: true,
            visibility_km: d.visibility_m / 1000.0,
            paused: false,
            teleport: String::new(),
            status: String::new(),
        }
    }

    /// Settings for this frame from the panel and the forecast's valid time.
    pub fn settings(&self, valid: DateTime<Utc>, frame: u32) -> Settings {
        let mut s = Settings::new(
            self.preset,
            valid + Duration::seconds((self.time_offset_h * 3600.0) as i64),
        );
        s.layers_on = self.layers_on;
        s.coverage_mul = self.coverage;
        s.density_mul = self.density;
        s.extinction = self.extinction;
        s.hg_g = self.hg_g;
        // The panel's EV is an offset over the adapted exposure; the eye adapts over ~10 frames.
        s.exposure_ev = self.exposure;
        s.exposure_rate = WINDOW_ADAPTATION;
        s.frame_index = frame;
        s.visibility_m = self.visibility_km * 1000.0;
        if self.reproject {
            // A teleport or a new map: the fresh subset, upsampled, until the history fills
            // again (a full march would stall the window for a frame).
            s.reprojection = Reprojection::On { full_reset: false };
        }
        if self.sun_override {
            let (a, e) = (
                self.sun_azimuth.to_radians(),
                self.sun_elevation.to_radians(),
            );
            s.sun_override = Some(glam::DVec3::new(
                e.cos() * a.sin(),
                e.cos() * a.cos(),
                e.sin(),
            ));
        }
        s
    }
}

/// The march's size relative to the window when none is given: the whole window on a GPU; on a
/// CPU adapter ¼, where reprojection (one pixel of each 4×4 cell marched a frame, the rest kept
/// from the frames before) makes a 1280×720 window fly at about 19 fps over the real East Asia
/// map on 2 cores, against 4 fps marching every pixel (docs/fly.md). ½ looks sharper at about
/// 9 fps: the panel's slider or `fly --render-scale 0.5`.
pub fn default_render_scale(cpu: bool) -> f32 {
    if cpu {
        0.25
    } else {
        1.0
    }
}

/// Share of the way (in stops) to the metered exposure the window goes each frame.
pub const WINDOW_ADAPTATION: f32 = 0.1;

/// Local mean solar time at a longitude, as HH:MM.
pub fn solar_time(utc: DateTime<Utc>, lon: f64) -> String {
    let t = utc + Duration::seconds((lon / 15.0 * 3600.0) as i64);
    t.format("%H:%M").to_string()
}

pub fn hud(ui: &mut egui::Ui, h: &Hud) {
    // Clipped to the view beside the panel: its shapes then make a mesh of their own, which
    // the overlay redraws alone as the numbers change (app::overlay).
    let view = ui.available_rect_before_wrap();
    egui::Area::new(egui::Id::unique("hud"))
        .fixed_pos(egui::pos2(10.0, 10.0))
        .show(ui.ctx(), |ui| {
            ui.set_clip_rect(view);
            egui::Frame::popup(ui.style()).show(ui, |ui| {
                if let Some(f) = &h.follow {
                    ui.monospace(f);
                }
                ui.monospace(format!("LAT {:>9.4}°  LON {:>9.4}°", h.lat, h.lon));
                ui.monospace(format!("ALT {:>7.0} m    HDG {:>5.1}°", h.alt_m, h.heading));
                ui.monospace(format!(
                    "SPD {:>5.0} m/s ({:.0} kt)",
                    h.speed,
                    h.speed * 1.943_844
                ));
                ui.monospace(format!(
                    "UTC {}  solar {}",
                    h.utc.format("%Y-%m-%d %H:%M"),
                    solar_time(h.utc, h.lon)
                ));
                if let Some(d) = &h.daylight {
                    ui.colored_label(egui::Color32::from_rgb(255, 200, 90), d);
                }
                if let Some(w) = &h.weather {
                    ui.monospace(w);
                }
                ui.monospace(format!(
                    "{:.1} fps  frame {:.0} ms  GPU {}",
                    h.fps,
                    h.frame_ms,
                    h.gpu_ms.map_or("n/a".into(), |g| format!("{g:.2} ms"))
                ));
                ui.small(format!(
                    "{}  march {}×{}",
                    h.adapter, h.march_size.0, h.march_size.1
                ));
            });
        });
}

pub fn panel(ui: &mut egui::Ui, c: &mut Controls) -> Actions {
    let mut act = Actions::default();
    egui::Panel::right("controls")
        .default_size(260.0)
        .show(ui, |ui| {
            ui.heading("Stratus");
            quality_and_time(ui, c);
            ui.separator();
            layers(ui, c, &mut act);
            ui.separator();
            look(ui, c);
            ui.separator();
            teleport(ui, c, &mut act);
            ui.horizontal(|ui| {
                ui.checkbox(&mut c.paused, "pause (Space)");
                if ui.button("screenshot (F12)").clicked() {
                    act.screenshot = true;
                }
            });
            ui.separator();
            ui.small(
                "W/S throttle · Up/Down pitch · Left/Right bank · A/D yaw · right-drag look · Shift fast",
            );
            if !c.status.is_empty() {
                ui.label(&c.status);
            }
        });
    act
}

/// The panel's first group: quality, render scale, reprojection, visibility and the clock.
fn quality_and_time(ui: &mut egui::Ui, c: &mut Controls) {
    egui::ComboBox::from_label("quality")
        .selected_text(c.preset.name())
        .show_ui(ui, |ui| {
            for p in Preset::ALL {
                ui.selectable_value(&mut c.preset, p, p.name());
            }
        });
    ui.add(egui::Slider::new(&mut c.render_scale, 0.1..=1.0).text("render scale"));
    ui.checkbox(&mut c.reproject, "reprojection (march a subset a frame)");
    ui.add(
        egui::Slider::new(&mut c.visibility_km, 1.0..=200.0)
            .logarithmic(true)
            .text("visibility (km)"),
    );
    let (lo, hi) = c.time_range_h;
    ui.add(egui::Slider::new(&mut c.time_offset_h, lo..=hi).text(c.time_label));
    ui.horizontal(|ui| {
        ui.label("time runs");
        for r in Rate::ALL {
            ui.selectable_value(&mut c.time_rate, r, r.name());
        }
    });
}

/// The layers present, each switchable, and their rh_cr where the RH field is at hand.
fn layers(ui: &mut egui::Ui, c: &mut Controls, act: &mut Actions) {
    ui.label("layers");
    ui.horizontal(|ui| {
        for (k, name) in ["low", "middle", "high"].iter().enumerate() {
            if c.present[k] {
                ui.checkbox(&mut c.layers_on[k], *name);
            }
        }
    });
    ui.add_enabled_ui(c.rh_cr_editable, |ui| {
        for (k, name) in ["rh_cr low", "rh_cr middle", "rh_cr high"]
            .iter()
            .enumerate()
            .filter(|(k, _)| c.present[*k])
        {
            if ui
                .add(egui::Slider::new(&mut c.rh_cr[k], 0.0..=0.99).text(*name))
                .changed()
            {
                act.rh_cr_changed = true;
            }
        }
    });
    if !c.rh_cr_editable {
        ui.small("rh_cr needs the RH field: open a GRIB2 file (drop one here)");
    }
}

/// The look: coverage and density multipliers, absorption, phase, exposure, the Sun.
fn look(ui: &mut egui::Ui, c: &mut Controls) {
    ui.add(egui::Slider::new(&mut c.coverage, 0.0..=3.0).text("coverage ×"));
    ui.add(egui::Slider::new(&mut c.density, 0.0..=5.0).text("density ×"));
    ui.add(
        egui::Slider::new(&mut c.extinction, 0.001..=0.2)
            .logarithmic(true)
            .text("absorption"),
    );
    ui.add(egui::Slider::new(&mut c.hg_g, -0.9..=0.9).text("HG g"));
    ui.add(egui::Slider::new(&mut c.exposure, -6.0..=6.0).text("exposure EV"));
    ui.checkbox(&mut c.sun_override, "sun override");
    ui.add_enabled_ui(c.sun_override, |ui| {
        ui.add(egui::Slider::new(&mut c.sun_azimuth, 0.0..=360.0).text("sun azimuth"));
        ui.add(egui::Slider::new(&mut c.sun_elevation, -20.0..=90.0).text("sun elevation"));
    });
}

/// The teleport field and its button: a position typed as `lat, lon, alt_m`, checked.
fn teleport(ui: &mut egui::Ui, c: &mut Controls, act: &mut Actions) {
    ui.horizontal(|ui| {
        ui.label("teleport");
        ui.text_edit_singleline(&mut c.teleport)
            .on_hover_text("lat, lon, alt_m");
    });
    if ui.button("go").clicked() {
        let v: Vec<f64> = c
            .teleport
            .split(',')
            .filter_map(|p| p.trim().parse().ok())
            .collect();
        if v.len() == 3
            && v.iter().all(|x| x.is_finite())
            && (-90.0..=90.0).contains(&v[0])
            && v[2] >= 0.0
        {
            act.teleport = Some((v[0], v[1], v[2]));
        } else {
            c.status = "teleport: give lat, lon, alt_m (alt ≥ 0)".into();
        }
    }
}
