//! Cut the embedded real GFS sample out of a full GFS GRIB2 file: whole messages copied byte for
//! byte, in file order, no re-encoding. A message is kept when any field in it matches a rule
//! below, so NCEP's u+v messages (two fields in one message) travel whole.
//!
//! ```sh
//! cargo run -p stratus-ingest --example cut_sample -- \
//!     data-samples/gfs/gfs.t12z.pgrbf120.2p5deg.grib2 data-samples/gfs-2011011012-f120-2p5.grib2
//! ```
//!
//! The selection is the table `RULES`; `data-samples/README.md` says what each rule is for. The
//! output is a pure function of the input bytes and this table (same input → same output bytes).

use std::collections::BTreeMap;
use std::path::PathBuf;

use stratus_ingest::grib;

/// Any pressure level.
const ALL: (f64, f64) = (0.0, f64::INFINITY);
/// The levels the cloud model reads by default (1000 hPa up to the default top, 100 hPa).
const TROPOSPHERE: (f64, f64) = (100.0, f64::INFINITY);

/// One kept field: (what, discipline, category, number, level types, pressure range in hPa
/// for isobaric levels (level type 100), inclusive).
type Rule = (&'static str, u8, u8, u8, &'static [u8], (f64, f64));

#[rustfmt::skip]
const RULES: &[Rule] = &[
    // Isobaric levels: what the CloudMap and the next issues read.
    ("r: relative humidity, every level",               0, 1, 1,   &[100], ALL),
    ("gh: geopotential height, every level",            0, 3, 5,   &[100], ALL),
    ("t: temperature, every level",                     0, 0, 0,   &[100], ALL),
    ("u+v: wind (one message), 1000-100 hPa",           0, 2, 2,   &[100], TROPOSPHERE),
    ("clwmr: cloud water mixing ratio, every level",    0, 1, 22,  &[100], ALL),
    // GFS's own cloud layers: cover (entire atmosphere, boundary layer, low, middle, high,
    // convective), bottom/top pressure, top temperature.
    ("tcc: total cloud cover by layer",                 0, 6, 1,   &[200, 211, 214, 224, 234, 244], ALL),
    ("pres: cloud bottom/top pressure",                 0, 3, 0,   &[212, 213, 222, 223, 232, 233, 242, 243], ALL),
    ("t: cloud top temperature",                        0, 0, 0,   &[213, 223, 233], ALL),
    ("cwat: cloud water, entire atmosphere",            0, 6, 6,   &[200], ALL),
    // Convection.
    ("cape: surface and 180-0 hPa above ground",        0, 7, 6,   &[1, 108], ALL),
    ("cin: surface and 180-0 hPa above ground",         0, 7, 7,   &[1, 108], ALL),
    ("lftx: surface lifted index",                      0, 7, 192, &[1], ALL),
    ("4lftx: best (4-layer) lifted index",              0, 7, 193, &[1], ALL),
    ("acpcp: convective precipitation",                 0, 1, 10,  &[1], ALL),
    ("cprat: convective precipitation rate",            0, 1, 196, &[1], ALL),
    // Tropopause (level type 7).
    ("pres: tropopause pressure",                       0, 3, 0,   &[7], ALL),
    ("gh: tropopause height",                           0, 3, 5,   &[7], ALL),
    ("t: tropopause temperature",                       0, 0, 0,   &[7], ALL),
    ("u+v: tropopause wind (one message)",              0, 2, 2,   &[7], ALL),
    // The ground (level type 1, surface).
    ("orog: surface geopotential height",               0, 3, 5,   &[1], ALL),
    ("sp: surface pressure",                            0, 3, 0,   &[1], ALL),
    ("t: surface temperature",                          0, 0, 0,   &[1], ALL),
    ("lsm: land cover (1 land, 0 sea)",                 2, 0, 0,   &[1], ALL),
    ("ci: ice cover",                                   10, 2, 0,  &[1], ALL),
    ("sdwe: water equivalent of accumulated snow depth", 0, 1, 13, &[1], ALL),
    ("al: albedo",                                      0, 19, 1,  &[1], ALL),
];

fn rule_of(m: &grib::MessageInfo) -> Option<usize> {
    RULES.iter().position(|&(_, d, c, n, levels, (lo, hi))| {
        let level = m.level_type.map(|t| t.code());
        (m.discipline.code(), m.category, m.number) == (d, c, n)
            && level.is_some_and(|t| levels.contains(&t))
            && (level != Some(100) || m.pressure_hpa().is_some_and(|p| p >= lo && p <= hi))
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [input, output] = args.as_slice() else {
        return Err("usage: cut_sample IN.grib2 OUT.grib2".into());
    };
    let bytes = std::fs::read(input)?;
    let fields = grib::scan(&bytes)?;

    // Message index → (offset, length, rules that matched one of its fields).
    let mut messages: BTreeMap<usize, (usize, usize, Vec<usize>)> = BTreeMap::new();
    let mut n_messages = 0;
    for f in &fields {
        n_messages = n_messages.max(f.index + 1);
        let entry = messages
            .entry(f.index)
            .or_insert((f.offset, f.length, Vec::new()));
        if let Some(r) = rule_of(f) {
            entry.2.push(r);
        }
    }

    let mut out = Vec::new();
    let mut per_rule = vec![0usize; RULES.len()];
    let mut kept = 0;
    for (&index, (offset, length, rules)) in &messages {
        if rules.is_empty() {
            continue;
        }
        let msg = &bytes[*offset..*offset + *length];
        // Independent of the scanner: a GRIB2 message starts "GRIB", its edition (octet 8) is 2,
        // its total length is octets 9-16 of section 0 (big-endian) and it ends "7777".
        let declared = u64::from_be_bytes(msg[8..16].try_into()?);
        if &msg[..4] != b"GRIB"
            || msg[7] != 2
            || declared != *length as u64
            || !msg.ends_with(b"7777")
        {
            return Err(
                format!("message {index} at byte {offset} is not a whole GRIB2 message").into(),
            );
        }
        out.extend_from_slice(msg);
        kept += 1;
        for &r in rules {
            per_rule[r] += 1;
        }
    }
    for (r, n) in RULES.iter().zip(&per_rule) {
        println!("{n:>3}  {}", r.0);
        if *n == 0 {
            eprintln!(
                "warning: no field in {} matches \"{}\"",
                input.display(),
                r.0
            );
        }
    }
    // The cut must scan as cleanly as the original, one message for each message kept.
    let check = grib::scan(&out)?;
    let check_msgs = check.last().map_or(0, |m| m.index + 1);
    if check_msgs != kept {
        return Err(format!("the cut scans as {check_msgs} messages, {kept} were written").into());
    }
    std::fs::write(output, &out)?;
    println!(
        "{}: kept {kept} of {n_messages} messages ({} fields), {} of {} bytes",
        output.display(),
        check.len(),
        out.len(),
        bytes.len()
    );
    Ok(())
}
