//! The lines of a text file, read one at a time from a file (a mesh is never held whole) or
//! taken from a string, checked to be text as they come.

use std::io::{BufRead, BufReader};
use std::path::Path;

use super::file::{Bounded, NOT_UTF8, NUL_BYTE};
use crate::error::{Error, Result};

/// Where the lines come from.
pub enum Lines<'a> {
    /// Text already in memory (the unit tests' files).
    #[cfg(test)]
    Text(&'a str),
    /// An opened file, read from its current position.
    File(&'a mut BufReader<Bounded>),
}

impl Lines<'_> {
    /// Call `f` with each line and its 1-based number, without its `\n` (or `\r\n`) ending, as
    /// [`str::lines`] gives them, and return the number of bytes read. A line holding a NUL
    /// byte or bytes that are not UTF-8 is an error at that line (`path` names the file), found
    /// when that line is read: a 2 GB file of zeros fails at line 1, not after reading it all.
    pub fn for_each(self, path: &Path, mut f: impl FnMut(usize, &str) -> Result<()>) -> Result<u64> {
        // Outside the unit tests there is one variant.
        #[allow(clippy::infallible_destructuring_match)]
        let reader = match self {
            #[cfg(test)]
            Lines::Text(text) => {
                for (i, line) in text.lines().enumerate() {
                    f(i + 1, line)?;
                }
                return Ok(text.len() as u64);
            }
            Lines::File(reader) => reader,
        };
        let (mut buf, mut number, mut bytes) = (Vec::new(), 0, 0);
        loop {
            number += 1;
            buf.clear();
            // `read_until` by hand: a NUL byte ends the reading when it is read, not when its
            // line ends (a file of zeros has no line end).
            let ended = loop {
                let available = match reader.fill_buf() {
                    Ok(available) => available,
                    Err(e) => return Err(reader.get_ref().error(e)),
                };
                if available.is_empty() {
                    break false;
                }
                let end = available.iter().position(|&b| b == b'\n');
                let chunk = &available[..end.map_or(available.len(), |e| e + 1)];
                // `contains` on bytes is a vectorised search: no cost worth measuring.
                if chunk.contains(&0) {
                    return Err(Error::parse(path, Some(number), NUL_BYTE));
                }
                buf.extend_from_slice(chunk);
                let n = chunk.len();
                reader.consume(n);
                bytes += n as u64;
                if end.is_some() {
                    break true;
                }
            };
            if !ended && buf.is_empty() {
                return Ok(bytes);
            }
            f(number, text_line(&buf, path, number)?)?;
        }
    }
}

/// One line's bytes (checked for NUL bytes as read) as text, without the line ending.
fn text_line<'a>(bytes: &'a [u8], path: &Path, number: usize) -> Result<&'a str> {
    let bytes = match bytes.strip_suffix(b"\n") {
        Some(line) => line.strip_suffix(b"\r").unwrap_or(line),
        None => bytes,
    };
    std::str::from_utf8(bytes).map_err(|_| Error::parse(path, Some(number), NOT_UTF8))
}
