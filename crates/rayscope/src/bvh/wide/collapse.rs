//! Collapsing the binary BVH into a wide one, choosing by the surface area heuristic which
//! binary nodes become wide nodes, which subtrees become leaves, and which nodes disappear
//! into their parents.
//!
//! A greedy collapse (each wide node opens its largest children until it has `W`) leaves
//! many nodes half empty: a binary node whose two children are leaves becomes a wide node of
//! two. Here a dynamic programme over the binary tree (Ylitie, Karras and Laine, "Efficient
//! Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", HPG 2017, section 4.1)
//! finds, for every binary node and every number of slots `i <= W`, the cheapest way to hang
//! its subtree from a parent as at most `i` children, each a wide node or a leaf holding a
//! whole subtree's primitives. On the dragon it makes half as many nodes, most of them full.

use super::kernels::{Lanes, NodeWidth};
use super::layout::{LeafRange, Tri4, WideNode};
use super::{ChildRef, Simd, WideBvh};
use bytemuck::Zeroable;
use wide::f32x8;

use crate::bvh::{Bvh, MAX_DEPTH, Primitives};
use crate::pages;

/// Binary trees with more nodes than this collapse on several threads.
const PARALLEL_COLLAPSE: usize = 1 << 13;

/// Cost of visiting a wide node, relative to one triangle test of a leaf (eight triangles,
/// two [`Tri4`] blocks, in one AVX2 test; the same cost unit as the SAH build's).
const NODE_COST: f32 = 1.5;

/// Most triangles the collapse gathers into one leaf: four two-block tests.
const LEAF_TRIANGLES: u32 = 16;

/// Triangle tests of a packed leaf of `count` triangles: eight at a time.
fn leaf_tests(count: u32) -> f32 {
    count.div_ceil(8) as f32
}

/// A child of a wide node being made: a binary node, as a leaf of its whole subtree's
/// primitives or as a wide node of its own.
#[derive(Clone, Copy, Debug, Default)]
struct Kid {
    /// Index of the binary node.
    bin: usize,
    /// Whether its subtree becomes one leaf.
    leaf: bool,
}

/// The least cost of a binary node's subtree hung from a parent as at most `i` children, at
/// index `i - 1`. Costs are surface areas times test counts, as in the SAH. Only the planning
/// reads them, each once (its parent's decision), so they live on a stack while a subtree is
/// planned, not in the plan: in it they were 70% of its bytes (the plan's 92 bytes a binary
/// node at `W = 16` were the collapse's peak memory, about 46 bytes a triangle).
type Costs<const W: usize> = [f32; W];

/// The collapse's decisions for one binary node.
#[derive(Clone, Copy, Debug)]
struct Decision<const W: usize> {
    /// How that least cost is reached: at index 0 (one child), 1 if the subtree is a leaf and
    /// 0 if it is a wide node; at index `i - 1 >= 1`, 0 if `i - 1` children do as well, else
    /// the number of children given to the left subtree (the right one takes the rest).
    choice: [u8; W],
    /// For a node made a wide node: the number of its `W` slots given to the left subtree.
    split: u8,
    /// Whether the subtree holds only static triangles (packable into blocks); other leaves
    /// are kept as the build made them.
    packable: bool,
    /// The primitive slots of the node's subtree (contiguous: the build partitions in place).
    range: LeafRange,
}

// SAFETY: bytes, a `bool` and two `u32`s: all-zero bits are a decision (no children, not
// packable, an empty range).
unsafe impl<const W: usize> Zeroable for Decision<W> {}

/// For `j` in `1..=W` slots (at index `j - 1`), the least cost of a left subtree in `k` of
/// them and a right one in `j - k`, and the least such `k` (`l` and `r` give each subtree's
/// least cost in `i` slots at index `i - 1`). Every `k` at once for eight `j`, eight lanes
/// wide (for `W` of 8 and 16): this min-plus convolution is most of the collapse's planning.
///
/// Only `k <= max_k` are tried, where `max_k` is at least the number of leaves under the left
/// subtree (its primitive count will do): more slots than leaves cost what as many as leaves
/// cost, while the right subtree's cost can only grow with fewer slots, so no larger `k` is
/// strictly better, and ties go to the least `k`. Most nodes are small: a node over leaves of
/// a few primitives tries a few `k`, not `W - 1`.
#[inline]
fn best_splits<const W: usize>(l: &[f32; W], r: &[f32; W], max_k: usize) -> [(f32, u8); W] {
    let max_k = max_k.clamp(1, W - 1);
    #[cfg(target_arch = "x86_64")]
    if W == 16 && std::arch::is_x86_feature_detected!("avx512f") {
        let (l16, r16) = (l.as_slice().try_into().expect("16 slots"), r.as_slice().try_into().expect("16 slots"));
        // SAFETY: the CPU has AVX-512 F (just checked).
        let best = unsafe { best_splits_avx512(l16, r16, max_k) };
        return std::array::from_fn(|j| best[j]);
    }
    let mut best = [(f32::INFINITY, 0u8); W];
    if W.is_multiple_of(8) && W <= 16 {
        // `padded[16 + i]` is r[i], infinite below: lane `i` of `shifted(first, k)` is
        // r[j - k - 1] for j - 1 = first + i, infinite where j <= k.
        let mut padded = [f32::INFINITY; 32];
        padded[16..16 + W].copy_from_slice(r);
        for first in (0..W).step_by(8) {
            // Eight consecutive floats: two unaligned loads (a lane-by-lane gather was a
            // quarter of the 16-wide collapse).
            let shifted = |k: usize| {
                let at = 16 + first - k;
                f32x8::new(padded[at..at + 8].try_into().expect("eight lanes"))
            };
            let (mut cost, mut split) = (f32x8::splat(f32::INFINITY), f32x8::ZERO);
            // Beyond `first + 8`, every lane's right part would have no slot.
            for k in 1..=max_k.min(first + 7) {
                let c = f32x8::splat(l[k - 1]) + shifted(k);
                let better = c.simd_lt(cost);
                cost = better.bitselect(c, cost);
                split = better.bitselect(f32x8::splat(k as f32), split);
            }
            let (cost, split) = (cost.to_array(), split.to_array());
            for i in 0..8 {
                // One slot (j = 1) has no split.
                if first + i >= 1 {
                    best[first + i] = (cost[i], split[i] as u8);
                }
            }
        }
        return best;
    }
    best_splits_scalar(l, r, max_k)
}

/// [`best_splits`] for 16 slots in one 512-bit register: the 16-wide tree is the rendering
/// tree where the CPU has AVX-512, and there the convolution's 15 steps in eight-lane halves
/// (SSE pairs in the baseline build) made its collapse twice the 8-wide one's time.
///
/// # Safety
/// The CPU must have AVX-512 F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn best_splits_avx512(l: &[f32; 16], r: &[f32; 16], max_k: usize) -> [(f32, u8); 16] {
    use std::arch::x86_64::*;
    // `padded[16 + i]` is r[i], infinite below, as in `best_splits`.
    let mut padded = [f32::INFINITY; 32];
    padded[16..].copy_from_slice(r);
    let (mut cost, mut split) = (_mm512_set1_ps(f32::INFINITY), _mm512_setzero_si512());
    for k in 1..=max_k {
        // SAFETY: lanes `16 - k .. 32 - k` of the 32-float array (`max_k <= 15`).
        let shifted = unsafe { _mm512_loadu_ps(padded.as_ptr().add(16 - k)) };
        let c = _mm512_add_ps(_mm512_set1_ps(l[k - 1]), shifted);
        let better = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(c, cost);
        cost = _mm512_mask_blend_ps(better, cost, c);
        split = _mm512_mask_blend_epi32(better, split, _mm512_set1_epi32(k as i32));
    }
    let (mut c, mut k) = ([0.0f32; 16], [0i32; 16]);
    // SAFETY: both arrays hold sixteen lanes.
    unsafe {
        _mm512_storeu_ps(c.as_mut_ptr(), cost);
        _mm512_storeu_si512(k.as_mut_ptr().cast(), split);
    }
    // One slot (lane 0) has no split.
    std::array::from_fn(|j| if j == 0 { (f32::INFINITY, 0) } else { (c[j], k[j] as u8) })
}

/// [`best_splits`] one candidate at a time (for other widths, and to check the vector code).
fn best_splits_scalar<const W: usize>(l: &[f32; W], r: &[f32; W], max_k: usize) -> [(f32, u8); W] {
    let mut best = [(f32::INFINITY, 0u8); W];
    for j in 2..=W {
        for k in 1..j.min(max_k + 1) {
            let c = l[k - 1] + r[j - k - 1];
            if c < best[j - 1].0 {
                best[j - 1] = (c, k as u8);
            }
        }
    }
    best
}

/// Subtrees with more binary nodes than this are planned on separate rayon tasks.
const PARALLEL_PLAN: usize = 1 << 12;

/// The collapse's decisions for every binary node.
struct Plan<const W: usize> {
    nodes: Vec<Decision<W>>,
}

impl<const W: usize> Plan<W> {
    /// Decide for every node of `bin` (not empty), bottom-up, subtrees in parallel.
    fn new<P: Primitives + Sync + ?Sized>(bin: &Bvh, prims: &P) -> Self {
        // Zeroed memory (the decisions' threads touch it first), where writing empty decisions
        // took a pass on one thread.
        let mut nodes = pages::zeroed(bin.nodes.len());
        Self::subtree(bin, prims, 0, &mut nodes);
        Plan { nodes }
    }

    /// Decide for the subtree of binary node `root`, whose nodes are `out` (in the binary
    /// tree's depth-first order, a subtree is a contiguous run starting at its root); returns
    /// the root's costs.
    fn subtree<P: Primitives + Sync + ?Sized>(bin: &Bvh, prims: &P, root: usize, out: &mut [Decision<W>]) -> Costs<W> {
        let node = &bin.nodes[root];
        if out.len() > PARALLEL_PLAN && !node.is_leaf() {
            let right = node.start as usize - root;
            let (this, children) = out.split_at_mut(1);
            let (l, r) = children.split_at_mut(right - 1);
            let (lc, rc) =
                rayon::join(|| Self::subtree(bin, prims, root + 1, l), || Self::subtree(bin, prims, root + right, r));
            let (d, cost) = Self::decide(bin, root, (&l[0], &lc), (&r[0], &rc));
            this[0] = d;
            return cost;
        }
        // Children come after their parent: a backwards sweep meets them first, each child's
        // subtree as one run (the right child's, then the left's), so the costs of the
        // subtrees not yet claimed by their parent form a stack, as deep as the tree, whose top
        // two are the node's left and right children when it is met.
        let mut costs: Vec<Costs<W>> = Vec::with_capacity(MAX_DEPTH + 1);
        for k in (0..out.len()).rev() {
            let i = root + k;
            let n = &bin.nodes[i];
            let (d, cost) = if n.is_leaf() {
                Self::decide_leaf(bin, prims, i)
            } else {
                let (l, r) = (i + 1 - root, n.start as usize - root);
                let (lc, rc) = (costs.pop(), costs.pop());
                let (lc, rc) = (lc.expect("the left child's costs"), rc.expect("the right child's costs"));
                Self::decide(bin, i, (&out[l], &lc), (&out[r], &rc))
            };
            out[k] = d;
            costs.push(cost);
        }
        costs.pop().expect("the root's costs")
    }

    /// A binary leaf stays a leaf.
    fn decide_leaf<P: Primitives + ?Sized>(bin: &Bvh, prims: &P, i: usize) -> (Decision<W>, Costs<W>) {
        let node = &bin.nodes[i];
        let (start, count) = (node.start, node.count);
        let packable = (start..start + count).all(|s| prims.is_triangle(s));
        let tests = if packable { leaf_tests(count) } else { count as f32 };
        let d = Decision { choice: [1; W], split: 0, packable, range: LeafRange { start, count } };
        (d, [node.bounds().half_area() * tests; W])
    }

    /// Interior node `i`, given its children's decisions and costs.
    fn decide(
        bin: &Bvh,
        i: usize,
        (l, l_cost): (&Decision<W>, &Costs<W>),
        (r, r_cost): (&Decision<W>, &Costs<W>),
    ) -> (Decision<W>, Costs<W>) {
        let area = bin.nodes[i].bounds().half_area();
        let count = l.range.count + r.range.count;
        let packable = l.packable && r.packable;
        let both = best_splits(l_cost, r_cost, l.range.count as usize);
        let as_node = area * NODE_COST + both[W - 1].0;
        let as_leaf = if packable && count <= LEAF_TRIANGLES { area * leaf_tests(count) } else { f32::INFINITY };
        let mut d = Decision {
            choice: [0; W],
            // At least one slot each: where no split has a finite cost (boxes so large that
            // their areas overflow), `best_splits` names none.
            split: both[W - 1].1.max(1),
            packable,
            range: LeafRange { start: l.range.start, count },
        };
        let mut cost = [0.0; W];
        (cost[0], d.choice[0]) = if as_leaf <= as_node { (as_leaf, 1) } else { (as_node, 0) };
        for j in 2..=W {
            (cost[j - 1], d.choice[j - 1]) = if both[j - 1].0 < cost[j - 2] { both[j - 1] } else { (cost[j - 2], 0) };
        }
        (d, cost)
    }

    /// The children of the wide node made for interior binary node `i`; returns them and
    /// how many there are.
    fn children(&self, bin: &Bvh, i: usize) -> ([Kid; W], usize) {
        let mut kids = [Kid::default(); W];
        let mut len = 0;
        let k = self.nodes[i].split as usize;
        self.gather(bin, i + 1, k, &mut kids, &mut len);
        self.gather(bin, bin.nodes[i].start as usize, W - k, &mut kids, &mut len);
        (kids, len)
    }

    /// Binary node `i`'s subtree as at most `slots` children, appended to `kids`.
    fn gather(&self, bin: &Bvh, i: usize, slots: usize, kids: &mut [Kid; W], len: &mut usize) {
        let node = &bin.nodes[i];
        if slots == 1 || node.is_leaf() {
            kids[*len] = Kid { bin: i, leaf: self.nodes[i].choice[0] == 1 };
            *len += 1;
            return;
        }
        match self.nodes[i].choice[slots - 1] as usize {
            0 => self.gather(bin, i, slots - 1, kids, len),
            k => {
                self.gather(bin, i + 1, k, kids, len);
                self.gather(bin, node.start as usize, slots - k, kids, len);
            }
        }
    }
}

/// How many nodes, blocks and ranges a part of the wide tree takes; or where a part starts in
/// the tree's arrays.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Counts {
    nodes: usize,
    blocks: usize,
    ranges: usize,
}

impl Counts {
    fn plus(self, o: Counts) -> Counts {
        Counts { nodes: self.nodes + o.nodes, blocks: self.blocks + o.blocks, ranges: self.ranges + o.ranges }
    }
}

/// Where one part of the collapse writes: its share of the wide tree's arrays (each part's
/// own run of nodes, blocks and ranges), `base` where that share starts in the tree, `used`
/// how much of it is written. The arrays are made at their final size before the parts are
/// filled, in parallel, where parts appended one after another into growing arrays held the
/// parts and the tree at once, and the growth's copies (the blocks were the collapse's peak
/// memory, about twice their size).
struct Out<'a, const W: usize> {
    nodes: &'a mut [WideNode<W>],
    blocks: &'a mut [Tri4],
    ranges: &'a mut [LeafRange],
    base: Counts,
    used: Counts,
}

impl<'a, const W: usize> Out<'a, W> {
    /// Split off the first `c` of each array, as a part starting at `base`.
    fn take(&mut self, c: Counts, base: Counts) -> Out<'a, W> {
        let (nodes, blocks, ranges) = (
            std::mem::take(&mut self.nodes).split_at_mut(c.nodes),
            std::mem::take(&mut self.blocks).split_at_mut(c.blocks),
            std::mem::take(&mut self.ranges).split_at_mut(c.ranges),
        );
        (self.nodes, self.blocks, self.ranges) = (nodes.1, blocks.1, ranges.1);
        Out { nodes: nodes.0, blocks: blocks.0, ranges: ranges.0, base, used: Counts::default() }
    }

    /// Whether every element of the part is used (nodes, blocks and ranges are handed out in
    /// order, and every node handed out is written).
    fn is_full(&self) -> bool {
        self.used == Counts { nodes: self.nodes.len(), blocks: self.blocks.len(), ranges: self.ranges.len() }
    }

    /// A new node (written later by `fill`); its index in the tree.
    fn node(&mut self) -> usize {
        self.used.nodes += 1;
        self.base.nodes + self.used.nodes - 1
    }

    /// A leaf reference for the subtree that `d` decided on: packed blocks when its slots are
    /// all static triangles and few enough, else a range (as [`leaf_size`] counts them).
    fn leaf<P: Primitives + ?Sized>(&mut self, prims: &P, d: &Decision<W>) -> ChildRef {
        let LeafRange { start, count } = d.range;
        let first = self.base.blocks + self.used.blocks;
        let size = leaf_size(d, first);
        if size.blocks > 0 {
            let chunks = (start..start + count).step_by(4);
            for (block, chunk) in self.blocks[self.used.blocks..][..size.blocks].iter_mut().zip(chunks) {
                let end = (chunk + 4).min(start + count);
                *block = Tri4::pack((chunk..end).filter_map(|s| prims.triangle(s).map(|t| (s, t))));
            }
            self.used.blocks += size.blocks;
            ChildRef::packed(first as u32, size.blocks as u32)
        } else {
            self.ranges[self.used.ranges] = d.range;
            self.used.ranges += 1;
            ChildRef::range((self.base.ranges + self.used.ranges - 1) as u32)
        }
    }

    /// Make the wide node at index `at` for interior binary node `bin_index`, and its subtree
    /// (in the order [`Plan::count`] counts them).
    fn fill<P: Primitives + ?Sized>(&mut self, bin: &Bvh, plan: &Plan<W>, prims: &P, bin_index: usize, at: usize) {
        let (kids, len) = plan.children(bin, bin_index);
        let mut wide = WideNode::empty();
        let mut interior = [(0usize, 0usize); W];
        let mut n_interior = 0;
        for (slot, kid) in kids[..len].iter().enumerate() {
            let child = &bin.nodes[kid.bin];
            if kid.leaf {
                let r = self.leaf(prims, &plan.nodes[kid.bin]);
                wide.set(slot, &child.bounds(), r);
            } else {
                let idx = self.node();
                wide.set(slot, &child.bounds(), ChildRef::node(idx as u32));
                interior[n_interior] = (kid.bin, idx);
                n_interior += 1;
            }
        }
        self.nodes[at - self.base.nodes] = wide;
        for &(k, idx) in &interior[..n_interior] {
            self.fill(bin, plan, prims, k, idx);
        }
    }
}

// The wide tree's arrays are allocated zeroed (`bytemuck::zeroed_vec`: for large arrays,
// fresh pages that the system zeroes when first touched, not written here), for the fill to
// write once.
// SAFETY: the rows are `f32`s and the children `ChildRef`s, each a `u32`: all-zero bits are a value.
unsafe impl<const W: usize> Zeroable for WideNode<W> {}
// SAFETY: `f32` corners and `u32` slots.
unsafe impl Zeroable for Tri4 {}
// SAFETY: two `u32`s.
unsafe impl Zeroable for LeafRange {}

/// What the leaf that `d` decided on takes, its first block at index `first`: blocks when its
/// slots are all static triangles, few enough, and the first block's index fits a
/// [`ChildRef`]; else a range.
fn leaf_size<const W: usize>(d: &Decision<W>, first: usize) -> Counts {
    let blocks = d.range.count.div_ceil(4);
    if d.packable && blocks <= ChildRef::MAX_BLOCKS && first < 1 << ChildRef::BLOCK_BITS {
        Counts { blocks: blocks as usize, ..Counts::default() }
    } else {
        Counts { ranges: 1, ..Counts::default() }
    }
}

impl<const W: usize> Plan<W> {
    /// The nodes, blocks and ranges that [`Out::fill`] writes for interior binary node
    /// `bin_index` (its own node not included), in its order, from `at` on: the returned
    /// counts are `at`'s plus them.
    fn count(&self, bin: &Bvh, bin_index: usize, mut at: Counts) -> Counts {
        let (kids, len) = self.children(bin, bin_index);
        for kid in &kids[..len] {
            at = if kid.leaf {
                at.plus(leaf_size(&self.nodes[kid.bin], at.blocks))
            } else {
                Counts { nodes: at.nodes + 1, ..at }
            };
        }
        for kid in kids[..len].iter().filter(|k| !k.leaf) {
            at = self.count(bin, kid.bin, at);
        }
        at
    }
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// Collapse a binary BVH by the surface area heuristic (see the module documentation).
    /// Leaves of static triangles (as `prims` reports them) are packed into [`Tri4`] blocks.
    pub fn from_binary<P: Primitives + Sync + ?Sized>(bin: &Bvh, prims: &P) -> Self {
        let mut tree = WideBvh { simd: Simd::detect(), ..WideBvh::default() };
        let Some(root) = bin.nodes.first() else { return tree };
        let b = root.bounds();
        tree.reach = b.min.abs().max(b.max.abs()).max_element();
        if root.is_leaf() {
            let d = Plan::<W>::decide_leaf(bin, prims, 0).0;
            tree.alloc(leaf_size(&d, 0).plus(Counts { nodes: 1, ..Counts::default() }));
            let mut out = tree.out();
            out.used.nodes = 1;
            let r = out.leaf(prims, &d);
            let mut top = WideNode::empty();
            top.set(0, &root.bounds(), r);
            tree.nodes[0] = top;
            return tree;
        }
        let plan = Plan::<W>::new(bin, prims);
        let one = Counts { nodes: 1, ..Counts::default() };
        if bin.nodes.len() < PARALLEL_COLLAPSE || bin.prim_indices.len() >= 1 << ChildRef::BLOCK_BITS {
            // On one thread, counting from the tree's start: the blocks' indices decide which
            // leaves fit a packed reference.
            tree.alloc(plan.count(bin, 0, one));
            let mut out = tree.out();
            out.used.nodes = 1;
            out.fill(bin, &plan, prims, 0, 0);
            debug_assert!(out.is_full(), "the collapse wrote what it counted");
            return tree;
        }
        // The root's subtrees collapse on separate tasks, each into its run of the arrays
        // (every block index fits a packed reference here, so each part is counted from 0).
        use rayon::prelude::*;
        let (kids, len) = plan.children(bin, 0);
        let sizes: Vec<Counts> = kids[..len]
            .par_iter()
            .map(|kid| if kid.leaf { leaf_size(&plan.nodes[kid.bin], 0) } else { plan.count(bin, kid.bin, one) })
            .collect();
        tree.alloc(sizes.iter().fold(one, |a, &s| a.plus(s)));
        let mut rest = tree.out();
        rest.take(one, Counts::default());
        let mut base = one;
        let mut parts = Vec::with_capacity(len);
        for &size in &sizes {
            parts.push(rest.take(size, base));
            base = base.plus(size);
        }
        let refs: Vec<ChildRef> = kids[..len]
            .par_iter()
            .zip(parts)
            .map(|(kid, mut part)| {
                let r = if kid.leaf {
                    part.leaf(prims, &plan.nodes[kid.bin])
                } else {
                    let at = part.node();
                    part.fill(bin, &plan, prims, kid.bin, at);
                    ChildRef::node(at as u32)
                };
                // The arrays were allocated zeroed: every element of the part is written.
                debug_assert!(part.is_full(), "the collapse wrote what it counted");
                r
            })
            .collect();
        let mut top = WideNode::empty();
        for (slot, (kid, r)) in kids[..len].iter().zip(refs).enumerate() {
            top.set(slot, &bin.nodes[kid.bin].bounds(), r);
        }
        tree.nodes[0] = top;
        tree
    }

    /// Make the arrays at their final sizes, zeroed, for [`Out::fill`] to write every element
    /// of. Allocated zeroed, their pages are first touched by the fill, on its threads: filled
    /// with empty values first (`vec![WideNode::empty(); n]`), every page was faulted in and
    /// written twice, the first time on one thread (120 ms of a 4M-triangle mesh's 300 ms
    /// collapse on two cores).
    fn alloc(&mut self, c: Counts) {
        self.nodes = pages::zeroed(c.nodes);
        self.blocks = pages::zeroed(c.blocks);
        self.ranges = pages::zeroed(c.ranges);
    }

    /// The whole tree's arrays, to write.
    fn out(&mut self) -> Out<'_, W> {
        Out {
            nodes: &mut self.nodes,
            blocks: &mut self.blocks,
            ranges: &mut self.ranges,
            base: Counts::default(),
            used: Counts::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{best_splits, best_splits_scalar};

    /// The vector convolution picks the scalar loop's costs and splits, ties included.
    fn check<const W: usize>(seed: &mut u64) {
        let mut next = || {
            *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            // Few distinct values, so that ties are common; some infinite.
            match (*seed >> 33) % 8 {
                0 => f32::INFINITY,
                v => v as f32,
            }
        };
        for round in 0..1000 {
            let mut l: [f32; W] = std::array::from_fn(|_| next());
            let mut r: [f32; W] = std::array::from_fn(|_| next());
            // As the collapse makes them: costs that do not grow with more slots and stop
            // falling beyond the subtree's leaves (`leaves`, which bounds the splits tried).
            let leaves = 1 + round % W;
            for i in 1..W {
                l[i] = if i < leaves { l[i].min(l[i - 1]) } else { l[i - 1] };
                r[i] = r[i].min(r[i - 1]);
            }
            let (fast, slow) = (best_splits(&l, &r, leaves), best_splits_scalar(&l, &r, W - 1));
            for j in 0..W {
                assert_eq!(fast[j].0, slow[j].0, "{W} slots, {l:?} {r:?}");
                // Where no split has a finite cost, which `k` is kept does not matter.
                if slow[j].0.is_finite() {
                    assert_eq!(fast[j].1, slow[j].1, "{W} slots, {l:?} {r:?}");
                }
            }
        }
    }

    #[test]
    fn vector_splits_match_scalar() {
        let mut seed = 7;
        check::<8>(&mut seed);
        check::<16>(&mut seed);
    }
}
