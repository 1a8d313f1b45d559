//! `rayscope slurm`: a render split into a Slurm job array (one task per part, each running
//! `rayscope render --part $SLURM_ARRAY_TASK_ID/N`) and a merge job that runs after the whole
//! array succeeded (`--dependency=afterok`). `--submit` submits both and waits, then checks
//! every task's final state and exit code with `scontrol show job` (without accounting,
//! `sacct` knows nothing; `sbatch --wait` does not report a failed array task), reports the
//! failed parts by index, and `--resume` resubmits only the parts whose partial film is
//! missing or not this render's, then merges.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::Args;
use rayscope::animation::{FrameRange, frame_path};
use rayscope::partial::file::read_partial;
use rayscope::partial::part::Split;
use rayscope::partial::{PartialFilm, Portion};

use crate::SceneArgs;

/// `rayscope slurm`'s flags (with every render option, passed on to the parts).
#[derive(Args)]
pub struct SlurmArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// The merged image (.png, .exr, .pfm); the scripts, logs and parts go in OUT.parts/.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Parts (array tasks) to split the render into.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536),
          required_unless_present = "frames", conflicts_with = "frames")]
    parts: Option<u32>,
    /// Render frames A..B (B excluded) or A..=B of the animation instead, one array task per
    /// frame (`render --frame $SLURM_ARRAY_TASK_ID`), to OUT_0001.png...; no merge.
    #[arg(long, value_name = "A..B", value_parser = FrameRange::parse)]
    frames: Option<FrameRange>,
    /// With --frames: frames per second of scene time (passed to each frame's render).
    #[arg(long, value_name = "F")]
    fps: Option<String>,
    /// With --frames: the shutter, a fraction of a frame (passed to each frame's render).
    #[arg(long, value_name = "S")]
    shutter: Option<String>,
    /// How to split: by sample index or by tiles [default: samples].
    #[arg(long, value_enum, value_name = "samples|tiles")]
    split: Option<Split>,
    /// CPUs per task (each part renders on as many threads).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=4096))]
    cpus_per_task: u32,
    /// Memory per task, in MB [default: the scene's measured footprint plus the film's].
    #[arg(long, value_name = "MB")]
    mem: Option<u64>,
    /// Slurm partition (queue) to submit to [default: the cluster's].
    #[arg(long, value_name = "NAME")]
    partition: Option<String>,
    /// Time limit per task, as Slurm takes it (`MM`, `HH:MM:SS`, ...).
    #[arg(long, value_name = "TIME")]
    time: Option<String>,
    /// Submit the array and the merge job, wait for them, check every task, report failures.
    #[arg(long)]
    submit: bool,
    /// Submit only the parts whose partial film is missing or not this render's (after a
    /// failure), then the merge; implies --submit.
    #[arg(long)]
    resume: bool,
    /// With --submit: give up waiting after this many seconds [default: no limit].
    #[arg(long, value_name = "SECONDS")]
    wait_timeout: Option<f64>,
}

/// The flags of `slurm` that are not `render`'s, with whether each takes a value: what is
/// left of the command line is passed to every part's `rayscope render`.
const OWN_FLAGS: [(&str, bool); 12] = [
    ("--frames", true),
    ("--output", true),
    ("-o", true),
    ("--parts", true),
    ("--split", true),
    ("--cpus-per-task", true),
    ("--mem", true),
    ("--partition", true),
    ("--time", true),
    ("--submit", false),
    ("--resume", false),
    ("--wait-timeout", true),
];

/// The render options of the command line: its arguments after `slurm` (or `k8s`) without
/// the flags of `own`.
pub fn render_options(own: &[(&str, bool)]) -> Vec<String> {
    let args: Vec<String> = std::env::args().collect();
    let start = args.iter().position(|a| a == "slurm" || a == "k8s").map_or(args.len(), |i| i + 1);
    let mut out = Vec::new();
    let mut i = start;
    while i < args.len() {
        let a = &args[i];
        let name = a.split_once('=').map_or(a.as_str(), |(n, _)| n);
        match own.iter().find(|(f, _)| *f == name) {
            Some((_, takes)) => i += if *takes && !a.contains('=') { 2 } else { 1 },
            None => {
                out.push(a.clone());
                i += 1;
            }
        }
    }
    out
}

/// `s` quoted for a POSIX shell.
pub fn shell_quote(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c)) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// Where one render's parts go: `OUT.parts/part-K.exr`.
pub fn part_path(dir: &Path, k: u32) -> PathBuf {
    dir.join(format!("part-{k}.exr"))
}

/// Megabytes a part needs: this process's peak memory after loading the scene (its
/// measured footprint), the film and the partial film's copies, and a quarter more.
pub fn memory_mb(width: u32, height: u32) -> u64 {
    let peak_kb = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .unwrap_or(256 << 10);
    // The film (28 B), its preview and the EXR's channels (40 B), the writer's buffers (40 B).
    let film = u64::from(width) * u64::from(height) * 108;
    ((peak_kb * 1024 + film) * 5 / 4).div_ceil(1 << 20).max(256)
}

pub fn cmd_slurm(args: SlurmArgs) -> Result<ExitCode> {
    rayscope::output::Format::from_path(&args.output)?;
    let (_, settings) = crate::load(&args.scene)?;
    let fingerprint = crate::parts::fingerprint(&args.scene, &settings)?;
    let exe = std::env::current_exe().context("finding this rayscope's path for the job scripts")?;
    let cwd = std::env::current_dir().context("the working directory")?;
    let output = cwd.join(&args.output);
    let dir = PathBuf::from(format!("{}.parts", output.display()));
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: creating the parts' folder", dir.display()))?;
    let split = args.split.unwrap_or_default();
    // The array's indices: parts 0..N, or the frames.
    let (first, n) = match (args.parts, args.frames) {
        (_, Some(f)) => (f.start, f.end - f.start),
        (Some(n), None) => (0, n),
        (None, None) => bail!("give --parts N or --frames A..B"),
    };
    let frames = args.frames.is_some();
    let mem = args.mem.unwrap_or_else(|| memory_mb(settings.width, settings.height));
    let mut render = render_options(&OWN_FLAGS);
    if args.scene.threads.is_none() {
        render.push("--threads".into());
        render.push("$SLURM_CPUS_PER_TASK".into());
    }
    let quoted: Vec<String> =
        render.iter().map(|a| if a.starts_with('$') { format!("\"{a}\"") } else { shell_quote(a) }).collect();
    let q = |p: &Path| shell_quote(&p.display().to_string());
    let mut head = format!(
        "#!/bin/sh\n#SBATCH --job-name=rayscope-parts\n#SBATCH --cpus-per-task={}\n#SBATCH --mem={mem}M\n#SBATCH --chdir={}\n",
        args.cpus_per_task,
        q(&cwd)
    );
    if let Some(p) = &args.partition {
        head += &format!("#SBATCH --partition={}\n", shell_quote(p));
    }
    if let Some(t) = &args.time {
        head += &format!("#SBATCH --time={}\n", shell_quote(t));
    }
    let task = if frames {
        format!("--frame \"$SLURM_ARRAY_TASK_ID\" -o {}", q(&output))
    } else {
        format!(
            "--part \"$SLURM_ARRAY_TASK_ID/{n}\" --split {} -o {}/part-\"$SLURM_ARRAY_TASK_ID\".exr",
            split.name(),
            q(&dir)
        )
    };
    let render_script = format!(
        "{head}#SBATCH --array={first}-{}\n#SBATCH --output={}/task-%a.log\n# Task $SLURM_ARRAY_TASK_ID: its file is written atomically, so a killed task leaves none.\nexec {} render {} --quiet {task}\n",
        first + n - 1,
        q(&dir),
        q(&exe),
        quoted.join(" "),
    );
    let files: Vec<String> = (0..n).map(|k| q(&part_path(&dir, k))).collect();
    let merge_script = format!(
        "#!/bin/sh\n#SBATCH --job-name=rayscope-merge\n#SBATCH --chdir={}\n#SBATCH --output={}/merge.log\n#SBATCH --mem={}M\nexec {} merge {} -o {}\n",
        q(&cwd),
        q(&dir),
        (u64::from(settings.width) * u64::from(settings.height) * 200).div_ceil(1 << 20).max(256),
        q(&exe),
        files.join(" "),
        q(&output)
    );
    let render_path = dir.join("render.sbatch");
    let merge_path = dir.join("merge.sbatch");
    for (path, text) in [(&render_path, &render_script), (&merge_path, &merge_script)] {
        rayscope::output::write_file(path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
    }
    if !(args.submit || args.resume) {
        if frames {
            println!("{}", render_path.display());
            eprintln!("wrote the job array of {n} frames; submit it with sbatch {}", render_path.display());
            return Ok(ExitCode::SUCCESS);
        }
        println!("{}", render_path.display());
        println!("{}", merge_path.display());
        eprintln!(
            "wrote the job array of {n} parts and the merge job; submit them with\n  \
             array=$(sbatch --parsable {})\n  sbatch --dependency=afterok:$array {}\n(or run `rayscope slurm` again with --submit)",
            render_path.display(),
            merge_path.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let done = |k: u32| {
        if frames { frame_path(&output, k).is_file() } else { is_part(&part_path(&dir, k), &fingerprint, k, n, split) }
    };
    let what = if frames { "frame" } else { "part" };
    let todo: Vec<u32> = (first..first + n).filter(|&k| !args.resume || !done(k)).collect();
    let start = Instant::now();
    let deadline = args.wait_timeout.map(|s| start + Duration::from_secs_f64(s.max(0.0)));
    if !todo.is_empty() {
        let indices: Vec<String> = todo.iter().map(u32::to_string).collect();
        if args.resume {
            eprintln!("resubmitting {} of {n}: {}", counted(what, todo.len()), indices.join(","));
        }
        let array = sbatch(&[&format!("--array={}", indices.join(",")), &render_path.display().to_string()])?;
        eprintln!("submitted job array {array} ({})", counted(what, todo.len()));
        let states = wait_for(&array, deadline)?;
        let failed: Vec<String> = todo
            .iter()
            .filter(|k| !states.iter().any(|t| t.index == Some(**k) && t.state == "COMPLETED" && t.exit_code == "0:0"))
            .map(|k| {
                let t = states.iter().find(|t| t.index == Some(*k));
                format!(
                    "{k} ({})",
                    t.map_or("no record: cancelled before it ran, or purged".to_string(), |t| format!(
                        "{}, exit code {}",
                        t.state, t.exit_code
                    ))
                )
            })
            .collect();
        if !failed.is_empty() {
            eprintln!(
                "error: {} of {n} failed: {}\nsee {}/task-K.log; rerun with --resume to resubmit only them",
                counted(what, failed.len()),
                failed.join(", "),
                dir.display()
            );
            return Ok(ExitCode::FAILURE);
        }
    }
    if frames {
        eprintln!(
            "rendered {n} frames -> {} ... in {:.1} s",
            frame_path(&output, first).display(),
            start.elapsed().as_secs_f64()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let merge = sbatch(&[&merge_path.display().to_string()])?;
    let states = wait_for(&merge, deadline)?;
    match states.first() {
        Some(t) if t.state == "COMPLETED" && t.exit_code == "0:0" => {
            eprintln!("merged {n} parts -> {} in {:.1} s", output.display(), start.elapsed().as_secs_f64());
            Ok(ExitCode::SUCCESS)
        }
        t => bail!(
            "the merge job {merge} failed ({}); see {}/merge.log",
            t.map_or("no record: cancelled before it ran, or purged".to_string(), |t| format!(
                "{}, exit code {}",
                t.state, t.exit_code
            )),
            dir.display()
        ),
    }
}

fn counted(what: &str, n: usize) -> String {
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}

/// Whether `path` holds part `k` of `n` of this render.
fn is_part(
    path: &Path,
    fingerprint: &rayscope::partial::fingerprint::Fingerprint,
    k: u32,
    n: u32,
    split: Split,
) -> bool {
    match read_partial(path) {
        Ok(PartialFilm { fingerprint: f, portion: Portion::Part(p), .. }) => {
            f.differences(fingerprint).is_empty() && (p.index, p.count, p.split) == (k, n, split)
        }
        _ => false,
    }
}

/// Submit with `sbatch --parsable ARGS`, returning the job id.
fn sbatch(args: &[&str]) -> Result<String> {
    let out =
        Command::new("sbatch").arg("--parsable").args(args).output().context("running sbatch (is Slurm installed?)")?;
    if !out.status.success() {
        bail!("sbatch {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim());
    }
    let text = String::from_utf8_lossy(&out.stdout);
    // `--parsable` prints `id` or `id;cluster`.
    Ok(text.trim().split(';').next().unwrap_or("").to_string())
}

/// One job or array task's record in `scontrol show job`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TaskState {
    /// The array task's index (`None` for a job that is not an array, or a pending range).
    pub index: Option<u32>,
    /// `JobState`: PENDING, RUNNING, COMPLETED, FAILED, CANCELLED, TIMEOUT, ...
    pub state: String,
    /// `ExitCode`, `status:signal`.
    pub exit_code: String,
}

/// The records of `scontrol show job --oneliner` output: one per array task (a pending
/// range of tasks is one record without an index).
pub fn parse_scontrol(text: &str) -> Vec<TaskState> {
    text.lines()
        .filter(|l| l.contains("JobState="))
        .map(|l| {
            let field = |key: &str| {
                l.split_whitespace().find_map(|f| f.strip_prefix(key).map(str::to_string)).unwrap_or_default()
            };
            TaskState {
                index: field("ArrayTaskId=").parse().ok(),
                state: field("JobState="),
                exit_code: field("ExitCode="),
            }
        })
        .collect()
}

/// States that end a job.
fn is_final(state: &str) -> bool {
    !matches!(state, "PENDING" | "RUNNING" | "CONFIGURING" | "COMPLETING" | "SUSPENDED" | "REQUEUED" | "RESIZING")
}

/// Poll `scontrol show job ID` until every task of the job has ended; their records.
fn wait_for(job: &str, deadline: Option<Instant>) -> Result<Vec<TaskState>> {
    let mut pause = Duration::from_millis(100);
    loop {
        let out = Command::new("scontrol")
            .args(["show", "job", "--oneliner", job])
            .output()
            .context("running scontrol (is Slurm installed?)")?;
        if !out.status.success() {
            bail!("scontrol show job {job}: {}", String::from_utf8_lossy(&out.stderr).trim());
        }
        let states = parse_scontrol(&String::from_utf8_lossy(&out.stdout));
        if !states.is_empty() && states.iter().all(|t| is_final(&t.state)) {
            return Ok(states);
        }
        if deadline.is_some_and(|d| Instant::now() >= d) {
            bail!("job {job} still running after --wait-timeout; it goes on (scancel {job} to stop it)");
        }
        std::thread::sleep(pause);
        pause = (pause * 2).min(Duration::from_secs(2));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scontrol_records_are_read() {
        let text = "JobId=12 ArrayJobId=10 ArrayTaskId=2 JobName=x JobState=FAILED Reason=NonZeroExitCode ExitCode=1:0\n\
                    JobId=10 ArrayJobId=10 ArrayTaskId=3-5 JobState=PENDING ExitCode=0:0\n";
        let s = parse_scontrol(text);
        assert_eq!(s[0], TaskState { index: Some(2), state: "FAILED".into(), exit_code: "1:0".into() });
        assert_eq!(s[1].index, None);
        assert!(!is_final(&s[1].state));
    }

    #[test]
    fn quoting() {
        assert_eq!(shell_quote("a.toml"), "a.toml");
        assert_eq!(shell_quote("it's here"), "'it'\\''s here'");
    }
}
