//! Bloom: below the threshold the image keeps every bit; the blur keeps the bright pass's
//! energy (the border mirrors weights back into the image); the render path leaves the film
//! alone.

use proptest::prelude::*;
use rayscope::math::Color;
use rayscope::post::bloom;
use rayscope::settings::BloomSettings;

/// An image of `w x h` pixels from `values` (cycled), each channel scaled into `0..=top`.
fn image(w: u32, h: u32, values: &[f32], top: f32) -> Vec<Color> {
    let n = (w * h) as usize;
    (0..n)
        .map(|i| {
            let v = |c: usize| values[(3 * i + c) % values.len()] * top;
            Color::new(v(0), v(1), v(2))
        })
        .collect()
}

fn total(layer: &[Color]) -> [f64; 3] {
    let mut s = [0.0; 3];
    for c in layer {
        for (k, v) in c.to_array().into_iter().enumerate() {
            s[k] += f64::from(v);
        }
    }
    s
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn below_the_threshold_the_image_keeps_every_bit(
        w in 1u32..40, h in 1u32..40,
        values in prop::collection::vec(0.0f32..=1.0, 1..64),
        threshold in 0.0f32..4.0, radius in 0.0f32..20.0, strength in 0.0f32..8.0,
    ) {
        // Every value at most the threshold (the top one equal to it).
        let pixels = image(w, h, &values, threshold);
        let mut out = pixels.clone();
        bloom::apply(&mut out, w, h, &BloomSettings { threshold, radius, strength });
        prop_assert!(pixels.iter().zip(&out).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
        prop_assert!(bloom::bright_pass(&pixels, threshold).iter().all(|c| *c == Color::ZERO));
    }

    #[test]
    fn the_blur_keeps_the_bright_pass_total_energy(
        w in 1u32..48, h in 1u32..48,
        values in prop::collection::vec(0.0f32..=1.0, 1..200),
        threshold in 0.0f32..2.0, radius in 0.0f32..70.0,
    ) {
        let pixels = image(w, h, &values, 4.0);
        let l = bloom::layers(&pixels, w, h, &BloomSettings { threshold, radius, strength: 1.0 });
        let (bright, blurred) = (total(&l.bright), total(&l.blurred));
        // Two passes, each adding up to 2 ceil(radius) + 1 rounded products into a pixel,
        // with weights that sum to 1 up to as many roundings: at most (8 ceil(r) + 6) units
        // of rounding (2^-24) of the total; the bound allows twice that.
        let bound = (8.0 * f64::from(radius.ceil()) + 8.0) * f64::from(f32::EPSILON);
        for k in 0..3 {
            prop_assert!((blurred[k] - bright[k]).abs() <= bound * bright[k] + 1e-12,
                "channel {k}: bright {} blurred {} (radius {radius}, {w}x{h})", bright[k], blurred[k]);
        }
        prop_assert!(l.blurred.iter().all(|c| c.min_element() >= 0.0 && c.is_finite()));
    }
}

#[test]
fn the_glow_adds_strength_times_the_blurred_bright_pass() {
    let (w, h) = (32, 24);
    let mut pixels = vec![Color::splat(0.25); (w * h) as usize];
    pixels[(12 * w + 16) as usize] = Color::new(9.0, 5.0, 0.5);
    let settings = BloomSettings { threshold: 1.0, radius: 4.0, strength: 0.5 };
    let l = bloom::layers(&pixels, w, h, &settings);
    let mut out = pixels.clone();
    bloom::apply(&mut out, w, h, &settings);
    for i in 0..pixels.len() {
        assert_eq!(out[i], pixels[i] + 0.5 * l.blurred[i]);
    }
    // The glow spreads over the Gaussian's reach and no further.
    let changed = pixels.iter().zip(&out).filter(|(a, b)| a != b).count();
    assert_eq!(changed, 9 * 9);
}
