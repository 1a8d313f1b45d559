//! Image bytes through the texture decoder and the PFM reader: see `rayscope::fuzzing::image`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    rayscope::fuzzing::image(input);
});
