//! Bloom in the viewer: the *Bloom* panel and its layer views. The worker applies bloom to
//! every frame it posts (so *Save image* writes what `rayscope render` would) and shows the
//! layer chosen: the image, the bright pass, or the bright pass blurred.

use egui::Ui;
use rayscope::film::FloatImage;
use rayscope::math::Color;
use rayscope::post::bloom;
use rayscope::settings::{BloomSettings, MAX_BLOOM_RADIUS};

use crate::state::ViewerState;

/// Which of bloom's layers the ray-traced view shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BloomLayer {
    /// The image, with the glow added.
    #[default]
    Image,
    /// The bright pass: what exceeds the threshold.
    Bright,
    /// The bright pass blurred by the Gaussian: the glow before its strength.
    Blurred,
}

impl BloomLayer {
    const ALL: [(BloomLayer, &'static str, &'static str); 3] = [
        (BloomLayer::Image, "Image", "The ray-traced image with the glow added"),
        (BloomLayer::Bright, "Bright pass", "Per channel, what exceeds the threshold: max(c - threshold, 0)"),
        (
            BloomLayer::Blurred,
            "Blurred",
            "The bright pass blurred by the Gaussian: the glow, added to the image times the strength",
        ),
    ];
}

/// The image a frame saves (`film`, bloomed) and the one it shows (`layer` of it).
pub fn frame_images(film: FloatImage, settings: &BloomSettings, layer: BloomLayer) -> (FloatImage, FloatImage) {
    if settings.is_off() {
        return (film.clone(), film);
    }
    let pixels: Vec<Color> = film.data.chunks_exact(3).map(Color::from_slice).collect();
    let (w, h) = (film.width, film.height);
    let layers = bloom::layers(&pixels, w, h, settings);
    let image = |px: &[Color]| FloatImage { data: px.iter().flat_map(|c| c.to_array()).collect(), ..film.clone() };
    let mut saved = film.clone();
    bloom::apply_to_image(&mut saved, settings);
    let shown = match layer {
        BloomLayer::Image => saved.clone(),
        BloomLayer::Bright => image(&layers.bright),
        BloomLayer::Blurred => image(&layers.blurred),
    };
    (saved, shown)
}

/// The *Bloom* panel: strength (0 is off), threshold, radius, and the layer shown.
pub fn panel(ui: &mut Ui, st: &mut ViewerState) {
    let mut b = st.settings.bloom;
    ui.add(egui::Slider::new(&mut b.strength, 0.0..=4.0).text("Strength"))
        .on_hover_text("Factor on the blurred bright pass added to the image; 0 turns bloom off (--bloom-strength)");
    ui.add(egui::Slider::new(&mut b.threshold, 0.0..=8.0).text("Threshold"))
        .on_hover_text("Values above this (linear, per channel) glow (--bloom-threshold)");
    ui.add(egui::Slider::new(&mut b.radius, 0.0..=MAX_BLOOM_RADIUS.min(128.0)).text("Radius (pixels)")).on_hover_text(
        "Reach of the glow's Gaussian in pixels; its standard deviation is a third of it (--bloom-radius)",
    );
    if b != st.settings.bloom {
        let settings = rayscope::settings::RenderSettings { bloom: b, ..st.settings.clone() };
        st.set_settings(settings);
    }
    ui.horizontal(|ui| {
        let before = st.bloom_layer;
        egui::ComboBox::from_label("Layer")
            .selected_text(BloomLayer::ALL.iter().find(|l| l.0 == st.bloom_layer).map_or("", |l| l.1))
            .show_ui(ui, |ui| {
                for (layer, label, tip) in BloomLayer::ALL {
                    ui.selectable_value(&mut st.bloom_layer, layer, label).on_hover_text(tip);
                }
            })
            .response
            .on_hover_text("Which of bloom's layers the ray-traced view shows");
        if st.bloom_layer != before {
            st.generation += 1;
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn film() -> FloatImage {
        let mut data = vec![0.2; 8 * 6 * 3];
        data[(3 * 8 + 4) * 3] = 5.0;
        FloatImage { width: 8, height: 6, channels: 3, data }
    }

    #[test]
    fn off_shows_and_saves_the_film_and_on_each_layer_is_the_library_s() {
        let off = BloomSettings::default();
        assert_eq!(frame_images(film(), &off, BloomLayer::Bright), (film(), film()));
        let on = BloomSettings { threshold: 1.0, radius: 2.0, strength: 0.5 };
        let pixels: Vec<Color> = film().data.chunks_exact(3).map(Color::from_slice).collect();
        let layers = bloom::layers(&pixels, 8, 6, &on);
        let mut bloomed = film();
        bloom::apply_to_image(&mut bloomed, &on);
        for (layer, want) in [(BloomLayer::Bright, &layers.bright), (BloomLayer::Blurred, &layers.blurred)] {
            let (saved, shown) = frame_images(film(), &on, layer);
            assert_eq!(saved, bloomed, "the saved image has the glow whatever the layer");
            let shown: Vec<Color> = shown.data.chunks_exact(3).map(Color::from_slice).collect();
            assert_eq!(&shown, want);
        }
        assert_eq!(frame_images(film(), &on, BloomLayer::Image).1, bloomed);
    }
}
