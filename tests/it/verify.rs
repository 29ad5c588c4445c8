//! `--verify K`, the exactness certificate: exact techniques pass it on a
//! shipped scene, inexact ones (centre silhouettes, a corrupted answer)
//! are caught and fail it, techniques without decisions are refused by
//! name, and `compare --verify` reports it per run.

use crate::common;

use penumbra::internal::error::Result;
use penumbra::internal::render::{verify_render, RenderOptions, Technique};
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::dcs::{DepthComplexitySampling, SilhouetteMode};
use penumbra::internal::shadow::kit::verify::{verify_with, VerifyReport, TIE_DISTANCE};
use penumbra::internal::shadow::technique::{PixelVisibility, SampleDecisions};
use penumbra::internal::shadow::ShadowContext;
use std::process::Command;

fn options(technique: &str, samples: u32, w: u32, h: u32, seed: u64) -> RenderOptions {
    RenderOptions {
        width: Some(w),
        height: Some(h),
        technique: Technique::named(technique).unwrap(),
        samples,
        seed,
        ..RenderOptions::default()
    }
}

fn verified(scene: &Scene, options: &RenderOptions, k: u64) -> VerifyReport {
    let r = verify_render(scene, options, k).expect("verify runs");
    eprintln!("{r}");
    r
}

/// The check saw real shadow: a share of the relations is blocked, not an
/// unlit or a fully lit view.
fn assert_saw_shadow(r: &VerifyReport) {
    assert!(
        r.blocked > r.checked / 20 && r.blocked < r.checked * 19 / 20,
        "{r:?}"
    );
}

/// Exact DCS (the default) and penumbra casting agree with the shadow
/// rays on the bunny, self-shadowing included: no disagreement beyond
/// the tie distance (measured: none at all).
#[test]
fn exact_techniques_pass_on_the_bunny() {
    let scene = common::shipped("bunny.toml");
    for technique in ["dcs", "penumbra-casting"] {
        let r = verified(&scene, &options(technique, 32, 96, 96, 3), 20_000);
        assert_eq!(r.technique, technique);
        assert!(r.declared_exact, "{r:?}");
        assert_eq!(r.requested, 20_000);
        assert_eq!(r.checked, 20_000, "every surface pixel has samples: {r:?}");
        assert_saw_shadow(&r);
        assert_eq!(r.beyond_tie, 0, "{r:?}");
        assert!(r.max_tie_distance <= TIE_DISTANCE, "{r:?}");
        assert!(r.passed() && r.check().is_ok());
    }
}

/// Same seed, same relations, same report; another seed checks other
/// relations.
#[test]
fn relations_are_keyed_by_the_seed() {
    let scene = common::shipped("spheres.toml");
    let a = verified(&scene, &options("dcs", 16, 64, 48, 1), 4_000);
    let b = verified(&scene, &options("dcs", 16, 64, 48, 1), 4_000);
    assert_eq!(a, b);
    let mut centre = options("dcs", 16, 64, 48, 1);
    centre.options.dcs.silhouettes = SilhouetteMode::Centre;
    let c1 = verified(&scene, &centre, 4_000);
    centre.seed = 2;
    let c2 = verified(&scene, &centre, 4_000);
    assert_ne!(c1.blocked, c2.blocked, "{c1:?} {c2:?}");
}

/// Centre silhouettes miss the bunny's self-shadowing edges: the check
/// catches it and fails, naming the technique.
#[test]
fn centre_silhouettes_are_caught_on_the_bunny() {
    let scene = common::shipped("bunny.toml");
    let mut o = options("dcs", 32, 128, 128, 0);
    o.options.dcs.silhouettes = SilhouetteMode::Centre;
    let r = verified(&scene, &o, 20_000);
    assert!(!r.declared_exact);
    assert!(r.beyond_tie > 0, "{r:?}");
    assert!(r.max_tie_distance > TIE_DISTANCE, "{r:?}");
    let worst = r.worst.expect("a worst disagreement");
    assert!(!worst.textured && worst.tie_distance > TIE_DISTANCE);
    assert_ne!(worst.ours, worst.reference);
    let e = r.check().unwrap_err().to_string();
    assert!(e.contains("`dcs` is not exact here"), "{e}");
}

/// Exact DCS's decisions with one sample of every pixel flipped.
struct Corrupted(DepthComplexitySampling);

impl SampleDecisions for Corrupted {
    fn sample_visibility(
        &self,
        ctx: &ShadowContext,
        light: usize,
        pixels: &[usize],
    ) -> Result<Vec<PixelVisibility>> {
        let mut v = self.0.sample_visibility(ctx, light, pixels)?;
        for p in &mut v {
            if let Some(x) = p.visibility.first_mut() {
                *x = 1.0 - *x;
            }
        }
        Ok(v)
    }
}

/// An answer corrupted behind the hook is caught: the flipped relations
/// are the disagreements (sample 0 of 4: a quarter of them), and the
/// honest answer has none.
#[test]
fn a_corrupted_answer_is_caught() {
    let scene = common::shipped("spheres.toml");
    let frame = common::Frame::new(&scene, 64, 48);
    let ctx = frame.ctx(&scene);
    let dcs = DepthComplexitySampling {
        samples: 4,
        seed: 9,
        silhouettes: SilhouetteMode::WholeLight,
        mode: Default::default(),
        pattern: SamplePattern::Stratified,
        transmittance: Default::default(),
        coverage: Default::default(),
        opacity_filter: Default::default(),
        rays: penumbra::internal::shadow::dcs::RayChoice::Never,
    };
    let honest = verify_with(&dcs, "dcs", true, &ctx, 8_000, 9).unwrap();
    assert_eq!(honest.disagreements, 0, "{honest:?}");
    let bad = verify_with(&Corrupted(dcs), "corrupted", true, &ctx, 8_000, 9).unwrap();
    eprintln!("{bad}");
    let flipped = bad.checked / 4;
    assert!(
        bad.disagreements > flipped * 8 / 10 && bad.disagreements < flipped * 12 / 10,
        "{bad:?}"
    );
    assert!(bad.beyond_tie > bad.disagreements / 2, "{bad:?}");
    assert!(bad.worst.is_some_and(|w| w.sample == 0));
    assert!(bad.check().is_err());
}

fn penumbra() -> Command {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
}

fn scene_path(name: &str) -> String {
    format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// The command line: a pass exits 0 and prints the counts; centre
/// silhouettes on the bunny exit non-zero with a clear message; a
/// technique without decisions is refused by name before rendering.
#[test]
fn the_command_line_exits_on_a_failed_check() {
    let dir = common::scratch_dir("verify-cli");
    let png = dir.join("out.png");
    let run = |extra: &[&str]| {
        let mut c = penumbra();
        c.args(["render", &scene_path("bunny.toml"), "-o"])
            .arg(&png)
            .args(["--width", "96", "--height", "96", "--samples", "32"])
            .args(extra);
        c.output().expect("penumbra runs")
    };
    let ok = run(&["--verify", "5000"]);
    let err = String::from_utf8_lossy(&ok.stderr);
    assert!(ok.status.success(), "{err}");
    assert!(
        err.contains("verify dcs: 5000 relations checked") && err.contains("0 beyond"),
        "{err}"
    );
    let bad = run(&["--verify", "20000", "--silhouettes", "centre"]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success(), "{err}");
    assert!(err.contains("`dcs` is not exact here"), "{err}");
    assert!(err.contains("tie distance"), "{err}");
    let _ = std::fs::remove_file(&png);
    let refused = run(&["--verify", "10", "--technique", "shadow-volumes"]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    assert!(
        err.contains("`shadow-volumes` does not expose its per-sample decisions")
            && err.contains("dcs, penumbra-casting"),
        "{err}"
    );
    assert!(!png.exists(), "refused before rendering");
    let zero = run(&["--verify", "0"]);
    let err = String::from_utf8_lossy(&zero.stderr);
    assert!(!zero.status.success());
    assert!(
        err.contains("--verify") && err.contains("outside 1..="),
        "{err}"
    );
    assert!(!png.exists(), "refused before rendering");
}

/// `compare --verify` reports the certificate for the runs of techniques
/// that expose their decisions, in results.json, results.csv and the
/// markdown table.
#[test]
fn compare_reports_it_per_run() {
    let dir = common::scratch_dir("verify-compare");
    let out = dir.join("out");
    let status = penumbra()
        .args(["compare", &scene_path("spheres.toml")])
        .args(["--techniques", "shadow-volumes,dcs", "--samples", "8"])
        // DCS with the light's centre's silhouettes too.
        .arg("--sweep-settings")
        .args(["--reference-samples", "64", "--repeat", "1", "--no-images"])
        .args(["--width", "48", "--height", "36", "--verify", "2000"])
        .arg("--out")
        .arg(&out)
        .arg("--cache-dir")
        .arg(dir.join("cache"))
        .output()
        .expect("compare runs");
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let runs = json[0]["runs"].as_array().unwrap();
    let mut verified = 0;
    for run in runs {
        let technique = run["technique"].as_str().unwrap();
        let v = &run["verify"];
        if technique.starts_with("dcs") {
            assert_eq!(v["checked"], 2000, "{run}");
            verified += 1;
        } else {
            assert!(v.is_null(), "{run}");
        }
    }
    // Exact and centre silhouettes.
    assert_eq!(verified, 2);
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    assert!(csv.lines().next().unwrap().ends_with("verify_max_tie"));
    assert!(csv.contains(",2000,"), "{csv}");
    let md = std::fs::read_to_string(out.join("results.md")).unwrap();
    assert!(md.contains("verify: disagreeing / checked"), "{md}");
    assert!(md.contains("/2000 ("), "{md}");
}

/// `--verify all` checks every sample of every receiving pixel (not a
/// draw): on spheres at 48 × 36 with 8 samples, exact DCS passes it, the
/// centre silhouettes fail it, and both count the same relations.
#[test]
fn verify_all_checks_every_relation() {
    use penumbra::internal::shadow::kit::verify::{parse_amount, EVERY_RELATION};
    assert_eq!(parse_amount("all"), Ok(EVERY_RELATION));
    assert_eq!(parse_amount("12"), Ok(12));
    assert!(parse_amount("some").is_err());
    let scene = common::shipped("spheres.toml");
    let exact = verified(&scene, &options("dcs", 8, 48, 36, 0), EVERY_RELATION);
    // Every surface pixel of this view receives shadows.
    let frame = common::Frame::new(&scene, 48, 36);
    let surface = (0..48 * 36)
        .filter(|&i| frame.gbuffer.is_surface(i))
        .count() as u64;
    assert_eq!(exact.checked, surface * 8, "{exact:?}");
    assert_saw_shadow(&exact);
    assert_eq!(exact.beyond_tie, 0, "{exact:?}");
    let mut o = options("dcs", 8, 48, 36, 0);
    o.options.dcs.silhouettes = SilhouetteMode::Centre;
    let centre = verified(&scene, &o, EVERY_RELATION);
    assert_eq!(centre.checked, exact.checked);
    assert!(centre.beyond_tie > 0, "{centre:?}");
}
