//! What the CLI's test files share: running the binary.

use std::path::Path;
use std::process::{Command, Output};

/// Run `rayscope` with `args` in `dir`, without the environment's asset folder.
pub fn rayscope(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rayscope"))
        .args(args)
        .current_dir(dir)
        .env_remove("RAYSCOPE_ASSETS")
        .output()
        .unwrap()
}

/// What the process wrote to stderr.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Run `rayscope` with `args` in `dir`, send it Ctrl-C (SIGINT) after `ms` milliseconds, and
/// wait for it to finish.
#[allow(dead_code)] // Not every test file interrupts a render.
pub fn interrupted(dir: &Path, args: &[&str], ms: u64) -> Output {
    let child = Command::new(env!("CARGO_BIN_EXE_rayscope"))
        .args(args)
        .current_dir(dir)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(ms));
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    child.wait_with_output().unwrap()
}
