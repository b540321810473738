//! GRIB2 reading, one job per module:
//! - [`scan`](mod@scan): find every message and read its section headers, never decoding data, so
//!   `inspect` is cheap and every size a file declares is checked against the bytes it really
//!   has before anything is allocated for it;
//! - [`info`]: what a field's headers say ([`MessageInfo`], [`LatLonGrid`]) and how `inspect`
//!   shows it;
//! - [`tables`]: the WMO code tables those headers use, as enums;
//! - `validate`: the checks a field must pass before its data is decoded;
//! - `decode`: decoding one field (through gribberish) into a north-up [`Field`];
//! - `guard`: containing the decoder's panics (gribberish 1.9 can panic on corrupted data).

mod decode;
mod guard;
pub mod info;
pub mod scan;
pub mod tables;
mod validate;

use thiserror::Error;

pub use decode::{decode_values, Field};
pub use info::{LatLonGrid, MessageInfo};
pub use scan::scan;
pub use tables::{
    BitmapIndicator, Discipline, GridTemplate, Packing, ProductionStatus, SurfaceType, TimeUnit,
};
pub use validate::validate_message;

/// Largest grid accepted (points). A 0.1° global grid is 6.5 M; this leaves room for finer ones
/// while refusing headers that would make a multi-gigabyte allocation.
pub const MAX_POINTS: u64 = 64 * 1024 * 1024;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum GribError {
    #[error("empty file")]
    Empty,
    #[error("{}", crate::error::not_grib(*.0))]
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
