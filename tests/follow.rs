//! `--follow` against test senders on loopback that speak each simulator's format as its
//! documentation gives it (written here from the documents, not with the library's encoders):
//! the pose is what was sent, garbage is counted and changes nothing, silence is reported, and
//! `flight --follow` records the same frame `render` makes at that camera, says where it waits,
//! reports the speed the aircraft flew and counts the frames a silent simulator left frozen.

mod common;
use common::{stratus, synthetic_map};

use std::net::UdpSocket;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use stratus::follow::{Follower, Kind, Source, FEET};

/// The aircraft every sender reports: 10 000 ft over the synthetic sample's region, heading
/// 45°, nose 12° down, wings level (`render` has no roll).
const LAT: f32 = 45.5;
const LON: f32 = -22.0;
const ALT_FT: f32 = 39_370.08;
const HEADING: f32 = 45.0;
const PITCH: f32 = -12.0;

/// X-Plane's data output ("Exchanging Data with X-Plane"): `DATA`, one internal byte, then
/// 36-byte rows of a little-endian i32 index and eight f32 values. Row 20: lat, lon, alt ft
/// MSL, alt ft AGL, on runway, indicated alt, lat south, lon west; row 17: pitch, roll, true
/// heading, magnetic heading; row 3: KIAS, KEAS, KTAS, KTGS, unused, then mph. Unused slots
/// hold -999.
fn xplane_packet(lat: f32, lon: f32, alt_ft: f32, heading: f32, pitch: f32, roll: f32) -> Vec<u8> {
    // An aircraft holding still (slewed): ground speed 0.
    xplane_rows(lat, lon, alt_ft, heading, pitch, roll, Some(0.0))
}

/// The same with the ground speed `ktgs` in row 3, or without row 3.
fn xplane_rows(
    lat: f32,
    lon: f32,
    alt_ft: f32,
    heading: f32,
    pitch: f32,
    roll: f32,
    ktgs: Option<f32>,
) -> Vec<u8> {
    let mut p = Vec::new();
    p.extend_from_slice(b"DATA");
    p.push(0);
    let mut rows: Vec<(i32, [f32; 8])> = vec![
        // Row 13 (trim, flaps), which users tick too: skipped.
        (13, [0.1, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0, 0.0]),
        (
            17,
            [
                pitch,
                roll,
                heading,
                heading + 3.0,
                -999.0,
                -999.0,
                -999.0,
                -999.0,
            ],
        ),
    ];
    if let Some(kt) = ktgs {
        rows.push((3, [kt, kt, kt, kt, -999.0, kt * 1.15, kt * 1.15, kt * 1.15]));
    }
    // Row 20 last: a packet cut short anywhere has no position (the garbage test's cuts).
    rows.push((20, [lat, lon, alt_ft, 2000.0, 0.0, alt_ft, -999.0, -999.0]));
    for (index, values) in rows {
        p.extend_from_slice(&index.to_le_bytes());
        for v in values {
            p.extend_from_slice(&v.to_le_bytes());
        }
    }
    p
}

/// FlightGear's generic protocol with docs/flightgear/stratus.xml: six `%f` chunks separated
/// by commas, a newline after each set.
fn flightgear_packet(
    lat: f64,
    lon: f64,
    alt_ft: f64,
    heading: f64,
    pitch: f64,
    roll: f64,
) -> Vec<u8> {
    format!("{lat:.6},{lon:.6},{alt_ft:.6},{heading:.6},{pitch:.6},{roll:.6}\n").into_bytes()
}

fn packet(kind: Kind) -> Vec<u8> {
    match kind {
        Kind::XPlane => xplane_packet(LAT, LON, ALT_FT, HEADING, PITCH, 0.0),
        Kind::FlightGear => flightgear_packet(
            LAT as f64,
            LON as f64,
            ALT_FT as f64,
            HEADING as f64,
            PITCH as f64,
            0.0,
        ),
    }
}

/// The camera a packet gives, as `render --camera` arguments that parse to the same f64s.
fn camera_arg(kind: Kind) -> String {
    let alt_m = match kind {
        Kind::XPlane => ALT_FT as f64 * FEET,
        Kind::FlightGear => format!("{:.6}", ALT_FT as f64).parse::<f64>().unwrap() * FEET,
    };
    format!("{},{},{alt_m}", LAT as f64, LON as f64)
}

/// A tiny deterministic generator for garbage (no dependency needed).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 33
    }
}

/// Garbage packet `i` for `kind`: random bytes, cut-short records, NaN or out-of-range values,
/// wrong headers, by turns.
fn garbage(kind: Kind, i: usize, rng: &mut Lcg) -> Vec<u8> {
    let good = packet(kind);
    match (kind, i % 5) {
        (_, 0) => (0..rng.next() % 300).map(|_| rng.next() as u8).collect(),
        (_, 1) => good[..(rng.next() as usize % good.len())].to_vec(),
        (Kind::XPlane, 2) => xplane_packet(f32::NAN, LON, ALT_FT, HEADING, PITCH, 0.0),
        (Kind::XPlane, 3) => xplane_packet(LAT, LON, 1e9, HEADING, PITCH, 0.0),
        (Kind::XPlane, _) => {
            let mut p = good;
            p[..4].copy_from_slice(b"DATB");
            p
        }
        (Kind::FlightGear, 2) => flightgear_packet(f64::NAN, 0.0, 1.0, 0.0, 0.0, 0.0),
        (Kind::FlightGear, 3) => flightgear_packet(45.0, 0.0, 1.0, 0.0, 120.0, 0.0),
        (Kind::FlightGear, _) => {
            b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M\n".to_vec()
        }
    }
}

fn listen(kind: Kind) -> Follower {
    Follower::bind(Source { kind, port: 0 }).expect("bind on loopback")
}

fn sender() -> UdpSocket {
    UdpSocket::bind("127.0.0.1:0").unwrap()
}

/// Poll until `n` packets (good or bad) have arrived, or two seconds have passed.
fn drain(f: &mut Follower, n: u64) {
    let until = Instant::now() + Duration::from_secs(2);
    loop {
        f.poll(Instant::now());
        let st = f.status(Instant::now());
        if st.received + st.malformed >= n || Instant::now() > until {
            return;
        }
        thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn poses_are_what_each_simulator_sent() {
    for kind in [Kind::XPlane, Kind::FlightGear] {
        let mut f = listen(kind);
        let port = f.port();
        let t = thread::spawn(move || {
            let s = sender();
            s.send_to(&packet(kind), ("127.0.0.1", port)).unwrap();
        });
        t.join().unwrap();
        drain(&mut f, 1);
        let fix = f.last_fix().expect("a pose from the packet");
        assert!(
            (fix.lat - 45.5).abs() < 1e-9 && (fix.lon + 22.0).abs() < 1e-9,
            "{fix:?}"
        );
        // 39 370.08 ft is 12 000 m (within f32's and %f's rounding).
        assert!(
            (fix.alt_m - 12_000.0).abs() < 0.01,
            "{kind:?}: {}",
            fix.alt_m
        );
        assert_eq!((fix.heading, fix.pitch, fix.roll), (45.0, -12.0, 0.0));
        let st = f.status(Instant::now());
        assert_eq!((st.received, st.malformed, st.stale_s), (1, 0, None));
        // One packet gives no speed: the pose stays where it was sent.
        assert_eq!(
            f.pose(Instant::now() + Duration::from_millis(500)),
            Some(fix)
        );
        // Silence is reported.
        let later = f.status(Instant::now() + Duration::from_millis(2500));
        assert!(later.stale_s.is_some_and(|s| s > 2.0), "{later:?}");
        assert!(
            later.line().contains("no packets for 2 s"),
            "{}",
            later.line()
        );
    }
}

#[test]
fn a_thousand_garbage_packets_change_nothing() {
    for kind in [Kind::XPlane, Kind::FlightGear] {
        let mut f = listen(kind);
        let s = sender();
        let to = ("127.0.0.1", f.port());
        s.send_to(&packet(kind), to).unwrap();
        drain(&mut f, 1);
        let before = f.last_fix().unwrap();
        let mut rng = Lcg(17);
        let mut sent = 1;
        for i in 0..1000 {
            s.send_to(&garbage(kind, i, &mut rng), to).unwrap();
            sent += 1;
            if i % 100 == 50 {
                s.send_to(&packet(kind), to).unwrap();
                sent += 1;
            }
            // Drained as it goes: the loopback socket's buffer would drop a burst of 1 000.
            if i % 50 == 49 {
                drain(&mut f, sent);
            }
        }
        drain(&mut f, sent);
        let st = f.status(Instant::now());
        assert_eq!(st.malformed, 1000, "{kind:?}: {st:?}");
        assert_eq!(st.received, 11, "{kind:?}: {st:?}");
        // The same packet again and again: no speed, no drift.
        assert_eq!(f.pose(Instant::now()), Some(before), "{kind:?}");
        assert!(st.line().contains("1000 malformed"), "{}", st.line());
    }
}

/// A port nobody listens on now (the binary binds it next).
fn free_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Sends `kind`'s packet every 20 ms to `port`, with a garbage packet after each, until stopped.
fn keep_sending(kind: Kind, port: u16, stop: Arc<AtomicBool>) -> thread::JoinHandle<()> {
    thread::spawn(move || {
        let s = sender();
        let mut rng = Lcg(5);
        let mut i = 0;
        while !stop.load(Ordering::Relaxed) {
            // Nobody listening yet is an ICMP error on some sends: ignored, as a simulator does.
            let _ = s.send_to(&packet(kind), ("127.0.0.1", port));
            let _ = s.send_to(&garbage(kind, i, &mut rng), ("127.0.0.1", port));
            i += 1;
            thread::sleep(Duration::from_millis(20));
        }
    })
}

fn flight(map: &Path, follow: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    flight_for(map, follow, out, ("1", "2"), extra)
}

/// `flight --follow` for `duration` s at `fps`.
fn flight_for(
    map: &Path,
    follow: &str,
    out: &Path,
    (duration, fps): (&str, &str),
    extra: &[&str],
) -> std::process::Output {
    let mut a = vec![
        "flight",
        "--map",
        map.to_str().unwrap(),
        "--follow",
        follow,
        "--duration",
        duration,
        "--fps",
        fps,
        "--size",
        "64x36",
        "--preset",
        "fast",
        "--out",
        out.to_str().unwrap(),
    ];
    a.extend_from_slice(extra);
    stratus(&a)
}

#[test]
fn a_recording_matches_render_at_the_same_camera() {
    let dir = tempfile::tempdir().unwrap();
    let map = synthetic_map(dir.path());
    for (kind, name) in [(Kind::XPlane, "xplane"), (Kind::FlightGear, "flightgear")] {
        let port = free_port();
        let stop = Arc::new(AtomicBool::new(false));
        let t = keep_sending(kind, port, stop.clone());
        let out = dir.path().join(format!("rec-{name}"));
        let o = flight(&map, &format!("{name}:{port}"), &out, &[]);
        stop.store(true, Ordering::Relaxed);
        t.join().unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(stdout.contains("wrote 2 frames"), "{stdout}");
        assert!(
            !stdout.contains(" 0 malformed"),
            "garbage was sent: {stdout}"
        );

        let shot = dir.path().join(format!("render-{name}.png"));
        let r = stratus(&[
            "render",
            "--map",
            map.to_str().unwrap(),
            "--camera",
            &camera_arg(kind),
            "--heading",
            "45",
            "--pitch",
            "-12",
            "--size",
            "64x36",
            "--preset",
            "fast",
            "--out",
            shot.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let a = image::open(out.join("frame-00000.png")).unwrap().to_rgba8();
        let b = image::open(&shot).unwrap().to_rgba8();
        assert_eq!(a.dimensions(), b.dimensions());
        let worst = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap();
        assert!(
            worst <= 1,
            "{name}: frame and render differ by {worst} levels"
        );
    }
}

#[test]
fn no_packet_is_one_error_and_no_folder() {
    let dir = tempfile::tempdir().unwrap();
    let map = synthetic_map(dir.path());
    let port = free_port();
    // Only garbage: the follower must not take any of it for a pose.
    let s = sender();
    let out = dir.path().join("never");
    let child = {
        let follow = format!("xplane:{port}");
        let map = map.clone();
        let out = out.clone();
        thread::spawn(move || flight(&map, &follow, &out, &["--wait", "1"]))
    };
    let mut rng = Lcg(9);
    for i in 0..40 {
        let _ = s.send_to(&garbage(Kind::XPlane, i, &mut rng), ("127.0.0.1", port));
        thread::sleep(Duration::from_millis(20));
    }
    let o = child.join().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("error") && !l.contains("XDG_RUNTIME_DIR"))
        .collect();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(lines.len(), 1, "{err}");
    assert!(
        lines[0].contains("no packet from X-Plane on UDP port"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "nothing may be left when no packet came");
    // A bad --follow is refused before anything is bound or created.
    let o = flight(&map, "msfs:1", &out, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("xplane[:PORT]"));
    assert!(!out.exists());
}

#[test]
fn the_shipped_protocol_sends_what_the_parser_reads() {
    let xml = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/flightgear/stratus.xml"),
    )
    .unwrap();
    let nodes: Vec<&str> = xml
        .split("<node>")
        .skip(1)
        .filter_map(|s| s.split("</node>").next())
        .collect();
    assert_eq!(
        nodes,
        [
            "/position/latitude-deg",
            "/position/longitude-deg",
            "/position/altitude-ft",
            "/orientation/heading-deg",
            "/orientation/pitch-deg",
            "/orientation/roll-deg",
            "/velocities/groundspeed-kt",
            "/velocities/vertical-speed-fps"
        ]
    );
    assert!(xml.contains("<var_separator>,</var_separator>"));
    assert!(xml.contains("<line_separator>newline</line_separator>"));
    // XML forbids two dashes in a row inside a comment; FlightGear 2020.3 then refuses the
    // whole file ("not well-formed (invalid token)") and sends nothing.
    for comment in xml.split("<!--").skip(1) {
        let body = comment.split("-->").next().unwrap();
        assert!(
            !body.contains("--") && !body.ends_with('-'),
            "the protocol file must be XML: a comment holds \"--\""
        );
    }
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/fly.md")).unwrap();
    assert!(doc.contains("--generic=socket,out,30,127.0.0.1,5505,udp,stratus"));
}

/// Metres east of 45.5° N that `metres` is, in degrees of longitude at `alt_m`.
fn east_deg(metres: f64, alt_m: f64) -> f64 {
    (metres / ((6_371_000.0 + alt_m) * 45.5f64.to_radians().cos())).to_degrees()
}

/// Sends an aircraft flying east at `speed` m/s (12 000 m, level) to `port` until stopped, a
/// packet 10 to 60 ms after the one before (a busy simulator's uneven frames), each with the
/// position at the moment it is sent. `with_speed`: the packets carry the ground speed too.
fn fly_east(
    kind: Kind,
    port: u16,
    speed: f64,
    with_speed: bool,
    stop: Arc<AtomicBool>,
) -> thread::JoinHandle<()> {
    thread::spawn(move || {
        let s = sender();
        let mut rng = Lcg(23);
        let t0 = Instant::now();
        let alt_m = 12_000.0;
        while !stop.load(Ordering::Relaxed) {
            let lon = -22.0 + east_deg(speed * t0.elapsed().as_secs_f64(), alt_m);
            let kt = speed * 3600.0 / 1852.0;
            let p = match (kind, with_speed) {
                (Kind::FlightGear, false) => {
                    flightgear_packet(45.5, lon, alt_m / FEET, 90.0, 0.0, 0.0)
                }
                (Kind::FlightGear, true) => format!(
                    "{:.8},{lon:.8},{:.2},90.000,0.000,0.000,{kt:.2},0.00\n",
                    45.5,
                    alt_m / FEET
                )
                .into_bytes(),
                (Kind::XPlane, _) => xplane_rows(
                    45.5,
                    lon as f32,
                    (alt_m / FEET) as f32,
                    90.0,
                    0.0,
                    0.0,
                    with_speed.then_some(kt as f32),
                ),
            };
            let _ = s.send_to(&p, ("127.0.0.1", port));
            thread::sleep(Duration::from_millis(10 + rng.next() % 51));
        }
    })
}

/// The "ground speed over N frames: LO-HI m/s …" line's LO and HI.
fn speed_range(stdout: &str) -> Option<(f64, f64)> {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("ground speed over"))?;
    let range = line.split(": ").nth(1)?.split(" m/s").next()?;
    let (lo, hi) = range.split_once('-')?;
    Some((lo.parse().ok()?, hi.parse().ok()?))
}

#[test]
fn the_recorded_speed_is_the_speed_flown_despite_uneven_packets() {
    let dir = tempfile::tempdir().unwrap();
    let map = synthetic_map(dir.path());
    // 150 kt east; packets 10-60 ms apart; a frame every 0.25 s polls several at once.
    let speed = 77.17;
    for (kind, name, with_speed) in [
        (Kind::FlightGear, "flightgear", false),
        (Kind::XPlane, "xplane", false),
        (Kind::FlightGear, "flightgear", true),
        (Kind::XPlane, "xplane", true),
    ] {
        let port = free_port();
        let stop = Arc::new(AtomicBool::new(false));
        let t = fly_east(kind, port, speed, with_speed, stop.clone());
        let out = dir.path().join(format!("speed-{name}-{with_speed}"));
        let o = flight_for(&map, &format!("{name}:{port}"), &out, ("3", "4"), &[]);
        stop.store(true, Ordering::Relaxed);
        t.join().unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{stderr}");
        let (lo, hi) = speed_range(&stdout).unwrap_or_else(|| panic!("{stdout}"));
        for v in [lo, hi] {
            assert!(
                (v / speed - 1.0).abs() < 0.05,
                "{name} (speeds sent: {with_speed}): {lo}-{hi} m/s, flown {speed}: {stdout}"
            );
        }
        let source = if with_speed {
            "the simulator's own"
        } else {
            "measured from packet arrival times"
        };
        assert!(stdout.contains(source), "{stdout}");
        assert!(stdout.contains("; 0 of 12 frames held"), "{stdout}");
        assert!(!stderr.contains("warning"), "{stderr}");
    }
}

#[test]
fn waiting_says_where_and_how_to_send() {
    let dir = tempfile::tempdir().unwrap();
    let map = synthetic_map(dir.path());
    for (kind, name, how) in [
        (
            Kind::FlightGear,
            "flightgear",
            "docs/flightgear/stratus.xml",
        ),
        (Kind::XPlane, "xplane", "Data Output"),
    ] {
        let port = free_port();
        let out = dir.path().join(format!("never-{name}"));
        let o = flight(&map, &format!("{name}:{port}"), &out, &["--wait", "0.5"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        let line = err
            .lines()
            .find(|l| l.starts_with("waiting"))
            .unwrap_or_else(|| panic!("no waiting line: {err}"));
        let want = format!(
            "waiting up to 0.5 s (--wait) for {} on UDP port {port}",
            kind.name()
        );
        assert!(line.starts_with(&want), "{line}");
        assert!(line.contains(how) && line.contains("docs/fly.md"), "{line}");
    }
}

#[test]
fn a_simulator_gone_silent_is_warned_and_its_frozen_frames_counted() {
    let dir = tempfile::tempdir().unwrap();
    let map = synthetic_map(dir.path());
    let port = free_port();
    let stop = Arc::new(AtomicBool::new(false));
    let t = fly_east(Kind::FlightGear, port, 77.17, true, stop.clone());
    let out = dir.path().join("silent");
    let child = {
        let (map, out) = (map.clone(), out.clone());
        let follow = format!("flightgear:{port}");
        thread::spawn(move || flight_for(&map, &follow, &out, ("4", "4"), &[]))
    };
    // The simulator dies once the recording has begun (its staging folder exists; frame 0 is
    // taken after the renderer starts): the recording goes on for 4 s, so at least its last
    // frames come more than a second after the last packet, however slow the renderer.
    let until = Instant::now() + Duration::from_secs(120);
    let begun = |out: &Path| {
        std::fs::read_dir(out)
            .into_iter()
            .flatten()
            .flatten()
            .any(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with(".stratus-frames.")
            })
    };
    while !begun(&out) && Instant::now() < until {
        thread::sleep(Duration::from_millis(2));
    }
    stop.store(true, Ordering::Relaxed);
    t.join().unwrap();
    let o = child.join().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    // A recording with frozen frames is still a complete recording: exit 0, and said twice.
    assert!(o.status.success(), "{stderr}");
    let starts: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("warning: no packet from FlightGear for"))
        .collect();
    assert_eq!(
        starts.len(),
        1,
        "one warning when the silence starts: {stderr}{stdout}"
    );
    // "FlightGear: N packets, 0 malformed (ignored); HELD of 16 frames held its last pose"
    let held: u64 = stdout
        .lines()
        .find(|l| l.starts_with("FlightGear:"))
        .and_then(|l| l.split("; ").nth(1))
        .and_then(|s| s.strip_suffix(" of 16 frames held its last pose"))
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!((1..=16).contains(&held), "{held} held: {stdout}");
    assert!(
        stderr.contains(&format!(
            "warning: {held} of 16 frames hold FlightGear's last pose"
        )),
        "{stderr}"
    );
}
