//! Axis-aligned bounding boxes.

use crate::math::Vec3A;

/// An axis-aligned box. The empty box has `min = +inf`, `max = -inf`, so growing it by any
/// point gives that point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3A,
    /// Upper corner.
    pub max: Vec3A,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The box containing nothing.
    pub const EMPTY: Aabb = Aabb { min: Vec3A::splat(f32::INFINITY), max: Vec3A::splat(f32::NEG_INFINITY) };

    /// The smallest box containing all `points`.
    pub fn from_points(points: impl IntoIterator<Item = Vec3A>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.grow(p))
    }

    /// This box grown to contain `p`.
    #[inline]
    pub fn grow(self, p: Vec3A) -> Aabb {
        Aabb { min: self.min.min(p), max: self.max.max(p) }
    }

    /// The smallest box containing both.
    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    /// Whether the box contains no point.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// Whether both corners are finite numbers.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.min.is_finite() && self.max.is_finite()
    }

    /// Edge lengths (zero for the empty box).
    #[inline]
    pub fn extent(&self) -> Vec3A {
        (self.max - self.min).max(Vec3A::ZERO)
    }

    /// The centre point.
    #[inline]
    pub fn center(&self) -> Vec3A {
        0.5 * (self.min + self.max)
    }

    /// Half the surface area: the SAH only needs ratios, so the factor 2 is left out.
    #[inline]
    pub fn half_area(&self) -> f32 {
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// Whether `o` lies inside this box (borders included).
    #[inline]
    pub fn contains(&self, o: &Aabb) -> bool {
        o.is_empty() || (self.min.cmple(o.min).all() && self.max.cmpge(o.max).all())
    }

    /// Entry distance of the ray `origin + t * dir` into the box if it meets it within
    /// `[t_min, t_max]`, else `f32::INFINITY`. `inv_dir` must come from [`safe_inv_dir`].
    /// Conservative, as pbrt-v4's box test: each distance `(p - o) * inv` is within three
    /// roundings of exact, so the exit distance is scaled by [`SLAB_SLACK`] and a ray through
    /// the box's edge or corner (through a mesh vertex, say) is never culled.
    #[inline(always)]
    pub fn hit_distance(&self, origin: Vec3A, inv_dir: Vec3A, t_min: f32, t_max: f32) -> f32 {
        let t0 = (self.min - origin) * inv_dir;
        let t1 = (self.max - origin) * inv_dir;
        let near = t0.min(t1).max_element().max(t_min);
        let far = (t0.max(t1).min_element() * SLAB_SLACK).min(t_max);
        if near <= far { near } else { f32::INFINITY }
    }
}

/// `1 + 2 gamma(3)` (pbrt's `gamma(n) = n u / (1 - n u)`, `u = 2^-24`): what
/// [`Aabb::hit_distance`] scales exit distances by, so that rounding never culls a box the
/// ray meets.
pub const SLAB_SLACK: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON / 2.0) / (1.0 - 3.0 * f32::EPSILON / 2.0);

/// The least direction component whose reciprocal [`safe_inv_dir`] keeps: 2^-64. Smaller
/// ones (zero among them) are replaced by it, with their sign.
pub const SAFE_INV_MIN: f32 = 1.0 / 18_446_744_073_709_551_616.0;

/// The reciprocal of a ray direction for slab tests, with components smaller than 2^-64
/// ([`SAFE_INV_MIN`], zero among them) replaced by 2^-64 of the same sign: every other
/// component's is exactly `1 / d` (the triangle test's set-up reuses it,
/// [`crate::geometry::TriRay::with_inv`]). A plain `1 / 0 = inf` would make `0 * inf = NaN`
/// for a ray that starts on a slab plane, and SIMD min/max do not ignore NaN: the box would
/// be missed. The replacement's inverse, 2^64, is a power of two, so the wide
/// BVHs' fused slab test (`p * inv - o * inv`) computes `o * inv` exactly for such axes, and
/// is small enough that `o * inv` cannot overflow for any origin within 10^19 of zero.
#[inline(always)]
pub fn safe_inv_dir(dir: Vec3A) -> Vec3A {
    let mag = dir.abs().max(Vec3A::splat(SAFE_INV_MIN));
    Vec3A::ONE / Vec3A::select(dir.cmplt(Vec3A::ZERO), -mag, mag)
}
