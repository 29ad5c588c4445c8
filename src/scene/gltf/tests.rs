//! glTF files built in the tests (JSON and bytes), read back.

use super::*;
use crate::scene::{Material, TextureData};
use serde_json::{json, Value};
use std::path::PathBuf;

/// An empty directory of its own for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penumbra-gltf-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A glTF document under construction: JSON plus one binary buffer.
struct Doc {
    json: Value,
    bin: Vec<u8>,
}

impl Doc {
    fn new() -> Self {
        Doc {
            json: json!({
                "asset": {"version": "2.0"},
                "scene": 0,
                "scenes": [{"nodes": []}],
            }),
            bin: Vec::new(),
        }
    }

    /// Appends `v` to the top-level array `key`, returning its index.
    fn push(&mut self, key: &str, v: Value) -> usize {
        let array = self.json[key].as_array_mut();
        match array {
            Some(a) => {
                a.push(v);
                a.len() - 1
            }
            None => {
                self.json[key] = json!([v]);
                0
            }
        }
    }

    /// A buffer view of `bytes` (4-byte aligned in the buffer).
    fn view(&mut self, bytes: &[u8], stride: Option<usize>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        let mut v = json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()});
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        self.push("bufferViews", v)
    }

    /// A float accessor of `ty` ("VEC3", ...) over `data`.
    fn floats(&mut self, data: &[f32], ty: &str) -> usize {
        let per = match ty {
            "VEC2" => 2,
            "VEC3" => 3,
            _ => 1,
        };
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        self.push(
            "accessors",
            json!({"bufferView": view, "componentType": 5126, "count": data.len() / per, "type": ty}),
        )
    }

    /// An unsigned short index accessor.
    fn indices(&mut self, data: &[u16]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        self.push(
            "accessors",
            json!({"bufferView": view, "componentType": 5123, "count": data.len(), "type": "SCALAR"}),
        )
    }

    /// A node with `fields`, at the root of the scene.
    fn root_node(&mut self, fields: Value) -> usize {
        let n = self.push("nodes", fields);
        self.json["scenes"][0]["nodes"]
            .as_array_mut()
            .unwrap()
            .push(json!(n));
        n
    }

    /// A mesh of one primitive `prim`, placed by a root node.
    fn mesh_node(&mut self, prim: Value) -> usize {
        let m = self.push("meshes", json!({"primitives": [prim]}));
        self.root_node(json!({"mesh": m}))
    }

    /// The JSON with buffer 0 given as `buffer`.
    fn json_with(&self, buffer: Value) -> Value {
        let mut j = self.json.clone();
        if !self.bin.is_empty() {
            j["buffers"] = json!([buffer]);
        }
        j
    }

    /// `.gltf` text with the buffer as a base64 data URI.
    fn data_uri(&self) -> Vec<u8> {
        use base64::Engine;
        let b64 = base64::engine::general_purpose::STANDARD.encode(&self.bin);
        let uri = format!("data:application/octet-stream;base64,{b64}");
        serde_json::to_vec(&self.json_with(json!({"byteLength": self.bin.len(), "uri": uri})))
            .unwrap()
    }

    /// `.gltf` text with the buffer in `name` (to be written beside it).
    fn external(&self, name: &str) -> Vec<u8> {
        let buffer = json!({"byteLength": self.bin.len(), "uri": name});
        serde_json::to_vec(&self.json_with(buffer)).unwrap()
    }

    /// The GLB file.
    fn glb(&self) -> Vec<u8> {
        glb(
            &serde_json::to_vec(&self.json_with(json!({"byteLength": self.bin.len()}))).unwrap(),
            Some(&self.bin),
        )
    }

    /// Writes the data-URI form as `name` in a scratch directory.
    fn write(&self, test: &str) -> PathBuf {
        let path = scratch(test).join("model.gltf");
        std::fs::write(&path, self.data_uri()).unwrap();
        path
    }
}

/// A GLB of `json` and `bin` chunks, padded as the format asks.
fn glb(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let pad = |v: &mut Vec<u8>, with: u8| {
        while !v.len().is_multiple_of(4) {
            v.push(with);
        }
    };
    let mut j = json.to_vec();
    pad(&mut j, b' ');
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend([0; 4]);
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&j);
    if let Some(bin) = bin {
        let mut b = bin.to_vec();
        pad(&mut b, 0);
        out.extend((b.len() as u32).to_le_bytes());
        out.extend(b"BIN\0");
        out.extend(&b);
    }
    let len = (out.len() as u32).to_le_bytes();
    out[8..12].copy_from_slice(&len);
    out
}

/// Loads `path` as a scene's line 7 would.
fn load_into(path: &Path, assets: &mut Assets) -> Result<GltfModel> {
    load_gltf(path, Path::new("scene.toml"), 7, None, assets)
}

fn load(path: &Path) -> Result<GltfModel> {
    load_into(path, &mut Assets::new())
}

/// The error message of loading `path`.
fn error(path: &Path) -> String {
    match load(path) {
        Ok(_) => panic!("{} loaded", path.display()),
        Err(e) => e.to_string(),
    }
}

/// A unit right triangle in z = 0, counter-clockwise seen from +z.
const TRIANGLE: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// One triangle, non-indexed.
fn triangle_doc() -> Doc {
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    d.mesh_node(json!({"attributes": {"POSITION": p}}));
    d
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

#[test]
fn single_triangle_reads_as_written() {
    let path = triangle_doc().write("single");
    let model = load(&path).unwrap();
    let m = &model.mesh;
    assert_eq!(
        m.positions,
        TRIANGLE.chunks(3).map(Vec3::from_slice).collect::<Vec<_>>()
    );
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    assert_eq!(m.material_ids, vec![super::super::assets::DEFAULT_MATERIAL]);
    assert!(m.normals.is_none() && m.uvs.is_none());
    assert!(model.warnings.is_empty(), "{:?}", model.warnings);
}

#[test]
fn node_hierarchy_places_vertices() {
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let m = d.push(
        "meshes",
        json!({"primitives": [{"attributes": {"POSITION": p}}]}),
    );
    // Child: scale 2 in x, then move by (0, 0, 5), as a column-major matrix.
    let child = d.push(
        "nodes",
        json!({"mesh": m, "matrix": [2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1]}),
    );
    // Parent: rotate 90° about z (x → y), then translate (10, 0, 0).
    let s = std::f32::consts::FRAC_1_SQRT_2;
    d.root_node(json!({"children": [child], "translation": [10, 0, 0], "rotation": [0, 0, s, s]}));
    let model = load(&d.write("hierarchy")).unwrap();
    // v → parent(child(v)): (x, y, z) → (2x, y, z + 5) → (10 - y, 2x, z + 5).
    let want = [
        Vec3::new(10.0, 0.0, 5.0),
        Vec3::new(10.0, 2.0, 5.0),
        Vec3::new(9.0, 0.0, 5.0),
    ];
    for (got, want) in model.mesh.positions.iter().zip(want) {
        assert!(close(*got, want), "{got} vs {want}");
    }
    assert_eq!(model.mesh.triangles, vec![[0, 1, 2]]);
}

#[test]
fn mirroring_node_flips_winding_and_normals_use_inverse_transpose() {
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let n = d.floats(&[0.0, 0.0, 1.0].repeat(3), "VEC3");
    let m = d.push(
        "meshes",
        json!({"primitives": [{"attributes": {"POSITION": p, "NORMAL": n}}]}),
    );
    d.root_node(json!({"mesh": m, "scale": [-1, 1, 4]}));
    let model = load(&d.write("mirror")).unwrap();
    let mesh = &model.mesh;
    assert_eq!(mesh.triangles, vec![[0, 2, 1]]);
    // The face normal of the flipped triangle still points where the
    // file's normals do.
    assert!(mesh.face_normal(0).z > 0.0);
    let normals = mesh.normals.as_ref().unwrap();
    assert!(normals.iter().all(|&n| close(n, Vec3::Z)), "{normals:?}");

    // A shear: the normal is the inverse transpose's, not the matrix's.
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let n = d.floats(&[0.0, 1.0, 0.0].repeat(3), "VEC3");
    let m = d.push(
        "meshes",
        json!({"primitives": [{"attributes": {"POSITION": p, "NORMAL": n}}]}),
    );
    // x' = x, y' = x + y (column-major: column 0 is (1, 1, 0)).
    d.root_node(json!({"mesh": m, "matrix": [1,1,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}));
    let model = load(&d.write("shear")).unwrap();
    // The plane y = 0 goes to x = y, facing (-1, 1, 0) where it faced +y.
    let want = Vec3::new(-1.0, 1.0, 0.0).normalize();
    for &n in model.mesh.normals.as_ref().unwrap() {
        assert!(close(n, want), "{n}");
    }
}

#[test]
fn strips_and_fans_give_triangles_wound_as_the_spec_draws_them() {
    let square = [
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 2.0, 0.0, 0.0,
    ];
    for (mode, want) in [
        (5, vec![[0, 1, 2], [1, 3, 2], [2, 3, 4]]),
        (6, vec![[1, 2, 0], [2, 3, 0], [3, 4, 0]]),
    ] {
        let mut d = Doc::new();
        let p = d.floats(&square, "VEC3");
        d.mesh_node(json!({"attributes": {"POSITION": p}, "mode": mode}));
        let model = load(&d.write(&format!("mode{mode}"))).unwrap();
        assert_eq!(model.mesh.triangles, want, "mode {mode}");
    }
    // A strip over an index list: the indices are what is stripped.
    let mut d = Doc::new();
    let p = d.floats(&square, "VEC3");
    let i = d.indices(&[4, 3, 2, 1]);
    d.mesh_node(json!({"attributes": {"POSITION": p}, "indices": i, "mode": 5}));
    let model = load(&d.write("strip-indexed")).unwrap();
    assert_eq!(model.mesh.triangles, vec![[4, 3, 2], [3, 1, 2]]);
    // Every strip triangle of a flat strip faces the same way.
    let mut d = Doc::new();
    let p = d.floats(&square[..12], "VEC3");
    d.mesh_node(json!({"attributes": {"POSITION": p}, "mode": 5}));
    let mesh = load(&d.write("strip-facing")).unwrap().mesh;
    assert!((0..2).all(|t| mesh.face_normal(t).z > 0.0));
}

#[test]
fn sparse_accessor_overrides_elements() {
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let idx = d.view(&[2u8, 0, 0, 0], None);
    let values: Vec<u8> = [5.0f32, 6.0, 7.0]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let vals = d.view(&values, None);
    d.json["accessors"][p]["sparse"] = json!({
        "count": 1,
        "indices": {"bufferView": idx, "componentType": 5121},
        "values": {"bufferView": vals},
    });
    d.mesh_node(json!({"attributes": {"POSITION": p}}));
    let mesh = load(&d.write("sparse")).unwrap().mesh;
    assert_eq!(mesh.positions[2], Vec3::new(5.0, 6.0, 7.0));
    assert_eq!(mesh.positions[1], Vec3::X);

    // Without a bufferView: zeros, then the substitutions.
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    d.json["accessors"][p]
        .as_object_mut()
        .unwrap()
        .remove("bufferView");
    let idx = d.view(&[1u8, 0, 0, 0], None);
    let vals = d.view(&values, None);
    d.json["accessors"][p]["sparse"] = json!({
        "count": 1,
        "indices": {"bufferView": idx, "componentType": 5121},
        "values": {"bufferView": vals},
    });
    d.mesh_node(json!({"attributes": {"POSITION": p}}));
    let mesh = load(&d.write("sparse-zero")).unwrap().mesh;
    assert_eq!(
        mesh.positions,
        vec![Vec3::ZERO, Vec3::new(5.0, 6.0, 7.0), Vec3::ZERO]
    );

    // An index past the count is named.
    d.json["accessors"][p]["sparse"]["count"] = json!(1);
    let idx = d.view(&[9u8, 0, 0, 0], None);
    d.json["accessors"][p]["sparse"]["indices"]["bufferView"] = json!(idx);
    let msg = error(&d.write("sparse-bad"));
    assert!(
        msg.contains("/accessors/0/sparse/indices") && msg.contains("index 9"),
        "{msg}"
    );
}

#[test]
fn uvs_flip_to_bottom_row_convention_and_normalized_integers_read() {
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let t = d.floats(&[0.0, 0.0, 1.0, 0.25, 0.5, 1.0], "VEC2");
    d.mesh_node(json!({"attributes": {"POSITION": p, "TEXCOORD_0": t}}));
    let mesh = load(&d.write("uv")).unwrap().mesh;
    assert_eq!(
        mesh.uvs.unwrap(),
        vec![
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 0.75),
            Vec2::new(0.5, 0.0)
        ]
    );

    // Normalized unsigned bytes with a byte stride of 4 (padding).
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let v = d.view(&[0, 255, 9, 9, 255, 0, 9, 9, 51, 102, 9, 9], Some(4));
    let t = d.push(
        "accessors",
        json!({"bufferView": v, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC2"}),
    );
    d.mesh_node(json!({"attributes": {"POSITION": p, "TEXCOORD_0": t}}));
    let uvs = load(&d.write("uv-u8")).unwrap().mesh.uvs.unwrap();
    assert_eq!(uvs[0], Vec2::new(0.0, 0.0));
    assert_eq!(uvs[1], Vec2::new(1.0, 1.0));
    assert!((uvs[2] - Vec2::new(0.2, 0.6)).abs().max_element() < 1e-6);
}

#[test]
fn primitives_without_normals_get_face_normals_when_others_have_them() {
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let n = d.floats(&[0.0, 0.6, 0.8].repeat(3), "VEC3");
    // The second triangle faces -z (clockwise seen from +z).
    let q = d.floats(&[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.0, 1.0], "VEC3");
    d.push(
        "meshes",
        json!({"primitives": [
            {"attributes": {"POSITION": p, "NORMAL": n}},
            {"attributes": {"POSITION": q}},
        ]}),
    );
    d.root_node(json!({"mesh": 0}));
    let model = load(&d.write("mixed-normals")).unwrap();
    let normals = model.mesh.normals.unwrap();
    assert_eq!(normals.len(), 6);
    assert!(normals[..3]
        .iter()
        .all(|&n| close(n, Vec3::new(0.0, 0.6, 0.8))));
    assert!(
        normals[3..].iter().all(|&n| close(n, Vec3::NEG_Z)),
        "{normals:?}"
    );
    // Primitives without normals are the normal case: no warning.
    assert!(model.warnings.is_empty(), "{:?}", model.warnings);
}

/// A 2 × 1 RGBA PNG: left texel alpha 255, right texel alpha 64.
fn rgba_png() -> Vec<u8> {
    let img = image::RgbaImage::from_raw(2, 1, vec![255, 0, 0, 255, 0, 255, 0, 64]).unwrap();
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .unwrap();
    bytes
}

/// The scene material of a one-triangle file with material `material`
/// whose base colour texture (if `textured`) is [`rgba_png`].
fn material_of(test: &str, material: Value, textured: bool) -> (Material, Assets) {
    let mut d = triangle_doc();
    d.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    let mut material = material;
    if textured {
        let png = rgba_png();
        let v = d.view(&png, None);
        d.push("images", json!({"bufferView": v, "mimeType": "image/png"}));
        d.push("textures", json!({"source": 0}));
        material["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
    }
    d.push("materials", material);
    let mut assets = Assets::new();
    let model = load_into(&d.write(test), &mut assets).unwrap();
    let id = model.mesh.material_ids[0] as usize;
    (assets.materials[id].clone(), assets)
}

fn scalars(assets: &Assets, t: Option<usize>) -> Vec<f32> {
    match &assets.textures[t.expect("an opacity texture")].data {
        TextureData::Scalar(s) => s.clone(),
        other => panic!("{other:?}"),
    }
}

#[test]
fn alpha_modes_give_the_opacity_model() {
    let base = |mode: &str, a: f32| json!({"alphaMode": mode, "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1.0, a], "metallicFactor": 0.0}, "doubleSided": true});
    let (m, _) = material_of("opaque", base("OPAQUE", 0.3), false);
    assert_eq!(
        (m.albedo, m.opacity, m.opacity_texture),
        (Vec3::new(0.5, 0.25, 1.0), 1.0, None)
    );

    let (m, _) = material_of("blend", base("BLEND", 0.3), false);
    assert_eq!((m.opacity, m.opacity_texture), (0.3, None));
    let (m, assets) = material_of("blend-tex", base("BLEND", 0.5), true);
    assert_eq!(m.opacity, 0.5);
    let alpha = scalars(&assets, m.opacity_texture);
    assert_eq!(alpha.len(), 2);
    assert!(
        alpha[0] == 1.0 && (alpha[1] - 64.0 / 255.0).abs() < 1e-6,
        "{alpha:?}"
    );

    // MASK without a texture: the factor against the cutoff.
    let (m, _) = material_of("mask-on", base("MASK", 0.5), false);
    assert_eq!((m.opacity, m.opacity_texture), (1.0, None));
    let (m, _) = material_of("mask-off", base("MASK", 0.49), false);
    assert_eq!((m.opacity, m.opacity_texture), (0.0, None));
    // MASK with a texture: alpha × factor thresholded (0.25 × 0.9 < 0.5).
    let mut mask = base("MASK", 0.9);
    mask["alphaCutoff"] = json!(0.5);
    let (m, assets) = material_of("mask-tex", mask, true);
    assert_eq!(m.opacity, 1.0);
    assert_eq!(scalars(&assets, m.opacity_texture), vec![1.0, 0.0]);
    // The albedo texture is the image, sRGB decoded.
    let albedo = &assets.textures[m.albedo_texture.unwrap()];
    assert_eq!(albedo.lookup_rgb(Vec2::new(0.25, 0.5)), Vec3::X);
}

#[test]
fn ignored_features_are_named_in_one_warning() {
    let mut d = triangle_doc();
    d.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    d.push(
        "materials",
        json!({"normalTexture": {"index": 0}, "emissiveFactor": [1, 1, 1],
               "extensions": {"KHR_materials_transmission": {}}}),
    );
    d.json["extensionsUsed"] = json!(["KHR_materials_transmission", "KHR_lights_punctual"]);
    d.json["animations"] = json!([]);
    let model = load(&d.write("ignored")).unwrap();
    assert_eq!(model.warnings.len(), 1, "{:?}", model.warnings);
    let w = &model.warnings[0];
    for part in [
        "model.gltf: not modelled by penumbra and ignored:",
        "metallic-roughness (1 material)",
        "normal maps (1 material)",
        "emission (1 material)",
        "doubleSided: false",
        "KHR_materials_transmission",
    ] {
        assert!(w.contains(part), "{part} not in {w}");
    }
    assert!(!w.contains("KHR_lights_punctual"), "{w}");
}

#[test]
fn glb_data_uri_and_external_bin_give_identical_meshes() {
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let n = d.floats(&[0.0, 0.0, 1.0].repeat(3), "VEC3");
    let t = d.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
    let i = d.indices(&[0, 1, 2, 2, 1, 0]);
    d.mesh_node(json!({"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": t}, "indices": i}));
    let dir = scratch("three-forms");
    std::fs::write(dir.join("a.glb"), d.glb()).unwrap();
    std::fs::write(dir.join("b.gltf"), d.data_uri()).unwrap();
    std::fs::write(dir.join("c.gltf"), d.external("c%20data.bin")).unwrap();
    std::fs::write(dir.join("c data.bin"), &d.bin).unwrap();
    let meshes: Vec<Mesh> = ["a.glb", "b.gltf", "c.gltf"]
        .iter()
        .map(|f| load(&dir.join(f)).unwrap().mesh)
        .collect();
    for m in &meshes[1..] {
        assert_eq!(m.positions, meshes[0].positions);
        assert_eq!(m.normals, meshes[0].normals);
        assert_eq!(m.uvs, meshes[0].uvs);
        assert_eq!(m.triangles, meshes[0].triangles);
        assert_eq!(m.material_ids, meshes[0].material_ids);
    }
    assert_eq!(meshes[0].triangles, vec![[0, 1, 2], [2, 1, 0]]);
}

#[test]
fn cameras_and_lights_come_with_their_node_transforms() {
    let mut d = triangle_doc();
    d.push(
        "cameras",
        json!({"type": "perspective", "name": "cam",
        "perspective": {"yfov": std::f32::consts::FRAC_PI_2, "znear": 0.1, "aspectRatio": 1.5}}),
    );
    d.push(
        "cameras",
        json!({"type": "orthographic",
        "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10}}),
    );
    d.root_node(json!({"camera": 0, "translation": [1, 2, 3]}));
    // Rotated 90° about x: -z → +y, +y → +z.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    d.root_node(json!({"camera": 1, "name": "ortho-node", "rotation": [s, 0, 0, s]}));
    d.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    d.json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "spot", "color": [1, 0.5, 0], "intensity": 20, "spot": {"outerConeAngle": 0.5}},
    ]}});
    d.root_node(json!({"translation": [0, 5, 0], "rotation": [s, 0, 0, s],
        "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    let model = load(&d.write("camera")).unwrap();
    let [persp, ortho] = &model.cameras[..] else {
        panic!("{:?}", model.cameras)
    };
    assert_eq!(persp.name.as_deref(), Some("cam"));
    assert_eq!(persp.eye, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!((persp.forward, persp.up), (Vec3::NEG_Z, Vec3::Y));
    assert!((persp.yfov_degrees - 90.0).abs() < 1e-4);
    assert_eq!(
        (persp.aspect, persp.unsupported.as_ref()),
        (Some(1.5), None)
    );
    assert_eq!(ortho.name.as_deref(), Some("ortho-node"));
    assert!(close(ortho.forward, Vec3::Y) && close(ortho.up, Vec3::Z));
    assert!(ortho.unsupported.as_ref().unwrap().contains("orthographic"));
    let [light] = &model.lights[..] else {
        panic!("{:?}", model.lights)
    };
    assert_eq!(light.position, Vec3::new(0.0, 5.0, 0.0));
    assert!(close(light.direction, Vec3::Y));
    assert_eq!(
        (light.color, light.intensity, light.range),
        (Vec3::new(1.0, 0.5, 0.0), 20.0, None)
    );
    assert_eq!(
        light.kind,
        GltfLightKind::Spot {
            inner_cone_angle: 0.0,
            outer_cone_angle: 0.5
        }
    );
}

#[test]
fn points_and_lines_are_skipped_with_a_warning_or_refused_alone() {
    let mut d = triangle_doc();
    let p = d.floats(&TRIANGLE[..6], "VEC3");
    d.mesh_node(json!({"attributes": {"POSITION": p}, "mode": 1}));
    let model = load(&d.write("lines-mixed")).unwrap();
    assert_eq!(model.mesh.triangles.len(), 1);
    assert!(
        model.warnings[0].contains("/meshes/1/primitives/0/mode"),
        "{:?}",
        model.warnings
    );

    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    d.mesh_node(json!({"attributes": {"POSITION": p}, "mode": 0}));
    let msg = error(&d.write("points"));
    assert!(
        msg.starts_with("scene.toml:7:") && msg.contains("/meshes/0/primitives/0"),
        "{msg}"
    );
}

/// A change to a valid file.
type Mutation = Box<dyn Fn(&mut Doc)>;

#[test]
fn errors_name_the_json_pointer() {
    let cases: Vec<(&str, Mutation, &str)> = vec![
        (
            "index-range",
            Box::new(|d: &mut Doc| {
                let i = d.indices(&[0, 1, 3]);
                d.json["meshes"][0]["primitives"][0]["indices"] = json!(i);
            }),
            "/meshes/0/primitives/0/indices: index 3 (element 2) is out of range",
        ),
        (
            "accessor-bounds",
            Box::new(|d: &mut Doc| d.json["accessors"][0]["count"] = json!(4)),
            "/accessors/0: 4 elements of 12 bytes",
        ),
        (
            "accessor-missing",
            Box::new(|d: &mut Doc| {
                d.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(9)
            }),
            "/meshes/0/primitives/0/attributes/POSITION: accessor 9 does not exist",
        ),
        (
            "view-bounds",
            Box::new(|d: &mut Doc| d.json["bufferViews"][0]["byteOffset"] = json!(4)),
            "/bufferViews/0: byteOffset 4 + byteLength 36 lies outside buffer 0",
        ),
        (
            "type",
            Box::new(|d: &mut Doc| d.json["accessors"][0]["type"] = json!("VEC2")),
            "/accessors/0/type: POSITION needs type Vec3",
        ),
        (
            "non-finite",
            Box::new(|d: &mut Doc| {
                let p = d.floats(&[0.0, 0.0, f32::NAN, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3");
                d.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(p);
            }),
            "/accessors/1: POSITION element 0 is not finite",
        ),
        (
            "material",
            Box::new(|d: &mut Doc| d.json["meshes"][0]["primitives"][0]["material"] = json!(2)),
            "/meshes/0/primitives/0/material: material 2 does not exist",
        ),
        (
            "node-mesh",
            Box::new(|d: &mut Doc| d.json["nodes"][0]["mesh"] = json!(5)),
            "/nodes/0/mesh: mesh 5 does not exist",
        ),
        (
            "cycle",
            Box::new(|d: &mut Doc| d.json["nodes"][0]["children"] = json!([0])),
            "/nodes/0/children/0: node 0 appears twice",
        ),
        (
            "mode",
            Box::new(|d: &mut Doc| d.json["meshes"][0]["primitives"][0]["mode"] = json!(9)),
            "/meshes/0/primitives/0/mode",
        ),
        (
            "image",
            Box::new(|d: &mut Doc| {
                d.json["meshes"][0]["primitives"][0]["material"] = json!(0);
                d.push(
                    "materials",
                    json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}),
                );
                d.push("textures", json!({"source": 0}));
                d.push("images", json!({"uri": "missing.png"}));
            }),
            "/images/0/uri: cannot read texture",
        ),
        (
            "draco",
            Box::new(|d: &mut Doc| {
                d.json["extensionsRequired"] =
                    json!(["KHR_lights_punctual", "KHR_draco_mesh_compression"]);
            }),
            "/extensionsRequired/1: the file requires extension KHR_draco_mesh_compression (Draco",
        ),
        (
            "meshopt",
            Box::new(|d: &mut Doc| {
                d.json["extensionsRequired"] = json!(["EXT_meshopt_compression"])
            }),
            "EXT_meshopt_compression (meshopt compression)",
        ),
        (
            "huge-count",
            Box::new(|d: &mut Doc| {
                d.json["accessors"][0]["count"] = json!(1u64 << 60);
                d.json["accessors"][0]
                    .as_object_mut()
                    .unwrap()
                    .remove("bufferView");
            }),
            "more than 2^32",
        ),
    ];
    for (name, mutate, want) in cases {
        let mut d = triangle_doc();
        mutate(&mut d);
        let msg = error(&d.write(name));
        assert!(
            msg.contains("model.gltf: ") && msg.contains(want),
            "{name}: {msg}"
        );
    }
}

#[test]
fn file_level_errors_are_named() {
    let dir = scratch("file-errors");
    // Bad JSON: serde_json's line and column.
    let bad = dir.join("bad.gltf");
    std::fs::write(
        &bad,
        "{\n  \"asset\": {\"version\": \"2.0\"},\n  \"nodes\": [,]\n}",
    )
    .unwrap();
    let msg = error(&bad);
    assert!(
        msg.contains("bad.gltf:3: not valid glTF 2.0 JSON") && msg.contains("line 3"),
        "{msg}"
    );
    // glTF 1.0.
    let old = dir.join("old.gltf");
    std::fs::write(
        &old,
        r#"{"asset": {"version": "1.0"}, "meshes": {"m": {}}}"#,
    )
    .unwrap();
    assert!(error(&old).contains("/asset/version: glTF 1.0"));
    // A missing external buffer, at its URI.
    let d = triangle_doc();
    let ext = dir.join("ext.gltf");
    std::fs::write(&ext, d.external("gone.bin")).unwrap();
    let msg = error(&ext);
    assert!(
        msg.contains("/buffers/0/uri: cannot read buffer") && msg.contains("gone.bin"),
        "{msg}"
    );
    // A truncated external buffer.
    std::fs::write(dir.join("gone.bin"), &d.bin[..10]).unwrap();
    let msg = error(&ext);
    assert!(
        msg.contains("/buffers/0: byteLength is 36 but the data has only 10"),
        "{msg}"
    );
    // A missing glTF file is an error at the scene's line.
    let msg = error(&dir.join("nowhere.glb"));
    assert!(msg.starts_with("scene.toml:7: cannot read glTF"), "{msg}");
    // GLB version and lengths.
    let mut glb = d.glb();
    glb[4] = 1;
    let path = dir.join("v1.glb");
    std::fs::write(&path, &glb).unwrap();
    assert!(error(&path).contains("GLB: version 1"));
    let mut glb = d.glb();
    glb[8] += 1;
    std::fs::write(&path, &glb).unwrap();
    assert!(
        error(&path).contains("the header gives a length of"),
        "{}",
        error(&path)
    );
}

#[test]
fn truncated_glb_never_panics() {
    let mut d = triangle_doc();
    let i = d.indices(&[0, 1, 2]);
    d.json["meshes"][0]["primitives"][0]["indices"] = json!(i);
    let glb = d.glb();
    let dir = scratch("truncated");
    let path = dir.join("t.glb");
    std::fs::write(&path, &glb).unwrap();
    assert!(load(&path).is_ok());
    for len in 0..glb.len() {
        // Cut with its length field kept (a truncated download) and with
        // it patched (a broken writer): both must fail cleanly.
        for patch in [false, true] {
            let mut cut = glb[..len].to_vec();
            if patch && len >= 12 {
                let l = (len as u32).to_le_bytes();
                cut[8..12].copy_from_slice(&l);
            }
            std::fs::write(&path, &cut).unwrap();
            assert!(load(&path).is_err(), "length {len} loaded");
        }
    }
}

#[test]
fn a_mesh_on_two_nodes_is_placed_twice() {
    let mut d = Doc::new();
    let p = d.floats(&TRIANGLE, "VEC3");
    let m = d.push(
        "meshes",
        json!({"primitives": [{"attributes": {"POSITION": p}}]}),
    );
    d.root_node(json!({"mesh": m}));
    d.root_node(json!({"mesh": m, "translation": [0, 0, 3]}));
    let mesh = load(&d.write("instances")).unwrap().mesh;
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    assert_eq!(
        mesh.positions[3..],
        mesh.positions[..3]
            .iter()
            .map(|p| *p + Vec3::Z * 3.0)
            .collect::<Vec<_>>()
    );
}

#[test]
fn quantized_positions_read_when_the_extension_is_required() {
    let mut d = Doc::new();
    // Normalized shorts, each element padded to 8 bytes.
    let shorts: [i16; 12] = [0, 0, 0, 0, 32767, 0, 0, 0, 0, -32767, 0, 0];
    let bytes: Vec<u8> = shorts.iter().flat_map(|x| x.to_le_bytes()).collect();
    let v = d.view(&bytes, Some(8));
    let p = d.push(
        "accessors",
        json!({"bufferView": v, "componentType": 5122, "normalized": true, "count": 3, "type": "VEC3"}),
    );
    d.mesh_node(json!({"attributes": {"POSITION": p}}));
    d.json["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    d.json["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    let model = load(&d.write("quantized")).unwrap();
    assert_eq!(model.mesh.positions, vec![Vec3::ZERO, Vec3::X, Vec3::NEG_Y]);
    assert!(model.warnings.is_empty(), "{:?}", model.warnings);
}
