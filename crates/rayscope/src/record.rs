//! Ray recording for the visual debugger.
//!
//! The integrator is generic over a [`RayRecorder`]. Normal renders use [`NoRecorder`], whose
//! methods are empty and inline away, so the debugger traces a pixel with exactly the code the
//! renderer runs, at no cost to the renderer. [`RayTree`] records what the debugger draws.

use serde::Serialize;

use crate::math::{Color, Vec3A};
use crate::ray::Ray;

/// Why a ray was cast.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RayKind {
    /// From the camera through a pixel.
    Camera,
    /// Mirror reflection.
    Reflection,
    /// Continuation through a transparent surface.
    Transmission,
    /// One of the rays sampling a glossy reflection lobe.
    Glossy,
}

/// What a recorded ray hit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RecordedHit {
    /// Distance along the ray.
    pub t: f32,
    /// The hit point.
    pub point: [f32; 3],
    /// Global primitive id.
    pub prim: u32,
    /// Material index.
    pub material: u32,
    /// Geometric normal (towards the ray).
    pub geo_normal: [f32; 3],
    /// Shading normal (interpolated when enabled).
    pub shading_normal: [f32; 3],
}

/// Observes the integrator. Every method has an empty default.
pub trait RayRecorder {
    /// Whether this recorder keeps anything; lets the integrator skip work done only for it.
    const RECORDS: bool = false;
    /// A ray of `kind` at recursion `depth` is about to be traced.
    #[inline(always)]
    fn begin_ray(&mut self, _kind: RayKind, _depth: u32, _ray: &Ray) {}
    /// The current ray hit (or missed, `None`).
    #[inline(always)]
    fn hit(&mut self, _hit: Option<RecordedHit>) {}
    /// A shadow ray from `from` towards the point `to` sampled on light `light`, whose colour
    /// there is `light_color`; `blocked_at` is where an opaque surface stopped it;
    /// `transmitted` the light fraction that got through.
    #[inline(always)]
    fn shadow(&mut self, _shadow: &ShadowEvent) {}
    /// The current ray is done and returns `color`.
    #[inline(always)]
    fn end_ray(&mut self, _color: Color) {}
}

/// A shadow ray as the integrator reports it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowEvent {
    /// Index of the light.
    pub light: usize,
    /// Origin (the offset shading point).
    pub from: Vec3A,
    /// The point sampled on the light.
    pub to: Vec3A,
    /// The light's colour at that point.
    pub light_color: Color,
    /// Where an opaque surface blocked the ray, if one did.
    pub blocked_at: Option<Vec3A>,
    /// Fraction of the light that arrived (0 blocked, 1 free, between through transparency).
    pub transmitted: Color,
}

/// Records nothing; what normal renders use.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoRecorder;

impl RayRecorder for NoRecorder {}

/// A shadow ray as recorded.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RecordedShadow {
    /// Index of the light.
    pub light: usize,
    /// Origin (the offset shading point).
    pub from: [f32; 3],
    /// The light point aimed at.
    pub to: [f32; 3],
    /// The light's colour at that point.
    pub light_color: [f32; 3],
    /// Where an opaque surface blocked it, if one did.
    pub blocked_at: Option<[f32; 3]>,
    /// Fraction of the light's colour that arrived.
    pub transmitted: [f32; 3],
}

/// One ray of the tree.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecordedRay {
    /// Why it was cast.
    pub kind: RayKind,
    /// Recursion depth (camera rays are 0).
    pub depth: u32,
    /// Index of the parent ray in [`RayTree::rays`], `None` for the camera ray.
    pub parent: Option<usize>,
    /// Origin.
    pub origin: [f32; 3],
    /// Direction.
    pub dir: [f32; 3],
    /// What it hit.
    pub hit: Option<RecordedHit>,
    /// The shadow rays cast from its hit point.
    pub shadows: Vec<RecordedShadow>,
    /// The colour this ray returned (its contribution before the parent's weighting).
    pub color: [f32; 3],
}

/// The full tree of one pixel's rays, in the order they were cast.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RayTree {
    /// The rays; a ray's parent comes before it.
    pub rays: Vec<RecordedRay>,
    #[serde(skip)]
    open: Vec<usize>,
}

impl RayRecorder for RayTree {
    const RECORDS: bool = true;

    fn begin_ray(&mut self, kind: RayKind, depth: u32, ray: &Ray) {
        self.rays.push(RecordedRay {
            kind,
            depth,
            parent: self.open.last().copied(),
            origin: ray.origin.to_array(),
            dir: ray.dir.to_array(),
            hit: None,
            shadows: Vec::new(),
            color: [0.0; 3],
        });
        self.open.push(self.rays.len() - 1);
    }

    fn hit(&mut self, hit: Option<RecordedHit>) {
        if let Some(&i) = self.open.last() {
            self.rays[i].hit = hit;
        }
    }

    fn shadow(&mut self, s: &ShadowEvent) {
        if let Some(&i) = self.open.last() {
            self.rays[i].shadows.push(RecordedShadow {
                light: s.light,
                from: s.from.to_array(),
                to: s.to.to_array(),
                light_color: s.light_color.to_array(),
                blocked_at: s.blocked_at.map(|p| p.to_array()),
                transmitted: s.transmitted.to_array(),
            });
        }
    }

    fn end_ray(&mut self, color: Color) {
        if let Some(i) = self.open.pop() {
            self.rays[i].color = color.to_array();
        }
    }
}
