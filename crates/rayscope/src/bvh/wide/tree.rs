//! The wide BVH that rendering traverses, its width chosen for the CPU at run time: 16
//! children a node where the CPU has AVX-512 (a node's sixteen boxes in one 512-bit test per
//! step), else 8 (one AVX2 test per step, or two SSE/NEON halves); and 8 for small scenes. On
//! the dragon the 16-wide tree has a quarter fewer node visits per ray; with one instruction
//! per step either way, that made incoherent rays 7-10% faster, single camera rays 3-8%,
//! camera packets 9% and shadow rays 15% (BENCHMARKS.md, sixth round). Both widths give the
//! same hits, bit for bit.

use super::packet::{PACKET, PacketHits, TILE_RUNS, TileHits};
use super::shadow::Occluders;
use super::{Bvh8, Bvh16, ChildRef, FrustumTest, SimdLevel, WideBox, WideRef};
use crate::bvh::{Bvh, BvhError, BvhHit, Primitives, TraversalObserver};
use crate::geometry::{Aabb, Frustum};
use crate::math::Vec3A;
use crate::ray::Ray;

/// Fewest primitives for which rendering uses the 16-wide tree.
pub const MIN_PRIMS_16: usize = 512;

/// A wide BVH of the width the CPU traverses fastest (see the module documentation).
#[derive(Clone, Debug)]
pub enum WideTree {
    /// Eight children a node.
    Eight(Bvh8),
    /// Sixteen children a node.
    Sixteen(Bvh16),
}

impl Default for WideTree {
    fn default() -> Self {
        WideTree::Eight(Bvh8::default())
    }
}

/// `$e` on the tree inside `$tree`, whichever its width (one predictable branch per call).
macro_rules! each {
    ($tree:expr, $t:ident => $e:expr) => {
        match $tree {
            WideTree::Eight($t) => $e,
            WideTree::Sixteen($t) => $e,
        }
    };
}

impl WideTree {
    /// The width this CPU traverses fastest: 16 with AVX-512, else 8.
    pub fn best_width() -> usize {
        if SimdLevel::detect() == SimdLevel::Avx512 { 16 } else { 8 }
    }

    /// Collapse `bin` into a tree of [`WideTree::best_width`], or 8 for fewer than
    /// [`MIN_PRIMS_16`] primitives (see [`crate::bvh::WideBvh::from_binary`]).
    pub fn from_binary<P: Primitives + Sync + ?Sized>(bin: &Bvh, prims: &P) -> WideTree {
        // Small trees are a level or two deep at either width: there the wider tests save no
        // level and cost their set-up (the cube and the Cornell box rendered 2-4% slower).
        let width = if bin.prim_indices.len() < MIN_PRIMS_16 { 8 } else { Self::best_width() };
        Self::with_width(bin, prims, width)
    }

    /// Collapse `bin` into a tree of `width` children a node: 16, or else 8 (also for a
    /// 16-wide tree too deep for the traversals' stack, see
    /// [`crate::bvh::WideBvh::fits_stack`]).
    pub fn with_width<P: Primitives + Sync + ?Sized>(bin: &Bvh, prims: &P, width: usize) -> WideTree {
        if width == 16 {
            let tree = Bvh16::from_binary(bin, prims);
            if tree.fits_stack() {
                return WideTree::Sixteen(tree);
            }
        }
        WideTree::Eight(Bvh8::from_binary(bin, prims))
    }

    /// Children per node.
    pub fn width(&self) -> usize {
        match self {
            WideTree::Eight(_) => 8,
            WideTree::Sixteen(_) => 16,
        }
    }

    /// Nodes in the tree.
    pub fn node_count(&self) -> usize {
        each!(self, t => t.nodes.len())
    }

    /// The traversal variant in use.
    pub fn simd_level(&self) -> SimdLevel {
        each!(self, t => t.simd_level())
    }

    /// The same tree traversed by the baseline code (to compare it with the detected one).
    pub fn portable(self) -> WideTree {
        match self {
            WideTree::Eight(t) => WideTree::Eight(t.portable()),
            WideTree::Sixteen(t) => WideTree::Sixteen(t.portable()),
        }
    }

    /// Check the tree against the binary one it was collapsed from (see
    /// [`crate::bvh::WideBvh::validate`]).
    pub fn validate(&self, bin: &Bvh, prim_bounds: &[Aabb]) -> Result<(), BvhError> {
        each!(self, t => t.validate(bin, prim_bounds))
    }

    /// Whether a ray inside `frustum` may hit a primitive (see
    /// [`crate::bvh::WideBvh::frustum_test`]).
    pub fn frustum_test(&self, frustum: &Frustum) -> FrustumTest {
        each!(self, t => t.frustum_test(frustum))
    }

    /// The closest hit along `ray` within its interval.
    #[inline]
    pub fn intersect<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> Option<BvhHit> {
        each!(self, t => t.intersect(ray, prims))
    }

    /// [`WideTree::intersect`], reporting the traversal to `obs`.
    #[inline]
    pub fn intersect_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        each!(self, t => t.intersect_counted(ray, prims, obs))
    }

    /// The closest hits of up to [`super::packet::PACKET`] rays (see
    /// [`crate::bvh::WideBvh::intersect_packet`]).
    #[inline]
    pub fn intersect_packet<P: Primitives + ?Sized>(&self, rays: &[Ray], prims: &P) -> PacketHits {
        each!(self, t => t.intersect_packet(rays, prims))
    }

    /// The closest hits of up to [`TILE_RUNS`] runs of rays (see
    /// [`crate::bvh::WideBvh::intersect_tile`]).
    #[inline]
    pub fn intersect_tile<P: Primitives + ?Sized>(&self, runs: &[&[Ray]], prims: &P) -> TileHits {
        each!(self, t => t.intersect_tile(runs, prims))
    }

    /// [`WideTree::intersect_tile`], reporting each ray's traversal to its observer (see
    /// [`crate::bvh::WideBvh::intersect_tile_counted`]).
    #[inline]
    pub fn intersect_tile_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        runs: &[&[Ray]],
        prims: &P,
        obs: &mut [[O; PACKET]; TILE_RUNS],
    ) -> TileHits {
        each!(self, t => t.intersect_tile_counted(runs, prims, obs))
    }

    /// [`WideTree::intersect_packet`], reporting each ray's traversal to its observer (see
    /// [`crate::bvh::WideBvh::intersect_packet_counted`]).
    #[inline]
    pub fn intersect_packet_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> PacketHits {
        each!(self, t => t.intersect_packet_counted(rays, prims, obs))
    }

    /// Whether anything blocks `ray` within its interval.
    #[inline]
    pub fn occluded<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        each!(self, t => t.occluded(ray, prims))
    }

    /// Which of up to [`PACKET`] rays something blocks, as a bit mask (see
    /// [`crate::bvh::WideBvh::occluded_packet`]).
    #[inline]
    pub fn occluded_packet<P: Primitives + ?Sized>(&self, rays: &[Ray], prims: &P) -> u32 {
        each!(self, t => t.occluded_packet(rays, prims))
    }

    /// [`WideTree::occluded_packet`], reporting each ray's traversal to its observer (see
    /// [`crate::bvh::WideBvh::occluded_packet_counted`]).
    #[inline]
    pub fn occluded_packet_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        rays: &[Ray],
        prims: &P,
        obs: &mut [O; PACKET],
    ) -> u32 {
        each!(self, t => t.occluded_packet_counted(rays, prims, obs))
    }

    /// [`WideTree::occluded`], reporting the traversal to `obs`.
    #[inline]
    pub fn occluded_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> bool {
        each!(self, t => t.occluded_counted(ray, prims, obs))
    }

    /// What shadow rays from `apex` towards a sphere may cross (see
    /// [`crate::bvh::WideBvh::occluders`]).
    pub fn occluders(&self, apex: Vec3A, side: Vec3A, center: Vec3A, radius: f32) -> Option<Occluders> {
        each!(self, t => t.occluders(apex, side, center, radius))
    }

    /// [`WideTree::occluders`], reporting the query to `obs` (see
    /// [`crate::bvh::WideBvh::occluders_counted`]).
    pub fn occluders_counted<O: TraversalObserver>(
        &self,
        apex: Vec3A,
        side: Vec3A,
        center: Vec3A,
        radius: f32,
        obs: &mut O,
    ) -> Option<Occluders> {
        each!(self, t => t.occluders_counted(apex, side, center, radius, obs))
    }

    /// Levels of boxes, leaves included (see [`crate::bvh::WideBvh::box_levels`]).
    pub fn box_levels(&self) -> u32 {
        each!(self, t => t.box_levels())
    }

    /// The boxes of level `level` (see [`crate::bvh::WideBvh::boxes_at_level`]).
    pub fn boxes_at_level(&self, level: u32) -> Vec<WideBox> {
        each!(self, t => t.boxes_at_level(level))
    }

    /// The boxes of what one query entered (see [`crate::bvh::WideBvh::visited_boxes`]).
    pub fn visited_boxes(&self, entered: &[ChildRef]) -> Vec<WideBox> {
        each!(self, t => t.visited_boxes(entered))
    }

    /// The box of a node or leaf (see [`crate::bvh::WideBvh::wide_box`]).
    pub fn wide_box(&self, at: WideRef) -> Option<Aabb> {
        each!(self, t => t.wide_box(at))
    }

    /// [`WideTree::occluded`] for a ray of the group `occ` was collected for.
    #[inline]
    pub fn occluded_among<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P, occ: &Occluders) -> bool {
        // The list alone answers: no dispatch on the width (one copy of the loop to inline).
        occ.blocks(ray, prims)
    }
}
