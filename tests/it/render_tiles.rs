//! `render --tiles I/N` + `merge-tiles`: the assembled PNG and EXR are the
//! single render's bytes for every technique that accepts bands, and the
//! merge refuses missing, duplicated and mismatched bands by name.

use crate::common;

use penumbra::internal::cluster::tiles::{band_rows, merge_parts, read_part, render_part};
use penumbra::internal::output::OutputSet;
use penumbra::internal::render::{render, with_threads, Aov, RenderOptions};
use penumbra::internal::report::Progress;
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::Technique;
use std::path::{Path, PathBuf};

fn options(technique: Technique, w: u32, h: u32) -> RenderOptions {
    RenderOptions {
        width: Some(w),
        height: Some(h),
        aovs: vec![Aov::Depth, Aov::Mask, Aov::Vcoef],
        technique,
        samples: 8,
        ..RenderOptions::default()
    }
}

/// The single render's PNG and EXR bytes.
fn whole(scene: &Scene, o: &RenderOptions, dir: &Path) -> (Vec<u8>, Vec<u8>) {
    let out = render(scene, o).expect("render");
    let (png, exr) = (dir.join("whole.png"), dir.join("whole.exr"));
    let mut set = OutputSet::new();
    set.png(&png, out.width, out.height, &out.radiance).unwrap();
    set.exr(
        &png.with_extension("exr"),
        out.width,
        out.height,
        &out.radiance,
        &out.layers,
    )
    .unwrap();
    set.commit().unwrap();
    (std::fs::read(png).unwrap(), std::fs::read(exr).unwrap())
}

/// Renders the `n` bands (band 1 on one thread, the others on two) and
/// returns the part paths, or the first error.
fn parts(scene: &Scene, o: &RenderOptions, n: u32, dir: &Path) -> penumbra::Result<Vec<PathBuf>> {
    (1..=n)
        .map(|i| {
            let path = dir.join(format!("{i}.part"));
            let threads = Some(if i == 1 { 1 } else { 2 });
            with_threads(threads, || {
                render_part(scene, o, i, n, &path, &Progress::hidden())
            })??;
            Ok(path)
        })
        .collect()
}

fn merged(parts: &[PathBuf], dir: &Path) -> penumbra::Result<(Vec<u8>, Vec<u8>)> {
    let (png, exr) = (dir.join("merged.png"), dir.join("merged.exr"));
    merge_parts(parts, &png, Some(&exr))?;
    Ok((std::fs::read(png).unwrap(), std::fs::read(exr).unwrap()))
}

fn check_scene(name: &str, w: u32, h: u32, n: u32, tweak: impl Fn(&mut RenderOptions)) {
    let scene = common::shipped(name);
    let mut accepted = 0;
    for technique in Technique::all() {
        let dir = common::scratch_dir(&format!("tiles-{name}-{}", technique.name()));
        let mut o = options(technique, w, h);
        tweak(&mut o);
        match parts(&scene, &o, n, &dir) {
            Err(e) => {
                // Only the technique the module refuses, with its reason.
                assert_eq!(technique.name(), "adaptive-maps", "{e}");
                assert!(e.to_string().contains("1-ring"), "{e}");
            }
            Ok(paths) => {
                accepted += 1;
                let want = whole(&scene, &o, &dir);
                let got = merged(&paths, &dir).expect("merge");
                assert!(got.0 == want.0, "{name} {}: PNG differs", technique.name());
                assert!(got.1 == want.1, "{name} {}: EXR differs", technique.name());
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    assert!(accepted >= 10, "only {accepted} techniques rendered bands");
}

#[test]
fn bands_assemble_the_single_render_bytes_for_every_technique() {
    check_scene("spheres.toml", 96, 200, 4, |_| {});
}

/// DCS's cost choice is the whole frame's in every band: at 96×256 the
/// spheres' frame is counted, while a band alone (a quarter of the
/// receivers) would be traced, and the two paths' bits differ at ties and
/// in the depth-complexity layers.
#[test]
fn bands_make_the_frames_cost_choice() {
    let scene = common::shipped("spheres.toml");
    let dir = common::scratch_dir("tiles-dcs-plan");
    let o = options("dcs".parse().expect("the dcs technique"), 96, 256);
    let paths = parts(&scene, &o, 4, &dir).expect("bands");
    let want = whole(&scene, &o, &dir);
    let got = merged(&paths, &dir).expect("merge");
    assert!(got.0 == want.0, "PNG differs");
    assert!(got.1 == want.1, "EXR differs");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bands_with_textures_opacity_and_small_chunks() {
    // Penumbra casting with chunks that straddle band boundaries (48 does
    // not divide 64): its chunk-shared hierarchy must still see whole
    // chunks.
    check_scene("fence.toml", 80, 256, 3, |o| {
        o.options.penumbra_casting.pc_chunk = 48;
    });
}

#[test]
fn band_rows_cover_the_image_in_whole_tiles() {
    for h in [1u32, 63, 64, 65, 200, 1000, 4097] {
        let tile_rows = h.div_ceil(64);
        for n in 1..=tile_rows.min(9) {
            let mut next = 0;
            let mut sizes = Vec::new();
            for i in 1..=n {
                let r = band_rows(h, i, n).unwrap();
                assert_eq!(r.start, next, "h {h} band {i}/{n}");
                assert!(r.end > r.start, "h {h} band {i}/{n} empty");
                assert_eq!(r.start % 64, 0);
                assert!(r.end.is_multiple_of(64) || r.end == h);
                sizes.push(r.end.div_ceil(64) - r.start / 64);
                next = r.end;
            }
            assert_eq!(next, h);
            let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
            assert!(hi - lo <= 1, "h {h} n {n}: unbalanced {sizes:?}");
        }
        let e = band_rows(h, 1, tile_rows + 1).unwrap_err().to_string();
        assert!(e.contains("tile"), "{e}");
    }
}

#[test]
fn merge_names_missing_duplicated_and_mismatched_bands() {
    let scene = common::shipped("quad.toml");
    let dir = common::scratch_dir("tiles-refusals");
    let o = options(Technique::named("reference").unwrap(), 64, 256);
    let paths = parts(&scene, &o, 4, &dir).unwrap();
    assert_eq!(read_part(&paths[2]).unwrap().header.rows, [128, 192]);

    let e = merged(
        &[paths[0].clone(), paths[1].clone(), paths[3].clone()],
        &dir,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("missing band 3/4 (rows 128..192)"), "{e}");
    assert!(
        !dir.join("merged.png").exists(),
        "a refused merge wrote output"
    );

    let mut dup = paths.clone();
    dup.push(paths[1].clone());
    let e = merged(&dup, &dir).unwrap_err().to_string();
    assert!(e.contains("band 2/4 is also in"), "{e}");

    // A band of another render (another seed) is refused with the reason.
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    let o2 = RenderOptions {
        seed: 1,
        ..o.clone()
    };
    let p2 = parts(&scene, &o2, 4, &other).unwrap();
    let e = merged(
        &[
            paths[0].clone(),
            paths[1].clone(),
            p2[2].clone(),
            paths[3].clone(),
        ],
        &dir,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("render options differs") && e.contains("3.part"),
        "{e}"
    );

    // A truncated part (a copy cut short) is refused, naming the file.
    let cut = dir.join("cut.part");
    let bytes = std::fs::read(&paths[2]).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() - 4]).unwrap();
    let e = merged(
        &[paths[0].clone(), paths[1].clone(), cut, paths[3].clone()],
        &dir,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("cut.part") && e.contains("truncated"), "{e}");

    // And the four good ones merge.
    merged(&paths, &dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn cli_tiles_and_merge_tiles() {
    let dir = common::scratch_dir("tiles-cli");
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"))
            .args(args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap()
    };
    let d = |f: &str| dir.join(f).to_str().unwrap().to_string();
    let base = [
        "render",
        "scenes/spheres.toml",
        "--technique",
        "dcs",
        "--samples",
        "4",
    ];
    let size = ["--width", "64", "--height", "128", "--aov", "mask"];
    let whole = run(&[&base[..], &size, &["-o", &d("w.png"), "--exr", &d("w.exr")]].concat());
    assert!(whole.status.success());
    for i in ["1/2", "2/2"] {
        let p = d(&format!("{}.part", &i[..1]));
        let out = run(&[&base[..], &size, &["--tiles", i, "-o", &p]].concat());
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let m = run(&[
        "merge-tiles",
        &d("2.part"),
        &d("1.part"),
        "-o",
        &d("m.png"),
        "--exr",
        &d("m.exr"),
    ]);
    assert!(m.status.success(), "{}", String::from_utf8_lossy(&m.stderr));
    assert_eq!(
        std::fs::read(d("m.png")).unwrap(),
        std::fs::read(d("w.png")).unwrap()
    );
    assert_eq!(
        std::fs::read(d("m.exr")).unwrap(),
        std::fs::read(d("w.exr")).unwrap()
    );
    let bad = run(&[&base[..], &size, &["--tiles", "3/2", "-o", &d("x.part")]].concat());
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--tiles"));
    let _ = std::fs::remove_dir_all(&dir);
}
