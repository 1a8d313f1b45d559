//! Loaders against hostile files (issue 14): whatever a path names and whatever a file holds,
//! loading ends in a scene or an error naming the file (and line), never a panic, a hang or
//! memory exhausted.

use std::path::{Path, PathBuf};

use rayscope::Error;
use rayscope::math::Vec3;
use rayscope::scene::{DEFAULT_MAX_FILE_BYTES, Scene};

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

/// A folder holding the given files.
fn folder(files: &[(&str, &str)]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    dir
}

fn load(path: &Path) -> rayscope::Result<Scene> {
    Scene::load(path.to_str().unwrap(), None)
}

/// The file and line of a parse error, and its message.
fn parse_error(result: rayscope::Result<Scene>) -> (PathBuf, Option<usize>, String) {
    match result {
        Err(Error::Parse { path, line, message }) => (path, line, message),
        Err(e) => panic!("expected a parse error, got {e}"),
        Ok(_) => panic!("expected a parse error, got a scene"),
    }
}

fn material<'a>(scene: &'a Scene, name: &str) -> &'a rayscope::scene::Material {
    scene.materials.iter().find(|m| m.name == name).unwrap_or_else(|| panic!("no material '{name}'"))
}

fn obj_with_mtl(mtl: &str) -> tempfile::TempDir {
    let obj = format!("mtllib m.mtl\n{TRIANGLE}usemtl red\nf 1 2 3\n");
    folder(&[("a.obj", &obj), ("m.mtl", mtl)])
}

#[test]
fn a_colour_of_one_value_is_grey() {
    let dir = obj_with_mtl("newmtl red\nKd 0.5\nKs 0.25\nKa 1\nKe 1\nTf 1\n");
    let scene = load(&dir.path().join("a.obj")).unwrap();
    let m = material(&scene, "red");
    assert_eq!((m.kd, m.ks), (Vec3::splat(0.5), Vec3::splat(0.25)));
}

#[test]
fn a_colour_of_two_values_is_an_error_at_its_line() {
    for line in ["Ks 0.5 0.5", "Ke 1 1", "Kd", "Kd spectral x.rfl", "Kd 1 2 3 4", "Ns", "d 1 2"] {
        let dir = obj_with_mtl(&format!("newmtl red\n{line}\n"));
        let (path, at, message) = parse_error(load(&dir.path().join("a.obj")));
        assert_eq!((path, at), (dir.path().join("m.mtl"), Some(2)), "{line}: {message}");
    }
}

#[test]
fn paths_that_are_no_regular_file_are_refused() {
    let dir = folder(&[]);
    let fifo = dir.path().join("fifo.png");
    let made_fifo = std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success());
    let obj = |mtllib: &str| format!("mtllib {mtllib}\n{TRIANGLE}usemtl t\nf 1 2 3\n");
    let mut cases = vec![
        ("zero.obj", "/dev/zero".to_string()),
        ("random.obj", "/dev/urandom".to_string()),
        ("folder.obj", "/".to_string()),
        ("scene.toml", "/dev/zero".to_string()),
    ];
    std::fs::write(dir.path().join("mtl-zero.obj"), obj("/dev/zero")).unwrap();
    std::fs::write(dir.path().join("tex.mtl"), "newmtl t\nmap_Kd /dev/urandom\n").unwrap();
    std::fs::write(dir.path().join("tex.obj"), obj("tex.mtl")).unwrap();
    if made_fifo {
        std::fs::write(dir.path().join("fifo.mtl"), "newmtl t\nmap_Kd -s 1 1 1 fifo.png\n").unwrap();
        std::fs::write(dir.path().join("fifo.obj"), obj("fifo.mtl")).unwrap();
    }
    for (link, target) in cases.drain(..) {
        std::os::unix::fs::symlink(target, dir.path().join(link)).unwrap();
    }
    for (name, refused) in [
        ("zero.obj", "zero.obj"),
        ("random.obj", "random.obj"),
        ("folder.obj", "folder.obj"),
        ("scene.toml", "scene.toml"),
        ("mtl-zero.obj", "/dev/zero"),
        ("tex.obj", "/dev/urandom"),
        ("fifo.obj", "fifo.png"),
    ] {
        if name == "fifo.obj" && !made_fifo {
            continue;
        }
        match load(&dir.path().join(name)) {
            Err(e @ Error::NotAFile { .. }) => assert!(e.to_string().contains(refused), "{name}: {e}"),
            Err(e) => panic!("{name}: expected 'not a regular file', got {e}"),
            Ok(_) => panic!("{name}: loaded"),
        }
    }
}

#[test]
fn files_larger_than_the_limit_are_refused_before_reading() {
    let dir = folder(&[]);
    let path = dir.path().join("huge.obj");
    // Sparse: no disk space, and nothing is read.
    std::fs::File::create(&path).unwrap().set_len(DEFAULT_MAX_FILE_BYTES + 1).unwrap();
    match load(&path) {
        Err(e @ Error::TooLarge { .. }) => {
            assert!(e.to_string().contains("RAYSCOPE_MAX_FILE_BYTES"), "{e}");
            assert!(e.to_string().contains("--max-file-bytes"), "{e}");
        }
        Err(e) => panic!("expected 'too large', got {e}"),
        Ok(_) => panic!("loaded"),
    }
}

#[test]
fn a_large_file_of_zeros_fails_at_line_1_without_being_read() {
    let dir = folder(&[]);
    // Sparse, under the limit: streamed, the first line's NUL ends the reading, where the
    // whole file was read into memory (2 GB) before it was checked.
    for name in ["zeros.obj", "zeros.toml"] {
        let path = dir.path().join(name);
        std::fs::File::create(&path).unwrap().set_len(2 << 30).unwrap();
        let start = std::time::Instant::now();
        let (at, line, message) = parse_error(load(&path));
        assert_eq!((at, line), (path, Some(1)), "{message}");
        assert!(message.contains("NUL"), "{message}");
        // Not a timing test: seconds would mean the whole file was read (2 GB of zeros).
        assert!(start.elapsed().as_secs() < 20);
    }
}

#[test]
fn negative_colours_and_dissolves_outside_0_1_are_errors_at_their_line() {
    for line in ["Kd -0.5", "Ks 1 -1 1", "Ka 0 0 -1", "Ke -1", "Tf 1 1 -0.1", "d 1.5", "d -0.1", "d -halo 2"] {
        let dir = obj_with_mtl(&format!("newmtl red\nKd 0.5\n{line}\n"));
        let (path, at, message) = parse_error(load(&dir.path().join("a.obj")));
        assert_eq!((path, at), (dir.path().join("m.mtl"), Some(3)), "{line}: {message}");
    }
    let dir = obj_with_mtl("newmtl red\nKd 0 0 0\nd 0\n");
    assert_eq!(material(&load(&dir.path().join("a.obj")).unwrap(), "red").transparency, 0.0);
}

#[test]
fn files_that_are_no_mesh_are_errors_naming_the_line() {
    let passwd = "root:x:0:0:root:/root:/bin/bash\ndaemon:x:1:1::/usr/sbin:/usr/sbin/nologin\n";
    let toml = "# a scene\nname = \"x\"\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n";
    let zeros = "\0".repeat(4096);
    let latin1 = "v 0 0 0\n# caf\u{e9}\n";
    let dir = folder(&[("passwd.obj", passwd), ("scene.obj", toml), ("zeros.obj", &zeros)]);
    let mut bytes = latin1.as_bytes().to_vec();
    // "é" in Latin-1.
    bytes.splice(bytes.len() - 3..bytes.len() - 1, [0xe9]);
    std::fs::write(dir.path().join("latin1.obj"), bytes).unwrap();
    for (name, line, why) in [
        ("passwd.obj", 1, "not an OBJ statement"),
        ("scene.obj", 2, "not an OBJ statement"),
        ("zeros.obj", 1, "not a text file"),
        ("latin1.obj", 2, "not a text file"),
    ] {
        let (path, at, message) = parse_error(load(&dir.path().join(name)));
        assert_eq!((path, at), (dir.path().join(name), Some(line)), "{message}");
        assert!(message.contains(why), "{message}");
    }
}

#[test]
fn a_mesh_without_faces_is_an_error() {
    let dir = folder(&[("empty.obj", ""), ("points.obj", TRIANGLE), ("lines.obj", &format!("{TRIANGLE}l 1 2 3\n"))]);
    for name in ["empty.obj", "points.obj", "lines.obj"] {
        let (path, _, message) = parse_error(load(&dir.path().join(name)));
        assert_eq!(path, dir.path().join(name));
        assert!(message.contains("no faces"), "{message}");
    }
}

#[test]
fn texture_indices_without_texture_coordinates_are_ignored_with_a_warning() {
    // The course's triangle.obj.
    let text = "# triangle.obj\n#\n\nv  0.0  0.0  0.0\nv  0.0  0.0  1.0\nv  0.0  1.0  0.0\n\nvn  0.0  0.0  -1.0\n\nf  1/1  2/1  3/1 \n";
    let dir = folder(&[("triangle.obj", text)]);
    let scene = load(&dir.path().join("triangle.obj")).unwrap();
    assert_eq!(scene.meshes[0].triangles.len(), 1);
    assert!(scene.meshes[0].uvs.is_empty());
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(scene.warnings[0].contains("triangle.obj:10"), "{}", scene.warnings[0]);
    // But texture coordinates defined after the faces that use them break OBJ's rule.
    let later = format!("{TRIANGLE}f 1/1 2/1 3/1\nvt 0 0\n");
    let dir = folder(&[("later.obj", &later)]);
    assert_eq!(parse_error(load(&dir.path().join("later.obj"))).1, Some(4));
}

#[test]
fn the_course_triangle_loads() {
    let Some(assets) = std::env::var_os("RAYSCOPE_ASSETS").map(PathBuf::from) else { return };
    let scene = load(&assets.join("triangle.obj")).unwrap();
    assert_eq!(scene.meshes[0].triangles.len(), 1);
    assert_eq!(scene.warnings.len(), 1);
}

#[test]
fn every_obj_error_names_the_file_and_line() {
    // Each line is what tobj reports without a line (its message in the comment).
    let cases = [
        ("f 1 2 9", "face vertex index out of bounds"),
        ("f 1 2 0", "face vertex index out of bounds"),
        ("f 1/1/1/1 2 3", "face parse error"),
        ("f 1 2 x", "face parse error"),
        ("l 1 y", "face parse error"),
        ("vt 0.5", "texcoord parse error"),
        ("vt a b", "texcoord parse error"),
        ("vn 0 1", "normal parse error"),
        ("v 1 2 3 4 5", "color parse error"),
        ("v 1 2 3 0", "scaling by zero"),
        ("usemtl", "material parse error"),
        ("mtllib", "the folder read as a file"),
    ];
    for (line, what) in cases {
        let text = format!("{TRIANGLE}{line}\nf 1 2 3\n");
        let dir = folder(&[("bad.obj", &text)]);
        let (path, at, message) = parse_error(load(&dir.path().join("bad.obj")));
        assert_eq!((path, at), (dir.path().join("bad.obj"), Some(4)), "{line} ({what}): {message}");
    }
    // Vertex colours on some vertices only, which tobj pairs up by position.
    let dir = folder(&[("colours.obj", "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")]);
    assert_eq!(parse_error(load(&dir.path().join("colours.obj"))).1, Some(2));
}

#[test]
fn every_library_of_an_mtllib_line_is_read() {
    let obj = format!("mtllib a.mtl b.mtl\n{TRIANGLE}usemtl from-b\nf 1 2 3\nusemtl from-a\nf 3 2 1\n");
    let dir =
        folder(&[("two.obj", &obj), ("a.mtl", "newmtl from-a\nKd 1 0 0\n"), ("b.mtl", "newmtl from-b\nKd 0 1 0\n")]);
    let scene = load(&dir.path().join("two.obj")).unwrap();
    assert_eq!(material(&scene, "from-a").kd, Vec3::X);
    assert_eq!(material(&scene, "from-b").kd, Vec3::Y);
    let used: Vec<&str> = scene.meshes.iter().map(|m| scene.materials[m.materials[0] as usize].name.as_str()).collect();
    assert_eq!(used, ["from-b", "from-a"]);
}

#[test]
fn texture_options_are_skipped_and_the_file_name_is_last() {
    let dir = folder(&[]);
    image::RgbImage::from_pixel(2, 2, image::Rgb([255, 0, 0])).save(dir.path().join("one.png")).unwrap();
    let obj = format!("mtllib m.mtl\n{TRIANGLE}vt 0 0\nusemtl t\nf 1/1 2/1 3/1\n");
    let options =
        ["-s 1 1 1 -o 0 0 0", "-o 0.5", "-s 1 1 -clamp on", "-blendu off -blendv off -mm 0 1 -texres 512", "-t 0 0 0"];
    for opts in options {
        std::fs::write(dir.path().join("t.obj"), &obj).unwrap();
        std::fs::write(dir.path().join("m.mtl"), format!("newmtl t\nmap_Kd {opts} one.png\n")).unwrap();
        let scene = load(&dir.path().join("t.obj")).unwrap_or_else(|e| panic!("{opts}: {e}"));
        assert_eq!(scene.textures.len(), 1, "{opts}");
        assert!(material(&scene, "t").texture.is_some(), "{opts}");
    }
    for bad in ["-s 1 1 1", "-bogus 1 one.png", "-mm 1 one.png", ""] {
        std::fs::write(dir.path().join("m.mtl"), format!("newmtl t\nmap_Kd {bad}\n")).unwrap();
        let (path, at, message) = parse_error(load(&dir.path().join("t.obj")));
        assert_eq!((path, at), (dir.path().join("m.mtl"), Some(2)), "{bad}: {message}");
    }
}

#[test]
fn duplicate_faces_are_dropped_with_one_warning() {
    // Faces 2 and 3 repeat face 1 (3 rotated); face 4 is face 1 reversed (the other side),
    // face 5 another triangle: both kept. The second group's copy of face 1 is its own.
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ng a\nf 1 2 3\nf 1 2 3\nf 2 3 1\nf 1 3 2\nf 2 4 3\n\
               g b\nf 1 2 3\n";
    let dir = folder(&[("dup.obj", obj)]);
    let scene = load(&dir.path().join("dup.obj")).unwrap();
    assert_eq!(scene.triangle_count(), 4);
    let warnings: Vec<_> = scene.warnings.iter().filter(|w| w.contains("duplicate")).collect();
    assert_eq!(warnings.len(), 1, "{:?}", scene.warnings);
    assert!(warnings[0].contains("dup.obj") && warnings[0].contains("2 duplicate faces"), "{}", warnings[0]);
}
