//! Mip pyramids for trilinear texture filtering ([`crate::settings::TextureFilter::Trilinear`]):
//! the texture's own texels are level 0, each further level a box-filtered half of the one
//! below, down to 1x1. A texture builds its pyramid the first time a trilinear lookup asks
//! for it ([`crate::material::Texture::mips`]), so renders with the other filters pay no
//! memory or time for it.
//!
//! Downsampling is area-weighted: texel `(x, y)` of a level of size `w' x h'` is the mean of
//! the rectangle `[x w/w', (x+1) w/w') x [y h/h', (y+1) h/h')` of the level below (`w x h`),
//! partial texels counted by the fraction of them inside. For even sizes that is the plain
//! 2x2 box; odd sizes (`w' = floor(w/2)`) get three-texel footprints with fractional end
//! weights, so every level keeps the mean of the image exactly (up to rounding) whatever its
//! size. Texels are averaged as they are stored: textures are used as linear values (the
//! course's 8-bit `/ 255`; see [`crate::io`]), so the pyramid averages what shading reads.

use crate::math::{Color, Vec2};

/// A grid of texels, row 0 at the top, addressed with wrapping (repeat), as textures are;
/// its texels are colours or, for images of 8-bit values, [`Unorm8`] ones.
#[derive(Clone, Copy, Debug)]
pub struct TexelGrid<'a, T = Color> {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// `width * height` texels, row by row.
    pub texels: &'a [T],
}

/// A texel as a grid stores it, read as a colour.
pub trait Texel: Copy {
    /// Its colour.
    fn color(self) -> Color;
}

impl Texel for Color {
    #[inline(always)]
    fn color(self) -> Color {
        self
    }
}

/// A texel of an image of 8-bit values, read as `value / 255` per channel: bit for bit the
/// colour the image's loader made of it ([`crate::io`]), in 4 bytes where the colour takes
/// 12. A lookup's four texels then share cache lines three times as often: the textured
/// teapot's 128x128 texture is 64 KiB rather than 192.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Unorm8(pub [u8; 4]);

/// `k / 255` for every byte `k`: the loader's `Color / 255.0`, per channel.
static UNORM8: [f32; 256] = {
    let mut t = [0.0; 256];
    let mut k = 0;
    while k < 256 {
        t[k] = k as f32 / 255.0;
        k += 1;
    }
    t
};

impl Unorm8 {
    /// `c` as 8-bit values, if each of its channels is exactly `k / 255` for a byte `k`.
    pub fn exactly(c: Color) -> Option<Unorm8> {
        let byte = |v: f32| {
            let k = (v * 255.0).round();
            ((0.0..=255.0).contains(&k) && UNORM8[k as usize].to_bits() == v.to_bits()).then_some(k as u8)
        };
        Some(Unorm8([byte(c.x)?, byte(c.y)?, byte(c.z)?, 0]))
    }
}

impl Texel for Unorm8 {
    #[inline(always)]
    fn color(self) -> Color {
        let [r, g, b, _] = self.0;
        Color::new(UNORM8[r as usize], UNORM8[g as usize], UNORM8[b as usize])
    }
}

/// `i` wrapped into `0..n` (repeat addressing, as OBJ texture coordinates outside [0, 1]
/// expect). An index already inside, as most are, skips the division, whose latency the
/// texel loads waited on.
#[inline]
fn wrap(i: i64, n: u32) -> usize {
    if (i as u64) < u64::from(n) { i as usize } else { i.rem_euclid(i64::from(n)) as usize }
}

/// The wrapped neighbour after `i`, whose wrapped index is `wrapped`: `wrap(i + 1, n)` with
/// one 64-bit division fewer (a bilinear lookup's four texels then cost two, not eight, which
/// were 2% of the textured teapot's render). A coordinate so large that it saturated to
/// `i64::MAX` keeps the neighbour it had, `i64::MIN`'s.
#[inline]
fn wrap_next(i: i64, wrapped: usize, n: u32) -> usize {
    if i == i64::MAX {
        wrap(i64::MIN, n)
    } else if wrapped + 1 == n as usize {
        0
    } else {
        wrapped + 1
    }
}

/// `x.floor()`, bit for bit, without a call: the baseline x86-64 the library is compiled for
/// has no rounding instruction (SSE4.1's `roundss`), so `f32::floor` is a call into libm, two
/// per bilinear lookup (about 2% of the textured teapot's render). A float of magnitude 2^23
/// or more is an integer already (or infinite, or NaN), and is its own floor; below that the
/// truncation to an integer is exact, and one less where it rounded up (negative
/// non-integers); the sign of a zero is kept (`floor(-0.0)` is `-0.0`).
#[inline(always)]
fn floor(x: f32) -> f32 {
    const INTEGERS: f32 = 8_388_608.0; // 2^23
    if x.abs() < INTEGERS {
        let t = x as i32 as f32;
        if t > x { t - 1.0 } else { t.copysign(x) }
    } else {
        x
    }
}

impl<T: Texel> TexelGrid<'_, T> {
    #[inline]
    fn texel(&self, x: i64, y: i64) -> Color {
        self.at(wrap(x, self.width), wrap(y, self.height))
    }

    /// The texel at wrapped indices `(x, y)`.
    #[inline]
    fn at(&self, x: usize, y: usize) -> Color {
        self.texels[y * self.width as usize + x].color()
    }

    /// Where `uv` (v = 0 at the bottom, the OBJ convention) falls, in texels.
    #[inline]
    fn position(&self, uv: Vec2) -> Vec2 {
        Vec2::new(uv.x * self.width as f32, (1.0 - uv.y) * self.height as f32)
    }

    /// The texel under `uv`.
    #[inline]
    pub fn nearest(&self, uv: Vec2) -> Color {
        let p = self.position(uv);
        self.texel(floor(p.x) as i64, floor(p.y) as i64)
    }

    /// The bilinear blend of the four texel centres around `uv`.
    #[inline]
    pub fn bilinear(&self, uv: Vec2) -> Color {
        let p = self.position(uv);
        let (fx, fy) = (p.x - 0.5, p.y - 0.5);
        let (x0, y0) = (floor(fx), floor(fy));
        let (tx, ty) = (fx - x0, fy - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let (xa, ya) = (wrap(x0, self.width), wrap(y0, self.height));
        let (xb, yb) = (wrap_next(x0, xa, self.width), wrap_next(y0, ya, self.height));
        let top = self.at(xa, ya).lerp(self.at(xb, ya), tx);
        let bottom = self.at(xa, yb).lerp(self.at(xb, yb), tx);
        top.lerp(bottom, ty)
    }

    /// The mean of every texel (in `f64`, for tests and the debugger).
    pub fn mean(&self) -> Color {
        let sum = self
            .texels
            .iter()
            .map(|t| t.color())
            .fold([0.0f64; 3], |s, c| [s[0] + c.x as f64, s[1] + c.y as f64, s[2] + c.z as f64]);
        let n = self.texels.len().max(1) as f64;
        Color::new((sum[0] / n) as f32, (sum[1] / n) as f32, (sum[2] / n) as f32)
    }
}

/// One level above level 0 of a pyramid.
#[derive(Clone, Debug, PartialEq)]
struct Level {
    width: u32,
    height: u32,
    texels: Vec<Color>,
}

/// The levels of a texture's pyramid above level 0 (the texture itself, which the pyramid does
/// not copy): halves down to 1x1.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MipPyramid {
    levels: Vec<Level>,
}

impl MipPyramid {
    /// The pyramid over `base` (level 0).
    pub fn build(base: TexelGrid) -> MipPyramid {
        let mut levels: Vec<Level> = Vec::new();
        let (mut w, mut h) = (base.width, base.height);
        while w > 1 || h > 1 {
            let below =
                levels.last().map_or(base, |l| TexelGrid { width: l.width, height: l.height, texels: &l.texels });
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            levels.push(Level { width: nw, height: nh, texels: downsample(below, nw, nh) });
            (w, h) = (nw, nh);
        }
        MipPyramid { levels }
    }

    /// Levels counting level 0: `1 + floor(log2(max(width, height)))`.
    pub fn level_count(&self) -> usize {
        self.levels.len() + 1
    }

    /// Level `level` (0 is `base`, the texture's own texels; clamped to the top).
    pub fn level<'a>(&'a self, base: TexelGrid<'a>, level: usize) -> TexelGrid<'a> {
        match level.min(self.levels.len()) {
            0 => base,
            l => {
                let l = &self.levels[l - 1];
                TexelGrid { width: l.width, height: l.height, texels: &l.texels }
            }
        }
    }

    /// The trilinear lookup at `uv` for level of detail `lod` (fractional; clamped to the
    /// pyramid's levels): bilinear in the two levels around it, blended linearly.
    pub fn trilinear(&self, base: TexelGrid, uv: Vec2, lod: f32) -> Color {
        let top = self.levels.len() as f32;
        // `max` before `min`: a NaN level of detail reads level 0.
        let lod = lod.max(0.0).min(top);
        let l0 = lod.floor();
        let t = lod - l0;
        let below = self.level(base, l0 as usize).bilinear(uv);
        if t == 0.0 {
            return below;
        }
        below.lerp(self.level(base, l0 as usize + 1).bilinear(uv), t)
    }
}

/// Area weights of a 1-D box downsampling from `from` texels to `to` (`to <= from`): for each
/// output texel, its first input texel and the weights of the inputs it covers (summing to 1).
fn box_weights(from: u32, to: u32) -> Vec<(usize, Vec<f32>)> {
    let r = from as f64 / to as f64;
    (0..to)
        .map(|i| {
            let (a, b) = (i as f64 * r, (i + 1) as f64 * r);
            let first = a.floor() as usize;
            let last = (b.ceil() as usize).min(from as usize);
            let w = (first..last).map(|j| (((j + 1) as f64).min(b) - (j as f64).max(a)) / r).map(|w| w as f32);
            (first, w.collect())
        })
        .collect()
}

/// `src` box-filtered down to `width x height` texels (each at most `src`'s), separably: rows
/// first, then columns.
fn downsample(src: TexelGrid, width: u32, height: u32) -> Vec<Color> {
    let (sw, sh) = (src.width as usize, src.height as usize);
    let (wx, wy) = (box_weights(src.width, width), box_weights(src.height, height));
    let mut rows = vec![Color::ZERO; width as usize * sh];
    for y in 0..sh {
        let line = &src.texels[y * sw..(y + 1) * sw];
        for (x, (first, w)) in wx.iter().enumerate() {
            rows[y * width as usize + x] = w.iter().enumerate().map(|(k, w)| *w * line[first + k]).sum();
        }
    }
    let mut out = vec![Color::ZERO; width as usize * height as usize];
    for (y, (first, w)) in wy.iter().enumerate() {
        for x in 0..width as usize {
            out[y * width as usize + x] =
                w.iter().enumerate().map(|(k, w)| *w * rows[(first + k) * width as usize + x]).sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn grid(width: u32, height: u32, texels: &[Color]) -> TexelGrid<'_> {
        TexelGrid { width, height, texels }
    }

    fn close(a: Color, b: Color, tol: f32) -> bool {
        (a - b).abs().max_element() <= tol
    }

    #[test]
    fn a_checkerboards_levels_are_grey_from_level_one() {
        // 8x8 texels of alternating black and white: every 2x2 box holds two of each.
        let texels: Vec<Color> =
            (0..64).map(|i| if (i % 8 + i / 8) % 2 == 0 { Color::ONE } else { Color::ZERO }).collect();
        let base = grid(8, 8, &texels);
        let p = MipPyramid::build(base);
        assert_eq!(p.level_count(), 4);
        for l in 1..4 {
            let g = p.level(base, l);
            assert_eq!((g.width, g.height), (8 >> l, 8 >> l));
            assert!(g.texels.iter().all(|c| *c == Color::splat(0.5)), "level {l}: {:?}", g.texels);
        }
        // Level 0 is the texture itself; between 0 and 1, the blend.
        let uv = Vec2::new(1.0 / 16.0, 1.0 - 1.0 / 16.0);
        assert_eq!(p.trilinear(base, uv, 0.0), Color::ONE);
        assert_eq!(p.trilinear(base, uv, 0.5), Color::splat(0.75));
        assert_eq!(p.trilinear(base, uv, 99.0), Color::splat(0.5));
        assert_eq!(p.trilinear(base, uv, f32::NAN), Color::ONE);
    }

    #[test]
    fn odd_sizes_reach_one_texel_and_keep_the_mean() {
        let texels: Vec<Color> = (0..5 * 3).map(|i| Color::new(i as f32, (i * i) as f32 * 0.1, 1.0)).collect();
        let base = grid(5, 3, &texels);
        let p = MipPyramid::build(base);
        let sizes: Vec<_> = (0..p.level_count()).map(|l| (p.level(base, l).width, p.level(base, l).height)).collect();
        assert_eq!(sizes, [(5, 3), (2, 1), (1, 1)]);
        let mean = base.mean();
        for l in 1..p.level_count() {
            assert!(close(p.level(base, l).mean(), mean, 1e-4), "level {l}");
        }
    }

    /// The inlined floor is `f32::floor`, bit for bit, over every kind of float.
    #[test]
    fn floor_is_f32_floor() {
        let special = [
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            0.999_999_9,
            -0.999_999_9,
            1.0e-45,
            -1.0e-45,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            16_777_217.0,
            2.0e9,
            -2.0e9,
            3.0e38,
            -3.0e38,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        // (A NaN stays a NaN; lookups never see one: `Texture::sample` returns black first.)
        let same = |x: f32| if x.is_nan() { floor(x).is_nan() } else { floor(x).to_bits() == x.floor().to_bits() };
        for x in special {
            assert!(same(x), "{x}");
        }
        // A sweep over every exponent and sign, and every float near the threshold.
        for bits in (0u32..=u32::MAX).step_by(65_521) {
            assert!(same(f32::from_bits(bits)), "{bits:#x}");
        }
        for bits in 0x4AFF_FF00u32..0x4B00_0100 {
            assert!(same(f32::from_bits(bits)) && same(-f32::from_bits(bits)), "{bits:#x}");
        }
    }

    proptest! {
        /// The wrapped neighbour is `wrap(i + 1)` as the lookup computed it before (with the
        /// saturated `i64::MAX`'s neighbour `i64::MIN`), for any index and size.
        #[test]
        fn the_wrapped_neighbour_is_the_next_index_wrapped(
            i in prop_oneof![any::<i64>(), -100i64..100, Just(i64::MAX), Just(i64::MIN), Just(i64::MAX - 1)],
            n in prop_oneof![1u32..5, any::<u32>().prop_map(|n| n.max(1))],
        ) {
            prop_assert_eq!(wrap_next(i, wrap(i, n), n), wrap(i.wrapping_add(1), n));
        }

        /// The wrap with its shortcut for indices inside is the Euclidean remainder, for any
        /// index and size.
        #[test]
        fn wrap_is_the_euclidean_remainder(
            i in prop_oneof![any::<i64>(), -100i64..100, Just(i64::MAX), Just(i64::MIN), Just(-1i64)],
            n in prop_oneof![1u32..5, any::<u32>().prop_map(|n| n.max(1))],
        ) {
            prop_assert_eq!(wrap(i, n), i.rem_euclid(i64::from(n)) as usize);
        }

        /// Every level of a power-of-two texture has the image's mean, and the top is 1x1.
        #[test]
        fn every_level_keeps_the_mean(log_w in 0u32..6, log_h in 0u32..6, seed in any::<u64>()) {
            let (w, h) = (1u32 << log_w, 1u32 << log_h);
            let mut s = seed | 1;
            let texels: Vec<Color> = (0..w * h)
                .map(|_| {
                    s ^= s << 13;
                    s ^= s >> 7;
                    s ^= s << 17;
                    Color::new((s % 1000) as f32 / 999.0, (s / 1000 % 1000) as f32 / 999.0, 0.5)
                })
                .collect();
            let base = grid(w, h, &texels);
            let p = MipPyramid::build(base);
            prop_assert_eq!(p.level_count() as u32, 1 + log_w.max(log_h));
            let top = p.level(base, p.level_count() - 1);
            prop_assert_eq!((top.width, top.height), (1, 1));
            for l in 0..p.level_count() {
                prop_assert!(close(p.level(base, l).mean(), base.mean(), 1e-5));
            }
        }
    }
}
