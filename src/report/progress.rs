//! Progress on stderr for long work: a bar that appears only after a few
//! seconds and only when stderr is a terminal, with an estimate of the
//! time left; and the cost model a render's time is estimated by (the
//! probe renders that feed it are `crate::render::estimate`'s: report
//! does not call render).

use crate::observe::Cancel;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};
use std::fmt::Write;
use std::io::IsTerminal;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Delay before the bar shows: short work stays silent.
const SHOW_AFTER: Duration = Duration::from_secs(2);

/// Light samples beyond which a render first prints its estimated time:
/// far more than the shipped scenes need.
pub const MANY_SAMPLES: u32 = 4096;

/// Width of the time-based bar, in characters.
const BAR: usize = 30;

/// Stage-level progress of one command.
pub struct Progress {
    bar: ProgressBar,
    /// Set once the work is done: a bar not yet shown never shows.
    done: Arc<Mutex<bool>>,
    /// Raised to stop the work (a library caller's [`Cancel`]).
    cancel: Cancel,
}

impl Progress {
    /// A reporter over `steps` steps, its time left estimated from the
    /// steps done; silent when `enabled` is false or stderr is not a
    /// terminal.
    pub fn new(steps: u64, enabled: bool) -> Self {
        let bar = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::hidden());
        if let Ok(style) =
            ProgressStyle::with_template("{elapsed:>4} [{bar:30}] {pos}/{len} {msg}, ~{eta} left")
        {
            bar.set_style(style.progress_chars("=> "));
        }
        Progress::with_bar(bar, enabled)
    }

    /// A reporter whose bar and time left follow the clock against an
    /// expected total (a render is one long stage: steps say nothing).
    pub fn timed(expected: Duration, enabled: bool) -> Self {
        let bar = ProgressBar::with_draw_target(Some(5), ProgressDrawTarget::hidden());
        let fraction = move |state: &ProgressState| {
            state.elapsed().as_secs_f64() / expected.as_secs_f64().max(1e-3)
        };
        let style =
            ProgressStyle::with_template("{elapsed:>4} [{timebar}] {msg}, {left}").map(|style| {
                style
                    .with_key("timebar", move |s: &ProgressState, w: &mut dyn Write| {
                        // Never full before the work is: at most BAR - 1.
                        let done = ((fraction(s) * BAR as f64) as usize).min(BAR - 1);
                        let _ = write!(w, "{}>{}", "=".repeat(done), " ".repeat(BAR - 1 - done));
                    })
                    .with_key("left", move |s: &ProgressState, w: &mut dyn Write| {
                        let left = expected.saturating_sub(s.elapsed());
                        let _ = match left.is_zero() {
                            true => write!(w, "longer than estimated"),
                            false => write!(w, "~{} left", format_duration(left)),
                        };
                    })
            });
        if let Ok(style) = style {
            bar.set_style(style);
        }
        Progress::with_bar(bar, enabled)
    }

    fn with_bar(bar: ProgressBar, enabled: bool) -> Self {
        let done = Arc::new(Mutex::new(false));
        if enabled && std::io::stderr().is_terminal() {
            // Shown by the clock, not by the next stage: one stage (a
            // render's shadows) can be most of the work.
            let (bar, done) = (bar.clone(), Arc::clone(&done));
            std::thread::spawn(move || {
                std::thread::sleep(SHOW_AFTER);
                if let Ok(done) = done.lock() {
                    if !*done {
                        bar.set_draw_target(ProgressDrawTarget::stderr());
                        bar.enable_steady_tick(Duration::from_millis(200));
                    }
                }
            });
        }
        Progress {
            bar,
            done,
            cancel: Cancel::new(),
        }
    }

    /// This reporter, its work stopped once `cancel` is raised.
    pub fn with_cancel(mut self, cancel: Cancel) -> Self {
        self.cancel = cancel;
        self
    }

    /// The work's cancel flag: an observer for the renders inside the
    /// work, which stops them without counting their stages as steps.
    pub fn cancel(&self) -> &Cancel {
        &self.cancel
    }

    /// A reporter that never draws.
    pub fn hidden() -> Self {
        Progress::new(0, false)
    }

    /// Starts the named stage.
    pub fn stage(&self, name: &str) {
        self.bar.set_message(name.to_string());
    }

    /// Finishes a step.
    pub fn step(&self) {
        self.bar.inc(1);
    }

    /// Removes the bar (and keeps it from appearing).
    pub fn finish(&self) {
        if let Ok(mut done) = self.done.lock() {
            *done = true;
        }
        self.bar.finish_and_clear();
    }
}

/// The command line's bar hears a render's stages, and stops it when
/// its cancel flag is raised.
impl crate::observe::Observer for Progress {
    fn stage(&self, name: &str) {
        Progress::stage(self, name);
    }

    fn step(&self) {
        Progress::step(self);
    }

    fn cancelled(&self) -> bool {
        self.cancel.is_cancelled()
    }
}

impl Drop for Progress {
    /// A reporter dropped on an error path must not draw afterwards.
    fn drop(&mut self) {
        self.finish();
    }
}

/// `1 h 05 min`, `3 min 20 s`, `12.5 s`.
pub fn format_duration(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s < 60.0 {
        return format!("{s:.1} s");
    }
    let whole = s.round() as u64;
    let (h, m, sec) = (whole / 3600, whole / 60 % 60, whole % 60);
    match h {
        0 => format!("{m} min {sec:02} s"),
        h if h < 48 => format!("{h} h {m:02} min"),
        h => format!("{} days {} h", h / 24, h % 24),
    }
}

/// The cost model of a render: a fixed part (geometry, acceleration
/// structures, silhouettes), a part per pixel and a part per pixel and
/// light sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderCost {
    /// Seconds, whatever the image size.
    pub fixed: f64,
    /// Seconds per pixel.
    pub per_pixel: f64,
    /// Seconds per pixel and light sample.
    pub per_sample: f64,
}

impl RenderCost {
    /// Fits the model to timed probes `(pixels, samples, seconds)`: `tiny`
    /// (so few pixels that its time is the fixed part), then `a` and `b`,
    /// two probes of one larger image at fewer and more samples (the same
    /// samples: no per-sample part is measured, the per-pixel part has
    /// it). Parts made negative by timing noise are clamped to zero.
    pub fn fit(tiny: (f64, f64, f64), a: (f64, f64, f64), b: (f64, f64, f64)) -> Self {
        let fixed = tiny.2.max(0.0);
        let (pixels, s1, t1) = a;
        let (_, s2, t2) = b;
        let pixels = pixels.max(1.0);
        let per_sample = match s2 > s1 {
            true => ((t2 - t1) / (pixels * (s2 - s1))).max(0.0),
            false => 0.0,
        };
        let per_pixel = ((t1 - fixed) / pixels - per_sample * s1).max(0.0);
        RenderCost {
            fixed,
            per_pixel,
            per_sample,
        }
    }

    /// Predicted seconds for `pixels` pixels at `samples` samples.
    pub fn seconds(&self, pixels: f64, samples: f64) -> f64 {
        self.fixed + pixels * (self.per_pixel + self.per_sample * samples)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cost_model_recovers_its_parts() {
        let truth = RenderCost {
            fixed: 0.5,
            per_pixel: 2e-6,
            per_sample: 3e-8,
        };
        // The tiny probe's own pixels are part of its time: off by 64 px.
        let at = |p: f64, s: f64| (p, s, truth.seconds(p, s));
        let tiny = (64.0, 1.0, truth.fixed);
        let fit = RenderCost::fit(tiny, at(6144.0, 1.0), at(6144.0, 1024.0));
        for (a, b) in [
            (fit.fixed, truth.fixed),
            (fit.per_pixel, truth.per_pixel),
            (fit.per_sample, truth.per_sample),
        ] {
            assert!((a - b).abs() <= 1e-9 * b, "{fit:?}");
        }
        let full = truth.seconds(1e6, 1e6);
        assert!((fit.seconds(1e6, 1e6) - full).abs() <= 1e-9 * full);
        // Noise that would make a part negative clamps it to zero.
        let fit = RenderCost::fit((64.0, 4.0, 1.0), (400.0, 4.0, 0.9), (400.0, 64.0, 0.8));
        assert!(
            fit.per_sample == 0.0 && fit.per_pixel == 0.0 && fit.fixed == 1.0,
            "{fit:?}"
        );
    }

    #[test]
    fn durations_read_naturally() {
        assert_eq!(format_duration(Duration::from_millis(12_340)), "12.3 s");
        assert_eq!(format_duration(Duration::from_secs(200)), "3 min 20 s");
        assert_eq!(format_duration(Duration::from_secs(3900)), "1 h 05 min");
        assert_eq!(
            format_duration(Duration::from_secs(3 * 86400 + 7200)),
            "3 days 2 h"
        );
    }
}
