//! `stratus ingest`: GRIB2 relative humidity → CloudMap PNG + sidecar, with a progress bar.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use stratus_ingest::cloudmap::load_meta;
use stratus_ingest::error::shown;

use super::files::check_out;
use super::options::{progress_bar, IngestOpts};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// GRIB2 forecast file.
    pub file: PathBuf,
    #[command(flatten)]
    pub ingest: IngestOpts,
    /// Output PNG; the sidecar goes next to it with a .json extension.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.out.extension().and_then(|e| e.to_str()) != Some("png") {
        anyhow::bail!("{}: output must be a .png file", shown(&args.out));
    }
    // Before the forecast is read: a bad output fails at once. (The write checks again.)
    let inputs = [args.file.clone()];
    check_out(&args.out, &inputs)?;
    check_out(&args.out.with_extension("json"), &inputs)?;
    let t0 = Instant::now();
    let plan = args.ingest.plan(&args.file)?;
    let pb = progress_bar(plan.height() as u64, "ingest rows");
    // The library's error names the file; no context is added, so it is named once.
    let sidecar = plan.write(&args.out, &|done| pb.set_position(done as u64))?;
    pb.finish_and_clear();
    let meta = load_meta(&sidecar)?;
    out!(
        "{} + {}: {}x{} px, {} layer(s), {:.2} s",
        shown(&args.out),
        shown(&sidecar),
        meta.width,
        meta.height,
        meta.layers.len(),
        t0.elapsed().as_secs_f64()
    )?;
    for l in &meta.layers {
        out!(
            "  {:<6} {:>5.0}–{:<5.0} m  rh_cr {:.2}  levels {:?} hPa  mean cover {:.3}  max {:.3}",
            l.kind.name(),
            l.base_m,
            l.top_m,
            l.rh_cr,
            l.levels_hpa,
            l.mean_coverage,
            l.max_coverage
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
