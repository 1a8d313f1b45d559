//! Comparing an image with rayscope's render of the same scene: how many pixels differ, by
//! how much, how different the two look (SSIM), and a picture of where.
//!
//! - this file: the images compared ([`CompareImage`], read by [`read_image`] or made from a
//!   render by [`CompareImage::from_render`]), the comparison ([`compare`], [`Comparison`]);
//! - `ssim.rs`: the structural similarity index of Wang et al. (2004) on luminance;
//! - `difference.rs`: the difference image (black where equal, a heat ramp elsewhere).
//!
//! The rule for what "differ" means: the course's images are 8-bit, so two pixels differ
//! when their 8-bit values differ in any channel. An 8-bit image (PNG, BMP: anything the
//! decoder gives as integers, 16-bit PNGs rounded to 8 bits) is compared with our render as
//! our PNG writer stores it; a float image (OpenEXR, Radiance HDR) with our linear floats,
//! and a pixel differs when the two would differ once written as 8-bit PNGs (each value
//! clamped to `[0, 1]`, times 255, rounded): float noise below one level is not a
//! difference, but it is in the errors, which are measured on the values compared (levels
//! divided by 255 for 8-bit images, the floats themselves otherwise).

mod difference;
mod ssim;

use std::path::Path;

use image::DynamicImage;

use crate::error::{Error, Result};
use crate::film::FloatImage;
use crate::output::{Encoding, to_rgb8, to_u8};

pub use difference::difference_color;
pub use ssim::{SSIM_SIGMA, SSIM_WINDOW};

/// How an image's values are stored, which decides how it is compared (see the module's doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Depth {
    /// 8 bits a channel: values are levels divided by 255.
    EightBit,
    /// Floating point: linear values as they are.
    Float,
}

/// An RGB image to compare, with a name for messages (its file, or what rendered it).
#[derive(Clone, Debug, PartialEq)]
pub struct CompareImage {
    /// Three channels; for [`Depth::EightBit`], exact multiples of 1/255 in `[0, 1]`.
    pub image: FloatImage,
    /// How its values are stored.
    pub depth: Depth,
    /// The file it came from, or what made it ("rayscope's render of cornell-box").
    pub name: String,
}

/// Read `path` (PNG, BMP, OpenEXR or Radiance HDR, told by its content) as an image to
/// compare: integer formats as 8-bit, float formats as floats, which must be finite. Alpha
/// is ignored. The file is read as the loaders read files: a regular file, within the byte
/// limit ([`crate::scene::max_file_bytes`]); every error names it.
pub fn read_image(path: &Path) -> Result<CompareImage> {
    let img = crate::io::image_file::read_image(path)?;
    let (width, height) = (img.width(), img.height());
    let (data, depth) = match img {
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_) => {
            let data = img.to_rgb32f().into_raw();
            if let Some(i) = data.iter().position(|v| !v.is_finite()) {
                let p = (i / 3) as u64;
                let (x, y) = (p % u64::from(width), p / u64::from(width));
                return Err(Error::parse(path, None, format!("pixel ({x}, {y}) is not a finite colour")));
            }
            (data, Depth::Float)
        }
        _ => (img.to_rgb8().into_raw().into_iter().map(level).collect(), Depth::EightBit),
    };
    let image = FloatImage { width, height, channels: 3, data };
    Ok(CompareImage { image, depth, name: path.display().to_string() })
}

/// The value of an 8-bit level.
fn level(v: u8) -> f32 {
    f32::from(v) / 255.0
}

impl CompareImage {
    /// Our render (a 3-channel float image) as it is compared with an image of `depth`: for
    /// 8-bit, as the PNG writer stores it with `encoding`; for float, as it is.
    pub fn from_render(render: &FloatImage, depth: Depth, encoding: Encoding, name: impl Into<String>) -> CompareImage {
        let data = match depth {
            Depth::EightBit => to_rgb8(render, encoding).into_iter().map(level).collect(),
            Depth::Float => render.data.clone(),
        };
        let image = FloatImage { data, ..render.clone() };
        CompareImage { image, depth, name: name.into() }
    }
}

/// Per-channel errors and their summary over the channels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ChannelErrors {
    /// Red, green, blue.
    pub rgb: [f64; 3],
    /// All channels: the mean of the three for a mean error, the largest for a maximum.
    pub overall: f64,
}

/// What [`compare`] found. Errors are absolute differences of values in `[0, 1]` units (one
/// 8-bit level is 1/255).
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels whose 8-bit values differ in any channel.
    pub differing: u64,
    /// Mean absolute error over all pixels.
    pub mean_error: ChannelErrors,
    /// Largest absolute error of any pixel.
    pub max_error: ChannelErrors,
    /// Mean SSIM of the two images' luminance (1: identical); `None` for an image smaller
    /// than the [`SSIM_WINDOW`] in either direction, which has no whole window.
    pub ssim: Option<f64>,
    /// Per pixel, rows from the top: its largest channel error, or `None` where the 8-bit
    /// values are equal.
    errors: Vec<Option<f32>>,
}

impl Comparison {
    /// Pixels compared.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Whether pixel `(x, y)` differs, and if so its largest channel error.
    pub fn error_at(&self, x: u32, y: u32) -> Option<f32> {
        self.errors[y as usize * self.width as usize + x as usize]
    }

    /// The pixels that differ, row by row from the top.
    pub fn differing_pixels(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        let w = self.width as usize;
        self.errors.iter().enumerate().filter(|(_, e)| e.is_some()).map(move |(i, _)| ((i % w) as u32, (i / w) as u32))
    }

    /// The difference image: black where the pixels are equal, elsewhere a colour for the
    /// error (see [`difference_color`]).
    pub fn difference_image(&self) -> FloatImage {
        difference::image(self)
    }

    /// The summary line: `N of M pixels differ`.
    pub fn summary(&self) -> String {
        format!("{} of {} pixels differ", self.differing, self.pixels())
    }
}

/// Compare `theirs` with `ours`. Images of different sizes, or of different [`Depth`], are an
/// error naming both; build `ours` with [`CompareImage::from_render`] for the depth of theirs.
pub fn compare(theirs: &CompareImage, ours: &CompareImage) -> Result<Comparison> {
    let (a, b) = (&theirs.image, &ours.image);
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::Invalid(format!(
            "{} is {}x{} pixels but {} is {}x{}: only images of the same size can be compared",
            theirs.name, a.width, a.height, ours.name, b.width, b.height
        )));
    }
    if theirs.depth != ours.depth || a.channels != 3 || b.channels != 3 {
        return Err(Error::Invalid(format!(
            "{} ({:?}) and {} ({:?}) must both be RGB of the same depth to be compared",
            theirs.name, theirs.depth, ours.name, ours.depth
        )));
    }
    let mut sum = [0f64; 3];
    let mut max = [0f64; 3];
    let mut differing = 0;
    let errors: Vec<Option<f32>> = a
        .data
        .chunks_exact(3)
        .zip(b.data.chunks_exact(3))
        .map(|(p, q)| {
            let mut largest = 0f32;
            for c in 0..3 {
                let e = (p[c] - q[c]).abs();
                sum[c] += f64::from(e);
                max[c] = max[c].max(f64::from(e));
                largest = largest.max(e);
            }
            let differs = (0..3).any(|c| quantise(p[c]) != quantise(q[c]));
            differing += u64::from(differs);
            differs.then_some(largest)
        })
        .collect();
    let n = (errors.len().max(1)) as f64;
    let mean = sum.map(|s| s / n);
    Ok(Comparison {
        width: a.width,
        height: a.height,
        differing,
        mean_error: ChannelErrors { rgb: mean, overall: mean.iter().sum::<f64>() / 3.0 },
        max_error: ChannelErrors { rgb: max, overall: max.into_iter().fold(0.0, f64::max) },
        ssim: ssim::mean_ssim(&luminance(a), &luminance(b), a.width as usize, a.height as usize),
        errors,
    })
}

/// A value's 8-bit level, as the PNG writer stores it (the course's linear look).
fn quantise(v: f32) -> u8 {
    to_u8(v, Encoding::Linear)
}

/// Luminance in 8-bit units (`[0, 255]` for values in `[0, 1]`), with the weights of ITU-R
/// BT.601 that Wang et al.'s reference code applies to colour images (MATLAB's `rgb2gray`).
fn luminance(img: &FloatImage) -> Vec<f64> {
    img.data
        .chunks_exact(3)
        .map(|p| 255.0 * (0.298_936 * f64::from(p[0]) + 0.587_043 * f64::from(p[1]) + 0.114_021 * f64::from(p[2])))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, depth: Depth, f: impl Fn(u32, u32) -> [f32; 3]) -> CompareImage {
        let f = &f;
        let data = (0..height).flat_map(|y| (0..width).flat_map(move |x| f(x, y))).collect();
        CompareImage { image: FloatImage { width, height, channels: 3, data }, depth, name: "img".into() }
    }

    fn pattern(x: u32, y: u32) -> [f32; 3] {
        [level(((x * 7 + y * 13) % 200) as u8), level(((x * x + y) % 256) as u8), level((x ^ y) as u8)]
    }

    #[test]
    fn identical_images_have_no_difference_and_ssim_1() {
        let a = image(40, 30, Depth::EightBit, pattern);
        let c = compare(&a, &a.clone()).unwrap();
        assert_eq!((c.differing, c.pixels()), (0, 1200));
        assert_eq!(c.summary(), "0 of 1200 pixels differ");
        assert_eq!(c.mean_error, ChannelErrors::default());
        assert_eq!(c.max_error, ChannelErrors::default());
        assert_eq!(c.ssim, Some(1.0));
        assert!(c.difference_image().data.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn a_constant_offset_gives_its_error_everywhere() {
        let a = image(20, 20, Depth::EightBit, pattern);
        // 3 levels more in green, except where that would pass 255.
        let b = image(20, 20, Depth::EightBit, |x, y| {
            let p = pattern(x, y);
            [p[0], p[1] + 3.0 / 255.0, p[2]]
        });
        let c = compare(&a, &b).unwrap();
        assert_eq!(c.differing, 400);
        let e = 3.0 / 255.0;
        assert!((c.mean_error.rgb[1] - e).abs() < 1e-6, "{:?}", c.mean_error);
        assert_eq!((c.mean_error.rgb[0], c.mean_error.rgb[2]), (0.0, 0.0));
        assert!((c.mean_error.overall - e / 3.0).abs() < 1e-6);
        assert!((c.max_error.overall - e).abs() < 1e-6 && c.max_error.rgb[0] == 0.0);
        assert_eq!(c.differing_pixels().count(), 400);
    }

    #[test]
    fn exactly_the_changed_pixels_differ() {
        let a = image(16, 12, Depth::EightBit, pattern);
        let changed = [(0, 0), (5, 3), (15, 11)];
        let b = image(16, 12, Depth::EightBit, |x, y| {
            let mut p = pattern(x, y);
            if changed.contains(&(x, y)) {
                p[2] = 1.0 - p[2] + level(1);
            }
            p
        });
        let c = compare(&a, &b).unwrap();
        assert_eq!(c.differing_pixels().collect::<Vec<_>>(), changed);
        let diff = c.difference_image();
        for y in 0..12 {
            for x in 0..16 {
                let black = diff.pixel(x, y).iter().all(|&v| v == 0.0);
                assert_eq!(black, !changed.contains(&(x, y)), "({x}, {y})");
            }
        }
    }

    #[test]
    fn floats_differ_only_where_their_8_bit_values_do() {
        let a = image(2, 1, Depth::Float, |x, _| [0.5, 0.25, if x == 0 { 2.0 } else { 0.1 }]);
        // Pixel 0: 3.0 against 2.0 clamps to the same level; pixel 1: 1e-4 apart is the same
        // level too; but both errors count.
        let b = image(2, 1, Depth::Float, |x, _| [0.5, 0.25, if x == 0 { 3.0 } else { 0.1001 }]);
        let c = compare(&a, &b).unwrap();
        assert_eq!(c.differing, 0);
        assert!((c.max_error.rgb[2] - 1.0).abs() < 1e-6);
        let d = image(2, 1, Depth::Float, |x, _| [0.5, 0.25 + 1.0 / 255.0, if x == 0 { 2.0 } else { 0.1 }]);
        assert_eq!(compare(&a, &d).unwrap().differing, 2);
    }

    #[test]
    fn sizes_and_depths_must_match() {
        let a = image(4, 4, Depth::EightBit, pattern);
        let mut b = image(5, 4, Depth::EightBit, pattern);
        b.name = "ours".into();
        let err = compare(&a, &b).unwrap_err().to_string();
        assert_eq!(err, "img is 4x4 pixels but ours is 5x4: only images of the same size can be compared");
        let f = image(4, 4, Depth::Float, pattern);
        assert!(compare(&a, &f).is_err());
        // Too small for one SSIM window: no SSIM, but the rest.
        assert_eq!(compare(&a, &a).unwrap().ssim, None);
    }

    #[test]
    fn a_render_is_compared_as_its_png_would_be() {
        let render = FloatImage { width: 2, height: 1, channels: 3, data: vec![0.5, -1.0, 7.0, 0.001, 0.999, 0.3] };
        let ours = CompareImage::from_render(&render, Depth::EightBit, Encoding::Linear, "ours");
        assert_eq!(ours.image.data, to_rgb8(&render, Encoding::Linear).into_iter().map(level).collect::<Vec<_>>());
        let float = CompareImage::from_render(&render, Depth::Float, Encoding::Linear, "ours");
        assert_eq!(float.image, render);
    }

    #[test]
    fn image_files_are_read_by_their_content() {
        let dir = tempfile::tempdir().unwrap();
        let rgb = image::RgbImage::from_fn(3, 2, |x, y| image::Rgb([x as u8 * 100, y as u8 * 50, 7]));
        for (name, format) in [("a.png", image::ImageFormat::Png), ("a.bmp", image::ImageFormat::Bmp)] {
            let path = dir.path().join(name);
            rgb.save_with_format(&path, format).unwrap();
            let img = read_image(&path).unwrap();
            assert_eq!(img.depth, Depth::EightBit);
            assert_eq!(img.image.pixel(2, 1), [level(200), level(50), level(7)]);
        }
        let path = dir.path().join("a.exr");
        let float = image::Rgb32FImage::from_fn(2, 1, |x, _| image::Rgb([x as f32 * 4.0, 0.5, 0.25]));
        DynamicImage::ImageRgb32F(float).save_with_format(&path, image::ImageFormat::OpenExr).unwrap();
        let img = read_image(&path).unwrap();
        assert_eq!((img.depth, img.image.pixel(1, 0)), (Depth::Float, &[4.0, 0.5, 0.25][..]));
        // Not an image: an error that names the file.
        let bad = dir.path().join("bad.png");
        std::fs::write(&bad, b"not an image").unwrap();
        let err = read_image(&bad).unwrap_err().to_string();
        assert!(err.starts_with(&bad.display().to_string()) && err.contains("cannot decode"), "{err}");
        let err = read_image(&dir.path().join("missing.png")).unwrap_err().to_string();
        assert!(err.contains("missing.png") && err.contains("No such file"), "{err}");
    }
}
