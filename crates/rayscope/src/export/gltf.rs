//! A scene's meshes as glTF 2.0: a `.gltf` JSON document and its `.bin` buffer.
//!
//! Each mesh is a node (no transform: the vertices are in world space) whose mesh has one
//! primitive per run of triangles of one material, sharing the mesh's POSITION, NORMAL and
//! TEXCOORD_0 accessors, with 32-bit indices. Materials carry glTF factors for other programs
//! and the exact Phong values in their `extras`, which rayscope reads back
//! ([`crate::io::gltf::material`]); textures are PNG files beside the document, upside down
//! (glTF's texture coordinates start at the image's top, rayscope's at its bottom).

use serde_json::{Value, json};

use super::{OutFile, TextureFiles, material_names};
use crate::error::Result;
use crate::io::gltf::material::{Extras, PhongExtras, pbr_from_phong};
use crate::scene::Scene;

/// glTF's component type numbers.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
/// glTF's buffer view targets.
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The buffer and the views and accessors into it, as they are added.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// Add `bytes` as a buffer view and an accessor of `count` elements of type `kind`
    /// (component type `component`); returns the accessor's index.
    fn add(
        &mut self,
        bytes: &[u8],
        count: usize,
        kind: &str,
        component: u32,
        target: u32,
        bounds: Option<(Value, Value)>,
    ) -> usize {
        // Views start on 4-byte boundaries (every component here is 4 bytes).
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len(), "target": target
        }));
        self.bin.extend_from_slice(bytes);
        let mut accessor = json!({
            "bufferView": self.views.len() - 1, "componentType": component, "count": count, "type": kind
        });
        if let Some((min, max)) = bounds {
            accessor["min"] = min;
            accessor["max"] = max;
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }
}

fn floats(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// The glTF document and buffer of meshes `meshes` of `scene`, named `name.gltf` and
/// `name.bin`; returns the document's name and the files.
pub(crate) fn write(
    scene: &Scene,
    meshes: &[usize],
    name: &str,
    textures: &mut TextureFiles,
) -> Result<(String, Vec<OutFile>)> {
    let names = material_names(scene);
    let mut b = Builder::default();
    let mut material_index: Vec<Option<usize>> = vec![None; scene.materials.len()];
    let mut materials = Vec::new();
    let mut images: Vec<Value> = Vec::new();
    let mut texture_index = std::collections::HashMap::new();
    let mut gltf_meshes = Vec::new();
    let mut nodes = Vec::new();
    for &i in meshes {
        let m = &scene.meshes[i];
        let positions = b.add(
            &floats(m.positions.iter().flat_map(|p| p.to_array())),
            m.positions.len(),
            "VEC3",
            FLOAT,
            ARRAY_BUFFER,
            bounds(&m.positions),
        );
        let mut attributes = json!({ "POSITION": positions });
        if !m.normals.is_empty() {
            let normals = b.add(
                &floats(m.normals.iter().flat_map(|n| n.to_array())),
                m.normals.len(),
                "VEC3",
                FLOAT,
                ARRAY_BUFFER,
                None,
            );
            attributes["NORMAL"] = json!(normals);
        }
        if !m.uvs.is_empty() {
            let uvs =
                b.add(&floats(m.uvs.iter().flat_map(|t| t.to_array())), m.uvs.len(), "VEC2", FLOAT, ARRAY_BUFFER, None);
            attributes["TEXCOORD_0"] = json!(uvs);
        }
        let mut primitives = Vec::new();
        let mut start = 0;
        while start < m.triangles.len() {
            let mat = m.materials[start];
            let end = m.materials[start..].iter().position(|&x| x != mat).map_or(m.triangles.len(), |k| start + k);
            let indices: Vec<u8> = m.triangles[start..end].iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
            let acc = b.add(&indices, (end - start) * 3, "SCALAR", UNSIGNED_INT, ELEMENT_ARRAY_BUFFER, None);
            let material = match material_index[mat as usize] {
                Some(k) => k,
                None => {
                    let source = &scene.materials[mat as usize];
                    let pbr = pbr_from_phong(source);
                    let mut value = json!({
                        "name": names[mat as usize],
                        "pbrMetallicRoughness": {
                            "baseColorFactor": pbr.base_color,
                            "metallicFactor": pbr.metallic,
                            "roughnessFactor": pbr.roughness,
                        },
                        "alphaMode": if pbr.alpha_mode == ::gltf::material::AlphaMode::Blend { "BLEND" } else { "OPAQUE" },
                        "doubleSided": true,
                        "extras": serde_json::to_value(Extras { rayscope: PhongExtras::of(source) })
                            .expect("plain numbers serialise"),
                    });
                    if let Some(t) = source.texture {
                        let next = texture_index.len();
                        let index = match texture_index.entry(t) {
                            std::collections::hash_map::Entry::Occupied(e) => *e.get(),
                            std::collections::hash_map::Entry::Vacant(e) => {
                                images.push(json!({ "uri": textures.name(t)? }));
                                *e.insert(next)
                            }
                        };
                        value["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": index });
                    }
                    materials.push(value);
                    material_index[mat as usize] = Some(materials.len() - 1);
                    materials.len() - 1
                }
            };
            primitives.push(json!({ "attributes": attributes, "indices": acc, "material": material, "mode": 4 }));
            start = end;
        }
        gltf_meshes.push(json!({ "name": m.name, "primitives": primitives }));
        nodes.push(json!({ "name": m.name, "mesh": gltf_meshes.len() - 1 }));
    }
    let textures_json: Vec<Value> = (0..images.len()).map(|k| json!({ "source": k })).collect();
    let bin_name = format!("{name}.bin");
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "rayscope" },
        "scene": 0,
        "scenes": [{ "name": scene.name, "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": gltf_meshes,
        "materials": materials,
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{ "uri": bin_name, "byteLength": b.bin.len() }],
    });
    if !images.is_empty() {
        doc["images"] = json!(images);
        doc["textures"] = json!(textures_json);
    }
    let gltf_name = format!("{name}.gltf");
    let text = serde_json::to_string_pretty(&doc).expect("a JSON value serialises");
    Ok((
        gltf_name.clone(),
        vec![OutFile { name: gltf_name, bytes: text.into_bytes() }, OutFile { name: bin_name, bytes: b.bin }],
    ))
}

/// The POSITION accessor's `min` and `max`, which glTF requires.
fn bounds(positions: &[crate::math::Vec3A]) -> Option<(Value, Value)> {
    let min = positions.iter().copied().reduce(|a, b| a.min(b))?;
    let max = positions.iter().copied().reduce(|a, b| a.max(b))?;
    Some((json!(min.to_array()), json!(max.to_array())))
}
