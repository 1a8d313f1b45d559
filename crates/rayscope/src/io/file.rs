//! Reading the files a user names (meshes, MTL files, textures, scene files): regular files
//! only, and no more than a documented number of bytes, streamed rather than held whole.
//!
//! A path may name anything: `/dev/zero` or `/dev/urandom` would be read until memory runs
//! out, a FIFO would block forever, a directory fails with an unhelpful OS message. So the
//! file is opened without blocking (a FIFO swapped in after any earlier look at the path
//! cannot block the open) and the opened handle's own metadata is checked: regular files
//! only, no larger than the limit. The limit is enforced again while reading ([`Bounded`]),
//! for files whose size says nothing (a file that grows, `/proc` files of size 0).

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

/// The environment variable that sets [`max_file_bytes`] (a number of bytes).
pub const MAX_FILE_BYTES_VAR: &str = "RAYSCOPE_MAX_FILE_BYTES";

/// The default of [`max_file_bytes`]: 4 GiB, above any mesh the course or a laptop's memory
/// holds, below what would exhaust it.
pub const DEFAULT_MAX_FILE_BYTES: u64 = 4 << 30;

/// The limit set by [`set_max_file_bytes`]; 0 when unset.
static MAX_FILE_BYTES: AtomicU64 = AtomicU64::new(0);

/// Set the largest file the loaders read, for the whole process (a command-line flag's
/// value); `None` returns to [`MAX_FILE_BYTES_VAR`] or the default.
pub fn set_max_file_bytes(bytes: Option<u64>) {
    MAX_FILE_BYTES.store(bytes.map_or(0, |b| b.max(1)), Ordering::Relaxed);
}

/// The largest file, in bytes, the loaders read: the value of [`set_max_file_bytes`], else
/// [`MAX_FILE_BYTES_VAR`], else [`DEFAULT_MAX_FILE_BYTES`].
pub fn max_file_bytes() -> Result<u64> {
    limit(MAX_FILE_BYTES.load(Ordering::Relaxed), std::env::var(MAX_FILE_BYTES_VAR).ok())
}

/// The limit from the value set (0: none) and the environment variable's.
fn limit(set: u64, var: Option<String>) -> Result<u64> {
    match (set, var) {
        (0, Some(v)) => v
            .trim()
            .parse()
            .ok()
            .filter(|&b| b > 0)
            .ok_or_else(|| Error::Invalid(format!("{MAX_FILE_BYTES_VAR}={v}: expected a positive number of bytes"))),
        (0, None) => Ok(DEFAULT_MAX_FILE_BYTES),
        (set, _) => Ok(set),
    }
}

/// The regular file at `path`, opened for reading within [`max_file_bytes`].
pub fn open(path: &Path) -> Result<Bounded> {
    open_within(path, max_file_bytes()?)
}

/// The regular file at `path`, opened for reading within `limit` bytes.
fn open_within(path: &Path, limit: u64) -> Result<Bounded> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // Opening a FIFO for reading blocks until a writer comes; without blocking it opens
        // at once, and the type check below refuses it. Regular files ignore the flag.
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(|e| Error::io(path, e))?;
    // The handle's own metadata: no race between a check of the path and the open.
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    check_regular(path, &meta)?;
    if meta.len() > limit {
        return Err(Error::TooLarge { path: path.to_path_buf(), limit });
    }
    Ok(Bounded { file, path: path.to_path_buf(), limit, read: 0, size_hint: meta.len() })
}

/// The buffer of a file's reader: larger than std's 8 KiB default, for fewer system calls on
/// a mesh of hundreds of MB.
pub const BUFFER_BYTES: usize = 64 << 10;

/// An opened regular file that fails to read past its byte limit (an [`std::io::Error`]
/// that [`Bounded::error`] turns into [`Error::TooLarge`]), wherever the reader is.
#[derive(Debug)]
pub struct Bounded {
    file: File,
    path: PathBuf,
    limit: u64,
    /// The position: the bytes before it were read (or sought past).
    read: u64,
    /// The size the file had when opened.
    size_hint: u64,
}

/// The marker of a read past the limit, inside the [`std::io::Error`] a reader returns.
#[derive(Debug)]
struct OverLimit;

impl std::fmt::Display for OverLimit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("larger than the file size limit")
    }
}

impl std::error::Error for OverLimit {}

impl Bounded {
    /// The error for a failed read of this file: [`Error::TooLarge`] past the limit, else
    /// [`Error::Io`] naming the path.
    pub fn error(&self, e: std::io::Error) -> Error {
        if e.get_ref().is_some_and(|inner| inner.is::<OverLimit>()) {
            return Error::TooLarge { path: self.path.clone(), limit: self.limit };
        }
        Error::io(&self.path, e)
    }

    /// Start again from the first byte.
    pub fn rewind(&mut self) -> Result<()> {
        self.seek(SeekFrom::Start(0)).map(drop).map_err(|e| self.error(e))
    }

    /// The position: the bytes read (or sought past) before it.
    pub fn position(&self) -> u64 {
        self.read
    }

    /// The size the file had when it was opened.
    pub fn size(&self) -> u64 {
        self.size_hint
    }

    /// A buffered reader over it.
    pub fn buffered(self) -> BufReader<Bounded> {
        BufReader::with_capacity(BUFFER_BYTES, self)
    }
}

impl Read for Bounded {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        // One byte past the limit may be read: it tells a file that grew since it was opened.
        let room = self.limit.saturating_add(1).saturating_sub(self.read);
        let want = buf.len().min(usize::try_from(room).unwrap_or(usize::MAX));
        let n = self.file.read(&mut buf[..want])?;
        self.read += n as u64;
        if self.read > self.limit {
            return Err(std::io::Error::other(OverLimit));
        }
        Ok(n)
    }
}

impl Seek for Bounded {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.read = self.file.seek(pos)?;
        Ok(self.read)
    }
}

/// The error of a text file with a NUL byte: no text file holds one, and all of a sparse file
/// or `/dev/zero` are.
pub const NUL_BYTE: &str = "not a text file (a NUL byte)";

/// The error of a text file with bytes that are not UTF-8.
pub const NOT_UTF8: &str = "not a text file (bytes that are not UTF-8)";

/// The text of the regular file at `path` (a scene file: small), at most [`max_file_bytes`]
/// bytes. NUL bytes and bytes that are not UTF-8 are an error at their line; a NUL byte is
/// found as the file is read, not after reading all of it.
pub fn read_text(path: &Path) -> Result<String> {
    let mut file = open(path)?;
    // Not the whole size at once: a sparse file of gigabytes fails at its first chunk.
    let mut bytes = Vec::with_capacity(file.size_hint.min(1 << 20) as usize);
    let line_of = |bytes: &[u8]| bytes.iter().filter(|&&b| b == b'\n').count() + 1;
    let mut chunk = vec![0; BUFFER_BYTES];
    loop {
        let n = match file.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(file.error(e)),
        };
        bytes.extend_from_slice(&chunk[..n]);
        if let Some(nul) = chunk[..n].iter().position(|&b| b == 0) {
            let at = bytes.len() - n + nul;
            return Err(Error::parse(path, Some(line_of(&bytes[..at])), NUL_BYTE));
        }
    }
    String::from_utf8(bytes).map_err(|e| {
        let line = line_of(&e.as_bytes()[..e.utf8_error().valid_up_to()]);
        Error::parse(path, Some(line), NOT_UTF8)
    })
}

fn check_regular(path: &Path, meta: &std::fs::Metadata) -> Result<()> {
    let t = meta.file_type();
    if t.is_file() {
        return Ok(());
    }
    Err(Error::NotAFile { path: path.to_path_buf(), kind: kind_of(&t) })
}

/// What a file that is not a regular file is, in words.
fn kind_of(t: &std::fs::FileType) -> &'static str {
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::*;

    #[test]
    fn the_limit_is_set_then_the_variable_then_the_default() {
        assert_eq!(limit(0, None).unwrap(), DEFAULT_MAX_FILE_BYTES);
        assert_eq!(limit(0, Some(" 1000 ".into())).unwrap(), 1000);
        assert_eq!(limit(5, Some("1000".into())).unwrap(), 5);
        for bad in ["", "0", "-1", "4GiB"] {
            assert!(limit(0, Some(bad.into())).is_err(), "{bad}");
        }
    }

    #[test]
    fn files_above_the_limit_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        std::fs::write(&path, "0123456789").unwrap();
        // Through the limit's argument, not the process-wide setting: tests run in parallel,
        // and another one reading a file meanwhile would meet a 9-byte limit.
        let over = open_within(&path, 9);
        assert!(matches!(over, Err(Error::TooLarge { limit: 9, .. })), "{over:?}");
        let mut at = open_within(&path, 10).unwrap();
        let mut bytes = Vec::new();
        at.read_to_end(&mut bytes).unwrap();
        assert_eq!(bytes.len(), 10);
    }

    #[test]
    fn a_file_whose_size_says_nothing_is_bounded_while_read() {
        // /proc files are regular files of size 0: only the reading can find them too large.
        let mut status = open_within(Path::new("/proc/self/status"), 10).unwrap();
        let err = status.read_to_end(&mut Vec::new()).unwrap_err();
        assert!(matches!(status.error(err), Error::TooLarge { limit: 10, .. }));
    }

    #[test]
    fn a_file_that_grows_past_the_limit_fails_while_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        std::fs::write(&path, "0123456789").unwrap();
        let mut file = open_within(&path, 12).unwrap();
        std::fs::OpenOptions::new().append(true).open(&path).unwrap().write_all(b"abc").unwrap();
        let err = file.read_to_end(&mut Vec::new()).unwrap_err();
        assert!(matches!(file.error(err), Error::TooLarge { limit: 12, .. }));
    }
}
