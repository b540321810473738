//! `stratus verify-interpolation` end to end through the binary (issue 31): the JSON the issue
//! names and its bar on the real +0/+6/+12 h Poland series, a three-step series made by
//! carrying a real map a known distance east (the motion must recover its middle step where
//! the cross-fade shows two ghosts), and the bad holds (one line naming the file, exit 2).

mod common;

use std::path::{Path, PathBuf};

use chrono::Duration;
use common::{real_map, sample, stratus};
use serde_json::Value;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::ExtraRole;
use stratus_ingest::series::meta::{SeriesLayer, StepWinds};
use stratus_ingest::series::{SeriesMeta, SeriesStep, SERIES_FORMAT};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The real Poland series (GFS 0.25°, 2020-08-04 12 UTC, +0/+6/+12 h) ingested as the issue
/// measures it: 48–56°N 13–25°E at 480×320.
fn poland(dir: &Path) -> PathBuf {
    let files: Vec<PathBuf> = ["f000", "f006", "f012"]
        .iter()
        .map(|f| {
            sample(&format!(
                "gfs-series-poland/gfs.20200804.t12z.pgrb2.0p25.{f}"
            ))
        })
        .collect();
    let out = dir.join("pl.png");
    let mut args = vec!["ingest"];
    args.extend(files.iter().map(|f| s(f)));
    args.extend_from_slice(&["--region", "48,56,13,25", "--size", "480x320"]);
    args.extend_from_slice(&["--out", s(&out)]);
    let o = stratus(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join("pl.json")
}

/// `verify-interpolation --json`, parsed, with the scores printed for the record.
fn verify(map: &Path, hold: &str) -> Value {
    let o = stratus(&[
        "verify-interpolation",
        "--map",
        s(map),
        "--hold",
        hold,
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    println!("{}: {v}", map.display());
    v
}

fn score(l: &Value, blend: &str) -> f64 {
    l[blend].as_f64().unwrap()
}

#[test]
fn on_the_poland_series_motion_is_nowhere_worse_and_better_where_clouds_moved() {
    let dir = tempfile::tempdir().unwrap();
    let map = poland(dir.path());
    let v = verify(&map, "6");
    assert_eq!(v["hold"].as_f64(), Some(6.0));
    let layers = v["layers"].as_array().unwrap();
    let kinds: Vec<&str> = layers.iter().map(|l| l["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["low", "middle", "high"]);
    for l in layers {
        assert_eq!(l.as_object().unwrap().len(), 4, "{l}");
        let (m, c, w) = (score(l, "motion"), score(l, "crossfade"), score(l, "wind"));
        assert!(m >= c - 0.005 && m >= w - 0.005, "{l}");
    }
    // The middle layer's clouds travel over these 12 h (the wind beats the cross-fade there
    // by 0.12): so must the motion.
    let mid = &layers[1];
    assert!(
        score(mid, "motion") > score(mid, "crossfade") + 0.05,
        "{mid}"
    );
}

/// Map `m` carried `px` pixels east (the region spans all longitudes, so what leaves in the
/// east comes back in the west: a real map carried round the globe).
fn carried(m: &CloudMap, px: usize) -> CloudMap {
    let (w, h) = (m.width(), m.height());
    let mut out = m.clone();
    for j in 0..h {
        for i in 0..w {
            out.texels[j * w + (i + px) % w] = m.texels[j * w + i];
        }
    }
    out
}

/// Beside `real` (a plain map of a region all round the globe), a series of three steps 6 h
/// apart, step k the map carried `px`·k pixels east, each step with its own images.
fn carried_series(real: &Path, px: usize) -> PathBuf {
    let dir = real.parent().unwrap();
    let m = CloudMap::load(real).unwrap();
    let src = &m.meta.source;
    let (run, hour0, valid0) = (
        src.reference_time.unwrap(),
        src.forecast_step_h,
        src.valid_time.unwrap(),
    );
    let steps = (0..3)
        .map(|k| {
            let mut step = carried(&m, px * k);
            let hour = hour0 + 6.0 * k as f64;
            let valid = valid0 + Duration::hours(6 * k as i64);
            step.meta.source.forecast_step_h = hour;
            step.meta.source.valid_time = Some(valid);
            let png = dir.join(format!("moved-{k}.png"));
            step.save(&png).unwrap();
            let saved =
                stratus_ingest::cloudmap::load_meta(&dir.join(format!("moved-{k}.json"))).unwrap();
            let image = |r| saved.extra(r).unwrap().image.clone();
            SeriesStep {
                forecast_hour: hour,
                valid_time: valid,
                map: format!("moved-{k}.json"),
                winds: Some(StepWinds {
                    u: image(ExtraRole::WindU),
                    v: image(ExtraRole::WindV),
                }),
                mean_wind: None,
            }
        })
        .collect();
    let series = SeriesMeta {
        format: SERIES_FORMAT.into(),
        reference_time: run,
        region: m.meta.region,
        width: m.meta.width,
        height: m.meta.height,
        layers: m
            .meta
            .layers
            .iter()
            .map(|l| SeriesLayer {
                kind: l.kind,
                channel: l.channel,
                levels_hpa: l.levels_hpa.clone(),
            })
            .collect(),
        steps,
    };
    let path = dir.join("moved.json");
    std::fs::write(&path, serde_json::to_string_pretty(&series).unwrap()).unwrap();
    path
}

#[test]
fn a_map_carried_a_known_distance_is_recovered_at_its_middle_step() {
    let dir = tempfile::tempdir().unwrap();
    // The real GFS sample all round the globe, 60°S–60°N at 0.5° a pixel.
    let real = real_map(dir.path(), "globe", "-60,60,-180,180", "720x240");
    // 8 px = 4° of longitude per 6 h: 445 km at the equator, 314 km at 45°.
    let series = carried_series(&real, 8);
    let v = verify(&series, &format!("{}", 120 + 6));
    for l in v["layers"].as_array().unwrap() {
        let (m, c) = (score(l, "motion"), score(l, "crossfade"));
        assert!(m >= 0.95, "{l}");
        // The cross-fade shows the clouds twice, 8° apart, each half-covered.
        assert!(c < m - 0.05, "{l}");
    }
}

#[test]
fn a_hold_without_a_step_either_side_is_one_line_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let map = poland(dir.path());
    for (hold, says) in [("0", "first"), ("12", "last"), ("3", "no step at +3 h")] {
        let o = stratus(&["verify-interpolation", "--map", s(&map), "--hold", hold]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "--hold {hold}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "--hold {hold}: {err}");
        assert!(
            err.contains(s(&map)) && err.contains(says),
            "--hold {hold}: {err}"
        );
        assert!(o.stdout.is_empty());
    }
}

/// Measurement for docs/time.md (run with `--ignored --nocapture`): on the two-step North
/// Atlantic series and each pair of the Poland series, the earlier step carried along the
/// motion estimated between the pair, against the later step (a fit, the motion having seen
/// the later step), beside `verify-advection`'s wind and persistence; the mean guard per layer.
#[test]
#[ignore]
fn motion_fit_on_the_real_pairs() {
    use stratus::score::{compare, MAP_THRESHOLD};
    use stratus_ingest::cloudmap::COVERAGE_FULL;
    use stratus_ingest::series::{advect, motion, Series};
    let dir = tempfile::tempdir().unwrap();
    let na_files = [
        sample("gfs-series/gfs.t18z.pgrb2.2p50.f000"),
        sample("gfs-series/gfs.t18z.pgrb2.2p50.f006"),
    ];
    let out = dir.path().join("na.png");
    let o = stratus(&[
        "ingest",
        s(&na_files[0]),
        s(&na_files[1]),
        "--region",
        "30,70,-60,40",
        "--size",
        "1024x512",
        "--out",
        s(&out),
    ]);
    assert!(o.status.success());
    let mask = |m: &CloudMap, c: usize| -> Vec<bool> {
        let t = MAP_THRESHOLD as f64 * COVERAGE_FULL;
        m.texels.iter().map(|x| x[c] as f64 > t).collect()
    };
    let na = Series::load(&dir.path().join("na.json")).unwrap();
    let pl = Series::load(&poland(dir.path())).unwrap();
    for (name, series, k0, k1) in [
        ("na +0→+6", &na, 0, 1),
        ("pl +0→+6", &pl, 0, 1),
        ("pl +6→+12", &pl, 1, 2),
        ("pl +0→+12", &pl, 0, 2),
    ] {
        let (a, b) = (series.step_map(k0).unwrap(), series.step_map(k1).unwrap());
        let dt = 3600.0 * (series.steps()[k1].forecast_hour - series.steps()[k0].forecast_hour);
        let t = std::time::Instant::now();
        let m = motion::estimate(&a, &b, dt).unwrap();
        let est = t.elapsed().as_secs_f64();
        let (moved, wind) = (motion::carried(&a, &m), advect(&a, dt));
        for l in &m.layers {
            let truth = mask(&b, l.channel);
            let d = |x: &CloudMap| compare(&mask(x, l.channel), &truth).dice;
            let (dx, dy, g) = l.summary();
            println!(
                "{name} {}: motion fit {:.4} wind {:.4} persistence {:.4}; mean guard {g:.2}, mean guarded motion ({dx:.1}, {dy:.1}) px; estimate {est:.2} s",
                l.kind.name(),
                d(&moved),
                d(&wind),
                d(&a)
            );
        }
    }
}
