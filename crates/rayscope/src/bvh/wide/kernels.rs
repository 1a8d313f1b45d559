//! The SIMD kernels: a ray's slab test against a node's `W` boxes at once ([`NodeTest`]) and
//! the packed triangle test, on the portable `wide` vectors, and which test each width uses
//! at each [`super::SimdLevel`] ([`NodeWidth`]). The `std::arch` tests for x86-64 are in `avx.rs`.
//!
//! None of this is the crate's API. The tests are declared `pub` only because [`NodeWidth`]
//! names them and the wide tree's public methods are bounded by it; this module is private,
//! and only [`Lanes`] and [`NodeWidth`] are re-exported, hidden, for code generic over the
//! width. A test is made with the token of the CPU features it is compiled for
//! ([`NodeTest::Cpu`]), so that its methods are safe to call.
//!
//! # The slab test
//!
//! Every box test of the wide trees (single rays, packets' leaves, any-hit) computes the same
//! bits, on every instruction set, so that hits never depend on the code path:
//! - the distance to a plane `p` along axis `a` is `p * inv[a] - o[a] * inv[a]` with one
//!   rounding (a fused multiply-subtract; `o[a] * inv[a]` is rounded once per ray). Against
//!   `(p - o[a]) * inv[a]` it takes one instruction where that takes two, on the chain of
//!   dependent operations that each node visit waits for.
//!   [`safe_inv_dir`](crate::geometry::aabb::safe_inv_dir) makes the inverse of a zero
//!   direction component a power of two, so that for a ray parallel to a slab `o[a] * inv[a]`
//!   is exact and so is the sign of every distance;
//! - when the ray's interval starts at or after zero (every ray the renderer makes), the
//!   entry distance is the maximum of the three entry planes' distances and the interval
//!   start, the exit distance the minimum of the exit planes' and the interval end, and the
//!   box is hit when entry <= exit, all compared as the floats' bit patterns read as signed
//!   integers. For non-negative floats that order is the float order, and a negative exit
//!   (a box behind the ray) reads as negative and is rejected; integer max, min and compare
//!   take one cycle where the float ones take three or four. Lines (intervals starting below
//!   zero) are tested with float max, min and compare.

use wide::{f32x4, f32x8, f32x16, i32x4, i32x8, i32x16};

#[cfg(target_arch = "x86_64")]
use super::avx::{Avx2Node8, Avx512Node16};
use super::simd::{Avx2, Avx512, Baseline};
use super::{Tri4, WideNode};
use crate::geometry::TriRay;
use crate::geometry::triangle::edges_f64;
use crate::math::Vec3A;
use crate::ray::Ray;

/// The ray's data for the packed triangle test, computed once per ray: its watertight set-up
/// ([`TriRay`]), which each kernel broadcasts from (the portable one's splats are hoisted out
/// of its loops; the AVX2 one's `vbroadcastss` reads memory).
pub struct RayLanes {
    pub(super) tri: TriRay,
}

impl RayLanes {
    #[inline(always)]
    pub(super) fn new(ray: &Ray) -> RayLanes {
        RayLanes { tri: TriRay::new(ray) }
    }

    /// [`RayLanes::new`] from the ray's safe inverse direction `inv`, without a division
    /// ([`TriRay::with_inv`]).
    #[inline(always)]
    pub(super) fn with_inv(ray: &Ray, inv: Vec3A) -> RayLanes {
        RayLanes { tri: TriRay::with_inv(ray, inv) }
    }
}

/// The packed tests' cold path: lanes `mask` had an edge function of exactly 0, so their three
/// are recomputed in double precision from the sheared corners `x`, `y` (by vertex, then
/// lane), as the scalar test does ([`edges_f64`]).
#[cold]
#[inline(never)]
pub(super) fn edges_f64_lanes<const N: usize>(
    mut mask: u32,
    x: [[f32; N]; 3],
    y: [[f32; N]; 3],
    e: &mut [[f32; N]; 3],
) {
    while mask != 0 {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let exact = edges_f64(x.map(|v| v[lane]), y.map(|v| v[lane]));
        for k in 0..3 {
            e[k][lane] = exact[k];
        }
    }
}

/// A row of [`WideNode::bounds`]: the children's lower x, y, z, then upper x, y, z planes. A
/// type of six values rather than a `usize`, so that indexing the six rows needs no bounds
/// check: a packet's rays keep their rows in memory, and each node test of each ray reloaded
/// and checked all six.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Row {
    /// Lower x.
    MinX,
    /// Lower y.
    MinY,
    /// Lower z.
    MinZ,
    /// Upper x.
    MaxX,
    /// Upper y.
    MaxY,
    /// Upper z.
    MaxZ,
}

impl Row {
    /// The row at index `i` (below 6).
    const fn at(i: usize) -> Row {
        match i {
            0 => Row::MinX,
            1 => Row::MinY,
            2 => Row::MinZ,
            3 => Row::MaxX,
            4 => Row::MaxY,
            _ => Row::MaxZ,
        }
    }
}

/// For each axis, the row of [`WideNode::bounds`] the ray enters a box by and the one it
/// leaves by: the lower plane when the (safe) inverse direction is positive. Since
/// `(lo - o) * inv <= (hi - o) * inv` for positive `inv` in rounded arithmetic too, this gives
/// exactly the scalar test's `min`/`max` of the two plane distances with half the work.
#[inline(always)]
pub(super) fn planes(inv: Vec3A) -> ([Row; 3], [Row; 3]) {
    // By the mask of negative components (one compare for the three): a table lookup.
    const PLANES: [([Row; 3], [Row; 3]); 8] = {
        let mut t = [([Row::MinX; 3], [Row::MinX; 3]); 8];
        let mut m = 0;
        while m < 8 {
            let (nx, ny, nz) = (m & 1, m >> 1 & 1, m >> 2);
            t[m] = (
                [Row::at(3 * nx), Row::at(1 + 3 * ny), Row::at(2 + 3 * nz)],
                [Row::at(3 - 3 * nx), Row::at(4 - 3 * ny), Row::at(5 - 3 * nz)],
            );
            m += 1;
        }
        t
    };
    PLANES[inv.cmplt(Vec3A::ZERO).bitmask() as usize]
}

/// The rows of [`NodeTest::Planes`]: the entry planes' `near`, then the exit planes' `far`.
#[inline(always)]
pub(super) fn plane_rows(near: &[Row; 3], far: &[Row; 3]) -> [Row; 6] {
    [near[0], near[1], near[2], far[0], far[1], far[2]]
}

/// Bound on the slab test's rounding, relative to `(|o| + reach) * |inv|` per axis (see
/// [`SlabOrigin`]): four times the unit roundoff 2^-24, where the analysis needs three.
pub(super) const SLAB_ROUNDING: f32 = 1.0 / (1 << 22) as f32;

/// Per axis, the ray's `o * inv` (rounded once) as the slab test subtracts it from the planes
/// a ray enters boxes by (`near`) and from those it leaves by (`far`): moved apart by a bound
/// on the test's rounding, so that the test is conservative and a ray through a box's edge or
/// corner (as a ray through a mesh's vertex is, at every box around the vertex) never misses
/// it. The computed distance to plane `p` is within `(2 |p| + 3 |o|) |inv| 2^-24` of the exact
/// one (the rounding of `inv`, of `o * inv` and of the fused result); with every plane within
/// `reach` of zero, `(|o| + reach) |inv| 2^-22` covers it. Without this, rays aimed at the
/// vertices of a closed sphere escaped through the boxes, not through the triangle test.
#[derive(Clone, Copy, Debug)]
pub(super) struct SlabOrigin {
    /// `o * inv` plus the bound: entry distances come out no later than exact.
    pub(super) near: Vec3A,
    /// `o * inv` minus the bound: exit distances come out no earlier than exact.
    pub(super) far: Vec3A,
}

impl SlabOrigin {
    #[inline(always)]
    pub(super) fn new(origin: Vec3A, inv: Vec3A, reach: f32) -> SlabOrigin {
        let oinv = origin * inv;
        // Finite, so that an infinite `o * inv` stays infinite rather than turning NaN.
        let pad = ((origin.abs() + Vec3A::splat(reach)) * inv.abs() * SLAB_ROUNDING).min(Vec3A::splat(f32::MAX));
        SlabOrigin { near: oinv + pad, far: oinv - pad }
    }
}

/// A ray prepared for the slab test of one node's `W` boxes at once. Only [`NodeTest::new`]
/// makes one, with the token of the CPU features the test is compiled for: where a test
/// exists, the CPU has them.
pub trait NodeTest<const W: usize>: Sized {
    /// The token that proves the CPU has the test's features ([`Baseline`]: none).
    type Cpu: Copy;

    /// Prepare `ray` with its safe inverse direction `inv`, on the CPU `cpu` vouches for, for
    /// a tree whose boxes lie within `reach` of the origin on every axis ([`SlabOrigin`]).
    fn new(cpu: Self::Cpu, ray: &Ray, inv: Vec3A, reach: f32) -> Self;

    /// Entry distances of the node's `W` child boxes and the mask of those hit within
    /// `[t_min, t_max]`, by the slab test of the module documentation. `FORWARD` says that
    /// `t_min >= 0` (distances then compare in integer order); the traversals choose it once
    /// per ray, as a branch per node measured 8% slower.
    #[inline(always)]
    fn test<const FORWARD: bool>(&self, n: &WideNode<W>, t_min: f32, t_max: f32) -> ([f32; W], u32) {
        self.test_planes::<FORWARD>(&self.planes(n), t_min, t_max)
    }

    /// A node's six rows of planes as this ray's test takes them: the three its direction
    /// enters boxes by, then the three it leaves by, in the test's registers. Rays whose
    /// directions have the same signs share them, so a packet of such rays loads a node's
    /// planes once for all of them ([`NodeTest::test_planes`]).
    type Planes: Copy;

    /// `n`'s planes in this ray's order (see [`NodeTest::Planes`]).
    fn planes(&self, n: &WideNode<W>) -> Self::Planes;

    /// [`NodeTest::test`] of the node whose planes `p` are, loaded by [`NodeTest::planes`] of
    /// this ray or of one whose direction has the same signs: the same results, bit for bit.
    fn test_planes<const FORWARD: bool>(&self, p: &Self::Planes, t_min: f32, t_max: f32) -> ([f32; W], u32);

    /// The lanes of `near` (entry distances from [`NodeTest::test`]) greater than `x`, and
    /// those equal to it, as bit masks (a NaN lane is neither): the traversal's ordering of a
    /// node's hit children by rank.
    #[inline(always)]
    fn farther_and_tied(&self, near: &[f32; W], x: f32) -> (u32, u32) {
        near.iter()
            .enumerate()
            .fold((0, 0), |(gt, eq), (j, &n)| (gt | u32::from(n > x) << j, eq | u32::from(n == x) << j))
    }

    /// Two packed blocks' corners as the triangle test of ray `r` starts from them
    /// ([`Corners4`] of each, in the test's registers): what rays with the same origin and
    /// axes share.
    type Corners: Copy;

    /// The corners of blocks `a` and `b` for ray `r` (see [`NodeTest::Corners`]).
    #[inline(always)]
    fn pair_corners(cpu: Self::Cpu, r: &RayLanes, a: &Tri4, b: &Tri4) -> Self::Corners {
        Self::translated(cpu, &Self::pair_rows(cpu, r.tri.axes, a, b), r.tri.origin)
    }

    /// Two packed blocks' vertex rows along a ray's axes ([`TriRay::axes`]), not yet
    /// translated by its origin: what rays with the same axes share whatever their origins
    /// (shadow rays from neighbouring points), each then translating them by its own.
    type Rows: Copy;

    /// The rows of blocks `a` and `b` along `axes` (see [`NodeTest::Rows`]).
    fn pair_rows(cpu: Self::Cpu, axes: [usize; 3], a: &Tri4, b: &Tri4) -> Self::Rows;

    /// The corners `rows` make for a ray whose origin along its axes is `origin`
    /// ([`TriRay::origin`]): [`NodeTest::pair_corners`]'s, bit for bit.
    fn translated(cpu: Self::Cpu, rows: &Self::Rows, origin: [f32; 3]) -> Self::Corners;

    /// [`NodeTest::intersect_pair`] from the pair's corners `c`, made for `r` or for a ray
    /// with the same origin and axes ([`TriRay::origin`], [`TriRay::axes`]): the same bits.
    fn intersect_corners(cpu: Self::Cpu, r: &RayLanes, c: &Self::Corners, t_min: f32, t_max: f32) -> PairHits;

    /// Two packed blocks at once, as the packed 4-wide test (`Tri4::intersect`) gives them:
    /// lanes 0..4 are `a`'s, 4..8 are `b`'s. Both are tested against `[t_min, t_max]`. It
    /// needs the CPU's token and the ray's triangle set-up only, not a node test: a packet's
    /// rays reach leaves without making one.
    #[inline(always)]
    fn intersect_pair(cpu: Self::Cpu, r: &RayLanes, a: &Tri4, b: &Tri4, t_min: f32, t_max: f32) -> PairHits {
        Self::intersect_corners(cpu, r, &Self::pair_corners(cpu, r, a, b), t_min, t_max)
    }
}

/// A block's corners as the watertight test starts from them for one ray: per vertex, the
/// rows along the ray's x, y and z axes (its permutation, [`TriRay::axes`]), translated by its
/// origin. Rays with the same origin and axes (a packet's camera rays entering one leaf) share
/// them, and each ray's test goes on from there with its own shear.
pub(super) type Corners4 = [[f32x4; 3]; 3];

/// The lanes hit and their `t`, `u`, `v`, for eight triangles.
pub type PairHits = (u32, [f32; 8], [f32; 8], [f32; 8]);

/// Whether the `wide` vectors fuse `mul_add` and `mul_sub` themselves: where the crate is
/// compiled for FMA (or NEON). Elsewhere [`fused_mul_add`] (and [`fused_mul_sub`]) goes through
/// `f32::mul_add` lane by lane: an instruction in code compiled for FMA (the AVX2 and AVX-512
/// traversals, which call the portable tests for the widths they have no `std::arch` test
/// of), else libm's exact `fmaf` (the baseline traversal is slower, never different).
const WIDE_FUSES: bool = cfg!(any(target_feature = "fma", all(target_arch = "aarch64", target_feature = "neon")));

/// `a * b - c` with one rounding, lane by lane: the AVX2 test's `vfmsub`, bit for bit (the
/// negation is exact, and folded into the fused instruction).
#[inline(always)]
pub(super) fn fused_mul_sub<const N: usize, V>(a: V, b: V, c: V) -> V
where
    V: Copy + FloatLanes<N> + std::ops::Neg<Output = V>,
{
    fused_mul_add(a, b, -c)
}

/// `a * b + c` with one rounding, lane by lane: `f32::mul_add` and the AVX2 test's `vfmadd`,
/// bit for bit (see [`WIDE_FUSES`]).
#[inline(always)]
pub(super) fn fused_mul_add<const N: usize, V>(a: V, b: V, c: V) -> V
where
    V: Copy + FloatLanes<N>,
{
    if WIDE_FUSES {
        a.mul_add_fused(b, c)
    } else {
        let (a, b, c) = (a.lanes(), b.lanes(), c.lanes());
        V::from_lanes(std::array::from_fn(|i| a[i].mul_add(b[i], c[i])))
    }
}

/// The `wide` vector types the portable tests use, as arrays of lanes.
pub(super) trait FloatLanes<const N: usize> {
    /// `self * b + c`, fused where `wide` fuses it.
    fn mul_add_fused(self, b: Self, c: Self) -> Self;
    /// The lanes.
    fn lanes(self) -> [f32; N];
    /// From lanes.
    fn from_lanes(l: [f32; N]) -> Self;
}

macro_rules! lanes_impl {
    ($v:ty, $n:literal) => {
        impl FloatLanes<$n> for $v {
            #[inline(always)]
            fn mul_add_fused(self, b: Self, c: Self) -> Self {
                self.mul_add(b, c)
            }
            #[inline(always)]
            fn lanes(self) -> [f32; $n] {
                self.to_array()
            }
            #[inline(always)]
            fn from_lanes(l: [f32; $n]) -> Self {
                <$v>::new(l)
            }
        }
    };
}

lanes_impl!(f32x4, 4);
lanes_impl!(f32x8, 8);
lanes_impl!(f32x16, 16);

/// The slab test's last steps (see the module documentation) on the portable vectors, lane
/// by lane: from each lane's distances to the planes it enters by (`near`) and leaves by
/// (`far`) and its interval, its entry distance and whether it hits. The portable node tests
/// (a ray against `W` boxes) and the packets' leaf test (eight rays against one box) share it.
pub(super) trait Slab: Sized {
    /// Intervals starting at or after zero (`t_min` with -0 made +0): integer order.
    fn forward(near: [Self; 3], far: [Self; 3], t_min: Self, t_max: Self) -> (Self, u32);
    /// Any interval (lines): float order.
    fn lines(near: [Self; 3], far: [Self; 3], t_min: Self, t_max: Self) -> (Self, u32);
}

macro_rules! slab_impl {
    ($v:ty, $i:ty, $w:literal) => {
        impl Slab for $v {
            #[inline(always)]
            fn forward([n0, n1, n2]: [Self; 3], [f0, f1, f2]: [Self; 3], t_min: Self, t_max: Self) -> (Self, u32) {
                let i = |v: $v| -> $i { wide::bytemuck::cast(v) };
                let near = i(n0).max(i(n1)).max(i(n2).max(i(t_min)));
                let far = i(f0).min(i(f1)).min(i(f2).min(i(t_max)));
                let miss = near.simd_gt(far).to_bitmask() as u32;
                (wide::bytemuck::cast(near), !miss & ((1 << $w) - 1))
            }

            #[inline(always)]
            fn lines([n0, n1, n2]: [Self; 3], [f0, f1, f2]: [Self; 3], t_min: Self, t_max: Self) -> (Self, u32) {
                let near = n0.fast_max(n1).fast_max(n2.fast_max(t_min));
                let far = f0.fast_min(f1).fast_min(f2.fast_min(t_max));
                (near, near.simd_le(far).to_bitmask())
            }
        }
    };
}

slab_impl!(f32x4, i32x4, 4);
slab_impl!(f32x8, i32x8, 8);
slab_impl!(f32x16, i32x16, 16);

macro_rules! portable_node_test {
    ($name:ident, $w:literal, $v:ty) => {
        /// The slab test on the portable `wide` vectors.
        pub struct $name {
            inv: [$v; 3],
            /// `o * inv` per axis, for the entry and the exit planes ([`SlabOrigin`]).
            oinv_near: [$v; 3],
            oinv_far: [$v; 3],
            near: [Row; 3],
            far: [Row; 3],
        }

        impl NodeTest<$w> for $name {
            type Cpu = Baseline;

            #[inline(always)]
            fn new(_: Baseline, ray: &Ray, inv: Vec3A, reach: f32) -> Self {
                let (near, far) = planes(inv);
                let o = SlabOrigin::new(ray.origin, inv, reach);
                let splat = |v: Vec3A| [<$v>::splat(v.x), <$v>::splat(v.y), <$v>::splat(v.z)];
                $name { inv: splat(inv), oinv_near: splat(o.near), oinv_far: splat(o.far), near, far }
            }

            type Corners = [Corners4; 2];

            type Rows = [Corners4; 2];

            #[inline(always)]
            fn pair_rows(_: Baseline, axes: [usize; 3], a: &Tri4, b: &Tri4) -> [Corners4; 2] {
                [a.rows(axes), b.rows(axes)]
            }

            #[inline(always)]
            fn translated(_: Baseline, rows: &[Corners4; 2], origin: [f32; 3]) -> [Corners4; 2] {
                rows.map(|r| Tri4::translated(&r, origin))
            }

            #[inline(always)]
            fn intersect_corners(_: Baseline, r: &RayLanes, c: &[Corners4; 2], t_min: f32, t_max: f32) -> PairHits {
                let (ma, ta, ua, va) = Tri4::intersect_corners(&c[0], r, t_min, t_max);
                let (mb, tb, ub, vb) = Tri4::intersect_corners(&c[1], r, t_min, t_max);
                let cat = |x: [f32; 4], y: [f32; 4]| [x[0], x[1], x[2], x[3], y[0], y[1], y[2], y[3]];
                (ma | mb << 4, cat(ta, tb), cat(ua, ub), cat(va, vb))
            }

            type Planes = [$v; 6];

            #[inline(always)]
            fn planes(&self, n: &WideNode<$w>) -> [$v; 6] {
                plane_rows(&self.near, &self.far).map(|r| <$v>::new(n.bounds[r as usize]))
            }

            #[inline(always)]
            fn test_planes<const FORWARD: bool>(&self, p: &[$v; 6], t_min: f32, t_max: f32) -> ([f32; $w], u32) {
                let t = |plane: usize, a: usize, oinv: &[$v; 3]| fused_mul_sub(p[plane], self.inv[a], oinv[a]);
                let (on, of) = (&self.oinv_near, &self.oinv_far);
                let near = [t(0, 0, on), t(1, 1, on), t(2, 2, on)];
                let far = [t(3, 0, of), t(4, 1, of), t(5, 2, of)];
                // Finite ends keep empty slots (boxes at +inf) out, whatever the direction.
                let t_max = <$v>::splat(t_max.min(f32::MAX));
                let (near, mask) = if FORWARD {
                    // `+ 0.0` turns -0 into +0.
                    <$v>::forward(near, far, <$v>::splat(t_min + 0.0), t_max)
                } else {
                    <$v>::lines(near, far, <$v>::splat(t_min.max(f32::MIN)), t_max)
                };
                (near.to_array(), mask)
            }
        }
    };
}

portable_node_test!(Portable4, 4, f32x4);
portable_node_test!(Portable8, 8, f32x8);
portable_node_test!(Portable16, 16, f32x16);

impl Tri4 {
    /// The watertight test on four triangles at once, with exactly the scalar test's
    /// arithmetic ([`Triangle::intersect_prepared`](crate::geometry::Triangle::intersect_prepared)),
    /// so hits are bit-identical: returns the lanes hit within `[t_min, t_max]` and their `t`,
    /// `u`, `v`. The permutation is a choice of rows (the block is structure-of-arrays).
    #[inline(always)]
    pub(super) fn intersect(&self, r: &RayLanes, t_min: f32, t_max: f32) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
        Tri4::intersect_corners(&self.corners(&r.tri), r, t_min, t_max)
    }

    /// The block's corners for a ray whose triangle set-up is `tri` ([`Corners4`]).
    #[inline(always)]
    pub(super) fn corners(&self, tri: &TriRay) -> Corners4 {
        Tri4::translated(&self.rows(tri.axes), tri.origin)
    }

    /// The block's vertex rows along `axes` (a ray's [`TriRay::axes`]), untranslated.
    #[inline(always)]
    pub(super) fn rows(&self, [kx, ky, kz]: [usize; 3]) -> Corners4 {
        let l = |a: &[f32; 4]| f32x4::new(*a);
        let rows = |v: &[[f32; 4]; 3]| [l(&v[kx]), l(&v[ky]), l(&v[kz])];
        [rows(&self.v0), rows(&self.v1), rows(&self.v2)]
    }

    /// Rows ([`Tri4::rows`]) translated by `origin` (a ray's [`TriRay::origin`]): the
    /// block's [`Corners4`] for the ray.
    #[inline(always)]
    pub(super) fn translated(rows: &Corners4, origin: [f32; 3]) -> Corners4 {
        let [ox, oy, oz] = origin.map(f32x4::splat);
        rows.map(|[x, y, z]| [x - ox, y - oy, z - oz])
    }

    /// [`Tri4::intersect`] from the block's corners `c` ([`Tri4::corners`] for `r`, or for a
    /// ray with the same origin and axes).
    #[inline(always)]
    pub(super) fn intersect_corners(
        c: &Corners4,
        r: &RayLanes,
        t_min: f32,
        t_max: f32,
    ) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
        let (sx, sy, sz) = (f32x4::splat(r.tri.sx), f32x4::splat(r.tri.sy), f32x4::splat(r.tri.sz));
        let sheared = |[x, y, z]: [f32x4; 3]| (fused_mul_add(sx, z, x), fused_mul_add(sy, z, y), z);
        let (x0, y0, z0) = sheared(c[0]);
        let (x1, y1, z1) = sheared(c[1]);
        let (x2, y2, z2) = sheared(c[2]);
        let (mut e0, mut e1, mut e2) = (x1 * y2 - y1 * x2, x2 * y0 - y2 * x0, x0 * y1 - y0 * x1);
        let zero = f32x4::ZERO;
        let bounds = |e0: f32x4, e1: f32x4, e2: f32x4| (e0.fast_min(e1).fast_min(e2), e0.fast_max(e1).fast_max(e2));
        let (mut lo, mut hi) = bounds(e0, e1, e2);
        // The scalar test's check for an edge function of exactly 0, on the least and greatest.
        let flat = (lo.simd_eq(zero) | hi.simd_eq(zero)).to_bitmask();
        if flat != 0 {
            let a = |v: [f32x4; 3]| v.map(f32x4::to_array);
            let mut e = a([e0, e1, e2]);
            edges_f64_lanes(flat, a([x0, x1, x2]), a([y0, y1, y2]), &mut e);
            [e0, e1, e2] = e.map(f32x4::new);
            (lo, hi) = bounds(e0, e1, e2);
        }
        // No mixed signs (NaN lanes, whichever way `fast_min` takes them, fail `ok_det`).
        let same_side = lo.simd_ge(zero) | hi.simd_le(zero);
        let det = e0 + e1 + e2;
        let t_scaled = fused_mul_add(e2, z2, fused_mul_add(e1, z1, e0 * z0)) * sz;
        let inv_det = f32x4::ONE / det;
        let t = t_scaled * inv_det;
        // det != 0 and finite: |det| in (0, inf).
        let ok_det = det.abs().simd_gt(zero) & det.abs().simd_lt(f32x4::splat(f32::INFINITY));
        let ok_t = t.simd_ge(f32x4::splat(t_min)) & t.simd_le(f32x4::splat(t_max));
        let mask = (same_side & ok_det & ok_t).to_bitmask();
        (mask, t.to_array(), (e1 * inv_det).to_array(), (e2 * inv_det).to_array())
    }
}

/// The node tests of one width: the portable one and those used at [`super::SimdLevel::Avx2`] and
/// [`super::SimdLevel::Avx512`] (each made with a token the level's own converts to).
pub trait NodeWidth<const W: usize> {
    /// The baseline test.
    type Portable: NodeTest<W, Cpu = Baseline>;
    /// The test compiled for AVX2 (the portable one, where no better exists).
    type Avx2: NodeTest<W, Cpu: From<Avx2>>;
    /// The test compiled for AVX-512 (the AVX2 one, where no better exists).
    type Avx512: NodeTest<W, Cpu: From<Avx512>>;
}

/// Names the node tests of width `W` (see [`NodeWidth`]).
pub struct Lanes<const W: usize>;

impl NodeWidth<4> for Lanes<4> {
    type Portable = Portable4;
    type Avx2 = Portable4;
    type Avx512 = Portable4;
}

impl NodeWidth<8> for Lanes<8> {
    type Portable = Portable8;
    #[cfg(target_arch = "x86_64")]
    type Avx2 = Avx2Node8;
    #[cfg(not(target_arch = "x86_64"))]
    type Avx2 = Portable8;
    type Avx512 = Self::Avx2;
}

impl NodeWidth<16> for Lanes<16> {
    type Portable = Portable16;
    type Avx2 = Portable16;
    #[cfg(target_arch = "x86_64")]
    type Avx512 = Avx512Node16;
    #[cfg(not(target_arch = "x86_64"))]
    type Avx512 = Portable16;
}

pub(super) type PortableTest<const W: usize> = <Lanes<W> as NodeWidth<W>>::Portable;
#[cfg(target_arch = "x86_64")]
pub(super) type Avx2Test<const W: usize> = <Lanes<W> as NodeWidth<W>>::Avx2;
#[cfg(target_arch = "x86_64")]
pub(super) type Avx512Test<const W: usize> = <Lanes<W> as NodeWidth<W>>::Avx512;

#[cfg(test)]
mod tests {
    use proptest::prelude::RngExt;
    use proptest::test_runner::{RngAlgorithm, TestRng};

    use super::{NodeTest, Portable8, Portable16};
    #[cfg(target_arch = "x86_64")]
    use crate::bvh::wide::avx::{Avx2Node8, Avx512Node16};
    use crate::bvh::wide::simd::{Avx2, Avx512, Baseline};
    use crate::bvh::wide::traverse::{far_to_near, sort_far_to_near};
    use crate::bvh::wide::{ChildRef, WideNode};
    use crate::geometry::aabb::safe_inv_dir;
    use crate::math::Vec3A;
    use crate::ray::Ray;

    fn vec3(rng: &mut TestRng, lo: f32, hi: f32) -> Vec3A {
        Vec3A::new(rng.random_range(lo..hi), rng.random_range(lo..hi), rng.random_range(lo..hi))
    }

    /// Uniform on the unit sphere.
    fn dir(rng: &mut TestRng) -> Vec3A {
        loop {
            let v = vec3(rng, -1.0, 1.0);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }

    /// A point of a coarse grid in the plane z = 0.
    fn grid(rng: &mut TestRng) -> Vec3A {
        Vec3A::new(rng.random_range(-2..3) as f32, rng.random_range(-2..3) as f32, 0.0)
    }

    /// A triangle on [`grid`]'s points, its last corner lifted off the plane now and then: rays
    /// through grid points meet its corners and edges.
    fn grid_triangle(rng: &mut TestRng) -> crate::geometry::Triangle {
        let v = [grid(rng), grid(rng), grid(rng)];
        crate::geometry::Triangle::new(v[0], v[1], v[2] + Vec3A::Z * rng.random_range(-1..2) as f32)
    }

    /// A random wide node: boxes around the origin, some slots empty (at +inf, as the collapse
    /// leaves them), some flat, some touching the ray origins' planes.
    fn random_node<const W: usize>(rng: &mut TestRng) -> WideNode<W> {
        let mut n = WideNode { bounds: [[f32::INFINITY; W]; 6], child: [ChildRef::EMPTY; W] };
        for i in 0..W {
            if rng.random::<f32>() < 0.15 {
                continue;
            }
            let (a, b) = (vec3(rng, -1.0, 1.0), vec3(rng, -1.0, 1.0));
            let (mut lo, hi) = (a.min(b), a.max(b));
            if rng.random::<f32>() < 0.1 {
                lo.x = hi.x;
            }
            for axis in 0..3 {
                n.bounds[axis][i] = lo[axis];
                n.bounds[axis + 3][i] = hi[axis];
            }
            n.child[i] = ChildRef::node(i as u32);
        }
        n
    }

    /// The packed triangle tests (portable, and AVX2 where the CPU has it) give the scalar
    /// watertight test's hits bit for bit, on triangles of a coarse grid hit through their
    /// corners and edges by rays along the axes and diagonals (so that edge functions of exactly
    /// 0, and the double-precision fallback, are common), and on any rays.
    #[test]
    fn packed_triangles_match_the_scalar_test() {
        use crate::bvh::wide::kernels::RayLanes;
        use crate::bvh::wide::{EMPTY, Tri4};
        use crate::geometry::Triangle;
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        #[cfg(target_arch = "x86_64")]
        let avx2 = Avx2::new();
        let (mut hits, mut fallback) = (0, 0);
        for _ in 0..20_000 {
            let tris: [Triangle; 8] = std::array::from_fn(|_| grid_triangle(&mut rng));
            let a = Tri4::pack((0..4).map(|i| (i as u32, tris[i])));
            let b = Tri4::pack((4..8).map(|i| (i as u32, tris[i])));
            let origin = if rng.random::<bool>() { grid(&mut rng) + Vec3A::Z * 3.0 } else { vec3(&mut rng, -3.0, 3.0) };
            let d = [Vec3A::NEG_Z, Vec3A::new(1.0, 1.0, -1.0).normalize(), dir(&mut rng)][rng.random_range(0..3usize)];
            let ray = Ray::new(origin, d);
            let lanes = RayLanes::new(&ray);
            let (ma, ta, ua, va) = a.intersect(&lanes, 0.0, 10.0);
            let (mb, tb, ub, vb) = b.intersect(&lanes, 0.0, 10.0);
            let portable = (ma | mb << 4, [ta, tb].concat(), [ua, ub].concat(), [va, vb].concat());
            for (i, tri) in tris.iter().enumerate() {
                let scalar = tri.intersect(&ray, 0.0, 10.0);
                assert_eq!(portable.0 & 1 << i != 0, scalar.is_some(), "lane {i}: {tri:?} {ray:?}");
                if let Some(h) = scalar {
                    hits += 1;
                    let bits = |x: f32| x.to_bits();
                    assert_eq!(
                        (bits(h.t), bits(h.u), bits(h.v)),
                        (bits(portable.1[i]), bits(portable.2[i]), bits(portable.3[i]))
                    );
                }
                let r = crate::geometry::TriRay::new(&ray);
                let e = |p: Vec3A| (p[r.axes[0]] - r.origin[0], p[r.axes[1]] - r.origin[1]);
                fallback += usize::from(tri.vertices().iter().any(|&p| e(p) == (0.0, 0.0)));
            }
            #[cfg(target_arch = "x86_64")]
            if let Some(cpu) = avx2 {
                let (m, t, u, v) = <Avx2Node8 as NodeTest<8>>::intersect_pair(cpu, &lanes, &a, &b, 0.0, 10.0);
                assert_eq!(m, portable.0, "{ray:?}");
                for i in (0..8).filter(|i| m & 1 << i != 0) {
                    assert_eq!(
                        [t[i], u[i], v[i]].map(f32::to_bits),
                        [portable.1[i], portable.2[i], portable.3[i]].map(f32::to_bits)
                    );
                }
            }
            assert_ne!(a.slot, [EMPTY; 4]);
        }
        assert!(hits > 5000 && fallback > 1000, "{hits} hits, {fallback} through a corner");
    }

    /// A pair's corners made for one ray serve every ray of the same origin and axes, as a
    /// packet's leaves use them: each ray's hits from the shared corners are those of its own
    /// pair test, bit for bit (portable, and AVX2 where the CPU has it), on rays from one
    /// origin through a fan of directions around one axis, hitting the grid's corners and
    /// edges.
    #[test]
    fn shared_corners_give_each_rays_own_hits() {
        use crate::bvh::wide::Tri4;
        use crate::bvh::wide::kernels::RayLanes;
        use crate::geometry::Triangle;
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        let (mut shared, mut hits) = (0, 0);
        for _ in 0..5_000 {
            let tris: [Triangle; 8] = std::array::from_fn(|_| grid_triangle(&mut rng));
            let a = Tri4::pack((0..4).map(|i| (i as u32, tris[i])));
            let b = Tri4::pack((4..7).map(|i| (i as u32, tris[i])));
            let origin = grid(&mut rng) + Vec3A::Z * 3.0;
            let towards = |rng: &mut TestRng| {
                let p = if rng.random::<bool>() { grid(rng) } else { vec3(rng, -2.0, 2.0) * Vec3A::new(1.0, 1.0, 0.0) };
                Ray::new(origin, (p - origin).normalize())
            };
            let lead = RayLanes::new(&towards(&mut rng));
            let portable = <Portable8 as NodeTest<8>>::pair_corners(Baseline, &lead, &a, &b);
            #[cfg(target_arch = "x86_64")]
            let avx2 = Avx2::new().map(|cpu| (cpu, <Avx2Node8 as NodeTest<8>>::pair_corners(cpu, &lead, &a, &b)));
            for _ in 0..4 {
                let ray = towards(&mut rng);
                let lanes = RayLanes::new(&ray);
                if lanes.tri.axes != lead.tri.axes {
                    continue;
                }
                shared += 1;
                let bits = |(m, t, u, v): super::PairHits| {
                    let keep = |x: [f32; 8]| {
                        (0..8).map(|i| if m & 1 << i != 0 { x[i].to_bits() } else { 0 }).collect::<Vec<_>>()
                    };
                    (m, keep(t), keep(u), keep(v))
                };
                let own = bits(<Portable8 as NodeTest<8>>::intersect_pair(Baseline, &lanes, &a, &b, 0.0, 10.0));
                let from_shared =
                    bits(<Portable8 as NodeTest<8>>::intersect_corners(Baseline, &lanes, &portable, 0.0, 10.0));
                assert_eq!(own, from_shared, "{ray:?}");
                hits += own.0.count_ones();
                #[cfg(target_arch = "x86_64")]
                if let Some((cpu, corners)) = avx2 {
                    let own = bits(<Avx2Node8 as NodeTest<8>>::intersect_pair(cpu, &lanes, &a, &b, 0.0, 10.0));
                    let from_shared =
                        bits(<Avx2Node8 as NodeTest<8>>::intersect_corners(cpu, &lanes, &corners, 0.0, 10.0));
                    assert_eq!(own, from_shared, "{ray:?}");
                }
            }
        }
        assert!(shared > 10_000 && hits > 5_000, "{shared} rays shared corners, {hits} hits");
    }

    /// The SIMD node tests of each width, where the target has them.
    #[cfg(target_arch = "x86_64")]
    type Simd8 = Avx2Node8;
    #[cfg(not(target_arch = "x86_64"))]
    type Simd8 = Portable8;
    #[cfg(target_arch = "x86_64")]
    type Simd16 = Avx512Node16;
    #[cfg(not(target_arch = "x86_64"))]
    type Simd16 = Portable16;

    /// The slab test gives the same bits on the SIMD paths (AVX2 for 8 children, AVX-512 for
    /// 16, where the CPU has them) as on the portable one (entry distances and hit masks), for
    /// rays (integer order) and lines (float order), rays parallel to an axis and origins on
    /// box planes among them; and it agrees with the scalar box test.
    #[test]
    fn slab_test_is_the_same_on_every_path() {
        // The tokens of the SIMD tests, where the CPU has their features.
        #[cfg(target_arch = "x86_64")]
        let (avx2, avx512) = (Avx2::new(), Avx512::new());
        #[cfg(not(target_arch = "x86_64"))]
        let (avx2, avx512) = (Avx2::new().map(Baseline::from), Avx512::new().map(Baseline::from));
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        let mut hits = 0;
        for _ in 0..3000 {
            hits += slab_case::<8, Portable8, Simd8>(&mut rng, avx2);
            hits += slab_case::<16, Portable16, Simd16>(&mut rng, avx512);
        }
        assert!(hits > 1500, "the random boxes are hit often enough to test something ({hits})");
    }

    /// The traversal's rank placement of a node's hit children (`far_to_near`, by
    /// [`NodeTest::farther_and_tied`] on each path) gives the insertion sort's order, entry for
    /// entry: distances from a few values (ties), some of them NaN, negative, zero of either
    /// sign or infinite, and random sets of hit lanes.
    #[test]
    fn children_are_placed_in_the_insertion_sorts_order() {
        #[cfg(target_arch = "x86_64")]
        let (avx2, avx512) = (Avx2::new(), Avx512::new());
        #[cfg(not(target_arch = "x86_64"))]
        let (avx2, avx512) = (Avx2::new().map(Baseline::from), Avx512::new().map(Baseline::from));
        let ray = Ray::new(Vec3A::ZERO, Vec3A::X);
        let inv = safe_inv_dir(ray.dir);
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        for _ in 0..4000 {
            order_case::<8, _>(&mut rng, &Portable8::new(Baseline, &ray, inv, 1.0));
            order_case::<16, _>(&mut rng, &Portable16::new(Baseline, &ray, inv, 1.0));
            if let Some(cpu) = avx2 {
                order_case::<8, _>(&mut rng, &Simd8::new(cpu, &ray, inv, 1.0));
            }
            if let Some(cpu) = avx512 {
                order_case::<16, _>(&mut rng, &Simd16::new(cpu, &ray, inv, 1.0));
            }
        }
    }

    fn order_case<const W: usize, T: NodeTest<W>>(rng: &mut TestRng, boxes: &T) {
        const VALUES: [f32; 8] = [0.0, -0.0, 0.5, 1.0, 2.0, -1.0, f32::INFINITY, f32::NAN];
        let nan = rng.random::<u32>() % 4 == 0;
        let near: [f32; W] = std::array::from_fn(|_| VALUES[rng.random::<u32>() as usize % if nan { 8 } else { 7 }]);
        let child: [ChildRef; W] = std::array::from_fn(|i| ChildRef::node(i as u32 + 1));
        let hit = (rng.random::<u32>() & ((1u64 << W) - 1) as u32).max(1);
        let mut order = [(ChildRef::ROOT, 0.0f32); W];
        let mut visited = 0u32;
        let k = far_to_near(boxes, &child, &near, hit, &mut order, |c| visited |= 1 << (c.node_index() - 1));
        let mut expected: Vec<(ChildRef, f32)> =
            (0..W).filter(|i| hit & 1 << i != 0).map(|i| (child[i], near[i])).collect();
        sort_far_to_near(&mut expected, |e| e.1);
        assert_eq!(k, expected.len());
        assert_eq!(visited, hit, "every hit child is visited once");
        let bits = |e: &[(ChildRef, f32)]| e.iter().map(|(c, n)| (*c, n.to_bits())).collect::<Vec<_>>();
        assert_eq!(bits(&order[..k]), bits(&expected), "near {near:?}, hit {hit:#x}");
    }

    /// One random node and ray for [`slab_test_is_the_same_on_every_path`]: the portable test
    /// `P` against the SIMD test `S` (made with `simd`, where the CPU has its features) and the
    /// scalar box test. Returns the number of boxes hit.
    fn slab_case<const W: usize, P: NodeTest<W, Cpu = Baseline>, S: NodeTest<W>>(
        rng: &mut TestRng,
        simd: Option<S::Cpu>,
    ) -> usize {
        let node = random_node::<W>(rng);
        let mut ray = Ray::new(vec3(rng, -1.5, 1.5), dir(rng));
        match rng.random::<u64>() % 6 {
            0 => ray.dir = Vec3A::new(0.0, ray.dir.y, ray.dir.z).normalize(),
            1 => ray.origin.x = node.bounds[0][0],
            2 => ray.t.min = -rng.random_range(0.0..2.0),
            3 => ray.t.max = rng.random_range(0.0..1.0),
            _ => {}
        }
        let inv = safe_inv_dir(ray.dir);
        let (t_min, t_max) = (ray.t.min, ray.t.max);
        let portable = {
            let p = P::new(Baseline, &ray, inv, 1.0);
            if t_min >= 0.0 { p.test::<true>(&node, t_min, t_max) } else { p.test::<false>(&node, t_min, t_max) }
        };
        if let Some(cpu) = simd {
            // Here the test is compiled without its features (its intrinsics are calls), in the
            // traversal with them: the same operations either way.
            let fast = {
                let a = S::new(cpu, &ray, inv, 1.0);
                if t_min >= 0.0 { a.test::<true>(&node, t_min, t_max) } else { a.test::<false>(&node, t_min, t_max) }
            };
            assert_eq!(portable.1, fast.1, "{W}-wide masks differ for {ray:?}");
            for i in 0..W {
                if portable.1 & 1 << i != 0 {
                    assert_eq!(
                        portable.0[i].to_bits(),
                        fast.0[i].to_bits(),
                        "{W}-wide entry distances differ for {ray:?}"
                    );
                }
            }
        }
        // Against the scalar test (float arithmetic): the same boxes, up to rays that graze a
        // box within rounding.
        let mut hits = 0;
        for i in 0..W {
            if node.child[i] == ChildRef::EMPTY {
                assert_eq!(portable.1 & 1 << i, 0, "an empty slot was hit by {ray:?}");
                continue;
            }
            let b = node.child_bounds(i);
            let scalar = b.hit_distance(ray.origin, inv, t_min, t_max);
            if portable.1 & 1 << i != 0 {
                hits += 1;
                assert!((portable.0[i] - scalar).abs() <= 1e-4 * (1.0 + scalar.abs()) || scalar == f32::INFINITY);
            }
        }
        hits
    }
}
