//! Byte builders for tests: valid files and the damaged or unsupported inputs the reader must
//! refuse without panicking. Each is a few hundred bytes.
//!
//! Compiled only with the `fixtures` cargo feature (tests, examples and fuzz enable it).
use chrono::{TimeZone, Utc};

use super::bits::{micro_deg, sm16, BitWriter};
use super::message::section;
use super::{encode_file, encode_message, encode_sections, find_section, param, Grib2Field};
use crate::grib::tables::{Discipline, SurfaceType};

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
        discipline: Discipline::from_code(p.0),
        category: p.1,
        number: p.2,
        level_type: Some(SurfaceType::Isobaric),
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
