//! Pins the gribberish 1.9 behaviours `grib.rs` works around, so a dependency bump that changes
//! them is noticed (and docs/ingest.md updated).

use std::path::Path;

#[test]
fn gribberish_lists_a_cut_off_last_message_as_whole_and_stratus_refuses_it() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data-samples/gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    let bytes = std::fs::read(path).unwrap();
    let whole = gribberish::message::MessageIterator::from_data(&bytes, 0).count();
    let cut = &bytes[..bytes.len() - 5000];
    let upstream = std::panic::catch_unwind(|| {
        gribberish::message::MessageIterator::from_data(cut, 0).count()
    });
    // Upstream lists the cut-off message as if it were whole, without a word.
    assert_eq!(upstream.ok(), Some(whole));
    let last = std::panic::catch_unwind(|| {
        let m = gribberish::message::MessageIterator::from_data(cut, 0)
            .last()
            .unwrap();
        (
            m.len(),
            m.byte_offset(),
            m.data().map(|v| v.len()).map_err(|e| e.to_string()),
        )
    });
    println!(
        "gribberish on the cut-off last message: {last:?} (file is {} bytes)",
        cut.len()
    );
    // It reports the declared length, not the bytes there, and blames a missing data section.
    let (len, off, data) = last.unwrap();
    assert!(off + len > cut.len());
    assert!(data.is_err());
    let ours = stratus_ingest::grib::scan(cut).unwrap_err().to_string();
    assert!(ours.contains("cut off"), "{ours}");
}
