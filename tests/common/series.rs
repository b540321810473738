//! Long series made cheaply from a real one: its step maps repeated at new forecast hours, each
//! step with its own step sidecar (a copy of the real step's with the new hour and valid time,
//! naming the same images), so each step's sidecar agrees with its entry in the series. A step
//! keeps the real step's motion images (issue 31): step k is real step k mod n and step k + 1
//! real step k mod n + 1 wherever the real step has a motion, so they are right; where it has
//! none (the real last step) the interval's motion is estimated at load.

use std::path::{Path, PathBuf};

use chrono::{DateTime, Duration, Utc};
use serde_json::Value;

fn read_json(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn write_json(p: &Path, v: &Value) {
    std::fs::write(p, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

/// Beside the series sidecar `real`, the series `NAME.json` of `n` steps `every_h` hours apart
/// from its run's analysis, step k the real series' step k mod (its steps). With
/// `mean_winds: false` the steps' recorded mean winds are left out, as in a sidecar written
/// before they were recorded.
pub fn repeated(real: &Path, name: &str, n: usize, every_h: f64, mean_winds: bool) -> PathBuf {
    let dir = real.parent().unwrap();
    let mut series = read_json(real);
    let real_steps = series["steps"].as_array().unwrap().clone();
    let t0 = DateTime::parse_from_rfc3339(series["reference_time"].as_str().unwrap())
        .unwrap()
        .with_timezone(&Utc);
    let steps: Vec<Value> = (0..n)
        .map(|k| {
            let hour = every_h * k as f64;
            let valid = (t0 + Duration::milliseconds((hour * 3.6e6).round() as i64))
                .format("%Y-%m-%dT%H:%M:%SZ")
                .to_string();
            let mut step = real_steps[k % real_steps.len()].clone();
            let mut sidecar = read_json(&dir.join(step["map"].as_str().unwrap()));
            sidecar["source"]["forecast_step_h"] = hour.into();
            sidecar["source"]["valid_time"] = valid.clone().into();
            let map = format!("{name}-step{k:04}.json");
            write_json(&dir.join(&map), &sidecar);
            step["forecast_hour"] = hour.into();
            step["valid_time"] = valid.into();
            step["map"] = map.into();
            if !mean_winds {
                step.as_object_mut().unwrap().remove("mean_wind");
            }
            if k + 1 == n {
                // The real step's motion is to the real step after it; the last step has none.
                step.as_object_mut().unwrap().remove("motion");
            }
            step
        })
        .collect();
    series["steps"] = steps.into();
    let path = dir.join(format!("{name}.json"));
    write_json(&path, &series);
    path
}

/// Give every interval of the series at `path` but the last its first interval's stored motion,
/// where it has none, so no interval is estimated at load (seconds each for a large map). For
/// tests of what the timeline holds and uploads, not of where the cloud goes: the borrowed
/// motion is the real +0 → +6 h one, wrong for a +6 → +0 h pair.
pub fn motion_everywhere(path: &Path) {
    let mut series = read_json(path);
    let steps = series["steps"].as_array_mut().unwrap();
    let first = steps[0]["motion"].clone();
    assert!(
        !first.is_null(),
        "the series' first step has no stored motion"
    );
    let n = steps.len();
    for step in steps.iter_mut().take(n - 1) {
        if step.get("motion").is_none() {
            step["motion"] = first.clone();
        }
    }
    write_json(path, &series);
}
