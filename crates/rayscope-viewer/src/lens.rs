//! Depth of field in the viewer: the lens's panel, Alt-click to focus on the clicked surface,
//! and the focal plane as overlay lines (the selected pixel's lens rays, which the debugger
//! records as the renderer casts them, converge on it).

use egui::Ui;
use glam::Vec3;
use rayscope::camera::{Camera, RayGenerator};
use rayscope::math::Vec2;
use rayscope::scene::Scene;
use rayscope::settings::RenderSettings;

use crate::overlay::Lines;
use crate::state::ViewerState;

/// The focal plane's colour: a grid drawn at the focus distance (faded where the scene is in
/// front of it, as every hidden overlay line is).
pub const FOCAL_PLANE_COLOR: [f32; 4] = [0.95, 0.6, 1.0, 0.9];

/// Cells of the focal plane's grid along each side.
const GRID_CELLS: u32 = 8;

/// The lens controls: aperture (lens radius) and focus distance, with `look_distance` (the
/// camera's look-at distance) as the focus when none is set.
pub fn lens_panel(ui: &mut Ui, s: &mut RenderSettings, look_distance: f32) {
    ui.add(egui::Slider::new(&mut s.aperture, 0.0..=0.5).logarithmic(true).smallest_positive(1e-3).text("Aperture"))
        .on_hover_text(
            "Lens radius in scene units (depth of field); 0 is a pinhole, everything sharp. Alt-click the image \
             to focus on the surface under the mouse",
        );
    let mut fixed = s.focus_distance.is_some();
    ui.checkbox(&mut fixed, "Set focus distance").on_hover_text(
        "Off: the lens focuses on the camera's look-at point (it follows zoom); on: at the distance below",
    );
    let mut d = s.focus_distance.unwrap_or(look_distance);
    ui.add_enabled(fixed, egui::DragValue::new(&mut d).range(1e-3..=1e6).speed(0.01).prefix("focus distance "))
        .on_hover_text("Depth of the plane in focus, along the view axis, in scene units");
    s.focus_distance = fixed.then_some(d);
}

/// Alt-click: focus the lens on the surface under pixel `(x, y)` as the trackball sees it
/// (restarting the accumulation). Returns the status line to show.
pub fn focus_at(state: &mut ViewerState, x: u32, y: u32) -> String {
    let (w, h) = (state.settings.width, state.settings.height);
    match depth_at(&state.scene, &state.trackball.camera(), x, y, w, h) {
        Some(d) => {
            let settings = RenderSettings { focus_distance: Some(d), ..state.settings.clone() };
            state.set_settings(settings);
            let hint = if state.settings.aperture > 0.0 { "" } else { " (set an aperture to see the blur)" };
            format!("focus distance {d:.3}{hint}")
        }
        None => format!("pixel ({x}, {y}) sees no surface to focus on"),
    }
}

/// What the focal plane's lines depend on (for the overlay's cache): the lens and the camera,
/// as bits; `None` for a pinhole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FocalKey([u32; 12]);

impl FocalKey {
    /// The key of `settings`' focal plane seen through `camera`.
    pub fn new(settings: &RenderSettings, camera: &Camera) -> Option<FocalKey> {
        let lens = rayscope::lens::ThinLens::new(settings, camera)?;
        let p = camera.position;
        let q = camera.rotation;
        let floats = [lens.focus_distance, camera.fov_y, p.x, p.y, p.z, q.x, q.y, q.z, q.w];
        let mut key = [settings.width, settings.height, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        for (k, f) in key[2..].iter_mut().zip(floats) {
            *k = f.to_bits();
        }
        Some(FocalKey(key))
    }
}

/// The depth along `camera`'s view axis of the surface seen at the centre of pixel `(x, y)`
/// of a `width x height` image (the pinhole's ray), or `None` where it sees nothing.
pub fn depth_at(scene: &Scene, camera: &Camera, x: u32, y: u32, width: u32, height: u32) -> Option<f32> {
    let ray = camera.pixel_ray(x, y, width, height);
    let hit = scene.intersect(&ray)?;
    let forward = camera.rotation * glam::Vec3::Z;
    Some(hit.t * Vec3::from(ray.dir).dot(forward))
}

/// The focal plane of `settings`' lens seen through `camera` as a grid over the image's
/// frustum at the focus distance; nothing for a pinhole.
pub fn focal_plane_lines(out: &mut Lines, camera: &Camera, settings: &RenderSettings) {
    let Some(lens) = rayscope::lens::ThinLens::new(settings, camera) else { return };
    let (w, h) = (settings.width, settings.height);
    let rays = RayGenerator::new(camera, w, h);
    let forward = camera.rotation * Vec3::Z;
    // The point at the focus depth on the ray through image point (u, v) in [0, 1]^2.
    let at = |u: f32, v: f32| {
        let r = rays.ray(0, 0, Vec2::new(u * w as f32, v * h as f32));
        let d = Vec3::from(r.dir);
        Vec3::from(r.origin) + d * (lens.focus_distance / d.dot(forward))
    };
    for i in 0..=GRID_CELLS {
        let t = i as f32 / GRID_CELLS as f32;
        out.line(at(t, 0.0), at(t, 1.0), FOCAL_PLANE_COLOR);
        out.line(at(0.0, t), at(1.0, t), FOCAL_PLANE_COLOR);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayscope::camera::CameraDesc;
    use rayscope::scene::builtin;

    #[test]
    fn the_focal_plane_lies_at_the_focus_depth() {
        let camera = Camera::from_desc(&CameraDesc::default());
        let forward = camera.rotation * Vec3::Z;
        let mut out = Lines::default();
        let pinhole = RenderSettings { width: 40, height: 30, ..RenderSettings::default() };
        focal_plane_lines(&mut out, &camera, &pinhole);
        assert!(out.0.is_empty(), "a pinhole has no focal plane");
        let lens = RenderSettings { aperture: 0.1, focus_distance: Some(2.5), ..pinhole };
        focal_plane_lines(&mut out, &camera, &lens);
        assert_eq!(out.0.len(), 4 * (GRID_CELLS as usize + 1));
        for v in &out.0 {
            let depth = (Vec3::from_array(v.pos) - Vec3::from(camera.position)).dot(forward);
            assert!((depth - 2.5).abs() < 1e-4, "{depth}");
        }
    }

    #[test]
    fn alt_click_depth_is_the_hit_along_the_view_axis() {
        let scene = Scene::load("cornell-box", None).unwrap();
        let camera = Camera::from_desc(&builtin::scene_desc("cornell-box").unwrap().camera);
        let d = depth_at(&scene, &camera, 20, 20, 40, 40).expect("the box is in the middle");
        let ray = camera.pixel_ray(20, 20, 40, 40);
        let hit = scene.intersect(&ray).unwrap();
        let p = Vec3::from(ray.origin + ray.dir * hit.t);
        assert!(((p - Vec3::from(camera.position)).dot(camera.rotation * Vec3::Z) - d).abs() < 1e-5);
        assert!(depth_at(&scene, &camera, 0, 0, 40, 40).is_none(), "the corner sees the background");
    }
}
