//! The binary's resource limits (issue 14): the largest file it reads (`--max-file-bytes`)
//! and meshes that need more memory than the process may have.

use std::path::Path;
use std::process::{Command, Output};

fn rayscope(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rayscope"))
        .args(args)
        .current_dir(dir)
        .env_remove("RAYSCOPE_ASSETS")
        .env_remove("RAYSCOPE_MAX_FILE_BYTES")
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

#[test]
fn max_file_bytes_bounds_every_command_that_loads_a_scene() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("t.obj"), TRIANGLE).unwrap();
    let size = TRIANGLE.len().to_string();
    let under = (TRIANGLE.len() - 1).to_string();
    for command in
        [&["render", "t.obj", "--width", "8", "-o", "t.png"][..], &["debug", "t.obj", "--width", "8", "--pixel", "4,4"]]
    {
        let o = rayscope(dir.path(), &[command, &["--max-file-bytes", &under]].concat());
        let err = stderr(&o);
        assert!(!o.status.success(), "{command:?}");
        for needle in ["t.obj", &format!("limit of {under} bytes"), "--max-file-bytes", "RAYSCOPE_MAX_FILE_BYTES"] {
            assert!(err.contains(needle), "{command:?}: expected '{needle}' in {err}");
        }
        let o = rayscope(dir.path(), &[command, &["--max-file-bytes", &size]].concat());
        assert!(o.status.success(), "{command:?}: {}", stderr(&o));
    }
    // The largest limit there is: no overflow one byte past it.
    let o = rayscope(
        dir.path(),
        &["render", "t.obj", "--width", "8", "-o", "t.png", "--max-file-bytes", &u64::MAX.to_string()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for bad in ["0", "-1", "1GiB"] {
        let o = rayscope(dir.path(), &["render", "t.obj", "-o", "t.png", &format!("--max-file-bytes={bad}")]);
        assert!(!o.status.success() && stderr(&o).contains("--max-file-bytes"), "{bad}: {}", stderr(&o));
    }
}

/// An OBJ grid of `k` x `k` quads (2 k² distinct triangles) or, `same`, `2 k²` copies of
/// one triangle; written in one string (tens of MB for a million triangles).
fn big_obj(path: &Path, k: usize, same: bool) {
    use std::fmt::Write;
    let mut text = String::with_capacity(40 * k * k);
    if same {
        text.push_str("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
        text.push_str(&"f 1 2 3\n".repeat(2 * k * k));
    } else {
        for j in 0..=k {
            for i in 0..=k {
                writeln!(text, "v {i} {j} {}", (i * j) % 7).unwrap();
            }
        }
        for j in 0..k {
            for i in 0..k {
                let a = j * (k + 1) + i + 1;
                let (b, c, d) = (a + 1, a + k + 1, a + k + 2);
                writeln!(text, "f {a} {b} {d}\nf {a} {d} {c}").unwrap();
            }
        }
    }
    std::fs::write(path, text).unwrap();
}

/// Render `obj` (in `dir`) at 32 x 32 under an address-space limit of `kib` KiB (`ulimit -v`),
/// on two threads (each thread's stack and malloc arena take address space).
fn render_within(dir: &Path, obj: &str, kib: u64) -> Output {
    let bin = env!("CARGO_BIN_EXE_rayscope");
    let script = format!("ulimit -v {kib} && exec \"{bin}\" render {obj} --width 32 --threads 2 -o out.png");
    Command::new("sh")
        .args(["-c", &script])
        .current_dir(dir)
        .env("RAYON_NUM_THREADS", "2")
        .env_remove("RAYSCOPE_MAX_FILE_BYTES")
        .output()
        .unwrap()
}

#[test]
fn a_million_triangles_load_and_render_in_700_mb_of_address_space() {
    let dir = tempfile::tempdir().unwrap();
    big_obj(&dir.path().join("grid.obj"), 707, false);
    // The BVH build reserved room for two nodes per triangle at every parallel level (the
    // address space peaked at 880 MB where 320 MB are used).
    let o = render_within(dir.path(), "grid.obj", 700_000);
    assert!(o.status.success(), "{:?}: {}", o.status, stderr(&o));
    let out = stderr(&o);
    assert!(out.contains("999698 triangles"), "{out}");
}

#[test]
fn a_mesh_that_cannot_fit_is_an_error_naming_its_size_not_an_abort() {
    let dir = tempfile::tempdir().unwrap();
    big_obj(&dir.path().join("grid.obj"), 707, false);
    big_obj(&dir.path().join("same.obj"), 707, true);
    for obj in ["grid.obj", "same.obj"] {
        // Room for the program, not for the mesh (about 300 MB).
        let o = render_within(dir.path(), obj, 150_000);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{obj}: {err}");
        for needle in [obj, "999698 triangles", "MB of memory", "ulimit -v"] {
            assert!(err.contains(needle), "{obj}: expected '{needle}' in {err}");
        }
    }
}
