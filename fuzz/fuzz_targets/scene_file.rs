//! Scene file text (TOML), parsed and loaded: see `rayscope::fuzzing::scene_file`.
#![no_main]

use std::sync::LazyLock;

use libfuzzer_sys::fuzz_target;
use rayscope::fuzzing::{FuzzDir, scene_file};

static DIR: LazyLock<FuzzDir> = LazyLock::new(|| FuzzDir::new().expect("a folder for the fixtures"));

fuzz_target!(|input: &[u8]| {
    let _ = scene_file(&DIR, input);
});
