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
    let (rgb, _) = render_chart(title, y_label, points, error_floor, size)
        .map_err(|why| Error::file(path, None, why))?;
    write_rgb8(path, width, height, &rgb)
}

/// Where the chart of [`write_error_vs_time_sized`] with these arguments
/// puts its point labels, and what bounds them: the chart is drawn in
/// memory (nothing is written) and its layout returned. An error for a
/// chart below [`MIN_CHART_SIZE`].
pub fn error_vs_time_labels(
    title: &str,
    y_label: &str,
    points: &[ChartPoint],
    error_floor: Option<f64>,
    size: (u32, u32),
) -> Result<ChartLabels> {
    if size.0 < MIN_CHART_SIZE.0 || size.1 < MIN_CHART_SIZE.1 {
        return Err(Error::param(
            "chart size",
            format!(
                "{}×{} is below {}×{}",
                size.0, size.1, MIN_CHART_SIZE.0, MIN_CHART_SIZE.1
            ),
        ));
    }
    let (_, labels) = render_chart(title, y_label, points, error_floor, size)
        .map_err(|why| Error::param("chart", why))?;
    Ok(labels)
}

/// The chart's pixels (8-bit RGB) and its label layout.
fn render_chart(
    title: &str,
    y_label: &str,
    points: &[ChartPoint],
    error_floor: Option<f64>,
    size: (u32, u32),
) -> std::result::Result<(Vec<u8>, ChartLabels), String> {
    register_embedded_font()?;
    let mut rgb = vec![255u8; size.0 as usize * size.1 as usize * 3];
    let labels = draw(&mut rgb, size, title, y_label, points, error_floor)
        .map_err(|why| format!("cannot draw the chart: {why}"))?;
    Ok((rgb, labels))
}

/// A rectangle of chart pixels: columns `x0..x1`, rows `y0..y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LabelBox {
    /// First column.
    pub x0: i32,
    /// First row.
    pub y0: i32,
    /// One past the last column.
    pub x1: i32,
    /// One past the last row.
    pub y1: i32,
}

impl LabelBox {
    /// The box of `size` whose top left is `(x, y)`.
    pub fn at((x, y): (i32, i32), (w, h): (u32, u32)) -> Self {
        LabelBox {
            x0: x,
            y0: y,
            x1: x + w as i32,
            y1: y + h as i32,
        }
    }

    /// Whether the two share a pixel.
    pub fn intersects(&self, other: &LabelBox) -> bool {
        self.x0 < other.x1 && other.x0 < self.x1 && self.y0 < other.y1 && other.y0 < self.y1
    }

    /// Whether every pixel of `self` is in `bounds`.
    pub fn inside(&self, bounds: &LabelBox) -> bool {
        self.x0 >= bounds.x0 && self.y0 >= bounds.y0 && self.x1 <= bounds.x1 && self.y1 <= bounds.y1
    }

    /// The box grown by `d` pixels on every side.
    fn grown(&self, d: i32) -> Self {
        LabelBox {
            x0: self.x0 - d,
            y0: self.y0 - d,
            x1: self.x1 + d,
            y1: self.y1 + d,
        }
    }

    /// The point of the box nearest to `p`.
    fn nearest(&self, (x, y): (i32, i32)) -> (i32, i32) {
        (x.clamp(self.x0, self.x1 - 1), y.clamp(self.y0, self.y1 - 1))
    }
}

/// A label to place next to its marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LabelRequest {
    /// The marker's centre, in pixels.
    pub anchor: (i32, i32),
    /// The label's box size (its text and a pixel of padding), in pixels.
    pub size: (u32, u32),
}

/// Where a chart's labels went.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartLabels {
    /// The chart's size, in pixels.
    pub image: (u32, u32),
    /// The plotting area: every label lies in it.
    pub plot: LabelBox,
    /// The legend's box (labels keep out of it), if there is a legend.
    pub legend: Option<LabelBox>,
    /// The box of each drawn label, in drawing order.
    pub boxes: Vec<LabelBox>,
    /// Labels left out: no place in the plotting area was free of the
    /// others, the legend and the chart's edges (a note under the chart
    /// says how many).
    pub left_out: usize,
}

/// Radius of a point's marker (its Pareto ring), in pixels.
const MARKER_RADIUS: i32 = 8;

/// Places `labels` (in priority order: earlier labels get the better
/// places) inside `bounds`, never overlapping each other or any of
/// `obstacles`: each takes the candidate position, from right of its
/// marker outwards in rings, that covers the fewest markers (`markers`,
/// centres; a marker is a disc of [`MARKER_RADIUS`]) and lies nearest its
/// own; a label with no free position is left out (`None`). Pure and
/// deterministic: the same input gives the same boxes.
pub fn place_labels(
    labels: &[LabelRequest],
    bounds: LabelBox,
    obstacles: &[LabelBox],
    markers: &[(i32, i32)],
) -> Vec<Option<LabelBox>> {
    let marker_boxes: Vec<LabelBox> = markers
        .iter()
        .map(|&(x, y)| LabelBox {
            x0: x - MARKER_RADIUS,
            y0: y - MARKER_RADIUS,
            x1: x + MARKER_RADIUS + 1,
            y1: y + MARKER_RADIUS + 1,
        })
        .collect();
    let mut placed: Vec<LabelBox> = Vec::new();
    let mut out = Vec::with_capacity(labels.len());
    for label in labels {
        let mut best: Option<(u64, LabelBox)> = None;
        for (order, (ring, candidate)) in candidates(label).into_iter().enumerate() {
            if !candidate.inside(&bounds)
                || placed.iter().any(|p| p.intersects(&candidate))
                || obstacles.iter().any(|o| o.intersects(&candidate))
            {
                continue;
            }
            let covered = marker_boxes
                .iter()
                .filter(|m| m.intersects(&candidate))
                .count() as u64;
            // A covered marker costs more than moving a ring out.
            let cost = (covered * 3 + ring as u64 * 2) * 1000 + order as u64;
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, candidate));
            }
        }
        if let Some((_, b)) = best {
            placed.push(b);
        }
        out.push(best.map(|(_, b)| b));
    }
    out
}

/// The positions `label` may take, with their ring: ring 0 right, left,
/// above and below its marker; rings 1 to 16 ever farther out in sixteen
/// directions (drawn with a leader line to the marker).
fn candidates(label: &LabelRequest) -> Vec<(u32, LabelBox)> {
    let (ax, ay) = label.anchor;
    let (w, h) = (label.size.0 as i32, label.size.1 as i32);
    let gap = MARKER_RADIUS + 2;
    let at = |x: i32, y: i32| LabelBox::at((x, y), label.size);
    let mut out = vec![
        (0, at(ax + gap, ay - h - 1)),
        (0, at(ax + gap, ay - h / 2)),
        (0, at(ax + gap, ay + 2)),
        (0, at(ax - gap - w, ay - h - 1)),
        (0, at(ax - gap - w, ay - h / 2)),
        (0, at(ax - gap - w, ay + 2)),
        (0, at(ax - w / 2, ay - gap - h)),
        (0, at(ax - w / 2, ay + gap)),
    ];
    let step = f64::from(h.max(8) + 2);
    for ring in 1..=16u32 {
        let d = f64::from(gap) + f64::from(ring) * step;
        for k in 0..16 {
            let angle = f64::from(k) * std::f64::consts::PI / 8.0;
            let (c, s) = (angle.cos(), -angle.sin());
            // The box's centre, pushed out until the box clears the
            // distance `d` from the marker along the direction.
            let cx = f64::from(ax) + c * (d + f64::from(w) / 2.0);
            let cy = f64::from(ay) + s * (d + f64::from(h) / 2.0);
            let x = (cx - f64::from(w) / 2.0).round() as i32;
            let y = (cy - f64::from(h) / 2.0).round() as i32;
            out.push((ring, at(x, y)));
        }
    }
    out
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

/// The legend's box for `lines` (its entries' texts) in `font` at
/// `corner` of the plotting area `plot`: plotters' own layout (entries
/// 1.25 lines apart, a 30-pixel sample area, a 10-pixel margin, 5 pixels
/// from the corner's edges), so that a box drawn at its top left is
/// exactly this one.
fn legend_box(
    lines: &[String],
    font: &FontDesc,
    plot: &LabelBox,
    corner: usize,
) -> Option<LabelBox> {
    const AREA: i32 = 30;
    const MARGIN: i32 = 10;
    let (mut w, mut h) = (0, 0);
    for (i, line) in lines.iter().enumerate() {
        let y = (f64::from(i as u32) * font.get_size() * 1.25).round() as i32;
        let (dx, dy) = font.box_size(line).ok()?;
        w = w.max(dx as i32);
        h = h.max(y + dy as i32);
    }
    let (w, h) = (w + AREA + 2 * MARGIN, h + 2 * MARGIN);
    let (pw, ph) = (plot.x1 - plot.x0, plot.y1 - plot.y0);
    let (x, y) = match corner {
        0 => (pw - w - 5, 5),
        1 => (5, 5),
        2 => (pw - w - 5, ph - h - 5),
        _ => (5, ph - h - 5),
    };
    Some(LabelBox::at(
        (plot.x0 + x, plot.y0 + y),
        (w.max(0) as u32, h.max(0) as u32),
    ))
}

/// Draws the chart into `rgb` (`size`, 3 bytes per pixel); returns where
/// its labels went.
fn draw(
    rgb: &mut [u8],
    size: (u32, u32),
    title: &str,
    y_label: &str,
    points: &[ChartPoint],
    error_floor: Option<f64>,
) -> std::result::Result<ChartLabels, String> {
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
    // Room for one line of notes (log-axis floors, labels left out).
    let note_height = tick + 6;
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
    let (xs, ys) = chart.plotting_area().get_pixel_range();
    let plot = LabelBox {
        x0: xs.start,
        y0: ys.start,
        x1: xs.end,
        y1: ys.end,
    };

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
    let staircase = front_staircase(&placed);
    if let Some(path) = staircase.clone() {
        chart
            .draw_series(DashedLineSeries::new(path, 5, 5, BLACK.stroke_width(1)))
            .map_err(|e| err(&e))?
            .label("Pareto front")
            .legend(|(x, y)| {
                EmptyElement::at((x + 12, y)) + Circle::new((0, 0), 7, BLACK.stroke_width(2))
            });
    }

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
        chart
            .draw_series(curve.iter().map(move |p| {
                let ring = if p.front {
                    BLACK.to_rgba()
                } else {
                    TRANSPARENT
                };
                EmptyElement::at((p.x, p.y))
                    + Circle::new((0, 0), MARKER_RADIUS as u32, ring.stroke_width(2))
                    + Circle::new((0, 0), 4, colour.filled())
            }))
            .map_err(|e| err(&e))?;
    }

    let label_font = ("sans-serif", tick)
        .into_font()
        .color(&RGBColor(40, 40, 40));
    if placed.is_empty() {
        let centre = (
            (x_range.start * x_range.end).sqrt(),
            (y_range.start * y_range.end).sqrt(),
        );
        let font = label_font.clone().pos(Pos::new(HPos::Center, VPos::Center));
        chart
            .draw_series([Text::new("no finite points to plot", centre, font)])
            .map_err(|e| err(&e))?;
    }

    // The legend (an empty one would be an empty box) in the corner whose
    // box covers the fewest markers (ties: upper right, upper left, lower
    // right, lower left), at the box computed for it.
    let markers: Vec<(i32, i32)> = placed
        .iter()
        .map(|p| chart.backend_coord(&(p.x, p.y)))
        .collect();
    let entries: Vec<String> = (floor_line.map(|_| "reference noise floor".to_string()))
        .into_iter()
        .chain(staircase.as_ref().map(|_| "Pareto front".to_string()))
        .chain(curves.iter().map(|(t, _)| t.to_string()))
        .collect();
    let legend_font = FontDesc::new(FontFamily::SansSerif, f64::from(tick), FontStyle::Normal);
    let legend = match entries.is_empty() {
        true => None,
        false => (0..4)
            .filter_map(|corner| legend_box(&entries, &legend_font, &plot, corner))
            .min_by_key(|b| {
                let near = b.grown(MARKER_RADIUS);
                markers
                    .iter()
                    .filter(|&&(x, y)| near.intersects(&LabelBox::at((x, y), (1, 1))))
                    .count()
            }),
    };
    if let Some(b) = legend {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::Coordinate(
                b.x0 - plot.x0,
                b.y0 - plot.y0,
            ))
            .label_font(("sans-serif", tick))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()
            .map_err(|e| err(&e))?;
    }

    // The labels: the Pareto front's first, then by curve; each in a
    // place no other label, the legend or the plot's edges take.
    let order: Vec<usize> = (0..placed.len())
        .filter(|&i| placed[i].front)
        .chain((0..placed.len()).filter(|&i| !placed[i].front))
        .collect();
    let pad = 1;
    let requests: Vec<LabelRequest> = order
        .iter()
        .map(|&i| {
            let (w, h) = label_font.font.box_size(&placed[i].label).unwrap_or((0, 0));
            LabelRequest {
                anchor: markers[i],
                size: (w + 2 * pad, h + 2 * pad),
            }
        })
        .collect();
    let obstacles: Vec<LabelBox> = legend.iter().map(|b| b.grown(2)).collect();
    let boxes = place_labels(&requests, plot, &obstacles, &markers);
    let font = label_font.pos(Pos::new(HPos::Left, VPos::Top));
    let mut drawn = Vec::new();
    for ((&i, request), b) in order.iter().zip(&requests).zip(&boxes) {
        let Some(b) = b else { continue };
        let (ax, ay) = request.anchor;
        let (nx, ny) = b.nearest((ax, ay));
        let (dx, dy) = (nx - ax, ny - ay);
        if dx * dx + dy * dy > (MARKER_RADIUS + 6).pow(2) {
            // A label moved away from its marker: a leader line to it,
            // from the marker's ring.
            let len = f64::from(dx * dx + dy * dy).sqrt();
            let r = f64::from(MARKER_RADIUS) / len;
            let from = (
                ax + (f64::from(dx) * r).round() as i32,
                ay + (f64::from(dy) * r).round() as i32,
            );
            root.draw(&PathElement::new(
                vec![from, (nx, ny)],
                RGBColor(150, 150, 150).stroke_width(1),
            ))
            .map_err(|e| err(&e))?;
        }
        root.draw(&Text::new(
            placed[i].label.clone(),
            (b.x0 + pad as i32, b.y0 + pad as i32),
            font.clone(),
        ))
        .map_err(|e| err(&e))?;
        drawn.push(*b);
    }
    let left_out = boxes.iter().filter(|b| b.is_none()).count();

    let notes: Vec<String> = note
        .into_iter()
        .chain((left_out > 0).then(|| {
            format!(
                "{left_out} point label{} left out for want of room (results.md lists every run)",
                if left_out == 1 { "" } else { "s" }
            )
        }))
        .collect();
    if !notes.is_empty() {
        let y = size.1 as i32 - margin / 2 - note_height;
        root.draw(&Text::new(
            notes.join("; "),
            (margin, y),
            label_font.clone(),
        ))
        .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(ChartLabels {
        image: size,
        plot,
        legend,
        boxes: drawn,
        left_out,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disjoint_inside(boxes: &[LabelBox], bounds: &LabelBox, obstacles: &[LabelBox]) {
        for (i, a) in boxes.iter().enumerate() {
            assert!(a.inside(bounds), "{a:?} outside {bounds:?}");
            assert!(
                !obstacles.iter().any(|o| o.intersects(a)),
                "{a:?} on an obstacle"
            );
            for b in &boxes[i + 1..] {
                assert!(!a.intersects(b), "{a:?} and {b:?} overlap");
            }
        }
    }

    #[test]
    fn boxes_intersect_only_when_they_share_a_pixel() {
        let a = LabelBox::at((0, 0), (10, 5));
        assert!(a.intersects(&LabelBox::at((9, 4), (3, 3))));
        assert!(
            !a.intersects(&LabelBox::at((10, 0), (3, 3))),
            "edge to edge"
        );
        assert!(!a.intersects(&LabelBox::at((0, 5), (3, 3))));
        assert!(a.inside(&LabelBox::at((0, 0), (10, 5))));
        assert!(!a.inside(&LabelBox::at((1, 0), (10, 5))));
    }

    /// Deliberately clustered points: thirty labels on markers a few
    /// pixels apart, a legend beside them and the plot's edge near: every
    /// label placed is clear of the others, the legend and the edges; most
    /// find a place, and the same input places them the same way.
    #[test]
    fn clustered_labels_never_overlap() {
        let bounds = LabelBox::at((100, 50), (600, 400));
        let legend = LabelBox::at((460, 60), (230, 150));
        let markers: Vec<(i32, i32)> = (0..30)
            .map(|i| (440 + (i % 6) * 3, 120 + (i / 6) * 2))
            .collect();
        let labels: Vec<LabelRequest> = (0..30)
            .map(|i| LabelRequest {
                anchor: markers[i],
                size: (40 + (i as u32 % 4) * 15, 17),
            })
            .collect();
        let placed = place_labels(&labels, bounds, &[legend], &markers);
        assert_eq!(placed.len(), labels.len());
        let boxes: Vec<LabelBox> = placed.iter().flatten().copied().collect();
        disjoint_inside(&boxes, &bounds, &[legend]);
        assert!(boxes.len() >= 25, "{} of 30 placed", boxes.len());
        assert_eq!(placed, place_labels(&labels, bounds, &[legend], &markers));
        // A lone label takes the place right of its marker.
        let one = place_labels(&labels[..1], bounds, &[], &markers[..1]);
        let b = one[0].expect("placed");
        assert!(b.x0 > markers[0].0 && b.y1 <= markers[0].1, "{b:?}");
        // Against the right edge, it goes left of its marker.
        let edge = LabelRequest {
            anchor: (bounds.x1 - 5, 200),
            size: (60, 17),
        };
        let b = place_labels(&[edge], bounds, &[], &[edge.anchor])[0].expect("placed");
        assert!(b.x1 <= edge.anchor.0 && b.inside(&bounds), "{b:?}");
        // No room at all: left out, never forced over another.
        let tiny = LabelBox::at((0, 0), (50, 20));
        let crowd = [LabelRequest {
            anchor: (25, 10),
            size: (45, 15),
        }; 3];
        let placed = place_labels(&crowd, tiny, &[], &[(25, 10)]);
        let boxes: Vec<LabelBox> = placed.iter().flatten().copied().collect();
        disjoint_inside(&boxes, &tiny, &[]);
        assert!(boxes.len() < 3);
    }

    /// The same on a drawn chart: points of several techniques bunched at
    /// one spot (the labels as drawn, with the real font and legend).
    #[test]
    fn a_chart_of_clustered_points_has_disjoint_labels() {
        let mut points = Vec::new();
        for (t, technique) in ["dcs", "dcs centre", "reference", "shadow-map"]
            .iter()
            .enumerate()
        {
            for k in 0..8 {
                points.push(ChartPoint {
                    technique: technique.to_string(),
                    label: format!("{} spp, setting {t}", 4 << k),
                    seconds: 0.1 * (1.0 + 0.01 * f64::from(k) + 0.003 * t as f64),
                    error: 0.02 * (1.0 - 0.01 * f64::from(k) + 0.002 * t as f64),
                });
            }
        }
        // One far point, so the cluster is small on the axes.
        points.push(ChartPoint {
            technique: "reference".into(),
            label: "4096 spp".into(),
            seconds: 30.0,
            error: 1e-4,
        });
        for size in [CHART_SIZE, MIN_CHART_SIZE] {
            let labels = error_vs_time_labels("t", "error", &points, Some(1e-3), size).unwrap();
            let image = LabelBox::at((0, 0), size);
            assert!(labels.plot.inside(&image));
            let legend: Vec<LabelBox> = labels.legend.into_iter().collect();
            disjoint_inside(&labels.boxes, &labels.plot, &legend);
            assert_eq!(labels.boxes.len() + labels.left_out, points.len());
            if size == CHART_SIZE {
                assert!(labels.boxes.len() >= 20, "{labels:?}");
            }
        }
    }
}
