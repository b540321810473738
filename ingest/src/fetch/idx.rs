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

/// Parse an inventory. Lines must have at least the six fields, offsets must not decrease, and
/// blank lines are skipped; anything else is an error naming the line (1-based).
pub fn parse(text: &str) -> Result<Vec<IdxMessage>, String> {
    let mut lines: Vec<IdxLine> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim_end_matches('\r');
        if raw.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = raw.split(':').collect();
        let bad = |m: &str| format!("line {}: {m}: {:?}", i + 1, shorten(raw));
        if f.len() < 6 {
            return Err(bad("fewer than 6 ':'-separated fields"));
        }
        let offset: u64 = f[1]
            .parse()
            .map_err(|_| bad("byte offset is not a number"))?;
        let date = f[2]
            .strip_prefix("d=")
            .ok_or_else(|| bad("third field is not d=YYYYMMDDHH"))?;
        if let Some(prev) = lines.last() {
            if offset < prev.offset {
                return Err(bad("byte offset goes backwards"));
            }
        }
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
    fn names_round_trip() {
        assert_eq!(parameter_of("RH"), Some((0, 1, 1)));
        assert_eq!(parameter_of("LAND"), Some((2, 0, 0)));
        assert_eq!(parameter_of("NOPE"), None);
    }
}
