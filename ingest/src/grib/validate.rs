//! Validation before decoding: everything `decode_values` (and the decoder under it) will
//! trust is checked against the bytes really there, so no allocation is sized by an unchecked
//! header and no unsupported layout reaches the decoder.

use super::info::{LatLonGrid, MessageInfo};
use super::scan::Sec;
use super::tables::{BitmapIndicator, GridTemplate, Packing};
use super::{GribError, MAX_POINTS};

/// Check one field of `bytes` (the whole file) for decoding; returns its grid.
pub(super) fn validate_for_decode(
    bytes: &[u8],
    info: &MessageInfo,
) -> Result<LatLonGrid, GribError> {
    let secs = &info.sections;
    if info.offset + info.length > bytes.len() || secs.s7.1 > info.length {
        return Err(corrupt(info, "message lies outside the file".into()));
    }
    let grid = check_grid(info)?;
    let declared = grid.ni as u64 * grid.nj as u64;
    check_bitmap(bytes, info, declared)?;
    check_packing(bytes, info)?;
    Ok(grid)
}

/// The field's message is corrupt: `msg` says how.
fn corrupt(info: &MessageInfo, msg: String) -> GribError {
    GribError::Corrupt {
        index: info.index,
        offset: info.offset,
        msg,
    }
}

/// The field's message uses what stratus does not decode: `msg` says what.
fn unsupported(info: &MessageInfo, msg: String) -> GribError {
    GribError::Unsupported {
        index: info.index,
        offset: info.offset,
        msg,
    }
}

/// The grid: a regular lat/lon grid (template 3.0) of at least 2×2 and at most [`MAX_POINTS`]
/// points as section 3 counts them, with finite positive increments, row-major, within ±90°,
/// and no more packed values than points.
fn check_grid(info: &MessageInfo) -> Result<LatLonGrid, GribError> {
    let grid = match (&info.grid, info.grid_template) {
        (Some(g), Some(GridTemplate::LatLon)) => g.clone(),
        (_, t) => {
            let t = t.map_or(u16::MAX, GridTemplate::code);
            return Err(unsupported(
                info,
                format!(
                    "grid template 3.{t} is not supported (only 3.0 regular latitude/longitude)"
                ),
            ));
        }
    };
    let declared = grid.ni as u64 * grid.nj as u64;
    if grid.ni < 2 || grid.nj < 2 {
        return Err(unsupported(
            info,
            format!("grid {}x{} is too small to interpolate", grid.ni, grid.nj),
        ));
    }
    if declared != info.grid_points {
        return Err(corrupt(
            info,
            format!(
                "grid claims {}x{} = {declared} points but section 3 says {}",
                grid.ni, grid.nj, info.grid_points
            ),
        ));
    }
    if declared > MAX_POINTS {
        return Err(corrupt(
            info,
            format!(
                "grid claims {}x{} = {declared} points, more than the {MAX_POINTS} accepted",
                grid.ni, grid.nj
            ),
        ));
    }
    if !(grid.di > 0.0 && grid.dj > 0.0 && grid.di.is_finite() && grid.dj.is_finite()) {
        return Err(corrupt(
            info,
            format!("grid increments {} x {} degrees", grid.di, grid.dj),
        ));
    }
    if grid.scan_mode & 0x20 != 0 {
        return Err(unsupported(
            info,
            "scanning mode with adjacent points in j (column-major)".into(),
        ));
    }
    if grid.north() > 90.0 + 1e-6 || grid.south() < -90.0 - 1e-6 {
        return Err(corrupt(
            info,
            format!("latitudes {}..{} outside ±90", grid.lat1, grid.lat2),
        ));
    }
    if info.packed_values > declared {
        return Err(corrupt(
            info,
            format!(
                "section 5 packs {} values into a grid of {declared} points",
                info.packed_values
            ),
        ));
    }
    Ok(grid)
}

/// The bit-map: none with a value for every point, or one whose set bits match the packed
/// values; predefined and earlier bit-maps are not supported.
fn check_bitmap(bytes: &[u8], info: &MessageInfo, declared: u64) -> Result<(), GribError> {
    let offset = info.offset;
    let secs = &info.sections;
    match info.bitmap {
        BitmapIndicator::None => {
            if info.packed_values != declared {
                return Err(corrupt(info, format!(
                    "grid has {declared} points but section 5 packs {} values and there is no bit-map",
                    info.packed_values
                )));
            }
        }
        BitmapIndicator::Present => {
            let (a, b) = secs.s6;
            let bitmap = &bytes[offset + a + 6..offset + b];
            if (bitmap.len() as u64) * 8 < declared {
                return Err(corrupt(
                    info,
                    format!(
                        "bit-map holds {} bits for {declared} points",
                        bitmap.len() * 8
                    ),
                ));
            }
            let ones: u64 = bitmap.iter().map(|x| x.count_ones() as u64).sum::<u64>()
                - trailing_ones(bitmap, declared);
            if ones != info.packed_values {
                return Err(corrupt(
                    info,
                    format!(
                        "bit-map marks {ones} points present but section 5 packs {} values",
                        info.packed_values
                    ),
                ));
            }
        }
        x @ (BitmapIndicator::Predefined(_) | BitmapIndicator::Previous) => {
            return Err(unsupported(
                info,
                format!(
                    "bit-map indicator {} (predefined or earlier bit-map)",
                    x.code()
                ),
            ))
        }
    }
    Ok(())
}

/// The packing: a supported template whose bits per value, and for complex packing whose
/// group descriptors, fit the data section.
fn check_packing(bytes: &[u8], info: &MessageInfo) -> Result<(), GribError> {
    let (index, offset) = (info.index, info.offset);
    let secs = &info.sections;
    let (a5, b5) = secs.s5;
    let s5 = Sec {
        b: &bytes[offset + a5..offset + b5],
        index,
        offset,
        num: 5,
    };
    let data_len = (secs.s7.1 - secs.s7.0).saturating_sub(5) as u64;
    let packing = match info.packing {
        Some(p) if p.is_supported() => p,
        p => {
            let t = p.map_or(u16::MAX, Packing::code);
            return Err(unsupported(info, format!(
                "data packing 5.{t} (supported: 5.0 simple, 5.2/5.3 complex, 5.40 JPEG2000, 5.41 PNG, 5.42 CCSDS)"
            )));
        }
    };
    let bits = s5.u8(20)? as u64;
    if matches!(packing, Packing::Simple | Packing::Png | Packing::Ccsds) && bits > 32 {
        return Err(corrupt(info, format!("{bits} bits per value (at most 32)")));
    }
    if packing == Packing::Simple && data_len * 8 < bits * info.packed_values {
        return Err(corrupt(
            info,
            format!(
                "data section holds {data_len} bytes; {} values of {bits} bits need {}",
                info.packed_values,
                (bits * info.packed_values).div_ceil(8)
            ),
        ));
    }
    if matches!(packing, Packing::Complex | Packing::ComplexSpatialDiff) {
        let groups = s5.u32(32)? as u64;
        if bits > 32 || groups > info.packed_values.max(1) {
            return Err(corrupt(
                info,
                format!(
                "complex packing declares {groups} groups of {bits}-bit references for {} values",
                info.packed_values
            ),
            ));
        }
        let group_width_bits = s5.u8(37)? as u64;
        let group_len_bits = s5.u8(47)? as u64;
        // A constant field (no groups; NCEP sends such) leaves the descriptor octets unset.
        if groups > 0 && (group_width_bits > 32 || group_len_bits > 32) {
            return Err(corrupt(
                info,
                "complex packing group descriptors wider than 32 bits".into(),
            ));
        }
        let need = (groups * (bits + group_width_bits + group_len_bits)).div_ceil(8);
        if need > data_len {
            return Err(corrupt(info, format!(
                "complex packing needs {need} bytes of group descriptors; data section holds {data_len}"
            )));
        }
    }
    Ok(())
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

/// Validate one whole GRIB2 message standing alone (`msg` is exactly its bytes, as a byte-range
/// download delivers it): it must scan as exactly one message filling `msg`, and every field in
/// it must pass the checks a field passes before it is decoded. Returns its fields.
pub fn validate_message(msg: &[u8]) -> Result<Vec<MessageInfo>, GribError> {
    if msg.len() < 16 || &msg[..4] != b"GRIB" {
        return Err(GribError::Corrupt {
            index: 0,
            offset: 0,
            msg: "the bytes do not start with a 'GRIB' marker".into(),
        });
    }
    let fields = super::scan(msg)?;
    if let Some(f) = fields.iter().find(|f| f.index != 0) {
        return Err(GribError::Corrupt {
            index: f.index,
            offset: f.offset,
            msg: "more than one message where one was expected".into(),
        });
    }
    if let Some(f) = fields.first().filter(|f| f.length != msg.len()) {
        return Err(GribError::Corrupt {
            index: 0,
            offset: 0,
            msg: format!(
                "the message declares {} bytes but {} arrived",
                f.length,
                msg.len()
            ),
        });
    }
    for f in &fields {
        validate_for_decode(msg, f)?;
    }
    Ok(fields)
}
