//! Downloading the GFS fields stratus needs, not whole forecast files: the run's `.idx`
//! inventory says where each message lies ([`idx`]), the fields and levels asked for pick
//! messages ([`select`]), adjacent ones are merged into a few byte ranges ([`plan_chunks`])
//! fetched a few at a time with retries ([`http`]) through a cache that lets an interrupted
//! run resume ([`cache`]); every message is checked with the GRIB2 validator and against its
//! inventory line before the step's file is written, atomically. URL layouts: [`source`].

pub mod cache;
pub mod http;
pub mod idx;
pub mod select;
pub mod source;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use thiserror::Error;

use crate::error::IngestError;
use crate::grib::{self, MessageInfo};
use cache::Cache;
use http::{ByteRange, Client, MAX_IDX_BYTES};
use idx::IdxMessage;
use select::{FieldSpec, Levels};
use source::Run;

/// Adjacent messages are merged into one request up to this size, so a step is still a few
/// requests that can run in parallel and a failed one costs little to repeat.
pub const MAX_CHUNK_BYTES: u64 = 16 << 20;

#[derive(Debug, Error)]
pub enum FetchError {
    #[error("{url}{}: {msg}", in_range(.range))]
    Http {
        url: String,
        range: Option<ByteRange>,
        msg: String,
    },
    #[error("{url}: not an inventory: {msg}")]
    Inventory { url: String, msg: String },
    #[error("{url}: {msg}")]
    Select { url: String, msg: String },
    #[error("{url} ({range}): {msg}")]
    Mismatch {
        url: String,
        range: ByteRange,
        msg: String,
    },
    #[error(transparent)]
    Write(#[from] IngestError),
}

fn in_range(r: &Option<ByteRange>) -> String {
    r.map(|r| format!(" ({r})")).unwrap_or_default()
}

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
    /// re-run from another source reuses them (every message is validated either way).
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
    /// Read the step's inventory and pick its messages.
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
        Ok(StepPlan {
            step,
            grib_url: self.run.grib_url(step),
            cache_key: self.run.file_path(step),
            idx_url,
            messages,
            chunks,
            out: self.out_dir.join(self.run.out_name(step)),
        })
    }

    /// Download (or read from the cache) every chunk of `plan`, validate every message, and
    /// write the step's file atomically. The cache entries are removed once the file is in
    /// place. Returns the file's size.
    pub fn fetch(&self, plan: &StepPlan, progress: &dyn Progress) -> Result<u64, FetchError> {
        crate::output::check_output(&plan.out)?;
        let data = self.download(plan, progress)?;
        for (chunk, bytes) in plan.chunks.iter().zip(&data) {
            if let Err(e) = self.check_chunk(plan, chunk, bytes) {
                // What is in the cache may be what is wrong: the next run asks again.
                self.cache.remove(&plan.cache_key, chunk.range);
                return Err(e);
            }
        }
        // Chunk by chunk into the file: no second copy of the step in memory.
        crate::output::write_atomic(&plan.out, |w| {
            use std::io::Write;
            data.iter()
                .try_for_each(|bytes| w.write_all(bytes))
                .map_err(|e| e.to_string())
        })?;
        for c in &plan.chunks {
            self.cache.remove(&plan.cache_key, c.range);
        }
        Ok(data.iter().map(|b| b.len() as u64).sum())
    }

    /// Every chunk's bytes, in plan order: from the cache where a whole one is there, else
    /// downloaded (a few at once) and put in the cache. The first failure stops the others
    /// from starting new requests; what they finished stays cached.
    fn download(
        &self,
        plan: &StepPlan,
        progress: &dyn Progress,
    ) -> Result<Vec<Vec<u8>>, FetchError> {
        let n = plan.chunks.len();
        let results: Mutex<Vec<Option<Vec<u8>>>> = Mutex::new(vec![None; n]);
        let first_error: Mutex<Option<FetchError>> = Mutex::new(None);
        let next = AtomicUsize::new(0);
        let stop = AtomicBool::new(false);
        let work = || loop {
            if stop.load(Ordering::SeqCst) {
                return;
            }
            let i = next.fetch_add(1, Ordering::SeqCst);
            let Some(chunk) = plan.chunks.get(i) else {
                return;
            };
            let got = match self.cache.get(&plan.cache_key, chunk.range) {
                Some(b) => {
                    progress.cached(b.len() as u64);
                    Ok(b)
                }
                None => self
                    .client
                    .get_range(&plan.grib_url, chunk.range, &|d| progress.downloaded(d))
                    .and_then(|b| {
                        self.cache.put(&plan.cache_key, chunk.range, &b)?;
                        Ok(b)
                    }),
            };
            match got {
                Ok(b) => lock(&results)[i] = Some(b),
                Err(e) => {
                    stop.store(true, Ordering::SeqCst);
                    lock(&first_error).get_or_insert(e);
                    return;
                }
            }
        };
        std::thread::scope(|s| {
            for _ in 0..self.parallel.clamp(1, 16).min(n.max(1)) {
                s.spawn(work);
            }
        });
        if let Some(e) = lock(&first_error).take() {
            return Err(e);
        }
        let results = std::mem::take(&mut *lock(&results));
        results
            .into_iter()
            .zip(&plan.chunks)
            .map(|(r, c)| {
                r.ok_or_else(|| FetchError::Http {
                    url: plan.grib_url.clone(),
                    range: Some(c.range),
                    msg: "not downloaded".into(),
                })
            })
            .collect()
    }

    /// Split a chunk into its messages and check each: a valid GRIB2 message by itself, of
    /// the parameter, level and run its inventory lines say.
    fn check_chunk(&self, plan: &StepPlan, chunk: &Chunk, bytes: &[u8]) -> Result<(), FetchError> {
        for m in &plan.messages[chunk.messages.clone()] {
            let range = ByteRange {
                start: m.start,
                end: m.end,
            };
            let mismatch = |msg: String| FetchError::Mismatch {
                url: plan.grib_url.clone(),
                range,
                msg,
            };
            let a = (m.start - chunk.range.start) as usize;
            let b = match m.end {
                Some(e) => (e - chunk.range.start) as usize,
                None => bytes.len(),
            };
            let what = describe(m);
            let msg = bytes
                .get(a..b)
                .ok_or_else(|| mismatch(format!("{what}: missing bytes")))?;
            let fields = grib::validate_message(msg).map_err(|e| {
                if msg.starts_with(b"GRIB") {
                    mismatch(format!("{what}: not a valid GRIB2 message: {e}"))
                } else {
                    mismatch(format!(
                        "the inventory {} does not match the file: no GRIB message starts at byte {} where it places {what}",
                        plan.idx_url, m.start
                    ))
                }
            })?;
            check_against_inventory(m, &fields).map_err(|e| {
                mismatch(format!(
                    "the inventory {} does not match the file: {e}",
                    plan.idx_url
                ))
            })?;
        }
        Ok(())
    }
}

/// `message 12 (RH 500 mb)`.
fn describe(m: &IdxMessage) -> String {
    let what: Vec<String> = m
        .lines
        .iter()
        .map(|l| format!("{} {}", l.name, l.level))
        .collect();
    let number = m.lines.first().map_or("?", |l| l.number.as_str());
    format!("message {number} ({})", what.join(", "))
}

/// The fields of one message against its inventory lines: as many, and each of the parameter,
/// isobaric level and run its line names (where stratus knows the name).
pub fn check_against_inventory(m: &IdxMessage, fields: &[MessageInfo]) -> Result<(), String> {
    if fields.len() != m.lines.len() {
        return Err(format!(
            "the message at byte {} holds {} field(s), the inventory lists {}",
            m.start,
            fields.len(),
            m.lines.len()
        ));
    }
    for (line, f) in m.lines.iter().zip(fields) {
        let is = format!("{} {}", idx::ncep_name(f), idx::level_text(f));
        let says = format!("{} {}", line.name, line.level);
        let wrong_param = idx::parameter_of(&line.name).is_some_and(|p| p != f.parameter());
        let wrong_level = select::mb_of(&line.level)
            .is_some_and(|p| f.pressure_hpa().is_none_or(|q| (p - q).abs() > 1e-6));
        let wrong_run = f
            .reference_time
            .is_some_and(|t| t.format("%Y%m%d%H").to_string() != line.date);
        if wrong_param || wrong_level || wrong_run {
            return Err(format!(
                "the message at byte {} is {is} of d={}, the inventory says {says} of d={}",
                m.start,
                f.reference_time
                    .map_or_else(|| "?".into(), |t| t.format("%Y%m%d%H").to_string()),
                line.date
            ));
        }
    }
    Ok(())
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
            "1:0:d=1:A:1 mb:anl:\n2:10:d=1:B:1 mb:anl:\n3:20:d=1:C:1 mb:anl:\n4:30:d=1:D:1 mb:anl:\n5:45:d=1:E:1 mb:anl:\n",
        )
        .unwrap();
        // Take 1, 2, 4, 5: 1+2 merge, 4+5 merge (5 runs to the end).
        let picked: Vec<IdxMessage> = [0, 1, 3, 4].iter().map(|&i| inv[i].clone()).collect();
        let c = plan_chunks(&picked, 100);
        assert_eq!(c.len(), 2);
        assert_eq!(
            c[0].range,
            ByteRange {
                start: 0,
                end: Some(20)
            }
        );
        assert_eq!(c[0].messages, 0..2);
        assert_eq!(
            c[1].range,
            ByteRange {
                start: 30,
                end: None
            }
        );
        // A cap of 15 bytes keeps 1 and 2 apart.
        let c = plan_chunks(&picked, 15);
        assert_eq!(c.len(), 3);
    }
}
