//! `diff_images` on small EXR and PNG files written here: exact metrics,
//! channel pairing, masks, tolerances and errors that name the culprit.

use crate::common;

use glam::Vec3;
use penumbra::internal::output::{srgb_decode, srgb_encode_u8, write_exr, write_png, Layer};
use penumbra::internal::report::{diff_images, DiffOptions, DiffReport, ErrorMetrics};
use penumbra::Error;
use std::path::{Path, PathBuf};

const W: u32 = 8;
const H: u32 = 4;
const N: usize = (W * H) as usize;

/// A radiance image with dyadic values (exact in f32 and under offsets).
fn radiance(offset: Vec3) -> Vec<Vec3> {
    (0..N)
        .map(|i| Vec3::new(i as f32 / 64.0, 0.5, 1.0 - i as f32 / 128.0) + offset)
        .collect()
}

fn layer(name: &str, channel: &str, values: Vec<f32>) -> Layer {
    Layer {
        name: name.into(),
        channels: vec![(channel.into(), values)],
    }
}

fn exr(path: &Path, radiance: &[Vec3], layers: &[Layer]) -> PathBuf {
    write_exr(path, W, H, radiance, layers).expect("write test EXR");
    path.to_path_buf()
}

/// An EXR with bare channels (no layer prefix and no `R, G, B`), as other
/// tools write them.
fn bare_exr(path: &Path, channels: &[(&str, Vec<f32>)]) -> PathBuf {
    use exr::prelude::*;
    let list: Vec<AnyChannel<FlatSamples>> = channels
        .iter()
        .map(|(n, v)| AnyChannel::new(*n, FlatSamples::F32(v.clone())))
        .collect();
    let layer = exr::image::Layer::new(
        (W as usize, H as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .expect("write bare EXR");
    path.to_path_buf()
}

fn channel<'a>(report: &'a DiffReport, name: &str) -> &'a ErrorMetrics {
    &report
        .channels
        .iter()
        .find(|c| c.channel_a == name)
        .unwrap_or_else(|| panic!("no channel {name} in {report:?}"))
        .metrics
}

/// The option and message of a parameter error.
fn param_error(result: penumbra::Result<DiffReport>) -> (String, String) {
    match result.map(|_| ()).unwrap_err() {
        Error::Parameter { name, message } => (name, message),
        other => panic!("expected a parameter error, got {other}"),
    }
}

#[test]
fn identical_images_have_zero_error() {
    let dir = common::scratch_dir("diff-identical");
    let layers = [layer("vcoef", "0", vec![0.25; N])];
    let a = exr(&dir.join("a.exr"), &radiance(Vec3::ZERO), &layers);
    let b = exr(&dir.join("b.exr"), &radiance(Vec3::ZERO), &layers);
    let options = DiffOptions {
        max_abs: Some(0.0),
        rmse: Some(0.0),
        ..DiffOptions::default()
    };
    let report = diff_images(&a, &b, &options).unwrap();
    assert_eq!((report.width, report.height), (W, H));
    // Every channel the two share, in A's order.
    let names: Vec<&str> = report
        .channels
        .iter()
        .map(|c| c.channel_a.as_str())
        .collect();
    let mut expected = vec!["B", "G", "R", "vcoef.0"];
    expected.sort();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(sorted, expected);
    for c in &report.channels {
        assert_eq!(c.channel_a, c.channel_b);
        assert_eq!(
            c.metrics,
            ErrorMetrics {
                count: N as u64,
                ..ErrorMetrics::default()
            }
        );
    }
    assert_eq!(report.overall.count, 4 * N as u64);
    assert_eq!(report.overall.max_abs, 0.0);
    assert!(report.passed(), "{:?}", report.failures);
    let text = report.to_text();
    assert!(text.ends_with("PASS\n"), "{text}");
    assert!(text.contains("vcoef.0"), "{text}");
}

#[test]
fn known_offset_in_exr_is_measured_exactly() {
    let dir = common::scratch_dir("diff-offset");
    let a = exr(
        &dir.join("a.exr"),
        &radiance(Vec3::new(0.25, 0.0, 0.0)),
        &[],
    );
    let b = exr(&dir.join("b.exr"), &radiance(Vec3::ZERO), &[]);
    let report = diff_images(&a, &b, &DiffOptions::default()).unwrap();
    let r = channel(&report, "R");
    assert_eq!(
        *r,
        ErrorMetrics {
            count: N as u64,
            rmse: 0.25,
            mean_abs: 0.25,
            max_abs: 0.25,
            frac_over: 1.0,
            non_finite: 0,
        }
    );
    assert_eq!(channel(&report, "G").max_abs, 0.0);
    assert_eq!(channel(&report, "B").max_abs, 0.0);
    // Overall: one channel in three is off by 0.25.
    let o = report.overall;
    assert_eq!(o.count, 3 * N as u64);
    assert_eq!(o.max_abs, 0.25);
    assert_eq!(o.mean_abs, 0.25 / 3.0);
    assert!((o.rmse - (0.0625f64 / 3.0).sqrt()).abs() < 1e-15);
    assert_eq!(o.frac_over, 1.0 / 3.0);
    // No tolerance given: nothing can fail.
    assert!(report.passed());
}

#[test]
fn known_offset_in_png_within_quantisation() {
    // PNG stores 8-bit sRGB codes, so each side is the code nearest its
    // value, decoded. The expected error is computed through the same
    // encode/decode pair; reading back yields f32, so allow f32 rounding.
    // Independently, each side moves by at most half a code step, which
    // near linear 0.5–0.6 is below 0.004, so the error is 0.1 ± 0.008.
    let dir = common::scratch_dir("diff-png");
    let (va, vb) = (0.6f32, 0.5f32);
    let a = dir.join("a.png");
    let b = dir.join("b.png");
    write_png(&a, W, H, &vec![Vec3::splat(va); N]).unwrap();
    write_png(&b, W, H, &vec![Vec3::splat(vb); N]).unwrap();
    let report = diff_images(&a, &b, &DiffOptions::default()).unwrap();
    let names: Vec<&str> = report
        .channels
        .iter()
        .map(|c| c.channel_a.as_str())
        .collect();
    assert_eq!(names, ["R", "G", "B"]);
    let decoded = |v: f32| srgb_decode(f64::from(srgb_encode_u8(v)) / 255.0) as f32;
    let expected = f64::from(decoded(va)) - f64::from(decoded(vb));
    for c in &report.channels {
        let m = c.metrics;
        assert!((m.max_abs - expected).abs() < 1e-6, "{m:?} vs {expected}");
        assert!((m.rmse - expected).abs() < 1e-6);
        assert!((m.mean_abs - expected).abs() < 1e-6);
        assert!((m.max_abs - 0.1).abs() < 0.008);
        assert_eq!(m.frac_over, 1.0);
    }
}

#[test]
fn exceeded_tolerances_are_failures_in_words() {
    let dir = common::scratch_dir("diff-tolerance");
    let a = exr(
        &dir.join("a.exr"),
        &radiance(Vec3::new(0.25, 0.0, 0.0)),
        &[],
    );
    let b = exr(&dir.join("b.exr"), &radiance(Vec3::ZERO), &[]);
    let strict = DiffOptions {
        max_abs: Some(0.1),
        rmse: Some(0.01),
        ..DiffOptions::default()
    };
    let report = diff_images(&a, &b, &strict).unwrap();
    assert!(!report.passed());
    assert_eq!(
        report.failures,
        [
            "max abs error 0.25 > 0.1 (channel R)".to_string(),
            format!("rmse {:.4} > 0.01 (all channels)", (0.0625f64 / 3.0).sqrt()),
        ]
    );
    let text = report.to_text();
    assert!(
        text.contains("FAIL: max abs error 0.25 > 0.1 (channel R)"),
        "{text}"
    );
    assert!(!text.contains("PASS"));
    // Tolerances that hold, including one met with equality.
    let loose = DiffOptions {
        max_abs: Some(0.25),
        rmse: Some(0.2),
        ..DiffOptions::default()
    };
    assert!(diff_images(&a, &b, &loose).unwrap().passed());
    // Only G compared: R's error does not count.
    let only_g = DiffOptions {
        channels_a: vec!["G".into()],
        ..strict
    };
    let report = diff_images(&a, &b, &only_g).unwrap();
    assert!(report.passed(), "{:?}", report.failures);
    assert_eq!(report.channels.len(), 1);
}

#[test]
fn non_finite_values_fail_every_tolerance() {
    let dir = common::scratch_dir("diff-nan");
    let mut bad = radiance(Vec3::ZERO);
    bad[3].y = f32::NAN;
    bad[5].z = f32::INFINITY;
    let a = exr(&dir.join("a.exr"), &bad, &[]);
    let b = exr(&dir.join("b.exr"), &radiance(Vec3::ZERO), &[]);
    let options = DiffOptions {
        max_abs: Some(1e30),
        rmse: Some(1e30),
        ..DiffOptions::default()
    };
    let report = diff_images(&a, &b, &options).unwrap();
    assert_eq!(report.overall.non_finite, 2);
    assert_eq!(channel(&report, "G").non_finite, 1);
    assert_eq!(channel(&report, "R").non_finite, 0);
    assert_eq!(report.overall.max_abs, f64::INFINITY);
    assert_eq!(report.failures.len(), 3, "{:?}", report.failures);
    assert!(report.to_text().contains("inf"));
}

#[test]
fn channels_pair_by_position_across_names() {
    let dir = common::scratch_dir("diff-pairing");
    let coef: Vec<f32> = (0..N).map(|i| i as f32 / 32.0).collect();
    let light: Vec<f32> = coef.iter().map(|v| v + 0.5).collect();
    let a = exr(
        &dir.join("a.exr"),
        &radiance(Vec3::ZERO),
        &[layer("vcoef", "0", coef.clone()), layer("vcoef", "1", coef)],
    );
    let b = bare_exr(
        &dir.join("b.exr"),
        &[("light0", light.clone()), ("light1", light)],
    );
    // Nothing in common: an error that lists both files' channels.
    let (name, message) = param_error(diff_images(&a, &b, &DiffOptions::default()));
    assert_eq!(name, "--channels-a");
    assert!(
        message.contains("a.exr") && message.contains("b.exr"),
        "{message}"
    );
    assert!(
        message.contains("light0") && message.contains("vcoef.0"),
        "{message}"
    );

    let options = DiffOptions {
        channels_a: vec!["vcoef.0".into(), "vcoef.1".into()],
        channels_b: vec!["light0".into(), "light1".into()],
        ..DiffOptions::default()
    };
    let report = diff_images(&a, &b, &options).unwrap();
    assert_eq!(report.channels.len(), 2);
    assert_eq!(report.channels[0].channel_a, "vcoef.0");
    assert_eq!(report.channels[0].channel_b, "light0");
    assert_eq!(report.channels[1].channel_b, "light1");
    for c in &report.channels {
        assert_eq!(c.metrics.max_abs, 0.5);
        assert_eq!(c.metrics.rmse, 0.5);
        assert_eq!(c.metrics.count, N as u64);
    }
    assert!(report.to_text().contains("vcoef.0 / light0"));

    // Lists of different lengths cannot pair up.
    let uneven = DiffOptions {
        channels_b: vec!["light0".into()],
        ..options
    };
    let (name, _) = param_error(diff_images(&a, &b, &uneven));
    assert_eq!(name, "--channels-b");
}

#[test]
fn mask_excludes_pixels() {
    let dir = common::scratch_dir("diff-mask");
    // A differs from B only in the right half (x >= 4); the mask covers
    // the left half.
    let mut shifted = radiance(Vec3::ZERO);
    for (i, c) in shifted.iter_mut().enumerate() {
        if i as u32 % W >= W / 2 {
            *c += Vec3::splat(0.5);
        }
    }
    let left: Vec<f32> = (0..N)
        .map(|i| if (i as u32 % W) < W / 2 { 1.0 } else { 0.0 })
        .collect();
    let right: Vec<f32> = left.iter().map(|v| 1.0 - v).collect();
    let a = exr(&dir.join("a.exr"), &shifted, &[]);
    let b = exr(&dir.join("b.exr"), &radiance(Vec3::ZERO), &[]);
    // The mask file also has an `R` that says the opposite: `mask.Y` wins.
    let radiance_right: Vec<Vec3> = right.iter().map(|&v| Vec3::splat(v)).collect();
    let mask = exr(
        &dir.join("mask.exr"),
        &radiance_right,
        &[layer("mask", "Y", left)],
    );
    let options = DiffOptions {
        mask: Some(mask.clone()),
        max_abs: Some(0.0),
        ..DiffOptions::default()
    };
    let report = diff_images(&a, &b, &options).unwrap();
    assert_eq!(report.overall.count, 3 * N as u64 / 2);
    assert_eq!(report.overall.max_abs, 0.0);
    assert!(report.passed());
    // The mask's `R` channel picks the other half: every value is off.
    let options = DiffOptions {
        mask_channel: Some("R".into()),
        ..options
    };
    let report = diff_images(&a, &b, &options).unwrap();
    assert_eq!(report.overall.count, 3 * N as u64 / 2);
    assert_eq!(report.overall.max_abs, 0.5);
    assert_eq!(report.overall.frac_over, 1.0);
    assert!(!report.passed());
    // A PNG mask: white where compared, by its `R` channel.
    let png_mask = dir.join("mask.png");
    let white_left: Vec<Vec3> = (0..N)
        .map(|i| Vec3::splat(if (i as u32 % W) < W / 2 { 1.0 } else { 0.0 }))
        .collect();
    write_png(&png_mask, W, H, &white_left).unwrap();
    let options = DiffOptions {
        mask: Some(png_mask),
        ..DiffOptions::default()
    };
    let report = diff_images(&a, &b, &options).unwrap();
    assert_eq!(report.overall.count, 3 * N as u64 / 2);
    assert_eq!(report.overall.max_abs, 0.0);
    // A mask channel that is not there.
    let options = DiffOptions {
        mask: Some(mask),
        mask_channel: Some("alpha".into()),
        ..DiffOptions::default()
    };
    let (name, message) = param_error(diff_images(&a, &b, &options));
    assert_eq!(name, "--mask-channel");
    assert!(
        message.contains("mask.exr") && message.contains("mask.Y"),
        "{message}"
    );
}

#[test]
fn errors_name_the_file_or_parameter() {
    let dir = common::scratch_dir("diff-errors");
    let a = exr(&dir.join("a.exr"), &radiance(Vec3::ZERO), &[]);
    let b = exr(&dir.join("b.exr"), &radiance(Vec3::ZERO), &[]);

    // Size mismatch: both files and both sizes.
    let small = dir.join("small.png");
    write_png(&small, 3, 2, &[Vec3::ZERO; 6]).unwrap();
    let e = diff_images(&a, &small, &DiffOptions::default()).unwrap_err();
    let text = e.to_string();
    for part in ["a.exr", "small.png", "8×4", "3×2"] {
        assert!(text.contains(part), "{part} missing from: {text}");
    }

    // A channel A lacks: the option, the file and what it has.
    let options = DiffOptions {
        channels_a: vec!["depth.Z".into()],
        channels_b: vec!["R".into()],
        ..DiffOptions::default()
    };
    let (name, message) = param_error(diff_images(&a, &b, &options));
    assert_eq!(name, "--channels-a");
    assert!(
        message.contains("a.exr") && message.contains("depth.Z"),
        "{message}"
    );
    assert!(message.contains("R") && message.contains("G"), "{message}");
    // A channel B lacks.
    let options = DiffOptions {
        channels_a: vec!["R".into()],
        channels_b: vec!["light0".into()],
        ..DiffOptions::default()
    };
    let (name, message) = param_error(diff_images(&a, &b, &options));
    assert_eq!(name, "--channels-b");
    assert!(
        message.contains("b.exr") && message.contains("light0"),
        "{message}"
    );
    // Only --channels-b given: its names are looked up on both sides and
    // the error blames the option the user wrote.
    let options = DiffOptions {
        channels_b: vec!["light0".into()],
        ..DiffOptions::default()
    };
    let (name, message) = param_error(diff_images(&a, &b, &options));
    assert_eq!(name, "--channels-b");
    assert!(message.contains("a.exr"), "{message}");

    // Missing file: an I/O error at that path.
    let missing = dir.join("missing.exr");
    let e = diff_images(&a, &missing, &DiffOptions::default()).unwrap_err();
    assert!(
        matches!(&e, Error::Io { path, .. } if *path == missing),
        "{e}"
    );
    let e = diff_images(&missing, &b, &DiffOptions::default()).unwrap_err();
    assert!(
        matches!(&e, Error::Io { path, .. } if *path == missing),
        "{e}"
    );

    // Corrupt files: a file error at that path.
    let junk = dir.join("junk.exr");
    std::fs::write(&junk, b"not an image at all").unwrap();
    let e = diff_images(&a, &junk, &DiffOptions::default()).unwrap_err();
    assert!(
        matches!(&e, Error::File { path, .. } if *path == junk),
        "{e}"
    );
    let truncated = dir.join("truncated.exr");
    let bytes = std::fs::read(&a).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let e = diff_images(&truncated, &b, &DiffOptions::default()).unwrap_err();
    assert!(e.to_string().contains("truncated.exr"), "{e}");

    // A mask of the wrong size or missing.
    let options = DiffOptions {
        mask: Some(small.clone()),
        ..DiffOptions::default()
    };
    let e = diff_images(&a, &b, &options).unwrap_err();
    assert!(
        e.to_string().contains("small.png") && e.to_string().contains("3×2"),
        "{e}"
    );
    let options = DiffOptions {
        mask: Some(missing.clone()),
        ..DiffOptions::default()
    };
    let e = diff_images(&a, &b, &options).unwrap_err();
    assert!(
        matches!(&e, Error::Io { path, .. } if *path == missing),
        "{e}"
    );

    // A mask channel without a mask.
    let options = DiffOptions {
        mask_channel: Some("Y".into()),
        ..DiffOptions::default()
    };
    let (name, message) = param_error(diff_images(&a, &b, &options));
    assert_eq!(name, "--mask-channel");
    assert!(message.contains("--mask"), "{message}");

    // Tolerances must be numbers at least 0.
    for (max_abs, rmse, option) in [
        (Some(-1.0), None, "--max-abs"),
        (Some(f64::NAN), None, "--max-abs"),
        (None, Some(-0.5), "--rmse"),
    ] {
        let options = DiffOptions {
            max_abs,
            rmse,
            ..DiffOptions::default()
        };
        let (name, _) = param_error(diff_images(&a, &b, &options));
        assert_eq!(name, option);
    }
}
