//! Writing output without destroying what is not output and without leaving half a file: the
//! one file-commit mechanism of the whole program (ingest, render, flight, fetch and the rest).
//!
//! - **One file** ([`write_atomic`]): written to a temporary file created exclusively (never
//!   through an existing name, so a planted symbolic link is never followed) under an
//!   unpredictable name in the target's folder, synced, then renamed over the target. A
//!   reader sees the old file or the new one, never a mix; on any error the temporary is
//!   removed and the target is untouched.
//! - **Only regular files are replaced** ([`check_output`]): a device node (`/dev/null`), a
//!   FIFO, a directory, a socket or a symbolic link at the target is refused with an error
//!   naming it, before any work and again just before the rename. An output that is one of
//!   the command's inputs is refused too ([`ensure_not_input`]).
//! - **A CloudMap's PNG and sidecar commit together** ([`write_pair`]), with its extra images
//!   when it has them ([`write_set`]): see their docs.
//! - **Many files staged, then committed as a set** ([`StagingDir`], [`commit_staged`]): a
//!   series' step maps, a flight's frames. Renames happen under a lock across processes
//!   ([`write_pair`]'s) and the in-process commit lock; a failed rename puts back what moved.
//! - **Temporaries are accounted for**: each temporary file and staging folder is registered
//!   while it exists, and each folder a run creates for its output ([`create_folder`]), so
//!   the binary's signal handler can remove them ([`cleanup_temps`]); ones a killed process
//!   left behind are swept from the folder by the next write or staging there once older than
//!   [`STALE_TEMP_AGE`].

use std::collections::BTreeSet;
use std::ffi::{OsStr, OsString};
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, SystemTime};

use tempfile::TempPath;

use crate::error::{shown, IngestError, Result};

/// Every temporary file stratus writes is named `.NAME.RANDOM.stratus-tmp` beside `NAME`.
pub const TEMP_SUFFIX: &str = ".stratus-tmp";

/// The previous PNG, kept during a pair's commit, is named `.NAME.RANDOM.stratus-kept`.
pub const KEPT_SUFFIX: &str = ".stratus-kept";

/// A temporary of ours untouched for this long belongs to a process that is gone: the next
/// write to its folder removes it. (A live writer touches its temporary continuously and holds
/// it only for the seconds a map takes to write.)
pub const STALE_TEMP_AGE: Duration = Duration::from_secs(15 * 60);

/// A flight's staging folder inside its output folder is named `.stratus-frames.RANDOM`.
pub const FRAMES_STAGING_PREFIX: &str = ".stratus-frames.";

/// Temporaries (files and staging folders) that exist now, for [`cleanup_temps`].
static LIVE: Mutex<BTreeSet<PathBuf>> = Mutex::new(BTreeSet::new());
/// Folders this run created for its output, outermost first: [`cleanup_temps`] removes them
/// when empty.
static CREATED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Held while renames put output in place, so [`cleanup_temps`] never cuts a pair in half.
static COMMIT: Mutex<()> = Mutex::new(());
/// Set by [`cleanup_temps`]: no temporary is created and nothing is committed after it.
static SHUTTING_DOWN: AtomicBool = AtomicBool::new(false);

/// The data behind these locks is valid whatever a panicking holder was doing.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Remove every temporary file and staging folder this process has open, then the folders it
/// created for its output that are empty, innermost first, and refuse to create or commit any
/// more: for the binary's INT/TERM/HUP handler, which exits afterwards. A pair (or a staged
/// set) in the middle of its renames is let finish first, so an interrupted write leaves the
/// old files or the new ones. Returns how many temporaries were removed.
///
/// Call it from an ordinary thread (such as a signal-handling thread), not from inside an
/// async signal handler: it takes locks.
pub fn cleanup_temps() -> usize {
    SHUTTING_DOWN.store(true, Ordering::SeqCst);
    let _commit = lock(&COMMIT);
    let live = std::mem::take(&mut *lock(&LIVE));
    // Staging folders ([`StagingDir`]) are registered too, hence the folder removal.
    let removed = live
        .iter()
        .filter(|p| fs::remove_file(p).is_ok() || fs::remove_dir_all(p).is_ok())
        .count();
    let created = std::mem::take(&mut *lock(&CREATED));
    remove_if_empty(&created);
    removed
}

/// Create the folder `out` and any missing parents; returns the folders created, outermost
/// first. Each is removed by [`cleanup_temps`] if still empty, for the rest of the run; on an
/// error the caller removes them with [`remove_if_empty`].
pub fn create_folder(out: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut missing: Vec<PathBuf> = out
        .ancestors()
        .filter(|p| !p.as_os_str().is_empty())
        .take_while(|p| fs::symlink_metadata(p).is_err())
        .map(Path::to_path_buf)
        .collect();
    missing.reverse();
    fs::create_dir_all(out)?;
    lock(&CREATED).extend(missing.iter().cloned());
    Ok(missing)
}

/// Remove those of `dirs` (outermost first, as [`create_folder`] returns them) that are
/// empty, innermost first. Never removes a folder that holds anything.
pub fn remove_if_empty(dirs: &[PathBuf]) {
    for d in dirs.iter().rev() {
        let _ = fs::remove_dir(d);
    }
}

/// Paths of the temporary files that exist now (for tests and diagnostics).
pub fn live_temps() -> Vec<PathBuf> {
    lock(&LIVE).iter().cloned().collect()
}

/// Refuse `path` as an output unless it is absent or a regular file: nothing else (a device
/// node, a FIFO, a directory, a socket, a symbolic link) is ever replaced. Cheap; commands call
/// it before their work so a bad `--out` fails at once.
pub fn check_output(path: &Path) -> Result<()> {
    if path.file_name().is_none() {
        return Err(IngestError::write(path, "it names no file"));
    }
    match fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_file() => Ok(()),
        Ok(m) => Err(IngestError::NotRegularFile {
            path: path.to_path_buf(),
            kind: kind_of(&m.file_type()),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(IngestError::write(path, e)),
    }
}

pub(crate) fn kind_of(t: &fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a directory"
    } else if t.is_symlink() {
        "a symbolic link"
    } else {
        "something else"
    }
}

/// Refuse `output` when it is one of `inputs`: the same file by identity (device and inode, so
/// hard links, symbolic links and `./` spellings are caught), not just the same spelling. An
/// output that does not exist yet is no input.
pub fn ensure_not_input(output: &Path, inputs: &[&Path]) -> Result<()> {
    for &input in inputs {
        if same_file(output, input) {
            return Err(IngestError::OutputIsInput {
                output: output.to_path_buf(),
                input: input.to_path_buf(),
            });
        }
    }
    Ok(())
}

fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (fs::metadata(a), fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        matches!((fs::canonicalize(a), fs::canonicalize(b)), (Ok(x), Ok(y)) if x == y)
    }
}

fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A temporary file of ours beside the file it will become, registered while it exists and
/// removed when dropped unless it was renamed into place.
struct Temp {
    path: Option<TempPath>,
}

impl Temp {
    fn create(target: &Path) -> Result<(File, Temp)> {
        let name = target
            .file_name()
            .ok_or_else(|| IngestError::write(target, "it names no file"))?;
        let mut prefix = OsString::from(".");
        prefix.push(name);
        prefix.push(".");
        let mut b = tempfile::Builder::new();
        b.prefix(&prefix).suffix(TEMP_SUFFIX).rand_bytes(10);
        #[cfg(unix)]
        {
            // As `File::create` would make it (less the umask), not the temp default 0600.
            use std::os::unix::fs::PermissionsExt;
            b.permissions(fs::Permissions::from_mode(0o666));
        }
        let dir = parent_dir(target);
        // Created and registered under one lock, after the shutdown check, so that
        // `cleanup_temps` either sees this file or this call sees the shutdown.
        let mut live = lock(&LIVE);
        if SHUTTING_DOWN.load(Ordering::SeqCst) {
            return Err(IngestError::Interrupted {
                path: target.to_path_buf(),
            });
        }
        let (file, path) = b
            .tempfile_in(dir)
            .map_err(|e| {
                // tempfile appends ` at path "…"` (the random temp name) to the OS error: the
                // folder is named already, so keep the OS error alone.
                let full = e.to_string();
                let os = full.split(" at path ").next().unwrap_or(&full).to_string();
                IngestError::write(
                    target,
                    format!("cannot create a temporary file in {}: {os}", shown(dir)),
                )
            })?
            .into_parts();
        live.insert(path.to_path_buf());
        Ok((file, Temp { path: Some(path) }))
    }

    /// Rename into place over `target` (callers hold [`commit_guard`]).
    fn persist(mut self, target: &Path) -> std::io::Result<()> {
        let Some(p) = self.path.take() else {
            return Err(std::io::Error::other("temporary file already used"));
        };
        let key = p.to_path_buf();
        match p.persist(target) {
            Ok(()) => {
                lock(&LIVE).remove(&key);
                Ok(())
            }
            Err(e) => {
                self.path = Some(e.path);
                Err(e.error)
            }
        }
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        if let Some(p) = self.path.take() {
            lock(&LIVE).remove(&p.to_path_buf());
            // Dropping the TempPath removes the file.
        }
    }
}

/// The in-process commit lock, refused once the process is shutting down.
fn commit_guard(path: &Path) -> Result<MutexGuard<'static, ()>> {
    let g = lock(&COMMIT);
    if SHUTTING_DOWN.load(Ordering::SeqCst) {
        return Err(IngestError::Interrupted {
            path: path.to_path_buf(),
        });
    }
    Ok(g)
}

/// Write `body` to a new temporary beside `path`, flush and sync it; returns it unrenamed.
fn write_temp<F>(path: &Path, body: F) -> Result<Temp>
where
    F: FnOnce(&mut BufWriter<File>) -> std::result::Result<(), String>,
{
    let (file, tmp) = Temp::create(path)?;
    let mut w = BufWriter::new(file);
    body(&mut w).map_err(|m| IngestError::write(path, m))?;
    let file = w
        .into_inner()
        .map_err(|e| IngestError::write(path, e.error()))?;
    file.sync_all().map_err(|e| IngestError::write(path, e))?;
    Ok(tmp)
}

/// Write one file atomically: `body` writes to a temporary beside `path`, which is then
/// renamed over it. On any error the temporary is removed and `path` is untouched; `path` must
/// be absent or a regular file ([`check_output`]).
pub fn write_atomic<F>(path: &Path, body: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> std::result::Result<(), String>,
{
    check_output(path)?;
    sweep_stale(parent_dir(path));
    let tmp = write_temp(path, body)?;
    let _g = commit_guard(path)?;
    // It may have been replaced by something else while we wrote.
    check_output(path)?;
    tmp.persist(path).map_err(|e| IngestError::write(path, e))
}

/// A fresh 128-bit identifier (32 hex digits), different for every call in every process:
/// what binds a PNG to its sidecar. Not a secret, so the standard library's randomly keyed
/// hasher is randomness enough.
pub(crate) fn new_image_id() -> String {
    use std::collections::hash_map::RandomState;
    use std::hash::{BuildHasher, Hasher};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let now = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let mut id = String::with_capacity(32);
    for _ in 0..2 {
        let mut h = RandomState::new().build_hasher();
        h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
        h.write_u128(now);
        h.write_u32(std::process::id());
        id.push_str(&format!("{:016x}", h.finish()));
    }
    id
}

/// Write a CloudMap's PNG (`png`) and its sidecar (`png` with `.json`) as one pair.
///
/// `write_png` writes the PNG given the pair's fresh image id (which the PNG carries in a text
/// chunk); `sidecar` returns the sidecar's bytes given the PNG's file name and that id.
///
/// The design, and why it holds:
/// 1. Both files are written completely to temporaries first (see [`write_atomic`]), so
///    nothing the user has is touched while the long work runs; any error there leaves the
///    previous pair exactly as it was.
/// 2. The renames happen under an exclusive lock on `.MAP.json.lock` (`flock`, released by the
///    kernel if the process dies; the holder deletes the file, and a waiter that finds the
///    file it locked deleted tries again), so two writers to the same map never interleave:
///    the last to commit wins whole.
/// 3. Inside the lock: the previous PNG is kept under a hard link (a copy where links are not
///    supported), the new PNG is renamed into place, then the sidecar. If the sidecar rename
///    fails, the previous PNG is put back, so the previous pair is whole again; on success the
///    kept one is removed.
/// 4. What no rename order can prevent — a reader between the two renames, or a power loss
///    there — is caught rather than trusted: the sidecar (format 2) records the image id and
///    the loader refuses a PNG that does not carry it (after a short retry, which covers the
///    reader case).
///
/// The names stay `MAP.png` and `MAP.json`, as GIS tools and the docs expect.
pub fn write_pair<P, S>(png: &Path, inputs: &[&Path], write_png: P, sidecar: S) -> Result<PathBuf>
where
    P: FnOnce(&mut BufWriter<File>, &str) -> std::result::Result<(), String>,
    S: FnOnce(&str, &str) -> Result<Vec<u8>>,
{
    write_set(png, inputs, write_png, Vec::new(), sidecar)
}

/// Writes one extra image of a map's set: gets the file and the set's image id.
pub type ExtraWriter<'a> =
    Box<dyn FnOnce(&mut BufWriter<File>, &str) -> std::result::Result<(), String> + 'a>;

/// [`write_pair`] for a map with extra images (version 3: structure, type, winds): every
/// image is written to a temporary first, all carry the same image id, and they are renamed
/// into place under the pair's lock before the PNG, which goes before the sidecar; if any
/// rename fails, every file already renamed is put back as it was, so the previous set stays
/// whole. Readers trust an extra image only when it carries the sidecar's image id, as for
/// the PNG. `extras` are (path, writer); their names go in the sidecar.
pub fn write_set<'a, P, S>(
    png: &Path,
    inputs: &[&Path],
    write_png: P,
    extras: Vec<(PathBuf, ExtraWriter<'a>)>,
    sidecar: S,
) -> Result<PathBuf>
where
    P: FnOnce(&mut BufWriter<File>, &str) -> std::result::Result<(), String>,
    S: FnOnce(&str, &str) -> Result<Vec<u8>>,
{
    let json_path = png.with_extension("json");
    if json_path == png {
        return Err(IngestError::write(
            png,
            "a CloudMap's PNG cannot be named like its .json sidecar",
        ));
    }
    let name = png.file_name().and_then(|n| n.to_str()).ok_or_else(|| {
        IngestError::write(
            png,
            "the file name is not valid UTF-8, and the sidecar records it as text; choose a UTF-8 name",
        )
    })?;
    let mut outs: Vec<PathBuf> = extras.iter().map(|(p, _)| p.clone()).collect();
    outs.extend([png.to_path_buf(), json_path.clone()]);
    for (k, out) in outs.iter().enumerate() {
        if outs[..k].contains(out) {
            return Err(IngestError::write(out, "named twice in one map's files"));
        }
        check_output(out)?;
        ensure_not_input(out, inputs)?;
    }
    sweep_stale(parent_dir(png));
    let id = new_image_id();
    // The extra images first, then the PNG: all complete before anything is renamed.
    let mut temps = Vec::with_capacity(extras.len() + 1);
    for (path, write) in extras {
        let tmp = write_temp(&path, |w| write(w, &id))?;
        temps.push((path, tmp));
    }
    let png_tmp = write_temp(png, |w| write_png(w, &id))?;
    temps.push((png.to_path_buf(), png_tmp));
    let json = sidecar(name, &id)?;
    let json_tmp = write_temp(&json_path, |w| {
        w.write_all(&json).map_err(|e| e.to_string())
    })?;
    let _pair = PairLock::acquire(&json_path)?;
    let _g = commit_guard(png)?;
    for out in &outs {
        check_output(out)?;
    }
    commit_set(temps, &json_path, json_tmp)?;
    Ok(json_path)
}

#[cfg(test)]
thread_local! {
    /// Test hook: make the sidecar rename of the next pair fail.
    pub(crate) static FAIL_SIDECAR_RENAME: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// A file renamed into place during a commit, and what was there before it.
struct Committed {
    path: PathBuf,
    kept: Option<PathBuf>,
}

/// Put back every file of `done` as it was before the commit (best effort; what could not be
/// put back is named in the returned text).
fn roll_back(done: Vec<Committed>) -> String {
    let mut also = String::new();
    for c in done.into_iter().rev() {
        let restored = match &c.kept {
            Some(k) => fs::rename(k, &c.path),
            None => fs::remove_file(&c.path),
        };
        if let Err(r) = restored {
            also.push_str(&format!(
                "; the previous {} could not be put back ({r}){}",
                shown(&c.path),
                c.kept
                    .as_deref()
                    .map_or_else(String::new, |k| format!(" and is kept as {}", shown(k)))
            ));
        }
    }
    also
}

fn commit_set(files: Vec<(PathBuf, Temp)>, json: &Path, json_tmp: Temp) -> Result<()> {
    let mut done: Vec<Committed> = Vec::with_capacity(files.len());
    for (path, tmp) in files {
        let kept = match keep_previous(&path) {
            Ok(k) => k,
            Err(e) => {
                roll_back(done);
                return Err(e);
            }
        };
        if let Err(e) = tmp.persist(&path) {
            if let Some(k) = &kept {
                let _ = fs::remove_file(k);
            }
            let also = roll_back(done);
            return Err(IngestError::write(&path, format!("{e}{also}")));
        }
        done.push(Committed { path, kept });
    }
    #[cfg(test)]
    let json_result = if FAIL_SIDECAR_RENAME.with(|f| f.replace(false)) {
        Err(std::io::Error::other("injected failure"))
    } else {
        json_tmp.persist(json)
    };
    #[cfg(not(test))]
    let json_result = json_tmp.persist(json);
    if let Err(e) = json_result {
        let also = roll_back(done);
        return Err(IngestError::write(json, format!("{e}{also}")));
    }
    for c in done {
        if let Some(k) = c.kept {
            let _ = fs::remove_file(k);
        }
    }
    Ok(())
}

/// Keep the file now at `png` (if any) reachable under a fresh temporary name: a hard link, or
/// a copy where the file system has none. One a killed process leaves is swept later.
fn keep_previous(png: &Path) -> Result<Option<PathBuf>> {
    match fs::symlink_metadata(png) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(IngestError::write(png, e)),
        Ok(_) => {}
    }
    let mut name = OsString::from(".");
    name.push(png.file_name().unwrap_or_default());
    name.push(format!(".{}{KEPT_SUFFIX}", &new_image_id()[..12]));
    let kept = parent_dir(png).join(name);
    // `hard_link` never replaces an existing name, so the kept name is ours alone.
    if fs::hard_link(png, &kept).is_err() {
        let mut src = File::open(png).map_err(|e| IngestError::write(png, e))?;
        let mut dst = File::options()
            .write(true)
            .create_new(true)
            .open(&kept)
            .map_err(|e| IngestError::write(&kept, e))?;
        std::io::copy(&mut src, &mut dst)
            .and_then(|_| dst.sync_all())
            .map_err(|e| {
                let _ = fs::remove_file(&kept);
                IngestError::write(&kept, e)
            })?;
    }
    Ok(Some(kept))
}

/// A private folder where several files are written completely before any is put in place
/// ([`commit_staged`]): a forecast series' step maps and its sidecar, a flight's frames.
/// Registered while it exists, and removed with everything in it when dropped, so an error
/// leaves nothing behind; one a killed run left is swept once older than [`STALE_TEMP_AGE`].
pub struct StagingDir {
    dir: Option<tempfile::TempDir>,
}

impl StagingDir {
    /// A fresh folder beside `target` (a file the staged set will include), named like a
    /// temporary (`.NAME.RANDOM.stratus-tmp`).
    pub fn create(target: &Path) -> Result<StagingDir> {
        let name = target
            .file_name()
            .ok_or_else(|| IngestError::write(target, "it names no file"))?;
        let mut prefix = OsString::from(".");
        prefix.push(name);
        prefix.push(".");
        let dir = parent_dir(target);
        Self::make(target, dir, &prefix, TEMP_SUFFIX, |e| {
            format!("cannot create a staging folder in {}: {e}", shown(dir))
        })
    }

    /// A fresh folder inside the output folder `folder`, named `PREFIX` and random
    /// characters ([`FRAMES_STAGING_PREFIX`] for a flight's frames).
    pub fn create_in(folder: &Path, prefix: &str) -> Result<StagingDir> {
        Self::make(folder, folder, OsStr::new(prefix), "", |e| {
            format!("cannot create a staging folder: {e}")
        })
    }

    /// Sweep `dir`, then create and register the folder (refused once shutting down);
    /// `what` is the path errors name.
    fn make(
        what: &Path,
        dir: &Path,
        prefix: &OsStr,
        suffix: &str,
        fault: impl FnOnce(std::io::Error) -> String,
    ) -> Result<StagingDir> {
        sweep_stale(dir);
        let mut live = lock(&LIVE);
        if SHUTTING_DOWN.load(Ordering::SeqCst) {
            return Err(IngestError::Interrupted {
                path: what.to_path_buf(),
            });
        }
        let tmp = tempfile::Builder::new()
            .prefix(prefix)
            .suffix(suffix)
            .rand_bytes(10)
            .tempdir_in(dir)
            .map_err(|e| IngestError::write(what, fault(e)))?;
        live.insert(tmp.path().to_path_buf());
        Ok(StagingDir { dir: Some(tmp) })
    }

    pub fn path(&self) -> &Path {
        self.dir.as_ref().map_or(Path::new("."), |d| d.path())
    }
}

impl Drop for StagingDir {
    fn drop(&mut self) {
        if let Some(d) = self.dir.take() {
            lock(&LIVE).remove(d.path());
            // Dropping the TempDir removes the folder and what it holds.
        }
    }
}

/// Put staged files in place: each `(staged, target)` is renamed over its target in order,
/// under the lock of `lock_on`'s pair (the set's last file, written last) and the commit
/// lock. A target that is not absent or a regular file is refused before anything moves; if
/// any rename fails, every file already moved is put back as it was (the previous files
/// restored, new ones removed), so the previous set stays whole.
pub fn commit_staged(files: &[(PathBuf, PathBuf)], lock_on: &Path) -> Result<()> {
    commit_staged_then(files, lock_on, || ())
}

/// [`commit_staged`], then `after` while the locks are still held (a flight removes the
/// frames of an earlier, longer run there, so a signal finds either set whole).
pub fn commit_staged_then<T>(
    files: &[(PathBuf, PathBuf)],
    lock_on: &Path,
    after: impl FnOnce() -> T,
) -> Result<T> {
    let _pair = PairLock::acquire(lock_on)?;
    let _g = commit_guard(lock_on)?;
    for (_, target) in files {
        check_output(target)?;
    }
    let mut done: Vec<Committed> = Vec::with_capacity(files.len());
    for (staged, target) in files {
        let kept = match keep_previous(target) {
            Ok(k) => k,
            Err(e) => {
                roll_back(done);
                return Err(e);
            }
        };
        if let Err(e) = fs::rename(staged, target) {
            if let Some(k) = &kept {
                let _ = fs::remove_file(k);
            }
            let also = roll_back(done);
            return Err(IngestError::write(target, format!("{e}{also}")));
        }
        done.push(Committed {
            path: target.clone(),
            kept,
        });
    }
    for c in done {
        if let Some(k) = c.kept {
            let _ = fs::remove_file(k);
        }
    }
    Ok(after())
}

/// An exclusive lock across processes on `target`: the lock file `.NAME.lock` beside it, the
/// one a pair's commit takes. A Zarr store is created and appended to under it, so racing
/// writers run one after the other. Released when dropped.
pub struct OutputLock {
    _lock: PairLock,
}

/// Take [`OutputLock`] on `target`, waiting for its holder.
pub fn lock_output(target: &Path) -> Result<OutputLock> {
    Ok(OutputLock {
        _lock: PairLock::acquire(target)?,
    })
}

/// Exclusive lock on a map's pair, across processes (see [`write_pair`]).
struct PairLock {
    path: PathBuf,
    _file: File,
}

impl PairLock {
    fn lock_path(sidecar: &Path) -> PathBuf {
        let mut name = OsString::from(".");
        name.push(sidecar.file_name().unwrap_or_default());
        name.push(".lock");
        parent_dir(sidecar).join(name)
    }

    #[cfg(unix)]
    fn acquire(sidecar: &Path) -> Result<PairLock> {
        use rustix::fs::{flock, open, FlockOperation, Mode, OFlags};
        use std::os::unix::fs::MetadataExt;
        let path = Self::lock_path(sidecar);
        let err =
            |e: &dyn std::fmt::Display| IngestError::write(&path, format!("cannot lock: {e}"));
        loop {
            // NOFOLLOW: a planted symbolic link makes this fail, never open its target.
            let fd = open(
                &path,
                OFlags::RDWR | OFlags::CREATE | OFlags::NOFOLLOW | OFlags::CLOEXEC,
                Mode::from_raw_mode(0o644),
            )
            .map_err(|e| err(&e))?;
            let file = File::from(fd);
            flock(&file, FlockOperation::LockExclusive).map_err(|e| err(&e))?;
            // The holder before us deletes the file on release: locked a deleted file, retry.
            let held = file.metadata().map_err(|e| err(&e))?;
            match fs::symlink_metadata(&path) {
                Ok(now) if now.dev() == held.dev() && now.ino() == held.ino() => {
                    return Ok(PairLock { path, _file: file });
                }
                Ok(_) => continue,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
                Err(e) => return Err(err(&e)),
            }
        }
    }

    /// Without `flock`: the lock is the file's existence. One left by a killed process is
    /// taken over after a minute (commits take milliseconds).
    #[cfg(not(unix))]
    fn acquire(sidecar: &Path) -> Result<PairLock> {
        let path = Self::lock_path(sidecar);
        let start = std::time::Instant::now();
        loop {
            match File::options().write(true).create_new(true).open(&path) {
                Ok(file) => return Ok(PairLock { path, _file: file }),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    if start.elapsed() > Duration::from_secs(60) {
                        let _ = fs::remove_file(&path);
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
                Err(e) => return Err(IngestError::write(&path, format!("cannot lock: {e}"))),
            }
        }
    }
}

impl Drop for PairLock {
    fn drop(&mut self) {
        // Deleted while still held (the file closes after this), so no lock file stays.
        let _ = fs::remove_file(&self.path);
    }
}

/// What a name in an output folder is to us.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Ours {
    /// `.NAME.RANDOM.stratus-tmp`, or the `.NAME.png.tmpPID` / `.NAME.json.tmpPID` of
    /// versions before it.
    Temp,
    /// `.NAME.RANDOM.stratus-kept`: a previous PNG kept during a pair's commit.
    Kept,
    /// `.stratus-frames.RANDOM`: a flight's staging folder ([`FRAMES_STAGING_PREFIX`]).
    Frames,
}

fn ours(name: &str) -> Option<Ours> {
    if !name.starts_with('.') {
        return None;
    }
    if name.ends_with(TEMP_SUFFIX) {
        return Some(Ours::Temp);
    }
    if name.ends_with(KEPT_SUFFIX) {
        return Some(Ours::Kept);
    }
    if name.len() > FRAMES_STAGING_PREFIX.len() && name.starts_with(FRAMES_STAGING_PREFIX) {
        return Some(Ours::Frames);
    }
    let i = name.rfind(".tmp")?;
    let (head, pid) = (&name[..i], &name[i + 4..]);
    let legacy = !pid.is_empty()
        && pid.bytes().all(|b| b.is_ascii_digit())
        && (head.ends_with(".png") || head.ends_with(".json"));
    legacy.then_some(Ours::Temp)
}

/// Time since a file of ours last changed. A temporary's writer touches it as it writes, so
/// its modification time tells; a kept PNG is a hard link carrying the old PNG's modification
/// time, so its status-change time (set when the link was made) tells where there is one.
fn age(kind: Ours, m: &fs::Metadata) -> Option<Duration> {
    let changed = match kind {
        #[cfg(unix)]
        Ours::Kept => {
            use std::os::unix::fs::MetadataExt;
            SystemTime::UNIX_EPOCH + Duration::from_secs(u64::try_from(m.ctime()).ok()?)
        }
        _ => m.modified().ok()?,
    };
    SystemTime::now().duration_since(changed).ok()
}

/// Remove our temporaries in `dir` that are older than [`STALE_TEMP_AGE`] and not this
/// process's: what a killed run left. Temporaries and kept PNGs are files, staging folders
/// ([`StagingDir`]) folders: anything else under such a name is left alone. Best effort;
/// never follows a link.
fn sweep_stale(dir: &Path) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let Some(kind) = e.file_name().to_str().and_then(ours) else {
            continue;
        };
        let path = e.path();
        let Ok(m) = fs::symlink_metadata(&path) else {
            continue;
        };
        let (file, folder) = (m.file_type().is_file(), m.file_type().is_dir());
        let shape = match kind {
            Ours::Temp => file || folder,
            Ours::Kept => file,
            Ours::Frames => folder,
        };
        if shape
            && age(kind, &m).is_some_and(|a| a > STALE_TEMP_AGE)
            && !lock(&LIVE).contains(&path)
        {
            let _ = if folder {
                fs::remove_dir_all(&path)
            } else {
                fs::remove_file(&path)
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temp_names_are_recognised_and_nothing_else() {
        for (name, kind) in [
            (".m.png.Ab3dE9xYz1.stratus-tmp", Ours::Temp),
            (".m.png.tmp1234", Ours::Temp),
            (".m.json.tmp7", Ours::Temp),
            (".m.png.Ab3dE9xYz1.stratus-kept", Ours::Kept),
            (".stratus-frames.Ab3dE9xYz1", Ours::Frames),
        ] {
            assert_eq!(ours(name), Some(kind), "{name}");
        }
        for theirs in [
            "m.png",
            ".bashrc.tmp1",
            ".m.png.tmp",
            ".m.png.tmp12a",
            "m.png.stratus-tmp",
            ".m.json.lock",
            ".stratus-frames.",
            "stratus-frames.Ab3dE9xYz1",
        ] {
            assert_eq!(ours(theirs), None, "{theirs}");
        }
    }

    #[test]
    fn ids_differ() {
        let a: BTreeSet<String> = (0..1000).map(|_| new_image_id()).collect();
        assert_eq!(a.len(), 1000);
        assert!(a.iter().all(|id| id.len() == 32));
    }

    #[test]
    fn a_failed_sidecar_rename_puts_the_previous_png_back() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("m.png");
        let json = dir.path().join("m.json");
        let write = |tag: &'static str| {
            write_pair(
                &png,
                &[],
                move |w, _| w.write_all(tag.as_bytes()).map_err(|e| e.to_string()),
                move |_, _| Ok(format!("{tag}.json").into_bytes()),
            )
        };
        write("old").unwrap();
        FAIL_SIDECAR_RENAME.with(|f| f.set(true));
        let e = write("new").unwrap_err();
        assert!(e.to_string().contains("injected failure"), "{e}");
        assert_eq!(fs::read(&png).unwrap(), b"old");
        assert_eq!(fs::read(&json).unwrap(), b"old.json");
        let mut left: Vec<_> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        left.sort();
        assert_eq!(
            left,
            ["m.json", "m.png"],
            "temporaries or a lock left behind"
        );
        // With no previous pair, a failed sidecar leaves no PNG either.
        let png2 = dir.path().join("n.png");
        FAIL_SIDECAR_RENAME.with(|f| f.set(true));
        write_pair(
            &png2,
            &[],
            |w, _| w.write_all(b"x").map_err(|e| e.to_string()),
            |_, _| Ok(b"{}".to_vec()),
        )
        .unwrap_err();
        assert!(!png2.exists());
    }

    #[test]
    fn a_failed_sidecar_rename_puts_every_extra_image_back() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("m.png");
        let extra = dir.path().join("m.base.png");
        let write = |tag: &'static str| {
            let extras: Vec<(PathBuf, ExtraWriter)> = vec![(
                extra.clone(),
                Box::new(move |w: &mut BufWriter<File>, id: &str| {
                    w.write_all(format!("{tag} {id}").as_bytes())
                        .map_err(|e| e.to_string())
                }),
            )];
            write_set(
                &png,
                &[],
                move |w, _| w.write_all(tag.as_bytes()).map_err(|e| e.to_string()),
                extras,
                move |_, id| Ok(format!("{tag} {id}").into_bytes()),
            )
        };
        write("old").unwrap();
        let before = fs::read(&extra).unwrap();
        // The extra image and the sidecar carry the same id.
        assert_eq!(before, fs::read(dir.path().join("m.json")).unwrap());
        FAIL_SIDECAR_RENAME.with(|f| f.set(true));
        write("new").unwrap_err();
        assert_eq!(fs::read(&extra).unwrap(), before);
        assert_eq!(fs::read(&png).unwrap(), b"old");
        let mut left: Vec<_> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        left.sort();
        assert_eq!(left, ["m.base.png", "m.json", "m.png"]);
    }

    #[test]
    fn stale_temps_are_swept_and_fresh_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let stale = d.join(".m.png.tmp4242");
        let stale_new = d.join(".m.png.BBBBBBBBBB.stratus-tmp");
        let fresh = d.join(".m.png.AAAAAAAAAA.stratus-tmp");
        let user = d.join(".notes.tmp1");
        let old = SystemTime::now() - STALE_TEMP_AGE - Duration::from_secs(60);
        for p in [&stale, &stale_new, &fresh, &user] {
            let f = File::create(p).unwrap();
            if p != &fresh {
                f.set_modified(old).unwrap();
            }
        }
        write_atomic(&d.join("m.png"), |w| {
            w.write_all(b"png").map_err(|e| e.to_string())
        })
        .unwrap();
        assert!(
            !stale.exists() && !stale_new.exists(),
            "stale temporaries stay"
        );
        assert!(
            fresh.exists(),
            "a fresh temporary (maybe a live writer's) was removed"
        );
        assert!(user.exists(), "a file that is not ours was removed");
    }

    #[test]
    fn stale_staging_folders_are_swept_and_fresh_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let frames = d.join(".stratus-frames.AAAAAAAAAA");
        let series = d.join(".s.json.BBBBBBBBBB.stratus-tmp");
        let fresh = d.join(".stratus-frames.CCCCCCCCCC");
        let kept_dir = d.join(".m.png.DDDDDDDDDD.stratus-kept");
        let old = SystemTime::now() - STALE_TEMP_AGE - Duration::from_secs(60);
        for p in [&frames, &series, &fresh, &kept_dir] {
            fs::create_dir(p).unwrap();
            fs::write(p.join("frame-00000.png"), b"x").unwrap();
            if p != &fresh {
                File::open(p).unwrap().set_modified(old).unwrap();
            }
        }
        let ours = StagingDir::create_in(d, FRAMES_STAGING_PREFIX).unwrap();
        assert!(ours.path().exists());
        assert!(
            !frames.exists() && !series.exists(),
            "stale staging folders stay"
        );
        assert!(fresh.exists(), "a fresh staging folder was removed");
        assert!(
            kept_dir.exists(),
            "a folder under a kept PNG's name was removed"
        );
        let p = ours.path().to_path_buf();
        drop(ours);
        assert!(!p.exists(), "a dropped staging folder stays");
    }

    #[test]
    fn a_staged_set_commits_and_runs_its_after_step_under_the_lock() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let staging = StagingDir::create_in(d, FRAMES_STAGING_PREFIX).unwrap();
        fs::write(d.join("a"), b"old").unwrap();
        let files: Vec<(PathBuf, PathBuf)> = ["a", "b"]
            .iter()
            .map(|n| {
                fs::write(staging.path().join(n), n.as_bytes()).unwrap();
                (staging.path().join(n), d.join(n))
            })
            .collect();
        let lock_file = PairLock::lock_path(&d.join("b"));
        let held = commit_staged_then(&files, &d.join("b"), || lock_file.exists()).unwrap();
        assert!(held, "the after step ran without the lock");
        assert_eq!(fs::read(d.join("a")).unwrap(), b"a");
        assert_eq!(fs::read(d.join("b")).unwrap(), b"b");
        assert!(!lock_file.exists());
    }

    #[test]
    fn a_pair_waits_for_the_lock_and_the_lock_file_goes() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("m.png");
        let json = dir.path().join("m.json");
        let held = PairLock::acquire(&json).unwrap();
        let lock_file = PairLock::lock_path(&json);
        assert!(lock_file.exists());
        std::thread::scope(|s| {
            let writer = s.spawn(|| {
                write_pair(
                    &png,
                    &[],
                    |w, _| w.write_all(b"png").map_err(|e| e.to_string()),
                    |_, _| Ok(b"{}".to_vec()),
                )
            });
            std::thread::sleep(Duration::from_millis(300));
            assert!(
                !png.exists(),
                "the pair was committed while another held its lock"
            );
            drop(held);
            writer.join().unwrap().unwrap();
        });
        assert_eq!(fs::read(&png).unwrap(), b"png");
        assert!(!lock_file.exists(), "the lock file stays");
    }
}
