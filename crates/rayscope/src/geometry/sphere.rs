//! Analytic spheres.

use super::{Aabb, PrimHit};
use crate::math::Vec3A;
use crate::ray::Ray;

/// A sphere by centre and radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3A,
    /// Radius (positive).
    pub radius: f32,
}

impl Sphere {
    /// The bounding box.
    pub fn bounds(&self) -> Aabb {
        Aabb { min: self.center - Vec3A::splat(self.radius), max: self.center + Vec3A::splat(self.radius) }
    }

    /// Nearest intersection in `[t_min, t_max]`: the near root, else the far one (the ray
    /// starts inside). Uses the half-b form and the stable quadratic
    /// (`q = -(b + sign(b) sqrt(disc))`) so that a far-away or grazing ray keeps its precision.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        let oc = ray.origin - self.center;
        let a = ray.dir.length_squared();
        let half_b = oc.dot(ray.dir);
        // c computed from the component of oc perpendicular to the ray, which avoids the
        // catastrophic cancellation of |oc|^2 - r^2 for distant origins (Ray Tracing Gems ch. 7).
        let perp = oc - (half_b / a) * ray.dir;
        let disc = a * (self.radius * self.radius - perp.length_squared());
        // Written so that a NaN discriminant also misses.
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        let c = oc.length_squared() - self.radius * self.radius;
        let q = -(half_b + disc.sqrt().copysign(half_b));
        let (mut t0, mut t1) = (c / q, q / a);
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        [t0, t1].into_iter().find(|t| *t >= t_min && *t <= t_max).map(|t| PrimHit { t, u: 0.0, v: 0.0 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Sphere {
        Sphere { center: Vec3A::new(0.0, 0.0, 5.0), radius: 1.0 }
    }

    #[test]
    fn hits_front_and_from_inside() {
        let r = Ray::new(Vec3A::ZERO, Vec3A::Z);
        assert!((unit().intersect(&r, 0.0, f32::INFINITY).unwrap().t - 4.0).abs() < 1e-5);
        let inside = Ray::new(Vec3A::new(0.0, 0.0, 5.0), Vec3A::Z);
        assert!((unit().intersect(&inside, 0.0, f32::INFINITY).unwrap().t - 1.0).abs() < 1e-5);
    }

    #[test]
    fn misses_and_grazes() {
        let miss = Ray::new(Vec3A::new(0.0, 1.01, 0.0), Vec3A::Z);
        assert!(unit().intersect(&miss, 0.0, f32::INFINITY).is_none());
        let graze = Ray::new(Vec3A::new(0.0, 0.9999, 0.0), Vec3A::Z);
        let h = unit().intersect(&graze, 0.0, f32::INFINITY).unwrap();
        assert!((h.t - 5.0).abs() < 0.05);
        let behind = Ray::new(Vec3A::new(0.0, 0.0, 10.0), Vec3A::Z);
        assert!(unit().intersect(&behind, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn far_origin_keeps_precision() {
        let s = Sphere { center: Vec3A::new(0.0, 0.0, 1.0e4), radius: 1.0 };
        let h = s.intersect(&Ray::new(Vec3A::ZERO, Vec3A::Z), 0.0, f32::INFINITY).unwrap();
        assert!((h.t - (1.0e4 - 1.0)).abs() < 1e-2);
    }
}
