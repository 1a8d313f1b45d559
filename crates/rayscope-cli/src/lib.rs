//! `rayscope`: render course scenes to image files, list and export the built-in scenes,
//! print one pixel's ray tree, measure the course's table, and open the viewer.
//!
//! The command line is a library with one entry point, [`main`], that the binary calls: a
//! library can be a dependency, which is how the viewer's tests turn on this crate's `viewer`
//! feature, so that `cargo test --workspace` builds `rayscope view` and tests it while a
//! plain `cargo run -p rayscope-cli -- render` builds no GUI at all (see `Cargo.toml`).

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

mod bench;
mod bench_split;
mod bloom_args;
mod bvh_obj;
mod bvh_split;
mod compare;
mod env_args;
mod export;
pub mod frames;
mod k8s;
mod parts;
mod slurm;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayscope::aov::{Aov, render_aov};
use rayscope::camera::CameraDesc;
use rayscope::debug::{PixelTrace, SampleChoice, trace_pixel_samples, write_rays_obj};
use rayscope::film::Film;
use rayscope::math::Vec3;
use rayscope::motion::Interpolation;
use rayscope::output::{Encoding, Format, write_image};
use rayscope::progressive::{ImagingMode, Progressive};
use rayscope::record::{MAX_RECORDED_RAYS, RayTree};
use rayscope::render::{render_cancellable, render_reusing};
use rayscope::scene::{Scene, builtin};
use rayscope::settings::{PixelFilter, RenderSettings, ShadingModel, TextureFilter};

#[derive(Parser)]
#[command(name = "rayscope", version, about = "A fast, inspectable Whitted-style ray tracer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// The largest file (mesh, MTL, texture, scene file) read, in bytes; else the
    /// RAYSCOPE_MAX_FILE_BYTES environment variable, else 4 GiB.
    #[arg(long, global = true, value_name = "BYTES", value_parser = clap::value_parser!(u64).range(1..))]
    max_file_bytes: Option<u64>,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an image file (.png, .exr or .pfm).
    Render(RenderArgs),
    /// List the built-in scenes, print one as a TOML scene file, or write any scene as OBJ or
    /// glTF files with a TOML scene file for the camera, lights and spheres.
    Scenes {
        /// Print this built-in scene as TOML instead of listing them; with --format, the scene
        /// (built-in, .toml, or a mesh file) to write.
        #[arg(long, value_name = "NAME")]
        export: Option<String>,
        /// Write the scene's meshes in this format into DIR (with NAME.toml to load it back).
        #[arg(long, value_enum, requires = "export")]
        format: Option<rayscope::export::ExportFormat>,
        /// The folder --format writes into (created if missing).
        #[arg(value_name = "DIR", requires = "format")]
        dir: Option<PathBuf>,
    },
    /// Trace one pixel and print its ray tree as JSON.
    Debug(DebugArgs),
    /// Print a node of the binary BVH's SAH split candidates (every plane of every axis with
    /// its cost, and the split taken) as JSON.
    Bvh(bvh_split::BvhArgs),
    /// Compare an image (yours) with rayscope's render of the same scene and settings: how
    /// many pixels differ, by how much, SSIM, and a difference image. Exit status 0 when no
    /// pixel differs, 1 when some do, 2 on trouble.
    Compare(compare::CompareArgs),
    /// Measure the course report's performance table on this machine.
    Bench(BenchArgs),
    /// Merge the partial films of every part of a render (`render --part K/N`) into its
    /// image, which equals the render in one process bit for bit.
    Merge(parts::MergeArgs),
    /// Write (and with --submit, run and watch) a Slurm job array rendering a scene in
    /// --parts parts, and the job that merges them.
    Slurm(slurm::SlurmArgs),
    /// Print a Kubernetes Indexed Job rendering a scene in --parts parts, and the Job that
    /// merges them.
    K8s(k8s::K8sArgs),
    /// Open the viewer and visual debugger (needs the `viewer` feature: `cargo run -p
    /// rayscope-cli --features viewer -- view`).
    View(ViewArgs),
}

#[derive(Args)]
struct BenchArgs {
    /// Folder with the course's scene files (rows that need them are skipped without); else
    /// the RAYSCOPE_ASSETS environment variable, else ../shared/scenes when it exists.
    #[arg(long, value_name = "DIR")]
    assets: Option<PathBuf>,
    /// Worker threads (default: all cores; at most 256 or 4 per core, whichever is more).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
    /// Renders per row; the fastest counts.
    #[arg(long, default_value_t = 10, value_name = "N")]
    repetitions: usize,
    /// Renders per row before measuring.
    #[arg(long, default_value_t = 1, value_name = "N")]
    warmup: usize,
    /// One render per row and no warm-up: every row, fast (a smoke run for CI).
    #[arg(long)]
    quick: bool,
    /// Also write the table as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Also write the table as CSV.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
}

#[derive(Args)]
struct ViewArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Save a screenshot of the whole window here after --frames frames, and quit.
    #[arg(long, value_name = "FILE")]
    screenshot: Option<PathBuf>,
    /// Debug this pixel (X,Y from the top-left) from the start.
    #[arg(long, value_parser = parse_pixel, value_name = "X,Y")]
    debug_pixel: Option<(u32, u32)>,
    /// Debug a rectangle of pixels from the start, corners X0,Y0 and X1,Y1 included (up to 64
    /// pixels: a larger one is cut from its top-left corner).
    #[arg(long, value_parser = parse_rect, value_name = "X0,Y0,X1,Y1")]
    debug_rect: Option<[(u32, u32); 2]>,
    /// Which samples of the debugged pixels to trace: `all` (the default) or one index.
    #[arg(long, value_parser = parse_samples, value_name = "all|K")]
    samples: Option<SampleChoice>,
    /// Highlight row N (from 0) of the debugged pixel's explanation table in 3D.
    #[arg(long, value_name = "N")]
    explain_row: Option<usize>,
    /// Show this frame of the scene's animation (its `[animation]`, or 24 fps with a half-frame
    /// shutter), as `render --frame F` renders it; default: the still.
    #[arg(long, value_name = "F", value_parser = clap::value_parser!(u32).range(0..=rayscope::animation::MAX_FRAME as i64))]
    animation_frame: Option<u32>,
    /// Colour the overlay's rays by recursion depth, by kind, or by their sample's shutter time.
    #[arg(long, value_enum, value_name = "depth|kind|time")]
    color_rays_by: Option<ColorRaysBy>,
    /// Width of the debugger's overlay lines, in points.
    #[arg(long, value_name = "W", value_parser = parse_line_width)]
    line_width: Option<f32>,
    /// Show this BVH level from the start.
    #[arg(long, value_name = "L")]
    bvh_level: Option<u32>,
    /// Of the BVH level, draw only the nodes the debug pixel's camera ray entered.
    #[arg(long, requires = "bvh_level")]
    bvh_visited: bool,
    /// The tree the BVH level view draws: the wide tree rendering traverses, or the course's
    /// binary tree.
    #[arg(long, value_enum, default_value_t = bvh_obj::BvhTree::Wide)]
    bvh_tree: bvh_obj::BvhTree,
    /// Show this binary BVH node's SAH split candidates (planes and cost chart) from the start.
    #[arg(long, value_name = "NODE")]
    split_node: Option<u32>,
    /// After selecting the debug pixel, turn the camera by these angles (degrees about x and
    /// y) to see its ray tree from the side.
    #[arg(long, value_name = "DX,DY", value_parser = parse_orbit)]
    orbit: Option<(f32, f32)>,
    /// Ray-traced frames to render before the screenshot; fewer when the image is complete
    /// sooner (the heat map is one frame).
    #[arg(long, default_value_t = 1, value_name = "N")]
    frames: u32,
    /// The view to start in (theirs, ours and difference need --compare).
    #[arg(long, value_enum, default_value = "raster")]
    view: ViewArg,
    /// Which of bloom's layers the ray-traced view shows: the image, the bright pass or the
    /// blurred bright pass (with --bloom-strength above 0).
    #[arg(long, value_enum, default_value = "image")]
    bloom_layer: BloomLayerArg,
    /// Compare this image (PNG, BMP, OpenEXR) with our render of the scene, as `rayscope
    /// compare` does: adds the views theirs, ours and difference; rendered at its size unless
    /// --width/--height say otherwise.
    #[arg(long, value_name = "THEIRS")]
    compare: Option<PathBuf>,
}

#[derive(Clone, Copy, ValueEnum)]
enum BloomLayerArg {
    Image,
    Bright,
    Blurred,
}

#[derive(Clone, Copy, ValueEnum)]
enum ViewArg {
    Raster,
    Traced,
    HeatMap,
    MipLevels,
    Theirs,
    Ours,
    Difference,
}

#[derive(Args)]
pub(crate) struct SceneArgs {
    /// A built-in scene name (see `rayscope scenes`), a .toml scene file or a mesh file (.obj,
    /// .ply, .gltf or .glb).
    #[arg(default_value = builtin::DEFAULT_SCENE)]
    scene: String,
    /// Folder with the course's scene files; else the RAYSCOPE_ASSETS environment variable,
    /// else ../shared/scenes when it exists (relative to the working directory).
    #[arg(long, value_name = "DIR")]
    assets: Option<PathBuf>,
    /// Worker threads (default: all cores; at most 256 or 4 per core, whichever is more).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
    #[command(flatten)]
    settings: SettingsArgs,
    #[command(flatten)]
    environment: env_args::EnvironmentArgs,
}

/// Overrides of [`RenderSettings`]; each given flag wins over the scene file's `[render]`.
#[derive(Args)]
struct SettingsArgs {
    /// Image width in pixels [default: 800].
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels [default: 800].
    #[arg(long)]
    height: Option<u32>,
    /// Deepest reflection/transparency recursion [default: 5].
    #[arg(long, value_name = "N")]
    max_depth: Option<u32>,
    /// Adaptive depth control: cast no reflection or transmission ray whose weight (the share
    /// of its light that reaches the pixel) is below this; 0 turns it off [default: 1/255].
    #[arg(long, value_name = "WEIGHT")]
    adc_bailout: Option<f32>,
    /// Show unlit diffuse colours (the course's "shading off").
    #[arg(long)]
    no_shading: bool,
    /// The scene-wide shading model; a material's own `model` (scene file) wins [default: phong].
    #[arg(long, value_enum, value_name = "MODEL")]
    shading_model: Option<ShadingModel>,
    /// Cast no shadow rays.
    #[arg(long)]
    no_shadows: bool,
    /// No mirror reflections.
    #[arg(long)]
    no_reflections: bool,
    /// Treat every surface as opaque.
    #[arg(long)]
    no_transparency: bool,
    /// Ignore diffuse textures.
    #[arg(long)]
    no_textures: bool,
    /// Interpolate vertex normals (smooth shading).
    #[arg(long)]
    interpolate_normals: bool,
    /// Texture filtering [default: bilinear].
    #[arg(long, value_enum)]
    texture_filter: Option<TextureFilter>,
    /// Samples (camera rays) per pixel, for anti-aliasing and motion blur [default: 1]; with
    /// --progressive, samples per frame.
    #[arg(long, value_name = "N")]
    spp: Option<u32>,
    /// Shadow rays per area light (soft shadows); 0 shades lights from their centre [default: 0].
    #[arg(long, value_name = "N")]
    light_samples: Option<u32>,
    /// Rays per glossy reflection; 0 reflects as a perfect mirror [default: 0].
    #[arg(long, value_name = "N")]
    gloss_samples: Option<u32>,
    /// Pixel filter for anti-aliasing [default: box].
    #[arg(long, value_enum)]
    filter: Option<PixelFilter>,
    /// Seed of the random numbers [default: 0].
    #[arg(long)]
    seed: Option<u64>,
    /// Lens radius in scene units, for depth of field; 0 is a pinhole [default: 0].
    #[arg(long, value_name = "R", value_parser = parse_aperture, allow_negative_numbers = true)]
    aperture: Option<f32>,
    /// Depth in focus along the view axis, with --aperture [default: the look-at distance].
    #[arg(long, value_name = "D", value_parser = parse_focus_distance, allow_negative_numbers = true)]
    focus_distance: Option<f32>,
    /// The camera's pose when the shutter closes (motion blur): trackball rotation in degrees,
    /// optionally followed by a distance: `RX,RY,RZ[,DIST]`.
    #[arg(long, value_name = "RX,RY,RZ[,DIST]", value_parser = parse_camera_end)]
    camera_end: Option<CameraEnd>,
    /// Interpolate every keyframed path of the scene (objects' and the camera's) this way,
    /// whatever the scene file says: `linear` or `catmull-rom`.
    #[arg(long, value_name = "linear|catmull-rom", value_parser = parse_interpolation)]
    interpolation: Option<Interpolation>,
    #[command(flatten)]
    bloom: bloom_args::BloomArgs,
}

fn parse_interpolation(s: &str) -> Result<Interpolation, String> {
    Interpolation::ALL
        .into_iter()
        .find(|i| i.name() == s)
        .ok_or_else(|| format!("'{s}': expected linear or catmull-rom"))
}

/// How `view` colours the overlay's rays (`--color-rays-by`).
#[derive(Clone, Copy, Debug, ValueEnum)]
enum ColorRaysBy {
    /// By recursion depth (the course's colours).
    Depth,
    /// By the kind of ray.
    Kind,
    /// By the sample's shutter time.
    Time,
}

/// The `--camera-end` pose: trackball rotation and, optionally, distance.
#[derive(Clone, Copy, Debug)]
struct CameraEnd {
    rotation: Vec3,
    distance: Option<f32>,
}

/// A lens radius: finite, 0 or more (clap names the flag in its error).
fn parse_aperture(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(r) if r.is_finite() && r >= 0.0 => Ok(r),
        _ => Err(format!("'{s}' is not a lens radius (a finite number, 0 or more)")),
    }
}

/// A focus distance: finite and above 0.
fn parse_focus_distance(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(d) if d.is_finite() && d > 0.0 => Ok(d),
        _ => Err(format!("'{s}' is not a focus distance (a finite number above 0)")),
    }
}

fn parse_camera_end(s: &str) -> Result<CameraEnd, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|p| p.trim().parse::<f32>().map_err(|_| format!("'{p}' is not a number")))
        .collect::<Result<_, _>>()?;
    if !(3..=4).contains(&v.len()) || v.iter().any(|x| !x.is_finite()) {
        return Err("expected RX,RY,RZ or RX,RY,RZ,DIST (finite numbers)".into());
    }
    if v.get(3).is_some_and(|&d| d <= 0.0) {
        return Err("the distance DIST must be positive".into());
    }
    Ok(CameraEnd { rotation: Vec3::new(v[0], v[1], v[2]), distance: v.get(3).copied() })
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output file; the format follows the extension (.png, .exr, .pfm).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Apply the sRGB curve to PNG output (default: the course's linear clamp to [0,1] x 255).
    #[arg(long)]
    srgb: bool,
    /// Write this buffer instead of colour (needs .exr or .pfm).
    #[arg(long, value_enum)]
    aov: Option<Aov>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
    /// Render in frames of --spp samples, accumulating until --target-spp, --time-limit or
    /// Ctrl-C.
    #[arg(long)]
    progressive: bool,
    /// With --progressive (or --resume): stop at this many samples per pixel.
    #[arg(long, value_name = "N")]
    target_spp: Option<u32>,
    /// With --progressive (or --resume): stop after the frame that passes this many seconds.
    #[arg(long, value_name = "SECONDS")]
    time_limit: Option<f64>,
    /// Render this many times in one process and report the fastest render (every render
    /// gives the same image): timings with warm caches and threads, for comparisons.
    #[arg(long, value_name = "N", default_value_t = 1, conflicts_with = "progressive",
          value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    #[command(flatten)]
    parts: parts::PartArgs,
    #[command(flatten)]
    animation: frames::AnimationArgs,
}

#[derive(Args)]
struct DebugArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// The pixel, `X,Y` from the top-left corner.
    #[arg(long, value_parser = parse_pixel)]
    pixel: (u32, u32),
    /// Which of the pixel's samples to trace: `all` (the pixel's value as rendered), or one
    /// by index (0 to spp - 1).
    #[arg(long, value_name = "all|K", default_value = "all", value_parser = parse_samples)]
    samples: SampleChoice,
    /// Trace only this sample (the same as --samples K).
    #[arg(long, value_name = "K", conflicts_with = "samples")]
    sample: Option<u32>,
    /// Print the pixel's colour as a sum of terms (per sample, ray and light) as text instead
    /// of the JSON.
    #[arg(long)]
    explain: bool,
    /// Also write the rays as an OBJ file of lines and points, one group per kind of ray.
    #[arg(long, value_name = "FILE.obj")]
    export_rays: Option<PathBuf>,
    /// Record at most this many rays (shadow rays included, over all the samples traced);
    /// the rest are traced but not printed.
    #[arg(long, value_name = "N", default_value_t = MAX_RECORDED_RAYS)]
    max_rays: usize,
    /// Also write the boxes of BVH level N (its nodes, and the leaves at or above it) to
    /// FILE.obj as line cubes, one group for the nodes and one for the leaves.
    #[arg(long, num_args = 2, value_names = ["N", "FILE.obj"])]
    export_bvh_level: Option<Vec<String>>,
    /// The tree --export-bvh-level writes: the wide tree rendering traverses, or the course's
    /// binary tree.
    #[arg(long, value_enum, default_value_t = bvh_obj::BvhTree::Wide, requires = "export_bvh_level")]
    bvh_tree: bvh_obj::BvhTree,
}

fn parse_samples(s: &str) -> Result<SampleChoice, String> {
    if s == "all" {
        return Ok(SampleChoice::All);
    }
    s.parse().map(SampleChoice::One).map_err(|_| format!("'{s}' is neither `all` nor a sample index"))
}

fn parse_orbit(s: &str) -> Result<(f32, f32), String> {
    let (x, y) = s.split_once(',').ok_or("expected DX,DY")?;
    let p = |v: &str| v.trim().parse::<f32>().ok().filter(|v| v.is_finite()).ok_or(format!("'{v}' is not a number"));
    Ok((p(x)?, p(y)?))
}

fn parse_pixel(s: &str) -> Result<(u32, u32), String> {
    let (x, y) = s.split_once(',').ok_or("expected X,Y")?;
    let p = |v: &str| v.trim().parse::<u32>().map_err(|_| format!("'{v}' is not a pixel coordinate"));
    Ok((p(x)?, p(y)?))
}

/// Two corner pixels, `X0,Y0,X1,Y1`.
fn parse_rect(s: &str) -> Result<[(u32, u32); 2], String> {
    let parts: Vec<&str> = s.split(',').collect();
    let [x0, y0, x1, y1] = parts[..] else { return Err("expected X0,Y0,X1,Y1".into()) };
    Ok([parse_pixel(&format!("{x0},{y0}"))?, parse_pixel(&format!("{x1},{y1}"))?])
}

fn parse_line_width(s: &str) -> Result<f32, String> {
    s.trim()
        .parse::<f32>()
        .ok()
        .filter(|w| (0.5..=32.0).contains(w))
        .ok_or(format!("'{s}' is not a line width (0.5 to 32 points)"))
}

/// The exit status of a render that Ctrl-C stopped (after writing the image it had): the
/// shell's convention for a process ended by SIGINT (128 + 2), so that a script can tell it
/// from a finished render.
pub const EXIT_INTERRUPTED: u8 = 130;

/// Run the command line on the process's arguments: 0 when done, 130 for a render stopped by
/// Ctrl-C, 1 (after printing the error) on failure; `compare` follows `diff` instead (0 the
/// same, 1 different, 2 on failure).
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let failure = match cli.command {
        Command::Compare(_) => ExitCode::from(compare::EXIT_TROUBLE),
        _ => ExitCode::FAILURE,
    };
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", message(&e));
            failure
        }
    }
}

/// An error and its causes, `: `-separated, each said once: the library's errors already show
/// the error they wrap (`out.png: Permission denied`), which printing the chain repeated.
fn message(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if !text.ends_with(&c) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&c);
        }
    }
    text
}

fn run(cli: Cli) -> Result<ExitCode> {
    let done = |r: Result<()>| r.map(|()| ExitCode::SUCCESS);
    // Process-wide, before any scene loads: the viewer loads scenes in this process too.
    rayscope::scene::set_max_file_bytes(cli.max_file_bytes);
    match cli.command {
        Command::Render(args) => cmd_render(args),
        Command::Scenes { export, format, dir } => done(cmd_scenes(export, format, dir)),
        Command::Debug(args) => done(cmd_debug(args)),
        Command::Bvh(args) => done(bvh_split::cmd_bvh(args)),
        Command::Compare(args) => compare::cmd_compare(args),
        Command::Bench(args) => done(cmd_bench(args)),
        Command::Merge(args) => done(parts::cmd_merge(args)),
        Command::Slurm(args) => slurm::cmd_slurm(args),
        Command::K8s(args) => done(k8s::cmd_k8s(args)),
        Command::View(args) => done(cmd_view(args)),
    }
}

fn cmd_scenes(
    export: Option<String>,
    format: Option<rayscope::export::ExportFormat>,
    dir: Option<PathBuf>,
) -> Result<()> {
    if let Some(name) = export {
        return export::cmd_export(&name, format, dir.as_deref());
    }
    for b in builtin::BUILTINS {
        let files = if b.needs_assets { " (needs the asset folder)" } else { "" };
        println!("{:<34}{}{}", b.name, b.description, files);
    }
    Ok(())
}

/// Load the scene and merge settings: defaults, then the scene's `[render]`, then flags.
fn load(args: &SceneArgs) -> Result<(Scene, RenderSettings)> {
    let scene = Scene::load(&args.scene, args.assets.as_deref())?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let mut s = scene.render.clone().unwrap_or_default();
    let f = &args.settings;
    s.width = f.width.unwrap_or(s.width);
    s.height = f.height.unwrap_or(s.height);
    s.max_depth = f.max_depth.unwrap_or(s.max_depth);
    s.adc_bailout = f.adc_bailout.unwrap_or(s.adc_bailout);
    s.shading &= !f.no_shading;
    s.shading_model = f.shading_model.unwrap_or(s.shading_model);
    s.shadows &= !f.no_shadows;
    s.reflections &= !f.no_reflections;
    s.transparency &= !f.no_transparency;
    s.textures &= !f.no_textures;
    s.interpolate_normals |= f.interpolate_normals;
    s.spp = f.spp.unwrap_or(s.spp);
    s.light_samples = f.light_samples.unwrap_or(s.light_samples);
    s.gloss_samples = f.gloss_samples.unwrap_or(s.gloss_samples);
    s.seed = f.seed.unwrap_or(s.seed);
    s.filter = f.filter.unwrap_or(s.filter);
    s.texture_filter = f.texture_filter.unwrap_or(s.texture_filter);
    s.aperture = f.aperture.unwrap_or(s.aperture);
    s.focus_distance = f.focus_distance.or(s.focus_distance);
    f.bloom.apply(&mut s.bloom)?;
    s.validate()?;
    let mut scene = scene;
    args.environment.apply(&mut scene)?;
    if let Some(i) = f.interpolation {
        scene.set_motion_interpolation(i);
    }
    if f.camera_end.is_some() && scene.camera_path.is_some() {
        bail!("--camera-end: the scene's camera already moves along its `camera_motion` path");
    }
    if let Some(end) = &f.camera_end {
        let CameraDesc::Trackball { look_at, distance, fov, .. } = scene.camera else {
            bail!("--camera-end needs a trackball camera; give a look-at scene's end pose as `camera_end` in its file");
        };
        let distance = end.distance.unwrap_or(distance);
        scene.camera_end = Some(CameraDesc::Trackball { look_at, distance, rotation: end.rotation, fov });
    }
    Ok((scene, s))
}

/// The most `--threads` accepted: more threads than cores only take turns on them, and each
/// reserves a stack, so thousands exhaust the process's threads or memory (5000 failed with
/// "Resource temporarily unavailable", 100000 hung) for no gain.
fn max_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    cores.saturating_mul(4).max(256)
}

fn parse_threads(s: &str) -> Result<usize, String> {
    let n: usize = s.trim().parse().map_err(|_| format!("'{s}' is not a number of threads"))?;
    let max = max_threads();
    if !(1..=max).contains(&n) {
        return Err(format!("{n} is out of range: give 1 to {max} (256, or 4 per core where that is more)"));
    }
    Ok(n)
}

fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let n = threads.unwrap_or(0);
    rayon::ThreadPoolBuilder::new().num_threads(n).build().context("starting the worker threads (--threads)")
}

fn cmd_render(args: RenderArgs) -> Result<ExitCode> {
    let format = Format::from_path(&args.output)?;
    if args.aov.is_some() && !format.is_float() {
        bail!("{}: AOVs are float data; write them to .exr or .pfm", args.output.display());
    }
    if args.time_limit.is_some_and(|t| !t.is_finite() || t < 0.0) {
        bail!("--time-limit must be a number of seconds, at least 0");
    }
    if args.target_spp.is_some_and(|t| t == 0 || t > rayscope::settings::MAX_SAMPLES) {
        bail!("--target-spp must be 1 to {}", rayscope::settings::MAX_SAMPLES);
    }
    let animating = args.animation.frames.is_some() || args.animation.frame.is_some();
    if animating && (args.progressive || args.repeat > 1) {
        bail!("--frames and --frame render each frame once: not with --progressive or --repeat");
    }
    if animating && (args.parts.part.is_some() || args.parts.resume.is_some()) {
        bail!("--frames and --frame render whole frames: not with --part or --resume");
    }
    let load_start = std::time::Instant::now();
    let (mut scene, settings) = load(&args.scene)?;
    let animation = args.animation.resolve(&scene)?;
    // Loading includes the BVH build, reported apart.
    let load_ms = (load_start.elapsed().as_secs_f64() - scene.build_time.as_secs_f64()) * 1e3;
    let pool = thread_pool(args.scene.threads)?;
    let total = settings.width as u64 * settings.height as u64;
    let bar = ProgressBar::with_draw_target(
        Some(total),
        if args.quiet || !std::io::stderr().is_terminal() {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        },
    );
    bar.set_style(
        ProgressStyle::with_template("{spinner} {bar:40} {percent:>3}% {elapsed} (eta {eta})").expect("valid template"),
    );
    let progress = |p: rayscope::render::RenderProgress| bar.set_position(p.done as u64);
    let encoding = if args.srgb { Encoding::Srgb } else { Encoding::Linear };
    if let Some(animation) = animation {
        bar.set_style(
            ProgressStyle::with_template("{prefix} {bar:40} {percent:>3}% {elapsed} (eta {eta})")
                .expect("valid template"),
        );
        eprintln!(
            "{}: load {load_ms:.1} ms, frames {} at {} fps, shutter {} of a frame -> {}",
            scene.name,
            animation.frames,
            animation.settings.fps,
            animation.settings.shutter,
            rayscope::animation::frame_path(&args.output, animation.frames.start).display()
        );
        let how = frames::FrameOutput { aov: args.aov, encoding };
        let skip = args.animation.skip_existing;
        return frames::render_frames(&mut scene, &settings, &animation, &args.output, how, skip, &pool, &bar);
    }
    let stats = scene.bvh_stats();
    let summary = |what: &str| {
        format!(
            "{}: {}, load {load_ms:.1} ms, BVH {:.1} ms ({}), {what} -> {}",
            scene.name,
            counted(scene.triangle_count() as u64, "triangle", "triangles"),
            scene.build_time.as_secs_f64() * 1e3,
            counted(stats.levels as u64, "level", "levels"),
            args.output.display()
        )
    };
    if let Some(aov) = args.aov {
        let start = std::time::Instant::now();
        let img = pool.install(|| render_aov(&scene, &settings, &scene.camera(), aov, &progress));
        bar.finish_and_clear();
        write_image(&img, &args.output, encoding)?;
        eprintln!("{}", summary(&format!("AOV in {:.1} ms", start.elapsed().as_secs_f64() * 1e3)));
        return Ok(ExitCode::SUCCESS);
    }
    let cancel = interrupt_flag();
    let fingerprint = match (&args.parts.part, &args.parts.checkpoint, &args.parts.resume) {
        (None, None, None) => None,
        _ => Some(parts::fingerprint(&args.scene, &settings)?),
    };
    if let (Some((k, n)), Some(fingerprint)) = (args.parts.part, &fingerprint) {
        parts::check_exr(&args.output, "--part")?;
        let part = rayscope::partial::part::Part::new(k, n, args.parts.split.unwrap_or_default())?;
        let out = pool.install(|| rayscope::partial::part::render_part(&scene, &settings, part, &cancel, &progress));
        bar.finish_and_clear();
        if !out.complete {
            // An interrupted part is not written: merge must never take it for a whole part.
            eprintln!("interrupted: part {k}/{n} not written; exit status {EXIT_INTERRUPTED}");
            return Ok(ExitCode::from(EXIT_INTERRUPTED));
        }
        let note = samples_note(&out.film);
        parts::write_part(&args.output, fingerprint.clone(), part, out.film)?;
        eprintln!(
            "{}",
            summary(&format!(
                "part {k}/{n} split by {}, render {:.1} ms, {note}",
                part.split.name(),
                out.elapsed.as_secs_f64() * 1e3
            ))
        );
        return Ok(ExitCode::SUCCESS);
    }
    let progressive = args.progressive || args.parts.resume.is_some();
    if !progressive && (args.target_spp.is_some() || args.time_limit.is_some()) {
        bail!("--target-spp and --time-limit need --progressive (or --resume)");
    }
    let checkpoint = args.parts.checkpoint.clone().or(args.parts.resume.clone());
    if let Some(path) = &checkpoint {
        parts::check_exr(path, "--checkpoint")?;
        if args.target_spp.is_none() {
            bail!("--checkpoint and --resume need --target-spp: the samples the render ends at (and stratifies over)");
        }
    }
    let every = args.parts.checkpoint_every.unwrap_or(parts::DEFAULT_CHECKPOINT_SECONDS);
    if !(every.is_finite() && every > 0.0) {
        bail!("--checkpoint-every must be a number of seconds above 0");
    }
    let (film, rays, elapsed) = if progressive {
        if args.target_spp.is_none() && args.time_limit.is_none() {
            eprintln!("rendering progressively until Ctrl-C (give --target-spp or --time-limit to stop by itself)");
        }
        if let Some(target) = args.target_spp {
            bar.set_length(target as u64);
        }
        bar.set_position(0);
        let start = std::time::Instant::now();
        let mut prog = Progressive::new(settings.clone(), ImagingMode::Dynamic, args.target_spp);
        if let (Some(path), Some(fp)) = (&args.parts.resume, &fingerprint) {
            let (film, frames) = parts::load_checkpoint(path, fp, args.target_spp)?;
            if !prog.restore(film, frames) {
                bail!("{}: the checkpoint's image size is not the settings'", path.display());
            }
        }
        let limit = args.time_limit.map(std::time::Duration::from_secs_f64);
        let save = |film: &Film, frames: u32| -> Result<()> {
            match (&checkpoint, &fingerprint) {
                (Some(path), Some(fp)) => {
                    let c = rayscope::partial::Checkpoint { target_spp: args.target_spp, frames };
                    parts::save_checkpoint(path, fp, c, film)
                }
                _ => Ok(()),
            }
        };
        let mut last_save = std::time::Instant::now();
        let mut failed = None;
        let rays = pool.install(|| {
            prog.run(&scene, &scene.camera_motion(), limit, &cancel, |film, info| {
                bar.set_position(film.sample_range().0 as u64);
                if last_save.elapsed().as_secs_f64() >= every {
                    last_save = std::time::Instant::now();
                    if let Err(e) = save(film, info.frame) {
                        failed = Some(e);
                        return std::ops::ControlFlow::Break(());
                    }
                }
                std::ops::ControlFlow::Continue(())
            })
        });
        if let Some(e) = failed {
            return Err(e.context("writing the checkpoint"));
        }
        // The last state, finished or interrupted (Ctrl-C), so that --resume goes on from it.
        save(prog.film(), prog.frames()).context("writing the checkpoint")?;
        (prog.film().clone(), rays, start.elapsed())
    } else {
        let mut out = pool.install(|| render_cancellable(&scene, &settings, &cancel, &progress));
        let mut fastest = out.elapsed;
        // Two films take turns: each render after the second writes to the pages of the one
        // before last (`render_reusing`), and the last complete image is kept whole.
        let mut spare = None;
        for _ in 1..args.repeat {
            if cancel.load(Ordering::Relaxed) {
                break;
            }
            bar.set_position(0);
            let film = spare.take();
            let again = pool.install(|| render_reusing(&scene, &settings, &cancel, &progress, film));
            if cancel.load(Ordering::Relaxed) {
                // Keep the complete image of an earlier render.
                break;
            }
            fastest = fastest.min(again.elapsed);
            spare = Some(std::mem::replace(&mut out, again).film);
        }
        (out.film, out.rays, fastest)
    };
    bar.finish_and_clear();
    let mut image = film.to_image();
    rayscope::post::bloom::apply_to_image(&mut image, &settings.bloom);
    write_image(&image, &args.output, encoding)?;
    let mrays = rays.total() as f64 / elapsed.as_secs_f64().max(1e-9) / 1e6;
    eprintln!(
        "{}",
        summary(&format!(
            "render {:.1} ms{}, {}, {mrays:.2} Mrays/s",
            elapsed.as_secs_f64() * 1e3,
            if args.repeat > 1 { format!(" (fastest of {})", args.repeat) } else { String::new() },
            samples_note(&film)
        ))
    );
    if film.dropped() > 0 {
        eprintln!(
            "warning: {} not finite (NaN or infinite) and added as black; the scene has degenerate values",
            counted(film.dropped(), "sample was", "samples were")
        );
    }
    if cancel.load(Ordering::Relaxed) {
        eprintln!(
            "interrupted: the image holds what was rendered ({}); exit status {EXIT_INTERRUPTED}",
            samples_note(&film)
        );
        return Ok(ExitCode::from(EXIT_INTERRUPTED));
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(not(feature = "viewer"))]
fn cmd_view(_: ViewArgs) -> Result<()> {
    bail!(
        "this rayscope was built without the viewer (it is the `viewer` feature, as it needs the GUI \
         stack, eframe and wgpu, whose first build takes minutes). Run it with `cargo run -p rayscope-cli \
         --features viewer -- view [SCENE] [options]`, or install it with `cargo install --path \
         crates/rayscope-cli --features viewer`"
    )
}

#[cfg(feature = "viewer")]
fn cmd_view(mut args: ViewArgs) -> Result<()> {
    use rayscope_viewer::session;
    use rayscope_viewer::state::ViewKind;
    // First, while this is the only thread: a private runtime dir where the session has none,
    // so that the Vulkan driver's probe for Wayland prints no error (see `session`).
    let runtime = tempfile::Builder::new().prefix("rayscope-runtime-").tempdir()?;
    // SAFETY: no other thread exists yet (rayon's pool starts with the scene's BVH build below).
    unsafe { session::quiet_wayland_probe(runtime.path()) }?;
    session::check_display()?;
    if let Some(theirs) = &args.compare {
        compare::size_from(theirs, &mut args.scene.settings)?;
    }
    // Check the scene and flags here, so that mistakes are reported on the terminal.
    let (_, settings) = load(&args.scene)?;
    let view = match args.view {
        ViewArg::Raster => ViewKind::Raster,
        ViewArg::Traced => ViewKind::RayTraced,
        ViewArg::HeatMap => ViewKind::HeatMap,
        ViewArg::MipLevels => ViewKind::MipLevels,
        ViewArg::Theirs => ViewKind::Theirs,
        ViewArg::Ours => ViewKind::Ours,
        ViewArg::Difference => ViewKind::Difference,
    };
    if matches!(view, ViewKind::Theirs | ViewKind::Ours | ViewKind::Difference) && args.compare.is_none() {
        bail!("--view theirs, ours and difference need an image to compare: --compare THEIRS.png");
    }
    rayscope_viewer::run(rayscope_viewer::ViewerOptions {
        scene: args.scene.scene.clone(),
        assets: args.scene.assets.clone(),
        settings: Some(settings),
        view: Some(view),
        debug_pixel: args.debug_pixel,
        debug_rect: args.debug_rect.map(|[a, b]| rayscope_viewer::state::PixelRect::spanning(a, b)),
        line_width: args.line_width,
        samples: args.samples,
        explain_row: args.explain_row,
        bvh_level: args.bvh_level,
        orbit: args.orbit,
        bvh_only_visited: args.bvh_visited,
        bvh_tree: Some(args.bvh_tree),
        split_node: args.split_node,
        screenshot: args.screenshot,
        frames: args.frames,
        compare: args.compare,
        motion_interpolation: args.scene.settings.interpolation,
        animation_frame: args.animation_frame,
        color_by: args.color_rays_by.map(|c| match c {
            ColorRaysBy::Depth => rayscope_viewer::overlay::ColorBy::Depth,
            ColorRaysBy::Kind => rayscope_viewer::overlay::ColorBy::Kind,
            ColorRaysBy::Time => rayscope_viewer::overlay::ColorBy::Time,
        }),
        environment: args.scene.environment.viewer_override()?,
        bloom_layer: match args.bloom_layer {
            BloomLayerArg::Image => rayscope_viewer::bloom::BloomLayer::Image,
            BloomLayerArg::Bright => rayscope_viewer::bloom::BloomLayer::Bright,
            BloomLayerArg::Blurred => rayscope_viewer::bloom::BloomLayer::Blurred,
        },
    })
}

fn cmd_bench(args: BenchArgs) -> Result<()> {
    let pool = thread_pool(args.threads)?;
    let (reps, warmup) = if args.quick { (1, 0) } else { (args.repetitions.max(1), args.warmup) };
    let threads = pool.current_num_threads();
    let mut report = pool.install(|| bench::run(args.assets.as_deref(), reps, warmup, threads))?;
    report.split_rules = pool.install(|| bench_split::run(args.assets.as_deref(), reps, warmup))?;
    print!("{}{}", bench::markdown(&report), bench_split::markdown(&report.split_rules));
    if let Some(p) = &args.json {
        bench::write_text(p, &serde_json::to_string_pretty(&report)?)?;
    }
    if let Some(p) = &args.csv {
        bench::write_text(p, &bench::csv(&report))?;
    }
    Ok(())
}

fn samples_note(film: &Film) -> String {
    match film.sample_range() {
        (a, b) if a == b => format!("{a} spp"),
        (a, b) => format!("{a} to {b} spp"),
    }
}

/// `n` and the noun, singular (`one`) for one: "1 triangle", "2 triangles".
fn counted(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// A flag that Ctrl-C sets, so renders stop cleanly and write what they have; a second Ctrl-C
/// exits at once.
fn interrupt_flag() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    let _ = ctrlc::set_handler(move || {
        if f.swap(true, Ordering::SeqCst) {
            std::process::exit(EXIT_INTERRUPTED.into());
        }
    });
    flag
}

fn cmd_debug(args: DebugArgs) -> Result<()> {
    let (scene, settings) = load(&args.scene)?;
    let (x, y) = args.pixel;
    if x >= settings.width || y >= settings.height {
        bail!("pixel {x},{y} is outside the {}x{} image", settings.width, settings.height);
    }
    let which = args.sample.map_or(args.samples, SampleChoice::One);
    if let SampleChoice::One(k) = which
        && k >= settings.spp
    {
        bail!("sample {k} does not exist: the pixel has {} (--spp)", counted(settings.spp.into(), "sample", "samples"));
    }
    let trace = trace_pixel_samples(&scene, &settings, &scene.camera_motion(), x, y, which, args.max_rays);
    let explanation = trace.explain();
    if let Some(path) = &args.export_rays {
        let counts = write_rays_obj(&trace, path)?;
        eprintln!(
            "wrote {}: {} and {}",
            path.display(),
            counted(counts.segments as u64, "segment", "segments"),
            counted(counts.points as u64, "point", "points")
        );
    }
    if let Some([level, path]) = args.export_bvh_level.as_deref() {
        let level: u32 = level.parse().map_err(|_| anyhow::anyhow!("--export-bvh-level: '{level}' is not a level"))?;
        let boxes = bvh_obj::export_level(&scene, args.bvh_tree, level, path.as_ref())?;
        eprintln!("wrote {}: {}", path, counted(boxes as u64, "box", "boxes"));
    }
    // Streamed: a tree at its bound is about 70 MB of text, which need not be held as well
    // (the peak of a 100 000-ray tree falls from 280 to 210 MB).
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    if args.explain {
        write!(out, "{explanation}")?;
    } else {
        let json = serde_json::json!({
            "scene": scene.name,
            "pixel": [x, y],
            "spp": settings.spp,
            "value": trace.value.to_array(),
            "samples": samples_json(&trace, &scene)?,
            "explanation": explanation,
        });
        serde_json::to_writer_pretty(&mut out, &json)?;
        writeln!(out)?;
    }
    out.flush()?;
    for sample in &trace.samples {
        for note in debug_notes(&sample.tree) {
            eprintln!("note: sample {}: {note}", sample.index);
        }
    }
    Ok(())
}

/// The samples of `trace` as JSON, each hit's material named beside its index.
fn samples_json(trace: &PixelTrace, scene: &Scene) -> Result<serde_json::Value> {
    let mut samples = serde_json::to_value(&trace.samples)?;
    for sample in samples.as_array_mut().into_iter().flatten() {
        // The tree's rays and cut at the sample's level, where they are read.
        let tree = sample.as_object_mut().and_then(|s| s.remove("tree"));
        if let (Some(serde_json::Value::Object(tree)), Some(s)) = (tree, sample.as_object_mut()) {
            s.extend(tree);
        }
        for ray in sample["rays"].as_array_mut().into_iter().flatten() {
            let hit = &mut ray["hit"];
            if let Some(m) = hit["material"].as_u64() {
                let name = scene.materials.get(m as usize).map(|m| m.name.clone());
                hit["material_name"] = name.into();
            }
        }
    }
    Ok(samples)
}

/// What the debugger's output leaves out or cannot show: the rays past its bound, and the
/// branches adaptive depth control did not cast (the first one spelled out).
fn debug_notes(tree: &RayTree) -> Vec<String> {
    let mut notes = Vec::new();
    if let Some(cut) = &tree.cut {
        notes.push(format!("the ray tree was cut (--max-rays): {cut}"));
    }
    let mut stops = tree.rays.iter().enumerate().flat_map(|(i, r)| r.stopped.iter().map(move |b| (i, b)));
    if let Some((i, first)) = stops.next() {
        notes.push(format!(
            "adaptive depth control stopped {} (listed as `stopped` under their rays); the first, of ray {i}: {first}",
            counted(1 + stops.count() as u64, "branch", "branches"),
        ));
    }
    notes
}
