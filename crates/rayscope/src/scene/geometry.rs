//! The scene's shapes in BVH order, and the BVH over them.

use rayon::prelude::*;

use super::{Hit, Mesh, PrimRef, SceneSphere};
use crate::animation::Shutter;
use crate::bvh::{BuildParams, Bvh, NoObserver, Occluders, PACKET, Primitives, TILE_RUNS, TraversalObserver, WideTree};
use crate::geometry::{Aabb, PrimHit, Sphere, Triangle};
use crate::math::Vec3A;
use crate::motion::MotionPath;
use crate::pages;
use crate::ray::Ray;

/// A primitive in the form intersection wants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A triangle.
    Triangle(Triangle),
    /// A sphere.
    Sphere(Sphere),
    /// A moving shape: index into [`Geometry::moving`]. Kept out of line so that static
    /// shapes, the common case, stay small.
    Moving(u32),
}

/// A shape translated over the shutter interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovingShape {
    /// The shape (a triangle or a sphere): at shutter time 0 for a linear motion, at rest
    /// (untranslated) for a path.
    pub shape: Shape,
    /// How it moves.
    pub motion: ShapeMotion,
}

/// How a [`MovingShape`] moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShapeMotion {
    /// Linearly, by `delta` from shutter time 0 to 1: a path of two keys at times 0 and 1,
    /// moved as rayscope always moved it (`delta * time`), bit for bit. Only under
    /// [`Shutter::STILL`], where scene time is the ray's shutter fraction (any other shutter
    /// moves such a path as a [`ShapeMotion::Path`], held outside its keys).
    Linear {
        /// Its displacement from shutter time 0 to 1.
        delta: Vec3A,
    },
    /// Along path `i` of [`Geometry::paths`], translated by its value at the ray's time.
    Path(u32),
}

impl Shape {
    /// Intersect a static shape within `[t_min, t_max]` (a `Moving` one needs its
    /// [`Geometry`]: see [`Geometry::intersect_shape`]).
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        match self {
            Shape::Triangle(t) => t.intersect(ray, t_min, t_max),
            Shape::Sphere(s) => s.intersect(ray, t_min, t_max),
            Shape::Moving(_) => None,
        }
    }

    /// Bounding box of a static shape (empty for `Moving`; see [`Geometry::shape_bounds`]).
    pub fn bounds(&self) -> Aabb {
        match self {
            Shape::Triangle(t) => t.bounds(),
            Shape::Sphere(s) => s.bounds(),
            Shape::Moving(_) => Aabb::EMPTY,
        }
    }
}

/// The BVH and the shapes it indexes, stored in BVH order so a leaf's shapes are contiguous.
///
/// The shapes are stored compactly ([`Geometry::shape`] gives slot `i`'s): a static
/// triangle as the indices of its three corners into a copy of the meshes' positions, 12 bytes
/// (plus its share of the positions) where a [`Shape`] takes 64. Rendering reads them rarely:
/// the wide tree's leaves hold their own copies of the triangles ([`crate::bvh::Tri4`]), so a
/// slot's shape is read for the leaves that are not packed (spheres, moving shapes), for a
/// hit's geometric normal, and by the binary tree's traversal (the debugger's).
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    /// The binary hierarchy: what the debugger's level view draws, and what `wide` is
    /// collapsed from.
    pub bvh: Bvh,
    /// The wide hierarchy rendering traverses (8 or 16 children a node, for the CPU).
    pub wide: WideTree,
    /// Per slot, its shape: a static triangle's corners, as indices into `vertices`; or
    /// `[OTHER, i, 0]`: `others[i]`.
    corners: Vec<[u32; 3]>,
    /// The corners of static triangles: every mesh's positions at shutter open, the meshes one
    /// after another.
    vertices: Vec<Vec3A>,
    /// The shapes that are not a static triangle's corners (see `corners`).
    others: Vec<Shape>,
    /// Moving shapes, referenced by [`Shape::Moving`].
    pub moving: Vec<MovingShape>,
    /// The paths of moving shapes, referenced by [`ShapeMotion::Path`] (one per moving mesh
    /// or sphere).
    pub paths: Vec<MotionPath>,
    /// Which primitive each slot holds and its material, in slot order: shading reads these
    /// for every hit, and neighbouring rays hit neighbouring slots (the global order put
    /// a cache miss on every hit).
    pub slots: Vec<SlotInfo>,
    /// The scene time the tree's bounds hold the moving shapes over; rays' shutter fractions
    /// map onto it ([`Shutter::time`]).
    pub shutter: Shutter,
}

/// The primitive in one BVH slot: [`Geometry::slots`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlotInfo {
    /// The primitive.
    pub prim: PrimRef,
    /// Its material.
    pub material: u32,
}

/// Marks a slot whose shape is in [`Geometry::others`] (in `corners`).
const OTHER: u32 = u32::MAX;

impl Primitives for Geometry {
    /// Inlined into every traversal's range leaves: the shapes stored whole (spheres, moving
    /// shapes) by reference, as before the compact storage; a static triangle's, which a range
    /// leaf holds only where the collapse could not pack it, out of line (made from its corners
    /// inline, it cost the dragon's packet and shadow traversals 0.7-2.1% more instructions,
    /// though they never reach it).
    #[inline(always)]
    fn intersect(&self, index: u32, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        match self.corners[index as usize] {
            [OTHER, i, _] => self.intersect_shape(&self.others[i as usize], ray, t_min, t_max),
            corners => self.intersect_corners(corners, ray, t_min, t_max),
        }
    }

    #[inline(always)]
    fn triangle(&self, index: u32) -> Option<Triangle> {
        self.triangle_of(self.corners[index as usize])
    }

    /// From the slot's corners alone: the collapse asks it of every slot while it plans, and
    /// making the triangle would read its three corners from the vertices, out of order.
    fn is_triangle(&self, index: u32) -> bool {
        self.is_triangle_of(self.corners[index as usize])
    }
}

impl Geometry {
    /// Build over every triangle of `meshes` and every sphere, in global primitive order.
    pub fn build(meshes: &[Mesh], spheres: &[SceneSphere], prims: &[PrimRef]) -> Geometry {
        Geometry::build_with(meshes, spheres, prims, &BuildParams::default())
    }

    /// [`Geometry::build`] with these BVH build parameters (another split rule, for
    /// comparisons).
    pub fn build_with(meshes: &[Mesh], spheres: &[SceneSphere], prims: &[PrimRef], params: &BuildParams) -> Geometry {
        Geometry::build_for(meshes, spheres, prims, params, Shutter::STILL)
    }

    /// [`Geometry::build_with`] for the scene times `shutter` exposes: moving shapes are
    /// bounded over those times only.
    pub fn build_for(
        meshes: &[Mesh],
        spheres: &[SceneSphere],
        prims: &[PrimRef],
        params: &BuildParams,
        shutter: Shutter,
    ) -> Geometry {
        Geometry::build_by(meshes, spheres, prims.len(), |i| prims[i as usize], params, shutter)
    }

    /// [`Geometry::build_for`] over `count` primitives, global id `i` being `prim(i)`: the
    /// scene gives them without an array ([`super::PrimIds`]).
    pub(super) fn build_by(
        meshes: &[Mesh],
        spheres: &[SceneSphere],
        count: usize,
        prim: impl Fn(u32) -> PrimRef + Sync,
        params: &BuildParams,
        shutter: Shutter,
    ) -> Geometry {
        let mut geometry = Geometry { shutter, ..Geometry::default() };
        let slot_info = |i: u32| {
            let prim = prim(i);
            SlotInfo { prim, material: prim.material(meshes, spheres) }
        };
        let vertex_count: usize = meshes.iter().map(|m| m.positions.len()).sum();
        // Corner indices must stay below `OTHER`; beyond (never, in practice: 64 GB of
        // positions), every shape is stored whole.
        if anything_moves(meshes, spheres) || vertex_count >= OTHER as usize {
            // Moving shapes are numbered in order: make every shape first, then reorder.
            let linear = shutter.is_still();
            let prims = (0..count as u32).map(&prim);
            let shapes = all_shapes(meshes, spheres, prims, linear, &mut geometry.moving, &mut geometry.paths);
            let g = &geometry;
            let bvh = Bvh::build_from(shapes.len(), |i| g.shape_bounds(&shapes[i]), params);
            geometry.bvh = bvh;
            geometry.others = map(&geometry.bvh.prim_indices, |&i| shapes[i as usize]);
            geometry.corners = (0..geometry.others.len() as u32).map(|i| [OTHER, i, 0]).collect();
            geometry.slots = map(&geometry.bvh.prim_indices, |&i| slot_info(i));
            geometry.wide = WideTree::from_binary(&geometry.bvh, &geometry);
            return geometry;
        }
        // Nothing moves: the bounds come straight from the meshes (no array of them); each
        // slot's corners are then found once, in slot order, and the wide tree collapsed over
        // them (a shapes array in global order and a reordering pass were a third of the build
        // on two cores; the collapse packing each slot's triangle through the faces in the
        // tree's order, a cache miss a slot, was another 6%).
        let shape = |p: &PrimRef| still_shape(meshes, spheres, p);
        geometry.bvh = Bvh::build_from(count, |i| shape(&prim(i as u32)).bounds(), params);
        let mut first = Vec::with_capacity(meshes.len());
        geometry.vertices = pages::with_capacity(vertex_count);
        for m in meshes {
            first.push(geometry.vertices.len() as u32);
            // Moved as `still_shape` moves them, so that the corners are its corners.
            let offset = m.motion.as_ref().map_or(Vec3A::ZERO, MotionPath::start);
            geometry.vertices.par_extend(m.positions.par_iter().map(|&p| p + offset));
        }
        // Spheres are `others` in their own order.
        geometry.others = (0..spheres.len() as u32).map(|s| shape(&PrimRef::Sphere(s))).collect();
        let corners = |&i: &u32| match prim(i) {
            PrimRef::Triangle { mesh, face } => {
                meshes[mesh as usize].triangles[face as usize].map(|c| first[mesh as usize] + c)
            }
            PrimRef::Sphere(s) => [OTHER, s, 0],
        };
        geometry.corners = map(&geometry.bvh.prim_indices, corners);
        geometry.wide = WideTree::from_binary(&geometry.bvh, &geometry);
        if count > PARALLEL_PASS {
            // The plan's memory, before the slots' array is made.
            crate::io::memory::release_free_memory();
        }
        geometry.slots = map(&geometry.bvh.prim_indices, |&i| slot_info(i));
        geometry
    }

    /// The shape in slot `slot`.
    #[inline(always)]
    pub fn shape(&self, slot: u32) -> Shape {
        self.shape_of(self.corners[slot as usize])
    }

    /// The shapes, in slot order.
    pub fn shapes(&self) -> impl ExactSizeIterator<Item = Shape> + '_ {
        (0..self.corners.len() as u32).map(|slot| self.shape(slot))
    }

    /// The shape a slot's `corners` name.
    #[inline(always)]
    fn shape_of(&self, corners: [u32; 3]) -> Shape {
        match corners {
            [OTHER, i, _] => self.others[i as usize],
            [a, b, c] => Shape::Triangle(self.corner_triangle([a, b, c])),
        }
    }

    /// The triangle a slot's `corners` name, if it is one (the others' triangles included).
    #[inline(always)]
    fn triangle_of(&self, corners: [u32; 3]) -> Option<Triangle> {
        match corners {
            [OTHER, i, _] => match self.others[i as usize] {
                Shape::Triangle(t) => Some(t),
                _ => None,
            },
            [a, b, c] => Some(self.corner_triangle([a, b, c])),
        }
    }

    /// Whether [`Geometry::triangle_of`] gives a triangle for these corners.
    #[inline(always)]
    fn is_triangle_of(&self, corners: [u32; 3]) -> bool {
        match corners {
            [OTHER, i, _] => matches!(self.others[i as usize], Shape::Triangle(_)),
            _ => true,
        }
    }

    /// Intersect the static triangle of these corners.
    #[inline(never)]
    fn intersect_corners(&self, corners: [u32; 3], ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        self.corner_triangle(corners).intersect(ray, t_min, t_max)
    }

    /// The triangle of these corners (indices into `vertices`).
    #[inline(always)]
    fn corner_triangle(&self, [a, b, c]: [u32; 3]) -> Triangle {
        let v = &self.vertices;
        Triangle::new(v[a as usize], v[b as usize], v[c as usize])
    }

    /// Intersect `shape` (moving ones at the ray's time).
    #[inline(always)]
    pub fn intersect_shape(&self, shape: &Shape, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        match shape {
            Shape::Moving(i) => self.intersect_moving(*i, ray, t_min, t_max),
            s => s.intersect(ray, t_min, t_max),
        }
    }

    /// Intersect moving shape `i` at the ray's time. Out of line: evaluating a path is much
    /// code, and inlined into every traversal's leaf test it changed the static scenes'
    /// code (0.16% more instructions for the Cornell box, which has no moving shape).
    #[inline(never)]
    fn intersect_moving(&self, i: u32, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        let m = &self.moving[i as usize];
        let offset = match m.motion {
            ShapeMotion::Linear { delta } => delta * ray.time,
            ShapeMotion::Path(p) => self.paths[p as usize].at(self.shutter.time(ray.time)),
        };
        // Moving the ray back is moving the shape forward.
        let local = Ray { origin: ray.origin - offset, ..*ray };
        m.shape.intersect(&local, t_min, t_max)
    }

    /// The box of `shape` over the scene times [`Geometry::shutter`] exposes: for a linear
    /// translation, the union of its boxes at the two ends; along a path, its box at rest swept
    /// over the path's bound over those times ([`MotionPath::sweep_over`]).
    pub fn shape_bounds(&self, shape: &Shape) -> Aabb {
        match shape {
            Shape::Moving(i) => {
                let m = &self.moving[*i as usize];
                let b = m.shape.bounds();
                match m.motion {
                    ShapeMotion::Linear { delta } => b.union(Aabb { min: b.min + delta, max: b.max + delta }),
                    ShapeMotion::Path(p) => self.paths[p as usize].sweep_over(b, self.shutter),
                }
            }
            s => s.bounds(),
        }
    }

    /// The boxes the BVH was built over, in global primitive order (empty for a primitive left
    /// out of the tree): what [`crate::bvh::split_candidates`] needs to replay its build.
    pub fn build_bounds(&self) -> Vec<Aabb> {
        let order = &self.bvh.prim_indices;
        let mut bounds = vec![Aabb::EMPTY; order.iter().map(|&i| i as usize + 1).max().unwrap_or(0)];
        for (shape, &i) in self.shapes().zip(order) {
            bounds[i as usize] = self.shape_bounds(&shape);
        }
        bounds
    }

    /// Closest hit, with its global primitive id (through the wide BVH). Kept out of line:
    /// inlined into the integrator's shading, the tree's dispatch on width and instruction
    /// set made the Cornell box render 10% slower.
    #[inline(never)]
    pub fn intersect<O: TraversalObserver>(&self, ray: &Ray, stats: &mut O) -> Option<Hit> {
        let hit = self.wide.intersect_counted(ray, self, stats);
        self.scene_hit(hit)
    }

    /// Closest hits of up to [`PACKET`] rays, traced together when they share an origin
    /// (see [`crate::bvh::packet`]); each is what [`Geometry::intersect`] gives.
    #[inline(always)]
    pub fn intersect_packet(&self, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        self.scene_hits(self.wide.intersect_packet(rays, self))
    }

    /// [`Geometry::intersect_packet`], reporting each ray's traversal to its observer in `obs`
    /// (see [`crate::bvh::WideBvh::intersect_packet_counted`]).
    pub fn intersect_packet_counted<O: TraversalObserver>(
        &self,
        rays: &[Ray],
        obs: &mut [O; PACKET],
    ) -> [Option<Hit>; PACKET] {
        self.scene_hits(self.wide.intersect_packet_counted(rays, self, obs))
    }

    /// Closest hit through the binary BVH (for the debugger, whose views show its nodes).
    pub fn intersect_binary<O: TraversalObserver>(&self, ray: &Ray, stats: &mut O) -> Option<Hit> {
        let hit = self.bvh.intersect_counted(ray, self, stats);
        self.scene_hit(hit)
    }

    /// Closest hits of up to [`TILE_RUNS`] runs of rays, traced as one tile when they share
    /// an origin (see [`crate::bvh::WideBvh::intersect_tile`]); each is what
    /// [`Geometry::intersect`] gives.
    #[inline(always)]
    pub fn intersect_tile(&self, runs: &[&[Ray]]) -> [[Option<Hit>; PACKET]; TILE_RUNS] {
        self.scene_tile_hits(self.wide.intersect_tile(runs, self))
    }

    /// [`Geometry::intersect_tile`], reporting each ray's traversal to its observer in `obs`
    /// (see [`crate::bvh::WideBvh::intersect_tile_counted`]).
    pub fn intersect_tile_counted<O: TraversalObserver>(
        &self,
        runs: &[&[Ray]],
        obs: &mut [[O; PACKET]; TILE_RUNS],
    ) -> [[Option<Hit>; PACKET]; TILE_RUNS] {
        self.scene_tile_hits(self.wide.intersect_tile_counted(runs, self, obs))
    }

    /// Whether anything blocks `ray` (through the wide BVH). Out of line, as
    /// [`Geometry::intersect`].
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_counted(ray, &mut NoObserver)
    }

    /// [`Geometry::occluded`], reporting the traversal to `obs`. Out of line, as
    /// [`Geometry::intersect`] (one copy per observer: [`NoObserver`]'s is the renderer's).
    #[inline(never)]
    pub fn occluded_counted<O: TraversalObserver>(&self, ray: &Ray, obs: &mut O) -> bool {
        self.wide.occluded_counted(ray, self, obs)
    }

    /// Which of up to [`PACKET`] rays something blocks: bit `i` is [`Geometry::occluded`] of
    /// `rays[i]` (one walk of the tree for all of them; see [`crate::bvh::WideBvh::occluded_packet`]).
    #[inline(never)]
    pub fn occluded_packet(&self, rays: &[Ray]) -> u32 {
        self.wide.occluded_packet(rays, self)
    }

    /// What shadow rays from `apex` (on the side of `side`) into the sphere (`center`,
    /// `radius`) may cross, for [`Geometry::occluded_among`]; see
    /// [`crate::bvh::shadow`].
    pub fn occluders(&self, apex: Vec3A, side: Vec3A, center: Vec3A, radius: f32) -> Option<Occluders> {
        self.wide.occluders(apex, side, center, radius)
    }

    /// [`Geometry::occluded`] for a ray of the group `occ` was collected for.
    #[inline]
    pub fn occluded_among(&self, ray: &Ray, occ: &Occluders) -> bool {
        self.wide.occluded_among(ray, self, occ)
    }

    /// The global primitive id in BVH slot `slot`.
    #[inline]
    pub fn prim_id(&self, slot: u32) -> u32 {
        self.bvh.prim_indices[slot as usize]
    }

    #[inline]
    fn scene_hit(&self, hit: Option<crate::bvh::BvhHit>) -> Option<Hit> {
        hit.map(|h| Hit { t: h.hit.t, slot: h.slot, u: h.hit.u, v: h.hit.v })
    }

    /// [`Geometry::scene_hit`] of each of a packet's hits, in a loop written out: the
    /// array's `map` was left as an out-of-line call (`try_map`) that read the traversal's
    /// just-written hits back field by field, 5% of the teapot's packets of eight.
    #[inline(always)]
    fn scene_hits(&self, hits: crate::bvh::wide::PacketHits) -> [Option<Hit>; PACKET] {
        let mut out = [None; PACKET];
        for (out, hit) in out.iter_mut().zip(hits) {
            *out = self.scene_hit(hit);
        }
        out
    }

    /// [`Geometry::scene_hits`] of each run of a tile.
    #[inline(always)]
    fn scene_tile_hits(&self, runs: crate::bvh::wide::TileHits) -> [[Option<Hit>; PACKET]; TILE_RUNS] {
        let mut out = [[None; PACKET]; TILE_RUNS];
        for (out, run) in out.iter_mut().zip(runs) {
            *out = self.scene_hits(run);
        }
        out
    }
}

/// Scenes with more primitives than this make their shapes and bounds on all threads.
const PARALLEL_PASS: usize = 1 << 14;

/// `f` over `items`, on all threads for large scenes.
fn map<T: Sync, U: Send>(items: &[T], f: impl Fn(&T) -> U + Sync + Send) -> Vec<U> {
    let mut out = pages::with_capacity(items.len());
    if items.len() > PARALLEL_PASS {
        items.par_iter().map(f).collect_into_vec(&mut out);
    } else {
        out.extend(items.iter().map(f));
    }
    out
}

/// Primitive `p` as a shape, translated by `offset`.
fn shape_at(meshes: &[Mesh], spheres: &[SceneSphere], p: &PrimRef, offset: Vec3A) -> Shape {
    match *p {
        PrimRef::Triangle { mesh, face } => {
            let m = &meshes[mesh as usize];
            let [a, b, c] = m.triangles[face as usize].map(|i| m.positions[i as usize] + offset);
            Shape::Triangle(Triangle::new(a, b, c))
        }
        PrimRef::Sphere(s) => {
            let s = &spheres[s as usize];
            Shape::Sphere(Sphere { center: s.center + offset, radius: s.radius })
        }
    }
}

/// Whether any mesh or sphere moves (has a path that does not stand still).
pub(super) fn anything_moves(meshes: &[Mesh], spheres: &[SceneSphere]) -> bool {
    let moves = |m: &Option<MotionPath>| m.as_ref().is_some_and(|m| !m.is_still());
    meshes.iter().any(|m| moves(&m.motion)) || spheres.iter().any(|s| moves(&s.motion))
}

/// The motion of primitive `p`.
fn motion_of<'a>(meshes: &'a [Mesh], spheres: &'a [SceneSphere], p: &PrimRef) -> Option<&'a MotionPath> {
    match *p {
        PrimRef::Triangle { mesh, .. } => meshes[mesh as usize].motion.as_ref(),
        PrimRef::Sphere(s) => spheres[s as usize].motion.as_ref(),
    }
}

/// Primitive `p` as a shape at shutter open (its motion, if any, aside).
fn still_shape(meshes: &[Mesh], spheres: &[SceneSphere], p: &PrimRef) -> Shape {
    shape_at(meshes, spheres, p, motion_of(meshes, spheres, p).map_or(Vec3A::ZERO, MotionPath::start))
}

/// Every primitive as a shape, in global primitive order; moving ones go to `moving`, their
/// paths (one per moving mesh or sphere) to `paths`.
fn all_shapes(
    meshes: &[Mesh],
    spheres: &[SceneSphere],
    prims: impl Iterator<Item = PrimRef>,
    linear: bool,
    moving: &mut Vec<MovingShape>,
    paths: &mut Vec<MotionPath>,
) -> Vec<Shape> {
    // The index in `paths` of each moving mesh's or sphere's path (a mesh's triangles share
    // one), by owner: mesh `i` is `i`, sphere `j` is `meshes.len() + j`.
    let mut path_index = std::collections::HashMap::new();
    prims
        .map(|p| {
            let p = &p;
            let owner = match *p {
                PrimRef::Triangle { mesh, .. } => mesh as usize,
                PrimRef::Sphere(s) => meshes.len() + s as usize,
            };
            let motion = motion_of(meshes, spheres, p);
            let (offset, motion) = match motion {
                Some(m) if !m.is_still() => match m.as_linear().filter(|_| linear) {
                    Some((start, end)) => (start, ShapeMotion::Linear { delta: end - start }),
                    None => {
                        let i = *path_index.entry(owner).or_insert_with(|| {
                            paths.push(m.clone());
                            paths.len() as u32 - 1
                        });
                        (Vec3A::ZERO, ShapeMotion::Path(i))
                    }
                },
                _ => return still_shape(meshes, spheres, p),
            };
            moving.push(MovingShape { shape: shape_at(meshes, spheres, p, offset), motion });
            Shape::Moving(moving.len() as u32 - 1)
        })
        .collect()
}
