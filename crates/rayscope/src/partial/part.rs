//! Parts of a render: part `K` of `N` renders some samples of every pixel (`--split
//! samples`: each part is itself an unbiased image) or every sample of some tiles (`--split
//! tiles`), and [`render_part`] renders one into a film that merges exactly with the others.

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use crate::film::Film;
use crate::render::{RenderOutput, RenderProgress, SamplePass, render_pass};
use crate::scene::Scene;
use crate::settings::RenderSettings;

/// How a render is split into parts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Split {
    /// By sample index: part `K` renders samples `K * spp / N` to `(K + 1) * spp / N` of
    /// every pixel.
    #[default]
    Samples,
    /// By tiles of [`TILE`] x [`TILE`] pixels, dealt out in turn: tile `t` (row-major) goes
    /// to part `t % N`, so each part gets a share of the image's easy and hard regions.
    Tiles,
}

impl Split {
    /// Its name on the command line and in partial films.
    pub fn name(self) -> &'static str {
        match self {
            Split::Samples => "samples",
            Split::Tiles => "tiles",
        }
    }

    /// The split called `name`.
    pub fn from_name(name: &str) -> Option<Split> {
        [Split::Samples, Split::Tiles].into_iter().find(|s| s.name() == name)
    }
}

/// Side of a tile of [`Split::Tiles`], in pixels.
pub const TILE: u32 = 32;

/// Most parts a render may be split into.
pub const MAX_PARTS: u32 = 1 << 16;

/// Part `index` of `count` of a render, split by `split`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Part {
    /// From 0 to `count - 1` (as Slurm's `SLURM_ARRAY_TASK_ID` and Kubernetes'
    /// `JOB_COMPLETION_INDEX` count).
    pub index: u32,
    /// Parts in all, 1 to [`MAX_PARTS`].
    pub count: u32,
    /// How the render is split.
    pub split: Split,
}

impl Part {
    /// Part `index` of `count`, checked (a message naming `--part` otherwise).
    pub fn new(index: u32, count: u32, split: Split) -> Result<Part, crate::Error> {
        if count == 0 || count > MAX_PARTS || index >= count {
            return Err(crate::Error::Invalid(format!(
                "--part {index}/{count}: need 0 <= K < N and 1 <= N <= {MAX_PARTS}"
            )));
        }
        Ok(Part { index, count, split })
    }

    /// The samples `lo..hi` this part renders of each pixel in it, for `spp` in all.
    pub fn sample_range(&self, spp: u32) -> (u32, u32) {
        match self.split {
            Split::Samples => {
                let at = |k: u32| (u64::from(k) * u64::from(spp) / u64::from(self.count)) as u32;
                (at(self.index), at(self.index + 1))
            }
            Split::Tiles => (0, spp),
        }
    }

    /// Whether pixel `(x, y)` of an image `width` wide is in this part.
    pub fn has_pixel(&self, x: u32, y: u32, width: u32) -> bool {
        match self.split {
            Split::Samples => true,
            Split::Tiles => {
                let across = width.div_ceil(TILE);
                let tile = u64::from(y / TILE) * u64::from(across) + u64::from(x / TILE);
                tile % u64::from(self.count) == u64::from(self.index)
            }
        }
    }
}

/// Render `part` of the render of `scene` with `settings` (all `settings.spp` samples per
/// pixel, stratified over them as one render is): a film holding exactly this part's samples,
/// which [`super::merge`] adds to the other parts' to make that render's film, bit for bit.
pub fn render_part(
    scene: &Scene,
    settings: &RenderSettings,
    part: Part,
    cancel: &AtomicBool,
    progress: &(dyn Fn(RenderProgress) + Sync),
) -> RenderOutput {
    let start = Instant::now();
    let (lo, hi) = part.sample_range(settings.spp);
    let w = settings.width;
    let mut film = Film::new(w, settings.height);
    // Each pixel starts at the first sample of the part (so it draws the same random numbers
    // as in one render), and pixels outside the part start full, so the pass skips them.
    let inside = |i: usize| part.has_pixel(i as u32 % w, i as u32 / w, w);
    for (i, n) in film.counts_mut().iter_mut().enumerate() {
        *n = if inside(i) { lo } else { settings.spp };
    }
    let pass = SamplePass { samples: hi - lo, limit: hi, planned: settings.spp, seed: settings.seed };
    let (rays, complete) = render_pass(scene, settings, &scene.camera_motion(), &mut film, pass, cancel, progress);
    // The counts say how many samples the part holds.
    for (i, n) in film.counts_mut().iter_mut().enumerate() {
        *n = if inside(i) { *n - lo } else { 0 };
    }
    RenderOutput { film, rays, elapsed: start.elapsed(), complete }
}
