//! FlightGear's generic protocol, with the output definition Stratus ships in
//! `docs/flightgear/stratus.xml`: one ASCII line per datagram,
//!
//! ```text
//! latitude-deg,longitude-deg,altitude-ft,heading-deg,pitch-deg,roll-deg,groundspeed-kt,vertical-speed-fps\n
//! ```
//!
//! read from `/position/latitude-deg`, `/position/longitude-deg`, `/position/altitude-ft`
//! (MSL), `/orientation/heading-deg` (true), `/orientation/pitch-deg`,
//! `/orientation/roll-deg`, `/velocities/groundspeed-kt` and `/velocities/vertical-speed-fps`.
//! A line of the first six only (the file Stratus shipped before the speeds) is read too: the
//! speed is then measured from packet times. FlightGear is started with
//! `--generic=socket,out,30,HOST,5505,udp,stratus`.

use super::{Fix, ParseError, FEET, KNOT};

/// Fields on a line: position and attitude, then the two speeds.
pub const FIELDS: usize = 8;
/// Fields on a line without the speeds.
pub const FIELDS_WITHOUT_SPEEDS: usize = 6;
/// Longest line accepted: six numbers printed with `%.8f` take well under 128 bytes.
pub const MAX_LINE: usize = 256;

/// Parse one datagram: one line of eight (or six) comma-separated numbers ending in a newline. The
/// newline is required: FlightGear always sends the line separator, and without it a datagram
/// cut short could still read as six numbers.
pub fn parse(packet: &[u8]) -> Result<Fix, ParseError> {
    if packet.len() > MAX_LINE {
        return Err(ParseError::TooLong(packet.len()));
    }
    let text = std::str::from_utf8(packet).map_err(|_| ParseError::NotText)?;
    let line = text.strip_suffix('\n').ok_or(ParseError::NoNewline)?;
    let line = line.strip_suffix('\r').unwrap_or(line);
    if line.contains('\n') {
        return Err(ParseError::Fields(line.split('\n').count()));
    }
    let mut v = [0f64; FIELDS];
    let mut n = 0;
    for part in line.split(',') {
        if n == FIELDS {
            return Err(ParseError::Fields(line.split(',').count()));
        }
        v[n] = part
            .trim()
            .parse::<f64>()
            .map_err(|_| ParseError::Number(n))?;
        n += 1;
    }
    let fix = Fix::checked(v[0], v[1], v[2] * FEET, v[3], v[4], v[5])?;
    match n {
        FIELDS => fix.with_motion(Some(v[6] * KNOT), Some(v[7] * FEET)),
        FIELDS_WITHOUT_SPEEDS => Ok(fix),
        _ => Err(ParseError::Fields(n)),
    }
}

/// A line as the shipped protocol makes FlightGear send it (for tests, fuzz seeds and the
/// loopback sender): with the speeds when the fix has both, else the six fields without them.
pub fn encode(fix: &Fix) -> Vec<u8> {
    let speeds = match (fix.ground_speed, fix.climb) {
        (Some(gs), Some(climb)) => format!(",{:.2},{:.2}", gs / KNOT, climb / FEET),
        _ => String::new(),
    };
    format!(
        "{:.8},{:.8},{:.4},{:.4},{:.4},{:.4}{speeds}\n",
        fix.lat,
        fix.lon,
        fix.alt_m / FEET,
        fix.heading,
        fix.pitch,
        fix.roll
    )
    .into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_shipped_line() {
        let f = parse(b"45.50000000,-22.25000000,10000.0000,270.0000,-5.0000,10.0000\n").unwrap();
        assert_eq!((f.lat, f.lon), (45.5, -22.25));
        assert!((f.alt_m - 3048.0).abs() < 1e-9);
        assert_eq!((f.heading, f.pitch, f.roll), (270.0, -5.0, 10.0));
        assert!(parse(b"1,2,3,4,5,6\r\n").is_ok());
        assert_eq!((f.ground_speed, f.climb), (None, None));
        let f = parse(b"45.5,-22.25,10000.00,270.000,-5.000,10.000,100.00,-10.00\n").unwrap();
        assert!((f.ground_speed.unwrap() - 51.444).abs() < 1e-3, "{f:?}");
        assert!((f.climb.unwrap() + 3.048).abs() < 1e-9, "{f:?}");
    }

    #[test]
    fn faults_are_errors() {
        for (bad, what) in [
            (&b"1,2,3,4,5"[..], "five fields"),
            (b"1,2,3,4,5,6,7\n", "seven fields"),
            (b"1,2,3,4,5,6,7,8,9\n", "nine fields"),
            (b"1,2,3,4,5,6,-5,0\n", "negative ground speed"),
            (b"1,2,3,4,5,6,50,1e6\n", "climb"),
            (b"1,2,3,4,5,6,nan,0\n", "NaN speed"),
            (b"1,2,x,4,5,6\n", "not a number"),
            (b"nan,2,3,4,5,6\n", "NaN"),
            (b"1,inf,3,4,5,6\n", "infinite"),
            (b"95,2,3,4,5,6\n", "latitude"),
            (b"1,2,3,4,95,6\n", "pitch"),
            (b"1,2,3,4,5,6\n1,2,3,4,5,6\n", "two lines"),
            (b"\xff\xfe", "not UTF-8"),
            (b"", "empty"),
        ] {
            assert!(parse(bad).is_err(), "{what}");
        }
        assert!(parse(&[b'1'; 300]).is_err());
    }
}
