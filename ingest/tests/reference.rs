//! The CloudMap against the independent reference (ecCodes + SciPy RectBivariateSpline) made
//! from the real GFS 2.5° file: RH 400 hPa, rh_cr 0.65, East Asia, 1300×1100.

use std::path::{Path, PathBuf};

use stratus_ingest::forecast::{Forecast, LevelSelect};
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::spline::Interp;
use stratus_ingest::Region;

fn sample(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data-samples")
        .join(rel)
}

fn read_grey16(path: &Path) -> (u32, u32, Vec<f64>) {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0u8; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Grayscale);
    assert_eq!(info.bit_depth, png::BitDepth::Sixteen);
    let v = buf[..info.buffer_size()]
        .chunks_exact(2)
        .map(|c| u16::from_be_bytes([c[0], c[1]]) as f64 / 65535.0)
        .collect();
    (info.width, info.height, v)
}

/// (mean absolute error, 99th percentile of absolute error) of the A channel vs the reference.
fn errors(interp: Interp) -> (f64, f64) {
    let gfs = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    let reference = sample("reference/east-asia-400hPa-rhcr0.65-1300x1100.png");
    let (w, h, refv) = read_grey16(&reference);
    let fc = Forecast::open(&gfs, LevelSelect::One(400.0)).unwrap();
    let plan = Plan::new(
        &fc,
        &IngestOptions {
            region: Region::parse("0,55,39,105").unwrap(),
            width: w,
            height: h,
            rh_cr: [0.65; 3],
            interp,
        },
    )
    .unwrap();
    let map = plan.build();
    let mut err: Vec<f64> = map
        .texels
        .iter()
        .zip(&refv)
        .map(|(t, r)| (t[3] as f64 / 65535.0 - r).abs())
        .collect();
    let mae = err.iter().sum::<f64>() / err.len() as f64;
    err.sort_by(f64::total_cmp);
    let p99 = err[(err.len() as f64 * 0.99) as usize];
    (mae, p99)
}

#[test]
fn spline_matches_the_independent_reference() {
    let (mae, p99) = errors(Interp::Spline);
    println!("spline vs reference: MAE {mae:.6}, p99 {p99:.6}");
    assert!(mae <= 0.002, "MAE {mae}");
    assert!(p99 <= 0.02, "p99 {p99}");
}

#[test]
fn cheaper_methods_err_more_than_the_spline() {
    let (spline, _) = errors(Interp::Spline);
    for m in [Interp::CatmullRom, Interp::Bilinear, Interp::Nearest] {
        let (mae, p99) = errors(m);
        println!("{m} vs reference: MAE {mae:.6}, p99 {p99:.6}");
        assert!(mae > spline, "{m} MAE {mae} not above spline {spline}");
    }
}

#[test]
fn rh_cr_extremes_stay_finite_and_ordered() {
    // rh_cr 0: any humidity is cloud; rh_cr 0.9999: only saturated air; 1.0 is refused.
    let gfs = sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2");
    let fc = Forecast::open(&gfs, LevelSelect::One(400.0)).unwrap();
    let mut plan = Plan::new(
        &fc,
        &IngestOptions {
            region: Region::parse("0,55,39,105").unwrap(),
            width: 66,
            height: 55,
            rh_cr: [0.0; 3],
            interp: Interp::Spline,
        },
    )
    .unwrap();
    let mean = |m: &stratus_ingest::CloudMap| {
        m.texels.iter().map(|t| t[3] as f64).sum::<f64>() / m.texels.len() as f64 / 65535.0
    };
    let all = mean(&plan.build());
    plan.set_rh_cr([0.65; 3]).unwrap();
    let paper = mean(&plan.build());
    plan.set_rh_cr([0.9999; 3]).unwrap();
    let saturated = mean(&plan.build());
    println!("mean cover at rh_cr 0 / 0.65 / 0.9999: {all:.4} / {paper:.4} / {saturated:.6}");
    assert!(all > paper && paper > saturated && saturated >= 0.0);
    assert!(plan.set_rh_cr([1.0, 0.5, 0.5]).is_err());
}
