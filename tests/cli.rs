//! The command line end to end: outputs, channel names, exit codes and
//! error messages.

mod common;

use penumbra::output::read_image;
use std::path::Path;
use std::process::Command;

fn penumbra(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run penumbra");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout),
    )
}

#[test]
fn render_writes_png_and_exr_with_contract_channel_names() {
    let dir = common::scratch_dir("cli-render");
    let png = dir.join("quad.png");
    let exr = dir.join("quad.exr");
    let (ok, msg) = penumbra(&[
        "render",
        "scenes/quad.toml",
        "-o",
        png.to_str().unwrap(),
        "--exr",
        exr.to_str().unwrap(),
        "--aov",
        "depth,position,normal,albedo,mask,vcoef",
        "--width",
        "64",
        "--height",
        "48",
        "--technique",
        "shadow-volumes",
    ]);
    assert!(ok, "{msg}");
    let img = read_image(&exr).expect("read exr");
    assert_eq!((img.width, img.height), (64, 48));
    let mut names: Vec<&str> = img.channels.iter().map(|(n, _)| n.as_str()).collect();
    names.sort();
    let mut want = vec![
        "R",
        "G",
        "B",
        "depth.Z",
        "position.X",
        "position.Y",
        "position.Z",
        "normal.X",
        "normal.Y",
        "normal.Z",
        "albedo.R",
        "albedo.G",
        "albedo.B",
        "mask.Y",
        "vcoef.0",
        "stencil.0",
    ];
    want.sort();
    assert_eq!(names, want);
    let mask = img.channel("mask.Y").expect("mask");
    assert!(mask.contains(&1.0) && mask.iter().all(|&m| m == 0.0 || m == 1.0));
    let vcoef = img.channel("vcoef.0").expect("vcoef");
    assert!(vcoef.contains(&0.0), "the occluder casts a shadow");
    let png_img = read_image(&png).expect("read png");
    assert_eq!((png_img.width, png_img.height), (64, 48));
    // No temporary files left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .expect("dir")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n != "quad.png" && n != "quad.exr")
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn info_reports_the_scene() {
    let (ok, msg) = penumbra(&["info", "scenes/spheres.toml"]);
    assert!(ok, "{msg}");
    assert!(msg.contains("triangles  61562"), "{msg}");
    assert!(msg.contains("lights     1"), "{msg}");
}

/// Every bad invocation fails with a message naming what is wrong, and
/// never leaves an output file.
#[test]
fn bad_input_fails_cleanly() {
    let dir = common::scratch_dir("cli-bad");
    let out = dir.join("out.png");
    let o = out.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["render", "scenes/nope.toml", "-o", o], "nope.toml"),
        (
            &["render", "scenes/quad.toml", "-o", o, "--aov", "depth"],
            "--exr",
        ),
        (
            &[
                "render",
                "scenes/quad.toml",
                "-o",
                o,
                "--exr",
                "x.exr",
                "--aov",
                "colour",
            ],
            "colour",
        ),
        (
            &["render", "scenes/quad.toml", "-o", o, "--threads", "0"],
            "--threads",
        ),
        (
            &["render", "scenes/quad.toml", "-o", o, "--width", "0"],
            "--width",
        ),
        (
            &["render", "scenes/quad.toml", "-o", o, "--width", "20000"],
            "width",
        ),
        (
            &[
                "render",
                "scenes/quad.toml",
                "-o",
                o,
                "--technique",
                "magic",
            ],
            "magic",
        ),
        (
            &["render", "scenes/quad.toml", "-o", o, "--samples", "0"],
            "--samples",
        ),
        (
            &[
                "render",
                "scenes/quad.toml",
                "-o",
                "/nonexistent-dir/x.png",
                "--width",
                "8",
                "--height",
                "8",
            ],
            "/nonexistent-dir/x.png",
        ),
    ];
    for (args, needle) in cases {
        let (ok, msg) = penumbra(args);
        assert!(!ok, "{args:?} should fail");
        assert!(
            msg.contains(needle),
            "{args:?}: message `{msg}` should name `{needle}`"
        );
        assert!(!msg.contains("panicked"), "{args:?} panicked: {msg}");
        assert!(!Path::new(o).exists(), "{args:?} left an output behind");
    }
}

/// Techniques that count opaque occluders only say so, instead of
/// silently dropping semi-opaque casters' shadows; DCS does not warn.
#[test]
fn unsupported_semi_opaque_casters_are_not_silent() {
    let dir = std::env::temp_dir().join(format!("penumbra-cli-warn-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("t.png");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/tinted.toml");
    let (ok, stderr) = penumbra(&[
        "render",
        scene,
        "--technique",
        "wedges",
        "--width",
        "32",
        "--height",
        "32",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert!(stderr.contains("NOT shadowed"), "{stderr}");
    let (ok, stderr) = penumbra(&[
        "render",
        scene,
        "--technique",
        "dcs",
        "--width",
        "32",
        "--height",
        "32",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
}
