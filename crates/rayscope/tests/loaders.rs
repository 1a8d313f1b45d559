//! Loaders against hostile files (issue 14): whatever a path names and whatever a file holds,
//! loading ends in a scene or an error naming the file (and line), never a panic, a hang or
//! memory exhausted.

use std::path::Path;

use rayscope::Error;
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
        std::fs::write(dir.path().join("fifo.mtl"), "newmtl t\nmap_Kd fifo.png\n").unwrap();
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
        }
        Err(e) => panic!("expected 'too large', got {e}"),
        Ok(_) => panic!("loaded"),
    }
}
