//! Structural invariants of a built tree.

use super::Bvh;
use crate::geometry::Aabb;

/// A broken invariant, with the node where it was found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BvhError {
    /// A child index points outside the array or not after its parent.
    #[error("node {node}: child index {child} is out of order or out of range")]
    BadChild {
        /// The parent.
        node: usize,
        /// The offending child index.
        child: usize,
    },
    /// A child's box sticks out of its parent's.
    #[error("node {node}: child {child}'s box is not inside its parent's")]
    ChildOutside {
        /// The parent.
        node: usize,
        /// The child.
        child: usize,
    },
    /// A leaf's range runs past the primitive array.
    #[error("leaf {node}: primitive range {start}..{end} is out of range")]
    BadRange {
        /// The leaf.
        node: usize,
        /// First slot.
        start: usize,
        /// One past the last slot.
        end: usize,
    },
    /// A primitive's box sticks out of its leaf's.
    #[error("leaf {node}: primitive {prim}'s box is not inside the leaf's")]
    PrimOutside {
        /// The leaf.
        node: usize,
        /// The input index of the primitive.
        prim: u32,
    },
    /// A slot is covered by no leaf or by several, or a node is unreachable.
    #[error("slot {slot} is referenced {times} times (expected once)")]
    Coverage {
        /// The slot.
        slot: usize,
        /// How often leaves cover it.
        times: usize,
    },
    /// A primitive index appears twice, or an index is out of range.
    #[error("primitive {prim} is stored twice or does not exist")]
    BadPrimIndex {
        /// The input index.
        prim: u32,
    },
    /// Nodes exist that no path from the root reaches (or some are reached twice).
    #[error("{0} nodes are unreachable from the root or shared")]
    Unreachable(usize),
}

impl Bvh {
    /// Check every invariant: children follow their parent and lie inside its box; leaves
    /// cover every slot exactly once and contain their primitives' boxes (`prim_bounds` are the
    /// input boxes the tree was built from); every node is reachable; every stored primitive
    /// index is valid and unique.
    pub fn validate(&self, prim_bounds: &[Aabb]) -> Result<(), BvhError> {
        let mut seen = vec![false; prim_bounds.len()];
        for &p in &self.prim_indices {
            match seen.get_mut(p as usize) {
                Some(s) if !*s => *s = true,
                _ => return Err(BvhError::BadPrimIndex { prim: p }),
            }
        }
        if self.nodes.is_empty() {
            return match self.prim_indices.is_empty() {
                true => Ok(()),
                false => Err(BvhError::Coverage { slot: 0, times: 0 }),
            };
        }
        let mut covered = vec![0usize; self.prim_indices.len()];
        let mut reached = 0usize;
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            reached += 1;
            let n = &self.nodes[i];
            let bounds = n.bounds();
            if n.is_leaf() {
                let (start, end) = (n.start as usize, n.start as usize + n.count as usize);
                if end > self.prim_indices.len() {
                    return Err(BvhError::BadRange { node: i, start, end });
                }
                for (c, &prim) in covered[start..end].iter_mut().zip(&self.prim_indices[start..end]) {
                    *c += 1;
                    if !bounds.contains(&prim_bounds[prim as usize]) {
                        return Err(BvhError::PrimOutside { node: i, prim });
                    }
                }
            } else {
                for child in [i + 1, n.start as usize] {
                    if child <= i || child >= self.nodes.len() {
                        return Err(BvhError::BadChild { node: i, child });
                    }
                    if !bounds.contains(&self.nodes[child].bounds()) {
                        return Err(BvhError::ChildOutside { node: i, child });
                    }
                    stack.push(child);
                }
            }
        }
        if let Some((slot, &times)) = covered.iter().enumerate().find(|(_, c)| **c != 1) {
            return Err(BvhError::Coverage { slot, times });
        }
        if reached != self.nodes.len() {
            return Err(BvhError::Unreachable(self.nodes.len().abs_diff(reached)));
        }
        Ok(())
    }
}
