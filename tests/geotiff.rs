//! `stratus ingest … --out MAP.tif` read by a real GIS client: GDAL's `gdalinfo -json` and
//! `gdallocationinfo` (Debian's `gdal-bin`; `scripts/deps.sh` installs it). Checks the size,
//! the bounds against the region, EPSG:4326, 256×256 blocks, the overviews, and band values
//! equal to the PNG's at several pixels (and the first overview's to the PNG's 2×2 mean).
//! Without GDAL these tests say why and pass; the writer's own tests (`stratus-ingest`,
//! `geotiff::tests`) read the file back without GDAL.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use serde_json::Value;
use stratus_ingest::geotiff::pyramid;
use stratus_ingest::CloudMap;

fn sample() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data-samples/gfs-2011011012-f120-2p5.grib2")
}

fn stratus(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_stratus"))
        .args(args)
        .output()
        .expect("run stratus")
}

/// GDAL's tools are installed (else say why the test checks nothing).
fn gdal(test: &str) -> bool {
    let ok = Command::new("gdalinfo")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        eprintln!(
            "{test}: SKIPPED: gdalinfo not found (install Debian's gdal-bin; scripts/deps.sh does)"
        );
    }
    ok
}

/// Ingest `region` at `size` to both a PNG pair and a GeoTIFF in `dir`.
fn ingest_both(dir: &Path, region: &str, size: &str) -> (CloudMap, PathBuf) {
    let gfs = sample();
    let png = dir.join("m.png");
    let tif = dir.join("m.tif");
    for out in [&png, &tif] {
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
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert!(
        !dir.join("m.tif.json").exists(),
        "a sidecar was written for the GeoTIFF"
    );
    (CloudMap::load(&png.with_extension("json")).unwrap(), tif)
}

fn gdalinfo(tif: &Path) -> Value {
    let o = Command::new("gdalinfo")
        .arg("-json")
        .arg(tif)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// The 4 band values at each pixel (x, y) of `tif`.
fn values_at(tif: &Path, pixels: &[(usize, usize)]) -> Vec<[u16; 4]> {
    let mut cmd = Command::new("gdallocationinfo");
    cmd.arg("-valonly");
    let mut child = cmd
        .arg(tif)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    {
        // Pixel coordinates, one point a line; the pixel's centre, so no edge is ambiguous.
        let mut stdin = child.stdin.take().unwrap();
        for &(x, y) in pixels {
            writeln!(stdin, "{x}.5 {y}.5").unwrap();
        }
    }
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Vec<u16> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| l.trim().parse().unwrap())
        .collect();
    assert_eq!(v.len(), 4 * pixels.len(), "gdallocationinfo gave {v:?}");
    v.chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

/// Pixels worth reading: corners, the centre, and where each band peaks and changes.
fn probes(map: &CloudMap) -> Vec<(usize, usize)> {
    let (w, h) = (map.width(), map.height());
    let mut p = vec![
        (0, 0),
        (w - 1, 0),
        (0, h - 1),
        (w - 1, h - 1),
        (w / 2, h / 2),
    ];
    for c in 0..4 {
        let i = (0..map.texels.len())
            .max_by_key(|&i| map.texels[i][c])
            .unwrap();
        p.push((i % w, i / w));
        // A pixel with a value strictly between 0 and full.
        if let Some(i) = (0..map.texels.len())
            .step_by(97)
            .find(|&i| (1..65535).contains(&map.texels[i][c]))
        {
            p.push((i % w, i / w));
        }
    }
    p
}

/// Everything the issue asks gdalinfo to show, for one region.
fn check(region: &str, size: (usize, usize), bounds: [f64; 4]) {
    let dir = tempfile::tempdir().unwrap();
    let (map, tif) = ingest_both(dir.path(), region, &format!("{}x{}", size.0, size.1));
    let (w, h) = size;
    let info = gdalinfo(&tif);
    assert_eq!(info["driverShortName"], "GTiff");
    assert_eq!(info["size"], serde_json::json!([w, h]));
    // Bounds: [west, south, east, north] exactly the region's.
    let [west, south, east, north] = bounds;
    let gt: Vec<f64> = info["geoTransform"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let want = [
        west,
        (east - west) / w as f64,
        0.0,
        north,
        0.0,
        -(north - south) / h as f64,
    ];
    assert!(
        gt.iter().zip(&want).all(|(a, b)| close(*a, *b)),
        "geoTransform {gt:?}, want {want:?}"
    );
    let corner = |k: &str| -> (f64, f64) {
        let c = &info["cornerCoordinates"][k];
        (c[0].as_f64().unwrap(), c[1].as_f64().unwrap())
    };
    let (ulx, uly) = corner("upperLeft");
    let (lrx, lry) = corner("lowerRight");
    assert!(
        close(ulx, west) && close(uly, north) && close(lrx, east) && close(lry, south),
        "corners {:?}",
        info["cornerCoordinates"]
    );
    // EPSG:4326, pixel-is-area.
    let wkt = info["coordinateSystem"]["wkt"].as_str().unwrap();
    assert!(wkt.contains("ID[\"EPSG\",4326]"), "{wkt}");
    assert_eq!(info["metadata"][""]["AREA_OR_POINT"], "Area");
    // The map's metadata travels inside, as GDAL metadata.
    let meta: Value =
        serde_json::from_str(info["metadata"][""]["STRATUS_CLOUDMAP"].as_str().unwrap()).unwrap();
    assert_eq!(meta["width"], w);
    assert_eq!(meta["layers"].as_array().unwrap().len(), 3);
    assert_eq!(
        info["metadata"]["IMAGE_STRUCTURE"]["COMPRESSION"],
        "DEFLATE"
    );
    // Four UInt16 bands, 256×256 blocks, the overview pyramid down to one tile.
    let bands = info["bands"].as_array().unwrap();
    assert_eq!(bands.len(), 4);
    let ovr: Vec<Value> = pyramid(w as u32, h as u32)[1..]
        .iter()
        .map(|&(a, b)| serde_json::json!({ "size": [a, b] }))
        .collect();
    assert!(!ovr.is_empty());
    for (i, b) in bands.iter().enumerate() {
        assert_eq!(b["type"], "UInt16");
        assert_eq!(b["block"], serde_json::json!([256, 256]), "band {}", i + 1);
        assert_eq!(b["overviews"], Value::Array(ovr.clone()), "band {}", i + 1);
        assert!(b["description"].as_str().unwrap().contains("coverage"));
    }
    // Band values: the PNG's exactly.
    let px = probes(&map);
    let got = values_at(&tif, &px);
    for (&(x, y), g) in px.iter().zip(&got) {
        assert_eq!(*g, map.texels[y * w + x], "pixel ({x}, {y})");
    }
    assert!(got.iter().any(|v| v[3] > 0), "only empty pixels probed");
    // The first overview: the rounded mean of the PNG's 2×2 pixels.
    let half: Vec<(usize, usize)> = px.iter().map(|&(x, y)| (x / 2, y / 2)).collect();
    // The overview copied out as it is stored (gdallocationinfo's own -overview option reads
    // pixel coordinates differently across GDAL versions).
    let ovr = dir.path().join("ovr0.tif");
    let o = Command::new("gdal_translate")
        .args(["-q", "-ovr", "0"])
        .arg(&tif)
        .arg(&ovr)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got = values_at(&ovr, &half);
    for (&(x, y), g) in half.iter().zip(&got) {
        let mut sum = [0u32; 4];
        let mut n = 0;
        for yy in 2 * y..(2 * y + 2).min(h) {
            for xx in 2 * x..(2 * x + 2).min(w) {
                for (s, &v) in sum.iter_mut().zip(&map.texels[yy * w + xx]) {
                    *s += u32::from(v);
                }
                n += 1;
            }
        }
        let want = sum.map(|s| ((s + n / 2) / n) as u16);
        assert_eq!(*g, want, "overview pixel ({x}, {y})");
    }
}

#[test]
fn gdal_reads_the_geotiff_as_the_region_and_the_png() {
    if !gdal("gdal_reads_the_geotiff_as_the_region_and_the_png") {
        return;
    }
    // 600×500: 3×2 full-resolution tiles with ragged edges, two overviews.
    check("0,55,39,105", (600, 500), [39.0, 0.0, 105.0, 55.0]);
}

#[test]
fn a_dateline_region_keeps_continuous_longitudes() {
    if !gdal("a_dateline_region_keeps_continuous_longitudes") {
        return;
    }
    // West 150, east -150: written as 150..210 so the raster is one piece.
    check("10,50,150,-150", (300, 200), [150.0, 10.0, 210.0, 50.0]);
    // The same region in 0..360 longitudes, and one east of the date line in 0..360
    // (taken to -160..-140).
    check("10,50,150,210", (300, 200), [150.0, 10.0, 210.0, 50.0]);
    check("-30,30,200,220", (257, 300), [-160.0, -30.0, -140.0, 30.0]);
}

#[test]
fn the_extension_chooses_the_format_and_others_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let gfs = sample();
    for name in ["m.jpg", "m", "m.tif.gz"] {
        let out = dir.path().join(name);
        let o = stratus(&[
            "ingest",
            gfs.to_str().unwrap(),
            "--region",
            "0,55,39,105",
            "--size",
            "30x20",
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(name) && err.contains(".tif"), "{err}");
    }
    // A GeoTIFF alone: no sidecar, no temporaries; the input is never the output.
    let tif = dir.path().join("M.TIFF");
    let o = stratus(&[
        "ingest",
        gfs.to_str().unwrap(),
        "--region",
        "0,55,39,105",
        "--size",
        "30x20",
        "--out",
        tif.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut left: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["M.TIFF"]);
    let bytes = std::fs::read(&tif).unwrap();
    assert_eq!(&bytes[..8], b"II\x2a\x00\x08\x00\x00\x00");
    let copy = dir.path().join("in.tif");
    std::fs::copy(&gfs, &copy).unwrap();
    let o = stratus(&[
        "ingest",
        copy.to_str().unwrap(),
        "--region",
        "0,55,39,105",
        "--size",
        "30x20",
        "--out",
        copy.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("is the input"), "{err}");
    assert_eq!(std::fs::read(&copy).unwrap(), std::fs::read(&gfs).unwrap());
}
