//! Outputs of the 2026-12 fuzz campaign's repros: every output of a
//! command is written all or none, parts and partial results are checked
//! before they are trusted, the output format follows the extension, and
//! stdout write errors are errors, not panics.

mod common;

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
