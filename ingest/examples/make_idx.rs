//! Write NCEP `.idx` inventories for GRIB2 files that come without one (the shared test files),
//! from the ingest crate's own scanner: `cargo run -p stratus-ingest --example make_idx --
//! FILE… [--out DIR]`. Each inventory goes to DIR/NAME.idx (default: print to stdout).

use std::path::PathBuf;

use stratus_ingest::fetch::idx;
use stratus_ingest::{grib, input};

fn main() {
    let mut files: Vec<PathBuf> = Vec::new();
    let mut out: Option<PathBuf> = None;
    let mut args = std::env::args_os().skip(1);
    while let Some(a) = args.next() {
        if a == "--out" {
            out = args.next().map(PathBuf::from);
        } else {
            files.push(a.into());
        }
    }
    if files.is_empty() {
        eprintln!("usage: make_idx FILE… [--out DIR]");
        std::process::exit(2);
    }
    for f in files {
        let result = input::read_grib(&f)
            .map_err(|e| e.to_string())
            .and_then(|bytes| {
                let fields = grib::scan(&bytes).map_err(|e| format!("{}: {e}", f.display()))?;
                Ok(idx::write(&bytes, &fields))
            });
        let text = match result {
            Ok(t) => t,
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(2);
            }
        };
        match &out {
            Some(dir) => {
                let name = f
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .to_string();
                let path = dir.join(format!("{name}.idx"));
                if let Err(e) = std::fs::write(&path, text) {
                    eprintln!("error: {}: {e}", path.display());
                    std::process::exit(2);
                }
            }
            None => print!("{text}"),
        }
    }
}
