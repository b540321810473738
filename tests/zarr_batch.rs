//! The Zarr store's motion arrays and its batch calls through the binary (issue 32): a store
//! carries the motion a PNG series stores (a store-loaded series blends along exactly that
//! motion, written at once or by `--append`); `--plan`, `--step K`, `--motion K`, `--finish`
//! (in any order a cluster runs them) write every chunk a serial `ingest --out` writes, byte
//! for byte; a call outside the plan, of another run, region or run time, or before what it
//! needs is one line, exit 2, nothing written.

mod common;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use common::{ingest, ingest_out, na_pair, ok, refused_one_line, snapshot, stratus};
use stratus_ingest::series::Series;
use stratus_ingest::zarr::Store;

const NA: [&str; 4] = ["--region", "30,65,-60,10", "--size", "260x140"];

/// Interval 0's motion of `s`, guarded, per layer.
fn motion_of(s: &Series) -> Vec<(Vec<f32>, Vec<f32>)> {
    let (a, b) = (s.step_map(0).unwrap(), s.step_map(1).unwrap());
    let m = s.motion(0, &a, &b).unwrap();
    m.layers.iter().map(|l| l.guarded_px()).collect()
}

#[test]
fn a_store_carries_the_png_series_motion_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let f = na_pair();
    let png = dir.path().join("na.png");
    ok(&ingest_out(&f, &NA, &png, &[]));
    let series = Series::load(&png.with_extension("json")).unwrap();
    assert!(
        series.meta.steps[0].motion.is_some(),
        "the PNG series stores motion"
    );
    let want = motion_of(&series);

    let whole = dir.path().join("whole.zarr");
    let appended = dir.path().join("appended.zarr");
    ok(&ingest_out(&f, &NA, &whole, &[]));
    ok(&ingest_out(&f[..1], &NA, &appended, &[]));
    ok(&ingest_out(&f[1..], &NA, &appended, &["--append"]));
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
    let f = na_pair();
    let serial = dir.path().join("serial.zarr");
    let out = dir.path().join("b.zarr");
    let o = out.to_str().unwrap();
    ok(&ingest_out(&f, &NA, &serial, &[]));

    let call = |files: &[PathBuf], extra: &[&str]| ingest_out(files, &NA, &out, extra);
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
    let f = na_pair();
    let out = dir.path().join("b.zarr");
    let call = |files: &[PathBuf], extra: &[&str]| ingest_out(files, &NA, &out, extra);
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
