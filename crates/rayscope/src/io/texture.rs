//! Loading texture images.

use std::io::{BufRead, Seek};
use std::path::Path;

use super::file::open;
use crate::error::{Error, Result};
use crate::material::Texture;
use crate::math::Color;

/// Load an image file as a texture; 8-bit values map to `[0, 1]` linearly, as in the course.
/// The decoder reads the file through [`super::file::Bounded`]: never more than the limit.
pub fn load_texture(path: &Path) -> Result<Texture> {
    decode(open(path)?.buffered(), path)
}

/// Decode an image read from `reader` (the format is told by its magic bytes).
fn decode(reader: impl BufRead + Seek, path: &Path) -> Result<Texture> {
    let img = image::ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?
        .decode()
        .map_err(|e| Error::parse(path, None, format!("cannot decode image: {e}")))?
        .to_rgb8();
    let (width, height) = img.dimensions();
    if width == 0 || height == 0 {
        return Err(Error::parse(path, None, "image has no pixels"));
    }
    let texels = img.pixels().map(|p| Color::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0).collect();
    Ok(Texture { width, height, texels })
}
