//! The node tests in `std::arch` for x86-64: eight boxes in AVX2, sixteen in AVX-512, and
//! eight triangles in AVX2. Each does the portable test's operations (`kernels.rs`) lane for
//! lane, in the same order, so every path gives the same bits.
//!
//! A test is made only with its level's token ([`Avx2`], [`Avx512`]), so wherever one exists
//! the CPU has the features its intrinsics need: that is the proof each `unsafe` block here
//! cites.

use super::kernels::{NodeTest, PairHits, RayLanes, planes};
use super::simd::{Avx2, Avx512};
use super::{Tri4, WideNode};
use crate::math::Vec3A;
use crate::ray::Ray;

/// The 8-wide slab test in AVX2 (`std::arch`): one 256-bit instruction per step. Made only
/// with an [`Avx2`] token.
pub struct Avx2Node8 {
    o: [std::arch::x86_64::__m256; 3],
    dir: [std::arch::x86_64::__m256; 3],
    inv: [std::arch::x86_64::__m256; 3],
    oinv: [std::arch::x86_64::__m256; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl NodeTest<8> for Avx2Node8 {
    type Cpu = Avx2;

    // Not `target_feature` functions themselves: those would stay out-of-line calls in the
    // traversal compiled for AVX2, where these inline.
    #[inline(always)]
    fn new(_: Avx2, ray: &Ray, inv: Vec3A) -> Self {
        use std::arch::x86_64::_mm256_set1_ps as splat;
        let (near, far) = planes(inv);
        let oinv = ray.origin * inv;
        // SAFETY: the token proves that the CPU has AVX2.
        unsafe {
            Avx2Node8 {
                o: [splat(ray.origin.x), splat(ray.origin.y), splat(ray.origin.z)],
                dir: [splat(ray.dir.x), splat(ray.dir.y), splat(ray.dir.z)],
                inv: [splat(inv.x), splat(inv.y), splat(inv.z)],
                oinv: [splat(oinv.x), splat(oinv.y), splat(oinv.z)],
                near,
                far,
            }
        }
    }

    #[inline(always)]
    fn test<const FORWARD: bool>(&self, n: &WideNode<8>, t_min: f32, t_max: f32) -> ([f32; 8], u32) {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX2 and FMA (`self` was made with their token); nodes are 64-byte aligned and each row
        // is 32 bytes, as the aligned loads need; `d` holds eight floats.
        unsafe {
            // The same operations, in the same order, as the portable test: identical results.
            let t = |row: usize, a: usize| {
                _mm256_fmsub_ps(_mm256_load_ps(n.bounds[row].as_ptr()), self.inv[a], self.oinv[a])
            };
            let t_max = _mm256_set1_ps(t_max.min(f32::MAX));
            let mut d = [0.0f32; 8];
            if FORWARD {
                let i = _mm256_castps_si256;
                let near = _mm256_max_epi32(
                    _mm256_max_epi32(i(t(self.near[0], 0)), i(t(self.near[1], 1))),
                    _mm256_max_epi32(i(t(self.near[2], 2)), i(_mm256_set1_ps(t_min + 0.0))),
                );
                let far = _mm256_min_epi32(
                    _mm256_min_epi32(i(t(self.far[0], 0)), i(t(self.far[1], 1))),
                    _mm256_min_epi32(i(t(self.far[2], 2)), i(t_max)),
                );
                let miss = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(near, far))) as u32;
                _mm256_storeu_ps(d.as_mut_ptr(), _mm256_castsi256_ps(near));
                return (d, !miss & 0xff);
            }
            let near = _mm256_max_ps(
                _mm256_max_ps(t(self.near[0], 0), t(self.near[1], 1)),
                _mm256_max_ps(t(self.near[2], 2), _mm256_set1_ps(t_min.max(f32::MIN))),
            );
            let far = _mm256_min_ps(
                _mm256_min_ps(t(self.far[0], 0), t(self.far[1], 1)),
                _mm256_min_ps(t(self.far[2], 2), t_max),
            );
            _mm256_storeu_ps(d.as_mut_ptr(), near);
            (d, _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32)
        }
    }

    /// Möller–Trumbore on eight triangles in 256-bit registers: the operations of
    /// `Tri4::intersect`, lane for lane, so the hits are the same bits.
    #[inline(always)]
    fn intersect_pair(&self, _: &RayLanes, a: &Tri4, b: &Tri4, t_min: f32, t_max: f32) -> PairHits {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX2 (`self` was made with its token); the loads read 16 bytes from rows of 4 floats.
        unsafe {
            let l = |x: &[f32; 4], y: &[f32; 4]| {
                _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(_mm_loadu_ps(x.as_ptr())), _mm_loadu_ps(y.as_ptr()))
            };
            let (mul, sub, add) = (_mm256_mul_ps, _mm256_sub_ps, _mm256_add_ps);
            let [dx, dy, dz] = self.dir;
            let (e1x, e1y, e1z) = (l(&a.e1[0], &b.e1[0]), l(&a.e1[1], &b.e1[1]), l(&a.e1[2], &b.e1[2]));
            let (e2x, e2y, e2z) = (l(&a.e2[0], &b.e2[0]), l(&a.e2[1], &b.e2[1]), l(&a.e2[2], &b.e2[2]));
            let px = sub(mul(dy, e2z), mul(dz, e2y));
            let py = sub(mul(dz, e2x), mul(dx, e2z));
            let pz = sub(mul(dx, e2y), mul(dy, e2x));
            let det = add(add(mul(e1x, px), mul(e1y, py)), mul(e1z, pz));
            let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
            let sx = sub(self.o[0], l(&a.v0[0], &b.v0[0]));
            let sy = sub(self.o[1], l(&a.v0[1], &b.v0[1]));
            let sz = sub(self.o[2], l(&a.v0[2], &b.v0[2]));
            let u = mul(add(add(mul(sx, px), mul(sy, py)), mul(sz, pz)), inv_det);
            let qx = sub(mul(sy, e1z), mul(sz, e1y));
            let qy = sub(mul(sz, e1x), mul(sx, e1z));
            let qz = sub(mul(sx, e1y), mul(sy, e1x));
            let v = mul(add(add(mul(dx, qx), mul(dy, qy)), mul(dz, qz)), inv_det);
            let t = mul(add(add(mul(e2x, qx), mul(e2y, qy)), mul(e2z, qz)), inv_det);
            let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
            let abs_det = _mm256_andnot_ps(_mm256_set1_ps(-0.0), det);
            let and = _mm256_and_ps;
            let ok_det = and(
                _mm256_cmp_ps::<_CMP_GT_OQ>(abs_det, zero),
                _mm256_cmp_ps::<_CMP_LT_OQ>(abs_det, _mm256_set1_ps(f32::INFINITY)),
            );
            let ok_u = and(_mm256_cmp_ps::<_CMP_GE_OQ>(u, zero), _mm256_cmp_ps::<_CMP_LE_OQ>(u, one));
            let ok_v = and(_mm256_cmp_ps::<_CMP_GE_OQ>(v, zero), _mm256_cmp_ps::<_CMP_LE_OQ>(add(u, v), one));
            let ok_t = and(
                _mm256_cmp_ps::<_CMP_GE_OQ>(t, _mm256_set1_ps(t_min)),
                _mm256_cmp_ps::<_CMP_LE_OQ>(t, _mm256_set1_ps(t_max)),
            );
            let mask = _mm256_movemask_ps(and(and(ok_det, ok_u), and(ok_v, ok_t))) as u32;
            let store = |x: __m256| {
                let mut out = [0.0f32; 8];
                _mm256_storeu_ps(out.as_mut_ptr(), x);
                out
            };
            (mask, store(t), store(u), store(v))
        }
    }
}

/// The 16-wide slab test in AVX-512 (`std::arch`): one 512-bit instruction per step, with
/// the 8-wide AVX2 test's triangle test. Made only with an [`Avx512`] token.
pub struct Avx512Node16 {
    /// The leaves' test (and its ray splats).
    pair: Avx2Node8,
    inv: [std::arch::x86_64::__m512; 3],
    oinv: [std::arch::x86_64::__m512; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl NodeTest<16> for Avx512Node16 {
    type Cpu = Avx512;

    #[inline(always)]
    fn new(cpu: Avx512, ray: &Ray, inv: Vec3A) -> Self {
        use std::arch::x86_64::_mm512_set1_ps as splat;
        let (near, far) = planes(inv);
        let oinv = ray.origin * inv;
        // SAFETY: the token proves that the CPU has AVX-512 F.
        unsafe {
            Avx512Node16 {
                pair: <Avx2Node8 as NodeTest<8>>::new(cpu.into(), ray, inv),
                inv: [splat(inv.x), splat(inv.y), splat(inv.z)],
                oinv: [splat(oinv.x), splat(oinv.y), splat(oinv.z)],
                near,
                far,
            }
        }
    }

    #[inline(always)]
    fn test<const FORWARD: bool>(&self, n: &WideNode<16>, t_min: f32, t_max: f32) -> ([f32; 16], u32) {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX-512 F (`self` was made with its token); nodes are 64-byte aligned and each row is
        // 64 bytes, as the aligned loads need; `d` holds sixteen floats.
        unsafe {
            // The portable test's operations, in its order: identical results.
            let t = |row: usize, a: usize| {
                _mm512_fmsub_ps(_mm512_load_ps(n.bounds[row].as_ptr()), self.inv[a], self.oinv[a])
            };
            let t_max = _mm512_set1_ps(t_max.min(f32::MAX));
            let mut d = [0.0f32; 16];
            if FORWARD {
                let i = _mm512_castps_si512;
                let near = _mm512_max_epi32(
                    _mm512_max_epi32(i(t(self.near[0], 0)), i(t(self.near[1], 1))),
                    _mm512_max_epi32(i(t(self.near[2], 2)), i(_mm512_set1_ps(t_min + 0.0))),
                );
                let far = _mm512_min_epi32(
                    _mm512_min_epi32(i(t(self.far[0], 0)), i(t(self.far[1], 1))),
                    _mm512_min_epi32(i(t(self.far[2], 2)), i(t_max)),
                );
                _mm512_storeu_ps(d.as_mut_ptr(), _mm512_castsi512_ps(near));
                return (d, u32::from(_mm512_cmple_epi32_mask(near, far)));
            }
            let near = _mm512_max_ps(
                _mm512_max_ps(t(self.near[0], 0), t(self.near[1], 1)),
                _mm512_max_ps(t(self.near[2], 2), _mm512_set1_ps(t_min.max(f32::MIN))),
            );
            let far = _mm512_min_ps(
                _mm512_min_ps(t(self.far[0], 0), t(self.far[1], 1)),
                _mm512_min_ps(t(self.far[2], 2), t_max),
            );
            _mm512_storeu_ps(d.as_mut_ptr(), near);
            (d, u32::from(_mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, far)))
        }
    }

    #[inline(always)]
    fn intersect_pair(&self, r: &RayLanes, a: &Tri4, b: &Tri4, t_min: f32, t_max: f32) -> PairHits {
        self.pair.intersect_pair(r, a, b, t_min, t_max)
    }
}
