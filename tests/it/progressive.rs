//! Progressive rendering to a target error (`render --target-error`):
//! the error estimate is calibrated against the true error, the stop
//! rules hold, and the result is the same bits for any thread count.

use crate::common;
use penumbra::internal::output::read_image;
use penumbra::{render, Aov, RenderOptions, StopReason, StopRule, Technique};
use std::process::Command;

/// The image side of the calibration renders: small enough for CI, with
/// thousands of shading points in penumbrae.
const SIDE: u32 = 96;

fn options(technique: &str, samples: u32, rule: StopRule) -> RenderOptions {
    RenderOptions {
        width: Some(SIDE),
        height: Some(SIDE),
        technique: technique.parse::<Technique>().expect("a technique"),
        samples,
        progressive: Some(rule),
        ..RenderOptions::default()
    }
}

fn sets(n: u64, samples: u32) -> StopRule {
    StopRule {
        max_samples: Some(n * u64::from(samples)),
        ..StopRule::default()
    }
}

/// Mean squared difference of two images over R, G, B of the pixels
/// where `surface` holds.
fn mse(a: &[glam::Vec3], b: &[glam::Vec3], surface: &[bool]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for ((x, y), &s) in a.iter().zip(b).zip(surface) {
        if s {
            let d = (*x - *y).as_dvec3();
            sum += d.length_squared();
            n += 3;
        }
    }
    sum / n as f64
}

/// The estimated RMSE of a progressive render (batch means over its
/// sets) is within ±20 % of its true RMSE against a 4096-sample
/// reference, for every exact technique on spheres, bunny and tinted.
/// The reference is itself progressive (8 sets of 512), so its own
/// estimated error is subtracted from the measured squared error: the
/// two are independent, so their mean squared errors add.
#[test]
fn error_estimate_is_calibrated_against_a_4096_sample_reference() {
    for scene_name in ["spheres", "bunny", "tinted"] {
        let scene = common::shipped(&format!("{scene_name}.toml"));
        let mut reference_options = options("reference", 512, sets(8, 512));
        reference_options.seed = 0x5eed;
        reference_options.aovs = vec![Aov::Mask];
        let reference = render(&scene, &reference_options).expect("the reference renders");
        let surface: Vec<bool> = reference.layer("mask").expect("mask").channels[0]
            .1
            .iter()
            .map(|m| *m > 0.5)
            .collect();
        let reference_error = reference
            .explain
            .convergence
            .as_ref()
            .unwrap()
            .error
            .unwrap();
        for technique in ["dcs", "penumbra-casting", "reference"] {
            let out = render(&scene, &options(technique, 16, sets(8, 16))).expect("renders");
            let c = out.explain.convergence.as_ref().expect("progressive");
            assert_eq!((c.sets, c.stop), (8, StopReason::MaxSamples));
            let estimated = c.error.expect("an estimate after 8 sets");
            let measured = mse(&out.radiance, &reference.radiance, &surface);
            let truth = (measured - reference_error * reference_error)
                .max(0.0)
                .sqrt();
            let ratio = estimated / truth;
            eprintln!(
                "{scene_name} {technique}: estimated {estimated:.4e}, true {truth:.4e} \
                 (reference's own {reference_error:.2e}), ratio {ratio:.3}"
            );
            assert!(
                (0.8..=1.2).contains(&ratio),
                "{scene_name} {technique}: estimated RMSE {estimated:.4e} vs true {truth:.4e} \
                 (ratio {ratio:.3}, allowed 0.8..=1.2)"
            );
        }
    }
}

/// One set is the ordinary render, bit for bit: set 0 uses the seed.
#[test]
fn one_set_is_the_ordinary_render() {
    let scene = common::shipped("spheres.toml");
    let plain = RenderOptions {
        progressive: None,
        aovs: vec![Aov::Vcoef],
        ..options("dcs", 8, StopRule::default())
    };
    let one = RenderOptions {
        aovs: vec![Aov::Vcoef],
        ..options("dcs", 8, sets(1, 8))
    };
    let a = render(&scene, &plain).unwrap();
    let b = render(&scene, &one).unwrap();
    assert_eq!(common::render_bits(&a), common::render_bits(&b));
    assert_eq!(b.explain.convergence.unwrap().error, None);
}

/// A target error stops at the first set whose estimate meets it, and
/// the image, the error layer and the set count are the same bits on one
/// thread and on three.
#[test]
fn target_error_stops_at_the_first_set_that_meets_it_on_any_thread_count() {
    let scene = common::shipped("bunny.toml");
    let target = 4e-3;
    let rule = StopRule {
        target_error: Some(target),
        max_samples: Some(64 * 8),
        ..StopRule::default()
    };
    let mut runs = Vec::new();
    for threads in [1, 3] {
        let o = RenderOptions {
            threads: Some(threads),
            aovs: vec![Aov::Mask, Aov::Vcoef, Aov::Error],
            ..options("dcs", 8, rule)
        };
        runs.push(render(&scene, &o).unwrap());
    }
    assert_eq!(common::render_bits(&runs[0]), common::render_bits(&runs[1]));
    let c = runs[0].explain.convergence.clone().unwrap();
    let d = runs[1].explain.convergence.clone().unwrap();
    let untimed = |c: &penumbra::Convergence| {
        let curve: Vec<_> = c.curve.iter().map(|p| (p.samples, p.error)).collect();
        (c.sets, c.error, c.vcoef_error, c.stop, curve)
    };
    assert_eq!(untimed(&c), untimed(&d));
    assert_eq!(c.stop, StopReason::TargetError, "{}", c.summary());
    assert!(c.error.unwrap() <= target);
    let before = c.curve[c.curve.len() - 2].error;
    assert!(
        before.is_none_or(|e| e > target),
        "stopped late: {:?}",
        c.curve
    );
    // The error layer's mean square over the shading points is the
    // image estimate's square.
    let y = &runs[0].layer("error").expect("the error layer").channels[0].1;
    let mask = &runs[0].layer("mask").expect("the mask").channels[0].1;
    let (sum, n) = (y.iter().zip(mask))
        .filter(|(_, m)| **m > 0.5)
        .fold((0.0, 0.0), |(s, n), (e, _)| {
            (s + f64::from(*e).powi(2), n + 1.0)
        });
    let from_layer = (sum / n).sqrt();
    assert!(
        (from_layer / c.error.unwrap() - 1.0).abs() < 1e-3,
        "{from_layer} vs {}",
        c.error.unwrap()
    );
}

/// Refusals name the option: a technique that does not sample the
/// light, the error layer without sets, a bad target.
#[test]
fn refusals_name_the_option() {
    let scene = common::shipped("quad.toml");
    let cases = [
        (
            options("shadow-map", 16, sets(4, 16)),
            "does not sample the light",
        ),
        (
            RenderOptions {
                aovs: vec![Aov::Error],
                progressive: None,
                ..options("dcs", 16, sets(4, 16))
            },
            "--aov",
        ),
        (
            options(
                "dcs",
                16,
                StopRule {
                    target_error: Some(-1.0),
                    ..StopRule::default()
                },
            ),
            "--target-error",
        ),
    ];
    for (o, want) in cases {
        let e = render(&scene, &o).unwrap_err().to_string();
        assert!(e.contains(want), "{e}");
    }
}

/// The command line: the EXR header records how the render stopped, the
/// error layer is written, the preview is a PNG twice as wide as the
/// image, and `--max-time` stops by the clock.
#[test]
fn command_line_records_the_stop_in_the_exr_and_writes_the_preview() {
    let dir = common::scratch_dir("progressive-cli");
    let exr = dir.join("out.exr");
    let preview = dir.join("preview.png");
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args([
            "render",
            "scenes/spheres.toml",
            "--width",
            "64",
            "--height",
            "48",
        ])
        .args([
            "--samples",
            "8",
            "--target-error",
            "0.01",
            "--aov",
            "error,vcoef",
        ])
        .arg("-o")
        .arg(&exr)
        .arg("--preview")
        .arg(&preview)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("stopped by target-error"), "{stderr}");
    let bytes = std::fs::read(&exr).unwrap();
    let header = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    for key in [
        "penumbra.sets",
        "penumbra.samples",
        "penumbra.estimatedRmse",
        "penumbra.stopReason",
        "target-error",
    ] {
        assert!(header.contains(key), "{key} missing from the EXR header");
    }
    let image = read_image(&exr).unwrap();
    assert!(image.channel("error.Y").is_some() && image.channel("error.V").is_some());
    let p = read_image(&preview).unwrap();
    assert_eq!((p.width, p.height), (128, 48));

    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args([
            "render",
            "scenes/spheres.toml",
            "--width",
            "64",
            "--height",
            "48",
        ])
        .args(["--samples", "4", "--max-time", "300ms", "--explain"])
        .arg("-o")
        .arg(dir.join("t.png"))
        .arg("--convergence")
        .arg(dir.join("curve.csv"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("stopped by max-time"), "{stderr}");
    let csv = std::fs::read_to_string(dir.join("curve.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "set,samples,seconds,estimated_rmse");
    assert!(rows.len() >= 2, "{csv}");
    assert!(rows[1].starts_with("1,4,"), "{csv}");
}

/// `compare --target-error E` adds one progressive run per technique that
/// renders progressively (none for the others), each stopped at E by its
/// own estimate, whose measured radiance RMSE against compare's reference
/// agrees with that estimate (the reference's own noise included, so a
/// wide band: the estimate's calibration is the test above).
#[test]
fn compare_target_error_runs_each_progressive_technique_to_the_target() {
    let dir = common::scratch_dir("progressive-compare");
    let scene = common::shipped("spheres.toml");
    let target = 5e-3;
    let options = penumbra::CompareOptions {
        techniques: ["dcs", "reference", "shadow-map"]
            .map(|n| n.parse::<Technique>().expect("registered"))
            .to_vec(),
        samples: vec![4],
        reference_samples: 1024,
        width: Some(64),
        height: Some(48),
        images: false,
        repeat: 1,
        cache_dir: dir.join("cache"),
        target_error: Some(target),
        ..penumbra::CompareOptions::default()
    };
    let records = penumbra::compare(&[scene], &options, None).expect("compare runs");
    let progressive: Vec<_> = (records.iter())
        .filter(|r| {
            r.setting.starts_with("to RMSE") && r.quantity == "radiance" && r.region == "all"
        })
        .collect();
    // The technique column holds the curve: the name and the target.
    let names: Vec<&str> = progressive.iter().map(|r| r.technique.as_str()).collect();
    assert_eq!(names, ["dcs to RMSE 5.0e-3", "reference to RMSE 5.0e-3"]);
    for r in progressive {
        let samples = r.samples.expect("the samples it took");
        assert_eq!(samples % 16, 0, "{}", r.setting);
        assert!((32..=1024).contains(&samples), "{}", r.setting);
        let measured = r.rmse.expect("radiance RMSE");
        assert!(
            measured < 1.6 * target,
            "{} {}: measured RMSE {measured:.3e} against a target of {target:.1e}",
            r.technique,
            r.setting
        );
    }
}
