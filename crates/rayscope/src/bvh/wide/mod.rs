//! Wide BVHs collapsed from the binary one, for rendering: each node holds its `W` children's
//! boxes as structure-of-arrays, so one SIMD slab test checks them all. Rendering uses the
//! 16-wide tree ([`Bvh16`]) where the CPU has AVX-512, whose nodes are then tested with one
//! 512-bit instruction per step, and the 8-wide tree ([`Bvh8`]) elsewhere: with AVX2, one
//! 256-bit instruction per step, else the portable `wide` vectors (two SSE or NEON halves).
//! The choice is made at run time ([`tree::WideTree`]). The 4-wide tree ([`Bvh4`]) is
//! the same code at half the width, kept to measure one against the other. Wider nodes mean
//! fewer levels, and with them fewer loop iterations, stack entries and dependent loads per
//! ray. The binary BVH stays for the debugger's level view.
//!
//! # The slab test
//!
//! Every box test of the wide trees (single rays, packets' leaves, any-hit) computes the same
//! bits, on every instruction set, so that hits never depend on the code path:
//! - the distance to a plane `p` along axis `a` is `p * inv[a] - o[a] * inv[a]` with one
//!   rounding (a fused multiply-subtract; `o[a] * inv[a]` is rounded once per ray). Against
//!   `(p - o[a]) * inv[a]` it takes one instruction where that takes two, on the chain of
//!   dependent operations that each node visit waits for. [`safe_inv_dir`] makes the inverse
//!   of a zero direction component a power of two, so that for a ray parallel to a slab
//!   `o[a] * inv[a]` is exact and so is the sign of every distance;
//! - when the ray's interval starts at or after zero (every ray the renderer makes), the
//!   entry distance is the maximum of the three entry planes' distances and the interval
//!   start, the exit distance the minimum of the exit planes' and the interval end, and the
//!   box is hit when entry <= exit, all compared as the floats' bit patterns read as signed
//!   integers. For non-negative floats that order is the float order, and a negative exit
//!   (a box behind the ray) reads as negative and is rejected; integer max, min and compare
//!   take one cycle where the float ones take three or four. Lines (intervals starting below
//!   zero) are tested with float max, min and compare.

pub mod collapse;
pub mod packet;
pub mod shadow;
pub mod tree;

pub use packet::PACKET;
pub use shadow::Occluders;
pub use tree::WideTree;

use wide::{f32x4, f32x8, f32x16, i32x4, i32x8, i32x16};

use super::{Bvh, BvhError, BvhHit, NoObserver, Primitives, TraversalObserver};
use crate::geometry::Aabb;
use crate::geometry::aabb::safe_inv_dir;
use crate::geometry::{PrimHit, Triangle};
use crate::math::Vec3A;
use crate::ray::Ray;

/// The instruction set a traversal runs on, chosen at run time so the binary still runs on any
/// x86-64. All give bit-identical hits: the AVX2 variant is the same traversal compiled for
/// AVX2, FMA and BMI, with the 8-wide node and two-block triangle tests written in `std::arch`
/// doing the portable tests' operations lane for lane; the AVX-512 variant adds the 16-wide
/// node test in 512-bit registers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SimdLevel {
    /// The target's baseline (SSE2 on x86-64, NEON on AArch64, scalar elsewhere).
    #[default]
    Portable,
    /// x86-64 with AVX2, FMA, BMI1/2 and LZCNT (x86-64-v3).
    Avx2,
    /// x86-64-v3 and AVX-512 F, VL, BW and DQ (x86-64-v4).
    Avx512,
}

impl SimdLevel {
    /// The best level this CPU supports.
    pub fn detect() -> SimdLevel {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
            && std::arch::is_x86_feature_detected!("popcnt")
        {
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx512bw")
                && std::arch::is_x86_feature_detected!("avx512dq")
            {
                return SimdLevel::Avx512;
            }
            return SimdLevel::Avx2;
        }
        SimdLevel::Portable
    }
}

/// Marks an unused child slot.
pub const EMPTY: u32 = u32::MAX;
/// Set on a child reference that is a leaf.
pub(super) const LEAF_BIT: u32 = 1 << 31;
/// Set, with [`LEAF_BIT`], on a leaf of packed triangles ([`Tri4`] blocks).
pub(super) const PACKED_BIT: u32 = 1 << 30;
/// Bits of a packed leaf reference that hold its first block.
pub(super) const BLOCK_BITS: u32 = 26;
/// Most blocks one packed leaf holds (4 bits of count - 1); larger leaves use ranges.
pub(super) const MAX_BLOCKS: u32 = 16;

/// Rows of [`WideNode::bounds`]: lower x, y, z, then upper x, y, z.
const ROWS: usize = 6;

/// One node: `W` child boxes and `W` child references; 128 bytes (two cache lines) at
/// `W = 4`, 256 bytes (four) at `W = 8`, 448 bytes (seven) at `W = 16`.
///
/// | field | bytes (W = 4 / 8 / 16) | meaning |
/// |---|---|---|
/// | `bounds[0..3]` | 0..48 / 0..96 / 0..192 | lower x, y, z corners of the `W` child boxes, one row per axis |
/// | `bounds[3..6]` | 48..96 / 96..192 / 192..384 | upper x, y, z corners |
/// | `child` | 96..112 / 192..224 / 384..448 | per child: [`EMPTY`]; a node index; a packed leaf: bits 31 and 30 set, bits 26..30 the block count - 1, bits 0..26 the first [`Tri4`] block; or a range leaf: bit 31 set, bits 0..30 an index into [`WideBvh::ranges`] |
/// | padding | 112..128 / 224..256 / none | keeps nodes aligned to cache lines |
///
/// A box row per axis and side lets the slab test load, for each axis, just the plane the
/// ray enters by and the one it leaves by. Empty slots have boxes at `+inf` that no ray with
/// a finite `t_max` can hit.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode<const W: usize> {
    /// Lower x, y, z and upper x, y, z of the `W` children, by row.
    pub bounds: [[f32; W]; ROWS],
    /// Child references (see the table).
    pub child: [u32; W],
}

const _: () = assert!(std::mem::size_of::<WideNode<4>>() == 128);
const _: () = assert!(std::mem::size_of::<WideNode<8>>() == 256);
const _: () = assert!(std::mem::size_of::<WideNode<16>>() == 448);

impl<const W: usize> WideNode<W> {
    pub(super) fn empty() -> Self {
        WideNode { bounds: [[f32::INFINITY; W]; ROWS], child: [EMPTY; W] }
    }

    pub(super) fn set(&mut self, i: usize, b: &Aabb, child: u32) {
        for axis in 0..3 {
            self.bounds[axis][i] = b.min[axis];
            self.bounds[axis + 3][i] = b.max[axis];
        }
        self.child[i] = child;
    }

    /// The box of child `i`.
    pub fn child_bounds(&self, i: usize) -> Aabb {
        let row = |r: usize| Vec3A::new(self.bounds[r][i], self.bounds[r + 1][i], self.bounds[r + 2][i]);
        Aabb { min: row(0), max: row(3) }
    }
}

/// Four triangles in structure-of-arrays form, for one 4-wide Möller–Trumbore test: the
/// leaves of static triangles are stored as these. 160 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct Tri4 {
    /// First vertices, by axis.
    pub v0: [[f32; 4]; 3],
    /// Edges from vertex 0 to vertex 1, by axis.
    pub e1: [[f32; 4]; 3],
    /// Edges from vertex 0 to vertex 2, by axis.
    pub e2: [[f32; 4]; 3],
    /// Primitive slot of each lane; [`EMPTY`] for an unused lane (whose triangle is
    /// degenerate and never hit).
    pub slot: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Tri4>() == 160);

impl Tri4 {
    pub(super) fn pack(tris: impl Iterator<Item = (u32, Triangle)>) -> Tri4 {
        let mut t = Tri4::EMPTY;
        for (lane, (slot, tri)) in tris.take(4).enumerate() {
            for axis in 0..3 {
                t.v0[axis][lane] = tri.v0[axis];
                t.e1[axis][lane] = tri.e1[axis];
                t.e2[axis][lane] = tri.e2[axis];
            }
            t.slot[lane] = slot;
        }
        t
    }

    /// A block of four unused lanes (degenerate triangles, never hit).
    pub const EMPTY: Tri4 = Tri4 { v0: [[0.0; 4]; 3], e1: [[0.0; 4]; 3], e2: [[0.0; 4]; 3], slot: [EMPTY; 4] };

    /// Copy lane `from` of `src` into lane `to`, bit for bit.
    pub fn copy_lane(&mut self, to: usize, src: &Tri4, from: usize) {
        for axis in 0..3 {
            self.v0[axis][to] = src.v0[axis][from];
            self.e1[axis][to] = src.e1[axis][from];
            self.e2[axis][to] = src.e2[axis][from];
        }
        self.slot[to] = src.slot[from];
    }

    /// The triangle in `lane`.
    pub fn triangle(&self, lane: usize) -> Triangle {
        let v = |a: &[[f32; 4]; 3]| Vec3A::new(a[0][lane], a[1][lane], a[2][lane]);
        Triangle { v0: v(&self.v0), e1: v(&self.e1), e2: v(&self.e2) }
    }

    /// Möller–Trumbore on four triangles at once, with exactly the scalar test's arithmetic
    /// ([`Triangle::intersect`]), so hits are bit-identical: returns the lanes hit within
    /// `[t_min, t_max]` and their `t`, `u`, `v`.
    #[inline(always)]
    pub(super) fn intersect(&self, r: &RayLanes, t_min: f32, t_max: f32) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
        let l = |a: &[f32; 4]| f32x4::new(*a);
        let (e1x, e1y, e1z) = (l(&self.e1[0]), l(&self.e1[1]), l(&self.e1[2]));
        let (e2x, e2y, e2z) = (l(&self.e2[0]), l(&self.e2[1]), l(&self.e2[2]));
        // p = dir x e2
        let px = r.dy * e2z - r.dz * e2y;
        let py = r.dz * e2x - r.dx * e2z;
        let pz = r.dx * e2y - r.dy * e2x;
        let det = e1x * px + e1y * py + e1z * pz;
        let inv_det = f32x4::ONE / det;
        // s = origin - v0
        let sx = r.ox - l(&self.v0[0]);
        let sy = r.oy - l(&self.v0[1]);
        let sz = r.oz - l(&self.v0[2]);
        let u = (sx * px + sy * py + sz * pz) * inv_det;
        // q = s x e1
        let qx = sy * e1z - sz * e1y;
        let qy = sz * e1x - sx * e1z;
        let qz = sx * e1y - sy * e1x;
        let v = (r.dx * qx + r.dy * qy + r.dz * qz) * inv_det;
        let t = (e2x * qx + e2y * qy + e2z * qz) * inv_det;
        let zero = f32x4::ZERO;
        // det != 0 and finite: |det| in (0, inf).
        let ok_det = det.abs().simd_gt(zero) & det.abs().simd_lt(f32x4::splat(f32::INFINITY));
        let ok_u = u.simd_ge(zero) & u.simd_le(f32x4::ONE);
        let ok_v = v.simd_ge(zero) & (u + v).simd_le(f32x4::ONE);
        let ok_t = t.simd_ge(f32x4::splat(t_min)) & t.simd_le(f32x4::splat(t_max));
        let mask = (ok_det & ok_u & ok_v & ok_t).to_bitmask();
        (mask, t.to_array(), u.to_array(), v.to_array())
    }
}

/// The reference to a packed leaf of blocks `first..first + count` in [`WideBvh::blocks`]
/// (`count` in `1..=MAX_BLOCKS`, `first` below `2^BLOCK_BITS`); [`packed_blocks`] reads it.
#[inline]
pub(super) fn packed_ref(first: u32, count: u32) -> u32 {
    debug_assert!((1..=MAX_BLOCKS).contains(&count) && first < 1 << BLOCK_BITS);
    LEAF_BIT | PACKED_BIT | ((count - 1) << BLOCK_BITS) | first
}

/// The first block of a packed leaf reference (the reference's low bits, whatever else it is).
#[inline(always)]
fn first_block(child: u32) -> usize {
    (child & ((1 << BLOCK_BITS) - 1)) as usize
}

/// The blocks of a packed leaf reference: `first..first + count` in [`WideBvh::blocks`].
#[inline(always)]
pub(super) fn packed_blocks(child: u32) -> std::ops::Range<usize> {
    let first = first_block(child);
    first..first + ((child >> BLOCK_BITS) & 0xf) as usize + 1
}

/// The reference to range leaf `index` of [`WideBvh::ranges`]; [`range_index`] reads it.
#[inline]
pub(super) fn range_ref(index: u32) -> u32 {
    debug_assert!(index & (LEAF_BIT | PACKED_BIT) == 0);
    LEAF_BIT | index
}

/// The index in [`WideBvh::ranges`] of a range leaf reference.
#[inline(always)]
pub(super) fn range_index(child: u32) -> usize {
    (child & !LEAF_BIT) as usize
}

/// Whether a child reference is a packed leaf.
#[inline(always)]
pub(super) fn is_packed(child: u32) -> bool {
    child & (LEAF_BIT | PACKED_BIT) == LEAF_BIT | PACKED_BIT
}

/// Where a range leaf's primitives are: slots `start..start + count`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LeafRange {
    /// First slot.
    pub start: u32,
    /// Number of slots.
    pub count: u32,
}

#[inline(always)]
pub(super) fn ray_is_finite(ray: &Ray) -> bool {
    ray.origin.is_finite() && ray.dir.is_finite() && !ray.t.min.is_nan() && !ray.t.max.is_nan()
}

/// A wide BVH: nodes of `W` children, leaves of packed triangles or primitive ranges.
#[derive(Clone, Debug, Default)]
pub struct WideBvh<const W: usize> {
    /// Nodes; `nodes[0]` is the root. Empty for an empty scene.
    pub nodes: Vec<WideNode<W>>,
    /// Packed triangles of the leaves that hold only static triangles.
    pub blocks: Vec<Tri4>,
    /// The other leaves (spheres, moving shapes, mixes, oversized leaves): slot ranges whose
    /// primitives are intersected one by one through [`Primitives`].
    pub ranges: Vec<LeafRange>,
    /// The traversal variant: [`SimdLevel::detect`] when built. Private to the BVH module so
    /// that it can only name a level the CPU has; [`WideBvh::portable`] selects the baseline.
    pub(super) simd: SimdLevel,
}

/// The 4-wide BVH (128-byte nodes, tested with 4-lane vectors).
pub type Bvh4 = WideBvh<4>;
/// The 8-wide BVH (256-byte nodes, one AVX2 test per step on x86-64): what rendering
/// traverses where the CPU lacks AVX-512.
pub type Bvh8 = WideBvh<8>;
/// The 16-wide BVH (448-byte nodes, one AVX-512 test per step): what rendering traverses
/// where the CPU has AVX-512. Its traversals need [`WideBvh::fits_stack`] (a query on a
/// deeper tree would overflow the fixed stack and panic); [`tree::WideTree`] checks.
pub type Bvh16 = WideBvh<16>;

/// Deepest traversal stack: `W - 1` pushes per level of a tree at most [`super::MAX_DEPTH`]
/// deep, for the 8-wide tree (whose depth is at most the binary tree's). A 16-wide tree is
/// used only where its own depth fits ([`WideBvh::fits_stack`]; every course mesh's does,
/// with room to spare): a stack sized for the worst 16-wide tree was a page more per query.
const STACK: usize = 7 * super::MAX_DEPTH + 8;

/// A fixed-capacity stack on the machine stack. Its storage is left uninitialised: zeroing
/// a few KiB per ray showed up in profiles as a few percent of render time.
pub(super) struct Stack<T: Copy> {
    items: [std::mem::MaybeUninit<T>; STACK],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Stack { items: [const { std::mem::MaybeUninit::uninit() }; STACK], len: 0 }
    }

    #[inline(always)]
    pub(super) fn push(&mut self, v: T) {
        // Cannot overflow: the tree is at most MAX_DEPTH levels deep and each level pushes
        // at most W - 1 entries; the bounds check stays as a guard.
        self.items[self.len].write(v);
        self.len += 1;
    }

    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below `len` was written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

/// The ray's data for the packed triangle test, splatted across four lanes once per ray.
pub struct RayLanes {
    ox: f32x4,
    oy: f32x4,
    oz: f32x4,
    dx: f32x4,
    dy: f32x4,
    dz: f32x4,
}

impl RayLanes {
    #[inline(always)]
    pub(super) fn new(ray: &Ray) -> RayLanes {
        RayLanes {
            ox: f32x4::splat(ray.origin.x),
            oy: f32x4::splat(ray.origin.y),
            oz: f32x4::splat(ray.origin.z),
            dx: f32x4::splat(ray.dir.x),
            dy: f32x4::splat(ray.dir.y),
            dz: f32x4::splat(ray.dir.z),
        }
    }
}

/// One ray made ready for leaf tests: the ray, its node test (which also runs the two-block
/// triangle test) and its four-lane splat.
pub(super) struct OneRay<'a, T> {
    pub(super) ray: &'a Ray,
    pub(super) boxes: &'a T,
    pub(super) lanes: &'a RayLanes,
}

/// For each axis, the row of [`WideNode::bounds`] the ray enters a box by and the one it
/// leaves by: the lower plane when the (safe) inverse direction is positive. Since
/// `(lo - o) * inv <= (hi - o) * inv` for positive `inv` in rounded arithmetic too, this gives
/// exactly the scalar test's `min`/`max` of the two plane distances with half the work.
#[inline(always)]
pub(super) fn planes(inv: Vec3A) -> ([usize; 3], [usize; 3]) {
    let (nx, ny, nz) = (usize::from(inv.x < 0.0), usize::from(inv.y < 0.0), usize::from(inv.z < 0.0));
    ([3 * nx, 1 + 3 * ny, 2 + 3 * nz], [3 - 3 * nx, 4 - 3 * ny, 5 - 3 * nz])
}

/// A ray prepared for the slab test of one node's `W` boxes at once.
pub trait NodeTest<const W: usize>: Sized {
    /// Prepare `ray` with its safe inverse direction `inv`.
    ///
    /// # Safety
    /// The CPU must have the features the implementation is compiled for.
    unsafe fn new(ray: &Ray, inv: Vec3A) -> Self;

    /// Entry distances of the node's `W` child boxes and the mask of those hit within
    /// `[t_min, t_max]`, by the slab test of the module documentation. `FORWARD` says that
    /// `t_min >= 0` (distances then compare in integer order); the traversals choose it once
    /// per ray, as a branch per node measured 8% slower.
    ///
    /// # Safety
    /// As for [`NodeTest::new`].
    unsafe fn test<const FORWARD: bool>(&self, n: &WideNode<W>, t_min: f32, t_max: f32) -> ([f32; W], u32);

    /// Two packed blocks at once, as the packed 4-wide test (`Tri4::intersect`) gives them:
    /// lanes 0..4 are `a`'s, 4..8 are `b`'s. Both are tested against `[t_min, t_max]`.
    ///
    /// # Safety
    /// As for [`NodeTest::new`].
    #[inline(always)]
    unsafe fn intersect_pair(&self, r: &RayLanes, a: &Tri4, b: &Tri4, t_min: f32, t_max: f32) -> PairHits {
        let (ma, ta, ua, va) = a.intersect(r, t_min, t_max);
        let (mb, tb, ub, vb) = b.intersect(r, t_min, t_max);
        let cat = |x: [f32; 4], y: [f32; 4]| [x[0], x[1], x[2], x[3], y[0], y[1], y[2], y[3]];
        (ma | mb << 4, cat(ta, tb), cat(ua, ub), cat(va, vb))
    }
}

/// Lanes of a packed test that hit, with their `t`, `u`, `v`.
struct Hits<'a> {
    mask: u32,
    t: &'a [f32],
    u: &'a [f32],
    v: &'a [f32],
}

impl Hits<'_> {
    /// Keep each hit lane that is closer than the closest so far (`t_max`, `best`), with the
    /// primitive slot `slot(lane)` (see [`closer`]).
    #[inline(always)]
    fn take(self, slot: impl Fn(usize) -> u32, t_max: &mut f32, best: &mut Option<BvhHit>) {
        let mut mask = self.mask;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let hit = BvhHit { slot: slot(lane), hit: PrimHit { t: self.t[lane], u: self.u[lane], v: self.v[lane] } };
            closer(hit, t_max, best);
        }
    }
}

/// Keep `hit` as the closest so far if it is nearer than `best` (whose distance is `t_max`),
/// or as near and in a lower slot. Ties go to the lower slot so that the closest hit does not
/// depend on the order leaves are visited in: single rays and packets, which visit them in
/// different orders, report the same primitive where a ray meets a shared edge.
#[inline(always)]
fn closer(hit: BvhHit, t_max: &mut f32, best: &mut Option<BvhHit>) {
    let t = hit.hit.t;
    if t < *t_max || (t == *t_max && best.is_none_or(|b| hit.slot < b.slot)) {
        *t_max = t;
        *best = Some(hit);
    }
}

/// The lanes hit and their `t`, `u`, `v`, for eight triangles.
pub type PairHits = (u32, [f32; 8], [f32; 8], [f32; 8]);

/// `a * b - c` with one rounding, lane by lane: the AVX2 test's `vfmsub`, bit for bit. The
/// `wide` vectors fuse it only where the crate is compiled for FMA (or NEON); elsewhere each
/// lane goes through `f32::mul_add` (an instruction in code compiled for FMA, else libm's
/// exact `fmaf`: the baseline traversal is slower, never different).
#[inline(always)]
pub(super) fn fused_mul_sub<const N: usize, V>(a: V, b: V, c: V) -> V
where
    V: Copy + FloatLanes<N>,
{
    if cfg!(any(target_feature = "fma", all(target_arch = "aarch64", target_feature = "neon"))) {
        a.mul_sub_fused(b, c)
    } else {
        let (a, b, c) = (a.lanes(), b.lanes(), c.lanes());
        V::from_lanes(std::array::from_fn(|i| a[i].mul_add(b[i], -c[i])))
    }
}

/// The `wide` vector types the portable tests use, as arrays of lanes.
pub(super) trait FloatLanes<const N: usize> {
    /// `self * b - c`, fused where `wide` fuses it.
    fn mul_sub_fused(self, b: Self, c: Self) -> Self;
    /// The lanes.
    fn lanes(self) -> [f32; N];
    /// From lanes.
    fn from_lanes(l: [f32; N]) -> Self;
}

macro_rules! lanes_impl {
    ($v:ty, $n:literal) => {
        impl FloatLanes<$n> for $v {
            #[inline(always)]
            fn mul_sub_fused(self, b: Self, c: Self) -> Self {
                self.mul_sub(b, c)
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
            /// `o * inv` per axis, rounded once.
            oinv: [$v; 3],
            near: [usize; 3],
            far: [usize; 3],
        }

        impl NodeTest<$w> for $name {
            #[inline(always)]
            unsafe fn new(ray: &Ray, inv: Vec3A) -> Self {
                let (near, far) = planes(inv);
                let oinv = ray.origin * inv;
                $name {
                    inv: [<$v>::splat(inv.x), <$v>::splat(inv.y), <$v>::splat(inv.z)],
                    oinv: [<$v>::splat(oinv.x), <$v>::splat(oinv.y), <$v>::splat(oinv.z)],
                    near,
                    far,
                }
            }

            #[inline(always)]
            unsafe fn test<const FORWARD: bool>(&self, n: &WideNode<$w>, t_min: f32, t_max: f32) -> ([f32; $w], u32) {
                let t = |row: usize, a: usize| fused_mul_sub(<$v>::new(n.bounds[row]), self.inv[a], self.oinv[a]);
                let near = [t(self.near[0], 0), t(self.near[1], 1), t(self.near[2], 2)];
                let far = [t(self.far[0], 0), t(self.far[1], 1), t(self.far[2], 2)];
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

/// The 8-wide slab test in AVX2 (`std::arch`): one 256-bit instruction per step.
#[cfg(target_arch = "x86_64")]
pub struct Avx2Node8 {
    o: [std::arch::x86_64::__m256; 3],
    dir: [std::arch::x86_64::__m256; 3],
    inv: [std::arch::x86_64::__m256; 3],
    oinv: [std::arch::x86_64::__m256; 3],
    near: [usize; 3],
    far: [usize; 3],
}

#[cfg(target_arch = "x86_64")]
impl NodeTest<8> for Avx2Node8 {
    // Not `target_feature` functions themselves: those would stay out-of-line calls in the
    // traversal compiled for AVX2, where these inline.
    #[inline(always)]
    unsafe fn new(ray: &Ray, inv: Vec3A) -> Self {
        use std::arch::x86_64::_mm256_set1_ps as splat;
        let (near, far) = planes(inv);
        let oinv = ray.origin * inv;
        // SAFETY: the caller vouches for AVX2.
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
    unsafe fn test<const FORWARD: bool>(&self, n: &WideNode<8>, t_min: f32, t_max: f32) -> ([f32; 8], u32) {
        use std::arch::x86_64::*;
        // SAFETY: the caller vouches for AVX2 and FMA; nodes are 64-byte aligned and each row
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
    unsafe fn intersect_pair(&self, _: &RayLanes, a: &Tri4, b: &Tri4, t_min: f32, t_max: f32) -> PairHits {
        use std::arch::x86_64::*;
        // SAFETY: the caller vouches for AVX2; the loads read 16 bytes from rows of 4 floats.
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
/// the 8-wide AVX2 test's triangle test.
#[cfg(target_arch = "x86_64")]
pub struct Avx512Node16 {
    /// The leaves' test (and its ray splats).
    pair: Avx2Node8,
    inv: [std::arch::x86_64::__m512; 3],
    oinv: [std::arch::x86_64::__m512; 3],
    near: [usize; 3],
    far: [usize; 3],
}

#[cfg(target_arch = "x86_64")]
impl NodeTest<16> for Avx512Node16 {
    #[inline(always)]
    unsafe fn new(ray: &Ray, inv: Vec3A) -> Self {
        use std::arch::x86_64::_mm512_set1_ps as splat;
        let (near, far) = planes(inv);
        let oinv = ray.origin * inv;
        // SAFETY: the caller vouches for AVX-512 (and with it AVX2).
        unsafe {
            Avx512Node16 {
                pair: <Avx2Node8 as NodeTest<8>>::new(ray, inv),
                inv: [splat(inv.x), splat(inv.y), splat(inv.z)],
                oinv: [splat(oinv.x), splat(oinv.y), splat(oinv.z)],
                near,
                far,
            }
        }
    }

    #[inline(always)]
    unsafe fn test<const FORWARD: bool>(&self, n: &WideNode<16>, t_min: f32, t_max: f32) -> ([f32; 16], u32) {
        use std::arch::x86_64::*;
        // SAFETY: the caller vouches for AVX-512 F; nodes are 64-byte aligned and each row is
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
    unsafe fn intersect_pair(&self, r: &RayLanes, a: &Tri4, b: &Tri4, t_min: f32, t_max: f32) -> PairHits {
        // SAFETY: as for `new`.
        unsafe { self.pair.intersect_pair(r, a, b, t_min, t_max) }
    }
}

/// The node tests of one width: the portable one and those used at [`SimdLevel::Avx2`] and
/// [`SimdLevel::Avx512`].
pub trait NodeWidth<const W: usize> {
    /// The baseline test.
    type Portable: NodeTest<W>;
    /// The test compiled for AVX2 (the portable one, where no better exists).
    type Avx2: NodeTest<W>;
    /// The test compiled for AVX-512 (the AVX2 one, where no better exists).
    type Avx512: NodeTest<W>;
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

type PortableTest<const W: usize> = <Lanes<W> as NodeWidth<W>>::Portable;
#[cfg(target_arch = "x86_64")]
type Avx2Test<const W: usize> = <Lanes<W> as NodeWidth<W>>::Avx2;
#[cfg(target_arch = "x86_64")]
type Avx512Test<const W: usize> = <Lanes<W> as NodeWidth<W>>::Avx512;

/// Sort traversal entries farthest first by their entry distance `near` (insertion sort: at
/// most eight); single rays and packets both order their children with it.
#[inline(always)]
pub(super) fn sort_far_to_near<E: Copy>(order: &mut [E], near: impl Fn(&E) -> f32) {
    for i in 1..order.len() {
        let e = order[i];
        let mut j = i;
        while j > 0 && near(&order[j - 1]) < near(&e) {
            order[j] = order[j - 1];
            j -= 1;
        }
        order[j] = e;
    }
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// A packed leaf's blocks two at a time, with the lanes of the pair that are the leaf's:
    /// `0xff`, or `0x0f` for a last odd block, paired with the block after it (or an empty
    /// one at the end of the array) so that every step is one eight-lane test.
    #[inline(always)]
    pub(super) fn block_pairs(&self, leaf: u32) -> impl Iterator<Item = (&Tri4, &Tri4, u32)> {
        let range = packed_blocks(leaf);
        let end = range.end;
        range.step_by(2).map(move |i| {
            let b = self.blocks.get(i + 1).unwrap_or(&Tri4::EMPTY);
            (&self.blocks[i], b, if i + 1 < end { 0xff } else { 0x0f })
        })
    }

    /// Ask for a child's memory as soon as its box is hit, so that the loads overlap the
    /// work on its siblings (incoherent rays wait on cache misses more than on arithmetic): a
    /// node's four lines, or a packed leaf's first pair of blocks (five lines).
    #[inline(always)]
    pub(super) fn prefetch(&self, child: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let (p, lines): (*const i8, usize) = if is_packed(child) {
                (self.blocks.as_ptr().wrapping_add(packed_blocks(child).start).cast(), 5)
            } else if child & LEAF_BIT == 0 {
                (self.nodes.as_ptr().wrapping_add(child as usize).cast(), size_of::<WideNode<W>>() / 64)
            } else {
                return;
            };
            for line in 0..lines {
                // SAFETY: a prefetch is a hint and never faults, whatever the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = child;
    }

    /// [`WideBvh::prefetch`] choosing the address without branches: the four lines of a node
    /// or the first four of a packed leaf's blocks (of the first node for a range leaf).
    #[inline(always)]
    pub(super) fn prefetch_branchless(&self, child: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let node = self.nodes.as_ptr().wrapping_add((child & !(LEAF_BIT | PACKED_BIT)) as usize) as *const i8;
            let block = self.blocks.as_ptr().wrapping_add(first_block(child)) as *const i8;
            let p = if is_packed(child) {
                block
            } else if child & LEAF_BIT == 0 {
                node
            } else {
                self.nodes.as_ptr() as *const i8
            };
            for line in 0..4 {
                // SAFETY: a prefetch is a hint and never faults, whatever the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = child;
    }

    /// Levels of nodes (0 for an empty tree).
    pub fn depth(&self) -> usize {
        let mut depth = vec![0usize; self.nodes.len()];
        if let Some(d) = depth.first_mut() {
            *d = 1;
        }
        // Children come after their parents (the collapse appends them depth-first).
        for i in 0..self.nodes.len() {
            for &c in &self.nodes[i].child {
                if c != EMPTY && c & LEAF_BIT == 0 {
                    depth[c as usize] = depth[i] + 1;
                }
            }
        }
        depth.into_iter().max().unwrap_or(0)
    }

    /// Whether the traversals' fixed stack holds every entry this tree can need: `W - 1` per
    /// level. Always so up to eight children a node (the depth is at most the binary tree's).
    pub fn fits_stack(&self) -> bool {
        (W - 1) * self.depth() + W <= STACK
    }

    /// The traversal variant in use.
    pub fn simd_level(&self) -> SimdLevel {
        self.simd
    }

    /// The same tree traversed by the baseline code (to compare it with the detected one).
    pub fn portable(mut self) -> Self {
        self.simd = SimdLevel::Portable;
        self
    }

    /// The closest hit along `ray` within its interval.
    #[inline]
    pub fn intersect<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> Option<BvhHit> {
        self.intersect_counted(ray, prims, &mut NoObserver)
    }

    /// [`WideBvh::intersect`], reporting the traversal to `obs`.
    #[inline]
    pub fn intersect_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        // NaN rays would pass every slab test (SIMD min/max pass NaN through); they hit nothing.
        if self.nodes.is_empty() || !ray_is_finite(ray) {
            return None;
        }
        // SAFETY: `simd` names only a level the CPU has (see the field); the portable test
        // needs no CPU feature.
        unsafe {
            match self.simd {
                #[cfg(target_arch = "x86_64")]
                SimdLevel::Avx512 => self.intersect_avx512(ray, prims, obs),
                #[cfg(target_arch = "x86_64")]
                SimdLevel::Avx2 => self.intersect_avx2(ray, prims, obs),
                _ => self.intersect_portable(ray, prims, obs),
            }
        }
    }

    /// The portable traversal, kept out of line: inlined into every caller beside the SIMD
    /// dispatch, its code and its stack array made those callers' frames several pages deep
    /// on machines that never take it.
    #[inline(never)]
    fn intersect_portable<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        // SAFETY: the portable test needs no CPU feature.
        unsafe { self.intersect_with::<PortableTest<W>, P, O>(ray, prims, obs) }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn intersect_avx2<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        // SAFETY: this function runs only where the CPU has AVX2.
        unsafe { self.intersect_with::<Avx2Test<W>, P, O>(ray, prims, obs) }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
    unsafe fn intersect_avx512<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        // SAFETY: this function runs only where the CPU has AVX-512.
        unsafe { self.intersect_with::<Avx512Test<W>, P, O>(ray, prims, obs) }
    }

    /// The closest-hit traversal with node test `T` (the CPU must have its features),
    /// compiled once for each order of the slab test and chosen per ray.
    #[inline(always)]
    unsafe fn intersect_with<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        // SAFETY: the caller vouches for T's CPU features.
        unsafe {
            if ray.t.min >= 0.0 {
                self.closest::<T, P, O, true>(ray, prims, obs)
            } else {
                self.closest::<T, P, O, false>(ray, prims, obs)
            }
        }
    }

    /// [`WideBvh::intersect_with`] in one order of the slab test (`FORWARD`: `t_min >= 0`).
    #[inline(always)]
    unsafe fn closest<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver, const FORWARD: bool>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        // SAFETY: the caller vouches for T's CPU features.
        let boxes = unsafe { T::new(ray, safe_inv_dir(ray.dir)) };
        let lanes = RayLanes::new(ray);
        let (t_min, mut t_max) = (ray.t.min, ray.t.max);
        let mut best = None;
        // Entries: a child reference and its entry distance, so that entries a closer hit
        // has since ruled out are dropped when popped.
        let mut stack: Stack<(u32, f32)> = Stack::new();
        let mut current = 0u32;
        loop {
            if current & LEAF_BIT != 0 {
                let one = OneRay { ray, boxes: &boxes, lanes: &lanes };
                // SAFETY: as for `T::new`.
                unsafe { self.leaf_closest(current, &one, prims, obs, &mut t_max, &mut best) };
            } else {
                let node = &self.nodes[current as usize];
                obs.entered(current);
                obs.boxes_tested(W as u32);
                // SAFETY: as for `T::new`.
                let (near, mut mask) = unsafe { boxes.test::<FORWARD>(node, t_min, t_max) };
                if mask != 0 {
                    let first = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if mask == 0 {
                        // One child hit (the common case deep in the tree): straight on. A
                        // branch here measured faster than folding this case into the
                        // two-child one, most on camera rays, where it predicts well.
                        current = node.child[first];
                        continue;
                    }
                    if mask & (mask - 1) == 0 {
                        // Two children hit: the nearer next, without a branch on which it is
                        // (a branch mispredicts half the time on incoherent rays).
                        let second = mask.trailing_zeros() as usize;
                        let a = (node.child[first], near[first]);
                        let b = (node.child[second], near[second]);
                        let b_nearer = b.1 < a.1;
                        let (nearer, farther) = (if b_nearer { b } else { a }, if b_nearer { a } else { b });
                        self.prefetch_branchless(farther.0);
                        stack.push(farther);
                        current = nearer.0;
                        continue;
                    }
                    // Visit the nearest hit child now; push the others, farthest first.
                    let mut order = [(0u32, 0.0f32); W];
                    order[0] = (node.child[first], near[first]);
                    self.prefetch(node.child[first]);
                    let mut k = 1;
                    while mask != 0 {
                        let i = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        order[k] = (node.child[i], near[i]);
                        self.prefetch(node.child[i]);
                        k += 1;
                    }
                    sort_far_to_near(&mut order[..k], |e| e.1);
                    for &e in &order[..k - 1] {
                        stack.push(e);
                    }
                    current = order[k - 1].0;
                    continue;
                }
            }
            loop {
                let Some((c, entry)) = stack.pop() else { return best };
                if entry <= t_max {
                    current = c;
                    break;
                }
            }
        }
    }

    /// Intersect leaf reference `leaf` with one ray, keeping the closest hit in `t_max` and
    /// `best` (the single-ray traversal and each ray of a packet share this).
    ///
    /// # Safety
    /// As for [`NodeTest::new`].
    #[inline(always)]
    pub(super) unsafe fn leaf_closest<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        leaf: u32,
        one: &OneRay<'_, T>,
        prims: &P,
        obs: &mut O,
        t_max: &mut f32,
        best: &mut Option<BvhHit>,
    ) {
        let t_min = one.ray.t.min;
        if is_packed(leaf) {
            // Blocks two at a time (one 8-lane test where the CPU has AVX2), a leaf's last odd
            // block with whatever block follows it, its lanes masked off: leaves of one, two,
            // three blocks all run the same code, where a separate single-block test after the
            // pairs was a branch the leaf's size decided (and mispredicted). A lane beyond a
            // closer hit in the pair's first block is dropped by `closer` rather than by the
            // test: the same outcome as testing block by block.
            for (a, b, lanes) in self.block_pairs(leaf) {
                obs.prim_tested();
                if lanes == 0xff {
                    obs.prim_tested();
                }
                // SAFETY: the caller vouches for T's CPU features.
                let (mask, t, u, v) = unsafe { one.boxes.intersect_pair(one.lanes, a, b, t_min, *t_max) };
                let hits = Hits { mask: mask & lanes, t: &t, u: &u, v: &v };
                hits.take(|lane| if lane < 4 { a.slot[lane] } else { b.slot[lane - 4] }, t_max, best);
            }
        } else {
            let LeafRange { start, count } = self.ranges[range_index(leaf)];
            for slot in start..start + count {
                obs.prim_tested();
                if let Some(hit) = prims.intersect(slot, one.ray, t_min, *t_max) {
                    closer(BvhHit { slot, hit }, t_max, best);
                }
            }
        }
    }

    /// Whether anything blocks `ray` within its interval; stops at the first hit found.
    #[inline]
    pub fn occluded<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        if self.nodes.is_empty() || !ray_is_finite(ray) {
            return false;
        }
        // SAFETY: `simd` names only a level the CPU has (see the field); the portable test
        // needs no CPU feature.
        unsafe {
            match self.simd {
                #[cfg(target_arch = "x86_64")]
                SimdLevel::Avx512 => self.occluded_avx512(ray, prims),
                #[cfg(target_arch = "x86_64")]
                SimdLevel::Avx2 => self.occluded_avx2(ray, prims),
                _ => self.occluded_portable(ray, prims),
            }
        }
    }

    /// The portable any-hit traversal, kept out of line (see [`WideBvh::intersect_counted`]).
    #[inline(never)]
    fn occluded_portable<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        // SAFETY: the portable test needs no CPU feature.
        unsafe { self.occluded_with::<PortableTest<W>, P>(ray, prims) }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn occluded_avx2<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        // SAFETY: this function runs only where the CPU has AVX2.
        unsafe { self.occluded_with::<Avx2Test<W>, P>(ray, prims) }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
    unsafe fn occluded_avx512<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        // SAFETY: this function runs only where the CPU has AVX-512.
        unsafe { self.occluded_with::<Avx512Test<W>, P>(ray, prims) }
    }

    /// The any-hit traversal with node test `T` (the CPU must have its features), compiled
    /// once for each order of the slab test and chosen per ray.
    #[inline(always)]
    unsafe fn occluded_with<T: NodeTest<W>, P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        // SAFETY: the caller vouches for T's CPU features.
        unsafe {
            if ray.t.min >= 0.0 { self.any::<T, P, true>(ray, prims) } else { self.any::<T, P, false>(ray, prims) }
        }
    }

    /// [`WideBvh::occluded_with`] in one order of the slab test (`FORWARD`: `t_min >= 0`).
    #[inline(always)]
    unsafe fn any<T: NodeTest<W>, P: Primitives + ?Sized, const FORWARD: bool>(&self, ray: &Ray, prims: &P) -> bool {
        // SAFETY: the caller vouches for T's CPU features.
        let boxes = unsafe { T::new(ray, safe_inv_dir(ray.dir)) };
        let lanes = RayLanes::new(ray);
        let (t_min, t_max) = (ray.t.min, ray.t.max);
        let mut stack: Stack<u32> = Stack::new();
        let mut current = 0u32;
        loop {
            if is_packed(current) {
                for (a, b, pair_lanes) in self.block_pairs(current) {
                    // SAFETY: as for `T::new`.
                    if unsafe { boxes.intersect_pair(&lanes, a, b, t_min, t_max) }.0 & pair_lanes != 0 {
                        return true;
                    }
                }
            } else if current & LEAF_BIT != 0 {
                let LeafRange { start, count } = self.ranges[range_index(current)];
                for slot in start..start + count {
                    if prims.intersect(slot, ray, t_min, t_max).is_some() {
                        return true;
                    }
                }
            } else {
                let node = &self.nodes[current as usize];
                // SAFETY: as for `T::new`.
                let (_, mut mask) = unsafe { boxes.test::<FORWARD>(node, t_min, t_max) };
                if mask != 0 {
                    // Any order finds a blocker; the first hit child is visited next.
                    let first = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    while mask != 0 {
                        let i = mask.trailing_zeros() as usize;
                        self.prefetch(node.child[i]);
                        stack.push(node.child[i]);
                        mask &= mask - 1;
                    }
                    current = node.child[first];
                    continue;
                }
            }
            match stack.pop() {
                Some(c) => current = c,
                None => return false,
            }
        }
    }

    /// Check the collapsed tree: every primitive slot is in exactly one leaf reference,
    /// inside its box, and every node is reachable exactly once.
    pub fn validate(&self, bin: &Bvh, prim_bounds: &[Aabb]) -> Result<(), BvhError> {
        let mut covered = vec![0usize; bin.prim_indices.len()];
        if self.nodes.is_empty() {
            return if covered.is_empty() { Ok(()) } else { Err(BvhError::Coverage { slot: 0, times: 0 }) };
        }
        let mut reached = vec![0u32; self.nodes.len()];
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            reached[i] += 1;
            let n = &self.nodes[i];
            for k in 0..W {
                let c = n.child[k];
                if c == EMPTY {
                    continue;
                }
                let b = n.child_bounds(k);
                if c & LEAF_BIT != 0 {
                    let slots: Vec<u32> = if is_packed(c) {
                        let range = packed_blocks(c);
                        let bad = BvhError::BadRange { node: i, start: range.start, end: range.end };
                        let blocks = self.blocks.get(range).ok_or(bad)?;
                        blocks.iter().flat_map(|b| b.slot).filter(|s| *s != EMPTY).collect()
                    } else {
                        let bad = BvhError::BadChild { node: i, child: c as usize };
                        let r = self.ranges.get(range_index(c)).ok_or(bad)?;
                        (r.start..r.start + r.count).collect()
                    };
                    for slot in slots {
                        let Some(cov) = covered.get_mut(slot as usize) else {
                            return Err(BvhError::BadRange { node: i, start: slot as usize, end: slot as usize + 1 });
                        };
                        *cov += 1;
                        let prim = bin.prim_indices[slot as usize];
                        if !b.contains(&prim_bounds[prim as usize]) {
                            return Err(BvhError::PrimOutside { node: i, prim });
                        }
                    }
                } else {
                    let c = c as usize;
                    if c <= i || c >= self.nodes.len() {
                        return Err(BvhError::BadChild { node: i, child: c });
                    }
                    for j in 0..W {
                        if self.nodes[c].child[j] != EMPTY && !b.contains(&self.nodes[c].child_bounds(j)) {
                            return Err(BvhError::ChildOutside { node: i, child: c });
                        }
                    }
                    stack.push(c);
                }
            }
        }
        if let Some((slot, &times)) = covered.iter().enumerate().find(|(_, c)| **c != 1) {
            return Err(BvhError::Coverage { slot, times });
        }
        if let Some(n) = reached.iter().position(|r| *r != 1) {
            return Err(BvhError::Unreachable(n));
        }
        Ok(())
    }
}
