//! Error metrics, the Pareto front, error-vs-time charts and error heat
//! maps, against answers worked out by hand.

use crate::common;

use penumbra::internal::report::{
    colour_bar_rect, error_metrics, heatmap_canvas, heatmap_colour, pareto_front,
    write_error_heatmap, write_error_vs_time, write_error_vs_time_sized, ChartPoint,
    ErrorAccumulator, ErrorMetrics, HeatmapScale, CHART_SIZE, COLOUR_BAR_BAND, HEATMAP_BACKGROUND,
    HEATMAP_NON_FINITE, VISIBLE_ERROR,
};
use penumbra::Error;
use std::path::Path;

/// `|a − b| <= tol`, with a message.
fn close(a: f64, b: f64, tol: f64, what: &str) {
    assert!((a - b).abs() <= tol, "{what}: {a} vs {b}");
}

#[test]
fn constant_offset_gives_the_offset_everywhere() {
    // 0.1 is not exact in f32, so the error is the f32 difference in f64.
    let reference: Vec<f32> = (0..100).map(|i| i as f32 / 100.0).collect();
    let test: Vec<f32> = reference.iter().map(|v| v + 0.1).collect();
    let m = error_metrics(&test, &reference, |_| true);
    assert_eq!(m.count, 100);
    assert_eq!(m.non_finite, 0);
    assert_eq!(m.frac_over, 1.0);
    close(m.rmse, 0.1, 1e-6, "rmse");
    close(m.mean_abs, 0.1, 1e-6, "mean");
    close(m.max_abs, 0.1, 1e-6, "max");
    // Exact with dyadic values and offset: every difference and sum is exact.
    let reference: Vec<f32> = (0..100).map(|i| i as f32 / 64.0).collect();
    let test: Vec<f32> = reference.iter().map(|v| v - 0.125).collect();
    let m = error_metrics(&test, &reference, |_| true);
    assert_eq!((m.rmse, m.mean_abs, m.max_abs), (0.125, 0.125, 0.125));
}

#[test]
fn a_single_outlier() {
    // 99 exact values and one off by 1: mean 1/100, rmse sqrt(1/100) = 0.1,
    // max 1, one value in a hundred visible.
    let reference = vec![0.5f32; 100];
    let mut test = reference.clone();
    test[37] = 1.5;
    let m = error_metrics(&test, &reference, |_| true);
    assert_eq!(m.count, 100);
    assert_eq!(m.max_abs, 1.0);
    assert_eq!(m.mean_abs, 0.01);
    close(m.rmse, 0.1, 1e-15, "rmse");
    assert_eq!(m.frac_over, 0.01);
}

#[test]
fn errors_at_the_visibility_threshold_are_not_over() {
    let reference = [0.0f32; 4];
    // 1/255 in f32 rounds up or down; compare with the f64 threshold the
    // metric uses, over values clearly below and above it.
    let test = [0.0f32, 0.003, 0.0045, -0.01];
    let m = error_metrics(&test, &reference, |_| true);
    const { assert!(0.003 < VISIBLE_ERROR && 0.0045 > VISIBLE_ERROR) };
    assert_eq!(m.frac_over, 0.5);
}

#[test]
fn include_mask_selects_the_values() {
    // Only even indices count: errors 0, 2, 4 (values 1, 3, 5 are huge).
    let reference = [0.0f32; 6];
    let test = [0.0f32, 100.0, 2.0, 100.0, 4.0, 100.0];
    let m = error_metrics(&test, &reference, |i| i % 2 == 0);
    assert_eq!(m.count, 3);
    assert_eq!(m.mean_abs, 2.0);
    assert_eq!(m.max_abs, 4.0);
    close(m.rmse, (20.0f64 / 3.0).sqrt(), 1e-15, "rmse");
    assert_eq!(m.frac_over, 2.0 / 3.0);
}

#[test]
fn empty_set_is_all_zeros() {
    assert_eq!(error_metrics(&[], &[], |_| true), ErrorMetrics::default());
    assert_eq!(
        error_metrics(&[1.0, 2.0], &[3.0, 4.0], |_| false),
        ErrorMetrics::default()
    );
    assert_eq!(
        ErrorAccumulator::default().finish(),
        ErrorMetrics::default()
    );
}

#[test]
fn different_lengths_compare_the_common_prefix() {
    let m = error_metrics(&[1.0, 1.0, 9.0], &[0.0, 0.0], |_| true);
    assert_eq!(m.count, 2);
    assert_eq!(m.max_abs, 1.0);
    let m = error_metrics(&[1.0], &[0.0, 5.0, 5.0], |_| true);
    assert_eq!(m.count, 1);
}

#[test]
fn non_finite_values_never_pass() {
    for (t, r) in [
        (f32::NAN, 0.0),
        (0.0, f32::NAN),
        (f32::INFINITY, 0.0),
        (0.0, f32::NEG_INFINITY),
        // Equal infinities are not "no error": the value is broken.
        (f32::INFINITY, f32::INFINITY),
    ] {
        let m = error_metrics(&[0.25, t, 0.5], &[0.25, r, 0.5], |_| true);
        assert_eq!(m.count, 3, "{t} vs {r}");
        assert_eq!(m.non_finite, 1, "{t} vs {r}");
        assert_eq!(m.max_abs, f64::INFINITY);
        assert_eq!(m.rmse, f64::INFINITY);
        assert_eq!(m.mean_abs, f64::INFINITY);
        // The broken value is the one visible error of three.
        assert_eq!(m.frac_over, 1.0 / 3.0);
        // Any tolerance check `value <= tolerance` fails.
        assert!(m.max_abs > 1e300 && m.rmse > 1e300 && m.mean_abs > 1e300);
    }
}

#[test]
fn accumulator_merge_equals_one_pass() {
    let mut rng = common::Rng(7);
    // Dyadic values (multiples of 1/1024 below 4): every partial sum is
    // exact in f64, so a merge must give exactly the one-pass bits.
    let pairs: Vec<(f64, f64)> = (0..1000)
        .map(|_| {
            (
                rng.range(0, 4095) as f64 / 1024.0,
                rng.range(0, 4095) as f64 / 1024.0,
            )
        })
        .collect();
    let mut one = ErrorAccumulator::default();
    for &(t, r) in &pairs {
        one.add(t, r);
    }
    for split in [0, 1, 333, 999, 1000] {
        let (mut a, mut b) = (ErrorAccumulator::default(), ErrorAccumulator::default());
        for &(t, r) in &pairs[..split] {
            a.add(t, r);
        }
        for &(t, r) in &pairs[split..] {
            b.add(t, r);
        }
        a.merge(&b);
        assert_eq!(a.finish(), one.finish(), "split at {split}");
    }
    // Arbitrary values: equal up to rounding, and counts exactly.
    let pairs: Vec<(f64, f64)> = (0..1000).map(|_| (rng.f64(), rng.f64())).collect();
    let mut one = ErrorAccumulator::default();
    let (mut a, mut b) = (ErrorAccumulator::default(), ErrorAccumulator::default());
    for (k, &(t, r)) in pairs.iter().enumerate() {
        one.add(t, r);
        if k < 400 { &mut a } else { &mut b }.add(t, r);
    }
    a.merge(&b);
    let (m, o) = (a.finish(), one.finish());
    assert_eq!(
        (m.count, m.max_abs, m.frac_over),
        (o.count, o.max_abs, o.frac_over)
    );
    close(m.rmse, o.rmse, 1e-14, "rmse");
    close(m.mean_abs, o.mean_abs, 1e-14, "mean");
    // Non-finite values survive a merge.
    let mut bad = ErrorAccumulator::default();
    bad.add(f64::NAN, 0.0);
    a.merge(&bad);
    let m = a.finish();
    assert_eq!((m.non_finite, m.count), (1, 1001));
    assert_eq!(m.rmse, f64::INFINITY);
}

fn point(technique: &str, label: &str, seconds: f64, error: f64) -> ChartPoint {
    ChartPoint {
        technique: technique.into(),
        label: label.into(),
        seconds,
        error,
    }
}

#[test]
fn pareto_front_of_a_constructed_set() {
    let points = [
        point("a", "fast, bad", 1.0, 0.5),        // front: fastest
        point("a", "dominated", 2.0, 0.6),        // beaten by 0 in both
        point("b", "middle", 2.0, 0.2),           // front
        point("b", "same time, worse", 2.0, 0.3), // beaten by 2 (tie in time)
        point("c", "slow, good", 5.0, 0.05),      // front
        point("c", "twin", 5.0, 0.05),            // identical to 4: kept
        point("c", "slower, worse", 6.0, 0.05),   // beaten by 4 (tie in error)
        point("d", "nan", f64::NAN, 0.0),         // never on the front ...
        point("d", "nan error", 0.5, f64::NAN),   // ... and beats nothing
    ];
    assert_eq!(
        pareto_front(&points),
        [true, false, true, false, true, true, false, false, false]
    );
    assert!(pareto_front(&[]).is_empty());
    assert_eq!(pareto_front(&points[..1]), [true]);
}

/// Reads a PNG back as 8-bit RGB.
fn read_rgb(path: &Path) -> image::RgbImage {
    image::open(path).expect("a readable PNG").to_rgb8()
}

#[test]
fn chart_is_a_png_of_the_requested_size() {
    let dir = common::scratch_dir("chart");
    let points = [
        point("pcss", "8", 0.02, 0.03),
        point("pcss", "32", 0.07, 0.016),
        point("shadow volumes", "4 spp", 0.05, 0.05),
        point("shadow volumes", "64 spp", 0.8, 0.005),
        point("reference", "256", 5.0, 0.002),
    ];
    let path = dir.join("chart.png");
    write_error_vs_time(&path, "Error vs time", "RMSE", &points, Some(0.0015)).unwrap();
    let img = read_rgb(&path);
    assert_eq!(img.dimensions(), CHART_SIZE);
    // Something was drawn: the first curve's colour is there.
    assert!(img.pixels().any(|p| p.0 == [0, 114, 178]));
    // Bit-identical when drawn again (and so on every machine: the font
    // is compiled in and nothing depends on the system).
    let again = dir.join("again.png");
    write_error_vs_time(&again, "Error vs time", "RMSE", &points, Some(0.0015)).unwrap();
    assert_eq!(
        std::fs::read(&path).unwrap(),
        std::fs::read(&again).unwrap()
    );
    // No temporary file is left behind.
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["again.png", "chart.png"]);
}

#[test]
fn chart_copes_with_degenerate_input() {
    let dir = common::scratch_dir("chart-degenerate");
    let cases: Vec<(&str, Vec<ChartPoint>, Option<f64>)> = vec![
        ("none", vec![], None),
        ("one", vec![point("a", "x", 0.1, 0.01)], Some(0.02)),
        (
            "zeros",
            vec![point("a", "x", 0.0, 0.0), point("a", "y", 0.0, 0.0)],
            Some(0.0),
        ),
        (
            "negative",
            vec![point("a", "x", -1.0, -0.5), point("b", "y", 1.0, 0.1)],
            Some(-1.0),
        ),
        (
            "equal",
            vec![point("a", "x", 0.5, 0.5), point("b", "y", 0.5, 0.5)],
            None,
        ),
        (
            "nan",
            vec![
                point("a", "x", f64::NAN, 0.1),
                point("a", "y", 0.1, f64::NAN),
                point("b", "z", 0.2, f64::INFINITY),
                point("b", "w", 0.2, 0.1),
            ],
            Some(f64::NAN),
        ),
        ("all nan", vec![point("a", "x", f64::NAN, f64::NAN)], None),
        (
            "huge range",
            vec![point("a", "x", 1e-9, 1e-30), point("a", "y", 1e9, 1e30)],
            Some(1e-20),
        ),
    ];
    for (name, points, floor) in cases {
        let path = dir.join(format!("{name}.png"));
        write_error_vs_time(&path, name, "error", &points, floor)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(read_rgb(&path).dimensions(), CHART_SIZE, "{name}");
        let small = dir.join(format!("{name}-small.png"));
        write_error_vs_time_sized(&small, name, "error", &points, floor, (320, 200)).unwrap();
        assert_eq!(read_rgb(&small).dimensions(), (320, 200), "{name}");
    }
}

#[test]
fn chart_errors_name_the_path() {
    let dir = common::scratch_dir("chart-errors");
    let points = [point("a", "x", 1.0, 1.0)];
    let missing = dir.join("no-such-dir").join("chart.png");
    let e = write_error_vs_time(&missing, "t", "e", &points, None).unwrap_err();
    assert!(
        matches!(&e, Error::Io { path, .. } if *path == missing),
        "{e}"
    );
    let tiny = dir.join("tiny.png");
    let e = write_error_vs_time_sized(&tiny, "t", "e", &points, None, (10, 10)).unwrap_err();
    assert!(
        e.to_string().contains("tiny.png") && e.to_string().contains("too small"),
        "{e}"
    );
    assert!(!tiny.exists());
}

#[test]
fn heatmap_colours() {
    let dir = common::scratch_dir("heatmap");
    let path = dir.join("heat.png");
    // Pixels: 0, scale, 2·scale, −scale, background, NaN, +inf, scale/2.
    let error = [0.0, 0.5, 1.0, -0.5, 0.0, f32::NAN, f32::INFINITY, 0.25];
    let valid = [true, true, true, true, false, true, true, true];
    write_error_heatmap(&path, 4, 2, &error, &valid, &scale(0.5)).unwrap();
    let img = read_rgb(&path);
    // The image, then its colour bar's band below it (and at least
    // MIN_HEATMAP_WIDTH wide): the map's pixels are 1:1 in the top left.
    assert_eq!(img.dimensions(), heatmap_canvas(4, 2));
    assert_eq!(img.height(), 2 + COLOUR_BAR_BAND);
    assert!(img.width() > 4);
    let px = |i: u32| img.get_pixel(i % 4, i / 4).0;
    let dark = [68, 1, 84]; // viridis at 0
    let bright = [254, 232, 37]; // viridis at 1
    assert_eq!(px(0), dark);
    assert_eq!(px(1), bright);
    assert_eq!(px(2), bright, "clamped above the scale");
    assert_eq!(px(3), bright, "the magnitude counts, not the sign");
    assert_eq!(px(4), HEATMAP_BACKGROUND);
    assert_eq!(px(4), [128, 128, 128]);
    assert_eq!(px(5), HEATMAP_NON_FINITE);
    assert_eq!(px(5), [255, 0, 255]);
    assert_eq!(px(6), HEATMAP_NON_FINITE);
    // Halfway: between the ends, and brighter than 0 (viridis' luminance
    // rises monotonically).
    let mid = px(7);
    assert_eq!(mid, heatmap_colour(0.25, 0.5));
    assert!(luma(dark) < luma(mid) && luma(mid) < luma(bright));
    let ramp: Vec<f64> = (0..=100)
        .map(|k| luma(heatmap_colour(k as f32 / 100.0, 1.0)))
        .collect();
    assert!(ramp.windows(2).all(|w| w[0] <= w[1]), "{ramp:?}");
    // A degenerate scale: zero stays dark, any error is brightest.
    assert_eq!(heatmap_colour(0.0, 0.0), dark);
    assert_eq!(heatmap_colour(1e-9, 0.0), bright);
    assert_eq!(heatmap_colour(1e-9, f32::NAN), bright);
}

fn scale(max: f32) -> HeatmapScale<'static> {
    HeatmapScale {
        quantity: "|ΔVcoef|",
        unit: "unitless",
        max,
    }
}

fn luma(c: [u8; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Every heat map carries its colour scale: a bar under the image, as
/// the colours of the map from 0 at its left to the scale's top at its
/// right, monotone in brightness; white around it; the ticks and
/// caption drawn in the band, never over the image.
#[test]
fn heatmaps_carry_their_colour_bar() {
    let dir = common::scratch_dir("heatmap-bar");
    for (w, h) in [(8u32, 6u32), (600, 40)] {
        let path = dir.join(format!("heat-{w}.png"));
        let error: Vec<f32> = (0..w * h).map(|i| (i % w) as f32 / w as f32).collect();
        let valid = vec![true; error.len()];
        write_error_heatmap(&path, w, h, &error, &valid, &scale(0.5)).unwrap();
        let img = read_rgb(&path);
        assert_eq!(img.dimensions(), heatmap_canvas(w, h));
        assert_eq!(img.dimensions().1, h + COLOUR_BAR_BAND);
        for y in 0..h {
            for x in 0..w {
                let e = error[(y * w + x) as usize];
                assert_eq!(img.get_pixel(x, y).0, heatmap_colour(e, 0.5), "{x},{y}");
            }
        }
        let (x0, y0, x1, y1) = colour_bar_rect(w, h);
        assert!(y0 >= h && y1 <= img.height() && x1 <= img.width());
        assert!(x1 - x0 >= 200, "a bar long enough to read");
        let row: Vec<[u8; 3]> = (x0..x1)
            .map(|x| img.get_pixel(x, (y0 + y1) / 2).0)
            .collect();
        // Every column of the bar is one colour, top to bottom.
        for x in x0..x1 {
            for y in y0..y1 {
                assert_eq!(img.get_pixel(x, y).0, row[(x - x0) as usize]);
            }
        }
        assert_eq!(row[0], heatmap_colour(0.0, 0.5), "0 at the left");
        assert_eq!(
            *row.last().unwrap(),
            heatmap_colour(0.5, 0.5),
            "the top at the right"
        );
        // Monotone along the scale: brighter every few columns, and
        // never darker from one column to the next by more than the
        // rounding of one 8-bit channel (viridis' luminance rises
        // monotonically; its 8-bit codes step one channel at a time).
        let brightness: Vec<f64> = row.iter().map(|&c| luma(c)).collect();
        assert!(
            brightness.windows(2).all(|p| p[1] >= p[0] - 0.75),
            "monotone along the scale: {brightness:?}"
        );
        assert!(
            brightness.windows(8).all(|p| p[7] > p[0]),
            "rising along the scale: {brightness:?}"
        );
        assert!(brightness[0] + 100.0 < *brightness.last().unwrap());
        // Text (the ticks and caption) is drawn in the band: some pixels
        // of the band outside the bar are neither white nor the bar's.
        let inked = (h..img.height())
            .flat_map(|y| (0..img.width()).map(move |x| (x, y)))
            .filter(|&(x, y)| !(x0..x1).contains(&x) || !(y0..y1).contains(&y))
            .filter(|&(x, y)| img.get_pixel(x, y).0 != [255, 255, 255])
            .count();
        assert!(inked > 200, "ticks and caption drawn: {inked} pixels");
    }
}

#[test]
fn heatmap_checks_sizes() {
    let dir = common::scratch_dir("heatmap-sizes");
    let path = dir.join("heat.png");
    let e = write_error_heatmap(&path, 2, 2, &[0.0; 3], &[true; 3], &scale(1.0)).unwrap_err();
    assert!(e.to_string().contains("heat.png"), "{e}");
    let e = write_error_heatmap(&path, 2, 2, &[0.0; 4], &[true; 3], &scale(1.0)).unwrap_err();
    assert!(e.to_string().contains("heat.png"), "{e}");
    assert!(!path.exists());
}
