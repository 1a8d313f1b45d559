//! The course's Phong material and its textures.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::gradient::{Gradient, GradientKey};
use crate::math::{Color, Vec2};
use crate::mipmap::{MipPyramid, TexelGrid, Unorm8};
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
    /// Texels, row 0 at the top of the image. Set by [`Texture::new`] and not changed after:
    /// lookups may read the 8-bit copy it makes of them.
    pub texels: Vec<Color>,
    /// The mip pyramid, built by the first trilinear lookup ([`Texture::mips`]).
    mips: MipCache,
    /// The texels as 8-bit values, where every one is (an image of 8-bit values, as most
    /// are): what the nearest and bilinear lookups read, the same colours in a third of the
    /// memory.
    unorm8: Option<Vec<Unorm8>>,
}

impl Texture {
    /// A texture of `width x height` texels, row 0 at the top of the image.
    pub fn new(width: u32, height: u32, texels: Vec<Color>) -> Texture {
        let unorm8 = texels.iter().map(|c| Unorm8::exactly(*c)).collect();
        Texture { width, height, texels, mips: MipCache::default(), unorm8 }
    }

    /// Its texels as a grid (level 0 of its pyramid).
    #[inline]
    pub fn grid(&self) -> TexelGrid<'_> {
        self.grid_of(&self.texels)
    }

    /// `texels`, this texture's in some form, as a grid of its size.
    #[inline]
    fn grid_of<'a, T>(&self, texels: &'a [T]) -> TexelGrid<'a, T> {
        TexelGrid { width: self.width, height: self.height, texels }
    }

    /// The colour at `uv` (v = 0 at the bottom of the image, the OBJ convention). Trilinear
    /// filtering needs a footprint ([`Texture::sample_lod`]); without one it reads level 0,
    /// bilinearly.
    pub fn sample(&self, uv: Vec2, filter: TextureFilter) -> Color {
        if !uv.is_finite() {
            return Color::ZERO;
        }
        match (&self.unorm8, filter) {
            (Some(texels), TextureFilter::Nearest) => self.grid_of(texels).nearest(uv),
            (Some(texels), TextureFilter::Bilinear | TextureFilter::Trilinear) => self.grid_of(texels).bilinear(uv),
            (None, TextureFilter::Nearest) => self.grid().nearest(uv),
            (None, TextureFilter::Bilinear | TextureFilter::Trilinear) => self.grid().bilinear(uv),
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

    /// Every byte `k` is read back as the loader's `k / 255`, bit for bit; values that are
    /// not such a quotient (between two, beyond 1, negative zero, NaN) have no 8-bit form.
    #[test]
    fn unorm8_texels_are_the_loaders_values() {
        use crate::mipmap::Texel;
        for k in 0..=255u8 {
            let loaded = Color::splat(k as f32) / 255.0;
            let texel = Unorm8::exactly(loaded).expect("an 8-bit value");
            assert_eq!(texel, Unorm8([k, k, k, 0]));
            assert_eq!(texel.color().to_array().map(f32::to_bits), loaded.to_array().map(f32::to_bits));
        }
        for v in [0.3, 1.5, -0.0, 2.0 / 255.0 + 1e-7, f32::NAN, f32::INFINITY] {
            assert_eq!(Unorm8::exactly(Color::new(0.0, v, 1.0)), None, "{v}");
        }
    }

    /// A texture of 8-bit values read through its 8-bit form gives its colours' lookups bit for
    /// bit (nearest and bilinear, uvs inside, outside and on texel edges); one texel that is
    /// not 8-bit keeps the whole texture in colours.
    #[test]
    fn unorm8_lookups_equal_colour_lookups() {
        let (w, h) = (7u32, 5u32);
        let byte = |i: u32, c: u32| ((i * 37 + c * 91) % 256) as f32;
        let texels: Vec<Color> = (0..w * h).map(|i| Color::new(byte(i, 0), byte(i, 1), byte(i, 2)) / 255.0).collect();
        let t = Texture::new(w, h, texels.clone());
        assert!(t.unorm8.is_some());
        let mut odd = texels;
        odd[11].y = 0.3;
        assert!(Texture::new(w, h, odd).unorm8.is_none());
        for i in -40..60 {
            for j in -30..45 {
                let uv = Vec2::new(i as f32 / 28.0, j as f32 / 20.0 + 0.013);
                for filter in [TextureFilter::Nearest, TextureFilter::Bilinear] {
                    let want = match filter {
                        TextureFilter::Nearest => t.grid().nearest(uv),
                        _ => t.grid().bilinear(uv),
                    };
                    let got = t.sample(uv, filter);
                    assert_eq!(got.to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "{uv} {filter:?}");
                }
            }
        }
    }
}
