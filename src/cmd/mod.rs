//! The command line: one module per subcommand (its clap arguments and `run`), and the options
//! and parsers they share (`options`). Only the binary sees this module.

/// `println!` that returns the write's error instead of panicking when stdout is closed (a pipe
/// whose reader quit): commands pass it up with `?`, and `main` ends quietly
/// ([`is_broken_pipe`]).
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)
    }};
}

pub mod bench;
pub mod demo;
pub mod fetch;
pub mod files;
pub mod flight;
pub mod fly;
pub mod ingest;
pub mod inspect;
pub mod options;
pub mod probe;
pub mod render;
pub mod score;
pub mod section;
pub mod verify_advection;
pub mod verify_interpolation;

/// Exit code when stdout's reader has gone: 128 + SIGPIPE, what a shell reports for a pipe
/// writer the signal stopped (`yes | head -1` under `set -o pipefail`).
pub const BROKEN_PIPE_EXIT: u8 = 141;

/// Whether `e` is a write to a stdout whose reader has gone.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
