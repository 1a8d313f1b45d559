//! Lights in the course's colour model. Each light can name a point on itself with its colour
//! there ([`Light::point_at`]); shading asks for [`LightSample`]s from a shading point.

use serde::{Deserialize, Serialize};

use crate::math::{Color, Vec2, Vec3, Vec3A, sin_cos_turns};

/// A light source. Lights are not visible geometry (as in the course).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Light {
    /// A point light.
    Point {
        /// Position.
        position: Vec3,
        /// Colour (intensity; not attenuated with distance, as in the course).
        color: Color,
    },
    /// A line segment whose colour is interpolated linearly between its ends.
    Segment {
        /// First end.
        endpoint0: Vec3,
        /// Second end.
        endpoint1: Vec3,
        /// Colour at `endpoint0`.
        color0: Color,
        /// Colour at `endpoint1`.
        color1: Color,
    },
    /// A parallelogram `v0 + a * edge01 + b * edge02` with bilinear corner colours:
    /// `color0` at `v0`, `color1` at `v0 + edge01`, `color2` at `v0 + edge02`, `color3` at
    /// `v0 + edge01 + edge02`.
    Parallelogram {
        /// Corner 0.
        v0: Vec3,
        /// Edge from corner 0 to corner 1.
        edge01: Vec3,
        /// Edge from corner 0 to corner 2.
        edge02: Vec3,
        /// Colour at corner 0.
        color0: Color,
        /// Colour at corner 1.
        color1: Color,
        /// Colour at corner 2.
        color2: Color,
        /// Colour at corner 3.
        color3: Color,
    },
    /// A sphere of uniform colour.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
        /// Colour.
        color: Color,
    },
}

/// A point on a light as seen from a shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// The point on the light.
    pub point: Vec3A,
    /// Unit direction from the shading point to `point`.
    pub wi: Vec3A,
    /// Distance from the shading point to `point`.
    pub distance: f32,
    /// The light's colour at `point`.
    pub color: Color,
    /// Density of the sample with respect to the light's sampling measure (1 for a point, or a
    /// sample taken at a fixed spot such as the centre).
    pub pdf: f32,
}

/// Samples one light from one shading point: [`Light::sampler`].
#[derive(Clone, Copy, Debug)]
pub struct LightSampler {
    p: Vec3A,
    kind: SamplerKind,
}

#[derive(Clone, Copy, Debug)]
enum SamplerKind {
    Fixed { point: Vec3A, color: Color },
    Segment { start: Vec3A, delta: Vec3A, color0: Color, color1: Color, pdf: f32 },
    Parallelogram { v0: Vec3A, edge01: Vec3A, edge02: Vec3A, colors: [Color; 4], pdf: f32 },
    SphereSurface { center: Vec3A, radius: f32, color: Color, pdf: f32 },
    SphereCone { w: Vec3A, t1: Vec3A, t2: Vec3A, d: f32, r2: f32, one_minus_cos_max: f32, color: Color, pdf: f32 },
}

impl LightSampler {
    /// The point chosen by `u` in `[0,1)^2`: see [`Light::sample`].
    #[inline(always)]
    pub fn sample(&self, u: Vec2) -> LightSample {
        let p = self.p;
        let at = |point: Vec3A, color: Color, pdf: f32| {
            let to = point - p;
            let distance = to.length();
            let wi = if distance > 0.0 { to / distance } else { Vec3A::ZERO };
            LightSample { point, wi, distance, color, pdf }
        };
        match self.kind {
            SamplerKind::Fixed { point, color } => at(point, color, 1.0),
            SamplerKind::Segment { start, delta, color0, color1, pdf } => {
                at(start + u.x * delta, color0.lerp(color1, u.x), pdf)
            }
            SamplerKind::Parallelogram { v0, edge01, edge02, colors: [c0, c1, c2, c3], pdf } => {
                let c = c0.lerp(c1, u.x).lerp(c2.lerp(c3, u.x), u.y);
                at(v0 + u.x * edge01 + u.y * edge02, c, pdf)
            }
            SamplerKind::SphereSurface { center, radius, color, pdf } => {
                let z = 1.0 - 2.0 * u.x;
                let s = (1.0 - z * z).max(0.0).sqrt();
                let (sin_phi, cos_phi) = sin_cos_turns(u.y);
                at(center + radius * Vec3A::new(s * cos_phi, s * sin_phi, z), color, pdf)
            }
            SamplerKind::SphereCone { w, t1, t2, d, r2, one_minus_cos_max, color, pdf } => {
                let one_minus_cos = u.x * one_minus_cos_max;
                let cos = 1.0 - one_minus_cos;
                let sin = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
                let (sin_phi, cos_phi) = sin_cos_turns(u.y);
                let dir = (sin * cos_phi) * t1 + (sin * sin_phi) * t2 + cos * w;
                // Where the direction meets the sphere: the near root of |p + t dir - c| = r.
                // `b` is the distance to the closest approach, `h2` the half chord squared.
                let b = d * cos;
                let h2 = (r2 - d * d * sin * sin).max(0.0);
                let t = b - h2.sqrt();
                // The direction is unit length by construction: no need to measure it again.
                LightSample { point: p + t * dir, wi: dir, distance: t, color, pdf }
            }
        }
    }
}

impl Light {
    /// The point at parameters `u` in `[0,1]^2` and the light's colour there: the position of
    /// a point light; `lerp(endpoint0, endpoint1, u.x)` on a segment; `v0 + u.x edge01 + u.y
    /// edge02` on a parallelogram; the centre of a sphere.
    #[inline(always)]
    pub fn point_at(&self, u: Vec2) -> (Vec3A, Color) {
        match *self {
            Light::Point { position, color } => (position.into(), color),
            Light::Segment { endpoint0, endpoint1, color0, color1 } => {
                (endpoint0.lerp(endpoint1, u.x).into(), color0.lerp(color1, u.x))
            }
            Light::Parallelogram { v0, edge01, edge02, color0, color1, color2, color3 } => {
                let c = color0.lerp(color1, u.x).lerp(color2.lerp(color3, u.x), u.y);
                ((v0 + u.x * edge01 + u.y * edge02).into(), c)
            }
            Light::Sphere { center, color, .. } => (center.into(), color),
        }
    }

    /// The light shaded as a point light at its centre (with its mean colour there), from
    /// shading point `p`: hard shadows from every kind of light.
    #[inline(always)]
    pub fn center_sample(&self, p: Vec3A) -> LightSample {
        let (point, color) = self.point_at(Vec2::splat(0.5));
        let to = point - p;
        let distance = to.length();
        LightSample { point, wi: to / distance, distance, color, pdf: 1.0 }
    }

    /// A point on the light for shading point `p`, chosen by `u` in `[0,1)^2`, with the
    /// light's colour there. Point lights ignore `u`. Segments and parallelograms are sampled
    /// uniformly by length/area (`pdf` per unit length/area). Sphere lights are sampled
    /// uniformly in the cone of directions that the sphere subtends from `p` (`pdf` per
    /// steradian), so every sample lands on the cap that `p` can see; from inside the sphere,
    /// uniformly over its surface. (The course's reports drew latitude and longitude uniformly
    /// and re-drew points facing away, which crowds samples at the poles and wastes draws.)
    pub fn sample(&self, p: Vec3A, u: Vec2) -> LightSample {
        self.sampler(p).sample(u)
    }

    /// The work of [`Light::sample`] that depends only on the shading point, done once: a
    /// shading point draws many samples from each light.
    pub fn sampler(&self, p: Vec3A) -> LightSampler {
        let kind = match *self {
            Light::Point { position, color } => SamplerKind::Fixed { point: position.into(), color },
            Light::Segment { endpoint0, endpoint1, color0, color1 } => {
                let len = endpoint0.distance(endpoint1);
                SamplerKind::Segment {
                    start: endpoint0.into(),
                    delta: (endpoint1 - endpoint0).into(),
                    color0,
                    color1,
                    pdf: if len > 0.0 { 1.0 / len } else { 1.0 },
                }
            }
            Light::Parallelogram { v0, edge01, edge02, color0, color1, color2, color3 } => {
                let area = edge01.cross(edge02).length();
                SamplerKind::Parallelogram {
                    v0: v0.into(),
                    edge01: edge01.into(),
                    edge02: edge02.into(),
                    colors: [color0, color1, color2, color3],
                    pdf: if area > 0.0 { 1.0 / area } else { 1.0 },
                }
            }
            Light::Sphere { center, radius, color } => {
                let c = Vec3A::from(center);
                let d2 = c.distance_squared(p);
                let r2 = radius * radius;
                if radius <= 0.0 {
                    SamplerKind::Fixed { point: c, color }
                } else if d2 <= r2 {
                    // Inside the light: every direction sees it; sample its whole surface.
                    SamplerKind::SphereSurface {
                        center: c,
                        radius,
                        color,
                        pdf: 1.0 / (4.0 * std::f32::consts::PI * r2),
                    }
                } else {
                    let d = d2.sqrt();
                    let w = (c - p) / d;
                    let sin2_max = r2 / d2;
                    // 1 - cos(theta_max), by its series for small cones, where the direct form
                    // loses every digit to cancellation.
                    let one_minus_cos_max = if sin2_max < 1e-3 {
                        sin2_max * (0.5 + sin2_max / 8.0)
                    } else {
                        1.0 - (1.0 - sin2_max).max(0.0).sqrt()
                    };
                    let (t1, t2) = w.any_orthonormal_pair();
                    SamplerKind::SphereCone {
                        w,
                        t1,
                        t2,
                        d,
                        r2,
                        one_minus_cos_max,
                        color,
                        pdf: 1.0 / (std::f32::consts::TAU * one_minus_cos_max),
                    }
                }
            }
        };
        LightSampler { p, kind }
    }

    /// A representative position (the centre), for drawing and for distance heuristics.
    pub fn center(&self) -> Vec3A {
        self.point_at(Vec2::splat(0.5)).0
    }

    /// A sphere holding every point of the light: `(centre, radius)`.
    pub fn bounding_sphere(&self) -> (Vec3A, f32) {
        match *self {
            Light::Point { position, .. } => (position.into(), 0.0),
            Light::Segment { endpoint0, endpoint1, .. } => {
                (endpoint0.lerp(endpoint1, 0.5).into(), 0.5 * endpoint0.distance(endpoint1))
            }
            Light::Parallelogram { v0, edge01, edge02, .. } => {
                let half = 0.5 * (edge01 + edge02).length().max((edge01 - edge02).length());
                ((v0 + 0.5 * (edge01 + edge02)).into(), half)
            }
            Light::Sphere { center, radius, .. } => (center.into(), radius),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parallelogram_colours_are_bilinear() {
        let l = Light::Parallelogram {
            v0: Vec3::ZERO,
            edge01: Vec3::X,
            edge02: Vec3::Z,
            color0: Vec3::X,
            color1: Vec3::Y,
            color2: Vec3::Z,
            color3: Vec3::new(0.0, 1.0, 1.0),
        };
        assert_eq!(l.point_at(Vec2::new(1.0, 0.0)), (Vec3A::X, Vec3::Y));
        assert_eq!(l.point_at(Vec2::new(0.0, 1.0)), (Vec3A::Z, Vec3::Z));
        let (p, c) = l.point_at(Vec2::splat(0.5));
        assert_eq!(p, Vec3A::new(0.5, 0.0, 0.5));
        assert!((c - Vec3::new(0.25, 0.5, 0.5)).abs().max_element() < 1e-6);
    }

    #[test]
    fn sphere_samples_lie_on_the_visible_cap() {
        let l = Light::Sphere { center: Vec3::new(0.0, 3.0, 0.0), radius: 1.0, color: Vec3::ONE };
        let p = Vec3A::ZERO;
        for i in 0..64 {
            for j in 0..64 {
                let u = Vec2::new((i as f32 + 0.5) / 64.0, (j as f32 + 0.5) / 64.0);
                let s = l.sample(p, u);
                let n = (s.point - Vec3A::new(0.0, 3.0, 0.0)).normalize();
                assert!(((s.point - Vec3A::new(0.0, 3.0, 0.0)).length() - 1.0).abs() < 1e-4);
                // Visible from p: the sphere's normal there faces p.
                assert!(n.dot(-s.wi) >= -1e-3, "{:?}", s.point);
            }
        }
        // A zero-radius sphere is its centre.
        let dot = Light::Sphere { center: Vec3::Y, radius: 0.0, color: Vec3::ONE };
        assert_eq!(dot.sample(p, Vec2::new(0.3, 0.7)).point, Vec3A::Y);
    }

    #[test]
    fn segment_centre_is_midpoint_with_mean_colour() {
        let l =
            Light::Segment { endpoint0: Vec3::ZERO, endpoint1: Vec3::X * 2.0, color0: Vec3::ONE, color1: Vec3::ZERO };
        let s = l.center_sample(Vec3A::new(1.0, 1.0, 0.0));
        assert_eq!(s.point, Vec3A::X);
        assert_eq!(s.color, Vec3::splat(0.5));
        assert!((s.distance - 1.0).abs() < 1e-6);
        assert_eq!(s.wi, -Vec3A::Y);
    }
}
