//! `stratus verify-advection`: how well the layer winds carry the clouds, measured against the
//! forecast itself. The series' step at `--from` is carried forward to `--to` with its own
//! layer winds ([`stratus_ingest::series::advect`]: semi-Lagrangian, 10-minute trajectory
//! sub-steps) and compared with the step at `--to`, per layer, by the Dice coefficient of
//! the masks coverage > 0.5 ([`stratus::score::compare`]); beside it persistence, the earlier
//! step unchanged.

use std::path::PathBuf;
use std::process::ExitCode;

use serde::Serialize;
use stratus::scene::Scene;
use stratus::score::{compare, MAP_THRESHOLD};
use stratus_ingest::cloudmap::{CloudMap, COVERAGE_FULL};
use stratus_ingest::error::shown;
use stratus_ingest::meta::{show_num, LayerKind};
use stratus_ingest::series::advect;
use stratus_ingest::series::meta::show_hour;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Series sidecar (NAME.json) written by `stratus ingest FILE… --out NAME.png`.
    #[arg(long)]
    pub map: PathBuf,
    /// Forecast hour of the step carried forward.
    #[arg(long)]
    pub from: f64,
    /// Forecast hour of the step it is scored against (later than --from).
    #[arg(long)]
    pub to: f64,
    /// Print JSON: {"layers": [{"kind", "advected", "persistence"}]}.
    #[arg(long)]
    pub json: bool,
}

/// One layer's scores; serializes as the JSON prints it.
#[derive(Debug, Serialize)]
struct LayerScore {
    kind: LayerKind,
    advected: f64,
    persistence: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    layers: Vec<LayerScore>,
}

/// Layer channel `c` of `m` thresholded as the score does.
fn mask(m: &CloudMap, c: usize) -> Vec<bool> {
    let t = (MAP_THRESHOLD as f64 * COVERAGE_FULL) as f32;
    m.texels.iter().map(|x| x[c] as f32 > t).collect()
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    for (flag, h) in [("--from", a.from), ("--to", a.to)] {
        if !h.is_finite() {
            anyhow::bail!("{flag} {h}: a forecast hour is a finite number");
        }
    }
    if a.to <= a.from {
        anyhow::bail!(
            "--to {} must be a later forecast hour than --from {}",
            show_num(a.to),
            show_num(a.from)
        );
    }
    let Some(series) = Scene::open(&a.map).into_series()? else {
        anyhow::bail!(
            "{}: not a series sidecar; give the NAME.json `stratus ingest` wrote for several steps",
            shown(&a.map)
        );
    };
    let step = |h: f64| {
        series.step_at_hour(h).ok_or_else(|| {
            anyhow::anyhow!(
                "{}: no step at {}; the series has {}",
                shown(&a.map),
                show_hour(h),
                series.hours_text()
            )
        })
    };
    let (k0, k1) = (step(a.from)?, step(a.to)?);
    let (earlier, later) = (series.step_map(k0)?, series.step_map(k1)?);
    let t = std::time::Instant::now();
    let carried = advect(&earlier, (a.to - a.from) * 3600.0);
    tracing::info!("advection: {:.2} s", t.elapsed().as_secs_f64());
    let layers = later
        .meta
        .layers
        .iter()
        .map(|l| {
            let truth = mask(&later, l.channel);
            LayerScore {
                kind: l.kind,
                advected: compare(&mask(&carried, l.channel), &truth).dice,
                persistence: compare(&mask(&earlier, l.channel), &truth).dice,
            }
        })
        .collect();
    let report = Report { layers };
    if a.json {
        out!("{}", serde_json::to_string_pretty(&report)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    out!(
        "{}: {} carried to {} with its layer winds vs the {} step (Dice, coverage > {})",
        shown(&a.map),
        show_hour(a.from),
        show_hour(a.to),
        show_hour(a.to),
        MAP_THRESHOLD
    )?;
    out!("{:<7} {:>9} {:>12}", "layer", "advected", "persistence")?;
    for l in &report.layers {
        out!(
            "{:<7} {:>9.4} {:>12.4}",
            l.kind.name(),
            l.advected,
            l.persistence
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
