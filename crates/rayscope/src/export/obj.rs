//! A scene's meshes as Wavefront OBJ and MTL text.
//!
//! Each mesh is an `o` object with its own `v`, `vt` (when it has texture coordinates) and
//! `vn` lines, its faces in order with a `usemtl` where the material changes. Numbers are
//! written in Rust's shortest form that reads back to the same `f32`, so positions, normals
//! and texture coordinates come back bit for bit. The MTL carries `Kd`, `Ks`, `Ns`, `d` and
//! `map_Kd`; a material's glossiness has no MTL statement and is not written.

use std::fmt::Write;

use super::{OutFile, TextureFiles, material_names};
use crate::error::Result;
use crate::scene::Scene;

/// The OBJ and MTL files of meshes `meshes` of `scene`, named `name.obj` and `name.mtl`;
/// returns the OBJ file's name and the files.
pub(crate) fn write(
    scene: &Scene,
    meshes: &[usize],
    name: &str,
    textures: &mut TextureFiles,
) -> Result<(String, Vec<OutFile>)> {
    let names = material_names(scene);
    let mut used = vec![false; scene.materials.len()];
    let mut obj = format!("# {} (rayscope export)\nmtllib {name}.mtl\n", scene.name.replace('\n', " "));
    // OBJ's indices count across the whole file, from 1.
    let (mut v0, mut t0) = (1usize, 1usize);
    for &i in meshes {
        let m = &scene.meshes[i];
        let _ = writeln!(
            obj,
            "o {}",
            if m.name.trim().is_empty() { format!("mesh-{i}") } else { m.name.replace('\n', " ") }
        );
        for p in &m.positions {
            let _ = writeln!(obj, "v {} {} {}", p.x, p.y, p.z);
        }
        for t in &m.uvs {
            let _ = writeln!(obj, "vt {} {}", t.x, t.y);
        }
        for n in &m.normals {
            let _ = writeln!(obj, "vn {} {} {}", n.x, n.y, n.z);
        }
        let has_uv = !m.uvs.is_empty();
        let has_n = !m.normals.is_empty();
        let mut current = None;
        for (tri, &mat) in m.triangles.iter().zip(&m.materials) {
            if current != Some(mat) {
                let _ = writeln!(obj, "usemtl {}", names[mat as usize]);
                used[mat as usize] = true;
                current = Some(mat);
            }
            obj.push('f');
            for &c in tri {
                let c = c as usize;
                let _ = match (has_uv, has_n) {
                    (true, true) => write!(obj, " {}/{}/{}", v0 + c, t0 + c, v0 + c),
                    (true, false) => write!(obj, " {}/{}", v0 + c, t0 + c),
                    (false, true) => write!(obj, " {}//{}", v0 + c, v0 + c),
                    (false, false) => write!(obj, " {}", v0 + c),
                };
            }
            obj.push('\n');
        }
        v0 += m.positions.len();
        t0 += m.uvs.len();
    }
    let mut mtl = String::from("# rayscope export\n");
    for (k, m) in scene.materials.iter().enumerate().filter(|&(k, _)| used[k]) {
        let _ = writeln!(mtl, "newmtl {}", names[k]);
        let _ = writeln!(mtl, "Kd {} {} {}", m.kd.x, m.kd.y, m.kd.z);
        let _ = writeln!(mtl, "Ks {} {} {}", m.ks.x, m.ks.y, m.ks.z);
        let _ = writeln!(mtl, "Ns {}", m.shininess);
        let _ = writeln!(mtl, "d {}", m.transparency);
        if let Some(t) = m.texture {
            let _ = writeln!(mtl, "map_Kd {}", textures.name(t)?);
        }
    }
    let obj_name = format!("{name}.obj");
    Ok((
        obj_name.clone(),
        vec![
            OutFile { name: obj_name, bytes: obj.into_bytes() },
            OutFile { name: format!("{name}.mtl"), bytes: mtl.into_bytes() },
        ],
    ))
}
