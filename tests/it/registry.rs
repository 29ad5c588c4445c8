//! The technique registry: names, the docs table, capability checks and
//! defaults all come from one place, and every technique is reachable
//! through it.

use crate::common;

use penumbra::internal::geom::SceneGeometry;
use penumbra::internal::render::{render, view_for, RenderOptions};
use penumbra::internal::shadow::registry::{markdown_table, names, DEFAULT_TECHNIQUE};
use penumbra::internal::shadow::technique::{check_scene, Support, TermKind, Warning};
use penumbra::internal::shadow::{Technique, TechniqueOptions};
use std::process::Command;

#[test]
fn names_are_unique_and_each_parses_to_itself() {
    let all = names();
    assert!(all.len() >= 6, "{all:?}");
    for (i, n) in all.iter().enumerate() {
        assert!(!all[..i].contains(n), "{n} registered twice");
        assert_eq!(Technique::named(n).expect("registered").name(), *n);
        assert_eq!(n.parse::<Technique>().expect("parses").name(), *n);
    }
}

#[test]
fn an_unknown_name_lists_every_known_one() {
    let e = Technique::named("dsc").expect_err("unknown").to_string();
    assert!(e.contains("--technique") && e.contains("dsc"), "{e}");
    for n in names() {
        assert!(e.contains(n), "{n} missing from: {e}");
    }
}

#[test]
fn the_docs_table_is_the_registry_table() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/architecture.md"))
        .expect("docs/architecture.md");
    let begin = "<!-- techniques:begin -->\n";
    let a = doc.find(begin).expect("begin marker") + begin.len();
    let b = doc.find("<!-- techniques:end -->").expect("end marker");
    assert_eq!(
        &doc[a..b],
        markdown_table("algorithms/"),
        "regenerate with `penumbra techniques --markdown`"
    );
}

#[test]
fn the_readme_table_is_the_registry_table() {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md"))
        .expect("README.md");
    let begin = "<!-- techniques:begin -->\n";
    let a = readme.find(begin).expect("begin marker") + begin.len();
    let b = readme.find("<!-- techniques:end -->").expect("end marker");
    assert_eq!(
        &readme[a..b],
        markdown_table("docs/algorithms/"),
        "regenerate with `penumbra techniques --markdown` (links under docs/)"
    );
}

#[test]
fn the_default_is_exact_dcs_and_equals_the_command_line_defaults() {
    let options = RenderOptions::default();
    assert_eq!(options.technique.name(), DEFAULT_TECHNIQUE);
    assert_eq!(DEFAULT_TECHNIQUE, "dcs");
    let caps = options.technique.capabilities(&options.options);
    assert!(caps.exact, "the default technique must be exact: {caps:?}");
    assert!(caps.exact_image, "and so must its image: {caps:?}");
    // The CLI's defaults are the library's: render with no options at all
    // and with the library defaults gives the same bits.
    let dir = common::scratch_dir("registry-default");
    let png = dir.join("default.png");
    let exr = dir.join("default.exr");
    let status = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args([
            "render",
            "scenes/quad.toml",
            "--width",
            "48",
            "--height",
            "32",
        ])
        .arg("-o")
        .arg(&png)
        .arg("--exr")
        .arg(&exr)
        .args(["--aov", "vcoef"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .expect("runs");
    assert!(status.success());
    let scene = common::shipped("quad.toml");
    let out = render(
        &scene,
        &RenderOptions {
            width: Some(48),
            height: Some(32),
            aovs: vec![penumbra::internal::render::Aov::Vcoef],
            ..RenderOptions::default()
        },
    )
    .expect("render");
    let lib = dir.join("lib.exr");
    penumbra::internal::output::write_exr(&lib, out.width, out.height, &out.radiance, &out.layers)
        .expect("exr");
    assert_eq!(
        std::fs::read(&exr).expect("cli exr"),
        std::fs::read(&lib).expect("lib exr")
    );
}

/// Every technique whose capabilities refuse something is refused the same
/// way, with the parameter named; one that ignores something warns.
#[test]
fn capabilities_answer_for_every_technique() {
    let sphere = common::scene_in_scratch(
        "registry-sphere",
        r#"
[camera]
eye = [0.0, 3.0, 6.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 45.0
width = 32
height = 24

[[light]]
type = "sphere"
center = [0.0, 4.0, 0.0]
radius = 0.5
radiance = [5.0, 5.0, 5.0]

[[object]]
shape = "quad"
size = [6.0, 6.0]

[[object]]
shape = "box"
size = [0.5, 0.5, 0.5]
translate = [0.0, 1.0, 0.0]
"#,
        &[],
    );
    let defaults = TechniqueOptions::default();
    let sphere_geometry = SceneGeometry::new(&sphere);
    let sphere_view = view_for(&sphere, &RenderOptions::default()).unwrap();
    for t in Technique::all() {
        let caps = t.capabilities(&defaults);
        let checked = check_scene(t.info(), &defaults, &sphere, &sphere_geometry, &sphere_view);
        match caps.sphere_lights {
            Support::Refused { param, .. } => {
                let e = checked.expect_err("refused").to_string();
                assert!(e.contains(param) && e.contains(t.name()), "{e}");
                // And the render says the same, before any work.
                let r = render(
                    &sphere,
                    &RenderOptions {
                        technique: t,
                        ..RenderOptions::default()
                    },
                );
                assert!(r.is_err(), "{}", t.name());
            }
            _ => assert!(checked.expect("accepted").is_empty(), "{}", t.name()),
        }
    }
    // An option can change a capability: bit fields need rect lights.
    let mut bitfield = TechniqueOptions::default();
    bitfield.dcs.coverage = penumbra::internal::shadow::dcs::CoverageTest::BitField;
    let dcs = Technique::named("dcs").unwrap();
    let e = check_scene(
        dcs.info(),
        &bitfield,
        &sphere,
        &sphere_geometry,
        &sphere_view,
    )
    .expect_err("refused");
    assert!(e.to_string().contains("--coverage"), "{e}");
    assert!(!dcs.capabilities(&bitfield).exact);
}

#[test]
fn semi_opaque_casters_warn_with_techniques_that_ignore_them() {
    let scene = common::shipped("tinted.toml");
    let geometry = SceneGeometry::new(&scene);
    let view = view_for(&scene, &RenderOptions::default()).unwrap();
    let defaults = TechniqueOptions::default();
    for t in Technique::all() {
        let warnings =
            check_scene(t.info(), &defaults, &scene, &geometry, &view).expect("accepted");
        match t.capabilities(&defaults).semi_opaque {
            Support::Ignored(_) => assert!(
                matches!(warnings.as_slice(), [Warning::Ignored { technique, .. }] if *technique == t.name()),
                "{}: {warnings:?}",
                t.name()
            ),
            _ => assert!(warnings.is_empty(), "{}: {warnings:?}", t.name()),
        }
    }
}

#[test]
fn declared_output_kinds_match_the_terms_returned() {
    let scene = common::shipped("quad.toml");
    for t in Technique::all() {
        let options = RenderOptions {
            width: Some(32),
            height: Some(24),
            technique: t,
            samples: 4,
            ..RenderOptions::default()
        };
        let out = render(&scene, &options).expect("render");
        let kind = t.capabilities(&options.options).output;
        for term in &out.lights {
            assert_eq!(
                term.radiance().is_some(),
                kind == TermKind::Radiance,
                "{}",
                t.name()
            );
            assert!(term.vcoef().iter().all(|v| (0.0..=1.0).contains(v)));
        }
    }
}

#[test]
fn every_technique_has_quality_settings_and_a_listing_line() {
    let listing = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(["techniques"])
        .output()
        .expect("runs");
    assert!(listing.status.success());
    let text = String::from_utf8_lossy(&listing.stdout);
    let defaults = TechniqueOptions::default();
    for t in Technique::all() {
        assert!(text.lines().any(|l| l.starts_with(t.name())), "{text}");
        let sweep = penumbra::internal::shadow::technique::Sweep {
            samples: &[4, 16],
            patterns: &[penumbra::internal::sampling::SamplePattern::Stratified],
            semi_opaque: true,
            base: &defaults,
        };
        let settings = t.quality_settings(&sweep);
        assert!(!settings.is_empty(), "{}", t.name());
        for q in &settings {
            assert!(q.curve.starts_with(t.name()), "{}: {}", t.name(), q.curve);
        }
    }
}

/// "Adding a technique is its folder plus one line in the list"
/// (docs/architecture.md) holds only if the list and the folders agree:
/// every technique's module exists, and every folder or file under
/// `src/shadow/` is either a registered technique's or one of the named
/// shared layers.
#[test]
fn the_list_and_the_technique_folders_agree() {
    /// What `src/shadow/` holds besides the techniques.
    const SHARED: &[&str] = &[
        "mod.rs",
        "technique.rs",
        "registry.rs",
        "options.rs",
        "run.rs",
        "verify.rs",
        "kit",
    ];
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let modules: Vec<&str> = Technique::all().map(|t| t.info().module).collect();
    for module in &modules {
        assert!(
            src.join(module).exists(),
            "a registered technique's module {module} does not exist"
        );
    }
    for entry in std::fs::read_dir(src.join("shadow")).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        if SHARED.contains(&name.as_str()) {
            continue;
        }
        let as_module = if name.ends_with(".rs") {
            format!("shadow/{name}")
        } else {
            format!("shadow/{name}/")
        };
        assert!(
            modules.iter().any(|m| m.starts_with(&as_module)),
            "src/shadow/{name} is neither a registered technique (add it to \
             shadow/registry.rs's TECHNIQUES) nor a shared layer"
        );
    }
}

/// `penumbra techniques --json` is the registry as data: every registered
/// technique, in order, with its capabilities as the listing states them.
#[test]
fn techniques_as_json_are_the_registry() {
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(["techniques", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    let listed: Vec<&str> = json
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["name"].as_str().unwrap())
        .collect();
    assert_eq!(listed, names());
    let defaults = TechniqueOptions::default();
    for (entry, t) in json.as_array().unwrap().iter().zip(Technique::all()) {
        let caps = t.capabilities(&defaults);
        assert_eq!(entry["exact"], caps.exact, "{}", t.name());
        assert_eq!(entry["exact_image"], caps.exact_image, "{}", t.name());
        let sphere = entry["support"]["sphere_lights"].as_str().unwrap();
        match caps.sphere_lights {
            Support::Yes => assert_eq!(sphere, "yes"),
            Support::Refused { why, .. } => assert_eq!(sphere, format!("refused: {why}")),
            _ => assert!(!sphere.is_empty()),
        }
    }
    let dcs = &json.as_array().unwrap()[names().iter().position(|n| *n == "dcs").unwrap()];
    assert_eq!(dcs["output"], "radiance");
    assert_eq!(dcs["cost"], "raster");
}
