//! Every sample of a pixel, traced as the renderer traces it.
//!
//! The film holds a pixel as the sum of its samples (each passed through
//! [`finite_or_black`]) divided by their count, and the pixel filter is applied by warping
//! where samples go, not by weighting them: every sample weighs the same `1 / spp`. Tracing the
//! samples in order and summing them the same way gives the film's value bit for bit.

use serde::Serialize;

use crate::camera::CameraMotion;
use crate::film::{Film, finite_or_black};
use crate::math::Color;
use crate::record::RayTree;
use crate::render::{TileCulling, sample_time, trace_pixel};
use crate::scene::Scene;
use crate::settings::RenderSettings;

/// Which of a pixel's samples to trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleChoice {
    /// All `spp` of them.
    All,
    /// Only this one (0 to `spp - 1`).
    One(u32),
}

/// The samples of one pixel, with their ray trees.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PixelTrace {
    /// The pixel, `[x, y]` from the top-left corner.
    pub pixel: [u32; 2],
    /// The samples traced, in sample order.
    pub samples: Vec<SampleTrace>,
    /// The pixel's value from these samples as the film computes it: with
    /// [`SampleChoice::All`], bit-identical to [`crate::render::render`]'s film for this
    /// pixel; with [`SampleChoice::One`], that sample's colour (as the film would add it).
    pub value: Color,
    /// The pixel's tile, when the renderer culls it ([`TileCulling`]): the renderer traced
    /// none of its camera rays and filled it with the background, which the samples here,
    /// traced all the same, return as misses.
    pub culled: Option<CulledTile>,
}

/// Pixels whose camera rays the renderer did not trace, culled by one frustum test: their
/// frustum meets no box of the BVH ([`TileCulling`]). A tile, or its whole row of tiles where
/// the row's frustum was tested first and missed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct CulledTile {
    /// Its columns, `x[0]..x[1]`.
    pub x: [u32; 2],
    /// Its rows, `y[0]..y[1]`.
    pub y: [u32; 2],
    /// The BVH nodes the frustum test looked into.
    pub nodes: u32,
}

/// One sample of a pixel.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SampleTrace {
    /// Its index among the pixel's samples (it selects the sample's random numbers).
    pub index: u32,
    /// Its share of the pixel's value: `1 / samples traced`.
    pub weight: f32,
    /// Its shutter time in `[0, 1)`: where moving objects and a moving camera are for it.
    pub time: f32,
    /// The colour it traced (before [`finite_or_black`]).
    pub color: Color,
    /// True when the colour was not finite and the film adds black instead.
    pub dropped: bool,
    /// Its rays.
    pub tree: RayTree,
}

/// Trace the samples `which` of pixel `(x, y)` through `camera` with `settings`, exactly as
/// [`crate::render::render`] does, recording at most `max_rays` rays (shadow rays included)
/// over all the samples together: the samples after the bound are traced and counted in their
/// trees' [`RayTree::cut`], not recorded.
pub fn trace_pixel_samples(
    scene: &Scene,
    settings: &RenderSettings,
    camera: &CameraMotion,
    x: u32,
    y: u32,
    which: SampleChoice,
    max_rays: usize,
) -> PixelTrace {
    let indices = match which {
        SampleChoice::All => 0..settings.spp,
        SampleChoice::One(k) => k..k.saturating_add(1),
    };
    let count = indices.len();
    let weight = 1.0 / count.max(1) as f32;
    let mut budget = max_rays;
    // A film of this one pixel, to which the samples are added as the render adds them.
    let mut film = Film::new(1, 1);
    let mut dropped = 0;
    let mut samples = Vec::with_capacity(count);
    for index in indices {
        let mut tree = RayTree::with_limit(budget);
        let color = trace_pixel(scene, settings, camera, x, y, index, &mut tree);
        budget -= tree.recorded();
        let before = dropped;
        // Summed exactly, as the film sums them.
        film.add(0, 0, finite_or_black(color, &mut dropped));
        let time = sample_time(settings, x, y, index);
        samples.push(SampleTrace { index, weight, time, color, dropped: dropped > before, tree });
    }
    let value = film.get(0, 0);
    let culled = TileCulling::of(scene, settings, camera)
        .and_then(|culling| culling.culled_tile(x, y))
        .map(|(tile, test)| CulledTile { x: tile.x, y: tile.y, nodes: test.nodes });
    PixelTrace { pixel: [x, y], samples, value, culled }
}
