//! What `fetch` checks in the bytes of a message before it keeps them: as they arrive, that
//! a GRIB2 message of the length the inventory gives starts where the inventory places it
//! ([`HeadWatch`], so a server sending zeros or another file is refused after 16 bytes, not
//! after the range); once the message is whole, that it is a valid GRIB2 message of the
//! parameter, level and run its inventory lines name, that its data section decodes, and that
//! the values are plausible for the parameter ([`check_message`], [`PLAUSIBLE`]).

use super::idx::{self, IdxMessage, MAX_MESSAGE_BYTES};
use super::select;
use crate::grib::{self, MessageInfo};

/// Bytes of a GRIB2 indicator section: `GRIB`, two reserved octets, the discipline, the
/// edition, and the message's total length (8 octets).
const HEAD: usize = 16;

/// `message 12 (RH 500 mb)`.
pub fn describe(m: &IdxMessage) -> String {
    let what: Vec<String> = m
        .lines
        .iter()
        .map(|l| format!("{} {}", l.name, l.level))
        .collect();
    let number = m.lines.first().map_or("?", |l| l.number.as_str());
    format!("message {number} ({})", what.join(", "))
}

/// Checks the indicator section of each message of a range as the range's bytes arrive.
pub struct HeadWatch<'a> {
    /// (the message, its first byte in the range, its length, its first bytes so far).
    heads: Vec<(&'a IdxMessage, u64, u64, Vec<u8>)>,
}

impl<'a> HeadWatch<'a> {
    /// For `messages`, in a range that starts at byte `start` of the file and is `len` bytes
    /// long (the last message of a file, which the inventory gives no end, runs to its end).
    pub fn new(messages: &'a [IdxMessage], start: u64, len: u64) -> HeadWatch<'a> {
        let heads = messages
            .iter()
            .map(|m| {
                let at = m.start - start;
                let n = m.end.map_or(len.saturating_sub(at), |e| e - m.start);
                (m, at, n, Vec::with_capacity(HEAD))
            })
            .collect();
        HeadWatch { heads }
    }

    /// `bytes` arrived at byte `pos` of the range: check every indicator section now whole.
    pub fn feed(&mut self, pos: u64, bytes: &[u8]) -> Result<(), String> {
        let end = pos + bytes.len() as u64;
        for (m, at, len, got) in &mut self.heads {
            if got.len() == HEAD || *at >= end || *at + HEAD as u64 <= pos {
                continue;
            }
            let from = (*at + got.len() as u64 - pos) as usize;
            let take = (HEAD - got.len()).min(bytes.len() - from);
            got.extend_from_slice(&bytes[from..from + take]);
            if got.len() == HEAD {
                check_head(got, *len).map_err(|e| {
                    format!(
                        "{e} at byte {}, where the inventory places {}",
                        m.start,
                        describe(m)
                    )
                })?;
            }
        }
        Ok(())
    }
}

/// One indicator section against the message length the inventory gives.
fn check_head(h: &[u8], len: u64) -> Result<(), String> {
    if &h[..4] != b"GRIB" {
        return Err("no GRIB message starts".into());
    }
    if h[7] != 2 {
        return Err(format!(
            "a GRIB edition {} message, not GRIB2, starts",
            h[7]
        ));
    }
    let mut total = [0u8; 8];
    total.copy_from_slice(&h[8..16]);
    let total = u64::from_be_bytes(total);
    if total > MAX_MESSAGE_BYTES {
        return Err(format!(
            "a GRIB2 message declaring {total} bytes, more than a GFS message can be, starts"
        ));
    }
    if total != len {
        return Err(format!(
            "a GRIB2 message of {total} bytes where the inventory gives {len} starts"
        ));
    }
    Ok(())
}

/// What is wrong with one message's bytes.
#[derive(Debug)]
pub enum Problem {
    /// They are not the message the inventory lists there (another message, or no message).
    NotListed(String),
    /// They are that message, but damaged: it does not validate, its data do not decode, or
    /// its values are not plausible.
    Damaged(String),
}

/// Check one whole message `msg` (exactly its bytes) against its inventory entry `m`: a valid
/// GRIB2 message of the fields its lines name (see [`check_against_inventory`]), every field's
/// data decoding to values plausible for its parameter ([`PLAUSIBLE`]).
pub fn check_message(msg: &[u8], m: &IdxMessage) -> Result<(), Problem> {
    let what = describe(m);
    if !msg.starts_with(b"GRIB") {
        return Err(Problem::NotListed(format!(
            "no GRIB message starts at byte {}, where the inventory places {what}",
            m.start
        )));
    }
    let fields = grib::validate_message(msg)
        .map_err(|e| Problem::Damaged(format!("{what}: not a valid GRIB2 message: {e}")))?;
    check_against_inventory(m, &fields).map_err(Problem::NotListed)?;
    for f in &fields {
        let field =
            grib::decode_values(msg, f).map_err(|e| Problem::Damaged(format!("{what}: {e}")))?;
        plausible(f, &field.values).map_err(|e| Problem::Damaged(format!("{what}: {e}")))?;
    }
    Ok(())
}

/// The fields of one message against its inventory lines: as many, and each of the parameter,
/// isobaric level and run its line names (where stratus knows the name).
pub fn check_against_inventory(m: &IdxMessage, fields: &[MessageInfo]) -> Result<(), String> {
    if fields.len() != m.lines.len() {
        return Err(format!(
            "the message at byte {} holds {} field(s), the inventory lists {}",
            m.start,
            fields.len(),
            m.lines.len()
        ));
    }
    for (line, f) in m.lines.iter().zip(fields) {
        let is = format!("{} {}", idx::ncep_name(f), idx::level_text(f));
        let says = format!("{} {}", line.name, line.level);
        let wrong_param = idx::parameter_of(&line.name).is_some_and(|p| p != f.parameter());
        let wrong_level = select::mb_of(&line.level)
            .is_some_and(|p| f.pressure_hpa().is_none_or(|q| (p - q).abs() > 1e-6));
        let wrong_run = f
            .reference_time
            .is_some_and(|t| t.format("%Y%m%d%H").to_string() != line.date);
        if wrong_param || wrong_level || wrong_run {
            return Err(format!(
                "the message at byte {} is {is} of d={}, the inventory says {says} of d={}",
                m.start,
                f.reference_time
                    .map_or_else(|| "?".into(), |t| t.format("%Y%m%d%H").to_string()),
                line.date
            ));
        }
    }
    Ok(())
}

/// Values a parameter can take ([`Bound`]).
/// Wide enough for any real atmosphere at any GFS level (the top is 0.01 hPa, ~80 km), narrow
/// enough that a damaged data section shows. GFS's post-processor caps RH at 100 %: every RH
/// field in seven data-samples files (2.5° and 0.25°) peaks at 100.000003 % (packing), so the
/// bound is 101 %, a margin for packing only (a tampered range's 102.5 % is refused); TCDC
/// likewise. The extremes seen in data-samples are printed by the test below. Missing points
/// (NaN from a bit-map) are not values. Other parameters are checked for finite values only
/// (the decoder refuses infinities).
pub const PLAUSIBLE: [Bound; 16] = [
    bound((0, 1, 1), "RH", 0.0, 101.0, "%"),
    bound((0, 6, 1), "TCDC", 0.0, 101.0, "%"),
    bound((0, 3, 5), "HGT", -2_000.0, 100_000.0, "gpm"),
    bound((0, 2, 2), "UGRD", -300.0, 300.0, "m/s"),
    bound((0, 2, 3), "VGRD", -300.0, 300.0, "m/s"),
    bound((0, 0, 0), "TMP", 100.0, 400.0, "K"),
    bound((0, 1, 0), "SPFH", -0.001, 0.1, "kg/kg"),
    bound((0, 2, 8), "VVEL", -200.0, 200.0, "Pa/s"),
    bound((0, 3, 0), "PRES", 0.0, 110_000.0, "Pa"),
    bound((0, 1, 22), "CLMR", -0.001, 0.1, "kg/kg"),
    bound((0, 1, 23), "ICMR", -0.001, 0.1, "kg/kg"),
    bound((0, 1, 24), "RWMR", -0.001, 0.1, "kg/kg"),
    bound((0, 1, 25), "SNMR", -0.001, 0.1, "kg/kg"),
    bound((0, 14, 192), "O3MR", -1e-5, 1e-3, "kg/kg"),
    bound((0, 2, 10), "ABSV", -0.1, 0.1, "1/s"),
    bound((2, 0, 0), "LAND", 0.0, 1.0, "(fraction)"),
];

/// A parameter's plausible values.
#[derive(Debug, Clone, Copy)]
pub struct Bound {
    /// (discipline, category, number).
    pub parameter: (u8, u8, u8),
    /// NCEP's name.
    pub name: &'static str,
    pub least: f64,
    pub most: f64,
    pub unit: &'static str,
}

const fn bound(
    parameter: (u8, u8, u8),
    name: &'static str,
    least: f64,
    most: f64,
    unit: &'static str,
) -> Bound {
    Bound {
        parameter,
        name,
        least,
        most,
        unit,
    }
}

/// Every value of a decoded field within its parameter's [`PLAUSIBLE`] range.
pub fn plausible(info: &MessageInfo, values: &[f64]) -> Result<(), String> {
    let Some(&Bound {
        name,
        least: lo,
        most: hi,
        unit,
        ..
    }) = PLAUSIBLE.iter().find(|p| p.parameter == info.parameter())
    else {
        return Ok(());
    };
    let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in values.iter().filter(|v| !v.is_nan()) {
        min = min.min(v);
        max = max.max(v);
    }
    if min < lo || max > hi {
        let bad = if min < lo { min } else { max };
        return Err(format!(
            "its data decode to {name} {bad} {unit}, outside {lo}..={hi} {unit}, what {name} can be: the data section is damaged"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(rel: &str) -> Vec<u8> {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../data-samples")
            .join(rel);
        std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    }

    /// Every field of every real GFS file in data-samples is plausible; prints each checked
    /// parameter's extremes (what the bounds were chosen against).
    #[test]
    fn real_fields_are_plausible() {
        let files = [
            "gfs-series/gfs.t18z.pgrb2.2p50.f000",
            "gfs-series/gfs.t18z.pgrb2.2p50.f006",
            "gfs-series-poland/gfs.20200804.t12z.pgrb2.0p25.f000",
            "gfs-series-poland/gfs.20200804.t12z.pgrb2.0p25.f006",
            "gfs-series-poland/gfs.20200804.t12z.pgrb2.0p25.f012",
            "gfs/gfs.t12z.pgrbf120.2p5deg.grib2",
            "gfs/gfs.t18z.pgrb2.0p25.f186-RH.grib2",
        ];
        let mut extremes: Vec<(&str, f64, f64)> = Vec::new();
        for f in files {
            let bytes = sample(f);
            for info in grib::scan(&bytes).unwrap() {
                let Ok(field) = grib::decode_values(&bytes, &info) else {
                    continue;
                };
                plausible(&info, &field.values).unwrap_or_else(|e| panic!("{f}: {e}"));
                if let Some(p) = PLAUSIBLE.iter().find(|p| p.parameter == info.parameter()) {
                    let v = field.values.iter().filter(|v| !v.is_nan());
                    let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                        (a.min(x), b.max(x))
                    });
                    match extremes.iter_mut().find(|e| e.0 == p.name) {
                        Some(e) => *e = (e.0, e.1.min(lo), e.2.max(hi)),
                        None => extremes.push((p.name, lo, hi)),
                    }
                }
            }
        }
        for (name, lo, hi) in &extremes {
            println!("{name}: {lo} .. {hi}");
        }
        assert!(extremes.iter().any(|e| e.0 == "RH"));
    }

    #[test]
    fn heads_are_checked_as_they_arrive() {
        let inv =
            idx::parse("1:0:d=2015091218:RH:500 mb:anl:\n2:100:d=2015091218:RH:850 mb:anl:\n")
                .unwrap();
        let mut head = b"GRIB\0\0\0\x02".to_vec();
        head.extend_from_slice(&100u64.to_be_bytes());
        // Whole and right, fed a byte at a time.
        let mut w = HeadWatch::new(&inv[..1], 0, 100);
        for (i, b) in head.iter().enumerate() {
            w.feed(i as u64, std::slice::from_ref(b)).unwrap();
        }
        // Zeros fail at the 16th byte.
        let mut w = HeadWatch::new(&inv[..1], 0, 100);
        w.feed(0, &[0; 15]).unwrap();
        let e = w.feed(15, &[0]).unwrap_err();
        assert!(
            e.contains("no GRIB message starts at byte 0") && e.contains("RH 500 mb"),
            "{e}"
        );
        // A message of another length.
        let mut w = HeadWatch::new(&inv[1..], 100, 50);
        let e = w.feed(0, &head).unwrap_err();
        assert!(
            e.contains("of 100 bytes where the inventory gives 50"),
            "{e}"
        );
    }
}
