//! `stratus ingest … --out STORE.zarr`: the steps of the files (one or several) as one Zarr v3
//! store, or with `--append` added to an existing one (`stratus_ingest::zarr::write`).

use std::process::ExitCode;
use std::time::Instant;

use stratus_ingest::series::inputs::{series_steps, survey};
use stratus_ingest::zarr::write::{append, create, describe};

use super::super::options::progress_bar;
use super::Args;

pub fn run(args: &Args) -> anyhow::Result<ExitCode> {
    let surveyed = args
        .files
        .iter()
        .map(|f| survey(f))
        .collect::<Result<Vec<_>, _>>()?;
    let steps = series_steps(&surveyed)?;
    let opts = args.ingest.options()?;
    let t0 = Instant::now();
    let rows = opts.height as usize;
    let pb = progress_bar((rows * steps.len()) as u64, "ingest store rows");
    let progress = |k: usize, done: usize| pb.set_position((k * rows + done) as u64);
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
