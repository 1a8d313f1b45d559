//! `rayscope k8s`: a Kubernetes Indexed Job rendering a scene in parts (`completionMode:
//! Indexed`, the part from `JOB_COMPLETION_INDEX`, the parts on a shared volume) and the Job
//! that merges them, as YAML to apply with `kubectl`.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use rayscope::partial::part::Split;

use crate::SceneArgs;
use crate::slurm::{render_options, shell_quote};

/// `rayscope k8s`'s flags (with every render option, passed on to the parts).
#[derive(Args)]
pub struct K8sArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// The merged image, as the containers see it (on the shared volume).
    #[arg(short, long, value_name = "FILE", default_value = "/parts/out.png")]
    output: PathBuf,
    /// Parts (indexed pods) to split the render into.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536))]
    parts: u32,
    /// How to split: by sample index or by tiles [default: samples].
    #[arg(long, value_enum, value_name = "samples|tiles")]
    split: Option<Split>,
    /// Pods running at once [default: all parts].
    #[arg(long, value_name = "N")]
    parallelism: Option<u32>,
    /// The container image with rayscope (and the scene files) in it.
    #[arg(long, value_name = "IMAGE", default_value = "rayscope:latest")]
    image: String,
    /// The ReadWriteMany PersistentVolumeClaim mounted at /parts for the partial films.
    #[arg(long, value_name = "NAME", default_value = "rayscope-parts")]
    claim: String,
    /// Name of the Jobs (`NAME` renders, `NAME-merge` merges).
    #[arg(long, value_name = "NAME", default_value = "rayscope")]
    name: String,
    /// CPUs per pod.
    #[arg(long, value_name = "N", default_value_t = 1)]
    cpus: u32,
    /// Write the manifest here instead of printing it.
    #[arg(long, value_name = "FILE.yaml")]
    manifest: Option<PathBuf>,
}

const OWN_FLAGS: [(&str, bool); 10] = [
    ("--output", true),
    ("-o", true),
    ("--parts", true),
    ("--split", true),
    ("--parallelism", true),
    ("--image", true),
    ("--claim", true),
    ("--name", true),
    ("--cpus", true),
    ("--manifest", true),
];

pub fn cmd_k8s(args: K8sArgs) -> Result<()> {
    rayscope::output::Format::from_path(&args.output)?;
    let (_, settings) = crate::load(&args.scene)?;
    let n = args.parts;
    let split = args.split.unwrap_or_default();
    let mem = crate::slurm::memory_mb(settings.width, settings.height);
    let render: Vec<String> = render_options(&OWN_FLAGS).iter().map(|a| shell_quote(a)).collect();
    let threads = if args.scene.threads.is_none() { format!(" --threads {}", args.cpus) } else { String::new() };
    // The part is written to a temporary name and renamed by rayscope itself (atomic), so a
    // pod killed mid-write leaves no file that merge could take for a part.
    let render_cmd = format!(
        "rayscope render {}{threads} --quiet --part \"$JOB_COMPLETION_INDEX/{n}\" --split {} -o /parts/part-\"$JOB_COMPLETION_INDEX\".exr",
        render.join(" "),
        split.name()
    );
    let files: Vec<String> = (0..n).map(|k| format!("/parts/part-{k}.exr")).collect();
    let merge_cmd =
        format!("rayscope merge {} -o {}", files.join(" "), shell_quote(&args.output.display().to_string()));
    let yaml_str = |s: &str| format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""));
    // The merge Job waits for every part's file (each appears whole, by rename), so both Jobs
    // can be applied at once.
    let wait = format!(
        "until {}; do sleep 5; done",
        files.iter().map(|f| format!("[ -f {f} ]")).collect::<Vec<_>>().join(" && ")
    );
    let job = |name: &str, indexed: bool, cmd: &str, mem: u64| {
        let indexed = if indexed {
            format!(
                "  completionMode: Indexed\n  completions: {n}\n  parallelism: {}\n  backoffLimitPerIndex: 2\n  maxFailedIndexes: {n}\n",
                args.parallelism.unwrap_or(n).clamp(1, n)
            )
        } else {
            "  backoffLimit: 2\n".to_string()
        };
        format!(
            "apiVersion: batch/v1\nkind: Job\nmetadata:\n  name: {name}\nspec:\n{indexed}  template:\n    spec:\n      restartPolicy: Never\n{}      containers:\n      - name: rayscope\n        image: {}\n        command: [\"/bin/sh\", \"-c\", {}]\n        resources:\n          requests: {{cpu: \"{}\", memory: \"{mem}Mi\"}}\n          limits: {{memory: \"{mem}Mi\"}}\n        volumeMounts:\n        - {{name: parts, mountPath: /parts}}\n      volumes:\n      - name: parts\n        persistentVolumeClaim: {{claimName: {}}}\n",
            if indexed.contains("Indexed") {
                String::new()
            } else {
                format!(
                    "      initContainers:\n      - name: wait-for-parts\n        image: {}\n        command: [\"/bin/sh\", \"-c\", {}]\n        volumeMounts:\n        - {{name: parts, mountPath: /parts}}\n",
                    yaml_str(&args.image),
                    yaml_str(&wait)
                )
            },
            yaml_str(&args.image),
            yaml_str(cmd),
            args.cpus,
            yaml_str(&args.claim)
        )
    };
    let text = format!(
        "# {n} parts of {} rendered by an Indexed Job; {name}-merge waits for every part, then merges.\n\
         #   kubectl apply -f THIS.yaml && kubectl wait --for=condition=complete job/{name}-merge --timeout=24h\n\
         # Failed indexes: kubectl get job {name} -o jsonpath='{{.status.failedIndexes}}'\n{}---\n{}",
        args.scene.scene,
        job(&args.name, true, &render_cmd, mem),
        job(&format!("{}-merge", args.name), false, &merge_cmd, mem),
        name = args.name
    );
    match &args.manifest {
        Some(path) => rayscope::output::write_file(path, |w| std::io::Write::write_all(w, text.as_bytes()))?,
        None => print!("{text}"),
    }
    Ok(())
}
