//! Math types: glam's SIMD vectors, a linear RGB colour, and small helpers.

pub use glam::{Mat3, Quat, Vec2, Vec3, Vec3A};

/// Linear RGB colour. Values are not clamped: the film keeps them as they are.
pub type Color = Vec3;

/// Mirror reflection of `d` about the normal `n` (both need not be normalised for `n`, but
/// `n` must be unit length for the result to keep `d`'s length).
#[inline]
pub fn reflect(d: Vec3A, n: Vec3A) -> Vec3A {
    d - 2.0 * d.dot(n) * n
}

/// Flip `n` so that it lies in the same hemisphere as `reference`.
#[inline]
pub fn face_forward(n: Vec3A, reference: Vec3A) -> Vec3A {
    if n.dot(reference) < 0.0 { -n } else { n }
}

/// The course's rotation convention: glm's `quat(vec3 eulerRadians)`, which is
/// `Rz * Ry * Rx` (rotate about x first). Angles in degrees.
pub fn quat_from_euler_degrees(degrees: Vec3) -> Quat {
    let r = degrees * (std::f32::consts::PI / 180.0);
    Quat::from_euler(glam::EulerRot::ZYX, r.z, r.y, r.x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// glm's `quat(vec3)` written out as glm does; ours must agree with it exactly.
    fn glm_quat(e: Vec3) -> Quat {
        let c = (e * 0.5).to_array().map(f32::cos);
        let s = (e * 0.5).to_array().map(f32::sin);
        Quat::from_xyzw(
            s[0] * c[1] * c[2] - c[0] * s[1] * s[2],
            c[0] * s[1] * c[2] + s[0] * c[1] * s[2],
            c[0] * c[1] * s[2] - s[0] * s[1] * c[2],
            c[0] * c[1] * c[2] + s[0] * s[1] * s[2],
        )
    }

    #[test]
    fn euler_matches_glm() {
        for deg in [Vec3::new(20.0, 20.0, 0.0), Vec3::new(-35.0, 170.0, 42.0), Vec3::ZERO] {
            let a = quat_from_euler_degrees(deg);
            let b = glm_quat(deg * (std::f32::consts::PI / 180.0));
            assert!(a.dot(b).abs() > 1.0 - 1e-6, "{deg}: {a} vs {b}");
        }
    }

    #[test]
    fn reflect_mirrors() {
        let r = reflect(Vec3A::new(1.0, -1.0, 0.0), Vec3A::Y);
        assert_eq!(r, Vec3A::new(1.0, 1.0, 0.0));
    }
}
