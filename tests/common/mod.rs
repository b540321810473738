//! Helpers the end-to-end tests share: running the binary, finding the sample data, ingesting
//! the synthetic sample, a folder's files; the temporal tests' synthetic deck ([`deck`]).
//! (Each test crate uses a part of it, hence the allow.)
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub mod deck;
pub mod series;

/// Run the `stratus` binary with `args`, logging only errors.
pub fn stratus(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stratus"))
        .args(args)
        .env("RUST_LOG", "error")
        .output()
        .expect("run stratus")
}

/// The command succeeded (its stderr otherwise).
pub fn ok(o: &Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Exit 2 with one stderr line holding `needle`, and no panic.
pub fn refused_one_line(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(needle), "expected {needle:?} in: {err}");
}

/// A path under `data-samples/` (the real GFS files and the synthetic sample, in the repository).
pub fn sample(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data-samples")
        .join(rel)
}

/// The North Atlantic pair (GFS 2.5°, 2015-09-12 18 UTC, +0 h and +6 h).
pub fn na_pair() -> [PathBuf; 2] {
    ["f000", "f006"].map(|f| sample(&format!("gfs-series/gfs.t18z.pgrb2.2p50.{f}")))
}

/// `ingest FILES… ARGS…`: its output.
pub fn ingest<P: AsRef<Path>>(files: &[P], args: &[&str]) -> Output {
    let mut a = vec!["ingest"];
    a.extend(files.iter().map(|f| f.as_ref().to_str().unwrap()));
    a.extend_from_slice(args);
    stratus(&a)
}

/// `ingest FILES… PLACE… --out OUT EXTRA…` (PLACE: `--region … --size …`): its output.
pub fn ingest_out<P: AsRef<Path>>(
    files: &[P],
    place: &[&str],
    out: &Path,
    extra: &[&str],
) -> Output {
    let mut a = place.to_vec();
    a.extend(["--out", out.to_str().unwrap()]);
    a.extend_from_slice(extra);
    ingest(files, &a)
}

/// Every file under `dir` (its path under `dir`) with its bytes.
pub fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut m = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            if e.file_type().unwrap().is_dir() {
                todo.push(e.path());
            } else {
                let rel = e.path().strip_prefix(dir).unwrap().to_path_buf();
                m.insert(rel, std::fs::read(e.path()).unwrap());
            }
        }
    }
    m
}

/// The real Poland series (GFS 0.25°, 2020-08-04 12 UTC, +0/+6/+12 h) ingested as issue 31
/// measures it: 48–56°N 13–25°E at 480×320, into `dir/pl.json`.
pub fn poland(dir: &Path) -> PathBuf {
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
    args.extend(files.iter().map(|f| f.to_str().unwrap()));
    args.extend_from_slice(&["--region", "48,56,13,25", "--size", "480x320"]);
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    let o = stratus(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join("pl.json")
}

/// Ingest the synthetic sample (30–60°N, 40°W–0°, 160×120, all layers) into `dir/m.png`,
/// returning the sidecar.
pub fn synthetic_map(dir: &Path) -> PathBuf {
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("data-samples/synthetic-gfs-rh.grib2");
    let png = dir.join("m.png");
    let o = stratus(&[
        "ingest",
        sample.to_str().unwrap(),
        "--region",
        "30,60,-40,0",
        "--size",
        "160x120",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join("m.json")
}

/// Ingest the real GFS sample (`data-samples/gfs/`, all layers) over `region` at `size` into
/// `dir/NAME.png`, returning the sidecar.
pub fn real_map(dir: &Path, name: &str, region: &str, size: &str) -> PathBuf {
    ingest_sample(
        dir,
        "gfs/gfs.t12z.pgrbf120.2p5deg.grib2",
        name,
        region,
        size,
    )
}

/// Ingest `data-samples/FILE` (all layers) over `region` at `size` into `dir/NAME.png`,
/// returning the sidecar.
pub fn ingest_sample(dir: &Path, file: &str, name: &str, region: &str, size: &str) -> PathBuf {
    let file = sample(file);
    let png = dir.join(format!("{name}.png"));
    let o = stratus(&[
        "ingest",
        file.to_str().unwrap(),
        "--region",
        region,
        "--size",
        size,
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join(format!("{name}.json"))
}

/// `probe --map MAP --at AT --json`, which must succeed, as JSON.
pub fn probe_json(map: &Path, at: &str) -> serde_json::Value {
    let o = stratus(&[
        "probe",
        "--map",
        map.to_str().unwrap(),
        "--at",
        at,
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}
