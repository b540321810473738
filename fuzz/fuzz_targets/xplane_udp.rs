//! Any datagram as X-Plane's data output (`--follow xplane`): the parser returns a checked fix
//! or an error, never panics, and a fix it returns holds every range the follower relies on
//! (shared/follow_fix.rs), whatever attitude an earlier packet left.
//!
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run xplane_udp fuzz/corpus/xplane_udp fuzz/seeds-xplane`
//! from the workspace root.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stratus::follow::xplane;

#[path = "shared/follow_fix.rs"]
mod follow_fix;

fuzz_target!(|data: &[u8]| {
    for prev in [(0.0, 0.0, 0.0), (359.999, 89.9, -179.9)] {
        if let Ok(fix) = xplane::parse(data, prev) {
            follow_fix::check(&fix);
        }
    }
});
