//! Binned SAH construction, parallel over subtrees with rayon.

use rayon::join;

use super::{Bvh, BvhNode, MAX_DEPTH};
use crate::geometry::Aabb;
use crate::math::Vec3A;

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
        }
    }
}

#[derive(Clone, Copy)]
struct BuildPrim {
    bounds: Aabb,
    centroid: Vec3A,
    index: u32,
}

impl Bvh {
    /// Build over primitives with these bounding boxes. Primitives whose box is not finite
    /// (NaN or infinite coordinates) are left out.
    pub fn build(bounds: &[Aabb], params: &BuildParams) -> Bvh {
        let mut prims: Vec<BuildPrim> = bounds
            .iter()
            .enumerate()
            .filter(|(_, b)| b.is_finite() && !b.is_empty())
            .map(|(i, b)| BuildPrim { bounds: *b, centroid: b.center(), index: i as u32 })
            .collect();
        if prims.is_empty() {
            return Bvh::default();
        }
        let mut nodes = Vec::with_capacity(2 * prims.len());
        build_node(&mut prims, 0, 0, params, &mut nodes);
        // Subtrees were built with second-child indices relative to their own node, so they
        // could be built apart and concatenated; make them absolute now.
        for (i, node) in nodes.iter_mut().enumerate() {
            if !node.is_leaf() {
                node.start += i as u32;
            }
        }
        Bvh { nodes, prim_indices: prims.iter().map(|p| p.index).collect() }
    }
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

struct Split {
    axis: usize,
    /// Primitives whose bin is below this go left.
    bin: usize,
    cost: f32,
}

/// Appends the subtree over `prims` (which occupy slots `offset..`) to `out`, depth-first.
fn build_node(prims: &mut [BuildPrim], offset: u32, depth: usize, params: &BuildParams, out: &mut Vec<BvhNode>) {
    let bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds));
    let centroids = prims.iter().fold(Aabb::EMPTY, |b, p| b.grow(p.centroid));
    let n = prims.len();
    let leaf = BvhNode::new(bounds, offset, n as u32);
    if n == 1 || depth + 1 >= MAX_DEPTH {
        out.push(leaf);
        return;
    }
    let split = find_split(prims, &bounds, &centroids, params);
    let bins = params.bins.min(n.next_power_of_two().max(4));
    let leaf_cost = params.intersection_cost * blocks(n, params) as f32;
    let mid = match split {
        Some(s) if s.cost < leaf_cost || n > params.max_leaf_size => partition(prims, &centroids, &s, bins),
        None if n > params.max_leaf_size => median_split(prims, &centroids),
        _ => {
            out.push(leaf);
            return;
        }
    };
    let here = out.len();
    out.push(BvhNode::new(bounds, 0, 0));
    let (left, right) = prims.split_at_mut(mid);
    let right_offset = offset + mid as u32;
    if n > params.parallel_threshold {
        let (l, r) =
            join(|| subtree(left, offset, depth + 1, params), || subtree(right, right_offset, depth + 1, params));
        out[here].start = 1 + l.len() as u32;
        out.extend(l);
        out.extend(r);
    } else {
        build_node(left, offset, depth + 1, params, out);
        out[here].start = (out.len() - here) as u32;
        build_node(right, right_offset, depth + 1, params, out);
    }
}

fn subtree(prims: &mut [BuildPrim], offset: u32, depth: usize, params: &BuildParams) -> Vec<BvhNode> {
    let mut out = Vec::with_capacity(2 * prims.len());
    build_node(prims, offset, depth, params, &mut out);
    out
}

/// Intersection blocks a leaf of `n` primitives takes.
#[inline(always)]
fn blocks(n: usize, params: &BuildParams) -> usize {
    n.div_ceil(params.block_size.max(1))
}

#[inline]
fn bin_of(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

/// Most bins per axis the builder supports (its bins live on the stack).
pub const MAX_BINS: usize = 32;

/// The cheapest binned SAH split over the three axes, or `None` when all centroids coincide.
/// All three axes are binned in one pass over the primitives, into bins on the stack: the
/// build spends most of its time here.
fn find_split(prims: &[BuildPrim], bounds: &Aabb, centroids: &Aabb, params: &BuildParams) -> Option<Split> {
    // Small nodes get fewer bins: with n primitives, n bins already tell every split apart,
    // and the fixed cost of clearing and sweeping 3 x 16 bins dominates there.
    let nb = params.bins.min(prims.len().next_power_of_two().max(4)).clamp(2, MAX_BINS);
    let extent = centroids.extent();
    let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
    let empty = Bin { bounds: Aabb::EMPTY, count: 0 };
    let mut bins = [[empty; MAX_BINS]; 3];
    let lo = centroids.min;
    // A zero extent gives an infinite scale; such an axis is skipped below.
    let scale = Vec3A::splat(nb as f32) / extent;
    for p in prims {
        let rel = (p.centroid - lo) * scale;
        for (axis, axis_bins) in bins.iter_mut().enumerate() {
            let b = &mut axis_bins[(rel[axis] as usize).min(nb - 1)];
            b.bounds = b.bounds.union(p.bounds);
            b.count += 1;
        }
    }
    let mut best: Option<Split> = None;
    let mut right_area = [0.0f32; MAX_BINS];
    let mut right_count = [0u32; MAX_BINS];
    for (axis, bins) in bins.iter().enumerate() {
        if extent[axis] <= 0.0 {
            continue;
        }
        // Sweep from the right to know, for each split plane, the box and count to its right.
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in (1..nb).rev() {
            acc = acc.union(bins[i].bounds);
            cnt += bins[i].count;
            right_area[i] = acc.half_area();
            right_count[i] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in 1..nb {
            acc = acc.union(bins[i - 1].bounds);
            cnt += bins[i - 1].count;
            if cnt == 0 || right_count[i] == 0 {
                continue;
            }
            let cost = params.traversal_cost
                + params.intersection_cost
                    * (acc.half_area() * blocks(cnt as usize, params) as f32
                        + right_area[i] * blocks(right_count[i] as usize, params) as f32)
                    / parent_area;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(Split { axis, bin: i, cost });
            }
        }
    }
    best
}

fn partition(prims: &mut [BuildPrim], centroids: &Aabb, s: &Split, bins: usize) -> usize {
    let bins = bins.clamp(2, MAX_BINS);
    let lo = centroids.min[s.axis];
    // The same arithmetic as the binning, so every primitive lands on its bin's side.
    let scale = (Vec3A::splat(bins as f32) / centroids.extent())[s.axis];
    let mut mid = 0;
    for i in 0..prims.len() {
        if bin_of(prims[i].centroid[s.axis], lo, scale, bins) < s.bin {
            prims.swap(i, mid);
            mid += 1;
        }
    }
    mid
}

/// Halve by count along the widest centroid axis: the fallback when the SAH finds no plane
/// (all centroids in one point) but the set is too large for one leaf.
fn median_split(prims: &mut [BuildPrim], centroids: &Aabb) -> usize {
    let axis = centroids.extent().max_position();
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
    mid
}
