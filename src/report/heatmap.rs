//! Error heat maps: where in the image a technique departs from the
//! reference, and by how much. Every heat map carries its colour scale: a
//! colour bar under the image, with tick values and the quantity and unit
//! its caller names ([`HeatmapScale`]); the image's own pixels stay 1:1.

use super::chart::{register_embedded_font, tick_label};
use crate::error::{Error, Result};
use crate::output::{check_size, write_rgb8};
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// Colour of background pixels (`valid == false`): a grey that viridis
/// never produces.
pub const HEATMAP_BACKGROUND: [u8; 3] = [128, 128, 128];
/// Colour of non-finite errors: a magenta that viridis never produces.
pub const HEATMAP_NON_FINITE: [u8; 3] = [255, 0, 255];

/// Height of the band under a heat map that holds its colour bar, in
/// pixels.
pub const COLOUR_BAR_BAND: u32 = 64;

/// The narrowest heat map canvas: a narrower image gets a canvas this
/// wide (white right of it), so that the bar's ticks and caption fit.
pub const MIN_HEATMAP_WIDTH: u32 = 400;

/// Margin left and right of the bar, and of the caption.
const MARGIN: u32 = 8;
/// The caption's and the tick labels' size, in pixels.
const TEXT: u32 = 13;
/// Where in the band the caption, the bar and the ticks are (rows from
/// the band's top).
const CAPTION_Y: u32 = 5;
const BAR_Y: (u32, u32) = (24, 38);
const TICK_LENGTH: u32 = 4;

/// What a heat map shows, for its colour bar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeatmapScale<'a> {
    /// The quantity mapped, e.g. `|ΔVcoef| light 0` or `FLIP error`.
    pub quantity: &'a str,
    /// Its unit, e.g. `unitless` or `W/(m²·sr)`.
    pub unit: &'a str,
    /// The value shown brightest: the bar runs from 0 to it, and larger
    /// values show as it (its tick says `≥`).
    pub max: f32,
}

impl HeatmapScale<'_> {
    /// The caption under the map: the quantity and its unit.
    pub fn caption(&self) -> String {
        format!("{} ({})", self.quantity, self.unit)
    }

    /// The bar's ticks: fractions along it and their labels. 0, a
    /// quarter, half, three quarters and the top (marked `≥`: larger
    /// values show as it); a scale that is not a positive finite number
    /// has 0 and `> 0` only (every non-zero value shows brightest).
    pub fn ticks(&self) -> Vec<(f64, String)> {
        let max = f64::from(self.max);
        if !(max > 0.0 && max.is_finite()) {
            return vec![(0.0, "0".into()), (1.0, "> 0".into())];
        }
        (0..=4)
            .map(|k| {
                let t = f64::from(k) / 4.0;
                let label = tick_label(t * max);
                (
                    t,
                    if k == 4 {
                        format!("≥ {label}")
                    } else {
                        label
                    },
                )
            })
            .collect()
    }
}

/// The heat-map colour of one `|error|` at `scale`: viridis from dark
/// purple at 0 to yellow at `>= scale`, [`HEATMAP_NON_FINITE`] for NaN or
/// infinite errors. A `scale` that is not a positive finite number maps
/// every non-zero error to yellow (the limit of a tiny scale).
pub fn heatmap_colour(error: f32, scale: f32) -> [u8; 3] {
    if !error.is_finite() {
        return HEATMAP_NON_FINITE;
    }
    let e = f64::from(error).abs();
    let s = f64::from(scale);
    let t = if s > 0.0 && s.is_finite() {
        (e / s).min(1.0)
    } else if e > 0.0 {
        1.0
    } else {
        0.0
    };
    viridis(t)
}

/// Viridis at `t` in [0, 1] (clamped; NaN as 0).
fn viridis(t: f64) -> [u8; 3] {
    // `t` is finite and in [0, 1], the only input the colour map accepts
    // without panicking.
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let c = ViridisRGB::get_color(t);
    [c.0, c.1, c.2]
}

/// The canvas a `width × height` heat map is written on: at least
/// [`MIN_HEATMAP_WIDTH`] wide, and [`COLOUR_BAR_BAND`] taller than the
/// image (the bar's band below it).
pub fn heatmap_canvas(width: u32, height: u32) -> (u32, u32) {
    (
        width.max(MIN_HEATMAP_WIDTH),
        height.saturating_add(COLOUR_BAR_BAND),
    )
}

/// Where the colour bar's gradient is on the canvas of a `width ×
/// height` heat map: columns `x0..x1` and rows `y0..y1`. Column `x0`
/// shows 0, column `x1 - 1` the scale's top, linearly between.
pub fn colour_bar_rect(width: u32, height: u32) -> (u32, u32, u32, u32) {
    let (canvas, _) = heatmap_canvas(width, height);
    (MARGIN, height + BAR_Y.0, canvas - MARGIN, height + BAR_Y.1)
}

/// Writes |error| per pixel as a colour-mapped PNG (viridis, 0 → dark,
/// `scale.max` and above → brightest), pixels with `valid[i] == false`
/// (background) in neutral grey, non-finite errors in magenta, with the
/// colour bar of `scale` under the image ([`write_with_colour_bar`]: the
/// PNG is [`heatmap_canvas`]). Atomic write.
///
/// Colours are [`heatmap_colour`], [`HEATMAP_BACKGROUND`] and
/// [`HEATMAP_NON_FINITE`]. `error` and `valid` must each hold
/// `width × height` values (row-major, row 0 at the top); otherwise nothing
/// is written and the error names `path`.
pub fn write_error_heatmap(
    path: &Path,
    width: u32,
    height: u32,
    error: &[f32],
    valid: &[bool],
    scale: &HeatmapScale,
) -> Result<()> {
    check_size(path, width, height, error.len(), "error")?;
    if valid.len() != error.len() {
        return Err(Error::file(
            path,
            None,
            format!(
                "the validity mask has {} values, the error has {}",
                valid.len(),
                error.len()
            ),
        ));
    }
    let bytes: Vec<u8> = error
        .iter()
        .zip(valid)
        .flat_map(|(&e, &v)| {
            if v {
                heatmap_colour(e, scale.max)
            } else {
                HEATMAP_BACKGROUND
            }
        })
        .collect();
    let keys = [
        (HEATMAP_BACKGROUND, "no surface"),
        (HEATMAP_NON_FINITE, "not finite"),
    ];
    write_with_colour_bar(path, width, height, &bytes, &viridis, scale, &keys)
}

/// Writes `rgb` (`width × height` pixels of a colour map, 8-bit RGB) as a
/// PNG with its colour bar below: `colour(t)` for `t` from 0 to 1 along
/// the bar, the ticks and caption of `scale`, and a swatch per colour of
/// `keys` that the map uses outside its scale (e.g. grey for
/// background). The image's pixels are copied 1:1 into the top left of
/// the canvas ([`heatmap_canvas`]; white elsewhere). Atomic write.
pub fn write_with_colour_bar(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[u8],
    colour: &dyn Fn(f64) -> [u8; 3],
    scale: &HeatmapScale,
    keys: &[([u8; 3], &str)],
) -> Result<()> {
    check_size(path, width, height, rgb.len() / 3, "colour")?;
    if !rgb.len().is_multiple_of(3) {
        return Err(Error::file(path, None, "the colours are not RGB triples"));
    }
    let canvas = draw_with_colour_bar(width, height, rgb, colour, scale, keys)
        .map_err(|why| Error::file(path, None, format!("cannot draw the colour bar: {why}")))?;
    let (w, h) = heatmap_canvas(width, height);
    write_rgb8(path, w, h, &canvas)
}

/// The canvas of [`write_with_colour_bar`], 8-bit RGB.
fn draw_with_colour_bar(
    width: u32,
    height: u32,
    rgb: &[u8],
    colour: &dyn Fn(f64) -> [u8; 3],
    scale: &HeatmapScale,
    keys: &[([u8; 3], &str)],
) -> std::result::Result<Vec<u8>, String> {
    register_embedded_font()?;
    let (w, h) = heatmap_canvas(width, height);
    let mut canvas = vec![255u8; w as usize * h as usize * 3];
    let row = width as usize * 3;
    for y in 0..height as usize {
        let at = y * w as usize * 3;
        canvas[at..at + row].copy_from_slice(&rgb[y * row..(y + 1) * row]);
    }
    let (x0, y0, x1, y1) = colour_bar_rect(width, height);
    let span = f64::from((x1 - x0).max(2) - 1);
    for x in x0..x1 {
        let c = colour(f64::from(x - x0) / span);
        for y in y0..y1 {
            let at = (y as usize * w as usize + x as usize) * 3;
            canvas[at..at + 3].copy_from_slice(&c);
        }
    }
    let font = ("sans-serif", TEXT)
        .into_font()
        .color(&RGBColor(40, 40, 40));
    {
        let root = BitMapBackend::with_buffer(&mut canvas, (w, h)).into_drawing_area();
        let err = |e: &dyn std::fmt::Display| e.to_string();
        let dark = RGBColor(40, 40, 40);
        let (x0, y0, x1, y1) = (x0 as i32, y0 as i32, x1 as i32, y1 as i32);
        root.draw(&Rectangle::new(
            [(x0 - 1, y0 - 1), (x1, y1)],
            dark.stroke_width(1),
        ))
        .map_err(|e| err(&e))?;
        for (t, label) in scale.ticks() {
            let x = x0 + (t * span).round() as i32;
            root.draw(&PathElement::new(
                vec![(x, y1), (x, y1 + TICK_LENGTH as i32)],
                dark.stroke_width(1),
            ))
            .map_err(|e| err(&e))?;
            let anchor = match t {
                t if t <= 0.0 => HPos::Left,
                t if t >= 1.0 => HPos::Right,
                _ => HPos::Center,
            };
            let font = font.pos(Pos::new(anchor, VPos::Top));
            root.draw(&Text::new(label, (x, y1 + TICK_LENGTH as i32 + 1), font))
                .map_err(|e| err(&e))?;
        }
        let top = (height + CAPTION_Y) as i32;
        let caption = scale.caption();
        root.draw(&Text::new(
            caption.clone(),
            (MARGIN as i32, top),
            font.clone(),
        ))
        .map_err(|e| err(&e))?;
        // The keys right-aligned on the caption's line, where they fit.
        let caption_end = MARGIN as i32 + text_width(&font, &caption) as i32;
        let mut right = w as i32 - MARGIN as i32;
        for (c, name) in keys.iter().rev() {
            let needed = 12 + 4 + text_width(&font, name) as i32;
            if right - needed < caption_end + 12 {
                break;
            }
            let left = right - needed;
            root.draw(&Rectangle::new(
                [(left, top + 1), (left + 11, top + 12)],
                RGBColor(c[0], c[1], c[2]).filled(),
            ))
            .map_err(|e| err(&e))?;
            root.draw(&Rectangle::new(
                [(left, top + 1), (left + 11, top + 12)],
                dark.stroke_width(1),
            ))
            .map_err(|e| err(&e))?;
            root.draw(&Text::new(name.to_string(), (left + 16, top), font.clone()))
                .map_err(|e| err(&e))?;
            right = left - 12;
        }
        root.present().map_err(|e| err(&e))?;
    }
    // Drawing stays in the band: the image's pixels are as given.
    for y in 0..height as usize {
        let at = y * w as usize * 3;
        canvas[at..at + row].copy_from_slice(&rgb[y * row..(y + 1) * row]);
    }
    Ok(canvas)
}

/// The width of `text` in `font`, in pixels (0 when it cannot be
/// measured).
fn text_width(font: &TextStyle, text: &str) -> u32 {
    font.font.box_size(text).map_or(0, |(w, _)| w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_span_the_scale_and_mark_its_top() {
        let scale = HeatmapScale {
            quantity: "|ΔVcoef|",
            unit: "unitless",
            max: 0.25,
        };
        let ticks = scale.ticks();
        let labels: Vec<&str> = ticks.iter().map(|(_, l)| l.as_str()).collect();
        assert_eq!(labels, ["0", "0.0625", "0.125", "0.188", "≥ 0.25"]);
        assert_eq!(ticks.first().map(|t| t.0), Some(0.0));
        assert_eq!(ticks.last().map(|t| t.0), Some(1.0));
        assert_eq!(scale.caption(), "|ΔVcoef| (unitless)");
        for max in [0.0, f32::NAN, f32::INFINITY, -1.0] {
            let ticks = HeatmapScale { max, ..scale }.ticks();
            assert_eq!(ticks.len(), 2, "{max}");
        }
    }

    #[test]
    fn the_bar_lies_in_the_band_under_the_image() {
        for (w, h) in [(4, 2), (64, 48), (1024, 768)] {
            let (cw, ch) = heatmap_canvas(w, h);
            let (x0, y0, x1, y1) = colour_bar_rect(w, h);
            assert!(cw >= w && ch == h + COLOUR_BAR_BAND);
            assert!(y0 > h && y1 <= ch && x0 < x1 && x1 <= cw, "{w}×{h}");
        }
    }
}
