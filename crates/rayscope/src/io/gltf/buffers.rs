//! The bytes behind a glTF document: the GLB container's chunks, each buffer's data (the GLB's
//! binary chunk, a `data:` URI, or a file beside the document, read through
//! [`crate::io::file`] with its limits), and the accessors' elements read out of them, every
//! offset, stride and count checked against the bytes there are before anything is read.

use std::io::Read;
use std::path::Path;

use base64::Engine;
use gltf::accessor::{DataType, Dimensions};

use crate::error::{Error, Result};
use crate::io::file::open;

/// A glTF file's two parts: the JSON document and, in a GLB, its binary chunk.
pub struct Container {
    /// The JSON text.
    pub json: Vec<u8>,
    /// The GLB's `BIN` chunk.
    pub bin: Option<Vec<u8>>,
}

/// The magic bytes of a GLB file.
const GLB_MAGIC: &[u8; 4] = b"glTF";

/// Split a file's bytes into its document and binary chunk: a GLB's chunks (header, `JSON`
/// chunk, optional `BIN` chunk, every length checked), or the whole file as JSON.
pub fn split_container(bytes: Vec<u8>, path: &Path) -> Result<Container> {
    if !bytes.starts_with(GLB_MAGIC) {
        return Ok(Container { json: bytes, bin: None });
    }
    let bad = |message: String| Error::parse(path, None, format!("GLB: {message}"));
    let u32_at = |at: usize| -> Option<u32> {
        bytes.get(at..at + 4).map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
    };
    let version = u32_at(4).ok_or_else(|| bad("the header is truncated".into()))?;
    if version != 2 {
        return Err(bad(format!("version {version} is not supported (2 is)")));
    }
    let total = u32_at(8).ok_or_else(|| bad("the header is truncated".into()))? as usize;
    if total > bytes.len() {
        return Err(bad(format!("the header says {total} bytes, the file has {}", bytes.len())));
    }
    let mut chunks = Vec::new();
    let mut at = 12;
    while at < total {
        let (Some(len), Some(kind)) = (u32_at(at), bytes.get(at + 4..at + 8)) else {
            return Err(bad(format!("chunk {} has a truncated header", chunks.len())));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= total)
            .ok_or_else(|| bad(format!("chunk {} says {len} bytes, more than the file has after it", chunks.len())))?;
        chunks.push((kind.to_vec(), start..end));
        // Chunks are padded to 4 bytes.
        at = end.next_multiple_of(4);
    }
    let mut chunks = chunks.into_iter();
    let json = match chunks.next() {
        Some((kind, range)) if kind == b"JSON" => bytes[range].to_vec(),
        _ => return Err(bad("the first chunk is not the JSON chunk".into())),
    };
    let bin = chunks.next().filter(|(kind, _)| kind == b"BIN\0").map(|(_, range)| bytes[range].to_vec());
    Ok(Container { json, bin })
}

/// The whole of a regular file within the loaders' limit.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    let mut file = open(path)?;
    let mut bytes = Vec::with_capacity(file.size().min(1 << 30) as usize);
    file.read_to_end(&mut bytes).map_err(|e| file.error(e))?;
    Ok(bytes)
}

/// The data of a URI of the document at `path`: a base64 `data:` URI, or a file relative to
/// the document's folder (other schemes are refused: rayscope reads no network).
pub fn read_uri(uri: &str, path: &Path, what: &str) -> Result<Vec<u8>> {
    let bad = |message: String| Error::parse(path, None, format!("{what}: {message}"));
    if let Some(data) = uri.strip_prefix("data:") {
        let Some((_, payload)) = data.split_once(";base64,") else {
            return Err(bad("a data: URI that is not base64".into()));
        };
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| bad(format!("the data: URI is not valid base64 ({e})")));
    }
    if uri.contains("://") {
        return Err(bad(format!("'{uri}' is not a file beside the document (rayscope reads no network)")));
    }
    let name = percent_decode(uri).ok_or_else(|| bad(format!("'{uri}' is not a valid URI")))?;
    read_file(&path.parent().unwrap_or(Path::new(".")).join(name))
}

/// A relative URI's `%XX` escapes decoded (file names with spaces are written `%20`).
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Read the data of every buffer of `doc` (the document at `path`, with its GLB chunk `bin`):
/// each at least as long as the buffer says.
pub fn read_buffers(doc: &gltf::Document, bin: Option<&[u8]>, path: &Path) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let what = format!("buffer {}", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => match bin {
                Some(b) => b.to_vec(),
                None => {
                    return Err(Error::parse(path, None, format!("{what}: refers to a GLB binary chunk there is not")));
                }
            },
            gltf::buffer::Source::Uri(uri) => read_uri(uri, path, &what)?,
        };
        if data.len() < buffer.length() {
            return Err(Error::parse(
                path,
                None,
                format!(
                    "{what}: {} bytes, shorter than the {} its byteLength says (truncated?)",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// The bytes of buffer view `view`, checked to lie inside its buffer's data.
pub fn view_bytes<'a>(view: &gltf::buffer::View, buffers: &'a [Vec<u8>], path: &Path) -> Result<&'a [u8]> {
    let data = &buffers[view.buffer().index()];
    let (start, len) = (view.offset(), view.length());
    start.checked_add(len).and_then(|end| data.get(start..end)).ok_or_else(|| {
        Error::parse(
            path,
            None,
            format!(
                "bufferView {}: bytes {start}..{} lie outside buffer {} ({} bytes)",
                view.index(),
                start.saturating_add(len),
                view.buffer().index(),
                data.len()
            ),
        )
    })
}

/// What an accessor must be for its use: its element type and the component types read.
pub struct Expect {
    /// The element's type (VEC3 for positions, SCALAR for indices, ...).
    pub dimensions: Dimensions,
    /// The component types accepted (integers are read normalised when the accessor says so).
    pub types: &'static [DataType],
    /// The use, for errors: "POSITION", "indices", ...
    pub role: &'static str,
}

/// The elements of `accessor` as numbers (`count × components` of them), checked against
/// `expect` and against the bytes of its buffer view: an accessor of the wrong type, or one
/// whose elements reach past its view, is an error naming it.
pub fn read_accessor(accessor: &gltf::Accessor, expect: &Expect, buffers: &[Vec<u8>], path: &Path) -> Result<Vec<f64>> {
    let bad = |message: String| {
        Error::parse(path, None, format!("accessor {} ({}): {message}", accessor.index(), expect.role))
    };
    if accessor.dimensions() != expect.dimensions || !expect.types.contains(&accessor.data_type()) {
        return Err(bad(format!(
            "is {:?} of {:?}, expected {:?} of {:?}",
            accessor.dimensions(),
            accessor.data_type(),
            expect.dimensions,
            expect.types
        )));
    }
    if accessor.sparse().is_some() {
        return Err(bad("sparse accessors are not supported".into()));
    }
    let Some(view) = accessor.view() else {
        return Err(bad("has no bufferView (all zeros), which is not supported".into()));
    };
    let bytes = view_bytes(&view, buffers, path)?;
    let components = expect.dimensions.multiplicity();
    let size = accessor.data_type().size();
    let element = components * size;
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(bad(format!("the view's stride {stride} is smaller than an element ({element} bytes)")));
    }
    let count = accessor.count();
    // The last element ends inside the view.
    let first_end = accessor.offset().checked_add(element);
    let end = count
        .checked_sub(1)
        .map(|last| last.checked_mul(stride).zip(first_end).and_then(|(b, e)| b.checked_add(e)))
        .unwrap_or(Some(0));
    match end {
        Some(end) if end <= bytes.len() => {}
        _ => {
            return Err(bad(format!(
                "{count} elements from byte {} reach past bufferView {} ({} bytes)",
                accessor.offset(),
                view.index(),
                bytes.len()
            )));
        }
    }
    let normalized = accessor.normalized();
    let mut out = Vec::with_capacity(count * components);
    for i in 0..count {
        let at = accessor.offset() + i * stride;
        for c in 0..components {
            let b = &bytes[at + c * size..at + (c + 1) * size];
            out.push(component(accessor.data_type(), b, normalized));
        }
    }
    Ok(out)
}

/// One little-endian component's value (an integer divided to [0, 1] or [-1, 1] when
/// `normalized`, as glTF's normalised integers are).
fn component(t: DataType, b: &[u8], normalized: bool) -> f64 {
    let (v, max) = match t {
        DataType::I8 => (b[0] as i8 as f64, i8::MAX as f64),
        DataType::U8 => (b[0] as f64, u8::MAX as f64),
        DataType::I16 => (i16::from_le_bytes([b[0], b[1]]) as f64, i16::MAX as f64),
        DataType::U16 => (u16::from_le_bytes([b[0], b[1]]) as f64, u16::MAX as f64),
        DataType::U32 => (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64, u32::MAX as f64),
        DataType::F32 => return f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    };
    if normalized { (v / max).max(-1.0) } else { v }
}
