//! BVH build time and closest-hit / any-hit throughput on the dragon (100k triangles).
//!
//! `cargo bench -p rayscope --bench bvh`. Needs the course's scene folder (`RAYSCOPE_ASSETS`
//! or `../shared/scenes`); without it the benchmark says so and does nothing.

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rayscope::bvh::{BuildParams, Bvh};
use rayscope::geometry::Aabb;
use rayscope::ray::Ray;
use rayscope::scene::{LoadContext, Scene, builtin};

fn dragon() -> Option<Scene> {
    let assets = std::env::var_os("RAYSCOPE_ASSETS")
        .map(PathBuf::from)
        .or_else(|| Some(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")))
        .filter(|p| p.join("dragon.obj").is_file());
    let Some(assets) = assets else {
        eprintln!("NOTICE: dragon.obj not found (set RAYSCOPE_ASSETS); skipping the BVH benchmark");
        return None;
    };
    let desc = builtin::scene_desc("dragon").unwrap();
    Some(Scene::from_desc(&desc, &LoadContext { assets: Some(assets), ..LoadContext::default() }).unwrap())
}

fn bench(c: &mut Criterion) {
    let Some(scene) = dragon() else { return };
    let bounds: Vec<Aabb> = scene.geometry.shapes().map(|s| s.bounds()).collect();
    let mut g = c.benchmark_group("dragon");
    g.sample_size(20);
    g.bench_function("build", |b| b.iter(|| Bvh::build(black_box(&bounds), &BuildParams::default())));

    let (w, h) = (800u32, 800u32);
    let cam = scene.camera();
    let rays: Vec<Ray> =
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| cam.pixel_ray(x, y, w, h)).collect();
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("closest_hit_primary_800x800_1thread", |b| {
        b.iter(|| rays.iter().filter(|r| scene.intersect(r).is_some()).count())
    });
    let shadow: Vec<Ray> = rays
        .iter()
        .filter_map(|r| scene.intersect(r).map(|hit| (r, hit)))
        .map(|(r, hit)| {
            let si = scene.surface(r, &hit, &Default::default());
            Ray::spawn_to(si.point, si.geo_normal, rayscope::math::Vec3A::new(-1.0, 1.0, -1.0), 0.0)
        })
        .collect();
    g.throughput(Throughput::Elements(shadow.len() as u64));
    g.bench_function("any_hit_shadow_1thread", |b| b.iter(|| shadow.iter().filter(|r| scene.occluded(r)).count()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
