//! What the command line tells the user besides the image: refusals
//! before a render that cannot fit, warnings about scenes that render
//! black and options that do not apply, and the help and technique
//! listings.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs penumbra in `dir`: (exit code, stderr + stdout).
fn penumbra_in(dir: &Path, args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run penumbra");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout),
    )
}

/// Writes `toml` as `scene.toml` in a scratch directory for `test`.
fn scene(test: &str, toml: &str) -> (PathBuf, PathBuf) {
    let dir = common::scratch_dir(test);
    let path = dir.join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    (dir, path)
}

const QUAD: &str = "[camera]\neye = [0.0, 5.0, 6.0]\ntarget = [0.0, 0.0, 0.0]\nfov_y = 45\n\
                    width = 16\nheight = 16\n\
                    [[light]]\ntype = \"rect\"\ncenter = [0.0, 4.0, 0.0]\n\
                    u = [0.5, 0.0, 0.0]\nv = [0.0, 0.0, 0.5]\nradiance = 10\n\
                    [[object]]\nname = \"ground\"\nshape = \"quad\"\nsize = [6.0, 6.0]\n\
                    [[object]]\nname = \"occluder\"\nshape = \"quad\"\nsize = [1.0, 1.0]\n\
                    translate = [0.0, 1.0, 0.0]\n";

/// Under an address-space limit (`ulimit -v`, 2 GiB) an 8192² render is
/// refused with the estimate's message, not aborted by a failed
/// allocation (fuzz repro `image-estimate-ignores-ulimit-abort`).
#[test]
fn image_estimate_honours_the_address_space_limit() {
    let (dir, _) = scene("mem-ulimit", QUAD);
    let out = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 2097152 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_penumbra"))
        .args([
            "render",
            "scene.toml",
            "-o",
            "big.png",
            "--width",
            "8192",
            "--height",
            "8192",
            "--threads",
            "1",
            "--technique",
            "dcs",
            "--samples",
            "1",
        ])
        .current_dir(&dir)
        .output()
        .expect("run penumbra under ulimit");
    let msg = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains("8192x8192 needs about") && msg.contains("GiB available"),
        "{msg}"
    );
    assert!(!dir.join("big.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The warnings of a 16×16 `render` of `toml` (exit 0 expected).
fn render_warnings(test: &str, toml: &str, extra: &[&str]) -> Vec<String> {
    let (dir, _) = scene(test, toml);
    let mut args = vec!["render", "scene.toml", "-o", "o.png"];
    args.extend(extra);
    let (code, msg) = penumbra_in(&dir, &args);
    assert_eq!(code, 0, "{msg}");
    let _ = std::fs::remove_dir_all(&dir);
    msg.lines()
        .filter(|l| l.contains("warning"))
        .map(str::to_string)
        .collect()
}

/// Scenes that render black, or partly, for a reason the author may not
/// see: each gets a warning (no light; a one-sided rect light facing away
/// from every object; surfaces of opacity below 0.5, which the camera sees
/// through). The plain quad scene gets none.
#[test]
fn scenes_that_render_black_are_warned_about() {
    assert_eq!(
        render_warnings("warn-none", QUAD, &[]),
        Vec::<String>::new()
    );

    let no_light = QUAD.replace(
        "[[light]]\ntype = \"rect\"\ncenter = [0.0, 4.0, 0.0]\n\
                                 u = [0.5, 0.0, 0.0]\nv = [0.0, 0.0, 0.5]\nradiance = 10\n",
        "",
    );
    assert!(!no_light.contains("[[light]]"));
    let w = render_warnings("warn-nolight", &no_light, &[]);
    assert!(
        w.len() == 1 && w[0].contains("no [[light]]") && w[0].contains("black"),
        "{w:?}"
    );

    // u and v swapped: cross(u, v) points up, away from every object.
    let away = QUAD.replace(
        "u = [0.5, 0.0, 0.0]\nv = [0.0, 0.0, 0.5]",
        "u = [0.0, 0.0, 0.5]\nv = [0.5, 0.0, 0.0]",
    );
    let w = render_warnings("warn-away", &away, &[]);
    assert!(
        w.len() == 1 && w[0].contains("light[0] (rect)") && w[0].contains("lights nothing"),
        "{w:?}"
    );
    // Two-sided, it lights the scene: no warning.
    let two = away.replace("radiance = 10\n", "radiance = 10\ntwo_sided = true\n");
    assert_eq!(render_warnings("warn-two", &two, &[]), Vec::<String>::new());

    // The occluder at opacity 0.3 (as in scenes/tinted.toml's pane).
    let pane = format!("{QUAD}material = {{ opacity = 0.3 }}\n");
    let w = render_warnings("warn-pane", &pane, &["--technique", "reference"]);
    assert!(
        w.len() == 1 && w[0].contains("object[1] `occluder`") && w[0].contains("below 0.5"),
        "{w:?}"
    );
}

/// An option given on the command line that the technique does not read
/// warns, naming both (the registry's list of what each technique reads);
/// defaulted options and options that apply do not.
#[test]
fn options_that_do_not_apply_are_warned_about() {
    let w = render_warnings(
        "opt-pattern",
        QUAD,
        &[
            "--technique",
            "shadow-map",
            "--pattern",
            "sobol",
            "--map-size",
            "64",
        ],
    );
    assert!(
        w.len() == 1 && w[0].contains("--pattern does not apply to `shadow-map`"),
        "{w:?}"
    );
    let w = render_warnings(
        "opt-dcs-mode",
        QUAD,
        &[
            "--technique",
            "reference",
            "--dcs-mode",
            "vcoef",
            "--seed",
            "3",
        ],
    );
    assert!(
        w.len() == 1 && w[0].contains("--dcs-mode does not apply to `reference`"),
        "{w:?}"
    );
    let w = render_warnings(
        "opt-fine",
        QUAD,
        &["--technique", "dcs", "--pattern", "sobol"],
    );
    assert_eq!(w, Vec::<String>::new());
}

/// `penumbra techniques` keeps a gap between a name and its summary
/// (`penumbra-casting` ran into `hierarchical`).
#[test]
fn techniques_listing_keeps_its_columns_apart() {
    let (code, out) = penumbra_in(Path::new(env!("CARGO_MANIFEST_DIR")), &["techniques"]);
    assert_eq!(code, 0, "{out}");
    let line = out
        .lines()
        .find(|l| l.starts_with("penumbra-casting"))
        .expect("listed");
    assert!(line.starts_with("penumbra-casting  "), "{line}");
}

/// `render -h` stays short, groups its options under headings, shows no
/// rustdoc link syntax, and `--help` lists every `--pattern` value.
#[test]
fn render_help_is_short_grouped_and_plain() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (code, short) = penumbra_in(root, &["render", "-h"]);
    assert_eq!(code, 0, "{short}");
    // The short help fits a screen: the technique options are in --help.
    assert!(
        short.lines().count() <= 40,
        "{} lines",
        short.lines().count()
    );
    for heading in ["Output:", "Image:", "Light sampling:", "Diagnostics:"] {
        assert!(short.contains(heading), "no `{heading}` in\n{short}");
    }
    assert!(
        !short.contains("--dcs-mode") && short.contains("see --help"),
        "{short}"
    );
    let (code, long) = penumbra_in(root, &["render", "--help"]);
    assert_eq!(code, 0, "{long}");
    for heading in ["DCS:", "Shadow maps:", "PCSS:", "Penumbra casting:"] {
        assert!(long.contains(heading), "no `{heading}` in\n{long}");
    }
    for text in [&short, &long] {
        assert!(!text.contains("[`"), "doc-link syntax in the help");
    }
    for pattern in ["grid", "02", "sobol", "interleaved:N"] {
        assert!(
            long.contains(pattern),
            "--pattern does not list `{pattern}`"
        );
    }
}

/// The library refuses what the command line refuses, with the same
/// message: both go through `RenderOptions::validate`.
#[test]
fn the_library_refuses_what_the_command_line_refuses() {
    use penumbra::internal::render::{render, RenderOptions};
    let (dir, path) = scene("library_refuses", QUAD);
    let scene = penumbra::internal::scene::load_scene(&path).unwrap();
    let cases: [(&[&str], RenderOptions); 4] = [
        (
            &["--samples", "0"],
            RenderOptions {
                samples: 0,
                ..RenderOptions::default()
            },
        ),
        (
            &["--width", "0"],
            RenderOptions {
                width: Some(0),
                ..RenderOptions::default()
            },
        ),
        (
            &["--samples", "2000000"],
            RenderOptions {
                samples: 2_000_000,
                ..RenderOptions::default()
            },
        ),
        (
            &["--technique", "pcss", "--depth-bias=-1"],
            RenderOptions {
                technique: "pcss".parse().unwrap(),
                options: {
                    let mut o = penumbra::internal::shadow::TechniqueOptions::default();
                    o.shadow_map.depth_bias = -1.0;
                    o
                },
                ..RenderOptions::default()
            },
        ),
    ];
    for (args, options) in cases {
        let library = render(&scene, &options)
            .expect_err("the library refuses")
            .to_string();
        let mut cli_args = vec!["render", "scene.toml", "-o", "out.png"];
        cli_args.extend_from_slice(args);
        let (code, cli) = penumbra_in(&dir, &cli_args);
        assert_ne!(code, 0, "{args:?}: the command line refuses");
        assert!(
            cli.contains(&library),
            "{args:?}: the command line says\n{cli}\nthe library says\n{library}"
        );
    }
}
