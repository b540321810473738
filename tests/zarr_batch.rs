//! The Zarr store's motion arrays and its batch calls through the binary (issue 32): a store
//! carries the motion a PNG series stores (a store-loaded series blends along exactly that
//! motion, written at once or by `--append`); `--plan`, `--step K`, `--motion K`, `--finish`
//! (in any order a cluster runs them) write every chunk a serial `ingest --out` writes, byte
//! for byte; a call outside the plan, of another run, region or run time, or before what it
//! needs is one line, exit 2, nothing written.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use common::{ok, refused_one_line, sample, stratus};
use stratus_ingest::series::Series;
use stratus_ingest::zarr::Store;

const NA: [&str; 4] = ["--region", "30,65,-60,10", "--size", "260x140"];

fn files() -> Vec<String> {
    ["f000", "f006"]
        .iter()
        .map(|f| {
            sample(&format!("gfs-series/gfs.t18z.pgrb2.2p50.{f}"))
                .to_string_lossy()
                .into_owned()
        })
        .collect()
}

/// `ingest FILES… ARGS…`: its output.
fn ingest(files: &[String], args: &[&str]) -> std::process::Output {
    let mut a = vec!["ingest"];
    a.extend(files.iter().map(String::as_str));
    a.extend_from_slice(args);
    stratus(&a)
}

/// Every file under `dir` (relative path) with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
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

/// Interval 0's motion of `s`, guarded, per layer.
fn motion_of(s: &Series) -> Vec<(Vec<f32>, Vec<f32>)> {
    let (a, b) = (s.step_map(0).unwrap(), s.step_map(1).unwrap());
    let m = s.motion(0, &a, &b).unwrap();
    m.layers.iter().map(|l| l.guarded_px()).collect()
}

#[test]
fn a_store_carries_the_png_series_motion_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let f = files();
    let png = dir.path().join("na.png");
    let mut args = NA.to_vec();
    args.extend(["--out", png.to_str().unwrap()]);
    ok(&ingest(&f, &args));
    let series = Series::load(&png.with_extension("json")).unwrap();
    assert!(
        series.meta.steps[0].motion.is_some(),
        "the PNG series stores motion"
    );
    let want = motion_of(&series);

    let whole = dir.path().join("whole.zarr");
    let appended = dir.path().join("appended.zarr");
    let mut args = NA.to_vec();
    args.extend(["--out", whole.to_str().unwrap()]);
    ok(&ingest(&f, &args));
    let mut args = NA.to_vec();
    args.extend(["--out", appended.to_str().unwrap()]);
    ok(&ingest(&f[..1], &args));
    args.push("--append");
    ok(&ingest(&f[1..], &args));
    for store in [&whole, &appended] {
        let s = Arc::new(Store::open(store).unwrap());
        let entry = s.series.steps[0].motion.clone().expect("a motion entry");
        assert_eq!(entry.u, "motion_u");
        let before = s.stats().chunks_read;
        let got = motion_of(&Arc::clone(&s).into_series().unwrap());
        // Read from the arrays (6 chunks besides the two maps), not estimated.
        assert!(s.stats().chunks_read > before, "{}", store.display());
        assert!(
            got == want,
            "{}: the motion is not the PNG series'",
            store.display()
        );
    }
    // The appended store is the one written at once, chunk for chunk.
    let (a, b) = (snapshot(&whole), snapshot(&appended));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        if !k.ends_with("zarr.json") {
            assert!(b[k] == *v, "{} differs", k.display());
        }
    }
}

#[test]
fn batch_calls_write_the_serial_store_and_refuse_what_is_not_the_plan() {
    let dir = tempfile::tempdir().unwrap();
    let f = files();
    let serial = dir.path().join("serial.zarr");
    let out = dir.path().join("b.zarr");
    let o = out.to_str().unwrap();
    let mut args = NA.to_vec();
    args.extend(["--out", serial.to_str().unwrap()]);
    ok(&ingest(&f, &args));

    let call = |files: &[String], extra: &[&str]| {
        let mut a = NA.to_vec();
        a.extend(["--out", o]);
        a.extend_from_slice(extra);
        ingest(files, &a)
    };
    ok(&call(&f, &["--plan", "--run", "r1"]));
    // A second run on the store is refused at its run folder; the store is unchanged.
    let planned = snapshot(&out);
    refused_one_line(
        &call(&f, &["--plan", "--run", "r2"]),
        "another batch run (r1)",
    );
    refused_one_line(
        &call(&f, &["--step", "0", "--run", "r2"]),
        "batch run r1, not r2",
    );
    refused_one_line(
        &call(&f, &["--step", "2", "--run", "r1"]),
        "outside the plan",
    );
    refused_one_line(
        &call(&f[..1], &["--step", "0", "--run", "r1"]),
        "not the plan's",
    );
    let mut other = vec!["--region", "30,65,-60,11", "--size", "260x140", "--out", o];
    other.extend(["--step", "0", "--run", "r1"]);
    refused_one_line(&ingest(&f, &other), "the plan is region");
    refused_one_line(
        &call(&[], &["--motion", "0", "--run", "r1"]),
        "step 0 is not written yet",
    );
    refused_one_line(&call(&[], &["--finish", "--run", "r1"]), "not written yet");
    // The store is not a Stratus map until the run finishes.
    let probe = stratus(&["probe", "--map", o, "--at", "50,-25"]);
    refused_one_line(&probe, "has not finished");
    assert!(snapshot(&out) == planned, "a refused call wrote something");

    // The steps in reverse order, as a cluster may run them; a step repeated (retried).
    ok(&call(&f, &["--step", "1", "--run", "r1"]));
    ok(&call(&f, &["--step", "0", "--run", "r1"]));
    ok(&call(&f, &["--step", "0", "--run", "r1"]));
    refused_one_line(
        &call(&[], &["--motion", "1", "--run", "r1"]),
        "outside the plan",
    );
    ok(&call(&[], &["--motion", "0", "--run", "r1"]));
    ok(&call(&[], &["--finish", "--run", "r1"]));
    assert!(
        !dir.path().join(".b.zarr.batch").exists(),
        "the run folder is removed"
    );
    let (a, b) = (snapshot(&serial), snapshot(&out));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        if !k.ends_with("zarr.json") || k.parent() != Some(Path::new("")) {
            assert!(b[k] == *v, "{} differs", k.display());
        }
    }
    // A finished store takes no more batch calls.
    refused_one_line(
        &call(&f, &["--step", "0", "--run", "r1"]),
        "has no batch plan",
    );
    ok(&stratus(&["probe", "--map", o, "--at", "50,-25"]));
}

#[test]
fn a_damaged_step_chunk_stops_the_motion_call_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let f = files();
    let out = dir.path().join("b.zarr");
    let o = out.to_str().unwrap();
    let call = |files: &[String], extra: &[&str]| {
        let mut a = NA.to_vec();
        a.extend(["--out", o]);
        a.extend_from_slice(extra);
        ingest(files, &a)
    };
    ok(&call(&f, &["--plan", "--run", "r"]));
    ok(&call(&f, &["--step", "0", "--run", "r"]));
    ok(&call(&f, &["--step", "1", "--run", "r"]));
    std::fs::write(out.join("coverage/c/1/0/0/0"), b"not gzip").unwrap();
    let before = snapshot(dir.path());
    refused_one_line(
        &call(&[], &["--motion", "0", "--run", "r"]),
        "coverage/c/1/0/0/0: damaged chunk",
    );
    assert!(
        snapshot(dir.path()) == before,
        "a refused call wrote something"
    );
    std::fs::remove_file(out.join("zarr.json")).unwrap();
    refused_one_line(
        &call(&f, &["--step", "0", "--run", "r"]),
        "zarr.json: missing",
    );
}
