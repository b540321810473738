//! `stratus ingest` of several forecast steps: which inputs make a series (checked from their
//! headers before anything is decoded or written), then one map per step and the series
//! sidecar, committed together.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use stratus_ingest::error::shown;
use stratus_ingest::series::inputs::{series_steps, survey, StepSource};
use stratus_ingest::series::meta::show_hour;
use stratus_ingest::series::write::{series_outputs, step_png, write_series};

use super::super::files::check_out;
use super::super::options::progress_bar;
use super::Args;

/// The steps `files` make when they make more than one; `None` for one file of one step (a
/// plain map, written exactly as before). A single file whose headers cannot be surveyed is
/// left to the plain ingest, which says what is wrong with it.
pub fn steps_of(files: &[PathBuf]) -> anyhow::Result<Option<Vec<StepSource>>> {
    if let [one] = files {
        return Ok(match survey(one) {
            Ok(f) if f.steps.len() > 1 => Some(series_steps(&[f])?),
            _ => None,
        });
    }
    let surveyed = files
        .iter()
        .map(|f| survey(f))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Some(series_steps(&surveyed)?))
}

pub fn run(args: &Args, steps: &[StepSource]) -> anyhow::Result<ExitCode> {
    // Every output checked before any work; the write checks again before it commits.
    let outputs = series_outputs(&args.out, steps);
    for o in &outputs {
        check_out(o, &args.files)?;
    }
    let opts = args.ingest.options()?;
    let t0 = Instant::now();
    let rows = opts.height as usize;
    let pb = progress_bar((rows * steps.len()) as u64, "ingest series rows");
    let progress = |k: usize, done: usize| pb.set_position((k * rows + done) as u64);
    let (sidecar, meta) = write_series(&args.out, steps, args.ingest.select(), &opts, &progress)?;
    pb.finish_and_clear();
    out!(
        "{}: series of {} steps, {}x{} px, {} layer(s), {:.2} s",
        shown(&sidecar),
        meta.steps.len(),
        meta.width,
        meta.height,
        meta.layers.len(),
        t0.elapsed().as_secs_f64()
    )?;
    for (s, src) in meta.steps.iter().zip(steps) {
        out!(
            "  {:>7}  valid {}  {}  from {}",
            show_hour(s.forecast_hour),
            stratus_ingest::meta::format_time(&s.valid_time),
            shown(&step_png(&args.out, s.forecast_hour)),
            shown(&src.path)
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
