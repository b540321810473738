//! Decoding one validated field into a north-up [`Field`]. The data section itself is
//! unpacked by gribberish, on the bytes of that one field only, with its panics contained
//! (see [`super::guard`]) and its output checked against the grid it must fill.

use super::guard::contained;
use super::info::{LatLonGrid, MessageInfo};
use super::validate::validate_for_decode;
use super::GribError;

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

/// Decode one message (field) of `bytes`, the whole file [`scan`](super::scan()) read it from.
pub fn decode_values(bytes: &[u8], info: &MessageInfo) -> Result<Field, GribError> {
    let grid = validate_for_decode(bytes, info)?;
    let (index, offset) = (info.index, info.offset);
    let corrupt = |msg: String| GribError::Corrupt { index, offset, msg };
    let single = single_field_message(&bytes[offset..offset + info.length], info);
    let result = contained(|| {
        let m = gribberish::message::Message::from_data(&single, 0)
            .ok_or_else(|| "gribberish did not recognise the message".to_string())?;
        m.data().map_err(|e| e.to_string())
    });
    let raw = match result {
        Some(Ok(v)) => v,
        Some(Err(e)) => return Err(corrupt(format!("data section does not decode: {e}"))),
        None => {
            return Err(corrupt(
                "data section does not decode (the decoder failed on inconsistent packed data)"
                    .into(),
            ))
        }
    };
    let n = grid.ni * grid.nj;
    if raw.len() != n {
        return Err(corrupt(format!(
            "decoded {} values for {n} grid points",
            raw.len()
        )));
    }
    if raw.iter().any(|v| v.is_infinite()) {
        return Err(corrupt("decoded values include infinities".into()));
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
    let s = &info.sections;
    let mut parts: Vec<(usize, usize)> = vec![s.s1];
    parts.extend(s.s2);
    parts.extend([s.s3, s.s4, s.s5, s.s6, s.s7]);
    let body: usize = parts.iter().map(|(a, b)| b - a).sum();
    let total = 16 + body + 4;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&msg[..8]);
    out.extend_from_slice(&(total as u64).to_be_bytes());
    for (a, b) in parts {
        out.extend_from_slice(&msg[a..b]);
    }
    // An inherited bit-map (indicator 254) was resolved to the earlier section 6 itself.
    out.extend_from_slice(b"7777");
    out
}
