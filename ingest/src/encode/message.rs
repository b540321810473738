//! GRIB2 messages: one field → sections 0, 1, 3, 4, 5, 6, 7 and 8, and their assembly.

use chrono::{DateTime, Datelike, Timelike, Utc};

use super::bits::{micro_deg, scaled_level, sm16, sm32, BitWriter};
use super::pack::{pack_simple, Packed};
use crate::grib::tables::{
    BitmapIndicator, Discipline, GridTemplate, Packing, ProductionStatus, SurfaceType, TimeUnit,
};

/// One GRIB2 field on a regular latitude/longitude grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Grib2Field {
    /// Discipline (table 0.0).
    pub discipline: Discipline,
    /// Parameter category and number (table 4.1/4.2), e.g. (1, 1) = relative humidity.
    pub category: u8,
    pub number: u8,
    /// Type of first fixed surface (table 4.5), e.g. isobaric with the value in Pa; `None`
    /// writes the table's "missing".
    pub level_type: Option<SurfaceType>,
    /// Value of the first fixed surface in the unit of its type; NaN = missing.
    pub level_value: f64,
    pub ni: u32,
    pub nj: u32,
    /// First grid point (lat1 is the northernmost row with scanning mode 0), degrees.
    /// Longitudes may be 0–360 (as GFS writes them) or negative (written sign-and-magnitude;
    /// note gribberish 1.9 reads longitudes as unsigned and misplaces negative ones).
    pub lat1: f64,
    pub lon1: f64,
    /// Last grid point, degrees.
    pub lat2: f64,
    pub lon2: f64,
    /// Increments, degrees (positive).
    pub di: f64,
    pub dj: f64,
    pub reference_time: DateTime<Utc>,
    pub forecast_hours: u32,
    /// Row-major: row j (north to south), then column i (west to east). NaN = missing.
    pub values: Vec<f64>,
    /// Decimal scale factor D: values are packed as integers of value·10^D.
    pub decimal_scale: i16,
    /// Bits per packed value, 0..=32 (0 only for a constant field).
    pub bits: u8,
}

/// Shortcut for the parameters used here.
pub mod param {
    /// (discipline, category, number)
    pub const RH: (u8, u8, u8) = (0, 1, 1);
    pub const T: (u8, u8, u8) = (0, 0, 0);
    pub const GH: (u8, u8, u8) = (0, 3, 5);
}

pub(crate) fn section(num: u8, body: &[u8]) -> Vec<u8> {
    let len = body.len() + 5;
    let mut s = Vec::with_capacity(len);
    s.extend_from_slice(&(len as u32).to_be_bytes());
    s.push(num);
    s.extend_from_slice(body);
    s
}

/// Sections 1 and 3–7 of one field, each complete with its length and number, so that fixtures
/// can swap or damage one before assembly.
pub struct Sections {
    pub discipline: u8,
    pub s1: Vec<u8>,
    pub s3: Vec<u8>,
    pub s4: Vec<u8>,
    pub s5: Vec<u8>,
    pub s6: Vec<u8>,
    pub s7: Vec<u8>,
}

impl Sections {
    pub fn assemble(&self) -> Vec<u8> {
        assemble_message(
            self.discipline,
            &[&self.s1, &self.s3, &self.s4, &self.s5, &self.s6, &self.s7],
        )
    }
}

/// Section 0 + the given sections + section 8, with the total length filled in.
pub fn assemble_message(discipline: u8, sections: &[&[u8]]) -> Vec<u8> {
    let total = 16 + sections.iter().map(|s| s.len()).sum::<usize>() + 4;
    let mut m = Vec::with_capacity(total);
    m.extend_from_slice(b"GRIB");
    m.extend_from_slice(&[0, 0]); // octets 5-6 reserved
    m.push(discipline); // octet 7
    m.push(2); // octet 8: edition
    m.extend_from_slice(&(total as u64).to_be_bytes()); // octets 9-16
    for s in sections {
        m.extend_from_slice(s);
    }
    m.extend_from_slice(b"7777");
    m
}

pub fn encode_sections(f: &Grib2Field) -> Sections {
    let n = f.ni as u64 * f.nj as u64;
    assert_eq!(
        f.values.len() as u64,
        n,
        "values must hold ni*nj = {n} points"
    );
    let p = pack_simple(&f.values, f.decimal_scale, f.bits);
    Sections {
        discipline: f.discipline.code(),
        s1: section1(f),
        s3: section3(f, n),
        s4: section4(f),
        s5: section5(&p),
        s6: section6(f),
        s7: section(7, &p.data),
    }
}

/// Section 1: identification.
fn section1(f: &Grib2Field) -> Vec<u8> {
    let t = f.reference_time;
    let mut b = Vec::with_capacity(16);
    b.extend_from_slice(&7u16.to_be_bytes()); // 6-7 centre: NCEP
    b.extend_from_slice(&0u16.to_be_bytes()); // 8-9 sub-centre
    b.push(2); // 10 master tables version (as GFS)
    b.push(1); // 11 local tables version (as GFS)
    b.push(1); // 12 significance of reference time: start of forecast
    b.extend_from_slice(&(t.year() as u16).to_be_bytes()); // 13-14
    b.extend_from_slice(&[
        t.month() as u8,
        t.day() as u8,
        t.hour() as u8,
        t.minute() as u8,
        t.second() as u8,
    ]); // 15-19
    b.push(ProductionStatus::Research.code()); // 20 production status (these files are synthetic)
    b.push(1); // 21 type of data: forecast
    section(1, &b)
}

/// Section 3: grid definition, template 3.0, for `n` points.
fn section3(f: &Grib2Field, n: u64) -> Vec<u8> {
    let mut b = Vec::with_capacity(67);
    b.push(0); // 6 source: template
    b.extend_from_slice(&(n as u32).to_be_bytes()); // 7-10 number of points
    b.push(0); // 11 no optional list
    b.push(0); // 12
    b.extend_from_slice(&GridTemplate::LatLon.code().to_be_bytes()); // 13-14 template 3.0
    b.push(6); // 15 shape of earth: sphere of radius 6 371 229 m
    b.push(0); // 16 scale factor of radius
    b.extend_from_slice(&0u32.to_be_bytes()); // 17-20 scaled radius
    b.push(0); // 21 major axis scale
    b.extend_from_slice(&0u32.to_be_bytes()); // 22-25
    b.push(0); // 26 minor axis scale
    b.extend_from_slice(&0u32.to_be_bytes()); // 27-30
    b.extend_from_slice(&f.ni.to_be_bytes()); // 31-34 Ni
    b.extend_from_slice(&f.nj.to_be_bytes()); // 35-38 Nj
    b.extend_from_slice(&0u32.to_be_bytes()); // 39-42 basic angle 0: micro-degrees
    b.extend_from_slice(&u32::MAX.to_be_bytes()); // 43-46 subdivisions: missing
    b.extend_from_slice(&micro_deg(f.lat1).to_be_bytes()); // 47-50 La1
    b.extend_from_slice(&micro_deg(f.lon1).to_be_bytes()); // 51-54 Lo1
    b.push(0x30); // 55 resolution flags: increments given, winds grid-relative off
    b.extend_from_slice(&micro_deg(f.lat2).to_be_bytes()); // 56-59 La2
    b.extend_from_slice(&micro_deg(f.lon2).to_be_bytes()); // 60-63 Lo2
    b.extend_from_slice(&((f.di.abs() * 1e6).round() as u32).to_be_bytes()); // 64-67 Di
    b.extend_from_slice(&((f.dj.abs() * 1e6).round() as u32).to_be_bytes()); // 68-71 Dj
    b.push(0); // 72 scanning mode: +i, -j, rows
    let s3 = section(3, &b);
    debug_assert_eq!(s3.len(), 72);
    s3
}

/// Section 4: product definition, template 4.0.
fn section4(f: &Grib2Field) -> Vec<u8> {
    let mut b = Vec::with_capacity(29);
    b.extend_from_slice(&0u16.to_be_bytes()); // 6-7 no coordinate values
    b.extend_from_slice(&0u16.to_be_bytes()); // 8-9 template 4.0
    b.push(f.category); // 10
    b.push(f.number); // 11
    b.push(2); // 12 generating process: forecast
    b.push(0); // 13 background process
    b.push(96); // 14 analysis/forecast process: GFS (NCEP table)
    b.extend_from_slice(&0u16.to_be_bytes()); // 15-16 hours after cutoff
    b.push(0); // 17 minutes after cutoff
    b.push(TimeUnit::Hour.code()); // 18 unit of time range
    b.extend_from_slice(&sm32(f.forecast_hours as i64).to_be_bytes()); // 19-22
    let (scale, value) = match f.level_type {
        None => (255, u32::MAX),
        Some(_) => scaled_level(f.level_value),
    };
    b.push(f.level_type.map_or(255, SurfaceType::code)); // 23
    b.push(scale); // 24
    b.extend_from_slice(&value.to_be_bytes()); // 25-28
    b.push(255); // 29 second surface: missing
    b.push(255); // 30
    b.extend_from_slice(&u32::MAX.to_be_bytes()); // 31-34
    let s4 = section(4, &b);
    debug_assert_eq!(s4.len(), 34);
    s4
}

/// Section 5: data representation, template 5.0, of the packed values `p`.
fn section5(p: &Packed) -> Vec<u8> {
    let mut b = Vec::with_capacity(16);
    b.extend_from_slice(&p.count.to_be_bytes()); // 6-9 values packed
    b.extend_from_slice(&Packing::Simple.code().to_be_bytes()); // 10-11 template 5.0
    b.extend_from_slice(&p.reference.to_be_bytes()); // 12-15 R, IEEE 32-bit
    b.extend_from_slice(&sm16(p.binary_scale as i32).to_be_bytes()); // 16-17 E
    b.extend_from_slice(&sm16(p.decimal_scale as i32).to_be_bytes()); // 18-19 D
    b.push(p.bits); // 20
    b.push(0); // 21 original values: floating point
    let s5 = section(5, &b);
    debug_assert_eq!(s5.len(), 21);
    s5
}

/// Section 6: bit-map, only when something is missing.
fn section6(f: &Grib2Field) -> Vec<u8> {
    if f.values.iter().any(|v| v.is_nan()) {
        let mut w = BitWriter::new();
        for v in &f.values {
            w.put(u32::from(!v.is_nan()), 1);
        }
        let mut b = vec![BitmapIndicator::Present.code()]; // 6 indicator: bit-map follows
        b.extend_from_slice(&w.finish());
        section(6, &b)
    } else {
        section(6, &[BitmapIndicator::None.code()])
    }
}

/// One complete GRIB2 message for `f`.
pub fn encode_message(f: &Grib2Field) -> Vec<u8> {
    encode_sections(f).assemble()
}

/// Messages concatenated, as GRIB files are.
pub fn encode_file(fields: &[Grib2Field]) -> Vec<u8> {
    fields.iter().flat_map(encode_message).collect()
}

/// Byte offset (within `msg`) and length of the first section numbered `num` of a GRIB2
/// message written by this module.
pub fn find_section(msg: &[u8], num: u8) -> Option<(usize, usize)> {
    let mut p = 16;
    while p + 5 <= msg.len() && &msg[p..p + 4] != b"7777" {
        let len = u32::from_be_bytes(msg[p..p + 4].try_into().ok()?) as usize;
        if len < 5 {
            return None;
        }
        if msg[p + 4] == num {
            return Some((p, len));
        }
        p += len;
    }
    None
}
