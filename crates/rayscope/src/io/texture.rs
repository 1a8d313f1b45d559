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
