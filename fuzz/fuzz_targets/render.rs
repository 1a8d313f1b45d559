//! A scene file rendered tiny (at most 8 x 8 pixels, 2 samples, depth 4): every accepted scene
//! must render to finite pixels. See `rayscope::fuzzing::render_scene`.
#![no_main]

use std::sync::LazyLock;

use libfuzzer_sys::fuzz_target;
use rayscope::fuzzing::{FuzzDir, render_scene};

static DIR: LazyLock<FuzzDir> = LazyLock::new(|| FuzzDir::new().expect("a folder for the fixtures"));

fuzz_target!(|input: &[u8]| {
    if let Ok(pixels) = render_scene(&DIR, input) {
        assert!(pixels.iter().all(|p| p.is_finite()), "a render produced a pixel that is not finite");
    }
});
