//! The command line end to end: outputs, channel names, exit codes and
//! error messages.

use crate::common;

use penumbra::internal::output::read_image;
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
    // dcs shadows every pane; the only warning left is the scene's own
    // (the 0.3 pane is below the camera's 0.5 opacity threshold).
    assert!(!stderr.contains("NOT shadowed"), "{stderr}");
    assert!(
        stderr
            .lines()
            .all(|l| !l.contains("warning") || l.contains("warning: scene:")),
        "{stderr}"
    );
}

/// Runs penumbra with stdout a pipe whose reader is already gone, as in
/// `penumbra diff a.png a.png --json | head -1` once `head` has exited.
fn penumbra_into_closed_pipe(args: &[&str]) -> std::process::Output {
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(writer)
        .output()
        .expect("run penumbra")
}

/// Issue 19.3: printing to a closed pipe ends quietly with the command's
/// own exit code (0 here; `diff` keeps 1 for a failed tolerance), not a
/// panic (exit 101, "failed printing to stdout").
#[test]
fn printing_to_a_closed_pipe_ends_quietly() {
    let dir = common::scratch_dir("cli-pipe");
    let png = dir.join("a.png");
    let p = png.to_str().unwrap();
    let (ok, msg) = penumbra(&[
        "render",
        "scenes/quad.toml",
        "-o",
        p,
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert!(ok, "{msg}");
    let shadowed = dir.join("b.png");
    let q = shadowed.to_str().unwrap();
    let (ok, msg) = penumbra(&[
        "render",
        "scenes/quad.toml",
        "-o",
        q,
        "--width",
        "8",
        "--height",
        "8",
        "--technique",
        "shadow-volumes",
    ]);
    assert!(ok, "{msg}");
    for (args, code) in [
        (vec!["diff", p, p, "--json"], 0),
        (vec!["diff", p, p], 0),
        (vec!["diff", p, q, "--max-abs", "0"], 1),
        (vec!["info", "scenes/spheres.toml"], 0),
    ] {
        let out = penumbra_into_closed_pipe(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {stderr}");
        assert!(
            !stderr.contains("panicked") && !stderr.contains("Broken pipe"),
            "{args:?}: {stderr}"
        );
    }
}

/// Issue 19.2: an output that cannot be written fails the run before the
/// render, and no other output of the run is left behind.
#[test]
fn a_failed_output_leaves_no_other_output() {
    let dir = common::scratch_dir("cli-all-or-none");
    let png = dir.join("o.png");
    let bad_exr = dir.join("missing-dir/x.exr");
    let (ok, msg) = penumbra(&[
        "render",
        "scenes/quad.toml",
        "-o",
        png.to_str().unwrap(),
        "--exr",
        bad_exr.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert!(!ok);
    assert!(
        msg.contains("missing-dir") && msg.contains("does not exist"),
        "{msg}"
    );
    assert!(!png.exists(), "o.png was written although the EXR failed");
    // The same with an existing PNG: it keeps its old content.
    std::fs::write(&png, b"old").unwrap();
    let (ok, _) = penumbra(&[
        "render",
        "scenes/quad.toml",
        "-o",
        png.to_str().unwrap(),
        "--exr",
        dir.to_str().unwrap(), // a directory: refused
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert!(!ok);
    assert_eq!(std::fs::read(&png).unwrap(), b"old");
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["o.png"], "temporary files left behind");
}

/// Issue 19.1 through the CLI: `-o /proc/version` says why it cannot be
/// written instead of "No such file or directory"; `-o /dev/null` works
/// and leaves the device alone.
#[test]
fn special_output_paths() {
    let args = |o: &'static str| {
        [
            "render",
            "scenes/quad.toml",
            "-o",
            o,
            "--width",
            "8",
            "--height",
            "8",
        ]
    };
    if Path::new("/proc/version").exists() {
        // Through --exr, which takes any name (-o's extension picks the
        // format, and `version` has none).
        let dir = common::scratch_dir("cli-proc");
        let png = dir.join("a.png");
        let mut a = args("/proc/version").to_vec();
        a[3] = png.to_str().unwrap();
        a.extend(["--exr", "/proc/version"]);
        let (ok, msg) = penumbra(&a);
        assert!(!ok);
        assert!(!png.exists());
        assert!(
            msg.contains("/proc/version") && !msg.contains("No such file"),
            "{msg}"
        );
        assert!(msg.contains("does not accept new files"), "{msg}");
        let _ = std::fs::remove_dir_all(&dir);
    }
    if Path::new("/dev/null").exists() {
        let (ok, msg) = penumbra(&args("/dev/null"));
        assert!(ok, "{msg}");
        use std::os::unix::fs::FileTypeExt;
        let ft = std::fs::metadata("/dev/null").unwrap().file_type();
        assert!(ft.is_char_device(), "/dev/null was replaced");
    }
    if Path::new("/dev/full").exists() {
        let (ok, msg) = penumbra(&args("/dev/full"));
        assert!(!ok, "writing to /dev/full must fail");
        assert!(msg.contains("/dev/full"), "{msg}");
    }
}

/// Issue 19.10: one image-side limit, 16384, for `--width`/`--height` and
/// scene files.
#[test]
fn one_image_size_limit() {
    for flag in ["--width", "--height"] {
        let (ok, msg) = penumbra(&[
            "render",
            "scenes/quad.toml",
            "-o",
            "/dev/null",
            flag,
            "16385",
        ]);
        assert!(!ok);
        assert!(msg.contains(flag) && msg.contains("1..=16384"), "{msg}");
    }
    let dir = common::scratch_dir("cli-size-limit");
    for (side, ok_expected) in [(16384, true), (16385, false)] {
        let scene = dir.join(format!("s{side}.toml"));
        std::fs::write(
            &scene,
            format!("[camera]\neye = [0, 1, 2]\ntarget = [0, 0, 0]\nfov_y = 40\nwidth = {side}\nheight = 1\n"),
        )
        .unwrap();
        let (ok, msg) = penumbra(&["info", scene.to_str().unwrap()]);
        assert_eq!(ok, ok_expected, "{side}: {msg}");
        if !ok {
            assert!(msg.contains(":5:") && msg.contains("1..=16384"), "{msg}");
        }
    }
}

/// Issue 19.7: a sphere at the documented maximum tessellation is
/// estimated before it is generated: under a 4 GiB address-space limit it
/// is a clear error at its line, at once, not an allocation abort.
#[test]
fn huge_sphere_is_refused_before_allocating() {
    let dir = common::scratch_dir("cli-huge-sphere");
    let scene = dir.join("big.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nfov_y = 45\n\
         [[object]]\nshape = \"sphere\"\nsegments = 4096\nrings = 4096\n",
    )
    .unwrap();
    let started = std::time::Instant::now();
    let out = Command::new("/bin/sh")
        .arg("-c")
        .arg("ulimit -v 4194304 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_penumbra"))
        .args(["render", scene.to_str().unwrap(), "-o", "/dev/null"])
        .output()
        .expect("run penumbra under ulimit");
    let msg = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains("big.toml:8:") && msg.contains("33546240 triangles"),
        "{msg}"
    );
    assert!(msg.contains("GiB available"), "{msg}");
    assert!(
        started.elapsed().as_secs() < 10,
        "refused only after {:?}",
        started.elapsed()
    );
}

/// `PENUMBRA_SIMD` picks the level of the run-time dispatched routines
/// (`--explain` names it): `baseline` and `v3` give the default's bits (the reference, whose walks
/// are dispatched, on a scene with penumbrae), a bad value or a level
/// this CPU lacks is an error naming the variable.
#[test]
fn simd_level_from_the_environment() {
    use penumbra::internal::simd::level::Level;
    let dir = common::scratch_dir("cli-simd-level");
    let run = |level: Option<&str>, name: &str| {
        let exr = dir.join(format!("{name}.exr"));
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_penumbra"));
        cmd.args(["render", "scenes/spheres.toml", "--technique", "reference"])
            .args(["--samples", "16", "--width", "80", "--height", "60"])
            .args(["-o", dir.join(format!("{name}.png")).to_str().unwrap()])
            .args(["--exr", exr.to_str().unwrap(), "--explain"])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env_remove("PENUMBRA_SIMD");
        if let Some(level) = level {
            cmd.env("PENUMBRA_SIMD", level);
        }
        let out = cmd.output().expect("run penumbra");
        let text = String::from_utf8_lossy(&out.stderr).into_owned();
        (out.status.success(), text, std::fs::read(exr).ok())
    };
    let (ok, msg, default) = run(None, "default");
    assert!(ok, "{msg}");
    let (ok, msg, baseline) = run(Some("baseline"), "baseline");
    assert!(ok, "{msg}");
    // `--explain` says which level ran.
    assert!(
        msg.contains("simd: dispatched routines at baseline") && msg.contains("AVX kernels off"),
        "{msg}"
    );
    assert!(
        default.is_some() && baseline == default,
        "baseline changes bits"
    );
    let (ok, msg, v3) = run(Some("v3"), "v3");
    if Level::V3.supported() {
        assert!(
            ok && msg.contains("simd: dispatched routines at v3"),
            "{msg}"
        );
        assert!(v3 == default, "v3 changes bits");
    } else {
        assert!(
            !ok && msg.contains("PENUMBRA_SIMD") && msg.contains("lacks"),
            "{msg}"
        );
    }
    let (ok, msg, _) = run(Some("avx9"), "bad");
    assert!(!ok, "a bad level is accepted");
    assert!(
        msg.contains("PENUMBRA_SIMD") && msg.contains("avx9"),
        "{msg}"
    );
}
