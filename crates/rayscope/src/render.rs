//! Rendering an image: the parallel loop over bands of rows that adds samples to a film, and
//! single-sample tracing for the debugger (the same code path). The AOVs are in
//! [`crate::aov`].

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::bvh::PACKET;
use crate::camera::{CameraMotion, RayGenerator};
use crate::cone::Footprint;
use crate::film::{Film, FilmSlices, PassSlices, PixelAccumulator, Residual, finite_or_black};
use crate::integrator::{Integrator, PathContext};
use crate::lens::ThinLens;
use crate::math::{Color, Vec2};
use crate::ray::Ray;
use crate::record::{NoRecorder, RayKind, RayRecorder};
use crate::sampler::PixelSampler;
use crate::scene::Scene;
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
    match &scene.environment {
        None => pass_footprint(Integrator::new(scene, settings), camera, film, pass, cancel, progress),
        Some(env) => pass_footprint(Integrator::with_sky(scene, settings, env), camera, film, pass, cancel, progress),
    }
}

/// [`render_pass`] with `integrator`, whose rays carry cones when textures are filtered
/// trilinearly (chosen here, once: other filters run code with no footprint in it).
fn pass_footprint<S: Sky>(
    integrator: Integrator<S>,
    camera: &CameraMotion,
    film: &mut Film,
    pass: SamplePass,
    cancel: &AtomicBool,
    progress: &(dyn Fn(RenderProgress) + Sync),
) -> (RayCounts, bool) {
    if integrator.settings.texture_filter == TextureFilter::Trilinear {
        return pass_with(&integrator.with_cones(&camera.start), camera, film, pass, cancel, progress);
    }
    pass_with(&integrator, camera, film, pass, cancel, progress)
}

/// [`render_pass`] with `integrator`.
fn pass_with<S: Sky, C: Footprint>(
    integrator: &Integrator<S, C>,
    camera: &CameraMotion,
    film: &mut Film,
    pass: SamplePass,
    cancel: &AtomicBool,
    progress: &(dyn Fn(RenderProgress) + Sync),
) -> (RayCounts, bool) {
    let settings = integrator.settings;
    let still = camera.is_still().then(|| RayGenerator::new(&camera.start, settings.width, settings.height));
    let setup = Pass::new(integrator, camera, still.as_ref(), pass);
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

/// Rows per task in [`render_pass`]: enough work per task to amortise scheduling, few enough
/// tasks' worth of rows (50 for 800) to balance two or more threads.
const BAND_ROWS: usize = 16;

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
    let jitter = Vec2::splat(0.5) + settings.filter.warp(sampler.pixel_offset);
    let time = sampler.time;
    let mut ray = match still {
        Some(rays) => through(rays, x, y, jitter),
        None => through(&RayGenerator::new(&camera.at(time), settings.width, settings.height), x, y, jitter),
    };
    ray.time = time;
    ray
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

impl<'a, S: Sky, C: Footprint> Pass<'a, S, C> {
    /// Add the pass's samples to every pixel of `film`: bands of whole rows, rendered in
    /// place (each task owns its slice of the film, so there is no intermediate buffer to
    /// fill and copy; every pixel's value depends only on the pixel, so the split does not
    /// change the image). Tiles not started when `cancel` is set are skipped.
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
                if cancel.load(Ordering::Relaxed) {
                    return Band { tally: Tally::default(), residuals: Vec::new(), complete: false };
                }
                let mut tally = Tally::default();
                let mut residuals = Vec::new();
                let rows = sums.chunks_mut(w).zip(counts.chunks_mut(w));
                for (row, (sums, counts)) in rows.enumerate() {
                    let y = (b * BAND_ROWS + row) as u32;
                    let runs = sums.chunks_mut(PACKET).zip(counts.chunks_mut(PACKET));
                    for (run, (sums, counts)) in runs.enumerate() {
                        let pixels = PixelRun { x0: (run * PACKET) as u32, y, sums, counts, residuals: &mut residuals };
                        // Pixels side by side that are at the same sample, seen by a still
                        // camera: their camera rays share the pinhole and go through the BVH
                        // together.
                        let same = pixels.counts.iter().all(|c| *c == pixels.counts[0]);
                        tally.add(if self.packets && same {
                            self.sample_run(pixels)
                        } else {
                            self.sample_alone(pixels)
                        });
                    }
                }
                let d = done.fetch_add(sums.len(), Ordering::Relaxed) + sums.len();
                progress(RenderProgress { done: d, total });
                Band { tally, residuals, complete: true }
            })
            .collect()
    }

    fn new(
        integrator: &'a Integrator<'a, S, C>,
        camera: &'a CameraMotion,
        still: Option<&'a RayGenerator>,
        pass: SamplePass,
    ) -> Pass<'a, S, C> {
        // The lens of the pose at shutter open: a moving camera keeps its focus distance.
        let lens = ThinLens::new(integrator.settings, &camera.start);
        Pass { integrator, camera, still, lens, packets: camera.is_still() && lens.is_none(), pass }
    }

    /// Trace sample `k` of pixel `(x, y)`: the one function every image, and the debugger,
    /// uses (or [`Pass::sample_run`], which differs only in finding the camera rays' hits as
    /// a packet).
    fn sample_pixel<R: RayRecorder>(&self, x: u32, y: u32, k: u32, rec: &mut R) -> (Color, RayCounts) {
        let sampler = self.sampler(x, y, k);
        let ray = self.camera_ray(x, y, k, &sampler);
        if R::RECORDS && self.packets {
            // A still camera's rays go through the BVH in packets (`sample_run`): the recorder
            // is told what the packet of this pixel's run entered for its ray.
            let (rays, lane) = self.camera_run(x, y, k);
            let mut ctx = PathContext::new(sampler, rec);
            let c = self.integrator.li_in_packet(&rays, lane, &mut ctx);
            return (c, ctx.counts);
        }
        let mut ctx = PathContext::new(sampler, rec);
        let c = self.integrator.li(&ray, RayKind::Camera, 0, &mut ctx);
        (c, ctx.counts)
    }

    /// The camera rays of sample `k` of the run of pixels [`render_pass`] traces pixel
    /// `(x, y)` in (the [`PACKET`] pixels of row `y` from a multiple of [`PACKET`], fewer at
    /// the row's end), and the pixel's place in it.
    fn camera_run(&self, x: u32, y: u32, k: u32) -> (Vec<Ray>, usize) {
        let x0 = x - x % PACKET as u32;
        let x1 = (x0 + PACKET as u32).min(self.integrator.settings.width);
        let rays = (x0..x1).map(|xi| self.pinhole_ray(xi, y, &self.sampler(xi, y, k))).collect();
        (rays, (x - x0) as usize)
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

    /// Add the pass's samples to `run`, whose pixels are all at the same sample count, seen
    /// by a still camera: each sample's camera rays are traced as one packet, then each
    /// pixel's sample goes on as in [`Pass::sample_pixel`]. The film gets the same values, bit
    /// for bit, as pixel by pixel.
    fn sample_run<A: PixelAccumulator>(&self, run: PixelRun<A>) -> Tally {
        let PixelRun { x0, y, sums, counts, residuals } = run;
        let n = sums.len();
        let row = y * self.integrator.settings.width;
        let mut total = Tally::default();
        let first = counts[0];
        let last = sample_range(first, self.pass);
        let x = |i: usize| x0 + i.min(n - 1) as u32;
        for k in first..last {
            // Two arrays built in place: an array of (sampler, ray) pairs split into them cost
            // a `memcpy` per packet.
            let samplers: [PixelSampler; PACKET] = std::array::from_fn(|i| self.sampler(x(i), y, k));
            let rays: [Ray; PACKET] = std::array::from_fn(|i| self.pinhole_ray(x(i), y, &samplers[i]));
            let hits = self.integrator.scene.intersect_packet(&rays[..n]);
            let mut rec = NoRecorder;
            for (i, sampler) in samplers.into_iter().enumerate().take(n) {
                let mut ctx = PathContext::new(sampler, &mut rec);
                let c = self.integrator.li_hit(&rays[i], hits[i], RayKind::Camera, 0, &mut ctx);
                let c = finite_or_black(c, &mut total.dropped);
                if k == 0 {
                    sums[i].add_first(c);
                } else {
                    sums[i].add(c, row + x0 + i as u32, residuals);
                }
                total.rays.add(ctx.counts);
            }
        }
        counts.fill(last);
        total
    }

    /// Add the pass's samples to `run` one pixel and one sample at a time (pixels at
    /// different sample counts, or a moving camera).
    fn sample_alone<A: PixelAccumulator>(&self, run: PixelRun<A>) -> Tally {
        let PixelRun { x0, y, sums, counts, residuals } = run;
        let mut total = Tally::default();
        let row = y * self.integrator.settings.width;
        for (x, (sum, count)) in (x0..).zip(sums.iter_mut().zip(counts.iter_mut())) {
            let last = sample_range(*count, self.pass);
            for k in *count..last {
                let (c, r) = self.sample_pixel(x, y, k, &mut NoRecorder);
                sum.add(finite_or_black(c, &mut total.dropped), row + x, residuals);
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
    let start = Instant::now();
    let mut film = Film::new(settings.width, settings.height);
    let pass = SamplePass { samples: settings.spp, limit: settings.spp, planned: settings.spp, seed: settings.seed };
    let (rays, complete) = render_pass(scene, settings, &scene.camera_motion(), &mut film, pass, cancel, progress);
    RenderOutput { film, rays, elapsed: start.elapsed(), complete }
}

/// The shutter time of sample `k` of pixel `(x, y)` in [`render`] (with `planned =
/// settings.spp`): the time its camera ray, and every ray after it, carries.
pub fn sample_time(settings: &RenderSettings, x: u32, y: u32, k: u32) -> f32 {
    PixelSampler::new(settings.seed, y * settings.width + x, k, settings.spp).time
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
