//! Pixel reconstruction filters, applied by importance sampling: each sample's position is
//! drawn from the filter's distribution around the pixel centre and all samples weigh the
//! same. This is unbiased, keeps every pixel independent of its neighbours (so images stay
//! thread-independent), and needs no splatting (pbrt-v4 does the same).

use std::sync::OnceLock;

use crate::math::Vec2;
use crate::settings::PixelFilter;

/// Gaussian parameters: sigma and truncation radius, in pixels.
const SIGMA: f32 = 0.5;
const RADIUS: f32 = 1.5;
const TABLE: usize = 1024;

/// Inverse CDF of the truncated 1D Gaussian, tabulated once.
fn gaussian_table() -> &'static [f32] {
    static T: OnceLock<Vec<f32>> = OnceLock::new();
    T.get_or_init(|| {
        // Fine CDF by the midpoint rule, then invert it at TABLE + 1 levels.
        let steps = 1 << 14;
        let dx = 2.0 * RADIUS as f64 / steps as f64;
        let mut cdf = vec![0.0f64; steps + 1];
        for i in 0..steps {
            let x = -RADIUS as f64 + (i as f64 + 0.5) * dx;
            cdf[i + 1] = cdf[i] + (-(x * x) / (2.0 * (SIGMA as f64).powi(2))).exp() * dx;
        }
        let total = cdf[steps];
        let mut out = Vec::with_capacity(TABLE + 1);
        let mut j = 0;
        for k in 0..=TABLE {
            let target = k as f64 / TABLE as f64 * total;
            while j < steps && cdf[j + 1] < target {
                j += 1;
            }
            let span = (cdf[j + 1] - cdf[j]).max(1e-300);
            let f = ((target - cdf[j]) / span).clamp(0.0, 1.0);
            out.push((-RADIUS as f64 + (j as f64 + f) * dx) as f32);
        }
        out
    })
}

// Inlined into the camera rays' loop: the footprint's second instantiation of the render loop
// moved it out of line (2.2M more instructions on the Cornell box at 300x300, 2 spp).
#[inline(always)]
fn warp_1d(filter: PixelFilter, u: f32) -> f32 {
    match filter {
        PixelFilter::Box => u - 0.5,
        PixelFilter::Tent => {
            if u < 0.5 {
                -1.0 + (2.0 * u).sqrt()
            } else {
                1.0 - (2.0 - 2.0 * u).sqrt()
            }
        }
        PixelFilter::Gaussian => {
            let t = gaussian_table();
            let x = u * TABLE as f32;
            let i = (x as usize).min(TABLE - 1);
            t[i] + (t[i + 1] - t[i]) * (x - i as f32)
        }
    }
}

impl PixelFilter {
    /// The offset from the pixel centre, in pixels, of a sample with uniform numbers `u`. The
    /// filters are separable, so each axis is warped alone; stratification of `u` carries over.
    #[inline(always)]
    pub fn warp(self, u: Vec2) -> Vec2 {
        Vec2::new(warp_1d(self, u.x), warp_1d(self, u.y))
    }

    /// The largest offset [`PixelFilter::warp`] gives along an axis, in pixels: how far
    /// beyond its pixel's centre a sample may land.
    pub fn radius(self) -> f32 {
        match self {
            PixelFilter::Box => 0.5,
            PixelFilter::Tent => 1.0,
            PixelFilter::Gaussian => RADIUS,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moments(f: PixelFilter) -> (f32, f32, f32) {
        let n = 4096;
        let xs: Vec<f32> = (0..n).map(|i| warp_1d(f, (i as f32 + 0.5) / n as f32)).collect();
        let mean = xs.iter().sum::<f32>() / n as f32;
        let var = xs.iter().map(|x| x * x).sum::<f32>() / n as f32;
        let max = xs.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        (mean, var, max)
    }

    #[test]
    fn filters_have_their_shapes() {
        let (m, v, r) = moments(PixelFilter::Box);
        assert!(m.abs() < 1e-4 && (v - 1.0 / 12.0).abs() < 1e-3 && r <= 0.5);
        let (m, v, r) = moments(PixelFilter::Tent);
        assert!(m.abs() < 1e-4 && (v - 1.0 / 6.0).abs() < 1e-3 && r <= 1.0);
        let (m, v, r) = moments(PixelFilter::Gaussian);
        // Truncation at 3 sigma trims the variance by about 2.7%.
        assert!(m.abs() < 1e-3 && (v - 0.25 * 0.973).abs() < 3e-3 && r <= RADIUS, "{m} {v} {r}");
    }

    /// No sample lands farther from its pixel's centre than the filter's radius (what the
    /// renderer's tile frustums are widened by), the ends of `[0, 1)` included.
    #[test]
    fn warps_stay_within_the_radius() {
        for f in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Gaussian] {
            let ends = [0.0, f32::EPSILON, 0.5, 1.0 - f32::EPSILON / 2.0];
            let us = (0..=1 << 16).map(|i| i as f32 / 65537.0).chain(ends);
            for u in us {
                let w = warp_1d(f, u);
                assert!(w.abs() <= f.radius(), "{f:?} u {u}: {w}");
            }
        }
    }
}
