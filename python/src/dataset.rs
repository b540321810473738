//! A store, a PNG map or a series as plain arrays (name, dimensions, element type, shape,
//! little-endian bytes, attributes) and the group's attributes, which `stratus/__init__.py`
//! turns into an `xarray.Dataset` as `xarray.open_zarr` would.
//!
//! - A store is read as it is on disk: every array's `zarr.json` and chunks (checked by the
//!   ingest crate's own metadata reader, `zarr::array`), after `Store::open` has checked the
//!   store as the command line does.
//! - A PNG map or a series is laid out by the store's own layout (`stratus_ingest::zarr::layout`:
//!   arrays, dimensions, coordinates' values, CF and group attributes, as the writer lays them
//!   down) and variables table (`zarr::vars`: each plane's samples);
//!   tests/python/test_package.py checks that the two agree with a store of the same ingest.

use std::path::Path;

use anyhow::Context;
use serde_json::{Map, Value};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::error::shown;
use stratus_ingest::input::read_sidecar_text;
use stratus_ingest::meta::CloudMapMeta;
use stratus_ingest::series::{text_is_series, Series, SeriesMeta};
use stratus_ingest::zarr::array::{decode_chunk, le_bytes, ArrayMeta};
use stratus_ingest::zarr::layout::{self, Lattices};
use stratus_ingest::zarr::read::MAX_CHUNK_BYTES;
use stratus_ingest::zarr::vars::{self, planes, VARS};
use stratus_ingest::zarr::{self, Store};

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
    // In the order the writer lays them down (`zarr::layout`), then the rest (motion) by name.
    let order: Vec<String> = store.steps.first().map_or_else(Vec::new, |first| {
        layout::array_metas(store.series.reference_time, steps, &Lattices::of(first))
            .into_iter()
            .map(|(n, _)| n)
            .collect()
    });
    let rank = |n: &str| order.iter().position(|o| o == n).unwrap_or(usize::MAX);
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

/// The steps `maps` (one map, or a series' steps) laid out as the store lays them out: the
/// ingest crate's own layout (`zarr::layout`), each variable's planes as the writer takes them.
fn from_maps(path: &Path, maps: &[CloudMap], series: Option<&SeriesMeta>) -> Dataset {
    let metas: Vec<CloudMapMeta> = maps.iter().map(|m| m.meta.clone()).collect();
    let lat = Lattices::of(&metas[0]);
    let reference = layout::run_reference(series, &metas[0]);
    let coords = layout::coordinates(&metas, &lat);
    let arrays = layout::array_metas(reference, maps.len() as u64, &lat)
        .into_iter()
        .map(|(name, meta)| {
            let data = match coords.iter().find(|c| c.name == name) {
                Some(c) => le_bytes(&c.values, c.dtype),
                None => variable(maps, &name, &meta),
            };
            Array {
                name,
                dims: meta.dims,
                dtype: meta.dtype.name(),
                shape: meta.shape,
                data,
                attributes: meta.attributes,
            }
        })
        .collect();
    // The step sidecars as the files hold them (a store's name its steps `step-fHHH.png`),
    // the history saying where they were read; a single map has no series.
    let history = format!(
        "read from {} by the stratus Python package {}",
        shown(path),
        env!("CARGO_PKG_VERSION")
    );
    Dataset {
        attributes: layout::group_attributes(series, &metas, history),
        arrays,
    }
}

/// The variable `name` (laid out as `meta`) of every step of `maps`, as its bytes.
fn variable(maps: &[CloudMap], name: &str, meta: &ArrayMeta) -> Vec<u8> {
    let Some(v) = VARS.iter().find(|v| v.name == name) else {
        return Vec::new();
    };
    let plane: u64 = meta.shape.iter().rev().take(2).product();
    let mut samples = Vec::with_capacity(maps.len() * planes(v) * plane as usize);
    for map in maps {
        for l in 0..planes(v) {
            let s = vars::extract(map, v, l).unwrap_or_else(|| vec![0; plane as usize]);
            samples.extend(s.into_iter().map(u64::from));
        }
    }
    le_bytes(&samples, meta.dtype)
}
