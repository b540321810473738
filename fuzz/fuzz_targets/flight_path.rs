//! Any byte string as a flight path (`--path PATH.json`): parsing, validation, the frame count
//! and sampling must return, never panic; and every camera sampled from a path that validates
//! must itself validate, so a run that starts never fails half-way on a bad camera.
//!
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run flight_path fuzz/corpus/flight_path fuzz/seeds-flight`
//! from the workspace root.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stratus::flight::{FlightPath, DEFAULT_MAX_FRAMES};

fuzz_target!(|data: &[u8]| {
    let Ok(path) = FlightPath::parse(data) else {
        return;
    };
    let (first, last) = (path.keys[0].t, path.keys[path.keys.len() - 1].t);
    for fps in [0.001, 1.0, 10.0, 240.0] {
        if let Ok(n) = path.frames(fps, DEFAULT_MAX_FRAMES) {
            assert!((1..=DEFAULT_MAX_FRAMES).contains(&n));
        }
    }
    // Every key, the midpoints between keys, and points past either end (clamped).
    let mut ts: Vec<f64> = path.keys.iter().map(|k| k.t).collect();
    ts.extend(path.keys.windows(2).map(|w| w[0].t + (w[1].t - w[0].t) * 0.5));
    ts.extend([first - 1.0, last + 1.0, f64::MIN, f64::MAX]);
    for t in ts.into_iter().take(64) {
        let (cam, _time) = path.at(t);
        if let Err(e) = cam.validate() {
            panic!("t = {t}: a valid path sampled to a camera that is not: {e}");
        }
    }
});
