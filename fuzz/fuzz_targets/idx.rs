//! Any byte string as a `.idx` inventory (what `fetch` reads from a server): parsing must
//! return `Ok` or `Err`, never panic, and what it accepts must hold the promises `fetch`
//! relies on — messages in increasing, non-overlapping byte order, each within the size
//! bounds, only the last without an end, at most `MAX_IDX_LINES` lines; and picking fields
//! and planning the requests from it must not panic either.
//!
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run idx fuzz/corpus/idx fuzz/seeds-idx` from the workspace
//! root.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stratus_ingest::fetch::idx::{self, MAX_IDX_LINES, MAX_MESSAGE_BYTES, MIN_MESSAGE_BYTES};
use stratus_ingest::fetch::select::{self, Levels};
use stratus_ingest::fetch::{plan_chunks, MAX_CHUNK_BYTES};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(messages) = idx::parse(text) else {
        return;
    };
    assert!(!messages.is_empty());
    let lines: usize = messages.iter().map(|m| m.lines.len()).sum();
    assert!(lines <= MAX_IDX_LINES);
    for (i, m) in messages.iter().enumerate() {
        assert!(!m.lines.is_empty());
        assert!(m.lines.iter().all(|l| l.offset == m.start));
        match (m.end, messages.get(i + 1)) {
            (Some(end), Some(next)) => {
                assert_eq!(end, next.start);
                let len = end - m.start;
                assert!((MIN_MESSAGE_BYTES..=MAX_MESSAGE_BYTES).contains(&len));
            }
            (None, None) => {}
            _ => panic!("only the last message runs to the end of the file"),
        }
    }
    for fields in [select::default_fields(), select::parse_fields("TMP,r,tcc").unwrap()] {
        if let Ok(picked) = select::pick(&messages, &fields, &Levels::All) {
            let chunks = plan_chunks(&picked, MAX_CHUNK_BYTES);
            let covered: usize = chunks.iter().map(|c| c.messages.len()).sum();
            assert_eq!(covered, picked.len());
        }
    }
});
