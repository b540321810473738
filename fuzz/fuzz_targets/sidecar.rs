//! Any byte string as a CloudMap sidecar (`MAP.json`): parsing and validation must return
//! `Ok` or `Err`, never panic; and a sidecar that validates must survive being written and read
//! back unchanged, still valid (what `ingest` writes and `render` reads).
//!
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run sidecar fuzz/corpus/sidecar fuzz/seeds-sidecar` from the
//! workspace root.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stratus_ingest::meta::parse_time;
use stratus_ingest::CloudMapMeta;

fuzz_target!(|data: &[u8]| {
    if let Ok(s) = std::str::from_utf8(data) {
        // The one time parser, on whatever text comes.
        let _ = parse_time(s);
    }
    let Ok(meta) = serde_json::from_slice::<CloudMapMeta>(data) else {
        return;
    };
    let content = meta.validate_content();
    let Ok(()) = meta.validate() else {
        return;
    };
    assert!(content.is_ok(), "validate passed but validate_content failed");
    let text = serde_json::to_string_pretty(&meta).expect("a valid sidecar serialises");
    let back: CloudMapMeta = serde_json::from_str(&text).expect("a written sidecar parses");
    assert_eq!(back, meta, "a sidecar changed on the way through");
    back.validate().expect("a written sidecar validates");
});
