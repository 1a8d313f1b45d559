//! The Whitted integrator in the course's form: Phong direct lighting with shadow rays,
//! recursive mirror reflection weighted by `ks`, and transparency blended by `1 - d`.

use crate::math::{Color, Vec3A, reflect};
use crate::ray::Ray;
use crate::record::{RayKind, RayRecorder, RecordedHit};
use crate::render::RenderSettings;
use crate::scene::{Scene, SurfaceInteraction};

/// Counts of rays cast, for throughput figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera, reflection and transmission rays (closest-hit queries).
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

/// Traces rays through one scene with one set of settings.
pub struct Integrator<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// The settings.
    pub settings: &'a RenderSettings,
}

impl<'a> Integrator<'a> {
    /// An integrator for this scene and these settings.
    pub fn new(scene: &'a Scene, settings: &'a RenderSettings) -> Self {
        Integrator { scene, settings }
    }

    /// The colour arriving along `ray`, cast for reason `kind` at recursion `depth`.
    pub fn li<R: RayRecorder>(
        &self,
        ray: &Ray,
        kind: RayKind,
        depth: u32,
        rec: &mut R,
        counts: &mut RayCounts,
    ) -> Color {
        rec.begin_ray(kind, depth, ray);
        counts.primary_and_secondary += 1;
        let color = match self.scene.intersect(ray) {
            None => {
                rec.hit(None);
                self.settings.background
            }
            Some(hit) => {
                let si = self.scene.surface(ray, &hit, self.settings);
                rec.hit(Some(RecordedHit {
                    t: hit.t,
                    point: si.point.to_array(),
                    prim: hit.prim,
                    material: si.material,
                    geo_normal: si.geo_normal.to_array(),
                    shading_normal: si.shading_normal.to_array(),
                }));
                self.shade(ray, &si, depth, rec, counts)
            }
        };
        rec.end_ray(color);
        color
    }

    fn shade<R: RayRecorder>(
        &self,
        ray: &Ray,
        si: &SurfaceInteraction,
        depth: u32,
        rec: &mut R,
        counts: &mut RayCounts,
    ) -> Color {
        let s = self.settings;
        let mat = &self.scene.materials[si.material as usize];
        if !s.shading {
            // The course's "shading off" view: the diffuse colour as it is.
            return si.kd;
        }
        let mut color = self.direct(ray, si, rec, counts);
        let recurse = depth < s.max_depth;
        if recurse && s.reflections && mat.ks.max_element() > 0.0 {
            let dir = reflect(ray.dir, si.shading_normal).normalize();
            // A shading normal can tilt the mirror direction below the surface; such a ray
            // would start inside the object, so reflect about the geometric normal instead.
            let dir = if dir.dot(si.geo_normal) > 0.0 {
                dir
            } else {
                reflect(ray.dir, si.geo_normal).normalize()
            };
            let r = Ray::spawn(si.point, si.geo_normal, dir, ray.time);
            color += mat.ks * self.li(&r, RayKind::Reflection, depth + 1, rec, counts);
        }
        if recurse && s.transparency && mat.transparency < 1.0 {
            let r = Ray::spawn(si.point, si.geo_normal, ray.dir, ray.time);
            let behind = self.li(&r, RayKind::Transmission, depth + 1, rec, counts);
            color = mat.transparency * color + (1.0 - mat.transparency) * behind;
        }
        color
    }

    /// Phong direct lighting from every light, each shaded from its centre, with shadow rays.
    fn direct<R: RayRecorder>(&self, ray: &Ray, si: &SurfaceInteraction, rec: &mut R, counts: &mut RayCounts) -> Color {
        let mut sum = Color::ZERO;
        let view = -ray.dir;
        for (i, light) in self.scene.lights.iter().enumerate() {
            let ls = light.center_sample(si.point);
            let cos = si.shading_normal.dot(ls.wi);
            // A light behind the surface (as seen from the viewer's side) contributes nothing;
            // no shadow ray is needed to know that.
            if cos <= 0.0 || si.geo_normal.dot(ls.wi) <= 0.0 {
                continue;
            }
            let arrived = self.visibility(si, ls.point, ray.time, i, rec, counts);
            if arrived == Color::ZERO {
                continue;
            }
            sum += arrived * ls.color * self.phong(si, ls.wi, view, cos);
        }
        sum
    }

    /// The Phong BRDF times the cosine: `kd (n.l) + ks max(0, r.v)^shininess`.
    #[inline]
    fn phong(&self, si: &SurfaceInteraction, wi: Vec3A, view: Vec3A, cos: f32) -> Color {
        let mat = &self.scene.materials[si.material as usize];
        let diffuse = si.kd * cos;
        let r = reflect(-wi, si.shading_normal);
        let spec = r.dot(view).max(0.0);
        let specular = if mat.ks == Color::ZERO || spec == 0.0 {
            Color::ZERO
        } else {
            mat.ks * spec.powf(mat.shininess)
        };
        diffuse + specular
    }

    /// The fraction of light from `target` that reaches `si` (all of it without shadows).
    fn visibility<R: RayRecorder>(
        &self,
        si: &SurfaceInteraction,
        target: Vec3A,
        time: f32,
        light: usize,
        rec: &mut R,
        counts: &mut RayCounts,
    ) -> Color {
        if !self.settings.shadows {
            return Color::ONE;
        }
        counts.shadow += 1;
        let ray = Ray::spawn_to(si.point, si.geo_normal, target, time);
        let t = self.scene.transmittance(&ray, self.settings);
        if R::RECORDS {
            // Only the debugger wants to know where the blocker is: an extra query, never paid
            // by normal renders.
            let blocked_at = if t == Color::ZERO {
                self.scene.intersect(&ray).map(|h| ray.at(h.t))
            } else {
                None
            };
            rec.shadow(light, ray.origin, target, blocked_at, t);
        }
        t
    }
}
