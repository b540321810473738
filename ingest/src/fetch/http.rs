//! HTTP for `fetch`: whole small files (inventories) and byte ranges, with timeouts and
//! retries. What may pass on a second try — a connection refused or dropped, a timeout, a
//! 5xx or 429, a body shorter or longer than the range — is retried with exponential backoff
//! (with jitter, so parallel ranges do not retry in step); what cannot — a 404, another 4xx,
//! a server that ignores `Range` — fails at once. Redirects are followed here (at most
//! [`MAX_REDIRECTS`]), not by the HTTP library, so an error names the URL that failed. A range's
//! body is handed to its consumer as it arrives ([`Body`]), never held whole here.

use std::collections::hash_map::RandomState;
use std::hash::{BuildHasher, Hasher};
use std::io::Read;
use std::time::Duration;

use super::FetchError;

/// Redirects followed for one request.
pub const MAX_REDIRECTS: u32 = 5;

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

impl Failure {
    fn map(self, f: impl FnOnce(String) -> String) -> Failure {
        match self {
            Failure::Transient(m) => Failure::Transient(f(m)),
            Failure::Permanent(m) => Failure::Permanent(f(m)),
        }
    }
}

/// How a range's consumer ends a try.
pub enum BodyError {
    /// Worth another try (the bytes may come right next time).
    Retry(String),
    /// Ends the fetch with this error.
    Fatal(FetchError),
}

/// A range's body as it arrives: at most its length; a read error is kept (the connection
/// was lost, which the client retries) and the consumer sees it as an error.
pub struct Body<'a> {
    inner: &'a mut dyn Read,
    len: u64,
    got: u64,
    lost: Option<String>,
    progress: &'a (dyn Fn(i64) + Sync),
}

impl Read for Body<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let room = (self.len - self.got).min(buf.len() as u64) as usize;
        if room == 0 {
            return Ok(0);
        }
        match self.inner.read(&mut buf[..room]) {
            Ok(n) => {
                self.got += n as u64;
                (self.progress)(n as i64);
                Ok(n)
            }
            Err(e) => {
                self.lost = Some(e.to_string());
                Err(e)
            }
        }
    }
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
            .max_redirects(0)
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

    /// GET `url` (and `range`), following redirects; a failure after one names the URL
    /// redirected to.
    fn send(
        &self,
        url: &str,
        range: Option<ByteRange>,
    ) -> Result<ureq::http::Response<ureq::Body>, Failure> {
        let mut at = url.to_string();
        for _ in 0..=MAX_REDIRECTS {
            let mut req = self.agent.get(&at);
            if let Some(r) = range {
                req = req.header("Range", r.header());
            }
            let named = |f: Failure| match at == url {
                true => f,
                false => f.map(|m| format!("redirected to {at}: {m}")),
            };
            let resp = req.call().map_err(|e| named(transport(e)))?;
            let status = resp.status().as_u16();
            if !matches!(status, 301 | 302 | 303 | 307 | 308) {
                return match at == url {
                    true => Ok(resp),
                    // A status judged later is named by the URL that gave it.
                    false => match status_ok(status, if range.is_some() { 206 } else { 200 }) {
                        Err(f) if status != 200 => Err(named(f)),
                        _ => Ok(resp),
                    },
                };
            }
            let loc = resp
                .headers()
                .get("location")
                .and_then(|v| v.to_str().ok())
                .and_then(|l| resolve(&at, l.trim()))
                .ok_or_else(|| {
                    named(Failure::Permanent(format!(
                        "HTTP {status} without a usable Location"
                    )))
                })?;
            at = loc;
        }
        Err(Failure::Permanent(format!(
            "more than {MAX_REDIRECTS} redirects (the last to {at})"
        )))
    }

    /// GET a whole small file (at most `limit` bytes).
    pub fn get_small(&self, url: &str, limit: u64) -> Result<Vec<u8>, FetchError> {
        self.with_retries(url, None, || {
            let mut resp = self.send(url, None)?;
            status_ok(resp.status().as_u16(), 200)?;
            let mut buf = Vec::new();
            resp.body_mut()
                .as_reader()
                .take(limit + 1)
                .read_to_end(&mut buf)
                .map_err(|e| Failure::Transient(format!("connection lost: {e}")))?;
            if buf.len() as u64 > limit {
                return Err(Failure::Permanent(format!(
                    "larger than {}, the most an inventory may be",
                    crate::error::human_bytes(limit)
                )));
            }
            Ok(buf)
        })
    }

    /// GET `range` of `url`: the answer must be a 206 whose `Content-Range` is the range
    /// asked for, of at most `limit` bytes, and exactly that many bytes must arrive. `consume`
    /// gets the body as it arrives and its length, once per try; what it returns ends the try
    /// (a [`BodyError::Retry`] is retried, and so is a body cut short or too long).
    /// `progress` is told of bytes as they arrive (and takes them back when a try fails).
    pub fn get_range<T>(
        &self,
        url: &str,
        range: ByteRange,
        limit: u64,
        progress: &(dyn Fn(i64) + Sync),
        consume: &mut dyn FnMut(&mut Body, u64) -> Result<T, BodyError>,
    ) -> Result<T, FetchError> {
        let mut fatal = None;
        let got = self.with_retries(url, Some(range), || {
            let mut resp = self.send(url, Some(range))?;
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
                .ok_or_else(|| Failure::Transient("206 without a Content-Range".into()))?
                .to_string();
            let len = check_content_range(&cr, range)?;
            if len > limit {
                return Err(Failure::Permanent(format!(
                    "the server declares {len} bytes (Content-Range \"{cr}\"), more than the {limit} the messages asked for can be"
                )));
            }
            if let Some(cl) = resp.body().content_length() {
                if cl != len {
                    return Err(Failure::Transient(format!(
                        "Content-Length {cl} does not match Content-Range {cr}"
                    )));
                }
            }
            let mut reader = resp.body_mut().as_reader();
            let mut body = Body {
                inner: &mut reader,
                len,
                got: 0,
                lost: None,
                progress,
            };
            let result = consume(&mut body, len);
            let (got, lost) = (body.got, body.lost.take());
            // Bytes past the range, where no Content-Length said how many would come.
            let extra = result.is_ok() && got == len && reader.read(&mut [0u8; 1]).is_ok_and(|n| n > 0);
            let fail = |m: String| {
                progress(-(got as i64));
                Failure::Transient(m)
            };
            match result {
                _ if lost.is_some() => Err(fail(format!(
                    "connection lost after {got} of {len} bytes: {}",
                    lost.unwrap_or_default()
                ))),
                Err(BodyError::Fatal(e)) => {
                    progress(-(got as i64));
                    fatal = Some(e);
                    Err(Failure::Permanent(String::new()))
                }
                Err(BodyError::Retry(m)) => Err(fail(m)),
                Ok(_) if got != len => Err(fail(format!("{got} bytes arrived for a range of {len}"))),
                Ok(_) if extra => Err(fail(format!("more than the {len} bytes of the range arrived"))),
                Ok(v) => Ok(v),
            }
        });
        match (got, fatal) {
            (Err(_), Some(e)) => Err(e),
            (got, _) => got,
        }
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
                    tracing::info!(
                        "{}{}: {msg}; try {} of {tries}",
                        super::source::redact(url),
                        range.map(|r| format!(" ({r})")).unwrap_or_default(),
                        n + 1
                    );
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

/// Where a `Location` points, from the URL that answered with it.
fn resolve(base: &str, loc: &str) -> Option<String> {
    if loc.starts_with("http://") || loc.starts_with("https://") {
        return Some(loc.to_string());
    }
    if loc.contains("://") || loc.is_empty() {
        return None;
    }
    let scheme_end = base.find("://")? + 3;
    if let Some(rest) = loc.strip_prefix("//") {
        return Some(format!("{}{rest}", &base[..scheme_end]));
    }
    let auth_end = base[scheme_end..]
        .find(['/', '?', '#'])
        .map_or(base.len(), |i| scheme_end + i);
    if loc.starts_with('/') {
        return Some(format!("{}{loc}", &base[..auth_end]));
    }
    let path_end = base[auth_end..]
        .find(['?', '#'])
        .map_or(base.len(), |i| auth_end + i);
    let dir_end = base[auth_end..path_end]
        .rfind('/')
        .map_or(auth_end, |i| auth_end + i);
    Some(format!("{}/{loc}", &base[..dir_end]))
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
    // `b` is inclusive: `b + 1` overflows for `bytes 0-18446744073709551615`.
    let end = b.checked_add(1).ok_or_else(bad)?;
    if a != range.start || b < a || total.is_some_and(|t| end > t) {
        return Err(bad());
    }
    match range.end {
        Some(e) if end != e => Err(bad()),
        // From `start` to the end: the answer must reach the end of the file.
        None if total.is_some_and(|t| end != t) => Err(bad()),
        _ => Ok(end - a),
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
        // No wrap-around to a length of 0.
        let zero = ByteRange {
            start: 0,
            end: None,
        };
        assert!(check_content_range("bytes 0-18446744073709551615/*", zero).is_err());
        assert!(check_content_range("bytes 0-9/5", zero).is_err());
        assert_eq!(
            resolve("http://h:1/a/b.idx", "c.idx").unwrap(),
            "http://h:1/a/c.idx"
        );
        assert_eq!(resolve("http://h:1/a/b", "/x").unwrap(), "http://h:1/x");
        assert_eq!(resolve("https://h/a", "//g/y").unwrap(), "https://g/y");
        assert_eq!(resolve("http://h/a", "https://g/z").unwrap(), "https://g/z");
        assert!(resolve("http://h/a", "ftp://g/z").is_none());
    }
}
