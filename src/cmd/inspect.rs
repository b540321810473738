//! `stratus inspect FILE`: one row per GRIB message, from headers only (nothing is decoded).

use std::path::PathBuf;
use std::process::ExitCode;

use stratus_ingest::error::shown;
use stratus_ingest::{grib, input};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// GRIB2 file to list.
    pub file: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    // Capped like every GRIB read: `/dev/zero` or a huge file is refused, not held.
    let bytes = input::read_grib(&args.file)?;
    let msgs = grib::scan(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", shown(&args.file)))?;
    out!(
        "{:>6} {:>9}  {:<7} {:<6} {:<28} {:<44} {:<24} reference step",
        "#",
        "offset",
        "d.c.n",
        "name",
        "level",
        "grid",
        "packing"
    )?;
    for m in &msgs {
        out!("{m}")?;
    }
    out!("{} messages in {}", msgs.len(), shown(&args.file))?;
    Ok(ExitCode::SUCCESS)
}
