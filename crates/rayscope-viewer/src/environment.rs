//! The environment map in the viewer: the command line's `--env-*` flags kept across scene
//! loads ([`EnvOverride`]), the *Environment map* panel, the texel a missed ray read drawn on
//! a sphere around the scene ([`texel_lines`]), and the map seen through the camera as the
//! raster view's background ([`background`]).

use egui::Ui;
use rayscope::camera::{Camera, RayGenerator};
use rayscope::environment::{Environment, EnvironmentLookup};
use rayscope::math::{Vec2, Vec3};
use rayscope::scene::Scene;
use rayscope::settings::TextureFilter;

use crate::overlay::Lines;
use crate::state::ViewerState;

/// What the command line (or the panel) sets over the scene file's `[environment]`: a map of
/// its own, and its intensity and rotation. Applied to every scene loaded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EnvOverride {
    /// A map in place of the scene's (`--env-map`).
    pub map: Option<Environment>,
    /// The factor on the map's values (`--env-intensity`).
    pub intensity: Option<f32>,
    /// The rotation about +y in degrees (`--env-rotation`).
    pub rotation: Option<f32>,
}

impl EnvOverride {
    /// Set `scene`'s environment as overridden.
    pub fn apply(&self, scene: &mut Scene) {
        if let Some(map) = &self.map {
            scene.environment = Some(map.clone());
        }
        if let Some(env) = scene.environment.as_mut() {
            if let Some(i) = self.intensity {
                env.set_intensity(i);
            }
            if let Some(r) = self.rotation {
                env.set_rotation(r);
            }
        }
    }
}

/// The *Environment map* panel: the map's file and size, its intensity and rotation (a change
/// reloads the scene with them, on release of the slider).
pub fn panel(ui: &mut Ui, st: &mut ViewerState) {
    let Some(env) = st.scene.environment.clone() else {
        ui.label("none: rays that miss return the background colour")
            .on_hover_text("Give one with --env-map FILE or [environment] path = \"sky.hdr\" in a scene file");
        return;
    };
    let t = env.texture();
    ui.label(format!("{} ({}x{})", env.desc.path.display(), t.width, t.height)).on_hover_text(
        "The equirectangular map rays that miss return: the background, and what mirrors reflect. It is not a \
         light source: shadow rays and direct light do not see it. Its centre lies along -z, +y up",
    );
    let (mut intensity, mut rotation) = (env.desc.intensity, env.desc.rotation);
    let i = ui
        .add(egui::Slider::new(&mut intensity, 0.0..=16.0).logarithmic(true).text("Intensity"))
        .on_hover_text("Factor on the map's values (--env-intensity)");
    let r = ui
        .add(egui::Slider::new(&mut rotation, -180.0..=180.0).suffix("°").text("Rotation"))
        .on_hover_text("Turn the map about +y, right-handed: at +90 its centre moves from -z to -x (--env-rotation)");
    if i.drag_stopped() || r.drag_stopped() || (i.changed() && !i.dragged()) || (r.changed() && !r.dragged()) {
        st.env.intensity = Some(intensity);
        st.env.rotation = Some(rotation);
        st.reload();
    }
}

/// For a ray from `origin` that read the map as `lookup`: its direction drawn out to the
/// sphere of radius `reach` around `origin` (the map lies at infinity: only the direction
/// counts), the texel it read outlined there in the texel's colour, and the sphere's circles
/// through that point (its latitude and meridian), faint.
pub fn texel_lines(out: &mut Lines, env: &Environment, origin: Vec3, lookup: &EnvironmentLookup, reach: f32) {
    let t = env.texture();
    let (w, h) = (t.width as f32, t.height as f32);
    let [tx, ty] = lookup.texel.map(|v| v as f32);
    let at = |u: f32, v: f32| origin + Vec3::from(env.direction(Vec2::new(u / w, v / h))) * reach;
    let c = lookup.radiance / lookup.radiance.max_element().max(1.0);
    let color = [c.x.max(0.15), c.y.max(0.15), c.z.max(0.15), 1.0];
    // Each edge of the texel in steps, so that it follows the sphere.
    const STEPS: usize = 6;
    let corners = [(tx, ty), (tx + 1.0, ty), (tx + 1.0, ty + 1.0), (tx, ty + 1.0), (tx, ty)];
    for pair in corners.windows(2) {
        let ((u0, v0), (u1, v1)) = (pair[0], pair[1]);
        for s in 0..STEPS {
            let (a, b) = (s as f32 / STEPS as f32, (s + 1) as f32 / STEPS as f32);
            out.line(at(u0 + (u1 - u0) * a, v0 + (v1 - v0) * a), at(u0 + (u1 - u0) * b, v0 + (v1 - v0) * b), color);
        }
    }
    let faint = [0.55, 0.55, 0.6, 0.5];
    let [u, v] = lookup.uv;
    const ROUND: usize = 48;
    for s in 0..ROUND {
        let (a, b) = (s as f32 / ROUND as f32, (s + 1) as f32 / ROUND as f32);
        out.line(at(a * w, v * h), at(b * w, v * h), faint);
        out.line(at(u * w, a * h), at(u * w, b * h), faint);
    }
}

/// The map as the camera sees it, `width x height` pixels (linear values clamped to 8 bits,
/// as the ray-traced view shows them): what camera rays that miss return.
pub fn background(env: &Environment, camera: &Camera, width: u32, height: u32) -> egui::ColorImage {
    let rays = RayGenerator::new(camera, width, height);
    let mut rgba = Vec::with_capacity((width * height * 4) as usize);
    for y in 0..height {
        for x in 0..width {
            let c = env.radiance(rays.ray(x, y, Vec2::splat(0.5)).dir, TextureFilter::Bilinear);
            let c = (c.clamp(Vec3::ZERO, Vec3::ONE) * 255.0).round();
            rgba.extend([c.x as u8, c.y as u8, c.z as u8, 255]);
        }
    }
    egui::ColorImage::from_rgba_unmultiplied([width as usize, height as usize], &rgba)
}

/// The raster view's background ([`background`]), made again only when the scene or the
/// camera changes.
#[derive(Default)]
pub struct BackgroundCache {
    /// The scene (its address) and camera it shows.
    key: Option<(usize, Camera)>,
    texture: Option<egui::TextureHandle>,
}

/// The longer side of [`BackgroundCache`]'s image: the map is smooth, and the texture is
/// stretched over the view with linear filtering.
const BACKGROUND_SIDE: u32 = 320;

impl BackgroundCache {
    /// The texture of `scene`'s map seen by `camera` in an image of `aspect` (width / height),
    /// or `None` when the scene has no map.
    pub fn texture(
        &mut self,
        ctx: &egui::Context,
        scene: &std::sync::Arc<Scene>,
        camera: &Camera,
        aspect: f32,
    ) -> Option<egui::TextureId> {
        let env = scene.environment.as_ref()?;
        let key = (std::sync::Arc::as_ptr(scene) as usize, *camera);
        if self.key != Some(key) || self.texture.is_none() {
            let (w, h) = if aspect >= 1.0 {
                (BACKGROUND_SIDE, ((BACKGROUND_SIDE as f32 / aspect).round() as u32).max(1))
            } else {
                (((BACKGROUND_SIDE as f32 * aspect).round() as u32).max(1), BACKGROUND_SIDE)
            };
            let img = background(env, camera, w, h);
            match &mut self.texture {
                Some(t) => t.set(img, egui::TextureOptions::LINEAR),
                None => {
                    self.texture = Some(ctx.load_texture("rayscope environment", img, egui::TextureOptions::LINEAR))
                }
            }
            self.key = Some(key);
        }
        self.texture.as_ref().map(|t| t.id())
    }
}
