//! `stratus demo`: the main job on the embedded sample, end to end: ingest it (all layers),
//! render its views to PNG and print the Dice score of a top-down render against the map.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use stratus::picture::save_png;
use stratus::render::Renderer;
use stratus::scene::Scene;
use stratus::{scenes, score};
use stratus_ingest::error::shown;

use super::files::check_out;
use super::options::{progress_bar, LookOpts};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// GRIB2 file (default: the embedded sample), ingested over the sample's region.
    #[arg(long)]
    pub grib: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Size of each view, WxH.
    #[arg(long, default_value = "640x360")]
    pub size: String,
    #[command(flatten)]
    pub look: LookOpts,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let t0 = Instant::now();
    let sample = scenes::demo();
    let grib = a.grib.clone().unwrap_or_else(|| sample.path());
    let views = sample.scenes_named(&sample.demo_views);
    // Every output, before any work: none may be the forecast read, or other than a file.
    let outputs = ["cloudmap.png", "cloudmap.json", "score-diff.png"]
        .map(String::from)
        .into_iter()
        .chain(views.iter().map(|s| format!("{}.png", s.name)));
    for name in outputs {
        check_out(&a.out.join(name), std::slice::from_ref(&grib))?;
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create", shown(&a.out)))?;
    let plan = sample.plan(&grib)?;
    let pb = progress_bar(plan.height() as u64, "ingest rows");
    let png = a.out.join("cloudmap.png");
    let sidecar = plan.write(&png, &|d| pb.set_position(d as u64))?;
    pb.finish_and_clear();
    let map = Scene::open(&sidecar).map_at(None)?;
    out!(
        "ingested {} → {} ({}×{})",
        shown(&grib),
        shown(&sidecar),
        map.meta.width,
        map.meta.height
    )?;

    let settings = a.look.settings(&map, &sidecar)?;
    let (w, h) = stratus_ingest::region::parse_size(&a.size)?;
    let mut r = Renderer::new(a.look.gpu()?, &map);
    let pb = progress_bar(views.len() as u64, "render views");
    for scene in views {
        let mut s = settings.clone();
        if let Some(t) = scene.time {
            s.time = t;
        }
        let out = r.render(&scene.view, w, h, &s)?;
        let path = a.out.join(format!("{}.png", scene.name));
        save_png(&path, &out.to_image())?;
        pb.inc(1);
        out!(
            "{}: {:.0} ms{}",
            shown(&path),
            out.timings.wall_ms,
            out.timings
                .march_ms
                .map_or(String::new(), |m| format!(" (march {m:.1} ms GPU)"))
        )?;
    }
    pb.finish_and_clear();
    let report = score::score(
        &mut r,
        &map,
        &settings,
        score::default_size(&map),
        score::BLOCK,
        (score::RENDER_THRESHOLD, score::MAP_THRESHOLD),
    )?;
    let diff = a.out.join("score-diff.png");
    save_png(&diff, &report.diff_picture())?;
    let m = &report.total.similarity;
    out!(
        "Dice {:.4} (IoU {:.4}, precision {:.4}, recall {:.4}) top-down {}×{} in {}×{} blocks vs the map; diff in {}",
        m.dice,
        m.iou,
        m.precision,
        m.recall,
        report.width,
        report.height,
        report.block,
        report.block,
        shown(&diff)
    )?;
    out!("done in {:.1} s", t0.elapsed().as_secs_f64())?;
    Ok(ExitCode::SUCCESS)
}
