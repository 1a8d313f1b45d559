//! Stanford PLY meshes (ASCII, binary little endian and binary big endian), read in one pass
//! over the file, never held whole.
//!
//! What is read: the `vertex` element's `x y z`, and when present its normals `nx ny nz` and
//! texture coordinates (`u v`, `s t` or `texture_u texture_v`); the `face` element's list
//! `vertex_indices` (or `vertex_index`), of any length, fanned into triangles. Every other
//! element and property is read past. The header's counts are checked against the bytes left
//! in the file before anything is allocated (a header that claims a billion vertices in a
//! 1 kB file is an error, not an allocation), and every face index against the vertex count.
//! Errors name the file, and the element and its number (and the line, in an ASCII file).

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use super::file::{Bounded, open};
use super::memory::MeshSize;
use super::obj::{ObjFile, ObjMesh, smooth_normals};
use crate::error::{Error, Result};
use crate::math::{Vec2, Vec3};

/// The longest header read: real headers are a few hundred bytes, and a file that is no PLY
/// at all must not be read to its end looking for `end_header`.
const MAX_HEADER_BYTES: u64 = 64 << 10;

/// How the element data after the header is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    LittleEndian,
    BigEndian,
}

/// A scalar type of the format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(word: &str) -> Option<Scalar> {
        Some(match word {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Bytes in a binary file.
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The value of its bytes `b` (exactly [`Scalar::size`] of them) in byte order `format`.
    fn decode(self, b: &[u8], format: Format) -> f64 {
        macro_rules! num {
            ($t:ty) => {{
                let bytes = b.try_into().expect("the caller passes size() bytes");
                (if format == Format::BigEndian { <$t>::from_be_bytes(bytes) } else { <$t>::from_le_bytes(bytes) })
                    as f64
            }};
        }
        match self {
            Scalar::I8 => num!(i8),
            Scalar::U8 => num!(u8),
            Scalar::I16 => num!(i16),
            Scalar::U16 => num!(u16),
            Scalar::I32 => num!(i32),
            Scalar::U32 => num!(u32),
            Scalar::F32 => num!(f32),
            Scalar::F64 => num!(f64),
        }
    }
}

/// A property of an element: one scalar, or a list of them after a count.
#[derive(Clone, Debug, PartialEq)]
struct Property {
    name: String,
    /// For a list: the type of its count.
    count: Option<Scalar>,
    /// The type of the value (of each item, for a list).
    value: Scalar,
}

/// An element of the header: its name, how many the file holds, and their properties.
#[derive(Clone, Debug, PartialEq)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

impl Element {
    /// The fewest bytes one of these takes in the file: a list may be empty, and an ASCII
    /// value is at least one character and a separator.
    fn min_bytes(&self, format: Format) -> u64 {
        let each = |p: &Property| match format {
            Format::Ascii => 2,
            _ => p.count.unwrap_or(p.value).size() as u64,
        };
        self.properties.iter().map(each).sum::<u64>().max(1)
    }
}

/// The header: the format and the elements, in file order.
#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Its lines (the first line of data in an ASCII file is the next).
    lines: usize,
}

/// Where in a vertex record the properties that are read sit (indices into its properties).
#[derive(Default)]
struct VertexLayout {
    position: [usize; 3],
    normal: Option<[usize; 3]>,
    uv: Option<[usize; 2]>,
}

impl VertexLayout {
    fn of(element: &Element, path: &Path) -> Result<VertexLayout> {
        let find = |name: &str| -> Option<usize> {
            element.properties.iter().position(|p| p.name == name && p.count.is_none())
        };
        let all = |names: &[&str]| names.iter().map(|n| find(n)).collect::<Option<Vec<usize>>>();
        let Some(p) = all(&["x", "y", "z"]) else {
            return Err(Error::parse(path, None, "the vertex element has no scalar x, y and z properties"));
        };
        let normal = all(&["nx", "ny", "nz"]).map(|n| [n[0], n[1], n[2]]);
        let uv = [["u", "v"], ["s", "t"], ["texture_u", "texture_v"]]
            .iter()
            .find_map(|names| all(names))
            .map(|t| [t[0], t[1]]);
        Ok(VertexLayout { position: [p[0], p[1], p[2]], normal, uv })
    }
}

/// Load a PLY mesh file (regular files only, within [`super::file::max_file_bytes`]) as one
/// group with the default material; normals are the file's, or smooth ones when it has none.
pub fn load_ply(path: &Path) -> Result<ObjFile> {
    let mut reader = open(path)?.buffered();
    let header = read_header(&mut reader, path)?;
    let header_bytes = reader.get_ref().position().saturating_sub(reader.buffer().len() as u64);
    let room = reader.get_ref().size().saturating_sub(header_bytes);
    // The counts the header claims must fit the bytes the file has left.
    let mut needed = 0u64;
    for e in &header.elements {
        needed = needed.saturating_add(e.count.saturating_mul(e.min_bytes(header.format)));
        if needed > room {
            return Err(Error::parse(
                path,
                None,
                format!(
                    "the header says {} '{}' elements, more than the {room} bytes after it can hold",
                    e.count, e.name
                ),
            ));
        }
    }
    let vertex_count = header.elements.iter().find(|e| e.name == "vertex").map_or(0, |e| e.count);
    let face_count = header.elements.iter().find(|e| e.name == "face").map_or(0, |e| e.count);
    // At least one triangle a face; the reservation grows where faces are longer.
    let estimate = MeshSize { triangles: face_count, vertices: vertex_count };
    estimate.reserve(path)?;
    let mut mesh = PlyMesh {
        positions: estimate.vec(path, vertex_count as usize)?,
        normals: Vec::new(),
        uvs: Vec::new(),
        triangles: estimate.vec(path, face_count as usize)?,
    };
    let mut source = match header.format {
        Format::Ascii => Source::Ascii(AsciiSource { lines: header.lines }),
        format => Source::Binary(format),
    };
    for element in &header.elements {
        read_element(&mut reader, &mut source, element, vertex_count, &mut mesh, path)?;
    }
    if mesh.triangles.is_empty() {
        return Err(Error::parse(path, None, "no faces: a PLY file without triangles is not a mesh"));
    }
    let normals = if mesh.normals.is_empty() {
        let flat: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        smooth_normals(&mesh.positions, &flat)
    } else {
        mesh.normals.iter().map(|n| n.normalize_or_zero()).collect()
    };
    let name = path.file_stem().map_or_else(|| "ply".into(), |s| s.to_string_lossy().into_owned());
    Ok(ObjFile {
        raw_positions: mesh.positions.clone(),
        meshes: vec![ObjMesh {
            name,
            positions: mesh.positions,
            normals,
            uvs: mesh.uvs,
            triangles: mesh.triangles,
            material: None,
        }],
        materials: Vec::new(),
        warnings: Vec::new(),
    })
}

/// What the file gives, as it is read.
struct PlyMesh {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    triangles: Vec<[u32; 3]>,
}

/// Read the header's lines, up to and including `end_header`.
fn read_header(reader: &mut BufReader<Bounded>, path: &Path) -> Result<Header> {
    let mut limited = reader.by_ref().take(MAX_HEADER_BYTES);
    let mut line = Vec::new();
    let (mut format, mut elements, mut number) = (None, Vec::<Element>::new(), 0);
    loop {
        line.clear();
        number += 1;
        let n = limited.read_until(b'\n', &mut line).map_err(|e| limited.get_ref().get_ref().error(e))?;
        let err = |message: String| Error::parse(path, Some(number), message);
        if n == 0 {
            return Err(err("the header ends before `end_header` (is this a PLY file?)".into()));
        }
        let text = std::str::from_utf8(&line).map_err(|_| err("the header is not text".into()))?;
        let words: Vec<&str> = text.split_whitespace().collect();
        if number == 1 {
            if words != ["ply"] {
                return Err(err("not a PLY file: the first line is not `ply`".into()));
            }
            continue;
        }
        match words.as_slice() {
            ["format", kind, version] => {
                if *version != "1.0" {
                    return Err(err(format!("PLY version {version} is not supported (1.0 is)")));
                }
                format = Some(match *kind {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::LittleEndian,
                    "binary_big_endian" => Format::BigEndian,
                    _ => return Err(err(format!("unknown PLY format '{kind}'"))),
                });
            }
            ["comment" | "obj_info", ..] | [] => {}
            ["element", name, count] => {
                let count = count.parse().map_err(|_| err(format!("'{count}' is not an element count")))?;
                elements.push(Element { name: name.to_string(), count, properties: Vec::new() });
            }
            ["property", rest @ ..] => {
                let Some(element) = elements.last_mut() else {
                    return Err(err("a property before any element".into()));
                };
                let scalar = |w: &str| Scalar::parse(w).ok_or_else(|| err(format!("unknown property type '{w}'")));
                let property = match rest {
                    ["list", count, value, name] => {
                        let count = scalar(count)?;
                        if matches!(count, Scalar::F32 | Scalar::F64) {
                            return Err(err("a list's count must be an integer type".into()));
                        }
                        Property { name: name.to_string(), count: Some(count), value: scalar(value)? }
                    }
                    [value, name] => Property { name: name.to_string(), count: None, value: scalar(value)? },
                    _ => return Err(err(format!("malformed property: '{}'", text.trim()))),
                };
                element.properties.push(property);
            }
            ["end_header"] => break,
            _ => return Err(err(format!("not a PLY header line: '{}'", text.trim()))),
        }
    }
    let format = format.ok_or_else(|| Error::parse(path, None, "the header has no `format` line"))?;
    Ok(Header { format, elements, lines: number })
}

/// How element values are read.
enum Source {
    Ascii(AsciiSource),
    Binary(Format),
}

/// The position in an ASCII file: the lines read so far.
struct AsciiSource {
    lines: usize,
}

/// One element's values as read: scalars in `values` (list items included), and for each
/// property the index of its first value and its length (1 for a scalar).
#[derive(Default)]
struct Record {
    values: Vec<f64>,
    spans: Vec<(usize, usize)>,
}

impl Record {
    fn scalar(&self, property: usize) -> f64 {
        self.values[self.spans[property].0]
    }

    fn list(&self, property: usize) -> &[f64] {
        let (start, len) = self.spans[property];
        &self.values[start..start + len]
    }
}

/// The longest list read: far more corners than any real face has, and a bound on what one
/// record holds, so a lying count cannot allocate much.
const MAX_LIST: usize = 1 << 16;

/// Read the `count` records of `element` and keep what the mesh needs.
fn read_element(
    reader: &mut BufReader<Bounded>,
    source: &mut Source,
    element: &Element,
    vertex_count: u64,
    mesh: &mut PlyMesh,
    path: &Path,
) -> Result<()> {
    enum Use {
        Vertex(VertexLayout),
        Face(usize),
        Skip,
    }
    let usage = match element.name.as_str() {
        "vertex" => {
            let layout = VertexLayout::of(element, path)?;
            if layout.normal.is_some() {
                mesh.normals.reserve_exact(element.count as usize);
            }
            if layout.uv.is_some() {
                mesh.uvs.reserve_exact(element.count as usize);
            }
            Use::Vertex(layout)
        }
        "face" => {
            let list = element
                .properties
                .iter()
                .position(|p| p.count.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index"));
            let Some(list) = list else {
                return Err(Error::parse(path, None, "the face element has no `vertex_indices` list"));
            };
            Use::Face(list)
        }
        _ => Use::Skip,
    };
    let mut record = Record::default();
    let mut line = String::new();
    for i in 0..element.count {
        let at = |source: &Source| match source {
            Source::Ascii(a) => Some(a.lines),
            Source::Binary(_) => None,
        };
        let err = |source: &Source, message: String| {
            Error::parse(path, at(source), format!("{} {i}: {message}", element.name))
        };
        record.values.clear();
        record.spans.clear();
        match source {
            Source::Ascii(a) => {
                line.clear();
                a.lines += 1;
                let n = reader.read_line(&mut line).map_err(|e| match e.kind() {
                    std::io::ErrorKind::InvalidData => {
                        Error::parse(path, Some(a.lines), "not text (bytes that are not UTF-8)")
                    }
                    _ => reader.get_ref().error(e),
                })?;
                if n == 0 {
                    return Err(err(source, "the file ends before it (the header counts more)".into()));
                }
                let mut words = line.split_whitespace();
                for p in &element.properties {
                    let mut next = |what: &str| -> Result<f64> {
                        let w =
                            words.next().ok_or_else(|| err(source, format!("'{}' is missing its {what}", p.name)))?;
                        w.parse::<f64>().map_err(|_| err(source, format!("'{w}' is not a number ({})", p.name)))
                    };
                    let len = match p.count {
                        Some(_) => list_len(next("count")?).map_err(|m| err(source, format!("{}: {m}", p.name)))?,
                        None => 1,
                    };
                    record.spans.push((record.values.len(), len));
                    for _ in 0..len {
                        let v = next("value")?;
                        record.values.push(v);
                    }
                }
                if let Some(extra) = words.next() {
                    return Err(err(source, format!("'{extra}' is more than the header's properties")));
                }
            }
            Source::Binary(format) => {
                let format = *format;
                let mut buf = [0u8; 8];
                let mut read = |s: Scalar, what: &str| -> Result<f64> {
                    let b = &mut buf[..s.size()];
                    reader.read_exact(b).map_err(|e| match e.kind() {
                        std::io::ErrorKind::UnexpectedEof => {
                            err(source, format!("the file ends inside it ({what}; the header counts more)"))
                        }
                        _ => reader.get_ref().error(e),
                    })?;
                    Ok(s.decode(b, format))
                };
                for p in &element.properties {
                    let len = match p.count {
                        Some(c) => list_len(read(c, &p.name)?).map_err(|m| err(source, format!("{}: {m}", p.name)))?,
                        None => 1,
                    };
                    record.spans.push((record.values.len(), len));
                    for _ in 0..len {
                        let v = read(p.value, &p.name)?;
                        record.values.push(v);
                    }
                }
            }
        }
        match &usage {
            Use::Vertex(l) => {
                let v3 = |[a, b, c]: [usize; 3]| {
                    Vec3::new(record.scalar(a) as f32, record.scalar(b) as f32, record.scalar(c) as f32)
                };
                let p = v3(l.position);
                if !p.is_finite() {
                    return Err(err(source, "the position is not finite".into()));
                }
                mesh.positions.push(p);
                if let Some(n) = l.normal {
                    let n = v3(n);
                    if !n.is_finite() {
                        return Err(err(source, "the normal is not finite".into()));
                    }
                    mesh.normals.push(n);
                }
                if let Some([u, v]) = l.uv {
                    let t = Vec2::new(record.scalar(u) as f32, record.scalar(v) as f32);
                    if !t.is_finite() {
                        return Err(err(source, "the texture coordinates are not finite".into()));
                    }
                    mesh.uvs.push(t);
                }
            }
            Use::Face(list) => {
                let corners = record.list(*list);
                if corners.len() < 3 {
                    return Err(err(source, format!("a face needs at least 3 vertices, found {}", corners.len())));
                }
                let index = |v: f64| -> Result<u32> {
                    if v >= 0.0 && v < vertex_count as f64 && v.fract() == 0.0 {
                        Ok(v as u32)
                    } else {
                        Err(err(source, format!("vertex index {v} is out of range ({vertex_count} vertices)")))
                    }
                };
                let first = index(corners[0])?;
                let mut prev = index(corners[1])?;
                for &c in &corners[2..] {
                    let c = index(c)?;
                    mesh.triangles.push([first, prev, c]);
                    prev = c;
                }
            }
            Use::Skip => {}
        }
    }
    Ok(())
}

/// A list's count as read: a whole number, not negative, at most [`MAX_LIST`].
fn list_len(count: f64) -> Result<usize, String> {
    if count >= 0.0 && count <= MAX_LIST as f64 && count.fract() == 0.0 {
        Ok(count as usize)
    } else {
        Err(format!("a list of {count} items (at most {MAX_LIST} are read)"))
    }
}
