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
    for bad in ["0", "-1", "1GiB"] {
        let o = rayscope(dir.path(), &["render", "t.obj", "-o", "t.png", &format!("--max-file-bytes={bad}")]);
        assert!(!o.status.success() && stderr(&o).contains("--max-file-bytes"), "{bad}: {}", stderr(&o));
    }
}
