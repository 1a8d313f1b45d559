//! `KHR_lights_punctual` lights mapped to the course's lights, which are not attenuated with
//! distance:
//! - a point light becomes a point light at the node's origin whose colour is `color ×
//!   intensity / d²`, d the distance to the centre of the scene's vertices: the irradiance
//!   glTF's inverse-square law gives there, so the scene is lit as brightly as glTF means at
//!   its middle;
//! - a spot light becomes the same point light (its cone is ignored, with a warning);
//! - a directional light becomes a point light [`DIRECTIONAL_DISTANCE`] scene radii away
//!   against its direction (its rays nearly parallel across the scene) of colour `color ×
//!   intensity` (lux: the irradiance itself).

use std::path::Path;

use glam::Mat4;

use crate::light::Light;
use crate::math::Vec3;

/// How far a directional light is put, in radii of the scene's bounding sphere.
pub const DIRECTIONAL_DISTANCE: f32 = 1000.0;

/// The lights of `placed` (light index and node transform), mapped as the module says, for
/// a scene of vertices `positions`; a light with a colour or intensity that is not finite
/// and positive is skipped with a warning.
pub fn map(
    doc: &gltf::Document,
    placed: &[(usize, Mat4)],
    positions: &[Vec3],
    warnings: &mut Vec<String>,
    path: &Path,
) -> Vec<Light> {
    let center = if positions.is_empty() {
        Vec3::ZERO
    } else {
        positions.iter().copied().sum::<Vec3>() / positions.len() as f32
    };
    let radius = positions.iter().map(|p| p.distance(center)).fold(0.0f32, f32::max).max(1e-3);
    let Some(lights) = doc.lights() else { return Vec::new() };
    let lights: Vec<_> = lights.collect();
    let mut out = Vec::new();
    for &(index, world) in placed {
        let Some(light) = lights.get(index) else { continue };
        let rgb = Vec3::from_array(light.color()) * light.intensity();
        if !(rgb.is_finite() && rgb.min_element() >= 0.0) {
            warnings.push(format!(
                "{}: light {index} has a colour or intensity that is not finite and positive; skipped",
                path.display()
            ));
            continue;
        }
        let position = world.transform_point3(Vec3::ZERO);
        let at_distance = |p: Vec3| {
            let d2 = p.distance_squared(center);
            if d2 > 0.0 { rgb / d2 } else { rgb }
        };
        let mapped = match light.kind() {
            gltf::khr_lights_punctual::Kind::Point => Light::Point { position, color: at_distance(position) },
            gltf::khr_lights_punctual::Kind::Spot { .. } => {
                warnings.push(format!(
                    "{}: light {index} is a spot light; its cone is ignored (a point light)",
                    path.display()
                ));
                Light::Point { position, color: at_distance(position) }
            }
            gltf::khr_lights_punctual::Kind::Directional => {
                let dir = world.transform_vector3(-Vec3::Z).normalize_or_zero();
                if dir == Vec3::ZERO {
                    warnings.push(format!("{}: light {index} has no direction; skipped", path.display()));
                    continue;
                }
                Light::Point { position: center - dir * radius * DIRECTIONAL_DISTANCE, color: rgb }
            }
        };
        if let Light::Point { position, color } = &mapped
            && !(position.is_finite() && color.is_finite())
        {
            warnings.push(format!("{}: light {index} maps to values that are not finite; skipped", path.display()));
            continue;
        }
        out.push(mapped);
    }
    out
}
