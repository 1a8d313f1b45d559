//! Films: where rendered values are kept, as linear floats, until written out.

use crate::math::Color;

/// A linear-RGB colour image.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    width: u32,
    height: u32,
    pixels: Vec<Color>,
}

impl Film {
    /// A black film.
    pub fn new(width: u32, height: u32) -> Film {
        Film {
            width,
            height,
            pixels: vec![Color::ZERO; width as usize * height as usize],
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Pixels in rows from the top.
    pub fn pixels(&self) -> &[Color] {
        &self.pixels
    }

    /// Pixel `(x, y)`, row 0 at the top.
    pub fn get(&self, x: u32, y: u32) -> Color {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Set pixel `(x, y)`.
    pub fn set(&mut self, x: u32, y: u32, c: Color) {
        self.pixels[(y * self.width + x) as usize] = c;
    }

    /// Mean of all pixels.
    pub fn mean(&self) -> Color {
        self.pixels.iter().copied().sum::<Color>() / self.pixels.len().max(1) as f32
    }

    /// As a 3-channel float image.
    pub fn to_image(&self) -> FloatImage {
        FloatImage {
            width: self.width,
            height: self.height,
            channels: 3,
            data: self.pixels.iter().flat_map(|c| c.to_array()).collect(),
        }
    }
}

/// A float image of 1 or 3 channels, rows from the top, channels interleaved: colour or an
/// AOV, ready for the writers in [`crate::output`].
#[derive(Clone, Debug, PartialEq)]
pub struct FloatImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// 1 (grey) or 3 (RGB).
    pub channels: u32,
    /// `width * height * channels` values.
    pub data: Vec<f32>,
}

impl FloatImage {
    /// The `channels` values of pixel `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        let c = self.channels as usize;
        let i = (y as usize * self.width as usize + x as usize) * c;
        &self.data[i..i + c]
    }
}
