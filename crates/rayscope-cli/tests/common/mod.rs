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
