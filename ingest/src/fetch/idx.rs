//! NCEP `.idx` inventories (wgrib2's short inventory): one line per field,
//! `N:BYTE_OFFSET:d=YYYYMMDDHH:NAME:LEVEL:FORECAST:`, e.g.
//! `1:0:d=2011011012:HGT:1000 mb:120 hour fcst:`. A message's bytes run from its offset to the
//! next message's offset (the last one to the end of the file). Fields of one multi-field
//! message share an offset and are numbered `N.1`, `N.2`….
//!
//! [`parse`] reads one; [`write`] makes one from a scanned file, with NCEP's parameter names
//! and wgrib2's level and forecast wording, so tests (and a mirror) can serve inventories for
//! files that come without one.

use std::fmt::Write as _;

use crate::grib::{MessageInfo, SurfaceType, TimeUnit};
use crate::input::MAX_GRIB_BYTES;

/// One line of an inventory.
#[derive(Debug, Clone, PartialEq)]
pub struct IdxLine {
    /// `1`, or `5.2` for the second field of message 5.
    pub number: String,
    pub offset: u64,
    /// The run, `YYYYMMDDHH` (after `d=`).
    pub date: String,
    /// NCEP short name: `RH`, `HGT`, `UGRD`…
    pub name: String,
    /// wgrib2's level text: `500 mb`, `surface`, `low cloud layer`…
    pub level: String,
    /// `anl`, `6 hour fcst`, `0-6 hour ave fcst`…
    pub forecast: String,
}

/// One GRIB message as the inventory places it: its fields' lines and its byte range.
#[derive(Debug, Clone, PartialEq)]
pub struct IdxMessage {
    pub lines: Vec<IdxLine>,
    pub start: u64,
    /// Exclusive end; `None` for the last message, which runs to the end of the file.
    pub end: Option<u64>,
}

/// Largest inventory read: 1 MiB. A 0.25° step's is about 70 KB (some 750 lines).
pub const MAX_IDX_BYTES: u64 = 1 << 20;

/// Most lines an inventory may have: 10 000, over ten times a 0.25° step's.
pub const MAX_IDX_LINES: usize = 10_000;

/// Fewest bytes a GRIB2 message can be: the fixed parts of its mandatory sections — the
/// indicator (16), identification (21), grid (14), product (9), data representation (11),
/// bit-map (6) and data (5) sections and the end marker (4). Offsets closer than this cannot
/// be two messages.
pub const MIN_MESSAGE_BYTES: u64 = 86;

/// Most bytes one message may be: 32 MiB. A GFS 0.25° field is 1 038 240 points, at most
/// 4.2 MB even packed at 32 bits a value (GFS packs them in 1–2 MB); offsets farther apart
/// than this are not a GFS message.
pub const MAX_MESSAGE_BYTES: u64 = 32 << 20;

/// `N` or `N.K` (K ≥ 1, the field of a multi-field message).
fn message_number(s: &str) -> Option<(u64, u64)> {
    let (n, k) = match s.split_once('.') {
        Some((n, k)) => (n, k.parse().ok()?),
        None => (s, 1),
    };
    let n: u64 = n.parse().ok()?;
    (n >= 1 && k >= 1).then_some((n, k))
}

/// Parse an inventory. Each line must have at least the six fields; blank lines are skipped.
/// What one file's inventory cannot be is refused, naming the line (1-based): more than
/// [`MAX_IDX_BYTES`] or [`MAX_IDX_LINES`]; offsets that go backwards; a line repeated, or two
/// messages at one offset; message numbers that do not increase; a message shorter than
/// [`MIN_MESSAGE_BYTES`] or longer than [`MAX_MESSAGE_BYTES`]; an offset past the largest GRIB
/// file ([`MAX_GRIB_BYTES`]).
pub fn parse(text: &str) -> Result<Vec<IdxMessage>, String> {
    if text.len() as u64 > MAX_IDX_BYTES {
        return Err(format!(
            "{} bytes, more than an inventory may be ({} KiB)",
            text.len(),
            MAX_IDX_BYTES >> 10
        ));
    }
    let mut lines: Vec<IdxLine> = Vec::new();
    // The previous line's (line number, message number, field number).
    let mut prev: Option<(usize, u64, u64)> = None;
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim_end_matches('\r');
        if raw.trim().is_empty() {
            continue;
        }
        let bad = |m: &str| format!("line {}: {m}: {:?}", i + 1, shorten(raw));
        if lines.len() == MAX_IDX_LINES {
            return Err(bad(&format!(
                "more than {MAX_IDX_LINES} lines, more than an inventory may have"
            )));
        }
        let f: Vec<&str> = raw.split(':').collect();
        if f.len() < 6 {
            return Err(bad("fewer than 6 ':'-separated fields"));
        }
        let (n, k) =
            message_number(f[0]).ok_or_else(|| bad("the message number is not N or N.K"))?;
        let offset: u64 = f[1]
            .parse()
            .map_err(|_| bad("byte offset is not a number"))?;
        if offset > MAX_GRIB_BYTES {
            return Err(bad("byte offset is past the largest GRIB file (2 GiB)"));
        }
        let date = f[2]
            .strip_prefix("d=")
            .ok_or_else(|| bad("third field is not d=YYYYMMDDHH"))?;
        if let (Some(last), Some((pl, pn, pk))) = (lines.last(), prev) {
            let gap = offset
                .checked_sub(last.offset)
                .ok_or_else(|| bad("byte offset goes backwards"))?;
            if gap == 0 && (n, k) == (pn, pk) {
                return Err(bad(&format!("repeats line {pl}")));
            }
            if gap == 0 && (n != pn || k < pk) {
                return Err(bad(&format!(
                    "starts at the byte of message {pn} (line {pl}): two messages cannot start at one byte"
                )));
            }
            if gap > 0 && n <= pn {
                return Err(bad(&format!(
                    "message {n} after message {pn} (line {pl}): message numbers must increase"
                )));
            }
            if gap > 0 && gap < MIN_MESSAGE_BYTES {
                return Err(bad(&format!(
                    "would make message {pn} (line {pl}) {gap} bytes long; a GRIB2 message is at least {MIN_MESSAGE_BYTES}"
                )));
            }
            if gap > MAX_MESSAGE_BYTES {
                return Err(bad(&format!(
                    "would make message {pn} (line {pl}) {gap} bytes long, more than a GFS message can be ({} MiB)",
                    MAX_MESSAGE_BYTES >> 20
                )));
            }
        }
        if lines.last().is_none_or(|l| l.offset != offset) && k != 1 {
            return Err(bad(&format!("field {k} of a message with no field 1")));
        }
        prev = Some((i + 1, n, k));
        lines.push(IdxLine {
            number: f[0].to_string(),
            offset,
            date: date.to_string(),
            name: f[3].to_string(),
            level: f[4].to_string(),
            forecast: f[5].to_string(),
        });
    }
    if lines.is_empty() {
        return Err("the inventory is empty".into());
    }
    let mut msgs: Vec<IdxMessage> = Vec::new();
    for line in lines {
        match msgs.last_mut() {
            Some(m) if m.start == line.offset => m.lines.push(line),
            _ => {
                if let Some(m) = msgs.last_mut() {
                    m.end = Some(line.offset);
                }
                msgs.push(IdxMessage {
                    start: line.offset,
                    end: None,
                    lines: vec![line],
                });
            }
        }
    }
    Ok(msgs)
}

fn shorten(s: &str) -> String {
    s.chars().take(80).collect()
}

/// NCEP short names of the parameters stratus knows: (discipline, category, number, name).
pub const NCEP_NAMES: [(u8, u8, u8, &str); 30] = [
    (0, 0, 0, "TMP"),
    (0, 0, 2, "POT"),
    (0, 0, 4, "TMAX"),
    (0, 0, 5, "TMIN"),
    (0, 0, 6, "DPT"),
    (0, 1, 0, "SPFH"),
    (0, 1, 1, "RH"),
    (0, 1, 3, "PWAT"),
    (0, 1, 8, "APCP"),
    (0, 1, 22, "CLMR"),
    (0, 1, 23, "ICMR"),
    (0, 1, 24, "RWMR"),
    (0, 1, 25, "SNMR"),
    (0, 2, 2, "UGRD"),
    (0, 2, 3, "VGRD"),
    (0, 2, 8, "VVEL"),
    (0, 2, 10, "ABSV"),
    (0, 2, 14, "PVORT"),
    (0, 2, 22, "GUST"),
    (0, 3, 0, "PRES"),
    (0, 3, 1, "PRMSL"),
    (0, 3, 5, "HGT"),
    (0, 3, 192, "MSLET"),
    (0, 6, 1, "TCDC"),
    (0, 7, 6, "CAPE"),
    (0, 7, 7, "CIN"),
    (0, 14, 192, "O3MR"),
    (0, 19, 0, "VIS"),
    (0, 1, 7, "PRATE"),
    (2, 0, 0, "LAND"),
];

/// NCEP's short name of a field, or wgrib2's spelling for a parameter it has no name for.
pub fn ncep_name(info: &MessageInfo) -> String {
    let (d, c, n) = info.parameter();
    NCEP_NAMES
        .iter()
        .find(|p| (p.0, p.1, p.2) == (d, c, n))
        .map_or_else(
            || format!("var discipline={d} master_table=2 parmcat={c} parm={n}"),
            |p| p.3.to_string(),
        )
}

/// The parameter an NCEP short name stands for, when stratus knows the name.
pub fn parameter_of(name: &str) -> Option<(u8, u8, u8)> {
    NCEP_NAMES
        .iter()
        .find(|p| p.3 == name)
        .map(|p| (p.0, p.1, p.2))
}

fn num(x: f64) -> String {
    if (x - x.round()).abs() < 1e-9 {
        format!("{}", x.round() as i64)
    } else {
        format!("{}", (x * 1e6).round() / 1e6)
    }
}

/// wgrib2's level text for a field.
pub fn level_text(info: &MessageInfo) -> String {
    use SurfaceType as S;
    let v = info.level_value.unwrap_or(f64::NAN);
    let v2 = info.level2_value.unwrap_or(f64::NAN);
    let Some(ty) = info.level_type else {
        return "unknown level".into();
    };
    match ty {
        S::Isobaric => format!("{} mb", num(v / 100.0)),
        S::Surface => "surface".into(),
        S::MeanSeaLevel => "mean sea level".into(),
        S::HeightAboveGround => format!("{} m above ground", num(v)),
        S::Altitude => format!("{} m above mean sea level", num(v)),
        S::Sigma => format!("{} sigma level", num(v)),
        S::DepthBelowLand => format!("{}-{} m below ground", num(v), num(v2)),
        S::PressureFromGround => format!("{}-{} mb above ground", num(v / 100.0), num(v2 / 100.0)),
        S::PotentialVorticity => format!("PV={v:e} (Km^2/kg/s) surface"),
        S::Isotherm0C => "0C isotherm".into(),
        S::MaxWind => "max wind".into(),
        S::Tropopause => "tropopause".into(),
        S::NominalTop => "top of atmosphere".into(),
        S::EntireAtmosphere => "entire atmosphere".into(),
        S::EntireAtmosphereNcep => "entire atmosphere (considered as a single layer)".into(),
        S::HighestFreezing => "highest tropospheric freezing level".into(),
        S::BoundaryLayerCloud => "boundary layer cloud layer".into(),
        S::LowCloudBottom => "low cloud bottom level".into(),
        S::LowCloudTop => "low cloud top level".into(),
        S::LowCloudLayer => "low cloud layer".into(),
        S::PlanetaryBoundaryLayer => "planetary boundary layer".into(),
        S::MiddleCloudBottom => "middle cloud bottom level".into(),
        S::MiddleCloudTop => "middle cloud top level".into(),
        S::MiddleCloudLayer => "middle cloud layer".into(),
        S::HighCloudBottom => "high cloud bottom level".into(),
        S::HighCloudTop => "high cloud top level".into(),
        S::HighCloudLayer => "high cloud layer".into(),
        S::ConvectiveCloudBottom => "convective cloud bottom level".into(),
        S::ConvectiveCloudTop => "convective cloud top level".into(),
        S::ConvectiveCloudLayer => "convective cloud layer".into(),
        S::Other(t) => format!("level type {t}"),
    }
}

/// wgrib2's forecast text: `anl`, `120 hour fcst`, or for a statistic over a time range
/// (product template 4.8) `114-120 hour ave fcst`. `msg` is the field's whole message.
pub fn forecast_text(msg: &[u8], info: &MessageInfo) -> String {
    let start = info.step_hours.unwrap_or(0.0);
    if info.product_template == Some(8) {
        let (a, b) = info.sections.s4;
        let s4 = msg.get(a..b).unwrap_or_default();
        // Template 4.8: octet 47 the statistic, 49 the range's unit, 50–53 its length.
        if s4.len() >= 53 {
            let kind = match s4[46] {
                0 => "ave",
                1 => "acc",
                2 => "max",
                3 => "min",
                _ => "",
            };
            let len = u32::from_be_bytes([s4[49], s4[50], s4[51], s4[52]]) as f64;
            let hours = TimeUnit::from_code(s4[48]).and_then(|u| u.to_hours(len));
            if let (false, Some(h)) = (kind.is_empty(), hours) {
                return format!("{}-{} hour {kind} fcst", num(start), num(start + h));
            }
        }
    }
    if start == 0.0 {
        "anl".into()
    } else {
        format!("{} hour fcst", num(start))
    }
}

/// The inventory of a scanned file (`bytes` the whole file, `fields` what
/// [`crate::grib::scan`] found in it), in NCEP's `.idx` format.
pub fn write(bytes: &[u8], fields: &[MessageInfo]) -> String {
    let mut out = String::new();
    for f in fields {
        let multi = fields.iter().filter(|g| g.index == f.index).count() > 1;
        let number = if multi {
            format!("{}.{}", f.index + 1, f.field + 1)
        } else {
            format!("{}", f.index + 1)
        };
        let date = f
            .reference_time
            .map_or_else(|| "0000000000".into(), |t| t.format("%Y%m%d%H").to_string());
        let msg = bytes.get(f.offset..f.offset + f.length).unwrap_or_default();
        let _ = writeln!(
            out,
            "{number}:{}:d={date}:{}:{}:{}:",
            f.offset,
            ncep_name(f),
            level_text(f),
            forecast_text(msg, f)
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = "1:0:d=2011011012:HGT:1000 mb:120 hour fcst:\n\
                          2:1000:d=2011011012:RH:1000 mb:120 hour fcst:\n\
                          3:2500:d=2011011012:UGRD:500 mb:120 hour fcst:\n\
                          3.2:2500:d=2011011012:VGRD:500 mb:120 hour fcst:\n\
                          4:4000:d=2011011012:TCDC:low cloud layer:114-120 hour ave fcst:\n";

    #[test]
    fn parses_lines_and_groups_fields_of_one_message() {
        let m = parse(SAMPLE).unwrap();
        assert_eq!(m.len(), 4);
        assert_eq!((m[0].start, m[0].end), (0, Some(1000)));
        assert_eq!((m[2].start, m[2].end), (2500, Some(4000)));
        assert_eq!(m[2].lines.len(), 2);
        assert_eq!(m[2].lines[1].name, "VGRD");
        assert_eq!(m[3].end, None);
        assert_eq!(m[3].lines[0].level, "low cloud layer");
        assert_eq!(m[3].lines[0].date, "2011011012");
    }

    #[test]
    fn refuses_what_is_not_an_inventory() {
        assert!(parse("").unwrap_err().contains("empty"));
        assert!(parse("<html>404</html>").unwrap_err().contains("line 1"));
        let e = parse("1:100:d=2011011012:HGT:1000 mb:anl:\n2:50:d=2011011012:RH:1000 mb:anl:\n")
            .unwrap_err();
        assert!(e.contains("line 2") && e.contains("backwards"), "{e}");
        assert!(parse("1:x:d=1:HGT:1000 mb:anl:")
            .unwrap_err()
            .contains("offset"));
    }

    #[test]
    fn refuses_what_no_file_can_have() {
        let l = |n: &str, off: u64| format!("{n}:{off}:d=2011011012:RH:500 mb:anl:\n");
        let e = parse(&(l("1", 0) + &l("1", 0))).unwrap_err();
        assert!(e.contains("line 2: repeats line 1"), "{e}");
        let e = parse(&(l("1", 0) + &l("2", 0))).unwrap_err();
        assert!(e.contains("two messages cannot start at one byte"), "{e}");
        let e = parse(&(l("2", 0) + &l("1", 1000))).unwrap_err();
        assert!(e.contains("must increase"), "{e}");
        let e = parse(&(l("1", 0) + &l("2", 1))).unwrap_err();
        assert!(
            e.contains("1 bytes long; a GRIB2 message is at least 86"),
            "{e}"
        );
        let e = parse(&(l("1", 0) + &l("2", 600_000_000))).unwrap_err();
        assert!(e.contains("more than a GFS message can be"), "{e}");
        let e = parse(&l("1.2", 0)).unwrap_err();
        assert!(e.contains("no field 1"), "{e}");
        let e = parse(&l("x", 0)).unwrap_err();
        assert!(e.contains("message number"), "{e}");
        let many: String = (0..=MAX_IDX_LINES as u64)
            .map(|i| format!("{}:{}:d=1:A:1 mb:anl:\n", i + 1, i * 100))
            .collect();
        let e = parse(&many).unwrap_err();
        assert!(e.contains("more than 10000 lines"), "{e}");
        let big = "\n".repeat(MAX_IDX_BYTES as usize + 1);
        assert!(parse(&big).unwrap_err().contains("more than an inventory"));
        // Fields of one message: N.1, N.2 at one offset.
        let m = parse(&(l("1.1", 0) + &l("1.2", 0) + &l("2", 200))).unwrap();
        assert_eq!((m.len(), m[0].lines.len()), (2, 2));
    }

    #[test]
    fn names_round_trip() {
        assert_eq!(parameter_of("RH"), Some((0, 1, 1)));
        assert_eq!(parameter_of("LAND"), Some((2, 0, 0)));
        assert_eq!(parameter_of("NOPE"), None);
    }
}
