//! The sample encodings of a map's images: coverage as a 16-bit sample, and the structure
//! images' altitudes, winds and point sources (docs/ingest.md, "Structure images"; the
//! layout of each image is in `structure`).

use crate::layer::PointSource;

/// The PNG sample value of full coverage: coverage c in 0..1 is stored as round(c × 65535).
pub const COVERAGE_FULL: f64 = 65535.0;

/// Coverage (clamped to 0..1) as its 16-bit PNG sample.
pub fn coverage_to_sample(c: f64) -> u16 {
    (c.clamp(0.0, 1.0) * COVERAGE_FULL).round() as u16
}

/// Altitude (m) as its 16-bit sample; `None` → 0.
pub fn altitude_to_sample(m: Option<f64>) -> u16 {
    match m {
        Some(m) if m.is_finite() => ((m + 500.0) * 2.0).round().clamp(0.0, 65534.0) as u16 + 1,
        _ => 0,
    }
}

pub fn sample_to_altitude(v: u16) -> Option<f64> {
    (v != 0).then(|| (v - 1) as f64 * 0.5 - 500.0)
}

/// Wind component (m/s) as its 16-bit sample.
pub fn wind_to_sample(ms: f64) -> u16 {
    if !ms.is_finite() {
        return 32768;
    }
    (ms * 100.0 + 32768.0).round().clamp(0.0, 65535.0) as u16
}

pub fn sample_to_wind(v: u16) -> f64 {
    (v as f64 - 32768.0) / 100.0
}

/// Sources of the three layers packed into the type image's alpha.
pub fn pack_sources(s: [Option<PointSource>; 3]) -> u8 {
    s.iter()
        .enumerate()
        .map(|(c, s)| s.map_or(0, |s| s as u8) << (2 * c))
        .sum()
}

pub fn unpack_source(a: u8, channel: usize) -> Option<PointSource> {
    PointSource::from_code((a >> (2 * channel)) & 3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encodings_round_trip_within_their_step() {
        for m in [-500.0, 0.0, 123.4, 8848.0, 16_000.25, 32_266.5] {
            let back = sample_to_altitude(altitude_to_sample(Some(m))).unwrap();
            assert!((back - m).abs() <= 0.25, "{m} → {back}");
        }
        assert_eq!(altitude_to_sample(None), 0);
        assert_eq!(sample_to_altitude(0), None);
        assert_eq!(altitude_to_sample(Some(-600.0)), 1);
        for u in [-120.0, -0.004, 0.0, 37.25, 150.0] {
            assert!(
                (sample_to_wind(wind_to_sample(u)) - u).abs() <= 0.005,
                "{u}"
            );
        }
        let a = pack_sources([Some(PointSource::GfsLayer), None, Some(PointSource::Band)]);
        assert_eq!(a, 0b11_00_01);
        assert_eq!(unpack_source(a, 0), Some(PointSource::GfsLayer));
        assert_eq!(unpack_source(a, 1), None);
        assert_eq!(unpack_source(a, 2), Some(PointSource::Band));
    }
}
