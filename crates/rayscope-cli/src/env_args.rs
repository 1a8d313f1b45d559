//! The environment map's flags: `--env-map`, `--env-intensity` and `--env-rotation`, which
//! override the scene file's `[environment]` table.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use rayscope::environment::{Environment, EnvironmentDesc};
use rayscope::scene::Scene;

/// Overrides of the scene's environment map; each given flag wins over `[environment]`.
#[derive(Args, Clone, Debug, Default)]
pub struct EnvironmentArgs {
    /// An equirectangular environment map (.hdr, .exr or .png, twice as wide as high) that
    /// rays which miss return: the background, and what mirrors reflect (not a light source).
    #[arg(long, value_name = "FILE")]
    pub env_map: Option<PathBuf>,
    /// Factor on the environment map's values (at least 0) [default: 1].
    #[arg(long, value_name = "X", allow_negative_numbers = true)]
    pub env_intensity: Option<f32>,
    /// Rotation of the environment map about +y, in degrees [default: 0].
    #[arg(long, value_name = "DEGREES", allow_negative_numbers = true)]
    pub env_rotation: Option<f32>,
}

impl EnvironmentArgs {
    /// The environment these flags ask for, given the scene's own: a new map from `--env-map`
    /// (relative to the working directory), or the scene's with intensity and rotation
    /// replaced. An intensity or rotation without any map is an error.
    pub fn resolve(&self, scene: Option<&Environment>) -> Result<Option<Environment>> {
        let base = scene.map(|e| e.desc.clone()).unwrap_or_default();
        let desc = EnvironmentDesc {
            path: self.env_map.clone().unwrap_or(base.path),
            intensity: self.env_intensity.unwrap_or(base.intensity),
            rotation: self.env_rotation.unwrap_or(base.rotation),
        };
        desc.validate("--env-intensity", "--env-rotation")?;
        if self.env_map.is_some() {
            return Ok(Some(Environment::load(&desc, std::path::Path::new(""))?));
        }
        let Some(env) = scene else {
            if self.env_intensity.is_some() || self.env_rotation.is_some() {
                bail!(
                    "--env-intensity and --env-rotation need an environment map: --env-map FILE or [environment] in the scene file"
                );
            }
            return Ok(None);
        };
        let mut env = env.clone();
        env.set_intensity(desc.intensity);
        env.set_rotation(desc.rotation);
        Ok(Some(env))
    }

    /// The flags as the viewer keeps them over every scene it loads.
    #[cfg(feature = "viewer")]
    pub fn viewer_override(&self) -> Result<rayscope_viewer::environment::EnvOverride> {
        let map = if self.env_map.is_some() { self.resolve(None)? } else { None };
        Ok(rayscope_viewer::environment::EnvOverride {
            map,
            intensity: self.env_intensity,
            rotation: self.env_rotation,
        })
    }

    /// Apply [`EnvironmentArgs::resolve`] to `scene`.
    pub fn apply(&self, scene: &mut Scene) -> Result<()> {
        scene.environment = self.resolve(scene.environment.as_ref())?;
        Ok(())
    }
}
