//! The integrator against hand computations, and spawned rays against their own surfaces.

mod common;

use common::{Rng, icosphere, inline_scene, plane};
use rayscope::aov::{Aov, render_aov};
use rayscope::camera::CameraDesc;
use rayscope::light::Light;
use rayscope::material::MaterialDesc;
use rayscope::math::{Color, Vec3, Vec3A};
use rayscope::ray::Ray;
use rayscope::render::render;
use rayscope::scene::{LoadContext, Scene, SceneDesc};
use rayscope::settings::RenderSettings;

/// A 5x5 image whose centre pixel's ray goes exactly through the origin along +z.
fn settings() -> RenderSettings {
    RenderSettings { width: 5, height: 5, ..RenderSettings::default() }
}

fn camera() -> CameraDesc {
    CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -3.0), target: Vec3::ZERO, up: Vec3::Y, fov: 30.0 }
}

fn centre(scene: &SceneDesc, s: &RenderSettings) -> Color {
    let scene = Scene::from_desc(scene, &LoadContext::default()).unwrap();
    render(&scene, s, &|_| {}).film.get(2, 2)
}

fn close(a: Color, b: Color) {
    assert!((a - b).abs().max_element() < 1e-5, "{a} vs {b}");
}

const KD: Vec3 = Vec3::new(0.8, 0.4, 0.2);
const KS: Vec3 = Vec3::new(0.5, 0.5, 0.5);
const LIGHT: Vec3 = Vec3::new(1.0, 0.5, 2.0);

fn lit_plane() -> SceneDesc {
    SceneDesc {
        camera: camera(),
        meshes: vec![plane(
            0.0,
            MaterialDesc { kd: Some(KD), ks: Some(KS), shininess: Some(10.0), ..Default::default() },
        )],
        lights: vec![Light::Point { position: Vec3::new(1.0, 0.0, -1.0), color: LIGHT }],
        ..SceneDesc::default()
    }
}

#[test]
fn phong_matches_hand_computation() {
    // Hit point (0,0,0), normal (0,0,-1) towards the camera, light direction (1,0,-1)/sqrt2:
    // n.l = 1/sqrt2; the mirror of the light direction is (-1,0,-1)/sqrt2, and the view
    // direction is (0,0,-1), so r.v = 1/sqrt2.
    let c = std::f32::consts::FRAC_1_SQRT_2;
    let want = LIGHT * (KD * c + KS * c.powf(10.0));
    // No mirror reflection: the reflected ray leaves into empty space (black background).
    close(centre(&lit_plane(), &settings()), want);
}

#[test]
fn shading_off_shows_kd_and_shadows_block() {
    let s = RenderSettings { shading: false, ..settings() };
    close(centre(&lit_plane(), &s), KD);
    // A small opaque square between the point and the light.
    let mut scene = lit_plane();
    let (a, b) = (0.4, 0.6);
    let blocker = inline_scene(
        vec![Vec3::new(a, -0.1, -b), Vec3::new(b, -0.1, -a), Vec3::new(b, 0.1, -a), Vec3::new(a, 0.1, -b)],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    scene.meshes.extend(blocker.meshes);
    close(centre(&scene, &settings()), Color::ZERO);
    let no_shadows = RenderSettings { shadows: false, ..settings() };
    assert!(centre(&scene, &no_shadows).max_element() > 0.1);
}

#[test]
fn light_behind_the_surface_contributes_nothing() {
    let mut scene = lit_plane();
    scene.lights = vec![Light::Point { position: Vec3::new(0.0, 0.0, 1.0), color: LIGHT }];
    close(centre(&scene, &settings()), Color::ZERO);
}

#[test]
fn mirror_reflection_is_weighted_by_ks() {
    // A mirror plane at z = 0 facing the camera reflects the camera ray straight back to a
    // diffuse plane behind the camera (z = -5) that faces it; the light sits beside the camera.
    let mirror =
        MaterialDesc { kd: Some(Vec3::ZERO), ks: Some(Vec3::splat(0.5)), shininess: Some(1e6), ..Default::default() };
    let wall = MaterialDesc { kd: Some(Vec3::splat(0.6)), ..Default::default() };
    let scene = SceneDesc {
        camera: camera(),
        meshes: vec![plane(0.0, mirror), plane(-5.0, wall)],
        lights: vec![Light::Point { position: Vec3::new(0.0, 0.0, -1.0), color: Vec3::ONE }],
        ..SceneDesc::default()
    };
    // The wall point (0,0,-5) sees the light head-on: 0.6. The mirror adds 0.5 of that; its
    // own specular highlight is 0.5 * 1^1e6 = 0.5 (light, mirror point and eye aligned).
    close(centre(&scene, &settings()), Vec3::splat(0.5 + 0.5 * 0.6));
    let shallow = RenderSettings { max_depth: 0, ..settings() };
    close(centre(&scene, &shallow), Vec3::splat(0.5));
}

#[test]
fn transparency_blends_and_tints_shadows() {
    // A half-transparent red sheet (d = 0.25) in front of a white wall, the light in front.
    let sheet = MaterialDesc { kd: Some(Vec3::new(1.0, 0.0, 0.0)), transparency: Some(0.25), ..Default::default() };
    let wall = MaterialDesc { kd: Some(Vec3::ONE), ..Default::default() };
    let scene = SceneDesc {
        camera: camera(),
        meshes: vec![plane(-0.5, sheet), plane(0.0, wall)],
        lights: vec![Light::Point { position: Vec3::new(0.0, 0.0, -2.0), color: Vec3::ONE }],
        ..SceneDesc::default()
    };
    // Sheet lit head-on: (1,0,0). Wall behind: lit through the sheet, tinted by
    // kd * (1 - d) = (0.75, 0, 0). Blend: 0.25 * sheet + 0.75 * wall.
    let want = 0.25 * Vec3::new(1.0, 0.0, 0.0) + 0.75 * Vec3::new(0.75, 0.0, 0.0);
    close(centre(&scene, &settings()), want);
    let opaque = RenderSettings { transparency: false, ..settings() };
    close(centre(&scene, &opaque), Vec3::new(1.0, 0.0, 0.0));
}

#[test]
fn aovs_report_first_hits() {
    let scene = Scene::from_desc(&lit_plane(), &LoadContext::default()).unwrap();
    let s = settings();
    let depth = render_aov(&scene, &s, &scene.camera(), Aov::Depth, &|_| {});
    assert!((depth.pixel(2, 2)[0] - 3.0).abs() < 1e-5);
    let normal = render_aov(&scene, &s, &scene.camera(), Aov::Normal, &|_| {});
    assert_eq!(normal.pixel(2, 2), &[0.0, 0.0, -1.0]);
    let albedo = render_aov(&scene, &s, &scene.camera(), Aov::Albedo, &|_| {});
    assert_eq!(albedo.pixel(2, 2), &KD.to_array());
    let mut empty = lit_plane();
    empty.meshes.clear();
    let scene = Scene::from_desc(&empty, &LoadContext::default()).unwrap();
    assert!(render_aov(&scene, &s, &scene.camera(), Aov::Depth, &|_| {}).pixel(0, 0)[0].is_nan());
    assert_eq!(render_aov(&scene, &s, &scene.camera(), Aov::PrimId, &|_| {}).pixel(0, 0)[0], -1.0);
    assert!(render_aov(&scene, &s, &scene.camera(), Aov::Position, &|_| {}).pixel(4, 4).iter().all(|v| v.is_nan()));
}

#[test]
fn spawned_rays_never_rehit_their_surface() {
    // Rays from random points hit a finely tessellated sphere at random scales; from each hit,
    // rays spawned into both hemispheres must not find their own triangle again (no acne),
    // and shadow rays to points just outside must not be blocked by the surface they leave.
    let mut rng = Rng(21);
    for scale in [1e-3f32, 1.0, 1e3] {
        let (v, f) = icosphere(4);
        let v = v.into_iter().map(|p| p * scale + Vec3::new(0.3, -0.2, 0.1) * scale).collect();
        let scene = Scene::from_desc(&inline_scene(v, f), &LoadContext::default()).unwrap();
        let s = RenderSettings::default();
        let mut tested = 0;
        for _ in 0..4000 {
            let origin = rng.vec3(-3.0, 3.0) * scale;
            let aim = (rng.vec3(-0.9, 0.9) + Vec3A::new(0.3, -0.2, 0.1)) * scale;
            let ray = Ray::new(origin, (aim - origin).normalize());
            let Some(hit) = scene.intersect(&ray) else { continue };
            let si = scene.surface(&ray, &hit, &s.shading_options());
            tested += 1;
            for _ in 0..4 {
                let d = rng.dir();
                let r = Ray::spawn(si.point, si.geo_normal, d, 0.0);
                if let Some(h2) = scene.intersect(&r) {
                    assert!(h2.slot != hit.slot, "scale {scale}: re-hit own triangle at t = {}", h2.t);
                }
            }
            let target = si.point + si.geo_normal * (0.05 * scale);
            assert!(!scene.occluded(&Ray::spawn_to(si.point, si.geo_normal, target, 0.0)), "scale {scale}");
        }
        assert!(tested > 500);
    }
}

#[test]
fn no_peter_panning_at_contact() {
    // A box standing on a floor: floor points right next to the box's base, on the side away
    // from the light, must be in shadow (the offset must not let shadow rays slip under).
    let floor = MaterialDesc { kd: Some(Vec3::ONE), ..Default::default() };
    let s = 10.0;
    let mut scene = inline_scene(
        vec![Vec3::new(-s, 0.0, -s), Vec3::new(s, 0.0, -s), Vec3::new(s, 0.0, s), Vec3::new(-s, 0.0, s)],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    scene.meshes[0].material = Some(floor);
    // A wall x in [0, 0.1], y in [0, 1], standing on the floor.
    let wall = inline_scene(
        vec![Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 1.0, -1.0), Vec3::new(0.0, 1.0, 1.0), Vec3::new(0.0, 0.0, 1.0)],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    scene.meshes.extend(wall.meshes);
    let scene = Scene::from_desc(&scene, &LoadContext::default()).unwrap();
    let light = Vec3A::new(-1.0, 0.5, 0.0);
    for d in [1e-3f32, 1e-2, 0.1] {
        let p = Vec3A::new(d, 0.0, 0.0);
        let r = Ray::spawn_to(p, Vec3A::Y, light, 0.0);
        assert!(scene.occluded(&r), "floor point {d} behind the wall must be shadowed");
    }
}
