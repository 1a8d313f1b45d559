//! Parts, merge and checkpoints through the command line, and the Slurm flow through a real
//! (local) cluster: `.ci/slurm-cluster.sh` starts one and exports `RAYSCOPE_SLURM`; without
//! it the cluster test skips with a NOTICE.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use common::{rayscope, stderr};

const SCENE: [&str; 6] = ["render", "cornell-box-motion", "--light-samples", "2", "--gloss-samples", "2"];

fn run(dir: &Path, args: &[&str]) {
    let o = rayscope(dir, args);
    assert!(o.status.success(), "rayscope {args:?}: {}", stderr(&o));
}

fn with(extra: &[&str]) -> Vec<String> {
    SCENE.iter().chain(extra).map(|s| s.to_string()).collect()
}

fn run_with(dir: &Path, extra: &[&str]) {
    let args = with(extra);
    run(dir, &args.iter().map(String::as_str).collect::<Vec<_>>());
}

#[test]
fn merged_parts_equal_the_single_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let size = ["--width", "40", "--height", "30", "--spp", "8"];
    run_with(d, &[&size[..], &["-o", "one.pfm"]].concat());
    run_with(d, &[&size[..], &["-o", "one.png"]].concat());
    for split in ["samples", "tiles"] {
        for k in 0..3 {
            let part = format!("{k}/3");
            let out = format!("{split}{k}.exr");
            run_with(d, &[&size[..], &["--part", &part, "--split", split, "-o", &out]].concat());
        }
        let parts: Vec<String> = (0..3).rev().map(|k| format!("{split}{k}.exr")).collect();
        for out in ["merged.pfm", "merged.png"] {
            let mut args = vec!["merge"];
            args.extend(parts.iter().map(String::as_str));
            args.extend(["-o", out]);
            run(d, &args);
        }
        assert_eq!(std::fs::read(d.join("merged.pfm")).unwrap(), std::fs::read(d.join("one.pfm")).unwrap(), "{split}");
        assert_eq!(std::fs::read(d.join("merged.png")).unwrap(), std::fs::read(d.join("one.png")).unwrap(), "{split}");
    }
    // Errors name the files and what is wrong.
    let o = rayscope(d, &["merge", "samples0.exr", "samples2.exr", "-o", "x.png"]);
    assert!(!o.status.success() && stderr(&o).contains("missing part 1 of 3"), "{}", stderr(&o));
    let o = rayscope(d, &["merge", "samples0.exr", "samples1.exr", "tiles2.exr", "-o", "x.png"]);
    assert!(stderr(&o).contains("tiles2.exr") && stderr(&o).contains("split by tiles"), "{}", stderr(&o));
    let o = rayscope(d, &["merge", "samples0.exr", "samples1.exr", "one.pfm", "-o", "x.png"]);
    assert!(stderr(&o).contains("one.pfm"), "{}", stderr(&o));
    let o = rayscope(d, &["render", "cornell-box", "--part", "3/3", "-o", "x.exr"]);
    assert!(stderr(&o).contains("--part"), "{}", stderr(&o));
    let o = rayscope(d, &["render", "cornell-box", "--part", "0/3", "-o", "x.png"]);
    assert!(stderr(&o).contains("name it .exr"), "{}", stderr(&o));
}

#[test]
fn a_killed_checkpointing_render_resumes_to_the_same_bits() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let render = |extra: &[&str]| {
        let mut a = Vec::new();
        a.extend(with(&["--spp", "1", "--target-spp", "64", "--width", "96", "--height", "72", "--progressive"]));
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let whole = render(&["-o", "whole.pfm"]);
    run(d, &whole.iter().map(String::as_str).collect::<Vec<_>>());
    let checkpointing = |out: &str| {
        let mut a = render(&["--checkpoint", "ck.exr", "--checkpoint-every", "0.01", "-o", out]);
        if d.join("ck.exr").exists() {
            a.extend(["--resume".to_string(), "ck.exr".to_string()]);
        }
        a
    };
    // kill -9 at moments spread over the render: the checkpoint is always a whole file.
    let mut seed = 0x9e37_79b9u64;
    for round in 0..4 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_rayscope"))
            .args(checkpointing("part.pfm"))
            .current_dir(d)
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        std::thread::sleep(Duration::from_millis(30 + (seed >> 33) % 200));
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
        if d.join("ck.exr").exists() {
            // Read whole: merge refuses it as a checkpoint, not as a broken file.
            let o = rayscope(d, &["merge", "ck.exr", "-o", "x.png"]);
            assert!(stderr(&o).contains("a checkpoint, not a part"), "round {round}: {}", stderr(&o));
        }
    }
    let resumed = checkpointing("resumed.pfm");
    run(d, &resumed.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(std::fs::read(d.join("resumed.pfm")).unwrap(), std::fs::read(d.join("whole.pfm")).unwrap());
    // Another render's checkpoint is refused, naming what differs.
    let mut other = checkpointing("other.pfm");
    let at = other.iter().position(|a| a == "--light-samples").unwrap();
    other[at + 1] = "3".into();
    let o = rayscope(d, &other.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(stderr(&o).contains("light_samples (2 against 3)"), "{}", stderr(&o));
}

#[test]
fn slurm_renders_merges_reports_and_resumes() {
    let (Some(_), Ok(assets)) = (std::env::var_os("RAYSCOPE_SLURM"), std::env::var("RAYSCOPE_ASSETS")) else {
        eprintln!(
            "NOTICE: no local Slurm cluster (RAYSCOPE_SLURM, from .ci/slurm-cluster.sh) or no RAYSCOPE_ASSETS: skipped"
        );
        return;
    };
    let scene = format!("{assets}/CornellBox-Mirror-Rotated.obj");
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let opts = [scene.as_str(), "--width", "48", "--height", "48", "--spp", "4", "--light-samples", "2"];
    let cmd = |extra: &[&str]| {
        let mut a = vec!["slurm"];
        a.extend(opts);
        a.extend(["--parts", "4", "-o", "out.pfm", "--wait-timeout", "120"]);
        a.extend(extra);
        Command::new(env!("CARGO_BIN_EXE_rayscope")).args(&a).current_dir(d).output().unwrap()
    };
    let mut single = vec!["render"];
    single.extend(opts);
    single.extend(["-o", "single.pfm"]);
    run(d, &single);
    // Part 2 cannot be written (a folder is in its place): its task fails and is reported.
    std::fs::create_dir_all(d.join("out.pfm.parts/part-2.exr")).unwrap();
    let o = cmd(&["--submit"]);
    assert!(!o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("1 part of 4 failed: 2 (FAILED"), "{}", stderr(&o));
    assert!(!d.join("out.pfm").exists());
    std::fs::remove_dir(d.join("out.pfm.parts/part-2.exr")).unwrap();
    let o = cmd(&["--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resubmitting 1 part of 4: 2"), "{}", stderr(&o));
    assert_eq!(std::fs::read(d.join("out.pfm")).unwrap(), std::fs::read(d.join("single.pfm")).unwrap());
    // A killed task: a job holding the whole node keeps the array's tasks waiting while task 1
    // is killed (`scancel`); the kill is reported by index and --resume completes the render.
    let blocker = Command::new("sbatch")
        .args(["--parsable", "--exclusive", "--job-name=blocker", "--wrap", "sleep 120"])
        .output()
        .unwrap();
    assert!(blocker.status.success(), "{}", String::from_utf8_lossy(&blocker.stderr));
    let blocker = String::from_utf8_lossy(&blocker.stdout).trim().split(';').next().unwrap().to_string();
    let mut args = vec!["slurm"];
    args.extend(opts);
    args.extend(["--parts", "4", "-o", "killed.pfm", "--wait-timeout", "120", "--submit"]);
    let submit =
        Command::new(env!("CARGO_BIN_EXE_rayscope")).args(&args).current_dir(d).stderr(Stdio::piped()).spawn().unwrap();
    let started = std::time::Instant::now();
    let array = loop {
        let q = Command::new("squeue").args(["-h", "-n", "rayscope-parts", "-o", "%F"]).output().unwrap();
        let id = String::from_utf8_lossy(&q.stdout).lines().next().unwrap_or("").trim().to_string();
        if !id.is_empty() {
            break id;
        }
        assert!(started.elapsed().as_secs() < 60, "the array never showed in squeue");
        std::thread::sleep(Duration::from_millis(100));
    };
    for job in [format!("{array}_1"), blocker] {
        assert!(Command::new("scancel").arg(&job).status().unwrap().success(), "scancel {job}");
    }
    let o = submit.wait_with_output().unwrap();
    assert!(!o.status.success(), "{}", stderr(&o));
    // (A task cancelled before it started leaves no record in `scontrol show job`.)
    let report = stderr(&o);
    assert!(
        report.contains("1 part of 4 failed: 1 (CANCELLED")
            || report.contains("1 part of 4 failed: 1 (no record: cancelled before it ran"),
        "{report}"
    );
    assert!(!d.join("killed.pfm").exists());
    let mut args = vec!["slurm"];
    args.extend(opts);
    args.extend(["--parts", "4", "-o", "killed.pfm", "--wait-timeout", "120", "--resume"]);
    let o = rayscope(d, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resubmitting 1 part of 4: 1"), "{}", stderr(&o));
    assert_eq!(std::fs::read(d.join("killed.pfm")).unwrap(), std::fs::read(d.join("single.pfm")).unwrap());
    // A 3-frame animation, one array task per frame: each frame as `render --frame F` makes it.
    let anim = ["cornell-box-motion", "--width", "32", "--height", "32", "--spp", "2"];
    let mut a = vec!["slurm"];
    a.extend(anim);
    a.extend(["--frames", "0..3", "-o", "anim.png", "--submit", "--wait-timeout", "120"]);
    run(d, &a);
    for f in 0..3 {
        let mut r = vec!["render"];
        r.extend(anim);
        let frame = f.to_string();
        r.extend(["--frame", &frame, "-o", "local.png"]);
        run(d, &r);
        let name = |stem: &str| d.join(format!("{stem}_{f:04}.png"));
        assert_eq!(std::fs::read(name("anim")).unwrap(), std::fs::read(name("local")).unwrap(), "frame {f}");
    }
}
