//! A store, a PNG map or a series as plain arrays (name, dimensions, element type, shape,
//! little-endian bytes, attributes) and the group's attributes, which `stratus/__init__.py`
//! turns into an `xarray.Dataset` as `xarray.open_zarr` would.
//!
//! - A store is read as it is on disk: every array's `zarr.json` and chunks (checked by the
//!   ingest crate's own metadata reader, `zarr::array`), after `Store::open` has checked the
//!   store as the command line does.
//! - A PNG map or a series is laid out through the store's own variables table
//!   (`stratus_ingest::zarr::vars`: names, lattices, CF attributes, each plane's samples); the
//!   coordinates and run attributes follow the writer (`zarr::write`), and
//!   tests/python/test_package.py checks that the two agree with a store of the same ingest.

use std::path::Path;

use anyhow::Context;
use serde_json::{json, Map, Value};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::error::shown;
use stratus_ingest::input::read_sidecar_text;
use stratus_ingest::meta::{format_time, CloudMapMeta};
use stratus_ingest::series::{text_is_series, Series, SeriesMeta};
use stratus_ingest::zarr::array::{decode_chunk, ArrayMeta, Dtype};
use stratus_ingest::zarr::read::MAX_CHUNK_BYTES;
use stratus_ingest::zarr::vars::{self, planes, Grid, VARS};
use stratus_ingest::zarr::{self, Store, SERIES_ATTR, STEPS_ATTR, STORE_FORMAT};

/// One array, whole.
pub struct Array {
    pub name: String,
    pub dims: Vec<String>,
    pub dtype: &'static str,
    pub shape: Vec<u64>,
    /// Little-endian elements, row-major.
    pub data: Vec<u8>,
    pub attributes: Map<String, Value>,
}

/// The arrays and the group's attributes.
pub struct Dataset {
    pub attributes: Map<String, Value>,
    pub arrays: Vec<Array>,
}

/// A store (`*.zarr`, or a folder holding `zarr.json`), else a map's or a series' sidecar.
pub fn open(path: &Path) -> anyhow::Result<Dataset> {
    if zarr::is_store(path) {
        return read_store(path);
    }
    let text = read_sidecar_text(path)?;
    if text_is_series(&text) {
        let s = Series::from_text(path, &text)?;
        let maps = (0..s.meta.steps.len())
            .map(|k| s.step_map(k))
            .collect::<Result<Vec<_>, _>>()?;
        let mut series = s.meta.clone();
        // As the store records it: the motion images are not carried (docs/zarr.md).
        for step in &mut series.steps {
            step.motion = None;
        }
        Ok(from_maps(path, &maps, Some(&series)))
    } else {
        let map = CloudMap::load(path)?;
        Ok(from_maps(path, std::slice::from_ref(&map), None))
    }
}

/// The order the writer lays arrays down in (coordinates, then the variables table).
fn rank(name: &str) -> usize {
    const COORDS: [&str; 9] = [
        "time",
        "forecast_period",
        "layer",
        "lat",
        "lon",
        "structure_lat",
        "structure_lon",
        "ground_lat",
        "ground_lon",
    ];
    let vars = VARS.iter().map(|v| v.name);
    COORDS
        .into_iter()
        .chain(vars)
        .position(|n| n == name)
        .unwrap_or(usize::MAX)
}

fn read_json(path: &Path) -> anyhow::Result<Value> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", shown(path)))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", shown(path)))
}

/// Every array of the store at `path`, its time axis as long as the group's step list.
fn read_store(path: &Path) -> anyhow::Result<Dataset> {
    let store = Store::open(path)?;
    let steps = store.steps.len() as u64;
    let group = read_json(&path.join("zarr.json"))?;
    let attributes = group
        .get("attributes")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let mut names = Vec::new();
    let entries =
        std::fs::read_dir(path).with_context(|| format!("{}: cannot read", shown(path)))?;
    for e in entries {
        let e = e.with_context(|| format!("{}: cannot read", shown(path)))?;
        if e.path().join("zarr.json").is_file() {
            names.push(e.file_name().to_string_lossy().into_owned());
        }
    }
    names.sort_by_key(|n| (rank(n), n.clone()));
    let arrays = names
        .iter()
        .map(|n| read_array(&path.join(n), n, steps))
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Dataset { attributes, arrays })
}

/// One array of a store, whole; an array along `time` is read up to `steps`.
fn read_array(dir: &Path, name: &str, steps: u64) -> anyhow::Result<Array> {
    let meta_path = dir.join("zarr.json");
    let mut meta = ArrayMeta::from_json(&read_json(&meta_path)?)
        .map_err(|e| anyhow::anyhow!("{}: {e}", shown(&meta_path)))?;
    if meta.dims.first().map(String::as_str) == Some("time") {
        meta.shape[0] = meta.shape[0].min(steps);
    }
    let size = meta.dtype.size();
    let total: u64 = meta.shape.iter().product();
    let mut data = vec![0u8; total as usize * size];
    let grid: Vec<u64> = meta
        .shape
        .iter()
        .zip(&meta.chunks)
        .map(|(s, c)| s.div_ceil(*c))
        .collect();
    for idx in odometer(&grid) {
        let file = ArrayMeta::chunk_path(dir, &idx);
        let values = read_chunk(&file, &meta)?;
        place(&mut data, &meta, &idx, &values);
    }
    Ok(Array {
        name: name.to_string(),
        dims: meta.dims,
        dtype: meta.dtype.name(),
        shape: meta.shape,
        data,
        attributes: meta.attributes,
    })
}

/// A chunk's elements, or one error naming its file, worded as the store's own reader words
/// it (`zarr::read`), so Python and `stratus` report a damaged store alike.
fn read_chunk(file: &Path, meta: &ArrayMeta) -> anyhow::Result<Vec<u64>> {
    use std::io::Read;
    let fault = |msg: String| anyhow::anyhow!("{}: {msg}", shown(file));
    let f = std::fs::File::open(file).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => fault("chunk missing (the store is not whole)".into()),
        _ => fault(format!("cannot read: {e}")),
    })?;
    let mut bytes = Vec::new();
    f.take(MAX_CHUNK_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| fault(format!("cannot read: {e}")))?;
    if bytes.len() as u64 > MAX_CHUNK_BYTES {
        return Err(fault("damaged chunk: larger than any chunk".into()));
    }
    decode_chunk(&bytes, meta.dtype, meta.chunk_len())
        .map_err(|e| fault(format!("damaged chunk: {e}")))
}

/// Every index of a grid of `counts`, last dimension fastest.
fn odometer(counts: &[u64]) -> Vec<Vec<u64>> {
    let mut all = vec![vec![]];
    for &n in counts {
        all = all
            .into_iter()
            .flat_map(|p| {
                (0..n).map(move |i| {
                    let mut q = p.clone();
                    q.push(i);
                    q
                })
            })
            .collect();
    }
    all
}

/// Copy chunk `idx`'s `values` into the row-major `data` (edge chunks clipped).
fn place(data: &mut [u8], meta: &ArrayMeta, idx: &[u64], values: &[u64]) {
    let size = meta.dtype.size();
    let nd = meta.shape.len();
    let mut strides = vec![1u64; nd];
    for d in (0..nd.saturating_sub(1)).rev() {
        strides[d] = strides[d + 1] * meta.shape[d + 1];
    }
    for (k, &v) in values.iter().enumerate() {
        let mut rest = k as u64;
        let mut flat = 0u64;
        let mut inside = true;
        for d in (0..nd).rev() {
            let local = rest % meta.chunks[d];
            rest /= meta.chunks[d];
            let g = idx[d] * meta.chunks[d] + local;
            inside &= g < meta.shape[d];
            flat += g * strides[d];
        }
        if inside {
            let at = flat as usize * size;
            data[at..at + size].copy_from_slice(&v.to_le_bytes()[..size]);
        }
    }
}

fn array(name: &str, dims: &[&str], dtype: Dtype, shape: Vec<u64>, data: Vec<u8>) -> Array {
    Array {
        name: name.to_string(),
        dims: dims.iter().map(|d| d.to_string()).collect(),
        dtype: dtype.name(),
        shape,
        data,
        attributes: Map::new(),
    }
}

fn f64_bytes(v: impl Iterator<Item = f64>) -> Vec<u8> {
    v.flat_map(f64::to_le_bytes).collect()
}

/// The coordinates of the steps `metas`: time, forecast period, layer and every lattice's.
fn coordinates(metas: &[&CloudMapMeta], units: &str) -> Vec<Array> {
    let t = metas.len() as u64;
    let minutes = metas.iter().flat_map(|m| {
        let reference = m.source.reference_time.unwrap_or_default();
        let valid = m.source.valid_time.unwrap_or(reference);
        (valid - reference)
            .num_seconds()
            .div_euclid(60)
            .to_le_bytes()
    });
    let hours = f64_bytes(metas.iter().map(|m| m.source.forecast_step_h));
    let mut v = vec![
        array("time", &["time"], Dtype::I64, vec![t], minutes.collect()),
        array("forecast_period", &["time"], Dtype::F64, vec![t], hours),
        array("layer", &["layer"], Dtype::U8, vec![3], vec![0, 1, 2]),
    ];
    for grid in [Grid::Map, Grid::Structure, Grid::Ground] {
        let Some(g) = grid.of(metas[0]) else { continue };
        let [lat, lon] = grid.dims();
        let lats = (0..g.height).map(|j| g.north - j as f64 * g.dlat);
        let lons = (0..g.width).map(|i| g.west + i as f64 * g.dlon);
        v.push(array(
            lat,
            &[lat],
            Dtype::F64,
            vec![g.height as u64],
            f64_bytes(lats),
        ));
        v.push(array(
            lon,
            &[lon],
            Dtype::F64,
            vec![g.width as u64],
            f64_bytes(lons),
        ));
    }
    for a in &mut v {
        a.attributes = vars::coordinate_attributes(&a.name, units);
    }
    v
}

/// The steps `maps` (one map, or a series' steps) laid out as the store lays them out.
fn from_maps(path: &Path, maps: &[CloudMap], series: Option<&SeriesMeta>) -> Dataset {
    let metas: Vec<&CloudMapMeta> = maps.iter().map(|m| &m.meta).collect();
    let first = metas[0];
    let reference = series
        .map(|s| s.reference_time)
        .or(first.source.reference_time)
        .unwrap_or_default();
    let units = format!("minutes since {}", reference.format("%Y-%m-%d %H:%M:%S"));
    let mut arrays = coordinates(&metas, &units);
    for v in &VARS {
        let Some(g) = v.grid.of(first) else { continue };
        if v.grid == Grid::Structure && first.extra_images.is_empty() {
            continue;
        }
        let [lat, lon] = v.grid.dims();
        let mut dims = vec!["time"];
        let mut shape = vec![maps.len() as u64];
        if v.layered {
            dims.push("layer");
            shape.push(3);
        }
        dims.extend([lat, lon]);
        shape.extend([g.height as u64, g.width as u64]);
        let plane = g.width as usize * g.height as usize;
        let mut data = Vec::with_capacity(maps.len() * planes(v) * plane * v.dtype.size());
        for map in maps {
            for l in 0..planes(v) {
                let samples = vars::extract(map, v, l).unwrap_or_else(|| vec![0; plane]);
                match v.dtype {
                    Dtype::U8 => data.extend(samples.iter().map(|&s| s as u8)),
                    _ => data.extend(samples.iter().flat_map(|s| s.to_le_bytes())),
                }
            }
        }
        let mut a = array(v.name, &dims, v.dtype, shape, data);
        a.attributes = vars::attributes(v);
        a.attributes
            .insert("grid_mapping_note".into(), json!("EPSG:4326 pixel centres"));
        arrays.push(a);
    }
    Dataset {
        attributes: run_attributes(path, &metas, series, reference),
        arrays,
    }
}

/// The group attributes the writer gives a store of these steps; the step sidecars as the
/// files hold them (a store's name its steps `step-fHHH.png`), the history saying where they
/// were read, and a single map has no series.
fn run_attributes(
    path: &Path,
    metas: &[&CloudMapMeta],
    series: Option<&SeriesMeta>,
    reference: chrono::DateTime<chrono::Utc>,
) -> Map<String, Value> {
    let first = metas[0];
    let rh_cr: Map<String, Value> = first
        .layers
        .iter()
        .map(|l| (l.kind.name().to_string(), json!(l.rh_cr)))
        .collect();
    let files: Vec<&str> = metas.iter().map(|m| m.source.file.as_str()).collect();
    let region = series.map_or_else(|| json!(first.region), |s| json!(s.region));
    let mut a = json!({
        "Conventions": "CF-1.10",
        "title": "Stratus CloudMap: cloud cover per layer, cloud structure and ground",
        "institution": "stratus-ingest",
        "source": "NCEP GFS GRIB2 relative humidity (critical-humidity formula)",
        "history": format!(
            "read from {} by the stratus Python package {}",
            shown(path),
            env!("CARGO_PKG_VERSION")
        ),
        "stratus_format": STORE_FORMAT,
        "format_version": 1,
        "reference_time": format_time(&reference),
        "rh_cr": rh_cr,
        "source_files": files,
        "region": region,
        "interpolation": first.interpolation,
        STEPS_ATTR: metas,
    });
    if let (Some(s), Some(o)) = (series, a.as_object_mut()) {
        o.insert(SERIES_ATTR.into(), json!(s));
    }
    a.as_object().cloned().unwrap_or_default()
}
