//! What a map holds at one point: the ground under it and, per layer, coverage, base, top,
//! type and source ([`CloudMap::probe`], `stratus probe`), read from the coverage texels, the
//! structure images and the ground grid.

use crate::cloud::CloudType;
use crate::ground::{Ground, GroundSource, ProbeGround};
use crate::lattice::StructureGrid;
use crate::sample::{sample_to_altitude, unpack_source, COVERAGE_FULL};
use crate::structure::{Probe, ProbeLayer};

use super::CloudMap;

impl CloudMap {
    /// Per layer at (`lat`, `lon`): coverage (bilinear between the map's pixel centres),
    /// base/top (bilinear between the structure images' pixel centres, over those with a
    /// value), type and source (nearest structure pixel). Beyond the outer row of a pole the
    /// region reaches, each blends toward that row's mean (type and source: its first pixel
    /// from half-way on), so the pole answers the same at every longitude
    /// ([`StructureGrid::pole_weight`]). `None` outside the map's region. A
    /// map without structure images (versions 1 and 2, synthetic maps) gives each layer its
    /// band, its band's source and its default type.
    pub fn probe(&self, lat: f64, lon: f64) -> Option<Probe> {
        let r = &self.meta.region;
        if !(lat.is_finite() && lon.is_finite()) || lat < r.south || lat > r.north {
            return None;
        }
        let dlon = (lon - r.west).rem_euclid(360.0);
        if dlon > r.lon_span() + 1e-9 {
            return None;
        }
        let (w, h) = (self.width(), self.height());
        let x = pixel_coord(dlon / r.lon_span(), w);
        let y = pixel_coord((r.north - lat) / (r.north - r.south), h);
        let (cover, _) = taps(x, y, w, h);
        // Near a pole the region reaches, toward the pole row's mean (one pole, one answer).
        let own = StructureGrid::of_map(r, self.meta.width, self.meta.height);
        let cover_pole = own.pole_weight(r, lat);
        let structure = self.structure.as_ref().filter(|s| s.is_whole()).map(|s| {
            let g = &s.grid;
            let (x, y) = (g.x(r, lon), g.y(lat));
            let pole = g.pole_weight(r, lat);
            let (corners, mut nearest) = taps(x, y, g.width as usize, g.height as usize);
            if let Some((row, _)) = pole.filter(|&(_, t)| t >= 0.5) {
                nearest = row * g.width as usize;
            }
            (s, g, pole, (corners, nearest))
        });
        let layers = self
            .meta
            .layers
            .iter()
            .map(|l| {
                let c = l.channel;
                let texel = |k: usize| Some(self.texels[k][c] as f64 / COVERAGE_FULL);
                let coverage = own
                    .toward_pole(cover_pole, blend(&cover, texel), texel)
                    .unwrap_or(0.0);
                let cloudy = coverage > 0.0;
                let (base_m, top_m, cloud_type, source) = match &structure {
                    Some((s, g, pole, (corners, nearest))) => (
                        {
                            let f = |k: usize| sample_to_altitude(s.base[k][c]);
                            g.toward_pole(*pole, blend(corners, f), f)
                        },
                        {
                            let f = |k: usize| sample_to_altitude(s.top[k][c]);
                            g.toward_pole(*pole, blend(corners, f), f)
                        },
                        CloudType::from_code(s.types[*nearest][c]),
                        unpack_source(s.types[*nearest][3], c)
                            .map_or(l.altitude_source, |p| p.altitude_source(l.altitude_source)),
                    ),
                    None => (
                        Some(l.base_m),
                        Some(l.top_m),
                        Some(CloudType::layer_default(l.kind)),
                        l.altitude_source,
                    ),
                };
                ProbeLayer {
                    kind: l.kind,
                    coverage,
                    base_m: base_m.filter(|_| cloudy),
                    top_m: top_m.filter(|_| cloudy),
                    cloud_type: cloud_type.filter(|_| cloudy),
                    source,
                }
            })
            .collect();
        Some(Probe {
            lat,
            lon,
            ground: self.probe_ground(lat, lon),
            layers,
        })
    }
}

impl CloudMap {
    /// What the ground holds at (`lat`, `lon`) for a probe.
    pub fn probe_ground(&self, lat: f64, lon: f64) -> ProbeGround {
        let Some((g, s)) = self.ground().and_then(|g| Some((g, g.at(lat, lon)?))) else {
            return ProbeGround::NONE;
        };
        ProbeGround {
            ground_m: s.height_m,
            ground_source: GroundSource::Orography,
            land: Some(s.land),
            ice: Some(s.ice),
            snow_kg_m2: Some(s.snow_kg_m2),
            snow_cover: Some(s.snow_cover),
            albedo: Some(s.albedo),
            cwat_kg_m2: s.cwat_kg_m2,
            ground_fields: g.fields.clone(),
        }
    }

    /// The map's ground, when it has one (maps ingested from a file with orography).
    pub fn ground(&self) -> Option<&Ground> {
        self.ground.as_ref()
    }

    /// The terrain height at (`lat`, `lon`), m above mean sea level, and where it came from:
    /// the ground grid inside the map's region, sea level (0 m) where the map has no ground or
    /// the point is outside its region.
    pub fn ground_height_m(&self, lat: f64, lon: f64) -> (f64, GroundSource) {
        match self.ground().and_then(|g| g.at(lat, lon)) {
            Some(s) => (s.height_m, GroundSource::Orography),
            None => (0.0, GroundSource::None),
        }
    }
}

/// Fractional pixel coordinate (pixel centres at whole numbers) of a position `f` in 0..1
/// across `n` pixels, clamped to the outer centres.
fn pixel_coord(f: f64, n: usize) -> f64 {
    (f * n as f64 - 0.5).clamp(0.0, (n - 1) as f64)
}

/// Bilinear corners (index, weight) and the nearest pixel of a `w`×`h` image at fractional
/// pixel coordinates (`x`, `y`), already clamped to the outer centres.
fn taps(x: f64, y: f64, w: usize, h: usize) -> ([(usize, f64); 4], usize) {
    let (i0, j0) = (x.floor() as usize, y.floor() as usize);
    let (i1, j1) = ((i0 + 1).min(w - 1), (j0 + 1).min(h - 1));
    let (tx, ty) = (x - i0 as f64, y - j0 as f64);
    let corners = [
        (j0 * w + i0, (1.0 - tx) * (1.0 - ty)),
        (j0 * w + i1, tx * (1.0 - ty)),
        (j1 * w + i0, (1.0 - tx) * ty),
        (j1 * w + i1, tx * ty),
    ];
    (corners, y.round() as usize * w + x.round() as usize)
}

/// Weighted mean over the corners where `f` has a value; `None` if none has one.
fn blend(corners: &[(usize, f64); 4], f: impl Fn(usize) -> Option<f64>) -> Option<f64> {
    let (mut s, mut ws) = (0.0, 0.0);
    for &(k, wt) in corners {
        if let Some(v) = f(k) {
            s += v * wt;
            ws += wt;
        }
    }
    (ws > 1e-12).then(|| s / ws)
}
