//! `stratus fetch` end to end through the binary, against a small HTTP/1.1 server on 127.0.0.1
//! that serves the GFS files in data-samples in NOMADS' layout with `.idx` inventories made by
//! the ingest crate's generator, honours `Range`, and injects faults: a connection dropped
//! mid-range, 503s, a server too slow for the timeout, a range answered with the wrong length,
//! an inventory that does not match its file, a missing inventory, a server that hangs so
//! the fetch can be interrupted and resumed, and issue 28's: zeros instead of the file, bytes
//! shifted by one under honest headers, 404s after a few ranges, a redirect to nowhere, a
//! Content-Range ending at u64::MAX, ranges held back to race two fetches.

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
    /// After this many whole range answers, answer every further range request 404.
    fail_after: Option<usize>,
    /// Send the bytes one after the range asked for, under honest headers.
    shift: bool,
    /// Answer every range with zeros (of a file this large), whatever the file holds.
    zeros: Option<u64>,
    /// Answer a range to the end of the file with `Content-Range: bytes A-18446744073709551615/*`
    /// and no body.
    huge_content_range: bool,
    /// Answer every request with a redirect here.
    redirect_to: Option<String>,
    /// Wait this long before answering each of the next N ranges of a path containing this.
    delay: Option<(String, Duration, u32)>,
}

#[derive(Debug, Clone)]
struct Logged {
    path: String,
    range: Option<String>,
    outcome: &'static str,
    /// Body bytes the connection took.
    sent: u64,
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
        let record_sent = |outcome: &'static str, sent: u64| {
            log.lock().unwrap().push(Logged {
                path: path.clone(),
                range: range.clone(),
                outcome,
                sent,
            })
        };
        let record = |outcome: &'static str| record_sent(outcome, 0);
        let mut f = faults.lock().unwrap();
        if let Some(to) = f.redirect_to.clone() {
            drop(f);
            record("302");
            let _ = write!(
                w,
                "HTTP/1.1 302 Found\r\nLocation: {to}\r\nContent-Length: 0\r\n\r\n"
            );
            continue;
        }
        if let (Some(total), Some(spec)) = (
            f.zeros,
            range.as_deref().and_then(|r| r.strip_prefix("bytes=")),
        ) {
            drop(f);
            let (a, b) = spec.split_once('-').unwrap();
            let a: u64 = a.parse().unwrap();
            let b: u64 = b.parse().unwrap_or(total - 1);
            let _ = write!(
                w,
                "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes {a}-{b}/{total}\r\nContent-Length: {}\r\n\r\n",
                b - a + 1
            );
            let zeros = vec![0u8; 64 * 1024];
            let (mut left, mut sent) = (b - a + 1, 0);
            while left > 0 {
                let n = left.min(zeros.len() as u64);
                if w.write_all(&zeros[..n as usize]).is_err() {
                    break;
                }
                (left, sent) = (left - n, sent + n);
            }
            record_sent(if left == 0 { "206" } else { "cut" }, sent);
            if left > 0 {
                return;
            }
            continue;
        }
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
        if f.fail_after.is_some_and(|n| served >= n) {
            drop(f);
            record("404");
            let _ = w.write_all(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n");
            continue;
        }
        if f.huge_content_range && spec.ends_with('-') {
            drop(f);
            record("huge");
            let _ = write!(
                w,
                "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes {a}-18446744073709551615/*\r\nContent-Length: 0\r\n\r\n"
            );
            continue;
        }
        let delay = match &mut f.delay {
            Some((p, wait, n)) if path.contains(p.as_str()) && *n > 0 => {
                *n -= 1;
                Some(*wait)
            }
            _ => None,
        };
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
        let shift = usize::from(f.shift && b + 1 < bytes.len());
        drop(f);
        if let Some(wait) = delay {
            std::thread::sleep(wait);
        }
        if short {
            b -= 10;
        }
        let body = &bytes[a + shift..=b + shift];
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
        record_sent(if short { "short" } else { "206" }, body.len() as u64);
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

/// `fetch --step 6` of the 2015 run from `server` into `out`, running, its stderr piped.
fn spawn_fetch(server: &Server, out: &Path) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_stratus"))
        .arg("fetch")
        .args(RUN)
        .args([
            "--step",
            "6",
            "--resolution",
            "2p50",
            "--source",
            &server.base,
        ])
        .arg("--out")
        .arg(out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap()
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
    assert_refused(&o, &out, "the server's bytes do not match the inventory");
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
    assert_refused(&o, &out, "no GRIB message starts at byte");
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

fn idx_of(root: &Path, step: &str) -> PathBuf {
    root.join(SERIES)
        .join(format!("gfs.t18z.pgrb2.2p50.{step}.idx"))
}

/// Range requests the server saw (whatever it answered).
fn range_requests(server: &Server) -> usize {
    server.log().iter().filter(|l| l.range.is_some()).count()
}

/// The cached ranges in `dir`.
/// A fetch of step 6 into `out` that failed after `n` ranges, one at a time: its `n` cached
/// range files.
fn partly_cached(root: &Path, out: &Path, n: usize) -> Vec<PathBuf> {
    let server = Server::start(
        root,
        Faults {
            fail_after: Some(n),
            ..Faults::default()
        },
    );
    let o = fetch(&server, out, &["--step", "6", "--parallel", "1"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let cached = range_files(&out.join(".stratus-cache"));
    assert_eq!(cached.len(), n, "{cached:?}");
    cached
}

fn range_files(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir).map_or_else(
        |_| Vec::new(),
        |d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "range"))
                .collect()
        },
    )
}

/// Wait up to `secs` for `child`; kill it and fail if it runs on.
fn wait_for(child: &mut std::process::Child, secs: u64) -> std::process::ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if t0.elapsed() > Duration::from_secs(secs) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("still running after {secs} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Issue 28, 1 and 2: inventories no GFS file can have are refused, naming the inventory,
/// before a single range is asked for: messages 600 MB apart (the server would send zeros),
/// 20 000 lines a byte apart, a line repeated, more lines than any inventory, a pick larger
/// than a GFS step.
#[test]
fn hostile_inventories_are_refused_before_any_range() {
    let (d, root) = tree();
    let idx = idx_of(&root, "f006");
    let real = std::fs::read_to_string(&idx).unwrap();
    let line = |n: usize, off: u64, name: &str, level: &str| {
        format!("{n}:{off}:d=2015091218:{name}:{level}:6 hour fcst:\n")
    };
    let apart_600mb: String = (0..4)
        .map(|i| {
            line(
                i + 1,
                i as u64 * 600_000_000,
                "RH",
                &format!("{} mb", 1000 - 100 * i),
            )
        })
        .collect();
    let one_byte_apart: String = (0..20_000)
        .map(|i| {
            line(
                i + 1,
                i as u64,
                if i % 2 == 0 { "RH" } else { "TMP" },
                "500 mb",
            )
        })
        .collect();
    let mut repeated: Vec<&str> = real.lines().collect();
    repeated.insert(5, repeated[4]);
    let repeated = repeated.join("\n") + "\n";
    let too_many: String = (0..10_001)
        .map(|i| line(i + 1, i as u64 * 100, "TMP", "500 mb"))
        .collect();
    // 46 RH levels 30 MB apart: each message within bounds, the step 1.4 GB.
    let too_big: String = (0..46)
        .map(|i| {
            line(
                i + 1,
                i as u64 * 30_000_000,
                "RH",
                &format!("{} mb", 1000 - 20 * i),
            )
        })
        .collect();
    let cases = [
        (apart_600mb, "more than a GFS message can be"),
        (one_byte_apart, "a GRIB2 message is at least 86"),
        (repeated, "line 6: repeats line 5"),
        (too_many, "more than 10000 lines"),
        (too_big, "more than a GFS step can be"),
    ];
    for (i, (text, needle)) in cases.into_iter().enumerate() {
        std::fs::write(&idx, text).unwrap();
        let server = Server::start(
            &root,
            Faults {
                zeros: Some(100_000_000_000),
                ..Faults::default()
            },
        );
        let out = d.path().join(format!("out{i}"));
        let o = fetch(&server, &out, &["--step", "6", "--levels", "all"]);
        assert_refused(&o, &out, needle);
        assert!(
            stderr(&o).contains("f006.idx: bad inventory"),
            "{}",
            stderr(&o)
        );
        assert_eq!(range_requests(&server), 0, "{needle}: ranges asked for");
        assert!(range_files(&out.join(".stratus-cache")).is_empty());
    }
}

/// Issue 28, 1: a server that sends zeros where the inventory places messages (each within
/// the bounds) is refused as the first bytes arrive, not after it sent the ranges.
#[test]
fn bytes_that_are_not_the_message_are_refused_as_they_arrive() {
    let (d, root) = tree();
    let apart: String = (0..3)
        .map(|i| {
            format!(
                "{}:{}:d=2015091218:RH:{} mb:6 hour fcst:\n",
                i + 1,
                i * 30_000_000,
                1000 - 100 * i
            )
        })
        .collect();
    std::fs::write(idx_of(&root, "f006"), apart).unwrap();
    let server = Server::start(
        &root,
        Faults {
            zeros: Some(90_000_000),
            ..Faults::default()
        },
    );
    let out = d.path().join("out");
    let o = fetch(&server, &out, &["--step", "6", "--fields", "r"]);
    assert_refused(&o, &out, "no GRIB message starts at byte");
    assert!(
        stderr(&o).contains("the server's bytes do not match the inventory"),
        "{}",
        stderr(&o)
    );
    let log = server.log();
    let ranges: Vec<&Logged> = log.iter().filter(|l| l.range.is_some()).collect();
    assert!(!ranges.is_empty());
    for l in ranges {
        assert!(
            l.sent < 15_000_000,
            "{l:?}: the server sent most of the range"
        );
    }
    assert!(range_files(&out.join(".stratus-cache")).is_empty());
}

/// Issue 28, 3: a server that shifts every range by a byte under honest headers leaves
/// nothing in the cache, the message says the server's bytes are wrong, and one run against
/// an honest server then succeeds.
#[test]
fn a_lying_server_leaves_nothing_cached_and_one_honest_run_recovers() {
    let (d, root) = tree();
    let out = d.path().join("out");
    let liar = Server::start(
        &root,
        Faults {
            shift: true,
            ..Faults::default()
        },
    );
    let o = fetch(&liar, &out, &["--step", "6", "--parallel", "4"]);
    assert_refused(&o, &out, "the server's bytes do not match the inventory");
    assert!(
        range_files(&out.join(".stratus-cache")).is_empty(),
        "bad ranges cached"
    );
    drop(liar);
    let server = Server::start(&root, Faults::default());
    let o = fetch(&server, &out, &["--step", "6"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let want = expected_default(&sample("gfs-series/gfs.t18z.pgrb2.2p50.f006"));
    assert_eq!(std::fs::read(out_file(&out, "f006")).unwrap(), want);
}

/// Issue 28, 3 and 13: cached ranges changed on disk are all found on the next run, dropped
/// and downloaded again in that one run; the file is right.
#[test]
fn changed_cached_ranges_are_found_and_fetched_again() {
    let (d, root) = tree();
    let out = d.path().join("out");
    let cached = partly_cached(&root, &out, 3);
    for p in &cached {
        let mut b = std::fs::read(p).unwrap();
        let mid = b.len() / 2;
        b[mid] ^= 0x40;
        std::fs::write(p, b).unwrap();
    }
    let server = Server::start(&root, Faults::default());
    let o = fetch(&server, &out, &["--step", "6"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let want = expected_default(&sample("gfs-series/gfs.t18z.pgrb2.2p50.f006"));
    assert_eq!(std::fs::read(out_file(&out, "f006")).unwrap(), want);
    let err = stderr(&o);
    assert_eq!(
        err.matches("dropped that cached range").count(),
        3,
        "each named: {err}"
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains(" 0 from the cache"));
}

/// The bodies (after the 5-byte header) of section `num` of every message in `bytes` that
/// holds RH.
fn rh_sections(bytes: &[u8], num: u8) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    for f in grib::scan(bytes).unwrap() {
        if f.parameter() != (0, 1, 1) {
            continue;
        }
        let mut at = f.offset + 16;
        while at + 5 <= f.offset + f.length && &bytes[at..at + 4] != b"7777" {
            let len = u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
            if bytes[at + 4] == num {
                out.push(at + 5..at + len);
            }
            at += len;
        }
    }
    out
}

/// Issue 28, 13: RH messages damaged with their headers intact (so the inventory and the
/// validator agree) are refused, naming the message: data sections of all ones (which do not
/// decode), and a reference value of 5000 in the data representation section (which decodes,
/// to RH in the thousands).
#[test]
fn damaged_data_sections_are_refused() {
    let (d, root) = tree();
    let file = root.join(SERIES).join("gfs.t18z.pgrb2.2p50.f006");
    let real = std::fs::read(&file).unwrap();
    let all_ones = |b: &mut Vec<u8>| {
        for s in rh_sections(b, 7) {
            b[s].fill(0xFF);
        }
    };
    let reference_5000 = |b: &mut Vec<u8>| {
        // Template 5.x: the reference value R, an IEEE float, is octets 12-15.
        for s in rh_sections(b, 5) {
            b[s.start + 6..s.start + 10].copy_from_slice(&5000f32.to_be_bytes());
        }
    };
    type Damage<'a> = &'a dyn Fn(&mut Vec<u8>);
    let cases: [(Damage, &str); 2] = [
        (&all_ones, "data section does not decode"),
        (&reference_5000, "outside 0..=101 %, what RH can be"),
    ];
    for (i, (damage, needle)) in cases.into_iter().enumerate() {
        let mut bytes = real.clone();
        damage(&mut bytes);
        assert_ne!(bytes, real);
        std::fs::write(&file, &bytes).unwrap();
        std::fs::write(
            idx_of(&root, "f006"),
            idx::write(&bytes, &grib::scan(&bytes).unwrap()),
        )
        .unwrap();
        let server = Server::start(&root, Faults::default());
        let out = d.path().join(format!("out{i}"));
        let o = fetch(&server, &out, &["--step", "6", "--fields", "r"]);
        assert_refused(&o, &out, "the server sent a damaged message: message");
        assert!(stderr(&o).contains(needle), "{}", stderr(&o));
        assert!(range_files(&out.join(".stratus-cache")).is_empty());
    }
}

/// Issue 28, 4: two fetches into one --out at once both succeed; the second waits for the
/// first's lock on the cache, and neither removes what the other uses.
#[test]
fn two_fetches_into_one_out_at_once_both_succeed() {
    let (d, root) = tree();
    let out = d.path().join("out");
    let server = Server::start(
        &root,
        Faults {
            // The slow fetch's first 16 ranges (all it asks for at first) wait 3 s.
            delay: Some(("f006".into(), Duration::from_secs(3), 16)),
            ..Faults::default()
        },
    );
    let spawn = |step: &str, parallel: &str| {
        let mut a: Vec<&str> = vec!["fetch"];
        a.extend_from_slice(&RUN);
        a.extend_from_slice(&["--step", step, "--resolution", "2p50", "--source"]);
        Command::new(env!("CARGO_BIN_EXE_stratus"))
            .args(a)
            .arg(&server.base)
            .arg("--out")
            .arg(&out)
            .args([
                "--timeout",
                "10",
                "--backoff-ms",
                "20",
                "--parallel",
                parallel,
            ])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let slow = spawn("6", "16");
    let t0 = Instant::now();
    while !server.log().iter().any(|l| l.path.contains("f006.idx")) {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "the first never started"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // The slow one is waiting for its first range (its cache folder empty) when the fast one
    // starts.
    std::thread::sleep(Duration::from_millis(300));
    let fast = spawn("0", "4");
    let (fast, slow) = (
        fast.wait_with_output().unwrap(),
        slow.wait_with_output().unwrap(),
    );
    assert!(slow.status.success(), "slow: {}", stderr(&slow));
    assert!(fast.status.success(), "fast: {}", stderr(&fast));
    assert!(
        stderr(&fast).contains("waiting for another stratus fetch"),
        "{}",
        stderr(&fast)
    );
    for s in ["f000", "f006"] {
        let want = expected_default(&sample(&format!("gfs-series/gfs.t18z.pgrb2.2p50.{s}")));
        assert_eq!(std::fs::read(out_file(&out, s)).unwrap(), want, "{s}");
    }
    assert!(!out.join(".stratus-cache").exists());
}

/// Issue 28, 9: a --cache folder that existed (empty) is kept after a success; one the run
/// created is removed when empty, with the parents it created.
#[test]
fn a_cache_folder_that_existed_is_kept() {
    let (d, root) = tree();
    let server = Server::start(&root, Faults::default());
    let mine = d.path().join("mycache");
    std::fs::create_dir(&mine).unwrap();
    let out = d.path().join("out");
    let o = fetch(
        &server,
        &out,
        &["--step", "6", "--cache", mine.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(mine.is_dir(), "the user's cache folder was removed");
    let new = d.path().join("new").join("cache");
    let o = fetch(
        &server,
        &out,
        &["--step", "0", "--cache", new.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!d.path().join("new").exists());
}

/// Issue 28, 10: a step needs its size once on disk (the file is made from the cache, each
/// range removed as it is copied), and a file system without room for it is refused before
/// any range is downloaded, with one line saying what is needed and what is free. On a tmpfs
/// of a chosen size, mounted in a user namespace (`unshare -rm`).
#[test]
fn a_step_needs_its_size_once_and_a_full_disk_is_refused_at_once() {
    let probe = Command::new("unshare").args(["-rm", "true"]).status();
    if !probe.is_ok_and(|s| s.success()) {
        eprintln!("skipped: no user namespaces here (unshare -rm) to mount a small tmpfs");
        return;
    }
    let (d, root) = tree();
    let want = expected_default(&sample("gfs-series/gfs.t18z.pgrb2.2p50.f006"));
    let step = want.len() as u64;
    let run = |kib: u64, tag: &str| -> (Output, Server) {
        let server = Server::start(&root, Faults::default());
        let mnt = d.path().join(format!("mnt-{tag}"));
        let keep = d.path().join(format!("kept-{tag}"));
        std::fs::create_dir(&mnt).unwrap();
        let script = format!(
            "mount -t tmpfs -o size={kib}k tmpfs \"$1\" && \"$2\" fetch {} --step 6 --resolution 2p50 \
             --source \"$3\" --out \"$1/out\" --timeout 5 --backoff-ms 20; rc=$?; \
             cp \"$1/out/gfs.20150912.t18z.pgrb2.2p50.f006.grib2\" \"$4\" 2>/dev/null; exit $rc",
            RUN.join(" ")
        );
        let o = Command::new("unshare")
            .args(["-rm", "sh", "-c", &script, "sh"])
            .arg(&mnt)
            .arg(env!("CARGO_BIN_EXE_stratus"))
            .arg(&server.base)
            .arg(&keep)
            .output()
            .unwrap();
        (o, server)
    };
    // Room for 1.6 times the step: enough once (with 8 KiB a range file for its last block
    // and trailer), not twice.
    let (o, _s) = run(step * 8 / 5 / 1024, "fits");
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(d.path().join("kept-fits")).unwrap(), want);
    // Room for half the step: refused before any range.
    let (o, server) = run(step / 2 / 1024, "full");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("not enough free space for gfs.20150912.t18z.pgrb2.2p50.f006.grib2")
            && err.contains("available"),
        "{err}"
    );
    assert_eq!(range_requests(&server), 0);
}

/// Issue 28, 14: a FIFO where a cached range should be is refused at once, not waited on.
#[test]
fn a_fifo_in_the_cache_is_refused_not_waited_on() {
    let (d, root) = tree();
    let out = d.path().join("out");
    let cached = partly_cached(&root, &out, 1);
    std::fs::remove_file(&cached[0]).unwrap();
    assert!(Command::new("mkfifo")
        .arg(&cached[0])
        .status()
        .unwrap()
        .success());
    let server = Server::start(&root, Faults::default());
    let mut child = spawn_fetch(&server, &out);
    let status = wait_for(&mut child, 20);
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(2), "{err}");
    assert!(
        err.contains("a cached range is a FIFO (named pipe), not a regular file"),
        "{err}"
    );
}

/// Issue 28, 15: a failed redirect names the URL that failed; a password in --source is never
/// printed (errors and logs); a source without a host is refused; a Content-Range whose end
/// is u64::MAX does not wrap to an empty range.
#[test]
fn lines_say_what_failed_and_hide_passwords() {
    let (d, root) = tree();
    let out = d.path().join("out");
    let server = Server::start(
        &root,
        Faults {
            redirect_to: Some("http://127.0.0.1:1/elsewhere/moved.idx".into()),
            ..Faults::default()
        },
    );
    let o = fetch(&server, &out, &["--step", "6", "--retries", "0"]);
    assert_refused(
        &o,
        &out,
        "redirected to http://127.0.0.1:1/elsewhere/moved.idx",
    );

    let server = Server::start(
        &root,
        Faults {
            status_503: 2,
            ..Faults::default()
        },
    );
    let secret = server.base.replace("http://", "http://fred:s3cret@");
    let mut a = vec!["fetch"];
    a.extend_from_slice(&RUN);
    a.extend_from_slice(&["--step", "12", "--resolution", "2p50", "--source", &secret]);
    a.extend_from_slice(&["--out", out.to_str().unwrap(), "--backoff-ms", "20"]);
    let o = Command::new(env!("CARGO_BIN_EXE_stratus"))
        .args(&a)
        .env("RUST_LOG", "info")
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("try 1 of"), "the retries are logged: {err}");
    assert!(!err.contains("s3cret"), "{err}");
    assert!(err.contains("fred:***@127.0.0.1"), "{err}");

    for source in ["http://", "https:///pub/", "http://fred:s3cret@/pub/"] {
        let o = stratus(&[
            "fetch",
            "--date",
            "2015-09-12",
            "--cycle",
            "18",
            "--step",
            "6",
            "--source",
            source,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_refused(&o, &out, "names no host");
        assert!(!stderr(&o).contains("s3cret"));
    }

    // The last message of a file runs to its end: its range is asked for open-ended. A
    // file of one RH message, so that range starts at byte 0.
    let file = root.join(SERIES).join("gfs.t18z.pgrb2.2p50.f006");
    let bytes = std::fs::read(&file).unwrap();
    let fields = grib::scan(&bytes).unwrap();
    let rh = fields
        .iter()
        .find(|f| f.parameter() == (0, 1, 1) && f.pressure_hpa() == Some(500.0))
        .unwrap();
    let one = &bytes[rh.offset..rh.offset + rh.length];
    std::fs::write(&file, one).unwrap();
    std::fs::write(
        idx_of(&root, "f006"),
        idx::write(one, &grib::scan(one).unwrap()),
    )
    .unwrap();
    let server = Server::start(
        &root,
        Faults {
            huge_content_range: true,
            ..Faults::default()
        },
    );
    let o = fetch(
        &server,
        &out,
        &["--step", "6", "--fields", "r", "--retries", "0"],
    );
    assert_refused(
        &o,
        &out,
        "Content-Range \"bytes 0-18446744073709551615/*\" does not answer bytes 0-end",
    );
}

/// Issue 28, 16: an interrupt before the first range removes the folders the run created
/// (OUT and its cache), and keeps an OUT that existed.
#[test]
fn an_interrupt_before_the_first_range_removes_what_the_run_created() {
    let (d, root) = tree();
    for existed in [false, true] {
        let server = Server::start(
            &root,
            Faults {
                hang_after: Some(0),
                ..Faults::default()
            },
        );
        let top = d.path().join(format!("new-{existed}"));
        let out = top.join("out");
        if existed {
            std::fs::create_dir_all(&out).unwrap();
        }
        let mut child = spawn_fetch(&server, &out);
        let t0 = Instant::now();
        while !server.log().iter().any(|l| l.outcome == "hang") {
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "never reached a range"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let kill = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        assert_eq!(wait_for(&mut child, 20).code(), Some(130));
        if existed {
            let left: Vec<_> = std::fs::read_dir(&out).unwrap().collect();
            assert!(left.is_empty(), "{left:?}");
        } else {
            assert!(
                !top.exists(),
                "left {:?}",
                std::fs::read_dir(&top).ok().map(|d| d.count())
            );
        }
    }
}

/// A level the inventory lacks: the error lists every level it has (the list was cut at 12 with
/// no mark, so 850 hPa and the levels below it were hidden).
#[test]
fn an_absent_level_lists_every_level_there_is() {
    let (_d, root) = tree();
    let server = Server::start(&root, Faults::default());
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = fetch(
        &server,
        &out,
        &["--step", "6", "--fields", "r", "--levels", "15"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("it has it at"), "{err}");
    for level in ["10 mb", "100 mb", "500 mb", "850 mb", "1000 mb"] {
        assert!(err.contains(&format!(" {level}")), "{level} missing: {err}");
    }
    assert!(!err.contains('…'), "{err}");
}
