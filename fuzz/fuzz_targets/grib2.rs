//! Any byte string must come back from the GRIB reader as `Ok` or `Err`, never as a panic, an
//! abort or an allocation sized by an unchecked header.
//!
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run grib2 fuzz/corpus/grib2 fuzz/seeds` from the workspace
//! root: new inputs go to the first (git-ignored) directory. The seeds are written by
//! `cargo run -p stratus-ingest --example make_fuzz_seeds -- fuzz/seeds`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stratus_ingest::grib::{decode_values, scan};

fuzz_target!(|data: &[u8]| {
    let Ok(infos) = scan(data) else {
        return;
    };
    for info in infos.iter().filter(|i| i.is_relative_humidity()) {
        if let Ok(field) = decode_values(data, info) {
            // A decoded field must be exactly as large as the grid it claims.
            assert_eq!(field.values.len(), field.grid.ni * field.grid.nj);
        }
    }
});
