//! `stratus demo`: the main job on the embedded sample, end to end. Ingests
//! `data-samples/synthetic-gfs-rh.grib2` (all layers), renders a few views of it to PNG and prints
//! the Dice score of a top-down render against the map.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use stratus_ingest::cloudmap::CloudMap;

use super::ingest::{progress_bar, IngestOpts};
use super::render::{parse_time, save_png, LookOpts};
use crate::render::{Camera, Renderer, View};
use crate::score;

/// The embedded sample, relative to the workspace root.
pub const SAMPLE: &str = "data-samples/synthetic-gfs-rh.grib2";

#[derive(clap::Args, Debug)]
pub struct Args {
    /// GRIB2 file (default: the embedded synthetic sample).
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

pub fn sample_path() -> PathBuf {
    let here = Path::new(SAMPLE);
    if here.exists() {
        return here.to_path_buf();
    }
    Path::new(env!("CARGO_MANIFEST_DIR")).join(SAMPLE)
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let t0 = Instant::now();
    let grib = a.grib.clone().unwrap_or_else(sample_path);
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("{}: cannot create", a.out.display()))?;
    let opts = sample_opts();
    let plan = opts.plan(&grib)?;
    let pb = progress_bar(plan.height() as u64, "ingest rows");
    let png = a.out.join("cloudmap.png");
    let sidecar = plan.write(&png, &|d| pb.set_position(d as u64))?;
    pb.finish_and_clear();
    let map = CloudMap::load(&sidecar)?;
    println!(
        "ingested {} → {} ({}×{})",
        grib.display(),
        sidecar.display(),
        map.meta.width,
        map.meta.height
    );

    let settings = a.look.settings(&map)?;
    let (w, h) = stratus_ingest::region::parse_size(&a.size)?;
    let mut r = Renderer::new(a.look.gpu()?, &map);
    let dusk = parse_time("2024-06-01T20:45:00Z")?;
    // (file, camera, time override): above the front at the map's valid time, the same at dusk,
    // inside the middle layer, and the horizon from the ground.
    let views: [(&str, Camera, Option<chrono::DateTime<chrono::Utc>>); 4] = [
        (
            "above-noon.png",
            Camera::new(45.5, -22.0, 12_000.0, 45.0, -12.0),
            None,
        ),
        (
            "above-dusk.png",
            Camera::new(45.5, -22.0, 12_000.0, 45.0, -12.0),
            Some(dusk),
        ),
        (
            "inside-layer.png",
            Camera::new(47.0, -17.0, 4_500.0, 60.0, 0.0),
            None,
        ),
        (
            "horizon-ground.png",
            Camera::new(36.0, -28.6, 50.0, 45.0, 10.0),
            None,
        ),
    ];
    let pb = progress_bar(views.len() as u64, "render views");
    for (name, cam, time) in views {
        let mut s = settings.clone();
        if let Some(t) = time {
            s.time = t;
        }
        let out = r.render(&View::Perspective(cam), w, h, &s)?;
        let path = a.out.join(name);
        save_png(&path, &out.to_image()).with_context(|| path.display().to_string())?;
        pb.inc(1);
        println!(
            "{}: {:.0} ms{}",
            path.display(),
            out.timings.wall_ms,
            out.timings
                .march_ms
                .map_or(String::new(), |m| format!(" (march {m:.1} ms GPU)"))
        );
    }
    pb.finish_and_clear();
    let (sw, sh) = super::score::default_size(&map);
    let report = score::score(
        &mut r,
        &map,
        &settings,
        sw,
        sh,
        (score::RENDER_THRESHOLD, score::MAP_THRESHOLD),
    )?;
    let px = score::diff_image(&report.total.render_mask, &report.total.map_mask);
    let img = image::RgbaImage::from_fn(sw, sh, |x, y| {
        let p = px[(y * sw + x) as usize];
        image::Rgba([p[0], p[1], p[2], 255])
    });
    save_png(&a.out.join("score-diff.png"), &img)?;
    let m = &report.total.similarity;
    println!(
        "Dice {:.4} (IoU {:.4}, precision {:.4}, recall {:.4}) top-down {}×{} vs the map; diff in {}",
        m.dice,
        m.iou,
        m.precision,
        m.recall,
        sw,
        sh,
        a.out.join("score-diff.png").display()
    );
    println!("done in {:.1} s", t0.elapsed().as_secs_f64());
    Ok(ExitCode::SUCCESS)
}

/// The demo's (and bench's) ingest of the embedded sample: 30–60°N, 40°W–0°, 800×600, all
/// layers with the default critical humidities.
pub fn sample_opts() -> IngestOpts {
    IngestOpts {
        region: Some("30,60,-40,0".into()),
        size: "800x600".into(),
        level: None,
        top_hpa: stratus_ingest::forecast::DEFAULT_TOP_HPA,
        rh_cr: None,
        rh_cr_low: 0.80,
        rh_cr_mid: 0.65,
        rh_cr_high: 0.80,
        interp: stratus_ingest::spline::Interp::Spline,
    }
}
