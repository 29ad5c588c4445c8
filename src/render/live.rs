//! The live observer of a progressive render on the command line: one
//! line with the sets done, the current error estimate and the time left
//! (on a terminal), and on request a preview PNG rewritten every few
//! seconds. Here and not in `report`, which takes plain data and never
//! depends on render.

use super::SetStatus;
use crate::observe::{Cancel, Observer};
use crate::output::{srgb8, write_rgb8, write_stderr};
use crate::report::convergence::preview_bytes;
use crate::report::format_duration;
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
        );
        // A preview that cannot be written does not stop the render.
        if let Err(e) = write_rgb8(path, 2 * w, h, &bytes) {
            write_stderr(&format!("penumbra: warning: preview: {e}\n"));
        }
    }
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
