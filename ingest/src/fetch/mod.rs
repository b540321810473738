//! Downloading the GFS fields stratus needs, not whole forecast files: the run's `.idx`
//! inventory says where each message lies ([`idx`], which refuses what no GFS file's
//! inventory can be), the fields and levels asked for pick messages ([`select`]), adjacent
//! ones are merged into a few byte ranges ([`plan_chunks`]) fetched a few at a time with
//! retries ([`http`]) into a cache that lets an interrupted run resume ([`cache`]).
//!
//! Nothing is held whole in memory, and nothing unchecked is kept: a range streams to its
//! cache file while each message's indicator section is checked as it arrives, then each
//! message is checked whole ([`check`]: valid GRIB2, the fields its inventory lines name,
//! its data decoding to plausible values) before the range is kept. Ranges already cached
//! are checked the same way (and against their CRC) on a re-run, every bad one dropped and
//! downloaded again. Before downloading, the free space is checked ([`space`]); the step's
//! file is then assembled from the cache, each range removed as soon as it is copied, so a
//! step needs its size once on disk, not twice. URL layouts: [`source`].

pub mod cache;
pub mod check;
pub mod http;
pub mod idx;
pub mod select;
pub mod source;
pub mod space;

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use crate::error::{shown, IngestError};
use cache::{Cache, Lookup};
pub use check::check_against_inventory;
use check::{describe, HeadWatch, Problem};
use http::{BodyError, ByteRange, Client};
use idx::{IdxMessage, MAX_IDX_BYTES, MAX_MESSAGE_BYTES};
use select::{FieldSpec, Levels};
use source::Run;

/// Adjacent messages are merged into one request up to this size, so a step is still a few
/// requests that can run in parallel and a failed one costs little to repeat.
pub const MAX_CHUNK_BYTES: u64 = 16 << 20;

/// Most bytes the messages picked from one step may be: 1 GiB, twice a whole GFS 0.25° step
/// file (about 500 MB), which no choice of fields can exceed. (The default fields at 0.25°
/// are about 150 MB.)
pub const MAX_STEP_BYTES: u64 = 1 << 30;

/// Why a fetch failed; one line, with any password in a URL hidden ([`source::redact`]).
#[derive(Debug)]
pub enum FetchError {
    /// The server could not be asked or did not answer as HTTP must.
    Http {
        url: String,
        range: Option<ByteRange>,
        msg: String,
    },
    /// The inventory is not one a GFS file can have.
    Inventory {
        url: String,
        msg: String,
    },
    /// The fields or levels asked for are not in the inventory.
    Select {
        url: String,
        msg: String,
    },
    /// The bytes served at `range` are not the message the inventory lists there, or are it
    /// damaged.
    Served {
        url: String,
        range: ByteRange,
        msg: String,
    },
    /// Something in the cache folder that is not ours to remove.
    Cache {
        path: PathBuf,
        msg: String,
    },
    /// Not enough free space on a file system.
    Space {
        path: PathBuf,
        msg: String,
    },
    Write(IngestError),
}

impl From<IngestError> for FetchError {
    fn from(e: IngestError) -> FetchError {
        FetchError::Write(e)
    }
}

impl std::fmt::Display for FetchError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text = match self {
            FetchError::Http { url, range, msg } => {
                let r = range.map(|r| format!(" ({r})")).unwrap_or_default();
                format!("{url}{r}: {msg}")
            }
            FetchError::Inventory { url, msg } => format!("{url}: bad inventory: {msg}"),
            FetchError::Select { url, msg } => format!("{url}: {msg}"),
            FetchError::Served { url, range, msg } => format!("{url} ({range}): {msg}"),
            FetchError::Cache { path, msg } | FetchError::Space { path, msg } => {
                format!("{}: {msg}", shown(path))
            }
            FetchError::Write(e) => e.to_string(),
        };
        f.write_str(&source::redact(&text))
    }
}

impl std::error::Error for FetchError {}

/// One request: a byte range holding `messages` (indices into the plan's messages).
#[derive(Debug, Clone, PartialEq)]
pub struct Chunk {
    pub range: ByteRange,
    pub messages: std::ops::Range<usize>,
}

/// Merge the byte ranges of `messages` (in file order) where one ends where the next starts,
/// up to `max` bytes a chunk.
pub fn plan_chunks(messages: &[IdxMessage], max: u64) -> Vec<Chunk> {
    let mut out: Vec<Chunk> = Vec::new();
    for (i, m) in messages.iter().enumerate() {
        if let Some(c) = out.last_mut() {
            let joins =
                c.range.end == Some(m.start) && m.end.is_none_or(|e| e - c.range.start <= max);
            if joins {
                c.range.end = m.end;
                c.messages.end = i + 1;
                continue;
            }
        }
        out.push(Chunk {
            range: ByteRange {
                start: m.start,
                end: m.end,
            },
            messages: i..i + 1,
        });
    }
    out
}

/// What one step needs: its URLs, the messages picked and the requests that get them.
#[derive(Debug, Clone)]
pub struct StepPlan {
    pub step: u32,
    pub grib_url: String,
    /// The file's path under the source's base: what the cache knows its ranges by, so a
    /// re-run from another source reuses them (every message is checked either way).
    pub cache_key: String,
    pub idx_url: String,
    pub messages: Vec<IdxMessage>,
    pub chunks: Vec<Chunk>,
    /// Where the step's file goes.
    pub out: PathBuf,
}

impl StepPlan {
    /// Bytes of the chunks of known length (the last message of a file has none until its
    /// answer says).
    pub fn known_bytes(&self) -> u64 {
        self.chunks.iter().filter_map(|c| c.range.len()).sum()
    }

    /// The most bytes `chunk` may be: its length, or for one that runs to the end of the
    /// file, up to its last message's start and one message more.
    fn limit(&self, chunk: &Chunk) -> u64 {
        chunk.range.len().unwrap_or_else(|| {
            let last = chunk.messages.end.saturating_sub(1);
            let start = self
                .messages
                .get(last)
                .map_or(chunk.range.start, |m| m.start);
            start - chunk.range.start + MAX_MESSAGE_BYTES
        })
    }
}

/// Told of bytes as they arrive (negative: a failed try's bytes taken back) and of bytes read
/// from the cache.
pub trait Progress: Sync {
    fn downloaded(&self, delta: i64);
    fn cached(&self, bytes: u64);
}

/// A fetch of one run: the client, the cache and what to pick.
pub struct Fetcher {
    pub client: Client,
    pub cache: Cache,
    pub run: Run,
    pub fields: Vec<FieldSpec>,
    pub levels: Levels,
    pub out_dir: PathBuf,
    /// Requests in flight at once.
    pub parallel: usize,
}

impl Fetcher {
    /// Read the step's inventory and pick its messages; refuse a pick larger than
    /// [`MAX_STEP_BYTES`].
    pub fn plan(&self, step: u32) -> Result<StepPlan, FetchError> {
        let idx_url = self.run.idx_url(step);
        let text = self.client.get_small(&idx_url, MAX_IDX_BYTES)?;
        let inv_err = |msg: String| FetchError::Inventory {
            url: idx_url.clone(),
            msg,
        };
        let text = String::from_utf8(text).map_err(|_| inv_err("it is not text".into()))?;
        let inventory = idx::parse(&text).map_err(inv_err)?;
        let want = self.run.idx_date();
        if let Some(l) = inventory
            .iter()
            .flat_map(|m| &m.lines)
            .find(|l| l.date != want)
        {
            return Err(inv_err(format!(
                "message {} is of run d={}, not d={want}",
                l.number, l.date
            )));
        }
        let messages = select::pick(&inventory, &self.fields, &self.levels).map_err(|msg| {
            FetchError::Select {
                url: idx_url.clone(),
                msg,
            }
        })?;
        let chunks = plan_chunks(&messages, MAX_CHUNK_BYTES);
        let plan = StepPlan {
            step,
            grib_url: self.run.grib_url(step),
            cache_key: self.run.file_path(step),
            idx_url: idx_url.clone(),
            messages,
            chunks,
            out: self.out_dir.join(self.run.out_name(step)),
        };
        if plan.known_bytes() > MAX_STEP_BYTES {
            return Err(inv_err(format!(
                "the {} messages picked are {} bytes, more than a GFS step can be ({} GiB)",
                plan.messages.len(),
                plan.known_bytes(),
                MAX_STEP_BYTES >> 30
            )));
        }
        Ok(plan)
    }

    /// Get every chunk of `plan` into the cache, checked (what is cached already is checked
    /// again), then write the step's file atomically from the cache, removing each range as
    /// it is copied. Returns the file's size.
    pub fn fetch(&self, plan: &StepPlan, progress: &dyn Progress) -> Result<u64, FetchError> {
        crate::output::check_output(&plan.out)?;
        let mut missing = Vec::new();
        for (i, chunk) in plan.chunks.iter().enumerate() {
            match self.cached(plan, chunk)? {
                Some(len) => progress.cached(len),
                None => missing.push(i),
            }
        }
        space::check(self, plan, &missing)?;
        self.download(plan, &missing, progress)?;
        self.assemble(plan)
    }

    /// A chunk's length if the cache holds it whole and its messages pass the checks; a bad
    /// one is removed (with a warning saying why), to be downloaded again.
    fn cached(&self, plan: &StepPlan, chunk: &Chunk) -> Result<Option<u64>, FetchError> {
        let why = match self.cache.get(&plan.cache_key, chunk.range)? {
            Lookup::Absent => return Ok(None),
            Lookup::Damaged(why) => why,
            Lookup::Whole(c) => {
                match self.check_chunk(plan, chunk, c.len, |at, n| c.read_at(at, n)) {
                    Ok(()) => return Ok(Some(c.len)),
                    Err((_, p)) => {
                        let (Problem::NotListed(m) | Problem::Damaged(m)) = p;
                        format!("{}: {m}", shown(&c.path))
                    }
                }
            }
        };
        tracing::warn!(
            "{}",
            source::redact(&format!(
                "{why}; dropped that cached range of {} ({}), downloading it again",
                plan.grib_url, chunk.range
            ))
        );
        self.cache.remove(&plan.cache_key, chunk.range);
        Ok(None)
    }

    /// Check every message of a chunk of `len` bytes, read with `read_at` (from the chunk's
    /// start); the first failure with its message's range.
    fn check_chunk(
        &self,
        plan: &StepPlan,
        chunk: &Chunk,
        len: u64,
        mut read_at: impl FnMut(u64, u64) -> std::io::Result<Vec<u8>>,
    ) -> Result<(), (ByteRange, Problem)> {
        for m in &plan.messages[chunk.messages.clone()] {
            let range = ByteRange {
                start: m.start,
                end: m.end,
            };
            let at = m.start - chunk.range.start;
            let n = m.end.map_or(len.saturating_sub(at), |e| e - m.start);
            let bytes = read_at(at, n).map_err(|e| {
                (
                    range,
                    Problem::Damaged(format!("{}: cannot be read: {e}", describe(m))),
                )
            })?;
            check::check_message(&bytes, m).map_err(|p| (range, p))?;
        }
        Ok(())
    }

    /// Download the chunks `which` of `plan` into the cache, a few at once. The first failure
    /// stops the others from starting new requests; what they finished stays cached.
    fn download(
        &self,
        plan: &StepPlan,
        which: &[usize],
        progress: &dyn Progress,
    ) -> Result<(), FetchError> {
        let first_error: Mutex<Option<FetchError>> = Mutex::new(None);
        let next = AtomicUsize::new(0);
        let stop = AtomicBool::new(false);
        let work = || loop {
            if stop.load(Ordering::SeqCst) {
                return;
            }
            let Some(chunk) = which
                .get(next.fetch_add(1, Ordering::SeqCst))
                .and_then(|&i| plan.chunks.get(i))
            else {
                return;
            };
            if let Err(e) = self.download_chunk(plan, chunk, progress) {
                stop.store(true, Ordering::SeqCst);
                lock(&first_error).get_or_insert(e);
                return;
            }
        };
        std::thread::scope(|s| {
            for _ in 0..self.parallel.clamp(1, 16).min(which.len().max(1)) {
                s.spawn(work);
            }
        });
        let first = lock(&first_error).take();
        match first {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// One chunk, streamed into its cache file: each message's indicator section checked as
    /// it arrives (a server sending something else is refused at once), every message checked
    /// whole before the file is kept.
    fn download_chunk(
        &self,
        plan: &StepPlan,
        chunk: &Chunk,
        progress: &dyn Progress,
    ) -> Result<(), FetchError> {
        let served = |range: ByteRange, p: Problem| FetchError::Served {
            url: plan.grib_url.clone(),
            range,
            msg: match p {
                Problem::NotListed(m) => format!(
                    "the server's bytes do not match the inventory {}: {m}",
                    plan.idx_url
                ),
                Problem::Damaged(m) => format!("the server sent a damaged message: {m}"),
            },
        };
        let messages = &plan.messages[chunk.messages.clone()];
        self.client.get_range(
            &plan.grib_url,
            chunk.range,
            plan.limit(chunk),
            &|d| progress.downloaded(d),
            &mut |body, len| {
                let mut why: Option<BodyError> = None;
                let mut arrived = 0u64;
                let put = self.cache.put(&plan.cache_key, chunk.range, |w| {
                    let mut watch = HeadWatch::new(messages, chunk.range.start, len);
                    let mut buf = vec![0u8; 64 * 1024];
                    loop {
                        let n = body.read(&mut buf).map_err(|e| e.to_string())?;
                        if n == 0 {
                            break;
                        }
                        if let Err(m) = watch.feed(arrived, &buf[..n]) {
                            why =
                                Some(BodyError::Fatal(served(chunk.range, Problem::NotListed(m))));
                            return Err(String::new());
                        }
                        if let Err(e) = w.write(&buf[..n]) {
                            why = Some(BodyError::Fatal(FetchError::Cache {
                                path: self.cache.path(&plan.cache_key, chunk.range),
                                msg: format!("cannot write a cached range: {e}"),
                            }));
                            return Err(String::new());
                        }
                        arrived += n as u64;
                    }
                    if arrived != len {
                        return Err(format!("{arrived} bytes arrived for a range of {len}"));
                    }
                    if let Err((r, p)) =
                        self.check_chunk(plan, chunk, len, |at, n| w.read_at(at, n))
                    {
                        why = Some(BodyError::Fatal(served(r, p)));
                        return Err(String::new());
                    }
                    Ok(())
                });
                match (put, why) {
                    (_, Some(why)) => Err(why),
                    (Ok(()), None) => Ok(()),
                    // The body ended early or broke off: worth another try.
                    (Err(_), None) if arrived != len => Err(BodyError::Retry(format!(
                        "{arrived} bytes arrived for a range of {len}"
                    ))),
                    (Err(e), None) => Err(BodyError::Fatal(e.into())),
                }
            },
        )
    }

    /// Write the step's file from its cached chunks, in order, removing each chunk from the
    /// cache as soon as it is copied (the step is on disk once, plus one chunk). Returns the
    /// file's size.
    fn assemble(&self, plan: &StepPlan) -> Result<u64, FetchError> {
        let mut size = 0u64;
        let mut missing: Option<FetchError> = None;
        let written = crate::output::write_atomic(&plan.out, |w| {
            for chunk in &plan.chunks {
                let c = match self.cache.get(&plan.cache_key, chunk.range) {
                    Ok(Lookup::Whole(c)) => c,
                    Ok(Lookup::Absent) => {
                        return Err(format!("the cached {} is gone", chunk.range))
                    }
                    Ok(Lookup::Damaged(why)) => return Err(why),
                    Err(e) => {
                        missing = Some(e);
                        return Err(String::new());
                    }
                };
                c.copy_to(w)
                    .map_err(|e| format!("{}: {e}", shown(&c.path)))?;
                size += c.len;
                self.cache.remove(&plan.cache_key, chunk.range);
            }
            Ok(())
        });
        match (written, missing) {
            (_, Some(e)) => Err(e),
            (Err(e), None) => Err(e.into()),
            (Ok(()), None) => Ok(size),
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Where the cache goes by default: a hidden folder in the output folder.
pub fn default_cache_dir(out_dir: &Path) -> PathBuf {
    out_dir.join(".stratus-cache")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacent_messages_merge_up_to_the_cap() {
        let inv = idx::parse(
            "1:0:d=1:A:1 mb:anl:\n2:1000:d=1:B:1 mb:anl:\n3:2000:d=1:C:1 mb:anl:\n4:3000:d=1:D:1 mb:anl:\n5:4500:d=1:E:1 mb:anl:\n",
        )
        .unwrap();
        // Take 1, 2, 4, 5: 1+2 merge, 4+5 merge (5 runs to the end).
        let picked: Vec<IdxMessage> = [0, 1, 3, 4].iter().map(|&i| inv[i].clone()).collect();
        let c = plan_chunks(&picked, 10_000);
        assert_eq!(c.len(), 2);
        assert_eq!(
            c[0].range,
            ByteRange {
                start: 0,
                end: Some(2000)
            }
        );
        assert_eq!(c[0].messages, 0..2);
        assert_eq!(
            c[1].range,
            ByteRange {
                start: 3000,
                end: None
            }
        );
        // A cap of 1500 bytes keeps 1 and 2 apart.
        let c = plan_chunks(&picked, 1500);
        assert_eq!(c.len(), 3);
    }
}
