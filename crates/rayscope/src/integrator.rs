//! The Whitted integrator in the course's form: direct lighting by a shading model (the
//! course's Phong unless set) with shadow rays (hard,
//! or soft from sampled area lights), recursive mirror or glossy reflection weighted by `ks`,
//! and transparency blended by `1 - d`.
//!
//! Adaptive depth control bounds the ray tree: every ray carries its weight, the product of
//! the factors by which its light reaches the pixel, and a secondary ray whose weight falls
//! below [`RenderSettings::adc_bailout`] is not cast.

use crate::bvh::{PACKET, TILE_RUNS, TraversalLog};
use crate::camera::Camera;
use crate::cone::{Footprint, NoCone, RayCone};
use crate::light::{Light, LightSample};
use crate::material::Material;
use crate::math::{Color, Vec2, Vec3A, reflect};
use crate::ray::Ray;
use crate::record::{
    LightTerm, NoRecorder, RayKind, RayRecorder, RecordedHit, RecordedTraversal, ShadowEvent, SkipReason, SkippedLight,
    StoppedBranch, SurfaceFactors,
};
use crate::sampler::{PixelSampler, Strata2, stratum_1d};
use crate::scene::{Hit, LightVisibility, Scene, SurfaceInteraction};
use crate::settings::{RenderSettings, ShadingModel, ShadingOptions};
use crate::sky::{Background, Sky};

/// Counts of rays cast, for throughput figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera, reflection, glossy and transmission rays (closest-hit queries).
    pub primary_and_secondary: u64,
    /// Shadow rays (any-hit queries).
    pub shadow: u64,
}

impl RayCounts {
    /// All rays.
    pub fn total(&self) -> u64 {
        self.primary_and_secondary + self.shadow
    }

    /// Add another count.
    pub fn add(&mut self, o: RayCounts) {
        self.primary_and_secondary += o.primary_and_secondary;
        self.shadow += o.shadow;
    }
}

/// What one camera sample carries down its ray tree.
pub struct PathContext<'r, R: RayRecorder> {
    /// The sample's random numbers.
    pub sampler: PixelSampler,
    /// Who watches the rays.
    pub recorder: &'r mut R,
    /// Rays cast so far.
    pub counts: RayCounts,
    /// Whether a glossy reflection has already been split into many rays on this path: later
    /// glossy hits cast one ray each, so the tree grows linearly with depth, not as N^depth.
    pub glossy_split: bool,
}

impl<'r, R: RayRecorder> PathContext<'r, R> {
    /// A fresh context for one camera sample.
    pub fn new(sampler: PixelSampler, recorder: &'r mut R) -> Self {
        PathContext { sampler, recorder, counts: RayCounts::default(), glossy_split: false }
    }
}

/// Camera rays that the renderer traces together ([`Integrator::li_in_packet`]).
#[derive(Clone, Copy, Debug)]
pub enum CameraBatch<'r> {
    /// A packet: a run of up to [`PACKET`] pixels of a row.
    Packet(&'r [Ray]),
    /// A tile: the runs of up to [`TILE_RUNS`] rows, the same columns.
    Tile(&'r [&'r [Ray]]),
}

/// Traces rays through one scene with one set of settings; rays that miss return what `S`
/// says ([`crate::sky`]: the background colour, or an environment map).
pub struct Integrator<'a, S: Sky = Background, C: Footprint = NoCone> {
    /// The scene.
    pub scene: &'a Scene,
    /// The settings.
    pub settings: &'a RenderSettings,
    /// The settings' part that the scene's surface queries read.
    pub shading: ShadingOptions,
    /// Whether any surface is shaded by a model other than Phong: when none is, the renderer
    /// runs Phong's code alone, with no per-hit choice of model (the default render keeps its
    /// instructions).
    models: bool,
    /// What rays that miss return.
    pub sky: S,
    /// The footprint camera rays start with: [`NoCone`], or a [`RayCone`] when textures are
    /// filtered trilinearly ([`Integrator::with_cones`]).
    camera_cone: C,
    /// The strata of a light's `settings.light_samples` samples, made once: made in
    /// [`Integrator::direct`], their square root and `floor` call (a library call at the
    /// baseline instruction set) were hoisted to the start of every hit's direct lighting,
    /// point lights' too.
    light_strata: Strata2,
}

impl<'a> Integrator<'a> {
    /// An integrator for this scene and these settings, whose misses return the background
    /// colour (the scene's environment map, if any, is not looked at: see
    /// [`Integrator::with_sky`]).
    pub fn new(scene: &'a Scene, settings: &'a RenderSettings) -> Self {
        Integrator::with_sky(scene, settings, Background)
    }
}

impl<'a, S: Sky> Integrator<'a, S> {
    /// An integrator whose misses return what `sky` says.
    pub fn with_sky(scene: &'a Scene, settings: &'a RenderSettings, sky: S) -> Self {
        let models = scene.materials.iter().any(|m| m.shading_model(settings.shading_model) != ShadingModel::Phong);
        let light_strata = Strata2::new(settings.light_samples);
        Integrator {
            scene,
            settings,
            shading: settings.shading_options(),
            models,
            sky,
            camera_cone: NoCone,
            light_strata,
        }
    }

    /// This integrator with rays that carry a footprint, starting from `camera`'s
    /// ([`crate::cone`]): trilinear texture lookups then read the mip level of the ray's
    /// footprint.
    pub fn with_cones(self, camera: &Camera) -> Integrator<'a, S, RayCone> {
        let camera_cone = RayCone::camera(camera.tan_half_fov(), self.settings.height);
        let Integrator { scene, settings, shading, models, sky, light_strata, .. } = self;
        Integrator { scene, settings, shading, models, sky, camera_cone, light_strata }
    }
}

impl<'a, S: Sky, C: Footprint> Integrator<'a, S, C> {
    /// The colour arriving along `ray`, cast for reason `kind` at recursion `depth`, as a ray
    /// of weight 1 (a camera ray's).
    pub fn li<R: RayRecorder>(&self, ray: &Ray, kind: RayKind, depth: u32, ctx: &mut PathContext<R>) -> Color {
        self.cast(ray, kind, depth, Color::ONE, self.camera_cone, ctx)
    }

    /// The colour arriving along camera ray `lane` of run `run` of `batch`, traced as the
    /// renderer traces a still camera's rays: with the camera rays of its neighbours (a run
    /// of pixels of a row, or a tile's runs, as [`crate::render`] makes them), the recorder
    /// told what the packet's or the tile's traversal entered for this ray. `mirrors_ahead`:
    /// whether the render traces the run's mirror rays ahead ([`Integrator::first_mirrors`]),
    /// whose walks the recorder is then told as the render made them.
    pub fn li_in_packet<R: RayRecorder>(
        &self,
        batch: CameraBatch<'_>,
        (run, lane): (usize, usize),
        mirrors_ahead: bool,
        ctx: &mut PathContext<R>,
    ) -> Color {
        let (rays, hits, logs) = match batch {
            CameraBatch::Packet(rays) => {
                let mut logs: [TraversalLog; PACKET] = Default::default();
                let hits = self.scene.intersect_packet_counted(rays, &mut logs);
                (rays, hits, logs)
            }
            CameraBatch::Tile(runs) => {
                let mut logs: [[TraversalLog; PACKET]; TILE_RUNS] = Default::default();
                let hits = self.scene.intersect_tile_counted(runs, &mut logs);
                (runs[run], hits[run], std::mem::take(&mut logs[run]))
            }
        };
        let mut ahead = [TracedAhead::NONE; PACKET];
        if mirrors_ahead {
            let seen = std::array::from_fn(|i| rays.get(i).and_then(|ray| self.seen(ray, hits[i])));
            self.first_mirrors(rays, &seen, &mut ahead);
        }
        // `trace` with the answers traced ahead, written out: `trace` taking them as an
        // argument (its other callers passing none) ran the same instructions, but moved the
        // renderer's code so that the Cornell box and the dragon rendered 2% slower.
        let ray = &rays[lane];
        self.begin_ray(ray, Some(&logs[lane]), RayKind::Camera, 0, Color::ONE, ctx);
        let color = match hits[lane] {
            None => self.miss(ray, ctx),
            Some(hit) => {
                let seen = self.arrive(ray, hit, self.camera_cone, ctx.recorder);
                self.shade_seen(ray, &seen, 0, Color::ONE, ahead[lane], ctx)
            }
        };
        ctx.recorder.end_ray(color);
        color
    }

    /// [`Integrator::li`] for a ray whose closest hit is already known (`hit`, which must be
    /// what [`Scene::intersect`] gives): camera rays traced as a packet continue here.
    /// Inlined into the packets' loop, as the compiler chose before the sky and the shading
    /// models made the integrator generic and larger (out of line it cost 3% of a render).
    #[inline(always)]
    pub fn li_hit<R: RayRecorder>(
        &self,
        ray: &Ray,
        hit: Option<Hit>,
        kind: RayKind,
        depth: u32,
        ctx: &mut PathContext<R>,
    ) -> Color {
        self.trace(ray, hit, None, kind, depth, Color::ONE, self.camera_cone, ctx)
    }

    /// A ray of `weight` (a camera ray's is 1) and footprint `cone`: what
    /// [`Integrator::trace`] gives for its closest hit, found here (observed for a recorder,
    /// which is told what the traversal entered).
    fn cast<R: RayRecorder>(
        &self,
        ray: &Ray,
        kind: RayKind,
        depth: u32,
        weight: Color,
        cone: C,
        ctx: &mut PathContext<R>,
    ) -> Color {
        if R::RECORDS {
            let mut log = TraversalLog::default();
            let hit = self.scene.intersect_counted(ray, &mut log);
            return self.trace(ray, hit, Some(&log), kind, depth, weight, cone, ctx);
        }
        self.trace(ray, self.scene.intersect(ray), None, kind, depth, weight, cone, ctx)
    }

    /// A mirror ray traced ahead ([`Integrator::first_mirrors`]) as a recorder is told it:
    /// the render's any-hit walk of it (the packet's walk enters for each ray exactly what
    /// the ray enters alone), then, where something blocks it, the closest-hit walk that
    /// finds its hit. The ray's record keeps the last walk: the any-hit one of a ray that
    /// leaves the scene, the closest-hit one of a ray that meets it.
    fn cast_ahead<R: RayRecorder>(
        &self,
        ray: &Ray,
        depth: u32,
        weight: Color,
        cone: C,
        ctx: &mut PathContext<R>,
    ) -> Color {
        let mut log = TraversalLog::default();
        let blocked = self.scene.geometry.occluded_counted(ray, &mut log);
        let hit = if blocked { self.scene.intersect_counted(ray, &mut log) } else { None };
        self.trace(ray, hit, Some(&log), RayKind::Reflection, depth, weight, cone, ctx)
    }

    /// The colour arriving along `ray`, whose closest hit is `hit`, for a ray of `weight`: per
    /// colour channel, the product of the factors by which its light reaches the pixel (1 for
    /// a camera ray; the sample's share of the pixel is not counted, as in POV-Ray), whose
    /// footprint where it starts is `cone`. `log`, when recording, holds what the traversal
    /// that found `hit` entered; `ahead`: the rays already traced from the hit.
    // Inlined into its two callers, as the public entry points were before it took their
    // place: called, it cost the Cornell box 2.5% more instructions.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn trace<R: RayRecorder>(
        &self,
        ray: &Ray,
        hit: Option<Hit>,
        log: Option<&TraversalLog>,
        kind: RayKind,
        depth: u32,
        weight: Color,
        cone: C,
        ctx: &mut PathContext<R>,
    ) -> Color {
        self.begin_ray(ray, log, kind, depth, weight, ctx);
        let color = match hit {
            None => self.miss(ray, ctx),
            Some(hit) => {
                let seen = self.arrive(ray, hit, cone, ctx.recorder);
                self.shade_seen(ray, &seen, depth, weight, TracedAhead::NONE, ctx)
            }
        };
        ctx.recorder.end_ray(color);
        color
    }

    /// Whether the shadow rays of camera packets' hits are traced ahead of shading, as packets
    /// ([`Integrator::first_shadows`]): with shading and shadows on, in an opaque scene whose
    /// lights (at most eight) are each shaded from one point (point lights, or no light
    /// samples), so that each hit's first shadow ray towards each light is known beforehand;
    /// and in a scene of [`SHADOWS_AHEAD_PRIMS`] primitives or more.
    pub fn shadows_ahead(&self) -> bool {
        let s = self.settings;
        s.shading
            && s.shadows
            && self.scene.prim_count() >= SHADOWS_AHEAD_PRIMS
            && !self.scene.has_transparency
            && (1..=TracedAhead::LIGHTS).contains(&self.scene.lights.len())
            && self.scene.lights.iter().all(|l| self.shaded_from_one_point(l))
    }

    /// Whether `light` is shaded from one point, its centre (a point light, or any light
    /// without light samples: hard shadows), with one shadow ray; else from stratified
    /// samples. The one rule of [`Integrator::direct`] and [`Integrator::shadows_ahead`].
    #[inline(always)]
    fn shaded_from_one_point(&self, light: &Light) -> bool {
        self.settings.light_samples == 0 || matches!(light, Light::Point { .. })
    }

    /// What camera ray `ray` sees at its closest hit `hit` (what [`Scene::intersect`] gives),
    /// found as [`Integrator::li_hit`] finds it, for [`Integrator::li_seen`].
    #[inline(always)]
    pub fn seen(&self, ray: &Ray, hit: Option<Hit>) -> Option<Seen<C>> {
        hit.map(|hit| self.arrive(ray, hit, self.camera_cone, &mut NoRecorder))
    }

    /// The shadow ray each hit of a packet of camera rays (`rays`, with what they see, `seen`)
    /// casts first towards each light, traced as one packet per light: what
    /// [`Integrator::li_seen`] then shades them with. The same rays, made by the same rule,
    /// and the same answers as traced one by one while shading; where rays from neighbouring
    /// pixels converge on a light, one walk of the tree serves them all. Only for
    /// [`Integrator::shadows_ahead`].
    pub fn first_shadows(&self, rays: &[Ray], seen: &[Option<Seen<C>>; PACKET]) -> [TracedAhead; PACKET] {
        let mut ahead = [TracedAhead::NONE; PACKET];
        for (l, light) in self.scene.lights.iter().enumerate().take(TracedAhead::LIGHTS) {
            // Lanes beyond `k` are never traced.
            let mut shadow = [rays[0]; PACKET];
            let mut lane = [0; PACKET];
            let mut k = 0;
            for (i, (ray, seen)) in rays.iter().zip(seen).enumerate() {
                let Some(Seen { si, .. }) = seen else { continue };
                // `direct` computes this sample again, by the same call (the same bits): the
                // answers it needs are two bytes a hit, where the samples of eight lanes and
                // up to eight lights would be three kilobytes to fill and read back for a
                // square root and a division each.
                let ls = light.center_sample(si.point);
                if faces(si, &ls, si.shading_normal.dot(ls.wi)) {
                    shadow[k] = self
                        .scene
                        .light_visibility(si, light, 1, &self.shading, |vis| vis.shadow_ray(si, &ls, ray.time));
                    lane[k] = i;
                    k += 1;
                }
            }
            let blocked = self.scene.blocked_packet(&shadow[..k]);
            for (j, &i) in lane[..k].iter().enumerate() {
                ahead[i].traced |= 1 << l;
                ahead[i].blocked |= ((blocked >> j & 1) as u8) << l;
            }
        }
        ahead
    }

    /// Whether the mirror rays of camera packets' hits are traced ahead
    /// ([`Integrator::first_mirrors`]): where reflections are on and some material reflects
    /// as a sharp mirror.
    pub fn mirrors_ahead(&self) -> bool {
        let s = self.settings;
        s.shading && s.reflections && s.max_depth > 0 && self.scene.materials.iter().any(|m| self.casts_mirror_ray(m))
    }

    /// Whether a hit on `mat` reflects along one mirror ray, which
    /// [`Integrator::first_mirrors`] traces ahead: `mat` reflects (`ks` above zero), as a
    /// sharp mirror.
    #[inline(always)]
    fn casts_mirror_ray(&self, mat: &Material) -> bool {
        mat.ks.max_element() > 0.0 && self.mirrors_sharply(mat)
    }

    /// Whether `mat` reflects along the mirror direction alone (one ray), rather than over
    /// a glossy lobe.
    #[inline(always)]
    fn mirrors_sharply(&self, mat: &Material) -> bool {
        self.settings.gloss_samples == 0 || !mat.glossiness.unwrap_or(mat.shininess).is_finite()
    }

    /// The mirror rays of a packet's hits that reflect (`rays`, with what they see, `seen`),
    /// traced ahead as one any-hit packet, each answer kept in `ahead`: the reflection of a
    /// ray that nothing blocks is then shaded as a miss without a closest-hit walk (the same
    /// answer: nothing blocks a ray exactly when it has no closest hit), a blocked one is
    /// traced for its closest hit. Most mirror rays off a lone object leave the scene, and an
    /// any-hit walk of them together costs less than a closest-hit walk of each. Only for
    /// [`Integrator::mirrors_ahead`].
    pub fn first_mirrors(&self, rays: &[Ray], seen: &[Option<Seen<C>>; PACKET], ahead: &mut [TracedAhead; PACKET]) {
        let mut mirror = [rays[0]; PACKET];
        let mut lane = [0; PACKET];
        let mut k = 0;
        for (i, (ray, seen)) in rays.iter().zip(seen).enumerate() {
            let Some(Seen { si, .. }) = seen else { continue };
            let mat = &self.scene.materials[si.material as usize];
            if self.casts_mirror_ray(mat) {
                mirror[k] = Ray::spawn(si.point, si.geo_normal, mirror_dir(ray, si), ray.time);
                lane[k] = i;
                k += 1;
            }
        }
        if k == 0 {
            return;
        }
        let blocked = self.scene.blocked_packet(&mirror[..k]);
        for (j, &i) in lane[..k].iter().enumerate() {
            ahead[i].mirror = Some(blocked >> j & 1 == 0);
        }
    }

    /// [`Integrator::li_hit`] for a camera ray whose hit has been seen
    /// ([`Integrator::seen`]) and whose first shadow and mirror rays were traced ahead
    /// (`ahead`): the same colour, the same ray counts.
    #[inline(always)]
    pub fn li_seen<R: RayRecorder>(
        &self,
        ray: &Ray,
        seen: Option<&Seen<C>>,
        ahead: TracedAhead,
        ctx: &mut PathContext<R>,
    ) -> Color {
        self.begin_ray(ray, None, RayKind::Camera, 0, Color::ONE, ctx);
        let color = match seen {
            None => self.miss(ray, ctx),
            Some(seen) => self.shade_seen(ray, seen, 0, Color::ONE, ahead, ctx),
        };
        ctx.recorder.end_ray(color);
        color
    }

    /// A ray's start: told to the recorder (with its weight and, from `log`, what its
    /// traversal entered) and counted.
    #[inline(always)]
    fn begin_ray<R: RayRecorder>(
        &self,
        ray: &Ray,
        log: Option<&TraversalLog>,
        kind: RayKind,
        depth: u32,
        weight: Color,
        ctx: &mut PathContext<R>,
    ) {
        ctx.recorder.begin_ray(kind, depth, ray);
        if R::RECORDS {
            ctx.recorder.weight(weight);
            if let Some(t) = log.and_then(|log| RecordedTraversal::from_log(self.scene, log).pop()) {
                ctx.recorder.ray_traversal(t);
            }
        }
        ctx.counts.primary_and_secondary += 1;
    }

    /// The colour of a ray that hits nothing.
    #[inline(always)]
    fn miss<R: RayRecorder>(&self, ray: &Ray, ctx: &mut PathContext<R>) -> Color {
        ctx.recorder.hit(None);
        self.sky.miss(ray, self.settings, ctx.recorder)
    }

    /// What a ray of footprint `cone` sees at its closest hit `hit`: the surface there (its
    /// texture read at the cone's width where cones are carried, told to `rec`) and the cone
    /// arrived there.
    #[inline(always)]
    fn arrive<R: RayRecorder>(&self, ray: &Ray, hit: Hit, cone: C, rec: &mut R) -> Seen<C> {
        let cone = cone.arrive(hit.t, || self.scene.curvature(&hit, &self.shading));
        let si = if C::CONES {
            let seen = self.scene.surface_in_cone(ray, &hit, &self.shading, cone.width());
            if let Some(lod) = &seen.lod {
                rec.texture_lod(lod);
            }
            seen.si
        } else {
            self.scene.surface(ray, &hit, &self.shading)
        };
        Seen { hit, si, cone }
    }

    /// The colour a ray of `weight` brings back from what it sees (`seen`), told to the
    /// recorder; `ahead`: the shadow and mirror rays already traced from there.
    #[inline(always)]
    fn shade_seen<R: RayRecorder>(
        &self,
        ray: &Ray,
        seen: &Seen<C>,
        depth: u32,
        weight: Color,
        ahead: TracedAhead,
        ctx: &mut PathContext<R>,
    ) -> Color {
        let Seen { hit, si, cone } = seen;
        if R::RECORDS {
            ctx.recorder.hit(Some(RecordedHit {
                t: hit.t,
                point: si.point.to_array(),
                prim: self.scene.prim_id(hit),
                material: si.material,
                geo_normal: si.geo_normal.to_array(),
                shading_normal: si.shading_normal.to_array(),
            }));
        }
        self.shade(ray, si, depth, weight, *cone, ahead, ctx)
    }

    // Inlined into `trace` as main's compiler chose to: with the shading models it grew past
    // the inliner's limit, and the camera packets' loop (`Pass::sample_run`) that calls it
    // then cost 0.4% more instructions.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn shade<R: RayRecorder>(
        &self,
        ray: &Ray,
        si: &SurfaceInteraction,
        depth: u32,
        weight: Color,
        cone: C,
        ahead: TracedAhead,
        ctx: &mut PathContext<R>,
    ) -> Color {
        let s = self.settings;
        let mat = &self.scene.materials[si.material as usize];
        if !s.shading {
            // The course's "shading off" view: the diffuse colour as it is.
            return si.kd;
        }
        let mut color = Color::from(if self.models {
            self.direct_by_model(ray, si, ahead, ctx)
        } else {
            self.direct::<false, R>(ray, si, ahead, ctx)
        });
        let recurse = depth < s.max_depth;
        let transmits = recurse && s.transparency && mat.transparency < 1.0;
        if R::RECORDS {
            let opacity = transmits.then_some(mat.transparency);
            ctx.recorder.surface_factors(&SurfaceFactors { ks: mat.ks, opacity });
        }
        if recurse && s.reflections && mat.ks.max_element() > 0.0 {
            // The reflection reaches the pixel through `ks`, and through the opacity by which
            // the blend below scales the surface's colour.
            let reflected = if transmits { weight * mat.ks * mat.transparency } else { weight * mat.ks };
            color += mat.ks * self.reflection(ray, si, depth, reflected, cone.reflected(), ahead.mirror, ctx);
        }
        if transmits {
            // A branch that adaptive depth control stops adds nothing, as in POV-Ray: the
            // surface still lets through its `1 - d`, of black.
            let transmitted = weight * (1.0 - mat.transparency);
            let behind = if self.worth_casting(RayKind::Transmission, 1, transmitted, ctx) {
                let r = Ray::spawn(si.point, si.geo_normal, ray.dir, ray.time);
                self.cast(&r, RayKind::Transmission, depth + 1, transmitted, cone.transmitted(), ctx)
            } else {
                Color::ZERO
            };
            color = mat.transparency * color + (1.0 - mat.transparency) * behind;
        }
        color
    }

    /// Adaptive depth control: whether `rays` secondary rays of `kind`, each of `weight`, are
    /// worth casting, that is whether the weight's largest channel reaches
    /// [`RenderSettings::adc_bailout`]. Tells the recorder when they are not.
    #[inline]
    fn worth_casting<R: RayRecorder>(&self, kind: RayKind, rays: u32, weight: Color, ctx: &mut PathContext<R>) -> bool {
        let weight = weight.max_element();
        let adc_bailout = self.settings.adc_bailout;
        // Written so that a NaN weight is cast, as without adaptive depth control.
        if weight < adc_bailout {
            ctx.recorder.stopped(&StoppedBranch { kind, rays, weight, adc_bailout });
            return false;
        }
        true
    }

    /// The light the surface reflects specularly: along the mirror direction, or averaged over
    /// `gloss_samples` directions drawn from the Phong lobe `cos^n` around it, with `n` the
    /// material's `glossiness` (its `shininess` unless set; infinite for a perfect mirror).
    ///
    /// Directions are drawn with density `(n + 1) / 2pi * cos^n(alpha)`, so the plain mean of
    /// the returned colours estimates the lobe-weighted reflection without bias. The course
    /// drew directions at random and weighted each by its dot product with the mirror ray; that
    /// estimates a similar blur but spends rays where the weight is small. As `n` grows both
    /// converge to the mirror image. Lobe directions that fall below the surface are folded
    /// back above it (mirrored in the tangent plane), so they still carry light.
    ///
    /// `weight` is the whole reflection's; each of `n` glossy rays weighs `1/n` of it. A
    /// reflection that adaptive depth control stops returns black. `cone` is the mirror
    /// ray's footprint, which glossy rays share (their lobe's blur is not added to it).
    /// `mirror_ahead`: whether the mirror ray, traced ahead ([`Integrator::first_mirrors`]),
    /// hits nothing (`None`: not traced ahead).
    #[allow(clippy::too_many_arguments)]
    fn reflection<R: RayRecorder>(
        &self,
        ray: &Ray,
        si: &SurfaceInteraction,
        depth: u32,
        weight: Color,
        cone: C,
        mirror_ahead: Option<bool>,
        ctx: &mut PathContext<R>,
    ) -> Color {
        let mat = &self.scene.materials[si.material as usize];
        if self.mirrors_sharply(mat) {
            if !self.worth_casting(RayKind::Reflection, 1, weight, ctx) {
                return Color::ZERO;
            }
            // Made where it is used: the reflection of a mirror ray traced ahead and found to
            // miss needs no ray under a uniform sky (its colour), whose normalisation is then
            // not paid twice.
            let r = || Ray::spawn(si.point, si.geo_normal, mirror_dir(ray, si), ray.time);
            if let Some(missed) = mirror_ahead {
                // A recorder wants the ray's walks: it is traced again (the same answer).
                if R::RECORDS {
                    return self.cast_ahead(&r(), depth + 1, weight, cone, ctx);
                }
                if missed {
                    return self.trace(&r(), None, None, RayKind::Reflection, depth + 1, weight, cone, ctx);
                }
            }
            return self.cast(&r(), RayKind::Reflection, depth + 1, weight, cone, ctx);
        }
        let mirror = mirror_dir(ray, si);
        let exponent = mat.glossiness.unwrap_or(mat.shininess);
        let n = if ctx.glossy_split { 1 } else { self.settings.gloss_samples };
        let weight = weight / n as f32;
        if !self.worth_casting(RayKind::Glossy, n, weight, ctx) {
            return Color::ZERO;
        }
        let was_split = ctx.glossy_split;
        ctx.glossy_split = true;
        let mut sum = Color::ZERO;
        let strata = Strata2::new(n);
        for i in 0..n {
            let u = strata.sample(i, ctx.sampler.next_2d());
            let mut dir = sample_phong_lobe(mirror, exponent.max(0.0), u);
            let below = dir.dot(si.geo_normal);
            if below <= 0.0 {
                dir = (dir - 2.0 * below * si.geo_normal).normalize();
            }
            let r = Ray::spawn(si.point, si.geo_normal, dir, ray.time);
            sum += self.cast(&r, RayKind::Glossy, depth + 1, weight, cone, ctx);
        }
        ctx.glossy_split = was_split;
        sum / n as f32
    }

    /// [`Integrator::direct`] for scenes with other models than Phong, out of line: inlined
    /// beside Phong's, it made `shade` too large to be inlined into the camera rays' loop,
    /// which then cost the default render 0.6% more instructions.
    #[inline(never)]
    fn direct_by_model<R: RayRecorder>(
        &self,
        ray: &Ray,
        si: &SurfaceInteraction,
        ahead: TracedAhead,
        ctx: &mut PathContext<R>,
    ) -> Vec3A {
        self.direct::<true, R>(ray, si, ahead, ctx)
    }

    /// Direct lighting from every light by the surface's shading model (Phong unless set),
    /// with shadow rays. With `light_samples == 0`
    /// each light is shaded from its centre (hard shadows); otherwise each area light gets
    /// that many stratified samples, each shaded as a point light of the light's colour there,
    /// and contributes their mean. `MODELS`: whether the scene has surfaces shaded by other
    /// models than Phong (else every surface is Phong's, known at compile time).
    ///
    /// The colour comes back as a [`Vec3A`], the same three sums: a call returns it through
    /// memory, and a 16-byte vector is stored whole, so the caller's loads of it are forwarded
    /// from the store. A [`Color`] was stored as `x` and `y, z` and read back as `x, y` and
    /// `z`, a load no store forwards (1% of the Cornell box's render). `ahead`: the shadow
    /// rays towards lights' single points already traced from `si`.
    fn direct<const MODELS: bool, R: RayRecorder>(
        &self,
        ray: &Ray,
        si: &SurfaceInteraction,
        ahead: TracedAhead,
        ctx: &mut PathContext<R>,
    ) -> Vec3A {
        let mut sum = Color::ZERO;
        let n = self.settings.light_samples;
        // Resolved once per hit.
        let model = if MODELS {
            self.scene.materials[si.material as usize].shading_model(self.settings.shading_model)
        } else {
            ShadingModel::Phong
        };
        for (i, light) in self.scene.lights.iter().enumerate() {
            if self.shaded_from_one_point(light) {
                let center = light.center_sample(si.point);
                sum += self.scene.light_visibility(si, light, 1, &self.shading, |vis| {
                    let point = LightPoint { light: i, samples: 1, model };
                    self.shade_sample(ray, si, point, &center, vis, ahead.of(i), ctx)
                });
                continue;
            }
            let segment = matches!(light, Light::Segment { .. });
            let sampler = light.sampler(si.point);
            // The shadow rays the samples will cast: none without shadows.
            let rays = if self.settings.shadows { n } else { 0 };
            sum += self.scene.light_visibility(si, light, rays, &self.shading, |vis| {
                let strata = self.light_strata;
                let mut acc = Color::ZERO;
                for k in 0..n {
                    let u = if segment {
                        Vec2::new(stratum_1d(k, n, ctx.sampler.next_f32()), 0.5)
                    } else {
                        strata.sample(k, ctx.sampler.next_2d())
                    };
                    let ls = sampler.sample(u);
                    let point = LightPoint { light: i, samples: n, model };
                    acc += self.shade_sample(ray, si, point, &ls, vis, None, ctx);
                }
                acc / n as f32
            });
        }
        Vec3A::from(sum)
    }

    /// One light point as a point light: the shading model's terms times the light's colour
    /// times what the shadow ray lets through (`blocked`: whether it was found blocked
    /// ahead, if it was traced ahead).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn shade_sample<R: RayRecorder>(
        &self,
        ray: &Ray,
        si: &SurfaceInteraction,
        point: LightPoint,
        ls: &LightSample,
        vis: &LightVisibility,
        blocked: Option<bool>,
        ctx: &mut PathContext<R>,
    ) -> Color {
        let cos = si.shading_normal.dot(ls.wi);
        if !faces(si, ls, cos) {
            if R::RECORDS {
                record_skip(si, point, ls, cos, ctx);
            }
            return Color::ZERO;
        }
        let arrived = self.visibility(si, ls, ray.time, point.light, vis, blocked, ctx);
        if arrived == Color::ZERO {
            if R::RECORDS {
                self.record_term(ray, si, point, ls, cos, arrived, ctx);
            }
            return Color::ZERO;
        }
        if R::RECORDS {
            self.record_term(ray, si, point, ls, cos, arrived, ctx);
        }
        arrived * ls.color * self.shading(si, ls.wi, -ray.dir, cos, point.model)
    }

    /// Tell the recorder the terms of a shaded light point, as [`Integrator::shade_sample`]
    /// computes them. Out of line and cold: only the debugger runs it, and it stays out of the
    /// renderer's light loop.
    #[cold]
    #[inline(never)]
    #[allow(clippy::too_many_arguments, reason = "the shading state of one light point, for the debugger only")]
    fn record_term<R: RayRecorder>(
        &self,
        ray: &Ray,
        si: &SurfaceInteraction,
        point: LightPoint,
        ls: &LightSample,
        cos: f32,
        arrived: Color,
        ctx: &mut PathContext<R>,
    ) {
        let terms = self.shading_terms(si, ls.wi, -ray.dir, cos, point.model);
        let light = arrived * ls.color;
        ctx.recorder.light_term(&LightTerm {
            light: point.light,
            samples: point.samples,
            to: ls.point,
            model: point.model,
            kd: terms.diffuse_color,
            cos,
            ks: self.scene.materials[si.material as usize].ks,
            highlight: terms.highlight,
            light_color: ls.color,
            arrived,
            diffuse: light * terms.diffuse,
            specular: light * terms.specular,
        });
    }

    /// The shading model's BRDF times the cosine: its two terms added.
    #[inline]
    fn shading(&self, si: &SurfaceInteraction, wi: Vec3A, view: Vec3A, cos: f32, model: ShadingModel) -> Color {
        let terms = self.shading_terms(si, wi, view, cos, model);
        terms.diffuse + terms.specular
    }

    /// [`Integrator::shading`]'s two terms apart, with the diffuse colour and the highlight
    /// factor (the renderer adds the terms; the debugger shows them apart). The one formula of
    /// every model ([`ShadingModel`]):
    ///
    /// - diffuse: `kd (n.l)`; for the gradient model the gradient's colour at `n.l` (the ramp
    ///   from black to `kd` without a gradient, which is `kd (n.l)` again);
    /// - specular: `ks max(0, c)^shininess` with `c = r.v` (Phong, gradient), `c = n.h`
    ///   (Blinn-Phong), none for Lambert.
    #[inline(always)]
    fn shading_terms(&self, si: &SurfaceInteraction, wi: Vec3A, view: Vec3A, cos: f32, model: ShadingModel) -> Shading {
        let mat = &self.scene.materials[si.material as usize];
        let (diffuse_color, diffuse) = if model == ShadingModel::Gradient {
            // Without a gradient, the ramp from black at 0 to kd at 1, read at `cos`.
            let c = mat.gradient.as_ref().map_or(si.kd * cos, |g| g.at(cos));
            (c, c)
        } else {
            (si.kd, si.kd * cos)
        };
        let lobe = match model {
            ShadingModel::Phong | ShadingModel::Gradient => reflect(-wi, si.shading_normal).dot(view),
            ShadingModel::BlinnPhong => si.shading_normal.dot((wi + view).normalize()),
            ShadingModel::Lambert => 0.0,
        };
        let spec = lobe.max(0.0);
        let (specular, highlight) = if mat.ks == Color::ZERO || spec == 0.0 {
            (Color::ZERO, 0.0)
        } else {
            let highlight = spec.powf(mat.shininess);
            (mat.ks * highlight, highlight)
        };
        Shading { diffuse_color, diffuse, specular, highlight }
    }

    /// The fraction of light from `ls` that reaches `si` (all of it without shadows), as
    /// `vis`, the scene's view of the light from `si`, answers, or as the shadow ray traced
    /// ahead found (`blocked`, in an opaque scene: all or nothing).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn visibility<R: RayRecorder>(
        &self,
        si: &SurfaceInteraction,
        ls: &LightSample,
        time: f32,
        light: usize,
        vis: &LightVisibility,
        blocked: Option<bool>,
        ctx: &mut PathContext<R>,
    ) -> Color {
        if !self.settings.shadows {
            return Color::ONE;
        }
        ctx.counts.shadow += 1;
        // A recorder wants the ray's event and walk: it is traced again (the same answer).
        if let Some(blocked) = blocked.filter(|_| !R::RECORDS) {
            return if blocked { Color::ZERO } else { Color::ONE };
        }
        let ray = vis.shadow_ray(si, ls, time);
        if !R::RECORDS {
            return vis.transmittance(&ray);
        }
        let mut log = TraversalLog::default();
        let t = vis.transmittance_observed(&ray, si, &self.scene.lights[light], &mut log);
        // Only the debugger wants to know where the blocker is: an extra query, never paid
        // by normal renders.
        let blocked_at = if t == Color::ZERO { self.scene.intersect(&ray).map(|h| ray.at(h.t)) } else { None };
        ctx.recorder.shadow(&ShadowEvent {
            light,
            from: ray.origin,
            to: ls.point,
            light_color: ls.color,
            blocked_at,
            transmitted: t,
        });
        ctx.recorder.shadow_traversals(RecordedTraversal::from_log(self.scene, &log));
        t
    }
}

/// Primitives from which a scene's first shadow rays are traced ahead in packets
/// ([`Integrator::shadows_ahead`]). In smaller scenes a ray's walk is a node or two, cheaper
/// than the packet's set-up and the second pass over the hits: one packet rendered the
/// Cornell box (32 triangles) 10% slower and the shading-models spheres 10% slower, and the
/// monkey (968 triangles) 5% faster.
pub const SHADOWS_AHEAD_PRIMS: usize = 256;

/// Whether light point `ls` is on the lit side of `si` (`cos`: the shading normal's cosine
/// with it) and apart from it: a light point behind the surface (as seen from the viewer's
/// side) contributes nothing, and no shadow ray is needed to know that.
#[inline(always)]
fn faces(si: &SurfaceInteraction, ls: &LightSample, cos: f32) -> bool {
    !(cos <= 0.0 || si.geo_normal.dot(ls.wi) <= 0.0 || ls.distance <= 0.0)
}

/// The direction `ray` reflects to at `si`: about the shading normal, or about the geometric
/// normal where the shading normal would tilt it below the surface (the ray would then start
/// inside the object).
#[inline(always)]
fn mirror_dir(ray: &Ray, si: &SurfaceInteraction) -> Vec3A {
    let mirror = reflect(ray.dir, si.shading_normal).normalize();
    if mirror.dot(si.geo_normal) > 0.0 { mirror } else { reflect(ray.dir, si.geo_normal).normalize() }
}

/// What a ray sees at its closest hit, found before it is shaded: the hit, the surface
/// there, and the ray's footprint arrived there ([`Integrator::seen`]).
#[derive(Clone, Copy, Debug)]
pub struct Seen<C> {
    hit: Hit,
    si: SurfaceInteraction,
    cone: C,
}

/// What a hit's first rays, traced ahead of its shading, found: its shadow rays, one per
/// light shaded from one point ([`Integrator::first_shadows`]: bit `l` for light `l`), and its
/// mirror ray ([`Integrator::first_mirrors`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TracedAhead {
    /// The lights whose shadow ray was traced ahead.
    traced: u8,
    /// Those whose shadow ray was blocked.
    blocked: u8,
    /// Whether the hit's mirror ray hits nothing, if it was traced ahead.
    mirror: Option<bool>,
}

impl TracedAhead {
    /// Nothing traced.
    pub const NONE: TracedAhead = TracedAhead { traced: 0, blocked: 0, mirror: None };
    /// Lights that can be traced ahead (one bit each).
    pub const LIGHTS: usize = 8;

    /// Whether the shadow ray towards light `l` was blocked, if it was traced ahead.
    #[inline(always)]
    fn of(self, l: usize) -> Option<bool> {
        (l < Self::LIGHTS && self.traced >> l & 1 == 1).then_some(self.blocked >> l & 1 == 1)
    }
}

/// Tell the recorder that light point `ls` was skipped, and why (see
/// [`Integrator::record_term`] for why it is out of line).
#[cold]
#[inline(never)]
fn record_skip<R: RayRecorder>(
    si: &SurfaceInteraction,
    point: LightPoint,
    ls: &LightSample,
    cos: f32,
    ctx: &mut PathContext<R>,
) {
    if let Some(reason) = SkipReason::of(cos, si.geo_normal.dot(ls.wi), ls.distance) {
        ctx.recorder.light_skipped(&SkippedLight { light: point.light, to: ls.point, reason });
    }
}

/// Which light a light point belongs to, how many points that light is shaded with here, and
/// the model that shades them.
#[derive(Clone, Copy)]
struct LightPoint {
    light: usize,
    samples: u32,
    model: ShadingModel,
}

/// A shading model's two terms times the cosine, the diffuse colour and the highlight factor.
struct Shading {
    /// `kd`, or the gradient's colour at `n.l`.
    diffuse_color: Color,
    /// `kd (n.l)`, or the gradient's colour at `n.l`.
    diffuse: Color,
    /// `ks max(0, c)^shininess`, `c` the model's highlight cosine (zero for Lambert).
    specular: Color,
    /// `max(0, c)^shininess` (0 when `ks` is black, not computed then).
    highlight: f32,
}

/// A direction around unit vector `axis` with density `(n + 1) / 2pi * cos^n(alpha)`, where
/// `alpha` is the angle to the axis, from uniform numbers `u`.
pub fn sample_phong_lobe(axis: Vec3A, n: f32, u: Vec2) -> Vec3A {
    let cos = u.x.powf(1.0 / (n + 1.0));
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (sin_phi, cos_phi) = crate::math::sin_cos_turns(u.y);
    let (t1, t2) = axis.any_orthonormal_pair();
    (sin * cos_phi) * t1 + (sin * sin_phi) * t2 + cos * axis
}
