//! The BVH heat map: what it counts, its colour ramp from the fewest to the most nodes a camera
//! ray tested, and the legend that gives that scale. A heat map without its scale is one flat
//! colour that says nothing (the Cornell box's camera rays all test the same 8 boxes).

use egui::{Color32, Sense, Vec2};
use rayscope::film::FloatImage;

use crate::plural::counted;

/// The ramp's stops, from the fewest nodes (dark blue) to the most (red).
const RAMP: [[f32; 3]; 5] = [[0.0, 0.0, 0.3], [0.0, 0.4, 1.0], [0.0, 0.9, 0.5], [1.0, 0.9, 0.0], [1.0, 0.1, 0.0]];

/// What a heat-map frame measured: the spread of BVH node boxes tested per camera ray, the
/// tree they were tested in, and how long it took.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeatScale {
    /// The fewest boxes any camera ray tested (the ramp's first colour).
    pub min: u32,
    /// The most boxes any camera ray tested (the ramp's last colour).
    pub max: u32,
    /// Boxes per camera ray, averaged over the image.
    pub mean: f32,
    /// Children per node of the tree the renderer traverses (8 or 16).
    pub width: usize,
    /// Nodes of that tree.
    pub nodes: usize,
    /// Camera rays traced (one per pixel, through its centre, but for the culled pixels).
    pub rays: u64,
    /// Pixels in tiles the renderer culls (`rayscope::render::TileCulling`): no ray traced;
    /// the map shows each its share of its tile's frustum test.
    pub culled: u64,
    /// Time the traversals took, in milliseconds.
    pub millis: f64,
}

impl HeatScale {
    /// The scale of `aov`, the library's nodes-visited AOV of one camera ray per pixel, of
    /// which `culled` pixels were in tiles the renderer culls.
    pub fn of(aov: &FloatImage, width: usize, nodes: usize, culled: u64, millis: f64) -> HeatScale {
        let (min, max, sum) = aov
            .data
            .iter()
            .fold((f32::INFINITY, 0.0f32, 0.0f64), |(lo, hi, sum), &v| (lo.min(v), hi.max(v), sum + v as f64));
        let pixels = aov.data.len() as u64;
        let min = if pixels == 0 { 0.0 } else { min };
        HeatScale {
            min: min as u32,
            max: max as u32,
            mean: (sum / pixels.max(1) as f64) as f32,
            width,
            nodes,
            rays: pixels.saturating_sub(culled),
            culled,
            millis,
        }
    }

    /// Where `nodes` falls on the ramp, 0 to 1. When every ray tested as many boxes, the
    /// whole image takes the ramp's middle colour, and the legend says that there is no
    /// spread to show.
    pub fn position(&self, nodes: f32) -> f32 {
        if self.max == self.min {
            return 0.5;
        }
        ((nodes - self.min as f32) / (self.max - self.min) as f32).clamp(0.0, 1.0)
    }

    /// The heat map's colours for `aov`.
    pub fn image(&self, aov: &FloatImage) -> FloatImage {
        let data = aov.data.iter().flat_map(|&v| ramp(self.position(v))).collect();
        FloatImage { width: aov.width, height: aov.height, channels: 3, data }
    }

    /// Camera rays per second, in millions.
    pub fn mrays_per_s(&self) -> f64 {
        self.rays as f64 / (self.millis * 1e3).max(1e-9)
    }

    /// What the heat map shows and its scale, as the panel gives it.
    pub fn legend(&self, ui: &mut egui::Ui) {
        ui.label(format!(
            "BVH node boxes tested per camera ray, in the {}-wide tree the renderer traverses ({})",
            self.width,
            counted(self.nodes as u64, "node", "nodes"),
        ));
        ramp_bar(ui);
        if self.min == self.max {
            ui.label(format!("every ray tested {}: no spread to show", counted(self.max as u64, "box", "boxes")));
        } else {
            ui.label(format!("{} (blue) to {} (red) boxes per ray, mean {:.1}", self.min, self.max, self.mean));
        }
        ui.label(format!(
            "{} camera rays (one per pixel) in {:.1} ms, {:.2} Mrays/s",
            self.rays,
            self.millis,
            self.mrays_per_s()
        ));
        if self.culled > 0 {
            let pixels = self.rays + self.culled;
            ui.label(format!(
                "{} ({:.0}%) in tiles whose frustum meets no box: not traced, each its share of the tile's test",
                counted(self.culled, "pixel", "pixels"),
                100.0 * self.culled as f64 / pixels as f64
            ));
        }
    }
}

/// The ramp drawn as a bar, from its first colour (left) to its last, for a legend.
pub(crate) fn ramp_bar(ui: &mut egui::Ui) {
    let (rect, _) = ui.allocate_exact_size(Vec2::new(ui.available_width().min(260.0), 14.0), Sense::hover());
    let steps = 64;
    for i in 0..steps {
        let (a, b) = (i as f32 / steps as f32, (i + 1) as f32 / steps as f32);
        let x = |t: f32| rect.min.x + t * rect.width();
        let cell = egui::Rect::from_x_y_ranges(x(a)..=x(b), rect.y_range());
        ui.painter().rect_filled(cell, 0.0, color32(ramp((a + b) * 0.5)));
    }
}

/// The ramp's colour at `t` (0 to 1), linear RGB.
pub(crate) fn ramp(t: f32) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0) * (RAMP.len() - 1) as f32;
    let i = (t as usize).min(RAMP.len() - 2);
    let f = t - i as f32;
    let (a, b) = (RAMP[i], RAMP[i + 1]);
    [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f]
}

/// The egui colour of linear RGB `c` (clamped to [0, 1]).
pub(crate) fn color32(c: [f32; 3]) -> Color32 {
    let u = |v: f32| (v.clamp(0.0, 1.0) * 255.0) as u8;
    Color32::from_rgb(u(c[0]), u(c[1]), u(c[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn aov(values: &[f32]) -> FloatImage {
        FloatImage { width: values.len() as u32, height: 1, channels: 1, data: values.to_vec() }
    }

    #[test]
    fn the_scale_runs_from_the_fewest_to_the_most_nodes() {
        let a = aov(&[3.0, 5.0, 11.0, 5.0]);
        let s = HeatScale::of(&a, 8, 9, 0, 2.0);
        assert_eq!((s.min, s.max, s.mean, s.rays), (3, 11, 6.0, 4));
        // Culled pixels count in the scale and the mean, not in the rays traced.
        let c = HeatScale::of(&aov(&[0.25, 16.0, 32.0, 0.25]), 16, 9, 2, 2.0);
        assert_eq!((c.min, c.max, c.rays, c.culled), (0, 32, 2, 2));
        assert_eq!((s.position(3.0), s.position(11.0), s.position(7.0)), (0.0, 1.0, 0.5));
        let img = s.image(&a);
        let close = |c: &[f32], want: [f32; 3]| c.iter().zip(want).all(|(c, w)| (c - w).abs() < 1e-6);
        assert!(close(&img.data[0..3], RAMP[0]) && close(&img.data[6..9], RAMP[4]), "{:?}", img.data);
        assert!((s.mrays_per_s() - 0.002).abs() < 1e-9);
    }

    #[test]
    fn a_flat_map_takes_the_middle_colour() {
        let s = HeatScale::of(&aov(&[8.0; 6]), 8, 9, 0, 1.0);
        assert_eq!((s.min, s.max), (8, 8));
        assert_eq!(s.position(8.0), 0.5);
    }
}
