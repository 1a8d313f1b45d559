//! `rayscope compare THEIRS SCENE [render options] -o DIFF.png`: render the scene as `render`
//! would, compare a student's image with it, print how many pixels differ and by how much,
//! and write the difference image. The exit status follows `diff` and `cmp`: 0 when no pixel
//! differs, 1 when some do, 2 on trouble.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::Args;
use rayscope::compare::{CompareImage, Comparison, SSIM_SIGMA, SSIM_WINDOW, compare, read_image};
use rayscope::output::{Encoding, Format, write_image};
use rayscope::render::render;

use super::{SceneArgs, SettingsArgs, load, thread_pool};

/// The exit status when the images differ (`diff`'s and `cmp`'s).
pub const EXIT_DIFFERENT: u8 = 1;

/// The exit status of a `compare` that failed (a bad file, sizes that do not match, a bad
/// flag): `diff`'s and `cmp`'s "trouble", apart from [`EXIT_DIFFERENT`].
pub const EXIT_TROUBLE: u8 = 2;

#[derive(Args)]
pub(crate) struct CompareArgs {
    /// Their image: PNG or BMP (8-bit), OpenEXR (float).
    #[arg(value_name = "THEIRS")]
    theirs: PathBuf,
    #[command(flatten)]
    scene: SceneArgs,
    /// Write the difference image here (.png, .exr or .pfm): black where the pixels are
    /// equal, a heat ramp by the error elsewhere.
    #[arg(short, long, value_name = "DIFF")]
    output: Option<PathBuf>,
    /// Also write our render here.
    #[arg(long, value_name = "FILE")]
    ours: Option<PathBuf>,
    /// Our render as 8-bit with the sRGB curve (as `render --srgb`), for an image that was
    /// written with it; default the course's linear clamp.
    #[arg(long)]
    srgb: bool,
}

/// Render, compare, report, write; the exit status says whether the images differ.
pub(crate) fn cmd_compare(mut args: CompareArgs) -> Result<ExitCode> {
    for out in [&args.output, &args.ours].into_iter().flatten() {
        Format::from_path(out)?;
    }
    let theirs = read_image(&args.theirs)?;
    let (width, height) = (theirs.image.width, theirs.image.height);
    take_size(&args.theirs, &theirs, &mut args.scene.settings);
    let (scene, settings) = load(&args.scene)?;
    if (settings.width, settings.height) != (width, height) {
        bail!(
            "{} is {width}x{height} pixels but the render is {}x{} (--width/--height): only images of the same size \
             can be compared; leave out --width and --height to render at their image's size",
            args.theirs.display(),
            settings.width,
            settings.height
        );
    }
    let pool = thread_pool(args.scene.threads)?;
    let out = pool.install(|| render(&scene, &settings, &|_| {}));
    let mut image = out.film.to_image();
    // Ours as `rayscope render` writes it: with bloom when it is on.
    rayscope::post::bloom::apply_to_image(&mut image, &settings.bloom);
    if let Some(path) = &args.ours {
        write_image(&image, path, encoding(args.srgb))?;
    }
    let ours = CompareImage::from_render(
        &image,
        theirs.depth,
        encoding(args.srgb),
        format!("rayscope's render of {}", scene.name),
    );
    let c = compare(&theirs, &ours)?;
    print!("{}", report(&c));
    if let Some(path) = &args.output {
        write_image(&c.difference_image(), path, Encoding::Linear)?;
    }
    note_written(&args.ours, "our render");
    note_written(&args.output, "the difference image");
    Ok(if c.differing == 0 { ExitCode::SUCCESS } else { ExitCode::from(EXIT_DIFFERENT) })
}

/// Render at the size of their image, unless the flags give one (and say so): a scene's own
/// size is 800x800, and few projects render at exactly that.
fn take_size(path: &Path, theirs: &CompareImage, flags: &mut SettingsArgs) {
    let (width, height) = (theirs.image.width, theirs.image.height);
    if flags.width.is_none() && flags.height.is_none() {
        (flags.width, flags.height) = (Some(width), Some(height));
        eprintln!("rendering at {width}x{height}, the size of {}", path.display());
    }
}

/// For `view --compare`: read their image (so that a bad file is reported on the terminal)
/// and take its size as [`cmd_compare`] does.
#[cfg_attr(not(feature = "viewer"), allow(dead_code, reason = "`view` needs the viewer"))]
pub(crate) fn size_from(path: &Path, flags: &mut SettingsArgs) -> Result<()> {
    take_size(path, &read_image(path)?, flags);
    Ok(())
}

fn encoding(srgb: bool) -> Encoding {
    if srgb { Encoding::Srgb } else { Encoding::Linear }
}

fn note_written(path: &Option<PathBuf>, what: &str) {
    if let Some(p) = path.as_deref().map(Path::display) {
        eprintln!("wrote {what} to {p}");
    }
}

/// The report on stdout: the `N of M pixels differ` line, then the errors (in `[0, 1]`
/// units and in 8-bit levels) and the SSIM.
pub(crate) fn report(c: &Comparison) -> String {
    let errors = |e: &rayscope::compare::ChannelErrors| {
        format!(
            "{:.6} ({:.2} levels of 255); R {:.6}, G {:.6}, B {:.6}",
            e.overall,
            e.overall * 255.0,
            e.rgb[0],
            e.rgb[1],
            e.rgb[2]
        )
    };
    let ssim = match c.ssim {
        Some(s) => format!("{s:.6} (1 = identical)"),
        None => format!("n/a (the image is smaller than the {SSIM_WINDOW}x{SSIM_WINDOW} window)"),
    };
    format!(
        "{}\nmean error: {}\nmax error: {}\nSSIM: {ssim} on luminance, Gaussian {SSIM_WINDOW}x{SSIM_WINDOW} \
         windows (sigma {SSIM_SIGMA})\n",
        c.summary(),
        errors(&c.mean_error),
        errors(&c.max_error)
    )
}
