//! Depth of field: a thin lens in front of the pinhole camera (pbrt-v4's `PerspectiveCamera`).
//!
//! The pinhole ray through a pixel, `origin + t * d` with `d`'s component along the view axis
//! 1, meets the focal plane (depth `focus_distance`) at `p = origin + focus_distance * d`.
//! The thin lens moves the ray's origin to a point of a disk of radius `aperture` around the
//! pinhole, in the image plane's axes, and aims it at `p`: every lens sample of a pixel meets
//! the focal plane at the same point (sharp there), and spreads into a cone of radius
//! `aperture * |depth - focus| / focus` elsewhere (the circle of confusion). A lens of radius 0
//! is the pinhole, and the renderer then never builds one ([`ThinLens::new`] gives `None`).

use crate::camera::{Camera, RayGenerator};
use crate::math::{Vec2, Vec3A};
use crate::ray::Ray;
use crate::settings::RenderSettings;

/// A thin lens: where it focuses and how wide it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinLens {
    /// Lens radius, in scene units (> 0).
    pub radius: f32,
    /// Depth of the plane in focus, along the view axis (> 0).
    pub focus_distance: f32,
}

impl ThinLens {
    /// The lens `settings` ask for in front of `camera`, or `None` for a pinhole (aperture 0):
    /// the focus distance is [`RenderSettings::focus_distance`], else the camera's look-at
    /// distance.
    pub fn new(settings: &RenderSettings, camera: &Camera) -> Option<ThinLens> {
        (settings.aperture > 0.0).then(|| ThinLens {
            radius: settings.aperture,
            focus_distance: settings.focus_distance.unwrap_or(camera.look_distance),
        })
    }

    /// The ray through pixel `(px, py)` at offset `jitter` (as [`RayGenerator::ray`]) that
    /// leaves the lens at `lens` (a point of `[0,1]^2`, mapped onto the disk).
    #[inline]
    pub fn ray(&self, rays: &RayGenerator, px: u32, py: u32, jitter: Vec2, lens: Vec2) -> Ray {
        let d = rays.direction(px, py, jitter);
        let focus = rays.origin + self.focus_distance * d;
        let disk = self.radius * concentric_disk(lens);
        let origin = rays.origin + disk.x * rays.right.normalize() + disk.y * rays.up.normalize();
        Ray::new(origin, (focus - origin).normalize())
    }

    /// The point in focus on pixel `(px, py)`'s ray at offset `jitter`: where every lens
    /// sample's ray crosses the focal plane.
    pub fn focal_point(&self, rays: &RayGenerator, px: u32, py: u32, jitter: Vec2) -> Vec3A {
        rays.origin + self.focus_distance * rays.direction(px, py, jitter)
    }
}

/// Shirley and Chiu's concentric map of `[0,1]^2` onto the unit disk: area-preserving and
/// continuous, so stratified squares stay stratified on the lens.
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, std::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraDesc;

    #[test]
    fn concentric_disk_stays_in_the_unit_disk_and_keeps_the_centre() {
        assert_eq!(concentric_disk(Vec2::splat(0.5)), Vec2::ZERO);
        for i in 0..=20 {
            for j in 0..=20 {
                let p = concentric_disk(Vec2::new(i as f32 / 20.0, j as f32 / 20.0));
                assert!(p.length() <= 1.0 + 1e-6, "{p}");
            }
        }
        // The square's edge is the circle.
        assert!((concentric_disk(Vec2::new(1.0, 0.7)).length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn every_lens_ray_meets_the_focal_plane_at_the_pixels_point() {
        let camera = Camera::from_desc(&CameraDesc::default());
        let rays = RayGenerator::new(&camera, 64, 48);
        let lens = ThinLens { radius: 0.2, focus_distance: 2.5 };
        let forward = Vec3A::from(camera.rotation * crate::math::Vec3::Z);
        for (px, py) in [(0, 0), (63, 47), (20, 30)] {
            let jitter = Vec2::new(0.3, 0.8);
            let p = lens.focal_point(&rays, px, py, jitter);
            // The focal point is at depth focus_distance along the view axis.
            assert!(((p - camera.position).dot(forward) - 2.5).abs() < 1e-5);
            for u in [Vec2::ZERO, Vec2::new(0.9, 0.1), Vec2::new(0.5, 0.99), Vec2::splat(0.5)] {
                let r = lens.ray(&rays, px, py, jitter, u);
                // Where this ray crosses the focal plane.
                let t = (2.5 - (r.origin - camera.position).dot(forward)) / r.dir.dot(forward);
                let q = r.origin + t * r.dir;
                assert!(q.distance(p) < 1e-5, "pixel {px},{py} lens {u}: {q} vs {p}");
            }
        }
    }
}
