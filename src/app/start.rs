//! Where a flight starts: near the most broken cloud of the map, above it, Sun behind.

use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;

use super::pilot::Pilot;

/// Where a flight starts: 60 km from the part of the region with the most broken cloud, above
/// the highest layer, looking at it with the Sun behind. A clear centre would show an empty sky,
/// an overcast one a featureless deck.
pub fn start_pilot(map: &CloudMap, valid: DateTime<Utc>) -> Pilot {
    let region = map.meta.region;
    let (lat, lon) = cloudiest(map).unwrap_or_else(|| region.centre());
    let top = map
        .meta
        .layers
        .iter()
        .map(|l| l.top_m)
        .fold(2000.0, f64::max);
    let base = map.meta.layers.iter().map(|l| l.base_m).fold(top, f64::min);
    let sky = crate::sun::Sky::at(valid, lat, lon);
    let (e, n, _) = crate::render::camera::enu_basis(lat, lon);
    let sun_az = sky.sun.dir.dot(e).atan2(sky.sun.dir.dot(n)).to_degrees();
    // Stand back towards the Sun, so the target is ahead and lit from behind the camera.
    let back_m = 60_000.0;
    let (clat, clon) = destination(lat, lon, sun_az, back_m);
    let alt = top + 3000.0;
    let look_at = 0.5 * (base + top);
    let pitch = -((alt - look_at) / back_m).atan().to_degrees();
    Pilot::at(clat, clon, alt, (sun_az + 180.0).rem_euclid(360.0), pitch)
}

/// Centre of the 1/8-region block whose cover is most broken (mean m maximising m·(1−m)),
/// `None` for an empty map.
fn cloudiest(map: &CloudMap) -> Option<(f64, f64)> {
    const BLOCKS: usize = 8;
    let (w, h) = (map.width(), map.height());
    let mut best = (0.0f64, None);
    for by in 0..BLOCKS {
        for bx in 0..BLOCKS {
            let (x0, x1) = (
                bx * w / BLOCKS,
                ((bx + 1) * w / BLOCKS).max(bx * w / BLOCKS + 1),
            );
            let (y0, y1) = (
                by * h / BLOCKS,
                ((by + 1) * h / BLOCKS).max(by * h / BLOCKS + 1),
            );
            let mut sum = 0.0f64;
            for j in y0..y1.min(h) {
                for i in x0..x1.min(w) {
                    sum += f64::from(map.total(i, j));
                }
            }
            let mean = sum / ((x1 - x0) * (y1 - y0)) as f64;
            let broken = mean * (1.0 - mean);
            if broken > best.0 {
                let r = &map.meta.region;
                let cx = (x0 + x1) / 2;
                let cy = (y0 + y1) / 2;
                best = (
                    broken,
                    Some((r.pixel_lat(cy.min(h - 1), h), r.pixel_lon(cx.min(w - 1), w))),
                );
            }
        }
    }
    best.1
}

/// The point `dist_m` from (lat, lon) along the initial bearing `bearing_deg` on a sphere.
fn destination(lat: f64, lon: f64, bearing_deg: f64, dist_m: f64) -> (f64, f64) {
    let d = dist_m / crate::render::camera::EARTH_R;
    let (p1, l1, b) = (lat.to_radians(), lon.to_radians(), bearing_deg.to_radians());
    let p2 = (p1.sin() * d.cos() + p1.cos() * d.sin() * b.cos()).asin();
    let l2 = l1 + (b.sin() * d.sin() * p1.cos()).atan2(d.cos() - p1.sin() * p2.sin());
    let lon2 = (l2.to_degrees() + 540.0).rem_euclid(360.0) - 180.0;
    (p2.to_degrees(), lon2)
}
