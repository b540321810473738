//! A forecast series flown through time (DESIGN §9): which two steps the renderer holds for the
//! scene's moment, the step after them loaded ahead on a background thread so crossing into the
//! next interval costs an upload and no decode, and how far each layer's noise has drifted with
//! its wind since the series' first step.
//!
//! The drift is the time integral of each layer's region-mean wind, interpolated linearly
//! between steps (held before the first and after the last), so it is continuous through step
//! boundaries: the noise never jumps. One rigid offset per layer (not per pixel) keeps the
//! noise from shearing apart over hours where the wind varies; the coverage itself moves with
//! the per-pixel winds (render::blend).

use std::path::Path;
use std::thread::JoinHandle;

use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::error::Result;
use stratus_ingest::series::meta::show_hour;
use stratus_ingest::series::{is_series, Series};

use crate::render::{RenderError, Renderer};

/// Per layer (low, middle, high): (east, north), m/s or m.
pub type PerLayer = [[f64; 2]; 3];

#[derive(Debug, thiserror::Error)]
pub enum TimelineError {
    #[error(transparent)]
    Map(#[from] stratus_ingest::error::IngestError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("loading a step ahead: the loader thread stopped")]
    Loader,
}

pub struct Timeline {
    pub series: Series,
    /// Each step's valid time and region-mean layer winds.
    means: Vec<(DateTime<Utc>, PerLayer)>,
    /// The interval held on the GPU (steps k, k + 1) and the later step's map, which becomes
    /// the earlier one of the next interval.
    held: Option<(usize, CloudMap)>,
    /// The step after the held pair, loading.
    ahead: Option<(usize, JoinHandle<Result<CloudMap>>)>,
    /// Intervals uploaded so far (a test counts them).
    pub uploads: u32,
}

/// Region-mean wind of each layer of `map` (zero without winds).
pub fn mean_winds(map: &CloudMap) -> PerLayer {
    map.structure
        .as_ref()
        .filter(|s| s.is_whole())
        .map_or([[0.0; 2]; 3], crate::render::structure::mean_wind)
}

/// Step `k` of `series`, its valid time and step the series' (a map may serve several steps
/// of a synthetic series).
fn load_step(series: &Series, k: usize) -> Result<CloudMap> {
    let mut m = series.step_map(k)?;
    let s = &series.steps()[k];
    m.meta.source.valid_time = Some(s.valid_time);
    m.meta.source.forecast_step_h = s.forecast_hour;
    Ok(m)
}

/// What a command draws from `--map` at `time`: the map to start the renderer from (and to read
/// the camera's ground, the layers and, without a time, the valid time from) and, for a series,
/// the timeline that blends its steps on the GPU ([`Timeline::prepare`]). A plain map is loaded
/// as it is; a series gives the step nearer the moment (the first without one), whose structure
/// and ground the blend takes there. No CPU blend: that is [`Series::at`], the reference.
pub fn open_scene(
    path: &Path,
    time: Option<DateTime<Utc>>,
) -> Result<(CloudMap, Option<Timeline>)> {
    if !is_series(path) {
        return Ok((CloudMap::load(path)?, None));
    }
    let tl = Timeline::open(path)?;
    let k = match time {
        Some(t) => {
            let (first, last) = tl.span();
            if t < first || t > last {
                tracing::warn!(
                    "{} is outside the series ({} to {}): the nearest step is held",
                    stratus_ingest::meta::format_time(&t),
                    stratus_ingest::meta::format_time(&first),
                    stratus_ingest::meta::format_time(&last)
                );
            }
            tl.nearer_step(t)
        }
        None => 0,
    };
    let map = load_step(&tl.series, k)?;
    Ok((map, Some(tl)))
}

impl Timeline {
    /// Open the series sidecar `path`; each step's map is read once for its mean winds.
    pub fn open(path: &Path) -> Result<Timeline> {
        let series = Series::load(path)?;
        let mut means = Vec::with_capacity(series.steps().len());
        for (k, s) in series.steps().iter().enumerate() {
            means.push((s.valid_time, mean_winds(&load_step(&series, k)?)));
        }
        Ok(Timeline {
            series,
            means,
            held: None,
            ahead: None,
            uploads: 0,
        })
    }

    /// First and last valid time.
    pub fn span(&self) -> (DateTime<Utc>, DateTime<Utc>) {
        let s = self.series.steps();
        (s[0].valid_time, s[s.len() - 1].valid_time)
    }

    /// The interval (k, k + 1) holding `time`, clamped to the series' ends; `None` for a series
    /// of one step.
    pub fn interval(&self, time: DateTime<Utc>) -> Option<usize> {
        let s = self.series.steps();
        if s.len() < 2 {
            return None;
        }
        let after = s
            .iter()
            .position(|x| x.valid_time > time)
            .unwrap_or(s.len());
        Some(after.saturating_sub(1).min(s.len() - 2))
    }

    /// The step nearer `time` (the earlier one before mid-interval, as the blend takes the
    /// genus), clamped to the series' ends.
    pub fn nearer_step(&self, time: DateTime<Utc>) -> usize {
        let Some(k) = self.interval(time) else {
            return 0;
        };
        let s = self.series.steps();
        let (t0, t1) = (s[k].valid_time, s[k + 1].valid_time);
        if time - t0 < (t1 - t0) / 2 {
            k
        } else {
            k + 1
        }
    }

    /// The steps around `time` as the window's HUD shows them: `+0 h → +6 h` (`+0 h` for a
    /// series of one step).
    pub fn steps_text(&self, time: DateTime<Utc>) -> String {
        let s = self.series.steps();
        match self.interval(time) {
            Some(k) => format!(
                "{} → {}",
                show_hour(s[k].forecast_hour),
                show_hour(s[k + 1].forecast_hour)
            ),
            None => show_hour(s[0].forecast_hour),
        }
    }

    /// The wind cirrus is streaked along through the whole series: the first step's
    /// region-mean winds. One direction for the flight: the streaked noise is measured from the
    /// region's centre, so a direction turning with time would swing it by distance × angle
    /// far from the centre, and the pattern would boil (`Settings::streak_wind`).
    pub fn streak_wind(&self) -> PerLayer {
        self.means[0].1
    }

    /// How far each layer's noise has drifted with its mean wind from the first step to `time`
    /// (east, north m): the integral of the piecewise-linear wind.
    pub fn drift_m(&self, time: DateTime<Utc>) -> PerLayer {
        let secs = |a: DateTime<Utc>, b: DateTime<Utc>| (b - a).num_milliseconds() as f64 / 1e3;
        let m = &self.means;
        let mut out = [[0.0; 2]; 3];
        let mut add = |wa: &PerLayer, wb: &PerLayer, dt: f64, frac: f64| {
            // ∫₀^frac·dt of the wind going linearly from wa to wb over dt.
            for (c, o) in out.iter_mut().enumerate() {
                for x in 0..2 {
                    let (a, b) = (wa[c][x], wb[c][x]);
                    o[x] += dt * (a * frac + 0.5 * (b - a) * frac * frac);
                }
            }
        };
        let (t_first, w_first) = m[0];
        if time <= t_first {
            add(&w_first, &w_first, secs(t_first, time), 1.0);
            return out;
        }
        for pair in m.windows(2) {
            let ((t0, w0), (t1, w1)) = (pair[0], pair[1]);
            let dt = secs(t0, t1);
            if time >= t1 {
                add(&w0, &w1, dt, 1.0);
            } else {
                add(&w0, &w1, dt, secs(t0, time) / dt);
                return out;
            }
        }
        let (t_last, w_last) = m[m.len() - 1];
        add(&w_last, &w_last, secs(t_last, time), 1.0);
        out
    }

    /// Make `r` hold the two steps around `time` (uploading only when the interval changes,
    /// from the map loaded ahead where it can) and return the layers' drift at `time`.
    pub fn prepare(
        &mut self,
        r: &mut Renderer,
        time: DateTime<Utc>,
    ) -> std::result::Result<PerLayer, TimelineError> {
        let Some(k) = self.interval(time) else {
            if self.held.is_none() {
                let m = load_step(&self.series, 0)?;
                r.set_map(&m);
                self.held = Some((0, m));
            }
            return Ok(self.drift_m(time));
        };
        if self.held.as_ref().map(|h| h.0) != Some(k) {
            let a = match self.held.take() {
                Some((j, later)) if j + 1 == k => later,
                _ => load_step(&self.series, k)?,
            };
            let b = match self.ahead.take() {
                Some((j, handle)) if j == k + 1 => {
                    handle.join().map_err(|_| TimelineError::Loader)??
                }
                _ => load_step(&self.series, k + 1)?,
            };
            r.set_pair(&a, &b)?;
            self.uploads += 1;
            self.held = Some((k, b));
            if k + 2 < self.series.steps().len() {
                let series = self.series.clone();
                self.ahead = Some((k + 2, std::thread::spawn(move || load_step(&series, k + 2))));
            }
        }
        Ok(self.drift_m(time))
    }
}
