//! The mesh file formats, told apart by their extension: Wavefront OBJ ([`super::obj`]),
//! Stanford PLY ([`super::ply`]) and glTF 2.0 ([`super::gltf`]), each read into the same
//! groups and materials; glTF adds embedded textures, a camera and lights.

use std::path::Path;

use super::gltf::load_gltf;
use super::obj::{ObjFile, load_obj};
use super::ply::load_ply;
use crate::camera::CameraDesc;
use crate::error::Result;
use crate::light::Light;
use crate::material::Texture;

/// A mesh file's format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (and its MTL files).
    Obj,
    /// Stanford PLY.
    Ply,
    /// glTF 2.0, as JSON (`.gltf`) or binary (`.glb`).
    Gltf,
}

/// The extensions of the mesh files rayscope reads (lower case).
pub const MESH_EXTENSIONS: &[&str] = &["obj", "ply", "gltf", "glb"];

impl MeshFormat {
    /// The format of the file at `path` by its extension (any case); `None` for another.
    pub fn of(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply),
            "gltf" | "glb" => Some(MeshFormat::Gltf),
            _ => None,
        }
    }
}

/// What a mesh file gives: the groups and materials, and from glTF its embedded textures
/// (a material's `texture` indexes them), camera, lights and structure.
#[derive(Clone, Debug, Default)]
pub struct MeshFile {
    /// The groups, materials, positions and warnings.
    pub file: ObjFile,
    /// Textures decoded from the file (glTF); OBJ's are named by path in its materials.
    pub textures: Vec<Texture>,
    /// The file's camera (glTF).
    pub camera: Option<CameraDesc>,
    /// The file's lights (glTF).
    pub lights: Vec<Light>,
    /// The file's structure, one line each (glTF), for the debugger.
    pub outline: Vec<String>,
}

/// Load the mesh file at `path` by its format; a file of another extension is read as OBJ
/// (as it always was).
pub fn load_mesh_file(path: &Path) -> Result<MeshFile> {
    match MeshFormat::of(path) {
        Some(MeshFormat::Ply) => Ok(MeshFile { file: load_ply(path)?, ..MeshFile::default() }),
        Some(MeshFormat::Gltf) => load_gltf(path),
        Some(MeshFormat::Obj) | None => Ok(MeshFile { file: load_obj(path)?, ..MeshFile::default() }),
    }
}
