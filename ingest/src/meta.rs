//! The CloudMap sidecar (`MAP.json`): what a CloudMap PNG covers and how it was made.
//!
//! The renderer and the scorer read only this and the PNG; nothing downstream re-reads GRIB.

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

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
    pub fn channel(self) -> usize {
        match self {
            LayerKind::Low => 0,
            LayerKind::Middle => 1,
            LayerKind::High => 2,
        }
    }

    /// Default critical humidity (DESIGN §1.4).
    pub fn default_rh_cr(self) -> f64 {
        match self {
            LayerKind::Low => 0.80,
            LayerKind::Middle => 0.65,
            LayerKind::High => 0.80,
        }
    }

    pub fn name(self) -> &'static str {
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
    /// Analysis (reference) time, RFC 3339 UTC.
    pub reference_time: String,
    /// Forecast step, hours.
    pub forecast_step_h: f64,
    /// reference_time + step, RFC 3339 UTC: the time the clouds are valid for.
    pub valid_time: String,
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
