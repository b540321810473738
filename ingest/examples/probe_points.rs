//! Ingest a GFS file (all layers) around each `LAT,LON` given — a 3×3-pixel map whose pixel
//! centres are the 2.5° grid points around it — and print the probe there, as
//! `stratus probe --json` will. The check against ecCodes (docs/ingest.md) uses it.
//! `cargo run --release -p stratus-ingest --example probe_points -- FILE OUT.png LAT,LON…`
//!
//! With `--map S,N,W,E WxH` first, one map of that region and size is ingested instead and
//! every point is probed on it: a large map has structure images smaller than itself
//! (`structure::structure_size`), so this checks the probe through the reduced images.
use std::path::Path;

use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::region::parse_size;
use stratus_ingest::spline::Interp;
use stratus_ingest::{CloudMap, LayerKind, Region};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (map, rest) = match args.as_slice() {
        [flag, region, size, rest @ ..] if flag == "--map" => {
            (Some((Region::parse(region)?, parse_size(size)?)), rest)
        }
        rest => (None, rest),
    };
    let [file, out, points @ ..] = rest else {
        return Err("usage: probe_points [--map S,N,W,E WxH] FILE OUT.png LAT,LON...".into());
    };
    let fc = Forecast::open(Path::new(file), LevelSelect::AllBelow(DEFAULT_TOP_HPA))?;
    let step = fc.levels[0].field.grid.di;
    let ingest = |region: Region,
                  (width, height): (u32, u32)|
     -> Result<CloudMap, Box<dyn std::error::Error>> {
        let plan = Plan::new(
            &fc,
            &IngestOptions {
                region,
                width,
                height,
                rh_cr: LayerKind::DEFAULT_RH_CR,
                interp: Interp::Spline,
            },
        )?;
        Ok(CloudMap::load(&plan.write(Path::new(out), &|_| {})?)?)
    };
    let whole = match map {
        Some((region, size)) => Some(ingest(region, size)?),
        None => None,
    };
    for p in points {
        let (lat, lon) = p.split_once(',').ok_or("LAT,LON")?;
        let (lat, lon): (f64, f64) = (lat.parse()?, lon.parse()?);
        let h = 1.5 * step;
        let own;
        let map = match &whole {
            Some(m) => m,
            None => {
                let r = Region::parse(&format!("{},{},{},{}", lat - h, lat + h, lon - h, lon + h))?;
                own = ingest(r, (3, 3))?;
                &own
            }
        };
        let probe = map.probe(lat, lon).ok_or("outside")?;
        println!("{}", serde_json::to_string(&probe)?);
    }
    Ok(())
}
