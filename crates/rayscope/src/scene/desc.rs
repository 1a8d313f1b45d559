//! Scene descriptions: the TOML scene-file format, and turning a description into a [`Scene`].
//!
//! ```toml
//! name = "my scene"
//! [camera]                      # or kind = "look-at" with eye, target, up, fov
//! kind = "trackball"
//! rotation = [20, 20, 0]
//! aperture = 0.0                # lens radius, depth of field (0: a pinhole)
//! # focus_distance = 3.0        # depth in focus (default: the look-at distance)
//!
//! [[mesh]]
//! path = "bunny.obj"            # relative to this file; or `asset = "..."` in the asset folder
//! normalize = true              # the course's fit into the unit sphere
//! transform = { translate = [0, 0.5, 0], rotate = [0, 90, 0], scale = 1.0 }
//! material = { kd = [0.8, 0.2, 0.2] }   # overrides the MTL's fields that it names
//!
//! [[sphere]]
//! center = [0, 0, 0]
//! radius = 0.5
//! material = { kd = [0.2, 0.2, 0.8], ks = [0.5, 0.5, 0.5], shininess = 50 }
//! # model = "blinn-phong" | "lambert" | "gradient" (default: [render] shading_model, phong);
//! # the gradient model's colours by n.l: gradient = [[0.0, [0.1, 0.1, 0.3]], [0.5, [0.2, 0.2, 0.8]]]
//!
//! [[light]]
//! kind = "point"
//! position = [-1, 1, -1]
//! color = [1, 1, 1]
//!
//! [render]                      # any field of RenderSettings
//! max_depth = 3
//!
//! [animation]                   # render --frames: motion keys are seconds of scene time
//! fps = 24                      # frame F exposes [F / fps, (F + shutter) / fps]
//! frames = "0..48"              # A..B (B excluded) or A..=B
//! shutter = 0.5                 # the part of a frame the shutter is open (180 degrees)
//!
//! [environment]                 # an equirectangular map that rays which miss return
//! path = "sky.hdr"              # .hdr, .exr or .png, 2:1, relative to this file
//! intensity = 1.0
//! rotation = 0                  # degrees about +y
//! ```

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Mesh, Scene, SceneSphere, camera_lens};
use crate::animation::AnimationSettings;
use crate::camera::CameraDesc;
use crate::environment::{Environment, EnvironmentDesc};
use crate::error::{Error, Result};
use crate::gradient::Gradient;
use crate::io::mesh_file::{MeshFile, MeshFormat, load_mesh_file};
use crate::io::obj::{ObjFile, smooth_normals};
use crate::io::texture::load_texture;
use crate::light::Light;
use crate::material::{Material, MaterialDesc, Texture};
use crate::math::{Vec2, Vec3, Vec3A, quat_from_euler_degrees};
use crate::motion::{Interpolation, Keyframe, MotionPath};
use crate::settings::RenderSettings;

/// A whole scene as written in a scene file (and as the built-ins are defined).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// Display name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The camera (default: the course's trackball view).
    #[serde(default)]
    pub camera: CameraDesc,
    /// Triangle meshes.
    #[serde(default, rename = "mesh", skip_serializing_if = "Vec::is_empty")]
    pub meshes: Vec<MeshDesc>,
    /// Spheres.
    #[serde(default, rename = "sphere", skip_serializing_if = "Vec::is_empty")]
    pub spheres: Vec<SphereDesc>,
    /// Lights.
    #[serde(default, rename = "light", skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<Light>,
    /// Where the camera is when the shutter closes (motion blur); `None`: it stands still.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_end: Option<CameraDesc>,
    /// The camera's translation over the exposure (motion blur), instead of `camera_end`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_motion: Option<MotionDesc>,
    /// Render settings the scene asks for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub render: Option<RenderSettings>,
    /// How the scene is animated (`[animation] fps, frames, shutter`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation: Option<AnimationSettings>,
    /// The environment map that rays which miss return (`[environment] path, intensity,
    /// rotation`); `None`: the background colour.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<EnvironmentDesc>,
}

/// A motion during the exposure, a translation: linear from `start` (at shutter open) to
/// `end` (at close), or along keyframes `keys = [[t, [x, y, z]], ...]` with an
/// `interpolation` (`"catmull-rom"`, the default, or `"linear"`). See [`crate::motion`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "MotionFields", into = "MotionFields")]
pub enum MotionDesc {
    /// Today's linear motion.
    Linear {
        /// Translation at shutter open.
        start: Vec3,
        /// Translation at shutter close.
        end: Vec3,
    },
    /// Along keyframes.
    Keys {
        /// The keys, `(time, translation)`, times in seconds of scene time, increasing.
        keys: Vec<Keyframe>,
        /// How the path goes between them.
        interpolation: Interpolation,
    },
}

impl From<&MotionPath> for MotionDesc {
    /// The description that loads back as `path`: today's `start`/`end` form for the linear
    /// motion of two keys at 0 and 1, else its keys.
    fn from(path: &MotionPath) -> MotionDesc {
        match path.as_linear() {
            Some((start, end)) => MotionDesc::Linear { start: start.into(), end: end.into() },
            None => MotionDesc::Keys { keys: path.keys().to_vec(), interpolation: path.interpolation() },
        }
    }
}

impl MotionDesc {
    /// The path this describes (its values were checked by [`MotionDesc::path`]'s errors).
    pub fn path(&self) -> Result<MotionPath, String> {
        match self {
            MotionDesc::Linear { start, end } if !(start.is_finite() && end.is_finite()) => {
                Err("motion translations must be finite".into())
            }
            MotionDesc::Linear { start, end } => MotionPath::linear(*start, *end),
            MotionDesc::Keys { keys, interpolation } => MotionPath::new(keys.clone(), *interpolation),
        }
    }
}

/// A motion table as written: either form's fields, read as a plain struct so that a wrong
/// type or an unknown key is reported by name.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MotionFields {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    start: Option<Vec3>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    end: Option<Vec3>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    keys: Option<Vec<Keyframe>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    interpolation: Option<Interpolation>,
}

impl TryFrom<MotionFields> for MotionDesc {
    type Error = &'static str;

    fn try_from(f: MotionFields) -> Result<MotionDesc, &'static str> {
        match f {
            MotionFields { start, end: Some(end), keys: None, interpolation: None } => {
                Ok(MotionDesc::Linear { start: start.unwrap_or_default(), end })
            }
            MotionFields { start: None, end: None, keys: Some(keys), interpolation } => {
                Ok(MotionDesc::Keys { keys, interpolation: interpolation.unwrap_or_default() })
            }
            MotionFields { keys: Some(_), .. } => {
                Err("a motion has `keys` (and `interpolation`) or `start` and `end`, not both")
            }
            MotionFields { interpolation: Some(_), .. } => Err("`interpolation` goes with `keys`"),
            _ => Err("a motion needs `keys = [[t, [x, y, z]], ...]` (or `end`, with `start`, for a linear one)"),
        }
    }
}

impl From<MotionDesc> for MotionFields {
    fn from(d: MotionDesc) -> MotionFields {
        match d {
            MotionDesc::Linear { start, end } => {
                MotionFields { start: Some(start), end: Some(end), keys: None, interpolation: None }
            }
            MotionDesc::Keys { keys, interpolation } => {
                MotionFields { start: None, end: None, keys: Some(keys), interpolation: Some(interpolation) }
            }
        }
    }
}

/// A mesh: from an OBJ file (`path` or `asset`) or given inline (`vertices` and `faces`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshDesc {
    /// Name shown in the debugger.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// OBJ file, relative to the scene file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<PathBuf>,
    /// OBJ file, relative to the asset folder (the course's scene files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub asset: Option<PathBuf>,
    /// Inline vertex positions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertices: Option<Vec<Vec3>>,
    /// Inline triangles (0-based vertex indices).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub faces: Option<Vec<[u32; 3]>>,
    /// Inline per-vertex normals (default: smooth normals from the faces).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normals: Option<Vec<Vec3>>,
    /// Inline per-vertex texture coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uvs: Option<Vec<Vec2>>,
    /// Materials of an inline mesh, referenced by `face_materials`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<MaterialDesc>,
    /// Material of each inline face (default: the first material for all).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub face_materials: Vec<u32>,
    /// Translate by the mean of the vertices and scale by the largest distance from it, so the
    /// mesh fits the unit sphere (the course's normalisation), before `transform`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub normalize: bool,
    /// Placement applied after normalisation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transform: Option<TransformDesc>,
    /// Overrides the fields it names in every material of the mesh.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<MaterialDesc>,
    /// Motion during the exposure (motion blur): linear or along keyframes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionDesc>,
}

/// Scale, then rotate (Euler degrees, course convention), then translate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TransformDesc {
    /// Translation.
    pub translate: Vec3,
    /// Rotation, Euler angles in degrees.
    pub rotate: Vec3,
    /// Uniform scale.
    pub scale: f32,
}

impl Default for TransformDesc {
    fn default() -> Self {
        TransformDesc { translate: Vec3::ZERO, rotate: Vec3::ZERO, scale: 1.0 }
    }
}

/// An analytic sphere.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereDesc {
    /// Centre.
    pub center: Vec3,
    /// Radius (positive).
    pub radius: f32,
    /// Material (unnamed fields take the default material's values).
    #[serde(default)]
    pub material: MaterialDesc,
    /// Motion during the exposure (motion blur): linear or along keyframes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionDesc>,
}

/// Where relative paths in a description are resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadContext {
    /// Folder of the scene file (`path` entries are relative to it).
    pub base_dir: PathBuf,
    /// The asset folder (`asset` entries are relative to it); `None` uses [`default_assets`].
    pub assets: Option<PathBuf>,
}

impl Default for LoadContext {
    fn default() -> Self {
        LoadContext { base_dir: PathBuf::from("."), assets: None }
    }
}

/// The asset folder when none is given: `RAYSCOPE_ASSETS`, else `../shared/scenes` relative to
/// the working directory when it exists.
pub fn default_assets() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("RAYSCOPE_ASSETS").filter(|p| !p.is_empty()) {
        return Some(PathBuf::from(p));
    }
    let p = PathBuf::from("../shared/scenes");
    p.is_dir().then_some(p)
}

/// For a missing course file: the asset folder that was searched and how it was chosen, or
/// why there was none, with the working directory that relative folders start from.
fn searched_folder(given: bool, dir: Option<&Path>) -> String {
    let shown = |d: &Path| match std::path::absolute(d) {
        Ok(abs) if abs != d => format!("{} ({})", d.display(), abs.display()),
        _ => d.display().to_string(),
    };
    match dir {
        Some(d) if given => format!("Searched the asset folder given (--assets): {}", shown(d)),
        Some(d) if std::env::var_os("RAYSCOPE_ASSETS").is_some_and(|v| !v.is_empty()) => {
            format!("Searched the asset folder named by RAYSCOPE_ASSETS: {}", shown(d))
        }
        Some(d) => {
            format!("Searched the default asset folder, ../shared/scenes beside the working directory: {}", shown(d))
        }
        None => {
            let cwd = std::env::current_dir().map_or_else(|_| "?".into(), |d| d.display().to_string());
            format!(
                "No asset folder: neither --assets nor RAYSCOPE_ASSETS is set, and the default, \
                 ../shared/scenes beside the working directory ({cwd}), does not exist"
            )
        }
    }
}

impl SceneDesc {
    /// Parse a TOML scene file's text; errors name `path` and the line.
    pub fn from_toml(text: &str, path: &Path) -> Result<SceneDesc> {
        let desc: SceneDesc = toml::from_str(text).map_err(|e| {
            let span = e.span().map(|s| s.start.min(text.len())..s.end.min(text.len()));
            let line = span.clone().map(|s| culprit_line(text, s, e.message()));
            Error::parse(path, line, e.message().to_string())
        })?;
        let mut desc = desc;
        camera_lens::apply(text, &mut desc).map_err(|bad| {
            let bad = BadValue { table: bad.table, index: None, key: bad.key, message: bad.message };
            Error::parse(path, bad.line_in(text), bad.to_string())
        })?;
        check_values(&desc).map_err(|bad| Error::parse(path, bad.line_in(text), bad.to_string()))?;
        Ok(desc)
    }

    /// This description as TOML, with the lens (depth of field) in the camera table.
    pub fn to_toml(&self) -> String {
        toml::to_string(&camera_lens::export(self)).expect("scene descriptions always serialise")
    }

    /// A scene of one mesh file (OBJ, PLY or glTF): an OBJ or PLY file as [`Self::for_obj`];
    /// a glTF file with its own camera (then not normalised: the camera was placed for the
    /// file's coordinates) and lights, where it has them.
    pub fn for_mesh_file(path: &Path) -> Result<SceneDesc> {
        let mut desc = SceneDesc::for_obj(path);
        if MeshFormat::of(path) == Some(MeshFormat::Gltf) {
            let file = load_mesh_file(path)?;
            if let Some(camera) = file.camera {
                desc.camera = camera;
                desc.meshes[0].normalize = false;
            }
            if !file.lights.is_empty() {
                desc.lights = file.lights;
            }
        }
        Ok(desc)
    }

    /// A scene of one OBJ file, normalised, under the course's default light.
    pub fn for_obj(path: &Path) -> SceneDesc {
        SceneDesc {
            name: path.file_name().map(|n| n.to_string_lossy().into_owned()),
            meshes: vec![MeshDesc { path: Some(path.to_path_buf()), normalize: true, ..MeshDesc::default() }],
            lights: vec![Light::Point { position: Vec3::new(-1.0, 1.0, -1.0), color: Vec3::ONE }],
            ..SceneDesc::default()
        }
    }
}

/// Apply the fields `o` names to `m`.
fn apply_override(m: &mut Material, o: &MaterialDesc, textures: &mut TextureCache, base: &Path) -> Result<()> {
    if let Some(n) = &o.name {
        m.name = n.clone();
    }
    m.kd = o.kd.unwrap_or(m.kd);
    m.ks = o.ks.unwrap_or(m.ks);
    m.shininess = o.shininess.unwrap_or(m.shininess);
    m.transparency = o.transparency.unwrap_or(m.transparency);
    m.glossiness = o.glossiness.or(m.glossiness);
    m.model = o.model.or(m.model);
    if let Some(keys) = &o.gradient {
        m.gradient =
            Some(Gradient::new(keys.clone()).map_err(|e| Error::Invalid(format!("material '{}': {e}", m.name)))?);
    }
    if let Some(t) = &o.texture {
        m.texture = Some(textures.get(&base.join(t))?);
    }
    validate_material(m)
}

fn validate_material(m: &Material) -> Result<()> {
    let ok = m.kd.is_finite()
        && m.ks.is_finite()
        && m.shininess.is_finite()
        && (0.0..=1.0).contains(&m.transparency)
        && m.glossiness.is_none_or(|g| g >= 0.0);
    if ok {
        Ok(())
    } else {
        Err(Error::Invalid(format!(
            "material '{}': values must be finite, transparency in [0, 1] and glossiness >= 0",
            m.name
        )))
    }
}

#[derive(Default)]
struct TextureCache {
    textures: Vec<Texture>,
    by_path: HashMap<PathBuf, usize>,
}

impl TextureCache {
    fn get(&mut self, path: &Path) -> Result<usize> {
        if let Some(&i) = self.by_path.get(path) {
            return Ok(i);
        }
        self.textures.push(load_texture(path)?);
        self.by_path.insert(path.to_path_buf(), self.textures.len() - 1);
        Ok(self.textures.len() - 1)
    }
}

/// One mesh desc's geometry before placement: groups and their local materials.
struct Loaded {
    meshes: Vec<(Mesh, Option<usize>)>,
    raw_positions: Vec<Vec3>,
    materials: Vec<(Material, Option<PathBuf>)>,
    /// What the file's reader accepted but ignored.
    warnings: Vec<String>,
    /// Textures the file holds (glTF): a material's `texture` indexes them.
    textures: Vec<Texture>,
    /// The file's structure (glTF).
    outline: Vec<String>,
}

fn load_mesh_source(d: &MeshDesc, ctx: &LoadContext, scene: &str, textures: &mut TextureCache) -> Result<Loaded> {
    let file = match (&d.path, &d.asset, &d.vertices) {
        (Some(p), None, None) => Some(ctx.base_dir.join(p)),
        (None, Some(a), None) => {
            let dir = ctx.assets.clone().or_else(default_assets);
            let p = dir.as_ref().map_or_else(|| a.clone(), |d| d.join(a));
            // Anything at the path is read (and refused there if it is no regular file).
            if !p.exists() {
                let searched = searched_folder(ctx.assets.is_some(), dir.as_deref());
                return Err(Error::MissingAsset { scene: scene.to_string(), path: p, searched });
            }
            Some(p)
        }
        (None, None, Some(_)) => None,
        _ => {
            return Err(Error::Invalid(format!(
                "scene '{scene}': a mesh needs exactly one of `path`, `asset` or `vertices`"
            )));
        }
    };
    if let Some(path) = file {
        let MeshFile { file: ObjFile { meshes, materials, raw_positions, warnings }, textures, outline, .. } =
            load_mesh_file(&path)?;
        let meshes = meshes
            .into_iter()
            .map(|m| {
                // On every core: a big mesh's arrays are millions long.
                let mesh = Mesh {
                    name: m.name,
                    positions: m.positions.into_par_iter().map(Vec3A::from).collect(),
                    normals: m.normals.into_par_iter().map(Vec3A::from).collect(),
                    uvs: m.uvs,
                    materials: vec![0; m.triangles.len()],
                    motion: None,
                    triangles: m.triangles,
                };
                (mesh, m.material)
            })
            .collect();
        let materials = materials.into_iter().map(|m| (m.material, m.texture)).collect();
        return Ok(Loaded { meshes, raw_positions, materials, warnings, textures, outline });
    }
    let vertices = d.vertices.clone().unwrap_or_default();
    let faces = d.faces.clone().unwrap_or_default();
    let n = vertices.len();
    let bad =
        |what: String| Error::Invalid(format!("scene '{scene}', mesh '{}': {what}", d.name.as_deref().unwrap_or("")));
    let flat: Vec<u32> = faces.iter().flatten().copied().collect();
    let normals = match &d.normals {
        Some(ns) if ns.len() == n => ns.iter().map(|v| v.normalize_or_zero()).collect(),
        Some(ns) => return Err(bad(format!("{} normals for {n} vertices", ns.len()))),
        None => smooth_normals(&vertices, &flat),
    };
    let uvs = match &d.uvs {
        Some(uv) if uv.len() == n => uv.clone(),
        Some(uv) => return Err(bad(format!("{} uvs for {n} vertices", uv.len()))),
        None => Vec::new(),
    };
    let nmat = d.materials.len().max(1);
    let face_materials = if d.face_materials.is_empty() { vec![0; faces.len()] } else { d.face_materials.clone() };
    if face_materials.len() != faces.len() || face_materials.iter().any(|&m| m as usize >= nmat) {
        return Err(bad("face_materials must give a valid material for every face".into()));
    }
    let mut materials = Vec::new();
    for md in &d.materials {
        let mut m = Material::default();
        // Textures load here, relative to the scene file, into the scene's cache.
        apply_override(&mut m, md, textures, &ctx.base_dir)?;
        materials.push((m, None));
    }
    let mesh = Mesh {
        name: d.name.clone().unwrap_or_else(|| "mesh".into()),
        positions: vertices.iter().copied().map(Vec3A::from).collect(),
        normals: normals.into_iter().map(Vec3A::from).collect(),
        uvs,
        triangles: faces,
        materials: face_materials,
        motion: None,
    };
    // Inline meshes carry per-face material indices already; mark them with `None` so the
    // caller maps them through the local material table.
    Ok(Loaded {
        meshes: vec![(mesh, None)],
        raw_positions: vertices,
        materials,
        warnings: Vec::new(),
        textures: Vec::new(),
        outline: Vec::new(),
    })
}

/// Turn a description into a scene: load files, normalise and place meshes, resolve
/// materials and textures, check values, and build the BVH.
pub fn load(desc: &SceneDesc, ctx: &LoadContext) -> Result<Scene> {
    let name = desc.name.clone().unwrap_or_else(|| "scene".into());
    check_values(desc).map_err(|bad| Error::Invalid(format!("scene '{name}': {bad}")))?;
    let mut textures = TextureCache::default();
    let mut materials: Vec<Material> = vec![Material::default()];
    let mut meshes = Vec::new();
    let mut warnings = Vec::new();
    let mut outline = Vec::new();
    for d in &desc.meshes {
        let inline = d.vertices.is_some();
        let mut loaded = load_mesh_source(d, ctx, &name, &mut textures)?;
        warnings.append(&mut loaded.warnings);
        outline.append(&mut loaded.outline);
        let base = materials.len() as u32;
        // A file's own textures join the scene's, and its materials' indices move with them
        // (an inline mesh's materials index the scene's textures already).
        let embedded = textures.textures.len();
        textures.textures.append(&mut loaded.textures);
        for (mut m, tex) in loaded.materials {
            if !inline {
                m.texture = m.texture.map(|t| t + embedded);
            }
            if let Some(t) = tex {
                m.texture = Some(textures.get(&t)?);
            }
            if let Some(o) = &d.material {
                apply_override(&mut m, o, &mut textures, &ctx.base_dir)?;
            }
            materials.push(m);
        }
        // A file group without a material (or an inline mesh without materials) uses the
        // default material, with the override applied.
        let default_index = if d.material.is_some() || (inline && d.materials.is_empty()) {
            let mut m = Material::default();
            if let Some(o) = &d.material {
                apply_override(&mut m, o, &mut textures, &ctx.base_dir)?;
            }
            materials.push(m);
            materials.len() as u32 - 1
        } else {
            0
        };
        let placement = Placement::new(d, &loaded.raw_positions);
        for (mut mesh, material) in loaded.meshes {
            if inline {
                let has = !d.materials.is_empty();
                mesh.materials.par_iter_mut().for_each(|m| *m = if has { base + *m } else { default_index });
            } else {
                let idx = material.map(|i| base + i as u32).unwrap_or(default_index);
                mesh.materials.par_iter_mut().for_each(|m| *m = idx);
            }
            placement.apply(&mut mesh);
            mesh.motion = motion(&d.motion)?;
            meshes.push(mesh);
        }
    }
    let mut spheres = Vec::new();
    for (i, s) in desc.spheres.iter().enumerate() {
        // Named for the debugger when the file names it not: "sphere 2", not "default".
        let mut m = Material { name: format!("sphere {i}"), ..Material::default() };
        apply_override(&mut m, &s.material, &mut textures, &ctx.base_dir)?;
        materials.push(m);
        spheres.push(SceneSphere {
            center: s.center.into(),
            radius: s.radius,
            material: materials.len() as u32 - 1,
            motion: motion(&s.motion)?,
        });
    }
    let mut scene = Scene::new(
        name,
        desc.camera.clone(),
        meshes,
        spheres,
        materials,
        textures.textures,
        desc.lights.clone(),
        desc.render.clone(),
    );
    scene.camera_end = desc.camera_end.clone();
    scene.camera_path = motion(&desc.camera_motion)?;
    scene.animation = desc.animation;
    scene.environment = desc.environment.as_ref().map(|e| Environment::load(e, &ctx.base_dir)).transpose()?;
    scene.warnings = warnings;
    scene.outline = outline;
    Ok(scene)
}

/// The path a motion description gives (its values were checked by [`check_values`]).
fn motion(d: &Option<MotionDesc>) -> Result<Option<MotionPath>> {
    d.as_ref().map(|m| m.path().map_err(Error::Invalid)).transpose()
}

/// A value of a scene description that is out of its range, and where it is: the key in a
/// table (`[camera]`) or in one of an array of tables (the third `[[light]]`).
#[derive(Debug)]
struct BadValue {
    /// The table's name: `camera`, `camera_end`, `render`, `animation`, `mesh`, `sphere`,
    /// `light` or `environment`.
    table: &'static str,
    /// Which of the array of tables (0-based); `None` for a single table.
    index: Option<usize>,
    /// The key whose value is wrong; empty for the table as a whole.
    key: &'static str,
    /// What is wrong.
    message: String,
}

impl std::fmt::Display for BadValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.table)?;
        if let Some(i) = self.index {
            write!(f, " {}", i + 1)?;
        }
        if !self.key.is_empty() {
            write!(f, ", {}", self.key)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl BadValue {
    /// The 1-based line of the value in the scene file `text`: the key's line in its table,
    /// else the table's header (or, for an inline table, its key's line).
    fn line_in(&self, text: &str) -> Option<usize> {
        let header = match self.index {
            Some(_) => format!("[[{}]]", self.table),
            None => format!("[{}]", self.table),
        };
        let key_of = |l: &str| l.split_once('=').map(|(k, _)| k.trim().to_string());
        let mut lines = text.lines().enumerate();
        let mut seen = 0;
        let want = self.index.unwrap_or(0);
        let start = lines.by_ref().find(|(_, l)| {
            let hit = l.trim() == header && seen == want;
            seen += usize::from(l.trim() == header);
            hit
        });
        let Some((start, _)) = start else {
            // An inline table (`camera = { ... }`): its key's line.
            let top = text.lines().take_while(|l| !l.trim_start().starts_with('['));
            return top.enumerate().find(|(_, l)| key_of(l).as_deref() == Some(self.table)).map(|(i, _)| i + 1);
        };
        let body = lines.take_while(|(_, l)| !l.trim_start().starts_with('['));
        let found = body.filter(|_| !self.key.is_empty()).find(|(_, l)| key_of(l).as_deref() == Some(self.key));
        Some(found.map_or(start, |(i, _)| i) + 1)
    }
}

/// Check every number of a scene description: all finite, and each in its range. The parser
/// checks the types; this, the values, so that none renders a blank or wrong image silently.
fn check_values(desc: &SceneDesc) -> Result<(), BadValue> {
    let bad = |table, index, key, message: &str| Err(BadValue { table, index, key, message: message.into() });
    check_camera(&desc.camera).or_else(|e| bad("camera", None, e.key, e.message))?;
    if let Some(c) = &desc.camera_end {
        check_camera(c).or_else(|e| bad("camera_end", None, e.key, e.message))?;
    }
    if let Some(m) = &desc.camera_motion {
        if desc.camera_end.is_some() {
            bad("camera_motion", None, "", "give the camera's motion as `camera_motion` or `camera_end`, not both")?;
        }
        let key = if matches!(m, MotionDesc::Keys { .. }) { "keys" } else { "" };
        check_motion(Some(m)).or_else(|msg| bad("camera_motion", None, key, &msg))?;
    }
    if let Some(r) = &desc.render {
        r.validate().or_else(|e| bad("render", None, "", &e.to_string()))?;
    }
    if let Some(a) = &desc.animation {
        a.validate().or_else(|e| bad("animation", None, "", &e.to_string()))?;
    }
    for (i, m) in desc.meshes.iter().enumerate() {
        let at = |key, message: &str| bad("mesh", Some(i), key, message);
        let n = m.vertices.as_ref().map_or(0, Vec::len);
        if m.vertices.iter().flatten().any(|v| !v.is_finite()) {
            at("vertices", "vertices must be finite")?;
        }
        if let Some(f) = m.faces.iter().flatten().flatten().find(|&&f| f as usize >= n) {
            at("faces", &format!("face index {f} is out of range ({n} vertices)"))?;
        }
        if m.normals.iter().flatten().any(|v| !v.is_finite()) {
            at("normals", "normals must be finite")?;
        }
        if m.uvs.iter().flatten().any(|v| !v.is_finite()) {
            at("uvs", "texture coordinates must be finite")?;
        }
        for (key, d) in
            [("material", m.material.as_ref())].into_iter().chain(m.materials.iter().map(|d| ("materials", Some(d))))
        {
            d.map_or(Ok(()), check_material).or_else(|msg| at(key, &msg))?;
        }
        if let Some(t) = &m.transform {
            check_transform(t).or_else(|msg| at("transform", msg))?;
        }
        check_motion(m.motion.as_ref()).or_else(|msg| at("motion", &msg))?;
    }
    for (i, s) in desc.spheres.iter().enumerate() {
        let at = |key, message: &str| bad("sphere", Some(i), key, message);
        if !s.center.is_finite() {
            at("center", "the centre must be finite")?;
        }
        if !(s.radius.is_finite() && s.radius > 0.0) {
            at("radius", "the radius must be positive and finite")?;
        }
        check_material(&s.material).or_else(|msg| at("material", &msg))?;
        check_motion(s.motion.as_ref()).or_else(|msg| at("motion", &msg))?;
    }
    for (i, l) in desc.lights.iter().enumerate() {
        check_light(l).or_else(|e| bad("light", Some(i), e.key, e.message))?;
    }
    if let Some(e) = &desc.environment {
        e.validate("intensity", "rotation").or_else(|err| {
            let intensity_ok = e.intensity.is_finite() && e.intensity >= 0.0;
            let key = if intensity_ok { "rotation" } else { "intensity" };
            bad("environment", None, key, &err.to_string())
        })?;
    }
    Ok(())
}

/// A value that is wrong inside a table: its key and what is wrong.
struct BadKey {
    key: &'static str,
    message: &'static str,
}

/// The first of `values` that is not finite, as a [`BadKey`].
fn first_infinite(values: &[(&'static str, &Vec3)]) -> Result<(), BadKey> {
    match values.iter().find(|(_, v)| !v.is_finite()) {
        Some(&(key, _)) => Err(BadKey { key, message: "must be finite" }),
        None => Ok(()),
    }
}

/// A camera's values: finite, a field of view in (0, 180) degrees and a positive distance
/// (0 puts the eye in the look-at point, negative behind it: no view, or a mirrored one).
fn check_camera(c: &CameraDesc) -> Result<(), BadKey> {
    let fov = match c {
        CameraDesc::Trackball { look_at, distance, rotation, fov } => {
            first_infinite(&[("look_at", look_at), ("rotation", rotation)])?;
            if !(distance.is_finite() && *distance > 0.0) {
                return Err(BadKey { key: "distance", message: "must be positive and finite" });
            }
            fov
        }
        CameraDesc::LookAt { eye, target, up, fov } => {
            first_infinite(&[("eye", eye), ("target", target), ("up", up)])?;
            if eye == target {
                return Err(BadKey { key: "target", message: "must differ from the eye" });
            }
            fov
        }
    };
    if !(*fov > 0.0 && *fov < 180.0) {
        return Err(BadKey { key: "fov", message: "the field of view must be between 0 and 180 degrees" });
    }
    Ok(())
}

/// A material's values: colours finite and not negative, a finite shininess of at least 0,
/// transparency in [0, 1], and a glossiness of at least 0 (`inf` is a perfect mirror).
fn check_material(m: &MaterialDesc) -> Result<(), String> {
    let colour = |c: Option<Vec3>| c.is_none_or(|c| c.is_finite() && c.min_element() >= 0.0);
    if !(colour(m.kd) && colour(m.ks)) {
        return Err("colours (kd, ks) must be finite and not negative".into());
    }
    if !m.shininess.is_none_or(|s| s.is_finite() && s >= 0.0) {
        return Err("shininess must be finite and at least 0".into());
    }
    if !m.transparency.is_none_or(|t| (0.0..=1.0).contains(&t)) {
        return Err("transparency must be in [0, 1]".into());
    }
    if !m.glossiness.is_none_or(|g| g >= 0.0) {
        return Err("glossiness must be at least 0 (inf: a perfect mirror)".into());
    }
    if let Some(keys) = &m.gradient {
        Gradient::new(keys.clone())?;
    }
    Ok(())
}

/// A transform's values: finite, and a scale other than 0 (which would collapse the mesh).
fn check_transform(t: &TransformDesc) -> Result<(), &'static str> {
    if !(t.translate.is_finite() && t.rotate.is_finite() && t.scale.is_finite()) {
        return Err("translate, rotate and scale must be finite");
    }
    if t.scale == 0.0 {
        return Err("scale must not be 0");
    }
    Ok(())
}

/// A motion's values: finite translations and, for keys, the rules of [`MotionPath::new`] (at
/// least two, times finite and strictly increasing).
fn check_motion(m: Option<&MotionDesc>) -> Result<(), String> {
    m.map_or(Ok(()), |m| m.path().map(drop))
}

/// A light's values: finite positions and vectors, colours finite and not negative, a radius
/// of at least 0.
fn check_light(l: &Light) -> Result<(), BadKey> {
    match l {
        Light::Point { position, color } => {
            first_infinite(&[("position", position)])?;
            first_bad_colour(&[("color", color)])
        }
        Light::Segment { endpoint0, endpoint1, color0, color1 } => {
            first_infinite(&[("endpoint0", endpoint0), ("endpoint1", endpoint1)])?;
            first_bad_colour(&[("color0", color0), ("color1", color1)])
        }
        Light::Parallelogram { v0, edge01, edge02, color0, color1, color2, color3 } => {
            first_infinite(&[("v0", v0), ("edge01", edge01), ("edge02", edge02)])?;
            first_bad_colour(&[("color0", color0), ("color1", color1), ("color2", color2), ("color3", color3)])
        }
        Light::Sphere { center, radius, color } => {
            first_infinite(&[("center", center)])?;
            if !(radius.is_finite() && *radius >= 0.0) {
                return Err(BadKey { key: "radius", message: "must be finite and at least 0" });
            }
            first_bad_colour(&[("color", color)])
        }
    }
}

/// The first of `colours` that is not finite or has a negative channel, as a [`BadKey`].
fn first_bad_colour(colours: &[(&'static str, &Vec3)]) -> Result<(), BadKey> {
    match colours.iter().find(|(_, c)| !(c.is_finite() && c.min_element() >= 0.0)) {
        Some(&(key, _)) => Err(BadKey { key, message: "colours must be finite and not negative" }),
        None => Ok(()),
    }
}

/// The course's normalisation followed by the mesh's transform.
struct Placement {
    center: Vec3,
    inv_scale: f32,
    rotation: glam::Quat,
    scale: f32,
    translate: Vec3,
}

impl Placement {
    fn new(d: &MeshDesc, raw: &[Vec3]) -> Placement {
        let (mut center, mut inv_scale) = (Vec3::ZERO, 1.0);
        if d.normalize && !raw.is_empty() {
            center = raw.iter().copied().sum::<Vec3>() / raw.len() as f32;
            let max_d = raw.iter().map(|p| p.distance(center)).fold(0.0f32, f32::max);
            if max_d > 0.0 {
                inv_scale = 1.0 / max_d;
            }
        }
        let t = d.transform.clone().unwrap_or_default();
        Placement {
            center,
            inv_scale,
            rotation: quat_from_euler_degrees(t.rotate),
            scale: t.scale,
            translate: t.translate,
        }
    }

    fn apply(&self, mesh: &mut Mesh) {
        mesh.positions.par_iter_mut().for_each(|p| {
            let q = (Vec3::from(*p) - self.center) * self.inv_scale;
            *p = (self.rotation * (q * self.scale) + self.translate).into();
        });
        // A uniform scale keeps normals' directions; only the rotation (and a negative scale's
        // flip) applies.
        let flip = self.scale.signum();
        mesh.normals.par_iter_mut().for_each(|n| *n = Vec3A::from(self.rotation * Vec3::from(*n) * flip));
    }
}

/// 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset].matches('\n').count() + 1
}

/// The line to report for a parse error `message` whose span is `span`: its first line,
/// except in the tagged tables (camera, lights), which serde buffers before it sees their
/// fields, so that the span is the table's header. There the offending key is found in the
/// table's body: the one named by an unknown-field message, or else the one whose removal
/// makes the error go away or turn into that key missing (a value of the wrong type).
fn culprit_line(text: &str, span: std::ops::Range<usize>, message: &str) -> usize {
    let first = line_of(text, span.start);
    // A table's header starts its line (an array value starts after its key).
    let line_start = text[..span.start].rfind('\n').map_or(0, |i| i + 1);
    if !text[span.clone()].starts_with('[') || !text[line_start..span.start].trim().is_empty() {
        return first;
    }
    // The body: from the header to the next header (or the end).
    let mut end = span.end;
    for l in text[span.end..].split_inclusive('\n') {
        if l.trim_start().starts_with('[') && end > span.end {
            break;
        }
        end += l.len();
    }
    let span = span.start..end;
    let unknown = message.strip_prefix("unknown field `").and_then(|m| m.split('`').next());
    let mut offset = span.start;
    for l in text[span.clone()].split_inclusive('\n') {
        let key = l
            .split_once('=')
            .map(|(k, _)| k.trim())
            .filter(|k| !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-'));
        if let Some(key) = key {
            let culprit = match unknown {
                Some(u) => key == u,
                None if key == "kind" => false,
                None => {
                    let without = [&text[..offset], &text[offset + l.len()..]].concat();
                    match toml::from_str::<SceneDesc>(&without) {
                        Ok(_) => true,
                        Err(e) => e.message() == format!("missing field `{key}`"),
                    }
                }
            };
            if culprit {
                return line_of(text, offset);
            }
        }
        offset += l.len();
    }
    first
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_keys_are_errors_with_a_line() {
        let text = "name = \"x\"\n[camera]\nkind = \"trackball\"\nfovv = 3\n";
        match SceneDesc::from_toml(text, Path::new("s.toml")) {
            Err(Error::Parse { line, message, .. }) => {
                assert_eq!(line, Some(4), "{message}");
                assert!(message.contains("fovv"), "{message}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn bad_values_in_tagged_tables_name_their_line() {
        let cases = [
            ("name = \"x\"\n[camera]\nkind = \"trackball\"\nfov = \"wide\"\ndistance = 3\n", 4),
            ("[[light]]\nkind = \"point\"\ncolor = [1, 1, 1]\nposition = [0, \"up\", 0]\n", 4),
            ("[[light]]\nkind = \"point\"\nposition = [0, 1, 0]\ncolor = [1, 1]\n\n[[light]]\nkind = \"point\"\n", 4),
            // Untagged tables: the parser's own span, on the value.
            ("[[sphere]]\nradius = 1\ncenter = [0, \"a\", 0]\nmaterial = { kd = [1, 0, 0] }\n", 3),
        ];
        for (text, want) in cases {
            match SceneDesc::from_toml(text, Path::new("s.toml")) {
                Err(Error::Parse { line, message, .. }) => assert_eq!(line, Some(want), "{message}\n{text}"),
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn lights_and_spheres_parse() {
        let text = r#"
[[sphere]]
center = [0, 0, 0]
radius = 1
material = { kd = [1, 0, 0] }
[[light]]
kind = "parallelogram"
v0 = [0, 1, 0]
edge01 = [1, 0, 0]
edge02 = [0, 0, 1]
color0 = [1, 0, 0]
color1 = [0, 1, 0]
color2 = [0, 0, 1]
color3 = [0, 1, 1]
"#;
        let d = SceneDesc::from_toml(text, Path::new("s.toml")).unwrap();
        assert_eq!(d.spheres.len(), 1);
        assert!(matches!(d.lights[0], Light::Parallelogram { .. }));
        let scene = load(&d, &LoadContext::default()).unwrap();
        assert_eq!(scene.materials[scene.spheres[0].material as usize].kd, Vec3::X);
    }

    #[test]
    fn bad_values_are_rejected() {
        let nan_light = "[[light]]\nkind = \"point\"\nposition = [nan, 0, 0]\ncolor = [1, 1, 1]\n";
        let bad_face = "[[mesh]]\nvertices = [[0,0,0],[1,0,0],[0,1,0]]\nfaces = [[0,1,3]]\n";
        let nan_motion =
            "[[sphere]]\ncenter = [0, 0, 0]\nmotion = { start = [0, 0, 0], end = [nan, 0, 0] }\nradius = 1\n";
        for text in [nan_light, bad_face, nan_motion] {
            // A scene file's values are checked as it is read, at their line; a description
            // made in code, when it is loaded.
            let parsed = SceneDesc::from_toml(text, Path::new("s.toml"));
            assert!(matches!(parsed, Err(Error::Parse { line: Some(3), .. })), "{parsed:?}");
            let d: SceneDesc = toml::from_str(text).unwrap();
            assert!(matches!(load(&d, &LoadContext::default()), Err(Error::Invalid(_))));
        }
        let two_sources = "[[mesh]]\npath = \"a.obj\"\nasset = \"b.obj\"\n";
        let d = SceneDesc::from_toml(two_sources, Path::new("s.toml")).unwrap();
        assert!(load(&d, &LoadContext::default()).is_err());
    }

    #[test]
    fn missing_obj_names_the_path() {
        let d = SceneDesc::from_toml("[[mesh]]\npath = \"nope.obj\"\n", Path::new("s.toml")).unwrap();
        let err = load(&d, &LoadContext::default()).unwrap_err().to_string();
        assert!(err.contains("nope.obj"), "{err}");
    }

    #[test]
    fn normalisation_fits_the_unit_sphere() {
        let d = MeshDesc {
            vertices: Some(vec![Vec3::new(10.0, 0.0, 0.0), Vec3::new(14.0, 0.0, 0.0), Vec3::new(12.0, 2.0, 0.0)]),
            faces: Some(vec![[0, 1, 2]]),
            normalize: true,
            ..MeshDesc::default()
        };
        let scene = load(&SceneDesc { meshes: vec![d], ..SceneDesc::default() }, &LoadContext::default()).unwrap();
        let p = &scene.meshes[0].positions;
        let mean = p.iter().copied().sum::<Vec3A>() / 3.0;
        assert!(mean.length() < 1e-6);
        let max = p.iter().map(|v| v.length()).fold(0.0, f32::max);
        assert!((max - 1.0).abs() < 1e-6);
    }
}
