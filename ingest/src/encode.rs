//! A minimal GRIB2 encoder (WMO FM 92 GRIB edition 2), written from the WMO manual, for the
//! synthetic demo file and for test fixtures. It writes exactly one product per message:
//! sections 0, 1, 3 (template 3.0 regular lat/lon), 4 (template 4.0), 5 (template 5.0 simple
//! packing), 6 (bit-map only when a value is NaN), 7 and 8. Octet numbers in comments are the
//! 1-based ones of the WMO tables.
//!
//! Inputs are built by code, not read from files, so inconsistent inputs are programming errors
//! and panic with a message rather than returning an error.

use chrono::{DateTime, Datelike, Timelike, Utc};

/// One GRIB2 field on a regular latitude/longitude grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Grib2Field {
    /// Discipline (table 0.0): 0 = meteorological.
    pub discipline: u8,
    /// Parameter category and number (table 4.1/4.2), e.g. (1, 1) = relative humidity.
    pub category: u8,
    pub number: u8,
    /// Type of first fixed surface (table 4.5): 100 = isobaric, value in Pa. 255 = missing.
    pub level_type: u8,
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

// ---- integer encodings ----

/// GRIB2 signed integers are sign-and-magnitude: top bit is the sign.
fn sm32(v: i64) -> u32 {
    let mag = v.unsigned_abs();
    assert!(
        mag <= 0x7fff_ffff,
        "{v} does not fit a 32-bit GRIB signed integer"
    );
    if v < 0 {
        0x8000_0000 | mag as u32
    } else {
        mag as u32
    }
}

fn sm16(v: i32) -> u16 {
    let mag = v.unsigned_abs();
    assert!(
        mag <= 0x7fff,
        "{v} does not fit a 16-bit GRIB signed integer"
    );
    if v < 0 {
        0x8000 | mag as u16
    } else {
        mag as u16
    }
}

fn sm8(v: i32) -> u8 {
    let mag = v.unsigned_abs();
    assert!(mag <= 0x7f, "{v} does not fit an 8-bit GRIB signed integer");
    if v < 0 {
        0x80 | mag as u8
    } else {
        mag as u8
    }
}

/// Degrees as GRIB2 micro-degrees (basic angle 0), sign-and-magnitude.
fn micro_deg(deg: f64) -> u32 {
    sm32((deg * 1e6).round() as i64)
}

/// A surface value as (scale factor, scaled value) with value = scaled / 10^scale, using the
/// smallest scale that represents it exactly (isobaric levels in Pa need 0).
fn scaled_level(v: f64) -> (u8, u32) {
    if v.is_nan() {
        return (255, u32::MAX);
    }
    for s in 0..=9 {
        let x = v * 10f64.powi(s);
        if x.abs() >= 2_147_483_647.0 {
            break;
        }
        if (x - x.round()).abs() <= 1e-9 * x.abs().max(1.0) {
            return (sm8(s), sm32(x.round() as i64));
        }
    }
    panic!("level value {v} cannot be written as a scaled 32-bit integer");
}

/// Largest f32 not above `x`, so that every packed difference from the reference is >= 0.
fn f32_at_or_below(x: f64) -> f32 {
    let r = x as f32;
    if (r as f64) <= x {
        return r;
    }
    // `f32::next_down` needs Rust 1.86; the workspace targets 1.85.
    let b = r.to_bits();
    if r == 0.0 {
        -f32::from_bits(1)
    } else if r > 0.0 {
        f32::from_bits(b - 1)
    } else {
        f32::from_bits(b + 1)
    }
}

/// MSB-first bit writer for section 7 (and the section 6 bit-map).
struct BitWriter {
    out: Vec<u8>,
    acc: u64,
    n: u32,
}

impl BitWriter {
    fn new() -> Self {
        BitWriter {
            out: Vec::new(),
            acc: 0,
            n: 0,
        }
    }
    fn put(&mut self, v: u32, bits: u32) {
        if bits == 0 {
            return;
        }
        self.acc = (self.acc << bits) | (v as u64 & ((1u64 << bits) - 1));
        self.n += bits;
        while self.n >= 8 {
            self.n -= 8;
            self.out.push((self.acc >> self.n) as u8);
        }
        self.acc &= (1u64 << self.n) - 1;
    }
    /// Pads the last byte with zero bits (bit-map padding must be 0: some decoders count it).
    fn finish(mut self) -> Vec<u8> {
        if self.n > 0 {
            self.out.push((self.acc << (8 - self.n)) as u8);
        }
        self.out
    }
}

/// Simple packing (template 5.0) of the present values.
pub struct Packed {
    pub reference: f32,
    pub binary_scale: i16,
    pub decimal_scale: i16,
    pub bits: u8,
    pub count: u32,
    pub data: Vec<u8>,
}

/// Y = (R + X·2^E) / 10^D. E is the smallest binary scale for which the range fits `bits`.
pub fn pack_simple(values: &[f64], decimal_scale: i16, bits: u8) -> Packed {
    assert!(bits <= 32, "simple packing takes at most 32 bits per value");
    let present: Vec<f64> = values.iter().copied().filter(|v| !v.is_nan()).collect();
    assert!(
        present.iter().all(|v| v.is_finite()),
        "values must be finite or NaN"
    );
    // Decoders disagree on whether a constant (0-bit) field is scaled by 10^-D, so none is used.
    let decimal_scale = if bits == 0 { 0 } else { decimal_scale };
    let d = 10f64.powi(decimal_scale as i32);
    let scaled: Vec<f64> = present.iter().map(|v| v * d).collect();
    let min = scaled.iter().copied().fold(f64::INFINITY, f64::min);
    let max = scaled.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let max_int = if bits == 0 {
        0.0
    } else {
        ((1u64 << bits) - 1) as f64
    };
    let fit = |reference: f32| -> i32 {
        let range = max - reference as f64;
        if scaled.is_empty() || bits == 0 || range <= 0.0 {
            assert!(
                bits > 0 || range <= 0.5,
                "0 bits per value only encodes a constant field"
            );
            return 0;
        }
        let mut e = (range / max_int).log2().ceil() as i32;
        // Allow a finer scale where rounding still fits, and a coarser one where float error
        // in log2 pushed the maximum over.
        while (range / 2f64.powi(e - 1)).round() <= max_int {
            e -= 1;
        }
        while (range / 2f64.powi(e)).round() > max_int {
            e += 1;
        }
        e
    };
    let mut reference = if scaled.is_empty() {
        0.0
    } else {
        f32_at_or_below(min)
    };
    let mut e = fit(reference);
    // When the step is whole units of 10^-D anyway, a whole-unit reference costs no precision
    // and makes values decode to round numbers (RH 100.0, not 100.04).
    if e >= 0 && !scaled.is_empty() && min.abs() < 16_777_216.0 {
        reference = min.floor() as f32;
        e = fit(reference);
    }
    let step = 2f64.powi(e);
    let mut w = BitWriter::new();
    for s in &scaled {
        let x = ((s - reference as f64) / step).round().clamp(0.0, max_int);
        w.put(x as u32, bits as u32);
    }
    Packed {
        reference,
        binary_scale: e as i16,
        decimal_scale,
        bits,
        count: scaled.len() as u32,
        data: w.finish(),
    }
}

fn section(num: u8, body: &[u8]) -> Vec<u8> {
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

    // Section 1: identification.
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
    b.push(2); // 20 production status: research (these files are synthetic)
    b.push(1); // 21 type of data: forecast
    let s1 = section(1, &b);

    // Section 3: grid definition, template 3.0.
    let mut b = Vec::with_capacity(67);
    b.push(0); // 6 source: template
    b.extend_from_slice(&(n as u32).to_be_bytes()); // 7-10 number of points
    b.push(0); // 11 no optional list
    b.push(0); // 12
    b.extend_from_slice(&0u16.to_be_bytes()); // 13-14 template 3.0
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

    // Section 4: product definition, template 4.0.
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
    b.push(1); // 18 unit of time range: hour
    b.extend_from_slice(&sm32(f.forecast_hours as i64).to_be_bytes()); // 19-22
    let (scale, value) = if f.level_type == 255 {
        (255, u32::MAX)
    } else {
        scaled_level(f.level_value)
    };
    b.push(f.level_type); // 23
    b.push(scale); // 24
    b.extend_from_slice(&value.to_be_bytes()); // 25-28
    b.push(255); // 29 second surface: missing
    b.push(255); // 30
    b.extend_from_slice(&u32::MAX.to_be_bytes()); // 31-34
    let s4 = section(4, &b);
    debug_assert_eq!(s4.len(), 34);

    // Section 5: data representation, template 5.0.
    let p = pack_simple(&f.values, f.decimal_scale, f.bits);
    let mut b = Vec::with_capacity(16);
    b.extend_from_slice(&p.count.to_be_bytes()); // 6-9 values packed
    b.extend_from_slice(&0u16.to_be_bytes()); // 10-11 template 5.0
    b.extend_from_slice(&p.reference.to_be_bytes()); // 12-15 R, IEEE 32-bit
    b.extend_from_slice(&sm16(p.binary_scale as i32).to_be_bytes()); // 16-17 E
    b.extend_from_slice(&sm16(p.decimal_scale as i32).to_be_bytes()); // 18-19 D
    b.push(p.bits); // 20
    b.push(0); // 21 original values: floating point
    let s5 = section(5, &b);
    debug_assert_eq!(s5.len(), 21);

    // Section 6: bit-map, only when something is missing.
    let s6 = if f.values.iter().any(|v| v.is_nan()) {
        let mut w = BitWriter::new();
        for v in &f.values {
            w.put(u32::from(!v.is_nan()), 1);
        }
        let mut b = vec![0u8]; // 6 indicator: bit-map follows
        b.extend_from_slice(&w.finish());
        section(6, &b)
    } else {
        section(6, &[255])
    };

    let s7 = section(7, &p.data);
    Sections {
        discipline: f.discipline,
        s1,
        s3,
        s4,
        s5,
        s6,
        s7,
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

/// Byte builders for tests: valid files and the damaged or unsupported inputs the reader must
/// refuse without panicking. Each is a few hundred bytes.
pub mod fixtures {
    use super::*;
    use chrono::TimeZone;

    pub const NI: u32 = 6;
    pub const NJ: u32 = 5;

    /// Deterministic xorshift64 (no `rand` dependency), for noise and random bytes.
    pub struct XorShift(pub u64);

    impl XorShift {
        pub fn next_u64(&mut self) -> u64 {
            let mut x = self.0.max(1);
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            self.0 = x;
            x
        }
        /// Uniform in [0, 1).
        pub fn next_f64(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A small field: 6×5 points, 50–45°N × 10–15°E at 1°, 2024-06-01T00Z +12 h, on `hpa`.
    pub fn small_field(p: (u8, u8, u8), hpa: f64, values: Vec<f64>) -> Grib2Field {
        Grib2Field {
            discipline: p.0,
            category: p.1,
            number: p.2,
            level_type: 100,
            level_value: hpa * 100.0,
            ni: NI,
            nj: NJ,
            lat1: 50.0,
            lon1: 10.0,
            lat2: 46.0,
            lon2: 15.0,
            di: 1.0,
            dj: 1.0,
            reference_time: Utc.with_ymd_and_hms(2024, 6, 1, 0, 0, 0).unwrap(),
            forecast_hours: 12,
            values,
            decimal_scale: 1,
            bits: 10,
        }
    }

    /// RH in percent with a gradient, so every point differs.
    pub fn rh_values(hpa: f64) -> Vec<f64> {
        (0..NI * NJ)
            .map(|k| {
                let (i, j) = ((k % NI) as f64, (k / NI) as f64);
                (20.0 + 12.0 * i + 5.0 * j + (1000.0 - hpa) / 50.0).min(100.0)
            })
            .collect()
    }

    /// RH on 850, 700 and 500 hPa with geopotential height on the same levels.
    pub fn valid_rh_fields() -> Vec<Grib2Field> {
        let mut v = Vec::new();
        for hpa in [850.0, 700.0, 500.0] {
            v.push(small_field(param::RH, hpa, rh_values(hpa)));
            let z = match hpa as u32 {
                850 => 1457.0,
                700 => 3012.0,
                _ => 5574.0,
            };
            let mut gh = small_field(
                param::GH,
                hpa,
                (0..NI * NJ).map(|k| z - 3.0 * (k / NI) as f64).collect(),
            );
            gh.decimal_scale = 0;
            gh.bits = 12;
            v.push(gh);
        }
        v
    }

    /// A valid small RH file (3 RH + 3 gh messages).
    pub fn valid_rh() -> Vec<u8> {
        encode_file(&valid_rh_fields())
    }

    /// One RH message at 700 hPa whose corners are missing (section 6 bit-map).
    pub fn valid_rh_with_bitmap() -> Vec<u8> {
        let mut v = rh_values(700.0);
        for k in [0, (NI - 1) as usize, (NI * NJ - 1) as usize] {
            v[k] = f64::NAN;
        }
        encode_message(&small_field(param::RH, 700.0, v))
    }

    /// Temperature only: a well-formed file with no relative humidity in it.
    pub fn no_rh() -> Vec<u8> {
        let f = |hpa: f64| {
            let mut t = small_field(
                param::T,
                hpa,
                (0..NI * NJ)
                    .map(|k| 288.15 - (1000.0 - hpa) * 0.06 - (k / NI) as f64 * 0.5)
                    .collect(),
            );
            t.bits = 12;
            t
        };
        encode_file(&[f(850.0), f(500.0)])
    }

    /// [`valid_rh`] cut off inside the data section (section 7) of its last message.
    pub fn truncated() -> Vec<u8> {
        let fields = valid_rh_fields();
        let last = encode_message(&fields[fields.len() - 1]);
        let (s7, len7) = find_section(&last, 7).expect("section 7");
        let mut out = encode_file(&fields[..fields.len() - 1]);
        out.extend_from_slice(&last[..s7 + 5 + (len7 - 5) / 2]);
        out
    }

    /// Deterministic noise with no GRIB marker guaranteed (it may contain one by chance).
    pub fn random_bytes(seed: u64, len: usize) -> Vec<u8> {
        let mut r = XorShift(seed);
        (0..len).map(|_| r.next_u64() as u8).collect()
    }

    fn patch(msg: &mut [u8], sec: u8, octet: usize, bytes: &[u8]) {
        let (p, _) = find_section(msg, sec).expect("section present");
        let at = p + octet - 1;
        msg[at..at + bytes.len()].copy_from_slice(bytes);
    }

    fn rh_500() -> Vec<u8> {
        encode_message(&small_field(param::RH, 500.0, rh_values(500.0)))
    }

    /// Section 5 octet 20 (bits per value) set to 255.
    pub fn bits_per_value_255() -> Vec<u8> {
        let mut m = rh_500();
        patch(&mut m, 5, 20, &[255]);
        m
    }

    /// Section 5 octets 6-9 (values packed) set to 0xFFFFFF00.
    pub fn huge_packed_count() -> Vec<u8> {
        let mut m = rh_500();
        patch(&mut m, 5, 6, &0xFFFF_FF00u32.to_be_bytes());
        m
    }

    /// Structurally valid, with seeded bit flips inside the packed data of section 7: it may
    /// decode (to wrong values) but must never panic.
    pub fn flipped_data_bits(seed: u64) -> Vec<u8> {
        let mut m = rh_500();
        let (p, len) = find_section(&m, 7).expect("section 7");
        let mut r = XorShift(seed);
        for _ in 0..8 {
            let k = p + 5 + (r.next_u64() as usize) % (len - 5);
            m[k] ^= 1 << (r.next_u64() % 8);
        }
        m
    }

    /// A 10×10 field (100 values packed) whose section 3 claims a 60000×60000 grid, with the
    /// number of points (octets 7-10) changed to match, so only a size check stops it.
    pub fn huge_grid_claim() -> Vec<u8> {
        let mut f = small_field(param::RH, 500.0, vec![50.0; 100]);
        (f.ni, f.nj) = (10, 10);
        f.values = (0..100).map(|k| k as f64).collect();
        let mut m = encode_message(&f);
        patch(&mut m, 3, 7, &3_600_000_000u32.to_be_bytes());
        patch(&mut m, 3, 31, &60_000u32.to_be_bytes());
        patch(&mut m, 3, 35, &60_000u32.to_be_bytes());
        m
    }

    /// A well-formed RH message on a polar stereographic grid (template 3.20), 6×5 points.
    pub fn unsupported_grid() -> Vec<u8> {
        let mut s = encode_sections(&small_field(param::RH, 500.0, rh_values(500.0)));
        let mut b = Vec::with_capacity(60);
        b.push(0); // 6
        b.extend_from_slice(&(NI * NJ).to_be_bytes()); // 7-10
        b.extend_from_slice(&[0, 0]); // 11-12
        b.extend_from_slice(&20u16.to_be_bytes()); // 13-14 template 3.20
        b.push(6); // 15 shape of earth
        b.extend_from_slice(&[0; 15]); // 16-30 radii/axes
        b.extend_from_slice(&NI.to_be_bytes()); // 31-34 Nx
        b.extend_from_slice(&NJ.to_be_bytes()); // 35-38 Ny
        b.extend_from_slice(&micro_deg(60.0).to_be_bytes()); // 39-42 La1
        b.extend_from_slice(&micro_deg(350.0).to_be_bytes()); // 43-46 Lo1
        b.push(0x30); // 47 resolution flags
        b.extend_from_slice(&micro_deg(60.0).to_be_bytes()); // 48-51 LaD
        b.extend_from_slice(&micro_deg(0.0).to_be_bytes()); // 52-55 LoV
        b.extend_from_slice(&50_000_000u32.to_be_bytes()); // 56-59 Dx, mm
        b.extend_from_slice(&50_000_000u32.to_be_bytes()); // 60-63 Dy, mm
        b.push(0); // 64 projection centre: north pole
        b.push(0x40); // 65 scanning mode: +i, +j
        s.s3 = section(3, &b);
        debug_assert_eq!(s.s3.len(), 65);
        s.assemble()
    }

    /// Template 3.0 declared, but section 3 stops after 40 octets (before the corners).
    pub fn short_grid_section() -> Vec<u8> {
        let mut s = encode_sections(&small_field(param::RH, 500.0, rh_values(500.0)));
        s.s3 = section(3, &s.s3[5..40]);
        s.assemble()
    }

    /// Section 1 reference time with month 13 (gribberish 1.9 unwraps the date and panics).
    pub fn bad_reference_date() -> Vec<u8> {
        let mut m = rh_500();
        patch(&mut m, 1, 15, &[13]);
        m
    }

    /// IBM single-precision float (GRIB1 reference value), rounded so it is not above `x`.
    fn ibm_at_or_below(x: f64) -> (u32, f64) {
        if x == 0.0 {
            return (0, 0.0);
        }
        let neg = x < 0.0;
        let a = x.abs();
        let mut e = (a.log2() / 4.0).floor() as i32 + 1; // a = m·16^e, m in [1/16, 1)
        let mut m = a / 16f64.powi(e);
        if m >= 1.0 {
            e += 1;
            m /= 16.0;
        }
        // Round toward -infinity: down in magnitude for positives, up for negatives.
        let mut mant = if neg {
            (m * 16_777_216.0).ceil()
        } else {
            (m * 16_777_216.0).floor()
        } as u32;
        if mant >= 1 << 24 {
            mant >>= 4;
            e += 1;
        }
        let back = mant as f64 / 16_777_216.0 * 16f64.powi(e) * if neg { -1.0 } else { 1.0 };
        let bits = (u32::from(neg) << 31) | (((e + 64) as u32) << 24) | mant;
        (bits, back)
    }

    /// GRIB1 24-bit sign-and-magnitude.
    fn sm24(v: i32) -> [u8; 3] {
        let mag = v.unsigned_abs();
        assert!(mag < 1 << 23);
        let w = if v < 0 { mag | 1 << 23 } else { mag };
        [(w >> 16) as u8, (w >> 8) as u8, w as u8]
    }

    /// Values of [`grib1_rh`]: RH on a 4×3 grid, north to south, west to east.
    pub const GRIB1_VALUES: [f64; 12] = [
        55.0, 60.0, 65.0, 70.0, 62.0, 71.0, 80.0, 88.0, 40.0, 45.0, 93.0, 100.0,
    ];

    /// A well-formed GRIB edition 1 message: RH (table 2 parameter 52) at 500 hPa on a 4×3
    /// lat/lon grid (50–48°N, 10–13°E at 1°), simple packing, 2024-06-01T00Z +12 h.
    pub fn grib1_rh() -> Vec<u8> {
        // PDS, 28 octets.
        let mut pds = vec![0, 0, 28];
        pds.extend_from_slice(&[2, 7, 96, 255, 0x80]); // 4 table 2 version, 5 NCEP, 6 GFS, 7 grid in GDS, 8 GDS present
        pds.extend_from_slice(&[52, 100]); // 9 RH, 10 isobaric
        pds.extend_from_slice(&500u16.to_be_bytes()); // 11-12 level, hPa
        pds.extend_from_slice(&[24, 6, 1, 0, 0]); // 13-17 year of century, month, day, hour, minute
        pds.extend_from_slice(&[1, 12, 0, 0]); // 18 hour, 19 P1, 20 P2, 21 time range: P1
        pds.extend_from_slice(&[0, 0, 0, 21, 0]); // 22-23 averaged, 24 missing, 25 century, 26 sub-centre
        pds.extend_from_slice(&sm16(0).to_be_bytes()); // 27-28 D
        assert_eq!(pds.len(), 28);

        // GDS, 32 octets, data representation 0 (lat/lon).
        let mut gds = vec![0, 0, 32, 0, 255, 0];
        gds.extend_from_slice(&4u16.to_be_bytes()); // 7-8 Ni
        gds.extend_from_slice(&3u16.to_be_bytes()); // 9-10 Nj
        gds.extend_from_slice(&sm24(50_000)); // 11-13 La1, millidegrees
        gds.extend_from_slice(&sm24(10_000)); // 14-16 Lo1
        gds.push(0x80); // 17 increments given
        gds.extend_from_slice(&sm24(48_000)); // 18-20 La2
        gds.extend_from_slice(&sm24(13_000)); // 21-23 Lo2
        gds.extend_from_slice(&1000u16.to_be_bytes()); // 24-25 Di
        gds.extend_from_slice(&1000u16.to_be_bytes()); // 26-27 Dj
        gds.push(0); // 28 scanning mode
        gds.extend_from_slice(&[0; 4]); // 29-32 reserved
        assert_eq!(gds.len(), 32);

        // BDS: simple packing, 8 bits, E = 0, D = 0.
        let bits = 8u32;
        let min = GRIB1_VALUES.iter().copied().fold(f64::INFINITY, f64::min);
        let (r_bits, r) = ibm_at_or_below(min);
        let mut w = BitWriter::new();
        for v in GRIB1_VALUES {
            w.put((v - r).round() as u32, bits);
        }
        let mut data = w.finish();
        if (11 + data.len()) % 2 == 1 {
            data.push(0); // sections are padded to an even length
        }
        let len = 11 + data.len();
        let unused = (data.len() * 8) as u32 - bits * GRIB1_VALUES.len() as u32;
        let mut bds = (len as u32).to_be_bytes()[1..].to_vec(); // 1-3
        bds.push(unused as u8); // 4 flags 0 (grid point, simple, float) | unused bits
        bds.extend_from_slice(&sm16(0).to_be_bytes()); // 5-6 E
        bds.extend_from_slice(&r_bits.to_be_bytes()); // 7-10 R, IBM float
        bds.push(bits as u8); // 11
        bds.extend_from_slice(&data);

        let total = 8 + pds.len() + gds.len() + bds.len() + 4;
        let mut m = b"GRIB".to_vec();
        m.extend_from_slice(&(total as u32).to_be_bytes()[1..]);
        m.push(1);
        m.extend_from_slice(&pds);
        m.extend_from_slice(&gds);
        m.extend_from_slice(&bds);
        m.extend_from_slice(b"7777");
        m
    }

    /// Every fixture by name, for seed corpora and sweeping tests; `valid` says whether a
    /// reader should accept and decode it.
    pub fn all() -> Vec<(&'static str, bool, Vec<u8>)> {
        vec![
            ("valid_rh", true, valid_rh()),
            ("valid_rh_with_bitmap", true, valid_rh_with_bitmap()),
            ("no_rh", true, no_rh()),
            ("grib1_rh", false, grib1_rh()),
            ("truncated", false, truncated()),
            ("random_bytes", false, random_bytes(0x5eed, 512)),
            ("bits_per_value_255", false, bits_per_value_255()),
            ("huge_packed_count", false, huge_packed_count()),
            ("huge_grid_claim", false, huge_grid_claim()),
            ("unsupported_grid", false, unsupported_grid()),
            ("short_grid_section", false, short_grid_section()),
            ("bad_reference_date", false, bad_reference_date()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::fixtures::*;
    use super::*;
    use gribberish::message::{Message, MessageIterator};

    /// Half a packing step: the worst rounding error of simple packing.
    fn tolerance(m: &[u8]) -> f64 {
        let (p, _) = find_section(m, 5).unwrap();
        let e = m[p + 15..p + 17]
            .try_into()
            .map(u16::from_be_bytes)
            .unwrap();
        let d = m[p + 17..p + 19]
            .try_into()
            .map(u16::from_be_bytes)
            .unwrap();
        let sm = |x: u16| {
            if x & 0x8000 != 0 {
                -((x & 0x7fff) as i32)
            } else {
                x as i32
            }
        };
        0.5 * 2f64.powi(sm(e)) / 10f64.powi(sm(d)) + 1e-9
    }

    #[test]
    fn sign_magnitude() {
        assert_eq!(sm32(-40_000_000), 0x8000_0000 | 40_000_000);
        assert_eq!(sm16(-3), 0x8003);
        assert_eq!(sm8(-1), 0x81);
        assert_eq!(micro_deg(-0.5), 0x8000_0000 | 500_000);
        assert_eq!(scaled_level(50000.0), (0, 50000));
        assert_eq!(scaled_level(0.5), (1, 5));
        assert_eq!(scaled_level(-2.25), (2, 0x8000_0000 | 225));
    }

    #[test]
    fn octets_are_where_the_spec_puts_them() {
        let f = small_field(param::RH, 500.0, rh_values(500.0));
        let m = encode_message(&f);
        assert_eq!(&m[..4], b"GRIB");
        assert_eq!(m[7], 2);
        assert_eq!(
            u64::from_be_bytes(m[8..16].try_into().unwrap()),
            m.len() as u64
        );
        assert_eq!(&m[m.len() - 4..], b"7777");
        let o = |sec: u8, octet: usize| find_section(&m, sec).unwrap().0 + octet - 1;
        let u32at = |at: usize| u32::from_be_bytes(m[at..at + 4].try_into().unwrap());
        assert_eq!(u16::from_be_bytes([m[o(1, 6)], m[o(1, 7)]]), 7);
        assert_eq!(u16::from_be_bytes([m[o(1, 13)], m[o(1, 14)]]), 2024);
        assert_eq!(m[o(3, 15)], 6);
        assert_eq!(u32at(o(3, 31)), NI);
        assert_eq!(u32at(o(3, 35)), NJ);
        assert_eq!(u32at(o(3, 47)), 50_000_000);
        assert_eq!(m[o(3, 55)], 0x30);
        assert_eq!(u32at(o(3, 64)), 1_000_000);
        assert_eq!(m[o(3, 72)], 0);
        assert_eq!((m[o(4, 10)], m[o(4, 11)], m[o(4, 18)]), (1, 1, 1));
        assert_eq!(u32at(o(4, 19)), 12);
        assert_eq!((m[o(4, 23)], m[o(4, 24)]), (100, 0));
        assert_eq!(u32at(o(4, 25)), 50_000);
        assert_eq!(m[o(4, 29)], 255);
        assert_eq!(u32at(o(5, 6)), NI * NJ);
        assert_eq!(m[o(5, 20)], 10);
        assert_eq!(m[o(6, 6)], 255);
    }

    #[test]
    fn negative_longitudes_use_sign_magnitude() {
        let mut f = small_field(param::RH, 500.0, rh_values(500.0));
        (f.lon1, f.lon2) = (-40.0, -35.0);
        let m = encode_message(&f);
        let (p, _) = find_section(&m, 3).unwrap();
        assert_eq!(
            &m[p + 50..p + 54],
            &(0x8000_0000u32 | 40_000_000).to_be_bytes()
        );
    }

    #[test]
    fn packing_round_trips_within_half_a_step() {
        let v: Vec<f64> = (0..1000)
            .map(|k| -40.0 + (k as f64 * 0.37).sin() * 300.0)
            .collect();
        for (d, bits) in [(0, 8), (1, 12), (2, 16), (-1, 6), (0, 24)] {
            let p = pack_simple(&v, d, bits);
            let step = 2f64.powi(p.binary_scale as i32) / 10f64.powi(d as i32);
            let mut pos = 0usize;
            for &y in &v {
                let mut x = 0u64;
                for _ in 0..bits {
                    let bit = (p.data[pos / 8] >> (7 - pos % 8)) & 1;
                    x = (x << 1) | bit as u64;
                    pos += 1;
                }
                let back = (p.reference as f64 + x as f64 * 2f64.powi(p.binary_scale as i32))
                    / 10f64.powi(d as i32);
                assert!(
                    (back - y).abs() <= 0.5 * step + 1e-6,
                    "{d} {bits}: {y} -> {back}"
                );
            }
        }
    }

    #[test]
    fn gribberish_decodes_what_we_encode() {
        let fields = valid_rh_fields();
        let bytes = encode_file(&fields);
        let msgs: Vec<Message> = MessageIterator::from_data(&bytes, 0).collect();
        assert_eq!(msgs.len(), fields.len());
        for (m, f) in msgs.iter().zip(&fields) {
            let abbrev = m.variable_abbrev().unwrap();
            let want = if f.category == 1 { "RH" } else { "HGT" };
            assert_eq!(abbrev.to_uppercase(), want);
            let (_, level) = m.first_fixed_surface().unwrap();
            assert_eq!(level, Some(f.level_value));
            assert_eq!(m.grid_dimensions().unwrap(), (NJ as usize, NI as usize));
            let data = m.data().unwrap();
            let tol = tolerance(&bytes[m.byte_offset()..]);
            assert_eq!(data.len(), f.values.len());
            for (a, b) in data.iter().zip(&f.values) {
                assert!((a - b).abs() <= tol, "{a} vs {b} (tolerance {tol})");
            }
            assert_eq!(
                m.forecast_date().unwrap().to_rfc3339(),
                "2024-06-01T12:00:00+00:00"
            );
        }
    }

    #[test]
    fn gribberish_maps_the_bitmap_to_nan() {
        let bytes = valid_rh_with_bitmap();
        let m = MessageIterator::from_data(&bytes, 0).next().unwrap();
        let data = m.data().unwrap();
        let want = rh_values(700.0);
        assert_eq!(data.len(), want.len());
        for (k, (a, b)) in data.iter().zip(&want).enumerate() {
            if [0, NI as usize - 1, (NI * NJ) as usize - 1].contains(&k) {
                assert!(a.is_nan(), "point {k} should be missing");
            } else {
                assert!((a - b).abs() <= 0.051, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn grib1_fixture_is_well_formed() {
        let bytes = grib1_rh();
        assert_eq!(&bytes[..4], b"GRIB");
        assert_eq!(bytes[7], 1);
        let total = u32::from_be_bytes([0, bytes[4], bytes[5], bytes[6]]) as usize;
        assert_eq!(total, bytes.len());
        let m = MessageIterator::from_data(&bytes, 0).next().unwrap();
        let data = m.data().unwrap();
        assert_eq!(data.len(), GRIB1_VALUES.len());
        for (a, b) in data.iter().zip(GRIB1_VALUES) {
            assert!((a - b).abs() < 1e-3, "{a} vs {b}");
        }
        assert_eq!(m.first_fixed_surface().unwrap().1, Some(500.0));
    }

    #[test]
    fn fixtures_are_small_and_the_reader_refuses_the_bad_ones() {
        for (name, valid, bytes) in all() {
            assert!(bytes.len() < 2048, "{name} is {} bytes", bytes.len());
            let verdict = crate::grib::scan(&bytes).and_then(|infos| {
                infos
                    .iter()
                    .map(|i| crate::grib::decode_values(&bytes, i).map(|_| ()))
                    .collect::<Result<Vec<()>, _>>()
            });
            // The reader keeps a message whose date is impossible (reference time None);
            // whether to refuse it is the reader's policy, so only "no panic" is checked.
            if name != "bad_reference_date" {
                assert_eq!(verdict.is_ok(), valid, "{name}: {verdict:?}");
            }
        }
        for seed in 1..50 {
            let bytes = flipped_data_bits(seed);
            if let Ok(infos) = crate::grib::scan(&bytes) {
                for i in &infos {
                    let _ = crate::grib::decode_values(&bytes, i);
                }
            }
        }
    }

    /// Cross-check against ecCodes, an independent decoder:
    /// `pip install eccodes && cargo test -p stratus-ingest eccodes -- --ignored`.
    #[test]
    #[ignore = "needs python3 with the eccodes package"]
    fn eccodes_decodes_what_we_encode() {
        let ok = std::process::Command::new("python3")
            .args(["-c", "import eccodes"])
            .status()
            .is_ok_and(|s| s.success());
        assert!(ok, "python3 -c 'import eccodes' fails: pip install eccodes");
        let mut fields = valid_rh_fields();
        // Negative longitudes, negative values, a bit-map, fine and coarse packing.
        let mut t = small_field(param::T, 925.0, vec![0.0; (NI * NJ) as usize]);
        (t.lon1, t.lon2) = (-40.0, -35.0);
        t.values = (0..NI * NJ).map(|k| -12.5 + 0.731 * k as f64).collect();
        (t.decimal_scale, t.bits) = (2, 16);
        fields.push(t);
        let mut rh = small_field(param::RH, 250.0, rh_values(250.0));
        rh.values[7] = f64::NAN;
        rh.values[8] = f64::NAN;
        (rh.decimal_scale, rh.bits) = (0, 5);
        rh.forecast_hours = 384;
        fields.push(rh);
        let dir = tempfile::tempdir().unwrap();
        let grib = dir.path().join("f.grib2");
        std::fs::write(&grib, encode_file(&fields)).unwrap();
        let mut expect = String::new();
        for f in &fields {
            let short = match (f.category, f.number) {
                (1, 1) => "r",
                (3, 5) => "gh",
                _ => "t",
            };
            let vals: Vec<String> = f.values.iter().map(|v| format!("{v}")).collect();
            expect += &format!(
                "{short} {} {} {} {} {} {} {} {} {}\n",
                f.level_value / 100.0,
                f.ni,
                f.nj,
                f.lat1,
                f.lon1.rem_euclid(360.0),
                f.lat2,
                f.lon2.rem_euclid(360.0),
                f.forecast_hours,
                vals.join(",")
            );
        }
        let exp = dir.path().join("expect.txt");
        std::fs::write(&exp, expect).unwrap();
        let g1 = dir.path().join("g1.grib");
        std::fs::write(&g1, grib1_rh()).unwrap();
        let g1_vals: Vec<String> = GRIB1_VALUES.iter().map(|v| v.to_string()).collect();
        let out = std::process::Command::new("python3")
            .args(["-c", ECCODES_CHECK])
            .arg(&grib)
            .arg(&exp)
            .arg(&g1)
            .arg(g1_vals.join(","))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).to_string()
            + &String::from_utf8_lossy(&out.stderr);
        println!("{text}");
        assert!(out.status.success(), "ecCodes check failed:\n{text}");
    }

    const ECCODES_CHECK: &str = r#"
import sys, math, eccodes
grib, exp, g1, g1vals = sys.argv[1:5]
lines = [l.split() for l in open(exp).read().splitlines()]
worst = 0.0
with open(grib, 'rb') as f:
    for k, want in enumerate(lines):
        h = eccodes.codes_grib_new_from_file(f)
        assert h is not None, f'message {k} missing'
        g = lambda key: eccodes.codes_get(h, key)
        short, lev, ni, nj, la1, lo1, la2, lo2, step, vals = want
        got = (g('shortName'), g('typeOfLevel'), g('level'), g('Ni'), g('Nj'), g('step'), g('edition'))
        assert got == (short, 'isobaricInhPa', int(float(lev)), int(ni), int(nj), int(step), 2), (k, got)
        for key, v in [('latitudeOfFirstGridPointInDegrees', la1), ('longitudeOfFirstGridPointInDegrees', lo1),
                       ('latitudeOfLastGridPointInDegrees', la2), ('longitudeOfLastGridPointInDegrees', lo2)]:
            d = g(key) - float(v)
            if key.startswith('lon'):
                d = (d + 180.0) % 360.0 - 180.0
            assert abs(d) < 1e-6, (k, key, g(key), v)
        assert g('dataDate') == 20240601 and g('dataTime') == 0, k
        assert g('centre') == 'kwbc' and g('shapeOfTheEarth') == 6, k
        tol = 0.5 * 2.0 ** g('binaryScaleFactor') / 10.0 ** g('decimalScaleFactor') + 1e-9
        miss = g('missingValue')
        out = eccodes.codes_get_values(h)
        exp_vals = [float(x) for x in vals.split(',')]
        assert len(out) == len(exp_vals), k
        for a, b in zip(out, exp_vals):
            if math.isnan(b):
                assert a == miss, (k, a)
            else:
                assert abs(a - b) <= tol, (k, a, b, tol)
                worst = max(worst, abs(a - b) / tol)
        print(f'{short:>2} {lev:>6} hPa {ni}x{nj} ok (E={g("binaryScaleFactor")} D={g("decimalScaleFactor")} '
              f'bits={g("bitsPerValue")} missing={g("numberOfMissing")})')
        eccodes.codes_release(h)
    assert eccodes.codes_grib_new_from_file(f) is None, 'extra message'
print(f'worst error {worst:.3f} of the half-step tolerance')
with open(g1, 'rb') as f:
    h = eccodes.codes_grib_new_from_file(f)
    g = lambda key: eccodes.codes_get(h, key)
    assert (g('edition'), g('indicatorOfParameter'), g('shortName'), g('level'), g('Ni'), g('Nj')) == (1, 52, 'r', 500, 4, 3)
    out = eccodes.codes_get_values(h)
    assert all(abs(a - float(b)) < 1e-4 for a, b in zip(out, g1vals.split(','))), list(out)
    print('GRIB1 fixture ok', g('dataDate'), g('step'), g('latitudeOfFirstGridPointInDegrees'), g('longitudeOfLastGridPointInDegrees'))
"#;
}
