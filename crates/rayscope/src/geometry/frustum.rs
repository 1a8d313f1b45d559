//! A frustum: every ray from one point (the apex) whose direction lies in a rectangle of a
//! plane in front of it, as the camera rays of a tile of pixels do. It answers one question,
//! conservatively: may a box hold a point of it? "No" proves that no ray of the frustum meets
//! anything inside the box, which lets a tile of camera rays that misses every box of the BVH
//! skip its traversal (Reshetov, Soupikov and Hurley, "Multi-level ray tracing algorithm",
//! 2005; Benthin and Wald's frustum culling of ray packets).

use wide::f32x8;

use crate::geometry::Aabb;
use crate::math::Vec3A;

/// The rays from `apex` through the rectangle of directions `x * right + y * up + forward`,
/// `x` and `y` in given intervals: four planes through the apex, each keeping the side the
/// rectangle is on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// The common origin of the rays.
    apex: Vec3A,
    /// The side planes' normals, pointing inwards (a point `p` is inside a plane where
    /// `dot(normal, p - apex) >= 0`): left, right, bottom, top.
    normals: [Vec3A; 4],
}

/// The rectangle of directions a [`Frustum`] spans: `x * right + y * up + forward` for `x` in
/// `x`, `y` in `y` (intervals `[lo, hi]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionRect {
    /// The direction of `x = 1` minus `forward`.
    pub right: Vec3A,
    /// The direction of `y = 1` minus `forward`.
    pub up: Vec3A,
    /// The direction of `x = y = 0`.
    pub forward: Vec3A,
    /// The interval of `x`.
    pub x: [f32; 2],
    /// The interval of `y`.
    pub y: [f32; 2],
}

impl Frustum {
    /// The frustum of the rays from `apex` through `rect`. Each side plane holds the apex and
    /// one edge of the rectangle (its normal a cross product of the edge's direction and the
    /// corner direction it passes through, so `right`, `up` and `forward` need not be
    /// orthogonal), and is turned to face the rectangle's centre.
    pub fn new(apex: Vec3A, rect: &DirectionRect) -> Frustum {
        let DirectionRect { right, up, forward, x, y } = *rect;
        let centre = 0.5 * (x[0] + x[1]) * right + 0.5 * (y[0] + y[1]) * up + forward;
        let facing = |n: Vec3A| if n.dot(centre) < 0.0 { -n } else { n };
        let normals = [
            facing((x[0] * right + forward).cross(up)),
            facing((x[1] * right + forward).cross(up)),
            facing((y[0] * up + forward).cross(right)),
            facing((y[1] * up + forward).cross(right)),
        ];
        Frustum { apex, normals }
    }

    /// Whether `b` may hold a point of the frustum: false only when the whole box lies
    /// outside one of the side planes (its corner farthest along the plane's normal is
    /// behind it) by more than the rounding of the test. Conservative (a box beside the
    /// frustum near a corner of it passes), and a NaN, or an infinity on the side the far
    /// corner takes, keeps the box. The caller's margin covers the rounding of the rays'
    /// directions.
    #[inline]
    pub fn may_meet(&self, b: &Aabb) -> bool {
        let lo = b.min - self.apex;
        let hi = b.max - self.apex;
        // `b - apex` is rounded to 2^-24 of the larger magnitude: far from the world's origin
        // that error can exceed the caller's angular margin at a short distance, so a plane
        // keeps a box behind it by up to 2^-20 of the coordinates' scale.
        let scale = self.apex.abs().max(b.min.abs()).max(b.max.abs()).max_element() * (1.0 / 1_048_576.0);
        self.normals.iter().all(|&n| {
            let far = Vec3A::select(n.cmpge(Vec3A::ZERO), hi, lo);
            // Kept unless surely behind: a NaN (of the box, or of an infinite scale times a
            // zero normal) keeps it.
            let behind = n.dot(far) < -scale * n.abs().element_sum();
            !behind
        })
    }
}

impl Frustum {
    /// [`Frustum::may_meet`] for eight boxes at once, given as their corners' coordinates
    /// (`min[axis]`, `max[axis]`, a box per lane): the mask of the boxes it keeps. The same
    /// operations in the same order on each lane (glam's `dot`, `element_sum` and
    /// `max_element` included, NaN handling and all), so the same answers; the BVH's frustum
    /// walk tests a node's children this way rather than one box at a time.
    #[inline]
    pub fn may_meet_lanes(&self, min: [f32x8; 3], max: [f32x8; 3]) -> u32 {
        let apex = [self.apex.x, self.apex.y, self.apex.z].map(f32x8::splat);
        let lo: [f32x8; 3] = std::array::from_fn(|a| min[a] - apex[a]);
        let hi: [f32x8; 3] = std::array::from_fn(|a| max[a] - apex[a]);
        // `apex.abs().max(min.abs()).max(max.abs()).max_element()`: `max` is `maxps(a, b)`
        // (the second operand where either is NaN), the element fold `max(max(x, z), max(y, z))`.
        let s: [f32x8; 3] = std::array::from_fn(|a| apex[a].abs().fast_max(min[a].abs()).fast_max(max[a].abs()));
        let scale = s[0].fast_max(s[2]).fast_max(s[1].fast_max(s[2])) * f32x8::splat(1.0 / 1_048_576.0);
        let mut keep = 0xff;
        for n in &self.normals {
            let pick = |a: usize| if n[a] >= 0.0 { hi[a] } else { lo[a] };
            // `n.dot(far)`: `(x x' + y y') + z z'`, products rounded apart (no fused add).
            let dot = (f32x8::splat(n.x) * pick(0) + f32x8::splat(n.y) * pick(1)) + f32x8::splat(n.z) * pick(2);
            let behind = dot.simd_lt(-scale * f32x8::splat(n.abs().element_sum()));
            keep &= !behind.to_bitmask() & 0xff;
        }
        keep
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn rect(x: [f32; 2], y: [f32; 2]) -> DirectionRect {
        DirectionRect { right: Vec3A::X, up: Vec3A::Y, forward: -Vec3A::Z, x, y }
    }

    #[test]
    fn boxes_inside_beside_and_behind() {
        let f = Frustum::new(Vec3A::ZERO, &rect([-0.1, 0.1], [-0.1, 0.1]));
        let cube = |c: Vec3A, r: f32| Aabb { min: c - Vec3A::splat(r), max: c + Vec3A::splat(r) };
        assert!(f.may_meet(&cube(Vec3A::new(0.0, 0.0, -5.0), 0.1)));
        // Straddling one side plane.
        assert!(f.may_meet(&cube(Vec3A::new(0.55, 0.0, -5.0), 0.1)));
        assert!(!f.may_meet(&cube(Vec3A::new(0.7, 0.0, -5.0), 0.1)));
        assert!(!f.may_meet(&cube(Vec3A::new(0.0, -0.7, -5.0), 0.1)));
        // Behind the apex, on the frustum's axis.
        assert!(!f.may_meet(&cube(Vec3A::new(0.0, 0.0, 5.0), 0.1)));
        // Around the apex.
        assert!(f.may_meet(&cube(Vec3A::ZERO, 0.01)));
        // Far from the world's origin (where a float's step is 1/16), a box that touches a
        // side plane a little beyond, as rounded, is kept; one well outside is not.
        let far = Frustum::new(Vec3A::new(1.0e6, 1.0e6, 0.0), &rect([-0.1, 0.1], [-0.1, 0.1]));
        let x = |dx: f32| 1.0e6 + dx;
        let touching = Aabb { min: Vec3A::new(x(0.53), 1.0e6 - 0.1, -5.1), max: Vec3A::new(x(0.6), 1.0e6, -4.9) };
        assert!(far.may_meet(&touching));
        let outside = Aabb { min: Vec3A::new(x(3.0), 1.0e6 - 0.1, -5.1), max: Vec3A::new(x(3.5), 1.0e6, -4.9) };
        assert!(!far.may_meet(&outside));
        // NaN and infinite boxes are kept.
        assert!(f.may_meet(&Aabb { min: Vec3A::splat(f32::NAN), max: Vec3A::splat(f32::NAN) }));
        assert!(f.may_meet(&Aabb { min: Vec3A::splat(-f32::INFINITY), max: Vec3A::splat(f32::INFINITY) }));
    }

    proptest! {
        /// Eight boxes at once get the answers each gets alone: random boxes near and far
        /// from random frustums, some with NaN or infinite corners.
        #[test]
        fn eight_boxes_at_once_as_one_at_a_time(
            apex in prop::array::uniform3(-10.0f32..10.0),
            x in prop::array::uniform2(-0.5f32..0.5),
            y in prop::array::uniform2(-0.5f32..0.5),
            boxes in prop::collection::vec(
                (prop::array::uniform3(-20.0f32..20.0), prop::array::uniform3(0.0f32..3.0), prop::array::uniform2(0usize..12)),
                8,
            ),
        ) {
            let f = Frustum::new(Vec3A::from_array(apex), &rect([x[0].min(x[1]), x[0].max(x[1])], [y[0].min(y[1]), y[0].max(y[1])]));
            // Now and then one coordinate of one corner NaN or infinite.
            let odd = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
            let boxes: Vec<Aabb> = boxes
                .iter()
                .map(|(c, r, k)| {
                    let c = Vec3A::from_array(*c);
                    let mut b = Aabb { min: c - Vec3A::from_array(*r), max: c + Vec3A::from_array(*r) };
                    if k[0] < 6 {
                        let corner = if k[0] < 3 { &mut b.min } else { &mut b.max };
                        corner[k[0] % 3] = odd[k[1] % 3];
                    }
                    b
                })
                .collect();
            let lanes = |get: fn(&Aabb) -> Vec3A, a: usize| f32x8::new(std::array::from_fn(|i| get(&boxes[i])[a]));
            let min = [0, 1, 2].map(|a| lanes(|b| b.min, a));
            let max = [0, 1, 2].map(|a| lanes(|b| b.max, a));
            let one_by_one = (0..8).filter(|&i| f.may_meet(&boxes[i])).fold(0, |m, i| m | 1 << i);
            prop_assert_eq!(f.may_meet_lanes(min, max), one_by_one);
        }

        /// A box that a ray of the frustum meets is never culled: rays through random points
        /// of the rectangle (a skewed basis among them) against boxes around a point of the
        /// ray, degenerate (flat or point) boxes among them.
        #[test]
        fn a_box_on_a_ray_of_the_frustum_is_kept(
            apex in prop::array::uniform3(-10.0f32..10.0),
            skew in prop::array::uniform3(-0.5f32..0.5),
            x0 in -2.0f32..2.0,
            y0 in -2.0f32..2.0,
            size in prop::array::uniform2(0.01f32..2.0),
            s in prop::array::uniform2(0.01f32..=0.99),
            t in 1.0f32..100.0,
            r in prop::array::uniform3(0.0f32..1.0),
            offset in prop::array::uniform3(-1.0f32..=1.0),
        ) {
            // Rays strictly inside (the renderer widens its frustums by a pixel for rounding).
            let (x, y) = ([x0, x0 + size[0]], [y0, y0 + size[1]]);
            let rect = DirectionRect {
                right: Vec3A::new(1.0, skew[0], 0.0),
                up: Vec3A::new(skew[1], 1.0, skew[2]),
                forward: -Vec3A::Z,
                x,
                y,
            };
            let apex = Vec3A::from(apex);
            let f = Frustum::new(apex, &rect);
            let (px, py) = (x[0] + s[0] * (x[1] - x[0]), y[0] + s[1] * (y[1] - y[0]));
            let p = apex + t * (px * rect.right + py * rect.up + rect.forward);
            // A box holding `p` (anywhere in it).
            let r = Vec3A::from(r);
            let c = p + r * Vec3A::from(offset);
            let b = Aabb { min: c - r, max: c + r };
            prop_assume!(b.min.cmple(p).all() && p.cmple(b.max).all());
            prop_assert!(f.may_meet(&b), "{b:?} holds {p:?}");
        }
    }
}
