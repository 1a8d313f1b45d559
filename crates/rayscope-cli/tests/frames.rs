//! `render --frames A..B` and `--frame F` end to end: the files, their bits, the timeline's
//! effect on the image, Ctrl-C and `--skip-existing`, and the flags' errors.

use std::path::{Path, PathBuf};

mod common;

use common::{interrupted, rayscope, stderr};

const SMALL: [&str; 6] = ["--width", "48", "--height", "40", "--spp", "4"];

fn render(dir: &Path, args: &[&str]) -> String {
    let all: Vec<&str> = ["render"].iter().chain(args).chain(SMALL.iter()).copied().collect();
    let o = rayscope(dir, &all);
    assert!(o.status.success(), "{all:?}: {}", stderr(&o));
    stderr(&o)
}

fn bytes(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn frame_f_writes_the_file_frames_writes_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for ext in ["png", "exr", "pfm"] {
        let err = render(d, &["cornell-box-motion", "--frames", "0..=2", "-o", &format!("all.{ext}")]);
        assert!(err.contains("frames 0..3 at 24 fps") && err.contains("frame 2: scene time"), "{err}");
        for f in 0..3 {
            render(d, &["cornell-box-motion", "--frame", &f.to_string(), "-o", &format!("one.{ext}")]);
            let name = |stem: &str| format!("{stem}_{f:04}.{ext}");
            assert_eq!(bytes(d, &name("all")), bytes(d, &name("one")), "frame {f} .{ext}");
        }
        assert!(!d.join(format!("all_0003.{ext}")).exists(), "0..=2 holds three frames");
        // The sphere moves between frames.
        assert_ne!(bytes(d, &format!("all_0000.{ext}")), bytes(d, &format!("all_0001.{ext}")));
    }
}

#[test]
fn a_still_is_frame_0_at_one_frame_a_second_with_the_shutter_open_all_frame() {
    // The still's shutter is scene time [0, 1]: frame 0 at 1 fps with a whole-frame shutter
    // exposes the same span, and gives the same bits (through a BVH built for it).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d, &["cornell-box-motion", "-o", "still.pfm"]);
    render(d, &["cornell-box-motion", "--frame", "0", "--fps", "1", "--shutter", "1", "-o", "f.pfm"]);
    assert_eq!(bytes(d, "still.pfm"), bytes(d, "f_0000.pfm"));
    // Half the shutter is another image (less blur).
    render(d, &["cornell-box-motion", "--frame", "0", "--fps", "1", "--shutter", "0.5", "-o", "h.pfm"]);
    assert_ne!(bytes(d, "still.pfm"), bytes(d, "h_0000.pfm"));
}

/// A scene whose camera moves along keys over two seconds and whose sphere stands still.
const CAMERA_SCENE: &str = r#"
name = "moving camera"
[camera]
rotation = [20, 20, 0]
[[sphere]]
center = [0, 0, 0]
radius = 0.4
material = { kd = [0.8, 0.3, 0.2] }
[[light]]
kind = "point"
position = [-1, 1, -1]
color = [1, 1, 1]
[camera_motion]
interpolation = "linear"
keys = [[0, [0, 0, 0]], [2, [0.6, 0, 0]]]
[animation]
fps = 12
frames = "0..=24"
shutter = 0
"#;

#[test]
fn the_cameras_keyframes_move_the_image_between_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("cam.toml"), CAMERA_SCENE).unwrap();
    // The scene's own range, thinned: frames 0, 12 and 24 (0, 1 and 2 s).
    for f in ["0", "12", "24", "30"] {
        render(d, &["cam.toml", "--frame", f, "-o", "c.pfm"]);
    }
    let frames: Vec<Vec<u8>> =
        ["0000", "0012", "0024", "0030"].iter().map(|f| bytes(d, &format!("c_{f}.pfm"))).collect();
    assert_ne!(frames[0], frames[1]);
    assert_ne!(frames[1], frames[2]);
    // After the last key the camera holds.
    assert_eq!(frames[2], frames[3]);
    // The scene's `[animation] frames` is what `--frames scene` renders.
    let err = render(d, &["cam.toml", "--frames", "scene", "-o", "s.png"]);
    assert!(err.contains("frames 0..25 at 12 fps"), "{err}");
    assert!(d.join("s_0024.png").exists() && !d.join("s_0025.png").exists());
}

#[test]
fn a_scene_without_motion_warns_and_every_frame_is_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let err = render(d, &["spheres", "--frames", "3..5", "-o", "s.png"]);
    assert!(err.contains("warning") && err.contains("no motion"), "{err}");
    assert_eq!(bytes(d, "s_0003.png"), bytes(d, "s_0004.png"));
}

#[test]
fn skip_existing_continues_a_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d, &["cornell-box-motion", "--frames", "0..3", "-o", "a.png"]);
    let middle = bytes(d, "a_0001.png");
    std::fs::remove_file(d.join("a_0001.png")).unwrap();
    let err = render(d, &["cornell-box-motion", "--frames", "0..3", "--skip-existing", "-o", "a.png"]);
    assert_eq!(err.matches("exists, skipped").count(), 2, "{err}");
    assert_eq!(bytes(d, "a_0001.png"), middle);
}

fn course_assets() -> Option<PathBuf> {
    let dir = std::env::var_os("RAYSCOPE_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"));
    dir.join("CornellBox-Mirror-Rotated.obj").exists().then_some(dir)
}

#[test]
fn three_frames_of_a_course_scene() {
    let Some(assets) = course_assets() else {
        eprintln!("skipped: no course scenes (set RAYSCOPE_ASSETS)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = r#"
[[mesh]]
asset = "CornellBox-Mirror-Rotated.obj"
normalize = true
[[sphere]]
center = [0, -0.2, 0.2]
radius = 0.15
material = { kd = [0.2, 0.4, 0.9] }
motion = { keys = [[0, [-0.3, 0, 0]], [0.5, [0, 0.3, 0]], [1, [0.3, 0, 0]]] }
[[light]]
kind = "point"
position = [0, 0.5, 0.3]
color = [1, 1, 1]
"#;
    std::fs::write(d.join("course.toml"), scene).unwrap();
    let assets = assets.to_string_lossy().into_owned();
    let err = render(d, &["course.toml", "--assets", &assets, "--frames", "1..4", "--fps", "4", "-o", "c.png"]);
    assert_eq!(err.matches("scene time").count(), 3, "{err}");
    let f: Vec<Vec<u8>> = (1..4).map(|i| bytes(d, &format!("c_{i:04}.png"))).collect();
    assert!(f[0] != f[1] && f[1] != f[2], "the sphere moves between frames");
    render(d, &["course.toml", "--assets", &assets, "--frame", "2", "--fps", "4", "-o", "one.png"]);
    assert_eq!(bytes(d, "one_0002.png"), f[1]);
}

#[test]
fn ctrl_c_keeps_the_frames_written_and_not_the_interrupted_one() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["render", "cornell-box-motion", "--frames", "0..500", "-o", "k.png", "--width", "64", "--height", "64"];
    let out = interrupted(dir.path(), &[&args[..], &["--spp", "16"]].concat(), 1500);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted during frame") && err.contains("--skip-existing"), "{err}");
    let written: Vec<PathBuf> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().path()).collect();
    assert!(written.len() < 500, "{err}");
    for p in &written {
        assert!(image::open(p).is_ok(), "{}: a whole image", p.display());
    }
}

#[test]
fn bad_animation_flags_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fails = |args: &[&str], needle: &str| {
        let all: Vec<&str> = ["render", "cornell-box-motion", "-o", "x.png"].iter().chain(args).copied().collect();
        let o = rayscope(d, &all);
        let err = stderr(&o);
        assert!(!o.status.success() && !err.contains("panicked"), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: expected '{needle}' in {err}");
    };
    fails(&["--frames", "5..2"], "holds no frame");
    fails(&["--frames", "5..=2"], "ends before it starts");
    fails(&["--frames", "-3..2"], "negative");
    fails(&["--frames", "1-3"], "not a range of frames");
    fails(&["--frames", "0..99999999"], "past the last frame");
    fails(&["--frame", "-1"], "--frame");
    fails(&["--frames", "0..2", "--fps", "0"], "--fps");
    fails(&["--frames", "0..2", "--fps", "NaN"], "--fps");
    fails(&["--frames", "0..2", "--fps", "-24"], "--fps");
    fails(&["--frames", "0..2", "--shutter", "1.5"], "--shutter");
    fails(&["--fps", "24"], "need --frames");
    fails(&["--frames", "0..2", "--frame", "1"], "cannot be used with");
    fails(&["--frames", "0..2", "--progressive"], "--progressive");
    let o = rayscope(d, &["render", "spheres", "-o", "x.png", "--frames", "scene"]);
    assert!(stderr(&o).contains("no `[animation] frames`"), "{}", stderr(&o));
    std::fs::write(d.join("bad.toml"), "[animation]\nfps = -1\n").unwrap();
    let o = rayscope(d, &["render", "bad.toml", "-o", "x.png"]);
    let err = stderr(&o);
    assert!(err.contains("bad.toml:1") && err.contains("animation: fps -1"), "{err}");
}
