//! A fuzz harness on stable Rust: seeded mutations of the shipped scenes
//! and of small OBJ, MTL and texture inputs, and random command lines for
//! `render`, `diff` and `info`. Every case must end in one of two ways:
//!
//! - an error that names the file and line (scene, OBJ, MTL, texture
//!   references) or the parameter (command line, render limits), or the
//!   output or image path it is about, or
//! - an image (rendered at 16 × 16 by a technique from the registry)
//!   with no NaN in its radiance or in any layer,
//!
//! and never in a panic, a signal (abort, segfault) or a hang.
//!
//! Case kinds (`PENUMBRA_FUZZ_KIND=<name>` runs only one; a reported
//! case of such a run is rerun with the same setting): `scene`, `obj`,
//! `ply` (ASCII, binary little and big endian), `gltf` (its JSON, its
//! external buffer, or a GLB), `mtl`, `texture` (mutated inputs, loaded and
//! rendered; a binary PLY or glTF error names its byte offset or JSON
//! pointer where a text file's names its line); `render-cli`,
//! `print-cli` (`render`, `diff`, `info` command lines); `tiles` (two
//! band parts made once per worker, one mutated at or off its length or
//! in a header field, reordered, repeated or missing, merged to odd
//! names: a clean error naming a part or an output with nothing replaced
//! or left behind, or a merge equal bit for bit to the unmutated one);
//! `partials` (two `compare --shard` results made once per worker, a
//! shard's JSON mutated with names that leave the shard, numbers, types,
//! truncation, then `compare --merge`: an error naming a shard file with
//! no `--out` left, or success; either way nothing outside `--out`
//! changes); `special` (a FIFO, `/dev/zero`, `/dev/null` or a directory
//! as scene, OBJ, MTL, texture, `diff` image or tile part: refused naming
//! it; `/dev/full` as stdout of `techniques`, `diff` and `--help`: exit 2
//! naming `<stdout>`; a directory, a path ending in `/`, a link to an
//! existing file, a FIFO with a reader as `render`/`merge-tiles` outputs:
//! a failure replaces no file); `options` (random command lines of every
//! subcommand, options enumerated from clap's `Cli::command()`, values
//! valid, at the edges or garbage; `sweep` always a dry run, which must
//! write nothing); `agreement` (casters touching, just short of or
//! entering a rect or sphere light, objects with `receive_shadows =
//! false`: every technique refuses naming `--technique` or gives a finite
//! `vcoef` layer that is 1 on non-receiving pixels; an exact technique's
//! layer differs from the reference's by more than 1/16 on at most 0.5 %
//! of the surface pixels).
//!
//! `fuzz` runs the cases in a worker process (this test binary, test
//! `fuzz_worker`) under a 4 GiB address-space limit (`ulimit -v`), so
//! that a crash or a hang ends only the worker: the parent knows the case
//! it was running, reports it and starts a new worker after it. Knobs
//! (environment):
//!
//! - `PENUMBRA_FUZZ_CASES` (default 4000, about a minute on a loaded
//!   two-core machine), `PENUMBRA_FUZZ_SEED` (run seed, default 1),
//!   `PENUMBRA_FUZZ_TIMEOUT` (seconds per case, default 60);
//! - `PENUMBRA_FUZZ_CASE_SEED=0x...` reruns one reported case in-process,
//!   printing its inputs (kept in the printed directory) and its outcome.

use crate::common;

use clap::Parser;
use common::Rng;
use glam::Vec3;
use penumbra::internal::output::{read_image, write_exr, write_png, Layer};
use penumbra::internal::render::{render, Aov, RenderOptions};
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::scene::load_scene;
use penumbra::internal::shadow::dcs::{
    CoverageTest, DcsMode, RayChoice, SilhouetteMode, TransmittanceMode,
};
use penumbra::internal::shadow::kit::stsv::Filter;
use penumbra::internal::shadow::soft_shadow_map::{Accumulate, Lookup};
use penumbra::Error;
use std::fmt::Write as _;
use std::io::Write as _;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const DEFAULT_CASES: u64 = 4000;
const DEFAULT_TIMEOUT_S: u64 = 60;
/// The worker's address-space limit, KiB (4 GiB).
const ADDRESS_SPACE_KIB: u64 = 4 << 20;

fn env_u64(name: &str) -> Option<u64> {
    let v = std::env::var(name).ok()?;
    let v = v.trim();
    match v.strip_prefix("0x") {
        Some(hex) => u64::from_str_radix(hex, 16).ok(),
        None => v.parse().ok(),
    }
}

/// The seed of case `index` of a run: a SplitMix64 step, so that nearby
/// indices give unrelated cases.
fn case_seed(run_seed: u64, index: u64) -> u64 {
    Rng(run_seed ^ index.wrapping_mul(0xd1b5_4a32_d192_ed03)).next_u64()
}

// ------------------------------------------------------------ inputs ----

fn manifest() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The shipped scenes' text with relative file references made absolute,
/// so that a mutated copy in a scratch directory still finds its models.
fn shipped_scenes() -> &'static [(String, String)] {
    static SCENES: OnceLock<Vec<(String, String)>> = OnceLock::new();
    SCENES.get_or_init(|| {
        let dir = manifest().join("scenes");
        let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
            .expect("scenes/")
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        names.sort();
        assert!(names.len() >= 5, "the shipped scenes are the corpus");
        names
            .iter()
            .map(|p| {
                let text = std::fs::read_to_string(p).unwrap();
                let name = p.file_stem().unwrap().to_string_lossy().into_owned();
                (name, absolute_references(&text, &dir))
            })
            .collect()
    })
}

/// `obj = "../x.obj"` → `obj = "/abs/scenes/../x.obj"` (textures too,
/// except the shipped `fence-opacity.png`, which each case copies).
fn absolute_references(text: &str, dir: &Path) -> String {
    let mut out = String::new();
    for line in text.lines() {
        let trimmed = line.trim_start();
        let is_ref = trimmed.starts_with("obj ") || trimmed.starts_with("obj=");
        match (is_ref, line.find('"'), line.rfind('"')) {
            (true, Some(a), Some(b)) if b > a => {
                let file = &line[a + 1..b];
                let abs = dir.join(file);
                let _ = writeln!(out, "{}\"{}\"{}", &line[..a], abs.display(), &line[b + 1..]);
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    out
}

/// A small scene using every kind of input: the small OBJ (with its MTL
/// and textures), a textured rect light, a sphere light, built-in shapes
/// with inline materials and an opacity texture.
const SMALL_SCENE: &str = r#"[scene]
name = "small"
ambient = [0.02, 0.03, 0.04]
background = 0.1

[camera]
eye = [0.5, 2.0, 4.0]
target = [0.0, 0.3, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 50.0
width = 32
height = 24

[[light]]
type = "rect"
center = [0.5, 3.0, 0.5]
u = [0.4, 0.0, 0.0]
v = [0.0, 0.0, 0.3]
radiance = [6.0, 5.0, 4.0]
texture = "tex.png"
two_sided = true

[[light]]
type = "sphere"
center = [-1.5, 2.5, 1.0]
radius = 0.25
radiance = 3.0

[[object]]
name = "ground"
shape = "quad"
size = [6.0, 6.0]
material = { albedo = [0.7, 0.7, 0.7], specular = 0.1, shininess = 30.0 }

[[object]]
obj = "model.obj"
scale = 0.8
rotate = [0.0, 30.0, 0.0]
translate = [0.2, 0.1, 0.0]

[[object]]
shape = "sphere"
radius = 0.3
segments = 12
rings = 8
translate = [-0.8, 0.5, 0.3]
material = { albedo_texture = "tex.tga", opacity = 0.6 }

[[object]]
shape = "box"
size = [0.4, 0.6, 0.2]
translate = [0.9, 0.5, -0.6]
scale = [1.0, -1.0, 1.0]
material = { opacity_texture = "opacity.png" }
cast_shadows = true
receive_shadows = false
"#;

/// A tetrahedron with positions, uvs and normals, two groups, three
/// materials, relative indices, a quad and a 4-component vertex.
const SMALL_OBJ: &str = "# small model\n\
mtllib model.mtl\n\
o tetra\n\
v 0 0 0\n\
v 1 0 0\n\
v 0 1 0\n\
v 0 0 1 1\n\
v 0.5 0.5 0.5\n\
vt 0 0\n\
vt 1 0\n\
vt 0 1\n\
vn 0 0 -1\n\
vn 0 -1 0\n\
vn -1 0 0\n\
vn 0.577 0.577 0.577\n\
usemtl red\n\
f 1/1/1 3/3/1 2/2/1\n\
f 1/1/2 2/2/2 4/3/2\n\
usemtl fence\n\
f 1/1/3 4/2/3 3/3/3\n\
g top\n\
usemtl glass\n\
f 2/1/4 3/2/4 4/3/4\n\
f -2/-1/-1 -3/-2/-1 -4/-3/-1\n\
f 1/1/1 2/2/1 5/3/1 3/3/1\n";

const SMALL_MTL: &str = "newmtl red\n\
Kd 0.8 0.1 0.1\n\
Ks 0.2 0.2 0.2\n\
Ns 20\n\
newmtl fence\n\
Kd 0.5\n\
map_Kd tex.png\n\
map_d -bm 1 opacity.png\n\
newmtl glass\n\
Kd 0.9 0.9 1\n\
Tr 0.4\n\
illum 2\n";

/// The small binary inputs: (file name, bytes).
fn small_files() -> &'static [(&'static str, Vec<u8>)] {
    static FILES: OnceLock<Vec<(&'static str, Vec<u8>)>> = OnceLock::new();
    FILES.get_or_init(|| {
        let png = |rgba: bool| {
            let mut bytes = Vec::new();
            let (w, h) = (4u32, 3u32);
            let px: Vec<u8> = (0..w * h)
                .flat_map(|k| {
                    let v = (k * 37 % 256) as u8;
                    if rgba {
                        vec![v, 255 - v, 128, if k % 2 == 0 { 255 } else { 0 }]
                    } else {
                        vec![v, 255 - v, v / 2]
                    }
                })
                .collect();
            let color = if rgba {
                image::ExtendedColorType::Rgba8
            } else {
                image::ExtendedColorType::Rgb8
            };
            image::ImageEncoder::write_image(
                image::codecs::png::PngEncoder::new(&mut bytes),
                &px,
                w,
                h,
                color,
            )
            .unwrap();
            bytes
        };
        // An uncompressed 3 × 2 24-bit TGA, written by hand.
        let mut tga = vec![0u8, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 3, 0, 2, 0, 24, 0];
        tga.extend((0..18).map(|k| (k * 14) as u8));
        let fence = std::fs::read(manifest().join("scenes/fence-opacity.png")).unwrap();
        vec![
            ("tex.png", png(false)),
            ("opacity.png", png(true)),
            ("tex.tga", tga),
            ("fence-opacity.png", fence),
            ("model.obj", SMALL_OBJ.as_bytes().to_vec()),
            ("model.mtl", SMALL_MTL.as_bytes().to_vec()),
        ]
    })
}

// ---------------------------------------------------------- mutations ----

/// Numbers and tokens at the edges of what the loaders accept.
const EXTREMES: &[&str] = &[
    "0",
    "-0",
    "0.0",
    "-1",
    "1",
    "2",
    "3",
    "0.5",
    "1e38",
    "-1e38",
    "3.5e38",
    "-3.5e38",
    "3.4028235e38",
    "1e308",
    "1e-20",
    "1e-45",
    "1e-320",
    "1e9",
    "1.000001e9",
    "-1e9",
    "1e-9",
    "9.9e-10",
    "1e18",
    "1e30",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "4294967296",
    "4096",
    "4097",
    "16384",
    "16385",
    "65536",
    "179.99999",
    "180",
    "1e-30",
    "0x10",
    "1_000",
    "\"x\"",
    "\"\"",
    "[]",
    "[1, 2, 3, 4]",
    "[1, \"x\", 3]",
    "[[1, 2, 3]]",
    "true",
    "{}",
    "{ albedo = 2 }",
];

/// Keys (with a plausible value) a mutation may insert.
const KEYS: &[&str] = &[
    "segments = 4096",
    "rings = 4096",
    "radius = 1e-12",
    "two_sided = true",
    "texture = \"tex.png\"",
    "texture = \"missing.png\"",
    "texture = \".\"",
    "obj = \"model.obj\"",
    "obj = \"tex.png\"",
    "shape = \"sphere\"",
    "shape = \"box\"",
    "size = [1e-12, 1, 1]",
    "scale = -1",
    "scale = [1, 0, 1]",
    "rotate = [1e9, 0, 0]",
    "u = [0, 0, 0]",
    "v = [1, 0, 0]",
    "up = [0, 0, 0]",
    "type = \"sphere\"",
    "type = \"rect\"",
    "material = { opacity_texture = \"fence-opacity.png\" }",
    "material = { albedo_texture = \"opacity.png\", opacity = 0 }",
    "[[object]]",
    "[[light]]",
    "[camera]",
    "[scene]",
];

/// Words an OBJ or MTL mutation may insert.
const OBJ_LINES: &[&str] = &[
    "v 1e38 1e38 1e38",
    "v 1 2",
    "v 1 2 3 0",
    "vt 0.5",
    "vn 0 0 0",
    "f 1 2",
    "f 1//2 2//2 3//2",
    "f 0 1 2",
    "f -100 1 2",
    "f 1/1 2/2/2 3",
    "f 99999999999 1 2",
    "usemtl",
    "usemtl nothere",
    "mtllib missing.mtl",
    "mtllib",
    "l 1 2 3",
    "p 1",
    "g",
    "s off",
    "newmtl",
    "newmtl red",
    "Kd 1 2",
    "Kd -1 0 0",
    "Ks nan 0 0",
    "Ns -5",
    "d 2",
    "Tr -0.5",
    "map_Kd",
    "map_Kd missing.png",
    "map_d model.obj",
    "map_Kd -o 1 1 1 tex.tga",
    "\u{feff}v 0 0 0",
    "v 0.5 0.5 0.5 0.9 0.1 0.1",
];

/// Applies 1 to 4 random text mutations to `text`.
fn mutate_text(rng: &mut Rng, text: &str, inserts: &[&str], log: &mut String) -> Vec<u8> {
    let mut bytes = text.as_bytes().to_vec();
    for _ in 0..rng.range(1, 4) {
        let op = rng.range(0, 8);
        let _ = write!(log, "op{op} ");
        bytes = match op {
            0 => flip_bytes(rng, bytes),
            1 | 2 => substitute_number(rng, bytes),
            3 => truncate(rng, bytes),
            4 => edit_lines(rng, bytes, |rng, lines| {
                // Duplicate a run of 1..=8 lines.
                let (at, n) = pick_run(rng, lines.len(), 8);
                let run: Vec<String> = lines[at..at + n].to_vec();
                let to = rng.range(0, lines.len() as i64) as usize;
                lines.splice(to..to, run);
            }),
            5 => edit_lines(rng, bytes, |rng, lines| {
                let (at, n) = pick_run(rng, lines.len(), 3);
                lines.drain(at..at + n);
            }),
            6 => edit_lines(rng, bytes, |rng, lines| swap_keys(rng, lines)),
            _ => edit_lines(rng, bytes, |rng, lines| {
                let line = inserts[rng.range(0, inserts.len() as i64 - 1) as usize];
                let to = rng.range(0, lines.len() as i64) as usize;
                lines.insert(to, line.to_string());
            }),
        };
    }
    bytes
}

fn pick_run(rng: &mut Rng, len: usize, max: usize) -> (usize, usize) {
    if len == 0 {
        return (0, 0);
    }
    let at = rng.range(0, len as i64 - 1) as usize;
    let n = rng.range(1, max.min(len - at) as i64) as usize;
    (at, n)
}

fn flip_bytes(rng: &mut Rng, mut bytes: Vec<u8>) -> Vec<u8> {
    if bytes.is_empty() {
        return bytes;
    }
    for _ in 0..rng.range(1, 4) {
        let i = rng.range(0, bytes.len() as i64 - 1) as usize;
        bytes[i] = match rng.range(0, 3) {
            0 => bytes[i] ^ (1 << rng.range(0, 7)),
            1 => b"=[]{}\",.#\n-+e0\\'"[rng.range(0, 15) as usize],
            2 => rng.next_u64() as u8,
            _ => 0xff,
        };
    }
    bytes
}

fn truncate(rng: &mut Rng, mut bytes: Vec<u8>) -> Vec<u8> {
    let at = rng.range(0, bytes.len() as i64) as usize;
    bytes.truncate(at);
    bytes
}

/// Replaces one numeric token (or a whole value after `=`) by an extreme.
fn substitute_number(rng: &mut Rng, bytes: Vec<u8>) -> Vec<u8> {
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let mut tokens = Vec::new();
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            || ((b[i] == b'-' || b[i] == b'.') && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        if starts && (i == 0 || !b[i - 1].is_ascii_alphanumeric()) {
            let j = (i + 1..b.len())
                .find(|&j| !(b[j].is_ascii_digit() || b"._eE+-".contains(&b[j])))
                .unwrap_or(b.len());
            tokens.push(i..j);
            i = j;
        } else {
            i += 1;
        }
    }
    if tokens.is_empty() {
        return bytes;
    }
    let t = tokens[rng.range(0, tokens.len() as i64 - 1) as usize].clone();
    let with = EXTREMES[rng.range(0, EXTREMES.len() as i64 - 1) as usize];
    let mut out = text[..t.start].to_string();
    out.push_str(with);
    out.push_str(&text[t.end..]);
    out.into_bytes()
}

/// Swaps the keys (or, for lines without `=`, the lines) of two lines.
fn swap_keys(rng: &mut Rng, lines: &mut [String]) {
    if lines.len() < 2 {
        return;
    }
    let a = rng.range(0, lines.len() as i64 - 1) as usize;
    let b = rng.range(0, lines.len() as i64 - 1) as usize;
    match (lines[a].split_once('='), lines[b].split_once('=')) {
        (Some((ka, va)), Some((kb, vb))) => {
            let (na, nb) = (format!("{kb}={va}"), format!("{ka}={vb}"));
            lines[a] = na;
            lines[b] = nb;
        }
        _ => lines.swap(a, b),
    }
}

fn edit_lines(
    rng: &mut Rng,
    bytes: Vec<u8>,
    edit: impl FnOnce(&mut Rng, &mut Vec<String>),
) -> Vec<u8> {
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    edit(rng, &mut lines);
    let mut out = lines.join("\n");
    out.push('\n');
    out.into_bytes()
}

/// Byte-level mutations of an image file, including its size fields.
fn mutate_image(rng: &mut Rng, mut bytes: Vec<u8>, log: &mut String) -> Vec<u8> {
    let op = rng.range(0, 4);
    let _ = write!(log, "img-op{op} ");
    match op {
        0 => flip_bytes(rng, bytes),
        1 => truncate(rng, bytes),
        2 => {
            // PNG IHDR width/height at 16..24, TGA width/height at 12..16.
            let sizes: [u32; 6] = [0, 1, 65535, 1 << 16, 0x7fff_ffff, u32::MAX];
            let v = sizes[rng.range(0, 5) as usize];
            if bytes.starts_with(b"\x89PNG") && bytes.len() >= 24 {
                let at = 16 + 4 * rng.range(0, 1) as usize;
                bytes[at..at + 4].copy_from_slice(&v.to_be_bytes());
            } else if bytes.len() >= 16 {
                let at = 12 + 2 * rng.range(0, 1) as usize;
                bytes[at..at + 2].copy_from_slice(&(v as u16).to_le_bytes());
            }
            bytes
        }
        3 => {
            // Duplicate a chunk of bytes somewhere.
            if bytes.is_empty() {
                return bytes;
            }
            let a = rng.range(0, bytes.len() as i64 - 1) as usize;
            let n = rng.range(1, 64.min((bytes.len() - a) as i64)) as usize;
            let chunk = bytes[a..a + n].to_vec();
            let to = rng.range(0, bytes.len() as i64) as usize;
            bytes.splice(to..to, chunk);
            bytes
        }
        _ => Vec::new(),
    }
}

// ------------------------------------------------------------- cases ----

/// How a case ended, for the summary.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Rendered,
    FileError,
    ParameterError,
    PathError,
    CliUsage,
    Printed,
}

const OUTCOMES: [Outcome; 6] = [
    Outcome::Rendered,
    Outcome::FileError,
    Outcome::ParameterError,
    Outcome::PathError,
    Outcome::CliUsage,
    Outcome::Printed,
];

/// One case's inputs, for reproduction and failure messages.
struct Case {
    dir: PathBuf,
    log: String,
}

impl Case {
    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }
}

/// The case kinds (for `PENUMBRA_FUZZ_KIND`) and the first of their
/// per-mille slots in [`run_case`]'s mix.
const KINDS: [(&str, i64); 13] = [
    ("scene", 0),
    ("obj", 400),
    ("ply", 480),
    ("gltf", 505),
    ("mtl", 530),
    ("texture", 600),
    ("render-cli", 670),
    ("print-cli", 800),
    ("tiles", 860),
    ("partials", 900),
    ("special", 910),
    ("options", 940),
    ("agreement", 990),
];

/// Runs case `seed` in `dir` (emptied first). `Err` is a finding.
fn run_case(seed: u64, dir: &Path) -> Result<Outcome, String> {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).unwrap();
    let mut rng = Rng(seed);
    let mut case = Case {
        dir: dir.to_path_buf(),
        log: String::new(),
    };
    for (name, bytes) in small_files() {
        case.write(name, bytes);
    }
    let mut kind = rng.range(0, 999);
    if let Ok(name) = std::env::var("PENUMBRA_FUZZ_KIND") {
        kind = match KINDS.iter().find(|(n, _)| *n == name) {
            Some((_, first)) => *first,
            None => panic!("PENUMBRA_FUZZ_KIND={name}: not one of {KINDS:?}"),
        };
    }
    let name = KINDS
        .iter()
        .rev()
        .find(|(_, first)| *first <= kind)
        .unwrap()
        .0;
    let _ = write!(case.log, "[kind {name}] ");
    let result = match kind {
        0..=399 => scene_case(&mut rng, &mut case),
        400..=479 => model_case(&mut rng, &mut case, "model.obj", SMALL_OBJ),
        480..=504 => ply_case(&mut rng, &mut case),
        505..=529 => gltf_case(&mut rng, &mut case),
        530..=599 => model_case(&mut rng, &mut case, "model.mtl", SMALL_MTL),
        600..=669 => texture_case(&mut rng, &mut case),
        670..=799 => render_cli_case(&mut rng, &mut case),
        800..=859 => print_cli_case(&mut rng, &mut case),
        860..=899 => tile_case(&mut rng, &mut case),
        900..=909 => partial_case(&mut rng, &mut case),
        910..=939 => special_case(&mut rng, &mut case),
        940..=989 => options_case(&mut rng, &mut case),
        _ => agreement_case(&mut rng, &mut case),
    };
    result.map_err(|e| format!("{e}\n  inputs: {}\n  in {}", case.log, dir.display()))
}

/// A shipped scene (its big models mostly swapped for the small OBJ, to
/// keep cases fast) or the small scene, mutated.
fn scene_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    let scenes = shipped_scenes();
    let pick = rng.range(0, scenes.len() as i64) as usize;
    let (name, mut text) = match scenes.get(pick) {
        Some((n, t)) => (n.as_str(), t.clone()),
        None => ("small", SMALL_SCENE.to_string()),
    };
    if text.contains(".obj\"") && rng.range(0, 19) != 0 {
        text = text
            .lines()
            .map(|l| match l.trim_start().starts_with("obj") {
                true => "obj = \"model.obj\"".to_string(),
                false => l.to_string(),
            })
            .collect::<Vec<_>>()
            .join("\n");
    }
    let _ = write!(case.log, "scene {name}: ");
    let bytes = mutate_text(rng, &text, KEYS, &mut case.log);
    let path = case.write("scene.toml", &bytes);
    load_and_render(rng, case, &path)
}

/// The small scene with its OBJ or MTL mutated.
fn model_case(rng: &mut Rng, case: &mut Case, file: &str, base: &str) -> Result<Outcome, String> {
    let _ = write!(case.log, "{file}: ");
    let bytes = mutate_text(rng, base, OBJ_LINES, &mut case.log);
    case.write(file, &bytes);
    let path = case.write("scene.toml", SMALL_SCENE.as_bytes());
    load_and_render(rng, case, &path)
}

/// 1 to 4 byte mutations of a binary file: bytes flipped, a cut, a run
/// repeated.
fn mutate_binary(rng: &mut Rng, mut bytes: Vec<u8>, log: &mut String) -> Vec<u8> {
    for _ in 0..rng.range(1, 4) {
        let op = rng.range(0, 2);
        let _ = write!(log, "bin{op} ");
        bytes = match op {
            0 => flip_bytes(rng, bytes),
            1 => truncate(rng, bytes),
            _ => {
                let (at, n) = pick_run(rng, bytes.len(), 64);
                let run = bytes[at..at + n].to_vec();
                let to = rng.range(0, bytes.len() as i64) as usize;
                bytes.splice(to..to, run);
                bytes
            }
        };
    }
    bytes
}

/// The small scene with its model as `file` instead of the OBJ.
fn small_scene_with_model(case: &mut Case, file: &str) -> PathBuf {
    let scene = SMALL_SCENE.replace("obj = \"model.obj\"", &format!("obj = \"{file}\""));
    assert_ne!(scene, SMALL_SCENE);
    case.write("scene.toml", scene.as_bytes())
}

/// Lines a PLY header or body may gain.
const PLY_LINES: &[&str] = &[
    "element vertex 4000000000",
    "element face -1",
    "property float x",
    "property list uchar int vertex_indices",
    "property list int int vertex_indices",
    "property double nx",
    "property uchar red",
    "format binary_big_endian 1.0",
    "end_header",
    "3 0 1 9",
    "4 0 1 2 3",
    "255 0 1 2",
    "nan 0 0",
    "1e39 0 0",
];

/// The small tetrahedron as PLY (ASCII, or binary little or big endian)
/// with normals, colours and texture coordinates, mutated.
fn ply_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    let vertices: [[f32; 11]; 4] = [
        [0.0, 0.0, 0.0, -0.6, -0.6, -0.6, 255.0, 0.0, 0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 255.0, 0.0, 1.0, 0.0],
        [0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 255.0, 0.0, 1.0],
        [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 9.0, 9.0, 9.0, 1.0, 1.0],
    ];
    let faces: [[i32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let encoding = ["ascii", "binary_little_endian", "binary_big_endian"][rng.range(0, 2) as usize];
    let header = format!(
        "ply\nformat {encoding} 1.0\ncomment fuzz\nelement vertex 4\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         property float u\nproperty float v\n\
         element face 4\nproperty list uchar int vertex_indices\nend_header\n"
    );
    let _ = write!(case.log, "model.ply ({encoding}): ");
    let bytes = if encoding == "ascii" {
        let mut text = header;
        for v in &vertices {
            let words: Vec<String> = v.iter().map(|x| x.to_string()).collect();
            text += &(words.join(" ") + "\n");
        }
        for f in &faces {
            text += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
        }
        mutate_text(rng, &text, PLY_LINES, &mut case.log)
    } else {
        let big = encoding.ends_with("big_endian");
        let mut bytes = header.into_bytes();
        for v in &vertices {
            for (i, x) in v.iter().enumerate() {
                match (i, big) {
                    (6..=8, _) => bytes.push(*x as u8),
                    (_, true) => bytes.extend(x.to_be_bytes()),
                    (_, false) => bytes.extend(x.to_le_bytes()),
                }
            }
        }
        for f in &faces {
            bytes.push(3);
            for i in f {
                bytes.extend(if big {
                    i.to_be_bytes()
                } else {
                    i.to_le_bytes()
                });
            }
        }
        mutate_binary(rng, bytes, &mut case.log)
    };
    case.write("model.ply", &bytes);
    let path = small_scene_with_model(case, "model.ply");
    load_and_render(rng, case, &path)
}

/// The small tetrahedron as glTF: a `.gltf` with an external buffer (its
/// JSON or its buffer mutated) or a GLB (its bytes mutated), with a node
/// hierarchy, texture coordinates, a strip and a textured MASK material.
fn gltf_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    let mut bin: Vec<u8> = Vec::new();
    let positions = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    positions
        .iter()
        .flatten()
        .for_each(|x| bin.extend(x.to_le_bytes()));
    let uvs = [[0.0f32, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
    uvs.iter()
        .flatten()
        .for_each(|x| bin.extend(x.to_le_bytes()));
    [0u16, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]
        .iter()
        .for_each(|i| bin.extend(i.to_le_bytes()));
    let glb = rng.range(0, 1) == 1;
    let buffer = match glb {
        true => serde_json::json!({"byteLength": bin.len()}),
        false => serde_json::json!({"byteLength": bin.len(), "uri": "model.bin"}),
    };
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"translation": [0.0, 0.1, 0.0], "children": [1]},
            {"rotation": [0.0, 0.38268343, 0.0, 0.9238795], "scale": [1.0, 1.0, -1.0], "mesh": 0}
        ],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0},
            {"attributes": {"POSITION": 0}, "mode": 5}
        ]}],
        "materials": [{"alphaMode": "MASK", "alphaCutoff": 0.4,
                       "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.5, 0.2, 1.0],
                                                "baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "tex.png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 0, "byteOffset": 48, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 80},
            {"buffer": 0, "byteOffset": 80, "byteLength": 24}
        ],
        "buffers": [buffer]
    })
    .to_string();
    let (file, bytes) = if glb {
        let _ = write!(case.log, "model.glb: ");
        let mut json = json.into_bytes();
        json.resize(json.len().next_multiple_of(4), b' ');
        let mut glb = b"glTF".to_vec();
        glb.extend(2u32.to_le_bytes());
        glb.extend(((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
        glb.extend((json.len() as u32).to_le_bytes());
        glb.extend(b"JSON");
        glb.extend(json);
        glb.extend((bin.len() as u32).to_le_bytes());
        glb.extend(b"BIN\0");
        glb.extend(&bin);
        ("model.glb", mutate_binary(rng, glb, &mut case.log))
    } else if rng.range(0, 1) == 0 {
        let _ = write!(case.log, "model.gltf (JSON): ");
        case.write("model.bin", &bin);
        let inserts = [
            "\"count\": 4000000000,",
            "\"byteOffset\": -4,",
            "\"extensionsRequired\": [\"KHR_draco_mesh_compression\"],",
            "\"uri\": \"data:application/octet-stream;base64,AAAA\",",
            "\"mode\": 1,",
            "\"matrix\": [0,0,0,0, 0,0,0,0, 0,0,0,0, 0,0,0,1],",
        ];
        // One key per line, so that the line edits move whole members.
        let pretty = json.replace(",\"", ",\n\"");
        (
            "model.gltf",
            mutate_text(rng, &pretty, &inserts, &mut case.log),
        )
    } else {
        let _ = write!(case.log, "model.gltf (its buffer): ");
        let mutated = mutate_binary(rng, bin, &mut case.log);
        case.write("model.bin", &mutated);
        ("model.gltf", json.into_bytes())
    };
    case.write(file, &bytes);
    let path = small_scene_with_model(case, file);
    load_and_render(rng, case, &path)
}

/// The small scene (or fence.toml) with one of its textures mutated.
fn texture_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    let files = small_files();
    let k = rng.range(0, 3) as usize;
    let (name, bytes) = &files[k];
    let _ = write!(case.log, "{name}: ");
    let mutated = mutate_image(rng, bytes.clone(), &mut case.log);
    case.write(name, &mutated);
    let scene = match *name {
        "fence-opacity.png" => {
            &shipped_scenes()
                .iter()
                .find(|(n, _)| n == "fence")
                .expect("fence.toml")
                .1
        }
        _ => SMALL_SCENE,
    };
    let path = case.write("scene.toml", scene.as_bytes());
    load_and_render(rng, case, &path)
}

/// A scene load error must name the file and line (or the parameter).
fn check_load_error(e: &Error) -> Result<Outcome, String> {
    match e {
        Error::File {
            path,
            line: Some(_),
            message,
        } if !path.as_os_str().is_empty() && !message.is_empty() => Ok(Outcome::FileError),
        Error::Parameter { name, message } if !name.is_empty() && !message.is_empty() => {
            Ok(Outcome::ParameterError)
        }
        // Binary and JSON mesh files have no lines to name: the place is a
        // byte offset (binary PLY), a JSON pointer (glTF) or the GLB header.
        Error::File {
            path,
            line: None,
            message,
        } if names_a_place_without_lines(path, message) => Ok(Outcome::FileError),
        other => Err(format!("load error without a file and line: {other:?}")),
    }
}

/// A PLY, glTF, GLB or glTF buffer error that names its place: a byte
/// offset, a JSON pointer (`/meshes/0/...`) or the GLB's header.
fn names_a_place_without_lines(path: &Path, message: &str) -> bool {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let place = message.contains("(byte ")
        || message.starts_with('/')
        || message.contains(" /")
        || message.contains("`/")
        || message.contains("GLB");
    ["ply", "gltf", "glb", "bin"].contains(&ext) && place
}

fn any_nan(values: &[f32]) -> bool {
    values.iter().any(|v| v.is_nan())
}

/// Loads `path` and renders it at 16 × 16 with random options.
// The technique options are set field by field (see below) so that a new
// options group needs no edit here.
#[allow(clippy::field_reassign_with_default)]
fn load_and_render(rng: &mut Rng, case: &mut Case, path: &Path) -> Result<Outcome, String> {
    let scene = match load_scene(path) {
        Ok(s) => s,
        Err(e) => return check_load_error(&e),
    };
    let names = penumbra::internal::shadow::registry::names();
    let technique = names[rng.range(0, names.len() as i64 - 1) as usize];
    let patterns = [
        "stratified",
        "correlated",
        "rotated",
        "poisson",
        "sobol",
        "interleaved:3",
    ];
    let samples = [1, 2, 4, 9, 16][rng.range(0, 4) as usize];
    let seed = rng.next_u64();
    let pattern = SamplePattern::parse(patterns[rng.range(0, 5) as usize]).unwrap();
    // Field by field (in this order, which is the generator's), so that a
    // new options group needs no edit here.
    let mut technique_options = penumbra::internal::shadow::TechniqueOptions::default();
    technique_options.shadow_volumes =
        penumbra::internal::shadow::shadow_volumes::ShadowVolumeOptions {
            zpass: rng.range(0, 1) == 1,
        };
    technique_options.dcs = penumbra::internal::shadow::dcs::DcsOptions {
        silhouettes: [SilhouetteMode::Centre, SilhouetteMode::WholeLight][rng.range(0, 1) as usize],
        mode: [DcsMode::Vcoef, DcsMode::Direct][rng.range(0, 1) as usize],
        transmittance: [TransmittanceMode::Exact, TransmittanceMode::Summed]
            [rng.range(0, 1) as usize],
        coverage: [CoverageTest::Exact, CoverageTest::BitField][rng.range(0, 1) as usize],
        rays: [RayChoice::Auto, RayChoice::Never][rng.range(0, 1) as usize],
    };
    technique_options.stsv = penumbra::internal::shadow::kit::stsv::StsvOptions {
        opacity_filter: [Filter::Nearest, Filter::Bilinear][rng.range(0, 1) as usize],
    };
    technique_options.adaptive_maps =
        penumbra::internal::shadow::adaptive_maps::AdaptiveMapsOptions {
            adaptive_threshold: [0, 3][rng.range(0, 1) as usize],
            max_depth: rng.range(0, 2) as u32,
            comparison_scale: [1.0, 0.5, 0.01][rng.range(0, 2) as usize],
            adaptive_centre_depth: rng.range(0, 2) as u32,
            adaptive_split_all: rng.range(0, 3) == 0,
            adaptive_band_low: 0.5,
            adaptive_band_high: [0.0, 4.0][rng.range(0, 1) as usize],
        };
    technique_options.shadow_map = penumbra::internal::shadow::shadow_map::ShadowMapOptions {
        map_size: [1, 16, 64][rng.range(0, 2) as usize],
        pcf: ["1", "2x2", "3x3", "poisson:8"][rng.range(0, 3) as usize]
            .parse()
            .unwrap(),
        ..Default::default()
    };
    technique_options.pcss = penumbra::internal::shadow::pcss::PcssOptions {
        pcss_blocker_samples: [1, 4, 16][rng.range(0, 2) as usize],
        pcss_filter_samples: [1, 4, 16][rng.range(0, 2) as usize],
        pcss_kernel: [
            penumbra::internal::shadow::pcss::PcssKernel::Poisson,
            penumbra::internal::shadow::pcss::PcssKernel::Box,
        ][rng.range(0, 1) as usize],
        pcss_flat_receiver: rng.range(0, 1) == 1,
    };
    technique_options.ssm = penumbra::internal::shadow::soft_shadow_map::SsmOptions {
        ssm_passes: [1, 2][rng.range(0, 1) as usize],
        ssm_bottom_patches: rng.range(0, 1) == 1,
        ssm_accumulate: [Accumulate::F32, Accumulate::F16, Accumulate::F16Batched]
            [rng.range(0, 2) as usize],
        ssm_lookup: [Lookup::Nearest, Lookup::Bilinear][rng.range(0, 1) as usize],
    };
    technique_options.penumbra_casting =
        penumbra::internal::shadow::penumbra_casting::PenumbraCastingOptions {
            pc_sample_sets: [1, 2, 8][rng.range(0, 2) as usize],
            pc_umbra_bits: rng.range(0, 1) == 1,
            pc_on_demand_masks: rng.range(0, 1) == 1,
            ..Default::default()
        };
    let options = RenderOptions {
        width: Some(16),
        height: Some(16),
        aovs: Aov::ALL.to_vec(),
        technique: technique.parse().unwrap(),
        samples,
        seed,
        pattern,
        options: technique_options,
        threads: None,
        progressive: None,
    };
    let _ = write!(case.log, "| render {options:?}");
    match render(&scene, &options) {
        Ok(out) => {
            let radiance: Vec<f32> = out.radiance.iter().flat_map(|c| c.to_array()).collect();
            if any_nan(&radiance) {
                return Err(format!("{technique}: NaN in the radiance"));
            }
            for layer in &out.layers {
                for (name, values) in &layer.channels {
                    if any_nan(values) {
                        return Err(format!("{technique}: NaN in layer {}.{name}", layer.name));
                    }
                }
            }
            Ok(Outcome::Rendered)
        }
        Err(e @ Error::Parameter { .. }) => check_load_error(&e),
        Err(e) => Err(format!(
            "{technique}: render error without a parameter: {e:?}"
        )),
    }
}

/// Picks one of `values`.
fn one<'a>(rng: &mut Rng, values: &[&'a str]) -> &'a str {
    values[rng.range(0, values.len() as i64 - 1) as usize]
}

/// Runs a command line in-process (the library's parsing path), checking
/// how it ends; `paths` are the paths an I/O error may name.
fn run_cli(args: &[String], paths: &[PathBuf], case: &mut Case) -> Result<Outcome, String> {
    let _ = write!(case.log, "args {args:?}");
    match cli(args) {
        CliResult::Usage(u) => u,
        CliResult::Ran(Ok(_)) => Ok(Outcome::Printed),
        CliResult::Ran(Err(e)) => classify_error(&e, paths),
    }
}

/// `render` with random parameters (valid, invalid and extreme) on a
/// valid scene; the EXR output is checked for NaN.
fn render_cli_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    let scene = match rng.range(0, 2) {
        0 => case.write("scene.toml", SMALL_SCENE.as_bytes()),
        _ => {
            let scenes = shipped_scenes();
            let (_, text) = scenes
                .iter()
                .filter(|(n, _)| n != "bunny" && n != "sponza-plants")
                .nth(rng.range(0, 3) as usize)
                .unwrap();
            case.write("scene.toml", text.as_bytes())
        }
    };
    let png = case.dir.join("out.png");
    let exr = case.dir.join("out.exr");
    let mut paths = vec![scene.clone(), png.clone(), exr.clone()];
    let mut args: Vec<String> = ["penumbra", "render"].map(String::from).to_vec();
    args.push(scene.display().to_string());
    // Output paths: mostly plain, sometimes odd.
    let odd = [
        case.dir.display().to_string(),
        case.dir.join("missing/x.png").display().to_string(),
        "/dev/null".to_string(),
        String::new(),
        exr.display().to_string(),
    ];
    let out = match rng.range(0, 9) {
        k @ 0..=4 => odd[k as usize].clone(),
        _ => png.display().to_string(),
    };
    paths.extend(odd.iter().map(PathBuf::from));
    args.extend(["-o".into(), out]);
    let with_exr = rng.range(0, 3) != 0;
    if with_exr {
        args.extend(["--exr".into(), exr.display().to_string()]);
    }
    // Sizes: at most one side large, so that a valid case stays small.
    let sides = [
        "16",
        "1",
        "2",
        "17",
        "0",
        "-1",
        "16385",
        "65536",
        "4294967296",
        "x",
        "",
    ];
    let big = ["16384", "4096"];
    let (w, h) = match rng.range(0, 3) {
        0 => (one(rng, &sides).to_string(), "16".to_string()),
        1 => ("16".to_string(), one(rng, &sides).to_string()),
        2 => (one(rng, &big).to_string(), "1".to_string()),
        _ => ("16".to_string(), "16".to_string()),
    };
    args.extend(["--width".into(), w, "--height".into(), h]);
    let options: [(&str, &[&str]); 13] = [
        (
            "--technique",
            &[
                "none",
                "reference",
                "shadow-volumes",
                "wedges",
                "wedge-blend",
                "dcs",
                "DCS",
                "",
                "ray",
            ],
        ),
        (
            "--samples",
            &[
                "1",
                "2",
                "3",
                "7",
                "64",
                "0",
                "1048577",
                "-1",
                "x",
                "4294967296",
            ],
        ),
        ("--seed", &["0", "18446744073709551615", "-1", "1e3"]),
        ("--threads", &["1", "2", "3", "0", "1025", "-1", "x"]),
        (
            "--silhouettes",
            &["centre", "center", "light", "whole-light", "edge", ""],
        ),
        ("--dcs-mode", &["vcoef", "direct", "both"]),
        ("--transmittance", &["exact", "summed", "none"]),
        ("--coverage", &["exact", "bitfield", "bits"]),
        ("--opacity-filter", &["nearest", "bilinear", "cubic"]),
        (
            "--pattern",
            &[
                "stratified",
                "correlated",
                "rotated",
                "poisson",
                "sobol",
                "02",
                "interleaved",
                "interleaved:2",
                "interleaved16",
                "interleaved:1",
                "interleaved:17",
                "interleaved:",
                "halton",
            ],
        ),
        (
            "--aov",
            &[
                "depth",
                "position,normal,albedo,mask,vcoef",
                "vcoef",
                "colour",
                "",
                "depth,depth",
            ],
        ),
        ("--zpass", &[]),
        ("--timings", &[]),
    ];
    for (name, values) in options {
        if rng.range(0, 2) == 0 {
            args.push(name.to_string());
            if !values.is_empty() {
                args.push(one(rng, values).to_string());
            }
        }
    }
    if rng.range(0, 9) == 0 {
        args.push(one(rng, &["--explain", "--bogus", "extra", "--width"]).to_string());
    }
    paths.push(case.dir.join("missing"));
    let outcome = run_cli(&args, &paths, case)?;
    if outcome == Outcome::Printed && with_exr && exr.exists() {
        let img = read_image(&exr).map_err(|e| format!("written EXR unreadable: {e}"))?;
        for (name, values) in &img.channels {
            if any_nan(values) {
                return Err(format!("NaN in EXR channel {name}"));
            }
        }
        return Ok(Outcome::Rendered);
    }
    Ok(outcome)
}

/// `diff` with random channels, masks and tolerances on small (and
/// sometimes mutated) images, or `info` on a mutated scene.
fn print_cli_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    if rng.range(0, 3) == 0 {
        let bytes = mutate_text(rng, SMALL_SCENE, KEYS, &mut case.log);
        let scene = case.write("scene.toml", &bytes);
        let args = [
            "penumbra".into(),
            "info".into(),
            scene.display().to_string(),
        ];
        return run_cli(&args, &[], case);
    }
    let (w, h) = (5u32, 4u32);
    let n = (w * h) as usize;
    let radiance: Vec<Vec3> = (0..n).map(|k| Vec3::splat(k as f32 / n as f32)).collect();
    let a = case.dir.join("a.png");
    let b = case.dir.join("b.exr");
    write_png(&a, w, h, &radiance).unwrap();
    let layers = [
        Layer {
            name: "mask".into(),
            channels: vec![("Y".into(), (0..n).map(|k| (k % 2) as f32).collect())],
        },
        Layer {
            name: "depth".into(),
            channels: vec![("Z".into(), (0..n).map(|k| k as f32).collect())],
        },
    ];
    write_exr(&b, w, h, &radiance, &layers).unwrap();
    let mut images = vec![a.clone(), b.clone()];
    if rng.range(0, 2) == 0 {
        let which = images[rng.range(0, 1) as usize].clone();
        let bytes = mutate_image(rng, std::fs::read(&which).unwrap(), &mut case.log);
        let c = case.write("c.img", &bytes);
        images.push(c);
    }
    images.push(case.dir.join("missing.png"));
    images.push(case.dir.clone());
    let pick = |rng: &mut Rng, images: &[PathBuf]| {
        let k = match rng.range(0, 9) {
            0..=5 => rng.range(0, 1) as usize,
            _ => rng.range(0, images.len() as i64 - 1) as usize,
        };
        images[k].display().to_string()
    };
    let mut args: Vec<String> = vec!["penumbra".into(), "diff".into()];
    args.push(pick(rng, &images));
    args.push(pick(rng, &images));
    let options: [(&str, &[&str]); 10] = [
        (
            "--channels-a",
            &["R", "R,G,B", "mask.Y", "depth.Z,R", "X", "", ",", "R,R"],
        ),
        ("--channels-b", &["R", "G,B", "A", "depth.Z", "Y,Y,Y,Y"]),
        ("--mask-channel", &["mask.Y", "Y", "R", "nothere", ""]),
        ("--max-abs", &["0", "0.5", "-1", "nan", "inf", "1e308", "x"]),
        ("--rmse", &["0", "1e-9", "-0", "NaN", "-inf"]),
        ("--mask", &[]),
        ("--json", &[]),
        ("--flip", &[]),
        ("--flip-threshold", &["0", "0.05", "1", "-1", "nan", "inf"]),
        ("--flip-map", &[]),
    ];
    for (name, values) in options {
        if rng.range(0, 2) == 0 {
            args.push(name.to_string());
            match name {
                "--mask" => args.push(pick(rng, &images)),
                // A new map, or onto an input (refused).
                "--flip-map" => args.push(match rng.range(0, 2) {
                    0 => pick(rng, &images),
                    _ => case.dir.join("map.png").display().to_string(),
                }),
                _ if !values.is_empty() => args.push(one(rng, values).to_string()),
                _ => {}
            }
        }
    }
    run_cli(&args, &images, case)
}

// ------------------------------------------------- campaign surfaces ----

/// What a command line did: refused by clap (with the outcome it counts
/// as, or a finding) or ran (with the command's result).
enum CliResult {
    Usage(Result<Outcome, String>),
    Ran(Result<penumbra::internal::cli::Outcome, Error>),
}

/// Parses and runs a command line in-process.
fn cli(args: &[String]) -> CliResult {
    match penumbra::internal::cli::Cli::try_parse_from(args) {
        Ok(parsed) => CliResult::Ran(penumbra::internal::cli::run(parsed)),
        Err(e) => CliResult::Usage(match e.kind() {
            clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion => {
                Ok(Outcome::Printed)
            }
            _ if e.to_string().contains('-') => Ok(Outcome::CliUsage),
            _ => Err(format!("usage error naming no parameter: {e}")),
        }),
    }
}

/// An error of a command must name one of `paths` or a parameter (or a
/// file and line).
fn classify_error(e: &Error, paths: &[PathBuf]) -> Result<Outcome, String> {
    match e {
        Error::Io { path, .. }
        | Error::File {
            path, line: None, ..
        } if paths.iter().any(|p| p == path) => Ok(Outcome::PathError),
        _ => check_load_error(e),
    }
}

fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| s.to_string()).collect()
}

fn show(p: &Path) -> String {
    p.display().to_string()
}

/// This worker's cache of inputs made once (tile parts, compare shards):
/// beside the case directory, per process.
fn worker_cache(case: &Case) -> PathBuf {
    let dir = case
        .dir
        .parent()
        .unwrap()
        .join(format!("cache-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs a setup command line, which must succeed.
fn must_run(args: &[String]) -> Result<(), String> {
    match cli(args) {
        CliResult::Ran(Ok(_)) => Ok(()),
        CliResult::Ran(Err(e)) => Err(format!("setup {args:?}: {e}")),
        CliResult::Usage(u) => Err(format!("setup {args:?}: usage {u:?}")),
    }
}

/// A tiny scene for tile parts, compare shards and special outputs:
/// 16 × 130 so that it has two bands of 64-row tiles.
const TINY_SCENE: &str = r#"[camera]
eye = [0, 5, 6]
target = [0, 0, 0]
fov_y = 45
width = 16
height = 130
[[light]]
type = "rect"
center = [0, 4, 0]
u = [0.5, 0, 0]
v = [0, 0, 0.5]
radiance = 10
[[object]]
name = "ground"
shape = "quad"
size = [6.0, 6.0]
[[object]]
name = "occ"
shape = "box"
size = [1.0, 0.5, 1.0]
translate = [0.0, 1.0, 0.0]
"#;

/// Bit-for-bit equality of two decoded images (sizes, channel names and
/// values).
fn same_image(
    a: &penumbra::internal::output::LoadedImage,
    b: &penumbra::internal::output::LoadedImage,
) -> bool {
    a.width == b.width
        && a.height == b.height
        && a.channels.len() == b.channels.len()
        && a.channels
            .iter()
            .zip(&b.channels)
            .all(|((na, va), (nb, vb))| {
                na == nb
                    && va.len() == vb.len()
                    && va.iter().zip(vb).all(|(x, y)| x.to_bits() == y.to_bits())
            })
}

/// Everything under `root` (but `skip`): regular files by content,
/// links by target, other files by kind; never read from a special file.
fn snapshot(root: &Path, skip: &[PathBuf]) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if skip.contains(&p) {
                continue;
            }
            let Ok(meta) = std::fs::symlink_metadata(&p) else {
                continue;
            };
            let content = if meta.file_type().is_symlink() {
                let t = std::fs::read_link(&p).unwrap_or_default();
                format!("link {}", t.display()).into_bytes()
            } else if meta.is_dir() {
                stack.push(p.clone());
                b"dir".to_vec()
            } else if meta.is_file() {
                std::fs::read(&p).unwrap_or_default()
            } else {
                b"special".to_vec()
            };
            out.push((p, content));
        }
    }
    out.sort();
    out
}

/// Names of paths that differ between two snapshots.
fn changed(before: &[(PathBuf, Vec<u8>)], after: &[(PathBuf, Vec<u8>)]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for (p, c) in before {
        match after.iter().find(|(q, _)| q == p) {
            Some((_, d)) if d == c => {}
            Some(_) => names.push(format!("{} changed", p.display())),
            None => names.push(format!("{} removed", p.display())),
        }
    }
    for (p, _) in after {
        if !before.iter().any(|(q, _)| q == p) {
            names.push(format!("{} created", p.display()));
        }
    }
    names
}

/// Two band parts of [`TINY_SCENE`] and their merge (PNG and EXR),
/// made once per worker.
struct TileBase {
    parts: [Vec<u8>; 2],
    png: penumbra::internal::output::LoadedImage,
    exr: penumbra::internal::output::LoadedImage,
}

fn tile_base(case: &Case) -> Result<&'static TileBase, String> {
    static BASE: OnceLock<Result<TileBase, String>> = OnceLock::new();
    BASE.get_or_init(|| {
        let dir = worker_cache(case).join("tiles");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let scene = dir.join("scene.toml");
        std::fs::write(&scene, TINY_SCENE).unwrap();
        let (p1, p2) = (dir.join("p1"), dir.join("p2"));
        for (i, p) in [("1/2", &p1), ("2/2", &p2)] {
            let mut args = strings(&["penumbra", "render"]);
            args.push(show(&scene));
            args.extend(strings(&[
                "--aov",
                "vcoef,mask",
                "--samples",
                "4",
                "--threads",
                "1",
                "--tiles",
                i,
                "-o",
            ]));
            args.push(show(p));
            must_run(&args)?;
        }
        let (png, exr) = (dir.join("m.png"), dir.join("m.exr"));
        let mut args = strings(&["penumbra", "merge-tiles"]);
        args.extend([show(&p1), show(&p2), "-o".into(), show(&png)]);
        args.extend(["--exr".into(), show(&exr)]);
        must_run(&args)?;
        let read = |p: &Path| read_image(p).map_err(|e| format!("base merge: {e}"));
        Ok(TileBase {
            parts: [std::fs::read(&p1).unwrap(), std::fs::read(&p2).unwrap()],
            png: read(&png)?,
            exr: read(&exr)?,
        })
    })
    .as_ref()
    .map_err(Clone::clone)
}

/// Mutates a tile part: bytes changed at the same length (header or
/// data), truncated, lengthened, or one header field replaced.
fn mutate_part(rng: &mut Rng, mut bytes: Vec<u8>, log: &mut String) -> Vec<u8> {
    let header_end = bytes
        .iter()
        .enumerate()
        .filter(|(_, &b)| b == b'\n')
        .nth(1)
        .map_or(bytes.len(), |(i, _)| i + 1);
    let op = rng.range(0, 7);
    let _ = write!(log, "part-op{op} ");
    match op {
        0 => flip_bytes(rng, bytes),
        1 => {
            // Overwrite one float of the data at the same length.
            let data = bytes.len() - header_end;
            if data >= 4 {
                let at = header_end + rng.range(0, (data / 4 - 1) as i64) as usize * 4;
                let v: f32 =
                    [1.0, 0.0, -0.0, f32::NAN, f32::INFINITY, 1e-40][rng.range(0, 5) as usize];
                bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
            }
            bytes
        }
        2 => {
            // A byte of the header.
            let i = rng.range(0, header_end.max(1) as i64 - 1) as usize;
            if i < bytes.len() {
                bytes[i] ^= 1 << rng.range(0, 7);
            }
            bytes
        }
        3 => truncate(rng, bytes),
        4 => {
            let extra = [0usize, 1, 3, 4, 64][rng.range(0, 4) as usize];
            let fill = rng.next_u64() as u8;
            bytes.extend(vec![fill; extra]);
            if extra == 0 {
                bytes.push(b'\n');
            }
            bytes
        }
        _ => {
            // A field of the JSON header replaced.
            let first = bytes.iter().position(|&b| b == b'\n').map_or(0, |i| i + 1);
            let line = &bytes[first..header_end.max(first)];
            let Ok(mut v) = serde_json::from_slice::<serde_json::Value>(line) else {
                return bytes;
            };
            let mut leaves = Vec::new();
            json_leaves(&v, String::new(), &mut leaves);
            if leaves.is_empty() {
                return bytes;
            }
            let at = leaves[rng.range(0, leaves.len() as i64 - 1) as usize].clone();
            let with = json_edge(rng, &PathBuf::from("/nonexistent"));
            let _ = write!(log, "{at} = {with} ");
            if let Some(slot) = v.pointer_mut(&at) {
                *slot = with;
            }
            let mut out = bytes[..first].to_vec();
            out.extend(serde_json::to_vec(&v).unwrap());
            out.push(b'\n');
            out.extend(&bytes[header_end.min(bytes.len())..]);
            out
        }
    }
}

/// JSON pointers of every leaf (and every array and object) of `v`.
fn json_leaves(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Array(a) => {
            if !at.is_empty() {
                out.push(at.clone());
            }
            for (i, x) in a.iter().enumerate() {
                json_leaves(x, format!("{at}/{i}"), out);
            }
        }
        serde_json::Value::Object(o) => {
            if !at.is_empty() {
                out.push(at.clone());
            }
            for (k, x) in o {
                let k = k.replace('~', "~0").replace('/', "~1");
                json_leaves(x, format!("{at}/{k}"), out);
            }
        }
        _ => out.push(at),
    }
}

/// A JSON value at the edges: paths that leave a directory, odd names,
/// extreme numbers, other types.
fn json_edge(rng: &mut Rng, victim: &Path) -> serde_json::Value {
    use serde_json::json;
    match rng.range(0, 20) {
        0 => json!("../victim.txt"),
        1 => json!("../../victim.txt"),
        2 => json!("../../../victim.txt"),
        3 => json!(show(victim)),
        4 => json!(""),
        5 => json!("."),
        6 => json!(".."),
        7 => json!("a/b.png"),
        8 => json!("x\u{0}y"),
        9 => json!("images/../../victim.txt"),
        10 => json!("x".repeat(300)),
        11 => json!(-1),
        12 => json!(0),
        13 => json!(1e308),
        14 => json!(u64::MAX),
        15 => json!(0.5),
        16 => json!(null),
        17 => json!([]),
        18 => json!({}),
        19 => json!(true),
        _ => json!("x\ny"),
    }
}

/// Tile parts: a copy of the cached parts, one mutated (or reordered,
/// repeated, missing), merged with odd output names. Either a clean
/// error naming a part or an output (and nothing replaced or left
/// behind), or exit 0 with the merge equal bit for bit to the unmutated
/// one.
fn tile_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    let base = tile_base(case)?;
    let names = [["p1", "p2"], ["a.part", "b.part"], ["x.png", "y.exr"]][rng.range(0, 2) as usize];
    let p: Vec<PathBuf> = names.iter().map(|n| case.dir.join(n)).collect();
    let mut parts = base.parts.clone();
    let mutate = rng.range(0, 4) != 0;
    if mutate {
        let k = rng.range(0, 1) as usize;
        let _ = write!(case.log, "part {k}: ");
        for _ in 0..rng.range(1, 2) {
            parts[k] = mutate_part(rng, std::mem::take(&mut parts[k]), &mut case.log);
        }
    }
    case.write(names[0], &parts[0]);
    case.write(names[1], &parts[1]);
    let existing = case.write("existing.png", b"old");
    let mut inputs = vec![p[0].clone(), p[1].clone()];
    match rng.range(0, 9) {
        0 => inputs.reverse(),
        1 => inputs[1] = inputs[0].clone(),
        2 => inputs.truncate(1),
        3 => inputs.push(case.dir.join("missing.part")),
        _ => {}
    }
    let outs = [
        case.dir.join("m.exr"),
        case.dir.join("m.png"),
        p[0].clone(),
        p[1].clone(),
        existing.clone(),
        PathBuf::from(format!("{}/", case.dir.join("m.exr").display())),
        case.dir.join("missing/m.png"),
        case.dir.clone(),
        case.dir.join("m.bmp"),
    ];
    let o = match rng.range(0, 12) {
        k @ 0..=8 => outs[k as usize].clone(),
        _ => outs[0].clone(),
    };
    let exr = match rng.range(0, 5) {
        0 => Some(outs[rng.range(0, outs.len() as i64 - 1) as usize].clone()),
        1 => Some(case.dir.join("e.exr")),
        _ => None,
    };
    let mut args = strings(&["penumbra", "merge-tiles"]);
    args.extend(inputs.iter().map(|p| show(p)));
    args.extend(["-o".into(), show(&o)]);
    if let Some(e) = &exr {
        args.extend(["--exr".into(), show(e)]);
    }
    let _ = write!(case.log, "args {args:?}");
    let mut paths = inputs.clone();
    paths.push(o.clone());
    paths.extend(exr.clone());
    let before = snapshot(&case.dir, &[]);
    match cli(&args) {
        CliResult::Usage(u) => u,
        CliResult::Ran(Err(e)) => {
            let outcome = classify_error(&e, &paths)?;
            let diff = changed(&before, &snapshot(&case.dir, &[]));
            if !diff.is_empty() {
                return Err(format!("merge refused ({e}) but changed files: {diff:?}"));
            }
            Ok(outcome)
        }
        CliResult::Ran(Ok(_)) => {
            let clean = !mutate || parts[0] == base.parts[0] && parts[1] == base.parts[1];
            for out in std::iter::once(&o).chain(exr.iter()) {
                let img = read_image(out).map_err(|e| format!("merged output unreadable: {e}"))?;
                // Compared with the base merge of the same format.
                let png = std::fs::read(out).is_ok_and(|b| b.starts_with(b"\x89PNG"));
                let want = if png { &base.png } else { &base.exr };
                if !same_image(&img, want) {
                    return Err(format!(
                        "merge-tiles succeeded (parts {}) but {} differs from the unmutated merge",
                        if clean { "unmutated" } else { "mutated" },
                        out.display()
                    ));
                }
            }
            Ok(Outcome::Printed)
        }
    }
}

/// Two shards of a tiny compare of [`TINY_SCENE`], made once per worker.
fn shard_base(case: &Case) -> Result<&'static (PathBuf, PathBuf), String> {
    static BASE: OnceLock<Result<(PathBuf, PathBuf), String>> = OnceLock::new();
    BASE.get_or_init(|| {
        let dir = worker_cache(case).join("shards");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let scene = dir.join("scene.toml");
        std::fs::write(&scene, TINY_SCENE).unwrap();
        let shards = (dir.join("s1"), dir.join("s2"));
        for (i, out) in [("1/2", &shards.0), ("2/2", &shards.1)] {
            let mut args = strings(&["penumbra", "compare"]);
            args.push(show(&scene));
            args.extend(strings(&[
                "--techniques",
                "dcs,shadow-map",
                "--samples",
                "4,8",
                "--reference-samples",
                "16",
                "--width",
                "12",
                "--height",
                "12",
                "--threads",
                "1",
                "--repeat",
                "1",
                "--shard",
                i,
                "--out",
            ]));
            args.push(show(out));
            args.extend(["--cache-dir".into(), show(&dir.join("cache"))]);
            must_run(&args)?;
        }
        Ok(shards)
    })
    .as_ref()
    .map_err(Clone::clone)
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let (src, dst) = (e.path(), to.join(e.file_name()));
        if e.file_type().unwrap().is_dir() {
            copy_tree(&src, &dst);
        } else {
            std::fs::copy(&src, &dst).unwrap();
        }
    }
}

/// Partial compare results: a shard's JSON mutated (names that leave the
/// shard or `--out`, numbers, types, truncation), then `compare --merge`.
/// Either an error naming a shard's file, with no `--out` left behind,
/// or success with every file written under `--out`; in both, nothing
/// outside `--out` (a canary beside it, the shards) changes.
fn partial_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    let (b1, b2) = shard_base(case)?;
    let (s1, s2) = (case.dir.join("s1"), case.dir.join("s2"));
    copy_tree(b1, &s1);
    copy_tree(b2, &s2);
    let victim = case.write("victim.txt", b"precious");
    std::fs::create_dir_all(case.dir.join("res")).unwrap();
    case.write("res/canary", b"canary");
    let out = case.dir.join("res/out");
    let (shard, file) = match rng.range(0, 1) {
        0 => (&s1, s1.join("shard-1-of-2.json")),
        _ => (&s2, s2.join("shard-2-of-2.json")),
    };
    let text = std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))?;
    let mutated = match rng.range(0, 5) {
        0 => truncate(rng, text),
        1 => flip_bytes(rng, text),
        _ => {
            let mut v: serde_json::Value =
                serde_json::from_slice(&text).map_err(|e| format!("shard JSON: {e}"))?;
            let mut leaves = Vec::new();
            json_leaves(&v, String::new(), &mut leaves);
            // Mostly the names of images and heatmaps.
            let named: Vec<String> = leaves
                .iter()
                .filter(|l| l.contains("image") || l.contains("heatmap") || l.contains("dir"))
                .cloned()
                .collect();
            let pool = if !named.is_empty() && rng.range(0, 1) == 0 {
                &named
            } else {
                &leaves
            };
            for _ in 0..rng.range(1, 2) {
                let at = pool[rng.range(0, pool.len() as i64 - 1) as usize].clone();
                let with = json_edge(rng, &victim);
                let _ = write!(case.log, "{}:{at} = {with} ", file.display());
                if let Some(slot) = v.pointer_mut(&at) {
                    *slot = with;
                }
            }
            serde_json::to_vec(&v).unwrap()
        }
    };
    std::fs::write(&file, mutated).unwrap();
    let mut args = strings(&["penumbra", "compare", "--merge"]);
    args.extend([show(&s1), show(&s2), "--out".into(), show(&out)]);
    if rng.range(0, 3) == 0 {
        args.push("--no-images".into());
    }
    let _ = write!(case.log, "args {args:?}");
    let before = snapshot(&case.dir, &[]);
    let result = cli(&args);
    let diff = changed(&before, &snapshot(&case.dir, std::slice::from_ref(&out)));
    if !diff.is_empty() {
        return Err(format!(
            "compare --merge changed files outside --out: {diff:?}"
        ));
    }
    match result {
        CliResult::Usage(u) => u,
        CliResult::Ran(Ok(_)) => Ok(Outcome::Printed),
        CliResult::Ran(Err(e)) => {
            if out.exists() {
                return Err(format!(
                    "compare --merge failed ({e}) but left --out behind"
                ));
            }
            let msg = e.to_string();
            if !msg.contains(&show(shard)) && !msg.contains(&show(&s1)) && !msg.contains(&show(&s2))
            {
                return Err(format!("compare --merge error names no shard file: {msg}"));
            }
            Ok(Outcome::FileError)
        }
    }
}

/// Special files as inputs (a FIFO, `/dev/zero`, `/dev/null`, a
/// directory) of every reader, and as outputs (`/dev/full` as stdout, a
/// directory, a path ending in `/`, a link to an existing file). Inputs
/// are refused naming them, without blocking; a failing output replaces
/// no existing file and leaves nothing behind.
fn special_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    let fifo = case.dir.join("fifo");
    let ok = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        return Err("mkfifo failed".into());
    }
    let sub = case.dir.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let specials = [
        fifo.clone(),
        PathBuf::from("/dev/zero"),
        PathBuf::from("/dev/null"),
        sub.clone(),
    ];
    let special = specials[rng.range(0, 3) as usize].clone();
    let sp = show(&special);
    let _ = write!(case.log, "special {sp}: ");
    if rng.range(0, 1) == 0 {
        // As an input.
        let scene = case.dir.join("scene.toml");
        let what = rng.range(0, 6);
        let (path, args): (PathBuf, Vec<String>) = match what {
            0 => (special.clone(), strings(&["penumbra", "info", &sp])),
            1 => {
                let text = SMALL_SCENE.replace("\"model.obj\"", &format!("{sp:?}"));
                case.write("scene.toml", text.as_bytes());
                (scene.clone(), strings(&["penumbra", "info", &show(&scene)]))
            }
            2 => {
                let obj = SMALL_OBJ.replace("model.mtl", &sp);
                case.write("model.obj", obj.as_bytes());
                case.write("scene.toml", SMALL_SCENE.as_bytes());
                (scene.clone(), strings(&["penumbra", "info", &show(&scene)]))
            }
            3 => {
                let text = SMALL_SCENE.replace("\"tex.tga\"", &format!("{sp:?}"));
                case.write("scene.toml", text.as_bytes());
                (scene.clone(), strings(&["penumbra", "info", &show(&scene)]))
            }
            4 => {
                let a = case.dir.join("a.png");
                write_png(&a, 2, 2, &[Vec3::ONE; 4]).unwrap();
                let mut args = strings(&["penumbra", "diff"]);
                let mut pair = [show(&a), sp.clone()];
                if rng.range(0, 1) == 0 {
                    pair.reverse();
                }
                args.extend(pair);
                if rng.range(0, 2) == 0 {
                    args.extend(["--mask".into(), sp.clone()]);
                }
                (special.clone(), args)
            }
            5 => {
                let base = tile_base(case)?;
                let p1 = case.write("p1", &base.parts[0]);
                let mut args = strings(&["penumbra", "merge-tiles"]);
                args.extend([show(&p1), sp.clone(), "-o".into()]);
                args.push(show(&case.dir.join("m.png")));
                (special.clone(), args)
            }
            _ => {
                let mut args = strings(&["penumbra", "render", &sp, "-o"]);
                args.push(show(&case.dir.join("o.png")));
                (special.clone(), args)
            }
        };
        let _ = write!(case.log, "input {what} args {args:?}");
        return match cli(&args) {
            CliResult::Usage(u) => u,
            CliResult::Ran(Ok(_)) => Err(format!("special input {sp} accepted")),
            CliResult::Ran(Err(e)) => {
                let msg = e.to_string();
                let names_it = msg.contains(&sp) || special == sub && msg.contains("directory");
                if !names_it {
                    return Err(format!("special input {sp}: error not naming it: {msg}"));
                }
                classify_error(&e, &[path, special.clone()])
            }
        };
    }
    // As an output.
    let existing = case.write("existing.png", b"old");
    let existing_exr = case.write("existing.exr", b"old");
    let link = case.dir.join("link.png");
    std::os::unix::fs::symlink(&existing, &link).unwrap();
    let outs = [
        case.dir.join("new.png"),
        PathBuf::from("/dev/full"),
        PathBuf::from("/dev/full.png"),
        sub.clone(),
        PathBuf::from(format!("{}/", case.dir.join("d.png").display())),
        PathBuf::from(format!("{}/", existing.display())),
        link.clone(),
        existing.clone(),
        fifo.clone(),
        case.dir.join("x.exr/."),
    ];
    let o = outs[rng.range(0, outs.len() as i64 - 1) as usize].clone();
    let exr = match rng.range(0, 3) {
        0 => Some(existing_exr.clone()),
        1 => Some(outs[rng.range(0, outs.len() as i64 - 1) as usize].clone()),
        _ => None,
    };
    let what = rng.range(0, 3);
    if what == 3 {
        // stdout on a full device, through the binary.
        let args: Vec<String> = match rng.range(0, 4) {
            0 => strings(&["techniques"]),
            1 => strings(&["techniques", "--markdown"]),
            2 => strings(&["--help"]),
            3 => strings(&["techniques", "--names"]),
            _ => {
                let a = case.dir.join("a.png");
                write_png(&a, 2, 2, &[Vec3::ONE; 4]).unwrap();
                vec!["diff".into(), show(&a), show(&a)]
            }
        };
        let _ = write!(case.log, "stdout /dev/full: {args:?}");
        let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
            return Ok(Outcome::Printed);
        };
        let output = Command::new(env!("CARGO_BIN_EXE_penumbra"))
            .args(&args)
            .current_dir(&case.dir)
            .stdin(Stdio::null())
            .stdout(full)
            .stderr(Stdio::piped())
            .output()
            .map_err(|e| format!("run penumbra: {e}"))?;
        let err = String::from_utf8_lossy(&output.stderr);
        if output.status.code() != Some(2) || !err.contains("<stdout>") || err.contains("panicked")
        {
            return Err(format!(
                "stdout on /dev/full: {:?}, stderr {err:?}",
                output.status
            ));
        }
        return Ok(Outcome::PathError);
    }
    let mut args: Vec<String> = match what {
        0 | 1 => {
            let scene = case.write("scene.toml", SMALL_SCENE.as_bytes());
            let mut a = strings(&["penumbra", "render", &show(&scene)]);
            a.extend(strings(&[
                "--width",
                "8",
                "--height",
                "8",
                "--samples",
                "2",
            ]));
            a.extend(strings(&["--threads", "1"]));
            a
        }
        _ => {
            let base = tile_base(case)?;
            let p1 = case.write("p1", &base.parts[0]);
            let p2 = case.write("p2", &base.parts[1]);
            vec![
                "penumbra".into(),
                "merge-tiles".into(),
                show(&p1),
                show(&p2),
            ]
        }
    };
    args.extend(["-o".into(), show(&o)]);
    if let Some(e) = &exr {
        args.extend(["--exr".into(), show(e)]);
    }
    let _ = write!(case.log, "output args {args:?}");
    let mut paths = vec![o.clone()];
    paths.extend(exr.clone());
    // An output FIFO is written in place: like any writer, penumbra waits
    // for a reader, so the case holds one open (the outputs here are far
    // smaller than a pipe's buffer).
    let _reader = {
        use std::os::unix::fs::OpenOptionsExt;
        std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc_o_nonblock())
            .open(&fifo)
            .map_err(|e| format!("open the FIFO's read end: {e}"))?
    };
    let before = snapshot(&case.dir, &[]);
    match cli(&args) {
        CliResult::Usage(u) => u,
        CliResult::Ran(Ok(_)) => Ok(Outcome::Printed),
        CliResult::Ran(Err(e)) => {
            let outcome = classify_error(&e, &paths)?;
            let diff = changed(&before, &snapshot(&case.dir, &[]));
            if !diff.is_empty() {
                return Err(format!("failed ({e}) but changed files: {diff:?}"));
            }
            Ok(outcome)
        }
    }
}

/// `O_NONBLOCK` on Linux (no libc dependency in the tests).
fn libc_o_nonblock() -> i32 {
    0o4000
}

/// Values for an option of a subcommand: valid, at the edges and
/// garbage, bounded where a valid value would make a case slow.
fn option_values(sub: &str, long: &str, arg: &clap::Arg, case: &Case) -> Vec<String> {
    let d = |n: &str| show(&case.dir.join(n));
    let v: &[&str] = match long {
        "width" | "height" => &["1", "8", "16", "0", "-1", "16385", "x", ""],
        "samples" if sub == "compare" => &["1", "2,4", "0", "4,", "x", "1048577", ""],
        "samples" => &["1", "4", "0", "1048577", "x", "-1"],
        "reference-samples" => &["1", "8", "0", "x", "1048577"],
        "repeat" => &["1", "0", "2", "x"],
        "threads" | "cpus-per-task" => &["1", "2", "0", "1025", "x"],
        "seed" => &["0", "18446744073709551615", "-1", "x"],
        "verify" => &["1", "all", "0", "x", "8"],
        "tiles" if sub == "sweep" => &["1", "2", "0", "100000", "x"],
        "tiles" | "shard" => &[
            "1/2", "2/2", "0/2", "3/2", "1/0", "1/1", "x", "1/65536", "/",
        ],
        "shards" | "throttle" => &["1", "2", "0", "100000", "x"],
        "map-size" => &["1", "16", "0", "16385", "x"],
        "pcss-blocker-samples" | "pcss-filter-samples" => &["1", "4", "0", "65536", "x"],
        "pc-sample-sets" => &["0", "1", "8", "1025", "x"],
        "max-depth" | "adaptive-centre-depth" => &["0", "4", "12", "x", "-1"],
        "ssm-passes" => &["1", "2", "0", "1000", "x"],
        "patterns" | "pattern" => &[
            "stratified",
            "correlated",
            "sobol02",
            "interleaved4",
            "interleaved0",
            "stratified,sobol02",
            "x",
            "",
        ],
        "pcf" => &["1", "2x2", "3x3", "poisson:8", "poisson:0", "0x0", "x"],
        "aov" => &["vcoef", "depth,mask", "", "x", "vcoef,vcoef"],
        "channels-a" | "channels-b" | "mask-channel" => &["R", "R,G,B", "mask.Y", "", "X"],
        "sbatch" => &["/nonexistent/sbatch"],
        "penumbra" => &["/bin/true", "", "a b"],
        "partition" | "job-name" | "time" | "mem" | "account" | "qos" | "constraint"
        | "merge-time" | "merge-mem" | "setup" | "sbatch-arg" => &[
            "p",
            "",
            "a b",
            "1:00:00",
            "p\n#SBATCH --evil",
            "a\u{1b}b",
            "--x",
            "'",
        ],
        _ => &[],
    };
    if !v.is_empty() {
        return strings(v);
    }
    match long {
        "out" | "output" | "exr" | "report" | "log-dir" | "cache-dir" | "render" | "mask"
        | "merge" | "flip-map" => {
            let mut p = vec![
                d("out"),
                d("o.png"),
                d("o.exr"),
                format!("{}/", d("o.png")),
                d("missing/o.png"),
                show(&case.dir),
                d("scene.toml"),
                String::new(),
                "/dev/full".into(),
            ];
            if long == "mask" {
                p.push(d("a.png"));
            }
            return p;
        }
        _ => {}
    }
    let mut values: Vec<String> = arg
        .get_possible_values()
        .iter()
        .map(|p| p.get_name().to_string())
        .collect();
    if long == "technique" || long == "techniques" {
        values.extend(strings(&["reference,dcs", "dcs,dcs", ""]));
    }
    values.extend(strings(&[
        "0", "1", "2", "-1", "0.5", "x", "", "nan", "inf", "1e-9", "1e9",
    ]));
    values
}

/// Random command lines for every subcommand, their options enumerated
/// from clap (`Cli::command()`): each option taken with probability
/// 1/4, with a valid, edge or garbage value. Costly options get bounded
/// defaults when not drawn; outputs stay in the case directory (and
/// `sweep` is always a dry run, which must write nothing).
fn options_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    use clap::CommandFactory;
    let command = penumbra::internal::cli::Cli::command();
    let subs = [
        "compare",
        "merge-tiles",
        "sweep",
        "techniques",
        "render",
        "diff",
        "info",
    ];
    let sub = subs[rng.range(0, subs.len() as i64 - 1) as usize];
    let Some(c) = command.find_subcommand(sub) else {
        return Err(format!("no subcommand {sub}"));
    };
    let scene = case.write("scene.toml", TINY_SCENE.as_bytes());
    let a = case.dir.join("a.png");
    write_png(&a, 2, 2, &[Vec3::ONE; 4]).unwrap();
    let mut args = strings(&["penumbra", sub]);
    let mut given: Vec<String> = Vec::new();
    let mut trailing: Vec<String> = Vec::new();
    for arg in c.get_arguments() {
        let Some(long) = arg.get_long() else {
            continue;
        };
        if long == "help" || long == "submit" || rng.range(0, 3) != 0 {
            continue;
        }
        given.push(long.to_string());
        args.push(format!("--{long}"));
        if arg.get_action().takes_values() {
            let values = option_values(sub, long, arg, case);
            let v = values[rng.range(0, values.len() as i64 - 1) as usize].clone();
            if long == "merge" {
                // Directories of partials: the shards' or odd ones.
                args.push(show(&case.dir));
                if rng.range(0, 1) == 0 {
                    args.push(v);
                }
            } else {
                args.push(v);
            }
        }
    }
    if rng.range(0, 15) == 0 {
        args.push(one(rng, &["--bogus", "extra", "--", "-"]).to_string());
    }
    let has = |n: &str| given.iter().any(|g| g == n);
    let mut defaults = |pairs: &[(&str, String)]| {
        for (n, v) in pairs {
            if !has(n) {
                args.extend([format!("--{n}"), v.clone()]);
            }
        }
    };
    let mut positional: Vec<String> = Vec::new();
    let odd_scene = [
        show(&scene),
        show(&scene),
        show(&case.dir.join("missing.toml")),
        show(&case.dir),
    ][rng.range(0, 3) as usize]
        .clone();
    match sub {
        "compare" => {
            defaults(&[
                ("width", "8".into()),
                ("height", "8".into()),
                ("reference-samples", "8".into()),
                ("samples", "2".into()),
                ("repeat", "1".into()),
                ("threads", "1".into()),
                ("techniques", "dcs,shadow-map".into()),
                ("out", show(&case.dir.join("out"))),
                ("cache-dir", show(&case.dir.join("cache"))),
            ]);
            if !has("merge") {
                positional.push(odd_scene);
            }
        }
        "render" => {
            defaults(&[
                ("width", "16".into()),
                ("height", "16".into()),
                ("samples", "4".into()),
                ("threads", "1".into()),
                ("output", show(&case.dir.join("o.png"))),
            ]);
            positional.push(odd_scene);
        }
        "merge-tiles" => {
            let base = tile_base(case)?;
            let p1 = case.write("p1", &base.parts[0]);
            let p2 = case.write("p2", &base.parts[1]);
            defaults(&[("output", show(&case.dir.join("m.png")))]);
            positional.extend([show(&p1), show(&p2)]);
        }
        "sweep" => {
            defaults(&[("out", show(&case.dir.join("sweep")))]);
            if !has("dry-run") {
                positional.push("--dry-run".into());
            }
            trailing.push("--".into());
            trailing.push(odd_scene);
            if rng.range(0, 1) == 0 {
                trailing.extend(strings(&["--techniques", "dcs", "--width", "8"]));
            }
        }
        "diff" => positional.extend([show(&a), show(&a)]),
        "info" => positional.push(odd_scene),
        _ => {}
    }
    args.extend(positional);
    args.extend(trailing);
    let _ = write!(case.log, "args {args:?}");
    let before = snapshot(&case.dir, &[]);
    let mut paths: Vec<PathBuf> = args.iter().skip(2).map(PathBuf::from).collect();
    paths.push(case.dir.join("o.png"));
    let result = match cli(&args) {
        CliResult::Usage(u) => u,
        CliResult::Ran(Ok(_)) => Ok(Outcome::Printed),
        CliResult::Ran(Err(e)) => classify_error(&e, &paths),
    };
    if sub == "sweep" {
        let diff = changed(&before, &snapshot(&case.dir, &[]));
        if !diff.is_empty() {
            return Err(format!("sweep --dry-run wrote files: {diff:?}"));
        }
    }
    result
}

/// The agreement property on scenes the random scenes of
/// `tests/it/agreement.rs` do not make: an occluder touching or entering the
/// light (rect or sphere), and objects with `receive_shadows = false`.
/// Every technique either refuses naming `--technique` or renders a
/// finite `vcoef` layer that is exactly 1 on non-receiving surfaces; the
/// exact techniques' layer equals the reference's (same samples) on all
/// but 0.5 % of the surface pixels, beyond one sample's weight.
fn agreement_case(rng: &mut Rng, case: &mut Case) -> Result<Outcome, String> {
    const SIDE: u32 = 24;
    let sphere = rng.range(0, 1) == 1;
    let size = [0.25, 0.5, 0.8][rng.range(0, 2) as usize];
    let mut toml = String::from(
        "[camera]\neye = [0, 5, 6]\ntarget = [0, 0, 0]\nfov_y = 45\nwidth = 24\nheight = 24\n",
    );
    let _ = match sphere {
        true => write!(
            toml,
            "[[light]]\ntype = \"sphere\"\ncenter = [0, 4, 0]\nradius = {size}\nradiance = 10\n"
        ),
        false => write!(
            toml,
            "[[light]]\ntype = \"rect\"\ncenter = [0, 4, 0]\nu = [{size}, 0, 0]\nv = [0, 0, {size}]\nradiance = 10\n"
        ),
    };
    let receive = |rng: &mut Rng| match rng.range(0, 2) {
        0 => "receive_shadows = false\n",
        _ => "",
    };
    let r = receive(rng);
    let _ = write!(
        toml,
        "[[object]]\nname = \"ground\"\nshape = \"quad\"\nsize = [6.0, 6.0]\n{r}"
    );
    for k in 0..rng.range(0, 2) {
        let shape = ["box", "sphere", "quad"][rng.range(0, 2) as usize];
        let s = 0.3 + rng.f64() * 1.0;
        let at = [
            rng.f64() * 3.0 - 1.5,
            0.3 + rng.f64() * 2.0,
            rng.f64() * 3.0 - 1.5,
        ];
        let size = match shape {
            "sphere" => format!("radius = {}", s / 2.0),
            "quad" => format!("size = [{s}, {s}]\nrotate = [{}, 0, 0]", rng.range(0, 90)),
            _ => format!("size = [{s}, {s}, {s}]"),
        };
        let opacity = match rng.range(0, 4) {
            0 => "material = { opacity = 0.5 }\n",
            _ => "",
        };
        let r = receive(rng);
        let _ = write!(
            toml,
            "[[object]]\nname = \"o{k}\"\nshape = \"{shape}\"\n{size}\ntranslate = [{}, {}, {}]\n{opacity}{r}",
            at[0], at[1], at[2]
        );
    }
    // The caster at the light: touching it, just short of it, or into it.
    let depth = [0.0, 0.0, -1e-3, 1e-3, 0.01, 0.2, 0.5][rng.range(0, 6) as usize];
    let x = [0.0, 0.0, 0.3 * size, size, 2.0 * size][rng.range(0, 4) as usize];
    let r = receive(rng);
    let caster = match (sphere, rng.range(0, 1)) {
        // A vertical unit quad whose top edge is `depth` into the light's
        // plane (rect) or its ball (sphere).
        (false, 0) => format!(
            "shape = \"quad\"\nsize = [1, 1]\ntranslate = [{x}, {}, 0]\nrotate = [90, 0, 0]\n",
            4.0 - 0.5 + depth
        ),
        (true, 0) => format!(
            "shape = \"quad\"\nsize = [1, 1]\ntranslate = [{x}, {}, 0]\nrotate = [90, 0, 0]\n",
            4.0 - size - 0.5 + depth
        ),
        // A unit box whose top face is `depth` into the light.
        (false, _) => format!(
            "shape = \"box\"\nsize = [1, 1, 1]\ntranslate = [{x}, {}, 0]\n",
            4.0 - 0.5 + depth
        ),
        (true, _) => format!(
            "shape = \"box\"\nsize = [1, 1, 1]\ntranslate = [{x}, {}, 0]\n",
            4.0 - size - 0.5 + depth
        ),
    };
    let _ = write!(toml, "[[object]]\nname = \"caster\"\n{caster}{r}");
    let path = case.write("scene.toml", toml.as_bytes());
    let _ = write!(case.log, "agreement scene {}", path.display());
    let scene = load_scene(&path).map_err(|e| format!("generated scene: {e}"))?;
    let frame = common::Frame::new(&scene, SIDE, SIDE);
    let n = (SIDE * SIDE) as usize;
    let surface: Vec<usize> = (0..n).filter(|&i| frame.gbuffer.is_surface(i)).collect();
    let non_receiving: Vec<usize> = surface
        .iter()
        .copied()
        .filter(|&i| !scene.objects[frame.gbuffer.sample(i).object as usize].receive_shadows)
        .collect();
    let vcoef_of = |technique: penumbra::internal::shadow::Technique,
                    reference: bool|
     -> Result<(Vec<f32>, bool), Error> {
        let (options, pattern) = common::matched_sampling(technique);
        let options = RenderOptions {
            technique: match reference {
                true => penumbra::internal::shadow::Technique::named("reference").unwrap(),
                false => technique,
            },
            samples: 16,
            seed: 3,
            width: Some(SIDE),
            height: Some(SIDE),
            pattern,
            options,
            aovs: vec![Aov::Vcoef],
            threads: None,
            progressive: None,
        };
        let out = render(&scene, &options)?;
        let layer = out.layers.iter().find(|l| l.name == "vcoef");
        let v = layer.map(|l| l.channels[0].1.clone()).unwrap_or_default();
        Ok((v, out.warnings.is_empty()))
    };
    let mut failures: Vec<String> = Vec::new();
    for technique in penumbra::internal::shadow::Technique::all() {
        let name = technique.name();
        let mut fail = |f: String| failures.push(f);
        let (v, quiet) = match vcoef_of(technique, false) {
            Ok(r) => r,
            Err(e) => {
                let msg = e.to_string();
                if !msg.contains("--technique") {
                    fail(format!("{name} refused without naming --technique: {msg}"));
                }
                continue;
            }
        };
        if v.len() != n {
            fail(format!("{name}: vcoef layer of {} values", v.len()));
            continue;
        }
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            fail(format!("{name}: non-finite vcoef {} at pixel {i}", v[i]));
        }
        let shadowed = non_receiving.iter().filter(|&&i| v[i] != 1.0).count();
        if shadowed > 0 {
            fail(format!(
                "{name}: {shadowed} pixels of receive_shadows = false objects with vcoef below 1"
            ));
        }
        if technique
            .capabilities(&penumbra::internal::shadow::TechniqueOptions::default())
            .exact
            && quiet
            && name != "reference"
        {
            let r = match vcoef_of(technique, true) {
                Ok((r, _)) => r,
                Err(e) => {
                    fail(format!("reference: {e}"));
                    continue;
                }
            };
            let differ: Vec<usize> = surface
                .iter()
                .copied()
                .filter(|&i| (v[i] - r[i]).abs() > 1.0 / 16.0 + 1e-4)
                .collect();
            if differ.len() as f64 > 0.005 * surface.len() as f64 {
                fail(format!(
                    "{name}: {} of {} surface pixels differ from the reference by more than \
                     1/16 (first {:?})",
                    differ.len(),
                    surface.len(),
                    &differ[..differ.len().min(5)]
                ));
            }
        }
    }
    match failures.is_empty() {
        true => Ok(Outcome::Rendered),
        false => Err(failures.join("; ")),
    }
}

// ------------------------------------------------------------ driver ----

/// The worker side: runs cases `FROM..TO` of run `SEED`, appending
/// `start <index>` to the progress file before each and a line per
/// finding to the findings file; a final `done <counts>` line ends it.
#[test]
#[ignore = "the worker process of `fuzz`, which starts it"]
fn fuzz_worker() {
    let Ok(dir) = std::env::var("PENUMBRA_FUZZ_WORKER") else {
        // Run by hand (`--ignored`): nothing to do; `fuzz` is the test.
        eprintln!("fuzz_worker runs only as the worker process of `fuzz`");
        return;
    };
    let dir = PathBuf::from(dir);
    let from = env_u64("PENUMBRA_FUZZ_FROM").unwrap();
    let to = env_u64("PENUMBRA_FUZZ_TO").unwrap();
    let run_seed = env_u64("PENUMBRA_FUZZ_SEED").unwrap();
    let append = |name: &str, line: &str| {
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(dir.join(name))
            .unwrap();
        f.write_all(line.as_bytes()).unwrap();
        f.flush().unwrap();
    };
    // Panics are findings, reported with their case; keep their default
    // message (on the worker's stderr log) short.
    std::panic::set_hook(Box::new(|info| {
        eprintln!("panic: {info}");
    }));
    let mut counts = [0u64; OUTCOMES.len()];
    let work = dir.join("case");
    for index in from..to {
        append("progress", &format!("start {index}\n"));
        let seed = case_seed(run_seed, index);
        let result = catch_unwind(AssertUnwindSafe(|| run_case(seed, &work)));
        let finding = match result {
            Ok(Ok(outcome)) => {
                counts[OUTCOMES.iter().position(|o| *o == outcome).unwrap()] += 1;
                None
            }
            Ok(Err(e)) => Some(e),
            Err(panic) => {
                let msg = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                Some(format!("panic: {msg}"))
            }
        };
        if let Some(f) = finding {
            let one_line = f.replace('\n', " | ");
            append(
                "findings",
                &format!("case {index} seed {seed:#x}: {one_line}\n"),
            );
        }
    }
    let counts: Vec<String> = counts.iter().map(u64::to_string).collect();
    append("progress", &format!("done {}\n", counts.join(" ")));
}

/// Runs one case in-process and prints everything about it.
fn rerun(seed: u64) {
    let dir = common::scratch_dir(&format!("fuzz-case-{seed:x}"));
    let result = run_case(seed, &dir.join("case"));
    println!("case seed {seed:#x}: {result:?}");
    println!("inputs kept in {}", dir.join("case").display());
    assert!(
        result.is_ok(),
        "case {seed:#x} fails: {}",
        result.unwrap_err()
    );
}

#[test]
fn fuzz() {
    if let Some(seed) = env_u64("PENUMBRA_FUZZ_CASE_SEED") {
        return rerun(seed);
    }
    let cases = env_u64("PENUMBRA_FUZZ_CASES").unwrap_or(DEFAULT_CASES);
    let run_seed = env_u64("PENUMBRA_FUZZ_SEED").unwrap_or(1);
    let timeout =
        Duration::from_secs(env_u64("PENUMBRA_FUZZ_TIMEOUT").unwrap_or(DEFAULT_TIMEOUT_S));
    let dir = common::scratch_dir(&format!("fuzz-{run_seed}"));
    let exe = std::env::current_exe().unwrap();
    let started = Instant::now();
    let mut findings: Vec<String> = Vec::new();
    let mut counts = [0u64; OUTCOMES.len()];
    let mut next = 0;
    let mut workers = 0;
    while next < cases {
        workers += 1;
        let _ = std::fs::remove_file(dir.join("progress"));
        let log = dir.join(format!("worker-{workers}.log"));
        let mut command = Command::new("/bin/sh");
        command
            .arg("-c")
            .arg(format!(
                "ulimit -v {ADDRESS_SPACE_KIB} && exec \"$0\" \"$@\""
            ))
            .arg(&exe)
            .args([
                // The test's name inside the one test binary
                // (`fuzz::fuzz_worker`): the module path without the crate.
                &module_path!().split_once("::").map_or_else(
                    || "fuzz_worker".to_string(),
                    |(_, module)| format!("{module}::fuzz_worker"),
                ),
                "--exact",
                "--ignored",
                "--nocapture",
                "--test-threads=1",
            ])
            .env("PENUMBRA_FUZZ_WORKER", &dir)
            .env("PENUMBRA_FUZZ_FROM", next.to_string())
            .env("PENUMBRA_FUZZ_TO", cases.to_string())
            .env("PENUMBRA_FUZZ_SEED", run_seed.to_string())
            .env("RAYON_NUM_THREADS", "1")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap());
        let mut child = command.spawn().expect("start the fuzz worker");
        let mut last = (String::new(), Instant::now());
        let status = loop {
            std::thread::sleep(Duration::from_millis(20));
            if let Some(status) = child.try_wait().unwrap() {
                break Some(status);
            }
            let progress = std::fs::read_to_string(dir.join("progress")).unwrap_or_default();
            let line = progress.lines().last().unwrap_or("").to_string();
            if line != last.0 {
                last = (line, Instant::now());
            } else if last.1.elapsed() > timeout {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
        };
        let progress = std::fs::read_to_string(dir.join("progress")).unwrap_or_default();
        let line = progress.lines().last().unwrap_or("");
        if let Some(done) = line.strip_prefix("done ") {
            for (c, n) in counts.iter_mut().zip(done.split(' ')) {
                *c += n.parse::<u64>().unwrap();
            }
            break;
        }
        // The worker died (or hung) in the case it last started.
        let Some(index) = line
            .strip_prefix("start ")
            .and_then(|i| i.parse::<u64>().ok())
        else {
            let tail = std::fs::read_to_string(&log).unwrap_or_default();
            panic!("fuzz worker ended before its first case ({status:?}): {tail}");
        };
        let seed = case_seed(run_seed, index);
        let how = match status {
            None => format!("hang: no progress for {} s (killed)", timeout.as_secs()),
            Some(s) => {
                let log_text = std::fs::read_to_string(&log).unwrap_or_default();
                let tail: String = log_text
                    .chars()
                    .rev()
                    .take(600)
                    .collect::<Vec<_>>()
                    .into_iter()
                    .rev()
                    .collect();
                format!(
                    "worker died: {s}; stderr ends: {}",
                    tail.replace('\n', " | ")
                )
            }
        };
        let finding = format!("case {index} seed {seed:#x}: {how}");
        // Said at once (a long run shows its hangs and crashes as it goes).
        eprintln!("fuzz: {finding}");
        findings.push(finding);
        // Case counts of a dead worker are lost; its findings are kept.
        next = index + 1;
    }
    findings.extend(
        std::fs::read_to_string(dir.join("findings"))
            .unwrap_or_default()
            .lines()
            .map(str::to_string),
    );
    let summary: Vec<String> = OUTCOMES
        .iter()
        .zip(counts)
        .map(|(o, n)| format!("{o:?} {n}"))
        .collect();
    println!(
        "fuzz: {cases} cases, run seed {run_seed}, {workers} worker(s), {:.1} s: {}; {} finding(s)",
        started.elapsed().as_secs_f64(),
        summary.join(", "),
        findings.len()
    );
    for f in &findings {
        println!("  {f}");
    }
    assert!(
        findings.is_empty(),
        "{} finding(s); rerun one with PENUMBRA_FUZZ_CASE_SEED=<seed> cargo test --release \
         --test it fuzz:: -- fuzz --nocapture:\n{}",
        findings.len(),
        findings.join("\n")
    );
    // The harness must exercise both ends: inputs refused and images made.
    if cases >= 500 {
        assert!(
            counts[0] > cases / 20,
            "too few cases rendered: {summary:?}"
        );
        assert!(counts[1] > cases / 20, "too few file errors: {summary:?}");
    }
}

/// The unmutated inputs all load and render: otherwise the mutations
/// would only ever test the error paths.
#[test]
fn fuzz_corpus_is_valid() {
    let dir = common::scratch_dir("fuzz-corpus");
    let case = Case {
        dir: dir.clone(),
        log: String::new(),
    };
    for (name, bytes) in small_files() {
        case.write(name, bytes);
    }
    let mut texts: Vec<(String, String)> = shipped_scenes().to_vec();
    texts.push(("small".into(), SMALL_SCENE.into()));
    for (name, text) in &texts {
        let path = case.write("scene.toml", text.as_bytes());
        let scene = load_scene(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(scene.triangle_count() > 0, "{name}");
    }
    let small = load_scene(&dir.join("scene.toml")).unwrap();
    assert_eq!(small.lights.len(), 2);
    assert!(small.textures.len() >= 3, "textures of the small scene");
    assert!(small.materials.len() >= 5, "MTL and inline materials");
}
