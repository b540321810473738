//! The flight model behind the window: throttle, pitch, bank and yaw with coordinated turns,
//! moving over the sphere. Deliberately simple (no stalls, no wind): it exists to fly a camera.

use std::collections::HashSet;

use winit::keyboard::KeyCode;

use std::time::Instant;

use crate::follow::{Follower, Status};
use crate::render::camera::EARTH_R;
use crate::render::Camera;

const G: f64 = 9.81;

#[derive(Clone, Debug)]
pub struct Pilot {
    pub lat: f64,
    pub lon: f64,
    pub alt_m: f64,
    /// Degrees clockwise from north.
    pub heading: f64,
    /// Flight-path angle, degrees up.
    pub pitch: f64,
    /// Bank, degrees, right wing down positive.
    pub roll: f64,
    /// True airspeed, m/s.
    pub speed: f64,
    /// Mouse-look offsets from the nose, degrees.
    pub look_yaw: f64,
    pub look_pitch: f64,
    pub fov: f64,
}

impl Pilot {
    pub fn at(lat: f64, lon: f64, alt_m: f64, heading: f64, pitch: f64) -> Pilot {
        Pilot {
            lat,
            lon,
            alt_m,
            heading,
            pitch,
            roll: 0.0,
            speed: 120.0,
            look_yaw: 0.0,
            look_pitch: 0.0,
            fov: 60.0,
        }
    }

    pub fn camera(&self) -> Camera {
        let mut c = Camera::new(
            self.lat,
            self.lon,
            self.alt_m,
            self.heading + self.look_yaw,
            (self.pitch + self.look_pitch).clamp(-90.0, 90.0),
        );
        c.fov_deg = self.fov;
        c.roll_deg = self.roll;
        c
    }

    /// Advance by `dt` seconds with the keys held.
    pub fn step(&mut self, keys: &HashSet<KeyCode>, dt: f64) {
        let dt = dt.clamp(0.0, 0.5);
        let held = |k: KeyCode| keys.contains(&k);
        let axis = |pos: KeyCode, neg: KeyCode| held(pos) as i32 as f64 - held(neg) as i32 as f64;
        // Throttle: W/S change airspeed; Shift makes it brisk.
        let accel = if held(KeyCode::ShiftLeft) {
            200.0
        } else {
            30.0
        };
        self.speed =
            (self.speed + axis(KeyCode::KeyW, KeyCode::KeyS) * accel * dt).clamp(0.0, 2000.0);
        // Elevator: Down arrow pulls the nose up, as on a stick.
        self.pitch = (self.pitch + axis(KeyCode::ArrowDown, KeyCode::ArrowUp) * 25.0 * dt)
            .clamp(-89.0, 89.0);
        // Ailerons, and the bank slowly levels when released.
        let roll_in = axis(KeyCode::ArrowRight, KeyCode::ArrowLeft);
        if roll_in != 0.0 {
            self.roll = (self.roll + roll_in * 45.0 * dt).clamp(-80.0, 80.0);
        } else {
            self.roll -= self.roll * (0.8 * dt).min(1.0);
        }
        // Rudder, plus the coordinated turn a bank gives: ψ' = g·tan φ / v.
        let turn = if self.speed > 1.0 {
            (G * self.roll.to_radians().tan() / self.speed).to_degrees()
        } else {
            0.0
        };
        self.heading = (self.heading + (axis(KeyCode::KeyD, KeyCode::KeyA) * 20.0 + turn) * dt)
            .rem_euclid(360.0);
        // Move along the flight path over the sphere.
        let d = self.speed * dt;
        let (h, p) = (self.heading.to_radians(), self.pitch.to_radians());
        let r = EARTH_R + self.alt_m;
        self.lat += (d * p.cos() * h.cos() / r).to_degrees();
        let coslat = self.lat.to_radians().cos().max(1e-6);
        self.lon += (d * p.cos() * h.sin() / (r * coslat)).to_degrees();
        if self.lat.abs() > 90.0 {
            // Over a pole: come down the other side.
            self.lat = self.lat.signum() * 180.0 - self.lat;
            self.lon += 180.0;
            self.heading = (self.heading + 180.0).rem_euclid(360.0);
        }
        self.lon = (self.lon + 180.0).rem_euclid(360.0) - 180.0;
        self.alt_m = (self.alt_m + d * p.sin()).clamp(0.0, 1.0e6);
    }
}

/// How far above the map's terrain the pilot is held: the eye of someone standing on it.
pub const GROUND_MARGIN_M: f64 = 2.0;

/// Stop the pilot at the terrain: never lower than [`GROUND_MARGIN_M`] above `map`'s ground
/// there (sea level where the map has none). Flying into a slope holds the aircraft on it,
/// as the old sea-level floor did; after a step, a follow or a teleport.
pub fn keep_above_ground(pilot: &mut Pilot, map: &stratus_ingest::CloudMap) {
    let (ground, _) = map.ground_height_m(pilot.lat, pilot.lon);
    pilot.alt_m = pilot.alt_m.max(ground + GROUND_MARGIN_M);
}

/// One frame of `--follow`: read what the simulator sent and put the pilot at the aircraft's
/// pose (the mouse-look offsets stay: the view still turns from the nose). Before the first
/// packet the pilot stays where it is.
pub fn follow(pilot: &mut Pilot, follower: &mut Follower, now: Instant) -> Status {
    follower.poll(now);
    if let Some(fix) = follower.pose(now) {
        pilot.lat = fix.lat;
        pilot.lon = fix.lon;
        pilot.alt_m = fix.alt_m.max(0.0);
        pilot.heading = fix.heading;
        pilot.pitch = fix.pitch;
        pilot.roll = fix.roll;
        pilot.speed = follower.speed();
    }
    follower.status(now)
}

/// Put the pilot where a keyframed path is `t` seconds in (`fly --path`).
pub fn fly_path(pilot: &mut Pilot, path: &crate::flight::FlightPath, t: f64) {
    let (cam, _) = path.at(t);
    let f = cam.forward_enu.normalize();
    pilot.lat = cam.lat_deg;
    pilot.lon = cam.lon_deg;
    pilot.alt_m = cam.alt_m;
    pilot.heading = f.x.atan2(f.y).to_degrees().rem_euclid(360.0);
    pilot.pitch = f.z.clamp(-1.0, 1.0).asin().to_degrees();
    pilot.roll = cam.roll_deg;
    pilot.fov = cam.fov_deg;
    pilot.look_yaw = 0.0;
    pilot.look_pitch = 0.0;
    // The HUD's speed: the path's, over the half second around t.
    let dt = 0.5;
    let (t0, t1) = if t + dt <= path.duration() {
        (t, t + dt)
    } else {
        ((t - dt).max(0.0), t)
    };
    let pos = |t: f64| {
        let (c, _) = path.at(t);
        crate::render::camera::ecef(c.lat_deg, c.lon_deg, c.alt_m)
    };
    if t1 > t0 {
        pilot.speed = pos(t1).distance(pos(t0)) / (t1 - t0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::follow::{flightgear, Fix, Kind, Source};

    #[test]
    fn follow_takes_the_aircraft_pose_and_keeps_the_look() {
        let mut f = Follower::bind(Source {
            kind: Kind::FlightGear,
            port: 0,
        })
        .unwrap();
        let mut p = Pilot::at(0.0, 0.0, 5000.0, 0.0, 0.0);
        p.look_yaw = 30.0;
        let st = follow(&mut p, &mut f, Instant::now());
        assert!(st.line().ends_with("waiting for packets"), "{}", st.line());
        assert_eq!((p.lat, p.alt_m), (0.0, 5000.0), "no packet: stays put");
        let fix = Fix::checked(45.5, -22.0, 12_000.0, 45.0, -12.0, 20.0).unwrap();
        let s = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        s.send_to(&flightgear::encode(&fix), ("127.0.0.1", f.port()))
            .unwrap();
        s.send_to(b"garbage", ("127.0.0.1", f.port())).unwrap();
        let until = Instant::now() + std::time::Duration::from_secs(2);
        let mut st = follow(&mut p, &mut f, Instant::now());
        while st.received + st.malformed < 2 && Instant::now() < until {
            std::thread::sleep(std::time::Duration::from_millis(2));
            st = follow(&mut p, &mut f, Instant::now());
        }
        assert_eq!((st.received, st.malformed), (1, 1));
        assert!((p.lat - 45.5).abs() < 1e-9 && (p.alt_m - 12_000.0).abs() < 0.01);
        assert_eq!(
            (p.heading, p.pitch, p.roll, p.look_yaw),
            (45.0, -12.0, 20.0, 30.0)
        );
        let cam = p.camera();
        let want = Camera::new(p.lat, p.lon, p.alt_m, 75.0, -12.0);
        assert!((cam.forward_enu - want.forward_enu).length() < 1e-12);
        assert_eq!(cam.roll_deg, 20.0);
        assert!(
            st.line().starts_with("following FlightGear on :"),
            "{}",
            st.line()
        );
    }

    #[test]
    fn the_pilot_stops_at_the_terrain() {
        let t = chrono::TimeZone::with_ymd_and_hms(&chrono::Utc, 2024, 6, 1, 12, 0, 0).unwrap();
        let r = stratus_ingest::Region::parse("30,40,80,90").unwrap();
        let mut map = stratus_ingest::CloudMap::from_fn(r, 10, 10, &[], t, |_, _| [0.0; 3]);
        let mut p = Pilot::at(35.0, 85.0, 1000.0, 0.0, -45.0);
        keep_above_ground(&mut p, &map);
        assert_eq!(p.alt_m, 1000.0, "no ground grid: sea level, well below");
        map.ground = Some(stratus_ingest::ground::Ground {
            grid: stratus_ingest::meta::StructureGrid::of_map(&r, 2, 2),
            region: r,
            height_m: vec![5000.0; 4],
            land: vec![1.0; 4],
            ice: vec![0.0; 4],
            snow_kg_m2: vec![0.0; 4],
            albedo: vec![0.2; 4],
            cwat_kg_m2: vec![0.0; 4],
            fields: vec![stratus_ingest::ground::GroundField::Orography],
        });
        // Diving at 45° for a minute from 6 km: held 2 m above the 5 km plateau.
        p.alt_m = 6000.0;
        let none = HashSet::new();
        for _ in 0..600 {
            p.step(&none, 0.1);
            keep_above_ground(&mut p, &map);
            assert!(p.alt_m >= 5000.0 + GROUND_MARGIN_M - 1e-9, "{}", p.alt_m);
        }
        assert!((p.alt_m - 5002.0).abs() < 1e-9, "{}", p.alt_m);
    }

    #[test]
    fn flies_north_and_turns_when_banked() {
        let mut p = Pilot::at(0.0, 0.0, 1000.0, 0.0, 0.0);
        p.speed = 111.195;
        let none = HashSet::new();
        for _ in 0..100 {
            p.step(&none, 0.1);
        }
        // 1111.95 m north ≈ 0.01°.
        assert!((p.lat - 0.01).abs() < 1e-4, "{}", p.lat);
        let mut keys = HashSet::new();
        keys.insert(KeyCode::ArrowRight);
        p.step(&keys, 0.5);
        keys.clear();
        let h0 = p.heading;
        p.step(&keys, 0.5);
        assert!(p.heading > h0, "a right bank turns right");
    }

    #[test]
    fn a_played_path_gives_the_hud_its_speed() {
        // docs/flights/ea-cruise.json cruises at 230 m/s for its first 15 s.
        let path =
            crate::flight::FlightPath::parse(include_bytes!("../../docs/flights/ea-cruise.json"))
                .expect("the sample path");
        let mut p = Pilot::at(0.0, 0.0, 1000.0, 0.0, 0.0);
        for t in [1.0, 7.3, 14.0] {
            fly_path(&mut p, &path, t);
            assert!((p.speed - 230.0).abs() < 3.0, "at {t} s: {} m/s", p.speed);
        }
    }
}
