//! Binned SAH construction, parallel over subtrees with rayon.

use glam::UVec4;
use rayon::join;

use super::{Bvh, BvhNode, MAX_DEPTH};
use crate::geometry::Aabb;
use crate::math::{Vec3A, Vec4};
use crate::pages;

/// How the BVH is built.
#[derive(Clone, Debug)]
pub struct BuildParams {
    /// Number of bins per axis for the SAH sweep (2 to [`MAX_BINS`]).
    pub bins: usize,
    /// Largest leaf the SAH may choose; bigger sets are always split (unless inseparable).
    pub max_leaf_size: usize,
    /// Cost of visiting a node, relative to `intersection_cost`.
    pub traversal_cost: f32,
    /// Cost of intersecting one primitive.
    pub intersection_cost: f32,
    /// Subtrees with more primitives than this are built on separate rayon tasks.
    pub parallel_threshold: usize,
    /// Primitives intersected together in one SIMD test: a leaf costs one intersection per
    /// started block of this many, as the wide BVHs' packed leaves ([`super::wide::Tri4`]) are.
    pub block_size: usize,
    /// How a node's split is chosen: the binned SAH for every scene; the others only for
    /// comparisons (`rayscope bench`'s split-rule rows, the debugger).
    pub split_rule: SplitRule,
}

/// How the builder splits a node.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum SplitRule {
    /// The binned surface area heuristic ([`super::split_candidates`] shows its planes and costs);
    /// a node becomes a leaf where that is cheaper than its best split.
    #[default]
    Sah,
    /// Halve by count at the median centroid along the widest centroid axis, down to leaves
    /// of at most [`BuildParams::block_size`] primitives.
    Median,
    /// The course seed's rule, as its report describes it: along the longest axis of the
    /// node's box, the primitives whose box starts below the mean of the boxes' lower bounds
    /// go left; leaves of at most [`BuildParams::block_size`] primitives (a plane with nothing
    /// on one side falls back to the median).
    SeedMean,
}

impl SplitRule {
    /// Every rule, the default first.
    pub const ALL: [SplitRule; 3] = [SplitRule::Sah, SplitRule::Median, SplitRule::SeedMean];

    /// Its name in tables and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SplitRule::Sah => "sah",
            SplitRule::Median => "median",
            SplitRule::SeedMean => "seed-mean",
        }
    }
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            bins: 16,
            max_leaf_size: 8,
            traversal_cost: 1.5,
            intersection_cost: 1.0,
            parallel_threshold: 4096,
            block_size: 4,
            split_rule: SplitRule::Sah,
        }
    }
}

/// A primitive while the tree is built: its box and its index, packed in 32 bytes, the box's
/// corners as the `xyz` of two vectors and the index in their `w` lanes, which a box leaves
/// unused. Every pass over the primitives streams them (at the top of a big tree, from
/// memory): a separate centre and index made them 48 bytes, and the centre is two exact
/// operations away (the same bits as [`Aabb::center`]).
///
/// | field | `xyz`          | `w`                                      |
/// |-------|----------------|------------------------------------------|
/// | `lo`  | the box's min  | the index's low 16 bits, as a whole float |
/// | `hi`  | the box's max  | its high 16 bits, as a whole float        |
///
/// The halves are stored as whole numbers below 2^16, exact in an `f32` and never subnormal
/// or NaN: the `w` lanes ride along in the boxes' unions and centres, and subnormal values
/// there would slow the arithmetic on some processors.
#[derive(Clone, Copy)]
#[repr(C, align(16))]
pub(super) struct BuildPrim {
    lo: Vec4,
    hi: Vec4,
}

const _: () = assert!(std::mem::size_of::<BuildPrim>() == 32);

impl BuildPrim {
    #[inline(always)]
    pub(super) fn new(bounds: Aabb, index: u32) -> BuildPrim {
        BuildPrim { lo: bounds.min.extend((index & 0xffff) as f32), hi: bounds.max.extend((index >> 16) as f32) }
    }

    /// Its box (the `w` lanes are not part of it).
    #[inline(always)]
    pub(super) fn bounds(&self) -> Aabb {
        Aabb { min: Vec3A::from_vec4(self.lo), max: Vec3A::from_vec4(self.hi) }
    }

    /// Its index.
    #[inline(always)]
    pub(super) fn index(&self) -> u32 {
        self.lo.w as u32 | (self.hi.w as u32) << 16
    }

    /// Its box's centre: [`Aabb::center`]'s arithmetic.
    #[inline(always)]
    fn centroid(&self) -> Vec3A {
        Vec3A::from_vec4(0.5 * (self.lo + self.hi))
    }

    /// Its box's centre on `axis`, as [`BuildPrim::centroid`] computes it.
    #[inline(always)]
    fn centroid_on(&self, axis: usize) -> f32 {
        0.5 * (self.lo[axis] + self.hi[axis])
    }
}

/// Nodes with more primitives than this bin and bound them on several rayon tasks: at the top
/// of the tree, where the subtrees are not yet there to run in parallel.
const PARALLEL_PASS: usize = 1 << 15;
/// Primitives per task in those passes.
const PASS_CHUNK: usize = 1 << 13;

/// The box of a set of primitives and the box of their centroids.
#[derive(Clone, Copy)]
pub(super) struct Bounds {
    pub(super) bounds: Aabb,
    pub(super) centroids: Aabb,
}

impl Bounds {
    const EMPTY: Bounds = Bounds { bounds: Aabb::EMPTY, centroids: Aabb::EMPTY };

    #[inline(always)]
    fn add(&mut self, p: &BuildPrim) {
        self.bounds = self.bounds.union(p.bounds());
        self.centroids = self.centroids.grow(p.centroid());
    }

    fn merge(self, o: Bounds) -> Bounds {
        Bounds { bounds: self.bounds.union(o.bounds), centroids: self.centroids.union(o.centroids) }
    }

    pub(super) fn of(prims: &[BuildPrim]) -> Bounds {
        if prims.len() > PARALLEL_PASS {
            use rayon::prelude::*;
            return prims.par_chunks(PASS_CHUNK).map(Bounds::of).reduce(|| Bounds::EMPTY, Bounds::merge);
        }
        let mut b = Bounds::EMPTY;
        for p in prims {
            b.add(p);
        }
        b
    }
}

impl Bvh {
    /// Build over primitives with these bounding boxes. Primitives whose box is not finite
    /// (NaN or infinite coordinates) are left out.
    pub fn build(bounds: &[Aabb], params: &BuildParams) -> Bvh {
        Bvh::build_from(bounds.len(), |i| bounds[i], params)
    }

    /// [`Bvh::build`] over `count` primitives whose boxes `bounds` gives by index: the same
    /// tree, without an array of the boxes (32 bytes a primitive, alive beside the builder's
    /// own 48 at its peak).
    pub fn build_from(count: usize, bounds: impl Fn(usize) -> Aabb + Sync, params: &BuildParams) -> Bvh {
        use rayon::prelude::*;
        let prim = |i: usize| BuildPrim::new(bounds(i), i as u32);
        // Made in place (an exact-size collect into room advised for huge pages), then the rare
        // unusable boxes dropped (looked for on every core: `retain` goes through every
        // primitive on one).
        let mut prims: Vec<BuildPrim> = pages::with_capacity(count);
        if count > PARALLEL_PASS {
            (0..count).into_par_iter().map(prim).collect_into_vec(&mut prims);
        } else {
            prims.extend((0..count).map(prim));
        }
        let usable = |p: &BuildPrim| p.bounds().is_finite() && !p.bounds().is_empty();
        if !prims.par_iter().all(usable) {
            prims.retain(usable);
        }
        if prims.is_empty() {
            return Bvh::default();
        }
        let mut parts = Nodes::for_prims(prims.len(), params);
        let b = Bounds::of(&prims);
        build_node(&mut prims, b, 0, 0, params, &mut parts);
        let nodes = parts.into_vec();
        let mut prim_indices = pages::with_capacity(prims.len());
        prims.par_iter().map(BuildPrim::index).collect_into_vec(&mut prim_indices);
        Bvh { nodes, prim_indices }
    }
}

struct Split {
    axis: usize,
    /// Primitives whose bin is below this go left.
    bin: usize,
    /// Where the binning started on `axis` and its bins per unit: the partition bins with the
    /// same numbers, so every primitive lands on its bin's side.
    lo: f32,
    scale: f32,
    cost: f32,
    /// The boxes of the primitives left and right of the plane: unions of the bins' boxes
    /// on each side, which hold exactly those primitives (the partition bins as the binning
    /// did). Unions are exact in any order, so these are the boxes a pass over each side's
    /// primitives would find, up to which of two equal zeros a bound keeps, which no box
    /// test tells apart.
    left: Aabb,
    right: Aabb,
}

/// Nodes in depth-first order, held as a list of arrays: subtrees built on other threads come
/// back as arrays of their own and are joined by moving the arrays, not their nodes (copying
/// them into the parent's array at every parallel level was 5% of a million-triangle build);
/// [`Nodes::into_vec`] copies each node once at the end.
struct Nodes {
    /// Finished arrays, in order.
    done: Vec<Vec<BvhNode>>,
    /// Nodes in `done`.
    done_len: usize,
    /// The array being appended to.
    cur: Vec<BvhNode>,
}

impl Nodes {
    /// Room for the subtree over `n` primitives: all its nodes (at most two per primitive)
    /// where it is built on one thread; its root's where it is split between tasks, whose
    /// subtrees come back in arrays of their own.
    fn for_prims(n: usize, params: &BuildParams) -> Nodes {
        let capacity = if n > params.parallel_threshold { 1 } else { 2 * n };
        Nodes { done: Vec::new(), done_len: 0, cur: Vec::with_capacity(capacity) }
    }

    fn len(&self) -> usize {
        self.done_len + self.cur.len()
    }

    fn push(&mut self, node: BvhNode) {
        self.cur.push(node);
    }

    /// Move `other`'s nodes after these.
    fn append(&mut self, other: Nodes) {
        let cur = std::mem::take(&mut self.cur);
        for mut part in std::iter::once(cur).chain(other.done).chain(std::iter::once(other.cur)) {
            if !part.is_empty() {
                // The arrays were reserved for the most nodes a subtree can have (two per
                // primitive); a kept array holds only what was used, or the reserves add up
                // to gigabytes of address space on a 10M-triangle mesh.
                part.shrink_to_fit();
                self.done_len += part.len();
                self.done.push(part);
            }
        }
    }

    /// All the nodes in one array, their second-child indices made absolute: subtrees were
    /// built with indices relative to their own node, so they could be built apart and
    /// joined. The arrays are copied on every core, each into its place.
    fn into_vec(self) -> Vec<BvhNode> {
        use rayon::prelude::*;
        let mut all: Vec<BvhNode> = pages::zeroed(self.len());
        // Each array with its place in `all` and the index of its first node there.
        let (mut rest, mut first) = (&mut all[..], 0);
        let mut parts = Vec::with_capacity(self.done.len() + 1);
        for part in self.done.iter().chain(std::iter::once(&self.cur)) {
            let (place, after) = std::mem::take(&mut rest).split_at_mut(part.len());
            parts.push((place, &part[..], first));
            (rest, first) = (after, first + part.len());
        }
        parts.into_par_iter().for_each(|(place, part, first)| {
            for (i, (to, node)) in place.iter_mut().zip(part).enumerate() {
                *to = *node;
                if !node.is_leaf() {
                    to.start += (first + i) as u32;
                }
            }
        });
        all
    }
}

/// Appends the subtree over `prims` (which occupy slots `offset..` and have bounds `b`) to
/// `out`, depth-first.
fn build_node(prims: &mut [BuildPrim], b: Bounds, offset: u32, depth: usize, params: &BuildParams, out: &mut Nodes) {
    let n = prims.len();
    let leaf = BvhNode::new(b.bounds, offset, n as u32);
    if n == 1 || depth + 1 >= MAX_DEPTH {
        out.push(leaf);
        return;
    }
    let Some(Halves { mid, left: lb, right: rb }) = split_node(prims, &b, params) else {
        out.push(leaf);
        return;
    };
    let here = out.len();
    out.push(BvhNode::new(b.bounds, 0, 0));
    // This node's place in `out.cur`, which keeps it until an `append` moves the array away.
    let at = out.cur.len() - 1;
    let (left, right) = prims.split_at_mut(mid);
    let right_offset = offset + mid as u32;
    if n > params.parallel_threshold {
        let (l, r) = join(
            || subtree(left, lb, offset, depth + 1, params),
            || subtree(right, rb, right_offset, depth + 1, params),
        );
        out.cur[at].start = 1 + l.len() as u32;
        out.append(l);
        out.append(r);
    } else {
        // Below the threshold everything is built on this thread, into `out.cur`.
        build_node(left, lb, offset, depth + 1, params, out);
        out.cur[at].start = (out.len() - here) as u32;
        build_node(right, rb, right_offset, depth + 1, params, out);
    }
}

/// A node's primitives split in two: the first `mid` go left.
struct Halves {
    mid: usize,
    /// The bounds of the left ones.
    left: Bounds,
    /// The bounds of the right ones.
    right: Bounds,
}

impl Halves {
    /// `prims` split at `mid`, each side's bounds found by a pass over it.
    fn measured(prims: &[BuildPrim], mid: usize) -> Halves {
        Halves { mid, left: Bounds::of(&prims[..mid]), right: Bounds::of(&prims[mid..]) }
    }
}

/// Split `prims` (bounds `b`) by the rule of `params`, or `None` where the node is to be a
/// leaf.
#[inline(always)]
fn split_node(prims: &mut [BuildPrim], b: &Bounds, params: &BuildParams) -> Option<Halves> {
    let n = prims.len();
    if params.split_rule != SplitRule::Sah {
        return (n > params.block_size.max(1)).then(|| {
            let mid = simple_split(prims, b, params.split_rule);
            Halves::measured(prims, mid)
        });
    }
    // A split costs a node visit plus a part that is never negative (unless the costs are),
    // so a leaf that costs no more than the visit wins whatever the bins would say: a
    // seventh of the nodes the binning saw on a 1M-triangle mesh (four primitives or fewer).
    if n <= params.max_leaf_size && leaf_cost(n, params) <= params.traversal_cost && params.intersection_cost >= 0.0 {
        return None;
    }
    let split = find_split(prims, &b.bounds, &b.centroids, params);
    match split {
        Some(s) if s.cost < leaf_cost(n, params) || n > params.max_leaf_size => Some(partition(prims, &s)),
        None if n > params.max_leaf_size => {
            let mid = median_split(prims, &b.centroids);
            Some(Halves::measured(prims, mid))
        }
        _ => None,
    }
}

/// The SAH cost of making `n` primitives one leaf.
#[inline(always)]
pub(super) fn leaf_cost(n: usize, params: &BuildParams) -> f32 {
    params.intersection_cost * blocks(n as u32, params.block_size) as f32
}

/// The comparison rules' splits ([`SplitRule::Median`], [`SplitRule::SeedMean`]).
#[cold]
fn simple_split(prims: &mut [BuildPrim], b: &Bounds, rule: SplitRule) -> usize {
    if rule == SplitRule::SeedMean {
        let axis = b.bounds.extent().max_position();
        let mean = prims.iter().map(|p| p.bounds().min[axis] as f64).sum::<f64>() / prims.len() as f64;
        let mid = partition_by(prims, |p| (p.bounds().min[axis] as f64) < mean);
        if mid != 0 && mid != prims.len() {
            return mid;
        }
    }
    median_split(prims, &b.centroids)
}

fn subtree(prims: &mut [BuildPrim], b: Bounds, offset: u32, depth: usize, params: &BuildParams) -> Nodes {
    let mut out = Nodes::for_prims(prims.len(), params);
    build_node(prims, b, offset, depth, params, &mut out);
    out
}

/// Intersection blocks a leaf of `n` primitives takes with `block_size` per block; by a shift
/// where the size is a power of two (always, in practice): the SAH sweep counts blocks twice
/// per candidate plane ([`blocks4`], its three axes at once), and a division there showed in
/// profiles.
#[inline(always)]
fn blocks(n: u32, block_size: usize) -> u32 {
    let bs = block_size.max(1) as u32;
    if bs.is_power_of_two() { (n + bs - 1) >> bs.trailing_zeros() } else { n.div_ceil(bs) }
}

/// The bins of relative positions `rel` (`trunc(min(rel, top))` per axis, 0 for NaN): one
/// vector conversion, where `as usize` per axis costs a saturating sequence each.
#[inline(always)]
fn bin_indices(rel: Vec3A, top: Vec3A) -> [u32; 4] {
    // `max` first with ZERO second: SSE's max returns its second operand for a NaN.
    let clamped = rel.max(Vec3A::ZERO).min(top);
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, __m128i, _mm_cvttps_epi32};
        let v: __m128 = clamped.into();
        // SAFETY: SSE2 is part of x86-64; the lanes are in [0, top], so they convert exactly.
        let i: __m128i = unsafe { _mm_cvttps_epi32(v) };
        // SAFETY: __m128i and [u32; 4] have the same size, and every bit pattern is valid.
        unsafe { std::mem::transmute::<__m128i, [u32; 4]>(i) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let u = clamped.as_uvec3();
        [u.x, u.y, u.z, 0]
    }
}

/// Most bins per axis the builder supports (its bins live on the stack).
pub const MAX_BINS: usize = 32;

/// `N` bins on each axis (of which a node uses the first `nb <= N`): their boxes and their
/// counts in arrays of their own. A box alone is 32 bytes, a shift from its index, where a
/// box and its count made 48 (the binning's loop spent an instruction more on each address);
/// and the bins a node clears are 25% fewer bytes.
#[derive(Clone, Copy)]
pub(super) struct Bins<const N: usize> {
    bounds: [[Aabb; N]; 3],
    counts: [[u32; N]; 3],
}

impl<const N: usize> Bins<N> {
    /// Every bin empty.
    pub(super) const EMPTY: Bins<N> = Bins { bounds: [[Aabb::EMPTY; N]; 3], counts: [[0; N]; 3] };

    /// Add a primitive of box `b` to bin `idx[axis]` of each axis.
    #[inline(always)]
    fn add(&mut self, idx: [u32; 4], b: Aabb) {
        for ((bounds, counts), &i) in self.bounds.iter_mut().zip(&mut self.counts).zip(&idx) {
            // The index is at most `nb - 1 < N`; the mask (N is a power of two) leaves it as
            // it is and spares a bounds check per axis.
            let i = i as usize & (N - 1);
            bounds[i] = bounds[i].union(b);
            counts[i] += 1;
        }
    }

    /// Add the bins `o` of another set of primitives binned alike (the first `nb` of each
    /// axis: the others are empty in both): unions and sums, exact in any order.
    #[inline(always)]
    fn merge(&mut self, o: &Bins<N>, nb: usize) {
        for axis in 0..3 {
            for i in 0..nb {
                self.bounds[axis][i] = self.bounds[axis][i].union(o.bounds[axis][i]);
                self.counts[axis][i] += o.counts[axis][i];
            }
        }
    }

    /// Bin `i`'s box on `axis`.
    #[inline(always)]
    pub(super) fn bounds(&self, axis: usize, i: usize) -> Aabb {
        self.bounds[axis][i]
    }

    /// Bin `i`'s counts on the three axes, in the `x`, `y`, `z` lanes.
    #[inline(always)]
    pub(super) fn counts(&self, i: usize) -> UVec4 {
        UVec4::new(self.counts[0][i], self.counts[1][i], self.counts[2][i], 0)
    }
}

/// Primitives from which [`fill_bins`] bins in two sets: below, the second set's clearing
/// and merging cost more than the waits it saves.
const TWO_SETS: usize = 32;

/// Bin `prims` on all three axes at once (`nb <= N` bins from `lo`, `scale` bins per unit)
/// into `bins`, empty bins. Into the caller's bins: bins returned by value were copied at
/// every node, where the compiler could not build them in the caller's place (4% of a
/// 4M-triangle build in `memcpy` once, 2.7% of a 1M-triangle one after the small nodes'
/// early return came).
pub(super) fn fill_bins<const N: usize>(prims: &[BuildPrim], lo: Vec3A, scale: Vec3A, nb: usize, bins: &mut Bins<N>) {
    if prims.len() > PARALLEL_PASS {
        use rayon::prelude::*;
        let one = |c: &[BuildPrim]| {
            let mut part = Bins::EMPTY;
            fill_bins_here::<N>(c, lo, scale, nb, &mut part);
            part
        };
        let merge = |mut a: Bins<N>, b: Bins<N>| {
            a.merge(&b, nb);
            a
        };
        *bins = prims.par_chunks(PASS_CHUNK).map(one).reduce(|| Bins::EMPTY, merge);
    } else {
        fill_bins_here(prims, lo, scale, nb, bins);
    }
}

/// [`fill_bins`] on this thread, into `even` (empty bins).
#[inline(always)]
fn fill_bins_here<const N: usize>(prims: &[BuildPrim], lo: Vec3A, scale: Vec3A, nb: usize, even: &mut Bins<N>) {
    const { assert!(N.is_power_of_two()) };
    let top = Vec3A::splat((nb - 1) as f32);
    let add = |bins: &mut Bins<N>, p: &BuildPrim| bins.add(bin_indices((p.centroid() - lo) * scale, top), p.bounds());
    // Two sets of bins, for the even and the odd primitives, merged at the end: neighbours in
    // a mesh's order often land in the same bins, and with one set each primitive's update
    // waited for the previous one's store to that bin. Unions and counts are exact, so the
    // bins are the same whatever the grouping.
    if prims.len() < TWO_SETS {
        for p in prims {
            add(even, p);
        }
        return;
    }
    let mut odd = Bins::EMPTY;
    let mut two = prims.chunks_exact(2);
    for p in &mut two {
        add(even, &p[0]);
        add(&mut odd, &p[1]);
    }
    if let [p] = two.remainder() {
        add(even, p);
    }
    even.merge(&odd, nb);
}

/// The cheapest binned SAH split over the three axes, or `None` when all centroids coincide.
/// All three axes are binned in one pass over the primitives, into bins on the stack: the
/// build spends most of its time here.
fn find_split(prims: &[BuildPrim], bounds: &Aabb, centroids: &Aabb, params: &BuildParams) -> Option<Split> {
    // Small nodes get fewer bins: with n primitives, n bins already tell every split apart,
    // and the fixed cost of clearing and sweeping 3 x 16 bins dominates there. The bins are
    // sized for the count used (clearing 3 x 32 unused bins was 8% of the dragon's build).
    let nb = bin_count(prims.len(), params);
    match nb {
        ..=8 => find_split_in::<8>(prims, bounds, centroids, params, nb),
        9..=16 => find_split_in::<16>(prims, bounds, centroids, params, nb),
        _ => find_split_in::<MAX_BINS>(prims, bounds, centroids, params, nb),
    }
}

/// The bins per axis of a node of `n` primitives.
pub(super) fn bin_count(n: usize, params: &BuildParams) -> usize {
    params.bins.min(n.next_power_of_two().max(4)).clamp(2, MAX_BINS)
}

/// [`find_split`] with `nb <= N` bins per axis.
fn find_split_in<const N: usize>(
    prims: &[BuildPrim],
    bounds: &Aabb,
    centroids: &Aabb,
    params: &BuildParams,
    nb: usize,
) -> Option<Split> {
    let extent = centroids.extent();
    let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
    // A zero extent gives an infinite scale; such an axis is skipped below.
    let scale = Vec3A::splat(nb as f32) / extent;
    let mut bins = Bins::EMPTY;
    fill_bins::<N>(prims, centroids.min, scale, nb, &mut bins);
    // Candidates are ranked by area-weighted block counts; the division by the parent's area
    // (which does not change the ranking) is done once, for the winner. The sweep gives every
    // plane's weight and the cheapest is found afterwards: keeping the best so far while
    // sweeping made every plane wait on the previous one's compare and select, a chain that
    // was a third of the sweep's time.
    let mut weights = [Vec4::INFINITY; N];
    let swept = swept_axes(extent);
    sweep(&bins, nb, params.block_size, |planes| weights[planes.bin] = planes.split_weights(swept));
    let best = first_min(&weights)?;
    let side = |planes: std::ops::Range<usize>| planes.fold(Aabb::EMPTY, |b, i| b.union(bins.bounds(best.axis, i)));
    Some(Split {
        axis: best.axis,
        bin: best.bin,
        lo: centroids.min[best.axis],
        scale: scale[best.axis],
        cost: sah_cost(best.weight, parent_area, params),
        left: side(0..best.bin),
        right: side(best.bin..nb),
    })
}

/// The cheapest plane of a sweep.
struct BestPlane {
    axis: usize,
    bin: usize,
    weight: f32,
}

/// The first (in axis, then bin order) of the smallest finite weights, NaN ones left out:
/// the plane a sweep keeping the best so far by a strict `<` would end with. `weights[bin]`
/// holds the three axes' weights of that bin's plane in its `x`, `y`, `z` lanes (its `w`
/// lane is not read). `None` when every weight is infinite or NaN.
#[inline(always)]
fn first_min<const N: usize>(weights: &[Vec4; N]) -> Option<BestPlane> {
    // The `w` lanes made infinite, so that only the three axes count.
    let xyz = |w: Vec4| w.with_w(f32::INFINITY);
    // Where a weight is NaN, `min` with it first returns the other operand (SSE's rule, and
    // `f32::min`'s on glam's scalar path), so a NaN never becomes the least.
    let least = weights.iter().fold(Vec4::INFINITY, |m, &w| xyz(w).min(m)).min_element();
    if least == f32::INFINITY {
        return None;
    }
    // Bit `bin` of `at[axis]`: that plane's weight is the least.
    let mut at = [0u64; 3];
    let eq = Vec4::splat(least);
    for (bin, &w) in weights.iter().enumerate() {
        let mask = xyz(w).cmpeq(eq).bitmask();
        for (axis, bits) in at.iter_mut().enumerate() {
            *bits |= u64::from(mask >> axis & 1) << bin;
        }
    }
    let axis = at.iter().position(|&bits| bits != 0)?;
    let bin = at[axis].trailing_zeros() as usize;
    // That plane's own weight: `least` may be the other zero.
    Some(BestPlane { axis, bin, weight: weights[bin][axis] })
}

/// The SAH cost of a split whose area-weighted block count is `weight`, under a parent of
/// half-area `parent_area`.
#[inline(always)]
pub(super) fn sah_cost(weight: f32, parent_area: f32, params: &BuildParams) -> f32 {
    params.traversal_cost + params.intersection_cost * weight / parent_area
}

/// One plane position of the SAH sweep on all three axes: the plane between bins `bin - 1`
/// and `bin` of each axis, the axes in the `x`, `y`, `z` lanes.
#[derive(Clone, Copy)]
pub(super) struct SweptPlanes {
    /// The plane's place: between bins `bin - 1` and `bin`.
    pub(super) bin: usize,
    /// Area-weighted block counts, `A_left blocks_left + A_right blocks_right`.
    pub(super) weight: Vec4,
    /// Primitives left of the plane.
    pub(super) left: UVec4,
    /// Primitives right of it.
    pub(super) right: UVec4,
}

impl SweptPlanes {
    /// The weights of the planes that split (primitives on both sides, on an axis of
    /// `swept`), infinite for the others (and in the `w` lane).
    #[inline(always)]
    fn split_weights(&self, swept: [bool; 3]) -> Vec4 {
        let flat = glam::BVec4A::new(!swept[0], !swept[1], !swept[2], true);
        // A count is zero exactly when its float is (see `to_f32`): the test in vector lanes.
        let none = |n: UVec4| to_f32(n).cmpeq(Vec4::ZERO);
        Vec4::select(none(self.left) | none(self.right) | flat, Vec4::INFINITY, self.weight)
    }
}

/// The axes a sweep of centroids with this `extent` ([`Aabb::extent`], never negative or
/// NaN) goes along: those with extent.
#[inline(always)]
pub(super) fn swept_axes(extent: Vec3A) -> [bool; 3] {
    [extent.x > 0.0, extent.y > 0.0, extent.z > 0.0]
}

/// The three axes' half-areas of boxes `x`, `y`, `z` (one per axis), as the lanes of a
/// vector: [`Aabb::half_area`]'s arithmetic, in the same order, on all three at once.
#[inline(always)]
fn half_areas(x: &Aabb, y: &Aabb, z: &Aabb) -> Vec4 {
    let (ex, ey, ez) = (x.extent(), y.extent(), z.extent());
    let a = Vec4::new(ex.x, ey.x, ez.x, 0.0);
    let b = Vec4::new(ex.y, ey.y, ez.y, 0.0);
    let c = Vec4::new(ex.z, ey.z, ez.z, 0.0);
    a * b + b * c + c * a
}

/// Block counts of leaves of `n` primitives, lane by lane: [`blocks`] of each lane, its shift
/// done on the four lanes at once.
#[inline(always)]
fn blocks4(n: UVec4, block_size: usize) -> UVec4 {
    let bs = block_size.max(1) as u32;
    if bs.is_power_of_two() {
        (n + UVec4::splat(bs - 1)) >> UVec4::splat(bs.trailing_zeros())
    } else {
        UVec4::from_array(n.to_array().map(|c| blocks(c, block_size)))
    }
}

/// A count as a float: exact below 2^24, and the conversion of a signed lane (one
/// instruction) gives the unsigned value's float below 2^31, which a count of primitives
/// indexed by 32 bits (16 + 16 in [`BuildPrim`]) never reaches as a block count.
#[inline(always)]
fn to_f32(n: UVec4) -> Vec4 {
    n.as_ivec4().as_vec4()
}

/// The SAH sweep over the first `nb` bins of each axis, the three axes at once (in the
/// lanes of a vector), each plane position `1..nb` handed to `visit` in order: the builder's
/// one sweep, which [`super::split_candidates`] also runs. Each lane's arithmetic is that of
/// a sweep of its axis alone. Only the axes of [`swept_axes`] are candidates.
#[inline(always)]
pub(super) fn sweep<const N: usize>(bins: &Bins<N>, nb: usize, bs: usize, mut visit: impl FnMut(SweptPlanes)) {
    // Sweep from the right to know, for each split plane, the boxes and counts to its right.
    let mut right_area = [Vec4::ZERO; N];
    let mut right_count = [UVec4::ZERO; N];
    let (mut x, mut y, mut z, mut cnt) = (Aabb::EMPTY, Aabb::EMPTY, Aabb::EMPTY, UVec4::ZERO);
    for i in (1..nb).rev() {
        x = x.union(bins.bounds(0, i));
        y = y.union(bins.bounds(1, i));
        z = z.union(bins.bounds(2, i));
        cnt += bins.counts(i);
        right_area[i] = half_areas(&x, &y, &z);
        right_count[i] = cnt;
    }
    let (mut x, mut y, mut z, mut cnt) = (Aabb::EMPTY, Aabb::EMPTY, Aabb::EMPTY, UVec4::ZERO);
    for i in 1..nb {
        x = x.union(bins.bounds(0, i - 1));
        y = y.union(bins.bounds(1, i - 1));
        z = z.union(bins.bounds(2, i - 1));
        cnt += bins.counts(i - 1);
        let left_blocks = to_f32(blocks4(cnt, bs));
        let right_blocks = to_f32(blocks4(right_count[i], bs));
        let weight = half_areas(&x, &y, &z) * left_blocks + right_area[i] * right_blocks;
        visit(SweptPlanes { bin: i, weight, left: cnt, right: right_count[i] });
    }
}

/// Put the primitives left of split `s` first, and bound both sides: their boxes are the
/// split's (from the bins), their centroids' boxes grown in the same pass, which saves a pass
/// over the node's primitives (a tenth of the binary tree's build).
fn partition(prims: &mut [BuildPrim], s: &Split) -> Halves {
    // One loop per axis, the axis a constant in each: with the axis a variable, every
    // primitive's test went through a jump table to its lane.
    let (mid, [left, right]) = match s.axis {
        0 => partition_on::<0>(prims, s),
        1 => partition_on::<1>(prims, s),
        _ => partition_on::<2>(prims, s),
    };
    Halves {
        mid,
        left: Bounds { bounds: s.left, centroids: left },
        right: Bounds { bounds: s.right, centroids: right },
    }
}

/// [`partition`] along `AXIS`: the number put left and the boxes of the centroids that went
/// left and right.
///
/// Lomuto's scheme without a branch on the side: every primitive is swapped with the first
/// one of the right part, which grows or not by the comparison. Primitives arrive in file
/// order, where the side is a coin toss: Hoare's scheme, which branches on it, mispredicted
/// for about half of them on every level. The centroid boxes grow without a branch too.
#[inline(always)]
fn partition_on<const AXIS: usize>(prims: &mut [BuildPrim], s: &Split) -> (usize, [Aabb; 2]) {
    // The binning's arithmetic: for `rel >= 0` and a whole `s.bin` in 1..bins,
    // `trunc(min(rel, bins - 1)) < s.bin` exactly when `rel < s.bin` (the split axis has
    // extent, so `rel` is never NaN).
    let plane = s.bin as f32;
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86-64, and these intrinsics only compute on registers.
        unsafe {
            // Every lane of the test, as the scalar `(c - lo) * scale < plane` computes lane `AXIS`.
            let (lo, scale, plane) = (_mm_set1_ps(s.lo), _mm_set1_ps(s.scale), _mm_set1_ps(plane));
            let half = _mm_set1_ps(0.5);
            // Or-ed into a centroid, a quiet NaN's bits make it NaN, which `min` and `max` pass
            // over when it is their first operand (SSE returns the second): the side the
            // primitive did not go to keeps its box. Where the box takes which of two equal
            // zeros may differ from a sequential union's; the centroids' box only places the
            // bins, where the zeros' signs make no difference.
            let nan = _mm_castsi128_ps(_mm_set1_epi32(0x7fc0_0000));
            let inf = _mm_set1_ps(f32::INFINITY);
            let neg_inf = _mm_set1_ps(f32::NEG_INFINITY);
            let (mut lmin, mut lmax, mut rmin, mut rmax) = (inf, neg_inf, inf, neg_inf);
            let mut mid = 0;
            for i in 0..prims.len() {
                let p = prims[i];
                // [`BuildPrim::centroid`]'s arithmetic.
                let c = _mm_mul_ps(half, _mm_add_ps(p.lo.into(), p.hi.into()));
                let lt = _mm_cmplt_ps(_mm_mul_ps(_mm_sub_ps(c, lo), scale), plane);
                let goes = match AXIS {
                    0 => _mm_shuffle_ps::<0x00>(lt, lt),
                    1 => _mm_shuffle_ps::<0x55>(lt, lt),
                    _ => _mm_shuffle_ps::<0xaa>(lt, lt),
                };
                let (to_left, to_right) = (_mm_or_ps(c, _mm_andnot_ps(goes, nan)), _mm_or_ps(c, _mm_and_ps(goes, nan)));
                lmin = _mm_min_ps(to_left, lmin);
                lmax = _mm_max_ps(to_left, lmax);
                rmin = _mm_min_ps(to_right, rmin);
                rmax = _mm_max_ps(to_right, rmax);
                prims.swap(i, mid);
                mid += (_mm_movemask_ps(goes) & 1) as usize;
            }
            let aabb = |min: __m128, max: __m128| Aabb { min: Vec3A::from(min), max: Vec3A::from(max) };
            (mid, [aabb(lmin, lmax), aabb(rmin, rmax)])
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let (mut left, mut right) = (Aabb::EMPTY, Aabb::EMPTY);
        let mut mid = 0;
        for i in 0..prims.len() {
            let goes = (prims[i].centroid_on(AXIS) - s.lo) * s.scale < plane;
            let c = prims[i].centroid();
            let (m, inf) = (glam::BVec3A::splat(goes), Vec3A::INFINITY);
            left = Aabb { min: left.min.min(Vec3A::select(m, c, inf)), max: left.max.max(Vec3A::select(m, c, -inf)) };
            right =
                Aabb { min: right.min.min(Vec3A::select(m, inf, c)), max: right.max.max(Vec3A::select(m, -inf, c)) };
            prims.swap(i, mid);
            mid += usize::from(goes);
        }
        (mid, [left, right])
    }
}

/// Put the primitives that `goes_left` first; returns their number.
fn partition_by(prims: &mut [BuildPrim], goes_left: impl Fn(&BuildPrim) -> bool) -> usize {
    // Lomuto's scheme without a branch on the side, as in [`partition_on`].
    let mut mid = 0;
    for i in 0..prims.len() {
        let left = goes_left(&prims[i]);
        prims.swap(i, mid);
        mid += usize::from(left);
    }
    mid
}

/// Halve by count along the widest centroid axis: the fallback when the SAH finds no plane
/// (all centroids in one point) but the set is too large for one leaf.
fn median_split(prims: &mut [BuildPrim], centroids: &Aabb) -> usize {
    let axis = centroids.extent().max_position();
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |a, b| a.centroid_on(axis).total_cmp(&b.centroid_on(axis)));
    mid
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the sweep's callers kept before [`first_min`]: the best so far by a strict `<`.
    fn scan<const N: usize>(weights: &[[f32; N]; 3]) -> Option<(usize, usize, f32)> {
        let mut best: Option<(usize, usize, f32)> = None;
        for (axis, row) in weights.iter().enumerate() {
            for (bin, &w) in row.iter().enumerate() {
                if w < best.map_or(f32::INFINITY, |b| b.2) {
                    best = Some((axis, bin, w));
                }
            }
        }
        best
    }

    #[test]
    fn blocks4_is_blocks_lane_by_lane() {
        for bs in 1..=9 {
            for n in [0, 1, 2, 3, 4, 5, 7, 8, 9, 1000, u32::MAX >> 1] {
                let lanes = UVec4::new(n, n + 1, n / 2, n.saturating_sub(3));
                let want = lanes.to_array().map(|c| blocks(c, bs));
                assert_eq!(blocks4(lanes, bs).to_array(), want, "{n} in blocks of {bs}");
            }
        }
    }

    #[test]
    fn first_min_is_the_sequential_scans_choice() {
        // Few distinct values, so ties across bins and axes are common; NaN and infinities.
        let values = [0.0, -0.0, 1.0, 2.5, 1e30, f32::INFINITY, f32::NAN, f32::MIN_POSITIVE];
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            values[(state >> 40) as usize % values.len()]
        };
        for _ in 0..20_000 {
            let mut w = [[f32::INFINITY; 16]; 3];
            w.iter_mut().flatten().for_each(|x| *x = next());
            let lanes: [Vec4; 16] = std::array::from_fn(|bin| Vec4::new(w[0][bin], w[1][bin], w[2][bin], next()));
            let got = first_min(&lanes).map(|b| (b.axis, b.bin, b.weight));
            let want = scan(&w);
            assert_eq!(got.map(|g| (g.0, g.1)), want.map(|g| (g.0, g.1)), "{w:?}");
            assert_eq!(got.map(|g| g.2.to_bits()), want.map(|g| g.2.to_bits()), "{w:?}");
        }
        assert!(first_min(&[Vec4::INFINITY; 8]).is_none());
        assert!(first_min(&[Vec4::NAN; 8]).is_none());
        assert!(first_min(&[Vec4::new(f32::INFINITY, f32::NAN, f32::INFINITY, 0.0); 8]).is_none());
    }
}
