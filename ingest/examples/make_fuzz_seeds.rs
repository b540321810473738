//! Writes the seed corpus of the `grib2` fuzz target: every test fixture (valid files and the
//! damaged ones), each a few hundred bytes, so the fuzzer starts from real section layouts.
//!
//! `cargo run -p stratus-ingest --example make_fuzz_seeds -- fuzz/seeds`

use stratus_ingest::encode::fixtures;

fn main() {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "fuzz/seeds".into());
    std::fs::create_dir_all(&dir).expect("create seed directory");
    let mut seeds = fixtures::all();
    seeds.push(("flipped_data_bits", true, fixtures::flipped_data_bits(7)));
    for (name, _, bytes) in seeds {
        let path = std::path::Path::new(&dir).join(format!("{name}.grib"));
        std::fs::write(&path, &bytes).expect("write seed");
        println!("{} ({} bytes)", path.display(), bytes.len());
    }
}
