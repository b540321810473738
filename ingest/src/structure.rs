//! A version-3 map's structure images — per pixel and layer: cloud base and top, cloud type
//! and its source, layer wind — their encodings, how they are read back and checked, and the
//! point probe over a whole map ([`CloudMap::probe`]).
//!
//! Encodings (docs/ingest.md, "Structure images"), all row 0 north like the coverage PNG:
//! - `MAP.base.png`, `MAP.top.png`: 16-bit RGBA, R/G/B = low/middle/high layer, A = GFS's
//!   convective cloud. Sample 0 = no value; else altitude m = (v − 1) × 0.5 − 500, so
//!   −500 … 32 266.5 m in steps of 0.5 m.
//! - `MAP.type.png`: 8-bit RGBA, R/G/B = [`CloudType`] code of each layer (0 none, 1–10);
//!   A = base/top source, two bits a layer (low in bits 0–1, middle 2–3, high 4–5; 1 GFS
//!   layer, 2 RH column, 3 the layer's band, 0 none; bits 6–7 zero).
//! - `MAP.wind-u.png`, `MAP.wind-v.png`: 16-bit RGB, R/G/B = layer; m/s = (v − 32768) / 100,
//!   so ±327.68 m/s in steps of 0.01 m/s.
//!
//! Base, top, type and source are given everywhere a layer exists, cloud or not (where a
//! cloud of that layer would be): the coverage PNG says whether there is one, and a renderer
//! filtering these textures never blends a base with a "none".

use serde::Serialize;

use crate::cloudmap::{CloudMap, COVERAGE_FULL};
use crate::meta::{AltitudeSource, LayerKind};
use crate::weather::{CloudType, PointSource};

/// Altitude (m) as its 16-bit sample; `None` → 0.
pub fn altitude_to_sample(m: Option<f64>) -> u16 {
    match m {
        Some(m) if m.is_finite() => ((m + 500.0) * 2.0).round().clamp(0.0, 65534.0) as u16 + 1,
        _ => 0,
    }
}

pub fn sample_to_altitude(v: u16) -> Option<f64> {
    (v != 0).then(|| (v - 1) as f64 * 0.5 - 500.0)
}

/// Wind component (m/s) as its 16-bit sample.
pub fn wind_to_sample(ms: f64) -> u16 {
    if !ms.is_finite() {
        return 32768;
    }
    (ms * 100.0 + 32768.0).round().clamp(0.0, 65535.0) as u16
}

pub fn sample_to_wind(v: u16) -> f64 {
    (v as f64 - 32768.0) / 100.0
}

/// Sources of the three layers packed into the type image's alpha.
pub fn pack_sources(s: [Option<PointSource>; 3]) -> u8 {
    s.iter()
        .enumerate()
        .map(|(c, s)| s.map_or(0, |s| s as u8) << (2 * c))
        .sum()
}

pub fn unpack_source(a: u8, channel: usize) -> Option<PointSource> {
    PointSource::from_code((a >> (2 * channel)) & 3)
}

/// The structure images of a map, decoded (row-major, row 0 north).
#[derive(Debug, Clone, PartialEq)]
pub struct MapStructure {
    pub base: Vec<[u16; 4]>,
    pub top: Vec<[u16; 4]>,
    pub types: Vec<[u8; 4]>,
    pub wind_u: Vec<[u16; 3]>,
    pub wind_v: Vec<[u16; 3]>,
}

impl MapStructure {
    /// The first pixel whose type image breaks the table: (index, what is wrong).
    pub fn first_bad_type(&self) -> Option<(usize, String)> {
        self.types.iter().enumerate().find_map(|(k, t)| {
            if let Some(c) = (0..3).find(|&c| t[c] > CloudType::MAX_CODE) {
                return Some((
                    k,
                    format!(
                        "{} layer type code {} is outside the table (0..={})",
                        LayerKind::ALL[c].name(),
                        t[c],
                        CloudType::MAX_CODE
                    ),
                ));
            }
            (t[3] & 0xC0 != 0).then(|| (k, format!("source bits {:#04x} use bits 6-7", t[3])))
        })
    }
}

/// One layer at a point ([`CloudMap::probe`]); serializes as `stratus probe --json` prints it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProbeLayer {
    pub kind: LayerKind,
    /// 0..1, bilinear.
    pub coverage: f64,
    /// m above sea level, bilinear; `None` where the layer has no cloud.
    pub base_m: Option<f64>,
    pub top_m: Option<f64>,
    /// Nearest pixel's type; `None` where the layer has no cloud.
    #[serde(rename = "type")]
    pub cloud_type: Option<CloudType>,
    /// Where the base and top come from (nearest pixel).
    pub source: AltitudeSource,
}

/// What a map holds at one point, per layer.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Probe {
    pub lat: f64,
    pub lon: f64,
    pub layers: Vec<ProbeLayer>,
}

impl CloudMap {
    /// Per layer at (`lat`, `lon`): coverage and base/top (bilinear between pixel centres),
    /// type and source (nearest pixel). `None` outside the map's region. A map without
    /// structure images (versions 1 and 2, synthetic maps) gives each layer its band, its
    /// band's source and its default type.
    pub fn probe(&self, lat: f64, lon: f64) -> Option<Probe> {
        let r = &self.meta.region;
        let (w, h) = (self.width(), self.height());
        if !(lat.is_finite() && lon.is_finite()) || lat < r.south || lat > r.north {
            return None;
        }
        let dlon = (lon - r.west).rem_euclid(360.0);
        if dlon > r.lon_span() + 1e-9 {
            return None;
        }
        // Fractional pixel coordinates (pixel centres at +0.5), clamped to the outer centres.
        let x = (dlon / r.lon_span() * w as f64 - 0.5).clamp(0.0, (w - 1) as f64);
        let y = ((r.north - lat) / (r.north - r.south) * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (i0, j0) = (x.floor() as usize, y.floor() as usize);
        let (i1, j1) = ((i0 + 1).min(w - 1), (j0 + 1).min(h - 1));
        let (tx, ty) = (x - i0 as f64, y - j0 as f64);
        let corners = [
            (j0 * w + i0, (1.0 - tx) * (1.0 - ty)),
            (j0 * w + i1, tx * (1.0 - ty)),
            (j1 * w + i0, (1.0 - tx) * ty),
            (j1 * w + i1, tx * ty),
        ];
        let nearest = y.round() as usize * w + x.round() as usize;
        // Weighted mean over the corners that have a value.
        let blend = |f: &dyn Fn(usize) -> Option<f64>| -> Option<f64> {
            let (mut s, mut ws) = (0.0, 0.0);
            for &(k, wt) in &corners {
                if let Some(v) = f(k) {
                    s += v * wt;
                    ws += wt;
                }
            }
            (ws > 1e-12).then(|| s / ws)
        };
        let layers = self
            .meta
            .layers
            .iter()
            .map(|l| {
                let c = l.channel;
                let coverage =
                    blend(&|k| Some(self.texels[k][c] as f64 / COVERAGE_FULL)).unwrap_or(0.0);
                let cloudy = coverage > 0.0;
                let (base_m, top_m, cloud_type, source) = match &self.structure {
                    Some(s) => (
                        blend(&|k| sample_to_altitude(s.base[k][c])),
                        blend(&|k| sample_to_altitude(s.top[k][c])),
                        CloudType::from_code(s.types[nearest][c]),
                        unpack_source(s.types[nearest][3], c)
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
        Some(Probe { lat, lon, layers })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encodings_round_trip_within_their_step() {
        for m in [-500.0, 0.0, 123.4, 8848.0, 16_000.25, 32_266.5] {
            let back = sample_to_altitude(altitude_to_sample(Some(m))).unwrap();
            assert!((back - m).abs() <= 0.25, "{m} → {back}");
        }
        assert_eq!(altitude_to_sample(None), 0);
        assert_eq!(sample_to_altitude(0), None);
        assert_eq!(altitude_to_sample(Some(-600.0)), 1);
        for u in [-120.0, -0.004, 0.0, 37.25, 150.0] {
            assert!(
                (sample_to_wind(wind_to_sample(u)) - u).abs() <= 0.005,
                "{u}"
            );
        }
        let a = pack_sources([Some(PointSource::GfsLayer), None, Some(PointSource::Band)]);
        assert_eq!(a, 0b11_00_01);
        assert_eq!(unpack_source(a, 0), Some(PointSource::GfsLayer));
        assert_eq!(unpack_source(a, 1), None);
        assert_eq!(unpack_source(a, 2), Some(PointSource::Band));
    }
}
