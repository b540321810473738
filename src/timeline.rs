//! A forecast series flown through time (DESIGN §9): which two steps the renderer holds for the
//! scene's moment, the step after them loaded ahead on a background thread so crossing into the
//! next interval costs an upload and no decode, and how far each layer's noise has drifted with
//! its wind since the series' first step.
//!
//! The drift is the time integral of each layer's region-mean wind, interpolated linearly
//! between steps (held before the first and after the last), so it is continuous through step
//! boundaries: the noise never jumps. One rigid offset per layer (not per pixel) keeps the
//! noise from shearing apart over hours where the wind varies; the coverage itself moves along
//! the guarded motion between the two steps (issue 31, render::blend): the stored one, or for a
//! series sidecar from before it, estimated from the two steps when the interval is uploaded
//! (`Series::motion`; seconds for a large map, once per interval).
//!
//! Opening a series costs what its moment needs, whatever the series' length: the step maps
//! around the moment are the only ones decoded, the means come from the series sidecar
//! (`stratus_ingest::series::winds`). An older sidecar without them has each needed step's mean
//! taken from its map (decoded once, from the first step to the moment's interval).

use std::path::Path;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::error::Result;
use stratus_ingest::series::meta::show_hour;
use stratus_ingest::series::winds::map_mean_wind;
use stratus_ingest::series::Series;

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
    /// Each step's valid time and region-mean layer winds: from the series sidecar, else
    /// filled in as the steps are decoded ([`Timeline::prepare`] fills those it needs).
    means: Vec<(DateTime<Utc>, Option<PerLayer>)>,
    /// The step map [`Timeline::start`] decoded, kept for [`Timeline::prepare`].
    opened: Option<(usize, CloudMap)>,
    /// The interval held on the GPU (steps k, k + 1) and the later step's map, which becomes
    /// the earlier one of the next interval.
    held: Option<(usize, CloudMap)>,
    /// The step after the held pair, loading.
    ahead: Option<(usize, JoinHandle<Result<CloudMap>>)>,
    /// Intervals uploaded so far (a test counts them).
    pub uploads: u32,
    /// Whether the step after the held pair is loaded ahead (time runs on: fly, flight); a
    /// single frame (`render`) turns it off.
    pub load_ahead: bool,
    /// Step maps decoded so far, the loader thread's included (`render --timings` prints it).
    decoded: Arc<AtomicU32>,
}

/// Step `k` of `series`, its valid time and step the series' (a map may serve several steps
/// of a synthetic series). Counted in `decoded`.
fn load_step(series: &Series, k: usize, decoded: &AtomicU32) -> Result<CloudMap> {
    decoded.fetch_add(1, Ordering::Relaxed);
    tracing::debug!("decoding step {k} of {}", series.path.display());
    let mut m = series.step_map(k)?;
    let s = &series.steps()[k];
    m.meta.source.valid_time = Some(s.valid_time);
    m.meta.source.forecast_step_h = s.forecast_hour;
    Ok(m)
}

impl Timeline {
    /// Open the series sidecar `path` (its steps' sidecars are read, no step map is decoded).
    pub fn open(path: &Path) -> Result<Timeline> {
        Ok(Self::of(Series::load(path)?))
    }

    /// The timeline of a series already loaded (no step map is decoded).
    pub fn of(series: Series) -> Timeline {
        let means = series
            .steps()
            .iter()
            .map(|s| (s.valid_time, s.mean_wind))
            .collect();
        Timeline {
            series,
            means,
            opened: None,
            held: None,
            ahead: None,
            uploads: 0,
            load_ahead: true,
            decoded: Arc::new(AtomicU32::new(0)),
        }
    }

    /// The timeline of `series` at `time`, and the map to start the renderer from: the step
    /// nearer the moment (the first without one), whose structure and ground the blend takes
    /// there, decoded once and kept for [`Timeline::prepare`].
    pub fn start(series: Series, time: Option<DateTime<Utc>>) -> Result<(CloudMap, Timeline)> {
        let mut tl = Self::of(series);
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
        let map = tl.step(k)?;
        tl.opened = Some((k, map.clone()));
        Ok((map, tl))
    }

    /// Step maps decoded since the series was opened.
    pub fn decoded(&self) -> u32 {
        self.decoded.load(Ordering::Relaxed)
    }

    /// Step `k`'s map: the one [`Timeline::start`] kept, else decoded (its mean wind noted).
    fn step(&mut self, k: usize) -> Result<CloudMap> {
        if let Some((j, m)) = self.opened.take() {
            if j == k {
                return Ok(m);
            }
            self.opened = Some((j, m));
        }
        let m = load_step(&self.series, k, &self.decoded)?;
        self.note_mean(k, &m);
        Ok(m)
    }

    fn note_mean(&mut self, k: usize, map: &CloudMap) {
        if let Some(slot) = self.means.get_mut(k) {
            slot.1.get_or_insert_with(|| map_mean_wind(map));
        }
    }

    /// Make the mean winds of steps 0..=`last` known (an older sidecar lacks them: those steps'
    /// maps are decoded).
    fn fill_means(&mut self, last: usize) -> Result<()> {
        for k in 0..=last.min(self.means.len().saturating_sub(1)) {
            if self.means[k].1.is_none() {
                let m = load_step(&self.series, k, &self.decoded)?;
                self.note_mean(k, &m);
            }
        }
        Ok(())
    }

    /// Step `k`'s mean winds, known once [`Timeline::prepare`] has filled them in.
    fn mean(&self, k: usize) -> PerLayer {
        self.means[k].1.unwrap_or_default()
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
    /// far from the centre, and the pattern would boil (`Settings::streak_wind`). Read after
    /// [`Timeline::prepare`], which makes it known.
    pub fn streak_wind(&self) -> PerLayer {
        self.mean(0)
    }

    /// How far each layer's noise has drifted with its mean wind from the first step to `time`
    /// (east, north m): the integral of the piecewise-linear wind. Needs the means of the steps
    /// up to `time`'s interval ([`Timeline::prepare`] fills them in).
    fn drift_m(&self, time: DateTime<Utc>) -> PerLayer {
        let secs = |a: DateTime<Utc>, b: DateTime<Utc>| (b - a).num_milliseconds() as f64 / 1e3;
        let m: Vec<(DateTime<Utc>, PerLayer)> = self
            .means
            .iter()
            .enumerate()
            .map(|(k, x)| (x.0, self.mean(k)))
            .collect();
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
                let m = self.step(0)?;
                r.set_map(&m);
                self.held = Some((0, m));
            }
            return Ok(self.drift_m(time));
        };
        if self.held.as_ref().map(|h| h.0) != Some(k) {
            let a = match self.held.take() {
                Some((j, later)) if j + 1 == k => later,
                _ => self.step(k)?,
            };
            let b = match self.ahead.take() {
                Some((j, handle)) if j == k + 1 => {
                    let m = handle.join().map_err(|_| TimelineError::Loader)??;
                    self.note_mean(k + 1, &m);
                    m
                }
                _ => self.step(k + 1)?,
            };
            let motion = self.series.motion(k, &a, &b)?;
            r.set_pair(&a, &b, &motion)?;
            self.uploads += 1;
            self.held = Some((k, b));
            self.opened = None;
            if self.load_ahead && k + 2 < self.series.steps().len() {
                let series = self.series.clone();
                let decoded = Arc::clone(&self.decoded);
                self.ahead = Some((
                    k + 2,
                    std::thread::spawn(move || load_step(&series, k + 2, &decoded)),
                ));
            }
        }
        // The drift integrates the means from the first step to this interval's end.
        self.fill_means(k + 1)?;
        Ok(self.drift_m(time))
    }
}
