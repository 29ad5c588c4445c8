//! Meshes in the formats other tools write: the shipped bunny exported by
//! trimesh (an outside writer; scenes/models/stanford-bunny/CHANGES.txt) to
//! GLB and to binary and ASCII PLY renders bit for bit as the OBJ, and a
//! glTF's camera and light stand for the same camera and sphere light
//! written in TOML.

use crate::common;
use penumbra::internal::scene::load_scene;
use penumbra::{render, scene_from_toml, Aov, RenderOptions, Technique};
use std::path::Path;

fn options(technique: &str) -> RenderOptions {
    RenderOptions {
        technique: Technique::named(technique).expect("a registered technique"),
        samples: 16,
        width: Some(96),
        height: Some(96),
        aovs: vec![Aov::Depth, Aov::Normal, Aov::Vcoef],
        ..RenderOptions::default()
    }
}

#[test]
fn the_bunny_from_an_outside_writer_renders_as_the_obj() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let toml = std::fs::read_to_string(scenes.join("bunny.toml")).unwrap();
    let obj = "models/stanford-bunny/stanford-bunny.obj";
    assert!(toml.contains(obj));
    let of = |file: &str| {
        let text = toml.replace(obj, &format!("models/stanford-bunny/exports/{file}"));
        scene_from_toml(&text, &scenes).unwrap_or_else(|e| panic!("{file}: {e}"))
    };
    let reference = load_scene(&scenes.join("bunny.toml")).unwrap();
    for technique in ["dcs", "reference"] {
        let want = common::render_bits(&render(&reference, &options(technique)).unwrap());
        for file in [
            "stanford-bunny.glb",
            "stanford-bunny-binary.ply",
            "stanford-bunny-ascii.ply",
        ] {
            let got = common::render_bits(&render(&of(file), &options(technique)).unwrap());
            assert!(
                got == want,
                "{file} ({technique}) differs from the OBJ's image"
            );
        }
    }
}

/// The ground, the light and the image of both twins; `{camera}`,
/// `{light}` and `{fence}` are filled in.
const TWIN: &str = r#"
{camera}
width = 64
height = 64

{light}

[[object]]
name = "ground"
shape = "quad"
size = [8.0, 8.0]

[[object]]
{fence}
"#;

/// A glTF scene: a node hierarchy (a translated parent, a child rotated
/// half a turn about +Y and scaled by a matrix-free TRS) carrying an
/// alpha-masked, textured quad, a camera placed by its own node, and a
/// point light. Every transform is exact in binary, so that the OBJ twin
/// can hold the same world-space vertices.
fn write_gltf(dir: &Path) {
    let mut bin: Vec<u8> = Vec::new();
    let positions = [
        [-0.5f32, -0.5, 0.0],
        [0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
        [-0.5, 0.5, 0.0],
    ];
    // glTF's v = 0 is the top row.
    let uvs = [[0.0f32, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    positions
        .iter()
        .flatten()
        .for_each(|x| bin.extend(x.to_le_bytes()));
    uvs.iter()
        .flatten()
        .for_each(|x| bin.extend(x.to_le_bytes()));
    [0u16, 1, 2, 0, 2, 3]
        .iter()
        .for_each(|i| bin.extend(i.to_le_bytes()));
    std::fs::write(dir.join("fence.bin"), &bin).unwrap();
    let gltf = serde_json::json!({
        "asset": {"version": "2.0", "generator": "penumbra tests"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "lamp", "type": "point", "color": [1.0, 1.0, 1.0], "intensity": 10.0}
        ]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 2, 3]}],
        "nodes": [
            {"name": "parent", "translation": [0.0, 1.25, 0.0], "children": [1]},
            {"name": "child", "rotation": [0.0, 1.0, 0.0, 0.0], "scale": [2.0, 2.0, 2.0], "mesh": 0},
            {"name": "eye", "translation": [0.0, 1.5, -5.0], "rotation": [0.0, 1.0, 0.0, 0.0], "camera": 0},
            {"name": "lamp-node", "translation": [0.5, 4.0, 1.0],
             "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ],
        "cameras": [{"name": "view", "type": "perspective",
                     "perspective": {"yfov": 0.6, "znear": 0.1, "aspectRatio": 1.0}}],
        "meshes": [{"name": "fence", "primitives": [{
            "attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0, "mode": 4
        }]}],
        "materials": [{"name": "fence", "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": true,
                       "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                "metallicFactor": 0.0, "roughnessFactor": 1.0}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 10497, "wrapT": 10497}],
        "images": [{"uri": "fence-opacity.png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-0.5, -0.5, 0.0], "max": [0.5, 0.5, 0.0]},
            {"bufferView": 0, "byteOffset": 48, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 80},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12}
        ],
        "buffers": [{"uri": "fence.bin", "byteLength": bin.len()}]
    });
    std::fs::write(dir.join("fence.gltf"), gltf.to_string()).unwrap();
}

/// The same quad in world space as an OBJ whose MTL gives the texture as
/// albedo and (its binary alpha) as opacity, as the glTF's MASK does.
fn write_obj(dir: &Path) {
    // (x, y) -> (-2x, 2y + 1.25): the child's half turn and scale, then the
    // parent's translation.
    let obj = "mtllib fence.mtl\n\
               v 1 0.25 0\nv -1 0.25 0\nv -1 2.25 0\nv 1 2.25 0\n\
               vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
               usemtl fence\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    std::fs::write(dir.join("fence.obj"), obj).unwrap();
    let mtl = "newmtl fence\nKd 1 1 1\nmap_Kd fence-opacity.png\nmap_d fence-opacity.png\n";
    std::fs::write(dir.join("fence.mtl"), mtl).unwrap();
}

#[test]
fn a_gltf_scene_renders_as_its_toml_and_obj_twin() {
    let dir = common::scratch_dir("gltf-twin");
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    std::fs::copy(
        scenes.join("fence-opacity.png"),
        dir.join("fence-opacity.png"),
    )
    .unwrap();
    write_gltf(&dir);
    write_obj(&dir);
    let fill = |camera: &str, light: &str, fence: &str| {
        TWIN.replace("{camera}", camera)
            .replace("{light}", light)
            .replace("{fence}", fence)
    };
    let from_gltf = fill(
        "[camera]\nfrom = \"fence.gltf\"\nname = \"view\"",
        "[[light]]\ntype = \"sphere\"\nfrom = \"fence.gltf\"\nradius = 0.25",
        "obj = \"fence.gltf\"",
    );
    // The same numbers as the glTF reader computes them, printed so that
    // they read back as the same f32.
    let fov = 0.6f32.to_degrees();
    let radiance = 10.0f32 / (std::f32::consts::PI * 0.25 * 0.25);
    let from_toml = fill(
        &format!(
            "[camera]\neye = [0.0, 1.5, -5.0]\ntarget = [0.0, 1.5, -4.0]\nup = [0.0, 1.0, 0.0]\n\
             fov_y = {fov:?}"
        ),
        &format!(
            "[[light]]\ntype = \"sphere\"\ncenter = [0.5, 4.0, 1.0]\nradius = 0.25\n\
             radiance = [{radiance:?}, {radiance:?}, {radiance:?}]"
        ),
        "obj = \"fence.obj\"",
    );
    let a = scene_from_toml(&from_gltf, &dir).unwrap_or_else(|e| panic!("glTF twin: {e}"));
    let b = scene_from_toml(&from_toml, &dir).unwrap_or_else(|e| panic!("TOML twin: {e}"));
    assert_eq!((a.camera.width, a.camera.height), (64, 64));
    for technique in ["dcs", "reference"] {
        let mut o = options(technique);
        (o.width, o.height) = (None, None);
        let (ra, rb) = (render(&a, &o).unwrap(), render(&b, &o).unwrap());
        // The fence's holes show: some pixels are lit and some in shadow.
        let vcoef = &ra
            .layers
            .iter()
            .find(|l| l.name == "vcoef")
            .unwrap()
            .channels[0]
            .1;
        assert!(vcoef.contains(&0.0) && vcoef.contains(&1.0));
        assert!(
            common::render_bits(&ra) == common::render_bits(&rb),
            "{technique}: the glTF scene's image differs from its TOML + OBJ twin's"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `lights_from_emissive`: a glTF's emissive quad (with
/// `KHR_materials_emissive_strength`) becomes the rect light a TOML scene
/// would give, and leaves the mesh (a light does not block light); the
/// object's transform moves it with the rest.
#[test]
fn emissive_quads_become_rect_lights() {
    let dir = common::scratch_dir("gltf-emissive");
    // Two quads: an occluder at y = 1 and an emitter at y = 3 facing down.
    let quad = |y: f32, h: f32| [[-h, y, -h], [h, y, -h], [h, y, h], [-h, y, h]];
    let mut bin: Vec<u8> = Vec::new();
    for q in [quad(1.0, 0.25), quad(3.0, 0.5)] {
        q.iter()
            .flatten()
            .for_each(|x: &f32| bin.extend(x.to_le_bytes()));
    }
    [0u16, 1, 2, 0, 2, 3]
        .iter()
        .for_each(|i| bin.extend(i.to_le_bytes()));
    std::fs::write(dir.join("lamp.bin"), &bin).unwrap();
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0}, "indices": 2},
            {"attributes": {"POSITION": 1}, "indices": 2, "material": 0}
        ]}],
        "materials": [{"emissiveFactor": [1.0, 1.0, 1.0],
                       "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 8.0}},
                       "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0]}}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 0, "byteOffset": 48, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 96},
            {"buffer": 0, "byteOffset": 96, "byteLength": 12}
        ],
        "buffers": [{"uri": "lamp.bin", "byteLength": bin.len()}]
    });
    std::fs::write(dir.join("lamp.gltf"), gltf.to_string()).unwrap();
    std::fs::write(
        dir.join("occluder.obj"),
        "v -0.25 1 -0.25\nv 0.25 1 -0.25\nv 0.25 1 0.25\nv -0.25 1 0.25\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let camera = "[camera]\neye = [0.0, 4.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nfov_y = 45\n\
                  width = 48\nheight = 40\n";
    let ground = "[[object]]\nshape = \"quad\"\nsize = [6.0, 6.0]\n";
    let from_gltf = format!(
        "{camera}{ground}[[object]]\nobj = \"lamp.gltf\"\ntranslate = [0.25, 0.0, 0.0]\n\
         lights_from_emissive = true\n"
    );
    // The emitter faces down: u × v points down.
    let from_toml = format!(
        "{camera}[[light]]\ntype = \"rect\"\ncenter = [0.25, 3.0, 0.0]\nu = [0.0, 0.0, 0.5]\n\
         v = [-0.5, 0.0, 0.0]\nradiance = 8.0\n{ground}[[object]]\nobj = \"occluder.obj\"\n\
         translate = [0.25, 0.0, 0.0]\n"
    );
    let a = scene_from_toml(&from_gltf, &dir).unwrap_or_else(|e| panic!("glTF: {e}"));
    let b = scene_from_toml(&from_toml, &dir).unwrap_or_else(|e| panic!("TOML: {e}"));
    assert_eq!(a.lights.len(), 1);
    assert_eq!(
        a.objects[1].mesh.triangle_count(),
        2,
        "the emitter left the mesh"
    );
    for technique in ["dcs", "reference"] {
        let mut o = options(technique);
        (o.width, o.height) = (None, None);
        let (ra, rb) = (render(&a, &o).unwrap(), render(&b, &o).unwrap());
        assert!(
            common::render_bits(&ra) == common::render_bits(&rb),
            "{technique}: the emissive quad's light differs from the TOML rect light"
        );
    }
    // Only glTF objects take the key.
    let wrong =
        format!("{camera}[[object]]\nobj = \"occluder.obj\"\nlights_from_emissive = true\n");
    let Err(e) = scene_from_toml(&wrong, &dir) else {
        panic!("lights_from_emissive on an OBJ object loads");
    };
    let e = e.to_string();
    assert!(
        e.contains("lights_from_emissive") && e.contains("glTF"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
