//! A scene: what a command's `--map` names, a CloudMap or a forecast series, opened once and
//! the same way by every command (render, flight, fly, section, probe, score, demo, bench,
//! verify-advection).
//!
//! [`Scene::open`] reads and checks the sidecar once (a series' step sidecars with it); the
//! files the scene is read from ([`Scene::files`], what outputs are checked against), the map
//! at a moment ([`Scene::map_at`]) and a series' timeline for the renderer
//! ([`Scene::for_renderer`]) all come from that one reading. A sidecar that cannot be read
//! is no error at opening: commands check their outputs against the files first, and the
//! fault is the command's error when the map is taken.
//!
//! A Zarr store (`STORE.zarr`, `stratus_ingest::zarr`) is a scene too: one step is a map,
//! several a series whose steps are read from the store; its group metadata is read once.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::{meta_from_text, CloudMap};
use stratus_ingest::error::{IngestError, Result};
use stratus_ingest::input::read_sidecar_text;
use stratus_ingest::meta::CloudMapMeta;
use stratus_ingest::series::{text_is_series, Series};
use stratus_ingest::zarr::{self, Store};

use crate::timeline::Timeline;

/// A `--map` sidecar, read once.
pub struct Scene {
    path: PathBuf,
    opened: Opened,
}

/// What the sidecar turned out to be.
enum Opened {
    /// Not readable as a sidecar at all (missing, not a regular file, not JSON…).
    Unread(IngestError),
    /// A CloudMap's sidecar, checked (or why not).
    Map(Box<Result<CloudMapMeta>>),
    /// A series sidecar, its steps' sidecars checked (or why not).
    Series(Result<Series>),
    /// A Zarr store, its metadata checked (or why not).
    Store(Result<Arc<Store>>),
}

impl Scene {
    /// Read the sidecar `path` and, for a series, its steps' sidecars; no image is decoded.
    pub fn open(path: &Path) -> Scene {
        if zarr::is_store(path) {
            return Scene {
                path: path.to_path_buf(),
                opened: Opened::Store(Store::open(path).map(Arc::new)),
            };
        }
        let opened = match read_sidecar_text(path) {
            Err(e) => Opened::Unread(e),
            Ok(text) if text_is_series(&text) => Opened::Series(Series::from_text(path, &text)),
            Ok(text) => Opened::Map(Box::new(meta_from_text(path, &text))),
        };
        Scene {
            path: path.to_path_buf(),
            opened,
        }
    }

    /// The sidecar the scene was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The files the scene is read from: its sidecar and, as far as the sidecars could be
    /// read, a map's PNG or every file of a series' steps.
    pub fn files(&self) -> Vec<PathBuf> {
        let mut files = vec![self.path.clone()];
        match &self.opened {
            Opened::Map(m) => {
                if let Ok(meta) = m.as_ref() {
                    files.push(meta.image_path(&self.path));
                }
            }
            Opened::Series(Ok(s)) => files.extend(s.files()),
            Opened::Store(_) => files.push(self.path.join("zarr.json")),
            _ => {}
        }
        files
    }

    /// The store the scene was opened from, when it is one.
    pub fn store(&self) -> Option<&Arc<Store>> {
        match &self.opened {
            Opened::Store(Ok(s)) => Some(s),
            _ => None,
        }
    }

    /// The map at `time` as far as a probe at (`lat`, `lon`) reads it: from a store at a
    /// step (one step, no time, a time at or beyond a step) only the chunks around the point
    /// ([`Store::read_step_near`]); otherwise [`Scene::map_at`].
    pub fn map_near(self, time: Option<DateTime<Utc>>, lat: f64, lon: f64) -> Result<CloudMap> {
        if let Opened::Store(Ok(s)) = &self.opened {
            let steps = &s.series.steps;
            let k = match time {
                None => Some(0),
                Some(t) if steps.len() == 1 || t <= steps[0].valid_time => Some(0),
                Some(t) if steps.last().is_some_and(|l| t >= l.valid_time) => Some(steps.len() - 1),
                Some(t) => steps.iter().position(|s| s.valid_time == t),
            };
            if let Some(k) = k {
                return s.read_step_near(k, lat, lon);
            }
        }
        self.map_at(time)
    }

    /// The map at `time`: a series' moment ([`Series::at`], the CPU blend; its first step
    /// without a time) or the CloudMap as it is (`time` is then only the Sun's).
    pub fn map_at(self, time: Option<DateTime<Utc>>) -> Result<CloudMap> {
        match self.opened {
            Opened::Unread(e) => Err(e),
            Opened::Map(meta) => CloudMap::load_with(&self.path, (*meta)?),
            Opened::Series(s) => {
                let s = s?;
                match time {
                    Some(t) => s.at(t),
                    None => s.step_map(0),
                }
            }
            Opened::Store(s) => {
                let s = s?;
                match (s.steps.len(), time) {
                    (1, _) | (_, None) => s.read_step(0),
                    (_, Some(t)) => s.into_series()?.at(t),
                }
            }
        }
    }

    /// What a renderer draws from the scene at `time`: the map to start it from (and to read
    /// the camera's ground, the layers and, without a time, the valid time from) and, for a
    /// series, the timeline that blends its steps on the GPU ([`Timeline::prepare`]). A plain
    /// map is loaded as it is; a series gives the step nearer the moment ([`Timeline::start`]).
    /// No CPU blend: that is [`Scene::map_at`], the reference.
    pub fn for_renderer(self, time: Option<DateTime<Utc>>) -> Result<(CloudMap, Option<Timeline>)> {
        match self.opened {
            Opened::Series(s) => {
                let (map, tl) = Timeline::start(s?, time)?;
                Ok((map, Some(tl)))
            }
            Opened::Store(Ok(s)) if s.steps.len() > 1 => {
                let (map, tl) = Timeline::start(s.into_series()?, time)?;
                Ok((map, Some(tl)))
            }
            _ => Ok((self.map_at(time)?, None)),
        }
    }

    /// The series the scene is, `None` when it is a plain CloudMap; an error when the sidecar
    /// cannot be read, or is a series sidecar that is not whole.
    pub fn into_series(self) -> Result<Option<Series>> {
        match self.opened {
            Opened::Unread(e) => Err(e),
            Opened::Map(_) => Ok(None),
            Opened::Series(s) => s.map(Some),
            Opened::Store(s) => {
                let s = s?;
                match s.steps.len() {
                    1 => Ok(None),
                    _ => s.into_series().map(Some),
                }
            }
        }
    }
}
