//! glTF's metallic-roughness materials mapped to the course's Phong parameters, and back.
//!
//! The mapping (the README's "Materials from glTF" says why):
//! - `kd` = base colour × (1 − metallic): metals have no diffuse term. A base colour texture
//!   replaces `kd` (rayscope's textures do), so its factor is used only where it is white.
//! - `ks` = mix(0.04, base colour, metallic) × (1 − roughness): the reflectance at normal
//!   incidence (4% for dielectrics, the base colour for metals), which in the course's model
//!   is also the weight of the mirror reflection, so rough surfaces reflect less of it.
//! - `shininess` = 2 / α² − 2 with α = roughness²: the Blinn-Phong exponent whose lobe matches
//!   the GGX lobe of the same α (Walter et al. 2007), capped at [`MAX_SHININESS`].
//! - `transparency` (opacity): OPAQUE 1; BLEND the base colour's alpha; MASK 1 where the alpha
//!   reaches the cutoff, else 0.
//!
//! Files rayscope writes carry the exact Phong values in the material's `extras`
//! (`{"rayscope": {"kd": [..], "ks": [..], "shininess": n, "transparency": t}}`), read back
//! in preference to the mapping, so an exported scene loads back identical.

use serde::{Deserialize, Serialize};

use crate::material::Material;
use crate::math::{Color, Vec3};

/// The largest shininess a smooth glTF surface maps to (roughness 0 would be infinite).
pub const MAX_SHININESS: f32 = 10_000.0;

/// The reflectance at normal incidence of dielectrics in glTF's metallic-roughness model.
const DIELECTRIC_F0: f32 = 0.04;

/// The exact Phong values rayscope writes into a material's `extras`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PhongExtras {
    /// Diffuse reflectance.
    pub kd: [f32; 3],
    /// Specular reflectance.
    pub ks: [f32; 3],
    /// Phong exponent.
    pub shininess: f32,
    /// Opacity.
    pub transparency: f32,
    /// Glossy lobe exponent, when set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub glossiness: Option<f32>,
}

/// The `extras` object rayscope writes: `{"rayscope": PhongExtras}`.
#[derive(Serialize, Deserialize)]
pub struct Extras {
    /// The Phong values.
    pub rayscope: PhongExtras,
}

/// How a glTF material's factors map to Phong ([`phong_from_pbr`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pbr {
    /// Base colour and alpha.
    pub base_color: [f32; 4],
    /// Metalness in [0, 1].
    pub metallic: f32,
    /// Perceptual roughness in [0, 1].
    pub roughness: f32,
    /// How alpha is used.
    pub alpha_mode: gltf::material::AlphaMode,
    /// MASK's cutoff.
    pub alpha_cutoff: f32,
}

/// The Phong material of glTF factors `pbr` (the module's mapping); values outside their
/// ranges are clamped into them first.
pub fn phong_from_pbr(name: String, pbr: &Pbr) -> Material {
    let [r, g, b, a] = pbr.base_color.map(|c| if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 });
    let base = Color::new(r, g, b);
    let metallic = if pbr.metallic.is_finite() { pbr.metallic.clamp(0.0, 1.0) } else { 0.0 };
    let roughness = if pbr.roughness.is_finite() { pbr.roughness.clamp(0.0, 1.0) } else { 1.0 };
    let alpha = roughness * roughness;
    let shininess = if alpha > 0.0 { (2.0 / (alpha * alpha) - 2.0).min(MAX_SHININESS) } else { MAX_SHININESS };
    let transparency = match pbr.alpha_mode {
        gltf::material::AlphaMode::Opaque => 1.0,
        gltf::material::AlphaMode::Blend => a,
        gltf::material::AlphaMode::Mask => {
            if a >= pbr.alpha_cutoff {
                1.0
            } else {
                0.0
            }
        }
    };
    Material {
        name,
        kd: base * (1.0 - metallic),
        ks: Vec3::splat(DIELECTRIC_F0).lerp(base, metallic) * (1.0 - roughness),
        shininess: shininess.max(0.0),
        transparency,
        texture: None,
        glossiness: None,
        ..Material::default()
    }
}

/// The glTF factors that stand for a Phong material in a file rayscope writes (for other
/// programs; rayscope reads the exact [`PhongExtras`]): base colour `kd`, alpha the opacity,
/// no metal, and the roughness whose shininess is the material's (the mapping inverted).
pub fn pbr_from_phong(m: &Material) -> Pbr {
    // shininess = 2 / α² − 2  ⇔  α = sqrt(2 / (shininess + 2)), roughness = sqrt(α).
    let alpha = (2.0 / (m.shininess.max(0.0) + 2.0)).sqrt();
    Pbr {
        base_color: [m.kd.x.min(1.0), m.kd.y.min(1.0), m.kd.z.min(1.0), m.transparency],
        metallic: 0.0,
        roughness: alpha.sqrt(),
        alpha_mode: if m.transparency < 1.0 {
            gltf::material::AlphaMode::Blend
        } else {
            gltf::material::AlphaMode::Opaque
        },
        alpha_cutoff: 0.5,
    }
}

impl PhongExtras {
    /// The values of `m`.
    pub fn of(m: &Material) -> PhongExtras {
        PhongExtras {
            kd: m.kd.to_array(),
            ks: m.ks.to_array(),
            shininess: m.shininess,
            transparency: m.transparency,
            glossiness: m.glossiness,
        }
    }

    /// These values on a material named `name`, when they are valid (finite, not negative,
    /// an opacity in [0, 1]); `None` otherwise.
    pub fn material(&self, name: String) -> Option<Material> {
        let colour = |c: [f32; 3]| Vec3::from_array(c);
        let (kd, ks) = (colour(self.kd), colour(self.ks));
        let ok = kd.is_finite()
            && ks.is_finite()
            && kd.min_element() >= 0.0
            && ks.min_element() >= 0.0
            && self.shininess.is_finite()
            && self.shininess >= 0.0
            && (0.0..=1.0).contains(&self.transparency)
            && self.glossiness.is_none_or(|g| g >= 0.0);
        ok.then_some(Material {
            name,
            kd,
            ks,
            shininess: self.shininess,
            transparency: self.transparency,
            texture: None,
            glossiness: self.glossiness,
            ..Material::default()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pbr(base: [f32; 4], metallic: f32, roughness: f32) -> Pbr {
        Pbr { base_color: base, metallic, roughness, alpha_mode: gltf::material::AlphaMode::Opaque, alpha_cutoff: 0.5 }
    }

    #[test]
    fn dielectrics_keep_their_colour_and_metals_reflect_it() {
        let plastic = phong_from_pbr("p".into(), &pbr([1.0, 0.0, 0.0, 1.0], 0.0, 0.0));
        assert_eq!(plastic.kd, Vec3::X);
        assert_eq!(plastic.ks, Vec3::splat(DIELECTRIC_F0));
        assert_eq!(plastic.shininess, MAX_SHININESS);
        let gold = phong_from_pbr("g".into(), &pbr([1.0, 0.8, 0.3, 1.0], 1.0, 0.0));
        assert_eq!(gold.kd, Vec3::ZERO);
        assert_eq!(gold.ks, Vec3::new(1.0, 0.8, 0.3));
        let rough = phong_from_pbr("r".into(), &pbr([1.0; 4], 1.0, 1.0));
        assert_eq!((rough.ks, rough.shininess), (Vec3::ZERO, 0.0));
    }

    #[test]
    fn the_inverse_mapping_gives_back_the_shininess() {
        for shininess in [1.0f32, 10.0, 64.0, 500.0] {
            let m = Material { shininess, ..Material::default() };
            let back = phong_from_pbr("x".into(), &pbr_from_phong(&m));
            assert!((back.shininess - shininess).abs() < 1e-3 * shininess, "{shininess} -> {}", back.shininess);
        }
    }

    #[test]
    fn alpha_modes_map_to_opacity() {
        let mut p = pbr([1.0, 1.0, 1.0, 0.3], 0.0, 1.0);
        assert_eq!(phong_from_pbr("o".into(), &p).transparency, 1.0);
        p.alpha_mode = gltf::material::AlphaMode::Blend;
        assert_eq!(phong_from_pbr("b".into(), &p).transparency, 0.3);
        p.alpha_mode = gltf::material::AlphaMode::Mask;
        assert_eq!(phong_from_pbr("m".into(), &p).transparency, 0.0);
        p.alpha_cutoff = 0.2;
        assert_eq!(phong_from_pbr("m".into(), &p).transparency, 1.0);
    }
}
