//! Visibility between surface points and light points: the one door every shadow ray goes
//! through. The integrator asks [`Scene::light_visibility`] once per shading point and light,
//! and within it [`LightVisibility::transmittance`] for each point of the light it samples; it
//! never sees the BVH. Whether a point's shadow rays share one BVH query (the grouping of
//! [`crate::bvh::Occluders`]) is decided here alone, and a grouped answer is the same, bit for
//! bit, as tracing the ray alone.

use super::{Scene, SurfaceInteraction};
use crate::bvh::{NoObserver, Occluders, QueryKind, TraversalObserver};
use crate::light::{Light, LightSample};
use crate::math::Color;
use crate::ray::{Interval, Ray};
use crate::settings::ShadingOptions;

/// Light samples per shading point from which their shadow rays share one BVH query; below
/// it, the query costs more than it saves.
const GROUP_SHADOW_RAYS: u32 = 4;

/// What reaches one surface point from the points of one light, as [`Scene::light_visibility`]
/// lends it: [`LightVisibility::transmittance`] answers for each shadow ray made by
/// [`LightVisibility::shadow_ray`].
#[derive(Clone, Copy, Debug)]
pub struct LightVisibility<'a> {
    scene: &'a Scene,
    options: &'a ShadingOptions,
    /// What the shadow rays may cross, when they share one query; `None`: each ray is traced
    /// alone.
    group: Option<&'a Occluders>,
}

impl Scene {
    /// Call `f` with the visibility of `light` from surface point `si` (whose geometric normal
    /// faces the viewer), for `rays` shadow rays towards points of the light (1 for a single
    /// point, 0 when none will be cast); `options` shade the transparent surfaces that shadow
    /// rays look through. Returns what `f` does.
    ///
    /// Many rays share one BVH query, except in scenes with transparent surfaces (whose
    /// shadows need every surface crossed), from inside the light's bounds, or with a cluttered
    /// view of it. The query's list (1.6 KB) is lent to `f` where the query wrote it: a
    /// visibility returned by value copied it once more per shading point (1% more
    /// instructions in the sphere-lit Cornell box).
    #[inline(always)]
    pub fn light_visibility<T>(
        &self,
        si: &SurfaceInteraction,
        light: &Light,
        rays: u32,
        options: &ShadingOptions,
        f: impl FnOnce(&LightVisibility) -> T,
    ) -> T {
        let group = if rays >= GROUP_SHADOW_RAYS { self.shadow_group(si, light) } else { None };
        f(&LightVisibility { scene: self, options, group: group.as_ref() })
    }

    /// What shadow rays from `si` to points of `light` may cross, so that they share one BVH
    /// query; `None` where each must be traced alone.
    #[inline]
    fn shadow_group(&self, si: &SurfaceInteraction, light: &Light) -> Option<Occluders> {
        self.shadow_group_counted(si, light, &mut NoObserver)
    }

    /// [`Scene::shadow_group`], reporting the group's query to `obs`.
    #[inline]
    fn shadow_group_counted<O: TraversalObserver>(
        &self,
        si: &SurfaceInteraction,
        light: &Light,
        obs: &mut O,
    ) -> Option<Occluders> {
        if self.has_transparency {
            return None;
        }
        // The rays all leave from one origin (the lit side's offset: rays to the other side are
        // never cast), which is the apex of the group's query.
        let apex = Ray::spawn_origin(si.point, si.geo_normal, si.geo_normal);
        let (center, radius) = light.bounding_sphere();
        self.geometry.wide.occluders_counted(apex, si.geo_normal, center, radius, obs)
    }

    /// Whether anything lies on `ray` within its interval.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.geometry.occluded(ray)
    }

    /// Which of up to [`crate::bvh::PACKET`] shadow rays made by
    /// [`LightVisibility::shadow_ray`] (each traced alone: no group) are blocked, in a scene
    /// without transparent surfaces: bit `i` is set when [`Scene::transmittance`] of `rays[i]`
    /// is zero (it is one otherwise). The rays go through the tree together.
    pub fn blocked_packet(&self, rays: &[Ray]) -> u32 {
        debug_assert!(!self.has_transparency, "shadow rays through transparent surfaces are traced alone");
        self.geometry.occluded_packet(rays)
    }

    /// Fraction of light that passes from a surface point along `ray` (a shadow ray): zero
    /// when an opaque surface blocks it; through transparent surfaces, the product of
    /// `kd * (1 - d)` of each surface crossed (coloured shadows, as in the course).
    pub fn transmittance(&self, ray: &Ray, options: &ShadingOptions) -> Color {
        self.transmittance_counted(ray, options, &mut NoObserver)
    }

    /// [`Scene::transmittance`], reporting to `obs` each query of the wide BVH it makes: one
    /// any-hit query, or through transparent surfaces one closest-hit query per surface
    /// crossed.
    ///
    /// Inlined for the opaque scene's one any-hit query, so that its answer reaches the
    /// shading in registers: returned through memory from a call, the colour was stored as
    /// `x, y` and `z` and read back as `x` and `y, z`, a load no store forwards (1.4% of the
    /// dragon's render in a profile; inlined, the teapot's render was 3% faster).
    #[inline(always)]
    pub fn transmittance_counted<O: TraversalObserver>(
        &self,
        ray: &Ray,
        options: &ShadingOptions,
        obs: &mut O,
    ) -> Color {
        if !self.has_transparency {
            return if self.geometry.occluded_counted(ray, obs) { Color::ZERO } else { Color::ONE };
        }
        self.transmittance_through(ray, options, obs)
    }

    /// [`Scene::transmittance_counted`] in a scene with transparent surfaces: one closest-hit
    /// query per surface crossed.
    #[inline(never)]
    fn transmittance_through<O: TraversalObserver>(&self, ray: &Ray, options: &ShadingOptions, obs: &mut O) -> Color {
        let mut t = Color::ONE;
        let mut r = *ray;
        // Each surface crossed moves the ray past it; the bound guards against a loop on
        // pathological input (coincident transparent surfaces).
        for _ in 0..64 {
            let Some(hit) = self.geometry.intersect(&r, obs) else {
                return t;
            };
            let mat = &self.materials[self.geometry.slots[hit.slot as usize].material as usize];
            if mat.transparency >= 1.0 {
                return Color::ZERO;
            }
            let si = self.surface(&r, &hit, options);
            t *= si.kd * (1.0 - mat.transparency);
            if t.max_element() <= 0.0 {
                return Color::ZERO;
            }
            let next = Ray::spawn(si.point, si.geo_normal, r.dir, r.time);
            let travelled = (next.origin - r.origin).dot(r.dir);
            r = Ray { t: Interval { min: 0.0, max: r.t.max - travelled }, ..next };
        }
        Color::ZERO
    }
}

impl LightVisibility<'_> {
    /// The shadow ray from `si`, the surface point this was made for, to the light point `ls`
    /// (which must be on the side of its geometric normal, as every ray this answers must
    /// be), at shutter time `time`.
    #[inline(always)]
    pub fn shadow_ray(&self, si: &SurfaceInteraction, ls: &LightSample, time: f32) -> Ray {
        Ray::spawn_towards(si.point, si.geo_normal, ls.wi, ls.distance, time)
    }

    /// The fraction of light that passes along `ray`, a [`LightVisibility::shadow_ray`]: what
    /// [`Scene::transmittance`] gives, through the group's list where there is one (no
    /// transparency then, so all or nothing).
    #[inline(always)]
    pub fn transmittance(&self, ray: &Ray) -> Color {
        self.transmittance_counted(ray, &mut NoObserver)
    }

    /// [`LightVisibility::transmittance`] of a shadow ray from `si` to a point of `light` (the
    /// surface point and light this was made for), reporting to `obs` how it was answered: a
    /// grouped ray runs no traversal of its own, so `obs` is told a
    /// [`QueryKind::ShadowGroup`] query with what its group's frustum query entered (that
    /// query run again with the observer: the same inputs, the same visits); a ray traced
    /// alone, what [`Scene::transmittance_counted`] tells.
    #[inline(always)]
    pub fn transmittance_observed<O: TraversalObserver>(
        &self,
        ray: &Ray,
        si: &SurfaceInteraction,
        light: &Light,
        obs: &mut O,
    ) -> Color {
        if O::WATCHES && self.group.is_some() {
            obs.query(QueryKind::ShadowGroup, ray);
            self.scene.shadow_group_counted(si, light, obs);
        }
        self.transmittance_counted(ray, obs)
    }

    /// [`LightVisibility::transmittance`], reporting a ray traced alone to `obs`.
    #[inline(always)]
    fn transmittance_counted<O: TraversalObserver>(&self, ray: &Ray, obs: &mut O) -> Color {
        match self.group {
            Some(occ) => {
                if self.scene.geometry.occluded_among(ray, occ) {
                    Color::ZERO
                } else {
                    Color::ONE
                }
            }
            None => self.scene.transmittance_counted(ray, self.options, obs),
        }
    }
}
