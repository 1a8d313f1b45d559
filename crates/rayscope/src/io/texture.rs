//! Loading texture images.

use std::path::Path;

use super::file::read_bytes;
use crate::error::{Error, Result};
use crate::material::Texture;
use crate::math::Color;

/// Load an image file as a texture; 8-bit values map to `[0, 1]` linearly, as in the course.
pub fn load_texture(path: &Path) -> Result<Texture> {
    decode_texture(&read_bytes(path)?, path)
}

/// Decode the bytes of an image file as a texture (the format is told by its magic bytes);
/// `path` names it in errors.
pub fn decode_texture(bytes: &[u8], path: &Path) -> Result<Texture> {
    check_png_palette(bytes).map_err(|m| Error::parse(path, None, m))?;
    let img = image::load_from_memory(bytes)
        .map_err(|e| Error::parse(path, None, format!("cannot decode image: {e}")))?
        .to_rgb8();
    let (width, height) = img.dimensions();
    if width == 0 || height == 0 {
        return Err(Error::parse(path, None, "image has no pixels"));
    }
    let texels = img.pixels().map(|p| Color::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0).collect();
    Ok(Texture { width, height, texels })
}

/// The eight bytes that open every PNG file.
const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

/// A PNG's palette (`PLTE`) holds whole RGB entries: its length is a multiple of 3, as the
/// format requires. The `png` crate (0.18.1) accepts a ragged one and then panics expanding
/// it, so the chunk headers are walked before decoding; other formats pass unchecked.
fn check_png_palette(bytes: &[u8]) -> Result<(), String> {
    let Some(mut rest) = bytes.strip_prefix(PNG_SIGNATURE) else { return Ok(()) };
    // Each chunk: a 4-byte big-endian data length, a 4-byte type, the data, a 4-byte CRC.
    while let [l0, l1, l2, l3, t0, t1, t2, t3, ..] = *rest {
        let len = u32::from_be_bytes([l0, l1, l2, l3]) as usize;
        if [t0, t1, t2, t3] == *b"PLTE" && !len.is_multiple_of(3) {
            return Err(format!("PNG palette of {len} bytes: not whole RGB entries (a multiple of 3)"));
        }
        rest = rest.get(len.saturating_add(12)..).unwrap_or_default();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(check_png_palette(&png(&[(b"IHDR", 13), (b"PLTE", 6), (b"IDAT", 2), (b"IEND", 0)])).is_ok());
        let err = check_png_palette(&png(&[(b"IHDR", 13), (b"gAMA", 4), (b"PLTE", 38), (b"IDAT", 2)])).unwrap_err();
        assert!(err.contains("38 bytes"), "{err}");
        // Not PNG, or cut short: left to the decoder.
        assert!(check_png_palette(b"PF\n1 1\n-1\n").is_ok());
        let mut cut = png(&[(b"IHDR", 13)]);
        cut.extend_from_slice(&(3u32 << 28).to_be_bytes());
        cut.extend_from_slice(b"PLTE");
        assert!(check_png_palette(&cut).is_ok());
    }
}
