//! What stratus promises about files (docs/files.md), through the binary: no output replaces a
//! device node or one of the command's inputs, planted links are never followed, a map's PNG
//! and sidecar commit together, signals leave no temporaries, work and reads are bounded, a
//! closed stdout ends quietly, and every refusal is one line with exit code 2 that leaves every
//! file there was byte-identical.
#![cfg(unix)]

use std::collections::BTreeMap;
use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use stratus_ingest::cloudmap::CloudMap;

fn exe() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_stratus"));
    c.env("RUST_LOG", "error");
    c
}

fn stratus<S: AsRef<OsStr>>(args: &[S]) -> Output {
    exe().args(args).output().expect("run stratus")
}

fn sample_grib() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data-samples/synthetic-gfs-rh.grib2")
}

fn gfs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data-samples/gfs/gfs.t12z.pgrbf120.2p5deg.grib2")
}

/// Ingest the sample over `region` to `png` (its sidecar beside it); returns the sidecar.
fn ingest(png: &Path, region: &str) -> PathBuf {
    let o = stratus(&[
        "ingest".as_ref(),
        sample_grib().as_os_str(),
        "--region".as_ref(),
        region.as_ref(),
        "--size".as_ref(),
        "160x120".as_ref(),
        "--out".as_ref(),
        png.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    png.with_extension("json")
}

const REGION: &str = "30,60,-40,0";

/// Every entry under `dir` (not following links): file bytes, link targets, kinds.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, String> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, String>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            let m = std::fs::symlink_metadata(&p).unwrap();
            let t = m.file_type();
            let what = if t.is_file() {
                format!("file {:?}", std::fs::read(&p).unwrap())
            } else if t.is_symlink() {
                format!("link {:?}", std::fs::read_link(&p).unwrap())
            } else if t.is_dir() {
                walk(root, &p, out);
                "dir".into()
            } else if t.is_char_device() {
                "char device".into()
            } else {
                "other".into()
            };
            out.insert(p.strip_prefix(root).unwrap().to_path_buf(), what);
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Exit 2, exactly one stderr line, an `error:` containing `needle`, no panic.
fn refused(o: &Output, needle: &str) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "not one line: {err:?}");
    assert!(lines[0].starts_with("error: "), "{err}");
    assert!(lines[0].contains(needle), "wanted \"{needle}\" in: {err}");
    err
}

/// `mknod DIR/NAME c MAJOR MINOR` (a private copy of a /dev node: tests never touch /dev), or
/// `None` with the reason printed where that is not permitted.
fn device(dir: &Path, name: &str, major: u32, minor: u32) -> Option<PathBuf> {
    let p = dir.join(name);
    let ok = Command::new("mknod")
        .arg(&p)
        .args(["c", &major.to_string(), &minor.to_string()])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        eprintln!("skipped: mknod is not permitted here (not root?)");
    }
    ok.then_some(p)
}

fn path_json(dir: &Path, name: &str, ts: &[f64]) -> PathBuf {
    let keys: Vec<String> = ts
        .iter()
        .enumerate()
        .map(|(i, t)| {
            format!(
                r#"{{"t":{t:e},"lat":45,"lon":{},"alt_m":9000,"pitch":-10}}"#,
                -22.0 + 0.001 * i as f64
            )
        })
        .collect();
    let p = dir.join(name);
    std::fs::write(&p, format!(r#"{{"keys":[{}]}}"#, keys.join(","))).unwrap();
    p
}

/// A copy of the sidecar `from` at `to`, changed by `edit`.
fn edited(from: &Path, to: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(from).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(to, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

fn render_to(map: &Path, out: &Path) -> Output {
    stratus(&[
        "render".as_ref(),
        "--map".as_ref(),
        map.as_os_str(),
        "--camera".as_ref(),
        "45,-22,9000".as_ref(),
        "--size".as_ref(),
        "16x9".as_ref(),
        "--preset".as_ref(),
        "fast".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ])
}

// 1. Output never replaces a device node or one of the command's inputs.
#[test]
fn outputs_never_replace_devices_or_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = ingest(&d.join("m.png"), REGION);
    let png = d.join("m.png");
    std::fs::hard_link(&png, d.join("alias.png")).unwrap();
    std::os::unix::fs::symlink(&png, d.join("link.png")).unwrap();
    let grib = d.join("g.png");
    std::fs::copy(sample_grib(), &grib).unwrap();
    let path = path_json(d, "p.json", &[0.0, 1.0]);
    let frames = d.join("frames");
    std::fs::create_dir(&frames).unwrap();
    std::fs::hard_link(&png, frames.join("frame-00000.png")).unwrap();
    // Named .png, so that only their kind can be what refuses them.
    let devices: Vec<PathBuf> = [("null.png", 3), ("full.png", 7)]
        .iter()
        .filter_map(|&(n, minor)| device(d, n, 1, minor))
        .collect();
    let before = snapshot(d);

    for out in devices.iter() {
        refused(&render_to(&map, out), "not a regular file");
        refused(
            &stratus(&[
                "score".as_ref(),
                "--map".as_ref(),
                map.as_os_str(),
                "--diff".as_ref(),
                out.as_os_str(),
            ]),
            "not a regular file",
        );
    }
    for (out, needle) in [
        (png.clone(), "it is the input"),
        (map.clone(), "it is the input"),
        (d.join("alias.png"), "it is the input"),
        (d.join("link.png"), "symbolic link"),
    ] {
        refused(&render_to(&map, &out), needle);
    }
    refused(
        &stratus(&[
            "score".as_ref(),
            "--map".as_ref(),
            map.as_os_str(),
            "--diff".as_ref(),
            png.as_os_str(),
        ]),
        "it is the input",
    );
    refused(
        &stratus(&[
            "fly".as_ref(),
            map.as_os_str(),
            "--frames".as_ref(),
            "1".as_ref(),
            "--screenshot".as_ref(),
            png.as_os_str(),
        ]),
        "it is the input",
    );
    // The forecast as its own output.
    refused(
        &stratus(&[
            "ingest".as_ref(),
            grib.as_os_str(),
            "--region".as_ref(),
            REGION.as_ref(),
            "--size".as_ref(),
            "16x12".as_ref(),
            "--out".as_ref(),
            grib.as_os_str(),
        ]),
        "it is the input",
    );
    // flight: a file as the folder, a frame name that is the map's PNG, the path as a frame.
    let flight = |out: &Path, path: &Path| {
        stratus(&[
            "flight".as_ref(),
            "--map".as_ref(),
            map.as_os_str(),
            "--path".as_ref(),
            path.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
        ])
    };
    refused(&flight(&map, &path), "must be a folder");
    refused(&flight(&frames, &path), "it is the input");
    let p2 = path_json(d, "frame-00001.png", &[0.0, 1.0]);
    let before2 = snapshot(d);
    refused(&flight(d, &p2), "it is the input");
    assert_eq!(snapshot(d), before2);
    std::fs::remove_file(&p2).unwrap();

    assert_eq!(snapshot(d), before, "a file changed");
    CloudMap::load(&map).expect("the map still loads");
}

// 2. Planted symbolic links are never followed, and never replaced.
#[test]
fn planted_links_are_never_followed() {
    let dir = tempfile::tempdir().unwrap();
    let victim_dir = tempfile::tempdir().unwrap();
    let victim = victim_dir.path().join("victim");
    std::fs::write(&victim, b"precious").unwrap();
    let d = dir.path();
    let out = d.join("m.png");
    // The names the old writer used (.m.png.tmpPID) for the pids the next runs will get.
    let next = Command::new("true").spawn().unwrap().id();
    for pid in next..next + 300 {
        for ext in ["png", "json"] {
            std::os::unix::fs::symlink(&victim, d.join(format!(".m.{ext}.tmp{pid}"))).unwrap();
        }
    }
    ingest(&out, REGION);
    assert!(std::fs::symlink_metadata(&out).unwrap().is_file());
    assert!(std::fs::symlink_metadata(out.with_extension("json"))
        .unwrap()
        .is_file());
    CloudMap::load(&out.with_extension("json")).unwrap();
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");

    // A link in the output's place, or in the pair lock's, is refused, its target untouched.
    let before = snapshot(d);
    let victims = snapshot(victim_dir.path());
    let run = |out: &Path| {
        stratus(&[
            "ingest".as_ref(),
            sample_grib().as_os_str(),
            "--region".as_ref(),
            REGION.as_ref(),
            "--size".as_ref(),
            "16x12".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ])
    };
    let linked = d.join("l.png");
    std::os::unix::fs::symlink(&victim, &linked).unwrap();
    std::os::unix::fs::symlink(&victim, d.join(".m.json.lock")).unwrap();
    let before_links = snapshot(d);
    refused(&run(&linked), "symbolic link");
    refused(&run(&out), ".m.json.lock");
    assert_eq!(snapshot(d), before_links);
    std::fs::remove_file(&linked).unwrap();
    std::fs::remove_file(d.join(".m.json.lock")).unwrap();
    assert_eq!(snapshot(d), before);
    assert_eq!(snapshot(victim_dir.path()), victims);
}

// 3. Two ingests to one map at once: whichever wins, the pair is whole.
#[test]
fn concurrent_ingests_leave_a_whole_pair() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let regions = ["30,60,-40,0", "35,55,-35,-5"];
    let reference: Vec<CloudMap> = regions
        .iter()
        .enumerate()
        .map(|(i, r)| CloudMap::load(&ingest(&d.join(format!("ref{i}.png")), r)).unwrap())
        .collect();
    assert_ne!(reference[0].texels, reference[1].texels);
    let out = d.join("m.png");
    let spawn = |region: &str| {
        exe()
            .args(["ingest".as_ref(), sample_grib().as_os_str()])
            .args(["--region", region, "--size", "160x120", "--out"])
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    for trial in 0..25 {
        let (a, b) = if trial % 2 == 0 { (0, 1) } else { (1, 0) };
        let ca = spawn(regions[a]);
        let cb = spawn(regions[b]);
        for c in [ca, cb] {
            let o = c.wait_with_output().unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        }
        let map = CloudMap::load(&out.with_extension("json"))
            .unwrap_or_else(|e| panic!("trial {trial}: the pair does not load: {e}"));
        let want = reference
            .iter()
            .find(|r| r.meta.region == map.meta.region)
            .expect("a region one of the writers wrote");
        assert!(
            want.texels == map.texels,
            "trial {trial}: the PNG is not the sidecar's region"
        );
        // Exactly the map's files: the pair and the structure images its sidecar lists, no
        // temporary, kept PNG or lock.
        let mut want: Vec<String> = ["m.json", "m.png"].map(String::from).to_vec();
        want.extend(map.meta.extra_images.iter().map(|e| e.image.clone()));
        want.sort();
        let mut left = names(d);
        left.retain(|n| !n.starts_with("ref"));
        assert_eq!(left, want, "trial {trial}: leftovers");
    }
}

// 4. INT, TERM, HUP remove the temporaries in flight and exit 128 + the signal.
#[test]
fn signals_leave_no_temporaries() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("m.png");
    ingest(&out, REGION);
    let before = snapshot(d);
    for (sig, num) in [("INT", 2), ("TERM", 15), ("HUP", 1)] {
        let child = exe()
            .arg("ingest")
            .arg(gfs())
            .args(["--region", "0,55,39,105", "--size", "6500x5500", "--out"])
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Signal once the write is under way (a temporary exists), or after 20 s.
        let t0 = Instant::now();
        while !names(d).iter().any(|n| n.ends_with(".stratus-tmp"))
            && t0.elapsed() < Duration::from_secs(20)
        {
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(
            names(d).iter().any(|n| n.ends_with(".stratus-tmp")),
            "SIG{sig}: no temporary ever appeared"
        );
        let kill = Command::new("kill")
            .args(["-s", sig, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(128 + num), "SIG{sig}: {err}");
        assert!(err.trim().is_empty(), "SIG{sig}: {err}");
        assert_eq!(snapshot(d), before, "SIG{sig}: files left or changed");
    }
}

// 5. flight checks its work before starting it.
#[test]
fn flight_refuses_unbounded_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = ingest(&d.join("m.png"), REGION);
    let long = path_json(d, "long.json", &[0.0, 1e8]);
    let huge = path_json(d, "huge.json", &[0.0, 1.7e308]);
    let wide = path_json(d, "wide.json", &[-1.7e308, 1.7e308]);
    let ts: Vec<f64> = (0..10_001).map(f64::from).collect();
    let many = path_json(d, "many.json", &ts);
    let bulky = d.join("bulky.json");
    {
        // A million keys: far past the size cap, refused before it is parsed.
        let key = r#"{"t":0,"lat":45,"lon":-22,"alt_m":9000},"#;
        let mut s = String::from(r#"{"keys":["#);
        s.push_str(&key.repeat(1_000_000));
        s.push_str(r#"{"t":1,"lat":45,"lon":-22,"alt_m":9000}]}"#);
        std::fs::write(&bulky, s).unwrap();
    }
    let before = snapshot(d);
    let out = d.join("frames");
    let flight = |path: &Path, extra: &[&str]| {
        let mut c = exe();
        c.args(["flight", "--map"])
            .arg(&map)
            .arg("--path")
            .arg(path)
            .arg("--out")
            .arg(&out)
            .args(extra);
        c.output().unwrap()
    };
    refused(
        &flight(&long, &[]),
        "1.000e9 frames, more than the limit of 10000",
    );
    // Raising the limit does not make 1e9 frames fit on the disk.
    refused(
        &flight(&long, &["--max-frames", "2000000000"]),
        "need about",
    );
    // A span too long to count is refused, never wrapped to 0 frames.
    refused(
        &flight(&huge, &["--max-frames", &u64::MAX.to_string()]),
        "inf frames",
    );
    refused(
        &flight(&wide, &[]),
        "more than a number of seconds can hold",
    );
    refused(&flight(&many, &[]), "10001 keys; at most 10000");
    refused(&flight(&bulky, &[]), "larger than 4 MiB");
    refused(&flight(&long, &["--size", "0x9"]), "bad size");
    assert!(!out.exists(), "a refused run created its folder");
    assert_eq!(snapshot(d), before);
}

/// `sh -c 'ulimit -v KIB; exec stratus ARGS'`: the command under a memory cap.
fn capped(kib: u64, args: &[&OsStr]) -> Output {
    let mut c = Command::new("sh");
    c.arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_stratus"))
        .args(args)
        .env("RUST_LOG", "error");
    c.output().unwrap()
}

/// A PNG whose header says `w`×`h` RGBA 16-bit, with next to no data: what a decoder that
/// trusted the header would expand to gigabytes.
fn png_bomb(w: u32, h: u32) -> Vec<u8> {
    fn crc(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    fn chunk(out: &mut Vec<u8>, kind: &[u8], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc(&body).to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[16, 6, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    // zlib: a stored block of zeros.
    chunk(
        &mut png,
        b"IDAT",
        &[0x78, 0x01, 0x01, 0x04, 0x00, 0xfb, 0xff, 0, 0, 0, 0],
    );
    chunk(&mut png, b"IEND", &[]);
    png
}

// 6. Reads are capped by what a valid file can be; a map's size is checked before decoding.
#[test]
fn reads_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = ingest(&d.join("m.png"), REGION);
    // A sidecar at the largest size allowed over a PNG that claims 16384×16384 (2 GiB).
    std::fs::write(d.join("bomb.png"), png_bomb(16384, 16384)).unwrap();
    let bomb = d.join("bomb.json");
    edited(&map, &bomb, |v| {
        v["width"] = 8192.into();
        v["height"] = 8192.into();
        v["image"] = "bomb.png".into();
    });
    let Some(zero) = device(d, "zero", 1, 5) else {
        return;
    };
    let path = path_json(d, "p.json", &[0.0, 1.0]);
    let before = snapshot(d);
    let out = d.join("out.png");
    let z = zero.as_os_str();
    let o = |s: &'static str| OsStr::new(s);
    const CAP: u64 = 1 << 20; // 1 GiB of address space
    for (args, needle) in [
        (vec![o("inspect"), z], "not a GRIB file"),
        (
            vec![
                o("ingest"),
                z,
                o("--region"),
                o(REGION),
                o("--out"),
                out.as_os_str(),
            ],
            "not a GRIB file",
        ),
        (
            vec![
                o("render"),
                o("--map"),
                z,
                o("--camera"),
                o("45,-22,9000"),
                o("--out"),
                out.as_os_str(),
            ],
            // A map's files are read only as regular files (issue 28: a FIFO would hang).
            "it is a character device, not a regular file",
        ),
        (
            vec![
                o("flight"),
                o("--map"),
                map.as_os_str(),
                o("--path"),
                z,
                o("--out"),
                d.join("frames").as_os_str(),
            ],
            "larger than 4 MiB",
        ),
        (
            vec![
                o("render"),
                o("--map"),
                bomb.as_os_str(),
                o("--camera"),
                o("45,-22,9000"),
                o("--out"),
                out.as_os_str(),
            ],
            "PNG is 16384x16384 but its sidecar says 8192x8192",
        ),
    ] {
        let t0 = Instant::now();
        let r = capped(CAP, &args);
        refused(&r, needle);
        assert!(t0.elapsed() < Duration::from_secs(10), "{args:?} was slow");
    }
    // ingest and the loader agree on the largest map.
    refused(
        &stratus(&[
            "ingest".as_ref(),
            sample_grib().as_os_str(),
            "--region".as_ref(),
            REGION.as_ref(),
            "--size".as_ref(),
            "16384x16".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ]),
        "1..=8192",
    );
    assert_eq!(snapshot(d), before);
    assert!(path.exists());
}

/// Run with stdout a pipe whose reader has already gone.
fn to_closed_pipe(args: &[&OsStr]) -> Output {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    exe()
        .args(args)
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap()
}

// 7. A closed stdout ends the program quietly, with the shell's SIGPIPE code.
#[test]
fn broken_pipes_end_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let map = ingest(&dir.path().join("m.png"), REGION);
    let before = snapshot(dir.path());
    let o = to_closed_pipe(&["inspect".as_ref(), gfs().as_os_str()]);
    assert_eq!(o.status.code(), Some(141));
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let o = to_closed_pipe(&[
        "score".as_ref(),
        "--map".as_ref(),
        map.as_os_str(),
        "--json".as_ref(),
        "--preset".as_ref(),
        "fast".as_ref(),
        "--score-size".as_ref(),
        "32x24".as_ref(),
        "--min-dice".as_ref(),
        "0".as_ref(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(141), "{err}");
    assert!(
        err.lines().all(|l| l.starts_with("stratus: adapter")),
        "{err}"
    );
    assert_eq!(snapshot(dir.path()), before);
}

// 8. The CI gate takes a DSC: anything else is a bad argument, not a pass or a failed gate.
#[test]
fn min_dice_must_be_a_dsc() {
    let dir = tempfile::tempdir().unwrap();
    let map = ingest(&dir.path().join("m.png"), REGION);
    let before = snapshot(dir.path());
    for bad in ["NaN", "2", "-0.1", "inf"] {
        refused(
            &stratus(&[
                "score".as_ref(),
                "--map".as_ref(),
                map.as_os_str(),
                "--min-dice".as_ref(),
                bad.as_ref(),
            ]),
            &format!("--min-dice {bad} must be a number in 0..=1"),
        );
    }
    assert_eq!(snapshot(dir.path()), before);
}

// 9. Sidecar values outside physical ranges are refused, naming the sidecar and the field.
#[test]
fn absurd_sidecars_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = ingest(&d.join("m.png"), REGION);
    type Edit = fn(&mut serde_json::Value);
    let cases: [(Edit, &str); 4] = [
        (
            |v| v["layers"][2]["top_m"] = 1e12.into(),
            "top_m: 1000000000000 m",
        ),
        (|v| v["layers"][0]["base_m"] = (-1e308).into(), "base_m"),
        (|v| v["layers"][1]["rh_cr"] = 5.into(), "rh_cr"),
        (|v| v["layers"][1]["channel"] = 2.into(), "channel"),
    ];
    for (i, (edit, _)) in cases.iter().enumerate() {
        edited(&map, &d.join(format!("bad{i}.json")), *edit);
    }
    let before = snapshot(d);
    let out = d.join("f.png");
    for (i, (_, needle)) in cases.iter().enumerate() {
        let bad = d.join(format!("bad{i}.json"));
        let err = refused(&render_to(&bad, &out), needle);
        assert!(err.contains(&format!("bad{i}.json")), "{err}");
    }
    assert_eq!(snapshot(d), before);
}

// 10. Names: one line whatever the name, the sidecar named, OS errors once, NaN as NaN.
#[test]
fn names_and_numbers_are_reported_as_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = ingest(&d.join("m.png"), REGION);
    let bad_time = d.join("bad time.json");
    edited(&map, &bad_time, |v| {
        v["source"]["valid_time"] = "soon".into()
    });
    let before = snapshot(d);

    let err = refused(
        &stratus(&[
            "ingest".as_ref(),
            d.join("a\nb.grib2").as_os_str(),
            "--region".as_ref(),
            REGION.as_ref(),
            "--out".as_ref(),
            d.join("x.png").as_os_str(),
        ]),
        r#"a\nb.grib2"#,
    );
    assert_eq!(err.matches("os error").count(), 1, "{err}");
    let bad_utf8 = d.join(OsStr::from_bytes(b"m\xff.png"));
    refused(
        &stratus(&[
            "ingest".as_ref(),
            sample_grib().as_os_str(),
            "--region".as_ref(),
            REGION.as_ref(),
            "--size".as_ref(),
            "16x12".as_ref(),
            "--out".as_ref(),
            bad_utf8.as_os_str(),
        ]),
        "not valid UTF-8",
    );
    let out = d.join("f.png");
    refused(&render_to(&bad_time, &out), "bad time.json: bad CloudMap");
    let err = refused(&render_to(&d.join("gone.json"), &out), "gone.json");
    assert_eq!(err.matches("os error").count(), 1, "{err}");
    for (opt, v) in [("--pitch", "NaN"), ("--heading", "inf"), ("--fov", "NaN")] {
        let o = exe()
            .args(["render", "--map"])
            .arg(&map)
            .args(["--camera", "45,-22,9000", opt, v, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        refused(&o, &format!("{opt} {v} must be a finite number"));
    }
    assert_eq!(snapshot(d), before);
}

fn flight(map: &Path, path: &Path, out: &Path) -> Output {
    exe()
        .args(["flight", "--map"])
        .arg(map)
        .arg("--path")
        .arg(path)
        .arg("--out")
        .arg(out)
        .args(["--size", "16x9", "--preset", "fast", "--fps", "4"])
        .output()
        .unwrap()
}

// 11. flight's folder holds exactly this run's frames, or — after a failure — what it held.
#[test]
fn flight_folder_holds_this_run_or_what_it_held() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = ingest(&d.join("m.png"), REGION);
    let path = path_json(d, "p.json", &[0.0, 0.5]); // 3 frames at 4 fps
    let out = d.join("frames");
    std::fs::create_dir(&out).unwrap();
    for i in 0..6 {
        std::fs::write(out.join(format!("frame-{i:05}.png")), b"old").unwrap();
    }
    for other in ["notes.txt", "frame-7.png", "frame-00009.png.bak"] {
        std::fs::write(out.join(other), b"mine").unwrap();
    }
    let o = flight(&map, &path, &out);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("wrote 3 frames frame-00000..00002.png to")
            && stdout.contains("removed 3 frame(s) of an earlier, longer run"),
        "{stdout}"
    );
    assert_eq!(
        names(&out),
        [
            "frame-00000.png",
            "frame-00001.png",
            "frame-00002.png",
            "frame-00009.png.bak",
            "frame-7.png",
            "notes.txt"
        ]
    );
    for i in 0..3 {
        let img = image::open(out.join(format!("frame-{i:05}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (16, 9));
    }
    assert_eq!(std::fs::read(out.join("notes.txt")).unwrap(), b"mine");

    // No space left: on a small tmpfs (root only), a run that fills it leaves it as it was.
    let mnt = d.join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
        .arg(&mnt)
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipped the no-space case: cannot mount a tmpfs here (not root?)");
        return;
    }
    struct Unmount(PathBuf);
    impl Drop for Unmount {
        fn drop(&mut self) {
            let _ = Command::new("umount").arg(&self.0).status();
        }
    }
    let _unmount = Unmount(mnt.clone());
    // Leave 16 KiB: 40 frames of 16×9 are estimated at 6 KiB but take a 4 KiB page each.
    let old = mnt.join("old");
    std::fs::create_dir(&old).unwrap();
    std::fs::write(old.join("frame-00000.png"), b"old").unwrap();
    std::fs::write(mnt.join("filler"), vec![1u8; 40 << 10]).unwrap();
    let long = path_json(d, "long.json", &[0.0, 9.75]);
    let before = snapshot(&mnt);
    for out in [mnt.join("new/frames"), old.clone()] {
        let o = flight(&map, &long, &out);
        let err = String::from_utf8_lossy(&o.stderr);
        let lines: Vec<&str> = err
            .lines()
            .filter(|l| !l.starts_with("stratus: adapter"))
            .collect();
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert_eq!(lines.len(), 1, "{err}");
        assert!(lines[0].contains("No space left"), "{err}");
        assert_eq!(snapshot(&mnt), before, "{out:?}: the folder changed");
    }
}

// 12. Log lines carry no colour codes when stderr is not a terminal.
#[test]
fn log_lines_are_plain_off_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let map = ingest(&dir.path().join("m.png"), REGION);
    let o = exe()
        .env("RUST_LOG", "debug")
        .args(["render", "--map"])
        .arg(&map)
        .args([
            "--camera",
            "45,-22,9000",
            "--adapter",
            "no-such-gpu",
            "--out",
        ])
        .arg(dir.path().join("f.png"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("DEBUG"), "no log lines to check: {err}");
    assert!(!err.contains('\x1b'), "colour codes in: {err:?}");
}
