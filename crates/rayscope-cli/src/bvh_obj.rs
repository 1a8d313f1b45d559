//! `rayscope debug --export-bvh-level N FILE.obj`: the boxes of one level of a BVH as line
//! cubes in a Wavefront OBJ file (eight `v` corners and twelve `l` edges a box), one group for
//! the level's nodes and one for the leaves at or above it, so that the tree opens in Blender
//! or any OBJ viewer beside the scene.

use std::io::Write;
use std::path::Path;

use anyhow::{Result, bail};
use rayscope::geometry::Aabb;
use rayscope::output::write_file;
use rayscope::scene::Scene;

pub use rayscope::bvh::BvhTree;

/// The boxes of one level, split as the file's groups.
struct LevelBoxes {
    nodes: Vec<Aabb>,
    leaves: Vec<Aabb>,
}

/// The boxes of `level` of `tree`: its nodes at that level, and its leaves at or above it.
fn level_boxes(scene: &Scene, tree: BvhTree, level: u32) -> Result<LevelBoxes> {
    let (levels, boxes): (u32, Vec<(bool, Aabb)>) = match tree {
        BvhTree::Wide => {
            (scene.wide_levels(), scene.wide_boxes_at_level(level).iter().map(|b| (b.is_leaf(), b.bounds)).collect())
        }
        BvhTree::Binary => (
            scene.bvh_stats().levels as u32,
            scene.geometry.bvh.boxes_at_level(level).iter().map(|b| (b.is_leaf, b.bounds)).collect(),
        ),
    };
    if level >= levels {
        bail!(
            "BVH level {level} does not exist: the {} tree has levels 0 to {}",
            tree_name(scene, tree),
            levels as i64 - 1
        );
    }
    let (leaves, nodes): (Vec<_>, Vec<_>) = boxes.into_iter().partition(|(leaf, _)| *leaf);
    Ok(LevelBoxes {
        nodes: nodes.into_iter().map(|b| b.1).collect(),
        leaves: leaves.into_iter().map(|b| b.1).collect(),
    })
}

/// What the tree is called in messages and the file's header: "16-wide", "binary".
fn tree_name(scene: &Scene, tree: BvhTree) -> String {
    match tree {
        BvhTree::Wide => format!("{}-wide", scene.geometry.wide.width()),
        BvhTree::Binary => "binary".into(),
    }
}

/// The twelve edges of a box whose corners are numbered by their bits (x: 1, y: 2, z: 4).
const EDGES: [(usize, usize); 12] =
    [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)];

/// Write `boxes` as group `name`: each box's corners, then its edges; `next` is the OBJ index
/// of the next vertex (1-based), advanced past the corners written.
fn write_group(out: &mut impl Write, name: &str, boxes: &[Aabb], next: &mut usize) -> std::io::Result<()> {
    writeln!(out, "g {name}")?;
    for b in boxes {
        for corner in 0..8 {
            let pick = |axis: usize| if corner >> axis & 1 == 0 { b.min[axis] } else { b.max[axis] };
            writeln!(out, "v {} {} {}", pick(0), pick(1), pick(2))?;
        }
        for (a, c) in EDGES {
            writeln!(out, "l {} {}", *next + a, *next + c)?;
        }
        *next += 8;
    }
    Ok(())
}

/// Write the boxes of `level` of `tree` to `path` (atomically); returns the boxes written.
pub fn export_level(scene: &Scene, tree: BvhTree, level: u32, path: &Path) -> Result<usize> {
    let boxes = level_boxes(scene, tree, level)?;
    let name = tree_name(scene, tree);
    write_file(path, |out| {
        writeln!(
            out,
            "# rayscope: level {level} of the {name} BVH of {}: {} node boxes at the level, {} leaf boxes at or above it",
            scene.name,
            boxes.nodes.len(),
            boxes.leaves.len()
        )?;
        writeln!(out, "o bvh-{name}-level-{level}")?;
        let mut next = 1;
        write_group(out, &format!("level-{level}-nodes"), &boxes.nodes, &mut next)?;
        write_group(out, &format!("level-{level}-leaves"), &boxes.leaves, &mut next)
    })?;
    Ok(boxes.nodes.len() + boxes.leaves.len())
}
