//! Golden hashes: every shipped scene × every registered technique, rendered
//! small by the `penumbra` binary as a user would, must give the recorded
//! bits — the PNG's 8-bit pixels and every EXR layer's `f32` values.
//!
//! This is the record that proves a refactoring changed no output bit (the
//! SIMD levels and thread counts are checked against each other elsewhere;
//! this checks against history). When an image is meant to change,
//! regenerate the record with
//!
//! ```text
//! PENUMBRA_GOLDEN=update cargo test --release --test it golden::
//! ```
//!
//! and commit `tests/golden/hashes.txt` with the change that explains it.
//! A failure prints every entry that changed.

use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use crate::common;

const RECORD: &str = "tests/golden/hashes.txt";
const WIDTH: u32 = 64;
const HEIGHT: u32 = 48;
const SAMPLES: u32 = 16;
const AOVS: &str = "depth,position,normal,albedo,mask,vcoef";

/// One render to hash: a shipped scene and a technique with its defaults,
/// or with `extra` arguments under its own record name.
struct Run {
    scene: String,
    technique: String,
    /// The record's name for it: the technique's, or `technique:variant`.
    name: String,
    extra: &'static [&'static str],
}

/// Variants recorded beside a technique's defaults: DCS's counting path
/// alone, which its cost choice replaces by rays on small renders of
/// scenes of many triangles (the shipped 61k–69k ones at this size).
const VARIANTS: [(&str, &str, &[&str]); 1] = [("dcs", "dcs:counted", &["--dcs-rays", "never"])];

fn binary() -> &'static str {
    env!("CARGO_BIN_EXE_penumbra")
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The first 16 hex digits of SHA-256: 64 bits, ample to notice a change.
fn digest(bytes: &[u8]) -> String {
    let sum = Sha256::digest(bytes);
    sum.iter().take(8).map(|b| format!("{b:02x}")).collect()
}

fn techniques() -> Vec<String> {
    let out = Command::new(binary())
        .args(["techniques", "--names"])
        .output()
        .expect("run penumbra techniques");
    assert!(out.status.success(), "penumbra techniques --names failed");
    String::from_utf8(out.stdout)
        .expect("technique names are UTF-8")
        .lines()
        .map(str::to_owned)
        .collect()
}

fn scenes() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(repo().join("scenes"))
        .expect("read scenes/")
        .filter_map(|e| {
            let path = e.ok()?.path();
            (path.extension()? == "toml").then(|| path.file_stem()?.to_str().map(str::to_owned))?
        })
        .collect();
    names.sort();
    names
}

/// Renders `run` into `dir` and returns its record entries (item → hash);
/// a refused combination is recorded as refused.
fn hash_run(run: &Run, dir: &Path) -> BTreeMap<String, String> {
    let stem = format!("{}-{}", run.scene, run.name.replace(':', "-"));
    let png = dir.join(format!("{stem}.png"));
    let exr = dir.join(format!("{stem}.exr"));
    let out = Command::new(binary())
        .current_dir(repo())
        .args(["render", &format!("scenes/{}.toml", run.scene)])
        .args(["--technique", &run.technique])
        .args(run.extra)
        .args(["--samples", &SAMPLES.to_string()])
        .args([
            "--width",
            &WIDTH.to_string(),
            "--height",
            &HEIGHT.to_string(),
        ])
        .args(["--threads", "1", "--aov", AOVS])
        .arg("-o")
        .arg(&png)
        .arg("--exr")
        .arg(&exr)
        .output()
        .expect("run penumbra render");
    let mut entries = BTreeMap::new();
    if !out.status.success() {
        entries.insert("refused".to_owned(), "-".to_owned());
        return entries;
    }
    let pixels = image::open(&png).expect("read the PNG").to_rgb8();
    entries.insert("png".to_owned(), digest(pixels.as_raw()));
    let layers = penumbra::internal::output::read_image(&exr).expect("read the EXR");
    for (name, values) in &layers.channels {
        let bytes: Vec<u8> = values
            .iter()
            .flat_map(|v| v.to_bits().to_le_bytes())
            .collect();
        entries.insert(format!("exr:{name}"), digest(&bytes));
    }
    entries
}

/// The record as lines `scene technique item hash`, sorted.
fn render_record() -> Vec<String> {
    let techniques = techniques();
    let runs: Vec<Run> = scenes()
        .into_iter()
        .flat_map(|scene| {
            let defaults = techniques.iter().map(|technique| Run {
                scene: scene.clone(),
                technique: technique.clone(),
                name: technique.clone(),
                extra: &[],
            });
            let variants = VARIANTS.iter().map(|&(technique, name, extra)| Run {
                scene: scene.clone(),
                technique: technique.to_owned(),
                name: name.to_owned(),
                extra,
            });
            defaults.chain(variants).collect::<Vec<_>>()
        })
        .collect();
    let dir = common::ScratchDir::new("golden");
    let next = AtomicUsize::new(0);
    let lines = Mutex::new(Vec::new());
    let workers = std::thread::available_parallelism().map_or(2, |n| n.get().min(4));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(run) = runs.get(i) else { break };
                let entries = hash_run(run, &dir.0);
                let mut lines = lines.lock().expect("no worker panicked");
                for (item, hash) in entries {
                    lines.push(format!("{} {} {} {}", run.scene, run.name, item, hash));
                }
            });
        }
    });
    let mut lines = lines.into_inner().expect("no worker panicked");
    lines.sort();
    lines
}

/// `scene technique item` → hash.
fn keyed(lines: &[String]) -> BTreeMap<String, String> {
    lines
        .iter()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .filter_map(|l| {
            let (key, hash) = l.rsplit_once(' ')?;
            Some((key.to_owned(), hash.to_owned()))
        })
        .collect()
}

#[test]
fn every_scene_and_technique_gives_the_recorded_bits() {
    let got = render_record();
    let path = repo().join(RECORD);
    if std::env::var("PENUMBRA_GOLDEN").as_deref() == Ok("update") {
        let header = format!(
            "# penumbra golden hashes: scene technique item sha256[..16]\n\
             # {WIDTH}x{HEIGHT}, {SAMPLES} samples, --aov {AOVS}; regenerate with\n\
             # PENUMBRA_GOLDEN=update cargo test --release --test it golden::\n"
        );
        std::fs::create_dir_all(path.parent().expect("record has a folder")).expect("mkdir");
        std::fs::write(&path, header + &got.join("\n") + "\n").expect("write the record");
        eprintln!("golden: wrote {} entries to {RECORD}", got.len());
        return;
    }
    let recorded = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{RECORD}: {e} (create it with PENUMBRA_GOLDEN=update)"));
    let want = keyed(&recorded.lines().map(str::to_owned).collect::<Vec<_>>());
    let got = keyed(&got);
    let mut changes = Vec::new();
    for (key, hash) in &want {
        match got.get(key) {
            None => changes.push(format!("  gone:    {key} (was {hash})")),
            Some(h) if h != hash => changes.push(format!("  changed: {key}: {hash} -> {h}")),
            Some(_) => {}
        }
    }
    for (key, hash) in &got {
        if !want.contains_key(key) {
            changes.push(format!("  new:     {key} {hash}"));
        }
    }
    assert!(
        changes.is_empty(),
        "{} of {} golden entries differ from {RECORD}:\n{}\n\
         If the change is intended, regenerate: PENUMBRA_GOLDEN=update cargo test --release --test it golden::",
        changes.len(),
        want.len(),
        changes.join("\n")
    );
}
