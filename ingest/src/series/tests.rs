//! Blend, advection and series checks on made-up maps whose answer is known.

use std::path::PathBuf;

use chrono::{DateTime, Utc};

use super::advect::{advect, blend, sample_coverage, EARTH_RADIUS_M};
use super::inputs::{series_steps, InputFile};
use super::*;
use crate::grib::LatLonGrid;
use crate::meta::{LayerKind, StructureGrid};
use crate::region::Region;
use crate::structure::{wind_to_sample, MapStructure};

fn t0() -> DateTime<Utc> {
    crate::meta::parse_time("2015-09-12T18:00:00Z").unwrap()
}

/// 0.1° pixels around the equator.
fn region() -> Region {
    Region::parse("-10,10,0,40").unwrap()
}
const W: u32 = 400;
const H: u32 = 200;

/// A round blob of cover 1 in the high layer (and 0.6 in the low one) of radius 1.5° at
/// (`lat`, `lon`), with a uniform wind (`u`, `v`) m/s in every layer.
fn blob_map(lat: f64, lon: f64, (u, v): (f64, f64), valid: DateTime<Utc>) -> CloudMap {
    let bands = [
        (LayerKind::Low, 500.0, 1500.0),
        (LayerKind::High, 8000.0, 10000.0),
    ];
    let mut m = CloudMap::from_fn(region(), W, H, &bands, valid, |la, lo| {
        let d = ((la - lat).powi(2) + (lo - lon).powi(2)).sqrt();
        let c = (1.5 - d).clamp(0.0, 0.3) / 0.3;
        [0.6 * c, 0.0, c]
    });
    // A step of the t0 run, as its sidecar records it (Series::load compares them).
    m.meta.source.reference_time = Some(t0());
    m.meta.source.forecast_step_h = (valid - t0()).num_seconds() as f64 / 3600.0;
    let grid = StructureGrid::of_map(&region(), 20, 10);
    let n = 200;
    m.structure = Some(MapStructure {
        grid,
        base: vec![[0; 4]; n],
        top: vec![[0; 4]; n],
        types: vec![[0; 4]; n],
        wind_u: vec![[wind_to_sample(u); 3]; n],
        wind_v: vec![[wind_to_sample(v); 3]; n],
    });
    m
}

/// Centroid (column, row) of channel `c`'s coverage, and its peak.
fn centroid(m: &CloudMap, c: usize) -> (f64, f64, u16) {
    let (mut s, mut sx, mut sy, mut peak) = (0.0, 0.0, 0.0, 0);
    for (k, t) in m.texels.iter().enumerate() {
        let v = t[c] as f64;
        s += v;
        sx += v * (k % m.width()) as f64;
        sy += v * (k / m.width()) as f64;
        peak = peak.max(t[c]);
    }
    (sx / s, sy / s, peak)
}

const SIX_H: f64 = 6.0 * 3600.0;

/// Pixels (0.1° each) a wind of `ms` covers in six hours at the equator.
fn pixels_in_six_hours(ms: f64) -> f64 {
    ms * SIX_H / EARTH_RADIUS_M * 180.0 / std::f64::consts::PI / 0.1
}

#[test]
fn a_uniform_wind_moves_a_blob_by_the_expected_pixels() {
    let m = blob_map(0.0, 10.0, (10.0, -5.0), t0());
    let (x0, y0, p0) = centroid(&m, 2);
    let moved = advect(&m, SIX_H);
    let (x1, y1, p1) = centroid(&moved, 2);
    // East is +column, south is +row (row 0 north).
    let (dx, dy) = (pixels_in_six_hours(10.0), pixels_in_six_hours(5.0));
    assert!((dx - 19.43).abs() < 0.01, "{dx}");
    assert!(
        (x1 - x0 - dx).abs() < 0.3,
        "east {} px, expected {dx}",
        x1 - x0
    );
    assert!(
        (y1 - y0 - dy).abs() < 0.3,
        "south {} px, expected {dy}",
        y1 - y0
    );
    assert!(
        p1 as f64 > 0.95 * p0 as f64,
        "the blob is carried, not smeared away"
    );
    // Every layer moves, and the total is the max of the layers.
    let (xl, _, _) = centroid(&moved, 0);
    assert!((xl - x0 - dx).abs() < 0.3);
    assert!(moved
        .texels
        .iter()
        .all(|t| t[3] == t[0].max(t[1]).max(t[2])));
    assert_eq!(
        moved.meta.source.valid_time,
        Some(t0() + chrono::Duration::hours(6))
    );
}

#[test]
fn advection_with_zero_wind_is_persistence() {
    let m = blob_map(1.0, 12.0, (0.0, 0.0), t0());
    let moved = advect(&m, SIX_H);
    assert_eq!(moved.texels, m.texels);
}

#[test]
fn the_blend_at_its_ends_is_the_step_maps() {
    let later = t0() + chrono::Duration::hours(6);
    // Winds that do not match the motion: the ends must hold whatever the winds.
    let a = blob_map(0.0, 10.0, (20.0, 7.0), t0());
    let b = blob_map(3.0, 25.0, (-15.0, 4.0), later);
    let at0 = blend(&a, &b, 0.0, SIX_H).unwrap();
    assert_eq!(at0.texels, a.texels);
    assert_eq!(at0.meta.source.valid_time, Some(t0()));
    let at1 = blend(&a, &b, 1.0, SIX_H).unwrap();
    assert_eq!(at1.texels, b.texels);
    assert_eq!(at1.meta.source.valid_time, Some(later));
}

#[test]
fn between_steps_a_front_travels_instead_of_fading() {
    // Step b is step a carried by its own wind: half-way, one whole blob half-way along.
    let u = 10.0;
    let dx_deg = pixels_in_six_hours(u) * 0.1;
    let a = blob_map(0.0, 10.0, (u, 0.0), t0());
    let b = blob_map(
        0.0,
        10.0 + dx_deg,
        (u, 0.0),
        t0() + chrono::Duration::hours(6),
    );
    let mid = blend(&a, &b, 0.5, SIX_H).unwrap();
    let (xa, _, pa) = centroid(&a, 2);
    let (xm, _, pm) = centroid(&mid, 2);
    assert!((xm - xa - 0.5 * dx_deg / 0.1).abs() < 0.3, "{xm} vs {xa}");
    assert!(pm as f64 > 0.95 * pa as f64, "peak {pm} of {pa}: faded");
    // Half-way along, the blob's centre is cloud; a crossfade would leave two half blobs.
    let c = sample_coverage(&mid, 2, 0.0, 10.0 + 0.5 * dx_deg);
    assert!(c > 0.95, "{c}");
    assert_eq!(
        mid.meta.source.valid_time,
        Some(t0() + chrono::Duration::hours(3))
    );
}

#[test]
fn maps_that_do_not_match_are_not_blended() {
    let a = blob_map(0.0, 10.0, (0.0, 0.0), t0());
    let mut b = a.clone();
    b.meta.width = 10;
    assert!(blend(&a, &b, 0.5, SIX_H).is_err());
    assert!(blend(&a, &a, 1.5, SIX_H).is_err());
}

fn input(name: &str, run_h: i64, steps: &[f64], ni: usize) -> InputFile {
    InputFile {
        path: PathBuf::from(name),
        grid: LatLonGrid {
            ni,
            nj: 73,
            lat1: 90.0,
            lat2: -90.0,
            lon1: 0.0,
            lon2: 357.5,
            di: 2.5,
            dj: 2.5,
            scan_mode: 0,
        },
        reference_time: t0() + chrono::Duration::hours(run_h),
        steps: steps.to_vec(),
    }
}

#[test]
fn files_that_are_not_one_series_are_named() {
    let ok = series_steps(&[input("a", 0, &[0.0], 144), input("b", 0, &[3.0, 6.0], 144)]).unwrap();
    let hours: Vec<f64> = ok.iter().map(|s| s.hour).collect();
    assert_eq!(hours, [0.0, 3.0, 6.0]);
    assert!(!ok[0].shared_file && ok[1].shared_file);

    let e = |files: &[InputFile]| series_steps(files).unwrap_err().to_string();
    let grid = e(&[input("a", 0, &[0.0], 144), input("b", 0, &[6.0], 360)]);
    assert!(grid.starts_with("b: its grid (360x73"), "{grid}");
    let run = e(&[input("a", 0, &[0.0], 144), input("b", 6, &[6.0], 144)]);
    assert!(
        run.starts_with("b: it is of the 2015-09-13T00:00:00Z run"),
        "{run}"
    );
    let close = e(&[input("a", 0, &[0.0], 144), input("b", 0, &[0.0002], 144)]);
    assert!(
        close.starts_with(
            "b: step +0.0002 h (0.72 s after the run) is not a whole number of minutes"
        ),
        "{close}"
    );
    let dup = e(&[input("a", 0, &[6.0], 144), input("b", 0, &[6.0], 144)]);
    assert_eq!(dup, "b: step +6 h is duplicated (also in a)");
    let order = e(&[
        input("late", 0, &[6.0], 144),
        input("early", 0, &[0.0], 144),
    ]);
    assert!(
        order.starts_with("early: step +0 h comes after +6 h of late")
            && order.ends_with("increasing forecast hour: early late"),
        "{order}"
    );
}

#[test]
fn a_series_loads_blends_between_steps_and_refuses_missing_maps() {
    let dir = tempfile::tempdir().unwrap();
    let later = t0() + chrono::Duration::hours(6);
    let maps = [
        blob_map(0.0, 10.0, (10.0, 0.0), t0()),
        blob_map(0.0, 12.0, (10.0, 0.0), later),
    ];
    let mut steps = Vec::new();
    for (m, h) in maps.iter().zip([0.0, 6.0]) {
        let png = write::step_png(&dir.path().join("s.png"), h);
        m.save(&png).unwrap();
        steps.push(SeriesStep {
            forecast_hour: h,
            valid_time: crate::grib::info::after_step(t0(), h),
            map: png
                .with_extension("json")
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into(),
            winds: None,
            mean_wind: None,
            motion: None,
        });
    }
    let meta = SeriesMeta {
        format: SERIES_FORMAT.into(),
        reference_time: t0(),
        region: region(),
        width: W,
        height: H,
        layers: maps[0]
            .meta
            .layers
            .iter()
            .map(|l| meta::SeriesLayer {
                kind: l.kind,
                channel: l.channel,
                levels_hpa: vec![],
            })
            .collect(),
        steps,
    };
    let path = dir.path().join("s.json");
    std::fs::write(&path, serde_json::to_string_pretty(&meta).unwrap()).unwrap();
    assert!(is_series(&path));
    let s = Series::load(&path).unwrap();
    assert_eq!(s.step_map(1).unwrap().texels, maps[1].texels);
    assert_eq!(s.at(later).unwrap().texels, maps[1].texels);
    let mid = s.at(t0() + chrono::Duration::hours(3)).unwrap();
    assert_eq!(
        mid.meta.source.valid_time,
        Some(t0() + chrono::Duration::hours(3))
    );
    assert_eq!(open_map(&path, None).unwrap().texels, maps[0].texels);

    // Entries swapped: each step's own sidecar says which step it is.
    let mut swapped = meta.clone();
    let (a, b) = (swapped.steps[0].map.clone(), swapped.steps[1].map.clone());
    (swapped.steps[0].map, swapped.steps[1].map) = (b, a);
    let other = dir.path().join("swapped.json");
    std::fs::write(&other, serde_json::to_string_pretty(&swapped).unwrap()).unwrap();
    let e = Series::load(&other).unwrap_err().to_string();
    assert!(
        e.contains("swapped.json: step +0 h:") && e.contains("it is the +6 h step"),
        "{e}"
    );

    std::fs::remove_file(dir.path().join("s-f006.png")).unwrap();
    let e = Series::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("s.json: step +6 h:") && e.contains("s-f006.png: missing"),
        "{e}"
    );
    std::fs::remove_file(dir.path().join("s-f006.json")).unwrap();
    let e = Series::load(&path).unwrap_err().to_string();
    assert!(e.contains("step +6 h:") && e.contains("s-f006.json"), "{e}");
}
