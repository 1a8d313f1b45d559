//! Ray recording for the visual debugger.
//!
//! The integrator is generic over a [`RayRecorder`]. Normal renders use [`NoRecorder`], whose
//! methods are empty and inline away, so the debugger traces a pixel with exactly the code the
//! renderer runs, at no cost to the renderer. [`RayTree`] records what the debugger draws,
//! with the nodes and leaves of the wide BVH each ray's own traversal entered
//! ([`RecordedTraversal`]).

use serde::Serialize;

use crate::bvh::{QueryKind, TraversalLog, WideRef};
use crate::environment::EnvironmentLookup;
use crate::math::{Color, Vec3A};
use crate::ray::{Interval, Ray};
use crate::scene::{Scene, TextureLod};
use crate::settings::ShadingModel;

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

impl RayKind {
    /// What a person calls a ray of this kind: "reflection", "glossy reflection".
    pub fn noun(self) -> &'static str {
        match self {
            RayKind::Camera => "camera ray",
            RayKind::Reflection => "reflection",
            RayKind::Transmission => "transmission",
            RayKind::Glossy => "glossy reflection",
        }
    }
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
    /// Adaptive depth control did not cast a branch of the current ray (its weight is below
    /// `adc_bailout`).
    #[inline(always)]
    fn stopped(&mut self, _branch: &StoppedBranch) {}
    /// The current ray is done and returns `color`.
    #[inline(always)]
    fn end_ray(&mut self, _color: Color) {}
    /// What the wide BVH's traversal entered to find the current ray's closest hit. Called
    /// only when [`RayRecorder::RECORDS`], after [`RayRecorder::begin_ray`].
    #[inline(always)]
    fn ray_traversal(&mut self, _traversal: RecordedTraversal) {}
    /// The queries of the wide BVH that answered the shadow ray [`RayRecorder::shadow`] last
    /// reported (one, or through transparent surfaces one per surface crossed). Called only
    /// when [`RayRecorder::RECORDS`], right after that `shadow`.
    #[inline(always)]
    fn shadow_traversals(&mut self, _traversals: Vec<RecordedTraversal>) {}
    /// The current ray's weight: per channel, the product of the factors by which its light
    /// reaches the pixel (1 for a camera ray; the sample's share of the pixel not counted).
    #[inline(always)]
    fn weight(&mut self, _weight: Color) {}
    /// How the current ray's hit weighs what it gathers: see [`SurfaceFactors`].
    #[inline(always)]
    fn surface_factors(&mut self, _factors: &SurfaceFactors) {}
    /// A light point was shaded at the current ray's hit: the terms of its Phong sum.
    #[inline(always)]
    fn light_term(&mut self, _term: &LightTerm) {}
    /// A light point at the current ray's hit was skipped, with no shadow ray: see
    /// [`SkipReason`].
    #[inline(always)]
    fn light_skipped(&mut self, _skip: &SkippedLight) {}
    /// The current ray missed and read the scene's environment map here. Called only when
    /// [`RayRecorder::RECORDS`], after [`RayRecorder::hit`] of `None`.
    #[inline(always)]
    fn environment(&mut self, _lookup: &EnvironmentLookup) {}
    /// The current ray's hit read its texture trilinearly, at this footprint and mip level.
    /// Called, after [`RayRecorder::hit`], for every recorder (whether or not it
    /// [`RayRecorder::RECORDS`]: the mip-level view needs nothing else) and only when textures
    /// are filtered trilinearly.
    #[inline(always)]
    fn texture_lod(&mut self, _lod: &TextureLod) {}
}

/// How a shaded surface weighs what it gathers, as the integrator applies it: its own light
/// (direct and reflected) is scaled by the opacity `d` when the surface also transmits, the
/// transmitted ray's light by `1 - d`, and the reflection by `ks` (and `1/n` for each of `n`
/// glossy rays).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SurfaceFactors {
    /// The material's specular reflectance: the reflection's weight.
    pub ks: Color,
    /// The opacity `d` when a transmission ray blends with the surface's own light; `None`
    /// when the surface does not transmit (opaque, transparency off, or at the maximum depth).
    pub opacity: Option<f32>,
}

/// One light point shaded as a point light, in the integrator's own terms: its colour is
/// `arrived * light_color * (kd * cos + ks * highlight)`, and the light's contribution to the
/// ray is the mean over its `samples` points.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LightTerm {
    /// Index of the light.
    pub light: usize,
    /// The points the light is sampled with at this hit (1: its centre or a point light);
    /// each weighs `1 / samples`.
    pub samples: u32,
    /// The point on the light.
    #[serde(serialize_with = "as_array")]
    pub to: Vec3A,
    /// The shading model that shaded it.
    pub model: ShadingModel,
    /// The diffuse colour at the hit (the texture's when textured); for the gradient model,
    /// the gradient's colour at `cos` (without a gradient, the ramp's: `kd cos`).
    pub kd: Color,
    /// The cosine between the shading normal and the direction to the light point.
    pub cos: f32,
    /// The material's specular reflectance.
    pub ks: Color,
    /// The highlight `max(0, c)^shininess` (0 when `ks` is black or the model has none), `c`
    /// being `r.v` (Phong, gradient) or `n.h` (Blinn-Phong).
    pub highlight: f32,
    /// The light's colour at the point.
    pub light_color: Color,
    /// The fraction of the light the shadow ray let through (1 without shadows).
    pub arrived: Color,
    /// `arrived * light_color * kd * cos` (for the gradient model `arrived * light_color *
    /// kd`: the gradient's colour is not multiplied by `cos` again).
    pub diffuse: Color,
    /// `arrived * light_color * ks * highlight`.
    pub specular: Color,
}

/// A light point the integrator shaded no light from, with no shadow ray: it lies behind the
/// surface.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SkippedLight {
    /// Index of the light.
    pub light: usize,
    /// The point on the light.
    #[serde(serialize_with = "as_array")]
    pub to: Vec3A,
    /// Which test it failed.
    pub reason: SkipReason,
}

/// Why a light point was skipped: the integrator's three tests, in the order it makes them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SkipReason {
    /// Behind the surface as the shading normal sees it (`cos <= 0`).
    BehindShadingNormal,
    /// In front of the shading normal but behind the geometric normal (an interpolated normal
    /// tilted towards a light the triangle faces away from).
    BehindGeometricNormal,
    /// At no distance from the shading point.
    ZeroDistance,
}

impl SkipReason {
    /// The first test a light point fails, from the cosines with the shading and geometric
    /// normals and its distance; `None` when it passes all three.
    pub fn of(cos_shading: f32, cos_geometric: f32, distance: f32) -> Option<SkipReason> {
        if cos_shading <= 0.0 {
            Some(SkipReason::BehindShadingNormal)
        } else if cos_geometric <= 0.0 {
            Some(SkipReason::BehindGeometricNormal)
        } else if distance <= 0.0 {
            Some(SkipReason::ZeroDistance)
        } else {
            None
        }
    }
}

impl std::fmt::Display for SkipReason {
    /// What the debugger says: "behind the surface (shading normal)".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SkipReason::BehindShadingNormal => "behind the surface (shading normal)",
            SkipReason::BehindGeometricNormal => "behind the surface (geometric normal)",
            SkipReason::ZeroDistance => "at the shading point",
        })
    }
}

fn as_array<S: serde::Serializer>(v: &Vec3A, s: S) -> Result<S::Ok, S::Error> {
    v.to_array().serialize(s)
}

/// A secondary ray (or a glossy reflection's rays) that adaptive depth control did not cast:
/// why the debugger shows no reflection or transmission where the material has one.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StoppedBranch {
    /// What the branch would have cast.
    pub kind: RayKind,
    /// How many rays it would have cast (a glossy reflection's samples, else 1).
    pub rays: u32,
    /// The weight of each of those rays (the largest colour channel).
    pub weight: f32,
    /// The `adc_bailout` it fell below.
    pub adc_bailout: f32,
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
#[derive(Clone, Debug, PartialEq, Serialize)]
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
    /// How the renderer answered it: the queries of the wide BVH it made, each with what it
    /// entered (one any-hit query; or one closest-hit query per surface crossed through
    /// transparent ones; or, for a ray of a group, its group's frustum query).
    pub traversals: Vec<RecordedTraversal>,
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
    /// The branches of its hit that adaptive depth control did not cast.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub stopped: Vec<StoppedBranch>,
    /// Its weight (see [`RayRecorder::weight`]).
    pub weight: [f32; 3],
    /// How its hit weighs what it gathers; `None` for a miss or with shading off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface: Option<SurfaceFactors>,
    /// The light points shaded at its hit, in order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub light_terms: Vec<LightTerm>,
    /// The light points skipped at its hit (behind the surface), in order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub skipped_lights: Vec<SkippedLight>,
    /// What the renderer's traversal of the wide BVH entered to find its closest hit.
    pub traversal: Option<RecordedTraversal>,
    /// For a ray that missed in a scene with an environment map: where it read the map.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub environment: Option<EnvironmentLookup>,
    /// For a hit whose texture was read trilinearly: the footprint and the mip level.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texture_lod: Option<TextureLod>,
}

impl std::fmt::Display for StoppedBranch {
    /// The debugger's explanation: "reflection not cast: weight 0.003 below adc_bailout 0.0039".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let rays = if self.rays == 1 { String::new() } else { format!(" ({} rays)", self.rays) };
        write!(
            f,
            "{}{rays} not cast: weight {} below adc_bailout {}",
            self.kind.noun(),
            three_digits(self.weight),
            three_digits(self.adc_bailout)
        )
    }
}

/// `x` rounded to three significant digits, for people: weights span many decades.
fn three_digits(x: f32) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x.into();
    }
    let scale = 10f64.powi(2 - f64::from(x.abs()).log10().floor() as i32);
    (f64::from(x) * scale).round() / scale
}

/// The most rays (camera, secondary and shadow rays together) a [`RayTree::default`] records:
/// about 15 MB of tree, and the rays a person can look through. Trees are small with adaptive
/// depth control on; without it one pixel can cast billions of rays.
pub const MAX_RECORDED_RAYS: usize = 100_000;

/// What a [`RayTree`] did not record once it was full. The colours it did record are still the
/// renderer's: the unrecorded rays were traced and counted, only not kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct TreeCut {
    /// The tree's bound: rays recorded, shadow rays included.
    pub limit: usize,
    /// Camera and secondary rays not recorded.
    pub rays: u64,
    /// Shadow rays not recorded.
    pub shadow_rays: u64,
}

impl std::fmt::Display for TreeCut {
    /// The debugger's note: "the first 1000 rays and shadow rays are recorded; 52311 more were
    /// traced (their light is in the colours) but not recorded: 32331 rays and 19980 shadow rays".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = |n: u64| if n == 1 { "" } else { "s" };
        write!(
            f,
            "the first {} rays and shadow rays are recorded; {} more were traced (their light is in the colours) \
             but not recorded: {} ray{} and {} shadow ray{}",
            self.limit,
            self.rays + self.shadow_rays,
            self.rays,
            s(self.rays),
            self.shadow_rays,
            s(self.shadow_rays)
        )
    }
}

/// The tree of one pixel's rays, in the order they were cast, up to a bound.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RayTree {
    /// The rays; a ray's parent comes before it.
    pub rays: Vec<RecordedRay>,
    /// Set when the tree reached its bound: how much was not recorded.
    pub cut: Option<TreeCut>,
    /// The most rays and shadow rays it records.
    #[serde(skip)]
    limit: usize,
    /// Rays and shadow rays recorded so far.
    #[serde(skip)]
    recorded: usize,
    /// The rays being traced, innermost last; `None` for one that is not recorded.
    #[serde(skip)]
    open: Vec<Option<usize>>,
    /// The last shadow ray reported, as its index in the current ray's shadows, if recorded.
    #[serde(skip)]
    last_shadow: Option<usize>,
}

impl Default for RayTree {
    /// A tree of at most [`MAX_RECORDED_RAYS`].
    fn default() -> Self {
        RayTree::with_limit(MAX_RECORDED_RAYS)
    }
}

impl RayTree {
    /// A tree that records at most `limit` rays, shadow rays included.
    pub fn with_limit(limit: usize) -> Self {
        RayTree { rays: Vec::new(), cut: None, limit, recorded: 0, open: Vec::new(), last_shadow: None }
    }

    /// Rays and shadow rays recorded, at most its limit.
    pub fn recorded(&self) -> usize {
        self.recorded
    }

    /// Whether the tree has room for one more ray; counts the ray in [`RayTree::cut`] when not.
    fn room(&mut self, shadow: bool) -> bool {
        if self.recorded < self.limit {
            self.recorded += 1;
            return true;
        }
        let cut = self.cut.get_or_insert(TreeCut { limit: self.limit, rays: 0, shadow_rays: 0 });
        if shadow {
            cut.shadow_rays += 1;
        } else {
            cut.rays += 1;
        }
        false
    }

    /// The recorded ray being traced, if it is recorded.
    fn current(&mut self) -> Option<&mut RecordedRay> {
        let i = (*self.open.last()?)?;
        Some(&mut self.rays[i])
    }
}

impl RayRecorder for RayTree {
    const RECORDS: bool = true;

    fn begin_ray(&mut self, kind: RayKind, depth: u32, ray: &Ray) {
        if !self.room(false) {
            self.open.push(None);
            return;
        }
        // Once the tree is full no ray is recorded, so a recorded ray's parent is recorded too.
        let parent = self.open.last().copied().flatten();
        self.rays.push(RecordedRay {
            kind,
            depth,
            parent,
            origin: ray.origin.to_array(),
            dir: ray.dir.to_array(),
            hit: None,
            shadows: Vec::new(),
            color: [0.0; 3],
            stopped: Vec::new(),
            weight: [1.0; 3],
            surface: None,
            light_terms: Vec::new(),
            skipped_lights: Vec::new(),
            traversal: None,
            environment: None,
            texture_lod: None,
        });
        self.open.push(Some(self.rays.len() - 1));
    }

    fn hit(&mut self, hit: Option<RecordedHit>) {
        if let Some(r) = self.current() {
            r.hit = hit;
        }
    }

    fn shadow(&mut self, s: &ShadowEvent) {
        self.last_shadow = None;
        // A ray that is not recorded came after the tree filled up, so its shadow rays find no
        // room either.
        if !self.room(true) {
            return;
        }
        if let Some(r) = self.current() {
            r.shadows.push(RecordedShadow {
                light: s.light,
                from: s.from.to_array(),
                to: s.to.to_array(),
                light_color: s.light_color.to_array(),
                blocked_at: s.blocked_at.map(|p| p.to_array()),
                transmitted: s.transmitted.to_array(),
                traversals: Vec::new(),
            });
            self.last_shadow = Some(r.shadows.len() - 1);
        }
    }

    fn ray_traversal(&mut self, traversal: RecordedTraversal) {
        if let Some(r) = self.current() {
            r.traversal = Some(traversal);
        }
    }

    fn shadow_traversals(&mut self, traversals: Vec<RecordedTraversal>) {
        if let Some(i) = self.last_shadow
            && let Some(r) = self.current()
        {
            r.shadows[i].traversals = traversals;
        }
    }

    fn stopped(&mut self, branch: &StoppedBranch) {
        if let Some(r) = self.current() {
            r.stopped.push(*branch);
        }
    }

    fn end_ray(&mut self, color: Color) {
        if let Some(Some(i)) = self.open.pop() {
            self.rays[i].color = color.to_array();
        }
    }

    fn weight(&mut self, weight: Color) {
        if let Some(r) = self.current() {
            r.weight = weight.to_array();
        }
    }

    fn surface_factors(&mut self, factors: &SurfaceFactors) {
        if let Some(r) = self.current() {
            r.surface = Some(*factors);
        }
    }

    fn light_term(&mut self, term: &LightTerm) {
        if let Some(r) = self.current() {
            r.light_terms.push(*term);
        }
    }

    fn light_skipped(&mut self, skip: &SkippedLight) {
        if let Some(r) = self.current() {
            r.skipped_lights.push(*skip);
        }
    }

    fn environment(&mut self, lookup: &EnvironmentLookup) {
        if let Some(r) = self.current() {
            r.environment = Some(*lookup);
        }
    }

    fn texture_lod(&mut self, lod: &TextureLod) {
        if let Some(r) = self.current() {
            r.texture_lod = Some(*lod);
        }
    }
}

/// A box of the wide BVH that a recorded ray's traversal entered.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct VisitedBox {
    /// The node or leaf (a leaf is named by its parent node and slot), as
    /// [`Scene::wide_boxes_at_level`] names it.
    pub at: WideRef,
    /// Its level in the wide tree (the root is 0).
    pub level: u32,
    /// The box's lower corner.
    pub min: [f32; 3],
    /// The box's upper corner.
    pub max: [f32; 3],
}

/// One query of the wide BVH that rendering traverses, made for a recorded ray, and what it
/// entered: the renderer's own traversal, observed (see [`crate::bvh::TraversalLog`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecordedTraversal {
    /// What the query asked: a closest hit (alone or in a packet of camera rays), whether
    /// anything blocks a shadow ray, or a group of shadow rays' frustum query.
    pub query: QueryKind,
    /// The ray's origin as the traversal got it.
    pub origin: [f32; 3],
    /// Its direction.
    pub dir: [f32; 3],
    /// The start of its interval.
    pub t_min: f32,
    /// The end of its interval (`null` in JSON for an unbounded ray).
    pub t_max: f32,
    /// Its shutter time.
    pub time: f32,
    /// The nodes and leaves entered, in the order they were entered. A leaf is entered when
    /// its box is hit and its primitives are tested; an any-hit query stops at the first
    /// blocker, so it lists only what it entered until then.
    pub visits: Vec<VisitedBox>,
}

impl RecordedTraversal {
    /// The ray as the traversal got it, with its interval and time: what
    /// [`Scene::visited_nodes`] replays through the binary tree.
    pub fn ray(&self) -> Ray {
        Ray {
            origin: Vec3A::from_array(self.origin),
            dir: Vec3A::from_array(self.dir),
            t: Interval { min: self.t_min, max: self.t_max },
            time: self.time,
        }
    }

    /// Wide nodes entered (leaves aside).
    pub fn nodes(&self) -> usize {
        self.visits.iter().filter(|v| matches!(v.at, WideRef::Node(_))).count()
    }

    /// Leaves entered.
    pub fn leaves(&self) -> usize {
        self.visits.len() - self.nodes()
    }

    /// Whether the traversal entered `at`.
    pub fn entered(&self, at: WideRef) -> bool {
        self.visits.iter().any(|v| v.at == at)
    }

    /// The queries `log` saw, with the boxes of what each entered, in `scene`'s wide BVH.
    pub fn from_log(scene: &Scene, log: &TraversalLog) -> Vec<RecordedTraversal> {
        log.queries
            .iter()
            .map(|q| RecordedTraversal {
                query: q.kind,
                origin: q.ray.origin.to_array(),
                dir: q.ray.dir.to_array(),
                t_min: q.ray.t.min,
                t_max: q.ray.t.max,
                time: q.ray.time,
                visits: scene
                    .visited_boxes(q)
                    .into_iter()
                    .map(|b| VisitedBox {
                        at: b.at,
                        level: b.level,
                        min: b.bounds.min.to_array(),
                        max: b.bounds.max.to_array(),
                    })
                    .collect(),
            })
            .collect()
    }
}

impl RayTree {
    /// Every wide node and leaf that some recorded ray's traversal entered, shadow rays
    /// included: the viewer's "only nodes the selected ray visited" filter for the wide
    /// tree's level view ([`Scene::wide_boxes_at_level`]); the binary tree's filter replays
    /// each recorded ray through it ([`Scene::visited_nodes`] of [`RecordedTraversal::ray`]).
    pub fn visited_wide(&self) -> std::collections::HashSet<WideRef> {
        let of_rays = self.rays.iter().filter_map(|r| r.traversal.as_ref());
        let of_shadows = self.rays.iter().flat_map(|r| r.shadows.iter().flat_map(|s| &s.traversals));
        of_rays.chain(of_shadows).flat_map(|t| t.visits.iter().map(|v| v.at)).collect()
    }
}
