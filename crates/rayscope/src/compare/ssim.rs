//! The structural similarity index (SSIM) of Wang, Bovik, Sheikh and Simoncelli, "Image
//! quality assessment: from error visibility to structural similarity" (IEEE TIP, 2004), as
//! their reference code computes it: an 11x11 circular Gaussian window (sigma 1.5, weights
//! summing to 1) slides over every position where it fits whole (MATLAB's `filter2(..,
//! 'valid')`), each position gives
//!
//! `SSIM = (2 mu_x mu_y + C1)(2 sigma_xy + C2) / ((mu_x^2 + mu_y^2 + C1)(sigma_x^2 + sigma_y^2 + C2))`
//!
//! with the window's weighted means, variances and covariance, `C1 = (K1 L)^2`, `C2 = (K2
//! L)^2`, `K1 = 0.01`, `K2 = 0.03`, `L = 255`, and the mean over the positions is the index
//! (1 for identical images). The paper's optional down-sampling of large images is not
//! applied: the course's images are compared pixel for pixel.
//!
//! The window is separable, so each weighted sum is a pass over the rows then one over the
//! columns (22 products a pixel, not 121), in `f64`.

/// The side of the square window, in pixels.
pub const SSIM_WINDOW: usize = 11;

/// The standard deviation of the window's Gaussian, in pixels.
pub const SSIM_SIGMA: f64 = 1.5;

/// The dynamic range of the values (8-bit levels).
const L: f64 = 255.0;
const K1: f64 = 0.01;
const K2: f64 = 0.03;
const C1: f64 = (K1 * L) * (K1 * L);
const C2: f64 = (K2 * L) * (K2 * L);

/// The window's one-dimensional weights, summing to 1.
fn weights() -> [f64; SSIM_WINDOW] {
    let r = (SSIM_WINDOW / 2) as f64;
    let mut w = [0.0; SSIM_WINDOW];
    for (i, v) in w.iter_mut().enumerate() {
        let d = i as f64 - r;
        *v = (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let sum: f64 = w.iter().sum();
    w.map(|v| v / sum)
}

/// The weighted sums of `values` (`width` x `height`, rows from the top) over every whole
/// window, as a `(width - 10) x (height - 10)` image.
fn filter_valid(values: &[f64], width: usize, height: usize, w: &[f64; SSIM_WINDOW]) -> Vec<f64> {
    let (ow, oh) = (width + 1 - SSIM_WINDOW, height + 1 - SSIM_WINDOW);
    // Along rows: every row, `ow` columns.
    let mut rows = vec![0.0; ow * height];
    for y in 0..height {
        let src = &values[y * width..(y + 1) * width];
        for x in 0..ow {
            rows[y * ow + x] = w.iter().zip(&src[x..x + SSIM_WINDOW]).map(|(a, b)| a * b).sum();
        }
    }
    // Along columns.
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = w.iter().enumerate().map(|(k, a)| a * rows[(y + k) * ow + x]).sum();
        }
    }
    out
}

/// The mean SSIM of two images of luminance in `[0, 255]` (`width` x `height`, rows from
/// the top); `None` when the image is smaller than the window in either direction.
pub(super) fn mean_ssim(x: &[f64], y: &[f64], width: usize, height: usize) -> Option<f64> {
    if width < SSIM_WINDOW || height < SSIM_WINDOW {
        return None;
    }
    let w = weights();
    let product = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| p * q).collect::<Vec<f64>>();
    let f = |v: &[f64]| filter_valid(v, width, height, &w);
    let (mu_x, mu_y) = (f(x), f(y));
    let (xx, yy, xy) = (f(&product(x, x)), f(&product(y, y)), f(&product(x, y)));
    let n = mu_x.len();
    let sum: f64 = (0..n)
        .map(|i| {
            let (mx, my) = (mu_x[i], mu_y[i]);
            let (vx, vy, cxy) = (xx[i] - mx * mx, yy[i] - my * my, xy[i] - mx * my);
            ((2.0 * mx * my + C1) * (2.0 * cxy + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2))
        })
        .sum();
    Some(sum / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pseudo-random image (a fixed linear congruential sequence), in `[0, 255]`.
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                ((s >> 33) % 256) as f64
            })
            .collect()
    }

    /// SSIM by the definition, window by window with the 2D weights: the oracle.
    fn ssim_direct(x: &[f64], y: &[f64], width: usize, height: usize) -> f64 {
        let w = weights();
        let mut sum = 0.0;
        let mut count = 0;
        for oy in 0..=height - SSIM_WINDOW {
            for ox in 0..=width - SSIM_WINDOW {
                let (mut mx, mut my, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for j in 0..SSIM_WINDOW {
                    for i in 0..SSIM_WINDOW {
                        let k = (oy + j) * width + ox + i;
                        let wt = w[i] * w[j];
                        mx += wt * x[k];
                        my += wt * y[k];
                        sxx += wt * x[k] * x[k];
                        syy += wt * y[k] * y[k];
                        sxy += wt * x[k] * y[k];
                    }
                }
                let (vx, vy, cxy) = (sxx - mx * mx, syy - my * my, sxy - mx * my);
                sum += ((2.0 * mx * my + C1) * (2.0 * cxy + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2));
                count += 1;
            }
        }
        sum / count as f64
    }

    #[test]
    fn the_window_is_a_normalised_gaussian() {
        let w = weights();
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert_eq!(w[0], w[10]);
        assert!((w[5] / w[4] - (1.0 / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()).abs() < 1e-12);
    }

    #[test]
    fn identical_images_score_1() {
        let x = noise(30 * 20, 1);
        assert_eq!(mean_ssim(&x, &x, 30, 20), Some(1.0));
    }

    #[test]
    fn constant_images_follow_the_luminance_term() {
        // No variance: SSIM is (2ab + C1) / (a^2 + b^2 + C1) at every window.
        let (a, b) = (100.0, 120.0);
        let s = mean_ssim(&[a; 16 * 14], &[b; 16 * 14], 16, 14).unwrap();
        let expected = (2.0 * a * b + C1) / (a * a + b * b + C1);
        assert!((s - expected).abs() < 1e-12, "{s} vs {expected}");
        assert!((C1 - 6.5025).abs() < 1e-12 && (C2 - 58.5225).abs() < 1e-12);
    }

    #[test]
    fn an_inverted_image_scores_below_0() {
        // Inverting about the mean keeps the means and variances and negates the covariance.
        let x = noise(24 * 24, 2);
        let y: Vec<f64> = x.iter().map(|v| 255.0 - v).collect();
        let s = mean_ssim(&x, &y, 24, 24).unwrap();
        assert!(s < 0.0, "{s}");
    }

    #[test]
    fn the_separable_filter_equals_the_definition() {
        let (w, h) = (23, 17);
        let x = noise(w * h, 3);
        let y: Vec<f64> =
            x.iter().zip(noise(w * h, 4)).map(|(a, n)| (a + 0.3 * (n - 128.0)).clamp(0.0, 255.0)).collect();
        let fast = mean_ssim(&x, &y, w, h).unwrap();
        let direct = ssim_direct(&x, &y, w, h);
        assert!((fast - direct).abs() < 1e-12, "{fast} vs {direct}");
        assert!(fast > 0.0 && fast < 1.0);
    }

    #[test]
    fn images_smaller_than_the_window_have_no_ssim() {
        let x = vec![0.0; 10 * 40];
        assert_eq!(mean_ssim(&x, &x, 10, 40), None);
        assert_eq!(mean_ssim(&x, &x, 40, 10), None);
        let x = vec![7.0; 11 * 11];
        assert_eq!(mean_ssim(&x, &x, 11, 11), Some(1.0));
    }
}
