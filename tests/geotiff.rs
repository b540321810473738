//! `stratus ingest … --out MAP.tif` read by a real GIS client: GDAL's `gdalinfo -json` and
//! `gdallocationinfo` (Debian's `gdal-bin`; `scripts/deps.sh` installs it). Checks the size,
//! the bounds against the region, EPSG:4326, 256×256 blocks, the overviews, and band values
//! equal to the PNG's at several pixels (and the first overview's to the PNG's 2×2 mean).
//! The structure image (`GTIFF_DIR:2:FILE`): named Float32 bands with units and nodata on the
//! structure lattice, whose values at lattice points are what `stratus probe` and the PNG
//! set's structure images say; an RH-only file has none.
//! Without GDAL these tests say why and pass; the writer's own tests (`stratus-ingest`,
//! `geotiff::tests`) read the file back without GDAL.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use serde_json::Value;
use stratus_ingest::geotiff::pyramid;
use stratus_ingest::structure::{
    sample_to_altitude, sample_to_wind, unpack_source, StructureBand, STRUCTURE_NODATA,
};
use stratus_ingest::weather::CloudType;
use stratus_ingest::{CloudMap, LayerKind};

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

/// `gdallocationinfo -valonly` of `dataset` at each line of `points` (`-wgs84`: "lon lat"; else
/// pixel coordinates), `bands` values a point.
fn float_values(dataset: &str, wgs84: bool, points: &[(f64, f64)], bands: usize) -> Vec<Vec<f64>> {
    let mut cmd = Command::new("gdallocationinfo");
    cmd.arg("-valonly");
    if wgs84 {
        cmd.arg("-wgs84");
    }
    let mut child = cmd
        .arg(dataset)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    {
        let mut stdin = child.stdin.take().unwrap();
        for (x, y) in points {
            writeln!(stdin, "{x} {y}").unwrap();
        }
    }
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Vec<f64> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| l.trim().parse().unwrap())
        .collect();
    assert_eq!(v.len(), bands * points.len(), "gdallocationinfo gave {v:?}");
    v.chunks_exact(bands).map(<[f64]>::to_vec).collect()
}

/// What the PNG set's structure images say for `band` at structure pixel `p`, in the
/// GeoTIFF's terms (physical units, [`STRUCTURE_NODATA`] for none).
fn expected(map: &CloudMap, band: StructureBand, p: usize) -> f64 {
    let s = map.structure.as_ref().unwrap();
    let nd = STRUCTURE_NODATA as f64;
    let wind = |k: LayerKind, v: u16| {
        let l = map.meta.layer(k).unwrap();
        match l.structure.as_ref().unwrap().wind {
            true => sample_to_wind(v),
            false => nd,
        }
    };
    match band {
        StructureBand::Base(k) => sample_to_altitude(s.base[p][k.channel()]).unwrap_or(nd),
        StructureBand::Top(k) => sample_to_altitude(s.top[p][k.channel()]).unwrap_or(nd),
        StructureBand::Type(k) => {
            CloudType::from_code(s.types[p][k.channel()]).map_or(nd, |t| t.code() as f64)
        }
        StructureBand::Source(k) => {
            unpack_source(s.types[p][3], k.channel()).map_or(nd, |x| x as u8 as f64)
        }
        StructureBand::WindU(k) => wind(k, s.wind_u[p][k.channel()]),
        StructureBand::WindV(k) => wind(k, s.wind_v[p][k.channel()]),
        StructureBand::ConvectiveBase => sample_to_altitude(s.base[p][3]).unwrap_or(nd),
        StructureBand::ConvectiveTop => sample_to_altitude(s.top[p][3]).unwrap_or(nd),
    }
}

/// Float32 values as GDAL prints them against the f64 they were made from.
fn same(got: f64, want: f64) -> bool {
    (got - want).abs() <= 1e-6 * want.abs().max(1.0)
}

/// The structure image of a map of the real sample over `region`: what `gdalinfo` shows, every
/// band at a spread of pixels equal to the PNG set's structure images, and at `points`
/// (lat, lon on the structure lattice; lon in the GeoTIFF's continuous convention) base, top,
/// type and source equal to `stratus probe --json` on the PNG map.
fn check_structure(region: &str, size: &str, points: &[(f64, f64)]) {
    let dir = tempfile::tempdir().unwrap();
    let (map, tif) = ingest_both(dir.path(), region, size);
    let sg = map.structure.as_ref().unwrap().grid;
    let page = format!("GTIFF_DIR:2:{}", tif.display());
    // The file lists it; the coverage stays the default dataset, its four bands as they were.
    let info = gdalinfo(&tif);
    assert_eq!(info["bands"].as_array().unwrap().len(), 4);
    assert_eq!(info["metadata"]["SUBDATASETS"]["SUBDATASET_2_NAME"], page);
    let info = gdalinfo(Path::new(&page));
    assert_eq!(info["size"], serde_json::json!([sg.width, sg.height]));
    assert_eq!(info["metadata"][""]["AREA_OR_POINT"], "Point");
    assert!(info["metadata"][""]["STRATUS_STRUCTURE"]
        .as_str()
        .unwrap()
        .contains("lattice"));
    let wkt = info["coordinateSystem"]["wkt"].as_str().unwrap();
    assert!(wkt.contains("ID[\"EPSG\",4326]"), "{wkt}");
    // Pixel-is-point: GDAL's pixel (i, j) is centred on lattice point (i, j); longitudes in
    // the coverage's convention (west in [-180, 180), continuous eastward).
    let west = (map.meta.region.west + 180.0).rem_euclid(360.0) - 180.0;
    let shift = west - map.meta.region.west;
    let gt: Vec<f64> = info["geoTransform"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let want = [
        sg.west + shift - sg.dlon / 2.0,
        sg.dlon,
        0.0,
        sg.north + sg.dlat / 2.0,
        0.0,
        -sg.dlat,
    ];
    assert!(
        gt.iter().zip(&want).all(|(a, b)| close(*a, *b)),
        "geoTransform {gt:?}, want {want:?}"
    );
    let kinds: Vec<LayerKind> = map.meta.layers.iter().map(|l| l.kind).collect();
    let layout = StructureBand::of_layers(&kinds);
    let bands = info["bands"].as_array().unwrap();
    assert_eq!(bands.len(), layout.len());
    for (b, l) in bands.iter().zip(&layout) {
        assert_eq!(b["type"], "Float32");
        assert_eq!(b["block"], serde_json::json!([256, 256]));
        assert_eq!(b["description"], l.description());
        assert_eq!(b["noDataValue"].as_f64(), Some(STRUCTURE_NODATA as f64));
        match l.unit() {
            "" => assert!(b["metadata"][""]["CODES"].as_str().unwrap().contains("1=")),
            u => assert_eq!(b["unit"], u),
        }
    }
    // Every band at a spread of pixels (corners among them): the PNG set's values.
    let (w, h) = (sg.width as usize, sg.height as usize);
    let mut px: Vec<usize> = (0..w * h).step_by(37).collect();
    px.extend([w - 1, (h - 1) * w, w * h - 1]);
    let at: Vec<(f64, f64)> = px
        .iter()
        .map(|&p| ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5))
        .collect();
    let got = float_values(&page, false, &at, layout.len());
    let mut with_value = vec![0; layout.len()];
    for (&p, g) in px.iter().zip(&got) {
        for (c, (&b, &v)) in layout.iter().zip(g).enumerate() {
            let e = expected(&map, b, p);
            assert!(same(v, e), "{b:?} at pixel {p}: {v}, PNG set {e}");
            with_value[c] += usize::from(v != STRUCTURE_NODATA as f64);
        }
    }
    // Every band holds values (the real sample has winds and convection in these regions).
    for (b, n) in layout.iter().zip(&with_value) {
        assert!(*n > 0, "{b:?} is nodata at every pixel read");
    }
    // At lattice points, by lat/lon: the probe's base, top, type and source.
    let lonlat: Vec<(f64, f64)> = points.iter().map(|&(lat, lon)| (lon, lat)).collect();
    let got = float_values(&page, true, &lonlat, layout.len());
    let mut compared = 0;
    for (&(lat, lon), g) in points.iter().zip(&got) {
        let o = stratus(&[
            "probe",
            "--map",
            tif.with_extension("json").to_str().unwrap(),
            "--at",
            &format!("{lat},{lon}"),
            "--json",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let probe: Value = serde_json::from_slice(&o.stdout).unwrap();
        let value = |b: StructureBand| g[layout.iter().position(|&x| x == b).unwrap()];
        for (l, pl) in map
            .meta
            .layers
            .iter()
            .zip(probe["layers"].as_array().unwrap())
        {
            let k = l.kind;
            assert_eq!(pl["kind"], k.name());
            // The probe gives base, top and type where the layer has cloud; the GeoTIFF gives
            // them wherever the layer exists.
            if let Some(base) = pl["base_m"].as_f64() {
                let top = pl["top_m"].as_f64().unwrap();
                assert!(
                    same(value(StructureBand::Base(k)), base)
                        && same(value(StructureBand::Top(k)), top),
                    "{lat},{lon} {}: GeoTIFF {} / {}, probe {base} / {top}",
                    k.name(),
                    value(StructureBand::Base(k)),
                    value(StructureBand::Top(k))
                );
                let ty = CloudType::from_code(value(StructureBand::Type(k)) as u8).unwrap();
                assert_eq!(pl["type"], ty.name(), "{lat},{lon} {}", k.name());
                compared += 1;
            }
            let source = match value(StructureBand::Source(k)) as u8 {
                1 => "gfs-layer",
                2 => "rh-column",
                _ => l.altitude_source.name(),
            };
            assert_eq!(pl["source"], source, "{lat},{lon} {}", k.name());
        }
    }
    assert!(compared >= 3, "only {compared} cloudy layers compared");
}

#[test]
fn the_structure_is_a_second_image_that_agrees_with_probe() {
    if !gdal("the_structure_is_a_second_image_that_agrees_with_probe") {
        return;
    }
    // North Atlantic: the convective tower at 50°N 25°W (docs/ingest.md's ecCodes table),
    // other 2.5° grid points, and lattice points between grid lines (k = 7 a cell here).
    let d = 2.5 / 7.0;
    check_structure(
        "30,65,-60,10",
        "600x300",
        &[
            (50.0, -25.0),
            (45.0, -5.0),
            (60.0, -40.0),
            (40.0, -30.0),
            (50.0 + 3.0 * d, -25.0 + 2.0 * d),
            (35.0 + d, 5.0 - 4.0 * d),
        ],
    );
}

#[test]
fn a_dateline_structure_keeps_continuous_longitudes() {
    if !gdal("a_dateline_structure_keeps_continuous_longitudes") {
        return;
    }
    // 150°E..150°W: lattice longitudes run on past 180 as the coverage's do.
    let d = 2.5 / 7.0;
    check_structure(
        "10,50,150,-150",
        "300x200",
        &[
            (30.0, 190.0),
            (40.0, 175.0),
            (20.0, 180.0),
            (15.0 + d, 200.0 - 3.0 * d),
        ],
    );
}

#[test]
fn an_rh_only_file_gives_the_coverage_bands_alone() {
    if !gdal("an_rh_only_file_gives_the_coverage_bands_alone") {
        return;
    }
    let rh = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data-samples/gfs/gfs.t18z.pgrb2.0p25.f186-RH.grib2");
    let dir = tempfile::tempdir().unwrap();
    let tif = dir.path().join("rh.tif");
    let o = stratus(&[
        "ingest",
        rh.to_str().unwrap(),
        "--level",
        "0.7",
        "--region",
        "-60,60,-180,180",
        "--size",
        "600x300",
        "--out",
        tif.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let info = gdalinfo(&tif);
    assert_eq!(info["bands"].as_array().unwrap().len(), 4);
    assert!(
        info["metadata"]["SUBDATASETS"].is_null(),
        "{}",
        info["metadata"]
    );
    let meta: Value =
        serde_json::from_str(info["metadata"][""]["STRATUS_CLOUDMAP"].as_str().unwrap()).unwrap();
    assert!(meta["source"]["fields"].is_null(), "{}", meta["source"]);
    // Only the coverage image and its overviews: one IFD each, chained from offset 8.
    let bytes = std::fs::read(&tif).unwrap();
    let u32_at = |a: usize| u32::from_le_bytes(bytes[a..a + 4].try_into().unwrap()) as usize;
    let (mut at, mut ifds) = (u32_at(4), 0);
    while at != 0 {
        let n = u16::from_le_bytes([bytes[at], bytes[at + 1]]) as usize;
        at = u32_at(at + 2 + 12 * n);
        ifds += 1;
    }
    assert_eq!(ifds, pyramid(600, 300).len());
}
