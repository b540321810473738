//! Issue 13 (the forecast's vertical structure and cloud types), through the library, on the
//! real GFS files: the coverage PNG is unchanged byte for byte, multi-field messages decode,
//! base/top come from the sources in order, old sidecars load, bad extra images are refused.

use std::path::{Path, PathBuf};

use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::grib;
use stratus_ingest::ground::ProbeGround;
use stratus_ingest::meta::AltitudeSource;
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::spline::Interp;
use stratus_ingest::structure::{unpack_source, Probe, ProbeLayer};
use stratus_ingest::weather::{CloudType, PointSource};
use stratus_ingest::{CloudMap, LayerKind, Region};

fn sample(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data-samples")
        .join(rel)
}

/// The real 2.5° sample (a test fails where it is absent).
fn real(rel: &str) -> Option<PathBuf> {
    let p = sample(rel);
    if p.exists() {
        Some(p)
    } else {
        panic!("{} is absent", p.display())
    }
}

/// FNV-1a 64 over a PNG's chunks (type and data) except `tEXt`, which holds the pair's random
/// image id: equal hashes mean the same header, pixels and compressed stream.
fn png_hash_without_id(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |b: &[u8]| {
        for &x in b {
            h ^= x as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    let mut p = 8;
    while p + 12 <= bytes.len() {
        let len = u32::from_be_bytes(bytes[p..p + 4].try_into().unwrap()) as usize;
        let ty = &bytes[p + 4..p + 8];
        if ty != b"tEXt" {
            eat(&bytes[p + 4..p + 8 + len]);
        }
        p += 12 + len;
    }
    h
}

fn coverage_png_hash(region: &str, size: (u32, u32), select: LevelSelect) -> u64 {
    let gfs = real("gfs/gfs.t12z.pgrbf120.2p5deg.grib2").unwrap();
    let fc = Forecast::open(&gfs, select).unwrap();
    let plan = Plan::new(
        &fc,
        &IngestOptions {
            region: Region::parse(region).unwrap(),
            width: size.0,
            height: size.1,
            rh_cr: LayerKind::DEFAULT_RH_CR,
            interp: Interp::Spline,
        },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("m.png");
    plan.write(&png, &|_| {}).unwrap();
    png_hash_without_id(&std::fs::read(&png).unwrap())
}

/// Hashes recorded with the ingest of main before issue 13 (commit a0cb52c): the structure,
/// type and wind images are added beside the coverage PNG, never into it.
#[test]
fn coverage_png_is_byte_identical_to_before() {
    if real("gfs/gfs.t12z.pgrbf120.2p5deg.grib2").is_none() {
        return;
    }
    let cases = [
        (
            "0,55,39,105",
            (260, 220),
            LevelSelect::AllBelow(DEFAULT_TOP_HPA),
        ),
        (
            "30,65,-50,0",
            (400, 280),
            LevelSelect::AllBelow(DEFAULT_TOP_HPA),
        ),
        ("0,55,39,105", (520, 440), LevelSelect::One(400.0)),
        (
            "-90,90,0,360",
            (288, 146),
            LevelSelect::AllBelow(DEFAULT_TOP_HPA),
        ),
    ];
    let got: Vec<u64> = cases
        .iter()
        .map(|(r, s, l)| coverage_png_hash(r, *s, *l))
        .collect();
    let want: [u64; 4] = [
        0x62d5_42ef_bcc3_f6b6,
        0xc92d_c573_8d52_476f,
        0xfea5_4c17_0bff_0cdb,
        0xbccb_a64e_8ebb_7658,
    ];
    assert_eq!(got, want);
}

/// The sample's `v` winds sit beside `u` in one message (sections 4–7 repeated): every field
/// is listed and decodes, and the values agree with ecCodes (multi-field support on), which
/// counts 343 fields in 307 messages.
#[test]
fn every_field_of_a_multi_field_message_decodes() {
    let Some(gfs) = real("gfs/gfs.t12z.pgrbf120.2p5deg.grib2") else {
        return;
    };
    let bytes = std::fs::read(&gfs).unwrap();
    let fields = grib::scan(&bytes).unwrap();
    assert_eq!(fields.len(), 343);
    assert_eq!(fields.last().unwrap().index + 1, 307);
    let second: Vec<_> = fields.iter().filter(|m| m.field > 0).collect();
    assert_eq!(second.len(), 36);
    for v in &second {
        assert_eq!(v.short_name(), "v", "{v}");
        let u = fields
            .iter()
            .find(|m| m.index == v.index && m.field == 0)
            .unwrap();
        assert_eq!(u.short_name(), "u");
        assert_eq!((u.level_type, u.level_value), (v.level_type, v.level_value));
    }
    let at500 = |name: &str| {
        let m = fields
            .iter()
            .find(|m| m.short_name() == name && m.pressure_hpa() == Some(500.0))
            .unwrap();
        grib::decode_values(&bytes, m).unwrap()
    };
    let (u, v) = (at500("u"), at500("v"));
    // ecCodes: u 16.79, v 4.12 at 50°N 25°W; v 4.02 at 15°N 137.5°E; mean v 0.045 m/s.
    assert!((u.at(134, 16) - 16.79).abs() < 0.01, "{}", u.at(134, 16));
    assert!((v.at(134, 16) - 4.12).abs() < 0.01, "{}", v.at(134, 16));
    assert!((v.at(55, 30) - 4.02).abs() < 0.01, "{}", v.at(55, 30));
    let mean_v = v.values.iter().sum::<f64>() / v.values.len() as f64;
    assert!((mean_v - 0.0451).abs() < 1e-3, "{mean_v}");
    // The series files have one field a message; their v decodes on its own.
    for (f, n) in [("f000", 322), ("f006", 366)] {
        let p = real(&format!("gfs-series/gfs.t18z.pgrb2.2p50.{f}")).unwrap();
        let b = std::fs::read(&p).unwrap();
        let all = grib::scan(&b).unwrap();
        assert_eq!(all.len(), n);
        assert!(all.iter().all(|m| m.field == 0));
        let v = all
            .iter()
            .find(|m| m.short_name() == "v" && m.pressure_hpa() == Some(500.0))
            .unwrap();
        grib::decode_values(&b, v).unwrap();
    }
}

fn ingest(file: &Path, region: &str, size: (u32, u32), out: &Path) -> CloudMap {
    let fc = Forecast::open(file, LevelSelect::AllBelow(DEFAULT_TOP_HPA)).unwrap();
    let plan = Plan::new(
        &fc,
        &IngestOptions {
            region: Region::parse(region).unwrap(),
            width: size.0,
            height: size.1,
            rh_cr: LayerKind::DEFAULT_RH_CR,
            interp: Interp::Spline,
        },
    )
    .unwrap();
    let json = plan.write(out, &|_| {}).unwrap();
    CloudMap::load(&json).unwrap()
}

fn sources(m: &CloudMap, k: LayerKind) -> Vec<AltitudeSource> {
    let st = m.meta.layer(k).unwrap().structure.as_ref().unwrap();
    st.sources.keys().copied().collect()
}

/// Base and top come from GFS's cloud layer where it has one, from the RH column elsewhere,
/// and match what ecCodes reads at a grid point (docs/ingest.md, "Verification"): at 50°N
/// 25°W GFS's middle cloud is 625–417 hPa, 3561–6472 m with that point's gh.
#[test]
fn base_and_top_come_from_gfs_then_the_rh_column() {
    let Some(gfs) = real("gfs/gfs.t12z.pgrbf120.2p5deg.grib2") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // Pixel centres on the 2.5° grid points: 47.5..52.5°N, 27.5..22.5°W.
    let m = ingest(
        &gfs,
        "46.25,53.75,-28.75,-21.25",
        (3, 3),
        &dir.path().join("m.png"),
    );
    assert_eq!(m.meta.format, "stratus-cloudmap/3");
    let p = m.probe(50.0, -25.0).unwrap();
    let mid = &p.layers[1];
    assert_eq!(mid.source, AltitudeSource::GfsLayer);
    assert_eq!(mid.cloud_type, Some(CloudType::Cumulonimbus));
    assert!((mid.base_m.unwrap() - 3561.0).abs() < 2.0, "{mid:?}");
    assert!((mid.top_m.unwrap() - 6472.0).abs() < 2.0, "{mid:?}");
    // Over the North Atlantic all three sources occur, and the sidecar says how often.
    let m = ingest(&gfs, "30,65,-50,0", (400, 280), &dir.path().join("na.png"));
    let low = m
        .meta
        .layer(LayerKind::Low)
        .unwrap()
        .structure
        .clone()
        .unwrap();
    assert!(
        low.sources.contains_key(&AltitudeSource::GfsLayer),
        "{low:?}"
    );
    assert!(
        low.sources.contains_key(&AltitudeSource::RhColumn),
        "{low:?}"
    );
    let total: f64 = low.sources.values().sum();
    assert!((total - 1.0).abs() < 1e-9, "{low:?}");
    assert!(low.types.contains_key(&CloudType::Cumulonimbus), "{low:?}");
    assert!(low.wind);
    // An analysis has no cloud-layer fields: the RH column and the band only, and no
    // convective cloud, so no cumulonimbus from GFS's convection.
    let f000 = real("gfs-series/gfs.t18z.pgrb2.2p50.f000").unwrap();
    let a = ingest(&f000, "30,65,-50,0", (200, 140), &dir.path().join("a.png"));
    for k in LayerKind::ALL {
        assert!(!sources(&a, k).contains(&AltitudeSource::GfsLayer), "{k:?}");
        assert!(sources(&a, k).contains(&AltitudeSource::RhColumn), "{k:?}");
    }
    assert!(!a
        .meta
        .source
        .fields
        .contains(&"cloud-layer-pressures".to_string()));
}

/// An RH-only file (one 0.25° level, all zero) still ingests: no cloud, the band, no type.
#[test]
fn an_rh_only_file_gives_the_band() {
    let Some(rh) = real("gfs/gfs.t18z.pgrb2.0p25.f186-RH.grib2") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let fc = Forecast::open(&rh, LevelSelect::AllBelow(0.5)).unwrap();
    let plan = Plan::new(
        &fc,
        &IngestOptions {
            region: Region::parse("0,55,39,105").unwrap(),
            width: 130,
            height: 110,
            rh_cr: LayerKind::DEFAULT_RH_CR,
            interp: Interp::Spline,
        },
    )
    .unwrap();
    let m = CloudMap::load(&plan.write(&dir.path().join("rh.png"), &|_| {}).unwrap()).unwrap();
    assert!(
        m.meta.source.fields.is_empty(),
        "{:?}",
        m.meta.source.fields
    );
    let layer = &m.meta.layers[0];
    let st = layer.structure.as_ref().unwrap();
    assert_eq!(st.cloudy_pixels, 0);
    assert_eq!((st.base_min_m, st.top_max_m), (layer.base_m, layer.top_m));
    let s = m.structure.as_ref().unwrap();
    let c = layer.channel;
    assert!(s
        .types
        .iter()
        .all(|t| unpack_source(t[3], c) == Some(PointSource::Band)));
    let p = m.probe(20.0, 70.0).unwrap();
    assert_eq!(p.layers[0].base_m, None);
    assert_eq!(p.layers[0].source, layer.altitude_source);
}

/// The probe serializes exactly as `stratus probe --json` prints it.
#[test]
fn the_probe_json_is_the_cli_format() {
    let p = Probe {
        lat: 50.0,
        lon: -25.0,
        ground: ProbeGround::NONE,
        layers: vec![
            ProbeLayer {
                kind: LayerKind::Low,
                coverage: 0.5,
                base_m: Some(600.5),
                top_m: Some(1200.0),
                cloud_type: Some(CloudType::Cumulus),
                source: AltitudeSource::GfsLayer,
            },
            ProbeLayer {
                kind: LayerKind::High,
                coverage: 0.0,
                base_m: None,
                top_m: None,
                cloud_type: None,
                source: AltitudeSource::RhColumn,
            },
        ],
    };
    assert_eq!(
        serde_json::to_string(&p).unwrap(),
        r#"{"lat":50.0,"lon":-25.0,"ground_m":0.0,"ground_source":"none","land":null,"ice":null,"snow_kg_m2":null,"snow_cover":null,"albedo":null,"cwat_kg_m2":null,"ground_fields":[],"layers":[{"kind":"low","coverage":0.5,"base_m":600.5,"top_m":1200.0,"type":"cumulus","source":"gfs-layer"},{"kind":"high","coverage":0.0,"base_m":null,"top_m":null,"type":null,"source":"rh-column"}]}"#
    );
}

/// A synthetic map (no structure) saved, then its sidecar rewritten as version 2 and as
/// version 1: each loads, without structure, and the probe gives the band and default type.
#[test]
fn version_1_and_2_sidecars_load_with_the_band() {
    let dir = tempfile::tempdir().unwrap();
    let t = chrono::TimeZone::with_ymd_and_hms(&chrono::Utc, 2024, 6, 1, 12, 0, 0).unwrap();
    let r = Region::parse("0,10,0,10").unwrap();
    let m = CloudMap::from_fn(
        r,
        20,
        20,
        &[(LayerKind::Middle, 3000.0, 5000.0)],
        t,
        |_, _| [0.0, 0.5, 0.0],
    );
    let json = m.save(&dir.path().join("s.png")).unwrap();
    let v3 = std::fs::read_to_string(&json).unwrap();
    assert!(v3.contains("stratus-cloudmap/3") && !v3.contains("extra_images"));
    let v2 = v3.replace("stratus-cloudmap/3", "stratus-cloudmap/2");
    let id_line = v3.lines().find(|l| l.contains("image_id")).unwrap();
    let v1 = v3
        .replace("stratus-cloudmap/3", "stratus-cloudmap/1")
        .replace(&format!("{id_line}\n"), "");
    for text in [v2, v1] {
        std::fs::write(&json, &text).unwrap();
        let back = CloudMap::load(&json).unwrap();
        assert!(back.structure.is_none());
        let p = back.probe(5.0, 5.0).unwrap();
        let l = &p.layers[0];
        assert_eq!((l.base_m, l.top_m), (Some(3000.0), Some(5000.0)));
        assert_eq!(l.cloud_type, Some(CloudType::Altostratus));
        assert_eq!(l.source, AltitudeSource::StandardAtmosphere);
    }
    // Extra images belong to version 3 only.
    let bad = v3
        .replace("stratus-cloudmap/3", "stratus-cloudmap/2")
        .replace(
            "\"region\"",
            "\"extra_images\": [{\"role\": \"base\", \"image\": \"s.base.png\"}],\n  \"region\"",
        );
    std::fs::write(&json, bad).unwrap();
    let e = CloudMap::load(&json).unwrap_err().to_string();
    assert!(e.contains("only stratus-cloudmap/3 has them"), "{e}");
}

/// Rewrite the PNG at `path` with `f` applied to its samples, keeping its image id.
fn tamper(path: &Path, size: Option<(u32, u32)>, f: impl Fn(&mut [u8])) {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = dec.read_info().unwrap();
    let id = r.info().uncompressed_latin1_text[0].text.clone();
    let (ct, bd) = (r.info().color_type, r.info().bit_depth);
    let mut buf = vec![0u8; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    let (w, h) = size.unwrap_or((info.width, info.height));
    let px = ct.samples() * if bd == png::BitDepth::Sixteen { 2 } else { 1 };
    buf.resize(w as usize * h as usize * px, 0);
    f(&mut buf);
    let mut enc = png::Encoder::new(std::fs::File::create(path).unwrap(), w, h);
    enc.set_color(ct);
    enc.set_depth(bd);
    enc.add_text_chunk("stratus-image-id".into(), id).unwrap();
    let mut wr = enc.write_header().unwrap();
    wr.write_image_data(&buf).unwrap();
    wr.finish().unwrap();
}

/// A missing extra image, one of the wrong size, a type image with a code outside the table,
/// or a sidecar listing only some: one line naming the file, never a panic.
#[test]
fn bad_extra_images_are_refused_in_one_line() {
    let Some(gfs) = real("gfs/gfs.t12z.pgrbf120.2p5deg.grib2") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let png_path = dir.path().join("m.png");
    let m = ingest(&gfs, "30,65,-50,0", (40, 28), &png_path);
    let s = m.structure.as_ref().unwrap();
    assert!(s
        .types
        .iter()
        .all(|t| t[..3].iter().all(|&c| c <= CloudType::MAX_CODE)));
    let json = png_path.with_extension("json");
    let fresh = |d: &Path| {
        ingest(&gfs, "30,65,-50,0", (40, 28), &d.join("m.png"));
    };
    let one_line = |want: &[&str]| {
        let e = CloudMap::load(&json).unwrap_err().to_string();
        assert_eq!(e.lines().count(), 1, "{e}");
        for w in want {
            assert!(e.contains(w), "{e:?} lacks {w:?}");
        }
    };
    // Missing.
    std::fs::remove_file(dir.path().join("m.type.png")).unwrap();
    one_line(&["m.type.png", "cannot read"]);
    // Wrong size (same image id).
    fresh(dir.path());
    tamper(&dir.path().join("m.base.png"), Some((2, 2)), |_| {});
    // The structure images of a 40x28 map of 50° x 35° lie on the 2.5° grid points: 21x15.
    one_line(&["m.base.png", "PNG is 2x2 but its sidecar says 21x15"]);
    // A type code outside the table.
    fresh(dir.path());
    tamper(&dir.path().join("m.type.png"), None, |b| {
        b[4 * 45 + 1] = 200
    });
    one_line(&[
        "m.type.png",
        "pixel (3, 2)",
        "middle layer type code 200 is outside the table (0..=10)",
    ]);
    // Another map's image (its id differs).
    fresh(dir.path());
    let other = tempfile::tempdir().unwrap();
    fresh(other.path());
    std::fs::copy(
        other.path().join("m.wind-u.png"),
        dir.path().join("m.wind-u.png"),
    )
    .unwrap();
    one_line(&["m.wind-u.png", "not the one its sidecar names"]);
    // A sidecar that lists four of the five.
    fresh(dir.path());
    let text = std::fs::read_to_string(&json).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut v = v;
    v["extra_images"].as_array_mut().unwrap().remove(4);
    std::fs::write(&json, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    one_line(&["m.json", "no wind-v image"]);
    // A structure grid larger than the map, one that leaves part of the region uncovered, and
    // one whose size is not the images'.
    let edit = |f: &dyn Fn(&mut serde_json::Value)| {
        fresh(dir.path());
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        f(&mut v["structure_grid"]);
        std::fs::write(&json, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    };
    edit(&|g| g["width"] = 41.into());
    one_line(&["m.json", "structure_grid.width: 41 px is outside 1..=40"]);
    edit(&|g| g["west"] = (-45.0).into());
    one_line(&["m.json", "structure_grid", "do not cover the region"]);
    edit(&|g| {
        g["width"] = 22.into();
        g["height"] = 16.into();
    });
    one_line(&["m.base.png", "PNG is 21x15 but its sidecar says 22x16"]);
}

/// A version-3 sidecar without `structure_grid` (as the first version-3 ingest wrote them,
/// every structure image at the map's size) still loads, its images taken as the map's pixels.
#[test]
fn a_version_3_sidecar_without_a_structure_grid_loads_at_the_map_size() {
    let Some(gfs) = real("gfs/gfs.t12z.pgrbf120.2p5deg.grib2") else {
        return;
    };
    let fc = Forecast::open(&gfs, LevelSelect::AllBelow(DEFAULT_TOP_HPA)).unwrap();
    let region = Region::parse("30,65,-50,0").unwrap();
    let mut plan = Plan::new(
        &fc,
        &IngestOptions {
            region,
            width: 200,
            height: 140,
            rh_cr: LayerKind::DEFAULT_RH_CR,
            interp: Interp::Spline,
        },
    )
    .unwrap();
    plan.use_map_pixels_for_structure();
    let dir = tempfile::tempdir().unwrap();
    let json = plan.write(&dir.path().join("m.png"), &|_| {}).unwrap();
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("structure_grid").unwrap();
    std::fs::write(&json, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let m = CloudMap::load(&json).unwrap();
    assert_eq!(m.meta.structure_grid, None);
    let s = m.structure.as_ref().unwrap();
    assert_eq!(
        s.grid,
        stratus_ingest::meta::StructureGrid::of_map(&region, 200, 140)
    );
    assert_eq!(s.base.len(), 200 * 140);
    let p = m.probe(50.0, -25.0).unwrap();
    assert_eq!(p.layers[1].source, AltitudeSource::GfsLayer);
}

/// The map built in memory (the renderer's live path) holds what the written set holds.
#[test]
fn built_and_written_structure_agree() {
    let Some(gfs) = real("gfs/gfs.t12z.pgrbf120.2p5deg.grib2") else {
        return;
    };
    let fc = Forecast::open(&gfs, LevelSelect::AllBelow(DEFAULT_TOP_HPA)).unwrap();
    let plan = Plan::new(
        &fc,
        &IngestOptions {
            region: Region::parse("-10,40,100,180").unwrap(),
            width: 160,
            height: 100,
            rh_cr: LayerKind::DEFAULT_RH_CR,
            interp: Interp::Spline,
        },
    )
    .unwrap();
    let built = plan.build();
    let dir = tempfile::tempdir().unwrap();
    let loaded = CloudMap::load(&plan.write(&dir.path().join("w.png"), &|_| {}).unwrap()).unwrap();
    assert_eq!(built.texels, loaded.texels);
    assert_eq!(built.structure, loaded.structure);
    // The sidecar's shares go through JSON (serde_json may round the last bit).
    for (a, b) in built.meta.layers.iter().zip(&loaded.meta.layers) {
        let (a, b) = (a.structure.as_ref().unwrap(), b.structure.as_ref().unwrap());
        assert_eq!(a.cloudy_pixels, b.cloudy_pixels);
        assert_eq!((a.base_min_m, a.top_max_m), (b.base_min_m, b.top_max_m));
        let close = |x: Vec<f64>, y: Vec<f64>| x.iter().zip(&y).all(|(x, y)| (x - y).abs() < 1e-12);
        assert!(a.sources.keys().eq(b.sources.keys()) && a.types.keys().eq(b.types.keys()));
        assert!(close(
            a.sources.values().copied().collect(),
            b.sources.values().copied().collect()
        ));
        assert!(close(
            a.types.values().copied().collect(),
            b.types.values().copied().collect()
        ));
    }
    // The western Pacific holds deep convection: some high-layer cumulonimbus.
    let high = loaded.meta.layer(LayerKind::High).unwrap();
    let types = &high.structure.as_ref().unwrap().types;
    assert!(
        types
            .get(&CloudType::Cumulonimbus)
            .is_some_and(|&f| f > 0.01),
        "{types:?}"
    );
}

/// Probe differences between two maps at `points`: per point and layer where both have a
/// cloud, |Δbase| and |Δtop| (m), sorted; and how many layers differ in type or source.
fn probe_differences(a: &CloudMap, b: &CloudMap, points: &[(f64, f64)]) -> (Vec<f64>, usize) {
    let (mut dz, mut mismatched) = (Vec::new(), 0);
    for &(lat, lon) in points {
        let (pa, pb) = (a.probe(lat, lon).unwrap(), b.probe(lat, lon).unwrap());
        for (la, lb) in pa.layers.iter().zip(&pb.layers) {
            if la.coverage == 0.0 || lb.coverage == 0.0 {
                continue;
            }
            for (x, y) in [(la.base_m, lb.base_m), (la.top_m, lb.top_m)] {
                dz.push((x.unwrap() - y.unwrap()).abs());
            }
            if (la.cloud_type, la.source) != (lb.cloud_type, lb.source) {
                mismatched += 1;
            }
        }
    }
    dz.sort_by(f64::total_cmp);
    (dz, mismatched)
}

/// A large map stores its structure on the forecast grid's lattice (7 pixels a 2.5° cell),
/// not at its own size; the sidecar and the PNG headers say so; and the probe through the
/// reduced images gives, at grid points (the verification points of docs/ingest.md among
/// them), exactly what a map whose pixels are the grid points gives, and between grid lines
/// what a full-resolution sampling (every map pixel, as before the reduction) gives, within
/// the 0.5 m quantisation; type and source everywhere alike.
#[test]
fn structure_images_are_reduced_and_probe_like_full_resolution() {
    let Some(gfs) = real("gfs/gfs.t12z.pgrbf120.2p5deg.grib2") else {
        return;
    };
    let fc = Forecast::open(&gfs, LevelSelect::AllBelow(DEFAULT_TOP_HPA)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let new_plan = |region: Region, (width, height): (u32, u32)| {
        Plan::new(
            &fc,
            &IngestOptions {
                region,
                width,
                height,
                rh_cr: LayerKind::DEFAULT_RH_CR,
                interp: Interp::Spline,
            },
        )
        .unwrap()
    };
    // North Atlantic (50°N 25°W, 45°N 5°W) and the western Pacific (15°N 137.5°E, 5°N 155°E).
    for (region, size, reduced_size) in [
        ("30,65,-50,0", (1000, 700), (141, 99)),
        ("-10,40,100,180", (1200, 750), (225, 141)),
    ] {
        let r = Region::parse(region).unwrap();
        let mut plan = new_plan(r, size);
        let g = plan.structure_grid();
        assert_eq!((g.width, g.height), reduced_size);
        let png_path = dir.path().join("r.png");
        let reduced = CloudMap::load(&plan.write(&png_path, &|_| {}).unwrap()).unwrap();
        assert_eq!(reduced.meta.structure_grid, Some(g));
        for x in &reduced.meta.extra_images {
            let f = std::fs::File::open(dir.path().join(&x.image)).unwrap();
            let r = png::Decoder::new(std::io::BufReader::new(f))
                .read_info()
                .unwrap();
            assert_eq!(
                (r.info().width, r.info().height),
                reduced_size,
                "{}",
                x.image
            );
        }
        assert_eq!(reduced.structure.as_ref().unwrap().grid, g);

        plan.use_map_pixels_for_structure();
        let full = plan.build();
        assert_eq!(full.texels, reduced.texels);
        let fg = full.structure.as_ref().unwrap().grid;
        assert_eq!((fg.width, fg.height), size);
        // Pixel centres on the grid points: bilinear weights 0 and 1 there, so exact.
        let on_grid = Region {
            south: r.south - 1.25,
            north: r.north + 1.25,
            west: r.west - 1.25,
            east: r.east + 1.25,
        };
        let cells = (
            on_grid.lon_span() / 2.5,
            (on_grid.north - on_grid.south) / 2.5,
        );
        let exact = plan_map(new_plan(on_grid, (cells.0 as u32, cells.1 as u32)), &dir);

        let (mut grid_points, mut between) = (Vec::new(), Vec::new());
        let mut lat = r.south + 2.5;
        while lat < r.north - 1.0 {
            let mut dlon = 2.5;
            while dlon < r.lon_span() - 1.0 {
                let lon = r.west + dlon;
                grid_points.push((lat, lon));
                between.extend([(lat + 0.625, lon + 0.625), (lat - 0.8, lon + 0.3)]);
                dlon += 2.5;
            }
            lat += 2.5;
        }
        for (what, other, points) in [
            ("grid points vs the grid", &exact, &grid_points),
            ("between grid lines vs full resolution", &full, &between),
        ] {
            let (dz, mismatched) = probe_differences(&reduced, other, points);
            let max = dz[dz.len() - 1];
            eprintln!(
                "{region}, {what}: {} points, {} base/top values, |Δz| median {:.2} max {:.2} m, type/source mismatches {mismatched}",
                points.len(),
                dz.len(),
                dz[dz.len() / 2],
                max
            );
            assert_eq!(mismatched, 0, "{region}, {what}");
            assert!(max <= 0.5, "{region}, {what}: {max}");
        }
        // What the reduction fixes: the full-resolution map, bilinear between pixels that
        // straddle grid lines, rounds the grid points' values by tens of metres.
        let (dz, _) = probe_differences(&full, &exact, &grid_points);
        eprintln!(
            "{region}, full resolution at grid points vs the grid: |Δz| median {:.2} max {:.2} m",
            dz[dz.len() / 2],
            dz[dz.len() - 1]
        );
    }
}

/// Write `plan`'s map into `dir` and load it.
fn plan_map(plan: Plan, dir: &tempfile::TempDir) -> CloudMap {
    let json = plan.write(&dir.path().join("g.png"), &|_| {}).unwrap();
    CloudMap::load(&json).unwrap()
}
