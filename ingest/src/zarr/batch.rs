//! A store written by many processes (a Dask cluster: `python -m stratus.batch`, docs/zarr.md
//! "Batch"), in four calls of `stratus ingest`, each a function here:
//!
//! 1. [`plan`] (`--plan`): from the files' headers only, every array's `zarr.json` for all the
//!    planned steps (time axis, lattices, motion intervals), the coordinates, and the group with
//!    the plan (`stratus_plan`), renamed into place; the run's folder `.STORE.zarr.batch/`
//!    created beside the store with `mkdir` (exclusive: a second run on the store is refused
//!    there) holding the run's id (`run`).
//! 2. [`step`] (`--step K`): step K ingested in staging, its chunks written into the store
//!    (time index K only, each file atomically), then its record `step-K.json` (its sidecar and
//!    series entry) in the run's folder.
//! 3. [`motion`] (`--motion K`): the motion from step K to K + 1, estimated from the two steps
//!    read back from the store, its chunks (interval K) and record `motion-K.json`.
//! 4. [`finish`] (`--finish`): every record read, the group's attributes written as a serial
//!    run writes them (the series, every step's sidecar), the run's folder removed.
//!
//! Every call names the run (`--run ID`) and is refused unless the run's folder holds that id,
//! so two runs never write one store. A call that is refused writes nothing; a call repeated
//! (a task retried) writes the same chunks again.

use std::path::{Path, PathBuf};

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use crate::cloudmap::CloudMap;
use crate::error::{shown, IngestError, Result};
use crate::forecast::LevelSelect;
use crate::grib::{self, SurfaceType};
use crate::lattice::{structure_grid, StructureGrid};
use crate::meta::{format_time, CloudMapMeta};
use crate::output::{ensure_not_input, lock_output, write_atomic, StagingDir};
use crate::pipeline::IngestOptions;
use crate::region::Region;
use crate::series::inputs::{InputFile, StepSource};
use crate::series::meta::{show_hour, SeriesLayer, StepMotion};
use crate::series::{stored, SeriesMeta, SeriesStep, SERIES_FORMAT};

use super::layout::{array_metas, step_time, Lattices};
use super::motion::{entry, write_interval};
use super::read::read_json;
use super::write::{
    ingest_steps, lattice_fault, put_atomic, put_staged, write_metadata, write_static_coords,
    write_step, write_time, Written,
};
use super::{fault, Store, STORE_FORMAT};

/// Group attribute of a planned store whose batch run has not finished.
pub const PLAN_ATTR: &str = "stratus_plan";

/// What a batch run planned: recorded in the group (`stratus_plan`) when the store is
/// created, checked by every later call.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    pub run: String,
    #[serde(with = "crate::series::meta::time_text")]
    pub reference_time: DateTime<Utc>,
    pub region: Region,
    pub width: u32,
    pub height: u32,
    /// Forecast hours of the steps, time index order.
    pub hours: Vec<f64>,
    pub structure_grid: Option<StructureGrid>,
    pub ground_grid: Option<StructureGrid>,
}

/// The run's folder beside the store: `.NAME.zarr.batch`.
pub fn run_dir(out: &Path) -> PathBuf {
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    out.with_file_name(format!(".{name}.batch"))
}

fn step_record(out: &Path, k: usize) -> PathBuf {
    run_dir(out).join(format!("step-{k}.json"))
}

fn motion_record(out: &Path, k: usize) -> PathBuf {
    run_dir(out).join(format!("motion-{k}.json"))
}

/// Removes the run's folder it made unless the plan succeeded.
struct RunGuard(Option<PathBuf>);

impl Drop for RunGuard {
    fn drop(&mut self) {
        if let Some(d) = self.0.take() {
            let _ = std::fs::remove_dir_all(d);
        }
    }
}

/// The run's folder, created exclusively, holding `run`; refused when another run has one.
fn claim(out: &Path, run: &str) -> Result<RunGuard> {
    let dir = run_dir(out);
    if let Err(e) = std::fs::create_dir(&dir) {
        let holder = std::fs::read_to_string(dir.join("run")).unwrap_or_default();
        return Err(match e.kind() {
            std::io::ErrorKind::AlreadyExists => fault(
                &dir,
                format!(
                    "another batch run ({}) is writing {}; if none is, remove this folder and the store",
                    holder.trim(),
                    shown(out)
                ),
            ),
            _ => IngestError::write(&dir, e),
        });
    }
    let guard = RunGuard(Some(dir.clone()));
    let p = dir.join("run");
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&p)
        .and_then(|mut f| std::io::Write::write_all(&mut f, run.as_bytes()))
        .map_err(|e| IngestError::write(&p, e))?;
    Ok(guard)
}

/// Whether the first step's file has the orography that gives a map its ground (the test
/// `GroundInputs::load` makes: on the RH grid, every point finite).
fn has_ground(path: &Path, grid: &grib::LatLonGrid) -> Result<bool> {
    let bytes = crate::input::read_grib(path)?;
    let msgs = grib::scan(&bytes).map_err(|e| IngestError::Grib {
        path: path.to_path_buf(),
        msg: e.to_string(),
    })?;
    let Some(m) = msgs
        .iter()
        .find(|m| m.parameter() == (0, 3, 5) && m.level_type == Some(SurfaceType::Surface))
    else {
        return Ok(false);
    };
    if m.grid.as_ref() != Some(grid) {
        return Ok(false);
    }
    Ok(grib::decode_values(&bytes, m).is_ok_and(|f| {
        f.values.len() == grid.ni * grid.nj && f.values.iter().all(|v| v.is_finite())
    }))
}

/// Create the store `out` (which must not exist) for `steps` (of the surveyed `files`),
/// from headers only, and claim it for the batch run `run`.
pub fn plan(
    out: &Path,
    files: &[InputFile],
    steps: &[StepSource],
    opts: &IngestOptions,
    run: &str,
) -> Result<Plan> {
    let inputs: Vec<&Path> = steps.iter().map(|s| s.path.as_path()).collect();
    ensure_not_input(out, &inputs)?;
    opts.region.validate()?;
    crate::region::check_size(opts.width, opts.height)?;
    let first = files
        .first()
        .ok_or_else(|| IngestError::BadMap("a store needs at least one step".into()))?;
    let g = &first.grid;
    let lattice = structure_grid(
        (opts.width, opts.height),
        &opts.region,
        (g.north(), g.west()),
        (g.di, g.dj),
    );
    let ground = has_ground(&first.path, g)?.then_some(lattice);
    let plan = Plan {
        run: run.to_string(),
        reference_time: first.reference_time,
        region: opts.region,
        width: opts.width,
        height: opts.height,
        hours: steps.iter().map(|s| s.hour).collect(),
        structure_grid: Some(lattice),
        ground_grid: ground,
    };
    let mut guard = claim(out, run)?;
    let exists = || {
        std::fs::symlink_metadata(out).is_ok().then(|| {
            fault(
                out,
                "cannot plan a batch run: it exists; a batch run writes a new store",
            )
        })
    };
    if let Some(e) = exists() {
        return Err(e);
    }
    let stage = StagingDir::create(out)?;
    let staged = stage.path().join("store.zarr");
    write_skeleton(&staged, &plan, steps)?;
    let _lock = lock_output(out)?;
    if let Some(e) = exists() {
        return Err(e);
    }
    std::fs::rename(&staged, out).map_err(|e| IngestError::write(out, e))?;
    guard.0 = None;
    Ok(plan)
}

/// The planned store's metadata, coordinates and group in `staged`.
fn write_skeleton(staged: &Path, plan: &Plan, steps: &[StepSource]) -> Result<()> {
    let lat = Lattices {
        map: StructureGrid::of_map(&plan.region, plan.width, plan.height),
        structure: plan.structure_grid,
        ground: plan.ground_grid,
    };
    let t = plan.hours.len() as u64;
    let mut arrays = array_metas(plan.reference_time, t, &lat);
    arrays.extend(super::motion::array_metas(
        (plan.width, plan.height),
        t.saturating_sub(1),
    ));
    let json_bytes = |v: &Value| serde_json::to_vec_pretty(v).unwrap_or_default();
    for (name, a) in arrays {
        put_staged(
            &staged.join(name).join("zarr.json"),
            &json_bytes(&a.to_json()),
        )?;
    }
    write_static_coords(staged, &lat, &put_staged)?;
    for (k, &h) in plan.hours.iter().enumerate() {
        let valid = crate::grib::info::after_step(plan.reference_time, h);
        let values = step_time((plan.reference_time, valid), h);
        write_time(staged, k, values, &put_staged)?;
    }
    let files: Vec<String> = steps.iter().map(|s| shown(&s.path).to_string()).collect();
    let group = json!({
        "zarr_format": 3,
        "node_type": "group",
        "attributes": {
            "Conventions": "CF-1.10",
            "title": "Stratus CloudMap (a batch run in progress: its steps are being written)",
            "stratus_format": STORE_FORMAT,
            "format_version": 1,
            "reference_time": format_time(&plan.reference_time),
            "region": plan.region,
            "source_files": files,
            PLAN_ATTR: plan,
        }
    });
    put_staged(&staged.join("zarr.json"), &json_bytes(&group))
}

/// The plan of the store `out` that the run `run` is writing; refused when it is not.
pub fn open_plan(out: &Path, run: &str) -> Result<Plan> {
    let group_path = out.join("zarr.json");
    let group = read_json(&group_path)?;
    let plan: Plan = match group.pointer(&format!("/attributes/{PLAN_ATTR}")) {
        Some(p) => serde_json::from_value(p.clone())
            .map_err(|e| fault(&group_path, format!("{PLAN_ATTR}: {e}")))?,
        None => {
            return Err(fault(
                out,
                "has no batch plan (a finished store, or not planned with --plan); a batch run writes a new store",
            ))
        }
    };
    let id_path = run_dir(out).join("run");
    let holder = std::fs::read_to_string(&id_path).map_err(|e| {
        fault(
            &id_path,
            format!("cannot read the batch run's id ({e}); the run was given up or finished"),
        )
    })?;
    if holder.trim() != run || plan.run != run {
        return Err(fault(
            &id_path,
            format!(
                "the store is being written by batch run {}, not {run}",
                holder.trim()
            ),
        ));
    }
    Ok(plan)
}

/// Why the inputs `steps` (ingested with `opts`) are not the plan's, if they are not.
fn plan_fault(
    p: &Plan,
    files: &[InputFile],
    steps: &[StepSource],
    opts: &IngestOptions,
) -> Option<String> {
    let same_region = serde_json::to_value(p.region).ok() == serde_json::to_value(opts.region).ok();
    if !same_region || (p.width, p.height) != (opts.width, opts.height) {
        return Some(format!(
            "the plan is region {},{},{},{} at {}x{}, not --region/--size of this call",
            p.region.south, p.region.north, p.region.west, p.region.east, p.width, p.height
        ));
    }
    if files.first().map(|f| f.reference_time) != Some(p.reference_time) {
        return Some(format!(
            "the plan is the {} run; the input files are not",
            format_time(&p.reference_time)
        ));
    }
    let hours: Vec<f64> = steps.iter().map(|s| s.hour).collect();
    (hours != p.hours).then(|| {
        format!(
            "the input files' steps ({}) are not the plan's ({})",
            hours
                .iter()
                .map(|&h| show_hour(h))
                .collect::<Vec<_>>()
                .join(", "),
            p.hours
                .iter()
                .map(|&h| show_hour(h))
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

/// What a step's task records for [`finish`]: its series entry and map sidecar.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct StepRecord {
    step: SeriesStep,
    meta: CloudMapMeta,
}

/// Write step `k` of the plan (the inputs `files`, `steps` as given to [`plan`]) into `out`.
#[allow(clippy::too_many_arguments)]
pub fn step(
    out: &Path,
    k: usize,
    files: &[InputFile],
    steps: &[StepSource],
    select: LevelSelect,
    opts: &IngestOptions,
    run: &str,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<SeriesStep> {
    let p = open_plan(out, run)?;
    if let Some(f) = plan_fault(&p, files, steps, opts) {
        return Err(fault(out, format!("cannot write step {k}: {f}")));
    }
    let src = steps.get(k).ok_or_else(|| {
        fault(
            out,
            format!(
                "step {k} is outside the plan's steps 0..{}",
                p.hours.len() - 1
            ),
        )
    })?;
    let (_stage, series) = ingest_steps(out, std::slice::from_ref(src), select, opts, progress)?;
    let meta = series
        .step_metas
        .first()
        .ok_or_else(|| fault(out, "the step was not ingested"))?;
    let planned = (p.structure_grid, p.ground_grid);
    let lat = Lattices::of(meta);
    if (lat.structure, lat.ground) != planned {
        return Err(fault(
            out,
            format!(
                "step {}: its structure or ground lattice is not the one planned from the headers",
                show_hour(src.hour)
            ),
        ));
    }
    write_step(out, k, &series.step_map(0)?, &in_store(out))?;
    let rec = StepRecord {
        step: series.meta.steps[0].clone(),
        meta: meta.clone(),
    };
    let bytes = serde_json::to_vec_pretty(&rec).map_err(|e| IngestError::write(out, e))?;
    put_record(&step_record(out, k), &bytes)?;
    Ok(rec.step)
}

/// A chunk into the store `out`, atomically, while the store is there: a call still running
/// when its run was given up (and the store removed) does not make a partial store again.
fn in_store(out: &Path) -> impl Fn(&Path, &[u8]) -> Result<()> + Sync + '_ {
    move |p, bytes| {
        if !out.join("zarr.json").is_file() {
            return Err(fault(
                out,
                "the store was removed while this call wrote it (its batch run was given up)",
            ));
        }
        put_atomic(p, bytes)
    }
}

/// A record into the run's folder, atomically; never creating the folder, so that a call
/// outliving its run (its worker killed, the task retried and the run finished) leaves no
/// stale run behind.
fn put_record(p: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(p, |w| {
        use std::io::Write;
        w.write_all(bytes).map_err(|e| e.to_string())
    })
}

/// Step `k`'s record, written by [`step`]; missing: the step is not written yet.
fn read_step_record(out: &Path, k: usize) -> Result<StepRecord> {
    let p = step_record(out, k);
    if !p.is_file() {
        return Err(fault(
            &p,
            format!("missing: step {k} is not written yet (stratus ingest … --step {k})"),
        ));
    }
    serde_json::from_value(read_json(&p)?).map_err(|e| fault(&p, format!("not a step record: {e}")))
}

/// The series of the plan `p` with the steps `recs` (its layers are the first step's).
fn series_of(p: &Plan, recs: &[&StepRecord]) -> SeriesMeta {
    let layers = recs.first().map_or_else(Vec::new, |r| {
        r.meta.layers.iter().map(SeriesLayer::from).collect()
    });
    SeriesMeta {
        format: SERIES_FORMAT.into(),
        reference_time: p.reference_time,
        region: p.region,
        width: p.width,
        height: p.height,
        layers,
        steps: recs.iter().map(|r| r.step.clone()).collect(),
    }
}

/// Write the motion from step `k` to `k + 1` (both written) into the planned store `out`.
pub fn motion(out: &Path, k: usize, run: &str) -> Result<StepMotion> {
    let p = open_plan(out, run)?;
    if k + 1 >= p.hours.len() {
        return Err(fault(
            out,
            format!(
                "interval {k} is outside the plan's intervals 0..{} (between its {} steps)",
                p.hours.len().saturating_sub(2),
                p.hours.len()
            ),
        ));
    }
    let (a, b) = (read_step_record(out, k)?, read_step_record(out, k + 1)?);
    let maps = maps_of(out, &p, [(k, &a), (k + 1, &b)])?;
    let interval_s = (p.hours[k + 1] - p.hours[k]) * 3600.0;
    let m = crate::series::motion::estimate(&maps[0], &maps[1], interval_s)?;
    let s = stored::samples(&m);
    write_interval(out, k, &s, &in_store(out))?;
    let e = entry(&s);
    let bytes = serde_json::to_vec_pretty(&e).map_err(|e| IngestError::write(out, e))?;
    put_record(&motion_record(out, k), &bytes)?;
    Ok(e)
}

/// The maps of two written steps (time index, record), read back from the store.
fn maps_of(out: &Path, p: &Plan, at: [(usize, &StepRecord); 2]) -> Result<Vec<CloudMap>> {
    let metas = vec![at[0].1.meta.clone()];
    let store = Store {
        path: out.to_path_buf(),
        series: series_of(p, &[at[0].1, at[1].1]),
        steps: Vec::new(),
        arrays: super::read::open_arrays(out, &metas)?,
        bytes_read: Default::default(),
        chunks_read: Default::default(),
    };
    at.iter()
        .map(|(t, r)| store.assemble_as(*t, r.meta.clone(), |_| None))
        .collect()
}

/// Finish the batch run `run` on `out`: every step and interval written, the group's
/// attributes as a serial run writes them, the run's folder removed.
pub fn finish(out: &Path, run: &str) -> Result<Written> {
    let p = open_plan(out, run)?;
    let n = p.hours.len();
    let recs = (0..n)
        .map(|k| read_step_record(out, k))
        .collect::<Result<Vec<_>>>()?;
    let mut series = series_of(&p, &recs.iter().collect::<Vec<_>>());
    for k in 0..n.saturating_sub(1) {
        let path = motion_record(out, k);
        if !path.is_file() {
            return Err(fault(
                &path,
                format!("missing: interval {k} is not written yet (stratus ingest … --motion {k})"),
            ));
        }
        let m: StepMotion = serde_json::from_value(read_json(&path)?)
            .map_err(|e| fault(&path, format!("not a motion record: {e}")))?;
        series.steps[k].motion = Some(m);
    }
    let metas: Vec<CloudMapMeta> = recs.into_iter().map(|r| r.meta).collect();
    series
        .validate()
        .map_err(|e| fault(out, format!("cannot finish: {e}")))?;
    let as_series = crate::series::Series {
        path: out.to_path_buf(),
        meta: series.clone(),
        step_metas: metas.clone(),
        loader: None,
    };
    if let Some(f) = lattice_fault(&as_series) {
        return Err(fault(out, format!("cannot finish: {f}")));
    }
    {
        let _lock = lock_output(out)?;
        write_metadata(out, &series, &metas, true, &put_atomic)?;
    }
    let _ = std::fs::remove_dir_all(run_dir(out));
    Ok(Written {
        path: out.to_path_buf(),
        series,
        added: n,
    })
}
