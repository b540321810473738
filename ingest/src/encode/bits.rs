//! The bit-level encodings of the writer: GRIB2's sign-and-magnitude integers, angles and
//! scaled surface values, and an MSB-first bit writer for packed data and bit-maps.

/// GRIB2 signed integers are sign-and-magnitude: top bit is the sign.
pub(crate) fn sm32(v: i64) -> u32 {
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

pub(crate) fn sm16(v: i32) -> u16 {
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

pub(crate) fn sm8(v: i32) -> u8 {
    let mag = v.unsigned_abs();
    assert!(mag <= 0x7f, "{v} does not fit an 8-bit GRIB signed integer");
    if v < 0 {
        0x80 | mag as u8
    } else {
        mag as u8
    }
}

/// Degrees as GRIB2 micro-degrees (basic angle 0), sign-and-magnitude.
pub(crate) fn micro_deg(deg: f64) -> u32 {
    sm32((deg * 1e6).round() as i64)
}

/// A surface value as (scale factor, scaled value) with value = scaled / 10^scale, using the
/// smallest scale that represents it exactly (isobaric levels in Pa need 0).
pub(crate) fn scaled_level(v: f64) -> (u8, u32) {
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
pub(crate) fn f32_at_or_below(x: f64) -> f32 {
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
pub(crate) struct BitWriter {
    out: Vec<u8>,
    acc: u64,
    n: u32,
}

impl BitWriter {
    pub(crate) fn new() -> Self {
        BitWriter {
            out: Vec::new(),
            acc: 0,
            n: 0,
        }
    }
    pub(crate) fn put(&mut self, v: u32, bits: u32) {
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
    pub(crate) fn finish(mut self) -> Vec<u8> {
        if self.n > 0 {
            self.out.push((self.acc << (8 - self.n)) as u8);
        }
        self.out
    }
}
