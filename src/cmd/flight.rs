//! `stratus flight`: a keyframed path rendered headless to a PNG sequence (and MP4 with ffmpeg).

use std::path::PathBuf;
use std::process::{Command, ExitCode};

use anyhow::Context;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::region::parse_size;

use stratus::flight::FlightPath;
use stratus::picture::save_png;
use stratus::render::{Renderer, View};

use super::options::{progress_bar, LookOpts};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// CloudMap sidecar (MAP.json).
    #[arg(long)]
    pub map: PathBuf,
    /// Keyframed path (JSON; see docs/fly.md).
    #[arg(long)]
    pub path: PathBuf,
    /// Output directory for frame-NNNNN.png (and flight.mp4 when ffmpeg is present).
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value = "640x360")]
    pub size: String,
    /// Frames per second of path time.
    #[arg(long, default_value_t = 10.0)]
    pub fps: f64,
    #[command(flatten)]
    pub look: LookOpts,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let text = std::fs::read_to_string(&a.path).with_context(|| format!("{}", a.path.display()))?;
    let path: FlightPath = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a flight path", a.path.display()))?;
    path.validate()
        .with_context(|| format!("{}", a.path.display()))?;
    if !(a.fps > 0.0 && a.fps <= 240.0) {
        anyhow::bail!("--fps {} must be in (0, 240]", a.fps);
    }
    let map = CloudMap::load(&a.map)?;
    let settings = a.look.settings(&map)?;
    let (w, h) = parse_size(&a.size)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("{}: cannot create", a.out.display()))?;
    let n = (path.duration() * a.fps).floor() as u64 + 1;
    let mut r = Renderer::new(a.look.gpu()?, &map);
    let pb = progress_bar(n, "frames");
    for i in 0..n {
        let (cam, time) = path.at(path.keys[0].t + i as f64 / a.fps);
        let mut s = settings.clone();
        if let Some(t) = time {
            s.time = t;
        }
        s.frame_index = i as u32;
        let out = r.render(&View::Perspective(cam), w, h, &s)?;
        let file = a.out.join(format!("frame-{i:05}.png"));
        save_png(&file, &out.to_image()).with_context(|| file.display().to_string())?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    println!("{n} frames in {}", a.out.display());
    let ffmpeg = Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_ok_and(|o| o.status.success());
    if ffmpeg {
        let mp4 = a.out.join("flight.mp4");
        let status = Command::new("ffmpeg")
            .args([
                "-y",
                "-loglevel",
                "error",
                "-framerate",
                &a.fps.to_string(),
                "-i",
            ])
            .arg(a.out.join("frame-%05d.png"))
            .args([
                "-pix_fmt",
                "yuv420p",
                "-vf",
                "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            ])
            .arg(&mp4)
            .status()?;
        if status.success() {
            println!("{}", mp4.display());
        } else {
            eprintln!("ffmpeg failed; the PNG frames are complete");
        }
    } else {
        println!("(ffmpeg not found: PNG frames only)");
    }
    Ok(ExitCode::SUCCESS)
}
