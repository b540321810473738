//! The genera drawn as what they are, on lavapipe: a cumulus coverage is the area under its
//! cells (render::cells), so a broken field shows the ground between its clouds; a
//! cumulonimbus leans downwind into its anvil.

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
    column(genus, c, t, (800.0, 2000.0), 8.0)
}

/// A low layer of one genus at coverage `c` everywhere, its columns `base`–`top` m, every
/// layer's wind `east` m/s from the west.
fn column(
    genus: CloudType,
    c: f64,
    t: DateTime<Utc>,
    (base, top): (f64, f64),
    east: f64,
) -> CloudMap {
    let region = Region {
        south: 20.0,
        north: 30.0,
        west: 100.0,
        east: 110.0,
    };
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
        wind_u: vec![[wind_to_sample(east); 3]; n],
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

/// Cloud brightness along one row of a `stratus section` image (0 clear, up to 1).
fn row(img: &image::RgbaImage, y: u32) -> Vec<f64> {
    (0..img.width())
        .map(|x| img.get_pixel(x, y).0[1] as f64 / 255.0)
        .collect()
}

/// The shift (px, positive east) that best lays row `a` onto row `b`.
fn best_shift(a: &[f64], b: &[f64], most: i64) -> i64 {
    let n = a.len() as i64;
    let score = |d: i64| -> f64 {
        (most..n - most)
            .map(|x| a[x as usize] * b[(x + d) as usize])
            .sum()
    };
    (-most..=most)
        .max_by(|&p, &q| score(p).total_cmp(&score(q)))
        .unwrap_or(0)
}

#[test]
fn a_cumulonimbus_leans_downwind_into_its_anvil() {
    let t = DateTime::parse_from_rfc3339("2024-06-21T05:00:00Z")
        .unwrap()
        .with_timezone(&Utc);
    let dir = tempfile::tempdir().unwrap();
    // A section along 25°N through the towers of a uniform convective column 1-9 km, 0.5 km a
    // pixel east-west, 50 m a pixel up: the row at 3.4 km (trunks only) against the row at
    // 7 km (three quarters up, where the tower has begun to lean and the anvil not yet spread).
    let lean = |east: f64| -> i64 {
        let map = column(CloudType::Cumulonimbus, 0.9, t, (1000.0, 9000.0), east);
        let png = dir.path().join(format!("cb{east}.png"));
        map.save(&png).unwrap();
        let out = dir.path().join(format!("s{east}.png"));
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_stratus"))
            .args(["section", "--map"])
            .arg(png.with_extension("json"))
            .args([
                "--from", "25,100.5", "--to", "25,109.5", "--size", "1800x200",
            ])
            .args(["--top-m", "10000", "--preset", "fast", "--out"])
            .arg(&out)
            .env("RUST_LOG", "error")
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let img = image::open(&out).unwrap().to_rgba8();
        // Row y holds the altitude 10 000 (1 - (y + 0.5) / 200) m.
        let (low, high) = (row(&img, 131), row(&img, 59));
        assert!(
            low.iter().filter(|&&v| v > 0.5).count() > 100,
            "the section met no trunk"
        );
        let d = best_shift(&low, &high, 40);
        println!("wind {east} m/s east: the tower at 7 km stands {d} px east of it at 3.4 km");
        d
    };
    // 0.35 tower spacings at the top, 0.11 of them (4.4 km, 9 px) three quarters up.
    let windy = lean(15.0);
    assert!((5..=14).contains(&windy), "leans {windy} px in a westerly");
    let calm = lean(0.0);
    assert!(calm.abs() <= 2, "leans {calm} px in calm air");
}
