//! Watertightness: rays from inside closed, crack-free meshes (shared vertices) never escape,
//! on any path of the wide trees (single rays at the detected SIMD level and the portable one,
//! packets, any-hit, shadow groups) nor through the binary tree's scalar test. Rays are aimed
//! at the meshes' edges and vertices, where a test that is not watertight lets them through,
//! and in uniform directions.

mod common;

use common::Rng;
use rayscope::bvh::{BuildParams, Bvh, Primitives, WideTree};
use rayscope::geometry::{Aabb, PrimHit, Triangle};
use rayscope::math::Vec3A;
use rayscope::ray::Ray;

/// A closed mesh: vertices and faces indexing them, so that neighbours share corners exactly.
struct Mesh {
    vertices: Vec<Vec3A>,
    faces: Vec<[u32; 3]>,
}

impl Mesh {
    fn triangle(&self, face: usize) -> Triangle {
        let [a, b, c] = self.faces[face].map(|i| self.vertices[i as usize]);
        Triangle::new(a, b, c)
    }

    /// A UV sphere of radius 1: `slices` around, `stacks` from pole to pole, the poles single
    /// vertices shared by their fans.
    fn uv_sphere(slices: u32, stacks: u32) -> Mesh {
        let mut vertices = vec![Vec3A::Y, -Vec3A::Y];
        for i in 1..stacks {
            let theta = std::f32::consts::PI * i as f32 / stacks as f32;
            for j in 0..slices {
                let phi = std::f32::consts::TAU * j as f32 / slices as f32;
                vertices.push(Vec3A::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()));
            }
        }
        let ring = |i: u32, j: u32| 2 + (i - 1) * slices + j % slices;
        let mut faces = Vec::new();
        for j in 0..slices {
            faces.push([0, ring(1, j + 1), ring(1, j)]);
            faces.push([1, ring(stacks - 1, j), ring(stacks - 1, j + 1)]);
        }
        for i in 1..stacks - 1 {
            for j in 0..slices {
                faces.push([ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)]);
                faces.push([ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)]);
            }
        }
        Mesh { vertices, faces }
    }

    /// The shared torus (`common::torus`).
    fn torus(big: f32, small: f32, n: u32, m: u32) -> Mesh {
        let (vertices, faces) = common::torus(big, small, n, m);
        Mesh { vertices, faces }
    }

    /// The shared icosphere (`common::icosphere`).
    fn icosphere(levels: u32) -> Mesh {
        let (v, faces) = common::icosphere(levels);
        Mesh { vertices: v.into_iter().map(Vec3A::from).collect(), faces }
    }
}

/// The mesh's triangles in BVH order.
struct Prims<'a> {
    mesh: &'a Mesh,
    bvh: &'a Bvh,
}

impl Primitives for Prims<'_> {
    fn intersect(&self, index: u32, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        self.triangle(index).unwrap().intersect(ray, t_min, t_max)
    }

    fn triangle(&self, index: u32) -> Option<Triangle> {
        Some(self.mesh.triangle(self.bvh.prim_indices[index as usize] as usize))
    }
}

/// Directions from `origin` to be tested: towards a random point of a random edge (its two
/// corners mixed), a random vertex, or anywhere (one in four each).
fn aim(rng: &mut Rng, mesh: &Mesh, origin: Vec3A) -> Vec3A {
    let face = mesh.faces[(rng.next_u64() % mesh.faces.len() as u64) as usize];
    let [a, b, _] = face.map(|i| mesh.vertices[i as usize]);
    let target = match rng.next_u64() % 4 {
        0 | 1 => a + (b - a) * rng.f32(),
        2 => a,
        _ => return rng.dir(),
    };
    (target - origin).normalize()
}

/// Escapes counted per path.
#[derive(Debug, Default)]
struct Escapes {
    rays: usize,
    single: usize,
    portable: usize,
    binary: usize,
    packet: usize,
    occluded: usize,
    shadow: usize,
    shadow_rays: usize,
}

/// Cast `n` rays from points `inside` gives, through every path, and count those that escape.
fn cast(mesh: &Mesh, n: usize, seed: u64, inside: impl Fn(&mut Rng) -> Vec3A) -> Escapes {
    let bounds: Vec<Aabb> = (0..mesh.faces.len()).map(|f| mesh.triangle(f).bounds()).collect();
    let bvh = Bvh::build(&bounds, &BuildParams::default());
    let prims = Prims { mesh, bvh: &bvh };
    let tree = WideTree::from_binary(&bvh, &prims);
    let portable = tree.clone().portable();
    let mut rng = Rng(seed);
    let mut e = Escapes::default();
    // Packets of eight rays from one origin; the first ray of each goes every other path too.
    for _ in 0..n / 8 {
        let origin = inside(&mut rng);
        let rays: Vec<Ray> = (0..8).map(|_| Ray::new(origin, aim(&mut rng, mesh, origin))).collect();
        e.rays += 8;
        e.packet += tree.intersect_packet(&rays, &prims).iter().filter(|h| h.is_none()).count();
        for ray in &rays {
            e.single += usize::from(tree.intersect(ray, &prims).is_none());
            e.occluded += usize::from(!tree.occluded(ray, &prims));
        }
        let ray = &rays[0];
        e.portable += usize::from(portable.intersect(ray, &prims).is_none());
        e.portable += usize::from(!portable.occluded(ray, &prims));
        e.binary += usize::from(bvh.intersect(ray, &prims).is_none());
        // Shadow group: towards a small light outside the mesh, beyond the point aimed at.
        let center = origin + ray.dir * 4.0;
        if let Some(occ) = tree.occluders(origin, Vec3A::ZERO, center, 0.01) {
            for _ in 0..4 {
                let target = center + rng.dir() * 0.01 * rng.f32();
                let shadow = Ray::spawn_to(origin, Vec3A::ZERO, target, 0.0);
                e.shadow_rays += 1;
                e.shadow += usize::from(!tree.occluded_among(&shadow, &prims, &occ));
            }
        }
    }
    e
}

/// Asserts no ray escaped on any path (and that the shadow groups were exercised).
fn assert_sealed(name: &str, e: &Escapes) {
    let escaped = e.single + e.portable + e.binary + e.packet + e.occluded + e.shadow;
    assert_eq!(escaped, 0, "{name}: rays escaped: {e:?}");
    assert!(e.shadow_rays > e.rays / 4, "{name}: too few shadow groups were collected: {e:?}");
}

#[test]
fn rays_never_escape_a_uv_sphere() {
    // 632 x 316: 398,160 triangles.
    let mesh = Mesh::uv_sphere(632, 316);
    let e = cast(&mesh, 400_000, 1, |rng| {
        // Anywhere inside, the centre (where every triangle is seen edge-on at the poles) too.
        if rng.f32() < 0.05 { Vec3A::ZERO } else { rng.dir() * 0.95 * rng.f32().cbrt() }
    });
    assert_sealed("UV sphere", &e);
}

#[test]
fn rays_never_escape_a_torus_or_an_icosphere() {
    let mesh = Mesh::torus(1.0, 0.3, 500, 200);
    let e = cast(&mesh, 200_000, 2, |rng| {
        // A point of the tube's core circle, moved within the tube.
        let u = rng.f32() * std::f32::consts::TAU;
        Vec3A::new(u.cos(), 0.0, u.sin()) + rng.dir() * 0.28 * rng.f32()
    });
    assert_sealed("torus", &e);
    let mesh = Mesh::icosphere(6);
    let e = cast(&mesh, 200_000, 3, |rng| rng.dir() * 0.95 * rng.f32().cbrt());
    assert_sealed("icosphere", &e);
}
