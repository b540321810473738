//! Top-down opacity against map coverage: a map whose coverage rises 0 → 1 from west to east is
//! rendered straight down at each preset, and the coverage where the mean opacity crosses 0.5
//! is printed — per layer for a map of bands (the paper's profile), and per cloud genus for a
//! map with structure images (DESIGN §7 profiles). That crossing is what the score's map
//! threshold stands for (docs/score.md).
//!
//! `--span DEG` makes the region DEG degrees a side (default 10: a ray 5.6 km wide north to
//! south; 20 gives 11 km, a 2.5° map's pixel as the score sees it).
//!
//! `cargo run --release --example coverage_ramp [-- --genera-only] [--span DEG] [GENUS…]`

use chrono::{DateTime, Utc};
use stratus::render::{Gpu, Preset, Renderer, Settings, View};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::{LayerKind, StructureGrid};
use stratus_ingest::region::Region;
use stratus_ingest::structure::{altitude_to_sample, wind_to_sample, MapStructure};
use stratus_ingest::weather::CloudType;

const BINS: usize = 20;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let genera_only = args.iter().any(|a| a == "--genera-only");
    // Any other argument names the genera to measure (all when none is named).
    let span_at = args.iter().position(|a| a == "--span");
    let span: f64 = match span_at {
        Some(i) => args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .filter(|v| (1.0..=60.0).contains(v))
            .ok_or_else(|| anyhow::anyhow!("--span wants degrees, 1 to 60"))?,
        None => 10.0,
    };
    let named: Vec<&String> = args
        .iter()
        .enumerate()
        .filter(|&(i, a)| !a.starts_with("--") && span_at.is_none_or(|s| i != s + 1))
        .map(|(_, a)| a)
        .collect();
    let region = Region {
        south: 20.0,
        north: 20.0 + span,
        west: 100.0,
        east: 100.0 + span,
    };
    let t: DateTime<Utc> =
        DateTime::parse_from_rfc3339("2024-06-21T12:00:00Z")?.with_timezone(&Utc);
    let (w, h) = (400u32, 200u32);
    let bands = [
        (LayerKind::Low, 500.0, 2500.0),
        (LayerKind::Middle, 3500.0, 6000.0),
        (LayerKind::High, 7000.0, 10000.0),
    ];
    let ramp = |kind: LayerKind, base, top| {
        CloudMap::from_fn(region, w, h, &[(kind, base, top)], t, |_, lon| {
            let c = (lon - 100.0) / span;
            [c, c, c]
        })
    };
    let mut r = Renderer::new(Gpu::new(None)?, &ramp(LayerKind::Low, 500.0, 2500.0));
    if !genera_only {
        for (kind, base, top) in bands {
            r.set_map(&ramp(kind, base, top));
            report(&mut r, (w, h), t, kind.name())?;
        }
    }
    for genus in CloudType::ALL {
        if !named.is_empty() && !named.iter().any(|n| *n == genus.name()) {
            continue;
        }
        // Each genus in the layer the rule puts it in, over that layer's band.
        let (kind, base, top) = match genus {
            CloudType::Cirrus | CloudType::Cirrocumulus | CloudType::Cirrostratus => bands[2],
            CloudType::Altocumulus | CloudType::Altostratus | CloudType::Nimbostratus => bands[1],
            CloudType::Cumulonimbus => (LayerKind::Low, 500.0, 10000.0),
            _ => bands[0],
        };
        let mut map = ramp(kind, base, top);
        let g = StructureGrid::of_map(&region, 20, 10);
        let n = (g.width * g.height) as usize;
        let c = kind.channel();
        let alt = |m: f64| {
            let mut v = [0u16; 4];
            v[c] = altitude_to_sample(Some(m));
            v[3] = v[c];
            v
        };
        let mut code = [0u8; 4];
        code[c] = genus.code();
        map.structure = Some(MapStructure {
            grid: g,
            base: vec![alt(base); n],
            top: vec![alt(top); n],
            types: vec![code; n],
            wind_u: vec![[wind_to_sample(20.0); 3]; n],
            wind_v: vec![[wind_to_sample(0.0); 3]; n],
        });
        r.set_map(&map);
        report(&mut r, (w, h), t, genus.name())?;
    }
    Ok(())
}

/// Render the ramp straight down at each preset and print where opacity crosses 0.5.
fn report(
    r: &mut Renderer,
    (w, h): (u32, u32),
    t: DateTime<Utc>,
    what: &str,
) -> anyhow::Result<()> {
    for p in [Preset::Fast, Preset::Balanced, Preset::High] {
        let out = r.render(&View::TopDown, w, h, &Settings::new(p, t))?;
        let mut sum = [0.0f64; BINS];
        let mut n = [0usize; BINS];
        for (k, c) in out.cloud.iter().enumerate() {
            let b = (k % w as usize) * BINS / w as usize;
            sum[b] += c[3] as f64;
            n[b] += 1;
        }
        let mean: Vec<f64> = (0..BINS).map(|b| sum[b] / n[b].max(1) as f64).collect();
        let cross = mean.iter().position(|&m| m >= 0.5);
        println!(
            "{what:13} {:9} crosses 0.5 at coverage {}  [{}]",
            p.name(),
            cross.map_or("never".into(), |b| format!(
                "{:.3}",
                (b as f64 + 0.5) / BINS as f64
            )),
            mean.iter()
                .map(|m| format!("{m:.2}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    Ok(())
}
