//! glTF 2.0 scenes (`.gltf` with external or `data:` buffers, and `.glb`), read with the
//! `gltf` crate's document model and validation; the bytes are rayscope's to read and check
//! ([`buffers`]), the materials are mapped to Phong in [`material`].
//!
//! What is read: the default scene's node tree (or, without scenes, every root node) with
//! each node's transform (matrix or TRS) applied to its mesh; every primitive of mode
//! TRIANGLES (indexed or not) with its positions, normals (smooth ones where it has none) and
//! first texture coordinates, one group each; the materials and their base colour textures;
//! the first perspective camera met in the tree; and `KHR_lights_punctual` lights
//! (see [`lights`]). Everything else (skins, animations, morph targets, other primitive
//! modes, orthographic cameras, other extensions) is skipped with a warning that names it;
//! a file whose structure or data is wrong (an accessor of the wrong type, indices out of
//! range, a buffer shorter than it says) is an error naming the element.

pub mod buffers;
mod lights;
pub mod material;

use std::path::Path;

use glam::Mat4;

use self::buffers::{Expect, read_accessor, read_buffers, read_file, read_uri, split_container, view_bytes};
use self::material::{Extras, Pbr, phong_from_pbr};
use super::memory::MeshSize;
use super::mesh_file::MeshFile;
use super::mtl::ObjMaterial;
use super::obj::{ObjMesh, smooth_normals};
use super::texture::decode_texture;
use crate::camera::CameraDesc;
use crate::error::{Error, Result};
use crate::material::Texture;
use crate::math::{Vec2, Vec3};
use gltf::accessor::{DataType, Dimensions};

/// The deepest node tree followed: far beyond real files, and a bound on a hostile one.
const MAX_DEPTH: usize = 256;

/// One mesh placed by a node.
struct Instance {
    node: usize,
    mesh: usize,
    world: Mat4,
}

/// What the walk of the node tree found.
#[derive(Default)]
struct Placed {
    instances: Vec<Instance>,
    camera: Option<(usize, Mat4)>,
    lights: Vec<(usize, Mat4)>,
}

/// Load a glTF or GLB file (and the buffers and images it names) within the loaders' limits:
/// the primitives as groups in world space, the materials (a textured material's `texture`
/// indexes [`MeshFile::textures`]), the camera, the lights and the outline.
pub fn load_gltf(path: &Path) -> Result<MeshFile> {
    let container = split_container(read_file(path)?, path)?;
    let gltf = gltf::Gltf::from_slice(&container.json)
        .map_err(|e| Error::parse(path, None, format!("not a valid glTF document: {e}")))?;
    let doc = &gltf.document;
    let buffers = read_buffers(doc, container.bin.as_deref(), path)?;
    let mut out = MeshFile::default();
    let warn = |out: &mut MeshFile, what: String| out.file.warnings.push(format!("{}: {what}", path.display()));
    for ext in doc.extensions_used() {
        if ext != "KHR_lights_punctual" {
            warn(&mut out, format!("extension {ext} is not supported; ignored"));
        }
    }
    for (what, n) in [("skin", doc.skins().len()), ("animation", doc.animations().len())] {
        if n > 0 {
            warn(&mut out, format!("{n} {what}(s) not supported; the meshes are read in their rest pose"));
        }
    }
    let placed = walk(doc, &mut out, path);
    // The memory the placed meshes take, asked for before any is read.
    let mut size = MeshSize::default();
    for i in &placed.instances {
        for p in doc.meshes().nth(i.mesh).into_iter().flat_map(|m| m.primitives()) {
            let corners = p.indices().or_else(|| p.get(&gltf::Semantic::Positions)).map_or(0, |a| a.count());
            size.triangles += corners as u64 / 3;
            size.vertices += p.get(&gltf::Semantic::Positions).map_or(0, |a| a.count()) as u64;
        }
    }
    size.reserve(path)?;
    for material in doc.materials() {
        let m = read_material(&material, &buffers, &mut out, path);
        out.file.materials.push(ObjMaterial { material: m, texture: None });
    }
    for instance in &placed.instances {
        read_instance(doc, instance, &buffers, &mut out, path)?;
    }
    if out.file.meshes.iter().all(|m| m.triangles.is_empty()) {
        return Err(Error::parse(path, None, "no triangles: the scene places no TRIANGLES primitive"));
    }
    out.file.raw_positions = out.file.meshes.iter().flat_map(|m| m.positions.iter().copied()).collect();
    if let Some((index, world)) = placed.camera {
        out.camera = camera(&gltf, index, world, &mut out.file.warnings, path);
    }
    out.lights = lights::map(doc, &placed.lights, &out.file.raw_positions, &mut out.file.warnings, path);
    Ok(out)
}

/// Walk the default scene's node tree (or every root node, in a file without scenes),
/// placing meshes, the camera and lights; nodes met twice (a cycle, or a node shared by two
/// parents, which glTF forbids) and trees deeper than [`MAX_DEPTH`] are skipped with a
/// warning.
fn walk(doc: &gltf::Document, out: &mut MeshFile, path: &Path) -> Placed {
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let children: std::collections::HashSet<usize> =
                doc.nodes().flat_map(|n| n.children().map(|c| c.index())).collect();
            doc.nodes().filter(|n| !children.contains(&n.index())).collect()
        }
    };
    let mut placed = Placed::default();
    let mut seen = vec![false; doc.nodes().len()];
    let mut stack: Vec<(gltf::Node, Mat4, usize)> = roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        let name = node_name(&node);
        if std::mem::replace(&mut seen[node.index()], true) {
            out.file.warnings.push(format!("{}: {name} is met twice in the tree; skipped", path.display()));
            continue;
        }
        if depth > MAX_DEPTH {
            out.file.warnings.push(format!("{}: {name} is deeper than {MAX_DEPTH} levels; skipped", path.display()));
            continue;
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        if !world.is_finite() {
            out.file.warnings.push(format!("{}: {name} has a transform that is not finite; skipped", path.display()));
            continue;
        }
        let kind = match node.transform() {
            gltf::scene::Transform::Matrix { .. } => "matrix",
            gltf::scene::Transform::Decomposed { .. } => "TRS",
        };
        let mut line = format!("{}{name} ({kind})", "  ".repeat(depth));
        if let Some(mesh) = node.mesh() {
            line += &format!(" -> mesh {} '{}'", mesh.index(), mesh.name().unwrap_or(""));
            placed.instances.push(Instance { node: node.index(), mesh: mesh.index(), world });
        }
        if let Some(camera) = node.camera() {
            line += &format!(" -> camera {}", camera.index());
            placed.camera.get_or_insert((camera.index(), world));
        }
        if let Some(light) = node.light() {
            line += &format!(" -> light {}", light.index());
            placed.lights.push((light.index(), world));
        }
        if node.skin().is_some() {
            line += " (skin ignored)";
        }
        out.outline.push(line);
        stack.extend(node.children().collect::<Vec<_>>().into_iter().rev().map(|c| (c, world, depth + 1)));
    }
    placed
}

fn node_name(node: &gltf::Node) -> String {
    format!("node {} '{}'", node.index(), node.name().unwrap_or(""))
}

/// The Phong material of a glTF material: the exact values rayscope wrote in its `extras`
/// when there are some, else [`phong_from_pbr`]; its base colour texture decoded into
/// `out.textures` (a texture that cannot be read is a warning, and the material untextured).
fn read_material(
    m: &gltf::Material,
    buffers: &[Vec<u8>],
    out: &mut MeshFile,
    path: &Path,
) -> crate::material::Material {
    let name = m.name().map_or_else(|| format!("material {}", m.index().unwrap_or(0)), str::to_string);
    let pbr = m.pbr_metallic_roughness();
    let factors = Pbr {
        base_color: pbr.base_color_factor(),
        metallic: pbr.metallic_factor(),
        roughness: pbr.roughness_factor(),
        alpha_mode: m.alpha_mode(),
        alpha_cutoff: m.alpha_cutoff().unwrap_or(0.5),
    };
    let exact = m
        .extras()
        .as_ref()
        .and_then(|raw| serde_json::from_str::<Extras>(raw.get()).ok())
        .and_then(|e| e.rayscope.material(name.clone()));
    let from_extras = exact.is_some();
    let mut material = exact.unwrap_or_else(|| phong_from_pbr(name.clone(), &factors));
    if let Some(info) = pbr.base_color_texture() {
        if info.tex_coord() != 0 {
            out.file.warnings.push(format!(
                "{}: material '{name}' uses texture coordinate set {}; only set 0 is read, the texture is ignored",
                path.display(),
                info.tex_coord()
            ));
        } else {
            match read_texture(&info.texture(), buffers, path) {
                Ok(t) => {
                    out.textures.push(t);
                    material.texture = Some(out.textures.len() - 1);
                }
                Err(e) => out.file.warnings.push(format!("material '{name}': its texture is ignored: {e}")),
            }
        }
    }
    for (what, present) in [
        ("normal texture", m.normal_texture().is_some()),
        ("occlusion texture", m.occlusion_texture().is_some()),
        ("emissive texture", m.emissive_texture().is_some()),
        ("metallic-roughness texture", pbr.metallic_roughness_texture().is_some()),
    ] {
        if present {
            out.file.warnings.push(format!("{}: material '{name}': its {what} is ignored", path.display()));
        }
    }
    let source = if from_extras { "rayscope's exact values" } else { "mapped" };
    out.outline.push(format!(
        "material {} '{name}': base colour {:?}, metallic {}, roughness {}, alpha {:?} -> kd {:?}, ks {:?}, \
         shininess {}, transparency {}{} ({source})",
        m.index().map_or("default".into(), |i| i.to_string()),
        factors.base_color,
        factors.metallic,
        factors.roughness,
        factors.alpha_mode,
        material.kd.to_array(),
        material.ks.to_array(),
        material.shininess,
        material.transparency,
        if material.texture.is_some() { ", textured" } else { "" },
    ));
    material
}

/// A texture's image, decoded, with its rows flipped: glTF's texture coordinates start at the
/// image's top, rayscope's (OBJ's) at its bottom. Flipping the image rather than the
/// coordinates keeps both exact, so a file rayscope wrote (flipped the same way) reads back
/// bit for bit.
fn read_texture(t: &gltf::Texture, buffers: &[Vec<u8>], path: &Path) -> Result<Texture> {
    let image = t.source();
    let what = format!("image {}", image.index());
    let bytes = match image.source() {
        gltf::image::Source::View { view, .. } => view_bytes(&view, buffers, path)?.to_vec(),
        gltf::image::Source::Uri { uri, .. } => read_uri(uri, path, &what)?,
    };
    let texture = decode_texture(&bytes, &path.with_file_name(format!("{}#{what}", file_name(path))))?;
    Ok(flip_rows(texture))
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// The texture upside down (its rows in reverse order).
pub fn flip_rows(t: Texture) -> Texture {
    let w = t.width as usize;
    let texels = if w == 0 { t.texels } else { t.texels.chunks_exact(w).rev().flatten().copied().collect() };
    Texture::new(t.width, t.height, texels)
}

/// The accessor types a use reads.
const FLOATS: &[DataType] = &[DataType::F32];
const INDICES: &[DataType] = &[DataType::U8, DataType::U16, DataType::U32];
const TEXCOORDS: &[DataType] = &[DataType::F32, DataType::U8, DataType::U16];

/// Read the primitives of the mesh `instance` places, as groups in world space.
fn read_instance(
    doc: &gltf::Document,
    instance: &Instance,
    buffers: &[Vec<u8>],
    out: &mut MeshFile,
    path: &Path,
) -> Result<()> {
    let Some(mesh) = doc.meshes().nth(instance.mesh) else { return Ok(()) };
    let mesh_name = mesh.name().unwrap_or("").to_string();
    let world = instance.world;
    let normal_matrix = world.inverse().transpose();
    let flip = world.determinant() < 0.0;
    for p in mesh.primitives() {
        let what = format!("mesh {} '{mesh_name}' primitive {}", mesh.index(), p.index());
        let warn = |out: &mut MeshFile, message: String| {
            out.file.warnings.push(format!("{}: {what}: {message}", path.display()));
        };
        if p.mode() != gltf::mesh::Mode::Triangles {
            warn(out, format!("mode {:?} is not supported (TRIANGLES is); skipped", p.mode()));
            continue;
        }
        if p.morph_targets().len() > 0 {
            warn(out, "its morph targets are ignored".into());
        }
        let context = |e: Error| match e {
            Error::Parse { path, line, message } => Error::Parse { path, line, message: format!("{what}: {message}") },
            e => e,
        };
        let Some(pos) = p.get(&gltf::Semantic::Positions) else {
            warn(out, "has no POSITION; skipped".into());
            continue;
        };
        let positions = read_accessor(
            &pos,
            &Expect { dimensions: Dimensions::Vec3, types: FLOATS, role: "POSITION" },
            buffers,
            path,
        )
        .map_err(context)?;
        let n = positions.len() / 3;
        let indices: Vec<u32> = match p.indices() {
            Some(acc) => {
                let raw = read_accessor(
                    &acc,
                    &Expect { dimensions: Dimensions::Scalar, types: INDICES, role: "indices" },
                    buffers,
                    path,
                )
                .map_err(context)?;
                if let Some((k, &bad)) = raw.iter().enumerate().find(|&(_, &i)| i >= n as f64) {
                    return Err(context(Error::parse(
                        path,
                        None,
                        format!("index {k} is {bad}, out of range ({n} vertices)"),
                    )));
                }
                raw.into_iter().map(|i| i as u32).collect()
            }
            None => (0..n as u32).collect(),
        };
        if !indices.len().is_multiple_of(3) {
            return Err(context(Error::parse(
                path,
                None,
                format!("{} indices are not a whole number of triangles", indices.len()),
            )));
        }
        let positions: Vec<Vec3> = positions
            .chunks_exact(3)
            .map(|c| world.transform_point3(Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)))
            .collect();
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(context(Error::parse(path, None, "a position is not finite")));
        }
        let mut triangles: Vec<[u32; 3]> = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        if flip {
            // A mirroring transform turns the winding; turn it back.
            triangles.iter_mut().for_each(|t| t.swap(1, 2));
        }
        // A vertex attribute of the primitive, one element per position.
        let attribute = |semantic: gltf::Semantic, expect: Expect| -> Result<Option<Vec<f64>>> {
            let Some(acc) = p.get(&semantic) else { return Ok(None) };
            let raw = read_accessor(&acc, &expect, buffers, path).map_err(context)?;
            let per = expect.dimensions.multiplicity();
            if raw.len() != n * per {
                let message = format!("{} {} elements for {n} positions", raw.len() / per, expect.role);
                return Err(context(Error::parse(path, None, message)));
            }
            Ok(Some(raw))
        };
        let vec3 = Expect { dimensions: Dimensions::Vec3, types: FLOATS, role: "NORMAL" };
        let normals = match attribute(gltf::Semantic::Normals, vec3)? {
            Some(raw) => raw
                .chunks_exact(3)
                .map(|c| {
                    let v = Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
                    let v = if world == Mat4::IDENTITY { v } else { normal_matrix.transform_vector3(v) };
                    if v.is_finite() { v.normalize_or_zero() } else { Vec3::ZERO }
                })
                .collect(),
            None => {
                let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
                smooth_normals(&positions, &flat)
            }
        };
        let vec2 = Expect { dimensions: Dimensions::Vec2, types: TEXCOORDS, role: "TEXCOORD_0" };
        let uvs: Vec<Vec2> = attribute(gltf::Semantic::TexCoords(0), vec2)?
            .map(|raw| raw.chunks_exact(2).map(|c| Vec2::new(c[0] as f32, c[1] as f32)).collect())
            .unwrap_or_default();
        if uvs.iter().any(|uv: &Vec2| !uv.is_finite()) {
            return Err(context(Error::parse(path, None, "a texture coordinate is not finite")));
        }
        out.outline.push(format!(
            "{what} (node {}): {} triangles, {n} vertices{}{}, material {}",
            instance.node,
            triangles.len(),
            if p.get(&gltf::Semantic::Normals).is_some() { ", normals" } else { "" },
            if uvs.is_empty() { "" } else { ", texture coordinates" },
            p.material().index().map_or("default".into(), |i| i.to_string()),
        ));
        out.file.meshes.push(ObjMesh {
            name: if mesh_name.is_empty() { what.clone() } else { mesh_name.clone() },
            positions,
            normals,
            uvs,
            triangles,
            material: p.material().index(),
        });
    }
    Ok(())
}

/// The scene's camera from camera `index` placed by `world`: a look-at camera at the node's
/// origin, looking down its −z axis with its +y up, of the camera's vertical field of view.
/// Orthographic cameras are skipped with a warning.
fn camera(gltf: &gltf::Gltf, index: usize, world: Mat4, warnings: &mut Vec<String>, path: &Path) -> Option<CameraDesc> {
    let json = gltf.document.as_json().cameras.get(index)?;
    let Some(p) = &json.perspective else {
        warnings.push(format!("{}: camera {index} is orthographic, which is not supported; ignored", path.display()));
        return None;
    };
    let fov = p.yfov.to_degrees();
    let eye = world.transform_point3(Vec3::ZERO);
    let forward = world.transform_vector3(-Vec3::Z).normalize_or_zero();
    let up = world.transform_vector3(Vec3::Y).normalize_or_zero();
    if !(fov > 0.0 && fov < 180.0) || forward == Vec3::ZERO || up == Vec3::ZERO || !eye.is_finite() {
        warnings.push(format!("{}: camera {index} has no usable pose or field of view; ignored", path.display()));
        return None;
    }
    Some(CameraDesc::LookAt { eye, target: eye + forward, up, fov })
}
