//! What a user feeds rayscope is checked, never silently wrong: limits that still render,
//! scene values that are refused at their line, and samples that never poison a film.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use rayscope::Error;
use rayscope::camera::CameraDesc;
use rayscope::math::Vec3;
use rayscope::progressive::{ImagingMode, Progressive};
use rayscope::scene::{Light, LoadContext, Scene, SceneDesc};
use rayscope::settings::RenderSettings;

fn small() -> RenderSettings {
    RenderSettings { width: 16, height: 12, ..RenderSettings::default() }
}

#[test]
fn a_time_limit_of_zero_still_renders_a_frame() {
    let scene = Scene::load("cornell-box", None).unwrap();
    let mut prog = Progressive::new(small(), ImagingMode::Dynamic, None);
    let rays = prog.run(&scene, &scene.camera_motion(), Some(Duration::ZERO), &AtomicBool::new(false), |_, _| {
        std::ops::ControlFlow::Continue(())
    });
    assert_eq!(prog.frames(), 1);
    assert!(rays.total() > 0);
    assert_eq!(prog.film().sample_range(), (1, 1), "every pixel has its sample");
}

#[test]
fn samples_that_are_not_finite_never_reach_the_film() {
    // Texture coordinates near the float limit make the texture lookup infinite, then NaN.
    let dir = tempfile::tempdir().unwrap();
    image::RgbImage::from_pixel(2, 1, image::Rgb([200, 100, 50])).save(dir.path().join("wide.png")).unwrap();
    let text = r#"
[[mesh]]
vertices = [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]
faces = [[0, 1, 2], [0, 2, 3]]
uvs = [[3e38, 3e38], [3e38, 0], [0, 3e38], [3e38, 3e38]]
materials = [{ kd = [1, 1, 1], texture = "wide.png" }]

[[light]]
kind = "point"
position = [0, 0, -3]
color = [1, 1, 1]
"#;
    let path = dir.path().join("s.toml");
    std::fs::write(&path, text).unwrap();
    let scene = Scene::load(path.to_str().unwrap(), None).unwrap();
    let out = rayscope::render::render(&scene, &small(), &|_| {});
    assert!(out.film.pixels().iter().all(|c| c.is_finite()), "a NaN reached the film");
    assert!(out.film.dropped() > 0, "the dropped samples are counted");
    assert!(out.film.dropped() <= 16 * 12);
}

/// The line and message of the error that scene file `text` gives.
fn scene_error(text: &str) -> (Option<usize>, String) {
    match SceneDesc::from_toml(text, Path::new("s.toml")) {
        Err(Error::Parse { line, message, .. }) => (line, message),
        other => panic!("expected a parse error for:\n{text}\ngot {other:?}"),
    }
}

const TRIANGLE: &str = "vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\nfaces = [[0, 1, 2]]\n";

#[test]
fn scene_values_out_of_range_are_errors_at_their_line() {
    let mesh = |extra: &str| format!("name = \"x\"\n[[mesh]]\n{TRIANGLE}{extra}\n");
    let cases = [
        // NaN rendered a blank image, as did scale = nan.
        ("[camera]\nfov = nan\n".to_string(), 2, "fov"),
        ("[camera]\nkind = \"trackball\"\nfov = 180\n".into(), 3, "fov"),
        ("[camera]\nkind = \"trackball\"\nrotation = [0, 0, 0]\ndistance = 0\n".into(), 4, "distance"),
        ("[camera]\nkind = \"trackball\"\ndistance = -2\n".into(), 3, "distance"),
        ("[camera]\nkind = \"look-at\"\neye = [0, 0, 0]\ntarget = [0, 0, inf]\n".into(), 4, "target"),
        ("camera = { fov = nan }\n".into(), 1, "fov"),
        ("[camera_end]\nfov = -1\n".into(), 2, "fov"),
        (mesh("transform = { scale = nan }"), 5, "transform"),
        (mesh("transform = { scale = 0 }"), 5, "transform"),
        (mesh("material = { kd = [-1, 0, 0] }"), 5, "not negative"),
        (mesh("materials = [{ transparency = 1.5 }]"), 5, "transparency"),
        (mesh("uvs = [[0, 0], [nan, 0], [0, 1]]"), 5, "uvs"),
        ("[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = { ks = [0, -0.5, 0] }\n".into(), 4, "not negative"),
        ("[[sphere]]\ncenter = [0, 0, 0]\nradius = 0\n".into(), 3, "radius"),
        ("[[light]]\nkind = \"point\"\nposition = [0, 1, 0]\ncolor = [1, -1, 1]\n".into(), 4, "color"),
        // A face index out of range was found after parsing, and named no file or line.
        (format!("[[mesh]]\n{TRIANGLE}\n[[mesh]]\nvertices = [[0, 0, 0]]\nfaces = [[0, 0, 3]]\n"), 7, "out of range"),
    ];
    for (text, line, needle) in cases {
        let (got, message) = scene_error(&text);
        assert_eq!(got, Some(line), "{message}\n{text}");
        assert!(message.contains(needle), "expected '{needle}' in: {message}\n{text}");
    }
}

#[test]
fn a_bad_sphere_light_is_named_by_its_key_not_printed_as_a_struct() {
    let text = "[[light]]\nkind = \"point\"\nposition = [0, 1, 0]\ncolor = [1, 1, 1]\n\n[[light]]\nkind = \"sphere\"\ncenter = [0, 1, 0]\nradius = -1\ncolor = [1, 1, 1]\n";
    let (line, message) = scene_error(text);
    assert_eq!(line, Some(9), "{message}");
    assert!(message.contains("light 2") && message.contains("radius"), "{message}");
    assert!(!message.contains('{') && !message.contains("Sphere"), "{message}");
    // A description made in code is checked the same way, by name.
    let desc = SceneDesc {
        lights: vec![Light::Sphere { center: Vec3::ZERO, radius: f32::NAN, color: Vec3::ONE }],
        ..SceneDesc::default()
    };
    let err = Scene::from_desc(&desc, &LoadContext::default()).unwrap_err().to_string();
    assert!(err.contains("light 1, radius") && !err.contains("Sphere {"), "{err}");
}

#[test]
fn every_camera_field_is_optional_and_a_wrong_type_is_named() {
    // `kind` too: a table without it is the course's trackball.
    let d = SceneDesc::from_toml("[camera]\nfov = 40\n", Path::new("s.toml")).unwrap();
    assert!(matches!(d.camera, CameraDesc::Trackball { fov: 40.0, distance: 3.0, .. }), "{:?}", d.camera);
    let d = SceneDesc::from_toml("[camera]\n", Path::new("s.toml")).unwrap();
    assert_eq!(d.camera, CameraDesc::default());
    // The real error, not `missing field 'kind'`.
    let (line, message) = scene_error("[camera]\ndistance = 2\nfov = \"fifty\"\n");
    assert_eq!(line, Some(3), "{message}");
    assert!(!message.contains("kind"), "{message}");
    // The other kind's fields are unknown, by name and line.
    let (line, message) = scene_error("[camera]\nfov = 40\neye = [0, 0, 1]\n");
    assert_eq!(line, Some(3), "{message}");
    assert!(message.contains("eye"), "{message}");
    let (line, message) = scene_error("[camera]\nkind = \"look-at\"\ntarget = [0, 0, 1]\n");
    assert_eq!(line, Some(1), "{message}");
    assert!(message.contains("eye"), "{message}");
    // Exported scenes read back as they were.
    for name in ["cornell-box", "spheres"] {
        let desc = rayscope::scene::builtin::scene_desc(name).unwrap();
        assert_eq!(SceneDesc::from_toml(&desc.to_toml(), Path::new("s.toml")).unwrap(), desc);
    }
}
