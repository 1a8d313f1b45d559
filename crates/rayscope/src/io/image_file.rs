//! Decoding image files (textures, and the images `rayscope compare` reads): the `image`
//! crate, which tells PNG, BMP, OpenEXR and Radiance HDR apart by their magic bytes, behind a
//! check of PNG palettes that keeps a malformed one from panicking the decoder.

use std::io::{BufRead, Read, Seek, SeekFrom};
use std::path::Path;

use image::DynamicImage;

use super::file::open;
use crate::error::{Error, Result};

/// Read the image file at `path` (a regular file within the byte limit, see [`super::file`]).
pub fn read_image(path: &Path) -> Result<DynamicImage> {
    decode_image(open(path)?.buffered(), path)
}

/// Decode an image read from `reader` (the format is told by its magic bytes); `path` names
/// it in errors. An image without pixels is an error.
pub fn decode_image(mut reader: impl BufRead + Seek, path: &Path) -> Result<DynamicImage> {
    check_png_palette(&mut reader).map_err(|e| Error::io(path, e))?.map_err(|m| Error::parse(path, None, m))?;
    let img = image::ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?
        .decode()
        .map_err(|e| Error::parse(path, None, format!("cannot decode image: {e}")))?;
    if img.width() == 0 || img.height() == 0 {
        return Err(Error::parse(path, None, "image has no pixels"));
    }
    Ok(img)
}

const PNG_SIGNATURE: [u8; 8] = *b"\x89PNG\r\n\x1a\n";

/// A PNG's palette (`PLTE`) holds whole RGB entries: its length is a multiple of 3, as the
/// format requires. The `png` crate (0.18.1) accepts a ragged one and then panics expanding
/// it, so the chunk headers are walked before decoding; other formats pass unchecked.
fn check_png_palette(r: &mut (impl Read + Seek)) -> std::io::Result<Result<(), String>> {
    let verdict = walk_png_chunks(r);
    r.rewind()?;
    verdict
}

/// The walk of [`check_png_palette`], from the start of `r`; a file that is not PNG, or is cut
/// short, is left to the decoder.
fn walk_png_chunks(r: &mut (impl Read + Seek)) -> std::io::Result<Result<(), String>> {
    let mut signature = [0u8; 8];
    if r.read_exact(&mut signature).is_err() || signature != PNG_SIGNATURE {
        return Ok(Ok(()));
    }
    // Each chunk: a 4-byte big-endian data length, a 4-byte type, the data, a 4-byte CRC.
    let mut header = [0u8; 8];
    while r.read_exact(&mut header).is_ok() {
        let [l0, l1, l2, l3, t0, t1, t2, t3] = header;
        let len = u32::from_be_bytes([l0, l1, l2, l3]);
        if [t0, t1, t2, t3] == *b"PLTE" && !len.is_multiple_of(3) {
            return Ok(Err(format!("PNG palette of {len} bytes: not whole RGB entries (a multiple of 3)")));
        }
        if [t0, t1, t2, t3] == *b"IEND" {
            break;
        }
        r.seek(SeekFrom::Current(i64::from(len) + 4))?;
    }
    Ok(Ok(()))
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use super::*;

    fn palette(bytes: &[u8]) -> Result<(), String> {
        check_png_palette(&mut Cursor::new(bytes)).unwrap()
    }

    /// A PNG's chunk headers (with no valid data or CRC: the check reads only the headers).
    fn png(chunks: &[(&[u8; 4], usize)]) -> Vec<u8> {
        let mut out = PNG_SIGNATURE.to_vec();
        for (kind, len) in chunks {
            out.extend_from_slice(&(*len as u32).to_be_bytes());
            out.extend_from_slice(*kind);
            out.extend(std::iter::repeat_n(0, len + 4));
        }
        out
    }

    #[test]
    fn a_palette_of_whole_rgb_entries_passes_and_a_ragged_one_is_an_error() {
        assert!(palette(&png(&[(b"IHDR", 13), (b"PLTE", 6), (b"IDAT", 2), (b"IEND", 0)])).is_ok());
        let err = palette(&png(&[(b"IHDR", 13), (b"gAMA", 4), (b"PLTE", 38), (b"IDAT", 2)])).unwrap_err();
        assert!(err.contains("38 bytes"), "{err}");
        // Not PNG, or cut short: left to the decoder.
        assert!(palette(b"PF\n1 1\n-1\n").is_ok());
        let mut cut = png(&[(b"IHDR", 13)]);
        cut.extend_from_slice(&(3u32 << 28).to_be_bytes());
        cut.extend_from_slice(b"PLTE");
        assert!(palette(&cut).is_ok());
    }
}
