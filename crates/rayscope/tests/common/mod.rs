//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

use rayscope::material::MaterialDesc;
use rayscope::math::{Vec3, Vec3A};
use rayscope::scene::{LoadContext, MeshDesc, Scene, SceneDesc, builtin};

/// SplitMix64: a tiny seeded generator, so tests are reproducible without a dependency.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    pub fn vec3(&mut self, lo: f32, hi: f32) -> Vec3A {
        Vec3A::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }

    /// Uniform on the unit sphere.
    pub fn dir(&mut self) -> Vec3A {
        loop {
            let v = self.vec3(-1.0, 1.0);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

/// The asset folder, or `None` with a printed notice (the test then skips that part).
pub fn assets(test: &str) -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("RAYSCOPE_ASSETS").map(PathBuf::from),
        Some(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")),
    ];
    let found = candidates.into_iter().flatten().find(|p| p.join("cube.obj").is_file());
    if found.is_none() {
        eprintln!(
            "NOTICE: {test}: the course's scene folder (shared/scenes) is absent; skipping the parts that need it"
        );
    }
    found
}

/// Load a built-in scene, with the asset folder when it needs one.
pub fn builtin_scene(name: &str, assets: Option<&PathBuf>) -> Scene {
    let desc = builtin::scene_desc(name).unwrap();
    let ctx = LoadContext { assets: assets.cloned(), ..LoadContext::default() };
    Scene::from_desc(&desc, &ctx).unwrap()
}

/// A scene of one inline triangle mesh plus extra description.
pub fn inline_scene(vertices: Vec<Vec3>, faces: Vec<[u32; 3]>) -> SceneDesc {
    SceneDesc {
        meshes: vec![MeshDesc { vertices: Some(vertices), faces: Some(faces), ..MeshDesc::default() }],
        ..SceneDesc::default()
    }
}

/// A big square in the plane z = `z`, facing -z (the shading tests' camera), of `material`.
pub fn plane(z: f32, material: MaterialDesc) -> MeshDesc {
    let s = 50.0;
    let mut m = inline_scene(
        vec![Vec3::new(-s, -s, z), Vec3::new(s, -s, z), Vec3::new(s, s, z), Vec3::new(-s, s, z)],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .meshes
    .remove(0);
    m.material = Some(material);
    m
}

/// A closed, curved mesh: an icosahedron subdivided and pushed onto the unit sphere.
pub fn icosphere(levels: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut v: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut next = Vec::new();
        let mut mid = std::collections::HashMap::new();
        let mut m = |a: u32, b: u32, v: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                v.len() as u32 - 1
            })
        };
        for [a, b, c] in f {
            let (ab, bc, ca) = (m(a, b, &mut v), m(b, c, &mut v), m(c, a, &mut v));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v, f)
}

/// A torus around the y axis (major radius `big`, tube radius `small`), `n` by `m` quads of two
/// triangles each, sharing their vertices as a mesh file's do.
pub fn torus(big: f32, small: f32, n: u32, m: u32) -> (Vec<Vec3A>, Vec<[u32; 3]>) {
    let mut vertices = Vec::new();
    for i in 0..n {
        let u = std::f32::consts::TAU * i as f32 / n as f32;
        for j in 0..m {
            let v = std::f32::consts::TAU * j as f32 / m as f32;
            let r = big + small * v.cos();
            vertices.push(Vec3A::new(r * u.cos(), small * v.sin(), r * u.sin()));
        }
    }
    let at = |i: u32, j: u32| (i % n) * m + j % m;
    let mut faces = Vec::new();
    for i in 0..n {
        for j in 0..m {
            faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    (vertices, faces)
}
