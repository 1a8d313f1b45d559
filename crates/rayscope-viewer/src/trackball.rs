//! The course's trackball camera, as the viewer drives it: orbit, pan and zoom around a
//! look-at point. It produces the same [`CameraDesc::Trackball`] the library traces, so the
//! rasterized preview and the ray tracer see exactly the same thing.

use glam::{EulerRot, Vec3};
use rayscope::camera::{Camera, CameraDesc};

/// Degrees of rotation per point of mouse drag.
const ORBIT_SPEED: f32 = 0.3;

/// Orbit state in the course's terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trackball {
    /// Point orbited and looked at.
    pub look_at: Vec3,
    /// Distance from the look-at point.
    pub distance: f32,
    /// Euler angles in degrees (glm's `quat(vec3)` convention).
    pub rotation: Vec3,
    /// Vertical field of view in degrees.
    pub fov: f32,
}

impl Trackball {
    /// The trackball that shows what `desc` shows.
    pub fn from_desc(desc: &CameraDesc) -> Trackball {
        match *desc {
            CameraDesc::Trackball { look_at, distance, rotation, fov } => {
                Trackball { look_at, distance, rotation, fov }
            }
            CameraDesc::LookAt { eye, target, fov, .. } => {
                let cam = Camera::from_desc(desc);
                let (z, y, x) = cam.rotation.to_euler(EulerRot::ZYX);
                Trackball {
                    look_at: target,
                    distance: eye.distance(target),
                    rotation: Vec3::new(x, y, z) * (180.0 / std::f32::consts::PI),
                    fov,
                }
            }
        }
    }

    /// As a camera description.
    pub fn to_desc(&self) -> CameraDesc {
        CameraDesc::Trackball { look_at: self.look_at, distance: self.distance, rotation: self.rotation, fov: self.fov }
    }

    /// The camera.
    pub fn camera(&self) -> Camera {
        Camera::from_desc(&self.to_desc())
    }

    /// Orbit by a mouse drag of `(dx, dy)` points: the scene follows the mouse.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        self.rotation.y -= dx * ORBIT_SPEED;
        self.rotation.x = (self.rotation.x + dy * ORBIT_SPEED).clamp(-89.0, 89.0);
    }

    /// Pan by a drag of `(dx, dy)` points in a view `height` points tall: the look-at point
    /// moves so that the scene follows the mouse.
    pub fn pan(&mut self, dx: f32, dy: f32, height: f32) {
        let cam = self.camera();
        let scale = 2.0 * self.distance * (self.fov.to_radians() * 0.5).tan() / height.max(1.0);
        // Screen right is the camera's local -x; screen up its local +y.
        let right = cam.rotation * -Vec3::X;
        let up = cam.rotation * Vec3::Y;
        self.look_at += (-dx * right + dy * up) * scale;
    }

    /// Zoom by `scroll` points of wheel movement (positive: closer).
    pub fn zoom(&mut self, scroll: f32) {
        self.distance = (self.distance * (-scroll * 0.002).exp()).clamp(1e-3, 1e4);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_round_trips_through_the_trackball() {
        let desc = CameraDesc::LookAt {
            eye: Vec3::new(1.0, 2.0, -3.0),
            target: Vec3::new(0.2, 0.1, 0.0),
            up: Vec3::Y,
            fov: 40.0,
        };
        let a = Camera::from_desc(&desc);
        let b = Trackball::from_desc(&desc).camera();
        assert!(a.position.distance(b.position) < 1e-4);
        assert!(a.rotation.dot(b.rotation).abs() > 1.0 - 1e-5);
    }

    #[test]
    fn controls_move_the_camera() {
        let mut t = Trackball::from_desc(&CameraDesc::default());
        let p0 = t.camera().position;
        t.zoom(100.0);
        assert!(t.distance < 3.0);
        t.orbit(10.0, 0.0);
        assert!(t.camera().position.distance(p0) > 0.01);
        t.pan(0.0, 10.0, 800.0);
        // Dragging down moves the scene down with the mouse: the camera, and its look-at
        // point, rise.
        assert!(t.look_at.y > 0.0);
    }
}
