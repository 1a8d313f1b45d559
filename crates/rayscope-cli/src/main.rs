//! `rayscope`: render course scenes to image files, list and export the built-in scenes, and
//! print one pixel's ray tree.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayscope::material::TextureFilter;
use rayscope::output::{Encoding, Format, write_image};
use rayscope::record::RayTree;
use rayscope::render::{Aov, RenderSettings, render, render_aov, trace_pixel};
use rayscope::scene::{Scene, builtin};

#[derive(Parser)]
#[command(name = "rayscope", version, about = "A fast, inspectable Whitted-style ray tracer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an image file (.png, .exr or .pfm).
    Render(RenderArgs),
    /// List the built-in scenes, or print one as a TOML scene file.
    Scenes {
        /// Print this built-in scene as TOML instead of listing them.
        #[arg(long, value_name = "NAME")]
        export: Option<String>,
    },
    /// Trace one pixel and print its ray tree as JSON.
    Debug(DebugArgs),
}

#[derive(Args)]
struct SceneArgs {
    /// A built-in scene name (see `rayscope scenes`), a .toml scene file or an .obj file.
    #[arg(default_value = builtin::DEFAULT_SCENE)]
    scene: String,
    /// Folder with the course's scene files.
    #[arg(long, env = "RAYSCOPE_ASSETS", value_name = "DIR")]
    assets: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    #[command(flatten)]
    settings: SettingsArgs,
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
    /// Show unlit diffuse colours (the course's "shading off").
    #[arg(long)]
    no_shading: bool,
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
    texture_filter: Option<FilterArg>,
}

#[derive(Clone, Copy, ValueEnum)]
enum FilterArg {
    Nearest,
    Bilinear,
}

#[derive(Clone, Copy, ValueEnum)]
enum AovArg {
    Depth,
    Position,
    Normal,
    Albedo,
    PrimId,
    NodesVisited,
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
    aov: Option<AovArg>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Args)]
struct DebugArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// The pixel, `X,Y` from the top-left corner.
    #[arg(long, value_parser = parse_pixel)]
    pixel: (u32, u32),
}

fn parse_pixel(s: &str) -> Result<(u32, u32), String> {
    let (x, y) = s.split_once(',').ok_or("expected X,Y")?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{v}' is not a pixel coordinate"))
    };
    Ok((p(x)?, p(y)?))
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => cmd_render(args),
        Command::Scenes { export } => cmd_scenes(export),
        Command::Debug(args) => cmd_debug(args),
    }
}

fn cmd_scenes(export: Option<String>) -> Result<()> {
    if let Some(name) = export {
        print!("{}", builtin::scene_desc(&name)?.to_toml());
        return Ok(());
    }
    for b in builtin::BUILTINS {
        let files = if b.needs_assets {
            " (needs the asset folder)"
        } else {
            ""
        };
        println!("{:<34}{}{}", b.name, b.description, files);
    }
    Ok(())
}

/// Load the scene and merge settings: defaults, then the scene's `[render]`, then flags.
fn load(args: &SceneArgs) -> Result<(Scene, RenderSettings)> {
    let scene = Scene::load(&args.scene, args.assets.as_deref())?;
    let mut s = scene.render.clone().unwrap_or_default();
    let f = &args.settings;
    s.width = f.width.unwrap_or(s.width);
    s.height = f.height.unwrap_or(s.height);
    s.max_depth = f.max_depth.unwrap_or(s.max_depth);
    s.shading &= !f.no_shading;
    s.shadows &= !f.no_shadows;
    s.reflections &= !f.no_reflections;
    s.transparency &= !f.no_transparency;
    s.textures &= !f.no_textures;
    s.interpolate_normals |= f.interpolate_normals;
    if let Some(t) = f.texture_filter {
        s.texture_filter = match t {
            FilterArg::Nearest => TextureFilter::Nearest,
            FilterArg::Bilinear => TextureFilter::Bilinear,
        };
    }
    s.validate()?;
    Ok((scene, s))
}

fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    if threads == Some(0) {
        bail!("--threads must be at least 1");
    }
    Ok(rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()?)
}

fn cmd_render(args: RenderArgs) -> Result<()> {
    let format = Format::from_path(&args.output)?;
    if args.aov.is_some() && !format.is_float() {
        bail!(
            "{}: AOVs are float data; write them to .exr or .pfm",
            args.output.display()
        );
    }
    let (scene, settings) = load(&args.scene)?;
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
    let stats = scene.bvh_stats();
    let summary = |what: &str| {
        format!(
            "{}: {} triangles, BVH {:.1} ms ({} levels), {what} -> {}",
            scene.name,
            scene.triangle_count(),
            scene.build_time.as_secs_f64() * 1e3,
            stats.levels,
            args.output.display()
        )
    };
    if let Some(aov) = args.aov {
        let aov = match aov {
            AovArg::Depth => Aov::Depth,
            AovArg::Position => Aov::Position,
            AovArg::Normal => Aov::Normal,
            AovArg::Albedo => Aov::Albedo,
            AovArg::PrimId => Aov::PrimId,
            AovArg::NodesVisited => Aov::NodesVisited,
        };
        let start = std::time::Instant::now();
        let img = pool.install(|| render_aov(&scene, &settings, aov, &progress));
        bar.finish_and_clear();
        write_image(&img, &args.output, encoding)?;
        eprintln!(
            "{}",
            summary(&format!("AOV in {:.1} ms", start.elapsed().as_secs_f64() * 1e3))
        );
        return Ok(());
    }
    let out = pool.install(|| render(&scene, &settings, &progress));
    bar.finish_and_clear();
    write_image(&out.film.to_image(), &args.output, encoding)
        .with_context(|| format!("writing {}", args.output.display()))?;
    eprintln!(
        "{}",
        summary(&format!(
            "render {:.1} ms, {:.2} Mrays/s",
            out.elapsed.as_secs_f64() * 1e3,
            out.mrays_per_second()
        ))
    );
    Ok(())
}

fn cmd_debug(args: DebugArgs) -> Result<()> {
    let (scene, settings) = load(&args.scene)?;
    let (x, y) = args.pixel;
    if x >= settings.width || y >= settings.height {
        bail!(
            "pixel {x},{y} is outside the {}x{} image",
            settings.width,
            settings.height
        );
    }
    let mut tree = RayTree::default();
    let color = trace_pixel(&scene, &settings, x, y, &mut tree);
    let json = serde_json::json!({
        "scene": scene.name,
        "pixel": [x, y],
        "color": color.to_array(),
        "rays": tree.rays,
    });
    println!("{}", serde_json::to_string_pretty(&json)?);
    Ok(())
}
