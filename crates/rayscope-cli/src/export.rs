//! `rayscope scenes --export NAME [--format obj|gltf DIR]`: print a scene as TOML, or write it
//! as mesh files with a TOML scene file beside them ([`rayscope::export`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use rayscope::export::{ExportFormat, export_scene};
use rayscope::scene::{Scene, builtin};

/// Export `name` (a built-in scene, a scene file or a mesh file): as TOML on standard output
/// without a format, else as `format` files into `dir`.
pub fn cmd_export(name: &str, format: Option<ExportFormat>, dir: Option<&Path>) -> Result<()> {
    let (format, dir) = match (format, dir) {
        (None, None) => {
            print!("{}", builtin::scene_desc(name)?.to_toml());
            return Ok(());
        }
        (Some(f), Some(d)) => (f, d),
        (Some(_), None) => bail!("--format needs the folder to write into (scenes --export NAME --format obj DIR)"),
        (None, Some(_)) => bail!("a folder is written only with --format obj|gltf"),
    };
    let scene = Scene::load(name, None).with_context(|| format!("loading {name}"))?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let stem = stem_of(name);
    let exported = export_scene(&scene, format, dir, &stem)?;
    for f in &exported.files {
        println!("{}", f.display());
    }
    eprintln!("render it with: rayscope render {}", exported.scene_file.display());
    Ok(())
}

/// The stem of the exported files: a built-in scene's name, or a file's stem.
fn stem_of(name: &str) -> String {
    let path = PathBuf::from(name);
    match path.file_stem().and_then(|s| s.to_str()) {
        Some(s) if !s.is_empty() && !s.starts_with('.') => s.to_string(),
        _ => "scene".into(),
    }
}
