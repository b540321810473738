//! `stratus score`: top-down render vs the CloudMap, Dice and friends, optionally a CI gate.

use std::path::PathBuf;
use std::process::ExitCode;

use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::error::shown;
use stratus_ingest::region::parse_size;

use stratus::picture::save_png;
use stratus::render::Renderer;
use stratus::score::{self, Report};

use stratus::scene::Scene;

use super::files::check_out;
use super::options::{IngestOpts, LookOpts};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// CloudMap sidecar (MAP.json). Or give a GRIB2 file with --grib and the ingest options.
    #[arg(long, conflicts_with = "grib", required_unless_present = "grib")]
    pub map: Option<PathBuf>,
    /// GRIB2 forecast to ingest in memory and score end to end (needs --region).
    #[arg(long)]
    pub grib: Option<PathBuf>,
    #[command(flatten)]
    pub ingest: IngestOpts,
    /// Render size WxH (default: the map's, at most 1024 on the longer side).
    #[arg(long = "score-size")]
    pub score_size: Option<String>,
    /// Pixels per side of the blocks the render's opacity and the map's coverage are averaged
    /// over before the masks: a cloud fraction per block, as a satellite pixel's (1: per ray).
    #[arg(long, default_value_t = score::BLOCK, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub block: u32,
    #[command(flatten)]
    pub look: LookOpts,
    /// Opacity above which a rendered pixel counts as cloud.
    #[arg(long, default_value_t = score::RENDER_THRESHOLD)]
    pub render_threshold: f32,
    /// Coverage above which a map pixel counts as cloud.
    #[arg(long, default_value_t = score::MAP_THRESHOLD)]
    pub map_threshold: f32,
    /// Write the total's diff picture (white both, orange render only, blue map only).
    #[arg(long)]
    pub diff: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Exit 1 when the total DSC is below this (the CI gate); a DSC, so in 0..=1.
    #[arg(long, allow_negative_numbers = true)]
    pub min_dice: Option<f64>,
}

pub fn load_or_ingest(
    scene: Option<Scene>,
    grib: &Option<PathBuf>,
    ingest: &IngestOpts,
    look: &LookOpts,
) -> anyhow::Result<CloudMap> {
    match (scene, grib) {
        (Some(s), _) => look.open_map(s),
        (None, Some(g)) => Ok(ingest.plan(g)?.build()),
        (None, None) => anyhow::bail!("give --map MAP.json or --grib FILE.grib2"),
    }
}

pub fn print_report(r: &Report) -> std::io::Result<()> {
    out!(
        "{} top-down {}×{} in {}×{} blocks ({}×{}, {} preset), render opacity > {} vs map coverage > {}",
        r.map,
        r.width,
        r.height,
        r.block,
        r.block,
        r.mask_width,
        r.mask_height,
        r.preset,
        r.render_threshold,
        r.map_threshold
    )?;
    out!(
        "{:<8} {:>7} {:>7} {:>9} {:>7} {:>9} {:>9}",
        "layer",
        "DSC",
        "IoU",
        "precision",
        "recall",
        "render #",
        "map #"
    )?;
    for s in std::iter::once(&r.total).chain(&r.layers) {
        let m = &s.similarity;
        out!(
            "{:<8} {:>7.4} {:>7.4} {:>9.4} {:>7.4} {:>9} {:>9}{}",
            s.layer,
            m.dice,
            m.iou,
            m.precision,
            m.recall,
            m.render_px,
            m.map_px,
            s.note
                .as_ref()
                .map_or(String::new(), |n| format!("  ({n})"))
        )?;
    }
    Ok(())
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let report = report(&a)?;
    if a.json {
        out!("{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        print_report(&report)?;
    }
    if let Some(min) = a.min_dice {
        if report.total.similarity.dice < min {
            eprintln!(
                "score: DSC {:.4} is below --min-dice {min}",
                report.total.similarity.dice
            );
            return Ok(ExitCode::from(1));
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The report `run` prints (and the diff picture written): what `stratus.score` in Python
/// returns, through this one function.
pub fn report(a: &Args) -> anyhow::Result<Report> {
    for (name, t) in [("render", a.render_threshold), ("map", a.map_threshold)] {
        if !(0.0..1.0).contains(&t) {
            anyhow::bail!("--{name}-threshold {t} must be in 0..1");
        }
    }
    if let Some(min) = a.min_dice {
        // NaN compares false with everything, so it would pass every gate.
        if !(0.0..=1.0).contains(&min) {
            anyhow::bail!("--min-dice {min} must be a number in 0..=1 (a DSC)");
        }
    }
    let scene = a.map.as_deref().map(Scene::open);
    let inputs = match (&scene, &a.grib) {
        (Some(s), _) => s.files(),
        (None, Some(g)) => vec![g.clone()],
        (None, None) => vec![],
    };
    if let Some(d) = &a.diff {
        if d.extension().and_then(|e| e.to_str()) != Some("png") {
            anyhow::bail!("{}: --diff must be a .png file", shown(d));
        }
        check_out(d, &inputs)?;
    }
    let map = load_or_ingest(scene, &a.grib, &a.ingest, &a.look)?;
    let source = a
        .map
        .as_ref()
        .or(a.grib.as_ref())
        .cloned()
        .unwrap_or_default();
    let settings = a.look.settings(&map, &source)?;
    let (w, h) = match &a.score_size {
        Some(s) => parse_size(s)?,
        None => score::default_size(&map),
    };
    let mut renderer = Renderer::new(a.look.gpu()?, &map);
    let mut report = score::score(
        &mut renderer,
        &map,
        &settings,
        (w, h),
        a.block,
        (a.render_threshold, a.map_threshold),
    )?;
    report.preset = a.look.preset.name().into();
    if let Some(src) = a.map.as_ref().or(a.grib.as_ref()) {
        report.map = shown(src).to_string();
    }
    if let Some(d) = &a.diff {
        save_png(d, &report.diff_picture())?;
    }
    Ok(report)
}
