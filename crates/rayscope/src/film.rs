//! Films: where rendered values are kept, as linear floats, until written out.

use crate::math::Color;

/// A linear-RGB accumulation film: per pixel, the sum of its samples and their count. The
/// pixel's value is their mean. Samples are added one at a time in sample order, so the same
/// samples give bit-identical sums however the work was split into frames or threads.
///
/// No NaN or infinity enters a film: a sample that is not finite (a degenerate input can
/// make one, and it would blank its pixel, or with a filter its neighbours, for good) adds
/// black instead, and is counted in [`Film::dropped`] so that it is reported, not hidden.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    width: u32,
    height: u32,
    sum: Vec<Color>,
    count: Vec<u32>,
    dropped: u64,
}

impl Film {
    /// A film with no samples.
    pub fn new(width: u32, height: u32) -> Film {
        let n = width as usize * height as usize;
        Film { width, height, sum: vec![Color::ZERO; n], count: vec![0; n], dropped: 0 }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    #[inline]
    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    /// The value of pixel `(x, y)` (row 0 at the top): the mean of its samples, black if none.
    pub fn get(&self, x: u32, y: u32) -> Color {
        let i = self.index(x, y);
        if self.count[i] == 0 { Color::ZERO } else { self.sum[i] / self.count[i] as f32 }
    }

    /// Samples accumulated in pixel `(x, y)`.
    pub fn samples(&self, x: u32, y: u32) -> u32 {
        self.count[self.index(x, y)]
    }

    /// The fewest and the most samples of any pixel.
    pub fn sample_range(&self) -> (u32, u32) {
        let min = self.count.iter().copied().min().unwrap_or(0);
        let max = self.count.iter().copied().max().unwrap_or(0);
        (min, max)
    }

    /// Per-pixel sums and counts, rows from the top (what the renderer accumulates into).
    pub fn raw(&self) -> (&[Color], &[u32]) {
        (&self.sum, &self.count)
    }

    /// Mutable sums and counts.
    pub fn raw_mut(&mut self) -> (&mut [Color], &mut [u32]) {
        (&mut self.sum, &mut self.count)
    }

    /// Samples that were not finite and were added as black (see [`Film`]).
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Count `n` more samples that were not finite and were added as black: whoever adds
    /// samples through [`Film::raw_mut`] adds them with [`finite_or_black`] and counts here.
    pub fn add_dropped(&mut self, n: u64) {
        self.dropped += n;
    }

    /// Forget every sample.
    pub fn clear(&mut self) {
        self.sum.fill(Color::ZERO);
        self.count.fill(0);
        self.dropped = 0;
    }

    /// Every pixel's value, rows from the top.
    pub fn pixels(&self) -> Vec<Color> {
        (0..self.height).flat_map(|y| (0..self.width).map(move |x| (x, y))).map(|(x, y)| self.get(x, y)).collect()
    }

    /// Mean of all pixels.
    pub fn mean(&self) -> Color {
        self.pixels().iter().copied().sum::<Color>() / (self.sum.len().max(1)) as f32
    }

    /// As a 3-channel float image.
    pub fn to_image(&self) -> FloatImage {
        FloatImage {
            width: self.width,
            height: self.height,
            channels: 3,
            data: self.pixels().iter().flat_map(|c| c.to_array()).collect(),
        }
    }
}

/// `c` if it is finite, else black and `dropped` counts it: what a sample may add to a film.
#[inline(always)]
#[allow(clippy::eq_op, reason = "`x - x` tells a finite `x` (0) from an infinite or NaN one (NaN)")]
pub fn finite_or_black(c: Color, dropped: &mut u64) -> Color {
    // `x - x` is 0 for a finite `x` and NaN for an infinite or NaN one, so one sum of the
    // three differences checks all components with one compare and one well-predicted branch
    // (three `is_finite` tests, each with its own branch, cost 2-3% of a 1-spp render's
    // instructions).
    let zero = (c.x - c.x) + (c.y - c.y) + (c.z - c.z);
    if zero == 0.0 { c } else { not_finite(dropped) }
}

/// The rare path of [`finite_or_black`], out of the sample loop.
#[cold]
#[inline(never)]
fn not_finite(dropped: &mut u64) -> Color {
    *dropped += 1;
    Color::ZERO
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_finite_samples_pass() {
        let mut dropped = 0;
        for c in [Color::ZERO, Color::new(f32::MAX, -f32::MAX, f32::MIN_POSITIVE), Color::new(0.5, 1.0, 3.0)] {
            assert_eq!(finite_or_black(c, &mut dropped), c);
        }
        assert_eq!(dropped, 0);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for axis in 0..3 {
                let mut c = Color::splat(0.25);
                c[axis] = bad;
                assert_eq!(finite_or_black(c, &mut dropped), Color::ZERO, "{c:?}");
            }
        }
        assert_eq!(dropped, 9);
    }
}
