//! Image writers (PNG, OpenEXR, PFM), all atomic: the image goes to a temporary file beside
//! the target, which is renamed over it only when complete, so an existing file is replaced
//! only by a whole new one and a failed write leaves nothing behind ([`write_file`], which
//! the command line's other outputs use too).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::film::FloatImage;

/// How 8-bit output maps linear values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Encoding {
    /// The course's look: clamp to `[0, 1]`, times 255.
    #[default]
    Linear,
    /// The sRGB transfer curve, for viewing on a calibrated display.
    Srgb,
}

/// Image file formats, chosen by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// 8-bit PNG.
    Png,
    /// 32-bit float OpenEXR.
    Exr,
    /// 32-bit float Portable Float Map.
    Pfm,
}

impl Format {
    /// The format for `path`'s extension.
    pub fn from_path(path: &Path) -> Result<Format> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(Format::Png),
            Some("exr") => Ok(Format::Exr),
            Some("pfm") => Ok(Format::Pfm),
            _ => Err(Error::Invalid(format!("{}: unknown image format; use .png, .exr or .pfm", path.display()))),
        }
    }

    /// Whether it stores floats (needed for AOVs).
    pub fn is_float(self) -> bool {
        self != Format::Png
    }
}

/// Write `img` to `path` in the format its extension names, atomically (see [`write_file`]).
pub fn write_image(img: &FloatImage, path: &Path, encoding: Encoding) -> Result<()> {
    let format = Format::from_path(path)?;
    write_file(path, |w| match format {
        Format::Png => write_png(img, w, encoding),
        Format::Pfm => write_pfm(img, w),
        Format::Exr => write_exr(img, w),
    })
}

/// Write a file atomically: `write` fills a temporary file beside the target, which is renamed
/// over it only when complete. A symbolic link is written through: the file it names is
/// replaced (beside itself), the link stays. An existing file keeps its permissions, and one
/// the user may not write is refused rather than replaced (renaming only needs the folder to
/// be writable, which would let anyone replace another user's read-only file in a shared
/// folder such as `/tmp`).
pub fn write_file(path: &Path, write: impl FnOnce(&mut BufWriter<&File>) -> std::io::Result<()>) -> Result<()> {
    let target = link_target(path).map_err(|e| Error::io(path, e))?;
    let existing = match std::fs::metadata(&target) {
        Ok(m) => Some(m),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(Error::io(path, e)),
    };
    if let Some(m) = &existing {
        check_replaceable(&target, m).map_err(|e| Error::io(path, e))?;
    }
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    // Errors name the output path the user gave, not the hidden temporary file, and carry
    // the operating system's message once.
    let fail = |e: std::io::Error| Error::io(path, os_error(e));
    let tmp = tempfile::Builder::new().prefix(".rayscope-").suffix(".partial").tempfile_in(dir).map_err(fail)?;
    // Temporary files are private (0600); the file is an ordinary one, or keeps the mode of
    // the file it replaces.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = existing.as_ref().map_or(0o644, |m| m.permissions().mode() & 0o7777);
        tmp.as_file().set_permissions(std::fs::Permissions::from_mode(mode)).map_err(fail)?;
    }
    {
        let mut w = BufWriter::new(tmp.as_file());
        write(&mut w).map_err(fail)?;
        w.flush().map_err(fail)?;
    }
    tmp.as_file().sync_all().map_err(fail)?;
    tmp.persist(&target).map_err(|e| fail(e.error))?;
    Ok(())
}

/// The file `path` names after following symbolic links (a dangling link's target, which the
/// write creates), so that the image replaces the target and the link stays a link.
fn link_target(path: &Path) -> std::io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    // Linux's limit on links followed in one lookup; more is a loop.
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let to = std::fs::read_link(&p)?;
                p = match p.parent() {
                    Some(dir) => dir.join(to),
                    None => to,
                };
            }
            _ => return Ok(p),
        }
    }
    Err(std::io::Error::other("too many levels of symbolic links"))
}

/// Whether the existing file `target` may be replaced: it must be a regular file that the
/// user could write in place. Opening it for writing (without truncating, so nothing changes)
/// asks the system itself, which knows owners, groups, ACLs, read-only mounts and root.
fn check_replaceable(target: &Path, meta: &std::fs::Metadata) -> std::io::Result<()> {
    if !meta.is_file() {
        return Err(std::io::Error::other("exists and is not a regular file; not replaced"));
    }
    std::fs::OpenOptions::new().write(true).open(target).map(drop).map_err(|e| {
        if e.kind() == std::io::ErrorKind::PermissionDenied {
            std::io::Error::new(e.kind(), "exists and is not writable by you; not replaced")
        } else {
            os_error(e)
        }
    })
}

/// `e` without the note that `tempfile` appends to its errors (` at path ".rayscope-….partial"`),
/// which names its hidden temporary file rather than the output.
fn os_error(e: std::io::Error) -> std::io::Error {
    if e.raw_os_error().is_some() {
        return e;
    }
    match e.to_string().split_once(" at path ") {
        Some((message, _)) => std::io::Error::new(e.kind(), message.to_string()),
        None => e,
    }
}

/// The 8-bit level of a linear value `v` (NaN is 0), as the PNG writer stores it.
pub(crate) fn to_u8(v: f32, encoding: Encoding) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let v = match encoding {
        Encoding::Linear => v,
        Encoding::Srgb if v <= 0.003_130_8 => 12.92 * v,
        Encoding::Srgb => 1.055 * v.powf(1.0 / 2.4) - 0.055,
    };
    (v * 255.0).round() as u8
}

/// 8-bit RGB (or grey) bytes of `img`, rows from the top.
pub fn to_rgb8(img: &FloatImage, encoding: Encoding) -> Vec<u8> {
    img.data.iter().map(|&v| to_u8(v, encoding)).collect()
}

fn write_png(img: &FloatImage, w: &mut impl Write, encoding: Encoding) -> std::io::Result<()> {
    use image::ImageEncoder;
    let color = if img.channels == 1 { image::ExtendedColorType::L8 } else { image::ExtendedColorType::Rgb8 };
    image::codecs::png::PngEncoder::new(w)
        .write_image(&to_rgb8(img, encoding), img.width, img.height, color)
        .map_err(std::io::Error::other)
}

fn write_pfm(img: &FloatImage, w: &mut impl Write) -> std::io::Result<()> {
    // PFM: "PF" (RGB) or "Pf" (grey), size, scale (negative: little-endian), rows bottom-up.
    let tag = if img.channels == 1 { "Pf" } else { "PF" };
    write!(w, "{tag}\n{} {}\n-1.0\n", img.width, img.height)?;
    let row = (img.width * img.channels) as usize;
    for y in (0..img.height as usize).rev() {
        for v in &img.data[y * row..(y + 1) * row] {
            w.write_all(&v.to_le_bytes())?;
        }
    }
    Ok(())
}

fn write_exr(img: &FloatImage, w: &mut (impl Write + std::io::Seek)) -> std::io::Result<()> {
    use exr::prelude::*;
    let size = (img.width as usize, img.height as usize);
    let result = if img.channels == 1 {
        let channel = AnyChannel::new("Y", FlatSamples::F32(img.data.clone()));
        Image::from_channels(size, AnyChannels::sort(SmallVec::from_vec(vec![channel]))).write().to_buffered(w)
    } else {
        let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
            let px = img.pixel(p.0 as u32, p.1 as u32);
            (px[0], px[1], px[2])
        });
        Image::from_channels(size, channels).write().to_buffered(w)
    };
    result.map_err(std::io::Error::other)
}

/// Read a PFM file (as written by [`write_image`]) back, for tests and tools.
pub fn read_pfm(path: &Path) -> Result<FloatImage> {
    parse_pfm(&std::fs::read(path).map_err(|e| Error::io(path, e))?, path)
}

/// Parse the bytes of a PFM file; `path` names it in errors.
pub fn parse_pfm(bytes: &[u8], path: &Path) -> Result<FloatImage> {
    let bad = |m: &str| Error::parse(path, None, m.to_string());
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos {
            return Err(bad("truncated header"));
        }
        fields.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
    }
    // One whitespace byte ends the header: a file that stops at the scale is cut short.
    if pos == bytes.len() {
        return Err(bad("truncated header"));
    }
    let data = &bytes[pos + 1..];
    let channels = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(bad("not a PFM file")),
    };
    let width: u32 = fields[1].parse().map_err(|_| bad("bad width"))?;
    let height: u32 = fields[2].parse().map_err(|_| bad("bad height"))?;
    let scale: f32 = fields[3].parse().map_err(|_| bad("bad scale"))?;
    // Sizes in u128, which no header's product overflows: the data must be in the file before
    // anything is allocated or sliced for it.
    let n = u128::from(width) * u128::from(height) * u128::from(channels);
    if n > (data.len() / 4) as u128 {
        return Err(bad("truncated data"));
    }
    let n = n as usize;
    let vals: Vec<f32> = data[..4 * n]
        .chunks_exact(4)
        .map(|c| {
            let b = [c[0], c[1], c[2], c[3]];
            if scale < 0.0 { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) }
        })
        .collect();
    // Rows are flipped in time proportional to the pixels: an empty image of 800 million rows
    // (width 0) is read at once, not row by row.
    let row = width as usize * channels as usize;
    let data = if row == 0 { Vec::new() } else { vals.chunks_exact(row).rev().flatten().copied().collect() };
    Ok(FloatImage { width, height, channels, data })
}
