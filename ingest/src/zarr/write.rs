//! Writing a store. Each step is ingested as the PNG set would be (`series::write`, into a
//! private staging folder) and that map's samples go into the store, so the store holds the
//! PNG map's values exactly.
//!
//! - [`create`]: the whole store is built inside the staging folder, then renamed into place
//!   under the output's lock ([`crate::output::lock_output`]); an existing store is never
//!   replaced (`--append` adds to one).
//! - [`append`]: under the store's lock, the store is read again, the new steps are checked
//!   against its run, region, size and layers and must come after its last step; then the
//!   new time indices' chunks are written (each file atomically), then every array's
//!   `zarr.json`, the group's last. A reader meanwhile sees the old steps (the group's step
//!   list says how many there are); racing appends run one after the other.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde_json::{json, Value};

use crate::cloudmap::CloudMap;
use crate::error::{shown, Result};
use crate::forecast::LevelSelect;
use crate::lattice::StructureGrid;
use crate::meta::{format_time, CloudMapMeta};
use crate::output::{ensure_not_input, lock_output, write_atomic, StagingDir};
use crate::pipeline::IngestOptions;
use crate::series::inputs::StepSource;
use crate::series::stored::{self, MotionSamples};
use crate::series::write::write_series;
use crate::series::{meta::show_hour, Series, SeriesMeta, SeriesStep};

use super::array::{encode_chunk, ArrayMeta};
use super::layout::{
    array_metas, group_attributes, lattices, meta_time, static_coordinates, Lattices,
    TIME_COORDINATES,
};
use super::motion::{entry, write_interval, MOTION_U};
use super::vars::{self, planes, VARS};
use super::{fault, Store, CHUNK_SIDE};

/// What a write did.
#[derive(Debug, Clone)]
pub struct Written {
    pub path: PathBuf,
    /// The store's series after the write.
    pub series: SeriesMeta,
    /// Steps this write added.
    pub added: usize,
}

/// How a file of the store is put down: straight into the staging folder, or atomically
/// into a live store.
pub(crate) type Put<'a> = &'a (dyn Fn(&Path, &[u8]) -> Result<()> + Sync);

pub(crate) fn put_staged(p: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(d) = p.parent() {
        std::fs::create_dir_all(d).map_err(|e| crate::error::IngestError::write(d, e))?;
    }
    std::fs::write(p, bytes).map_err(|e| crate::error::IngestError::write(p, e))
}

pub(crate) fn put_atomic(p: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(d) = p.parent() {
        std::fs::create_dir_all(d).map_err(|e| crate::error::IngestError::write(d, e))?;
    }
    write_atomic(p, |w| {
        use std::io::Write;
        w.write_all(bytes).map_err(|e| e.to_string())
    })
}

/// Ingest `steps` as PNG sets in a staging folder beside `out`; the series read back.
pub(crate) fn ingest_steps(
    out: &Path,
    steps: &[StepSource],
    select: LevelSelect,
    opts: &IngestOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(StagingDir, Series)> {
    let inputs: Vec<&Path> = steps.iter().map(|s| s.path.as_path()).collect();
    ensure_not_input(out, &inputs)?;
    let stage = StagingDir::create(out)?;
    // One name in every store, whatever the store is called: its steps' sidecars (kept in
    // the group's attributes) name `step-fHHH.png`.
    let png = stage.path().join("step.png");
    let (sidecar, _) = write_series(&png, steps, select, opts, progress)?;
    let series = Series::load(&sidecar)?;
    Ok((stage, series))
}

/// A new store at `out` (which must not exist) holding `steps`.
pub fn create(
    out: &Path,
    steps: &[StepSource],
    select: LevelSelect,
    opts: &IngestOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Written> {
    let exists = |out: &Path| {
        std::fs::symlink_metadata(out).is_ok().then(|| {
            fault(
                out,
                "cannot write: it exists; give --append to add later steps of its run, or remove it first",
            )
        })
    };
    if let Some(e) = exists(out) {
        return Err(e);
    }
    let (stage, series) = ingest_steps(out, steps, select, opts, progress)?;
    if let Some(f) = lattice_fault(&series) {
        return Err(fault(out, format!("cannot write: {f}")));
    }
    let staged = stage.path().join("store.zarr");
    for k in 0..series.meta.steps.len() {
        write_step(&staged, k, &series.step_map(k)?, &put_staged)?;
    }
    let meta = staged_motion(&staged, 0, &series, &put_staged)?;
    write_static_coords(&staged, &Lattices::of(&series.step_metas[0]), &put_staged)?;
    write_metadata(&staged, &meta, &series.step_metas, true, &put_staged)?;
    let _lock = lock_output(out)?;
    if let Some(e) = exists(out) {
        return Err(e);
    }
    std::fs::rename(&staged, out).map_err(|e| crate::error::IngestError::write(out, e))?;
    Ok(Written {
        path: out.to_path_buf(),
        series: meta,
        added: steps.len(),
    })
}

/// Add `steps` (later steps of the store's run, region, size and layers) to the store `out`.
pub fn append(
    out: &Path,
    steps: &[StepSource],
    select: LevelSelect,
    opts: &IngestOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Written> {
    // A store that cannot be opened, or of another region or size, is refused before any work.
    let before = Store::open(out)?;
    if let Some(f) = region_fault(&before.series, opts) {
        return Err(fault(out, format!("cannot append: {f}")));
    }
    let (_stage, new) = ingest_steps(out, steps, select, opts, progress)?;
    let _lock = lock_output(out)?;
    // Read again under the lock: another append may have come first.
    let store = Store::open(out)?;
    if let Some(f) = lattice_fault(&new).or_else(|| append_fault(&store, &new)) {
        return Err(fault(out, format!("cannot append: {f}")));
    }
    let t0 = store.steps.len();
    for k in 0..new.meta.steps.len() {
        write_step(out, t0 + k, &new.step_map(k)?, &put_atomic)?;
    }
    // A store from before the motion arrays gets none: its earlier intervals have none.
    let motion = out.join(MOTION_U).join("zarr.json").is_file();
    let mut series = store.series.clone();
    if motion {
        let joined = join_motion(&store, &new)?;
        write_interval(out, t0 - 1, &joined, &put_atomic)?;
        series.steps[t0 - 1].motion = Some(entry(&joined));
        series
            .steps
            .extend(staged_motion(out, t0, &new, &put_atomic)?.steps);
    } else {
        series
            .steps
            .extend(new.meta.steps.iter().map(|s| SeriesStep {
                motion: None,
                ..s.clone()
            }));
    }
    let mut metas = store.steps.clone();
    metas.extend(new.step_metas.iter().cloned());
    series
        .validate()
        .map_err(|e| fault(out, format!("cannot append: {e}")))?;
    write_metadata(out, &series, &metas, motion, &put_atomic)?;
    Ok(Written {
        path: out.to_path_buf(),
        series,
        added: new.meta.steps.len(),
    })
}

/// Why a store of `s` cannot take maps made with `opts`, if it cannot.
pub(crate) fn region_fault(s: &SeriesMeta, opts: &IngestOptions) -> Option<String> {
    let same_region = serde_json::to_value(s.region).ok() == serde_json::to_value(opts.region).ok();
    (!same_region || s.width != opts.width || s.height != opts.height).then(|| {
        format!(
            "the store holds region {} at {}x{}, not --region {} --size {}x{}; a store is one region and size",
            show_region(&s.region),
            s.width,
            s.height,
            show_region(&opts.region),
            opts.width,
            opts.height
        )
    })
}

fn show_region(r: &crate::region::Region) -> String {
    format!("{},{},{},{}", r.south, r.north, r.west, r.east)
}

/// Why the series `new` cannot be appended to `store`, if it cannot.
fn append_fault(store: &Store, new: &Series) -> Option<String> {
    let (s, n) = (&store.series, &new.meta);
    if s.reference_time != n.reference_time {
        return Some(format!(
            "the store holds the {} run, the input is of the {} run; a store is one run",
            format_time(&s.reference_time),
            format_time(&n.reference_time)
        ));
    }
    if s.layers != n.layers {
        return Some("the input's layers (or their levels) are not the store's".into());
    }
    if lattices(&store.steps[0]) != lattices(&new.step_metas[0]) {
        return Some("the input's structure or ground lattice is not the store's".into());
    }
    let last = s.steps.last()?.forecast_hour;
    let first = n.steps.first()?.forecast_hour;
    (first <= last).then(|| {
        format!(
            "step {} is not after the store's last step {}; append later steps only",
            show_hour(first),
            show_hour(last)
        )
    })
}

/// The first of `series`' steps whose lattices are not the first step's, as a fault.
pub(crate) fn lattice_fault(series: &Series) -> Option<String> {
    let first = lattices(series.step_metas.first()?);
    let (s, _) = series
        .meta
        .steps
        .iter()
        .zip(&series.step_metas)
        .find(|(_, m)| lattices(m) != first)?;
    Some(format!(
        "step {} has another structure or ground lattice than the first step; a store holds one",
        show_hour(s.forecast_hour)
    ))
}

/// The lattice of `g` split into chunk (row, column) indices.
fn chunk_keys(g: &StructureGrid) -> Vec<(usize, usize)> {
    let c = CHUNK_SIDE as usize;
    let (h, w) = (g.height as usize, g.width as usize);
    (0..h.div_ceil(c))
        .flat_map(|y| (0..w.div_ceil(c)).map(move |x| (y, x)))
        .collect()
}

/// Every chunk of step `map` at time index `t`, and its time coordinates.
pub(crate) fn write_step(store: &Path, t: usize, map: &CloudMap, put: Put) -> Result<()> {
    let c = CHUNK_SIDE as usize;
    for v in &VARS {
        let Some(g) = v.grid.of(&map.meta) else {
            continue;
        };
        for l in 0..planes(v) {
            let Some(plane) = vars::extract(map, v, l) else {
                continue;
            };
            let w = g.width as usize;
            chunk_keys(&g).par_iter().try_for_each(|&(y, x)| {
                let mut vals = vec![0u64; c * c];
                for r in 0..c.min(g.height as usize - y * c) {
                    let row = (y * c + r) * w;
                    let n = c.min(w - x * c);
                    for (k, &s) in plane[row + x * c..row + x * c + n].iter().enumerate() {
                        vals[r * c + k] = s as u64;
                    }
                }
                let mut idx = vec![t as u64];
                if v.layered {
                    idx.push(l as u64);
                }
                idx.extend([y as u64, x as u64]);
                let p = ArrayMeta::chunk_path(&store.join(v.name), &idx);
                put(&p, &encode_chunk(&vals, v.dtype))
            })?;
        }
    }
    write_time(store, t, meta_time(&map.meta), put)
}

/// Time index `t`'s coordinates, `values` ([`super::layout::step_time`]).
pub(crate) fn write_time(store: &Path, t: usize, values: [u64; 2], put: Put) -> Result<()> {
    for ((name, dtype), v) in TIME_COORDINATES.into_iter().zip(values) {
        put(
            &ArrayMeta::chunk_path(&store.join(name), &[t as u64]),
            &encode_chunk(&[v], dtype),
        )?;
    }
    Ok(())
}

/// The coordinates that do not grow ([`static_coordinates`]), each one chunk.
pub(crate) fn write_static_coords(store: &Path, lat: &Lattices, put: Put) -> Result<()> {
    for c in static_coordinates(lat) {
        put(
            &ArrayMeta::chunk_path(&store.join(c.name), &[0]),
            &encode_chunk(&c.values, c.dtype),
        )?;
    }
    Ok(())
}

/// The motion `staged` (a series ingested in staging) stores between its steps, written as
/// the store's intervals from `t0` on (its samples exactly: [`stored::read_samples`]); the
/// staged series with each step's motion entry naming the store's arrays.
fn staged_motion(store: &Path, t0: usize, staged: &Series, put: Put) -> Result<SeriesMeta> {
    let dir = staged.path.parent().unwrap_or(Path::new("."));
    let mut meta = staged.meta.clone();
    for (k, step) in meta.steps.iter_mut().enumerate() {
        if let Some(m) = &step.motion {
            let s = stored::read_samples(dir, m).map_err(|e| fault(store, e))?;
            write_interval(store, t0 + k, &s, put)?;
            step.motion = Some(entry(&s));
        }
    }
    Ok(meta)
}

/// The motion from the store's last step to the first of the steps `new` appends,
/// estimated as a series' write estimates it (from the two maps, equal to the PNG maps).
fn join_motion(store: &Store, new: &Series) -> Result<MotionSamples> {
    let t = store.steps.len() - 1;
    let (a, b) = (store.read_step(t)?, new.step_map(0)?);
    let last = store.series.steps[t].forecast_hour;
    let first = new.meta.steps[0].forecast_hour;
    let m = crate::series::motion::estimate(&a, &b, (first - last) * 3600.0)?;
    Ok(stored::samples(&m))
}

/// Every array's `zarr.json` for the steps `metas` (with the motion arrays when `motion`),
/// then the group's (last).
pub(crate) fn write_metadata(
    store: &Path,
    series: &SeriesMeta,
    metas: &[CloudMapMeta],
    motion: bool,
    put: Put,
) -> Result<()> {
    let json_bytes = |v: &Value| serde_json::to_vec_pretty(v).unwrap_or_default();
    let lat = Lattices::of(&metas[0]);
    let mut arrays = array_metas(series.reference_time, metas.len() as u64, &lat);
    if motion {
        let intervals = metas.len().saturating_sub(1) as u64;
        arrays.extend(super::motion::array_metas(
            (series.width, series.height),
            intervals,
        ));
    }
    for (name, a) in arrays {
        put(
            &store.join(name).join("zarr.json"),
            &json_bytes(&a.to_json()),
        )?;
    }
    put(
        &store.join("zarr.json"),
        &json_bytes(&group_json(series, metas)),
    )
}

/// The group's `zarr.json`: the layout's attributes ([`group_attributes`]), written here.
fn group_json(series: &SeriesMeta, metas: &[CloudMapMeta]) -> Value {
    let history = format!("written by stratus-ingest {}", env!("CARGO_PKG_VERSION"));
    json!({
        "zarr_format": 3,
        "node_type": "group",
        "attributes": group_attributes(Some(series), metas, history),
    })
}

/// For messages: a store's steps as people write them.
pub fn describe(w: &Written) -> String {
    format!(
        "{}: {} step(s) ({}), {}x{} px",
        shown(&w.path),
        w.series.steps.len(),
        w.series
            .steps
            .iter()
            .map(|s| show_hour(s.forecast_hour))
            .collect::<Vec<_>>()
            .join(", "),
        w.series.width,
        w.series.height
    )
}
