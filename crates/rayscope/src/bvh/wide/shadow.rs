//! Shadow rays grouped per shading point: many samples of one area light all leave the same
//! point towards the same light. One query collects what any of those segments could cross
//! (the triangles, and other leaves, that meet a frustum around the cone from the point to the
//! light's bounding sphere), and each shadow ray then tests just those, with no traversal. In
//! the open (the common case) the list is empty and every sample is visible at once.
//!
//! The answers are those of [`WideBvh::occluded`]: the frustum contains every segment, so a
//! primitive that blocks one is on the list, and each listed triangle or leaf is tested with
//! the traversal's own triangle and box tests.

#[cfg(target_arch = "x86_64")]
use super::avx::intersect_pair_avx2;
use super::kernels::{Lanes, NodeWidth, RayLanes};
use super::layout::{EMPTY, LeafRange, Tri4};
#[cfg(target_arch = "x86_64")]
use super::simd::Avx2;
use super::stack::Stack;
use super::traverse::{range_occluded, ray_is_finite};
use super::{ChildRef, Simd, WideBvh};
use crate::bvh::{NoObserver, Primitives, TraversalObserver};
use crate::geometry::aabb::safe_inv_dir;
use crate::geometry::{Aabb, Triangle};
use crate::math::Vec3A;
use crate::ray::Ray;

/// Most triangles a group keeps (in [`Tri4`] blocks); a query meeting more gives up, and its
/// rays traverse the tree one by one (a cluttered view of the light gains little from a list).
pub const MAX_TRIANGLES: usize = 32;
/// Most other leaves (spheres, moving shapes) a group keeps.
pub const MAX_LEAVES: usize = 8;

/// What segments from one point to one light may cross: [`WideBvh::occluders`]. The
/// triangles that may block them, repacked four to a block (each lane a bit-exact copy of the
/// tree's), and the other leaves with their boxes.
#[derive(Clone, Copy, Debug)]
pub struct Occluders {
    /// The tree's instruction set, which the triangle test runs on.
    simd: Simd,
    triangles: usize,
    blocks: [Tri4; MAX_TRIANGLES / 4],
    leaves: usize,
    boxes: [Aabb; MAX_LEAVES],
    ranges: [LeafRange; MAX_LEAVES],
}

impl Occluders {
    fn new(simd: Simd) -> Occluders {
        Occluders {
            simd,
            triangles: 0,
            blocks: [Tri4::EMPTY; MAX_TRIANGLES / 4],
            leaves: 0,
            boxes: [Aabb::EMPTY; MAX_LEAVES],
            ranges: [LeafRange { start: 0, count: 0 }; MAX_LEAVES],
        }
    }

    /// Triangles listed.
    pub fn triangles(&self) -> usize {
        self.triangles
    }

    /// Leaves of other primitives listed.
    pub fn leaves(&self) -> usize {
        self.leaves
    }

    /// Whether nothing can block any of the segments.
    pub fn is_empty(&self) -> bool {
        self.triangles == 0 && self.leaves == 0
    }
}

/// A plane `n . (x - apex) <= h`: the frustum is the intersection of seven of them.
#[derive(Clone, Copy, Debug)]
struct Plane {
    n: Vec3A,
    h: f32,
}

/// The square frustum, with its apex at the shading point, that holds the cone of directions
/// towards a sphere: four planes tangent to the cone, one behind the apex, one beyond the
/// sphere; and the surface's tangent plane, which the rays leave on one side.
struct Frustum {
    apex: Vec3A,
    planes: [Plane; 7],
    /// The corners of the pyramid's far end; with the apex, they span it.
    corners: [Vec3A; 4],
    /// Slack for the tests, far above float error.
    tol: f32,
}

impl Frustum {
    /// The frustum from `apex` around the sphere (`center`, `radius`) on the side `side`
    /// points to, or `None` when the apex is at or inside the sphere (every direction may
    /// lead to the light).
    fn new(apex: Vec3A, side: Vec3A, center: Vec3A, radius: f32) -> Option<Frustum> {
        let to = center - apex;
        let dist = to.length();
        // Margins far above float error: the frustum only needs to contain the segments.
        let scale = 1.0 + apex.abs().max_element().max(center.abs().max_element());
        let r = radius * (1.0 + 1e-3) + 1e-5 * scale;
        // Too close to the light (or not finite): trace each ray.
        if !dist.is_finite() || dist <= 1.5 * r {
            return None;
        }
        let a = to / dist;
        let sin = r / dist;
        let cos = (1.0 - sin * sin).sqrt();
        let (u, v) = a.any_orthonormal_pair();
        // A point at angle phi <= theta from the axis has n . (x - apex) = |x - apex|
        // sin(phi - theta) <= 0 for n = w cos(theta) - a sin(theta), w any unit vector
        // across the axis: the four sides.
        let tangent = |w: Vec3A| Plane { n: w * cos - a * sin, h: 0.0 };
        let tol = 1e-5 * (dist + r + scale);
        let mut planes = [
            tangent(u),
            tangent(-u),
            tangent(v),
            tangent(-v),
            Plane { n: -a, h: 0.0 },
            Plane { n: a, h: dist + r },
            // The surface the rays leave: the ones behind it are never cast.
            Plane { n: -side, h: 0.0 },
        ];
        for p in &mut planes {
            p.h += tol;
        }
        let far = dist + r;
        let half = far * (sin / cos) * (1.0 + 1e-3);
        let corners = [half * (u + v), half * (u - v), half * (v - u), -half * (u + v)].map(|c| far * a + c);
        Some(Frustum { apex, planes, corners, tol })
    }

    /// Whether the triangle may meet the frustum: false only when its corners all lie outside
    /// one plane.
    #[inline]
    fn may_meet_triangle(&self, t: &Triangle) -> bool {
        let [a, b, c] = t.vertices().map(|v| v - self.apex);
        if !self.planes.iter().all(|p| p.n.dot(a) <= p.h || p.n.dot(b) <= p.h || p.n.dot(c) <= p.h) {
            return false;
        }
        // The triangle's own plane separates when the apex and the far corners all lie
        // strictly on one side of it (the pyramid is their convex hull).
        let n = t.normal();
        let slack = self.tol * n.length();
        let side = |p: Vec3A| n.dot(p - a);
        let apex = side(Vec3A::ZERO);
        let above = apex > slack && self.corners.iter().all(|&c| side(c) > slack);
        let below = apex < -slack && self.corners.iter().all(|&c| side(c) < -slack);
        !(above || below)
    }

    /// Whether box `b` may meet the frustum: false only when it lies wholly outside one plane.
    #[inline]
    fn may_meet(&self, min: Vec3A, max: Vec3A) -> bool {
        let (lo, hi) = (min - self.apex, max - self.apex);
        self.planes.iter().all(|p| {
            // The box corner farthest along -n: the smallest n . (x - apex) over the box.
            let corner = Vec3A::select(p.n.cmpge(Vec3A::ZERO), lo, hi);
            p.n.dot(corner) <= p.h
        })
    }
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// The leaves that any segment from `apex` to a point of the sphere (`center`, `radius`)
    /// may cross, of those whose direction `d` has `side . d >= 0` (a shading point's
    /// geometric normal: shadow rays leave on its side; `Vec3A::ZERO` to keep them all);
    /// `None` when the apex is inside the sphere, a value is not finite, or more than
    /// [`MAX_TRIANGLES`] triangles or [`MAX_LEAVES`] other leaves qualify (then trace with
    /// [`WideBvh::occluded`]).
    pub fn occluders(&self, apex: Vec3A, side: Vec3A, center: Vec3A, radius: f32) -> Option<Occluders> {
        self.occluders_counted(apex, side, center, radius, &mut NoObserver)
    }

    /// [`WideBvh::occluders`], reporting to `obs` the nodes it enters and the leaves whose
    /// boxes meet the frustum (the leaves it opens); the caller reports the query's start
    /// ([`crate::bvh::QueryKind::ShadowGroup`]), for a shadow ray of the group.
    pub fn occluders_counted<O: TraversalObserver>(
        &self,
        apex: Vec3A,
        side: Vec3A,
        center: Vec3A,
        radius: f32,
        obs: &mut O,
    ) -> Option<Occluders> {
        if !apex.is_finite() || !side.is_finite() || !center.is_finite() || !radius.is_finite() {
            return None;
        }
        let frustum = Frustum::new(apex, side, center, radius)?;
        let mut out = Occluders::new(self.simd);
        if self.nodes.is_empty() {
            return Some(out);
        }
        let mut stack: Stack<ChildRef> = Stack::new();
        stack.push(ChildRef::ROOT);
        while let Some(index) = stack.pop() {
            let node = &self.nodes[index.node_index() as usize];
            obs.entered(index.node_index());
            obs.boxes_tested(W as u32);
            for i in 0..W {
                let child = node.child[i];
                if child == ChildRef::EMPTY {
                    continue;
                }
                let b = node.child_bounds(i);
                if !frustum.may_meet(b.min, b.max) {
                    continue;
                }
                if child.is_leaf() {
                    obs.entered_leaf(child);
                }
                if child.is_packed() {
                    // Keep the triangles that may meet the frustum, lane by lane.
                    for block in &self.blocks[child.packed_blocks()] {
                        for lane in 0..4 {
                            if block.slot[lane] == EMPTY || !frustum.may_meet_triangle(&block.triangle(lane)) {
                                continue;
                            }
                            if out.triangles == MAX_TRIANGLES {
                                return None;
                            }
                            out.blocks[out.triangles / 4].copy_lane(out.triangles % 4, block, lane);
                            out.triangles += 1;
                        }
                    }
                } else if child.is_leaf() {
                    if out.leaves == MAX_LEAVES {
                        return None;
                    }
                    out.boxes[out.leaves] = b;
                    out.ranges[out.leaves] = self.ranges[child.range_index()];
                    out.leaves += 1;
                } else {
                    stack.push(child);
                }
            }
        }
        Some(out)
    }

    /// Whether anything blocks `ray`, which must be one of the segments `occ` was collected
    /// for (from its apex towards its sphere): the same answer as [`WideBvh::occluded`].
    #[inline]
    pub fn occluded_among<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P, occ: &Occluders) -> bool {
        occ.blocks(ray, prims)
    }
}

impl Occluders {
    /// [`WideBvh::occluded_among`]: the list alone answers, whatever the tree's width (so
    /// that callers holding a tree of either width inline one copy of this hot loop).
    #[inline]
    pub fn blocks<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        if self.is_empty() || !ray_is_finite(ray) {
            return false;
        }
        let (t_min, t_max) = (ray.t.min, ray.t.max);
        let lanes = RayLanes::new(ray);
        // SAFETY: the AVX2 variant is called with the token that proves the CPU has its
        // features.
        let hit = unsafe {
            match self.simd {
                #[cfg(target_arch = "x86_64")]
                Simd::Avx512(cpu) => self.triangles_hit_avx2(cpu.into(), &lanes, t_min, t_max),
                #[cfg(target_arch = "x86_64")]
                Simd::Avx2(cpu) => self.triangles_hit_avx2(cpu, &lanes, t_min, t_max),
                _ => self.triangles_hit_portable(&lanes, t_min, t_max),
            }
        };
        if hit {
            return true;
        }
        if self.leaves == 0 {
            return false;
        }
        let inv = safe_inv_dir(ray.dir);
        for (b, r) in self.boxes[..self.leaves].iter().zip(&self.ranges[..self.leaves]) {
            // The traversal's own box test, so the same leaves are opened.
            if b.hit_distance(ray.origin, inv, t_min, t_max.min(f32::MAX)) != f32::INFINITY
                && range_occluded(*r, ray, prims)
            {
                return true;
            }
        }
        false
    }

    /// Whether a listed triangle is hit, on the baseline instruction set. Unused lanes of the
    /// last block hold degenerate triangles, which no ray hits.
    #[inline(always)]
    fn triangles_hit_portable(&self, lanes: &RayLanes, t_min: f32, t_max: f32) -> bool {
        self.blocks[..self.triangles.div_ceil(4)].iter().any(|block| block.intersect(lanes, t_min, t_max).0 != 0)
    }

    /// [`Occluders::triangles_hit_portable`] compiled for AVX2 and FMA: the traversal's own
    /// eight-triangle test (the same bits, with the fused operations as instructions rather
    /// than libm calls), two blocks at a time; the blocks past the last used are empty.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn triangles_hit_avx2(&self, cpu: Avx2, lanes: &RayLanes, t_min: f32, t_max: f32) -> bool {
        // A loop, not `any` with a closure: a closure is compiled without AVX2 (see `avx.rs`).
        for pair in self.blocks[..self.triangles.div_ceil(8) * 2].chunks_exact(2) {
            if intersect_pair_avx2(cpu, lanes, &pair[0], &pair[1], t_min, t_max).0 != 0 {
                return true;
            }
        }
        false
    }
}
