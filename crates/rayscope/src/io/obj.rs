//! Wavefront OBJ/MTL loading through `tobj`, with line-accurate validation.
//!
//! `tobj` does the parsing and triangulation; before it runs, a light scan of the text checks
//! every number and index so that a malformed file is reported with its line, never passed on
//! as NaN geometry or a panic.

use std::collections::HashMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use super::file::read_text;
use crate::error::{Error, Result};
use crate::material::Material;
use crate::math::{Vec2, Vec3};

/// One group of faces sharing a material, with unified per-corner vertex attributes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjMesh {
    /// Group or object name.
    pub name: String,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Vertex normals: as given, or area-weighted smooth normals when the file has none.
    pub normals: Vec<Vec3>,
    /// Texture coordinates (empty when the file has none for this group).
    pub uvs: Vec<Vec2>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Index into [`ObjFile::materials`], or `None` for the default material.
    pub material: Option<usize>,
}

/// A material read from an MTL file, with the texture it names (not yet loaded).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjMaterial {
    /// The Phong parameters (its `texture` is unset).
    pub material: Material,
    /// `map_Kd`, resolved against the OBJ file's folder (where its MTL files are).
    pub texture: Option<PathBuf>,
}

/// The contents of an OBJ file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjFile {
    /// The groups, in file order.
    pub meshes: Vec<ObjMesh>,
    /// The materials of the MTL files it uses.
    pub materials: Vec<ObjMaterial>,
    /// The file's vertex positions as listed (`v` lines of each group), for normalisation.
    pub raw_positions: Vec<Vec3>,
}

/// Load an OBJ file and the MTL files it names (regular files, within
/// [`super::file::max_file_bytes`]).
pub fn load_obj(path: &Path) -> Result<ObjFile> {
    let text = read_text(path)?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    parse_obj(&text, path, |mtl| {
        let p = dir.join(mtl);
        read_text(&p).map(|t| (p, t))
    })
}

/// Parse OBJ text. `path` names it in errors; `read_mtl` returns the path and text of an MTL
/// file named by `mtllib`.
pub fn parse_obj(text: &str, path: &Path, read_mtl: impl Fn(&str) -> Result<(PathBuf, String)>) -> Result<ObjFile> {
    scan_obj(text, path)?;
    let opts = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let mtl_error = std::cell::RefCell::new(None);
    let (models, materials) = tobj::load_obj_buf(&mut BufReader::new(text.as_bytes()), &opts, |mtl_path| {
        let name = mtl_path.to_string_lossy();
        match read_mtl(&name).and_then(|(p, t)| parse_mtl(&t, &p).map(|()| (p, t))) {
            Ok((p, t)) => tobj::load_mtl_buf(&mut BufReader::new(t.as_bytes())).inspect_err(|e| {
                *mtl_error.borrow_mut() = Some(Error::parse(&p, None, e.to_string()));
            }),
            Err(e) => {
                *mtl_error.borrow_mut() = Some(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    })
    .map_err(|e| Error::parse(path, None, e.to_string()))?;
    let materials = match (materials, mtl_error.into_inner()) {
        (_, Some(e)) => return Err(e),
        (Ok(m), None) => m,
        (Err(e), None) => return Err(Error::parse(path, None, e.to_string())),
    };
    let mut out = ObjFile::default();
    let dir = path.parent().unwrap_or(Path::new(""));
    out.materials = materials.iter().map(|m| convert_material(m, dir)).collect();
    for model in models {
        let mesh = &model.mesh;
        if mesh.indices.is_empty() {
            continue;
        }
        let positions: Vec<Vec3> = mesh.positions.chunks_exact(3).map(Vec3::from_slice).collect();
        out.raw_positions.extend_from_slice(&positions);
        let material = match mesh.material_id {
            Some(i) if i < out.materials.len() => Some(i),
            Some(i) => {
                return Err(Error::parse(
                    path,
                    None,
                    format!("group '{}' uses material #{i}, which no MTL defines", model.name),
                ));
            }
            None => None,
        };
        out.meshes.push(unify(&model.name, mesh, positions, material));
    }
    Ok(out)
}

/// Builds one vertex per distinct (position, normal, uv) corner, generating smooth normals
/// (area-weighted, per position so texture seams stay smooth) when the group has none.
fn unify(name: &str, mesh: &tobj::Mesh, positions: Vec<Vec3>, material: Option<usize>) -> ObjMesh {
    let has_n = !mesh.normals.is_empty() && mesh.normal_indices.len() == mesh.indices.len();
    let has_t = !mesh.texcoords.is_empty() && mesh.texcoord_indices.len() == mesh.indices.len();
    let file_normals: Vec<Vec3> = if has_n {
        mesh.normals.chunks_exact(3).map(Vec3::from_slice).collect()
    } else {
        smooth_normals(&positions, &mesh.indices)
    };
    let uvs: Vec<Vec2> = mesh.texcoords.chunks_exact(2).map(Vec2::from_slice).collect();
    let mut out = ObjMesh { name: name.to_string(), material, ..ObjMesh::default() };
    let mut map: HashMap<(u32, u32, u32), u32> = HashMap::with_capacity(positions.len());
    let mut corners = Vec::with_capacity(mesh.indices.len());
    for (k, &pi) in mesh.indices.iter().enumerate() {
        let ni = if has_n { mesh.normal_indices[k] } else { pi };
        let ti = if has_t { mesh.texcoord_indices[k] } else { u32::MAX };
        let next = out.positions.len() as u32;
        let idx = *map.entry((pi, ni, ti)).or_insert_with(|| {
            out.positions.push(positions[pi as usize]);
            out.normals.push(file_normals[ni as usize].normalize_or_zero());
            if has_t {
                out.uvs.push(uvs[ti as usize]);
            }
            next
        });
        corners.push(idx);
    }
    out.triangles = corners.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    out
}

/// Area-weighted vertex normals: the sum of the (unnormalised) face normals around a vertex.
pub fn smooth_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        let face = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += face;
        }
    }
    n.iter().map(|v| v.normalize_or_zero()).collect()
}

fn convert_material(m: &tobj::Material, dir: &Path) -> ObjMaterial {
    let d = Material::default();
    let material = Material {
        name: m.name.clone(),
        kd: m.diffuse.map(Vec3::from).unwrap_or(d.kd),
        ks: m.specular.map(Vec3::from).unwrap_or(d.ks),
        shininess: m.shininess.unwrap_or(d.shininess),
        transparency: m.dissolve.unwrap_or(1.0).clamp(0.0, 1.0),
        texture: None,
        glossiness: None,
    };
    // Textures are named relative to the MTL file, which `mtllib` names relative to the OBJ.
    let texture = m.diffuse_texture.as_deref().map(str::trim).filter(|t| !t.is_empty()).map(|t| dir.join(t));
    ObjMaterial { material, texture }
}

fn parse_floats(path: &Path, line_no: usize, words: &[&str], min: usize, max: usize) -> Result<()> {
    if words.len() < min || words.len() > max {
        return Err(Error::parse(
            path,
            Some(line_no),
            format!("expected {min} to {max} numbers, found {}", words.len()),
        ));
    }
    for w in words {
        let v: f32 = w.parse().map_err(|_| Error::parse(path, Some(line_no), format!("'{w}' is not a number")))?;
        if !v.is_finite() {
            return Err(Error::parse(path, Some(line_no), format!("'{w}' is not a finite number")));
        }
    }
    Ok(())
}

/// Check every `v`, `vt`, `vn` and `f` line: numbers parse and are finite, face indices refer
/// to elements defined before them (OBJ's rule), and faces have at least three corners.
fn scan_obj(text: &str, path: &Path) -> Result<()> {
    let mut counts = [0i64; 3]; // v, vt, vn
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let mut words = line.split_whitespace();
        let Some(head) = words.next() else { continue };
        let rest: Vec<&str> = words.collect();
        match head {
            "v" => {
                parse_floats(path, n, &rest, 3, 7)?;
                counts[0] += 1;
            }
            "vt" => {
                parse_floats(path, n, &rest, 1, 3)?;
                counts[1] += 1;
            }
            "vn" => {
                parse_floats(path, n, &rest, 3, 3)?;
                counts[2] += 1;
            }
            "f" => {
                if rest.len() < 3 {
                    return Err(Error::parse(
                        path,
                        Some(n),
                        format!("a face needs at least 3 vertices, found {}", rest.len()),
                    ));
                }
                for corner in &rest {
                    for (k, part) in corner.split('/').enumerate().take(3) {
                        if part.is_empty() && k > 0 {
                            continue;
                        }
                        let idx: i64 = part.parse().map_err(|_| {
                            Error::parse(path, Some(n), format!("'{corner}' is not a valid face vertex"))
                        })?;
                        let count = counts[[0, 1, 2][k]];
                        let ok = if idx > 0 { idx <= count } else { idx < 0 && -idx <= count };
                        if !ok {
                            let what = ["vertex", "texture coordinate", "normal"][k];
                            return Err(Error::parse(
                                path,
                                Some(n),
                                format!("{what} index {idx} is out of range ({count} defined so far)"),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Check the numeric fields of an MTL file (`Kd`, `Ks`, `Ka`, `Ke`, `Ns`, `d`, `Tr`, `Ni`).
pub fn parse_mtl(text: &str, path: &Path) -> Result<()> {
    for (i, line) in text.lines().enumerate() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.first().copied() {
            Some("Kd" | "Ks" | "Ka" | "Ke" | "Tf") => parse_floats(path, i + 1, &words[1..], 1, 3)?,
            Some("Ns" | "d" | "Ni") => parse_floats(path, i + 1, &words[1..], 1, 1)?,
            Some("Tr") => parse_floats(path, i + 1, &words[1..], 1, 2)?,
            Some("map_Kd") if words.len() < 2 => {
                return Err(Error::parse(path, Some(i + 1), "map_Kd names no file"));
            }
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_mtl(name: &str) -> Result<(PathBuf, String)> {
        Err(Error::io(name, std::io::Error::from(std::io::ErrorKind::NotFound)))
    }

    fn parse(text: &str) -> Result<ObjFile> {
        parse_obj(text, Path::new("test.obj"), no_mtl)
    }

    fn err_line(text: &str) -> (Option<usize>, String) {
        match parse(text) {
            Err(Error::Parse { line, message, .. }) => (line, message),
            other => panic!("expected a parse error, got {other:?}"),
        }
    }

    #[test]
    fn quad_is_triangulated_with_smooth_normals() {
        let f = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        assert_eq!(f.meshes.len(), 1);
        let m = &f.meshes[0];
        assert_eq!(m.triangles.len(), 2);
        assert!(m.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
        assert_eq!(f.raw_positions.len(), 4);
    }

    #[test]
    fn given_normals_and_uvs_are_kept() {
        let f = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 -1\nf 1/1/1 2/2/1 3/3/1\n").unwrap();
        let m = &f.meshes[0];
        assert_eq!(m.normals, vec![-Vec3::Z; 3]);
        assert_eq!(m.uvs[1], Vec2::new(1.0, 0.0));
    }

    #[test]
    fn negative_indices_are_relative() {
        let f = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n").unwrap();
        assert_eq!(f.meshes[0].triangles.len(), 1);
    }

    #[test]
    fn malformed_lines_are_reported_with_their_line() {
        assert_eq!(err_line("v 0 0 0\nv 1 x 0\n").0, Some(2));
        assert_eq!(err_line("v 0 0 0\nv nan 0 0\n").0, Some(2));
        assert_eq!(err_line("v 0 0\n").0, Some(1));
        let (line, msg) = err_line("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
        assert_eq!(line, Some(4));
        assert!(msg.contains("out of range"), "{msg}");
        assert_eq!(err_line("v 0 0 0\nv 1 0 0\nf 1 2\n").0, Some(3));
        assert_eq!(err_line("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\n").0, Some(4));
        assert_eq!(err_line("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n").0, Some(4));
    }

    #[test]
    fn materials_are_read_and_checked() {
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n";
        let good =
            |_: &str| Ok((PathBuf::from("m.mtl"), "newmtl red\nKd 1 0 0\nKs 0.5 0.5 0.5\nNs 20\nd 0.5\n".to_string()));
        let f = parse_obj(obj, Path::new("t.obj"), good).unwrap();
        let m = &f.materials[f.meshes[0].material.unwrap()].material;
        assert_eq!((m.kd, m.ks, m.shininess, m.transparency), (Vec3::X, Vec3::splat(0.5), 20.0, 0.5));
        let bad = |_: &str| Ok((PathBuf::from("m.mtl"), "newmtl red\nKd 1 zero 0\n".to_string()));
        match parse_obj(obj, Path::new("t.obj"), bad) {
            Err(Error::Parse { path, line, .. }) => {
                assert_eq!((path, line), (PathBuf::from("m.mtl"), Some(2)))
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(parse_obj(obj, Path::new("t.obj"), no_mtl), Err(Error::Io { .. })));
    }
}
