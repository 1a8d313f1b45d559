//! The debugger's record of the BVH traversal is the renderer's: for random pixels of the
//! built-in scenes (the dragon too, with the course's files), the camera ray's recorded nodes
//! are those the renderer's packet (or tile) traversal enters for it, their count is the heat map's, and
//! every recorded visit of every ray of the tree (reflections, glossy and transmission rays,
//! shadow rays) lies within the ray's interval and hangs from a node visited before it.

mod common;

use common::{Rng, assets, builtin_scene};
use rayscope::aov::{Aov, render_aov};
use rayscope::bvh::{PACKET, QueryKind, TILE_RUNS, TraversalLog, TraversalStats, WideRef};
use rayscope::camera::RayGenerator;
use rayscope::math::{Vec2, Vec3A};
use rayscope::ray::{Interval, Ray};
use rayscope::record::{RayTree, RecordedTraversal};
use rayscope::render::{TILE_ROWS, TileCulling, trace_pixel, traces_camera_tiles};
use rayscope::scene::{Scene, builtin::BUILTINS};
use rayscope::settings::RenderSettings;

/// Small images: the runs of pixels, packets and tiles are the same at any size.
fn settings(scene: &Scene) -> RenderSettings {
    let base = scene.render.clone().unwrap_or_default();
    RenderSettings { width: 61, height: 40, spp: 1, light_samples: 6, gloss_samples: 3, ..base }
}

/// The scenes of the test: every built-in one whose files are here.
fn scenes(test: &str) -> Vec<Scene> {
    let assets = assets(test);
    BUILTINS
        .iter()
        .filter(|b| !b.needs_assets || assets.is_some())
        .map(|b| builtin_scene(b.name, assets.as_ref()))
        .collect()
}

/// What a query entered, by name, in order.
fn names(t: &RecordedTraversal) -> Vec<WideRef> {
    t.visits.iter().map(|v| v.at).collect()
}

#[test]
fn camera_ray_records_what_the_renderers_packet_entered_and_the_heat_map_counts() {
    let mut rng = Rng(15);
    let (mut culled, mut tiled) = (0, 0);
    let scenes = scenes("camera_ray_records_what_the_renderers_packet_entered");
    let tiles = scenes.iter().any(traces_camera_tiles);
    for scene in scenes {
        let s = settings(&scene);
        let width = scene.geometry.wide.width();
        let heat = render_aov(&scene, &s, &scene.camera(), Aov::NodesVisited, &|_| {});
        let rays = RayGenerator::new(&scene.camera(), s.width, s.height);
        for _ in 0..12 {
            let (x, y) = ((rng.f32() * s.width as f32) as u32, (rng.f32() * s.height as f32) as u32);
            let mut tree = RayTree::default();
            trace_pixel(&scene, &s, &scene.camera_motion(), x, y, 0, &mut tree);
            let camera = &tree.rays[0];
            let recorded = camera.traversal.as_ref().expect("the camera ray's traversal is recorded");

            // The renderer's packet for this pixel: its run of the row, one sample at the
            // pixel centres, traced by the scene's packet traversal with an observer; or, in
            // a scene the renderer traces by tiles, the tile of its run (the runs of the
            // rows of its band of TILE_ROWS), traced as one.
            let x0 = x - x % PACKET as u32;
            let run = |y| (x0..(x0 + PACKET as u32).min(s.width)).map(|x| rays.ray(x, y, Vec2::splat(0.5))).collect();
            let lane = (x - x0) as usize;
            let (hits, logs) = if traces_camera_tiles(&scene) {
                tiled += 1;
                let y0 = y - y % TILE_ROWS as u32;
                let runs: Vec<Vec<Ray>> = (y0..(y0 + TILE_ROWS as u32).min(s.height)).map(run).collect();
                let tile: Vec<&[Ray]> = runs.iter().map(Vec::as_slice).collect();
                let mut logs: [[TraversalLog; PACKET]; TILE_RUNS] = Default::default();
                let hits = scene.intersect_tile_counted(&tile, &mut logs);
                let r = (y - y0) as usize;
                (hits[r], std::mem::take(&mut logs[r]))
            } else {
                let run: Vec<Ray> = run(y);
                let mut logs: [TraversalLog; PACKET] = Default::default();
                (scene.intersect_packet_counted(&run, &mut logs), logs)
            };
            let expected = &RecordedTraversal::from_log(&scene, &logs[lane])[0];
            assert_eq!(recorded.query, expected.query, "{} ({x}, {y})", scene.name);
            assert_eq!(names(recorded), names(expected), "{} ({x}, {y}): the recorded visits", scene.name);
            assert_eq!(camera.hit.map(|h| h.t), hits[lane].map(|h| h.t), "{} ({x}, {y})", scene.name);

            // The heat map's count: the boxes of every node entered.
            // In a tile the renderer culls, no ray is traced: the pixel's share of the boxes
            // the tile's frustum test looked at.
            let count = heat.data[(y * s.width + x) as usize];
            let culling = TileCulling::of(&scene, &s, &scene.camera_motion());
            match culling.and_then(|c| c.culled_tile(x, y)) {
                Some((tile, test)) => {
                    culled += 1;
                    assert!(camera.hit.is_none(), "{} ({x}, {y}): a culled pixel's ray hits", scene.name);
                    let share = (width as u32 * test.nodes) as f32 / tile.pixels() as f32;
                    assert_eq!(count, share, "{} ({x}, {y}): heat map of a culled tile", scene.name);
                }
                _ => assert_eq!(
                    count,
                    (recorded.nodes() * width) as f32,
                    "{} ({x}, {y}): heat map against record",
                    scene.name
                ),
            }
        }
    }
    assert!(culled > 0, "no pixel of a culled tile was drawn");
    assert_eq!(tiles, tiled > 0, "pixels of a scene traced by tiles");
}

/// The distances at which `ray` enters and leaves box `[min, max]`, in double precision.
fn slab(ray: &Ray, min: [f32; 3], max: [f32; 3]) -> (f64, f64) {
    let (mut near, mut far) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        let (o, d) = (f64::from(ray.origin[a]), f64::from(ray.dir[a]));
        let (lo, hi) = (f64::from(min[a]), f64::from(max[a]));
        if d == 0.0 {
            if o < lo || o > hi {
                return (f64::INFINITY, f64::NEG_INFINITY);
            }
            continue;
        }
        let (t0, t1) = ((lo - o) / d, (hi - o) / d);
        near = near.max(t0.min(t1));
        far = far.min(t0.max(t1));
    }
    (near, far)
}

/// Check what one query entered: the root first, every later visit a child of a node
/// visited before it, one level below it; and, for a query of one ray (the packet's leaves
/// too, which each ray tests itself), every box but the root's (where every traversal
/// starts, testing its children) met within the ray's interval.
fn check_query(scene: &Scene, t: &RecordedTraversal, what: &str) {
    let ray = t.ray();
    let Some(first) = t.visits.first() else { return };
    assert_eq!((first.at, first.level), (WideRef::Node(0), 0), "{what}: starts at the root");
    for (i, v) in t.visits.iter().enumerate() {
        let parent_level = match v.at {
            _ if i == 0 => None,
            // A leaf's parent is named; a node's is one of the nodes visited before it.
            WideRef::Leaf { parent, .. } => {
                t.visits[..i].iter().find(|p| p.at == WideRef::Node(parent)).map(|p| p.level)
            }
            WideRef::Node(_) => t.visits[..i].iter().find(|p| p.level + 1 == v.level).map(|p| p.level),
        };
        assert!(i == 0 || parent_level == Some(v.level - 1), "{what}: {:?} hangs from no node visited before it", v.at);
        assert_eq!(scene.wide_box(v.at).map(|b| (b.min.to_array(), b.max.to_array())), Some((v.min, v.max)));
        // The root is where every traversal starts: its children's boxes are the first tested.
        let one_ray = i > 0
            && match t.query {
                QueryKind::ClosestHit | QueryKind::AnyHit => true,
                QueryKind::Packet | QueryKind::Tile => matches!(v.at, WideRef::Leaf { .. }),
                QueryKind::ShadowGroup => false,
            };
        if one_ray {
            let (near, far) = slab(&ray, v.min, v.max);
            // The traversal's box test is conservative by a bound on its rounding.
            let slack = 1e-4 * (1.0 + near.abs().max(far.abs().min(1e6)));
            let (t_min, t_max) = (f64::from(ray.t.min), f64::from(ray.t.max));
            assert!(
                near.max(t_min) <= far.min(t_max) + slack,
                "{what}: {:?} entered, but the ray meets its box over [{near}, {far}], outside [{t_min}, {t_max}]",
                v.at
            );
        }
    }
}

#[test]
fn every_ray_of_the_tree_records_visits_within_its_interval() {
    let mut rng = Rng(51);
    let mut kinds = std::collections::HashSet::new();
    let scenes = scenes("every_ray_of_the_tree_records_visits_within_its_interval");
    // Camera tiles in the course's big meshes; without their files, built-in scenes are small.
    let tiles = scenes.iter().any(traces_camera_tiles).then_some(QueryKind::Tile);
    for scene in scenes {
        let s = settings(&scene);
        let width = scene.geometry.wide.width() as u32;
        for _ in 0..8 {
            let (x, y) = ((rng.f32() * s.width as f32) as u32, (rng.f32() * s.height as f32) as u32);
            let mut tree = RayTree::default();
            trace_pixel(&scene, &s, &scene.camera_motion(), x, y, 0, &mut tree);
            for (i, r) in tree.rays.iter().enumerate() {
                let what = format!("{} ({x}, {y}) ray {i} ({:?})", scene.name, r.kind);
                let t = r.traversal.as_ref().expect("every ray's traversal is recorded");
                kinds.insert(t.query);
                check_query(&scene, t, &what);
                if t.query == QueryKind::ClosestHit {
                    // The count the renderer's own traversal makes of the same ray.
                    let mut stats = TraversalStats::default();
                    scene.intersect_counted(&t.ray(), &mut stats);
                    assert_eq!(stats.nodes_visited, t.nodes() as u32 * width, "{what}");
                }
                for (j, shadow) in r.shadows.iter().enumerate() {
                    assert!(!shadow.traversals.is_empty(), "{what} shadow {j}: its traversal is recorded");
                    for q in &shadow.traversals {
                        kinds.insert(q.query);
                        check_query(&scene, q, &format!("{what} shadow {j}"));
                    }
                }
            }
        }
    }
    let always = [QueryKind::Packet, QueryKind::ClosestHit, QueryKind::AnyHit, QueryKind::ShadowGroup];
    for kind in always.into_iter().chain(tiles) {
        assert!(kinds.contains(&kind), "no {kind:?} query was recorded: the test misses a path");
    }
}

#[test]
fn a_short_interval_stops_the_traversal() {
    // A ray along the Cornell box's depth, cut short: no box beyond its end is entered.
    let scene = builtin_scene("cornell-box", None);
    let full = Ray::new(Vec3A::new(0.0, 0.0, 3.0), Vec3A::new(0.01, 0.02, -1.0).normalize());
    let mut leaves = Vec::new();
    for t_max in [0.5, 2.0, 2.5, 3.0, f32::INFINITY] {
        let ray = Ray { t: Interval { min: 0.0, max: t_max }, ..full };
        let mut log = TraversalLog::default();
        scene.intersect_counted(&ray, &mut log);
        let t = &RecordedTraversal::from_log(&scene, &log)[0];
        assert_eq!((t.t_min, t.t_max), (0.0, t_max));
        check_query(&scene, t, &format!("t_max {t_max}"));
        leaves.push(t.leaves());
    }
    // Short of the box (which starts 2 units away) no leaf is entered; the whole ray enters some.
    assert_eq!(leaves[0], 0, "{leaves:?}");
    assert!(leaves.windows(2).all(|w| w[0] <= w[1]) && leaves[4] > 0, "{leaves:?}");
}

#[test]
fn wide_levels_cover_the_tree() {
    for scene in scenes("wide_levels_cover_the_tree") {
        let levels = scene.wide_levels();
        let nodes: usize =
            (0..levels).map(|l| scene.wide_boxes_at_level(l).iter().filter(|b| !b.is_leaf()).count()).sum();
        assert_eq!(nodes, scene.geometry.wide.node_count(), "{}: every node at one level", scene.name);
        // The deepest level holds only leaves (a node has children below it).
        let last = scene.wide_boxes_at_level(levels - 1);
        assert!(last.iter().all(|b| b.is_leaf()), "{}: the deepest level is leaves", scene.name);
    }
}
