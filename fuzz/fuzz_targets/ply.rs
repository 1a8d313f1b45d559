//! A PLY file loaded as the command line loads one: see `rayscope::fuzzing::ply`.
#![no_main]

use std::sync::LazyLock;

use libfuzzer_sys::fuzz_target;
use rayscope::fuzzing::{FuzzDir, ply};

static DIR: LazyLock<FuzzDir> = LazyLock::new(|| FuzzDir::new().expect("a folder for the fuzzed files"));

fuzz_target!(|input: &[u8]| {
    let _ = ply(&DIR, input);
});
