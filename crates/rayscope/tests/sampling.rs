//! The stochastic features against closed forms: soft shadows, anti-aliasing, gloss, motion
//! blur, and determinism across threads and progressive stop-and-resume.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};

use common::inline_scene;
use rayscope::camera::CameraDesc;
use rayscope::light::Light;
use rayscope::material::MaterialDesc;
use rayscope::math::{Color, Vec2, Vec3, Vec3A};
use rayscope::progressive::{ImagingMode, Progressive};
use rayscope::render::render;
use rayscope::sampler::stratum_1d;
use rayscope::scene::{LoadContext, MeshDesc, Scene, SceneDesc, SphereDesc, desc::MotionDesc};
use rayscope::settings::{PixelFilter, RenderSettings};

fn quad(corners: [Vec3; 4], material: MaterialDesc) -> MeshDesc {
    let mut m = inline_scene(corners.to_vec(), vec![[0, 1, 2], [0, 2, 3]]).meshes.remove(0);
    m.material = Some(material);
    m
}

fn white() -> MaterialDesc {
    MaterialDesc { kd: Some(Vec3::ONE), ..MaterialDesc::default() }
}

/// A floor (y = 0) seen by a one-pixel camera whose ray hits the origin from the side.
fn floor_scene(lights: Vec<Light>, occluder: bool) -> SceneDesc {
    let s = 10.0;
    let mut meshes = vec![quad(
        [Vec3::new(-s, 0.0, -s), Vec3::new(s, 0.0, -s), Vec3::new(s, 0.0, s), Vec3::new(-s, 0.0, s)],
        white(),
    )];
    if occluder {
        // The half plane x < 0 at height 0.5: it hides exactly the x < 0 half of a light
        // centred over the origin at height 1.
        let y = 0.5;
        meshes.push(quad(
            [Vec3::new(-s, y, -s), Vec3::new(0.0, y, -s), Vec3::new(0.0, y, s), Vec3::new(-s, y, s)],
            white(),
        ));
    }
    SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.3, -1.0), target: Vec3::ZERO, up: Vec3::Y, fov: 10.0 },
        meshes,
        lights,
        ..SceneDesc::default()
    }
}

fn one_pixel(desc: &SceneDesc, s: RenderSettings) -> Color {
    let scene = Scene::from_desc(desc, &LoadContext::default()).unwrap();
    render(&scene, &RenderSettings { width: 1, height: 1, ..s }, &|_| {}).film.get(0, 0)
}

fn square_light() -> Light {
    Light::Parallelogram {
        v0: Vec3::new(-0.5, 1.0, -0.5),
        edge01: Vec3::X,
        edge02: Vec3::Z,
        color0: Vec3::ONE,
        color1: Vec3::ONE,
        color2: Vec3::ONE,
        color3: Vec3::ONE,
    }
}

#[test]
fn half_covered_parallelogram_light_gives_half_the_light() {
    // Strata (7x7, 21x21) that do not line up with the occluder's edge, so the estimate is
    // really random; averaged over 8 seeds. Tolerances are three standard deviations.
    for (n, tol) in [(49, 0.03), (441, 0.006)] {
        let ratio = (0..8)
            .map(|seed| {
                let s = RenderSettings { light_samples: n, seed, ..RenderSettings::default() };
                let free = one_pixel(&floor_scene(vec![square_light()], false), s.clone()).x;
                let half = one_pixel(&floor_scene(vec![square_light()], true), s).x;
                assert!(free > 0.1);
                half / free
            })
            .sum::<f32>()
            / 8.0;
        assert!((ratio - 0.5).abs() < tol, "{n} samples: {ratio}");
    }
}

#[test]
fn fully_visible_sphere_light_matches_the_analytic_value() {
    // Uniform directions in the cone the sphere subtends: E[cos] = (1 + cos(theta_max)) / 2.
    let (d, r) = (1.0f32, 0.6f32);
    let light = Light::Sphere { center: Vec3::new(0.0, d, 0.0), radius: r, color: Vec3::splat(2.0) };
    let cos_max = (1.0 - (r / d).powi(2)).sqrt();
    let want = 2.0 * (1.0 + cos_max) / 2.0;
    let got = one_pixel(&floor_scene(vec![light], false), RenderSettings { light_samples: 256, ..Default::default() });
    assert!((got.x - want).abs() < 2e-3, "{} vs {want}", got.x);
    // Hard shadows shade it from its centre: cos = 1.
    let hard = one_pixel(&floor_scene(vec![light_at(d, r)], false), RenderSettings::default());
    assert!((hard.x - 2.0).abs() < 1e-5);
}

fn light_at(d: f32, r: f32) -> Light {
    Light::Sphere { center: Vec3::new(0.0, d, 0.0), radius: r, color: Vec3::splat(2.0) }
}

#[test]
fn segment_light_colour_averages_its_ends() {
    let seg = |c0: Vec3, c1: Vec3| Light::Segment {
        endpoint0: Vec3::new(-0.5, 1.0, 0.0),
        endpoint1: Vec3::new(0.5, 1.0, 0.0),
        color0: c0,
        color1: c1,
    };
    // The stratified samples' mean colour is the average of the ends.
    let l = seg(Vec3::X, Vec3::Z);
    let n = 64;
    let mean: Vec3 =
        (0..n).map(|i| l.sample(Vec3A::ZERO, Vec2::new(stratum_1d(i, n, 0.5), 0.5)).color).sum::<Vec3>() / n as f32;
    assert!((mean - Vec3::new(0.5, 0.0, 0.5)).abs().max_element() < 1e-5);
    // Seen from a point under its middle (a symmetric weighting), the two-coloured segment
    // lights like one of the average colour.
    let s = RenderSettings { light_samples: 64, ..Default::default() };
    let two = one_pixel(&floor_scene(vec![seg(Vec3::X, Vec3::Z)], false), s.clone());
    let avg = one_pixel(&floor_scene(vec![seg(Vec3::splat(0.5), Vec3::splat(0.5))], false), s);
    assert!((two.x - avg.x).abs() < 1e-3 && (two.z - avg.z).abs() < 1e-3, "{two} vs {avg}");
}

#[test]
fn zero_size_lights_with_one_sample_equal_hard_shadows() {
    let p = Vec3::new(0.2, 1.0, 0.1);
    for light in [
        Light::Sphere { center: p, radius: 0.0, color: Vec3::ONE },
        Light::Segment { endpoint0: p, endpoint1: p, color0: Vec3::ONE, color1: Vec3::ONE },
        Light::Parallelogram {
            v0: p,
            edge01: Vec3::ZERO,
            edge02: Vec3::ZERO,
            color0: Vec3::ONE,
            color1: Vec3::ONE,
            color2: Vec3::ONE,
            color3: Vec3::ONE,
        },
    ] {
        let desc = floor_scene(vec![light.clone()], true);
        let hard = one_pixel(&desc, RenderSettings::default());
        let soft = one_pixel(&desc, RenderSettings { light_samples: 1, ..Default::default() });
        assert_eq!(hard, soft, "{light:?}");
    }
}

#[test]
fn soft_shadow_variance_falls_with_samples() {
    let desc = floor_scene(vec![square_light()], true);
    let var = |n: u32| {
        let vals: Vec<f32> = (0..48)
            .map(|seed| one_pixel(&desc, RenderSettings { light_samples: n, seed, ..Default::default() }).x)
            .collect();
        let m = vals.iter().sum::<f32>() / vals.len() as f32;
        vals.iter().map(|v| (v - m).powi(2)).sum::<f32>() / (vals.len() - 1) as f32
    };
    let (v4, v16, v64) = (var(4), var(16), var(64));
    // At least 1/N (stratification does better on this smooth integrand).
    assert!(v4 / v16 > 3.0 && v16 / v64 > 3.0, "variances {v4} {v16} {v64}");
}

#[test]
fn anti_aliased_edge_pixel_converges_to_its_coverage() {
    // Camera 3 units from the plane z = 0, fov 30: a pixel's footprint on the plane is linear
    // in screen coordinates. White where world x > e, nothing elsewhere, shading off.
    let e = 0.05f32;
    let desc = SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -3.0), target: Vec3::ZERO, up: Vec3::Y, fov: 30.0 },
        meshes: vec![quad(
            [Vec3::new(e, -5.0, 0.0), Vec3::new(5.0, -5.0, 0.0), Vec3::new(5.0, 5.0, 0.0), Vec3::new(e, 5.0, 0.0)],
            white(),
        )],
        ..SceneDesc::default()
    };
    let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
    let s = RenderSettings { width: 5, height: 5, shading: false, spp: 1024, ..Default::default() };
    let film = render(&scene, &s, &|_| {}).film;
    // Pixel (2, 2) spans screen x in [-0.2, 0.2], world x = -screen_x * 3 tan(15 deg).
    let k = 3.0 * 15f32.to_radians().tan();
    let coverage = (0.2 * k - e) / (0.4 * k);
    assert!((film.get(2, 2).x - coverage).abs() < 0.01, "{} vs {coverage}", film.get(2, 2).x);
    // The tent and Gaussian filters reach into neighbours but keep the edge's mean.
    for filter in [PixelFilter::Tent, PixelFilter::Gaussian] {
        let f = render(&scene, &RenderSettings { filter, ..s.clone() }, &|_| {}).film;
        let v = f.get(2, 2).x;
        assert!(v > 0.05 && v < 0.95, "{filter:?}: {v}");
    }
}

fn mirror_scene(shininess: f32) -> SceneDesc {
    // A glossy plane facing the camera reflects a lit, diffuse wall behind the camera.
    let g = MaterialDesc {
        kd: Some(Vec3::ZERO),
        ks: Some(Vec3::splat(0.8)),
        shininess: Some(shininess),
        ..Default::default()
    };
    let s = 5.0;
    SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -3.0), target: Vec3::ZERO, up: Vec3::Y, fov: 40.0 },
        meshes: vec![
            quad([Vec3::new(-s, -s, 0.0), Vec3::new(s, -s, 0.0), Vec3::new(s, s, 0.0), Vec3::new(-s, s, 0.0)], g),
            quad(
                [Vec3::new(-s, -s, -6.0), Vec3::new(s, -s, -6.0), Vec3::new(s, s, -6.0), Vec3::new(-s, s, -6.0)],
                white(),
            ),
        ],
        lights: vec![Light::Point { position: Vec3::new(1.5, 1.0, -4.0), color: Vec3::ONE }],
        ..SceneDesc::default()
    }
}

#[test]
fn gloss_in_a_white_surrounding_returns_ks() {
    let g =
        MaterialDesc { kd: Some(Vec3::ZERO), ks: Some(Vec3::splat(0.3)), shininess: Some(5.0), ..Default::default() };
    let desc = SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -3.0), target: Vec3::ZERO, up: Vec3::Y, fov: 20.0 },
        meshes: vec![quad(
            [
                Vec3::new(-5.0, -5.0, 0.0),
                Vec3::new(5.0, -5.0, 0.0),
                Vec3::new(5.0, 5.0, 0.0),
                Vec3::new(-5.0, 5.0, 0.0),
            ],
            g,
        )],
        ..SceneDesc::default()
    };
    let s = RenderSettings { width: 3, height: 3, background: Vec3::ONE, gloss_samples: 16, ..Default::default() };
    let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
    let film = render(&scene, &s, &|_| {}).film;
    // Every lobe ray (those folded back above the surface too) sees the white surrounding.
    for c in film.pixels() {
        assert!((c - Vec3::splat(0.3)).abs().max_element() < 1e-6, "{c}");
    }
}

#[test]
fn gloss_converges_to_the_mirror_as_shininess_grows() {
    let s = RenderSettings { width: 24, height: 24, ..Default::default() };
    let img = |shininess: f32, gloss: u32| {
        let scene = Scene::from_desc(&mirror_scene(shininess), &LoadContext::default()).unwrap();
        render(&scene, &RenderSettings { gloss_samples: gloss, ..s.clone() }, &|_| {}).film.pixels()
    };
    let diff = |a: &[Color], b: &[Color]| {
        a.iter().zip(b).map(|(x, y)| (*x - *y).abs().max_element()).sum::<f32>() / a.len() as f32
    };
    let errs: Vec<f32> = [10.0, 100.0, 1000.0, 1e6].iter().map(|&n| diff(&img(n, 16), &img(n, 0))).collect();
    assert!(errs.windows(2).all(|w| w[1] < w[0]), "{errs:?}");
    assert!(errs[3] < 2e-3, "{errs:?}");
    // A material with infinite glossiness stays a perfect mirror with gloss sampling on.
    let mut d = mirror_scene(10.0);
    d.meshes[0].material.as_mut().unwrap().glossiness = Some(f32::INFINITY);
    let scene = Scene::from_desc(&d, &LoadContext::default()).unwrap();
    let g = render(&scene, &RenderSettings { gloss_samples: 16, ..s.clone() }, &|_| {}).film.pixels();
    assert_eq!(g, img(10.0, 0));
}

fn moving_sphere(end_x: f32) -> SceneDesc {
    SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -10.0), target: Vec3::ZERO, up: Vec3::Y, fov: 20.0 },
        spheres: vec![SphereDesc {
            center: Vec3::new(-1.0, 0.0, 0.0),
            radius: 0.2,
            material: white(),
            motion: Some(MotionDesc::Linear { start: Vec3::ZERO, end: Vec3::new(end_x, 0.0, 0.0) }),
        }],
        ..SceneDesc::default()
    }
}

#[test]
fn moving_sphere_leaves_a_smear_along_its_path() {
    let s = RenderSettings { width: 64, height: 9, shading: false, spp: 64, ..Default::default() };
    let row = |desc: &SceneDesc| {
        let scene = Scene::from_desc(desc, &LoadContext::default()).unwrap();
        let f = render(&scene, &s, &|_| {}).film;
        (0..s.width).map(|x| f.get(x, 4).x).collect::<Vec<f32>>()
    };
    // Screen column of world x on the plane z = 0: x_ndc = -x / (10 tan(10 deg) * aspect).
    let half_w = 10.0 * 10f32.to_radians().tan() * (64.0 / 9.0);
    let col = |x: f32| ((-x / half_w + 1.0) / 2.0 * 64.0) as i32;
    let lit = |r: &[f32]| {
        let c: Vec<i32> = r.iter().enumerate().filter(|(_, v)| **v > 0.0).map(|(i, _)| i as i32).collect();
        (*c.first().unwrap(), *c.last().unwrap())
    };
    let moving = row(&moving_sphere(2.0));
    let (lo, hi) = lit(&moving);
    // The path runs from x = -1.2 to x = 1.2 (screen right is world -x).
    assert!((lo - col(1.2)).abs() <= 1 && (hi - col(-1.2)).abs() <= 1, "{lo}..{hi} vs {}..{}", col(1.2), col(-1.2));
    // Along the path the sphere spends equal time everywhere: the middle is a dim, even smear.
    let mid = moving[col(0.0) as usize];
    assert!(mid > 0.05 && mid < 0.35, "{mid}");
    // No motion gives exactly the still image.
    let still = SceneDesc {
        spheres: vec![SphereDesc { motion: None, ..moving_sphere(0.0).spheres[0].clone() }],
        ..moving_sphere(0.0)
    };
    assert_eq!(row(&moving_sphere(0.0)), row(&still));
}

#[test]
fn moving_camera_blurs_and_a_still_one_does_not() {
    let base = rayscope::scene::builtin::scene_desc("cornell-box").unwrap();
    let s = RenderSettings { width: 32, height: 32, spp: 16, ..Default::default() };
    let img = |end: Option<CameraDesc>| {
        let mut d = base.clone();
        d.camera_end = end;
        let scene = Scene::from_desc(&d, &LoadContext::default()).unwrap();
        render(&scene, &s, &|_| {}).film.pixels()
    };
    assert_eq!(img(None), img(Some(base.camera.clone())));
    let moved =
        CameraDesc::Trackball { look_at: Vec3::ZERO, distance: 3.0, rotation: Vec3::new(20.0, 50.0, 0.0), fov: 50.0 };
    assert_ne!(img(None), img(Some(moved)));
}

fn soft_scene() -> Scene {
    let d = rayscope::scene::builtin::scene_desc("cornell-box-sphere-light").unwrap();
    Scene::from_desc(&d, &LoadContext::default()).unwrap()
}

fn soft_settings() -> RenderSettings {
    RenderSettings { width: 40, height: 40, spp: 4, light_samples: 4, gloss_samples: 3, ..Default::default() }
}

#[test]
fn images_do_not_depend_on_threads() {
    let scene = soft_scene();
    let s = soft_settings();
    let with = |t: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
        pool.install(|| render(&scene, &s, &|_| {})).film
    };
    assert_eq!(with(1), with(2));
    assert_eq!(with(2), with(3));
}

#[test]
fn progressive_equals_one_shot_and_survives_stop_and_resume() {
    let scene = soft_scene();
    // Tall enough for many bands of rows, so that stopping after the first band leaves some
    // unrendered whatever the threads do meanwhile.
    let s = RenderSettings { height: 200, ..soft_settings() };
    let target = 8;
    let one_shot = render(&scene, &RenderSettings { spp: target, ..s.clone() }, &|_| {}).film;
    let camera = scene.camera_motion();
    let never = AtomicBool::new(false);
    let frames = RenderSettings { spp: 2, ..s.clone() };
    let mut p = Progressive::new(frames.clone(), ImagingMode::Dynamic, Some(target));
    while !p.is_done() {
        p.render_frame(&scene, &camera, &never, &|_| {});
    }
    assert_eq!(p.frames(), 4);
    assert_eq!(p.film(), &one_shot, "frames of 2 samples add up to the 8-sample render, bit for bit");
    // Interrupted half-way through a frame, then resumed: the same film.
    let mut q = Progressive::new(frames, ImagingMode::Dynamic, Some(target));
    q.render_frame(&scene, &camera, &never, &|_| {});
    let stop = AtomicBool::new(false);
    let info = q.render_frame(&scene, &camera, &stop, &|_| stop.store(true, Ordering::Relaxed));
    assert!(!info.complete);
    let (lo, hi) = q.film().sample_range();
    assert!(lo < hi, "the interrupted frame reached some pixels only");
    while !q.is_done() {
        q.render_frame(&scene, &camera, &never, &|_| {});
    }
    assert_eq!(q.film(), &one_shot);
}

#[test]
fn imaging_modes() {
    let scene = soft_scene();
    let s = RenderSettings { width: 16, height: 16, spp: 1, light_samples: 2, ..Default::default() };
    let never = AtomicBool::new(false);
    let cam = scene.camera_motion();
    // Continuous: each frame replaces the last, with fresh samples.
    let mut c = Progressive::new(s.clone(), ImagingMode::Continuous, None);
    c.render_frame(&scene, &cam, &never, &|_| {});
    let first = c.film().clone();
    c.render_frame(&scene, &cam, &never, &|_| {});
    assert_eq!(c.film().sample_range(), (1, 1));
    assert_ne!(c.film(), &first);
    // Dynamic: accumulates; a camera change restarts.
    let mut d = Progressive::new(s.clone(), ImagingMode::Dynamic, None);
    d.render_frame(&scene, &cam, &never, &|_| {});
    d.render_frame(&scene, &cam, &never, &|_| {});
    assert_eq!(d.film().sample_range(), (2, 2));
    let mut moved = cam.clone();
    moved.start.position += Vec3A::X * 0.1;
    d.render_frame(&scene, &moved, &never, &|_| {});
    assert_eq!(d.film().sample_range(), (1, 1));
    // A restart after one frame zeroes that frame's film in place (`Film::clear`): the same
    // film as a new render's, bit for bit.
    let mut r = Progressive::new(s.clone(), ImagingMode::Dynamic, None);
    r.render_frame(&scene, &cam, &never, &|_| {});
    r.render_frame(&scene, &moved, &never, &|_| {});
    let mut fresh = Progressive::new(s.clone(), ImagingMode::Dynamic, None);
    fresh.render_frame(&scene, &moved, &never, &|_| {});
    assert_eq!(r.film(), fresh.film());
    // A settings change restarts too.
    d.set_settings(RenderSettings { light_samples: 3, ..s.clone() });
    assert_eq!(d.film().sample_range(), (0, 0));
    // Exposure: a fixed number of frames; camera moves during it are kept (blur).
    let mut e = Progressive::new(s.clone(), ImagingMode::Exposure { frames: 3 }, None);
    e.render_frame(&scene, &cam, &never, &|_| {});
    e.render_frame(&scene, &moved, &never, &|_| {});
    assert!(!e.is_done());
    e.render_frame(&scene, &cam, &never, &|_| {});
    assert!(e.is_done());
    assert_eq!(e.film().sample_range(), (3, 3));
}
