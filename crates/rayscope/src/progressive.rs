//! Progressive rendering: frames of samples accumulated into a film, shared by the CLI and the
//! viewer. It serves the course's three imaging modes.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::camera::CameraMotion;
use crate::film::Film;
use crate::render::{RayCounts, RenderProgress, SamplePass, render_pass};
use crate::sampler::hash;
use crate::scene::Scene;
use crate::settings::RenderSettings;

/// How frames combine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImagingMode {
    /// Each frame is rendered afresh with its own anti-aliasing samples (a new seed per frame)
    /// and replaces the last.
    Continuous,
    /// Frames accumulate into a running average, which restarts when a setting or the camera
    /// changes.
    Dynamic,
    /// Accumulate exactly `frames` frames, then stop; camera moves during the exposure are
    /// kept, blurring the image (the course's motion blur).
    Exposure {
        /// Frames in the exposure.
        frames: u32,
    },
}

/// What one frame did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameInfo {
    /// Frames rendered since the last reset (this one included).
    pub frame: u32,
    /// Samples per pixel now in the film (the least any pixel has).
    pub samples_per_pixel: u32,
    /// Rays this frame cast.
    pub rays: RayCounts,
    /// Time this frame took.
    pub elapsed: Duration,
    /// False when a cancel request cut the frame short.
    pub complete: bool,
}

impl FrameInfo {
    /// Millions of rays per second in this frame.
    pub fn mrays_per_second(&self) -> f64 {
        self.rays.total() as f64 / self.elapsed.as_secs_f64().max(1e-9) / 1e6
    }
}

/// A progressive render: call [`Progressive::render_frame`] repeatedly; read
/// [`Progressive::film`] between frames.
#[derive(Clone, Debug)]
pub struct Progressive {
    settings: RenderSettings,
    mode: ImagingMode,
    target_spp: Option<u32>,
    film: Film,
    frame: u32,
    last_camera: Option<CameraMotion>,
}

impl Progressive {
    /// A progressive render; each frame adds `settings.spp` samples per pixel. `target_spp`,
    /// if known, is the total the film will reach: it lets the sampler stratify over it (so
    /// the finished film equals a one-shot render of that many samples, bit for bit) and ends
    /// the render there.
    pub fn new(settings: RenderSettings, mode: ImagingMode, target_spp: Option<u32>) -> Progressive {
        let film = Film::new(settings.width, settings.height);
        Progressive { settings, mode, target_spp, film, frame: 0, last_camera: None }
    }

    /// The current settings.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// The imaging mode.
    pub fn mode(&self) -> ImagingMode {
        self.mode
    }

    /// Change the settings; any change restarts the accumulation.
    pub fn set_settings(&mut self, settings: RenderSettings) {
        if settings != self.settings {
            self.film = Film::new(settings.width, settings.height);
            self.settings = settings;
            self.reset();
        }
    }

    /// Change the mode; restarts the accumulation.
    pub fn set_mode(&mut self, mode: ImagingMode) {
        self.mode = mode;
        self.reset();
    }

    /// Forget all samples.
    pub fn reset(&mut self) {
        self.film.clear();
        self.frame = 0;
        self.last_camera = None;
    }

    /// The accumulated image.
    pub fn film(&self) -> &Film {
        &self.film
    }

    /// Continue from `film` (a checkpoint's, of these settings), as if its `frames` frames
    /// had been rendered here: the render goes on to the same bits as one never stopped (the
    /// film's sums are exact). Returns false, changing nothing, if the film's size is not the
    /// settings'.
    pub fn restore(&mut self, film: Film, frames: u32) -> bool {
        if (film.width(), film.height()) != (self.settings.width, self.settings.height) {
            return false;
        }
        self.film = film;
        self.frame = frames;
        self.last_camera = None;
        true
    }

    /// Frames since the last reset.
    pub fn frames(&self) -> u32 {
        self.frame
    }

    /// Whether the render has reached its end: the target sample count, or the exposure's
    /// frames. Continuous and open-ended dynamic renders never end by themselves.
    pub fn is_done(&self) -> bool {
        match self.mode {
            ImagingMode::Exposure { frames } => self.frame >= frames,
            _ => self.target_spp.is_some_and(|t| self.film.sample_range().0 >= t),
        }
    }

    /// Render one more frame seen through `camera`; stops early (keeping finished tiles) when
    /// `cancel` is set.
    pub fn render_frame(
        &mut self,
        scene: &Scene,
        camera: &CameraMotion,
        cancel: &AtomicBool,
        progress: &(dyn Fn(RenderProgress) + Sync),
    ) -> FrameInfo {
        let start = Instant::now();
        if self.mode == ImagingMode::Dynamic && self.last_camera.as_ref().is_some_and(|c| c != camera) {
            self.reset();
        }
        let s = &self.settings;
        let samples = s.spp;
        let pass = match self.mode {
            ImagingMode::Continuous => {
                self.film.clear();
                let seed = hash(&[s.seed, self.frame as u64]);
                SamplePass { samples, limit: samples, planned: s.spp, seed }
            }
            ImagingMode::Dynamic => {
                let limit = self.target_spp.unwrap_or(u32::MAX);
                SamplePass { samples, limit, planned: self.target_spp.unwrap_or(0), seed: s.seed }
            }
            ImagingMode::Exposure { frames } => {
                let total = frames.saturating_mul(s.spp);
                SamplePass { samples, limit: total, planned: total, seed: s.seed }
            }
        };
        self.last_camera = Some(camera.clone());
        let (rays, complete) = render_pass(scene, &self.settings, camera, &mut self.film, pass, cancel, progress);
        self.frame += 1;
        FrameInfo {
            frame: self.frame,
            samples_per_pixel: self.film.sample_range().0,
            rays,
            elapsed: start.elapsed(),
            complete,
        }
    }

    /// Render frames until the render is done ([`Progressive::is_done`]), `time_limit` has
    /// passed (checked between frames, after the first), `cancel` is set, or `on_frame` breaks. `on_frame` sees
    /// the film after every frame: the CLI's progress bar and the viewer's display both hang
    /// here. Returns the rays cast.
    pub fn run(
        &mut self,
        scene: &Scene,
        camera: &CameraMotion,
        time_limit: Option<Duration>,
        cancel: &AtomicBool,
        mut on_frame: impl FnMut(&Film, &FrameInfo) -> ControlFlow<()>,
    ) -> RayCounts {
        let start = Instant::now();
        let mut rays = RayCounts::default();
        let mut frames = 0;
        while !self.is_done() && !cancel.load(Ordering::Relaxed) {
            // At least one frame, however short the limit: a limit of 0 wrote an all-black
            // image that looked like a render.
            if frames > 0 && time_limit.is_some_and(|t| start.elapsed() >= t) {
                break;
            }
            let info = self.render_frame(scene, camera, cancel, &|_| {});
            frames += 1;
            rays.add(info.rays);
            if on_frame(&self.film, &info).is_break() {
                break;
            }
        }
        rays
    }
}
