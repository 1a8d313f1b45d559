//! Lights in the course's colour model. Each light can name a point on itself with its colour
//! there ([`Light::point_at`]); shading asks for [`LightSample`]s from a shading point.

use serde::{Deserialize, Serialize};

use crate::math::{Color, Vec2, Vec3, Vec3A};

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

impl Light {
    /// The point at parameters `u` in `[0,1]^2` and the light's colour there: the position of
    /// a point light; `lerp(endpoint0, endpoint1, u.x)` on a segment; `v0 + u.x edge01 + u.y
    /// edge02` on a parallelogram; the centre of a sphere.
    pub fn point_at(&self, u: Vec2) -> (Vec3A, Color) {
        match *self {
            Light::Point { position, color } => (position.into(), color),
            Light::Segment {
                endpoint0,
                endpoint1,
                color0,
                color1,
            } => (endpoint0.lerp(endpoint1, u.x).into(), color0.lerp(color1, u.x)),
            Light::Parallelogram {
                v0,
                edge01,
                edge02,
                color0,
                color1,
                color2,
                color3,
            } => {
                let c = color0.lerp(color1, u.x).lerp(color2.lerp(color3, u.x), u.y);
                ((v0 + u.x * edge01 + u.y * edge02).into(), c)
            }
            Light::Sphere { center, color, .. } => (center.into(), color),
        }
    }

    /// The light shaded as a point light at its centre (with its mean colour there), from
    /// shading point `p`: hard shadows from every kind of light.
    pub fn center_sample(&self, p: Vec3A) -> LightSample {
        let (point, color) = self.point_at(Vec2::splat(0.5));
        let to = point - p;
        let distance = to.length();
        LightSample {
            point,
            wi: to / distance,
            distance,
            color,
            pdf: 1.0,
        }
    }

    /// A representative position (the centre), for drawing and for distance heuristics.
    pub fn center(&self) -> Vec3A {
        self.point_at(Vec2::splat(0.5)).0
    }

    /// Whether every number in the light is finite and its radius (if any) non-negative.
    pub fn is_valid(&self) -> bool {
        let v = |x: &Vec3| x.is_finite();
        match self {
            Light::Point { position, color } => v(position) && v(color),
            Light::Segment {
                endpoint0,
                endpoint1,
                color0,
                color1,
            } => [endpoint0, endpoint1, color0, color1].into_iter().all(v),
            Light::Parallelogram {
                v0,
                edge01,
                edge02,
                color0,
                color1,
                color2,
                color3,
            } => [v0, edge01, edge02, color0, color1, color2, color3].into_iter().all(v),
            Light::Sphere { center, radius, color } => v(center) && v(color) && radius.is_finite() && *radius >= 0.0,
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
    fn segment_centre_is_midpoint_with_mean_colour() {
        let l = Light::Segment {
            endpoint0: Vec3::ZERO,
            endpoint1: Vec3::X * 2.0,
            color0: Vec3::ONE,
            color1: Vec3::ZERO,
        };
        let s = l.center_sample(Vec3A::new(1.0, 1.0, 0.0));
        assert_eq!(s.point, Vec3A::X);
        assert_eq!(s.color, Vec3::splat(0.5));
        assert!((s.distance - 1.0).abs() < 1e-6);
        assert_eq!(s.wi, -Vec3A::Y);
    }
}
