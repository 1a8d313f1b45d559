//! Motion along paths: a translation keyframed over the shutter interval, a clean function of
//! time ([`MotionPath::at`]) for motion blur, the BVH's bounds and frames of an animation.
//!
//! A path is a list of [`Keyframe`]s, `(time, translation)`, with times in seconds of scene
//! time (finite, strictly increasing; a still image exposes `[0, 1]`, an animation's frames
//! their own spans: [`crate::animation`]), and an [`Interpolation`] between them. Before the
//! first key and after the last the translation holds at that key's.
//!
//! **Catmull-Rom** here is the spline through the keys parametrised by their *times*: each
//! segment `[t_i, t_i+1]` is the cubic Hermite curve between its keys whose derivatives (the
//! velocities) at the keys are the finite differences
//! `m_i = (p_i+1 - p_i-1) / (t_i+1 - t_i-1)`, and at the end keys the one-sided
//! `m_0 = (p_1 - p_0) / (t_1 - t_0)` and `m_n = (p_n - p_n-1) / (t_n - t_n-1)`. With keys
//! evenly spaced in time this is exactly the uniform Catmull-Rom spline; with uneven times the
//! velocity stays continuous across keys, which the uniform spline (parametrised by key
//! index) would not give, and the centripetal one (parametrised by distance) would not follow
//! the keys' times at all: for motion, the parameter must be time. With two keys both
//! interpolations are the same straight segment, and it is evaluated as the linear motion
//! (`p_0.lerp(p_1, u)`), so two keys at times 0 and 1 give today's linear motion bit for bit.
//!
//! Catmull-Rom leaves the hull of its keys (it overshoots around sharp turns), so
//! [`MotionPath::bounds`] is the box of each segment's cubic over its extremes per axis: the
//! segment's ends and the roots of its derivative in the segment, not the keys' box.

use serde::{Deserialize, Serialize};

use crate::animation::Shutter;
use crate::geometry::Aabb;
use crate::math::{Vec3, Vec3A};

/// How a path goes between its keys.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// Straight segments at constant speed between keys.
    Linear,
    /// The Catmull-Rom spline through the keys, parametrised by their times (see the module).
    #[default]
    CatmullRom,
}

impl Interpolation {
    /// Both kinds, in the order a user picks them from.
    pub const ALL: [Interpolation; 2] = [Interpolation::Linear, Interpolation::CatmullRom];

    /// The name scene files use.
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Linear => "linear",
            Interpolation::CatmullRom => "catmull-rom",
        }
    }
}

/// A key of a path: the translation at a scene time. Written `[t, [x, y, z]]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "(f32, Vec3)", into = "(f32, Vec3)")]
pub struct Keyframe {
    /// Scene time in seconds (a still image exposes `[0, 1]`).
    pub time: f32,
    /// Translation at that time.
    pub translation: Vec3,
}

impl From<(f32, Vec3)> for Keyframe {
    fn from((time, translation): (f32, Vec3)) -> Keyframe {
        Keyframe { time, translation }
    }
}

impl From<Keyframe> for (f32, Vec3) {
    fn from(k: Keyframe) -> (f32, Vec3) {
        (k.time, k.translation)
    }
}

/// A translation over the shutter interval through keyframes (see the module). Made only by
/// [`MotionPath::new`], which checks its keys.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionPath {
    keys: Vec<Keyframe>,
    interpolation: Interpolation,
    /// One per pair of neighbouring keys.
    segments: Vec<Segment>,
    /// Every key is the same translation: [`MotionPath::at`] is exactly that, at any time
    /// (interpolating between equal values would round).
    still: bool,
}

/// One segment `[t0, t0 + h]` as a cubic in `u = (t - t0) / h`:
/// `p(u) = ((a u + b) u + c) u + d` (Catmull-Rom), or `d.lerp(e, u)` (linear).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Segment {
    t0: f32,
    h: f32,
    a: Vec3A,
    b: Vec3A,
    c: Vec3A,
    /// The translation at the segment's start.
    d: Vec3A,
    /// The translation at its end.
    e: Vec3A,
    /// Whether it is evaluated as a cubic (else as `d.lerp(e, u)`).
    cubic: bool,
}

/// A path's bound is widened by this many units in the last place of its largest
/// coefficient: evaluating a segment's cubic (Horner, three multiply-adds) and adding it to a
/// shape's coordinates rounds a few times, each by half an ulp of at most that magnitude, so
/// the box stays conservative for the BVH.
pub const BOUND_SLACK_ULPS: f32 = 16.0;

impl MotionPath {
    /// A path through `keys` (at least two, times finite and strictly increasing, translations
    /// finite); the error says which rule a key breaks.
    pub fn new(keys: Vec<Keyframe>, interpolation: Interpolation) -> Result<MotionPath, String> {
        if keys.len() < 2 {
            return Err(format!("a path needs at least two keyframes, not {}", keys.len()));
        }
        for (i, k) in keys.iter().enumerate() {
            if !(k.time.is_finite() && k.translation.is_finite()) {
                return Err(format!("keyframe {i}: time and translation must be finite"));
            }
            if i > 0 && k.time <= keys[i - 1].time {
                return Err(format!("keyframe {i}: times must increase (time {} after {})", k.time, keys[i - 1].time));
            }
        }
        let segments = segments(&keys, interpolation);
        if segments.iter().any(|s| !(s.a.is_finite() && s.b.is_finite() && s.c.is_finite())) {
            return Err("the keyframes are too close in time for their distance (the path's speed overflows)".into());
        }
        let still = keys.iter().all(|k| k.translation == keys[0].translation);
        Ok(MotionPath { keys, interpolation, segments, still })
    }

    /// Today's linear motion: `start` when the shutter opens, `end` when it closes.
    pub fn linear(start: Vec3, end: Vec3) -> Result<MotionPath, String> {
        let keys = vec![Keyframe { time: 0.0, translation: start }, Keyframe { time: 1.0, translation: end }];
        MotionPath::new(keys, Interpolation::Linear)
    }

    /// The keys, in time order.
    pub fn keys(&self) -> &[Keyframe] {
        &self.keys
    }

    /// How the path goes between keys.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The same keys, interpolated as `interpolation`.
    pub fn with_interpolation(&self, interpolation: Interpolation) -> MotionPath {
        MotionPath {
            segments: segments(&self.keys, interpolation),
            keys: self.keys.clone(),
            interpolation,
            still: self.still,
        }
    }

    /// The translation when the shutter opens: the first key's.
    pub fn start(&self) -> Vec3A {
        Vec3A::from(self.keys[0].translation)
    }

    /// Whether every key is the same translation (the path stands still).
    pub fn is_still(&self) -> bool {
        self.still
    }

    /// Whether this is the linear motion of two keys at times 0 and 1, whose translation at `t`
    /// is `start + (end - start) * t` up to rounding: the form the renderer moves a shape by.
    pub fn as_linear(&self) -> Option<(Vec3A, Vec3A)> {
        match self.keys[..] {
            [a, b] if a.time == 0.0 && b.time == 1.0 => Some((a.translation.into(), b.translation.into())),
            _ => None,
        }
    }

    /// The translation at shutter time `t` (held at the end keys' outside them).
    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        let first = self.keys[0].time;
        let last = self.keys[self.keys.len() - 1].time;
        // A time that is not a number holds at the start too.
        if self.still || t <= first || t.is_nan() {
            return self.segments[0].d;
        }
        if t >= last {
            return self.segments[self.segments.len() - 1].e;
        }
        // The segment whose start is the last key at or before `t`.
        let i = self.keys.partition_point(|k| k.time <= t) - 1;
        self.segments[i.min(self.segments.len() - 1)].at(t)
    }

    /// A box that holds the translation at every time: per segment, its cubic's values at its
    /// ends and at the roots of its derivative inside it (the extremes per axis), widened by
    /// [`BOUND_SLACK_ULPS`].
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        let mut magnitude = Vec3A::ZERO;
        for s in &self.segments {
            b = b.grow(s.d).grow(s.e);
            magnitude = magnitude.max(s.d.abs()).max(s.e.abs());
            if s.cubic {
                magnitude = magnitude.max(s.a.abs() + s.b.abs() + s.c.abs() + s.d.abs());
                for axis in 0..3 {
                    for u in derivative_roots(s.a[axis], s.b[axis], s.c[axis]).into_iter().flatten() {
                        let v = s.cubic_at(u)[axis];
                        b.min[axis] = b.min[axis].min(v);
                        b.max[axis] = b.max[axis].max(v);
                    }
                }
            }
        }
        let slack = magnitude * (BOUND_SLACK_ULPS * f32::EPSILON);
        Aabb { min: b.min - slack, max: b.max + slack }
    }

    /// A box that holds the translation at every scene time `shutter` exposes (held at the
    /// end keys' outside them): per segment it overlaps, its values at the overlap's ends and
    /// at the roots of its derivative inside it, widened by [`BOUND_SLACK_ULPS`]. A shutter
    /// over all the keys gets [`MotionPath::bounds`] itself (a still's keys in `[0, 1]`: the
    /// same box, the same tree); a frame of a long animation gets its own span's, so its tree
    /// stays tight.
    pub fn bounds_over(&self, shutter: Shutter) -> Aabb {
        let (first, last) = (self.keys[0].time, self.keys[self.keys.len() - 1].time);
        if shutter.open <= first && shutter.close >= last {
            return self.bounds();
        }
        // The points the box holds; the slack's magnitude grows with them.
        let mut b = Aabb::EMPTY;
        let mut magnitude = Vec3A::ZERO;
        let add = |p: Vec3A, b: &mut Aabb, magnitude: &mut Vec3A| {
            *b = b.grow(p);
            *magnitude = magnitude.max(p.abs());
        };
        if shutter.open < first {
            add(self.segments[0].d, &mut b, &mut magnitude);
        }
        if shutter.close > last {
            add(self.segments[self.segments.len() - 1].e, &mut b, &mut magnitude);
        }
        for s in &self.segments {
            let (ua, ub) = (((shutter.open - s.t0) / s.h).max(0.0), ((shutter.close - s.t0) / s.h).min(1.0));
            if ua > ub {
                continue;
            }
            add(s.at_u(ua), &mut b, &mut magnitude);
            add(s.at_u(ub), &mut b, &mut magnitude);
            if s.cubic {
                magnitude = magnitude.max(s.a.abs() + s.b.abs() + s.c.abs() + s.d.abs());
                for axis in 0..3 {
                    let roots = derivative_roots(s.a[axis], s.b[axis], s.c[axis]);
                    for u in roots.into_iter().flatten().filter(|&u| u > ua && u < ub) {
                        let v = s.cubic_at(u)[axis];
                        b.min[axis] = b.min[axis].min(v);
                        b.max[axis] = b.max[axis].max(v);
                    }
                }
            }
        }
        let slack = magnitude * (BOUND_SLACK_ULPS * f32::EPSILON);
        Aabb { min: b.min - slack, max: b.max + slack }
    }

    /// The box of a shape whose box at rest is `rest` over the whole path: `rest` moved by
    /// [`MotionPath::bounds`], widened by [`BOUND_SLACK_ULPS`] of its own magnitude for the
    /// rounding of the sums (the shape's coordinates plus the translation).
    pub fn sweep(&self, rest: Aabb) -> Aabb {
        moved(rest, self.bounds())
    }

    /// [`MotionPath::sweep`] over the scene times `shutter` exposes
    /// ([`MotionPath::bounds_over`]).
    pub fn sweep_over(&self, rest: Aabb, shutter: Shutter) -> Aabb {
        moved(rest, self.bounds_over(shutter))
    }

    /// `n + 1` points of the path at evenly spaced times from the first key to the last (a
    /// polyline to draw; `n` at least 1).
    pub fn polyline(&self, n: usize) -> Vec<Vec3A> {
        let n = n.max(1);
        let (t0, t1) = (self.keys[0].time, self.keys[self.keys.len() - 1].time);
        (0..=n).map(|i| self.at(t0 + (t1 - t0) * i as f32 / n as f32)).collect()
    }
}

/// A box at rest, `rest`, moved by every translation in `path`, widened by
/// [`BOUND_SLACK_ULPS`] of its own magnitude for the rounding of the sums.
fn moved(rest: Aabb, path: Aabb) -> Aabb {
    let (min, max) = (rest.min + path.min, rest.max + path.max);
    let slack = min.abs().max(max.abs()) * (BOUND_SLACK_ULPS * f32::EPSILON);
    Aabb { min: min - slack, max: max + slack }
}

impl Segment {
    #[inline]
    fn at(&self, t: f32) -> Vec3A {
        self.at_u((t - self.t0) / self.h)
    }

    /// The translation at `u` in `[0, 1]` along the segment.
    #[inline]
    fn at_u(&self, u: f32) -> Vec3A {
        if self.cubic { self.cubic_at(u) } else { self.d.lerp(self.e, u) }
    }

    #[inline]
    fn cubic_at(&self, u: f32) -> Vec3A {
        ((self.a * u + self.b) * u + self.c) * u + self.d
    }
}

/// The segments between neighbouring keys: linear, or the Hermite cubics with the tangents of
/// the module's doc (two keys: one linear segment either way).
fn segments(keys: &[Keyframe], interpolation: Interpolation) -> Vec<Segment> {
    let p = |i: usize| Vec3A::from(keys[i].translation);
    let t = |i: usize| keys[i].time;
    let n = keys.len() - 1;
    // Velocity at key i: central difference inside, one-sided at the ends.
    let velocity = |i: usize| {
        let (lo, hi) = (i.saturating_sub(1), (i + 1).min(n));
        (p(hi) - p(lo)) / (t(hi) - t(lo))
    };
    let cubic = interpolation == Interpolation::CatmullRom && keys.len() > 2;
    (0..n)
        .map(|i| {
            let (d, e, h) = (p(i), p(i + 1), t(i + 1) - t(i));
            let (a, b, c) = if cubic {
                let (m0, m1) = (velocity(i) * h, velocity(i + 1) * h);
                (2.0 * (d - e) + m0 + m1, 3.0 * (e - d) - 2.0 * m0 - m1, m0)
            } else {
                (Vec3A::ZERO, Vec3A::ZERO, e - d)
            };
            Segment { t0: t(i), h, a, b, c, d, e, cubic }
        })
        .collect()
}

/// The roots in `(0, 1)` of the derivative `3a u^2 + 2b u + c` of `a u^3 + b u^2 + c u + d`.
fn derivative_roots(a: f32, b: f32, c: f32) -> [Option<f32>; 2] {
    let inside = |u: f32| (u > 0.0 && u < 1.0).then_some(u);
    let (qa, qb, qc) = (3.0 * a as f64, 2.0 * b as f64, c as f64);
    if qa == 0.0 {
        return [if qb == 0.0 { None } else { inside((-qc / qb) as f32) }, None];
    }
    let disc = qb * qb - 4.0 * qa * qc;
    if disc < 0.0 {
        return [None, None];
    }
    let s = disc.sqrt();
    // The numerically stable pair: q = -(b + sign(b) s) / 2, roots q / a and c / q.
    let q = -0.5 * (qb + s.copysign(qb));
    let r0 = q / qa;
    let r1 = if q == 0.0 { r0 } else { qc / q };
    [inside(r0 as f32), inside(r1 as f32)]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(time: f32, x: f32, y: f32) -> Keyframe {
        Keyframe { time, translation: Vec3::new(x, y, 0.0) }
    }

    #[test]
    fn passes_through_its_keys_and_holds_outside_them() {
        for interp in Interpolation::ALL {
            let keys = vec![key(0.1, 0.0, 0.0), key(0.4, 1.0, 2.0), key(0.6, -1.0, 0.5), key(0.9, 3.0, 3.0)];
            let p = MotionPath::new(keys.clone(), interp).unwrap();
            for k in &keys {
                assert!(p.at(k.time).distance(k.translation.into()) < 1e-5, "{interp:?} {k:?}");
            }
            assert_eq!(p.at(0.0), p.start());
            assert_eq!(p.at(1.0), Vec3A::new(3.0, 3.0, 0.0));
            assert_eq!(p.at(f32::NAN), p.start());
        }
    }

    #[test]
    fn two_keys_are_the_linear_motion_bit_for_bit() {
        let (a, b) = (Vec3::new(0.3, -1.7, 2.1), Vec3::new(-0.9, 0.25, 1e-3));
        for interp in Interpolation::ALL {
            let p = MotionPath::new(
                vec![Keyframe { time: 0.0, translation: a }, Keyframe { time: 1.0, translation: b }],
                interp,
            )
            .unwrap();
            for i in 0..1000 {
                let t = i as f32 / 1000.0;
                assert_eq!(p.at(t), Vec3A::from(a).lerp(b.into(), t));
            }
        }
    }

    #[test]
    fn uniform_catmull_rom_matches_the_textbook_matrix() {
        // Keys evenly spaced in time: the uniform Catmull-Rom spline,
        // 0.5 * (2 p1 + (-p0 + p2) u + (2 p0 - 5 p1 + 4 p2 - p3) u^2 + (-p0 + 3 p1 - 3 p2 + p3) u^3).
        let ys = [0.0f32, 1.0, -0.5, 2.0];
        let keys = ys.iter().enumerate().map(|(i, &y)| key(i as f32 / 3.0, 0.0, y)).collect();
        let p = MotionPath::new(keys, Interpolation::CatmullRom).unwrap();
        let [p0, p1, p2, p3] = ys;
        for i in 0..=20 {
            let u = i as f32 / 20.0;
            let want = 0.5
                * (2.0 * p1
                    + (-p0 + p2) * u
                    + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * u * u
                    + (-p0 + 3.0 * p1 - 3.0 * p2 + p3) * u * u * u);
            let got = p.at((1.0 + u) / 3.0).y;
            assert!((got - want).abs() < 1e-5, "u {u}: {got} vs {want}");
        }
    }

    #[test]
    fn catmull_rom_bound_covers_its_overshoot() {
        // A sharp turn: the spline overshoots the keys' box; the bound holds it, and it is
        // tight (the sampled extremes reach it up to the sampling step).
        let keys = vec![key(0.0, 0.0, 0.0), key(0.3, 1.0, 1.0), key(0.35, 1.0, 0.0), key(1.0, 0.0, 1.0)];
        let p = MotionPath::new(keys, Interpolation::CatmullRom).unwrap();
        let b = p.bounds();
        let samples: Vec<Vec3A> = (0..=100_000).map(|i| p.at(i as f32 / 100_000.0)).collect();
        let seen = Aabb::from_points(samples.iter().copied());
        assert!(seen.max.x > 1.0 || seen.max.y > 1.0 || seen.min.y < 0.0, "the test path should overshoot");
        assert!(b.contains(&seen), "{b:?} vs {seen:?}");
        assert!((b.max - seen.max).max_element() < 1e-4 && (seen.min - b.min).max_element() < 1e-4, "{b:?} {seen:?}");
    }

    #[test]
    fn bad_keys_are_refused_with_a_reason() {
        let cases: [(Vec<Keyframe>, &str); 5] = [
            (vec![key(0.0, 0.0, 0.0)], "at least two"),
            (vec![key(0.5, 0.0, 0.0), key(0.5, 1.0, 0.0)], "increase"),
            (vec![key(0.6, 0.0, 0.0), key(0.2, 1.0, 0.0)], "increase"),
            (vec![key(0.0, 0.0, 0.0), key(f32::INFINITY, 1.0, 0.0)], "finite"),
            (vec![key(0.0, f32::NAN, 0.0), key(1.0, 1.0, 0.0)], "finite"),
        ];
        for (keys, want) in cases {
            let err = MotionPath::new(keys, Interpolation::CatmullRom).unwrap_err();
            assert!(err.contains(want), "{err}");
        }
    }
}
