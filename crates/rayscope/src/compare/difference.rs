//! The difference image: black where the two images are equal (at 8 bits), and a heat ramp
//! over the differing pixels by the largest error of their channels, on a logarithmic scale
//! of 8-bit levels so that a one-level slip is as visible as a wrong colour: 1 level is dark
//! purple, 4 red, 16 orange, 64 yellow, 255 (or more, for floats) white.

use super::Comparison;
use crate::film::FloatImage;

/// The ramp's colours, from the smallest difference (t = 0) to the largest (t = 1), evenly
/// spaced.
const RAMP: [[f32; 3]; 5] = [[0.30, 0.0, 0.45], [0.85, 0.1, 0.15], [1.0, 0.5, 0.0], [1.0, 0.95, 0.2], [1.0, 1.0, 1.0]];

/// The colour of a differing pixel whose largest channel error is `error` (in `[0, 1]` units:
/// one 8-bit level is 1/255): `ln(levels) / ln(255)` along the ramp, clamped to its ends, so
/// that 1 level is its first colour and 255 its last (the stops between: 255^(1/4), about 4
/// levels, 16 and 64). Never black: a pixel that differs at 8
/// bits by less than a level of float error still shows.
pub fn difference_color(error: f32) -> [f32; 3] {
    let levels = (error * 255.0).max(1.0);
    let t = (levels.ln() / 255f32.ln()).clamp(0.0, 1.0) * (RAMP.len() - 1) as f32;
    let i = (t as usize).min(RAMP.len() - 2);
    let f = t - i as f32;
    let (a, b) = (RAMP[i], RAMP[i + 1]);
    [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * f)
}

/// The difference image of `c` (see the module's doc).
pub(super) fn image(c: &Comparison) -> FloatImage {
    let data = c.errors.iter().flat_map(|e| e.map_or([0.0; 3], difference_color)).collect();
    FloatImage { width: c.width, height: c.height, channels: 3, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_from_purple_at_one_level_to_white() {
        let near = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5);
        for (stop, &colour) in RAMP.iter().enumerate() {
            let levels = 255f32.powf(stop as f32 / 4.0);
            assert!(near(difference_color(levels / 255.0), colour), "{levels} levels");
        }
        assert_eq!(difference_color(0.0001), RAMP[0], "less than a level shows as one");
        assert_eq!(difference_color(7.0), RAMP[4]);
        // Brighter as the error grows, never black.
        let lum = |c: [f32; 3]| c.iter().sum::<f32>();
        let mut last = 0.0;
        for l in 1..=255 {
            let v = lum(difference_color(l as f32 / 255.0));
            assert!(v >= last && v > 0.5, "{l}: {v}");
            last = v;
        }
    }
}
