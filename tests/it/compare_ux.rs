//! `compare` without surprises: only the runs asked for (the others
//! under `--sweep-settings`), listed before any starts; chart labels that
//! never overlap, on the results of shipped scenes.

use crate::common;

use penumbra::internal::compare::{compare_scene, scene_charts, CompareOptions};
use penumbra::internal::render::Technique;
use penumbra::internal::report::{
    error_vs_time_labels, ChartLabels, LabelBox, Progress, CHART_SIZE,
};
use std::process::Command;

fn penumbra(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run penumbra");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The (technique, setting) pairs of a results.csv's runs, in order.
fn runs_in(path: &std::path::Path) -> Vec<(String, String)> {
    let mut reader = csv::Reader::from_path(path).expect("results.csv reads");
    let mut runs: Vec<(String, String)> = reader
        .records()
        .map(|row| row.expect("a row"))
        .filter(|row| !row[1].starts_with("reference-"))
        .map(|row| (row[1].to_string(), row[2].to_string()))
        .collect();
    runs.dedup();
    runs
}

/// By default each technique runs its default configuration at each
/// sample count asked for, and the list of runs is the first thing on
/// stderr; `--sweep-settings` adds the registry's other settings, marked
/// in the list as added by it.
#[test]
fn only_the_runs_asked_for_listed_before_they_start() {
    let dir = common::ScratchDir::new("compare-ux-runs");
    let cache = dir.0.join("cache");
    let out = dir.0.join("plain");
    let args = |out: &std::path::Path, extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = [
            "compare",
            "scenes/quad.toml",
            "--techniques",
            "dcs,shadow-map",
            "--samples",
            "4",
            "--reference-samples",
            "16",
            "--repeat",
            "1",
            "--width",
            "24",
            "--height",
            "24",
            "--threads",
            "1",
            "--no-images",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        a.extend(["--cache-dir".into(), cache.display().to_string()]);
        a.extend(["--out".into(), out.display().to_string()]);
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let run = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        penumbra(&a)
    };
    let (code, _, err) = run(args(&out, &[]));
    assert_eq!(code, Some(0), "{err}");
    let first = err.lines().next().unwrap_or_default();
    assert!(
        first
            .starts_with("compare: 2 runs and the reference on quad (24×24, 1 timed render each):"),
        "{err}"
    );
    assert!(err.contains("reference 16 spp (to compute)"), "{err}");
    assert!(err.contains("dcs 4 spp;"), "{err}");
    assert!(err.contains("shadow-map 1024² map, pcf 1"), "{err}");
    assert!(!err.contains("--sweep-settings"), "{err}");
    assert_eq!(
        runs_in(&out.join("results.csv")),
        [
            ("dcs".to_string(), "4 spp".to_string()),
            ("shadow-map".to_string(), "1024² map, pcf 1".to_string())
        ]
    );

    // With the option: the other settings too, each marked in the list;
    // the reference now comes from the cache.
    let swept = dir.0.join("swept");
    let (code, _, err) = run(args(&swept, &["--sweep-settings"]));
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("reference 16 spp (cached)"), "{err}");
    assert!(
        err.contains("dcs centre 4 spp, centre silhouettes [--sweep-settings]"),
        "{err}"
    );
    assert!(
        err.contains("shadow-map 256² map, pcf 1 [--sweep-settings]"),
        "{err}"
    );
    assert!(!err.contains("dcs 4 spp [--sweep-settings]"), "{err}");
    let runs = runs_in(&swept.join("results.csv"));
    let listed = err
        .lines()
        .next()
        .and_then(|l| l.split(':').nth(1))
        .unwrap_or_default();
    assert!(
        listed.starts_with(&format!(" {} runs and the reference", runs.len())),
        "{listed} vs {runs:?}"
    );
    for (technique, setting) in &runs {
        assert!(
            err.replace("\n  ", " ")
                .contains(&format!("{technique} {setting}")),
            "{technique} {setting} listed: {err}"
        );
    }
    assert!(runs.iter().any(|r| r.0 == "dcs centre"), "{runs:?}");
    assert!(runs.len() > 5, "{runs:?}");
    // The report's command reruns the same sweep.
    let md = std::fs::read_to_string(swept.join("results.md")).expect("results.md");
    assert!(md.contains("--sweep-settings"), "{md}");

    // A shard lists its own share of the same plan.
    let shards = dir.0.join("shards");
    let (code, _, err) = run(args(&shards, &["--sweep-settings", "--shard", "2/2"]));
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.starts_with("compare shard 2/2 (")
            && err.contains(&format!("of the sweep's {} runs)", runs.len())),
        "{err}"
    );
}

/// Every box pairwise disjoint, in the plotting area (so in the image),
/// out of the legend.
fn check_labels(what: &str, labels: &ChartLabels) {
    let image = LabelBox {
        x0: 0,
        y0: 0,
        x1: labels.image.0 as i32,
        y1: labels.image.1 as i32,
    };
    assert!(labels.plot.inside(&image), "{what}: {labels:?}");
    for (i, a) in labels.boxes.iter().enumerate() {
        assert!(a.x0 < a.x1 && a.y0 < a.y1, "{what}: empty box {a:?}");
        assert!(
            a.inside(&labels.plot) && a.inside(&image),
            "{what}: {a:?} outside"
        );
        if let Some(legend) = &labels.legend {
            assert!(!a.intersects(legend), "{what}: {a:?} over the legend");
        }
        for b in &labels.boxes[i + 1..] {
            assert!(!a.intersects(b), "{what}: {a:?} and {b:?} overlap");
        }
    }
}

/// The labels of every chart `compare` draws for shipped scenes, on the
/// sweep's real results (the default techniques, a few more, and their
/// swept settings: crowded charts), at the charts' size and a small one:
/// pairwise disjoint, inside the image and the plot, clear of the legend.
#[test]
fn chart_labels_never_overlap_on_shipped_scenes() {
    let dir = common::ScratchDir::new("compare-ux-labels");
    for name in ["spheres.toml", "quad.toml"] {
        let scene = common::shipped(name);
        let mut techniques = CompareOptions::default().techniques;
        for more in ["shadow-map", "pcss", "soft-shadow-map", "wedges"] {
            techniques.push(Technique::named(more).expect("registered"));
        }
        let options = CompareOptions {
            techniques,
            samples: vec![4, 16, 64],
            reference_samples: 32,
            repeat: 1,
            width: Some(64),
            height: Some(48),
            images: false,
            sweep_settings: true,
            cache_dir: dir.0.join("cache"),
            ..CompareOptions::default()
        };
        let out = dir.0.join(name);
        let result = compare_scene(&scene, &options, &out, &Progress::hidden()).expect("compare");
        let charts = scene_charts(&result);
        assert_eq!(charts.len(), 5, "{name}: the image's three and Vcoef's two");
        for chart in &charts {
            assert!(out.join(chart.file).is_file(), "{}", chart.file);
            let distinct = {
                let mut p: Vec<(&str, u64, u64)> = (chart.points.iter())
                    .map(|p| (p.technique.as_str(), p.seconds.to_bits(), p.error.to_bits()))
                    .collect();
                p.sort_unstable();
                p.dedup();
                p.len()
            };
            for size in [CHART_SIZE, (480, 360)] {
                let what = format!("{name} {} at {size:?}", chart.file);
                let labels = error_vs_time_labels(
                    &chart.title,
                    chart.y_label,
                    &chart.points,
                    chart.floor,
                    size,
                )
                .expect("the chart draws");
                check_labels(&what, &labels);
                assert_eq!(labels.image, size);
                assert_eq!(labels.boxes.len() + labels.left_out, distinct, "{what}");
                if size == CHART_SIZE {
                    assert!(
                        labels.left_out * 4 <= distinct,
                        "{what}: {} of {distinct} labels left out",
                        labels.left_out
                    );
                }
            }
        }
    }
}
