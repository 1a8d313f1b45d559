//! Adaptive depth control (`adc_bailout`) and the debugger's bounded ray tree: ray trees that
//! doubled with every level stay small, the cut falls exactly where the weights say, 0 turns it
//! off, and the recorded tree stops at its bound and says so.

mod common;

use common::plane;
use rayscope::camera::CameraDesc;
use rayscope::light::Light;
use rayscope::material::MaterialDesc;
use rayscope::math::{Color, Vec3};
use rayscope::record::{NoRecorder, RayKind, RayTree, RecordedRay, StoppedBranch};
use rayscope::render::{RenderOutput, render, trace_pixel};
use rayscope::scene::{LoadContext, MeshDesc, Scene, SceneDesc, SphereDesc};
use rayscope::settings::{DEFAULT_ADC_BAILOUT, RenderSettings};

/// The hostile scene: two nested spheres that both reflect fully and let half the
/// light through (`ks = 1`, `d = 0.5`), so every hit casts two rays that hit again.
fn nested_spheres() -> Scene {
    let glass = MaterialDesc {
        kd: Some(Vec3::splat(0.5)),
        ks: Some(Vec3::ONE),
        shininess: Some(20.0),
        transparency: Some(0.5),
        ..Default::default()
    };
    let sphere = |radius| SphereDesc { center: Vec3::ZERO, radius, material: glass.clone(), motion: None };
    let desc = SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -3.0), target: Vec3::ZERO, up: Vec3::Y, fov: 40.0 },
        spheres: vec![sphere(1.0), sphere(0.5)],
        lights: vec![Light::Point { position: Vec3::new(0.3, 0.2, -0.2), color: Vec3::ONE }],
        ..SceneDesc::default()
    };
    Scene::from_desc(&desc, &LoadContext::default()).unwrap()
}

fn hostile(adc_bailout: f32, max_depth: u32) -> RenderSettings {
    RenderSettings { width: 8, height: 8, max_depth, adc_bailout, ..RenderSettings::default() }
}

#[test]
fn reflecting_and_transmitting_spheres_cast_a_bounded_number_of_rays() {
    // Every ray a hit casts weighs half of the hit's ray (ks * d = 0.5 and 1 - d = 0.5), so
    // with 1/1024 rays down to depth 10 are cast and none deeper: at most 2^11 - 1 rays a
    // pixel, where max_depth alone allows 2^65 - 1.
    assert_eq!(DEFAULT_ADC_BAILOUT, 1.0 / 1024.0);
    let scene = nested_spheres();
    let out = render(&scene, &hostile(DEFAULT_ADC_BAILOUT, 64), &|_| {});
    assert!(out.rays.primary_and_secondary <= 64 * 2047, "{:?}", out.rays);
    let tree = |adc_bailout, max_depth| {
        let mut tree = RayTree::with_limit(usize::MAX);
        trace_pixel(&scene, &hostile(adc_bailout, max_depth), &scene.camera_motion(), 4, 4, 0, &mut tree);
        tree
    };
    // Without adaptive depth control the centre pixel passes that bound by depth 20 already.
    let unbounded = tree(0.0, 20);
    assert!(unbounded.rays.len() > 2047, "{} rays", unbounded.rays.len());
    assert!(unbounded.rays.iter().all(|r| r.stopped.is_empty()));
    let bounded = tree(DEFAULT_ADC_BAILOUT, 64);
    assert!(bounded.rays.len() <= 2047, "{} rays", bounded.rays.len());
    assert_eq!(bounded.rays.iter().map(|r| r.depth).max(), Some(10));
    assert!(bounded.rays.iter().flat_map(|r| &r.stopped).all(|b| b.weight == 1.0 / 2048.0));
    // Off, the tree reaches max_depth: what max_depth alone did before.
    assert_eq!(tree(0.0, 12).rays.iter().map(|r| r.depth).max(), Some(12));
}

/// The centre pixel of a 5x5 image looking along +z from (0, 0, -3) at `meshes`, traced with
/// a recorder: its tree and colour.
fn centre_tree(meshes: Vec<MeshDesc>, s: &RenderSettings) -> (RayTree, Color) {
    let desc = SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -3.0), target: Vec3::ZERO, up: Vec3::Y, fov: 30.0 },
        meshes,
        lights: vec![Light::Point { position: Vec3::new(0.0, 0.0, -2.0), color: Vec3::ONE }],
        ..SceneDesc::default()
    };
    let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
    let s = RenderSettings { width: 5, height: 5, ..s.clone() };
    let mut tree = RayTree::default();
    let c = trace_pixel(&scene, &s, &scene.camera_motion(), 2, 2, 0, &mut tree);
    // The recorder only watches: the colour is the renderer's.
    assert_eq!(c, trace_pixel(&scene, &s, &scene.camera_motion(), 2, 2, 0, &mut NoRecorder));
    (tree, c)
}

fn deepest(tree: &RayTree) -> u32 {
    tree.rays.iter().map(|r| r.depth).max().unwrap()
}

#[test]
fn a_mirror_chain_stops_where_its_weight_falls_below_the_bailout() {
    // Two facing mirrors of ks = 0.5 (z = 0 and z = -5): the centre ray bounces between them,
    // and the reflection at depth d weighs 0.5^d. With a bailout of 0.01, 0.5^6 = 0.0156 is
    // cast and 0.5^7 = 0.0078 is not.
    let mirror =
        MaterialDesc { kd: Some(Vec3::ZERO), ks: Some(Vec3::splat(0.5)), shininess: Some(1e6), ..Default::default() };
    let meshes = || vec![plane(0.0, mirror.clone()), plane(-5.0, mirror.clone())];
    let s = RenderSettings { max_depth: 64, adc_bailout: 0.01, ..RenderSettings::default() };
    let (tree, _) = centre_tree(meshes(), &s);
    assert_eq!(tree.rays.len(), 7);
    assert_eq!(deepest(&tree), 6);
    let stop = StoppedBranch { kind: RayKind::Reflection, rays: 1, weight: 0.5f32.powi(7), adc_bailout: 0.01 };
    assert_eq!(tree.rays[6].stopped, [stop]);
    assert_eq!(stop.to_string(), "reflection not cast: weight 0.00781 below adc_bailout 0.01");
    // Off, the chain goes on to max_depth, as before adaptive depth control.
    let (tree, _) = centre_tree(meshes(), &RenderSettings { adc_bailout: 0.0, ..s.clone() });
    assert_eq!((tree.rays.len(), deepest(&tree)), (65, 64));
    // A glossy reflection's rays weigh 1/n of it each: 0.5 / 16 is below 0.05, so the
    // camera ray casts none of its 16.
    let (tree, c) = centre_tree(meshes(), &RenderSettings { gloss_samples: 16, adc_bailout: 0.05, ..s });
    let stop = StoppedBranch { kind: RayKind::Glossy, rays: 16, weight: 0.5 / 16.0, adc_bailout: 0.05 };
    assert_eq!((tree.rays.len(), &tree.rays[0].stopped[..]), (1, &[stop][..]));
    // What is left is the mirror's own highlight (ks = 0.5; light, point and eye aligned).
    assert_eq!(c, Color::splat(0.5));
}

#[test]
fn transparent_layers_stop_at_the_predicted_depth() {
    // Sheets at z = 0, 1, 2, ... with d = 0.25: the light behind sheet d weighs 0.75^(d+1).
    // With a bailout of 0.1, 0.75^8 = 0.1001 is cast and 0.75^9 = 0.0751 is not.
    let sheet = MaterialDesc { kd: Some(Vec3::ONE), transparency: Some(0.25), ..Default::default() };
    let meshes: Vec<_> = (0..20).map(|z| plane(z as f32, sheet.clone())).collect();
    let s = RenderSettings { max_depth: 64, adc_bailout: 0.1, ..RenderSettings::default() };
    let (tree, _) = centre_tree(meshes.clone(), &s);
    assert_eq!((tree.rays.len(), deepest(&tree)), (9, 8));
    let stop = StoppedBranch { kind: RayKind::Transmission, rays: 1, weight: 0.75f32.powi(9), adc_bailout: 0.1 };
    assert_eq!(tree.rays[8].stopped, [stop]);
    // The light not cast for adds nothing: the colour of the first 9 sheets before a black
    // background (the light is in front of them all).
    let (_, c) = centre_tree(meshes.clone(), &s);
    let (_, nine) = centre_tree(meshes[..9].to_vec(), &RenderSettings { adc_bailout: 0.0, ..s });
    assert_eq!(c, nine);
}

#[test]
fn the_reflection_of_a_partly_transparent_surface_is_weighted_by_its_opacity() {
    // ks = (0.6, 0.2, 0.1) and d = 0.5: the reflection weighs max(ks) * d = 0.3, the light
    // behind 1 - d = 0.5.
    let sheet = MaterialDesc {
        kd: Some(Vec3::splat(0.5)),
        ks: Some(Vec3::new(0.6, 0.2, 0.1)),
        transparency: Some(0.5),
        shininess: Some(10.0),
        ..Default::default()
    };
    let s = |adc_bailout, transparency| RenderSettings { adc_bailout, transparency, ..RenderSettings::default() };
    let kinds = |tree: &RayTree| tree.rays.iter().map(|r| r.kind).collect::<Vec<_>>();
    let (tree, _) = centre_tree(vec![plane(0.0, sheet.clone())], &s(0.31, true));
    let stop = StoppedBranch { kind: RayKind::Reflection, rays: 1, weight: 0.3, adc_bailout: 0.31 };
    assert_eq!(tree.rays[0].stopped, [stop]);
    assert_eq!(kinds(&tree), [RayKind::Camera, RayKind::Transmission]);
    let (tree, _) = centre_tree(vec![plane(0.0, sheet.clone())], &s(0.29, true));
    assert_eq!(kinds(&tree), [RayKind::Camera, RayKind::Reflection, RayKind::Transmission]);
    // Opaque (transparency off), the reflection keeps all of ks: 0.6.
    let (tree, _) = centre_tree(vec![plane(0.0, sheet)], &s(0.59, false));
    assert_eq!(kinds(&tree), [RayKind::Camera, RayKind::Reflection]);
}

#[test]
fn adaptive_depth_control_is_the_same_on_any_number_of_threads() {
    let scene = nested_spheres();
    let s = RenderSettings { width: 24, height: 16, spp: 2, gloss_samples: 4, ..hostile(DEFAULT_ADC_BAILOUT, 64) };
    let on = |threads| -> RenderOutput {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render(&scene, &s, &|_| {}))
    };
    let (one, two) = (on(1), on(2));
    assert_eq!(one.rays, two.rays);
    let bits = |o: &RenderOutput| o.film.pixels().iter().map(|c| c.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    assert_eq!(bits(&one), bits(&two));
}

#[test]
fn the_debuggers_tree_stops_at_its_bound_and_says_so() {
    // Without adaptive depth control the hostile scene's centre pixel casts about 90 000 rays
    // and as many shadow rays at max_depth 22: more than the tree keeps.
    let scene = nested_spheres();
    let s = hostile(0.0, 22);
    let mut tree = RayTree::default();
    let c = trace_pixel(&scene, &s, &scene.camera_motion(), 4, 4, 0, &mut tree);
    let shadows: usize = tree.rays.iter().map(|r| r.shadows.len()).sum();
    assert_eq!(tree.rays.len() + shadows, rayscope::record::MAX_RECORDED_RAYS);
    let cut = tree.cut.expect("the tree says it was cut");
    assert!(cut.rays > 0 && cut.shadow_rays > 0, "{cut:?}");
    // Every recorded parent is recorded, and the colour is the renderer's.
    assert!(tree.rays.iter().skip(1).all(|r| r.parent.is_some_and(|p| p < tree.rays.len())));
    assert_eq!(c, trace_pixel(&scene, &s, &scene.camera_motion(), 4, 4, 0, &mut NoRecorder));
    // A small bound counts what it left out: every ray is either recorded or counted.
    let mut small = RayTree::with_limit(10);
    trace_pixel(&scene, &hostile(DEFAULT_ADC_BAILOUT, 64), &scene.camera_motion(), 4, 4, 0, &mut small);
    let mut all = RayTree::default();
    trace_pixel(&scene, &hostile(DEFAULT_ADC_BAILOUT, 64), &scene.camera_motion(), 4, 4, 0, &mut all);
    let cut = small.cut.unwrap();
    let recorded_shadows: usize = small.rays.iter().map(|r| r.shadows.len()).sum();
    assert_eq!(small.rays.len() + recorded_shadows, 10);
    // The first rays, as the full tree has them (the last may lack shadow rays).
    let same =
        |a: &RecordedRay, b: &RecordedRay| (a.parent, a.origin, a.hit, a.color) == (b.parent, b.origin, b.hit, b.color);
    assert!(small.rays.iter().zip(&all.rays).all(|(a, b)| same(a, b)));
    let all_shadows: usize = all.rays.iter().map(|r| r.shadows.len()).sum();
    assert_eq!(small.rays.len() as u64 + cut.rays, all.rays.len() as u64);
    assert_eq!(recorded_shadows as u64 + cut.shadow_rays, all_shadows as u64);
}

#[test]
fn adc_bailout_is_validated() {
    for bad in [f32::NAN, f32::INFINITY, -0.1, 1.5] {
        let e = RenderSettings { adc_bailout: bad, ..RenderSettings::default() }.validate().unwrap_err().to_string();
        assert!(e.contains("adc_bailout") && e.contains(&bad.to_string()), "{e}");
    }
    for good in [0.0, DEFAULT_ADC_BAILOUT, 1.0] {
        RenderSettings { adc_bailout: good, ..RenderSettings::default() }.validate().unwrap();
    }
}
