//! `stratus verify-interpolation` end to end through the binary (issue 31): the JSON the issue
//! names and its bar on the real +0/+6/+12 h Poland series, a three-step series made by
//! carrying a real map a known distance east (the motion must recover its middle step where
//! the cross-fade shows two ghosts), and the bad holds (one line naming the file, exit 2);
//! the motion stored with a series at ingest: damaged copies refused in one line (exit 2), a
//! series sidecar from before it still loading with the motion estimated.

mod common;

use std::path::{Path, PathBuf};

use chrono::Duration;
use common::{poland, real_map, sample, stratus};
use serde_json::Value;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::ExtraRole;
use stratus_ingest::series::meta::{SeriesLayer, StepWinds};
use stratus_ingest::series::{SeriesMeta, SeriesStep, SERIES_FORMAT};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
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
                motion: None,
            }
        })
        .collect();
    let series = SeriesMeta {
        format: SERIES_FORMAT.into(),
        reference_time: run,
        region: m.meta.region,
        width: m.meta.width,
        height: m.meta.height,
        layers: m.meta.layers.iter().map(SeriesLayer::from).collect(),
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

/// `probe` on `map` (with `--time`, the blend at +3 h): exit status and stderr.
fn probe(map: &Path, time: bool) -> (Option<i32>, String) {
    let mut args = vec!["probe", "--map", s(map), "--at", "52,19"];
    if time {
        args.extend_from_slice(&["--time", "2020-08-04T15:00:00Z"]);
    }
    let o = stratus(&args);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The series sidecar `map` with `edit` applied to its JSON, written beside it as `name`.
fn edited(map: &Path, name: &str, edit: impl Fn(&mut Value)) -> PathBuf {
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(map).unwrap()).unwrap();
    edit(&mut v);
    let p = map.with_file_name(name);
    std::fs::write(&p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    p
}

fn refused(map: &Path, time: bool, says: &[&str]) {
    let (code, err) = probe(map, time);
    assert_eq!(code, Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    for x in says {
        assert!(err.contains(x), "{x:?} not in: {err}");
    }
}

/// The motion images ingest writes (issue 31): a series whose motion images are missing, of the
/// wrong size, corrupt, or whose sidecar gives them a wrong size or an impossible scale is
/// refused in one line naming the file, exit 2; a sidecar from before them still loads (the
/// motion estimated, said in one info line).
#[test]
fn damaged_motion_images_are_one_line_and_exit_2_and_old_sidecars_load() {
    let dir = tempfile::tempdir().unwrap();
    let map = poland(dir.path());
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&map).unwrap()).unwrap();
    let steps = v["steps"].as_array().unwrap();
    assert_eq!(steps[0]["motion"]["u"], "pl-f000.motion-u.png");
    assert_eq!(steps[1]["motion"]["v"], "pl-f006.motion-v.png");
    assert!(steps[2].get("motion").is_none(), "the last step has none");
    let (code, err) = probe(&map, true);
    assert_eq!(code, Some(0), "{err}");

    let u0 = dir.path().join("pl-f000.motion-u.png");
    let v1 = dir.path().join("pl-f006.motion-v.png");
    let (keep_u0, keep_v1) = (std::fs::read(&u0).unwrap(), std::fs::read(&v1).unwrap());
    std::fs::remove_file(&u0).unwrap();
    refused(
        &map,
        false,
        &["pl.json", "step +0 h", "pl-f000.motion-u.png: missing"],
    );
    std::fs::write(&u0, &keep_u0).unwrap();

    // Another size than the sidecar says (a valid 16-bit RGBA PNG of 16×16).
    let mut small = Vec::new();
    stratus_ingest::cloudmap::encode_png16(&mut small, 16, 16, 4, &[0u8; 16 * 16 * 8]).unwrap();
    std::fs::write(&v1, &small).unwrap();
    refused(
        &map,
        false,
        &["step +6 h", "pl-f006.motion-v.png", "16x16", "240x160"],
    );
    // Corrupt pixel data behind a good header: found when the interval is decoded.
    std::fs::write(&v1, &keep_v1[..keep_v1.len() / 2]).unwrap();
    let (code, err) = probe(&map, false);
    assert_eq!(code, Some(0), "the header alone is checked at load: {err}");
    let later = edited(&map, "later.json", |v| {
        // The blend at +3 h reads the +0 → +6 h motion; make it the damaged one.
        v["steps"][0]["motion"] = v["steps"][1]["motion"].clone();
    });
    refused(
        &later,
        true,
        &["later.json", "pl-f006.motion-v.png", "corrupt"],
    );
    std::fs::write(&v1, &keep_v1).unwrap();

    for (name, field, value, says) in [
        (
            "scale.json",
            "scale",
            serde_json::json!(1.0e6),
            "steps[0].motion.scale",
        ),
        (
            "negative.json",
            "scale",
            serde_json::json!(-0.01),
            "steps[0].motion.scale",
        ),
        (
            "width.json",
            "width",
            serde_json::json!(480),
            "steps[0].motion: 480x160",
        ),
    ] {
        let bad = edited(&map, name, |v| {
            v["steps"][0]["motion"][field] = value.clone()
        });
        refused(&bad, false, &[name, says]);
    }

    // A series sidecar from before issue 31: no motion entries. It loads, the motion is
    // estimated, said once at info level; the blend is the stored one's up to quantisation.
    let old = edited(&map, "old.json", |v| {
        for s in v["steps"].as_array_mut().unwrap() {
            s.as_object_mut().unwrap().remove("motion");
        }
    });
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_stratus"))
        .args(["probe", "--map", s(&old), "--at", "52,19"])
        .args(["--time", "2020-08-04T15:00:00Z", "--json"])
        .env("RUST_LOG", "info")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let said: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("no motion images"))
        .collect();
    assert_eq!(said.len(), 1, "{err}");
    assert!(
        said[0].contains("old.json") && said[0].contains("estimated"),
        "{err}"
    );
    let a = stratus_ingest::series::Series::load(&map).unwrap();
    let b = stratus_ingest::series::Series::load(&old).unwrap();
    let t = a.steps()[0].valid_time + Duration::hours(3);
    let (ma, mb) = (a.at(t).unwrap(), b.at(t).unwrap());
    let worst = ma
        .texels
        .iter()
        .zip(&mb.texels)
        .flat_map(|(p, q)| (0..3).map(move |c| p[c].abs_diff(q[c])))
        .max()
        .unwrap();
    assert!(
        f64::from(worst) <= 0.01 * stratus_ingest::cloudmap::COVERAGE_FULL,
        "stored and estimated-at-load blends differ by {worst}"
    );
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

/// Measurement for docs/time.md (run with `--ignored --nocapture`): the cost of the motion at
/// the size of a 0.25° global step (1440×720 pixels; the real 2.5° sample ingested at that
/// size, its later step the same map carried 8 px east — the estimate's cost depends on the
/// map's size, not on its source's resolution): estimating it (what ingest adds per step),
/// writing and reading its images, and one CPU blend.
#[test]
#[ignore]
fn motion_cost_at_a_quarter_degree_global_size() {
    use stratus_ingest::series::{motion, stored};
    let dir = tempfile::tempdir().unwrap();
    let real = real_map(dir.path(), "globe", "-90,90,-180,180", "1440x720");
    let a = CloudMap::load(&real).unwrap();
    let mut b = carried(&a, 8);
    b.meta.source.valid_time = a.meta.source.valid_time.map(|t| t + Duration::hours(6));
    let t = std::time::Instant::now();
    let m = motion::estimate(&a, &b, 6.0 * 3600.0).unwrap();
    let est = t.elapsed().as_secs_f64();
    let (pu, pv) = (
        dir.path().join("g.motion-u.png"),
        dir.path().join("g.motion-v.png"),
    );
    let t = std::time::Instant::now();
    let entry = stored::write(&m, (&pu, &pv)).unwrap();
    let wr = t.elapsed().as_secs_f64();
    let bytes = std::fs::metadata(&pu).unwrap().len() + std::fs::metadata(&pv).unwrap().len();
    let t = std::time::Instant::now();
    let baked = m.baked();
    let blend = motion::blend(&a, &b, 0.5, 6.0 * 3600.0, &baked).unwrap();
    let bl = t.elapsed().as_secs_f64();
    let (dx, _, g) = baked.layers[2].summary();
    println!(
        "1440x720: estimate {est:.1} s; images {}x{} written in {wr:.3} s, {bytes} B; \
         CPU blend {bl:.2} s; high layer mean motion {dx:.2} px east (8 carried), guard {g:.2}; {} px",
        entry.width,
        entry.height,
        blend.width()
    );
}
