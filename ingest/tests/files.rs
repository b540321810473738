//! What stratus promises about files (issue 12), through the library: outputs never replace
//! what is not output, a map's PNG and sidecar commit together, every read is capped, and
//! sidecars with absurd values are refused naming the file and the field. Every test checks
//! that the files it did not ask to change are byte-identical afterwards.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use chrono::{TimeZone, Utc};
use stratus_ingest::cloudmap::{coverage_to_sample, write_atomic, CloudMap, MAX_SIDE};
use stratus_ingest::encode::fixtures;
use stratus_ingest::error::IngestError;
use stratus_ingest::forecast::{Forecast, LevelSelect};
use stratus_ingest::input::{read_capped, read_grib, MAX_GRIB_BYTES};
use stratus_ingest::output::{check_output, ensure_not_input};
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::spline::Interp;
use stratus_ingest::{LayerKind, Region};

/// Map number `k` (0..8): region south = k, middle coverage (k + 1) / 8 everywhere, so a PNG
/// and a sidecar of different maps are told apart even at the same size.
fn map(k: usize) -> CloudMap {
    let r = Region {
        south: k as f64,
        north: k as f64 + 10.0,
        west: 0.0,
        east: 10.0,
    };
    let t = Utc.with_ymd_and_hms(2024, 6, 1, 12, 0, 0).unwrap();
    CloudMap::from_fn(
        r,
        64,
        48,
        &[(LayerKind::Middle, 3000.0, 5000.0)],
        t,
        move |_, _| [0.0, (k + 1) as f64 / 8.0, 0.0],
    )
}

/// Which map a loaded pair is, asserting its PNG and sidecar agree.
fn which(m: &CloudMap) -> usize {
    let k = m.meta.region.south as usize;
    let want = coverage_to_sample((k + 1) as f64 / 8.0);
    assert!(
        m.texels.iter().all(|t| t[1] == want),
        "mismatched pair: sidecar of map {k}, PNG of another"
    );
    k
}

/// Every file under `dir` with its bytes (symbolic links as their target path).
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut v: Vec<_> = fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path();
            let m = fs::symlink_metadata(&p).unwrap();
            let bytes = if m.file_type().is_symlink() {
                fs::read_link(&p)
                    .unwrap()
                    .into_os_string()
                    .into_encoded_bytes()
            } else if m.is_file() {
                fs::read(&p).unwrap()
            } else {
                b"(special)".to_vec()
            };
            (p, bytes)
        })
        .collect();
    v.sort();
    v
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn one_line(e: &IngestError) -> String {
    let s = e.to_string();
    assert_eq!(s.lines().count(), 1, "not one line: {s}");
    s
}

#[cfg(unix)]
#[test]
fn planted_symlinks_are_never_followed() {
    use std::os::unix::fs::symlink;
    let dir = tempfile::tempdir().unwrap();
    let elsewhere = tempfile::tempdir().unwrap();
    let victim = elsewhere.path().join("victim");
    fs::write(&victim, b"precious").unwrap();
    let absent = elsewhere.path().join("never-created");
    let d = dir.path();
    // The names the old writer used (`.NAME.tmpPID`) and the lock file.
    let pid = std::process::id();
    symlink(&victim, d.join(format!(".m.png.tmp{pid}"))).unwrap();
    symlink(&victim, d.join(format!(".m.json.tmp{pid}"))).unwrap();
    let before = snapshot(elsewhere.path());
    map(1).save(&d.join("m.png")).unwrap();
    assert!(fs::symlink_metadata(d.join("m.png")).unwrap().is_file());
    assert_eq!(which(&CloudMap::load(&d.join("m.json")).unwrap()), 1);

    // An output that is itself a link is refused, whatever it points at.
    symlink(&victim, d.join("link.png")).unwrap();
    let e = map(2).save(&d.join("link.png")).unwrap_err();
    assert!(one_line(&e).contains("symbolic link"), "{e}");
    let e = write_atomic(&d.join("link.png"), |w| {
        w.write_all(b"x").map_err(|e| e.to_string())
    })
    .unwrap_err();
    assert!(matches!(e, IngestError::NotRegularFile { .. }), "{e}");

    // A link planted at the pair's lock makes the write fail; it never opens the target.
    symlink(&absent, d.join(".n.json.lock")).unwrap();
    let e = map(3).save(&d.join("n.png")).unwrap_err();
    assert!(one_line(&e).contains("cannot lock"), "{e}");
    assert!(!absent.exists(), "the lock followed a planted link");
    assert!(!d.join("n.png").exists() && !d.join("n.json").exists());

    assert_eq!(
        snapshot(elsewhere.path()),
        before,
        "a file outside the output changed"
    );
}

#[cfg(unix)]
#[test]
fn only_regular_files_are_replaced() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = d.join("pipe.png");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo");
    assert!(ok.success());
    fs::create_dir(d.join("folder.png")).unwrap();
    // A character device like /dev/null, made here (never the real one) where allowed.
    let dev = d.join("null.png");
    let have_dev = std::process::Command::new("mknod")
        .args([dev.as_os_str(), "c".as_ref(), "1".as_ref(), "3".as_ref()])
        .status()
        .is_ok_and(|s| s.success());
    if !have_dev {
        println!("mknod not permitted here: character-device case skipped (FIFO and folder run)");
    }
    let mut targets = vec![(fifo.clone(), "FIFO"), (d.join("folder.png"), "directory")];
    if have_dev {
        targets.push((dev.clone(), "character device"));
    }
    for (t, kind) in &targets {
        let e = write_atomic(t, |w| w.write_all(b"x").map_err(|e| e.to_string())).unwrap_err();
        let s = one_line(&e);
        assert!(s.contains(kind) && s.contains("not a regular file"), "{s}");
        assert!(s.contains(t.file_name().unwrap().to_str().unwrap()), "{s}");
        assert!(check_output(t).is_err());
        let e = map(1).save(t).unwrap_err();
        assert!(one_line(&e).contains(kind), "{e}");
    }
    assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    assert!(d.join("folder.png").is_dir());
    if have_dev {
        assert!(fs::symlink_metadata(&dev)
            .unwrap()
            .file_type()
            .is_char_device());
    }
    // The sidecar's place taken by a FIFO: refused before the PNG is written.
    let _ = std::process::Command::new("mkfifo")
        .arg(d.join("m.json"))
        .status();
    let e = map(1).save(&d.join("m.png")).unwrap_err();
    assert!(one_line(&e).contains("FIFO"), "{e}");
    assert!(!d.join("m.png").exists());
}

#[cfg(unix)]
#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A forecast named like the sidecar the output would write.
    let grib = d.join("m.json");
    fs::write(&grib, fixtures::valid_rh()).unwrap();
    let fc = Forecast::open(&grib, LevelSelect::AllBelow(100.0)).unwrap();
    let plan = Plan::new(
        &fc,
        &IngestOptions {
            region: Region::parse("46.5,49.5,10.5,14.5").unwrap(),
            width: 20,
            height: 15,
            rh_cr: LayerKind::DEFAULT_RH_CR,
            interp: Interp::Spline,
        },
    )
    .unwrap();
    let before = snapshot(d);
    let e = plan.write(&d.join("m.png"), &|_| {}).unwrap_err();
    assert!(
        matches!(e, IngestError::OutputIsInput { .. }),
        "{}",
        one_line(&e)
    );
    assert_eq!(snapshot(d), before, "the input changed or output was left");
    // The same file under other names is caught too.
    fs::hard_link(&grib, d.join("hard.png")).unwrap();
    std::os::unix::fs::symlink(&grib, d.join("soft.png")).unwrap();
    for other in ["hard.png", "soft.png", "./m.json"] {
        assert!(
            ensure_not_input(&d.join(other), &[&grib]).is_err(),
            "{other}"
        );
    }
    assert!(ensure_not_input(&d.join("new.png"), &[&grib]).is_ok());
    // And a write elsewhere works and loads.
    plan.write(&d.join("ok.png"), &|_| {}).unwrap();
    CloudMap::load(&d.join("ok.json")).unwrap();
}

#[test]
fn concurrent_writers_always_leave_a_matching_pair() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("m.png");
    let json = dir.path().join("m.json");
    let maps: Vec<CloudMap> = (0..4).map(map).collect();
    maps[0].save(&png).unwrap();
    let done = std::sync::atomic::AtomicBool::new(false);
    let loads = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|s| {
        let writers: Vec<_> = maps
            .iter()
            .map(|m| {
                let png = &png;
                s.spawn(move || {
                    for _ in 0..40 {
                        m.save(png).unwrap();
                    }
                })
            })
            .collect();
        // A reader all along: every load is one whole pair.
        s.spawn(|| {
            while !done.load(std::sync::atomic::Ordering::SeqCst) {
                let m = CloudMap::load(&json).unwrap();
                which(&m);
                loads.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            }
        });
        for w in writers {
            w.join().unwrap();
        }
        done.store(true, std::sync::atomic::Ordering::SeqCst);
    });
    which(&CloudMap::load(&json).unwrap());
    println!(
        "160 concurrent writes, {} loads during them, every pair whole",
        loads.into_inner()
    );
    assert_eq!(names(dir.path()), ["m.json", "m.png"], "temporaries left");
}

/// A PNG whose header claims `w`×`h` with a few bytes of (garbage) image data.
fn png_header_only(path: &Path, w: u32, h: u32) {
    let f = fs::File::create(path).unwrap();
    let mut enc = png::Encoder::new(f, w, h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Sixteen);
    let mut wr = enc.write_header().unwrap();
    wr.write_chunk(png::chunk::IDAT, &[0x78, 0x01, 0, 0, 0xff, 0xff])
        .unwrap();
    drop(wr);
}

#[test]
fn a_png_bomb_is_refused_before_decoding() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    map(1).save(&d.join("m.png")).unwrap();
    let sidecar: serde_json::Value =
        serde_json::from_slice(&fs::read(d.join("m.json")).unwrap()).unwrap();
    // The issue's bomb: a sidecar and PNG header agreeing on 16384×16384.
    let mut big = sidecar.clone();
    big["width"] = 16384.into();
    big["height"] = 16384.into();
    fs::write(d.join("m.json"), serde_json::to_vec_pretty(&big).unwrap()).unwrap();
    png_header_only(&d.join("m.png"), 16384, 16384);
    let t = Instant::now();
    let e = CloudMap::load(&d.join("m.json")).unwrap_err();
    let s = one_line(&e);
    assert!(
        s.contains("m.json") && s.contains(&format!("1..={MAX_SIDE}")),
        "{s}"
    );
    // A sidecar within the limit and a PNG header claiming far more: refused by the header.
    let mut small = sidecar;
    small["width"] = 100.into();
    small["height"] = 100.into();
    fs::write(d.join("m.json"), serde_json::to_vec_pretty(&small).unwrap()).unwrap();
    png_header_only(&d.join("m.png"), MAX_SIDE, MAX_SIDE);
    let e = CloudMap::load(&d.join("m.json")).unwrap_err();
    let s = one_line(&e);
    assert!(
        s.contains("PNG is 8192x8192 but its sidecar says 100x100"),
        "{s}"
    );
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    // Ingest refuses to make a map larger than the renderer takes.
    let r = map(1).meta.region;
    let t = Utc.with_ymd_and_hms(2024, 6, 1, 12, 0, 0).unwrap();
    let m = CloudMap::from_fn(r, MAX_SIDE + 1, 1, &[], t, |_, _| [0.0; 3]);
    let s = one_line(&m.save(&d.join("big.png")).unwrap_err());
    assert!(s.contains("width: 8193 px"), "{s}");
    assert!(!d.join("big.png").exists());
}

#[cfg(unix)]
#[test]
fn dev_zero_is_refused_at_once() {
    let t = Instant::now();
    let zero = Path::new("/dev/zero");
    let e = Forecast::open(zero, LevelSelect::AllBelow(100.0)).unwrap_err();
    assert!(one_line(&e).contains("not a GRIB file"), "{e}");
    let e = read_grib(zero).unwrap_err();
    assert!(one_line(&e).contains("/dev/zero"), "{e}");
    // A map's files are read only as regular files (issue 28: a FIFO would hang).
    let e = CloudMap::load(zero).unwrap_err();
    assert!(
        one_line(&e).contains("character device, not a regular file"),
        "{e}"
    );
    let e = read_capped(zero, 4096, "flight path").unwrap_err();
    assert!(
        one_line(&e).contains("4 KiB, the most a flight path may be"),
        "{e}"
    );
    // A map whose PNG is /dev/zero.
    let dir = tempfile::tempdir().unwrap();
    map(1).save(&dir.path().join("m.png")).unwrap();
    fs::remove_file(dir.path().join("m.png")).unwrap();
    std::os::unix::fs::symlink(zero, dir.path().join("m.png")).unwrap();
    let e = CloudMap::load(&dir.path().join("m.json")).unwrap_err();
    assert!(
        one_line(&e).contains("m.png: cannot read: it is a character device"),
        "{e}"
    );
    assert!(t.elapsed() < Duration::from_secs(3), "{:?}", t.elapsed());
}

#[test]
fn a_file_larger_than_any_grib_is_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge.grib2");
    let f = fs::File::create(&p).unwrap();
    f.set_len(MAX_GRIB_BYTES + 1).unwrap(); // sparse: costs no disk
    let t = Instant::now();
    let e = read_grib(&p).unwrap_err();
    assert!(one_line(&e).contains("larger than 2 GiB"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(1));
}

#[test]
fn absurd_sidecar_values_are_refused_naming_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    map(1).save(&d.join("m.png")).unwrap();
    let good: serde_json::Value =
        serde_json::from_slice(&fs::read(d.join("m.json")).unwrap()).unwrap();
    type Edit = fn(&mut serde_json::Value);
    let cases: Vec<(&str, Edit)> = vec![
        ("top_m", |v| v["layers"][0]["top_m"] = 1e12.into()),
        ("base_m", |v| v["layers"][0]["base_m"] = (-1e308).into()),
        ("not below top_m", |v| {
            v["layers"][0]["base_m"] = 6000.0.into()
        }),
        ("rh_cr", |v| v["layers"][0]["rh_cr"] = 5.into()),
        ("rh_cr", |v| v["layers"][0]["rh_cr"] = 1.0.into()),
        ("channel", |v| v["layers"][0]["channel"] = 2.into()),
        ("max_coverage", |v| {
            v["layers"][0]["max_coverage"] = 2.into()
        }),
        ("width", |v| v["width"] = 0.into()),
        ("height", |v| v["height"] = 9000.into()),
        ("region", |v| v["region"]["south"] = 95.0.into()),
        ("image", |v| v["image"] = "../elsewhere.png".into()),
        ("image_id", |v| {
            v.as_object_mut().unwrap().remove("image_id");
        }),
        ("format", |v| v["format"] = "stratus-cloudmap/9".into()),
        ("second middle layer", |v| {
            let l = v["layers"][0].clone();
            v["layers"].as_array_mut().unwrap().push(l);
        }),
    ];
    for (field, edit) in cases {
        let mut v = good.clone();
        edit(&mut v);
        let name = "bad.json";
        fs::write(d.join(name), serde_json::to_vec_pretty(&v).unwrap()).unwrap();
        let e = CloudMap::load(&d.join(name)).unwrap_err();
        let s = one_line(&e);
        assert!(s.contains(name) && s.contains(field), "{field}: {s}");
    }
    // A valid time that is not one names the sidecar too.
    let mut v = good.clone();
    v["source"]["valid_time"] = "soon".into();
    fs::write(d.join("t.json"), serde_json::to_vec_pretty(&v).unwrap()).unwrap();
    let s = one_line(&CloudMap::load(&d.join("t.json")).unwrap_err());
    assert!(
        s.contains("t.json") && s.contains("\"soon\" is not ISO 8601"),
        "{s}"
    );
    // The untouched sidecar still loads.
    which(&CloudMap::load(&d.join("m.json")).unwrap());
}

#[test]
fn version_1_pairs_still_load() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let m = map(2);
    // A v1 pair: PNG without an image id, sidecar format 1 without `image_id`.
    let mut bytes = Vec::new();
    for t in &m.texels {
        for c in t {
            bytes.extend_from_slice(&c.to_be_bytes());
        }
    }
    let f = fs::File::create(d.join("old.png")).unwrap();
    stratus_ingest::cloudmap::encode_png16(f, 64, 48, 4, &bytes).unwrap();
    let mut meta = m.meta.clone();
    meta.format = stratus_ingest::meta::FORMAT_V1.into();
    meta.image = "old.png".into();
    meta.image_id = None;
    fs::write(
        d.join("old.json"),
        serde_json::to_vec_pretty(&meta).unwrap(),
    )
    .unwrap();
    assert_eq!(which(&CloudMap::load(&d.join("old.json")).unwrap()), 2);
    // Written again, it becomes a version-2 pair under the same names.
    let loaded = CloudMap::load(&d.join("old.json")).unwrap();
    loaded.save(&d.join("old.png")).unwrap();
    let again = CloudMap::load(&d.join("old.json")).unwrap();
    assert_eq!(again.meta.format, stratus_ingest::meta::FORMAT);
    assert!(again.meta.image_id.is_some());
    assert_eq!(which(&again), 2);
    // A v2 sidecar beside a PNG that is not its own is refused, not trusted.
    map(3).save(&d.join("m.png")).unwrap();
    fs::copy(d.join("old.png"), d.join("m.png")).unwrap();
    let s = one_line(&CloudMap::load(&d.join("m.json")).unwrap_err());
    assert!(s.contains("not the one its sidecar names"), "{s}");
}

#[cfg(unix)]
#[test]
fn names_are_kept_exact_and_errors_stay_one_line() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A PNG name that is not UTF-8 cannot be recorded in the sidecar: refused, nothing written.
    let bad = d.join(std::ffi::OsStr::from_bytes(b"m\xff.png"));
    let e = map(1).save(&bad).unwrap_err();
    let s = one_line(&e);
    assert!(s.contains("not valid UTF-8") && s.contains(r"\xFF"), "{s}");
    assert!(names(d).is_empty(), "{:?}", names(d));
    // A newline in a name is shown escaped; the OS error appears once.
    let e = CloudMap::load(&d.join("two\nlines.json")).unwrap_err();
    let s = one_line(&e);
    assert!(s.contains(r"two\nlines.json"), "{s}");
    assert_eq!(s.matches("No such file").count(), 1, "{s}");
    assert!(std::error::Error::source(&e).is_none());
    // A newline in an output name is fine to write (it is UTF-8) and loads back.
    map(4).save(&d.join("a\nb.png")).unwrap();
    assert_eq!(which(&CloudMap::load(&d.join("a\nb.json")).unwrap()), 4);
}

/// Run by [`concurrent_processes_always_leave_a_matching_pair`] in child processes: writes
/// map `$STRATUS_TEST_WRITER` to `$STRATUS_TEST_OUT` many times. Does nothing otherwise.
#[test]
fn child_writer() {
    let (Ok(k), Ok(out)) = (
        std::env::var("STRATUS_TEST_WRITER"),
        std::env::var("STRATUS_TEST_OUT"),
    ) else {
        return;
    };
    let m = map(k.parse().unwrap());
    for _ in 0..30 {
        m.save(Path::new(&out)).unwrap();
    }
}

#[test]
fn concurrent_processes_always_leave_a_matching_pair() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("m.png");
    let json = dir.path().join("m.json");
    map(0).save(&png).unwrap();
    let exe = std::env::current_exe().unwrap();
    let children: Vec<_> = (0..4)
        .map(|k| {
            std::process::Command::new(&exe)
                .args(["--exact", "child_writer", "--test-threads", "1"])
                .env("STRATUS_TEST_WRITER", k.to_string())
                .env("STRATUS_TEST_OUT", &png)
                .stdout(std::process::Stdio::null())
                .spawn()
                .unwrap()
        })
        .collect();
    let mut loads = 0;
    let mut children = children;
    while children.iter_mut().any(|c| c.try_wait().unwrap().is_none()) {
        which(&CloudMap::load(&json).unwrap());
        loads += 1;
    }
    for mut c in children {
        assert!(c.wait().unwrap().success(), "a writer failed");
    }
    which(&CloudMap::load(&json).unwrap());
    println!("4 processes × 30 writes, {loads} loads during them, every pair whole");
    assert_eq!(names(dir.path()), ["m.json", "m.png"], "temporaries left");
}
