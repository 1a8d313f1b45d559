//! Triangles in the form the intersection test wants: one vertex and two edges.

use super::{Aabb, PrimHit};
use crate::math::Vec3A;
use crate::ray::Ray;

/// A triangle stored as `v0`, `e1 = v1 - v0`, `e2 = v2 - v0`, the precomputation the
/// Möller–Trumbore test uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// First vertex.
    pub v0: Vec3A,
    /// Edge from vertex 0 to vertex 1.
    pub e1: Vec3A,
    /// Edge from vertex 0 to vertex 2.
    pub e2: Vec3A,
}

impl Triangle {
    /// The triangle with these corners.
    #[inline]
    pub fn new(v0: Vec3A, v1: Vec3A, v2: Vec3A) -> Triangle {
        Triangle { v0, e1: v1 - v0, e2: v2 - v0 }
    }

    /// The three corners.
    pub fn vertices(&self) -> [Vec3A; 3] {
        [self.v0, self.v0 + self.e1, self.v0 + self.e2]
    }

    /// The bounding box.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.vertices())
    }

    /// Unnormalised geometric normal `e1 x e2` (its length is twice the area).
    #[inline]
    pub fn normal(&self) -> Vec3A {
        self.e1.cross(self.e2)
    }

    /// Möller–Trumbore, double-sided, with inclusive barycentric bounds so a ray through a
    /// shared edge or vertex hits at least one of the triangles meeting there. Degenerate
    /// (zero-area) triangles and NaN inputs give no hit: every comparison with NaN is false.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        let p = ray.dir.cross(self.e2);
        let det = self.e1.dot(p);
        // A zero determinant means the ray is parallel to the plane (or the triangle is
        // degenerate): no single hit point exists.
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv_det = 1.0 / det;
        let s = ray.origin - self.v0;
        let u = s.dot(p) * inv_det;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(self.e1);
        let v = ray.dir.dot(q) * inv_det;
        if !(v >= 0.0 && u + v <= 1.0) {
            return None;
        }
        let t = self.e2.dot(q) * inv_det;
        (t >= t_min && t <= t_max).then_some(PrimHit { t, u, v })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> Triangle {
        Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)
    }

    fn ray_down(x: f32, y: f32) -> Ray {
        Ray::new(Vec3A::new(x, y, 1.0), -Vec3A::Z)
    }

    #[test]
    fn hits_interior_with_barycentrics() {
        let h = tri().intersect(&ray_down(0.25, 0.5), 0.0, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.u - 0.25).abs() < 1e-6 && (h.v - 0.5).abs() < 1e-6);
    }

    #[test]
    fn edges_and_vertices_are_hit() {
        for (x, y) in [(0.5, 0.0), (0.0, 0.5), (0.5, 0.5), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
            assert!(tri().intersect(&ray_down(x, y), 0.0, f32::INFINITY).is_some(), "({x},{y})");
        }
    }

    #[test]
    fn misses_outside_and_behind() {
        assert!(tri().intersect(&ray_down(0.6, 0.6), 0.0, f32::INFINITY).is_none());
        assert!(tri().intersect(&ray_down(-0.01, 0.5), 0.0, f32::INFINITY).is_none());
        let behind = Ray::new(Vec3A::new(0.2, 0.2, -1.0), -Vec3A::Z);
        assert!(tri().intersect(&behind, 0.0, f32::INFINITY).is_none());
        assert!(tri().intersect(&ray_down(0.2, 0.2), 0.0, 0.5).is_none(), "beyond t_max");
    }

    #[test]
    fn back_side_is_hit() {
        let up = Ray::new(Vec3A::new(0.2, 0.2, -1.0), Vec3A::Z);
        assert!(tri().intersect(&up, 0.0, f32::INFINITY).is_some());
    }

    #[test]
    fn grazing_and_degenerate_rays_miss() {
        // In the triangle's plane: parallel, no unique hit.
        let graze = Ray::new(Vec3A::new(-1.0, 0.2, 0.0), Vec3A::X);
        assert!(tri().intersect(&graze, 0.0, f32::INFINITY).is_none());
        let zero_area = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::X * 2.0);
        assert!(zero_area.intersect(&ray_down(0.5, 0.0), 0.0, f32::INFINITY).is_none());
        let nan = Triangle::new(Vec3A::splat(f32::NAN), Vec3A::X, Vec3A::Y);
        assert!(nan.intersect(&ray_down(0.2, 0.2), 0.0, f32::INFINITY).is_none());
        let nan_ray = Ray::new(Vec3A::splat(f32::NAN), -Vec3A::Z);
        assert!(tri().intersect(&nan_ray, 0.0, f32::INFINITY).is_none());
    }
}
