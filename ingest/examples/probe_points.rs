//! Ingest a GFS file (all layers) around each `LAT,LON` given — a 3×3-pixel map whose pixel
//! centres are the 2.5° grid points around it — and print the probe there, as
//! `stratus probe --json` will. The check against ecCodes (docs/ingest.md) uses it.
//! `cargo run --release -p stratus-ingest --example probe_points -- FILE OUT.png LAT,LON…`
use std::path::Path;

use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::spline::Interp;
use stratus_ingest::{CloudMap, LayerKind, Region};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [file, out, points @ ..] = args.as_slice() else {
        return Err("usage: probe_points FILE OUT.png LAT,LON...".into());
    };
    let fc = Forecast::open(Path::new(file), LevelSelect::AllBelow(DEFAULT_TOP_HPA))?;
    let step = fc.levels[0].field.grid.di;
    for p in points {
        let (lat, lon) = p.split_once(',').ok_or("LAT,LON")?;
        let (lat, lon): (f64, f64) = (lat.parse()?, lon.parse()?);
        let h = 1.5 * step;
        let plan = Plan::new(
            &fc,
            &IngestOptions {
                region: Region::parse(&format!("{},{},{},{}", lat - h, lat + h, lon - h, lon + h))?,
                width: 3,
                height: 3,
                rh_cr: LayerKind::DEFAULT_RH_CR,
                interp: Interp::Spline,
            },
        )?;
        let json = plan.write(Path::new(out), &|_| {})?;
        let map = CloudMap::load(&json)?;
        let probe = map.probe(lat, lon).ok_or("outside")?;
        println!("{}", serde_json::to_string(&probe)?);
    }
    Ok(())
}
