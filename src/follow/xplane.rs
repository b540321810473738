//! X-Plane's UDP data output ("Data Output" screen, "Network via UDP" column), as documented in
//! X-Plane's `Instructions/Exchanging Data with X-Plane` and its Data Output screen:
//!
//! - 4 bytes `DATA`, then 1 byte for X-Plane's internal use;
//! - then one or more 36-byte records: a little-endian `i32` row index (the number in the Data
//!   Output screen's first column) followed by 8 little-endian `f32` values.
//!
//! Rows used (X-Plane 10–12 numbering): **20** "latitude, longitude & altitude" — latitude
//! (°), longitude (°), altitude (ft MSL), … — **17** "pitch, roll & headings" — pitch (°),
//! roll (°), true heading (°), magnetic heading (°) — and, when ticked, **3** "speeds" —
//! indicated, equivalent and true airspeed (kt), true ground speed (kt), an unused slot, then
//! the same in mph — and **4** "Mach, VVI, g-load" — Mach, an unused slot, vertical speed
//! (ft/min), …. Other rows a user ticked are skipped.

use super::{Fix, ParseError, FEET, KNOT};

/// `DATA` and X-Plane's internal byte.
pub const HEADER_LEN: usize = 5;
/// One row: an `i32` index and 8 `f32` values.
pub const RECORD_LEN: usize = 36;
/// The row with latitude, longitude and altitude (ft MSL).
pub const ROW_POSITION: i32 = 20;
/// The row with pitch, roll and true heading.
pub const ROW_ATTITUDE: i32 = 17;
/// The row with the speeds; slot 3 is the ground speed (kt).
pub const ROW_SPEEDS: i32 = 3;
/// The row with Mach, vertical speed and g-load; slot 2 is the vertical speed (ft/min).
pub const ROW_VVI: i32 = 4;
/// Highest row index the Data Output screen has (X-Plane 12 has about 140): anything beyond is
/// not X-Plane's.
const MAX_ROW: i32 = 255;

/// Parse one datagram. It must carry row 20; row 17 is optional (the attitude then stays
/// `prev_attitude`: a user may tick the rows at different rates); rows 3 and 4 give the
/// simulator's own ground speed and climb rate when present. Any fault makes the whole
/// datagram malformed: a half-read packet is never used.
pub fn parse(packet: &[u8], prev_attitude: (f64, f64, f64)) -> Result<Fix, ParseError> {
    if packet.len() < HEADER_LEN + RECORD_LEN {
        return Err(ParseError::TooShort(packet.len()));
    }
    if &packet[..4] != b"DATA" {
        return Err(ParseError::Header);
    }
    let body = &packet[HEADER_LEN..];
    if !body.len().is_multiple_of(RECORD_LEN) {
        return Err(ParseError::Truncated(body.len() % RECORD_LEN));
    }
    let mut position = None;
    let mut attitude = None;
    let (mut ground_speed, mut climb) = (None, None);
    for rec in body.chunks_exact(RECORD_LEN) {
        let index = i32::from_le_bytes([rec[0], rec[1], rec[2], rec[3]]);
        if !(0..=MAX_ROW).contains(&index) {
            return Err(ParseError::UnknownRecord(index));
        }
        let mut v = [0f64; 8];
        for (k, x) in v.iter_mut().enumerate() {
            let o = 4 + 4 * k;
            *x = f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]) as f64;
        }
        match index {
            ROW_POSITION => position = Some((v[0], v[1], v[2] * FEET)),
            ROW_ATTITUDE => attitude = Some((v[2], v[0], v[1])),
            ROW_SPEEDS => ground_speed = Some(v[3] * KNOT),
            ROW_VVI => climb = Some(v[2] * FEET / 60.0),
            _ => {}
        }
    }
    let (lat, lon, alt_m) = position.ok_or(ParseError::NoPosition)?;
    let (heading, pitch, roll) = attitude.unwrap_or(prev_attitude);
    Fix::checked(lat, lon, alt_m, heading, pitch, roll)?.with_motion(ground_speed, climb)
}

/// A datagram as X-Plane sends it (for tests, fuzz seeds and the loopback sender): rows 20 and
/// 17 for `fix`, and rows 3 and 4 for its speeds when it has them.
pub fn encode(fix: &Fix) -> Vec<u8> {
    let mut p = b"DATA*".to_vec();
    let mut row = |index: i32, v: [f64; 8]| {
        p.extend_from_slice(&index.to_le_bytes());
        for x in v {
            p.extend_from_slice(&(x as f32).to_le_bytes());
        }
    };
    // Unused slots carry X-Plane's -999 filler.
    row(
        ROW_POSITION,
        [
            fix.lat,
            fix.lon,
            fix.alt_m / FEET,
            0.0,
            0.0,
            fix.alt_m / FEET,
            -999.0,
            -999.0,
        ],
    );
    row(
        ROW_ATTITUDE,
        [
            fix.pitch,
            fix.roll,
            fix.heading,
            fix.heading,
            -999.0,
            -999.0,
            -999.0,
            -999.0,
        ],
    );
    if let Some(gs) = fix.ground_speed {
        let kt = gs / KNOT;
        row(
            ROW_SPEEDS,
            [kt, kt, kt, kt, -999.0, 0.0, 0.0, kt * 1.150_779],
        );
    }
    if let Some(climb) = fix.climb {
        row(
            ROW_VVI,
            [
                0.2,
                -999.0,
                climb / FEET * 60.0,
                -999.0,
                1.0,
                0.0,
                0.0,
                -999.0,
            ],
        );
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix() -> Fix {
        Fix::checked(45.5, -22.25, 3048.0, 270.0, -5.0, 10.0).unwrap()
    }

    #[test]
    fn round_trip_within_f32() {
        let got = parse(&encode(&fix()), (0.0, 0.0, 0.0)).unwrap();
        let f = fix();
        assert!((got.lat - f.lat).abs() < 1e-5 && (got.lon - f.lon).abs() < 1e-5);
        assert!(
            (got.alt_m - 3048.0).abs() < 1e-3,
            "10 000 ft is 3048 m: {}",
            got.alt_m
        );
        assert_eq!((got.heading, got.pitch, got.roll), (270.0, -5.0, 10.0));
    }

    #[test]
    fn speeds_are_read_when_sent() {
        let f = fix().with_motion(Some(51.444), Some(-2.54)).unwrap();
        let got = parse(&encode(&f), (0.0, 0.0, 0.0)).unwrap();
        assert!((got.ground_speed.unwrap() - 51.444).abs() < 1e-4, "{got:?}");
        assert!((got.climb.unwrap() + 2.54).abs() < 1e-4, "{got:?}");
        assert_eq!(parse(&encode(&fix()), (0.0, 0.0, 0.0)).unwrap().climb, None);
    }

    #[test]
    fn other_rows_are_skipped_and_attitude_may_be_absent() {
        let mut p = encode(&fix());
        // A trim row (13) in between is fine.
        let mut trim = 13i32.to_le_bytes().to_vec();
        trim.extend(std::iter::repeat_n(0u8, 32));
        p.splice(5..5, trim);
        assert!(parse(&p, (0.0, 0.0, 0.0)).is_ok());
        // Position only: the attitude given is kept.
        let only = &encode(&fix())[..HEADER_LEN + RECORD_LEN];
        let got = parse(only, (90.0, 1.0, 2.0)).unwrap();
        assert_eq!((got.heading, got.pitch, got.roll), (90.0, 1.0, 2.0));
    }

    #[test]
    fn faults_are_errors() {
        let good = encode(&fix());
        assert!(matches!(
            parse(&good[..40], (0.0, 0.0, 0.0)),
            Err(ParseError::TooShort(40))
        ));
        assert!(matches!(
            parse(&good[..50], (0.0, 0.0, 0.0)),
            Err(ParseError::Truncated(_))
        ));
        let mut bad = good.clone();
        bad[..4].copy_from_slice(b"RPOS");
        assert!(matches!(
            parse(&bad, (0.0, 0.0, 0.0)),
            Err(ParseError::Header)
        ));
        let mut nan = good.clone();
        nan[9..13].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(
            parse(&nan, (0.0, 0.0, 0.0)),
            Err(ParseError::Value(_))
        ));
        let mut far = good.clone();
        far[9..13].copy_from_slice(&91f32.to_le_bytes());
        assert!(matches!(
            parse(&far, (0.0, 0.0, 0.0)),
            Err(ParseError::Value(_))
        ));
        let mut idx = good.clone();
        idx[5..9].copy_from_slice(&(-7i32).to_le_bytes());
        assert!(matches!(
            parse(&idx, (0.0, 0.0, 0.0)),
            Err(ParseError::UnknownRecord(-7))
        ));
        let attitude_only = [&good[..5], &good[41..]].concat();
        assert!(matches!(
            parse(&attitude_only, (0.0, 0.0, 0.0)),
            Err(ParseError::NoPosition)
        ));
    }
}
