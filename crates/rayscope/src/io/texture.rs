//! Loading texture images.

use std::io::{BufRead, Cursor, Read, Seek, SeekFrom};
use std::path::Path;

use image::DynamicImage;

use super::file::open;
use crate::error::{Error, Result};
use crate::material::Texture;
use crate::math::Color;

/// Load an image file as a texture; 8-bit values map to `[0, 1]` linearly, as in the course,
/// and floating-point images (OpenEXR, Radiance HDR) keep their values, which must be finite
/// (negative ones are clamped to 0). The decoder reads the file through
/// [`super::file::Bounded`]: never more than the limit.
pub fn load_texture(path: &Path) -> Result<Texture> {
    decode(open(path)?.buffered(), path)
}

/// Decode the bytes of an image file as a texture, as [`load_texture`] decodes a file; `path`
/// names it in errors.
pub fn decode_texture(bytes: &[u8], path: &Path) -> Result<Texture> {
    decode(Cursor::new(bytes), path)
}

/// Decode an image read from `reader` (the format is told by its magic bytes).
fn decode(mut reader: impl BufRead + Seek, path: &Path) -> Result<Texture> {
    check_png_palette(&mut reader).map_err(|e| Error::io(path, e))?.map_err(|m| Error::parse(path, None, m))?;
    let img = image::ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?
        .decode()
        .map_err(|e| Error::parse(path, None, format!("cannot decode image: {e}")))?;
    let (width, height) = (img.width(), img.height());
    if width == 0 || height == 0 {
        return Err(Error::parse(path, None, "image has no pixels"));
    }
    let texels = match img {
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_) => {
            let img = img.to_rgb32f();
            if let Some((i, _)) = img.pixels().enumerate().find(|(_, p)| !p.0.iter().all(|v| v.is_finite())) {
                let (x, y) = (i as u32 % width, i as u32 / width);
                return Err(Error::parse(path, None, format!("texel ({x}, {y}) is not a finite colour")));
            }
            img.pixels().map(|p| Color::new(p[0], p[1], p[2]).max(Color::ZERO)).collect()
        }
        _ => img.to_rgb8().pixels().map(|p| Color::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0).collect(),
    };
    Ok(Texture { width, height, texels })
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

    /// A 2x1 floating-point image, encoded in `format`.
    fn float_image(texels: [f32; 6], format: image::ImageFormat) -> Vec<u8> {
        let img = image::Rgb32FImage::from_raw(2, 1, texels.to_vec()).unwrap();
        let mut out = Cursor::new(Vec::new());
        DynamicImage::ImageRgb32F(img).write_to(&mut out, format).unwrap();
        out.into_inner()
    }

    #[test]
    fn float_textures_keep_their_values_and_must_be_finite() {
        let path = Path::new("t");
        let exr =
            decode_texture(&float_image([0.25, 2.0, 0.0, -1.0, 0.5, 8.0], image::ImageFormat::OpenExr), path).unwrap();
        assert_eq!(exr.texels, vec![Color::new(0.25, 2.0, 0.0), Color::new(0.0, 0.5, 8.0)]);
        // Radiance HDR keeps 8 bits of mantissa per channel: powers of two come back exactly.
        let hdr = decode_texture(&float_image([0.25, 2.0, 1.0, 4.0, 0.5, 8.0], image::ImageFormat::Hdr), path).unwrap();
        assert_eq!(hdr.texels, vec![Color::new(0.25, 2.0, 1.0), Color::new(4.0, 0.5, 8.0)]);
        let nan = float_image([0.0, f32::NAN, 0.0, 0.0, 0.0, 0.0], image::ImageFormat::OpenExr);
        let err = decode_texture(&nan, path).unwrap_err().to_string();
        assert!(err.contains("texel (0, 0)"), "{err}");
        let inf = float_image([0.0, 0.0, 0.0, 0.0, 0.0, f32::INFINITY], image::ImageFormat::OpenExr);
        let err = decode_texture(&inf, path).unwrap_err().to_string();
        assert!(err.contains("texel (1, 0)"), "{err}");
    }
}
