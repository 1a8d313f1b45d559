//! Bounding volume hierarchies. The binary BVH, in one flat array: its node layout
//! ([`node`]), binned-SAH build ([`build`]; [`split_candidates`] shows a node's SAH planes and
//! costs), closest-hit and any-hit traversal
//! ([`traverse`]), invariant checks ([`validate`]) and statistics ([`stats`]). It serves the
//! debugger's level view, and the wide trees that rendering traverses are collapsed from it
//! ([`wide`]: the collapse, the layouts, the width chosen for the CPU, the SIMD kernels, the
//! traversals, camera-ray packets and grouped shadow rays; its documentation maps its files).
//!
//! The BVH knows only boxes. Primitives are reached through the [`Primitives`] trait by their
//! position in [`Bvh::prim_indices`] order, so the owner can store them in that order and a
//! leaf's primitives sit next to each other in memory.

pub mod build;
pub mod node;
pub mod split_candidates;
pub mod stats;
pub mod traverse;
pub mod validate;
pub mod wide;

pub use build::{BuildParams, SplitRule};
pub use node::BvhNode;
pub use split_candidates::{Candidate, ChosenSplit, SplitCandidates, split_candidates};
pub use stats::{BvhStats, LevelBox, NoObserver, NodeLog, QueryKind, TraversalObserver, TraversalStats};
pub use validate::BvhError;
pub use wide::{
    Bvh4, Bvh8, Bvh16, ChildRef, FrustumTest, LoggedQuery, Occluders, PACKET, SimdLevel, TILE_RUNS, TileHits,
    TraversalLog, WideBox, WideBvh, WideRef, WideTree,
};

use crate::geometry::PrimHit;
use crate::ray::Ray;

/// Which of a scene's two trees the debugger's level views and exports draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum BvhTree {
    /// The wide tree (8 or 16 children a node) that rendering traverses; its visited nodes are
    /// the ones the renderer's traversals entered, as the ray recorder keeps them.
    Wide,
    /// The course's binary tree, which the wide one is collapsed from and rendering does not
    /// traverse; its visited nodes are a replay of the recorded rays through it.
    Binary,
}

/// Deepest tree the builder makes; traversal stacks are sized by it.
pub const MAX_DEPTH: usize = 64;

/// The primitives a BVH was built over, addressed by their position in BVH order.
pub trait Primitives {
    /// Intersect primitive `index` (a position in [`Bvh::prim_indices`]) within `[t_min, t_max]`.
    fn intersect(&self, index: u32, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit>;

    /// Primitive `index` as a static triangle, if it is one: such primitives may be packed
    /// for SIMD intersection ([`wide::Tri4`]), which must then give the hits `intersect` does.
    fn triangle(&self, _index: u32) -> Option<crate::geometry::Triangle> {
        None
    }

    /// Whether [`Primitives::triangle`] gives primitive `index`: what the wide tree's collapse
    /// asks of every primitive when it plans which leaves to pack, before it packs them.
    /// Implementations that know it without making the triangle say so here (making it reads
    /// the triangle's corners, cache misses in the tree's order).
    fn is_triangle(&self, index: u32) -> bool {
        self.triangle(index).is_some()
    }
}

/// A bounding volume hierarchy in one flat array, depth-first: a node's first child follows it.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// The nodes; `nodes[0]` is the root. Empty when built over no (finite) primitive.
    pub nodes: Vec<BvhNode>,
    /// For each BVH-order slot, the index of the input primitive stored there. Primitives with
    /// non-finite bounds (NaN or infinite vertices) are left out: no ray can hit them.
    pub prim_indices: Vec<u32>,
}

/// A hit reported by the BVH: the primitive's BVH-order slot and where it was hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhHit {
    /// Slot of the primitive in [`Bvh::prim_indices`] order.
    pub slot: u32,
    /// Distance and surface parameters.
    pub hit: PrimHit,
}
