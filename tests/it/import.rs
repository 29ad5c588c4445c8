//! `penumbra import MODEL -o SCENE.toml`: the starting scene loads, frames
//! the model and shows a soft shadow at once; a model with a floor of its
//! own gets no ground quad; mistakes are refused by name.

use crate::common;
use penumbra::{load_scene, render, Aov, RenderOptions, Technique};
use std::path::Path;
use std::process::Command;

fn import(model: &Path, output: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .arg("import")
        .arg(model)
        .arg("-o")
        .arg(output)
        .output()
        .expect("run penumbra import")
}

/// The fractions of surface pixels that are lit (Vcoef 1), in umbra
/// (below 0.05) and in penumbra (between).
fn shadow_fractions(scene: &penumbra::Scene) -> (f64, f64, f64) {
    let options = RenderOptions {
        technique: Technique::named("dcs").unwrap(),
        samples: 64,
        width: Some(96),
        height: Some(72),
        aovs: vec![Aov::Mask, Aov::Vcoef],
        ..RenderOptions::default()
    };
    let image = render(scene, &options).expect("render");
    let layer = |name: &str| {
        let l = image.layers.iter().find(|l| l.name == name).unwrap();
        l.channels[0].1.clone()
    };
    let (mask, vcoef) = (layer("mask"), layer("vcoef"));
    let surface: Vec<f32> = (mask.iter().zip(&vcoef))
        .filter(|(m, _)| **m > 0.5)
        .map(|(_, v)| *v)
        .collect();
    let share = |f: &dyn Fn(f32) -> bool| {
        surface.iter().filter(|v| f(**v)).count() as f64 / surface.len() as f64
    };
    (
        share(&|v| v >= 1.0),
        share(&|v| v < 0.05),
        share(&|v| (0.05..1.0).contains(&v)),
    )
}

#[test]
fn an_imported_model_renders_with_a_soft_shadow_at_once() {
    let dir = common::scratch_dir("import");
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for model in [
        "models/stanford-bunny/exports/stanford-bunny.glb",
        "models/stanford-bunny/exports/stanford-bunny-binary.ply",
        "models/stanford-bunny/stanford-bunny.obj",
    ] {
        let output = dir.join("bunny.toml");
        let out = import(&scenes.join(model), &output);
        assert!(
            out.status.success(),
            "{model}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let scene = load_scene(&output).unwrap_or_else(|e| panic!("{model}: {e}"));
        // The model, and a ground quad under it.
        assert_eq!(scene.objects.len(), 2, "{model}");
        assert_eq!(scene.objects[1].mesh.triangle_count(), 69_451, "{model}");
        let (lit, umbra, penumbra) = shadow_fractions(&scene);
        assert!(
            lit > 0.3 && umbra > 0.005 && penumbra > 0.01,
            "{model}: lit {lit}, umbra {umbra}, penumbra {penumbra}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_model_with_its_own_floor_gets_no_ground_and_mistakes_are_named() {
    let dir = common::scratch_dir("import-floor");
    // A floor quad and a box standing on it (a unit cube, 12 triangles).
    let mut obj = String::from("v -3 0 -3\nv 3 0 -3\nv 3 0 3\nv -3 0 3\nf 1 4 3 2\n");
    for (x, y, z) in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
        .into_iter()
        .chain([(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])
    {
        obj += &format!("v {x} {y} {z}\n");
    }
    for f in [
        "5 8 7 6",
        "9 10 11 12",
        "5 6 10 9",
        "8 12 11 7",
        "5 9 12 8",
        "6 7 11 10",
    ] {
        obj += &format!("f {f}\n");
    }
    std::fs::write(dir.join("room.obj"), obj).unwrap();
    let output = dir.join("scenes").join("room.toml");
    std::fs::create_dir_all(output.parent().unwrap()).unwrap();
    let out = import(&dir.join("room.obj"), &output);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&output).unwrap();
    // Named relative to the scene's folder.
    assert!(text.contains("obj = \"../room.obj\""), "{text}");
    let scene = load_scene(&output).unwrap();
    assert_eq!(
        scene.objects.len(),
        1,
        "no ground quad: the model has a floor"
    );
    // The box's shadow is short (the light is high above a low box), but
    // there.
    let (lit, umbra, penumbra) = shadow_fractions(&scene);
    assert!(
        lit > 0.3 && umbra + penumbra > 0.003,
        "lit {lit}, umbra {umbra}, penumbra {penumbra}"
    );

    // A missing model, and the model as the output, are refused by name.
    let out = import(&dir.join("missing.ply"), &dir.join("x.toml"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        err.contains("MODEL") && err.contains("missing.ply"),
        "{err}"
    );
    assert!(!dir.join("x.toml").exists());
    let out = import(&dir.join("room.obj"), &dir.join("room.obj"));
    assert_eq!(out.status.code(), Some(2));
    assert!(std::fs::read_to_string(dir.join("room.obj"))
        .unwrap()
        .starts_with("v -3 0 -3"));
    let _ = std::fs::remove_dir_all(&dir);
}
