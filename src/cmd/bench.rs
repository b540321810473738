//! `stratus bench`: every preset and every shortcut-off variant on fixed scenes, against the
//! reference; a markdown table and a chart for docs/performance.md.

use std::path::PathBuf;
use std::process::ExitCode;

use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::region::parse_size;

use stratus::picture::write_png;
use stratus::render::{gpu, Gpu, Renderer};
use stratus::{bench, scenes};

use super::files::check_out;
use super::options::progress_bar;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Size the presets are timed at.
    #[arg(long, default_value = "480x270")]
    pub size: String,
    /// Size every configuration is compared with the reference at (the reference is slow).
    #[arg(long, default_value = "240x135")]
    pub error_size: String,
    /// Timed repeats per configuration (median reported).
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write the chart here (PNG).
    #[arg(long)]
    pub chart: Option<PathBuf>,
    /// Adapter to use (any part of its name).
    #[arg(long)]
    pub adapter: Option<String>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let size = parse_size(&a.size)?;
    let error_size = parse_size(&a.error_size)?;
    if a.repeats == 0 || a.repeats > 100 {
        anyhow::bail!("--repeats {} must be in 1..=100", a.repeats);
    }
    if let Some(c) = &a.chart {
        // Before minutes of benchmarking.
        check_out(c, &[])?;
    }
    let sample = scenes::synthetic();
    let map: CloudMap = sample.map()?;
    let time = map
        .meta
        .source
        .valid_time
        .ok_or_else(|| anyhow::anyhow!("the sample has no valid time"))?;
    let g = Gpu::new(a.adapter.as_deref())?;
    eprintln!("stratus: adapter {}", gpu::describe(&g.info));
    let mut r = Renderer::new(g, &map);
    let total = (bench::SCENES.len() * (bench::configs().len() + 1)) as u64;
    let pb = progress_bar(total, "bench");
    let rows = bench::run(
        &mut r,
        &sample,
        &map,
        time,
        size,
        error_size,
        a.repeats,
        &|what| {
            pb.set_message(what.to_string());
            pb.inc(1);
        },
    )?;
    pb.finish_and_clear();
    if let Some(c) = &a.chart {
        let img = bench::chart(&rows);
        write_png(
            c,
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )?;
    }
    if a.json {
        out!("{}", serde_json::to_string_pretty(&rows)?)?;
    } else {
        out!("adapter: {}\n", gpu::describe(&r.gpu.info))?;
        out!("{}", bench::table(&rows).trim_end_matches('\n'))?;
    }
    Ok(ExitCode::SUCCESS)
}
