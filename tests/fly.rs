//! The real `stratus fly` window under Xvfb (X11 + Mesa): a few frames, then a screenshot that
//! must show clouds and the control panel. An empty map from the same start is the control: the
//! clouds are what differs. Also: no display at all is a clear error, not a panic.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::region::Region;

/// A 640×360 Xvfb server on a free display, killed on drop. One at a time in this process:
/// two tests starting servers together could both pick the same free number, and the loser
/// would draw on the winner's server until it goes away.
struct Xvfb {
    child: Child,
    display: String,
    _one_at_a_time: MutexGuard<'static, ()>,
}

static ONE_SERVER: Mutex<()> = Mutex::new(());

impl Xvfb {
    fn start() -> Xvfb {
        let guard = ONE_SERVER.lock().unwrap_or_else(|e| e.into_inner());
        for n in 90..140 {
            if display_in_use(n) {
                continue;
            }
            let mut child = Command::new("Xvfb")
                .args([
                    &format!(":{n}"),
                    "-screen",
                    "0",
                    "1024x768x24",
                    "-nolisten",
                    "tcp",
                ])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("Xvfb is needed for the window test (Debian: apt-get install xvfb)");
            // Ready when the socket accepts a connection, not when its file exists: a server
            // killed before (SIGKILL, a test run cut off) leaves its socket file behind, and a
            // client that comes before the new server binds it is refused (CI, stop 39).
            let sock = format!("/tmp/.X11-unix/X{n}");
            let t0 = Instant::now();
            while t0.elapsed() < Duration::from_secs(10) {
                if let Ok(Some(status)) = child.try_wait() {
                    panic!("Xvfb :{n} exited at start: {status}");
                }
                if std::os::unix::net::UnixStream::connect(&sock).is_ok() {
                    return Xvfb {
                        child,
                        display: format!(":{n}"),
                        _one_at_a_time: guard,
                    };
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = child.kill();
            let _ = child.wait();
            panic!("Xvfb :{n} did not start within 10 s");
        }
        panic!("no free X display number in 90..140");
    }
}

/// Whether display `n` is taken: its lock file names a live process. A lock left by a server
/// that died (killed with its test run) is stale, and Xvfb takes the number over itself; read
/// as taken, 50 of them used up every number the tests try.
fn display_in_use(n: u32) -> bool {
    match std::fs::read_to_string(format!("/tmp/.X{n}-lock")) {
        Ok(pid) => match pid.trim().parse::<u32>() {
            Ok(pid) => Path::new(&format!("/proc/{pid}")).exists(),
            Err(_) => true,
        },
        Err(e) => e.kind() != std::io::ErrorKind::NotFound,
    }
}

impl Drop for Xvfb {
    /// SIGTERM first, so the server removes its lock and socket; SIGKILL if it lingers.
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(5) {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A map over the North Atlantic whose cover is `cover` everywhere, saved in `dir`.
fn map(dir: &Path, name: &str, cover: f64) -> PathBuf {
    let region = Region {
        south: 40.0,
        north: 50.0,
        west: -30.0,
        east: -15.0,
    };
    let m = CloudMap::from_fn(
        region,
        96,
        64,
        &[(LayerKind::Low, 1000.0, 3000.0)],
        chrono::DateTime::parse_from_rfc3339("2024-06-21T14:00:00Z")
            .expect("a valid time")
            .to_utc(),
        |_, _| [cover, 0.0, 0.0],
    );
    let png = dir.join(format!("{name}.png"));
    m.save(&png).expect("save map")
}

fn fly(display: Option<&str>, map: &Path, shot: &Path) -> std::process::Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_stratus"));
    c.args([
        "fly",
        map.to_str().unwrap(),
        "--window",
        "640x360",
        "--frames",
        "3",
        "--screenshot",
        shot.to_str().unwrap(),
    ])
    .env("RUST_LOG", "error")
    .env_remove("WAYLAND_DISPLAY");
    match display {
        Some(d) => c.env("DISPLAY", d),
        None => c.env_remove("DISPLAY"),
    };
    c.output().expect("run stratus fly")
}

struct Shot {
    w: usize,
    h: usize,
    rgb: Vec<[f32; 3]>,
}

impl Shot {
    fn load(p: &Path) -> Shot {
        let img = image::open(p).expect("screenshot is a PNG").to_rgb8();
        let (w, h) = (img.width() as usize, img.height() as usize);
        let rgb = img
            .pixels()
            .map(|p| [p[0], p[1], p[2]].map(|c| f32::from(c) / 255.0))
            .collect();
        Shot { w, h, rgb }
    }

    fn at(&self, x: usize, y: usize) -> [f32; 3] {
        self.rgb[y * self.w + x]
    }

    /// Pixels in columns x0..x1, rows y0..y1.
    fn area(&self, x0: usize, x1: usize, y0: usize, y1: usize) -> Vec<[f32; 3]> {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .map(|(x, y)| self.at(x, y))
            .collect()
    }
}

fn luma(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

#[test]
fn window_shows_clouds_and_the_panel() {
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let cloudy = map(dir.path(), "cloudy", 1.0);
    let clear = map(dir.path(), "clear", 0.0);
    let (s1, s0) = (
        // Not cloudy.png: that is the map's own PNG, which a screenshot may not replace.
        dir.path().join("cloudy-shot.png"),
        dir.path().join("clear-shot.png"),
    );
    let mut march_w = Vec::new();
    for (m, s) in [(&cloudy, &s1), (&clear, &s0)] {
        let o = fly(Some(&x.display), m, s);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "stratus fly failed: {err}");
        assert!(!err.contains("panicked"), "{err}");
        // "(march WxH, preset)": the march's size, from the `--frames` summary on stdout.
        let out = String::from_utf8_lossy(&o.stdout);
        let w = out
            .split("(march ")
            .nth(1)
            .and_then(|t| t.split('x').next())
            .and_then(|t| t.parse::<u32>().ok());
        march_w.push(w.unwrap_or_else(|| panic!("no march size in: {out}")));
    }
    // The clouds are marched beside the panel, not under it: at the CPU adapter's ¼ render
    // scale a march a quarter of the view's width, which ends where the panel begins (about
    // 290 px of the 640 are the panel's).
    for w in &march_w {
        assert!(
            (70..=100).contains(w),
            "march {w} px wide: not a quarter of the view beside the panel"
        );
    }
    let (a, b) = (Shot::load(&s1), Shot::load(&s0));
    assert_eq!((a.w, a.h), (640, 360), "screenshot is the window's size");

    // The panel: egui's dark grey on the right edge, with lighter text and widgets on it.
    let panel = a.area(a.w - 60, a.w - 4, 10, a.h - 10);
    let dark = panel.iter().filter(|c| luma(**c) < 0.15).count();
    let light = panel.iter().filter(|c| luma(**c) > 0.5).count();
    assert!(
        dark * 10 > panel.len() * 6,
        "panel background: {dark} of {} dark",
        panel.len()
    );
    assert!(
        light * 200 > panel.len(),
        "panel text: {light} of {} light",
        panel.len()
    );

    // The view: the lower half of the scene (below the horizon, the deck) left of the panel.
    let (x0, x1, y0, y1) = (a.w / 10, a.w / 2, a.h * 6 / 10, a.h * 9 / 10);
    let deck = a.area(x0, x1, y0, y1);
    let ground = b.area(x0, x1, y0, y1);
    let mean = |v: &[[f32; 3]]| v.iter().map(|c| luma(*c)).sum::<f32>() / v.len() as f32;
    // Blue over red: the clear view's sea lies under the air's blue light; cloud is whiter.
    let blue = |v: &[[f32; 3]]| v.iter().map(|c| c[2] - c[0]).sum::<f32>() / v.len() as f32;
    let changed = deck
        .iter()
        .zip(&ground)
        .map(|(d, g)| (0..3).map(|k| (d[k] - g[k]).abs()).sum::<f32>() / 3.0)
        .sum::<f32>()
        / deck.len() as f32;
    let (ld, lg) = (mean(&deck), mean(&ground));
    let (bd, bg) = (blue(&deck), blue(&ground));
    eprintln!(
        "deck luma {ld:.3} blue−red {bd:.3}, clear ground luma {lg:.3} blue−red {bg:.3}; \
         mean |Δ| {changed:.3}; panel {dark} dark / {light} light of {}",
        panel.len()
    );
    if let Ok(keep) = std::env::var("STRATUS_KEEP_SHOTS") {
        let _ = std::fs::copy(&s1, Path::new(&keep).join("fly-cloudy.png"));
        let _ = std::fs::copy(&s0, Path::new(&keep).join("fly-clear.png"));
    }
    // The same camera, time and exposure start in both runs: only the map differs, so what
    // differs is the cloud. The window adapts its exposure to each view, which narrows the
    // brightness gap (measured: luma 0.66 against 0.56, mean |Δ| 0.099, blue−red 0.100
    // against 0.262): the deck must change the view and be whiter than the sea.
    assert!(
        changed > 0.05,
        "the cloud deck hardly changes the view (mean |Δ| {changed:.3})"
    );
    assert!(
        bd + 0.08 < bg,
        "the cloud deck (blue−red {bd:.3}) must be whiter than the clear view (blue−red {bg:.3})"
    );
    // Not a blank frame: the view (sky over deck) has structure.
    let view = a.area(0, a.w * 7 / 10, 0, a.h);
    let m = mean(&view);
    let sd = (view.iter().map(|c| (luma(*c) - m).powi(2)).sum::<f32>() / view.len() as f32).sqrt();
    assert!(sd > 0.03, "view luma spread {sd:.4}: a blank frame");
    assert!(view.iter().flatten().all(|c| c.is_finite()));
}

/// The `HH:MM` after "valid YYYY-MM-DD " in the window's summary line, as minutes of the day.
fn valid_minutes(line: &str) -> Option<u32> {
    let at = line.find("valid 2015-09-12 ")? + "valid 2015-09-12 ".len();
    let hm = line.get(at..at + 5)?;
    let (h, m) = hm.split_once(':')?;
    Some(h.parse::<u32>().ok()? * 60 + m.parse::<u32>().ok()?)
}

/// The real +0/+6 h series in the window: the HUD's weather line (also printed in the
/// `--frames` summary) gives the moment and the steps around it; `--time` starts there and
/// `--time-rate 600` runs it on (at most MAX_STEP_S = 1 s of wall time a frame, so 4 frames
/// are at most 40 simulated minutes).
#[test]
fn window_flies_a_series_with_time_running() {
    let f0 = common::sample("gfs-series/gfs.t18z.pgrb2.2p50.f000");
    let f6 = common::sample("gfs-series/gfs.t18z.pgrb2.2p50.f006");
    if !(f0.is_file() && f6.is_file()) {
        panic!("data-samples/gfs-series not found");
    }
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("na.png");
    let o = common::stratus(&[
        "ingest",
        f0.to_str().unwrap(),
        f6.to_str().unwrap(),
        "--region",
        "30,70,-60,40",
        "--size",
        "256x128",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let series = dir.path().join("na.json");
    let shot = dir.path().join("shot.png");
    let run = |extra: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_stratus"))
            .args([
                "fly",
                series.to_str().unwrap(),
                "--window",
                "640x360",
                "--frames",
                "4",
                "--screenshot",
                shot.to_str().unwrap(),
            ])
            .args(extra)
            .env("RUST_LOG", "error")
            .env_remove("WAYLAND_DISPLAY")
            .env("DISPLAY", &x.display)
            .output()
            .expect("run stratus fly");
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(o.status.success(), "stratus fly failed: {err}");
        assert!(!err.contains("panicked"), "{err}");
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    let held = run(&["--time", "2015-09-12T23:00:00Z"]);
    eprintln!("{held}");
    assert!(
        held.contains("valid 2015-09-12 23:00 UTC · step +0 h → +6 h"),
        "{held}"
    );
    let running = run(&["--time", "2015-09-12T20:00:00Z", "--time-rate", "600"]);
    eprintln!("{running}");
    assert!(running.contains("step +0 h → +6 h · ×600"), "{running}");
    let m = valid_minutes(&running).expect("a valid time in the summary");
    assert!(
        m > 20 * 60 && m <= 20 * 60 + 40,
        "time ran to {:02}:{:02}, not within 40 min after 20:00",
        m / 60,
        m % 60
    );
    let s = Shot::load(&shot);
    assert_eq!((s.w, s.h), (640, 360));
}

#[test]
fn no_display_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let m = map(dir.path(), "m", 0.5);
    let shot = dir.path().join("s.png");
    let o = fly(None, &m, &shot);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("stratus render"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!shot.exists());
}
