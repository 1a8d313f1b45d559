//! Frustum culling: whether a frustum of rays (the camera rays of a tile of pixels) may meet
//! any leaf box of the tree, found by walking the tree with the frustum in place of a ray.
//! A tile whose frustum meets none has nothing to hit, and its rays need no traversal.

use wide::f32x8;

use super::kernels::{Lanes, NodeWidth};
use super::stack::Stack;
use super::{ChildRef, WideBvh};
use crate::geometry::Frustum;

/// Most nodes a frustum test looks into before it gives up and keeps the tile (whose rays
/// are then traced as usual): a bound on its cost where a frustum passes between many boxes
/// without meeting a leaf's. The course's meshes need at most 13 for the tiles they cull.
pub const MAX_FRUSTUM_NODES: u32 = 64;

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
    /// primitive's box meets), or after [`MAX_FRUSTUM_NODES`] nodes (then `may_hit`).
    pub fn frustum_test(&self, frustum: &Frustum) -> FrustumTest {
        self.frustum_test_within(frustum, MAX_FRUSTUM_NODES)
    }

    /// [`WideBvh::frustum_test`] that gives up after `max_nodes` nodes.
    pub(crate) fn frustum_test_within(&self, frustum: &Frustum, max_nodes: u32) -> FrustumTest {
        let mut out = FrustumTest::default();
        if self.nodes.is_empty() {
            return out;
        }
        let mut stack = Stack::<ChildRef>::new();
        stack.push(ChildRef::ROOT);
        while let Some(node) = stack.pop() {
            if out.nodes == max_nodes {
                out.may_hit = true;
                return out;
            }
            out.nodes += 1;
            let n = &self.nodes[node.node_index() as usize];
            // The children's boxes eight at a time, then in order as before.
            let mut kept = 0u32;
            if W.is_multiple_of(8) {
                for first in (0..W).step_by(8) {
                    let row = |r: usize| f32x8::new(n.bounds[r][first..first + 8].try_into().expect("eight children"));
                    kept |= frustum.may_meet_lanes([row(0), row(1), row(2)], [row(3), row(4), row(5)]) << first;
                }
            } else {
                kept = (0..W).filter(|&i| frustum.may_meet(&n.child_bounds(i))).fold(0, |m, i| m | 1 << i);
            }
            for (i, &child) in n.child.iter().enumerate() {
                if child == ChildRef::EMPTY || kept & 1 << i == 0 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{BuildParams, Bvh, Bvh8, Primitives};
    use crate::geometry::{Aabb, DirectionRect, PrimHit, Triangle};
    use crate::math::Vec3A;
    use crate::ray::Ray;

    /// Triangles reached through the binary tree's slot order.
    struct Tris<'a> {
        tris: &'a [Triangle],
        bvh: &'a Bvh,
    }

    impl Primitives for Tris<'_> {
        fn intersect(&self, index: u32, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
            self.triangle(index).and_then(|t| t.intersect(ray, t_min, t_max))
        }

        fn triangle(&self, index: u32) -> Option<Triangle> {
            Some(self.tris[self.bvh.prim_indices[index as usize] as usize])
        }
    }

    /// Triangles on a grid in the plane z = 0, tiny and far apart: a deep tree with room
    /// between its leaves.
    fn grid() -> Vec<Triangle> {
        let mut tris = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let p = Vec3A::new(i as f32, j as f32, 0.0);
                tris.push(Triangle::new(p, p + Vec3A::new(0.1, 0.0, 0.0), p + Vec3A::new(0.0, 0.1, 0.0)));
            }
        }
        tris
    }

    /// A frustum that meets a triangle may hit; one through the gaps between them walks
    /// nodes and culls; one that meets nothing costs the root alone; and a walk past its
    /// bound keeps the tile (conservative), having looked into no more nodes than the bound.
    #[test]
    fn the_walk_finds_leaves_culls_gaps_and_stops_at_its_bound() {
        let tris = grid();
        let bounds: Vec<Aabb> = tris.iter().map(Triangle::bounds).collect();
        let bin = Bvh::build(&bounds, &BuildParams::default());
        let tree = Bvh8::from_binary(&bin, &Tris { tris: &tris, bvh: &bin });
        // Looking down -z from above the grid, through a small window around (x, y).
        let window = |x: f32, y: f32, r: f32| {
            let rect = DirectionRect { right: Vec3A::X, up: Vec3A::Y, forward: -Vec3A::Z, x: [-r, r], y: [-r, r] };
            Frustum::new(Vec3A::new(x, y, 10.0), &rect)
        };
        let on = tree.frustum_test(&window(10.03, 10.03, 0.001));
        assert!(on.may_hit && on.nodes >= 2, "{on:?}");
        let gap = tree.frustum_test(&window(10.5, 10.5, 0.01));
        assert!(!gap.may_hit && gap.nodes >= 2, "{gap:?}");
        let away = tree.frustum_test(&window(-50.0, -50.0, 0.01));
        assert_eq!(away, FrustumTest { may_hit: false, nodes: 1 });
        let cut = tree.frustum_test_within(&window(10.5, 10.5, 0.01), 1);
        assert_eq!(cut, FrustumTest { may_hit: true, nodes: 1 });
    }
}
