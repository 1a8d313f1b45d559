//! Rendering an image: the parallel loop over bands of rows that adds samples to a film, and
//! single-sample tracing for the debugger (the same code path). The AOVs are in
//! [`crate::aov`].

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::bvh::{FrustumTest, PACKET};
use crate::camera::{CameraMotion, RayGenerator};
use crate::cone::Footprint;
use crate::film::exact_sum::ExactSum;
use crate::film::{Film, FilmSlices, PassSlices, PixelAccumulator, Residual, finite_or_black};
use crate::integrator::{CameraBatch, Integrator, PathContext};
use crate::lens::ThinLens;
use crate::math::{Color, Vec2};
use crate::ray::Ray;
use crate::record::{NoRecorder, RayKind, RayRecorder};
use crate::sampler::PixelSampler;
use crate::scene::{Hit, Scene};
use crate::settings::{RenderSettings, TextureFilter};
use crate::sky::Sky;

// The counts a render reports, under the name its users meet them by.
pub use crate::integrator::RayCounts;

/// Progress of a render, as passed to its callback.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderProgress {
    /// Pixels finished in this pass.
    pub done: usize,
    /// Pixels in all.
    pub total: usize,
}

/// A finished (or interrupted) render.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// The image.
    pub film: Film,
    /// Rays cast.
    pub rays: RayCounts,
    /// Wall-clock time of the tile loop.
    pub elapsed: Duration,
    /// False when a cancel request stopped the render before every pixel was done.
    pub complete: bool,
}

impl RenderOutput {
    /// Millions of rays per second, all kinds.
    pub fn mrays_per_second(&self) -> f64 {
        self.rays.total() as f64 / self.elapsed.as_secs_f64().max(1e-9) / 1e6
    }
}

/// The tiles rendering culls: [`PACKET`] by [`TILE_ROWS`] pixels from the top-left corner
/// (cut by the image's edges), each tested once per pass. A tile whose frustum (every ray of
/// its pixels, at every offset the pixel filter gives, widened by a pixel) meets no leaf box
/// of the BVH cannot hit anything: where every missing ray returns the same colour (the
/// background, no environment map) and camera rays share an origin (a still pinhole), the
/// renderer fills such a tile with it and traces none of its rays. The film, the ray counts
/// and every other number are those of tracing them. A row of tiles (the image's width) is
/// tested first, and where its frustum meets no leaf box all its tiles are culled without a
/// test each: the rows above and below a lone object (1.2-1.9% of the dragon's, the teapot's
/// and the Cornell box's renders, BENCHMARKS.md, session 32).
#[derive(Clone, Copy, Debug)]
pub struct TileCulling<'a> {
    scene: &'a Scene,
    /// The still camera's rays.
    rays: RayGenerator,
    /// How far from its pixel's centre a sample may land ([`crate::settings::PixelFilter::radius`]).
    reach: f32,
    /// The image's size.
    size: [u32; 2],
}

/// A tile of the image: columns `x[0]..x[1]`, rows `y[0]..y[1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    /// Its columns.
    pub x: [u32; 2],
    /// Its rows.
    pub y: [u32; 2],
}

impl Tile {
    /// Its pixels.
    pub fn pixels(&self) -> u32 {
        (self.x[1] - self.x[0]) * (self.y[1] - self.y[0])
    }
}

impl<'a> TileCulling<'a> {
    /// The culling of a render of `scene` with `settings` through `camera`: `None` where
    /// rendering traces every camera ray (a moving camera, a lens, an environment map).
    pub fn of(scene: &'a Scene, settings: &RenderSettings, camera: &CameraMotion) -> Option<TileCulling<'a>> {
        let pinhole = camera.is_still() && ThinLens::new(settings, &camera.start).is_none();
        (pinhole && scene.environment.is_none()).then(|| TileCulling {
            scene,
            rays: RayGenerator::new(&camera.start, settings.width, settings.height),
            reach: settings.filter.radius(),
            size: [settings.width, settings.height],
        })
    }

    /// The tile that holds pixel `(x, y)`.
    pub fn tile(&self, x: u32, y: u32) -> Tile {
        let (x0, y0) = (x - x % PACKET as u32, y - y % TILE_ROWS as u32);
        let [w, h] = self.size;
        Tile { x: [x0, (x0 + PACKET as u32).min(w)], y: [y0, (y0 + TILE_ROWS as u32).min(h)] }
    }

    /// The frustum test of `tile`: `may_hit` false when none of its rays can hit anything,
    /// and the nodes the test looked into.
    pub fn test(&self, tile: Tile) -> FrustumTest {
        self.scene.frustum_test(&self.rays.tile_frustum(tile.x, tile.y, self.reach))
    }

    /// The row of tiles that holds `tile`: the image's width, the tile's rows.
    fn row_of(&self, tile: Tile) -> Tile {
        Tile { x: [0, self.size[0]], y: tile.y }
    }

    /// When the renderer culls the tile that holds pixel `(x, y)`: the tiles culled by one
    /// frustum test with it and that test, the tile's row where the row's frustum meets no
    /// leaf box, else the tile alone.
    pub fn culled_tile(&self, x: u32, y: u32) -> Option<(Tile, FrustumTest)> {
        let tile = self.tile(x, y);
        let row = self.row_of(tile);
        let test = self.test(row);
        if !test.may_hit {
            return Some((row, test));
        }
        let test = self.test(tile);
        (!test.may_hit).then_some((tile, test))
    }

    /// Each tile of rows `y[0]..y[1]` (as [`TileCulling::tiles`] orders them) and whether the
    /// renderer culls it: all of a row whose frustum meets no leaf box, else those whose own
    /// does not (the one rule of [`TileCulling::culled_tile`]).
    fn culled(&self, y: [u32; 2]) -> impl Iterator<Item = (Tile, bool)> + '_ {
        (y[0]..y[1]).step_by(TILE_ROWS).flat_map(move |ty| {
            let row = self.row_of(self.tile(0, ty));
            let all = !self.test(row).may_hit;
            self.tiles([ty, row.y[1]]).map(move |t| (t, all || !self.test(t).may_hit))
        })
    }

    /// The tiles of rows `y[0]..y[1]` (`y[0]` a multiple of [`TILE_ROWS`]), by tile row then
    /// column.
    fn tiles(&self, y: [u32; 2]) -> impl Iterator<Item = Tile> + '_ {
        let w = self.size[0];
        (y[0]..y[1]).step_by(TILE_ROWS).flat_map(move |ty| (0..w).step_by(PACKET).map(move |tx| self.tile(tx, ty)))
    }

    /// Pixels of the image in tiles the renderer culls (whose camera rays it does not trace).
    pub fn culled_pixels(&self) -> u64 {
        self.culled([0, self.size[1]]).filter(|(_, culled)| *culled).map(|(t, _)| u64::from(t.pixels())).sum()
    }
}

/// Which samples a pass adds to each pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SamplePass {
    /// Samples to add to every pixel; each pixel continues from the samples it already has.
    pub samples: u32,
    /// No pixel goes past this many samples (so pixels left behind by an interrupted pass
    /// catch up without the others overshooting); `u32::MAX` for no limit.
    pub limit: u32,
    /// The total the pixel is planned to receive (selects stratification; 0: open-ended).
    pub planned: u32,
    /// Seed of this pass's random numbers.
    pub seed: u64,
}

/// Add `pass.samples` samples to every pixel of `film` (sized as `settings`), seen through
/// `camera`. Pixel sample `k` always uses the same random numbers, so adding 3 then 2 samples
/// gives the same film, bit for bit, as adding 5. Tiles not started when `cancel` is set are
/// skipped; the return value says whether every pixel got its samples.
pub fn render_pass(
    scene: &Scene,
    settings: &RenderSettings,
    camera: &CameraMotion,
    film: &mut Film,
    pass: SamplePass,
    cancel: &AtomicBool,
    progress: &(dyn Fn(RenderProgress) + Sync),
) -> (RayCounts, bool) {
    // The sky is chosen here, once: a scene without an environment map runs the miss path
    // it always had (see `crate::sky`).
    pass_culling(scene, settings, camera, film, pass, CameraTrace::Fast, cancel, progress)
}

/// How a pass traces its camera rays: with the shortcuts rendering takes, or plainly.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CameraTrace {
    /// Rendering's choice: tiles that cannot hit anything skipped ([`Pass::cull`]), and
    /// tiles of packets traced as one where the scene is large enough ([`Pass::tiles`]).
    Fast,
    /// Every camera ray traced, packet by packet (the oracle of the shortcuts' tests).
    #[cfg_attr(not(test), allow(dead_code))]
    Plain,
}

/// [`render_pass`], with rendering's shortcuts or without.
#[allow(clippy::too_many_arguments)]
fn pass_culling(
    scene: &Scene,
    settings: &RenderSettings,
    camera: &CameraMotion,
    film: &mut Film,
    pass: SamplePass,
    culling: CameraTrace,
    cancel: &AtomicBool,
    progress: &(dyn Fn(RenderProgress) + Sync),
) -> (RayCounts, bool) {
    let run = PassRun { camera, pass, culling, cancel, progress };
    match &scene.environment {
        None => pass_footprint(Integrator::new(scene, settings), film, run),
        Some(env) => pass_footprint(Integrator::with_sky(scene, settings, env), film, run),
    }
}

/// What a pass is asked to do, beside its integrator and film.
#[derive(Clone, Copy)]
struct PassRun<'a> {
    camera: &'a CameraMotion,
    pass: SamplePass,
    culling: CameraTrace,
    cancel: &'a AtomicBool,
    progress: &'a (dyn Fn(RenderProgress) + Sync),
}

/// [`render_pass`] with `integrator`, whose rays carry cones when textures are filtered
/// trilinearly (chosen here, once: other filters run code with no footprint in it).
fn pass_footprint<S: Sky>(integrator: Integrator<S>, film: &mut Film, run: PassRun) -> (RayCounts, bool) {
    if integrator.settings.texture_filter == TextureFilter::Trilinear {
        return pass_with(&integrator.with_cones(&run.camera.start), film, run);
    }
    pass_with(&integrator, film, run)
}

/// [`render_pass`] with `integrator`.
fn pass_with<S: Sky, C: Footprint>(integrator: &Integrator<S, C>, film: &mut Film, run: PassRun) -> (RayCounts, bool) {
    let PassRun { camera, pass, culling, cancel, progress } = run;
    let settings = integrator.settings;
    let still = camera.is_still().then(|| RayGenerator::new(&camera.start, settings.width, settings.height));
    let mut setup = Pass::new(integrator, camera, still.as_ref(), pass);
    if culling == CameraTrace::Plain {
        setup.cull = None;
        setup.tiles = false;
    }
    // A fresh film's first pass of one sample adds to `f32` sums, any other to `f64` ones
    // (`Film::pass_slices`): the same loop, generic over the sums.
    let results = match film.pass_slices(pass.samples) {
        PassSlices::Single(slices) => setup.bands(slices, cancel, progress),
        PassSlices::Exact(slices) => setup.bands(slices, cancel, progress),
    };
    let mut sum = Tally::default();
    let mut complete = true;
    let mut residuals = Vec::new();
    for band in results {
        sum.add(band.tally);
        complete &= band.complete;
        residuals.extend(band.residuals);
    }
    film.add_dropped(sum.dropped);
    film.add_residuals(residuals);
    (sum.rays, complete)
}

/// What the samples of some pixels cast and left out.
#[derive(Clone, Copy, Debug, Default)]
struct Tally {
    /// Rays cast.
    rays: RayCounts,
    /// Samples that were not finite, added as black ([`finite_or_black`]).
    dropped: u64,
}

impl Tally {
    fn add(&mut self, o: Tally) {
        self.rays.add(o.rays);
        self.dropped += o.dropped;
    }
}

/// One band of rows of a pass: its tally, what its sums lost to rounding, and whether it ran
/// (false: cancelled first).
struct Band {
    tally: Tally,
    residuals: Vec<Residual>,
    complete: bool,
}

/// Rows per task in [`render_pass`]: enough work per task to amortise scheduling, and tasks
/// small enough (100 for 800 rows) that the last ones leave little for one thread alone where
/// the work gathers in a few rows (the dragon's, the Cornell box's: 16 rows were 1.5% slower
/// on two threads).
const BAND_ROWS: usize = 8;

/// Rows of a tile whose camera rays are culled together ([`TileCulling`]): tiles are
/// [`PACKET`] pixels wide (a packet's run of a row) and this tall, one row of them a band. Small
/// enough to follow a silhouette (on the dragon, 8x8 tiles leave out 95% of the pixels its
/// rays miss), large enough that the frustum test costs little per pixel.
pub const TILE_ROWS: usize = 8;

/// Fewest primitives for a scene's camera rays to go through the BVH as tiles of packets
/// ([`Scene::intersect_tile`]) rather than packet by packet: the camera hits of the Cornell
/// box's 32 triangles (a root and its leaves) took 6% longer as tiles, the teapot's 11-14%
/// and the dragon's 12-19% less (BENCHMARKS.md, session 28).
pub const TILE_PRIMS: usize = 256;

/// Whether a still pinhole camera's rays in `scene` go through the BVH as tiles of packets
/// ([`Scene::intersect_tile`], a tile's [`TILE_ROWS`] rows together) rather than packet by
/// packet: in scenes of [`TILE_PRIMS`] primitives or more.
pub fn traces_camera_tiles(scene: &Scene) -> bool {
    scene.prim_count() >= TILE_PRIMS
}

// A tile's rows are traced together: at most one tile's runs.
const _: () = assert!(TILE_ROWS <= crate::bvh::TILE_RUNS);

// A band is whole tiles: `Pass::bands` indexes a band's tiles from its first row.
const _: () = assert!(BAND_ROWS.is_multiple_of(TILE_ROWS));

/// The samples a pixel that has `first` gets in `pass`: `first..` the returned end.
fn sample_range(first: u32, pass: SamplePass) -> u32 {
    first.saturating_add(pass.samples).min(pass.limit.max(first))
}

/// The camera ray of pixel `(x, y)` for the sample whose random numbers are `sampler`
/// (`still`: a still camera's ray generator, made once per pass; a moving camera's is made
/// per sample), made by `through` from the pose's generator, the pixel and the jitter (a
/// pinhole's ray, or a lens's: generic, so the pinhole's code has no lens in it).
#[inline(always)]
fn camera_ray(
    settings: &RenderSettings,
    camera: &CameraMotion,
    still: Option<&RayGenerator>,
    x: u32,
    y: u32,
    sampler: &PixelSampler,
    through: impl Fn(&RayGenerator, u32, u32, Vec2) -> Ray,
) -> Ray {
    let jitter = pixel_jitter(settings, sampler);
    let time = sampler.time;
    let mut ray = match still {
        Some(rays) => through(rays, x, y, jitter),
        None => through(&RayGenerator::new(&camera.at(time), settings.width, settings.height), x, y, jitter),
    };
    ray.time = time;
    ray
}

/// Where in its pixel the sample `sampler` draws goes through (0.5 is the centre), by the
/// settings' pixel filter.
#[inline(always)]
fn pixel_jitter(settings: &RenderSettings, sampler: &PixelSampler) -> Vec2 {
    Vec2::splat(0.5) + settings.filter.warp(sampler.pixel_offset)
}

/// What every pixel of a pass shares.
struct Pass<'a, S: Sky, C: Footprint> {
    /// The scene and settings, ready to shade.
    integrator: &'a Integrator<'a, S, C>,
    /// The camera over the shutter interval.
    camera: &'a CameraMotion,
    /// A still camera's ray generator, made once per pass (`None` for a moving camera, whose
    /// generator is made per sample).
    still: Option<&'a RayGenerator>,
    /// The thin lens (`None`: a pinhole, whose rays draw no lens sample).
    lens: Option<ThinLens>,
    /// Whether camera rays go through the BVH in packets: a still pinhole's rays share their
    /// origin (a lens's do not, and the packet would fall back to one by one).
    packets: bool,
    /// Whether a still pinhole's camera rays go through the BVH as tiles of packets, a tile's
    /// rows together ([`Scene::intersect_tile`]): with [`Pass::packets`], where
    /// [`traces_camera_tiles`].
    tiles: bool,
    /// Whether a packet's hits trace their first shadow rays ahead, as packets
    /// ([`Integrator::shadows_ahead`]).
    shadows_ahead: bool,
    /// Whether a packet's hits (where their shadow rays are traced ahead) trace their mirror
    /// rays ahead too ([`Integrator::mirrors_ahead`]).
    mirrors_ahead: bool,
    /// Where camera rays go in packets and misses do not depend on the ray (no environment
    /// map): the tiles' frustum tests, and the colour every camera ray that hits nothing
    /// returns, which fills a tile whose frustum meets no box of the BVH, its rays not traced
    /// ([`TileCulling`]). `None`: every pixel is traced.
    cull: Option<(TileCulling<'a>, Color)>,
    /// Which samples the pass adds.
    pass: SamplePass,
}

/// Up to [`PACKET`] pixels of row `y` from `x0` rightwards, with their running sums and sample
/// counts in the film, and where to keep what the sums lose to rounding.
struct PixelRun<'a, A> {
    x0: u32,
    y: u32,
    sums: &'a mut [A],
    counts: &'a mut [u32],
    residuals: &'a mut Vec<Residual>,
}

/// A run's pixels in the film: their sums and sample counts.
type RunSlices<'a, A> = (&'a mut [A], &'a mut [u32]);

impl<'a, S: Sky, C: Footprint> Pass<'a, S, C> {
    /// Add the pass's samples to every pixel of `film`: bands of whole rows, rendered in
    /// place (each task owns its slice of the film, so there is no intermediate buffer to
    /// fill and copy; every pixel's value depends only on the pixel, so the split does not
    /// change the image). Tiles not started when `cancel` is set are skipped. Sums left
    /// stale by a cleared film ([`FilmSlices::stale`]) are zeroed band by band, each just
    /// before its band adds to them (a skipped band's too).
    fn bands<A: PixelAccumulator>(
        &self,
        film: FilmSlices<'_, A>,
        cancel: &AtomicBool,
        progress: &(dyn Fn(RenderProgress) + Sync),
    ) -> Vec<Band> {
        let w = self.integrator.settings.width as usize;
        let total = film.sums.len();
        let done = AtomicUsize::new(0);
        let band = BAND_ROWS * w;
        film.sums
            .par_chunks_mut(band)
            .zip(film.counts.par_chunks_mut(band))
            .enumerate()
            .map(|(b, (sums, counts))| {
                if film.stale {
                    sums.fill(A::default());
                }
                if cancel.load(Ordering::Relaxed) {
                    return Band { tally: Tally::default(), residuals: Vec::new(), complete: false };
                }
                let mut tally = Tally::default();
                let mut residuals = Vec::new();
                let y0 = b * BAND_ROWS;
                let culled = self.culled_tiles(y0, sums.len() / w);
                if self.tiles {
                    self.band_by_tiles(y0 as u32, sums, counts, &culled, &mut tally, &mut residuals);
                } else {
                    self.band_by_runs(y0 as u32, sums, counts, &culled, &mut tally, &mut residuals);
                }
                let d = done.fetch_add(sums.len(), Ordering::Relaxed) + sums.len();
                progress(RenderProgress { done: d, total });
                Band { tally, residuals, complete: true }
            })
            .collect()
    }

    /// Add the pass's samples to the band of rows from `y0` (its film `sums` and `counts`,
    /// `culled` its tiles' culling as [`Pass::culled_tiles`] gives it) run by run: each run of
    /// a row's [`PACKET`] pixels filled where its tile is culled, else traced as a packet
    /// ([`Pass::sample_run`]) or pixel by pixel.
    fn band_by_runs<A: PixelAccumulator>(
        &self,
        y0: u32,
        sums: &mut [A],
        counts: &mut [u32],
        culled: &[bool],
        tally: &mut Tally,
        residuals: &mut Vec<Residual>,
    ) {
        let w = self.integrator.settings.width as usize;
        let tiles = w.div_ceil(PACKET);
        let rows = sums.chunks_mut(w).zip(counts.chunks_mut(w));
        for (row, (sums, counts)) in rows.enumerate() {
            let y = y0 + row as u32;
            let runs = sums.chunks_mut(PACKET).zip(counts.chunks_mut(PACKET));
            for (run, (sums, counts)) in runs.enumerate() {
                let pixels = PixelRun { x0: (run * PACKET) as u32, y, sums, counts, residuals: &mut *residuals };
                if let Some((_, miss)) = self.cull.filter(|_| culled[row / TILE_ROWS * tiles + run]) {
                    tally.add(self.fill_missed(pixels, miss));
                    continue;
                }
                tally.add(self.sample_run_or_alone(pixels));
            }
        }
    }

    /// Add the pass's samples to `pixels`, a run of a row: as a packet ([`Pass::sample_run`])
    /// where they are side by side at the same sample and seen by a still camera (their camera
    /// rays share the pinhole and go through the BVH together), else pixel by pixel.
    #[inline(always)]
    fn sample_run_or_alone<A: PixelAccumulator>(&self, pixels: PixelRun<A>) -> Tally {
        let same = pixels.counts.iter().all(|c| *c == pixels.counts[0]);
        if self.packets && same { self.sample_run(pixels) } else { self.sample_alone(pixels) }
    }

    /// Add the pass's samples to the band of rows from `y0` (its film `sums` and `counts`,
    /// `culled` its tiles' culling as [`Pass::culled_tiles`] gives it) tile by tile, each
    /// tile's camera rays traced as one ([`Pass::sample_tile`]) when all its pixels are at
    /// the same sample, else run by run as [`Pass::bands`] traces them.
    fn band_by_tiles<A: PixelAccumulator>(
        &self,
        y0: u32,
        sums: &mut [A],
        counts: &mut [u32],
        culled: &[bool],
        tally: &mut Tally,
        residuals: &mut Vec<Residual>,
    ) {
        let w = self.integrator.settings.width as usize;
        let tiles = w.div_ceil(PACKET);
        let tile_rows = sums.chunks_mut(TILE_ROWS * w).zip(counts.chunks_mut(TILE_ROWS * w));
        for (ty, (sums, counts)) in tile_rows.enumerate() {
            let y0 = y0 + (ty * TILE_ROWS) as u32;
            let mut rows: Vec<_> = sums
                .chunks_mut(w)
                .zip(counts.chunks_mut(w))
                .map(|(s, c)| s.chunks_mut(PACKET).zip(c.chunks_mut(PACKET)))
                .collect();
            for (t, x0) in (0..w).step_by(PACKET).enumerate() {
                let x0 = x0 as u32;
                let mut runs: [Option<RunSlices<A>>; TILE_ROWS] =
                    std::array::from_fn(|r| rows.get_mut(r).and_then(Iterator::next));
                if let Some((_, miss)) = self.cull.filter(|_| culled[ty * tiles + t]) {
                    for (r, (sums, counts)) in runs.iter_mut().flatten().enumerate() {
                        let pixels = PixelRun { x0, y: y0 + r as u32, sums, counts, residuals: &mut *residuals };
                        tally.add(self.fill_missed(pixels, miss));
                    }
                    continue;
                }
                // Pixels of the tile all at the same sample (see `Pass::bands`).
                let first = runs[0].as_ref().map(|(_, c)| c[0]);
                if runs.iter().flatten().all(|(_, c)| c.iter().all(|c| Some(*c) == first)) {
                    tally.add(self.sample_tile(x0, y0, &mut runs, residuals));
                    continue;
                }
                for (r, (sums, counts)) in runs.iter_mut().flatten().enumerate() {
                    let pixels = PixelRun { x0, y: y0 + r as u32, sums, counts, residuals: &mut *residuals };
                    tally.add(self.sample_run_or_alone(pixels));
                }
            }
        }
    }

    fn new(
        integrator: &'a Integrator<'a, S, C>,
        camera: &'a CameraMotion,
        still: Option<&'a RayGenerator>,
        pass: SamplePass,
    ) -> Pass<'a, S, C> {
        // The lens of the pose at shutter open: a moving camera keeps its focus distance.
        let lens = ThinLens::new(integrator.settings, &camera.start);
        let packets = camera.is_still() && lens.is_none();
        let tiles = packets && traces_camera_tiles(integrator.scene);
        // The one rule of `TileCulling::of` (which the debugger and the heat map ask too),
        // for the passes that have a still camera's generator (not the debugger's own).
        let (scene, settings) = (integrator.scene, integrator.settings);
        let culling = still.and_then(|_| TileCulling::of(scene, settings, camera));
        let cull = culling.zip(integrator.sky.uniform(settings));
        let shadows_ahead = packets && integrator.shadows_ahead();
        let mirrors_ahead = shadows_ahead && integrator.mirrors_ahead();
        Pass { integrator, camera, still, lens, packets, tiles, shadows_ahead, mirrors_ahead, cull, pass }
    }

    /// Which tiles of the band of `rows` rows from row `y0` hold no pixel whose camera rays
    /// could hit anything, by tile row then column ([`TileCulling::tile`]; empty when the
    /// pass does not cull).
    fn culled_tiles(&self, y0: usize, rows: usize) -> Vec<bool> {
        let Some((culling, _)) = &self.cull else { return Vec::new() };
        culling.culled([y0 as u32, (y0 + rows) as u32]).map(|(_, culled)| culled).collect()
    }

    /// Trace sample `k` of pixel `(x, y)`: the one function every image, and the debugger,
    /// uses (or [`Pass::sample_run`] and [`Pass::sample_tile`], which differ only in finding
    /// the camera rays' hits as a packet or a tile).
    fn sample_pixel<R: RayRecorder>(&self, x: u32, y: u32, k: u32, rec: &mut R) -> (Color, RayCounts) {
        let sampler = self.sampler(x, y, k);
        let ray = self.camera_ray(x, y, k, &sampler);
        if R::RECORDS && self.packets {
            // A still camera's rays go through the BVH in packets (`sample_run`) or tiles
            // (`sample_tile`): the recorder is told what the packet or tile of this pixel
            // entered for its ray.
            let (runs, run, lane) = self.camera_batch(x, y, k);
            let mut ctx = PathContext::new(sampler, rec);
            let tile: Vec<&[Ray]> = runs.iter().map(Vec::as_slice).collect();
            let batch = if self.tiles { CameraBatch::Tile(&tile) } else { CameraBatch::Packet(tile[run]) };
            let c = self.integrator.li_in_packet(batch, (run, lane), self.mirrors_ahead, &mut ctx);
            return (c, ctx.counts);
        }
        let mut ctx = PathContext::new(sampler, rec);
        let c = self.integrator.li(&ray, RayKind::Camera, 0, &mut ctx);
        (c, ctx.counts)
    }

    /// The camera rays of sample `k` that [`render_pass`] traces with pixel `(x, y)`'s, run
    /// by run: its packet (the [`PACKET`] pixels of a row from a multiple of [`PACKET`], fewer
    /// at the row's end) or, where the pass traces tiles, its tile (those runs of the
    /// [`TILE_ROWS`] rows from a multiple of [`TILE_ROWS`], fewer at the image's end); and the
    /// pixel's run and place in it.
    fn camera_batch(&self, x: u32, y: u32, k: u32) -> (Vec<Vec<Ray>>, usize, usize) {
        let (w, h) = (self.integrator.settings.width, self.integrator.settings.height);
        let rows = if self.tiles { TILE_ROWS as u32 } else { 1 };
        let (x0, y0) = (x - x % PACKET as u32, y - y % rows);
        let (x1, y1) = ((x0 + PACKET as u32).min(w), (y0 + rows).min(h));
        let run = |yi: u32| (x0..x1).map(|xi| self.pinhole_ray(xi, yi, &self.sampler(xi, yi, k))).collect();
        ((y0..y1).map(run).collect(), (y - y0) as usize, (x - x0) as usize)
    }

    /// The sampler of sample `k` of pixel `(x, y)`.
    #[inline]
    fn sampler(&self, x: u32, y: u32, k: u32) -> PixelSampler {
        PixelSampler::new(self.pass.seed, y * self.integrator.settings.width + x, k, self.pass.planned)
    }

    /// The camera ray of sample `k` of pixel `(x, y)`, whose other numbers `sampler` draws:
    /// through the lens if there is one.
    #[inline]
    fn camera_ray(&self, x: u32, y: u32, k: u32, sampler: &PixelSampler) -> Ray {
        match self.lens {
            None => self.pinhole_ray(x, y, sampler),
            Some(lens) => {
                let pixel = y * self.integrator.settings.width + x;
                let u = PixelSampler::lens_offset(self.pass.seed, pixel, k, self.pass.planned);
                camera_ray(self.integrator.settings, self.camera, self.still, x, y, sampler, |g, x, y, j| {
                    lens.ray(g, x, y, j, u)
                })
            }
        }
    }

    /// The pinhole's camera ray of pixel `(x, y)` for the sample `sampler` draws (the packets'
    /// rays: [`Pass::packets`] holds only without a lens).
    #[inline(always)]
    fn pinhole_ray(&self, x: u32, y: u32, sampler: &PixelSampler) -> Ray {
        camera_ray(self.integrator.settings, self.camera, self.still, x, y, sampler, RayGenerator::ray)
    }

    /// [`Pass::pinhole_ray`] of the pixels `(x(i), y)` of a run, for the samples `samplers`
    /// draw: the same rays bit for bit, a still camera's made eight at a time
    /// ([`RayGenerator::rays8`]).
    #[inline(always)]
    fn pinhole_run(&self, x: impl Fn(usize) -> u32, y: u32, samplers: &[PixelSampler; PACKET]) -> [Ray; PACKET] {
        const { assert!(PACKET == 8, "a run's rays are made eight at a time") };
        let Some(generator) = self.still else {
            return std::array::from_fn(|i| self.pinhole_ray(x(i), y, &samplers[i]));
        };
        let settings = self.integrator.settings;
        let jitter = std::array::from_fn(|i| pixel_jitter(settings, &samplers[i]));
        let mut rays = generator.rays8(std::array::from_fn(x), [y; PACKET], jitter);
        for (ray, sampler) in rays.iter_mut().zip(samplers) {
            ray.time = sampler.time;
        }
        rays
    }

    /// Add the pass's samples to `run`, whose pixels are all at the same sample count, seen
    /// by a still camera: each sample's camera rays are traced as one packet, then each
    /// pixel's sample goes on as in [`Pass::sample_pixel`]. Where the scene allows
    /// ([`Integrator::shadows_ahead`]), the hits are seen first and their first shadow rays
    /// traced as packets too (and, [`Integrator::mirrors_ahead`], their mirror rays as an
    /// any-hit packet), then each pixel is shaded with the answers. The film gets the same
    /// values, bit for bit, as pixel by pixel.
    fn sample_run<A: PixelAccumulator>(&self, run: PixelRun<A>) -> Tally {
        let PixelRun { x0, y, sums, counts, residuals } = run;
        let n = sums.len();
        let mut total = Tally::default();
        let first = counts[0];
        let last = sample_range(first, self.pass);
        let x = |i: usize| x0 + i.min(n - 1) as u32;
        for k in first..last {
            // Two arrays built in place: an array of (sampler, ray) pairs split into them cost
            // a `memcpy` per packet.
            let samplers: [PixelSampler; PACKET] = std::array::from_fn(|i| self.sampler(x(i), y, k));
            let rays = self.pinhole_run(x, y, &samplers);
            let hits = self.integrator.scene.intersect_packet(&rays[..n]);
            let run = PixelRun { x0, y, sums: &mut *sums, counts: &mut *counts, residuals: &mut *residuals };
            self.shade_run(run, k, &samplers, &rays[..n], &hits, &mut total);
        }
        counts.fill(last);
        total
    }

    /// Add the pass's samples to the runs of a tile (`runs`, the runs of up to [`TILE_ROWS`]
    /// rows from row `y0`, the same columns from `x0`, every pixel at the same sample count),
    /// seen by a still camera: each sample's camera rays are traced as one tile
    /// ([`Scene::intersect_tile`]), then each run is shaded as [`Pass::sample_run`] shades
    /// it. The film gets the same values, bit for bit.
    fn sample_tile<A: PixelAccumulator>(
        &self,
        x0: u32,
        y0: u32,
        runs: &mut [Option<RunSlices<A>>; TILE_ROWS],
        residuals: &mut Vec<Residual>,
    ) -> Tally {
        let m = runs.iter().flatten().count();
        let n = runs[0].as_ref().map_or(0, |(sums, _)| sums.len());
        let mut total = Tally::default();
        let first = runs[0].as_ref().map_or(0, |(_, counts)| counts[0]);
        let last = sample_range(first, self.pass);
        let x = |i: usize| x0 + i.min(n - 1) as u32;
        let y = |r: usize| y0 + r.min(m - 1) as u32;
        for k in first..last {
            // The samplers a flat array, run after run, built in place (nested
            // `array::from_fn`s built each run's array apart and copied it in); the rays a
            // run's eight at a time.
            let samplers: [PixelSampler; PACKET * TILE_ROWS] =
                std::array::from_fn(|j| self.sampler(x(j % PACKET), y(j / PACKET), k));
            let (run_samplers, _) = samplers.as_chunks::<PACKET>();
            let rays: [[Ray; PACKET]; TILE_ROWS] = std::array::from_fn(|r| self.pinhole_run(x, y(r), &run_samplers[r]));
            let tile: [&[Ray]; TILE_ROWS] = std::array::from_fn(|r| &rays[r][..n]);
            let hits = self.integrator.scene.intersect_tile(&tile[..m]);
            for ((r, (sums, counts)), samplers) in runs.iter_mut().flatten().enumerate().zip(run_samplers) {
                let run = PixelRun { x0, y: y(r), sums, counts, residuals: &mut *residuals };
                self.shade_run(run, k, samplers, tile[r], &hits[r], &mut total);
            }
        }
        for (_, counts) in runs.iter_mut().flatten() {
            counts.fill(last);
        }
        total
    }

    /// Add sample `k` of each pixel of `run` to its sum, the camera rays `rays` (made with
    /// `samplers`) having found `hits`: each pixel's sample goes on as in
    /// [`Pass::sample_pixel`]. Where the scene allows ([`Integrator::shadows_ahead`]), the
    /// hits are seen first and their first shadow rays traced as packets too (and,
    /// [`Integrator::mirrors_ahead`], their mirror rays as an any-hit packet), then each
    /// pixel is shaded with the answers.
    #[inline(always)]
    fn shade_run<A: PixelAccumulator>(
        &self,
        run: PixelRun<A>,
        k: u32,
        samplers: &[PixelSampler; PACKET],
        rays: &[Ray],
        hits: &[Option<Hit>; PACKET],
        total: &mut Tally,
    ) {
        let PixelRun { x0, y, sums, residuals, .. } = run;
        let n = rays.len();
        let row = y * self.integrator.settings.width;
        let mut add = |i: usize, c: Color, rays: RayCounts| {
            let c = finite_or_black(c, &mut total.dropped);
            if k == 0 {
                sums[i].add_first(c);
            } else {
                sums[i].add(c, row + x0 + i as u32, residuals);
            }
            total.rays.add(rays);
        };
        let mut rec = NoRecorder;
        // Two loops over the lanes, one per way of shading: one loop choosing per lane
        // (`match` on the shadows traced ahead or not) rendered the Cornell box 2% and the
        // dragon 0.5% slower (BENCHMARKS.md, session 24).
        if self.shadows_ahead {
            // Filled in place (`array::from_fn` built the kilobyte apart and copied it).
            let mut seen = [None; PACKET];
            for (i, seen) in seen.iter_mut().enumerate().take(n) {
                *seen = self.integrator.seen(&rays[i], hits[i]);
            }
            let mut ahead = self.integrator.first_shadows(rays, &seen);
            if self.mirrors_ahead {
                self.integrator.first_mirrors(rays, &seen, &mut ahead);
            }
            for (i, sampler) in samplers.iter().cloned().enumerate().take(n) {
                let mut ctx = PathContext::new(sampler, &mut rec);
                let c = self.integrator.li_seen(&rays[i], seen[i].as_ref(), ahead[i], &mut ctx);
                add(i, c, ctx.counts);
            }
            return;
        }
        for (i, sampler) in samplers.iter().cloned().enumerate().take(n) {
            let mut ctx = PathContext::new(sampler, &mut rec);
            let c = self.integrator.li_hit(&rays[i], hits[i], RayKind::Camera, 0, &mut ctx);
            add(i, c, ctx.counts);
        }
    }

    /// Add the pass's samples to `run`, whose camera rays cannot hit anything (its tile was
    /// culled): each sample is `miss`, the colour every missing ray returns, added as a
    /// traced miss is (the same bits, the same ray counts), without making or tracing a ray.
    fn fill_missed<A: PixelAccumulator>(&self, run: PixelRun<A>, miss: Color) -> Tally {
        let camera_ray = RayCounts { primary_and_secondary: 1, shadow: 0 };
        // Checked once, not per sample: every sample adds what `finite_or_black` makes of
        // `miss`, and counts as dropped if `miss` was.
        let mut bad = 0;
        let miss = finite_or_black(miss, &mut bad);
        self.per_sample(run, |_, _, dropped| {
            *dropped += bad;
            (miss, camera_ray)
        })
    }

    /// Add the pass's samples to `run` one pixel and one sample at a time (pixels at
    /// different sample counts, or a moving camera).
    fn sample_alone<A: PixelAccumulator>(&self, run: PixelRun<A>) -> Tally {
        let y = run.y;
        self.per_sample(run, |x, k, dropped| {
            let (c, rays) = self.sample_pixel(x, y, k, &mut NoRecorder);
            (finite_or_black(c, dropped), rays)
        })
    }

    /// Add the pass's samples to `run` pixel by pixel, sample by sample, sample `k` of the
    /// pixel in column `x` being `sample(x, k, dropped)`: its colour, finite (it counts in
    /// `dropped` a sample it made black: [`finite_or_black`]), and the rays it cast.
    #[inline(always)]
    fn per_sample<A: PixelAccumulator>(
        &self,
        run: PixelRun<A>,
        mut sample: impl FnMut(u32, u32, &mut u64) -> (Color, RayCounts),
    ) -> Tally {
        let PixelRun { x0, y, sums, counts, residuals } = run;
        let mut total = Tally::default();
        let row = y * self.integrator.settings.width;
        for (x, (sum, count)) in (x0..).zip(sums.iter_mut().zip(counts.iter_mut())) {
            let last = sample_range(*count, self.pass);
            for k in *count..last {
                let (c, r) = sample(x, k, &mut total.dropped);
                sum.add(c, row + x, residuals);
                total.rays.add(r);
            }
            *count = last;
        }
        total
    }
}

/// Render `scene` with `settings` (all `spp` samples per pixel) on the current rayon pool,
/// calling `progress` as tiles finish.
pub fn render(scene: &Scene, settings: &RenderSettings, progress: &(dyn Fn(RenderProgress) + Sync)) -> RenderOutput {
    render_cancellable(scene, settings, &AtomicBool::new(false), progress)
}

/// [`render`] that stops early when `cancel` is set, keeping the tiles it finished (the
/// others stay black, with no samples).
pub fn render_cancellable(
    scene: &Scene,
    settings: &RenderSettings,
    cancel: &AtomicBool,
    progress: &(dyn Fn(RenderProgress) + Sync),
) -> RenderOutput {
    render_reusing(scene, settings, cancel, progress, None)
}

/// [`render_cancellable`] in the memory of `film`, an earlier render's, where one is given
/// (its samples are dropped first: [`Film::cleared`]); a new film otherwise. The same image,
/// bit for bit; renders one after another (`render --repeat`, an animation's frames, `rayscope
/// bench`) skip the page faults of a new film.
pub fn render_reusing(
    scene: &Scene,
    settings: &RenderSettings,
    cancel: &AtomicBool,
    progress: &(dyn Fn(RenderProgress) + Sync),
    film: Option<Film>,
) -> RenderOutput {
    let start = Instant::now();
    let (width, height) = (settings.width, settings.height);
    let mut film = film.map_or_else(|| Film::new(width, height), |film| film.cleared(width, height));
    let pass = SamplePass { samples: settings.spp, limit: settings.spp, planned: settings.spp, seed: settings.seed };
    let (rays, complete) = render_pass(scene, settings, &scene.camera_motion(), &mut film, pass, cancel, progress);
    RenderOutput { film, rays, elapsed: start.elapsed(), complete }
}

/// The shutter time of sample `k` of pixel `(x, y)` in [`render`] (with `planned =
/// settings.spp`): the time its camera ray, and every ray after it, carries.
pub fn sample_time(settings: &RenderSettings, x: u32, y: u32, k: u32) -> f32 {
    PixelSampler::new(settings.seed, y * settings.width + x, k, settings.spp).time
}

/// The sum [`render`] adds to pixel `(x, y)`'s film (with `settings`, through `camera`), as
/// the debugger's replay finds it: each of the `spp` samples traced alone by [`trace_pixel`],
/// summed exactly, as the film sums them. A render equals it bit for bit, however its rays
/// were grouped.
pub fn replay_pixel_sum(scene: &Scene, settings: &RenderSettings, camera: &CameraMotion, x: u32, y: u32) -> [f64; 3] {
    let mut sum: [ExactSum; 3] = Default::default();
    for k in 0..settings.spp {
        let c = trace_pixel(scene, settings, camera, x, y, k, &mut NoRecorder);
        for (e, v) in sum.iter_mut().zip(c.to_array()) {
            e.add(f64::from(v));
        }
    }
    sum.map(|e| e.to_f64())
}

/// Trace sample `k` of pixel `(x, y)` alone through `camera`, exactly as [`render`] does (with
/// `planned = settings.spp`), reporting every ray to `rec`. Returns the sample's colour.
pub fn trace_pixel<R: RayRecorder>(
    scene: &Scene,
    settings: &RenderSettings,
    camera: &CameraMotion,
    x: u32,
    y: u32,
    k: u32,
    rec: &mut R,
) -> Color {
    let pass = SamplePass { samples: 1, limit: u32::MAX, planned: settings.spp, seed: settings.seed };
    let at = PixelSample { x, y, k };
    match &scene.environment {
        None => trace_footprint(Integrator::new(scene, settings), camera, pass, at, rec),
        Some(env) => trace_footprint(Integrator::with_sky(scene, settings, env), camera, pass, at, rec),
    }
    .0
}

/// Sample `k` of pixel `(x, y)`.
#[derive(Clone, Copy)]
struct PixelSample {
    x: u32,
    y: u32,
    k: u32,
}

/// [`trace_pixel`] with `integrator`, whose rays carry cones when textures are filtered
/// trilinearly, as [`render_pass`] chooses.
fn trace_footprint<S: Sky, R: RayRecorder>(
    integrator: Integrator<S>,
    camera: &CameraMotion,
    pass: SamplePass,
    at: PixelSample,
    rec: &mut R,
) -> (Color, RayCounts) {
    let PixelSample { x, y, k } = at;
    if integrator.settings.texture_filter == TextureFilter::Trilinear {
        return Pass::new(&integrator.with_cones(&camera.start), camera, None, pass).sample_pixel(x, y, k, rec);
    }
    Pass::new(&integrator, camera, None, pass).sample_pixel(x, y, k, rec)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::environment::{Environment, EnvironmentDesc};
    use crate::material::Texture;
    use crate::scene::{LoadContext, builtin};
    use crate::settings::PixelFilter;

    /// A film's sums, sample counts and residuals, as bits.
    fn film_bits(film: &Film) -> (Vec<[u64; 3]>, Vec<u32>, usize) {
        (film.sums().map(|s| s.map(f64::to_bits)).collect(), film.counts().to_vec(), film.residuals().len())
    }

    /// Passes of `samples` each (the first on `f32` sums, the later ones on `f64`), culling
    /// tiles or not: the films and the ray counts.
    fn passes(scene: &Scene, settings: &RenderSettings, samples: &[u32], culling: CameraTrace) -> (Film, RayCounts) {
        let mut film = Film::new(settings.width, settings.height);
        let mut rays = RayCounts::default();
        let camera = scene.camera_motion();
        for &n in samples {
            let pass = SamplePass { samples: n, limit: u32::MAX, planned: 0, seed: settings.seed };
            let (r, complete) =
                pass_culling(scene, settings, &camera, &mut film, pass, culling, &AtomicBool::new(false), &|_| {});
            assert!(complete);
            rays.add(r);
        }
        (film, rays)
    }

    /// Tiles whose camera rays cannot hit anything, filled without tracing them, give the
    /// films (every sum, count and residual, bit for bit) and the ray counts of tracing every
    /// ray: one sample, then more on the `f64` sums, with each pixel filter (whose samples
    /// reach past the pixel), an image whose last tiles are cut by its edges, a sphere that
    /// moves during the exposure (seen by a still camera, whose tiles are culled by the
    /// sphere's swept box), and a scene with an environment map (which culls nothing).
    #[test]
    fn culled_tiles_render_as_traced_ones() {
        let load = |name| Scene::from_desc(&builtin::scene_desc(name).unwrap(), &LoadContext::default()).unwrap();
        let mut sky = load("spheres");
        let texels = (0..32).map(|i| Color::new(i as f32 / 32.0, 0.5, 1.0 - i as f32 / 64.0)).collect();
        let desc = EnvironmentDesc { path: "sky.exr".into(), intensity: 1.0, rotation: 30.0 };
        sky.environment = Some(Environment::from_texture(desc, Texture::new(8, 4, texels)).unwrap());
        let settings = RenderSettings::default();
        assert!(TileCulling::of(&sky, &settings, &sky.camera_motion()).is_none());
        let moving = load("cornell-box-motion");
        assert!(moving.camera_motion().is_still());
        let scenes = ["cornell-box", "spheres", "single-triangle", "shading-models"].map(|name| (name, load(name)));
        for (name, scene) in scenes.into_iter().chain([("cornell-box-motion", moving), ("spheres with a sky", sky)]) {
            for filter in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Gaussian] {
                let settings = RenderSettings { width: 77, height: 61, filter, ..RenderSettings::default() };
                let (traced, rays) = passes(&scene, &settings, &[1, 2], CameraTrace::Plain);
                let (culled, culled_rays) = passes(&scene, &settings, &[1, 2], CameraTrace::Fast);
                assert_eq!(film_bits(&culled), film_bits(&traced), "{name} {filter:?}");
                assert_eq!(culled_rays, rays, "{name} {filter:?}");
            }
        }
    }

    /// A folded surface of `2 n^2` triangles over `[-1, 1]^2` that shadows itself.
    fn folded_surface(n: u32) -> crate::scene::MeshDesc {
        use crate::math::Vec3;
        let height = |x: f32, z: f32| 0.4 * (4.0 * x).sin() * (3.0 * z).cos();
        let vertices = (0..=n)
            .flat_map(|i| (0..=n).map(move |j| (i, j)))
            .map(|(i, j)| {
                let (x, z) = (2.0 * i as f32 / n as f32 - 1.0, 2.0 * j as f32 / n as f32 - 1.0);
                Vec3::new(x, height(x, z), z)
            })
            .collect();
        let v = |i: u32, j: u32| i * (n + 1) + j;
        let faces = (0..n).flat_map(|i| {
            (0..n).flat_map(move |j| [[v(i, j), v(i + 1, j), v(i + 1, j + 1)], [v(i, j), v(i + 1, j + 1), v(i, j + 1)]])
        });
        crate::scene::MeshDesc { vertices: Some(vertices), faces: Some(faces.collect()), ..Default::default() }
    }

    /// Camera rays traced as tiles of packets give the films (every sum, count and residual,
    /// bit for bit) and the ray counts of tracing them packet by packet: a folded surface of
    /// 800 triangles (above [`TILE_PRIMS`]) in images whose last tiles are cut by the edges
    /// (fewer and shorter runs), one sample then more, with each pixel filter, with ray cones,
    /// and with shadows sampled (nothing traced ahead).
    #[test]
    fn tiles_render_as_packets() {
        use crate::scene::SceneDesc;
        let lights = vec![
            crate::light::Light::Point { position: crate::math::Vec3::new(1.5, 1.2, 0.5), color: Color::splat(0.6) },
            crate::light::Light::Sphere {
                center: crate::math::Vec3::new(0.0, 2.0, 0.0),
                radius: 0.3,
                color: Color::splat(0.3),
            },
        ];
        let desc = SceneDesc { meshes: vec![folded_surface(20)], lights, ..SceneDesc::default() };
        let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
        assert!(traces_camera_tiles(&scene));
        let base = RenderSettings { width: 45, height: 29, ..RenderSettings::default() };
        let variants = [
            base.clone(),
            RenderSettings { width: 64, height: 64, filter: PixelFilter::Tent, ..base.clone() },
            RenderSettings { filter: PixelFilter::Gaussian, texture_filter: TextureFilter::Trilinear, ..base.clone() },
            RenderSettings { light_samples: 3, ..base.clone() },
        ];
        for s in variants {
            let (packets, rays) = passes(&scene, &s, &[1, 2], CameraTrace::Plain);
            let (tiles, tile_rays) = passes(&scene, &s, &[1, 2], CameraTrace::Fast);
            assert_eq!(film_bits(&tiles), film_bits(&packets), "{s:?}");
            assert_eq!(tile_rays, rays, "{s:?}");
            let lit = packets.sums().filter(|sum| sum[1] > 0.0).count();
            assert!(rays.shadow > 0 && lit > packets.sums().len() / 8, "{s:?}: the surface is lit ({lit} pixels)");
        }
    }

    /// Camera packets whose hits trace their first shadow rays ahead, as packets, give each
    /// pixel what tracing it alone gives (the debugger's replay), bit for bit: a folded
    /// surface of 800 triangles that shadows itself, under two point lights and a sphere
    /// light shaded from its centre, by the Phong and Blinn-Phong models, with and without
    /// ray cones; with the sphere light sampled, nothing is traced ahead.
    #[test]
    fn shadows_traced_ahead_equal_shadows_traced_alone() {
        use crate::math::Vec3;
        use crate::scene::SceneDesc;
        use crate::settings::ShadingModel;
        let mesh = folded_surface(20);
        let lights = vec![
            crate::light::Light::Point { position: Vec3::new(1.5, 1.2, 0.5), color: Vec3::splat(0.6) },
            crate::light::Light::Point { position: Vec3::new(-1.0, 0.9, -1.5), color: Vec3::new(0.2, 0.3, 0.5) },
            crate::light::Light::Sphere { center: Vec3::new(0.0, 2.0, 0.0), radius: 0.3, color: Vec3::splat(0.3) },
        ];
        let desc = SceneDesc { meshes: vec![mesh], lights, ..SceneDesc::default() };
        let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
        assert!(scene.prim_count() >= crate::integrator::SHADOWS_AHEAD_PRIMS);
        let base = RenderSettings { width: 37, height: 29, light_samples: 0, ..RenderSettings::default() };
        let variants = [
            (base.clone(), true),
            (RenderSettings { shading_model: ShadingModel::BlinnPhong, ..base.clone() }, true),
            (RenderSettings { texture_filter: TextureFilter::Trilinear, spp: 2, ..base.clone() }, true),
            (RenderSettings { light_samples: 4, ..base.clone() }, false),
        ];
        let camera = scene.camera_motion();
        for (s, ahead) in variants {
            assert_eq!(Integrator::new(&scene, &s).shadows_ahead(), ahead, "{s:?}");
            let out = render(&scene, &s, &|_| {});
            let mut shadowed = 0;
            for y in 0..s.height {
                for x in 0..s.width {
                    let replayed = replay_pixel_sum(&scene, &s, &camera, x, y);
                    assert_eq!(out.film.sum(x, y), replayed, "pixel ({x}, {y}) of {s:?}");
                    shadowed += usize::from(out.film.sum(x, y)[2] < 0.05);
                }
            }
            assert!(shadowed > 10, "the surface shadows itself ({shadowed} dark pixels)");
        }
    }

    /// Camera packets whose hits trace their mirror rays ahead, as any-hit packets, give each
    /// pixel what tracing it alone gives (the debugger's replay), bit for bit: a folded
    /// surface, half of it a sharp mirror, whose mirror rays leave the scene or meet the
    /// surface or a ceiling over half of it, by the Phong model with and without ray cones,
    /// and with adaptive depth control stopping the reflections traced ahead; glossy
    /// reflections and a depth of 0 trace nothing ahead. The debugger records each mirror
    /// ray's walk as the render made it.
    #[test]
    fn mirrors_traced_ahead_equal_mirrors_traced_alone() {
        use crate::bvh::QueryKind;
        use crate::material::MaterialDesc;
        use crate::math::Vec3;
        use crate::record::RayTree;
        use crate::scene::SceneDesc;
        let mirror = MaterialDesc { ks: Some(Color::splat(0.5)), shininess: Some(20.0), ..MaterialDesc::default() };
        let mut mesh = folded_surface(20);
        mesh.materials = vec![mirror, MaterialDesc::default()];
        mesh.face_materials = (0..800).map(|f| u32::from(f % 2 == 1)).collect();
        // A ceiling over half of the surface, for the mirror rays to meet.
        let ceiling = crate::scene::MeshDesc {
            vertices: Some(vec![
                Vec3::new(-3.0, 1.6, -3.0),
                Vec3::new(0.0, 1.6, -3.0),
                Vec3::new(0.0, 1.6, 3.0),
                Vec3::new(-3.0, 1.6, 3.0),
            ]),
            faces: Some(vec![[0, 1, 2], [0, 2, 3]]),
            ..Default::default()
        };
        let lights = vec![crate::light::Light::Point { position: Vec3::new(1.5, 1.2, 0.5), color: Vec3::splat(0.8) }];
        let desc = SceneDesc { meshes: vec![mesh, ceiling], lights, ..SceneDesc::default() };
        let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
        let base = RenderSettings { width: 37, height: 29, light_samples: 0, ..RenderSettings::default() };
        let variants = [
            (base.clone(), true),
            (RenderSettings { texture_filter: TextureFilter::Trilinear, spp: 2, ..base.clone() }, true),
            (RenderSettings { adc_bailout: 0.6, ..base.clone() }, true),
            (RenderSettings { gloss_samples: 4, ..base.clone() }, false),
            (RenderSettings { max_depth: 0, ..base.clone() }, false),
        ];
        let camera = scene.camera_motion();
        for (s, ahead) in variants {
            assert_eq!(Integrator::new(&scene, &s).mirrors_ahead(), ahead, "{s:?}");
            let out = render(&scene, &s, &|_| {});
            for y in 0..s.height {
                for x in 0..s.width {
                    let replayed = replay_pixel_sum(&scene, &s, &camera, x, y);
                    assert_eq!(out.film.sum(x, y), replayed, "pixel ({x}, {y}) of {s:?}");
                }
            }
        }
        // The base render's mirror rays both leave the scene and meet something; the debugger
        // records the render's walk of each: the any-hit walk of one that leaves the scene,
        // the closest-hit walk after it of one that meets it.
        let (mut left, mut met) = (0, 0);
        for y in 0..base.height {
            for x in 0..base.width {
                let mut tree = RayTree::default();
                trace_pixel(&scene, &base, &camera, x, y, 0, &mut tree);
                for ray in tree.rays.iter().filter(|r| r.kind == RayKind::Reflection && r.depth == 1) {
                    let walk = ray.traversal.as_ref().map(|t| t.query);
                    let want = if ray.hit.is_some() { QueryKind::ClosestHit } else { QueryKind::AnyHit };
                    assert_eq!(walk, Some(want), "the mirror ray of pixel ({x}, {y})");
                    *if ray.hit.is_some() { &mut met } else { &mut left } += 1;
                }
            }
        }
        assert!(left > 50 && met > 50, "mirror rays: {left} leave, {met} meet something");
    }

    /// A render into an earlier render's film equals a render into a new film, bit for bit
    /// (sums, counts, residuals, dropped samples): after a one-sample film of the same size
    /// (reused in place), after a cancelled one (half filled), after a film of `f64` sums and
    /// after one of another size (both replaced by a new film).
    #[test]
    fn reused_films_render_as_new_ones() {
        let scene = Scene::from_desc(&builtin::scene_desc("cornell-box").unwrap(), &LoadContext::default()).unwrap();
        let settings = RenderSettings { width: 61, height: 47, ..RenderSettings::default() };
        let fresh = render(&scene, &settings, &|_| {}).film;
        let stopped = AtomicBool::new(false);
        let stop_midway = |p: RenderProgress| stopped.store(p.done * 2 >= p.total, Ordering::Relaxed);
        let cancelled = render_cancellable(&scene, &settings, &stopped, &stop_midway);
        assert!(!cancelled.complete);
        let earlier = [
            ("one sample", render(&scene, &settings, &|_| {}).film),
            ("cancelled", cancelled.film),
            ("four samples", render(&scene, &RenderSettings { spp: 4, ..settings.clone() }, &|_| {}).film),
            ("another size", render(&scene, &RenderSettings { width: 20, ..settings.clone() }, &|_| {}).film),
        ];
        for (name, film) in earlier {
            let out = render_reusing(&scene, &settings, &AtomicBool::new(false), &|_| {}, Some(film));
            assert!(out.complete, "{name}");
            assert_eq!(film_bits(&out.film), film_bits(&fresh), "{name}");
            assert!(out.film == fresh, "{name}");
        }
    }

    /// A reused film's old sums, left by its clear to the next pass's bands, are gone
    /// after a pass cancelled midway: the pixels the pass rendered hold what a fresh render
    /// gives them, the others no samples and zero sums (zeroed by the bands the pass skipped).
    #[test]
    fn cancelled_renders_leave_no_old_sums_in_reused_films() {
        let scene = Scene::from_desc(&builtin::scene_desc("cornell-box").unwrap(), &LoadContext::default()).unwrap();
        let settings = RenderSettings { width: 61, height: 47, ..RenderSettings::default() };
        let fresh = render(&scene, &settings, &|_| {}).film;
        let earlier = render(&scene, &settings, &|_| {}).film;
        let stopped = AtomicBool::new(false);
        let stop_midway = |p: RenderProgress| stopped.store(p.done * 2 >= p.total, Ordering::Relaxed);
        let out = render_reusing(&scene, &settings, &stopped, &stop_midway, Some(earlier));
        assert!(!out.complete);
        let counts = out.film.counts();
        assert!(counts.contains(&0) && counts.contains(&1));
        let fresh_sums: Vec<_> = fresh.sums().collect();
        for (i, (sum, n)) in out.film.sums().zip(counts).enumerate() {
            let expected = if *n == 0 { [0.0; 3] } else { fresh_sums[i] };
            assert_eq!(sum.map(f64::to_bits), expected.map(f64::to_bits), "pixel {i}, {n} samples");
        }
    }

    /// The culling is not idle: most tiles of the course's Cornell box at its default size,
    /// seen from outside, hold only background, and are culled; a tile the box fills is not.
    #[test]
    fn background_tiles_are_culled() {
        let scene = Scene::from_desc(&builtin::scene_desc("cornell-box").unwrap(), &LoadContext::default()).unwrap();
        let settings = RenderSettings::default();
        let integrator = Integrator::new(&scene, &settings);
        let camera = scene.camera_motion();
        let still = RayGenerator::new(&camera.start, settings.width, settings.height);
        let pass = SamplePass { samples: 1, limit: 1, planned: 1, seed: 0 };
        let setup = Pass::new(&integrator, &camera, Some(&still), pass);
        assert!(setup.cull.is_some());
        let h = settings.height as usize;
        let culled: Vec<bool> =
            (0..h).step_by(BAND_ROWS).flat_map(|y0| setup.culled_tiles(y0, BAND_ROWS.min(h - y0))).collect();
        let share = culled.iter().filter(|c| **c).count() as f64 / culled.len() as f64;
        assert!(share > 0.5, "{share}");
        let culling = TileCulling::of(&scene, &settings, &camera).unwrap();
        // 8 x 8 tiles, none cut at 800 x 800.
        assert_eq!(culling.culled_pixels(), 64 * culled.iter().filter(|c| **c).count() as u64);
        let centre = culling.tile(settings.width / 2, settings.height / 2);
        assert_eq!(centre, Tile { x: [400, 408], y: [400, 408] });
        assert!(culling.test(centre).may_hit);
        let corner = culling.tile(799, 799);
        assert!(!culling.test(corner).may_hit && culling.test(corner).nodes >= 1);
        // An image's last tiles are cut by its edges.
        let small = RenderSettings { width: 77, height: 61, ..settings.clone() };
        let cut = TileCulling::of(&scene, &small, &camera).unwrap().tile(76, 60);
        assert_eq!((cut, cut.pixels()), (Tile { x: [72, 77], y: [56, 61] }, 25));
        // An environment map or a lens turns the culling off.
        let lens = RenderSettings { aperture: 0.1, ..settings.clone() };
        assert!(TileCulling::of(&scene, &lens, &camera).is_none());
    }
}
