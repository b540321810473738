//! What every fix a follow parser accepts must hold (shared by the two UDP targets): the
//! ranges `Fix::checked` and `Fix::with_motion` promise, and a camera the renderer accepts,
//! at the fix and after the longest extrapolation at its fastest allowed speed and climb.

use stratus::follow::{Fix, ALT_RANGE_M, MAX_CLIMB, MAX_EXTRAPOLATION, MAX_SPEED};

pub fn check(fix: &Fix) {
    assert!((-90.0..=90.0).contains(&fix.lat), "{fix:?}");
    assert!((-180.0..=180.0).contains(&fix.lon), "{fix:?}");
    assert!(
        (ALT_RANGE_M.0..=ALT_RANGE_M.1).contains(&fix.alt_m),
        "{fix:?}"
    );
    // rem_euclid may round a tiny negative heading up to 360 itself: the same direction.
    assert!((0.0..=360.0).contains(&fix.heading), "{fix:?}");
    assert!((-90.0..=90.0).contains(&fix.pitch), "{fix:?}");
    assert!((-180.0..=180.0).contains(&fix.roll), "{fix:?}");
    if let Some(v) = fix.ground_speed {
        assert!((0.0..=MAX_SPEED).contains(&v), "{fix:?}");
    }
    if let Some(c) = fix.climb {
        assert!((-MAX_CLIMB..=MAX_CLIMB).contains(&c), "{fix:?}");
    }
    let t = MAX_EXTRAPOLATION.as_secs_f64();
    let v = fix.ground_speed.unwrap_or(MAX_SPEED);
    for dz in [-MAX_CLIMB * t, 0.0, MAX_CLIMB * t] {
        let moved = fix.moved(v * t, dz);
        if let Err(e) = moved.camera().validate() {
            panic!("{fix:?} extrapolated to {moved:?}: {e}");
        }
    }
    if let Err(e) = fix.camera().validate() {
        panic!("{fix:?}: {e}");
    }
}
