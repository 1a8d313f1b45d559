//! `rayscope view SCENE --compare THEIRS.png`: a student's image beside ours. The scene is
//! rendered once with the settings, from the scene's camera, as `rayscope compare` renders it
//! (the library's [`rayscope::compare`] measures the two); three views show their image, our
//! render and the difference image, and the debugger panel shows, for the selected pixel, both
//! values (8-bit and float) beside our ray tree.
//!
//! The views are still images of the scene's camera: a click in one of them puts the camera
//! back there first, so the ray tree traced is the pixel compared. Our render is made again
//! (*Compare again*) only when asked: with many samples it takes seconds, which a settings
//! slider must not cost on every step.

use std::path::{Path, PathBuf};

use egui::{Color32, TextureHandle};
use rayscope::compare::{CompareImage, Comparison, Depth, compare, read_image};
use rayscope::film::FloatImage;
use rayscope::output::{Encoding, to_rgb8};
use rayscope::render::render;
use rayscope::scene::Scene;
use rayscope::settings::RenderSettings;

use crate::state::{ViewKind, ViewerState};

/// Their image, our render, what the comparison found, and the views' textures.
pub struct CompareViews {
    /// Their image's file.
    pub path: PathBuf,
    /// Their image.
    pub theirs: CompareImage,
    /// Our render as it was compared (8-bit for an 8-bit image of theirs).
    pub ours: CompareImage,
    /// Our render's float values.
    pub ours_float: FloatImage,
    /// What the comparison found.
    pub comparison: Comparison,
    /// The settings our render was made with.
    pub settings: RenderSettings,
    /// The difference image.
    pub difference: FloatImage,
    /// Textures of the three views, made when first shown.
    textures: Option<[TextureHandle; 3]>,
}

/// One pixel in both images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelValues {
    /// The pixel, `(x, y)` from the top-left.
    pub pixel: (u32, u32),
    /// Their value: 8-bit levels and `[0, 1]` floats (for an 8-bit image, the levels / 255).
    pub theirs: ([u8; 3], [f32; 3]),
    /// Ours, the same way; the floats are our render's own.
    pub ours: ([u8; 3], [f32; 3]),
    /// The largest channel error, where the 8-bit values differ.
    pub error: Option<f32>,
}

/// The views the comparison adds, with their labels and tooltips.
pub const COMPARE_VIEWS: [(ViewKind, &str, &str); 3] = [
    (ViewKind::Theirs, "Theirs", "Your image (--compare), as read"),
    (
        ViewKind::Ours,
        "Ours",
        "rayscope's render compared with it: the scene's camera and the settings of the comparison",
    ),
    (
        ViewKind::Difference,
        "Difference",
        "Black where the 8-bit pixels are equal; purple (1 level) to white (255) by the error",
    ),
];

impl CompareViews {
    /// Read `path` and compare it with `scene` rendered with `settings` (whose size must be
    /// the image's); the error says what went wrong, naming the file.
    pub fn new(path: &Path, scene: &Scene, settings: &RenderSettings) -> Result<CompareViews, String> {
        let theirs = read_image(path).map_err(|e| e.to_string())?;
        let mut ours_float = render(scene, settings, &|_| {}).film.to_image();
        rayscope::post::bloom::apply_to_image(&mut ours_float, &settings.bloom);
        let ours = CompareImage::from_render(
            &ours_float,
            theirs.depth,
            Encoding::Linear,
            format!("rayscope's render of {}", scene.name),
        );
        let comparison = compare(&theirs, &ours).map_err(|e| e.to_string())?;
        let difference = comparison.difference_image();
        Ok(CompareViews {
            path: path.to_path_buf(),
            theirs,
            ours,
            ours_float,
            comparison,
            settings: settings.clone(),
            difference,
            textures: None,
        })
    }

    /// Pixel `(x, y)` in both images.
    pub fn values_at(&self, x: u32, y: u32) -> PixelValues {
        let eight = |img: &FloatImage| -> [u8; 3] {
            let p = FloatImage { width: 1, height: 1, channels: 3, data: img.pixel(x, y).to_vec() };
            let v = to_rgb8(&p, Encoding::Linear);
            [v[0], v[1], v[2]]
        };
        let floats = |img: &FloatImage| -> [f32; 3] {
            let p = img.pixel(x, y);
            [p[0], p[1], p[2]]
        };
        let ours_eight = match self.ours.depth {
            Depth::EightBit => eight(&self.ours.image),
            Depth::Float => eight(&self.ours_float),
        };
        PixelValues {
            pixel: (x, y),
            theirs: (eight(&self.theirs.image), floats(&self.theirs.image)),
            ours: (ours_eight, floats(&self.ours_float)),
            error: self.comparison.error_at(x, y),
        }
    }

    /// The image a comparison view shows.
    fn image(&self, view: ViewKind) -> Option<(usize, &FloatImage)> {
        match view {
            ViewKind::Theirs => Some((0, &self.theirs.image)),
            ViewKind::Ours => Some((1, &self.ours_float)),
            ViewKind::Difference => Some((2, &self.difference)),
            _ => None,
        }
    }

    /// The texture of `view` (one of [`COMPARE_VIEWS`]), made the first time.
    pub fn texture(&mut self, ctx: &egui::Context, view: ViewKind) -> Option<egui::TextureId> {
        let (i, _) = self.image(view)?;
        if self.textures.is_none() {
            let made = COMPARE_VIEWS.map(|(v, ..)| {
                let (_, img) = self.image(v).expect("a comparison view");
                let rgb = to_rgb8(img, Encoding::Linear);
                let color = egui::ColorImage::from_rgb([img.width as usize, img.height as usize], &rgb);
                ctx.load_texture(format!("rayscope compare {v:?}"), color, egui::TextureOptions::NEAREST)
            });
            self.textures = Some(made);
        }
        self.textures.as_ref().map(|t| t[i].id())
    }

    /// The panel: what the comparison found and, for `pixel`, both values.
    pub fn panel(&self, ui: &mut egui::Ui, pixel: Option<(u32, u32)>, settings: &RenderSettings) -> bool {
        let c = &self.comparison;
        let mut again = false;
        egui::CollapsingHeader::new("Comparison").default_open(true).show(ui, |ui| {
            ui.label(format!("{} with {}", self.path.display(), self.ours.name));
            ui.strong(c.summary());
            ui.label(format!("mean error {:.5} ({:.2} levels)", c.mean_error.overall, c.mean_error.overall * 255.0));
            ui.label(format!("max error {:.5} ({:.0} levels)", c.max_error.overall, c.max_error.overall * 255.0));
            if let Some(s) = c.ssim {
                ui.label(format!("SSIM {s:.5} (1 = identical)"));
            }
            if *settings != self.settings {
                ui.colored_label(ui.visuals().warn_fg_color, "The settings changed since this comparison.");
            }
            again = ui
                .button("Compare again")
                .on_hover_text("Render the scene again with the current settings and compare")
                .clicked();
            let Some((x, y)) = pixel else {
                ui.label("Click a pixel to see both values.");
                return;
            };
            let v = self.values_at(x, y);
            match v.error {
                Some(e) => {
                    ui.colored_label(Color32::from_rgb(255, 150, 60), format!("pixel ({x}, {y}) differs by {e:.5}"))
                }
                None => ui.label(format!("pixel ({x}, {y}) is equal")),
            };
            for (name, (eight, float)) in [("theirs", v.theirs), ("ours", v.ours)] {
                ui.horizontal(|ui| {
                    let (r, _) = ui.allocate_exact_size(egui::Vec2::splat(14.0), egui::Sense::hover());
                    ui.painter().rect_filled(r, 2.0, Color32::from_rgb(eight[0], eight[1], eight[2]));
                    ui.label(format!(
                        "{name}: ({}, {}, {}) · ({:.4}, {:.4}, {:.4})",
                        eight[0], eight[1], eight[2], float[0], float[1], float[2]
                    ));
                });
            }
        });
        again
    }
}

impl ViewerState {
    /// Compare the image at `path` with the current scene and settings; on failure the error
    /// (naming the file) is in [`ViewerState::error`] and the last comparison stays.
    pub fn load_compare(&mut self, path: &Path) {
        match CompareViews::new(path, &self.scene, &self.settings) {
            Ok(c) => self.compare = Some(c),
            Err(e) => self.error = Some(e),
        }
    }

    /// Render and compare again with the current scene and settings.
    pub fn recompare(&mut self) {
        if let Some(path) = self.compare.as_ref().map(|c| c.path.clone()) {
            self.load_compare(&path);
        }
    }

    /// The pixel values of the selected pixel in both images, when comparing.
    pub fn compared_values(&self) -> Option<PixelValues> {
        let (c, sel) = (self.compare.as_ref()?, self.selection.as_ref()?);
        let (x, y) = sel.first().pixel;
        Some(c.values_at(x, y))
    }

    /// A click on pixel `(x, y)`: in a comparison view the camera goes back to the scene's
    /// (the one compared) first, so that the ray tree is that pixel's.
    pub fn click_pixel(&mut self, x: u32, y: u32) {
        if COMPARE_VIEWS.iter().any(|(v, ..)| *v == self.view) {
            self.reset_camera();
        }
        self.select_pixel(x, y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cornell-box state at 64x48 and their image, the render with shadows off, saved as PNG.
    fn compared() -> (ViewerState, tempfile::TempDir) {
        let mut s = ViewerState::new("cornell-box", None);
        s.set_settings(RenderSettings { width: 64, height: 48, ..s.settings.clone() });
        let dir = tempfile::tempdir().unwrap();
        let theirs = dir.path().join("theirs.png");
        let settings = RenderSettings { shadows: false, ..s.settings.clone() };
        let img = render(&s.scene, &settings, &|_| {}).film.to_image();
        rayscope::output::write_image(&img, &theirs, Encoding::Linear).unwrap();
        s.load_compare(&theirs);
        assert!(s.error.is_none(), "{:?}", s.error);
        (s, dir)
    }

    #[test]
    fn a_comparison_gives_three_views_and_both_values_of_a_clicked_pixel() {
        let (mut s, _dir) = compared();
        let c = s.compare.as_ref().unwrap();
        assert!(c.comparison.differing > 0, "the shadows are missing from theirs");
        for (view, ..) in COMPARE_VIEWS {
            let (_, img) = c.image(view).unwrap();
            assert_eq!((img.width, img.height), (64, 48));
        }
        assert_eq!(c.ours_float, render(&s.scene, &s.settings, &|_| {}).film.to_image());
        let (x, y) = c.comparison.differing_pixels().next().unwrap();
        let (equal_x, equal_y) = (0..48)
            .flat_map(|y| (0..64).map(move |x| (x, y)))
            .find(|&(x, y)| c.comparison.error_at(x, y).is_none())
            .unwrap();
        // A click in the difference view, after orbiting: the camera goes back, the pixel is
        // traced, and both values are there.
        s.view = ViewKind::Difference;
        s.trackball.orbit(20.0, 10.0);
        s.click_pixel(x, y);
        assert_eq!(s.trackball, crate::trackball::Trackball::from_desc(&s.scene.camera));
        assert_eq!(s.selection.as_ref().unwrap().first().pixel, (x, y));
        let v = s.compared_values().unwrap();
        let c = s.compare.as_ref().unwrap();
        assert_ne!(v.theirs.0, v.ours.0, "a differing pixel's 8-bit values differ");
        assert_eq!(v.error, c.comparison.error_at(x, y));
        let ours = c.ours_float.pixel(x, y);
        assert_eq!(v.ours.1, [ours[0], ours[1], ours[2]]);
        assert_eq!(v.theirs.1, v.theirs.0.map(|l| f32::from(l) / 255.0));
        s.click_pixel(equal_x, equal_y);
        let v = s.compared_values().unwrap();
        assert_eq!((v.theirs.0, v.error), (v.ours.0, None));
    }

    #[test]
    fn a_bad_or_mismatched_image_is_an_error_naming_it() {
        let (mut s, dir) = compared();
        let bad = dir.path().join("bad.png");
        std::fs::write(&bad, b"no image").unwrap();
        s.load_compare(&bad);
        assert!(s.error.as_ref().unwrap().contains("bad.png"), "{:?}", s.error);
        assert!(s.compare.is_some(), "the last comparison stays");
        s.error = None;
        s.set_settings(RenderSettings { width: 32, ..s.settings.clone() });
        s.recompare();
        let err = s.error.as_ref().unwrap();
        assert!(err.contains("theirs.png is 64x48") && err.contains("32x48"), "{err}");
    }
}
