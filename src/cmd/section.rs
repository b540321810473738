//! `stratus section`: a vertical cross-section of the rendered cloud along the great circle
//! between two points — altitude against distance, the march's own density evaluated on the
//! GPU (render::section), with the map's per-layer base and top drawn over it and the ground
//! line: the curtain view meteorologists know from Met.3D and lidar.

use std::path::PathBuf;
use std::process::ExitCode;

use glam::DVec3;
use stratus::picture::save_png;
use stratus::render::Renderer;
use stratus::sun::up_at;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::error::shown;
use stratus_ingest::region::parse_size;

use stratus::scene::Scene;

use super::files::check_out;
use super::options::{parse_lat_lon, LookOpts};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// CloudMap sidecar (MAP.json), series sidecar or Zarr store (STORE.zarr).
    #[arg(long)]
    pub map: PathBuf,
    /// Start of the section, LAT,LON in degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub from: String,
    /// End of the section, LAT,LON in degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub to: String,
    /// Output PNG.
    #[arg(long)]
    pub out: PathBuf,
    /// Image size WxH: columns along the path, rows from --top-m down to sea level.
    #[arg(long, default_value = "1200x450")]
    pub size: String,
    /// Altitude of the image's top edge in metres; default: 1 km above the map's highest top.
    #[arg(long)]
    pub top_m: Option<f64>,
    #[command(flatten)]
    pub look: LookOpts,
}

/// Optical depth over this length maps to full white: the picture shows where cloud is and how
/// dense, not how a camera would see it.
const SHADE_LENGTH_M: f32 = 100.0;
const LAYER_COLOURS: [[u8; 3]; 3] = [[255, 150, 40], [90, 220, 90], [90, 170, 255]];
const GROUND: [u8; 3] = [120, 90, 60];

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let scene = Scene::open(&a.map);
    check_out(&a.out, &scene.files())?;
    let from = parse_lat_lon(&a.from, "--from")?;
    let to = parse_lat_lon(&a.to, "--to")?;
    let (w, h) = parse_size(&a.size)?;
    let map = a.look.open_map(scene)?;
    let settings = a.look.settings(&map, &a.map)?;
    let (p0, p1) = (up_at(from.0, from.1), up_at(to.0, to.1));
    let angle = p0.dot(p1).clamp(-1.0, 1.0).acos();
    if !(1e-7..std::f64::consts::PI - 1e-6).contains(&angle) {
        anyhow::bail!(
            "--from {} --to {}: the two points must differ and not be antipodal (the great circle between them is then not one path)",
            a.from,
            a.to
        );
    }
    let top_m = match a.top_m {
        Some(t) if t.is_finite() && t > 0.0 && t <= 100_000.0 => t,
        Some(t) => anyhow::bail!(
            "--top-m {}: must be an altitude in 0 < m ≤ 100000",
            stratus_ingest::meta::show_num(t)
        ),
        None => highest_top(&map) + 1000.0,
    };
    let columns: Vec<DVec3> = (0..w)
        .map(|i| slerp(p0, p1, angle, (i as f64 + 0.5) / w as f64))
        .collect();
    let gpu = a.look.gpu()?;
    // The device's limits before anything is allocated: a validation error after seconds of
    // work is many lines naming no option.
    stratus::render::section::check_fits(&gpu.device.limits(), w, h)
        .map_err(|e| anyhow::anyhow!("--size {}: {e}", a.size))?;
    let mut r = Renderer::new(gpu, &map);
    let sigma = r.section(&columns, h, top_m as f32, &settings)?;
    let mut img = image::RgbaImage::new(w, h);
    for (k, s) in sigma.iter().enumerate() {
        let v = 1.0 - (-s.max(0.0) * SHADE_LENGTH_M).exp();
        let g = (v.sqrt() * 255.0).round() as u8;
        // Dark blue clear air, white cloud.
        let bg = [12u8, 20, 40];
        let px = bg.map(|b| b.saturating_add(((255 - b) as f32 * g as f32 / 255.0) as u8));
        img.put_pixel(
            k as u32 % w,
            k as u32 / w,
            image::Rgba([px[0], px[1], px[2], 255]),
        );
    }
    let row_of = |alt: f64| ((1.0 - alt / top_m) * h as f64 - 0.5).round();
    // Faint altitude lines every 2 km.
    let mut alt = 2000.0;
    while alt < top_m {
        let y = row_of(alt);
        if (0.0..h as f64).contains(&y) {
            for x in (0..w).step_by(4) {
                img.put_pixel(x, y as u32, image::Rgba([70, 80, 100, 255]));
            }
        }
        alt += 2000.0;
    }
    // The map's base and top of each layer where it has cloud; the ground: the map's terrain
    // (sea level where it has none).
    for (x, dir) in columns.iter().enumerate() {
        let (lat, lon) = (dir.z.asin().to_degrees(), dir.y.atan2(dir.x).to_degrees());
        if let Some(p) = map.probe(lat, lon) {
            for l in p.layers.iter().filter(|l| l.coverage > 0.0) {
                let c = LAYER_COLOURS[l.kind.channel()];
                for alt in [l.base_m, l.top_m].into_iter().flatten() {
                    let y = row_of(alt);
                    if (0.0..h as f64).contains(&y) {
                        img.put_pixel(x as u32, y as u32, image::Rgba([c[0], c[1], c[2], 255]));
                    }
                }
            }
        }
        let (terrain_m, _) = map.ground_height_m(lat, lon);
        let ground = row_of(terrain_m).clamp(0.0, h as f64 - 1.0) as u32;
        for y in ground.saturating_sub(1)..h {
            img.put_pixel(
                x as u32,
                y,
                image::Rgba([GROUND[0], GROUND[1], GROUND[2], 255]),
            );
        }
    }
    save_png(&a.out, &img)?;
    let km = angle * stratus::render::camera::EARTH_R / 1000.0;
    out!(
        "{}: section {km:.0} km × 0–{top_m:.0} m from {} to {} over {} ({w}×{h}: {:.1} km and {:.0} m a pixel); base and top lines: low orange, middle green, high blue; ground brown",
        shown(&a.out),
        a.from,
        a.to,
        shown(&a.map),
        km / w as f64,
        top_m / h as f64
    )?;
    Ok(ExitCode::SUCCESS)
}

/// Highest cloud top of the map's layers (m).
fn highest_top(map: &CloudMap) -> f64 {
    map.meta
        .layers
        .iter()
        .map(|l| l.structure.as_ref().map_or(l.top_m, |s| s.top_max_m))
        .fold(0.0, f64::max)
}

/// The point a fraction `t` of the way along the great circle from `a` to `b` (`angle` apart).
fn slerp(a: DVec3, b: DVec3, angle: f64, t: f64) -> DVec3 {
    let s = angle.sin();
    (a * ((1.0 - t) * angle).sin() / s + b * (t * angle).sin() / s).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_path_follows_the_great_circle() {
        let (a, b) = (up_at(0.0, 0.0), up_at(0.0, 90.0));
        let angle = a.dot(b).acos();
        let m = slerp(a, b, angle, 0.5);
        assert!((m - up_at(0.0, 45.0)).length() < 1e-12);
        assert!((slerp(a, b, angle, 0.0) - a).length() < 1e-12);
        assert!((slerp(a, b, angle, 1.0) - b).length() < 1e-12);
    }
}
