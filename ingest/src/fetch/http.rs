//! HTTP for `fetch`: whole small files (inventories) and byte ranges, with timeouts and
//! retries. What may pass on a second try — a connection refused or dropped, a timeout, a
//! 5xx or 429, a body shorter or longer than the range — is retried with exponential backoff
//! (with jitter, so parallel ranges do not retry in step); what cannot — a 404, another 4xx,
//! a server that ignores `Range` — fails at once.

use std::collections::hash_map::RandomState;
use std::hash::{BuildHasher, Hasher};
use std::io::Read;
use std::time::Duration;

use super::FetchError;
use crate::input::MAX_GRIB_BYTES;

/// Largest inventory read: a 0.25° step's is about 70 KB.
pub const MAX_IDX_BYTES: u64 = 4 << 20;

/// Longest wait between two tries.
const MAX_BACKOFF: Duration = Duration::from_secs(30);

/// Retry and timeout settings.
#[derive(Debug, Clone)]
pub struct Policy {
    /// Tries after the first.
    pub retries: u32,
    /// Wait before the first retry; doubled for each further one.
    pub backoff: Duration,
    /// Connecting, waiting for the response headers, and each read of the body.
    pub timeout: Duration,
}

/// A blocking HTTP client (one connection pool, shared by the download threads).
pub struct Client {
    agent: ureq::Agent,
    policy: Policy,
}

/// How one try went wrong.
enum Failure {
    /// Worth another try.
    Transient(String),
    /// Will not change on another try.
    Permanent(String),
}

/// A byte range: `start..end`, or from `start` to the end of the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ByteRange {
    pub start: u64,
    pub end: Option<u64>,
}

impl ByteRange {
    /// The `Range` header's value (HTTP ranges are inclusive).
    pub fn header(&self) -> String {
        match self.end {
            Some(e) => format!("bytes={}-{}", self.start, e - 1),
            None => format!("bytes={}-", self.start),
        }
    }
    pub fn len(&self) -> Option<u64> {
        self.end.map(|e| e - self.start)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == Some(0)
    }
}

impl std::fmt::Display for ByteRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.end {
            Some(e) => write!(f, "bytes {}-{}", self.start, e - 1),
            None => write!(f, "bytes {}-end", self.start),
        }
    }
}

impl Client {
    pub fn new(policy: Policy) -> Client {
        let config = ureq::Agent::config_builder()
            // Status codes are judged here (which to retry), not turned into errors.
            .http_status_as_error(false)
            .timeout_connect(Some(policy.timeout))
            .timeout_recv_response(Some(policy.timeout))
            // A per-read timeout, not one for the whole body: a large range on a slow but
            // live connection is fine, a stalled one is not.
            .timeout_per_read(Some(policy.timeout))
            .user_agent(concat!("stratus/", env!("CARGO_PKG_VERSION")))
            .build();
        Client {
            agent: config.new_agent(),
            policy,
        }
    }

    /// GET a whole small file (at most `limit` bytes).
    pub fn get_small(&self, url: &str, limit: u64) -> Result<Vec<u8>, FetchError> {
        self.with_retries(url, None, || {
            let mut resp = self.agent.get(url).call().map_err(transport)?;
            status_ok(resp.status().as_u16(), 200)?;
            let mut buf = Vec::new();
            resp.body_mut()
                .as_reader()
                .take(limit + 1)
                .read_to_end(&mut buf)
                .map_err(|e| Failure::Transient(format!("connection lost: {e}")))?;
            if buf.len() as u64 > limit {
                return Err(Failure::Permanent(format!(
                    "larger than {limit} bytes, the most an inventory may be"
                )));
            }
            Ok(buf)
        })
    }

    /// GET `range` of `url`: the answer must be a 206 whose `Content-Range` is the range
    /// asked for, and exactly that many bytes must arrive. `progress` is told of bytes as they
    /// arrive (and takes them back when a try fails).
    pub fn get_range(
        &self,
        url: &str,
        range: ByteRange,
        progress: &(dyn Fn(i64) + Sync),
    ) -> Result<Vec<u8>, FetchError> {
        self.with_retries(url, Some(range), || {
            let mut resp = self
                .agent
                .get(url)
                .header("Range", range.header())
                .call()
                .map_err(transport)?;
            let status = resp.status().as_u16();
            if status == 200 {
                return Err(Failure::Permanent(
                    "the server ignored the Range request (HTTP 200); it cannot serve byte ranges"
                        .into(),
                ));
            }
            status_ok(status, 206)?;
            let cr = resp
                .headers()
                .get("content-range")
                .and_then(|v| v.to_str().ok())
                .ok_or_else(|| Failure::Transient("206 without a Content-Range".into()))?;
            let len = check_content_range(cr, range)?;
            if len > MAX_GRIB_BYTES {
                return Err(Failure::Permanent(format!(
                    "the server declares {len} bytes, more than a GRIB2 file may be"
                )));
            }
            if let Some(cl) = resp.body().content_length() {
                if cl != len {
                    return Err(Failure::Transient(format!(
                        "Content-Length {cl} does not match Content-Range {cr}"
                    )));
                }
            }
            // Checked against the cap above before this allocation.
            let mut buf = Vec::with_capacity(len as usize);
            let mut reader = resp.body_mut().as_reader().take(len + 1);
            let mut chunk = [0u8; 64 * 1024];
            let result = loop {
                match reader.read(&mut chunk) {
                    Ok(0) => break Ok(()),
                    Ok(n) => {
                        buf.extend_from_slice(&chunk[..n]);
                        progress(n as i64);
                    }
                    Err(e) => break Err(e),
                }
            };
            let got = buf.len() as u64;
            let fail = |m: String| {
                progress(-(got as i64));
                Failure::Transient(m)
            };
            if let Err(e) = result {
                return Err(fail(format!(
                    "connection lost after {got} of {len} bytes: {e}"
                )));
            }
            if got != len {
                return Err(fail(format!("{got} bytes arrived for a range of {len}")));
            }
            Ok(buf)
        })
    }

    fn with_retries<T>(
        &self,
        url: &str,
        range: Option<ByteRange>,
        mut attempt: impl FnMut() -> Result<T, Failure>,
    ) -> Result<T, FetchError> {
        let tries = self.policy.retries + 1;
        let mut last = String::new();
        for n in 0..tries {
            match attempt() {
                Ok(v) => return Ok(v),
                Err(Failure::Permanent(msg)) => {
                    return Err(FetchError::Http {
                        url: url.to_string(),
                        range,
                        msg,
                    })
                }
                Err(Failure::Transient(msg)) => {
                    tracing::info!("{url} {range:?}: {msg}; try {} of {tries}", n + 1);
                    last = msg;
                    if n + 1 < tries {
                        std::thread::sleep(self.backoff(n));
                    }
                }
            }
        }
        Err(FetchError::Http {
            url: url.to_string(),
            range,
            msg: format!("{last} (gave up after {tries} tries)"),
        })
    }

    /// Wait before retry `n` (0-based): backoff × 2ⁿ, capped, less up to half at random.
    fn backoff(&self, n: u32) -> Duration {
        let full = self
            .policy
            .backoff
            .saturating_mul(1u32 << n.min(16))
            .min(MAX_BACKOFF);
        let r = RandomState::new().build_hasher().finish() % 1000;
        full.mul_f64(1.0 - r as f64 / 2000.0)
    }
}

fn transport(e: ureq::Error) -> Failure {
    match e {
        ureq::Error::BadUri(m) => Failure::Permanent(format!("bad URL: {m}")),
        ureq::Error::Timeout(t) => Failure::Transient(format!("timed out ({t:?})")),
        e => Failure::Transient(e.to_string()),
    }
}

fn status_ok(status: u16, want: u16) -> Result<(), Failure> {
    match status {
        s if s == want => Ok(()),
        404 => Err(Failure::Permanent("not found (HTTP 404)".into())),
        416 => Err(Failure::Permanent(
            "the range lies outside the file (HTTP 416): the inventory does not match the file"
                .into(),
        )),
        408 | 429 | 500..=599 => Err(Failure::Transient(format!("HTTP {status}"))),
        s => Err(Failure::Permanent(format!("HTTP {s}"))),
    }
}

/// Check `Content-Range: bytes A-B/T` against the range asked for; returns its length.
fn check_content_range(cr: &str, range: ByteRange) -> Result<u64, Failure> {
    let bad = || Failure::Transient(format!("Content-Range \"{cr}\" does not answer {range}"));
    let rest = cr.trim().strip_prefix("bytes ").ok_or_else(bad)?;
    let (span, total) = rest.split_once('/').ok_or_else(bad)?;
    let (a, b) = span.split_once('-').ok_or_else(bad)?;
    let (a, b): (u64, u64) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    let total: Option<u64> = match total.trim() {
        "*" => None,
        t => Some(t.parse().map_err(|_| bad())?),
    };
    if a != range.start || b < a {
        return Err(bad());
    }
    match range.end {
        Some(e) if b + 1 != e => Err(bad()),
        // From `start` to the end: the answer must reach the end of the file.
        None if total.is_some_and(|t| b + 1 != t) => Err(bad()),
        _ => Ok(b - a + 1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn content_range_must_answer_the_range() {
        let r = ByteRange {
            start: 10,
            end: Some(20),
        };
        assert_eq!(r.header(), "bytes=10-19");
        assert!(matches!(check_content_range("bytes 10-19/100", r), Ok(10)));
        assert!(check_content_range("bytes 10-18/100", r).is_err());
        assert!(check_content_range("bytes 0-19/100", r).is_err());
        assert!(check_content_range("junk", r).is_err());
        let open = ByteRange {
            start: 90,
            end: None,
        };
        assert!(matches!(
            check_content_range("bytes 90-99/100", open),
            Ok(10)
        ));
        assert!(check_content_range("bytes 90-95/100", open).is_err());
    }
}
