//! Rays, parametric intervals, and the one rule that offsets secondary rays.

use crate::math::{Vec3A, face_forward};

/// A closed parametric interval `[min, max]` along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Smallest accepted `t`.
    pub min: f32,
    /// Largest accepted `t`.
    pub max: f32,
}

impl Interval {
    /// `[0, +inf)`: everything in front of the origin.
    pub const FORWARD: Interval = Interval { min: 0.0, max: f32::INFINITY };
}

/// A ray `origin + t * dir` with `t` in `t`, at shutter time `time` in `[0, 1)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3A,
    /// Its direction; unit length for every ray the tracer makes.
    pub dir: Vec3A,
    /// The accepted parametric range.
    pub t: Interval,
    /// Time within the shutter interval, in `[0, 1)`.
    pub time: f32,
}

/// Relative size of the offset that lifts a secondary ray's origin off its surface. Scaled by
/// the magnitude of the hit point, so it stays above float error at any scene scale while
/// remaining far below a pixel's footprint in the course's unit-sized scenes.
pub const SPAWN_EPSILON: f32 = 1e-4;

impl Ray {
    /// A ray over `[0, +inf)` at time 0.
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Ray {
        Ray { origin, dir, t: Interval::FORWARD, time: 0.0 }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + t * self.dir
    }

    /// A secondary ray leaving surface point `p` (geometric normal `ng`) in unit direction
    /// `dir`, at the parent's `time`. Its origin moves off the surface, to the side `dir` goes,
    /// so that it can never re-hit the surface it starts on (no acne), by an amount small
    /// enough not to detach shadows from their casters (no peter-panning).
    #[inline]
    pub fn spawn(p: Vec3A, ng: Vec3A, dir: Vec3A, time: f32) -> Ray {
        Ray { origin: offset_origin(p, ng, dir), dir, t: Interval::FORWARD, time }
    }

    /// Where a secondary ray leaving surface point `p` (geometric normal `ng`) in direction
    /// `dir` starts: the origin [`Ray::spawn`] and its kin give it. Every direction on the
    /// same side of the surface gets the same origin.
    #[inline]
    pub fn spawn_origin(p: Vec3A, ng: Vec3A, dir: Vec3A) -> Vec3A {
        offset_origin(p, ng, dir)
    }

    /// A shadow ray from surface point `p` towards `target`, ending just short of it, so that
    /// geometry at the target itself (an area light's own surface) does not count as a blocker.
    /// Returns the ray and the distance from `p` to `target`.
    #[inline]
    pub fn spawn_to(p: Vec3A, ng: Vec3A, target: Vec3A, time: f32) -> Ray {
        let to = target - p;
        let dir = to.normalize_or_zero();
        let origin = offset_origin(p, ng, dir);
        let dist = (target - origin).length();
        Ray { origin, dir, t: Interval { min: 0.0, max: dist * (1.0 - SPAWN_EPSILON) }, time }
    }

    /// [`Ray::spawn_to`] for a target already known by its unit direction `wi` from `p` and
    /// its `distance`: no normalisation or length again, as each light sample has them.
    #[inline]
    pub fn spawn_towards(p: Vec3A, ng: Vec3A, wi: Vec3A, distance: f32, time: f32) -> Ray {
        let origin = offset_origin(p, ng, wi);
        // The offset moved the origin along the direction by its projection on it.
        let dist = distance - (origin - p).dot(wi);
        Ray { origin, dir: wi, t: Interval { min: 0.0, max: dist * (1.0 - SPAWN_EPSILON) }, time }
    }
}

#[inline]
fn offset_origin(p: Vec3A, ng: Vec3A, dir: Vec3A) -> Vec3A {
    let scale = SPAWN_EPSILON * (1.0 + p.abs().max_element());
    p + face_forward(ng, dir) * scale
}
