//! Wavefront OBJ/MTL loading through `tobj`, with line-accurate validation.
//!
//! `tobj` does the parsing and triangulation; before it runs, a light scan of the text checks
//! every number, index and statement so that a malformed file (or one that is no OBJ at all)
//! is reported with its line, never passed on as NaN geometry, an empty mesh or a panic, and
//! splits the `mtllib` lines into the names that [`super::mtl`] reads.

use std::cell::RefCell;
use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
#[cfg(test)]
use std::path::PathBuf;

use rayon::prelude::*;

use super::duplicates::without_duplicates;
use super::file::{BUFFER_BYTES, open};
use super::index_hash::{IndexHash, pack};
use super::lines::Lines;
use super::memory::MeshSize;
#[cfg(test)]
use super::mtl::parse_mtl;
use super::mtl::{ObjMaterial, read_mtl};
use super::obj_parallel::read_obj_parallel;
use crate::error::{Error, Result};
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

/// The contents of an OBJ file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjFile {
    /// The groups, in file order.
    pub meshes: Vec<ObjMesh>,
    /// The materials of the MTL files it uses.
    pub materials: Vec<ObjMaterial>,
    /// The file's vertex positions as listed (`v` lines of each group), for normalisation.
    pub raw_positions: Vec<Vec3>,
    /// What was accepted but ignored, one message each, naming the file and line.
    pub warnings: Vec<String>,
}

/// Load an OBJ file and the MTL files it names (regular files, within
/// [`super::file::max_file_bytes`]). The file is streamed, never held whole: read in parallel
/// by [`read_obj_parallel`] where it has the common forms only, else twice, by the scan that
/// checks it, then by `tobj`.
pub fn load_obj(path: &Path) -> Result<ObjFile> {
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let read_library = |mtl: &str| {
        let p = dir.join(mtl);
        read_mtl(Lines::File(&mut open(&p)?.buffered()), &p)
    };
    if let Some(file) = read_obj_parallel(path, || open(path), read_library)? {
        return Ok(file);
    }
    let mut reader = open(path)?.buffered();
    let scan = scan_obj(Lines::File(&mut reader), path)?;
    scan.size.reserve(path)?;
    let mut file = reader.into_inner();
    file.rewind()?;
    // tobj reads what the scan checked and no more, should the file have grown since.
    let faces = BufReader::with_capacity(BUFFER_BYTES, file.take(scan.bytes));
    read_obj(faces, scan, path, read_library)
}

/// Parse OBJ text. `path` names it in errors; `read_mtl` returns the path and text of an MTL
/// file named by `mtllib`. A file without faces is an error: it is not a mesh. (For the unit
/// tests: files are read by [`load_obj`].) The parallel reader and the checked one must agree:
/// where both read the text, their files are compared.
#[cfg(test)]
pub fn parse_obj(text: &str, path: &Path, read_mtl: impl Fn(&str) -> Result<(PathBuf, String)>) -> Result<ObjFile> {
    let read_library = |name: &str| read_mtl(name).and_then(|(p, t)| parse_mtl(&t, &p));
    let parallel = read_obj_parallel(path, || Ok(text.as_bytes()), read_library);
    let checked = parse_obj_checked(text, path, read_library);
    match (parallel, &checked) {
        (Ok(Some(fast)), Ok(file)) => assert_eq!(&fast, file, "the parallel reader differs on {text:?}"),
        (Ok(Some(fast)), Err(e)) => panic!("the parallel reader read {fast:?} where the checked one failed: {e}"),
        (Err(e), Ok(_)) => panic!("the parallel reader failed ({e}) where the checked one read {text:?}"),
        (Err(e), Err(c)) => assert_eq!(e.to_string(), c.to_string()),
        (Ok(None), _) => {}
    }
    checked
}

/// Parse OBJ text with the checked reader (the scan and `tobj`) only.
#[cfg(test)]
pub fn parse_obj_checked(
    text: &str,
    path: &Path,
    read_library: impl Fn(&str) -> Result<Vec<ObjMaterial>>,
) -> Result<ObjFile> {
    let scan = scan_obj(Lines::Text(text), path)?;
    read_obj(text.as_bytes(), scan, path, read_library)
}

/// Read the faces of an OBJ file that [`scan_obj`] checked (`scan`) with `tobj`, and its
/// materials with `read_mtl` (the materials of one MTL file, by its name in `mtllib`).
fn read_obj(
    faces: impl BufRead,
    scan: ObjScan,
    path: &Path,
    read_mtl: impl Fn(&str) -> Result<Vec<ObjMaterial>>,
) -> Result<ObjFile> {
    // `tobj` reads the faces and calls back for each `mtllib` line, in file order; the
    // libraries are read here, by the names the scan split (tobj takes the whole rest of the
    // line for one name). Our materials are numbered globally and tobj's list stays empty,
    // so the indices it gives groups are ours.
    let libraries = RefCell::new(scan.libraries.into_iter());
    let materials = RefCell::new(Vec::<ObjMaterial>::new());
    let mtl_error = RefCell::new(None);
    let load_library = |_: &Path| -> tobj::MTLLoadResult {
        let names = libraries.borrow_mut().next().unwrap_or_default();
        let mut materials = materials.borrow_mut();
        let mut by_name = Vec::new();
        for name in names {
            match read_mtl(&name) {
                Ok(read) => {
                    for m in read {
                        by_name.push((m.material.name.clone(), materials.len()));
                        materials.push(m);
                    }
                }
                Err(e) => {
                    mtl_error.borrow_mut().get_or_insert(e);
                    return Err(tobj::LoadError::OpenFileFailed);
                }
            }
        }
        Ok((Vec::new(), by_name.into_iter().collect()))
    };
    // tobj reads an `l` line of three or more vertices as a face: they are blanked (lines
    // kept, for tobj's count of them) by a filter, used only for files that have them.
    let loaded = if scan.polylines {
        load_faces(WithoutPolylines { inner: faces, line: Vec::new(), at: 0 }, path, load_library)
    } else {
        load_faces(faces, path, load_library)
    };
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let (models, _) = loaded?.map_err(|e| Error::parse(path, None, e.to_string()))?;
    let mut out = ObjFile { materials: materials.into_inner(), warnings: scan.warnings, ..ObjFile::default() };
    let mut duplicates = 0;
    // Each model is dropped once unified: tobj's copy and ours of one group at a time, not of
    // the whole file.
    for model in models {
        let mesh = &model.mesh;
        if mesh.indices.is_empty() {
            continue;
        }
        let mut positions = scan.size.vec(path, mesh.positions.len() / 3)?;
        positions.extend(mesh.positions.chunks_exact(3).map(Vec3::from_slice));
        out.raw_positions.try_reserve(positions.len()).map_err(|_| scan.size.out_of_memory(path))?;
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
        let has_n = !mesh.normals.is_empty() && mesh.normal_indices.len() == mesh.indices.len();
        let has_t = !mesh.texcoords.is_empty() && mesh.texcoord_indices.len() == mesh.indices.len();
        let normals: Vec<Vec3> = mesh.normals.chunks_exact(3).map(Vec3::from_slice).collect();
        let uvs: Vec<Vec2> = mesh.texcoords.chunks_exact(2).map(Vec2::from_slice).collect();
        let corners = Corners {
            positions,
            indices: &mesh.indices,
            normals: has_n.then_some((&normals[..], &mesh.normal_indices[..])),
            uvs: has_t.then_some((&uvs[..], &mesh.texcoord_indices[..])),
        };
        out.meshes.push(unify(&model.name, material, corners, &mut duplicates, scan.size, path)?);
    }
    finish(out, duplicates, path)
}

/// The file read, checked to have faces, with the warning of the `duplicates` dropped.
pub(super) fn finish(mut out: ObjFile, duplicates: usize, path: &Path) -> Result<ObjFile> {
    if out.meshes.is_empty() {
        return Err(Error::parse(path, None, "no faces (`f` lines): nothing to render"));
    }
    if duplicates > 0 {
        out.warnings.push(format!(
            "{}: {duplicates} duplicate face{} (the same three vertices, in the same order, as an earlier face of \
             its group) dropped",
            path.display(),
            if duplicates == 1 { "" } else { "s" }
        ));
    }
    Ok(out)
}

/// Run `tobj` over `faces`, calling `load_library` for each `mtllib` line.
fn load_faces(
    mut faces: impl BufRead,
    path: &Path,
    load_library: impl Fn(&Path) -> tobj::MTLLoadResult,
) -> Result<tobj::LoadResult> {
    let opts = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    // The scan admits only what tobj reads without error or panic; should a panic remain,
    // it is an error in this file, not the end of the program.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| tobj::load_obj_buf(&mut faces, &opts, load_library)))
        .map_err(|_| Error::parse(path, None, "the OBJ reader failed on this file"))
}

/// A reader of an OBJ file's lines in which `l` (polyline) lines are empty.
struct WithoutPolylines<R> {
    inner: R,
    /// The current line, as given on.
    line: Vec<u8>,
    /// How much of `line` was consumed.
    at: usize,
}

impl<R: BufRead> Read for WithoutPolylines<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.fill_buf()?.read(buf)?;
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for WithoutPolylines<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        if self.at == self.line.len() {
            self.line.clear();
            self.at = 0;
            self.inner.read_until(b'\n', &mut self.line)?;
            let head = self.line.split(u8::is_ascii_whitespace).find(|w| !w.is_empty());
            if head == Some(b"l") {
                self.line.clear();
                self.line.push(b'\n');
            }
        }
        Ok(&self.line[self.at..])
    }

    fn consume(&mut self, amount: usize) {
        self.at += amount;
    }
}

/// The corners of a group's triangles, three a triangle, as indices into its attributes.
pub(super) struct Corners<'a> {
    /// The group's positions, numbered in order of first use (as `tobj` numbers them).
    pub positions: Vec<Vec3>,
    /// Each corner's position.
    pub indices: &'a [u32],
    /// The normals and each corner's, when the group has them.
    pub normals: Option<(&'a [Vec3], &'a [u32])>,
    /// The texture coordinates and each corner's, when the group has them.
    pub uvs: Option<(&'a [Vec2], &'a [u32])>,
}

/// Builds one vertex per distinct (position, normal, uv) corner, generating smooth normals
/// (area-weighted, per position so texture seams stay smooth) when the group has none, and
/// drops duplicate faces (counted in `duplicates`). The large arrays are reserved fallibly:
/// the file's `size` and `path` make the error of a mesh that does not fit.
pub(super) fn unify(
    name: &str,
    material: Option<usize>,
    corners: Corners,
    duplicates: &mut usize,
    size: MeshSize,
    path: &Path,
) -> Result<ObjMesh> {
    let Corners { positions, indices, normals, uvs } = corners;
    let oom = |_| size.out_of_memory(path);
    let mut smooth = Vec::new();
    let (file_normals, normal_indices) = match normals {
        Some(given) => given,
        None => {
            smooth = smooth_normals(&positions, indices);
            (&smooth[..], indices)
        }
    };
    let mut out = ObjMesh { name: name.to_string(), material, ..ObjMesh::default() };
    if let Some(shared) = shared_attributes(positions.len(), indices, normal_indices, uvs.map(|(_, t)| t), size, path)?
    {
        // Vertices shared as the file shares them: vertex k is position k.
        match shared.normals {
            Some(normals) => {
                out.normals = size.vec(path, positions.len())?;
                out.normals.par_extend(normals.par_iter().map(|&n| file_normals[n as usize].normalize_or_zero()));
            }
            // Position k's smooth normal, normalised again as every vertex's normal is.
            None => {
                smooth.par_iter_mut().for_each(|n| *n = n.normalize_or_zero());
                out.normals = smooth;
            }
        }
        if let Some((uvs, _)) = uvs {
            out.uvs = size.vec(path, positions.len())?;
            out.uvs.extend(shared.uvs.iter().map(|&t| uvs[t as usize]));
        }
        out.positions = positions;
        out.positions.shrink_to_fit();
        out.triangles = without_duplicates(indices, duplicates, size, path)?;
        return Ok(out);
    }
    // As many vertices as positions, unless normals or texture coordinates split some.
    out.positions.try_reserve_exact(positions.len()).map_err(oom)?;
    out.normals.try_reserve_exact(positions.len()).map_err(oom)?;
    let mut map: HashMap<u128, u32, IndexHash> = HashMap::with_hasher(IndexHash::new());
    map.try_reserve(positions.len()).map_err(oom)?;
    let mut unified = size.vec(path, indices.len())?;
    for (k, &pi) in indices.iter().enumerate() {
        let ni = normal_indices[k];
        let ti = uvs.map_or(u32::MAX, |(_, t)| t[k]);
        let next = out.positions.len() as u32;
        let idx = *map.entry(pack([pi, ni, ti])).or_insert_with(|| {
            out.positions.push(positions[pi as usize]);
            out.normals.push(file_normals[ni as usize].normalize_or_zero());
            if let Some((uvs, _)) = uvs {
                out.uvs.push(uvs[ti as usize]);
            }
            next
        });
        unified.push(idx);
    }
    drop(map);
    out.positions.shrink_to_fit();
    out.normals.shrink_to_fit();
    out.triangles = without_duplicates(&unified, duplicates, size, path)?;
    Ok(out)
}

/// Each position's normal and texture coordinate index.
struct Shared {
    /// `None`: position k's normal is normal k (smooth normals, made per position).
    normals: Option<Vec<u32>>,
    uvs: Vec<u32>,
}

/// The normal and texture coordinate index of each of `count` positions, when every corner
/// of a position has the same ones and positions are numbered in order of first use: then
/// [`unify`]'s vertices are the positions, in their order, and no map of corners is needed.
fn shared_attributes(
    count: usize,
    positions: &[u32],
    normals: &[u32],
    uvs: Option<&[u32]>,
    size: MeshSize,
    path: &Path,
) -> Result<Option<Shared>> {
    if uvs.is_none() && std::ptr::eq(positions, normals) {
        // Normals indexed as the positions are (smooth ones): only the order is to check.
        let mut next = 0;
        for &p in positions {
            if p > next {
                return Ok(None);
            }
            next += u32::from(p == next);
        }
        return Ok((next as usize == count).then_some(Shared { normals: None, uvs: Vec::new() }));
    }
    let mut shared_normals = size.vec(path, count)?;
    let mut shared_uvs = size.vec(path, uvs.map_or(0, |_| count))?;
    for (k, &p) in positions.iter().enumerate() {
        let p = p as usize;
        let t = uvs.map(|t| t[k]);
        if p == shared_normals.len() {
            shared_normals.push(normals[k]);
            shared_uvs.extend(t);
        } else if p > shared_normals.len() || shared_normals[p] != normals[k] || t.is_some_and(|t| shared_uvs[p] != t) {
            return Ok(None);
        }
    }
    Ok((shared_normals.len() == count).then_some(Shared { normals: Some(shared_normals), uvs: shared_uvs }))
}

/// Area-weighted vertex normals: the sum of the (unnormalised) face normals around a vertex.
/// On every core, each task summing around its own range of vertices: every task reads
/// every face's corners, and computes the normals of the faces that touch its range only,
/// adding them in face order as one pass over the faces would (the same sums, bit for bit,
/// on any number of threads).
pub fn smooth_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; positions.len()];
    let per_task = positions.len().div_ceil(rayon::current_num_threads()).max(VERTICES_PER_TASK);
    n.par_chunks_mut(per_task).enumerate().for_each(|(k, sums)| {
        let (first, len) = ((k * per_task) as u32, sums.len() as u32);
        for t in indices.chunks_exact(3) {
            // Corners relative to the range: below it they wrap around, above `len`.
            let rel = [t[0], t[1], t[2]].map(|i| i.wrapping_sub(first));
            if rel.iter().all(|&r| r >= len) {
                continue;
            }
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
            let face = (b - a).cross(c - a);
            for r in rel {
                if r < len {
                    sums[r as usize] += face;
                }
            }
        }
    });
    n.par_iter_mut().for_each(|v| *v = v.normalize_or_zero());
    n
}

/// The fewest vertices [`smooth_normals`] gives a task: each task reads all the faces.
const VERTICES_PER_TASK: usize = 1 << 16;

/// The statements of the elements faces index: positions, texture coordinates, normals.
const ELEMENTS: [&str; 3] = ["v", "vt", "vn"];

/// What [`ELEMENTS`] are, in messages.
const ELEMENT_NAMES: [&str; 3] = ["vertex", "texture coordinate", "normal"];

/// The warning of faces that give indices of element `k` (1: `vt`, 2: `vn`) in a file without
/// any, first at `line`.
pub(super) fn missing_warning(path: &Path, k: usize, line: usize) -> String {
    format!(
        "{}:{line}: faces give {} indices but the file has no `{}` lines; they are ignored",
        path.display(),
        ELEMENT_NAMES[k],
        ELEMENTS[k]
    )
}

/// The numbers of a line, between `min` and `max` of them, all finite.
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

/// What the scan of an OBJ file found besides errors.
struct ObjScan {
    /// The MTL file names of each `mtllib` line, in file order.
    libraries: Vec<Vec<String>>,
    /// Accepted but ignored, naming the file and line.
    warnings: Vec<String>,
    /// Whether there are `l` (polyline) lines, which tobj would read as faces.
    polylines: bool,
    /// The bytes scanned: all of the file.
    bytes: u64,
    /// Its triangles and vertices.
    size: MeshSize,
}

/// The statements of the OBJ format; a line starting with anything else is not OBJ.
const STATEMENTS: &[&str] = &[
    "v",
    "vt",
    "vn",
    "vp",
    "f",
    "l",
    "p",
    "o",
    "g",
    "s",
    "mg",
    "mtllib",
    "usemtl",
    "usemap",
    "maplib",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "call",
    "csh",
];

/// Check every line before `tobj` reads the file, so that what it would reject, or read as
/// NaN geometry, is an error at its line: numbers parse and are finite, face indices refer to
/// elements defined before them (OBJ's rule), faces have at least three corners, and every
/// statement is OBJ's. Faces that give texture coordinate (or normal) indices in a file
/// without any `vt` (`vn`) lines are accepted with a warning, as other readers do.
fn scan_obj(lines: Lines, path: &Path) -> Result<ObjScan> {
    let mut scan =
        ObjScan { libraries: Vec::new(), warnings: Vec::new(), polylines: false, bytes: 0, size: MeshSize::default() };
    let mut counts = [0i64; 3]; // v, vt, vn
    // The first line whose face refers to texture coordinates or normals when none exist.
    let mut missing: [Option<usize>; 3] = [None; 3];
    let mut colored = false;
    scan.bytes = lines.for_each(path, |n, line| {
        let err = |message: String| Error::parse(path, Some(n), message);
        let mut words = line.split_whitespace();
        let Some(head) = words.next() else { return Ok(()) };
        if head.starts_with('#') {
            return Ok(());
        }
        let rest: Vec<&str> = words.collect();
        match head {
            "v" => {
                // x y z, then nothing, a weight w, or a colour r g b (tobj's reading).
                if ![3, 4, 6].contains(&rest.len()) {
                    return Err(err(format!("expected 3, 4 or 6 numbers, found {}", rest.len())));
                }
                parse_floats(path, n, &rest, 3, 6)?;
                if let [x, y, z, w] = rest[..] {
                    // tobj divides by the weight.
                    let [x, y, z, w] = [x, y, z, w].map(|s| s.parse::<f32>().unwrap_or(f32::NAN));
                    if !(x / w).is_finite() || !(y / w).is_finite() || !(z / w).is_finite() {
                        return Err(err(format!("the weight {w} makes the vertex infinite")));
                    }
                }
                // tobj pairs colours with vertices by position in its list.
                if counts[0] > 0 && colored != (rest.len() == 6) {
                    return Err(err("vertex colours are given for some vertices only".into()));
                }
                colored = rest.len() == 6;
                counts[0] += 1;
            }
            "vt" => {
                parse_floats(path, n, &rest, 2, 3)?;
                counts[1] += 1;
            }
            "vn" => {
                parse_floats(path, n, &rest, 3, 3)?;
                counts[2] += 1;
            }
            "f" | "l" => {
                let face = head == "f";
                scan.polylines |= !face;
                if face && rest.len() < 3 {
                    return Err(err(format!("a face needs at least 3 vertices, found {}", rest.len())));
                }
                if face {
                    scan.size.triangles += rest.len() as u64 - 2;
                }
                for corner in &rest {
                    let invalid = || err(format!("'{corner}' is not a valid face vertex"));
                    for (k, part) in corner.split('/').enumerate() {
                        if k > 2 {
                            return Err(invalid());
                        }
                        if part.is_empty() && k > 0 {
                            continue;
                        }
                        let idx: i64 = part.parse().map_err(|_| invalid())?;
                        // Polylines are not drawn (nor given to tobj); only their syntax matters.
                        if !face {
                            continue;
                        }
                        let count = counts[k];
                        if count == 0 && k > 0 {
                            missing[k].get_or_insert(n);
                            continue;
                        }
                        let ok = if idx > 0 { idx <= count } else { idx < 0 && -idx <= count };
                        if !ok {
                            let what = ["vertex", "texture coordinate", "normal"][k];
                            return Err(err(format!("{what} index {idx} is out of range ({count} defined so far)")));
                        }
                    }
                }
            }
            "mtllib" => {
                if rest.is_empty() {
                    return Err(err("mtllib names no file".into()));
                }
                // The format's `mtllib a.mtl b.mtl`: several libraries, all read.
                scan.libraries.push(rest.iter().map(|s| s.to_string()).collect());
            }
            // tobj takes the name after the first space.
            "usemtl" if line.split_once(' ').is_none_or(|(_, name)| name.trim().is_empty()) => {
                return Err(err("usemtl names no material".into()));
            }
            _ if STATEMENTS.contains(&head) => {}
            _ => {
                let shown: String = line.chars().take(60).collect();
                return Err(err(format!("not an OBJ statement: '{}' (is this a mesh file?)", shown.escape_debug())));
            }
        }
        Ok(())
    })?;
    scan.size.vertices = counts.iter().sum::<i64>() as u64;
    for k in 1..3 {
        match missing[k] {
            // Elements defined after the faces that refer to them break OBJ's rule.
            Some(line) if counts[k] > 0 => {
                return Err(Error::parse(
                    path,
                    Some(line),
                    format!("{} index refers to no `{}` line before it", ELEMENT_NAMES[k], ELEMENTS[k]),
                ));
            }
            Some(line) => scan.warnings.push(missing_warning(path, k, line)),
            None => {}
        }
    }
    Ok(scan)
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

    /// The normals summed around ranges of vertices on several threads are the bits of one
    /// pass over the faces (faces in random order, touching several ranges).
    #[test]
    fn smooth_normals_on_many_threads_are_one_pass_sums() {
        let mut seed = 7u64;
        let mut next = |m: u64| {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 33) % m
        };
        let positions: Vec<Vec3> = (0..3 * VERTICES_PER_TASK)
            .map(|_| Vec3::new(next(1000) as f32, next(1000) as f32, next(1000) as f32) * 1e-3)
            .collect();
        let indices: Vec<u32> = (0..6 * positions.len()).map(|_| next(positions.len() as u64) as u32).collect();
        let mut want = vec![Vec3::ZERO; positions.len()];
        for t in indices.chunks_exact(3) {
            let face = (positions[t[1] as usize] - positions[t[0] as usize])
                .cross(positions[t[2] as usize] - positions[t[0] as usize]);
            t.iter().for_each(|&i| want[i as usize] += face);
        }
        let want: Vec<Vec3> = want.iter().map(|v| v.normalize_or_zero()).collect();
        for threads in [1, 2, 5] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let got = pool.install(|| smooth_normals(&positions, &indices));
            assert!(
                got.iter().zip(&want).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)),
                "{threads} threads"
            );
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
        assert_eq!(err_line("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\nvt 0 0\n").0, Some(4));
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

    /// An OBJ text of `v` positions, `t` texture coordinates and `n` normals, then faces
    /// (each given as corners of (position, uv, normal) choices, relative or absolute) among
    /// group and material statements, with the line ending `end`.
    fn generated(v: usize, t: usize, n: usize, faces: &[(u8, Vec<(usize, u8)>)], end: &str) -> String {
        let mut text = format!("# generated{end}mtllib m.mtl{end}");
        for i in 0..v {
            text += &format!("v {} {:.3} -{}e-1{end}", i as f32 * 0.37, i as f32 / 7.0, i % 5);
        }
        for i in 0..t {
            text += &format!("vt {} {}{end}", i as f32 * 0.1, 0.5);
        }
        for i in 0..n {
            text += &format!("vn 0 {} 1{end}", i % 3);
        }
        for (statement, corners) in faces {
            match statement % 8 {
                0 => text += &format!("g part{statement}{end}"),
                1 => text += &format!("usemtl {}{end}", ["red", "blue", "none"][*statement as usize % 3]),
                2 => text += &format!("o{end}s 1{end}{end}"),
                _ => {}
            }
            text += "f";
            for &(c, form) in corners {
                let rel = |count: usize| {
                    if form & 8 != 0 { format!("-{}", count - c % count) } else { format!("{}", c % count + 1) }
                };
                text += &match (form % 4, t > 0, n > 0) {
                    (1, true, _) => format!(" {}/{}", rel(v), rel(t)),
                    (2, _, true) => format!(" {}//{}", rel(v), rel(n)),
                    (3, true, true) => format!(" {}/{}/{}", rel(v), rel(t), rel(n)),
                    _ => format!(" {}", rel(v)),
                };
            }
            text += end;
        }
        text
    }

    proptest::proptest! {
        #[test]
        fn the_parallel_reader_equals_the_checked_one(
            v in 3usize..12,
            t in 0usize..4,
            n in 0usize..4,
            faces in proptest::collection::vec(
                (0u8..24, proptest::collection::vec((0usize..40, 0u8..16), 3..6)), 1..12),
            crlf in proptest::bool::ANY,
        ) {
            let text = generated(v, t, n, &faces, if crlf { "\r\n" } else { "\n" });
            let mtl = |_: &str| Ok((PathBuf::from("m.mtl"), "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n".to_string()));
            let read_library = |name: &str| mtl(name).and_then(|(p, t)| parse_mtl(&t, &p));
            // Both readers read it (`parse_obj` compares them), and the fast one did not give it back.
            parse_obj(&text, Path::new("g.obj"), mtl).unwrap();
            let fast = read_obj_parallel(Path::new("g.obj"), || Ok(text.as_bytes()), read_library).unwrap();
            proptest::prop_assert!(fast.is_some(), "given back: {text:?}");
        }
    }

    #[test]
    fn mixed_corners_and_late_elements_read_alike() {
        // Corners without normals in a file with some (tobj gives them the previous corner's),
        // normals after the faces (the group has them: they are read before it ends),
        // and texture coordinate indices in a file without any (a warning).
        for text in [
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 1 0\nf 1//2 2 3//1\nf 3 2 1\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nvn 0 0 1\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/2 3/3\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ng a\nf 1 2 3\ng b\nf 2 4 3\nf 3 2 4\nf 1 2 3 4\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2 3\nf 1 2/1 3\n",
        ] {
            parse(text).unwrap();
        }
    }
}
