//! Closest-hit and any-hit traversal of a wide tree, one ray at a time: the dispatch to the
//! detected instruction set, the walk down the tree with its fixed stack and prefetches, and
//! the leaf tests (which packets share).

use super::kernels::PortableTest;
#[cfg(target_arch = "x86_64")]
use super::kernels::{Avx2Test, Avx512Test};
use super::kernels::{Lanes, NodeTest, NodeWidth, RayLanes};
use super::layout::{LeafRange, Tri4, WideNode};
use super::simd::Baseline;
#[cfg(target_arch = "x86_64")]
use super::simd::{Avx2, Avx512};
use super::stack::Stack;
use super::{ChildRef, Simd, WideBvh};
use crate::bvh::{BvhHit, NoObserver, Primitives, QueryKind, TraversalObserver};
use crate::geometry::PrimHit;
use crate::geometry::aabb::safe_inv_dir;
use crate::ray::Ray;

#[inline(always)]
pub(super) fn ray_is_finite(ray: &Ray) -> bool {
    ray.origin.is_finite() && ray.dir.is_finite() && !ray.t.min.is_nan() && !ray.t.max.is_nan()
}

/// One ray made ready for leaf tests: the ray, its node test (which also runs the two-block
/// triangle test) and its four-lane splat.
pub(super) struct OneRay<'a, C> {
    pub(super) ray: &'a Ray,
    pub(super) cpu: C,
    pub(super) lanes: &'a RayLanes,
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

/// One pair of a packed leaf's blocks (`a`, `b`, and the mask of their lanes that hold
/// triangles, as [`WideBvh::block_pairs`] gives them) against one ray (`r`, from `t_min` to
/// the closest hit so far, `t_max` and `best`), from the pair's corners for the ray (or for a
/// ray of the same origin and axes): the single ray's leaves and the packets' leaves share it.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn pair_closest<const W: usize, T: NodeTest<W>, O: TraversalObserver>(
    cpu: T::Cpu,
    r: &RayLanes,
    corners: &T::Corners,
    (a, b, lanes): (&Tri4, &Tri4, u32),
    t_min: f32,
    obs: &mut O,
    t_max: &mut f32,
    best: &mut Option<BvhHit>,
) {
    obs.prim_tested();
    if lanes == 0xff {
        obs.prim_tested();
    }
    let (mask, t, u, v) = T::intersect_corners(cpu, r, corners, t_min, *t_max);
    let hits = Hits { mask: mask & lanes, t: &t, u: &u, v: &v };
    hits.take(|lane| if lane < 4 { a.slot[lane] } else { b.slot[lane - 4] }, t_max, best);
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

/// Whether a primitive of `range` blocks `ray` within its interval: out of line, as
/// [`WideBvh::range_closest`] is (the any-hit traversal's range leaves and the shadow groups'
/// leaves share it).
#[inline(never)]
pub(super) fn range_occluded<P: Primitives + ?Sized>(range: LeafRange, ray: &Ray, prims: &P) -> bool {
    let LeafRange { start, count } = range;
    (start..start + count).any(|slot| prims.intersect(slot, ray, ray.t.min, ray.t.max).is_some())
}

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

/// The nearest of a node's entered children `order` (at least one, in lane order), to go
/// into next; the others pushed on `stack` farthest first, so that they pop nearest first.
/// Packets and tiles both descend with it.
#[inline(always)]
pub(super) fn descend<E: Copy>(order: &mut [E], stack: &mut Stack<E>, near: impl Fn(&E) -> f32) -> E {
    sort_far_to_near(order, near);
    let last = order.len() - 1;
    for &e in &order[..last] {
        stack.push(e);
    }
    order[last]
}

/// Put the hit children `hit` of a node (references `child`, entry distances `near`) into
/// `order` farthest first, calling `visit` on each as it is placed; returns their number.
///
/// Each child goes straight to its place by its rank, the number of hit children farther
/// than it or as far in a lower lane (two vector compares, [`NodeTest::farther_and_tied`]):
/// no branch on the distances, which an insertion sort mispredicted on incoherent rays. That
/// is the order [`sort_far_to_near`] gives the children listed by lane (it is stable), and
/// without NaN distances the ranks are `0..k`, each once; with one, the insertion sort
/// orders them as before.
#[inline(always)]
pub(super) fn far_to_near<const W: usize, T: NodeTest<W>>(
    boxes: &T,
    child: &[ChildRef; W],
    near: &[f32; W],
    hit: u32,
    order: &mut [(ChildRef, f32); W],
    mut visit: impl FnMut(ChildRef),
) -> usize {
    let k = hit.count_ones() as usize;
    let mut placed = 0u32;
    let mut left = hit;
    while left != 0 {
        let i = left.trailing_zeros() as usize;
        left &= left - 1;
        let (farther, tied) = boxes.farther_and_tied(near, near[i]);
        let rank = (hit & (farther | tied & ((1 << i) - 1))).count_ones() as usize;
        placed |= 1 << rank;
        order[rank] = (child[i], near[i]);
        visit(child[i]);
    }
    if u64::from(placed) != (1u64 << k) - 1 {
        let mut left = hit;
        for e in &mut order[..k] {
            let i = left.trailing_zeros() as usize;
            left &= left - 1;
            *e = (child[i], near[i]);
        }
        sort_far_to_near(&mut order[..k], |e| e.1);
    }
    k
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// A packed leaf's blocks two at a time, with the lanes of the pair that are the leaf's:
    /// `0xff`, or `0x0f` for a last odd block, paired with the block after it (or an empty
    /// one at the end of the array) so that every step is one eight-lane test.
    #[inline(always)]
    pub(super) fn block_pairs(&self, leaf: ChildRef) -> impl Iterator<Item = (&Tri4, &Tri4, u32)> {
        let range = leaf.packed_blocks();
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
    pub(super) fn prefetch(&self, child: ChildRef) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let (p, lines): (*const i8, usize) = if child.is_packed() {
                (self.blocks.as_ptr().wrapping_add(child.packed_blocks().start).cast(), 5)
            } else if !child.is_leaf() {
                (self.nodes.as_ptr().wrapping_add(child.node_index() as usize).cast(), size_of::<WideNode<W>>() / 64)
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
    pub(super) fn prefetch_branchless(&self, child: ChildRef) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let node = self.nodes.as_ptr().wrapping_add(child.index_bits()) as *const i8;
            let block = self.blocks.as_ptr().wrapping_add(child.first_block()) as *const i8;
            let p = if child.is_packed() {
                block
            } else if !child.is_leaf() {
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
        obs.query(QueryKind::ClosestHit, ray);
        // NaN rays would pass every slab test (SIMD min/max pass NaN through); they hit nothing.
        if self.nodes.is_empty() || !ray_is_finite(ray) {
            return None;
        }
        // SAFETY: each `#[target_feature]` variant is called with the token (`cpu`) that proves
        // the CPU has its features.
        unsafe {
            match self.simd {
                #[cfg(target_arch = "x86_64")]
                Simd::Avx512(cpu) => self.intersect_avx512(cpu, ray, prims, obs),
                #[cfg(target_arch = "x86_64")]
                Simd::Avx2(cpu) => self.intersect_avx2(cpu, ray, prims, obs),
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
        self.intersect_with::<PortableTest<W>, P, O>(Baseline, ray, prims, obs)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn intersect_avx2<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx2,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        self.intersect_with::<Avx2Test<W>, P, O>(cpu.into(), ray, prims, obs)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
    fn intersect_avx512<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx512,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        self.intersect_with::<Avx512Test<W>, P, O>(cpu.into(), ray, prims, obs)
    }

    /// The closest-hit traversal with node test `T` (on the CPU `cpu` proves), compiled once
    /// for each order of the slab test and chosen per ray.
    #[inline(always)]
    fn intersect_with<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: T::Cpu,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        if ray.t.min >= 0.0 {
            self.closest::<T, P, O, true>(cpu, ray, prims, obs)
        } else {
            self.closest::<T, P, O, false>(cpu, ray, prims, obs)
        }
    }

    /// [`WideBvh::intersect_with`] in one order of the slab test (`FORWARD`: `t_min >= 0`).
    #[inline(always)]
    fn closest<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver, const FORWARD: bool>(
        &self,
        cpu: T::Cpu,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        let inv = safe_inv_dir(ray.dir);
        let boxes = T::new(cpu, ray, inv, self.reach);
        let lanes = RayLanes::with_inv(ray, inv);
        let (t_min, mut t_max) = (ray.t.min, ray.t.max);
        let mut best = None;
        // Entries: a child reference and its entry distance, so that entries a closer hit
        // has since ruled out are dropped when popped.
        let mut stack: Stack<(ChildRef, f32)> = Stack::new();
        let mut current = ChildRef::ROOT;
        loop {
            if current.is_leaf() {
                obs.entered_leaf(current);
                let one = OneRay { ray, cpu, lanes: &lanes };
                self.leaf_closest::<T, P, O>(current, &one, prims, obs, &mut t_max, &mut best);
            } else {
                let node = &self.nodes[current.node_index() as usize];
                obs.entered(current.node_index());
                obs.boxes_tested(W as u32);
                let (near, mut mask) = boxes.test::<FORWARD>(node, t_min, t_max);
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
                    let mut order = [(ChildRef::ROOT, 0.0f32); W];
                    let hit = mask | 1 << first;
                    let k = far_to_near(&boxes, &node.child, &near, hit, &mut order, |c| self.prefetch(c));
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
    #[inline(always)]
    pub(super) fn leaf_closest<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        leaf: ChildRef,
        one: &OneRay<'_, T::Cpu>,
        prims: &P,
        obs: &mut O,
        t_max: &mut f32,
        best: &mut Option<BvhHit>,
    ) {
        let t_min = one.ray.t.min;
        if leaf.is_packed() {
            // Blocks two at a time (one 8-lane test where the CPU has AVX2), a leaf's last odd
            // block with whatever block follows it, its lanes masked off: leaves of one, two,
            // three blocks all run the same code, where a separate single-block test after the
            // pairs was a branch the leaf's size decided (and mispredicted). A lane beyond a
            // closer hit in the pair's first block is dropped by `closer` rather than by the
            // test: the same outcome as testing block by block.
            for pair in self.block_pairs(leaf) {
                let corners = T::pair_corners(one.cpu, one.lanes, pair.0, pair.1);
                pair_closest::<W, T, O>(one.cpu, one.lanes, &corners, pair, t_min, obs, t_max, best);
            }
        } else {
            self.range_closest(leaf, one.ray, prims, obs, t_max, best);
        }
    }

    /// [`WideBvh::leaf_closest`] for a range leaf (spheres, or triangles the packing left
    /// out), out of line: inlined, the primitives' own per-ray set-up (the triangle test's
    /// shear, a sphere's `|d|^2`) was hoisted out of the traversal loop and paid by every ray,
    /// most of which never meet a range leaf.
    #[inline(never)]
    fn range_closest<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        leaf: ChildRef,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
        t_max: &mut f32,
        best: &mut Option<BvhHit>,
    ) {
        let LeafRange { start, count } = self.ranges[leaf.range_index()];
        for slot in start..start + count {
            obs.prim_tested();
            if let Some(hit) = prims.intersect(slot, ray, ray.t.min, *t_max) {
                closer(BvhHit { slot, hit }, t_max, best);
            }
        }
    }

    /// Whether anything blocks `ray` within its interval; stops at the first hit found.
    #[inline]
    pub fn occluded<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        self.occluded_counted(ray, prims, &mut NoObserver)
    }

    /// [`WideBvh::occluded`], reporting the traversal to `obs`.
    #[inline]
    pub fn occluded_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> bool {
        obs.query(QueryKind::AnyHit, ray);
        if self.nodes.is_empty() || !ray_is_finite(ray) {
            return false;
        }
        // SAFETY: each `#[target_feature]` variant is called with the token (`cpu`) that proves
        // the CPU has its features.
        unsafe {
            match self.simd {
                #[cfg(target_arch = "x86_64")]
                Simd::Avx512(cpu) => self.occluded_avx512(cpu, ray, prims, obs),
                #[cfg(target_arch = "x86_64")]
                Simd::Avx2(cpu) => self.occluded_avx2(cpu, ray, prims, obs),
                _ => self.occluded_portable(ray, prims, obs),
            }
        }
    }

    /// The portable any-hit traversal, kept out of line (see [`WideBvh::intersect_counted`]).
    #[inline(never)]
    fn occluded_portable<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> bool {
        self.occluded_with::<PortableTest<W>, P, O>(Baseline, ray, prims, obs)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn occluded_avx2<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx2,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> bool {
        self.occluded_with::<Avx2Test<W>, P, O>(cpu.into(), ray, prims, obs)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
    fn occluded_avx512<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx512,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> bool {
        self.occluded_with::<Avx512Test<W>, P, O>(cpu.into(), ray, prims, obs)
    }

    /// The any-hit traversal with node test `T` (on the CPU `cpu` proves), compiled once for
    /// each order of the slab test and chosen per ray.
    #[inline(always)]
    fn occluded_with<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: T::Cpu,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> bool {
        if ray.t.min >= 0.0 {
            self.any::<T, P, O, true>(cpu, ray, prims, obs)
        } else {
            self.any::<T, P, O, false>(cpu, ray, prims, obs)
        }
    }

    /// [`WideBvh::occluded_with`] in one order of the slab test (`FORWARD`: `t_min >= 0`).
    #[inline(always)]
    pub(super) fn any<T: NodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver, const FORWARD: bool>(
        &self,
        cpu: T::Cpu,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> bool {
        let inv = safe_inv_dir(ray.dir);
        let boxes = T::new(cpu, ray, inv, self.reach);
        let lanes = RayLanes::with_inv(ray, inv);
        let (t_min, t_max) = (ray.t.min, ray.t.max);
        let mut stack: Stack<ChildRef> = Stack::new();
        let mut current = ChildRef::ROOT;
        loop {
            if current.is_packed() {
                obs.entered_leaf(current);
                for (a, b, pair_lanes) in self.block_pairs(current) {
                    if T::intersect_pair(cpu, &lanes, a, b, t_min, t_max).0 & pair_lanes != 0 {
                        return true;
                    }
                }
            } else if current.is_leaf() {
                obs.entered_leaf(current);
                if range_occluded(self.ranges[current.range_index()], ray, prims) {
                    return true;
                }
            } else {
                let node = &self.nodes[current.node_index() as usize];
                obs.entered(current.node_index());
                obs.boxes_tested(W as u32);
                let (_, mut mask) = boxes.test::<FORWARD>(node, t_min, t_max);
                if mask != 0 {
                    // Any order finds a blocker. The highest child hit is visited next, the
                    // others pushed from the lowest up (popped from the highest down): the
                    // order a packet's rays keep (`WideBvh::any_packet`), so that a shadow
                    // ray meets the same nodes in a packet as alone.
                    let first = (31 - mask.leading_zeros()) as usize;
                    mask &= !(1 << first);
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
}
