//! Films: where rendered values are kept, as sums of samples, until written out; and their
//! exact sums ([`exact_sum`]), which make a film's value independent of how its samples were
//! grouped (split into parts on many machines, or a render stopped and resumed).

pub mod exact_sum;

use crate::math::Color;
use exact_sum::ExactSum;
use rayon::iter::ParallelIterator;
use rayon::slice::ParallelSliceMut;

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
/// A new film keeps its sums as `f32` until a pixel gets a second sample ([`Sums`]): a
/// one-sample render, the default, then fills 16 bytes a pixel instead of 28.
///
/// No NaN or infinity enters a film: a sample that is not finite (a degenerate input can
/// make one, and it would blank its pixel, or with a filter its neighbours, for good) adds
/// black instead, and is counted in [`Film::dropped`] so that it is reported, not hidden.
#[derive(Clone, Debug)]
pub struct Film {
    width: u32,
    height: u32,
    sums: Sums,
    count: Vec<u32>,
    /// Sorted by pixel (stably: a pixel's residuals in the order they arose).
    residuals: Vec<Residual>,
    dropped: u64,
}

/// A film's running sums.
#[derive(Clone, Debug)]
enum Sums {
    /// Before any pixel has two samples: each sum is zero or the pixel's one sample, which an
    /// `f32` holds exactly (12 bytes a pixel, where `f64` sums take 24: the allocation, the
    /// page faults and the writes of a one-sample render's film are 16 bytes a pixel with the
    /// count, not 28). `filled`: some pixel may hold a sample (the next sample to any pixel
    /// needs `f64` sums, and [`Film::widen`] makes them). `stale`: the film was cleared
    /// ([`Film::clear`]) without zeroing the sums, which hold an earlier render's values until
    /// the next pass zeroes them band by band (read as zeros meanwhile: `stale` implies not
    /// `filled`).
    Single { sums: Vec<[f32; 3]>, filled: bool, stale: bool },
    /// `f64` running sums, checked for exactness as samples are added.
    Exact(Vec<PixelSum>),
}

impl Sums {
    /// Zero sums for `n` pixels.
    fn zero(n: usize) -> Sums {
        Sums::Single { sums: vec![[0.0; 3]; n], filled: false, stale: false }
    }

    /// Pixel `i`'s running sum.
    #[inline]
    fn get(&self, i: usize) -> PixelSum {
        match self {
            Sums::Single { stale: true, .. } => [0.0; 3],
            Sums::Single { sums, .. } => sums[i].map(f64::from),
            Sums::Exact(sums) => sums[i],
        }
    }

    fn len(&self) -> usize {
        match self {
            Sums::Single { sums, .. } => sums.len(),
            Sums::Exact(sums) => sums.len(),
        }
    }
}

/// The mutable sums and counts of a film, for the renderer to add samples to (with a
/// [`PixelAccumulator`]: [`add_sample`] for `f64` sums).
pub(crate) struct FilmSlices<'a, S> {
    /// Per-pixel sums, rows from the top.
    pub sums: &'a mut [S],
    /// Per-pixel sample counts.
    pub counts: &'a mut [u32],
    /// Whether `sums` hold an earlier render's values, which each band of the pass zeroes
    /// before it adds (or, cancelled, instead): a cleared film's `f32` sums ([`Film::clear`]).
    pub stale: bool,
}

/// How the renderer adds a sample to a pixel's sum in a film's storage: the `f64` sums add it
/// exactly ([`add_sample`], or [`add_first_sample`] for a pixel's first), the `f32` sums of a
/// film's first pass store it (see [`Sums`]).
pub(crate) trait PixelAccumulator: Send + Copy + Default {
    /// Add sample `c` (finite: see [`finite_or_black`]), the pixel's first (its sample 0,
    /// whose sum is zero).
    fn add_first(&mut self, c: Color);

    /// Add sample `c` (finite), a later one, to the sum of pixel `pixel`, pushing what the
    /// addition loses to `residuals`.
    fn add(&mut self, c: Color, pixel: u32, residuals: &mut Vec<Residual>);
}

impl PixelAccumulator for PixelSum {
    #[inline(always)]
    fn add_first(&mut self, c: Color) {
        add_first_sample(self, c);
    }

    #[inline(always)]
    fn add(&mut self, c: Color, pixel: u32, residuals: &mut Vec<Residual>) {
        add_sample(self, c, pixel, residuals);
    }
}

/// The one sample a film's first pass adds to a pixel (a pass that would add two runs on
/// `f64` sums), stored as [`add_first_sample`] stores it in an `f64`: whether it is the
/// pixel's sample 0 or a later one (a part's first, `crate::partial`), its sum is zero.
impl PixelAccumulator for [f32; 3] {
    #[inline(always)]
    fn add_first(&mut self, c: Color) {
        debug_assert!(self.iter().all(|s| s.to_bits() == 0), "an f32 sum takes one sample");
        // `0.0 + x`, not `x`: a sample of -0.0 leaves a sum of +0.0, as an addition does.
        *self = [0.0 + c.x, 0.0 + c.y, 0.0 + c.z];
    }

    #[inline(always)]
    fn add(&mut self, c: Color, _: u32, _: &mut Vec<Residual>) {
        self.add_first(c);
    }
}

/// A film's sums and counts lent to a render pass, in the storage the pass adds to.
pub(crate) enum PassSlices<'a> {
    /// The first pass of a fresh film, adding at most one sample to each pixel.
    Single(FilmSlices<'a, [f32; 3]>),
    /// Any other pass.
    Exact(FilmSlices<'a, PixelSum>),
}

/// Films are equal when their sizes, sums, counts, residuals and dropped samples are, however
/// their sums are stored.
impl PartialEq for Film {
    fn eq(&self, other: &Film) -> bool {
        (self.width, self.height, &self.count, &self.residuals, self.dropped)
            == (other.width, other.height, &other.count, &other.residuals, other.dropped)
            && self.sums().eq(other.sums())
    }
}

impl Film {
    /// A film with no samples.
    pub fn new(width: u32, height: u32) -> Film {
        let n = width as usize * height as usize;
        Film { width, height, sums: Sums::zero(n), count: vec![0; n], residuals: Vec::new(), dropped: 0 }
    }

    /// This film with no samples, sized `width` x `height`: [`Film::new`]'s film, in this
    /// one's memory where it is the same size ([`Film::clear`]).
    pub fn cleared(mut self, width: u32, height: u32) -> Film {
        if (self.width, self.height) != (width, height) {
            return Film::new(width, height);
        }
        self.clear();
        self
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
        Ok(Film { width, height, sums: Sums::Exact(sum), count, residuals, dropped })
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
        if self.residuals.is_empty() { self.sums.get(i) } else { self.exact_with_residuals(i) }
    }

    /// [`Film::exact`] where some pixel has residuals: this one's, if any, added exactly.
    #[cold]
    #[inline(never)]
    fn exact_with_residuals(&self, i: usize) -> PixelSum {
        let first = self.residuals.partition_point(|r| (r.pixel as usize) < i);
        let mine = self.residuals[first..].iter().take_while(|r| r.pixel as usize == i);
        let sum = self.sums.get(i);
        if first == self.residuals.len() || self.residuals[first].pixel as usize != i {
            return sum;
        }
        let mut exact: [ExactSum; 3] = Default::default();
        for (c, e) in exact.iter_mut().enumerate() {
            e.add(sum[c]);
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
    pub fn sums(&self) -> impl ExactSizeIterator<Item = PixelSum> + '_ {
        (0..self.sums.len()).map(|i| self.sums.get(i))
    }

    /// Per-pixel sample counts, rows from the top.
    pub fn counts(&self) -> &[u32] {
        &self.count
    }

    /// What the running sums lost to rounding, sorted by pixel.
    pub fn residuals(&self) -> &[Residual] {
        &self.residuals
    }

    /// Per-pixel sample counts, to set where a pass is to start (a part's first sample).
    pub(crate) fn counts_mut(&mut self) -> &mut [u32] {
        &mut self.count
    }

    /// Mutable sums and counts for a render pass that adds at most `most` samples to any
    /// pixel, in `f32` while the film is fresh and `most` is 1 (see [`Sums`]), else in `f64`;
    /// what its additions lose comes back through [`Film::add_residuals`].
    pub(crate) fn pass_slices(&mut self, most: u32) -> PassSlices<'_> {
        if most > 1 || matches!(self.sums, Sums::Single { filled: true, .. }) {
            self.widen();
        }
        match &mut self.sums {
            Sums::Single { sums, filled, stale } => {
                *filled = true;
                // The pass zeroes every band's sums, those it renders and those it skips.
                let stale = std::mem::take(stale);
                PassSlices::Single(FilmSlices { sums, counts: &mut self.count, stale })
            }
            Sums::Exact(sums) => PassSlices::Exact(FilmSlices { sums, counts: &mut self.count, stale: false }),
        }
    }

    /// The sums in `f64` from now on (the same values: an `f32` converts exactly; a film with
    /// no sample yet gets zeroed memory, as `Film::new` had it before, not a conversion).
    fn widen(&mut self) -> &mut [PixelSum] {
        match &self.sums {
            Sums::Single { filled: false, sums, .. } => self.sums = Sums::Exact(vec![[0.0; 3]; sums.len()]),
            Sums::Single { filled: true, sums, .. } => {
                self.sums = Sums::Exact(sums.iter().map(|s| s.map(f64::from)).collect());
            }
            Sums::Exact(_) => {}
        }
        match &mut self.sums {
            Sums::Exact(sums) => sums,
            Sums::Single { .. } => unreachable!("widened above"),
        }
    }

    /// Add one sample `c` (finite: see [`finite_or_black`]) to pixel `(x, y)`, exactly, as the
    /// renderer adds its samples with [`add_sample`].
    pub fn add(&mut self, x: u32, y: u32, c: Color) {
        let i = self.index(x, y);
        let mut lost = Vec::new();
        add_sample(&mut self.widen()[i], c, i as u32, &mut lost);
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
        for (i, (sum, o)) in self.widen().iter_mut().zip(other.sums()).enumerate() {
            add_exact(sum, o, i as u32, &mut lost);
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

    /// Forget every sample: [`Film::new`]'s film of this size. `f32` sums (which a one-sample
    /// render leaves) are left to the next pass, which zeroes each band's just before it adds
    /// to them, in cache (a clear of the whole film, 12 bytes a pixel, cost 1.5-3% of a
    /// one-sample render); `f64` sums are replaced. The counts are zeroed here (a part's pass
    /// sets them first). Renders one after another
    /// (`render --repeat`, an animation's frames, the viewer's frames while the camera moves)
    /// then write to pages they have touched, where a new film's first writes fault in fresh
    /// zeroed pages from the kernel: some 650 faults and 5-6 ms of kernel time a render at
    /// 800x800 (the Cornell box on two threads, `perf stat`; see BENCHMARKS.md).
    pub fn clear(&mut self) {
        match &mut self.sums {
            Sums::Single { filled, stale, .. } => {
                // On every thread: one thread took 0.9 ms to zero the counts and the sums (16
                // bytes a pixel, 10 MB at 800x800) while the others waited for the render.
                const CHUNK: usize = 1 << 14;
                self.count.par_chunks_mut(CHUNK).for_each(|counts| counts.fill(0));
                *stale |= std::mem::take(filled);
            }
            Sums::Exact(_) => {
                self.sums = Sums::zero(self.count.len());
                self.count.fill(0);
            }
        }
        self.residuals.clear();
        self.dropped = 0;
    }

    /// Every pixel's value, rows from the top.
    pub fn pixels(&self) -> Vec<Color> {
        (0..self.count.len()).map(|i| self.value(i)).collect()
    }

    /// Mean of all pixels.
    pub fn mean(&self) -> Color {
        self.pixels().iter().copied().sum::<Color>() / (self.count.len().max(1)) as f32
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
pub fn finite_or_black(c: Color, dropped: &mut u64) -> Color {
    // A component is not finite when its exponent bits are all ones. `x` and `y` are tested
    // together as one 64-bit word, `z` alone: a sample's colour usually arrives through the
    // stack as an 8-byte store of `x, y` and a 4-byte one of `z`, and loads that match them are
    // forwarded from the stores, where a float test's load of `y, z` as a pair spans both and
    // waits for them to retire (3-4% of a 1-spp render of the Cornell box). One branch, which
    // predicts well: adding the exponent's lowest bit carries into a lane's sign bit only from
    // an all-ones exponent, and never into the next lane.
    const EXP: u64 = 0x7f80_0000_7f80_0000;
    const CARRY: u64 = 0x0080_0000_0080_0000;
    const SIGN: u64 = 0x8000_0000_8000_0000;
    let xy = u64::from(c.x.to_bits()) | (u64::from(c.y.to_bits()) << 32);
    let z = u64::from(c.z.to_bits());
    let inf_or_nan = (((xy & EXP) + CARRY) | ((z & EXP) + CARRY)) & SIGN;
    if inf_or_nan == 0 {
        return c;
    }
    // Black made here, not returned by the cold call: a colour returned from it came back
    // through the stack, where the common path's joined it, and a sum's `0.0 + c` then loaded
    // `y, z` as a pair across both stores and waited as above.
    count_dropped(dropped);
    Color::ZERO
}

/// The rare path of [`finite_or_black`], out of the sample loop.
#[cold]
#[inline(never)]
fn count_dropped(dropped: &mut u64) {
    *dropped += 1;
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

    /// The bit test agrees with `is_finite` on every component, whatever the other two hold:
    /// random bit patterns, and the edges of the exponent (all ones but one bit, all ones with
    /// any sign and payload).
    #[test]
    fn the_bit_test_is_is_finite() {
        let mut rng = crate::sampler::Pcg32::new(0x9e37_79b9_7f4a_7c15, 0);
        let mut next = || rng.next_u32();
        let edges = [0x7f80_0000, 0xff80_0000, 0x7fc0_0001, 0xffff_ffff, 0x7f7f_ffff, 0xff7f_ffff, 0x8000_0000, 1, 0];
        for n in 0..200_000u32 {
            let mut bits = [next(), next(), next()];
            if n % 4 == 0 {
                bits[(n / 4 % 3) as usize] = edges[(n / 12) as usize % edges.len()];
            }
            let c = Color::new(f32::from_bits(bits[0]), f32::from_bits(bits[1]), f32::from_bits(bits[2]));
            let mut dropped = 0;
            let out = finite_or_black(c, &mut dropped);
            if c.is_finite() {
                assert_eq!((out.to_array().map(f32::to_bits), dropped), (bits, 0));
            } else {
                assert_eq!((out, dropped), (Color::ZERO, 1), "{bits:x?}");
            }
        }
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

    /// A fresh film's one-sample pass stores `f32` sums; the next pass, or a pass of more
    /// than one sample, works on `f64` sums holding the same values; films compare by value
    /// whatever their storage.
    #[test]
    fn the_first_one_sample_pass_adds_to_f32_sums() {
        let samples = [Color::new(-0.0, 0.1, 3.0e38), Color::new(1.0e-45, 0.5, 7.25)];
        let mut film = Film::new(2, 1);
        match film.pass_slices(1) {
            PassSlices::Single(s) => {
                for (i, c) in samples.iter().enumerate() {
                    s.sums[i].add_first(*c);
                    s.counts[i] = 1;
                }
            }
            PassSlices::Exact(_) => panic!("a fresh film's one-sample pass adds to f32 sums"),
        }
        let mut exact = Film::new(2, 1);
        for (i, c) in samples.iter().enumerate() {
            exact.add(i as u32, 0, *c);
        }
        assert!(matches!(exact.sums, Sums::Exact(_)));
        assert_eq!(film, exact);
        for i in 0..2 {
            assert_eq!(film.get(i, 0).to_array().map(f32::to_bits), exact.get(i, 0).to_array().map(f32::to_bits));
            assert_eq!(film.sum(i, 0).map(f64::to_bits), exact.sum(i, 0).map(f64::to_bits));
        }
        assert_eq!(film.sum(0, 0)[0].to_bits(), 0, "-0.0 is added as +0.0");
        // A second pass widens, keeping every value.
        assert!(matches!(film.pass_slices(1), PassSlices::Exact(_)));
        assert_eq!(film, exact);
        assert!(matches!(Film::new(1, 1).pass_slices(2), PassSlices::Exact(_)));
    }

    /// A cleared film reads as a new one while its `f32` sums still hold the old values (its
    /// next pass zeroes them band by band), and hands the pass those sums marked stale, however
    /// often it was cleared; a film no pass has been given sums to fill has none to zero.
    #[test]
    fn a_cleared_film_reads_as_new_until_its_pass_zeroes_it() {
        let mut film = Film::new(2, 1);
        match film.pass_slices(1) {
            PassSlices::Single(s) => {
                assert!(!s.stale, "a new film's sums are zero");
                s.sums[1].add_first(Color::new(0.25, 0.5, 1.0));
                s.counts[1] = 1;
            }
            PassSlices::Exact(_) => panic!("a fresh film's one-sample pass adds to f32 sums"),
        }
        film.clear();
        assert_eq!(film, Film::new(2, 1));
        assert!(film.sums().all(|s| s.iter().all(|v| v.to_bits() == 0)));
        assert!(matches!(&film.sums, Sums::Single { sums, stale: true, .. } if sums[1] == [0.25, 0.5, 1.0]));
        film.clear();
        match film.pass_slices(1) {
            PassSlices::Single(s) => assert!(s.stale, "the old sums are the pass's to zero"),
            PassSlices::Exact(_) => panic!("a cleared film's one-sample pass adds to f32 sums"),
        }
        let mut new = Film::new(2, 1);
        new.clear();
        assert!(matches!(new.pass_slices(1), PassSlices::Single(s) if !s.stale), "nothing to zero");
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
            for &k in order {
                film.add(0, 0, Color::splat(samples[k]));
            }
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
