//! The mip-level view: every pixel coloured by the mip level trilinear filtering reads at its
//! first textured hit (the library's [`rayscope::aov::Aov::MipLevel`], traced by the renderer
//! with its ray cones, through mirrors), on the heat map's ramp from level 0 (dark blue, the
//! texture's own texels) to the top level (red, the 1x1 mean), with the legend that gives the
//! scale. Pixels that read no texture are grey.

use rayscope::film::FloatImage;

use crate::heat::{ramp, ramp_bar};

/// Grey, for pixels that read no texture.
const UNTEXTURED: [f32; 3] = [0.25, 0.25, 0.25];

/// What a mip-level frame measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MipScale {
    /// The ramp's top: the highest level of the scene's textures (at least 1).
    pub top: u32,
    /// The highest level any pixel read.
    pub max: f32,
    /// Pixels that read a texture.
    pub textured: usize,
    /// Pixels in the image.
    pub pixels: usize,
    /// Time the frame took, in milliseconds.
    pub millis: f64,
}

impl MipScale {
    /// The scale of `aov`, the library's mip-level AOV, for textures whose highest level is
    /// `top`.
    pub fn of(aov: &FloatImage, top: u32, millis: f64) -> MipScale {
        let read = aov.data.iter().filter(|l| **l >= 0.0);
        MipScale {
            top: top.max(1),
            max: read.clone().fold(0.0, |m, l| m.max(*l)),
            textured: read.count(),
            pixels: aov.data.len(),
            millis,
        }
    }

    /// The view's colours for `aov`.
    pub fn image(&self, aov: &FloatImage) -> FloatImage {
        let colour = |l: f32| if l >= 0.0 { ramp(l / self.top as f32) } else { UNTEXTURED };
        let data = aov.data.iter().flat_map(|&l| colour(l)).collect();
        FloatImage { width: aov.width, height: aov.height, channels: 3, data }
    }

    /// What the view shows and its scale, as the panel gives it.
    pub fn legend(&self, ui: &mut egui::Ui) {
        ui.label("Mip level trilinear filtering reads at each pixel's first textured hit (sample 0, its ray cone)");
        ramp_bar(ui);
        ui.label(format!("level 0 (blue, the texels) to {} (red, the 1x1 mean); grey: no texture", self.top));
        ui.label(format!(
            "{} of {} pixels textured, highest level read {:.2}; {:.1} ms",
            self.textured, self.pixels, self.max, self.millis
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_run_up_the_ramp_and_untextured_pixels_are_grey() {
        let aov = FloatImage { width: 3, height: 1, channels: 1, data: vec![0.0, 4.0, -1.0] };
        let s = MipScale::of(&aov, 4, 1.0);
        assert_eq!((s.textured, s.pixels, s.max), (2, 3, 4.0));
        let img = s.image(&aov);
        assert_eq!(&img.data[0..3], &ramp(0.0));
        assert_eq!(&img.data[3..6], &ramp(1.0));
        assert_eq!(&img.data[6..9], &UNTEXTURED);
    }
}
