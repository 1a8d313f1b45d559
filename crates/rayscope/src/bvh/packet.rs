//! Closest hits for packets of up to eight rays that share an origin, such as a row of a
//! pinhole camera's pixels, traversing the 8-wide BVH once for all of them.
//!
//! Camera rays of neighbouring pixels visit nearly the same nodes. Traced one at a time, each
//! ray pays for those nodes' loads and, above all, for their data-dependent branches (which
//! children were hit, in which order); a packet pays once. Inner nodes are tested against the
//! whole packet at once by interval arithmetic (the children in the vector lanes, as for one
//! ray): with a shared origin, each slab distance `(plane - o) * inv` is bounded over the
//! packet by the smallest and largest inverse direction, so a child the packet test rejects is
//! missed by every ray. A leaf's box is then tested per ray, exactly as the single-ray
//! traversal tests it, and only the rays that hit it intersect its triangles, each with the
//! single-ray leaf code (`WideBvh::leaf_closest`).
//!
//! Each ray's closest hit is the one the single-ray traversal reports, bit for bit: the packet
//! may visit more inner nodes than a ray would (never fewer), leaves are culled by the same
//! per-ray test, and ties between equally distant primitives go to the lower slot whatever
//! the order leaves are visited in.

use wide::f32x8;

use super::wide::{
    Bvh8, EMPTY, LEAF_BIT, NodeTest, NodeWidth, OneRay, RayLanes, SimdLevel, Slab, Stack, WideNode, fused_mul_sub,
    planes, ray_is_finite, sort_far_to_near,
};
use super::{BvhHit, NoObserver, Primitives};
use crate::geometry::aabb::safe_inv_dir;
use crate::math::Vec3A;
use crate::ray::Ray;

/// Rays per packet.
pub const PACKET: usize = 8;

/// The closest hit of each ray of a packet (`None` beyond the rays given).
pub type PacketHits = [Option<BvhHit>; PACKET];

/// Whether `rays`, whose inverse directions are `invs`, can be traced as one packet: at most
/// [`PACKET`] finite rays with the same origin (bit for bit) and, per axis, the same direction
/// sign.
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
    child: u32,
    lanes: u32,
    near: f32,
}

/// The packet in the layouts its tests need.
struct Packet {
    /// Shared origin.
    o: Vec3A,
    /// Per axis, the rows of [`WideNode::bounds`] the rays enter and leave boxes by.
    near_row: [usize; 3],
    far_row: [usize; 3],
    /// Per axis, the smallest and largest inverse direction over the packet.
    inv_lo: [f32; 3],
    inv_hi: [f32; 3],
    /// Per axis, each ray's inverse direction (lanes beyond the packet repeat its last ray).
    inv: [f32x8; 3],
    /// Per axis, each ray's `o * inv`, rounded once (as the single-ray test has it).
    oinv: [f32x8; 3],
    /// Per axis, a bound on the rounding error of the single-ray test's `o * inv` term over
    /// the packet, which the inner nodes' test allows for.
    slack: [f32; 3],
    /// Each ray's interval start (finite).
    t_min: f32x8,
    /// The lanes whose interval starts at or after zero (tested in integer order), and their
    /// starts with -0 made +0.
    nonneg: u32,
    t_min_pos: f32x8,
    /// Smallest interval start over the packet.
    t_min_lo: f32,
    /// Rays in the packet.
    active: u32,
}

impl Bvh8 {
    /// The closest hit of each of up to [`PACKET`] `rays`, identical to
    /// [`crate::bvh::WideBvh::intersect`] on each: as one packet when they are finite, share
    /// their origin bit for bit and have one direction sign per axis, else one by one.
    pub fn intersect_packet<P: Primitives + ?Sized>(&self, rays: &[Ray], prims: &P) -> PacketHits {
        if rays.is_empty() || self.nodes.is_empty() {
            return [None; PACKET];
        }
        #[cfg(target_arch = "x86_64")]
        if self.simd_level() == SimdLevel::Avx2 {
            // SAFETY: the level is Avx2 only where the CPU has those features.
            return unsafe { self.packet_avx2(rays, prims) };
        }
        // SAFETY: the portable test needs no CPU feature.
        unsafe { self.packet_setup::<<super::wide::Lanes<8> as NodeWidth<8>>::Portable, P>(rays, prims) }
    }

    /// [`Bvh8::intersect_packet`] compiled for AVX2, the packet's set-up included.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn packet_avx2<P: Primitives + ?Sized>(&self, rays: &[Ray], prims: &P) -> PacketHits {
        // SAFETY: this function runs only where the CPU has AVX2.
        unsafe { self.packet_setup::<<super::wide::Lanes<8> as NodeWidth<8>>::Avx2, P>(rays, prims) }
    }

    /// The packet's set-up and traversal with node test `T` (the CPU must have its features);
    /// `rays` is not empty.
    #[inline(always)]
    unsafe fn packet_setup<T: NodeTest<8>, P: Primitives + ?Sized>(&self, rays: &[Ray], prims: &P) -> PacketHits {
        let mut hits = [None; PACKET];
        let last = rays.len() - 1;
        // Lanes beyond the packet repeat its last ray.
        let invs: [Vec3A; PACKET] = std::array::from_fn(|lane| safe_inv_dir(rays[lane.min(last)].dir));
        if !packet_compatible(rays, &invs) {
            for (hit, ray) in hits.iter_mut().zip(rays) {
                *hit = self.intersect(ray, prims);
            }
            return hits;
        }
        // SAFETY: the caller vouches for T's CPU features.
        unsafe { self.packet_with::<T, P>(rays, &invs, prims, &mut hits) };
        hits
    }

    /// The packet traversal, with `T` for each ray's leaf tests (the CPU must have its
    /// features). `rays` is non-empty and packet-compatible, `invs` their inverse directions
    /// (lanes beyond the packet repeating its last ray).
    #[inline(always)]
    unsafe fn packet_with<T: NodeTest<8>, P: Primitives + ?Sized>(
        &self,
        rays: &[Ray],
        invs: &[Vec3A; PACKET],
        prims: &P,
        hits: &mut PacketHits,
    ) {
        let n = rays.len();
        let ray = |lane: usize| &rays[lane.min(n - 1)];
        let axis = |a: usize| f32x8::new(invs.map(|v| v[a]));
        let inv = [axis(0), axis(1), axis(2)];
        let o = rays[0].origin;
        let oinv_axis = |a: usize| f32x8::new(invs.map(|v| o[a] * v[a]));
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
        let p = Packet {
            o,
            near_row,
            far_row,
            inv_lo,
            inv_hi,
            inv,
            oinv: [oinv_axis(0), oinv_axis(1), oinv_axis(2)],
            // Twice the worst rounding of `o * inv` (2^-24 relative), with room to spare.
            slack: std::array::from_fn(|a| o[a].abs() * inv_lo[a].abs().max(inv_hi[a].abs()) * (2.0f32).powi(-22)),
            nonneg: (0..PACKET).filter(|&lane| t_min_of(lane) >= 0.0).fold(0, |m, lane| m | 1 << lane),
            t_min_pos: f32x8::new(std::array::from_fn(|lane| t_min_of(lane) + 0.0)),
            t_min: f32x8::new(t_min),
            // Lanes beyond the packet repeat its last ray: the least over all is over the rays.
            t_min_lo: t_min.into_iter().fold(f32::INFINITY, lesser),
            active: (1u32 << n) - 1,
        };
        let mut t_max: [f32; PACKET] = std::array::from_fn(|lane| ray(lane).t.max);
        // The packet's farthest interval end, for the inner nodes' test and the stack.
        let mut t_far = t_max[..n].iter().copied().fold(f32::NEG_INFINITY, greater);

        // Each ray's leaf-test set-up, made when the ray first reaches a leaf (rays that miss
        // everything never need one).
        let mut singles: [std::mem::MaybeUninit<(T, RayLanes)>; PACKET] =
            [const { std::mem::MaybeUninit::uninit() }; PACKET];
        let mut made = 0u32;

        let mut stack: Stack<Entry> = Stack::new();
        let mut current = Entry { child: 0, lanes: p.active, near: 0.0 };
        loop {
            if current.child & LEAF_BIT != 0 {
                let mut lanes = current.lanes;
                while lanes != 0 {
                    let lane = lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    let r = &rays[lane];
                    if made & 1 << lane == 0 {
                        // SAFETY: the caller vouches for T's CPU features.
                        singles[lane].write((unsafe { T::new(r, invs[lane]) }, RayLanes::new(r)));
                        made |= 1 << lane;
                    }
                    // SAFETY: written above, or earlier as `made` records.
                    let (boxes, splat) = unsafe { singles[lane].assume_init_ref() };
                    let one = OneRay { ray: r, boxes, lanes: splat };
                    // SAFETY: as above.
                    unsafe {
                        self.leaf_closest(
                            current.child,
                            &one,
                            prims,
                            &mut NoObserver,
                            &mut t_max[lane],
                            &mut hits[lane],
                        )
                    };
                }
                t_far = t_max[..n].iter().copied().fold(f32::NEG_INFINITY, greater);
            } else {
                let node = &self.nodes[current.child as usize];
                let (near, mut mask) = p.test(node, t_far);
                let mut order = [Entry { child: EMPTY, lanes: 0, near: 0.0 }; 8];
                let mut k = 0;
                let t_max_v = f32x8::new(t_max);
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let child = node.child[i];
                    let lanes = if child & LEAF_BIT != 0 {
                        p.leaf_lanes(node, i, t_max_v) & current.lanes
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
                    // Nearest child next; the others pushed farthest first.
                    sort_far_to_near(&mut order[..k], |e| e.near);
                    for &e in &order[..k - 1] {
                        stack.push(e);
                    }
                    current = order[k - 1];
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

impl Packet {
    /// The children of `node` that some ray of the packet may hit within `[t_min, t_far]`,
    /// and a lower bound on their entry distances over the packet. Conservative: every child
    /// a ray's own slab test accepts is in the mask.
    #[inline(always)]
    fn test(&self, node: &WideNode<8>, t_far: f32) -> ([f32; 8], u32) {
        let zero = f32x8::ZERO;
        // With the origin shared, `(plane - o) * inv` is, over the packet, smallest at the
        // smallest inverse direction when `plane - o >= 0` and at the largest otherwise, and
        // largest the other way round.
        // The single-ray test rounds differently (`p * inv - o * inv`, fused): its distances
        // are within 2^-22 of the bound's magnitude plus `slack` of these (see `slack`), so
        // each bound is widened by a little more than that.
        let bound = |row: usize, a: usize, lowest: bool| {
            let d = f32x8::new(node.bounds[row]) - f32x8::splat(self.o[a]);
            let (lo, hi) = (f32x8::splat(self.inv_lo[a]), f32x8::splat(self.inv_hi[a]));
            let ge = d.simd_ge(zero);
            let b = d * if lowest { ge.bitselect(lo, hi) } else { ge.bitselect(hi, lo) };
            let margin = b.abs() * f32x8::splat((2.0f32).powi(-21)) + f32x8::splat(self.slack[a]);
            if lowest { b - margin } else { b + margin }
        };
        let near = bound(self.near_row[0], 0, true)
            .fast_max(bound(self.near_row[1], 1, true))
            .fast_max(bound(self.near_row[2], 2, true).fast_max(f32x8::splat(self.t_min_lo)));
        // A finite end keeps empty slots (boxes at +inf) out, as in the single-ray test.
        let far = bound(self.far_row[0], 0, false)
            .fast_min(bound(self.far_row[1], 1, false))
            .fast_min(bound(self.far_row[2], 2, false).fast_min(f32x8::splat(t_far.min(f32::MAX))));
        (near.to_array(), near.simd_le(far).to_bitmask())
    }

    /// The rays that hit child `i` of `node` within their own intervals, tested as the
    /// single-ray traversal tests a box (the same operations, lane by lane).
    #[inline(always)]
    fn leaf_lanes(&self, node: &WideNode<8>, i: usize, t_max: f32x8) -> u32 {
        let t = |row: usize, a: usize| fused_mul_sub(f32x8::splat(node.bounds[row][i]), self.inv[a], self.oinv[a]);
        let near = [t(self.near_row[0], 0), t(self.near_row[1], 1), t(self.near_row[2], 2)];
        let far = [t(self.far_row[0], 0), t(self.far_row[1], 1), t(self.far_row[2], 2)];
        let t_max = t_max.fast_min(f32x8::splat(f32::MAX));
        let mut hit = f32x8::forward(near, far, self.t_min_pos, t_max).1 & self.nonneg;
        if self.nonneg & self.active != self.active {
            // Lines among the rays: float order for them.
            hit |= f32x8::lines(near, far, self.t_min, t_max).1 & !self.nonneg;
        }
        hit & self.active
    }
}
