//! What a ray that hits nothing returns: the settings' background colour ([`Background`]) or
//! an environment map's radiance in its direction. A type parameter of the integrator, chosen
//! once per render, so that a scene without a map compiles to the very miss path (and the
//! inlining) it had before maps existed: a branch per miss on an `Option` tipped the
//! renderer's sample loop over the inliner's budget (2.9% more instructions on the Cornell
//! box).

use crate::environment::Environment;
use crate::math::Color;
use crate::ray::Ray;
use crate::record::RayRecorder;
use crate::settings::RenderSettings;

/// What rays that miss return.
pub trait Sky: Copy + Sync {
    /// The colour arriving along `ray`, which hit nothing, told to `recorder` when it records.
    fn miss<R: RayRecorder>(&self, ray: &Ray, settings: &RenderSettings, recorder: &mut R) -> Color;

    /// The colour every missing ray returns, when it does not depend on the ray (rendering
    /// then fills the pixels of a tile whose camera rays cannot hit anything without tracing
    /// them); `None` where it does (the default).
    fn uniform(&self, _settings: &RenderSettings) -> Option<Color> {
        None
    }
}

/// The settings' background colour, the same in every direction.
#[derive(Clone, Copy, Debug, Default)]
pub struct Background;

impl Sky for Background {
    #[inline(always)]
    fn miss<R: RayRecorder>(&self, _ray: &Ray, settings: &RenderSettings, _recorder: &mut R) -> Color {
        settings.background
    }

    fn uniform(&self, settings: &RenderSettings) -> Option<Color> {
        Some(settings.background)
    }
}

impl Sky for &Environment {
    /// The map's radiance in the ray's direction (filtered as textures are), and, for the
    /// debugger, the texel it read.
    #[inline]
    fn miss<R: RayRecorder>(&self, ray: &Ray, settings: &RenderSettings, recorder: &mut R) -> Color {
        if R::RECORDS {
            let lookup = self.lookup(ray.dir, settings.texture_filter);
            recorder.environment(&lookup);
            return lookup.radiance;
        }
        self.radiance(ray.dir, settings.texture_filter)
    }
}
