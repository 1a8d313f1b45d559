//! The BVH against brute force (on chosen and on arbitrary inputs), its invariants, and
//! degenerate inputs.

mod common;

use common::{Rng, assets, builtin_scene};
use proptest::prelude::{Just, ProptestConfig, Strategy, any, prop, prop_oneof, proptest};
use rayscope::bvh::wide::{Lanes, NodeWidth};
use rayscope::bvh::{
    BuildParams, Bvh, Bvh4, Bvh8, Bvh16, ChildRef, Primitives, QueryKind, SplitRule, TILE_RUNS, TraversalLog, WideBvh,
    WideTree, split_candidates,
};
use rayscope::geometry::aabb::safe_inv_dir;
use rayscope::geometry::{Aabb, PrimHit, Sphere, Triangle};
use rayscope::math::Vec3A;
use rayscope::ray::Ray;
use rayscope::scene::{Scene, Shape};

/// Shapes in input order, for brute force; the BVH reaches them through its slot order.
struct Ordered<'a> {
    shapes: &'a [Shape],
    bvh: &'a Bvh,
}

impl Primitives for Ordered<'_> {
    fn intersect(&self, index: u32, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        self.shapes[self.bvh.prim_indices[index as usize] as usize].intersect(ray, t_min, t_max)
    }

    // Triangles are offered for packing, so the 4-wide BVH's SIMD triangle test is checked too.
    fn triangle(&self, index: u32) -> Option<Triangle> {
        match self.shapes[self.bvh.prim_indices[index as usize] as usize] {
            Shape::Triangle(t) => Some(t),
            _ => None,
        }
    }
}

fn brute_closest(shapes: &[Shape], ray: &Ray) -> Option<(u32, PrimHit)> {
    let mut best: Option<(u32, PrimHit)> = None;
    for (i, s) in shapes.iter().enumerate() {
        let t_max = best.map_or(ray.t.max, |b| b.1.t);
        if let Some(h) = s.intersect(ray, ray.t.min, t_max) {
            best = Some((i as u32, h));
        }
    }
    best
}

/// Check closest-hit and any-hit against brute force on `n` rays from `origin_of`.
fn check(shapes: &[Shape], rays: impl Iterator<Item = Ray>) -> usize {
    let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
    check_with(shapes, &bounds, &BuildParams::default(), rays)
}

/// [`check`] with these build parameters: the binary BVH and the 4-, 8- and 16-wide BVHs
/// collapsed from it, each against brute force and against each other (the wide ones run the
/// SIMD slab tests, the binary one the scalar one).
fn check_with(shapes: &[Shape], bounds: &[Aabb], params: &BuildParams, rays: impl Iterator<Item = Ray>) -> usize {
    let bvh = Bvh::build(bounds, params);
    bvh.validate(bounds).unwrap();
    let prims = Ordered { shapes, bvh: &bvh };
    let bvh4 = Bvh4::from_binary(&bvh, &prims);
    bvh4.validate(&bvh, bounds).unwrap();
    let bvh8 = Bvh8::from_binary(&bvh, &prims);
    bvh8.validate(&bvh, bounds).unwrap();
    let bvh16 = Bvh16::from_binary(&bvh, &prims);
    bvh16.validate(&bvh, bounds).unwrap();
    // The same trees traversed by the baseline code: identical hits whatever the CPU has.
    let (portable4, portable8) = (bvh4.clone().portable(), bvh8.clone().portable());
    let portable16 = bvh16.clone().portable();
    let mut hits = 0;
    for ray in rays {
        let got = bvh.intersect(&ray, &prims).map(|h| (bvh.prim_indices[h.slot as usize], h.hit));
        check_wide(&bvh4, &portable4, &prims, shapes, &ray, got);
        check_wide(&bvh8, &portable8, &prims, shapes, &ray, got);
        check_wide(&bvh16, &portable16, &prims, shapes, &ray, got);
        let want = brute_closest(shapes, &ray);
        match (got, want) {
            (None, None) => {}
            (Some((gp, gh)), Some((_, wh))) => {
                hits += 1;
                // Equal distance; where two primitives tie (a shared edge), either is right,
                // but the one reported must really be hit at that distance.
                assert_eq!(gh.t, wh.t, "ray {ray:?}");
                assert_eq!(shapes[gp as usize].intersect(&ray, ray.t.min, ray.t.max).map(|h| h.t), Some(gh.t));
            }
            (g, w) => panic!("ray {ray:?}: BVH {g:?}, brute force {w:?}"),
        }
        assert_eq!(bvh.occluded(&ray, &prims), want.is_some(), "any-hit, ray {ray:?}");
    }
    hits
}

/// A wide BVH (`W` children) agrees with its portable twin, with the binary BVH's hit `got`,
/// and with the scalar triangle test's barycentrics.
fn check_wide<const W: usize>(
    wide: &WideBvh<W>,
    portable: &WideBvh<W>,
    prims: &Ordered,
    shapes: &[Shape],
    ray: &Ray,
    got: Option<(u32, PrimHit)>,
) where
    Lanes<W>: NodeWidth<W>,
{
    assert_eq!(portable.intersect(ray, prims), wide.intersect(ray, prims), "{W}-wide SIMD levels, {ray:?}");
    assert_eq!(portable.occluded(ray, prims), wide.occluded(ray, prims), "{W}-wide SIMD levels, {ray:?}");
    let hit = wide.intersect(ray, prims).map(|h| (prims.bvh.prim_indices[h.slot as usize], h.hit));
    assert_eq!(got.map(|g| g.1.t), hit.map(|w| w.1.t), "binary and {W}-wide BVH disagree on {ray:?}");
    if let (Some(g), Some(w)) = (got, hit) {
        // The packed (SIMD) triangle test returns the scalar test's exact barycentrics.
        let scalar = shapes[w.0 as usize].intersect(ray, ray.t.min, ray.t.max).unwrap();
        assert_eq!((scalar.t, scalar.u, scalar.v), (w.1.t, w.1.u, w.1.v), "{ray:?}");
        assert!(g.0 == w.0 || g.1.t == w.1.t);
    }
    assert_eq!(wide.occluded(ray, prims), got.is_some(), "{W}-wide any-hit, ray {ray:?}");
}

fn random_soup(rng: &mut Rng, n: usize, size: f32) -> Vec<Shape> {
    (0..n)
        .map(|_| {
            let c = rng.vec3(-1.0, 1.0);
            if rng.f32() < 0.05 {
                Shape::Sphere(Sphere { center: c, radius: rng.range(0.01, 0.2) })
            } else {
                Shape::Triangle(Triangle::new(c, c + rng.vec3(-size, size), c + rng.vec3(-size, size)))
            }
        })
        .collect()
}

fn random_rays(rng: &mut Rng, n: usize, spread: f32) -> Vec<Ray> {
    (0..n)
        .map(|_| {
            let mut r = Ray::new(rng.vec3(-spread, spread), rng.dir());
            if rng.f32() < 0.2 {
                // Some bounded rays, like shadow rays.
                r.t.max = rng.range(0.1, 2.0);
            }
            r
        })
        .collect()
}

#[test]
fn random_soups_match_brute_force() {
    let mut rng = Rng(7);
    let mut hits = 0;
    for (n, size) in [(1, 0.5), (2, 0.5), (10, 0.3), (100, 0.2), (1000, 0.1), (5000, 0.05)] {
        let shapes = random_soup(&mut rng, n, size);
        let rays = random_rays(&mut rng, 2000, 1.5);
        hits += check(&shapes, rays.into_iter());
    }
    assert!(hits > 1000, "the rays must actually hit things ({hits})");
}

#[test]
fn parallel_build_matches_brute_force() {
    // Above the parallel threshold, subtrees are built on separate tasks and concatenated.
    let mut rng = Rng(11);
    let shapes = random_soup(&mut rng, 40_000, 0.02);
    let rays = random_rays(&mut rng, 500, 1.2);
    check(&shapes, rays.into_iter());
}

#[test]
fn degenerate_inputs() {
    let p = Vec3A::new(0.3, 0.2, 0.1);
    let rays = |rng: &mut Rng| random_rays(rng, 300, 1.0).into_iter();
    let mut rng = Rng(3);
    // Empty.
    let bvh = Bvh::build(&[], &BuildParams::default());
    bvh.validate(&[]).unwrap();
    assert!(bvh.nodes.is_empty());
    assert!(Bvh4::from_binary(&bvh, &Ordered { shapes: &[], bvh: &bvh }).nodes.is_empty());
    assert!(Bvh8::from_binary(&bvh, &Ordered { shapes: &[], bvh: &bvh }).nodes.is_empty());
    assert!(Bvh16::from_binary(&bvh, &Ordered { shapes: &[], bvh: &bvh }).nodes.is_empty());
    check(&[], rays(&mut rng));
    // One triangle.
    check(&[Shape::Triangle(Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y))], rays(&mut rng));
    // Zero-area triangles (a point and a line), mixed with a real one.
    let zero = vec![
        Shape::Triangle(Triangle::new(p, p, p)),
        Shape::Triangle(Triangle::new(Vec3A::ZERO, Vec3A::X, 2.0 * Vec3A::X)),
        Shape::Triangle(Triangle::new(Vec3A::ZERO, Vec3A::Y, Vec3A::Z)),
    ];
    check(&zero, rays(&mut rng));
    // NaN and infinite triangles are left out of the tree and never hit.
    let nan = [
        Shape::Triangle(Triangle::new(Vec3A::splat(f32::NAN), Vec3A::X, Vec3A::Y)),
        Shape::Triangle(Triangle::new(Vec3A::ZERO, Vec3A::splat(f32::INFINITY), Vec3A::Y)),
        Shape::Triangle(Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Z)),
    ];
    let bounds: Vec<Aabb> = nan.iter().map(Shape::bounds).collect();
    let bvh = Bvh::build(&bounds, &BuildParams::default());
    bvh.validate(&bounds).unwrap();
    assert_eq!(bvh.prim_indices, vec![2]);
    // All primitives in one point (centroids coincide: no SAH plane exists).
    let same: Vec<Shape> = (0..100).map(|_| Shape::Triangle(Triangle::new(p, p + Vec3A::X, p + Vec3A::Y))).collect();
    check(&same, rays(&mut rng));
    let bounds: Vec<Aabb> = same.iter().map(Shape::bounds).collect();
    let bvh = Bvh::build(&bounds, &BuildParams::default());
    assert!(bvh.stats().levels > 1, "a large inseparable set is still split by count");
    // NaN rays hit nothing and do not panic.
    let tri = [Shape::Triangle(Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y))];
    check(
        &tri,
        [Ray::new(Vec3A::splat(f32::NAN), Vec3A::Z), Ray::new(Vec3A::ZERO, Vec3A::splat(f32::NAN))].into_iter(),
    );
    // Lines rather than rays (intervals from -inf), down every axis: the empty child slots'
    // boxes at +inf must stay out of reach.
    let soup = random_soup(&mut rng, 300, 0.2);
    let lines: Vec<Ray> = random_rays(&mut rng, 200, 1.0)
        .into_iter()
        .map(|mut r| {
            r.dir = -r.dir.abs();
            r.t.min = f32::NEG_INFINITY;
            r
        })
        .collect();
    check(&soup, lines.iter().copied());
    let bounds: Vec<Aabb> = soup.iter().map(Shape::bounds).collect();
    let bvh = Bvh::build(&bounds, &BuildParams::default());
    let prims = Ordered { shapes: &soup, bvh: &bvh };
    let packets: Vec<Vec<Ray>> =
        lines.chunks(8).map(|c| c.iter().map(|r| Ray { origin: lines[0].origin, ..*r }).collect()).collect();
    for width in [8, 16] {
        check_packets(&WideTree::with_width(&bvh, &prims, width), &prims, &packets);
    }
    // Huge coordinates.
    let scaled = |shapes: Vec<Shape>, k: f32| -> Vec<Shape> {
        shapes
            .into_iter()
            .map(|s| match s {
                Shape::Triangle(t) => Shape::Triangle(Triangle::new(t.v0 * k, t.v1 * k, t.v2 * k)),
                other => other,
            })
            .collect()
    };
    let huge = scaled(random_soup(&mut rng, 200, 0.3), 1e6);
    check(&huge, random_rays(&mut rng, 300, 1e6).into_iter());
    // Coordinates so large that the boxes' areas, and with them every SAH cost, overflow to
    // infinity: the collapse still gives both sides of a split a slot.
    let vast = scaled(random_soup(&mut rng, 200, 0.3), 1e30);
    check(&vast, random_rays(&mut rng, 300, 1e30).into_iter());
}

#[test]
fn wide_bvh_handles_huge_leaves_and_lone_roots() {
    let mut rng = Rng(17);
    let p = Vec3A::new(0.1, 0.2, 0.3);
    // 300 primitives in one point and a build that never splits: one leaf larger than a
    // 4-wide leaf reference holds, which the collapse must spread over nodes.
    let same: Vec<Shape> = (0..300).map(|_| Shape::Triangle(Triangle::new(p, p + Vec3A::X, p + Vec3A::Y))).collect();
    let bounds: Vec<Aabb> = same.iter().map(Shape::bounds).collect();
    let lazy = BuildParams { max_leaf_size: 1000, traversal_cost: 1e9, ..BuildParams::default() };
    let bvh = Bvh::build(&bounds, &lazy);
    assert_eq!(bvh.nodes.len(), 1, "a single leaf root");
    check_with(&same, &bounds, &lazy, random_rays(&mut rng, 300, 1.0).into_iter());
    // A lone small leaf root.
    let one = [Shape::Triangle(Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y))];
    let b1: Vec<Aabb> = one.iter().map(Shape::bounds).collect();
    check_with(&one, &b1, &BuildParams::default(), random_rays(&mut rng, 300, 1.0).into_iter());
    // Leaves of many sizes.
    let soup = random_soup(&mut rng, 2000, 0.1);
    let bs: Vec<Aabb> = soup.iter().map(Shape::bounds).collect();
    let big_leaves = BuildParams { max_leaf_size: 40, traversal_cost: 30.0, ..BuildParams::default() };
    check_with(&soup, &bs, &big_leaves, random_rays(&mut rng, 1000, 1.2).into_iter());
}

#[test]
fn axis_parallel_rays_through_box_faces() {
    // Directions with zero components give infinite reciprocals; origins on slab planes give
    // 0 * inf = NaN, which the slab test must ignore rather than miss.
    let grid: Vec<Shape> = (0..10)
        .flat_map(|i| {
            (0..10).map(move |j| {
                let o = Vec3A::new(i as f32, j as f32, 0.0);
                Shape::Triangle(Triangle::new(o, o + Vec3A::X, o + Vec3A::Y))
            })
        })
        .collect();
    let mut rays = Vec::new();
    for i in 0..10 {
        for j in 0..10 {
            rays.push(Ray::new(Vec3A::new(i as f32 + 0.25, j as f32 + 0.25, -1.0), Vec3A::Z));
            rays.push(Ray::new(Vec3A::new(i as f32, j as f32 + 0.25, -1.0), Vec3A::Z));
            rays.push(Ray::new(Vec3A::new(-1.0, j as f32 + 0.1, 0.0), Vec3A::X));
        }
    }
    check(&grid, rays.into_iter());
}

fn scene_shapes(scene: &Scene) -> Vec<Shape> {
    let mut shapes = vec![None; scene.prim_count()];
    for (slot, &p) in scene.geometry.bvh.prim_indices.iter().enumerate() {
        shapes[p as usize] = Some(scene.geometry.shape(slot as u32));
    }
    shapes.into_iter().map(|s| s.unwrap()).collect()
}

/// The built-in scenes the BVH tests trace: those made in code, and the course's meshes when
/// their folder is there.
fn course_scene_names(assets: Option<&std::path::PathBuf>) -> Vec<&'static str> {
    let mut names = vec!["cornell-box", "cube", "single-triangle", "spheres"];
    if assets.is_some() {
        names.extend(["monkey", "teapot", "dragon"]);
    }
    names
}

#[test]
fn course_scenes_match_brute_force() {
    let assets = assets("course_scenes_match_brute_force");
    let names = course_scene_names(assets.as_ref());
    let mut rng = Rng(5);
    for name in names {
        let scene = builtin_scene(name, assets.as_ref());
        let shapes = scene_shapes(&scene);
        let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
        scene.geometry.bvh.validate(&bounds).unwrap();
        let n = if shapes.len() > 50_000 { 300 } else { 1500 };
        // Camera rays of the default view, and random rays through the scene.
        let cam = scene.camera();
        let mut rays: Vec<Ray> =
            (0..n / 2).map(|i| cam.pixel_ray((i * 37) as u32 % 100, (i * 53) as u32 % 100, 100, 100)).collect();
        rays.extend(random_rays(&mut rng, n / 2, 1.0));
        // The rendering tree traversed by the baseline code as well as by the detected one,
        // and the tree of the other width (8 or 16) that other CPUs render with.
        let g = &scene.geometry;
        let other = WideTree::with_width(&g.bvh, g, 24 - g.wide.width());
        other.validate(&g.bvh, &bounds).unwrap();
        let trees = [g.wide.clone().portable(), other.clone(), other.portable()];
        for ray in &rays {
            let got = scene.intersect(ray);
            let want = brute_closest(&shapes, ray);
            assert_eq!(got.map(|h| h.t), want.map(|w| w.1.t), "{name}: ray {ray:?}");
            assert_eq!(scene.occluded(ray), want.is_some(), "{name}");
            for t in &trees {
                let (w, level) = (t.width(), t.simd_level());
                assert_eq!(t.intersect(ray, g), g.wide.intersect(ray, g), "{name}: {w}-wide, {level:?}, {ray:?}");
                assert_eq!(t.occluded(ray, g), g.wide.occluded(ray, g), "{name}: {w}-wide, {level:?}, {ray:?}");
            }
        }
    }
}

#[test]
fn level_boxes_cover_every_primitive() {
    let mut rng = Rng(9);
    let shapes = random_soup(&mut rng, 3000, 0.05);
    let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
    let bvh = Bvh::build(&bounds, &BuildParams::default());
    let stats = bvh.stats();
    assert_eq!(stats.nodes, 2 * stats.leaves - 1);
    assert!(stats.mean_leaf_size >= 1.0 && stats.mean_leaf_size <= 8.0);
    for level in 0..stats.levels as u32 + 1 {
        let boxes = bvh.boxes_at_level(level);
        let covered: usize = boxes
            .iter()
            .map(|b| {
                let n = &bvh.nodes[b.node as usize];
                if n.is_leaf() { n.count as usize } else { count_below(&bvh, b.node as usize) }
            })
            .sum();
        assert_eq!(covered, shapes.len(), "level {level}");
    }
    assert_eq!(bvh.boxes_at_level(0).len(), 1);
}

fn count_below(bvh: &Bvh, i: usize) -> usize {
    let n = &bvh.nodes[i];
    if n.is_leaf() { n.count as usize } else { count_below(bvh, i + 1) + count_below(bvh, n.start as usize) }
}

#[test]
fn validate_catches_broken_trees() {
    let mut rng = Rng(1);
    let shapes = random_soup(&mut rng, 100, 0.1);
    let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
    let good = Bvh::build(&bounds, &BuildParams::default());
    let mut shrunk = good.clone();
    shrunk.nodes[1].max = shrunk.nodes[1].min;
    assert!(shrunk.validate(&bounds).is_err());
    let mut dup = good.clone();
    dup.prim_indices[1] = dup.prim_indices[0];
    assert!(dup.validate(&bounds).is_err());
    let mut bad_child = good.clone();
    bad_child.nodes[0].start = 0;
    assert!(bad_child.validate(&bounds).is_err());
}

/// Shadow rays grouped per shading point (`bvh::shadow`) get the answers of traversing the
/// tree one ray at a time: random points, lights and segments in random soups and in the
/// Cornell box, with hits and misses both frequent, on the detected SIMD level and the
/// portable one (the groups' triangle test is dispatched on it).
#[test]
fn shadow_groups_match_one_ray_at_a_time() {
    let mut rng = Rng(21);
    let (mut groups, mut blocked, mut open, mut gave_up) = (0, 0, 0, 0);
    let mut check_groups = |wide: &WideTree, prims: &dyn Primitives, rng: &mut Rng, scale: f32| {
        let portable = wide.clone().portable();
        for _ in 0..300 {
            let apex = rng.vec3(-scale, scale);
            let side = rng.dir();
            let center = rng.vec3(-scale, scale);
            let radius = rng.range(0.0, 0.3 * scale);
            let Some(occ) = wide.occluders(apex, side, center, radius) else {
                gave_up += 1;
                continue;
            };
            groups += 1;
            let occ_portable = portable.occluders(apex, side, center, radius).expect("the same list");
            for _ in 0..40 {
                // A point of the light's ball, seen from the apex on the side of `side`.
                let target = center + rng.dir() * radius * rng.f32().sqrt();
                let to = target - apex;
                if to.dot(side) <= 0.0 {
                    continue;
                }
                let ray = Ray::spawn_to(apex, Vec3A::ZERO, target, 0.0);
                let want = wide.occluded(&ray, prims);
                assert_eq!(wide.occluded_among(&ray, prims, &occ), want, "{ray:?} to {target:?}");
                assert_eq!(portable.occluded_among(&ray, prims, &occ_portable), want, "portable, {ray:?}");
                if want { blocked += 1 } else { open += 1 }
            }
        }
    };
    for (n, size) in [(1, 0.5), (50, 0.3), (2000, 0.05)] {
        let shapes = random_soup(&mut rng, n, size);
        let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
        let bvh = Bvh::build(&bounds, &BuildParams::default());
        let prims = Ordered { shapes: &shapes, bvh: &bvh };
        for width in [8, 16] {
            check_groups(&WideTree::with_width(&bvh, &prims, width), &prims, &mut rng, 1.2);
        }
    }
    let scene = builtin_scene("cornell-box-sphere-light", None);
    let g = &scene.geometry;
    check_groups(&g.wide, g, &mut rng, 0.6);
    check_groups(&WideTree::with_width(&g.bvh, g, 24 - g.wide.width()), g, &mut rng, 0.6);
    assert!(groups > 500 && blocked > 2000 && open > 2000 && gave_up > 10, "{groups} {blocked} {open} {gave_up}");
}

/// Packets of rays from one origin: a narrow cone (like neighbouring camera rays, nearly
/// always one direction sign per axis) or, one time in four, any directions (mixed signs,
/// which the packet code hands to single-ray traversal). Sizes 1 to 8; some rays bounded.
fn random_packets(rng: &mut Rng, n: usize, spread: f32) -> Vec<Vec<Ray>> {
    (0..n)
        .map(|_| {
            let origin = rng.vec3(-spread, spread);
            let axis = rng.dir();
            let wide_open = rng.f32() < 0.25;
            let len = 1 + (rng.f32() * 8.0) as usize % 8;
            (0..len)
                .map(|_| {
                    let dir = if wide_open { rng.dir() } else { (axis + rng.vec3(-0.03, 0.03)).normalize() };
                    let mut r = Ray::new(origin, dir);
                    if rng.f32() < 0.2 {
                        r.t.max = rng.range(0.1, 2.0);
                    }
                    r
                })
                .collect()
        })
        .collect()
}

/// Each ray of a packet gets exactly the single-ray traversal's hit, on the detected SIMD
/// level and the portable one.
fn check_packets<P: Primitives>(tree: &WideTree, prims: &P, packets: &[Vec<Ray>]) -> usize {
    let portable = tree.clone().portable();
    let mut hits = 0;
    for rays in packets {
        let got = tree.intersect_packet(rays, prims);
        assert_eq!(got, portable.intersect_packet(rays, prims), "SIMD levels, {rays:?}");
        for (i, hit) in got.iter().enumerate() {
            let want = rays.get(i).and_then(|r| tree.intersect(r, prims));
            assert_eq!(*hit, want, "ray {i} of {rays:?}");
            hits += usize::from(hit.is_some());
        }
    }
    hits
}

/// [`check_packets`] on the 8- and 16-wide trees over `shapes`; returns the hits.
fn check_packets_in(shapes: &[Shape], packets: &[Vec<Ray>]) -> usize {
    let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
    let bvh = Bvh::build(&bounds, &BuildParams::default());
    let prims = Ordered { shapes, bvh: &bvh };
    [8, 16].into_iter().map(|width| check_packets(&WideTree::with_width(&bvh, &prims, width), &prims, packets)).sum()
}

#[test]
fn packets_equal_single_rays() {
    let mut rng = Rng(21);
    let mut hits = 0;
    for (n, size) in [(0, 0.1), (1, 0.5), (10, 0.3), (1000, 0.1), (20_000, 0.03)] {
        let shapes = random_soup(&mut rng, n, size);
        let mut packets = random_packets(&mut rng, 1500, 1.5);
        // Rays that cannot go as a packet: a NaN direction, and two origins.
        let mut bad = packets[0].clone();
        bad.push(Ray::new(Vec3A::ZERO, Vec3A::new(f32::NAN, 0.0, 1.0)));
        packets.push(bad);
        packets.push(vec![Ray::new(Vec3A::ZERO, Vec3A::X), Ray::new(Vec3A::Y, Vec3A::X)]);
        hits += check_packets_in(&shapes, &packets);
    }
    assert!(hits > 2000, "the rays must actually hit things ({hits})");
}

#[test]
fn camera_packets_equal_single_rays_on_course_scenes() {
    let assets = assets("camera_packets_equal_single_rays_on_course_scenes");
    let names = course_scene_names(assets.as_ref());
    for name in names {
        let scene = builtin_scene(name, assets.as_ref());
        let cam = scene.camera();
        let (w, h) = (200u32, 150u32);
        let rays: Vec<Ray> =
            (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| cam.pixel_ray(x, y, w, h)).collect();
        let packets: Vec<Vec<Ray>> = rays.chunks(8).map(<[Ray]>::to_vec).collect();
        let g = &scene.geometry;
        let hits = check_packets(&g.wide, g, &packets);
        assert!(hits > 100, "{name}: {hits} hits");
        assert_eq!(check_packets(&WideTree::with_width(&g.bvh, g, 24 - g.wide.width()), g, &packets), hits);
    }
}

/// Tiles of rays from one origin, as a still pinhole's tile makes them: 1 to [`TILE_RUNS`]
/// runs of 1 to 8 rays in a narrow cone (a camera tile's rows), the last run often shorter
/// (the image's edge), some rays bounded; and tiles that cannot go as one (one run in
/// another direction octant, of mixed signs, from another origin, or empty), which go run by
/// run.
fn random_tiles(rng: &mut Rng, n: usize, spread: f32) -> Vec<Vec<Vec<Ray>>> {
    (0..n)
        .map(|i| {
            let origin = rng.vec3(-spread, spread);
            let axis = rng.dir();
            let runs = 1 + (rng.f32() * TILE_RUNS as f32) as usize % TILE_RUNS;
            let len = 1 + (rng.f32() * 8.0) as usize % 8;
            let mut tile: Vec<Vec<Ray>> = (0..runs)
                .map(|r| {
                    let len = if r + 1 == runs && rng.f32() < 0.3 { 1 + len / 2 } else { len };
                    (0..len)
                        .map(|_| {
                            let mut ray = Ray::new(origin, (axis + rng.vec3(-0.05, 0.05)).normalize());
                            if rng.f32() < 0.1 {
                                ray.t.max = rng.range(0.1, 2.0);
                            }
                            ray
                        })
                        .collect()
                })
                .collect();
            let r = i % tile.len();
            match i % 16 {
                0 => tile[r].iter_mut().for_each(|ray| *ray = Ray::new(origin, -ray.dir)),
                1 => tile[r].push(Ray::new(origin, rng.dir())),
                2 => tile[r][0] = Ray::new(origin + Vec3A::splat(1e-3), tile[r][0].dir),
                4 => tile[r].iter_mut().for_each(|ray| *ray = Ray::new(origin + Vec3A::splat(1e-3), ray.dir)),
                3 => tile[r].clear(),
                _ => {}
            }
            tile.iter_mut().for_each(|run| run.truncate(8));
            tile
        })
        .collect()
}

/// Each ray of a tile gets exactly the single-ray traversal's hit, on the detected SIMD level
/// and the portable one, and with observers; counts in `tiled` the tiles traced as one
/// (their rays told [`QueryKind::Tile`]). Returns the hits.
fn check_tiles<P: Primitives>(tree: &WideTree, prims: &P, tiles: &[Vec<Vec<Ray>>], tiled: &mut usize) -> usize {
    let portable = tree.clone().portable();
    let mut hits = 0;
    for tile in tiles {
        let runs: Vec<&[Ray]> = tile.iter().map(Vec::as_slice).collect();
        let got = tree.intersect_tile(&runs, prims);
        assert_eq!(got, portable.intersect_tile(&runs, prims), "SIMD levels, {runs:?}");
        let mut logs: [[TraversalLog; 8]; TILE_RUNS] = Default::default();
        assert_eq!(got, tree.intersect_tile_counted(&runs, prims, &mut logs), "observed, {runs:?}");
        *tiled += usize::from(logs[0][0].queries.first().is_some_and(|q| q.kind == QueryKind::Tile));
        for (r, run_hits) in got.iter().enumerate() {
            for (i, hit) in run_hits.iter().enumerate() {
                let want = runs.get(r).and_then(|run| run.get(i)).and_then(|ray| tree.intersect(ray, prims));
                assert_eq!(*hit, want, "ray {i} of run {r} of {runs:?}");
                hits += usize::from(hit.is_some());
            }
        }
    }
    hits
}

#[test]
fn tiles_equal_single_rays() {
    let mut rng = Rng(31);
    let (mut hits, mut tiled) = (0, 0);
    for (n, size) in [(0, 0.1), (1, 0.5), (10, 0.3), (1000, 0.1), (20_000, 0.03)] {
        let shapes = random_soup(&mut rng, n, size);
        let mut tiles = random_tiles(&mut rng, 400, 1.5);
        // No runs at all, and more runs than a tile holds (those beyond are not traced).
        tiles.push(Vec::new());
        tiles.push(vec![tiles[5][0].clone(); TILE_RUNS + 1]);
        let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
        let bvh = Bvh::build(&bounds, &BuildParams::default());
        let prims = Ordered { shapes: &shapes, bvh: &bvh };
        for width in [8, 16] {
            hits += check_tiles(&WideTree::with_width(&bvh, &prims, width), &prims, &tiles, &mut tiled);
        }
    }
    assert!(hits > 5000, "the rays must actually hit things ({hits})");
    // Of 4000 tiles (but the empty scene's), three in four can go as one.
    assert!(tiled > 2000, "tiles traced as one: {tiled}");
}

#[test]
fn camera_tiles_equal_single_rays_on_course_scenes() {
    let assets = assets("camera_tiles_equal_single_rays_on_course_scenes");
    for name in course_scene_names(assets.as_ref()) {
        let scene = builtin_scene(name, assets.as_ref());
        let cam = scene.camera();
        // Not multiples of the tile: the last tiles have shorter and fewer runs.
        let (w, h) = (203u32, 150u32);
        let tiles: Vec<Vec<Vec<Ray>>> = (0..h)
            .step_by(TILE_RUNS)
            .flat_map(|y0| (0..w).step_by(8).map(move |x0| (x0, y0)))
            .map(|(x0, y0)| {
                let rows = y0..(y0 + TILE_RUNS as u32).min(h);
                rows.map(|y| (x0..(x0 + 8).min(w)).map(|x| cam.pixel_ray(x, y, w, h)).collect()).collect()
            })
            .collect();
        let g = &scene.geometry;
        let mut tiled = 0;
        let hits = check_tiles(&g.wide, g, &tiles, &mut tiled);
        assert!(hits > 100, "{name}: {hits} hits");
        let other = WideTree::with_width(&g.bvh, g, 24 - g.wide.width());
        assert_eq!(check_tiles(&other, g, &tiles, &mut tiled), hits);
        // Every tile is traced as one: a pinhole's rays share the origin and, in a 50-degree
        // view, nearly always their direction signs.
        assert!(tiled > tiles.len(), "{name}: {tiled} of twice {} tiles traced as one", tiles.len());
    }
}

/// A shadow ray from `origin` towards a point light at `light`, stopping just short of it as
/// shadow rays do (up the y axis where the way there has no finite direction: at scales near
/// 1e30 its length overflows).
fn shadow_ray_to(origin: Vec3A, light: Vec3A) -> Ray {
    let to = light - origin;
    let mut r = Ray::new(origin, to.normalize_or(Vec3A::Y));
    r.t.max = to.length() * (1.0 - 1e-4);
    r
}

/// Packets of shadow rays: each ray from its own origin (scattered over a patch, as the hits
/// of neighbouring camera rays are) towards one light point, stopping short of it as shadow
/// rays do; one packet in four from origins anywhere in any directions, a few rays starting
/// before their origin. Sizes 1 to 8.
fn random_shadow_packets(rng: &mut Rng, n: usize, spread: f32) -> Vec<Vec<Ray>> {
    (0..n)
        .map(|_| {
            let light = rng.vec3(-2.0 * spread, 2.0 * spread);
            let patch = rng.vec3(-spread, spread);
            let scattered = rng.f32() < 0.25;
            let len = 1 + (rng.f32() * 8.0) as usize % 8;
            (0..len)
                .map(|_| {
                    let origin = if scattered { rng.vec3(-spread, spread) } else { patch + rng.vec3(-0.05, 0.05) };
                    let mut r = if scattered { Ray::new(origin, rng.dir()) } else { shadow_ray_to(origin, light) };
                    if rng.f32() < 0.05 {
                        r.t.min = -0.1;
                    }
                    r
                })
                .collect()
        })
        .collect()
}

/// Each ray of a packet of rays with their own origins gets exactly the single-ray any-hit
/// answer, on the detected SIMD level and the portable one. Returns the rays blocked.
fn check_shadow_packets<P: Primitives>(tree: &WideTree, prims: &P, packets: &[Vec<Ray>]) -> u32 {
    let portable = tree.clone().portable();
    let mut blocked = 0;
    for rays in packets {
        let got = tree.occluded_packet(rays, prims);
        assert_eq!(got, portable.occluded_packet(rays, prims), "SIMD levels, {rays:?}");
        assert_eq!(got >> rays.len(), 0, "bits beyond the packet, {rays:?}");
        // Each ray's record of the packet's walk is its walk alone: the same nodes and leaves
        // in the same order (what the debugger, which traces shadow rays alone, shows).
        let mut logs: [TraversalLog; 8] = Default::default();
        assert_eq!(tree.occluded_packet_counted(rays, prims, &mut logs), got);
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(got >> i & 1 == 1, tree.occluded(ray, prims), "ray {i} of {rays:?}");
            let mut alone = TraversalLog::default();
            tree.occluded_counted(ray, prims, &mut alone);
            // (Compared without the logged rays, which may hold a NaN.)
            let visits =
                |log: &TraversalLog| log.queries.iter().map(|q| (q.kind, q.entered.clone())).collect::<Vec<_>>();
            assert_eq!(visits(&logs[i]), visits(&alone), "ray {i} of {rays:?}");
        }
        blocked += got.count_ones();
    }
    blocked
}

/// [`check_shadow_packets`] on the 8- and 16-wide trees over `shapes`.
fn check_shadow_packets_in(shapes: &[Shape], packets: &[Vec<Ray>]) -> u32 {
    let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
    let bvh = Bvh::build(&bounds, &BuildParams::default());
    let prims = Ordered { shapes, bvh: &bvh };
    [8, 16]
        .into_iter()
        .map(|width| check_shadow_packets(&WideTree::with_width(&bvh, &prims, width), &prims, packets))
        .sum()
}

#[test]
fn shadow_packets_equal_single_rays() {
    let mut rng = Rng(22);
    let (mut blocked, mut rays) = (0, 0);
    for (n, size) in [(0, 0.1), (1, 0.5), (10, 0.3), (1000, 0.1), (20_000, 0.03)] {
        let shapes = random_soup(&mut rng, n, size);
        let mut packets = random_shadow_packets(&mut rng, 1500, 1.5);
        // A NaN direction and an infinite origin beside ordinary rays, and an empty packet.
        let mut bad = packets[0].clone();
        bad.truncate(6);
        bad.push(Ray::new(Vec3A::ZERO, Vec3A::new(f32::NAN, 0.0, 1.0)));
        bad.push(Ray::new(Vec3A::splat(f32::INFINITY), Vec3A::X));
        packets.push(bad);
        packets.push(Vec::new());
        rays += packets.iter().map(Vec::len).sum::<usize>() as u32 * 2;
        blocked += check_shadow_packets_in(&shapes, &packets);
    }
    assert!(blocked > 2000 && blocked < rays - 2000, "blocked and open rays both ({blocked} of {rays})");
}

/// The shadow rays the renderer traces ahead: from the course scenes' camera hits towards
/// each light, eight neighbouring pixels a packet.
#[test]
fn shadow_packets_equal_single_rays_on_course_scenes() {
    let assets = assets("shadow_packets_equal_single_rays_on_course_scenes");
    for name in course_scene_names(assets.as_ref()) {
        let scene = builtin_scene(name, assets.as_ref());
        let cam = scene.camera();
        let (w, h) = (200u32, 150u32);
        let options = rayscope::settings::ShadingOptions::default();
        let mut packets = Vec::new();
        for light in &scene.lights {
            for y in 0..h {
                for x0 in (0..w).step_by(8) {
                    let packet: Vec<Ray> = (x0..x0 + 8)
                        .filter_map(|x| {
                            let ray = cam.pixel_ray(x, y, w, h);
                            let si = scene.surface(&ray, &scene.intersect(&ray)?, &options);
                            let ls = light.center_sample(si.point);
                            (si.geo_normal.dot(ls.wi) > 0.0)
                                .then(|| Ray::spawn_towards(si.point, si.geo_normal, ls.wi, ls.distance, 0.0))
                        })
                        .collect();
                    packets.push(packet);
                }
            }
        }
        let g = &scene.geometry;
        let blocked = check_shadow_packets(&g.wide, g, &packets);
        assert_eq!(check_shadow_packets(&WideTree::with_width(&g.bvh, g, 24 - g.wide.width()), g, &packets), blocked);
    }
}

/// The inverse of a zero direction component is a power of two, so that `o * inv` is exact.
#[test]
fn zero_direction_components_invert_to_a_power_of_two() {
    let inv = safe_inv_dir(Vec3A::new(0.0, -1e-30, 1e-30));
    assert_eq!(inv.x, 2f32.powi(64));
    assert_eq!(inv.y, -(2f32.powi(64)));
    assert_eq!(inv.z, 2f32.powi(64));
    let o = 0.3f32;
    assert_eq!((o * inv.x) / inv.x, o);
}

/// The SAH collapse fills nodes (a greedy one left a third of the dragon's nodes with two
/// children) and keeps leaves within 16 triangles.
#[test]
fn collapse_fills_wide_nodes() {
    let mut rng = Rng(31);
    let shapes: Vec<Shape> =
        random_soup(&mut rng, 5000, 0.05).into_iter().filter(|s| matches!(s, Shape::Triangle(_))).collect();
    let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
    let bvh = Bvh::build(&bounds, &BuildParams::default());
    let prims = Ordered { shapes: &shapes, bvh: &bvh };
    let wide = Bvh8::from_binary(&bvh, &prims);
    wide.validate(&bvh, &bounds).unwrap();
    let children: usize = wide.nodes.iter().map(|n| n.child.iter().filter(|&&c| c != ChildRef::EMPTY).count()).sum();
    let mean = children as f32 / wide.nodes.len() as f32;
    assert!(mean >= 6.0, "mean children per node {mean}");
    assert!(wide.ranges.is_empty(), "every leaf of triangles is packed");
    for n in &wide.nodes {
        for &c in &n.child {
            if c != ChildRef::EMPTY && c.is_packed() {
                let blocks = c.packed_blocks().len();
                assert!(blocks <= 4, "a leaf of {blocks} blocks");
            }
        }
    }
}

/// A 16-wide tree is no deeper than the binary tree it comes from, and the course's meshes
/// and a chain of ever larger boxes (the deepest binary tree the SAH makes) fit the
/// traversals' fixed stack; where one would not, `WideTree` falls back to 8 children.
#[test]
fn sixteen_wide_trees_fit_the_stack() {
    let chain: Vec<Shape> = (0..64)
        .map(|i| {
            let x = 1.5f32.powi(i);
            Shape::Triangle(Triangle::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x, 1.0, 0.0), Vec3A::new(x, 0.0, 1.0)))
        })
        .collect();
    let mut rng = Rng(41);
    for shapes in [chain, random_soup(&mut rng, 20_000, 0.02)] {
        let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
        let bvh = Bvh::build(&bounds, &BuildParams::default());
        let prims = Ordered { shapes: &shapes, bvh: &bvh };
        let wide = Bvh16::from_binary(&bvh, &prims);
        assert!(wide.depth() <= bvh.stats().levels, "{} > {}", wide.depth(), bvh.stats().levels);
        assert!(wide.fits_stack());
        assert_eq!(WideTree::with_width(&bvh, &prims, 16).width(), 16);
    }
    let assets = assets("sixteen_wide_trees_fit_the_stack");
    for name in course_scene_names(assets.as_ref()) {
        let g = &builtin_scene(name, assets.as_ref()).geometry;
        assert!(Bvh16::from_binary(&g.bvh, g).fits_stack(), "{name}");
    }
}

/// Scales of the soups the properties draw: unit, large and small; and huge and tiny, where
/// every triangle test overflows or underflows (so nothing is hit, and no tree may say so).
const SCALES: [f32; 5] = [1.0, 1e6, 1e-6, 1e30, 1e-30];

/// A coordinate at `scale`: mostly anywhere in `[-scale, scale]`, sometimes one of a few fixed
/// values, so that vertices, edges and box planes coincide.
fn coordinate(scale: f32) -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => (-1.0f32..=1.0).prop_map(move |x| x * scale),
        1 => prop::sample::select(&[0.0f32, 0.5, -1.0][..]).prop_map(move |x| x * scale),
    ]
}

/// A point at `scale` (see [`coordinate`]).
fn point(scale: f32) -> impl Strategy<Value = Vec3A> {
    [coordinate(scale), coordinate(scale), coordinate(scale)].prop_map(Vec3A::from_array)
}

/// Triangles at `scale`: one in general position, a degenerate one (all vertices in one point,
/// collinear vertices, a vertex repeated), or two that share an edge.
fn triangles(scale: f32) -> impl Strategy<Value = Vec<Shape>> {
    let p = move || point(scale);
    prop_oneof![
        4 => (p(), p(), p()).prop_map(|(a, b, c)| vec![Triangle::new(a, b, c)]),
        1 => p().prop_map(|a| vec![Triangle::new(a, a, a)]),
        1 => (p(), p(), -2.0f32..2.0).prop_map(|(a, b, s)| vec![Triangle::new(a, b, a + (b - a) * s)]),
        1 => (p(), p()).prop_map(|(a, b)| vec![Triangle::new(a, b, a)]),
        1 => (p(), p(), p(), p()).prop_map(|(a, b, c, d)| vec![Triangle::new(a, b, c), Triangle::new(b, a, d)]),
    ]
    .prop_map(|tris| tris.into_iter().map(Shape::Triangle).collect())
}

/// A ray into `shapes` at `scale`: from anywhere around them, towards a point of one of the
/// triangles or in any direction (axis-parallel ones among them, and the zero vector), over
/// the half-line or a bounded interval. Directions are drawn at unit scale, so that the
/// triangle test's products stay finite wherever the soup's do.
fn ray(scale: f32, shapes: Vec<Shape>) -> impl Strategy<Value = Ray> {
    let aim = (prop::bool::weighted(0.7), any::<prop::sample::Index>(), 0.0f32..=1.0, 0.0f32..=1.0);
    let interval = prop::option::weighted(0.2, 0.0f32..3.0);
    (point(2.0 * scale), point(1.0), aim, interval).prop_map(move |(origin, dir, (aim, at, u, v), t_max)| {
        let dir = match point_on(&shapes, at, u, v) {
            Some(p) if aim => (p - origin) * (1.0 / scale),
            _ => dir,
        };
        let mut ray = Ray::new(origin, dir);
        if let Some(t) = t_max {
            ray.t.max = t * scale;
        }
        ray
    })
}

/// The point of shape `at` of `shapes` at barycentrics `(u, v)` (both in `[0, 1]`, folded
/// into the triangle where `u + v > 1`), if that shape is a triangle.
fn point_on(shapes: &[Shape], at: prop::sample::Index, u: f32, v: f32) -> Option<Vec3A> {
    let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
    match shapes.get(at.index(shapes.len().max(1))) {
        Some(Shape::Triangle(t)) => Some(t.v0 + u * (t.v1 - t.v0) + v * (t.v2 - t.v0)),
        _ => None,
    }
}

/// Whether brute force's answer is one a BVH must give for `ray`: every primitive hit within
/// the ray's interval is hit no nearer than its own box. On a (nearly) degenerate triangle
/// the triangle test can report a hit outside the triangle's box (its determinant is rounding
/// noise); a tree, which culls by boxes, cannot be held to find that one.
fn unambiguous(shapes: &[Shape], ray: &Ray) -> bool {
    let inv = safe_inv_dir(ray.dir);
    shapes.iter().all(|s| {
        s.intersect(ray, ray.t.min, ray.t.max)
            .is_none_or(|h| h.t >= s.bounds().hit_distance(ray.origin, inv, ray.t.min, ray.t.max))
    })
}

/// A triangle soup at one of [`SCALES`], and that scale.
fn soup() -> impl Strategy<Value = (f32, Vec<Shape>)> {
    prop::sample::select(&SCALES[..]).prop_flat_map(|scale| {
        (Just(scale), prop::collection::vec(triangles(scale), 0..40).prop_map(|parts| parts.concat()))
    })
}

/// A triangle soup and rays into it.
fn soup_and_rays() -> impl Strategy<Value = (Vec<Shape>, Vec<Ray>)> {
    soup().prop_flat_map(|(scale, shapes)| {
        let rays = prop::collection::vec(ray(scale, shapes.clone()), 1..32);
        (Just(shapes), rays)
    })
}

/// A triangle soup and packets of up to eight rays into it, each packet's from one origin.
fn soup_and_packets() -> impl Strategy<Value = (Vec<Shape>, Vec<Vec<Ray>>)> {
    soup().prop_flat_map(|(scale, shapes)| {
        let packet = prop::collection::vec(ray(scale, shapes.clone()), 1..=8)
            .prop_map(|rays| rays.iter().map(|r| Ray { origin: rays[0].origin, ..*r }).collect());
        (Just(shapes), prop::collection::vec(packet, 1..8))
    })
}

proptest! {
    // Half a second each. Failures are not saved to files: the failing case is printed, and
    // one worth keeping becomes a test of its own.
    #![proptest_config(ProptestConfig { cases: 1024, failure_persistence: None, ..ProptestConfig::default() })]

    /// On arbitrary triangle soups, degenerate and huge or tiny ones included, the binary tree
    /// and the 4-, 8- and 16-wide trees, on the detected SIMD level and the portable one, give
    /// brute force's closest hit (the same primitive, or the same distance where triangles
    /// share an edge) and its any-hit answer.
    #[test]
    fn soups_match_brute_force((shapes, rays) in soup_and_rays()) {
        check(&shapes, rays.into_iter().filter(|ray| unambiguous(&shapes, ray)));
    }

    /// Packets of rays from one origin into such soups get, ray by ray, the single-ray
    /// traversal's hits, at both widths and on the detected and the portable SIMD level.
    #[test]
    fn soup_packets_equal_single_rays((shapes, packets) in soup_and_packets()) {
        check_packets_in(&shapes, &packets);
    }
}

/// A triangle soup and packets of up to eight rays into it, each ray from its own origin.
fn soup_and_shadow_packets() -> impl Strategy<Value = (Vec<Shape>, Vec<Vec<Ray>>)> {
    soup().prop_flat_map(|(scale, shapes)| {
        let packet = prop::collection::vec(ray(scale, shapes.clone()), 1..=8);
        (Just(shapes), prop::collection::vec(packet, 1..8))
    })
}

/// A triangle soup and packets of up to eight shadow rays towards one light far outside it,
/// each through a point of a triangle (often a vertex or an edge: the boxes' corners and
/// faces) from a little behind it, or from the point itself.
fn soup_and_converging_shadow_packets() -> impl Strategy<Value = (Vec<Shape>, Vec<Vec<Ray>>)> {
    soup().prop_flat_map(|(scale, shapes)| {
        let corner = prop_oneof![Just(0.0f32), Just(1.0), 0.0f32..=1.0];
        let aim = (any::<prop::sample::Index>(), corner.clone(), corner, prop_oneof![Just(0.0f32), 0.0f32..0.5]);
        let packet = (point(1.0), prop::collection::vec(aim, 1..=8));
        let triangles = shapes.clone();
        let packets = prop::collection::vec(packet, 1..8).prop_map(move |packets| {
            packets
                .into_iter()
                .map(|(light, aims)| {
                    let light = light.normalize_or(Vec3A::X) * (3.0 * scale);
                    aims.into_iter()
                        .map(|(at, u, v, behind)| {
                            let point = point_on(&triangles, at, u, v).unwrap_or(Vec3A::ZERO);
                            shadow_ray_to(point + (point - light) * behind, light)
                        })
                        .collect()
                })
                .collect()
        });
        (Just(shapes), packets)
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, failure_persistence: None, ..ProptestConfig::default() })]

    /// Packets of rays with their own origins into such soups get, ray by ray, the single-ray
    /// any-hit answer, at both widths and on the detected and the portable SIMD level.
    #[test]
    fn soup_shadow_packets_equal_single_rays((shapes, packets) in soup_and_shadow_packets()) {
        check_shadow_packets_in(&shapes, &packets);
    }

    /// So do shadow rays converging on a light through the soup's vertices and edges, where
    /// the boxes' tests are closest to their rounding.
    #[test]
    fn converging_shadow_packets_equal_single_rays((shapes, packets) in soup_and_converging_shadow_packets()) {
        check_shadow_packets_in(&shapes, &packets);
    }
}

/// Every split rule (the SAH the renderer builds with, and the median and the seed's mean rule
/// `rayscope bench` compares it with) yields a valid tree that gives brute force's hits, on
/// random soups and inseparable sets.
#[test]
fn every_split_rule_builds_a_valid_tree_with_brute_force_hits() {
    let mut rng = Rng(23);
    let p = Vec3A::new(0.3, 0.2, 0.1);
    let same: Vec<Shape> = (0..40).map(|_| Shape::Triangle(Triangle::new(p, p + Vec3A::X, p + Vec3A::Y))).collect();
    for split_rule in SplitRule::ALL {
        let params = BuildParams { split_rule, ..BuildParams::default() };
        for shapes in [random_soup(&mut rng, 3000, 0.1), random_soup(&mut rng, 7, 0.5), same.clone()] {
            let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
            let hits = check_with(&shapes, &bounds, &params, random_rays(&mut rng, 400, 1.5).into_iter());
            assert!(shapes.len() < 3000 || hits > 50, "{split_rule:?}: the rays must hit things ({hits})");
        }
    }
}

/// The SAH's candidates are the builder's: at every inner node of a SAH tree (serial and
/// parallel builds) the chosen plane is the candidate of least cost and splits the node's
/// primitives as the builder did (the left child holds the chosen plane's left count).
#[test]
fn the_chosen_split_is_the_cheapest_candidate_and_the_builders() {
    let mut rng = Rng(29);
    for n in [2, 9, 300, 5000, 40_000] {
        let shapes = random_soup(&mut rng, n, 0.05);
        let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
        let params = BuildParams::default();
        let bvh = Bvh::build(&bounds, &params);
        let mut inner = 0;
        // Every node of small trees; a sample of the big ones' (the root and its neighbours).
        for node in (0..bvh.nodes.len() as u32).take(600) {
            let c = split_candidates(&bvh, &bounds, node, &params).unwrap();
            assert_eq!(c.split, !bvh.nodes[node as usize].is_leaf());
            let costs = c.axis.iter().flatten().filter_map(|k| k.cost);
            if let Some(chosen) = c.chosen_candidate() {
                let least = costs.fold(f32::INFINITY, f32::min);
                assert_eq!(chosen.cost, Some(least), "node {node} of {n}");
                assert_eq!(chosen.left + chosen.right, c.prims);
                if c.split {
                    inner += 1;
                    assert_eq!(c.left_child_prims, Some(chosen.left), "node {node} of {n}: the builder's split");
                }
            }
            // Planes lie inside the node's box, in increasing order per axis.
            for (axis, planes) in c.axis.iter().enumerate() {
                assert!(planes.iter().all(|k| k.position >= c.min[axis] && k.position <= c.max[axis]));
                assert!(planes.windows(2).all(|w| w[0].position <= w[1].position));
            }
        }
        assert!(n < 9 || inner > 0);
    }
    let bvh = Bvh::build(&[], &BuildParams::default());
    assert!(split_candidates(&bvh, &[], 0, &BuildParams::default()).is_none());
}
