//! Wide BVHs collapsed from the binary one, for rendering: each node holds its `W` children's
//! boxes as structure-of-arrays, so one SIMD slab test checks them all. Rendering uses the
//! 16-wide tree ([`Bvh16`]) where the CPU has AVX-512, whose nodes are then tested with one
//! 512-bit instruction per step, and the 8-wide tree ([`Bvh8`]) elsewhere: with AVX2, one
//! 256-bit instruction per step, else the portable `wide` vectors (two SSE or NEON halves).
//! The choice is made at run time ([`WideTree`]). The 4-wide tree ([`Bvh4`]) is
//! the same code at half the width, kept to measure one against the other. Wider nodes mean
//! fewer levels, and with them fewer loop iterations, stack entries and dependent loads per
//! ray. The binary BVH stays for the debugger's level view.
//!
//! # Map
//!
//! The files in the order data flows, from the binary tree to the hits:
//! - `collapse.rs`: the binary BVH collapsed into a wide tree by the surface area heuristic,
//!   leaves of static triangles packed four to a [`Tri4`] block;
//! - `layout.rs`: what the tree stores ([`WideNode`], [`Tri4`], [`LeafRange`]); `child.rs`: the
//!   child references ([`ChildRef`]), which say what and where each child is;
//! - `tree.rs`: [`WideTree`], the width rendering uses, chosen for the CPU;
//! - `simd.rs`: [`SimdLevel`], the instruction set, detected at run time, and the tokens that
//!   prove the CPU has a level's features (what the traversals' `unsafe` blocks rest on);
//! - `kernels.rs`: the slab test (documented there) and the packed triangle test on the
//!   portable vectors, and which test each width uses at each level; `avx.rs`: the AVX2 and
//!   AVX-512 tests;
//! - `stack.rs`: the traversals' fixed stack;
//! - `traverse.rs`: closest-hit and any-hit traversal, one ray at a time;
//! - `packet/`: closest hits of packets of camera rays that share an origin (`mod.rs`: the
//!   traversal; `setup.rs`: the packet's set-up, portable and in AVX2 lanes; `tile.rs`: up
//!   to eight packets, a tile's rows, walking the tree once);
//! - `occluded_packet.rs`: any-hit for packets of rays with their own origins (shadow rays
//!   of neighbouring pixels towards one light), each ray with its single-ray node test;
//! - `frustum.rs`: whether a frustum of rays (a tile's camera rays) may meet any leaf box;
//! - `shadow.rs`: shadow rays grouped per shading point, answered without a traversal;
//! - `validate.rs`: the tree's invariants;
//! - `visits.rs`: what the debugger draws of the tree: the boxes of a level, and the nodes and
//!   leaves a traversal entered ([`TraversalLog`]) with their boxes.

#[cfg(target_arch = "x86_64")]
mod avx;
mod child;
mod collapse;
mod frustum;
mod kernels;
mod layout;
mod occluded_packet;
mod packet;
mod shadow;
mod simd;
mod stack;
mod traverse;
mod tree;
mod validate;
mod visits;

pub use child::ChildRef;
pub use frustum::FrustumTest;
/// The bound of the wide tree's methods (the widths it is made in: 4, 8 and 16), for code
/// generic over the width; the node tests it names stay inside the crate.
#[doc(hidden)]
pub use kernels::{Lanes, NodeWidth};
pub use layout::{EMPTY, LeafRange, Tri4, WideNode};
pub use packet::{PACKET, PacketHits, TILE_RUNS, TileHits};
pub use shadow::{MAX_LEAVES, MAX_TRIANGLES, Occluders};
pub use simd::SimdLevel;
pub use tree::{MIN_PRIMS_16, WideTree};
pub use visits::{LoggedQuery, TraversalLog, WideBox, WideRef};

use simd::Simd;

/// A wide BVH: nodes of `W` children, leaves of packed triangles or primitive ranges.
#[derive(Clone, Debug, Default)]
pub struct WideBvh<const W: usize> {
    /// Nodes; `nodes[0]` is the root. Empty for an empty scene.
    pub nodes: Vec<WideNode<W>>,
    /// Packed triangles of the leaves that hold only static triangles.
    pub blocks: Vec<Tri4>,
    /// The other leaves (spheres, moving shapes, mixes, oversized leaves): slot ranges whose
    /// primitives are intersected one by one through [`crate::bvh::Primitives`].
    pub ranges: Vec<LeafRange>,
    /// The largest magnitude of any box coordinate (0 for an empty tree): what the slab
    /// tests' bound on their rounding is scaled by (see `kernels.rs`, `SlabOrigin`).
    pub reach: f32,
    /// The traversal variant: [`SimdLevel::detect`]'s when built, with the token that proves
    /// the CPU has it; [`WideBvh::portable`] selects the baseline.
    simd: Simd,
}

/// The 4-wide BVH (128-byte nodes, tested with 4-lane vectors).
pub type Bvh4 = WideBvh<4>;
/// The 8-wide BVH (256-byte nodes, one AVX2 test per step on x86-64): what rendering
/// traverses where the CPU lacks AVX-512.
pub type Bvh8 = WideBvh<8>;
/// The 16-wide BVH (448-byte nodes, one AVX-512 test per step): what rendering traverses
/// where the CPU has AVX-512. Its traversals need [`WideBvh::fits_stack`] (a query on a
/// deeper tree would overflow the fixed stack and panic); [`WideTree`] checks.
pub type Bvh16 = WideBvh<16>;

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// Levels of nodes (0 for an empty tree).
    pub fn depth(&self) -> usize {
        let mut depth = vec![0usize; self.nodes.len()];
        if let Some(d) = depth.first_mut() {
            *d = 1;
        }
        // Children come after their parents (the collapse appends them depth-first).
        for i in 0..self.nodes.len() {
            for &c in &self.nodes[i].child {
                if c != ChildRef::EMPTY && !c.is_leaf() {
                    depth[c.node_index() as usize] = depth[i] + 1;
                }
            }
        }
        depth.into_iter().max().unwrap_or(0)
    }

    /// The traversal variant in use.
    pub fn simd_level(&self) -> SimdLevel {
        self.simd.level()
    }

    /// The same tree traversed by the baseline code (to compare it with the detected one).
    pub fn portable(mut self) -> Self {
        self.simd = Simd::Portable;
        self
    }
}
