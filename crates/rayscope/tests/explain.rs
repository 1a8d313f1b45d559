//! The debugger's pixel traces: every sample of a pixel replays the renderer bit for bit, the
//! explanation's terms sum to the rendered pixel, skipped light points are reported, and the
//! exported OBJ holds every segment of the trees.

mod common;

use common::{Rng, assets, builtin_scene};
use rayscope::camera::CameraDesc;
use rayscope::debug::{PixelTrace, SampleChoice, trace_pixel_samples, write_rays_obj};
use rayscope::math::{Color, Vec3A};
use rayscope::record::{MAX_RECORDED_RAYS, NoRecorder, SkipReason};
use rayscope::render::{render, trace_pixel};
use rayscope::scene::{Scene, builtin};
use rayscope::settings::{PixelFilter, RenderSettings};

/// The built-in scenes available here (those needing the course's files only with them).
fn scenes(test: &str) -> Vec<(&'static str, Scene)> {
    let assets = assets(test);
    builtin::BUILTINS
        .iter()
        .filter(|b| !b.needs_assets || assets.is_some())
        .map(|b| (b.name, builtin_scene(b.name, assets.as_ref())))
        .collect()
}

/// A scene whose camera moves during the exposure (motion blur): the Cornell box, pulled back.
fn moving_camera() -> Scene {
    let mut scene = builtin_scene("cornell-box", None);
    let CameraDesc::Trackball { look_at, distance, rotation, fov } = scene.camera else {
        panic!("the Cornell box has a trackball camera");
    };
    scene.camera_end = Some(CameraDesc::Trackball { look_at, distance: distance * 1.3, rotation, fov });
    scene
}

fn small(spp: u32) -> RenderSettings {
    RenderSettings { width: 24, height: 20, spp, ..RenderSettings::default() }
}

/// Checks `trace` of pixel `(x, y)` against the render's film and against plain `trace_pixel`.
fn check_replay(name: &str, scene: &Scene, s: &RenderSettings, film: &rayscope::film::Film, x: u32, y: u32) {
    let camera = scene.camera_motion();
    let trace = trace_pixel_samples(scene, s, &camera, x, y, SampleChoice::All, MAX_RECORDED_RAYS);
    assert_eq!(trace.samples.len(), s.spp as usize);
    assert_eq!(trace.value.to_array(), film.get(x, y).to_array(), "{name} ({x}, {y}) {s:?}");
    for sample in &trace.samples {
        let alone = trace_pixel(scene, s, &camera, x, y, sample.index, &mut NoRecorder);
        assert_eq!(sample.color.to_array(), alone.to_array(), "{name} ({x}, {y}) sample {}", sample.index);
        assert_eq!(sample.weight, 1.0 / s.spp as f32);
    }
    let one = trace_pixel_samples(scene, s, &camera, x, y, SampleChoice::One(s.spp - 1), MAX_RECORDED_RAYS);
    assert_eq!(one.samples.len(), 1);
    let (one, all) = (&one.samples[0], trace.samples.last().unwrap());
    assert_eq!((one.index, one.color.to_array(), &one.tree.rays), (all.index, all.color.to_array(), &all.tree.rays));
    assert_eq!(one.weight, 1.0);
}

/// All the samples a pixel trace holds equal the samples rendered: its value is the film's,
/// bit for bit, at 1, 4 and 9 samples, with soft shadows, glossy reflections, a tent filter
/// and a moving camera.
#[test]
fn every_sample_replays_the_film_bit_for_bit() {
    let mut rng = Rng(15);
    let variants = [
        small(1),
        small(4),
        RenderSettings { light_samples: 4, gloss_samples: 3, ..small(9) },
        RenderSettings { filter: PixelFilter::Tent, light_samples: 2, ..small(4) },
    ];
    let mut cases: Vec<(&str, Scene)> = scenes("every_sample_replays_the_film_bit_for_bit");
    cases.push(("cornell-box, moving camera", moving_camera()));
    for (name, scene) in &cases {
        for s in &variants {
            let film = render(scene, s, &|_| {}).film;
            for _ in 0..4 {
                let x = (rng.f32() * s.width as f32) as u32;
                let y = (rng.f32() * s.height as f32) as u32;
                check_replay(name, scene, s, &film, x, y);
            }
        }
    }
}

/// Random settings drawn over everything that changes the integrator's sum.
fn random_settings(rng: &mut Rng) -> RenderSettings {
    let pick = |rng: &mut Rng, n: u32| (rng.f32() * n as f32) as u32;
    RenderSettings {
        width: 16,
        height: 14,
        spp: 1 + pick(rng, 5),
        light_samples: [0, 1, 3, 4][pick(rng, 4) as usize],
        gloss_samples: [0, 0, 2, 5][pick(rng, 4) as usize],
        shadows: rng.f32() < 0.8,
        reflections: rng.f32() < 0.8,
        transparency: rng.f32() < 0.8,
        shading: rng.f32() < 0.85,
        max_depth: pick(rng, 7),
        interpolate_normals: rng.f32() < 0.5,
        background: if rng.f32() < 0.3 { Color::new(0.2, 0.3, 0.5) } else { Color::ZERO },
        seed: rng.next_u64(),
        ..RenderSettings::default()
    }
}

/// Whether the explanation's terms sum to its pixel's value.
///
/// The terms are the renderer's own products, regrouped: the renderer computes
/// `d * (direct + ks * reflected) + (1 - d) * behind` ray by ray and divides sums by counts,
/// the terms multiply each leaf by its path's weight. Every term is non-negative (colours,
/// weights and cosines are), so no cancellation amplifies the rounding: each of the at most a
/// few dozen roundings on a term's path moves it by at most 2^-24 of itself, and the sum by
/// at most that many ulps of the sum. Relative 1e-4 of the sum (about 800 ulps) is far above
/// that and far below any missing or doubled term of visible size; the absolute 1e-6 covers
/// pixels near black, where relative bounds mean nothing.
fn sums_to_value(trace: &PixelTrace) -> Result<(), String> {
    let e = trace.explain();
    if !e.complete {
        return Err("tree cut".into());
    }
    // For a light shaded from one point, the factors shown multiply to the term.
    for t in &e.terms {
        if let Some(l) = t.lights.filter(|l| l.points == 1 && l.shaded == 1) {
            let product = t.material * l.factor * l.light_color * l.arrived;
            if (product - t.value).abs().max_element() > 1e-6 * (1.0 + t.value.max_element()) {
                return Err(format!(
                    "{:?} term of ray {}: factors give {product:?}, value {:?}",
                    t.kind, t.ray, t.value
                ));
            }
        }
    }
    let scale: Color = e.terms.iter().map(|t| t.contribution.abs()).sum::<Color>().max(e.value.abs());
    let err = (e.sum - e.value).abs();
    if (err - (scale * 1e-4 + Color::splat(1e-6))).max_element() > 0.0 {
        return Err(format!("terms sum to {:?}, the pixel is {:?}\n{e}", e.sum, e.value));
    }
    Ok(())
}

/// The demand: on every built-in scene, random pixels and random settings, the
/// explanation's terms sum to the rendered pixel.
#[test]
fn the_terms_sum_to_the_rendered_pixel() {
    let mut rng = Rng(2026);
    let mut cases = scenes("the_terms_sum_to_the_rendered_pixel");
    cases.push(("cornell-box, moving camera", moving_camera()));
    for (name, scene) in &cases {
        for _ in 0..10 {
            let s = random_settings(&mut rng);
            let film = render(scene, &s, &|_| {}).film;
            for _ in 0..5 {
                let x = (rng.f32() * s.width as f32) as u32;
                let y = (rng.f32() * s.height as f32) as u32;
                let trace = trace_pixel_samples(scene, &s, &scene.camera_motion(), x, y, SampleChoice::All, 1 << 20);
                assert_eq!(trace.value.to_array(), film.get(x, y).to_array(), "{name} ({x}, {y}) {s:?}");
                if let Err(e) = sums_to_value(&trace) {
                    panic!("{name} pixel ({x}, {y}) {s:?}: {e}");
                }
            }
        }
    }
}

/// A light point behind the surface is skipped with its reason and no shadow ray; the terms
/// still sum to the pixel.
#[test]
fn skipped_light_points_are_recorded_with_their_reason() {
    // Soft shadows sample area lights whose points lie partly behind the surfaces they light
    // (the ceiling beside the Cornell box's light, the cube's faces turned away).
    let s = RenderSettings { width: 24, height: 24, light_samples: 4, ..RenderSettings::default() };
    let mut skipped = 0;
    for name in ["cornell-box-parallelogram-light", "cornell-box-sphere-light", "cube", "cube-segment-light"] {
        let scene = builtin_scene(name, None);
        for y in 0..s.height {
            for x in 0..s.width {
                let trace = trace_pixel_samples(&scene, &s, &scene.camera_motion(), x, y, SampleChoice::All, 10_000);
                for ray in trace.samples.iter().flat_map(|t| &t.tree.rays) {
                    for skip in &ray.skipped_lights {
                        skipped += 1;
                        let hit = ray.hit.unwrap();
                        let to = skip.to - Vec3A::from(hit.point);
                        let cos = Vec3A::from(hit.shading_normal).dot(to);
                        assert_eq!(skip.reason == SkipReason::BehindShadingNormal, cos <= 0.0, "{name}: {skip:?}");
                        let shadows = ray.shadows.iter();
                        assert!(shadows.filter(|sh| sh.to == skip.to.to_array()).count() == 0, "no shadow ray");
                    }
                }
                sums_to_value(&trace).unwrap();
            }
        }
    }
    assert!(skipped > 0, "no light point was behind a surface");
}

/// Parses the OBJ's `l` and `p` elements per group.
fn obj_elements(text: &str) -> (usize, usize, Vec<String>) {
    let (mut lines, mut points, mut groups) = (0, 0, Vec::new());
    let vertices = text.lines().filter(|l| l.starts_with("v ")).count();
    for l in text.lines() {
        let mut words = l.split_whitespace();
        match words.next() {
            Some("g") => groups.push(words.next().unwrap().to_string()),
            Some(tag @ ("l" | "p")) => {
                let idx: Vec<usize> = words.map(|w| w.parse().unwrap()).collect();
                assert!(idx.iter().all(|i| (1..=vertices).contains(i)), "{l}");
                if tag == "l" {
                    assert_eq!(idx.len(), 2, "{l}");
                    lines += 1;
                } else {
                    points += 1;
                }
            }
            _ => {}
        }
    }
    (lines, points, groups)
}

/// The exported OBJ reloads with one segment per ray and per shadow ray (two for a blocked
/// one: to the blocker and past it).
#[test]
fn exported_rays_reload_with_every_segment() {
    let scene = builtin_scene("cornell-box", None);
    let s = RenderSettings { width: 40, height: 40, spp: 4, light_samples: 2, ..RenderSettings::default() };
    let dir = std::env::temp_dir().join(format!("rayscope-export-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("rays.obj");
    for (x, y) in [(20, 20), (8, 30), (33, 5)] {
        let trace = trace_pixel_samples(&scene, &s, &scene.camera_motion(), x, y, SampleChoice::All, 10_000);
        let counts = write_rays_obj(&trace, &path).unwrap();
        let rays = trace.samples.iter().flat_map(|t| &t.tree.rays);
        let expected: usize =
            rays.map(|r| 1 + r.shadows.iter().map(|s| if s.blocked_at.is_some() { 2 } else { 1 }).sum::<usize>()).sum();
        let text = std::fs::read_to_string(&path).unwrap();
        let (lines, points, groups) = obj_elements(&text);
        assert_eq!((lines, points), (counts.segments, counts.points));
        assert_eq!(lines, expected, "({x}, {y})");
        let hits = trace.samples.iter().flat_map(|t| &t.tree.rays).any(|r| r.hit.is_some());
        assert!(groups.contains(&"camera".to_string()), "{groups:?}");
        assert_eq!(groups.contains(&"hit-points".to_string()), hits, "{groups:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The debugger names every hit's material: from the MTL's `newmtl`, the scene file, or the
/// sphere it belongs to.
#[test]
fn materials_are_named() {
    let names = |scene: &str| builtin_scene(scene, None).materials.iter().map(|m| m.name.clone()).collect::<Vec<_>>();
    assert!(names("cornell-box").contains(&"tallBox".to_string()), "{:?}", names("cornell-box"));
    assert!(
        names("spheres").ends_with(&["sphere 0".into(), "sphere 1".into(), "sphere 2".into()]),
        "{:?}",
        names("spheres")
    );
}

/// A pixel of a tile the renderer culls (its frustum meets no box of the BVH) says so: the
/// trace names the tile and the explanation tells that the renderer filled it with the
/// background, which the traced rays return; a pixel the Cornell box covers has no such note.
#[test]
fn culled_pixels_say_they_were_not_traced() {
    let scene = builtin_scene("cornell-box", None);
    let s = RenderSettings::default();
    let camera = scene.camera_motion();
    let corner = trace_pixel_samples(&scene, &s, &camera, 3, 5, SampleChoice::All, MAX_RECORDED_RAYS);
    let tile = corner.culled.expect("the corner's tile is culled");
    // The top row of tiles misses the box: culled as a whole, by one test.
    assert_eq!((tile.x, tile.y), ([0, 800], [0, 8]));
    assert!(tile.nodes >= 1);
    assert!(corner.samples.iter().all(|s| s.tree.rays.iter().all(|r| r.hit.is_none())));
    let text = corner.explain().to_string();
    assert!(
        text.contains(
            "not traced by the renderer: the frustum of its tiles (columns 0..800, rows 0..8) meets no leaf box"
        ),
        "{text}"
    );
    let centre = trace_pixel_samples(&scene, &s, &camera, 400, 400, SampleChoice::All, MAX_RECORDED_RAYS);
    assert!(centre.culled.is_none() && !centre.explain().to_string().contains("not traced"));
}
