//! The packet's set-up: the rays checked and put in the layouts the traversal's tests need
//! ([`Packet`]), portably ray by ray ([`Packet::new`]) or eight lanes at a time in AVX2
//! intrinsics ([`Packet::new_avx2`]), the same packet bit for bit.

use wide::f32x8;

use super::super::kernels::{SLAB_ROUNDING, planes};
#[cfg(target_arch = "x86_64")]
use super::super::simd::Avx2;
use super::super::traverse::ray_is_finite;
use super::{PACKET, Packet, SLACK_ROUNDING, greater, lesser};
use crate::geometry::aabb::safe_inv_dir;
use crate::math::Vec3A;
use crate::ray::Ray;

/// Whether `rays`, whose inverse directions are `invs`, can be traced as one packet: at most
/// [`PACKET`] finite rays with the same origin (bit for bit) and, per axis, the same direction
/// sign.
#[inline(always)]
fn packet_compatible(rays: &[Ray], invs: &[Vec3A; PACKET]) -> bool {
    let Some(first) = rays.first() else { return false };
    if rays.len() > PACKET || !ray_is_finite(first) {
        return false;
    }
    // The same origin bit for bit (so only the first one's needs checking for finiteness);
    // every ray checked without an early exit, which would be a branch per ray.
    let origin = first.origin.to_array().map(f32::to_bits);
    let sign = |inv: &Vec3A| inv.cmplt(Vec3A::ZERO).bitmask();
    let mut ok = true;
    for (r, inv) in rays.iter().zip(invs) {
        ok &= (r.origin.to_array().map(f32::to_bits) == origin)
            & (sign(inv) == sign(&invs[0]))
            & r.dir.is_finite()
            & !r.t.min.is_nan()
            & !r.t.max.is_nan();
    }
    ok
}

impl Packet {
    /// The packet of `rays`, or `None` where they cannot be traced as one: at most [`PACKET`]
    /// finite rays with the same origin (bit for bit) and, per axis, the same direction sign
    /// (see [`packet_compatible`]); `reach` is the tree's (`WideBvh::reach`). Lanes beyond
    /// the packet repeat its last ray. The portable set-up, ray by ray; [`Packet::new_avx2`]
    /// makes the same packet, bit for bit, eight lanes at a time.
    pub(super) fn new(rays: &[Ray], reach: f32) -> Option<Packet> {
        let n = rays.len();
        let last = n.checked_sub(1)?;
        let ray = |lane: usize| &rays[lane.min(last)];
        let invs: [Vec3A; PACKET] = std::array::from_fn(|lane| safe_inv_dir(ray(lane).dir));
        if !packet_compatible(rays, &invs) {
            return None;
        }
        let axis = |a: usize| f32x8::new(invs.map(|v| v[a]));
        let inv = [axis(0), axis(1), axis(2)];
        let o = rays[0].origin;
        // Each ray's `o * inv` for entry and exit planes, as its single-ray test has them:
        // `SlabOrigin::new`'s operations in its order, eight rays at a time (the same bits).
        let slab = |a: usize| {
            let oinv = f32x8::splat(o[a]) * inv[a];
            let pad = ((f32x8::splat(o[a].abs()) + f32x8::splat(reach)) * inv[a].abs() * f32x8::splat(SLAB_ROUNDING))
                .fast_min(f32x8::splat(f32::MAX));
            (oinv + pad, oinv - pad)
        };
        let slab = [slab(0), slab(1), slab(2)];
        let (mut inv_lo, mut inv_hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for v in &invs[..n] {
            for a in 0..3 {
                inv_lo[a] = lesser(inv_lo[a], v[a]);
                inv_hi[a] = greater(inv_hi[a], v[a]);
            }
        }
        // The rows entered and left by are the same for every ray: one sign per axis.
        let (near_row, far_row) = planes(invs[0]);
        let t_min_of = |lane: usize| ray(lane).t.min;
        // Finite, as in the single-ray test: with an end at -inf, a ray going down every axis
        // would meet the empty slots' boxes at +inf.
        let t_min: [f32; PACKET] = std::array::from_fn(|lane| greater(t_min_of(lane), f32::MIN));
        Some(Packet {
            o,
            near_row,
            far_row,
            inv_lo,
            inv_hi,
            inv,
            oinv_near: slab.map(|(near, _)| near),
            oinv_far: slab.map(|(_, far)| far),
            // Twice the worst rounding of `o * inv` (2^-24 relative), with room to spare, and
            // the widest the single-ray tests' entry and exit planes are moved apart (over all
            // lanes: those beyond the packet repeat its last ray).
            slack: std::array::from_fn(|a| {
                let apart = (slab[a].0 - slab[a].1).to_array().into_iter().fold(0.0f32, greater);
                o[a].abs() * inv_lo[a].abs().max(inv_hi[a].abs()) * SLACK_ROUNDING + apart
            }),
            nonneg: (0..PACKET).filter(|&lane| t_min_of(lane) >= 0.0).fold(0, |m, lane| m | 1 << lane),
            t_min_pos: f32x8::new(std::array::from_fn(|lane| t_min_of(lane) + 0.0)),
            t_min: f32x8::new(t_min),
            // Lanes beyond the packet repeat its last ray: the least over all is over the rays.
            // A zero made +0, whichever order the lanes are taken in.
            t_min_lo: t_min.into_iter().fold(f32::INFINITY, lesser) + 0.0,
            t_end: f32x8::new(std::array::from_fn(|lane| ray(lane).t.max)),
            t_far: rays.iter().map(|r| r.t.max).fold(f32::NEG_INFINITY, greater),
            active: (1u32 << n) - 1,
        })
    }

    /// [`Packet::new`] in AVX2 intrinsics, the eight rays' components in the lanes of one
    /// vector per axis: the same operations on each lane, so the same packet bit for bit.
    /// Made ray by ray, the set-up (eight divisions, dozens of lane shuffles, vectors put
    /// together from scalars stored one at a time and read back whole, which store-to-load
    /// forwarding cannot serve) cost a packet that misses the root more than the rest of its
    /// traversal. No closures: one is compiled without its caller's CPU features, and the
    /// intrinsics in it stay calls (the helpers are `#[inline(always)]` functions).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) fn new_avx2(_: Avx2, rays: &[Ray], reach: f32) -> Option<Packet> {
        use avx2_lanes::*;
        use std::arch::x86_64::*;
        let n = rays.len();
        if n == 0 || n > PACKET {
            return None;
        }
        let last = n - 1;
        let ray: [&Ray; PACKET] = std::array::from_fn(|lane| &rays[lane.min(last)]);
        // SAFETY: the token proves that the CPU has AVX2, and its callers are compiled for it.
        unsafe {
            let dir = transpose(ray.map(|r| &r.dir));
            let t_start = lanes(ray.map(|r| r.t.min));
            let t_end = lanes(ray.map(|r| r.t.max));
            let inv = [safe_inv(dir[0]), safe_inv(dir[1]), safe_inv(dir[2])];
            // `packet_compatible`: the same origin bit for bit (the first one finite), finite
            // directions, interval ends that are not NaN, one direction sign per axis.
            let o = rays[0].origin;
            let signs = [negative(inv[0]), negative(inv[1]), negative(inv[2])];
            let ok = o.is_finite()
                & same_origin(rays)
                & (finite(dir[0]) & finite(dir[1]) & finite(dir[2]) == 0xff)
                & (ordered(t_start, t_end) == 0xff)
                & signs.iter().all(|&m| m == 0 || m == 0xff);
            if !ok {
                return None;
            }
            let t_min = _mm256_max_ps(t_start, _mm256_set1_ps(f32::MIN));
            // The packet's eight bounds over its lanes in one reduction, the least as the
            // negated greatest of the negated lanes (exact; no lane is NaN, and no inverse
            // direction is zero, so there is no sign of zero to choose).
            let [hi_x, hi_y, hi_z, lo_x, lo_y, lo_z, t_min_lo, t_far] = greatest_each([
                inv[0],
                inv[1],
                inv[2],
                negated(inv[0]),
                negated(inv[1]),
                negated(inv[2]),
                negated(t_min),
                t_end,
            ]);
            let inv_lo = [-lo_x, -lo_y, -lo_z];
            let inv_hi = [hi_x, hi_y, hi_z];
            let slab = [slab(o.x, inv[0], reach), slab(o.y, inv[1], reach), slab(o.z, inv[2], reach)];
            let slack = [apart(slab[0]), apart(slab[1]), apart(slab[2])];
            let slack =
                std::array::from_fn(|a| o[a].abs() * inv_lo[a].abs().max(inv_hi[a].abs()) * SLACK_ROUNDING + slack[a]);
            let (near_row, far_row) = planes(Vec3A::from_array(inv_lo));
            Some(Packet {
                o,
                near_row,
                far_row,
                inv_lo,
                inv_hi,
                inv: [wide(inv[0]), wide(inv[1]), wide(inv[2])],
                oinv_near: [wide(slab[0].0), wide(slab[1].0), wide(slab[2].0)],
                oinv_far: [wide(slab[0].1), wide(slab[1].1), wide(slab[2].1)],
                slack,
                nonneg: non_negative(t_start),
                t_min_pos: wide(_mm256_add_ps(t_start, _mm256_setzero_ps())),
                t_min: wide(t_min),
                t_min_lo: -t_min_lo + 0.0,
                t_end: wide(t_end),
                t_far,
                active: (1u32 << n) - 1,
            })
        }
    }
}

/// The AVX2 helpers of [`Packet::new_avx2`]: eight lanes, one per ray. Each is
/// `#[inline(always)]` and `unsafe`: its caller proves that the CPU has AVX2 and is compiled
/// for it.
#[cfg(target_arch = "x86_64")]
mod avx2_lanes {
    use std::arch::x86_64::*;

    use wide::f32x8;

    use super::super::super::kernels::SLAB_ROUNDING;
    use super::greater;
    use crate::geometry::aabb::SAFE_INV_MIN;
    use crate::math::Vec3A;
    use crate::ray::Ray;

    /// Eight vectors' `x`, `y` and `z` in three vectors of eight lanes: rows `l` and `l + 4`
    /// share a vector, two unpacks of each pair of those and two of their results leave the
    /// lanes in order.
    #[inline(always)]
    pub(super) unsafe fn transpose(v: [&Vec3A; 8]) -> [__m256; 3] {
        // SAFETY: the caller's CPU has AVX2; each load reads one whole `Vec3A` (16 bytes,
        // 16-byte aligned).
        unsafe {
            let row = |l: usize| v[l].as_ref().as_ptr();
            let pair = |l: usize| (row(l), row(l + 4));
            let [(a0, a4), (a1, a5), (a2, a6), (a3, a7)] = [pair(0), pair(1), pair(2), pair(3)];
            let r04 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(_mm_load_ps(a0)), _mm_load_ps(a4));
            let r15 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(_mm_load_ps(a1)), _mm_load_ps(a5));
            let r26 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(_mm_load_ps(a2)), _mm_load_ps(a6));
            let r37 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(_mm_load_ps(a3)), _mm_load_ps(a7));
            let (xy01, zw01) =
                (_mm256_castps_pd(_mm256_unpacklo_ps(r04, r15)), _mm256_castps_pd(_mm256_unpackhi_ps(r04, r15)));
            let (xy23, zw23) =
                (_mm256_castps_pd(_mm256_unpacklo_ps(r26, r37)), _mm256_castps_pd(_mm256_unpackhi_ps(r26, r37)));
            [
                _mm256_castpd_ps(_mm256_unpacklo_pd(xy01, xy23)),
                _mm256_castpd_ps(_mm256_unpackhi_pd(xy01, xy23)),
                _mm256_castpd_ps(_mm256_unpacklo_pd(zw01, zw23)),
            ]
        }
    }

    /// Eight floats in the lanes of one vector, in order.
    #[inline(always)]
    pub(super) unsafe fn lanes(v: [f32; 8]) -> __m256 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_setr_ps(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]) }
    }

    /// Whether every ray's origin is the first one's, bit for bit.
    #[inline(always)]
    pub(super) unsafe fn same_origin(rays: &[Ray]) -> bool {
        // SAFETY: the caller's CPU has AVX2; each load reads one whole `Vec3A`.
        unsafe {
            let first = _mm_castps_si128(_mm_load_ps(rays[0].origin.as_ref().as_ptr()));
            let mut same = _mm_set1_epi32(-1);
            for r in &rays[1..] {
                let o = _mm_castps_si128(_mm_load_ps(r.origin.as_ref().as_ptr()));
                same = _mm_and_si128(same, _mm_cmpeq_epi32(o, first));
            }
            _mm_movemask_ps(_mm_castsi128_ps(same)) & 0b111 == 0b111
        }
    }

    /// `|v|`, lane by lane.
    #[inline(always)]
    unsafe fn abs(v: __m256) -> __m256 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), v) }
    }

    /// `safe_inv_dir`'s operations on one axis, lane by lane (the same bits).
    #[inline(always)]
    pub(super) unsafe fn safe_inv(d: __m256) -> __m256 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe {
            let mag = _mm256_max_ps(abs(d), _mm256_set1_ps(SAFE_INV_MIN));
            let neg = _mm256_cmp_ps::<_CMP_LT_OQ>(d, _mm256_setzero_ps());
            _mm256_div_ps(_mm256_set1_ps(1.0), _mm256_blendv_ps(mag, _mm256_xor_ps(mag, _mm256_set1_ps(-0.0)), neg))
        }
    }

    /// The lanes below zero, as a bit mask.
    #[inline(always)]
    pub(super) unsafe fn negative(v: __m256) -> i32 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(v, _mm256_setzero_ps())) }
    }

    /// The lanes at or above zero, as a bit mask.
    #[inline(always)]
    pub(super) unsafe fn non_negative(v: __m256) -> u32 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(v, _mm256_setzero_ps())) as u32 }
    }

    /// The finite lanes, as a bit mask.
    #[inline(always)]
    pub(super) unsafe fn finite(v: __m256) -> i32 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(abs(v), _mm256_set1_ps(f32::INFINITY))) }
    }

    /// The lanes where neither `a` nor `b` is NaN, as a bit mask.
    #[inline(always)]
    pub(super) unsafe fn ordered(a: __m256, b: __m256) -> i32 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_ORD_Q>(a, b)) }
    }

    /// `-v`, lane by lane (exact).
    #[inline(always)]
    pub(super) unsafe fn negated(v: __m256) -> __m256 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_xor_ps(v, _mm256_set1_ps(-0.0)) }
    }

    /// The greatest of the lanes (none NaN): halves, quarters, pairs.
    #[inline(always)]
    pub(super) unsafe fn greatest(v: __m256) -> f32 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe {
            let m = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
            let m = _mm_max_ps(m, _mm_movehl_ps(m, m));
            _mm_cvtss_f32(_mm_max_ps(m, _mm_movehdup_ps(m)))
        }
    }

    /// The greatest of each vector's lanes (none NaN), in order: eight reductions at once,
    /// each step halving the lanes of two vectors in one maximum (seven maxima and fourteen
    /// shuffles, where eight [`greatest`]s take 24 of each and eight conversions).
    #[inline(always)]
    pub(super) unsafe fn greatest_each(v: [__m256; 8]) -> [f32; 8] {
        // SAFETY: the caller's CPU has AVX2; the store writes eight floats into eight.
        unsafe {
            let low = quads(pairs(v[0], v[1]), pairs(v[2], v[3]));
            let high = quads(pairs(v[4], v[5]), pairs(v[6], v[7]));
            // The halves' greatest: vectors 0-3 from `low`, 4-7 from `high`.
            let all =
                _mm256_max_ps(_mm256_permute2f128_ps::<0x20>(low, high), _mm256_permute2f128_ps::<0x31>(low, high));
            let mut out = [0.0f32; 8];
            _mm256_storeu_ps(out.as_mut_ptr(), all);
            out
        }
    }

    /// [`greatest_each`]'s first step: per 128-bit half, the greater of `a`'s lanes 0 and 2
    /// and of its lanes 1 and 3 in places 0 and 2, `b`'s in places 1 and 3.
    #[inline(always)]
    unsafe fn pairs(a: __m256, b: __m256) -> __m256 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_max_ps(_mm256_unpacklo_ps(a, b), _mm256_unpackhi_ps(a, b)) }
    }

    /// [`greatest_each`]'s second step, on two [`pairs`]: per 128-bit half, the greatest of
    /// each of the four vectors' four lanes, in their order.
    #[inline(always)]
    unsafe fn quads(a: __m256, b: __m256) -> __m256 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { _mm256_max_ps(_mm256_shuffle_ps::<0b01_00_01_00>(a, b), _mm256_shuffle_ps::<0b11_10_11_10>(a, b)) }
    }

    /// `SlabOrigin::new`'s `o * inv` moved towards the entry and the exit planes on one axis,
    /// lane by lane, as `Packet::new` has them (the same operations in the same order).
    #[inline(always)]
    pub(super) unsafe fn slab(o: f32, inv: __m256, reach: f32) -> (__m256, __m256) {
        // SAFETY: the caller's CPU has AVX2.
        unsafe {
            let oinv = _mm256_mul_ps(_mm256_set1_ps(o), inv);
            let reach = _mm256_add_ps(_mm256_set1_ps(o.abs()), _mm256_set1_ps(reach));
            let pad = _mm256_mul_ps(_mm256_mul_ps(reach, abs(inv)), _mm256_set1_ps(SLAB_ROUNDING));
            let pad = _mm256_min_ps(pad, _mm256_set1_ps(f32::MAX));
            (_mm256_add_ps(oinv, pad), _mm256_sub_ps(oinv, pad))
        }
    }

    /// The widest the entry and exit planes of `slab` are apart over the lanes, at least +0.
    /// `Packet::new`'s fold skips NaN lanes (`inf - inf` where `o * inv` overflows): made +0
    /// here, which the fold from +0 leaves as it is too.
    #[inline(always)]
    pub(super) unsafe fn apart(slab: (__m256, __m256)) -> f32 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe {
            let d = _mm256_sub_ps(slab.0, slab.1);
            greater(0.0, greatest(_mm256_and_ps(d, _mm256_cmp_ps::<_CMP_ORD_Q>(d, d))))
        }
    }

    /// The lanes as the portable vector.
    #[inline(always)]
    pub(super) unsafe fn wide(v: __m256) -> f32x8 {
        // SAFETY: eight floats either way.
        f32x8::new(unsafe { std::mem::transmute::<__m256, [f32; 8]>(v) })
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// Every field of `p`, as bits.
    fn bits(p: &Packet) -> Vec<u32> {
        let mut v: Vec<u32> = [p.o.x, p.o.y, p.o.z].map(f32::to_bits).to_vec();
        v.extend(p.near_row.iter().chain(&p.far_row).map(|&r| r as u32));
        v.extend(p.inv_lo.iter().chain(&p.inv_hi).chain(&p.slack).map(|x| x.to_bits()));
        for x in p.inv.iter().chain(&p.oinv_near).chain(&p.oinv_far).chain([&p.t_min_pos, &p.t_min, &p.t_end]) {
            v.extend(x.to_array().map(f32::to_bits));
        }
        v.extend([p.nonneg, p.t_min_lo.to_bits(), p.t_far.to_bits(), p.active]);
        v
    }

    /// [`Packet::new_avx2`] makes [`Packet::new`]'s packet bit for bit, or refuses the rays
    /// as it does.
    fn check(rays: &[Ray]) {
        let Some(cpu) = Avx2::new() else { return };
        let reach = 3.5;
        // SAFETY: the token proves that the CPU has AVX2.
        let fast = Packet::new_avx2(cpu, rays, reach);
        let portable = Packet::new(rays, reach);
        assert_eq!(fast.as_ref().map(bits), portable.as_ref().map(bits), "{rays:?}");
    }

    /// Finite floats of all magnitudes and both signs, zeros and the extremes among them.
    fn any_finite() -> impl Strategy<Value = f32> {
        prop_oneof![
            -4.0f32..4.0,
            Just(0.0f32),
            Just(-0.0f32),
            Just(f32::MAX),
            Just(-f32::MAX),
            Just(1e-30f32),
            Just(-1e-40f32),
            any::<f32>().prop_filter("finite", |x| x.is_finite()),
        ]
    }

    proptest! {
        /// Packets of one to eight rays from one origin in directions of one sign per axis
        /// (or not, when `flip` breaks it), with intervals that start before, at and after 0.
        #[test]
        fn the_avx2_set_up_makes_the_portable_packet(
            origin in prop::array::uniform3(any_finite()),
            dirs in prop::collection::vec(prop::array::uniform3(any_finite()), 1..=8),
            signs in prop::array::uniform3(any::<bool>()),
            flip in any::<bool>(),
            t_min in prop::collection::vec(prop_oneof![Just(0.0f32), Just(-0.0), -1.0f32..1.0, Just(f32::NEG_INFINITY)], 8),
            t_max in prop::collection::vec(prop_oneof![Just(f32::INFINITY), 0.0f32..10.0], 8),
        ) {
            let origin = Vec3A::from_array(origin);
            let rays: Vec<Ray> = dirs
                .iter()
                .enumerate()
                .map(|(i, d)| {
                    let d = Vec3A::from_array(std::array::from_fn(|a| {
                        let flipped = signs[a] ^ (flip && i == 1 && a == 0);
                        if flipped { -d[a].abs() } else { d[a].abs() }
                    }));
                    Ray { origin, dir: d, t: crate::ray::Interval { min: t_min[i], max: t_max[i] }, time: 0.0 }
                })
                .collect();
            check(&rays);
        }
    }

    /// Rays that cannot go as a packet, and the empty and the overlong packet.
    #[test]
    fn the_avx2_set_up_refuses_what_the_portable_one_refuses() {
        let ray = Ray::new(Vec3A::new(0.5, -1.0, 2.0), Vec3A::new(0.3, 0.4, -0.5));
        check(&[]);
        check(&[ray; 9]);
        check(&[ray; 8]);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for a in 0..3 {
                let mut r = ray;
                r.dir[a] = bad;
                check(&[ray, r]);
                let mut r = ray;
                r.origin[a] = bad;
                check(&[r, r]);
                check(&[ray, r]);
            }
            let mut r = ray;
            r.t.min = bad;
            check(&[ray, ray, r]);
            let mut r = ray;
            r.t.max = bad;
            check(&[r]);
        }
        // Origins equal as numbers but not as bits.
        let mut r = Ray::new(Vec3A::ZERO, ray.dir);
        let mut s = r;
        s.origin.y = -0.0;
        check(&[r, s]);
        // `o * inv` overflowing: infinite slab origins, NaN between them.
        r.origin = Vec3A::new(3e38, -3e38, 1.0);
        r.dir = Vec3A::new(1e-30, -1e-30, 1.0);
        check(&[r, r, r]);
    }
}
