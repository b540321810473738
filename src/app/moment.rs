//! The scene's moment in the window: the span the time slider covers (a series' first to last
//! valid time, or a day either side of a plain map's), time running at a chosen rate, and for a
//! series the renderer kept on the two steps around the moment (crate::timeline: GPU blend, the
//! next step loaded ahead) with each layer's noise drifted by its wind.

use chrono::{DateTime, Utc};

use super::panel::Controls;
use super::Running;
use crate::render::Settings;
use crate::timeline::Timeline;

/// How fast simulated time runs against wall time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Rate {
    #[default]
    Paused,
    X1,
    X60,
    X600,
}

impl Rate {
    pub const ALL: [Rate; 4] = [Rate::Paused, Rate::X1, Rate::X60, Rate::X600];

    /// Simulated seconds per wall-clock second.
    pub fn factor(self) -> f64 {
        match self {
            Rate::Paused => 0.0,
            Rate::X1 => 1.0,
            Rate::X60 => 60.0,
            Rate::X600 => 600.0,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Rate::Paused => "pause",
            Rate::X1 => "×1",
            Rate::X60 => "×60",
            Rate::X600 => "×600",
        }
    }
}

impl std::str::FromStr for Rate {
    type Err = String;

    fn from_str(s: &str) -> Result<Rate, String> {
        match s.trim_start_matches(['x', '×']) {
            "pause" | "0" => Ok(Rate::Paused),
            "1" => Ok(Rate::X1),
            "60" => Ok(Rate::X60),
            "600" => Ok(Rate::X600),
            _ => Err(format!("unknown time rate \"{s}\" (pause, 1, 60, 600)")),
        }
    }
}

/// Most wall seconds one frame runs time on by: a stall (start-up, a window drag) must not jump
/// the weather by hours at ×600. A CPU adapter's frames (≈ 0.2–0.7 s) stay under it.
pub const MAX_STEP_S: f64 = 1.0;

/// Hours from `base` to `t`.
fn hours(base: DateTime<Utc>, t: DateTime<Utc>) -> f64 {
    (t - base).num_milliseconds() as f64 / 3.6e6
}

/// The time the panel's slider counts from: a series' first step, else the map's valid time.
pub fn slider_base(map_valid: DateTime<Utc>, timeline: Option<&Timeline>) -> DateTime<Utc> {
    timeline.map_or(map_valid, |t| t.span().0)
}

impl Controls {
    /// Point the time slider at a map: over `span` (a series' first and last valid time) or a
    /// day either side of `base`, starting at `start` (`--time`; `base` without one). A start
    /// outside the span widens the slider rather than being moved.
    pub fn set_time(
        &mut self,
        base: DateTime<Utc>,
        start: Option<DateTime<Utc>>,
        span: Option<(DateTime<Utc>, DateTime<Utc>)>,
    ) {
        self.time_offset_h = start.map_or(0.0, |t| hours(base, t));
        let (lo, hi, label) = match span {
            Some((a, b)) if b > a => (hours(base, a), hours(base, b), "time (h from first step)"),
            _ => (-24.0, 24.0, "time (h from valid)"),
        };
        self.time_range_h = (lo.min(self.time_offset_h), hi.max(self.time_offset_h));
        self.time_label = label;
    }

    /// Run time on by `dt_s` wall seconds at the chosen rate, at most [`MAX_STEP_S`] a frame;
    /// at the slider's end it stops.
    pub fn advance_time(&mut self, dt_s: f64) {
        if self.time_rate == Rate::Paused {
            return;
        }
        let (_, hi) = self.time_range_h;
        self.time_offset_h += dt_s.clamp(0.0, MAX_STEP_S) * self.time_rate.factor() / 3600.0;
        if self.time_offset_h >= hi {
            self.time_offset_h = hi;
            self.time_rate = Rate::Paused;
        }
    }
}

impl Running {
    /// For a series, put the renderer on the two steps around this frame's time and drift the
    /// noise. A step that cannot be loaded is said on the panel and the series is let go: the
    /// window keeps flying over what the GPU holds.
    pub(super) fn weather_at(&mut self, settings: &mut Settings) {
        let Some(tl) = self.timeline.as_mut() else {
            return;
        };
        match tl.prepare(&mut self.renderer, settings.time) {
            Ok(drift) => {
                settings.drift_m = drift;
                settings.streak_wind = Some(tl.streak_wind());
            }
            Err(e) => {
                self.controls.status = format!("series: {e}; the weather is held");
                self.timeline = None;
            }
        }
    }

    /// The HUD's weather line for a series: "valid 2015-09-12 21:00 UTC · step +0 h → +6 h",
    /// with the rate while time runs.
    pub(super) fn weather_line(&self, time: DateTime<Utc>) -> Option<String> {
        let tl = self.timeline.as_ref()?;
        let rate = match self.controls.time_rate {
            Rate::Paused => String::new(),
            r => format!(" · {}", r.name()),
        };
        Some(format!(
            "valid {} UTC · step {}{rate}",
            time.format("%Y-%m-%d %H:%M"),
            tl.steps_text(time)
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Preset;

    fn at(h: i64) -> DateTime<Utc> {
        DateTime::<Utc>::UNIX_EPOCH + chrono::Duration::hours(h)
    }

    #[test]
    fn the_slider_spans_the_series_and_time_stops_at_its_end() {
        let mut c = Controls::new(Preset::Fast, [0.8; 3], false, true);
        c.set_time(at(0), Some(at(3)), Some((at(0), at(6))));
        assert_eq!((c.time_offset_h, c.time_range_h), (3.0, (0.0, 6.0)));
        c.time_rate = Rate::X600;
        for _ in 0..6 {
            c.advance_time(1.0); // ten simulated minutes each: one hour
        }
        assert!((c.time_offset_h - 4.0).abs() < 1e-9);
        c.advance_time(60.0); // a stall: at most MAX_STEP_S
        assert!((c.time_offset_h - 4.0 - 600.0 * MAX_STEP_S / 3600.0).abs() < 1e-9);
        for _ in 0..100 {
            c.advance_time(1.0);
        }
        assert_eq!((c.time_offset_h, c.time_rate), (6.0, Rate::Paused));
        // A plain map: a day either side, widened to take a far --time.
        c.set_time(at(0), Some(at(30)), None);
        assert_eq!(c.time_range_h, (-24.0, 30.0));
        assert_eq!("600".parse::<Rate>(), Ok(Rate::X600));
        assert_eq!("x60".parse::<Rate>(), Ok(Rate::X60));
        assert!("7".parse::<Rate>().is_err());
    }
}
