//! Scripted fly-throughs: a keyframed path (serde JSON) sampled into cameras and times.
//!
//! ```json
//! { "keys": [ { "t": 0, "lat": 45.5, "lon": -22, "alt_m": 12000, "heading": 45, "pitch": -12,
//!               "time": "2024-06-01T12:00:00Z" },
//!             { "t": 5, "lat": 46.0, "lon": -21, "alt_m": 9000, "heading": 60, "pitch": -5 } ] }
//! ```
//! `t` is seconds along the path; positions and angles are interpolated linearly (heading the
//! short way round), the time of day likewise where keys give it.

use std::path::{Path, PathBuf};

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};
use stratus_ingest::error::shown;
use stratus_ingest::IngestError;

use crate::render::Camera;

/// Most keys a path may have: a keyframed path is written by hand or by a small script; ten
/// thousand keys is hours of flight at one key a second.
pub const MAX_KEYS: usize = 10_000;

/// Largest path file read: 4 MiB, room for [`MAX_KEYS`] keys of a few hundred bytes each.
pub const MAX_PATH_BYTES: u64 = 4 << 20;

/// Default cap on the frames one `flight` run renders (`--max-frames` raises it): 10 000
/// frames is 17 minutes at 10 fps.
pub const DEFAULT_MAX_FRAMES: u64 = 10_000;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Key {
    pub t: f64,
    pub lat: f64,
    pub lon: f64,
    pub alt_m: f64,
    #[serde(default)]
    pub heading: f64,
    #[serde(default)]
    pub pitch: f64,
    #[serde(default)]
    pub time: Option<DateTime<Utc>>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FlightPath {
    pub keys: Vec<Key>,
    #[serde(default = "default_fov")]
    pub fov_deg: f64,
}

fn default_fov() -> f64 {
    60.0
}

#[derive(Debug, thiserror::Error)]
pub enum PathError {
    #[error("not a flight path: {0}")]
    Json(String),
    #[error("the path needs at least 2 keys, it has {0}")]
    TooFewKeys(usize),
    #[error("the path has {0} keys; at most {MAX_KEYS} are accepted")]
    TooManyKeys(usize),
    #[error("key {0}: t must increase and be finite")]
    BadTime(usize),
    #[error("the keys span {} s, more than a number of seconds can hold", num(*.0))]
    TooLong(f64),
    #[error("key {0}: {1}")]
    BadKey(usize, String),
    /// More frames than the caller allows (or than can be counted).
    #[error("{} s at {fps} fps is {} frames, more than the limit of {max} (raise it with --max-frames)", num(*.seconds), num(*.frames))]
    TooManyFrames {
        seconds: f64,
        fps: f64,
        frames: f64,
        max: u64,
    },
}

/// A number for a message: as written up to a billion, in exponent form above (1.7e308 has
/// 309 digits otherwise), `inf` as such.
fn num(x: f64) -> String {
    if x.is_finite() && x.abs() >= 1e9 {
        format!("{x:.3e}")
    } else {
        format!("{x}")
    }
}

/// A path file that could not be used: unreadable (the error names the file) or not a valid
/// path (named here).
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error(transparent)]
    Read(#[from] IngestError),
    #[error("{}: {err}", shown(.path))]
    Bad { path: PathBuf, err: PathError },
}

fn lerp(a: f64, b: f64, f: f64) -> f64 {
    a + (b - a) * f
}

/// Angle interpolation the short way round (degrees).
fn lerp_deg(a: f64, b: f64, f: f64) -> f64 {
    let d = (b - a + 540.0).rem_euclid(360.0) - 180.0;
    a + d * f
}

impl FlightPath {
    /// Read a path file: at most [`MAX_PATH_BYTES`], then [`FlightPath::parse`].
    pub fn load(path: &Path) -> Result<FlightPath, LoadError> {
        let bytes = stratus_ingest::input::read_capped(path, MAX_PATH_BYTES, "flight path")?;
        FlightPath::parse(&bytes).map_err(|err| LoadError::Bad {
            path: path.to_path_buf(),
            err,
        })
    }

    /// Parse a path's JSON and [`validate`](Self::validate) it.
    pub fn parse(json: &[u8]) -> Result<FlightPath, PathError> {
        let p: FlightPath =
            serde_json::from_slice(json).map_err(|e| PathError::Json(e.to_string()))?;
        p.validate()?;
        Ok(p)
    }

    /// Check what sampling relies on: 2..=[`MAX_KEYS`] keys with finite, increasing `t`
    /// spanning a finite time, and every key a camera that can be rendered, with the angles
    /// interpolation works on (longitude and heading within ±360°, pitch within ±90°).
    pub fn validate(&self) -> Result<(), PathError> {
        if self.keys.len() < 2 {
            return Err(PathError::TooFewKeys(self.keys.len()));
        }
        if self.keys.len() > MAX_KEYS {
            return Err(PathError::TooManyKeys(self.keys.len()));
        }
        for (i, k) in self.keys.iter().enumerate() {
            if !k.t.is_finite() || (i > 0 && k.t <= self.keys[i - 1].t) {
                return Err(PathError::BadTime(i));
            }
            for (name, v, limit) in [
                ("lon", k.lon, 360.0),
                ("heading", k.heading, 360.0),
                ("pitch", k.pitch, 90.0),
            ] {
                if !(-limit..=limit).contains(&v) {
                    return Err(PathError::BadKey(
                        i,
                        format!("{name} {v} is outside -{limit}..={limit}"),
                    ));
                }
            }
            let mut c = Camera::new(k.lat, k.lon, k.alt_m, k.heading, k.pitch);
            c.fov_deg = self.fov_deg;
            c.validate()
                .map_err(|e| PathError::BadKey(i, e.to_string()))?;
        }
        let d = self.duration();
        if !d.is_finite() {
            return Err(PathError::TooLong(d));
        }
        Ok(())
    }

    /// Frames a run at `fps` renders (one at each key time step, both ends included), refused
    /// above `max` — checked in floating point, so a span too long to count is refused, never
    /// wrapped to a small number.
    pub fn frames(&self, fps: f64, max: u64) -> Result<u64, PathError> {
        let seconds = self.duration();
        let frames = (seconds * fps).floor() + 1.0;
        if !(frames.is_finite() && frames >= 1.0 && frames <= max as f64) {
            return Err(PathError::TooManyFrames {
                seconds,
                fps,
                frames,
                max,
            });
        }
        Ok(frames as u64)
    }

    /// Seconds from the first key to the last.
    pub fn duration(&self) -> f64 {
        match (self.keys.first(), self.keys.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        }
    }

    /// Camera and (if keyed) time at `t` seconds, clamped to the path.
    pub fn at(&self, t: f64) -> (Camera, Option<DateTime<Utc>>) {
        let k = &self.keys;
        let t = t.clamp(k[0].t, k[k.len() - 1].t);
        let i = k
            .windows(2)
            .position(|w| t <= w[1].t)
            .unwrap_or(k.len() - 2);
        let (a, b) = (&k[i], &k[i + 1]);
        let f = (t - a.t) / (b.t - a.t);
        let mut cam = Camera::new(
            lerp(a.lat, b.lat, f),
            lerp_deg(a.lon, b.lon, f),
            lerp(a.alt_m, b.alt_m, f),
            lerp_deg(a.heading, b.heading, f),
            lerp(a.pitch, b.pitch, f),
        );
        cam.fov_deg = self.fov_deg;
        let time = match (a.time, b.time) {
            (Some(ta), Some(tb)) => {
                let ms = (tb - ta).num_milliseconds() as f64 * f;
                Some(ta + chrono::Duration::milliseconds(ms as i64))
            }
            (Some(ta), None) => Some(ta),
            (None, Some(tb)) => Some(tb),
            (None, None) => None,
        };
        (cam, time)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(t: f64, lon: f64, heading: f64) -> Key {
        Key {
            t,
            lat: 10.0,
            lon,
            alt_m: 1000.0,
            heading,
            pitch: 0.0,
            time: None,
        }
    }

    #[test]
    fn interpolates_across_the_date_line_and_north() {
        let p = FlightPath {
            keys: vec![key(0.0, 179.0, 350.0), key(2.0, -179.0, 10.0)],
            fov_deg: 60.0,
        };
        p.validate().unwrap();
        let (c, _) = p.at(1.0);
        assert!(
            (c.lon_deg.rem_euclid(360.0) - 180.0).abs() < 1e-9,
            "{}",
            c.lon_deg
        );
        // Heading 350 → 10 passes through north, not south.
        let h = crate::render::camera::heading_pitch_enu(0.0, 0.0);
        assert!((c.forward_enu - h).length() < 1e-9);
    }

    #[test]
    fn bad_paths_are_refused() {
        let one = FlightPath {
            keys: vec![key(0.0, 0.0, 0.0)],
            fov_deg: 60.0,
        };
        assert!(one.validate().is_err());
        let back = FlightPath {
            keys: vec![key(1.0, 0.0, 0.0), key(1.0, 1.0, 0.0)],
            fov_deg: 60.0,
        };
        assert!(back.validate().is_err());
    }

    #[test]
    fn work_is_bounded_before_it_starts() {
        let span = |t1: f64| FlightPath {
            keys: vec![key(0.0, 0.0, 0.0), key(t1, 1.0, 0.0)],
            fov_deg: 60.0,
        };
        assert_eq!(span(0.5).frames(4.0, 10).unwrap(), 3);
        assert!(span(1e8).frames(10.0, DEFAULT_MAX_FRAMES).is_err());
        assert_eq!(span(1e8).frames(10.0, u64::MAX).unwrap(), 1_000_000_001);
        // Too long to count: an error, never a wrap to 0 frames.
        assert!(span(1.7e308).frames(10.0, u64::MAX).is_err());
        let wide = FlightPath {
            keys: vec![key(-1.7e308, 0.0, 0.0), key(1.7e308, 1.0, 0.0)],
            fov_deg: 60.0,
        };
        assert!(matches!(wide.validate(), Err(PathError::TooLong(_))));
        let many = FlightPath {
            keys: (0..=MAX_KEYS).map(|i| key(i as f64, 0.0, 0.0)).collect(),
            fov_deg: 60.0,
        };
        assert!(matches!(many.validate(), Err(PathError::TooManyKeys(_))));
        // Angles interpolation could not handle.
        let far = FlightPath {
            keys: vec![key(0.0, 1e308, 0.0), key(1.0, -1e308, 0.0)],
            fov_deg: 60.0,
        };
        assert!(far.validate().is_err());
    }
}
