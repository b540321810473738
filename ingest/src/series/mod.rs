//! A CloudMap series: the maps of several forecast steps of one run (DESIGN §9), their series
//! sidecar ([`meta`]), which input files make one ([`inputs`]), how it is written ([`write`]),
//! and the weather at any moment of it ([`Series::at`]: the two steps around the moment
//! moved along the guarded motion between them and blended, [`motion`]; the motion stored
//! with the series, [`stored`], or for a series written before it, estimated from the two
//! steps). The layer-wind blend ([`advect`]) stays as the reference `verify-interpolation`
//! and `verify-advection` compare with.
//!
//! [`Series::load`] reads the series sidecar and checks every step's sidecar, PNG and
//! structure images are there and match the series; step maps themselves are decoded only
//! when a moment needs them, so a long series costs two maps of memory.

pub mod advect;
pub mod check;
pub mod inputs;
pub mod meta;
pub mod motion;
pub mod stored;
pub mod winds;
pub mod write;

use std::path::{Path, PathBuf};

use chrono::{DateTime, Utc};

use crate::cloudmap::{load_meta, CloudMap};
use crate::error::{shown, IngestError, Result};
use crate::meta::CloudMapMeta;

pub use advect::{advect, blend, genus_switch_w};
pub use meta::{SeriesMeta, SeriesStep, SERIES_FORMAT};

/// A series sidecar, checked, with its step maps' sidecars.
#[derive(Debug, Clone)]
pub struct Series {
    pub path: PathBuf,
    pub meta: SeriesMeta,
    /// Each step's map sidecar (same order as `meta.steps`).
    pub step_metas: Vec<CloudMapMeta>,
    /// Where the step maps come from when they are not PNG sets beside the sidecar (a Zarr
    /// store, `crate::zarr`); `None`: the step sidecars' PNG sets.
    pub loader: Option<StepLoader>,
}

/// Reads step `k`'s map of a series held elsewhere than in PNG sets (a Zarr store), and
/// (when that place holds it) the stored motion from step `k` to `k + 1`.
#[derive(Clone)]
pub struct StepLoader(
    std::sync::Arc<dyn Fn(usize) -> Result<CloudMap> + Send + Sync>,
    Option<MotionLoader>,
);

/// Reads the stored motion after step `k` of a series held elsewhere than in PNG sets.
type MotionLoader = std::sync::Arc<dyn Fn(usize) -> Result<motion::Motion> + Send + Sync>;

impl StepLoader {
    pub fn new(f: impl Fn(usize) -> Result<CloudMap> + Send + Sync + 'static) -> StepLoader {
        StepLoader(std::sync::Arc::new(f), None)
    }

    /// The loader that also reads each step's stored motion with `m` (used for the steps
    /// whose series entry names a motion).
    pub fn with_motion(
        self,
        m: impl Fn(usize) -> Result<motion::Motion> + Send + Sync + 'static,
    ) -> StepLoader {
        StepLoader(self.0, Some(std::sync::Arc::new(m)))
    }
}

impl std::fmt::Debug for StepLoader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("StepLoader")
    }
}

/// Whether `path` is a series sidecar (its `format` says so). A file that cannot be read or
/// parsed is not one: the map loader then reports what is wrong with it.
pub fn is_series(path: &Path) -> bool {
    sidecar_is_series(path).unwrap_or(false)
}

/// Whether the sidecar `path` is a series sidecar; an error when it is no sidecar at all (not
/// a regular file, unreadable, not JSON: [`crate::input::read_sidecar_text`]).
pub fn sidecar_is_series(path: &Path) -> Result<bool> {
    let text = crate::input::read_sidecar_text(path)?;
    Ok(text_is_series(&text))
}

/// Whether a sidecar's text (already read: [`crate::input::read_sidecar_text`]) is a series
/// sidecar's.
pub fn text_is_series(text: &str) -> bool {
    #[derive(serde::Deserialize)]
    struct Peek {
        format: Option<serde_json::Value>,
    }
    serde_json::from_str::<Peek>(text)
        .ok()
        .and_then(|p| p.format)
        .is_some_and(|f| f == SERIES_FORMAT)
}

/// The map a `--map` argument names at `time`: a series' moment ([`Series::at`]; its first
/// step without a time) or a plain CloudMap (loaded as is; `time` is then only the Sun's).
pub fn open_map(path: &Path, time: Option<DateTime<Utc>>) -> Result<CloudMap> {
    if !is_series(path) {
        return CloudMap::load(path);
    }
    let s = Series::load(path)?;
    match time {
        Some(t) => s.at(t),
        None => s.step_map(0),
    }
}

impl Series {
    /// Read and check the series sidecar `path` and each step's sidecar: present, valid, the
    /// step the series entry says it is and of the series' run, region, size and layers
    /// ([`check::step_fault`]), its PNG and structure images present. The first fault is one
    /// error naming the series sidecar, the step and the file.
    pub fn load(path: &Path) -> Result<Series> {
        let text = crate::input::read_sidecar_text(path)?;
        Self::from_text(path, &text)
    }

    /// [`Series::load`] of the series sidecar's text already read
    /// ([`crate::input::read_sidecar_text`]); `path` names it and locates its steps.
    pub fn from_text(path: &Path, text: &str) -> Result<Series> {
        let meta: SeriesMeta = serde_json::from_str(text)
            .map_err(|e| IngestError::series(path, format!("series sidecar is not valid: {e}")))?;
        meta.validate()
            .map_err(|e| IngestError::series(path, format!("series sidecar: {e}")))?;
        let dir = folder(path);
        let mut step_metas = Vec::with_capacity(meta.steps.len());
        for s in &meta.steps {
            let at = |msg: String| {
                IngestError::series(
                    path,
                    format!("step {}: {msg}", meta::show_hour(s.forecast_hour)),
                )
            };
            let sidecar = dir.join(&s.map);
            let m = load_meta(&sidecar).map_err(|e| at(e.to_string()))?;
            if let Some(fault) = check::step_fault(&meta, s, &m, step_metas.first()) {
                return Err(at(format!("{}: {fault}", shown(&sidecar))));
            }
            let mut images = vec![m.image_path(&sidecar)];
            images.extend(m.extra_images.iter().map(|x| dir.join(&x.image)));
            if let Some(g) = &m.ground {
                images.extend([dir.join(&g.image), dir.join(&g.water_image)]);
            }
            if let Some(w) = &s.winds {
                images.extend([dir.join(&w.u), dir.join(&w.v)]);
            }
            if let Some(mo) = &s.motion {
                images.extend([dir.join(&mo.u), dir.join(&mo.v)]);
            }
            for p in &images {
                match std::fs::metadata(p) {
                    Ok(m) if m.is_file() => {}
                    Ok(m) => {
                        let kind = crate::output::kind_of(&m.file_type());
                        return Err(at(format!(
                            "{}: it is {kind}, not a regular file",
                            shown(p)
                        )));
                    }
                    Err(_) => return Err(at(format!("{}: missing", shown(p)))),
                }
            }
            if let Some(mo) = &s.motion {
                stored::check(dir, mo).map_err(at)?;
            }
            step_metas.push(m);
        }
        let n = meta.steps.len();
        if meta.steps[..n - 1].iter().any(|s| s.motion.is_none()) {
            tracing::info!(
                "{}: no motion images (a series sidecar from before issue 31): each interval's motion is estimated from its two steps when first needed",
                shown(path)
            );
        }
        Ok(Series {
            path: path.to_path_buf(),
            meta,
            step_metas,
            loader: None,
        })
    }

    /// A series held elsewhere (a Zarr store at `path`): its sidecar `meta` and step sidecars
    /// checked as [`Series::load`] checks them, its step maps read by `loader`.
    pub fn with_loader(
        path: &Path,
        meta: SeriesMeta,
        step_metas: Vec<CloudMapMeta>,
        loader: StepLoader,
    ) -> Result<Series> {
        meta.validate()
            .map_err(|e| IngestError::series(path, format!("series: {e}")))?;
        for (s, m) in meta.steps.iter().zip(&step_metas) {
            if let Some(fault) = check::step_fault(&meta, s, m, step_metas.first()) {
                return Err(IngestError::series(
                    path,
                    format!("step {}: {fault}", meta::show_hour(s.forecast_hour)),
                ));
            }
        }
        if step_metas.len() != meta.steps.len() {
            return Err(IngestError::series(path, "not one map per step"));
        }
        Ok(Series {
            path: path.to_path_buf(),
            meta,
            step_metas,
            loader: Some(loader),
        })
    }

    pub fn steps(&self) -> &[SeriesStep] {
        &self.meta.steps
    }

    /// Index of the step at `hour`, if the series has it.
    pub fn step_at_hour(&self, hour: f64) -> Option<usize> {
        self.meta
            .steps
            .iter()
            .position(|s| (s.forecast_hour - hour).abs() < 1e-6)
    }

    /// The hours the series holds, as people write them (`+0 h, +6 h`).
    pub fn hours_text(&self) -> String {
        self.meta
            .steps
            .iter()
            .map(|s| meta::show_hour(s.forecast_hour))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Load step `k`'s map (PNG and structure checked as [`CloudMap::load`] does).
    pub fn step_map(&self, k: usize) -> Result<CloudMap> {
        let s = self.meta.steps.get(k).ok_or_else(|| {
            IngestError::series(
                &self.path,
                format!("no step {k} (it has {})", self.meta.steps.len()),
            )
        })?;
        let sidecar = folder(&self.path).join(&s.map);
        // The step's sidecar was read and checked by `load`: only its images are read now.
        let read = match (&self.loader, self.step_metas.get(k)) {
            (Some(l), _) => (l.0)(k),
            (None, Some(m)) => CloudMap::load_with(&sidecar, m.clone()),
            (None, None) => CloudMap::load(&sidecar),
        };
        read.map_err(|e| {
            IngestError::series(
                &self.path,
                format!("step {}: {e}", meta::show_hour(s.forecast_hour)),
            )
        })
    }

    /// The guarded motion from step `k` to step `k + 1` (their maps `a`, `b`): the stored one
    /// ([`stored::read`]), else — a series sidecar from before issue 31 — estimated from `a`
    /// and `b` ([`motion::estimate`], seconds for a large map), in the stored form either way
    /// ([`motion::Motion::baked`]).
    pub fn motion(&self, k: usize, a: &CloudMap, b: &CloudMap) -> Result<motion::Motion> {
        let steps = &self.meta.steps;
        let (Some(s0), Some(s1)) = (steps.get(k), steps.get(k + 1)) else {
            return Err(IngestError::series(
                &self.path,
                format!("no interval after step {k} (it has {} steps)", steps.len()),
            ));
        };
        if let Some(m) = &s0.motion {
            if let Some(read) = self.loader.as_ref().and_then(|l| l.1.as_ref()) {
                return read(k);
            }
            return stored::read(folder(&self.path), m, &self.meta).map_err(|e| {
                IngestError::series(
                    &self.path,
                    format!("step {}: {e}", meta::show_hour(s0.forecast_hour)),
                )
            });
        }
        let interval = (s1.valid_time - s0.valid_time).num_milliseconds() as f64 / 1000.0;
        let t = std::time::Instant::now();
        let m = motion::estimate(a, b, interval)?.baked();
        tracing::debug!(
            "motion {} → {} estimated in {:.1} s",
            meta::show_hour(s0.forecast_hour),
            meta::show_hour(s1.forecast_hour),
            t.elapsed().as_secs_f64()
        );
        Ok(m)
    }

    /// The weather at `time`: the step map where a step is valid then; between two steps their
    /// blend along the guarded motion between them ([`Series::motion`], [`motion::blend`]:
    /// growth and decay stay a cross-fade); before the first or after the last step that step
    /// unchanged. Held, not extrapolated along the last motion: the forecast says nothing
    /// beyond its steps, and a motion estimated over one interval carried further would move
    /// cloud that the next step (there is none) might have cleared.
    pub fn at(&self, time: DateTime<Utc>) -> Result<CloudMap> {
        let steps = &self.meta.steps;
        let after = steps.iter().position(|s| s.valid_time > time);
        let k = match after {
            Some(0) => {
                tracing::warn!(
                    "{} is before the series' first step: first step held",
                    crate::meta::format_time(&time)
                );
                return self.step_map(0);
            }
            None => {
                if steps.last().is_some_and(|s| s.valid_time < time) {
                    tracing::warn!(
                        "{} is after the series' last step: last step held",
                        crate::meta::format_time(&time)
                    );
                }
                return self.step_map(steps.len() - 1);
            }
            Some(k) => k - 1,
        };
        if steps[k].valid_time == time {
            return self.step_map(k);
        }
        let (t0, t1) = (steps[k].valid_time, steps[k + 1].valid_time);
        let interval = (t1 - t0).num_milliseconds() as f64 / 1000.0;
        let w = (time - t0).num_milliseconds() as f64 / 1000.0 / interval;
        let (a, b) = (self.step_map(k)?, self.step_map(k + 1)?);
        let m = self.motion(k, &a, &b)?;
        motion::blend(&a, &b, w, interval, &m).map_err(|e| IngestError::series(&self.path, e))
    }

    /// Every file the series reads: its step sidecars, PNGs, structure, ground and motion
    /// images.
    pub fn files(&self) -> Vec<PathBuf> {
        if self.loader.is_some() {
            return vec![self.path.clone()];
        }
        let dir = folder(&self.path);
        let mut v = Vec::new();
        for (s, m) in self.meta.steps.iter().zip(&self.step_metas) {
            let sidecar = dir.join(&s.map);
            if let Some(mo) = &s.motion {
                v.extend([dir.join(&mo.u), dir.join(&mo.v)]);
            }
            v.push(m.image_path(&sidecar));
            v.extend(m.extra_images.iter().map(|x| dir.join(&x.image)));
            if let Some(g) = &m.ground {
                v.extend([dir.join(&g.image), dir.join(&g.water_image)]);
            }
            v.push(sidecar);
        }
        v
    }
}

fn folder(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

#[cfg(test)]
mod tests;
