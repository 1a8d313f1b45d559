//! Environment maps: closed forms for what rays that miss return, the debugger's record of
//! the texel read, scene files and bad input.

mod common;

use std::path::Path;

use rayscope::camera::RayGenerator;
use rayscope::debug::{SampleChoice, trace_pixel_samples};
use rayscope::environment::{Environment, EnvironmentDesc};
use rayscope::material::{MaterialDesc, Texture};
use rayscope::math::{Color, Vec2, Vec3, Vec3A};
use rayscope::render::render;
use rayscope::scene::{LoadContext, Scene, SceneDesc, SphereDesc};
use rayscope::settings::{RenderSettings, TextureFilter};

const W: u32 = 96;
const H: u32 = 72;

/// A perfect mirror sphere (kd 0, ks 0.5) at the origin, low on the left of the default
/// camera's view, and no lights: its pixels show only what it reflects.
fn mirror_scene() -> Scene {
    let desc = SceneDesc {
        spheres: vec![SphereDesc {
            center: Vec3::new(-0.35, -0.3, 0.0),
            radius: 0.3,
            material: MaterialDesc {
                kd: Some(Color::ZERO),
                ks: Some(Color::splat(0.5)),
                shininess: Some(100.0),
                ..MaterialDesc::default()
            },
            motion: None,
        }],
        ..SceneDesc::default()
    };
    Scene::from_desc(&desc, &LoadContext::default()).unwrap()
}

fn map(width: u32, texels: Vec<Color>, intensity: f32, rotation: f32) -> Environment {
    let desc = EnvironmentDesc { path: "test.exr".into(), intensity, rotation };
    Environment::from_texture(desc, Texture::new(width, width / 2, texels)).unwrap()
}

fn settings(filter: TextureFilter) -> RenderSettings {
    RenderSettings { width: W, height: H, texture_filter: filter, ..RenderSettings::default() }
}

/// The camera ray direction of every pixel's centre (one sample per pixel renders the centre),
/// with whether it hits the scene.
fn pixel_rays(scene: &Scene) -> Vec<(u32, u32, Vec3A, bool)> {
    let rays = RayGenerator::new(&scene.camera(), W, H);
    let mut out = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let ray = rays.ray(x, y, Vec2::splat(0.5));
            out.push((x, y, ray.dir, scene.intersect(&ray).is_some()));
        }
    }
    out
}

#[test]
fn a_constant_map_is_every_missed_pixel_exactly_and_ks_times_it_in_a_mirror() {
    let mut scene = mirror_scene();
    let c = Color::new(0.3, 0.75, 1.5);
    scene.environment = Some(map(16, vec![c; 128], 2.0, 33.0));
    for filter in [TextureFilter::Bilinear, TextureFilter::Nearest] {
        let film = render(&scene, &settings(filter), &|_| {}).film;
        let (mut missed, mut mirrored) = (0, 0);
        for (x, y, _, hit) in pixel_rays(&scene) {
            let want = if hit { Color::splat(0.5) * (c * 2.0) } else { c * 2.0 };
            assert_eq!(film.get(x, y), want, "pixel {x},{y} (hit {hit})");
            if hit { mirrored += 1 } else { missed += 1 }
        }
        assert!(missed > 1000 && mirrored > 100, "{missed} missed, {mirrored} on the mirror");
    }
}

/// Where direction `d` falls in a `w x w/2` map turned by `rotation` degrees, written out
/// from the documented convention (centre along -z, `u` to the right, +y at the top row), as
/// continuous texel coordinates.
fn texel_coords(d: Vec3A, w: u32, rotation: f32) -> Vec2 {
    let (s, c) = rotation.to_radians().sin_cos();
    let d = Vec3A::new(d.x * c - d.z * s, d.y, d.x * s + d.z * c).normalize();
    let u = 0.5 + d.x.atan2(-d.z) / std::f32::consts::TAU;
    let v = d.y.acos() / std::f32::consts::PI;
    Vec2::new(u * w as f32, v * (w / 2) as f32)
}

#[test]
fn one_bright_texel_lights_exactly_the_pixels_whose_direction_falls_into_it() {
    let mut scene = mirror_scene();
    let w = 64u32;
    let aim = RayGenerator::new(&scene.camera(), W, H).ray(W * 7 / 10, H * 3 / 10, Vec2::splat(0.5)).dir;
    for (rotation, filter) in
        [(0.0, TextureFilter::Nearest), (0.0, TextureFilter::Bilinear), (-20.0, TextureFilter::Nearest)]
    {
        // The texel that the upper right of the view looks at, alone bright.
        let texel = texel_coords(aim, w, rotation).floor();
        let mut texels = vec![Color::ZERO; (w * w / 2) as usize];
        texels[(texel.y as u32 * w + texel.x as u32) as usize] = Color::ONE;
        let centre = texel + Vec2::splat(0.5);
        scene.environment = Some(map(w, texels, 1.0, rotation));
        let film = render(&scene, &settings(filter), &|_| {}).film;
        let (mut lit, mut checked) = (0, 0);
        for (x, y, dir, hit) in pixel_rays(&scene) {
            if hit {
                continue;
            }
            // Nearest: the texel's own square; bilinear: the square of one texel around its
            // centre, where its weight is not zero.
            let off = (texel_coords(dir, w, rotation) - centre).abs();
            let half = if filter == TextureFilter::Nearest { 0.5 } else { 1.0 };
            // Directions within rounding of an edge are left out.
            if (off - Vec2::splat(half)).abs().min_element() < 1e-3 {
                continue;
            }
            checked += 1;
            let inside = off.max_element() < half;
            let value = film.get(x, y);
            assert_eq!(value != Color::ZERO, inside, "pixel {x},{y}: {value} ({filter:?}, rotation {rotation})");
            lit += usize::from(inside);
        }
        assert!(lit >= 10 && checked > 4000, "{lit} lit of {checked} ({filter:?}, rotation {rotation})");
    }
}

#[test]
fn the_debugger_records_the_texel_a_missed_ray_read_and_explains_it() {
    let mut scene = mirror_scene();
    let w = 32;
    let texels: Vec<Color> = (0..w * w / 2).map(|i| Color::new(i as f32 / 512.0, 0.5, 1.0)).collect();
    scene.environment = Some(map(w, texels, 1.5, 10.0));
    let s = settings(TextureFilter::Bilinear);
    let film = render(&scene, &s, &|_| {}).film;
    // A background pixel (top right) and a mirror pixel: every miss records its lookup.
    let mirror = pixel_rays(&scene).into_iter().find(|r| r.3).map(|r| (r.0, r.1)).unwrap();
    for (x, y) in [(W - 5, 4), mirror] {
        let trace = trace_pixel_samples(&scene, &s, &scene.camera_motion(), x, y, SampleChoice::All, 1000);
        assert_eq!(trace.value, film.get(x, y));
        let rays = &trace.samples[0].tree.rays;
        let missed = rays.iter().find(|r| r.hit.is_none()).unwrap();
        let lookup = missed.environment.expect("a missed ray records its lookup");
        let env = scene.environment.as_ref().unwrap();
        let at = texel_coords(Vec3A::from(missed.dir), w, 10.0);
        assert_eq!(lookup.texel, [at.x as u32, at.y as u32]);
        assert_eq!(lookup.radiance, Color::from(missed.color));
        assert_eq!(lookup.radiance, env.radiance(Vec3A::from(missed.dir), TextureFilter::Bilinear));
        let explained = trace.explain();
        let term = explained.terms.iter().find(|t| t.environment.is_some()).unwrap();
        assert_eq!(term.kind.name(), "environment");
        assert!((explained.sum - trace.value).abs().max_element() < 1e-6);
        assert!(explained.to_string().contains(&format!("map texel ({}, {})", lookup.texel[0], lookup.texel[1])));
    }
}

/// A 2:1 Radiance HDR file of `width` texels, each `value`.
fn write_hdr(path: &Path, width: u32, height: u32, value: f32) {
    let img = image::Rgb32FImage::from_pixel(width, height, image::Rgb([value; 3]));
    image::DynamicImage::ImageRgb32F(img).save(path).unwrap();
}

#[test]
fn scene_files_load_the_map_relative_to_themselves_and_export_it() {
    let dir = tempfile::tempdir().unwrap();
    write_hdr(&dir.path().join("sky.hdr"), 8, 4, 0.5);
    let text = "[[sphere]]\ncenter = [0, 0, -5]\nradius = 0.1\n\n[environment]\npath = \"sky.hdr\"\nintensity = 4\nrotation = 45\n";
    let file = dir.path().join("scene.toml");
    std::fs::write(&file, text).unwrap();
    let scene = Scene::load(file.to_str().unwrap(), None).unwrap();
    let env = scene.environment.as_ref().unwrap();
    assert_eq!((env.desc.intensity, env.desc.rotation), (4.0, 45.0));
    assert_eq!(env.radiance(Vec3A::Y, TextureFilter::Bilinear), Color::splat(2.0));
    let desc = SceneDesc::from_toml(text, &file).unwrap();
    let again = SceneDesc::from_toml(&desc.to_toml(), &file).unwrap();
    assert_eq!(again.environment, desc.environment);
    assert!(desc.to_toml().contains("[environment]"));
}

#[test]
fn bad_maps_and_values_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let load = |text: &str| {
        let file = dir.path().join("scene.toml");
        std::fs::write(&file, format!("[[sphere]]\ncenter = [0, 0, -5]\nradius = 0.1\n\n[environment]\n{text}"))
            .unwrap();
        Scene::load(file.to_str().unwrap(), None).unwrap_err().to_string()
    };
    let err = load("path = \"missing.hdr\"\n");
    assert!(err.contains("missing.hdr"), "{err}");
    write_hdr(&dir.path().join("square.hdr"), 4, 4, 1.0);
    let err = load("path = \"square.hdr\"\n");
    assert!(err.contains("square.hdr") && err.contains("twice as wide as high") && err.contains("4x4"), "{err}");
    write_hdr(&dir.path().join("sky.hdr"), 4, 2, 1.0);
    let err = load("path = \"sky.hdr\"\nintensity = -1\n");
    assert!(err.contains("scene.toml:7") && err.contains("environment, intensity"), "{err}");
    let err = load("path = \"sky.hdr\"\nrotation = nan\n");
    assert!(err.contains("scene.toml:7") && err.contains("environment, rotation"), "{err}");
    std::fs::write(dir.path().join("junk.png"), b"not an image").unwrap();
    let err = load("path = \"junk.png\"\n");
    assert!(err.contains("junk.png") && err.contains("cannot decode"), "{err}");
    // The guarded readers: a device is refused, never read.
    let err = load("path = \"/dev/zero\"\n");
    assert!(err.contains("/dev/zero") && err.contains("not a regular file"), "{err}");
    let err = load("path = \".\"\n");
    assert!(err.contains("not a regular file"), "{err}");
}
