//! Closest hits for packets of up to eight rays that share an origin, such as a row of a
//! pinhole camera's pixels, traversing a wide BVH (8 or 16 children a node) once for all of
//! them.
//!
//! Camera rays of neighbouring pixels visit nearly the same nodes. Traced one at a time, each
//! ray pays for those nodes' loads and, above all, for their data-dependent branches (which
//! children were hit, in which order); a packet pays once. Inner nodes are tested against the
//! whole packet at once by interval arithmetic (the children in the vector lanes, eight at a
//! time, as for one ray): with a shared origin, each slab distance `(plane - o) * inv` is
//! bounded over the packet by the smallest and largest inverse direction, so a child the
//! packet test rejects is missed by every ray. A leaf's box is then tested per ray, exactly as the single-ray
//! traversal tests it, and only the rays that hit it intersect its triangles, each with the
//! single-ray leaf code (`pair_closest`). Where those rays also share their triangle axes (the
//! dominant component of their directions), each pair of blocks is loaded and translated to
//! the origin once for all of them (`NodeTest::pair_corners`), and each ray's test goes on
//! from the shared corners.
//!
//! Each ray's closest hit is the one the single-ray traversal reports, bit for bit: the packet
//! may visit more inner nodes than a ray would (never fewer), leaves are culled by the same
//! per-ray test, and ties between equally distant primitives go to the lower slot whatever
//! the order leaves are visited in.
//!
//! Here: the traversal and its inner-node tests (portable, AVX2, AVX-512). In `setup`: the
//! packet's set-up, which checks that the rays can go as one and puts them in the layouts the
//! tests need, ray by ray or eight lanes at a time in AVX2 (the same packet bit for bit). In
//! `tile`: up to eight packets (a camera tile's rows) walking the tree once, the inner nodes
//! tested for all of them, the leaves per packet by the packet's own leaf code
//! (`WideBvh::packet_leaf`).

use wide::f32x8;

use super::kernels::{Lanes, NodeTest, NodeWidth, RayLanes, Row, Slab, fused_mul_sub};
use super::layout::WideNode;
use super::simd::Baseline;
#[cfg(target_arch = "x86_64")]
use super::simd::{Avx2, Avx512};
use super::stack::Stack;
use super::traverse::{OneRay, descend, pair_closest};
use super::{ChildRef, Simd, WideBvh};
use crate::bvh::{BvhHit, NoObserver, Primitives, QueryKind, TraversalObserver};
use crate::math::Vec3A;
use crate::ray::Ray;

mod setup;
mod tile;

pub use tile::{TILE_RUNS, TileHits};

/// Rays per packet.
pub const PACKET: usize = 8;

/// The closest hit of each ray of a packet (`None` beyond the rays given).
pub type PacketHits = [Option<BvhHit>; PACKET];

/// The set bits of `mask`, lowest first.
#[inline(always)]
pub(in crate::bvh::wide) fn lanes_of(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            i
        })
    })
}

/// The lesser of two numbers that are not NaN (the packet's rays are checked finite, their
/// hits' distances are finite): one instruction, where `f32::min`'s handling of NaN costs
/// several, and the packet's set-up takes dozens of these.
#[inline(always)]
fn lesser(a: f32, b: f32) -> f32 {
    if b < a { b } else { a }
}

/// The greater of two numbers that are not NaN (see [`lesser`]).
#[inline(always)]
fn greater(a: f32, b: f32) -> f32 {
    if b > a { b } else { a }
}

/// A stack entry: a child reference, the rays still to trace into it, and the packet's
/// (lower-bound) entry distance.
#[derive(Clone, Copy)]
struct Entry {
    child: ChildRef,
    lanes: u32,
    near: f32,
}

/// The packet in the layouts its tests need.
#[derive(Clone)]
pub struct Packet {
    /// Shared origin.
    o: Vec3A,
    /// Per axis, the rows of [`WideNode::bounds`] the rays enter and leave boxes by.
    near_row: [Row; 3],
    far_row: [Row; 3],
    /// Per axis, the smallest and largest inverse direction over the packet.
    inv_lo: [f32; 3],
    inv_hi: [f32; 3],
    /// Per axis, each ray's inverse direction (lanes beyond the packet repeat its last ray).
    inv: [f32x8; 3],
    /// Per axis, each ray's `o * inv` for the planes it enters and leaves boxes by, as the
    /// single-ray test has them (`SlabOrigin`).
    oinv_near: [f32x8; 3],
    oinv_far: [f32x8; 3],
    /// Per axis, a bound on the rounding error of the single-ray test's `o * inv` term over
    /// the packet, which the inner nodes' test allows for.
    slack: [f32; 3],
    /// Each ray's interval start (finite).
    t_min: f32x8,
    /// The lanes whose interval starts at or after zero (tested in integer order), and their
    /// starts with -0 made +0.
    nonneg: u32,
    t_min_pos: f32x8,
    /// Smallest interval start over the packet (a zero as +0).
    t_min_lo: f32,
    /// Each ray's interval end, as given.
    t_end: f32x8,
    /// The farthest interval end over the packet.
    t_far: f32,
    /// Rays in the packet.
    active: u32,
}

/// The packet's test of an inner node of `W` children (see [`Packet::test`]), made ready for
/// one packet, with the token of the CPU features it is compiled for (as a `NodeTest` is).
pub trait PacketNodeTest<const W: usize>: Sized {
    /// The token that proves the CPU has the test's features ([`Baseline`]: none).
    type Cpu: Copy;

    /// The packet of `rays` (see [`Packet::new`]), made on the CPU `cpu` vouches for.
    fn packet(cpu: Self::Cpu, rays: &[Ray], reach: f32) -> Option<Packet>;

    /// Prepare the test for packet `p`, on the CPU `cpu` vouches for.
    fn new(cpu: Self::Cpu, p: &Packet) -> Self;

    /// [`Packet::test`] on `node`.
    fn test(&self, p: &Packet, node: &WideNode<W>, t_far: f32) -> ([f32; W], u32);

    /// [`Packet::leaf_lanes`]: the rays whose own box test lets them into child `i`.
    #[inline(always)]
    fn leaf_lanes(&self, p: &Packet, node: &WideNode<W>, i: usize, t_max: f32x8) -> u32 {
        p.leaf_lanes(node, i, t_max)
    }
}

/// The portable packet test: children eight at a time in the `wide` vectors.
pub struct PortablePacketTest;

impl<const W: usize> PacketNodeTest<W> for PortablePacketTest {
    type Cpu = Baseline;

    #[inline(always)]
    fn packet(_: Baseline, rays: &[Ray], reach: f32) -> Option<Packet> {
        Packet::new(rays, reach)
    }

    #[inline(always)]
    fn new(_: Baseline, _: &Packet) -> Self {
        PortablePacketTest
    }

    #[inline(always)]
    fn test(&self, p: &Packet, node: &WideNode<W>, t_far: f32) -> ([f32; W], u32) {
        p.test(node, t_far)
    }
}

/// A packet test of a `W`-wide node in `std::arch` intrinsics: [`Packet::test`]'s operations
/// on all `W` children at once, one instruction per step (the portable vectors, compiled for the
/// baseline, take two 128-bit halves per eight children, and their blends and masks several
/// more). Given as closures, spliced in as expressions (a closure would be compiled without the
/// caller's CPU features, and its intrinsics stay calls): `ge` is the mask of lanes `>= 0`,
/// `pick(m, x, y)` takes `y` where `m` is set, `le(a, b)` the bit mask of lanes `a <= b`.
macro_rules! simd_packet_test {
    ($(#[$doc:meta])* $name:ident, $w:literal, $cpu:ident, $v:ident, $splat:ident, $load:ident, $store:ident,
     $sub:ident, $mul:ident, $add:ident, $max:ident, $min:ident, $andnot:ident,
     ge: |$gd:ident| $ge:expr, pick: |$pm:ident, $px:ident, $py:ident| $pick:expr,
     le: |$la:ident, $lb:ident| $le:expr) => {
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        pub struct $name {
            o: [std::arch::x86_64::$v; 3],
            lo: [std::arch::x86_64::$v; 3],
            hi: [std::arch::x86_64::$v; 3],
            slack: [std::arch::x86_64::$v; 3],
            t_min_lo: std::arch::x86_64::$v,
            cpu: $cpu,
        }

        #[cfg(target_arch = "x86_64")]
        impl PacketNodeTest<$w> for $name {
            type Cpu = $cpu;

            #[inline(always)]
            fn packet(cpu: $cpu, rays: &[Ray], reach: f32) -> Option<Packet> {
                Packet::new_avx2(cpu.into(), rays, reach)
            }

            #[inline(always)]
            fn new(cpu: $cpu, p: &Packet) -> Self {
                use std::arch::x86_64::$splat as splat;
                // SAFETY: the token proves that the CPU has the intrinsics' features.
                unsafe {
                    $name {
                        o: [splat(p.o.x), splat(p.o.y), splat(p.o.z)],
                        lo: [splat(p.inv_lo[0]), splat(p.inv_lo[1]), splat(p.inv_lo[2])],
                        hi: [splat(p.inv_hi[0]), splat(p.inv_hi[1]), splat(p.inv_hi[2])],
                        slack: [splat(p.slack[0]), splat(p.slack[1]), splat(p.slack[2])],
                        t_min_lo: splat(p.t_min_lo),
                        cpu,
                    }
                }
            }

            #[inline(always)]
            fn test(&self, p: &Packet, node: &WideNode<$w>, t_far: f32) -> ([f32; $w], u32) {
                use std::arch::x86_64::*;
                // SAFETY: the CPU has the intrinsics' features (`self` was made with their
                // token); `d` holds `W` floats.
                unsafe {
                    let near = $max(
                        $max(self.bound::<true>(node, p.near_row[0], 0), self.bound::<true>(node, p.near_row[1], 1)),
                        $max(self.bound::<true>(node, p.near_row[2], 2), self.t_min_lo),
                    );
                    let far = $min(
                        $min(self.bound::<false>(node, p.far_row[0], 0), self.bound::<false>(node, p.far_row[1], 1)),
                        $min(self.bound::<false>(node, p.far_row[2], 2), $splat(t_far.min(f32::MAX))),
                    );
                    let mut d = [0.0f32; $w];
                    $store(d.as_mut_ptr(), near);
                    let ($la, $lb) = (near, far);
                    (d, $le)
                }
            }

            #[inline(always)]
            fn leaf_lanes(&self, p: &Packet, node: &WideNode<$w>, i: usize, t_max: f32x8) -> u32 {
                p.leaf_lanes_avx2(self.cpu.into(), node, i, t_max)
            }
        }

        #[cfg(target_arch = "x86_64")]
        impl $name {
            /// The bound over the packet of the distances to plane row `row` (axis `a`) of
            /// `node`'s children: the lowest if `LOWEST`, else the highest (as in
            /// [`Packet::test`]). A method, not a closure: a closure is compiled without the
            /// caller's CPU features, and the intrinsics in it stayed calls.
            #[inline(always)]
            fn bound<const LOWEST: bool>(&self, node: &WideNode<$w>, row: Row, a: usize) -> std::arch::x86_64::$v {
                use std::arch::x86_64::*;
                // SAFETY: the CPU has the intrinsics' features (`self` was made with their
                // token); nodes are 64-byte aligned and each row is `4 W` bytes (32 or 64), as
                // the aligned load needs.
                unsafe {
                    let d = $sub($load(node.bounds[row as usize].as_ptr()), self.o[a]);
                    let $gd = d;
                    let $pm = $ge;
                    let ($px, $py) = if LOWEST { (self.hi[a], self.lo[a]) } else { (self.lo[a], self.hi[a]) };
                    let inv = $pick;
                    let b = $mul(d, inv);
                    let margin = $add($mul($andnot($splat(-0.0), b), $splat(PACKET_EPS)), self.slack[a]);
                    if LOWEST { $sub(b, margin) } else { $add(b, margin) }
                }
            }
        }
    };
}

simd_packet_test!(
    /// The packet test of a 16-wide node in AVX-512 (compares into mask registers).
    Avx512PacketTest, 16, Avx512, __m512, _mm512_set1_ps, _mm512_load_ps, _mm512_storeu_ps,
    _mm512_sub_ps, _mm512_mul_ps, _mm512_add_ps, _mm512_max_ps, _mm512_min_ps, _mm512_andnot_ps,
    ge: |d| _mm512_cmp_ps_mask::<_CMP_GE_OQ>(d, _mm512_setzero_ps()),
    pick: |m, x, y| _mm512_mask_blend_ps(m, x, y),
    le: |a, b| u32::from(_mm512_cmp_ps_mask::<_CMP_LE_OQ>(a, b))
);

simd_packet_test!(
    /// The packet test of an 8-wide node in AVX2 (compares into vector masks, blends by them).
    Avx2PacketTest, 8, Avx2, __m256, _mm256_set1_ps, _mm256_load_ps, _mm256_storeu_ps,
    _mm256_sub_ps, _mm256_mul_ps, _mm256_add_ps, _mm256_max_ps, _mm256_min_ps, _mm256_andnot_ps,
    ge: |d| _mm256_cmp_ps::<_CMP_GE_OQ>(d, _mm256_setzero_ps()),
    pick: |m, x, y| _mm256_blendv_ps(x, y, m),
    le: |a, b| _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(a, b)) as u32
);

/// The widths packets traverse (8 and 16) and their inner-node tests at [`SimdLevel::Avx2`]
/// and [`SimdLevel::Avx512`]; at the baseline it is [`PortablePacketTest`].
pub trait PacketWidth<const W: usize> {
    /// The test compiled for AVX2 (the portable one, where no better exists).
    type Avx2: PacketNodeTest<W, Cpu: From<Avx2>>;
    /// The test compiled for AVX-512.
    type Avx512: PacketNodeTest<W, Cpu: From<Avx512>>;
}

impl PacketWidth<8> for Lanes<8> {
    #[cfg(target_arch = "x86_64")]
    type Avx2 = Avx2PacketTest;
    #[cfg(not(target_arch = "x86_64"))]
    type Avx2 = PortablePacketTest;
    type Avx512 = Self::Avx2;
}

impl PacketWidth<16> for Lanes<16> {
    type Avx2 = PortablePacketTest;
    #[cfg(target_arch = "x86_64")]
    type Avx512 = Avx512PacketTest;
    #[cfg(not(target_arch = "x86_64"))]
    type Avx512 = PortablePacketTest;
}

/// How much the inner nodes' test widens each bound, relative to its magnitude (see
/// [`Packet::test`]).
const PACKET_EPS: f32 = 1.0 / (1 << 21) as f32;

/// Relative bound on the rounding of the single-ray test's `o * inv` over the packet (see
/// [`Packet::slack`]): twice the worst, 2^-24, with room to spare.
const SLACK_ROUNDING: f32 = 1.0 / (1 << 22) as f32;

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W> + PacketWidth<W>,
{
    /// The closest hit of each of up to [`PACKET`] `rays`, identical to
    /// [`WideBvh::intersect`] on each: as one packet when they are finite, share their origin
    /// bit for bit and have one direction sign per axis, else one by one. For trees of 8 or
    /// 16 children a node.
    pub fn intersect_packet<P: Primitives + ?Sized>(&self, rays: &[Ray], prims: &P) -> PacketHits {
        self.intersect_packet_counted(rays, prims, &mut [NoObserver; PACKET])
    }

    /// [`WideBvh::intersect_packet`], reporting each ray's traversal to its observer in `obs`
    /// (`obs[i]` for `rays[i]`): a ray traced in the packet is told [`QueryKind::Packet`] and
    /// every inner node the packet enters (the ray is in it: inner nodes are tested for the
    /// whole packet), and the leaves its own box test lets it into; a ray traced alone (the
    /// rays do not form a packet) is told what [`WideBvh::intersect_counted`] tells.
    pub fn intersect_packet_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> PacketHits {
        if rays.is_empty() || self.nodes.is_empty() {
            if O::WATCHES {
                for (ray, o) in rays.iter().zip(obs.iter_mut()) {
                    o.query(QueryKind::Packet, ray);
                }
            }
            return [None; PACKET];
        }
        // SAFETY: each `#[target_feature]` variant is called with the token (`cpu`) that proves
        // the CPU has its features.
        unsafe {
            match self.simd {
                #[cfg(target_arch = "x86_64")]
                Simd::Avx512(cpu) => self.packet_avx512(cpu, rays, prims, obs),
                #[cfg(target_arch = "x86_64")]
                Simd::Avx2(cpu) => self.packet_avx2(cpu, rays, prims, obs),
                _ => self.packet_portable(rays, prims, obs),
            }
        }
    }

    /// The portable packet traversal, kept out of line (see
    /// [`WideBvh::intersect_counted`]).
    #[inline(never)]
    fn packet_portable<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> PacketHits {
        self.packet_setup::<<Lanes<W> as NodeWidth<W>>::Portable, PortablePacketTest, P, O>(
            Baseline, Baseline, rays, prims, obs,
        )
    }

    /// [`WideBvh::intersect_packet`] compiled for AVX2, the packet's set-up included.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn packet_avx2<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx2,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> PacketHits {
        self.packet_setup::<<Lanes<W> as NodeWidth<W>>::Avx2, <Lanes<W> as PacketWidth<W>>::Avx2, P, O>(
            cpu.into(),
            cpu.into(),
            rays,
            prims,
            obs,
        )
    }

    /// [`WideBvh::intersect_packet`] compiled for AVX-512, the packet's set-up included.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
    fn packet_avx512<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx512,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> PacketHits {
        self.packet_setup::<<Lanes<W> as NodeWidth<W>>::Avx512, <Lanes<W> as PacketWidth<W>>::Avx512, P, O>(
            cpu.into(),
            cpu.into(),
            rays,
            prims,
            obs,
        )
    }

    /// The packet's set-up and traversal with leaf test `T` and inner-node test `Q` (on the
    /// CPU `leaf_cpu` and `node_cpu` vouch for); `rays` is not empty.
    #[inline(always)]
    fn packet_setup<T: NodeTest<W>, Q: PacketNodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        leaf_cpu: T::Cpu,
        node_cpu: Q::Cpu,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> PacketHits {
        let mut hits = [None; PACKET];
        let Some(p) = Q::packet(node_cpu, rays, self.reach) else {
            for ((hit, ray), o) in hits.iter_mut().zip(rays).zip(obs.iter_mut()) {
                *hit = self.intersect_counted(ray, prims, o);
            }
            return hits;
        };
        if O::WATCHES {
            for (ray, o) in rays.iter().zip(obs.iter_mut()) {
                o.query(QueryKind::Packet, ray);
            }
        }
        self.packet_with::<T, Q, P, O>(leaf_cpu, node_cpu, rays, &p, prims, &mut hits, obs);
        hits
    }

    /// The packet traversal of `p` (made of `rays`), with `T` for each ray's leaf tests and
    /// `Q` for the inner nodes (made with `leaf_cpu` and `node_cpu`): each ray's closest hit
    /// goes into `hits`, which the caller gives all `None` (the traversal writes a lane only
    /// where it finds a hit).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn packet_with<T: NodeTest<W>, Q: PacketNodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        leaf_cpu: T::Cpu,
        node_cpu: Q::Cpu,
        rays: &[Ray],
        p: &Packet,
        prims: &P,
        hits: &mut PacketHits,
        obs: &mut [O; PACKET],
    ) {
        let nodes = Q::new(node_cpu, p);
        let mut state = PacketRays::new(p, rays.len());
        let mut setups = NO_SETUPS;
        // The packet's farthest interval end, for the inner nodes' test and the stack.
        let mut t_far = p.t_far;

        let mut stack: Stack<Entry> = Stack::new();
        let mut current = Entry { child: ChildRef::ROOT, lanes: p.active, near: 0.0 };
        loop {
            if current.child.is_leaf() {
                self.packet_leaf::<T, P, O>(
                    leaf_cpu,
                    current.child,
                    current.lanes,
                    rays,
                    p,
                    prims,
                    obs,
                    (&mut state, &mut setups, &mut *hits),
                );
                t_far = state.t_far();
            } else {
                let node = &self.nodes[current.child.node_index() as usize];
                if O::WATCHES {
                    // Every ray of the entry pays for the node's test.
                    let mut lanes = current.lanes;
                    while lanes != 0 {
                        let lane = lanes.trailing_zeros() as usize;
                        lanes &= lanes - 1;
                        obs[lane].entered(current.child.node_index());
                        obs[lane].boxes_tested(W as u32);
                    }
                }
                let (near, mut mask) = nodes.test(p, node, t_far);
                let mut order = [Entry { child: ChildRef::EMPTY, lanes: 0, near: 0.0 }; W];
                let mut k = 0;
                let t_max_v = f32x8::new(state.t_max);
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let child = node.child[i];
                    let lanes = if child.is_leaf() {
                        nodes.leaf_lanes(p, node, i, t_max_v) & current.lanes
                    } else {
                        current.lanes
                    };
                    if lanes != 0 {
                        order[k] = Entry { child, lanes, near: near[i] };
                        self.prefetch(child);
                        k += 1;
                    }
                }
                if k > 0 {
                    current = descend(&mut order[..k], &mut stack, |e| e.near);
                    continue;
                }
            }
            loop {
                let Some(e) = stack.pop() else { return };
                if e.near <= t_far {
                    current = e;
                    break;
                }
            }
        }
    }
}

/// What a packet's traversal keeps of each ray: the end of its interval (its closest hit's
/// distance once it has one), and which of its rays have their leaf-test set-ups made (in the
/// [`LeafSetups`] beside it). The hits themselves go straight to the caller's array: kept
/// here, they were copied out at the end, a 64-byte load of the lanes' just-stored fields that
/// waited for the stores to retire (store forwarding fails across stores), and the caller's
/// reads of the copy waited again (3% of the teapot's packets of eight).
pub(super) struct PacketRays {
    t_max: [f32; PACKET],
    /// The lanes whose leaf set-ups are made.
    made: u32,
    /// Rays in the packet.
    n: usize,
}

/// The leaf-test set-ups of a packet's rays, each made when its ray first reaches a leaf
/// (rays that miss everything never need one); the state's `made` mask says which are. Kept
/// apart from [`PacketRays`], which is copied when made (an array of them for a tile): a
/// struct that held them was copied whole, uninitialised set-ups and all (a `memcpy` of 592
/// bytes a packet, eight a tile).
pub(super) type LeafSetups = [std::mem::MaybeUninit<RayLanes>; PACKET];

/// Leaf set-ups none of which is made yet.
pub(super) const NO_SETUPS: LeafSetups = [const { std::mem::MaybeUninit::uninit() }; PACKET];

impl PacketRays {
    /// No rays (for a tile's runs beyond its packets, or to be [`PacketRays::start`]ed).
    pub(super) const NONE: PacketRays = PacketRays { t_max: [f32::NEG_INFINITY; PACKET], made: 0, n: 0 };

    /// The rays of packet `p` of `n` rays, before the traversal.
    #[inline(always)]
    pub(super) fn new(p: &Packet, n: usize) -> PacketRays {
        let mut rays = PacketRays::NONE;
        rays.start(p, n);
        rays
    }

    /// Make these the rays of packet `p` of `n` rays, before the traversal.
    #[inline(always)]
    pub(super) fn start(&mut self, p: &Packet, n: usize) {
        self.t_max = p.t_end.to_array();
        self.made = 0;
        self.n = n;
    }

    /// The farthest interval end over the packet's rays.
    #[inline(always)]
    pub(super) fn t_far(&self) -> f32 {
        self.t_max[..self.n].iter().copied().fold(f32::NEG_INFINITY, greater)
    }
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W> + PacketWidth<W>,
{
    /// The rays `lanes` of packet `p` (made of `rays`) in leaf `leaf`: each ray's closest hit
    /// in `hits` (its distance in `state`) updated by the leaf's primitives (`T` the leaf
    /// test, on `leaf_cpu`). `singles` are the leaf set-ups of the same packet's rays, those
    /// made so far as `state.made` says (the three go together from the start of the
    /// traversal, the hits `None` then).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn packet_leaf<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        leaf_cpu: T::Cpu,
        leaf: ChildRef,
        lanes: u32,
        rays: &[Ray],
        p: &Packet,
        prims: &P,
        obs: &mut [O; PACKET],
        (state, singles, hits): (&mut PacketRays, &mut LeafSetups, &mut PacketHits),
    ) {
        let PacketRays { t_max, made, .. } = state;
        for lane in lanes_of(lanes) {
            if *made & 1 << lane == 0 {
                // From the inverse direction the packet has: no division.
                let inv = Vec3A::from_array(p.inv.map(|v| v.as_array()[lane]));
                singles[lane].write(RayLanes::with_inv(&rays[lane], inv));
                *made |= 1 << lane;
            }
            obs[lane].entered_leaf(leaf);
        }
        // SAFETY: every lane of the entry was written above, or earlier as `made` records
        // (`singles` have been this packet's set-ups since its state was started, `made` 0).
        let single = |lane: usize| unsafe { singles[lane].assume_init_ref() };
        let lead = lanes.trailing_zeros() as usize;
        let shared = leaf.is_packed()
            && lanes & (lanes - 1) != 0
            && lanes_of(lanes).all(|lane| single(lane).tri.axes == single(lead).tri.axes);
        if shared {
            // Rays of one origin with the same axes: each pair's corners are loaded and
            // translated once for all of them, and each ray goes on from there, pair by pair
            // as alone (the same tests in the same order, so the same hits).
            for pair in self.block_pairs(leaf) {
                let corners = T::pair_corners(leaf_cpu, single(lead), pair.0, pair.1);
                for lane in lanes_of(lanes) {
                    pair_closest::<W, T, O>(
                        leaf_cpu,
                        single(lane),
                        &corners,
                        pair,
                        rays[lane].t.min,
                        &mut obs[lane],
                        &mut t_max[lane],
                        &mut hits[lane],
                    );
                }
            }
        } else {
            for lane in lanes_of(lanes) {
                let one = OneRay { ray: &rays[lane], cpu: leaf_cpu, lanes: single(lane) };
                self.leaf_closest::<T, P, O>(leaf, &one, prims, &mut obs[lane], &mut t_max[lane], &mut hits[lane]);
            }
        }
    }
}

impl Packet {
    /// The children of `node` that some ray of the packet may hit within `[t_min, t_far]`,
    /// and a lower bound on their entry distances over the packet. Conservative: every child
    /// a ray's own slab test accepts is in the mask. Eight children at a time.
    #[inline(always)]
    fn test<const W: usize>(&self, node: &WideNode<W>, t_far: f32) -> ([f32; W], u32) {
        let mut near = [0.0; W];
        let mut mask = 0;
        for first in (0..W).step_by(8) {
            // Each row's eight floats as one copy (a lane-by-lane gather cost the 8-wide
            // packets 12%); the entry distances stored straight into their place.
            let rows = std::array::from_fn(|row| {
                f32x8::new(node.bounds[row][first..first + 8].try_into().expect("eight children"))
            });
            mask |= self.test8(&rows, t_far, &mut near[first..first + 8]) << first;
        }
        (near, mask)
    }

    /// [`Packet::test`] for eight children, whose bounds' rows are `rows`: their lower bounds
    /// on entry distances go to `near_out`, the mask is returned.
    #[inline(always)]
    fn test8(&self, rows: &[f32x8; 6], t_far: f32, near_out: &mut [f32]) -> u32 {
        let zero = f32x8::ZERO;
        // With the origin shared, `(plane - o) * inv` is, over the packet, smallest at the
        // smallest inverse direction when `plane - o >= 0` and at the largest otherwise, and
        // largest the other way round.
        // The single-ray test rounds differently (`p * inv - o * inv`, fused): its distances
        // are within 2^-22 of the bound's magnitude plus `slack` of these (see `slack`), so
        // each bound is widened by a little more than that.
        let bound = |row: Row, a: usize, lowest: bool| {
            let d = rows[row as usize] - f32x8::splat(self.o[a]);
            let (lo, hi) = (f32x8::splat(self.inv_lo[a]), f32x8::splat(self.inv_hi[a]));
            let ge = d.simd_ge(zero);
            let b = d * if lowest { ge.bitselect(lo, hi) } else { ge.bitselect(hi, lo) };
            let margin = b.abs() * f32x8::splat(PACKET_EPS) + f32x8::splat(self.slack[a]);
            if lowest { b - margin } else { b + margin }
        };
        let near = bound(self.near_row[0], 0, true)
            .fast_max(bound(self.near_row[1], 1, true))
            .fast_max(bound(self.near_row[2], 2, true).fast_max(f32x8::splat(self.t_min_lo)));
        // A finite end keeps empty slots (boxes at +inf) out, as in the single-ray test.
        let far = bound(self.far_row[0], 0, false)
            .fast_min(bound(self.far_row[1], 1, false))
            .fast_min(bound(self.far_row[2], 2, false).fast_min(f32x8::splat(t_far.min(f32::MAX))));
        near_out.copy_from_slice(near.as_array());
        near.simd_le(far).to_bitmask()
    }

    /// [`Packet::leaf_lanes`] in AVX2 intrinsics: the eight rays in one 256-bit vector, where
    /// the portable vectors take two halves and their fused multiply-subtract goes lane by lane
    /// (`fused_mul_sub` without `wide` fusing). The same operations in the same order, so the
    /// same lanes. A method, not a closure (see [`Packet::new_avx2`]).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn leaf_lanes_avx2<const W: usize>(&self, _: Avx2, node: &WideNode<W>, i: usize, t_max: f32x8) -> u32 {
        use std::arch::x86_64::*;
        // SAFETY: the token proves that the CPU has AVX2 and FMA, and the traversals that call
        // this are compiled for them; the transmutes are between eight floats and eight
        // floats.
        unsafe {
            let v = |x: f32x8| std::mem::transmute::<[f32; 8], __m256>(x.to_array());
            let (b, nr, fr) = (&node.bounds, self.near_row, self.far_row);
            let (inv, on, of) = (self.inv.map(v), self.oinv_near.map(v), self.oinv_far.map(v));
            let near = [
                _mm256_fmsub_ps(_mm256_set1_ps(b[nr[0] as usize][i]), inv[0], on[0]),
                _mm256_fmsub_ps(_mm256_set1_ps(b[nr[1] as usize][i]), inv[1], on[1]),
                _mm256_fmsub_ps(_mm256_set1_ps(b[nr[2] as usize][i]), inv[2], on[2]),
            ];
            let far = [
                _mm256_fmsub_ps(_mm256_set1_ps(b[fr[0] as usize][i]), inv[0], of[0]),
                _mm256_fmsub_ps(_mm256_set1_ps(b[fr[1] as usize][i]), inv[1], of[1]),
                _mm256_fmsub_ps(_mm256_set1_ps(b[fr[2] as usize][i]), inv[2], of[2]),
            ];
            let t_max = _mm256_min_ps(v(t_max), _mm256_set1_ps(f32::MAX));
            // `Slab::forward`: intervals from +0 on, compared as integers.
            let near_i = [_mm256_castps_si256(near[0]), _mm256_castps_si256(near[1]), _mm256_castps_si256(near[2])];
            let far_i = [_mm256_castps_si256(far[0]), _mm256_castps_si256(far[1]), _mm256_castps_si256(far[2])];
            let n = _mm256_max_epi32(
                _mm256_max_epi32(near_i[0], near_i[1]),
                _mm256_max_epi32(near_i[2], _mm256_castps_si256(v(self.t_min_pos))),
            );
            let f = _mm256_min_epi32(
                _mm256_min_epi32(far_i[0], far_i[1]),
                _mm256_min_epi32(far_i[2], _mm256_castps_si256(t_max)),
            );
            let miss = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(n, f))) as u32;
            let mut hit = !miss & 0xff & self.nonneg;
            if self.nonneg & self.active != self.active {
                // `Slab::lines`: float order for the rays that are lines.
                let n = _mm256_max_ps(_mm256_max_ps(near[0], near[1]), _mm256_max_ps(near[2], v(self.t_min)));
                let f = _mm256_min_ps(_mm256_min_ps(far[0], far[1]), _mm256_min_ps(far[2], t_max));
                hit |= _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(n, f)) as u32 & !self.nonneg;
            }
            hit & self.active
        }
    }

    /// The rays that hit child `i` of `node` within their own intervals, tested as the
    /// single-ray traversal tests a box (the same operations, lane by lane).
    #[inline(always)]
    fn leaf_lanes<const W: usize>(&self, node: &WideNode<W>, i: usize, t_max: f32x8) -> u32 {
        let t = |row: Row, a: usize, oinv: &[f32x8; 3]| {
            fused_mul_sub(f32x8::splat(node.bounds[row as usize][i]), self.inv[a], oinv[a])
        };
        let (on, of) = (&self.oinv_near, &self.oinv_far);
        let near = [t(self.near_row[0], 0, on), t(self.near_row[1], 1, on), t(self.near_row[2], 2, on)];
        let far = [t(self.far_row[0], 0, of), t(self.far_row[1], 1, of), t(self.far_row[2], 2, of)];
        let t_max = t_max.fast_min(f32x8::splat(f32::MAX));
        let mut hit = f32x8::forward(near, far, self.t_min_pos, t_max).1 & self.nonneg;
        if self.nonneg & self.active != self.active {
            // Lines among the rays: float order for them.
            hit |= f32x8::lines(near, far, self.t_min, t_max).1 & !self.nonneg;
        }
        hit & self.active
    }
}
