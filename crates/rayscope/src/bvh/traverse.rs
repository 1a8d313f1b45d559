//! Closest-hit and any-hit traversal.
//!
//! Both walk the tree with a fixed-size stack on the machine stack (no allocation per ray),
//! test a node's two children together and descend into the nearer first. Closest-hit shrinks
//! the ray's interval at every hit so farther boxes are pruned; any-hit stops at the first hit.

use super::{Bvh, BvhHit, MAX_DEPTH, NoObserver, Primitives, TraversalObserver};
use crate::geometry::aabb::safe_inv_dir;
use crate::ray::Ray;

impl Bvh {
    /// The closest hit along `ray` within its interval.
    #[inline]
    pub fn intersect<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> Option<BvhHit> {
        self.intersect_counted(ray, prims, &mut NoObserver)
    }

    /// [`Bvh::intersect`], reporting the traversal to `stats` (counts of tested boxes and
    /// primitives, or the nodes entered: see [`TraversalObserver`]). Observers that do nothing
    /// compile away.
    pub fn intersect_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        stats: &mut O,
    ) -> Option<BvhHit> {
        let root = self.nodes.first()?;
        let inv = safe_inv_dir(ray.dir);
        let (t_min, mut t_max) = (ray.t.min, ray.t.max);
        stats.boxes_tested(1);
        if root.bounds().hit_distance(ray.origin, inv, t_min, t_max) == f32::INFINITY {
            return None;
        }
        let mut best = None;
        // Each entry keeps the far child's entry distance, so a node that a closer hit has
        // since ruled out is dropped when popped, without re-testing its box.
        let mut stack = [(0u32, 0.0f32); MAX_DEPTH];
        let mut sp = 0;
        let mut index = 0usize;
        loop {
            let node = &self.nodes[index];
            stats.entered(index as u32);
            if node.is_leaf() {
                for slot in node.start..node.start + node.count {
                    stats.prim_tested();
                    if let Some(hit) = prims.intersect(slot, ray, t_min, t_max) {
                        t_max = hit.t;
                        best = Some(BvhHit { slot, hit });
                    }
                }
            } else {
                let (a, b) = (index + 1, node.start as usize);
                stats.boxes_tested(2);
                let da = self.nodes[a].bounds().hit_distance(ray.origin, inv, t_min, t_max);
                let db = self.nodes[b].bounds().hit_distance(ray.origin, inv, t_min, t_max);
                let (near, far, dn, df) = if da <= db { (a, b, da, db) } else { (b, a, db, da) };
                if dn != f32::INFINITY {
                    if df != f32::INFINITY {
                        stack[sp] = (far as u32, df);
                        sp += 1;
                    }
                    index = near;
                    continue;
                }
            }
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let (i, entry) = stack[sp];
                if entry <= t_max {
                    index = i as usize;
                    break;
                }
            }
        }
    }

    /// Whether anything blocks `ray` within its interval; stops at the first hit found.
    pub fn occluded<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        let Some(root) = self.nodes.first() else {
            return false;
        };
        let inv = safe_inv_dir(ray.dir);
        let (t_min, t_max) = (ray.t.min, ray.t.max);
        if root.bounds().hit_distance(ray.origin, inv, t_min, t_max) == f32::INFINITY {
            return false;
        }
        let mut stack = [0u32; MAX_DEPTH];
        let mut sp = 0;
        let mut index = 0usize;
        loop {
            let node = &self.nodes[index];
            if node.is_leaf() {
                for slot in node.start..node.start + node.count {
                    if prims.intersect(slot, ray, t_min, t_max).is_some() {
                        return true;
                    }
                }
            } else {
                let (a, b) = (index + 1, node.start as usize);
                let ha = self.nodes[a].bounds().hit_distance(ray.origin, inv, t_min, t_max) != f32::INFINITY;
                let hb = self.nodes[b].bounds().hit_distance(ray.origin, inv, t_min, t_max) != f32::INFINITY;
                match (ha, hb) {
                    (true, true) => {
                        stack[sp] = b as u32;
                        sp += 1;
                        index = a;
                        continue;
                    }
                    (true, false) => {
                        index = a;
                        continue;
                    }
                    (false, true) => {
                        index = b;
                        continue;
                    }
                    (false, false) => {}
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            index = stack[sp] as usize;
        }
    }
}
