//! Writing a loaded scene out as mesh files other programs open: Wavefront OBJ with its MTL
//! ([`obj`]) or glTF 2.0 with its `.bin` ([`gltf`]), the textures as PNG files beside them,
//! and a TOML scene file for what the mesh formats do not carry the course's way (the camera,
//! the lights, the spheres, the render settings, motion) that names the mesh file, so that
//! `rayscope render NAME.toml` renders what the scene rendered.
//!
//! Meshes are written in world space (placed, normalised), in their order and with their
//! triangles in order, so the BVH built when the file is read back is the same. A mesh with a
//! motion goes into a file of its own (`NAME-moving-K.obj`), which the scene file gives that
//! motion. Every file is encoded in memory first: a scene that cannot be written leaves no
//! file behind; then each is written atomically ([`crate::output::write_file`]).

pub mod gltf;
pub mod obj;

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::material::{Material, MaterialDesc, Texture};
use crate::motion::MotionPath;
use crate::output::write_file;
use crate::scene::desc::MotionDesc;
use crate::scene::{MeshDesc, Scene, SceneDesc, SphereDesc};

/// The mesh format of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ExportFormat {
    /// Wavefront OBJ + MTL.
    Obj,
    /// glTF 2.0 (`.gltf` JSON + `.bin`).
    Gltf,
}

/// The files an export wrote, the scene file first.
#[derive(Clone, Debug, PartialEq)]
pub struct Exported {
    /// The TOML scene file that loads the export back.
    pub scene_file: PathBuf,
    /// Every file written, the scene file included.
    pub files: Vec<PathBuf>,
}

/// One file to write: its name in the export's folder and its bytes.
pub(crate) struct OutFile {
    pub name: String,
    pub bytes: Vec<u8>,
}

/// The meshes of a scene that share one motion (none, or the same translation), by index.
pub(crate) struct MeshGroup {
    pub motion: Option<MotionPath>,
    pub meshes: Vec<usize>,
}

/// The meshes of `scene` grouped by their motion, the still ones first, in mesh order.
fn group_by_motion(scene: &Scene) -> Vec<MeshGroup> {
    let mut groups: Vec<MeshGroup> = vec![MeshGroup { motion: None, meshes: Vec::new() }];
    for (i, m) in scene.meshes.iter().enumerate() {
        match groups.iter_mut().find(|g| g.motion == m.motion) {
            Some(g) => g.meshes.push(i),
            None => groups.push(MeshGroup { motion: m.motion.clone(), meshes: vec![i] }),
        }
    }
    groups.retain(|g| !g.meshes.is_empty());
    groups
}

/// The textures of a scene written as PNG files named `NAME-texture-K.png`, each once.
pub(crate) struct TextureFiles<'a> {
    scene: &'a Scene,
    stem: String,
    /// The file name of each texture written so far, by texture index.
    names: Vec<Option<String>>,
    /// Whether a written texture is upside down (glTF's rows run the other way).
    flipped: bool,
    files: Vec<OutFile>,
}

impl<'a> TextureFiles<'a> {
    pub(crate) fn new(scene: &'a Scene, stem: &str, flipped: bool) -> Self {
        TextureFiles {
            scene,
            stem: stem.to_string(),
            names: vec![None; scene.textures.len()],
            flipped,
            files: Vec::new(),
        }
    }

    /// The file name of texture `index`, encoding it the first time. Texels are stored as
    /// 8-bit values (the course's textures are 8-bit, and come back exactly; a floating-point
    /// texture's values are clamped to [0, 1] and rounded).
    pub(crate) fn name(&mut self, index: usize) -> Result<String> {
        if let Some(name) = &self.names[index] {
            return Ok(name.clone());
        }
        let name = format!("{}-texture-{index}.png", self.stem);
        let bytes = encode_png(&self.scene.textures[index], self.flipped, &name)?;
        self.files.push(OutFile { name: name.clone(), bytes });
        self.names[index] = Some(name.clone());
        Ok(name)
    }

    pub(crate) fn into_files(self) -> Vec<OutFile> {
        self.files
    }
}

/// A texture as PNG bytes (rows reversed when `flipped`).
fn encode_png(t: &Texture, flipped: bool, name: &str) -> Result<Vec<u8>> {
    let w = t.width as usize;
    let rows: Vec<&[crate::math::Color]> = if w == 0 { Vec::new() } else { t.texels.chunks_exact(w).collect() };
    let ordered: Vec<&[crate::math::Color]> = if flipped { rows.into_iter().rev().collect() } else { rows };
    let bytes: Vec<u8> = ordered
        .into_iter()
        .flatten()
        .flat_map(|c| c.to_array().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
        .collect();
    let img = image::RgbImage::from_raw(t.width, t.height, bytes)
        .ok_or_else(|| Error::Invalid(format!("{name}: the texture's size does not match its texels")))?;
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).map_err(|e| Error::Invalid(format!("{name}: {e}")))?;
    Ok(out.into_inner())
}

/// A material as a scene file writes it: every value, and its texture's file.
pub(crate) fn material_desc(m: &Material, textures: &mut TextureFiles) -> Result<MaterialDesc> {
    Ok(MaterialDesc {
        name: Some(m.name.clone()),
        kd: Some(m.kd),
        ks: Some(m.ks),
        shininess: Some(m.shininess),
        transparency: Some(m.transparency),
        texture: m.texture.map(|t| textures.name(t).map(PathBuf::from)).transpose()?,
        glossiness: m.glossiness,
        model: m.model,
        gradient: m.gradient.as_ref().map(|g| g.keys().to_vec()),
    })
}

/// The names of a scene's materials in a mesh file: their own where unique and on one line,
/// else numbered.
pub(crate) fn material_names(scene: &Scene) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for (i, m) in scene.materials.iter().enumerate() {
        let clean = !m.name.trim().is_empty() && !m.name.contains(['\n', '\r']) && m.name.trim() == m.name;
        let name = if clean && !names.contains(&m.name) { m.name.clone() } else { format!("material-{i}") };
        names.push(name);
    }
    names
}

/// The scene's environment map as the exported scene file names it: the map's file copied
/// beside it (read through the same guards as every input), so the folder is whole.
fn environment_desc(
    scene: &Scene,
    stem: &str,
    files: &mut Vec<OutFile>,
) -> Result<Option<crate::environment::EnvironmentDesc>> {
    let Some(env) = &scene.environment else { return Ok(None) };
    let path = &env.desc.path;
    let mut bytes = Vec::new();
    let mut file = crate::io::file::open(path)?;
    std::io::Read::read_to_end(&mut file, &mut bytes).map_err(|e| file.error(e))?;
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("hdr").to_ascii_lowercase();
    let name = format!("{stem}-environment.{ext}");
    files.push(OutFile { name: name.clone(), bytes });
    Ok(Some(crate::environment::EnvironmentDesc { path: PathBuf::from(name), ..env.desc.clone() }))
}

/// Write `scene` into folder `dir` as `stem.toml` and mesh files of `format` (see the module).
pub fn export_scene(scene: &Scene, format: ExportFormat, dir: &Path, stem: &str) -> Result<Exported> {
    if stem.is_empty() || stem.contains(['/', '\\']) || stem.starts_with('.') {
        return Err(Error::Invalid(format!("'{stem}' cannot name exported files")));
    }
    let mut textures = TextureFiles::new(scene, stem, format == ExportFormat::Gltf);
    let mut files = Vec::new();
    let mut meshes = Vec::new();
    for (k, group) in group_by_motion(scene).into_iter().enumerate() {
        let name = if k == 0 && group.motion.is_none() { stem.to_string() } else { format!("{stem}-moving-{k}") };
        let (mesh_file, mut written) = match format {
            ExportFormat::Obj => obj::write(scene, &group.meshes, &name, &mut textures)?,
            ExportFormat::Gltf => gltf::write(scene, &group.meshes, &name, &mut textures)?,
        };
        files.append(&mut written);
        meshes.push(MeshDesc {
            name: Some(name.clone()),
            path: Some(PathBuf::from(mesh_file)),
            motion: group.motion.as_ref().map(MotionDesc::from),
            ..MeshDesc::default()
        });
    }
    let mut spheres = Vec::new();
    for s in &scene.spheres {
        spheres.push(SphereDesc {
            center: s.center.into(),
            radius: s.radius,
            material: material_desc(&scene.materials[s.material as usize], &mut textures)?,
            motion: s.motion.as_ref().map(MotionDesc::from),
        });
    }
    let desc = SceneDesc {
        name: Some(scene.name.clone()),
        camera: scene.camera.clone(),
        meshes,
        spheres,
        lights: scene.lights.clone(),
        camera_end: scene.camera_end.clone(),
        camera_motion: scene.camera_path.as_ref().map(MotionDesc::from),
        environment: environment_desc(scene, stem, &mut files)?,
        render: scene.render.clone(),
        animation: scene.animation,
    };
    files.append(&mut textures.into_files());
    let scene_name = format!("{stem}.toml");
    files.insert(0, OutFile { name: scene_name.clone(), bytes: desc.to_toml().into_bytes() });
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut written = Vec::new();
    for f in &files {
        let path = dir.join(&f.name);
        write_file(&path, |w| w.write_all(&f.bytes))?;
        written.push(path);
    }
    Ok(Exported { scene_file: dir.join(scene_name), files: written })
}
