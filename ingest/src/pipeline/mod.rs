//! Forecast → CloudMap: spline upsampling per level, the critical-humidity formula per pixel
//! (after interpolation), max over each layer's levels, 16-bit RGBA out (DESIGN §1.3–1.5).
//! One job per module:
//! - `physics`: the coverage formula ([`coverage`]);
//! - `plan`: the resampling plan ([`Plan::new`]: taps, prepared levels, the map's sidecar
//!   content) and the coverage rows it yields, built in memory or re-derived for a new rh_cr;
//! - [`pixels`]: the grid structure sampled onto the structure images' pixels;
//! - `bands`: rows in parallel bands, streamed in order, the one loop every writer uses, so a
//!   6500×5500 map never holds more than a few bands in memory;
//! - `png`: the PNG writer (coverage, structure and ground images and the sidecar, one set);
//! - `tiff`: the GeoTIFF writer ([`crate::geotiff`] does the format);
//! - `stats`: the coverage statistics the sidecar records.
//!
//! The rh_cr rule and the standard atmosphere are the vocabulary's (`layer`); they stay
//! reachable here as [`validate_rh_cr`] and [`standard_altitude_m`].

use std::path::PathBuf;

use crate::forecast::RhLevel;
use crate::ground::Ground;
use crate::lattice::Placement;
use crate::meta::CloudMapMeta;
use crate::region::Region;
use crate::spline::{Interp, Tap};
use crate::weather::WeatherInputs;

mod bands;
mod physics;
pub mod pixels;
mod plan;
mod png;
mod stats;
mod tiff;

pub use crate::layer::{standard_altitude_m, validate_rh_cr};
pub use physics::coverage;
pub(crate) use stats::fill_stats;
pub use tiff::{GEOTIFF_META_ITEM, LAYER_BANDS};

use pixels::PixelSampler;

/// What the user asked of one ingest.
#[derive(Debug, Clone)]
pub struct IngestOptions {
    pub region: Region,
    pub width: u32,
    pub height: u32,
    /// Critical humidity per layer (low, middle, high), fractions in [0, 1).
    pub rh_cr: [f64; 3],
    pub interp: Interp,
}

/// One RH level prepared for fast row evaluation.
struct PreparedLevel {
    layer: usize,
    rh_cr: f64,
    ni: usize,
    /// Row-major values and their north–south slopes.
    y: Vec<f64>,
    s: Vec<f64>,
}

/// A ready-to-run resampling of one forecast onto one region.
pub struct Plan {
    levels: Vec<PreparedLevel>,
    rows: Vec<Tap>,
    cols: Vec<Tap>,
    /// Column of the padded axis → grid column.
    pad_map: Vec<usize>,
    interp: Interp,
    width: usize,
    height: usize,
    /// The forecast file read, which the output must not replace.
    source: PathBuf,
    pub meta: CloudMapMeta,
    /// Per-pixel structure, types and winds (issue 13), and what recomputes it when rh_cr
    /// changes (the RH-column source depends on it).
    sampler: PixelSampler,
    placement: Placement,
    rh: Vec<RhLevel>,
    weather: WeatherInputs,
    /// The ground on the structure lattice, when the forecast has orography (issue 14).
    ground: Option<Ground>,
}

#[cfg(test)]
mod tests;
