//! Simple packing (data representation template 5.0): values → reference, scales and bits.

use super::bits::{f32_at_or_below, BitWriter};

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
