//! `stratus render`: one frame of a CloudMap to PNG, headless.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use crate::render::{gpu, Camera, Gpu, Preset, Renderer, Settings, View};
use anyhow::Context;
use chrono::{DateTime, Utc};
use glam::DVec3;
use stratus_ingest::cloudmap::{write_atomic, CloudMap};
use stratus_ingest::region::parse_size;

/// Look and light options shared by every command that renders.
#[derive(clap::Args, Debug, Clone)]
pub struct LookOpts {
    /// Quality preset.
    #[arg(long, value_enum, default_value = "balanced")]
    pub preset: Preset,
    /// UTC time for the Sun and Moon (ISO 8601, e.g. 2011-01-15T06:00:00Z); default: the map's valid time.
    #[arg(long)]
    pub time: Option<String>,
    /// Sun direction E,N,U in the camera's local frame, instead of the computed one.
    #[arg(long, allow_hyphen_values = true)]
    pub sun_dir: Option<String>,
    /// Exposure correction in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f64,
    /// Meteorological visibility in km (aerial haze).
    #[arg(long, default_value_t = 60.0)]
    pub visibility_km: f64,
    /// Coverage multiplier.
    #[arg(long, default_value_t = 1.0)]
    pub coverage: f32,
    /// Density multiplier.
    #[arg(long, default_value_t = 1.0)]
    pub density: f32,
    /// Layers to draw, e.g. low,middle,high.
    #[arg(long, default_value = "low,middle,high")]
    pub layers: String,
    /// Adapter to use: any part of its name (see the line printed on start).
    #[arg(long)]
    pub adapter: Option<String>,
}

/// Parse a comma-separated list of exactly `n` numbers.
pub fn parse_numbers(s: &str, n: usize, what: &str) -> anyhow::Result<Vec<f64>> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|p| p.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if v.len() == n && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => anyhow::bail!("{what} \"{s}\" must be {n} comma-separated numbers"),
    }
}

pub fn parse_time(s: &str) -> anyhow::Result<DateTime<Utc>> {
    DateTime::parse_from_rfc3339(s)
        .map(|d| d.with_timezone(&Utc))
        .or_else(|_| {
            chrono::NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M:%S").map(|n| n.and_utc())
        })
        .or_else(|_| {
            chrono::NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M").map(|n| n.and_utc())
        })
        .with_context(|| format!("time \"{s}\" is not ISO 8601 (e.g. 2011-01-15T06:00:00Z)"))
}

impl LookOpts {
    pub fn settings(&self, map: &CloudMap) -> anyhow::Result<Settings> {
        let time = match &self.time {
            Some(t) => parse_time(t)?,
            None => parse_time(&map.meta.source.valid_time)
                .with_context(|| "the map's valid time is unreadable: give --time".to_string())?,
        };
        let mut s = Settings::new(self.preset, time);
        if let Some(d) = &self.sun_dir {
            let v = parse_numbers(d, 3, "--sun-dir")?;
            s.sun_override = Some(DVec3::new(v[0], v[1], v[2]));
        }
        s.exposure_ev = self.exposure;
        s.visibility_m = self.visibility_km * 1000.0;
        s.coverage_mul = self.coverage;
        s.density_mul = self.density;
        s.layers_on = [false; 3];
        for name in self.layers.split(',').map(str::trim) {
            let k = match name {
                "low" => 0,
                "middle" | "mid" => 1,
                "high" => 2,
                "" => continue,
                other => anyhow::bail!("--layers: unknown layer \"{other}\" (low, middle, high)"),
            };
            s.layers_on[k] = true;
        }
        s.validate()?;
        Ok(s)
    }

    /// Open the GPU, saying which adapter it is.
    pub fn gpu(&self) -> anyhow::Result<Gpu> {
        let gpu = Gpu::new(self.adapter.as_deref())?;
        eprintln!(
            "stratus: adapter {}{}",
            gpu::describe(&gpu.info),
            if gpu.is_cpu() {
                " — a CPU driver: expect seconds per frame"
            } else {
                ""
            }
        );
        Ok(gpu)
    }
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// CloudMap sidecar (MAP.json) written by `stratus ingest`.
    #[arg(long)]
    pub map: PathBuf,
    /// Camera position LAT,LON,ALT_M (degrees, degrees, metres above sea level).
    #[arg(long, allow_hyphen_values = true, required_unless_present = "top_down")]
    pub camera: Option<String>,
    /// Render the map's whole region straight down (orthographic, what `score` compares).
    #[arg(long)]
    pub top_down: bool,
    /// Heading, degrees clockwise from north.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub heading: f64,
    /// Pitch, degrees up from the horizon (negative looks down).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pitch: f64,
    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 60.0)]
    pub fov: f64,
    /// Output size WxH.
    #[arg(long, default_value = "1280x720")]
    pub size: String,
    #[command(flatten)]
    pub look: LookOpts,
    /// Output PNG.
    #[arg(long)]
    pub out: PathBuf,
    /// Print GPU time per pass (timestamp queries where the adapter has them) and work counters.
    #[arg(long)]
    pub timings: bool,
    /// Render this many times and report the median (a first frame pays for warm-up).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeat: u32,
}

pub fn parse_camera(s: &str, heading: f64, pitch: f64, fov: f64) -> anyhow::Result<Camera> {
    let v = parse_numbers(s, 3, "--camera")?;
    let mut cam = Camera::new(v[0], v[1], v[2], heading, pitch);
    cam.fov_deg = fov;
    cam.validate()?;
    Ok(cam)
}

/// Write an RGBA8 image as PNG through a temporary file.
pub fn save_png(path: &Path, img: &image::RgbaImage) -> anyhow::Result<()> {
    write_png(
        path,
        img.as_raw(),
        img.width(),
        img.height(),
        image::ExtendedColorType::Rgba8,
    )
}

/// Write raw 8-bit pixels as PNG through a temporary file, so no half-written file is left.
pub fn write_png(
    path: &Path,
    raw: &[u8],
    width: u32,
    height: u32,
    color: image::ExtendedColorType,
) -> anyhow::Result<()> {
    write_atomic(path, |w| {
        image::codecs::png::PngEncoder::new(w)
            .write_image(raw, width, height, color)
            .map_err(|e| e.to_string())
    })?;
    Ok(())
}

use image::ImageEncoder;

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let map = CloudMap::load(&a.map)?;
    let settings = a.look.settings(&map)?;
    let view = match (&a.camera, a.top_down) {
        (_, true) => View::TopDown,
        (Some(c), false) => View::Perspective(parse_camera(c, a.heading, a.pitch, a.fov)?),
        (None, false) => anyhow::bail!("--camera LAT,LON,ALT_M or --top-down is required"),
    };
    let (w, h) = parse_size(&a.size)?;
    let mut r = Renderer::new(a.look.gpu()?, &map);
    let mut out = r.render(&view, w, h, &settings)?;
    if a.repeat > 1 {
        let mut runs = Vec::new();
        for _ in 0..a.repeat {
            runs.push(r.render(&view, w, h, &settings)?);
        }
        runs.sort_by(|x, y| x.timings.wall_ms.total_cmp(&y.timings.wall_ms));
        out = runs.swap_remove(runs.len() / 2);
    }
    save_png(&a.out, &out.to_image()).with_context(|| format!("{}", a.out.display()))?;
    if a.timings {
        print_timings(&out);
    }
    Ok(ExitCode::SUCCESS)
}

/// GPU times are absent where the adapter has no (trustworthy) timestamps: CPU drivers.
pub fn print_timings(out: &crate::render::Output) {
    let t = out.timings;
    let f = |v: Option<f64>| {
        v.map_or("n/a (no GPU timestamps: see wall)".to_string(), |v| {
            format!("{v:.3} ms")
        })
    };
    println!(
        "march {}  present {}  wall {:.1} ms  ({}×{})",
        f(t.march_ms),
        f(t.present_ms),
        t.wall_ms,
        out.width,
        out.height
    );
    let s = out.stats;
    let px = s.rays.max(1) as f64;
    println!(
        "per pixel: {:.1} steps, {:.1} density samples, {:.1} light samples; skipped {}, early exits {}, samples outside region {}, rays cut short {}",
        s.steps as f64 / px,
        s.density_samples as f64 / px,
        s.light_samples as f64 / px,
        s.skipped_steps,
        s.early_exits,
        s.outside_samples,
        s.cut_rays
    );
}
