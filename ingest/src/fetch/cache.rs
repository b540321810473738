//! The download cache: each byte range fetched is kept as a file named by its file's path in
//! the run (the key) and range (`HASH.START-END.range`), written atomically, so a run that is interrupted — a signal, a
//! lost connection, a server that gave up — leaves only whole ranges, and the next run reads
//! them instead of asking again. A step's ranges are removed once its file is written.

use std::path::{Path, PathBuf};

use super::http::ByteRange;
use crate::error::IngestError;
use crate::input::{read_capped, MAX_GRIB_BYTES};

pub struct Cache {
    dir: PathBuf,
}

/// FNV-1a, 64 bits: a name for a key that stays the same across builds and platforms (std's
/// hashers promise neither).
fn fnv1a(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

impl Cache {
    /// A cache in `dir`, created (with its parents) if absent.
    pub fn open(dir: &Path) -> Result<Cache, IngestError> {
        std::fs::create_dir_all(dir).map_err(|e| IngestError::Write {
            path: dir.to_path_buf(),
            msg: format!("cannot create the cache folder: {e}"),
        })?;
        Ok(Cache {
            dir: dir.to_path_buf(),
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The file holding `range` of the file `key` names.
    pub fn path(&self, key: &str, range: ByteRange) -> PathBuf {
        let end = range
            .end
            .map_or_else(|| "end".to_string(), |e| e.to_string());
        self.dir
            .join(format!("{:016x}.{}-{end}.range", fnv1a(key), range.start))
    }

    /// The cached bytes of `range`, when a whole one is there (of the range's length where
    /// that is known).
    pub fn get(&self, key: &str, range: ByteRange) -> Option<Vec<u8>> {
        let path = self.path(key, range);
        let limit = range.len().unwrap_or(MAX_GRIB_BYTES);
        let bytes = read_capped(&path, limit, "cached range").ok()?;
        match range.len() {
            Some(n) if bytes.len() as u64 != n => None,
            _ if bytes.is_empty() => None,
            _ => Some(bytes),
        }
    }

    pub fn put(&self, key: &str, range: ByteRange, bytes: &[u8]) -> Result<(), IngestError> {
        crate::output::write_atomic(&self.path(key, range), |w| {
            use std::io::Write;
            w.write_all(bytes).map_err(|e| e.to_string())
        })
    }

    /// Forget `range` (absent is fine).
    pub fn remove(&self, key: &str, range: ByteRange) {
        let _ = std::fs::remove_file(self.path(key, range));
    }

    /// Remove the cache folder if nothing is left in it.
    pub fn remove_if_empty(&self) {
        let _ = std::fs::remove_dir(&self.dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_whole_ranges_only() {
        let dir = tempfile::tempdir().unwrap();
        let c = Cache::open(&dir.path().join("c")).unwrap();
        let r = ByteRange {
            start: 5,
            end: Some(9),
        };
        assert!(c.get("http://x/a", r).is_none());
        c.put("http://x/a", r, b"abcd").unwrap();
        assert_eq!(c.get("http://x/a", r).unwrap(), b"abcd");
        assert!(c.get("http://x/b", r).is_none(), "another URL");
        // A file of the wrong length is not a cached range.
        std::fs::write(c.path("http://x/a", r), b"abc").unwrap();
        assert!(c.get("http://x/a", r).is_none());
        c.remove("http://x/a", r);
        c.remove_if_empty();
        assert!(!dir.path().join("c").exists());
        assert_eq!(fnv1a(""), 0xcbf2_9ce4_8422_2325);
    }
}
