//! Scanning: locating every message of a file and reading its section headers (WMO FM 92
//! GRIB edition 2) without decoding data. Every read is bounds-checked against the section it
//! belongs to, and a file that is cut off, or whose sections do not tile their message, is an
//! error — never silently shortened.

use chrono::{DateTime, NaiveDate, Utc};

use super::info::{LatLonGrid, MessageInfo};
use super::tables::{
    BitmapIndicator, GridTemplate, Packing, ProductionStatus, SurfaceType, TimeUnit,
};
use super::GribError;

/// One section's bytes, with what an error about it must name.
pub(super) struct Sec<'a> {
    pub(super) b: &'a [u8],
    pub(super) index: usize,
    pub(super) offset: usize,
    pub(super) num: u8,
}

impl Sec<'_> {
    /// Octets `from..=to` (1-based, as the WMO tables number them).
    pub(super) fn bytes(&self, from: usize, to: usize) -> Result<&[u8], GribError> {
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
    pub(super) fn u8(&self, o: usize) -> Result<u8, GribError> {
        Ok(self.bytes(o, o)?[0])
    }
    pub(super) fn u16(&self, o: usize) -> Result<u16, GribError> {
        let b = self.bytes(o, o + 1)?;
        Ok(u16::from_be_bytes([b[0], b[1]]))
    }
    pub(super) fn u32(&self, o: usize) -> Result<u32, GribError> {
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

/// Scan a whole file: every message is located and its headers validated.
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

pub(super) fn find_marker(b: &[u8]) -> Option<usize> {
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
    let mut cur = MessageInfo::empty(index, offset, msg.len(), discipline);
    let mut last_bitmap: Option<(usize, usize)> = None;
    let mut p = 16usize;
    let mut last = 0u8;
    let end = msg.len() - 4;
    while p < end {
        let (len, num) = section_at(msg, p, end, last, &corrupt)?;
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
                // Octet 20 is past what older readers needed; a short section 1 just lacks it.
                cur.production_status = s.u8(20).ok().and_then(ProductionStatus::from_code);
                cur.sections.s1 = range;
            }
            2 => cur.sections.s2 = Some(range),
            3 => {
                parse_grid(&s, &mut cur)?;
                cur.sections.s3 = range;
            }
            4 => {
                parse_product(&s, &mut cur)?;
                cur.sections.s4 = range;
            }
            5 => {
                cur.packed_values = s.u32(6)? as u64;
                cur.packing = Packing::from_code(s.u16(10)?);
                cur.sections.s5 = range;
            }
            6 => {
                cur.bitmap = BitmapIndicator::from_code(s.u8(6)?);
                cur.sections.s6 = range;
                match cur.bitmap {
                    BitmapIndicator::Present => last_bitmap = Some(range),
                    BitmapIndicator::Previous => {
                        let prev = last_bitmap.ok_or_else(|| {
                            corrupt("bit-map indicator 254 but no earlier bit-map".into())
                        })?;
                        cur.bitmap = BitmapIndicator::Present;
                        cur.sections.s6 = prev;
                    }
                    _ => {}
                }
            }
            7 => {
                if last != 6 {
                    return Err(corrupt("data section 7 without a bit-map section 6".into()));
                }
                cur.sections.s7 = range;
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

/// The section at message byte `p` (before `end`, where '7777' starts): its length and
/// number, checked against the bytes left and against the section before it (`last`).
fn section_at(
    msg: &[u8],
    p: usize,
    end: usize,
    last: u8,
    corrupt: &dyn Fn(String) -> GribError,
) -> Result<(usize, u8), GribError> {
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
    Ok((len, num))
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
    info.grid_template = GridTemplate::from_code(s.u16(13)?);
    if info.grid_template != Some(GridTemplate::LatLon) {
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
    let template = s.u16(8)?;
    info.product_template = (template != u16::MAX).then_some(template);
    // Templates 4.0–4.15 share octets 10–34 (parameter, time, surfaces); others (e.g. 4.48
    // aerosols) shift them, so only these are read.
    if template > 15 {
        return Ok(());
    }
    info.category = s.u8(10)?;
    info.number = s.u8(11)?;
    let unit = TimeUnit::from_code(s.u8(18)?);
    let ft = s.i32sm(19)? as f64;
    info.step_hours = unit.and_then(|u| u.to_hours(ft));
    let surface = |t: usize| -> Result<(Option<SurfaceType>, Option<f64>), GribError> {
        let ty = SurfaceType::from_code(s.u8(t)?);
        let sf = s.i8sm(t + 1)?;
        let raw = s.u32(t + 2)?;
        let v = if ty.is_none() || raw == u32::MAX || s.u8(t + 1)? == 255 {
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
