//! The eframe application: panels, the viewport and its mouse controls, the worker, and the
//! headless screenshot mode.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use egui::{Color32, Key, PointerButton, Pos2, Rect, Sense, Stroke, Vec2};
use rayscope::camera::CameraMotion;
use rayscope::debug::SampleChoice;
use rayscope::film::FloatImage;
use rayscope::output::{Encoding, write_image};
use rayscope::record::RayTree;
use rayscope::scene::builtin;
use rayscope::settings::{MAX_DEPTH, PixelFilter, RenderSettings, ShadingModel, TextureFilter};

use crate::files::{BrowserAction, FileBrowser};
use crate::overlay::{ColorBy, LineKind, legend};
use crate::plural::counted;
use crate::preview::{Backdrop, LineVertex, OverlayDraw, Preview};
use crate::session::{NO_DISPLAY_HINT, check_display};
use crate::state::{BvhTree, Highlight, ModeChoice, OverlayKey, PixelDebug, PixelRect, ViewKind, ViewerState};
use crate::worker::{FalseColour, FrameImage, RenderJob, Worker};

/// The most rays the ray-tree panel lists: each is a widget drawn every frame, and a tree
/// can hold up to [`crate::state::RECORDED_RAYS`].
const LISTED_RAYS: usize = 1000;

/// How the viewer starts.
#[derive(Clone, Debug, Default)]
pub struct ViewerOptions {
    /// Built-in scene name, `.toml` or `.obj` file.
    pub scene: String,
    /// Asset folder for scenes that need the course's files.
    pub assets: Option<PathBuf>,
    /// Render settings to start with (default: the scene's).
    pub settings: Option<RenderSettings>,
    /// Start in this view.
    pub view: Option<ViewKind>,
    /// Debug this pixel from the start.
    pub debug_pixel: Option<(u32, u32)>,
    /// Debug this rectangle of pixels from the start (up to 64 of them; after `debug_pixel`).
    pub debug_rect: Option<PixelRect>,
    /// Overlay line width in points (default [`crate::state::DEFAULT_LINE_WIDTH`]).
    pub line_width: Option<f32>,
    /// Which samples of the debugged pixels to trace (default all).
    pub samples: Option<SampleChoice>,
    /// Highlight this row (from 0) of the first debugged pixel's explanation table.
    pub explain_row: Option<usize>,
    /// Show this BVH level from the start.
    pub bvh_level: Option<u32>,
    /// Draw only the BVH nodes the debug pixel's camera ray entered.
    pub bvh_only_visited: bool,
    /// The tree the BVH level view draws (default: the wide tree rendering traverses).
    pub bvh_tree: Option<BvhTree>,
    /// Show this binary BVH node's SAH split candidates from the start.
    pub split_node: Option<u32>,
    /// Turn the trackball by these angles (degrees about x and y) after selecting the debug
    /// pixel, to look at its ray tree from the side.
    pub orbit: Option<(f32, f32)>,
    /// Headless use: after `frames` ray-traced frames, save a screenshot of the window here
    /// and quit.
    pub screenshot: Option<PathBuf>,
    /// Frames to render before the screenshot; fewer when the image is complete sooner (the
    /// heat map is one frame; dynamic accumulation stops at its maximum samples).
    pub frames: u32,
    /// An image to compare with ours (see [`crate::compare`]).
    pub compare: Option<PathBuf>,
    /// Interpolate every keyframed path of the scene this way (default: the scene file's).
    pub motion_interpolation: Option<rayscope::motion::Interpolation>,
    /// Colour the overlay's rays this way (default: by depth).
    pub color_by: Option<crate::overlay::ColorBy>,
    /// The environment map's flags, over the scene file's (`--env-map`, `--env-intensity`,
    /// `--env-rotation`).
    pub environment: crate::environment::EnvOverride,
    /// Which of bloom's layers the ray-traced view shows.
    pub bloom_layer: crate::bloom::BloomLayer,
}

/// Open the viewer window; returns when it closes (or, with a screenshot, once it is saved).
pub fn run(opts: ViewerOptions) -> anyhow::Result<()> {
    check_display()?;
    let outcome: Arc<Mutex<Option<Result<(), String>>>> = Arc::new(Mutex::new(None));
    let out = outcome.clone();
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1440.0, 900.0]).with_title("rayscope"),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let headless = opts.screenshot.is_some();
    eframe::run_native(
        "rayscope",
        native,
        Box::new(move |cc| {
            let mut app = RayscopeApp::new(cc, opts);
            app.outcome = out;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("the viewer window failed: {e}; {NO_DISPLAY_HINT}"))?;
    match outcome.lock().unwrap().take() {
        Some(Err(e)) => anyhow::bail!(e),
        None if headless => anyhow::bail!("the viewer closed before the screenshot was taken"),
        _ => Ok(()),
    }
}

struct Headless {
    path: PathBuf,
    frames: u32,
    requested: bool,
    saved: Arc<Mutex<Option<Result<(), String>>>>,
    started: Instant,
}

/// The viewer application.
pub struct RayscopeApp {
    /// Everything the viewer shows and edits.
    pub state: ViewerState,
    worker: Worker,
    preview: Option<Preview>,
    traced: Option<egui::TextureHandle>,
    /// The environment map behind the raster view.
    env_background: crate::environment::BackgroundCache,
    last_frame: Option<FrameImage>,
    last_job: Option<(u64, CameraMotion, Option<FalseColour>, u32, u32)>,
    headless: Option<Headless>,
    outcome: Arc<Mutex<Option<Result<(), String>>>>,
    browser: Option<FileBrowser>,
    save_path: String,
    status: String,
    /// The rectangle of the viewport image in the last frame (points).
    pub image_rect: Option<Rect>,
    watched: Option<(PathBuf, Option<std::time::SystemTime>)>,
    /// The overlay's lines, what they were made from, and a number that changes with them
    /// (so that the preview uploads them again only then).
    overlay: Option<(OverlayKey, u64, Vec<LineVertex>)>,
    last_watch: Option<Instant>,
    /// Where a rectangle-selecting drag started (screen position).
    rect_drag: Option<Pos2>,
}

impl RayscopeApp {
    /// Create the app for `cc` with `opts`.
    pub fn new(cc: &eframe::CreationContext<'_>, opts: ViewerOptions) -> RayscopeApp {
        let spec = if opts.scene.is_empty() { builtin::DEFAULT_SCENE.to_string() } else { opts.scene.clone() };
        let mut state = ViewerState::new(&spec, opts.assets.clone());
        if let Some(i) = opts.motion_interpolation {
            state.set_motion_interpolation(i);
        }
        if let Some(c) = opts.color_by {
            state.color_by = c;
        }
        if opts.environment != crate::environment::EnvOverride::default() {
            state.env = opts.environment.clone();
            state.reload();
        }
        state.bloom_layer = opts.bloom_layer;
        if let Some(s) = opts.settings.clone() {
            state.set_settings(s);
        }
        if let Some(path) = &opts.compare {
            state.load_compare(path);
        }
        if let Some(s) = opts.samples {
            state.samples = s;
        }
        if let Some(v) = opts.view {
            state.view = v;
        }
        if let Some(tree) = opts.bvh_tree {
            state.bvh_tree = tree;
        }
        state.bvh_level = opts.bvh_level.map(|l| l.min(state.bvh_levels()));
        state.bvh_only_visited = opts.bvh_only_visited;
        state.split = opts.split_node.map(|n| crate::split::SplitView::new(&state.scene, n));
        if let Some((x, y)) = opts.debug_pixel {
            let (x, y) = (x.min(state.settings.width - 1), y.min(state.settings.height - 1));
            state.select_pixel(x, y);
        }
        if let Some(r) = opts.debug_rect {
            state.select_rect(r);
        }
        if let Some(w) = opts.line_width {
            state.line_width = w;
        }
        if let Some(row) = opts.explain_row {
            state.highlight_term(row);
        }
        if let Some((dx, dy)) = opts.orbit {
            state.trackball.rotation.x = (state.trackball.rotation.x + dx).clamp(-89.0, 89.0);
            state.trackball.rotation.y += dy;
        }
        let ctx = cc.egui_ctx.clone();
        let worker = Worker::new(move || ctx.request_repaint());
        let preview = cc.wgpu_render_state.as_ref().map(|rs| Preview::new(&rs.device));
        let headless = opts.screenshot.clone().map(|path| Headless {
            path,
            frames: opts.frames.max(1),
            requested: false,
            saved: Arc::new(Mutex::new(None)),
            started: Instant::now(),
        });
        RayscopeApp {
            state,
            worker,
            preview,
            traced: None,
            env_background: Default::default(),
            last_frame: None,
            last_job: None,
            headless,
            outcome: Arc::new(Mutex::new(None)),
            browser: None,
            save_path: "rayscope.png".into(),
            status: String::new(),
            image_rect: None,
            watched: None,
            overlay: None,
            last_watch: None,
            rect_drag: None,
        }
    }

    /// Reload the scene when its file changes on disk (checked about once a second).
    fn watch_scene_file(&mut self, ctx: &egui::Context) {
        let Some(path) = self.state.scene_file() else {
            self.watched = None;
            return;
        };
        if self.last_watch.is_some_and(|t| t.elapsed().as_millis() < 1000) {
            return;
        }
        self.last_watch = Some(Instant::now());
        let modified = std::fs::metadata(&path).and_then(|m| m.modified()).ok();
        match &self.watched {
            Some((p, m)) if *p == path => {
                if *m != modified {
                    self.state.reload();
                    self.status = format!("reloaded {}", path.display());
                    self.watched = Some((path, modified));
                }
            }
            _ => self.watched = Some((path, modified)),
        }
        ctx.request_repaint_after(std::time::Duration::from_secs(1));
    }

    /// The newest ray-traced frame shown.
    pub fn last_frame(&self) -> Option<&FrameImage> {
        self.last_frame.as_ref()
    }

    /// With a screenshot to take: whether it was saved (or why not), once the app is done and
    /// has asked its window to close; `None` until then.
    pub fn headless_outcome(&self) -> Option<Result<(), String>> {
        self.outcome.lock().unwrap().clone()
    }

    /// Frames the worker has delivered.
    pub fn frames_delivered(&self) -> u64 {
        self.worker.frames_posted()
    }

    fn poll_worker(&mut self, ctx: &egui::Context) {
        if let Some(f) = self.worker.take_frame()
            && f.generation == self.state.generation
        {
            let img = egui::ColorImage::from_rgba_unmultiplied([f.width as usize, f.height as usize], &f.rgba);
            match &mut self.traced {
                Some(t) => t.set(img, egui::TextureOptions::NEAREST),
                None => self.traced = Some(ctx.load_texture("rayscope traced", img, egui::TextureOptions::NEAREST)),
            }
            self.last_frame = Some(f);
        }
    }

    fn submit_job(&mut self) {
        let camera = self.state.camera();
        let false_colour = match self.state.view {
            ViewKind::HeatMap => Some(FalseColour::HeatMap),
            ViewKind::MipLevels => Some(FalseColour::MipLevels),
            _ => None,
        };
        let key = (self.state.generation, camera.clone(), false_colour, self.state.max_spp, self.state.exposure_frames);
        if self.last_job.as_ref() == Some(&key) {
            return;
        }
        self.last_job = Some(key);
        self.worker.submit(RenderJob {
            scene: self.state.scene.clone(),
            settings: self.state.settings.clone(),
            mode: self.state.imaging_mode(),
            camera,
            false_colour,
            max_spp: self.state.max_spp,
            generation: self.state.generation,
            bloom_layer: self.state.bloom_layer,
        });
    }

    fn top_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.strong("rayscope");
            ui.separator();
            let mut pick: Option<String> = None;
            egui::ComboBox::from_label("Scene").selected_text(self.state.scene_spec.clone()).show_ui(ui, |ui| {
                for b in builtin::BUILTINS {
                    let r = ui.selectable_label(self.state.scene_spec == b.name, b.name).on_hover_text(b.description);
                    if r.clicked() {
                        pick = Some(b.name.to_string());
                    }
                }
            });
            if ui
                .button("Open scene/mesh…")
                .on_hover_text("Open a .toml scene file or a mesh: .obj, .ply, .gltf or .glb")
                .clicked()
            {
                let dir = std::env::current_dir().unwrap_or_default();
                self.browser = Some(FileBrowser::new(dir));
            }
            if crate::scene_file::has_contents(&self.state.scene)
                && ui.button("Scene file").on_hover_text("What the scene's files hold and what was skipped").clicked()
            {
                crate::scene_file::open(ui.ctx());
            }
            if ui
                .button("Reload")
                .on_hover_text(
                    "Load the current scene again from its files (scene files reload by themselves when they change)",
                )
                .clicked()
            {
                self.state.reload();
            }
            if let Some(spec) = pick {
                self.state.load_scene(&spec);
            }
            if let Some(e) = &self.state.error {
                ui.colored_label(Color32::LIGHT_RED, format!("⚠ {e}"));
            }
        });
    }

    fn settings_panel(&mut self, ui: &mut egui::Ui) {
        let st = &mut self.state;
        egui::CollapsingHeader::new("View").default_open(true).show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.selectable_value(&mut st.view, ViewKind::Raster, "Raster")
                    .on_hover_text("The rasterized GPU preview with the debugger's drawings (Tab toggles)");
                ui.selectable_value(&mut st.view, ViewKind::RayTraced, "Ray traced")
                    .on_hover_text("The ray-traced image (Tab toggles)");
                ui.selectable_value(&mut st.view, ViewKind::HeatMap, "Heat map")
                    .on_hover_text("BVH node boxes each camera ray tested: blue fewest, red most");
                ui.selectable_value(&mut st.view, ViewKind::MipLevels, "Mip levels").on_hover_text(
                    "The mip level trilinear filtering reads at each pixel's first textured hit, from its ray cone \
                     (through mirrors): blue the texels, red the 1x1 mean, grey no texture",
                );
            });
            if st.compare.is_some() {
                ui.horizontal(|ui| {
                    for (view, label, tip) in crate::compare::COMPARE_VIEWS {
                        ui.selectable_value(&mut st.view, view, label).on_hover_text(tip);
                    }
                });
            }
            if st.view == ViewKind::HeatMap
                && let Some(scale) = self.last_frame.as_ref().and_then(|f| f.heat)
            {
                scale.legend(ui);
            }
            if st.view == ViewKind::MipLevels
                && let Some(scale) = self.last_frame.as_ref().and_then(|f| f.mips)
            {
                scale.legend(ui);
            }
        });
        egui::CollapsingHeader::new("Environment map").default_open(true).show(ui, |ui| {
            crate::environment::panel(ui, st);
        });
        egui::CollapsingHeader::new("Bloom").default_open(true).show(ui, |ui| crate::bloom::panel(ui, st));
        egui::CollapsingHeader::new("Imaging mode").default_open(true).show(ui, |ui| {
            let mut mode = st.mode;
            ui.radio_value(&mut mode, ModeChoice::Continuous, "Continuous")
                .on_hover_text("Every frame is rendered afresh with its own anti-aliasing samples");
            ui.radio_value(&mut mode, ModeChoice::Dynamic, "Dynamic")
                .on_hover_text("A running average that restarts when a setting or the camera changes");
            ui.radio_value(&mut mode, ModeChoice::Exposure, "Manual exposure")
                .on_hover_text("Accumulate a number of frames; moving the camera meanwhile blurs the image");
            st.set_mode(mode);
            ui.add(egui::Slider::new(&mut st.exposure_frames, 1..=256).text("Exposure frames"))
                .on_hover_text("Frames in one exposure");
            if ui.button("Expose").on_hover_text("Start a new exposure of that many frames").clicked() {
                st.expose();
            }
            ui.add(egui::Slider::new(&mut st.max_spp, 1..=4096).logarithmic(true).text("Max samples"))
                .on_hover_text("Dynamic mode stops refining at this many samples per pixel");
            if let Some(f) = self.last_frame.as_ref().filter(|f| f.heat.is_none() && f.mips.is_none()) {
                ui.label(format!(
                    "{}, {}/pixel, {:.2} Mrays/s",
                    counted(f.frames.into(), "frame", "frames"),
                    counted(f.spp.into(), "sample", "samples"),
                    f.mrays_per_s
                ));
            }
        });
        let mut s = st.settings.clone();
        egui::CollapsingHeader::new("Rendering").default_open(true).show(ui, |ui| {
            ui.checkbox(&mut s.shading, "Shading").on_hover_text("Phong shading; off shows the unlit diffuse colour");
            egui::ComboBox::from_label("Shading model")
                .selected_text(s.shading_model.name())
                .show_ui(ui, |ui| {
                    for m in ShadingModel::ALL {
                        ui.selectable_value(&mut s.shading_model, m, m.name());
                    }
                })
                .response
                .on_hover_text(
                    "The scene-wide shading model: phong, blinn-phong (half-vector highlight), lambert (no highlight) \
                 or gradient (the diffuse colour read from the material's gradient by n.l); a material's own \
                 `model` wins",
                );
            ui.checkbox(&mut s.shadows, "Shadows").on_hover_text("Cast shadow rays to the lights");
            ui.checkbox(&mut s.reflections, "Reflections").on_hover_text("Recursive mirror/glossy reflection");
            ui.checkbox(&mut s.transparency, "Transparency").on_hover_text("See through materials with d < 1");
            ui.checkbox(&mut s.textures, "Textures").on_hover_text("Use diffuse textures (map_Kd)");
            ui.checkbox(&mut s.interpolate_normals, "Interpolated normals")
                .on_hover_text("Blend vertex normals across triangles (smooth shading)");
            ui.add(egui::Slider::new(&mut s.max_depth, 0..=MAX_DEPTH).text("Max recursion depth"))
                .on_hover_text("Rays at this depth cast no reflection or transmission ray");
            ui.add(
                egui::Slider::new(&mut s.adc_bailout, 0.0..=1.0)
                    .logarithmic(true)
                    .smallest_positive(1e-5)
                    .text("ADC bailout"),
            )
            .on_hover_text(
                "Adaptive depth control: no reflection or transmission ray whose weight (the share of its light \
                 that reaches the pixel) is below this; 0 turns it off",
            );
            ui.add(egui::Slider::new(&mut s.spp, 1..=64).text("Anti-aliasing rays"))
                .on_hover_text("Camera rays per pixel in each frame");
            ui.add(egui::Slider::new(&mut s.light_samples, 0..=256).text("Rays per light"))
                .on_hover_text("Shadow rays per area light (soft shadows); 0 shades from the light's centre");
            ui.add(egui::Slider::new(&mut s.gloss_samples, 0..=128).text("Gloss rays"))
                .on_hover_text("Rays per glossy reflection; 0 reflects as a perfect mirror");
            egui::ComboBox::from_label("Pixel filter").selected_text(format!("{:?}", s.filter)).show_ui(ui, |ui| {
                for f in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Gaussian] {
                    ui.selectable_value(&mut s.filter, f, format!("{f:?}"));
                }
            });
            egui::ComboBox::from_label("Texture filter")
                .selected_text(format!("{:?}", s.texture_filter))
                .show_ui(ui, |ui| {
                    let tips = [
                        (TextureFilter::Nearest, "The texel under the point"),
                        (TextureFilter::Bilinear, "A blend of the four nearest texels"),
                        (
                            TextureFilter::Trilinear,
                            "Mipmapping: the texture's pyramid read at the level of the ray cone's footprint \
                             (see the Mip levels view)",
                        ),
                    ];
                    for (f, tip) in tips {
                        ui.selectable_value(&mut s.texture_filter, f, format!("{f:?}")).on_hover_text(tip);
                    }
                })
                .response
                .on_hover_text("How textures are filtered; trilinear averages what a pixel covers, far away too");
            crate::lens::lens_panel(ui, &mut s, st.trackball.distance);
        });
        st.set_settings(s);
        egui::CollapsingHeader::new("Camera").default_open(true).show(ui, |ui| {
            let t = st.trackball;
            ui.label(format!(
                "rotation ({:.0}, {:.0}, {:.0}), distance {:.2}",
                t.rotation.x, t.rotation.y, t.rotation.z, t.distance
            ));
            ui.label(
                "Drag: orbit · right/shift-drag: pan · wheel: zoom · click: debug a pixel · Ctrl-drag (or the \
                 rectangle tool): debug a rectangle of pixels · Alt-click: focus the lens there",
            );
            if ui.button("Reset camera").on_hover_text("Back to the scene's camera").clicked() {
                st.reset_camera();
            }
        });
        egui::CollapsingHeader::new("Motion").default_open(true).show(ui, |ui| crate::motion::panel(ui, st));
        egui::CollapsingHeader::new("Render to file").default_open(true).show(ui, |ui| {
            ui.text_edit_singleline(&mut self.save_path).on_hover_text("A .png, .exr or .pfm path");
            if ui.button("Save image").on_hover_text("Write the current ray-traced image (atomically)").clicked() {
                self.status = match &self.last_frame {
                    None => "no ray-traced image yet".into(),
                    Some(f) => match write_image(&f.image, std::path::Path::new(&self.save_path), Encoding::Linear) {
                        Ok(()) => format!("saved {} ({} spp)", self.save_path, f.spp),
                        Err(e) => format!("error: {e}"),
                    },
                };
            }
            if !self.status.is_empty() {
                ui.label(&self.status);
            }
        });
    }

    fn debugger_panel(&mut self, ui: &mut egui::Ui) {
        let st = &mut self.state;
        egui::CollapsingHeader::new("Selected pixel").default_open(true).show(ui, |ui| match &st.selection {
            None => {
                ui.label("Click the image to trace a pixel; Ctrl-drag to trace a rectangle of pixels.");
            }
            Some(sel) => {
                if sel.pixels.len() > 1 {
                    let (a, b) = (sel.first().pixel, sel.pixels.last().expect("not empty").pixel);
                    ui.label(format!(
                        "{} from ({}, {}) to ({}, {}), drawn together",
                        counted(sel.pixels.len() as u64, "pixel", "pixels"),
                        a.0,
                        a.1,
                        b.0,
                        b.1
                    ));
                }
                if let Some(note) = &sel.clamped {
                    ui.colored_label(ui.visuals().warn_fg_color, note);
                }
                for p in sel.pixels.iter().take(4) {
                    pixel_swatch(ui, p);
                }
                if sel.pixels.len() > 4 {
                    ui.label(format!("… and {} more", sel.pixels.len() - 4));
                }
            }
        });
        if let Some(c) = &st.compare
            && c.panel(ui, st.selection.as_ref().map(|s| s.first().pixel), &st.settings)
        {
            st.recompare();
        }
        let mut clear = false;
        if let Some(sel) = &st.selection {
            let mut listed = 0;
            let several = sel.pixels.len() > 1;
            for (n, p) in sel.pixels.iter().enumerate() {
                for (k, sample) in p.trace.samples.iter().enumerate() {
                    let rays = counted(sample.tree.rays.len() as u64, "ray", "rays");
                    let of_pixel = if several { format!(" of ({}, {})", p.pixel.0, p.pixel.1) } else { String::new() };
                    let of_sample =
                        if p.trace.samples.len() > 1 { format!(" sample {}", sample.index) } else { String::new() };
                    let title = format!("Ray tree{of_pixel}{of_sample} ({rays}, time {:.3})", sample.time);
                    egui::CollapsingHeader::new(title).id_salt(("tree", n, k)).default_open(n == 0 && k == 0).show(
                        ui,
                        |ui| {
                            ray_list(ui, st, &sample.tree, (p.pixel, sample.index), &mut listed);
                        },
                    );
                }
            }
            if ui.button("Clear selection").on_hover_text("Stop debugging these pixels").clicked() {
                clear = true;
            }
        }
        if clear {
            st.selection = None;
        }
        egui::CollapsingHeader::new("Samples").default_open(true).show(ui, |ui| {
            let spp = st.settings.spp.max(1);
            let mut choice = st.samples;
            ui.horizontal(|ui| {
                ui.radio_value(&mut choice, SampleChoice::All, "All samples").on_hover_text(
                    "Trace every sample of the pixel with the current settings (anti-aliasing, light and gloss \
                     samples, lens, shutter time): their mean is the rendered pixel",
                );
                let one = matches!(choice, SampleChoice::One(_));
                if ui.radio(one, "One sample").on_hover_text("Trace one sample, chosen by its index").clicked() && !one
                {
                    choice = SampleChoice::One(0);
                }
            });
            if let SampleChoice::One(k) = &mut choice {
                ui.add(egui::Slider::new(k, 0..=spp - 1).text("Sample index")).on_hover_text(
                    "Which sample (0 to anti-aliasing rays - 1); it selects the sample's random numbers",
                );
            }
            st.set_samples(choice);
        });
        if st.selection.is_some() {
            egui::CollapsingHeader::new("Explanation").default_open(true).show(ui, |ui| explanation_table(ui, st));
        }
        egui::CollapsingHeader::new("Overlay").default_open(true).show(ui, |ui| {
            for kind in LineKind::ALL {
                let mut on = st.shown.contains(kind);
                if ui.checkbox(&mut on, kind.label()).on_hover_text(kind.tooltip()).changed() {
                    st.shown.set(kind, on);
                }
            }
            ui.add(egui::Slider::new(&mut st.max_depth_shown, 0..=MAX_DEPTH).text("Max depth shown"))
                .on_hover_text("Draw rays up to this recursion depth (0: camera rays only), with their shadow rays");
            ui.add(egui::Slider::new(&mut st.line_width, 1.0..=8.0).text("Line width"))
                .on_hover_text("Width of the overlay's lines, in points");
            ui.horizontal(|ui| {
                ui.label("Colour rays by");
                ui.radio_value(&mut st.color_by, ColorBy::Depth, "depth")
                    .on_hover_text("The camera ray white, then warmer colours per bounce (as the course does)");
                ui.radio_value(&mut st.color_by, ColorBy::Kind, "kind")
                    .on_hover_text("Camera, reflection, glossy and transmission rays each in their own colour");
                ui.radio_value(&mut st.color_by, ColorBy::Time, "time").on_hover_text(
                    "Each sample's rays by its shutter time: blue when the shutter opens, orange when it closes \
                     (motion blur: where moving things were for that sample)",
                );
            });
            ui.checkbox(&mut st.rect_tool, "Select rectangle by dragging").on_hover_text(
                "A drag selects a rectangle of pixels (up to 64) instead of orbiting; Ctrl-drag does so always",
            );
            ui.label("Lines are solid in front of the scene's surfaces and faded where a surface hides them.");
            egui::CollapsingHeader::new("Legend").default_open(false).show(ui, |ui| {
                for e in legend(st.color_by) {
                    ui.horizontal(|ui| {
                        let (r, _) = ui.allocate_exact_size(Vec2::new(22.0, 10.0), Sense::hover());
                        let [cr, cg, cb, ca] = e.color.map(|c| (c * 255.0) as u8);
                        ui.painter().rect_filled(r, 1.0, Color32::from_rgba_unmultiplied(cr, cg, cb, ca));
                        ui.label(&e.meaning);
                    });
                }
            });
        });
        egui::CollapsingHeader::new("BVH").default_open(true).show(ui, |ui| {
            let stats = st.scene.bvh_stats();
            ui.label(format!(
                "binary tree: {}, {}, {}, {:.1} primitives per leaf; wide tree: {}",
                counted(stats.nodes as u64, "node", "nodes"),
                counted(stats.leaves as u64, "leaf", "leaves"),
                counted(stats.levels as u64, "level", "levels"),
                stats.mean_leaf_size,
                counted(st.scene.wide_levels() as u64, "level", "levels"),
            ));
            ui.horizontal(|ui| {
                ui.label("Tree");
                ui.radio_value(&mut st.bvh_tree, BvhTree::Wide, "wide (rendered)")
                    .on_hover_text("The 8- or 16-wide tree the renderer traverses");
                ui.radio_value(&mut st.bvh_tree, BvhTree::Binary, "binary (course)")
                    .on_hover_text("The course's binary tree, built first and collapsed into the wide one");
            });
            let mut on = st.bvh_level.is_some();
            ui.checkbox(&mut on, "Show BVH level")
                .on_hover_text("Draw the boxes of one level (and the leaves above it)");
            let mut level = st.bvh_level.unwrap_or(0);
            let levels = st.bvh_levels();
            ui.add_enabled(on, egui::Slider::new(&mut level, 0..=levels.saturating_sub(1)).text("Level"))
                .on_hover_text("0 is the root");
            st.bvh_level = on.then_some(level.min(levels.saturating_sub(1)));
            ui.checkbox(&mut st.bvh_only_visited, "Only nodes the selected ray visited").on_hover_text(
                "Of that level, draw only the nodes the selected rays entered: in the wide tree, those the \
                     renderer's own traversals entered for every ray of the trees (recorded); in the binary tree, \
                     those a replay of the camera rays enters",
            );
            let mut on = st.split.is_some();
            ui.checkbox(&mut on, "SAH split candidates").on_hover_text(
                "For a node of the binary tree: every candidate split plane of the builder's binned SAH drawn \
                 across the node's box (x red, y green, z blue; the plane taken yellow) and their costs charted",
            );
            let mut node = st.split.as_ref().map_or(0, |v| v.node);
            let nodes = st.scene.geometry.bvh.nodes.len().max(1) as u32;
            ui.add_enabled(on, egui::Slider::new(&mut node, 0..=nodes - 1).text("Node")).on_hover_text(
                "The node's index in the binary tree's depth-first array (0 is the root; its first child follows it)",
            );
            if !on {
                st.split = None;
            } else if st.split.as_ref().is_none_or(|v| v.node != node) {
                st.split = Some(crate::split::SplitView::new(&st.scene, node));
            }
            if let Some(v) = &st.split {
                v.panel(ui);
            }
        });
    }

    /// The preview's texture for `rect`: the scene with the overlay (the raster view) or the
    /// overlay alone on a transparent background, over the scene's depth (the other views).
    /// `None` without a GPU renderer.
    fn preview_texture(
        &mut self,
        ui: &egui::Ui,
        frame: &eframe::Frame,
        rect: Rect,
        backdrop: Backdrop,
    ) -> Option<egui::TextureId> {
        let (preview, rs) = match (&mut self.preview, frame.wgpu_render_state()) {
            (Some(p), Some(rs)) => (p, rs),
            _ => return None,
        };
        let ppp = ui.ctx().pixels_per_point();
        let size = [(rect.width() * ppp).round() as u32, (rect.height() * ppp).round() as u32];
        // The lines are made again only when what they show changes, not per frame.
        let overlay = self.state.overlay_key();
        if self.overlay.as_ref().is_none_or(|(k, ..)| *k != overlay) {
            let version = self.overlay.as_ref().map_or(0, |(_, v, _)| v + 1);
            self.overlay = Some((overlay, version, self.state.overlay_lines()));
        }
        let (_, version, lines) = self.overlay.as_ref().expect("made above");
        let key = Arc::as_ptr(&self.state.scene) as usize;
        let camera = self.state.trackball.camera();
        let draw = OverlayDraw { lines, version: *version, width_px: self.state.line_width * ppp, backdrop };
        Some(preview.render(rs, &self.state.scene, key, &camera, size, draw))
    }

    fn viewport(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) {
        let area = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(area, Sense::click_and_drag());
        let rect = self.state.image_rect(area);
        self.image_rect = Some(rect);
        let painter = ui.painter_at(area);
        let uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
        let note = |text: &str| {
            painter.text(rect.center(), egui::Align2::CENTER_CENTER, text, Default::default(), Color32::GRAY)
        };
        match self.state.view {
            ViewKind::Raster => {
                let camera = self.state.trackball.camera();
                let aspect = self.state.settings.width as f32 / self.state.settings.height as f32;
                let map = self.env_background.texture(ui.ctx(), &self.state.scene, &camera, aspect);
                if let Some(id) = map {
                    painter.image(id, rect, uv, Color32::WHITE);
                }
                let backdrop = if map.is_some() { Backdrop::SceneOverMap } else { Backdrop::Scene };
                match self.preview_texture(ui, frame, rect, backdrop) {
                    Some(id) => {
                        painter.image(id, rect, uv, Color32::WHITE);
                    }
                    None => {
                        note("no GPU renderer");
                    }
                }
            }
            view => {
                painter.rect_filled(rect, 0.0, Color32::BLACK);
                let compared = self.state.compare.as_mut().and_then(|c| c.texture(ui.ctx(), view));
                match compared.or(self.traced.as_ref().map(|t| t.id())) {
                    Some(id) => {
                        painter.image(id, rect, uv, Color32::WHITE);
                    }
                    None => {
                        note("rendering…");
                    }
                }
                // The same lines over the image: the ray tracer looks through the preview's
                // camera, so they project onto the pixels they explain.
                if let Some(id) = self.preview_texture(ui, frame, rect, Backdrop::DepthOnly) {
                    painter.image(id, rect, uv, Color32::WHITE);
                } else {
                    let corner = rect.left_top() + Vec2::splat(8.0);
                    let text = "no GPU renderer: the overlay needs it";
                    painter.text(corner, egui::Align2::LEFT_TOP, text, Default::default(), Color32::GRAY);
                }
            }
        }
        self.mark_selection(&painter, rect);
        // Mouse: click debugs a pixel; Ctrl-drag (or any drag with the rectangle tool) selects
        // a rectangle; drag orbits; right or shift drag pans; wheel zooms.
        let (shift, ctrl, alt) =
            ui.input(|i| (i.modifiers.shift, i.modifiers.command || i.modifiers.ctrl, i.modifiers.alt));
        if response.clicked()
            && let Some(p) = response.interact_pointer_pos().and_then(|pos| self.state.pixel_at(pos, rect))
        {
            if alt {
                self.status = crate::lens::focus_at(&mut self.state, p.0, p.1);
            } else {
                self.state.click_pixel(p.0, p.1);
            }
        }
        if response.drag_started_by(PointerButton::Primary) && (ctrl || self.state.rect_tool) {
            self.rect_drag = ui.input(|i| i.pointer.press_origin()).filter(|p| rect.contains(*p));
        }
        let delta = response.drag_delta();
        if let Some(from) = self.rect_drag {
            let to = response.interact_pointer_pos().unwrap_or(from);
            let pen = Stroke::new(1.5, Color32::from_rgb(255, 220, 0));
            painter.rect_stroke(Rect::from_two_pos(from, to), 0.0, pen, egui::StrokeKind::Middle);
            if response.drag_stopped() {
                self.rect_drag = None;
                let clamp = |p: Pos2| rect.clamp(p);
                let a = self.state.pixel_at(clamp(from), rect);
                let b = self.state.pixel_at(clamp(to), rect);
                if let (Some(a), Some(b)) = (a, b) {
                    self.state.select_rect(PixelRect::spanning(a, b));
                }
            }
        } else if response.dragged_by(PointerButton::Secondary)
            || (response.dragged_by(PointerButton::Primary) && shift)
        {
            self.state.trackball.pan(delta.x, delta.y, rect.height());
        } else if response.dragged_by(PointerButton::Primary) {
            self.state.trackball.orbit(delta.x, delta.y);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.state.trackball.zoom(scroll);
            }
        }
    }

    /// In the image views, mark the selected pixel (a crosshair) or rectangle (its outline).
    fn mark_selection(&self, painter: &egui::Painter, rect: Rect) {
        let Some(sel) = self.state.selection.as_ref().filter(|_| self.state.view != ViewKind::Raster) else {
            return;
        };
        let (w, h) = (self.state.settings.width as f32, self.state.settings.height as f32);
        let at = |x: f32, y: f32| Pos2::new(rect.min.x + x / w * rect.width(), rect.min.y + y / h * rect.height());
        let s = Stroke::new(1.5, Color32::from_rgb(255, 220, 0));
        let (a, b) = (sel.first().pixel, sel.pixels.last().expect("not empty").pixel);
        if sel.pixels.len() > 1 {
            let r = Rect::from_min_max(at(a.0 as f32, a.1 as f32), at(b.0 as f32 + 1.0, b.1 as f32 + 1.0));
            painter.rect_stroke(r.expand(2.0), 0.0, s, egui::StrokeKind::Outside);
        } else {
            let p = at(a.0 as f32 + 0.5, a.1 as f32 + 0.5);
            painter.circle_stroke(p, 6.0, s);
            painter.line_segment([p - Vec2::X * 10.0, p + Vec2::X * 10.0], s);
            painter.line_segment([p - Vec2::Y * 10.0, p + Vec2::Y * 10.0], s);
        }
    }

    fn headless_step(&mut self, ctx: &egui::Context) {
        let Some(h) = &mut self.headless else { return };
        if let Some(result) = h.saved.lock().unwrap().take() {
            *self.outcome.lock().unwrap() = Some(result);
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        if h.started.elapsed().as_secs() > 300 {
            *self.outcome.lock().unwrap() = Some(Err("timed out waiting for frames".into()));
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        // `frames` frames, or fewer when the view's image is complete sooner: the heat map
        // is one frame (another would be the same), and dynamic accumulation stops at its
        // maximum. Waiting for frames that never come kept the window open for ever.
        let posted = self.worker.frames_posted();
        let ready = self.last_frame.as_ref().is_some_and(|f| f.done || posted >= h.frames as u64);
        if ready && !h.requested {
            h.requested = true;
            let (path, saved, ctx2) = (h.path.clone(), h.saved.clone(), ctx.clone());
            ctx.request_screenshot(move |image| {
                let [w, hgt] = image.size;
                let data = image.pixels.iter().flat_map(|c| [c.r(), c.g(), c.b()]).map(|v| v as f32 / 255.0).collect();
                let img = FloatImage { width: w as u32, height: hgt as u32, channels: 3, data };
                let r = write_image(&img, &path, Encoding::Linear).map_err(|e| e.to_string());
                *saved.lock().unwrap() = Some(r);
                ctx2.request_repaint();
            });
        }
        ctx.request_repaint();
    }
}

/// A debugged pixel's position, colour swatch and value.
fn pixel_swatch(ui: &mut egui::Ui, p: &PixelDebug) {
    ui.horizontal(|ui| {
        ui.label(format!("pixel ({}, {})", p.pixel.0, p.pixel.1));
        let color = p.color();
        let c = color.clamp(glam::Vec3::ZERO, glam::Vec3::ONE) * 255.0;
        let (r, _) = ui.allocate_exact_size(Vec2::splat(14.0), Sense::hover());
        ui.painter().rect_filled(r, 2.0, Color32::from_rgb(c.x as u8, c.y as u8, c.z as u8));
        ui.label(format!("({:.3}, {:.3}, {:.3})", color.x, color.y, color.z));
    });
}

/// The rays of one sample's tree, each a collapsible entry (`salt`: the pixel and sample, for
/// their ids); `listed` counts the entries of every tree so far, which stop at [`LISTED_RAYS`].
fn ray_list(ui: &mut egui::Ui, st: &ViewerState, tree: &RayTree, salt: ((u32, u32), u32), listed: &mut usize) {
    if let Some(cut) = &tree.cut {
        ui.colored_label(ui.visuals().warn_fg_color, format!("Tree cut: {cut}"));
    }
    let room = LISTED_RAYS.saturating_sub(*listed);
    for (i, r) in tree.rays.iter().enumerate().take(room) {
        let title = format!("#{i} {:?} · depth {}", r.kind, r.depth);
        egui::CollapsingHeader::new(title).id_salt(("ray", salt, i)).default_open(i < 4).show(ui, |ui| {
            match &r.hit {
                None => {
                    ui.label("missed");
                }
                Some(h) => {
                    let mat = &st.scene.materials[h.material as usize];
                    ui.label(format!("hit at t = {:.4}", h.t));
                    ui.label(format!("primitive {} · material '{}'", h.prim, mat.name));
                }
            }
            ui.label(format!("colour ({:.3}, {:.3}, {:.3})", r.color[0], r.color[1], r.color[2]));
            let reached = r.shadows.iter().filter(|s| s.blocked_at.is_none()).count();
            if !r.shadows.is_empty() {
                let rays = counted(r.shadows.len() as u64, "shadow ray", "shadow rays");
                ui.label(format!("{rays}: {reached} reached, {} blocked", r.shadows.len() - reached));
            }
            for stopped in &r.stopped {
                ui.label(format!("adaptive depth control: {stopped}"));
            }
            skipped_lights(ui, r);
        });
    }
    *listed += tree.rays.len().min(room);
    if let Some(more) = tree.rays.len().checked_sub(room).filter(|&n| n > 0) {
        ui.label(format!(
            "… and {} more, not listed here (`rayscope debug` prints them all)",
            counted(more as u64, "ray", "rays")
        ));
    }
}

/// The light points skipped at a ray's hit, counted per light and reason: "light 0: 3 points
/// skipped, behind the surface (shading normal)".
fn skipped_lights(ui: &mut egui::Ui, r: &rayscope::record::RecordedRay) {
    let mut groups: Vec<(usize, rayscope::record::SkipReason, u64)> = Vec::new();
    for s in &r.skipped_lights {
        match groups.iter_mut().find(|g| g.0 == s.light && g.1 == s.reason) {
            Some(g) => g.2 += 1,
            None => groups.push((s.light, s.reason, 1)),
        }
    }
    for (light, reason, n) in groups {
        let points = counted(n, "point", "points");
        ui.label(format!("light {light}: {points} skipped (no shadow ray), {reason}"));
    }
}

/// Three decimals per channel, one number when they are equal.
fn rgb3(c: glam::Vec3) -> String {
    if c.x == c.y && c.y == c.z { format!("{:.3}", c.x) } else { format!("({:.3}, {:.3}, {:.3})", c.x, c.y, c.z) }
}

/// The first selected pixel's value as a sum of terms, one row per term; a click on a row
/// highlights its ray, or its light and shadow rays, in 3D.
fn explanation_table(ui: &mut egui::Ui, st: &mut ViewerState) {
    let Some(p) = st.selection.as_ref().map(|s| s.first()) else { return };
    let e = &p.explanation;
    ui.label(format!("pixel ({}, {}) = the sum of these terms (click a row to see it in 3D)", p.pixel.0, p.pixel.1));
    let mut pick = None;
    egui::ScrollArea::both().max_height(320.0).id_salt("explanation").show(ui, |ui| {
        egui::Grid::new("explanation-grid").striped(true).show(ui, |ui| {
            for h in ["sample", "ray", "term", "factors", "value", "x weight", "x share", "= adds"] {
                ui.strong(h);
            }
            ui.end_row();
            for (i, t) in e.terms.iter().enumerate() {
                let here = Highlight { sample: t.sample, ray: t.ray, light: t.light };
                let on = st.highlight == Some(here);
                if ui.selectable_label(on, t.sample.to_string()).clicked() {
                    pick = Some(if on { None } else { Some(here) });
                }
                let kind = e.rays.iter().find(|r| r.sample == t.sample && r.ray == t.ray).map(|r| r.kind.noun());
                if ui.selectable_label(on, format!("#{} {}", t.ray, kind.unwrap_or(""))).clicked() {
                    pick = Some(Some(Highlight { light: None, ..here }));
                }
                let light = t.light.map_or(String::new(), |l| format!(" light {l}"));
                ui.label(format!("{}{light}", t.kind.name())).on_hover_text(format!("term {i}"));
                ui.label(t.factors_text());
                ui.label(rgb3(t.value));
                ui.label(rgb3(t.path_weight));
                ui.label(format!("{:.3}", t.sample_weight));
                ui.label(rgb3(t.contribution));
                ui.end_row();
            }
        });
    });
    ui.label(format!("sum of the terms: ({:.6}, {:.6}, {:.6})", e.sum.x, e.sum.y, e.sum.z));
    ui.label(format!("the pixel (renderer): ({:.6}, {:.6}, {:.6})", e.value.x, e.value.y, e.value.z));
    if !e.complete {
        ui.colored_label(ui.visuals().warn_fg_color, "a ray tree was cut: the terms of unrecorded rays are missing");
    }
    for s in &e.dropped_samples {
        ui.label(format!("sample {s}: not finite, added as black"));
    }
    if let Some(h) = pick {
        st.highlight = h;
    }
}

impl eframe::App for RayscopeApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.poll_worker(&ctx);
        self.watch_scene_file(&ctx);
        if ctx.input(|i| i.key_pressed(Key::Tab)) {
            self.state.view = if self.state.view == ViewKind::Raster { ViewKind::RayTraced } else { ViewKind::Raster };
        }
        egui::Panel::top("rayscope-top").show(ui, |ui| self.top_bar(ui));
        egui::Panel::left("rayscope-settings").resizable(true).default_size(290.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| self.settings_panel(ui));
        });
        egui::Panel::right("rayscope-debugger").resizable(true).default_size(320.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| self.debugger_panel(ui));
        });
        egui::CentralPanel::no_frame().show(ui, |ui| self.viewport(ui, frame));
        crate::scene_file::scene_file_window(&ctx, &self.state.scene);
        if let Some(b) = &mut self.browser {
            match b.show(&ctx) {
                BrowserAction::None => {}
                BrowserAction::Cancel => self.browser = None,
                BrowserAction::Open(p) => {
                    self.browser = None;
                    self.state.load_scene(&p.to_string_lossy());
                }
            }
        }
        self.submit_job();
        self.headless_step(&ctx);
    }
}
