//! Environment maps: an equirectangular (latitude-longitude) image around the scene, whose
//! radiance a ray that hits nothing returns in place of the background colour.
//!
//! The direction convention (right-handed, +y up, as the course's scenes): the map's centre
//! (`u = 0.5`, `v = 0.5`) lies along -z, the direction the built-in Cornell box is seen along;
//! `u` grows to the right as seen looking that way (+x at `u = 0.75`, +z at the seam `u = 0`
//! and `1`, -x at `u = 0.25`); the top row (`v = 0`) is +y, the bottom row -y. A rotation of `rotation`
//! degrees turns the map about +y, right-handed: at +90 its centre moves from -z to -x.
//!
//! The map is not a light source: shadow rays and direct lighting do not see it, only rays that
//! miss (camera rays show it as the background, mirror and glossy reflections reflect it).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::io::texture::load_texture;
use crate::material::Texture;
use crate::math::{Color, Vec2, Vec3A};
use crate::settings::TextureFilter;

/// An environment map as a scene file's `[environment]` table writes it, and as the command
/// line's `--env-map`, `--env-intensity` and `--env-rotation` give it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentDesc {
    /// The image: Radiance `.hdr`, OpenEXR `.exr` or `.png`, twice as wide as high; relative
    /// to the scene file. PNG values are taken linearly, 8-bit `/ 255`, as textures are.
    pub path: PathBuf,
    /// Factor on the map's values (at least 0, finite). Default 1.
    #[serde(default = "one")]
    pub intensity: f32,
    /// Rotation of the map about +y, in degrees (right-handed; finite). Default 0.
    #[serde(default)]
    pub rotation: f32,
}

fn one() -> f32 {
    1.0
}

impl Default for EnvironmentDesc {
    /// No file, intensity 1, no rotation.
    fn default() -> Self {
        EnvironmentDesc { path: PathBuf::new(), intensity: 1.0, rotation: 0.0 }
    }
}

impl EnvironmentDesc {
    /// Check intensity and rotation; the message names the keys as `what` calls them (the
    /// flags `--env-intensity`/`--env-rotation`, or the scene file's keys).
    pub fn validate(&self, intensity_name: &str, rotation_name: &str) -> Result<()> {
        if !(self.intensity.is_finite() && self.intensity >= 0.0) {
            return Err(Error::Invalid(format!(
                "{intensity_name} {}: the environment map's intensity must be a finite number, at least 0",
                self.intensity
            )));
        }
        if !self.rotation.is_finite() {
            return Err(Error::Invalid(format!(
                "{rotation_name} {}: the environment map's rotation must be a finite number of degrees",
                self.rotation
            )));
        }
        Ok(())
    }
}

/// A loaded environment map, ready to look up. Cheap to clone (the texels are shared).
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// What it was loaded from, the path as resolved.
    pub desc: EnvironmentDesc,
    /// The image, linear values, row 0 at the top (+y).
    map: Arc<Texture>,
    /// `(sin, cos)` of the rotation.
    turn: Vec2,
}

/// One lookup of the map: what the debugger shows of a ray that missed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct EnvironmentLookup {
    /// The ray's direction (unit length).
    pub dir: [f32; 3],
    /// The map coordinates it points at, after the rotation: `u` to the right, `v` down.
    pub uv: [f32; 2],
    /// The texel the direction falls into (column, row from the top).
    pub texel: [u32; 2],
    /// The radiance returned: the filtered map times the intensity.
    pub radiance: Color,
}

impl Environment {
    /// Load the map `desc` names (its path relative to `base`), through the guarded readers:
    /// a regular file within the size limit, decoded as a texture is, and twice as wide as
    /// high.
    pub fn load(desc: &EnvironmentDesc, base: &Path) -> Result<Environment> {
        let path = base.join(&desc.path);
        let map = load_texture(&path)?;
        let desc = EnvironmentDesc { path, ..desc.clone() };
        Environment::from_texture(desc, map)
    }

    /// A map from texels already decoded (`desc.path` names it in errors).
    pub fn from_texture(desc: EnvironmentDesc, map: Texture) -> Result<Environment> {
        let path = &desc.path;
        if map.width != 2 * map.height {
            return Err(Error::parse(
                path,
                None,
                format!(
                    "an environment map is equirectangular, twice as wide as high; this one is {}x{}",
                    map.width, map.height
                ),
            ));
        }
        if map.texels.len() != map.width as usize * map.height as usize {
            return Err(Error::parse(path, None, "the texels do not fill the image"));
        }
        if let Some(i) = map.texels.iter().position(|t| !t.is_finite()) {
            let (x, y) = (i as u32 % map.width, i as u32 / map.width);
            return Err(Error::parse(path, None, format!("texel ({x}, {y}) is not a finite colour")));
        }
        desc.validate("intensity", "rotation").map_err(|e| Error::parse(path, None, e.to_string()))?;
        let mut env = Environment { desc, map: Arc::new(map), turn: Vec2::ZERO };
        env.set_rotation(env.desc.rotation);
        Ok(env)
    }

    /// Set the factor on the map's values (validated by [`EnvironmentDesc::validate`]).
    pub fn set_intensity(&mut self, intensity: f32) {
        self.desc.intensity = intensity;
    }

    /// Set the rotation about +y, in degrees.
    pub fn set_rotation(&mut self, degrees: f32) {
        self.desc.rotation = degrees;
        let (s, c) = degrees.to_radians().sin_cos();
        self.turn = Vec2::new(s, c);
    }

    /// The map's image (linear values, row 0 at the top).
    pub fn texture(&self) -> &Texture {
        &self.map
    }

    /// The map coordinates `(u, v)` of direction `dir` (any length but 0), after the
    /// rotation: see the module's convention.
    #[inline]
    pub fn uv(&self, dir: Vec3A) -> Vec2 {
        let Vec2 { x: s, y: c } = self.turn;
        // The map turned by +rotation shows at `dir` what the unturned map shows at `dir`
        // turned back: R_y(-rotation) dir.
        let x = dir.x * c - dir.z * s;
        let z = dir.x * s + dir.z * c;
        let len = dir.length();
        let u = 0.5 + x.atan2(-z) * (0.5 * std::f32::consts::FRAC_1_PI);
        let v = (dir.y / len).clamp(-1.0, 1.0).acos() * std::f32::consts::FRAC_1_PI;
        Vec2::new(u, v)
    }

    /// The radiance arriving from direction `dir` (what a ray that misses returns): the map
    /// at [`Environment::uv`], bilinear (nearest with [`TextureFilter::Nearest`]), times the
    /// intensity. Columns wrap around the seam; rows stop at the poles.
    #[inline]
    pub fn radiance(&self, dir: Vec3A, filter: TextureFilter) -> Color {
        let uv = self.uv(dir);
        if !uv.is_finite() {
            return Color::ZERO;
        }
        let (w, h) = (self.map.width as f32, self.map.height as f32);
        let (x, y) = (uv.x * w, uv.y * h);
        let c = if matches!(filter, TextureFilter::Nearest) {
            self.texel(x.floor() as i64, y.floor() as i64)
        } else {
            let (fx, fy) = (x - 0.5, y - 0.5);
            let (x0, y0) = (fx.floor(), fy.floor());
            let (tx, ty) = (fx - x0, fy - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            // `a + (b - a) t`: a constant map gives its value exactly.
            let lerp = |a: Color, b: Color, t: f32| a + (b - a) * t;
            let top = lerp(self.texel(x0, y0), self.texel(x0 + 1, y0), tx);
            let bottom = lerp(self.texel(x0, y0 + 1), self.texel(x0 + 1, y0 + 1), tx);
            lerp(top, bottom, ty)
        };
        c * self.desc.intensity
    }

    /// [`Environment::radiance`] with what the debugger shows of it.
    pub fn lookup(&self, dir: Vec3A, filter: TextureFilter) -> EnvironmentLookup {
        let uv = self.uv(dir);
        let (x, y) = self
            .texel_index((uv.x * self.map.width as f32).floor() as i64, (uv.y * self.map.height as f32).floor() as i64);
        EnvironmentLookup {
            dir: dir.normalize_or_zero().to_array(),
            uv: uv.to_array(),
            texel: [x as u32, y as u32],
            radiance: self.radiance(dir, filter),
        }
    }

    /// The unit direction through map coordinates `(u, v)`: the inverse of
    /// [`Environment::uv`] (for drawing a texel's outline on a sphere).
    pub fn direction(&self, uv: Vec2) -> Vec3A {
        let phi = (uv.x - 0.5) * std::f32::consts::TAU;
        let theta = uv.y * std::f32::consts::PI;
        let (sp, cp) = phi.sin_cos();
        let (st, ct) = theta.sin_cos();
        // Unturned: x = sin(theta) sin(phi), z = -sin(theta) cos(phi); then R_y(+rotation).
        let (x, z) = (st * sp, -st * cp);
        let Vec2 { x: s, y: c } = self.turn;
        Vec3A::new(x * c + z * s, ct, -x * s + z * c)
    }

    /// Column and row of texel `(x, y)`: columns wrap, rows clamp.
    #[inline]
    fn texel_index(&self, x: i64, y: i64) -> (usize, usize) {
        let x = x.rem_euclid(self.map.width as i64) as usize;
        let y = y.clamp(0, self.map.height as i64 - 1) as usize;
        (x, y)
    }

    #[inline]
    fn texel(&self, x: i64, y: i64) -> Color {
        let (x, y) = self.texel_index(x, y);
        self.map.texels[y * self.map.width as usize + x]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(width: u32, texels: Vec<Color>, rotation: f32) -> Environment {
        let desc = EnvironmentDesc { path: "test.hdr".into(), rotation, ..EnvironmentDesc::default() };
        Environment::from_texture(desc, Texture::new(width, width / 2, texels)).unwrap()
    }

    #[test]
    fn the_centre_is_minus_z_and_u_grows_to_the_right() {
        let e = env(4, vec![Color::ZERO; 8], 0.0);
        let close = |a: Vec2, b: [f32; 2]| (a - Vec2::from(b)).abs().max_element() < 1e-6;
        assert!(close(e.uv(-Vec3A::Z), [0.5, 0.5]));
        assert!(close(e.uv(Vec3A::X), [0.75, 0.5]));
        assert!(close(e.uv(-Vec3A::X), [0.25, 0.5]));
        assert!(close(e.uv(Vec3A::Y), [e.uv(Vec3A::Y).x, 0.0]));
        assert!(close(e.uv(-Vec3A::Y * 3.0), [e.uv(-Vec3A::Y).x, 1.0]));
        // +90 degrees turns the centre to -x.
        let turned = env(4, vec![Color::ZERO; 8], 90.0);
        assert!(close(turned.uv(-Vec3A::X), [0.5, 0.5]));
    }

    #[test]
    fn direction_inverts_uv() {
        let e = env(4, vec![Color::ZERO; 8], 37.0);
        for (u, v) in [(0.1, 0.2), (0.5, 0.5), (0.9, 0.7), (0.3, 0.95)] {
            let uv = e.uv(e.direction(Vec2::new(u, v)));
            assert!((uv - Vec2::new(u, v)).abs().max_element() < 1e-5, "{u} {v}: {uv}");
        }
    }

    #[test]
    fn a_constant_map_gives_its_value_exactly_and_columns_wrap() {
        let c = Color::new(0.3, 1.7, 0.1);
        let e = env(8, vec![c; 32], 12.0);
        for d in [Vec3A::X, Vec3A::new(0.3, -0.9, 0.2), Vec3A::Z, Vec3A::Y, Vec3A::new(-1e-3, 0.2, 1.0)] {
            assert_eq!(e.radiance(d, TextureFilter::Bilinear), c);
            assert_eq!(e.radiance(d, TextureFilter::Nearest), c);
        }
        // Across the seam (+z), bilinear blends the first and last columns.
        let mut texels = vec![Color::ZERO; 8];
        texels[0] = Color::ONE;
        texels[4] = Color::ONE;
        let e = env(4, texels, 0.0);
        let seam = e.radiance(Vec3A::new(0.0, 0.0, 1.0), TextureFilter::Bilinear);
        assert!((seam - Color::splat(0.5)).abs().max_element() < 1e-6, "{seam}");
    }

    #[test]
    fn bad_maps_and_values_are_errors_naming_the_file() {
        let desc = EnvironmentDesc { path: "sky.png".into(), ..EnvironmentDesc::default() };
        let square = Texture::new(4, 4, vec![Color::ZERO; 16]);
        let err = Environment::from_texture(desc.clone(), square).unwrap_err().to_string();
        assert!(err.contains("sky.png") && err.contains("4x4"), "{err}");
        let nan = Texture::new(2, 1, vec![Color::ZERO, Color::new(0.0, f32::NAN, 0.0)]);
        let err = Environment::from_texture(desc.clone(), nan).unwrap_err().to_string();
        assert!(err.contains("texel (1, 0)"), "{err}");
        let negative = EnvironmentDesc { intensity: -1.0, ..desc.clone() };
        let err = negative.validate("--env-intensity", "--env-rotation").unwrap_err().to_string();
        assert!(err.contains("--env-intensity -1"), "{err}");
        let nan = EnvironmentDesc { rotation: f32::NAN, ..desc };
        let err = nan.validate("--env-intensity", "--env-rotation").unwrap_err().to_string();
        assert!(err.contains("--env-rotation NaN"), "{err}");
    }
}
