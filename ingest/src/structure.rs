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
//!
//! The images cover the map's region at their own, smaller size, on the forecast grid's
//! lattice ([`structure_grid`]): the structure is bilinear (or nearest) between grid points, so
//! a few pixels per grid cell hold it exactly, where the coverage needs the map's full
//! resolution. Readers sample them by lat/lon (the sidecar's `structure_grid`): bilinear for
//! base, top and wind, nearest pixel for type and source.
//!
//! A GeoTIFF map carries the same pixels decoded to physical units, one Float32 band per
//! layer and quantity ([`StructureBand`]), in its second image (`crate::geotiff::PageSpec`).

use serde::Serialize;

use crate::cloudmap::{CloudMap, COVERAGE_FULL};
use crate::ground::ProbeGround;
use crate::meta::{AltitudeSource, LayerKind, StructureGrid};
use crate::region::Region;
use crate::weather::{CloudType, PointSource};

/// Structure pixels per forecast grid cell along each axis, most preferred first. The
/// pixel centres are put on the grid's own lattice, every grid point a pixel centre and k − 1
/// more between neighbours, so bilinear between pixels reproduces bilinear between grid points
/// exactly (each pixel cell lies inside one grid cell, where the field is bilinear), and with k
/// odd the nearest pixel's nearest grid point is the point's own (no pixel centre sits on the
/// half-way line). 7 rather than 1: a texture filter's limited weight precision and the
/// convective cloud's presence mask (nearest grid point) then step at 1/7 of a cell. Smaller
/// k are for maps too small to hold 7 a cell.
pub const STRUCTURE_OVERSAMPLE: [u32; 4] = [7, 5, 3, 1];

/// One axis of the structure lattice: the region spans `from..from + span` grid cells (from
/// the grid's first point); the first pixel centre in cells and the pixel count at the largest
/// oversampling whose count fits in `cap`, from the grid line at or before the region's
/// start to the one at or after its end (so the region is covered by centres).
fn lattice_axis(from: f64, span: f64, cap: u32) -> Option<(f64, u32, u32)> {
    if !(from.is_finite() && span.is_finite() && span > 0.0) {
        return None;
    }
    STRUCTURE_OVERSAMPLE.iter().find_map(|&k| {
        let kf = k as f64;
        // The slack keeps a region edge on a lattice line from adding a pixel by rounding.
        let first = (from * kf + 1e-6).floor();
        let last = ((from + span) * kf - 1e-6).ceil();
        let n = last - first + 1.0;
        (n <= cap as f64).then(|| (first / kf, n as u32, k))
    })
}

/// Where a `map`-sized map of `region`'s structure images lie, on the forecast grid whose
/// first point is (`grid_north`, `grid_west`) with spacing (`di`, `dj`) degrees: per axis, the
/// grid's lattice at [`STRUCTURE_OVERSAMPLE`] pixels a cell (7 where it fits in the map's side,
/// else 5, 3, 1), covering the region; an axis where even one pixel per grid point does not
/// fit (a map coarser than its grid) keeps the map's own pixels. Never larger than the map.
pub fn structure_grid(
    map: (u32, u32),
    region: &Region,
    (grid_north, grid_west): (f64, f64),
    (di, dj): (f64, f64),
) -> StructureGrid {
    let mut g = StructureGrid::of_map(region, map.0, map.1);
    let from_lon = (region.west - grid_west).rem_euclid(360.0) / di;
    if let Some((first, n, k)) = lattice_axis(from_lon, region.lon_span() / di, map.0) {
        g.width = n;
        g.west = region.west - (from_lon - first) * di;
        g.dlon = di / k as f64;
    }
    let from_lat = (grid_north - region.north) / dj;
    if let Some((first, n, k)) = lattice_axis(from_lat, (region.north - region.south) / dj, map.1) {
        g.height = n;
        g.north = region.north + (from_lat - first) * dj;
        g.dlat = dj / k as f64;
    }
    g
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

/// The value a GeoTIFF structure band holds where it has none (GDAL's nodata).
pub const STRUCTURE_NODATA: f32 = -9999.0;

/// One band of a GeoTIFF's structure image, in physical units: the structure images' samples
/// decoded ([`STRUCTURE_NODATA`] where they hold none).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StructureBand {
    /// Cloud base, m above mean sea level.
    Base(LayerKind),
    /// Cloud top, m above mean sea level.
    Top(LayerKind),
    /// [`CloudType`] code, 1..=10.
    Type(LayerKind),
    /// [`PointSource`] code of the base and top: 1 GFS layer, 2 RH column, 3 the band.
    Source(LayerKind),
    /// Layer-mean eastward wind, m/s.
    WindU(LayerKind),
    /// Layer-mean northward wind, m/s.
    WindV(LayerKind),
    /// GFS's convective cloud base and top, m above mean sea level.
    ConvectiveBase,
    ConvectiveTop,
}

impl StructureBand {
    /// The bands of a map with `layers`, in band order: per layer base, top, type, source,
    /// wind u, wind v; then the convective cloud's base and top.
    pub fn of_layers(layers: &[LayerKind]) -> Vec<StructureBand> {
        let mut v = Vec::with_capacity(6 * layers.len() + 2);
        for &k in layers {
            v.extend([
                StructureBand::Base(k),
                StructureBand::Top(k),
                StructureBand::Type(k),
                StructureBand::Source(k),
                StructureBand::WindU(k),
                StructureBand::WindV(k),
            ]);
        }
        v.extend([StructureBand::ConvectiveBase, StructureBand::ConvectiveTop]);
        v
    }

    /// GDAL's band description.
    pub fn description(self) -> String {
        match self {
            StructureBand::Base(k) => format!("{} cloud base", k.name()),
            StructureBand::Top(k) => format!("{} cloud top", k.name()),
            StructureBand::Type(k) => format!("{} cloud type (code)", k.name()),
            StructureBand::Source(k) => format!("{} cloud base/top source (code)", k.name()),
            StructureBand::WindU(k) => format!("{} layer wind u (eastward)", k.name()),
            StructureBand::WindV(k) => format!("{} layer wind v (northward)", k.name()),
            StructureBand::ConvectiveBase => "convective cloud base".into(),
            StructureBand::ConvectiveTop => "convective cloud top".into(),
        }
    }

    /// GDAL's unit type; empty for codes.
    pub fn unit(self) -> &'static str {
        match self {
            StructureBand::Type(_) | StructureBand::Source(_) => "",
            StructureBand::WindU(_) | StructureBand::WindV(_) => "m/s",
            _ => "m",
        }
    }

    /// The code table of a code band, as text (`1=cirrus, 2=…`).
    pub fn codes(self) -> Option<String> {
        match self {
            StructureBand::Type(_) => Some(
                CloudType::ALL
                    .iter()
                    .map(|t| format!("{}={}", t.code(), t.name()))
                    .collect::<Vec<_>>()
                    .join(", "),
            ),
            StructureBand::Source(_) => Some(format!(
                "{}=gfs-layer, {}=rh-column, {}=band (the layer's altitude band)",
                PointSource::GfsLayer as u8,
                PointSource::RhColumn as u8,
                PointSource::Band as u8
            )),
            _ => None,
        }
    }
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

/// The structure images of a map, decoded (row-major, row 0 north), `grid.width`×`grid.height`
/// pixels where `grid` puts them ([`structure_grid`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MapStructure {
    pub grid: StructureGrid,
    pub base: Vec<[u16; 4]>,
    pub top: Vec<[u16; 4]>,
    pub types: Vec<[u8; 4]>,
    pub wind_u: Vec<[u16; 3]>,
    pub wind_v: Vec<[u16; 3]>,
}

impl MapStructure {
    /// Whether every image holds `width`×`height` pixels.
    pub fn is_whole(&self) -> bool {
        let n = self.grid.width as usize * self.grid.height as usize;
        n > 0
            && [
                self.base.len(),
                self.top.len(),
                self.types.len(),
                self.wind_u.len(),
                self.wind_v.len(),
            ]
            .iter()
            .all(|&l| l == n)
    }

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

/// What a map holds at one point: the ground, and per layer the cloud.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Probe {
    pub lat: f64,
    pub lon: f64,
    /// The ground there (`ground_m`, `ground_source`, …, `cwat_kg_m2`), flat in the JSON.
    #[serde(flatten)]
    pub ground: ProbeGround,
    pub layers: Vec<ProbeLayer>,
}

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

    #[test]
    fn the_structure_lattice_follows_the_grid_and_never_exceeds_the_map() {
        let ea = Region::parse("0,55,39,105").unwrap();
        let gfs = |map| structure_grid(map, &ea, (90.0, 0.0), (2.5, 2.5));
        // 39..105°E: lattice lines every 2.5/7° from the one at or west of 39°E (38.93°) to
        // 105°E, 186 centres; 0..55°N: 22 cells × 7 + 1.
        let g = gfs((6500, 5500));
        assert_eq!((g.width, g.height), (186, 155));
        assert!((g.west - (15.0 + 4.0 / 7.0) * 2.5).abs() < 1e-9, "{g:?}");
        assert_eq!(g.north, 55.0);
        assert!((g.dlon - 2.5 / 7.0).abs() < 1e-12 && (g.dlat - 2.5 / 7.0).abs() < 1e-12);
        assert_eq!(gfs((1300, 1100)), g);
        // Too small for 7 a cell: 5, 3, 1, then the map's own pixels.
        let g = gfs((150, 100));
        assert_eq!(
            (g.width, g.height, g.dlon, g.dlat),
            (133, 67, 0.5, 2.5 / 3.0)
        );
        let g = gfs((20, 3));
        assert_eq!((g.width, g.height), (20, 3));
        assert_eq!(g, StructureGrid::of_map(&ea, 20, 3));
        // 0.25°: 264 × 220 cells.
        let g = structure_grid((6500, 5500), &ea, (90.0, 0.0), (0.25, 0.25));
        assert_eq!((g.width, g.height), (1849, 1541));
        // Across the date line (grid lines 170°E..190°E).
        let pac = Region::parse("-10,10,170,-170").unwrap();
        let g = structure_grid((4000, 4000), &pac, (90.0, 0.0), (2.5, 2.5));
        assert_eq!((g.width, g.height, g.west), (57, 57, 170.0));
        // A degenerate grid spacing keeps the map's pixels.
        let g = structure_grid((40, 30), &pac, (90.0, 0.0), (0.0, f64::NAN));
        assert_eq!(g, StructureGrid::of_map(&pac, 40, 30));
    }
}
