//! One chunk of an OBJ file's lines, parsed on its own so that the chunks of a file parse on
//! all cores ([`super::obj`] puts them together in file order).
//!
//! A chunk does not know how many vertices the chunks before it define, so it keeps face
//! indices as written (absolute, or relative to its own count) and the extremes a range check
//! needs: when they pass against the counts before the chunk (almost always), the chunk is
//! right; when not, the chunk is parsed again knowing them ([`Before`]), which checks every
//! index and stops at the first error, at its line, as a reader of the whole file would.
//! Every line is checked as the scan of the old two-pass reader checked it, with the same
//! messages: numbers parse and are finite, indices refer to elements defined before them,
//! faces have three corners or more, statements are OBJ's.

use super::decimal::parse_f32;
use super::file::{NOT_UTF8, NUL_BYTE};
use crate::math::{Vec2, Vec3};

/// A corner without this index (a face that gives none, or gives one where none exist).
pub const MISSING: i64 = i64::MIN;

/// The offset that marks an index relative to the chunk's first element: a stored value below
/// zero (and above [`MISSING`]) is `RELATIVE + i`, element `i` counted from the chunk's first.
const RELATIVE: i64 = -(1 << 62);

/// The kinds of elements a face corner indexes: positions, texture coordinates, normals.
const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];

/// The statements of the OBJ format; a line starting with anything else is not OBJ.
pub const STATEMENTS: &[&str] = &[
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

/// What the file defines before a chunk, for the exact (second) parse of it.
#[derive(Clone, Copy, Debug, Default)]
pub struct Before {
    /// The `v`, `vt` and `vn` lines before it.
    pub counts: [i64; 3],
    /// Whether the last `v` line before it gave a colour (`None`: no `v` line yet).
    pub colored: Option<bool>,
}

/// A statement that changes what the faces after it belong to.
#[derive(Clone, Debug)]
pub enum Statement {
    /// `o` or `g`: a new group, with this name.
    Group(String),
    /// `usemtl`: the faces after it use the material of this name.
    UseMtl(String),
    /// `mtllib`: the MTL files to read, in order.
    MtlLib(Vec<String>),
}

/// A [`Statement`] and where it is.
#[derive(Clone, Debug)]
pub struct Event {
    /// The triangle corners of the chunk before it.
    pub corners: usize,
    /// The `v`, `vt` and `vn` lines of the chunk before it.
    pub counts: [i64; 3],
    /// The statement.
    pub statement: Statement,
}

/// The `v` lines' colours in a chunk: the first and the last.
#[derive(Clone, Copy, Debug)]
pub struct Colors {
    /// Whether the first `v` line gives a colour.
    pub first: bool,
    /// Whether the last one does.
    pub last: bool,
}

/// The extremes of one kind of index in a chunk, to check them against the count before it.
#[derive(Clone, Copy, Debug)]
pub struct Extremes {
    /// The largest `index - count` of a positive (absolute) index, where `count` is the
    /// chunk's elements before its face: fine when at most the count before the chunk.
    pub over: i64,
    /// The smallest `count + index` of a negative (relative) index: fine when at least minus
    /// the count before the chunk.
    pub under: i64,
    /// The first line giving an index while the chunk had no element of the kind yet: fine
    /// only when the file has none before the chunk either (a warning, or an error if some
    /// come later).
    pub unbacked: Option<usize>,
}

impl Default for Extremes {
    fn default() -> Extremes {
        Extremes { over: i64::MIN, under: i64::MAX, unbacked: None }
    }
}

/// A chunk's lines, parsed.
#[derive(Clone, Debug, Default)]
pub struct Chunk {
    /// Its lines.
    pub lines: usize,
    /// The `v` lines' positions (divided by a weight, as given).
    pub positions: Vec<Vec3>,
    /// The `vt` lines' coordinates.
    pub texcoords: Vec<Vec2>,
    /// The `vn` lines' normals.
    pub normals: Vec<Vec3>,
    /// The triangles' corners (faces fanned from their first corner), three a triangle: the
    /// position, texture coordinate and normal index of each, stored as [`resolve`] reads
    /// them. The texture coordinate (normal) list is empty when no corner gives one.
    pub corners: [Vec<i64>; 3],
    /// The group, material and library statements, in order.
    pub events: Vec<Event>,
    /// The triangles of its faces.
    pub triangles: u64,
    /// The colours of its `v` lines (`None`: no `v` line).
    pub colors: Option<Colors>,
    /// The extremes of its indices, per kind (for a chunk parsed without [`Before`]).
    pub extremes: [Extremes; 3],
    /// The first texture coordinate (normal) index given where the file has none so far, per
    /// kind (index 0 unused): its line (for a chunk parsed with [`Before`]).
    pub missing: [Option<usize>; 3],
    /// The first error: its line and message. The chunk's lines after it are not parsed.
    pub error: Option<(usize, String)>,
}

/// A stored index as the 0-based index of its element, given the chunk's first (`base`);
/// [`MISSING`] stays.
#[inline]
pub fn resolve(stored: i64, base: i64) -> i64 {
    if stored >= 0 || stored == MISSING { stored } else { base + (stored - RELATIVE) }
}

impl Chunk {
    /// Whether the indices pass against what the file defines `before` the chunk (parsed
    /// without [`Before`]), its first `v` line's colour agrees with the last before it, and
    /// no index is given where none exist but some do before the chunk.
    pub fn fits(&self, before: &Before) -> bool {
        let colors = match (self.colors, before.colored) {
            (Some(c), Some(last)) => c.first == last,
            _ => true,
        };
        colors
            && self
                .extremes
                .iter()
                .zip(before.counts)
                .all(|(e, count)| e.over <= count && e.under >= -count && (e.unbacked.is_none() || count == 0))
    }
}

/// Whether `b` is whitespace to [`str::split_whitespace`] (for ASCII bytes).
#[inline(always)]
fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\n' | 0x0b | 0x0c | b'\r')
}

/// The words of a line as [`str::split_whitespace`] gives them, by bytes when the text is
/// ASCII.
fn split_words<'a>(line: &'a str, ascii: bool, words: &mut Vec<&'a str>) {
    words.clear();
    if !ascii {
        words.extend(line.split_whitespace());
        return;
    }
    let bytes = line.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        while i < bytes.len() && is_space(bytes[i]) {
            i += 1;
        }
        let start = i;
        while i < bytes.len() && !is_space(bytes[i]) {
            i += 1;
        }
        if start < i {
            // ASCII: every byte is a character boundary.
            words.push(&line[start..i]);
        }
    }
}

/// A chunk's state as it parses: what the lines give and count.
struct Parser<'a> {
    chunk: Chunk,
    /// What the file defines before the chunk, when known (the exact parse).
    before: Option<Before>,
    /// Whether the chunk's text is ASCII.
    ascii: bool,
    /// The words of the current line.
    words: Vec<&'a str>,
    /// The corners of the current face.
    face: Vec<[i64; 3]>,
}

/// Parse `text` (whole lines of an OBJ file; the last may lack its line end), knowing what
/// comes `before` it or not (see [`Chunk::fits`]).
pub fn parse_chunk(text: &[u8], before: Option<Before>) -> Chunk {
    // The first line that is no text: the chunk ends before it, with its error.
    let nul = memchr::memchr(0, text);
    let invalid = match std::str::from_utf8(text) {
        Ok(_) => None,
        Err(e) => Some(e.valid_up_to()),
    };
    let bad = match (nul, invalid) {
        (Some(n), Some(u)) => Some(n.min(u)),
        (n, u) => n.or(u),
    };
    let good = bad.map_or(text.len(), |b| memchr::memrchr(b'\n', &text[..b]).map_or(0, |n| n + 1));
    // SAFETY: `good` ends at a line end (or 0) before the first byte that breaks UTF-8, so
    // `text[..good]` is valid UTF-8 (a line end is never inside a character).
    let valid = unsafe { std::str::from_utf8_unchecked(&text[..good]) };
    let mut p =
        Parser { chunk: Chunk::default(), before, ascii: valid.is_ascii(), words: Vec::new(), face: Vec::new() };
    let mut number = 0;
    for line in valid.split_inclusive('\n') {
        number += 1;
        // `\n` or `\r\n` ends a line; a last line without `\n` keeps a `\r`.
        let line = match line.strip_suffix('\n') {
            Some(line) => line.strip_suffix('\r').unwrap_or(line),
            None => line,
        };
        if let Err(message) = p.line(number, line) {
            p.chunk.error = Some((number, message));
            p.chunk.lines = number;
            return p.chunk;
        }
    }
    if let Some(b) = bad {
        // The NUL byte wins when on the same line: the reader stops at it, before the line
        // is checked as UTF-8.
        let line_of = |at: usize| number + 1 + memchr::memchr_iter(b'\n', &text[good..at]).count();
        let on = line_of(b);
        let message = if nul.is_some_and(|n| line_of(n) == on) { NUL_BYTE } else { NOT_UTF8 };
        p.chunk.error = Some((on, message.to_string()));
        number = on;
    }
    p.chunk.lines = number;
    p.chunk
}

impl<'a> Parser<'a> {
    /// The count of the kind `k`'s elements so far: the file's when known, else the chunk's.
    fn count(&self, k: usize) -> i64 {
        let chunk = [self.chunk.positions.len(), self.chunk.texcoords.len(), self.chunk.normals.len()][k] as i64;
        chunk + self.before.map_or(0, |b| b.counts[k])
    }

    /// Parse one line (`number` in the chunk), its line end removed.
    fn line(&mut self, number: usize, line: &'a str) -> Result<(), String> {
        let mut words = std::mem::take(&mut self.words);
        split_words(line, self.ascii, &mut words);
        let result = self.statement(number, line, &words);
        self.words = words;
        result
    }

    fn statement(&mut self, number: usize, line: &'a str, words: &[&'a str]) -> Result<(), String> {
        let Some((&head, rest)) = words.split_first() else { return Ok(()) };
        if head.starts_with('#') {
            return Ok(());
        }
        match head {
            "v" => self.vertex(rest),
            "vt" => {
                let [u, v, ..] = floats(rest, 2, 3)?;
                self.chunk.texcoords.push(Vec2::new(u, v));
                Ok(())
            }
            "vn" => {
                let [x, y, z, ..] = floats(rest, 3, 3)?;
                self.chunk.normals.push(Vec3::new(x, y, z));
                Ok(())
            }
            "f" | "l" => self.face(number, head == "f", rest),
            "mtllib" => {
                if rest.is_empty() {
                    return Err("mtllib names no file".into());
                }
                // The format's `mtllib a.mtl b.mtl`: several libraries, all read.
                self.event(Statement::MtlLib(rest.iter().map(|s| s.to_string()).collect()));
                Ok(())
            }
            "usemtl" => {
                // The name after the first space, as the old reader (tobj) took it.
                let name = line.split_once(' ').map(|(_, name)| name.trim()).unwrap_or_default();
                if name.is_empty() {
                    return Err("usemtl names no material".into());
                }
                self.event(Statement::UseMtl(name.to_string()));
                Ok(())
            }
            "o" | "g" => {
                // What follows the line's first character, trimmed, as tobj named groups.
                let first = line.chars().next().map_or(0, char::len_utf8);
                let name = line[first..].trim();
                let name = if name.is_empty() { "unnamed_object" } else { name };
                self.event(Statement::Group(name.to_string()));
                Ok(())
            }
            _ if STATEMENTS.contains(&head) => Ok(()),
            _ => {
                let shown: String = line.chars().take(60).collect();
                Err(format!("not an OBJ statement: '{}' (is this a mesh file?)", shown.escape_debug()))
            }
        }
    }

    fn event(&mut self, statement: Statement) {
        let counts =
            [self.chunk.positions.len(), self.chunk.texcoords.len(), self.chunk.normals.len()].map(|c| c as i64);
        self.chunk.events.push(Event { corners: self.chunk.corners[0].len(), counts, statement });
    }

    /// A `v` line: x y z, then nothing, a weight w, or a colour r g b.
    fn vertex(&mut self, rest: &[&str]) -> Result<(), String> {
        if ![3, 4, 6].contains(&rest.len()) {
            return Err(format!("expected 3, 4 or 6 numbers, found {}", rest.len()));
        }
        let [x, y, z, w, ..] = floats(rest, 3, 6)?;
        let position = if rest.len() == 4 {
            let p = [x / w, y / w, z / w];
            if !p.iter().all(|c| c.is_finite()) {
                return Err(format!("the weight {} makes the vertex infinite", rest[3]));
            }
            Vec3::from(p)
        } else {
            Vec3::new(x, y, z)
        };
        // Colours were paired with vertices by position in a list: all or none.
        let colored = rest.len() == 6;
        let last = match self.chunk.colors {
            Some(c) => Some(c.last),
            None => self.before.and_then(|b| b.colored),
        };
        if last.is_some_and(|last| last != colored) {
            return Err("vertex colours are given for some vertices only".into());
        }
        match &mut self.chunk.colors {
            Some(c) => c.last = colored,
            None => self.chunk.colors = Some(Colors { first: colored, last: colored }),
        }
        self.chunk.positions.push(position);
        Ok(())
    }

    /// An `f` (`face`) or `l` line: corners `v`, `v/vt`, `v//vn` or `v/vt/vn`.
    fn face(&mut self, number: usize, face: bool, rest: &[&str]) -> Result<(), String> {
        if face && rest.len() < 3 {
            return Err(format!("a face needs at least 3 vertices, found {}", rest.len()));
        }
        self.face.clear();
        for corner in rest {
            let invalid = || format!("'{corner}' is not a valid face vertex");
            let mut stored = [MISSING; 3];
            for (k, part) in corner.split('/').enumerate() {
                if k > 2 {
                    return Err(invalid());
                }
                if part.is_empty() && k > 0 {
                    continue;
                }
                let idx = parse_index(part).ok_or_else(invalid)?;
                // Polylines are not drawn; only their syntax matters.
                if !face {
                    continue;
                }
                stored[k] = self.index(number, k, idx)?;
            }
            self.face.push(stored);
        }
        if !face {
            return Ok(());
        }
        self.chunk.triangles += rest.len() as u64 - 2;
        let before = self.chunk.corners[0].len();
        for k in 0..3 {
            if k > 0 && self.chunk.corners[k].is_empty() && self.face.iter().all(|c| c[k] == MISSING) {
                continue;
            }
            let corners = self.chunk.face_corners(k, before);
            let face = &self.face;
            for i in 1..face.len() - 1 {
                corners.extend_from_slice(&[face[0][k], face[i][k], face[i + 1][k]]);
            }
        }
        Ok(())
    }

    /// Check and store index `idx` of kind `k` on line `number`.
    fn index(&mut self, number: usize, k: usize, idx: i64) -> Result<i64, String> {
        let local = [self.chunk.positions.len(), self.chunk.texcoords.len(), self.chunk.normals.len()][k] as i64;
        let Some(before) = self.before else {
            let e = &mut self.chunk.extremes[k];
            if local == 0 && k > 0 {
                e.unbacked.get_or_insert(number);
                return Ok(MISSING);
            }
            if idx > 0 {
                e.over = e.over.max(idx - local);
                return Ok(idx - 1);
            }
            if idx == 0 {
                // No index at all: out of range whatever the count, for the exact parse to say.
                e.over = i64::MAX;
                return Ok(MISSING);
            }
            e.under = e.under.min(local + idx);
            return Ok(RELATIVE + local + idx);
        };
        let count = self.count(k);
        if count == 0 && k > 0 {
            self.chunk.missing[k].get_or_insert(number);
            return Ok(MISSING);
        }
        let ok = if idx > 0 { idx <= count } else { idx < 0 && -idx <= count };
        if !ok {
            return Err(format!("{} index {idx} is out of range ({count} defined so far)", KINDS[k]));
        }
        Ok(if idx > 0 { idx - 1 } else { before.counts[k] + local + idx })
    }
}

impl Chunk {
    /// The corner list of kind `k`, filled with [`MISSING`] for the `n` corners before the
    /// current face.
    fn face_corners(&mut self, k: usize, n: usize) -> &mut Vec<i64> {
        if k > 0 && self.corners[k].len() < n {
            self.corners[k].resize(n, MISSING);
        }
        &mut self.corners[k]
    }
}

/// A face index: an integer as [`str::parse::<i64>`] reads it.
#[inline]
fn parse_index(text: &str) -> Option<i64> {
    let bytes = text.as_bytes();
    if (1..=9).contains(&bytes.len()) && bytes.iter().all(u8::is_ascii_digit) {
        return Some(bytes.iter().fold(0, |n, &b| n * 10 + i64::from(b - b'0')));
    }
    text.parse().ok()
}

/// The numbers of a line, between `min` and `max` of them, all finite; the rest of the six
/// returned are 0.
fn floats(words: &[&str], min: usize, max: usize) -> Result<[f32; 6], String> {
    if words.len() < min || words.len() > max {
        return Err(format!("expected {min} to {max} numbers, found {}", words.len()));
    }
    let mut out = [0.0; 6];
    for (o, w) in out.iter_mut().zip(words) {
        let v = parse_f32(w).ok_or_else(|| format!("'{w}' is not a number"))?;
        if !v.is_finite() {
            return Err(format!("'{w}' is not a finite number"));
        }
        *o = v;
    }
    Ok(out)
}
