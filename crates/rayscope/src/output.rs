//! Image writers (PNG, OpenEXR, PFM), all atomic: the image goes to a temporary file beside
//! the target, which is renamed over it only when complete, so an existing file is replaced
//! only by a whole new one and a failed write leaves nothing behind.

use std::io::{BufWriter, Write};
use std::path::Path;

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

/// Write `img` to `path` in the format its extension names, atomically.
pub fn write_image(img: &FloatImage, path: &Path, encoding: Encoding) -> Result<()> {
    let format = Format::from_path(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".rayscope-")
        .suffix(".partial")
        .tempfile_in(dir)
        .map_err(|e| Error::io(dir, e))?;
    // Temporary files are private (0600); the image is an ordinary file.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file().set_permissions(std::fs::Permissions::from_mode(0o644)).map_err(|e| Error::io(path, e))?;
    }
    {
        let mut w = BufWriter::new(tmp.as_file());
        let result = match format {
            Format::Png => write_png(img, &mut w, encoding),
            Format::Pfm => write_pfm(img, &mut w),
            Format::Exr => write_exr(img, &mut w),
        };
        result.map_err(|e| Error::io(path, e))?;
        w.flush().map_err(|e| Error::io(path, e))?;
    }
    tmp.as_file().sync_all().map_err(|e| Error::io(path, e))?;
    tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    Ok(())
}

fn to_u8(v: f32, encoding: Encoding) -> u8 {
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
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
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
    pos += 1;
    let channels = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(bad("not a PFM file")),
    };
    let width: u32 = fields[1].parse().map_err(|_| bad("bad width"))?;
    let height: u32 = fields[2].parse().map_err(|_| bad("bad height"))?;
    let scale: f32 = fields[3].parse().map_err(|_| bad("bad scale"))?;
    let n = (width * height * channels) as usize;
    if bytes.len() < pos + 4 * n {
        return Err(bad("truncated data"));
    }
    let vals: Vec<f32> = bytes[pos..pos + 4 * n]
        .chunks_exact(4)
        .map(|c| {
            let b = [c[0], c[1], c[2], c[3]];
            if scale < 0.0 { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) }
        })
        .collect();
    let row = (width * channels) as usize;
    let data = (0..height as usize).rev().flat_map(|y| vals[y * row..(y + 1) * row].to_vec()).collect();
    Ok(FloatImage { width, height, channels, data })
}
