//! Why the picture is dark (issue 30): a map's valid time can be night or dusk where the
//! window opens, and a newcomer then sees a dark screen. The HUD says so, with the local solar
//! time and a daylight time to ask for.

use chrono::{DateTime, Duration, NaiveTime, Utc};

/// Sun elevation (degrees) under which the window's exposure no longer opens up for the day
/// (exposure.wgsl's `day` ramp ends at about 6°): the picture is a dusk or night picture.
pub const LOW_SUN_DEG: f64 = 6.0;
/// Under this the Sun's light is gone (civil twilight's end).
pub const NIGHT_DEG: f64 = -6.0;

/// A HUD line when the Sun is low or down at (lat, lon) at `utc`: what it is, the local mean
/// solar time, and the UTC time of local solar noon that day to pick daylight with; `None` by
/// day.
pub fn note(utc: DateTime<Utc>, lat: f64, lon: f64) -> Option<String> {
    let el = crate::sun::Sky::at(utc, lat, lon).sun_elevation_deg;
    if el >= LOW_SUN_DEG {
        return None;
    }
    let offset = Duration::seconds((lon / 15.0 * 3600.0) as i64);
    let solar = utc + offset;
    let what = if el < NIGHT_DEG {
        "night"
    } else if solar.time() < NaiveTime::from_hms_opt(12, 0, 0).unwrap_or_default() {
        "dawn"
    } else {
        "dusk"
    };
    let noon = solar_noon(utc, lon)?;
    Some(format!(
        "{what} here (local solar {}, Sun {el:.0}°): for daylight move the time slider or start with --time {}",
        solar.format("%H:%M"),
        noon.format("%Y-%m-%dT%H:%M:%SZ")
    ))
}

/// The UTC time of local mean solar noon at `lon` on the local solar day of `utc`.
pub fn solar_noon(utc: DateTime<Utc>, lon: f64) -> Option<DateTime<Utc>> {
    let offset = Duration::seconds((lon / 15.0 * 3600.0) as i64);
    Some((utc + offset).date_naive().and_hms_opt(12, 0, 0)?.and_utc() - offset)
}

#[cfg(test)]
mod tests {
    use super::*;
    use chrono::TimeZone;

    #[test]
    fn says_dusk_night_or_nothing() {
        // The East Asia sample's valid time, 2011-01-15 12 UTC: dusk at 80°E (local solar
        // 17:20), night over eastern Tibet (90°E, 18:00), day over Arabia.
        let t = Utc.with_ymd_and_hms(2011, 1, 15, 12, 0, 0).unwrap();
        let west = note(t, 32.0, 80.0).expect("dusk at 80°E");
        assert!(west.starts_with("dusk here (local solar 17:20"), "{west}");
        assert!(west.contains("--time 2011-01-15T06:40:00Z"), "{west}");
        let tibet = note(t, 32.0, 90.0).expect("night at 90°E");
        assert!(tibet.starts_with("night"), "{tibet}");
        assert_eq!(note(t, 25.0, 45.0), None, "noon-ish over Arabia");
        let dawn = note(t, 30.0, -75.0).expect("dawn at 75°W");
        assert!(dawn.starts_with("dawn"), "{dawn}");
    }
}
