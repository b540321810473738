//! The genera drawn as what they are, on lavapipe: a cumulus coverage is the area under its
//! cells (render::cells), so a broken field shows the ground between its clouds; a
//! cumulonimbus leans downwind into its anvil.

mod common;

use chrono::{DateTime, Utc};
use stratus::render::camera::Camera;
use stratus::render::march::Variant;
use stratus::render::{Gpu, Preset, Renderer, Settings, View};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::{LayerKind, StructureGrid};
use stratus_ingest::region::Region;
use stratus_ingest::structure::{altitude_to_sample, wind_to_sample, MapStructure};
use stratus_ingest::weather::CloudType;

/// The tests' time: 05 UTC at midsummer, the Sun well up over the maps' region (100–110°E).
fn morning() -> DateTime<Utc> {
    DateTime::parse_from_rfc3339("2024-06-21T05:00:00Z")
        .unwrap()
        .with_timezone(&Utc)
}

/// A renderer holding `map` and the fast preset's settings at the tests' time.
fn fast(map: &CloudMap) -> (Renderer, Settings) {
    let r = Renderer::new(Gpu::new(None).unwrap(), map);
    (r, Settings::new(Preset::Fast, morning()))
}

/// The maps' region: 20–30°N 100–110°E (a top-down ray of a 200-pixel map is 5.6 km wide).
const WIDE: Region = Region {
    south: 20.0,
    north: 30.0,
    west: 100.0,
    east: 110.0,
};

/// A low layer of one genus at one coverage everywhere, its columns 800–2000 m.
fn uniform(genus: CloudType, c: f64, t: DateTime<Utc>) -> CloudMap {
    column_in(WIDE, genus, c, t, (800.0, 2000.0), 8.0)
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
    column_in(WIDE, genus, c, t, (base, top), east)
}

/// As [`column`], over `region`.
fn column_in(
    region: Region,
    genus: CloudType,
    c: f64,
    t: DateTime<Utc>,
    (base, top): (f64, f64),
    east: f64,
) -> CloudMap {
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

/// Fraction of the top-down rays more than half opaque, and their mean opacity.
fn opaque_fraction(r: &mut Renderer, map: &CloudMap, s: &Settings) -> (f64, f64) {
    r.set_map(map);
    let out = r.render(&View::TopDown, 200, 200, s).unwrap();
    let a = out.alpha();
    let mean = a.iter().map(|&v| v as f64).sum::<f64>() / a.len() as f64;
    (
        a.iter().filter(|&&v| v > 0.5).count() as f64 / a.len() as f64,
        mean,
    )
}

/// 25–25.5°N 105–105.5°E: a top-down ray of a 200-pixel map is 280 m wide, the cells (2 km
/// apart) are drawn one by one.
const NARROW: Region = Region {
    south: 25.0,
    north: 25.5,
    west: 105.0,
    east: 105.5,
};

#[test]
fn a_cumulus_coverage_is_the_area_under_its_cells() {
    let t = morning();
    let (mut r, s) = fast(&uniform(CloudType::Cumulus, 0.5, t));
    let near = |c: f64| column_in(NARROW, CloudType::Cumulus, c, t, (800.0, 2000.0), 8.0);
    for c in [0.15, 0.4, 0.7] {
        let (f, _) = opaque_fraction(&mut r, &near(c), &s);
        println!("cumulus at coverage {c}, rays 280 m wide: {f:.3} of the rays opaque");
        // Scattered cumulus is drawn, and broken cumulus has clear sky between its cells.
        assert!(
            (f - c).abs() < 0.1,
            "coverage {c}: {f:.3} of the rays opaque"
        );
        // Rays 5.6 km wide cover several cells: each reads the field's mean (issue 30), an
        // opacity of the coverage, not a coin toss.
        let (_, mean) = opaque_fraction(&mut r, &uniform(CloudType::Cumulus, c, t), &s);
        println!("cumulus at coverage {c}, rays 5.6 km wide: mean opacity {mean:.3}");
        assert!(
            (mean - c).abs() < 0.05,
            "coverage {c}: mean opacity {mean:.3}"
        );
    }
    // A stratiform deck at the same broken coverage is a deck: nearly every ray meets it.
    let (st, _) = opaque_fraction(&mut r, &uniform(CloudType::Stratus, 0.7, t), &s);
    println!("stratus at coverage 0.7: {st:.3} of the rays opaque");
    assert!(st > 0.9, "stratus 0.7: {st:.3}");
}

/// 10–30°N 100–120°E: a top-down ray of a 200-pixel map is 11 km wide, a 2.5° map's pixel.
const BROAD: Region = Region {
    south: 10.0,
    north: 30.0,
    west: 100.0,
    east: 120.0,
};

/// Straight down from a map pixel's width a cumulonimbus cluster is its mean (cloud.wgsl
/// `tower_fade`): as opaque as its coverage. Its towers, anvils and shield were all or nothing
/// there (about 0.75 × the coverage below 0.5, 1 above), so the score's blocks over a broken
/// Cb field followed where the towers stood (docs/footprint.md, "A draw CI made").
#[test]
fn a_cumulonimbus_seen_from_a_map_pixel_is_as_opaque_as_its_coverage() {
    let t = morning();
    let deep = |c: f64| column_in(BROAD, CloudType::Cumulonimbus, c, t, (1000.0, 9000.0), 8.0);
    let (mut r, s) = fast(&deep(0.5));
    for c in [0.3, 0.7] {
        let (_, mean) = opaque_fraction(&mut r, &deep(c), &s);
        println!("cumulonimbus at coverage {c}, rays 11 km wide: mean opacity {mean:.3}");
        assert!(
            (mean - c).abs() < 0.05,
            "coverage {c}: mean opacity {mean:.3}"
        );
    }
}

#[test]
fn each_map_compiles_only_the_march_its_genera_need() {
    let t = morning();
    let stratus = uniform(CloudType::Stratus, 0.6, t);
    let (mut r, s) = fast(&stratus);
    // The genera's code in the variants compiled after a frame of each map, in order.
    let seen = |r: &mut Renderer, map: &CloudMap| {
        r.set_map(map);
        r.render(&View::TopDown, 32, 32, &s).unwrap();
        let v = r.march_variants_compiled();
        let any = |pick: fn(Variant) -> bool| v.iter().any(|&x| pick(x));
        (v.len(), any(Variant::towers), any(Variant::cells))
    };
    assert_eq!(seen(&mut r, &stratus), (1, false, false));
    // A convective column too shallow for towers (1.2 km, under render::structure::MIN_TOWER_M)
    // is drawn as cumulus: the cells' variant, not the towers'.
    assert_eq!(
        seen(&mut r, &uniform(CloudType::Cumulonimbus, 0.6, t)),
        (2, false, true)
    );
    // Cumulus compiles the same variant: nothing more.
    assert_eq!(
        seen(&mut r, &uniform(CloudType::Cumulus, 0.6, t)),
        (2, false, true)
    );
    // A deep cumulonimbus the towers', alone (not with the cells).
    let deep = column(CloudType::Cumulonimbus, 0.6, t, (1000.0, 9000.0), 8.0);
    assert_eq!(seen(&mut r, &deep), (3, true, true));
    assert!(r
        .march_variants_compiled()
        .iter()
        .all(|v| !(v.towers() && v.cells())));
    // A second frame of a map compiles nothing more.
    assert_eq!(seen(&mut r, &stratus).0, 3);
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
    let t = morning();
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

/// The median extinction (1/m) of the cloudy points of a map's section along 25°N, 100.5–109.5°E
/// (1 000 columns), in the rows between `lo` and `hi` m.
fn cloudy_median(r: &mut Renderer, map: &CloudMap, s: &Settings, (lo, hi): (f64, f64)) -> f64 {
    r.set_map(map);
    let lat = 25f64.to_radians();
    let columns: Vec<glam::DVec3> = (0..1000)
        .map(|i| {
            let lon = (100.5 + 9.0 * (i as f64 + 0.5) / 1000.0).to_radians();
            glam::DVec3::new(lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin())
        })
        .collect();
    let (height, top) = (200u32, 10_000.0);
    let sigma = r.section(&columns, height, top as f32, s).unwrap();
    let mut cloudy: Vec<f64> = (0..height)
        .filter(|&y| {
            let h = top * (1.0 - (y as f64 + 0.5) / height as f64);
            (lo..=hi).contains(&h)
        })
        .flat_map(|y| sigma[(y * 1000) as usize..((y + 1) * 1000) as usize].to_vec())
        .filter(|&v| v > 0.0)
        .map(f64::from)
        .collect();
    assert!(cloudy.len() > 1000, "{} cloudy points", cloudy.len());
    cloudy.sort_by(f64::total_cmp);
    cloudy[cloudy.len() / 2]
}

#[test]
fn a_cumulonimbus_trunk_is_denser_than_a_cumulus_not_a_veil() {
    let t = morning();
    let cu = uniform(CloudType::Cumulus, 0.7, t);
    let (mut r, s) = fast(&cu);
    // Inside a cumulus cell, and inside the trunks of an 8 km deep convective column under
    // where the trunks lean and the anvils spread. A cumulonimbus holds more water than a
    // cumulus (1-3 against 0.3-1 g/m3); normalised to its column as a deck is (2 km / 8 km), a
    // trunk would be a sixth as dense as it is: a translucent veil seen from the side.
    let cell = cloudy_median(&mut r, &cu, &s, (900.0, 1900.0));
    let cb = column(CloudType::Cumulonimbus, 0.9, t, (1000.0, 9000.0), 0.0);
    let trunk = cloudy_median(&mut r, &cb, &s, (2000.0, 5000.0));
    let deck = column(CloudType::Stratus, 0.9, t, (1000.0, 9000.0), 0.0);
    let stratus = cloudy_median(&mut r, &deck, &s, (2000.0, 5000.0));
    println!(
        "median extinction: cumulus cell {cell:.4}, trunk {trunk:.4}, 8 km stratus {stratus:.4} /m"
    );
    assert!(
        trunk > cell && trunk < 4.0 * cell,
        "trunk {trunk} against a cumulus cell's {cell}"
    );
    assert!(trunk > 3.0 * stratus, "trunk {trunk}, deck {stratus}");
}

/// A high layer of cirrus at coverage `c` everywhere over 40–50°N 5°W–5°E (the tile's worst
/// place: at 0° of longitude the east is one of the noise tile's own axes), columns 7–8 km,
/// a 30 m/s westerly.
fn cirrus_sheet(c: f64, t: DateTime<Utc>) -> CloudMap {
    let region = Region {
        south: 40.0,
        north: 50.0,
        west: -5.0,
        east: 5.0,
    };
    let mut map = CloudMap::from_fn(
        region,
        200,
        200,
        &[(LayerKind::High, 7000.0, 8000.0)],
        t,
        |_, _| [0.0, 0.0, c],
    );
    let g = StructureGrid::of_map(&region, 20, 20);
    let n = (g.width * g.height) as usize;
    let alt = |m: f64| {
        let s = altitude_to_sample(Some(m));
        [0, 0, s, s]
    };
    map.structure = Some(MapStructure {
        grid: g,
        base: vec![alt(7000.0); n],
        top: vec![alt(8000.0); n],
        types: vec![[0, 0, CloudType::Cirrus.code(), 0]; n],
        wind_u: vec![[wind_to_sample(30.0); 3]; n],
        wind_v: vec![[wind_to_sample(0.0); 3]; n],
    });
    map
}

/// The power spectrum of an image's columns (each with its mean taken off, under a Hann
/// window), averaged over the columns: index k is k cycles over the height.
fn column_spectrum(a: &[f32], w: usize, h: usize) -> Vec<f64> {
    let mut s = vec![0.0; h / 2];
    for x in 0..w {
        let col: Vec<f64> = (0..h).map(|y| a[y * w + x] as f64).collect();
        let mean = col.iter().sum::<f64>() / h as f64;
        let win: Vec<f64> = col
            .iter()
            .enumerate()
            .map(|(y, v)| {
                let hann = 0.5 - 0.5 * (std::f64::consts::TAU * y as f64 / h as f64).cos();
                (v - mean) * hann
            })
            .collect();
        for (k, sk) in s.iter_mut().enumerate() {
            let (mut re, mut im) = (0.0, 0.0);
            for (y, v) in win.iter().enumerate() {
                let ph = std::f64::consts::TAU * (k * y) as f64 / h as f64;
                re += v * ph.cos();
                im -= v * ph.sin();
            }
            *sk += (re * re + im * im) / w as f64;
        }
    }
    s
}

/// The cirrus streaks are not a washboard (issue 30): straight down from 80 km on a uniform
/// sheet of cirrus streaked by a westerly, the picture's luminance across the streaks (down its
/// columns) has no single period standing out of its spectrum. Before the period was broken
/// the strongest, 5 cycles over the height with its harmonics, was 16.9× the band's median
/// power; now 3.3× (docs/footprint.md, "Breaking the cirrus period", which renders this map
/// with `stratus render` before and after). The sheet's mean luminance is unchanged (0.810).
#[test]
fn cirrus_streaks_have_no_single_period() {
    let t = morning();
    let map = cirrus_sheet(0.6, t);
    // The map, for `stratus render` with another build (docs/footprint.md's before and after).
    if let Ok(p) = std::env::var("STRATUS_STREAKS_MAP") {
        map.save(std::path::Path::new(&p)).unwrap();
    }
    let (mut r, mut s) = fast(&map);
    s.time = DateTime::parse_from_rfc3339("2024-06-21T12:00:00Z")
        .unwrap()
        .with_timezone(&Utc);
    let (w, h) = (128usize, 192usize);
    let view = View::Perspective(stratus::render::Camera::new(
        45.0, 0.0, 80_000.0, 0.0, -90.0,
    ));
    let o = r.render(&view, w as u32, h as u32, &s).unwrap();
    if let Ok(p) = std::env::var("STRATUS_STREAKS_PNG") {
        o.to_image().save(p).unwrap();
    }
    let mean = o.alpha().iter().map(|&v| v as f64).sum::<f64>() / (w * h) as f64;
    // Rec. 709 luminance of the picture's sRGB values, 0..1.
    let lum: Vec<f32> = o
        .pixels
        .chunks_exact(4)
        .map(|p| (0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32) / 255.0)
        .collect();
    let spec = column_spectrum(&lum, w, h);
    // Wavelengths from a third of the height (64 px, 32 km) down to 4 px.
    let band = &spec[3..h / 4];
    let mut sorted = band.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let (k, peak) = band
        .iter()
        .enumerate()
        .map(|(i, &p)| (i + 3, p))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    let ratio = peak / median;
    println!(
        "cirrus 0.6 from 80 km: mean opacity {mean:.3}; strongest period {:.1} px ({k} cycles), {ratio:.1}× the band's median power",
        h as f64 / k as f64
    );
    assert!(mean > 0.2, "the sheet is drawn: mean opacity {mean:.3}");
    assert!(
        ratio < 8.0,
        "a single period stands out: {ratio:.1}× at {k} cycles"
    );
}

/// A cumulus field seen from far off and at a slant is drawn as its mean, a slab whose optical
/// depth straight down is −ln(1 − c) (cloud.wgsl `cumulus_slab`), so each ray's opacity is
/// 1 − (1 − c)^(1/sin e), e its elevation where it meets the field. The far march's steps
/// (1.5 km here: a map with high cloud has shells 16 km deep, a segment's step is its length
/// over 16) are longer than the slab is thick (0.6 km at coverage 0.15), and the clear-air
/// stride's 4–6 km hopped it. Measured on the middle patch at c = 0.15 against its model 0.261:
/// 0.000 when one point of the slab's profile stood for a step, 0.097 with the slab averaged
/// over the step, 0.261 with the stride bounded in altitude (march.wgsl `stride_mult`).
#[test]
fn a_far_cumulus_field_at_a_slant_is_not_lost_between_the_steps() {
    let t = morning();
    let s = Settings::new(Preset::Balanced, t);
    // 120 km up at the region's south edge, 35° down toward its middle: the centre rays meet
    // the field about 210 km away, where the cells have faded into the slab.
    let mut cam = stratus::render::Camera::new(21.0, 105.0, 120_000.0, 0.0, -35.0);
    cam.fov_deg = 60.0;
    let (w, h) = (160u32, 90u32);
    let patch = || {
        ((h * 7 / 16)..(h * 9 / 16))
            .flat_map(move |y| ((w * 3 / 8)..(w * 5 / 8)).map(move |x| (x, y)))
    };
    // Each patch ray's elevation where it meets the slab (about 1.1 km up): the Earth's
    // curvature makes it shallower than the camera's pitch (33.4° at the centre, not 35°).
    let b = cam.basis();
    let sines: Vec<f64> = patch()
        .map(|(x, y)| {
            let d = cam.pixel_ray(f64::from(x) + 0.5, f64::from(y) + 0.5, w, h);
            let r = stratus::render::camera::EARTH_R + 1100.0;
            let (pb, pc) = (b.position.dot(d), b.position.length_squared() - r * r);
            let p = b.position + d * (-pb - (pb * pb - pc).sqrt());
            -p.normalize().dot(d)
        })
        .collect();
    for c in [0.15, 0.4] {
        let mut map = CloudMap::from_fn(
            WIDE,
            200,
            200,
            &[
                (LayerKind::Low, 800.0, 2000.0),
                (LayerKind::High, 12000.0, 16000.0),
            ],
            t,
            |_, _| [c, 0.0, 0.0],
        );
        map.structure = column(CloudType::Cumulus, c, t, (800.0, 2000.0), 8.0).structure;
        let mut r = Renderer::new(Gpu::new(None).unwrap(), &map);
        let out = r.render(&View::Perspective(cam), w, h, &s).unwrap();
        let a = out.alpha();
        let n = sines.len() as f64;
        let mean = patch()
            .map(|(x, y)| f64::from(a[(y * w + x) as usize]))
            .sum::<f64>()
            / n;
        let model = sines
            .iter()
            .map(|e| 1.0 - (1.0 - c).powf(1.0 / e))
            .sum::<f64>()
            / n;
        println!(
            "cumulus {c} seen at 35° from 120 km: mean opacity {mean:.3}, its slab {model:.3}"
        );
        assert!(
            (mean - model).abs() <= 0.1 * model,
            "coverage {c}: mean opacity {mean:.3}, the slab's {model:.3}"
        );
    }
}

/// The East Asia sample at 325×275, all layers: cumulus over the Arabian Sea and the Bay of
/// Bengal, cumulonimbus south of Sri Lanka, cirrus over Tibet.
/// A renderer over it, and the fast preset at 06 UTC on 2011-01-15 (the map's valid time less
/// half an hour) with a fixed exposure: an adapted one follows the frames before it.
fn east_asia(dir: &std::path::Path) -> (Renderer, Settings) {
    let path = common::real_map(dir, "ea", "0,55,39,105", "325x275");
    let map = CloudMap::load(&path).unwrap();
    let time = DateTime::parse_from_rfc3339("2011-01-15T06:00:00Z")
        .unwrap()
        .with_timezone(&Utc);
    let mut s = Settings::new(Preset::Fast, time);
    s.exposure_auto = false;
    (Renderer::new(Gpu::new(None).unwrap(), &map), s)
}

/// A view that no cumulus or cumulonimbus column can reach marches without their code, and
/// draws what the map's variant draws, to the byte. The cameras: north over Tibet and the
/// cruise view west of it (the nearest cells 1 700 km off), then a turn in 36 headings
/// north of the Arabian Sea's cumulus, whose field enters and leaves the frame at its edges.
#[test]
fn a_view_compiles_only_the_genera_within_its_reach() {
    let dir = tempfile::tempdir().unwrap();
    let (mut r, on) = east_asia(dir.path());
    let mut off = on.clone();
    off.march.shortcuts.feature_reach = false;
    let far = [
        Camera::new(30.5, 86.0, 6000.0, 0.0, 8.0),
        Camera::new(35.0, 74.0, 12000.0, 60.0, -15.0),
    ];
    let turn = (0..36).map(|k| Camera::new(18.0, 62.0, 3000.0, 10.0 * k as f64, -5.0));
    let mut cells = Vec::new();
    for cam in far.into_iter().chain(turn) {
        let view = View::Perspective(cam);
        let near = r.render(&view, 120, 68, &on).unwrap();
        let narrowed = r.last_march_variant().unwrap();
        let all = r.render(&view, 120, 68, &off).unwrap();
        let whole = r.last_march_variant().unwrap();
        assert!(whole.cells() && whole.towers(), "{whole:?}");
        assert!(!narrowed.towers(), "{cam:?}: {narrowed:?}");
        assert!(near.pixels == all.pixels, "{cam:?}: the pictures differ");
        assert!(near.cloud == all.cloud, "{cam:?}: the cloud differs");
        cells.push(narrowed.cells());
    }
    assert_eq!(&cells[..2], [false, false]);
    // The turn sees the cells' field, and turns away from it.
    assert!(
        cells[2..].contains(&true) && cells[2..].contains(&false),
        "{cells:?}"
    );
}

/// In real time (the window, a host engine) a frame does not wait for the narrower march to
/// compile: it draws with the map's variant, the same picture, until a thread has compiled the
/// narrower one, which later frames take.
#[test]
fn a_realtime_frame_does_not_wait_for_a_narrower_march() {
    let dir = tempfile::tempdir().unwrap();
    let (mut r, s) = east_asia(dir.path());
    r.set_realtime(true);
    let view = View::Perspective(Camera::new(30.5, 86.0, 6000.0, 0.0, 8.0));
    let first = r.render(&view, 120, 68, &s).unwrap();
    assert!(r.last_march_variant().is_some_and(|v| v.cells()));
    let start = std::time::Instant::now();
    let later = loop {
        let out = r.render(&view, 120, 68, &s).unwrap();
        if r.last_march_variant().is_some_and(|v| !v.cells()) {
            break out;
        }
        assert!(
            start.elapsed().as_secs() < 600,
            "the narrower march was not compiled in 10 minutes"
        );
        std::thread::sleep(std::time::Duration::from_millis(200));
    };
    assert!(first.pixels == later.pixels, "the pictures differ");
}
