//! Reading inputs with a cap: no input may make stratus read (and hold) more than a valid file
//! of its kind can be, whatever it is — a huge file, a pipe, `/dev/zero`. Limits are public
//! constants, so the command line and the docs can name them. A map's files (sidecars, PNGs)
//! are only ever regular files ([`open_regular`]): a FIFO given as `--map` is refused, not
//! waited on.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{IngestError, Result};

/// Largest GRIB2 file read: 2 GiB. A whole GFS 0.25° forecast step is about 0.5 GiB, and one
/// field at [`crate::grib::MAX_POINTS`] points of 32 bits is 256 MiB; a bigger file is refused
/// before it is read (or, for a stream, as soon as it passes the limit).
pub const MAX_GRIB_BYTES: u64 = 2 << 30;

/// A GRIB file's first message must start within this many bytes (WMO bulletin headers are a
/// few dozen): a stream without a `GRIB` marker so far is refused here, not at [`MAX_GRIB_BYTES`].
pub const GRIB_MARKER_WITHIN: usize = 1 << 20;

/// Largest sidecar (`MAP.json`) read: 1 MiB; a real one is about 2 KiB.
pub const MAX_SIDECAR_BYTES: u64 = 1 << 20;

/// Open `path` for reading; a directory is refused, and a regular file larger than `limit` is
/// refused before anything is read.
fn open_capped(path: &Path, limit: u64, what: &'static str) -> Result<File> {
    let f = File::open(path).map_err(|e| IngestError::io(path, e))?;
    let meta = f.metadata().map_err(|e| IngestError::io(path, e))?;
    if meta.is_dir() {
        return Err(IngestError::io(
            path,
            std::io::Error::other("it is a directory"),
        ));
    }
    if meta.is_file() && meta.len() > limit {
        return Err(too_large(path, what, limit));
    }
    Ok(f)
}

fn too_large(path: &Path, what: &'static str, limit: u64) -> IngestError {
    IngestError::TooLarge {
        path: path.to_path_buf(),
        what,
        limit,
    }
}

/// Read at most `limit` more bytes of `r` onto `buf`; an error if there are more.
fn read_rest(
    r: &mut impl Read,
    buf: &mut Vec<u8>,
    path: &Path,
    limit: u64,
    what: &'static str,
) -> Result<()> {
    let room = limit.saturating_sub(buf.len() as u64);
    r.take(room + 1)
        .read_to_end(buf)
        .map_err(|e| IngestError::io(path, e))?;
    if buf.len() as u64 > limit {
        return Err(too_large(path, what, limit));
    }
    Ok(())
}

/// Read a whole file of at most `limit` bytes (`what` names its kind in the error).
pub fn read_capped(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>> {
    let mut f = open_capped(path, limit, what)?;
    let mut buf = Vec::new();
    read_rest(&mut f, &mut buf, path, limit, what)?;
    Ok(buf)
}

/// Read a GRIB file: at most [`MAX_GRIB_BYTES`], and refused as soon as its first
/// [`GRIB_MARKER_WITHIN`] bytes hold no `GRIB` marker (so `/dev/zero` fails at once).
pub fn read_grib(path: &Path) -> Result<Vec<u8>> {
    const WHAT: &str = "GRIB2 file";
    let mut f = open_capped(path, MAX_GRIB_BYTES, WHAT)?;
    let mut buf = Vec::new();
    (&mut f)
        .take(GRIB_MARKER_WITHIN as u64)
        .read_to_end(&mut buf)
        .map_err(|e| IngestError::io(path, e))?;
    if buf.len() == GRIB_MARKER_WITHIN && !buf.windows(4).any(|w| w == b"GRIB") {
        return Err(IngestError::Grib {
            path: path.to_path_buf(),
            msg: crate::error::not_grib(GRIB_MARKER_WITHIN),
        });
    }
    read_rest(&mut f, &mut buf, path, MAX_GRIB_BYTES, WHAT)?;
    Ok(buf)
}

/// Open `path` for reading if it is a regular file; a FIFO, a device, a socket or a directory
/// is refused before a byte is read. On Unix the open itself does not wait (`O_NONBLOCK`: a
/// FIFO without a writer would otherwise block it forever) and the type is that of the file
/// opened, so a swap between a check and the open cannot slip one through; reads of a regular
/// file are unaffected by the flag.
pub fn open_regular(path: &Path) -> Result<File> {
    #[cfg(unix)]
    let f = {
        use rustix::fs::{open, Mode, OFlags};
        let flags = OFlags::RDONLY | OFlags::NONBLOCK | OFlags::CLOEXEC;
        File::from(open(path, flags, Mode::empty()).map_err(|e| IngestError::io(path, e.into()))?)
    };
    #[cfg(not(unix))]
    let f = {
        let m = std::fs::metadata(path).map_err(|e| IngestError::io(path, e))?;
        if !m.is_file() {
            return Err(not_regular(path, &m.file_type()));
        }
        File::open(path).map_err(|e| IngestError::io(path, e))?
    };
    let m = f.metadata().map_err(|e| IngestError::io(path, e))?;
    if !m.is_file() {
        return Err(not_regular(path, &m.file_type()));
    }
    Ok(f)
}

fn not_regular(path: &Path, t: &std::fs::FileType) -> IngestError {
    let kind = crate::output::kind_of(t);
    IngestError::io(
        path,
        std::io::Error::other(format!("it is {kind}, not a regular file")),
    )
}

/// Read a sidecar's text: a regular file ([`open_regular`]) of at most [`MAX_SIDECAR_BYTES`],
/// UTF-8, valid JSON (the error gives serde's line and column). A TIFF or PNG given where a
/// sidecar belongs is named as such.
pub fn read_sidecar_text(path: &Path) -> Result<String> {
    const WHAT: &str = "CloudMap sidecar";
    let mut f = open_regular(path)?;
    let size = f.metadata().map_err(|e| IngestError::io(path, e))?.len();
    if size > MAX_SIDECAR_BYTES {
        return Err(too_large(path, WHAT, MAX_SIDECAR_BYTES));
    }
    let mut bytes = Vec::new();
    read_rest(&mut f, &mut bytes, path, MAX_SIDECAR_BYTES, WHAT)?;
    let bad = |msg: String| IngestError::BadCloudMap {
        path: path.to_path_buf(),
        msg,
    };
    let text = String::from_utf8(bytes).map_err(|e| {
        bad(match image_kind(e.as_bytes()) {
            Some(kind) => format!(
                "{kind}, not a sidecar: a map is read from its JSON sidecar (MAP.json) or a series sidecar (NAME.json), which `stratus ingest --out MAP.png` writes"
            ),
            None => "sidecar is not UTF-8 text".into(),
        })
    })?;
    // The syntax first: a typed parse stops at its first missing field, which in a file with
    // a syntax error further on (or a series read as a map) names the wrong fault.
    serde_json::from_str::<serde::de::IgnoredAny>(&text)
        .map_err(|e| bad(format!("sidecar is not valid JSON: {e}")))?;
    Ok(text)
}

/// What image file `bytes` begin as, if they begin as one a user may mistake for a map.
fn image_kind(bytes: &[u8]) -> Option<&'static str> {
    match bytes {
        [b'I', b'I', 42 | 43, 0, ..] | [b'M', b'M', 0, 42 | 43, ..] => {
            Some("it is a TIFF (a GeoTIFF map is for GIS; stratus does not read it back)")
        }
        [0x89, b'P', b'N', b'G', ..] => Some("it is a PNG image"),
        _ => None,
    }
}
