//! FLIP (through nv-flip) on images made here, `diff --flip` end to end,
//! and the interior mask on a rendered scene.

use crate::common;

use glam::Vec3;
use penumbra::internal::output::{read_image, srgb8, write_exr, write_png};
use penumbra::internal::render::{render, Aov, RenderOptions, Technique};
use penumbra::internal::report::{
    colour_bar_rect, diff_images, flip_radiance, heatmap_canvas, interior_mask, DiffOptions,
    COLOUR_BAR_BAND,
};
use std::path::Path;
use std::process::Command;

const W: u32 = 64;
const H: u32 = 48;
const N: usize = (W * H) as usize;

/// A smooth image with some structure: a diagonal ramp, a bright disc.
fn image() -> Vec<Vec3> {
    (0..N)
        .map(|i| {
            let (x, y) = ((i % W as usize) as f32, (i / W as usize) as f32);
            let ramp = 0.1 + 0.6 * (x + y) / (W + H) as f32;
            let disc = if (x - 40.0).hypot(y - 20.0) < 9.0 {
                0.3
            } else {
                0.0
            };
            Vec3::new(ramp + disc, 0.5 * ramp, 0.8 - 0.5 * ramp)
        })
        .collect()
}

/// `image()` with `amount` times one fixed pattern of noise in [-1, 1].
fn noisy(amount: f32) -> Vec<Vec3> {
    let mut rng = common::Rng(42);
    image()
        .into_iter()
        .map(|c| {
            let mut n = || (2.0 * rng.f64() - 1.0) as f32;
            c + amount * Vec3::new(n(), n(), n())
        })
        .collect()
}

#[test]
fn flip_of_an_image_against_itself_is_zero() {
    let map = flip_radiance(&image(), &image(), W, H).unwrap();
    assert_eq!(map.values.len(), N);
    let m = map.metrics_all();
    assert_eq!(m.count, N as u64);
    assert_eq!((m.mean, m.p50, m.p99, m.max), (0.0, 0.0, 0.0, 0.0));
}

#[test]
fn flip_rises_with_noise_and_gives_the_same_bits_twice() {
    let clean = image();
    let mut last = 0.0;
    for amount in [0.01, 0.03, 0.1, 0.3] {
        let map = flip_radiance(&clean, &noisy(amount), W, H).unwrap();
        let m = map.metrics_all();
        assert!(
            m.mean > last,
            "noise {amount}: mean {} after {last}",
            m.mean
        );
        assert!(m.p50 <= m.p90 && m.p90 <= m.p99 && m.p99 <= m.max, "{m:?}");
        assert!(m.max <= 1.0);
        last = m.mean;
        // Deterministic: the same map, bit for bit.
        let again = flip_radiance(&clean, &noisy(amount), W, H).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&map.values), bits(&again.values), "noise {amount}");
    }
    assert!(last > 0.05, "strong noise is plainly visible: {last}");
}

#[test]
fn a_png_reads_back_to_the_codes_flip_was_given() {
    // diff takes a PNG's decoded colours and re-encodes them: FLIP of a
    // PNG against the EXR it was written from is then exactly FLIP of
    // the tone-mapped EXR, i.e. zero.
    let dir = common::ScratchDir::new("flip-png-codes");
    let (png, exr) = (dir.0.join("a.png"), dir.0.join("a.exr"));
    let img = noisy(0.2);
    write_png(&png, W, H, &img).unwrap();
    write_exr(&exr, W, H, &img, &[]).unwrap();
    let back = read_image(&png).unwrap();
    let colours: Vec<Vec3> = (0..N)
        .map(|i| {
            let c = |n: &str| back.channel(n).unwrap()[i];
            Vec3::new(c("R"), c("G"), c("B"))
        })
        .collect();
    assert_eq!(srgb8(&colours), srgb8(&img));
    let report = diff_images(
        &png,
        &exr,
        &DiffOptions {
            flip: true,
            ..DiffOptions::default()
        },
    )
    .unwrap();
    let f = report.flip.as_ref().expect("FLIP asked for");
    assert_eq!((f.metrics.mean, f.metrics.max), (0.0, 0.0));
    assert!(report.to_text().contains("FLIP"));
}

fn penumbra(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .output()
        .expect("run penumbra");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn diff_flip_threshold_sets_the_exit_code_and_the_map_is_written() {
    let dir = common::ScratchDir::new("flip-cli");
    let (reference, test) = (dir.0.join("ref.exr"), dir.0.join("test.png"));
    write_exr(&reference, W, H, &image(), &[]).unwrap();
    write_png(&test, W, H, &noisy(0.05)).unwrap();
    let mean = diff_images(
        &test,
        &reference,
        &DiffOptions {
            flip: true,
            ..DiffOptions::default()
        },
    )
    .unwrap()
    .flip
    .unwrap()
    .metrics
    .mean;
    assert!(mean > 0.0);

    // Above the mean: passes; below it: exit 1, saying why.
    let above = format!("{}", mean * 1.5);
    let below = format!("{}", mean * 0.5);
    let (code, out, err) = penumbra(&["diff", s(&test), s(&reference), "--flip-threshold", &above]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(out.contains("FLIP (sRGB 8-bit, 67 ppd)"), "{out}");
    assert!(out.contains("PASS"), "{out}");
    let (code, out, err) = penumbra(&["diff", s(&test), s(&reference), "--flip-threshold", &below]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(
        out.contains("FAIL: FLIP mean") && out.contains("--flip-threshold"),
        "{out}"
    );
    // The JSON report carries the figures.
    let (code, out, _) = penumbra(&["diff", s(&test), s(&reference), "--flip", "--json"]);
    assert_eq!(code, Some(0));
    let json: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(json["flip"]["metrics"]["count"], N as u64);
    assert!(json["flip"]["metrics"]["p99"].as_f64().unwrap() > 0.0);
    // A bad threshold is an error naming the option.
    let (code, _, err) = penumbra(&["diff", s(&test), s(&reference), "--flip-threshold=-1"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--flip-threshold"), "{err}");

    // The error map: a PNG of the images' size and its colour bar's band
    // below, magma colours (not grey), the bar from FLIP 0 to 1 rising in
    // brightness.
    let map = dir.0.join("map.png");
    let (code, out, err) = penumbra(&["diff", s(&test), s(&reference), "--flip-map", s(&map)]);
    assert_eq!(code, Some(0), "{out}{err}");
    let img = image::open(&map).expect("the map is a PNG").into_rgb8();
    assert_eq!(img.dimensions(), heatmap_canvas(W, H));
    assert_eq!(img.height(), H + COLOUR_BAR_BAND);
    assert!(img.pixels().any(|p| p[0] != p[2]), "coloured");
    let (x0, y0, x1, y1) = colour_bar_rect(W, H);
    let luma = |x: u32| {
        let c = img.get_pixel(x, (y0 + y1) / 2).0;
        0.2126 * f64::from(c[0]) + 0.7152 * f64::from(c[1]) + 0.0722 * f64::from(c[2])
    };
    assert!(luma(x0) < 20.0 && luma(x1 - 1) > 200.0, "black to light");
    for x in x0 + 1..x1 {
        assert!(luma(x) >= luma(x - 1) - 0.75, "monotone at column {x}");
    }
    for x in x0 + 8..x1 {
        assert!(luma(x) > luma(x - 8), "rising at column {x}");
    }
    // Never over an input, never another format; nothing written then.
    let before = std::fs::read(&test).unwrap();
    let (code, _, err) = penumbra(&["diff", s(&test), s(&reference), "--flip-map", s(&test)]);
    assert_eq!(code, Some(2));
    assert!(err.contains("same file as the input"), "{err}");
    assert_eq!(std::fs::read(&test).unwrap(), before);
    let exr_map = dir.0.join("map.exr");
    let (code, _, err) = penumbra(&["diff", s(&test), s(&reference), "--flip-map", s(&exr_map)]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--flip-map"), "{err}");
    assert!(!exr_map.exists());
}

#[test]
fn the_interior_excludes_silhouettes_on_a_rendered_scene() {
    let scene = common::shipped("spheres.toml");
    let out = render(
        &scene,
        &RenderOptions {
            width: Some(W),
            height: Some(H),
            aovs: vec![Aov::Depth, Aov::Normal, Aov::Mask],
            technique: Technique::named("none").unwrap(),
            ..RenderOptions::default()
        },
    )
    .unwrap();
    let channel = |layer: &str, c: &str| -> Vec<f32> {
        let l = out.layers.iter().find(|l| l.name == layer).unwrap();
        l.channels.iter().find(|(n, _)| n == c).unwrap().1.clone()
    };
    let depth = channel("depth", "Z");
    let (nx, ny, nz) = (
        channel("normal", "X"),
        channel("normal", "Y"),
        channel("normal", "Z"),
    );
    let normal: Vec<[f32; 3]> = (0..N).map(|i| [nx[i], ny[i], nz[i]]).collect();
    let fg: Vec<bool> = channel("mask", "Y").iter().map(|&m| m > 0.5).collect();
    let interior = interior_mask(W as usize, H as usize, &depth, &normal, &fg).unwrap();
    let w = W as usize;
    let at = |x: usize, y: usize| y * w + x;

    let inside = interior.iter().filter(|&&b| b).count();
    assert!(inside > N / 10, "the ground's open parts: {inside} of {N}");
    let mut silhouettes = 0;
    let mut depth_edges = 0;
    for y in 0..H as usize {
        for x in 0..w {
            let i = at(x, y);
            // Nothing within 2 px of the background is interior.
            let near_bg = (y.saturating_sub(2)..=(y + 2).min(H as usize - 1))
                .any(|yy| (x.saturating_sub(2)..=(x + 2).min(w - 1)).any(|xx| !fg[at(xx, yy)]));
            if near_bg {
                assert!(!interior[i], "({x}, {y}) is near the background");
            }
            if fg[i] && near_bg {
                silhouettes += 1;
            }
            // Neither side of a sphere's outline over the ground is.
            if x + 1 < w && fg[i] && fg[i + 1] {
                let (a, b) = (depth[i], depth[i + 1]);
                if (a - b).abs() > 0.1 * a.min(b) {
                    depth_edges += 1;
                    assert!(!interior[i] && !interior[i + 1], "({x}, {y})");
                }
            }
        }
    }
    assert!(
        silhouettes > 0 && depth_edges > 0,
        "{silhouettes} {depth_edges}"
    );
}
