//! Typed errors of the ingest library. Each renders as one line naming the file and the fault:
//! file names are shown through [`shown`], so a name holding a newline (or bytes that are not
//! UTF-8) cannot split the line or be shown as something it is not, and an OS error is written
//! once, in the message, never again as a `source` (a `{:#}` chain would repeat it).

use std::fmt;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// A path for a one-line message: as is when it is printable UTF-8, else quoted and escaped
/// (`"a\nb.png"`, `"m\xFF.png"`) so the line stays one line and the name stays exact.
pub fn shown(path: &Path) -> Shown<'_> {
    Shown(path)
}

/// See [`shown`].
pub struct Shown<'a>(&'a Path);

impl fmt::Display for Shown<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0.to_str() {
            Some(s) if !s.chars().any(char::is_control) => f.write_str(s),
            _ => write!(f, "{:?}", self.0),
        }
    }
}

#[derive(Debug, Error)]
pub enum IngestError {
    /// The OS error is in the message, and deliberately not a `source` (see the module doc).
    #[error("{}: cannot read: {err}", shown(.path))]
    Io { path: PathBuf, err: std::io::Error },
    #[error("{}: {msg}", shown(.path))]
    Grib { path: PathBuf, msg: String },
    #[error("no relative humidity in {}; it holds: {holds}", shown(.path))]
    NoRelativeHumidity { path: PathBuf, holds: String },
    #[error("{}: no relative humidity at {level} hPa; levels present: {present}", shown(.path))]
    LevelAbsent {
        path: PathBuf,
        level: f64,
        present: String,
    },
    #[error("bad region: {0}")]
    BadRegion(String),
    #[error("bad size: {0}")]
    BadSize(String),
    #[error("bad critical humidity: {0}")]
    BadRhCr(String),
    /// The map the options describe is not one the loader would accept (e.g. a layer band
    /// above the atmosphere from a very high level).
    #[error("bad map: {0}")]
    BadMap(String),
    #[error("{}: cannot write: {msg}", shown(.path))]
    Write { path: PathBuf, msg: String },
    /// An output path names something that is not a regular file (a device node, a FIFO, a
    /// directory, a symbolic link…): it is never replaced.
    #[error("{}: cannot write: it is {kind}, not a regular file; stratus only replaces regular files", shown(.path))]
    NotRegularFile { path: PathBuf, kind: &'static str },
    /// An output path is (the same file as) one of the command's inputs.
    #[error("{}: cannot write: it is the input {}; choose another output", shown(.output), shown(.input))]
    OutputIsInput { output: PathBuf, input: PathBuf },
    /// An input is larger than any valid file of its kind.
    #[error("{}: cannot read: larger than {}, the most a {what} may be", shown(.path), human_bytes(*.limit))]
    TooLarge {
        path: PathBuf,
        what: &'static str,
        limit: u64,
    },
    /// The process is shutting down (`output::cleanup_temps` ran): nothing is written.
    #[error("{}: not written: interrupted", shown(.path))]
    Interrupted { path: PathBuf },
    #[error("{}: bad CloudMap: {msg}", shown(.path))]
    BadCloudMap { path: PathBuf, msg: String },
    /// Inputs that do not make one forecast series, or a series sidecar that is not whole
    /// (`series`).
    #[error("{}: {msg}", shown(.path))]
    Series { path: PathBuf, msg: String },
}

/// A number a user or a file gave, for a one-line message: as Rust writes it for ordinary
/// magnitudes (up to 15 digits), in exponent form beyond them (`1e308`, not 309 digits;
/// `1e-9`).
pub fn show_num(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-6..1e15).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// The message of a file that holds no `GRIB` marker in its first `within` bytes (one text
/// for the reader that refuses it early, `input::read_grib`, and for the scanner).
pub fn not_grib(within: usize) -> String {
    format!("not a GRIB file (no 'GRIB' marker in its first {within} bytes)")
}

/// `2 GiB`, `1 MiB`, `512 bytes`.
pub(crate) fn human_bytes(n: u64) -> String {
    const UNITS: [(u64, &str); 3] = [(1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")];
    for (size, unit) in UNITS {
        if n >= size && (n / size) * size == n {
            return format!("{} {unit}", n / size);
        }
    }
    format!("{n} bytes")
}

impl IngestError {
    pub(crate) fn io(path: &Path, err: std::io::Error) -> IngestError {
        IngestError::Io {
            path: path.to_path_buf(),
            err,
        }
    }
    pub(crate) fn series(path: &Path, msg: impl fmt::Display) -> IngestError {
        IngestError::Series {
            path: path.to_path_buf(),
            msg: msg.to_string(),
        }
    }
    pub(crate) fn write(path: &Path, msg: impl fmt::Display) -> IngestError {
        IngestError::Write {
            path: path.to_path_buf(),
            msg: msg.to_string(),
        }
    }
}

pub type Result<T, E = IngestError> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn names_stay_on_one_line_and_exact() {
        assert_eq!(shown(Path::new("/tmp/m.png")).to_string(), "/tmp/m.png");
        assert_eq!(shown(Path::new("a\nb.png")).to_string(), r#""a\nb.png""#);
        use std::os::unix::ffi::OsStrExt;
        let bad = Path::new(std::ffi::OsStr::from_bytes(b"m\xff.png"));
        assert_eq!(shown(bad).to_string(), r#""m\xFF.png""#);
        let e = IngestError::io(
            Path::new("x\ny.json"),
            std::io::Error::from(std::io::ErrorKind::NotFound),
        );
        assert_eq!(e.to_string().lines().count(), 1, "{e}");
        // The OS error is written once and is not also a source a chain would print again.
        assert!(std::error::Error::source(&e).is_none());
    }

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(human_bytes(2 << 30), "2 GiB");
        assert_eq!(human_bytes(1 << 20), "1 MiB");
        assert_eq!(human_bytes(1000), "1000 bytes");
    }
}
