//! The store's layout, defined once: which arrays a store of some steps holds (name,
//! dimensions, shape, chunks, element type, CF attributes), its coordinates' values and the
//! group's attributes. [`super::write`] and [`super::batch`] put it on disk; the Python package
//! (python/src/dataset.rs) lays a PNG map or series out by the same functions, so a Dataset
//! opened from PNG cannot drift from the store.

use chrono::{DateTime, Utc};
use serde_json::{json, Map, Value};

use crate::lattice::StructureGrid;
use crate::meta::{format_time, CloudMapMeta};
use crate::series::SeriesMeta;

use super::array::{ArrayMeta, Dtype};
use super::vars::{self, Grid, VARS};
use super::{CHUNK_SIDE, SERIES_ATTR, STEPS_ATTR, STORE_FORMAT};

/// The lattices of a store: the map's pixels, and the structure and ground lattices when
/// its steps have them (one of each per store).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lattices {
    pub map: StructureGrid,
    pub structure: Option<StructureGrid>,
    pub ground: Option<StructureGrid>,
}

impl Lattices {
    pub fn of(m: &CloudMapMeta) -> Lattices {
        let (structure, ground) = lattices(m);
        Lattices {
            map: StructureGrid::of_map(&m.region, m.width, m.height),
            structure,
            ground,
        }
    }

    pub fn get(&self, g: Grid) -> Option<StructureGrid> {
        match g {
            Grid::Map => Some(self.map),
            Grid::Structure => self.structure,
            Grid::Ground => self.ground,
        }
    }
}

/// A step's structure and ground lattices (`None`: it has none; a structure lattice without
/// structure images is none): one of each per store.
pub fn lattices(m: &CloudMapMeta) -> (Option<StructureGrid>, Option<StructureGrid>) {
    (
        m.structure_grid.filter(|_| !m.extra_images.is_empty()),
        m.ground.as_ref().map(|g| g.grid),
    )
}

/// The run a store's steps belong to: the series' reference time, else the first step's.
pub fn run_reference(series: Option<&SeriesMeta>, first: &CloudMapMeta) -> DateTime<Utc> {
    series
        .map(|s| s.reference_time)
        .or(first.source.reference_time)
        .unwrap_or_default()
}

/// One coordinate: its name, element type and values, each as the element type's bits (what
/// [`super::array::encode_chunk`] and [`super::array::le_bytes`] take).
#[derive(Debug, Clone, PartialEq)]
pub struct Coordinate {
    pub name: &'static str,
    pub dtype: Dtype,
    pub values: Vec<u64>,
}

/// The coordinates along `time`, in the store's order, and their element types.
pub const TIME_COORDINATES: [(&str, Dtype); 2] =
    [("time", Dtype::I64), ("forecast_period", Dtype::F64)];

/// One step's [`TIME_COORDINATES`], as bits: whole minutes after the run `reference`, and
/// hours.
pub fn step_time((reference, valid): (DateTime<Utc>, DateTime<Utc>), hours: f64) -> [u64; 2] {
    let minutes = (valid - reference).num_seconds().div_euclid(60);
    [minutes as u64, hours.to_bits()]
}

/// The time coordinates of the step `m`: [`step_time`] of its sidecar's run and valid time.
pub fn meta_time(m: &CloudMapMeta) -> [u64; 2] {
    let reference = m.source.reference_time.unwrap_or_default();
    let valid = m.source.valid_time.unwrap_or(reference);
    step_time((reference, valid), m.source.forecast_step_h)
}

/// The coordinates that do not grow: layer, then each lattice's latitudes and longitudes.
pub fn static_coordinates(lat: &Lattices) -> Vec<Coordinate> {
    let mut v = vec![Coordinate {
        name: "layer",
        dtype: Dtype::U8,
        values: vec![0, 1, 2],
    }];
    for grid in [Grid::Map, Grid::Structure, Grid::Ground] {
        let Some(g) = lat.get(grid) else { continue };
        let [y, x] = grid.dims();
        let lats = (0..g.height).map(|j| (g.north - j as f64 * g.dlat).to_bits());
        let lons = (0..g.width).map(|i| (g.west + i as f64 * g.dlon).to_bits());
        for (name, values) in [(y, lats.collect()), (x, lons.collect())] {
            v.push(Coordinate {
                name,
                dtype: Dtype::F64,
                values,
            });
        }
    }
    v
}

/// Every coordinate of a store of the steps `metas` on `lat`, in the store's order.
pub fn coordinates(metas: &[CloudMapMeta], lat: &Lattices) -> Vec<Coordinate> {
    let times: Vec<[u64; 2]> = metas.iter().map(meta_time).collect();
    let mut v: Vec<Coordinate> = TIME_COORDINATES
        .iter()
        .enumerate()
        .map(|(k, &(name, dtype))| Coordinate {
            name,
            dtype,
            values: times.iter().map(|t| t[k]).collect(),
        })
        .collect();
    v.extend(static_coordinates(lat));
    v
}

/// The arrays of a store of `t` steps of the run `reference` on `lat` (coordinates, then the
/// data variables on the lattices it has), in the store's order.
pub fn array_metas(reference: DateTime<Utc>, t: u64, lat: &Lattices) -> Vec<(String, ArrayMeta)> {
    let units = format!("minutes since {}", reference.format("%Y-%m-%d %H:%M:%S"));
    let coord = |name: &str, n: u64, chunk: u64, dtype: Dtype| {
        let a = ArrayMeta {
            shape: vec![n],
            chunks: vec![chunk],
            dtype,
            dims: vec![if name == "forecast_period" {
                "time"
            } else {
                name
            }
            .to_string()],
            attributes: vars::coordinate_attributes(name, &units),
        };
        (name.to_string(), a)
    };
    let mut v: Vec<_> = TIME_COORDINATES
        .iter()
        .map(|&(name, dtype)| coord(name, t, 1, dtype))
        .collect();
    // The static coordinates are one chunk each.
    for c in static_coordinates(lat) {
        let n = c.values.len() as u64;
        v.push(coord(c.name, n, n, c.dtype));
    }
    for var in &VARS {
        let Some(g) = lat.get(var.grid) else {
            continue;
        };
        let [y, x] = var.grid.dims();
        let (mut shape, mut chunks, mut dims) = (vec![t], vec![1], vec!["time"]);
        if var.layered {
            shape.push(3);
            chunks.push(1);
            dims.push("layer");
        }
        shape.extend([g.height as u64, g.width as u64]);
        chunks.extend([CHUNK_SIDE, CHUNK_SIDE]);
        dims.extend([y, x]);
        let mut attributes = vars::attributes(var);
        attributes.insert("grid_mapping_note".into(), json!("EPSG:4326 pixel centres"));
        v.push((
            var.name.to_string(),
            ArrayMeta {
                shape,
                chunks,
                dtype: var.dtype,
                dims: dims.into_iter().map(String::from).collect(),
                attributes,
            },
        ));
    }
    v
}

/// The group's attributes for the steps `metas`: CF run attributes, `history` as given, and
/// the sidecars a reader rebuilds maps from (every step's; the series', where there is one).
pub fn group_attributes(
    series: Option<&SeriesMeta>,
    metas: &[CloudMapMeta],
    history: String,
) -> Map<String, Value> {
    let first = &metas[0];
    let rh_cr: Map<String, Value> = first
        .layers
        .iter()
        .map(|l| (l.kind.name().to_string(), json!(l.rh_cr)))
        .collect();
    let files: Vec<&str> = metas.iter().map(|m| m.source.file.as_str()).collect();
    let region = series.map_or_else(|| json!(first.region), |s| json!(s.region));
    let mut a = match json!({
        "Conventions": "CF-1.10",
        "title": "Stratus CloudMap: cloud cover per layer, cloud structure and ground",
        "institution": "stratus-ingest",
        "source": "NCEP GFS GRIB2 relative humidity (critical-humidity formula)",
        "history": history,
        "stratus_format": STORE_FORMAT,
        "format_version": 1,
        "reference_time": format_time(&run_reference(series, first)),
        "rh_cr": rh_cr,
        "source_files": files,
        "region": region,
        "interpolation": first.interpolation,
        STEPS_ATTR: metas,
    }) {
        Value::Object(a) => a,
        _ => Map::new(),
    };
    if let Some(s) = series {
        a.insert(SERIES_ATTR.into(), json!(s));
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::region::Region;

    #[test]
    fn every_coordinate_has_its_array_in_the_store_order_and_length() {
        let region = Region {
            south: 30.0,
            north: 40.0,
            west: -10.0,
            east: 10.0,
        };
        let lat = Lattices {
            map: StructureGrid::of_map(&region, 8, 4),
            structure: None,
            ground: Some(StructureGrid::of_map(&region, 5, 3)),
        };
        let arrays = array_metas(DateTime::default(), 2, &lat);
        let statics = static_coordinates(&lat);
        let names: Vec<&str> = TIME_COORDINATES
            .iter()
            .map(|c| c.0)
            .chain(statics.iter().map(|c| c.name))
            .collect();
        assert_eq!(
            names,
            [
                "time",
                "forecast_period",
                "layer",
                "lat",
                "lon",
                "ground_lat",
                "ground_lon"
            ]
        );
        for (k, name) in names.iter().enumerate() {
            let (n, meta) = &arrays[k];
            assert_eq!(n, name);
            assert_eq!(meta.dims, [if k < 2 { "time" } else { name }]);
        }
        for (c, (_, meta)) in statics.iter().zip(&arrays[2..]) {
            assert_eq!(
                (meta.shape[0] as usize, meta.dtype),
                (c.values.len(), c.dtype)
            );
        }
        assert_eq!(
            statics[1].values[0],
            38.75f64.to_bits(),
            "the first row's centre"
        );
    }
}
