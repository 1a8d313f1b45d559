//! Bloom's flags: `--bloom-threshold`, `--bloom-radius` and `--bloom-strength`, which override
//! the scene file's `[render.bloom]`.

use anyhow::{Result, bail};
use clap::Args;
use rayscope::settings::BloomSettings;

/// Overrides of [`BloomSettings`]; each given flag wins over the scene file's.
#[derive(Args, Clone, Debug, Default)]
pub struct BloomArgs {
    /// Bloom: values above this (linear, per channel) glow [default: 1].
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub bloom_threshold: Option<f32>,
    /// Bloom: the reach of the glow's Gaussian, in pixels (0 to 512; standard deviation a
    /// third of it) [default: 8].
    #[arg(long, value_name = "PIXELS", allow_negative_numbers = true)]
    pub bloom_radius: Option<f32>,
    /// Bloom: the glow's factor; above 0 turns bloom on [default: 0, off].
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub bloom_strength: Option<f32>,
}

impl BloomArgs {
    /// Apply the flags given to `bloom`. A threshold or radius that would do nothing, as
    /// bloom stays off, is an error that says how to turn it on.
    pub fn apply(&self, bloom: &mut BloomSettings) -> Result<()> {
        bloom.threshold = self.bloom_threshold.unwrap_or(bloom.threshold);
        bloom.radius = self.bloom_radius.unwrap_or(bloom.radius);
        bloom.strength = self.bloom_strength.unwrap_or(bloom.strength);
        bloom.validate()?;
        if bloom.is_off() && (self.bloom_threshold.is_some() || self.bloom_radius.is_some()) {
            bail!("bloom is off: give --bloom-strength S (above 0) to turn it on");
        }
        Ok(())
    }
}
