//! The invariants of a collapsed tree, checked against the binary tree it came from.

use super::kernels::{Lanes, NodeWidth};
use super::layout::EMPTY;
use super::{ChildRef, WideBvh};
use crate::bvh::{Bvh, BvhError};
use crate::geometry::Aabb;

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// Check the collapsed tree: every primitive slot is in exactly one leaf reference,
    /// inside its box, and every node is reachable exactly once.
    pub fn validate(&self, bin: &Bvh, prim_bounds: &[Aabb]) -> Result<(), BvhError> {
        let mut covered = vec![0usize; bin.prim_indices.len()];
        if self.nodes.is_empty() {
            return if covered.is_empty() { Ok(()) } else { Err(BvhError::Coverage { slot: 0, times: 0 }) };
        }
        let mut reached = vec![0u32; self.nodes.len()];
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            reached[i] += 1;
            let n = &self.nodes[i];
            for k in 0..W {
                let c = n.child[k];
                if c == ChildRef::EMPTY {
                    continue;
                }
                let b = n.child_bounds(k);
                if c.is_leaf() {
                    let slots: Vec<u32> = if c.is_packed() {
                        let range = c.packed_blocks();
                        let bad = BvhError::BadRange { node: i, start: range.start, end: range.end };
                        let blocks = self.blocks.get(range).ok_or(bad)?;
                        blocks.iter().flat_map(|b| b.slot).filter(|s| *s != EMPTY).collect()
                    } else {
                        let bad = BvhError::BadChild { node: i, child: c.to_bits() as usize };
                        let r = self.ranges.get(c.range_index()).ok_or(bad)?;
                        (r.start..r.start + r.count).collect()
                    };
                    for slot in slots {
                        let Some(cov) = covered.get_mut(slot as usize) else {
                            return Err(BvhError::BadRange { node: i, start: slot as usize, end: slot as usize + 1 });
                        };
                        *cov += 1;
                        let prim = bin.prim_indices[slot as usize];
                        if !b.contains(&prim_bounds[prim as usize]) {
                            return Err(BvhError::PrimOutside { node: i, prim });
                        }
                    }
                } else {
                    let c = c.node_index() as usize;
                    if c <= i || c >= self.nodes.len() {
                        return Err(BvhError::BadChild { node: i, child: c });
                    }
                    for j in 0..W {
                        if self.nodes[c].child[j] != ChildRef::EMPTY && !b.contains(&self.nodes[c].child_bounds(j)) {
                            return Err(BvhError::ChildOutside { node: i, child: c });
                        }
                    }
                    stack.push(c);
                }
            }
        }
        if let Some((slot, &times)) = covered.iter().enumerate().find(|(_, c)| **c != 1) {
            return Err(BvhError::Coverage { slot, times });
        }
        if let Some(n) = reached.iter().position(|r| *r != 1) {
            return Err(BvhError::Unreachable(n));
        }
        Ok(())
    }
}
