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

use std::path::{Path, PathBuf};

use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::{meta_from_text, CloudMap};
use stratus_ingest::error::{IngestError, Result};
use stratus_ingest::input::read_sidecar_text;
use stratus_ingest::meta::CloudMapMeta;
use stratus_ingest::series::{text_is_series, Series};

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
}

impl Scene {
    /// Read the sidecar `path` and, for a series, its steps' sidecars; no image is decoded.
    pub fn open(path: &Path) -> Scene {
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
            _ => {}
        }
        files
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
        }
    }
}
