//! The free-space check before a step is downloaded: the ranges still missing go to the cache,
//! and the step's file is assembled from the cache, each range removed once copied. So where
//! the cache and the output share a file system, a step needs the missing ranges plus its
//! largest range (the one being copied while it is still cached); where they do not, the
//! cache's needs the missing ranges and the output's the whole step.

use std::os::unix::fs::MetadataExt;
use std::path::Path;

use super::{FetchError, Fetcher, StepPlan};
use crate::error::shown;

/// What a file takes beyond its bytes, at most: one block of the file system (4 KiB on the
/// usual ones) for its last partial block, and one for the cache's trailer.
const PER_FILE: u64 = 8 << 10;

/// Free bytes on the file system holding `dir`, for an unprivileged user, where the OS says.
pub fn free_bytes(dir: &Path) -> Option<u64> {
    let s = rustix::fs::statvfs(dir).ok()?;
    Some(s.f_bavail.saturating_mul(s.f_frsize))
}

/// `1.5 MiB`, `300 KiB`.
fn size(n: u64) -> String {
    if n >= 1 << 20 {
        format!("{:.1} MiB", n as f64 / (1 << 20) as f64)
    } else {
        format!("{} KiB", n.div_ceil(1 << 10))
    }
}

/// Refuse to start `plan` when the chunks `missing` and its file will not fit (see the module
/// doc). The length of a range to the end of the file is not known before it arrives: it
/// counts as nothing here.
pub fn check(f: &Fetcher, plan: &StepPlan, missing: &[usize]) -> Result<(), FetchError> {
    let len = |i: &usize| plan.chunks.get(*i).and_then(|c| c.range.len()).unwrap_or(0);
    let to_download: u64 = missing.iter().map(|i| len(i) + PER_FILE).sum();
    let whole = plan.known_bytes() + PER_FILE;
    let largest = (0..plan.chunks.len()).map(|i| len(&i)).max().unwrap_or(0) + PER_FILE;
    let cache = f.cache.dir();
    let out = plan.out.parent().unwrap_or(Path::new("."));
    let dev = |p: &Path| std::fs::metadata(p).map(|m| m.dev()).ok();
    let name = plan
        .out
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let short = |dir: &Path, need: u64, what: &str| -> Result<(), FetchError> {
        let Some(free) = free_bytes(dir) else {
            return Ok(());
        };
        if need <= free {
            return Ok(());
        }
        Err(FetchError::Space {
            path: dir.to_path_buf(),
            msg: format!(
                "not enough free space for {name}: it needs {} ({what}), {} is available",
                size(need),
                size(free)
            ),
        })
    };
    if dev(cache).is_some() && dev(cache) == dev(out) {
        short(
            out,
            to_download + largest,
            "the ranges still to download, and one range more while the file is assembled",
        )
    } else {
        short(cache, to_download, "the ranges still to download")?;
        short(
            out,
            whole,
            &format!("the step's file; the cache is on {}", shown(cache)),
        )
    }
}
