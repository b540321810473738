//! `stratus inspect FILE`: one row per GRIB message, from headers only (nothing is decoded).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use stratus_ingest::grib;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// GRIB2 file to list.
    pub file: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let bytes = std::fs::read(&args.file)
        .with_context(|| format!("{}: cannot read", args.file.display()))?;
    let msgs = grib::scan(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", args.file.display()))?;
    println!(
        "{:>6} {:>9}  {:<7} {:<6} {:<28} {:<44} {:<24} reference step",
        "#", "offset", "d.c.n", "name", "level", "grid", "packing"
    );
    for m in &msgs {
        println!("{m}");
    }
    println!("{} messages in {}", msgs.len(), args.file.display());
    Ok(ExitCode::SUCCESS)
}
