//! What a user feeds rayscope is checked, never silently wrong: limits that still render,
//! scene values that are refused at their line, and samples that never poison a film.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use rayscope::progressive::{ImagingMode, Progressive};
use rayscope::scene::Scene;
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
