//! A version-3 map's structure images — per pixel and layer: cloud base and top, cloud type
//! and its source, layer wind — as a map holds them ([`MapStructure`]) and checks them, the
//! GeoTIFF's structure bands, and what the point probe answers ([`Probe`]; the probe itself is
//! `CloudMap::probe`, in `cloudmap`). The sample encodings are `sample`'s, the lattice
//! `lattice`'s; both stay reachable here.
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

use crate::cloud::CloudType;
use crate::ground::ProbeGround;
use crate::lattice::StructureGrid;
use crate::layer::{AltitudeSource, LayerKind, PointSource};

// The encodings and the lattice live in the vocabulary; their old paths stay.
pub use crate::lattice::{structure_grid, STRUCTURE_OVERSAMPLE};
pub use crate::sample::{
    altitude_to_sample, pack_sources, sample_to_altitude, sample_to_wind, unpack_source,
    wind_to_sample,
};

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

/// One layer at a point (`CloudMap::probe`); serializes as `stratus probe --json` prints it.
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
