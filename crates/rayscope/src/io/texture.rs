//! Loading texture images.

use std::io::{BufRead, Cursor, Seek};
use std::path::Path;

use image::DynamicImage;

use super::file::open;
use super::image_file::decode_image;
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
fn decode(reader: impl BufRead + Seek, path: &Path) -> Result<Texture> {
    let img = decode_image(reader, path)?;
    let (width, height) = (img.width(), img.height());
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
    Ok(Texture::new(width, height, texels))
}

#[cfg(test)]
mod tests {
    use super::*;

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
