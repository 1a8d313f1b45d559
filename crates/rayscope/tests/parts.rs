//! Renders split into parts and merged, through partial film files: the merged film equals
//! the one-shot render bit for bit (any number of parts, either split, with anti-aliasing,
//! soft shadows, gloss and motion blur); merging refuses parts that do not make one render.

mod common;

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use common::builtin_scene;
use rayscope::partial::file::{read_partial, write_partial};
use rayscope::partial::fingerprint::Fingerprint;
use rayscope::partial::merge::merge_parts;
use rayscope::partial::part::{Part, Split, render_part};
use rayscope::partial::{PartialFilm, Portion};
use rayscope::render::render;
use rayscope::scene::Scene;
use rayscope::settings::{PixelFilter, RenderSettings};

fn settings() -> RenderSettings {
    RenderSettings {
        width: 37,
        height: 29,
        spp: 8,
        light_samples: 2,
        gloss_samples: 2,
        filter: PixelFilter::Tent,
        seed: 7,
        ..RenderSettings::default()
    }
}

/// Render every part of `n` to files in `dir`, returning the files read back.
fn parts(
    scene: &Scene,
    s: &RenderSettings,
    n: u32,
    split: Split,
    dir: &std::path::Path,
) -> Vec<(PathBuf, PartialFilm)> {
    let fingerprint = Fingerprint::new("cornell-box-motion", "test", s);
    (0..n)
        .map(|k| {
            let part = Part::new(k, n, split).unwrap();
            let out = render_part(scene, s, part, &AtomicBool::new(false), &|_| {});
            let path = dir.join(format!("part{k}.exr"));
            let partial =
                PartialFilm { fingerprint: fingerprint.clone(), portion: Portion::Part(part), film: out.film };
            write_partial(&partial, &path).unwrap();
            let back = read_partial(&path).unwrap();
            assert_eq!(back, partial, "the file holds the film exactly");
            (path, back)
        })
        .collect()
}

#[test]
fn merged_parts_equal_one_render() {
    let scene = builtin_scene("cornell-box-motion", None);
    let s = settings();
    let one = render(&scene, &s, &|_| {}).film;
    let dir = tempfile::tempdir().unwrap();
    for split in [Split::Samples, Split::Tiles] {
        for n in [1, 2, 3, 4, 7] {
            let films = parts(&scene, &s, n, split, dir.path());
            // Any order of the files.
            let mut reversed = films.clone();
            reversed.reverse();
            for set in [films, reversed] {
                let merged = merge_parts(&set).unwrap();
                assert_eq!(merged.sample_range(), (s.spp, s.spp));
                assert_eq!(merged.pixels(), one.pixels(), "{n} parts split by {}", split.name());
            }
        }
    }
}

#[test]
fn merge_refuses_what_is_not_one_render() {
    let scene = builtin_scene("cornell-box", None);
    let s = RenderSettings { width: 16, height: 8, spp: 4, ..RenderSettings::default() };
    let dir = tempfile::tempdir().unwrap();
    let three = parts(&scene, &s, 3, Split::Samples, dir.path());
    let err = |set: &[(PathBuf, PartialFilm)]| merge_parts(set).unwrap_err().to_string();
    let e = err(&three[..2]);
    assert!(e.contains("missing part 2 of 3"), "{e}");
    let e = err(&[three[0].clone(), three[1].clone(), three[1].clone()]);
    assert!(e.contains("are both part 1 of 3"), "{e}");
    let other = RenderSettings { seed: 3, ..s.clone() };
    let odd = dir.path().join("odd");
    std::fs::create_dir(&odd).unwrap();
    let others = parts(&scene, &other, 3, Split::Samples, &odd);
    let e = err(&[three[0].clone(), three[1].clone(), others[2].clone()]);
    assert!(e.contains("parts of different renders: seed (0 against 3)"), "{e}");
    assert!(e.contains("part2.exr"), "{e}");
    let tiles = parts(&scene, &s, 3, Split::Tiles, &odd);
    let e = err(&[three[0].clone(), three[1].clone(), tiles[2].clone()]);
    assert!(e.contains("split by tiles"), "{e}");
    // An ordinary EXR image is not a partial film.
    let plain = dir.path().join("plain.exr");
    let img = rayscope::render::render(&scene, &s, &|_| {}).film.to_image();
    rayscope::output::write_image(&img, &plain, rayscope::output::Encoding::Linear).unwrap();
    let e = read_partial(&plain).unwrap_err().to_string();
    assert!(e.contains("plain.exr") && e.contains("not a rayscope partial film"), "{e}");
    let junk = dir.path().join("junk.exr");
    std::fs::write(&junk, b"not an exr").unwrap();
    let e = read_partial(&junk).unwrap_err().to_string();
    assert!(e.contains("junk.exr") && e.contains("not a readable OpenEXR file"), "{e}");
}
