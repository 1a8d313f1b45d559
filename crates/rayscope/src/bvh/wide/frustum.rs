//! Frustum culling: whether a frustum of rays (the camera rays of a tile of pixels) may meet
//! any leaf box of the tree, found by walking the tree with the frustum in place of a ray.
//! A tile whose frustum meets none has nothing to hit, and its rays need no traversal.

use super::kernels::{Lanes, NodeWidth};
use super::stack::Stack;
use super::{ChildRef, WideBvh};
use crate::geometry::Frustum;

/// What [`WideBvh::frustum_test`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrustumTest {
    /// Whether a leaf box may meet the frustum (false: no ray in the frustum hits anything).
    pub may_hit: bool,
    /// Nodes whose children's boxes the walk tested (the debugger's measure of its cost).
    pub nodes: u32,
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// Whether a ray inside `frustum` may hit a primitive of the tree: depth first through
    /// the nodes whose boxes may meet the frustum, stopping at the first leaf box that may
    /// ([`Frustum::may_meet`], conservative: `may_hit` is never false for a frustum a
    /// primitive's box meets).
    pub fn frustum_test(&self, frustum: &Frustum) -> FrustumTest {
        let mut out = FrustumTest::default();
        if self.nodes.is_empty() {
            return out;
        }
        let mut stack = Stack::<ChildRef>::new();
        stack.push(ChildRef::ROOT);
        while let Some(node) = stack.pop() {
            out.nodes += 1;
            let n = &self.nodes[node.node_index() as usize];
            for (i, &child) in n.child.iter().enumerate() {
                if child == ChildRef::EMPTY || !frustum.may_meet(&n.child_bounds(i)) {
                    continue;
                }
                if child.is_leaf() {
                    out.may_hit = true;
                    return out;
                }
                // At most `W - 1` more entries a level than the node popped: the traversals'
                // bound (`fits_stack`).
                stack.push(child);
            }
        }
        out
    }
}
