//! Writes the embedded demo file: a SYNTHETIC GFS-like GRIB2 file (not a real forecast).
//!
//! `cargo run -p stratus-ingest --example make_sample -- data-samples/synthetic-gfs-rh.grib2`
//!
//! 0.5° grid over 30–60°N, 40°W–0° (81×61 points, longitudes written 320–360 as GFS does),
//! reference time 2024-06-01T00Z, step +12 h, on 9 isobaric levels; fields r (RH, %), gh (m)
//! and t (K). The RH field is a smooth sum of Gaussians and sinusoids with a fixed seed: a
//! cold-front band tilting north-west with height, a few deep convective cells with anvils, a
//! subtropical subsidence dry slot with marine stratocumulus under it, and a cirrus shield, so
//! low, middle and high cloud all appear. Output is byte-for-byte reproducible.

use chrono::{TimeZone, Utc};
use stratus_ingest::encode::{encode_file, fixtures::XorShift, param, Grib2Field};
use stratus_ingest::grib::{Discipline, SurfaceType};

const LEVELS_HPA: [f64; 9] = [
    1000.0, 925.0, 850.0, 700.0, 600.0, 500.0, 400.0, 300.0, 250.0,
];
const NI: u32 = 81;
const NJ: u32 = 61;
const NORTH: f64 = 60.0;
const WEST: f64 = -40.0;
const STEP: f64 = 0.5;

/// ISA height (m) of a pressure level; every level here is in the troposphere.
fn isa_height(hpa: f64) -> f64 {
    288.15 / 0.0065 * (1.0 - (hpa / 1013.25).powf(0.190_263))
}

fn gauss(dx: f64, dy: f64, sx: f64, sy: f64) -> f64 {
    (-0.5 * ((dx / sx).powi(2) + (dy / sy).powi(2))).exp()
}

/// Smooth "weather noise": a few sinusoids with seeded wavenumbers and phases.
struct Waves(Vec<(f64, f64, f64, f64)>);

impl Waves {
    fn new(rng: &mut XorShift, n: usize) -> Self {
        Waves(
            (0..n)
                .map(|_| {
                    (
                        0.05 + 0.15 * rng.next_f64(),
                        0.05 + 0.15 * rng.next_f64(),
                        std::f64::consts::TAU * rng.next_f64(),
                        0.5 + 0.5 * rng.next_f64(),
                    )
                })
                .collect(),
        )
    }
    /// In about [-1, 1].
    fn at(&self, lon: f64, lat: f64, z: f64) -> f64 {
        let s: f64 = self
            .0
            .iter()
            .map(|&(kx, ky, ph, a)| a * (kx * lon + ky * lat + ph + 0.8 * z).sin())
            .sum();
        s / self.0.len() as f64 * 1.6
    }
}

/// Relative humidity in percent at (lon °E, lat °N, pressure hPa).
fn rh(lon: f64, lat: f64, hpa: f64, noise: &Waves) -> f64 {
    // 0 at 1000 hPa, 1 at 250 hPa.
    let z = (1000.0 - hpa) / 750.0;
    // Background: moist boundary layer, drier aloft.
    let mut v = 62.0 - 22.0 * z + 12.0 * noise.at(lon, lat, z);

    // Cold front from the south-west to the north-east; the band slopes back (north-west)
    // with height and widens, as a frontal surface does.
    let front_lat = 33.0 + 0.62 * (lon + 40.0) + 2.5 * (0.18 * lon).sin() + 3.0 * z;
    let across = lat - front_lat;
    let width = 1.6 + 1.8 * z;
    let band = (-0.5 * (across / width).powi(2)).exp();
    v += (38.0 - 6.0 * z) * band;

    // Warm-conveyor cirrus shield ahead (east/south-east) of the front, upper levels only.
    let shield = gauss(across + 4.0, 0.0, 3.5, 1.0) * gauss(lon + 14.0, lat - 50.0, 12.0, 8.0);
    v += 45.0 * shield * ((z - 0.55) / 0.3).clamp(0.0, 1.0);

    // Subtropical high: subsidence dries the middle troposphere...
    let high = gauss(lon + 16.0, lat - 35.0, 7.0, 4.5);
    let aloft = ((z - 0.1) / 0.25).clamp(0.0, 1.0);
    v -= 50.0 * high * aloft * (1.0 - (2.0 * (z - 0.45)).powi(2)).max(0.2);
    // ...over a moist marine layer (stratocumulus at 1000–925 hPa).
    v += 38.0 * high * (1.0 - z / 0.25).clamp(0.0, 1.0);

    // Deep convective cells in the warm sector with anvils spreading at 300–250 hPa.
    for &(clon, clat, r) in &[(-33.0, 34.0, 1.1), (-27.5, 36.5, 0.9), (-22.0, 33.0, 1.3)] {
        let tower = gauss(lon - clon, lat - clat, r, r);
        let anvil = gauss(lon - clon - 1.5, lat - clat - 0.5, 3.0 * r, 2.0 * r);
        v += 45.0 * tower + 30.0 * anvil * ((z - 0.7) / 0.2).clamp(0.0, 1.0);
    }

    // Dry slot behind the front (north-west), strongest in the middle.
    v -= 28.0 * gauss(lon + 34.0, lat - 52.0, 5.0, 4.0) * (1.0 - (z - 0.5).abs());

    v.clamp(1.0, 100.0)
}

fn main() {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "data-samples/synthetic-gfs-rh.grib2".into());
    let mut rng = XorShift(0x5757_2024_0601_0012);
    let noise = Waves::new(&mut rng, 6);
    let dyn_noise = Waves::new(&mut rng, 4);

    let base = Grib2Field {
        discipline: Discipline::Meteorological,
        category: 1,
        number: 1,
        level_type: Some(SurfaceType::Isobaric),
        level_value: 0.0,
        ni: NI,
        nj: NJ,
        lat1: NORTH,
        lon1: 360.0 + WEST,
        lat2: NORTH - STEP * (NJ - 1) as f64,
        lon2: 360.0 + WEST + STEP * (NI - 1) as f64,
        di: STEP,
        dj: STEP,
        reference_time: Utc.with_ymd_and_hms(2024, 6, 1, 0, 0, 0).unwrap(),
        forecast_hours: 12,
        values: Vec::new(),
        decimal_scale: 1,
        bits: 10,
    };
    let points = || {
        (0..NJ)
            .flat_map(|j| (0..NI).map(move |i| (WEST + STEP * i as f64, NORTH - STEP * j as f64)))
    };

    let mut fields = Vec::new();
    for &hpa in &LEVELS_HPA {
        let z = (1000.0 - hpa) / 750.0;
        let level_value = hpa * 100.0;
        let rh_vals: Vec<f64> = points()
            .map(|(lon, lat)| rh(lon, lat, hpa, &noise))
            .collect();
        let field = |p: (u8, u8, u8), values, decimal_scale, bits| Grib2Field {
            discipline: Discipline::from_code(p.0),
            category: p.1,
            number: p.2,
            level_value,
            values,
            decimal_scale,
            bits,
            ..base.clone()
        };
        fields.push(field(param::RH, rh_vals, 1, 10));

        // Heights fall towards the pole and in an upper trough to the west; more so aloft.
        let z0 = isa_height(hpa);
        let scale = 0.15 + z0 / 5500.0;
        let gh: Vec<f64> = points()
            .map(|(lon, lat)| {
                let trough = -40.0 * gauss(lon + 32.0, lat - 55.0, 10.0, 8.0);
                z0 + scale * (-9.0 * (lat - 45.0) + trough + 8.0 * dyn_noise.at(lon, lat, z))
            })
            .collect();
        fields.push(field(param::GH, gh, 0, 14));

        // ISA temperature, colder to the north and behind the front.
        let t: Vec<f64> = points()
            .map(|(lon, lat)| {
                288.15
                    - 0.0065 * z0
                    - 0.45 * (lat - 45.0)
                    - 2.0 * gauss(lon + 32.0, lat - 55.0, 10.0, 8.0)
                    + 1.0 * dyn_noise.at(lon, lat, z)
            })
            .collect();
        fields.push(field(param::T, t, 1, 12));
    }

    let bytes = encode_file(&fields);
    if let Some(dir) = std::path::Path::new(&out).parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).expect("create output directory");
        }
    }
    std::fs::write(&out, &bytes).expect("write output");
    println!(
        "wrote {out}: {} messages, {} bytes",
        fields.len(),
        bytes.len()
    );
    for &hpa in &LEVELS_HPA {
        let v: Vec<f64> = points()
            .map(|(lon, lat)| rh(lon, lat, hpa, &noise))
            .collect();
        let frac = |t: f64| v.iter().filter(|&&x| x > t).count() as f64 / v.len() as f64 * 100.0;
        let (min, max) = v
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        println!(
            "  {hpa:>4} hPa  RH {min:5.1}..{max:5.1} %  >65 %: {:4.1}% of points  >80 %: {:4.1}%",
            frac(65.0),
            frac(80.0)
        );
    }
}
