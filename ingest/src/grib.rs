//! GRIB2 message scanning, validation and decoding.
//!
//! The scanner reads section headers itself (WMO FM 92 GRIB edition 2) so that `inspect` never
//! decodes data and so that every size a file declares is checked against the bytes it really
//! has before anything is allocated for it. Data decoding is delegated to `gribberish`, on the
//! byte slice of one validated message only, with its panics contained (gribberish 1.9 can panic
//! on corrupted data sections) and its silent skip of a cut-off last message made loud.

use chrono::{DateTime, Duration, NaiveDate, Utc};
use std::fmt;
use thiserror::Error;

/// Largest grid accepted (points). A 0.1° global grid is 6.5 M; this leaves room for finer ones
/// while refusing headers that would make a multi-gigabyte allocation.
pub const MAX_POINTS: u64 = 64 * 1024 * 1024;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum GribError {
    #[error("empty file")]
    Empty,
    #[error("not a GRIB file (no 'GRIB' marker in its first {0} bytes)")]
    NotGrib(usize),
    #[error("message {index} at byte {offset} is GRIB edition 1, which stratus does not read; convert it with ecCodes: grib_set -s edition=2 IN OUT")]
    Edition1 { index: usize, offset: usize },
    #[error("message {index} at byte {offset} has unknown GRIB edition {edition}")]
    BadEdition {
        index: usize,
        offset: usize,
        edition: u8,
    },
    #[error("file is cut off: message {index} at byte {offset} declares {declared} bytes but only {available} remain")]
    CutOff {
        index: usize,
        offset: usize,
        declared: u64,
        available: usize,
    },
    #[error("message {index} at byte {offset} is corrupt: {msg}")]
    Corrupt {
        index: usize,
        offset: usize,
        msg: String,
    },
    #[error("message {index} at byte {offset} cannot be decoded: {msg}")]
    Unsupported {
        index: usize,
        offset: usize,
        msg: String,
    },
}

/// A regular latitude/longitude grid (template 3.0), normalised to rows from north to south.
#[derive(Debug, Clone, PartialEq)]
pub struct LatLonGrid {
    pub ni: usize,
    pub nj: usize,
    /// Latitude of the first and last row as stored (scan order), degrees.
    pub lat1: f64,
    pub lat2: f64,
    pub lon1: f64,
    pub lon2: f64,
    pub di: f64,
    pub dj: f64,
    pub scan_mode: u8,
}

impl LatLonGrid {
    /// Northernmost latitude (row 0 after normalisation).
    pub fn north(&self) -> f64 {
        self.lat1.max(self.lat2)
    }
    pub fn south(&self) -> f64 {
        self.lat1.min(self.lat2)
    }
    /// Westernmost longitude (column 0 after normalisation).
    pub fn west(&self) -> f64 {
        if self.scan_mode & 0x80 != 0 {
            self.lon2
        } else {
            self.lon1
        }
    }
    /// True when the columns cover the whole circle (wrap in longitude).
    pub fn is_global(&self) -> bool {
        (self.ni as f64 * self.di - 360.0).abs() < 1e-3 * self.di.max(1e-9)
    }
}

/// Everything `inspect` shows and `decode_values` needs about one message, from headers only.
#[derive(Debug, Clone)]
pub struct MessageInfo {
    /// Message number in the file (0-based) and field number inside it (0-based; GRIB2 lets
    /// one message carry several fields by repeating sections 2/3/4–7, as NCEP does for u/v).
    pub index: usize,
    pub field: usize,
    pub offset: usize,
    pub length: usize,
    pub discipline: u8,
    pub category: u8,
    pub number: u8,
    pub product_template: u16,
    pub level_type: u8,
    /// Level value in the level type's SI unit (Pa for isobaric), None when missing.
    pub level_value: Option<f64>,
    pub level2_type: u8,
    pub level2_value: Option<f64>,
    pub grid_template: u16,
    pub grid: Option<LatLonGrid>,
    /// Number of grid points (section 3).
    pub grid_points: u64,
    /// Number of values packed (section 5).
    pub packed_values: u64,
    pub packing_template: u16,
    /// Bit-map indicator of section 6 (0 = bit-map follows, 255 = none).
    pub bitmap_indicator: u8,
    pub reference_time: Option<DateTime<Utc>>,
    pub step_hours: Option<f64>,
    // Byte ranges (message-relative) of the sections this field uses; section 6 may be one
    // inherited from an earlier field (indicator 254).
    sec1: (usize, usize),
    sec2: Option<(usize, usize)>,
    sec3: (usize, usize),
    sec4: (usize, usize),
    sec5: (usize, usize),
    sec6: (usize, usize),
    sec7: (usize, usize),
}

impl MessageInfo {
    /// Short name (ecCodes convention) where known, else `d.c.n`.
    pub fn short_name(&self) -> String {
        let known = match (self.discipline, self.category, self.number) {
            (0, 0, 0) => "t",
            (0, 0, 2) => "pt",
            (0, 0, 4) => "tmax",
            (0, 0, 5) => "tmin",
            (0, 0, 6) => "dpt",
            (0, 1, 0) => "q",
            (0, 1, 1) => "r",
            (0, 1, 3) => "pwat",
            (0, 1, 8) => "tp",
            (0, 1, 22) => "clwmr",
            (0, 1, 23) => "icmr",
            (0, 1, 24) => "rwmr",
            (0, 1, 25) => "snmr",
            (0, 2, 2) => "u",
            (0, 2, 3) => "v",
            (0, 2, 8) => "w",
            (0, 2, 10) => "absv",
            (0, 2, 14) => "pv",
            (0, 2, 22) => "gust",
            (0, 3, 0) => "pres",
            (0, 3, 1) => "prmsl",
            (0, 3, 5) => "gh",
            (0, 6, 1) => "tcc",
            (0, 7, 6) => "cape",
            (0, 7, 7) => "cin",
            (0, 19, 0) => "vis",
            (0, 14, 192) => "o3mr",
            _ => "",
        };
        if known.is_empty() {
            format!("{}.{}.{}", self.discipline, self.category, self.number)
        } else {
            known.to_string()
        }
    }

    pub fn is_relative_humidity(&self) -> bool {
        (self.discipline, self.category, self.number) == (0, 1, 1)
    }

    /// Pressure in hPa when the first surface is isobaric.
    pub fn pressure_hpa(&self) -> Option<f64> {
        (self.level_type == 100)
            .then_some(self.level_value)
            .flatten()
            .map(|pa| pa / 100.0)
    }

    /// Human-readable level, e.g. `isobaric 400 hPa`, `low cloud layer`.
    pub fn level_text(&self) -> String {
        let v = self.level_value;
        let num = |unit: &str, scale: f64| match v {
            Some(x) => format!("{} {unit}", trim_num(x / scale)),
            None => String::new(),
        };
        match self.level_type {
            1 => "surface".into(),
            4 => "0°C isotherm".into(),
            6 => "max wind".into(),
            7 => "tropopause".into(),
            10 | 200 => "entire atmosphere".into(),
            100 => format!("isobaric {}", num("hPa", 100.0)),
            101 => "mean sea level".into(),
            102 => format!("altitude {}", num("m", 1.0)),
            103 => format!("height above ground {}", num("m", 1.0)),
            104 => format!("sigma {}", num("", 1.0)),
            106 => format!("depth below land {}", num("m", 1.0)),
            108 => format!("pressure from ground {}", num("hPa", 100.0)),
            109 => format!("PV surface {}", num("PVU", 1e-6)),
            8 => "nominal top of atmosphere".into(),
            204 => "highest freezing level".into(),
            211 => "boundary-layer cloud layer".into(),
            212 => "low cloud bottom".into(),
            213 => "low cloud top".into(),
            214 => "low cloud layer".into(),
            220 => "planetary boundary layer".into(),
            222 => "middle cloud bottom".into(),
            223 => "middle cloud top".into(),
            224 => "middle cloud layer".into(),
            232 => "high cloud bottom".into(),
            233 => "high cloud top".into(),
            234 => "high cloud layer".into(),
            242 => "convective cloud bottom".into(),
            243 => "convective cloud top".into(),
            244 => "convective cloud layer".into(),
            t => format!("level type {t} {}", num("", 1.0)),
        }
        .trim()
        .to_string()
    }

    /// Packing name of the data representation template.
    pub fn packing_text(&self) -> String {
        let name = match self.packing_template {
            0 => "simple",
            2 => "complex",
            3 => "complex+spatial-diff",
            40 => "jpeg2000",
            41 => "png",
            42 => "ccsds",
            _ => "other",
        };
        format!("5.{} {name}", self.packing_template)
    }

    pub fn valid_time(&self) -> Option<DateTime<Utc>> {
        let r = self.reference_time?;
        let s = self.step_hours?;
        Some(r + Duration::seconds((s * 3600.0).round() as i64))
    }
}

fn trim_num(x: f64) -> String {
    if (x - x.round()).abs() < 1e-9 {
        format!("{}", x.round() as i64)
    } else {
        format!("{x:.3}")
    }
}

impl fmt::Display for MessageInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let grid = match &self.grid {
            Some(g) => format!(
                "3.{} {}x{} lat {}..{} lon {}..{}",
                self.grid_template,
                g.ni,
                g.nj,
                trim_num(g.lat1),
                trim_num(g.lat2),
                trim_num(g.lon1),
                trim_num(g.lon2)
            ),
            None => format!("3.{} ({} points)", self.grid_template, self.grid_points),
        };
        let rt = self
            .reference_time
            .map(|t| t.format("%Y-%m-%dT%H:%MZ").to_string())
            .unwrap_or_else(|| "?".into());
        let step = self
            .step_hours
            .map(|s| format!("+{}h", trim_num(s)))
            .unwrap_or_else(|| "?".into());
        write!(
            f,
            "{:>6} {:>9}  {:<7} {:<6} {:<28} {:<44} {:<24} {} {}",
            if self.field == 0 {
                format!("{}", self.index + 1)
            } else {
                format!("{}.{}", self.index + 1, self.field + 1)
            },
            self.offset,
            format!("{}.{}.{}", self.discipline, self.category, self.number),
            self.short_name(),
            self.level_text(),
            grid,
            self.packing_text(),
            rt,
            step
        )
    }
}

// ---- byte readers: every read is bounds-checked against the section it belongs to ----

struct Sec<'a> {
    b: &'a [u8],
    index: usize,
    offset: usize,
    num: u8,
}

impl Sec<'_> {
    /// Octets `from..=to` (1-based, as the WMO tables number them).
    fn bytes(&self, from: usize, to: usize) -> Result<&[u8], GribError> {
        self.b.get(from - 1..to).ok_or_else(|| GribError::Corrupt {
            index: self.index,
            offset: self.offset,
            msg: format!(
                "section {} is {} bytes, too short for octets {from}-{to}",
                self.num,
                self.b.len()
            ),
        })
    }
    fn u8(&self, o: usize) -> Result<u8, GribError> {
        Ok(self.bytes(o, o)?[0])
    }
    fn u16(&self, o: usize) -> Result<u16, GribError> {
        let b = self.bytes(o, o + 1)?;
        Ok(u16::from_be_bytes([b[0], b[1]]))
    }
    fn u32(&self, o: usize) -> Result<u32, GribError> {
        let b = self.bytes(o, o + 3)?;
        Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }
    /// GRIB2 signed integers are sign-and-magnitude, not two's complement.
    fn i32sm(&self, o: usize) -> Result<i32, GribError> {
        let v = self.u32(o)?;
        let mag = (v & 0x7fff_ffff) as i32;
        Ok(if v & 0x8000_0000 != 0 { -mag } else { mag })
    }
    fn i8sm(&self, o: usize) -> Result<i8, GribError> {
        let v = self.u8(o)?;
        let mag = (v & 0x7f) as i8;
        Ok(if v & 0x80 != 0 { -mag } else { mag })
    }
}

/// Scan a whole file: every message is located and its headers validated. A file that is cut
/// off, or whose sections do not tile their message, is an error — never silently shortened.
pub fn scan(bytes: &[u8]) -> Result<Vec<MessageInfo>, GribError> {
    if bytes.is_empty() {
        return Err(GribError::Empty);
    }
    let mut out = Vec::new();
    let mut pos = 0usize;
    loop {
        // Messages may be separated by padding; look for the next marker.
        let Some(rel) = find_marker(&bytes[pos..]) else {
            if out.is_empty() {
                return Err(GribError::NotGrib(bytes.len()));
            }
            break;
        };
        let offset = pos + rel;
        let index = out.last().map_or(0, |m: &MessageInfo| m.index + 1);
        if bytes.len() < offset + 16 {
            return Err(GribError::CutOff {
                index,
                offset,
                declared: 16,
                available: bytes.len() - offset,
            });
        }
        let edition = bytes[offset + 7];
        match edition {
            2 => {}
            1 => return Err(GribError::Edition1 { index, offset }),
            e => {
                return Err(GribError::BadEdition {
                    index,
                    offset,
                    edition: e,
                })
            }
        }
        let mut lenb = [0u8; 8];
        lenb.copy_from_slice(&bytes[offset + 8..offset + 16]);
        let declared = u64::from_be_bytes(lenb);
        let available = bytes.len() - offset;
        if declared > available as u64 {
            return Err(GribError::CutOff {
                index,
                offset,
                declared,
                available,
            });
        }
        let length = declared as usize;
        let msg = &bytes[offset..offset + length];
        out.extend(parse_message(msg, index, offset, bytes[offset + 6])?);
        pos = offset + length;
        if pos >= bytes.len() {
            break;
        }
    }
    Ok(out)
}

fn find_marker(b: &[u8]) -> Option<usize> {
    b.windows(4).position(|w| w == b"GRIB")
}

fn parse_message(
    msg: &[u8],
    index: usize,
    offset: usize,
    discipline: u8,
) -> Result<Vec<MessageInfo>, GribError> {
    let corrupt = |m: String| GribError::Corrupt {
        index,
        offset,
        msg: m,
    };
    if msg.len() < 16 + 4 || &msg[msg.len() - 4..] != b"7777" {
        return Err(corrupt(format!(
            "its {} declared bytes do not end with '7777'",
            msg.len()
        )));
    }
    let mut fields = Vec::new();
    let mut cur = MessageInfo {
        index,
        field: 0,
        offset,
        length: msg.len(),
        discipline,
        category: 255,
        number: 255,
        product_template: 65535,
        level_type: 255,
        level_value: None,
        level2_type: 255,
        level2_value: None,
        grid_template: 65535,
        grid: None,
        grid_points: 0,
        packed_values: 0,
        packing_template: 65535,
        bitmap_indicator: 255,
        reference_time: None,
        step_hours: None,
        sec1: (0, 0),
        sec2: None,
        sec3: (0, 0),
        sec4: (0, 0),
        sec5: (0, 0),
        sec6: (0, 0),
        sec7: (0, 0),
    };
    let mut last_bitmap: Option<(usize, usize)> = None;
    let mut p = 16usize;
    let mut last = 0u8;
    let end = msg.len() - 4;
    while p < end {
        if end - p < 5 {
            return Err(corrupt(format!("{} stray bytes before '7777'", end - p)));
        }
        let len = u32::from_be_bytes([msg[p], msg[p + 1], msg[p + 2], msg[p + 3]]) as usize;
        let num = msg[p + 4];
        if len < 5 || len > end - p {
            return Err(corrupt(format!(
                "section {num} at message byte {p} declares {len} bytes; {} remain",
                end - p
            )));
        }
        // Sections come in order; after a data section 7 a new field may restart at 2, 3 or 4.
        let in_order = (1..=7).contains(&num) && (num > last || (last == 7 && num >= 2));
        if !in_order || (last == 0 && num != 1) {
            return Err(corrupt(format!("section {num} follows section {last}")));
        }
        let s = Sec {
            b: &msg[p..p + len],
            index,
            offset,
            num,
        };
        let range = (p, p + len);
        match num {
            1 => {
                cur.reference_time = reference_time(&s)?;
                cur.sec1 = range;
            }
            2 => cur.sec2 = Some(range),
            3 => {
                parse_grid(&s, &mut cur)?;
                cur.sec3 = range;
            }
            4 => {
                parse_product(&s, &mut cur)?;
                cur.sec4 = range;
            }
            5 => {
                cur.packed_values = s.u32(6)? as u64;
                cur.packing_template = s.u16(10)?;
                cur.sec5 = range;
            }
            6 => {
                cur.bitmap_indicator = s.u8(6)?;
                cur.sec6 = range;
                match cur.bitmap_indicator {
                    0 => last_bitmap = Some(range),
                    254 => {
                        // "Use the bit-map defined earlier in this message."
                        let prev = last_bitmap.ok_or_else(|| {
                            corrupt("bit-map indicator 254 but no earlier bit-map".into())
                        })?;
                        cur.bitmap_indicator = 0;
                        cur.sec6 = prev;
                    }
                    _ => {}
                }
            }
            7 => {
                if last != 6 {
                    return Err(corrupt("data section 7 without a bit-map section 6".into()));
                }
                cur.sec7 = range;
                fields.push(cur.clone());
                cur.field += 1;
            }
            _ => {}
        }
        last = num;
        p += len;
    }
    if last != 7 {
        return Err(corrupt(format!(
            "it ends after section {last}, before the data section 7"
        )));
    }
    Ok(fields)
}

fn reference_time(s: &Sec) -> Result<Option<DateTime<Utc>>, GribError> {
    let (y, mo, d) = (s.u16(13)?, s.u8(15)?, s.u8(16)?);
    let (h, mi, se) = (s.u8(17)?, s.u8(18)?, s.u8(19)?);
    Ok(NaiveDate::from_ymd_opt(y as i32, mo as u32, d as u32)
        .and_then(|dt| dt.and_hms_opt(h as u32, mi as u32, se as u32))
        .map(|n| n.and_utc()))
}

fn parse_grid(s: &Sec, info: &mut MessageInfo) -> Result<(), GribError> {
    info.grid_points = s.u32(7)? as u64;
    info.grid_template = s.u16(13)?;
    if info.grid_template != 0 {
        return Ok(());
    }
    let ni = s.u32(31)?;
    let nj = s.u32(35)?;
    let basic = s.u32(39)?;
    let sub = s.u32(43)?;
    // Angles are in micro-degrees unless a basic angle/subdivision pair says otherwise.
    let unit = if basic == 0 || basic == u32::MAX || sub == 0 || sub == u32::MAX {
        1e-6
    } else {
        basic as f64 / sub as f64
    };
    let ang = |o: usize| -> Result<f64, GribError> { Ok(s.i32sm(o)? as f64 * unit) };
    let (lat1, lon1, lat2, lon2) = (ang(47)?, ang(51)?, ang(56)?, ang(60)?);
    let (di_raw, dj_raw) = (s.u32(64)?, s.u32(68)?);
    let scan_mode = s.u8(72)?;
    let (ni_u, nj_u) = (ni as usize, nj as usize);
    let lon_span = (lon2 - lon1).rem_euclid(360.0);
    // Increments may be "missing" (all ones); derive them from the corners then.
    let di = if di_raw == u32::MAX || di_raw == 0 {
        if ni > 1 {
            lon_span / (ni - 1) as f64
        } else {
            0.0
        }
    } else {
        di_raw as f64 * unit
    };
    let dj = if dj_raw == u32::MAX || dj_raw == 0 {
        if nj > 1 {
            (lat1 - lat2).abs() / (nj - 1) as f64
        } else {
            0.0
        }
    } else {
        dj_raw as f64 * unit
    };
    info.grid = Some(LatLonGrid {
        ni: ni_u,
        nj: nj_u,
        lat1,
        lat2,
        lon1,
        lon2,
        di,
        dj,
        scan_mode,
    });
    Ok(())
}

fn parse_product(s: &Sec, info: &mut MessageInfo) -> Result<(), GribError> {
    info.product_template = s.u16(8)?;
    // Templates 4.0–4.15 share octets 10–34 (parameter, time, surfaces); others (e.g. 4.48
    // aerosols) shift them, so only these are read.
    if info.product_template > 15 {
        return Ok(());
    }
    info.category = s.u8(10)?;
    info.number = s.u8(11)?;
    let unit = s.u8(18)?;
    let ft = s.i32sm(19)? as f64;
    info.step_hours = match unit {
        0 => Some(ft / 60.0),
        1 => Some(ft),
        2 => Some(ft * 24.0),
        10 => Some(ft * 3.0),
        11 => Some(ft * 6.0),
        12 => Some(ft * 12.0),
        13 => Some(ft / 3600.0),
        _ => None,
    };
    let surface = |t: usize| -> Result<(u8, Option<f64>), GribError> {
        let ty = s.u8(t)?;
        let sf = s.i8sm(t + 1)?;
        let raw = s.u32(t + 2)?;
        let v = if ty == 255 || raw == u32::MAX || s.u8(t + 1)? == 255 {
            None
        } else {
            let mag = (raw & 0x7fff_ffff) as f64;
            let signed = if raw & 0x8000_0000 != 0 { -mag } else { mag };
            Some(signed / 10f64.powi(sf as i32))
        };
        Ok((ty, v))
    };
    (info.level_type, info.level_value) = surface(23)?;
    (info.level2_type, info.level2_value) = surface(29)?;
    Ok(())
}

/// A decoded field on a lat/lon grid, rows from north to south, columns from west to east.
/// Missing points (bit-map) are NaN.
#[derive(Debug, Clone)]
pub struct Field {
    pub grid: LatLonGrid,
    pub values: Vec<f64>,
}

impl Field {
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.values[j * self.grid.ni + i]
    }
}

/// Check everything `decode_values` will trust, so no allocation is sized by an unchecked header.
fn validate_for_decode(bytes: &[u8], info: &MessageInfo) -> Result<LatLonGrid, GribError> {
    let (index, offset) = (info.index, info.offset);
    let corrupt = |m: String| GribError::Corrupt {
        index,
        offset,
        msg: m,
    };
    let unsupported = |m: String| GribError::Unsupported {
        index,
        offset,
        msg: m,
    };
    if info.offset + info.length > bytes.len() || info.sec7.1 > info.length {
        return Err(corrupt("message lies outside the file".into()));
    }
    let grid = match (&info.grid, info.grid_template) {
        (Some(g), 0) => g.clone(),
        (_, t) => {
            return Err(unsupported(format!(
                "grid template 3.{t} is not supported (only 3.0 regular latitude/longitude)"
            )))
        }
    };
    let declared = grid.ni as u64 * grid.nj as u64;
    if grid.ni < 2 || grid.nj < 2 {
        return Err(unsupported(format!(
            "grid {}x{} is too small to interpolate",
            grid.ni, grid.nj
        )));
    }
    if declared != info.grid_points {
        return Err(corrupt(format!(
            "grid claims {}x{} = {declared} points but section 3 says {}",
            grid.ni, grid.nj, info.grid_points
        )));
    }
    if declared > MAX_POINTS {
        return Err(corrupt(format!(
            "grid claims {}x{} = {declared} points, more than the {MAX_POINTS} accepted",
            grid.ni, grid.nj
        )));
    }
    if !(grid.di > 0.0 && grid.dj > 0.0 && grid.di.is_finite() && grid.dj.is_finite()) {
        return Err(corrupt(format!(
            "grid increments {} x {} degrees",
            grid.di, grid.dj
        )));
    }
    if grid.scan_mode & 0x20 != 0 {
        return Err(unsupported(
            "scanning mode with adjacent points in j (column-major)".into(),
        ));
    }
    if grid.north() > 90.0 + 1e-6 || grid.south() < -90.0 - 1e-6 {
        return Err(corrupt(format!(
            "latitudes {}..{} outside ±90",
            grid.lat1, grid.lat2
        )));
    }
    if info.packed_values > declared {
        return Err(corrupt(format!(
            "section 5 packs {} values into a grid of {declared} points",
            info.packed_values
        )));
    }
    match info.bitmap_indicator {
        255 => {
            if info.packed_values != declared {
                return Err(corrupt(format!(
                    "grid has {declared} points but section 5 packs {} values and there is no bit-map",
                    info.packed_values
                )));
            }
        }
        0 => {
            let (a, b) = info.sec6;
            let bitmap = &bytes[offset + a + 6..offset + b];
            if (bitmap.len() as u64) * 8 < declared {
                return Err(corrupt(format!(
                    "bit-map holds {} bits for {declared} points",
                    bitmap.len() * 8
                )));
            }
            let ones: u64 = bitmap.iter().map(|x| x.count_ones() as u64).sum::<u64>()
                - trailing_ones(bitmap, declared);
            if ones != info.packed_values {
                return Err(corrupt(format!(
                    "bit-map marks {ones} points present but section 5 packs {} values",
                    info.packed_values
                )));
            }
        }
        x => {
            return Err(unsupported(format!(
                "bit-map indicator {x} (predefined or earlier bit-map)"
            )))
        }
    }
    let (a5, b5) = info.sec5;
    let s5 = Sec {
        b: &bytes[offset + a5..offset + b5],
        index,
        offset,
        num: 5,
    };
    let data_len = (info.sec7.1 - info.sec7.0).saturating_sub(5) as u64;
    match info.packing_template {
        0 | 2 | 3 | 40 | 41 | 42 => {}
        t => {
            return Err(unsupported(format!(
                "data packing 5.{t} (supported: 5.0 simple, 5.2/5.3 complex, 5.40 JPEG2000, 5.41 PNG, 5.42 CCSDS)"
            )))
        }
    }
    let bits = s5.u8(20)? as u64;
    if matches!(info.packing_template, 0 | 41 | 42) && bits > 32 {
        return Err(corrupt(format!("{bits} bits per value (at most 32)")));
    }
    if info.packing_template == 0 && data_len * 8 < bits * info.packed_values {
        return Err(corrupt(format!(
            "data section holds {data_len} bytes; {} values of {bits} bits need {}",
            info.packed_values,
            (bits * info.packed_values).div_ceil(8)
        )));
    }
    if matches!(info.packing_template, 2 | 3) {
        let groups = s5.u32(32)? as u64;
        if bits > 32 || groups > info.packed_values.max(1) {
            return Err(corrupt(format!(
                "complex packing declares {groups} groups of {bits}-bit references for {} values",
                info.packed_values
            )));
        }
        let group_width_bits = s5.u8(37)? as u64;
        let group_len_bits = s5.u8(47)? as u64;
        if group_width_bits > 32 || group_len_bits > 32 {
            return Err(corrupt(
                "complex packing group descriptors wider than 32 bits".into(),
            ));
        }
        let need = (groups * (bits + group_width_bits + group_len_bits)).div_ceil(8);
        if need > data_len {
            return Err(corrupt(format!(
                "complex packing needs {need} bytes of group descriptors; data section holds {data_len}"
            )));
        }
    }
    Ok(grid)
}

/// Bits set beyond the first `n` bits of a bit-map (padding), which must not count.
fn trailing_ones(bitmap: &[u8], n: u64) -> u64 {
    let mut c = 0;
    let total = bitmap.len() as u64 * 8;
    for bit in n..total {
        let byte = bitmap[(bit / 8) as usize];
        if byte & (0x80 >> (bit % 8)) != 0 {
            c += 1;
        }
    }
    c
}

thread_local! {
    static IN_DECODER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Install (once) a panic hook that stays quiet for panics contained inside the decoder and
/// defers to the previous hook for everything else.
fn quiet_decoder_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let prev = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |p| {
            if !IN_DECODER.with(|f| f.get()) {
                prev(p)
            }
        }));
    });
}

/// Decode one validated message into a north-up field.
pub fn decode_values(bytes: &[u8], info: &MessageInfo) -> Result<Field, GribError> {
    let grid = validate_for_decode(bytes, info)?;
    let (index, offset) = (info.index, info.offset);
    let single = single_field_message(&bytes[offset..offset + info.length], info);
    let msg_bytes = single.as_slice();
    quiet_decoder_panics();
    IN_DECODER.with(|f| f.set(true));
    let result = std::panic::catch_unwind(|| {
        let m = gribberish::message::Message::from_data(msg_bytes, 0)
            .ok_or_else(|| "gribberish did not recognise the message".to_string())?;
        m.data().map_err(|e| e.to_string())
    });
    IN_DECODER.with(|f| f.set(false));
    let raw =
        match result {
            Ok(Ok(v)) => v,
            Ok(Err(e)) => {
                return Err(GribError::Corrupt {
                    index,
                    offset,
                    msg: format!("data section does not decode: {e}"),
                })
            }
            Err(_) => return Err(GribError::Corrupt {
                index,
                offset,
                msg:
                    "data section does not decode (the decoder failed on inconsistent packed data)"
                        .into(),
            }),
        };
    let n = grid.ni * grid.nj;
    if raw.len() != n {
        return Err(GribError::Corrupt {
            index,
            offset,
            msg: format!("decoded {} values for {n} grid points", raw.len()),
        });
    }
    if raw.iter().any(|v| v.is_infinite()) {
        return Err(GribError::Corrupt {
            index,
            offset,
            msg: "decoded values include infinities".into(),
        });
    }
    Ok(Field {
        values: to_north_up(raw, &grid),
        grid,
    })
}

/// Reorder values so that row 0 is the northernmost and column 0 the westernmost.
fn to_north_up(raw: Vec<f64>, g: &LatLonGrid) -> Vec<f64> {
    let south_to_north = g.scan_mode & 0x40 != 0;
    let east_to_west = g.scan_mode & 0x80 != 0;
    if !south_to_north && !east_to_west {
        return raw;
    }
    let mut out = Vec::with_capacity(raw.len());
    for j in 0..g.nj {
        let src_j = if south_to_north { g.nj - 1 - j } else { j };
        let row = &raw[src_j * g.ni..(src_j + 1) * g.ni];
        if east_to_west {
            out.extend(row.iter().rev());
        } else {
            out.extend_from_slice(row);
        }
    }
    out
}

/// The bytes of a one-field GRIB2 message holding just `info`'s field: sections 0, 1, (2), 3,
/// 4, 5, 6, 7 and '7777'. The decoder reads only the first field of a message, so a later field
/// of a multi-field message is handed to it this way.
fn single_field_message(msg: &[u8], info: &MessageInfo) -> Vec<u8> {
    let mut parts: Vec<(usize, usize)> = vec![info.sec1];
    parts.extend(info.sec2);
    parts.extend([info.sec3, info.sec4, info.sec5, info.sec6, info.sec7]);
    let body: usize = parts.iter().map(|(a, b)| b - a).sum();
    let total = 16 + body + 4;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&msg[..8]);
    out.extend_from_slice(&(total as u64).to_be_bytes());
    for (a, b) in parts {
        out.extend_from_slice(&msg[a..b]);
    }
    // The section-6 indicator was rewritten to 0 when inherited; the inherited section is 0.
    out.extend_from_slice(b"7777");
    out
}
