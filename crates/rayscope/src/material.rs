//! The course's Phong material and its textures.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::gradient::{Gradient, GradientKey};
use crate::math::{Color, Vec2};
use crate::settings::{ShadingModel, TextureFilter};

/// A Phong material in the course's form.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name (from the MTL file or the scene), for the debugger.
    pub name: String,
    /// Diffuse reflectance.
    pub kd: Color,
    /// Specular reflectance; also the weight of the mirror reflection.
    pub ks: Color,
    /// Phong exponent (MTL `Ns`).
    pub shininess: f32,
    /// Opacity in the course's convention (MTL `d`): 1 is opaque, 0 fully transparent.
    pub transparency: f32,
    /// Index of the diffuse texture in [`crate::scene::Scene::textures`]; replaces `kd`.
    pub texture: Option<usize>,
    /// Phong exponent of the glossy reflection lobe; `None` uses `shininess`, infinity keeps
    /// the material a perfect mirror even when glossy reflections are on.
    pub glossiness: Option<f32>,
    /// Its shading model; `None` shades it with the scene-wide
    /// [`crate::settings::RenderSettings::shading_model`].
    pub model: Option<ShadingModel>,
    /// The gradient model's diffuse colours by `n.l`; `None` reads the ramp from black to `kd`.
    pub gradient: Option<Gradient>,
}

impl Material {
    /// The model that shades it under the scene-wide `default`: its own wins.
    #[inline]
    pub fn shading_model(&self, default: ShadingModel) -> ShadingModel {
        self.model.unwrap_or(default)
    }
}

impl Default for Material {
    /// Assimp's default OBJ material, which the course used for meshes without an MTL:
    /// grey 0.6 diffuse, no specular.
    fn default() -> Self {
        Material {
            name: "default".into(),
            kd: Color::splat(0.6),
            ks: Color::ZERO,
            shininess: 1.0,
            transparency: 1.0,
            texture: None,
            glossiness: None,
            model: None,
            gradient: None,
        }
    }
}

/// How a scene file writes a material (a full material, or an override of one from a file).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    /// Name shown in the debugger.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Diffuse reflectance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kd: Option<Color>,
    /// Specular reflectance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ks: Option<Color>,
    /// Phong exponent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shininess: Option<f32>,
    /// Opacity, the course's `transparency` (1 = opaque).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transparency: Option<f32>,
    /// Diffuse texture image, relative to the scene file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture: Option<PathBuf>,
    /// Exponent of the glossy reflection lobe (default: `shininess`; `inf`: perfect mirror).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub glossiness: Option<f32>,
    /// Shading model (`phong`, `blinn-phong`, `lambert`, `gradient`); default: the scene-wide
    /// `shading_model`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<ShadingModel>,
    /// The gradient model's colours by `n.l`: `[[position, [r, g, b]], ...]`, positions in
    /// [0, 1] in increasing order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gradient: Option<Vec<GradientKey>>,
}

/// An RGB image in linear float values (the course used the 8-bit values / 255 as they are).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Texels, row 0 at the top of the image.
    pub texels: Vec<Color>,
}

impl Texture {
    fn texel(&self, x: i64, y: i64) -> Color {
        // Wrap (repeat) addressing, as OBJ texture coordinates outside [0,1] expect.
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.texels[y * self.width as usize + x]
    }

    /// The colour at `uv` (v = 0 at the bottom of the image, the OBJ convention).
    pub fn sample(&self, uv: Vec2, filter: TextureFilter) -> Color {
        if !uv.is_finite() {
            return Color::ZERO;
        }
        let x = uv.x * self.width as f32;
        let y = (1.0 - uv.y) * self.height as f32;
        match filter {
            TextureFilter::Nearest => self.texel(x.floor() as i64, y.floor() as i64),
            TextureFilter::Bilinear => {
                let (fx, fy) = (x - 0.5, y - 0.5);
                let (x0, y0) = (fx.floor(), fy.floor());
                let (tx, ty) = (fx - x0, fy - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                // Wrapping: a huge coordinate saturates to i64::MAX, whose neighbour overflowed.
                let (x1, y1) = (x0.wrapping_add(1), y0.wrapping_add(1));
                let top = self.texel(x0, y0).lerp(self.texel(x1, y0), tx);
                let bottom = self.texel(x0, y1).lerp(self.texel(x1, y1), tx);
                top.lerp(bottom, ty)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        Texture { width: 2, height: 2, texels: vec![Color::ONE, Color::ZERO, Color::ZERO, Color::ONE] }
    }

    #[test]
    fn nearest_picks_texels() {
        let t = checker();
        assert_eq!(t.sample(Vec2::new(0.25, 0.75), TextureFilter::Nearest), Color::ONE);
        assert_eq!(t.sample(Vec2::new(0.75, 0.75), TextureFilter::Nearest), Color::ZERO);
    }

    #[test]
    fn bilinear_blends_between_centres() {
        let t = checker();
        let mid = t.sample(Vec2::new(0.5, 0.5), TextureFilter::Bilinear);
        assert!((mid - Color::splat(0.5)).abs().max_element() < 1e-6);
        let centre = t.sample(Vec2::new(0.25, 0.75), TextureFilter::Bilinear);
        assert!((centre - Color::ONE).abs().max_element() < 1e-6);
    }
}
