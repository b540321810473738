//! Issue 14, the ground from the forecast, through the binary on the real GFS sample: the
//! terrain `probe` reports is the file's orography (decoded here independently and
//! interpolated as docs/ingest.md says), the sea is at sea level, the column's cloud water is
//! the file's, cameras cannot go below the terrain but can stand on it, flight paths under it
//! are lifted, a series' steps each get their ground, and a broken ground image is one line
//! with exit code 2 and nothing written.

mod common;
use common::{real_map, sample, stratus, synthetic_map};

use std::path::{Path, PathBuf};
use std::process::Output;

use stratus_ingest::grib::{self, SurfaceType};
use stratus_ingest::spline::{Interp, Tap, WRAP_PAD};

fn gfs() -> PathBuf {
    sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2")
}

/// Tibet and India (20–45°N, 70–105°E), big enough for 7 lattice texels per grid cell.
const TIBET: &str = "20,45,70,105";
/// The North Atlantic (30–65°N, 50°W–0°).
const ATLANTIC: &str = "30,65,-50,0";

fn probe(map: &Path, at: &str) -> serde_json::Value {
    common::probe_json(map, at)
}

fn num(v: &serde_json::Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} in {v}"))
}

/// A field of the sample on its grid, decoded here: (grid, values north first).
fn decoded(param: (u8, u8, u8), levels: &[SurfaceType]) -> grib::Field {
    let bytes = std::fs::read(gfs()).unwrap();
    let msgs = grib::scan(&bytes).unwrap();
    let m = msgs
        .iter()
        .find(|m| m.parameter() == param && m.level_type.is_some_and(|l| levels.contains(&l)))
        .unwrap_or_else(|| panic!("{param:?} not in the sample"));
    grib::decode_values(&bytes, m).unwrap()
}

/// The field at (lat, lon) by the not-a-knot spline over the whole global grid (north–south
/// along every column, then west–east through those values, padded across the seam), as the
/// coverage and the ground are interpolated.
fn spline_at(f: &grib::Field, lat: f64, lon: f64) -> f64 {
    let g = &f.grid;
    let (ni, nj) = (g.ni, g.nj);
    let row = Tap::at(Interp::Spline, (g.north() - lat) / g.dj, nj);
    let n_pad = ni + 2 * WRAP_PAD;
    let mut line = vec![0.0; n_pad];
    let (mut col, mut cs) = (vec![0.0; nj], vec![0.0; nj]);
    for (k, x) in line.iter_mut().enumerate() {
        let c = (k as isize - WRAP_PAD as isize).rem_euclid(ni as isize) as usize;
        for (j, v) in col.iter_mut().enumerate() {
            *v = f.at(c, j);
        }
        Interp::Spline.slopes(&col, &mut cs);
        *x = row.eval(&col, &cs);
    }
    let mut s = vec![0.0; n_pad];
    Interp::Spline.slopes(&line, &mut s);
    let u = (lon - g.west()).rem_euclid(360.0) / g.di + WRAP_PAD as f64;
    Tap::at(Interp::Spline, u, n_pad).eval(&line, &s)
}

#[test]
fn the_ground_over_tibet_is_the_files_orography() {
    let dir = tempfile::tempdir().unwrap();
    let map = real_map(dir.path(), "tibet", TIBET, "700x500");
    let p = probe(&map, "33,85");
    let ground = num(&p, "ground_m");
    assert_eq!(p["ground_source"], "orography", "{p}");
    let orog = decoded((0, 3, 5), &[SurfaceType::Surface]);
    let want = spline_at(&orog, 33.0, 85.0);
    println!("33°N 85°E: probe {ground:.1} m, the file's orography by spline {want:.1} m");
    assert!(
        (ground - want).abs() <= 50.0,
        "probe {ground} m, the file's orography by spline {want} m"
    );
    assert!((4000.0..=5500.0).contains(&ground), "{ground}");
    // The grid point itself (32.5°N 85°E, a lattice texel centre) to the 0.5 m encoding step.
    let node = orog.at((85.0 / 2.5) as usize, ((90.0 - 32.5) / 2.5) as usize);
    let at_node = num(&probe(&map, "32.5,85"), "ground_m");
    assert!((at_node - node).abs() <= 0.5, "{at_node} vs {node}");
    assert!(num(&p, "land") > 0.99, "{p}");
    let fields = p["ground_fields"].as_array().unwrap();
    assert_eq!(fields.len(), 6, "the sample has every ground field: {p}");
    // The text output says it too.
    let o = stratus(&["probe", "--map", map.to_str().unwrap(), "--at", "33,85"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains(&format!("ground  {} m (orography)", ground.round())),
        "{text}"
    );
}

#[test]
fn the_sea_is_at_sea_level_and_cloud_water_is_the_files() {
    let dir = tempfile::tempdir().unwrap();
    let map = real_map(dir.path(), "atl", ATLANTIC, "500x350");
    let p = probe(&map, "45,-30");
    assert!(num(&p, "ground_m").abs() < 1.0, "{p}");
    assert!(num(&p, "land") < 0.01, "{p}");
    // 52.5°N 25°W is a grid point: the probe gives the file's cwat there (DESIGN §8: 0.86).
    let p = probe(&map, "52.5,-25");
    let cwat = num(&p, "cwat_kg_m2");
    let field = decoded(
        (0, 6, 6),
        &[
            SurfaceType::EntireAtmosphere,
            SurfaceType::EntireAtmosphereNcep,
        ],
    );
    let node = field.at((335.0 / 2.5) as usize, ((90.0 - 52.5) / 2.5) as usize);
    assert!((cwat - node).abs() < 0.002, "{cwat} vs the file's {node}");
    assert!((cwat - 0.86).abs() < 0.01, "{cwat}");
    // Nowhere over the map is the sea below sea level, and no texel leaves the range of the
    // file's grid points around the region (a spline alone rings past both).
    let m = stratus_ingest::CloudMap::load(&map).unwrap();
    let g = m.ground().unwrap();
    let (lo, hi) = orog_range_over(30.0, 65.0, 310.0, 360.0);
    let mut sea = 0;
    for (k, (&h, &land)) in g.height_m.iter().zip(&g.land).enumerate() {
        assert!(
            (lo as f32 - 0.5..=hi as f32 + 0.5).contains(&h),
            "texel {k}: {h} m outside the grid's {lo}..{hi} m"
        );
        if land < 0.5 {
            sea += 1;
            assert!(h >= 0.0, "texel {k}: sea at {h} m");
        }
    }
    assert!(sea > g.height_m.len() / 2, "{sea} sea texels");
    assert!(
        lo < -1.0,
        "the file's coasts dip below 0 m ({lo}), so the sea check bites"
    );
}

/// The lowest and highest orography grid points in a box (lon 0..360, one grid cell around).
fn orog_range_over(south: f64, north: f64, west: f64, east: f64) -> (f64, f64) {
    let f = decoded((0, 3, 5), &[SurfaceType::Surface]);
    let mut m = (f64::MAX, f64::MIN);
    for j in 0..f.grid.nj {
        let lat = 90.0 - 2.5 * j as f64;
        for i in 0..f.grid.ni {
            let lon = 2.5 * i as f64;
            let lon_in = if east >= 360.0 {
                lon >= west - 2.5 || lon <= east - 360.0 + 2.5
            } else {
                lon >= west - 2.5 && lon <= east + 2.5
            };
            if (south - 2.5..=north + 2.5).contains(&lat) && lon_in {
                m = (m.0.min(f.at(i, j)), m.1.max(f.at(i, j)));
            }
        }
    }
    m
}

fn render(map: &Path, camera: &str, out: &Path) -> Output {
    stratus(&[
        "render",
        "--map",
        map.to_str().unwrap(),
        "--camera",
        camera,
        "--pitch",
        "5",
        "--size",
        "48x27",
        "--preset",
        "fast",
        "--out",
        out.to_str().unwrap(),
    ])
}

/// One `error:` line, exit 2, no output, no panic.
fn refused(o: &Output, needles: &[&str], out: &Path) {
    let err = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.contains("XDG_RUNTIME_DIR"))
        .collect();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(lines.len(), 1, "{err}");
    for n in needles {
        assert!(lines[0].contains(n), "wanted {n:?} in: {err}");
    }
    assert!(!out.exists(), "nothing may be written on error");
}

#[test]
fn cameras_cannot_go_below_the_terrain_but_can_stand_on_it() {
    let dir = tempfile::tempdir().unwrap();
    let map = real_map(dir.path(), "tibet", TIBET, "350x250");
    let ground = num(&probe(&map, "33,85"), "ground_m");
    let out = dir.path().join("f.png");
    refused(
        &render(&map, "33,85,1000", &out),
        &[
            "below the ground",
            "at 1000 m",
            &format!("which is at {ground:.0} m (the map's terrain"),
            "ground+N",
        ],
        &out,
    );
    refused(&render(&map, "33,85,ground-5", &out), &["--camera"], &out);
    let o = render(&map, "33,85,ground+2", &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(image::open(&out).is_ok());
    // Without a ground grid (the synthetic sample has no orography) the ground is sea level.
    let syn_dir = dir.path().join("syn");
    std::fs::create_dir(&syn_dir).unwrap();
    let syn = synthetic_map(&syn_dir);
    let p = probe(&syn, "45,-20");
    assert_eq!(
        (num(&p, "ground_m"), &p["ground_source"]),
        (0.0, &"none".into())
    );
    assert!(p["cwat_kg_m2"].is_null(), "{p}");
    let out2 = dir.path().join("g.png");
    let o = render(&syn, "45,-20,ground", &out2);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_flight_under_the_terrain_is_lifted_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let map = real_map(dir.path(), "tibet", TIBET, "350x250");
    let path = dir.path().join("p.json");
    std::fs::write(
        &path,
        r#"{"keys": [{"t": 0, "lat": 33, "lon": 84, "alt_m": 9000, "heading": 90, "pitch": -5},
                     {"t": 1, "lat": 33, "lon": 85, "alt_m": 1000, "heading": 90, "pitch": -5}]}"#,
    )
    .unwrap();
    let frames = dir.path().join("frames");
    let o = stratus(&[
        "flight",
        "--map",
        map.to_str().unwrap(),
        "--path",
        path.to_str().unwrap(),
        "--out",
        frames.to_str().unwrap(),
        "--size",
        "32x18",
        "--fps",
        "1",
        "--preset",
        "fast",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(frames.join("frame-00001.png").is_file());
    assert!(
        err.contains("warning: 1 of 2 frames were below the terrain")
            && err.contains("frame 1 at 33.000,85.000, 1000 m under ground"),
        "{err}"
    );
}

#[test]
fn every_series_step_gets_its_ground() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.png");
    let f0 = sample("gfs-series/gfs.t18z.pgrb2.2p50.f000");
    let f6 = sample("gfs-series/gfs.t18z.pgrb2.2p50.f006");
    let o = stratus(&[
        "ingest",
        f0.to_str().unwrap(),
        f6.to_str().unwrap(),
        "--region",
        ATLANTIC,
        "--size",
        "200x140",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (step, albedo) in [("s-f000", false), ("s-f006", true)] {
        let text = std::fs::read_to_string(dir.path().join(format!("{step}.json"))).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let fields: Vec<&str> = v["ground"]["fields"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|f| f.as_str())
            .collect();
        assert!(fields.contains(&"orography"), "{step}: {fields:?}");
        // The analysis has no albedo: the default stands in, and the sidecar says so.
        assert_eq!(fields.contains(&"albedo"), albedo, "{step}: {fields:?}");
        assert!(dir.path().join(format!("{step}.ground.png")).is_file());
    }
    // Between the steps the ground is there too; over the sea at sea level.
    let series = dir.path().join("s.json");
    let o = stratus(&[
        "probe",
        "--map",
        series.to_str().unwrap(),
        "--at",
        "45,-30",
        "--time",
        "2015-09-12T21:00:00Z",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let p: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(p["ground_source"], "orography", "{p}");
    assert!(num(&p, "ground_m").abs() < 1.0, "{p}");
}

/// Rewrite the PNG at `path` with `f` applied to its samples (and a new size), keeping its id.
fn tamper(path: &Path, size: Option<(u32, u32)>, f: impl Fn(&mut [u8])) {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = dec.read_info().unwrap();
    let id = r.info().uncompressed_latin1_text[0].text.clone();
    let (ct, bd) = (r.info().color_type, r.info().bit_depth);
    let mut buf = vec![0u8; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    let (w, h) = size.unwrap_or((info.width, info.height));
    buf.resize(w as usize * h as usize * ct.samples() * 2, 0);
    f(&mut buf);
    let mut enc = png::Encoder::new(std::fs::File::create(path).unwrap(), w, h);
    enc.set_color(ct);
    enc.set_depth(bd);
    enc.add_text_chunk("stratus-image-id".into(), id).unwrap();
    let mut wr = enc.write_header().unwrap();
    wr.write_image_data(&buf).unwrap();
    wr.finish().unwrap();
}

#[test]
fn a_bad_ground_image_is_one_line_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fresh = || real_map(d, "m", ATLANTIC, "120x84");
    let out = d.join("f.png");
    let check = |needles: &[&str]| {
        let map = d.join("m.json");
        refused(&render(&map, "45,-30,3000", &out), needles, &out);
        let o = stratus(&["probe", "--map", map.to_str().unwrap(), "--at", "45,-30"]);
        assert_eq!(o.status.code(), Some(2));
        assert!(o.stdout.is_empty(), "probe printed nothing");
    };
    let map = fresh();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&map).unwrap()).unwrap();
    let (w, h) = (
        v["ground"]["grid"]["width"].as_u64().unwrap(),
        v["ground"]["grid"]["height"].as_u64().unwrap(),
    );
    // Missing.
    std::fs::remove_file(d.join("m.ground.png")).unwrap();
    check(&["m.ground.png", "cannot read"]);
    // Wrong size, same image id: refused before any pixel is decoded.
    fresh();
    tamper(&d.join("m.ground-water.png"), Some((3, 2)), |_| {});
    check(&[
        "m.ground-water.png",
        &format!("PNG is 3x2 but its sidecar says {w}x{h}"),
    ]);
    // A texel without a terrain height.
    fresh();
    tamper(&d.join("m.ground.png"), None, |b| {
        b[8 * 5] = 0;
        b[8 * 5 + 1] = 0;
    });
    check(&["m.ground.png", "pixel (5, 0): no terrain height"]);
    // Not a PNG at all.
    fresh();
    std::fs::write(d.join("m.ground.png"), b"not a png").unwrap();
    check(&["m.ground.png", "not a PNG"]);
    // A sidecar whose ground grid does not cover the region.
    fresh();
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&map).unwrap()).unwrap();
    v["ground"]["grid"]["west"] = (-45.0).into();
    std::fs::write(&map, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    check(&["m.json", "ground.grid", "do not cover the region"]);
}

/// A loaded map saved elsewhere (`CloudMap::save`, what the window's re-derived maps use)
/// keeps its ground texel for texel; one without orography saves without one.
#[test]
fn a_saved_map_keeps_its_ground() {
    let dir = tempfile::tempdir().unwrap();
    let map = real_map(dir.path(), "m", ATLANTIC, "120x84");
    let m = stratus_ingest::CloudMap::load(&map).unwrap();
    let copy = dir.path().join("copy").join("c.png");
    std::fs::create_dir(copy.parent().unwrap()).unwrap();
    let json = m.save(&copy).unwrap();
    let back = stratus_ingest::CloudMap::load(&json).unwrap();
    assert_eq!(back.ground(), m.ground());
    assert!(copy.with_file_name("c.ground-water.png").is_file());
    let meta = back.meta.ground.as_ref().unwrap();
    assert_eq!(
        (meta.image.as_str(), meta.water_image.as_str()),
        ("c.ground.png", "c.ground-water.png")
    );
    let mut bare = m.clone();
    bare.ground = None;
    let json = bare.save(&dir.path().join("bare.png")).unwrap();
    let back = stratus_ingest::CloudMap::load(&json).unwrap();
    assert!(back.ground().is_none() && back.meta.ground.is_none());
    assert_eq!(back.ground_height_m(45.0, -30.0).0, 0.0);
}
