//! Every shading model against its closed form on an analytic scene (a sphere under a point
//! light: the hit point, normal, light and view directions computed here from the camera ray
//! and the sphere's equation), the models' relations, the scene-wide default against the
//! material's own model, the explanation naming the model, and bad scene files.

use std::path::Path;

use rayscope::camera::{Camera, CameraDesc, CameraMotion};
use rayscope::debug::{SampleChoice, trace_pixel_samples};
use rayscope::gradient::{Gradient, GradientKey};
use rayscope::light::Light;
use rayscope::material::MaterialDesc;
use rayscope::math::{Color, Vec3};
use rayscope::render::render;
use rayscope::scene::{LoadContext, Scene, SceneDesc, SphereDesc};
use rayscope::settings::{RenderSettings, ShadingModel};

const SIZE: u32 = 24;
const KD: Vec3 = Vec3::new(0.7, 0.4, 0.2);
const KS: Vec3 = Vec3::new(0.5, 0.5, 0.5);
const SHININESS: f32 = 12.0;
const LIGHT_COLOR: Vec3 = Vec3::new(1.0, 0.9, 0.8);
const RADIUS: f32 = 1.0;
/// Pixels on the sphere: its middle, its lit side, its rim, its dark side.
const PIXELS: [[u32; 2]; 5] = [[12, 12], [14, 9], [16, 8], [9, 15], [11, 13]];

fn camera() -> CameraDesc {
    CameraDesc::LookAt { eye: Vec3::new(0.0, 0.0, -4.0), target: Vec3::ZERO, up: Vec3::Y, fov: 40.0 }
}

/// The toon gradient of the tests: dark to 0.3, a step to mid at 0.3, a ramp to light.
fn toon() -> Vec<GradientKey> {
    let key = |at, c: [f32; 3]| GradientKey { at, color: Color::from(c) };
    vec![key(0.0, [0.05, 0.05, 0.1]), key(0.3, [0.1, 0.1, 0.2]), key(0.3, [0.4, 0.3, 0.2]), key(1.0, [0.9, 0.7, 0.5])]
}

fn sphere_scene(model: Option<ShadingModel>, gradient: Option<Vec<GradientKey>>, light: Vec3) -> SceneDesc {
    SceneDesc {
        camera: camera(),
        spheres: vec![SphereDesc {
            center: Vec3::ZERO,
            radius: RADIUS,
            material: MaterialDesc {
                kd: Some(KD),
                ks: Some(KS),
                shininess: Some(SHININESS),
                model,
                gradient,
                ..Default::default()
            },
            motion: None,
        }],
        lights: vec![Light::Point { position: light, color: LIGHT_COLOR }],
        ..SceneDesc::default()
    }
}

/// No mirror reflection (it would leave into the black background anyway, but the closed
/// forms below are the direct light alone).
fn settings(model: ShadingModel) -> RenderSettings {
    RenderSettings { width: SIZE, height: SIZE, reflections: false, shading_model: model, ..Default::default() }
}

fn film(desc: &SceneDesc, s: &RenderSettings) -> Vec<Color> {
    let scene = Scene::from_desc(desc, &LoadContext::default()).unwrap();
    render(&scene, s, &|_| {}).film.pixels()
}

/// The geometry at pixel `(x, y)` by hand: the camera ray met with the sphere `|p| = r`.
struct Geometry {
    n: Vec3,
    l: Vec3,
    v: Vec3,
}

fn geometry(x: u32, y: u32, light: Vec3) -> Geometry {
    let ray = Camera::from_desc(&camera()).pixel_ray(x, y, SIZE, SIZE);
    let (o, d) = (Vec3::from(ray.origin), Vec3::from(ray.dir).normalize());
    // |o + t d|^2 = r^2: t^2 + 2 (o.d) t + |o|^2 - r^2 = 0, the nearer root.
    let b = o.dot(d);
    let disc = b * b - (o.length_squared() - RADIUS * RADIUS);
    assert!(disc > 0.0, "pixel ({x}, {y}) misses the sphere");
    let p = o + (-b - disc.sqrt()) * d;
    Geometry { n: p.normalize(), l: (light - p).normalize(), v: -d }
}

/// The closed form of each model at one point.
fn closed_form(model: ShadingModel, g: &Geometry, gradient: Option<&Gradient>) -> Vec3 {
    let cos = g.n.dot(g.l);
    if cos <= 0.0 {
        return Vec3::ZERO;
    }
    let r = 2.0 * cos * g.n - g.l;
    let h = (g.l + g.v).normalize();
    let highlight = |c: f32| KS * c.max(0.0).powf(SHININESS);
    let phong = KD * cos + highlight(r.dot(g.v));
    let shaded = match model {
        ShadingModel::Phong => phong,
        ShadingModel::BlinnPhong => KD * cos + highlight(g.n.dot(h)),
        ShadingModel::Lambert => KD * cos,
        ShadingModel::Gradient => gradient.map_or(KD * cos, |gr| gr.at(cos)) + highlight(r.dot(g.v)),
    };
    LIGHT_COLOR * shaded
}

fn close(a: Color, b: Vec3, what: &str) {
    assert!((a - b).abs().max_element() < 2e-4, "{what}: rendered {a}, closed form {b}");
}

const LIGHT: Vec3 = Vec3::new(2.0, 3.0, -4.0);

#[test]
fn every_model_matches_its_closed_form_on_a_lit_sphere() {
    let gradient = Gradient::new(toon()).unwrap();
    let lit = PIXELS.iter().filter(|[x, y]| geometry(*x, *y, LIGHT).n.dot(geometry(*x, *y, LIGHT).l) > 0.0).count();
    assert!(lit >= 4, "the pixels should be mostly lit: {lit}");
    for model in ShadingModel::ALL {
        let keys = (model == ShadingModel::Gradient).then(toon);
        // Once as the scene-wide default, once as the material's own model.
        let images = [
            film(&sphere_scene(None, keys.clone(), LIGHT), &settings(model)),
            film(&sphere_scene(Some(model), keys, LIGHT), &settings(ShadingModel::Phong)),
        ];
        for image in &images {
            for [x, y] in PIXELS {
                let want = closed_form(model, &geometry(x, y, LIGHT), Some(&gradient));
                close(image[(y * SIZE + x) as usize], want, &format!("{} at ({x}, {y})", model.name()));
            }
        }
        assert_eq!(images[0], images[1], "{}: the material's model and the scene-wide one differ", model.name());
    }
}

#[test]
fn the_materials_own_model_wins_over_the_scene_wide_one() {
    let lambert = film(&sphere_scene(Some(ShadingModel::Lambert), None, LIGHT), &settings(ShadingModel::BlinnPhong));
    let plain = film(&sphere_scene(None, None, LIGHT), &settings(ShadingModel::Lambert));
    assert_eq!(lambert, plain);
}

#[test]
fn blinn_phong_equals_phong_at_the_mirror_direction() {
    // A light placed along the view direction's mirror image about the normal at pixel
    // (14, 9): there r = v and h = n, so both highlights are ks x 1.
    let [x, y] = [14, 9];
    let at = geometry(x, y, LIGHT);
    let p = at.n * RADIUS;
    let mirror = 2.0 * at.n.dot(at.v) * at.n - at.v;
    let light = p + 3.0 * mirror;
    let g = geometry(x, y, light);
    let pixel = |model| film(&sphere_scene(None, None, light), &settings(model))[(y * SIZE + x) as usize];
    let (phong, blinn) = (pixel(ShadingModel::Phong), pixel(ShadingModel::BlinnPhong));
    close(phong, LIGHT_COLOR * (KD * g.n.dot(g.l) + KS), "phong at the mirror direction");
    close(blinn, LIGHT_COLOR * (KD * g.n.dot(g.l) + KS), "blinn-phong at the mirror direction");
    // Away from it Blinn-Phong's highlight is the wider: at least Phong's everywhere here.
    let (p, b) = (film(&sphere_scene(None, None, LIGHT), &settings(ShadingModel::Phong)), {
        film(&sphere_scene(None, None, LIGHT), &settings(ShadingModel::BlinnPhong))
    });
    assert!(p.iter().zip(&b).all(|(p, b)| b.cmpge(*p - 1e-6).all()));
}

#[test]
fn gradient_without_keys_is_phong_bit_for_bit() {
    // The ramp from black to kd read at n.l is kd (n.l): Phong's diffuse term, same arithmetic.
    let phong = film(&sphere_scene(None, None, LIGHT), &settings(ShadingModel::Phong));
    let gradient = film(&sphere_scene(None, None, LIGHT), &settings(ShadingModel::Gradient));
    assert_eq!(phong, gradient);
}

#[test]
fn the_explanation_names_the_model_and_sums_to_the_pixel() {
    for model in ShadingModel::ALL {
        let keys = (model == ShadingModel::Gradient).then(toon);
        let scene = Scene::from_desc(&sphere_scene(Some(model), keys, LIGHT), &LoadContext::default()).unwrap();
        let s = settings(ShadingModel::Phong);
        let cam = CameraMotion::still(Camera::from_desc(&scene.camera));
        let trace = trace_pixel_samples(&scene, &s, &cam, 14, 9, SampleChoice::All, 1000);
        let e = trace.explain();
        let terms: Vec<_> = e.terms.iter().filter(|t| t.lights.is_some()).collect();
        assert!(terms.iter().all(|t| t.model == Some(model)), "{}", model.name());
        // Lambert has no highlight term.
        assert_eq!(terms.len(), if model == ShadingModel::Lambert { 1 } else { 2 }, "{}", model.name());
        assert!((e.sum - e.value).abs().max_element() < 1e-6);
        let text = e.to_string();
        assert!(text.contains(&format!("{}: ", model.name())), "{text}");
        if model == ShadingModel::Gradient {
            assert!(text.contains("gradient ("), "{text}");
        }
    }
}

#[test]
fn scene_files_save_and_read_models_and_gradients() {
    let desc = sphere_scene(Some(ShadingModel::Gradient), Some(toon()), LIGHT);
    let text = desc.to_toml();
    assert!(text.contains("model = \"gradient\""), "{text}");
    let back = SceneDesc::from_toml(&text, Path::new("saved.toml")).unwrap();
    assert_eq!(back.spheres[0].material, desc.spheres[0].material);
}

/// A scene file with one sphere whose material line is `material`.
fn with_material(material: &str) -> String {
    format!(
        "[camera]\nkind = \"look-at\"\neye = [0, 0, -4]\ntarget = [0, 0, 0]\nup = [0, 1, 0]\nfov = 40\n\n\
         [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = {material}\n"
    )
}

#[test]
fn bad_models_and_gradients_name_the_file_and_line() {
    let cases = [
        ("{ model = \"toon\" }", "toon"),
        ("{ gradient = [[0.5, [1, 1, 1]], [0.2, [0, 0, 0]]] }", "key 2"),
        ("{ gradient = [[1.5, [1, 1, 1]]] }", "not in [0, 1]"),
        ("{ gradient = [] }", "at least one key"),
        ("{ gradient = [[nan, [1, 1, 1]]] }", "key 1"),
        ("{ gradient = [[0.5, [nan, 1, 1]]] }", "finite"),
        ("{ gradient = [[0.5, [-1, 1, 1]]] }", "not negative"),
    ];
    for (material, says) in cases {
        let err = SceneDesc::from_toml(&with_material(material), Path::new("bad.toml")).unwrap_err().to_string();
        assert!(err.contains("bad.toml") && err.contains(":11") && err.contains(says), "{material}: {err}");
    }
}
