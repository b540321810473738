//! Writing a series: every step map (`NAME-fHHH.png`, its sidecar and structure images, as a
//! single-file ingest writes them), every step's motion to the next (`NAME-fHHH.motion-u/v.png`,
//! [`super::stored`], estimated from the two step maps just written) and the series sidecar
//! (`NAME.json`) are made in a staging
//! folder beside the output, then renamed into place together, the series sidecar last
//! ([`crate::output::commit_staged`]). An error at any point leaves the folder as it was.

use std::path::{Path, PathBuf};

use crate::cloudmap::{extra_path, load_meta};
use crate::error::{IngestError, Result};
use crate::forecast::{Forecast, LevelSelect};
use crate::ground::image::ground_paths;
use crate::meta::{CloudMapMeta, ExtraRole};
use crate::output::{check_output, commit_staged, ensure_not_input, write_atomic, StagingDir};
use crate::pipeline::{IngestOptions, Plan};

use super::inputs::StepSource;
use super::meta::{
    hour_tag, SeriesLayer, SeriesMeta, SeriesStep, StepMotion, StepWinds, SERIES_FORMAT,
};
use super::stored::motion_paths;
use super::winds::{step_mean_wind, LayerWinds};

/// The step map of `out` (`DIR/NAME.png`) at `hour`: `DIR/NAME-fHHH.png`.
pub fn step_png(out: &Path, hour: f64) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    out.with_file_name(format!("{stem}-{}.png", hour_tag(hour)))
}

/// Every file a series written to `out` may consist of: per step its extra images, ground
/// images (when its forecast has orography), motion images (every step but the last), PNG and
/// sidecar, then the series sidecar (`out` with `.json`), in commit order.
pub fn series_outputs(out: &Path, steps: &[StepSource]) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for (k, s) in steps.iter().enumerate() {
        let png = step_png(out, s.hour);
        v.extend(ExtraRole::ALL.iter().map(|&r| extra_path(&png, r)));
        if k + 1 < steps.len() {
            let (u, mv) = motion_paths(&png);
            v.extend([u, mv]);
        }
        let (surface, water) = ground_paths(&png);
        v.extend([surface, water]);
        v.push(png.clone());
        v.push(png.with_extension("json"));
    }
    v.push(out.with_extension("json"));
    v
}

fn name_of(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Ingest `steps` (from [`super::inputs::series_steps`]) with `opts` into the series `out`
/// (`DIR/NAME.png`: step maps `DIR/NAME-fHHH.png`, series sidecar `DIR/NAME.json`).
/// `progress(step, rows)` reports each step's rows. Returns the series sidecar's path and meta.
pub fn write_series(
    out: &Path,
    steps: &[StepSource],
    select: LevelSelect,
    opts: &IngestOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(PathBuf, SeriesMeta)> {
    let first = steps
        .first()
        .ok_or_else(|| IngestError::BadMap("a series needs at least one step".into()))?;
    let inputs: Vec<&Path> = steps.iter().map(|s| s.path.as_path()).collect();
    let finals = series_outputs(out, steps);
    for f in &finals {
        check_output(f)?;
        ensure_not_input(f, &inputs)?;
    }
    let series_json = out.with_extension("json");
    let stage = StagingDir::create(&series_json)?;
    let staged = |p: &Path| stage.path().join(p.file_name().unwrap_or_default());
    let mut metas: Vec<StepWritten> = Vec::with_capacity(steps.len());
    for (k, s) in steps.iter().enumerate() {
        let step = s.shared_file.then_some(s.hour);
        let fc = Forecast::open_step(&s.path, select, step)?;
        let plan = Plan::new(&fc, opts)?;
        let png = staged(&step_png(out, s.hour));
        let sidecar = plan.write(&png, &|rows| progress(k, rows))?;
        tracing::info!(
            "series step {} of {}: {}",
            k + 1,
            steps.len(),
            png.display()
        );
        metas.push((load_meta(&sidecar)?, s, step_mean_wind(&sidecar)?));
    }
    let motions = write_motions(out, steps, &staged)?;
    let meta = series_meta(&metas, &motions, first)?;
    let json = serde_json::to_vec_pretty(&meta).map_err(|e| IngestError::write(&series_json, e))?;
    write_atomic(&staged(&series_json), |w| {
        use std::io::Write;
        w.write_all(&json).map_err(|e| e.to_string())
    })?;
    // A step without orography wrote no ground images: only those are left out.
    let ground_files: Vec<PathBuf> = steps
        .iter()
        .flat_map(|s| {
            let (a, b) = ground_paths(&step_png(out, s.hour));
            [a, b]
        })
        .collect();
    let moves: Vec<(PathBuf, PathBuf)> = finals
        .iter()
        .filter(|f| !ground_files.contains(f) || staged(f).is_file())
        .map(|f| (staged(f), f.clone()))
        .collect();
    commit_staged(&moves, &series_json)?;
    Ok((series_json, meta))
}

/// The motion from each step to the next, estimated from the step maps staged (decoded once
/// each) and written beside them ([`super::stored`]); `None` for the last step.
fn write_motions(
    out: &Path,
    steps: &[StepSource],
    staged: &dyn Fn(&Path) -> PathBuf,
) -> Result<Vec<Option<StepMotion>>> {
    let load = |s: &StepSource| {
        crate::cloudmap::CloudMap::load(&staged(&step_png(out, s.hour)).with_extension("json"))
    };
    let mut v = Vec::with_capacity(steps.len());
    let mut earlier = match steps.first() {
        Some(s) if steps.len() > 1 => Some(load(s)?),
        _ => None,
    };
    for pair in steps.windows(2) {
        let (a, later) = (earlier.take(), load(&pair[1])?);
        let a = a.ok_or_else(|| IngestError::BadMap("a series step was not loaded".into()))?;
        let t = std::time::Instant::now();
        let interval_s = (pair[1].hour - pair[0].hour) * 3600.0;
        let motion = super::motion::estimate(&a, &later, interval_s)?;
        let (u, mv) = motion_paths(&staged(&step_png(out, pair[0].hour)));
        v.push(Some(super::stored::write(&motion, (&u, &mv))?));
        tracing::info!(
            "series motion {} → {}: estimated in {:.1} s",
            super::meta::show_hour(pair[0].hour),
            super::meta::show_hour(pair[1].hour),
            t.elapsed().as_secs_f64()
        );
        earlier = Some(later);
    }
    v.push(None);
    Ok(v)
}

/// A step map written: its sidecar, its input and its region-mean layer winds.
type StepWritten<'a> = (CloudMapMeta, &'a StepSource, Option<LayerWinds>);

/// The series sidecar of the step maps written, each with its motion to the next.
fn series_meta(
    metas: &[StepWritten],
    motions: &[Option<StepMotion>],
    first: &StepSource,
) -> Result<SeriesMeta> {
    let (m0, _, _) = &metas[0];
    let reference_time = m0
        .source
        .reference_time
        .ok_or_else(|| IngestError::series(&first.path, "has no readable reference time (run)"))?;
    let mut steps = Vec::with_capacity(metas.len());
    for ((m, s, mean_wind), motion) in metas.iter().zip(motions) {
        let kinds = |x: &CloudMapMeta| x.layers.iter().map(|l| l.kind).collect::<Vec<_>>();
        if kinds(m) != kinds(m0) {
            return Err(IngestError::series(
                &s.path,
                format!(
                    "step {} holds other layers than the first step",
                    super::meta::show_hour(s.hour)
                ),
            ));
        }
        let png = m.image.clone();
        let sidecar = Path::new(&png).with_extension("json");
        let winds = match (m.extra(ExtraRole::WindU), m.extra(ExtraRole::WindV)) {
            (Some(u), Some(v)) => Some(StepWinds {
                u: u.image.clone(),
                v: v.image.clone(),
            }),
            _ => None,
        };
        steps.push(SeriesStep {
            forecast_hour: s.hour,
            valid_time: crate::grib::info::after_step(reference_time, s.hour),
            map: name_of(&sidecar),
            winds,
            mean_wind: *mean_wind,
            motion: motion.clone(),
        });
    }
    let meta = SeriesMeta {
        format: SERIES_FORMAT.into(),
        reference_time,
        region: m0.region,
        width: m0.width,
        height: m0.height,
        layers: m0.layers.iter().map(SeriesLayer::from).collect(),
        steps,
    };
    meta.validate()
        .map_err(|e| IngestError::series(&first.path, format!("series sidecar: {e}")))?;
    Ok(meta)
}
