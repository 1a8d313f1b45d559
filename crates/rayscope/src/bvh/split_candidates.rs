//! The SAH's choice made visible: for a node of the binary BVH, every candidate split plane
//! of the binned SAH with its cost, and the plane taken, computed by the builder's own binning
//! and sweep ([`super::build`]), not a second formula.

use serde::Serialize;

use super::build::{
    Bins, Bounds, BuildParams, BuildPrim, MAX_BINS, bin_count, fill_bins, leaf_cost, sah_cost, sweep, swept_axes,
};
use super::{Bvh, MAX_DEPTH};
use crate::geometry::Aabb;
use crate::math::Vec3A;

/// One candidate plane of a node's SAH sweep.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Candidate {
    /// Where the plane cuts its axis (a world coordinate): primitives whose box centre lies
    /// below go left.
    pub position: f32,
    /// Primitives to its left.
    pub left: u32,
    /// Primitives to its right.
    pub right: u32,
    /// Its SAH cost, `traversal_cost + intersection_cost x (A_left x blocks_left + A_right x
    /// blocks_right) / A_node` (the builder's); `None` when a side is empty (no split).
    pub cost: Option<f32>,
}

/// The plane the SAH picks: the first candidate of least cost, in axis then position order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct ChosenSplit {
    /// Its axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Its index in [`SplitCandidates::axis`]`[axis]`.
    pub index: usize,
}

/// A node's candidate split planes, per axis, and the split taken.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SplitCandidates {
    /// The node's index in [`Bvh::nodes`].
    pub node: u32,
    /// Its depth (the root is 0).
    pub depth: u32,
    /// The primitives under it.
    pub prims: u32,
    /// Its box.
    pub min: [f32; 3],
    /// Its box.
    pub max: [f32; 3],
    /// Bins per axis the builder used for it.
    pub bins: u32,
    /// The candidates of each axis (x, y, z), in position order; empty for an axis along
    /// which every box centre is the same.
    pub axis: [Vec<Candidate>; 3],
    /// The cheapest candidate; `None` when no plane separates the primitives.
    pub chosen: Option<ChosenSplit>,
    /// The SAH cost of keeping the primitives in one leaf.
    pub leaf_cost: f32,
    /// Whether the builder split the node (it has children): the cheapest plane when that
    /// beats the leaf, or a node too large for a leaf ([`BuildParams::max_leaf_size`]).
    pub split: bool,
    /// Primitives in the node's left child, when it was split.
    pub left_child_prims: Option<u32>,
}

impl SplitCandidates {
    /// The chosen candidate.
    pub fn chosen_candidate(&self) -> Option<&Candidate> {
        self.chosen.map(|c| &self.axis[c.axis][c.index])
    }
}

/// The candidate planes of node `node` of `bvh`, built with `params` over primitives with the
/// boxes `bounds` (what [`Bvh::build`] was given); `None` for a node index out of range. The
/// numbers are the builder's: the same bins (at most [`MAX_BINS`]) from the same centroids,
/// the same sweep and cost, so for a tree built with the SAH the chosen plane is the one that
/// split the node (a test checks it).
pub fn split_candidates(bvh: &Bvh, bounds: &[Aabb], node: u32, params: &BuildParams) -> Option<SplitCandidates> {
    let n = bvh.nodes.get(node as usize)?;
    let (lo, hi, depth) = prim_range(bvh, node)?;
    let prims: Vec<BuildPrim> =
        bvh.prim_indices[lo as usize..hi as usize].iter().map(|&i| BuildPrim::new(bounds[i as usize], i)).collect();
    let b = Bounds::of(&prims);
    let nb = bin_count(prims.len(), params);
    let extent = b.centroids.extent();
    let scale = Vec3A::splat(nb as f32) / extent;
    let mut bins = Bins::<MAX_BINS>::EMPTY;
    fill_bins::<MAX_BINS>(&prims, b.centroids.min, scale, nb, &mut bins);
    let parent_area = b.bounds.half_area().max(f32::MIN_POSITIVE);
    let swept = swept_axes(extent);
    let mut planes = Vec::with_capacity(nb);
    sweep(&bins, nb, params.block_size, |p| planes.push(p));
    let mut axis: [Vec<Candidate>; 3] = Default::default();
    let (mut best_weight, mut chosen) = (f32::INFINITY, None);
    // In axis, then bin order: the order in which the builder breaks ties.
    for (a, candidates) in axis.iter_mut().enumerate().filter(|(a, _)| swept[*a]) {
        for p in &planes {
            let (weight, left, right) = (p.weight[a], p.left[a], p.right[a]);
            let splits = left != 0 && right != 0;
            if splits && weight < best_weight {
                best_weight = weight;
                chosen = Some(ChosenSplit { axis: a, index: candidates.len() });
            }
            candidates.push(Candidate {
                position: b.centroids.min[a] + p.bin as f32 / scale[a],
                left,
                right,
                cost: splits.then(|| sah_cost(weight, parent_area, params)),
            });
        }
    }
    let split = !n.is_leaf();
    Some(SplitCandidates {
        node,
        depth,
        prims: prims.len() as u32,
        min: n.min,
        max: n.max,
        bins: nb as u32,
        axis,
        chosen,
        leaf_cost: leaf_cost(prims.len(), params),
        split,
        left_child_prims: split.then(|| prim_range(bvh, node + 1).map_or(0, |(l, h, _)| h - l)),
    })
}

/// The slots `lo..hi` of [`Bvh::prim_indices`] under node `node` (a subtree's primitives are
/// contiguous: from its leftmost leaf's first to its rightmost leaf's last), and its depth.
fn prim_range(bvh: &Bvh, node: u32) -> Option<(u32, u32, u32)> {
    let depth = depth_of(bvh, node)?;
    let (mut left, mut right) = (node, node);
    for _ in 0..MAX_DEPTH {
        if bvh.nodes[left as usize].is_leaf() {
            break;
        }
        left += 1;
    }
    for _ in 0..MAX_DEPTH {
        if bvh.nodes[right as usize].is_leaf() {
            break;
        }
        right = bvh.nodes[right as usize].start;
    }
    let (l, r) = (&bvh.nodes[left as usize], &bvh.nodes[right as usize]);
    Some((l.start, r.start + r.count, depth))
}

/// The depth of node `node`, found by walking down from the root.
fn depth_of(bvh: &Bvh, node: u32) -> Option<u32> {
    let (mut at, mut depth) = (0u32, 0u32);
    while at != node {
        let n = bvh.nodes.get(at as usize)?;
        if n.is_leaf() {
            return None;
        }
        // The right child's subtree starts at `start`; everything before it is the left's.
        at = if node >= n.start { n.start } else { at + 1 };
        depth += 1;
    }
    Some(depth)
}
