//! `stratus bench`: every preset and every shortcut-off variant on fixed scenes, against the
//! reference; a markdown table and a chart for docs/performance.md.

use std::path::PathBuf;
use std::process::ExitCode;

use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::region::parse_size;

use stratus::picture::write_png;
use stratus::render::{gpu, Gpu, Renderer};
use stratus::scene::Scene;
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
    /// Measure temporal reprojection instead: fly `--path` over `--map` at 15 frames a second
    /// (a cruise, a 3°/s turn, a teleport), each reprojected frame against a full march at the
    /// same camera; a table, and with --chart the error against frame number.
    #[arg(long, requires = "map")]
    pub reprojection: bool,
    /// The map the reprojection is measured over (e.g. the real GFS East Asia all-layers map).
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// The flight: straight for its first 15 s, then turning (docs/flights/ea-cruise.json).
    #[arg(long, default_value = "docs/flights/ea-cruise.json")]
    pub path: PathBuf,
    /// Quality preset the reprojection is measured at.
    #[arg(long, default_value = "balanced")]
    pub preset: stratus::render::Preset,
    /// Measure what a pixel shows against what it covers instead (issue 30): the window's
    /// start view, the time-lapse's 250 km view and the bench's scenes (at --size), each at
    /// the product's size against its own 4×4-supersampled render, and the change a 0.1° turn
    /// makes to each (docs/footprint.md).
    #[arg(long, conflicts_with = "reprojection")]
    pub footprint: bool,
    /// With --footprint: only the views whose name contains this.
    #[arg(long, requires = "footprint", default_value = "")]
    pub views: String,
    /// With --footprint: write each view's product picture beside its supersampled twin
    /// (both as measured) into this folder, one PNG per view.
    #[arg(long, requires = "footprint")]
    pub pictures: Option<std::path::PathBuf>,
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
    if a.reprojection {
        return reprojection(&a, size);
    }
    if a.footprint {
        return footprint(&a, size);
    }
    let sample = scenes::synthetic();
    let map: CloudMap = sample.map()?;
    let terrain = scenes::terrain();
    let terrain_map: CloudMap = terrain.map()?;
    let g = Gpu::new(a.adapter.as_deref())?;
    eprintln!("stratus: adapter {}", gpu::describe(&g.info));
    let mut r = Renderer::new(g, &map);
    let sets = [
        bench::Set {
            sample: &sample,
            map: &map,
            scenes: &bench::SCENES,
        },
        bench::Set {
            sample: &terrain,
            map: &terrain_map,
            scenes: &bench::TERRAIN_SCENES,
        },
    ];
    let total = sets.iter().map(bench::Set::steps).sum::<usize>() as u64;
    let pb = progress_bar(total, "bench");
    let rows = bench::run(&mut r, &sets, size, error_size, a.repeats, &|what| {
        pb.set_message(what.to_string());
        pb.inc(1);
    })?;
    pb.finish_and_clear();
    if let Some(c) = &a.chart {
        write_chart(c, &bench::chart(&rows))?;
    }
    if a.json {
        out!("{}", serde_json::to_string_pretty(&rows)?)?;
    } else {
        out!("adapter: {}\n", gpu::describe(&r.gpu.info))?;
        out!("{}", bench::table(&rows).trim_end_matches('\n'))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// `bench --reprojection`: the reprojection's error along three flights.
fn reprojection(a: &Args, size: (u32, u32)) -> anyhow::Result<ExitCode> {
    use stratus::reprojection_bench::{along, chart, measure, path_time, table, Flight};
    let map_path = a
        .map
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("--reprojection needs --map"))?;
    let map = Scene::open(map_path).map_at(None)?;
    let path = stratus::flight::FlightPath::load(&a.path)?;
    let time = path_time(&path)
        .or(map.meta.source.valid_time)
        .ok_or_else(|| anyhow::anyhow!("neither the path nor the map gives a time"))?;
    let mut s = stratus::render::Settings::new(a.preset, time);
    // A fixed exposure: the pictures are compared by their pixels.
    s.exposure_auto = false;
    const FPS: f64 = 15.0;
    // A teleport: 1 s along the path, then the same flight 1° (111 km) further north.
    let mut teleport = along(&path, 0.0, 15, FPS);
    teleport.extend(along(&path, 1.0, 30, FPS).into_iter().map(|mut c| {
        c.lat_deg += 1.0;
        c
    }));
    let flights = [
        Flight {
            name: "cruise 230 m/s".into(),
            cameras: along(&path, 0.0, 45, FPS),
        },
        Flight {
            name: "turn 3°/s".into(),
            cameras: along(&path, 15.0, 45, FPS),
        },
        Flight {
            name: "teleport at frame 15".into(),
            cameras: teleport,
        },
    ];
    let total = flights.iter().map(|f| f.cameras.len()).sum::<usize>() as u64;
    let gpus = [
        Gpu::new(a.adapter.as_deref())?,
        Gpu::new(a.adapter.as_deref())?,
    ];
    eprintln!("stratus: adapter {}", gpu::describe(&gpus[0].info));
    let pb = progress_bar(total, "reprojection");
    let rows = measure(gpus, &map, &s, &flights, size, &|what| {
        pb.set_message(what.to_string());
        pb.inc(1);
    })?;
    pb.finish_and_clear();
    if let Some(c) = &a.chart {
        write_chart(c, &chart(&rows, 0.0125))?;
    }
    if a.json {
        out!("{}", serde_json::to_string_pretty(&rows)?)?;
    } else {
        out!("{}", table(&rows).trim_end())?;
    }
    Ok(ExitCode::SUCCESS)
}

/// `bench --footprint`: each view against its own supersampled render.
fn footprint(a: &Args, size: (u32, u32)) -> anyhow::Result<ExitCode> {
    use stratus::footprint_bench::{cases, run, table};
    let sets = cases(size)?;
    let g = Gpu::new(a.adapter.as_deref())?;
    eprintln!("stratus: adapter {}", gpu::describe(&g.info));
    let mut r = Renderer::new(g, &sets[0].map);
    let total = sets.iter().map(|s| s.cases.len()).sum::<usize>() as u64;
    let pb = progress_bar(total, "footprint");
    if let Some(dir) = &a.pictures {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("{}: cannot create the folder: {e}", dir.display()))?;
    }
    let rows = run(&mut r, &sets, &a.views, a.pictures.as_deref(), &|what| {
        pb.set_message(what.to_string());
        pb.inc(1);
    })?;
    pb.finish_and_clear();
    if a.json {
        out!("{}", serde_json::to_string_pretty(&rows)?)?;
    } else {
        out!("adapter: {}\n", gpu::describe(&r.gpu.info))?;
        out!("{}", table(&rows).trim_end())?;
    }
    Ok(ExitCode::SUCCESS)
}

fn write_chart(path: &std::path::Path, img: &image::RgbImage) -> anyhow::Result<()> {
    write_png(
        path,
        img.as_raw(),
        img.width(),
        img.height(),
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(())
}
