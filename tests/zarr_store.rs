//! The Zarr v3 store end to end through the binary (issue 32): a store written by `ingest
//! --out STORE.zarr` equals the PNG maps of the same steps value for value (coverage,
//! structure, ground, the sidecar's content); `--append` adds a later step and gives the store
//! a run at once gives; `probe` reads only a few chunks; bad input (another region or run to
//! `--append`, a damaged chunk, missing metadata) is one line, exit 2, nothing written.

mod common;

use std::path::Path;

use common::{ingest_out, na_pair, ok, refused_one_line, sample, snapshot, stratus};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::zarr::Store;

const NA: [&str; 4] = ["--region", "30,65,-60,10", "--size", "1300x700"];

/// `ingest FILES NA --out OUT EXTRA…`: its output.
fn ingest(files: &[&Path], out: &Path, extra: &[&str]) -> std::process::Output {
    ingest_out(files, &NA, out, extra)
}

/// The two maps hold the same values; their sidecars the same content (the image id, which
/// binds a PNG set's files, aside).
fn assert_same_map(a: &CloudMap, b: &CloudMap, what: &str) {
    assert!(a.texels == b.texels, "{what}: coverage differs");
    assert!(a.structure.is_some(), "{what}: no structure");
    assert!(a.structure == b.structure, "{what}: structure differs");
    assert!(a.ground.is_some(), "{what}: no ground");
    assert!(a.ground == b.ground, "{what}: ground differs");
    let (mut ma, mut mb) = (a.meta.clone(), b.meta.clone());
    ma.image_id = None;
    mb.image_id = None;
    // A store's steps name their images `step-fHHH…`, the PNG set's `NAME-fHHH…`.
    let text = |m| {
        serde_json::to_string(&m)
            .unwrap()
            .replace("\"na-f", "\"step-f")
    };
    assert_eq!(text(ma), text(mb), "{what}: sidecar");
}

#[test]
fn the_store_equals_the_png_maps_value_for_value_and_probe_reads_little() {
    let dir = tempfile::tempdir().unwrap();
    let [f0, f6] = na_pair();
    let (store, png) = (dir.path().join("na.zarr"), dir.path().join("na.png"));
    ok(&ingest(&[&f0, &f6], &store, &[]));
    ok(&ingest(&[&f0, &f6], &png, &[]));
    let s = Store::open(&store).unwrap();
    assert_eq!(s.steps.len(), 2);
    for (k, tag) in ["f000", "f006"].iter().enumerate() {
        let from_png = CloudMap::load(&dir.path().join(format!("na-{tag}.json"))).unwrap();
        assert_same_map(&s.read_step(k).unwrap(), &from_png, tag);
    }
    // Through every `--map` command's scene: a step, and a moment between the steps.
    let between = "2015-09-12T21:00:00Z";
    for at in ["50,-25", "31,-59", "64.9,9.9"] {
        // A moment between the steps (the blend reads both steps whole) at one point only.
        let times: &[Option<&str>] = match at {
            "50,-25" => &[None, Some("2015-09-13T00:00:00Z"), Some(between)],
            _ => &[None, Some("2015-09-13T00:00:00Z")],
        };
        for &time in times {
            let probe = |map: &Path| {
                let mut args = vec![
                    "probe",
                    "--map",
                    map.to_str().unwrap(),
                    "--at",
                    at,
                    "--json",
                ];
                if let Some(t) = time {
                    args.extend(["--time", t]);
                }
                let o = stratus(&args);
                ok(&o);
                serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
            };
            let mut z = probe(&store);
            let read = z.as_object_mut().unwrap().remove("store").unwrap();
            assert_eq!(z, probe(&dir.path().join("na.json")), "{at} {time:?}");
            let (bytes, size) = (
                read["bytes_read"].as_u64().unwrap(),
                read["store_bytes"].as_u64().unwrap(),
            );
            assert!(bytes > 0 && bytes <= size, "{read}");
            if time != Some(between) {
                // At a step: a few chunks around the point, not the store.
                assert!(bytes * 4 < size, "{at}: read {read}");
            }
        }
    }
}

#[test]
fn append_adds_a_later_step_and_refuses_what_is_not_one() {
    let dir = tempfile::tempdir().unwrap();
    let [f0, f6] = na_pair();
    let (whole, grown) = (dir.path().join("whole.zarr"), dir.path().join("grown.zarr"));
    ok(&ingest(&[&f0, &f6], &whole, &[]));
    ok(&ingest(&[&f0], &grown, &[]));
    assert_eq!(Store::open(&grown).unwrap().steps.len(), 1);
    ok(&ingest(&[&f6], &grown, &["--append"]));
    let (a, b) = (Store::open(&whole).unwrap(), Store::open(&grown).unwrap());
    assert_eq!(a.series, b.series);
    for k in 0..2 {
        assert_same_map(
            &b.read_step(k).unwrap(),
            &a.read_step(k).unwrap(),
            "appended",
        );
    }

    let before = snapshot(dir.path());
    // The same step again, an earlier one, another region, another run: refused, untouched.
    refused_one_line(
        &ingest(&[&f6], &grown, &["--append"]),
        "not after the store's last step",
    );
    let mut args = vec!["ingest", f6.to_str().unwrap(), "--region", "30,60,-60,10"];
    args.extend([
        "--size",
        "1300x700",
        "--out",
        grown.to_str().unwrap(),
        "--append",
    ]);
    refused_one_line(&stratus(&args), "a store is one region and size");
    let other_run = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    refused_one_line(
        &ingest(&[&other_run], &grown, &["--append"]),
        "a store is one run",
    );
    // Without --append an existing store is never replaced.
    refused_one_line(&ingest(&[&f6], &grown, &[]), "give --append");
    assert!(
        before == snapshot(dir.path()),
        "a refused write changed files"
    );
}

#[test]
fn racing_appends_are_serialised() {
    let dir = tempfile::tempdir().unwrap();
    let [f0, f6] = na_pair();
    let store = dir.path().join("race.zarr");
    ok(&ingest(&[&f0], &store, &[]));
    let run = || {
        let (f6, store) = (f6.clone(), store.clone());
        std::thread::spawn(move || ingest(&[&f6], &store, &["--append"]))
    };
    let (a, b) = (run(), run());
    let (a, b) = (a.join().unwrap(), b.join().unwrap());
    let codes = [a.status.code(), b.status.code()];
    assert!(
        codes.contains(&Some(0)) && codes.contains(&Some(2)),
        "{codes:?}"
    );
    let loser = if a.status.success() { &b } else { &a };
    refused_one_line(loser, "not after the store's last step");
    let s = Store::open(&store).unwrap();
    assert_eq!(s.steps.len(), 2);
    s.read_step(1).unwrap();
}

#[test]
fn a_damaged_or_incomplete_store_is_one_line_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let [f0, _] = na_pair();
    let store = dir.path().join("d.zarr");
    ok(&ingest(&[&f0], &store, &[]));
    let map = store.to_str().unwrap();
    let probe = || stratus(&["probe", "--map", map, "--at", "50,-25"]);
    ok(&probe());
    // A damaged chunk the probe reads (the point's coverage chunk).
    let chunk = store.join("coverage/c/0/0/0/1");
    let good = std::fs::read(&chunk).unwrap();
    std::fs::write(&chunk, &good[..good.len() / 2]).unwrap();
    refused_one_line(&probe(), "damaged chunk");
    std::fs::write(&chunk, b"not gzip").unwrap();
    refused_one_line(&probe(), "coverage/c/0/0/0/1");
    std::fs::remove_file(&chunk).unwrap();
    refused_one_line(&probe(), "chunk missing");
    std::fs::write(&chunk, &good).unwrap();
    ok(&probe());
    // Missing metadata: an array's, the group's.
    let meta = store.join("cloud_base/zarr.json");
    std::fs::rename(&meta, dir.path().join("saved.json")).unwrap();
    refused_one_line(&probe(), "cloud_base/zarr.json: missing");
    std::fs::rename(dir.path().join("saved.json"), &meta).unwrap();
    std::fs::remove_file(store.join("zarr.json")).unwrap();
    refused_one_line(&probe(), "zarr.json: missing");
    let before = snapshot(dir.path());
    refused_one_line(&ingest(&[&f0], &store, &["--append"]), "missing");
    assert!(
        before == snapshot(dir.path()),
        "a refused append changed files"
    );
    refused_one_line(
        &stratus(&[
            "probe",
            "--map",
            dir.path().join("none.zarr").to_str().unwrap(),
            "--at",
            "50,-25",
        ]),
        "not a Zarr store",
    );
}
