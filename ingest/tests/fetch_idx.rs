//! The `.idx` generator against the real shared GFS files: every inventory it writes parses
//! back, and every message range it gives is one valid GRIB2 message that matches its lines —
//! what `fetch` checks of a downloaded range.

use std::path::Path;

use stratus_ingest::fetch::{check_against_inventory, idx};
use stratus_ingest::grib;

#[test]
fn generated_inventories_locate_every_message() {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-samples");
    for rel in [
        "gfs/gfs.t12z.pgrbf120.2p5deg.grib2",
        "gfs-series/gfs.t18z.pgrb2.2p50.f000",
        "gfs-series/gfs.t18z.pgrb2.2p50.f006",
    ] {
        let bytes = std::fs::read(shared.join(rel)).unwrap();
        let fields = grib::scan(&bytes).unwrap();
        let text = idx::write(&bytes, &fields);
        assert_eq!(text.lines().count(), fields.len(), "{rel}");
        let msgs = idx::parse(&text).unwrap();
        for m in &msgs {
            let end = m.end.map_or(bytes.len(), |e| e as usize);
            let msg = &bytes[m.start as usize..end];
            let got = grib::validate_message(msg).unwrap_or_else(|e| panic!("{rel} {m:?}: {e}"));
            check_against_inventory(m, &got).unwrap();
        }
        assert!(text.contains(":RH:500 mb:"), "{rel}");
    }
}
