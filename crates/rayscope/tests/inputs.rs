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
