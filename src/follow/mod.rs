//! Following a flight simulator's aircraft from its UDP output (`fly --follow`,
//! `flight --follow`): X-Plane's data output ([`xplane`]) and FlightGear's generic protocol with
//! the definition Stratus ships ([`flightgear`]).
//!
//! A [`Follower`] owns a UDP socket read by a thread of its own ([`receiver`]), which stamps
//! each datagram with its arrival time. Each frame the caller drains what arrived
//! ([`Follower::poll`]); every datagram is parsed and checked, a bad one is counted and
//! dropped, and the last good one is kept with its arrival time. Between packets the pose is
//! extrapolated along the aircraft's heading at its ground speed and climb rate ([`motion`]:
//! the simulator's own when its packets carry them, else measured over the last second of
//! packets; bounded, and for at most [`MAX_EXTRAPOLATION`]); after [`STALE_AFTER`] without a
//! packet the status says for how long. Nothing the network sends can make this panic.

pub mod flightgear;
pub mod motion;
pub mod receiver;
pub mod xplane;

use std::collections::VecDeque;
use std::net::UdpSocket;
use std::str::FromStr;
use std::time::{Duration, Instant};

use crate::render::camera::EARTH_R;
use crate::render::Camera;
use motion::{Track, Velocity};
use receiver::Receiving;

/// Metres per foot (both simulators send altitude in feet).
pub const FEET: f64 = 0.3048;
/// Metres per second per knot (both simulators send speeds in knots).
pub const KNOT: f64 = 1852.0 / 3600.0;
/// X-Plane's data output has no fixed destination port: the user types one in (Settings →
/// Network, "Send network data output"; X-Plane itself listens on 49000 and sends from 49001,
/// so 49003 is the customary free port for a receiver).
pub const XPLANE_PORT: u16 = 49003;
/// The port the FlightGear command line in docs/fly.md sends to.
pub const FLIGHTGEAR_PORT: u16 = 5505;
/// Lowest and highest altitude accepted (m MSL): the Dead Sea shore to far above any airliner.
pub const ALT_RANGE_M: (f64, f64) = (-500.0, 100_000.0);
/// Fastest ground speed believed (m/s): a jump between packets faster than this is a teleport
/// (the user moved the aircraft), and the pose is held instead of flown there.
pub const MAX_SPEED: f64 = 1_000.0;
/// Fastest climb or descent believed (m/s).
pub const MAX_CLIMB: f64 = 150.0;
/// Longest time a pose is extrapolated past its packet: beyond it the aircraft waits.
pub const MAX_EXTRAPOLATION: Duration = Duration::from_secs(1);
/// Silence after which the follower reports the packets as stopped.
pub const STALE_AFTER: Duration = Duration::from_secs(1);
/// Most datagrams read in one poll: a flood cannot stall a frame.
const MAX_PER_POLL: usize = 4096;

/// Which simulator speaks on the socket.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    XPlane,
    FlightGear,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::XPlane => "X-Plane",
            Kind::FlightGear => "FlightGear",
        }
    }

    pub fn default_port(self) -> u16 {
        match self {
            Kind::XPlane => XPLANE_PORT,
            Kind::FlightGear => FLIGHTGEAR_PORT,
        }
    }
}

impl Source {
    /// How to make the simulator send here, in one clause for a waiting line.
    pub fn setup_hint(&self) -> String {
        let port = self.port;
        let how = match self.kind {
            Kind::XPlane => format!(
                "in X-Plane's Data Output tick \"Network via UDP\" for rows 20, 17 and 3 and send them to this machine, port {port}"
            ),
            Kind::FlightGear => format!(
                "copy docs/flightgear/stratus.xml to $FG_ROOT/Protocol/ and start fgfs with --generic=socket,out,30,THIS-MACHINE,{port},udp,stratus"
            ),
        };
        format!("{how} (docs/fly.md, \"Following a simulator\")")
    }
}

/// `xplane[:PORT]` or `flightgear[:PORT]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Source {
    pub kind: Kind,
    pub port: u16,
}

impl FromStr for Source {
    type Err = FollowError;

    fn from_str(s: &str) -> Result<Source, FollowError> {
        let bad = || FollowError::BadSource(s.to_string());
        let (name, port) = match s.split_once(':') {
            Some((n, p)) => (n, Some(p)),
            None => (s, None),
        };
        let kind = match name.to_ascii_lowercase().as_str() {
            "xplane" | "x-plane" => Kind::XPlane,
            "flightgear" | "fgfs" => Kind::FlightGear,
            _ => return Err(bad()),
        };
        let port = match port {
            None => kind.default_port(),
            Some(p) => p.parse::<u16>().ok().filter(|&p| p > 0).ok_or_else(bad)?,
        };
        Ok(Source { kind, port })
    }
}

#[derive(Debug, thiserror::Error)]
pub enum FollowError {
    #[error("--follow \"{0}\": expected xplane[:PORT] or flightgear[:PORT] (PORT 1..65535)")]
    BadSource(String),
    #[error("cannot listen for {kind} on UDP port {port}: {err}")]
    Bind {
        kind: &'static str,
        port: u16,
        err: std::io::Error,
    },
}

/// Why a datagram was dropped.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ParseError {
    #[error("{0} bytes is too short")]
    TooShort(usize),
    #[error("{0} bytes is too long")]
    TooLong(usize),
    #[error("not an X-Plane DATA packet")]
    Header,
    #[error("a record cut short ({0} bytes left over)")]
    Truncated(usize),
    #[error("record index {0} is not one X-Plane sends")]
    UnknownRecord(i32),
    #[error("no position record (X-Plane row 20)")]
    NoPosition,
    #[error("the line has no newline at its end (cut short?)")]
    NoNewline,
    #[error("not text")]
    NotText,
    #[error("{0} fields, expected 6 or 8")]
    Fields(usize),
    #[error("field {0} is not a number")]
    Number(usize),
    #[error("{0}")]
    Value(String),
}

/// An aircraft's position and attitude (degrees, metres MSL), checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fix {
    pub lat: f64,
    pub lon: f64,
    pub alt_m: f64,
    /// True heading, degrees clockwise from north, 0..360.
    pub heading: f64,
    /// Degrees up.
    pub pitch: f64,
    /// Degrees, right wing down positive.
    pub roll: f64,
    /// Ground speed (m/s) the simulator sent with this fix, when its packet carries one.
    pub ground_speed: Option<f64>,
    /// Climb rate (m/s, up positive) the simulator sent, when its packet carries one.
    pub climb: Option<f64>,
}

impl Fix {
    /// A fix from a packet's values, or why they cannot be one: every value finite, latitude
    /// within ±90°, longitude within ±360° (wrapped to ±180°), altitude within
    /// [`ALT_RANGE_M`], pitch within ±90°, roll and heading within ±360°.
    pub fn checked(
        lat: f64,
        lon: f64,
        alt_m: f64,
        heading: f64,
        pitch: f64,
        roll: f64,
    ) -> Result<Fix, ParseError> {
        for (name, v, lo, hi) in [
            ("latitude", lat, -90.0, 90.0),
            ("longitude", lon, -360.0, 360.0),
            ("altitude", alt_m, ALT_RANGE_M.0, ALT_RANGE_M.1),
            ("heading", heading, -360.0, 360.0),
            ("pitch", pitch, -90.0, 90.0),
            ("roll", roll, -360.0, 360.0),
        ] {
            // Written so that NaN fails too.
            if !(v >= lo && v <= hi) {
                return Err(ParseError::Value(format!(
                    "{name} {v} is outside {lo}..{hi}"
                )));
            }
        }
        Ok(Fix {
            lat,
            lon: wrap180(lon),
            alt_m,
            heading: heading.rem_euclid(360.0),
            pitch,
            roll: wrap180(roll),
            ground_speed: None,
            climb: None,
        })
    }

    /// This fix with the simulator's own ground speed and climb rate (m/s), or why they
    /// cannot be: finite, ground speed within 0..[`MAX_SPEED`], climb within ±[`MAX_CLIMB`].
    pub fn with_motion(
        self,
        ground_speed: Option<f64>,
        climb: Option<f64>,
    ) -> Result<Fix, ParseError> {
        for (name, v, lo, hi) in [
            ("ground speed", ground_speed, 0.0, MAX_SPEED),
            ("climb rate", climb, -MAX_CLIMB, MAX_CLIMB),
        ] {
            if let Some(v) = v.filter(|v| !(*v >= lo && *v <= hi)) {
                return Err(ParseError::Value(format!(
                    "{name} {v} m/s is outside {lo}..{hi}"
                )));
            }
        }
        Ok(Fix {
            ground_speed,
            climb,
            ..self
        })
    }

    /// The camera at this fix: the aircraft's nose, banked with it (ground level at least:
    /// the renderer's sphere has no terrain below sea level).
    pub fn camera(&self) -> Camera {
        let mut c = Camera::new(
            self.lat,
            self.lon,
            self.alt_m.max(0.0),
            self.heading,
            self.pitch,
        );
        c.roll_deg = self.roll;
        c
    }

    /// This fix moved `d` metres along its heading over the sphere and `dz` metres up.
    pub fn moved(&self, d: f64, dz: f64) -> Fix {
        let r = EARTH_R + self.alt_m;
        let h = self.heading.to_radians();
        let mut lat = self.lat + (d * h.cos() / r).to_degrees();
        let mut lon =
            self.lon + (d * h.sin() / (r * self.lat.to_radians().cos().max(1e-6))).to_degrees();
        let mut heading = self.heading;
        if lat.abs() > 90.0 {
            // Over a pole: down the other side.
            lat = lat.signum() * 180.0 - lat;
            lon += 180.0;
            heading = (heading + 180.0).rem_euclid(360.0);
        }
        Fix {
            lat,
            lon: wrap180(lon),
            alt_m: (self.alt_m + dz).clamp(ALT_RANGE_M.0, ALT_RANGE_M.1),
            heading,
            ..*self
        }
    }
}

fn wrap180(x: f64) -> f64 {
    let w = (x + 180.0).rem_euclid(360.0) - 180.0;
    // rem_euclid can round up to 360 for tiny negatives.
    if w >= 180.0 {
        w - 360.0
    } else {
        w
    }
}

/// Great-circle distance between two fixes at their mean altitude (m).
fn distance(a: &Fix, b: &Fix) -> f64 {
    let (la1, la2) = (a.lat.to_radians(), b.lat.to_radians());
    let dla = la2 - la1;
    let dlo = (b.lon - a.lon).to_radians();
    let s = (dla / 2.0).sin().powi(2) + la1.cos() * la2.cos() * (dlo / 2.0).sin().powi(2);
    let r = EARTH_R + 0.5 * (a.alt_m + b.alt_m);
    2.0 * r * s.sqrt().clamp(0.0, 1.0).asin()
}

/// What the HUD and the recorder report.
#[derive(Clone, Debug, PartialEq)]
pub struct Status {
    pub kind: Kind,
    pub port: u16,
    /// Good packets in the last second.
    pub packets_per_s: usize,
    pub received: u64,
    pub malformed: u64,
    /// Seconds since the last good packet once past [`STALE_AFTER`]; `None` while fresh or
    /// before the first packet.
    pub stale_s: Option<f64>,
    /// A good packet has arrived.
    pub any: bool,
}

impl Status {
    /// One line for the HUD: "following X-Plane on :49003 · 30 packets/s · 0 malformed", and
    /// "no packets for N s" or "waiting for packets" when there are none.
    pub fn line(&self) -> String {
        let head = format!(
            "following {} on :{} · {} packets/s · {} malformed",
            self.kind.name(),
            self.port,
            self.packets_per_s,
            self.malformed
        );
        match (self.any, self.stale_s) {
            (false, _) => format!("{head} · waiting for packets"),
            // Whole seconds passed, not rounded up: "for 2 s" after 2.6 s.
            (true, Some(s)) => format!("{head} · no packets for {} s", s.floor()),
            (true, None) => head,
        }
    }
}

/// A UDP listener that turns a simulator's packets into a camera pose.
pub struct Follower {
    source: Source,
    receiving: Receiving,
    /// The last good fix and when it arrived.
    last: Option<(Fix, Instant)>,
    /// The recent fixes the speed comes from.
    track: Track,
    arrivals: VecDeque<Instant>,
    received: u64,
    malformed: u64,
}

impl Follower {
    /// Listen on every interface on `source.port` (a simulator usually runs on another
    /// machine); port 0 takes any free port ([`Follower::port`] says which).
    pub fn bind(source: Source) -> Result<Follower, FollowError> {
        let err = |err| FollowError::Bind {
            kind: source.kind.name(),
            port: source.port,
            err,
        };
        let socket = UdpSocket::bind(("0.0.0.0", source.port)).map_err(err)?;
        let port = socket.local_addr().map_err(err)?.port();
        Ok(Follower {
            source: Source { port, ..source },
            receiving: Receiving::start(socket).map_err(err)?,
            last: None,
            track: Track::default(),
            arrivals: VecDeque::new(),
            received: 0,
            malformed: 0,
        })
    }

    pub fn source(&self) -> Source {
        self.source
    }

    pub fn port(&self) -> u16 {
        self.source.port
    }

    /// Take every datagram the receiving thread has read (at most a few thousand), each at
    /// the time it arrived; `now` ages the packet rate.
    pub fn poll(&mut self, now: Instant) {
        for _ in 0..MAX_PER_POLL {
            let Some(d) = self.receiving.next() else {
                break;
            };
            match self.parse(&d.bytes) {
                Ok(fix) => self.accept(fix, d.at),
                Err(e) => {
                    self.malformed += 1;
                    tracing::debug!("dropped a {} packet: {e}", self.source.kind.name());
                }
            }
        }
        self.trim(now);
    }

    /// Parse one datagram in this follower's format.
    pub fn parse(&self, packet: &[u8]) -> Result<Fix, ParseError> {
        match self.source.kind {
            Kind::XPlane => {
                let att = self
                    .last
                    .map_or((0.0, 0.0, 0.0), |(f, _)| (f.heading, f.pitch, f.roll));
                xplane::parse(packet, att)
            }
            Kind::FlightGear => flightgear::parse(packet),
        }
    }

    fn accept(&mut self, fix: Fix, at: Instant) {
        self.track.push(fix, at);
        self.last = Some((fix, at));
        self.received += 1;
        self.arrivals.push_back(at);
    }

    fn trim(&mut self, now: Instant) {
        while self
            .arrivals
            .front()
            .is_some_and(|&t| now.saturating_duration_since(t) > Duration::from_secs(1))
        {
            self.arrivals.pop_front();
        }
    }

    /// The aircraft's ground speed and climb rate: the simulator's own where its packets carry
    /// them, else measured over the last second of packets; `None` while unknown (before
    /// packets span a quarter of a second, and after a teleport).
    pub fn velocity(&self) -> Option<Velocity> {
        self.track.velocity()
    }

    /// Ground speed (m/s), 0 while unknown.
    pub fn speed(&self) -> f64 {
        self.velocity().map_or(0.0, |v| v.ground)
    }

    /// The last fix as received, without extrapolation.
    pub fn last_fix(&self) -> Option<Fix> {
        self.last.map(|(f, _)| f)
    }

    /// The pose at `now`: the last fix flown on along its heading for the time since it
    /// arrived (at most [`MAX_EXTRAPOLATION`]); `None` before the first packet.
    pub fn pose(&self, now: Instant) -> Option<Fix> {
        let (fix, at) = self.last?;
        let dt = now
            .saturating_duration_since(at)
            .min(MAX_EXTRAPOLATION)
            .as_secs_f64();
        let (v, climb) = self.velocity().map_or((0.0, 0.0), |v| (v.ground, v.climb));
        if v == 0.0 && climb == 0.0 {
            return Some(fix);
        }
        Some(fix.moved(v * dt, climb * dt))
    }

    /// Packet counts and staleness at `now`.
    pub fn status(&mut self, now: Instant) -> Status {
        self.trim(now);
        let stale_s = self.last.and_then(|(_, at)| {
            let quiet = now.saturating_duration_since(at);
            (quiet > STALE_AFTER).then_some(quiet.as_secs_f64())
        });
        Status {
            kind: self.source.kind,
            port: self.source.port,
            packets_per_s: self.arrivals.len(),
            received: self.received,
            malformed: self.malformed,
            stale_s,
            any: self.last.is_some(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_parse() {
        let s: Source = "xplane".parse().unwrap();
        assert_eq!((s.kind, s.port), (Kind::XPlane, XPLANE_PORT));
        let s: Source = "FlightGear:6000".parse().unwrap();
        assert_eq!((s.kind, s.port), (Kind::FlightGear, 6000));
        for bad in [
            "msfs",
            "xplane:",
            "xplane:0",
            "xplane:70000",
            "xplane:-1",
            "",
        ] {
            assert!(bad.parse::<Source>().is_err(), "{bad}");
        }
    }

    #[test]
    fn values_are_checked_and_wrapped() {
        let f = Fix::checked(10.0, 350.0, 100.0, -90.0, 0.0, 270.0).unwrap();
        assert_eq!((f.lon, f.heading, f.roll), (-10.0, 270.0, -90.0));
        assert!(Fix::checked(f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0).is_err());
        assert!(Fix::checked(0.0, 0.0, 1e6, 0.0, 0.0, 0.0).is_err());
        assert!(Fix::checked(0.0, 0.0, 0.0, f64::INFINITY, 0.0, 0.0).is_err());
    }

    #[test]
    fn extrapolates_along_the_heading_and_stops_after_a_second() {
        let mut f = Follower::bind(Source {
            kind: Kind::FlightGear,
            port: 0,
        })
        .unwrap();
        let t0 = Instant::now();
        let a = Fix::checked(0.0, 0.0, 1000.0, 90.0, 0.0, 0.0).unwrap();
        // 100 m east in 0.5 s, measured from the arrival times: 200 m/s.
        let b = a.moved(100.0, 0.0);
        f.accept(a, t0);
        f.accept(b, t0 + Duration::from_millis(500));
        let p = f.pose(t0 + Duration::from_millis(1000)).unwrap();
        assert!(
            (distance(&b, &p) - 100.0).abs() < 1e-3,
            "{}",
            distance(&b, &p)
        );
        assert!(p.lon > b.lon && (p.lat - b.lat).abs() < 1e-9);
        let far = f.pose(t0 + Duration::from_secs(60)).unwrap();
        assert!((distance(&b, &far) - 200.0).abs() < 1e-3);
        // A teleport is held, not flown.
        let c = b.moved(500_000.0, 0.0);
        f.accept(c, t0 + Duration::from_millis(600));
        assert_eq!(f.pose(t0 + Duration::from_millis(900)), Some(c));
        let st = f.status(t0 + Duration::from_millis(3600));
        assert!(st.stale_s.is_some_and(|s| (s - 3.0).abs() < 1e-6), "{st:?}");
        assert!(st.line().ends_with("no packets for 3 s"), "{}", st.line());
    }
}
