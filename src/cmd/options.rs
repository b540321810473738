//! Options and parsers the commands share: how to look (preset, time, Sun, layers), how to
//! ingest, numbers and times on the command line, progress bars.

use std::path::Path;

use anyhow::Context;
use chrono::{DateTime, Utc};
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use stratus::render::{defaults, gpu, Camera, Gpu, Preset, Settings};
use stratus::scene::Scene;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::ground::GroundSource;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::pipeline::{validate_rh_cr, IngestOptions, Plan};
use stratus_ingest::region::{parse_size, Region};
use stratus_ingest::spline::Interp;

/// Look and light options shared by every command that renders.
#[derive(clap::Args, Debug, Clone)]
pub struct LookOpts {
    /// Quality preset: fast, balanced, high or reference.
    #[arg(long, default_value = "balanced")]
    pub preset: Preset,
    /// UTC time for the Sun and Moon (ISO 8601, e.g. 2011-01-15T06:00:00Z), and with a series
    /// the weather's moment (blended between the two steps around it); default: the map's
    /// valid time (a series' first step).
    #[arg(long)]
    pub time: Option<String>,
    /// Sun direction E,N,U in the camera's local frame, instead of the computed one.
    #[arg(long, allow_hyphen_values = true)]
    pub sun_dir: Option<String>,
    /// Exposure: `auto` adapts to the scene (metered each frame, from ½ stop under to 3 over the
    /// Sun's-height exposure); a number of stops fixes it (over a daylight exposure), so pictures
    /// can be compared by luminance.
    #[arg(long, default_value = "auto", allow_hyphen_values = true, value_parser = parse_exposure)]
    pub exposure: Exposure,
    /// Meteorological visibility in km (aerial haze).
    #[arg(long, default_value_t = defaults::VISIBILITY_M / 1000.0)]
    pub visibility_km: f64,
    /// Coverage multiplier.
    #[arg(long, default_value_t = defaults::COVERAGE_MUL)]
    pub coverage: f32,
    /// Density multiplier.
    #[arg(long, default_value_t = defaults::DENSITY_MUL)]
    pub density: f32,
    /// Layers to draw, e.g. low,middle,high.
    #[arg(long, default_value = "low,middle,high")]
    pub layers: String,
    /// Adapter to use: any part of its name (see the line printed on start).
    #[arg(long)]
    pub adapter: Option<String>,
}

/// `--exposure`: adapted to the scene, or fixed at a number of stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    Auto,
    Fixed(f64),
}

fn parse_exposure(s: &str) -> Result<Exposure, String> {
    if s == "auto" {
        return Ok(Exposure::Auto);
    }
    match s.parse::<f64>() {
        Ok(ev) if ev.is_finite() => Ok(Exposure::Fixed(ev)),
        _ => Err(format!("\"{s}\" is neither `auto` nor a number of stops")),
    }
}

/// Parse a comma-separated list of exactly `n` numbers.
pub fn parse_numbers(s: &str, n: usize, what: &str) -> anyhow::Result<Vec<f64>> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|p| p.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if v.len() == n && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => anyhow::bail!("{what} \"{s}\" must be {n} comma-separated numbers"),
    }
}

/// Longitudes a point may be given at: either convention (−180..180, 0..360) and a turn
/// beyond it either way, as the region's west..east may be written.
pub const LON_LIMIT: f64 = 360.0;

/// A point `LAT,LON` in degrees on the command line (`--at`, `--from`, `--to`, the first two
/// parts of `--camera`): the one parser. The latitude within ±90, the longitude within
/// ±[`LON_LIMIT`], both finite; the error names `flag` and the value.
pub fn parse_lat_lon(s: &str, flag: &str) -> anyhow::Result<(f64, f64)> {
    let v = parse_numbers(s, 2, flag)
        .map_err(|_| anyhow::anyhow!("{flag} \"{s}\" must be LAT,LON in degrees"))?;
    check_lat_lon(v[0], v[1], flag, s)?;
    Ok((v[0], v[1]))
}

/// Check a point's latitude and longitude (finite, within ±90 and ±[`LON_LIMIT`]).
fn check_lat_lon(lat: f64, lon: f64, flag: &str, s: &str) -> anyhow::Result<()> {
    use stratus_ingest::meta::show_num;
    if !(-90.0..=90.0).contains(&lat) {
        anyhow::bail!(
            "{flag} \"{s}\": latitude {} is outside -90..90",
            show_num(lat)
        );
    }
    if !(-LON_LIMIT..=LON_LIMIT).contains(&lon) {
        anyhow::bail!(
            "{flag} \"{s}\": longitude {} is outside -{LON_LIMIT}..{LON_LIMIT}",
            show_num(lon)
        );
    }
    Ok(())
}

/// A time on the command line: the sidecar's one parser (ISO 8601, without a zone read as UTC).
pub fn parse_time(s: &str) -> anyhow::Result<DateTime<Utc>> {
    Ok(stratus_ingest::meta::parse_time(s)?)
}

impl LookOpts {
    /// `--time`, parsed: the scene's moment (the Sun's, and a series' weather).
    pub fn moment(&self) -> anyhow::Result<Option<DateTime<Utc>>> {
        self.time.as_deref().map(parse_time).transpose()
    }

    /// The map `--map` names at `--time`: a series' moment (its first step without a time) or
    /// a plain CloudMap ([`Scene::map_at`]).
    pub fn open_map(&self, scene: Scene) -> anyhow::Result<CloudMap> {
        Ok(scene.map_at(self.moment()?)?)
    }

    /// The settings for `map`, read from `source` (its sidecar, or the GRIB file it was
    /// ingested from in memory), which errors about the map name.
    pub fn settings(&self, map: &CloudMap, source: &Path) -> anyhow::Result<Settings> {
        let time = match &self.time {
            Some(t) => parse_time(t)?,
            None => map.meta.source.valid_time.with_context(|| {
                format!(
                    "{}: the map has no valid_time: give --time",
                    stratus_ingest::error::shown(source)
                )
            })?,
        };
        let mut s = Settings::new(self.preset, time);
        if let Some(d) = &self.sun_dir {
            let v = parse_numbers(d, 3, "--sun-dir")?;
            s.sun_override = Some(DVec3::new(v[0], v[1], v[2]));
        }
        match self.exposure {
            Exposure::Auto => s.exposure_auto = true,
            Exposure::Fixed(ev) => {
                s.exposure_auto = false;
                s.exposure_ev = ev;
            }
        }
        s.visibility_m = self.visibility_km * 1000.0;
        s.coverage_mul = self.coverage;
        s.density_mul = self.density;
        s.layers_on = [false; 3];
        for name in self
            .layers
            .split(',')
            .map(str::trim)
            .filter(|n| !n.is_empty())
        {
            let kind = LayerKind::ALL
                .into_iter()
                .find(|k| k.name() == name || (name == "mid" && *k == LayerKind::Middle));
            let kind = kind.ok_or_else(|| {
                anyhow::anyhow!("--layers: unknown layer \"{name}\" (low, middle, high)")
            })?;
            s.layers_on[kind.channel()] = true;
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

/// Eye height of `--camera LAT,LON,ground`: a person standing on the terrain.
pub const EYE_HEIGHT_M: f64 = 2.0;

/// How high `--camera` puts the eye.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CameraAlt {
    /// Metres above mean sea level (`LAT,LON,ALT_M`).
    Sea(f64),
    /// Metres above the terrain there (`LAT,LON,ground` = [`EYE_HEIGHT_M`], `LAT,LON,ground+N`).
    Ground(f64),
}

/// `--camera LAT,LON,ALT_M | LAT,LON,ground | LAT,LON,ground+N`, read without the map.
pub fn parse_camera_spec(s: &str) -> anyhow::Result<(f64, f64, CameraAlt)> {
    let bad = || {
        anyhow::anyhow!(
            "--camera \"{s}\" must be LAT,LON,ALT_M (metres above sea level), LAT,LON,ground or LAT,LON,ground+N (N metres above the terrain)"
        )
    };
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [lat, lon, alt] = parts[..] else {
        return Err(bad());
    };
    let num = |x: &str| x.parse::<f64>().ok().filter(|v| v.is_finite());
    let (lat, lon) = (num(lat).ok_or_else(bad)?, num(lon).ok_or_else(bad)?);
    check_lat_lon(lat, lon, "--camera", s)?;
    let alt = match alt.strip_prefix("ground") {
        Some("") => CameraAlt::Ground(EYE_HEIGHT_M),
        Some(rest) => {
            let n = rest.strip_prefix('+').and_then(num).ok_or_else(bad)?;
            if n < 0.0 {
                return Err(bad());
            }
            CameraAlt::Ground(n)
        }
        None => CameraAlt::Sea(num(alt).ok_or_else(bad)?),
    };
    Ok((lat, lon, alt))
}

/// The camera `--camera` names over `map`: `ground` altitudes are taken from the map's terrain
/// there ([`CloudMap::ground_height_m`]: sea level where it has none), and a camera below the
/// terrain is refused, naming both heights.
pub fn parse_camera(
    s: &str,
    heading: f64,
    pitch: f64,
    fov: f64,
    map: &CloudMap,
) -> anyhow::Result<Camera> {
    let (lat, lon, alt) = parse_camera_spec(s)?;
    let (ground, source) = map.ground_height_m(lat, lon);
    let alt_m = match alt {
        CameraAlt::Sea(m) => m,
        CameraAlt::Ground(n) => ground + n,
    };
    if alt_m < ground {
        use stratus_ingest::meta::show_num;
        // Whole metres, decimetres under one (a camera 0.3 m under is not "0 m below").
        let m = |x: f64| match x.abs() {
            a if a > 0.0 && a < 0.5 => format!("{:.1}", (x * 10.0).round() / 10.0 + 0.0),
            a if a < 1e9 => format!("{:.0}", x.round() + 0.0),
            _ => show_num(x),
        };
        anyhow::bail!(
            "--camera {s}: the camera at {} m is {} m below the ground there, which is at {} m ({}); give an altitude above it, or LAT,LON,ground+N",
            m(alt_m),
            m(ground - alt_m),
            m(ground),
            match source {
                GroundSource::Orography => "the map's terrain from the forecast's orography",
                GroundSource::None => "sea level",
            }
        );
    }
    camera(lat, lon, alt_m, heading, pitch, fov)
}

/// A checked camera at a position, looking along heading and pitch, with a field of view.
pub fn camera(
    lat: f64,
    lon: f64,
    alt_m: f64,
    heading: f64,
    pitch: f64,
    fov: f64,
) -> anyhow::Result<Camera> {
    // Named as given: a NaN heading would otherwise surface as a view direction of zero length.
    for (name, v) in [("--heading", heading), ("--pitch", pitch), ("--fov", fov)] {
        if !v.is_finite() {
            anyhow::bail!("{name} {v} must be a finite number");
        }
    }
    let mut cam = Camera::new(lat, lon, alt_m, heading, pitch);
    cam.fov_deg = fov;
    cam.validate()?;
    Ok(cam)
}

/// How to turn a forecast file into a CloudMap.
#[derive(clap::Args, Debug, Clone)]
pub struct IngestOpts {
    /// Region as S,N,W,E in degrees (longitudes -180..180 or 0..360; W > E crosses the date line).
    #[arg(long, allow_hyphen_values = true)]
    pub region: Option<String>,
    /// Output size WxH in pixels (each side 1..=8192, what the renderer can upload).
    #[arg(long, default_value = "1024x1024")]
    pub size: String,
    /// One isobaric level in hPa (the paper's case); default: all levels folded into layers.
    #[arg(long)]
    pub level: Option<f64>,
    /// Highest level (lowest pressure, hPa) folded into the layers when --level is not given.
    #[arg(long, default_value_t = DEFAULT_TOP_HPA)]
    pub top_hpa: f64,
    /// Critical humidity for every layer (fraction, 0 ≤ x < 1).
    #[arg(long, allow_negative_numbers = true)]
    pub rh_cr: Option<f64>,
    /// Critical humidity of the low layer.
    #[arg(long, default_value_t = LayerKind::Low.default_rh_cr())]
    pub rh_cr_low: f64,
    /// Critical humidity of the middle layer.
    #[arg(long, default_value_t = LayerKind::Middle.default_rh_cr())]
    pub rh_cr_mid: f64,
    /// Critical humidity of the high layer.
    #[arg(long, default_value_t = LayerKind::High.default_rh_cr())]
    pub rh_cr_high: f64,
    /// spline | catmull-rom | bilinear | nearest.
    #[arg(long, default_value = "spline")]
    pub interp: Interp,
}

impl IngestOpts {
    pub fn options(&self) -> anyhow::Result<IngestOptions> {
        let region = Region::parse(
            self.region
                .as_deref()
                .ok_or_else(|| anyhow::anyhow!("--region S,N,W,E is required to ingest"))?,
        )?;
        self.options_over(region, parse_size(&self.size)?)
    }

    /// These options over a region and size given by the caller (a file dropped on the window).
    pub fn options_over(
        &self,
        region: Region,
        (width, height): (u32, u32),
    ) -> anyhow::Result<IngestOptions> {
        let rh_cr = match self.rh_cr {
            Some(x) => [x; 3],
            None => [self.rh_cr_low, self.rh_cr_mid, self.rh_cr_high],
        };
        for x in rh_cr {
            validate_rh_cr(x)?;
        }
        Ok(IngestOptions {
            region,
            width,
            height,
            rh_cr,
            interp: self.interp,
        })
    }

    pub fn select(&self) -> LevelSelect {
        match self.level {
            Some(p) => LevelSelect::One(p),
            None => LevelSelect::AllBelow(self.top_hpa),
        }
    }

    /// Validate the options, read the file and prepare the resampling.
    pub fn plan(&self, file: &Path) -> anyhow::Result<Plan> {
        self.plan_with(file, self.options()?)
    }

    /// Like [`IngestOpts::plan`] over a given region and size.
    pub fn plan_over(&self, file: &Path, region: Region, size: (u32, u32)) -> anyhow::Result<Plan> {
        self.plan_with(file, self.options_over(region, size)?)
    }

    fn plan_with(&self, file: &Path, opts: IngestOptions) -> anyhow::Result<Plan> {
        let fc = Forecast::open(file, self.select())?;
        Ok(Plan::new(&fc, &opts)?)
    }
}

/// A bar on stderr for long work; hidden when stderr is not a terminal.
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}
