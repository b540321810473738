//! The genera drawn as what they are, on lavapipe: a cumulus coverage is the area under its
//! cells (render::cells), so a broken field shows the ground between its clouds.

use chrono::{DateTime, Utc};
use stratus::render::march::Variant;
use stratus::render::{Gpu, Preset, Renderer, Settings, View};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::{LayerKind, StructureGrid};
use stratus_ingest::region::Region;
use stratus_ingest::structure::{altitude_to_sample, wind_to_sample, MapStructure};
use stratus_ingest::weather::CloudType;

/// A low layer of one genus at one coverage everywhere, its columns 800–2000 m.
fn uniform(genus: CloudType, c: f64, t: DateTime<Utc>) -> CloudMap {
    let region = Region {
        south: 20.0,
        north: 30.0,
        west: 100.0,
        east: 110.0,
    };
    let (base, top) = (800.0, 2000.0);
    let mut map = CloudMap::from_fn(
        region,
        200,
        200,
        &[(LayerKind::Low, base, top)],
        t,
        |_, _| [c, 0.0, 0.0],
    );
    let g = StructureGrid::of_map(&region, 20, 20);
    let n = (g.width * g.height) as usize;
    let alt = |m: f64| {
        let s = altitude_to_sample(Some(m));
        [s, 0, 0, s]
    };
    map.structure = Some(MapStructure {
        grid: g,
        base: vec![alt(base); n],
        top: vec![alt(top); n],
        types: vec![[genus.code(), 0, 0, 0]; n],
        wind_u: vec![[wind_to_sample(8.0); 3]; n],
        wind_v: vec![[wind_to_sample(0.0); 3]; n],
    });
    map
}

/// Fraction of the top-down rays more than half opaque.
fn opaque_fraction(r: &mut Renderer, map: &CloudMap, s: &Settings) -> f64 {
    r.set_map(map);
    let out = r.render(&View::TopDown, 200, 200, s).unwrap();
    let a = out.alpha();
    a.iter().filter(|&&v| v > 0.5).count() as f64 / a.len() as f64
}

#[test]
fn a_cumulus_coverage_is_the_area_under_its_cells() {
    let t = DateTime::parse_from_rfc3339("2024-06-21T05:00:00Z")
        .unwrap()
        .with_timezone(&Utc);
    let mut r = Renderer::new(
        Gpu::new(None).unwrap(),
        &uniform(CloudType::Cumulus, 0.5, t),
    );
    let s = Settings::new(Preset::Fast, t);
    for c in [0.15, 0.4, 0.7] {
        let f = opaque_fraction(&mut r, &uniform(CloudType::Cumulus, c, t), &s);
        println!("cumulus at coverage {c}: {f:.3} of the rays opaque");
        // Scattered cumulus is drawn, and broken cumulus has clear sky between its cells.
        assert!(
            (f - c).abs() < 0.1,
            "coverage {c}: {f:.3} of the rays opaque"
        );
    }
    // A stratiform deck at the same broken coverage is a deck: nearly every ray meets it.
    let st = opaque_fraction(&mut r, &uniform(CloudType::Stratus, 0.7, t), &s);
    println!("stratus at coverage 0.7: {st:.3} of the rays opaque");
    assert!(st > 0.9, "stratus 0.7: {st:.3}");
}

#[test]
fn each_map_compiles_only_the_march_its_genera_need() {
    let t = DateTime::parse_from_rfc3339("2024-06-21T05:00:00Z")
        .unwrap()
        .with_timezone(&Utc);
    let v = |towers, cells| Variant { towers, cells };
    let stratus = uniform(CloudType::Stratus, 0.6, t);
    let mut r = Renderer::new(Gpu::new(None).unwrap(), &stratus);
    let s = Settings::new(Preset::Fast, t);
    let frame = |r: &mut Renderer, map: &CloudMap| {
        r.set_map(map);
        r.render(&View::TopDown, 32, 32, &s).unwrap();
    };
    frame(&mut r, &stratus);
    assert!(r.march_variant_compiled(v(false, false)));
    assert!(!r.march_variant_compiled(v(false, true)) && !r.march_variant_compiled(v(true, false)));
    frame(&mut r, &uniform(CloudType::Cumulus, 0.6, t));
    assert!(
        r.march_variant_compiled(v(false, true)),
        "cumulus without the cells"
    );
    assert!(!r.march_variant_compiled(v(true, false)));
    frame(&mut r, &uniform(CloudType::Cumulonimbus, 0.6, t));
    assert!(
        r.march_variant_compiled(v(true, false)),
        "cumulonimbus without the towers"
    );
    assert!(!r.march_variant_compiled(v(true, true)));
}
