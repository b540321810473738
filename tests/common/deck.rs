//! The synthetic scene the temporal tests (reproject, tsr) render: a middle deck 3–5 km over
//! 0–2°N 0–4°E (256×128) at noon of the June solstice, the `fast` preset at a fixed exposure,
//! on the first adapter (lavapipe in CI).

use chrono::{DateTime, Utc};
use stratus::render::{Gpu, Preset, Settings};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::region::Region;

pub fn noon() -> DateTime<Utc> {
    DateTime::parse_from_rfc3339("2024-06-21T12:00:00Z")
        .unwrap()
        .with_timezone(&Utc)
}

/// The middle deck, its coverage at (latitude, longitude) `coverage`'s.
pub fn middle_deck(coverage: impl Fn(f64, f64) -> f64 + Sync) -> CloudMap {
    CloudMap::from_fn(
        Region {
            south: 0.0,
            north: 2.0,
            west: 0.0,
            east: 4.0,
        },
        256,
        128,
        &[(LayerKind::Middle, 3000.0, 5000.0)],
        noon(),
        |la, lo| [0.0, coverage(la, lo), 0.0],
    )
}

pub fn gpu() -> Gpu {
    Gpu::new(None).expect("a wgpu adapter (install mesa-vulkan-drivers)")
}

/// `fast` at noon, the exposure fixed (pictures compare pixel for pixel).
pub fn fast_settings() -> Settings {
    let mut s = Settings::new(Preset::Fast, noon());
    s.exposure_auto = false;
    s
}
