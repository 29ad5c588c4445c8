//! Outputs of the 2026-12 fuzz campaign's repros: every output of a
//! command is written all or none, parts and partial results are checked
//! before they are trusted, the output format follows the extension, and
//! stdout write errors are errors, not panics.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_penumbra"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run penumbra")
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned() + &String::from_utf8_lossy(&o.stdout)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The names in `dir`, sorted (temporary files would show here).
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Repro `techniques-stdout-error-panics`: stdout on a full disk is an
/// error naming `<stdout>` with exit 2 (was a panic, 101), for the
/// listings and for clap's `--help`/`--version` (was a silent 0).
#[test]
fn stdout_write_errors_are_errors() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        return; // no /dev/full on this system
    };
    for args in [
        &["techniques"][..],
        &["techniques", "--names"],
        &["techniques", "--markdown"],
        &["--help"],
        &["--version"],
        &["render", "--help"],
    ] {
        let out = bin()
            .args(args)
            .stdout(full.try_clone().unwrap())
            .output()
            .unwrap();
        let msg = text(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {msg}");
        assert!(
            msg.contains("penumbra: error: <stdout>:") && !msg.contains("panicked"),
            "{args:?}: {msg}"
        );
    }
    // A closed pipe stays a quiet success.
    for args in [&["techniques"][..], &["--help"]] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = bin().args(args).stdout(writer).output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{args:?}: {}", text(&out));
        assert!(out.stderr.is_empty(), "{args:?}: {}", text(&out));
    }
}

/// A band render of the shipped quad at 40×130 (two bands) with layers.
fn quad_args<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut a = vec![
        "render",
        "scenes/quad.toml",
        "--aov",
        "vcoef,mask",
        "--width",
        "40",
        "--height",
        "130",
        "--threads",
        "1",
        "--samples",
        "4",
    ];
    a.extend_from_slice(extra);
    a
}

/// Renders both bands of [`quad_args`] into `dir/p1`, `dir/p2`.
fn two_parts(dir: &Path) -> (PathBuf, PathBuf) {
    let (p1, p2) = (dir.join("p1"), dir.join("p2"));
    for (i, p) in [("1/2", &p1), ("2/2", &p2)] {
        let out = run(&quad_args(&["--tiles", i, "-o", s(p)]));
        assert!(out.status.success(), "{}", text(&out));
    }
    (p1, p2)
}

/// Repro `merge-tiles-accepts-corrupt-part`: a float of a part's data
/// overwritten at the same length (1.0, or a NaN) is refused, naming the
/// part, instead of merging into a different image; a format-1 part (no
/// checksum) is refused with the format named.
#[test]
fn damaged_parts_are_refused() {
    let dir = common::scratch_dir("safety-damaged-part");
    let (p1, p2) = two_parts(&dir);
    let bytes = std::fs::read(&p2).unwrap();
    let mut at_10 = bytes.clone();
    let i = at_10.len() * 10 / 100 / 4 * 4;
    at_10[i..i + 4].copy_from_slice(&1.0f32.to_le_bytes());
    let mut nan = bytes.clone();
    let j = nan.len() - 4000;
    nan[j..j + 4].copy_from_slice(&[0xff, 0xff, 0xff, 0x7f]);
    for (name, damaged) in [("one", at_10), ("nan", nan)] {
        let bad = dir.join(name);
        std::fs::write(&bad, damaged).unwrap();
        let m = dir.join("m.png");
        let out = run(&["merge-tiles", s(&p1), s(&bad), "-o", s(&m)]);
        let msg = text(&out);
        assert_eq!(out.status.code(), Some(2), "{msg}");
        assert!(
            msg.contains(s(&bad)) && msg.contains("damaged") && msg.contains("2/2"),
            "{msg}"
        );
        assert!(!m.exists());
    }
    // The undamaged parts still merge.
    let out = run(&["merge-tiles", s(&p1), s(&p2), "-o", s(&dir.join("ok.png"))]);
    assert!(out.status.success(), "{}", text(&out));
    // An old part (format 1, no checksum) is named as such.
    let old = dir.join("old");
    let mut v1 = std::fs::read(&p1).unwrap();
    v1[b"PENUMBRA-TILE ".len()] = b'1';
    std::fs::write(&old, v1).unwrap();
    let out = run(&["merge-tiles", s(&old), s(&p2), "-o", s(&dir.join("o.png"))]);
    let msg = text(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(
        msg.contains(s(&old)) && msg.contains("part format 1"),
        "{msg}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Repro `merge-tiles-output-overwrites-input`: an output that is one of
/// the parts (by name, or through a link) is refused and the part kept.
#[test]
fn merge_never_overwrites_a_part() {
    let dir = common::scratch_dir("safety-merge-input");
    let (p1, p2) = two_parts(&dir);
    let png = dir.join("p1.png");
    std::fs::copy(&p1, &png).unwrap();
    let link = dir.join("link.exr");
    std::os::unix::fs::symlink(&p2, &link).unwrap();
    let before = (std::fs::read(&png).unwrap(), std::fs::read(&p2).unwrap());
    for args in [
        vec!["merge-tiles", s(&png), s(&p2), "-o", s(&png)],
        vec!["merge-tiles", s(&png), s(&p2), "-o", s(&link)],
        vec![
            "merge-tiles",
            s(&png),
            s(&p2),
            "-o",
            s(&dir.join("m.png")),
            "--exr",
            s(&p2),
        ],
    ] {
        let out = run(&args);
        let msg = text(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {msg}");
        assert!(msg.contains("same file as the input"), "{msg}");
    }
    assert_eq!(
        before,
        (std::fs::read(&png).unwrap(), std::fs::read(&p2).unwrap())
    );
    assert!(!dir.join("m.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Point 6: the extension of `-o` decides the format (`x.exr` alone is
/// an EXR with the layers, byte for byte the `--exr` of a PNG render);
/// other extensions are refused naming `--output` and the accepted ones;
/// parts keep any name and `merge-tiles` follows the same rule.
#[test]
fn the_extension_decides_the_format() {
    let dir = common::scratch_dir("safety-format");
    let d = |f: &str| dir.join(f);
    let out = run(&quad_args(&[
        "-o",
        s(&d("both.png")),
        "--exr",
        s(&d("both.exr")),
    ]));
    assert!(out.status.success(), "{}", text(&out));
    let out = run(&quad_args(&["-o", s(&d("alone.exr"))]));
    assert!(out.status.success(), "{}", text(&out));
    let alone = std::fs::read(d("alone.exr")).unwrap();
    assert_eq!(&alone[..4], &[0x76, 0x2f, 0x31, 0x01], "not an EXR");
    assert_eq!(alone, std::fs::read(d("both.exr")).unwrap());
    for bad in ["x.tif", "x.jpg", "x", "x.png.part"] {
        let out = run(&quad_args(&["-o", s(&d(bad))]));
        let msg = text(&out);
        assert_eq!(out.status.code(), Some(2), "{bad}: {msg}");
        assert!(
            msg.contains("--output") && msg.contains(".png") && msg.contains(".exr"),
            "{bad}: {msg}"
        );
        assert!(!d(bad).exists());
    }
    // --aov with an EXR -o needs no --exr; with a PNG -o alone it does.
    let out = run(&[
        "render",
        "scenes/quad.toml",
        "-o",
        s(&d("n.png")),
        "--aov",
        "depth",
    ]);
    assert!(text(&out).contains("--aov"), "{}", text(&out));
    // Parts keep any name; merge-tiles picks the format by extension too.
    let (p1, p2) = two_parts(&dir);
    let out = run(&["merge-tiles", s(&p1), s(&p2), "-o", s(&d("m.exr"))]);
    assert!(out.status.success(), "{}", text(&out));
    assert_eq!(
        std::fs::read(d("m.exr")).unwrap(),
        std::fs::read(d("both.exr")).unwrap()
    );
    let out = run(&["merge-tiles", s(&p1), s(&p2), "-o", s(&d("m.bmp"))]);
    assert!(text(&out).contains("--output"), "{}", text(&out));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Repro `exr-trailing-slash-replaces-png`: an output path ending in `/`
/// is refused before the render and an existing PNG (also behind a
/// symlinked `-o`) keeps its content, for `render` and `merge-tiles`.
#[test]
fn a_directory_like_output_path_changes_nothing() {
    let dir = common::scratch_dir("safety-trailing-slash");
    let png = dir.join("o.png");
    let target = dir.join("target.png");
    let link = dir.join("link.png");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let (p1, p2) = two_parts(&dir);
    let slash = format!("{}/", dir.join("o.exr").display());
    for o in [&png, &link] {
        std::fs::write(&png, b"old").unwrap();
        std::fs::write(&target, b"old").unwrap();
        for args in [
            quad_args(&["-o", s(o), "--exr", &slash]),
            vec!["merge-tiles", s(&p1), s(&p2), "-o", s(o), "--exr", &slash],
            quad_args(&["-o", s(o), "--exr", s(&dir.join("e.exr/."))]),
        ] {
            let out = run(&args);
            let msg = text(&out);
            assert_eq!(out.status.code(), Some(2), "{args:?}: {msg}");
            assert!(msg.contains("ends in /"), "{msg}");
            assert_eq!(std::fs::read(&png).unwrap(), b"old");
            assert_eq!(std::fs::read(&target).unwrap(), b"old");
        }
    }
    assert_eq!(
        listing(&dir),
        ["link.png", "o.png", "p1", "p2", "target.png"],
        "temporary files left behind"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A commit whose second rename fails (its directory vanished after the
/// outputs were staged) puts the first output's old content back.
#[test]
fn a_late_rename_failure_restores_replaced_outputs() {
    use penumbra::internal::output::OutputSet;
    let dir = common::scratch_dir("safety-undo");
    let (a, sub) = (dir.join("a.png"), dir.join("sub"));
    std::fs::create_dir(&sub).unwrap();
    std::fs::write(&a, b"old").unwrap();
    let mut set = OutputSet::new();
    let put = |bytes: &'static [u8]| {
        move |tmp: &Path| std::fs::write(tmp, bytes).map_err(|e| penumbra::Error::io(tmp, e))
    };
    set.stage(&a, put(b"new")).unwrap();
    set.stage(&sub.join("b.png"), put(b"new")).unwrap();
    std::fs::remove_dir_all(&sub).unwrap();
    assert!(set.commit().is_err());
    assert_eq!(std::fs::read(&a).unwrap(), b"old");
    assert_eq!(listing(&dir), ["a.png"], "backups left behind");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Repro `verify-failure-leaves-png`: a render whose `--verify` fails
/// (exit 2) writes no output; the help says so.
#[test]
fn a_failed_verify_writes_nothing() {
    let dir = common::scratch_dir("safety-verify");
    // Centre silhouettes miss the bunny's self-shadowing edges: the
    // certificate fails (tests/it/verify.rs).
    let scene = std::path::PathBuf::from("scenes/bunny.toml");
    let (png, exr) = (dir.join("v.png"), dir.join("v.exr"));
    let out = run(&[
        "render",
        s(&scene),
        "-o",
        s(&png),
        "--exr",
        s(&exr),
        "--technique",
        "dcs",
        "--silhouettes",
        "centre",
        "--width",
        "128",
        "--height",
        "128",
        "--samples",
        "32",
        "--seed",
        "0",
        "--verify",
        "20000",
    ]);
    let msg = text(&out);
    assert_eq!(out.status.code(), Some(2), "{msg}");
    assert!(msg.contains("disagree"), "{msg}");
    assert!(!png.exists() && !exr.exists(), "unverified output written");
    assert!(listing(&dir).is_empty());
    let help = text(&run(&["render", "--help"]));
    assert!(help.contains("no output is written"), "{help}");
    let help = text(&run(&["compare", "--help"]));
    assert!(help.contains("once the results are written"), "{help}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Two shards of a tiny compare sweep of the shipped quad into
/// `dir/sh/s1`, `dir/sh/s2`.
fn two_shards(dir: &Path) -> (PathBuf, PathBuf) {
    let cache = dir.join("cache");
    let shards = (dir.join("sh/s1"), dir.join("sh/s2"));
    for (i, out) in [("1/2", &shards.0), ("2/2", &shards.1)] {
        let o = run(&[
            "compare",
            "scenes/quad.toml",
            "--techniques",
            "dcs,shadow-map",
            "--samples",
            "4,8",
            "--reference-samples",
            "16",
            "--width",
            "24",
            "--height",
            "24",
            "--threads",
            "1",
            "--repeat",
            "1",
            "--shard",
            i,
            "--out",
            s(out),
            "--cache-dir",
            s(&cache),
        ]);
        assert!(o.status.success(), "{}", text(&o));
    }
    shards
}

/// Repro `merge-image-path-traversal`: a partial result's image names are
/// never followed (`../../../victim.txt` would have been read from outside
/// the shard and written outside `--out`); a damaged name is refused,
/// naming the partial, and the refused merge leaves no `--out` behind.
#[test]
fn merge_takes_no_paths_from_partials() {
    let dir = common::scratch_dir("safety-merge-paths");
    let (s1, s2) = two_shards(&dir);
    let partial = s1.join("shard-1-of-2.json");
    let original = std::fs::read_to_string(&partial).unwrap();
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, b"precious").unwrap();
    let edit = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut j: serde_json::Value = serde_json::from_str(&original).unwrap();
        f(&mut j);
        std::fs::write(&partial, serde_json::to_string(&j).unwrap()).unwrap();
    };
    let out_dir = dir.join("out/a/b");
    let edits: [&dyn Fn(&mut serde_json::Value); 4] = [
        &|j| j["runs"][0]["image"] = "../../../victim.txt".into(),
        &|j| j["runs"][0]["image"] = "".into(),
        &|j| j["runs"][0]["heatmaps"] = serde_json::json!([""]),
        &|j| j["scenes"][0]["dir"] = "../..".into(),
    ];
    for (k, e) in edits.iter().enumerate() {
        edit(*e);
        let o = run(&["compare", "--merge", s(&s1), s(&s2), "--out", s(&out_dir)]);
        let msg = text(&o);
        if k < 3 {
            assert_eq!(o.status.code(), Some(2), "edit {k}: {msg}");
            assert!(msg.contains("shard-1-of-2.json"), "edit {k}: {msg}");
            assert!(!dir.join("out").exists(), "edit {k}: --out left behind");
        } else {
            // The scene's directory is derived, not read: the merge works.
            assert!(o.status.success(), "edit {k}: {msg}");
            let _ = std::fs::remove_dir_all(dir.join("out"));
        }
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    }
    // A missing image is named before anything is written.
    std::fs::write(&partial, &original).unwrap();
    let image = std::fs::read_dir(s2.join("images"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| !p.ends_with("reference.png"))
        .unwrap();
    std::fs::remove_file(&image).unwrap();
    let o = run(&["compare", "--merge", s(&s1), s(&s2), "--out", s(&out_dir)]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains(s(&image)), "{}", text(&o));
    assert!(!dir.join("out").exists(), "--out left behind");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Repro `sweep-newline-injects-sbatch-line`: an option value with a
/// newline (or another control character) is refused naming the option,
/// and writes no script.
#[test]
fn sweep_refuses_multi_line_values() {
    let dir = common::scratch_dir("safety-sweep-newline");
    let out = dir.join("out");
    for (option, value) in [
        ("--partition", "p\n#SBATCH --evil"),
        ("--job-name", "a\rb"),
        ("--time", "1:00\n"),
        ("--mem", "4G\n#SBATCH --x"),
        ("--account", "a\u{1b}b"),
        ("--qos", "q\nq"),
        ("--constraint", "c\nc"),
        ("--merge-time", "1\n2"),
        ("--merge-mem", "1\n2"),
        ("--setup", "module load x\nrm -rf /"),
        ("--sbatch-arg", "--mail-type=END\n#SBATCH --evil"),
        ("--log-dir", "logs\n#SBATCH --evil"),
    ] {
        let arg = format!("{option}={value}");
        let o = run(&[
            "sweep",
            "--slurm",
            "--out",
            s(&out),
            "--shards",
            "2",
            &arg,
            "--",
            "scenes/quad.toml",
            "--techniques",
            "dcs",
        ]);
        let msg = text(&o);
        assert_eq!(o.status.code(), Some(2), "{option}: {msg}");
        assert!(msg.contains(&format!("`{option}`")), "{option}: {msg}");
        assert!(!out.exists(), "{option}: scripts written");
    }
    let o = run(&[
        "sweep",
        "--slurm",
        "--out",
        s(&dir.join("new\nline")),
        "--shards",
        "2",
        "--dry-run",
        "--",
        "scenes/quad.toml",
    ]);
    assert!(text(&o).contains("`--out`"), "{}", text(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `sweep --submit` without Slurm leaves nothing behind: a missing
/// sbatch is found before anything is written, and a failing one (nothing
/// queued) has what this run created removed again (a folder that was
/// there before stays).
#[test]
fn a_failed_submission_leaves_nothing() {
    let dir = common::scratch_dir("safety-sweep-submit");
    let out = dir.join("new/out");
    let sweep = |out: &Path, sbatch: &str| {
        run(&[
            "sweep",
            "--slurm",
            "--out",
            s(out),
            "--shards",
            "2",
            "--references-job",
            "--submit",
            "--sbatch",
            sbatch,
            "--",
            "scenes/quad.toml",
        ])
    };
    let o = sweep(&out, "/nonexistent/sbatch");
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("`--sbatch`"), "{}", text(&o));
    assert!(!dir.join("new").exists());
    let o = sweep(&out, "no-such-sbatch-on-the-path");
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(!dir.join("new").exists());
    // An sbatch that runs and fails: everything created goes again.
    let fail = "/bin/false";
    if Path::new(fail).exists() {
        let o = sweep(&out, fail);
        assert_eq!(o.status.code(), Some(2), "{}", text(&o));
        assert!(text(&o).contains("--submit"), "{}", text(&o));
        assert!(!dir.join("new").exists(), "{:?}", listing(&dir));
        let keep = dir.join("keep");
        std::fs::create_dir(&keep).unwrap();
        std::fs::write(keep.join("mine"), b"x").unwrap();
        let o = sweep(&keep, fail);
        assert_eq!(o.status.code(), Some(2));
        assert_eq!(listing(&keep), ["mine"]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}
