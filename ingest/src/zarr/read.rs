//! Reading a store: [`Store::open`] checks the group's metadata (the run, the steps' sidecars)
//! and every array's `zarr.json` against it; [`Store::read_step`] gives a step's CloudMap,
//! [`Store::read_step_near`] the same map with only the chunks a probe at one point reads
//! (the rest zero). Every chunk read is counted ([`Store::stats`]). A missing or damaged
//! chunk, a missing `zarr.json` or metadata that does not agree is one error naming the file.

use std::collections::BTreeMap;
use std::io::Read;
use std::ops::Range;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use rayon::prelude::*;
use serde_json::Value;

use crate::cloudmap::CloudMap;
use crate::error::Result;
use crate::ground::image as ground_image;
use crate::lattice::StructureGrid;
use crate::meta::CloudMapMeta;
use crate::region::Region;
use crate::series::{Series, SeriesMeta, StepLoader};
use crate::structure::MapStructure;

use super::array::{decode_chunk, ArrayMeta};
use super::vars::{ground_channel, planes, Grid, Var, VARS};
use super::{fault, Store, SERIES_ATTR, STEPS_ATTR, STORE_FORMAT};

/// Largest `zarr.json` read (the group's holds every step's sidecar).
pub const MAX_META_BYTES: u64 = 256 << 20;
/// Largest chunk file read: a whole chunk's samples with gzip's worst case, and then some.
pub const MAX_CHUNK_BYTES: u64 = 4 << 20;

/// What reading has cost so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ReadStats {
    pub chunks_read: u64,
    pub bytes_read: u64,
}

/// Rows and columns of a lattice to read.
#[derive(Debug, Clone)]
pub(crate) struct Window {
    rows: Range<usize>,
    cols: Range<usize>,
}

/// Read a JSON file of the store, with a cap.
pub(crate) fn read_json(path: &Path) -> Result<Value> {
    let f = std::fs::File::open(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => fault(path, "missing: the store's metadata is not there"),
        _ => fault(path, format!("cannot read: {e}")),
    })?;
    let mut text = Vec::new();
    f.take(MAX_META_BYTES + 1)
        .read_to_end(&mut text)
        .map_err(|e| fault(path, format!("cannot read: {e}")))?;
    if text.len() as u64 > MAX_META_BYTES {
        return Err(fault(path, "larger than any store metadata"));
    }
    serde_json::from_slice(&text).map_err(|e| fault(path, format!("not valid JSON: {e}")))
}

impl Store {
    /// Open the store at `path`: its group metadata (format, series, every step's sidecar,
    /// each checked as a sidecar is) and every array's metadata (present, this store's
    /// encoding, shapes agreeing with the steps).
    pub fn open(path: &Path) -> Result<Store> {
        if !path.is_dir() {
            return Err(fault(path, "not a Zarr store (no such folder)"));
        }
        let group = read_json(&path.join("zarr.json"))?;
        let at = |msg: String| fault(&path.join("zarr.json"), msg);
        let attrs = group.get("attributes").cloned().unwrap_or(Value::Null);
        if group.get("node_type") != Some(&Value::from("group")) {
            return Err(at("not a Zarr v3 group".into()));
        }
        if attrs.get("stratus_format") != Some(&Value::from(STORE_FORMAT)) {
            return Err(at(format!(
                "not a Stratus store (no {STORE_FORMAT:?} format)"
            )));
        }
        if let Some(p) = attrs.get(super::batch::PLAN_ATTR) {
            let run = p.get("run").and_then(Value::as_str).unwrap_or("?");
            return Err(at(format!(
                "a batch run ({run}) has not finished writing this store (stratus ingest --out STORE --finish --run {run})"
            )));
        }
        let series: SeriesMeta = serde_json::from_value(attrs[SERIES_ATTR].clone())
            .map_err(|e| at(format!("{SERIES_ATTR}: {e}")))?;
        series
            .validate()
            .map_err(|e| at(format!("{SERIES_ATTR}: {e}")))?;
        let steps: Vec<CloudMapMeta> = serde_json::from_value(attrs[STEPS_ATTR].clone())
            .map_err(|e| at(format!("{STEPS_ATTR}: {e}")))?;
        if steps.len() != series.steps.len() {
            return Err(at(format!(
                "{STEPS_ATTR}: {} sidecars for {} steps",
                steps.len(),
                series.steps.len()
            )));
        }
        for (k, (m, s)) in steps.iter().zip(&series.steps).enumerate() {
            m.validate_content()
                .map_err(|e| at(format!("{STEPS_ATTR}[{k}]: {e}")))?;
            if let Some(f) = crate::series::check::step_fault(&series, s, m, steps.first()) {
                return Err(at(format!("{STEPS_ATTR}[{k}]: {f}")));
            }
        }
        let mut arrays = open_arrays(path, &steps)?;
        arrays.extend(super::motion::open_arrays(path, &series)?);
        Ok(Store {
            path: path.to_path_buf(),
            series,
            steps,
            arrays,
            bytes_read: AtomicU64::new(0),
            chunks_read: AtomicU64::new(0),
        })
    }

    /// Chunks and bytes read since the store was opened.
    pub fn stats(&self) -> ReadStats {
        ReadStats {
            chunks_read: self.chunks_read.load(Ordering::Relaxed),
            bytes_read: self.bytes_read.load(Ordering::Relaxed),
        }
    }

    /// Bytes of every file in the store.
    pub fn size_on_disk(&self) -> u64 {
        dir_size(&self.path)
    }

    /// Step `k`'s map, whole: the CloudMap its PNG set gives.
    pub fn read_step(&self, k: usize) -> Result<CloudMap> {
        self.assemble(k, |_| None)
    }

    /// Step `k`'s map with only the chunks that [`CloudMap::probe`] at (`lat`, `lon`) reads
    /// (its bilinear neighbours on each lattice, a pole's whole row near a pole); the other
    /// samples are 0. Its probe there equals the whole map's.
    pub fn read_step_near(&self, k: usize, lat: f64, lon: f64) -> Result<CloudMap> {
        let region = self.series.region;
        self.assemble(k, |g| Some(window(g, &region, lat, lon)))
    }

    /// The store as a [`Series`] whose steps are read from it.
    pub fn into_series(self: Arc<Self>) -> Result<Series> {
        let (store, with_motion) = (Arc::clone(&self), Arc::clone(&self));
        let loader = StepLoader::new(move |k| store.read_step(k))
            .with_motion(move |k| with_motion.read_motion(k));
        Series::with_loader(&self.path, self.series.clone(), self.steps.clone(), loader)
    }

    /// Step `k`'s map from its planes, each read through `win` (None: whole).
    fn assemble(
        &self,
        k: usize,
        win: impl Fn(&StructureGrid) -> Option<Window> + Sync,
    ) -> Result<CloudMap> {
        let meta = self
            .steps
            .get(k)
            .ok_or_else(|| fault(&self.path, format!("no step {k}")))?
            .clone();
        self.assemble_as(k, meta, win)
    }

    /// The map at time index `k` whose sidecar is `meta`, from its planes, each read through
    /// `win` (None: whole).
    pub(crate) fn assemble_as(
        &self,
        k: usize,
        meta: CloudMapMeta,
        win: impl Fn(&StructureGrid) -> Option<Window> + Sync,
    ) -> Result<CloudMap> {
        let plane = |v: &Var, l: usize| -> Result<Option<Vec<u16>>> {
            let Some(g) = v
                .grid
                .of(&meta)
                .filter(|_| self.arrays.contains_key(v.name))
            else {
                return Ok(None);
            };
            self.read_plane(v, k, l, &g, win(&g)).map(Some)
        };
        let mut got: BTreeMap<&str, Vec<Vec<u16>>> = BTreeMap::new();
        for v in &VARS {
            let mut ps = Vec::with_capacity(3);
            for l in 0..planes(v) {
                match plane(v, l)? {
                    Some(p) => ps.push(p),
                    None => break,
                }
            }
            if !ps.is_empty() {
                got.insert(v.name, ps);
            }
        }
        build_map(&self.path, meta, got)
    }

    /// One plane (time `t`, layer `l`) of `v` on grid `g`, the chunks `win` covers read.
    fn read_plane(
        &self,
        v: &Var,
        t: usize,
        l: usize,
        g: &StructureGrid,
        win: Option<Window>,
    ) -> Result<Vec<u16>> {
        let a = &self.arrays[v.name];
        let (w, h) = (g.width as usize, g.height as usize);
        let win = win.unwrap_or(Window {
            rows: 0..h,
            cols: 0..w,
        });
        let (cy, cx) = (
            a.chunks[a.chunks.len() - 2] as usize,
            a.chunks[a.chunks.len() - 1] as usize,
        );
        let mut keys = Vec::new();
        for y in win.rows.start / cy..win.rows.end.div_ceil(cy) {
            for x in win.cols.start / cx..win.cols.end.div_ceil(cx) {
                keys.push((y, x));
            }
        }
        let dir = self.path.join(v.name);
        let chunks: Vec<((usize, usize), Vec<u64>)> = keys
            .par_iter()
            .map(|&(y, x)| {
                let mut idx = vec![t as u64];
                if v.layered {
                    idx.push(l as u64);
                }
                idx.extend([y as u64, x as u64]);
                let p = ArrayMeta::chunk_path(&dir, &idx);
                Ok(((y, x), self.read_chunk(&p, a)?))
            })
            .collect::<Result<_>>()?;
        let mut out = vec![0u16; w * h];
        for ((y, x), vals) in chunks {
            for r in 0..cy.min(h.saturating_sub(y * cy)) {
                let row = y * cy + r;
                let n = cx.min(w.saturating_sub(x * cx));
                for (c, &val) in vals[r * cx..r * cx + n].iter().enumerate() {
                    out[row * w + x * cx + c] = val as u16;
                }
            }
        }
        Ok(out)
    }

    /// One chunk file, decoded; counted.
    pub(crate) fn read_chunk(&self, p: &Path, a: &ArrayMeta) -> Result<Vec<u64>> {
        let f = std::fs::File::open(p).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => fault(p, "chunk missing (the store is not whole)"),
            _ => fault(p, format!("cannot read: {e}")),
        })?;
        let mut bytes = Vec::new();
        f.take(MAX_CHUNK_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| fault(p, format!("cannot read: {e}")))?;
        self.bytes_read
            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
        self.chunks_read.fetch_add(1, Ordering::Relaxed);
        if bytes.len() as u64 > MAX_CHUNK_BYTES {
            return Err(fault(p, "damaged chunk: larger than any chunk"));
        }
        decode_chunk(&bytes, a.dtype, a.chunk_len())
            .map_err(|e| fault(p, format!("damaged chunk: {e}")))
    }
}

/// The rows and columns of `g` a probe at (`lat`, `lon`) reads: the bilinear neighbours and
/// the nearest pixel, one more each side; near a pole the region reaches, the whole pole row.
fn window(g: &StructureGrid, region: &Region, lat: f64, lon: f64) -> Window {
    let (w, h) = (g.width as usize, g.height as usize);
    let (x, y) = (g.x(region, lon), g.y(lat));
    let around = |v: f64, n: usize| {
        let i = v.max(0.0).floor() as usize;
        i.saturating_sub(1)..(i + 3).min(n)
    };
    let cols = match g.pole_weight(region, lat) {
        Some(_) => 0..w,
        None => around(x, w),
    };
    Window {
        rows: around(y, h),
        cols,
    }
}

/// Every array's metadata, present and agreeing with the steps.
pub(crate) fn open_arrays(
    path: &Path,
    steps: &[CloudMapMeta],
) -> Result<BTreeMap<String, ArrayMeta>> {
    let first = &steps[0];
    let mut arrays = BTreeMap::new();
    for v in &VARS {
        let Some(g) = v.grid.of(first) else { continue };
        if v.grid == Grid::Structure && first.extra_images.is_empty() {
            continue;
        }
        let p = path.join(v.name).join("zarr.json");
        let a = ArrayMeta::from_json(&read_json(&p)?).map_err(|e| fault(&p, e))?;
        let mut want = vec![steps.len() as u64];
        if v.layered {
            want.push(3);
        }
        want.extend([g.height as u64, g.width as u64]);
        // The time axis may be longer: an append cut short after its chunks.
        if a.shape.len() != want.len() || a.shape[0] < want[0] || a.shape[1..] != want[1..] {
            return Err(fault(
                &p,
                format!("shape {:?} is not the steps' {want:?}", a.shape),
            ));
        }
        if a.dtype != v.dtype || a.chunks[..a.chunks.len() - 2].iter().any(|&c| c != 1) {
            return Err(fault(&p, "not this store's data type or chunking"));
        }
        arrays.insert(v.name.to_string(), a);
    }
    Ok(arrays)
}

/// The CloudMap of `meta` from its planes by variable name.
fn build_map(
    store: &Path,
    meta: CloudMapMeta,
    got: BTreeMap<&str, Vec<Vec<u16>>>,
) -> Result<CloudMap> {
    let p = |name: &str, l: usize| got.get(name).and_then(|v| v.get(l));
    let missing = |name: &str| fault(&store.join(name), "missing: the store is not whole");
    let cov = got.get("coverage").ok_or_else(|| missing("coverage"))?;
    let total = p("total_coverage", 0).ok_or_else(|| missing("total_coverage"))?;
    let texels = (0..total.len())
        .map(|k| [cov[0][k], cov[1][k], cov[2][k], total[k]])
        .collect();
    let structure = match (meta.extra_images.is_empty(), meta.structure_grid) {
        (false, Some(grid)) => Some(build_structure(store, grid, &got)?),
        _ => None,
    };
    let ground = match &meta.ground {
        Some(gm) => {
            let (mut surface, mut water) = (Vec::new(), Vec::new());
            let n = gm.grid.width as usize * gm.grid.height as usize;
            for k in 0..n {
                for name in [
                    "surface_altitude",
                    "land_area_fraction",
                    "sea_ice_area_fraction",
                    "surface_albedo",
                    "surface_snow_amount",
                    "cloud_condensed_water_content",
                ] {
                    let v = p(name, 0).ok_or_else(|| missing(name))?[k];
                    let into = if ground_channel(name).0 {
                        &mut water
                    } else {
                        &mut surface
                    };
                    into.extend_from_slice(&v.to_be_bytes());
                }
            }
            let g = ground_image::decode(gm.grid, meta.region, gm.fields.clone(), &surface, &water)
                .map_err(|(_, e)| fault(&store.join("surface_altitude"), e))?;
            Some(g)
        }
        None => None,
    };
    Ok(CloudMap {
        meta,
        texels,
        structure,
        ground,
    })
}

/// The structure images from their planes.
fn build_structure(
    store: &Path,
    grid: StructureGrid,
    got: &BTreeMap<&str, Vec<Vec<u16>>>,
) -> Result<MapStructure> {
    let get = |name: &str| {
        got.get(name)
            .ok_or_else(|| fault(&store.join(name), "missing: the store is not whole"))
    };
    let (base, top, cb, ct) = (
        get("cloud_base")?,
        get("cloud_top")?,
        &get("convective_cloud_base")?[0],
        &get("convective_cloud_top")?[0],
    );
    let (ty, src, u, v) = (
        get("cloud_type")?,
        get("cloud_base_source")?,
        get("eastward_wind")?,
        get("northward_wind")?,
    );
    let n = grid.width as usize * grid.height as usize;
    let s = MapStructure {
        grid,
        base: (0..n)
            .map(|k| [base[0][k], base[1][k], base[2][k], cb[k]])
            .collect(),
        top: (0..n)
            .map(|k| [top[0][k], top[1][k], top[2][k], ct[k]])
            .collect(),
        types: (0..n)
            .map(|k| {
                let packed = (0..3).map(|l| (src[l][k].min(3) as u8) << (2 * l)).sum();
                [
                    ty[0][k].min(255) as u8,
                    ty[1][k].min(255) as u8,
                    ty[2][k].min(255) as u8,
                    packed,
                ]
            })
            .collect(),
        wind_u: (0..n).map(|k| [u[0][k], u[1][k], u[2][k]]).collect(),
        wind_v: (0..n).map(|k| [v[0][k], v[1][k], v[2][k]]).collect(),
    };
    if let Some((k, what)) = s.first_bad_type() {
        let w = grid.width as usize;
        return Err(fault(
            &store.join("cloud_type"),
            format!("pixel ({}, {}): {what}", k % w, k / w),
        ));
    }
    if let Some(k) = (0..n).find(|&k| (0..3).any(|l| src[l][k] > 3)) {
        return Err(fault(
            &store.join("cloud_base_source"),
            format!("pixel {k}: a code beyond 3"),
        ));
    }
    Ok(s)
}

/// Bytes of the files under `dir` (links not followed).
fn dir_size(dir: &Path) -> u64 {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return 0;
    };
    rd.flatten()
        .map(|e| match e.file_type() {
            Ok(t) if t.is_dir() => dir_size(&e.path()),
            Ok(t) if t.is_file() => e.metadata().map_or(0, |m| m.len()),
            _ => 0,
        })
        .sum()
}
