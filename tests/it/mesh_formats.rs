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
            assert!(got == want, "{file} ({technique}) differs from the OBJ's image");
        }
    }
}
