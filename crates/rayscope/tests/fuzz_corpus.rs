//! The fuzz targets' corpora (`fuzz/corpus/<target>/`) and the reproducers of what they found
//! (`fuzz/regressions/<target>/`), replayed on stable by an ordinary `cargo test`: every file
//! goes through the entry point its fuzz target calls and must load or fail with an error,
//! never panic, and every render it makes must be finite.

use std::path::{Path, PathBuf};

use rayscope::fuzzing::{FuzzDir, gltf, image, obj_mtl, ply, render_scene, scene_file};

/// Every file of the target's corpus and regressions, sorted (an empty list fails: a moved
/// folder must not pass unnoticed).
fn inputs(target: &str) -> Vec<PathBuf> {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz");
    let mut files: Vec<PathBuf> = ["corpus", "regressions"]
        .iter()
        .filter_map(|kind| std::fs::read_dir(fuzz.join(kind).join(target)).ok())
        .flatten()
        .map(|entry| entry.expect("a readable corpus folder").path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no corpus for the fuzz target {target} under {}", fuzz.display());
    files
}

/// Runs `run` on every input of `target`; fails naming each file whose run panicked.
fn replay(target: &str, run: impl Fn(&[u8])) {
    let panicked: Vec<String> = inputs(target)
        .into_iter()
        .filter(|path| {
            let bytes = std::fs::read(path).expect("a readable corpus file");
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(&bytes))).is_err()
        })
        .map(|path| path.display().to_string())
        .collect();
    assert!(panicked.is_empty(), "{} inputs of {target} panicked:\n{}", panicked.len(), panicked.join("\n"));
}

#[test]
fn obj_mtl_corpus_loads_or_fails_cleanly() {
    let dir = FuzzDir::new().unwrap();
    replay("obj_mtl", |input| {
        let _ = obj_mtl(&dir, input);
    });
}

#[test]
fn gltf_corpus_loads_or_fails_cleanly() {
    let dir = FuzzDir::new().unwrap();
    replay("gltf", |input| {
        let _ = gltf(&dir, input);
    });
}

#[test]
fn ply_corpus_loads_or_fails_cleanly() {
    let dir = FuzzDir::new().unwrap();
    replay("ply", |input| {
        let _ = ply(&dir, input);
    });
}

#[test]
fn scene_file_corpus_loads_or_fails_cleanly() {
    let dir = FuzzDir::new().unwrap();
    replay("scene_file", |input| {
        let _ = scene_file(&dir, input);
    });
}

#[test]
fn image_corpus_decodes_or_fails_cleanly() {
    replay("image", |input| {
        image(input);
    });
}

#[test]
fn render_corpus_renders_finite_pixels_or_fails_cleanly() {
    let dir = FuzzDir::new().unwrap();
    replay("render", |input| {
        if let Ok(pixels) = render_scene(&dir, input) {
            assert!(pixels.iter().all(|p| p.is_finite()), "a pixel that is not finite");
        }
    });
}
