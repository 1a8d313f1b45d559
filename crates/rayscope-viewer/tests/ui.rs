//! The real app, driven headless by egui_kittest on wgpu (Mesa's lavapipe on CI): pick a
//! scene, click a pixel, toggle views and settings by their labels, and check the state and
//! the pixels of the 3D view.

use std::path::Path;
use std::sync::Once;
use std::time::{Duration, Instant};

use egui::{Event, Modifiers, PointerButton, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use rayscope_viewer::state::{ModeChoice, ViewKind};
use rayscope_viewer::{RayscopeApp, ViewerOptions};

/// The app in a 1440x900 harness, or `None` (with a notice) where no wgpu adapter exists.
fn harness(opts: ViewerOptions) -> Option<Harness<'static, RayscopeApp>> {
    static QUIET: Once = Once::new();
    QUIET.call_once(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("xdg-runtime");
        // SAFETY: every test that starts wgpu (or any thread of the app) comes through here
        // and waits for this call to end, so no other thread touches the environment.
        unsafe { rayscope_viewer::session::quiet_wayland_probe(&dir) }.expect("a private runtime dir");
    });
    let built = std::panic::catch_unwind(move || {
        Harness::builder()
            .with_size([1440.0, 900.0])
            .with_max_steps(400)
            .wgpu()
            .build_eframe(move |cc| RayscopeApp::new(cc, opts))
    });
    match built {
        Ok(h) => Some(h),
        // A panic while building is how a missing adapter shows, but so is a broken shader or
        // app: where a GPU (or lavapipe) is known to be there, as on CI, it fails the test.
        Err(panic) if std::env::var_os("RAYSCOPE_REQUIRE_GPU").is_some() => std::panic::resume_unwind(panic),
        Err(_) => {
            eprintln!(
                "NOTICE: no wgpu adapter (install mesa-vulkan-drivers); skipping the viewer UI test \
                 (set RAYSCOPE_REQUIRE_GPU=1 to fail instead)"
            );
            None
        }
    }
}

/// Step the app until the worker has delivered `n` frames (it renders on its own thread).
fn wait_frames(h: &mut Harness<'_, RayscopeApp>, n: u64) {
    let start = Instant::now();
    while h.state().frames_delivered() < n || h.state().last_frame().is_none() {
        assert!(start.elapsed() < Duration::from_secs(120), "the worker delivered no frame");
        std::thread::sleep(Duration::from_millis(20));
        h.run_steps(1);
    }
    h.run_steps(2);
}

fn click(h: &mut Harness<'_, RayscopeApp>, pos: Pos2) {
    h.event(Event::PointerMoved(pos));
    h.run_steps(1);
    for pressed in [true, false] {
        h.event(Event::PointerButton { pos, button: PointerButton::Primary, pressed, modifiers: Modifiers::NONE });
        h.run_steps(1);
    }
    h.run_steps(1);
}

fn count(img: &image::RgbaImage, rect: egui::Rect, pred: impl Fn([u8; 3]) -> bool) -> usize {
    let mut n = 0;
    for y in rect.min.y.max(0.0) as u32..(rect.max.y as u32).min(img.height()) {
        for x in rect.min.x.max(0.0) as u32..(rect.max.x as u32).min(img.width()) {
            let p = img.get_pixel(x, y).0;
            if pred([p[0], p[1], p[2]]) {
                n += 1;
            }
        }
    }
    n
}

fn near(c: [u8; 3], want: [f32; 4]) -> bool {
    (0..3).all(|i| (c[i] as f32 - want[i] * 255.0).abs() < 40.0)
}

#[test]
fn click_a_pixel_and_see_its_ray_tree() {
    let opts = ViewerOptions { scene: "cornell-box".into(), ..Default::default() };
    let Some(mut h) = harness(opts) else { return };
    wait_frames(&mut h, 1);
    let rect = h.state().image_rect.expect("the viewport was laid out");
    // Click the centre of the image: pixel (400, 400).
    click(&mut h, rect.center());
    let sel = h.state().state.selection.as_ref().expect("the click selected a pixel");
    assert_eq!(sel.first().pixel, (400, 400));
    assert!(sel.first().trace.samples[0].tree.rays.len() >= 2, "camera ray and the mirror's reflection");
    // The panel lists the tree.
    h.get_by_label_contains("Ray tree (");
    h.get_by_label_contains("#1 Reflection");
    // The 3D view shows the scene (the red wall) and the overlay (shadow ray, normal,
    // triangle outline) near the selected pixel.
    let img = h.render().expect("rendered");
    let red = count(&img, rect, |c| c[0] > 90 && c[1] < 40 && c[2] < 40);
    assert!(red > 1000, "the red wall is drawn ({red} pixels)");
    let around = egui::Rect::from_center_size(rect.center(), egui::vec2(rect.width() * 0.5, rect.height() * 0.6));
    let outline = count(&img, around, |c| near(c, rayscope_viewer::overlay::TRIANGLE_COLOR));
    let shadow = count(&img, rect, |c| near(c, rayscope_viewer::overlay::REACHED_COLOR));
    assert!(outline > 20 && shadow > 20, "overlay drawn: outline {outline}, shadow ray {shadow}");
}

#[test]
fn views_and_settings_by_their_labels() {
    let opts = ViewerOptions { scene: "cornell-box".into(), ..Default::default() };
    let Some(mut h) = harness(opts) else { return };
    wait_frames(&mut h, 1);
    h.get_by_label("Ray traced").click();
    h.run_steps(2);
    assert_eq!(h.state().state.view, ViewKind::RayTraced);
    let g = h.state().state.generation;
    h.get_by_label("Shadows").click();
    h.run_steps(2);
    assert!(!h.state().state.settings.shadows);
    assert!(h.state().state.generation > g, "a settings change restarts the accumulation");
    h.get_by_label("Continuous").click();
    h.run_steps(2);
    assert_eq!(h.state().state.mode, ModeChoice::Continuous);
    // The traced view shows the ray-traced image: its pixels match the worker's frame.
    let gen_now = h.state().state.generation;
    let start = Instant::now();
    while h.state().last_frame().is_none_or(|f| f.generation != gen_now) {
        assert!(start.elapsed() < Duration::from_secs(120));
        std::thread::sleep(Duration::from_millis(20));
        h.run_steps(1);
    }
    h.run_steps(2);
    let rect = h.state().image_rect.unwrap();
    let img = h.render().unwrap();
    let red = count(&img, rect, |c| c[0] > 90 && c[1] < 40 && c[2] < 40);
    assert!(red > 1000, "the traced red wall ({red})");
    h.get_by_label("Heat map").click();
    h.run_steps(2);
    assert_eq!(h.state().state.view, ViewKind::HeatMap);
}

#[test]
fn the_heat_map_has_a_legend_that_says_what_it_measured() {
    let opts = ViewerOptions { scene: "cornell-box".into(), view: Some(ViewKind::HeatMap), ..Default::default() };
    let Some(mut h) = harness(opts) else { return };
    wait_frames(&mut h, 1);
    let scale = h.state().last_frame().and_then(|f| f.heat).expect("a heat-map frame carries its scale");
    // Most of the box's background is in tiles the renderer culls: not traced, counted apart.
    assert!(scale.min <= scale.max && scale.max > 0 && scale.rays + scale.culled == 800 * 800, "{scale:?}");
    assert!(scale.culled > 800 * 800 / 2 && scale.culled % 64 == 0, "{scale:?}");
    assert!(scale.millis > 0.0 && scale.mrays_per_s() > 0.0, "it measured its rays: {scale:?}");
    h.get_by_label_contains("node boxes tested per camera ray");
    h.get_by_label_contains("camera rays (one per pixel)");
    h.get_by_label_contains("in tiles whose frustum meets no box: not traced");
    // The Cornell box's rays all test as many boxes: the legend says so rather than showing
    // a scale with one value.
    if scale.min == scale.max {
        h.get_by_label_contains("no spread to show");
    } else {
        h.get_by_label_contains("boxes per ray");
    }
    // What the frames panel shows for a render (frames, Mrays/s) is not shown for a heat map.
    assert!(h.query_by_label_contains("samples/pixel").is_none());
}

#[test]
fn the_mip_level_view_has_a_legend_and_levels_that_rise_to_the_horizon() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/scenes/checker-floor.toml");
    let opts = ViewerOptions { scene: scene.into(), view: Some(ViewKind::MipLevels), ..Default::default() };
    let Some(mut h) = harness(opts) else { return };
    wait_frames(&mut h, 1);
    let scale = h.state().last_frame().and_then(|f| f.mips).expect("a mip-level frame carries its scale");
    // The floor fills the lower half; the far floor reads high levels.
    assert!(scale.textured > scale.pixels / 3 && scale.max > 3.0 && scale.top == 6, "{scale:?}");
    h.get_by_label_contains("Mip level trilinear filtering reads");
    h.get_by_label_contains("grey: no texture");
    assert!(h.query_by_label_contains("samples/pixel").is_none());
}

/// `--screenshot` with `--frames 2` in every view: each must save its screenshot and ask the
/// window to close (the heat map, one frame, never reached two and kept the window open).
#[test]
fn every_view_finishes_its_frames_and_saves_the_screenshot() {
    let dir = tempfile::tempdir().unwrap();
    for view in [ViewKind::Raster, ViewKind::RayTraced, ViewKind::HeatMap, ViewKind::MipLevels] {
        let shot = dir.path().join(format!("{view:?}.png"));
        let opts = ViewerOptions {
            scene: "cornell-box".into(),
            view: Some(view),
            screenshot: Some(shot.clone()),
            frames: 2,
            ..Default::default()
        };
        let Some(mut h) = harness(opts) else { return };
        let start = Instant::now();
        while h.state().headless_outcome().is_none() {
            assert!(start.elapsed() < Duration::from_secs(120), "{view:?}: no screenshot after 120 s");
            std::thread::sleep(Duration::from_millis(20));
            h.run_steps(1);
        }
        assert_eq!(h.state().headless_outcome(), Some(Ok(())), "{view:?}: the screenshot was saved");
        let img = image::open(&shot).unwrap_or_else(|e| panic!("{view:?}: {e}"));
        assert!(img.width() >= 800 && img.height() >= 600, "{view:?}: the whole window");
    }
}

#[test]
fn pick_a_scene_and_show_bvh_boxes() {
    let opts = ViewerOptions { scene: "cornell-box".into(), ..Default::default() };
    let Some(mut h) = harness(opts) else { return };
    h.get_by_label("Scene").click();
    h.run_steps(2);
    h.get_by_label("spheres").click();
    h.run_steps(2);
    assert_eq!(h.state().state.scene_spec, "spheres");
    assert_eq!(h.state().state.scene.spheres.len(), 3);
    h.get_by_label("Scene").click();
    h.run_steps(2);
    h.get_by_label("cornell-box").click();
    h.run_steps(2);
    assert_eq!(h.state().state.scene_spec, "cornell-box");
    h.get_by_label("Show BVH level").click();
    h.run_steps(3);
    assert_eq!(h.state().state.bvh_level, Some(0));
    let rect = h.state().image_rect.unwrap();
    let img = h.render().unwrap();
    let boxes = count(&img, rect, |c| near(c, rayscope_viewer::overlay::BOX_COLOR));
    assert!(boxes > 100, "the root box is drawn ({boxes})");
}

#[test]
fn the_ray_panel_explains_stopped_branches_and_a_cut_tree() {
    // Two nested spheres that reflect fully and let half the light through: every hit casts
    // two rays that hit again.
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("nested.toml");
    let glass = "material = { kd = [0.5, 0.5, 0.5], ks = [1, 1, 1], shininess = 20, transparency = 0.5 }";
    let text = format!(
        "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1.0\n{glass}\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 0.5\n\
         {glass}\n[[light]]\nkind = \"point\"\nposition = [0.3, 0.2, -0.2]\ncolor = [1, 1, 1]\n"
    );
    std::fs::write(&scene, text).unwrap();
    let small = rayscope::settings::RenderSettings { width: 8, height: 8, ..Default::default() };
    let open = |settings| {
        let scene = scene.to_string_lossy().into_owned();
        harness(ViewerOptions { scene, settings: Some(settings), debug_pixel: Some((4, 4)), ..Default::default() })
    };
    // The camera ray's reflection and transmission weigh 0.5 each: below 0.6, neither is cast.
    let Some(mut h) = open(rayscope::settings::RenderSettings { adc_bailout: 0.6, ..small.clone() }) else { return };
    wait_frames(&mut h, 1);
    assert_eq!(h.state().state.selection.as_ref().unwrap().first().trace.samples[0].tree.rays[0].stopped.len(), 2);
    h.get_by_label("adaptive depth control: reflection not cast: weight 0.5 below adc_bailout 0.6");
    h.get_by_label("adaptive depth control: transmission not cast: weight 0.5 below adc_bailout 0.6");
    // Its slider shows the value, not one clamped to a narrower range.
    assert_eq!(h.state().state.settings.adc_bailout, 0.6);
    assert!(h.query_all_by_label("ADC bailout").next().is_some());
    // Without it, at depth 22 the tree passes the recorder's bound, and the panel says so.
    let Some(mut h) = open(rayscope::settings::RenderSettings { adc_bailout: 0.0, max_depth: 22, ..small }) else {
        return;
    };
    wait_frames(&mut h, 1);
    // (The max-depth slider kept 22: it clamped to 10 before.)
    assert_eq!(h.state().state.settings.max_depth, 22);
    assert!(h.state().state.selection.as_ref().unwrap().first().trace.samples[0].tree.cut.is_some());
    h.get_by_label_contains("Tree cut: the first 10000 rays and shadow rays are recorded");
    h.get_by_label_contains("more, not listed here");
}

/// The Cornell box with `settings`, its centre pixel (400, 400) debugged, and a frame rendered.
fn cornell_box_centre(settings: rayscope::settings::RenderSettings) -> Option<Harness<'static, RayscopeApp>> {
    let opts = ViewerOptions {
        scene: "cornell-box".into(),
        settings: Some(settings),
        debug_pixel: Some((400, 400)),
        ..Default::default()
    };
    let mut h = harness(opts)?;
    wait_frames(&mut h, 1);
    Some(h)
}

/// Pixels of the viewport that a kind of line adds: the view rendered with it, less without.
fn added_by(h: &mut Harness<'_, RayscopeApp>, kind: rayscope_viewer::overlay::LineKind, want: [f32; 4]) -> usize {
    let rect = h.state().image_rect.unwrap();
    let with = count(&h.render().unwrap(), rect, |c| near(c, want));
    h.get_by_label(kind.label()).click();
    h.run_steps(3);
    assert!(!h.state().state.shown.contains(kind), "the toggle turned {kind:?} off");
    let without = count(&h.render().unwrap(), rect, |c| near(c, want));
    h.get_by_label(kind.label()).click();
    h.run_steps(3);
    with.saturating_sub(without)
}

#[test]
fn the_overlay_is_drawn_in_every_view_and_each_kind_toggles() {
    use rayscope_viewer::overlay::{LineKind, REACHED_COLOR, TRIANGLE_COLOR};
    let Some(mut h) = cornell_box_centre(rayscope::settings::RenderSettings { light_samples: 8, ..Default::default() })
    else {
        return;
    };
    for (view, label) in
        [(ViewKind::Raster, "Raster"), (ViewKind::RayTraced, "Ray traced"), (ViewKind::HeatMap, "Heat map")]
    {
        h.get_by_label(label).click();
        h.run_steps(3);
        assert_eq!(h.state().state.view, view);
        let shadow = added_by(&mut h, LineKind::ShadowReached, REACHED_COLOR);
        let outline = added_by(&mut h, LineKind::Normals, TRIANGLE_COLOR);
        assert!(shadow > 50 && outline > 20, "{view:?}: shadow rays {shadow}, outlines {outline}");
    }
    // Every kind has its toggle, with a tooltip.
    for kind in LineKind::ALL {
        h.get_by_label(kind.label());
    }
    // Wider lines cover more pixels.
    h.get_by_label("Raster").click();
    h.run_steps(3);
    let thin = added_by(&mut h, LineKind::Normals, TRIANGLE_COLOR);
    h.state_mut().state.line_width = 5.0;
    h.run_steps(3);
    let wide = added_by(&mut h, LineKind::Normals, TRIANGLE_COLOR);
    assert!(wide > 2 * thin, "width 5 covers more than width 1.5: {wide} vs {thin}");
    // The legend names the colours (with no selection, so that it is in view).
    h.state_mut().state.selection = None;
    h.run_steps(2);
    h.get_by_label("Legend").click();
    h.run_steps(2);
    h.get_by_label_contains("shadow ray that reached the light");
    h.get_by_label_contains("faded: a surface hides this part of the line");
}

#[test]
fn ctrl_drag_selects_a_rectangle_and_a_drag_still_orbits() {
    let opts = ViewerOptions { scene: "cornell-box".into(), ..Default::default() };
    let Some(mut h) = harness(opts) else { return };
    wait_frames(&mut h, 1);
    // Image pixel (x, y)'s centre on the screen (the panels may have changed the viewport).
    let at = |h: &Harness<'_, RayscopeApp>, x: f32, y: f32| {
        let rect = h.state().image_rect.unwrap();
        let px = rect.width() / 800.0;
        Pos2::new(rect.min.x + (x + 0.5) * px, rect.min.y + (y + 0.5) * px)
    };
    let drag = |h: &mut Harness<'_, RayscopeApp>, from: (f32, f32), to: (f32, f32), modifiers: Modifiers| {
        let (from, to) = (at(h, from.0, from.1), at(h, to.0, to.1));
        h.event(Event::ModifiersChanged(modifiers));
        h.event(Event::PointerMoved(from));
        h.run_steps(1);
        h.event(Event::PointerButton { pos: from, button: PointerButton::Primary, pressed: true, modifiers });
        h.run_steps(1);
        for i in 1..=4 {
            h.event(Event::PointerMoved(from + (to - from) * (i as f32 / 4.0)));
            h.run_steps(1);
        }
        h.event(Event::PointerButton { pos: to, button: PointerButton::Primary, pressed: false, modifiers });
        h.event(Event::ModifiersChanged(Modifiers::NONE));
        h.run_steps(2);
    };
    // From pixel (300, 300) to (309, 303): 40 pixels, 40 trees.
    let rotation = h.state().state.trackball.rotation;
    drag(&mut h, (300.0, 300.0), (309.0, 303.0), Modifiers::CTRL);
    let sel = h.state().state.selection.as_ref().expect("the drag selected pixels");
    assert_eq!(sel.first().pixel, (300, 300));
    assert_eq!(sel.pixels.last().unwrap().pixel, (309, 303));
    assert_eq!(sel.pixels.len(), 40);
    assert_eq!(h.state().state.trackball.rotation, rotation, "a Ctrl-drag does not orbit");
    h.get_by_label_contains("Ray tree of (300, 300)");
    // A large one is clamped to 64, with a note.
    drag(&mut h, (100.0, 100.0), (300.0, 300.0), Modifiers::CTRL);
    let sel = h.state().state.selection.as_ref().unwrap();
    assert_eq!((sel.pixels.len(), sel.first().pixel), (64, (100, 100)));
    h.get_by_label_contains("at most 64 pixels are traced together");
    // A plain drag orbits.
    drag(&mut h, (400.0, 400.0), (500.0, 420.0), Modifiers::NONE);
    assert_ne!(h.state().state.trackball.rotation, rotation);
}

#[test]
fn every_sample_and_the_explanation_table() {
    let Some(mut h) =
        cornell_box_centre(rayscope::settings::RenderSettings { spp: 4, light_samples: 4, ..Default::default() })
    else {
        return;
    };
    let p = h.state().state.selection.as_ref().unwrap().first().clone();
    assert_eq!(p.trace.samples.len(), 4, "all samples by default");
    h.get_by_label_contains("Ray tree sample 3 (");
    // The table: its sum beside the renderer's value, and a row that highlights in 3D.
    h.get_by_label_contains("sum of the terms");
    h.get_by_label_contains("the pixel (renderer)");
    assert_eq!(h.state().state.highlight, None);
    h.get_all_by_label("diffuse light 0").next().expect("a diffuse row");
    let first = p.explanation.terms[0];
    h.get_all_by_label(&first.sample.to_string()).next().unwrap().click();
    h.run_steps(3);
    let hl = h.state().state.highlight.expect("the row is highlighted");
    assert_eq!((hl.sample, hl.ray, hl.light), (first.sample, first.ray, first.light));
    // One sample by index.
    h.get_by_label("One sample").click();
    h.run_steps(3);
    assert_eq!(h.state().state.samples, rayscope::debug::SampleChoice::One(0));
    assert_eq!(h.state().state.selection.as_ref().unwrap().first().trace.samples.len(), 1);
}
