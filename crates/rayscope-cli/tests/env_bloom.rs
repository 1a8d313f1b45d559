//! The command line's environment map and bloom: flags, what they render, the debugger's
//! record of the map, and their errors.

mod common;

use common::{rayscope, stderr};
use rayscope::math::Color;
use rayscope::output::read_pfm;
use rayscope::post::bloom;
use rayscope::settings::BloomSettings;

fn pixels(path: &std::path::Path) -> (u32, u32, Vec<Color>) {
    let img = read_pfm(path).unwrap();
    (img.width, img.height, img.data.chunks_exact(3).map(Color::from_slice).collect())
}

#[test]
fn env_map_flags_light_the_background_and_the_debugger_shows_the_texel() {
    let dir = tempfile::tempdir().unwrap();
    let sky = image::Rgb32FImage::from_pixel(16, 8, image::Rgb([0.25, 0.5, 1.0]));
    image::DynamicImage::ImageRgb32F(sky).save(dir.path().join("sky.hdr")).unwrap();
    let size = ["--width", "32", "--height", "24"];
    let env = ["--env-map", "sky.hdr", "--env-intensity", "2", "--env-rotation", "-45"];
    let o = rayscope(dir.path(), &[&["render", "spheres", "-o", "e.pfm"][..], &size, &env].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, _, px) = pixels(&dir.path().join("e.pfm"));
    // A pixel whose camera ray misses every sphere (the debugger says so) shows the map's
    // constant value times 2.
    let missed = [(0u32, 23u32), (16, 23), (31, 23), (0, 0), (31, 0)].into_iter().find_map(|(x, y)| {
        let pixel = format!("{x},{y}");
        let o = rayscope(dir.path(), &[&["debug", "spheres", "--pixel", &pixel][..], &size, &env].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        json["samples"][0]["rays"][0]["hit"].is_null().then_some((x, y, json))
    });
    let (x, y, json) = missed.expect("a corner of the view misses the spheres");
    assert_eq!(px[(y * w + x) as usize], Color::new(0.5, 1.0, 2.0));
    let ray = &json["samples"][0]["rays"][0];
    assert_eq!(ray["environment"]["radiance"], serde_json::json!([0.5, 1.0, 2.0]));
    assert!(ray["environment"]["texel"].as_array().is_some_and(|t| t.len() == 2));
    assert_eq!(json["explanation"]["terms"][0]["kind"], "environment");
}

#[test]
fn bloom_adds_the_blurred_bright_pass_and_is_off_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let size = ["--width", "40", "--height", "30"];
    let run = |out: &str, extra: &[&str]| {
        let o = rayscope(dir.path(), &[&["render", "spheres", "-o", out][..], &size, extra].concat());
        assert!(o.status.success(), "{}", stderr(&o));
    };
    run("plain.pfm", &[]);
    run("zero.pfm", &["--bloom-strength", "0"]);
    run("bloom.pfm", &["--bloom-threshold", "0.5", "--bloom-radius", "3", "--bloom-strength", "0.75"]);
    let plain = std::fs::read(dir.path().join("plain.pfm")).unwrap();
    assert_eq!(plain, std::fs::read(dir.path().join("zero.pfm")).unwrap(), "strength 0 keeps every bit");
    let (w, h, base) = pixels(&dir.path().join("plain.pfm"));
    let (_, _, bloomed) = pixels(&dir.path().join("bloom.pfm"));
    let mut want = base.clone();
    bloom::apply(&mut want, w, h, &BloomSettings { threshold: 0.5, radius: 3.0, strength: 0.75 });
    assert_eq!(bloomed, want);
    assert_ne!(bloomed, base, "the spheres' lit sides exceed 0.5");
}

#[test]
fn bad_env_and_bloom_flags_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (args, want) in [
        (vec!["--env-map", "nowhere.hdr"], "nowhere.hdr"),
        (vec!["--env-intensity", "3"], "need an environment map"),
        (vec!["--bloom-radius", "-2", "--bloom-strength", "1"], "--bloom-radius -2"),
        (vec!["--bloom-strength", "nan"], "--bloom-strength NaN"),
        (vec!["--bloom-threshold", "2"], "--bloom-strength S"),
    ] {
        let o = rayscope(dir.path(), &[&["render", "spheres", "-o", "x.png"][..], &args].concat());
        assert!(!o.status.success() && stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
    }
}
