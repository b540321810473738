//! `stratus render` through the binary: a real frame, and every bad input a clear one-line
//! error with exit code 2 and no output file.

mod common;
use common::{stratus, synthetic_map};

use std::path::Path;

fn render(map: &Path, camera: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut a = vec![
        "render",
        "--map",
        map.to_str().unwrap(),
        "--camera",
        camera,
        "--heading",
        "45",
        "--pitch",
        "-12",
        "--size",
        "64x36",
        "--preset",
        "fast",
        "--out",
        out.to_str().unwrap(),
    ];
    a.extend_from_slice(extra);
    stratus(&a)
}

fn refused(o: &std::process::Output, needle: &str, out: &Path) {
    let err = String::from_utf8_lossy(&o.stderr);
    // Mesa's Wayland probe prints "XDG_RUNTIME_DIR is invalid" on machines without a display
    // session; that is the driver's, not ours.
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("error") && !l.contains("XDG_RUNTIME_DIR"))
        .collect();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(lines.len(), 1, "{err}");
    assert!(lines[0].contains(needle), "wanted \"{needle}\" in: {err}");
    assert!(!out.exists(), "nothing may be written on error");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn renders_a_frame_with_timings() {
    let dir = tempfile::tempdir().unwrap();
    let map = synthetic_map(dir.path());
    let out = dir.path().join("f.png");
    let o = render(&map, "45.5,-22,12000", &out, &["--timings"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (64, 36));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("march") && stdout.contains("per pixel"),
        "{stdout}"
    );
    // The synthetic sample has cirrus but no wind, no cumulus, no cumulonimbus: no genus code.
    assert!(stdout.contains("genus code in the march: none"), "{stdout}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("adapter"));
}

#[test]
fn bad_inputs_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = synthetic_map(d);
    let out = d.join("f.png");
    // Missing sidecar.
    refused(
        &render(&d.join("nope.json"), "45,-22,9000", &out, &[]),
        "nope.json",
        &out,
    );
    // Malformed sidecar.
    let bad = d.join("bad.json");
    std::fs::write(&bad, "{ not json").unwrap();
    refused(&render(&bad, "45,-22,9000", &out, &[]), "bad.json", &out);
    // A PNG whose size disagrees with its sidecar.
    let text = std::fs::read_to_string(&map)
        .unwrap()
        .replace("\"width\": 160", "\"width\": 161");
    let lying = d.join("lying.json");
    std::fs::write(&lying, text).unwrap();
    refused(
        &render(&lying, "45,-22,9000", &out, &[]),
        "sidecar says 161x120",
        &out,
    );
    // Camera below the ground.
    refused(
        &render(&map, "45,-22,-10", &out, &[]),
        "below the ground",
        &out,
    );
    // Sun direction of zero length.
    refused(
        &render(&map, "45,-22,9000", &out, &["--sun-dir", "0,0,0"]),
        "zero length",
        &out,
    );
    // Unreadable camera and time.
    refused(&render(&map, "45,-22", &out, &[]), "--camera", &out);
    refused(
        &render(&map, "45,-22,9000", &out, &["--time", "yesterday"]),
        "ISO 8601",
        &out,
    );
    // No such adapter.
    refused(
        &render(&map, "45,-22,9000", &out, &["--adapter", "no-such-gpu-xyz"]),
        "no adapter matches",
        &out,
    );
}

/// Issue 28 #7 and #15: `--camera` reads its point with the one LAT,LON parser (latitude
/// within ±90, longitude within ±360), and a camera under the ground says how far under
/// (500 m below ground at 0 m, not "at -500 m … (0 m)"); huge numbers are echoed compactly.
#[test]
fn camera_points_and_depths_are_checked_and_said_plainly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = synthetic_map(d);
    let out = d.join("f.png");
    refused(
        &render(&map, "45,1000,9000", &out, &[]),
        "--camera \"45,1000,9000\": longitude 1000 is outside -360..360",
        &out,
    );
    refused(
        &render(&map, "91,-22,9000", &out, &[]),
        "--camera \"91,-22,9000\": latitude 91 is outside -90..90",
        &out,
    );
    refused(
        &render(&map, "45,-22,-500", &out, &[]),
        "the camera at -500 m is 500 m below the ground there, which is at 0 m",
        &out,
    );
    refused(
        &render(&map, "45,-22,-1e308", &out, &[]),
        "the camera at -1e308 m is 1e308 m below the ground",
        &out,
    );
    refused(
        &render(&map, "45,-22,1e308", &out, &[]),
        "altitude 1e308 m is above the 10000000 m limit",
        &out,
    );
}
