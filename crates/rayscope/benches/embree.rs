//! rayscope's BVH side by side with Intel Embree 3 on the same triangles and the same rays.
//!
//! ```sh
//! apt-get install libembree-dev libtbb-dev
//! cargo bench -p rayscope --features embree --bench embree
//! RAYSCOPE_EMBREE_MESHES=dragon,teapot cargo bench -p rayscope --features embree --bench embree
//! ```
//!
//! For each mesh (the dragon and the teapot from the course's files, and a procedural mesh of
//! about a million triangles) it builds both BVHs, traces 800x800 camera rays (one at a time,
//! in packets of eight neighbouring pixels: our `intersect_packet` against Embree's
//! `rtcIntersect8`, and in tiles of 8 x 8 pixels: our `intersect_tile`, the render's way in
//! big scenes, against `rtcIntersect8` on each of the tile's eight rows, the same rays in the
//! same order), as many incoherent rays (random origins in the scene's box, random
//! directions) and shadow rays (any-hit) on 1 and 2 threads, checks that both find the same
//! closest hits, and prints the times, throughputs and ratios as a Markdown table. Embree gets
//! its recommended settings: flush-to-zero and denormals-are-zero on every thread, the
//! coherent flag for camera rays, its default (medium quality) build on the same number of
//! threads.

mod common;

use std::ffi::CString;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use embree::sys;
use rayon::prelude::*;
use rayscope::bvh::{PACKET, TILE_RUNS};
use rayscope::camera::CameraDesc;
use rayscope::material::Material;
use rayscope::math::Vec3A;
use rayscope::ray::Ray;
use rayscope::scene::{Geometry, LoadContext, Mesh, Scene, builtin};

const REPS: usize = 7;

struct Soup {
    name: String,
    positions: Vec<Vec3A>,
    triangles: Vec<[u32; 3]>,
}

fn course_mesh(name: &str, assets: &Option<PathBuf>) -> Option<Soup> {
    let assets = assets.clone()?;
    let desc = builtin::scene_desc(name).ok()?;
    let scene = Scene::from_desc(&desc, &LoadContext { assets: Some(assets), ..LoadContext::default() }).ok()?;
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for m in &scene.meshes {
        let base = positions.len() as u32;
        positions.extend_from_slice(&m.positions);
        triangles.extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    Some(Soup { name: name.into(), positions, triangles })
}

/// A bumpy torus of `n x m x 2` triangles fitting the unit sphere: a million-triangle mesh
/// with detail at every scale, needing no file.
fn procedural(n: u32, m: u32) -> Soup {
    let mut positions = Vec::with_capacity((n * m) as usize);
    for i in 0..n {
        for j in 0..m {
            let (u, v) = (i as f32 / n as f32 * std::f32::consts::TAU, j as f32 / m as f32 * std::f32::consts::TAU);
            let bump = 0.03 * ((7.0 * u).sin() * (13.0 * v).cos() + 0.5 * (41.0 * u + 3.0 * v).sin());
            let r = 0.25 + bump;
            positions.push(Vec3A::new((0.7 + r * v.cos()) * u.cos(), r * v.sin(), (0.7 + r * v.cos()) * u.sin()));
        }
    }
    let idx = |i: u32, j: u32| (i % n) * m + (j % m);
    let mut triangles = Vec::with_capacity((2 * n * m) as usize);
    for i in 0..n {
        for j in 0..m {
            triangles.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            triangles.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
        }
    }
    Soup { name: format!("procedural torus ({}k)", 2 * n * m / 1000), positions, triangles }
}

/// Our scene over the soup's triangles (its BVH is built on the way).
fn ours(soup: &Soup) -> Scene {
    let mesh = Mesh {
        name: soup.name.clone(),
        positions: soup.positions.clone(),
        triangles: soup.triangles.clone(),
        materials: vec![0; soup.triangles.len()],
        ..Mesh::default()
    };
    Scene::new(
        soup.name.clone(),
        CameraDesc::default(),
        vec![mesh],
        vec![],
        vec![Material::default()],
        vec![],
        vec![],
        None,
    )
}

struct Embree {
    device: sys::RTCDevice,
    scene: sys::RTCScene,
}

// SAFETY: Embree's device and scene handles may be used from any thread; a committed scene is
// only read by the queries, which Embree allows from many threads at once.
unsafe impl Send for Embree {}
// SAFETY: as for `Send`: the queries (`&self`) only read the committed scene.
unsafe impl Sync for Embree {}

impl Embree {
    /// Build once on `threads` threads; returns the scene and the time of `rtcCommitScene`.
    fn build(soup: &Soup, threads: usize) -> (Embree, Duration) {
        let cfg = CString::new(format!("threads={threads}")).unwrap();
        // SAFETY: Embree's C API used as documented: `cfg` outlives the call that reads it, and
        // the new buffers hold as many vertices and triangles as are written to them.
        unsafe {
            let device = sys::rtcNewDevice(cfg.as_ptr());
            let scene = sys::rtcNewScene(device);
            sys::rtcSetSceneBuildQuality(scene, sys::RTCBuildQuality::MEDIUM);
            let geom = sys::rtcNewGeometry(device, sys::RTCGeometryType::TRIANGLE);
            let v = sys::rtcSetNewGeometryBuffer(
                geom,
                sys::RTCBufferType::VERTEX,
                0,
                sys::RTCFormat::FLOAT3,
                16,
                soup.positions.len(),
            ) as *mut [f32; 4];
            for (i, p) in soup.positions.iter().enumerate() {
                *v.add(i) = [p.x, p.y, p.z, 0.0];
            }
            let ix = sys::rtcSetNewGeometryBuffer(
                geom,
                sys::RTCBufferType::INDEX,
                0,
                sys::RTCFormat::UINT3,
                12,
                soup.triangles.len(),
            ) as *mut [u32; 3];
            for (i, t) in soup.triangles.iter().enumerate() {
                *ix.add(i) = *t;
            }
            sys::rtcCommitGeometry(geom);
            sys::rtcAttachGeometry(scene, geom);
            sys::rtcReleaseGeometry(geom);
            let start = Instant::now();
            sys::rtcCommitScene(scene);
            (Embree { device, scene }, start.elapsed())
        }
    }

    fn intersect(&self, r: &Ray, coherent: bool) -> Option<(u32, f32)> {
        let mut rh = sys::RTCRayHit {
            ray: rtc_ray(r),
            hit: sys::RTCHit {
                Ng_x: 0.0,
                Ng_y: 0.0,
                Ng_z: 0.0,
                u: 0.0,
                v: 0.0,
                primID: u32::MAX,
                geomID: u32::MAX,
                instID: [u32::MAX],
            },
        };
        let mut ctx =
            if coherent { embree::IntersectContext::coherent() } else { embree::IntersectContext::incoherent() };
        // SAFETY: a committed scene, and a context and ray hit that live across the call.
        unsafe { sys::rtcIntersect1(self.scene, &mut ctx, &mut rh) };
        (rh.hit.geomID != u32::MAX).then_some((rh.hit.primID, rh.ray.tfar))
    }

    /// Closest hits of up to eight rays in one `rtcIntersect8` call (Embree's packet mode,
    /// with the coherent flag: for camera rays of neighbouring pixels); returns how many hit.
    fn intersect8(&self, rays: &[Ray]) -> usize {
        // SAFETY: `RTCRayHit8` is plain floats and integers, for which zero bits are valid.
        let mut rh: sys::RTCRayHit8 = unsafe { std::mem::zeroed() };
        let mut valid = [0i32; 8];
        for (i, r) in rays.iter().enumerate().take(8) {
            let one = rtc_ray(r);
            let ray = &mut rh.ray;
            (ray.org_x[i], ray.org_y[i], ray.org_z[i], ray.tnear[i]) = (one.org_x, one.org_y, one.org_z, one.tnear);
            (ray.dir_x[i], ray.dir_y[i], ray.dir_z[i], ray.tfar[i]) = (one.dir_x, one.dir_y, one.dir_z, one.tfar);
            ray.mask[i] = u32::MAX;
            rh.hit.geomID[i] = u32::MAX;
            valid[i] = -1;
        }
        let mut ctx = embree::IntersectContext::coherent();
        // SAFETY: as in `intersect`; `valid` holds the eight lanes' flags Embree reads.
        unsafe { sys::rtcIntersect8(valid.as_ptr(), self.scene, &mut ctx, &mut rh) };
        rh.hit.geomID.iter().take(rays.len()).filter(|g| **g != u32::MAX).count()
    }

    fn occluded(&self, r: &Ray) -> bool {
        let mut ray = rtc_ray(r);
        let mut ctx = embree::IntersectContext::incoherent();
        // SAFETY: as in `intersect`.
        unsafe { sys::rtcOccluded1(self.scene, &mut ctx, &mut ray) };
        ray.tfar < 0.0
    }
}

fn rtc_ray(r: &Ray) -> sys::RTCRay {
    sys::RTCRay {
        org_x: r.origin.x,
        org_y: r.origin.y,
        org_z: r.origin.z,
        tnear: r.t.min,
        dir_x: r.dir.x,
        dir_y: r.dir.y,
        dir_z: r.dir.z,
        time: 0.0,
        tfar: r.t.max,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

impl Drop for Embree {
    fn drop(&mut self) {
        // SAFETY: the handles were made by `build` and are released once, here.
        unsafe {
            sys::rtcReleaseScene(self.scene);
            sys::rtcReleaseDevice(self.device);
        }
    }
}

/// Flush-to-zero and denormals-are-zero, as Embree recommends, on the calling thread.
#[allow(deprecated)]
fn ftz_daz() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: setting the FTZ and DAZ bits of MXCSR only changes how this thread's float
    // operations round denormals.
    unsafe {
        use std::arch::x86_64::{_mm_getcsr, _mm_setcsr};
        _mm_setcsr(_mm_getcsr() | 0x8040);
    }
}

/// Throughput of `ours` and of `theirs` over `rays` on `pool`, in Mrays/s: the fastest of
/// REPS passes each, the two alternating so that both see the same state of a shared machine.
fn compare<F, G>(pool: &rayon::ThreadPool, rays: &[Ray], ours: F, theirs: G) -> (f64, f64)
where
    F: Fn(&Ray) -> bool + Sync,
    G: Fn(&Ray) -> bool + Sync,
{
    compare_groups(pool, rays, 1, |c| c.iter().filter(|r| ours(r)).count(), |c| c.iter().filter(|r| theirs(r)).count())
}

/// [`compare`] for functions that trace `group` rays at a time and return how many hit.
fn compare_groups<F, G>(pool: &rayon::ThreadPool, rays: &[Ray], group: usize, ours: F, theirs: G) -> (f64, f64)
where
    F: Fn(&[Ray]) -> usize + Sync,
    G: Fn(&[Ray]) -> usize + Sync,
{
    let pass = |f: &(dyn Fn(&[Ray]) -> usize + Sync)| {
        pool.install(|| rays.par_chunks(4096).map(|c| c.chunks(group).map(f).sum::<usize>()).sum::<usize>())
    };
    alternate(rays.len(), || pass(&ours), || pass(&theirs))
}

/// Rays per second of `ours` and `theirs` over `rays` rays: the fastest of [`REPS`] passes
/// each, alternating (each runs one pass and returns its hits).
fn alternate(rays: usize, ours: impl Fn() -> usize, theirs: impl Fn() -> usize) -> (f64, f64) {
    let time = |pass: &dyn Fn() -> usize| {
        let start = Instant::now();
        std::hint::black_box(pass());
        start.elapsed()
    };
    let (mut a, mut b) = (Duration::MAX, Duration::MAX);
    for _ in 0..REPS {
        a = a.min(time(&ours));
        b = b.min(time(&theirs));
    }
    let rate = |d: Duration| rays as f64 / d.as_secs_f64() / 1e6;
    (rate(a), rate(b))
}

/// Image width of the camera rays ([`common::camera_rays`]).
const WIDTH: usize = 800;

/// `f`'s hits summed over the tiles of `band` (camera rays of [`TILE_RUNS`] rows of
/// [`WIDTH`], row after row), each given as its runs of [`PACKET`] pixels.
fn in_tiles(band: &[Ray], f: &(dyn Fn(&[&[Ray]]) -> usize + Sync)) -> usize {
    (0..WIDTH)
        .step_by(PACKET)
        .map(|x0| f(&std::array::from_fn::<_, TILE_RUNS, _>(|r| &band[WIDTH * r + x0..][..PACKET])))
        .sum()
}

/// Rays per second of `ours` and `theirs` over the camera rays `rays` cut into tiles
/// ([`in_tiles`]), each function given a tile's runs; the fastest of [`REPS`] alternating
/// passes each.
fn compare_tiles<F, G>(pool: &rayon::ThreadPool, rays: &[Ray], ours: F, theirs: G) -> (f64, f64)
where
    F: Fn(&[&[Ray]]) -> usize + Sync,
    G: Fn(&[&[Ray]]) -> usize + Sync,
{
    let pass = |f: &(dyn Fn(&[&[Ray]]) -> usize + Sync)| {
        pool.install(|| rays.par_chunks(WIDTH * TILE_RUNS).map(|band| in_tiles(band, f)).sum::<usize>())
    };
    alternate(rays.len(), || pass(&ours), || pass(&theirs))
}

fn main() {
    let assets = common::assets();
    if assets.is_none() {
        eprintln!("NOTICE: the course's scene files are absent (set RAYSCOPE_ASSETS); only the procedural mesh runs");
    }
    // RAYSCOPE_EMBREE_MESHES=dragon,teapot,torus picks meshes (default: all three).
    let pick = std::env::var("RAYSCOPE_EMBREE_MESHES").unwrap_or_else(|_| "dragon,teapot,torus".into());
    let wanted: Vec<&str> = pick.split(',').map(str::trim).collect();
    let mut soups: Vec<Soup> =
        ["dragon", "teapot"].iter().filter(|n| wanted.contains(n)).filter_map(|n| course_mesh(n, &assets)).collect();
    if wanted.contains(&"torus") {
        soups.push(procedural(1000, 500));
    }
    println!("Our traversal: {:?} (chosen at run time).\n", rayscope::bvh::SimdLevel::detect());
    println!(
        "| mesh | triangles | threads | build ms (ours / Embree) | camera Mrays/s (ours / Embree / ratio) | camera, packets of 8 | camera, tiles of 8 x 8 | incoherent | any-hit (shadow) | hits agree |"
    );
    println!("|---|---:|---:|---|---|---|---|---|---|---|");
    for soup in &soups {
        let scene = ours(soup);
        let cam = common::camera_rays(&scene);
        let inc = common::incoherent_rays(&scene, cam.len());
        let shadow = common::shadow_rays(&scene, &cam);
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.broadcast(|_| ftz_daz());
            ftz_daz();
            // Both builds, alternating, the fastest of each; the last Embree scene is kept.
            let (mut build_ours, mut emb_build) = (Duration::MAX, Duration::MAX);
            let mut kept = None;
            for _ in 0..REPS {
                build_ours = build_ours.min(pool.install(|| ours_build_time(&scene)));
                let (e, t) = Embree::build(soup, threads);
                emb_build = emb_build.min(t);
                kept = Some(e);
            }
            let emb = kept.unwrap();
            // Same closest hits: same primitive, or (at a shared edge or vertex, where either
            // triangle is right) the same distance within 1e-4 relative.
            let mut disagree = 0usize;
            for (rays, coherent) in [(&cam, true), (&inc, false)] {
                for r in rays.iter() {
                    let a = scene.intersect(r).map(|h| (scene.prim_id(&h), h.t));
                    let b = emb.intersect(r, coherent);
                    let same = match (a, b) {
                        (None, None) => true,
                        (Some((pa, ta)), Some((pb, tb))) => pa == pb || (ta - tb).abs() <= 1e-4 * ta.abs().max(1e-3),
                        _ => false,
                    };
                    disagree += usize::from(!same);
                }
            }
            let total = cam.len() + inc.len();
            let (oc, ec) = compare(&pool, &cam, |r| scene.intersect(r).is_some(), |r| emb.intersect(r, true).is_some());
            // Eight neighbouring pixels of a row per packet, as the renderer traces them. Both
            // packet modes must find what their single rays find.
            let our_packet = |c: &[Ray]| scene.intersect_packet(c).iter().filter(|h| h.is_some()).count();
            let hits = |f: &dyn Fn(&[Ray]) -> usize| cam.chunks(PACKET).map(f).sum::<usize>();
            let single = cam.iter().filter(|r| emb.intersect(r, true).is_some()).count();
            assert_eq!(hits(&|c| emb.intersect8(c)), single, "rtcIntersect8 and rtcIntersect1 disagree");
            assert_eq!(hits(&our_packet), cam.iter().filter(|r| scene.intersect(r).is_some()).count());
            let (op, ep) = compare_groups(&pool, &cam, PACKET, our_packet, |c| emb.intersect8(c));
            let our_tile = |t: &[&[Ray]]| scene.intersect_tile(t).iter().flatten().filter(|h| h.is_some()).count();
            let their_tile = |t: &[&[Ray]]| t.iter().map(|run| emb.intersect8(run)).sum();
            let tiled: usize = cam.chunks(WIDTH * TILE_RUNS).map(|band| in_tiles(band, &our_tile)).sum();
            assert_eq!(tiled, hits(&our_packet), "tiles and packets disagree");
            let (ot, et) = compare_tiles(&pool, &cam, our_tile, their_tile);
            let (oi, ei) =
                compare(&pool, &inc, |r| scene.intersect(r).is_some(), |r| emb.intersect(r, false).is_some());
            let (os, es) = compare(&pool, &shadow, |r| scene.occluded(r), |r| emb.occluded(r));
            println!(
                "| {} | {} | {threads} | {:.1} / {:.1} | {oc:.2} / {ec:.2} / {:.2} | {op:.2} / {ep:.2} / {:.2} | {ot:.2} / {et:.2} / {:.2} | {oi:.2} / {ei:.2} / {:.2} | {os:.2} / {es:.2} / {:.2} | {} of {total} differ |",
                soup.name,
                soup.triangles.len(),
                build_ours.as_secs_f64() * 1e3,
                emb_build.as_secs_f64() * 1e3,
                oc / ec,
                op / ep,
                ot / et,
                oi / ei,
                os / es,
                disagree
            );
        }
    }
}

/// One build of our BVH (shapes, binary SAH tree, collapse and packing) over `scene`.
fn ours_build_time(scene: &Scene) -> Duration {
    let prims = scene.prim_refs();
    let start = Instant::now();
    let g = Geometry::build(&scene.meshes, &scene.spheres, &prims);
    let t = start.elapsed();
    std::hint::black_box(g);
    t
}
