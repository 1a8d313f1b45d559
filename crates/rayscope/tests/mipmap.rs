//! Trilinear filtering (mipmapping) against its purpose and its footprint's closed forms: a
//! checkerboard towards the horizon converges to its mean with trilinear and aliases with
//! nearest; the level grows with distance; a mirror's reflection carries the cone on (a flat
//! one as a straight path of the same length, a curved one wider); and the default filters
//! render as they did.

use rayscope::aov::{Aov, render_aov};
use rayscope::camera::{Camera, CameraDesc, CameraMotion};
use rayscope::material::{Material, Texture};
use rayscope::math::{Color, Vec2, Vec3, Vec3A};
use rayscope::record::RayTree;
use rayscope::render::{render, trace_pixel};
use rayscope::scene::{Mesh, Scene, SceneSphere};
use rayscope::settings::{RenderSettings, TextureFilter};

/// A `size x size` checkerboard of black and white squares `square` texels wide.
fn checker(size: u32, square: u32) -> Texture {
    let texels = (0..size * size)
        .map(|i| if (i % size / square + i / size / square).is_multiple_of(2) { Color::ONE } else { Color::ZERO })
        .collect();
    Texture::new(size, size, texels)
}

/// A square `[-h, h]^2` quad in the plane through `center` spanned by `a` and `b` (unit), its
/// uv `0..repeat` across, with `material`.
fn quad(center: Vec3A, a: Vec3A, b: Vec3A, h: f32, repeat: f32, material: u32) -> Mesh {
    let corner = |s: f32, t: f32| center + a * (s * h) + b * (t * h);
    Mesh {
        name: "quad".into(),
        positions: vec![corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)],
        uvs: vec![Vec2::ZERO, Vec2::new(repeat, 0.0), Vec2::new(repeat, repeat), Vec2::new(0.0, repeat)],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        materials: vec![material; 2],
        ..Mesh::default()
    }
}

fn textured() -> Material {
    Material { texture: Some(0), ..Material::default() }
}

fn mirror() -> Material {
    Material { kd: Color::ZERO, ks: Color::ONE, ..Material::default() }
}

fn look_at(eye: Vec3, target: Vec3, fov: f32) -> CameraDesc {
    CameraDesc::LookAt { eye, target, up: Vec3::Y, fov }
}

/// Unlit: every pixel is its texture lookup.
fn flat(width: u32, height: u32, filter: TextureFilter) -> RenderSettings {
    RenderSettings { width, height, shading: false, texture_filter: filter, ..RenderSettings::default() }
}

/// A checkerboard floor (y = 0) to the horizon, seen from 1 above it.
fn floor() -> Scene {
    let floor = quad(Vec3A::new(0.0, 0.0, 500.0), Vec3A::X, Vec3A::Z, 500.0, 2000.0, 0);
    let camera = look_at(Vec3::Y, Vec3::new(0.0, 0.8, 10.0), 40.0);
    Scene::new("floor".into(), camera, vec![floor], vec![], vec![textured()], vec![checker(64, 8)], vec![], None)
}

#[test]
fn far_rows_converge_to_the_mean_with_trilinear_and_alias_with_nearest() {
    let scene = floor();
    let (w, h) = (96, 96);
    // The band of rows just below the horizon (at row 48 - 10 * 0.2 / ...): the floor's far
    // part, where each pixel covers many checker squares.
    let err = |filter| {
        let film = render(&scene, &flat(w, h, filter), &|_| {}).film;
        let horizon = (0..h).find(|&y| film.get(w / 2, y) != Color::ZERO).unwrap();
        let band = horizon..horizon + 8;
        let n = band.len() as f32 * w as f32;
        band.flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| (film.get(x, y).x - 0.5).abs()).sum::<f32>() / n
    };
    let (nearest, trilinear) = (err(TextureFilter::Nearest), err(TextureFilter::Trilinear));
    eprintln!("mean |error| against the mean colour over the far band: nearest {nearest}, trilinear {trilinear}");
    assert!(nearest > 0.4, "nearest should alias to black or white: {nearest}");
    assert!(trilinear < 0.05, "trilinear should converge to grey: {trilinear}");
}

#[test]
fn the_mip_level_grows_towards_the_horizon() {
    let scene = floor();
    let s = flat(48, 48, TextureFilter::Bilinear);
    let aov = render_aov(&scene, &s, &scene.camera(), Aov::MipLevel, &|_| {});
    let column: Vec<f32> = (0..48).map(|y| aov.data[y * 48 + 24]).collect();
    let floor_rows: Vec<f32> = column.iter().copied().filter(|l| *l >= 0.0).collect();
    assert!(floor_rows.len() > 20, "{column:?}");
    // From the horizon down (rows top to bottom), the level never increases.
    assert!(floor_rows.windows(2).all(|p| p[0] >= p[1]), "{column:?}");
    assert!(floor_rows[0] > floor_rows[floor_rows.len() - 1] + 2.0, "{column:?}");
    // Above the horizon nothing is read.
    assert_eq!(column[0], -1.0);
}

/// The cone width at the textured hit of the centre pixel's ray tree.
fn textured_width(scene: &Scene, settings: &RenderSettings) -> f32 {
    let mut tree = RayTree::default();
    let camera = CameraMotion::still(Camera::from_desc(&scene.camera));
    trace_pixel(scene, settings, &camera, settings.width / 2, settings.height / 2, 0, &mut tree);
    let lods: Vec<_> = tree.rays.iter().filter_map(|r| r.texture_lod).collect();
    assert_eq!(lods.len(), 1, "{:?}", tree.rays);
    lods[0].cone_width
}

#[test]
fn a_mirror_carries_the_cone_on() {
    // Camera at the origin looking along +z, a pixel 1/101 of a 90-degree view.
    let camera = look_at(Vec3::ZERO, Vec3::Z, 90.0);
    let s = RenderSettings { width: 101, height: 101, texture_filter: TextureFilter::Trilinear, ..Default::default() };
    let spread = (2.0f32 / 101.0).atan();
    let wall = |z: f32, facing: Vec3A| quad(Vec3A::new(0.0, 0.0, z), Vec3A::X, facing.cross(Vec3A::X), 50.0, 10.0, 0);
    let scene = |meshes, spheres| {
        Scene::new(
            "m".into(),
            camera.clone(),
            meshes,
            spheres,
            vec![textured(), mirror()],
            vec![checker(64, 8)],
            vec![],
            None,
        )
    };
    // Directly: a textured wall 3 ahead.
    let direct = textured_width(&scene(vec![wall(3.0, Vec3A::NEG_Z)], vec![]), &s);
    assert!((direct - 3.0 * spread).abs() < 1e-5 * 3.0, "{direct}");
    // Through a flat mirror 2 ahead onto a textured wall 1 behind the camera: 3 from the
    // mirror, a path of 5, and as wide as a straight path of 5.
    let mut m = wall(2.0, Vec3A::NEG_Z);
    m.materials = vec![1; 2];
    let reflected = textured_width(&scene(vec![m, wall(-1.0, Vec3A::Z)], vec![]), &s);
    assert!(reflected > direct);
    assert!((reflected - 5.0 * spread).abs() < 1e-4, "{reflected} vs {}", 5.0 * spread);
    // A convex mirror (a sphere whose front is 2 ahead) spreads the cone more.
    let ball = SceneSphere { center: Vec3A::new(0.0, 0.0, 3.0), radius: 1.0, material: 1, motion: None };
    let curved = textured_width(&scene(vec![wall(-1.0, Vec3A::Z)], vec![ball]), &s);
    assert!(curved > reflected * 1.5, "{curved} vs {reflected}");
}

#[test]
fn nearest_and_bilinear_carry_no_cone() {
    let scene = floor();
    for filter in [TextureFilter::Nearest, TextureFilter::Bilinear] {
        let s = flat(9, 9, filter);
        let mut tree = RayTree::default();
        trace_pixel(&scene, &s, &scene.camera_motion(), 4, 6, 0, &mut tree);
        assert!(tree.rays.iter().all(|r| r.texture_lod.is_none()));
    }
}
