//! `stratus ingest`: GRIB2 relative humidity → CloudMap PNG + sidecar, with a progress bar.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;

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
        anyhow::bail!("{}: output must be a .png file", args.out.display());
    }
    let t0 = Instant::now();
    let plan = args.ingest.plan(&args.file)?;
    let pb = progress_bar(plan.height() as u64, "ingest rows");
    let sidecar = plan
        .write(&args.out, &|done| pb.set_position(done as u64))
        .with_context(|| format!("writing {}", args.out.display()))?;
    pb.finish_and_clear();
    let meta: stratus_ingest::CloudMapMeta =
        serde_json::from_str(&std::fs::read_to_string(&sidecar)?)?;
    println!(
        "{} + {}: {}x{} px, {} layer(s), {:.2} s",
        args.out.display(),
        sidecar.display(),
        meta.width,
        meta.height,
        meta.layers.len(),
        t0.elapsed().as_secs_f64()
    );
    for l in &meta.layers {
        println!(
            "  {:<6} {:>5.0}–{:<5.0} m  rh_cr {:.2}  levels {:?} hPa  mean cover {:.3}  max {:.3}",
            l.kind.name(),
            l.base_m,
            l.top_m,
            l.rh_cr,
            l.levels_hpa,
            l.mean_coverage,
            l.max_coverage
        );
    }
    Ok(ExitCode::SUCCESS)
}
