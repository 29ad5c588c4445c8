//! A progress bar on stderr that appears only for work longer than a
//! second and only when stderr is a terminal.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Delay before the bar shows: short renders stay silent.
const SHOW_AFTER: Duration = Duration::from_secs(1);

/// Stage-level progress of one command.
pub struct Progress {
    bar: ProgressBar,
    start: Instant,
    enabled: bool,
    shown: Mutex<bool>,
}

impl Progress {
    /// A progress reporter over `steps` steps; silent when `enabled` is
    /// false or stderr is not a terminal.
    pub fn new(steps: u64, enabled: bool) -> Self {
        let bar = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::hidden());
        if let Ok(style) = ProgressStyle::with_template("{elapsed:>4} [{bar:30}] {pos}/{len} {msg}")
        {
            bar.set_style(style.progress_chars("=> "));
        }
        Progress {
            bar,
            start: Instant::now(),
            enabled: enabled && std::io::stderr().is_terminal(),
            shown: Mutex::new(false),
        }
    }

    /// A reporter that never draws.
    pub fn hidden() -> Self {
        Progress::new(0, false)
    }

    /// Starts the named stage.
    pub fn stage(&self, name: &str) {
        self.maybe_show();
        self.bar.set_message(name.to_string());
    }

    /// Finishes a step.
    pub fn step(&self) {
        self.maybe_show();
        self.bar.inc(1);
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }

    fn maybe_show(&self) {
        if !self.enabled || self.start.elapsed() < SHOW_AFTER {
            return;
        }
        if let Ok(mut shown) = self.shown.lock() {
            if !*shown {
                self.bar.set_draw_target(ProgressDrawTarget::stderr());
                self.bar.enable_steady_tick(Duration::from_millis(200));
                *shown = true;
            }
        }
    }
}
