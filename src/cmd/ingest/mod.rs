//! `stratus ingest`: GRIB2 relative humidity → CloudMap, with a progress bar. The output's
//! extension chooses the format: `.png` writes the PNG + `.json` sidecar pair, `.tif`/`.tiff`
//! one georeferenced, tiled GeoTIFF with overviews (no sidecar: its metadata is inside).
//! Several steps of one run (several files, or one file holding several) make a series
//! (`series`): one map per step and the series sidecar. `.zarr` writes one Zarr v3 store of
//! one step or several (`store`; `--append` adds later steps of its run).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use stratus_ingest::cloudmap::load_meta;
use stratus_ingest::error::shown;

use super::files::check_out;
use super::options::{progress_bar, IngestOpts};

mod series;
mod store;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// GRIB2 forecast file(s). Several steps of one run (several files in increasing forecast
    /// hour, or one file holding several steps) make a series: NAME-fHHH.png per step and the
    /// series sidecar NAME.json.
    #[arg(required_unless_present_any = ["motion", "finish"], num_args = 1..)]
    pub files: Vec<PathBuf>,
    #[command(flatten)]
    pub ingest: IngestOpts,
    /// Output: MAP.png (the sidecar goes next to it with a .json extension), MAP.tif
    /// (a GeoTIFF in EPSG:4326, tiled, with overviews; no sidecar) or STORE.zarr (a Zarr v3
    /// store of one step or a series, which xarray opens; docs/zarr.md).
    #[arg(long)]
    pub out: PathBuf,
    /// With --out STORE.zarr: add the files' steps (later steps of the store's run, same
    /// region and size) to the existing store.
    #[arg(long, conflicts_with_all = ["plan", "step", "motion", "finish"])]
    pub append: bool,
    #[command(flatten)]
    pub batch: BatchArgs,
}

/// A store written by several processes (a Dask cluster: `python -m stratus.batch`;
/// docs/zarr.md, "Batch"): `--plan` once, then `--step K` for every step and `--motion K` for
/// every interval (in any order, any process, each step's after the plan and each interval's
/// after its two steps), then `--finish` once. Every call names the run with `--run ID`.
#[derive(clap::Args, Debug)]
pub struct BatchArgs {
    /// Batch, first call: create the store --out (which must not exist) for every step of
    /// FILES, from their headers only (arrays, coordinates, time axis), and claim it for the
    /// run --run (the folder .STORE.zarr.batch beside it; another run is refused).
    #[arg(long, requires = "run", conflicts_with_all = ["step", "motion", "finish"])]
    pub plan: bool,
    /// Batch: write step K (0-based, time order) of the planned store; give the same FILES,
    /// --region, --size and ingest options as --plan. Writes only time index K's chunks.
    #[arg(long, value_name = "K", requires = "run", conflicts_with_all = ["motion", "finish"])]
    pub step: Option<usize>,
    /// Batch: write the motion from step K to step K + 1 (both already written) into the
    /// planned store: only interval K's chunks. Needs no FILES.
    #[arg(long, value_name = "K", requires = "run", conflicts_with = "finish")]
    pub motion: Option<usize>,
    /// Batch, last call: every step and interval written, write the store's series and step
    /// records (what the Stratus reader needs) and release the run. Needs no FILES.
    #[arg(long, requires = "run")]
    pub finish: bool,
    /// Batch: the run's id (any text without newlines; python -m stratus.batch makes one).
    #[arg(long, value_name = "ID")]
    pub run: Option<String>,
}

impl BatchArgs {
    fn any(&self) -> bool {
        self.plan || self.step.is_some() || self.motion.is_some() || self.finish
    }
}

/// The output formats, chosen by the extension.
enum Format {
    Png,
    GeoTiff,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let ext = args.out.extension().and_then(|e| e.to_str());
    let format = match ext.map(str::to_ascii_lowercase).as_deref() {
        Some("png") => Format::Png,
        Some("tif" | "tiff") => Format::GeoTiff,
        Some("zarr") => return store::run(&args),
        _ => anyhow::bail!(
            "{}: output must be a .png file (CloudMap PNG + .json sidecar), a .tif/.tiff file (GeoTIFF) or a .zarr store",
            shown(&args.out)
        ),
    };
    if args.append || args.batch.any() {
        anyhow::bail!(
            "{}: --append, --plan, --step, --motion and --finish write a Zarr store; give --out STORE.zarr",
            shown(&args.out)
        );
    }
    if let Some(steps) = series::steps_of(&args.files)? {
        if !matches!(format, Format::Png) {
            anyhow::bail!(
                "{}: a series of {} steps is written as PNG maps; give --out NAME.png",
                shown(&args.out),
                steps.len()
            );
        }
        return series::run(&args, &steps);
    }
    let file = &args.files[0];
    // Before the forecast is read: a bad output fails at once. (The write checks again.)
    let inputs = [file.clone()];
    check_out(&args.out, &inputs)?;
    if let Format::Png = format {
        check_out(&args.out.with_extension("json"), &inputs)?;
    }
    let t0 = Instant::now();
    let plan = args.ingest.plan(file)?;
    let pb = progress_bar(plan.height() as u64, "ingest rows");
    let progress = |done| pb.set_position(done as u64);
    // The library's error names the file; no context is added, so it is named once.
    let (meta, written) = match format {
        Format::Png => {
            let sidecar = plan.write(&args.out, &progress)?;
            pb.finish_and_clear();
            let written = format!("{} + {}", shown(&args.out), shown(&sidecar));
            (load_meta(&sidecar)?, written)
        }
        Format::GeoTiff => {
            let meta = plan.write_geotiff(&args.out, &progress)?;
            pb.finish_and_clear();
            (meta, format!("{} (GeoTIFF)", shown(&args.out)))
        }
    };
    out!(
        "{}: {}x{} px, {} layer(s), {:.2} s",
        written,
        meta.width,
        meta.height,
        meta.layers.len(),
        t0.elapsed().as_secs_f64()
    )?;
    for l in &meta.layers {
        out!(
            "  {:<6} {:>5.0}–{:<5.0} m  rh_cr {:.2}  levels {:?} hPa  mean cover {:.3}  max {:.3}",
            l.kind.name(),
            l.base_m,
            l.top_m,
            l.rh_cr,
            l.levels_hpa,
            l.mean_coverage,
            l.max_coverage
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
