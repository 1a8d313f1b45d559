//! Math types: glam's SIMD vectors, a linear RGB colour, and small helpers.

pub use glam::{Mat3, Quat, Vec2, Vec3, Vec3A, Vec4};

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

/// `(sin, cos)` of `2 pi t`, for `t` in `[0, 1)`: an odd polynomial after reduction to a
/// quarter turn, accurate to about 1e-6, several times cheaper than libm's `sincosf`. For
/// sampling directions, where that accuracy is far below the noise.
#[inline]
pub fn sin_cos_turns(t: f32) -> (f32, f32) {
    #[inline(always)]
    fn sin_turns(t: f32) -> f32 {
        // Reduce to x in [-1/4, 1/4] turns, where sin is odd and monotonic (t < 1.25 here, so
        // no rounding call is needed: baseline x86-64 has no rounding instruction).
        let mut x = if t >= 0.5 { t - 1.0 } else { t };
        if x > 0.25 {
            x = 0.5 - x;
        } else if x < -0.25 {
            x = -0.5 - x;
        }
        let a = x * std::f32::consts::TAU;
        let a2 = a * a;
        let a4 = a2 * a2;
        // Taylor coefficients to a^11 (truncation error below 6e-8 at a = pi/2), evaluated in
        // Estrin's form: shorter dependency chains than Horner's, which profiles showed
        // stalling the shadow-sampling loop.
        let p0 = 1.0 - a2 * (1.0 / 6.0);
        let p1 = 1.0 / 120.0 - a2 * (1.0 / 5040.0);
        let p2 = 1.0 / 362880.0 - a2 * (1.0 / 39916800.0);
        a * (p0 + a4 * (p1 + a4 * p2))
    }
    (sin_turns(t), sin_turns(t + 0.25))
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
    fn fast_sin_cos_is_accurate() {
        for i in 0..=10000 {
            let t = i as f32 / 10000.0 * 0.99999;
            let (s, c) = sin_cos_turns(t);
            let (es, ec) = (std::f32::consts::TAU * t).sin_cos();
            assert!((s - es).abs() < 2e-6 && (c - ec).abs() < 2e-6, "{t}: {s} {c} vs {es} {ec}");
        }
    }

    #[test]
    fn reflect_mirrors() {
        let r = reflect(Vec3A::new(1.0, -1.0, 0.0), Vec3A::Y);
        assert_eq!(r, Vec3A::new(1.0, 1.0, 0.0));
    }
}
