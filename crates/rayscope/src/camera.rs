//! Cameras: the course's trackball and a plain look-at camera, both reduced to one pinhole
//! model so that every face of rayscope generates the same primary rays.

use serde::{Deserialize, Serialize};
use wide::f32x8;

use crate::animation::Shutter;
use crate::geometry::{DirectionRect, Frustum};
use crate::math::{Mat3, Quat, Vec2, Vec3, Vec3A, quat_from_euler_degrees};
use crate::motion::MotionPath;
use crate::ray::Ray;

/// How a scene describes its camera. Every field has a default, `kind` too (a trackball), so
/// it is read through [`CameraFields`] rather than as a tagged enum: serde's tagged enums
/// require the tag and report it missing before any other mistake in the table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", try_from = "CameraFields")]
pub enum CameraDesc {
    /// The course's trackball: orbit `distance` around `look_at`, rotated by Euler angles.
    Trackball {
        /// Point orbited and looked at.
        #[serde(default)]
        look_at: Vec3,
        /// Distance from the look-at point.
        #[serde(default = "default_distance")]
        distance: f32,
        /// Euler angles in degrees, glm's `quat(vec3)` convention (x first, then y, then z).
        #[serde(default = "default_rotation")]
        rotation: Vec3,
        /// Vertical field of view in degrees.
        #[serde(default = "default_fov")]
        fov: f32,
    },
    /// A camera at `eye` looking at `target`, with `up` roughly up.
    LookAt {
        /// Camera position.
        eye: Vec3,
        /// Point looked at.
        target: Vec3,
        /// Up direction (need not be orthogonal to the view direction).
        #[serde(default = "default_up")]
        up: Vec3,
        /// Vertical field of view in degrees.
        #[serde(default = "default_fov")]
        fov: f32,
    },
}

/// The two kinds of camera, as a scene file names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum CameraKind {
    Trackball,
    LookAt,
}

/// A camera table as written: any of the fields of either kind. Read as a plain struct, a
/// wrong type is reported at its key and an unknown key by name.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFields {
    kind: Option<CameraKind>,
    look_at: Option<Vec3>,
    distance: Option<f32>,
    rotation: Option<Vec3>,
    fov: Option<f32>,
    eye: Option<Vec3>,
    target: Option<Vec3>,
    up: Option<Vec3>,
    // The lens, read by the scene's loader into the render settings (`scene/camera_lens.rs`);
    // declared here so that the table's parse accepts them and checks their types.
    #[allow(dead_code, reason = "read by the scene loader's own parse of the table")]
    aperture: Option<f32>,
    #[allow(dead_code, reason = "read by the scene loader's own parse of the table")]
    focus_distance: Option<f32>,
}

impl TryFrom<CameraFields> for CameraDesc {
    type Error = String;

    fn try_from(f: CameraFields) -> Result<CameraDesc, String> {
        let fov = f.fov.unwrap_or_else(default_fov);
        let kind = f.kind.unwrap_or(CameraKind::Trackball);
        // The other kind's fields, by name: the message a tagged enum gave.
        let foreign = match kind {
            CameraKind::Trackball => [("eye", f.eye.is_some()), ("target", f.target.is_some()), ("up", f.up.is_some())],
            CameraKind::LookAt => [
                ("look_at", f.look_at.is_some()),
                ("distance", f.distance.is_some()),
                ("rotation", f.rotation.is_some()),
            ],
        };
        if let Some((key, _)) = foreign.iter().find(|(_, given)| *given) {
            let (this, expected) = match kind {
                CameraKind::Trackball => {
                    ("trackball", "`kind`, `look_at`, `distance`, `rotation`, `fov`, `aperture` or `focus_distance`")
                }
                CameraKind::LookAt => {
                    ("look-at", "`kind`, `eye`, `target`, `up`, `fov`, `aperture` or `focus_distance`")
                }
            };
            return Err(format!("unknown field `{key}` for a {this} camera, expected {expected}"));
        }
        Ok(match kind {
            CameraKind::Trackball => CameraDesc::Trackball {
                look_at: f.look_at.unwrap_or_default(),
                distance: f.distance.unwrap_or_else(default_distance),
                rotation: f.rotation.unwrap_or_else(default_rotation),
                fov,
            },
            CameraKind::LookAt => CameraDesc::LookAt {
                eye: f.eye.ok_or("missing field `eye`")?,
                target: f.target.ok_or("missing field `target`")?,
                up: f.up.unwrap_or_else(default_up),
                fov,
            },
        })
    }
}

fn default_distance() -> f32 {
    3.0
}
fn default_rotation() -> Vec3 {
    Vec3::new(20.0, 20.0, 0.0)
}
fn default_fov() -> f32 {
    50.0
}
fn default_up() -> Vec3 {
    Vec3::Y
}

impl Default for CameraDesc {
    /// The course's default view: fov 50, distance 3, look-at origin, rotation (20, 20, 0).
    fn default() -> Self {
        CameraDesc::Trackball {
            look_at: Vec3::ZERO,
            distance: default_distance(),
            rotation: default_rotation(),
            fov: default_fov(),
        }
    }
}

/// A pinhole camera: position, orientation and vertical field of view.
///
/// Primary ray through normalised screen point `(x, y)` in `[-1, 1]^2` (y up):
/// `origin = position`,
/// `dir = rotation * normalize(-x * tan(fov/2) * aspect, y * tan(fov/2), 1)`.
/// The camera looks along its local `+z`; screen right is local `-x`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub position: Vec3A,
    /// Camera-to-world rotation.
    pub rotation: Quat,
    /// Vertical field of view in degrees.
    pub fov_y: f32,
    /// Distance along the view axis to the point looked at: where a thin lens focuses unless
    /// told otherwise ([`crate::lens::ThinLens`]).
    pub look_distance: f32,
}

impl Camera {
    /// The camera a description stands for.
    pub fn from_desc(desc: &CameraDesc) -> Camera {
        match *desc {
            CameraDesc::Trackball { look_at, distance, rotation, fov } => {
                let rotation = quat_from_euler_degrees(rotation);
                Camera {
                    position: Vec3A::from(look_at + rotation * Vec3::new(0.0, 0.0, -distance)),
                    rotation,
                    fov_y: fov,
                    look_distance: distance,
                }
            }
            CameraDesc::LookAt { eye, target, up, fov } => {
                let forward = (target - eye).normalize_or(Vec3::Z);
                // Local +x is screen-left: up x forward.
                let left = up.cross(forward).try_normalize().unwrap_or_else(|| forward.any_orthonormal_vector());
                let cam_up = forward.cross(left);
                let rotation = Quat::from_mat3(&Mat3::from_cols(left, cam_up, forward)).normalize();
                Camera { position: Vec3A::from(eye), rotation, fov_y: fov, look_distance: (target - eye).length() }
            }
        }
    }

    /// The primary ray through normalised screen point `ndc` (`[-1, 1]^2`, y up) for an image
    /// of aspect ratio `aspect` (width / height): the course's formula as written. The
    /// renderer makes its rays with a [`RayGenerator`], which agrees up to rounding.
    pub fn ray(&self, ndc: Vec2, aspect: f32) -> Ray {
        let h = self.tan_half_fov();
        let local = Vec3::new(-ndc.x * h * aspect, ndc.y * h, 1.0).normalize();
        Ray::new(self.position, Vec3A::from(self.rotation * local))
    }

    /// `tan(fov_y / 2)`.
    #[inline]
    pub fn tan_half_fov(&self) -> f32 {
        (self.fov_y.to_radians() * 0.5).tan()
    }

    /// The normalised screen point of the centre of pixel `(px, py)` (row 0 at the top) in a
    /// `width x height` image, offset by `jitter` in `[0, 1)^2` (0.5 is the centre).
    #[inline]
    pub fn ndc(px: u32, py: u32, width: u32, height: u32, jitter: Vec2) -> Vec2 {
        Vec2::new((px as f32 + jitter.x) / width as f32 * 2.0 - 1.0, 1.0 - (py as f32 + jitter.y) / height as f32 * 2.0)
    }

    /// The primary ray through the centre of pixel `(px, py)`, as the renderer makes it
    /// ([`RayGenerator`]; build one to make many).
    pub fn pixel_ray(&self, px: u32, py: u32, width: u32, height: u32) -> Ray {
        RayGenerator::new(self, width, height).ray(px, py, Vec2::splat(0.5))
    }
}

/// The primary rays of one camera pose for one image size, with everything that depends only
/// on them done once: the rotation as three axes, `tan(fov/2)` and the aspect ratio folded
/// into them, and the pixel-to-screen scale as a product. Per ray that leaves a
/// multiply-add per axis and a normalisation (a quaternion rotation and three divisions were
/// a tenth of a simple scene's render time).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayGenerator {
    pub(crate) origin: Vec3A,
    /// World direction of screen `x = 1` minus the forward axis.
    pub(crate) right: Vec3A,
    /// World direction of screen `y = 1` minus the forward axis.
    pub(crate) up: Vec3A,
    forward: Vec3A,
    /// `2 / width` and `2 / height`.
    scale: Vec2,
}

impl RayGenerator {
    /// Rays of `camera` for a `width x height` image.
    pub fn new(camera: &Camera, width: u32, height: u32) -> RayGenerator {
        let h = camera.tan_half_fov();
        let aspect = width as f32 / height as f32;
        let axis = |v: Vec3| Vec3A::from(camera.rotation * v);
        RayGenerator {
            origin: camera.position,
            // Screen right is local -x (the course's convention), scaled to the image plane.
            right: axis(Vec3::new(-h * aspect, 0.0, 0.0)),
            up: axis(Vec3::new(0.0, h, 0.0)),
            forward: axis(Vec3::Z),
            scale: Vec2::new(2.0 / width as f32, 2.0 / height as f32),
        }
    }

    /// The ray through pixel `(px, py)` (row 0 at the top) at offset `jitter` in `[0, 1)^2`
    /// (0.5 is the centre): [`Camera::ray`] at [`Camera::ndc`], up to rounding.
    #[inline]
    pub fn ray(&self, px: u32, py: u32, jitter: Vec2) -> Ray {
        Ray::new(self.origin, self.direction(px, py, jitter).normalize())
    }

    /// [`RayGenerator::ray`] of eight pixels (`px[i]`, `py[i]`, `jitter[i]`), the same rays
    /// bit for bit: each lane takes the scalar code's operations in its order (no fused
    /// multiply-adds; the length as `(x x + y y) + z z`, as glam's), so the eight square roots
    /// and 24 divisions of the normalisations go in vector instructions, where one ray at a
    /// time they queued on the divider (a tenth of the packet loop's samples in the Cornell
    /// box's profile sat on the store after the division).
    ///
    /// Only where glam normalises by dividing by the length (its SSE2 code, which x86-64
    /// always has): its other back ends (NEON, scalar) multiply by the length's reciprocal,
    /// which rounds otherwise, and there the rays are made one at a time.
    #[inline(always)]
    pub(crate) fn rays8(&self, px: [u32; 8], py: [u32; 8], jitter: [Vec2; 8]) -> [Ray; 8] {
        if !cfg!(all(any(target_arch = "x86", target_arch = "x86_64"), target_feature = "sse2")) {
            return std::array::from_fn(|i| self.ray(px[i], py[i], jitter[i]));
        }
        let splat = f32x8::splat;
        let x = f32x8::new(std::array::from_fn(|i| px[i] as f32 + jitter[i].x)) * splat(self.scale.x) - splat(1.0);
        let y = splat(1.0) - f32x8::new(std::array::from_fn(|i| py[i] as f32 + jitter[i].y)) * splat(self.scale.y);
        let axis = |a: usize| x * splat(self.right[a]) + y * splat(self.up[a]) + splat(self.forward[a]);
        let (dx, dy, dz) = (axis(0), axis(1), axis(2));
        let length = (dx * dx + dy * dy + dz * dz).sqrt();
        let (dx, dy, dz) = ((dx / length).to_array(), (dy / length).to_array(), (dz / length).to_array());
        std::array::from_fn(|i| Ray::new(self.origin, Vec3A::new(dx[i], dy[i], dz[i])))
    }

    /// A frustum holding every ray [`RayGenerator::ray`] gives for the pixels of columns
    /// `x[0]..x[1]` and rows `y[0]..y[1]` with a jitter within `reach` pixels of the pixel
    /// centre (the filter's radius), widened by one more pixel on every side: far more than
    /// the rounding of the rays' directions moves them.
    pub fn tile_frustum(&self, x: [u32; 2], y: [u32; 2], reach: f32) -> Frustum {
        let m = reach + 1.0;
        let (sx, sy) = (|p: f32| p * self.scale.x - 1.0, |p: f32| 1.0 - p * self.scale.y);
        let rect = DirectionRect {
            right: self.right,
            up: self.up,
            forward: self.forward,
            x: [sx(x[0] as f32 + 0.5 - m), sx(x[1] as f32 - 0.5 + m)],
            // Screen y grows upwards, rows downwards.
            y: [sy(y[1] as f32 - 0.5 + m), sy(y[0] as f32 + 0.5 - m)],
        };
        Frustum::new(self.origin, &rect)
    }

    /// The unnormalised direction of [`RayGenerator::ray`]: its component along the view
    /// axis is 1, so `origin + t * direction` lies at depth `t` (the thin lens's focal plane).
    #[inline]
    pub(crate) fn direction(&self, px: u32, py: u32, jitter: Vec2) -> Vec3A {
        let x = (px as f32 + jitter.x) * self.scale.x - 1.0;
        let y = 1.0 - (py as f32 + jitter.y) * self.scale.y;
        x * self.right + y * self.up + self.forward
    }
}

/// A camera that may move during the exposure: `start` at scene time 0, and either `end` at
/// scene time 1 (interpolated between, held outside) or a `path` its position is translated
/// along (its orientation and field of view stay `start`'s); seen over the scene times its
/// `shutter` exposes.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraMotion {
    /// The pose when the shutter opens (with a path: before the path's translation).
    pub start: Camera,
    /// The pose when it closes (`None`: no end pose).
    pub end: Option<Camera>,
    /// A path the camera's position is translated along (`None`: none); it takes precedence
    /// over `end` (scene files give one or the other).
    pub path: Option<MotionPath>,
    /// The scene time the exposure covers ([`Shutter::STILL`] for a still image).
    pub shutter: Shutter,
}

impl CameraMotion {
    /// A camera that does not move.
    pub fn still(camera: Camera) -> CameraMotion {
        CameraMotion { start: camera, end: None, path: None, shutter: Shutter::STILL }
    }

    /// Whether the camera has one pose for the whole exposure (no end pose, no path), so that
    /// all its rays share a pinhole and can be traced in packets.
    #[inline]
    pub fn is_still(&self) -> bool {
        self.end.is_none() && self.path.is_none()
    }

    /// The pose at shutter fraction `u` in `[0, 1)`, at scene time `t` =
    /// [`Shutter::time`]`(u)`: along the path, the start pose translated by the path's value
    /// at `t`; towards an end pose, positions and fields of view interpolated linearly,
    /// orientations by slerp, at `t` held to `[0, 1]` (under [`Shutter::STILL`], `t` is `u`).
    #[inline]
    pub fn at(&self, u: f32) -> Camera {
        let t = self.shutter.time(u);
        match (&self.path, &self.end) {
            (Some(path), _) => Camera { position: self.start.position + path.at(t), ..self.start },
            (None, Some(end)) if *end != self.start => self.towards(end, t.clamp(0.0, 1.0)),
            _ => self.start,
        }
    }

    /// The pose a fraction `t` of the way from `start` to `end`.
    #[inline]
    fn towards(&self, end: &Camera, t: f32) -> Camera {
        Camera {
            position: self.start.position.lerp(end.position, t),
            rotation: self.start.rotation.slerp(end.rotation, t),
            fov_y: self.start.fov_y + (end.fov_y - self.start.fov_y) * t,
            look_distance: self.start.look_distance + (end.look_distance - self.start.look_distance) * t,
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    proptest! {
        /// Eight rays at once are each the ray made alone, bit for bit (origin, direction,
        /// interval, time): random look-at cameras and fields of view, image sizes from 1
        /// pixel to 16k, pixels anywhere (beyond the image too) and jitters in `[0, 1]`.
        #[test]
        fn eight_rays_at_once_as_one_at_a_time(
            eye in prop::array::uniform3(-100.0f32..100.0),
            target in prop::array::uniform3(-1.0f32..1.0),
            fov in 1.0f32..170.0,
            size in (1u32..16384, 1u32..16384),
            px in prop::array::uniform8(0u32..20000),
            py in prop::array::uniform8(0u32..20000),
            jitter in prop::array::uniform8(prop::array::uniform2(0.0f32..=1.0)),
        ) {
            let desc = CameraDesc::LookAt { eye: Vec3::from_array(eye), target: Vec3::from_array(target), up: Vec3::Y, fov };
            let g = RayGenerator::new(&Camera::from_desc(&desc), size.0, size.1);
            let jitter = jitter.map(Vec2::from_array);
            let eight = g.rays8(px, py, jitter);
            for i in 0..8 {
                let one = g.ray(px[i], py[i], jitter[i]);
                let bits = |r: &Ray| (r.origin.to_array().map(f32::to_bits), r.dir.to_array().map(f32::to_bits), r.t, r.time.to_bits());
                prop_assert_eq!(bits(&eight[i]), bits(&one), "lane {}", i);
            }
        }
    }

    #[test]
    fn default_trackball_looks_at_origin_from_above() {
        let cam = Camera::from_desc(&CameraDesc::default());
        assert!((cam.position.length() - 3.0).abs() < 1e-5);
        assert!(cam.position.y > 0.0, "rotation (20,20,0) lifts the eye above the look-at point");
        let centre = cam.ray(Vec2::ZERO, 1.0);
        let to_origin = (-cam.position).normalize();
        assert!(centre.dir.dot(to_origin) > 1.0 - 1e-6);
    }

    #[test]
    fn screen_right_is_local_minus_x() {
        let cam = Camera::from_desc(&CameraDesc::Trackball {
            look_at: Vec3::ZERO,
            distance: 3.0,
            rotation: Vec3::ZERO,
            fov: 90.0,
        });
        let r = cam.ray(Vec2::new(1.0, 0.0), 1.0);
        assert!(r.dir.x < 0.0 && r.dir.z > 0.0);
        let up = cam.ray(Vec2::new(0.0, 1.0), 1.0);
        assert!(up.dir.y > 0.0);
    }

    #[test]
    fn motion_interpolates_between_poses() {
        let a = Camera::from_desc(&CameraDesc::default());
        let b = Camera::from_desc(&CameraDesc::Trackball {
            look_at: Vec3::ZERO,
            distance: 3.0,
            rotation: Vec3::new(20.0, 60.0, 0.0),
            fov: 50.0,
        });
        let m = CameraMotion { end: Some(b), ..CameraMotion::still(a) };
        assert!(m.at(0.0).position.distance(a.position) < 1e-6 && m.at(0.0).rotation.dot(a.rotation) > 1.0 - 1e-6);
        assert_eq!(CameraMotion { end: Some(a), ..CameraMotion::still(a) }.at(0.3), a, "no motion is exactly still");
        let mid = m.at(0.5);
        // Slerp keeps the eye on the trackball's sphere only for the rotation; the position is
        // a straight line, so the midpoint lies inside it.
        assert!(mid.position.length() < 3.0 && mid.position.length() > 2.8);
        let still = CameraMotion::still(a);
        assert_eq!(still.at(0.7), a);
    }

    #[test]
    fn ray_generator_matches_the_camera_formula() {
        let cam = Camera::from_desc(&CameraDesc::default());
        let (w, h) = (640, 480);
        let rays = RayGenerator::new(&cam, w, h);
        for (x, y, j) in [(0, 0, Vec2::ZERO), (639, 479, Vec2::splat(0.999)), (320, 100, Vec2::new(0.25, 0.75))] {
            let a = rays.ray(x, y, j);
            let b = cam.ray(Camera::ndc(x, y, w, h, j), w as f32 / h as f32);
            assert_eq!(a.origin, b.origin);
            assert!(a.dir.dot(b.dir) > 1.0 - 1e-6 && a.dir.is_normalized(), "{x},{y}");
        }
    }

    #[test]
    fn look_at_matches_equivalent_trackball() {
        let tb = Camera::from_desc(&CameraDesc::default());
        let target = Vec3::ZERO;
        let up = tb.rotation * Vec3::Y;
        let la = Camera::from_desc(&CameraDesc::LookAt { eye: Vec3::from(tb.position), target, up, fov: 50.0 });
        for ndc in [Vec2::new(0.3, -0.7), Vec2::new(-1.0, 1.0)] {
            let (a, b) = (tb.ray(ndc, 1.0), la.ray(ndc, 1.0));
            assert!(a.dir.dot(b.dir) > 1.0 - 1e-6, "{ndc}");
        }
    }
}
