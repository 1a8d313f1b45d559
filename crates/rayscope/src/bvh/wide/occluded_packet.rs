//! Any-hit for packets of up to [`PACKET`] rays with origins of their own, such as the shadow
//! rays from the points a row of camera rays hit towards one point light, traversing the wide
//! tree once for all of them.
//!
//! Each ray keeps its own node test, the single ray's ([`NodeTest`]), so each ray enters
//! exactly the nodes and leaves it enters alone and meets the same triangles in the same
//! test: its answer is [`WideBvh::occluded`]'s, bit for bit. What the rays share is the walk:
//! a node is fetched and branched on once for every ray that reaches it (a ray's mask of hit
//! children is one test of the node's boxes in registers), and a leaf's blocks once for every
//! ray that enters it. Neighbouring shadow rays that converge on one light enter nearly the
//! same nodes, so the loads and unpredictable branches that dominate single rays (a
//! 448-byte node per step) are paid once per packet. Where the rays' directions have one sign
//! per axis (nearly every packet of shadow rays), they enter and leave boxes by the same
//! planes: a node's six rows are loaded once and each ray's test goes on from them in
//! registers ([`NodeTest::test_planes`], the same arithmetic). Likewise in a leaf, each pair of
//! blocks is loaded once along the rays' axes (the dominant components of their directions,
//! nearly always shared) and each ray translates it by its own origin
//! ([`NodeTest::pair_rows`], [`NodeTest::translated`]). A ray leaves the packet as soon as it
//! is blocked.
//!
//! (Testing the inner nodes once for the packet instead, by interval arithmetic over the
//! rays' origins and directions as camera packets do, entered a third more nodes and paid a
//! per-ray box test for each leaf child: 20% slower on the dragon's shadow rays.)

use std::mem::MaybeUninit;

use super::kernels::PortableTest;
#[cfg(target_arch = "x86_64")]
use super::kernels::{Avx2Test, Avx512Test};
use super::kernels::{Lanes, NodeTest, NodeWidth, RayLanes};
use super::packet::{PACKET, lanes_of};
use super::simd::Baseline;
#[cfg(target_arch = "x86_64")]
use super::simd::{Avx2, Avx512};
use super::stack::Stack;
use super::traverse::{range_occluded, ray_is_finite};
use super::{ChildRef, Simd, WideBvh};
use crate::bvh::{NoObserver, Primitives, QueryKind, TraversalObserver};
use crate::geometry::aabb::safe_inv_dir;
use crate::math::Vec3A;
use crate::ray::Ray;

/// Bit `i` of a byte moved to bit `8 i` of a word, for every byte: a row of the packet's
/// ray-by-child bit matrix spread so that its transpose is an OR of shifts ([`ByChild`]).
const SPREAD: [u64; 256] = {
    let mut t = [0u64; 256];
    let mut x = 0;
    while x < 256 {
        let mut i = 0;
        while i < 8 {
            t[x] |= ((x as u64 >> i) & 1) << (8 * i);
            i += 1;
        }
        x += 1;
    }
    t
};

/// For each of a node's (up to 16) children, the rays of the packet whose test hit it: byte
/// `i % 8` of word `i / 8` holds child `i`'s rays. Each ray's child mask goes in as two
/// table lookups and shifts, where reading a child's rays from the masks took a shift, a
/// mask and an OR per ray for every child entered.
#[derive(Clone, Copy, Default)]
struct ByChild([u64; 2]);

// A ray a bit of a byte, a child a byte: at most eight rays and sixteen children.
const _: () = assert!(PACKET <= 8);

impl ByChild {
    /// Add ray `r`'s mask of hit children.
    #[inline(always)]
    fn add(&mut self, r: usize, mask: u32) {
        self.0[0] |= SPREAD[(mask & 0xff) as usize] << r;
        self.0[1] |= SPREAD[(mask >> 8 & 0xff) as usize] << r;
    }

    /// The rays whose tests hit child `i`.
    #[inline(always)]
    fn rays(&self, i: usize) -> u32 {
        (self.0[i / 8] >> (8 * (i % 8)) & 0xff) as u32
    }
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// Which of `rays` (at most [`PACKET`]) something blocks within their intervals: bit `i`
    /// is [`WideBvh::occluded`] of `rays[i]`.
    #[inline]
    pub fn occluded_packet<P: Primitives + ?Sized>(&self, rays: &[Ray], prims: &P) -> u32 {
        self.occluded_packet_counted(rays, prims, &mut [NoObserver; PACKET])
    }

    /// [`WideBvh::occluded_packet`], reporting each ray's traversal to its observer in `obs`:
    /// exactly what [`WideBvh::occluded_counted`] reports for the ray alone (the same nodes
    /// and leaves, in the same order), as each ray takes its own node tests and children in
    /// the single ray's order.
    #[inline]
    pub fn occluded_packet_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> u32 {
        assert!(rays.len() <= PACKET, "a packet holds at most {PACKET} rays");
        for (ray, obs) in rays.iter().zip(obs.iter_mut()) {
            obs.query(QueryKind::AnyHit, ray);
        }
        if self.nodes.is_empty() || rays.is_empty() {
            return 0;
        }
        // SAFETY: each `#[target_feature]` variant is called with the token (`cpu`) that proves
        // the CPU has its features.
        unsafe {
            match self.simd {
                #[cfg(target_arch = "x86_64")]
                Simd::Avx512(cpu) => self.occluded_packet_avx512(cpu, rays, prims, obs),
                #[cfg(target_arch = "x86_64")]
                Simd::Avx2(cpu) => self.occluded_packet_avx2(cpu, rays, prims, obs),
                _ => self.occluded_packet_portable(rays, prims, obs),
            }
        }
    }

    /// The portable packet any-hit traversal, out of line (as the single ray's).
    #[inline(never)]
    fn occluded_packet_portable<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> u32 {
        self.any_packet::<PortableTest<W>, P, O>(Baseline, rays, prims, obs)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn occluded_packet_avx2<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx2,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> u32 {
        self.any_packet::<Avx2Test<W>, P, O>(cpu.into(), rays, prims, obs)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
    fn occluded_packet_avx512<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx512,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> u32 {
        self.any_packet::<Avx512Test<W>, P, O>(cpu.into(), rays, prims, obs)
    }

    /// [`WideBvh::occluded_packet`] with node test `T` (on the CPU `cpu` proves). The packet
    /// is compiled for the forward slab test only (`t_min >= 0`, as every shadow ray's): a ray
    /// that starts before its origin goes alone.
    ///
    /// A node's hit children are entered from the highest slot down, as the single ray's
    /// (`WideBvh::any`) are: each ray then meets its own nodes and leaves in its own order,
    /// whichever other rays share them, and stops at the blocker it stops at alone.
    #[inline(always)]
    fn any_packet<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: T::Cpu,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> u32 {
        let mut blocked = 0u32;
        let mut active = 0u32;
        for (i, ray) in rays.iter().enumerate() {
            if !ray_is_finite(ray) {
                continue;
            }
            if ray.t.min >= 0.0 {
                active |= 1 << i;
            } else if self.any::<T, P, O, false>(cpu, ray, prims, &mut obs[i]) {
                blocked |= 1 << i;
            }
        }
        if active == 0 {
            return blocked;
        }
        // Each active ray's node test and triangle set-up, made in a loop: in a closure (as
        // `array::from_fn` takes) they were compiled without this function's CPU features,
        // their intrinsics left as calls.
        let mut tests: [MaybeUninit<T>; PACKET] = [const { MaybeUninit::uninit() }; PACKET];
        let mut lanes: [MaybeUninit<RayLanes>; PACKET] = [const { MaybeUninit::uninit() }; PACKET];
        let (mut t_min, mut t_max) = ([0.0; PACKET], [0.0; PACKET]);
        // Whether the rays' directions have one sign per axis (all but a few packets of
        // neighbouring shadow rays): they then enter and leave boxes by the same planes, which
        // each node loads once for all of them.
        let mut octants = 0u32;
        for i in lanes_of(active) {
            let ray = &rays[i];
            let inv = safe_inv_dir(ray.dir);
            octants |= 1 << inv.cmplt(Vec3A::ZERO).bitmask();
            tests[i].write(T::new(cpu, ray, inv, self.reach));
            lanes[i].write(RayLanes::with_inv(ray, inv));
            (t_min[i], t_max[i]) = (ray.t.min, ray.t.max);
        }
        let one_octant = octants.is_power_of_two();
        let mut stack: Stack<(ChildRef, u32)> = Stack::new();
        let (mut current, mut entering) = (ChildRef::ROOT, active);
        loop {
            // Rays blocked since the entry was pushed go no further.
            entering &= !blocked;
            if entering != 0 {
                if O::WATCHES {
                    for r in lanes_of(entering) {
                        if current.is_leaf() {
                            obs[r].entered_leaf(current);
                        } else {
                            obs[r].entered(current.node_index());
                            obs[r].boxes_tested(W as u32);
                        }
                    }
                }
                if current.is_packed() {
                    let mut open = entering;
                    // SAFETY: every ray of `entering` is in `active`, whose lanes were all
                    // written above.
                    let axes = unsafe { lanes[entering.trailing_zeros() as usize].assume_init_ref() }.tri.axes;
                    for (a, b, pair_lanes) in self.block_pairs(current) {
                        // The pair's rows along the first ray's axes, loaded once for the rays
                        // that share them (nearly all), each translating them by its origin.
                        let rows = T::pair_rows(cpu, axes, a, b);
                        for r in lanes_of(open) {
                            // SAFETY: as for `axes`.
                            let lanes = unsafe { lanes[r].assume_init_ref() };
                            let corners = if lanes.tri.axes == axes {
                                T::translated(cpu, &rows, lanes.tri.origin)
                            } else {
                                T::pair_corners(cpu, lanes, a, b)
                            };
                            if T::intersect_corners(cpu, lanes, &corners, t_min[r], t_max[r]).0 & pair_lanes != 0 {
                                open &= !(1 << r);
                            }
                        }
                        if open == 0 {
                            break;
                        }
                    }
                    blocked |= entering & !open;
                } else if current.is_leaf() {
                    let range = self.ranges[current.range_index()];
                    for r in lanes_of(entering) {
                        if range_occluded(range, &rays[r], prims) {
                            blocked |= 1 << r;
                        }
                    }
                } else {
                    let node = &self.nodes[current.node_index() as usize];
                    let mut by_child = ByChild::default();
                    let mut hit = 0u32;
                    // Rays of one octant share the node's planes: loaded once, by the first.
                    let shared = if one_octant {
                        // SAFETY: every ray of `entering` is in `active`, whose tests were all
                        // written above.
                        Some(unsafe { tests[entering.trailing_zeros() as usize].assume_init_ref() }.planes(node))
                    } else {
                        None
                    };
                    for r in lanes_of(entering) {
                        // SAFETY: as for `shared`.
                        let test = unsafe { tests[r].assume_init_ref() };
                        let (_, m) = match &shared {
                            Some(planes) => test.test_planes::<true>(planes, t_min[r], t_max[r]),
                            None => test.test::<true>(node, t_min[r], t_max[r]),
                        };
                        by_child.add(r, m);
                        hit |= m;
                    }
                    if hit != 0 {
                        // The highest child hit is entered next, the others pushed from the
                        // lowest up (so popped from the highest down).
                        let first = (31 - hit.leading_zeros()) as usize;
                        for i in lanes_of(hit & !(1 << first)) {
                            self.prefetch(node.child[i]);
                            stack.push((node.child[i], by_child.rays(i)));
                        }
                        current = node.child[first];
                        entering = by_child.rays(first);
                        continue;
                    }
                }
            }
            match stack.pop() {
                Some((c, e)) => (current, entering) = (c, e),
                None => return blocked,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `ByChild` transposes the rays' child masks: child `i`'s rays are the rays whose mask
    /// has bit `i`, for masks of every pattern (a xorshift sequence of them) and every child.
    #[test]
    fn by_child_is_the_transpose_of_the_rays_masks() {
        let mut x = 0x9e37_79b9_u32;
        for _ in 0..2000 {
            let mut masks = [0u32; PACKET];
            let mut by_child = ByChild::default();
            for (r, m) in masks.iter_mut().enumerate() {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                *m = x & 0xffff;
                by_child.add(r, *m);
            }
            for i in 0..16 {
                let want = masks.iter().enumerate().fold(0, |acc, (r, m)| acc | ((m >> i) & 1) << r);
                assert_eq!(by_child.rays(i), want, "child {i} of {masks:x?}");
            }
        }
    }
}
