//! A progressive render's pictures from plain data: the convergence
//! curve (chart and CSV) and the preview's pixels (the mean image beside
//! its error heat map). The live observer that calls them is
//! `crate::render`'s (report does not depend on render).

use super::heatmap::{heatmap_colour, HEATMAP_BACKGROUND};
use crate::error::{Error, Result};
use crate::output::write_rgb8;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use std::path::Path;

/// One set's point on the convergence curve.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SetPoint {
    /// Light samples per pixel and light so far.
    pub samples: u64,
    /// Seconds since the first set started.
    pub seconds: f64,
    /// The estimated radiance RMSE of the mean so far (none after one set).
    pub error: Option<f64>,
}

/// The preview's pixels: the mean image (8-bit sRGB) on the left and the
/// per-pixel error heat map on the right, scaled so the 99th percentile of
/// the shading points' errors is the brightest colour (a pixel's error is
/// far above the image's RMSE in a penumbra, so the target would
/// saturate it).
pub fn preview_bytes(width: u32, image: &[u8], error: &[f32], surface: &[bool]) -> Vec<u8> {
    let scale = error_scale(error, surface);
    let w = width as usize;
    let mut out = Vec::with_capacity(image.len() * 2);
    for (y, row) in image.chunks(3 * w).enumerate() {
        out.extend_from_slice(row);
        for x in 0..w {
            let i = y * w + x;
            out.extend(match surface.get(i) {
                Some(true) => heatmap_colour(error[i], scale),
                _ => HEATMAP_BACKGROUND,
            });
        }
    }
    out
}

/// The 99th percentile of the errors at shading points (0 if none).
pub fn error_scale(error: &[f32], surface: &[bool]) -> f32 {
    let mut e: Vec<f32> = (error.iter().zip(surface))
        .filter(|(e, s)| **s && e.is_finite())
        .map(|(e, _)| *e)
        .collect();
    if e.is_empty() {
        return 0.0;
    }
    let k = (e.len() * 99 / 100).min(e.len() - 1);
    *e.select_nth_unstable_by(k, f32::total_cmp).1
}

/// The convergence curve as CSV: one row per set.
pub fn convergence_csv(curve: &[SetPoint]) -> String {
    let mut out = String::from("set,samples,seconds,estimated_rmse\n");
    for (k, p) in curve.iter().enumerate() {
        let e = p.error.map_or(String::new(), |e| format!("{e:e}"));
        out.push_str(&format!("{},{},{},{e}\n", k + 1, p.samples, p.seconds));
    }
    out
}

/// Size of the convergence chart, in pixels.
pub const CONVERGENCE_CHART_SIZE: (u32, u32) = (900, 600);

/// Writes a progressive render's convergence as a log-log chart (PNG):
/// the estimated radiance RMSE after each set against the light samples,
/// the Monte Carlo rate (error ∝ samples^−½, through the first estimate)
/// as a dashed line, and the target as a horizontal line. Atomic. The
/// axes are the samples, not the time, so the chart has the same bits on
/// every machine (the title gives the time).
pub fn write_convergence_chart(
    path: &Path,
    title: &str,
    curve: &[SetPoint],
    target: Option<f64>,
) -> Result<()> {
    let (w, h) = CONVERGENCE_CHART_SIZE;
    let mut rgb = vec![255u8; (w * h * 3) as usize];
    draw_convergence(&mut rgb, title, curve, target)
        .map_err(|e| Error::file(path, None, format!("cannot draw the chart: {e}")))?;
    write_rgb8(path, w, h, &rgb)
}

fn draw_convergence(
    rgb: &mut [u8],
    title: &str,
    curve: &[SetPoint],
    target: Option<f64>,
) -> std::result::Result<(), String> {
    super::chart::register_embedded_font()?;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    // Drawn in log10 units on linear axes, so every tick is labelled with
    // its value (plotters' log axes label only whole decades).
    let points: Vec<(f64, f64)> = (curve.iter())
        .filter_map(|p| {
            let e = p.error.filter(|e| e.is_finite() && *e > 0.0)?;
            Some(((p.samples as f64).log10(), e.log10()))
        })
        .collect();
    let root = BitMapBackend::with_buffer(rgb, CONVERGENCE_CHART_SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let fold = |v: &mut dyn Iterator<Item = f64>| {
        v.fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)))
    };
    let (x0, x1) = fold(&mut points.iter().map(|p| p.0));
    let (y0, y1) = fold(&mut points.iter().map(|p| p.1).chain(target.map(f64::log10)));
    let (x0, x1, y0, y1) = if points.is_empty() {
        (0.0, 3.0, -3.0, -1.0)
    } else {
        (x0 - 0.1, x1 + 0.1, y0 - 0.1, y1 + 0.1)
    };
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("light samples per pixel (log scale)")
        .y_desc("estimated radiance RMSE (log scale)")
        .axis_desc_style(("sans-serif", 16))
        .label_style(("sans-serif", 14))
        .x_labels(10)
        .y_labels(10)
        .x_label_formatter(&|v| format!("{:.0}", 10f64.powf(*v)))
        .y_label_formatter(&|v| format!("{:.2e}", 10f64.powf(*v)))
        .light_line_style(WHITE)
        .bold_line_style(RGBColor(225, 225, 225))
        .draw()
        .map_err(|e| err(&e))?;
    if let Some(t) = target.map(f64::log10) {
        let grey = RGBColor(90, 90, 90);
        chart
            .draw_series(LineSeries::new([(x0, t), (x1, t)], grey.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(format!("target {:.1e}", 10f64.powf(t)))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], grey.stroke_width(2)));
    }
    if let Some(&(s0, e0)) = points.first() {
        // Monte Carlo: error ∝ samples^−½, a line of slope −½ here.
        let rate = |s: f64| e0 - 0.5 * (s - s0);
        let black = RGBColor(40, 40, 40);
        chart
            .draw_series(DashedLineSeries::new(
                [(x0, rate(x0)), (x1, rate(x1))],
                8,
                6,
                black.stroke_width(1),
            ))
            .map_err(|e| err(&e))?
            .label("samples^-1/2 through the first estimate")
            .legend(move |(x, y)| {
                DashedPathElement::new([(x, y), (x + 24, y)], 6, 4, black.stroke_width(1))
            });
    }
    let blue = RGBColor(0, 114, 178);
    chart
        .draw_series(LineSeries::new(
            points.iter().copied(),
            blue.stroke_width(2),
        ))
        .map_err(|e| err(&e))?
        .label("estimated RMSE after each set")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], blue.stroke_width(2)));
    chart
        .draw_series(points.iter().map(|&p| Circle::new(p, 4, blue.filled())))
        .map_err(|e| err(&e))?;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(200, 200, 200))
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preview_puts_the_heat_map_beside_the_image() {
        let image = [10u8, 20, 30, 40, 50, 60];
        let bytes = preview_bytes(2, &image, &[0.0, 1.0], &[true, false]);
        assert_eq!(bytes.len(), 12);
        assert_eq!(&bytes[..6], &image);
        assert_eq!(&bytes[6..9], &heatmap_colour(0.0, 0.0));
        assert_eq!(&bytes[9..], &HEATMAP_BACKGROUND);
    }
}
