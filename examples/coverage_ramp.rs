//! Top-down opacity against map coverage: a map whose coverage rises 0 → 1 from west to east is
//! rendered straight down at each preset, and the mean opacity per coverage bin is printed.
//! The coverage where opacity crosses 0.5 is the map threshold `stratus score` uses (docs/score.md).
//!
//! `cargo run --release --example coverage_ramp`

use chrono::{DateTime, Utc};
use stratus::render::{Gpu, Preset, Renderer, Settings, View};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::region::Region;

fn main() -> anyhow::Result<()> {
    let region = Region {
        south: 20.0,
        north: 30.0,
        west: 100.0,
        east: 110.0,
    };
    let t: DateTime<Utc> =
        DateTime::parse_from_rfc3339("2024-06-21T12:00:00Z")?.with_timezone(&Utc);
    let (w, h) = (400u32, 200u32);
    let bins = 20usize;
    for (kind, base, top) in [
        (LayerKind::Low, 500.0, 2500.0),
        (LayerKind::Middle, 3500.0, 6000.0),
        (LayerKind::High, 7000.0, 10000.0),
    ] {
        let map = CloudMap::from_fn(region, w, h, &[(kind, base, top)], t, |_, lon| {
            let c = (lon - 100.0) / 10.0;
            [c, c, c]
        });
        let mut r = Renderer::new(Gpu::new(None)?, &map);
        for p in [Preset::Fast, Preset::Balanced, Preset::High] {
            let out = r.render(&View::TopDown, w, h, &Settings::new(p, t))?;
            let mut sum = vec![0.0f64; bins];
            let mut n = vec![0usize; bins];
            for (k, c) in out.cloud.iter().enumerate() {
                let x = k % w as usize;
                let b = x * bins / w as usize;
                sum[b] += c[3] as f64;
                n[b] += 1;
            }
            let row: Vec<String> = (0..bins)
                .map(|b| format!("{:.2}", sum[b] / n[b] as f64))
                .collect();
            let cross = (0..bins).find(|&b| sum[b] / n[b] as f64 >= 0.5);
            println!(
                "{:6} {:9} crosses 0.5 at coverage {}  [{}]",
                kind.name(),
                p.name(),
                cross.map_or("never".into(), |b| format!(
                    "{:.3}",
                    (b as f64 + 0.5) / bins as f64
                )),
                row.join(" ")
            );
        }
    }
    Ok(())
}
