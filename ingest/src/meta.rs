//! The CloudMap sidecar (`MAP.json`): what a CloudMap PNG covers and how it was made.
//!
//! The renderer and the scorer read only this and the PNG; nothing downstream re-reads GRIB.

use chrono::{DateTime, SecondsFormat, Utc};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;

use crate::region::Region;

/// Sidecar format tag; bumped when a field changes meaning.
pub const FORMAT: &str = "stratus-cloudmap/1";

/// Cloud layer (ISCCP convention by pressure of the level).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, PartialOrd, Ord)]
#[serde(rename_all = "lowercase")]
pub enum LayerKind {
    /// p > 680 hPa; PNG channel R.
    Low,
    /// 680 ≥ p ≥ 440 hPa; PNG channel G.
    Middle,
    /// p < 440 hPa; PNG channel B.
    High,
}

impl LayerKind {
    pub const ALL: [LayerKind; 3] = [LayerKind::Low, LayerKind::Middle, LayerKind::High];

    /// The layer an isobaric level belongs to.
    pub fn of_pressure_hpa(p: f64) -> LayerKind {
        if p > 680.0 {
            LayerKind::Low
        } else if p >= 440.0 {
            LayerKind::Middle
        } else {
            LayerKind::High
        }
    }

    /// RGBA channel index in the CloudMap PNG (0 = R).
    pub const fn channel(self) -> usize {
        match self {
            LayerKind::Low => 0,
            LayerKind::Middle => 1,
            LayerKind::High => 2,
        }
    }

    /// Default critical humidity of each layer, indexed by [`LayerKind::channel`] (DESIGN
    /// §1.4). The one definition: the CLI, the control panel and the tests read it from here.
    pub const DEFAULT_RH_CR: [f64; 3] = [0.80, 0.65, 0.80];

    /// Default critical humidity of this layer (DESIGN §1.4).
    pub const fn default_rh_cr(self) -> f64 {
        Self::DEFAULT_RH_CR[self.channel()]
    }

    pub const fn name(self) -> &'static str {
        match self {
            LayerKind::Low => "low",
            LayerKind::Middle => "middle",
            LayerKind::High => "high",
        }
    }
}

/// Where a layer's altitude band came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AltitudeSource {
    /// Geopotential height (`gh`) on the same levels, averaged over the region.
    GeopotentialHeight,
    /// ICAO standard atmosphere.
    StandardAtmosphere,
}

/// One cloud layer of the map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerMeta {
    pub kind: LayerKind,
    /// PNG channel holding this layer's coverage (0 = R, 1 = G, 2 = B).
    pub channel: usize,
    /// Isobaric levels folded into this layer (max coverage over them), hPa, descending.
    pub levels_hpa: Vec<f64>,
    pub rh_cr: f64,
    /// Cloud base and top above mean sea level, metres.
    pub base_m: f64,
    pub top_m: f64,
    pub altitude_source: AltitudeSource,
    /// Mean and max coverage over the map (0..1), for quick inspection.
    pub mean_coverage: f64,
    pub max_coverage: f64,
}

/// Where the forecast came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceMeta {
    pub file: String,
    /// Analysis (reference) time; `None` when the file's date is unreadable. Stored as RFC 3339
    /// UTC with whole seconds (`2011-01-10T12:00:00Z`), or `""` when `None`.
    #[serde(with = "sidecar_time")]
    pub reference_time: Option<DateTime<Utc>>,
    /// Forecast step, hours.
    pub forecast_step_h: f64,
    /// reference_time + step: the time the clouds are valid for. Stored like `reference_time`.
    #[serde(with = "sidecar_time")]
    pub valid_time: Option<DateTime<Utc>>,
    /// Grid of the source field: Ni × Nj and spacing in degrees.
    pub grid_ni: usize,
    pub grid_nj: usize,
    pub grid_di_deg: f64,
    pub grid_dj_deg: f64,
}

/// The sidecar written next to each CloudMap PNG.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CloudMapMeta {
    pub format: String,
    /// PNG file name, relative to the sidecar's directory.
    pub image: String,
    pub region: Region,
    pub width: u32,
    pub height: u32,
    pub layers: Vec<LayerMeta>,
    /// `spline`, `catmull-rom`, `bilinear` or `nearest`.
    pub interpolation: String,
    pub source: SourceMeta,
}

impl CloudMapMeta {
    /// Path of the PNG this sidecar describes.
    pub fn image_path(&self, sidecar: &Path) -> PathBuf {
        sidecar
            .parent()
            .unwrap_or_else(|| Path::new("."))
            .join(&self.image)
    }

    pub fn layer(&self, kind: LayerKind) -> Option<&LayerMeta> {
        self.layers.iter().find(|l| l.kind == kind)
    }
}

/// A time that is not ISO 8601 / RFC 3339.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("time {0:?} is not ISO 8601 (e.g. 2011-01-15T06:00:00Z)")]
pub struct BadTime(pub String);

/// Parse a UTC time as stratus writes and accepts it: RFC 3339 with any offset (converted to
/// UTC), or a date and time without offset (`2011-01-15T06:00:00`, `2011-01-15T06:00`), read
/// as UTC. The one parser for sidecar times and `--time`.
pub fn parse_time(s: &str) -> Result<DateTime<Utc>, BadTime> {
    DateTime::parse_from_rfc3339(s)
        .map(|d| d.with_timezone(&Utc))
        .or_else(|_| {
            chrono::NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M:%S").map(|n| n.and_utc())
        })
        .or_else(|_| {
            chrono::NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M").map(|n| n.and_utc())
        })
        .map_err(|_| BadTime(s.to_string()))
}

/// A time as the sidecar stores it: RFC 3339, UTC, whole seconds, `Z` (`2011-01-15T12:00:00Z`).
pub fn format_time(t: &DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::Secs, true)
}

/// Serde for the sidecar's optional times: `""` is "unknown", so version-1 sidecars (which
/// wrote `""` when the GRIB date was unreadable) load and new ones are byte-identical.
mod sidecar_time {
    use super::{format_time, parse_time};
    use chrono::{DateTime, Utc};
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(t: &Option<DateTime<Utc>>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&t.as_ref().map(format_time).unwrap_or_default())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<DateTime<Utc>>, D::Error> {
        let s = String::deserialize(d)?;
        if s.is_empty() {
            return Ok(None);
        }
        parse_time(&s).map(Some).map_err(D::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sidecar as version 1 wrote it (what `ingest` of the 2.5° GFS file made), byte for byte.
    pub(crate) const V1_SIDECAR: &str = r#"{
  "format": "stratus-cloudmap/1",
  "image": "ea.png",
  "region": {
    "south": 0.0,
    "north": 55.0,
    "west": 39.0,
    "east": 105.0
  },
  "width": 260,
  "height": 220,
  "layers": [
    {
      "kind": "middle",
      "channel": 1,
      "levels_hpa": [
        600.0,
        500.0
      ],
      "rh_cr": 0.65,
      "base_m": 3147.5,
      "top_m": 6624.25,
      "altitude_source": "geopotential-height",
      "mean_coverage": 0.125,
      "max_coverage": 1.0
    }
  ],
  "interpolation": "spline",
  "source": {
    "file": "/data/gfs.t12z.pgrbf120.2p5deg.grib2",
    "reference_time": "2011-01-10T12:00:00Z",
    "forecast_step_h": 120.0,
    "valid_time": "2011-01-15T12:00:00Z",
    "grid_ni": 144,
    "grid_nj": 73,
    "grid_di_deg": 2.5,
    "grid_dj_deg": 2.5
  }
}"#;

    #[test]
    fn times_are_typed_and_round_trip_byte_identical() {
        let m: CloudMapMeta = serde_json::from_str(V1_SIDECAR).unwrap();
        assert_eq!(
            m.source.valid_time,
            Some(parse_time("2011-01-15T12:00:00Z").unwrap())
        );
        assert_eq!(serde_json::to_string_pretty(&m).unwrap(), V1_SIDECAR);
        // An unknown time is "" both ways.
        let blank = V1_SIDECAR.replace("2011-01-10T12:00:00Z", "");
        let m: CloudMapMeta = serde_json::from_str(&blank).unwrap();
        assert_eq!(m.source.reference_time, None);
        assert_eq!(serde_json::to_string_pretty(&m).unwrap(), blank);
        // A time that is not one is refused, and the error says which.
        let bad = V1_SIDECAR.replace("2011-01-15T12:00:00Z", "next tuesday");
        let e = serde_json::from_str::<CloudMapMeta>(&bad).unwrap_err();
        assert!(
            e.to_string().contains("\"next tuesday\" is not ISO 8601"),
            "{e}"
        );
    }

    #[test]
    fn one_parser_for_every_time_form() {
        let t = parse_time("2011-01-15T06:00:00Z").unwrap();
        assert_eq!(parse_time("2011-01-15T06:00:00").unwrap(), t);
        assert_eq!(parse_time("2011-01-15T06:00").unwrap(), t);
        assert_eq!(parse_time("2011-01-15T08:00:00+02:00").unwrap(), t);
        assert_eq!(format_time(&t), "2011-01-15T06:00:00Z");
        assert!(parse_time("2011-13-15T06:00").is_err());
    }

    #[test]
    fn rh_cr_defaults_are_defined_once() {
        let by_kind: Vec<f64> = LayerKind::ALL.iter().map(|k| k.default_rh_cr()).collect();
        assert_eq!(by_kind, LayerKind::DEFAULT_RH_CR);
        assert_eq!(LayerKind::DEFAULT_RH_CR, [0.80, 0.65, 0.80]);
    }
}
