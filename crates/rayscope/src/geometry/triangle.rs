//! Triangles by their exact corners, and the watertight ray-triangle test (Woop, Benthin and
//! Wald, "Watertight Ray/Triangle Intersection", JCGT 2013; pbrt-v4's `IntersectTriangle`).
//!
//! # Why watertight
//!
//! Möller–Trumbore computes each triangle's barycentrics from that triangle's own edges, so
//! two triangles sharing an edge round differently along it and a ray through the edge can
//! miss both: from inside a closed 500k-triangle sphere, 15 of 3M rays escaped. The watertight
//! test first moves the ray into a frame where it is the +z axis through the origin ([`TriRay`]:
//! a translation by the origin, a permutation of the axes and a shear, the same for every
//! triangle), so each vertex's 2D position depends on the vertex alone. The sign of the edge
//! function of a shared edge is then computed from the very same floats by both triangles, in
//! opposite order, and `a * b - c * d` rounds to exactly minus `c * d - a * b`: one triangle
//! or the other (or both, on the edge itself) accepts the ray, never neither.
//!
//! Every path of the wide trees (`bvh/wide`: the portable and AVX2 kernels, single rays,
//! packets, shadow groups) does these operations lane for lane, in the order written in
//! [`Triangle::intersect_prepared`], so all give the same bits. The shear and `t`'s sum of
//! products are fused multiply-adds (one rounding, one instruction where the code is compiled
//! for FMA: the wide trees' AVX2 and AVX-512 traversals and the shadow groups dispatched to
//! them; elsewhere `f32::mul_add` is libm's exact `fmaf`, slower, never different). The edge
//! functions are not: `round(a * b) - round(c * d)` has the exact sign or is 0 (then the
//! double-precision fallback decides), since rounding is monotonic, and it is exactly minus
//! `round(c * d) - round(a * b)`, so the two triangles of a shared edge always agree on its
//! side. A fused `a * b - round(c * d)` can get the sign wrong (when `c * d` rounds past
//! `a * b`) and the neighbour, fused the other way, wrong too: the ray would slip between.

use super::aabb::SAFE_INV_MIN;
use super::{Aabb, PrimHit};
use crate::math::Vec3A;
use crate::ray::Ray;

/// A triangle by its three corners, stored exactly as the mesh gives them: a vertex shared by
/// two triangles is the very same float in both, which the watertight test needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Vertex 0.
    pub v0: Vec3A,
    /// Vertex 1 (barycentric `u`).
    pub v1: Vec3A,
    /// Vertex 2 (barycentric `v`).
    pub v2: Vec3A,
}

/// A ray in the form the watertight test wants, computed once per ray: the axis along which
/// it goes fastest becomes z, and the shear that maps its direction onto +z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriRay {
    /// World axes that act as x, y and z: `z` is the largest `|dir|` component's, `x` and `y`
    /// the next two in cyclic order.
    pub axes: [usize; 3],
    /// The origin's components along `axes`.
    pub origin: [f32; 3],
    /// `-dir[x] * sz`: added to x per unit of z.
    pub sx: f32,
    /// `-dir[y] * sz`: added to y per unit of z.
    pub sy: f32,
    /// `1 / dir[z]`: scales z into the ray's `t`.
    pub sz: f32,
}

impl TriRay {
    /// The permutation and shear of `ray`. A zero or non-finite direction gives NaN shears,
    /// with which no triangle is hit.
    #[inline]
    pub fn new(ray: &Ray) -> TriRay {
        TriRay::set_up(ray, |_, d| 1.0 / d)
    }

    /// [`TriRay::new`] for a ray whose safe inverse direction (`safe_inv_dir(ray.dir)`) is
    /// `inv`, as the traversals have it for their box tests: the same bits, without the
    /// division. The dominant component is at least [`SAFE_INV_MIN`] in every ray but
    /// degenerate ones (a direction shorter than 2^-64), so `inv` holds its reciprocal
    /// exactly; those others divide, out of line. The division sat at the head of each ray's
    /// first triangle test, whose shear waited for it.
    #[inline(always)]
    pub fn with_inv(ray: &Ray, inv: Vec3A) -> TriRay {
        let inv: &[f32; 3] = inv.as_ref();
        TriRay::set_up(ray, |z, d| if d.abs() >= SAFE_INV_MIN { inv[z] } else { reciprocal(d) })
    }

    /// The set-up, with `sz(z, d[z])` giving `1 / d[z]` for the dominant axis `z`.
    #[inline(always)]
    fn set_up(ray: &Ray, sz: impl Fn(usize, f32) -> f32) -> TriRay {
        // The components are read from the ray where it is (arrays, not `Vec3A`s: indexing a
        // `Vec3A` by a run-time axis is a `match`, which cost 2% of a dragon render's packet
        // traversal). A copy (`to_array`, `map`) was stored as 8 + 4 bytes and read back across
        // the two stores, which store-to-load forwarding cannot serve: the dearest stall of a
        // packet ray's leaf set-up. The magnitudes are taken in a register.
        let (d, o): (&[f32; 3], &[f32; 3]) = (ray.dir.as_ref(), ray.origin.as_ref());
        let a = ray.dir.abs();
        let a = [a.x, a.y, a.z];
        // Ties go to the later axis in the order z, y, x, every path alike (it is computed here only).
        let z = if a[0] > a[1] && a[0] > a[2] {
            0
        } else if a[1] > a[2] {
            1
        } else {
            2
        };
        // x and y follow z in cyclic order.
        const AXES: [[usize; 3]; 3] = [[1, 2, 0], [2, 0, 1], [0, 1, 2]];
        let axes = AXES[z];
        // One reciprocal (pbrt-v4 has three divisions).
        let sz = sz(z, d[z]);
        TriRay { axes, origin: axes.map(|k| o[k]), sx: -d[axes[0]] * sz, sy: -d[axes[1]] * sz, sz }
    }
}

/// `1 / d`, out of line: [`TriRay::with_inv`]'s rare case.
#[cold]
#[inline(never)]
fn reciprocal(d: f32) -> f32 {
    1.0 / d
}

/// The edge functions of a triangle whose sheared 2D corners are `x`, `y` (each by vertex),
/// in double precision: what the test falls back to where one of them is exactly 0 in single
/// precision (the ray through an edge or a vertex, as far as `f32` can tell; the products of
/// two `f32` are exact in `f64`, so the sign is then right unless the point is truly on the
/// edge). Returns them rounded back to `f32`, like pbrt-v4. Cold: most rays never come here.
#[cold]
#[inline(never)]
pub fn edges_f64(x: [f32; 3], y: [f32; 3]) -> [f32; 3] {
    let (x, y) = (x.map(f64::from), y.map(f64::from));
    let e = |i: usize, j: usize| (x[i] * y[j] - y[i] * x[j]) as f32;
    [e(1, 2), e(2, 0), e(0, 1)]
}

impl Triangle {
    /// The triangle with these corners.
    #[inline]
    pub fn new(v0: Vec3A, v1: Vec3A, v2: Vec3A) -> Triangle {
        Triangle { v0, v1, v2 }
    }

    /// The three corners.
    pub fn vertices(&self) -> [Vec3A; 3] {
        [self.v0, self.v1, self.v2]
    }

    /// The bounding box; not finite (NaN) when a corner is not, so that the BVH leaves the
    /// triangle out (a box of the finite corners alone would let it in).
    pub fn bounds(&self) -> Aabb {
        if self.vertices().iter().all(|v| v.is_finite()) {
            Aabb::from_points(self.vertices())
        } else {
            Aabb { min: Vec3A::NAN, max: Vec3A::NAN }
        }
    }

    /// Whether the corners are collinear (or coincide) exactly: `(v1 - v0) x (v2 - v0)` is
    /// zero. Such a triangle is never hit (as in pbrt-v4); seen along a ray, rounding could
    /// otherwise give its edge functions a sum that is not zero. The packed blocks store it
    /// as NaN corners instead, so their kernels need not test it.
    #[inline]
    pub fn is_degenerate(&self) -> bool {
        self.normal().cmpeq(Vec3A::ZERO).all()
    }

    /// Unnormalised geometric normal `(v1 - v0) x (v2 - v0)` (its length is twice the area).
    #[inline]
    pub fn normal(&self) -> Vec3A {
        (self.v1 - self.v0).cross(self.v2 - self.v0)
    }

    /// The watertight test (see the module documentation), double-sided: a ray through a
    /// shared edge or vertex of a closed mesh hits at least one of the triangles meeting
    /// there. Degenerate (zero-area as seen along the ray) triangles and NaN inputs give no
    /// hit. Prepares the ray on each call; [`Triangle::intersect_prepared`] takes it prepared.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        if self.is_degenerate() {
            return None;
        }
        self.intersect_prepared(&TriRay::new(ray), t_min, t_max)
    }

    /// [`Triangle::intersect`] with the ray's permutation and shear computed once, for a
    /// triangle that is not degenerate ([`Triangle::is_degenerate`]). The packed kernels do
    /// these operations in this order, lane for lane.
    #[inline(always)]
    pub fn intersect_prepared(&self, r: &TriRay, t_min: f32, t_max: f32) -> Option<PrimHit> {
        let [kx, ky, kz] = r.axes;
        // Translate, permute and shear each vertex (z is scaled later, on the sum). Fused: the
        // result depends on the vertex and the ray alone, as watertightness needs.
        let sheared = |p: Vec3A| {
            let z = p[kz] - r.origin[2];
            (r.sx.mul_add(z, p[kx] - r.origin[0]), r.sy.mul_add(z, p[ky] - r.origin[1]), z)
        };
        let (x0, y0, z0) = sheared(self.v0);
        let (x1, y1, z1) = sheared(self.v1);
        let (x2, y2, z2) = sheared(self.v2);
        // Not fused (see the module documentation).
        let mut e = [x1 * y2 - y1 * x2, x2 * y0 - y2 * x0, x0 * y1 - y0 * x1];
        let (mut lo, mut hi) = (e[0].min(e[1]).min(e[2]), e[0].max(e[1]).max(e[2]));
        // An edge function of exactly 0 is the least or the greatest one, unless another is
        // negative and a third positive: mixed signs, which the exact ones keep (a non-zero
        // rounded one has the exact sign), so such a ray is rejected either way.
        if lo == 0.0 || hi == 0.0 {
            e = edges_f64([x0, x1, x2], [y0, y1, y2]);
            (lo, hi) = (e[0].min(e[1]).min(e[2]), e[0].max(e[1]).max(e[2]));
        }
        let [e0, e1, e2] = e;
        // Mixed signs: the ray passes outside one edge. Zero counts as either side (inclusive).
        // (A NaN edge function makes `det` NaN, rejected below, whatever these say.)
        if !(lo >= 0.0 || hi <= 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        // Zero: degenerate as seen along the ray; not finite: overflow or NaN.
        if !(det.abs() > 0.0 && det.abs() < f32::INFINITY) {
            return None;
        }
        // z is scaled once, on the sum, where pbrt-v4 scales each vertex's: two products fewer.
        let t_scaled = e2.mul_add(z2, e1.mul_add(z1, e0 * z0)) * r.sz;
        // `t` itself is compared, not `t_scaled` with `t_max * det` as in pbrt-v4: the rounded
        // quotient could otherwise land just past `t_max`. The packed kernels divide anyway.
        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        (t >= t_min && t <= t_max).then_some(PrimHit { t, u: e1 * inv_det, v: e2 * inv_det })
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::RngExt;
    use proptest::test_runner::{RngAlgorithm, TestRng};

    use super::*;

    fn tri() -> Triangle {
        Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)
    }

    fn ray_down(x: f32, y: f32) -> Ray {
        Ray::new(Vec3A::new(x, y, 1.0), -Vec3A::Z)
    }

    #[test]
    fn hits_interior_with_barycentrics() {
        let h = tri().intersect(&ray_down(0.25, 0.5), 0.0, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.u - 0.25).abs() < 1e-6 && (h.v - 0.5).abs() < 1e-6);
    }

    #[test]
    fn edges_and_vertices_are_hit() {
        for (x, y) in [(0.5, 0.0), (0.0, 0.5), (0.5, 0.5), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
            assert!(tri().intersect(&ray_down(x, y), 0.0, f32::INFINITY).is_some(), "({x},{y})");
        }
    }

    #[test]
    fn misses_outside_and_behind() {
        assert!(tri().intersect(&ray_down(0.6, 0.6), 0.0, f32::INFINITY).is_none());
        assert!(tri().intersect(&ray_down(-0.01, 0.5), 0.0, f32::INFINITY).is_none());
        let behind = Ray::new(Vec3A::new(0.2, 0.2, -1.0), -Vec3A::Z);
        assert!(tri().intersect(&behind, 0.0, f32::INFINITY).is_none());
        assert!(tri().intersect(&ray_down(0.2, 0.2), 0.0, 0.5).is_none(), "beyond t_max");
    }

    #[test]
    fn back_side_is_hit() {
        let up = Ray::new(Vec3A::new(0.2, 0.2, -1.0), Vec3A::Z);
        assert!(tri().intersect(&up, 0.0, f32::INFINITY).is_some());
    }

    /// Uniform in `[lo, hi)` per axis.
    fn point(rng: &mut TestRng, lo: f32, hi: f32) -> Vec3A {
        Vec3A::new(rng.random_range(lo..hi), rng.random_range(lo..hi), rng.random_range(lo..hi))
    }

    /// Rays from random origins aimed at `target` each hit at least one of `tris`.
    fn never_none(tris: &[Triangle], target: impl Fn(&mut TestRng) -> Vec3A, what: &str) {
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        for _ in 0..20_000 {
            let origin = point(&mut rng, -3.0, 3.0);
            let ray = Ray::new(origin, (target(&mut rng) - origin).normalize());
            let hits = tris.iter().filter(|t| t.intersect(&ray, 0.0, f32::INFINITY).is_some()).count();
            assert!(hits >= 1, "{what}: {ray:?} went through");
        }
    }

    #[test]
    fn rays_through_a_shared_edge_hit_one_or_both() {
        // Two triangles sharing the edge from a to b, in either order, in a tilted plane (origins
        // off the plane see them on either side of the edge: no silhouette to slip past).
        let (a, b) = (Vec3A::new(1.0, 0.0, 0.3), Vec3A::new(0.0, 1.0, -0.2));
        let tris = [Triangle::new(Vec3A::ZERO, a, b), Triangle::new(b, a, a + b)];
        never_none(&tris, |rng| a.lerp(b, rng.random_range(0.0..1.0)), "edge");
    }

    #[test]
    fn rays_through_a_shared_vertex_hit_a_triangle_of_its_fan() {
        // Seven triangles around c, wound either way, in a tilted plane.
        let c = Vec3A::new(0.1, 0.2, 0.05);
        let (du, dv) = (Vec3A::new(1.0, 0.1, 0.3), Vec3A::new(-0.2, 1.0, 0.4));
        let ring: Vec<Vec3A> = (0..7)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / 7.0;
                c + a.cos() * du + a.sin() * dv
            })
            .collect();
        let tris: Vec<Triangle> = (0..7)
            .map(|i| {
                if i % 2 == 0 {
                    Triangle::new(c, ring[i], ring[(i + 1) % 7])
                } else {
                    Triangle::new(ring[(i + 1) % 7], ring[i], c)
                }
            })
            .collect();
        never_none(&tris, |_| c, "vertex");
    }

    #[test]
    fn degenerate_triangles_and_nan_never_hit() {
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        let p = Vec3A::new(0.3, 0.2, 0.1);
        let flat = [
            Triangle::new(p, p, p),
            Triangle::new(Vec3A::ZERO, Vec3A::X, 2.0 * Vec3A::X),
            Triangle::new(p, p, Vec3A::Y),
            Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::X),
        ];
        for _ in 0..20_000 {
            let origin = point(&mut rng, -2.0, 2.0);
            // Aimed at a corner or a point of an edge, where the edge functions are 0.
            let target = [Vec3A::ZERO, p, Vec3A::X * rng.random_range(0.0..2.0), Vec3A::Y][rng.random_range(0..4usize)];
            let ray = Ray::new(origin, (target - origin).normalize());
            for t in &flat {
                assert!(t.intersect(&ray, f32::MIN, f32::MAX).is_none(), "{t:?} hit by {ray:?}");
            }
        }
        let t = tri();
        let nan = f32::NAN;
        assert!(t.intersect(&ray_down(0.2, 0.2), nan, f32::INFINITY).is_none());
        assert!(t.intersect(&ray_down(0.2, 0.2), 0.0, nan).is_none());
        assert!(t.intersect(&Ray::new(Vec3A::new(0.2, nan, 1.0), -Vec3A::Z), 0.0, f32::INFINITY).is_none());
        assert!(t.intersect(&Ray::new(Vec3A::new(0.2, 0.2, 1.0), Vec3A::new(nan, 0.0, -1.0)), 0.0, 9.0).is_none());
        assert!(t.intersect(&Ray::new(Vec3A::new(0.2, 0.2, 1.0), Vec3A::ZERO), 0.0, 9.0).is_none());
        for corner in 0..3 {
            let mut v = t.vertices();
            v[corner].y = nan;
            assert!(Triangle::new(v[0], v[1], v[2]).intersect(&ray_down(0.2, 0.2), 0.0, 9.0).is_none());
        }
    }

    #[test]
    fn hits_stay_within_the_interval() {
        let t = Triangle::new(Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(1.0, 0.0, 0.5), Vec3A::new(0.0, 1.0, 0.25));
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        for _ in 0..1000 {
            let (u, v) = (rng.random_range(0.0..0.5), rng.random_range(0.0..0.5));
            let target = t.v0 + u * (t.v1 - t.v0) + v * (t.v2 - t.v0);
            let origin = point(&mut rng, -3.0, 3.0);
            let ray = Ray::new(origin, (target - origin).normalize());
            let h = t.intersect(&ray, 0.0, f32::INFINITY).unwrap();
            assert!((h.u - u).abs() < 1e-4 && (h.v - v).abs() < 1e-4, "{h:?} for {u}, {v}");
            // With the interval ending exactly at the hit, or one float before or after it.
            assert_eq!(t.intersect(&ray, 0.0, h.t).map(|g| g.t), Some(h.t));
            assert_eq!(t.intersect(&ray, h.t, h.t).map(|g| g.t), Some(h.t));
            assert!(t.intersect(&ray, 0.0, h.t.next_down()).is_none());
            assert!(t.intersect(&ray, h.t.next_up(), f32::INFINITY).is_none());
        }
    }

    /// [`TriRay::with_inv`] is [`TriRay::new`] bit for bit: unit directions of every dominant
    /// axis, ties, and components at and around 2^-64, zero, infinite and NaN.
    #[test]
    fn set_up_from_the_inverse_direction_is_the_divisions() {
        use crate::geometry::aabb::safe_inv_dir;
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        let special = [
            0.0,
            -0.0,
            SAFE_INV_MIN,
            -SAFE_INV_MIN,
            SAFE_INV_MIN.next_down(),
            1e-30,
            0.5,
            -0.5,
            f32::INFINITY,
            f32::NAN,
        ];
        let component = |rng: &mut TestRng| {
            if rng.random::<bool>() {
                special[rng.random_range(0..special.len())]
            } else {
                rng.random_range(-1.0..1.0f32)
            }
        };
        for _ in 0..50_000 {
            let mut d = Vec3A::new(component(&mut rng), component(&mut rng), component(&mut rng));
            if rng.random::<bool>() {
                d *= SAFE_INV_MIN;
            }
            let ray = Ray::new(Vec3A::new(0.3, -2.0, 5.0), d);
            let bits = |t: TriRay| (t.axes, t.origin.map(f32::to_bits), [t.sx, t.sy, t.sz].map(f32::to_bits));
            assert_eq!(bits(TriRay::with_inv(&ray, safe_inv_dir(d))), bits(TriRay::new(&ray)), "{d:?}");
        }
    }

    #[test]
    fn grazing_and_degenerate_rays_miss() {
        // In the triangle's plane: parallel, no unique hit.
        let graze = Ray::new(Vec3A::new(-1.0, 0.2, 0.0), Vec3A::X);
        assert!(tri().intersect(&graze, 0.0, f32::INFINITY).is_none());
        let zero_area = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::X * 2.0);
        assert!(zero_area.intersect(&ray_down(0.5, 0.0), 0.0, f32::INFINITY).is_none());
        let nan = Triangle::new(Vec3A::splat(f32::NAN), Vec3A::X, Vec3A::Y);
        assert!(nan.intersect(&ray_down(0.2, 0.2), 0.0, f32::INFINITY).is_none());
        let nan_ray = Ray::new(Vec3A::splat(f32::NAN), -Vec3A::Z);
        assert!(tri().intersect(&nan_ray, 0.0, f32::INFINITY).is_none());
    }
}
