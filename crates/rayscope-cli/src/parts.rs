//! The command line's partial films: `render --part K/N` (a part of a render, for many
//! machines), `render --progressive --checkpoint` and `--resume` (a render saved as it goes
//! and continued), and `merge` (parts into the image). The library does the work
//! (`rayscope::partial`); this maps flags onto it and names the files in messages.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use rayscope::film::Film;
use rayscope::output::{Encoding, write_image};
use rayscope::partial::file::{read_partial, write_partial};
use rayscope::partial::fingerprint::Fingerprint;
use rayscope::partial::merge::merge_parts;
use rayscope::partial::part::{Part, Split};
use rayscope::partial::{Checkpoint, PartialFilm, Portion};
use rayscope::settings::RenderSettings;

use crate::SceneArgs;

/// `--part K/N`: part K (from 0) of N.
pub fn parse_part(s: &str) -> Result<(u32, u32), String> {
    let (k, n) = s.split_once('/').ok_or("expected K/N, as 0/4 (K from 0 to N-1)")?;
    let p = |v: &str| v.trim().parse::<u32>().map_err(|_| format!("'{v}' is not a whole number"));
    let (k, n) = (p(k)?, p(n)?);
    Part::new(k, n, Split::Samples).map_err(|e| e.to_string())?;
    Ok((k, n))
}

/// The flags of `render` for parts and checkpoints.
#[derive(Args, Clone, Debug, Default)]
pub struct PartArgs {
    /// Render part K (0 to N-1, as SLURM_ARRAY_TASK_ID and JOB_COMPLETION_INDEX count) of N
    /// parts of the render, into a partial film (-o PART.exr) for `rayscope merge`.
    #[arg(long, value_name = "K/N", value_parser = parse_part, conflicts_with = "progressive")]
    pub part: Option<(u32, u32)>,
    /// How --part splits the render: by sample index (each part an unbiased image) or by
    /// tiles of 32x32 pixels dealt out in turn [default: samples].
    #[arg(long, value_enum, value_name = "samples|tiles", requires = "part")]
    pub split: Option<Split>,
    /// With --progressive and --target-spp: save the render's state to this partial film
    /// (.exr) as it goes, every --checkpoint-every seconds, at the end and on Ctrl-C; resume
    /// it with --resume.
    #[arg(long, value_name = "FILE.exr", requires = "progressive")]
    pub checkpoint: Option<PathBuf>,
    /// Seconds between checkpoints [default: 60].
    #[arg(long, value_name = "SECONDS", requires = "checkpoint")]
    pub checkpoint_every: Option<f64>,
    /// Continue the progressive render saved in this checkpoint (give the same scene and
    /// options; it keeps saving to the same file): it ends with the same bits as a render
    /// never stopped.
    #[arg(long, value_name = "FILE.exr", conflicts_with = "part")]
    pub resume: Option<PathBuf>,
}

/// Seconds between checkpoints when --checkpoint-every is not given.
pub const DEFAULT_CHECKPOINT_SECONDS: f64 = 60.0;

/// The fingerprint of rendering `args`' scene with `settings`: the scene file's bytes (or a
/// built-in's name) and the flags that change the scene.
pub fn fingerprint(args: &SceneArgs, settings: &RenderSettings) -> Result<Fingerprint> {
    let path = Path::new(&args.scene);
    let mut hash = Fnv::default();
    if path.is_file() {
        hash.add(
            &std::fs::read(path).with_context(|| format!("{}: reading the scene to fingerprint it", path.display()))?,
        );
    } else {
        hash.add(args.scene.as_bytes());
    }
    let f = &args.settings;
    let scene_flags = format!("{:?} {:?} {:?}", f.camera_end, f.interpolation.map(|i| i.name()), args.environment);
    hash.add(scene_flags.as_bytes());
    Ok(Fingerprint::new(&args.scene, &hash.hex(), settings))
}

/// FNV-1a, twice (two offsets) for 128 bits: a fingerprint, not a defence against forgery.
struct Fnv([u64; 2]);

impl Default for Fnv {
    fn default() -> Self {
        Fnv([0xcbf2_9ce4_8422_2325, 0x6c62_272e_07bb_0142])
    }
}

impl Fnv {
    fn add(&mut self, bytes: &[u8]) {
        for h in &mut self.0 {
            for &b in bytes {
                *h = (*h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    }

    fn hex(&self) -> String {
        format!("{:016x}{:016x}", self.0[0], self.0[1])
    }
}

/// Write the partial film of `part` to `path` (which must be .exr).
pub fn write_part(path: &Path, fingerprint: Fingerprint, part: Part, film: Film) -> Result<()> {
    check_exr(path, "--part")?;
    write_partial(&PartialFilm { fingerprint, portion: Portion::Part(part), film }, path)?;
    Ok(())
}

/// Check that `path` names an .exr file (what `flag` writes).
pub fn check_exr(path: &Path, flag: &str) -> Result<()> {
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        bail!("{}: {flag} writes a partial film, an OpenEXR file: name it .exr", path.display());
    }
    Ok(())
}

/// A checkpoint to continue: its film and frames, after checking that it belongs to this
/// render (`fingerprint`, `target_spp`), or an error saying what differs.
pub fn load_checkpoint(path: &Path, fingerprint: &Fingerprint, target_spp: Option<u32>) -> Result<(Film, u32)> {
    let saved = read_partial(path)?;
    let Portion::Checkpoint(c) = saved.portion else {
        bail!("{}: a part of a split render, not a checkpoint (merge it with `rayscope merge`)", path.display());
    };
    let mut differences = saved.fingerprint.differences(fingerprint);
    if c.target_spp != target_spp {
        let show = |t: Option<u32>| t.map_or("none".to_string(), |t| t.to_string());
        differences.push(format!("--target-spp ({} against {})", show(c.target_spp), show(target_spp)));
    }
    if !differences.is_empty() {
        bail!(
            "{}: a checkpoint of another render; it differs from this one in {}",
            path.display(),
            differences.join(", ")
        );
    }
    Ok((saved.film, c.frames))
}

/// Save a progressive render's state to `path`.
pub fn save_checkpoint(path: &Path, fingerprint: &Fingerprint, checkpoint: Checkpoint, film: &Film) -> Result<()> {
    let partial =
        PartialFilm { fingerprint: fingerprint.clone(), portion: Portion::Checkpoint(checkpoint), film: film.clone() };
    write_partial(&partial, path)?;
    Ok(())
}

/// `rayscope merge`'s flags.
#[derive(Args)]
pub struct MergeArgs {
    /// The partial films of every part of one render (from `render --part K/N`).
    #[arg(required = true, value_name = "PART.exr")]
    parts: Vec<PathBuf>,
    /// The image; the format follows the extension (.png, .exr, .pfm).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Apply the sRGB curve to PNG output (as `render --srgb`).
    #[arg(long)]
    srgb: bool,
}

/// `rayscope merge`: check the parts make one render, add them, write the image (with the
/// render's bloom, as `render` would).
pub fn cmd_merge(args: MergeArgs) -> Result<()> {
    rayscope::output::Format::from_path(&args.output)?;
    let start = std::time::Instant::now();
    let parts: Vec<(PathBuf, PartialFilm)> =
        args.parts.iter().map(|p| Ok((p.clone(), read_partial(p)?))).collect::<Result<_>>()?;
    let film = merge_parts(&parts)?;
    let settings = parts[0].1.fingerprint.render_settings().with_context(|| {
        format!("{}: the settings in its fingerprint are not this rayscope's", parts[0].0.display())
    })?;
    let mut image = film.to_image();
    rayscope::post::bloom::apply_to_image(&mut image, &settings.bloom);
    let encoding = if args.srgb { Encoding::Srgb } else { Encoding::Linear };
    write_image(&image, &args.output, encoding)?;
    eprintln!(
        "merged {} of {} ({}x{}, {} spp) in {:.1} ms -> {}",
        parts.len(),
        parts[0].1.fingerprint.scene,
        film.width(),
        film.height(),
        film.sample_range().1,
        start.elapsed().as_secs_f64() * 1e3,
        args.output.display()
    );
    if film.dropped() > 0 {
        eprintln!("warning: {} samples were not finite and were added as black", film.dropped());
    }
    Ok(())
}
