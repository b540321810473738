//! Each step's region-mean layer winds: what the renderer drifts the noise with through a
//! series (the integral of these from the first step), recorded in the series sidecar at ingest
//! so that opening a series decodes only the step maps a moment needs, not every step's.

use std::path::Path;

use crate::cloudmap::CloudMap;
use crate::error::Result;
use crate::sample::sample_to_wind;
use crate::structure::MapStructure;

/// Per layer (low, middle, high): (east, north) m/s.
pub type LayerWinds = [[f64; 2]; 3];

/// The largest wind the wind images can hold (m/s, [`crate::sample::wind_to_sample`]'s
/// range): a recorded mean beyond it was not made from them.
pub const MAX_MEAN_WIND: f64 = 327.68;

/// Per layer, the mean of the wind images over the structure lattice (m/s).
pub fn mean_wind(s: &MapStructure) -> LayerWinds {
    let n = s.wind_u.len().max(1) as f64;
    std::array::from_fn(|c| {
        let mean = |w: &[[u16; 3]]| w.iter().map(|x| sample_to_wind(x[c])).sum::<f64>() / n;
        [mean(&s.wind_u), mean(&s.wind_v)]
    })
}

/// The region-mean layer winds of `map`; zero for a map without (whole) structure images.
pub fn map_mean_wind(map: &CloudMap) -> LayerWinds {
    map.structure
        .as_ref()
        .filter(|s| s.is_whole())
        .map_or([[0.0; 2]; 3], mean_wind)
}

/// The region-mean layer winds of the step map whose sidecar is `sidecar` (decoded once, at
/// ingest); `None` for a map without structure images (nothing to record).
pub fn step_mean_wind(sidecar: &Path) -> Result<Option<LayerWinds>> {
    let map = CloudMap::load(sidecar)?;
    Ok(map
        .structure
        .as_ref()
        .filter(|s| s.is_whole())
        .map(mean_wind))
}

/// Whether `w` could be a recorded mean: finite and within the wind images' range.
pub fn is_plausible(w: &LayerWinds) -> bool {
    w.iter()
        .flatten()
        .all(|v| v.is_finite() && v.abs() <= MAX_MEAN_WIND)
}
