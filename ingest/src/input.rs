//! Reading inputs with a cap: no input may make stratus read (and hold) more than a valid file
//! of its kind can be, whatever it is — a huge file, a pipe, `/dev/zero`. Limits are public
//! constants, so the command line and the docs can name them.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{IngestError, Result};
use crate::grib::GribError;

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
            msg: GribError::NotGrib(GRIB_MARKER_WITHIN).to_string(),
        });
    }
    read_rest(&mut f, &mut buf, path, MAX_GRIB_BYTES, WHAT)?;
    Ok(buf)
}

/// Read a sidecar's text: at most [`MAX_SIDECAR_BYTES`], UTF-8.
pub fn read_sidecar_text(path: &Path) -> Result<String> {
    let bytes = read_capped(path, MAX_SIDECAR_BYTES, "CloudMap sidecar")?;
    String::from_utf8(bytes).map_err(|_| IngestError::BadCloudMap {
        path: path.to_path_buf(),
        msg: "sidecar is not UTF-8 text".into(),
    })
}
