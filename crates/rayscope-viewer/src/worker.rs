//! The render worker: a thread that runs the library's progressive renderer on its own rayon
//! pool, one frame at a time, and hands finished frames to the UI. The UI never waits on it:
//! it submits jobs (scene, settings, camera, mode) and takes the latest frame when one is ready.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use rayscope::aov::{Aov, render_aov};
use rayscope::camera::CameraMotion;
use rayscope::film::FloatImage;
use rayscope::output::{Encoding, to_rgb8};
use rayscope::progressive::{ImagingMode, Progressive};
use rayscope::render::TileCulling;
use rayscope::scene::Scene;
use rayscope::settings::RenderSettings;

use crate::heat::HeatScale;
use crate::mip::MipScale;

/// What to render.
#[derive(Clone)]
pub struct RenderJob {
    /// The scene.
    pub scene: Arc<Scene>,
    /// Settings (`spp` is samples per frame).
    pub settings: RenderSettings,
    /// How frames combine.
    pub mode: ImagingMode,
    /// The camera for the next frames.
    pub camera: CameraMotion,
    /// Render a false-colour view (the BVH heat map, the mip levels) instead of the image.
    pub false_colour: Option<FalseColour>,
    /// Dynamic mode stops accumulating at this many samples per pixel.
    pub max_spp: u32,
    /// Which of bloom's layers the frames show.
    pub bloom_layer: crate::bloom::BloomLayer,
    /// Bumped by the UI whenever the accumulation must restart (new scene, settings, mode,
    /// or a new exposure). Camera changes alone do not bump it: the imaging mode decides
    /// whether they restart (dynamic) or blur (exposure).
    pub generation: u64,
}

/// A finished frame, ready for display.
#[derive(Clone, Debug)]
pub struct FrameImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA, 8 bits per channel, rows from the top.
    pub rgba: Vec<u8>,
    /// The float image (for saving to a file).
    pub image: FloatImage,
    /// Frames accumulated.
    pub frames: u32,
    /// Samples per pixel accumulated.
    pub spp: u32,
    /// Throughput of the last frame.
    pub mrays_per_s: f64,
    /// The job generation it belongs to.
    pub generation: u64,
    /// Whether accumulation has finished (the worker idles until the next job).
    pub done: bool,
    /// For a heat map, its scale and what it measured.
    pub heat: Option<HeatScale>,
    /// For the mip-level view, its scale and what it measured.
    pub mips: Option<MipScale>,
}

/// The false-colour views, each one frame of facts per pixel rather than an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FalseColour {
    /// BVH node boxes tested per camera ray.
    HeatMap,
    /// The mip level trilinear filtering reads.
    MipLevels,
}

struct Shared {
    job: Mutex<Option<RenderJob>>,
    wake: Condvar,
    cancel: AtomicBool,
    quit: AtomicBool,
    latest: Mutex<Option<FrameImage>>,
    frames_posted: AtomicU64,
}

/// The worker thread and its mailbox.
pub struct Worker {
    shared: Arc<Shared>,
    handle: Option<JoinHandle<()>>,
}

impl Worker {
    /// Start the worker; `repaint` is called (from the worker thread) after every frame.
    pub fn new(repaint: impl Fn() + Send + Sync + 'static) -> Worker {
        let shared = Arc::new(Shared {
            job: Mutex::new(None),
            wake: Condvar::new(),
            cancel: AtomicBool::new(false),
            quit: AtomicBool::new(false),
            latest: Mutex::new(None),
            frames_posted: AtomicU64::new(0),
        });
        let s = shared.clone();
        let handle = std::thread::Builder::new()
            .name("rayscope-render".into())
            .spawn(move || run(&s, &repaint))
            .expect("the render thread starts");
        Worker { shared, handle: Some(handle) }
    }

    /// Replace the job. A frame in flight is cut short when the accumulation must restart.
    pub fn submit(&self, job: RenderJob) {
        let mut slot = self.shared.job.lock().unwrap();
        let restart = slot.as_ref().is_some_and(|j| {
            j.generation != job.generation
                || j.false_colour != job.false_colour
                || (j.camera != job.camera && !matches!(job.mode, ImagingMode::Exposure { .. }))
        });
        if restart {
            self.shared.cancel.store(true, Ordering::Relaxed);
        }
        *slot = Some(job);
        self.shared.wake.notify_all();
    }

    /// The newest finished frame, if one arrived since the last call.
    pub fn take_frame(&self) -> Option<FrameImage> {
        self.shared.latest.lock().unwrap().take()
    }

    /// Frames posted since the worker started.
    pub fn frames_posted(&self) -> u64 {
        self.shared.frames_posted.load(Ordering::Relaxed)
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.shared.quit.store(true, Ordering::Relaxed);
        self.shared.cancel.store(true, Ordering::Relaxed);
        self.shared.wake.notify_all();
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

fn to_frame(image: FloatImage, frames: u32, spp: u32, mrays_per_s: f64, generation: u64, done: bool) -> FrameImage {
    let rgb = to_rgb8(&image, Encoding::Linear);
    let rgba = rgb.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect();
    let (width, height) = (image.width, image.height);
    FrameImage { width, height, rgba, image, frames, spp, mrays_per_s, generation, done, heat: None, mips: None }
}

/// The heat map of `job`'s camera: one frame, complete (the traversal is deterministic, so
/// another frame would be the same image).
fn heat_frame(job: &RenderJob, pool: &rayon::ThreadPool) -> FrameImage {
    let start = Instant::now();
    let aov = pool.install(|| render_aov(&job.scene, &job.settings, &job.camera.start, Aov::NodesVisited, &|_| {}));
    let millis = start.elapsed().as_secs_f64() * 1e3;
    let wide = &job.scene.geometry.wide;
    let culled = TileCulling::of(&job.scene, &job.settings, &CameraMotion::still(job.camera.start))
        .map_or(0, |c| c.culled_pixels());
    let scale = HeatScale::of(&aov, wide.width(), wide.node_count(), culled, millis);
    let frame = to_frame(scale.image(&aov), 1, 1, scale.mrays_per_s(), job.generation, true);
    FrameImage { heat: Some(scale), ..frame }
}

/// The mip-level view of `job`'s camera: one frame, complete (sample 0 of every pixel).
fn mip_frame(job: &RenderJob, pool: &rayon::ThreadPool) -> FrameImage {
    let start = Instant::now();
    let aov = pool.install(|| render_aov(&job.scene, &job.settings, &job.camera.start, Aov::MipLevel, &|_| {}));
    let millis = start.elapsed().as_secs_f64() * 1e3;
    let top = job.scene.textures.iter().map(|t| t.top_level()).max().unwrap_or(0);
    let scale = MipScale::of(&aov, top, millis);
    let frame = to_frame(scale.image(&aov), 1, 1, 0.0, job.generation, true);
    FrameImage { mips: Some(scale), ..frame }
}

fn run(shared: &Shared, repaint: &(dyn Fn() + Send + Sync)) {
    // Leave a core for the UI, so it stays smooth while the tracer works.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get().saturating_sub(1).max(1));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a rayon pool");
    let mut progressive: Option<(Progressive, u64, usize)> = None;
    // The job the worker finished, and idles on until a job differs from it.
    let mut finished: Option<RenderJob> = None;
    loop {
        let job = {
            let mut slot = shared.job.lock().unwrap();
            loop {
                if shared.quit.load(Ordering::Relaxed) {
                    return;
                }
                let idle = match (&*slot, &finished) {
                    (None, _) => true,
                    // Done with this job; a camera move asks for more, except after an
                    // exposure, whose image stands until the next one.
                    (Some(j), Some(f)) => {
                        j.generation == f.generation
                            && j.false_colour == f.false_colour
                            && (j.camera == f.camera || matches!(j.mode, ImagingMode::Exposure { .. }))
                    }
                    _ => false,
                };
                if !idle {
                    break;
                }
                slot = shared.wake.wait(slot).unwrap();
            }
            shared.cancel.store(false, Ordering::Relaxed);
            slot.clone().expect("a job")
        };
        finished = None;
        if let Some(view) = job.false_colour {
            let frame = match view {
                FalseColour::HeatMap => heat_frame(&job, &pool),
                FalseColour::MipLevels => mip_frame(&job, &pool),
            };
            post(shared, frame, repaint);
            finished = Some(job);
            continue;
        }
        let key = Arc::as_ptr(&job.scene) as usize;
        let fresh = !matches!(&progressive, Some((_, g, k)) if *g == job.generation && *k == key);
        if fresh {
            progressive = Some((Progressive::new(job.settings.clone(), job.mode, None), job.generation, key));
        }
        let (prog, _, _) = progressive.as_mut().expect("set above");
        let info = pool.install(|| prog.render_frame(&job.scene, &job.camera, &shared.cancel, &|_| {}));
        if !info.complete {
            // Cut short by a new job: its film is about to be replaced.
            continue;
        }
        let done = prog.is_done() || (job.mode == ImagingMode::Dynamic && info.samples_per_pixel >= job.max_spp);
        let (saved, shown) = crate::bloom::frame_images(prog.film().to_image(), &job.settings.bloom, job.bloom_layer);
        let frame = to_frame(shown, info.frame, info.samples_per_pixel, info.mrays_per_second(), job.generation, done);
        post(shared, FrameImage { image: saved, ..frame }, repaint);
        if done {
            finished = Some(job);
        }
    }
}

fn post(shared: &Shared, frame: FrameImage, repaint: &(dyn Fn() + Send + Sync)) {
    *shared.latest.lock().unwrap() = Some(frame);
    shared.frames_posted.fetch_add(1, Ordering::Relaxed);
    repaint();
}
