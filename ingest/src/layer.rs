//! The layer vocabulary every stage shares: the three cloud layers by pressure (ISCCP) and
//! their critical humidities (the one rh_cr rule, [`validate_rh_cr`]), the altitudes a layer
//! may span and the standard atmosphere that places a level without gh, and where a layer's or
//! a point's base and top came from ([`AltitudeSource`], [`PointSource`]).

use serde::{Deserialize, Serialize};

use crate::error::{IngestError, Result};

/// Layer bases and tops a sidecar may hold, metres above mean sea level: from below the
/// lowest land (the Dead Sea shore is at −430 m) to the Kármán line. Every level a GFS file
/// holds (up to 0.4 hPa, about 50 km) fits; a band at 10¹² m or ±10³⁰⁸ m does not.
pub const ALTITUDE_RANGE_M: std::ops::RangeInclusive<f64> = -500.0..=100_000.0;

/// The ISCCP layer boundaries by pressure (hPa): low p > 680, middle 680 ≥ p ≥ 440, high p < 440.
pub const LOW_TOP_HPA: f64 = 680.0;
pub const MIDDLE_TOP_HPA: f64 = 440.0;

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
        if p > LOW_TOP_HPA {
            LayerKind::Low
        } else if p >= MIDDLE_TOP_HPA {
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

/// Where a layer's altitude band, or one pixel's base and top, came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AltitudeSource {
    /// Geopotential height (`gh`) on the same levels, averaged over the region (a band).
    GeopotentialHeight,
    /// ICAO standard atmosphere (a band).
    StandardAtmosphere,
    /// GFS's own cloud bottom and top pressure of the layer, through the point's gh profile.
    GfsLayer,
    /// Where the point's RH column crosses the layer's rh_cr.
    RhColumn,
}

impl AltitudeSource {
    pub const fn name(self) -> &'static str {
        match self {
            AltitudeSource::GeopotentialHeight => "geopotential-height",
            AltitudeSource::StandardAtmosphere => "standard-atmosphere",
            AltitudeSource::GfsLayer => "gfs-layer",
            AltitudeSource::RhColumn => "rh-column",
        }
    }
}

/// Where one grid point's (or pixel's) base and top came from; its code is what the type
/// image's alpha channel holds, two bits per layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub enum PointSource {
    GfsLayer = 1,
    RhColumn = 2,
    /// The layer's band (its sidecar `altitude_source` says whether gh or the standard
    /// atmosphere made it).
    Band = 3,
}

impl PointSource {
    pub fn from_code(c: u8) -> Option<PointSource> {
        match c {
            1 => Some(PointSource::GfsLayer),
            2 => Some(PointSource::RhColumn),
            3 => Some(PointSource::Band),
            _ => None,
        }
    }

    /// As the sidecar and the probe name it; a band is named by what made it.
    pub fn altitude_source(self, band: AltitudeSource) -> AltitudeSource {
        match self {
            PointSource::GfsLayer => AltitudeSource::GfsLayer,
            PointSource::RhColumn => AltitudeSource::RhColumn,
            PointSource::Band => band,
        }
    }
}

/// Check a critical humidity: the formula divides by 1 − rh_cr.
pub fn validate_rh_cr(x: f64) -> Result<f64> {
    if !x.is_finite() || !(0.0..1.0).contains(&x) {
        return Err(IngestError::BadRhCr(format!(
            "rh_cr must be in [0, 1) (a fraction; the formula divides by 1 - rh_cr), got {x}"
        )));
    }
    Ok(x)
}

/// ICAO standard atmosphere altitude (m) of a pressure (hPa), troposphere and lower stratosphere.
pub fn standard_altitude_m(p_hpa: f64) -> f64 {
    if p_hpa >= 226.32 {
        44330.8 * (1.0 - (p_hpa / 1013.25).powf(0.190263))
    } else {
        11000.0 - 6341.6 * (p_hpa / 226.32).ln()
    }
}

/// [`validate_rh_cr`] for the critical humidities of the three layers (low, middle, high).
pub fn validate_rh_crs(rh_cr: [f64; 3]) -> Result<[f64; 3]> {
    for x in rh_cr {
        validate_rh_cr(x)?;
    }
    Ok(rh_cr)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_atmosphere_is_monotonic_and_sane() {
        assert!(standard_altitude_m(1013.25).abs() < 1.0);
        assert!((standard_altitude_m(500.0) - 5574.0).abs() < 30.0);
        assert!((standard_altitude_m(226.32) - 11000.0).abs() < 5.0);
        let mut prev = -1.0;
        for p in (10..=1000).rev().step_by(10) {
            let z = standard_altitude_m(p as f64);
            assert!(z > prev);
            prev = z;
        }
    }
}
