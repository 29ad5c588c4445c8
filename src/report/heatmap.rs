//! Error heat maps: where in the image a technique departs from the
//! reference, and by how much.

use crate::error::{Error, Result};
use crate::output::{check_size, write_rgb8};
use plotters::style::colors::colormaps::ViridisRGB;
use std::path::Path;

/// Colour of background pixels (`valid == false`): a grey that viridis
/// never produces.
pub const HEATMAP_BACKGROUND: [u8; 3] = [128, 128, 128];
/// Colour of non-finite errors: a magenta that viridis never produces.
pub const HEATMAP_NON_FINITE: [u8; 3] = [255, 0, 255];

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
    // `t` is finite and in [0, 1], the only input the colour map accepts
    // without panicking.
    let c = ViridisRGB::get_color(t);
    [c.0, c.1, c.2]
}

/// Writes |error| per pixel as a colour-mapped PNG (perceptual map such as viridis/inferno, 0 → dark, >= `scale` → brightest), pixels with `valid[i] == false` (background) in neutral grey, non-finite errors in magenta. Atomic write.
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
    scale: f32,
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
                heatmap_colour(e, scale)
            } else {
                HEATMAP_BACKGROUND
            }
        })
        .collect();
    write_rgb8(path, width, height, &bytes)
}
