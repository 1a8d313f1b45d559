//! The BVHs are the same, bit for bit, as the builder and the collapse made them before their
//! memory was cut (branch `mem`: boxes given by index, the plan without its costs, the wide
//! tree written into arrays of its final size, the shapes stored compactly), and the same on
//! any number of threads: the fingerprints below were taken from main's build (ce02be4).
//! The same tree means the same leaves in the same order, so the same closest hits, ties
//! included.

mod common;

use common::{assets, builtin_scene};
use rayscope::bvh::{Bvh, WideBvh, WideTree};
use rayscope::camera::CameraDesc;
use rayscope::material::Material;
use rayscope::scene::{Mesh, Scene};

/// FNV-1a over 32-bit words.
struct Fnv(u64);

impl Fnv {
    fn word(&mut self, w: u32) {
        for b in w.to_le_bytes() {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }

    fn floats(&mut self, fs: &[f32]) {
        fs.iter().for_each(|f| self.word(f.to_bits()));
    }
}

fn binary_print(h: &mut Fnv, bvh: &Bvh) {
    for n in &bvh.nodes {
        h.floats(&n.min);
        h.floats(&n.max);
        h.word(n.start);
        h.word(n.count);
    }
    bvh.prim_indices.iter().for_each(|&i| h.word(i));
}

fn wide_print<const W: usize>(h: &mut Fnv, t: &WideBvh<W>) {
    h.word(W as u32);
    for n in &t.nodes {
        n.bounds.iter().for_each(|row| h.floats(row));
        n.child.iter().for_each(|c| h.word(c.to_bits()));
    }
    for b in &t.blocks {
        for v in [&b.v0, &b.v1, &b.v2] {
            v.iter().for_each(|axis| h.floats(axis));
        }
        b.slot.iter().for_each(|&s| h.word(s));
    }
    for r in &t.ranges {
        h.word(r.start);
        h.word(r.count);
    }
    h.word(t.reach.to_bits());
}

/// The scene's binary tree and its collapses at both widths, as one number.
fn fingerprint(scene: &Scene) -> u64 {
    let g = &scene.geometry;
    let mut h = Fnv(0xcbf2_9ce4_8422_2325);
    binary_print(&mut h, &g.bvh);
    for width in [8, 16] {
        match WideTree::with_width(&g.bvh, g, width) {
            WideTree::Eight(t) => wide_print(&mut h, &t),
            WideTree::Sixteen(t) => wide_print(&mut h, &t),
        }
    }
    h.0
}

/// The shared torus (`common::torus`) as a scene of its own: `2 n m` triangles sharing their
/// vertices, as the loader makes an OBJ file's.
fn torus(n: u32, m: u32) -> Scene {
    let (positions, triangles) = common::torus(1.0, 0.3, n, m);
    let materials = vec![0; triangles.len()];
    let mesh = Mesh { name: "torus".into(), positions, triangles, materials, ..Mesh::default() };
    let camera = CameraDesc::default();
    Scene::new("torus".into(), camera, vec![mesh], Vec::new(), vec![Material::default()], Vec::new(), Vec::new(), None)
}

/// `make` on a pool of `threads` threads.
fn on_threads<T: Send>(threads: usize, make: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(make)
}

#[test]
fn trees_are_as_main_built_them_on_any_thread_count() {
    let assets = assets("trees_are_as_main_built_them_on_any_thread_count");
    let expected: [(&str, u64); 7] = [
        ("cornell-box", 0x44b77ebc0288d2ae),
        ("cube", 0xf80db87dfa69627e),
        ("single-triangle", 0x7d81884dcf33627c),
        ("spheres", 0x8b0506eccc2dfe23),
        ("monkey", 0x9763749510d8b1ff),
        ("teapot", 0x51b0bec7d5574815),
        ("dragon", 0xb4a37ec15891858e),
    ];
    for (name, want) in expected {
        if assets.is_none() && ["monkey", "teapot", "dragon"].contains(&name) {
            continue;
        }
        for threads in [1, 2, 3] {
            let scene = on_threads(threads, || builtin_scene(name, assets.as_ref()));
            let got = fingerprint(&scene);
            assert_eq!(got, want, "{name} on {threads} threads");
        }
    }
    // Big enough for the parallel build, plan and collapse (a quarter of a million triangles).
    for threads in [1, 2, 3] {
        let got = on_threads(threads, || fingerprint(&torus(500, 250)));
        assert_eq!(got, 0x8cd4d61240074c2c, "torus on {threads} threads");
    }
}
