//! `stratus verify-interpolation`: how well the blend between two forecast steps stands in for
//! the step between them. The series' step at `--hold` (a forecast hour, as `verify-advection`
//! names steps) is left out; the steps either side of it are blended at its valid time three
//! ways — along the motion estimated between them (`motion`,
//! [`stratus_ingest::series::motion`]), the plain cross-fade (`crossfade`), and today's wind
//! advection ([`stratus_ingest::series::blend`], `wind`) — and each is compared with the held
//! step per layer by the Dice coefficient of the masks coverage > 0.5
//! ([`stratus::score::compare`]).

use std::path::PathBuf;
use std::process::ExitCode;

use serde::Serialize;
use stratus::score::{compare, MAP_THRESHOLD};
use stratus_ingest::cloudmap::{CloudMap, COVERAGE_FULL};
use stratus_ingest::error::shown;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::series::meta::show_hour;
use stratus_ingest::series::{blend, motion, Series};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Series sidecar (NAME.json) written by `stratus ingest FILE… --out NAME.png`.
    #[arg(long)]
    pub map: PathBuf,
    /// Forecast hour of the step left out and rebuilt from the steps either side of it (as
    /// `verify-advection --from/--to` name steps: `--hold 6` is the +6 h step). Not the first
    /// or last step.
    #[arg(long)]
    pub hold: f64,
    /// Print JSON: {"hold": H, "layers": [{"kind", "motion", "crossfade", "wind"}]}.
    #[arg(long)]
    pub json: bool,
}

/// One layer's scores; serializes as the JSON prints it.
#[derive(Debug, Serialize)]
struct LayerScore {
    kind: LayerKind,
    motion: f64,
    crossfade: f64,
    wind: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    hold: f64,
    layers: Vec<LayerScore>,
}

/// Layer channel `c` of `m` thresholded as the score does.
fn mask(m: &CloudMap, c: usize) -> Vec<bool> {
    let t = (MAP_THRESHOLD as f64 * COVERAGE_FULL) as f32;
    m.texels.iter().map(|x| x[c] as f32 > t).collect()
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (series, k) = held_step(&a)?;
    let steps = series.steps();
    let (t0, t, t1) = (
        steps[k - 1].valid_time,
        steps[k].valid_time,
        steps[k + 1].valid_time,
    );
    let interval = (t1 - t0).num_milliseconds() as f64 / 1000.0;
    let w = (t - t0).num_milliseconds() as f64 / 1000.0 / interval;
    let (before, held, after) = (
        series.step_map(k - 1)?,
        series.step_map(k)?,
        series.step_map(k + 1)?,
    );
    let report = Report {
        hold: a.hold,
        layers: scores(&before, &held, &after, w, interval)?,
    };
    if a.json {
        out!("{}", serde_json::to_string_pretty(&report)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    print_table(&a, &series, k, &report)
}

/// The series and the index of the step `--hold` names, refused (one line) where it is no
/// step, or the first or the last.
fn held_step(a: &Args) -> anyhow::Result<(Series, usize)> {
    if !a.hold.is_finite() {
        anyhow::bail!("--hold {}: a forecast hour is a finite number", a.hold);
    }
    if !stratus_ingest::series::sidecar_is_series(&a.map)? {
        anyhow::bail!(
            "{}: not a series sidecar; give the NAME.json `stratus ingest` wrote for several steps",
            shown(&a.map)
        );
    }
    let series = Series::load(&a.map)?;
    let k = series.step_at_hour(a.hold).ok_or_else(|| {
        anyhow::anyhow!(
            "{}: no step at {}; the series has {}",
            shown(&a.map),
            show_hour(a.hold),
            series.hours_text()
        )
    })?;
    let steps = series.steps();
    if k == 0 || k + 1 == steps.len() {
        anyhow::bail!(
            "{}: {} is the series' {} step; --hold takes a step with a step either side ({})",
            shown(&a.map),
            show_hour(a.hold),
            if k == 0 { "first" } else { "last" },
            series.hours_text()
        );
    }
    Ok((series, k))
}

/// The three blends of `before` and `after` at `w`, each scored against `held` per layer.
fn scores(
    before: &CloudMap,
    held: &CloudMap,
    after: &CloudMap,
    w: f64,
    interval: f64,
) -> anyhow::Result<Vec<LayerScore>> {
    let clock = std::time::Instant::now();
    let m = motion::estimate(before, after, interval)?;
    tracing::info!("motion estimate: {:.2} s", clock.elapsed().as_secs_f64());
    for l in &m.layers {
        let (dx, dy, g) = l.summary();
        tracing::info!(
            "{}: mean guarded motion ({dx:.1}, {dy:.1}) px east, south over the interval; mean guard {g:.2}",
            l.kind.name()
        );
    }
    let moved = motion::blend(before, after, w, interval, &m)?;
    let faded = motion::crossfade(before, after, w, interval)?;
    let carried = blend(before, after, w, interval)?;
    let layers: Vec<LayerScore> = held
        .meta
        .layers
        .iter()
        .map(|l| {
            let truth = mask(held, l.channel);
            let dice = |x: &CloudMap| compare(&mask(x, l.channel), &truth).dice;
            LayerScore {
                kind: l.kind,
                motion: dice(&moved),
                crossfade: dice(&faded),
                wind: dice(&carried),
            }
        })
        .collect();
    Ok(layers)
}

/// The report as a table, one row per layer.
fn print_table(a: &Args, series: &Series, k: usize, report: &Report) -> anyhow::Result<ExitCode> {
    let steps = series.steps();
    out!(
        "{}: {} rebuilt from {} and {} vs the {} step (Dice, coverage > {})",
        shown(&a.map),
        show_hour(a.hold),
        show_hour(steps[k - 1].forecast_hour),
        show_hour(steps[k + 1].forecast_hour),
        show_hour(a.hold),
        MAP_THRESHOLD
    )?;
    out!(
        "{:<7} {:>9} {:>10} {:>9}",
        "layer",
        "motion",
        "crossfade",
        "wind"
    )?;
    for l in &report.layers {
        out!(
            "{:<7} {:>9.4} {:>10.4} {:>9.4}",
            l.kind.name(),
            l.motion,
            l.crossfade,
            l.wind
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
