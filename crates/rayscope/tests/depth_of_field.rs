//! Depth of field (the thin lens) against closed forms: aperture 0 is the pinhole bit for bit,
//! every lens sample of a pixel meets the focal plane at one point (also as the debugger
//! records them), and the blur of an edge grows with its distance from the focal plane as the
//! circle of confusion says.

mod common;

use common::inline_scene;
use rayscope::camera::{Camera, CameraDesc, CameraMotion};
use rayscope::debug::{SampleChoice, trace_pixel_samples};
use rayscope::material::MaterialDesc;
use rayscope::math::{Vec3, Vec3A};
use rayscope::render::{render, replay_pixel_sum};
use rayscope::scene::{LoadContext, MeshDesc, Scene, SceneDesc, builtin};
use rayscope::settings::RenderSettings;

fn load(desc: &SceneDesc) -> Scene {
    Scene::from_desc(desc, &LoadContext::default()).unwrap()
}

fn quad(corners: [Vec3; 4]) -> MeshDesc {
    let mut m = inline_scene(corners.to_vec(), vec![[0, 1, 2], [0, 2, 3]]).meshes.remove(0);
    m.material = Some(MaterialDesc { kd: Some(Vec3::ONE), ..MaterialDesc::default() });
    m
}

const FOV: f32 = 40.0;
const EYE_Z: f32 = -4.0;

/// The normalised screen height `ndc_y` (y up) at depth `depth` from the eye, in world y.
fn world_y(ndc_y: f32, depth: f32) -> f32 {
    ndc_y * (FOV.to_radians() * 0.5).tan() * depth
}

/// White bands (unlit: shading off) on black, one per depth, each a half plane `x > 0` in
/// world (the left half of the image: screen right is `-x`) cut to a band of rows, so each
/// band's vertical edge is in the image centre's column (a third of a pixel of a 96 x 72
/// image off the centre line, so that one pixel is partly covered).
fn bands(depths: &[f32], ndc_rows: &[f32]) -> SceneDesc {
    let meshes = depths
        .iter()
        .zip(ndc_rows)
        .map(|(&d, &row)| {
            let (lo, hi) = (world_y(row - 0.12, d), world_y(row + 0.12, d));
            let z = EYE_Z + d;
            let x = world_y(2.0 / 96.0 / 3.0, d) * 4.0 / 3.0;
            quad([Vec3::new(x, lo, z), Vec3::new(20.0, lo, z), Vec3::new(20.0, hi, z), Vec3::new(x, hi, z)])
        })
        .collect();
    SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, EYE_Z), target: Vec3::ZERO, up: Vec3::Y, fov: FOV },
        meshes,
        ..SceneDesc::default()
    }
}

#[test]
fn aperture_zero_is_the_pinhole_bit_for_bit() {
    let scene = load(&builtin::scene_desc("cornell-box").unwrap());
    let base = RenderSettings { width: 40, height: 30, spp: 4, ..RenderSettings::default() };
    let pinhole = render(&scene, &base, &|_| {}).film;
    // A focus distance without an aperture changes nothing.
    let lensless = RenderSettings { aperture: 0.0, focus_distance: Some(0.7), ..base.clone() };
    let same = render(&scene, &lensless, &|_| {}).film;
    assert_eq!(pinhole.pixels(), same.pixels());
    // A lens changes the image.
    let lens = RenderSettings { aperture: 0.05, ..base };
    assert_ne!(pinhole.pixels(), render(&scene, &lens, &|_| {}).film.pixels());
}

#[test]
fn recorded_lens_rays_converge_on_the_focal_plane() {
    let desc = builtin::scene_desc("cornell-box").unwrap();
    let scene = load(&desc);
    let focus = 2.2;
    let settings = RenderSettings {
        width: 30,
        height: 20,
        spp: 9,
        aperture: 0.1,
        focus_distance: Some(focus),
        ..Default::default()
    };
    let camera = scene.camera();
    let forward = Vec3A::from(camera.rotation * Vec3::Z);
    // One sample per pixel offset: the pixel's offsets differ, so follow one sample at a time
    // and compare it with the pinhole ray of the same offset (aperture 0, same sample).
    let pinhole = RenderSettings { aperture: 0.0, ..settings.clone() };
    let (x, y) = (11, 7);
    let lens_trace = trace_pixel_samples(&scene, &settings, &scene.camera_motion(), x, y, SampleChoice::All, 10_000);
    let pin_trace = trace_pixel_samples(&scene, &pinhole, &scene.camera_motion(), x, y, SampleChoice::All, 10_000);
    let mut origins = Vec::new();
    for (l, p) in lens_trace.samples.iter().zip(&pin_trace.samples) {
        let (lr, pr) = (&l.tree.rays[0], &p.tree.rays[0]);
        let (lo, ld) = (Vec3A::from(lr.origin), Vec3A::from(lr.dir));
        let (po, pd) = (Vec3A::from(pr.origin), Vec3A::from(pr.dir));
        // The pinhole ray's point at depth `focus`, and the lens ray's.
        let p_focus = po + pd * (focus / pd.dot(forward));
        let t = (focus - (lo - camera.position).dot(forward)) / ld.dot(forward);
        let l_focus = lo + ld * t;
        assert!(l_focus.distance(p_focus) < 1e-4, "sample {}: {l_focus} vs {p_focus}", l.index);
        // The lens ray leaves the lens disk, in the plane of the pinhole.
        assert!((lo - camera.position).dot(forward).abs() < 1e-5);
        assert!(lo.distance(camera.position) <= 0.1 + 1e-5);
        origins.push(lo);
    }
    assert!(origins.windows(2).any(|w| w[0] != w[1]), "the lens samples spread over the lens");
}

#[test]
fn a_lens_render_equals_the_debuggers_replay_on_any_thread_count() {
    let scene = load(&builtin::scene_desc("cornell-box").unwrap());
    // 37 columns: runs of 8 pixels and a shorter one; 4 samples: the lens's 2 x 2 grid; 3: its
    // shuffled (0,2)-sequence.
    for spp in [4, 3] {
        let s = RenderSettings { width: 37, height: 23, spp, aperture: 0.08, ..RenderSettings::default() };
        let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
        let one = pool(1).install(|| render(&scene, &s, &|_| {}));
        let two = pool(2).install(|| render(&scene, &s, &|_| {}));
        assert_eq!(one.film.pixels(), two.film.pixels(), "{spp} spp");
        let camera = scene.camera_motion();
        for y in 0..s.height {
            for x in 0..s.width {
                let replayed = replay_pixel_sum(&scene, &s, &camera, x, y);
                assert_eq!(one.film.sum(x, y), replayed, "pixel ({x}, {y}), {spp} spp");
            }
        }
    }
}

/// Pixels of row `y` whose value is strictly between black and white: the width of the
/// band's edge, blurred.
fn edge_width(film: &rayscope::film::Film, y: u32) -> u32 {
    (0..film.width()).filter(|&x| (0.02..0.98).contains(&film.get(x, y).x)).count() as u32
}

#[test]
fn blur_grows_with_the_distance_from_the_focal_plane() {
    // Bands in focus (depth 4), at 5 and at 8; the lens focuses at 4.
    let depths = [4.0, 5.0, 8.0];
    let rows = [0.55, 0.0, -0.55];
    let scene = load(&bands(&depths, &rows));
    let (w, h) = (96, 72);
    let aperture = 0.3;
    let base = RenderSettings { width: w, height: h, spp: 64, shading: false, ..RenderSettings::default() };
    let pinhole = render(&scene, &base, &|_| {}).film;
    let lens = render(&scene, &RenderSettings { aperture, ..base }, &|_| {}).film;
    let row = |ndc: f32| ((1.0 - ndc) * 0.5 * h as f32) as u32;
    let tan = (FOV.to_radians() * 0.5).tan();
    let mut widths = Vec::new();
    for (&d, &r) in depths.iter().zip(&rows) {
        let y = row(r);
        let (sharp, blurred) = (edge_width(&pinhole, y), edge_width(&lens, y));
        // Circle of confusion: the lens rays of a pixel spread over a disk of radius
        // aperture * |d - f| / f at depth d, where a pixel is 2 d tan(fov/2) / h wide.
        let coc = aperture * (d - 4.0f32).abs() / 4.0 / (2.0 * d * tan / h as f32);
        println!(
            "depth {d}: edge {sharp} px sharp, {blurred} px through the lens (circle of confusion radius {coc:.2} px)"
        );
        assert_eq!(sharp, 1, "the pinhole's edge is one pixel wide");
        // The disk's edge spread covers its diameter (less the tails below 2%), plus the
        // pixel the edge is in.
        assert!(
            (blurred as f32) <= 2.0 * coc + 1.0 && (blurred as f32) >= 2.0 * coc * 0.6,
            "depth {d}: {blurred} px for a circle of radius {coc:.2}"
        );
        widths.push(blurred);
    }
    assert_eq!(widths[0], 1, "the focal plane stays sharp: {widths:?}");
    assert!(widths[0] < widths[1] && widths[1] < widths[2], "{widths:?}");
}

#[test]
fn a_moving_camera_with_a_lens_renders_and_without_one_is_unchanged() {
    let mut desc = builtin::scene_desc("cornell-box").unwrap();
    let CameraDesc::Trackball { look_at, distance, rotation, fov } = desc.camera else { panic!("trackball") };
    desc.camera_end =
        Some(CameraDesc::Trackball { look_at, distance, rotation: rotation + Vec3::new(0.0, 10.0, 0.0), fov });
    let scene = load(&desc);
    let motion: CameraMotion = scene.camera_motion();
    assert!(motion.end.is_some());
    let base = RenderSettings { width: 24, height: 24, spp: 4, ..RenderSettings::default() };
    let still_lens = RenderSettings { aperture: 0.0, focus_distance: Some(3.0), ..base.clone() };
    assert_eq!(render(&scene, &base, &|_| {}).film.pixels(), render(&scene, &still_lens, &|_| {}).film.pixels());
    let lens = render(&scene, &RenderSettings { aperture: 0.05, ..base }, &|_| {}).film;
    assert!(lens.pixels().iter().all(|c| c.is_finite()));
    // The focus distance defaults to the look-at distance.
    assert_eq!(Camera::from_desc(&desc.camera).look_distance, distance);
}

#[test]
fn bad_lens_values_are_clear_errors() {
    for (s, what) in [
        (RenderSettings { aperture: -0.1, ..Default::default() }, "aperture"),
        (RenderSettings { aperture: f32::NAN, ..Default::default() }, "aperture"),
        (RenderSettings { focus_distance: Some(-2.0), ..Default::default() }, "focus distance"),
        (RenderSettings { focus_distance: Some(0.0), ..Default::default() }, "focus distance"),
        (RenderSettings { focus_distance: Some(f32::INFINITY), ..Default::default() }, "focus distance"),
    ] {
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains(what), "{e}");
    }
}

/// The lens is a key of the camera table: it reaches the render settings, bad values and a
/// lens given twice (or in `camera_end`) are errors naming the file and line, the old
/// `[render]` keys still work, and export writes the lens into the camera table.
#[test]
fn the_camera_table_holds_the_lens() {
    let path = std::path::Path::new("lens.toml");
    let read = |text: &str| rayscope::scene::SceneDesc::from_toml(text, path);
    let d = read("[camera]\nkind = \"trackball\"\naperture = 0.1\nfocus_distance = 2.5\n").unwrap();
    let r = d.render.as_ref().unwrap();
    assert_eq!((r.aperture, r.focus_distance), (0.1, Some(2.5)));
    // The alias, as documented.
    let old = read("[render]\naperture = 0.1\nfocus_distance = 2.5\n").unwrap();
    assert_eq!(old.render, d.render);
    // Export writes the lens into the camera table, and reads back the same.
    let text = d.to_toml();
    let camera = text.split("[camera]").nth(1).unwrap().split("\n[").next().unwrap();
    assert!(camera.contains("aperture = 0.1") && camera.contains("focus_distance = 2.5"), "{text}");
    assert!(!text.split("[render]").nth(1).unwrap().contains("aperture"), "{text}");
    assert_eq!(read(&text).unwrap(), d);
    for (text, want) in [
        ("name = \"x\"\n[camera]\nfov = 40\naperture = -0.5\n", ["lens.toml:4:", "camera, aperture", "aperture -0.5"]),
        ("[camera]\nfocus_distance = 0.0\n", ["lens.toml:2:", "focus_distance", "focus distance 0"]),
        ("[camera]\naperture = 0.1\n[render]\naperture = 0.2\n", ["lens.toml:2:", "[render]", "give it once"]),
        ("[camera_end]\naperture = 0.1\n", ["lens.toml:2:", "camera_end", "give it in [camera]"]),
        ("[camera]\naperture = \"wide\"\n", ["lens.toml:2:", "invalid type", "string"]),
    ] {
        let err = read(text).unwrap_err().to_string();
        assert!(want.iter().all(|w| err.contains(w)), "{text}: {err}");
    }
}
