//! What to fetch: field names (stratus' short names or NCEP's), isobaric levels, forecast steps,
//! and which inventory messages they pick.

use super::idx::IdxMessage;

/// The fields fetched when none are named: relative humidity (the clouds) and what the
/// renderer and a flight use beside it — geopotential height, wind, GFS's own cloud-layer
/// cover, orography and the land mask.
pub const DEFAULT_FIELDS: &str = "r,gh,u,v,tcc,orog,lsm";

/// Default isobaric levels, hPa: the troposphere ingest folds into cloud layers.
pub const DEFAULT_LEVELS: &str = "1000-100";

/// Which levels a field is taken on.
#[derive(Debug, Clone, PartialEq)]
pub enum LevelMatch {
    /// Isobaric levels (`N mb`), filtered by [`Levels`].
    Isobaric,
    /// Exactly these wgrib2 level texts.
    Named(Vec<String>),
}

/// One field asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldSpec {
    /// What the user wrote.
    pub asked: String,
    /// NCEP short name in the inventory.
    pub ncep: String,
    pub levels: LevelMatch,
    /// An error when the inventory lacks it; the default fields besides RH are taken only
    /// where present (a step-0 file has no cloud-layer averages).
    pub required: bool,
}

/// stratus' (ecCodes') short names → (NCEP name, level). `None` for the level: isobaric.
const ALIASES: [(&str, &str, Option<&[&str]>); 16] = [
    ("r", "RH", None),
    ("gh", "HGT", None),
    ("u", "UGRD", None),
    ("v", "VGRD", None),
    ("t", "TMP", None),
    ("q", "SPFH", None),
    ("w", "VVEL", None),
    ("clwmr", "CLMR", None),
    ("icmr", "ICMR", None),
    ("o3mr", "O3MR", None),
    ("absv", "ABSV", None),
    (
        "tcc",
        "TCDC",
        Some(&["low cloud layer", "middle cloud layer", "high cloud layer"]),
    ),
    (
        "cloudbase",
        "PRES",
        Some(&[
            "low cloud bottom level",
            "middle cloud bottom level",
            "high cloud bottom level",
        ]),
    ),
    (
        "cloudtop",
        "PRES",
        Some(&[
            "low cloud top level",
            "middle cloud top level",
            "high cloud top level",
        ]),
    ),
    ("orog", "HGT", Some(&["surface"])),
    ("lsm", "LAND", Some(&["surface"])),
];

/// Parse `--fields`: comma-separated names. A name is one of stratus' short names (`r`, `gh`,
/// `u`, `v`, `t`, `q`, `w`, `clwmr`, `icmr`, `o3mr`, `absv` on isobaric levels; `tcc` on the
/// three cloud layers; `cloudbase`/`cloudtop` the layers' pressures; `orog`, `lsm`) or an
/// NCEP name in capitals (`TMP`, on isobaric levels), and may name its level with `@`:
/// `TMP@2 m above ground`, `tcc@entire atmosphere`.
pub fn parse_fields(s: &str) -> Result<Vec<FieldSpec>, String> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (name, level) = match part.split_once('@') {
            Some((n, l)) => (n.trim(), Some(l.trim().to_string())),
            None => (part, None),
        };
        let (ncep, default) = match ALIASES.iter().find(|a| a.0 == name) {
            Some(a) => (a.1.to_string(), a.2),
            None if !name.is_empty()
                && name
                    .chars()
                    .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_') =>
            {
                (name.to_string(), None)
            }
            None => {
                let known: Vec<&str> = ALIASES.iter().map(|a| a.0).collect();
                return Err(format!(
                    "unknown field \"{name}\": use one of {} or an NCEP name in capitals (TMP, SPFH…)",
                    known.join(", ")
                ));
            }
        };
        let levels = match (level, default) {
            (Some(l), _) => LevelMatch::Named(vec![l]),
            (None, Some(d)) => LevelMatch::Named(d.iter().map(|x| x.to_string()).collect()),
            (None, None) => LevelMatch::Isobaric,
        };
        out.push(FieldSpec {
            asked: part.to_string(),
            ncep,
            levels,
            required: true,
        });
    }
    if out.is_empty() {
        return Err("--fields names no field".into());
    }
    Ok(out)
}

/// The fields fetched when `--fields` is not given ([`DEFAULT_FIELDS`]): RH required, the
/// others where the inventory has them.
pub fn default_fields() -> Vec<FieldSpec> {
    let mut f = parse_fields(DEFAULT_FIELDS).unwrap_or_default();
    for x in f.iter_mut().filter(|x| x.ncep != "RH") {
        x.required = false;
    }
    f
}

/// Isobaric levels (hPa) to take.
#[derive(Debug, Clone, PartialEq)]
pub enum Levels {
    All,
    /// Every level within the range, inclusive (either order).
    Range(f64, f64),
    /// Exactly these; each must be in the inventory.
    List(Vec<f64>),
}

/// Parse `--levels`: `all`, a range `1000-100`, or a list `850,500,300` (hPa).
pub fn parse_levels(s: &str) -> Result<Levels, String> {
    let s = s.trim();
    let bad =
        || format!("--levels \"{s}\" must be all, a range like 1000-100, or a list like 850,500");
    if s == "all" {
        return Ok(Levels::All);
    }
    let ok = |x: f64| x.is_finite() && x > 0.0 && x <= 1100.0;
    if let Some((a, b)) = s.split_once('-') {
        let (a, b) = (a.trim().parse::<f64>(), b.trim().parse::<f64>());
        return match (a, b) {
            (Ok(a), Ok(b)) if ok(a) && ok(b) => Ok(Levels::Range(a.min(b), a.max(b))),
            _ => Err(bad()),
        };
    }
    let v: Result<Vec<f64>, _> = s.split(',').map(|p| p.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if !v.is_empty() && v.iter().all(|&x| ok(x)) => Ok(Levels::List(v)),
        _ => Err(bad()),
    }
}

/// The hPa of an isobaric level text (`500 mb`), if it is one.
pub fn mb_of(level: &str) -> Option<f64> {
    level.strip_suffix(" mb")?.trim().parse().ok()
}

impl Levels {
    /// `100-1000 mb`, `850, 500 mb`, `every isobaric level`.
    pub fn describe(&self) -> String {
        match self {
            Levels::All => "any isobaric level".into(),
            Levels::Range(a, b) => format!("{a}-{b} mb"),
            Levels::List(v) => {
                let v: Vec<String> = v.iter().map(|x| x.to_string()).collect();
                format!("{} mb", v.join(", "))
            }
        }
    }

    fn takes(&self, hpa: f64) -> bool {
        match self {
            Levels::All => true,
            Levels::Range(lo, hi) => hpa >= lo - 1e-9 && hpa <= hi + 1e-9,
            Levels::List(v) => v.iter().any(|&x| (x - hpa).abs() < 1e-6),
        }
    }
}

/// Parse `--step`: `H`, `H,H,…`, or `A-B/S` (every S hours from A to B), mixable with commas.
/// Returns the steps sorted, without repeats.
pub fn parse_steps(s: &str) -> Result<Vec<u32>, String> {
    let bad = || format!("--step \"{s}\" must be hours: 6, 0,6,12 or 0-24/3");
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim) {
        if let Some((range, by)) = part.split_once('/') {
            let (a, b) = range.split_once('-').ok_or_else(bad)?;
            let (a, b, by): (u32, u32, u32) = (
                a.trim().parse().map_err(|_| bad())?,
                b.trim().parse().map_err(|_| bad())?,
                by.trim().parse().map_err(|_| bad())?,
            );
            // Bounded before expanding, so a huge range is refused, not built.
            if by == 0 || a > b || b > 9999 {
                return Err(bad());
            }
            out.extend((a..=b).step_by(by as usize));
        } else {
            out.push(part.parse().map_err(|_| bad())?);
        }
    }
    if out.iter().any(|&h| h > 9999) {
        return Err(bad());
    }
    out.sort_unstable();
    out.dedup();
    if out.len() > 1000 {
        return Err(format!(
            "--step \"{s}\" names {} steps; at most 1000",
            out.len()
        ));
    }
    Ok(out)
}

/// The messages of `inventory` the fields and levels pick, in file order. An error names a
/// field (or a listed level) the inventory does not have.
pub fn pick(
    inventory: &[IdxMessage],
    fields: &[FieldSpec],
    levels: &Levels,
) -> Result<Vec<IdxMessage>, String> {
    let line_takes = |f: &FieldSpec, name: &str, level: &str| {
        f.ncep == name
            && match &f.levels {
                LevelMatch::Isobaric => mb_of(level).is_some_and(|p| levels.takes(p)),
                LevelMatch::Named(l) => l.iter().any(|x| x == level),
            }
    };
    for f in fields {
        let found: Vec<&str> = inventory
            .iter()
            .flat_map(|m| &m.lines)
            .filter(|l| line_takes(f, &l.name, &l.level))
            .map(|l| l.level.as_str())
            .collect();
        if found.is_empty() && !f.required {
            continue;
        }
        if found.is_empty() {
            let mut has: Vec<&str> = Vec::new();
            for l in inventory.iter().flat_map(|m| &m.lines) {
                if l.name == f.ncep && !has.contains(&l.level.as_str()) {
                    has.push(&l.level);
                }
            }
            return Err(if has.is_empty() {
                format!("the inventory has no {} ({})", f.ncep, f.asked)
            } else {
                format!(
                    "the inventory has no {} ({}) at {}; it has it at: {}",
                    f.ncep,
                    f.asked,
                    match &f.levels {
                        LevelMatch::Isobaric => levels.describe(),
                        LevelMatch::Named(l) => l.join(", "),
                    },
                    levels_listed(&has)
                )
            });
        }
        if let (Levels::List(want), LevelMatch::Isobaric) = (levels, &f.levels) {
            for &p in want {
                if !found
                    .iter()
                    .any(|l| mb_of(l).is_some_and(|x| (x - p).abs() < 1e-6))
                {
                    return Err(format!(
                        "the inventory has no {} ({}) at {p} mb",
                        f.ncep, f.asked
                    ));
                }
            }
        }
    }
    Ok(inventory
        .iter()
        .filter(|m| {
            m.lines
                .iter()
                .any(|l| fields.iter().any(|f| line_takes(f, &l.name, &l.level)))
        })
        .cloned()
        .collect())
}

/// Every level of a list, or the first [`LISTED_LEVELS`] and how many more (a hostile inventory
/// may hold thousands): a cut list says that it is cut.
fn levels_listed(levels: &[&str]) -> String {
    if levels.len() <= LISTED_LEVELS {
        return levels.join(", ");
    }
    format!(
        "{}, … and {} more",
        levels[..LISTED_LEVELS].join(", "),
        levels.len() - LISTED_LEVELS
    )
}

/// GFS writes a parameter at up to 41 isobaric levels (0.25°): all of them are listed.
const LISTED_LEVELS: usize = 48;

#[cfg(test)]
mod tests {
    use super::super::idx::parse;
    use super::*;

    const INV: &str = "1:0:d=2024010100:HGT:1000 mb:6 hour fcst:\n\
                       2:1000:d=2024010100:RH:1000 mb:6 hour fcst:\n\
                       3:2000:d=2024010100:RH:500 mb:6 hour fcst:\n\
                       4:3000:d=2024010100:RH:10 mb:6 hour fcst:\n\
                       5:4000:d=2024010100:TCDC:low cloud layer:0-6 hour ave fcst:\n\
                       6:5000:d=2024010100:HGT:surface:6 hour fcst:\n\
                       7:6000:d=2024010100:TMP:2 m above ground:6 hour fcst:\n";

    #[test]
    fn steps() {
        assert_eq!(parse_steps("6").unwrap(), vec![6]);
        assert_eq!(parse_steps("12,0,6,6").unwrap(), vec![0, 6, 12]);
        assert_eq!(parse_steps("0-12/6,3").unwrap(), vec![0, 3, 6, 12]);
        for bad in [
            "",
            "x",
            "6-0/3",
            "0-6/0",
            "0-6",
            "-1",
            "0-99999/1",
            "0-4000000000/1",
        ] {
            assert!(parse_steps(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn levels_and_fields() {
        assert_eq!(
            parse_levels("100-1000").unwrap(),
            Levels::Range(100.0, 1000.0)
        );
        assert_eq!(
            parse_levels("850, 500").unwrap(),
            Levels::List(vec![850.0, 500.0])
        );
        assert!(parse_levels("0-1000").is_err() && parse_levels("a").is_err());
        let f = parse_fields("r,orog,TMP@2 m above ground").unwrap();
        assert_eq!(f[0].ncep, "RH");
        assert_eq!(f[1].levels, LevelMatch::Named(vec!["surface".into()]));
        assert_eq!(
            f[2].levels,
            LevelMatch::Named(vec!["2 m above ground".into()])
        );
        assert!(parse_fields("rh").unwrap_err().contains("unknown field"));
        assert_eq!(default_fields().iter().filter(|f| f.required).count(), 1);
    }

    #[test]
    fn picks_by_name_and_level() {
        let inv = parse(INV).unwrap();
        let lv = parse_levels(DEFAULT_LEVELS).unwrap();
        let p = pick(&inv, &parse_fields("r").unwrap(), &lv).unwrap();
        assert_eq!(
            p.iter().map(|m| m.start).collect::<Vec<_>>(),
            vec![1000, 2000]
        );
        let p = pick(
            &inv,
            &parse_fields("orog,tcc,TMP@2 m above ground").unwrap(),
            &lv,
        )
        .unwrap();
        assert_eq!(
            p.iter().map(|m| m.start).collect::<Vec<_>>(),
            vec![4000, 5000, 6000]
        );
        // The default set skips what is absent (no wind here).
        let p = pick(&inv, &default_fields(), &lv).unwrap();
        assert_eq!(
            p.iter().map(|m| m.start).collect::<Vec<_>>(),
            vec![0, 1000, 2000, 4000, 5000]
        );
        let e = pick(&inv, &parse_fields("u").unwrap(), &lv).unwrap_err();
        assert!(e.contains("no UGRD"), "{e}");
        let e = pick(
            &inv,
            &parse_fields("r").unwrap(),
            &Levels::List(vec![925.0]),
        )
        .unwrap_err();
        assert!(e.contains("925"), "{e}");
    }
}
