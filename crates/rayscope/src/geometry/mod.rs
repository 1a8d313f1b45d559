//! Geometric primitives and their ray intersection routines.

pub mod aabb;
pub mod frustum;
pub mod sphere;
pub mod triangle;

pub use aabb::Aabb;
pub use frustum::{DirectionRect, Frustum};
pub use sphere::Sphere;
pub use triangle::{TriRay, Triangle};

/// Where a ray meets a primitive: the distance and the primitive's own surface parameters
/// (barycentrics `u`, `v` of vertices 1 and 2 for a triangle; zero for a sphere).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// First surface parameter.
    pub u: f32,
    /// Second surface parameter.
    pub v: f32,
}
