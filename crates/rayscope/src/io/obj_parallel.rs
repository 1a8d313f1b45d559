//! The fast reader of OBJ files: the text is read in blocks of whole lines, each block split at
//! line ends into chunks that rayon reads on every core, in two passes. The first counts the
//! elements and triangles of each chunk, so that the memory the mesh needs is checked
//! ([`MeshSize::reserve`]) and its arrays sized exactly before anything is parsed; the second
//! parses each chunk into its own slices of those arrays, negative indices resolved by the
//! counts before it. Then, in file order, the groups are cut (`o`, `g`, `usemtl`), their
//! positions numbered as `tobj` numbers them, and unified ([`super::obj`]).
//!
//! It reads the common forms only: `v x y z`, `vt`, `vn`, faces of three or more corners with
//! indices in range, comments and the `o`, `g`, `s`, `usemtl` and `mtllib` statements. Any
//! other line, and any line the checks of [`super::obj`] would report, makes it give the file
//! back (`Ok(None)`) to the checked reader, which reports the error at its line or reads what
//! is rare (vertex colours, weights, polylines) through `tobj`. Both give the same [`ObjFile`].

use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

use memchr::{memchr, memrchr};
use rayon::prelude::*;

use super::file::Bounded;
use super::float::{parse_f32, parse_index};
use super::memory::MeshSize;
use super::mtl::ObjMaterial;
use super::obj::{Corners, ObjFile, finish, missing_warning, unify};
use crate::error::Result;
use crate::math::{Vec2, Vec3};

/// The bytes read at a time: the reader's two buffers (one read into while the other's lines
/// are counted or parsed) are its only memory besides the mesh's own.
const BLOCK_BYTES: usize = 16 << 20;

/// The bytes of a chunk, about: enough lines for a task to outweigh its scheduling, few enough
/// that a block keeps every core busy.
const CHUNK_BYTES: usize = 512 << 10;

/// A corner's texture coordinate or normal index that the face does not give.
const MISSING: u32 = u32::MAX;

/// Where the bytes of an OBJ file come from.
pub trait Source: Send {
    /// Read into `buf`, returning how many bytes were read (0 at the end).
    fn read_some(&mut self, buf: &mut [u8]) -> Result<usize>;
}

impl Source for Bounded {
    fn read_some(&mut self, buf: &mut [u8]) -> Result<usize> {
        loop {
            match std::io::Read::read(self, buf) {
                Ok(n) => return Ok(n),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(self.error(e)),
            }
        }
    }
}

/// Text in memory (the unit tests' files).
#[cfg(test)]
impl Source for &[u8] {
    fn read_some(&mut self, buf: &mut [u8]) -> Result<usize> {
        Ok(std::io::Read::read(self, buf).unwrap_or(0))
    }
}

/// Read the OBJ file that `open` opens (twice, from its start), named `path` in errors, with
/// the materials of one MTL file by its name in `mtllib` from `read_mtl`. `Ok(None)`: a file
/// for the checked reader (see the module's documentation).
pub fn read_obj_parallel<S: Source>(
    path: &Path,
    mut open: impl FnMut() -> Result<S>,
    read_mtl: impl Fn(&str) -> Result<Vec<ObjMaterial>>,
) -> Result<Option<ObjFile>> {
    let mut buffers = [vec![0; BLOCK_BYTES], vec![0; BLOCK_BYTES]];
    let mut counts: Vec<Count> = Vec::new();
    let counted = for_each_block(&mut open()?, &mut buffers, |block| {
        let found: Option<Vec<Count>> = chunks(block).par_iter().map(|c| count(c)).collect();
        Ok(found.map(|found| counts.extend(found)).is_some())
    })?;
    let total = counts.iter().fold(Count::default(), |a, c| a.plus(c));
    let fits_u32 = total.elements.iter().all(|&e| e < u64::from(MISSING));
    if !counted || total.triangles == 0 || !fits_u32 {
        return Ok(None);
    }
    let size = MeshSize { triangles: total.triangles, vertices: total.elements.iter().sum() };
    size.reserve(path)?;
    let [v, vt, vn] = total.elements.map(|e| e as usize);
    let corners = usize::try_from(total.triangles.saturating_mul(3)).map_err(|_| size.out_of_memory(path))?;
    // Zeroed memory, the pages touched first by the threads that parse into them.
    let mut positions = size.zeroed(path, v)?;
    let mut uvs = size.zeroed(path, vt)?;
    let mut normals = size.zeroed(path, vn)?;
    let mut indices = [
        size.zeroed(path, corners)?,
        filled(size, path, if vt > 0 { corners } else { 0 }, MISSING)?,
        filled(size, path, if vn > 0 { corners } else { 0 }, MISSING)?,
    ];

    let mut parsed: Vec<Parsed> = Vec::new();
    let (mut start, mut next) = (Count::default(), 0);
    let [pi, ti, ni] = &mut indices;
    let mut rest = Slices { positions: &mut positions, uvs: &mut uvs, normals: &mut normals, corners: [pi, ti, ni] };
    let read = for_each_block(&mut open()?, &mut buffers, |block| {
        let chunks = chunks(block);
        // A file that changed since it was counted is not read on.
        let Some(block_counts) = counts.get(next..next + chunks.len()) else { return Ok(false) };
        next += chunks.len();
        let mut work = Vec::with_capacity(chunks.len());
        for (chunk, count) in chunks.into_iter().zip(block_counts) {
            let Some((mine, others)) = std::mem::take(&mut rest).split(count) else { return Ok(false) };
            work.push((chunk, start, mine));
            start = start.plus(count);
            rest = others;
        }
        let found: Option<Vec<Parsed>> = work.into_par_iter().map(|(c, s, out)| parse(c, s, out)).collect();
        Ok(found.map(|found| parsed.extend(found)).is_some())
    })?;
    drop(buffers);
    if !read || next != counts.len() {
        return Ok(None);
    }

    let mut warnings = Vec::new();
    for k in 1..3 {
        match parsed.iter().find_map(|p| p.missing[k]) {
            // Indices given before any element of their kind, in a file that has some: an
            // error, which the checked reader reports.
            Some(_) if total.elements[k] > 0 => return Ok(None),
            Some(line) => warnings.push(missing_warning(path, k, line as usize)),
            None => {}
        }
    }
    let mut groups = Groups {
        path,
        size,
        positions: &positions,
        uvs: &uvs,
        normals: &normals,
        indices,
        remap: filled(size, path, v, MISSING)?,
        out: ObjFile { warnings, ..ObjFile::default() },
        duplicates: 0,
    };
    let mut group = Group { name: "unnamed_object".to_string(), material: None, start: 0 };
    let mut by_name: HashMap<String, usize> = HashMap::new();
    for event in parsed.into_iter().flat_map(|p| p.events) {
        let text = event.text.as_str();
        let head = text.split_whitespace().next().unwrap_or_default();
        match head {
            // tobj's reading of each statement.
            "o" | "g" => {
                groups.cut(&mut group, &event)?;
                let size = text.chars().next().map_or(0, char::len_utf8);
                group.name = text[size..].trim().to_string();
                if group.name.is_empty() {
                    group.name = "unnamed_object".to_string();
                }
            }
            "mtllib" => {
                for name in text.split_whitespace().skip(1) {
                    for m in read_mtl(name)? {
                        by_name.insert(m.material.name.clone(), groups.out.materials.len());
                        groups.out.materials.push(m);
                    }
                }
            }
            _ => {
                let name = text.split_once(' ').unwrap_or_default().1.trim();
                let material = by_name.get(name).copied();
                if material != group.material {
                    groups.cut(&mut group, &event)?;
                }
                group.material = material;
            }
        }
    }
    let end = Event { triangles: total.triangles, elements: total.elements, text: String::new() };
    groups.cut(&mut group, &end)?;
    let Groups { out, duplicates, .. } = groups;
    finish(out, duplicates, path).map(Some)
}

/// A vector of `len` copies of `value`, reserved fallibly (`size` and `path` make the error).
fn filled<T: Clone>(size: MeshSize, path: &Path, len: usize, value: T) -> Result<Vec<T>> {
    let mut v = size.vec(path, len)?;
    v.resize(len, value);
    Ok(v)
}

/// Call `f` with each block of whole lines of `source` in order (the last line of the file
/// may lack its end), in one of `buffers` while the next block is read into the other (on
/// one core, the reading left the others idle: a tenth of a big file's load). `Ok(false)`
/// where `f` says so, or where a line is longer than a buffer: the file is for the checked
/// reader.
fn for_each_block(
    source: &mut impl Source,
    buffers: &mut [Vec<u8>; 2],
    mut f: impl FnMut(&[u8]) -> Result<bool> + Send,
) -> Result<bool> {
    let [cur, next] = buffers;
    let (mut cur, mut next) = (&mut cur[..], &mut next[..]);
    let mut filled = fill(source, cur, 0)?;
    loop {
        // A buffer not filled holds the end of the file.
        let end = filled < cur.len();
        let cut = if end {
            filled
        } else {
            match memrchr(b'\n', &cur[..filled]) {
                Some(i) => i + 1,
                None => return Ok(false),
            }
        };
        // The last line's start, carried over to the next block.
        let carried = filled - cut;
        next[..carried].copy_from_slice(&cur[cut..filled]);
        let block = &cur[..cut];
        let (read, went_on) = rayon::join(
            || if end { Ok(carried) } else { fill(source, next, carried) },
            || if block.is_empty() { Ok(true) } else { f(block) },
        );
        if !went_on? {
            return Ok(false);
        }
        if end {
            return Ok(true);
        }
        filled = read?;
        std::mem::swap(&mut cur, &mut next);
    }
}

/// Read from `source` into `buffer` after its first `filled` bytes until it is full or the
/// source ends; the bytes it then holds.
fn fill(source: &mut impl Source, buffer: &mut [u8], mut filled: usize) -> Result<usize> {
    while filled < buffer.len() {
        let n = source.read_some(&mut buffer[filled..])?;
        if n == 0 {
            break;
        }
        filled += n;
    }
    Ok(filled)
}

/// A block split at line ends into chunks of about [`CHUNK_BYTES`].
fn chunks(block: &[u8]) -> Vec<&[u8]> {
    let mut out = Vec::with_capacity(block.len() / CHUNK_BYTES + 1);
    let mut start = 0;
    while start < block.len() {
        let end = match block.get(start + CHUNK_BYTES..).and_then(|after| memchr(b'\n', after)) {
            Some(i) => start + CHUNK_BYTES + i + 1,
            None => block.len(),
        };
        out.push(&block[start..end]);
        start = end;
    }
    out
}

/// The lines of a chunk as [`str::lines`] gives them: without their `\n` or `\r\n`.
fn lines(chunk: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut start = 0;
    std::iter::from_fn(move || {
        if start >= chunk.len() {
            return None;
        }
        let Some(i) = memchr(b'\n', &chunk[start..]) else {
            let line = &chunk[start..];
            start = chunk.len();
            return Some(line);
        };
        let line = &chunk[start..start + i];
        start += i + 1;
        Some(line.strip_suffix(b"\r").unwrap_or(line))
    })
}

/// The words of a line, split at ASCII whitespace as [`str::split_whitespace`] splits ASCII text.
fn words(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|&b| matches!(b, b' ' | b'\t' | b'\r' | 0x0b | 0x0c)).filter(|w| !w.is_empty())
}

/// What the first pass counted in a chunk (or in the chunks before one).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Count {
    /// Its lines.
    lines: u64,
    /// Its `v`, `vt` and `vn` lines.
    elements: [u64; 3],
    /// The triangles of its faces.
    triangles: u64,
}

impl Count {
    /// The counts of two chunks together.
    fn plus(self, other: &Count) -> Count {
        Count {
            lines: self.lines + other.lines,
            elements: [0, 1, 2].map(|k| self.elements[k] + other.elements[k]),
            triangles: self.triangles + other.triangles,
        }
    }
}

/// Count a chunk's lines, elements and triangles; `None` for a chunk that is not text, or that
/// holds a statement the fast reader does not read.
fn count(chunk: &[u8]) -> Option<Count> {
    if memchr(0, chunk).is_some() || std::str::from_utf8(chunk).is_err() {
        return None;
    }
    let ascii = chunk.is_ascii();
    let mut c = Count::default();
    for line in lines(chunk) {
        c.lines += 1;
        let mut words = words(line);
        let Some(head) = words.next() else { continue };
        match head {
            b"v" => c.elements[0] += 1,
            b"vt" => c.elements[1] += 1,
            b"vn" => c.elements[2] += 1,
            b"f" => {
                let n = words.count() as u64;
                if n < 3 {
                    return None;
                }
                c.triangles += n - 2;
            }
            b"o" | b"g" | b"s" | b"usemtl" | b"mtllib" => continue,
            _ if head[0] == b'#' => continue,
            _ => return None,
        }
        // Numbers are ASCII; other whitespace than ASCII's would split words differently.
        if !ascii && !line.is_ascii() {
            return None;
        }
    }
    Some(c)
}

/// The parts of the mesh's arrays that a chunk fills.
#[derive(Default)]
struct Slices<'a> {
    positions: &'a mut [Vec3],
    uvs: &'a mut [Vec2],
    normals: &'a mut [Vec3],
    /// Position, texture coordinate and normal indices, three corners a triangle; the second
    /// and third are empty when the file has no `vt` (`vn`) lines.
    corners: [&'a mut [u32]; 3],
}

impl<'a> Slices<'a> {
    /// The first chunk's slices, of `count`, and the rest; `None` if they are too short.
    fn split(self, count: &Count) -> Option<(Slices<'a>, Slices<'a>)> {
        fn cut<T>(s: &mut [T], n: u64) -> Option<(&mut [T], &mut [T])> {
            s.split_at_mut_checked(usize::try_from(n).ok()?)
        }
        let corners = count.triangles.checked_mul(3)?;
        let (p, p_rest) = cut(self.positions, count.elements[0])?;
        let (t, t_rest) = cut(self.uvs, count.elements[1])?;
        let (n, n_rest) = cut(self.normals, count.elements[2])?;
        let [ci, ct, cn] = self.corners;
        let (ci, ci_rest) = cut(ci, corners)?;
        let (ct, ct_rest) = if ct.is_empty() { (ct, Default::default()) } else { cut(ct, corners)? };
        let (cn, cn_rest) = if cn.is_empty() { (cn, Default::default()) } else { cut(cn, corners)? };
        Some((
            Slices { positions: p, uvs: t, normals: n, corners: [ci, ct, cn] },
            Slices { positions: p_rest, uvs: t_rest, normals: n_rest, corners: [ci_rest, ct_rest, cn_rest] },
        ))
    }
}

/// A statement that cuts or names groups (`o`, `g`, `usemtl`) or reads materials (`mtllib`).
struct Event {
    /// The triangles before it.
    triangles: u64,
    /// The `v`, `vt` and `vn` lines before it.
    elements: [u64; 3],
    /// The line.
    text: String,
}

/// What the second pass found in a chunk besides the mesh.
#[derive(Default)]
struct Parsed {
    /// Its statements, in order.
    events: Vec<Event>,
    /// The first line whose face gives texture coordinate (normal) indices before any `vt`
    /// (`vn`) line.
    missing: [Option<u64>; 3],
}

/// Parse a chunk that [`count`] counted into `out` (`start`: the counts of the chunks before it); `None` for a line that the checked reader
/// would report (or that it reads and this one does not).
fn parse(chunk: &[u8], start: Count, out: Slices) -> Option<Parsed> {
    let Slices { positions, uvs, normals, corners: [pi, ti, ni] } = out;
    let mut parsed = Parsed::default();
    let mut local = [0usize; 3];
    let mut t = 0;
    let mut face: Vec<[u32; 3]> = Vec::new();
    for (i, line) in lines(chunk).enumerate() {
        let line_no = start.lines + i as u64 + 1;
        let mut words = words(line);
        let Some(head) = words.next() else { continue };
        match head {
            b"v" => {
                let [x, y, z] = floats(&mut words, 3)?;
                *positions.get_mut(local[0])? = Vec3::new(x, y, z);
                local[0] += 1;
            }
            b"vt" => {
                let [u, v, _] = floats(&mut words, 2)?;
                *uvs.get_mut(local[1])? = Vec2::new(u, v);
                local[1] += 1;
            }
            b"vn" => {
                let [x, y, z] = floats(&mut words, 3)?;
                *normals.get_mut(local[2])? = Vec3::new(x, y, z);
                local[2] += 1;
            }
            b"f" => {
                face.clear();
                for word in words {
                    let mut corner = [MISSING; 3];
                    for (k, part) in word.split(|&b| b == b'/').enumerate() {
                        if k > 2 {
                            return None;
                        }
                        if part.is_empty() && k > 0 {
                            continue;
                        }
                        let index = parse_index(part)?;
                        let count = start.elements[k] + local[k] as u64;
                        if count == 0 && k > 0 {
                            parsed.missing[k].get_or_insert(line_no);
                            continue;
                        }
                        let back = index.unsigned_abs();
                        let resolved = match index {
                            _ if back == 0 || back > count => return None,
                            1.. => back - 1,
                            _ => count - back,
                        };
                        corner[k] = u32::try_from(resolved).ok()?;
                    }
                    face.push(corner);
                }
                // tobj's triangulation: a fan around the first corner.
                for j in 1..face.len().saturating_sub(1) {
                    for (slot, corner) in [face[0], face[j], face[j + 1]].into_iter().enumerate() {
                        let at = 3 * t + slot;
                        *pi.get_mut(at)? = corner[0];
                        if !ti.is_empty() {
                            *ti.get_mut(at)? = corner[1];
                        }
                        if !ni.is_empty() {
                            *ni.get_mut(at)? = corner[2];
                        }
                    }
                    t += 1;
                }
            }
            b"o" | b"g" | b"usemtl" | b"mtllib" => {
                let text = std::str::from_utf8(line).ok()?;
                let unnamed = match head {
                    b"usemtl" => text.split_once(' ').is_none_or(|(_, name)| name.trim().is_empty()),
                    b"mtllib" => words.next().is_none(),
                    _ => false,
                };
                if unnamed {
                    return None;
                }
                let elements = [0, 1, 2].map(|k| start.elements[k] + local[k] as u64);
                let triangles = start.triangles + t as u64;
                parsed.events.push(Event { triangles, elements, text: text.to_string() });
            }
            b"s" => {}
            _ if head[0] == b'#' => {}
            _ => return None,
        }
    }
    // The chunk holds what it held when counted (a file that changed does not).
    let full = local == [positions.len(), uvs.len(), normals.len()] && 3 * t == pi.len();
    full.then_some(parsed)
}

/// The numbers of a line: at least `min` and at most three, finite; missing ones are 0.
fn floats<'a>(words: &mut impl Iterator<Item = &'a [u8]>, min: usize) -> Option<[f32; 3]> {
    let mut out = [0.0; 3];
    let mut n = 0;
    for word in words {
        let v = parse_f32(word).filter(|v| v.is_finite())?;
        *out.get_mut(n)? = v;
        n += 1;
    }
    (n >= min).then_some(out)
}

/// The group being read: its name, material and first triangle.
struct Group {
    name: String,
    material: Option<usize>,
    start: u64,
}

/// The mesh read, cut into groups in file order.
struct Groups<'a> {
    path: &'a Path,
    size: MeshSize,
    positions: &'a [Vec3],
    uvs: &'a [Vec2],
    normals: &'a [Vec3],
    /// The corners' position, texture coordinate and normal indices (see [`Slices`]).
    indices: [Vec<u32>; 3],
    /// A file position's number in the current group, or [`MISSING`].
    remap: Vec<u32>,
    out: ObjFile,
    duplicates: usize,
}

impl Groups<'_> {
    /// End `group` at `event` (when it has triangles, as tobj ends a model) and start the next.
    fn cut(&mut self, group: &mut Group, event: &Event) -> Result<()> {
        if event.triangles > group.start {
            self.unify(group, group.start..event.triangles, event.elements)?;
        }
        group.start = event.triangles;
        Ok(())
    }

    /// Unify the `triangles` of `group`, given the `v`, `vt` and `vn` lines read when it ended:
    /// its positions numbered in order of first use, as tobj numbers them (and
    /// [`ObjFile::raw_positions`] lists them), corners without a texture coordinate or
    /// normal index taking the previous corner's (the first: the first element's), as tobj
    /// fills them in.
    fn unify(&mut self, group: &Group, triangles: Range<u64>, elements: [u64; 3]) -> Result<()> {
        let (path, size) = (self.path, self.size);
        let corners = triangles.start as usize * 3..triangles.end as usize * 3;
        let [pi, ti, ni] = &mut self.indices;
        let pi = &mut pi[corners.clone()];
        let mut used = size.vec(path, self.positions.len().min(pi.len()))?;
        let mut compact = size.vec(path, self.positions.len().min(pi.len()))?;
        for p in pi.iter_mut() {
            let number = &mut self.remap[*p as usize];
            if *number == MISSING {
                *number = compact.len() as u32;
                compact.push(self.positions[*p as usize]);
                used.push(*p);
            }
            *p = *number;
        }
        for &p in &used {
            self.remap[p as usize] = MISSING;
        }
        drop(used);
        let filled_in = |indices: &mut Vec<u32>, present: bool| -> Option<Range<usize>> {
            let indices = indices.get_mut(corners.clone()).filter(|_| present)?;
            let mut previous = 0;
            for i in indices {
                if *i == MISSING {
                    *i = previous;
                }
                previous = *i;
            }
            Some(corners.clone())
        };
        let uv_corners = filled_in(ti, elements[1] > 0);
        let normal_corners = filled_in(ni, elements[2] > 0);
        self.out.raw_positions.try_reserve(compact.len()).map_err(|_| size.out_of_memory(path))?;
        self.out.raw_positions.extend_from_slice(&compact);
        let corners = Corners {
            positions: compact,
            indices: &*pi,
            normals: normal_corners.map(|r| (self.normals, &ni[r])),
            uvs: uv_corners.map(|r| (self.uvs, &ti[r])),
        };
        let mesh = unify(&group.name, group.material, corners, &mut self.duplicates, size, path)?;
        self.out.meshes.push(mesh);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A source that gives at most three bytes a read.
    struct Trickle<'a>(&'a [u8]);

    impl Source for Trickle<'_> {
        fn read_some(&mut self, buf: &mut [u8]) -> Result<usize> {
            let n = buf.len().min(3).min(self.0.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    /// Blocks of whole lines, in order, every byte once, whatever the buffers' size and the
    /// reads' length; a line longer than a buffer gives the file up.
    #[test]
    fn blocks_are_whole_lines_in_order() {
        let text = b"v 1 2 3\nv 4 5 6\n\nf 1 2 3\n# a comment\nv 7 8 9";
        for size in 12..=text.len() + 2 {
            let mut buffers = [vec![0; size], vec![0; size]];
            let mut blocks: Vec<Vec<u8>> = Vec::new();
            let read = for_each_block(&mut Trickle(text), &mut buffers, |b| {
                blocks.push(b.to_vec());
                Ok(true)
            });
            assert!(read.unwrap(), "buffers of {size}");
            assert_eq!(blocks.concat(), text, "buffers of {size}");
            let (last, whole) = blocks.split_last().unwrap();
            assert!(whole.iter().all(|b| b.ends_with(b"\n")), "buffers of {size}");
            assert!(!last.is_empty());
        }
        let mut small = [vec![0; 11], vec![0; 11]];
        assert!(!for_each_block(&mut Trickle(text), &mut small, |_| Ok(true)).unwrap());
        let mut stop = [vec![0; 16], vec![0; 16]];
        assert!(!for_each_block(&mut Trickle(text), &mut stop, |_| Ok(false)).unwrap());
    }
}
