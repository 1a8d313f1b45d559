//! The course's scenes, built in. Those that need no file (the Cornell boxes, the cube, the
//! single triangle, the spheres) are generated here, reproducing the course's files exactly
//! (a test checks them against the files when the asset folder is present); the others name
//! course files in the asset folder.

use crate::animation::{AnimationSettings, FrameRange};
use crate::camera::CameraDesc;
use crate::error::{Error, Result};
use crate::gradient::GradientKey;
use crate::light::Light;
use crate::material::MaterialDesc;
use crate::math::{Vec2, Vec3};
use crate::settings::ShadingModel;

use super::desc::{MeshDesc, MotionDesc, SceneDesc, SphereDesc};
use crate::motion::{Interpolation, Keyframe};

/// A built-in scene: its name, a one-line description, and whether it needs the asset folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BuiltinInfo {
    /// The name to ask for.
    pub name: &'static str,
    /// What it shows.
    pub description: &'static str,
    /// Whether it reads course files from the asset folder.
    pub needs_assets: bool,
}

/// Every built-in scene, the default first.
pub const BUILTINS: &[BuiltinInfo] = &[
    BuiltinInfo {
        name: "cornell-box",
        description: "Cornell box with mirror, point light (0, 0.58, 0)",
        needs_assets: false,
    },
    BuiltinInfo {
        name: "cornell-box-sphere-light",
        description: "Cornell box, sphere light at (0, 0.45, 0), radius 0.1",
        needs_assets: false,
    },
    BuiltinInfo {
        name: "cornell-box-parallelogram-light",
        description: "Cornell box, red/green/blue/cyan parallelogram light",
        needs_assets: false,
    },
    BuiltinInfo { name: "single-triangle", description: "one triangle, point light (-1, 1, -1)", needs_assets: false },
    BuiltinInfo {
        name: "cube",
        description: "the course cube (translucent), point light (-1, 1, -1)",
        needs_assets: false,
    },
    BuiltinInfo {
        name: "cube-segment-light",
        description: "the course cube under a two-coloured segment light",
        needs_assets: false,
    },
    BuiltinInfo {
        name: "spheres",
        description: "three spheres, point light (3, 0, 3) of colour 15",
        needs_assets: false,
    },
    BuiltinInfo {
        name: "cornell-box-motion",
        description: "Cornell box, a sphere on a keyframed Catmull-Rom loop (motion blur with --spp; --frames: 24 at 24 fps)",
        needs_assets: false,
    },
    BuiltinInfo {
        name: "shading-models",
        description: "four spheres: phong, blinn-phong / lambert, gradient (toon), point light (2, 2.5, -3)",
        needs_assets: false,
    },
    BuiltinInfo { name: "monkey", description: "Suzanne (monkey-rotated.obj), two point lights", needs_assets: true },
    BuiltinInfo { name: "teapot", description: "textured Utah teapot (teapot.obj)", needs_assets: true },
    BuiltinInfo { name: "dragon", description: "100k-triangle Stanford dragon (dragon.obj)", needs_assets: true },
    BuiltinInfo {
        name: "cube-textured",
        description: "the 2022 textured cube (v2022/cube-textured.obj)",
        needs_assets: true,
    },
];

/// The scene rendered when none is named: the Cornell box, which needs no file.
pub const DEFAULT_SCENE: &str = "cornell-box";

fn point(x: f32, y: f32, z: f32) -> Light {
    Light::Point { position: Vec3::new(x, y, z), color: Vec3::ONE }
}

fn scene(name: &str, meshes: Vec<MeshDesc>, spheres: Vec<SphereDesc>, lights: Vec<Light>) -> SceneDesc {
    SceneDesc {
        name: Some(name.to_string()),
        camera: CameraDesc::default(),
        meshes,
        spheres,
        lights,
        ..SceneDesc::default()
    }
}

fn asset(path: &str) -> MeshDesc {
    MeshDesc { asset: Some(path.into()), normalize: true, ..MeshDesc::default() }
}

/// The description of built-in scene `name`.
pub fn scene_desc(name: &str) -> Result<SceneDesc> {
    let l = |x, y, z| Vec3::new(x, y, z);
    Ok(match name {
        "cornell-box" => scene(name, vec![cornell_box()], vec![], vec![point(0.0, 0.58, 0.0)]),
        "cornell-box-sphere-light" => scene(
            name,
            vec![cornell_box()],
            vec![],
            vec![Light::Sphere { center: l(0.0, 0.45, 0.0), radius: 0.1, color: Vec3::ONE }],
        ),
        "cornell-box-parallelogram-light" => scene(
            name,
            vec![cornell_box()],
            vec![],
            vec![Light::Parallelogram {
                v0: l(-0.2, 0.5, 0.0),
                edge01: l(0.4, 0.0, 0.0),
                edge02: l(0.0, 0.0, 0.4),
                color0: l(1.0, 0.0, 0.0),
                color1: l(0.0, 1.0, 0.0),
                color2: l(0.0, 0.0, 1.0),
                color3: l(0.0, 1.0, 1.0),
            }],
        ),
        "single-triangle" => scene(name, vec![single_triangle()], vec![], vec![point(-1.0, 1.0, -1.0)]),
        "cube" => scene(name, vec![cube()], vec![], vec![point(-1.0, 1.0, -1.0)]),
        "cube-segment-light" => scene(
            name,
            vec![cube()],
            vec![],
            vec![Light::Segment {
                endpoint0: l(1.5, 0.5, -0.6),
                endpoint1: l(-1.0, 0.5, -0.5),
                color0: l(0.9, 0.2, 0.1),
                color1: l(0.2, 1.0, 0.3),
            }],
        ),
        "spheres" => {
            let s = |c: Vec3, r: f32, kd: Vec3| SphereDesc {
                center: c,
                radius: r,
                material: MaterialDesc { kd: Some(kd), ..MaterialDesc::default() },
                motion: None,
            };
            scene(
                name,
                vec![],
                vec![
                    s(l(3.0, -2.0, 10.2), 1.0, l(0.8, 0.2, 0.2)),
                    s(l(-2.0, 2.0, 4.0), 2.0, l(0.6, 0.8, 0.2)),
                    s(l(0.0, 0.0, 6.0), 0.75, l(0.2, 0.2, 0.8)),
                ],
                vec![Light::Point { position: l(3.0, 0.0, 3.0), color: Vec3::splat(15.0) }],
            )
        }
        "cornell-box-motion" => SceneDesc {
            // The sphere's loop takes one second and ends where it starts: 24 frames loop.
            animation: Some(AnimationSettings { frames: Some(FrameRange { start: 0, end: 24 }), ..Default::default() }),
            ..scene(name, vec![cornell_box()], vec![path_sphere()], vec![point(0.0, 0.58, 0.0)])
        },
        "shading-models" => shading_models(name),
        "monkey" => {
            scene(name, vec![asset("monkey-rotated.obj")], vec![], vec![point(-1.0, 1.0, -1.0), point(1.0, -1.0, -1.0)])
        }
        "teapot" => scene(name, vec![asset("teapot.obj")], vec![], vec![point(-1.0, 1.0, -1.0)]),
        "dragon" => scene(name, vec![asset("dragon.obj")], vec![], vec![point(-1.0, 1.0, -1.0)]),
        "cube-textured" => scene(
            name,
            vec![MeshDesc { normalize: false, ..asset("v2022/cube-textured.obj") }],
            vec![],
            vec![point(-1.0, 1.5, -1.0)],
        ),
        _ => return Err(Error::UnknownScene { name: name.to_string(), known: builtin_names() }),
    })
}

/// The built-in scenes' names, comma separated (for error messages).
pub fn builtin_names() -> String {
    BUILTINS.iter().map(|b| b.name).collect::<Vec<_>>().join(", ")
}

/// A sphere in the Cornell box moving along a closed Catmull-Rom loop of five keys (the last
/// the first) over the shutter interval, beside the mirror block.
fn path_sphere() -> SphereDesc {
    let keys = [
        (0.0, [-0.2, 0.0, 0.0]),
        (0.25, [0.0, 0.2, -0.1]),
        (0.5, [0.2, 0.05, 0.0]),
        (0.75, [0.0, -0.1, 0.1]),
        (1.0, [-0.2, 0.0, 0.0]),
    ];
    let keys = keys.iter().map(|&(time, p)| Keyframe { time, translation: Vec3::from_array(p) }).collect();
    SphereDesc {
        center: Vec3::new(-0.25, -0.1, 0.25),
        radius: 0.1,
        material: MaterialDesc { kd: Some(Vec3::new(0.9, 0.6, 0.1)), ..MaterialDesc::default() },
        motion: Some(MotionDesc::Keys { keys, interpolation: Interpolation::CatmullRom }),
    }
}

/// The four shading models side by side: one material but for its `model`, the gradient's a
/// three-band toon ramp in the material's hue.
fn shading_models(name: &str) -> SceneDesc {
    let l = |x, y, z| Vec3::new(x, y, z);
    let key = |at, color| GradientKey { at, color };
    let toon = vec![
        key(0.0, l(0.12, 0.04, 0.03)),
        key(0.3, l(0.12, 0.04, 0.03)),
        key(0.3, l(0.45, 0.17, 0.11)),
        key(0.7, l(0.45, 0.17, 0.11)),
        key(0.7, l(0.8, 0.3, 0.2)),
        key(1.0, l(0.8, 0.3, 0.2)),
    ];
    let models = [
        // The camera looks along +z, screen right is world -x.
        (ShadingModel::Phong, l(0.45, 0.45, 0.0), None),
        (ShadingModel::BlinnPhong, l(-0.45, 0.45, 0.0), None),
        (ShadingModel::Lambert, l(0.45, -0.45, 0.0), None),
        (ShadingModel::Gradient, l(-0.45, -0.45, 0.0), Some(toon)),
    ];
    let spheres = models
        .into_iter()
        .map(|(model, center, gradient)| SphereDesc {
            center,
            radius: 0.36,
            material: MaterialDesc {
                name: Some(model.name().into()),
                model: Some(model),
                gradient,
                ..material("", l(0.8, 0.3, 0.2), Vec3::splat(0.3), 40.0, 1.0)
            },
            motion: None,
        })
        .collect();
    SceneDesc {
        camera: CameraDesc::LookAt { eye: l(0.0, 0.0, -5.0), target: Vec3::ZERO, up: Vec3::Y, fov: 24.0 },
        ..scene(name, vec![], spheres, vec![Light::Point { position: l(2.0, 2.5, -3.0), color: Vec3::ONE }])
    }
}

fn material(name: &str, kd: Vec3, ks: Vec3, shininess: f32, transparency: f32) -> MaterialDesc {
    MaterialDesc {
        name: Some(name.into()),
        kd: Some(kd),
        ks: Some(ks),
        shininess: Some(shininess),
        transparency: Some(transparency),
        ..MaterialDesc::default()
    }
}

/// Quads (as 4 corners in order) into a fan-triangulated inline mesh, one material per quad.
fn quads_mesh(name: &str, quads: &[([Vec3; 4], u32)], materials: Vec<MaterialDesc>, normalize: bool) -> MeshDesc {
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    let mut face_materials = Vec::new();
    let mut normals = Vec::new();
    for (q, m) in quads {
        let base = vertices.len() as u32;
        let n = (q[1] - q[0]).cross(q[2] - q[0]).normalize();
        vertices.extend_from_slice(q);
        normals.extend([n; 4]);
        faces.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        face_materials.extend([*m, *m]);
    }
    MeshDesc {
        name: Some(name.into()),
        vertices: Some(vertices),
        faces: Some(faces),
        normals: Some(normals),
        materials,
        face_materials,
        normalize,
        ..MeshDesc::default()
    }
}

/// The course's `CornellBox-Mirror-Rotated.obj`: McGuire's Cornell box (no front wall) with a
/// mirror tall box, its 16 quads in the file's order so that normalisation (which uses the mean
/// of the 64 listed vertices) places it exactly where the course did.
pub fn cornell_box() -> MeshDesc {
    let v = Vec3::new;
    let white = Vec3::new(0.725, 0.71, 0.68);
    let materials = vec![
        material("floor", white, Vec3::ZERO, 10.000002, 1.0),
        material("ceiling", white, Vec3::ZERO, 10.000002, 1.0),
        material("backWall", white, Vec3::ZERO, 10.000002, 1.0),
        material("rightWall", Vec3::new(0.14, 0.45, 0.091), Vec3::ZERO, 10.000002, 1.0),
        material("leftWall", Vec3::new(0.63, 0.065, 0.05), Vec3::ZERO, 10.000002, 1.0),
        material("shortBox", white, Vec3::ZERO, 10.000002, 1.0),
        material("tallBox", Vec3::splat(0.01), Vec3::splat(0.95), 4.0, 1.0),
        material("light", Vec3::splat(0.78), Vec3::ZERO, 10.000002, 1.0),
    ];
    let mut quads = vec![
        ([v(1.01, 0.0, -0.99), v(-1.0, 0.0, -0.99), v(-1.0, 0.0, 1.04), v(0.99, 0.0, 1.04)], 0),
        ([v(1.02, 1.99, -0.99), v(1.02, 1.99, 1.04), v(-1.0, 1.99, 1.04), v(-1.0, 1.99, -0.99)], 1),
        ([v(0.99, 0.0, 1.04), v(-1.0, 0.0, 1.04), v(-1.0, 1.99, 1.04), v(1.02, 1.99, 1.04)], 2),
        ([v(-1.0, 0.0, 1.04), v(-1.0, 0.0, -0.99), v(-1.0, 1.99, -0.99), v(-1.0, 1.99, 1.04)], 3),
        ([v(1.01, 0.0, -0.99), v(0.99, 0.0, 1.04), v(1.02, 1.99, 1.04), v(1.02, 1.99, -0.99)], 4),
    ];
    // A box: its top, then one side per footprint edge (bottom corners, then top corners).
    let boxed = |foot: [Vec2; 4], h: f32, sides: [(usize, usize); 4], m: u32, quads: &mut Vec<([Vec3; 4], u32)>| {
        quads.push((foot.map(|p| v(p.x, h, p.y)), m));
        for (a, b) in sides {
            let (a, b) = (foot[a], foot[b]);
            quads.push(([v(a.x, 0.0, a.y), v(a.x, h, a.y), v(b.x, h, b.y), v(b.x, 0.0, b.y)], m));
        }
    };
    let p = Vec2::new;
    let short = [p(-0.53, -0.75), p(-0.70, -0.17), p(-0.13, 0.0), p(0.05, -0.57)];
    boxed(short, 0.6, [(3, 2), (0, 3), (1, 0), (2, 1)], 5, &mut quads);
    let tall = [p(0.53, -0.09), p(-0.04, 0.09), p(0.14, 0.67), p(0.71, 0.49)];
    boxed(tall, 1.2, [(0, 3), (3, 2), (2, 1), (1, 0)], 6, &mut quads);
    quads.push(([v(0.24, 1.98, -0.16), v(0.24, 1.98, 0.22), v(-0.23, 1.98, 0.22), v(-0.23, 1.98, -0.16)], 7));
    quads_mesh("CornellBox-Mirror", &quads, materials, true)
}

/// The course's `triangle.obj` (its one normal is (0, 0, -1)), with `kd` forced to 1 as the
/// course's scene did.
pub fn single_triangle() -> MeshDesc {
    MeshDesc {
        name: Some("triangle".into()),
        vertices: Some(vec![Vec3::ZERO, Vec3::Z, Vec3::Y]),
        faces: Some(vec![[0, 1, 2]]),
        normals: Some(vec![-Vec3::Z; 3]),
        materials: vec![MaterialDesc { name: Some("white".into()), kd: Some(Vec3::ONE), ..MaterialDesc::default() }],
        ..MeshDesc::default()
    }
}

/// The course's `cube.obj` with `cube.mtl`: the unit cube `[0,1]^3`, faces grey, blue, red,
/// green, red, grey, every material with the file's `d 0.452632` (translucent).
pub fn cube() -> MeshDesc {
    let d = 0.452632;
    let materials = vec![
        material("buffy-gray", Vec3::splat(0.5), Vec3::ZERO, 1.0, d),
        material("buffy-red", Vec3::new(0.8, 0.0, 0.0), Vec3::ZERO, 1.0, d),
        material("buffy-green", Vec3::new(0.0, 0.8, 0.0), Vec3::ZERO, 1.0, d),
        material("buffy-blue", Vec3::new(0.0, 0.0, 0.8), Vec3::ZERO, 1.0, d),
    ];
    let c = |i: u32| Vec3::new(((i >> 2) & 1) as f32, ((i >> 1) & 1) as f32, (i & 1) as f32);
    // The file's faces (0-based corners of the cube, corner i = (i>>2, i>>1 & 1, i & 1)).
    let faces: [([u32; 3], u32); 12] = [
        ([0, 6, 4], 0),
        ([0, 2, 6], 0),
        ([0, 3, 2], 3),
        ([0, 1, 3], 3),
        ([2, 7, 6], 1),
        ([2, 3, 7], 1),
        ([4, 6, 7], 2),
        ([4, 7, 5], 2),
        ([0, 4, 5], 1),
        ([0, 5, 1], 1),
        ([1, 5, 7], 0),
        ([1, 7, 3], 0),
    ];
    let mut vertices = Vec::new();
    let mut tris = Vec::new();
    let mut normals = Vec::new();
    let mut face_materials = Vec::new();
    for (f, m) in faces {
        let base = vertices.len() as u32;
        let p = f.map(c);
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        vertices.extend(p);
        normals.extend([n; 3]);
        tris.push([base, base + 1, base + 2]);
        face_materials.push(m);
    }
    MeshDesc {
        name: Some("cube".into()),
        vertices: Some(vertices),
        faces: Some(tris),
        normals: Some(normals),
        materials,
        face_materials,
        ..MeshDesc::default()
    }
}
