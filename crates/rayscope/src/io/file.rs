//! Reading the files a user names (meshes, MTL files, textures, scene files): regular files
//! only, and no more than a documented number of bytes.
//!
//! A path may name anything: `/dev/zero` or `/dev/urandom` would be read until memory runs
//! out, a FIFO would block forever, a directory fails with an unhelpful OS message. So the
//! path's metadata (following symbolic links) is checked before the file is opened, and the
//! read stops one byte past the limit.

use std::io::Read;
use std::path::Path;
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

/// The bytes of the regular file at `path`, at most [`max_file_bytes`] of them.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    read_bytes_within(path, max_file_bytes()?)
}

/// The bytes of the regular file at `path`, at most `limit` of them.
fn read_bytes_within(path: &Path, limit: u64) -> Result<Vec<u8>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    check_regular(path, &meta)?;
    if meta.len() > limit {
        return Err(Error::TooLarge { path: path.to_path_buf(), limit });
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    // The path may have been replaced between the check and the open: check what was opened.
    check_regular(path, &file.metadata().map_err(|e| Error::io(path, e))?)?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    // One byte past the limit tells a file that grew since its size was read.
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(Error::TooLarge { path: path.to_path_buf(), limit });
    }
    Ok(bytes)
}

/// The text of the regular file at `path` (see [`read_bytes`]). Bytes that are not UTF-8, and
/// NUL bytes (which no text file holds, and all of a sparse file or `/dev/zero` are), are an
/// error at their line, found before any parser scans the file's lines.
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = read_bytes(path)?;
    let line_of = |bytes: &[u8]| bytes.iter().filter(|&&b| b == b'\n').count() + 1;
    // `contains` on bytes is a vectorised search: no cost worth measuring on a mesh.
    if bytes.contains(&0) {
        let nul = bytes.iter().position(|&b| b == 0).unwrap_or(0);
        return Err(Error::parse(path, Some(line_of(&bytes[..nul])), "not a text file (a NUL byte)"));
    }
    String::from_utf8(bytes).map_err(|e| {
        let line = line_of(&e.as_bytes()[..e.utf8_error().valid_up_to()]);
        Error::parse(path, Some(line), "not a text file (bytes that are not UTF-8)")
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
        let over = read_bytes_within(&path, 9);
        let at = read_bytes_within(&path, 10);
        assert!(matches!(over, Err(Error::TooLarge { limit: 9, .. })), "{over:?}");
        assert_eq!(at.unwrap().len(), 10);
    }
}
