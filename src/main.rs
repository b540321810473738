//! The `stratus` command line: fetch, inspect, ingest, render, score, fly.
//!
//! # Layers
//!
//! Bottom first: a module uses only modules on its own line or on the lines above it.
//!
//! 1. `cleanup` — the signal hook: INT, TERM and HUP remove what is in flight, then exit
//! 2. `cmd` — one module per subcommand over the `stratus` library and `stratus-ingest`

use std::io::{IsTerminal, Write};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cleanup;
#[macro_use]
mod cmd;

#[derive(Parser)]
#[command(
    name = "stratus",
    version,
    about = "Weather-data-driven volumetric clouds for flight simulation"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Download a GFS run's fields by byte range (NOMADS, AWS, Google or a mirror), one validated file per step.
    Fetch(cmd::fetch::Args),
    /// List the messages of a GRIB file, one row each (headers only, no decoding).
    Inspect(cmd::inspect::Args),
    /// GRIB2 relative humidity → CloudMap PNG + JSON sidecar.
    Ingest(cmd::ingest::Args),
    /// What a CloudMap holds at a point, per layer: coverage, base, top, type.
    Probe(cmd::probe::Args),
    /// Render one frame of a CloudMap to PNG, headless.
    Render(cmd::render::Args),
    /// A vertical cross-section of the rendered cloud along a great circle, with the map's base and top.
    Section(cmd::section::Args),
    /// Top-down render vs the CloudMap: Dice, IoU, precision, recall; a CI gate with --min-dice.
    Score(cmd::score::Args),
    /// Fly over a CloudMap (or a GRIB2 file) in a window: flight controls, HUD, control panel.
    Fly(cmd::fly::Args),
    /// A keyframed flight path rendered headless to PNG frames (MP4 with ffmpeg).
    Flight(cmd::flight::Args),
    /// Speed against accuracy: every preset and shortcut on fixed scenes vs the reference.
    Bench(cmd::bench::Args),
    /// Carry a series' earlier step forward with its winds; Dice per layer against the later step, beside persistence.
    VerifyAdvection(cmd::verify_advection::Args),
    /// Leave a series' step out and rebuild it from the steps either side: Dice per layer of the motion blend, the cross-fade and the wind blend.
    VerifyInterpolation(cmd::verify_interpolation::Args),
    /// The main job on the embedded sample: ingest, render a few views, print the Dice score.
    Demo(cmd::demo::Args),
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        // Colour codes only for a terminal: a log file or a CI capture gets plain text.
        .with_ansi(std::io::stderr().is_terminal())
        .init();
    if let Err(e) = cleanup::install() {
        // Still usable: only an interrupted write would leave its temporary behind.
        tracing::warn!(
            "cannot handle INT/TERM/HUP ({e}): an interrupted run may leave temporary files"
        );
    }
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) if !e.use_stderr() => {
            // --help / --version.
            let _ = e.print();
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            // Usage errors in one line, like every other error.
            let text = e.to_string();
            let first = text.lines().next().unwrap_or("bad arguments");
            let _ = writeln!(std::io::stderr().lock(), "{first} (see stratus --help)");
            return ExitCode::from(2);
        }
    };
    if !matches!(cli.command, Command::Fly(_)) && std::env::var_os("NODEVICE_SELECT").is_none() {
        // Mesa's device-select Vulkan layer probes for a Wayland display to rank GPUs and prints
        // "error: XDG_RUNTIME_DIR is invalid" where there is none. Headless commands rank the
        // adapters themselves (render::gpu), so the layer is switched off for them (still one
        // thread here).
        std::env::set_var("NODEVICE_SELECT", "1");
    }
    let result = match cli.command {
        Command::Fetch(a) => cmd::fetch::run(a),
        Command::Inspect(a) => cmd::inspect::run(a),
        Command::Ingest(a) => cmd::ingest::run(a),
        Command::Probe(a) => cmd::probe::run(a),
        Command::Section(a) => cmd::section::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Score(a) => cmd::score::run(a),
        Command::Demo(a) => cmd::demo::run(a),
        Command::VerifyAdvection(a) => cmd::verify_advection::run(a),
        Command::VerifyInterpolation(a) => cmd::verify_interpolation::run(a),
        Command::Bench(a) => cmd::bench::run(a),
        Command::Flight(a) => cmd::flight::run(a),
        Command::Fly(a) => cmd::fly::run(a),
    };
    if let Some(sig) = cleanup::received() {
        // The work stopped because of the signal: finish as the handler does, quietly.
        cleanup::shut_down(sig);
    }
    match result {
        Ok(code) => code,
        Err(e) if cmd::is_broken_pipe(&e) => {
            // The reader of stdout has gone (`stratus inspect G | head -1`): nothing to report
            // to, and not a success either (a gate's verdict may be unread), so the shell's
            // code for a pipe writer stopped by SIGPIPE.
            ExitCode::from(cmd::BROKEN_PIPE_EXIT)
        }
        Err(e) => {
            // One line: the chain of causes joined, the file named by the innermost error.
            // Written without panicking should stderr be closed too.
            let _ = writeln!(std::io::stderr().lock(), "error: {e:#}");
            ExitCode::from(2)
        }
    }
}
