//! OBJ/MTL loading through `tobj` (triangulated, single index).
//!
//! tobj reports errors without line numbers and panics or overflows on a
//! few malformed inputs (`Kd 0.5`, huge relative face indices), so every
//! file is first scanned here: each line tobj would read is checked (numbers
//! well-formed and finite, face indices in range, ...) and errors name the
//! file and line. The scan also rewrites the few lines tobj would misread
//! and blanks the ones we do not use, so tobj only ever sees valid input.

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

/// Reads a text file referenced from `from:line`. A missing or unreadable
/// file is an error at the reference; invalid UTF-8 one in the file itself.
fn read_text(path: &Path, what: &str, from: &Path, line: usize) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| {
        Error::file(
            from,
            Some(line),
            format!("cannot read {what} `{}`: {e}", path.display()),
        )
    })?;
    String::from_utf8(bytes).map_err(|e| {
        let bad = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..bad].iter().filter(|&&b| b == b'\n').count() + 1;
        Error::file(path, Some(line), "not valid UTF-8 text")
    })
}

/// Lines as tobj sees them (`BufRead::lines`: `\n` or `\r\n` ends a line),
/// with their 1-based number and byte range.
fn lines(text: &str) -> impl Iterator<Item = (usize, Range<usize>, &str)> {
    let mut start = 0;
    text.split('\n').enumerate().map(move |(i, raw)| {
        let range = start..start + raw.len();
        start = range.end + 1;
        (i + 1, range, raw.strip_suffix('\r').unwrap_or(raw))
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

/// What the OBJ scan learned: the text to hand to tobj and the `mtllib`
/// references in file order (tobj asks for them in that order).
struct ObjScan<'a> {
    text: Cow<'a, str>,
    mtllibs: Vec<(String, usize)>,
}

/// Element kinds a face index can refer to, as named in messages.
const KINDS: [&str; 3] = ["vertices", "texture coordinates", "normals"];

fn scan_obj<'a>(path: &Path, text: &'a str) -> Result<ObjScan<'a>> {
    let mut counts = [0i64; 3];
    // Largest absolute index per kind and its line: forward references are
    // legal in tobj, so they are checked against the totals at the end.
    let mut max_index = [(0i64, 0usize); 3];
    let mut mtllibs = Vec::new();
    let mut edits = Edits::default();
    for (ln, range, line) in lines(text) {
        let err = |msg: String| Error::file(path, Some(ln), msg);
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "v" | "vt" | "vn" => {
                let nums = numbers(words, err)?;
                let (kind, ok) = match keyword {
                    // x y z, x y z w (w ≠ 0: tobj divides by it), x y z r g b
                    "v" => (
                        0,
                        matches!(nums.len(), 3 | 6) || (nums.len() == 4 && nums[3] != 0.0),
                    ),
                    "vt" => (1, matches!(nums.len(), 2 | 3)),
                    _ => (2, nums.len() == 3 && nums.iter().any(|&x| x != 0.0)),
                };
                if !ok {
                    return Err(err(format!("malformed `{keyword}` line (wrong count of numbers, zero w or zero normal)")));
                }
                counts[kind] += 1;
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
                        } else if x > max_index[kind].0 {
                            max_index[kind] = (x, ln);
                        }
                    }
                }
                if corners == 0 {
                    return Err(err("face without vertices".into()));
                }
            }
            // tobj would triangulate polylines; they are not surfaces.
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
    for kind in 0..3 {
        let (x, ln) = max_index[kind];
        if x > counts[kind] {
            return Err(Error::file(
                path,
                Some(ln),
                format!(
                    "face index {x} out of range: the file has {} {}",
                    counts[kind], KINDS[kind]
                ),
            ));
        }
    }
    Ok(ObjScan {
        text: edits.apply(text),
        mtllibs,
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
    for (ln, range, line) in lines(text) {
        let err = |msg: String| Error::file(path, Some(ln), msg);
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
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

/// The file name of a `map_*` statement: options (`-bm 0.5 file.png`) are
/// skipped by taking the last word, and Windows separators are accepted.
fn texture_file(spec: &str) -> String {
    let name = if spec.starts_with('-') {
        spec.split_whitespace().last().unwrap_or(spec)
    } else {
        spec
    };
    name.replace('\\', "/")
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
    let mut texture = |spec: &Option<String>, kind, line| -> Result<Option<usize>> {
        spec.as_deref()
            .map(|s| assets.texture(&dir.join(texture_file(s)), kind, mtl_path, line))
            .transpose()
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
    let text = read_text(path, "OBJ", from, line)?;
    let scan = scan_obj(path, &text)?;
    let dir = path.parent().unwrap_or(Path::new(""));

    let next_mtllib = Cell::new(0);
    let mtl_error: RefCell<Option<Error>> = RefCell::new(None);
    let loaded: RefCell<Vec<LoadedMtl>> = RefCell::new(Vec::new());
    let load_mtl = |_: &Path| -> tobj::MTLLoadResult {
        let index = next_mtllib.replace(next_mtllib.get() + 1);
        let (Some((name, ln)), None) = (scan.mtllibs.get(index), material_override) else {
            return Ok(Default::default());
        };
        let mtl_path = dir.join(name);
        let result = read_text(&mtl_path, "MTL", path, *ln).and_then(|t| {
            let (text, lines) = scan_mtl(&mtl_path, &t)?;
            let parsed = tobj::load_mtl_buf(&mut text.as_bytes())
                .map_err(|e| Error::file(&mtl_path, None, format!("MTL parse error: {e}")))?;
            Ok((parsed, lines))
        });
        match result {
            Ok((parsed, materials)) => {
                loaded.borrow_mut().push(LoadedMtl {
                    path: mtl_path,
                    materials,
                });
                Ok(parsed)
            }
            Err(e) => {
                mtl_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    // Other fields exist with tobj's optional features (merging, reordering).
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let parsed = tobj::load_obj_buf(&mut scan.text.as_bytes(), &options, load_mtl);
    if let Some(e) = mtl_error.take() {
        return Err(e);
    }
    let (models, materials) =
        parsed.map_err(|e| Error::file(path, None, format!("OBJ parse error: {e}")))?;
    let materials = materials.unwrap_or_default();
    let loaded = loaded.into_inner();

    // tobj material index → scene material index, converted on first use so
    // that unused materials cannot fail on their textures.
    let mut ids: HashMap<usize, u32> = HashMap::new();
    let mut material_id = |tobj_id: Option<usize>, assets: &mut Assets| -> Result<u32> {
        if let Some(id) = material_override {
            return Ok(id);
        }
        let Some(m) = tobj_id.and_then(|i| materials.get(i).map(|m| (i, m))) else {
            return Ok(DEFAULT_MATERIAL);
        };
        if let Some(&id) = ids.get(&m.0) {
            return Ok(id);
        }
        // tobj appends each MTL file's materials in load order.
        let mut i = m.0;
        let source = loaded.iter().find_map(|l| match l.materials.get(i) {
            Some(lines) => Some((l.path.as_path(), lines)),
            None => {
                i -= l.materials.len();
                None
            }
        });
        let fallback = MtlLines::default();
        let (mtl_path, lines) = source.unwrap_or((Path::new(""), &fallback));
        let material = convert_material(m.1, mtl_path, lines, assets)?;
        let id = assets.material(material)?;
        ids.insert(m.0, id);
        Ok(id)
    };

    let mut mesh = Mesh::default();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let (mut all_normals, mut any_uvs) = (true, false);
    let too_big = || Error::file(path, None, "more than 2^32 vertices");
    for model in &models {
        let m = &model.mesh;
        let n = m.positions.len() / 3;
        let base = u32::try_from(mesh.positions.len()).map_err(|_| too_big())?;
        mesh.positions
            .extend(m.positions.chunks_exact(3).map(Vec3::from_slice));
        // tobj leaves out the normal (uv) of a corner that has none, so the
        // arrays only line up when every vertex has one.
        if m.normals.len() == 3 * n {
            normals.extend(m.normals.chunks_exact(3).map(Vec3::from_slice));
        } else {
            all_normals = false;
        }
        if m.texcoords.len() == 2 * n {
            any_uvs |= n > 0;
            uvs.extend(m.texcoords.chunks_exact(2).map(Vec2::from_slice));
        } else {
            uvs.resize(mesh.positions.len(), Vec2::ZERO);
        }
        let material = material_id(m.material_id, assets)?;
        for t in m.indices.chunks_exact(3) {
            let corner = |i: u32| base.checked_add(i).ok_or_else(too_big);
            mesh.triangles
                .push([corner(t[0])?, corner(t[1])?, corner(t[2])?]);
            mesh.material_ids.push(material);
        }
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
    Ok(mesh)
}
