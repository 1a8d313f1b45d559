//! The mip level a ray cone's footprint reads ([`TextureLod`]): the level of detail of Ray
//! Tracing Gems ch. 20, `log2` of the footprint's width in texels.

use serde::Serialize;

use crate::material::Texture;

/// Where a trilinear texture lookup read, and why: the ray cone's width at the hit, its
/// footprint on the surface in texels, and the mip level that footprint chose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TextureLod {
    /// Index of the texture in [`crate::scene::Scene::textures`].
    pub texture: usize,
    /// The ray cone's width at the hit, in scene units.
    pub cone_width: f32,
    /// `|n.d|`, the cosine between the ray and the surface's normal: a grazing ray's
    /// footprint is stretched by its inverse.
    pub cos: f32,
    /// The footprint's width in texels of level 0: `cone_width / cos * sqrt(texels per unit
    /// area)`, the texels per unit area being `width * height` times the surface's uv area per
    /// world area.
    pub texels: f32,
    /// The mip level read: `log2(texels)`, clamped to the pyramid (0 to
    /// [`Texture::top_level`]); fractional levels blend the two around them.
    pub level: f32,
}

/// Smallest `|n.d|` a footprint divides by: a ray that grazes the surface reads the top
/// levels, without an infinite footprint.
const MIN_COS: f32 = 1e-4;

impl TextureLod {
    /// The level a cone `cone_width` wide at the hit reads from `texture` (index `index`),
    /// arriving at cosine `cos` on a surface of `uv_density` (uv area per world area).
    pub fn of(texture: &Texture, index: usize, cone_width: f32, cos: f32, uv_density: f32) -> TextureLod {
        let texel_density = texture.width as f32 * texture.height as f32 * uv_density;
        let texels = cone_width / cos.max(MIN_COS) * texel_density.sqrt();
        // `max` first: a zero or NaN footprint reads level 0.
        let level = texels.log2().max(0.0).min(texture.top_level() as f32);
        TextureLod { texture: index, cone_width, cos, texels, level }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Color;

    #[test]
    fn the_level_is_log2_of_the_footprint_in_texels() {
        let t = Texture::new(256, 256, vec![Color::ZERO; 256 * 256]);
        // A unit square mapped to the whole texture: 256 texels per unit.
        let lod = |w: f32, cos: f32| TextureLod::of(&t, 0, w, cos, 1.0).level;
        assert_eq!(lod(1.0 / 256.0, 1.0), 0.0);
        assert_eq!(lod(4.0 / 256.0, 1.0), 2.0);
        assert_eq!(lod(4.0 / 256.0, 0.5), 3.0);
        assert_eq!(lod(0.0, 1.0), 0.0);
        assert_eq!(lod(1e9, 1.0), 8.0);
        assert_eq!(lod(1.0, 0.0), 8.0);
        // Monotone in the width (distance).
        let levels: Vec<f32> = (1..50).map(|i| lod(i as f32 / 1000.0, 0.7)).collect();
        assert!(levels.windows(2).all(|w| w[0] <= w[1]), "{levels:?}");
    }
}
