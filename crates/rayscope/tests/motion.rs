//! Motion along paths: the blur of a closed path is symmetric, two keys are today's linear
//! motion bit for bit, the BVH bounds every moving primitive over its whole path, a camera on
//! a path is the static camera where the path is, and bad keyframes are errors at their line.

use std::path::Path;

use proptest::prelude::*;
use rayscope::Error;
use rayscope::animation::{AnimationSettings, Shutter};
use rayscope::camera::{Camera, CameraDesc, CameraMotion};
use rayscope::debug::{SampleChoice, trace_pixel_samples};
use rayscope::material::MaterialDesc;
use rayscope::math::{Vec3, Vec3A};
use rayscope::motion::{Interpolation, Keyframe, MotionPath};
use rayscope::ray::Ray;
use rayscope::render::render;
use rayscope::scene::desc::MotionDesc;
use rayscope::scene::{LoadContext, MeshDesc, Scene, SceneDesc, SphereDesc};
use rayscope::settings::RenderSettings;

fn white() -> MaterialDesc {
    MaterialDesc { kd: Some(Vec3::ONE), ..MaterialDesc::default() }
}

/// A sphere of radius 0.2 at the origin moved by `motion`, seen head-on from (0, 0, -10)
/// along +z, up +y: image rows `y` and `h - 1 - y` are mirror images in the plane y = 0.
fn sphere_scene(motion: Option<MotionDesc>) -> SceneDesc {
    SceneDesc {
        camera: CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -10.0), target: Vec3::ZERO, up: Vec3::Y, fov: 20.0 },
        spheres: vec![SphereDesc { center: Vec3::ZERO, radius: 0.2, material: white(), motion }],
        ..SceneDesc::default()
    }
}

fn image(desc: &SceneDesc, s: &RenderSettings) -> Vec<f32> {
    let scene = Scene::from_desc(desc, &LoadContext::default()).unwrap();
    let film = render(&scene, s, &|_| {}).film;
    (0..s.height).flat_map(|y| (0..s.width).map(move |x| (x, y))).map(|(x, y)| film.get(x, y).x).collect()
}

/// Keys on a circle of radius 0.8 in the plane z = 0, at angles `2 pi i / 8` (closed: the
/// last is the first), reached at `times[i]`.
fn circle(times: [f32; 9]) -> MotionDesc {
    let keys = times
        .iter()
        .enumerate()
        .map(|(i, &time)| {
            let a = std::f32::consts::TAU * i as f32 / 8.0;
            Keyframe { time, translation: Vec3::new(0.8 * a.cos(), 0.8 * a.sin(), 0.0) }
        })
        .collect();
    MotionDesc::Keys { keys, interpolation: Interpolation::CatmullRom }
}

/// The image's departure from its mirror image in y = 0, against what noise allows.
///
/// With shading off a pixel's value is `v = (1/N) sum_k hit_k`, an unbiased estimate of the
/// fraction `c` of the pixel's area x shutter time in which the sphere covers it. Mirroring
/// in y = 0 maps the circle's key at angle `a` and time `t` to the key at `-a` and time
/// `1 - t`; reversing time maps the Catmull-Rom spline of the keys onto itself (the tangents
/// are differences of the keys, the end tangents one-sided differences, all of which reverse
/// with time), and shutter times are uniform on [0, 1), so `c` of a pixel equals `c` of its
/// mirror (up to float rounding of the path, far below a pixel). The difference `d = v - v'`
/// of a pixel and its mirror therefore has mean 0 and variance at most
/// `Var v + Var v' <= 2 c (1 - c) / (N - 1)` (the pixels' random numbers are independent
/// hashes; each `v` is a mean of `N` samples whose strata, jittered pixel offsets and
/// stratified times, make it no worse than `N - 1` independent draws of a Bernoulli(c)).
/// Returned: `D`, the sum of `d` over the upper half (the difference of the two halves'
/// light), `Q = sum over columns of D_x^2` (`D_x`: that sum within column `x`), and their
/// common expectation bound `E = sum 2 c (1 - c) / (N - 1)` over the pairs (`c` estimated by
/// the pair's mean): `Var D <= E` and `E[Q] <= E`.
fn asymmetry(img: &[f32], w: usize, h: usize, n: u32) -> (f64, f64, f64) {
    let (mut d, mut q, mut e) = (0.0f64, 0.0f64, 0.0f64);
    for x in 0..w {
        let mut column = 0.0f64;
        for y in 0..h / 2 {
            let (v, m) = (img[y * w + x] as f64, img[(h - 1 - y) * w + x] as f64);
            column += v - m;
            let c = (v + m) / 2.0;
            e += 2.0 * c * (1.0 - c) / (n as f64 - 1.0);
        }
        d += column;
        q += column * column;
    }
    (d, q, e)
}

#[test]
fn the_blur_of_a_closed_symmetric_path_is_symmetric() {
    let (w, h, n) = (64, 64, 81);
    let s = RenderSettings { width: w, height: h, spp: n, shading: false, ..Default::default() };
    let even = std::array::from_fn(|i| i as f32 / 8.0);
    let img = image(&sphere_scene(Some(circle(even))), &s);
    let partial = img.iter().filter(|v| **v > 0.0 && **v < 1.0).count();
    assert!(partial > 300, "the smear should cover many pixels partly: {partial}");
    // D is a sum of hundreds of independent terms of mean 0 (nearly normal): 4 standard
    // deviations. Q, a sum of 64 squared column sums of mean E in all, concentrates near its
    // mean: twice it.
    let (d, q, e) = asymmetry(&img, w as usize, h as usize, n);
    assert!(d.abs() <= 4.0 * e.sqrt(), "symmetric path: the halves differ by {d}, bound {}", 4.0 * e.sqrt());
    assert!(q <= 2.0 * e, "symmetric path: sum of squared column differences {q} above twice its bound {e}");
    // The control: the same circle, but the upper half (y > 0) takes 0.7 of the exposure.
    let slow_top =
        std::array::from_fn(|i| if i <= 4 { 0.7 * i as f32 / 4.0 } else { 0.7 + 0.3 * (i - 4) as f32 / 4.0 });
    let img = image(&sphere_scene(Some(circle(slow_top))), &s);
    let (d, q, e) = asymmetry(&img, w as usize, h as usize, n);
    assert!(d.abs() > 4.0 * e.sqrt() && q > 2.0 * e, "an asymmetric motion must fail the test: {d}, {q} vs {e}");
}

#[test]
fn two_keys_give_todays_linear_motion_bit_for_bit() {
    let (start, end) = (Vec3::new(-0.3, 0.1, 0.0), Vec3::new(0.5, -0.2, 0.3));
    let s = RenderSettings { width: 48, height: 48, spp: 16, ..Default::default() };
    // A sphere and a mesh (the Cornell box's tall block), moving.
    let scenes = |motion: MotionDesc| {
        let mut box_scene = rayscope::scene::builtin::scene_desc("cornell-box").unwrap();
        box_scene.meshes.push(MeshDesc {
            vertices: Some(vec![Vec3::new(-0.2, -0.2, 0.0), Vec3::new(0.2, -0.2, 0.0), Vec3::new(0.0, 0.2, 0.1)]),
            faces: Some(vec![[0, 1, 2]]),
            material: Some(white()),
            motion: Some(motion.clone()),
            ..MeshDesc::default()
        });
        [sphere_scene(Some(motion)), box_scene]
    };
    let linear = scenes(MotionDesc::Linear { start, end });
    for interpolation in Interpolation::ALL {
        let keys = vec![Keyframe { time: 0.0, translation: start }, Keyframe { time: 1.0, translation: end }];
        let keyed = scenes(MotionDesc::Keys { keys, interpolation });
        for (a, b) in linear.iter().zip(&keyed) {
            assert_eq!(image(a, &s), image(b, &s), "{interpolation:?}");
        }
    }
}

#[test]
fn a_camera_on_a_path_is_the_static_camera_where_the_path_is() {
    let base = rayscope::scene::builtin::scene_desc("cornell-box").unwrap();
    let start = Camera::from_desc(&base.camera);
    let keys = vec![
        Keyframe { time: 0.0, translation: Vec3::ZERO },
        Keyframe { time: 0.4, translation: Vec3::new(0.2, 0.1, 0.0) },
        Keyframe { time: 1.0, translation: Vec3::new(-0.1, 0.3, 0.2) },
    ];
    for interpolation in Interpolation::ALL {
        let path = MotionPath::new(keys.clone(), interpolation).unwrap();
        let motion = CameraMotion { path: Some(path), ..CameraMotion::still(start) };
        for k in &keys {
            let still = Camera { position: start.position + Vec3A::from(k.translation), ..start };
            assert_eq!(motion.at(k.time), still, "{interpolation:?} at key {}", k.time);
        }
    }
    // A path that holds still renders exactly the static camera there, though its rays are
    // made per sample (a moving camera's) and the static camera's in packets.
    let s = RenderSettings { width: 40, height: 40, spp: 4, ..Default::default() };
    let at = Vec3::new(0.1, -0.05, 0.2);
    let mut on_path = base.clone();
    let keys = vec![Keyframe { time: 0.0, translation: at }, Keyframe { time: 0.7, translation: at }];
    on_path.camera_motion = Some(MotionDesc::Keys { keys, interpolation: Interpolation::CatmullRom });
    let mut moved = base.clone();
    let CameraDesc::Trackball { look_at, distance, rotation, fov } = base.camera else { unreachable!() };
    moved.camera = CameraDesc::Trackball { look_at: look_at + at, distance, rotation, fov };
    assert_eq!(image(&on_path, &s), image(&moved, &s));
}

#[test]
fn each_debugged_sample_carries_its_shutter_time() {
    let keys = vec![
        Keyframe { time: 0.0, translation: Vec3::new(-0.5, 0.0, 0.0) },
        Keyframe { time: 0.5, translation: Vec3::new(0.0, 0.4, 0.0) },
        Keyframe { time: 1.0, translation: Vec3::new(0.5, 0.0, 0.0) },
    ];
    let desc = sphere_scene(Some(MotionDesc::Keys { keys, interpolation: Interpolation::CatmullRom }));
    let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
    let s = RenderSettings { width: 32, height: 32, spp: 9, ..Default::default() };
    let trace = trace_pixel_samples(&scene, &s, &scene.camera_motion(), 16, 14, SampleChoice::All, 10_000);
    let mut times: Vec<f32> = trace.samples.iter().map(|t| t.time).collect();
    for sample in &trace.samples {
        let camera_ray = &sample.tree.rays[0];
        let traversal = camera_ray.traversal.as_ref().expect("the camera ray's traversal is recorded");
        assert_eq!(traversal.time, sample.time, "sample {}", sample.index);
        assert!((0.0..1.0).contains(&sample.time));
    }
    // Nine stratified times: one in each ninth of the shutter.
    times.sort_by(f32::total_cmp);
    for (i, t) in times.iter().enumerate() {
        assert!((*t * 9.0).floor() as usize == i, "{times:?}");
    }
}

/// A path of 2 to 6 keys at increasing times in [0, 1], translations in [-2, 2]^3.
fn path() -> impl Strategy<Value = MotionPath> {
    (prop::collection::vec((0.01f32..1.0, prop::array::uniform3(-2.0f32..2.0)), 2..7), any::<bool>()).prop_map(
        |(steps, cr)| {
            let total: f32 = steps.iter().map(|(d, _)| d).sum();
            let mut t = 0.0;
            let keys = steps
                .iter()
                .map(|(d, p)| {
                    let k = Keyframe { time: (t / total).min(1.0), translation: Vec3::from_array(*p) };
                    t += d;
                    k
                })
                .collect();
            let interpolation = if cr { Interpolation::CatmullRom } else { Interpolation::Linear };
            MotionPath::new(keys, interpolation).unwrap()
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    /// The BVH's box of each moving primitive holds the primitive at every time, and the
    /// path's bound holds the path: at 512 times and at every key, for a sphere and a
    /// triangle moved along a random path; and a ray aimed at the sphere's centre at a random
    /// time hits it there, through the scene's BVH.
    #[test]
    fn the_bvh_bounds_each_moving_primitive_over_its_path(path in path(), times in prop::collection::vec(0.0f32..1.0, 8)) {
        let pb = path.bounds();
        for t in (0..=512).map(|i| i as f32 / 512.0).chain(path.keys().iter().map(|k| k.time)) {
            let p = path.at(t);
            prop_assert!(p.cmpge(pb.min).all() && p.cmple(pb.max).all(), "{p} outside {pb:?} at {t}");
        }
        let keys = path.keys().to_vec();
        let motion = MotionDesc::Keys { keys, interpolation: path.interpolation() };
        let tri = [Vec3::new(-0.2, -0.2, 0.0), Vec3::new(0.2, -0.2, 0.0), Vec3::new(0.0, 0.2, 0.1)];
        let desc = SceneDesc {
            meshes: vec![MeshDesc {
                vertices: Some(tri.to_vec()),
                faces: Some(vec![[0, 1, 2]]),
                motion: Some(motion.clone()),
                ..MeshDesc::default()
            }],
            spheres: vec![SphereDesc { center: Vec3::new(0.3, 0.0, 0.0), radius: 0.1, material: white(), motion: Some(motion) }],
            ..SceneDesc::default()
        };
        let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
        let g = &scene.geometry;
        for (slot, shape) in g.shapes().enumerate() {
            let bound = g.shape_bounds(&shape);
            let prim = scene.prim(g.prim_id(slot as u32));
            for t in (0..=512).map(|i| i as f32 / 512.0) {
                let offset = path.at(t);
                let at_t = match prim {
                    rayscope::scene::PrimRef::Triangle { .. } => rayscope::geometry::Aabb::from_points(tri.iter().map(|v| Vec3A::from(*v) + offset)),
                    rayscope::scene::PrimRef::Sphere(_) => {
                        let c = Vec3A::new(0.3, 0.0, 0.0) + offset;
                        rayscope::geometry::Aabb { min: c - 0.1, max: c + 0.1 }
                    }
                };
                prop_assert!(bound.contains(&at_t), "{prim:?} at {t}: {at_t:?} outside {bound:?}");
            }
        }
        for &t in &times {
            let c = Vec3A::new(0.3, 0.0, 0.0) + path.at(t);
            let origin = c + Vec3A::new(0.0, 0.0, -5.0);
            let ray = Ray { time: t, ..Ray::new(origin, Vec3A::Z) };
            let hit = scene.intersect(&ray);
            // The triangle may be in front; the sphere is hit at 4.9 unless it is.
            let t_hit = hit.map(|h| h.t);
            prop_assert!(t_hit.is_some_and(|d| d <= 4.9 + 1e-3), "ray at {t} missed: {t_hit:?}");
        }
    }
}

/// A path's keys stretched from `[0, 1]` over `[0, seconds]` (an animation's timeline).
fn stretched(path: &MotionPath, seconds: f32) -> MotionPath {
    let keys = path.keys().iter().map(|k| Keyframe { time: k.time * seconds, ..*k }).collect();
    MotionPath::new(keys, path.interpolation()).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, failure_persistence: None, ..ProptestConfig::default() })]

    /// A frame's bound holds the path at every scene time the frame exposes (and the moving
    /// sphere's box in the tree built for the frame holds the sphere then, and a ray at its
    /// centre hits it), it lies inside the whole path's bound, and a still's shutter over
    /// keys in [0, 1] gets the whole path's bound itself.
    #[test]
    fn a_frames_bound_holds_the_path_over_the_frame(
        path in path(),
        seconds in 0.5f32..20.0,
        frame in 0u32..400,
        fps in 1.0f64..60.0,
        shutter in 0.0f64..=1.0,
    ) {
        prop_assert_eq!(path.bounds_over(Shutter::STILL), path.bounds());
        let long = stretched(&path, seconds);
        let s = AnimationSettings { fps, shutter, frames: None }.shutter_of(frame);
        let b = long.bounds_over(s);
        let whole = long.bounds();
        let slack = 1e-4;
        prop_assert!(b.min.cmpge(whole.min - slack).all() && b.max.cmple(whole.max + slack).all(), "{b:?} not in {whole:?}");
        for i in 0..=256 {
            let t = s.time(i as f32 / 256.0 * (1.0 - f32::EPSILON));
            let p = long.at(t);
            prop_assert!(p.cmpge(b.min).all() && p.cmple(b.max).all(), "{p} outside {b:?} at {t} of {s:?}");
        }
        let keys = long.keys().to_vec();
        let motion = MotionDesc::Keys { keys, interpolation: long.interpolation() };
        let desc = SceneDesc {
            spheres: vec![SphereDesc { center: Vec3::new(0.3, 0.0, 0.0), radius: 0.1, material: white(), motion: Some(motion) }],
            ..SceneDesc::default()
        };
        let mut scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
        scene.set_shutter(s);
        let g = &scene.geometry;
        let bound = g.shape_bounds(&g.shape(0));
        for i in 0..=64 {
            let u = i as f32 / 64.0 * (1.0 - f32::EPSILON);
            let c = Vec3A::new(0.3, 0.0, 0.0) + long.at(s.time(u));
            let at_u = rayscope::geometry::Aabb { min: c - 0.1, max: c + 0.1 };
            prop_assert!(bound.contains(&at_u), "at {u}: {at_u:?} outside {bound:?}");
            let ray = Ray { time: u, ..Ray::new(c + Vec3A::new(0.0, 0.0, -5.0), Vec3A::Z) };
            let t_hit = scene.intersect(&ray).map(|h| h.t);
            prop_assert!(t_hit.is_some_and(|d| (d - 4.9).abs() < 1e-3), "ray at {u} missed: {t_hit:?}");
        }
    }
}

#[test]
fn a_late_frames_tree_is_tight_and_a_still_keeps_its_tree() {
    // A sphere crossing 20 units over 10 s: the tree of a frame bounds the frame's stretch
    // only (a few hundredths of a unit at 24 fps), not the whole crossing.
    let keys = vec![
        Keyframe { time: 0.0, translation: Vec3::new(-10.0, 0.0, 0.0) },
        Keyframe { time: 5.0, translation: Vec3::new(0.0, 1.0, 0.0) },
        Keyframe { time: 10.0, translation: Vec3::new(10.0, 0.0, 0.0) },
    ];
    let desc = sphere_scene(Some(MotionDesc::Keys { keys, interpolation: Interpolation::CatmullRom }));
    let mut scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
    let still_box = scene.geometry.shape_bounds(&scene.geometry.shape(0));
    let frame = AnimationSettings::default().shutter_of(100);
    scene.set_shutter(frame);
    let root = scene.geometry.shape_bounds(&scene.geometry.shape(0));
    let width = root.max.x - root.min.x;
    assert!(width < 0.4 + 0.1, "a frame's box is {width} wide");
    scene.set_shutter(Shutter::STILL);
    assert_eq!(scene.geometry.shape_bounds(&scene.geometry.shape(0)), still_box, "back to the still's box");
    assert_ne!(still_box, root);
    assert_eq!(scene.shutter(), Shutter::STILL);
}

#[test]
fn paths_are_exported_and_read_back() {
    let keys = vec![
        Keyframe { time: 0.0, translation: Vec3::new(0.0, 0.0, 0.0) },
        Keyframe { time: 0.25, translation: Vec3::new(0.5, 0.25, 0.0) },
        Keyframe { time: 1.0, translation: Vec3::new(1.0, 0.0, -0.5) },
    ];
    let mut d = sphere_scene(Some(MotionDesc::Keys { keys: keys.clone(), interpolation: Interpolation::Linear }));
    d.camera_motion = Some(MotionDesc::Keys { keys, interpolation: Interpolation::CatmullRom });
    let text = d.to_toml();
    assert!(text.contains("keys = [[0.0, [0.0, 0.0, 0.0]], [0.25, [0.5, 0.25, 0.0]]"), "{text}");
    assert!(text.contains("interpolation = \"linear\"") && text.contains("interpolation = \"catmull-rom\""), "{text}");
    assert_eq!(SceneDesc::from_toml(&text, Path::new("s.toml")).unwrap(), d);
    // Today's syntax is read and written as it was.
    let legacy = "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmotion = { start = [0, 0, 0], end = [1, 0, 0] }\n";
    let d = SceneDesc::from_toml(legacy, Path::new("s.toml")).unwrap();
    assert_eq!(d.spheres[0].motion, Some(MotionDesc::Linear { start: Vec3::ZERO, end: Vec3::X }));
    assert!(d.to_toml().contains("start = [0.0, 0.0, 0.0]"), "{}", d.to_toml());
    // The interpolation defaults to Catmull-Rom.
    let default = "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmotion = { keys = [[0, [0, 0, 0]], [1, [1, 0, 0]]] }\n";
    let d = SceneDesc::from_toml(default, Path::new("s.toml")).unwrap();
    assert!(matches!(d.spheres[0].motion, Some(MotionDesc::Keys { interpolation: Interpolation::CatmullRom, .. })));
}

#[test]
fn bad_keyframes_are_errors_naming_the_file_and_line() {
    let sphere =
        |motion: &str| format!("name = \"x\"\n\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmotion = {motion}\n");
    let cases = [
        (sphere("{ keys = [[0, [0, 0, 0]]] }"), 6, "at least two keyframes"),
        (sphere("{ keys = [[0, [0, 0, 0]], [0.6, [1, 0, 0]], [0.5, [1, 1, 0]]] }"), 6, "times must increase"),
        (sphere("{ keys = [[0, [0, 0, 0]], [0, [1, 0, 0]]] }"), 6, "times must increase"),
        // Key times are seconds of scene time, any finite increasing ones.
        (sphere("{ keys = [[0, [0, 0, 0]], [inf, [1, 0, 0]]] }"), 6, "finite"),
        (sphere("{ keys = [[1.5, [0, 0, 0]], [-0.1, [1, 0, 0]]] }"), 6, "increase"),
        (sphere("{ keys = [[0, [0, nan, 0]], [1, [1, 0, 0]]] }"), 6, "finite"),
        (sphere("{ keys = [[nan, [0, 0, 0]], [1, [1, 0, 0]]] }"), 6, "finite"),
        (
            sphere("{ keys = [[0, [0, 0, 0]], [1, [1, 0, 0]]], interpolation = \"cubic\" }"),
            6,
            "unknown variant `cubic`",
        ),
        (sphere("{ keys = [[0, [0, 0, 0]], [1, [1, 0, 0]]], end = [1, 0, 0] }"), 6, "not both"),
        (sphere("{ keys = [[0, [0, 0]], [1, [1, 0, 0]]] }"), 6, ""),
        (
            "[camera_end]\nrotation = [0, 0, 0]\n\n[camera_motion]\nkeys = [[0, [0, 0, 0]], [1, [1, 0, 0]]]\n"
                .to_string(),
            4,
            "not both",
        ),
        ("[camera_motion]\ninterpolation = \"linear\"\nkeys = [[0.5, [0, 0, 0]]]\n".to_string(), 3, "at least two"),
    ];
    for (text, line, want) in cases {
        match SceneDesc::from_toml(&text, Path::new("paths.toml")) {
            Err(e @ Error::Parse { .. }) => {
                let msg = e.to_string();
                assert!(msg.contains("paths.toml") && msg.contains(want), "{msg}\n{text}");
                let Error::Parse { line: got, .. } = e else { unreachable!() };
                assert_eq!(got, Some(line), "{msg}\n{text}");
            }
            other => panic!("{text}: {other:?}"),
        }
    }
}
