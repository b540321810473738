//! `stratus ingest` / `inspect` end to end through the binary: real GFS files, and every kind of
//! bad input the ingest issue lists. Bad input must exit 2 with one line naming the file and
//! leave no output behind; nothing may panic.

mod common;

use std::path::{Path, PathBuf};

use common::{real_map, sample, stratus};
use stratus_ingest::encode::fixtures;

const EA: [&str; 4] = ["--region", "0,55,39,105", "--size", "130x110"];

/// Run ingest on `input`, expecting exit 2, one stderr line containing `needle` (and the
/// file's name where `names_file`), and no output files.
fn expect_refused(input: &Path, extra: &[&str], needle: &str, names_file: bool) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("map.png");
    let mut args = vec!["ingest", input.to_str().unwrap()];
    args.extend_from_slice(&EA);
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    let o = stratus(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{input:?} {extra:?}: stderr {err}"
    );
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(needle), "expected '{needle}' in: {err}");
    if names_file {
        let name = input.file_name().unwrap().to_string_lossy();
        assert!(
            err.contains(name.as_ref()),
            "error does not name the file: {err}"
        );
    }
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "output left behind: {left:?}");
}

fn write_tmp(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn real_gfs_file_ingests_and_inspects() {
    let gfs = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    let o = stratus(&["inspect", gfs.to_str().unwrap()]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("0.1.1   r      isobaric 400 hPa"), "{text}");
    assert!(text.contains("tcc    low cloud layer"));
    assert!(text.contains("5.3 complex+spatial-diff"));
    assert!(text.contains("2011-01-10T12:00Z +120h"));

    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ea.png");
    let o = stratus(&[
        "ingest",
        gfs.to_str().unwrap(),
        "--region",
        "0,55,39,105",
        "--size",
        "260x220",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let map = stratus_ingest::CloudMap::load(&out.with_extension("json")).unwrap();
    assert_eq!(map.meta.layers.len(), 3);
    assert_eq!(
        map.meta.source.valid_time.map(|t| t.to_rfc3339()),
        Some("2011-01-15T12:00:00+00:00".to_string())
    );
    for l in &map.meta.layers {
        assert_eq!(
            l.altitude_source,
            stratus_ingest::meta::AltitudeSource::GeopotentialHeight
        );
        assert!(l.mean_coverage > 0.0 && l.max_coverage <= 1.0, "{l:?}");
    }
    let (low, mid, high) = (
        &map.meta.layers[0],
        &map.meta.layers[1],
        &map.meta.layers[2],
    );
    assert!(low.top_m <= mid.base_m + 1.0 && mid.top_m <= high.base_m + 1.0);
    assert!(high.top_m > 12_000.0 && high.top_m < 18_000.0, "{high:?}");
    // A is the max of R, G, B everywhere.
    assert!(map.texels.iter().all(|t| t[3] == t[0].max(t[1]).max(t[2])));
}

#[test]
fn dateline_region_in_both_conventions_gives_the_same_map() {
    let gfs = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    let dir = tempfile::tempdir().unwrap();
    let mut maps = Vec::new();
    for (i, region) in ["10,50,150,-150", "10,50,150,210"].iter().enumerate() {
        let out = dir.path().join(format!("d{i}.png"));
        let o = stratus(&[
            "ingest",
            gfs.to_str().unwrap(),
            "--region",
            region,
            "--size",
            "120x80",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        maps.push(stratus_ingest::CloudMap::load(&out.with_extension("json")).unwrap());
    }
    assert_eq!(maps[0].texels, maps[1].texels);
    assert!(maps[0].texels.iter().any(|t| t[3] > 0));
}

#[test]
fn all_zero_rh_gives_an_all_zero_map() {
    let f = sample("gfs/gfs.t18z.pgrb2.0p25.f186-RH.grib2");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("zero.png");
    let o = stratus(&[
        "ingest",
        f.to_str().unwrap(),
        "--level",
        "0.7",
        "--region",
        "-60,60,-180,180",
        "--size",
        "360x180",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let map = stratus_ingest::CloudMap::load(&out.with_extension("json")).unwrap();
    assert!(map.texels.iter().all(|t| *t == [0; 4]));
    // Without --level the tropospheric default finds nothing and says which levels exist.
    expect_refused(&f, &[], "levels present: 0.7 hPa", true);
}

#[test]
fn file_without_rh_says_what_it_holds() {
    let f = sample("gfs/gfs.t12z.pgrb2.0p25.f023-PV-TMP-missing.grib2");
    expect_refused(&f, &[], "no relative humidity in", true);
    expect_refused(&f, &[], "it holds: t on PV surface -2 PVU", false);
}

#[test]
fn bad_files_are_refused_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.grib2", vec![], "empty file"),
        (
            "text.grib2",
            b"this is a forecast, honest\n".to_vec(),
            "not a GRIB file",
        ),
        ("ed1.grib", fixtures::grib1_rh(), "edition 1"),
        ("cut.grib2", fixtures::truncated(), "cut off"),
        (
            "random.grib2",
            fixtures::random_bytes(0x5eed, 4096),
            "not a GRIB file",
        ),
        (
            "bpv.grib2",
            fixtures::bits_per_value_255(),
            "bits per value",
        ),
        ("count.grib2", fixtures::huge_packed_count(), "packs"),
        ("huge.grib2", fixtures::huge_grid_claim(), "60000x60000"),
        ("polar.grib2", fixtures::unsupported_grid(), "grid template"),
        ("short.grib2", fixtures::short_grid_section(), "corrupt"),
    ];
    for (name, bytes, needle) in cases {
        let p = write_tmp(d, name, &bytes);
        expect_refused(&p, &[], needle, true);
    }
}

#[test]
fn absent_level_lists_the_levels_present() {
    let gfs = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    expect_refused(
        &gfs,
        &["--level", "420"],
        "levels present: 1000, 975, 950",
        true,
    );
}

#[test]
fn bad_options_are_refused() {
    let gfs = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    for (region, size, needle) in [
        ("50,10,0,10", "10x10", "south"),
        ("-95,10,0,10", "10x10", "latitudes"),
        ("0,10,0,10", "0x10", "size"),
        ("0,10,0,10", "16385x10", "size"),
        ("0,10,0", "10x10", "S,N,W,E"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("m.png");
        let o = stratus(&[
            "ingest",
            gfs.to_str().unwrap(),
            "--region",
            region,
            "--size",
            size,
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{region} {size}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(needle), "'{needle}' not in {err}");
        assert!(!out.exists());
    }
    for x in ["1", "1.5", "-0.2"] {
        expect_refused(&gfs, &["--rh-cr", x], "rh_cr must be in [0, 1)", false);
    }
}

#[test]
fn bit_flips_in_a_real_message_never_panic_or_leave_output() {
    // Flip bits through the data section of the real 400 hPa RH message (complex packing with
    // spatial differencing). Each result is either a clean map or a clean one-line refusal.
    let gfs = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    let bytes = std::fs::read(&gfs).unwrap();
    let msgs = stratus_ingest::grib::scan(&bytes).unwrap();
    let m = msgs
        .iter()
        .find(|m| m.is_relative_humidity() && m.pressure_hpa() == Some(400.0))
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (mut refused, mut accepted) = (0, 0);
    for k in 0..24usize {
        let mut b = bytes.clone();
        // Spread flips over the whole message, headers included.
        let pos = m.offset + 16 + (k * 7919) % (m.length - 20);
        b[pos] ^= 1 << (k % 8);
        let p = write_tmp(dir.path(), &format!("flip{k}.grib2"), &b);
        let out = dir.path().join(format!("flip{k}.png"));
        let o = stratus(&[
            "ingest",
            p.to_str().unwrap(),
            "--level",
            "400",
            "--region",
            "0,55,39,105",
            "--size",
            "65x55",
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!err.contains("panicked"), "flip {k}: {err}");
        match o.status.code() {
            Some(0) => accepted += 1,
            Some(2) => {
                refused += 1;
                assert_eq!(err.trim_end().lines().count(), 1, "{err}");
                assert!(!out.exists());
            }
            c => panic!("flip {k}: exit {c:?}: {err}"),
        }
    }
    println!("bit flips: {refused} refused, {accepted} decoded to other values");
    assert!(refused > 0);
}

/// `probe` on the real sample: the JSON users script against (exact keys), the North Atlantic
/// convective tower the file holds near 50°N 25°W (GFS's own middle-cloud bottom and top,
/// verified against ecCodes in docs/ingest.md), and a point outside the map refused.
#[test]
fn probe_reports_the_column() {
    let dir = tempfile::tempdir().unwrap();
    let map = real_map(dir.path(), "natl", "30,70,-60,30", "180x80");
    let map = map.to_str().unwrap();
    let o = stratus(&["probe", "--map", map, "--at", "50,-25", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("probe JSON");
    assert_eq!(
        (v["lat"].as_f64(), v["lon"].as_f64()),
        (Some(50.0), Some(-25.0))
    );
    let layers = v["layers"].as_array().expect("layers");
    assert_eq!(layers.len(), 3);
    for l in layers {
        let keys: Vec<&str> = l.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        let mut sorted = keys.clone();
        sorted.sort();
        assert_eq!(
            sorted,
            ["base_m", "coverage", "kind", "source", "top_m", "type"],
            "{l}"
        );
    }
    let middle = &layers[1];
    assert_eq!(middle["kind"], "middle");
    assert_eq!(middle["type"], "cumulonimbus");
    assert_eq!(middle["source"], "gfs-layer");
    let (base, top) = (
        middle["base_m"].as_f64().unwrap(),
        middle["top_m"].as_f64().unwrap(),
    );
    assert!(
        (base - 3561.0).abs() < 2.0 && (top - 6472.0).abs() < 2.0,
        "{base} {top}"
    );
    let o = stratus(&["probe", "--map", map, "--at", "10,-25"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("outside the map's region"), "{err}");
}

/// Issue 28: on a global map the pole is one point with one answer, whatever longitude it is
/// asked at (ground and every layer), and a point off the globe is refused naming `--at`.
#[test]
fn the_pole_answers_the_same_at_every_longitude() {
    let dir = tempfile::tempdir().unwrap();
    let file = sample("gfs-2011011012-f120-2p5.grib2");
    let png = dir.path().join("globe.png");
    let o = stratus(&[
        "ingest",
        file.to_str().unwrap(),
        "--region",
        "-90,90,-180,180",
        "--size",
        "144x72",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let map = dir.path().join("globe.json");
    let probe = |at: &str| {
        let mut v = common::probe_json(&map, at);
        let o = v.as_object_mut().unwrap();
        o.remove("lat");
        o.remove("lon");
        v
    };
    for lat in ["90", "-90"] {
        let at = |lon: &str| probe(&format!("{lat},{lon}"));
        let first = at("0");
        for lon in ["90", "180", "-180", "-135", "37.5"] {
            assert_eq!(at(lon), first, "the pole at {lat},{lon} and {lat},0");
        }
    }
    // Just off the pole the answer still follows the longitude (the fix is at the pole).
    assert_ne!(probe("80,0"), probe("80,180"));

    for (at, what) in [
        ("91,0", "latitude 91 is outside -90..90"),
        ("0,1000", "longitude 1000 is outside -360..360"),
        ("0,nan", "LAT,LON"),
    ] {
        let o = stratus(&["probe", "--map", map.to_str().unwrap(), "--at", at]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{at}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains("--at") && err.contains(what), "{at}: {err}");
    }
}

/// Issue 28 #15: a GeoTIFF (or a PNG) given where a map's sidecar belongs is named as what it
/// is, not "sidecar is not UTF-8".
#[test]
fn a_geotiff_given_as_map_is_named_as_one() {
    let dir = tempfile::tempdir().unwrap();
    let gfs = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    let tif = dir.path().join("natl.tif");
    let mut args = vec!["ingest", gfs.to_str().unwrap()];
    args.extend_from_slice(&EA);
    args.extend_from_slice(&["--out", tif.to_str().unwrap()]);
    let o = stratus(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let png = real_map(dir.path(), "natl", "0,55,39,105", "130x110").with_extension("png");
    for (file, what) in [(&tif, "it is a TIFF"), (&png, "it is a PNG")] {
        let o = stratus(&["probe", "--map", file.to_str().unwrap(), "--at", "30,70"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(file.to_str().unwrap()), "{err}");
        assert!(err.contains(what) && err.contains("JSON sidecar"), "{err}");
        assert!(!err.contains("UTF-8"), "{err}");
    }
}
