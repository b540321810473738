//! What the binary does on INT, TERM and HUP: remove the temporary files and folders this run
//! has in flight (the ingest library's registry, [`stratus_ingest::output::cleanup_temps`], and
//! the folders [`track_dir`] names), then exit with 128 + the signal number, as a shell reports a
//! process killed by that signal.
//!
//! The handler runs on an ordinary thread (signal-hook's iterator), not inside an async signal
//! handler, so it may take locks and remove files.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicI32, Ordering};
use std::sync::{Mutex, MutexGuard};

/// Folders to remove on a signal, in the order registered; removed newest first.
static DIRS: Mutex<Vec<(PathBuf, Removal)>> = Mutex::new(Vec::new());
/// Held while output is moved into place, so a signal never cuts a commit in half.
static COMMIT: Mutex<()> = Mutex::new(());
/// The signal received, 0 while none.
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// How a tracked folder is removed.
#[derive(Clone, Copy, PartialEq)]
pub enum Removal {
    /// With everything in it: a staging folder of ours.
    Whole,
    /// Only when empty: a folder this run created for its output.
    IfEmpty,
}

/// The data behind these locks is valid whatever a panicking holder was doing.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

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

/// Remove what is in flight and exit with 128 + `sig`. Whichever thread gets here first does
/// the work; the exit ends the other.
pub fn shut_down(sig: i32) -> ! {
    SIGNAL.store(sig, Ordering::SeqCst);
    let _commit = lock(&COMMIT);
    stratus_ingest::output::cleanup_temps();
    let dirs = std::mem::take(&mut *lock(&DIRS));
    for (dir, how) in dirs.iter().rev() {
        let _ = match how {
            Removal::Whole => std::fs::remove_dir_all(dir),
            Removal::IfEmpty => std::fs::remove_dir(dir),
        };
    }
    std::process::exit(128 + sig)
}

/// Remove `dir` on a signal until the returned guard is dropped.
pub fn track_dir(dir: &Path, how: Removal) -> Tracked {
    lock(&DIRS).push((dir.to_path_buf(), how));
    Tracked(dir.to_path_buf())
}

/// See [`track_dir`].
pub struct Tracked(PathBuf);

impl Drop for Tracked {
    fn drop(&mut self) {
        lock(&DIRS).retain(|(d, _)| d != &self.0);
    }
}

/// Held while output is moved into place: a signal waits for it.
pub fn commit_guard() -> MutexGuard<'static, ()> {
    lock(&COMMIT)
}
