//! `stratus fly`: open the window over a CloudMap or a GRIB2 file.

use std::path::PathBuf;
use std::process::ExitCode;

use stratus_ingest::region::parse_size;

use stratus::app::moment::Rate;
use stratus::app::{fly, FlyOptions};
use stratus::follow::{Follower, Source};
use stratus::render::Preset;
use stratus::scene::Scene;

use super::files::check_out;
use super::options::{parse_time, progress_bar, IngestOpts};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A CloudMap sidecar (MAP.json) or a GRIB2 forecast (with --region and the ingest options).
    pub input: PathBuf,
    #[command(flatten)]
    pub ingest: IngestOpts,
    /// Window size WxH.
    #[arg(long = "window", default_value = "1280x720")]
    pub window: String,
    /// Quality preset: fast, balanced, high or reference.
    #[arg(long, default_value = "fast")]
    pub preset: Preset,
    /// Adapter to use (any part of its name).
    #[arg(long)]
    pub adapter: Option<String>,
    /// Render this many frames, then exit (with --screenshot: save the last one).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Follow a simulator's aircraft: xplane[:PORT] (UDP 49003) or flightgear[:PORT] (5505).
    #[arg(long)]
    pub follow: Option<String>,
    /// UTC time the window starts at (ISO 8601, e.g. 2015-09-12T21:00:00Z): the Sun's, and with
    /// a series the weather's moment (blended between the two steps around it); default: the
    /// map's valid time (a series' first step).
    #[arg(long)]
    pub time: Option<String>,
    /// How fast time runs from the start: pause, 1, 60 or 600 (simulated seconds per second;
    /// the panel changes it).
    #[arg(long, default_value = "pause")]
    pub time_rate: Rate,
    /// Temporal reprojection: each frame marches one pixel of each subset cell (the preset's
    /// size) and reprojects the rest from the frames before: on or off.
    #[arg(long, default_value = "on", action = clap::ArgAction::Set, value_parser = parse_on_off)]
    pub reprojection: bool,
    /// The march's size relative to the window, 0.05..1 (default: 1 on a GPU, ¼ on a CPU
    /// adapter).
    #[arg(long)]
    pub render_scale: Option<f32>,
    /// Temporal super-resolution (issue 30): at a render scale under 1 with reprojection, march
    /// the same number of rays a frame but at the window's own size, one pixel of each (n /
    /// scale)² cell, so a still view converges to the full-resolution picture: on or off. Off
    /// by default: on lavapipe it costs 1.5–3× the frame time of the enlarged march
    /// (docs/footprint.md).
    #[arg(long, default_value = "off", action = clap::ArgAction::Set, value_parser = parse_on_off)]
    pub super_resolution: bool,
    /// Meteorological visibility in km (aerial haze; the panel changes it).
    #[arg(long, default_value_t = stratus::render::defaults::VISIBILITY_M / 1000.0)]
    pub visibility_km: f64,
    /// Play a keyframed flight path (the `flight` command's JSON) in real time, looping: the
    /// camera follows it instead of the keyboard.
    #[arg(long, conflicts_with = "follow")]
    pub path: Option<PathBuf>,
    /// Where --frames saves its last frame (PNG).
    #[arg(long, requires = "frames")]
    pub screenshot: Option<PathBuf>,
}

/// `on` or `off`.
pub fn parse_on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("\"{s}\" is neither `on` nor `off`")),
    }
}

fn is_json(p: &std::path::Path) -> bool {
    p.extension().and_then(|e| e.to_str()) == Some("json")
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if a.frames == Some(0) {
        anyhow::bail!("--frames must be at least 1");
    }
    // A sidecar is a scene; anything else a GRIB2 file ingested in memory.
    let scene = is_json(&a.input).then(|| Scene::open(&a.input));
    if let Some(shot) = &a.screenshot {
        let inputs = match &scene {
            Some(s) => s.files(),
            None => vec![a.input.clone()],
        };
        check_out(shot, &inputs)?;
    }
    let size = parse_size(&a.window)?;
    if let Some(r) = a.render_scale.filter(|r| !(0.05..=1.0).contains(r)) {
        anyhow::bail!("--render-scale {r} must be in 0.05..=1");
    }
    if !(a.visibility_km.is_finite() && a.visibility_km > 0.0) {
        anyhow::bail!(
            "--visibility-km {} must be a positive number",
            a.visibility_km
        );
    }
    // Bound before the window opens: a port in use is a one-line error, not a window.
    let follow = match &a.follow {
        Some(s) => Some(Follower::bind(s.parse::<Source>()?)?),
        None => None,
    };
    if let Some(f) = &follow {
        let s = f.source();
        eprintln!(
            "listening for {} on UDP port {} (the HUD counts its packets): {}",
            s.kind.name(),
            s.port,
            s.setup_hint()
        );
    }
    let time = a.time.as_deref().map(parse_time).transpose()?;
    let path = a
        .path
        .as_deref()
        .map(stratus::flight::FlightPath::load)
        .transpose()?;
    let (map, plan, timeline) = if let Some(scene) = scene {
        let (map, timeline) = scene.for_renderer(time)?;
        (map, None, timeline)
    } else {
        let plan = a.ingest.plan(&a.input)?;
        let pb = progress_bar(1, "ingest");
        let map = plan.build();
        pb.finish_and_clear();
        (map, Some(plan), None)
    };
    let base = a.ingest.clone();
    let ingest_dropped = Box::new(move |p: &std::path::Path, region, size| {
        let plan = base.plan_over(p, region, size)?;
        Ok((plan.build(), plan))
    });
    fly(FlyOptions {
        map,
        plan,
        size,
        preset: a.preset,
        adapter: a.adapter,
        frames: a.frames,
        screenshot: a.screenshot,
        ingest_dropped,
        follow,
        time,
        time_rate: a.time_rate,
        timeline,
        reprojection: a.reprojection,
        render_scale: a.render_scale,
        super_resolution: a.super_resolution,
        visibility_km: a.visibility_km,
        path,
    })?;
    Ok(ExitCode::SUCCESS)
}
