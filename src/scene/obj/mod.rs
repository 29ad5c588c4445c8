//! OBJ/MTL loading through `tobj` (triangulated, single index).
//!
//! tobj reports errors without line numbers and panics or overflows on a
//! few malformed inputs (`Kd 0.5`, huge relative face indices), so every
//! file is first scanned here: each line tobj would read is checked (numbers
//! well-formed and finite, face indices in range, ...) and errors name the
//! file and line. The scan also rewrites the few lines tobj would misread
//! and blanks the ones we do not use, so tobj only ever sees valid input.
//!
//! Files as exporters write them load (docs/scene-format.md, "OBJ and MTL
//! files in the wild"): a byte-order mark, zero or non-finite normals (the
//! face's geometric normal stands in), `mtllib` names with spaces or
//! several files, `\` separators and a letter case that differs from the
//! file on disk, `map_*` options, `Tr` for `d`, and statements we do not
//! use, which are skipped without a word.
//!
//! A plain file (positions and triangles only, as scanners and
//! subdividers write them) takes a parallel fast path to the same mesh
//! ([`plain`]); any other falls back to the scan and tobj.

use super::assets::{Assets, TextureKind, DEFAULT_MATERIAL};
use super::Material;
use crate::error::{Error, Result};
use crate::geom::Mesh;
use glam::{Vec2, Vec3};
use std::borrow::Cow;
use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

mod plain;

/// Reads a file referenced from `from:line` (through [`super::input`]: a
/// missing, unreadable, special or oversized file is an error at the
/// reference).
fn read_bytes(path: &Path, what: &str, from: &Path, line: usize) -> Result<Vec<u8>> {
    super::input::read(path).map_err(|e| {
        Error::file(
            from,
            Some(line),
            format!("cannot read {what} `{}`: {e}", path.display()),
        )
    })
}

/// Decodes a file's bytes as text: invalid UTF-8 is an error in the file
/// itself. A UTF-8 byte-order mark is dropped (it would glue itself to the
/// first statement's keyword).
fn decode_text(path: &Path, bytes: Vec<u8>) -> Result<String> {
    let mut text = String::from_utf8(bytes).map_err(|e| {
        let bad = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..bad].iter().filter(|&&b| b == b'\n').count() + 1;
        Error::file(path, Some(line), "not valid UTF-8 text")
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// Reads a text file referenced from `from:line`.
fn read_text(path: &Path, what: &str, from: &Path, line: usize) -> Result<String> {
    decode_text(path, read_bytes(path, what, from, line)?)
}

/// The mesh format other than OBJ that `path` is, by its extension or its
/// content, in words; `None` for anything else (read as OBJ). tobj reads
/// any text as OBJ and skips what it does not know, so without this an
/// ASCII PLY, STL, OFF or glTF file would load as an empty mesh.
fn other_mesh_format(path: &Path, bytes: &[u8]) -> Option<&'static str> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_lowercase);
    let by_extension = match ext.as_deref() {
        Some("ply") => Some("PLY"),
        Some("stl") => Some("STL"),
        Some("off") => Some("OFF"),
        Some("gltf") => Some("glTF"),
        Some("glb") => Some("binary glTF (GLB)"),
        Some("fbx") => Some("FBX"),
        Some("dae") => Some("COLLADA"),
        Some("3ds") => Some("3DS"),
        Some("blend") => Some("Blender"),
        Some("usd" | "usda" | "usdc" | "usdz") => Some("USD"),
        _ => None,
    };
    if by_extension.is_some() {
        return by_extension;
    }
    if bytes.starts_with(b"glTF") {
        return Some("binary glTF (GLB)");
    }
    // A binary STL: an 80-byte header, a triangle count, 50 bytes each.
    if let Some(count) = bytes.get(80..84) {
        let count = u32::from_le_bytes([count[0], count[1], count[2], count[3]]) as u64;
        if 84 + 50 * count == bytes.len() as u64 {
            return Some("binary STL");
        }
    }
    let text = bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(bytes);
    let start = text.iter().position(|b| !b.is_ascii_whitespace())?;
    let text = &text[start..];
    let first_line = text.split(|&b| b == b'\n').next().unwrap_or(text);
    let first_word = first_line
        .split(|b| b.is_ascii_whitespace())
        .next()
        .unwrap_or(first_line);
    match first_word {
        b"ply" => Some("PLY"),
        b"solid" => Some("ASCII STL"),
        // OFF and its variants (COFF, NOFF, STCNOFF, 4OFF, ...).
        w if w.ends_with(b"OFF")
            && w.iter()
                .all(|b| b.is_ascii_uppercase() || b.is_ascii_digit()) =>
        {
            Some("OFF")
        }
        // No OBJ statement starts with `{`; glTF's JSON does.
        _ if text.starts_with(b"{") => Some("glTF (JSON)"),
        _ => None,
    }
}

/// True for a normal that cannot be made unit length (zero, too small or
/// too large for `f32`, or not finite).
fn unusable_normal(n: Vec3) -> bool {
    n.normalize_or_zero() == Vec3::ZERO
}

/// The entry of `dir` named `name`, ignoring letter case when no entry has
/// that exact name; `None` when none or several match.
fn entry_any_case(dir: &Path, name: &std::ffi::OsStr) -> Option<PathBuf> {
    let exact = dir.join(name);
    if exact.exists() {
        return Some(exact);
    }
    let wanted = name.to_str()?.to_lowercase();
    let mut found = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_str().map(str::to_lowercase) == Some(wanted.clone()));
    match (found.next(), found.next()) {
        (Some(e), None) => Some(e.path()),
        _ => None,
    }
}

/// Finds a file an OBJ or MTL file in `dir` names, as exporters write
/// names: `\` or `/` separators, relative to `dir` or absolute, each
/// component matched exactly or else in any letter case. When the path
/// does not resolve (say an absolute path on the exporter's machine), the
/// file's bare name is looked up in `dir` the same way; that fallback is
/// returned as `Err` so the caller can say so. `None`: not found at all.
fn find_file(dir: &Path, name: &str) -> Option<std::result::Result<PathBuf, PathBuf>> {
    use std::path::Component;
    let name = name.replace('\\', "/");
    let wanted = Path::new(&name);
    let mut at = dir.to_path_buf();
    let mut resolved = true;
    for c in wanted.components() {
        match c {
            Component::RootDir | Component::Prefix(_) => at = PathBuf::from(c.as_os_str()),
            Component::CurDir => {}
            Component::ParentDir => at.push(".."),
            Component::Normal(part) => match entry_any_case(&at, part) {
                Some(next) => at = next,
                None => {
                    resolved = false;
                    break;
                }
            },
        }
    }
    if resolved && at.is_file() {
        return Some(Ok(at));
    }
    let bare = wanted.file_name()?;
    if wanted.components().count() > 1 {
        if let Some(p) = entry_any_case(dir, bare).filter(|p| p.is_file()) {
            return Some(Err(p));
        }
    }
    None
}

/// One non-blank line as tobj sees it (`BufRead::lines`: `\n` or `\r\n`
/// ends a line): its 1-based number, byte range, text, first word and
/// the words after it.
struct Statement<'a> {
    ln: usize,
    range: Range<usize>,
    line: &'a str,
    keyword: &'a str,
    words: std::str::SplitWhitespace<'a>,
}

/// The statements of an OBJ or MTL text (blank lines skipped), for both
/// scans.
fn statements(text: &str) -> impl Iterator<Item = Statement<'_>> {
    let mut start = 0;
    text.split('\n').enumerate().filter_map(move |(i, raw)| {
        let range = start..start + raw.len();
        start = range.end + 1;
        let line = raw.strip_suffix('\r').unwrap_or(raw);
        let mut words = line.split_whitespace();
        let keyword = words.next()?;
        Some(Statement {
            ln: i + 1,
            range,
            line,
            keyword,
            words,
        })
    })
}

/// Line replacements, applied only if there are any (most files need none).
#[derive(Default)]
struct Edits(Vec<(Range<usize>, String)>);

impl Edits {
    fn replace(&mut self, range: Range<usize>, with: String) {
        self.0.push((range, with));
    }

    fn apply(self, text: &str) -> Cow<'_, str> {
        if self.0.is_empty() {
            return Cow::Borrowed(text);
        }
        let mut out = String::with_capacity(text.len());
        let mut at = 0;
        for (range, with) in self.0 {
            out.push_str(&text[at..range.start]);
            out.push_str(&with);
            at = range.end;
        }
        out.push_str(&text[at..]);
        Cow::Owned(out)
    }
}

/// The text after a line's first word, trimmed (names may contain spaces).
fn rest_after_keyword(line: &str) -> &str {
    let line = line.trim_start();
    line.find(char::is_whitespace)
        .map_or("", |i| line[i..].trim())
}

/// Parses every remaining word as a finite number.
fn numbers<'a>(
    words: impl Iterator<Item = &'a str>,
    err: impl Fn(String) -> Error,
) -> Result<Vec<f32>> {
    words
        .map(|w| match w.parse::<f32>() {
            Ok(x) if x.is_finite() => Ok(x),
            Ok(_) => Err(err(format!("non-finite number `{w}`"))),
            Err(_) => Err(err(format!("malformed number `{w}`"))),
        })
        .collect()
}

/// Parses every remaining word as a number, `inf` and `nan` included.
fn any_numbers<'a>(
    words: impl Iterator<Item = &'a str>,
    err: impl Fn(String) -> Error,
) -> Result<Vec<f32>> {
    words
        .map(|w| {
            w.parse::<f32>()
                .map_err(|_| err(format!("malformed number `{w}`")))
        })
        .collect()
}

/// What the OBJ scan learned: the text to hand to tobj, the `mtllib`
/// references in file order (tobj asks for them in that order) and the
/// unusable `vn` lines (rewritten to `vn 0 0 0` for tobj): how many, and
/// the first one's line.
struct ObjScan<'a> {
    text: Cow<'a, str>,
    mtllibs: Vec<(String, usize)>,
    bad_normals: Option<(usize, usize)>,
}

/// Element kinds a face index can refer to, as named in messages.
const KINDS: [&str; 3] = ["vertices", "texture coordinates", "normals"];

fn scan_obj<'a>(path: &Path, text: &'a str) -> Result<ObjScan<'a>> {
    let mut counts = [0i64; 3];
    let mut mtllibs = Vec::new();
    let mut bad_normals: Option<(usize, usize)> = None;
    let mut edits = Edits::default();
    for Statement {
        ln,
        range,
        line,
        keyword,
        words,
    } in statements(text)
    {
        let err = |msg: String| Error::file(path, Some(ln), msg);
        match keyword {
            "v" | "vt" => {
                let nums = numbers(words, err)?;
                let (kind, ok) = match keyword {
                    // x y z, x y z w (w ≠ 0: tobj divides by it), x y z r g b
                    "v" => (
                        0,
                        matches!(nums.len(), 3 | 6) || (nums.len() == 4 && nums[3] != 0.0),
                    ),
                    _ => (1, matches!(nums.len(), 2 | 3)),
                };
                if !ok {
                    return Err(err(format!(
                        "malformed `{keyword}` line (wrong count of numbers or zero w)"
                    )));
                }
                if kind == 0 && nums.len() == 6 {
                    // Vertex colours are not used, and tobj fails (with no
                    // line) on a file where only some vertices have them:
                    // keep the position, as written.
                    let xyz: Vec<&str> = line.split_whitespace().skip(1).take(3).collect();
                    edits.replace(range, format!("v {}", xyz.join(" ")));
                }
                counts[kind] += 1;
            }
            "vn" => {
                let nums = any_numbers(words, err)?;
                let [x, y, z] = nums[..] else {
                    return Err(err("malformed `vn` line (needs 3 numbers)".into()));
                };
                // Exporters write zero normals for degenerate corners: the
                // corners using one get their face's normal (load_obj).
                if unusable_normal(Vec3::new(x, y, z)) {
                    bad_normals.get_or_insert((0, ln)).0 += 1;
                    if !(x.is_finite() && y.is_finite() && z.is_finite()) {
                        edits.replace(range, "vn 0 0 0".into());
                    }
                }
                counts[2] += 1;
            }
            "f" => {
                let mut corners = 0;
                for corner in words {
                    corners += 1;
                    for (kind, part) in corner.split('/').enumerate() {
                        if kind > 2 {
                            return Err(err(format!("malformed face vertex `{corner}`")));
                        }
                        if part.is_empty() {
                            if kind == 0 {
                                return Err(err(format!(
                                    "face vertex `{corner}` has no position index"
                                )));
                            }
                            continue;
                        }
                        let x: i64 = part
                            .parse()
                            .map_err(|_| err(format!("malformed face index `{part}`")))?;
                        if x == 0 {
                            return Err(err("face index 0 (OBJ indices start at 1)".into()));
                        } else if x < 0 && counts[kind] + x < 0 {
                            return Err(err(format!(
                                "relative face index {x} out of range: only {} {} so far",
                                counts[kind], KINDS[kind]
                            )));
                        } else if x > counts[kind] {
                            // tobj resolves indices when it closes a group,
                            // so a forward reference fails there without a
                            // line, or not at all: refused here, at the face.
                            return Err(err(format!(
                                "face index {x} out of range: only {} {} before this line \
                                 (elements must come before the faces that use them)",
                                counts[kind], KINDS[kind]
                            )));
                        }
                    }
                }
                if corners == 0 {
                    return Err(err("face without vertices".into()));
                }
            }
            // tobj would triangulate polylines; they are not surfaces.
            // (`p` points, `s` smoothing groups, `g`/`o` names, free-form
            // statements: tobj skips or only names them.)
            "l" => edits.replace(range, String::new()),
            // tobj splits at the first space only: canonicalise.
            "mtllib" | "usemtl" => {
                let name = rest_after_keyword(line);
                if name.is_empty() {
                    return Err(err(format!("`{keyword}` without a name")));
                }
                if keyword == "mtllib" {
                    mtllibs.push((name.to_string(), ln));
                }
                let canonical = format!("{keyword} {name}");
                if line != canonical {
                    edits.replace(range, canonical);
                }
            }
            _ => {}
        }
    }
    Ok(ObjScan {
        text: edits.apply(text),
        mtllibs,
        bad_normals,
    })
}

/// Lines of the texture statements of one MTL material, for error messages.
#[derive(Debug, Default)]
struct MtlLines {
    map_kd: Option<usize>,
    map_d: Option<usize>,
}

/// One MTL file as loaded: its path and, per material in tobj's order, the
/// texture lines.
struct LoadedMtl {
    path: PathBuf,
    materials: Vec<MtlLines>,
}

/// Checks an MTL file and rewrites it for tobj: keeps only the statements
/// we use (so junk in `Ka`, `illum`, `bump` ... cannot fail), expands the
/// single-value colour form `Kd r` to `Kd r r r` (tobj panics on it).
fn scan_mtl<'a>(path: &Path, text: &'a str) -> Result<(Cow<'a, str>, Vec<MtlLines>)> {
    let mut materials: Vec<MtlLines> = Vec::new();
    let mut edits = Edits::default();
    for Statement {
        ln,
        range,
        line,
        keyword,
        words,
    } in statements(text)
    {
        let err = |msg: String| Error::file(path, Some(ln), msg);
        match keyword {
            "newmtl" if rest_after_keyword(line).is_empty() => {
                return Err(err("`newmtl` without a name".into()))
            }
            "newmtl" => materials.push(MtlLines::default()),
            "Kd" | "Ks" | "Ns" | "d" | "Tr" => {
                let nums = numbers(words, err)?;
                let colour = matches!(keyword, "Kd" | "Ks");
                match nums.as_slice() {
                    [x] if colour => edits.replace(range, format!("{keyword} {x} {x} {x}")),
                    [_, _, _] if colour => {}
                    [_] => {}
                    _ if colour => return Err(err(format!("`{keyword}` needs 1 or 3 numbers"))),
                    _ => return Err(err(format!("`{keyword}` needs one number"))),
                }
                if nums.iter().any(|&x| x < 0.0) {
                    return Err(err(format!("negative `{keyword}`")));
                }
                if matches!(keyword, "d" | "Tr") && nums.iter().any(|&x| x > 1.0) {
                    return Err(err(format!("`{keyword}` must be in [0, 1]")));
                }
            }
            "map_Kd" | "map_d" => {
                if rest_after_keyword(line).is_empty() {
                    return Err(err(format!("`{keyword}` without a file name")));
                }
                if texture_spec(rest_after_keyword(line)).file.is_empty() {
                    return Err(err(format!("`{keyword}` has options but no file name")));
                }
                if let Some(m) = materials.last_mut() {
                    *(if keyword == "map_Kd" {
                        &mut m.map_kd
                    } else {
                        &mut m.map_d
                    }) = Some(ln);
                }
            }
            _ if keyword.starts_with('#') => {}
            _ => edits.replace(range, String::new()),
        }
    }
    Ok((edits.apply(text), materials))
}

/// A `map_*` statement's argument: the file name after the options.
struct TextureSpec<'a> {
    /// The rest of the statement after the options (may contain spaces).
    file: &'a str,
    /// An `-o`, `-s` or `-t` option moves, scales or perturbs the uvs: we
    /// do not apply it.
    moves_uvs: bool,
}

/// Splits a `map_*` argument into options and file name. The options are
/// the MTL format's (`-blendu`, `-blendv`, `-cc`, `-clamp`, `-bm`,
/// `-boost`, `-texres`, `-imfchan`, `-type` with one value, `-mm` with two,
/// `-o`, `-s`, `-t` with one to three numbers); an unknown `-word` takes the
/// numbers and `on`/`off` after it. All are skipped: textures are sampled
/// as they are.
fn texture_spec(spec: &str) -> TextureSpec<'_> {
    let words: Vec<(usize, &str)> = spec
        .split_whitespace()
        // Offsets of the words in `spec` (each is a subslice of it).
        .map(|w| (w.as_ptr() as usize - spec.as_ptr() as usize, w))
        .collect();
    let number = |i: usize| words.get(i).and_then(|w| w.1.parse::<f32>().ok());
    let mut moves_uvs = false;
    let mut i = 0;
    while let Some(&(_, opt)) = words.get(i) {
        // `-` then a letter (`-0.5` or `-` alone would be a file name).
        let is_option = opt
            .strip_prefix('-')
            .is_some_and(|rest| rest.starts_with(|c: char| c.is_ascii_alphabetic()));
        if !is_option {
            break;
        }
        i += 1;
        match opt {
            "-o" | "-s" | "-t" => {
                let neutral = if opt == "-s" { 1.0 } else { 0.0 };
                let start = i;
                while i < start + 3 {
                    let Some(x) = number(i) else { break };
                    moves_uvs |= x != neutral;
                    i += 1;
                }
            }
            "-mm" => i += 2,
            "-blendu" | "-blendv" | "-cc" | "-clamp" | "-bm" | "-boost" | "-texres"
            | "-imfchan" | "-type" => i += 1,
            _ => {
                while words
                    .get(i)
                    .is_some_and(|w| w.1.parse::<f32>().is_ok() || matches!(w.1, "on" | "off"))
                {
                    i += 1;
                }
            }
        }
    }
    TextureSpec {
        file: words.get(i).map_or("", |&(at, _)| spec[at..].trim_end()),
        moves_uvs,
    }
}

/// Resolves a file named in `from` (an OBJ or MTL file in `dir`) with
/// [`find_file`]; a bare-name fallback is reported, a miss leaves the path
/// as written so that reading it fails with that name.
fn resolve(dir: &Path, name: &str, what: &str, from: &Path, line: Option<usize>) -> PathBuf {
    match find_file(dir, name) {
        Some(Ok(p)) => p,
        Some(Err(p)) => {
            let at = line.map_or(String::new(), |l| format!(":{l}"));
            eprintln!(
                "warning: {}{at}: {what} `{name}` not found there; using `{}`",
                from.display(),
                p.display()
            );
            p
        }
        None => dir.join(name.replace('\\', "/")),
    }
}

/// Converts one tobj material (already range-checked by the scan), loading
/// its textures relative to the MTL file.
fn convert_material(
    m: &tobj::Material,
    mtl_path: &Path,
    lines: &MtlLines,
    assets: &mut Assets,
) -> Result<Material> {
    let dir = mtl_path.parent().unwrap_or(Path::new(""));
    let mut texture = |spec: &Option<String>, kind, line: Option<usize>| -> Result<Option<usize>> {
        let Some(spec) = spec.as_deref().map(texture_spec) else {
            return Ok(None);
        };
        if spec.moves_uvs {
            let at = line.map_or(String::new(), |l| format!(":{l}"));
            eprintln!(
                "warning: {}{at}: texture options -o/-s/-t are not applied",
                mtl_path.display()
            );
        }
        let path = resolve(dir, spec.file, "texture", mtl_path, line);
        assets.texture(&path, kind, mtl_path, line).map(Some)
    };
    let defaults = Material::default();
    let tr = m
        .unknown_param
        .get("Tr")
        .and_then(|t| t.parse::<f32>().ok());
    Ok(Material {
        name: m.name.clone(),
        albedo: m.diffuse.map_or(defaults.albedo, Vec3::from),
        albedo_texture: texture(&m.diffuse_texture, TextureKind::Color, lines.map_kd)?,
        specular: m.specular.map_or(defaults.specular, Vec3::from),
        shininess: m.shininess.unwrap_or(defaults.shininess),
        // `Tr` is the transparency some exporters write instead of `d`.
        opacity: m
            .dissolve
            .or(tr.map(|t| 1.0 - t))
            .unwrap_or(defaults.opacity),
        opacity_texture: texture(&m.dissolve_texture, TextureKind::Opacity, lines.map_d)?,
    })
}

/// The files of an `mtllib` statement at `obj:line`: its whole argument as
/// one name (names with spaces), else each word when every one is a file
/// (the format's list of names), else the whole name, which then fails to
/// read with that name.
fn mtllib_files(dir: &Path, name: &str, obj: &Path, line: usize) -> Vec<PathBuf> {
    if find_file(dir, name).is_none() && name.contains(char::is_whitespace) {
        let words: Vec<&str> = name.split_whitespace().collect();
        if words.iter().all(|w| find_file(dir, w).is_some()) {
            return (words.iter())
                .map(|w| resolve(dir, w, "MTL file", obj, Some(line)))
                .collect();
        }
    }
    vec![resolve(dir, name, "MTL file", obj, Some(line))]
}

/// Loads an OBJ (and its MTL files) as one object-space mesh, all tobj
/// models merged. `from:line` is the scene statement that references it.
///
/// With `material_override` (an inline material) every triangle gets it
/// and the MTL files are not read at all. Otherwise MTL materials are added
/// to `assets` as triangles use them; triangles without one get the
/// default material. Vertex normals are kept only if every vertex has one;
/// uvs are kept if any model has them (zero where a model lacks them), and
/// made zero with a warning when a textured material needs them.
/// Degenerate triangles are left for the loader, which drops them after
/// the transform.
pub(super) fn load_obj(
    path: &Path,
    from: &Path,
    line: usize,
    material_override: Option<u32>,
    assets: &mut Assets,
) -> Result<Mesh> {
    let text = read_obj_text(path, from, line)?;
    if let Some(model) = plain::parse(&text) {
        // No material, normal or texture statement: the general path's
        // scan would change nothing, and tobj would read no MTL file.
        let mut material_ids = MaterialIds {
            material_override,
            materials: &[],
            loaded: &[],
            ids: HashMap::new(),
        };
        let merged = merge_models(path, &[model], &mut material_ids, assets)?;
        return finish_mesh(path, from, line, merged, assets, None);
    }
    let scan = scan_obj(path, &text)?;
    let dir = path.parent().unwrap_or(Path::new(""));

    let mtl_loader = MtlLoader {
        dir,
        obj: path,
        mtllibs: &scan.mtllibs,
        material_override,
        next_mtllib: Cell::new(0),
        error: RefCell::new(None),
        loaded: RefCell::new(Vec::new()),
    };
    let parsed = tobj::load_obj_buf(&mut scan.text.as_bytes(), &tobj_options(), |_| {
        mtl_loader.load_next()
    });
    if let Some(e) = mtl_loader.error.take() {
        return Err(e);
    }
    let (models, materials) =
        parsed.map_err(|e| Error::file(path, None, format!("OBJ parse error: {e}")))?;
    let materials = materials.unwrap_or_default();
    let loaded = mtl_loader.loaded.into_inner();

    let mut material_ids = MaterialIds {
        material_override,
        materials: &materials,
        loaded: &loaded,
        ids: HashMap::new(),
    };
    let merged = merge_models(path, &models, &mut material_ids, assets)?;
    finish_mesh(path, from, line, merged, assets, scan.bad_normals)
}

/// How tobj reads every OBJ: triangulated (polygons as fans), one index
/// per vertex, points and polylines skipped.
fn tobj_options() -> tobj::LoadOptions {
    // Other fields exist with tobj's optional features (merging, reordering).
    #[allow(clippy::needless_update)]
    tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    }
}

/// Reads an OBJ file referenced from `from:line` as text; another mesh
/// format is an error at the reference.
fn read_obj_text(path: &Path, from: &Path, line: usize) -> Result<String> {
    let bytes = read_bytes(path, "OBJ", from, line)?;
    if let Some(format) = other_mesh_format(path, &bytes) {
        let read_as = match format {
            "PLY" => "; PLY is read from files named `.ply`",
            "glTF (JSON)" | "binary glTF (GLB)" => {
                "; glTF is read from files named `.gltf` or `.glb`"
            }
            _ => "",
        };
        return Err(Error::file(
            from,
            Some(line),
            format!(
                "`{}` is a {format} file; penumbra reads meshes as Wavefront OBJ \
                 (`.obj`, with its `.mtl` files), PLY (`.ply`) and glTF 2.0 \
                 (`.gltf`, `.glb`){read_as}",
                path.display()
            ),
        ));
    }
    decode_text(path, bytes)
}

/// tobj's material loader for one OBJ file: tobj asks once per `mtllib`
/// line, in file order, so the n-th call reads the n-th scanned `mtllib`.
/// tobj's loader is `Fn`, hence the cells.
struct MtlLoader<'a> {
    /// The OBJ file's directory.
    dir: &'a Path,
    /// The OBJ file.
    obj: &'a Path,
    /// The scan's `mtllib` names and lines.
    mtllibs: &'a [(String, usize)],
    /// An inline material: no MTL file is read.
    material_override: Option<u32>,
    /// The next call's `mtllib` index.
    next_mtllib: Cell<usize>,
    /// The first error (tobj's own would name no file or line).
    error: RefCell<Option<Error>>,
    /// The MTL files loaded, in tobj's order.
    loaded: RefCell<Vec<LoadedMtl>>,
}

impl MtlLoader<'_> {
    /// Loads the next `mtllib` statement's files as one material list.
    fn load_next(&self) -> tobj::MTLLoadResult {
        let index = self.next_mtllib.replace(self.next_mtllib.get() + 1);
        let (Some((name, ln)), None) = (self.mtllibs.get(index), self.material_override) else {
            return Ok(Default::default());
        };
        let mut merged: Option<(Vec<tobj::Material>, _)> = None;
        for mtl_path in mtllib_files(self.dir, name, self.obj, *ln) {
            let result = read_text(&mtl_path, "MTL", self.obj, *ln).and_then(|t| {
                let (text, lines) = scan_mtl(&mtl_path, &t)?;
                let parsed = tobj::load_mtl_buf(&mut text.as_bytes())
                    .map_err(|e| Error::file(&mtl_path, None, format!("MTL parse error: {e}")))?;
                Ok((parsed, lines))
            });
            match result {
                Ok(((mats, map), materials)) => {
                    self.loaded.borrow_mut().push(LoadedMtl {
                        path: mtl_path,
                        materials,
                    });
                    // Several files on one line: one list, as tobj merges
                    // the results of successive lines.
                    match &mut merged {
                        None => merged = Some((mats, map)),
                        Some((all, all_map)) => {
                            let offset = all.len();
                            all.extend(mats);
                            all_map.extend(map.into_iter().map(|(k, i)| (k, i + offset)));
                        }
                    }
                }
                Err(e) => {
                    self.error.borrow_mut().get_or_insert(e);
                    return Err(tobj::LoadError::OpenFileFailed);
                }
            }
        }
        Ok(merged.unwrap_or_default())
    }
}

/// tobj material index → scene material index, converted on first use so
/// that unused materials cannot fail on their textures.
struct MaterialIds<'a> {
    /// An inline material every triangle gets.
    material_override: Option<u32>,
    /// tobj's materials.
    materials: &'a [tobj::Material],
    /// The MTL files they came from, in tobj's order.
    loaded: &'a [LoadedMtl],
    /// Materials converted so far.
    ids: HashMap<usize, u32>,
}

impl MaterialIds<'_> {
    /// The scene material of tobj material `tobj_id`.
    fn get(&mut self, tobj_id: Option<usize>, assets: &mut Assets) -> Result<u32> {
        if let Some(id) = self.material_override {
            return Ok(id);
        }
        let Some((index, material)) = tobj_id.and_then(|i| self.materials.get(i).map(|m| (i, m)))
        else {
            return Ok(DEFAULT_MATERIAL);
        };
        if let Some(&id) = self.ids.get(&index) {
            return Ok(id);
        }
        // tobj appends each MTL file's materials in load order.
        let mut i = index;
        let source = self.loaded.iter().find_map(|l| match l.materials.get(i) {
            Some(lines) => Some((l.path.as_path(), lines)),
            None => {
                i -= l.materials.len();
                None
            }
        });
        let fallback = MtlLines::default();
        let (mtl_path, lines) = source.unwrap_or((Path::new(""), &fallback));
        let converted = convert_material(material, mtl_path, lines, assets)?;
        let id = assets.material(converted)?;
        self.ids.insert(index, id);
        Ok(id)
    }
}

/// tobj's models merged into one mesh, before the per-vertex arrays are
/// kept or dropped.
struct MergedModels {
    /// Positions, triangles and material ids.
    mesh: Mesh,
    /// Vertex normals, complete only when `all_normals`.
    normals: Vec<Vec3>,
    /// Uvs, zero where a model lacks them.
    uvs: Vec<Vec2>,
    /// Every model has a normal per vertex.
    all_normals: bool,
    /// Some model with vertices has uvs.
    any_uvs: bool,
}

/// Merges tobj's models (of the OBJ at `path`) into one mesh.
fn merge_models(
    path: &Path,
    models: &[tobj::Model],
    material_ids: &mut MaterialIds,
    assets: &mut Assets,
) -> Result<MergedModels> {
    let mut mesh = Mesh::default();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let (mut all_normals, mut any_uvs) = (true, false);
    let too_big = || Error::file(path, None, "more than 2^32 vertices");
    for model in models {
        let model_mesh = &model.mesh;
        let vertices = model_mesh.positions.len() / 3;
        let base = u32::try_from(mesh.positions.len()).map_err(|_| too_big())?;
        mesh.positions
            .extend(model_mesh.positions.chunks_exact(3).map(Vec3::from_slice));
        // tobj leaves out the normal (uv) of a corner that has none, so the
        // arrays only line up when every vertex has one.
        if model_mesh.normals.len() == 3 * vertices {
            normals.extend(model_mesh.normals.chunks_exact(3).map(Vec3::from_slice));
        } else {
            all_normals = false;
        }
        if model_mesh.texcoords.len() == 2 * vertices {
            any_uvs |= vertices > 0;
            uvs.extend(model_mesh.texcoords.chunks_exact(2).map(Vec2::from_slice));
        } else {
            uvs.resize(mesh.positions.len(), Vec2::ZERO);
        }
        let material = material_ids.get(model_mesh.material_id, assets)?;
        for triangle in model_mesh.indices.chunks_exact(3) {
            let corner = |i: u32| base.checked_add(i).ok_or_else(too_big);
            mesh.triangles.push([
                corner(triangle[0])?,
                corner(triangle[1])?,
                corner(triangle[2])?,
            ]);
            mesh.material_ids.push(material);
        }
    }
    Ok(MergedModels {
        mesh,
        normals,
        uvs,
        all_normals,
        any_uvs,
    })
}

/// The merged mesh as loaded: refused without faces; normals kept only if
/// every vertex has one, uvs if any model has them or a material is
/// textured; unusable normals (`bad_normals`, from the scan) replaced.
fn finish_mesh(
    path: &Path,
    from: &Path,
    line: usize,
    merged: MergedModels,
    assets: &Assets,
    bad_normals: Option<(usize, usize)>,
) -> Result<Mesh> {
    let MergedModels {
        mut mesh,
        normals,
        uvs,
        all_normals,
        any_uvs,
    } = merged;
    if mesh.triangles.is_empty() {
        // Vertices alone (a point cloud, or faces lost in export) render as
        // nothing: refused rather than an invisible object.
        // The whole file is at fault, not one of its lines: named at the
        // scene line that asked for it.
        return Err(Error::file(
            from,
            Some(line),
            format!(
                "OBJ `{}` has no faces (`f` lines): nothing to render (points and lines \
                 are not surfaces)",
                path.display()
            ),
        ));
    }
    if all_normals && !mesh.positions.is_empty() {
        mesh.normals = Some(normals);
    }
    let textured = mesh.material_ids.iter().any(|&id| {
        assets
            .materials
            .get(id as usize)
            .is_some_and(|m| m.albedo_texture.is_some() || m.opacity_texture.is_some())
    });
    if textured && !any_uvs {
        eprintln!(
            "warning: {}: textured material on a mesh without texture coordinates; using uv (0, 0)",
            path.display()
        );
    }
    if any_uvs || textured {
        mesh.uvs = Some(uvs);
    }
    if let Some((count, line)) = bad_normals {
        let corners = replace_unusable_normals(&mut mesh);
        if corners > 0 {
            eprintln!(
                "warning: {}:{line}: {count} zero or non-finite `vn` normal(s), the first \
                 here; the {corners} triangle corner(s) using them take their face's \
                 geometric normal",
                path.display()
            );
        }
    }
    Ok(mesh)
}

/// Gives every triangle corner whose vertex normal is unusable (zero or
/// not finite) the triangle's geometric normal, splitting a vertex that
/// triangles with different normals share; returns how many corners
/// changed. Vertices no triangle uses get an arbitrary unit normal, so
/// that every normal of the mesh stays finite through the transform.
pub(super) fn replace_unusable_normals(mesh: &mut Mesh) -> usize {
    let Some(normals) = mesh.normals.as_mut() else {
        return 0;
    };
    let bad: Vec<bool> = normals.iter().map(|&n| unusable_normal(n)).collect();
    // The normal each bad vertex got from the first triangle using it.
    let mut given: HashMap<u32, Vec3> = HashMap::new();
    let mut corners = 0;
    for tri in &mut mesh.triangles {
        if !tri.iter().any(|&v| bad[v as usize]) {
            continue;
        }
        // In f64, so that tiny triangles still get a direction; a
        // degenerate one (dropped by the loader) gets any unit vector.
        let [a, b, c] = tri.map(|v| mesh.positions[v as usize].as_dvec3());
        let g = (b - a).cross(c - a).normalize_or_zero().as_vec3();
        let g = if unusable_normal(g) { Vec3::Z } else { g };
        for v in tri.iter_mut() {
            if !bad[*v as usize] {
                continue;
            }
            corners += 1;
            match given.get(v) {
                None => {
                    normals[*v as usize] = g;
                    given.insert(*v, g);
                }
                Some(&n) if n == g => {}
                Some(_) => {
                    // Another face already gave this vertex its normal: a
                    // copy (out of u32 indices, the first face's normal).
                    let i = *v as usize;
                    if let Ok(copy) = u32::try_from(mesh.positions.len()) {
                        mesh.positions.push(mesh.positions[i]);
                        normals.push(g);
                        if let Some(uvs) = mesh.uvs.as_mut() {
                            uvs.push(uvs[i]);
                        }
                        *v = copy;
                    }
                }
            }
        }
    }
    for (n, &bad) in normals.iter_mut().zip(&bad) {
        if bad && unusable_normal(*n) {
            *n = Vec3::Z;
        }
    }
    corners
}
