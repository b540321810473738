//! `stratus render`: one frame of a CloudMap to PNG, headless ([`frame`]: the picture itself,
//! which the Python package's `render` returns).

use std::path::PathBuf;
use std::process::ExitCode;

use stratus::picture::save_png;
use stratus::render::{Renderer, View};
use stratus_ingest::region::parse_size;

use stratus::scene::Scene;

use super::files::check_out;
use super::options::{parse_camera, LookOpts};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub frame: FrameArgs,
    /// Output PNG.
    #[arg(long)]
    pub out: PathBuf,
}

/// Every flag of `stratus render` but `--out`: what makes the frame ([`frame`]; the Python
/// package's `render` takes these and gets the pixels).
#[derive(clap::Args, Debug)]
pub struct FrameArgs {
    /// CloudMap sidecar (MAP.json), series sidecar or Zarr store (STORE.zarr) written by
    /// `stratus ingest`.
    #[arg(long)]
    pub map: PathBuf,
    /// Camera position LAT,LON,ALT_M (degrees, degrees, metres above sea level), or
    /// LAT,LON,ground (2 m above the map's terrain) or LAT,LON,ground+N (N m above it). A
    /// camera below the terrain is refused.
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
    /// Print GPU time per pass (timestamp queries where the adapter has them) and work counters.
    #[arg(long)]
    pub timings: bool,
    /// Render this many times and report the median (a first frame pays for warm-up).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeat: u32,
    /// Temporal reprojection: a single frame has no history and marches every pixel; with
    /// --repeat, `on` makes each frame after the first march the preset's subset and reproject
    /// the rest from the frame before, as the window does (for timing it).
    #[arg(long, default_value = "off", action = clap::ArgAction::Set, value_parser = super::fly::parse_on_off)]
    pub reprojection: bool,
    /// March at this fraction of --size (0.05..=1) and enlarge the march to --size in the
    /// present pass, as the window does at its render scale (`fly --render-scale`; a CPU
    /// adapter's window defaults to 0.25): the window's picture, headless. With --reprojection
    /// on the first frame is the fresh subset, as in the window.
    #[arg(long, default_value_t = 1.0)]
    pub render_scale: f32,
    /// With --render-scale under 1 and --reprojection on: the window's `--super-resolution`
    /// (marched at --size in cells of the preset's side over the scale; `fast` at 0.25: one
    /// pixel of each 16×16 a frame) instead of the march at the scale enlarged.
    #[arg(long, default_value = "off", action = clap::ArgAction::Set, value_parser = super::fly::parse_on_off)]
    pub super_resolution: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let scene = Scene::open(&a.frame.map);
    check_out(&a.out, &scene.files())?;
    frame(&a.frame, scene, |img| Ok(save_png(&a.out, img)?))?;
    Ok(ExitCode::SUCCESS)
}

/// The frame `a` asks for, rendered from `scene` and read back: the RGBA8 picture `stratus
/// render` writes to PNG. `done` takes it before --timings prints (the command saves it there).
pub fn frame(
    a: &FrameArgs,
    scene: Scene,
    done: impl FnOnce(&image::RgbaImage) -> anyhow::Result<()>,
) -> anyhow::Result<image::RgbaImage> {
    // A series is blended on the GPU (the two steps around --time), as `flight` does.
    let (map, mut timeline) = scene.for_renderer(a.look.moment()?)?;
    let mut settings = a.look.settings(&map, &a.map)?;
    if a.reprojection {
        // At a render scale under 1 the window's own rule: its first frame is the fresh subset
        // (the window never marches every pixel).
        let full_reset = a.render_scale >= 1.0;
        settings.reprojection = stratus::render::Reprojection::On { full_reset };
    }
    let view = match (&a.camera, a.top_down) {
        (_, true) => View::TopDown,
        (Some(c), false) => View::Perspective(parse_camera(c, a.heading, a.pitch, a.fov, &map)?),
        (None, false) => anyhow::bail!("--camera LAT,LON,ALT_M or --top-down is required"),
    };
    let (w, h) = parse_size(&a.size)?;
    if !(0.05..=1.0).contains(&a.render_scale) {
        anyhow::bail!("--render-scale {} must be in 0.05..=1", a.render_scale);
    }
    let mut r = Renderer::new(a.look.gpu()?, &map);
    if let Some(tl) = &mut timeline {
        // One frame: the step after the two around --time is never needed.
        tl.load_ahead = false;
        settings.drift_m = tl.prepare(&mut r, settings.time)?;
        settings.streak_wind = Some(tl.streak_wind());
    }
    if a.render_scale < 1.0 {
        return scaled(a, &mut r, &view, (w, h), &settings, done);
    }
    let mut out = r.render(&view, w, h, &settings)?;
    if a.repeat > 1 {
        let mut runs = Vec::new();
        for i in 1..=a.repeat {
            let mut s = settings.clone();
            if a.reprojection {
                // The window's frames count on (each its own jitter), as in `scaled`.
                s.frame_index = settings.frame_index.wrapping_add(i);
            }
            runs.push(r.render(&view, w, h, &s)?);
        }
        let mut order: Vec<usize> = (0..runs.len()).collect();
        order.sort_by(|&x, &y| runs[x].timings.wall_ms.total_cmp(&runs[y].timings.wall_ms));
        let median = order[order.len() / 2];
        let timings = runs[median].timings;
        // With --reprojection on the picture is the last frame, the one the history has
        // built up (the median frame's was whichever the clock picked); the timings are the
        // median frame's either way.
        let shown = if a.reprojection {
            runs.len() - 1
        } else {
            median
        };
        out = runs.swap_remove(shown);
        out.timings = timings;
    }
    let img = out.to_image();
    done(&img)?;
    if a.timings {
        print_timings(&out)?;
        if let Some(v) = r.last_march_variant() {
            out!("genus code in the march: {}", v.describe_genera())?;
        }
        if let Some(tl) = &timeline {
            out!(
                "series: {} of {} step maps decoded",
                tl.decoded(),
                tl.series.steps().len()
            )?;
        }
    }
    Ok(img)
}

/// `--render-scale` below 1: each frame made as the window makes it (`scaled::plan`).
fn scaled(
    a: &FrameArgs,
    r: &mut Renderer,
    view: &View,
    size: (u32, u32),
    settings: &stratus::render::Settings,
    done: impl FnOnce(&image::RgbaImage) -> anyhow::Result<()>,
) -> anyhow::Result<image::RgbaImage> {
    // --super-resolution: marched at --size in cells of the preset's side over the scale, as
    // the window does with it; else marched small and enlarged.
    let (march, settings) = if a.super_resolution {
        stratus::scaled::plan(size, a.render_scale, view, settings)
    } else {
        (
            stratus::scaled::march_size(size, a.render_scale),
            settings.clone(),
        )
    };
    let mut runs = Vec::new();
    for i in 0..a.repeat {
        let mut s = settings.clone();
        if a.reprojection {
            // The window's frames count on (each its own jitter).
            s.frame_index = settings.frame_index.wrapping_add(i);
        }
        runs.push(stratus::scaled::render(r, view, march, size, &s)?);
    }
    let ms = {
        let mut t: Vec<f64> = runs.iter().map(|x| x.1).collect();
        t.sort_by(f64::total_cmp);
        t[t.len() / 2]
    };
    // With --reprojection on the last frame is the one the history has built up.
    let (img, _) = runs.pop().ok_or_else(|| anyhow::anyhow!("no frame"))?;
    done(&img)?;
    if a.timings {
        let how = if march == size {
            format!(
                "marched at {}×{} in {n}×{n} cells, one pixel of each a frame",
                size.0,
                size.1,
                n = settings.march.subset
            )
        } else {
            format!(
                "march {}×{} enlarged to {}×{}",
                march.0, march.1, size.0, size.1
            )
        };
        out!("wall {ms:.1} ms (median of {}; {how})", a.repeat)?;
    }
    Ok(img)
}

/// GPU times are absent where the adapter has no (trustworthy) timestamps: CPU drivers.
pub fn print_timings(out: &stratus::render::Output) -> std::io::Result<()> {
    let t = out.timings;
    let f = |v: Option<f64>| {
        v.map_or("n/a (no GPU timestamps: see wall)".to_string(), |v| {
            format!("{v:.3} ms")
        })
    };
    out!(
        "march {}  present {}  wall {:.1} ms  ({}×{})",
        f(t.march_ms),
        f(t.present_ms),
        t.wall_ms,
        out.width,
        out.height
    )?;
    let s = out.stats;
    let px = s.rays.max(1) as f64;
    out!(
        "per pixel: {:.1} steps, {:.1} density samples, {:.1} light samples; skipped {}, early exits {}, samples outside region {}, rays cut short {}, pixels reworked {}",
        s.steps as f64 / px,
        s.density_samples as f64 / px,
        s.light_samples as f64 / px,
        s.skipped_steps,
        s.early_exits,
        s.outside_samples,
        s.cut_rays,
        s.reworked
    )
}
