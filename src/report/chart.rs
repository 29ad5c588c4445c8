//! Error-vs-time charts: each technique's quality/cost trade-off on
//! log-log axes, with the Pareto front and the reference's own noise.
//!
//! Drawn by plotters into an RGB buffer with a font compiled into the
//! binary (no system fonts are looked up), then encoded like every other
//! PNG here, so a chart has the same bits on every machine.

use crate::error::{Error, Result};
use crate::output::write_rgb8;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};
use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

/// The size of the charts [`write_error_vs_time`] writes, in pixels.
pub const CHART_SIZE: (u32, u32) = (1024, 720);

/// The smallest chart [`write_error_vs_time_sized`] accepts: below this the
/// axes, labels and legend no longer fit.
pub const MIN_CHART_SIZE: (u32, u32) = (240, 180);

/// One measured run: a technique at one setting.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartPoint {
    /// The technique; one curve per technique.
    pub technique: String,
    /// The setting, written next to the marker (e.g. `"16 spp"`).
    pub label: String,
    /// Time taken (x axis).
    pub seconds: f64,
    /// Error against the reference (y axis).
    pub error: f64,
}

/// true for points no other point beats in both time and error (ties kept).
///
/// A point is beaten when another is at least as fast and at least as
/// accurate, and strictly better in one of the two; identical points do not
/// beat each other, so both stay on the front. A point with a NaN time or
/// error is never on the front and beats nothing. O(n²), for the few dozen
/// points a chart has.
pub fn pareto_front(points: &[ChartPoint]) -> Vec<bool> {
    let beats = |a: &ChartPoint, b: &ChartPoint| {
        a.seconds <= b.seconds && a.error <= b.error && (a.seconds < b.seconds || a.error < b.error)
    };
    points
        .iter()
        .map(|p| !p.seconds.is_nan() && !p.error.is_nan() && !points.iter().any(|q| beats(q, p)))
        .collect()
}

/// Log-log error-vs-time chart, one curve (line + markers, labelled with `label`) per technique in order of appearance, a legend, the Pareto front marked (e.g. ringed markers and/or a dashed step line), and `error_floor` (the reference's own noise) as a horizontal dashed line labelled "reference noise floor". Written atomically as PNG via crate::output::write_atomically.
///
/// The chart is [`CHART_SIZE`]; see [`write_error_vs_time_sized`] for the
/// details.
pub fn write_error_vs_time(
    path: &Path,
    title: &str,
    y_label: &str,
    points: &[ChartPoint],
    error_floor: Option<f64>,
) -> Result<()> {
    write_error_vs_time_sized(path, title, y_label, points, error_floor, CHART_SIZE)
}

/// [`write_error_vs_time`] at `size` (width, height) pixels, at least
/// [`MIN_CHART_SIZE`].
///
/// Points with a non-finite time or error are left out (an infinite error
/// is a failure the metrics report; it has no place on a log axis). A log
/// axis has no zero, so zero or negative values are clamped to a small
/// positive floor: a decade below the smallest positive value on that axis
/// (1e-6 if it has none), and a note under the chart says so. Coinciding
/// points of one technique share a marker, their labels joined. An
/// `error_floor` that is not positive and finite is not drawn. With no
/// drawable point the chart has empty axes; one point or identical points
/// get a range around them.
pub fn write_error_vs_time_sized(
    path: &Path,
    title: &str,
    y_label: &str,
    points: &[ChartPoint],
    error_floor: Option<f64>,
    size: (u32, u32),
) -> Result<()> {
    let (width, height) = size;
    if width < MIN_CHART_SIZE.0 || height < MIN_CHART_SIZE.1 {
        return Err(Error::file(
            path,
            None,
            format!(
                "a {width}×{height} chart is too small (at least {}×{})",
                MIN_CHART_SIZE.0, MIN_CHART_SIZE.1
            ),
        ));
    }
    register_embedded_font().map_err(|why| Error::file(path, None, why))?;
    let mut rgb = vec![255u8; width as usize * height as usize * 3];
    draw(&mut rgb, size, title, y_label, points, error_floor)
        .map_err(|why| Error::file(path, None, format!("cannot draw the chart: {why}")))?;
    write_rgb8(path, width, height, &rgb)
}

/// The font every chart's text is drawn with, registered once as plotters'
/// sans-serif family. It comes compiled into the binary, so charts look
/// (and are) the same with or without system fonts.
pub(crate) fn register_embedded_font() -> std::result::Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err("the embedded chart font cannot be parsed".into())
    }
}

/// Okabe–Ito colours first (distinguishable with the common colour-vision
/// deficiencies and on white), then six darker ones so that a comparison of
/// every registered technique (fourteen curves) repeats no colour. Curves
/// past the fourteenth reuse them.
const PALETTE: [RGBColor; 14] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 120, 120),
    RGBColor(240, 228, 66),
    RGBColor(0, 0, 0),
    RGBColor(136, 34, 85),
    RGBColor(102, 51, 153),
    RGBColor(140, 86, 30),
    RGBColor(128, 128, 0),
    RGBColor(0, 0, 128),
];

/// A point where it is drawn: clamped into the log axes.
#[derive(Clone)]
struct Placed {
    x: f64,
    y: f64,
    label: String,
    front: bool,
}

/// Where an axis draws zero and negative values: a decade below its
/// smallest positive value, or 1e-6 if it has none.
fn log_floor(values: impl Iterator<Item = f64>) -> f64 {
    let min = values.filter(|v| *v > 0.0).fold(f64::INFINITY, f64::min);
    if min.is_finite() {
        min / 10.0
    } else {
        1e-6
    }
}

/// A log-axis range covering `lo..=hi` (both positive) with some margin,
/// and at least one decade so the axis gets labels.
fn log_range(lo: f64, hi: f64) -> Range<f64> {
    let (a, b) = (lo.ln(), hi.ln());
    let decade = 10f64.ln();
    let span = (b - a).max(decade);
    let mid = 0.5 * (a + b);
    let half = 0.5 * span * 1.15;
    (mid - half).exp()..(mid + half).exp()
}

/// A tick label: few digits, plain for ordinary magnitudes, `1e-5` style
/// beyond them.
pub(crate) fn tick_label(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        return "0".into();
    }
    if (1e-3..1e4).contains(&a) {
        let digits = (2 - a.log10().floor() as i32).clamp(0, 5) as usize;
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.1e}");
        s.replace(".0e", "e")
    }
}

/// A log axis whose ticks are 1, 2 and 5 times powers of ten (thinned to
/// powers of ten when there are too many), instead of plotters' own
/// choice, which can land on values such as 0.30000000000000004.
struct LogAxis(Range<f64>);

impl Ranged for LogAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let (a, b) = (self.0.start.ln(), self.0.end.ln());
        let t = (value.ln() - a) / (b - a);
        let px = f64::from(limit.0) + t * f64::from(limit.1 - limit.0);
        // Off-chart values still map to a finite pixel; plotters clips.
        px.clamp(-1e6, 1e6).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        let max = hint.max_num_points().max(2);
        let (lo, hi) = (self.0.start, self.0.end);
        let first = lo.log10().floor() as i32 - 1;
        let last = hi.log10().ceil() as i32 + 1;
        for mantissas in [&[1.0, 2.0, 5.0][..], &[1.0][..]] {
            let ticks: Vec<f64> = (first..=last)
                .flat_map(|e| mantissas.iter().map(move |m| m * 10f64.powi(e)))
                .filter(|v| *v >= lo && *v <= hi)
                .collect();
            if ticks.len() <= max {
                return ticks;
            }
        }
        // Very wide ranges: every k-th power of ten.
        let decades = (last - first) as usize + 1;
        let step = decades.div_ceil(max).max(1);
        (first..=last)
            .step_by(step)
            .map(|e| 10f64.powi(e))
            .filter(|v| *v >= lo && *v <= hi)
            .collect()
    }

    fn range(&self) -> Range<f64> {
        self.0.clone()
    }
}

/// The legend corner with the fewest points under it, so the legend hides
/// as little data as possible (ties: upper right, upper left, lower right,
/// lower left). `points` are in axis fractions, (0, 0) at the lower left.
fn legend_corner(points: &[(f64, f64)]) -> SeriesLabelPosition {
    let corners = [
        (SeriesLabelPosition::UpperRight, 0.6..1.01, 0.65..1.01),
        (SeriesLabelPosition::UpperLeft, -0.01..0.4, 0.65..1.01),
        (SeriesLabelPosition::LowerRight, 0.6..1.01, -0.01..0.35),
        (SeriesLabelPosition::LowerLeft, -0.01..0.4, -0.01..0.35),
    ];
    let mut best = (usize::MAX, SeriesLabelPosition::UpperRight);
    for (corner, us, vs) in corners {
        let n = points
            .iter()
            .filter(|(u, v)| us.contains(u) && vs.contains(v))
            .count();
        if n < best.0 {
            best = (n, corner);
        }
    }
    best.1
}

/// Where `v` lies on the log range `r`, as a fraction.
fn fraction(r: &Range<f64>, v: f64) -> f64 {
    (v.ln() - r.start.ln()) / (r.end.ln() - r.start.ln())
}

/// Where everything goes: the finite points placed on log axes (zero and
/// negative values at a floor below the smallest positive one), grouped
/// into curves, and the axes' ranges.
struct ChartLayout<'a> {
    /// Curves in order of first appearance, each sorted by time.
    curves: Vec<(&'a str, Vec<Placed>)>,
    /// The reference's noise floor, when finite and positive.
    floor_line: Option<f64>,
    x_range: Range<f64>,
    y_range: Range<f64>,
    /// Which clamped values the axes show at their floor.
    note: Option<String>,
}

impl<'a> ChartLayout<'a> {
    fn of(points: &'a [ChartPoint], error_floor: Option<f64>) -> Self {
        let front = pareto_front(points);
        let shown: Vec<(usize, &ChartPoint)> = points
            .iter()
            .enumerate()
            .filter(|(_, p)| p.seconds.is_finite() && p.error.is_finite())
            .collect();
        let floor_line = error_floor.filter(|f| f.is_finite() && *f > 0.0);
        let x_floor = log_floor(shown.iter().map(|(_, p)| p.seconds));
        let y_floor = log_floor(shown.iter().map(|(_, p)| p.error).chain(floor_line));
        let positive_or = |v: f64, floor: f64| if v > 0.0 { v } else { floor };

        // Curves in order of first appearance, each sorted by time.
        let mut curves: Vec<(&str, Vec<Placed>)> = Vec::new();
        for &(i, p) in &shown {
            let placed = Placed {
                x: positive_or(p.seconds, x_floor),
                y: positive_or(p.error, y_floor),
                label: p.label.clone(),
                front: front[i],
            };
            match curves.iter_mut().find(|(t, _)| *t == p.technique) {
                Some((_, c)) => match c.iter_mut().find(|q| (q.x, q.y) == (placed.x, placed.y)) {
                    Some(q) => {
                        q.label = format!("{}, {}", q.label, placed.label);
                        q.front |= placed.front;
                    }
                    None => c.push(placed),
                },
                None => curves.push((p.technique.as_str(), vec![placed])),
            }
        }
        for (_, c) in &mut curves {
            c.sort_by(|a, b| a.x.total_cmp(&b.x));
        }

        let placed = curves.iter().flat_map(|(_, c)| c.iter());
        let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f64::MAX, 0.0f64, f64::MAX, 0.0f64);
        for p in placed {
            x_lo = x_lo.min(p.x);
            x_hi = x_hi.max(p.x);
            y_lo = y_lo.min(p.y);
            y_hi = y_hi.max(p.y);
        }
        if let Some(f) = floor_line {
            y_lo = y_lo.min(f);
            y_hi = y_hi.max(f);
        }
        // Nothing to draw on an axis: a neutral range.
        if x_hi == 0.0 {
            (x_lo, x_hi) = (1e-2, 1.0);
        }
        if y_hi == 0.0 {
            (y_lo, y_hi) = (1e-3, 1e-1);
        }
        let x_range = log_range(x_lo, x_hi);
        let y_range = log_range(y_lo, y_hi);

        let clamped: Vec<String> = [
            ("time", x_floor, shown.iter().any(|(_, p)| p.seconds <= 0.0)),
            ("error", y_floor, shown.iter().any(|(_, p)| p.error <= 0.0)),
        ]
        .iter()
        .filter(|(_, _, any)| *any)
        .map(|(what, at, _)| format!("{what} ≤ 0 drawn at {}", tick_label(*at)))
        .collect();
        let note = (!clamped.is_empty()).then(|| format!("log axes: {}", clamped.join(", ")));

        ChartLayout {
            curves,
            floor_line,
            x_range,
            y_range,
            note,
        }
    }
}

/// The Pareto front as a staircase: from each front point, across at its
/// error to the next one's time, then down; `None` without front points.
fn front_staircase(placed: &[&Placed]) -> Option<Vec<(f64, f64)>> {
    let mut steps: Vec<&Placed> = placed.iter().copied().filter(|p| p.front).collect();
    steps.sort_by(|a, b| a.x.total_cmp(&b.x).then(b.y.total_cmp(&a.y)));
    if steps.is_empty() {
        return None;
    }
    let mut path = vec![(steps[0].x, steps[0].y)];
    for w in steps.windows(2) {
        path.push((w[1].x, w[0].y));
        path.push((w[1].x, w[1].y));
    }
    Some(path)
}

/// Draws the chart into `rgb` (`size`, 3 bytes per pixel).
fn draw(
    rgb: &mut [u8],
    size: (u32, u32),
    title: &str,
    y_label: &str,
    points: &[ChartPoint],
    error_floor: Option<f64>,
) -> std::result::Result<(), String> {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let ChartLayout {
        curves,
        floor_line,
        x_range,
        y_range,
        note,
    } = ChartLayout::of(points, error_floor);
    let placed: Vec<&Placed> = curves.iter().flat_map(|(_, c)| c.iter()).collect();

    let root = BitMapBackend::with_buffer(rgb, size).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let small = size.0 < 600 || size.1 < 400;
    let (caption, text, tick) = if small { (16, 12, 11) } else { (26, 18, 15) };
    let margin = if small { 8 } else { 18 };
    let note_height = if note.is_some() { tick + 6 } else { 0 };
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", caption))
        .margin(margin)
        .margin_bottom(margin + note_height)
        .x_label_area_size(if small { 34 } else { 56 })
        .y_label_area_size(if small { 48 } else { 86 })
        .build_cartesian_2d(LogAxis(x_range.clone()), LogAxis(y_range.clone()))
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc(y_label)
        .axis_desc_style(("sans-serif", text))
        .label_style(("sans-serif", tick))
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .light_line_style(WHITE)
        .bold_line_style(RGBColor(225, 225, 225))
        .draw()
        .map_err(|e| err(&e))?;

    if let Some(f) = floor_line {
        let grey = RGBColor(90, 90, 90);
        chart
            .draw_series(DashedLineSeries::new(
                [(x_range.start, f), (x_range.end, f)],
                10,
                6,
                grey.stroke_width(2),
            ))
            .map_err(|e| err(&e))?
            .label("reference noise floor")
            .legend(move |(x, y)| {
                DashedPathElement::new([(x, y), (x + 24, y)], 6, 4, grey.stroke_width(2))
            });
    }

    // The Pareto front as a dashed staircase: from each front point, across
    // at its error to the next one's time, then down.
    if let Some(path) = front_staircase(&placed) {
        chart
            .draw_series(DashedLineSeries::new(path, 5, 5, BLACK.stroke_width(1)))
            .map_err(|e| err(&e))?
            .label("Pareto front")
            .legend(|(x, y)| {
                EmptyElement::at((x + 12, y)) + Circle::new((0, 0), 7, BLACK.stroke_width(2))
            });
    }

    let label_font = ("sans-serif", tick)
        .into_font()
        .color(&RGBColor(40, 40, 40));
    for (k, (technique, curve)) in curves.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(
                curve.iter().map(|p| (p.x, p.y)),
                colour.stroke_width(2),
            ))
            .map_err(|e| err(&e))?
            .label(*technique)
            .legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (24, 0)], colour.stroke_width(2))
                    + Circle::new((12, 0), 4, colour.filled())
            });
        let (font, x_range) = (label_font.clone(), &x_range);
        chart
            .draw_series(curve.iter().map(move |p| {
                let ring = if p.front {
                    BLACK.to_rgba()
                } else {
                    TRANSPARENT
                };
                // Labels go right of the marker, or left of it near the
                // right edge, where they would be cut off.
                let (anchor, dx) = if fraction(x_range, p.x) > 0.85 {
                    (HPos::Right, -9)
                } else {
                    (HPos::Left, 9)
                };
                let font = font.pos(Pos::new(anchor, VPos::Bottom));
                EmptyElement::at((p.x, p.y))
                    + Circle::new((0, 0), 8, ring.stroke_width(2))
                    + Circle::new((0, 0), 4, colour.filled())
                    + Text::new(p.label.clone(), (dx, -5), font)
            }))
            .map_err(|e| err(&e))?;
    }

    if placed.is_empty() {
        let centre = (
            (x_range.start * x_range.end).sqrt(),
            (y_range.start * y_range.end).sqrt(),
        );
        let font = label_font.pos(Pos::new(HPos::Center, VPos::Center));
        chart
            .draw_series([Text::new("no finite points to plot", centre, font)])
            .map_err(|e| err(&e))?;
    }
    // An empty legend would be an empty box.
    if !placed.is_empty() || floor_line.is_some() {
        let in_axes: Vec<(f64, f64)> = placed
            .iter()
            .map(|p| (fraction(&x_range, p.x), fraction(&y_range, p.y)))
            .collect();
        chart
            .configure_series_labels()
            .position(legend_corner(&in_axes))
            .label_font(("sans-serif", tick))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()
            .map_err(|e| err(&e))?;
    }

    if let Some(note) = note {
        let y = size.1 as i32 - margin / 2 - note_height;
        root.draw(&Text::new(note, (margin, y), label_font.clone()))
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
