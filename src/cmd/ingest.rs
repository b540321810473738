//! `stratus ingest`: GRIB2 relative humidity → CloudMap PNG + sidecar, with a progress bar.
//! The ingest options are shared with `score` and `fly`, which can start from a GRIB2 file too.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::pipeline::{validate_rh_cr, IngestOptions, Plan};
use stratus_ingest::region::{parse_size, Region};
use stratus_ingest::spline::Interp;

/// How to turn a forecast file into a CloudMap.
#[derive(clap::Args, Debug, Clone)]
pub struct IngestOpts {
    /// Region as S,N,W,E in degrees (longitudes -180..180 or 0..360; W > E crosses the date line).
    #[arg(long, allow_hyphen_values = true)]
    pub region: Option<String>,
    /// Output size WxH in pixels (each side 1..=16384).
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
    #[arg(long, default_value_t = 0.80)]
    pub rh_cr_low: f64,
    #[arg(long, default_value_t = 0.65)]
    pub rh_cr_mid: f64,
    #[arg(long, default_value_t = 0.80)]
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
        let (width, height) = parse_size(&self.size)?;
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

    fn select(&self) -> LevelSelect {
        match self.level {
            Some(p) => LevelSelect::One(p),
            None => LevelSelect::AllBelow(self.top_hpa),
        }
    }

    /// Validate the options, read the file and prepare the resampling.
    pub fn plan(&self, file: &Path) -> anyhow::Result<Plan> {
        let opts = self.options()?;
        let fc = Forecast::open(file, self.select())?;
        Ok(Plan::new(&fc, &opts)?)
    }
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// GRIB2 forecast file.
    pub file: PathBuf,
    #[command(flatten)]
    pub ingest: IngestOpts,
    /// Output PNG; the sidecar goes next to it with a .json extension.
    #[arg(long)]
    pub out: PathBuf,
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

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.out.extension().and_then(|e| e.to_str()) != Some("png") {
        anyhow::bail!("{}: output must be a .png file", args.out.display());
    }
    let t0 = Instant::now();
    let plan = args.ingest.plan(&args.file)?;
    let pb = progress_bar(plan.height() as u64, "ingest rows");
    let sidecar = plan
        .write(&args.out, &|done| pb.set_position(done as u64))
        .with_context(|| format!("writing {}", args.out.display()))?;
    pb.finish_and_clear();
    let meta: stratus_ingest::CloudMapMeta =
        serde_json::from_str(&std::fs::read_to_string(&sidecar)?)?;
    println!(
        "{} + {}: {}x{} px, {} layer(s), {:.2} s",
        args.out.display(),
        sidecar.display(),
        meta.width,
        meta.height,
        meta.layers.len(),
        t0.elapsed().as_secs_f64()
    );
    for l in &meta.layers {
        println!(
            "  {:<6} {:>5.0}–{:<5.0} m  rh_cr {:.2}  levels {:?} hPa  mean cover {:.3}  max {:.3}",
            l.kind.name(),
            l.base_m,
            l.top_m,
            l.rh_cr,
            l.levels_hpa,
            l.mean_coverage,
            l.max_coverage
        );
    }
    Ok(ExitCode::SUCCESS)
}
