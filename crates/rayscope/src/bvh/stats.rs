//! Tree statistics, per-ray traversal counters, and the boxes of one level for the debugger.

use serde::Serialize;

use super::{Bvh, BvhNode, ChildRef};
use crate::geometry::Aabb;
use crate::ray::Ray;

/// Counters of one traversal (or a sum of many): what a heat map shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalStats {
    /// Nodes whose box was tested.
    pub nodes_visited: u32,
    /// Primitives intersected.
    pub prims_tested: u32,
}

/// Which query of the wide tree a traversal answers: what [`TraversalObserver::query`] is
/// told when one starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum QueryKind {
    /// The closest hit of one ray ([`crate::bvh::WideBvh::intersect`]).
    ClosestHit,
    /// The closest hit of one ray of a packet of camera rays
    /// ([`crate::bvh::WideBvh::intersect_packet`]): inner nodes are tested once for the whole
    /// packet, so the ray pays for every node the packet enters; leaves are tested per ray.
    Packet,
    /// The closest hit of one ray of a tile of camera rays, up to eight packets of them
    /// ([`crate::bvh::WideBvh::intersect_tile`]): inner nodes are tested once for the whole
    /// tile, so the ray pays for every node the tile enters; leaves are tested per ray.
    Tile,
    /// Whether anything blocks a shadow ray ([`crate::bvh::WideBvh::occluded`]): stops at the
    /// first blocker found.
    AnyHit,
    /// The frustum query of a group of shadow rays from one point to one light
    /// ([`crate::bvh::WideBvh::occluders`]): the nodes and leaves it opens, whose triangles the
    /// group's rays then test with no traversal of their own.
    ShadowGroup,
}

/// Watches a traversal. Every method defaults to nothing.
pub trait TraversalObserver {
    /// Whether the observer watches at all: a traversal skips the bookkeeping it does only for
    /// an observer (a packet's loop over its rays at each node) when not, so that
    /// [`NoObserver`] compiles to the traversal without one.
    const WATCHES: bool = true;
    /// A query of `kind` for `ray` (its real interval and time) starts; the events that follow
    /// are its, up to the next query.
    #[inline(always)]
    fn query(&mut self, _kind: QueryKind, _ray: &Ray) {}
    /// `n` node boxes were tested against the ray.
    #[inline(always)]
    fn boxes_tested(&mut self, _n: u32) {}
    /// A primitive was intersected.
    #[inline(always)]
    fn prim_tested(&mut self) {}
    /// The traversal entered node `index` (its box was hit and it was processed).
    #[inline(always)]
    fn entered(&mut self, _index: u32) {}
    /// A traversal of a wide tree entered leaf `leaf` (its box was hit and its primitives are
    /// tested, up to the first blocker for an any-hit query). Binary trees report their leaves
    /// through [`TraversalObserver::entered`], as their other nodes.
    #[inline(always)]
    fn entered_leaf(&mut self, _leaf: ChildRef) {}
}

impl TraversalObserver for TraversalStats {
    #[inline(always)]
    fn boxes_tested(&mut self, n: u32) {
        self.nodes_visited += n;
    }
    #[inline(always)]
    fn prim_tested(&mut self) {
        self.prims_tested += 1;
    }
}

/// Observes nothing: traversal at full speed.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoObserver;

impl TraversalObserver for NoObserver {
    const WATCHES: bool = false;
}

/// Records the nodes a traversal entered, in order: what the debugger's "visited nodes" view
/// draws.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NodeLog(pub Vec<u32>);

impl TraversalObserver for NodeLog {
    fn entered(&mut self, index: u32) {
        self.0.push(index);
    }
}

/// Summary of a built tree.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// All nodes.
    pub nodes: usize,
    /// Leaf nodes.
    pub leaves: usize,
    /// Number of levels (a lone root leaf is one level; an empty tree zero).
    pub levels: usize,
    /// Mean primitives per leaf.
    pub mean_leaf_size: f32,
    /// SAH cost with unit traversal and intersection costs, relative to the root's area.
    pub sah_cost: f32,
}

/// A box of the level view: the node, its box, and whether it is a leaf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelBox {
    /// Index of the node in [`Bvh::nodes`].
    pub node: u32,
    /// Its box.
    pub bounds: Aabb,
    /// Its depth (the root is level 0).
    pub level: u32,
    /// Whether it is a leaf (a leaf above the requested level ends its branch there).
    pub is_leaf: bool,
}

impl Bvh {
    /// Depth-first walk yielding each node index with its level.
    fn walk(&self, mut f: impl FnMut(usize, u32, &BvhNode)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![(0usize, 0u32)];
        while let Some((i, level)) = stack.pop() {
            let n = &self.nodes[i];
            f(i, level, n);
            if !n.is_leaf() {
                stack.push((n.start as usize, level + 1));
                stack.push((i + 1, level + 1));
            }
        }
    }

    /// Node and leaf counts, levels, mean leaf size and SAH cost.
    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats { nodes: self.nodes.len(), ..BvhStats::default() };
        let Some(root) = self.nodes.first() else {
            return s;
        };
        let root_area = root.bounds().half_area().max(f32::MIN_POSITIVE);
        let mut prims = 0usize;
        let mut cost = 0.0f64;
        self.walk(|_, level, n| {
            s.levels = s.levels.max(level as usize + 1);
            let rel = (n.bounds().half_area() / root_area) as f64;
            if n.is_leaf() {
                s.leaves += 1;
                prims += n.count as usize;
                cost += rel * n.count as f64;
            } else {
                cost += rel;
            }
        });
        s.mean_leaf_size = prims as f32 / s.leaves as f32;
        s.sah_cost = cost as f32;
        s
    }

    /// The boxes at `level`, and the leaves that end above it (the course report's choice,
    /// so that every primitive is covered by some drawn box).
    pub fn boxes_at_level(&self, level: u32) -> Vec<LevelBox> {
        let mut out = Vec::new();
        self.walk(|i, l, n| {
            if l == level || (l < level && n.is_leaf()) {
                out.push(LevelBox { node: i as u32, bounds: n.bounds(), level: l, is_leaf: n.is_leaf() });
            }
        });
        out
    }
}
