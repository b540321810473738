//! `stratus fetch`: download the GRIB2 messages a GFS run's steps need — RH on isobaric levels
//! and what the renderer uses beside it — by byte range from NOMADS, AWS, Google or a mirror,
//! into one validated file per step (docs/fetch.md). The work is the ingest library's
//! [`stratus_ingest::fetch`]; this is the command line and the progress bar.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::time::Duration;

use anyhow::Context;
use chrono::NaiveDate;
use indicatif::{ProgressBar, ProgressStyle};
use stratus_ingest::error::shown;
use stratus_ingest::fetch::cache::Cache;
use stratus_ingest::fetch::http::{Client, Policy};
use stratus_ingest::fetch::select::{self, DEFAULT_FIELDS, DEFAULT_LEVELS};
use stratus_ingest::fetch::source::{self, Run};
use stratus_ingest::fetch::{default_cache_dir, Fetcher, Progress};
use stratus_ingest::output::remove_if_empty;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run's date, YYYY-MM-DD (UTC).
    #[arg(long)]
    pub date: String,
    /// The run's cycle hour: 00, 06, 12 or 18.
    #[arg(long)]
    pub cycle: u32,
    /// Forecast hours: 6, 0,6,12, or 0-24/3 (every 3 h from 0 to 24).
    #[arg(long)]
    pub step: String,
    /// Grid: 0p25, 0p50, 1p00, or any name the server has (the file is gfs.tHHz.pgrb2.RES.fFFF).
    #[arg(long, default_value = "0p25")]
    pub resolution: String,
    /// Fields: r,gh,u,v,t,q,w,tcc,cloudbase,cloudtop,orog,lsm or NCEP names (TMP@2 m above ground).
    #[arg(long, help = format!("Fields, comma-separated [default: {DEFAULT_FIELDS}; all but r only where present]"))]
    pub fields: Option<String>,
    /// Isobaric levels in hPa: a range 1000-100, a list 850,500,300, or all.
    #[arg(long, default_value = DEFAULT_LEVELS)]
    pub levels: String,
    /// nomads, aws, google, or the base URL of a mirror in NOMADS' layout.
    #[arg(long, default_value = "nomads")]
    pub source: String,
    /// Folder for the step files (created if absent).
    #[arg(long)]
    pub out: PathBuf,
    /// Folder for downloaded ranges, so a re-run fetches only what is missing; locked while in use, never removed if it existed [default: OUT/.stratus-cache].
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Ranges downloaded at once.
    #[arg(long, default_value_t = 4)]
    pub parallel: usize,
    /// Tries after the first for what may pass on a retry (connection lost, timeout, 5xx, short body).
    #[arg(long, default_value_t = 4)]
    pub retries: u32,
    /// Seconds to wait for a connection, a response, or each read of a body.
    #[arg(long, default_value_t = 30.0)]
    pub timeout: f64,
    /// Milliseconds before the first retry; doubled for each next one.
    #[arg(long, default_value_t = 1000, hide = true)]
    pub backoff_ms: u64,
}

/// The progress bar, and the counts the summary line reports.
struct Bar {
    pb: ProgressBar,
    downloaded: AtomicI64,
    cached: AtomicU64,
}

impl Progress for Bar {
    fn downloaded(&self, delta: i64) {
        self.downloaded.fetch_add(delta, Ordering::Relaxed);
        if delta >= 0 {
            self.pb.inc(delta as u64);
            // The last message of a file has no known length until it arrives.
            if self.pb.length().is_some_and(|l| self.pb.position() > l) {
                self.pb.set_length(self.pb.position());
            }
        } else {
            self.pb.dec(delta.unsigned_abs());
        }
    }
    fn cached(&self, bytes: u64) {
        self.cached.fetch_add(bytes, Ordering::Relaxed);
        self.pb.inc(bytes);
    }
}

fn bytes_bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg} [{bar:40}] {bytes}/{total_bytes} {binary_bytes_per_sec} ({eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let date = NaiveDate::parse_from_str(&args.date, "%Y-%m-%d")
        .with_context(|| format!("--date \"{}\" must be YYYY-MM-DD", args.date))?;
    if args.cycle > 23 {
        anyhow::bail!(
            "--cycle {} must be an hour, 0-23 (GFS runs at 00, 06, 12, 18)",
            args.cycle
        );
    }
    let steps = select::parse_steps(&args.step).map_err(anyhow::Error::msg)?;
    source::check_resolution(&args.resolution).map_err(anyhow::Error::msg)?;
    let fields = match &args.fields {
        Some(f) => select::parse_fields(f).map_err(anyhow::Error::msg)?,
        None => select::default_fields(),
    };
    let levels = select::parse_levels(&args.levels).map_err(anyhow::Error::msg)?;
    let base = source::base_url(&args.source).map_err(anyhow::Error::msg)?;
    if !(args.timeout.is_finite() && args.timeout > 0.0 && args.timeout <= 3600.0) {
        anyhow::bail!(
            "--timeout {} must be seconds, more than 0 and at most 3600",
            args.timeout
        );
    }
    if args.parallel == 0 || args.parallel > 16 {
        anyhow::bail!("--parallel {} must be 1-16", args.parallel);
    }
    if args.retries > 20 {
        anyhow::bail!("--retries {} must be at most 20", args.retries);
    }
    if args.out.exists() && !args.out.is_dir() {
        anyhow::bail!("{}: --out must be a folder", shown(&args.out));
    }
    // Folders this run creates are removed again when empty: on an error here, on a signal
    // by the handler (output::cleanup_temps), never one that existed before.
    let created_out = super::files::create_folder(&args.out)?;
    let (cache_dir, ours) = match &args.cache {
        Some(c) => (c.clone(), false),
        None => (default_cache_dir(&args.out), true),
    };
    let result = (|| {
        let created_cache = super::files::create_folder(&cache_dir)?;
        let cache = Cache::open(&cache_dir, &|| {
            let _ = writeln!(
                std::io::stderr().lock(),
                "waiting for another stratus fetch that is using the cache {}",
                shown(&cache_dir)
            );
        })?;
        let fetcher = Fetcher {
            client: Client::new(Policy {
                retries: args.retries,
                backoff: Duration::from_millis(args.backoff_ms),
                timeout: Duration::from_secs_f64(args.timeout),
            }),
            cache,
            run: Run {
                base,
                date,
                cycle: args.cycle,
                resolution: args.resolution.clone(),
            },
            fields,
            levels,
            out_dir: args.out.clone(),
            parallel: args.parallel,
        };
        let result = fetch_steps(&fetcher, &steps);
        // Whole ranges stay for the next run. An empty cache folder goes if it is ours (the
        // default) or this run made it, while the lock is held; a --cache folder that was
        // there before stays.
        if ours {
            fetcher.cache.remove_if_empty();
        }
        remove_if_empty(&created_cache);
        result
    })();
    if result.is_err() {
        remove_if_empty(&created_out);
    }
    result?;
    Ok(ExitCode::SUCCESS)
}

fn fetch_steps(fetcher: &Fetcher, steps: &[u32]) -> anyhow::Result<()> {
    for &step in steps {
        let plan = fetcher.plan(step)?;
        let bar = Bar {
            pb: bytes_bar(plan.known_bytes(), &format!("f{step:03}")),
            downloaded: AtomicI64::new(0),
            cached: AtomicU64::new(0),
        };
        let size = fetcher.fetch(&plan, &bar);
        // Cleared before any error line, so that line stands alone.
        bar.pb.finish_and_clear();
        let size = size?;
        out!(
            "{}: {} messages, {} bytes in {} range(s) ({} downloaded, {} from the cache)",
            shown(&plan.out),
            plan.messages.len(),
            size,
            plan.chunks.len(),
            bar.downloaded.load(Ordering::Relaxed).max(0),
            bar.cached.load(Ordering::Relaxed)
        )?;
    }
    Ok(())
}
