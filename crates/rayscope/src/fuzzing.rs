//! Entry points of the fuzz targets (`fuzz/fuzz_targets/`) and of the test that replays their
//! corpora (`tests/fuzz_corpus.rs`): each takes one input as bytes and hands it to the
//! functions the real loaders use, so that what the fuzzers find is what a user would meet.
//! None of them may panic; an input the loaders refuse is an `Err`, which is fine.
//!
//! Text and image bytes are parsed in memory. An OBJ file is read the way the command line
//! reads it, from a file (its `mtllib` and `map_Kd` names are files beside it), so the OBJ
//! target writes its input into a private folder ([`FuzzDir`]) first; scene files find a small
//! valid mesh, material library and texture there too.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::file::set_max_file_bytes;
use crate::io::texture::decode_texture;
use crate::output::parse_pfm;
use crate::render::render;
use crate::scene::{LoadContext, Scene, SceneDesc};
use crate::settings::RenderSettings;

/// The largest file a fuzzed input can make the loaders read: inputs are small, and a name
/// that reaches some large file elsewhere on the machine should fail fast, not stall a run.
const MAX_FILE_BYTES: u64 = 1 << 20;

/// The largest image side, depth and sample counts of a fuzzed render: the point is that every
/// accepted scene renders, not how big a render the fuzzer can ask for.
const RENDER_SIDE_CAP: u32 = 8;
/// See [`RENDER_SIDE_CAP`].
const RENDER_DEPTH_CAP: u32 = 4;
/// See [`RENDER_SIDE_CAP`].
const RENDER_SAMPLES_CAP: u32 = 2;

/// What separates the OBJ text, the MTL text and the texture bytes in an [`obj_mtl`] input
/// (NUL is in no text file, and the texture, last, may hold any byte).
pub const PART_SEPARATOR: u8 = 0;

/// A fuzzed OBJ input's file names in [`FuzzDir`]: the seeds' `mtllib` and `map_Kd` name them.
pub const OBJ_NAME: &str = "fuzz.obj";
/// See [`OBJ_NAME`].
pub const MTL_NAME: &str = "fuzz.mtl";
/// See [`OBJ_NAME`].
pub const TEXTURE_NAME: &str = "fuzz.png";

/// The name [`gltf`] writes a JSON glTF input under.
pub const GLTF_NAME: &str = "fuzz.gltf";

/// The name [`gltf`] writes a GLB input under.
pub const GLB_NAME: &str = "fuzz.glb";

/// The name [`ply`] writes its input under.
pub const PLY_NAME: &str = "fuzz.ply";

/// A valid mesh a scene file may name (`path = "cube.obj"`), with its material library and
/// texture (`checker.png`, 2 x 2 texels, written by [`FuzzDir::new`]).
const CUBE_OBJ: &str = "mtllib cube.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl checker\nf 1/1 4/4 3/3 2/2\nf 5/1 6/2 7/3 8/4\nf 1/1 2/2 6/3 5/4\n\
f 4/1 8/2 7/3 3/4\nf 1/1 5/2 8/3 4/4\nf 2/1 3/2 7/3 6/4\n";
/// See [`CUBE_OBJ`].
const CUBE_MTL: &str = "newmtl checker\nKd 0.8 0.8 0.8\nKs 0.2\nNs 20\nd 0.9\nmap_Kd checker.png\n";

/// A private folder holding the files of a fuzzed OBJ input and the fixtures scene files
/// name; removed when dropped.
pub struct FuzzDir {
    dir: tempfile::TempDir,
}

impl FuzzDir {
    /// A new folder with the fixtures (in memory, `/dev/shm`, where there is one). It also caps
    /// the files the loaders read, for the whole process, at a size no input reaches.
    pub fn new() -> Result<FuzzDir> {
        set_max_file_bytes(Some(MAX_FILE_BYTES));
        let shm = Path::new("/dev/shm");
        let parent = if shm.is_dir() { shm.to_path_buf() } else { std::env::temp_dir() };
        let dir =
            tempfile::Builder::new().prefix("rayscope-fuzz-").tempdir_in(&parent).map_err(|e| Error::io(&parent, e))?;
        let out = FuzzDir { dir };
        out.write("cube.obj", CUBE_OBJ.as_bytes())?;
        out.write("cube.mtl", CUBE_MTL.as_bytes())?;
        let checker =
            image::RgbImage::from_fn(2, 2, |x, y| image::Rgb(if (x + y) % 2 == 0 { [255; 3] } else { [0; 3] }));
        let png = out.path().join("checker.png");
        checker.save(&png).map_err(|e| Error::parse(&png, None, e.to_string()))?;
        Ok(out)
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    fn write(&self, name: &str, bytes: &[u8]) -> Result<PathBuf> {
        let path = self.path().join(name);
        std::fs::write(&path, bytes).map_err(|e| Error::io(&path, e))?;
        Ok(path)
    }
}

/// An OBJ file, an MTL file and a texture, split at the first two [`PART_SEPARATOR`]s (missing
/// parts are empty), written as [`OBJ_NAME`], [`MTL_NAME`] and [`TEXTURE_NAME`] and loaded as
/// `rayscope render fuzz.obj` loads them (the scene, BVH and all).
pub fn obj_mtl(dir: &FuzzDir, input: &[u8]) -> Result<Scene> {
    let mut parts = input.splitn(3, |&b| b == PART_SEPARATOR);
    let mut next = || parts.next().unwrap_or_default();
    let obj = dir.write(OBJ_NAME, next())?;
    dir.write(MTL_NAME, next())?;
    dir.write(TEXTURE_NAME, next())?;
    Scene::from_desc(&SceneDesc::for_obj(&obj), &LoadContext { base_dir: dir.path().to_path_buf(), assets: None })
}

/// A glTF file (a GLB when it starts with GLB's magic bytes, else JSON), written as
/// [`GLTF_NAME`] or [`GLB_NAME`] and loaded as `rayscope render fuzz.glb` loads it (camera,
/// lights, the scene, BVH and all); its external buffers and images find the fixtures.
pub fn gltf(dir: &FuzzDir, input: &[u8]) -> Result<Scene> {
    let name = if input.starts_with(b"glTF") { GLB_NAME } else { GLTF_NAME };
    mesh_file(dir, name, input)
}

/// A PLY file, written as [`PLY_NAME`] and loaded as `rayscope render fuzz.ply` loads it.
pub fn ply(dir: &FuzzDir, input: &[u8]) -> Result<Scene> {
    mesh_file(dir, PLY_NAME, input)
}

/// `input` written as `name` in `dir` and loaded as the command line loads a mesh file.
fn mesh_file(dir: &FuzzDir, name: &str, input: &[u8]) -> Result<Scene> {
    let path = dir.write(name, input)?;
    let desc = SceneDesc::for_mesh_file(&path)?;
    Scene::from_desc(&desc, &LoadContext { base_dir: dir.path().to_path_buf(), assets: None })
}

/// Scene file text (TOML), parsed and loaded as `rayscope render scene.toml` does, with the
/// scene file and the asset folder in `dir` (so `path` and `asset` entries find the fixtures).
pub fn scene_file(dir: &FuzzDir, input: &[u8]) -> Result<Scene> {
    let path = dir.path().join("fuzz.toml");
    let text = std::str::from_utf8(input).map_err(|_| Error::parse(&path, None, "not UTF-8"))?;
    let desc = SceneDesc::from_toml(text, &path)?;
    Scene::from_desc(&desc, &LoadContext { base_dir: dir.path().to_path_buf(), assets: Some(dir.path().to_path_buf()) })
}

/// Image bytes through every image reader: the texture decoder (which tells PNG and the other
/// formats by their magic bytes, and refuses those it is not built with) and the PFM reader.
/// Returns how many of the two accepted it.
pub fn image(input: &[u8]) -> usize {
    let path = Path::new("fuzz.img");
    usize::from(decode_texture(input, path).is_ok()) + usize::from(parse_pfm(input, path).is_ok())
}

/// A scene file loaded as by [`scene_file`] and rendered with its `[render]` settings (else
/// the defaults) capped by [`RENDER_SIDE_CAP`] and the like. Returns the image's pixels, which must be finite.
pub fn render_scene(dir: &FuzzDir, input: &[u8]) -> Result<Vec<crate::math::Color>> {
    let scene = scene_file(dir, input)?;
    let asked = scene.render.clone().unwrap_or_default();
    asked.validate()?;
    let settings = RenderSettings {
        width: asked.width.min(RENDER_SIDE_CAP),
        height: asked.height.min(RENDER_SIDE_CAP),
        max_depth: asked.max_depth.min(RENDER_DEPTH_CAP),
        spp: asked.spp.min(RENDER_SAMPLES_CAP),
        light_samples: asked.light_samples.min(RENDER_SAMPLES_CAP),
        gloss_samples: asked.gloss_samples.min(RENDER_SAMPLES_CAP),
        ..asked
    };
    Ok(render(&scene, &settings, &|_| {}).film.pixels())
}
