//! A CloudMap series end to end through the binary, on the two real GFS steps (+0 h, +6 h of
//! the 2015-09-12 18 UTC run): ingest of several files, the series sidecar, `probe --time`,
//! `verify-advection`, and every bad input the issue lists (exit 2, one line naming the file,
//! nothing written).

mod common;

use std::path::{Path, PathBuf};

use common::{sample, stratus};
use stratus_ingest::cloudmap::CloudMap;

const REGION: [&str; 4] = ["--region", "30,70,-60,40", "--size", "256x128"];

/// The two series files, or `None` (with the reason printed) (a test fails where they are absent).
fn steps() -> Option<(PathBuf, PathBuf)> {
    let f0 = sample("gfs-series/gfs.t18z.pgrb2.2p50.f000");
    let f6 = sample("gfs-series/gfs.t18z.pgrb2.2p50.f006");
    if f0.is_file() && f6.is_file() {
        Some((f0, f6))
    } else {
        panic!("{} not found (data-samples/gfs-series)", f0.display())
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn ingest(files: &[&Path], out: &Path) -> std::process::Output {
    let mut args = vec!["ingest"];
    args.extend(files.iter().map(|f| s(f)));
    args.extend_from_slice(&REGION);
    args.extend_from_slice(&["--out", s(out)]);
    stratus(&args)
}

fn names_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Exit 2, one stderr line that names `file` and says `what`.
fn assert_refused(o: &std::process::Output, file: &Path, what: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.contains(s(file)), "names {}: {err}", file.display());
    assert!(err.contains(what), "says {what:?}: {err}");
}

#[test]
fn the_real_steps_round_trip_as_a_series() {
    let Some((f0, f6)) = steps() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("na.png");
    let o = ingest(&[&f0, &f6], &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut want = vec!["na.json".to_string()];
    for step in ["na-f000", "na-f006"] {
        for suffix in [
            ".base.png",
            ".ground-water.png",
            ".ground.png",
            ".json",
            ".png",
            ".top.png",
            ".type.png",
            ".wind-u.png",
            ".wind-v.png",
        ] {
            want.push(format!("{step}{suffix}"));
        }
    }
    // The motion from +0 h to +6 h (issue 31): on the first step only.
    want.extend(["na-f000.motion-u.png".into(), "na-f000.motion-v.png".into()]);
    want.sort();
    assert_eq!(names_in(dir.path()), want);

    let series: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("na.json")).unwrap())
            .unwrap();
    assert_eq!(series["format"], "stratus-cloudmap-series/1");
    assert_eq!(series["reference_time"], "2015-09-12T18:00:00Z");
    let st = series["steps"].as_array().unwrap();
    assert_eq!(st.len(), 2);
    assert_eq!(st[1]["forecast_hour"], 6.0);
    assert_eq!(st[1]["valid_time"], "2015-09-13T00:00:00Z");
    assert_eq!(st[1]["map"], "na-f006.json");
    assert_eq!(st[1]["winds"]["u"], "na-f006.wind-u.png");
    assert_eq!(st[1]["winds"]["v"], "na-f006.wind-v.png");
    assert_eq!(st[0]["motion"]["u"], "na-f000.motion-u.png");
    assert_eq!(st[0]["motion"]["width"], 256);
    assert!(st[1].get("motion").is_none());
    let kinds: Vec<&str> = series["layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["low", "middle", "high"]);

    // Each step map is exactly what a single-file ingest of its file makes.
    let single = dir.path().join("single");
    std::fs::create_dir(&single).unwrap();
    let o = ingest(&[&f6], &single.join("one.png"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let one = CloudMap::load(&single.join("one.json")).unwrap();
    assert_eq!(
        one.meta.format, "stratus-cloudmap/3",
        "one file, one step: a plain map"
    );
    let step = CloudMap::load(&dir.path().join("na-f006.json")).unwrap();
    assert_eq!(step.texels, one.texels);
    assert_eq!(step.structure, one.structure);
    assert_eq!(step.meta.layers, one.meta.layers);

    // --map takes the series: without a time its first step, with one the moment.
    let probe = |map: &Path, time: Option<&str>| {
        let mut args = vec!["probe", "--map", s(map), "--at", "50,-20", "--json"];
        if let Some(t) = time {
            args.extend(["--time", t]);
        }
        let o = stratus(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    let series_json = dir.path().join("na.json");
    assert_eq!(
        probe(&series_json, None),
        probe(&dir.path().join("na-f000.json"), None)
    );
    assert_eq!(
        probe(&series_json, Some("2015-09-13T00:00:00Z")),
        probe(&dir.path().join("na-f006.json"), None)
    );
    let mid = probe(&series_json, Some("2015-09-12T21:00:00Z"));
    assert_eq!(mid["layers"].as_array().unwrap().len(), 3);
}

#[test]
fn verify_advection_prints_the_json_the_issue_names() {
    let Some((f0, f6)) = steps() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("na.png");
    assert!(ingest(&[&f0, &f6], &out).status.success());
    let map = dir.path().join("na.json");
    let o = stratus(&[
        "verify-advection",
        "--map",
        s(&map),
        "--from",
        "0",
        "--to",
        "6",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let top: Vec<&String> = v.as_object().unwrap().keys().collect();
    assert_eq!(top, ["layers"]);
    let layers = v["layers"].as_array().unwrap();
    let kinds: Vec<&str> = layers.iter().map(|l| l["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["low", "middle", "high"]);
    for l in layers {
        let mut keys: Vec<&String> = l.as_object().unwrap().keys().collect();
        keys.sort();
        assert_eq!(keys, ["advected", "kind", "persistence"]);
        for k in ["advected", "persistence"] {
            let d = l[k].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&d), "{k} {d}");
        }
        // Carrying the clouds changes them: advected and persistence are not the same map.
        assert_ne!(l["advected"], l["persistence"]);
    }
    // A step the series does not have is named with the ones it has.
    let o = stratus(&[
        "verify-advection",
        "--map",
        s(&map),
        "--from",
        "0",
        "--to",
        "12",
    ]);
    assert_refused(&o, &map, "no step at +12 h; the series has +0 h, +6 h");
}

#[test]
fn files_that_are_not_one_series_are_refused_and_nothing_is_written() {
    let Some((f0, f6)) = steps() else { return };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let other_grid = root.join("data-samples/synthetic-gfs-rh.grib2");
    let other_run = root.join("data-samples/gfs-2011011012-f120-2p5.grib2");
    let cases: [(&[&Path], &Path, &str); 4] = [
        (&[&f0, &other_grid], &other_grid, "a series is one grid"),
        (&[&f0, &other_run], &other_run, "a series is one run"),
        (&[&f0, &f6, &f6], &f6, "step +6 h is duplicated"),
        (&[&f6, &f0], &f0, "steps out of order"),
    ];
    for (files, named, what) in cases {
        let dir = tempfile::tempdir().unwrap();
        let o = ingest(files, &dir.path().join("na.png"));
        assert_refused(&o, named, what);
        assert_eq!(names_in(dir.path()), Vec::<String>::new(), "{what}");
    }
    // The order message gives the order expected.
    let dir = tempfile::tempdir().unwrap();
    let o = ingest(&[&f6, &f0], &dir.path().join("na.png"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!("increasing forecast hour: {} {}", s(&f0), s(&f6))),
        "{err}"
    );
}

#[test]
fn a_series_whose_step_maps_are_missing_is_refused() {
    let Some((f0, f6)) = steps() else { return };
    let dir = tempfile::tempdir().unwrap();
    assert!(ingest(&[&f0, &f6], &dir.path().join("na.png"))
        .status
        .success());
    let map = dir.path().join("na.json");
    for (gone, what) in [
        ("na-f006.wind-u.png", "missing"),
        ("na-f006.json", "cannot read"),
    ] {
        std::fs::remove_file(dir.path().join(gone)).unwrap();
        let before = names_in(dir.path());
        let o = stratus(&["probe", "--map", s(&map), "--at", "50,-20"]);
        assert_refused(&o, &dir.path().join(gone), what);
        assert!(String::from_utf8_lossy(&o.stderr).contains(s(&map)));
        let o = stratus(&[
            "verify-advection",
            "--map",
            s(&map),
            "--from",
            "0",
            "--to",
            "6",
        ]);
        assert_refused(&o, &dir.path().join(gone), what);
        assert_eq!(names_in(dir.path()), before, "nothing written");
    }
}

/// The two real steps ingested as a series into `dir`; its sidecar.
fn ingested(dir: &Path) -> PathBuf {
    let Some((f0, f6)) = steps() else {
        unreachable!()
    };
    let o = ingest(&[&f0, &f6], &dir.join("na.png"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join("na.json")
}

/// Rewrite the JSON file `path` through `edit`.
fn edit_json(path: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

fn probe_series(map: &Path) -> std::process::Output {
    stratus(&["probe", "--map", s(map), "--at", "50,-20"])
}

fn verify(map: &Path) -> std::process::Output {
    stratus(&[
        "verify-advection",
        "--map",
        s(map),
        "--from",
        "0",
        "--to",
        "6",
    ])
}

/// Issue 28 #5: each step's own sidecar says which step it is; a series whose `map` entries
/// were swapped would show +6 h at +0 h and advect +6 h onto +0 h.
#[test]
fn a_series_whose_map_entries_are_swapped_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let map = ingested(dir.path());
    edit_json(&map, |v| {
        let first = v["steps"][0]["map"].take();
        v["steps"][0]["map"] = v["steps"][1]["map"].take();
        v["steps"][1]["map"] = first;
    });
    for o in [probe_series(&map), verify(&map)] {
        assert_refused(&o, &map, "step +0 h: ");
        assert_refused(&o, &dir.path().join("na-f006.json"), "it is the +6 h step");
    }
    // The winds named for a step must be that step's too.
    let dir = tempfile::tempdir().unwrap();
    let map = ingested(dir.path());
    let dir = dir.path();
    edit_json(&map, |v| {
        let first = v["steps"][0]["winds"].take();
        v["steps"][0]["winds"] = v["steps"][1]["winds"].take();
        v["steps"][1]["winds"] = first;
    });
    assert_refused(
        &probe_series(&map),
        &dir.join("na-f000.json"),
        "wind images",
    );
}

/// Issue 28 #12: steps are whole minutes after the run (so at least a minute apart), refused
/// at series load and at ingest, one line naming the file.
#[test]
fn steps_less_than_a_minute_apart_are_refused() {
    let Some((f0, _)) = steps() else { return };
    let dir = tempfile::tempdir().unwrap();
    let map = ingested(dir.path());
    edit_json(&map, |v| {
        v["steps"][1]["forecast_hour"] = 0.0002.into();
        v["steps"][1]["valid_time"] = "2015-09-12T18:00:01Z".into();
    });
    for o in [probe_series(&map), verify(&map)] {
        assert_refused(&o, &map, "not a whole number of minutes");
    }
    let o = stratus(&[
        "render",
        "--map",
        s(&map),
        "--time",
        "2015-09-12T18:00:00Z",
        "--camera",
        "50,-20,9000",
        "--size",
        "16x9",
        "--preset",
        "fast",
        "--out",
        s(&dir.path().join("f.png")),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.lines()
            .any(|l| l.contains(s(&map)) && l.contains("not a whole number of minutes")),
        "{err}"
    );

    // At ingest: the +0 h file beside a copy of it whose steps read 1 s (GRIB's unit of
    // seconds), so the two are 1/3600 h apart.
    let one_second = dir.path().join("f000-plus-1s.grib2");
    std::fs::write(
        &one_second,
        with_step_in_seconds(&std::fs::read(&f0).unwrap(), 1),
    )
    .unwrap();
    let out = tempfile::tempdir().unwrap();
    let o = ingest(&[&f0, &one_second], &out.path().join("na.png"));
    assert_refused(&o, &one_second, "not a whole number of minutes");
    assert_eq!(names_in(out.path()), Vec::<String>::new());
}

/// `bytes` (a GRIB2 file) with every message's product definition (templates 4.0–4.15)
/// stating its forecast time as `seconds` in GRIB's unit of seconds (code table 4.4: 13).
fn with_step_in_seconds(bytes: &[u8], seconds: u32) -> Vec<u8> {
    let mut b = bytes.to_vec();
    let mut at = 0;
    while let Some(k) = b[at..].windows(4).position(|w| w == b"GRIB") {
        let start = at + k;
        let total = u64::from_be_bytes(b[start + 8..start + 16].try_into().unwrap()) as usize;
        let mut sec = start + 16;
        while sec + 5 <= start + total && &b[sec..sec + 4] != b"7777" {
            let len = u32::from_be_bytes(b[sec..sec + 4].try_into().unwrap()) as usize;
            let template = u16::from_be_bytes([b[sec + 7], b[sec + 8]]);
            if b[sec + 4] == 4 && template <= 15 {
                b[sec + 17] = 13;
                b[sec + 18..sec + 22].copy_from_slice(&seconds.to_be_bytes());
            }
            sec += len;
        }
        at = start + total;
    }
    b
}

/// Issue 28 #15: a series sidecar that is not JSON says so, with serde's line and column,
/// not what a map sidecar would miss ("missing field rh_cr").
#[test]
fn a_series_that_is_not_json_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let map = ingested(dir.path());
    let text = std::fs::read_to_string(&map).unwrap();
    let broken = format!(
        "{},\n}}\n",
        text.trim_end().trim_end_matches('}').trim_end()
    );
    std::fs::write(&map, broken).unwrap();
    for o in [probe_series(&map), verify(&map)] {
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!err.contains("missing field"), "{err}");
        assert_refused(&o, &map, "not valid JSON");
        assert!(err.contains(" line ") && err.contains(" column "), "{err}");
    }
}

/// Run stratus with `args`, failing (after killing it) if it has not ended within 60 s.
fn stratus_within(args: &[&str]) -> std::process::Output {
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_stratus"))
        .args(args)
        .env("RUST_LOG", "error")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(60) {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("stratus {args:?} still running after 60 s: it waits on a FIFO");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

fn mkfifo(path: &Path) {
    std::fs::remove_file(path).ok();
    let o = std::process::Command::new("mkfifo")
        .arg(path)
        .output()
        .unwrap();
    assert!(o.status.success(), "mkfifo: {o:?}");
}

/// Issue 28 #14: a FIFO given as `--map`, as a step's sidecar or as a map's PNG is refused at
/// once (one line naming it), never waited on.
#[cfg(unix)]
#[test]
fn fifos_among_a_maps_files_are_refused_not_waited_on() {
    let Some((_, f6)) = steps() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.json");
    mkfifo(&fifo);
    let o = stratus_within(&["probe", "--map", s(&fifo), "--at", "50,-20"]);
    assert_refused(&o, &fifo, "a FIFO (named pipe), not a regular file");

    // A plain map whose PNG is a FIFO.
    let one = dir.path().join("one");
    std::fs::create_dir(&one).unwrap();
    assert!(ingest(&[&f6], &one.join("m.png")).status.success());
    mkfifo(&one.join("m.png"));
    let o = stratus_within(&["probe", "--map", s(&one.join("m.json")), "--at", "50,-20"]);
    assert_refused(&o, &one.join("m.png"), "FIFO");

    // A series whose second step's sidecar is a FIFO.
    let map = ingested(dir.path());
    mkfifo(&dir.path().join("na-f006.json"));
    let o = stratus_within(&["probe", "--map", s(&map), "--at", "50,-20"]);
    assert_refused(&o, &dir.path().join("na-f006.json"), "FIFO");
    assert!(String::from_utf8_lossy(&o.stderr).contains(s(&map)));
}
