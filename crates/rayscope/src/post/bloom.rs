//! Bloom ([`BloomSettings`]): the bright pass, its separable Gaussian blur, and the blur added
//! back to the image.
//!
//! The blur scatters every pixel's value over its neighbours with normalised weights, and a
//! weight that falls past the image's border is mirrored back into it (the border is a mirror
//! half a pixel out), so no energy leaves the image: the blurred layer's total is the bright
//! pass's, per channel, up to float rounding (the tests bound it). Each pass of the separable
//! blur runs row by row in parallel; the vertical pass is the horizontal one on the transposed
//! image.

use rayon::prelude::*;

use crate::film::FloatImage;
use crate::math::Color;
use crate::settings::BloomSettings;

/// The layers of a bloom, for the debugger's views: what glows, and its glow.
#[derive(Clone, Debug, PartialEq)]
pub struct BloomLayers {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The bright pass: per channel, `max(c - threshold, 0)`; rows from the top.
    pub bright: Vec<Color>,
    /// The bright pass blurred by the Gaussian; rows from the top.
    pub blurred: Vec<Color>,
}

/// The normalised weights of the Gaussian of `radius` pixels: `2 ceil(radius) + 1` of them,
/// centred, with standard deviation `radius / 3`; radius 0 is the single weight 1.
pub fn gaussian_weights(radius: f32) -> Vec<f32> {
    let reach = radius.max(0.0).ceil() as i64;
    let sigma = radius / 3.0;
    let raw: Vec<f64> = (-reach..=reach)
        .map(|k| if reach == 0 { 1.0 } else { (-(k * k) as f64 / (2.0 * f64::from(sigma).powi(2))).exp() })
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|w| (w / sum) as f32).collect()
}

/// The bright pass of `pixels`: per channel, what exceeds `threshold`.
pub fn bright_pass(pixels: &[Color], threshold: f32) -> Vec<Color> {
    pixels.iter().map(|c| (*c - Color::splat(threshold)).max(Color::ZERO)).collect()
}

/// `layer` (`width x height`, rows from the top) blurred by the separable Gaussian of `radius`
/// pixels, its border a mirror (see the module).
pub fn blur(layer: &[Color], width: u32, height: u32, radius: f32) -> Vec<Color> {
    let weights = gaussian_weights(radius);
    let (w, h) = (width as usize, height as usize);
    let rows = scatter_rows(layer, w, &weights);
    let columns = scatter_rows(&transpose(&rows, w, h), h, &weights);
    transpose(&columns, h, w)
}

/// The bright pass and its blur.
pub fn layers(pixels: &[Color], width: u32, height: u32, settings: &BloomSettings) -> BloomLayers {
    let bright = bright_pass(pixels, settings.threshold);
    let blurred = blur(&bright, width, height, settings.radius);
    BloomLayers { width, height, bright, blurred }
}

/// Add `settings.strength` times the blurred bright pass to `pixels`. Off (strength 0), or
/// with no value above the threshold, the pixels keep every bit.
pub fn apply(pixels: &mut [Color], width: u32, height: u32, settings: &BloomSettings) {
    if settings.is_off() || pixels.iter().all(|c| c.max_element() <= settings.threshold) {
        return;
    }
    let glow = layers(pixels, width, height, settings).blurred;
    for (p, g) in pixels.iter_mut().zip(glow) {
        *p += settings.strength * g;
    }
}

/// [`apply`] to a 3-channel float image (a 1-channel one, an AOV, is left as it is).
pub fn apply_to_image(image: &mut FloatImage, settings: &BloomSettings) {
    if image.channels != 3 || settings.is_off() {
        return;
    }
    let mut pixels: Vec<Color> = image.data.chunks_exact(3).map(Color::from_slice).collect();
    apply(&mut pixels, image.width, image.height, settings);
    image.data = pixels.iter().flat_map(|c| c.to_array()).collect();
}

/// Every row of `layer` (rows of `width`) scattered along itself with `weights` (centred),
/// mirrored at the row's ends.
fn scatter_rows(layer: &[Color], width: usize, weights: &[f32]) -> Vec<Color> {
    let reach = (weights.len() / 2) as i64;
    let mut out = vec![Color::ZERO; layer.len()];
    out.par_chunks_mut(width).zip(layer.par_chunks(width)).for_each(|(out, row)| {
        for (i, &c) in row.iter().enumerate() {
            if c == Color::ZERO {
                continue;
            }
            let first = i as i64 - reach;
            if first >= 0 && i as i64 + reach < width as i64 {
                // Inside the row: no weight reaches past its ends (the same sums, in the same
                // order, as the mirrored loop, without its index folding).
                for (o, &wk) in out[first as usize..].iter_mut().zip(weights) {
                    *o += wk * c;
                }
                continue;
            }
            for (k, &wk) in weights.iter().enumerate() {
                out[mirror(first + k as i64, width)] += wk * c;
            }
        }
    });
    out
}

/// Index `i` folded into `0..n` by mirrors half a pixel past each end (`-1` is `0`, `n` is
/// `n - 1`), as often as needed.
fn mirror(i: i64, n: usize) -> usize {
    let n = n as i64;
    let m = i.rem_euclid(2 * n);
    (if m < n { m } else { 2 * n - 1 - m }) as usize
}

/// `layer` (`width x height`) transposed to `height x width`.
fn transpose(layer: &[Color], width: usize, height: usize) -> Vec<Color> {
    let mut out = vec![Color::ZERO; layer.len()];
    for (y, row) in layer.chunks_exact(width).enumerate() {
        for (x, &c) in row.iter().enumerate() {
            out[x * height + y] = c;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_normalised_symmetric_and_radius_zero_is_identity() {
        for r in [0.0, 0.4, 1.0, 2.5, 8.0, 40.0] {
            let w = gaussian_weights(r);
            assert_eq!(w.len(), 2 * r.ceil() as usize + 1);
            let sum: f64 = w.iter().map(|&x| f64::from(x)).sum();
            assert!((sum - 1.0).abs() < 1e-6, "{r}: {sum}");
            assert!(w.iter().zip(w.iter().rev()).all(|(a, b)| a == b));
        }
        assert_eq!(gaussian_weights(0.0), vec![1.0]);
    }

    #[test]
    fn mirror_folds_indices_back_into_the_row() {
        let folded: Vec<usize> = (-5..9).map(|i| mirror(i, 3)).collect();
        assert_eq!(folded, vec![1, 2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0, 1, 2]);
    }

    #[test]
    fn one_bright_pixel_blurs_into_the_outer_product_of_the_weights() {
        let (w, h) = (21u32, 21u32);
        let mut layer = vec![Color::ZERO; 441];
        layer[10 * 21 + 10] = Color::new(1.0, 2.0, 4.0);
        let blurred = blur(&layer, w, h, 3.0);
        let g = gaussian_weights(3.0);
        for y in 0..21 {
            for x in 0..21 {
                let (dx, dy) = (x as i64 - 10, y as i64 - 10);
                let want = if dx.abs() <= 3 && dy.abs() <= 3 {
                    g[(dx + 3) as usize] * g[(dy + 3) as usize] * Color::new(1.0, 2.0, 4.0)
                } else {
                    Color::ZERO
                };
                assert!((blurred[y * 21 + x] - want).abs().max_element() < 1e-6, "{x},{y}");
            }
        }
    }
}
