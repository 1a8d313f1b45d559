//! `rayscope bench`'s split-rule rows: the dragon's and the teapot's BVH built with the course
//! seed's rule (the mean of the boxes' lower bounds along the longest axis), a median split and
//! our binned SAH, each with its build time, size, SAH cost and the render time it gives.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Result;
use rayscope::bvh::{BuildParams, SplitRule};
use rayscope::render::render;
use rayscope::scene::{Geometry, Scene};
use rayscope::settings::RenderSettings;
use serde::Serialize;

/// The scenes whose trees are compared.
pub const SCENES: [&str; 2] = ["dragon", "teapot"];

/// One scene built with one split rule.
#[derive(Clone, Debug, Serialize)]
pub struct SplitRuleRow {
    /// Built-in scene.
    pub scene: String,
    /// The split rule (`sah`, `median`, `seed-mean`).
    pub rule: String,
    /// Fastest build of the whole geometry (the binary tree and the wide one collapsed from
    /// it), ms.
    pub build_ms: f64,
    /// Nodes of the binary tree.
    pub nodes: usize,
    /// Its levels.
    pub levels: usize,
    /// Its SAH cost (unit costs, relative to the root's area: `Bvh::stats`).
    pub sah_cost: f32,
    /// Fastest render at 800x800 through the wide tree collapsed from it, ms.
    pub render_ms: f64,
}

/// Measure every rule on every scene of [`SCENES`] that loads (those whose files are missing
/// are left out, with a note on stderr).
pub fn run(assets: Option<&Path>, repetitions: usize, warmup: usize) -> Result<Vec<SplitRuleRow>> {
    let mut rows = Vec::new();
    let settings = RenderSettings::default();
    for name in SCENES {
        let mut scene = match Scene::load(name, assets) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("bench split rules: {name} skipped: {e}");
                continue;
            }
        };
        let prims = scene.prim_refs();
        for rule in SplitRule::ALL {
            eprintln!("bench split rules: {name}, {}", rule.name());
            let params = BuildParams { split_rule: rule, ..BuildParams::default() };
            let (mut build, mut best) = (Duration::MAX, Duration::MAX);
            for k in 0..warmup + repetitions.max(1) {
                let start = Instant::now();
                let g = Geometry::build_with(&scene.meshes, &scene.spheres, &prims, &params);
                let b = start.elapsed();
                let original = std::mem::replace(&mut scene.geometry, g);
                let out = render(&scene, &settings, &|_| {});
                let ours = std::mem::replace(&mut scene.geometry, original);
                if k >= warmup {
                    build = build.min(b);
                    best = best.min(out.elapsed);
                }
                if k + 1 == warmup + repetitions.max(1) {
                    let stats = ours.bvh.stats();
                    rows.push(SplitRuleRow {
                        scene: name.to_string(),
                        rule: rule.name().to_string(),
                        build_ms: build.as_secs_f64() * 1e3,
                        nodes: stats.nodes,
                        levels: stats.levels,
                        sah_cost: stats.sah_cost,
                        render_ms: best.as_secs_f64() * 1e3,
                    });
                }
            }
        }
    }
    Ok(rows)
}

/// The rows as a Markdown table.
pub fn markdown(rows: &[SplitRuleRow]) -> String {
    let mut s = String::from(
        "\nSplit rules (the course seed's mean of lower bounds, a median split, our binned SAH):\n\n\
         | scene | split rule | BVH build (ms) | nodes | levels | SAH cost | render (ms) |\n\
         |---|---|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {:.2} | {} | {} | {:.1} | {:.1} |\n",
            r.scene, r.rule, r.build_ms, r.nodes, r.levels, r.sah_cost, r.render_ms
        );
    }
    s
}
