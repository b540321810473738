//! The binary's signal hook: on INT, TERM and HUP, remove what this run has in flight (the
//! temporaries, staging folders and created folders the one file-commit module registers:
//! [`stratus_ingest::output::cleanup_temps`]), then exit with 128 + the signal number, as a
//! shell reports a process killed by that signal.
//!
//! The handler runs on an ordinary thread (signal-hook's iterator), not inside an async signal
//! handler, so it may take locks and remove files.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal received, 0 while none.
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// Handle INT, TERM and HUP from now on (see the module doc).
pub fn install() -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
        std::thread::Builder::new()
            .name("signals".into())
            .spawn(move || {
                if let Some(sig) = signals.forever().next() {
                    shut_down(sig);
                }
            })?;
    }
    Ok(())
}

/// The signal received, if one was: the main thread then calls [`shut_down`] rather than
/// report the error its interrupted work returned.
pub fn received() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// Remove what is in flight (a commit in progress is let finish first) and exit with
/// 128 + `sig`. Whichever thread gets here first does the work; the exit ends the other.
pub fn shut_down(sig: i32) -> ! {
    SIGNAL.store(sig, Ordering::SeqCst);
    stratus_ingest::output::cleanup_temps();
    std::process::exit(128 + sig)
}
