//! The viewer's state and logic, apart from any window: the scene, the camera, the settings,
//! the imaging mode, the selected pixel with its ray tree, and the overlay lines the
//! debugger draws. Everything here is tested without a display.

use std::path::PathBuf;
use std::sync::Arc;

use egui::{Pos2, Rect};
use glam::Vec3;
use rayscope::camera::CameraMotion;
use rayscope::light::Light;
use rayscope::math::Vec3A;
use rayscope::progressive::ImagingMode;
use rayscope::record::{RayKind, RayTree};
use rayscope::render::trace_pixel;
use rayscope::scene::{Scene, builtin};
use rayscope::settings::RenderSettings;

use crate::preview::LineVertex;
use crate::trackball::Trackball;

/// The most rays (shadow rays included) the viewer records for a debugged pixel, a tenth of
/// `rayscope debug`'s bound: the 3D view draws every recorded ray in every frame.
pub const RECORDED_RAYS: usize = 10_000;

/// Which image the viewport shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewKind {
    /// The rasterized GPU preview with the debugger's overlays.
    Raster,
    /// The ray-traced image.
    RayTraced,
    /// BVH nodes visited per pixel.
    HeatMap,
    /// With `--compare`: their image (see [`crate::compare`]).
    Theirs,
    /// With `--compare`: our render compared with it.
    Ours,
    /// With `--compare`: the difference image.
    Difference,
}

/// The imaging mode as the panel offers it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModeChoice {
    /// Each frame fresh.
    Continuous,
    /// Running average, restarted by changes.
    Dynamic,
    /// A fixed number of frames; camera moves blur.
    Exposure,
}

/// The debugged pixel.
#[derive(Clone, Debug)]
pub struct Selection {
    /// Pixel `(x, y)`, row 0 at the top.
    pub pixel: (u32, u32),
    /// Every ray of its first sample, as the renderer traced them.
    pub tree: RayTree,
    /// The sample's colour.
    pub color: Vec3,
    /// BVH nodes the camera ray entered.
    pub visited: Vec<u32>,
    /// Distinguishes this selection from every other one (for [`OverlayKey`]).
    pub id: u64,
}

/// What [`ViewerState::overlay_lines`] depends on: while it is the same, so are the lines,
/// and the viewer draws the ones it made (and uploaded) before instead of making them for
/// every frame, which the deep BVH levels of a large mesh made slow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OverlayKey {
    scene: usize,
    bvh_level: Option<u32>,
    bvh_only_visited: bool,
    show_light_samples: bool,
    selection: Option<u64>,
}

/// Everything the viewer shows and edits.
pub struct ViewerState {
    /// The asset folder for built-in scenes that need course files.
    pub assets: Option<PathBuf>,
    /// What was loaded: a built-in name or a file path.
    pub scene_spec: String,
    /// The loaded scene.
    pub scene: Arc<Scene>,
    /// The last loading error, shown in the window.
    pub error: Option<String>,
    /// The interactive camera.
    pub trackball: Trackball,
    /// Render settings (`spp` is samples per frame).
    pub settings: RenderSettings,
    /// Imaging mode.
    pub mode: ModeChoice,
    /// Frames in an exposure.
    pub exposure_frames: u32,
    /// Dynamic mode stops at this many samples per pixel.
    pub max_spp: u32,
    /// What the viewport shows.
    pub view: ViewKind,
    /// The debugged pixel.
    pub selection: Option<Selection>,
    /// BVH level drawn, if any.
    pub bvh_level: Option<u32>,
    /// Draw only the BVH nodes the selected camera ray entered.
    pub bvh_only_visited: bool,
    /// Draw the selected pixel's light samples.
    pub show_light_samples: bool,
    /// Bumped whenever the accumulation must restart.
    pub generation: u64,
    /// An image compared with ours (`--compare`), and its views.
    pub compare: Option<crate::compare::CompareViews>,
}

impl ViewerState {
    /// Load `spec` (a built-in name, a `.toml` or an `.obj`). A scene that fails to load leaves
    /// the default scene in place and the error in [`ViewerState::error`].
    pub fn new(spec: &str, assets: Option<PathBuf>) -> ViewerState {
        let fallback = Scene::load(builtin::DEFAULT_SCENE, None).expect("the default scene needs no file");
        let mut s = ViewerState {
            assets,
            scene_spec: builtin::DEFAULT_SCENE.into(),
            trackball: Trackball::from_desc(&fallback.camera),
            scene: Arc::new(fallback),
            error: None,
            settings: RenderSettings::default(),
            mode: ModeChoice::Dynamic,
            exposure_frames: 16,
            max_spp: 256,
            view: ViewKind::Raster,
            selection: None,
            bvh_level: None,
            bvh_only_visited: false,
            show_light_samples: true,
            generation: 0,
            compare: None,
        };
        s.load_scene(spec);
        s
    }

    /// Load another scene; on failure keep the current one and record the error.
    pub fn load_scene(&mut self, spec: &str) {
        match Scene::load(spec, self.assets.as_deref()) {
            Ok(scene) => {
                self.trackball = Trackball::from_desc(&scene.camera);
                self.settings = RenderSettings {
                    width: self.settings.width,
                    height: self.settings.height,
                    ..scene.render.clone().unwrap_or_default()
                };
                self.scene = Arc::new(scene);
                self.scene_spec = spec.to_string();
                self.error = None;
                self.selection = None;
                self.bvh_level = self.bvh_level.map(|l| l.min(self.bvh_levels()));
                self.generation += 1;
            }
            Err(e) => self.error = Some(format!("{e}")),
        }
    }

    /// Load the current scene again (its files changed), keeping the camera, the settings and
    /// the selected pixel.
    pub fn reload(&mut self) {
        let (trackball, settings, selection) = (self.trackball, self.settings.clone(), self.selection.clone());
        let spec = self.scene_spec.clone();
        self.load_scene(&spec);
        if self.error.is_none() {
            self.trackball = trackball;
            self.settings = settings;
            self.selection = selection;
            self.retrace();
        }
    }

    /// The scene file behind the current scene, if it came from one (to watch for changes).
    pub fn scene_file(&self) -> Option<PathBuf> {
        let p = PathBuf::from(&self.scene_spec);
        p.is_file().then_some(p)
    }

    /// Back to the scene's own camera.
    pub fn reset_camera(&mut self) {
        self.trackball = Trackball::from_desc(&self.scene.camera);
    }

    /// Levels of the scene's BVH.
    pub fn bvh_levels(&self) -> u32 {
        self.scene.bvh_stats().levels as u32
    }

    /// The camera the ray tracer uses: the trackball's, standing still.
    pub fn camera(&self) -> CameraMotion {
        CameraMotion::still(self.trackball.camera())
    }

    /// The imaging mode for the worker.
    pub fn imaging_mode(&self) -> ImagingMode {
        match self.mode {
            ModeChoice::Continuous => ImagingMode::Continuous,
            ModeChoice::Dynamic => ImagingMode::Dynamic,
            ModeChoice::Exposure => ImagingMode::Exposure { frames: self.exposure_frames.max(1) },
        }
    }

    /// Apply new settings: restart the accumulation and re-trace the selected pixel.
    pub fn set_settings(&mut self, settings: RenderSettings) {
        if settings != self.settings {
            self.settings = settings;
            self.generation += 1;
            self.retrace();
        }
    }

    /// Change the imaging mode (restarts the accumulation).
    pub fn set_mode(&mut self, mode: ModeChoice) {
        if mode != self.mode {
            self.mode = mode;
            self.generation += 1;
        }
    }

    /// Start a new exposure.
    pub fn expose(&mut self) {
        self.mode = ModeChoice::Exposure;
        self.generation += 1;
    }

    /// The largest rectangle of the image's aspect ratio centred in `area`: where both views
    /// draw the image, so a point maps to the same pixel in each.
    pub fn image_rect(&self, area: Rect) -> Rect {
        let aspect = self.settings.width as f32 / self.settings.height as f32;
        let (w, h) = if area.width() / area.height().max(1.0) > aspect {
            (area.height() * aspect, area.height())
        } else {
            (area.width(), area.width() / aspect)
        };
        Rect::from_center_size(area.center(), egui::vec2(w, h))
    }

    /// The image pixel under `pos` when the image fills `rect`.
    pub fn pixel_at(&self, pos: Pos2, rect: Rect) -> Option<(u32, u32)> {
        if !rect.contains(pos) {
            return None;
        }
        let u = (pos.x - rect.min.x) / rect.width();
        let v = (pos.y - rect.min.y) / rect.height();
        let x = ((u * self.settings.width as f32) as u32).min(self.settings.width - 1);
        let y = ((v * self.settings.height as f32) as u32).min(self.settings.height - 1);
        Some((x, y))
    }

    /// Debug pixel `(x, y)`: trace its first sample with the library's recorder.
    pub fn select_pixel(&mut self, x: u32, y: u32) {
        let camera = self.camera();
        let mut tree = RayTree::with_limit(RECORDED_RAYS);
        let color = trace_pixel(&self.scene, &self.settings, &camera, x, y, 0, &mut tree);
        let visited = match tree.rays.first() {
            Some(r) => {
                let ray = rayscope::ray::Ray::new(Vec3A::from_array(r.origin), Vec3A::from_array(r.dir));
                self.scene.visited_nodes(&ray)
            }
            None => Vec::new(),
        };
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let id = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.selection = Some(Selection { pixel: (x, y), tree, color, visited, id });
    }

    /// Re-trace the selected pixel (after a settings change); the camera it was traced with is
    /// kept in the tree, so orbiting around it does not change it.
    pub fn retrace(&mut self) {
        if let Some(sel) = &self.selection {
            let (x, y) = sel.pixel;
            self.select_pixel(x, y);
        }
    }

    /// Radius of the scene's bounding sphere, for sizing markers.
    fn scale(&self) -> f32 {
        self.scene.geometry.bvh.nodes.first().map_or(1.0, |n| {
            let b = n.bounds();
            ((b.max - b.min).length() * 0.5).max(1e-3)
        })
    }

    /// What the overlay's lines depend on.
    pub fn overlay_key(&self) -> OverlayKey {
        OverlayKey {
            scene: Arc::as_ptr(&self.scene) as usize,
            bvh_level: self.bvh_level,
            bvh_only_visited: self.bvh_only_visited,
            show_light_samples: self.show_light_samples,
            selection: self.selection.as_ref().map(|s| s.id),
        }
    }

    /// Every line the debugger draws over the rasterized scene.
    pub fn overlay_lines(&self) -> Vec<LineVertex> {
        let mut out = Lines::default();
        let r = self.scale();
        for light in &self.scene.lights {
            light_marker(&mut out, light, r);
        }
        if let Some(level) = self.bvh_level {
            let visited: Option<std::collections::HashSet<u32>> =
                self.bvh_only_visited.then(|| self.selection.iter().flat_map(|s| s.visited.iter().copied()).collect());
            for b in self.scene.geometry.bvh.boxes_at_level(level) {
                if visited.as_ref().is_some_and(|v| !v.contains(&b.node)) {
                    continue;
                }
                let color = if b.is_leaf { LEAF_COLOR } else { BOX_COLOR };
                out.aabb(b.bounds.min.into(), b.bounds.max.into(), color);
            }
        }
        if let Some(sel) = &self.selection {
            self.ray_tree_lines(&mut out, sel, r);
        }
        out.0
    }

    fn ray_tree_lines(&self, out: &mut Lines, sel: &Selection, r: f32) {
        for ray in &sel.tree.rays {
            let o = Vec3::from_array(ray.origin);
            let d = Vec3::from_array(ray.dir);
            match &ray.hit {
                None => out.line(o, o + d * (4.0 * r), MISS_COLOR),
                Some(h) => {
                    let p = Vec3::from_array(h.point);
                    out.line(o, p, depth_color(ray.depth, ray.kind));
                    // The hit triangle, the geometric normal and, when shading uses another,
                    // the interpolated normal beside it.
                    if let Some(v) = self.scene.triangle_vertices(h.prim) {
                        let [a, b, c] = v.map(Vec3::from);
                        out.line(a, b, TRIANGLE_COLOR);
                        out.line(b, c, TRIANGLE_COLOR);
                        out.line(c, a, TRIANGLE_COLOR);
                    }
                    let ng = Vec3::from_array(h.geo_normal);
                    let ns = Vec3::from_array(h.shading_normal);
                    out.line(p, p + ng * (0.15 * r), NORMAL_COLOR);
                    if (ns - ng).length() > 1e-4 {
                        out.line(p, p + ns * (0.15 * r), SHADING_NORMAL_COLOR);
                    }
                }
            }
            for s in &ray.shadows {
                let from = Vec3::from_array(s.from);
                let to = Vec3::from_array(s.to);
                let reached = s.transmitted.iter().any(|t| *t > 0.0);
                match s.blocked_at {
                    Some(b) => {
                        let b = Vec3::from_array(b);
                        out.line(from, b, BLOCKED_COLOR);
                        out.cross(b, 0.02 * r, BLOCKED_COLOR);
                        out.line(b, to, [1.0, 0.3, 0.3, 0.25]);
                    }
                    None => out.line(from, to, if reached { REACHED_COLOR } else { BLOCKED_COLOR }),
                }
                if self.show_light_samples {
                    let c = if reached { REACHED_COLOR } else { BLOCKED_COLOR };
                    out.cross(to, 0.012 * r, c);
                }
            }
        }
    }
}

/// Colours of the overlay.
pub const MISS_COLOR: [f32; 4] = [1.0, 0.15, 0.15, 1.0];
/// Shadow ray that reached its light point.
pub const REACHED_COLOR: [f32; 4] = [0.2, 1.0, 0.2, 1.0];
/// Shadow ray that an opaque surface blocked, and the blocker.
pub const BLOCKED_COLOR: [f32; 4] = [1.0, 0.1, 0.1, 1.0];
/// The hit triangle's outline.
pub const TRIANGLE_COLOR: [f32; 4] = [1.0, 0.35, 0.85, 1.0];
/// Geometric normal.
pub const NORMAL_COLOR: [f32; 4] = [0.2, 0.4, 1.0, 1.0];
/// Interpolated (shading) normal.
pub const SHADING_NORMAL_COLOR: [f32; 4] = [0.2, 0.95, 1.0, 1.0];
/// BVH interior boxes.
pub const BOX_COLOR: [f32; 4] = [0.3, 0.9, 0.9, 0.8];
/// BVH leaves.
pub const LEAF_COLOR: [f32; 4] = [1.0, 0.55, 0.1, 0.9];

/// Rays by depth: the camera ray white (as in the course), then warmer colours per bounce;
/// glossy rays fainter, as there are many.
pub fn depth_color(depth: u32, kind: RayKind) -> [f32; 4] {
    const BY_DEPTH: [[f32; 3]; 6] =
        [[1.0, 1.0, 1.0], [1.0, 0.8, 0.2], [1.0, 0.5, 0.1], [0.65, 0.45, 1.0], [0.4, 0.75, 1.0], [0.8, 0.8, 0.5]];
    let c = BY_DEPTH[(depth as usize).min(BY_DEPTH.len() - 1)];
    let a = if kind == RayKind::Glossy { 0.5 } else { 1.0 };
    [c[0], c[1], c[2], a]
}

#[derive(Default)]
struct Lines(Vec<LineVertex>);

impl Lines {
    fn line(&mut self, a: Vec3, b: Vec3, color: [f32; 4]) {
        self.0.push(LineVertex { pos: a.to_array(), color });
        self.0.push(LineVertex { pos: b.to_array(), color });
    }

    fn cross(&mut self, p: Vec3, s: f32, color: [f32; 4]) {
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            self.line(p - axis * s, p + axis * s, color);
        }
    }

    fn aabb(&mut self, lo: Vec3, hi: Vec3, color: [f32; 4]) {
        let c = |i: u32| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        for (a, b) in [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)] {
            self.line(c(a), c(b), color);
        }
    }

    fn circle(&mut self, center: Vec3, u: Vec3, v: Vec3, color: [f32; 4]) {
        let n = 48;
        for i in 0..n {
            let a = std::f32::consts::TAU * i as f32 / n as f32;
            let b = std::f32::consts::TAU * (i + 1) as f32 / n as f32;
            self.line(center + u * a.cos() + v * a.sin(), center + u * b.cos() + v * b.sin(), color);
        }
    }
}

/// A light as the course drew it: a dot for a point light, a line for a segment, a quad for a
/// parallelogram, a wire sphere; in the light's colour.
fn light_marker(out: &mut Lines, light: &Light, r: f32) {
    let col = |c: Vec3| {
        let m = c.max_element().max(1e-6);
        let c = c / m.max(1.0);
        [c.x, c.y, c.z, 1.0]
    };
    match *light {
        Light::Point { position, color } => out.cross(position, 0.03 * r, col(color)),
        Light::Segment { endpoint0, endpoint1, color0, color1 } => {
            let n = 16;
            for i in 0..n {
                let (a, b) = (i as f32 / n as f32, (i + 1) as f32 / n as f32);
                out.line(
                    endpoint0.lerp(endpoint1, a),
                    endpoint0.lerp(endpoint1, b),
                    col(color0.lerp(color1, (a + b) * 0.5)),
                );
            }
        }
        Light::Parallelogram { v0, edge01, edge02, color0, color1, color2, color3 } => {
            let p = [v0, v0 + edge01, v0 + edge01 + edge02, v0 + edge02];
            let c = [color0, color1, color3, color2];
            for i in 0..4 {
                out.line(p[i], p[(i + 1) % 4], col((c[i] + c[(i + 1) % 4]) * 0.5));
            }
        }
        Light::Sphere { center, radius, color } => {
            let c = col(color);
            out.circle(center, Vec3::X * radius, Vec3::Y * radius, c);
            out.circle(center, Vec3::Y * radius, Vec3::Z * radius, c);
            out.circle(center, Vec3::Z * radius, Vec3::X * radius, c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> ViewerState {
        ViewerState::new("cornell-box", None)
    }

    #[test]
    fn clicks_map_to_pixels() {
        let s = state();
        let area = Rect::from_min_size(Pos2::new(100.0, 50.0), egui::vec2(1000.0, 800.0));
        let rect = s.image_rect(area);
        assert_eq!(rect.size(), egui::vec2(800.0, 800.0), "square image, letterboxed");
        assert_eq!(s.pixel_at(rect.min, rect), Some((0, 0)));
        assert_eq!(s.pixel_at(rect.center(), rect), Some((400, 400)));
        assert_eq!(s.pixel_at(rect.max - egui::vec2(0.01, 0.01), rect), Some((799, 799)));
        assert_eq!(s.pixel_at(area.min, rect), None, "outside the image");
    }

    #[test]
    fn the_ray_tree_is_the_librarys() {
        let mut s = state();
        s.select_pixel(400, 400);
        let sel = s.selection.as_ref().unwrap();
        let mut tree = RayTree::with_limit(RECORDED_RAYS);
        let color = trace_pixel(&s.scene, &s.settings, &s.scene.camera_motion(), 400, 400, 0, &mut tree);
        assert_eq!(sel.tree, tree);
        assert_eq!(sel.color, color);
        assert!(!sel.visited.is_empty() && sel.visited[0] == 0, "traversal starts at the root");
        // The tree's lines are drawn: camera ray white, shadow rays, normals, triangle.
        let lines = s.overlay_lines();
        assert!(lines.iter().any(|v| v.color == depth_color(0, RayKind::Camera)));
        assert!(lines.iter().any(|v| v.color == NORMAL_COLOR));
        assert!(lines.iter().any(|v| v.color == TRIANGLE_COLOR));
    }

    #[test]
    fn settings_and_modes_restart_accumulation() {
        let mut s = state();
        let g = s.generation;
        s.set_settings(s.settings.clone());
        assert_eq!(s.generation, g, "no change, no restart");
        s.set_settings(RenderSettings { shadows: false, ..s.settings.clone() });
        assert_eq!(s.generation, g + 1);
        s.set_mode(ModeChoice::Continuous);
        assert_eq!(s.generation, g + 2);
        s.expose();
        assert_eq!(s.generation, g + 3);
        assert_eq!(s.imaging_mode(), ImagingMode::Exposure { frames: 16 });
        // Camera moves do not bump the generation: the mode decides what they do.
        s.trackball.orbit(10.0, 5.0);
        assert_eq!(s.generation, g + 3);
    }

    #[test]
    fn settings_changes_retrace_the_selection() {
        let mut s = state();
        s.select_pixel(400, 400);
        let with = s.selection.as_ref().unwrap().tree.rays[0].shadows.len();
        s.set_settings(RenderSettings { shadows: false, ..s.settings.clone() });
        let without = s.selection.as_ref().unwrap().tree.rays[0].shadows.len();
        assert!(with > 0 && without == 0);
    }

    #[test]
    fn bvh_levels_and_visited_filter() {
        let mut s = state();
        s.bvh_level = Some(2);
        let all = s.overlay_lines().iter().filter(|v| v.color == BOX_COLOR || v.color == LEAF_COLOR).count();
        assert!(all >= 24);
        s.select_pixel(400, 400);
        s.bvh_only_visited = true;
        let visited = s.overlay_lines().iter().filter(|v| v.color == BOX_COLOR || v.color == LEAF_COLOR).count();
        assert!(visited <= all);
    }

    #[test]
    fn the_overlay_key_follows_what_the_lines_show() {
        let mut s = state();
        let key = s.overlay_key();
        let lines = s.overlay_lines();
        // Orbiting and settings that do not touch the selection leave the lines as they are.
        s.trackball.orbit(10.0, 5.0);
        assert_eq!(s.overlay_key(), key);
        assert_eq!(s.overlay_lines(), lines);
        s.bvh_level = Some(2);
        assert_ne!(s.overlay_key(), key);
        let level = s.overlay_key();
        s.select_pixel(400, 400);
        assert_ne!(s.overlay_key(), level);
        let selected = s.overlay_key();
        s.retrace();
        assert_ne!(s.overlay_key(), selected, "a re-traced pixel may have other shadow samples");
        for toggle in
            [|s: &mut ViewerState| s.bvh_only_visited ^= true, |s: &mut ViewerState| s.show_light_samples ^= true]
        {
            let before = s.overlay_key();
            toggle(&mut s);
            assert_ne!(s.overlay_key(), before);
        }
    }

    #[test]
    fn reload_keeps_the_view() {
        let dir = std::env::temp_dir().join(format!("rayscope-reload-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("s.toml");
        let light = "[[light]]\nkind = \"point\"\nposition = [3, 0, 3]\ncolor = [1, 1, 1]\n";
        std::fs::write(&file, format!("[[sphere]]\ncenter = [0, 0, 0]\nradius = 0.5\n{light}")).unwrap();
        let mut s = ViewerState::new(file.to_str().unwrap(), None);
        assert!(s.error.is_none(), "{:?}", s.error);
        assert_eq!(s.scene_file(), Some(file.clone()));
        s.trackball.orbit(30.0, 0.0);
        let t = s.trackball;
        s.select_pixel(400, 400);
        std::fs::write(&file, format!("[[sphere]]\ncenter = [0, 0, 0]\nradius = 0.8\n{light}")).unwrap();
        s.reload();
        assert_eq!(s.scene.spheres[0].radius, 0.8);
        assert_eq!(s.trackball, t);
        assert!(s.selection.is_some());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_bad_scene_shows_an_error_and_keeps_the_last() {
        let mut s = state();
        s.load_scene("no-such-scene.toml");
        assert!(s.error.as_ref().unwrap().contains("no-such-scene.toml"));
        assert_eq!(s.scene_spec, "cornell-box");
        s.load_scene("spheres");
        assert!(s.error.is_none());
        assert_eq!(s.scene.spheres.len(), 3);
    }
}
