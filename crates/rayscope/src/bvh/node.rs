//! The node layout.

use crate::geometry::Aabb;
use crate::math::Vec3A;

/// One BVH node, 32 bytes, two to a 64-byte cache line.
///
/// | field | bytes | meaning |
/// |---|---|---|
/// | `min` | 0..12 | lower corner of the node's box |
/// | `start` | 12..16 | leaf: first primitive slot; interior: index of the second child |
/// | `max` | 16..28 | upper corner of the node's box |
/// | `count` | 28..32 | leaf: number of primitives (at least 1); interior: 0 |
///
/// An interior node's first child is the node right after it (depth-first order), so only the
/// second child's index is stored.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct BvhNode {
    /// Lower corner of the box.
    pub min: [f32; 3],
    /// Leaf: first primitive slot. Interior: index of the second child.
    pub start: u32,
    /// Upper corner of the box.
    pub max: [f32; 3],
    /// Leaf: primitive count (> 0). Interior: 0.
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);

// SAFETY: `f32`s and `u32`s, no padding: all-zero bits are a node (the builder's arrays are
// allocated zeroed, for its threads to fill).
unsafe impl bytemuck::Zeroable for BvhNode {}

impl BvhNode {
    /// A node with this box.
    pub fn new(bounds: Aabb, start: u32, count: u32) -> BvhNode {
        BvhNode { min: bounds.min.to_array(), start, max: bounds.max.to_array(), count }
    }

    /// Whether the node is a leaf.
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    /// The node's box.
    #[inline(always)]
    pub fn bounds(&self) -> Aabb {
        Aabb { min: Vec3A::from_array(self.min), max: Vec3A::from_array(self.max) }
    }
}
