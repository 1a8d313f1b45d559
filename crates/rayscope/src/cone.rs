//! Ray cones, the footprint that trilinear texture filtering chooses its mip level by
//! (Akenine-Möller et al., "Texture Level of Detail Strategies for Real-Time Ray Tracing", Ray
//! Tracing Gems, ch. 20, and "Improved Shader and Texture Level of Detail Using Ray Cones",
//! 2021). Each ray carries a cone: its width where the ray starts and the angle it spreads
//! by. A camera ray's cone starts at the pinhole with width 0 and spreads by the angle of
//! one pixel; at a hit the width has grown by `spread * t`. A mirror reflection leaves with
//! that width and the spread widened by the surface's curvature (`2 k w`, the angle a mirror
//! of curvature `k` adds across a beam of width `w`: 0 for a flat triangle, so a reflection
//! in a plane mirror keeps growing as if the path were straight); a transmitted ray (which
//! goes straight through) keeps the cone.
//!
//! The integrator is generic over [`Footprint`], chosen once per render: [`NoCone`] (every
//! filter but trilinear) is zero-sized and its operations vanish, so the default render
//! carries nothing; [`RayCone`] does the bookkeeping.

/// What rays carry of their footprint: nothing ([`NoCone`]) or a cone ([`RayCone`]).
pub trait Footprint: Copy + Sync {
    /// Whether rays carry a cone (texture lookups then choose a mip level).
    const CONES: bool;
    /// The cone at a hit `t` along the ray, on a surface of curvature `curvature()` (read only
    /// when cones are carried).
    fn arrive(self, t: f32, curvature: impl FnOnce() -> f32) -> Self;
    /// The cone of the ray reflected at the hit this cone [`Footprint::arrive`]d at.
    fn reflected(self) -> Self;
    /// The cone of a ray that continues straight through the hit (transmission).
    fn transmitted(self) -> Self;
    /// Its width (0 without a cone).
    fn width(self) -> f32;
}

/// No footprint: rays carry nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NoCone;

impl Footprint for NoCone {
    const CONES: bool = false;
    #[inline(always)]
    fn arrive(self, _t: f32, _curvature: impl FnOnce() -> f32) -> Self {
        self
    }
    #[inline(always)]
    fn reflected(self) -> Self {
        self
    }
    #[inline(always)]
    fn transmitted(self) -> Self {
        self
    }
    #[inline(always)]
    fn width(self) -> f32 {
        0.0
    }
}

/// A ray cone: its width (diameter) and the angle it spreads by, in radians (positive:
/// widening). At a hit it also holds the surface's curvature, which a reflection turns into
/// spread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayCone {
    /// Width where the ray starts (at a hit: there), in scene units.
    pub width: f32,
    /// Spread angle in radians: the width grows by `spread` per unit of distance.
    pub spread: f32,
    /// Curvature (1 / radius) of the surface at the hit it arrived at; 0 elsewhere.
    pub curvature: f32,
}

impl RayCone {
    /// A pinhole camera's cone for an image `height` pixels tall with vertical field of view
    /// `2 atan(tan_half_fov)`: width 0, spread by the angle one pixel subtends at the centre.
    pub fn camera(tan_half_fov: f32, height: u32) -> RayCone {
        RayCone { width: 0.0, spread: (2.0 * tan_half_fov / height.max(1) as f32).atan(), curvature: 0.0 }
    }
}

impl Footprint for RayCone {
    const CONES: bool = true;
    #[inline]
    fn arrive(self, t: f32, curvature: impl FnOnce() -> f32) -> Self {
        RayCone { width: self.width + self.spread * t, spread: self.spread, curvature: curvature() }
    }
    #[inline]
    fn reflected(self) -> Self {
        RayCone { width: self.width, spread: self.spread + 2.0 * self.curvature * self.width, curvature: 0.0 }
    }
    #[inline]
    fn transmitted(self) -> Self {
        RayCone { curvature: 0.0, ..self }
    }
    #[inline]
    fn width(self) -> f32 {
        self.width
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cone_grows_with_distance_and_a_plane_mirror_continues_it() {
        let c = RayCone::camera(1.0, 2);
        assert!((c.spread - std::f32::consts::FRAC_PI_4).abs() < 1e-6);
        let at = c.arrive(2.0, || 0.0);
        assert_eq!(at.width, 2.0 * c.spread);
        // Off a flat mirror, 3 further: as wide as a straight path of 5.
        let far = at.reflected().arrive(3.0, || 0.0);
        assert!((far.width - c.arrive(5.0, || 0.0).width).abs() < 1e-6);
        // A convex mirror spreads the reflected cone more.
        let curved = at.arrive(0.0, || 1.0).reflected().arrive(3.0, || 0.0);
        assert!(curved.width > far.width);
        assert_eq!(at.transmitted().arrive(3.0, || 0.0), far);
    }
}
