//! glTF 2.0 (`.gltf` with external or embedded buffers, `.glb`) as one
//! mesh, with the file's cameras and punctual lights as data.
//!
//! The JSON is read into the gltf project's schema types (`gltf-json`);
//! its validation and the `gltf` crate's `Reader` are not used, since both
//! index arrays without checking them on some malformed files. Every index
//! followed here is checked, and every error names the file and a JSON
//! pointer (`/meshes/3/primitives/0/indices`). Buffers and accessors are
//! read in [`data`], materials converted in [`material`].
//!
//! Conventions are the OBJ reader's: counter-clockwise is front (a node
//! transform that mirrors flips the winding), uv v = 0 is the bottom row
//! (glTF's v = 0 is the top: v becomes 1 - v), and a mesh without normals
//! shades with its geometric normals.

mod cameras;
mod data;
mod material;
#[cfg(test)]
mod tests;

use super::assets::Assets;
use crate::error::{Error, Result};
use crate::geom::Mesh;
use cameras::{cameras, lights};
// For load.rs: `camera.from` and `[[light]] from`.
pub(super) use cameras::{GltfCamera, GltfLight, GltfLightKind};
use data::{check_alloc, err, packed, split_glb, Buffers};
use glam::{Mat3, Mat4, Quat, Vec2, Vec3};
use gltf_json as json;
use json::accessor::Type;
use json::mesh::{Mode, Semantic};
use json::validation::Checked;
use material::Materials;
use std::path::Path;

/// What a glTF file gives a scene: the meshes of the default scene's nodes
/// merged into one `Mesh` (each node's world transform applied), and its
/// placed cameras and punctual lights for the scene to use on request.
#[derive(Debug)]
pub(super) struct GltfModel {
    /// Every triangle of the scene's nodes, in the file's world space.
    pub mesh: Mesh,
    /// The cameras placed by nodes, in node order.
    pub cameras: Vec<GltfCamera>,
    /// The `KHR_lights_punctual` lights placed by nodes, in node order.
    pub lights: Vec<GltfLight>,
    /// Warnings about the file, each starting with its path; the caller
    /// prints them (as `warning: {text}`).
    pub warnings: Vec<String>,
    /// Primitives that are one emissive parallelogram (two triangles), as
    /// rect lights in the file's world space: what `lights_from_emissive`
    /// turns into lights.
    pub emissive_quads: Vec<EmissiveQuad>,
}

/// An emissive quad of a glTF file: a rect light in its world space.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct EmissiveQuad {
    /// The primitive, as a JSON pointer.
    pub at: String,
    /// Its two triangles' indices in [`GltfModel::mesh`].
    pub triangles: [usize; 2],
    /// Centre of the parallelogram.
    pub center: Vec3,
    /// Half-edges; `u × v` points to the front face's side.
    pub u: Vec3,
    /// See `u`.
    pub v: Vec3,
    /// `emissiveFactor` × `KHR_materials_emissive_strength`.
    pub radiance: Vec3,
    /// The material's `doubleSided`.
    pub two_sided: bool,
}

/// Extensions a file may require that penumbra reads.
const SUPPORTED_REQUIRED: &[&str] = &["KHR_lights_punctual", "KHR_mesh_quantization"];

/// Reads a glTF file (`.gltf` or `.glb`, told apart by content)
/// referenced from `from:line`.
///
/// With `material_override` (an inline material) every triangle gets it
/// and the file's materials and textures are not read. Otherwise triangles
/// get the file's materials (added to `assets`), or the default material.
/// Normals are kept when some primitive has them: a primitive without gets
/// its faces' geometric normals (the renderer's normals are all or none
/// per mesh, and these are what it would use). Degenerate triangles are
/// left for the loader, which drops them after the object's transform.
pub(super) fn load_gltf(
    path: &Path,
    from: &Path,
    line: usize,
    material_override: Option<u32>,
    assets: &mut Assets,
) -> Result<GltfModel> {
    let bytes = super::input::read(path).map_err(|e| {
        Error::file(
            from,
            Some(line),
            format!("cannot read glTF `{}`: {e}", path.display()),
        )
    })?;
    let (json_bytes, bin) = match bytes.starts_with(b"glTF") {
        true => split_glb(path, &bytes)?,
        false => (bytes.as_slice(), None),
    };
    let root = parse_json(path, json_bytes)?;
    check_required_extensions(path, &root)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut bufs = Buffers::new(path, dir, &root, bin);
    let placed = walk_scene(path, &root)?;
    let plan = plan(path, &root, &placed)?;
    if plan.triangle_primitives == 0 {
        let why = match plan.skipped.first() {
            Some(at) => {
                format!("only points and lines (first at {at}/mode), which are not surfaces")
            }
            None => "no mesh primitives in its scene".into(),
        };
        return Err(Error::file(
            from,
            Some(line),
            format!("glTF `{}` has {why}: nothing to render", path.display()),
        ));
    }
    let mut materials = Materials::new(material_override);
    let mut warnings = Vec::new();
    let mut emissive = Vec::new();
    let mesh = build_mesh(
        &mut bufs,
        &placed,
        &mut materials,
        assets,
        &mut warnings,
        &mut emissive,
    )?;
    let emissive_quads = emissive_quads(&mesh, &emissive);
    if let Some(first) = plan.skipped.first() {
        warnings.push(format!(
            "{}: {} points or lines primitive(s) skipped, the first at {first}/mode \
             (penumbra renders triangles only)",
            path.display(),
            plan.skipped.len()
        ));
    }
    if let Some(w) = ignored_warning(path, &root, &plan, &materials) {
        warnings.push(w);
    }
    Ok(GltfModel {
        mesh,
        cameras: cameras(path, &root, &placed)?,
        lights: lights(path, &root, &placed)?,
        warnings,
        emissive_quads,
    })
}

/// An emissive triangle primitive: its pointer, its triangles' range in
/// the mesh, its radiance and whether it is two-sided.
type EmissivePrimitive = (String, std::ops::Range<usize>, Vec3, bool);

/// The emission of material `m`: `emissiveFactor` times the
/// `KHR_materials_emissive_strength` factor, with `doubleSided`; `None`
/// for a material that does not emit.
fn emission(root: &json::Root, m: Option<usize>) -> Option<(Vec3, bool)> {
    let m = root.materials.get(m?)?;
    let strength = (m.extensions.as_ref())
        .and_then(|e| e.others.get("KHR_materials_emissive_strength"))
        .and_then(|e| e.get("emissiveStrength")?.as_f64())
        .unwrap_or(1.0) as f32;
    let radiance = Vec3::from(m.emissive_factor.0) * strength;
    (radiance.is_finite() && radiance.max_element() > 0.0 && radiance.min_element() >= 0.0)
        .then_some((radiance, m.double_sided))
}

/// The emissive primitives that are one parallelogram: two triangles over
/// four corners, opposite corners summing alike (to a part in 10⁵ of the
/// quad's size).
fn emissive_quads(mesh: &Mesh, emissive: &[EmissivePrimitive]) -> Vec<EmissiveQuad> {
    let mut quads = Vec::new();
    for (at, range, radiance, two_sided) in emissive {
        if range.len() != 2 {
            continue;
        }
        let (t0, t1) = (range.start, range.start + 1);
        let [a, b, c] = mesh.corners(t0);
        // The second triangle's corner that is not the first's.
        let Some(d) = mesh
            .corners(t1)
            .into_iter()
            .find(|p| ![a, b, c].contains(p))
        else {
            continue;
        };
        // Opposite corners: the pair whose midpoint equals the other pair's.
        let pairs = [((a, b), (c, d)), ((a, c), (b, d)), ((b, c), (a, d))];
        let size = (a - b).length().max((a - c).length()).max((b - c).length());
        let Some(((p, q), (r, s))) = pairs
            .into_iter()
            .find(|((p, q), (r, s))| ((*p + *q) - (*r + *s)).length() <= 1e-5 * size)
        else {
            continue;
        };
        let center = (p + q + r + s) * 0.25;
        // Half-edges from the centre to the midpoints of two sides.
        let (mut u, v) = ((p + r) * 0.5 - center, (p + s) * 0.5 - center);
        let front = (b - a).cross(c - a);
        if u.cross(v).dot(front) < 0.0 {
            u = -u;
        }
        if u.cross(v).length() <= 1e-6 * u.length() * v.length() {
            continue;
        }
        quads.push(EmissiveQuad {
            at: at.clone(),
            triangles: [t0, t1],
            center,
            u,
            v,
            radiance: *radiance,
            two_sided: *two_sided,
        });
    }
    quads
}

/// Parses the glTF JSON; errors give serde_json's line and column, and a
/// glTF 1.0 file is named as such.
fn parse_json(path: &Path, bytes: &[u8]) -> Result<json::Root> {
    // Some writers pad the GLB JSON chunk with zeros instead of spaces.
    let end = bytes.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    let bytes = &bytes[..end];
    let bytes = bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(bytes);
    serde_json::from_slice(bytes).map_err(|e| {
        let version = serde_json::from_slice::<serde_json::Value>(bytes)
            .ok()
            .and_then(|v| v.pointer("/asset/version")?.as_str().map(String::from));
        match version {
            Some(v) if !v.starts_with('2') => err(
                path,
                "/asset/version",
                format!("glTF {v}; penumbra reads glTF 2.0"),
            ),
            // serde_json counts lines from 1; 0 is an error not in the text.
            _ => Error::file(
                path,
                (e.line() > 0).then_some(e.line()),
                format!("not valid glTF 2.0 JSON: {e}"),
            ),
        }
    })
}

/// Refuses a file that requires an extension penumbra does not read,
/// naming it.
fn check_required_extensions(path: &Path, root: &json::Root) -> Result<()> {
    for (i, name) in root.extensions_required.iter().enumerate() {
        if SUPPORTED_REQUIRED.contains(&name.as_str()) {
            continue;
        }
        let what = match name.as_str() {
            "KHR_draco_mesh_compression" => " (Draco mesh compression)",
            "EXT_meshopt_compression" | "KHR_meshopt_compression" => " (meshopt compression)",
            _ => "",
        };
        return Err(err(
            path,
            &format!("/extensionsRequired/{i}"),
            format!(
                "the file requires extension {name}{what}, which penumbra does not read; \
                 export the model without it"
            ),
        ));
    }
    Ok(())
}

/// A node of the scene with its world transform.
struct Placed {
    /// Index in `/nodes`.
    node: usize,
    /// Parent chain of transforms, applied.
    world: Mat4,
}

/// The nodes of the default scene (else the first scene; else every node
/// that is no node's child) in depth-first order, with world transforms.
fn walk_scene(path: &Path, root: &json::Root) -> Result<Vec<Placed>> {
    let nodes = &root.nodes;
    let starts: Vec<(usize, String)> = match (root.scene, root.scenes.is_empty()) {
        (s, false) | (s @ Some(_), true) => {
            let s = s.map_or(0, |s| s.value());
            let Some(scene) = root.scenes.get(s) else {
                return Err(err(
                    path,
                    "/scene",
                    format!(
                        "scene {s} does not exist (the file has {})",
                        root.scenes.len()
                    ),
                ));
            };
            let at = |k| format!("/scenes/{s}/nodes/{k}");
            scene
                .nodes
                .iter()
                .enumerate()
                .map(|(k, n)| (n.value(), at(k)))
                .collect()
        }
        (None, true) => {
            let mut child = vec![false; nodes.len()];
            for c in nodes.iter().flat_map(|n| n.children.iter().flatten()) {
                if let Some(flag) = child.get_mut(c.value()) {
                    *flag = true;
                }
            }
            (0..nodes.len())
                .filter(|&n| !child[n])
                .map(|n| (n, format!("/nodes/{n}")))
                .collect()
        }
    };
    let mut seen = vec![false; nodes.len()];
    let mut placed = Vec::new();
    let mut stack: Vec<(usize, Mat4, String)> = starts
        .into_iter()
        .rev()
        .map(|(n, at)| (n, Mat4::IDENTITY, at))
        .collect();
    while let Some((n, parent, at)) = stack.pop() {
        let Some(node) = nodes.get(n) else {
            return Err(err(
                path,
                &at,
                format!("node {n} does not exist (the file has {})", nodes.len()),
            ));
        };
        if std::mem::replace(&mut seen[n], true) {
            return Err(err(
                path,
                &at,
                format!(
                    "node {n} appears twice in the scene (a node has at most one parent, \
                     and the hierarchy no cycles)"
                ),
            ));
        }
        let world = parent * local_transform(path, n, node)?;
        placed.push(Placed { node: n, world });
        let children = node.children.as_deref().unwrap_or_default();
        for (k, c) in children.iter().enumerate().rev() {
            stack.push((c.value(), world, format!("/nodes/{n}/children/{k}")));
        }
    }
    Ok(placed)
}

/// Node `n`'s transform: its `matrix`, else translation × rotation × scale.
fn local_transform(path: &Path, n: usize, node: &json::Node) -> Result<Mat4> {
    let finite = |field: &str, v: &[f32]| match v.iter().all(|x| x.is_finite()) {
        true => Ok(()),
        false => Err(err(
            path,
            &format!("/nodes/{n}/{field}"),
            "numbers must be finite",
        )),
    };
    if let Some(m) = &node.matrix {
        finite("matrix", m)?;
        return Ok(Mat4::from_cols_array(m));
    }
    let t = node.translation.unwrap_or([0.0; 3]);
    let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
    let s = node.scale.unwrap_or([1.0; 3]);
    finite("translation", &t)?;
    finite("rotation", &r)?;
    finite("scale", &s)?;
    // Exporters round quaternions: normalised here, as viewers do.
    let q = glam::Vec4::from_array(r).try_normalize().ok_or_else(|| {
        err(
            path,
            &format!("/nodes/{n}/rotation"),
            "a zero quaternion is no rotation",
        )
    })?;
    let q = Quat::from_vec4(q);
    Ok(Mat4::from_scale_rotation_translation(
        Vec3::from(s),
        q,
        Vec3::from(t),
    ))
}

/// What the scene's primitives add up to, counted before anything is read.
struct Plan {
    /// Primitives of triangles (modes 4, 5, 6), over all node instances.
    triangle_primitives: usize,
    /// Pointers of the points and lines primitives skipped.
    skipped: Vec<String>,
    /// Primitives with morph targets.
    morph_targets: usize,
    /// Primitives with vertex colours.
    vertex_colors: usize,
}

/// True for the triangle modes (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN).
fn is_triangles(mode: Checked<Mode>) -> bool {
    matches!(
        mode,
        Checked::Valid(Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)
    )
}

/// Triangles of `n` indices in `mode`.
fn triangle_count(mode: Mode, n: u64) -> u64 {
    match mode {
        Mode::Triangles => n / 3,
        _ => n.saturating_sub(2),
    }
}

/// Counts the scene's primitives and refuses a mesh that cannot fit in
/// memory (a mesh instanced by many nodes counts each time) or in `u32`
/// indices, before anything is allocated.
fn plan(path: &Path, root: &json::Root, placed: &[Placed]) -> Result<Plan> {
    let mut plan = Plan {
        triangle_primitives: 0,
        skipped: Vec::new(),
        morph_targets: 0,
        vertex_colors: 0,
    };
    let (mut vertices, mut triangles) = (0u64, 0u64);
    let count = |index: usize, used_at: &str| match root.accessors.get(index) {
        Some(a) => Ok(a.count.0),
        None => Err(err(
            path,
            used_at,
            format!(
                "accessor {index} does not exist (the file has {})",
                root.accessors.len()
            ),
        )),
    };
    for p in placed {
        let Some((m, mesh)) = node_mesh(path, root, p.node)? else {
            continue;
        };
        for (j, prim) in mesh.primitives.iter().enumerate() {
            let at = format!("/meshes/{m}/primitives/{j}");
            let mode = match prim.mode {
                Checked::Valid(mode) => mode,
                Checked::Invalid => return Err(err(path, &format!("{at}/mode"), "invalid")),
            };
            if !is_triangles(prim.mode) {
                plan.skipped.push(at);
                continue;
            }
            plan.triangle_primitives += 1;
            plan.morph_targets += usize::from(prim.targets.is_some());
            plan.vertex_colors += usize::from(
                prim.attributes
                    .contains_key(&Checked::Valid(Semantic::Colors(0))),
            );
            let Some(position) = prim.attributes.get(&Checked::Valid(Semantic::Positions)) else {
                return Err(err(
                    path,
                    &format!("{at}/attributes"),
                    "no POSITION attribute",
                ));
            };
            let position_at = format!("{at}/attributes/POSITION");
            let n = count(position.value(), &position_at)?;
            let corners = match prim.indices {
                Some(i) => count(i.value(), &format!("{at}/indices"))?,
                None => n,
            };
            vertices = vertices.saturating_add(n);
            triangles = triangles.saturating_add(triangle_count(mode, corners));
        }
    }
    if vertices > u64::from(u32::MAX) {
        return Err(Error::file(
            path,
            None,
            format!("{vertices} vertices over all nodes: more than 2^32"),
        ));
    }
    // Positions, normals and uvs per vertex; corners and material per
    // triangle.
    let bytes = vertices
        .saturating_mul(32)
        .saturating_add(triangles.saturating_mul(16));
    let what = format!("{triangles} triangles and {vertices} vertices over all nodes");
    check_alloc(path, "/nodes", &what, bytes)?;
    Ok(plan)
}

/// The mesh of node `n` (with its index), if it has one.
fn node_mesh<'a>(
    path: &Path,
    root: &'a json::Root,
    n: usize,
) -> Result<Option<(usize, &'a json::Mesh)>> {
    let Some(m) = root.nodes.get(n).and_then(|node| node.mesh) else {
        return Ok(None);
    };
    match root.meshes.get(m.value()) {
        Some(mesh) => Ok(Some((m.value(), mesh))),
        None => Err(err(
            path,
            &format!("/nodes/{n}/mesh"),
            format!(
                "mesh {} does not exist (the file has {})",
                m.value(),
                root.meshes.len()
            ),
        )),
    }
}

/// The mesh being built, with per-vertex arrays kept or dropped at the end.
#[derive(Default)]
struct Building {
    /// Positions, triangles and material ids.
    mesh: Mesh,
    /// Normals, zero where a primitive has none or an unusable one.
    normals: Vec<Vec3>,
    /// Uvs (our convention), zero where a primitive has none.
    uvs: Vec<Vec2>,
    /// Some primitive has normals.
    any_normals: bool,
    /// Some primitive has uvs.
    any_uvs: bool,
    /// Normals in the file that are zero or not finite.
    bad_normals: usize,
}

/// Reads every triangle primitive of the placed nodes into one mesh.
fn build_mesh(
    bufs: &mut Buffers,
    placed: &[Placed],
    materials: &mut Materials,
    assets: &mut Assets,
    warnings: &mut Vec<String>,
    emissive: &mut Vec<EmissivePrimitive>,
) -> Result<Mesh> {
    let (path, root) = (bufs.path, bufs.root);
    let mut b = Building::default();
    for p in placed {
        let Some((m, mesh)) = node_mesh(path, root, p.node)? else {
            continue;
        };
        for (j, prim) in mesh.primitives.iter().enumerate() {
            if !is_triangles(prim.mode) {
                continue;
            }
            let at = format!("/meshes/{m}/primitives/{j}");
            let material = prim.material.map(|i| i.value());
            let id = materials.id(bufs, material, &format!("{at}/material"), assets)?;
            let first = b.mesh.triangles.len();
            add_primitive(bufs, &mut b, prim, &at, p, id)?;
            if let Some((radiance, two_sided)) = emission(root, material) {
                emissive.push((at, first..b.mesh.triangles.len(), radiance, two_sided));
            }
        }
    }
    let Building {
        mut mesh,
        normals,
        uvs,
        any_normals,
        any_uvs,
        bad_normals,
    } = b;
    // As for OBJ: an inline material may be the textured one.
    let mut ids: Vec<u32> = mesh.material_ids.clone();
    ids.sort_unstable();
    ids.dedup();
    let textured = ids.iter().any(|&id| {
        assets
            .materials
            .get(id as usize)
            .is_some_and(|m| m.albedo_texture.is_some() || m.opacity_texture.is_some())
    });
    if textured && !any_uvs {
        warnings.push(format!(
            "{}: textured material on a mesh without texture coordinates; using uv (0, 0)",
            path.display()
        ));
    }
    if any_uvs || textured {
        mesh.uvs = Some(uvs);
    }
    if any_normals {
        mesh.normals = Some(normals);
        // Zero normals (primitives without, unusable ones) become their
        // faces' geometric normals, as for OBJ's zero `vn`.
        let corners = super::obj::replace_unusable_normals(&mut mesh);
        if bad_normals > 0 && corners > 0 {
            warnings.push(format!(
                "{}: {bad_normals} zero or non-finite normal(s); the triangle corners using \
                 them take their face's geometric normal",
                path.display()
            ));
        }
    }
    Ok(mesh)
}

/// Appends one triangle primitive (`at`) of the node `p` to `b`, with
/// scene material `material`.
fn add_primitive(
    bufs: &mut Buffers,
    b: &mut Building,
    prim: &json::mesh::Primitive,
    at: &str,
    p: &Placed,
    material: u32,
) -> Result<()> {
    let path = bufs.path;
    let Checked::Valid(mode) = prim.mode else {
        return Ok(());
    };
    let attribute = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|i| i.value());
    let Some(position) = attribute(Semantic::Positions) else {
        return Err(err(
            path,
            &format!("{at}/attributes"),
            "no POSITION attribute",
        ));
    };
    let positions = packed(bufs, position, &format!("{at}/attributes/POSITION"))?;
    positions.expect(path, Type::Vec3, "POSITION")?;
    let n = positions.count;
    // Within u32 by the plan.
    let base = b.mesh.positions.len() as u32;
    let linear = Mat3::from_mat4(p.world);
    for (k, xyz) in positions.floats().chunks_exact(3).enumerate() {
        let v = Vec3::from_slice(xyz);
        if !v.is_finite() {
            return Err(err(
                path,
                &positions.at,
                format!("POSITION element {k} is not finite ({at})"),
            ));
        }
        let w = p.world.transform_point3(v);
        if !w.is_finite() {
            return Err(err(
                path,
                &format!("/nodes/{}", p.node),
                format!("the node's transform takes vertex {k} of {at} beyond f32 range"),
            ));
        }
        b.mesh.positions.push(w);
    }
    let same_count = |what: &str, got: usize, acc_at: &str| match got == n {
        true => Ok(()),
        false => Err(err(
            path,
            acc_at,
            format!("{what} has {got} elements but POSITION has {n} ({at})"),
        )),
    };
    match attribute(Semantic::Normals) {
        Some(i) => {
            let normals = packed(bufs, i, &format!("{at}/attributes/NORMAL"))?;
            normals.expect(path, Type::Vec3, "NORMAL")?;
            same_count("NORMAL", normals.count, &normals.at)?;
            let to_world = linear.inverse().transpose();
            for xyz in normals.floats().chunks_exact(3) {
                let normal = (to_world * Vec3::from_slice(xyz)).normalize_or_zero();
                b.bad_normals += usize::from(normal == Vec3::ZERO);
                b.normals.push(normal);
            }
            b.any_normals = true;
        }
        None => b.normals.resize(b.mesh.positions.len(), Vec3::ZERO),
    }
    match attribute(Semantic::TexCoords(0)) {
        Some(i) => {
            let uvs = packed(bufs, i, &format!("{at}/attributes/TEXCOORD_0"))?;
            uvs.expect(path, Type::Vec2, "TEXCOORD_0")?;
            same_count("TEXCOORD_0", uvs.count, &uvs.at)?;
            // glTF's v = 0 is the image's top row, ours the bottom one.
            let floats = uvs.floats();
            b.uvs.extend(
                floats
                    .chunks_exact(2)
                    .map(|uv| Vec2::new(uv[0], 1.0 - uv[1])),
            );
            b.any_uvs = true;
        }
        None => b.uvs.resize(b.mesh.positions.len(), Vec2::ZERO),
    }
    let indices = match prim.indices {
        Some(i) => {
            let indices_at = format!("{at}/indices");
            let indices = packed(bufs, i.value(), &indices_at)?.indices(path)?;
            if let Some((k, &i)) = indices.iter().enumerate().find(|&(_, &i)| i as usize >= n) {
                return Err(err(
                    path,
                    &indices_at,
                    format!("index {i} (element {k}) is out of range: POSITION has {n} vertices"),
                ));
            }
            indices
        }
        // Within u32 by the plan.
        None => (0..n as u32).collect(),
    };
    if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
        let what = if prim.indices.is_some() {
            "indices"
        } else {
            "attributes/POSITION"
        };
        return Err(err(
            path,
            &format!("{at}/{what}"),
            format!(
                "{} corners is not a whole number of triangles",
                indices.len()
            ),
        ));
    }
    let mirror = linear.determinant() < 0.0;
    for mut tri in triangles(mode, &indices) {
        if mirror {
            // Keep counter-clockwise = front, as the loader does for a
            // mirroring object transform.
            tri.swap(1, 2);
        }
        b.mesh.triangles.push(tri.map(|i| base + i));
        b.mesh.material_ids.push(material);
    }
    Ok(())
}

/// The triangles of `indices` in `mode` (a triangle mode), wound as the
/// glTF specification draws them: a strip's odd triangles swap their last
/// two corners, a fan's turn around the first index.
fn triangles(mode: Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    let n = indices.len();
    match mode {
        Mode::TriangleStrip => (0..n.saturating_sub(2))
            .map(|i| match i % 2 {
                0 => [indices[i], indices[i + 1], indices[i + 2]],
                _ => [indices[i], indices[i + 2], indices[i + 1]],
            })
            .collect(),
        Mode::TriangleFan => (0..n.saturating_sub(2))
            .map(|i| [indices[i + 1], indices[i + 2], indices[0]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    }
}

/// The file's one warning about what penumbra does not model, if any.
fn ignored_warning(
    path: &Path,
    root: &json::Root,
    plan: &Plan,
    materials: &Materials,
) -> Option<String> {
    let mut items = materials.ignored.items();
    let mut add = |n: usize, what: &str| {
        if n > 0 {
            items.push(format!("{what} ({n})"));
        }
    };
    add(root.skins.len(), "skins");
    add(root.animations.len(), "animations");
    add(plan.morph_targets, "morph targets");
    add(plan.vertex_colors, "vertex colours");
    let mut extensions = materials.ignored.extensions.clone();
    extensions.extend(root.extensions_used.iter().cloned());
    items.extend(
        extensions
            .into_iter()
            .filter(|e| !SUPPORTED_REQUIRED.contains(&e.as_str())),
    );
    match items.is_empty() {
        true => None,
        false => Some(format!(
            "{}: not modelled by penumbra and ignored: {}",
            path.display(),
            items.join(", ")
        )),
    }
}
