//! A minimal GRIB2 writer (WMO FM 92 GRIB edition 2), written from the WMO manual, for the
//! synthetic demo file and for test fixtures. It writes exactly one product per message:
//! sections 0, 1, 3 (template 3.0 regular lat/lon), 4 (template 4.0), 5 (template 5.0 simple
//! packing), 6 (bit-map only when a value is NaN), 7 and 8. Octet numbers in comments are the
//! 1-based ones of the WMO tables.
//!
//! - [`bits`](self): sign-and-magnitude integers, scaled values, the bit writer (private);
//! - [`pack_simple`]: simple packing of the values;
//! - [`encode_message`] and friends: sections and their assembly;
//! - `fixtures` (feature `fixtures`): valid and damaged files for tests, examples and fuzzing.
//!
//! Inputs are built by code, not read from files, so inconsistent inputs are programming errors
//! and panic with a message rather than returning an error.

mod bits;
mod message;
mod pack;

#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
#[cfg(test)]
mod tests;

pub use message::{
    assemble_message, encode_file, encode_message, encode_sections, find_section, param,
    Grib2Field, Sections,
};
pub use pack::{pack_simple, Packed};
