//! Deterministic sampling: every random number a pixel sample uses is a function of the seed,
//! the pixel and the sample index alone, so images do not depend on threads, tiles or the
//! order in which pixels are rendered, and the debugger can replay any sample exactly.
//!
//! - Sub-pixel positions: with one sample, the pixel centre (the course's image); with a
//!   known sample count `N` that is a square `m x m`, a jittered
//!   `m x m` grid whose cells are visited in a per-pixel random order (any prefix is still
//!   unbiased); otherwise the `(0,2)`-sequence (Sobol' dimensions 0 and 1) randomised per pixel
//!   by a digital shift, whose first `2^k` points are stratified in every elementary interval.
//! - Shutter times: a per-pixel rotation of the base-3 radical inverse of the sample index.
//! - Everything else (light points, glossy directions): a PCG32 stream per pixel sample, used
//!   through stratified helpers ([`stratum_2d`], [`grid_dims`]).

use crate::math::Vec2;

/// Mix a 64-bit value (SplitMix64's finaliser): a strong, cheap hash for seeding.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash several words into one.
#[inline]
pub fn hash(words: &[u64]) -> u64 {
    words.iter().fold(0x51_7CC1_B727_220A, |h, &w| mix64(h ^ w.wrapping_add(0x9E37_79B9_7F4A_7C15)))
}

/// PCG32 (O'Neill): small state, good statistics, fast.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    /// A generator whose state is `state` (which should already be well mixed, as a hash
    /// output is) on stream `stream`, without PCG's warm-up steps.
    #[inline]
    pub fn from_state(state: u64, stream: u64) -> Pcg32 {
        Pcg32 { state, inc: (stream << 1) | 1 }
    }

    /// A generator for `seed` on stream `stream`.
    pub fn new(seed: u64, stream: u64) -> Pcg32 {
        let mut r = Pcg32 { state: 0, inc: (stream << 1) | 1 };
        r.next_u32();
        r.state = r.state.wrapping_add(seed);
        r.next_u32();
        r
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in `[0, 1)`.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        // 24 random bits: every value is exactly representable and below 1.
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Two uniform numbers in `[0, 1)`.
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }
}

/// Kensler's hash-based permutation of `0..n` ("Correlated Multi-Jittered Sampling", 2013):
/// element `i` of a pseudo-random permutation chosen by `key`, without storing it.
pub fn permute(mut i: u32, n: u32, key: u32) -> u32 {
    debug_assert!(i < n);
    if n <= 1 {
        return 0;
    }
    let mut w = n - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        i ^= key;
        i = i.wrapping_mul(0xe170_893d);
        i ^= key >> 16;
        i ^= (i & w) >> 4;
        i ^= key >> 8;
        i = i.wrapping_mul(0x0929_eb3f);
        i ^= key >> 23;
        i ^= (i & w) >> 1;
        i = i.wrapping_mul(1 | key >> 27);
        i = i.wrapping_mul(0x6935_fa69);
        i ^= (i & w) >> 11;
        i = i.wrapping_mul(0x74dc_b303);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0x9e50_1cc3);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0xc860_a3df);
        i &= w;
        i ^= i >> 5;
        if i < n {
            return (i.wrapping_add(key)) % n;
        }
    }
}

/// Van der Corput (base 2) radical inverse of `i`, as 32 bits.
#[inline]
fn van_der_corput(i: u32) -> u32 {
    i.reverse_bits()
}

/// Sobol' dimension 1 (the second coordinate of the (0,2)-sequence), as 32 bits.
#[inline]
fn sobol_dim1(mut i: u32) -> u32 {
    let mut v: u32 = 1 << 31;
    let mut r = 0;
    while i != 0 {
        if i & 1 != 0 {
            r ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    r
}

#[inline]
fn bits_to_unit(b: u32) -> f32 {
    (b >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Base-3 radical inverse of `i`, in `[0, 1)`: the digits reversed as an integer, then one
/// division.
fn radical_inverse_3(mut i: u32) -> f32 {
    // Five base-3 digits at a time through a table (one step for the first 243 samples,
    // where a digit loop's varying trip count cost branch mispredictions on every camera
    // sample). `reversed / scale` is the same rational number as digit by digit, with both
    // terms exact in f64 (3^25 < 2^53), so the result is identical.
    const DIGITS: u32 = 5;
    const BASE: u32 = 243; // 3^DIGITS
    const TABLE: [u16; BASE as usize] = {
        let mut t = [0u16; BASE as usize];
        let mut n = 0;
        while n < BASE {
            let (mut x, mut r, mut d) = (n, 0, 0);
            while d < DIGITS {
                r = r * 3 + x % 3;
                x /= 3;
                d += 1;
            }
            t[n as usize] = r as u16;
            n += 1;
        }
        t
    };
    let (mut reversed, mut scale) = (0u64, 1u64);
    while i > 0 {
        reversed = reversed * BASE as u64 + TABLE[(i % BASE) as usize] as u64;
        scale *= BASE as u64;
        i /= BASE;
    }
    (reversed as f64 / scale as f64) as f32
}

/// The integer square root of `n` when `n` is a perfect square.
pub fn exact_sqrt(n: u32) -> Option<u32> {
    // Truncation, not `round()`: baseline x86-64 has no rounding instruction, and this runs
    // for every camera sample.
    let m = ((n as f64).sqrt() + 0.5) as u64;
    (m * m == n as u64).then_some(m as u32)
}

/// A grid `a x b = n` as square as possible (`a <= b`), for stratifying `n` 2D samples.
pub fn grid_dims(n: u32) -> (u32, u32) {
    let mut a = (n as f64).sqrt().floor() as u32;
    while a > 1 && !n.is_multiple_of(a) {
        a -= 1;
    }
    let a = a.max(1);
    (a, n.max(1) / a)
}

/// Sample `i` of `n` stratified over `[0,1]^2`: a jittered cell of the [`grid_dims`] grid (see
/// [`Strata2::sample`] for why the square is closed).
#[inline]
pub fn stratum_2d(i: u32, n: u32, jitter: Vec2) -> Vec2 {
    Strata2::new(n).sample(i, jitter)
}

/// The [`grid_dims`] grid of `n` strata, computed once for a loop over its samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strata2 {
    a: u32,
    b: u32,
    inv: Vec2,
}

impl Strata2 {
    /// The grid for `n` samples.
    pub fn new(n: u32) -> Strata2 {
        let (a, b) = grid_dims(n);
        Strata2 { a, b, inv: Vec2::new(1.0 / a as f32, 1.0 / b as f32) }
    }

    /// Sample `i`: cell `i` of the grid, jittered by `jitter` in `[0,1)^2`. The result is in
    /// `[0,1]^2`, not `[0,1)^2`: in the last row or column, the largest jitter a sampler draws
    /// (`1 - 2^-24`) rounds the cell's far edge up to exactly 1 (every user of these numbers
    /// takes 1: light points are defined over `[0,1]^2`, the pixel filters at their edge).
    #[inline]
    pub fn sample(&self, i: u32, jitter: Vec2) -> Vec2 {
        let (x, y) = (i % self.a, (i / self.a) % self.b);
        (Vec2::new(x as f32, y as f32) + jitter) * self.inv
    }
}

/// Sample `i` of `n` stratified over `[0,1]` (the last stratum's largest jitter rounds up to
/// exactly 1, as in [`Strata2::sample`]).
#[inline]
pub fn stratum_1d(i: u32, n: u32, jitter: f32) -> f32 {
    (i as f32 + jitter) / n.max(1) as f32
}

/// The two hashes a pixel sample's numbers come from: one per pixel, one per sample.
struct SampleKeys {
    pixel_key: u64,
    sample_key: u64,
}

impl SampleKeys {
    #[inline]
    fn new(seed: u64, pixel: u32, index: u32) -> SampleKeys {
        let pixel_key = mix64(seed ^ mix64(pixel as u64 ^ 0x9E37_79B9_7F4A_7C15));
        let sample_key = mix64(pixel_key ^ (index as u64).wrapping_mul(0xD1B5_4A32_D192_ED03));
        SampleKeys { pixel_key, sample_key }
    }
}

/// Mixed into a pixel's key to give its lens samples their own numbers.
const LENS_STREAM: u64 = 0x6A09_E667_F3BC_C909;

/// A nested uniform (Owen) scramble of the bits of `i` read from the most significant end
/// (Burley, "Practical Hash-based Owen Scrambling", 2020): a permutation of the indices that
/// maps every aligned block of `2^k` indices onto an aligned block of `2^k`, so the first
/// `2^k` points of a shuffled `(0,2)`-sequence are still the stratified set of some block.
#[inline]
fn nested_uniform_shuffle(i: u32, seed: u32) -> u32 {
    // Laine and Karras's hash on the reversed bits: each bit is changed only by the bits below
    // it, which (reversed) are the bits above it.
    let mut x = i.reverse_bits().wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x.reverse_bits()
}

/// The random numbers of one pixel sample.
#[derive(Clone, Debug)]
pub struct PixelSampler {
    /// Position within the pixel, in `[0,1]^2` (1 only on a jittered grid's last row or
    /// column, as in [`Strata2::sample`]; `[0,1)^2` otherwise).
    pub pixel_offset: Vec2,
    /// Shutter time, in `[0, 1)`.
    pub time: f32,
    rng: Pcg32,
}

impl PixelSampler {
    /// The sampler of sample `index` of pixel `pixel` (a linear pixel index). `planned` is the
    /// number of samples the pixel will get if known (it selects the jittered grid for
    /// squares), or 0 for open-ended progressive rendering.
    ///
    /// Inlined: from a call, the sampler came back through memory as 8- and 4-byte stores
    /// that the caller's 16-byte copies into its packet's array of samplers read across, a
    /// load no store forwards (twice per sampler, 3% of a 1-spp render of the Cornell box).
    #[inline(always)]
    pub fn new(seed: u64, pixel: u32, index: u32, planned: u32) -> PixelSampler {
        // Built for every camera sample, so kept to a few hashes: a profile once found a
        // third of a simple scene's time here.
        let SampleKeys { pixel_key, sample_key } = SampleKeys::new(seed, pixel, index);
        let rng = Pcg32::from_state(sample_key, pixel_key);
        // One planned sample: the pixel centre, as the course traced it (tested before the
        // square root, whose latency showed in profiles of one-sample renders).
        let pixel_offset = if planned == 1 && index == 0 {
            Vec2::splat(0.5)
        } else {
            Self::offset(planned, index, pixel_key, sample_key)
        };
        let rotation = bits_to_unit((pixel_key >> 16) as u32);
        // The fractional part of a sum in [0, 2], without a libm call (baseline x86-64 has no
        // rounding instruction): subtracting 1 or 2 there is exact, so this equals `fract`.
        let sum = radical_inverse_3(index) + rotation;
        let time = if sum >= 2.0 {
            sum - 2.0
        } else if sum >= 1.0 {
            sum - 1.0
        } else {
            sum
        };
        PixelSampler { pixel_offset, time, rng }
    }

    /// The position in the pixel of sample `index` of `planned` (not the one-sample case).
    #[inline(never)]
    fn offset(planned: u32, index: u32, pixel_key: u64, sample_key: u64) -> Vec2 {
        match exact_sqrt(planned) {
            Some(m) if m > 1 && index < planned => {
                let cell = permute(index, planned, pixel_key as u32);
                let j = mix64(sample_key ^ 0xA076_1D64_78BD_642F);
                let jitter = Vec2::new(bits_to_unit(j as u32), bits_to_unit((j >> 32) as u32));
                (Vec2::new((cell % m) as f32, (cell / m) as f32) + jitter) / m as f32
            }
            _ => {
                let shift = pixel_key;
                Vec2::new(
                    bits_to_unit(van_der_corput(index) ^ (shift as u32)),
                    bits_to_unit(sobol_dim1(index) ^ ((shift >> 32) as u32)),
                )
            }
        }
    }

    /// The point on the lens of sample `index` of pixel `pixel` (arguments as
    /// [`PixelSampler::new`]), in `[0,1)^2` (up to the grid's closed edge, as
    /// [`Strata2::sample`]), for a thin lens ([`crate::lens::ThinLens`]): a function of the
    /// same seed, pixel and index, so the debugger replays it. It is not drawn by
    /// [`PixelSampler::new`], so that a pinhole camera's samples cost nothing more.
    ///
    /// Stratified jointly with [`PixelSampler::pixel_offset`]: with a square planned count the
    /// lens's `m x m` cells are each visited once, in an order independent of the pixel's
    /// (so every pixel cell sees a different lens cell); otherwise the `(0,2)`-sequence of an
    /// Owen-shuffled index with its own digital shift, whose first `2^k` points are still one
    /// per elementary interval, decorrelated from the pixel offsets by the shuffle.
    pub fn lens_offset(seed: u64, pixel: u32, index: u32, planned: u32) -> Vec2 {
        let SampleKeys { pixel_key, sample_key } = SampleKeys::new(seed, pixel, index);
        let lens_key = mix64(pixel_key ^ LENS_STREAM);
        match exact_sqrt(planned) {
            Some(m) if m > 1 && index < planned => {
                let cell = permute(index, planned, lens_key as u32);
                let j = mix64(sample_key ^ LENS_STREAM);
                let jitter = Vec2::new(bits_to_unit(j as u32), bits_to_unit((j >> 32) as u32));
                (Vec2::new((cell % m) as f32, (cell / m) as f32) + jitter) / m as f32
            }
            _ => {
                let i = nested_uniform_shuffle(index, (lens_key >> 32) as u32);
                Vec2::new(
                    bits_to_unit(van_der_corput(i) ^ (lens_key as u32)),
                    bits_to_unit(sobol_dim1(i) ^ ((lens_key >> 16) as u32)),
                )
            }
        }
    }

    /// The next uniform number in `[0, 1)`.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        self.rng.next_f32()
    }

    /// The next two uniform numbers.
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        self.rng.next_2d()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radical_inverse_3_matches_digit_by_digit() {
        let slow = |mut i: u32| {
            let (mut reversed, mut scale) = (0u64, 1u64);
            while i > 0 {
                reversed = reversed * 3 + (i % 3) as u64;
                scale *= 3;
                i /= 3;
            }
            (reversed as f64 / scale as f64) as f32
        };
        for i in (0..100_000).chain([242, 243, 244, 59048, 59049, u32::MAX - 1, u32::MAX]) {
            assert_eq!(radical_inverse_3(i).to_bits(), slow(i).to_bits(), "{i}");
        }
        assert_eq!(radical_inverse_3(1), 1.0 / 3.0);
    }

    #[test]
    fn permute_is_a_permutation() {
        for n in [1, 2, 7, 16, 100] {
            let mut seen: Vec<u32> = (0..n).map(|i| permute(i, n, 12345)).collect();
            seen.sort();
            assert_eq!(seen, (0..n).collect::<Vec<_>>());
        }
    }

    #[test]
    fn square_counts_fill_every_grid_cell() {
        let n = 16;
        let mut cells: Vec<(u32, u32)> = (0..n)
            .map(|i| {
                let o = PixelSampler::new(3, 77, i, n).pixel_offset;
                ((o.x * 4.0) as u32, (o.y * 4.0) as u32)
            })
            .collect();
        cells.sort();
        cells.dedup();
        assert_eq!(cells.len(), 16);
    }

    #[test]
    fn open_ended_samples_are_stratified_at_powers_of_two() {
        // The first 64 points of the shifted (0,2)-sequence: one per cell of an 8x8 grid, and
        // one per 64 x 1 strip.
        let pts: Vec<Vec2> = (0..64).map(|i| PixelSampler::new(9, 5, i, 0).pixel_offset).collect();
        assert_one_per_cell(&pts, |p| (p.x * 8.0) as u32 * 8 + (p.y * 8.0) as u32);
        assert_one_per_cell(&pts, |p| (p.x * 64.0) as u32);
    }

    /// Each of `pts` in its own cell, as `cell` numbers them.
    fn assert_one_per_cell(pts: &[Vec2], cell: impl Fn(&Vec2) -> u32) {
        let mut cells: Vec<u32> = pts.iter().map(cell).collect();
        cells.sort();
        cells.dedup();
        assert_eq!(cells.len(), pts.len());
    }

    #[test]
    fn same_inputs_same_numbers() {
        let mut a = PixelSampler::new(1, 2, 3, 4);
        let mut b = PixelSampler::new(1, 2, 3, 4);
        assert_eq!(a.pixel_offset, b.pixel_offset);
        assert_eq!(a.next_2d(), b.next_2d());
        let c = PixelSampler::new(1, 2, 4, 4);
        assert_ne!(a.pixel_offset, c.pixel_offset);
    }

    #[test]
    fn lens_offsets_are_stratified_and_replayable() {
        // A square count: one sample per lens cell, in another order than the pixel cells.
        let n = 16;
        let lens: Vec<Vec2> = (0..n).map(|i| PixelSampler::lens_offset(3, 77, i, n)).collect();
        let cell = |o: &Vec2| (o.x * 4.0) as u32 * 4 + (o.y * 4.0) as u32;
        assert_one_per_cell(&lens, cell);
        let pixel: Vec<_> = (0..n).map(|i| cell(&PixelSampler::new(3, 77, i, n).pixel_offset)).collect();
        assert_ne!(pixel, lens.iter().map(cell).collect::<Vec<_>>(), "lens cells follow the pixel cells");
        // Open-ended: the first 64 are one per cell of an 8x8 grid, of a 64 x 1 and of a 1 x 64.
        let pts: Vec<Vec2> = (0..64).map(|i| PixelSampler::lens_offset(9, 5, i, 0)).collect();
        assert_one_per_cell(&pts, |p| (p.x * 8.0) as u32 * 8 + (p.y * 8.0) as u32);
        assert_one_per_cell(&pts, |p| (p.x * 64.0) as u32);
        assert_one_per_cell(&pts, |p| (p.y * 64.0) as u32);
        assert!(pts.iter().all(|p| (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)));
        assert_eq!(PixelSampler::lens_offset(9, 5, 7, 0), pts[7], "the same inputs give the same point");
    }

    #[test]
    fn nested_uniform_shuffle_permutes_aligned_blocks() {
        for seed in [0, 1, 0xdead_beef] {
            let mut first: Vec<u32> = (0..8).map(|i| nested_uniform_shuffle(i, seed)).collect();
            first.sort();
            let base = first[0] & !7;
            assert_eq!(first, (base..base + 8).collect::<Vec<_>>(), "seed {seed}");
        }
    }

    #[test]
    fn grid_dims_are_near_square() {
        assert_eq!(grid_dims(50), (5, 10));
        assert_eq!(grid_dims(49), (7, 7));
        assert_eq!(grid_dims(7), (1, 7));
        assert_eq!(grid_dims(1), (1, 1));
    }

    #[test]
    fn times_cover_the_shutter() {
        // The first 27 base-3 radical inverses are the lattice i/27; rotated, they still put
        // one time in each 1/27 of the shutter.
        let t: Vec<f32> = (0..27).map(|i| PixelSampler::new(0, 1, i, 0).time).collect();
        assert!(t.iter().all(|v| (0.0..1.0).contains(v)));
        let mut bins: Vec<u32> = t.iter().map(|v| (v * 27.0) as u32).collect();
        bins.sort();
        bins.dedup();
        assert!(bins.len() >= 26, "{bins:?}");
    }
}
