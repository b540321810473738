//! Any datagram as a FlightGear generic-protocol line (`--follow flightgear`, the
//! docs/flightgear/stratus.xml definition): the parser returns a checked fix or an error,
//! never panics, and a fix it returns holds every range the follower relies on
//! (shared/follow_fix.rs).
//!
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run flightgear_udp fuzz/corpus/flightgear_udp fuzz/seeds-flightgear`
//! from the workspace root.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stratus::follow::flightgear;

#[path = "shared/follow_fix.rs"]
mod follow_fix;

fuzz_target!(|data: &[u8]| {
    if let Ok(fix) = flightgear::parse(data) {
        follow_fix::check(&fix);
    }
});
