//! The store's variables: their names, dimensions, element types and CF attributes, and how
//! each plane (one time, one layer) is taken from a [`CloudMap`] and put back. Every value is
//! the sample the PNG map holds (`sample`'s encodings), with CF's `scale_factor`/`add_offset`
//! so that xarray decodes physical units: the store and the PNG map agree value for value.

use serde_json::{json, Map, Value};

use crate::cloud::CloudType;
use crate::cloudmap::CloudMap;
use crate::ground::image as ground_image;
use crate::lattice::StructureGrid;
use crate::meta::CloudMapMeta;

use super::array::Dtype;

/// Which lattice a variable lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Grid {
    /// The coverage's pixels: dims `lat`, `lon`.
    Map,
    /// The structure lattice: `structure_lat`, `structure_lon`.
    Structure,
    /// The ground lattice: `ground_lat`, `ground_lon`.
    Ground,
}

impl Grid {
    /// The names of the grid's two dimensions (north–south, west–east).
    pub fn dims(self) -> [&'static str; 2] {
        match self {
            Grid::Map => ["lat", "lon"],
            Grid::Structure => ["structure_lat", "structure_lon"],
            Grid::Ground => ["ground_lat", "ground_lon"],
        }
    }

    /// Where the grid's pixel centres lie for a step with `meta`; `None` when the map has no
    /// such grid (no structure images, no ground).
    pub fn of(self, meta: &CloudMapMeta) -> Option<StructureGrid> {
        match self {
            Grid::Map => Some(StructureGrid::of_map(&meta.region, meta.width, meta.height)),
            Grid::Structure => meta.structure_grid,
            Grid::Ground => meta.ground.as_ref().map(|g| g.grid),
        }
    }
}

/// One data variable.
#[derive(Debug, Clone, Copy)]
pub struct Var {
    pub name: &'static str,
    pub grid: Grid,
    /// Has the `layer` dimension (low, middle, high).
    pub layered: bool,
    pub dtype: Dtype,
}

const fn var(name: &'static str, grid: Grid, layered: bool, dtype: Dtype) -> Var {
    Var {
        name,
        grid,
        layered,
        dtype,
    }
}

/// Every data variable, in the order they are written.
pub const VARS: [Var; 16] = [
    var("coverage", Grid::Map, true, Dtype::U16),
    var("total_coverage", Grid::Map, false, Dtype::U16),
    var("cloud_base", Grid::Structure, true, Dtype::U16),
    var("cloud_top", Grid::Structure, true, Dtype::U16),
    var("convective_cloud_base", Grid::Structure, false, Dtype::U16),
    var("convective_cloud_top", Grid::Structure, false, Dtype::U16),
    var("cloud_type", Grid::Structure, true, Dtype::U8),
    var("cloud_base_source", Grid::Structure, true, Dtype::U8),
    var("eastward_wind", Grid::Structure, true, Dtype::U16),
    var("northward_wind", Grid::Structure, true, Dtype::U16),
    var("surface_altitude", Grid::Ground, false, Dtype::U16),
    var("land_area_fraction", Grid::Ground, false, Dtype::U16),
    var("sea_ice_area_fraction", Grid::Ground, false, Dtype::U16),
    var("surface_albedo", Grid::Ground, false, Dtype::U16),
    var("surface_snow_amount", Grid::Ground, false, Dtype::U16),
    var(
        "cloud_condensed_water_content",
        Grid::Ground,
        false,
        Dtype::U16,
    ),
];

/// The layer planes a variable has: 3 when layered, else 1.
pub fn planes(v: &Var) -> usize {
    if v.layered {
        3
    } else {
        1
    }
}

/// The CF attributes of a data variable.
pub fn attributes(v: &Var) -> Map<String, Value> {
    let fraction = 1.0 / crate::sample::COVERAGE_FULL;
    // Altitudes: m = (v − 1) × 0.5 − 500, 0 = no value (`sample::altitude_to_sample`).
    let altitude = |std: &str, long: &str| {
        json!({"standard_name": std, "long_name": long, "units": "m",
               "scale_factor": 0.5, "add_offset": -500.5, "_FillValue": 0,
               "comment": "above mean sea level"})
    };
    let wind = |std: &str, long: &str| {
        json!({"standard_name": std, "long_name": long, "units": "m s-1",
               "scale_factor": 0.01, "add_offset": -327.68})
    };
    let frac = |std: &str, long: &str| json!({"standard_name": std, "long_name": long, "units": "1", "scale_factor": fraction});
    let v = match v.name {
        "coverage" => frac(
            "cloud_area_fraction_in_atmosphere_layer",
            "cloud cover of the layer (critical-humidity formula)",
        ),
        "total_coverage" => frac(
            "cloud_area_fraction",
            "total cloud cover (max of the layers)",
        ),
        "cloud_base" => altitude("cloud_base_altitude", "cloud base of the layer"),
        "cloud_top" => altitude("cloud_top_altitude", "cloud top of the layer"),
        "convective_cloud_base" => altitude(
            "convective_cloud_base_altitude",
            "GFS convective cloud base",
        ),
        "convective_cloud_top" => {
            altitude("convective_cloud_top_altitude", "GFS convective cloud top")
        }
        "cloud_type" => {
            let codes: Vec<u8> = (0..=CloudType::MAX_CODE).collect();
            let names: Vec<&str> = std::iter::once("none")
                .chain(CloudType::ALL.iter().map(|t| t.name()))
                .collect();
            json!({"long_name": "WMO cloud genus of the layer", "flag_values": codes,
                   "flag_meanings": names.join(" ")})
        }
        "cloud_base_source" => json!({"long_name": "where the layer's base and top come from",
            "flag_values": [0, 1, 2, 3], "flag_meanings": "none gfs_layer rh_column band"}),
        "eastward_wind" => wind("eastward_wind", "layer-mean eastward wind"),
        "northward_wind" => wind("northward_wind", "layer-mean northward wind"),
        "surface_altitude" => json!({"standard_name": "surface_altitude", "units": "m",
            "long_name": "terrain height", "scale_factor": 0.5, "add_offset": -500.5}),
        "land_area_fraction" => frac("land_area_fraction", "land fraction"),
        "sea_ice_area_fraction" => frac("sea_ice_area_fraction", "sea-ice fraction"),
        "surface_albedo" => frac("surface_albedo", "broadband surface albedo"),
        "surface_snow_amount" => json!({"standard_name": "surface_snow_amount", "units": "kg m-2",
            "long_name": "snow water equivalent", "scale_factor": 0.1}),
        _ => json!({"standard_name": "atmosphere_mass_content_of_cloud_condensed_water",
            "units": "kg m-2", "long_name": "total column cloud water", "scale_factor": 0.001}),
    };
    v.as_object().cloned().unwrap_or_default()
}

/// Plane `layer` of `v` in `map` (row-major, row 0 north), or `None` when the map lacks its
/// grid.
pub fn extract(map: &CloudMap, v: &Var, layer: usize) -> Option<Vec<u16>> {
    let l = layer;
    match v.grid {
        Grid::Map => {
            let c = if v.layered { l } else { 3 };
            Some(map.texels.iter().map(|t| t[c]).collect())
        }
        Grid::Structure => {
            let s = map.structure.as_ref()?;
            Some(match v.name {
                "cloud_base" => s.base.iter().map(|p| p[l]).collect(),
                "cloud_top" => s.top.iter().map(|p| p[l]).collect(),
                "convective_cloud_base" => s.base.iter().map(|p| p[3]).collect(),
                "convective_cloud_top" => s.top.iter().map(|p| p[3]).collect(),
                "cloud_type" => s.types.iter().map(|p| p[l] as u16).collect(),
                "cloud_base_source" => s
                    .types
                    .iter()
                    .map(|p| ((p[3] >> (2 * l)) & 3) as u16)
                    .collect(),
                "eastward_wind" => s.wind_u.iter().map(|p| p[l]).collect(),
                _ => s.wind_v.iter().map(|p| p[l]).collect(),
            })
        }
        Grid::Ground => {
            let g = map.ground.as_ref()?;
            let (bytes, stride, c) = match ground_channel(v.name) {
                (false, c) => (ground_image::surface_bytes(g), 4, c),
                (true, c) => (ground_image::water_bytes(g), 2, c),
            };
            Some(
                bytes
                    .chunks_exact(2)
                    .skip(c)
                    .step_by(stride)
                    .map(|b| u16::from_be_bytes([b[0], b[1]]))
                    .collect(),
            )
        }
    }
}

/// A ground variable's image (false: surface, true: water) and channel in it.
pub fn ground_channel(name: &str) -> (bool, usize) {
    match name {
        "surface_altitude" => (false, 0),
        "land_area_fraction" => (false, 1),
        "sea_ice_area_fraction" => (false, 2),
        "surface_albedo" => (false, 3),
        "surface_snow_amount" => (true, 0),
        _ => (true, 1),
    }
}

/// The coordinate variables' CF attributes, by name.
pub fn coordinate_attributes(name: &str, units_time: &str) -> Map<String, Value> {
    let v = match name {
        "time" => json!({"standard_name": "time", "long_name": "valid time",
            "units": units_time, "calendar": "proleptic_gregorian"}),
        "forecast_period" => json!({"standard_name": "forecast_period", "units": "hours",
            "long_name": "hours after the run (reference time)"}),
        "layer" => json!({"long_name": "cloud layer", "flag_values": [0, 1, 2],
            "flag_meanings": "low middle high"}),
        n if n.ends_with("lat") => json!({"standard_name": "latitude", "units": "degrees_north",
            "long_name": "latitude of the pixel centres"}),
        _ => json!({"standard_name": "longitude", "units": "degrees_east",
            "long_name": "longitude of the pixel centres (continuous east of the west edge)"}),
    };
    v.as_object().cloned().unwrap_or_default()
}
