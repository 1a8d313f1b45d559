//! Ray throughput of one kind of query on one thread, robust to a shared machine: the rays
//! are cut into chunks of 2048, each chunk is traced REPS times, and the sum of each chunk's
//! fastest pass gives the rate. Interference from other tenants comes in bursts; a best-of-N
//! over whole passes lets a burst in every pass through, the per-chunk minimum does not.
//! Compare two commits by building this bench at each and running the binaries alternately.
//!
//! RAYSCOPE_ASSETS=../shared/scenes cargo bench -p rayscope --bench rays -- teapot single
//!
//! Arguments: a built-in scene (default `teapot`), the kind of rays (`single`: 800x800
//! camera rays one at a time, `packet`: the same in packets of eight neighbours of a row,
//! `tile`: the same in tiles of eight such packets, a tile's rows (chunks are then bands of
//! eight rows), `shadow`: any-hit rays from each camera hit to a point at (-1, 1, -1), `incoherent`: as many
//! rays from random points of the scene's box in random directions) and REPS (default 30).

use std::time::{Duration, Instant};

mod common;

use rayscope::bvh::TILE_RUNS;
use rayscope::ray::Ray;
use rayscope::scene::{LoadContext, Scene, builtin};

fn main() {
    // `cargo bench` passes `--bench`; the rest are ours.
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let name = args.first().map_or("teapot", String::as_str);
    let kind = args.get(1).map_or("single", String::as_str);
    let reps: usize = args.get(2).map_or(30, |s| s.parse().expect("REPS is a number"));
    let desc = builtin::scene_desc(name).expect("a built-in scene");
    let scene = match Scene::from_desc(&desc, &LoadContext { assets: common::assets(), ..LoadContext::default() }) {
        Ok(scene) => scene,
        Err(e) => {
            eprintln!("NOTICE: {name} did not load ({e}); set RAYSCOPE_ASSETS to the course's scene folder");
            return;
        }
    };
    let camera = common::camera_rays(&scene);
    let rays = match kind {
        "single" | "packet" | "tile" => camera,
        "shadow" => common::shadow_rays(&scene, &camera),
        "incoherent" => common::incoherent_rays(&scene, camera.len()),
        other => panic!("unknown kind of rays {other:?}: single, packet, tile, shadow or incoherent"),
    };
    // A band of a tile's rows holds whole tiles.
    let chunk = if kind == "tile" { 800 * TILE_RUNS } else { 2048 };
    let chunks: Vec<&[Ray]> = rays.chunks(chunk).collect();
    let mut fastest = vec![Duration::MAX; chunks.len()];
    let mut hits = 0;
    for _ in 0..reps {
        hits = 0;
        for (chunk, best) in chunks.iter().zip(fastest.iter_mut()) {
            let start = Instant::now();
            hits += match kind {
                "shadow" => chunk.iter().filter(|r| scene.occluded(r)).count(),
                "packet" => chunk.chunks(8).map(|p| scene.intersect_packet(p).iter().flatten().count()).sum(),
                "tile" => (0..800)
                    .step_by(8)
                    .map(|x0| {
                        let runs: [&[Ray]; TILE_RUNS] = std::array::from_fn(|r| &chunk[800 * r + x0..][..8]);
                        scene.intersect_tile(&runs).iter().flatten().flatten().count()
                    })
                    .sum(),
                _ => chunk.iter().filter(|r| scene.intersect(r).is_some()).count(),
            };
            *best = (*best).min(start.elapsed());
        }
    }
    let total: Duration = fastest.iter().sum();
    println!(
        "{name} {kind}: {:.2} Mrays/s ({hits} of {} hit)",
        rays.len() as f64 / total.as_secs_f64() / 1e6,
        rays.len()
    );
}
