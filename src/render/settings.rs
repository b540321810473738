//! A frame's settings (everything but where the camera is), their defaults and their
//! validation, and how a frame is made from the ones before it ([`Reprojection`]).

use chrono::{DateTime, Utc};
use glam::DVec3;

use super::preset::{MarchParams, Preset};
use super::RenderError;

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

/// Largest reprojection cell side (px): the window at render scale 0.125 with a 4-px preset.
pub const MAX_SUBSET: u32 = 32;

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
        // The presets use 1–4; a window at a render scale under 1 reprojects at its own size in
        // cells of the preset's side over the scale (render scale ¼: 16).
        if !(m.subset.is_power_of_two() && m.subset <= MAX_SUBSET) {
            return bad(format!(
                "reprojection subset {} must be a power of two up to {MAX_SUBSET} pixels a side",
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
