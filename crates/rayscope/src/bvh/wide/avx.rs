//! The node tests in `std::arch` for x86-64: eight boxes in AVX2, sixteen in AVX-512, and
//! eight triangles (the watertight test) in AVX2. Each does the portable test's operations (`kernels.rs`) lane for
//! lane, in the same order, so every path gives the same bits.
//!
//! A test is made only with its level's token ([`Avx2`], [`Avx512`]), so wherever one exists
//! the CPU has the features its intrinsics need: that is the proof each `unsafe` block here
//! cites.

use super::kernels::{NodeTest, PairHits, RayLanes, Row, SlabOrigin, edges_f64_lanes, plane_rows, planes};
use super::simd::{Avx2, Avx512};
use super::{Tri4, WideNode};
use crate::geometry::TriRay;
use crate::math::Vec3A;
use crate::ray::Ray;

/// The 8-wide slab test in AVX2 (`std::arch`): one 256-bit instruction per step. Made only
/// with an [`Avx2`] token.
pub struct Avx2Node8 {
    inv: [std::arch::x86_64::__m256; 3],
    /// `o * inv` per axis, for the entry and the exit planes ([`SlabOrigin`]).
    oinv_near: [std::arch::x86_64::__m256; 3],
    oinv_far: [std::arch::x86_64::__m256; 3],
    near: [Row; 3],
    far: [Row; 3],
}

impl NodeTest<8> for Avx2Node8 {
    type Cpu = Avx2;

    // Not `target_feature` functions themselves: those would stay out-of-line calls in the
    // traversal compiled for AVX2, where these inline.
    #[inline(always)]
    fn new(_: Avx2, ray: &Ray, inv: Vec3A, reach: f32) -> Self {
        use std::arch::x86_64::_mm256_set1_ps;
        let (near, far) = planes(inv);
        let o = SlabOrigin::new(ray.origin, inv, reach);
        // (A macro, not a closure: see `pair_corners_avx2`.)
        macro_rules! splat {
            ($v:expr) => {
                [_mm256_set1_ps($v.x), _mm256_set1_ps($v.y), _mm256_set1_ps($v.z)]
            };
        }
        // SAFETY: the token proves that the CPU has AVX2.
        unsafe { Avx2Node8 { inv: splat!(inv), oinv_near: splat!(o.near), oinv_far: splat!(o.far), near, far } }
    }

    type Planes = [std::arch::x86_64::__m256; 6];

    #[inline(always)]
    fn planes(&self, n: &WideNode<8>) -> Self::Planes {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX2 and FMA (`self` was made with its token); nodes are 64-byte
        // aligned and each row is 32 bytes, as the aligned loads need.
        unsafe { plane_rows(&self.near, &self.far).map(|r| _mm256_load_ps(n.bounds[r as usize].as_ptr())) }
    }

    #[inline(always)]
    fn test_planes<const FORWARD: bool>(&self, p: &Self::Planes, t_min: f32, t_max: f32) -> ([f32; 8], u32) {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX2 and FMA (`self` was made with their token); `d` holds eight floats.
        unsafe {
            // The same operations, in the same order, as the portable test: identical results.
            let t = |plane: usize, a: usize, oinv: &[__m256; 3]| _mm256_fmsub_ps(p[plane], self.inv[a], oinv[a]);
            let t_max = _mm256_set1_ps(t_max.min(f32::MAX));
            let mut d = [0.0f32; 8];
            if FORWARD {
                let i = _mm256_castps_si256;
                let near = _mm256_max_epi32(
                    _mm256_max_epi32(i(t(0, 0, &self.oinv_near)), i(t(1, 1, &self.oinv_near))),
                    _mm256_max_epi32(i(t(2, 2, &self.oinv_near)), i(_mm256_set1_ps(t_min + 0.0))),
                );
                let far = _mm256_min_epi32(
                    _mm256_min_epi32(i(t(3, 0, &self.oinv_far)), i(t(4, 1, &self.oinv_far))),
                    _mm256_min_epi32(i(t(5, 2, &self.oinv_far)), i(t_max)),
                );
                let miss = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(near, far))) as u32;
                _mm256_storeu_ps(d.as_mut_ptr(), _mm256_castsi256_ps(near));
                return (d, !miss & 0xff);
            }
            let near = _mm256_max_ps(
                _mm256_max_ps(t(0, 0, &self.oinv_near), t(1, 1, &self.oinv_near)),
                _mm256_max_ps(t(2, 2, &self.oinv_near), _mm256_set1_ps(t_min.max(f32::MIN))),
            );
            let far = _mm256_min_ps(
                _mm256_min_ps(t(3, 0, &self.oinv_far), t(4, 1, &self.oinv_far)),
                _mm256_min_ps(t(5, 2, &self.oinv_far), t_max),
            );
            _mm256_storeu_ps(d.as_mut_ptr(), near);
            (d, _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32)
        }
    }

    #[inline(always)]
    fn farther_and_tied(&self, near: &[f32; 8], x: f32) -> (u32, u32) {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX2 (`self` was made with its token); `near` holds eight floats.
        unsafe {
            let (v, x) = (_mm256_loadu_ps(near.as_ptr()), _mm256_set1_ps(x));
            let gt = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(v, x)) as u32;
            (gt, _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(v, x)) as u32)
        }
    }

    type Corners = PairCorners256;

    type Rows = PairCorners256;

    #[inline(always)]
    fn pair_rows(cpu: Avx2, axes: [usize; 3], a: &Tri4, b: &Tri4) -> PairCorners256 {
        pair_rows_avx2(cpu, axes, a, b)
    }

    #[inline(always)]
    fn translated(cpu: Avx2, rows: &PairCorners256, origin: [f32; 3]) -> PairCorners256 {
        translated_avx2(cpu, rows, origin)
    }

    #[inline(always)]
    fn intersect_corners(cpu: Avx2, r: &RayLanes, c: &PairCorners256, t_min: f32, t_max: f32) -> PairHits {
        intersect_corners_avx2(cpu, r, c, t_min, t_max)
    }
}

/// The watertight test on eight triangles (two blocks, as [`NodeTest::intersect_pair`] gives
/// them) in 256-bit registers: the operations of `Tri4::intersect`, lane for lane, so the hits
/// are the same bits. The 8- and 16-wide trees' leaves and the shadow groups use it.
#[inline(always)]
pub(super) fn intersect_pair_avx2(cpu: Avx2, r: &RayLanes, a: &Tri4, b: &Tri4, t_min: f32, t_max: f32) -> PairHits {
    intersect_corners_avx2(cpu, r, &pair_corners_avx2(cpu, &r.tri, a, b), t_min, t_max)
}

/// Two blocks' corners for one ray in 256-bit registers ([`super::kernels::Corners4`] of
/// both, block `a` in the low lanes): per vertex, the rows along the ray's x, y and z axes,
/// translated by its origin (or not yet, as [`pair_rows_avx2`] gives them).
#[derive(Clone, Copy)]
pub struct PairCorners256([[std::arch::x86_64::__m256; 3]; 3]);

/// The corners of blocks `a` and `b` for a ray whose triangle set-up is `tri`.
#[inline(always)]
pub(super) fn pair_corners_avx2(cpu: Avx2, tri: &TriRay, a: &Tri4, b: &Tri4) -> PairCorners256 {
    translated_avx2(cpu, &pair_rows_avx2(cpu, tri.axes, a, b), tri.origin)
}

/// The vertex rows of blocks `a` and `b` along `axes` (a ray's [`TriRay::axes`]),
/// untranslated.
#[inline(always)]
pub(super) fn pair_rows_avx2(_: Avx2, [kx, ky, kz]: [usize; 3], a: &Tri4, b: &Tri4) -> PairCorners256 {
    use std::arch::x86_64::*;
    // SAFETY: the CPU has AVX2 (the token says so); the loads read 16 bytes from rows of 4
    // floats.
    unsafe {
        // Macros, not closures: a closure is a function of its own, compiled without the
        // caller's AVX2, and its intrinsics then stay calls (measured: a third more
        // instructions per render).
        macro_rules! load {
            ($x:expr, $y:expr) => {
                _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(_mm_loadu_ps($x.as_ptr())), _mm_loadu_ps($y.as_ptr()))
            };
        }
        // A vertex row of both blocks, permuted (a choice of rows).
        macro_rules! rows {
            ($v:ident) => {
                [load!(a.$v[kx], b.$v[kx]), load!(a.$v[ky], b.$v[ky]), load!(a.$v[kz], b.$v[kz])]
            };
        }
        PairCorners256([rows!(v0), rows!(v1), rows!(v2)])
    }
}

/// `rows` ([`pair_rows_avx2`]) translated by `origin` (a ray's [`TriRay::origin`]).
#[inline(always)]
pub(super) fn translated_avx2(_: Avx2, rows: &PairCorners256, origin: [f32; 3]) -> PairCorners256 {
    use std::arch::x86_64::*;
    // SAFETY: the CPU has AVX2 (the token says so).
    unsafe {
        let o = [_mm256_set1_ps(origin[0]), _mm256_set1_ps(origin[1]), _mm256_set1_ps(origin[2])];
        let [v0, v1, v2] = rows.0;
        macro_rules! translated {
            ($v:expr) => {
                [_mm256_sub_ps($v[0], o[0]), _mm256_sub_ps($v[1], o[1]), _mm256_sub_ps($v[2], o[2])]
            };
        }
        PairCorners256([translated!(v0), translated!(v1), translated!(v2)])
    }
}

/// [`intersect_pair_avx2`] from the pair's corners `c` ([`pair_corners_avx2`] for `r`, or for
/// a ray with the same origin and axes).
#[inline(always)]
pub(super) fn intersect_corners_avx2(_: Avx2, r: &RayLanes, c: &PairCorners256, t_min: f32, t_max: f32) -> PairHits {
    use std::arch::x86_64::*;
    // SAFETY: the CPU has AVX2 and FMA (the token says so); the stores write eight floats into
    // arrays of eight.
    unsafe {
        macro_rules! store {
            ($x:expr) => {{
                let mut out = [0.0f32; 8];
                _mm256_storeu_ps(out.as_mut_ptr(), $x);
                out
            }};
        }
        let tri = &r.tri;
        let (sx, sy, sz) = (_mm256_set1_ps(tri.sx), _mm256_set1_ps(tri.sy), _mm256_set1_ps(tri.sz));
        // A vertex's corners sheared.
        macro_rules! sheared {
            ($v:expr) => {{
                let [x, y, z] = $v;
                (_mm256_fmadd_ps(sx, z, x), _mm256_fmadd_ps(sy, z, y), z)
            }};
        }
        let (x0, y0, z0) = sheared!(c.0[0]);
        let (x1, y1, z1) = sheared!(c.0[1]);
        let (x2, y2, z2) = sheared!(c.0[2]);
        let (mul, sub, add) = (_mm256_mul_ps, _mm256_sub_ps, _mm256_add_ps);
        let mut e0 = sub(mul(x1, y2), mul(y1, x2));
        let mut e1 = sub(mul(x2, y0), mul(y2, x0));
        let mut e2 = sub(mul(x0, y1), mul(y0, x1));
        let zero = _mm256_setzero_ps();
        let (or, and, min, max) = (_mm256_or_ps, _mm256_and_ps, _mm256_min_ps, _mm256_max_ps);
        let (mut lo, mut hi) = (min(min(e0, e1), e2), max(max(e0, e1), e2));
        let flat =
            _mm256_movemask_ps(or(_mm256_cmp_ps::<_CMP_EQ_OQ>(lo, zero), _mm256_cmp_ps::<_CMP_EQ_OQ>(hi, zero))) as u32;
        if flat != 0 {
            let mut e = [store!(e0), store!(e1), store!(e2)];
            edges_f64_lanes(flat, [store!(x0), store!(x1), store!(x2)], [store!(y0), store!(y1), store!(y2)], &mut e);
            (e0, e1, e2) =
                (_mm256_loadu_ps(e[0].as_ptr()), _mm256_loadu_ps(e[1].as_ptr()), _mm256_loadu_ps(e[2].as_ptr()));
            (lo, hi) = (min(min(e0, e1), e2), max(max(e0, e1), e2));
        }
        // No mixed signs (NaN lanes, whichever way min and max take them, fail `ok_det`).
        let same_side = or(_mm256_cmp_ps::<_CMP_GE_OQ>(lo, zero), _mm256_cmp_ps::<_CMP_LE_OQ>(hi, zero));
        // Most triangles a ray meets in a leaf it passes beside: when the edges rule out
        // every lane, the determinant, the distance and the division are not needed (the hits
        // are the same; the lanes of a zero mask are never read).
        if _mm256_movemask_ps(same_side) == 0 {
            return (0, [0.0; 8], [0.0; 8], [0.0; 8]);
        }
        let det = add(add(e0, e1), e2);
        let t_scaled = mul(_mm256_fmadd_ps(e2, z2, _mm256_fmadd_ps(e1, z1, mul(e0, z0))), sz);
        let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
        let t = mul(t_scaled, inv_det);
        let abs_det = _mm256_andnot_ps(_mm256_set1_ps(-0.0), det);
        let ok_det = and(
            _mm256_cmp_ps::<_CMP_GT_OQ>(abs_det, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(abs_det, _mm256_set1_ps(f32::INFINITY)),
        );
        let ok_t = and(
            _mm256_cmp_ps::<_CMP_GE_OQ>(t, _mm256_set1_ps(t_min)),
            _mm256_cmp_ps::<_CMP_LE_OQ>(t, _mm256_set1_ps(t_max)),
        );
        let mask = _mm256_movemask_ps(and(same_side, and(ok_det, ok_t))) as u32;
        (mask, store!(t), store!(mul(e1, inv_det)), store!(mul(e2, inv_det)))
    }
}

/// The 16-wide slab test in AVX-512 (`std::arch`): one 512-bit instruction per step, with
/// the 8-wide AVX2 test's triangle test. Made only with an [`Avx512`] token.
pub struct Avx512Node16 {
    inv: [std::arch::x86_64::__m512; 3],
    /// `o * inv` per axis, for the entry and the exit planes ([`SlabOrigin`]).
    oinv_near: [std::arch::x86_64::__m512; 3],
    oinv_far: [std::arch::x86_64::__m512; 3],
    near: [Row; 3],
    far: [Row; 3],
}

impl NodeTest<16> for Avx512Node16 {
    type Cpu = Avx512;

    #[inline(always)]
    fn new(_: Avx512, ray: &Ray, inv: Vec3A, reach: f32) -> Self {
        use std::arch::x86_64::_mm512_set1_ps;
        let (near, far) = planes(inv);
        let o = SlabOrigin::new(ray.origin, inv, reach);
        // (A macro, not a closure: see `pair_corners_avx2`.)
        macro_rules! splat {
            ($v:expr) => {
                [_mm512_set1_ps($v.x), _mm512_set1_ps($v.y), _mm512_set1_ps($v.z)]
            };
        }
        // SAFETY: the token proves that the CPU has AVX-512 F.
        unsafe { Avx512Node16 { inv: splat!(inv), oinv_near: splat!(o.near), oinv_far: splat!(o.far), near, far } }
    }

    type Planes = [std::arch::x86_64::__m512; 6];

    #[inline(always)]
    fn planes(&self, n: &WideNode<16>) -> Self::Planes {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX-512 F (`self` was made with its token); nodes are 64-byte
        // aligned and each row is 64 bytes, as the aligned loads need.
        unsafe { plane_rows(&self.near, &self.far).map(|r| _mm512_load_ps(n.bounds[r as usize].as_ptr())) }
    }

    #[inline(always)]
    fn test_planes<const FORWARD: bool>(&self, p: &Self::Planes, t_min: f32, t_max: f32) -> ([f32; 16], u32) {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX-512 F (`self` was made with its token); `d` holds sixteen floats.
        unsafe {
            // The portable test's operations, in its order: identical results.
            let t = |plane: usize, a: usize, oinv: &[__m512; 3]| _mm512_fmsub_ps(p[plane], self.inv[a], oinv[a]);
            let t_max = _mm512_set1_ps(t_max.min(f32::MAX));
            let mut d = [0.0f32; 16];
            if FORWARD {
                let i = _mm512_castps_si512;
                let near = _mm512_max_epi32(
                    _mm512_max_epi32(i(t(0, 0, &self.oinv_near)), i(t(1, 1, &self.oinv_near))),
                    _mm512_max_epi32(i(t(2, 2, &self.oinv_near)), i(_mm512_set1_ps(t_min + 0.0))),
                );
                let far = _mm512_min_epi32(
                    _mm512_min_epi32(i(t(3, 0, &self.oinv_far)), i(t(4, 1, &self.oinv_far))),
                    _mm512_min_epi32(i(t(5, 2, &self.oinv_far)), i(t_max)),
                );
                _mm512_storeu_ps(d.as_mut_ptr(), _mm512_castsi512_ps(near));
                return (d, u32::from(_mm512_cmple_epi32_mask(near, far)));
            }
            let near = _mm512_max_ps(
                _mm512_max_ps(t(0, 0, &self.oinv_near), t(1, 1, &self.oinv_near)),
                _mm512_max_ps(t(2, 2, &self.oinv_near), _mm512_set1_ps(t_min.max(f32::MIN))),
            );
            let far = _mm512_min_ps(
                _mm512_min_ps(t(3, 0, &self.oinv_far), t(4, 1, &self.oinv_far)),
                _mm512_min_ps(t(5, 2, &self.oinv_far), t_max),
            );
            _mm512_storeu_ps(d.as_mut_ptr(), near);
            (d, u32::from(_mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, far)))
        }
    }

    #[inline(always)]
    fn farther_and_tied(&self, near: &[f32; 16], x: f32) -> (u32, u32) {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX-512 F (`self` was made with its token); `near` holds sixteen floats.
        unsafe {
            let (v, x) = (_mm512_loadu_ps(near.as_ptr()), _mm512_set1_ps(x));
            (u32::from(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(v, x)), u32::from(_mm512_cmp_ps_mask::<_CMP_EQ_OQ>(v, x)))
        }
    }

    type Corners = PairCorners256;

    type Rows = PairCorners256;

    #[inline(always)]
    fn pair_rows(cpu: Avx512, axes: [usize; 3], a: &Tri4, b: &Tri4) -> PairCorners256 {
        pair_rows_avx2(cpu.into(), axes, a, b)
    }

    #[inline(always)]
    fn translated(cpu: Avx512, rows: &PairCorners256, origin: [f32; 3]) -> PairCorners256 {
        translated_avx2(cpu.into(), rows, origin)
    }

    #[inline(always)]
    fn intersect_corners(cpu: Avx512, r: &RayLanes, c: &PairCorners256, t_min: f32, t_max: f32) -> PairHits {
        intersect_corners_avx2(cpu.into(), r, c, t_min, t_max)
    }
}
