//! PLY meshes (the Stanford polygon format): ASCII, binary little endian
//! and binary big endian.
//!
//! Hand-written rather than through a crate (docs/dependencies.md): the
//! PLY crates reserve memory from a header's counts before reading any
//! data, build a map or a `Vec` per element, and name neither the element
//! nor its index in their errors. Here the file is read once (through
//! [`super::input`]), every count is checked against the bytes left and
//! the memory available before anything is reserved, and faces are
//! triangulated as their indices stream by, with no allocation per element.
//!
//! Read: `vertex` `x y z`, `nx ny nz`, one uv pair (`u v`, `s t`,
//! `texture_u texture_v` or `texture_s texture_t`) and colours (`red green
//! blue`, or `diffuse_*`); `face` lists (`vertex_indices` or
//! `vertex_index`), polygons as fans; `tristrips` with `-1` restarts. The
//! renderer has no per-vertex colour, so vertex (or face) colours become
//! each face's albedo. Other elements and properties are skipped.

use super::assets::{Assets, DEFAULT_MATERIAL};
use super::texture::srgb_to_linear;
use super::Material;
use crate::error::{Error, Result};
use crate::geom::Mesh;
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::path::Path;

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
    /// The type a header names, in either spelling.
    fn from_name(name: &str) -> Option<Scalar> {
        Some(match name {
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

    /// The name used in messages.
    fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    /// Bytes in binary files.
    fn size(self) -> u64 {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The values of an integer type (ASCII values are checked against it).
    fn range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            _ => (0, u32::MAX.into()),
        }
    }
}

/// How the data after the header is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A property's type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PropertyKind {
    Scalar(Scalar),
    /// A count of type `count`, then that many values of type `item`.
    List {
        count: Scalar,
        item: Scalar,
    },
}

/// A `property` line.
#[derive(Debug)]
struct Property {
    name: String,
    kind: PropertyKind,
    /// Its header line.
    line: usize,
}

/// An `element` line and its properties.
#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    /// Its header line.
    line: usize,
    properties: Vec<Property>,
}

impl Element {
    /// The index and type of the scalar property `name`; a list by that
    /// name is an error.
    fn scalar(&self, path: &Path, name: &str) -> Result<Option<(usize, Scalar)>> {
        let Some(i) = self.properties.iter().position(|p| p.name == name) else {
            return Ok(None);
        };
        match self.properties[i].kind {
            PropertyKind::Scalar(ty) => Ok(Some((i, ty))),
            PropertyKind::List { .. } => Err(Error::file(
                path,
                Some(self.properties[i].line),
                format!(
                    "`{}` `{name}` must be a scalar property, not a list",
                    self.name
                ),
            )),
        }
    }

    /// The properties named `names`: all of them, or `None` when none is
    /// there; some but not all is an error.
    fn scalars<const N: usize>(
        &self,
        path: &Path,
        names: [&str; N],
    ) -> Result<Option<[(usize, Scalar); N]>> {
        let found: Vec<_> = (names.iter())
            .map(|n| self.scalar(path, n))
            .collect::<Result<_>>()?;
        if found.iter().all(Option::is_none) {
            return Ok(None);
        }
        match found.iter().copied().collect::<Option<Vec<_>>>() {
            Some(all) => Ok(all.try_into().ok()),
            None => Err(Error::file(
                path,
                Some(self.line),
                format!(
                    "`{}` has some of the properties `{}` but not all of them",
                    self.name,
                    names.join(" ")
                ),
            )),
        }
    }

    /// Smallest size of one record in the data: binary, the scalars and
    /// list counts; ASCII, a digit and a separator per property.
    fn min_record_bytes(&self, format: Format) -> u64 {
        let bytes = self.properties.iter().map(|p| match (format, p.kind) {
            (Format::Ascii, _) => 2,
            (_, PropertyKind::Scalar(ty) | PropertyKind::List { count: ty, .. }) => ty.size(),
        });
        bytes.sum()
    }
}

/// The header: format, elements, and where the data starts.
#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Byte offset of the data.
    data_start: usize,
    /// The `end_header` line's number.
    end_line: usize,
}

/// A header line for messages: at most 40 characters.
fn shown(line: &str) -> String {
    let mut s: String = line.chars().take(40).collect();
    if s.len() < line.len() {
        s.push('…');
    }
    s
}

/// Parses the header (up to and including `end_header`).
fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let mut at = if bytes.starts_with("\u{feff}".as_bytes()) {
        3
    } else {
        0
    };
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut number = 0;
    loop {
        number += 1;
        if at >= bytes.len() {
            // Named at the last line there is (the whole file is at fault).
            let msg = match number {
                1 => "empty file: not a PLY file",
                _ => "the header has no `end_header` line (is the file truncated?)",
            };
            return Err(Error::file(path, Some((number - 1).max(1)), msg));
        }
        let end = (bytes[at..].iter().position(|&b| b == b'\n')).map_or(bytes.len(), |i| at + i);
        let raw = &bytes[at..end];
        at = end + 1;
        let err = |msg: String| Error::file(path, Some(number), msg);
        let line = std::str::from_utf8(raw.strip_suffix(b"\r").unwrap_or(raw));
        if number == 1 {
            if !matches!(line.map(str::trim), Ok("ply")) {
                return Err(err("not a PLY file: the first line is not `ply`".into()));
            }
            continue;
        }
        let line = line.map_err(|_| err("header line is not text".into()))?;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        match words.as_slice() {
            [] | ["comment" | "obj_info", ..] => {}
            ["format", name, version] => {
                if format.is_some() {
                    return Err(err("a second `format` line".into()));
                }
                format = Some(match *name {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::BinaryLittleEndian,
                    "binary_big_endian" => Format::BinaryBigEndian,
                    _ => {
                        return Err(err(format!(
                            "unknown PLY format `{}` (ascii, binary_little_endian or \
                             binary_big_endian)",
                            shown(name)
                        )))
                    }
                });
                if !matches!(*version, "1.0" | "1") {
                    return Err(err(format!(
                        "PLY version `{}`: only 1.0 is read",
                        shown(version)
                    )));
                }
            }
            ["element", name, count] => {
                let count = count
                    .parse::<u64>()
                    .map_err(|_| err(format!("malformed element count `{}`", shown(count))))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    line: number,
                    properties: Vec::new(),
                });
            }
            ["property", rest @ ..] => {
                let Some(element) = elements.last_mut() else {
                    return Err(err("`property` before any `element`".into()));
                };
                let property = parse_property(rest, number, &err)?;
                if element.properties.iter().any(|p| p.name == property.name) {
                    return Err(err(format!(
                        "a second property `{}` in element `{}`",
                        property.name, element.name
                    )));
                }
                element.properties.push(property);
            }
            ["end_header"] => {
                let format =
                    format.ok_or_else(|| err("no `format` line before `end_header`".into()))?;
                return Ok(Header {
                    format,
                    elements,
                    data_start: at.min(bytes.len()),
                    end_line: number,
                });
            }
            _ => return Err(err(format!("malformed header line `{}`", shown(line)))),
        }
    }
}

/// Parses the words after `property` on header line `line`.
fn parse_property(words: &[&str], line: usize, err: &dyn Fn(String) -> Error) -> Result<Property> {
    let scalar = |word: &str| {
        Scalar::from_name(word)
            .ok_or_else(|| err(format!("unknown property type `{}`", shown(word))))
    };
    let (kind, name) = match words {
        ["list", count, item, name] => {
            let count = scalar(count)?;
            if !count.is_integer() {
                return Err(err(format!(
                    "a list's count must have an integer type, not {}",
                    count.name()
                )));
            }
            let item = scalar(item)?;
            (PropertyKind::List { count, item }, name)
        }
        [ty, name] if *ty != "list" => (PropertyKind::Scalar(scalar(ty)?), name),
        _ => return Err(err("malformed `property` line".into())),
    };
    Ok(Property {
        name: name.to_string(),
        kind,
        line,
    })
}

/// What an element is to the mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Vertex,
    Faces,
    Strips,
    Other,
}

/// Fields of a vertex record.
const X: usize = 0;
const NX: usize = 3;
const U: usize = 6;
const RED: usize = 8;
const FIELDS: usize = 11;

/// What a property's values feed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Slot {
    Skip,
    /// A field of the vertex record.
    Vertex(usize),
    /// A face's vertex index list.
    Corner,
    /// A triangle strip's vertex index list.
    StripCorner,
    /// A face's own colour channel.
    FaceColour(usize),
}

/// How a colour channel's values map to [0, 1].
#[derive(Debug, Clone, Copy, PartialEq)]
enum ColourScale {
    /// 0..255 (8-bit types, and 32-bit integers as tools write them).
    Byte,
    /// 0..65535.
    Short,
    /// 0..1.
    Unit,
}

impl ColourScale {
    fn of(ty: Scalar) -> Self {
        match ty {
            Scalar::I16 | Scalar::U16 => ColourScale::Short,
            Scalar::F32 | Scalar::F64 => ColourScale::Unit,
            _ => ColourScale::Byte,
        }
    }
}

/// What each element and property feeds, and which optional vertex
/// attributes the file has.
#[derive(Debug)]
struct Layout {
    kinds: Vec<Kind>,
    slots: Vec<Vec<Slot>>,
    vertex_count: u32,
    normals: bool,
    uvs: bool,
    /// Scales of the vertex colour channels, when there are colours.
    vertex_colours: Option<[ColourScale; 3]>,
    /// Scales of the face colour channels, when faces have colours.
    face_colours: Option<[ColourScale; 3]>,
    /// The vertices have an `alpha` (ignored).
    alpha: bool,
}

/// Uv property pairs, in the order they are looked for.
const UV_NAMES: [[&str; 2]; 4] = [
    ["u", "v"],
    ["s", "t"],
    ["texture_u", "texture_v"],
    ["texture_s", "texture_t"],
];

/// Colour property triples, in the order they are looked for.
const COLOUR_NAMES: [[&str; 3]; 2] = [
    ["red", "green", "blue"],
    ["diffuse_red", "diffuse_green", "diffuse_blue"],
];

/// The first colour triple `el` has: its properties and channel scales.
fn colours(path: &Path, el: &Element) -> Result<Option<([usize; 3], [ColourScale; 3])>> {
    for names in COLOUR_NAMES {
        if let Some(found) = el.scalars(path, names)? {
            return Ok(Some((
                found.map(|f| f.0),
                found.map(|f| ColourScale::of(f.1)),
            )));
        }
    }
    Ok(None)
}

/// Maps the header's elements and properties to the mesh.
fn layout(path: &Path, header: &Header) -> Result<Layout> {
    let mut layout = Layout {
        kinds: Vec::new(),
        slots: Vec::new(),
        vertex_count: 0,
        normals: false,
        uvs: false,
        vertex_colours: None,
        face_colours: None,
        alpha: false,
    };
    for el in &header.elements {
        let kind = match el.name.as_str() {
            "vertex" => Kind::Vertex,
            "face" => Kind::Faces,
            "tristrips" => Kind::Strips,
            _ => Kind::Other,
        };
        if kind != Kind::Other && layout.kinds.contains(&kind) {
            return Err(Error::file(
                path,
                Some(el.line),
                format!("a second `{}` element", el.name),
            ));
        }
        let mut slots = vec![Slot::Skip; el.properties.len()];
        match kind {
            Kind::Vertex => vertex_slots(path, el, &mut slots, &mut layout)?,
            Kind::Faces | Kind::Strips => {
                let list = ["vertex_indices", "vertex_index"]
                    .iter()
                    .find_map(|n| el.properties.iter().position(|p| p.name == *n));
                let Some(list) = list else {
                    return Err(Error::file(
                        path,
                        Some(el.line),
                        format!("`{}` has no `vertex_indices` list", el.name),
                    ));
                };
                let p = &el.properties[list];
                match p.kind {
                    PropertyKind::List { item, .. } if item.is_integer() => {}
                    _ => {
                        return Err(Error::file(
                            path,
                            Some(p.line),
                            format!("`{}` must be a list of integers", p.name),
                        ))
                    }
                }
                slots[list] = match kind {
                    Kind::Faces => Slot::Corner,
                    _ => Slot::StripCorner,
                };
                if kind == Kind::Faces {
                    if let Some((found, scales)) = colours(path, el)? {
                        for (c, i) in found.into_iter().enumerate() {
                            slots[i] = Slot::FaceColour(c);
                        }
                        layout.face_colours = Some(scales);
                    }
                }
            }
            Kind::Other => {}
        }
        layout.kinds.push(kind);
        layout.slots.push(slots);
    }
    if !layout.kinds.contains(&Kind::Vertex) {
        return Err(Error::file(
            path,
            Some(header.end_line),
            "no `vertex` element in the header",
        ));
    }
    Ok(layout)
}

/// Maps the `vertex` element's properties into `slots`.
fn vertex_slots(path: &Path, el: &Element, slots: &mut [Slot], layout: &mut Layout) -> Result<()> {
    layout.vertex_count = u32::try_from(el.count).map_err(|_| {
        Error::file(
            path,
            Some(el.line),
            format!("{} vertices: more than 2^32 - 1", el.count),
        )
    })?;
    let Some(xyz) = el.scalars(path, ["x", "y", "z"])? else {
        return Err(Error::file(
            path,
            Some(el.line),
            "`vertex` has no `x y z` properties",
        ));
    };
    for (k, (i, _)) in xyz.into_iter().enumerate() {
        slots[i] = Slot::Vertex(X + k);
    }
    if let Some(n) = el.scalars(path, ["nx", "ny", "nz"])? {
        for (k, (i, _)) in n.into_iter().enumerate() {
            slots[i] = Slot::Vertex(NX + k);
        }
        layout.normals = true;
    }
    for names in UV_NAMES {
        if let Some(uv) = el.scalars(path, names)? {
            for (k, (i, _)) in uv.into_iter().enumerate() {
                slots[i] = Slot::Vertex(U + k);
            }
            layout.uvs = true;
            break;
        }
    }
    if let Some((found, scales)) = colours(path, el)? {
        for (c, i) in found.into_iter().enumerate() {
            slots[i] = Slot::Vertex(RED + c);
        }
        layout.vertex_colours = Some(scales);
    }
    layout.alpha = el.scalar(path, "alpha")?.is_some();
    Ok(())
}

/// Refuses counts the data cannot hold or memory cannot take, before
/// anything is reserved from them.
fn check_sizes(path: &Path, header: &Header, layout: &Layout, data_bytes: usize) -> Result<()> {
    // An ASCII file's last value needs no separator after it.
    let slack = u64::from(header.format == Format::Ascii);
    let available = data_bytes as u64 + slack;
    let per_vertex = 12
        + 12 * u64::from(layout.normals)
        + 8 * u64::from(layout.uvs)
        + 12 * u64::from(layout.vertex_colours.is_some());
    let budget = crate::allocator::memory_budget();
    let (mut data_need, mut memory_need) = (0u64, 0u64);
    for (el, kind) in header.elements.iter().zip(&layout.kinds) {
        let min = el.min_record_bytes(header.format);
        data_need = data_need.saturating_add(el.count.saturating_mul(min));
        if data_need > available {
            return Err(Error::file(
                path,
                Some(el.line),
                format!(
                    "`element {} {}` cannot be in this file: its records take at least {min} \
                     bytes each, and the data after the header has {data_bytes} bytes \
                     (is the file truncated, or the count wrong?)",
                    el.name, el.count
                ),
            ));
        }
        // Vertex arrays are reserved in full, a triangle per face.
        memory_need = memory_need.saturating_add(el.count.saturating_mul(match kind {
            Kind::Vertex => per_vertex,
            Kind::Faces => 16,
            _ => 0,
        }));
        if let Some(have) = budget.filter(|&have| memory_need > have) {
            let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
            return Err(Error::file(
                path,
                Some(el.line),
                format!(
                    "`element {} {}` needs about {:.1} GiB of memory to load, more than \
                     the {:.1} GiB available",
                    el.name,
                    el.count,
                    gib(memory_need),
                    gib(have)
                ),
            ));
        }
    }
    Ok(())
}

/// Why a value could not be read when the data ends.
const ENDS: &str = "the file ends here (truncated?)";

/// The data after the header, read value by value.
struct Data<'a> {
    bytes: &'a [u8],
    pos: usize,
    format: Format,
}

impl Data<'_> {
    /// The next value, of type `ty`; `Err` says why not.
    fn value(&mut self, ty: Scalar) -> std::result::Result<f64, String> {
        match self.format {
            Format::Ascii => self.ascii(ty),
            Format::BinaryLittleEndian => self.binary(ty, false),
            Format::BinaryBigEndian => self.binary(ty, true),
        }
    }

    /// The next `N` bytes.
    fn take<const N: usize>(&mut self) -> std::result::Result<[u8; N], String> {
        let bytes = (self.bytes.get(self.pos..))
            .and_then(|b| b.first_chunk::<N>())
            .ok_or(ENDS)?;
        self.pos += N;
        Ok(*bytes)
    }

    fn binary(&mut self, ty: Scalar, big_endian: bool) -> std::result::Result<f64, String> {
        macro_rules! read {
            ($t:ty) => {{
                let b = self.take::<{ std::mem::size_of::<$t>() }>()?;
                f64::from(match big_endian {
                    true => <$t>::from_be_bytes(b),
                    false => <$t>::from_le_bytes(b),
                })
            }};
        }
        Ok(match ty {
            Scalar::I8 => read!(i8),
            Scalar::U8 => read!(u8),
            Scalar::I16 => read!(i16),
            Scalar::U16 => read!(u16),
            Scalar::I32 => read!(i32),
            Scalar::U32 => read!(u32),
            Scalar::F32 => read!(f32),
            Scalar::F64 => read!(f64),
        })
    }

    fn ascii(&mut self, ty: Scalar) -> std::result::Result<f64, String> {
        let bytes = self.bytes;
        let rest = bytes.get(self.pos..).unwrap_or_default();
        let Some(start) = rest.iter().position(|b| !b.is_ascii_whitespace()) else {
            // Errors point at the end.
            self.pos = bytes.len();
            return Err(ENDS.into());
        };
        let rest = &rest[start..];
        let len = (rest.iter().position(u8::is_ascii_whitespace)).unwrap_or(rest.len());
        let token = &rest[..len];
        // Errors point at the token.
        self.pos += start;
        let text = std::str::from_utf8(token).ok();
        let value = match ty {
            _ if ty.is_integer() => match text.and_then(|t| t.parse::<i64>().ok()) {
                Some(v) if (ty.range().0..=ty.range().1).contains(&v) => Some(v as f64),
                Some(v) => return Err(format!("`{v}` is out of range for {}", ty.name())),
                None => None,
            },
            // Parsed as written, so that a float reads as in a binary file.
            Scalar::F32 => text.and_then(|t| t.parse::<f32>().ok()).map(f64::from),
            _ => text.and_then(|t| t.parse::<f64>().ok()),
        };
        let value = value.ok_or_else(|| {
            let t = String::from_utf8_lossy(token);
            format!("malformed {} `{}`", ty.name(), shown(&t))
        })?;
        self.pos += len;
        Ok(value)
    }

    /// A list's length, refused when negative or when that many values
    /// cannot fit in the rest of the file.
    fn list_len(&mut self, count: Scalar, item: Scalar) -> std::result::Result<u64, String> {
        let n = self.value(count)?;
        if n < 0.0 {
            return Err(format!("negative list length {n}"));
        }
        let n = n as u64;
        let left = (self.bytes.len() - self.pos) as u64;
        let need = match self.format {
            Format::Ascii => n.saturating_mul(2).saturating_sub(1),
            _ => n.saturating_mul(item.size()),
        };
        if need > left {
            return Err(format!(
                "a list of {n} values cannot fit in the {left} bytes left in the file"
            ));
        }
        Ok(n)
    }

    /// The 1-based line of the current position (ASCII files).
    fn line(&self) -> usize {
        let end = self.pos.min(self.bytes.len());
        self.bytes[..end].iter().filter(|&&b| b == b'\n').count() + 1
    }
}

/// Reads every record of `el`, its values going to `slots` of `mesh`
/// (`kind` says what a record's end means); an error comes with the
/// record's index.
fn read_element(
    data: &mut Data,
    el: &Element,
    slots: &[Slot],
    kind: Kind,
    mesh: &mut Builder,
) -> std::result::Result<(), (u64, String)> {
    let skipped = slots.iter().all(|&s| s == Slot::Skip);
    let scalars_only = el
        .properties
        .iter()
        .all(|p| matches!(p.kind, PropertyKind::Scalar(_)));
    if el.properties.is_empty() {
        return Ok(());
    }
    if skipped && scalars_only && data.format != Format::Ascii {
        // Fixed-size records: skipped at once (the count was checked).
        let size = el.min_record_bytes(data.format);
        let left = (data.bytes.len() - data.pos) as u64;
        if el.count.saturating_mul(size) > left {
            return Err((left / size, ENDS.into()));
        }
        data.pos += (el.count * size) as usize;
        return Ok(());
    }
    for i in 0..el.count {
        let at = |why: String| (i, why);
        mesh.begin_record();
        for (p, &slot) in el.properties.iter().zip(slots) {
            match p.kind {
                PropertyKind::Scalar(ty) => {
                    let v = data.value(ty).map_err(at)?;
                    mesh.scalar(slot, v);
                }
                PropertyKind::List { count, item } => {
                    let n = data.list_len(count, item).map_err(at)?;
                    for _ in 0..n {
                        let v = data.value(item).map_err(at)?;
                        mesh.list_item(slot, v).map_err(at)?;
                    }
                }
            }
        }
        mesh.end_record(kind).map_err(at)?;
    }
    Ok(())
}

/// The face (or strip) being read.
#[derive(Debug, Default)]
struct Face {
    /// Corners so far (since the last restart, in a strip).
    corners: u64,
    /// The fan's first corner; in a strip, the corner two back.
    a: u32,
    /// The previous corner.
    b: u32,
    /// Sum of the corners' linear vertex colours.
    colour_sum: Vec3,
    /// The face's own colour channels, as read.
    colour: [f64; 3],
}

/// The mesh as it is read.
struct Builder<'a> {
    assets: &'a mut Assets,
    material_override: Option<u32>,
    vertex_count: u32,
    vertex_colours: Option<[ColourScale; 3]>,
    face_colours: Option<[ColourScale; 3]>,
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    /// Linear vertex colours.
    colours: Option<Vec<Vec3>>,
    triangles: Vec<[u32; 3]>,
    material_ids: Vec<u32>,
    /// The vertex being read.
    record: [f64; FIELDS],
    face: Face,
    /// Faces with fewer than 3 corners, skipped.
    short_faces: u64,
    /// sRGB byte to linear, as for 8-bit colour textures.
    srgb: [f32; 256],
    /// The material of each quantized face colour.
    colour_materials: HashMap<[u8; 3], u32>,
}

impl<'a> Builder<'a> {
    /// An empty mesh, its vertex arrays reserved (the counts are checked).
    fn new(
        layout: &Layout,
        face_count: u64,
        material_override: Option<u32>,
        assets: &'a mut Assets,
    ) -> Self {
        let n = layout.vertex_count as usize;
        fn reserve<T>(yes: bool, n: usize) -> Option<Vec<T>> {
            yes.then(|| Vec::with_capacity(n))
        }
        Builder {
            assets,
            material_override,
            vertex_count: layout.vertex_count,
            vertex_colours: layout.vertex_colours,
            face_colours: layout.face_colours,
            positions: Vec::with_capacity(n),
            normals: reserve(layout.normals, n),
            uvs: reserve(layout.uvs, n),
            colours: reserve(layout.vertex_colours.is_some(), n),
            triangles: Vec::with_capacity(face_count as usize),
            material_ids: Vec::with_capacity(face_count as usize),
            record: [0.0; FIELDS],
            face: Face::default(),
            short_faces: 0,
            srgb: std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)),
            colour_materials: HashMap::new(),
        }
    }

    fn begin_record(&mut self) {
        self.face = Face::default();
    }

    fn scalar(&mut self, slot: Slot, v: f64) {
        match slot {
            Slot::Vertex(field) => self.record[field] = v,
            Slot::FaceColour(channel) => self.face.colour[channel] = v,
            _ => {}
        }
    }

    fn list_item(&mut self, slot: Slot, v: f64) -> std::result::Result<(), String> {
        match slot {
            Slot::Corner => {
                let i = self.index(v)?;
                self.face.colour_sum += self.vertex_colour(i);
                if self.face.corners >= 2 {
                    self.triangles.push([self.face.a, self.face.b, i]);
                } else if self.face.corners == 0 {
                    self.face.a = i;
                }
                self.face.b = i;
                self.face.corners += 1;
            }
            Slot::StripCorner if v == -1.0 => self.face.corners = 0,
            Slot::StripCorner => {
                let i = self.index(v)?;
                let Face { a, b, .. } = self.face;
                if self.face.corners >= 2 {
                    // Every other triangle of a strip is wound the other way.
                    let tri = match (self.face.corners - 2) % 2 {
                        0 => [a, b, i],
                        _ => [b, a, i],
                    };
                    let colour = tri.iter().map(|&v| self.vertex_colour(v)).sum::<Vec3>() / 3.0;
                    let material = self.material(colour, self.vertex_colours.is_some())?;
                    self.triangles.push(tri);
                    self.material_ids.push(material);
                }
                self.face.a = b;
                self.face.b = i;
                self.face.corners += 1;
            }
            _ => {}
        }
        Ok(())
    }

    /// A vertex index, checked.
    fn index(&self, v: f64) -> std::result::Result<u32, String> {
        if v < 0.0 {
            return Err(format!("negative vertex index {v}"));
        }
        if v >= f64::from(self.vertex_count) {
            return Err(format!(
                "vertex index {v} is out of range (the file has {} vertices)",
                self.vertex_count
            ));
        }
        Ok(v as u32)
    }

    /// The linear colour of vertex `i` (zero without vertex colours).
    fn vertex_colour(&self, i: u32) -> Vec3 {
        (self.colours.as_ref())
            .and_then(|c| c.get(i as usize).copied())
            .unwrap_or_default()
    }

    /// Channel value `v` as a linear colour component.
    fn linear(&self, v: f64, scale: ColourScale) -> std::result::Result<f32, String> {
        if v.is_nan() {
            return Err("colour value NaN".into());
        }
        Ok(match scale {
            ColourScale::Byte => self.srgb[v.clamp(0.0, 255.0) as usize],
            ColourScale::Short => srgb_to_linear((v.clamp(0.0, 65535.0) / 65535.0) as f32),
            ColourScale::Unit => srgb_to_linear(v.clamp(0.0, 1.0) as f32),
        })
    }

    fn end_record(&mut self, kind: Kind) -> std::result::Result<(), String> {
        match kind {
            Kind::Vertex => self.end_vertex(),
            Kind::Faces => self.end_face(),
            Kind::Strips | Kind::Other => Ok(()),
        }
    }

    fn end_vertex(&mut self) -> std::result::Result<(), String> {
        let r = self.record;
        let field = |i: usize| r[i] as f32;
        let p = Vec3::new(field(X), field(X + 1), field(X + 2));
        if !p.is_finite() {
            return Err(format!(
                "position ({}, {}, {}) is not finite (as f32)",
                r[X],
                r[X + 1],
                r[X + 2]
            ));
        }
        self.positions.push(p);
        if let Some(normals) = &mut self.normals {
            // Unusable normals are replaced when the mesh is done, as for OBJ.
            normals.push(Vec3::new(field(NX), field(NX + 1), field(NX + 2)));
        }
        if let Some(uvs) = &mut self.uvs {
            let uv = Vec2::new(field(U), field(U + 1));
            if !uv.is_finite() {
                return Err(format!(
                    "texture coordinates ({}, {}) are not finite (as f32)",
                    r[U],
                    r[U + 1]
                ));
            }
            uvs.push(uv);
        }
        if let Some(scales) = self.vertex_colours {
            let mut c = Vec3::ZERO;
            for (k, scale) in scales.into_iter().enumerate() {
                c[k] = self.linear(r[RED + k], scale)?;
            }
            if let Some(colours) = &mut self.colours {
                colours.push(c);
            }
        }
        Ok(())
    }

    fn end_face(&mut self) -> std::result::Result<(), String> {
        let corners = self.face.corners;
        if corners < 3 {
            self.short_faces += 1;
            return Ok(());
        }
        let material = match self.face_colours {
            Some(scales) => {
                let mut c = Vec3::ZERO;
                for (k, scale) in scales.into_iter().enumerate() {
                    c[k] = self.linear(self.face.colour[k], scale)?;
                }
                self.material(c, true)?
            }
            None => {
                let mean = self.face.colour_sum / corners as f32;
                self.material(mean, self.vertex_colours.is_some())?
            }
        };
        self.material_ids.resize(self.triangles.len(), material);
        Ok(())
    }

    /// The material of a face of linear colour `colour` (`coloured`: the
    /// file gives one): the object's material if it has one, else one per
    /// colour, quantized to 8-bit sRGB like a colour texture's texels (so
    /// that a million faces make at most as many materials as there are
    /// distinct 8-bit colours, and a face of one vertex colour gets exactly
    /// that colour).
    fn material(&mut self, colour: Vec3, coloured: bool) -> std::result::Result<u32, String> {
        if let Some(id) = self.material_override {
            return Ok(id);
        }
        if !coloured {
            return Ok(DEFAULT_MATERIAL);
        }
        let key = colour
            .to_array()
            .map(|c| (linear_to_srgb(c) * 255.0).round() as u8);
        if let Some(&id) = self.colour_materials.get(&key) {
            return Ok(id);
        }
        let material = Material {
            name: "PLY colour".into(),
            albedo: Vec3::from(key.map(|k| self.srgb[usize::from(k)])),
            ..Material::default()
        };
        let id = self.assets.material(material).map_err(|e| e.to_string())?;
        self.colour_materials.insert(key, id);
        Ok(id)
    }
}

/// The exact sRGB encoding curve (the inverse of [`srgb_to_linear`]), for
/// values in [0, 1].
fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Reads a PLY mesh referenced from `from:line` (the scene file and line).
///
/// With `material_override` (the object's inline material) every face gets
/// it and colours are not used; otherwise a face's albedo is the mean of
/// its corners' colours (or its own colour), faces without colours get the
/// default material. Normals are kept when the vertices have them
/// (unusable ones replaced by the face's geometric normal, as for OBJ);
/// without them the geometric normal is used. Degenerate triangles are
/// left for the loader, which drops them after the transform.
pub(super) fn load_ply(
    path: &Path,
    from: &Path,
    line: usize,
    material_override: Option<u32>,
    assets: &mut Assets,
) -> Result<Mesh> {
    let bytes = super::input::read(path).map_err(|e| {
        Error::file(
            from,
            Some(line),
            format!("cannot read PLY `{}`: {e}", path.display()),
        )
    })?;
    parse_ply(path, &bytes, from, line, material_override, assets)
}

/// [`load_ply`] on the file's bytes.
fn parse_ply(
    path: &Path,
    bytes: &[u8],
    from: &Path,
    line: usize,
    material_override: Option<u32>,
    assets: &mut Assets,
) -> Result<Mesh> {
    let header = parse_header(path, bytes)?;
    let layout = layout(path, &header)?;
    check_sizes(path, &header, &layout, bytes.len() - header.data_start)?;
    let face_count = (header.elements.iter().zip(&layout.kinds))
        .filter(|(_, kind)| **kind == Kind::Faces)
        .map(|(el, _)| el.count)
        .sum::<u64>();
    let mut mesh = Builder::new(&layout, face_count, material_override, assets);
    let mut data = Data {
        bytes,
        pos: header.data_start,
        format: header.format,
    };
    // Faces before the vertices are read after them (their colours).
    let mut later = Vec::new();
    let mut have_vertices = false;
    for (e, el) in header.elements.iter().enumerate() {
        let (mut kind, mut slots) = (layout.kinds[e], layout.slots[e].clone());
        if matches!(kind, Kind::Faces | Kind::Strips) && !have_vertices {
            later.push((e, data.pos));
            kind = Kind::Other;
            slots.fill(Slot::Skip);
        }
        read_element(&mut data, el, &slots, kind, &mut mesh)
            .map_err(|(i, why)| data_error(path, &data, el, i, &why))?;
        have_vertices |= kind == Kind::Vertex;
    }
    for (e, pos) in later {
        let el = &header.elements[e];
        data.pos = pos;
        read_element(&mut data, el, &layout.slots[e], layout.kinds[e], &mut mesh)
            .map_err(|(i, why)| data_error(path, &data, el, i, &why))?;
    }
    finish(path, from, line, mesh, layout.alpha)
}

/// The error for record `i` of `el`: at its line in an ASCII file, with
/// the byte offset in a binary one.
fn data_error(path: &Path, data: &Data, el: &Element, i: u64, why: &str) -> Error {
    match data.format {
        Format::Ascii => Error::file(path, Some(data.line()), format!("`{}` {i}: {why}", el.name)),
        _ => Error::file(
            path,
            None,
            format!("`{}` {i} (byte {}): {why}", el.name, data.pos),
        ),
    }
}

/// The mesh as loaded: refused without faces; warnings for what was
/// skipped or changed.
fn finish(path: &Path, from: &Path, line: usize, b: Builder, alpha: bool) -> Result<Mesh> {
    let at = path.display();
    if b.triangles.is_empty() {
        return Err(Error::file(
            from,
            Some(line),
            format!("PLY `{at}` has no faces: nothing to render (points are not surfaces)"),
        ));
    }
    if b.short_faces > 0 {
        eprintln!(
            "warning: {at}: {} face(s) with fewer than 3 vertices skipped",
            b.short_faces
        );
    }
    let coloured = b.vertex_colours.is_some() || b.face_colours.is_some();
    let alpha_note = if alpha { "; `alpha` is ignored" } else { "" };
    match (coloured, b.material_override) {
        (true, Some(_)) => eprintln!(
            "warning: {at}: colours not used: the object's material applies to every \
             face{alpha_note}"
        ),
        (true, None) => eprintln!(
            "warning: {at}: the renderer has no per-vertex colour: each face's albedo is \
             the mean of its corners' colours (sRGB decoded, to 8-bit steps){alpha_note}"
        ),
        (false, _) if alpha => eprintln!("warning: {at}: `alpha` is ignored"),
        _ => {}
    }
    let textured = (b.material_override)
        .and_then(|id| b.assets.materials.get(id as usize))
        .is_some_and(|m| m.albedo_texture.is_some() || m.opacity_texture.is_some());
    let mut uvs = b.uvs;
    if textured && uvs.is_none() {
        eprintln!(
            "warning: {at}: textured material on a mesh without texture coordinates; \
             using uv (0, 0)"
        );
        uvs = Some(vec![Vec2::ZERO; b.positions.len()]);
    }
    let mut mesh = Mesh {
        positions: b.positions,
        normals: b.normals,
        uvs,
        triangles: b.triangles,
        material_ids: b.material_ids,
    };
    let corners = super::obj::replace_unusable_normals(&mut mesh);
    if corners > 0 {
        eprintln!(
            "warning: {at}: zero or non-finite normals; the {corners} triangle corner(s) \
             using them take their face's geometric normal"
        );
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A value of a test file, written as its type.
    #[derive(Debug, Clone, Copy)]
    enum V {
        F(f32),
        D(f64),
        B(u8),
        C(i8),
        I(i32),
        U(u32),
    }

    /// A property's value in a record: a scalar, or a list (its count as
    /// uchar unless given).
    enum P {
        S(V),
        L(Vec<V>),
        Counted(V, Vec<V>),
    }
    use P::{Counted, L, S};

    const FORMATS: [&str; 3] = ["ascii", "binary_little_endian", "binary_big_endian"];

    fn put(out: &mut Vec<u8>, v: V, format: &str) {
        let (le, be, text): (Vec<u8>, Vec<u8>, String) = match v {
            V::F(x) => (
                x.to_le_bytes().into(),
                x.to_be_bytes().into(),
                x.to_string(),
            ),
            V::D(x) => (
                x.to_le_bytes().into(),
                x.to_be_bytes().into(),
                x.to_string(),
            ),
            V::B(x) => (vec![x], vec![x], x.to_string()),
            V::C(x) => (
                x.to_le_bytes().into(),
                x.to_be_bytes().into(),
                x.to_string(),
            ),
            V::I(x) => (
                x.to_le_bytes().into(),
                x.to_be_bytes().into(),
                x.to_string(),
            ),
            V::U(x) => (
                x.to_le_bytes().into(),
                x.to_be_bytes().into(),
                x.to_string(),
            ),
        };
        match format {
            "ascii" => {
                out.extend(text.bytes());
                out.push(b' ');
            }
            "binary_little_endian" => out.extend(le),
            _ => out.extend(be),
        }
    }

    /// A PLY file: `header` (the lines after `format`) and the records of
    /// its elements, in order, written in `format`.
    fn file(format: &str, header: &str, records: &[Vec<P>]) -> Vec<u8> {
        let mut out = format!("ply\nformat {format} 1.0\n{header}end_header\n").into_bytes();
        for record in records {
            for p in record {
                match p {
                    S(v) => put(&mut out, *v, format),
                    L(items) | Counted(_, items) => {
                        let count = match p {
                            Counted(c, _) => *c,
                            _ => V::B(items.len() as u8),
                        };
                        put(&mut out, count, format);
                        items.iter().for_each(|&v| put(&mut out, v, format));
                    }
                }
            }
            if format == "ascii" {
                out.push(b'\n');
            }
        }
        out
    }

    fn load_with(bytes: &[u8], material: Option<u32>) -> Result<(Mesh, Assets)> {
        let mut assets = Assets::new();
        let path = Path::new("t.ply");
        let mesh = parse_ply(
            path,
            bytes,
            Path::new("scene.toml"),
            7,
            material,
            &mut assets,
        )?;
        Ok((mesh, assets))
    }

    fn load(bytes: &[u8]) -> Mesh {
        match load_with(bytes, None) {
            Ok((mesh, _)) => mesh,
            Err(e) => panic!("{e}"),
        }
    }

    fn error(bytes: &[u8]) -> String {
        match load_with(bytes, None) {
            Ok(_) => panic!("loaded: {}", String::from_utf8_lossy(bytes)),
            Err(e) => e.to_string(),
        }
    }

    fn assert_same(a: &Mesh, b: &Mesh) {
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.normals, b.normals);
        assert_eq!(a.uvs, b.uvs);
        assert_eq!(a.triangles, b.triangles);
        assert_eq!(a.material_ids, b.material_ids);
    }

    /// Vertex records `x y 0`.
    fn xy_vertices(xy: &[[f32; 2]]) -> Vec<Vec<P>> {
        xy.iter()
            .map(|&[x, y]| vec![S(V::F(x)), S(V::F(y)), S(V::F(0.0))])
            .collect()
    }

    const XYZ: &str = "property float x\nproperty float y\nproperty float z\n";

    /// A file with extra elements and properties around a quad and a
    /// triangle with normals, uvs and colours.
    fn rich(format: &str) -> Vec<u8> {
        let header = "comment written by hand\nobj_info for the tests\n\
            element material 1\nproperty float shine\nproperty list uchar float stuff\n\
            element vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
            property float nx\nproperty float ny\nproperty float nz\n\
            property double confidence\nproperty float s\nproperty float t\n\
            property uchar red\nproperty uchar green\nproperty uchar blue\n\
            property list uchar int extra\n\
            element face 2\nproperty list uchar int vertex_indices\nproperty int flags\n\
            element edge 1\nproperty int vertex1\nproperty int vertex2\n";
        let mut records = vec![vec![S(V::F(0.5)), L(vec![V::F(1.0), V::F(2.0)])]];
        let xy = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [2.0, 0.5]];
        for (i, [x, y]) in xy.into_iter().enumerate() {
            let c = [255, 0, 0, 0, 255][i];
            records.push(vec![
                S(V::F(x)),
                S(V::F(y)),
                S(V::F(0.0)),
                S(V::F(0.0)),
                S(V::F(0.0)),
                S(V::F(1.0)),
                S(V::D(0.25)),
                S(V::F(x / 2.0)),
                S(V::F(y)),
                S(V::B(c)),
                S(V::B(c)),
                S(V::B(255)),
                L(vec![V::I(7); i % 2]),
            ]);
        }
        let ints = |i: &[i32]| L(i.iter().map(|&i| V::I(i)).collect());
        records.push(vec![ints(&[0, 1, 2, 3]), S(V::I(0))]);
        records.push(vec![ints(&[1, 4, 2]), S(V::I(1))]);
        records.push(vec![S(V::I(0)), S(V::I(1))]);
        file(format, header, &records)
    }

    #[test]
    fn ascii_and_binary_give_the_same_mesh() {
        let meshes = FORMATS.map(|f| load(&rich(f)));
        let m = &meshes[0];
        let xy = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [2.0, 0.5]];
        let positions: Vec<Vec3> = xy.iter().map(|&[x, y]| Vec3::new(x, y, 0.0)).collect();
        assert_eq!(m.positions, positions);
        assert_eq!(m.triangles, [[0, 1, 2], [0, 2, 3], [1, 4, 2]]);
        assert_eq!(m.normals, Some(vec![Vec3::Z; 5]));
        let uvs = xy.iter().map(|&[x, y]| Vec2::new(x / 2.0, y)).collect();
        assert_eq!(m.uvs, Some(uvs));
        assert_eq!(m.material_ids.len(), 3);
        assert_eq!(
            m.material_ids[0], m.material_ids[1],
            "one material per face"
        );
        for other in &meshes[1..] {
            assert_same(m, other);
        }
    }

    #[test]
    fn polygons_are_fans_and_short_faces_are_skipped() {
        let header = format!(
            "element vertex 5\n{XYZ}element face 4\nproperty list uchar uint vertex_index\n"
        );
        let mut records =
            xy_vertices(&[[0.0, 0.0], [1.0, 0.0], [2.0, 1.0], [1.0, 2.0], [0.0, 1.0]]);
        for face in [&[0, 1, 2, 3][..], &[0, 1, 2, 3, 4], &[0, 1], &[]] {
            records.push(vec![L(face.iter().map(|&i| V::U(i)).collect())]);
        }
        for format in FORMATS {
            let m = load(&file(format, &header, &records));
            assert_eq!(
                m.triangles,
                [[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3], [0, 3, 4]]
            );
            assert_eq!(m.material_ids, [DEFAULT_MATERIAL; 5]);
            assert!(m.normals.is_none() && m.uvs.is_none());
        }
    }

    #[test]
    fn strips_restart_and_alternate_winding() {
        let header = format!(
            "element tristrips 1\nproperty list char int vertex_indices\n\
             element vertex 7\n{XYZ}"
        );
        let strip = [0, 1, 2, 3, -1, 4, 5, 6].map(V::I).to_vec();
        let mut records = vec![vec![Counted(V::C(strip.len() as i8), strip)]];
        records.extend(xy_vertices(&[[0.0, 0.0]; 7]));
        for format in FORMATS {
            let m = load(&file(format, &header, &records));
            assert_eq!(m.triangles, [[0, 1, 2], [2, 1, 3], [4, 5, 6]]);
            assert_eq!(m.material_ids, [DEFAULT_MATERIAL; 3]);
        }
    }

    #[test]
    fn vertex_colours_become_linear_face_albedo() {
        // Faces before vertices: colours are still the vertices'.
        let header = format!(
            "element face 3\nproperty list uchar int vertex_indices\n\
             element vertex 5\n{XYZ}property uchar red\nproperty uchar green\n\
             property uchar blue\nproperty uchar alpha\n"
        );
        let ints = |i: &[i32]| vec![L(i.iter().map(|&i| V::I(i)).collect())];
        let mut records = vec![ints(&[0, 1, 2]), ints(&[1, 2, 0]), ints(&[0, 3, 4])];
        let colours = [
            [255, 128, 0],
            [255, 128, 0],
            [255, 128, 0],
            [0; 3],
            [255; 3],
        ];
        for (i, c) in colours.into_iter().enumerate() {
            let mut r = vec![S(V::F(i as f32)), S(V::F(0.0)), S(V::F(0.0))];
            r.extend(c.map(|c| S(V::B(c))));
            r.push(S(V::B(9)));
            records.push(r);
        }
        for format in FORMATS {
            let (m, assets) = load_with(&file(format, &header, &records), None).unwrap();
            let albedo = |t: usize| assets.materials[m.material_ids[t] as usize].albedo;
            // One colour: exactly its decoded value, as a texture texel.
            let linear = |c: u8| srgb_to_linear(f32::from(c) / 255.0);
            assert_eq!(albedo(0), Vec3::new(1.0, linear(128), 0.0));
            assert_eq!(
                m.material_ids[0], m.material_ids[1],
                "a colour shares one material"
            );
            // Mixed: the mean of the linear colours, to an 8-bit sRGB step.
            let mean = (Vec3::new(1.0, linear(128), 0.0) + Vec3::ONE) / 3.0;
            assert!(
                (albedo(2) - mean).abs().max_element() < 0.01,
                "{}",
                albedo(2)
            );
            assert_eq!(assets.materials.len(), 3);
        }
        // An inline material wins over the colours.
        let (m, _) = load_with(&file("ascii", &header, &records), Some(5)).unwrap();
        assert_eq!(m.material_ids, [5; 3]);
    }

    #[test]
    fn float_and_face_colours() {
        let header = format!(
            "element vertex 3\n{XYZ}property float red\nproperty float green\n\
             property float blue\nelement face 1\nproperty list uchar int vertex_indices\n\
             property uchar red\nproperty uchar green\nproperty uchar blue\n"
        );
        let mut records: Vec<Vec<P>> = (0..3)
            .map(|i| {
                let mut r = vec![S(V::F(i as f32)), S(V::F((i % 2) as f32)), S(V::F(0.0))];
                r.extend([1.0, 0.5, 2.0].map(|c| S(V::F(c))));
                r
            })
            .collect();
        let corners = L(vec![V::I(0), V::I(1), V::I(2)]);
        records.push(vec![corners, S(V::B(0)), S(V::B(255)), S(V::B(0))]);
        let (m, assets) = load_with(&file("binary_big_endian", &header, &records), None).unwrap();
        // The face's own colour wins over its vertices'.
        assert_eq!(assets.materials[m.material_ids[0] as usize].albedo, Vec3::Y);
        // Without it, float vertex colours (clamped to [0, 1]).
        let header = header.replace(
            "property uchar red\nproperty uchar green\nproperty uchar blue\n",
            "",
        );
        records[3].truncate(1);
        let (m, assets) = load_with(&file("ascii", &header, &records), None).unwrap();
        let expected = Vec3::new(1.0, srgb_to_linear(0.5), 1.0);
        let albedo = assets.materials[m.material_ids[0] as usize].albedo;
        assert!((albedo - expected).abs().max_element() < 0.005, "{albedo}");
    }

    #[test]
    fn byte_order_mark_and_crlf_header() {
        let text = "\u{feff}ply\r\nformat ascii 1.0\r\ncomment x\r\nelement vertex 3\r\n\
            property float32 x\r\nproperty float32 y\r\nproperty float32 z\r\n\
            element face 1\r\nproperty list uint8 int32 vertex_indices\r\nend_header\r\n\
            0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2\r\n";
        let m = load(text.as_bytes());
        assert_eq!(m.triangles, [[0, 1, 2]]);
        assert_eq!(m.positions[1], Vec3::X);
    }

    /// A triangle in ASCII with `face` written as given.
    fn ascii_triangle(face: &str) -> Vec<u8> {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\n{XYZ}element face 2\n\
             property list uchar int vertex_indices\nend_header\n\
             0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n{face}\n"
        )
        .into_bytes()
    }

    #[test]
    fn header_errors_name_the_line() {
        let cases = [
            ("solid cube\n", "t.ply:1: not a PLY file"),
            ("", "t.ply:1: empty file"),
            ("ply\nformat binary_middle_endian 1.0\n", "t.ply:2: unknown PLY format"),
            ("ply\nformat ascii 2.0\n", "t.ply:2: PLY version `2.0`"),
            ("ply\nformat ascii 1.0\nproperty float x\n", "t.ply:3: `property` before any"),
            ("ply\nformat ascii 1.0\nelement v 1\nproperty float3 x\n", "t.ply:4: unknown property type `float3`"),
            ("ply\nformat ascii 1.0\nelement v -1\n", "t.ply:3: malformed element count `-1`"),
            ("ply\nformat ascii 1.0\nelement v 1\nproperty list float int i\n", "t.ply:4: a list's count must have an integer type"),
            ("ply\nformat ascii 1.0\nelement vertex 1\n", "t.ply:3: the header has no `end_header`"),
            ("ply\nelement vertex 0\nend_header\n", "t.ply:3: no `format` line"),
            ("ply\nformat ascii 1.0\nvertices 3\n", "t.ply:3: malformed header line `vertices 3`"),
            ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nend_header\n", "t.ply:3: `vertex` has no `x y z`"),
            ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float y\nproperty float z\nend_header\n", "t.ply:3: `vertex` has some of the properties `x y z`"),
            ("ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar float x\nend_header\n", "t.ply:4: `vertex` `x` must be a scalar"),
            ("ply\nformat ascii 1.0\nelement face 1\nproperty list uchar float vertex_indices\nend_header\n", "t.ply:4: `vertex_indices` must be a list of integers"),
            ("ply\nformat ascii 1.0\nelement face 1\nproperty int flags\nend_header\n", "t.ply:3: `face` has no `vertex_indices` list"),
            ("ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n", "t.ply:5: no `vertex` element"),
        ];
        for (text, expected) in cases {
            let e = error(text.as_bytes());
            assert!(
                e.starts_with(expected),
                "{e:?} should start with {expected:?}"
            );
        }
    }

    #[test]
    fn counts_the_file_cannot_hold_are_refused_before_reading() {
        let header = format!("element vertex 4000000000\n{XYZ}");
        let records = xy_vertices(&[[0.0, 0.0]; 3]);
        for format in FORMATS {
            let e = error(&file(format, &header, &records));
            assert!(
                e.starts_with("t.ply:3: `element vertex 4000000000` cannot be in this file"),
                "{e}"
            );
        }
        let header = format!("element vertex 3\n{XYZ}element face 50000000000\nproperty list uchar int vertex_indices\n");
        let e = error(&file("binary_little_endian", &header, &records));
        assert!(
            e.starts_with("t.ply:7: `element face 50000000000` cannot be in this file"),
            "{e}"
        );
    }

    #[test]
    fn data_errors_name_the_element_and_index() {
        // Face 1 is on line 14.
        let cases = [
            (
                "3 0 1 99",
                "t.ply:14: `face` 1: vertex index 99 is out of range (the file has 3 vertices)",
            ),
            ("3 0 -1 2", "t.ply:14: `face` 1: negative vertex index -1"),
            ("3 0 1 x", "t.ply:14: `face` 1: malformed int `x`"),
            (
                "300 0 1 2",
                "t.ply:14: `face` 1: `300` is out of range for uchar",
            ),
            (
                "200 0 1 2",
                "t.ply:14: `face` 1: a list of 200 values cannot fit in the 7 bytes",
            ),
            (
                "3 0 1",
                "t.ply:15: `face` 1: the file ends here (truncated?)",
            ),
        ];
        for (face, expected) in cases {
            let e = error(&ascii_triangle(face));
            assert!(
                e.starts_with(expected),
                "{e:?} should start with {expected:?}"
            );
        }
        let text = String::from_utf8(ascii_triangle("3 0 1 2")).unwrap();
        let e = error(text.replacen("\n1 0 0\n", "\ninf 0 0\n", 1).as_bytes());
        let expected = "t.ply:11: `vertex` 1: position (inf, 0, 0) is not finite";
        assert!(e.starts_with(expected), "{e}");
        let e = error(text.replacen("\n1 0 0\n", "\n1 0 1e39\n", 1).as_bytes());
        // Beyond f32: infinite.
        let expected = "t.ply:11: `vertex` 1: position (1, 0, inf) is not finite";
        assert!(e.starts_with(expected), "{e}");
    }

    #[test]
    fn binary_data_errors_name_the_element_index_and_byte() {
        let header = format!(
            "element vertex 3\n{XYZ}element face 2\nproperty list int int vertex_indices\n"
        );
        let vertices = xy_vertices(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        let with_face = |count: i32, items: &[i32]| {
            let mut records = xy_vertices(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
            records.push(vec![Counted(V::I(3), vec![V::I(0), V::I(1), V::I(2)])]);
            records.push(vec![Counted(
                V::I(count),
                items.iter().map(|&i| V::I(i)).collect(),
            )]);
            records
        };
        let data = |records: &[Vec<P>]| file("binary_little_endian", &header, records);
        let start = data(&vertices).len();
        let face1 = start + 16;
        let cases = [
            (
                with_face(3, &[0, 1, 3]),
                format!(
                    "`face` 1 (byte {}): vertex index 3 is out of range (the file has 3 vertices)",
                    face1 + 16
                ),
            ),
            (
                with_face(-1, &[]),
                format!("`face` 1 (byte {}): negative list length -1", face1 + 4),
            ),
            (
                with_face(1 << 30, &[0, 1, 2]),
                format!(
                    "`face` 1 (byte {}): a list of 1073741824 values cannot fit in the 12 bytes",
                    face1 + 4
                ),
            ),
        ];
        for (records, expected) in cases {
            let e = error(&data(&records));
            assert!(
                e.starts_with(&format!("t.ply: {expected}")),
                "{e:?} should start with {expected:?}"
            );
        }
        // NaN coordinates, in either byte order.
        let mut records = with_face(3, &[0, 1, 2]);
        records[1][1] = S(V::F(f32::NAN));
        for format in &FORMATS[1..] {
            let e = error(&file(format, &header, &records));
            assert!(e.starts_with("t.ply: `vertex` 1 (byte"), "{e}");
            assert!(e.contains("position (1, NaN, 0) is not finite"), "{e}");
        }
        // Truncated in the last element of the rich file.
        let bytes = rich("binary_little_endian");
        let e = error(&bytes[..bytes.len() - 2]);
        assert!(e.starts_with("t.ply: `edge` 0 (byte"), "{e}");
        assert!(e.ends_with("the file ends here (truncated?)"), "{e}");
    }

    #[test]
    fn no_faces_is_an_error_at_the_reference() {
        let header = format!("element vertex 3\n{XYZ}");
        let e = error(&file("ascii", &header, &xy_vertices(&[[0.0, 0.0]; 3])));
        assert!(
            e.starts_with("scene.toml:7: PLY `t.ply` has no faces"),
            "{e}"
        );
        let mut assets = Assets::new();
        let missing = Path::new("/nonexistent/x.ply");
        let e = load_ply(missing, Path::new("scene.toml"), 3, None, &mut assets).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("scene.toml:3: cannot read PLY `/nonexistent/x.ply`"),
            "{e}"
        );
    }

    #[test]
    fn every_truncation_and_corruption_fails_cleanly() {
        for format in FORMATS {
            let bytes = rich(format);
            for end in 0..bytes.len() {
                let result = load_with(&bytes[..end], None);
                // A cut in ASCII may leave a shorter, valid number.
                assert!(
                    format == "ascii" || result.is_err(),
                    "{format} cut at {end} loaded"
                );
            }
            for at in 0..bytes.len() {
                for value in [0, 0x7f, 0x80, 0xff, b'\n', b' '] {
                    let mut corrupt = bytes.clone();
                    corrupt[at] = value;
                    let _ = load_with(&corrupt, None);
                }
            }
        }
    }

    #[test]
    fn a_colour_per_face_gets_a_material_each() {
        // 2^16 faces of distinct colours: one material each (the hashed
        // lookup in `Assets` keeps this linear; no timing is asserted).
        let n = 1 << 16;
        let header = format!(
            "element vertex {}\n{XYZ}element face {n}\nproperty list uchar uint vertex_indices\n\
             property uchar red\nproperty uchar green\nproperty uchar blue\n",
            3
        );
        let mut records = xy_vertices(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        for i in 0..n {
            let corners = L(vec![V::U(0), V::U(1), V::U(2)]);
            records.push(vec![
                corners,
                S(V::B((i >> 8) as u8)),
                S(V::B(i as u8)),
                S(V::B(0)),
            ]);
        }
        let (m, assets) =
            load_with(&file("binary_little_endian", &header, &records), None).unwrap();
        assert_eq!(assets.materials.len(), n + 1);
        assert_eq!(m.material_ids[n - 1] as usize, n);
    }
}
