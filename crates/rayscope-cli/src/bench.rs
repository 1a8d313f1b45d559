//! `rayscope bench`: the course report's performance table, measured on this machine.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use rayscope::render::render_reusing;
use rayscope::scene::{Geometry, Scene};
use rayscope::settings::RenderSettings;

use crate::counted;
use serde::Serialize;

/// One row of the table: a scene and the settings the course measured it with.
pub struct RowSpec {
    /// Label in the table.
    pub label: &'static str,
    /// Built-in scene.
    pub scene: &'static str,
    /// Settings on top of the defaults (800x800).
    pub settings: fn(RenderSettings) -> RenderSettings,
    /// The course report's figure, in ms, on its students' hardware ([`NOT_IN_REPORT`] for
    /// rows the report did not measure).
    pub report_ms: f64,
}

/// [`RowSpec::report_ms`] of a row the course report did not measure (a later feature's cost):
/// shown as `–`, and `null` in JSON.
pub const NOT_IN_REPORT: f64 = f64::NAN;

/// The rows of the course report's table, in its order.
pub const ROWS: &[RowSpec] = &[
    RowSpec { label: "single triangle", scene: "single-triangle", settings: |s| s, report_ms: 9.0 },
    RowSpec { label: "cube", scene: "cube", settings: |s| s, report_ms: 20.0 },
    RowSpec { label: "Cornell box (point light)", scene: "cornell-box", settings: |s| s, report_ms: 40.0 },
    RowSpec {
        label: "Cornell box (sphere light)",
        scene: "cornell-box-sphere-light",
        settings: |s| s,
        report_ms: 66.0,
    },
    RowSpec { label: "monkey", scene: "monkey", settings: |s| s, report_ms: 65.0 },
    RowSpec { label: "dragon", scene: "dragon", settings: |s| s, report_ms: 55.0 },
    RowSpec { label: "teapot", scene: "teapot", settings: |s| s, report_ms: 96.0 },
    RowSpec {
        label: "dragon, interpolated normals",
        scene: "dragon",
        settings: |s| RenderSettings { interpolate_normals: true, ..s },
        report_ms: 55.0,
    },
    RowSpec {
        label: "Cornell box (sphere light), 50 shadow rays",
        scene: "cornell-box-sphere-light",
        settings: |s| RenderSettings { light_samples: 50, ..s },
        report_ms: 1250.0,
    },
    RowSpec {
        label: "  + 10 anti-aliasing rays",
        scene: "cornell-box-sphere-light",
        settings: |s| RenderSettings { light_samples: 50, spp: 10, ..s },
        report_ms: 13500.0,
    },
    RowSpec {
        label: "  + 50 glossy rays (no AA)",
        scene: "cornell-box-sphere-light",
        settings: |s| RenderSettings { light_samples: 50, gloss_samples: 50, ..s },
        report_ms: 6300.0,
    },
    // Not in the course's table: the Cornell box at 16 samples, then the same with a sphere
    // moving on a keyframed Catmull-Rom loop (blurred over the shutter), and through a thin
    // lens (depth of field: camera rays no longer share an origin, so they are traced one by
    // one instead of in packets).
    RowSpec {
        label: "Cornell box, 16 spp",
        scene: "cornell-box",
        settings: |s| RenderSettings { spp: 16, ..s },
        report_ms: NOT_IN_REPORT,
    },
    RowSpec {
        label: "  + a sphere on a keyframed path (motion blur)",
        scene: "cornell-box-motion",
        settings: |s| RenderSettings { spp: 16, ..s },
        report_ms: NOT_IN_REPORT,
    },
    RowSpec {
        label: "  + depth of field (aperture 0.05)",
        scene: "cornell-box",
        settings: |s| RenderSettings { spp: 16, aperture: 0.05, ..s },
        report_ms: NOT_IN_REPORT,
    },
];

/// A row's course figure as the table and the CSV show it.
fn report_figure(ms: f64) -> String {
    if ms.is_nan() { "–".into() } else { ms.to_string() }
}

/// A measured row.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Row label.
    pub scene: String,
    /// Built-in scene name.
    pub builtin: String,
    /// Triangles in the scene.
    pub triangles: usize,
    /// Fastest BVH build, ms.
    pub build_ms: f64,
    /// BVH levels.
    pub levels: usize,
    /// Fastest render, ms.
    pub render_ms: f64,
    /// All rays (camera, shadow, reflection) per second in the fastest render, millions.
    pub mrays_per_s: f64,
    /// Rays per render.
    pub rays: u64,
    /// The course report's figure (its hardware), ms.
    pub report_ms: f64,
    /// Why the row was not measured, if it was not.
    pub skipped: Option<String>,
}

/// The machine, for the record.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// CPU model.
    pub cpu: String,
    /// Logical cores available.
    pub cores: usize,
    /// Threads the bench used.
    pub threads: usize,
    /// Operating system.
    pub os: String,
    /// Image size.
    pub resolution: String,
    /// Renders per row (after warm-up).
    pub repetitions: usize,
    /// Warm-up renders per row.
    pub warmup: usize,
    /// The BVH traversal's instruction set and the wide BVH's width (chosen at run time).
    pub simd: String,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Where it ran.
    pub machine: Machine,
    /// The rows.
    pub rows: Vec<Row>,
    /// The split rules' rows (`crate::bench_split`).
    pub split_rules: Vec<crate::bench_split::SplitRuleRow>,
}

fn machine(threads: usize, repetitions: usize, warmup: usize) -> Machine {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let os = std::fs::read_to_string("/etc/os-release")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("PRETTY_NAME=")).map(|l| l[12..].trim_matches('"').to_string()))
        .unwrap_or_else(|| std::env::consts::OS.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let simd = format!("{:?}, {}-wide BVH", rayscope::bvh::SimdLevel::detect(), rayscope::bvh::WideTree::best_width());
    Machine { cpu, cores, threads, os, resolution: "800x800".into(), repetitions, warmup, simd }
}

/// Run the table. `progress` prints a line per step.
pub fn run(assets: Option<&Path>, repetitions: usize, warmup: usize, threads: usize) -> Result<Report> {
    let mut rows = Vec::new();
    let mut loaded: Option<(String, Scene)> = None;
    for (i, spec) in ROWS.iter().enumerate() {
        eprintln!("bench [{}/{}] {}", i + 1, ROWS.len(), spec.label);
        let needs_assets = rayscope::scene::builtin::BUILTINS.iter().any(|b| b.name == spec.scene && b.needs_assets);
        if loaded.as_ref().is_none_or(|(n, _)| n != spec.scene) {
            match Scene::load(spec.scene, assets) {
                Ok(s) => loaded = Some((spec.scene.to_string(), s)),
                Err(e) if needs_assets => {
                    eprintln!("  skipped: {e}");
                    rows.push(skipped(spec, format!("{e}")));
                    loaded = None;
                    continue;
                }
                Err(e) => return Err(e).context(spec.scene),
            }
        }
        let (_, scene) = loaded.as_ref().expect("loaded above");
        let settings = (spec.settings)(RenderSettings::default());
        let mut build = Duration::MAX;
        let mut best = Duration::MAX;
        let mut rays = 0;
        let prims = scene.prim_refs();
        // Each render after the first writes to the film of the one before, as a viewer's or
        // `render --repeat`'s renders do (warm, like the peers the figures are set beside).
        let mut film = None;
        for k in 0..warmup + repetitions.max(1) {
            let start = Instant::now();
            let g = Geometry::build(&scene.meshes, &scene.spheres, &prims);
            let b = start.elapsed();
            std::hint::black_box(&g);
            let out = render_reusing(scene, &settings, &AtomicBool::new(false), &|_| {}, film);
            film = Some(out.film);
            if k >= warmup {
                build = build.min(b);
                if out.elapsed < best {
                    best = out.elapsed;
                    rays = out.rays.total();
                }
            }
        }
        let render_ms = best.as_secs_f64() * 1e3;
        rows.push(Row {
            scene: spec.label.to_string(),
            builtin: spec.scene.to_string(),
            triangles: scene.triangle_count(),
            build_ms: build.as_secs_f64() * 1e3,
            levels: scene.bvh_stats().levels,
            render_ms,
            mrays_per_s: rays as f64 / best.as_secs_f64() / 1e6,
            rays,
            report_ms: spec.report_ms,
            skipped: None,
        });
        eprintln!("  {render_ms:.1} ms");
    }
    Ok(Report { machine: machine(threads, repetitions, warmup), rows, split_rules: Vec::new() })
}

fn skipped(spec: &RowSpec, why: String) -> Row {
    Row {
        scene: spec.label.to_string(),
        builtin: spec.scene.to_string(),
        triangles: 0,
        build_ms: f64::NAN,
        levels: 0,
        render_ms: f64::NAN,
        mrays_per_s: f64::NAN,
        rays: 0,
        report_ms: spec.report_ms,
        skipped: Some(why),
    }
}

/// The report as a Markdown table.
pub fn markdown(r: &Report) -> String {
    let m = &r.machine;
    let mut s = format!(
        "Machine: {}, {} ({} used), {}; {} traversal; {}, fastest of {} after {}.\n\n",
        m.cpu,
        counted(m.cores as u64, "core", "cores"),
        counted(m.threads as u64, "thread", "threads"),
        m.os,
        m.simd,
        m.resolution,
        counted(m.repetitions as u64, "render", "renders"),
        counted(m.warmup as u64, "warm-up render", "warm-up renders")
    );
    s += "| scene | triangles | BVH build (ms) | BVH levels | render (ms) | Mrays/s | course report (ms, its hardware) |\n";
    s += "|---|---:|---:|---:|---:|---:|---:|\n";
    for row in &r.rows {
        match &row.skipped {
            Some(_) => {
                s += &format!(
                    "| {} | – | – | – | skipped: no scene files | – | {} |\n",
                    row.scene,
                    report_figure(row.report_ms)
                )
            }
            None => {
                s += &format!(
                    "| {} | {} | {:.2} | {} | {:.1} | {:.2} | {} |\n",
                    row.scene,
                    row.triangles,
                    row.build_ms,
                    row.levels,
                    row.render_ms,
                    row.mrays_per_s,
                    report_figure(row.report_ms)
                )
            }
        }
    }
    s
}

/// The report as CSV.
pub fn csv(r: &Report) -> String {
    let mut s = String::from("scene,builtin,triangles,build_ms,levels,render_ms,mrays_per_s,rays,report_ms\n");
    for row in &r.rows {
        s += &format!(
            "\"{}\",{},{},{:.3},{},{:.3},{:.3},{},{}\n",
            row.scene.trim(),
            row.builtin,
            row.triangles,
            row.build_ms,
            row.levels,
            row.render_ms,
            row.mrays_per_s,
            row.rays,
            report_figure(row.report_ms)
        );
    }
    s
}

/// Write `text` to `path` atomically.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    Ok(rayscope::output::write_file(path, |w| w.write_all(text.as_bytes()))?)
}
