//! The rays the ray benchmarks trace (`embree.rs`, `rays.rs`), made the same way in both.

use std::path::PathBuf;

use rayscope::math::Vec3A;
use rayscope::ray::Ray;
use rayscope::scene::Scene;

/// The course's scene folder: `RAYSCOPE_ASSETS`, else `../shared/scenes` beside the
/// repository; `None` where it holds no `dragon.obj`.
pub fn assets() -> Option<PathBuf> {
    std::env::var_os("RAYSCOPE_ASSETS")
        .map(PathBuf::from)
        .or_else(|| Some(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")))
        .filter(|p| p.join("dragon.obj").is_file())
}

/// A small deterministic generator (a 64-bit LCG's high bits).
struct Rng(u64);

impl Rng {
    fn f32(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
}

/// The scene camera's 800x800 pixel-centre rays, row by row.
pub fn camera_rays(scene: &Scene) -> Vec<Ray> {
    let cam = scene.camera();
    (0..800u32).flat_map(|y| (0..800u32).map(move |x| (x, y))).map(|(x, y)| cam.pixel_ray(x, y, 800, 800)).collect()
}

/// `n` rays from random points of the scene's box in random directions.
pub fn incoherent_rays(scene: &Scene, n: usize) -> Vec<Ray> {
    let b = scene.geometry.bvh.nodes[0].bounds();
    let mut rng = Rng(42);
    (0..n)
        .map(|_| {
            let o = b.min + (b.max - b.min) * Vec3A::new(rng.f32(), rng.f32(), rng.f32());
            let d = loop {
                let v = Vec3A::new(rng.f32(), rng.f32(), rng.f32()) * 2.0 - Vec3A::ONE;
                if v.length_squared() > 1e-3 && v.length_squared() <= 1.0 {
                    break v.normalize();
                }
            };
            Ray::new(o, d)
        })
        .collect()
}

/// Any-hit rays from each of `cam`'s hits to a point light at (-1, 1, -1).
pub fn shadow_rays(scene: &Scene, cam: &[Ray]) -> Vec<Ray> {
    let light = Vec3A::new(-1.0, 1.0, -1.0);
    cam.iter()
        .filter_map(|r| scene.intersect(r).map(|h| (r, h)))
        .map(|(r, h)| {
            let si = scene.surface(r, &h, &Default::default());
            Ray::spawn_to(si.point, si.geo_normal, light, 0.0)
        })
        .collect()
}
