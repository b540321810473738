//! Sun and Moon: where they are for a UTC time, and what colour their light has at the ground.
//!
//! Positions use the low-precision formulas of the Astronomical Almanac (the Sun to about 0.01°,
//! the Moon to about 0.5°: plenty for lighting). Directions are Earth-centred, Earth-fixed (ECEF)
//! unit vectors: x toward (0°N, 0°E), y toward (0°N, 90°E), z toward the North Pole. The light's
//! colour comes from the air mass it crosses (Kasten–Young) with Rayleigh + aerosol optical
//! depths per RGB channel, so noon is white, dusk is red and the Sun below the horizon gives none.

use chrono::{DateTime, Utc};
use glam::DVec3;

/// A light in the sky: its ECEF direction (toward it) and linear-RGB irradiance scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub dir: DVec3,
    pub colour: [f64; 3],
}

/// The Sun and Moon over one place at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sky {
    pub sun: Light,
    pub moon: Light,
    /// Sun elevation above the local horizon, degrees.
    pub sun_elevation_deg: f64,
    /// Illuminated fraction of the Moon's disc, 0..1.
    pub moon_phase: f64,
}

/// Full-moon irradiance relative to the overhead Sun's (about 0.25 lux against 100 000 lux).
pub const MOON_TO_SUN: f64 = 2.5e-6;

/// Days since J2000.0 (2000-01-01 12:00 UTC).
fn days_since_j2000(t: DateTime<Utc>) -> f64 {
    let j2000 = DateTime::parse_from_rfc3339("2000-01-01T12:00:00Z")
        .map(|d| d.with_timezone(&Utc))
        .unwrap_or_default();
    (t - j2000).num_milliseconds() as f64 / 86_400_000.0
}

/// Greenwich mean sidereal time, degrees.
fn gmst_deg(n: f64) -> f64 {
    (280.460_618_37 + 360.985_647_366_29 * n).rem_euclid(360.0)
}

/// ECEF unit vector toward a body at right ascension `ra` and declination `dec` (degrees).
fn ecef_of(ra_deg: f64, dec_deg: f64, n: f64) -> DVec3 {
    let lon = (ra_deg - gmst_deg(n)).to_radians();
    let dec = dec_deg.to_radians();
    DVec3::new(dec.cos() * lon.cos(), dec.cos() * lon.sin(), dec.sin())
}

/// Ecliptic (longitude, latitude) → equatorial (right ascension, declination), degrees.
fn equatorial(lambda_deg: f64, beta_deg: f64, n: f64) -> (f64, f64) {
    let eps = (23.439 - 4.0e-7 * n).to_radians();
    let (l, b) = (lambda_deg.to_radians(), beta_deg.to_radians());
    let ra = (l.sin() * eps.cos() - b.tan() * eps.sin()).atan2(l.cos());
    let dec = (b.sin() * eps.cos() + b.cos() * eps.sin() * l.sin()).asin();
    (ra.to_degrees(), dec.to_degrees())
}

/// ECEF direction toward the Sun.
pub fn sun_dir(t: DateTime<Utc>) -> DVec3 {
    let n = days_since_j2000(t);
    let l = 280.460 + 0.985_647_4 * n;
    let g = (357.528 + 0.985_600_3 * n).to_radians();
    let lambda = l + 1.915 * g.sin() + 0.020 * (2.0 * g).sin();
    let (ra, dec) = equatorial(lambda, 0.0, n);
    ecef_of(ra, dec, n)
}

/// ECEF direction toward the Moon (geocentric; parallax under 1°, ignored).
pub fn moon_dir(t: DateTime<Utc>) -> DVec3 {
    let n = days_since_j2000(t);
    let l = 218.316 + 13.176_396 * n;
    let m = (134.963 + 13.064_993 * n).to_radians();
    let f = (93.272 + 13.229_350 * n).to_radians();
    let lambda = l + 6.289 * m.sin();
    let beta = 5.128 * f.sin();
    let (ra, dec) = equatorial(lambda, beta, n);
    ecef_of(ra, dec, n)
}

/// Local up (ECEF unit vector) at a latitude/longitude in degrees.
pub fn up_at(lat_deg: f64, lon_deg: f64) -> DVec3 {
    let (la, lo) = (lat_deg.to_radians(), lon_deg.to_radians());
    DVec3::new(la.cos() * lo.cos(), la.cos() * lo.sin(), la.sin())
}

/// Linear-RGB transmittance of the clear atmosphere toward a body at `elevation_deg`.
///
/// Optical depths at 680/550/440 nm: Rayleigh 0.036/0.097/0.236 plus a light aerosol load
/// (0.06/0.07/0.08). Below the horizon the light fades out over the Sun's own diameter.
pub fn transmittance(elevation_deg: f64) -> [f64; 3] {
    const TAU: [f64; 3] = [0.096, 0.167, 0.316];
    let e = elevation_deg.max(-0.5);
    // Kasten & Young (1989) air mass; finite at the horizon (about 38).
    let airmass = 1.0 / (e.to_radians().sin().max(0.0) + 0.50572 * (e + 6.07995).powf(-1.6364));
    let fade = ((elevation_deg + 0.5) / 0.5).clamp(0.0, 1.0);
    TAU.map(|t| (-t * airmass).exp() * fade)
}

impl Sky {
    /// The sky over (lat, lon) at time `t`.
    pub fn at(t: DateTime<Utc>, lat_deg: f64, lon_deg: f64) -> Sky {
        Sky::from_dirs(sun_dir(t), moon_dir(t), lat_deg, lon_deg)
    }

    /// The sky with a given Sun direction (the Moon opposite it, full), for overrides and tests.
    pub fn with_sun(sun: DVec3, lat_deg: f64, lon_deg: f64) -> Sky {
        Sky::from_dirs(sun, -sun, lat_deg, lon_deg)
    }

    fn from_dirs(sun: DVec3, moon: DVec3, lat_deg: f64, lon_deg: f64) -> Sky {
        let up = up_at(lat_deg, lon_deg);
        let sun_el = sun.dot(up).clamp(-1.0, 1.0).asin().to_degrees();
        let moon_el = moon.dot(up).clamp(-1.0, 1.0).asin().to_degrees();
        let phase = 0.5 * (1.0 - sun.dot(moon));
        let moon_t = transmittance(moon_el);
        Sky {
            sun: Light {
                dir: sun,
                colour: transmittance(sun_el),
            },
            moon: Light {
                dir: moon,
                colour: moon_t.map(|c| c * MOON_TO_SUN * phase),
            },
            sun_elevation_deg: sun_el,
            moon_phase: phase,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn utc(s: &str) -> DateTime<Utc> {
        DateTime::parse_from_rfc3339(s).unwrap().with_timezone(&Utc)
    }

    #[test]
    fn solstice_noon_at_greenwich() {
        // 2024-06-20 20:51 UTC solstice: declination +23.44°; at 12:00 UTC over 0°E the Sun
        // culminates (equation of time about −1.7 min) at 90 − 51.5 + 23.4 = 61.9° over London.
        let sky = Sky::at(utc("2024-06-21T12:02:00Z"), 51.5, 0.0);
        assert!(
            (sky.sun_elevation_deg - 61.9).abs() < 0.3,
            "{}",
            sky.sun_elevation_deg
        );
        let dec = sun_dir(utc("2024-06-21T00:00:00Z")).z.asin().to_degrees();
        assert!((dec - 23.44).abs() < 0.05, "{dec}");
    }

    #[test]
    fn midnight_is_dark_and_dusk_is_red() {
        let night = Sky::at(utc("2024-06-01T00:00:00Z"), 45.0, 10.0);
        assert!(night.sun_elevation_deg < -10.0);
        assert_eq!(night.sun.colour, [0.0; 3]);
        let t = transmittance(2.0);
        assert!(t[0] > 4.0 * t[2], "{t:?}");
        let noon = transmittance(90.0);
        assert!(noon.iter().all(|&c| c > 0.7 && c <= 1.0), "{noon:?}");
    }

    #[test]
    fn moon_phase_follows_a_known_full_moon() {
        // Full moon 2024-06-22 01:08 UTC; new moon 2024-06-06 12:38 UTC.
        let full = Sky::at(utc("2024-06-22T01:00:00Z"), 0.0, 0.0).moon_phase;
        let new = Sky::at(utc("2024-06-06T12:38:00Z"), 0.0, 0.0).moon_phase;
        assert!(full > 0.97, "{full}");
        assert!(new < 0.03, "{new}");
    }
}
