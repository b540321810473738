//! The download cache: each byte range fetched is kept as a file named by its file's path in
//! the run (the key) and range (`HASH.START-END.range`), written atomically and only after its
//! messages passed every check, so a run that is interrupted — a signal, a lost connection, a
//! server that gave up — leaves only whole, checked ranges, and the next run reads them
//! instead of asking again.
//!
//! - **Checked again on re-use**: each file ends with a trailer (CRC-32 and length of the
//!   range, [`TRAILER`] bytes), so a range changed on disk since it was written is found and
//!   dropped; the messages are checked again besides ([`super::check`]).
//! - **Only regular files**: a cached range is opened without following links and without
//!   blocking (a FIFO there would otherwise hang the run), and anything but a regular file is
//!   refused.
//! - **One fetch at a time**: the folder is locked (`flock` on the folder itself, released by
//!   the kernel when the process ends) while a fetch uses it; another fetch waits. A holder
//!   that removes the emptied folder leaves a waiter holding a lock on a removed folder, which
//!   it notices and opens the folder again.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use super::http::ByteRange;
use super::FetchError;
use crate::error::{shown, IngestError};

/// Bytes after a cached range: CRC-32 (4), the range's length (8), [`MAGIC`] (4).
pub const TRAILER: u64 = 16;
const MAGIC: &[u8; 4] = b"STRC";

pub struct Cache {
    dir: PathBuf,
    /// The locked folder; the lock goes with it.
    _lock: File,
}

/// FNV-1a, 64 bits: a name for a key that stays the same across builds and platforms (std's
/// hashers promise neither).
fn fnv1a(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// What the cache holds for a range.
pub enum Lookup {
    Absent,
    /// A file that is not the range it is named for (cut, changed, of an older format).
    Damaged(String),
    Whole(CachedRange),
}

/// A cached range whose trailer matched: its bytes are read from the file as needed.
pub struct CachedRange {
    pub path: PathBuf,
    file: File,
    pub len: u64,
}

impl CachedRange {
    /// `n` bytes from byte `at` of the range.
    pub fn read_at(&self, at: u64, n: u64) -> std::io::Result<Vec<u8>> {
        read_exact_at(&self.file, at, n)
    }

    /// Copy the whole range into `w`.
    pub fn copy_to(&self, w: &mut impl Write) -> std::io::Result<()> {
        use std::io::{Seek, SeekFrom};
        (&self.file).seek(SeekFrom::Start(0))?;
        let mut r = (&self.file).take(self.len);
        let n = std::io::copy(&mut r, w)?;
        if n != self.len {
            return Err(std::io::Error::other("the cached range was cut short"));
        }
        Ok(())
    }
}

fn read_exact_at(file: &File, at: u64, n: u64) -> std::io::Result<Vec<u8>> {
    use std::os::unix::fs::FileExt;
    let mut buf = vec![0u8; n as usize];
    file.read_exact_at(&mut buf, at)?;
    Ok(buf)
}

/// A range being written to the cache: bytes pass through to a temporary beside the range's
/// name while their CRC is taken; [`RangeWriter::read_at`] reads back what was written, so the
/// messages can be checked before the range is kept.
pub struct RangeWriter<'a> {
    w: &'a mut BufWriter<File>,
    crc: crc32fast::Hasher,
    len: u64,
}

impl RangeWriter<'_> {
    pub fn write(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.w.write_all(bytes)?;
        self.crc.update(bytes);
        self.len += bytes.len() as u64;
        Ok(())
    }

    /// `n` bytes from byte `at` of what was written.
    pub fn read_at(&mut self, at: u64, n: u64) -> std::io::Result<Vec<u8>> {
        self.w.flush()?;
        read_exact_at(self.w.get_ref(), at, n)
    }
}

impl Cache {
    /// The cache in `dir` (created with its parents if absent), locked for this process;
    /// `waiting` is called once if another process holds it, before this one waits for it.
    pub fn open(dir: &Path, waiting: &dyn Fn()) -> Result<Cache, IngestError> {
        let fail = |msg: String| IngestError::write(dir, msg);
        let mut told = false;
        // A few tries: each one lost means another fetch removed the folder in between.
        for _ in 0..100 {
            std::fs::create_dir_all(dir)
                .map_err(|e| fail(format!("cannot create the cache folder: {e}")))?;
            let f = match File::open(dir) {
                Ok(f) => f,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
                Err(e) => return Err(fail(format!("cannot open the cache folder: {e}"))),
            };
            use rustix::fs::{flock, FlockOperation};
            if flock(&f, FlockOperation::NonBlockingLockExclusive).is_err() {
                if !told {
                    waiting();
                    told = true;
                }
                flock(&f, FlockOperation::LockExclusive)
                    .map_err(|e| fail(format!("cannot lock the cache folder: {e}")))?;
            }
            // Still the folder at `dir`, not one another fetch removed while this one waited?
            let held = f.metadata().map_err(|e| fail(e.to_string()))?;
            let now = std::fs::metadata(dir);
            use std::os::unix::fs::MetadataExt;
            if now.is_ok_and(|m| m.dev() == held.dev() && m.ino() == held.ino()) {
                return Ok(Cache {
                    dir: dir.to_path_buf(),
                    _lock: f,
                });
            }
        }
        Err(fail(
            "cannot lock the cache folder: it keeps being removed".into(),
        ))
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

    /// What the cache holds for `range`. Anything but a regular file there is an error (it is
    /// not ours to remove); a file whose trailer does not match its bytes is `Damaged`.
    pub fn get(&self, key: &str, range: ByteRange) -> Result<Lookup, FetchError> {
        use std::os::unix::fs::OpenOptionsExt;
        let path = self.path(key, range);
        let flags = rustix::fs::OFlags::NONBLOCK | rustix::fs::OFlags::NOFOLLOW;
        let file = match std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(flags.bits() as i32)
            .open(&path)
        {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Lookup::Absent),
            Err(e) => {
                let msg = match std::fs::symlink_metadata(&path) {
                    Ok(m) if m.file_type().is_symlink() => {
                        "a cached range is a symbolic link, not a regular file; remove it".into()
                    }
                    _ => format!("cannot read a cached range: {e}"),
                };
                return Err(FetchError::Cache { path, msg });
            }
        };
        let meta = file.metadata().map_err(|e| FetchError::Cache {
            path: path.clone(),
            msg: format!("cannot read a cached range: {e}"),
        })?;
        if !meta.is_file() {
            return Err(FetchError::Cache {
                msg: format!(
                    "a cached range is {}, not a regular file; remove it",
                    kind_of(&meta.file_type())
                ),
                path,
            });
        }
        let size = meta.len();
        let damaged = |m: &str| Ok(Lookup::Damaged(format!("{}: {m}", shown(&path))));
        let Some(len) = size.checked_sub(TRAILER) else {
            return damaged("shorter than its trailer");
        };
        if range.len().is_some_and(|n| n != len) {
            return damaged("not the length of its range");
        }
        let Ok(t) = read_exact_at(&file, len, TRAILER) else {
            return damaged("its trailer cannot be read");
        };
        let crc = u32::from_be_bytes([t[0], t[1], t[2], t[3]]);
        let mut n = [0u8; 8];
        n.copy_from_slice(&t[4..12]);
        if &t[12..] != MAGIC || u64::from_be_bytes(n) != len {
            return damaged("no trailer (an older or foreign file)");
        }
        let mut h = crc32fast::Hasher::new();
        let mut r = (&file).take(len);
        let mut buf = vec![0u8; 64 * 1024];
        loop {
            match r.read(&mut buf) {
                Ok(0) => break,
                Ok(k) => h.update(&buf[..k]),
                Err(e) => return damaged(&format!("cannot be read: {e}")),
            }
        }
        if h.finalize() != crc {
            return damaged("its bytes changed since they were checked (CRC mismatch)");
        }
        Ok(Lookup::Whole(CachedRange { path, file, len }))
    }

    /// Write `range` atomically: `fill` writes its bytes (and may read them back to check
    /// them); the trailer follows. Nothing is kept when `fill` fails.
    pub fn put(
        &self,
        key: &str,
        range: ByteRange,
        fill: impl FnOnce(&mut RangeWriter) -> Result<(), String>,
    ) -> Result<(), IngestError> {
        crate::output::write_atomic(&self.path(key, range), |w| {
            let mut rw = RangeWriter {
                w,
                crc: crc32fast::Hasher::new(),
                len: 0,
            };
            fill(&mut rw)?;
            let (crc, len) = (rw.crc.finalize(), rw.len);
            let mut t = Vec::with_capacity(TRAILER as usize);
            t.extend_from_slice(&crc.to_be_bytes());
            t.extend_from_slice(&len.to_be_bytes());
            t.extend_from_slice(MAGIC);
            w.write_all(&t).map_err(|e| e.to_string())
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

fn kind_of(t: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if t.is_fifo() {
        "a FIFO (named pipe)"
    } else if t.is_socket() {
        "a socket"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_dir() {
        "a directory"
    } else {
        "something else"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn whole(l: Lookup) -> Option<Vec<u8>> {
        match l {
            Lookup::Whole(c) => Some(c.read_at(0, c.len).unwrap()),
            _ => None,
        }
    }

    #[test]
    fn keeps_whole_unchanged_ranges_only() {
        let dir = tempfile::tempdir().unwrap();
        let c = Cache::open(&dir.path().join("c"), &|| ()).unwrap();
        let r = ByteRange {
            start: 5,
            end: Some(9),
        };
        assert!(matches!(c.get("http://x/a", r).unwrap(), Lookup::Absent));
        c.put("http://x/a", r, |w| {
            w.write(b"abcd").map_err(|e| e.to_string())
        })
        .unwrap();
        assert_eq!(whole(c.get("http://x/a", r).unwrap()).unwrap(), b"abcd");
        assert!(matches!(c.get("http://x/b", r).unwrap(), Lookup::Absent));
        // One byte changed: damaged.
        let p = c.path("http://x/a", r);
        let mut b = std::fs::read(&p).unwrap();
        b[1] ^= 1;
        std::fs::write(&p, &b).unwrap();
        assert!(matches!(
            c.get("http://x/a", r).unwrap(),
            Lookup::Damaged(_)
        ));
        // A file of the wrong length, or without a trailer.
        std::fs::write(&p, b"abc").unwrap();
        assert!(matches!(
            c.get("http://x/a", r).unwrap(),
            Lookup::Damaged(_)
        ));
        // A fill that fails keeps nothing.
        assert!(c.put("http://x/a", r, |_| Err("no".into())).is_err());
        c.remove("http://x/a", r);
        assert!(matches!(c.get("http://x/a", r).unwrap(), Lookup::Absent));
        c.remove_if_empty();
        assert!(!dir.path().join("c").exists());
        assert_eq!(fnv1a(""), 0xcbf2_9ce4_8422_2325);
    }

    #[test]
    fn a_fifo_is_refused_not_waited_on() {
        let dir = tempfile::tempdir().unwrap();
        let c = Cache::open(dir.path(), &|| ()).unwrap();
        let r = ByteRange {
            start: 0,
            end: Some(9),
        };
        let p = c.path("k", r);
        assert!(std::process::Command::new("mkfifo")
            .arg(&p)
            .status()
            .unwrap()
            .success());
        let Err(e) = c.get("k", r) else {
            panic!("a FIFO read as a range")
        };
        assert!(e.to_string().contains("FIFO"), "{e}");
    }
}
