//! How fast the followed aircraft moves: the simulator's own ground speed and climb rate when
//! its packets carry them, else measured over the last second of fixes from the times the
//! receiving thread stamped on them (never from two packets alone: a few milliseconds of
//! jitter between two packets 33 ms apart is a large error).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use super::{distance, Fix, MAX_CLIMB, MAX_SPEED};

/// The fixes a speed is measured over (at least the last two are kept).
pub const WINDOW: Duration = Duration::from_secs(1);
/// Shortest span a speed is measured over.
pub const MIN_SPAN: Duration = Duration::from_millis(250);
/// Two packets are never taken as closer in time than this when looking for a teleport: the
/// network can deliver two of them together.
const TELEPORT_DT: f64 = 0.1;

/// Ground speed and climb rate (m/s), and whether the simulator reported them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Velocity {
    pub ground: f64,
    pub climb: f64,
    /// The ground speed is the simulator's own (else measured from packet times).
    pub reported: bool,
}

/// The recent fixes and when each arrived.
#[derive(Debug, Default)]
pub struct Track {
    fixes: VecDeque<(Fix, Instant)>,
}

impl Track {
    /// Add a fix that arrived at `at`. A jump faster than [`MAX_SPEED`] (or a climb faster than
    /// [`MAX_CLIMB`]) is a teleport: the measurement starts again from it.
    pub fn push(&mut self, fix: Fix, at: Instant) {
        if let Some(&(prev, t)) = self.fixes.back() {
            let dt = at
                .saturating_duration_since(t)
                .as_secs_f64()
                .max(TELEPORT_DT);
            if distance(&prev, &fix) > MAX_SPEED * dt
                || (fix.alt_m - prev.alt_m).abs() > MAX_CLIMB * dt
            {
                self.fixes.clear();
            }
        }
        self.fixes.push_back((fix, at));
        while self.fixes.len() > 2
            && self
                .fixes
                .front()
                .is_some_and(|&(_, t)| at.saturating_duration_since(t) > WINDOW)
        {
            self.fixes.pop_front();
        }
    }

    /// The velocity now: each of ground speed and climb the newest packet's own where it
    /// carries it, else measured from the oldest to the newest fix kept (when they span
    /// [`MIN_SPAN`]), else unknown (`None` when the ground speed is).
    pub fn velocity(&self) -> Option<Velocity> {
        let &(newest, _) = self.fixes.back()?;
        let measured = self.measured();
        let ground = newest.ground_speed.or(measured.map(|m| m.0))?;
        let climb = newest.climb.or(measured.map(|m| m.1)).unwrap_or(0.0);
        Some(Velocity {
            ground,
            climb,
            reported: newest.ground_speed.is_some(),
        })
    }

    /// Ground speed and climb from the oldest and newest fixes kept.
    fn measured(&self) -> Option<(f64, f64)> {
        let (&(a, ta), &(b, tb)) = (self.fixes.front()?, self.fixes.back()?);
        let span = tb.saturating_duration_since(ta);
        if span < MIN_SPAN {
            return None;
        }
        let dt = span.as_secs_f64();
        let (v, climb) = (distance(&a, &b) / dt, (b.alt_m - a.alt_m) / dt);
        (v <= MAX_SPEED && climb.abs() <= MAX_CLIMB).then_some((v, climb))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jittered_arrivals_give_the_speed_within_a_percent() {
        let mut t = Track::default();
        let t0 = Instant::now();
        let a = Fix::checked(45.0, 10.0, 1000.0, 90.0, 0.0, 0.0).unwrap();
        // 50 m/s, a packet every 33 ms sent on time, each delayed by 0–15 ms on the way.
        for k in 0..60u64 {
            let jitter = (k * 7919 % 16) as f64 * 1e-3;
            let sent = k as f64 / 30.0;
            t.push(
                a.moved(50.0 * sent, 0.0),
                t0 + Duration::from_secs_f64(sent + jitter),
            );
        }
        let v = t.velocity().unwrap();
        assert!((v.ground - 50.0).abs() < 0.5, "{v:?}");
        assert!(!v.reported);
    }

    #[test]
    fn the_simulator_speed_wins_and_teleports_restart() {
        let mut t = Track::default();
        let t0 = Instant::now();
        let a = Fix::checked(45.0, 10.0, 1000.0, 90.0, 0.0, 0.0).unwrap();
        t.push(a, t0);
        assert_eq!(t.velocity(), None, "one fix: no speed");
        let b = a
            .moved(10.0, 0.0)
            .with_motion(Some(12.0), Some(-1.0))
            .unwrap();
        t.push(b, t0 + Duration::from_millis(100));
        let v = t.velocity().unwrap();
        assert_eq!((v.ground, v.climb, v.reported), (12.0, -1.0, true));
        // 500 km away 0.1 s later: measured afresh from there.
        let c = a.moved(500_000.0, 0.0);
        t.push(c, t0 + Duration::from_millis(200));
        assert_eq!(t.velocity(), None);
    }
}
