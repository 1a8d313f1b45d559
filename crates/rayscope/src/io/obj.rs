//! Wavefront OBJ/MTL loading: the text read in large blocks, each split at line ends into
//! chunks that parse on all cores ([`super::obj_chunk`]), put together in file order here.
//!
//! Every line is checked as it is parsed, so that a malformed file (or one that is no OBJ at
//! all) is an error at its line, never NaN geometry, an empty mesh or a panic. What the faces
//! mean follows the reader rayscope used before (`tobj`, kept as the tests' oracle): a group
//! (`o`, `g`) or a change of material (`usemtl`) starts a new mesh, faces are fanned from
//! their first corner, a group's vertices are the positions its faces use in the order they
//! first use them, one per distinct (position, normal, texture coordinate) corner.

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;
#[cfg(test)]
use std::path::PathBuf;

use rayon::prelude::*;

use super::duplicates::without_duplicates;
use super::file::{Bounded, open};
use super::index_hash::{IndexHash, pack};
use super::lines::Lines;
use super::memory::MeshSize;
#[cfg(test)]
use super::mtl::parse_mtl;
use super::mtl::{ObjMaterial, read_mtl};
use super::obj_chunk::{Before, Chunk, MISSING, Statement, parse_chunk, resolve};
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

/// The bytes read at a time: the text the threads share out, and all of the file held at once
/// (with the part line carried to the next block).
const BLOCK_BYTES: usize = 16 << 20;

/// The bytes of a chunk of lines that one thread parses (the last line of it whole): small
/// enough for a block to give every core several, large enough that a chunk's start costs
/// nothing.
const CHUNK_BYTES: usize = 512 << 10;

/// Load an OBJ file and the MTL files it names (regular files, within
/// [`super::file::max_file_bytes`]). The file is read once, in blocks, never held whole.
pub fn load_obj(path: &Path) -> Result<ObjFile> {
    load_obj_split(path, BLOCK_BYTES, CHUNK_BYTES)
}

/// [`load_obj`], reading `block_bytes` at a time in chunks of `chunk_bytes` (the tests split
/// small files as large ones are).
fn load_obj_split(path: &Path, block_bytes: usize, chunk_bytes: usize) -> Result<ObjFile> {
    let mut file = open(path)?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mut assembler = Assembler::new(path, chunk_bytes, |mtl: &str| {
        let p = dir.join(mtl);
        read_mtl(Lines::File(&mut open(&p)?.buffered()), &p)
    });
    let mut block: Vec<u8> = Vec::new();
    loop {
        let start = block.len();
        let eof = read_block(&mut file, &mut block, block_bytes)?;
        // Whole lines only, but a line without end that holds a NUL byte goes as it is: a
        // file of zeros fails at its first block, not after being read whole.
        let end = match memchr::memrchr(b'\n', &block[start..]) {
            _ if eof => block.len(),
            Some(n) => start + n + 1,
            None if memchr::memchr(0, &block[start..]).is_some() => block.len(),
            None => continue,
        };
        assembler.feed(&block[..end])?;
        block.drain(..end);
        if eof {
            break;
        }
    }
    drop(block);
    assembler.finish()
}

/// Read up to `bytes` more of `file` onto `block`: whether the file ended.
fn read_block(file: &mut Bounded, block: &mut Vec<u8>, bytes: usize) -> Result<bool> {
    let start = block.len();
    block.resize(start + bytes, 0);
    let mut filled = start;
    while filled < block.len() {
        match file.read(&mut block[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(file.error(e)),
        }
    }
    let eof = filled < block.len();
    block.truncate(filled);
    Ok(eof)
}

/// Parse OBJ text. `path` names it in errors; `read_mtl` returns the path and text of an MTL
/// file named by `mtllib`. A file without faces is an error: it is not a mesh. (For the unit
/// tests: files are read by [`load_obj`].)
#[cfg(test)]
pub fn parse_obj(text: &str, path: &Path, read_mtl: impl Fn(&str) -> Result<(PathBuf, String)>) -> Result<ObjFile> {
    parse_obj_split(text, path, CHUNK_BYTES, read_mtl)
}

/// [`parse_obj`] in chunks of `chunk_bytes`.
#[cfg(test)]
fn parse_obj_split(
    text: &str,
    path: &Path,
    chunk_bytes: usize,
    read_mtl: impl Fn(&str) -> Result<(PathBuf, String)>,
) -> Result<ObjFile> {
    let mut assembler =
        Assembler::new(path, chunk_bytes, |name: &str| read_mtl(name).and_then(|(p, t)| parse_mtl(&t, &p)));
    assembler.feed(text.as_bytes())?;
    assembler.finish()
}

/// The faces of the group being read: the corners of its triangles, three a triangle, as
/// 0-based indices into the file's lists (`u32::MAX`: none given).
#[derive(Default)]
struct GroupFaces {
    /// Position indices.
    v: Vec<u32>,
    /// Texture coordinate indices (empty when no corner gave one).
    t: Vec<u32>,
    /// Normal indices (empty when no corner gave one).
    n: Vec<u32>,
}

/// The file's lines put together, chunk after chunk in file order, into groups.
struct Assembler<'p, M> {
    path: &'p Path,
    /// The bytes of a chunk: [`CHUNK_BYTES`] but in tests.
    chunk_bytes: usize,
    /// Reads the materials of one MTL file, by its name in `mtllib`.
    read_mtl: M,
    /// The lines before the next chunk.
    line: usize,
    /// The file's `v`, `vt` and `vn` lines so far.
    positions: Vec<Vec3>,
    texcoords: Vec<Vec2>,
    normals: Vec<Vec3>,
    /// Whether the last `v` line gave a colour (`None`: none yet).
    colored: Option<bool>,
    /// The triangles so far.
    triangles: u64,
    /// The group being read, its name and material.
    faces: GroupFaces,
    name: String,
    material: Option<usize>,
    /// The materials by name, the last definition of a name winning.
    by_name: HashMap<String, usize>,
    /// The first MTL file that failed: its error, reported once the OBJ file is checked.
    mtl_error: Option<Error>,
    /// The first line whose face gives texture coordinate (normal) indices where none exist.
    missing: [Option<usize>; 3],
    /// Per position of the file, its index in the group being exported (`u32::MAX`: none).
    first_use: Vec<u32>,
    duplicates: usize,
    out: ObjFile,
}

impl<'p, M: Fn(&str) -> Result<Vec<ObjMaterial>>> Assembler<'p, M> {
    fn new(path: &'p Path, chunk_bytes: usize, read_mtl: M) -> Self {
        Assembler {
            path,
            chunk_bytes,
            read_mtl,
            line: 0,
            positions: Vec::new(),
            texcoords: Vec::new(),
            normals: Vec::new(),
            colored: None,
            triangles: 0,
            faces: GroupFaces::default(),
            name: "unnamed_object".into(),
            material: None,
            by_name: HashMap::new(),
            mtl_error: None,
            missing: [None; 3],
            first_use: Vec::new(),
            duplicates: 0,
            out: ObjFile::default(),
        }
    }

    /// The size of the mesh so far, for memory errors.
    fn size(&self) -> MeshSize {
        let vertices = (self.positions.len() + self.texcoords.len() + self.normals.len()) as u64;
        MeshSize { triangles: self.triangles, vertices }
    }

    fn oom(&self) -> Error {
        self.size().out_of_memory(self.path)
    }

    /// The `v`, `vt` and `vn` lines so far.
    fn counts(&self) -> [i64; 3] {
        [self.positions.len(), self.texcoords.len(), self.normals.len()].map(|c| c as i64)
    }

    /// Parse whole lines of the file (the next after those fed before), on all cores.
    fn feed(&mut self, text: &[u8]) -> Result<()> {
        let mut pieces = Vec::new();
        let mut at = 0;
        while at < text.len() {
            let end = match memchr::memchr(b'\n', text.get(at + self.chunk_bytes..).unwrap_or_default()) {
                Some(n) => at + self.chunk_bytes + n + 1,
                None => text.len(),
            };
            pieces.push(&text[at..end]);
            at = end;
        }
        let chunks: Vec<Chunk> = pieces.par_iter().map(|piece| parse_chunk(piece, None)).collect();
        for (piece, chunk) in pieces.iter().zip(chunks) {
            let before = Before { counts: self.counts(), colored: self.colored };
            // Rarely: an index the chunk could not check alone, or an error in it, which the
            // exact parse finds at its line.
            let chunk = if chunk.fits(&before) { chunk } else { parse_chunk(piece, Some(before)) };
            self.merge(chunk)?;
        }
        Ok(())
    }

    /// Add a chunk's elements and faces, in order with its statements.
    fn merge(&mut self, chunk: Chunk) -> Result<()> {
        let base = self.counts();
        for k in 1..3 {
            let unbacked = if base[k] == 0 { chunk.extremes[k].unbacked } else { None };
            if let Some(line) = chunk.missing[k].or(unbacked) {
                self.missing[k].get_or_insert(self.line + line);
            }
        }
        self.positions.try_reserve(chunk.positions.len()).map_err(|_| self.oom())?;
        self.positions.extend_from_slice(&chunk.positions);
        self.texcoords.extend_from_slice(&chunk.texcoords);
        self.normals.extend_from_slice(&chunk.normals);
        if self.positions.len().max(self.texcoords.len()).max(self.normals.len()) >= u32::MAX as usize {
            return Err(Error::parse(self.path, Some(self.line + chunk.lines), "more than 4 billion vertices"));
        }
        if let Some(c) = chunk.colors {
            self.colored = Some(c.last);
        }
        self.triangles += chunk.triangles;
        let mut at = 0;
        for event in &chunk.events {
            self.add_corners(&chunk, at..event.corners, base)?;
            at = event.corners;
            let counts = [0, 1, 2].map(|k| base[k] + event.counts[k]);
            match &event.statement {
                Statement::Group(name) => {
                    self.end_group(counts)?;
                    self.name.clone_from(name);
                }
                Statement::UseMtl(name) => {
                    let material = self.by_name.get(name).copied();
                    if material != self.material {
                        self.end_group(counts)?;
                    }
                    self.material = material;
                }
                Statement::MtlLib(names) => self.library(names),
            }
        }
        self.add_corners(&chunk, at..chunk.corners[0].len(), base)?;
        if let Some((line, message)) = chunk.error {
            return Err(Error::parse(self.path, Some(self.line + line), message));
        }
        self.line += chunk.lines;
        Ok(())
    }

    /// Add the chunk's triangle corners `range` to the group, as indices into the file's lists
    /// (`base`: the counts before the chunk).
    fn add_corners(&mut self, chunk: &Chunk, range: std::ops::Range<usize>, base: [i64; 3]) -> Result<()> {
        if range.is_empty() {
            return Ok(());
        }
        let before = self.faces.v.len();
        for k in 0..3 {
            let stored = &chunk.corners[k];
            let list = match k {
                0 => &mut self.faces.v,
                1 => &mut self.faces.t,
                _ => &mut self.faces.n,
            };
            if k > 0 && stored.is_empty() && list.is_empty() {
                continue;
            }
            let oom = MeshSize { triangles: self.triangles, vertices: 0 };
            list.try_reserve(range.len() + before - list.len().min(before))
                .map_err(|_| oom.out_of_memory(self.path))?;
            list.resize(before, u32::MAX);
            if stored.is_empty() {
                list.resize(before + range.len(), u32::MAX);
                continue;
            }
            list.extend(stored[range.clone()].iter().map(|&s| match resolve(s, base[k]) {
                MISSING => u32::MAX,
                i => i as u32,
            }));
        }
        Ok(())
    }

    /// Read the MTL files of one `mtllib` line, numbering their materials after those before.
    fn library(&mut self, names: &[String]) {
        let mut by_name = Vec::new();
        for name in names {
            match (self.read_mtl)(name) {
                Ok(read) => {
                    for m in read {
                        by_name.push((m.material.name.clone(), self.out.materials.len()));
                        self.out.materials.push(m);
                    }
                }
                Err(e) => {
                    self.mtl_error.get_or_insert(e);
                    return;
                }
            }
        }
        self.by_name.extend(by_name);
    }

    /// End the group being read, if it has faces, with the file's lists as long as `counts`
    /// (the `v`, `vt` and `vn` lines before the statement that ends it).
    fn end_group(&mut self, counts: [i64; 3]) -> Result<()> {
        if self.faces.v.is_empty() {
            return Ok(());
        }
        let faces = std::mem::take(&mut self.faces);
        let mesh = self.unify(faces, counts[1] > 0, counts[2] > 0)?;
        self.out.meshes.push(mesh);
        Ok(())
    }

    /// The group's mesh: one vertex per distinct (position, normal, uv) corner, generating
    /// smooth normals (area-weighted, per position so texture seams stay smooth) when the
    /// file has no normals (`has_n`), without duplicate faces. A corner without a normal
    /// (texture coordinate) index where the file has some takes the previous corner's (the
    /// file's first for the group's first corner), as the old reader did.
    fn unify(&mut self, faces: GroupFaces, has_t: bool, has_n: bool) -> Result<ObjMesh> {
        let GroupFaces { v: mut corners, t, n } = faces;
        let (size, path) = (self.size(), self.path);
        let oom = |_| size.out_of_memory(path);
        // The group's positions in the order its faces first use them.
        if self.first_use.len() < self.positions.len() {
            self.first_use.try_reserve_exact(self.positions.len() - self.first_use.len()).map_err(oom)?;
            self.first_use.resize(self.positions.len(), u32::MAX);
        }
        let mut used: Vec<u32> = Vec::new();
        let mut positions: Vec<Vec3> = Vec::new();
        for c in corners.iter_mut() {
            let g = *c as usize;
            let mut local = self.first_use[g];
            if local == u32::MAX {
                local = positions.len() as u32;
                self.first_use[g] = local;
                used.try_reserve(1).map_err(oom)?;
                positions.try_reserve(1).map_err(oom)?;
                used.push(g as u32);
                positions.push(self.positions[g]);
            }
            *c = local;
        }
        for &g in &used {
            self.first_use[g as usize] = u32::MAX;
        }
        drop(used);
        positions.shrink_to_fit();
        let mut mesh = ObjMesh { name: self.name.clone(), material: self.material, ..ObjMesh::default() };
        if !has_t && !has_n {
            // One vertex per position, in that order: no map needed.
            let smooth = smooth_normals(&positions, &corners);
            mesh.normals = smooth.iter().map(|n| n.normalize_or_zero()).collect();
            mesh.positions = positions.clone();
        } else {
            let filled = |list: Vec<u32>| -> Vec<u32> {
                // The old reader's stand-in for a missing index: the previous corner's.
                let mut previous = 0;
                let mut list = if list.is_empty() { vec![u32::MAX; corners.len()] } else { list };
                for i in list.iter_mut() {
                    if *i == u32::MAX {
                        *i = previous;
                    }
                    previous = *i;
                }
                list
            };
            let t = if has_t { filled(t) } else { Vec::new() };
            let n = if has_n { filled(n) } else { Vec::new() };
            let smooth = if has_n { Vec::new() } else { smooth_normals(&positions, &corners) };
            mesh.positions.try_reserve_exact(positions.len()).map_err(oom)?;
            mesh.normals.try_reserve_exact(positions.len()).map_err(oom)?;
            let mut map: HashMap<u128, u32, IndexHash> = HashMap::with_hasher(IndexHash::new());
            map.try_reserve(positions.len()).map_err(oom)?;
            for (k, c) in corners.iter_mut().enumerate() {
                let pi = *c;
                let ni = if has_n { n[k] } else { pi };
                let ti = if has_t { t[k] } else { u32::MAX };
                let next = mesh.positions.len() as u32;
                *c = *map.entry(pack([pi, ni, ti])).or_insert_with(|| {
                    mesh.positions.push(positions[pi as usize]);
                    let normal = if has_n { self.normals[ni as usize] } else { smooth[ni as usize] };
                    mesh.normals.push(normal.normalize_or_zero());
                    if has_t {
                        mesh.uvs.push(self.texcoords[ti as usize]);
                    }
                    next
                });
            }
            mesh.positions.shrink_to_fit();
            mesh.normals.shrink_to_fit();
        }
        self.out.raw_positions.try_reserve(positions.len()).map_err(oom)?;
        self.out.raw_positions.extend_from_slice(&positions);
        drop(positions);
        mesh.triangles = without_duplicates(&corners, &mut self.duplicates, size, path)?;
        Ok(mesh)
    }

    /// The file read: its groups, or the errors found only at its end.
    fn finish(mut self) -> Result<ObjFile> {
        let counts = self.counts();
        for (k, what, element) in [(1, "texture coordinate", "vt"), (2, "normal", "vn")] {
            match self.missing[k] {
                // Elements defined after the faces that refer to them break OBJ's rule.
                Some(line) if counts[k] > 0 => {
                    return Err(Error::parse(
                        self.path,
                        Some(line),
                        format!("{what} index refers to no `{element}` line before it"),
                    ));
                }
                Some(line) => self.out.warnings.push(format!(
                    "{}:{line}: faces give {what} indices but the file has no `{element}` lines; they are ignored",
                    self.path.display()
                )),
                None => {}
            }
        }
        // The build of the BVH comes next: the memory for both, asked for at once.
        self.size().reserve(self.path)?;
        if let Some(e) = self.mtl_error.take() {
            return Err(e);
        }
        self.end_group(counts)?;
        // The file's lists are no longer needed: freed before the caller builds on the meshes.
        let path = self.path;
        let duplicates = self.duplicates;
        let mut out = std::mem::take(&mut self.out);
        drop(self);
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

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::io::obj_reference;

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

    /// The MTL file of the generated OBJ files.
    fn two_materials(name: &str) -> Result<(PathBuf, String)> {
        match name {
            "m.mtl" => Ok((PathBuf::from("m.mtl"), "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n".to_string())),
            _ => no_mtl(name),
        }
    }

    /// The new reader, in chunks of `chunk` bytes, and the old one read `text` alike: the
    /// same groups, bit for bit, or the same error at the same line.
    fn agrees(text: &str, chunk: usize) {
        let path = Path::new("t.obj");
        let new = parse_obj_split(text, path, chunk, two_materials);
        let old = obj_reference::parse_obj(text, path, two_materials);
        let show = |r: &Result<ObjFile>| match r {
            Ok(f) => format!("{f:?}"),
            Err(e) => format!("error: {e}"),
        };
        // Debug prints of f32 are exact (shortest round trip): equal prints are equal bits,
        // NaN and -0.0 included.
        assert_eq!(show(&new), show(&old), "chunks of {chunk} bytes:\n{text}");
    }

    /// A number as files write it.
    fn number() -> impl Strategy<Value = String> {
        prop_oneof![
            (-50i32..50).prop_map(|i| i.to_string()),
            any::<f32>().prop_filter("finite", |f| f.is_finite() && f.abs() < 1e6).prop_map(|f| format!("{f}")),
            (-10.0f64..10.0, 0usize..9).prop_map(|(f, d)| format!("{f:.d$}")),
            (-10.0f64..10.0).prop_map(|f| format!("{f:e}")),
            Just("0".to_string()),
            Just("-0".to_string()),
            Just("nan".to_string()),
            Just("1x".to_string()),
        ]
    }

    /// A face corner: `v`, `v/vt`, `v//vn` or `v/vt/vn`, indices absolute or relative and
    /// sometimes out of range.
    fn corner() -> impl Strategy<Value = String> {
        let index = prop_oneof![8 => 1i64..12, 3 => -12i64..0, 1 => Just(0i64)];
        (index.clone(), index.clone(), index, 0usize..5).prop_map(|(v, t, n, form)| match form {
            0 | 1 => v.to_string(),
            2 => format!("{v}/{t}"),
            3 => format!("{v}//{n}"),
            _ => format!("{v}/{t}/{n}"),
        })
    }

    /// A line of an OBJ file, mostly valid.
    fn line() -> impl Strategy<Value = String> {
        let numbers = |n| proptest::collection::vec(number(), n);
        prop_oneof![
            12 => numbers(3..4).prop_map(|n| format!("v {}", n.join(" "))),
            1 => numbers(4..5).prop_map(|n| format!("v {}", n.join(" "))),
            1 => numbers(6..7).prop_map(|n| format!("v {}", n.join(" "))),
            3 => numbers(2..4).prop_map(|n| format!("vt {}", n.join(" "))),
            3 => numbers(3..4).prop_map(|n| format!("vn {}", n.join("\t"))),
            12 => proptest::collection::vec(corner(), 3..7).prop_map(|c| format!("f {}", c.join(" "))),
            1 => proptest::collection::vec(corner(), 1..4).prop_map(|c| format!("f {}", c.join(" "))),
            1 => proptest::collection::vec(corner(), 2..4).prop_map(|c| format!("l {}", c.join(" "))),
            2 => "[og]( [a-z]{1,4}){0,2}".prop_map(|s| s),
            2 => prop_oneof![Just("usemtl red"), Just("usemtl blue"), Just("usemtl green"), Just("usemtl")]
                .prop_map(String::from),
            1 => prop_oneof![Just("mtllib m.mtl"), Just("mtllib"), Just("mtllib none.mtl")].prop_map(String::from),
            1 => prop_oneof![Just("# v 1 2"), Just(""), Just("s 1"), Just("  "), Just("vp 1"), Just("bogus 1")]
                .prop_map(String::from),
        ]
    }

    /// A file of mostly valid lines: the first vertices up front, so that most faces hold.
    fn file() -> impl Strategy<Value = String> {
        (proptest::collection::vec(line(), 0..40), 0usize..4, any::<bool>()).prop_map(|(lines, head, crlf)| {
            let mut text = String::new();
            let first = ["v 0 0 0", "v 1 0 0", "v 0 1 0", "v 0 0 1", "vt 0 0", "vn 0 0 1"];
            for l in first.iter().take(head + 2) {
                text.push_str(l);
                text.push('\n');
            }
            let end = if crlf { "\r\n" } else { "\n" };
            for l in lines {
                text.push_str(&l);
                text.push_str(end);
            }
            text
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

        #[test]
        fn generated_files_read_as_the_old_reader_read_them(text in file(), chunk in 1usize..200) {
            agrees(&text, chunk);
            agrees(&text, CHUNK_BYTES);
        }

        #[test]
        fn any_bytes_read_as_the_old_reader_read_them(bytes in proptest::collection::vec(any::<u8>(), 0..200), chunk in 1usize..64) {
            // Text only (the old reader took `&str`); the new one checks bytes in `load_obj`.
            let text = String::from_utf8_lossy(&bytes).replace('\0', " ");
            agrees(&text, chunk);
        }
    }

    #[test]
    fn files_read_in_small_blocks_read_as_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.obj");
        let mut text = String::from("mtllib m.mtl\n");
        for i in 0..50 {
            text.push_str(&format!("v {i} {} 0.5\nvn 0 0 1\nvt 0.{i} 0.5\n", i % 7));
        }
        for i in 3..50 {
            text.push_str(&format!("f {i}/{i}/{i} -2/-2/-2 -3/-3/-3\n"));
            if i % 9 == 0 {
                text.push_str("g part\nusemtl red\n");
            }
        }
        std::fs::write(&path, &text).unwrap();
        std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
        let whole = load_obj(&path).unwrap();
        for (block, chunk) in [(1, 1), (7, 3), (64, 1000), (1000, 16)] {
            assert_eq!(load_obj_split(&path, block, chunk).unwrap(), whole, "{block} {chunk}");
        }
        // A NUL byte and a bad UTF-8 byte, at their lines, however the file is split.
        for (bad, message) in [(&b"\0"[..], NUL_BYTE_MESSAGE), (&b"\xff"[..], NOT_UTF8_MESSAGE)] {
            let mut bytes = text.clone().into_bytes();
            let at = bytes.iter().position(|&b| b == b'f').unwrap() + 2;
            bytes.splice(at..at, bad.iter().copied());
            std::fs::write(&path, &bytes).unwrap();
            let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
            for (block, chunk) in [(1, 1), (7, 3), (BLOCK_BYTES, CHUNK_BYTES)] {
                match load_obj_split(&path, block, chunk) {
                    Err(Error::Parse { line: Some(l), message: m, .. }) => {
                        assert_eq!((l, m.as_str()), (line, message))
                    }
                    other => panic!("{other:?}"),
                }
            }
        }
    }

    const NUL_BYTE_MESSAGE: &str = super::super::file::NUL_BYTE;
    const NOT_UTF8_MESSAGE: &str = super::super::file::NOT_UTF8;
}
