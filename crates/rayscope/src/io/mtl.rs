//! Wavefront MTL material libraries, read here rather than by `tobj` (whose reader panics on
//! a colour of one value, which the format allows, and takes texture options for part of the
//! file name).
//!
//! What is read: `newmtl`, `Kd`, `Ks`, `Ns`, `d` and `map_Kd`; `Ka`, `Ke`, `Tf`, `Ni` and `Tr`
//! are checked but unused; other statements are ignored. A colour is one number (r = g = b, as
//! the format says) or three; two numbers, or the format's `spectral` and `xyz` forms, are
//! errors. Texture statements take the format's options (`-o u [v [w]]`, `-s ...`, `-t ...`,
//! `-mm base gain`, `-blendu on`, ...) before the file name, which is the rest of the line.
//! Colours are not negative and a dissolve `d` lies in [0, 1] (as a scene file's
//! `transparency`): other values are errors at their line, not clamped.

use std::path::{Path, PathBuf};

use super::lines::Lines;
use crate::error::{Error, Result};
use crate::material::Material;
use crate::math::Vec3;

/// A material read from an MTL file, with the texture it names (not yet loaded).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjMaterial {
    /// The Phong parameters (its `texture` is unset).
    pub material: Material,
    /// `map_Kd`, resolved against the MTL file's folder.
    pub texture: Option<PathBuf>,
}

/// Parse MTL text; `path` names it in errors and is where texture names are resolved from.
/// Statements before the first `newmtl` belong to no material and are dropped. (For the unit
/// tests: files are read by [`read_mtl`].)
#[cfg(test)]
pub fn parse_mtl(text: &str, path: &Path) -> Result<Vec<ObjMaterial>> {
    read_mtl(Lines::Text(text), path)
}

/// Read the materials of an MTL file's lines; `path` names it in errors and is where texture
/// names are resolved from. Statements before the first `newmtl` belong to no material and
/// are dropped.
pub fn read_mtl(lines: Lines, path: &Path) -> Result<Vec<ObjMaterial>> {
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut out: Vec<ObjMaterial> = Vec::new();
    // A nameless material that takes the statements before the first `newmtl`.
    let mut loose = ObjMaterial { material: Material::default(), texture: None };
    lines.for_each(path, |line_no, line| {
        let err = |message: String| Error::parse(path, Some(line_no), message);
        let mut words = line.split_whitespace();
        let Some(head) = words.next() else { return Ok(()) };
        let args: Vec<&str> = words.collect();
        if head == "newmtl" {
            if args.is_empty() {
                return Err(err("newmtl names no material".into()));
            }
            // The rest of the line, inner spaces kept, as `usemtl` names it.
            let name = line.trim_start()["newmtl".len()..].trim().to_string();
            out.push(ObjMaterial { material: Material { name, ..Material::default() }, texture: None });
            return Ok(());
        }
        let current = out.last_mut().unwrap_or(&mut loose);
        let m = &mut current.material;
        match head {
            "Kd" => m.kd = color(&args).map_err(err)?,
            "Ks" => m.ks = color(&args).map_err(err)?,
            "Ka" | "Ke" | "Tf" => {
                color(&args).map_err(err)?;
            }
            "Ns" => m.shininess = number(&args).map_err(err)?,
            // `d -halo 0.5`: the halo form's factor is read as plain dissolve.
            "d" => m.transparency = dissolve(args.strip_prefix(&["-halo"]).unwrap_or(&args)).map_err(err)?,
            "Ni" => {
                number(&args).map_err(err)?;
            }
            "Tr" => {
                // Some exporters write two numbers ("Tr 0 0"); both are checked, none used.
                if args.len() == 2 {
                    number(&args[1..]).map_err(err)?;
                }
                number(&args[..args.len().min(1)]).map_err(err)?;
            }
            "map_Kd" => current.texture = Some(dir.join(texture_file(&args).map_err(err)?)),
            _ => {}
        }
        Ok(())
    })?;
    Ok(out)
}

/// A colour statement's value: one number (grey) or three, none negative.
fn color(args: &[&str]) -> Result<Vec3, String> {
    let c = match args {
        [v] => Vec3::splat(finite(v)?),
        [r, g, b] => Vec3::new(finite(r)?, finite(g)?, finite(b)?),
        ["spectral" | "xyz", ..] => return Err(format!("'{}' colours are not supported; give r g b", args[0])),
        _ => return Err(format!("expected 1 number (grey) or 3 (r g b), found {}", args.len())),
    };
    if c.min_element() < 0.0 {
        return Err(format!("a colour cannot be negative, found {}", args.join(" ")));
    }
    Ok(c)
}

/// A dissolve (`d`): opacity, from 0 (transparent) to 1 (opaque).
fn dissolve(args: &[&str]) -> Result<f32, String> {
    let d = number(args)?;
    if !(0.0..=1.0).contains(&d) {
        return Err(format!("a dissolve lies in [0, 1], found {d}"));
    }
    Ok(d)
}

/// A statement's single number.
fn number(args: &[&str]) -> Result<f32, String> {
    match args {
        [v] => finite(v),
        _ => Err(format!("expected 1 number, found {}", args.len())),
    }
}

fn finite(word: &str) -> Result<f32, String> {
    match word.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("'{word}' is not a finite number")),
        Err(_) => Err(format!("'{word}' is not a number")),
    }
}

/// The file name of a texture statement (`map_Kd [options] file`): the options are skipped
/// with their arguments, and the rest of the line is the name.
fn texture_file(args: &[&str]) -> Result<String, String> {
    let mut rest = args;
    while let [option, after @ ..] = rest {
        if !option.starts_with('-') {
            break;
        }
        // The options of the MTL format and how many arguments each takes (at least, at most).
        let (min, max) = match *option {
            "-blendu" | "-blendv" | "-bm" | "-boost" | "-cc" | "-clamp" | "-imfchan" | "-texres" | "-type" => (1, 1),
            "-mm" => (2, 2),
            "-o" | "-s" | "-t" => (1, 3),
            _ => return Err(format!("unknown texture option '{option}'")),
        };
        // Optional arguments are numbers; the first word that is not one is the file name.
        let numeric = after.iter().take(max).take_while(|w| w.parse::<f32>().is_ok()).count();
        let taken = if min == max { min } else { numeric };
        if taken < min || after.len() < taken {
            return Err(format!("texture option '{option}' needs {min} argument(s) and a file name after them"));
        }
        rest = &after[taken..];
    }
    if rest.is_empty() {
        return Err("the texture statement names no file".into());
    }
    Ok(rest.join(" "))
}
