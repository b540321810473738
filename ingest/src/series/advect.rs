//! Clouds carried by the wind: semi-Lagrangian advection of a map's layers with its per-pixel
//! layer winds, and the blend of two forecast steps at a moment between them.
//!
//! Every output pixel follows a trajectory through the wind field (midpoint/RK2 steps of at
//! most [`SUBSTEP_S`], the wind sampled along the way, bilinear on the structure lattice) and
//! takes the coverage found at its end (bilinear between map pixels). Positions move in
//! degrees: east u / (R cos lat), north v / R, R = [`EARTH_RADIUS_M`]. A trajectory that leaves
//! the region takes the coverage at the nearest edge (inflow from outside is unknown; a region
//! spanning all longitudes wraps). The total (A) is recomputed as the max of the layers, as the
//! ingest makes it.

use chrono::Duration;
use rayon::prelude::*;

use crate::cloudmap::CloudMap;
use crate::error::{IngestError, Result};
use crate::lattice::StructureGrid;
use crate::region::Region;
use crate::sample::{coverage_to_sample, sample_to_wind, COVERAGE_FULL};
use crate::structure::MapStructure;

/// Mean Earth radius, m.
pub const EARTH_RADIUS_M: f64 = 6_371_000.0;

/// Longest trajectory sub-step, seconds: at 60 m/s a 10-minute step moves 36 km, well under
/// a 2.5° grid cell, so the wind sampled along the path follows its turns.
pub const SUBSTEP_S: f64 = 600.0;

/// Where the cos(lat) of the east–west step stops shrinking: within ~3° of a pole a
/// trajectory would otherwise race round the pole.
const MIN_COS_LAT: f64 = 0.05;

/// A layer's wind at a point, m/s (east, north).
type Wind<'a> = dyn Fn(usize, f64, f64) -> (f64, f64) + Sync + 'a;

/// Longitude `lon` put on the side of the region it is nearer to, so a point just west of
/// the region reads as west of it (not 359° east).
fn near_lon(region: &Region, lon: f64) -> f64 {
    let centre = region.west + 0.5 * region.lon_span();
    centre + (lon - centre + 180.0).rem_euclid(360.0) - 180.0
}

fn spans_all_longitudes(region: &Region) -> bool {
    region.lon_span() >= 360.0 - 1e-9
}

/// Coverage (0..1) of `map`'s channel `c` at (`lat`, `lon`): bilinear between pixel centres,
/// the nearest edge outside the region (wrapped east–west for a region all round).
pub fn sample_coverage(map: &CloudMap, c: usize, lat: f64, lon: f64) -> f64 {
    let r = &map.meta.region;
    let (w, h) = (map.width(), map.height());
    let span = r.lon_span();
    let y = ((r.north - lat) / (r.north - r.south) * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
    let x = (near_lon(r, lon) - r.west) / span * w as f64 - 0.5;
    let (i0, i1, tx) = if spans_all_longitudes(r) {
        let x = x.rem_euclid(w as f64);
        let i0 = (x.floor() as usize).min(w - 1);
        (i0, (i0 + 1) % w, x - i0 as f64)
    } else {
        let x = x.clamp(0.0, (w - 1) as f64);
        let i0 = x.floor() as usize;
        (i0, (i0 + 1).min(w - 1), x - i0 as f64)
    };
    let j0 = y.floor() as usize;
    let (j1, ty) = ((j0 + 1).min(h - 1), y - j0 as f64);
    let t = |i: usize, j: usize| map.texels[j * w + i][c] as f64;
    let top = t(i0, j0) * (1.0 - tx) + t(i1, j0) * tx;
    let bottom = t(i0, j1) * (1.0 - tx) + t(i1, j1) * tx;
    (top * (1.0 - ty) + bottom * ty) / COVERAGE_FULL
}

/// Layer winds on a structure lattice, decoded to m/s once (east, north; R/G/B = layer).
struct WindLattice {
    grid: StructureGrid,
    region: Region,
    u: Vec<[f32; 3]>,
    v: Vec<[f32; 3]>,
}

impl WindLattice {
    fn of(s: &MapStructure, region: Region) -> Option<WindLattice> {
        let n = s.grid.width as usize * s.grid.height as usize;
        if n == 0 || s.wind_u.len() < n || s.wind_v.len() < n {
            return None;
        }
        let dec = |w: &[[u16; 3]]| -> Vec<[f32; 3]> {
            w[..n]
                .iter()
                .map(|t| t.map(|x| sample_to_wind(x) as f32))
                .collect()
        };
        Some(WindLattice {
            grid: s.grid,
            region,
            u: dec(&s.wind_u),
            v: dec(&s.wind_v),
        })
    }

    /// (1 − w)·self + w·other, where both lie on one lattice.
    fn mix(mut self, other: &WindLattice, w: f32) -> Option<WindLattice> {
        if self.grid != other.grid {
            return None;
        }
        for (a, b) in self
            .u
            .iter_mut()
            .zip(&other.u)
            .chain(self.v.iter_mut().zip(&other.v))
        {
            for c in 0..3 {
                a[c] = (1.0 - w) * a[c] + w * b[c];
            }
        }
        Some(self)
    }

    /// Layer `c`'s wind at a point, bilinear between lattice pixels (clamped to the outer ones).
    fn at(&self, c: usize, lat: f64, lon: f64) -> (f64, f64) {
        let (g, r) = (&self.grid, &self.region);
        let (w, h) = (g.width as usize, g.height as usize);
        // Keep a point west of the region on the west edge (the lattice reads longitudes east
        // of the region's west edge).
        let lon = near_lon(r, lon).clamp(r.west, r.west + r.lon_span());
        let (x, y) = (g.x(r, lon), g.y(lat));
        let (i0, j0) = (x.floor() as usize, y.floor() as usize);
        let (i1, j1) = ((i0 + 1).min(w - 1), (j0 + 1).min(h - 1));
        let (tx, ty) = (x - i0 as f64, y - j0 as f64);
        let mix = |f: &[[f32; 3]]| {
            let p = |k: usize| f[k][c] as f64;
            let top = p(j0 * w + i0) * (1.0 - tx) + p(j0 * w + i1) * tx;
            let bottom = p(j1 * w + i0) * (1.0 - tx) + p(j1 * w + i1) * tx;
            top * (1.0 - ty) + bottom * ty
        };
        (mix(&self.u), mix(&self.v))
    }
}

/// The point reached from (`lat`, `lon`) after `seconds` (negative: backwards, the departure
/// point of a parcel arriving here) moving with `wind`: midpoint steps of at most
/// [`SUBSTEP_S`].
pub fn trace(
    lat: f64,
    lon: f64,
    seconds: f64,
    wind: impl Fn(f64, f64) -> (f64, f64),
) -> (f64, f64) {
    if seconds == 0.0 || !seconds.is_finite() {
        return (lat, lon);
    }
    let n = (seconds.abs() / SUBSTEP_S).ceil().max(1.0);
    let dt = seconds / n;
    let deg = 180.0 / std::f64::consts::PI / EARTH_RADIUS_M;
    let rate = |lat: f64, lon: f64| {
        let (u, v) = wind(lat, lon);
        let cos = lat.to_radians().cos().max(MIN_COS_LAT);
        (v * deg, u * deg / cos)
    };
    let (mut la, mut lo) = (lat, lon);
    for _ in 0..n as usize {
        let (a, b) = rate(la, lo);
        let (mla, mlo) = ((la + 0.5 * dt * a).clamp(-90.0, 90.0), lo + 0.5 * dt * b);
        let (a, b) = rate(mla, mlo);
        la = (la + dt * a).clamp(-90.0, 90.0);
        lo += dt * b;
    }
    (la, lo)
}

/// A map of the same size as `like`, each layer channel `c` of pixel (`lat`, `lon`) from `f`,
/// the total recomputed as the max of the layers.
fn map_pixels(like: &CloudMap, f: impl Fn(usize, f64, f64) -> f64 + Sync) -> Vec<[u16; 4]> {
    let (w, h) = (like.width(), like.height());
    let r = like.meta.region;
    let channels: Vec<usize> = like.meta.layers.iter().map(|l| l.channel).collect();
    let mut texels = vec![[0u16; 4]; w * h];
    texels.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        let lat = r.pixel_lat(j, h);
        for (i, t) in row.iter_mut().enumerate() {
            let lon = r.pixel_lon(i, w);
            for &c in &channels {
                t[c] = coverage_to_sample(f(c, lat, lon));
            }
            t[3] = t[0].max(t[1]).max(t[2]);
        }
    });
    texels
}

fn lattice_of(map: &CloudMap) -> Option<WindLattice> {
    let s = map.structure.as_ref().filter(|s| s.is_whole())?;
    WindLattice::of(s, map.meta.region)
}

/// The winds of `map`'s layers as a function (zero where it has no structure images).
fn winds_of(map: &CloudMap) -> Box<Wind<'static>> {
    match lattice_of(map) {
        Some(l) => Box::new(move |c, lat, lon| l.at(c, lat, lon)),
        None => Box::new(|_, _, _| (0.0, 0.0)),
    }
}

/// `map` carried forward by `seconds` with its own layer winds (held fixed in time): each
/// pixel takes the coverage at its departure point. Structure kept; valid time and step move
/// on by `seconds`; coverage statistics recomputed.
pub fn advect(map: &CloudMap, seconds: f64) -> CloudMap {
    let wind = winds_of(map);
    let texels = map_pixels(map, |c, lat, lon| {
        let (la, lo) = trace(lat, lon, -seconds, |a, b| wind(c, a, b));
        sample_coverage(map, c, la, lo)
    });
    let mut out = CloudMap {
        meta: map.meta.clone(),
        texels,
        structure: map.structure.clone(),
        ground: map.ground.clone(),
    };
    shift_time(&mut out, seconds);
    crate::pipeline::fill_stats(&mut out.meta, &out.texels);
    out
}

fn shift_time(map: &mut CloudMap, seconds: f64) {
    let d = Duration::milliseconds((seconds * 1000.0).round() as i64);
    let src = &mut map.meta.source;
    src.valid_time = src.valid_time.map(|t| t + d);
    src.forecast_step_h += seconds / 3600.0;
}

/// Whether `a` and `b` can be blended pixel for pixel: same region, size and layers.
pub fn check_compatible(a: &CloudMap, b: &CloudMap) -> std::result::Result<(), String> {
    let (ma, mb) = (&a.meta, &b.meta);
    if ma.region != mb.region || (ma.width, ma.height) != (mb.width, mb.height) {
        return Err(format!(
            "steps differ in region or size ({:?} {}x{} vs {:?} {}x{})",
            ma.region, ma.width, ma.height, mb.region, mb.width, mb.height
        ));
    }
    let kinds = |m: &crate::meta::CloudMapMeta| m.layers.iter().map(|l| l.kind).collect::<Vec<_>>();
    if kinds(ma) != kinds(mb) {
        return Err("steps hold different layers".into());
    }
    Ok(())
}

/// When, as a fraction of the interval, the structure lattice's texel `k` takes the later
/// step's cloud type: spread by a hash over 0.25..0.75, so the genera of a region change a few
/// texels a minute rather than all at once half-way (which showed as one jump in a time-lapse:
/// the genera differ in cell size and shape). The renderer's blend switches by the same rule.
pub fn genus_switch_w(k: usize) -> f32 {
    let mut x = (k as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^= x >> 31;
    0.25 + 0.5 * ((x >> 40) as f32 / (1u64 << 24) as f32)
}

/// The moment a fraction `w` (0..=1) of the way from step `a` to step `b`, `interval_s`
/// seconds apart (semi-Lagrangian blend): per layer, with the layer wind interpolated in time
/// ((1 − w)·wind_a + w·wind_b, sampled along the path), `a` is sampled upwind at the point a
/// parcel here left w·interval earlier and `b` downwind where it will be (1 − w)·interval
/// later, then (1 − w)·a + w·b. So a front travels between the steps instead of fading out
/// in one place and in at the next. The total (A) is the max of the blended layers, as the
/// ingest computes it. Structure (base, top, winds) is the nearer step's (`a` when
/// w < 0.5), as are the other sidecar fields; the cloud type switches from `a`'s to `b`'s
/// texel by texel at `genus_switch_w` of the interval; the valid time and step are the moment's.
pub fn blend(a: &CloudMap, b: &CloudMap, w: f64, interval_s: f64) -> Result<CloudMap> {
    check_compatible(a, b).map_err(IngestError::BadMap)?;
    if !(w.is_finite() && (0.0..=1.0).contains(&w)) {
        return Err(IngestError::BadMap(format!(
            "blend weight {w} is outside 0..=1"
        )));
    }
    // Steps of one series share a lattice: the time-interpolated wind is made once there.
    let mixed = match (lattice_of(a), lattice_of(b)) {
        (Some(la), Some(lb)) => la.mix(&lb, w as f32),
        _ => None,
    };
    let wind: Box<Wind<'_>> = match mixed {
        Some(l) => Box::new(move |c, lat, lon| l.at(c, lat, lon)),
        None => {
            let (wa, wb) = (winds_of(a), winds_of(b));
            Box::new(move |c, lat, lon| {
                let (ua, va) = wa(c, lat, lon);
                let (ub, vb) = wb(c, lat, lon);
                ((1.0 - w) * ua + w * ub, (1.0 - w) * va + w * vb)
            })
        }
    };
    let texels = map_pixels(a, |c, lat, lon| {
        let (la, lo) = trace(lat, lon, -w * interval_s, |p, q| wind(c, p, q));
        let (lb, ob) = trace(lat, lon, (1.0 - w) * interval_s, |p, q| wind(c, p, q));
        (1.0 - w) * sample_coverage(a, c, la, lo) + w * sample_coverage(b, c, lb, ob)
    });
    Ok(moment(a, b, w, interval_s, texels))
}

/// The map of the moment `w` between `a` and `b` holding `texels` (however they were blended):
/// the ground mixed in time, each layer's genus from the step its switch says, the nearer
/// step's sidecar with its valid time moved to the moment, statistics of `texels`.
pub(super) fn moment(
    a: &CloudMap,
    b: &CloudMap,
    w: f64,
    interval_s: f64,
    texels: Vec<[u16; 4]>,
) -> CloudMap {
    let nearer = if w < 0.5 { a } else { b };
    // The ground in between: its fields mixed in time where both steps have it on one
    // lattice (the terrain is the same; snow, ice and cloud water change), else the nearer's.
    let ground = match (&a.ground, &b.ground) {
        (Some(ga), Some(gb)) => ga.mix(gb, w as f32),
        _ => None,
    }
    .or_else(|| nearer.ground.clone());
    let mut structure = nearer.structure.clone();
    if let (Some(s), Some(sa), Some(sb)) = (&mut structure, &a.structure, &b.structure) {
        if sa.types.len() == s.types.len() && sb.types.len() == s.types.len() {
            for (k, t) in s.types.iter_mut().enumerate() {
                let from = if w < f64::from(genus_switch_w(k)) {
                    sa
                } else {
                    sb
                };
                t[..3].copy_from_slice(&from.types[k][..3]);
            }
        }
    }
    let mut out = CloudMap {
        meta: nearer.meta.clone(),
        texels,
        structure,
        ground,
    };
    let to_moment = if w < 0.5 { w } else { w - 1.0 } * interval_s;
    shift_time(&mut out, to_moment);
    crate::pipeline::fill_stats(&mut out.meta, &out.texels);
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn genera_switch_spread_over_the_middle_half_of_the_interval() {
        let w: Vec<f32> = (0..10_000).map(super::genus_switch_w).collect();
        assert!(w.iter().all(|x| (0.25..0.75).contains(x)));
        // Spread, not bunched: each tenth of the range gets about a tenth of the texels.
        for d in 0..10 {
            let lo = 0.25 + 0.05 * d as f32;
            let n = w.iter().filter(|x| (lo..lo + 0.05).contains(*x)).count();
            assert!(
                (800..1200).contains(&n),
                "{n} texels switch in {lo}..{}",
                lo + 0.05
            );
        }
    }
}
