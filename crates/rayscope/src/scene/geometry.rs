//! The scene's shapes in BVH order, and the BVH over them.

use super::{Hit, Mesh, PrimRef, SceneSphere};
use crate::bvh::{BuildParams, Bvh, Primitives, TraversalStats};
use crate::geometry::{Aabb, PrimHit, Sphere, Triangle};
use crate::ray::Ray;

/// A primitive in the form intersection wants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A triangle.
    Triangle(Triangle),
    /// A sphere.
    Sphere(Sphere),
}

impl Shape {
    /// Intersect within `[t_min, t_max]`.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        match self {
            Shape::Triangle(t) => t.intersect(ray, t_min, t_max),
            Shape::Sphere(s) => s.intersect(ray, t_min, t_max),
        }
    }

    /// Bounding box.
    pub fn bounds(&self) -> Aabb {
        match self {
            Shape::Triangle(t) => t.bounds(),
            Shape::Sphere(s) => s.bounds(),
        }
    }
}

impl Primitives for [Shape] {
    #[inline(always)]
    fn intersect(&self, index: u32, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        self[index as usize].intersect(ray, t_min, t_max)
    }
}

/// The BVH and the shapes it indexes, stored in BVH order so a leaf's shapes are contiguous.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    /// The hierarchy.
    pub bvh: Bvh,
    /// Shapes in BVH slot order.
    pub shapes: Vec<Shape>,
}

impl Geometry {
    /// Build over every triangle of `meshes` and every sphere, in global primitive order.
    pub fn build(meshes: &[Mesh], spheres: &[SceneSphere], prims: &[PrimRef]) -> Geometry {
        let shapes = all_shapes(meshes, spheres, prims);
        let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
        let bvh = Bvh::build(&bounds, &BuildParams::default());
        let shapes = bvh.prim_indices.iter().map(|&i| shapes[i as usize]).collect();
        Geometry { bvh, shapes }
    }

    /// Closest hit, with its global primitive id.
    #[inline]
    pub fn intersect(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit> {
        self.bvh.intersect_counted(ray, &self.shapes[..], stats).map(|h| Hit {
            t: h.hit.t,
            prim: self.bvh.prim_indices[h.slot as usize],
            u: h.hit.u,
            v: h.hit.v,
        })
    }
}

/// Every primitive as a shape, in global primitive order.
pub fn all_shapes(meshes: &[Mesh], spheres: &[SceneSphere], prims: &[PrimRef]) -> Vec<Shape> {
    prims
        .iter()
        .map(|p| match *p {
            PrimRef::Triangle { mesh, face } => {
                let m = &meshes[mesh as usize];
                let [a, b, c] = m.triangles[face as usize].map(|i| m.positions[i as usize]);
                Shape::Triangle(Triangle::new(a, b, c))
            }
            PrimRef::Sphere(s) => {
                let s = &spheres[s as usize];
                Shape::Sphere(Sphere {
                    center: s.center,
                    radius: s.radius,
                })
            }
        })
        .collect()
}
