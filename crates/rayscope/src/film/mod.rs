//! Films: where rendered values are kept, as sums of samples, until written out; and their
//! exact sums ([`exact_sum`]), which make a film's value independent of how its samples were
//! grouped (split into parts on many machines, or a render stopped and resumed).

pub mod exact_sum;

use crate::math::Color;
use exact_sum::ExactSum;

/// A pixel's sums of samples, red, green and blue, in `f64`.
pub type PixelSum = [f64; 3];

/// What an addition to a pixel's [`PixelSum`] lost to rounding: the pixel's exact sum is its
/// `f64` sum plus all its residuals (see [`Film`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Residual {
    /// The pixel, `y * width + x`.
    pub pixel: u32,
    /// The bits each channel's addition lost (0 where none).
    pub value: PixelSum,
}

/// A linear-RGB accumulation film: per pixel, the sum of its samples and their count. The
/// pixel's value is their mean.
///
/// Sums are exact, so a pixel's value depends only on its samples, not on the order or the
/// grouping in which they were added: a render split into parts and merged, or stopped and
/// resumed, equals the one-shot render bit for bit. Each `f32` sample is added to an `f64`
/// running sum and the addition checked for exactness (two subtractions and compares per
/// channel); while every addition is exact the `f64` sum IS the exact sum, whatever the order.
/// The rare addition that rounds (it takes some 30 binary orders of magnitude between the
/// samples of one pixel) records what it lost as a [`Residual`], computed exactly (TwoSum), and
/// the pixel's value is then taken from the exact sum of its `f64` sum and residuals
/// ([`ExactSum`]). With one sample the sum is the sample: the value has the bits it always had.
///
/// No NaN or infinity enters a film: a sample that is not finite (a degenerate input can
/// make one, and it would blank its pixel, or with a filter its neighbours, for good) adds
/// black instead, and is counted in [`Film::dropped`] so that it is reported, not hidden.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    width: u32,
    height: u32,
    sum: Vec<PixelSum>,
    count: Vec<u32>,
    /// Sorted by pixel (stably: a pixel's residuals in the order they arose).
    residuals: Vec<Residual>,
    dropped: u64,
}

/// The mutable sums and counts of a film, for the renderer to add samples to (with
/// [`add_sample`]).
pub struct FilmSlices<'a> {
    /// Per-pixel sums, rows from the top.
    pub sums: &'a mut [PixelSum],
    /// Per-pixel sample counts.
    pub counts: &'a mut [u32],
}

impl Film {
    /// A film with no samples.
    pub fn new(width: u32, height: u32) -> Film {
        let n = width as usize * height as usize;
        Film { width, height, sum: vec![[0.0; 3]; n], count: vec![0; n], residuals: Vec::new(), dropped: 0 }
    }

    /// A film from its parts (as a partial film file holds them), or what is wrong with them:
    /// sizes that do not match `width * height`, a residual naming a pixel outside, or a pixel
    /// with no samples and a sum other than +0 (a render adds a pixel's first sample without
    /// reading its sum: [`add_first_sample`]).
    pub fn from_parts(
        width: u32,
        height: u32,
        sum: Vec<PixelSum>,
        count: Vec<u32>,
        mut residuals: Vec<Residual>,
        dropped: u64,
    ) -> Result<Film, &'static str> {
        let n = width as usize * height as usize;
        if sum.len() != n || count.len() != n || residuals.iter().any(|r| r.pixel as usize >= n) {
            return Err("channels or residuals do not fit the image size");
        }
        if count.iter().zip(&sum).any(|(n, s)| *n == 0 && s.iter().any(|v| v.to_bits() != 0)) {
            return Err("a pixel with no samples has a sum");
        }
        residuals.sort_by_key(|r| r.pixel);
        Ok(Film { width, height, sum, count, residuals, dropped })
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
        self.value(self.index(x, y))
    }

    fn value(&self, i: usize) -> Color {
        let n = self.count[i];
        if n == 0 {
            return Color::ZERO;
        }
        let s = self.exact(i);
        let n = f64::from(n);
        Color::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
    }

    /// The exact sum of pixel `i`'s samples (truncated to `f64` where it needs more bits).
    #[inline]
    fn exact(&self, i: usize) -> PixelSum {
        // Almost every film has no residuals at all: one test, not a search, per pixel.
        if self.residuals.is_empty() { self.sum[i] } else { self.exact_with_residuals(i) }
    }

    /// [`Film::exact`] where some pixel has residuals: this one's, if any, added exactly.
    #[cold]
    #[inline(never)]
    fn exact_with_residuals(&self, i: usize) -> PixelSum {
        let first = self.residuals.partition_point(|r| (r.pixel as usize) < i);
        let mine = self.residuals[first..].iter().take_while(|r| r.pixel as usize == i);
        if first == self.residuals.len() || self.residuals[first].pixel as usize != i {
            return self.sum[i];
        }
        let mut exact: [ExactSum; 3] = Default::default();
        for (c, e) in exact.iter_mut().enumerate() {
            e.add(self.sum[i][c]);
            for r in mine.clone() {
                e.add(r.value[c]);
            }
        }
        exact.map(|e| e.to_f64())
    }

    /// The exact sum of pixel `(x, y)`'s samples, as [`Film::get`] divides it (an `f64` that
    /// holds it, or truncated to one in the rare pixel that needs more bits).
    pub fn sum(&self, x: u32, y: u32) -> PixelSum {
        self.exact(self.index(x, y))
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

    /// Per-pixel running sums (without their residuals), rows from the top.
    pub fn sums(&self) -> &[PixelSum] {
        &self.sum
    }

    /// Per-pixel sample counts, rows from the top.
    pub fn counts(&self) -> &[u32] {
        &self.count
    }

    /// What the running sums lost to rounding, sorted by pixel.
    pub fn residuals(&self) -> &[Residual] {
        &self.residuals
    }

    /// Mutable sums and counts, for the renderer; what its additions lose comes back through
    /// [`Film::add_residuals`].
    pub fn slices_mut(&mut self) -> FilmSlices<'_> {
        FilmSlices { sums: &mut self.sum, counts: &mut self.count }
    }

    /// Add one sample `c` (finite: see [`finite_or_black`]) to pixel `(x, y)`, exactly, as the
    /// renderer adds its samples through [`Film::slices_mut`] and [`add_sample`].
    pub fn add(&mut self, x: u32, y: u32, c: Color) {
        let i = self.index(x, y);
        let mut lost = Vec::new();
        add_sample(&mut self.sum[i], c, i as u32, &mut lost);
        self.count[i] += 1;
        self.add_residuals(lost);
    }

    /// Keep `more` residuals, made after the ones the film has (a pixel's residuals stay in
    /// the order they arose).
    pub fn add_residuals(&mut self, more: Vec<Residual>) {
        if !more.is_empty() {
            self.residuals.extend(more);
            self.residuals.sort_by_key(|r| r.pixel);
        }
    }

    /// Add every sample of `other` (a film of the same size) to this one: the sums exactly,
    /// so that films of disjoint samples merge into the film of all of them, whatever the
    /// grouping. Returns false, changing nothing, if the sizes differ.
    pub fn merge(&mut self, other: &Film) -> bool {
        if (self.width, self.height) != (other.width, other.height) {
            return false;
        }
        let mut lost = other.residuals.clone();
        for (i, (sum, o)) in self.sum.iter_mut().zip(&other.sum).enumerate() {
            add_exact(sum, *o, i as u32, &mut lost);
        }
        for (n, o) in self.count.iter_mut().zip(&other.count) {
            *n += o;
        }
        self.dropped += other.dropped;
        self.add_residuals(lost);
        true
    }

    /// Samples that were not finite and were added as black (see [`Film`]).
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Count `n` more samples that were not finite and were added as black: whoever adds
    /// samples through [`Film::slices_mut`] adds them with [`finite_or_black`] and counts here.
    pub fn add_dropped(&mut self, n: u64) {
        self.dropped += n;
    }

    /// Forget every sample.
    pub fn clear(&mut self) {
        self.sum.fill([0.0; 3]);
        self.count.fill(0);
        self.residuals.clear();
        self.dropped = 0;
    }

    /// Every pixel's value, rows from the top.
    pub fn pixels(&self) -> Vec<Color> {
        (0..self.sum.len()).map(|i| self.value(i)).collect()
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

/// Add the sample `c` (finite: see [`finite_or_black`]) to pixel `pixel`'s running `sum`,
/// pushing what the addition loses, if anything, to `residuals` (see [`Film`]).
#[inline(always)]
pub fn add_sample(sum: &mut PixelSum, c: Color, pixel: u32, residuals: &mut Vec<Residual>) {
    add_exact(sum, [f64::from(c.x), f64::from(c.y), f64::from(c.z)], pixel, residuals);
}

/// [`add_sample`] for a pixel's first sample (its sum is zero): the sum becomes `c` without
/// reading the old one or checking the addition, which is exact. A one-sample render adds
/// every sample here, where the check cost it about 3% of its instructions.
#[inline(always)]
pub fn add_first_sample(sum: &mut PixelSum, c: Color) {
    debug_assert!(sum.iter().all(|s| s.to_bits() == 0), "a pixel's first sample goes to a zero sum");
    // `0.0 + x`, not `x`: as in `add_sample`, a sample of -0.0 leaves a sum of +0.0.
    *sum = [0.0 + f64::from(c.x), 0.0 + f64::from(c.y), 0.0 + f64::from(c.z)];
}

/// `sum += b`, channel by channel, pushing what the additions lose to `residuals`.
#[inline(always)]
fn add_exact(sum: &mut PixelSum, b: PixelSum, pixel: u32, residuals: &mut Vec<Residual>) {
    let a = *sum;
    let s = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    *sum = s;
    // Adding to a zero sum (a pixel's first sample: every sample of a one-sample render) is
    // exact: the check below, most of this function's cost, is for the later ones.
    // (Compared as bits: a sum of -0.0 takes the check, which it passes.)
    if a[0].to_bits() | a[1].to_bits() | a[2].to_bits() == 0 {
        return;
    }
    // An addition `s = a + b` is exact iff `s - a == b` and `s - b == a`: when it rounds, the
    // subtraction of the operand of larger magnitude is exact (Fast2Sum) and so differs.
    let lost = (s[0] - a[0] != b[0])
        | (s[0] - b[0] != a[0])
        | (s[1] - a[1] != b[1])
        | (s[1] - b[1] != a[1])
        | (s[2] - a[2] != b[2])
        | (s[2] - b[2] != a[2]);
    if lost {
        push_residual(a, b, s, pixel, residuals);
    }
}

/// The rare path of [`add_exact`]: the exact rounding errors of `s = a + b` (Knuth's TwoSum).
#[cold]
#[inline(never)]
fn push_residual(a: PixelSum, b: PixelSum, s: PixelSum, pixel: u32, residuals: &mut Vec<Residual>) {
    let value = std::array::from_fn(|c| {
        let bb = s[c] - a[c];
        (a[c] - (s[c] - bb)) + (b[c] - bb)
    });
    residuals.push(Residual { pixel, value });
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

    /// The first sample's shortcut leaves the bits `add_sample` leaves on a zero sum, signed
    /// zeros, subnormals and extremes included.
    #[test]
    fn a_first_sample_is_added_as_add_sample_adds_it() {
        for c in [
            Color::ZERO,
            Color::new(-0.0, 0.0, -0.0),
            Color::new(f32::MAX, -f32::MAX, f32::MIN_POSITIVE),
            Color::new(1.0e-45, -3.5, 0.1),
        ] {
            let (mut first, mut added, mut lost) = ([0.0; 3], [0.0; 3], Vec::new());
            add_first_sample(&mut first, c);
            add_sample(&mut added, c, 0, &mut lost);
            assert_eq!(first.map(f64::to_bits), added.map(f64::to_bits), "{c:?}");
            assert!(lost.is_empty());
        }
    }

    #[test]
    fn a_film_whose_empty_pixel_has_a_sum_is_refused() {
        assert!(Film::from_parts(2, 1, vec![[0.0; 3], [0.5, 0.0, 0.0]], vec![0, 1], Vec::new(), 0).is_ok());
        let e = Film::from_parts(2, 1, vec![[0.0, -0.0, 0.0], [0.5; 3]], vec![0, 1], Vec::new(), 0).unwrap_err();
        assert_eq!(e, "a pixel with no samples has a sum");
    }

    /// A pixel whose samples span more binary orders than an f64 holds: its value is the
    /// same whatever the order of the samples, and films merged equal one film.
    #[test]
    fn sums_are_exact_in_any_grouping() {
        let samples = [1.0e8f32, 3.0e-9, 7.5, 1.0e-30, 2.5e-8, 1.0e8, 0.125];
        let fill = |order: &[usize]| {
            let mut film = Film::new(1, 1);
            let mut lost = Vec::new();
            let FilmSlices { sums, counts } = film.slices_mut();
            for &k in order {
                add_sample(&mut sums[0], Color::splat(samples[k]), 0, &mut lost);
                counts[0] += 1;
            }
            film.add_residuals(lost);
            film
        };
        let all = fill(&[0, 1, 2, 3, 4, 5, 6]);
        assert!(!all.residuals().is_empty(), "this pixel needs its residuals");
        let reversed = fill(&[6, 5, 4, 3, 2, 1, 0]);
        assert_eq!(all.get(0, 0), reversed.get(0, 0));
        let mut merged = fill(&[3, 0, 6]);
        assert!(merged.merge(&fill(&[5, 1])));
        assert!(merged.merge(&fill(&[2, 4])));
        assert_eq!(merged.get(0, 0), all.get(0, 0));
        assert_eq!(merged.sum(0, 0), all.sum(0, 0));
        assert_eq!(merged.samples(0, 0), 7);
    }
}
