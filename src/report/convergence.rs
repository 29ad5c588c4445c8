//! Live progress of a progressive render: one line with the sets done,
//! the current error estimate and the time left (on a terminal), and on
//! request a preview PNG rewritten every few seconds: the current mean
//! image beside its error heat map.

use super::heatmap::{heatmap_colour, HEATMAP_BACKGROUND};
use super::progress::format_duration;
use crate::observe::{Cancel, Observer};
use crate::output::{srgb8, write_rgb8, write_stderr};
use crate::render::SetStatus;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Least time between two preview writes.
pub const PREVIEW_EVERY: Duration = Duration::from_secs(2);

/// The observer of a progressive render on the command line.
pub struct ConvergenceProgress {
    bar: ProgressBar,
    preview: Option<PathBuf>,
    /// When the preview was last written (none yet).
    last_preview: Mutex<Option<Instant>>,
    cancel: Cancel,
}

impl ConvergenceProgress {
    /// A reporter that draws on stderr when it is a terminal and
    /// `enabled`, and writes `preview` (if any) as the sets finish.
    pub fn new(enabled: bool, preview: Option<PathBuf>) -> Self {
        let target = if enabled && std::io::stderr().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        };
        let bar = ProgressBar::with_draw_target(None, target);
        if let Ok(style) = ProgressStyle::with_template("{elapsed:>4} {spinner} {msg}") {
            bar.set_style(style);
        }
        bar.enable_steady_tick(Duration::from_millis(250));
        bar.set_message("first sample set");
        ConvergenceProgress {
            bar,
            preview,
            last_preview: Mutex::new(None),
            cancel: Cancel::new(),
        }
    }

    /// Clears the line.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }

    fn write_preview(&self, status: &SetStatus<'_>, last: bool) {
        let Some(path) = &self.preview else {
            return;
        };
        let Ok(mut when) = self.last_preview.lock() else {
            return;
        };
        if !last && when.is_some_and(|t| t.elapsed() < PREVIEW_EVERY) {
            return;
        }
        *when = Some(Instant::now());
        let (w, h) = status.size;
        let bytes = preview_bytes(
            w,
            &srgb8(&status.mean_radiance()),
            &status.error_map(),
            status.surface(),
            status.target_error,
        );
        // A preview that cannot be written does not stop the render.
        if let Err(e) = write_rgb8(path, 2 * w, h, &bytes) {
            write_stderr(&format!("penumbra: warning: preview: {e}\n"));
        }
    }
}

/// The preview's pixels: the mean image (8-bit sRGB) on the left and the
/// per-pixel error heat map on the right, scaled so the target error (or,
/// without one, the largest error) is the brightest colour.
pub fn preview_bytes(
    width: u32,
    image: &[u8],
    error: &[f32],
    surface: &[bool],
    target: Option<f64>,
) -> Vec<u8> {
    let scale = target.map_or_else(
        || error.iter().copied().fold(0.0f32, f32::max),
        |t| t as f32,
    );
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

impl Observer for ConvergenceProgress {
    fn stage(&self, name: &str) {
        if name != "shadows" {
            self.bar.set_message(name.to_string());
        }
    }

    fn cancelled(&self) -> bool {
        self.cancel.is_cancelled()
    }

    fn set_done(&self, status: &SetStatus<'_>) {
        let error = match (status.error, status.target_error) {
            (Some(e), Some(t)) => format!("est. RMSE {e:.2e} (target {t:.2e})"),
            (Some(e), None) => format!("est. RMSE {e:.2e}"),
            (None, _) => "est. RMSE after the second set".to_string(),
        };
        let left = status
            .time_left
            .map_or(String::new(), |t| format!(", ~{} left", format_duration(t)));
        self.bar.set_message(format!(
            "{} sets, {} spp, {error}{left}",
            status.sets, status.samples
        ));
        self.write_preview(status, status.last);
    }
}

impl Drop for ConvergenceProgress {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preview_puts_the_heat_map_beside_the_image() {
        let image = [10u8, 20, 30, 40, 50, 60];
        let bytes = preview_bytes(2, &image, &[0.0, 1.0], &[true, false], Some(1.0));
        assert_eq!(bytes.len(), 12);
        assert_eq!(&bytes[..6], &image);
        assert_eq!(&bytes[6..9], &heatmap_colour(0.0, 1.0));
        assert_eq!(&bytes[9..], &HEATMAP_BACKGROUND);
    }
}
