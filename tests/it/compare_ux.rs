//! `compare`'s charts: point labels that never overlap, on the results
//! of shipped scenes.

use crate::common;

use penumbra::internal::compare::{compare_scene, scene_charts, CompareOptions};
use penumbra::internal::render::Technique;
use penumbra::internal::report::{
    error_vs_time_labels, ChartLabels, LabelBox, Progress, CHART_SIZE,
};

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
