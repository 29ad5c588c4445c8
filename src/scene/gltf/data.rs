//! The bytes behind a glTF file: the GLB container, buffers (the GLB
//! binary chunk, external files, `data:` URIs) and accessors.
//!
//! Read and bounds-checked here rather than by the gltf crate's `Reader`,
//! which indexes slices without checking them on some malformed accessors:
//! every range is checked against the data before it is used, and every
//! count against the bytes that back it (and the memory left) before
//! anything is allocated, so a bad file is an error naming its JSON
//! pointer, never a panic.

use crate::error::{Error, Result};
use gltf_json as json;
use json::accessor::{ComponentType, Type};
use json::validation::Checked;
use std::borrow::Cow;
use std::fmt::Display;
use std::path::{Path, PathBuf};

/// An error in the glTF file `path` at JSON pointer `pointer`.
pub(super) fn err(path: &Path, pointer: &str, msg: impl Display) -> Error {
    Error::file(path, None, format!("{pointer}: {msg}"))
}

/// The little-endian `u32` at byte `at`, if the bytes are there.
fn word(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// GLB chunk types.
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// The GLB chunk whose header is at byte `at` of `bytes`: its type, its
/// data and the byte after it.
fn chunk(bytes: &[u8], at: usize) -> std::result::Result<(u32, &[u8], usize), String> {
    let length = bytes.len();
    let (Some(len), Some(kind)) = (word(bytes, at), word(bytes, at + 4)) else {
        return Err(format!(
            "the chunk header at byte {at} runs past the end ({length} bytes)"
        ));
    };
    let start = at + 8;
    match start.checked_add(len as usize).filter(|&end| end <= length) {
        Some(end) => Ok((kind, &bytes[start..end], end)),
        None => Err(format!(
            "the chunk at byte {at} is {len} bytes long, past the end ({length} bytes)"
        )),
    }
}

/// Splits a GLB file into its JSON chunk and its binary chunk (if any);
/// chunks of other types are skipped, as the format asks.
pub(super) fn split_glb<'a>(path: &Path, bytes: &'a [u8]) -> Result<(&'a [u8], Option<&'a [u8]>)> {
    let fail = |msg: String| Error::file(path, None, format!("GLB: {msg}"));
    let (Some(version), Some(length)) = (word(bytes, 4), word(bytes, 8)) else {
        return Err(fail(format!(
            "the file ends in its 12-byte header ({} bytes)",
            bytes.len()
        )));
    };
    if version != 2 {
        return Err(fail(format!(
            "version {version}; penumbra reads GLB version 2 (glTF 2.0)"
        )));
    }
    let length = length as usize;
    let Some(bytes) = bytes.get(..length) else {
        return Err(fail(format!(
            "the header gives a length of {length} bytes but the file has {} (truncated?)",
            bytes.len()
        )));
    };
    let chunk_at = |at: usize| chunk(bytes, at).map_err(fail);
    let (kind, json, mut at) = chunk_at(12)?;
    if kind != CHUNK_JSON {
        return Err(fail(format!(
            "the first chunk has type {kind:#010x}, not JSON"
        )));
    }
    while at < length {
        let (kind, data, end) = chunk_at(at)?;
        if kind == CHUNK_BIN {
            return Ok((json, Some(data)));
        }
        at = end;
    }
    Ok((json, None))
}

/// Decodes `%XX` escapes of a URI (file names with spaces are written
/// `%20`); anything malformed is kept as written.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (bytes[i], hex) {
            (b'%', Some(b)) => {
                out.push(b);
                i += 3;
            }
            (b, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The bytes of a `data:` URI (base64 only, as glTF exporters write them).
pub(super) fn data_uri(path: &Path, pointer: &str, uri: &str) -> Result<Vec<u8>> {
    use base64::Engine;
    let rest = uri.strip_prefix("data:").unwrap_or(uri);
    let Some((header, payload)) = rest.split_once(',') else {
        return Err(err(path, pointer, "`data:` URI without a `,`"));
    };
    if !header.ends_with(";base64") {
        return Err(err(
            path,
            pointer,
            "`data:` URI not in base64; penumbra reads base64 data URIs only",
        ));
    }
    base64::engine::general_purpose::STANDARD
        .decode(payload.trim())
        .map_err(|e| err(path, pointer, format!("bad base64 in `data:` URI: {e}")))
}

/// The file a relative URI names, beside the glTF file in `dir`; URLs
/// (`http://...`) are refused.
pub(super) fn uri_file(path: &Path, dir: &Path, pointer: &str, uri: &str) -> Result<PathBuf> {
    if uri.contains("://") {
        return Err(err(
            path,
            pointer,
            format!("`{uri}`: penumbra reads files beside the glTF file, not URLs"),
        ));
    }
    Ok(dir.join(percent_decode(uri)))
}

/// Reads the file a relative URI names (through [`crate::scene::input`]:
/// same limits and messages as the files an OBJ names).
pub(super) fn read_uri(
    path: &Path,
    dir: &Path,
    pointer: &str,
    uri: &str,
    what: &str,
) -> Result<(PathBuf, Vec<u8>)> {
    let file = uri_file(path, dir, pointer, uri)?;
    let bytes = super::super::input::read(&file).map_err(|e| {
        err(
            path,
            pointer,
            format!("cannot read {what} `{}`: {e}", file.display()),
        )
    })?;
    Ok((file, bytes))
}

/// Refuses an allocation of `bytes` that the memory left cannot hold.
pub(super) fn check_alloc(path: &Path, pointer: &str, what: &str, bytes: u64) -> Result<()> {
    let have = crate::allocator::memory_budget().unwrap_or(u64::MAX);
    if bytes > have.min(isize::MAX as u64) {
        let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
        return Err(err(
            path,
            pointer,
            format!(
                "{what} needs about {:.1} GiB, more than the {:.1} GiB available",
                gib(bytes),
                gib(have)
            ),
        ));
    }
    Ok(())
}

/// The buffers of one glTF file, read on first use (a file's animation
/// data may sit in buffers a still scene never reads).
pub(super) struct Buffers<'a> {
    /// The glTF file.
    pub path: &'a Path,
    /// Its directory, where relative URIs point.
    pub dir: &'a Path,
    /// Its JSON.
    pub root: &'a json::Root,
    /// The GLB binary chunk.
    bin: Option<&'a [u8]>,
    /// Buffers read so far, each cut to its `byteLength`.
    loaded: Vec<Option<Cow<'a, [u8]>>>,
}

impl<'a> Buffers<'a> {
    /// The buffers of `root` (read from `path`, with GLB chunk `bin`).
    pub fn new(path: &'a Path, dir: &'a Path, root: &'a json::Root, bin: Option<&'a [u8]>) -> Self {
        Buffers {
            path,
            dir,
            root,
            bin,
            loaded: vec![None; root.buffers.len()],
        }
    }

    /// Buffer `i`'s bytes; `used_at` is the pointer that refers to it.
    fn get(&mut self, i: usize, used_at: &str) -> Result<&[u8]> {
        let (path, root) = (self.path, self.root);
        let Some(buffer) = root.buffers.get(i) else {
            return Err(err(
                path,
                used_at,
                format!(
                    "buffer {i} does not exist (the file has {})",
                    self.loaded.len()
                ),
            ));
        };
        if self.loaded[i].is_none() {
            let at = format!("/buffers/{i}");
            let data: Cow<[u8]> = match (&buffer.uri, self.bin) {
                (None, Some(bin)) if i == 0 => Cow::Borrowed(bin),
                (None, _) => {
                    return Err(err(
                        path,
                        &at,
                        "no `uri`, and no GLB binary chunk to take the data from",
                    ))
                }
                (Some(uri), _) if uri.starts_with("data:") => {
                    Cow::Owned(data_uri(path, &format!("{at}/uri"), uri)?)
                }
                (Some(uri), _) => {
                    Cow::Owned(read_uri(path, self.dir, &format!("{at}/uri"), uri, "buffer")?.1)
                }
            };
            let length = buffer.byte_length.0;
            if (data.len() as u64) < length {
                return Err(err(
                    path,
                    &at,
                    format!(
                        "byteLength is {length} but the data has only {} bytes (truncated?)",
                        data.len()
                    ),
                ));
            }
            // Within the data's length, so within `usize`.
            let data = match data {
                Cow::Borrowed(b) => Cow::Borrowed(&b[..length as usize]),
                Cow::Owned(mut b) => {
                    b.truncate(length as usize);
                    Cow::Owned(b)
                }
            };
            self.loaded[i] = Some(data);
        }
        Ok(self.loaded[i].as_deref().unwrap_or_default())
    }

    /// Buffer view `v`'s bytes and stride; `used_at` refers to it.
    pub fn view(&mut self, v: usize, used_at: &str) -> Result<(&[u8], Option<usize>)> {
        let path = self.path;
        let root = self.root;
        let Some(view) = root.buffer_views.get(v) else {
            return Err(err(
                path,
                used_at,
                format!(
                    "bufferView {v} does not exist (the file has {})",
                    root.buffer_views.len()
                ),
            ));
        };
        let at = format!("/bufferViews/{v}");
        let b = view.buffer.value();
        let buffer = self.get(b, &format!("{at}/buffer"))?;
        let offset = view.byte_offset.map_or(0, |o| o.0);
        let end = offset.checked_add(view.byte_length.0);
        match end.filter(|&e| e <= buffer.len() as u64) {
            // Within the buffer's length, so within `usize`.
            Some(end) => Ok((
                &buffer[offset as usize..end as usize],
                view.byte_stride.map(|s| s.0),
            )),
            None => Err(err(
                path,
                &at,
                format!(
                    "byteOffset {offset} + byteLength {} lies outside buffer {b} ({} bytes)",
                    view.byte_length.0,
                    buffer.len()
                ),
            )),
        }
    }
}

/// An accessor's elements, tightly packed, sparse substitutions applied.
pub(super) struct Packed {
    /// The accessor's JSON pointer (`/accessors/7`).
    pub at: String,
    /// Component type.
    component: ComponentType,
    /// Element type.
    pub kind: Type,
    /// Integer components map to [0, 1] or [-1, 1].
    normalized: bool,
    /// Number of elements.
    pub count: usize,
    /// `count` elements of `element_size` bytes.
    bytes: Vec<u8>,
}

/// Bytes of one component.
fn component_size(c: ComponentType) -> usize {
    match c {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

/// Components per element (matrices without their column padding, which
/// no attribute we read has).
fn multiplicity(t: Type) -> usize {
    match t {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

/// The checked `count` elements of `elem` bytes from `offset` every
/// `stride` bytes of `data` (a view), copied tightly packed.
fn gather(
    data: &[u8],
    offset: u64,
    stride: usize,
    elem: usize,
    count: u64,
    fail: impl Fn(String) -> Error,
) -> Result<Vec<u8>> {
    let needed = match count {
        0 => Some(0),
        n => (n - 1)
            .checked_mul(stride as u64)
            .and_then(|x| x.checked_add(offset))
            .and_then(|x| x.checked_add(elem as u64)),
    };
    if needed.is_none_or(|n| n > data.len() as u64) {
        return Err(fail(format!(
            "{count} elements of {elem} bytes every {stride} bytes from byteOffset {offset} \
             run past the end of their bufferView ({} bytes)",
            data.len()
        )));
    }
    // Every element lies within `data` (checked above), so these fit.
    let (offset, count) = (offset as usize, count as usize);
    let mut out = Vec::with_capacity(count * elem);
    for k in 0..count {
        let start = offset + k * stride;
        out.extend_from_slice(&data[start..start + elem]);
    }
    Ok(out)
}

/// Reads accessor `index` (referred to at `used_at`) as packed elements.
pub(super) fn packed(bufs: &mut Buffers, index: usize, used_at: &str) -> Result<Packed> {
    let (path, root) = (bufs.path, bufs.root);
    let Some(acc) = root.accessors.get(index) else {
        return Err(err(
            path,
            used_at,
            format!(
                "accessor {index} does not exist (the file has {})",
                root.accessors.len()
            ),
        ));
    };
    let at = format!("/accessors/{index}");
    let fail = |msg: String| err(path, &at, msg);
    let Checked::Valid(json::accessor::GenericComponentType(component)) = acc.component_type else {
        return Err(fail("invalid componentType".into()));
    };
    let Checked::Valid(kind) = acc.type_ else {
        return Err(fail("invalid type".into()));
    };
    let elem = component_size(component) * multiplicity(kind);
    let count = acc.count.0;
    let total = count.saturating_mul(elem as u64);
    let mut bytes = match acc.buffer_view {
        Some(v) => {
            let (data, stride) = bufs.view(v.value(), &format!("{at}/bufferView"))?;
            let stride = stride.unwrap_or(elem);
            if stride < elem {
                return Err(fail(format!(
                    "bufferView {} has byteStride {stride}, less than the {elem}-byte element",
                    v.value()
                )));
            }
            let offset = acc.byte_offset.map_or(0, |o| o.0);
            gather(data, offset, stride, elem, count, fail)?
        }
        None => {
            // All zeros (to be filled by sparse substitution): nothing in
            // the file bounds the count, so memory does.
            check_alloc(path, &at, &format!("{count} elements"), total)?;
            vec![0; total as usize]
        }
    };
    if let Some(sparse) = &acc.sparse {
        substitute(bufs, &at, sparse, elem, &mut bytes)?;
    }
    Ok(Packed {
        at,
        component,
        kind,
        normalized: acc.normalized,
        count: count as usize,
        bytes,
    })
}

/// Applies an accessor's sparse substitutions to its packed `bytes`.
fn substitute(
    bufs: &mut Buffers,
    at: &str,
    sparse: &json::accessor::sparse::Sparse,
    elem: usize,
    bytes: &mut [u8],
) -> Result<()> {
    let path = bufs.path;
    let at = format!("{at}/sparse");
    let count = (bytes.len() / elem.max(1)) as u64;
    let n = sparse.count.0;
    if n > count {
        return Err(err(
            path,
            &format!("{at}/count"),
            format!("{n} substitutions, more than the accessor's {count} elements"),
        ));
    }
    let Checked::Valid(json::accessor::IndexComponentType(index_type)) =
        sparse.indices.component_type
    else {
        return Err(err(path, &format!("{at}/indices/componentType"), "invalid"));
    };
    let index_size = component_size(index_type);
    let indices_at = format!("{at}/indices");
    let (data, _) = bufs.view(sparse.indices.buffer_view.value(), &indices_at)?;
    let fail = |msg: String| err(path, &indices_at, msg);
    let indices = gather(
        data,
        sparse.indices.byte_offset.0,
        index_size,
        index_size,
        n,
        fail,
    )?;
    let values_at = format!("{at}/values");
    let (data, _) = bufs.view(sparse.values.buffer_view.value(), &values_at)?;
    let fail = |msg: String| err(path, &values_at, msg);
    let values = gather(data, sparse.values.byte_offset.0, elem, elem, n, fail)?;
    for (k, value) in values.chunks_exact(elem).enumerate() {
        let i = read_uint(index_type, &indices, k);
        if i >= count {
            return Err(err(
                path,
                &indices_at,
                format!("index {i} (entry {k}) is out of range: the accessor has {count} elements"),
            ));
        }
        // `i < count`, so the element lies within `bytes`.
        let start = i as usize * elem;
        bytes[start..start + elem].copy_from_slice(value);
    }
    Ok(())
}

/// Component `k` of packed unsigned integers of type `c`.
fn read_uint(c: ComponentType, bytes: &[u8], k: usize) -> u64 {
    let size = component_size(c);
    let b = &bytes[k * size..(k + 1) * size];
    match size {
        1 => u64::from(b[0]),
        2 => u64::from(u16::from_le_bytes([b[0], b[1]])),
        _ => u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
    }
}

impl Packed {
    /// Refuses an element type other than `want` for attribute `what`.
    pub fn expect(&self, path: &Path, want: Type, what: &str) -> Result<()> {
        if self.kind == want {
            return Ok(());
        }
        Err(err(
            path,
            &format!("{}/type", self.at),
            format!("{what} needs type {want:?}, not {:?}", self.kind),
        ))
    }

    /// The components as `f32`: floats as stored, normalized integers
    /// mapped to [0, 1] (unsigned) or [-1, 1] (signed) as the glTF
    /// specification says, other integers as their value.
    pub fn floats(&self) -> Vec<f32> {
        let b = &self.bytes;
        let n = self.normalized;
        match self.component {
            ComponentType::F32 => b
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect(),
            ComponentType::I8 => b
                .iter()
                .map(|&c| match (c as i8, n) {
                    (x, true) => (f32::from(x) / 127.0).max(-1.0),
                    (x, false) => f32::from(x),
                })
                .collect(),
            ComponentType::U8 => b
                .iter()
                .map(|&c| f32::from(c) / if n { 255.0 } else { 1.0 })
                .collect(),
            ComponentType::I16 => b
                .chunks_exact(2)
                .map(|c| match (i16::from_le_bytes([c[0], c[1]]), n) {
                    (x, true) => (f32::from(x) / 32767.0).max(-1.0),
                    (x, false) => f32::from(x),
                })
                .collect(),
            ComponentType::U16 => b
                .chunks_exact(2)
                .map(|c| {
                    f32::from(u16::from_le_bytes([c[0], c[1]])) / if n { 65535.0 } else { 1.0 }
                })
                .collect(),
            ComponentType::U32 => b
                .chunks_exact(4)
                .map(|c| {
                    let x = f64::from(u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
                    (x / if n { f64::from(u32::MAX) } else { 1.0 }) as f32
                })
                .collect(),
        }
    }

    /// The elements as vertex indices (unsigned byte, short or int
    /// scalars).
    pub fn indices(&self, path: &Path) -> Result<Vec<u32>> {
        self.expect(path, Type::Scalar, "indices")?;
        if !matches!(
            self.component,
            ComponentType::U8 | ComponentType::U16 | ComponentType::U32
        ) {
            return Err(err(
                path,
                &format!("{}/componentType", self.at),
                format!(
                    "indices need unsigned bytes, shorts or ints, not {:?}",
                    self.component
                ),
            ));
        }
        // Unsigned of at most 32 bits.
        Ok((0..self.count)
            .map(|k| read_uint(self.component, &self.bytes, k) as u32)
            .collect())
    }
}
