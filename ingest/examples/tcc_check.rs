//! Meteorological sanity check of the critical-humidity model: GFS's own layer cloud cover
//! (`tcc` on the low/middle/high cloud layers, NCEP level types 214/224/234) against the
//! RH-derived layer coverage, on the file's native grid, as Dice per layer.
//!
//! `cargo run --release -p stratus-ingest --example tcc_check -- FILE.grib2 [S,N,W,E]`

use std::path::PathBuf;

use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::grib::{self, SurfaceType};
use stratus_ingest::pipeline::coverage;
use stratus_ingest::{LayerKind, Region};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = PathBuf::from(args.next().ok_or("usage: tcc_check FILE [S,N,W,E]")?);
    let region = args
        .next()
        .map(|s| Region::parse(&s))
        .transpose()?
        .unwrap_or(Region {
            south: -90.0,
            north: 90.0,
            west: 0.0,
            east: 360.0,
        });
    let bytes = std::fs::read(&path)?;
    let msgs = grib::scan(&bytes)?;
    let fc = Forecast::from_bytes(&path, &bytes, LevelSelect::AllBelow(DEFAULT_TOP_HPA))?;
    let grid = fc.levels[0].field.grid.clone();
    println!("file {}  region {:?}", path.display(), region);
    println!("| layer | GFS tcc level | grid points | tcc ≥ 50 % | RH-derived CM ≥ 0.1 | Dice | Dice (tcc ≥ 20 %, CM > 0) | corr(tcc, CM) |");
    println!("|---|---|---|---|---|---|---|---|");
    for (kind, lt) in [
        (LayerKind::Low, SurfaceType::LowCloudLayer),
        (LayerKind::Middle, SurfaceType::MiddleCloudLayer),
        (LayerKind::High, SurfaceType::HighCloudLayer),
    ] {
        let Some(m) = msgs
            .iter()
            .find(|m| m.parameter() == (0, 6, 1) && m.level_type == Some(lt))
        else {
            println!("| {} | absent | | | | | | |", kind.name());
            continue;
        };
        let tcc = grib::decode_values(&bytes, m)?;
        let rh_cr = kind.default_rh_cr();
        let mut pts = Vec::new();
        for j in 0..grid.nj {
            let lat = grid.north() - j as f64 * grid.dj;
            for i in 0..grid.ni {
                let lon = grid.west() + i as f64 * grid.di;
                if region.to_pixel(lat, lon, 1, 1).is_none() {
                    continue;
                }
                let cm = fc
                    .levels
                    .iter()
                    .filter(|l| LayerKind::of_pressure_hpa(l.pressure_hpa) == kind)
                    .map(|l| coverage((l.field.at(i, j) / 100.0).clamp(0.0, 1.0), rh_cr))
                    .fold(0.0, f64::max);
                let t = tcc.at(i, j);
                if t.is_finite() {
                    pts.push((t, cm));
                }
            }
        }
        let dice = |tt: f64, ct: f64, strict: bool| {
            let (mut a, mut b, mut ab) = (0, 0, 0);
            for &(t, c) in &pts {
                let x = t >= tt;
                let y = if strict { c > ct } else { c >= ct };
                a += x as usize;
                b += y as usize;
                ab += (x && y) as usize;
            }
            (
                a,
                b,
                if a + b == 0 {
                    1.0
                } else {
                    2.0 * ab as f64 / (a + b) as f64
                },
            )
        };
        let (a, b, d1) = dice(50.0, 0.1, false);
        let (_, _, d2) = dice(20.0, 0.0, true);
        let n = pts.len() as f64;
        let (mt, mc) = pts
            .iter()
            .fold((0.0, 0.0), |s, p| (s.0 + p.0 / n, s.1 + p.1 / n));
        let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
        for &(t, c) in &pts {
            sxy += (t - mt) * (c - mc);
            sxx += (t - mt) * (t - mt);
            syy += (c - mc) * (c - mc);
        }
        let corr = sxy / (sxx * syy).sqrt();
        println!(
            "| {} (rh_cr {rh_cr}) | {} | {} | {:.1} % | {:.1} % | {d1:.3} | {d2:.3} | {corr:.3} |",
            kind.name(),
            m.level_text(),
            pts.len(),
            100.0 * a as f64 / n,
            100.0 * b as f64 / n,
        );
    }
    Ok(())
}
