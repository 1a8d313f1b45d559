//! The `rayscope` binary end to end: default render, scenes, debug, and clear errors.

use std::path::Path;
use std::process::{Command, Output};

mod common;

use common::{interrupted, rayscope, stderr};

#[test]
fn default_render_works_anywhere() {
    // From an empty folder with no asset folder beside it.
    let dir = tempfile::tempdir().unwrap();
    let o = rayscope(dir.path(), &["render", "-o", "out.png", "--width", "64", "--height", "48"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(dir.path().join("out.png")).unwrap();
    assert_eq!((img.width(), img.height()), (64, 48));
    let err = stderr(&o);
    assert!(err.contains("cornell-box") && err.contains("Mrays/s") && err.contains("levels"), "{err}");
}

#[test]
fn float_outputs_and_aovs() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        vec!["render", "spheres", "-o", "c.exr", "--width", "16", "--height", "16"],
        vec!["render", "-o", "d.pfm", "--aov", "depth", "--width", "16", "--height", "16"],
        vec!["render", "-o", "p.exr", "--aov", "prim-id", "--width", "16", "--height", "16"],
    ] {
        let o = rayscope(dir.path(), &args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    }
    let depth = rayscope::output::read_pfm(&dir.path().join("d.pfm")).unwrap();
    assert!(depth.data.iter().any(|v| v.is_nan()) && depth.data.iter().any(|v| v.is_finite()));
    let o = rayscope(dir.path(), &["render", "-o", "a.png", "--aov", "depth"]);
    assert!(!o.status.success() && stderr(&o).contains(".exr or .pfm"));
}

#[test]
fn scenes_list_and_export_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let o = rayscope(dir.path(), &["scenes"]);
    let list = String::from_utf8_lossy(&o.stdout);
    assert!(list.contains("cornell-box") && list.contains("dragon"));
    let o = rayscope(dir.path(), &["scenes", "--export", "spheres"]);
    assert!(o.status.success());
    std::fs::write(dir.path().join("s.toml"), &o.stdout).unwrap();
    let a = rayscope(dir.path(), &["render", "s.toml", "-o", "a.pfm", "--width", "20", "--height", "20"]);
    let b = rayscope(dir.path(), &["render", "spheres", "-o", "b.pfm", "--width", "20", "--height", "20"]);
    assert!(a.status.success() && b.status.success(), "{}", stderr(&a));
    assert_eq!(std::fs::read(dir.path().join("a.pfm")).unwrap(), std::fs::read(dir.path().join("b.pfm")).unwrap());
}

#[test]
fn thread_count_does_not_change_the_image() {
    let dir = tempfile::tempdir().unwrap();
    for t in ["1", "2"] {
        let o = rayscope(
            dir.path(),
            &["render", "-o", &format!("t{t}.pfm"), "--threads", t, "--width", "50", "--height", "30"],
        );
        assert!(o.status.success());
    }
    assert_eq!(std::fs::read(dir.path().join("t1.pfm")).unwrap(), std::fs::read(dir.path().join("t2.pfm")).unwrap());
}

#[test]
fn debug_prints_the_ray_tree() {
    let dir = tempfile::tempdir().unwrap();
    // The centre of the default Cornell box view hits the mirror box: a camera ray with a
    // reflection child.
    let o = rayscope(dir.path(), &["debug", "--pixel", "400,400"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rays = v["samples"][0]["rays"].as_array().unwrap();
    assert_eq!(rays[0]["kind"], "camera");
    assert!(rays[0]["hit"].is_object());
    assert!(rays.iter().any(|r| r["kind"] == "reflection" && r["parent"] == 0), "{v}");
    assert!(!rays[0]["shadows"].as_array().unwrap().is_empty());
    // The mirror box's material, by name beside its index.
    assert!(rays[0]["hit"]["material"].is_u64() && rays[0]["hit"]["material_name"].is_string(), "{v}");
    assert_eq!(v["value"], v["samples"][0]["color"]);
    assert_eq!(v["explanation"]["value"], v["value"]);
}

/// All of a pixel's samples are traced by default, one with `--samples K` (or `--sample K`);
/// `--explain` prints the terms and their sum; `--export-rays` writes an OBJ.
#[test]
fn debug_traces_every_sample_and_explains_the_colour() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["debug", "--pixel", "20,20", "--width", "40", "--height", "40", "--spp", "4", "--light-samples", "2"];
    let o = rayscope(d, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let samples = v["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 4);
    assert!(samples.iter().all(|s| s["weight"] == 0.25));
    let terms = v["explanation"]["terms"].as_array().unwrap();
    assert!(terms.iter().any(|t| t["kind"] == "diffuse" && t["light"] == 0), "{v}");
    for one in [["--samples", "2"], ["--sample", "2"]] {
        let o = rayscope(d, &[&args[..], &one[..]].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let w: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(w["samples"].as_array().unwrap().len(), 1);
        assert_eq!(w["samples"][0]["rays"], samples[2]["rays"]);
        assert_eq!(w["value"], samples[2]["color"]);
    }
    let o = rayscope(d, &[&args[..], &["--explain", "--export-rays", "rays.obj"][..]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout.clone()).unwrap();
    assert!(text.contains("sample 3 (weighs 0.25)") && text.contains("diffuse light 0"), "{text}");
    assert!(text.contains("sum of the terms") && text.contains("the pixel (renderer)"), "{text}");
    let obj = std::fs::read_to_string(d.join("rays.obj")).unwrap();
    assert!(obj.contains("g camera\n") && obj.lines().any(|l| l.starts_with("l ")), "{obj}");
    assert!(stderr(&o).contains("wrote rays.obj"), "{}", stderr(&o));
    fails_with(d, &["debug", "--pixel", "1,1", "--samples", "some"], &["neither `all` nor a sample index"]);
    fails_with(d, &["debug", "--pixel", "1,1", "--samples", "1", "--sample", "1"], &["cannot be used with"]);
}

fn fails_with(dir: &Path, args: &[&str], needles: &[&str]) {
    let o = rayscope(dir, args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} should fail");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: expected '{n}' in: {err}");
    }
}

#[test]
fn bad_input_gives_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("bad.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n").unwrap();
    std::fs::write(d.join("nan.obj"), "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(
        d.join("bad.toml"),
        "name = \"x\"\n[[light]]\nkind = \"point\"\nposition = [0, 0]\ncolor = [1, 1, 1]\n",
    )
    .unwrap();
    std::fs::write(d.join("unknown.toml"), "[render]\nwidht = 3\n").unwrap();
    std::fs::write(d.join("mesh.toml"), "[[mesh]]\npath = \"bad.obj\"\n").unwrap();
    fails_with(d, &["render", "bad.obj", "-o", "o.png"], &["bad.obj:4", "out of range"]);
    fails_with(d, &["render", "nan.obj", "-o", "o.png"], &["nan.obj:2"]);
    fails_with(d, &["render", "mesh.toml", "-o", "o.png"], &["bad.obj:4"]);
    fails_with(d, &["render", "bad.toml", "-o", "o.png"], &["bad.toml:4", "expected a sequence of 3"]);
    fails_with(d, &["render", "unknown.toml", "-o", "o.png"], &["unknown.toml:2", "widht"]);
    fails_with(d, &["render", "missing.toml", "-o", "o.png"], &["missing.toml"]);
    fails_with(d, &["render", "no-such-scene", "-o", "o.png"], &["unknown scene", "cornell-box"]);
    // A path that names no format read is refused as such (not looked up as a scene's name),
    // without reading it.
    for path in ["/etc/passwd", "/dev/zero", "model.stl", "./cornell-box"] {
        fails_with(d, &["render", path, "-o", "o.png"], &[path, "not a scene rayscope reads", ".toml", "cornell-box"]);
    }
    fails_with(d, &["render", "dragon", "-o", "o.png", "--assets", "nowhere"], &["dragon.obj", "--assets"]);
    fails_with(d, &["debug", "--pixel", "1,1", "--sample", "1"], &["has 1 sample (--spp)"]);
    fails_with(d, &["render", "-o", "o.png", "--width", "0"], &["out of range"]);
    fails_with(d, &["render", "-o", "o.png", "--width", "100000"], &["out of range"]);
    fails_with(d, &["render", "-o", "o.jpg"], &["unknown image format"]);
    fails_with(d, &["render", "-o", "o.png", "--threads", "0"], &["--threads"]);
    // Thousands of threads exhausted the process (5000) or hung (100000).
    fails_with(d, &["render", "-o", "o.png", "--threads", "5000"], &["--threads", "out of range"]);
    fails_with(d, &["render", "-o", "o.png", "--threads", "100000"], &["--threads", "out of range"]);
    fails_with(d, &["bench", "--threads", "100000"], &["--threads", "out of range"]);
    fails_with(d, &["render", "-o", "o.png", "--max-depth", "x"], &["invalid value"]);
    fails_with(d, &["debug", "--pixel", "900,1"], &["outside"]);
    // Nothing was written by any failing command.
    let written: Vec<_> = std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(!written.iter().any(|n| n.to_string_lossy().starts_with('o')), "{written:?}");
}

#[test]
fn a_missing_course_file_names_the_folder_searched_and_how_it_was_chosen() {
    // Outside the repository: no ../shared/scenes, no RAYSCOPE_ASSETS.
    let dir = tempfile::tempdir().unwrap();
    let cwd = dir.path().canonicalize().unwrap();
    let cwd = cwd.to_str().unwrap();
    fails_with(
        dir.path(),
        &["render", "dragon", "-o", "o.png"],
        &["dragon.obj: not found", "No asset folder", "../shared/scenes", cwd, "--assets DIR", "RAYSCOPE_ASSETS"],
    );
    fails_with(
        dir.path(),
        &["render", "dragon", "-o", "o.png", "--assets", "nowhere"],
        &["given (--assets): nowhere", &format!("{cwd}/nowhere")],
    );
    let o = Command::new(env!("CARGO_BIN_EXE_rayscope"))
        .args(["render", "dragon", "-o", "o.png"])
        .current_dir(dir.path())
        .env("RAYSCOPE_ASSETS", "/no/such/folder")
        .output()
        .unwrap();
    assert!(!o.status.success() && stderr(&o).contains("named by RAYSCOPE_ASSETS: /no/such/folder"), "{}", stderr(&o));
    // Beside a `shared/scenes` without the file: the default folder, and that it is one.
    std::fs::create_dir_all(dir.path().join("shared/scenes")).unwrap();
    let repo = dir.path().join("repo");
    std::fs::create_dir(&repo).unwrap();
    fails_with(&repo, &["render", "dragon", "-o", "o.png"], &["default asset folder", "../shared/scenes"]);
}

#[test]
fn counts_of_one_are_singular() {
    let dir = tempfile::tempdir().unwrap();
    let o = rayscope(dir.path(), &["render", "single-triangle", "-o", "t.png", "--width", "8", "--height", "8"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("single-triangle: 1 triangle,") && err.contains("(1 level)"), "{err}");
}

#[test]
fn course_assets_via_env_and_flag() {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes");
    if !assets.join("monkey-rotated.obj").is_file() {
        eprintln!("NOTICE: course_assets_via_env_and_flag: shared/scenes is absent; skipping");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let a = assets.to_str().unwrap();
    let o =
        rayscope(dir.path(), &["render", "monkey", "-o", "m.png", "--assets", a, "--width", "32", "--height", "32"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = Command::new(env!("CARGO_BIN_EXE_rayscope"))
        .args(["render", "teapot", "-o", "t.png", "--width", "32", "--height", "32"])
        .current_dir(dir.path())
        .env("RAYSCOPE_ASSETS", a)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn progressive_render_equals_one_shot() {
    let dir = tempfile::tempdir().unwrap();
    let common = ["cornell-box-sphere-light", "--width", "24", "--height", "24", "--light-samples", "4"];
    let mut a = vec!["render", "-o", "a.pfm", "--spp", "8"];
    a.extend(common);
    let mut b = vec!["render", "-o", "b.pfm", "--progressive", "--spp", "2", "--target-spp", "8"];
    b.extend(common);
    for args in [a, b] {
        let o = rayscope(dir.path(), &args);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).contains("8 spp"), "{}", stderr(&o));
    }
    assert_eq!(std::fs::read(dir.path().join("a.pfm")).unwrap(), std::fs::read(dir.path().join("b.pfm")).unwrap());
}

#[test]
fn repeated_renders_report_the_fastest_and_write_the_same_image() {
    let dir = tempfile::tempdir().unwrap();
    let common = ["cornell-box-sphere-light", "--width", "24", "--height", "24", "--light-samples", "4", "--spp", "2"];
    let mut a = vec!["render", "-o", "a.pfm"];
    a.extend(common);
    let mut b = vec!["render", "-o", "b.pfm", "--repeat", "3"];
    b.extend(common);
    assert!(rayscope(dir.path(), &a).status.success());
    let o = rayscope(dir.path(), &b);
    assert!(o.status.success() && stderr(&o).contains("(fastest of 3)"), "{}", stderr(&o));
    assert_eq!(std::fs::read(dir.path().join("a.pfm")).unwrap(), std::fs::read(dir.path().join("b.pfm")).unwrap());
    fails_with(dir.path(), &["render", "-o", "c.png", "--repeat", "0"], &["--repeat"]);
    fails_with(dir.path(), &["render", "-o", "c.png", "--repeat", "2", "--progressive"], &["--repeat"]);
}

#[test]
fn ctrl_c_writes_what_was_rendered() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["render", "cornell-box-sphere-light", "-o", "p.png", "--progressive", "--light-samples", "8"];
    let out = interrupted(dir.path(), &[&args[..], &["--width", "64", "--height", "64"]].concat(), 1500);
    let err = stderr(&out);
    // A stopped render is not a finished one: the shell's code for SIGINT, after the image.
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted") && err.contains("spp") && err.contains("130"), "{err}");
    assert!(image::open(dir.path().join("p.png")).is_ok());
}

#[test]
fn sampling_flags_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fails_with(d, &["render", "-o", "o.png", "--spp", "0"], &["samples per pixel"]);
    fails_with(d, &["render", "-o", "o.png", "--light-samples", "9999999"], &["out of range"]);
    fails_with(d, &["render", "-o", "o.png", "--target-spp", "4"], &["--progressive"]);
    fails_with(d, &["render", "-o", "o.png", "--camera-end", "1,2"], &["RX,RY,RZ"]);
    fails_with(d, &["render", "-o", "o.png", "--camera-end", "1,2,3,0"], &["--camera-end", "positive"]);
    fails_with(d, &["render", "-o", "o.png", "--progressive", "--time-limit=-1"], &["--time-limit"]);
    fails_with(d, &["render", "-o", "o.png", "--progressive", "--target-spp", "0"], &["--target-spp"]);
    let o = rayscope(
        d,
        &["render", "-o", "t.png", "--progressive", "--time-limit", "0.2", "--width", "16", "--height", "16"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = rayscope(
        d,
        &["render", "-o", "blur.png", "--camera-end", "20,40,0", "--spp", "4", "--width", "16", "--height", "16"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = rayscope(
        d,
        &["render", "-o", "f.png", "--spp", "4", "--filter", "gaussian", "--width", "16", "--height", "16"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// `rayscope view ARGS` in a real window under Xvfb, from `dir`, with no runtime dir (as over
/// ssh or in CI); `None` (with a notice) where xvfb-run is not installed. Fails after 120 s:
/// a view that never finishes its frames keeps its window open.
#[cfg(feature = "viewer")]
fn view_under_xvfb(dir: &Path, args: &[&str]) -> Option<Output> {
    let found = Command::new("sh").args(["-c", "command -v xvfb-run"]).output().map(|o| o.status.success());
    if !found.unwrap_or(false) {
        eprintln!("NOTICE: xvfb-run is not installed (see .ci/run); skipping the `rayscope view` window test");
        return None;
    }
    let mut child = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x1000x24", env!("CARGO_BIN_EXE_rayscope"), "view"])
        .args(args)
        .current_dir(dir)
        .env("WGPU_BACKEND", "vulkan")
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("RAYSCOPE_ASSETS")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed().as_secs() > 120 {
            let _ = child.kill();
            panic!("rayscope view {args:?} did not exit within 120 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let out = child.wait_with_output().unwrap();
    // Nothing is wrong without a runtime dir: no alarming line about it.
    assert!(!stderr(&out).contains("XDG_RUNTIME_DIR"), "{}", stderr(&out));
    Some(out)
}

/// Every view saves its screenshot after `--frames 2` and exits (the heat map, one frame,
/// used to wait for ever).
#[cfg(feature = "viewer")]
#[test]
fn every_view_finishes_its_frames_under_xvfb() {
    let dir = tempfile::tempdir().unwrap();
    for view in ["raster", "traced", "heat-map"] {
        let shot = format!("{view}.png");
        let args = ["cornell-box", "--view", view, "--screenshot", &shot, "--frames", "2"];
        let Some(out) = view_under_xvfb(dir.path(), &args) else { return };
        assert!(out.status.success(), "{view}: {}", stderr(&out));
        let img = image::open(dir.path().join(&shot)).unwrap();
        assert!(img.width() >= 800 && img.height() >= 600, "{view}");
    }
}

/// Without a display, `view` says so and how to get one, not winit's internal message.
#[cfg(feature = "viewer")]
#[test]
fn view_without_a_display_says_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_rayscope"))
        .args(["view", "--screenshot", "s.png"])
        .current_dir(dir.path())
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    for needle in ["no display found", "xvfb-run -a", "WGPU_BACKEND=vulkan"] {
        assert!(err.contains(needle), "expected '{needle}' in: {err}");
    }
}

/// A `rayscope` built without the viewer says how to build it with.
#[cfg(not(feature = "viewer"))]
#[test]
fn view_without_the_viewer_feature_says_how_to_get_it() {
    eprintln!(
        "NOTICE: built without the `viewer` feature (`cargo test --workspace` turns it on); not testing the window"
    );
    let dir = tempfile::tempdir().unwrap();
    fails_with(dir.path(), &["view"], &["--features viewer"]);
}

/// The real binary in a real window under Xvfb: `rayscope view --screenshot`.
#[cfg(feature = "viewer")]
#[test]
fn view_screenshot_under_xvfb() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "cornell-box",
        "--screenshot",
        "shot.png",
        "--debug-pixel",
        "400,400",
        "--bvh-tree",
        "binary",
        "--bvh-level",
        "2",
    ];
    let Some(out) = view_under_xvfb(dir.path(), &[&args[..], &["--frames", "2"]].concat()) else { return };
    assert!(out.status.success(), "{}", stderr(&out));
    let img = image::open(dir.path().join("shot.png")).unwrap().to_rgb8();
    assert!(img.width() >= 800 && img.height() >= 600);
    // The 3D view's background (its clear colour) frames the image: find it.
    let bg = [15u8, 15, 18];
    let (mut lo, mut hi) = ((u32::MAX, u32::MAX), (0, 0));
    for (x, y, p) in img.enumerate_pixels() {
        if p.0 == bg {
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
    }
    assert!(hi.0 > lo.0 + 400 && hi.1 > lo.1 + 400, "the 3D view is there: {lo:?}..{hi:?}");
    let centre = ((lo.0 + hi.0) / 2, (lo.1 + hi.1) / 2);
    let within = |r: u32, pred: &dyn Fn([u8; 3]) -> bool| {
        let mut n = 0;
        for y in centre.1.saturating_sub(r)..(centre.1 + r).min(img.height()) {
            for x in centre.0.saturating_sub(r)..(centre.0 + r).min(img.width()) {
                if pred(img.get_pixel(x, y).0) {
                    n += 1;
                }
            }
        }
        n
    };
    let near = |c: [u8; 3], w: [u8; 3]| (0..3).all(|i| (c[i] as i32 - w[i] as i32).abs() < 40);
    // Not blank: the scene's walls, red and green.
    assert!(within(400, &|c| c[0] > 90 && c[1] < 40 && c[2] < 40) > 2000, "red wall");
    assert!(
        within(400, &|c| c[1] > 25 && c[1] as u32 > 2 * c[0] as u32 && c[1] as u32 > 2 * c[2] as u32) > 2000,
        "green wall"
    );
    // The ray overlay at the selected pixel (the image centre): the hit triangle's outline
    // (pink) and the normal (blue) near it, and the shadow ray (green).
    assert!(within(150, &|c| near(c, [255, 89, 217])) > 20, "hit triangle outline near the centre");
    assert!(within(120, &|c| near(c, [51, 102, 255])) > 5, "hit normal at the centre");
    assert!(within(400, &|c| near(c, [51, 255, 51])) > 20, "shadow ray");
    // BVH boxes of level 2 (cyan) and leaves (orange).
    assert!(within(400, &|c| near(c, [77, 230, 230])) > 200, "BVH boxes");
}

#[test]
fn bench_quick_has_every_row() {
    let dir = tempfile::tempdir().unwrap();
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes");
    let have_assets = assets.join("dragon.obj").is_file();
    if !have_assets {
        eprintln!("NOTICE: bench_quick_has_every_row: shared/scenes is absent; rows that need it are skipped");
    }
    let o = Command::new(env!("CARGO_BIN_EXE_rayscope"))
        .args(["bench", "--quick", "--json", "b.json", "--csv", "b.csv", "--assets"])
        .arg(&assets)
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout);
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("b.json")).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 14, "the course report's eleven rows, and motion's and depth of field's three");
    assert_eq!(rows.iter().filter(|r| r["report_ms"].is_f64()).count(), 11, "the course report's eleven rows");
    assert!(v["machine"]["cpu"].is_string());
    for r in rows {
        let name = r["scene"].as_str().unwrap();
        assert!(table.contains(name.trim()), "{name} in the Markdown table");
        for key in ["triangles", "build_ms", "levels", "render_ms", "mrays_per_s", "report_ms"] {
            assert!(r.get(key).is_some(), "{name}: {key}");
        }
        if have_assets {
            assert!(r["render_ms"].as_f64().unwrap() > 0.0 && r["mrays_per_s"].as_f64().unwrap() > 0.0, "{name}");
        }
    }
    let csv = std::fs::read_to_string(dir.path().join("b.csv")).unwrap();
    assert_eq!(csv.lines().count(), 15, "a header and fourteen rows");
}

#[test]
fn output_errors_name_the_output_once() {
    let dir = tempfile::tempdir().unwrap();
    let o = rayscope(dir.path(), &["render", "-o", "no/dir/x.png", "--width", "8", "--height", "8"]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(err.contains("no/dir/x.png: No such file or directory"), "{err}");
    assert_eq!(err.matches("os error").count(), 1, "the system's message once: {err}");
    assert!(!err.contains(".partial"), "{err}");
}

/// As an unprivileged user in a world-writable folder (like `/tmp`), `-o` must not replace
/// another user's read-only file, which renaming over it would. Runs where the tests run as
/// root and `setpriv` can drop to `nobody`; skipped (with a notice) elsewhere.
#[cfg(unix)]
#[test]
fn a_file_the_user_may_not_write_is_not_replaced() {
    use std::os::unix::fs::PermissionsExt;
    let root = std::process::Command::new("id").arg("-u").output().is_ok_and(|o| o.stdout == b"0\n");
    let setpriv = std::process::Command::new("setpriv").arg("--version").output().is_ok_and(|o| o.status.success());
    if !(root && setpriv) {
        eprintln!("skipped: needs root and setpriv to act as an unprivileged user");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // World-writable, without /tmp's sticky bit (which forbids renaming over others' files).
    std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o777)).unwrap();
    let p = d.join("f.png");
    std::fs::write(&p, b"root's").unwrap();
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o444)).unwrap();
    let as_nobody = || {
        Command::new("setpriv")
            .args(["--reuid=65534", "--regid=65534", "--clear-groups", "--"])
            .arg(env!("CARGO_BIN_EXE_rayscope"))
            .args(["render", "-o", "f.png", "--width", "8", "--height", "8"])
            .current_dir(d)
            .env_remove("RAYSCOPE_ASSETS")
            .output()
            .unwrap()
    };
    let o = as_nobody();
    let err = stderr(&o);
    if err.contains("Permission denied") && !err.contains("f.png") {
        eprintln!("skipped: nobody cannot run the test binary here: {err}");
        return;
    }
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("f.png") && err.contains("not writable"), "{err}");
    assert_eq!(std::fs::read(&p).unwrap(), b"root's");
    // A file the user may write is replaced as before, keeping its mode.
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o666)).unwrap();
    let o = as_nobody();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(image::open(&p).is_ok());
    assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o666);
}

/// Two nested spheres that reflect fully and let half the light through: every hit casts two
/// rays that hit again (issue 14: at --max-depth 64 it never finished, and `debug` grew to 5 GB).
const NESTED_SPHERES: &str = r#"
[camera]
kind = "look-at"
eye = [0, 0, -3]
target = [0, 0, 0]
up = [0, 1, 0]
fov = 40
[[sphere]]
center = [0, 0, 0]
radius = 1.0
material = { kd = [0.5, 0.5, 0.5], ks = [1, 1, 1], shininess = 20, transparency = 0.5 }
[[sphere]]
center = [0, 0, 0]
radius = 0.5
material = { kd = [0.5, 0.5, 0.5], ks = [1, 1, 1], shininess = 20, transparency = 0.5 }
[[light]]
kind = "point"
position = [0.3, 0.2, -0.2]
color = [1, 1, 1]
[render]
width = 8
height = 8
"#;

#[test]
fn debug_explains_stopped_branches_and_a_cut_tree() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("nested.toml"), NESTED_SPHERES).unwrap();
    let json = |o: &Output| serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap();
    // Adaptive depth control stops the tree; the debugger says where and why.
    let o = rayscope(d, &["debug", "nested.toml", "--pixel", "4,4", "--max-depth", "64"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v = json(&o)["samples"][0].clone();
    assert!(v["cut"].is_null() && v["rays"].as_array().unwrap().len() < 2048);
    let stopped = v["rays"].as_array().unwrap().iter().find(|r| r["stopped"].is_array()).expect("a stopped branch");
    assert_eq!(stopped["stopped"][0]["adc_bailout"], 1.0 / 1024.0);
    let err = stderr(&o);
    assert!(err.contains("adaptive depth control stopped") && err.contains("below adc_bailout 0.000977"), "{err}");
    // Without it the tree passes the bound given; the rest is counted, not printed.
    let o = rayscope(
        d,
        &["debug", "nested.toml", "--pixel", "4,4", "--max-depth", "16", "--adc-bailout", "0", "--max-rays", "1000"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v = json(&o)["samples"][0].clone();
    let rays = v["rays"].as_array().unwrap();
    let shadows: usize = rays.iter().map(|r| r["shadows"].as_array().unwrap().len()).sum();
    assert_eq!(rays.len() + shadows, 1000);
    assert_eq!(v["cut"]["limit"], 1000);
    assert!(v["cut"]["rays"].as_u64().unwrap() > 0);
    let err = stderr(&o);
    assert!(
        err.contains("the ray tree was cut (--max-rays): the first 1000 rays") && !err.contains("adaptive"),
        "{err}"
    );
}

#[test]
fn adc_bailout_is_checked_from_the_flag_and_the_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("nested.toml"), NESTED_SPHERES).unwrap();
    std::fs::write(d.join("bad.toml"), "[render]\nadc_bailout = 2.5\n").unwrap();
    std::fs::write(d.join("off.toml"), format!("{NESTED_SPHERES}max_depth = 3\nadc_bailout = 0\n")).unwrap();
    fails_with(d, &["render", "-o", "o.png", "--adc-bailout", "1.5"], &["adc_bailout 1.5", "0 to 1"]);
    fails_with(d, &["render", "-o", "o.png", "--adc-bailout", "NaN"], &["adc_bailout NaN"]);
    fails_with(d, &["render", "bad.toml", "-o", "o.png"], &["bad.toml", "adc_bailout 2.5"]);
    // The file's 0 turns it off: at max_depth 3 the tree is whole (15 rays at most).
    let o = rayscope(d, &["debug", "off.toml", "--pixel", "4,4"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("adaptive"), "{}", stderr(&o));
    let o = rayscope(d, &["debug", "off.toml", "--pixel", "4,4", "--adc-bailout", "0.3"]);
    assert!(stderr(&o).contains("below adc_bailout 0.3"), "{}", stderr(&o));
}

#[test]
fn debug_records_the_traversal_and_exports_a_bvh_level() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = rayscope::scene::Scene::load("cornell-box", None).unwrap();
    // The JSON gives each ray what the renderer's traversal entered.
    let o = rayscope(d, &["debug", "--pixel", "400,400", "--export-bvh-level", "1", "wide.obj"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let camera = &v["samples"][0]["rays"][0]["traversal"];
    assert_eq!(camera["query"], "packet", "{camera}");
    assert_eq!(camera["visits"][0]["at"]["node"], 0, "{camera}");
    assert!(camera["t_max"].is_null() && camera["t_min"] == 0.0, "{camera}");
    let shadow = &v["samples"][0]["rays"][0]["shadows"][0]["traversals"][0];
    assert_eq!(shadow["query"], "any-hit", "{shadow}");
    assert!(shadow["t_max"].as_f64().unwrap() > 0.0, "{shadow}");

    // The OBJ reloads with 8 corners and 12 edges a box, as many boxes as the level has.
    let check = |file: &str, boxes: usize| {
        let text = std::fs::read_to_string(d.join(file)).unwrap();
        let vertices: Vec<[f32; 3]> = text
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                let c: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
                [c[0], c[1], c[2]]
            })
            .collect();
        let segments: Vec<(usize, usize)> = text
            .lines()
            .filter_map(|l| l.strip_prefix("l "))
            .map(|l| {
                let i: Vec<usize> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
                assert_eq!(i.len(), 2, "{l}");
                (i[0], i[1])
            })
            .collect();
        assert_eq!((vertices.len(), segments.len()), (8 * boxes, 12 * boxes), "{file}");
        // Every segment is an edge of its own box: both ends in it, one axis apart.
        for &(a, b) in &segments {
            assert!(a >= 1 && b >= 1 && (a - 1) / 8 == (b - 1) / 8, "{file}: {a} {b}");
            let (p, q) = (vertices[a - 1], vertices[b - 1]);
            assert_eq!((0..3).filter(|&k| p[k] != q[k]).count(), 1, "{file}: {p:?} {q:?}");
        }
        assert!(text.contains("g level-") && text.contains("-nodes") && text.contains("-leaves"), "{file}");
    };
    check("wide.obj", scene.wide_boxes_at_level(1).len());
    for level in [0, 2] {
        let file = format!("binary{level}.obj");
        let level_arg = level.to_string();
        let args = ["debug", "--pixel", "1,1", "--export-bvh-level", &level_arg, &file, "--bvh-tree", "binary"];
        let o = rayscope(d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        check(&file, scene.geometry.bvh.boxes_at_level(level).len());
    }
    fails_with(d, &["debug", "--pixel", "1,1", "--export-bvh-level", "99", "x.obj"], &["level 99 does not exist"]);
    fails_with(d, &["debug", "--pixel", "1,1", "--export-bvh-level", "two", "x.obj"], &["'two' is not a level"]);
    assert!(!d.join("x.obj").exists());
}

#[test]
fn lens_flags_and_keys_are_checked_and_exported() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fails_with(d, &["render", "-o", "o.png", "--aperture", "-0.1"], &["--aperture", "lens radius"]);
    fails_with(d, &["render", "-o", "o.png", "--aperture", "NaN"], &["--aperture"]);
    fails_with(d, &["render", "-o", "o.png", "--focus-distance", "0"], &["--focus-distance", "above 0"]);
    fails_with(d, &["render", "-o", "o.png", "--focus-distance", "-3"], &["--focus-distance"]);
    std::fs::write(d.join("bad.toml"), "[render]\naperture = -1.0\n").unwrap();
    fails_with(d, &["render", "bad.toml", "-o", "o.png"], &["bad.toml", "aperture -1"]);
    std::fs::write(d.join("far.toml"), "[render]\nfocus_distance = -2.0\n").unwrap();
    fails_with(d, &["render", "far.toml", "-o", "o.png"], &["far.toml", "focus distance -2"]);
    // A scene file's lens renders, and so do the flags'.
    std::fs::write(
        d.join("dof.toml"),
        "[render]\nwidth = 16\nheight = 16\nspp = 4\naperture = 0.1\nfocus_distance = 2.5\n",
    )
    .unwrap();
    let o = rayscope(d, &["render", "dof.toml", "-o", "dof.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = rayscope(
        d,
        &["render", "-o", "flag.png", "--aperture", "0.1", "--spp", "4", "--width", "16", "--height", "16"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}
