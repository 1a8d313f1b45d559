//! Built-in scenes: they render, do not depend on the thread count, and the generated ones
//! equal the course's files.

mod common;

use std::path::Path;

use common::{assets, builtin_scene};
use rayscope::math::Vec3A;
use rayscope::render::{render, replay_pixel_sum};
use rayscope::scene::{LoadContext, MeshDesc, Scene, SceneDesc, builtin};
use rayscope::settings::RenderSettings;

fn render_with_threads(scene: &Scene, s: &RenderSettings, threads: usize) -> Vec<[f32; 3]> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| render(scene, s, &|_| {})).film.pixels().iter().map(|c| c.to_array()).collect()
}

#[test]
fn every_builtin_renders_the_same_on_1_and_2_threads() {
    let assets = assets("every_builtin_renders_the_same_on_1_and_2_threads");
    let s = RenderSettings { width: 48, height: 40, ..RenderSettings::default() };
    for b in builtin::BUILTINS {
        if b.needs_assets && assets.is_none() {
            continue;
        }
        let scene = builtin_scene(b.name, assets.as_ref());
        let one = render_with_threads(&scene, &s, 1);
        let two = render_with_threads(&scene, &s, 2);
        assert_eq!(one, two, "{}", b.name);
        let lit = one.iter().filter(|p| p.iter().any(|v| *v > 0.0)).count();
        assert!(lit > 20, "{}: only {lit} non-black pixels", b.name);
        assert!(one.iter().flatten().all(|v| v.is_finite()), "{}", b.name);
    }
}

/// Renders trace camera rays of neighbouring pixels as packets; the debugger traces one pixel
/// at a time. Both must give every pixel the same value, bit for bit.
#[test]
fn renders_equal_the_debuggers_pixel_by_pixel_replay() {
    let assets = assets("renders_equal_the_debuggers_pixel_by_pixel_replay");
    // 37 columns: runs of 8 pixels and a shorter one at the end of each row.
    let s = RenderSettings { width: 37, height: 23, spp: 2, ..RenderSettings::default() };
    for b in builtin::BUILTINS {
        if b.needs_assets && assets.is_none() {
            continue;
        }
        let scene = builtin_scene(b.name, assets.as_ref());
        let out = render(&scene, &s, &|_| {});
        let camera = scene.camera_motion();
        for y in 0..s.height {
            for x in 0..s.width {
                let replayed = replay_pixel_sum(&scene, &s, &camera, x, y);
                assert_eq!(out.film.sum(x, y), replayed, "{} pixel ({x}, {y})", b.name);
            }
        }
    }
}

#[test]
fn scenes_needing_files_explain_how_to_find_them() {
    let desc = builtin::scene_desc("dragon").unwrap();
    let ctx = LoadContext { assets: Some("/nonexistent/folder".into()), ..LoadContext::default() };
    let err = Scene::from_desc(&desc, &ctx).unwrap_err().to_string();
    assert!(err.contains("/nonexistent/folder/dragon.obj") && err.contains("RAYSCOPE_ASSETS"), "{err}");
    let err = builtin::scene_desc("nope").unwrap_err().to_string();
    assert!(err.contains("cornell-box"), "{err}");
}

#[test]
fn exported_builtins_load_back_identically() {
    for b in builtin::BUILTINS {
        let desc = builtin::scene_desc(b.name).unwrap();
        let text = desc.to_toml();
        let back = SceneDesc::from_toml(&text, Path::new("export.toml")).unwrap();
        assert_eq!(back, desc, "{}", b.name);
    }
}

/// The triangles of a scene as sorted vertex triples with their material's parameters.
fn triangles(scene: &Scene) -> Vec<(Vec<[i64; 3]>, [i64; 5])> {
    let q = |v: f32| (v * 1e4).round() as i64;
    let mut out: Vec<_> = (0..scene.triangle_count() as u32)
        .map(|p| {
            let mut vs: Vec<[i64; 3]> =
                scene.triangle_vertices(p).unwrap().iter().map(|v: &Vec3A| v.to_array().map(q)).collect();
            vs.sort();
            let m = &scene.materials[scene.material_of(p) as usize];
            (vs, [q(m.kd.x), q(m.kd.y), q(m.ks.x), q(m.shininess), q(m.transparency)])
        })
        .collect();
    out.sort();
    out
}

#[test]
fn generated_scenes_equal_the_course_files() {
    let Some(assets) = assets("generated_scenes_equal_the_course_files") else {
        return;
    };
    let ctx = LoadContext { assets: Some(assets), ..LoadContext::default() };
    for (generated, file, normalize) in
        [(builtin::cornell_box(), "CornellBox-Mirror-Rotated.obj", true), (builtin::cube(), "cube.obj", false)]
    {
        let from_file = MeshDesc { asset: Some(file.into()), normalize, ..MeshDesc::default() };
        let a = Scene::from_desc(&SceneDesc { meshes: vec![generated], ..SceneDesc::default() }, &ctx).unwrap();
        let b = Scene::from_desc(&SceneDesc { meshes: vec![from_file], ..SceneDesc::default() }, &ctx).unwrap();
        assert_eq!(triangles(&a), triangles(&b), "{file}");
    }
}

#[test]
fn cornell_box_is_normalised_as_the_course_did() {
    // SOURCES.md: after normalisation the ceiling is at y = 0.643 and the floor at -0.407.
    let scene = builtin_scene("cornell-box", None);
    let ys: Vec<f32> = scene.meshes[0].positions.iter().map(|p| p.y).collect();
    let (lo, hi) = ys.iter().fold((f32::MAX, f32::MIN), |(a, b), &y| (a.min(y), b.max(y)));
    assert!((hi - 0.643).abs() < 1e-3 && (lo + 0.407).abs() < 1e-3, "{lo} {hi}");
}

#[test]
fn course_meshes_load_with_expected_sizes() {
    let Some(assets) = assets("course_meshes_load_with_expected_sizes") else {
        return;
    };
    for (name, tris) in [("monkey", 968), ("teapot", 15704), ("dragon", 100_000), ("cube-textured", 12)] {
        let scene = builtin_scene(name, Some(&assets));
        assert_eq!(scene.triangle_count(), tris, "{name}");
        if name != "cube-textured" {
            let max = scene.meshes.iter().flat_map(|m| &m.positions).map(|p| p.length()).fold(0.0, f32::max);
            assert!((max - 1.0).abs() < 1e-4, "{name} is normalised to the unit sphere ({max})");
        }
    }
    let teapot = builtin_scene("teapot", Some(&assets));
    assert_eq!(teapot.textures.len(), 1, "map_Kd default.png");
    assert!(teapot.meshes.iter().all(|m| m.normals.len() == m.positions.len()), "smooth normals generated");
}
