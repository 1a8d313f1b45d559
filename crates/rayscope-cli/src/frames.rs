//! `render --frames A..B` and `render --frame F`: an animation's frames, one after another
//! through the scene loaded once, each exposing its own span of the scene's timeline
//! ([`rayscope::animation`]) and written atomically to its own file (`OUT_0001.png`...).
//! `--frame F` is the same loop over one frame, so it writes exactly the file `--frames`
//! writes for `F` (one array task per frame on a cluster).

use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Result, bail};
use clap::Args;
use indicatif::ProgressBar;
use rayscope::animation::{AnimationSettings, Frame, FrameRange, MAX_FPS, MAX_FRAME};
use rayscope::aov::{Aov, render_aov};
use rayscope::film::Film;
use rayscope::output::{Encoding, write_image};
use rayscope::render::render_reusing;
use rayscope::scene::Scene;
use rayscope::settings::RenderSettings;

/// The animation flags (a command that renders frames flattens these): each given one wins
/// over the scene file's `[animation]`, which wins over [`AnimationSettings::default`].
#[derive(Args, Clone, Debug, Default)]
pub struct AnimationArgs {
    /// Render frames A to B of the scene's motion, `A..B` (B excluded) or `A..=B` (B
    /// included), to OUT_0001.png... (frame numbers, at least 4 digits, before -o's
    /// extension); `scene`: the scene file's `[animation] frames`.
    #[arg(long, value_name = "A..B|scene", allow_hyphen_values = true, value_parser = parse_frames,
          conflicts_with = "frame")]
    pub frames: Option<FramesArg>,
    /// Render only frame F of the animation, to the file --frames writes for it (bit for bit
    /// the same image): one task per frame of a job array.
    #[arg(long, value_name = "F", allow_negative_numbers = true,
          value_parser = clap::value_parser!(u32).range(0..=MAX_FRAME as i64))]
    pub frame: Option<u32>,
    /// Frames per second of scene time (motion keys are seconds) [default: 24].
    #[arg(long, value_name = "F", allow_negative_numbers = true, value_parser = parse_fps)]
    pub fps: Option<f64>,
    /// The part of each frame's duration the shutter is open, 0 to 1 [default: 0.5, a
    /// 180-degree shutter]: frame F exposes [F / fps, (F + shutter) / fps].
    #[arg(long, value_name = "S", allow_negative_numbers = true, value_parser = parse_shutter)]
    pub shutter: Option<f64>,
    /// With --frames: leave frames whose file exists as they are (continue an interrupted run).
    #[arg(long)]
    pub skip_existing: bool,
}

/// `--frames`'s value: a range, or none (the scene file's).
#[derive(Clone, Copy, Debug)]
pub enum FramesArg {
    /// `--frames A..B`.
    Range(FrameRange),
    /// `--frames scene`: the scene file's `[animation] frames`.
    FromScene,
}

fn parse_frames(s: &str) -> Result<FramesArg, String> {
    if s == "scene" { Ok(FramesArg::FromScene) } else { FrameRange::parse(s).map(FramesArg::Range) }
}

fn parse_fps(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(f) if f.is_finite() && f > 0.0 && f <= MAX_FPS => Ok(f),
        _ => Err(format!("'{s}' is not a frame rate (a number above 0, at most {MAX_FPS})")),
    }
}

fn parse_shutter(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(f) if (0.0..=1.0).contains(&f) => Ok(f),
        _ => Err(format!("'{s}' is not a shutter (a fraction of the frame's duration, 0 to 1)")),
    }
}

/// What to render: an animation's settings and its frames.
#[derive(Clone, Copy, Debug)]
pub struct Animation {
    /// Frame rate and shutter (the flags over the scene's `[animation]`).
    pub settings: AnimationSettings,
    /// The frames.
    pub frames: FrameRange,
}

impl AnimationArgs {
    /// The animation these flags ask of `scene` (`None`: neither --frames nor --frame, a
    /// still), or why they cannot.
    pub fn resolve(&self, scene: &Scene) -> Result<Option<Animation>> {
        let mut settings = scene.animation.unwrap_or_default();
        settings.fps = self.fps.unwrap_or(settings.fps);
        settings.shutter = self.shutter.unwrap_or(settings.shutter);
        let frames = match (self.frames, self.frame) {
            (Some(FramesArg::Range(r)), _) => r,
            (Some(FramesArg::FromScene), _) => match settings.frames {
                Some(r) => r,
                None => bail!("--frames scene: {} has no `[animation] frames`; give --frames A..B", scene.name),
            },
            (None, Some(f)) => FrameRange::single(f),
            (None, None) => {
                if self.fps.is_some() || self.shutter.is_some() || self.skip_existing {
                    bail!("--fps, --shutter and --skip-existing need --frames A..B or --frame F");
                }
                return Ok(None);
            }
        };
        settings.frames = Some(frames);
        settings.validate()?;
        Ok(Some(Animation { settings, frames }))
    }
}

/// How a frame's pixels are made: the render's film (with bloom) or an AOV.
#[derive(Clone, Copy)]
pub struct FrameOutput {
    /// The AOV to write instead of colour.
    pub aov: Option<Aov>,
    /// The PNG encoding.
    pub encoding: Encoding,
}

/// Render `animation`'s frames of `scene` one after another (the scene moved to each frame's
/// shutter: its BVH rebuilt only when something moves), writing each to its file beside
/// `output`; Ctrl-C stops after the frames already written (the interrupted one is not
/// written, so `--skip-existing` continues the run).
#[allow(clippy::too_many_arguments)]
pub fn render_frames(
    scene: &mut Scene,
    settings: &RenderSettings,
    animation: &Animation,
    output: &Path,
    how: FrameOutput,
    skip_existing: bool,
    pool: &rayon::ThreadPool,
    bar: &ProgressBar,
) -> Result<ExitCode> {
    if !scene.has_motion() {
        eprintln!("warning: {} has no motion: every frame is the same image", scene.name);
    }
    let cancel = crate::interrupt_flag();
    let count = animation.frames.len();
    let mut written = 0u32;
    // One film for every frame: each renders into the pages the one before touched.
    let mut film = None;
    for (i, number) in animation.frames.frames().enumerate() {
        let frame = animation.settings.frame(number, output);
        if skip_existing && frame.output.exists() {
            eprintln!("frame {number}: {} exists, skipped", frame.output.display());
            continue;
        }
        bar.set_prefix(format!("frame {number} ({} of {count})", i + 1));
        bar.set_position(0);
        let Some(times) = render_frame(scene, settings, &frame, how, &mut film, &cancel, pool, bar)? else {
            bar.finish_and_clear();
            eprintln!(
                "interrupted during frame {number}: it was not written; {} written. Run again with \
                 --skip-existing to continue; exit status {}",
                crate::counted(written as u64, "frame", "frames"),
                crate::EXIT_INTERRUPTED
            );
            return Ok(ExitCode::from(crate::EXIT_INTERRUPTED));
        };
        written += 1;
        bar.suspend(|| {
            eprintln!(
                "frame {number}: scene time {:.4} to {:.4} s, BVH {}, render {:.1} ms -> {}",
                frame.shutter.open,
                frame.shutter.close,
                times.bvh.map_or("kept".into(), |t| format!("{:.1} ms", t.as_secs_f64() * 1e3)),
                times.render.as_secs_f64() * 1e3,
                frame.output.display()
            )
        });
    }
    bar.finish_and_clear();
    Ok(ExitCode::SUCCESS)
}

/// How long a frame took.
struct FrameTimes {
    /// The BVH's rebuild for the frame's span (`None`: the tree was kept).
    bvh: Option<std::time::Duration>,
    /// The render, its image and its file.
    render: std::time::Duration,
}

/// Render and write one frame, in the film of the frame before where there is one (kept in
/// `film` for the next); `None` when Ctrl-C stopped it (nothing written).
#[allow(clippy::too_many_arguments)]
fn render_frame(
    scene: &mut Scene,
    settings: &RenderSettings,
    frame: &Frame,
    how: FrameOutput,
    film: &mut Option<Film>,
    cancel: &AtomicBool,
    pool: &rayon::ThreadPool,
    bar: &ProgressBar,
) -> Result<Option<FrameTimes>> {
    let bvh = scene.set_shutter(frame.shutter).then_some(scene.build_time);
    let start = std::time::Instant::now();
    let scene = &*scene;
    let progress = |p: rayscope::render::RenderProgress| bar.set_position(p.done as u64);
    let image = match how.aov {
        // AOVs are the first hits at shutter open.
        Some(aov) => pool.install(|| render_aov(scene, settings, &scene.camera_motion().at(0.0), aov, &progress)),
        None => {
            let reused = film.take();
            let out = pool.install(|| render_reusing(scene, settings, cancel, &progress, reused));
            if cancel.load(Ordering::Relaxed) || !out.complete {
                return Ok(None);
            }
            if out.film.dropped() > 0 {
                eprintln!(
                    "warning: frame {}: {} not finite (NaN or infinite) and added as black",
                    frame.number,
                    crate::counted(out.film.dropped(), "sample was", "samples were")
                );
            }
            let mut image = out.film.to_image();
            *film = Some(out.film);
            rayscope::post::bloom::apply_to_image(&mut image, &settings.bloom);
            image
        }
    };
    write_image(&image, &frame.output, how.encoding)?;
    Ok(Some(FrameTimes { bvh, render: start.elapsed() }))
}
