//! The course's Phong material and its textures.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::gradient::{Gradient, GradientKey};
use crate::math::{Color, Vec2};
use crate::mipmap::{MipPyramid, TexelGrid};
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
    /// The mip pyramid, built by the first trilinear lookup ([`Texture::mips`]).
    mips: MipCache,
}

impl Texture {
    /// A texture of `width x height` texels, row 0 at the top of the image.
    pub fn new(width: u32, height: u32, texels: Vec<Color>) -> Texture {
        Texture { width, height, texels, mips: MipCache::default() }
    }

    /// Its texels as a grid (level 0 of its pyramid).
    #[inline]
    pub fn grid(&self) -> TexelGrid<'_> {
        TexelGrid { width: self.width, height: self.height, texels: &self.texels }
    }

    /// The colour at `uv` (v = 0 at the bottom of the image, the OBJ convention). Trilinear
    /// filtering needs a footprint ([`Texture::sample_lod`]); without one it reads level 0,
    /// bilinearly.
    pub fn sample(&self, uv: Vec2, filter: TextureFilter) -> Color {
        if !uv.is_finite() {
            return Color::ZERO;
        }
        match filter {
            TextureFilter::Nearest => self.grid().nearest(uv),
            TextureFilter::Bilinear | TextureFilter::Trilinear => self.grid().bilinear(uv),
        }
    }

    /// The trilinear lookup at `uv` for the fractional mip level `lod` (0 is the texture's
    /// own texels; clamped to the pyramid), building the pyramid on first use.
    pub fn sample_lod(&self, uv: Vec2, lod: f32) -> Color {
        if !uv.is_finite() {
            return Color::ZERO;
        }
        self.mips().trilinear(self.grid(), uv, lod)
    }

    /// Its mip pyramid, built once, by the first caller (threads that ask meanwhile wait).
    pub fn mips(&self) -> &MipPyramid {
        self.mips.0.get_or_init(|| MipPyramid::build(self.grid()))
    }

    /// The highest mip level: `floor(log2(max(width, height)))`, the 1x1 level.
    pub fn top_level(&self) -> u32 {
        self.width.max(self.height).max(1).ilog2()
    }
}

/// A texture's lazily built pyramid. Derived data: it is not compared (two textures with the
/// same texels are equal whether or not either has built it).
#[derive(Clone, Debug, Default)]
struct MipCache(std::sync::OnceLock<MipPyramid>);

impl PartialEq for MipCache {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        Texture::new(2, 2, vec![Color::ONE, Color::ZERO, Color::ZERO, Color::ONE])
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
