//! `stratus fetch` end to end through the binary, against a small HTTP/1.1 server on 127.0.0.1
//! that serves the shared GFS files in NOMADS' layout with `.idx` inventories made by the
//! ingest crate's generator, honours `Range`, and injects faults: a connection dropped
//! mid-range, 503s, a server too slow for the timeout, a range answered with the wrong length,
//! an inventory that does not match its file, a missing inventory, and a server that hangs so
//! the fetch can be interrupted and resumed.

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use stratus_ingest::fetch::idx;
use stratus_ingest::grib::{self, MessageInfo, SurfaceType};

fn sample(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data-samples")
        .join(rel)
}

/// The run the 2.5° series files are: 2015-09-12 18Z, steps 0 and 6.
const RUN: [&str; 4] = ["--date", "2015-09-12", "--cycle", "18"];
const SERIES: &str = "gfs.20150912/18/atmos";

/// A served tree: the series files (and the 2011 file as step 120 of 2011-01-10 12Z) with
/// their inventories, in NOMADS' layout under `root`.
fn tree() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("www");
    let put = |src: PathBuf, rel: &str| {
        let dst = root.join(rel);
        std::fs::create_dir_all(dst.parent().unwrap()).unwrap();
        let bytes = std::fs::read(&src).unwrap();
        let fields = grib::scan(&bytes).unwrap();
        std::fs::write(&dst, &bytes).unwrap();
        std::fs::write(
            dst.with_file_name(format!(
                "{}.idx",
                dst.file_name().unwrap().to_str().unwrap()
            )),
            idx::write(&bytes, &fields),
        )
        .unwrap();
    };
    for s in ["f000", "f006"] {
        put(
            sample(&format!("gfs-series/gfs.t18z.pgrb2.2p50.{s}")),
            &format!("{SERIES}/gfs.t18z.pgrb2.2p50.{s}"),
        );
    }
    put(
        sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2"),
        "gfs.20110110/12/atmos/gfs.t12z.pgrb2.2p50.f120",
    );
    (dir, root)
}

/// Faults the server injects, each on the next N range requests it serves.
#[derive(Default, Clone)]
struct Faults {
    /// Send the headers and half the body, then close.
    drop_mid_body: u32,
    /// Answer 503 (to any request).
    status_503: u32,
    /// Send the headers, then stall this long before the body.
    stall: u32,
    stall_for: Duration,
    /// A 206 for 10 bytes fewer than asked, consistently declared.
    short_range: u32,
    /// After this many whole range answers, stall every further range request (until stop).
    hang_after: Option<usize>,
}

#[derive(Debug, Clone)]
struct Logged {
    path: String,
    range: Option<String>,
    outcome: &'static str,
}

struct Server {
    base: String,
    log: Arc<Mutex<Vec<Logged>>>,
    stop: Arc<AtomicBool>,
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
    }
}

impl Server {
    fn start(root: &Path, faults: Faults) -> Server {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let base = format!("http://{}/pub/", listener.local_addr().unwrap());
        let log = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let faults = Arc::new(Mutex::new(faults));
        let (root, log2, stop2) = (root.to_path_buf(), log.clone(), stop.clone());
        listener.set_nonblocking(true).unwrap();
        std::thread::spawn(move || {
            // Bounded: the server lives at most a minute, whatever the test does.
            let t0 = Instant::now();
            while !stop2.load(Ordering::SeqCst) && t0.elapsed() < Duration::from_secs(60) {
                match listener.accept() {
                    Ok((s, _)) => {
                        let (root, log, stop, faults) =
                            (root.clone(), log2.clone(), stop2.clone(), faults.clone());
                        std::thread::spawn(move || serve(s, &root, &log, &stop, &faults));
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(5)),
                }
            }
        });
        Server { base, log, stop }
    }

    fn log(&self) -> Vec<Logged> {
        self.log.lock().unwrap().clone()
    }

    /// Range requests answered whole, as `PATH RANGE`.
    fn served_ranges(&self) -> Vec<String> {
        self.log()
            .into_iter()
            .filter(|l| l.outcome == "206")
            .map(|l| format!("{} {}", l.path, l.range.unwrap_or_default()))
            .collect()
    }
}

fn take(n: &mut u32) -> bool {
    if *n > 0 {
        *n -= 1;
        true
    } else {
        false
    }
}

/// One connection: requests until the client closes it (or a fault does).
fn serve(
    s: TcpStream,
    root: &Path,
    log: &Mutex<Vec<Logged>>,
    stop: &AtomicBool,
    faults: &Mutex<Faults>,
) {
    let _ = s.set_read_timeout(Some(Duration::from_secs(20)));
    let mut w = match s.try_clone() {
        Ok(w) => w,
        Err(_) => return,
    };
    let mut r = BufReader::new(s);
    loop {
        let mut line = String::new();
        if r.read_line(&mut line).unwrap_or(0) == 0 {
            return;
        }
        let path = line.split_whitespace().nth(1).unwrap_or("").to_string();
        let mut range = None;
        loop {
            let mut h = String::new();
            if r.read_line(&mut h).unwrap_or(0) == 0 {
                return;
            }
            if h == "\r\n" || h == "\n" {
                break;
            }
            if let Some((k, v)) = h.split_once(':') {
                if k.eq_ignore_ascii_case("range") {
                    range = Some(v.trim().to_string());
                }
            }
        }
        let record = |outcome: &'static str| {
            log.lock().unwrap().push(Logged {
                path: path.clone(),
                range: range.clone(),
                outcome,
            })
        };
        let mut f = faults.lock().unwrap();
        if take(&mut f.status_503) {
            drop(f);
            record("503");
            let _ = w.write_all(b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\n\r\n");
            continue;
        }
        let rel = path.strip_prefix("/pub/").unwrap_or("");
        let file = root.join(rel);
        let bytes = match (rel.contains(".."), std::fs::read(&file)) {
            (false, Ok(b)) => b,
            _ => {
                drop(f);
                record("404");
                let _ = w.write_all(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n");
                continue;
            }
        };
        let Some(spec) = range.as_deref().and_then(|r| r.strip_prefix("bytes=")) else {
            drop(f);
            record("200");
            let _ = write!(
                w,
                "HTTP/1.1 200 OK\r\nContent-Length: {}\r\n\r\n",
                bytes.len()
            );
            let _ = w.write_all(&bytes);
            continue;
        };
        let (a, b) = spec.split_once('-').unwrap();
        let a: usize = a.parse().unwrap();
        let mut b: usize = if b.is_empty() {
            bytes.len() - 1
        } else {
            b.parse().unwrap()
        };
        if a >= bytes.len() {
            drop(f);
            record("416");
            let _ = write!(
                w,
                "HTTP/1.1 416 Range Not Satisfiable\r\nContent-Range: bytes */{}\r\nContent-Length: 0\r\n\r\n",
                bytes.len()
            );
            continue;
        }
        // As real servers do, a range past the end is cut at the end.
        b = b.min(bytes.len() - 1);
        let served = log
            .lock()
            .unwrap()
            .iter()
            .filter(|l| l.outcome == "206")
            .count();
        if f.hang_after.is_some_and(|n| served >= n) {
            drop(f);
            record("hang");
            while !stop.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(20));
            }
            return;
        }
        let (drop_mid, stall, short) = (
            take(&mut f.drop_mid_body),
            take(&mut f.stall),
            take(&mut f.short_range),
        );
        let stall_for = f.stall_for;
        drop(f);
        if short {
            b -= 10;
        }
        let body = &bytes[a..=b];
        let head = format!(
            "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes {a}-{b}/{}\r\nContent-Length: {}\r\n\r\n",
            bytes.len(),
            body.len()
        );
        let _ = w.write_all(head.as_bytes());
        if drop_mid {
            record("dropped");
            let _ = w.write_all(&body[..body.len() / 2]);
            let _ = w.shutdown(std::net::Shutdown::Both);
            return;
        }
        if stall {
            record("stalled");
            std::thread::sleep(stall_for);
            return;
        }
        let _ = w.write_all(body);
        record(if short { "short" } else { "206" });
    }
}

fn stratus(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stratus"))
        .args(args)
        .output()
        .expect("run stratus")
}

/// `fetch` of the 2015 run from `server` into `out`, with quick retries.
fn fetch(server: &Server, out: &Path, extra: &[&str]) -> Output {
    let mut a = vec!["fetch"];
    a.extend_from_slice(&RUN);
    a.extend_from_slice(&[
        "--resolution",
        "2p50",
        "--source",
        &server.base,
        "--out",
        out.to_str().unwrap(),
        "--backoff-ms",
        "20",
        "--timeout",
        "1",
    ]);
    if !extra.contains(&"--retries") {
        a.extend_from_slice(&["--retries", "3"]);
    }
    a.extend_from_slice(extra);
    stratus(&a)
}

/// What the default fields are, decided from the file itself (not its inventory): the bytes
/// of every message holding RH, gh, u or v at 100–1000 hPa, cloud-layer TCDC, surface HGT or
/// LAND, in file order.
fn expected_default(file: &Path) -> Vec<u8> {
    let bytes = std::fs::read(file).unwrap();
    let wanted = |m: &MessageInfo| {
        let p = m.parameter();
        let iso = m
            .pressure_hpa()
            .is_some_and(|h| (100.0..=1000.0).contains(&h));
        let layer = matches!(
            m.level_type,
            Some(
                SurfaceType::LowCloudLayer
                    | SurfaceType::MiddleCloudLayer
                    | SurfaceType::HighCloudLayer
            )
        );
        let surface = m.level_type == Some(SurfaceType::Surface);
        (iso && matches!(p, (0, 1, 1) | (0, 3, 5) | (0, 2, 2) | (0, 2, 3)))
            || (layer && p == (0, 6, 1))
            || (surface && (p == (0, 3, 5) || p == (2, 0, 0)))
    };
    pick_bytes(&bytes, wanted)
}

fn pick_bytes(bytes: &[u8], wanted: impl Fn(&MessageInfo) -> bool) -> Vec<u8> {
    let fields = grib::scan(bytes).unwrap();
    let mut out = Vec::new();
    let mut last = None;
    for m in fields.iter().filter(|m| wanted(m)) {
        if last != Some(m.index) {
            out.extend_from_slice(&bytes[m.offset..m.offset + m.length]);
            last = Some(m.index);
        }
    }
    out
}

fn out_file(out: &Path, step: &str) -> PathBuf {
    out.join(format!("gfs.20150912.t18z.pgrb2.2p50.{step}.grib2"))
}

/// The regular files in `out` outside the cache: what a failed run must not have left.
fn files_in(out: &Path) -> Vec<String> {
    match std::fs::read_dir(out) {
        Ok(d) => d
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name() != ".stratus-cache")
            .map(|e| e.file_name().to_string_lossy().to_string())
            .collect(),
        Err(_) => Vec::new(),
    }
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// Exit 2, one line naming `needle`, and no step file.
fn assert_refused(o: &Output, out: &Path, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(
        err.starts_with("error: ") && err.contains(needle),
        "{needle}: {err}"
    );
    assert!(files_in(out).is_empty(), "left {:?}", files_in(out));
}

#[test]
fn fetches_the_right_messages_byte_for_byte() {
    let (_d, root) = tree();
    let server = Server::start(&root, Faults::default());
    let out = _d.path().join("out");
    let o = fetch(&server, &out, &["--step", "0,6"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for s in ["f000", "f006"] {
        let want = expected_default(&sample(&format!("gfs-series/gfs.t18z.pgrb2.2p50.{s}")));
        let got = std::fs::read(out_file(&out, s)).unwrap();
        assert!(
            got.len() > 100_000 && got == want,
            "{s}: {} vs {} bytes",
            got.len(),
            want.len()
        );
    }
    // Only the inventories were read whole; everything else by range, merged where adjacent.
    let log = server.log();
    let whole: Vec<_> = log
        .iter()
        .filter(|l| l.range.is_none())
        .map(|l| l.path.clone())
        .collect();
    assert!(
        whole.len() == 2 && whole.iter().all(|p| p.ends_with(".idx")),
        "{whole:?}"
    );
    let ranges = server.served_ranges().len();
    let lines = String::from_utf8_lossy(&o.stdout);
    assert!(lines.contains("range(s)") && ranges >= 4, "{lines}");
    // The cache is emptied (and removed) once the files are in place.
    assert!(!out.join(".stratus-cache").exists());

    // A multi-field message (u and v packed together in the 2011 file) and a level list.
    let o = stratus(&[
        "fetch",
        "--date",
        "2011-01-10",
        "--cycle",
        "12",
        "--step",
        "120",
        "--resolution",
        "2p50",
        "--fields",
        "r,u",
        "--levels",
        "850,500",
        "--source",
        &server.base,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let src = std::fs::read(sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2")).unwrap();
    let want = pick_bytes(&src, |m| {
        matches!(m.parameter(), (0, 1, 1) | (0, 2, 2))
            && m.pressure_hpa().is_some_and(|h| h == 850.0 || h == 500.0)
    });
    let got = std::fs::read(out.join("gfs.20110110.t12z.pgrb2.2p50.f120.grib2")).unwrap();
    assert_eq!(got, want);
    // What was written reads back as GRIB2 with u and v both there.
    let fields = grib::scan(&got).unwrap();
    assert_eq!(fields.len(), 6, "RH, u and v at two levels");
}

#[test]
fn transient_faults_are_retried() {
    let (_d, root) = tree();
    let want = expected_default(&sample("gfs-series/gfs.t18z.pgrb2.2p50.f006"));
    let cases: [(&str, Faults); 4] = [
        (
            "dropped",
            Faults {
                drop_mid_body: 2,
                ..Faults::default()
            },
        ),
        (
            "503",
            Faults {
                status_503: 2,
                ..Faults::default()
            },
        ),
        (
            "stalled",
            Faults {
                stall: 1,
                stall_for: Duration::from_millis(2500),
                ..Faults::default()
            },
        ),
        (
            "short",
            Faults {
                short_range: 1,
                ..Faults::default()
            },
        ),
    ];
    for (what, faults) in cases {
        let server = Server::start(&root, faults);
        let out = _d.path().join(format!("out-{what}"));
        let o = fetch(&server, &out, &["--step", "6"]);
        assert!(o.status.success(), "{what}: {}", stderr(&o));
        assert_eq!(
            std::fs::read(out_file(&out, "f006")).unwrap(),
            want,
            "{what}"
        );
        let log = server.log();
        let faulted: Vec<&Logged> = log.iter().filter(|l| l.outcome == what).collect();
        assert!(!faulted.is_empty(), "{what}: the fault happened");
        // Each faulted request was asked again and then answered whole.
        for f in faulted {
            assert!(
                log.iter()
                    .any(|l| l.path == f.path && l.range == f.range && l.outcome == "206")
                    || (what == "503" && f.range.is_none()),
                "{what}: {f:?} retried"
            );
        }
    }
}

#[test]
fn what_cannot_succeed_exits_2_with_one_line_and_no_file() {
    let (d, root) = tree();
    let forever = 1000;
    let cases: [(&str, Faults, &str); 4] = [
        (
            "503",
            Faults {
                status_503: forever,
                ..Faults::default()
            },
            "HTTP 503 (gave up after 2 tries)",
        ),
        (
            "dropped",
            Faults {
                drop_mid_body: forever,
                ..Faults::default()
            },
            "gave up after 2 tries",
        ),
        (
            "stalled",
            Faults {
                stall: forever,
                stall_for: Duration::from_secs(3),
                ..Faults::default()
            },
            "gave up after 2 tries",
        ),
        (
            "short",
            Faults {
                short_range: forever,
                ..Faults::default()
            },
            "does not answer bytes",
        ),
    ];
    for (what, faults, needle) in cases {
        let server = Server::start(&root, faults);
        let out = d.path().join(format!("out-{what}"));
        let o = fetch(&server, &out, &["--step", "6", "--retries", "1"]);
        assert_refused(&o, &out, needle);
        assert!(stderr(&o).contains(&server.base), "{what}: names the URL");
    }

    // A missing inventory: not retried, named.
    let server = Server::start(&root, Faults::default());
    let out = d.path().join("out-noidx");
    let f000_idx =
        std::fs::read_to_string(root.join(SERIES).join("gfs.t18z.pgrb2.2p50.f000.idx")).unwrap();
    std::fs::remove_file(root.join(SERIES).join("gfs.t18z.pgrb2.2p50.f000.idx")).unwrap();
    let o = fetch(&server, &out, &["--step", "0"]);
    assert_refused(
        &o,
        &out,
        "gfs.t18z.pgrb2.2p50.f000.idx: not found (HTTP 404)",
    );
    assert_eq!(server.log().len(), 1, "a 404 is not retried");

    // An inventory that does not match its file: f006's inventory served for f000, then one
    // whose offsets are shifted.
    let dir = root.join(SERIES);
    std::fs::copy(
        dir.join("gfs.t18z.pgrb2.2p50.f006.idx"),
        dir.join("gfs.t18z.pgrb2.2p50.f000.idx"),
    )
    .unwrap();
    let out = d.path().join("out-mismatch");
    let o = fetch(&server, &out, &["--step", "0"]);
    assert_refused(&o, &out, "does not match the file");
    let shifted: String = f000_idx
        .lines()
        .map(|l| {
            let mut f: Vec<String> = l.split(':').map(String::from).collect();
            f[1] = (f[1].parse::<u64>().unwrap() + 8).to_string();
            f.join(":") + "\n"
        })
        .collect();
    std::fs::write(dir.join("gfs.t18z.pgrb2.2p50.f000.idx"), shifted).unwrap();
    let o = fetch(&server, &out, &["--step", "0"]);
    assert_refused(
        &o,
        &out,
        "does not match the file: no GRIB message starts at byte",
    );
    // A field the run does not have.
    let o = fetch(
        &server,
        &out,
        &["--step", "6", "--fields", "r@2 m above ground,ICEC"],
    );
    assert_refused(&o, &out, "has no ICEC");
}

#[test]
fn an_interrupted_fetch_resumes_with_only_what_is_missing() {
    let (d, root) = tree();
    let out = d.path().join("out");
    let server = Server::start(
        &root,
        Faults {
            hang_after: Some(3),
            ..Faults::default()
        },
    );
    let mut child = Command::new(env!("CARGO_BIN_EXE_stratus"))
        .args([
            "fetch",
            "--date",
            "2015-09-12",
            "--cycle",
            "18",
            "--step",
            "6",
        ])
        .args([
            "--resolution",
            "2p50",
            "--source",
            &server.base,
            "--parallel",
            "1",
        ])
        .arg("--out")
        .arg(&out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !server.log().iter().any(|l| l.outcome == "hang") {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "the fetch never reached the hang"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // The three ranges answered are in the cache once their writes are committed.
    let cache = out.join(".stratus-cache");
    while std::fs::read_dir(&cache).map_or(0, |d| d.count()) < 3 {
        assert!(t0.elapsed() < Duration::from_secs(20), "ranges not cached");
        std::thread::sleep(Duration::from_millis(20));
    }
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "interrupted by INT");
    assert!(
        files_in(&out).is_empty(),
        "no step file: {:?}",
        files_in(&out)
    );
    let first = server.served_ranges();
    assert_eq!(first.len(), 3);
    drop(server);

    let server = Server::start(&root, Faults::default());
    let o = fetch(&server, &out, &["--step", "6"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let want = expected_default(&sample("gfs-series/gfs.t18z.pgrb2.2p50.f006"));
    assert_eq!(std::fs::read(out_file(&out, "f006")).unwrap(), want);
    let second = server.served_ranges();
    assert!(
        second.iter().all(|r| !first.contains(r)),
        "re-fetched: {first:?} in {second:?}"
    );
    // Together the two runs asked for each range once: the same set a fresh run asks for.
    let fresh = Server::start(&root, Faults::default());
    let o = fetch(&fresh, &d.path().join("fresh"), &["--step", "6"]);
    assert!(o.status.success());
    let mut all: Vec<String> = first.into_iter().chain(second).collect();
    let mut want_all = fresh.served_ranges();
    all.sort();
    want_all.sort();
    assert_eq!(all, want_all);
    assert!(String::from_utf8_lossy(&o.stdout).contains("0 from the cache"));
}
