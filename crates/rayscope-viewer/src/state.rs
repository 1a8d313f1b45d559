//! The viewer's state and logic, apart from any window: the scene, the camera, the settings,
//! the imaging mode, the selected pixel with its ray tree, and the overlay lines the
//! debugger draws. Everything here is tested without a display.

use std::path::PathBuf;
use std::sync::Arc;

use egui::{Pos2, Rect};
use glam::Vec3;
use rayscope::animation::{AnimationSettings, Shutter};
use rayscope::camera::CameraMotion;
use rayscope::debug::{Explanation, PixelTrace, SampleChoice, trace_pixel_samples};
use rayscope::motion::Interpolation;
use rayscope::progressive::ImagingMode;
use rayscope::record::RayTree;
use rayscope::scene::{Scene, builtin};
use rayscope::settings::RenderSettings;

use crate::overlay::{
    BLOCKED_COLOR, BOX_COLOR, ColorBy, HIGHLIGHT_COLOR, LEAF_COLOR, LineKind, Lines, MISS_COLOR, NORMAL_COLOR,
    PAST_BLOCKER_COLOR, REACHED_COLOR, SHADING_NORMAL_COLOR, SKIPPED_COLOR, ShownKinds, TRIANGLE_COLOR, depth_color,
    kind_color, light_line_color,
};
use crate::preview::LineVertex;
use crate::trackball::Trackball;

/// The most rays (shadow rays included) the viewer records for a debugged pixel, over all its
/// samples, a tenth of `rayscope debug`'s bound: the 3D view draws every recorded ray in every
/// frame.
pub const RECORDED_RAYS: usize = 10_000;

/// The most pixels a dragged rectangle selects: their trees are drawn together, and more would
/// be a thicket (a larger drag is clamped, with a note).
pub const MAX_RECT_PIXELS: u32 = 64;

/// The default width of overlay lines, in points.
pub const DEFAULT_LINE_WIDTH: f32 = 1.5;

/// Which image the viewport shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewKind {
    /// The rasterized GPU preview with the debugger's overlays.
    Raster,
    /// The ray-traced image.
    RayTraced,
    /// BVH nodes visited per pixel.
    HeatMap,
    /// The mip level trilinear filtering reads per pixel.
    MipLevels,
    /// With `--compare`: their image (see [`crate::compare`]).
    Theirs,
    /// With `--compare`: our render compared with it.
    Ours,
    /// With `--compare`: the difference image.
    Difference,
}

/// Which BVH the level view draws.
pub use rayscope::bvh::BvhTree;

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

/// One debugged pixel.
#[derive(Clone, Debug)]
pub struct PixelDebug {
    /// Pixel `(x, y)`, row 0 at the top.
    pub pixel: (u32, u32),
    /// Its samples (all, or the one chosen) with every ray, as the renderer traced them; with
    /// all samples its value is the film's.
    pub trace: PixelTrace,
    /// Its value as a sum of terms.
    pub explanation: Explanation,
    /// Binary BVH nodes the camera rays entered (a replay; the wide tree's visits, as the
    /// renderer made them, are in the trees).
    pub visited: Vec<u32>,
}

impl PixelDebug {
    /// The pixel's value from the samples traced.
    pub fn color(&self) -> Vec3 {
        self.trace.value
    }

    /// The samples' ray trees.
    pub fn trees(&self) -> impl Iterator<Item = &RayTree> {
        self.trace.samples.iter().map(|s| &s.tree)
    }
}

/// What the explanation table's selected row points at in 3D: a ray of a sample, or the
/// shadow rays from it to one light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Highlight {
    /// The sample's index.
    pub sample: u32,
    /// The ray's index in the sample's tree.
    pub ray: usize,
    /// The light, for a light's term.
    pub light: Option<usize>,
}

/// The debugged pixels: one clicked, or a dragged rectangle of up to [`MAX_RECT_PIXELS`].
#[derive(Clone, Debug)]
pub struct Selection {
    /// The pixels, row by row; the first is the clicked one or the rectangle's top-left.
    pub pixels: Vec<PixelDebug>,
    /// Set when a dragged rectangle was larger than [`MAX_RECT_PIXELS`]: what was kept.
    pub clamped: Option<String>,
    /// Distinguishes this selection from every other one (for [`OverlayKey`]).
    pub id: u64,
    /// The camera its pixels were traced through (the focal plane is drawn for it).
    pub camera: rayscope::camera::Camera,
}

impl Selection {
    /// The first (or only) pixel.
    pub fn first(&self) -> &PixelDebug {
        &self.pixels[0]
    }
}

/// A rectangle of pixels, corners included, row 0 at the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    /// Top-left pixel.
    pub min: (u32, u32),
    /// Bottom-right pixel (inclusive).
    pub max: (u32, u32),
}

impl PixelRect {
    /// The rectangle spanned by two corner pixels in any order.
    pub fn spanning(a: (u32, u32), b: (u32, u32)) -> PixelRect {
        PixelRect { min: (a.0.min(b.0), a.1.min(b.1)), max: (a.0.max(b.0), a.1.max(b.1)) }
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.max.0 - self.min.0 + 1, self.max.1 - self.min.1 + 1)
    }

    /// The rectangle cut down to at most `max_pixels` from its top-left corner: as wide as it
    /// was (up to `max_pixels`), with as many rows as fit.
    pub fn clamped(&self, max_pixels: u32) -> PixelRect {
        let (w, h) = self.size();
        let w = w.min(max_pixels);
        let h = h.min(max_pixels / w);
        PixelRect { min: self.min, max: (self.min.0 + w - 1, self.min.1 + h - 1) }
    }

    /// Its pixels, row by row.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (self.min.1..=self.max.1).flat_map(move |y| (self.min.0..=self.max.0).map(move |x| (x, y)))
    }
}

/// What [`ViewerState::overlay_lines`] depends on: while it is the same, so are the lines,
/// and the viewer draws the ones it made (and uploaded) before instead of making them for
/// every frame, which the deep BVH levels of a large mesh made slow.
/// (The line width is not in it: the preview widens the same lines on the GPU.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OverlayKey {
    scene: usize,
    bvh_level: Option<u32>,
    bvh_tree: BvhTree,
    bvh_only_visited: bool,
    split_node: Option<u32>,
    shown: ShownKinds,
    max_depth_shown: u32,
    color_by: ColorBy,
    highlight: Option<Highlight>,
    selection: Option<u64>,
    show_paths: bool,
    focal_plane: Option<crate::lens::FocalKey>,
    frame: Option<u32>,
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
    /// The tree whose level is drawn.
    pub bvh_tree: BvhTree,
    /// Draw only the BVH nodes the selected rays entered.
    pub bvh_only_visited: bool,
    /// The binary BVH node whose SAH split candidates are shown, if any.
    pub split: Option<crate::split::SplitView>,
    /// Which kinds of lines are drawn.
    pub shown: ShownKinds,
    /// Rays deeper than this are not drawn (nor their shadow rays and normals).
    pub max_depth_shown: u32,
    /// How rays are coloured.
    pub color_by: ColorBy,
    /// Overlay line width in points.
    pub line_width: f32,
    /// Which samples of a pixel are traced.
    pub samples: SampleChoice,
    /// The explanation row picked, drawn highlighted (of the first selected pixel).
    pub highlight: Option<Highlight>,
    /// Whether a primary drag selects a rectangle of pixels (else it orbits; Ctrl-drag
    /// selects either way).
    pub rect_tool: bool,
    /// Bumped whenever the accumulation must restart.
    pub generation: u64,
    /// An image compared with ours (`--compare`), and its views.
    pub compare: Option<crate::compare::CompareViews>,
    /// Draw the paths of moving objects and of the camera.
    pub show_paths: bool,
    /// The interpolation every path is given on loading (`None`: the scene file's).
    pub motion_interpolation: Option<Interpolation>,
    /// The animation frame the ray tracer shows (`None`: the still, scene time `[0, 1]`),
    /// kept across reloads.
    pub frame: Option<u32>,
    /// Whether the timeline plays (steps a frame every `1 / fps` seconds).
    pub playing: bool,
    /// When, in the window's clock (seconds), the playing timeline last stepped.
    pub play_clock: Option<f64>,
    /// The environment map's flags, applied to every scene loaded.
    pub env: crate::environment::EnvOverride,
    /// Which of bloom's layers the ray-traced view shows.
    pub bloom_layer: crate::bloom::BloomLayer,
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
            bvh_tree: BvhTree::Wide,
            bvh_only_visited: false,
            split: None,
            shown: ShownKinds::default(),
            max_depth_shown: rayscope::settings::MAX_DEPTH,
            color_by: ColorBy::Depth,
            line_width: DEFAULT_LINE_WIDTH,
            rect_tool: false,
            samples: SampleChoice::All,
            highlight: None,
            generation: 0,
            compare: None,
            show_paths: true,
            motion_interpolation: None,
            frame: None,
            playing: false,
            play_clock: None,
            env: Default::default(),
            bloom_layer: Default::default(),
        };
        s.load_scene(spec);
        s
    }

    /// Load another scene; on failure keep the current one and record the error.
    pub fn load_scene(&mut self, spec: &str) {
        match Scene::load(spec, self.assets.as_deref()) {
            Ok(mut scene) => {
                if let Some(i) = self.motion_interpolation {
                    scene.set_motion_interpolation(i);
                }
                scene.set_shutter(frame_shutter(&scene, self.frame));
                self.env.apply(&mut scene);
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
                self.split = self.split.as_ref().map(|v| crate::split::SplitView::new(&self.scene, v.node));
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

    /// Interpolate every path of the scene as `interpolation`, now and on every later load
    /// (keeping the camera, the settings and the selection, as a reload does).
    pub fn set_motion_interpolation(&mut self, interpolation: Interpolation) {
        self.motion_interpolation = Some(interpolation);
        self.reload();
    }

    /// The scene's animation settings (its `[animation]`, else the defaults).
    pub fn animation(&self) -> AnimationSettings {
        self.scene.animation.unwrap_or_default()
    }

    /// Show animation frame `frame` (`None`: the still): the scene exposes the frame's span
    /// of its timeline (its BVH rebuilt around the moving shapes there) and the accumulation
    /// restarts.
    pub fn set_frame(&mut self, frame: Option<u32>) {
        if frame == self.frame {
            return;
        }
        self.frame = frame;
        let shutter = frame_shutter(&self.scene, frame);
        Arc::make_mut(&mut self.scene).set_shutter(shutter);
        self.generation += 1;
        self.retrace();
    }

    /// Back to the scene's own camera.
    pub fn reset_camera(&mut self) {
        self.trackball = Trackball::from_desc(&self.scene.camera);
    }

    /// Levels of the BVH the level view draws.
    pub fn bvh_levels(&self) -> u32 {
        match self.bvh_tree {
            BvhTree::Wide => self.scene.wide_levels(),
            BvhTree::Binary => self.scene.bvh_stats().levels as u32,
        }
    }

    /// The camera whose focal plane the overlay draws: the selection's (its lens rays
    /// converge there), else the trackball's.
    pub fn focal_camera(&self) -> rayscope::camera::Camera {
        self.selection.as_ref().map_or_else(|| self.trackball.camera(), |s| s.camera)
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
        let one = PixelRect { min: (x, y), max: (x, y) };
        self.select_rect(one);
    }

    /// Debug the pixels of `rect` (clipped to the image), up to [`MAX_RECT_PIXELS`] of them:
    /// a larger rectangle is cut down from its top-left corner, with a note saying so.
    pub fn select_rect(&mut self, rect: PixelRect) {
        let last = (self.settings.width - 1, self.settings.height - 1);
        let clip = |p: (u32, u32)| (p.0.min(last.0), p.1.min(last.1));
        let rect = PixelRect { min: clip(rect.min), max: clip(rect.max) };
        let kept = rect.clamped(MAX_RECT_PIXELS);
        let clamped = (kept != rect).then(|| {
            let ((w, h), (kw, kh)) = (rect.size(), kept.size());
            format!(
                "the {w}x{h} rectangle ({} pixels) was cut to its top-left {kw}x{kh}: at most {MAX_RECT_PIXELS} \
                 pixels are traced together",
                w * h
            )
        });
        let pixels = kept.pixels().map(|(x, y)| self.debug_pixel(x, y)).collect();
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let id = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.selection = Some(Selection { pixels, clamped, id, camera: self.trackball.camera() });
        self.highlight = None;
    }

    fn debug_pixel(&self, x: u32, y: u32) -> PixelDebug {
        let camera = self.camera();
        let which = match self.samples {
            SampleChoice::One(k) => SampleChoice::One(k.min(self.settings.spp.max(1) - 1)),
            all => all,
        };
        let trace = trace_pixel_samples(&self.scene, &self.settings, &camera, x, y, which, RECORDED_RAYS);
        let mut visited: Vec<u32> = trace
            .samples
            .iter()
            .filter_map(|s| s.tree.rays.first()?.traversal.as_ref())
            // The camera ray as its traversal got it, with its real interval and shutter time.
            .flat_map(|t| self.scene.visited_nodes(&t.ray()))
            .collect();
        visited.sort_unstable();
        visited.dedup();
        let explanation = trace.explain();
        PixelDebug { pixel: (x, y), trace, explanation, visited }
    }

    /// Highlight term `row` of the first selected pixel's explanation (nothing when there is
    /// no such row).
    pub fn highlight_term(&mut self, row: usize) {
        let term = self.selection.as_ref().and_then(|s| s.first().explanation.terms.get(row));
        self.highlight = term.map(|t| Highlight { sample: t.sample, ray: t.ray, light: t.light });
    }

    /// Trace other samples of the selected pixels: all, or one by index.
    pub fn set_samples(&mut self, samples: SampleChoice) {
        if samples != self.samples {
            self.samples = samples;
            self.retrace();
        }
    }

    /// Re-trace the selected pixels (after a settings change); the camera it was traced with is
    /// kept in the tree, so orbiting around it does not change it.
    pub fn retrace(&mut self) {
        if let Some(sel) = &self.selection {
            let first = sel.first().pixel;
            let last = sel.pixels.last().map_or(first, |p| p.pixel);
            self.select_rect(PixelRect { min: first, max: last });
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
            bvh_tree: self.bvh_tree,
            bvh_only_visited: self.bvh_only_visited,
            split_node: self.split.as_ref().map(|v| v.node),
            shown: self.shown,
            max_depth_shown: self.max_depth_shown,
            color_by: self.color_by,
            highlight: self.highlight,
            selection: self.selection.as_ref().map(|s| s.id),
            show_paths: self.show_paths,
            focal_plane: crate::lens::FocalKey::new(&self.settings, &self.focal_camera()),
            frame: self.frame,
        }
    }

    /// Every line the debugger draws over the scene.
    pub fn overlay_lines(&self) -> Vec<LineVertex> {
        let mut out = Lines::default();
        let r = self.scale();
        for light in &self.scene.lights {
            out.light(light, r, None);
        }
        if self.show_paths {
            crate::motion::path_lines(&mut out, &self.scene, r);
        }
        if let Some(level) = self.bvh_level {
            let pixels = || self.selection.iter().flat_map(|s| &s.pixels);
            match self.bvh_tree {
                BvhTree::Wide => {
                    // What the renderer's own traversals entered, for every ray of every tree.
                    let visited: Option<std::collections::HashSet<_>> = self
                        .bvh_only_visited
                        .then(|| pixels().flat_map(|p| p.trees()).flat_map(|t| t.visited_wide()).collect());
                    for b in self.scene.wide_boxes_at_level(level) {
                        if visited.as_ref().is_some_and(|v| !v.contains(&b.at)) {
                            continue;
                        }
                        let color = if b.is_leaf() { LEAF_COLOR } else { BOX_COLOR };
                        out.aabb(b.bounds.min.into(), b.bounds.max.into(), color);
                    }
                }
                BvhTree::Binary => {
                    let visited: Option<std::collections::HashSet<u32>> =
                        self.bvh_only_visited.then(|| pixels().flat_map(|p| p.visited.iter().copied()).collect());
                    for b in self.scene.geometry.bvh.boxes_at_level(level) {
                        if visited.as_ref().is_some_and(|v| !v.contains(&b.node)) {
                            continue;
                        }
                        let color = if b.is_leaf { LEAF_COLOR } else { BOX_COLOR };
                        out.aabb(b.bounds.min.into(), b.bounds.max.into(), color);
                    }
                }
            }
        }
        if let Some(split) = &self.split {
            split.lines(&mut out);
        }
        for p in self.selection.iter().flat_map(|s| &s.pixels) {
            for tree in p.trees() {
                self.ray_tree_lines(&mut out, tree, r);
            }
        }
        if let Some(h) = self.highlight {
            self.highlight_lines(&mut out, h, r);
        }
        crate::lens::focal_plane_lines(&mut out, &self.focal_camera(), &self.settings);
        out.0
    }

    /// The highlighted ray of the first pixel (drawn again on top, in the highlight colour),
    /// or its shadow rays to one light and that light.
    fn highlight_lines(&self, out: &mut Lines, h: Highlight, r: f32) {
        let Some(p) = self.selection.as_ref().map(|s| s.first()) else { return };
        let Some(ray) = p.trace.samples.iter().find(|s| s.index == h.sample).and_then(|s| s.tree.rays.get(h.ray))
        else {
            return;
        };
        let o = Vec3::from_array(ray.origin);
        let end = ray.hit.map_or(o + Vec3::from_array(ray.dir) * (4.0 * r), |hit| Vec3::from_array(hit.point));
        match h.light {
            None => out.line(o, end, HIGHLIGHT_COLOR),
            Some(l) => {
                for s in ray.shadows.iter().filter(|s| s.light == l) {
                    out.line(Vec3::from_array(s.from), Vec3::from_array(s.to), HIGHLIGHT_COLOR);
                }
                for t in ray.light_terms.iter().filter(|t| t.light == l) {
                    out.cross(t.to.into(), 0.02 * r, HIGHLIGHT_COLOR);
                }
                if let Some(light) = self.scene.lights.get(l) {
                    out.light(light, r, Some(HIGHLIGHT_COLOR));
                }
            }
        }
    }

    fn ray_tree_lines(&self, out: &mut Lines, tree: &RayTree, r: f32) {
        let shown = |k: LineKind| self.shown.contains(k);
        for ray in tree.rays.iter().filter(|ray| ray.depth <= self.max_depth_shown) {
            let o = Vec3::from_array(ray.origin);
            let d = Vec3::from_array(ray.dir);
            let color = match self.color_by {
                ColorBy::Depth => depth_color(ray.depth, ray.kind),
                ColorBy::Kind => kind_color(ray.kind),
                ColorBy::Time => crate::motion::ray_time_color(ray).unwrap_or_else(|| kind_color(ray.kind)),
            };
            let ray_shown = shown(LineKind::of_ray(ray.kind));
            match &ray.hit {
                None if ray_shown => {
                    out.line(o, o + d * (4.0 * r), MISS_COLOR);
                    if let (Some(env), Some(lookup)) = (&self.scene.environment, &ray.environment) {
                        crate::environment::texel_lines(out, env, o, lookup, 4.0 * r);
                    }
                }
                None => {}
                Some(h) => {
                    let p = Vec3::from_array(h.point);
                    if ray_shown {
                        out.line(o, p, color);
                    }
                    if shown(LineKind::Normals) {
                        // The hit triangle, the geometric normal and, when shading uses
                        // another, the interpolated normal beside it.
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
            }
            for s in &ray.shadows {
                let from = Vec3::from_array(s.from);
                let to = Vec3::from_array(s.to);
                let reached = s.transmitted.iter().any(|t| *t > 0.0);
                match s.blocked_at {
                    // As the course's shadow debug draws it: the light's colour up to the
                    // blocker, a cross there, and dark past it.
                    Some(b) if shown(LineKind::ShadowBlocked) => {
                        let b = Vec3::from_array(b);
                        out.line(from, b, light_line_color(Vec3::from_array(s.light_color)));
                        out.cross(b, 0.02 * r, BLOCKED_COLOR);
                        out.line(b, to, PAST_BLOCKER_COLOR);
                    }
                    Some(_) => {}
                    None if reached && shown(LineKind::ShadowReached) => out.line(from, to, REACHED_COLOR),
                    // Nothing got through, yet nothing opaque blocked it: fully absorbed by
                    // transparent surfaces.
                    None if !reached && shown(LineKind::ShadowBlocked) => out.line(from, to, PAST_BLOCKER_COLOR),
                    None => {}
                }
                if shown(LineKind::LightSamples) {
                    out.cross(to, 0.012 * r, if reached { REACHED_COLOR } else { BLOCKED_COLOR });
                }
            }
            // Light points the integrator skipped (behind the surface): no shadow ray, a
            // cross in their own colour; the panel gives the reason.
            if shown(LineKind::LightSamples) {
                for skip in &ray.skipped_lights {
                    out.cross(skip.to.into(), 0.012 * r, SKIPPED_COLOR);
                }
            }
        }
    }
}

/// The span of scene time frame `frame` of `scene`'s animation exposes (`None`: the still's).
fn frame_shutter(scene: &Scene, frame: Option<u32>) -> Shutter {
    frame.map_or(Shutter::STILL, |f| scene.animation.unwrap_or_default().shutter_of(f))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayscope::record::RayKind;
    use rayscope::render::{render, trace_pixel};

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
        let sel = s.selection.as_ref().unwrap().first();
        let mut tree = RayTree::with_limit(RECORDED_RAYS);
        let color = trace_pixel(&s.scene, &s.settings, &s.scene.camera_motion(), 400, 400, 0, &mut tree);
        assert_eq!(sel.trace.samples[0].tree, tree);
        assert_eq!(sel.color(), color);
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
        let with = s.selection.as_ref().unwrap().first().trace.samples[0].tree.rays[0].shadows.len();
        s.set_settings(RenderSettings { shadows: false, ..s.settings.clone() });
        let without = s.selection.as_ref().unwrap().first().trace.samples[0].tree.rays[0].shadows.len();
        assert!(with > 0 && without == 0);
    }

    #[test]
    fn bvh_levels_and_visited_filter() {
        let boxes = |s: &ViewerState| {
            s.overlay_lines().iter().filter(|v| v.color == BOX_COLOR || v.color == LEAF_COLOR).count() / 24
        };
        // The binary tree: a replay of the camera ray.
        let mut s = state();
        s.bvh_tree = BvhTree::Binary;
        s.bvh_level = Some(2);
        let all = boxes(&s);
        assert!(all >= 1);
        s.select_pixel(400, 400);
        s.bvh_only_visited = true;
        assert!(boxes(&s) <= all);
        // The wide tree: the boxes the renderer's traversals entered, for every ray of the tree.
        s.bvh_tree = BvhTree::Wide;
        s.bvh_only_visited = false;
        for level in 0..s.bvh_levels() {
            s.bvh_level = Some(level);
            let all = s.scene.wide_boxes_at_level(level);
            assert_eq!(boxes(&s), all.len(), "level {level}");
            s.bvh_only_visited = true;
            let tree = &s.selection.as_ref().unwrap().first().trace.samples[0].tree;
            let entered = tree.visited_wide();
            assert_eq!(boxes(&s), all.iter().filter(|b| entered.contains(&b.at)).count(), "level {level}");
            s.bvh_only_visited = false;
        }
        assert!(s.bvh_levels() >= 2, "a root and its leaves");
        let key = s.overlay_key();
        s.bvh_tree = BvhTree::Binary;
        assert_ne!(s.overlay_key(), key);
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
        for toggle in [
            |s: &mut ViewerState| s.bvh_only_visited ^= true,
            |s: &mut ViewerState| s.shown.set(LineKind::LightSamples, false),
            |s: &mut ViewerState| s.max_depth_shown = 0,
            |s: &mut ViewerState| s.color_by = ColorBy::Kind,
        ] {
            let before = s.overlay_key();
            toggle(&mut s);
            assert_ne!(s.overlay_key(), before);
        }
    }

    /// Segments of `lines` whose colour is `c`.
    fn segments(lines: &[LineVertex], c: [f32; 4]) -> usize {
        lines.chunks(2).filter(|v| v[0].color == c).count()
    }

    /// Segments of `kind` drawn: all the segments less those drawn without it.
    fn drawn(s: &mut ViewerState, kind: LineKind) -> usize {
        let all = s.overlay_lines().len() / 2;
        s.shown.set(kind, false);
        let without = s.overlay_lines().len() / 2;
        s.shown.set(kind, true);
        all - without
    }

    #[test]
    fn each_kind_toggles_its_own_lines() {
        // The mirror at the Cornell box's centre: a camera ray, a reflection, shadow rays.
        let mut s = state();
        s.settings.light_samples = 16;
        s.select_pixel(400, 400);
        let tree = s.selection.as_ref().unwrap().first().trace.samples[0].tree.clone();
        let rays = |k: RayKind| tree.rays.iter().filter(|r| r.kind == k).count();
        let (camera, reflections) = (rays(RayKind::Camera), rays(RayKind::Reflection));
        assert!(camera == 1 && reflections >= 1);
        let shadows: Vec<_> = tree.rays.iter().flat_map(|r| &r.shadows).collect();
        let blocked = shadows.iter().filter(|s| s.blocked_at.is_some()).count();
        let reached = shadows.iter().filter(|s| s.transmitted.iter().any(|t| *t > 0.0)).count();
        assert!(reached > 0);
        let all = s.overlay_lines();
        assert_eq!(all.len() % 2, 0, "vertex pairs");
        assert_eq!(segments(&all, REACHED_COLOR), 4 * reached, "a line and a light-sample cross each");
        assert_eq!(segments(&all, PAST_BLOCKER_COLOR), blocked);
        // Each toggle removes exactly its own lines.
        assert_eq!(drawn(&mut s, LineKind::Camera), camera);
        assert_eq!(drawn(&mut s, LineKind::Reflection), reflections);
        assert_eq!(drawn(&mut s, LineKind::Glossy), 0, "no glossy rays here");
        assert_eq!(drawn(&mut s, LineKind::Transmission), 0, "nor transparent surfaces");
        assert_eq!(drawn(&mut s, LineKind::ShadowReached), reached);
        assert_eq!(drawn(&mut s, LineKind::ShadowBlocked), 5 * blocked, "to the blocker, a cross, past it");
        assert_eq!(drawn(&mut s, LineKind::LightSamples), 3 * shadows.len());
        let hits = tree.rays.iter().filter(|r| r.hit.is_some()).count();
        assert!(drawn(&mut s, LineKind::Normals) >= hits, "a normal per hit");
        // With every kind off, the lights' shapes are all that is left.
        for k in LineKind::ALL {
            s.shown.set(k, false);
        }
        let lights_only = ViewerState { selection: None, ..state() }.overlay_lines();
        assert_eq!(s.overlay_lines(), lights_only);
    }

    #[test]
    fn blocked_shadow_rays_stop_in_the_lights_colour() {
        // Some point of the Cornell box's floor is shadowed by a block from the ceiling light.
        let mut s = state();
        s.settings.light_samples = 16;
        let grid = (0..800).step_by(25).flat_map(|y| (0..800).step_by(25).map(move |x| (x, y)));
        let blocked = grid.into_iter().find_map(|(x, y)| {
            s.select_pixel(x, y);
            let t = &s.selection.as_ref().unwrap().first().trace.samples[0].tree;
            t.rays.iter().flat_map(|r| &r.shadows).find(|sh| sh.blocked_at.is_some()).cloned()
        });
        let sh = blocked.expect("some pixel is in shadow");
        let lines = s.overlay_lines();
        let light = crate::overlay::light_line_color(Vec3::from_array(sh.light_color));
        let to_blocker = lines.chunks(2).find(|v| v[0].pos == sh.from && v[1].pos == sh.blocked_at.unwrap());
        assert_eq!(to_blocker.map(|v| v[0].color), Some(light));
        let past = lines.chunks(2).find(|v| v[0].pos == sh.blocked_at.unwrap() && v[1].pos == sh.to);
        assert_eq!(past.map(|v| v[0].color), Some(PAST_BLOCKER_COLOR));
    }

    #[test]
    fn the_depth_shown_limits_the_tree() {
        let mut s = state();
        s.select_pixel(400, 400);
        let tree = s.selection.as_ref().unwrap().first().trace.samples[0].tree.clone();
        let mut last = usize::MAX;
        for d in (0..=2).rev() {
            s.max_depth_shown = d;
            let drawn = segments(&s.overlay_lines(), depth_color(d, RayKind::Reflection));
            let want = tree.rays.iter().filter(|r| r.depth == d && r.hit.is_some()).count();
            if d > 0 {
                assert_eq!(drawn, want, "depth {d}");
            }
            let n = s.overlay_lines().len();
            assert!(n <= last, "fewer lines as the depth shown falls");
            last = n;
        }
        s.max_depth_shown = 0;
        assert!(segments(&s.overlay_lines(), depth_color(1, RayKind::Reflection)) == 0);
    }

    #[test]
    fn a_rectangle_selects_its_pixels_up_to_64() {
        let mut s = state();
        s.select_rect(PixelRect::spanning((403, 402), (400, 400)));
        let sel = s.selection.as_ref().unwrap();
        assert_eq!(sel.pixels.len(), 12);
        assert_eq!(sel.first().pixel, (400, 400));
        assert!(sel.clamped.is_none());
        for (p, want) in sel.pixels.iter().zip(PixelRect::spanning((400, 400), (403, 402)).pixels()) {
            let mut tree = RayTree::with_limit(RECORDED_RAYS);
            let c = trace_pixel(&s.scene, &s.settings, &s.camera(), want.0, want.1, 0, &mut tree);
            assert_eq!((p.pixel, &p.trace.samples[0].tree, p.color()), (want, &tree, c));
        }
        assert_eq!(drawn(&mut s, LineKind::Camera), 12, "one tree per pixel, drawn together");
        // A large drag is cut to 64 pixels from its top-left corner, and says so.
        s.select_rect(PixelRect::spanning((100, 100), (139, 119)));
        let sel = s.selection.as_ref().unwrap();
        assert_eq!(sel.pixels.len(), 40, "40 wide: one row of 40 (two would be 80)");
        s.select_rect(PixelRect::spanning((100, 100), (107, 199)));
        let sel = s.selection.as_ref().unwrap();
        assert_eq!(sel.pixels.len(), 64);
        assert_eq!(sel.pixels.last().unwrap().pixel, (107, 107));
        assert!(sel.clamped.as_ref().unwrap().contains("8x100 rectangle (800 pixels) was cut to its top-left 8x8"));
        // Clipped to the image; a re-trace keeps the rectangle.
        s.select_rect(PixelRect::spanning((798, 798), (900, 900)));
        assert_eq!(s.selection.as_ref().unwrap().pixels.len(), 4);
        s.set_settings(RenderSettings { shadows: false, ..s.settings.clone() });
        assert_eq!(s.selection.as_ref().unwrap().pixels.len(), 4);
    }

    #[test]
    fn every_sample_is_drawn_and_the_pixel_is_the_films() {
        // Nine anti-aliasing samples and soft shadows: the selection traces them all, its value
        // is the rendered pixel's bit for bit, and every sample's tree is drawn.
        let mut s = state();
        let settings = RenderSettings { spp: 9, light_samples: 4, width: 64, height: 64, ..s.settings.clone() };
        s.set_settings(settings.clone());
        let film = render(&s.scene, &settings, &|_| {}).film;
        for (x, y) in [(32, 32), (10, 50), (50, 12)] {
            s.select_pixel(x, y);
            let p = s.selection.as_ref().unwrap().first().clone();
            assert_eq!(p.trace.samples.len(), 9);
            assert_eq!(p.color(), film.get(x, y), "pixel ({x}, {y})");
            for sample in &p.trace.samples {
                let mut tree = RayTree::with_limit(RECORDED_RAYS);
                trace_pixel(&s.scene, &settings, &s.camera(), x, y, sample.index, &mut tree);
                assert_eq!(sample.tree.rays.len(), tree.rays.len(), "sample {}", sample.index);
            }
            assert_eq!(drawn(&mut s, LineKind::Camera), 9, "a camera ray per sample");
            // The explanation's terms sum to the pixel.
            let e = &p.explanation;
            assert!((e.sum - e.value).abs().max_element() <= 1e-4 * e.value.max_element().max(1.0), "{e:?}");
        }
        // One sample by index: its tree alone.
        s.set_samples(SampleChoice::One(4));
        let p = s.selection.as_ref().unwrap().first();
        assert_eq!(p.trace.samples.iter().map(|t| t.index).collect::<Vec<_>>(), [4]);
        assert_eq!(drawn(&mut s, LineKind::Camera), 1);
        // An index past spp is the last sample.
        s.set_samples(SampleChoice::One(40));
        assert_eq!(s.selection.as_ref().unwrap().first().trace.samples[0].index, 8);
    }

    #[test]
    fn an_explanation_row_highlights_its_ray_or_light() {
        let mut s = state();
        s.select_pixel(400, 400);
        let e = s.selection.as_ref().unwrap().first().explanation.clone();
        let term = e.terms.iter().find(|t| t.light.is_some()).expect("a light term");
        let key = s.overlay_key();
        s.highlight = Some(Highlight { sample: term.sample, ray: term.ray, light: term.light });
        assert_ne!(s.overlay_key(), key, "the highlight changes the lines");
        let lines = s.overlay_lines();
        let tree = &s.selection.as_ref().unwrap().first().trace.samples[0].tree;
        let shadows = tree.rays[term.ray].shadows.iter().filter(|sh| Some(sh.light) == term.light).count();
        assert!(segments(&lines, HIGHLIGHT_COLOR) > shadows, "its shadow rays and the light");
        // A ray's row: that ray, once.
        s.highlight = Some(Highlight { sample: 0, ray: 1, light: None });
        let ray = &tree.rays[1];
        let lines = s.overlay_lines();
        let hl: Vec<_> = lines.chunks(2).filter(|v| v[0].color == HIGHLIGHT_COLOR).collect();
        assert_eq!(hl.len(), 1);
        assert_eq!(hl[0][0].pos, ray.origin);
        // A new selection forgets the row.
        s.select_pixel(10, 10);
        assert_eq!(s.highlight, None);
    }

    #[test]
    fn skipped_light_points_are_drawn() {
        // A sphere lit from straight behind as the camera sees it: the light is behind the
        // surface the camera ray hits.
        let dir = std::env::temp_dir().join(format!("rayscope-skipped-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("s.toml");
        let scene = |light: Vec3| {
            format!(
                "[[sphere]]\ncenter = [0, 0, 0]\nradius = 0.5\n[[light]]\nkind = \"point\"\nposition = [{}, {}, {}]\n\
                 color = [1, 1, 1]\n",
                light.x, light.y, light.z
            )
        };
        std::fs::write(&file, scene(Vec3::Y * 10.0)).unwrap();
        let eye = Vec3::from(ViewerState::new(file.to_str().unwrap(), None).camera().start.position);
        std::fs::write(&file, scene(-3.0 * eye)).unwrap();
        let mut s = ViewerState::new(file.to_str().unwrap(), None);
        assert!(s.error.is_none(), "{:?}", s.error);
        s.select_pixel(400, 400);
        let tree = &s.selection.as_ref().unwrap().first().trace.samples[0].tree;
        let skipped = tree.rays.iter().map(|r| r.skipped_lights.len()).sum::<usize>();
        assert!(skipped > 0, "the sphere's front faces the camera, the light is behind it");
        assert_eq!(segments(&s.overlay_lines(), SKIPPED_COLOR), 3 * skipped);
        std::fs::remove_dir_all(&dir).unwrap();
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
