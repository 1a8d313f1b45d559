//! An OBJ file, an MTL file and a texture from one input (split at NUL bytes), loaded as the
//! command line loads an OBJ file: see `rayscope::fuzzing::obj_mtl`.
#![no_main]

use std::sync::LazyLock;

use libfuzzer_sys::fuzz_target;
use rayscope::fuzzing::{FuzzDir, obj_mtl};

static DIR: LazyLock<FuzzDir> = LazyLock::new(|| FuzzDir::new().expect("a folder for the fuzzed files"));

fuzz_target!(|input: &[u8]| {
    let _ = obj_mtl(&DIR, input);
});
