//! The SAH's choice at a node of the binary BVH, shown: the node's candidate split planes
//! drawn in 3D across its box (the plane taken in its own colour) and a chart of their costs
//! per axis, from [`rayscope::bvh::split_candidates`] (the builder's own numbers).

use egui::{Color32, Pos2, Sense, Stroke, Vec2};
use rayscope::bvh::{BuildParams, SplitCandidates, split_candidates};
use rayscope::math::Vec3;
use rayscope::scene::Scene;

use crate::overlay::Lines;

/// Colours of the x, y and z axes' planes and curves.
pub const AXIS_COLORS: [[f32; 4]; 3] = [[0.95, 0.35, 0.3, 1.0], [0.4, 0.85, 0.35, 1.0], [0.35, 0.55, 1.0, 1.0]];
/// Colour of the plane the SAH took.
pub const CHOSEN_COLOR: [f32; 4] = [1.0, 0.95, 0.2, 1.0];
/// Colour of the node's box.
pub const NODE_COLOR: [f32; 4] = [1.0, 1.0, 1.0, 1.0];

/// A node's candidates, computed once when the node is chosen.
#[derive(Clone, Debug)]
pub struct SplitView {
    /// The node (its index in the binary BVH).
    pub node: u32,
    /// Its candidates, `None` when the scene has no such node.
    pub candidates: Option<SplitCandidates>,
}

impl SplitView {
    /// The candidates of `node` of `scene`'s binary BVH.
    pub fn new(scene: &Scene, node: u32) -> SplitView {
        let g = &scene.geometry;
        SplitView { node, candidates: split_candidates(&g.bvh, &g.build_bounds(), node, &BuildParams::default()) }
    }

    /// The node's box and its planes as overlay lines: each candidate a rectangle across the
    /// box, perpendicular to its axis, in the axis's colour at half strength; the one taken
    /// in [`CHOSEN_COLOR`].
    pub fn lines(&self, out: &mut Lines) {
        let Some(c) = &self.candidates else { return };
        let (lo, hi) = (Vec3::from_array(c.min), Vec3::from_array(c.max));
        out.aabb(lo, hi, NODE_COLOR);
        for (axis, planes) in c.axis.iter().enumerate() {
            for (i, k) in planes.iter().enumerate() {
                let chosen = c.chosen.is_some_and(|ch| ch.axis == axis && ch.index == i);
                let [r, g, b, _] = AXIS_COLORS[axis];
                let color = if chosen { CHOSEN_COLOR } else { [r * 0.6, g * 0.6, b * 0.6, 1.0] };
                let (mut a, mut z) = (lo, hi);
                a[axis] = k.position;
                z[axis] = k.position;
                // The rectangle's four corners in the plane.
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let corner = |su: bool, sv: bool| {
                    let mut p = a;
                    p[u] = if su { z[u] } else { a[u] };
                    p[v] = if sv { z[v] } else { a[v] };
                    p
                };
                let q = [corner(false, false), corner(true, false), corner(true, true), corner(false, true)];
                for j in 0..4 {
                    out.line(q[j], q[(j + 1) % 4], color);
                }
            }
        }
    }

    /// The panel: the node's numbers and the chart of cost per plane, one curve per axis over
    /// the plane's position across the node's box, the plane taken marked.
    pub fn panel(&self, ui: &mut egui::Ui) {
        let Some(c) = &self.candidates else {
            ui.label(format!("node {} does not exist in the binary tree", self.node));
            return;
        };
        ui.label(format!(
            "node {} (depth {}): {} primitives, {} bins per axis; leaf cost {:.2}; {}",
            c.node,
            c.depth,
            c.prims,
            c.bins,
            c.leaf_cost,
            match (c.chosen_candidate(), c.split) {
                (Some(k), true) => format!(
                    "split at {} = {:.3} (cost {:.2}): {} | {}",
                    ["x", "y", "z"][c.chosen.map_or(0, |ch| ch.axis)],
                    k.position,
                    k.cost.unwrap_or(f32::NAN),
                    k.left,
                    k.right
                ),
                (Some(k), false) => format!("kept as a leaf (best plane's cost {:.2})", k.cost.unwrap_or(f32::NAN)),
                (None, true) => "split by count (no plane separates the centroids)".into(),
                (None, false) => "a leaf: no plane separates the centroids".into(),
            }
        ));
        chart(ui, c);
    }
}

/// Cost (vertical) per plane position (horizontal, across the node's box on each axis).
fn chart(ui: &mut egui::Ui, c: &SplitCandidates) {
    let (rect, response) = ui.allocate_exact_size(Vec2::new(ui.available_width().min(320.0), 140.0), Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_gray(24));
    let costs = c.axis.iter().flatten().filter_map(|k| k.cost).filter(|x| x.is_finite());
    let (lo, hi) = costs.fold((c.leaf_cost, c.leaf_cost), |(a, b), x| (a.min(x), b.max(x)));
    let span = (hi - lo).max(1e-6);
    let inner = rect.shrink(6.0);
    let y = |cost: f32| inner.bottom() - (cost - lo) / span * inner.height();
    let x = |axis: usize, pos: f32| {
        let (a, b) = (c.min[axis], c.max[axis]);
        inner.left() + ((pos - a) / (b - a).max(1e-12)).clamp(0.0, 1.0) * inner.width()
    };
    // The leaf's cost, for reference: a split is taken where a plane is below it.
    let leaf_y = y(c.leaf_cost);
    painter.line_segment([Pos2::new(inner.left(), leaf_y), Pos2::new(inner.right(), leaf_y)], (1.0, Color32::GRAY));
    for (axis, planes) in c.axis.iter().enumerate() {
        let color = rgba(AXIS_COLORS[axis]);
        let points: Vec<Pos2> =
            planes.iter().filter_map(|k| k.cost.map(|cost| Pos2::new(x(axis, k.position), y(cost)))).collect();
        painter.add(egui::Shape::line(points.clone(), Stroke::new(1.5, color)));
        for p in points {
            painter.circle_filled(p, 2.0, color);
        }
    }
    if let (Some(ch), Some(k)) = (c.chosen, c.chosen_candidate()) {
        let p = Pos2::new(x(ch.axis, k.position), y(k.cost.unwrap_or(lo)));
        painter.circle_stroke(p, 5.0, Stroke::new(2.0, rgba(CHOSEN_COLOR)));
    }
    response.on_hover_ui(|ui| {
        ui.label(
            "SAH cost of every candidate plane: x red, y green, z blue, each across the node's box \
             (left to right); higher is costlier. The grey line is the cost of a leaf; the yellow \
             ring marks the plane taken (the cheapest). Planes with nothing on one side are left out.",
        );
    });
}

fn rgba(c: [f32; 4]) -> Color32 {
    Color32::from_rgb((c[0] * 255.0) as u8, (c[1] * 255.0) as u8, (c[2] * 255.0) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayscope::scene::Scene;

    #[test]
    fn the_node_box_and_every_plane_are_drawn_the_chosen_one_in_its_colour() {
        let scene = Scene::load("cornell-box", None).unwrap();
        let view = SplitView::new(&scene, 0);
        let c = view.candidates.as_ref().expect("the root exists");
        let mut out = Lines::default();
        view.lines(&mut out);
        let planes: usize = c.axis.iter().map(Vec::len).sum();
        // Two vertices a segment: the box's 12 edges and each plane's 4.
        assert_eq!(out.0.len(), 2 * (12 + 4 * planes));
        let chosen = out.0.iter().filter(|v| v.color == CHOSEN_COLOR).count();
        assert_eq!(chosen, if c.chosen.is_some() { 8 } else { 0 });
        assert!(SplitView::new(&scene, u32::MAX).candidates.is_none());
    }
}
