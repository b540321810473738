//! `stratus ingest … --out STORE.zarr`: the steps of the files (one or several) as one Zarr v3
//! store, or with `--append` added to an existing one (`stratus_ingest::zarr::write`); with
//! `--plan`, `--step K`, `--motion K`, `--finish` one call of a batch run that many processes
//! share (`stratus_ingest::zarr::batch`).

use std::process::ExitCode;
use std::time::Instant;

use stratus_ingest::error::shown;
use stratus_ingest::series::inputs::{series_steps, survey};
use stratus_ingest::series::meta::show_hour;
use stratus_ingest::zarr::batch;
use stratus_ingest::zarr::write::{append, create, describe};

use super::super::options::progress_bar;
use super::Args;

pub fn run(args: &Args) -> anyhow::Result<ExitCode> {
    let t0 = Instant::now();
    let b = &args.batch;
    let run = b.run.as_deref().unwrap_or_default();
    if run.is_empty() && b.any() {
        anyhow::bail!("{}: --run ID names the batch run", shown(&args.out));
    }
    if let Some(k) = b.motion {
        let m = batch::motion(&args.out, k, run)?;
        out!(
            "{}: interval {k} (motion {}x{}, scale {:.3e} px) written, {:.2} s",
            shown(&args.out),
            m.width,
            m.height,
            m.scale,
            t0.elapsed().as_secs_f64()
        )?;
        return Ok(ExitCode::SUCCESS);
    }
    if b.finish {
        let w = batch::finish(&args.out, run)?;
        out!(
            "{} (Zarr v3; batch run {run} finished), {:.2} s",
            describe(&w),
            t0.elapsed().as_secs_f64()
        )?;
        return Ok(ExitCode::SUCCESS);
    }
    let surveyed = args
        .files
        .iter()
        .map(|f| survey(f))
        .collect::<Result<Vec<_>, _>>()?;
    let steps = series_steps(&surveyed)?;
    let opts = args.ingest.options()?;
    if b.plan {
        let p = batch::plan(&args.out, &surveyed, &steps, &opts, run)?;
        out!(
            "{}: planned {} step(s) ({}) and {} interval(s) for batch run {run}, {:.2} s",
            shown(&args.out),
            p.hours.len(),
            p.hours
                .iter()
                .map(|&h| show_hour(h))
                .collect::<Vec<_>>()
                .join(", "),
            p.hours.len().saturating_sub(1),
            t0.elapsed().as_secs_f64()
        )?;
        return Ok(ExitCode::SUCCESS);
    }
    let rows = opts.height as usize;
    let n = if b.step.is_some() { 1 } else { steps.len() };
    let pb = progress_bar((rows * n) as u64, "ingest store rows");
    let progress = |k: usize, done: usize| pb.set_position((k * rows + done) as u64);
    if let Some(k) = b.step {
        let s = batch::step(
            &args.out,
            k,
            &surveyed,
            &steps,
            args.ingest.select(),
            &opts,
            run,
            &progress,
        )?;
        pb.finish_and_clear();
        out!(
            "{}: step {k} ({}) written, {:.2} s",
            shown(&args.out),
            show_hour(s.forecast_hour),
            t0.elapsed().as_secs_f64()
        )?;
        return Ok(ExitCode::SUCCESS);
    }
    let write = if args.append { append } else { create };
    let written = write(&args.out, &steps, args.ingest.select(), &opts, &progress)?;
    pb.finish_and_clear();
    out!(
        "{} (Zarr v3; {} step(s) {}), {:.2} s",
        describe(&written),
        written.added,
        if args.append { "appended" } else { "written" },
        t0.elapsed().as_secs_f64()
    )?;
    Ok(ExitCode::SUCCESS)
}
