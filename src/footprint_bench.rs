//! What a pixel shows against what it covers (issue 30), measured: each view rendered at the
//! product's size and again 4×4 supersampled (4× wider and taller, box-downsampled in linear
//! RGB), and the difference between them — linear-RGB RMSE, mean luminance ratio — and how much
//! each picture changes when the camera turns by a tenth of a degree (the crawl a moving view
//! shows where sub-pixel detail is point-sampled). `stratus bench --footprint` prints it.
//!
//! Deterministic: every picture of a view is rendered at one fixed exposure (the product
//! render's own metered exposure, frozen, or the one the product fixes), at frame 0's jitter.

use std::path::Path;

use chrono::{DateTime, Utc};
use glam::DVec3;
use serde::Serialize;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::region::Region;
use stratus_ingest::IngestError;

use crate::render::frame::FIXED_EXPOSURE;
use crate::render::{Camera, Output, Preset, RenderError, Renderer, Settings, View};
use crate::scenes::{self, Sample};

/// Supersampling factor each way.
pub const SUPER: u32 = 4;
/// The turn the crawl is measured over (degrees of heading): a third of a pixel at 320×180.
pub const TURN_DEG: f64 = 0.1;

/// One measured view.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub view: String,
    /// Where the camera is (lat, lon, altitude, heading, pitch; or "straight down") and the
    /// Sun's elevation there (degrees).
    pub camera: String,
    pub sun_elevation_deg: Option<f64>,
    pub preset: &'static str,
    pub width: u32,
    pub height: u32,
    /// Linear-RGB RMSE of the product render against the supersampled one (downsampled).
    pub rgb_rmse: f64,
    /// Mean luminance of the product render over the supersampled one's.
    pub luminance_ratio: f64,
    /// Mean per-pixel absolute change (linear RGB, mean over channels) when the heading turns
    /// by [`TURN_DEG`]: of the product render, and of the supersampled render (downsampled).
    /// `None` for the straight-down view, which has no heading.
    pub turn_product: Option<f64>,
    pub turn_super: Option<f64>,
    /// The exposure every picture of the view was rendered at (stops over the fixed daylight
    /// exposure) and where it came from.
    pub exposure_ev: f64,
    pub exposure: &'static str,
    /// Percentage of the supersampled render's rays the driver cut short.
    pub cut_pct: f64,
}

/// A view to measure: where it looks, over which map, at which size and preset.
pub struct Case {
    pub name: String,
    pub view: View,
    pub size: (u32, u32),
    pub settings: Settings,
    /// `Some(ev)`: the product fixes its exposure there; `None`: meter it on the product render.
    pub fixed_ev: Option<f64>,
}

/// The cases over one map.
pub struct MapCases {
    pub map: CloudMap,
    pub cases: Vec<Case>,
}

#[derive(Debug, thiserror::Error)]
pub enum FootprintError {
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Ingest(#[from] IngestError),
    #[error("{0} has no valid time")]
    NoTime(&'static str),
}

/// The East Asia all-layers map of `docs/fly.md`'s window timings (`ingest
/// data-samples/gfs-2011011012-f120-2p5.grib2 --region 0,55,39,105 --size 1300x1100`).
pub fn east_asia() -> Sample {
    Sample {
        file: "data-samples/gfs-2011011012-f120-2p5.grib2",
        region: Region {
            south: 0.0,
            north: 55.0,
            west: 39.0,
            east: 105.0,
        },
        size: (1300, 1100),
        scenes: vec![],
        demo_views: vec![],
    }
}

/// The time-lapse's first step (scripts/gallery-timelapse.sh: the 2015-09-12 18 UTC series'
/// +0 h over 30–70°N, 60°W–40°E at 1024×512). Its first frame is this map at its valid time.
pub fn timelapse() -> Sample {
    Sample {
        file: "data-samples/gfs-series/gfs.t18z.pgrb2.2p50.f000",
        region: Region {
            south: 30.0,
            north: 70.0,
            west: -60.0,
            east: 40.0,
        },
        size: (1024, 512),
        scenes: vec![],
        demo_views: vec![],
    }
}

fn valid(map: &CloudMap, what: &'static str) -> Result<DateTime<Utc>, FootprintError> {
    map.meta
        .source
        .valid_time
        .ok_or(FootprintError::NoTime(what))
}

/// Every case: the window's start view, the time-lapse's 250 km view, the bench's scenes.
pub fn cases(bench_size: (u32, u32)) -> Result<Vec<MapCases>, FootprintError> {
    let mut all = Vec::new();
    // The window's start view: `fly` at its CPU defaults (fast, ¼ of 1280×720).
    let ea = east_asia().map()?;
    let t = valid(&ea, "the East Asia map")?;
    let cam = crate::app::start::start_pilot(&ea, t).camera();
    // At the map's valid time it is night there (the HUD says so); the same view at local
    // solar noon too, the time the HUD suggests.
    let noon = crate::app::daylight::solar_noon(t, cam.lon_deg).unwrap_or(t);
    all.push(MapCases {
        cases: vec![
            Case {
                name: "window start view (East Asia)".into(),
                view: View::Perspective(cam),
                size: (320, 180),
                settings: Settings::new(Preset::Fast, t),
                fixed_ev: None,
            },
            Case {
                name: "window start view at local noon".into(),
                view: View::Perspective(cam),
                size: (320, 180),
                settings: Settings::new(Preset::Fast, noon),
                fixed_ev: None,
            },
        ],
        map: ea,
    });
    // The time-lapse's first frame: 250 km over the Bay of Biscay (docs/flights/
    // natl-timelapse.json), the Sun held and the exposure fixed as the script does.
    let tl = timelapse().map()?;
    let t = valid(&tl, "the time-lapse map")?;
    let mut cam = Camera::new(45.0, -3.0, 250_000.0, 60.0, -50.0);
    cam.fov_deg = 60.0;
    let mut s = Settings::new(Preset::Balanced, t);
    s.sun_override = Some(DVec3::new(0.5, -0.5, 0.7));
    all.push(MapCases {
        cases: vec![Case {
            name: "time-lapse 250 km (North Atlantic)".into(),
            view: View::Perspective(cam),
            size: (480, 270),
            settings: s,
            fixed_ev: Some(0.0),
        }],
        map: tl,
    });
    // The bench's scenes, as `stratus bench` renders them.
    for (sample, names) in [
        (scenes::synthetic(), &crate::bench::SCENES[..]),
        (scenes::terrain(), &crate::bench::TERRAIN_SCENES[..]),
    ] {
        let map = sample.map()?;
        let t = valid(&map, "a bench sample")?;
        let cases = sample
            .scenes_named(names)
            .into_iter()
            .map(|sc| Case {
                name: format!("bench {}", sc.name),
                view: sc.view,
                size: bench_size,
                settings: Settings::new(Preset::Balanced, sc.time.unwrap_or(t)),
                fixed_ev: None,
            })
            .collect();
        all.push(MapCases { map, cases });
    }
    Ok(all)
}

/// Measure every case whose name contains `only` (all: ""); `progress` hears each view's name;
/// with `pictures`, each view's pair of pictures is written there.
pub fn run(
    r: &mut Renderer,
    sets: &[MapCases],
    only: &str,
    pictures: Option<&Path>,
    progress: &dyn Fn(&str),
) -> Result<Vec<Row>, FootprintError> {
    let mut rows = Vec::new();
    for set in sets {
        let cases: Vec<&Case> = set.cases.iter().filter(|c| c.name.contains(only)).collect();
        if cases.is_empty() {
            continue;
        }
        r.set_map(&set.map);
        for c in cases {
            progress(&c.name);
            let row = measure(r, c, pictures)?;
            tracing::info!("{row:?}");
            rows.push(row);
        }
    }
    Ok(rows)
}

/// The sRGB byte as linear light.
pub fn srgb_to_linear(c: u8) -> f64 {
    let c = c as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The picture in linear RGB, box-downsampled by `k` each way (`k` = 1: as it is).
pub fn linear_box(out: &Output, k: u32) -> Vec<[f64; 3]> {
    linear_box_rgba(&out.pixels, out.width, k)
}

/// The same for sRGB RGBA bytes `width` pixels a row.
pub fn linear_box_rgba(pixels: &[u8], width: u32, k: u32) -> Vec<[f64; 3]> {
    let height = (pixels.len() / (4 * width.max(1) as usize)) as u32;
    let (w, h) = (width / k, height / k);
    let mut v = vec![[0.0; 3]; (w * h) as usize];
    let n = (k * k) as f64;
    for y in 0..h * k {
        for x in 0..w * k {
            let i = ((y * width + x) * 4) as usize;
            let o = &mut v[((y / k) * w + x / k) as usize];
            for (c, v) in o.iter_mut().enumerate() {
                *v += srgb_to_linear(pixels[i + c]) / n;
            }
        }
    }
    v
}

/// Linear-RGB RMSE between two pictures of one size.
pub fn rmse(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let se: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>())
        .sum();
    (se / (3 * a.len().max(1)) as f64).sqrt()
}

/// Mean absolute difference per pixel and channel.
pub fn mean_abs(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let s: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs()).sum::<f64>())
        .sum();
    s / (3 * a.len().max(1)) as f64
}

/// Mean Rec. 709 luminance.
pub fn mean_luminance(a: &[[f64; 3]]) -> f64 {
    let s: f64 = a
        .iter()
        .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
        .sum();
    s / a.len().max(1) as f64
}

/// The view turned by `deg` of heading (same position, pitch, field of view and roll); `None`
/// for the straight-down view.
pub fn turned(view: &View, deg: f64) -> Option<View> {
    let View::Perspective(c) = view else {
        return None;
    };
    let f = c.forward_enu.normalize();
    let heading = f.x.atan2(f.y).to_degrees();
    let pitch = f.z.clamp(-1.0, 1.0).asin().to_degrees();
    let mut t = Camera::new(c.lat_deg, c.lon_deg, c.alt_m, heading + deg, pitch);
    t.fov_deg = c.fov_deg;
    t.roll_deg = c.roll_deg;
    Some(View::Perspective(t))
}

/// The settings with the exposure frozen: the case's fixed one, or what the product render
/// meters (one auto-exposed frame at the product's size).
fn frozen_exposure(
    r: &mut Renderer,
    c: &Case,
) -> Result<(Settings, f64, &'static str), RenderError> {
    let mut s = c.settings.clone();
    let (ev, how) = match c.fixed_ev {
        Some(ev) => (ev, "fixed by the product"),
        None => {
            s.exposure_auto = true;
            s.exposure_rate = 1.0;
            r.render(&c.view, c.size.0, c.size.1, &s)?;
            let e = r.read_exposure()?.value as f64;
            (
                (e / FIXED_EXPOSURE).log2(),
                "metered on the product render, frozen",
            )
        }
    };
    s.exposure_auto = false;
    s.exposure_ev = ev;
    Ok((s, ev, how))
}

/// One view: the product render and its supersampled twin, each also turned by [`TURN_DEG`].
/// With `pictures`, the pair is also written there ([`side_by_side`]).
pub fn measure(r: &mut Renderer, c: &Case, pictures: Option<&Path>) -> Result<Row, FootprintError> {
    let (s, ev, how) = frozen_exposure(r, c)?;
    let (w, h) = c.size;
    let product = linear_box(&r.render(&c.view, w, h, &s)?, 1);
    let big = r.render(&c.view, w * SUPER, h * SUPER, &s)?;
    let cut_pct = 100.0 * big.stats.cut_rays as f64 / big.stats.rays.max(1) as f64;
    let sup = linear_box(&big, SUPER);
    if let Some(dir) = pictures {
        side_by_side(
            &dir.join(format!("{}.png", file_name(&c.name))),
            w,
            h,
            &product,
            &sup,
        )?;
    }
    let (turn_product, turn_super) = match turned(&c.view, TURN_DEG) {
        Some(v) => {
            let p = linear_box(&r.render(&v, w, h, &s)?, 1);
            let q = linear_box(&r.render(&v, w * SUPER, h * SUPER, &s)?, SUPER);
            (Some(mean_abs(&product, &p)), Some(mean_abs(&sup, &q)))
        }
        None => (None, None),
    };
    let (camera, sun_elevation_deg) = match &c.view {
        View::Perspective(k) => {
            let f = k.forward_enu.normalize();
            let sun = crate::sun::Sky::at(s.time, k.lat_deg, k.lon_deg).sun_elevation_deg;
            (
                format!(
                    "{:.3}°N {:.3}°E {:.0} m, heading {:.1}°, pitch {:.1}°",
                    k.lat_deg,
                    k.lon_deg,
                    k.alt_m,
                    f.x.atan2(f.y).to_degrees().rem_euclid(360.0),
                    f.z.clamp(-1.0, 1.0).asin().to_degrees()
                ),
                Some(sun),
            )
        }
        View::TopDown => ("straight down".to_string(), None),
    };
    Ok(Row {
        view: c.name.clone(),
        camera,
        sun_elevation_deg,
        preset: preset_name(&s),
        width: w,
        height: h,
        rgb_rmse: rmse(&product, &sup),
        luminance_ratio: mean_luminance(&product) / mean_luminance(&sup).max(1e-12),
        turn_product,
        turn_super,
        exposure_ev: ev,
        exposure: how,
        cut_pct,
    })
}

/// A view's name as a file name: letters and digits, the rest dashes.
fn file_name(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect()
}

/// The product picture (left) beside its box-downsampled supersampled twin (right), both from
/// the linear RGB the table measures, sRGB-encoded: what the RMSE column compares.
fn side_by_side(
    path: &Path,
    w: u32,
    h: u32,
    product: &[[f64; 3]],
    sup: &[[f64; 3]],
) -> Result<(), IngestError> {
    let encode = |v: f64| {
        let s = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (255.0 * s).round().clamp(0.0, 255.0) as u8
    };
    let img = image::RgbaImage::from_fn(2 * w, h, |x, y| {
        let p = if x < w {
            product[(y * w + x) as usize]
        } else {
            sup[(y * w + x - w) as usize]
        };
        image::Rgba([encode(p[0]), encode(p[1]), encode(p[2]), 255])
    });
    crate::picture::save_png(path, &img)
}

fn preset_name(s: &Settings) -> &'static str {
    Preset::ALL
        .iter()
        .find(|p| p.params() == s.march)
        .map_or("custom", |p| p.name())
}

/// A markdown table of the rows.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| view | preset | size | RGB RMSE vs 4×4 | luminance ratio | 0.1° turn (product) | 0.1° turn (4×4) | exposure EV | cut % |\n|---|---|---|---:|---:|---:|---:|---:|---:|\n",
    );
    let f = |v: Option<f64>| v.map_or("–".to_string(), |x| format!("{x:.4}"));
    for r in rows {
        s += &format!(
            "| {} | {} | {}×{} | {:.4} | {:.3} | {} | {} | {:+.2} | {:.2} |\n",
            r.view,
            r.preset,
            r.width,
            r.height,
            r.rgb_rmse,
            r.luminance_ratio,
            f(r.turn_product),
            f(r.turn_super),
            r.exposure_ev,
            r.cut_pct
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{Stats, Timings};

    fn picture(w: u32, h: u32, f: impl Fn(u32, u32) -> u8) -> Output {
        let mut pixels = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let g = f(x, y);
                pixels.extend([g, g, g, 255]);
            }
        }
        Output {
            width: w,
            height: h,
            pixels,
            cloud: vec![[0.0; 4]; (w * h) as usize],
            cut: Vec::new(),
            stats: Stats::default(),
            timings: Timings::default(),
        }
    }

    #[test]
    fn box_downsample_averages_linear_light() {
        // A 2×2 checker of black and white averages to half the linear light, not half the
        // sRGB code (which would be 0.21 linear).
        let o = picture(2, 2, |x, y| if (x + y) % 2 == 0 { 255 } else { 0 });
        let v = linear_box(&o, 2);
        assert_eq!(v.len(), 1);
        assert!((v[0][0] - 0.5).abs() < 1e-12, "{:?}", v[0]);
        assert!((mean_luminance(&v) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn measures_of_equal_and_different_pictures() {
        let a = linear_box(&picture(4, 4, |_, _| 255), 1);
        let b = linear_box(&picture(4, 4, |_, _| 0), 1);
        assert_eq!(rmse(&a, &a), 0.0);
        assert!((rmse(&a, &b) - 1.0).abs() < 1e-12);
        assert!((mean_abs(&a, &b) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_turn_keeps_position_pitch_and_field() {
        let mut c = Camera::new(45.0, -3.0, 250_000.0, 60.0, -50.0);
        c.fov_deg = 50.0;
        let Some(View::Perspective(t)) = turned(&View::Perspective(c), TURN_DEG) else {
            panic!("a perspective view turns");
        };
        let h = |c: &Camera| c.forward_enu.x.atan2(c.forward_enu.y).to_degrees();
        assert!((h(&t) - h(&c) - TURN_DEG).abs() < 1e-9);
        assert!((t.forward_enu.z - c.forward_enu.z).abs() < 1e-12);
        assert_eq!((t.lat_deg, t.alt_m, t.fov_deg), (45.0, 250_000.0, 50.0));
        assert!(turned(&View::TopDown, 1.0).is_none());
    }
}
