//! `rayscope compare` end to end: our own render compares as identical; a render with a
//! shifted camera or without shadows differs in exactly the pixels it changed (found here by
//! comparing the two PNGs byte by byte); bad files and sizes give clear errors and status 2.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Output;

mod common;

use common::{rayscope, stderr};

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

const SIZE: [&str; 4] = ["--width", "96", "--height", "72"];

/// Render `scene` at [`SIZE`] with `flags` into `out`.
fn render(dir: &Path, scene: &str, flags: &[&str], out: &str) {
    let o = rayscope(dir, &[&["render", scene, "-o", out][..], &SIZE, flags].concat());
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The pixels where two PNGs' 8-bit values differ.
fn differing(a: &Path, b: &Path) -> BTreeSet<(u32, u32)> {
    let (a, b) = (image::open(a).unwrap().to_rgb8(), image::open(b).unwrap().to_rgb8());
    a.enumerate_pixels().filter(|(x, y, p)| b.get_pixel(*x, *y) != *p).map(|(x, y, _)| (x, y)).collect()
}

/// The pixels a difference image marks (all but the black ones).
fn marked(diff: &Path) -> BTreeSet<(u32, u32)> {
    let d = image::open(diff).unwrap().to_rgb8();
    d.enumerate_pixels().filter(|(_, _, p)| p.0 != [0, 0, 0]).map(|(x, y, _)| (x, y)).collect()
}

#[test]
fn our_own_render_is_identical() {
    let dir = tempfile::tempdir().unwrap();
    render(dir.path(), "cornell-box", &[], "theirs.png");
    // Their size is taken (and said so): no --width/--height needed.
    let o = rayscope(dir.path(), &["compare", "theirs.png", "cornell-box", "-o", "diff.png", "--ours", "ours.png"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert_eq!(out.lines().next(), Some("0 of 6912 pixels differ"), "{out}");
    assert!(out.contains("SSIM: 1.000000"), "{out}");
    assert!(out.contains("mean error: 0.000000") && out.contains("max error: 0.000000"), "{out}");
    assert!(stderr(&o).contains("rendering at 96x72, the size of theirs.png"), "{}", stderr(&o));
    assert!(marked(&dir.path().join("diff.png")).is_empty());
    assert_eq!(
        std::fs::read(dir.path().join("ours.png")).unwrap(),
        std::fs::read(dir.path().join("theirs.png")).unwrap()
    );
}

#[test]
fn a_missing_shadow_term_or_a_shifted_camera_differs_in_exactly_the_pixels_it_changed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d, "cornell-box", &[], "ours.png");
    // A shifted camera: the exported scene file with the trackball turned by one degree.
    let toml = rayscope(d, &["scenes", "--export", "cornell-box"]);
    let text = String::from_utf8(toml.stdout).unwrap();
    assert!(text.contains("rotation = [20.0, 20.0, 0.0]"), "{text}");
    std::fs::write(d.join("box.toml"), &text).unwrap();
    std::fs::write(
        d.join("shifted.toml"),
        text.replace("rotation = [20.0, 20.0, 0.0]", "rotation = [20.0, 21.0, 0.0]"),
    )
    .unwrap();
    render(d, "cornell-box", &["--no-shadows"], "no-shadows.png");
    render(d, "shifted.toml", &[], "shifted.png");
    for theirs in ["no-shadows.png", "shifted.png"] {
        let expected = differing(&d.join(theirs), &d.join("ours.png"));
        assert!(!expected.is_empty(), "{theirs} changed nothing");
        let o = rayscope(d, &[&["compare", theirs, "box.toml", "-o", "diff.png"][..], &SIZE].concat());
        assert_eq!(o.status.code(), Some(1), "{theirs}: different images exit 1: {}", stderr(&o));
        let first = stdout(&o).lines().next().unwrap().to_string();
        assert_eq!(first, format!("{} of 6912 pixels differ", expected.len()), "{theirs}");
        assert_eq!(marked(&d.join("diff.png")), expected, "{theirs}: the difference image marks exactly those");
        let ssim: f64 = stdout(&o).split("SSIM: ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
        assert!(ssim < 1.0 && ssim > 0.0, "{theirs}: {ssim}");
    }
    // Every render flag applies to ours: compared with shadows off too, they are the same.
    let o = rayscope(d, &["compare", "no-shadows.png", "cornell-box", "--no-shadows"]);
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
}

#[test]
fn their_float_image_is_compared_with_our_floats() {
    let dir = tempfile::tempdir().unwrap();
    render(dir.path(), "spheres", &[], "theirs.exr");
    let o = rayscope(dir.path(), &["compare", "theirs.exr", "spheres", "-o", "diff.exr"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).starts_with("0 of 6912 pixels differ\n"));
    let o = rayscope(dir.path(), &["compare", "theirs.exr", "spheres", "--no-shading"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

#[test]
fn bad_files_and_sizes_give_clear_errors_and_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d, "cornell-box", &[], "theirs.png");
    std::fs::write(d.join("bad.png"), b"this is no image").unwrap();
    let cases: [(&[&str], &[&str]); 5] = [
        (&["compare", "missing.png"], &["missing.png", "No such file"]),
        (&["compare", "bad.png"], &["bad.png", "cannot decode image"]),
        (&["compare", "."], &[".: is a directory, not a regular file"]),
        (
            &["compare", "theirs.png", "--width", "64", "--height", "64"],
            &["theirs.png is 96x72 pixels but the render is 64x64", "leave out --width and --height"],
        ),
        (&["compare", "theirs.png", "-o", "diff.gif"], &["diff.gif: unknown image format"]),
    ];
    for (args, needles) in cases {
        let o = rayscope(d, args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        for n in needles {
            assert!(err.contains(n), "{args:?}: expected '{n}' in: {err}");
        }
    }
    assert!(!d.join("diff.gif").exists());
}
