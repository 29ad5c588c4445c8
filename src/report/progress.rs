//! Progress on stderr for long work: a bar that appears only after a few
//! seconds and only when stderr is a terminal, with an estimate of the
//! time left; and the cost model a render's time is estimated by (the
//! probe renders that feed it are `crate::render::estimate`'s: report
//! does not call render). A `compare` sweep's bar and time left follow
//! the costs measured so far ([`super::estimate`]).

use super::estimate::{SweepEstimate, Work};
use crate::observe::Cancel;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};
use std::fmt::Write;
use std::io::IsTerminal;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

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
    /// A sweep's pieces of work and their measured times.
    sweep: Option<Arc<Mutex<SweepEstimate>>>,
    /// When the work started.
    clock: Instant,
    /// The bar may show (enabled, stderr a terminal).
    shown: bool,
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

    /// A reporter over a sweep's pieces of `work` (references and runs):
    /// its bar fills by time, the time done over that plus the time left
    /// that [`SweepEstimate`] predicts from the pieces already measured
    /// ([`Progress::work_started`], [`Progress::work_finished`]).
    pub fn sweep(work: Vec<Work>, enabled: bool) -> Self {
        let pieces = work.len();
        let estimate = Arc::new(Mutex::new(SweepEstimate::new(work)));
        let clock = Instant::now();
        let bar = ProgressBar::with_draw_target(Some(pieces as u64), ProgressDrawTarget::hidden());
        let (for_bar, for_count, for_left) = (
            Arc::clone(&estimate),
            Arc::clone(&estimate),
            Arc::clone(&estimate),
        );
        let style = ProgressStyle::with_template("{elapsed:>4} [{sweepbar}] {done} {msg}, {left}")
            .map(|style| {
                style
                    .with_key("sweepbar", move |_: &ProgressState, w: &mut dyn Write| {
                        let at = clock.elapsed().as_secs_f64();
                        let fraction = for_bar.lock().map_or(0.0, |e| {
                            e.fraction(at)
                                .unwrap_or(e.done() as f64 / pieces.max(1) as f64)
                        });
                        // Never full before the work is: at most BAR - 1.
                        let done = ((fraction * BAR as f64) as usize).min(BAR - 1);
                        let _ = write!(w, "{}>{}", "=".repeat(done), " ".repeat(BAR - 1 - done));
                    })
                    .with_key("done", move |_: &ProgressState, w: &mut dyn Write| {
                        let done = for_count.lock().map_or(0, |e| e.done());
                        let _ = write!(w, "{done}/{pieces}");
                    })
                    .with_key("left", move |_: &ProgressState, w: &mut dyn Write| {
                        let at = clock.elapsed().as_secs_f64();
                        let _ = match for_left.lock().ok().and_then(|e| e.left(at)) {
                            None => write!(w, "estimating the time left"),
                            Some(left) => write!(w, "~{} left", format_duration(seconds(left))),
                        };
                    })
            });
        if let Ok(style) = style {
            bar.set_style(style.progress_chars("=> "));
        }
        let mut progress = Progress::with_bar(bar, enabled);
        progress.sweep = Some(estimate);
        progress.clock = clock;
        progress
    }

    /// A sweep's piece of work starts: `scene`'s reference (`run`
    /// `None`) or run `run`. Nothing for a reporter of no sweep, or a
    /// piece not in its work.
    pub fn work_started(&self, scene: usize, run: Option<usize>) {
        let at = self.clock.elapsed().as_secs_f64();
        if let Some(mut e) = self.sweep.as_ref().and_then(|e| e.lock().ok()) {
            if let Some(i) = e.index_of(scene, run) {
                e.start(i, at);
            }
        }
    }

    /// `scene`'s reference will be read from the cache, and its
    /// computation took `seconds`: the time estimate learns the ray
    /// tracer's cost before the read.
    pub fn reference_cached(&self, scene: usize, seconds: f64) {
        if let Some(mut e) = self.sweep.as_ref().and_then(|e| e.lock().ok()) {
            if let Some(i) = e.index_of(scene, None) {
                e.cached(i, seconds);
            }
        }
    }

    /// A render of `scene` without shadows took `seconds`: every render
    /// of the scene costs at least that (the time estimate's first guess
    /// of a technique not timed yet).
    pub fn work_baseline(&self, scene: usize, seconds: f64) {
        if let Some(mut e) = self.sweep.as_ref().and_then(|e| e.lock().ok()) {
            e.baseline(scene, seconds);
        }
    }

    /// Whether a sweep's time estimate is shown (a sweep's reporter,
    /// enabled, on a terminal): worth probe renders for.
    pub fn estimate_shown(&self) -> bool {
        self.sweep.is_some() && self.shown
    }

    /// The sweep's piece of work under way is expected to take `seconds`
    /// (from probe renders), until it reports a share of its own.
    pub fn work_expected(&self, seconds: f64) {
        if let Some(mut e) = self.sweep.as_ref().and_then(|e| e.lock().ok()) {
            e.expect(seconds);
        }
    }

    /// The sweep's piece of work under way is `share` (in (0, 1)) done:
    /// it is then predicted by its own pace (a reference's first half).
    pub fn work_part(&self, share: f64) {
        let at = self.clock.elapsed().as_secs_f64();
        if let Some(mut e) = self.sweep.as_ref().and_then(|e| e.lock().ok()) {
            e.part(at, share);
        }
    }

    /// A sweep's piece of work is done; with `model`, other pieces are
    /// predicted from that many seconds instead of the time it took (a
    /// reference read from the cache: the time its computation took).
    pub fn work_finished(&self, scene: usize, run: Option<usize>, model: Option<f64>) {
        let at = self.clock.elapsed().as_secs_f64();
        if let Some(mut e) = self.sweep.as_ref().and_then(|e| e.lock().ok()) {
            if let Some(i) = e.index_of(scene, run) {
                e.finish(i, at, model);
            }
        }
    }

    /// The sweep's estimated time left now (`None` for a reporter of no
    /// sweep, or before anything usable is measured).
    pub fn sweep_left(&self) -> Option<Duration> {
        let at = self.clock.elapsed().as_secs_f64();
        let e = self.sweep.as_ref()?.lock().ok()?;
        e.left(at).map(seconds)
    }

    fn with_bar(bar: ProgressBar, enabled: bool) -> Self {
        let done = Arc::new(Mutex::new(false));
        let shown = enabled && std::io::stderr().is_terminal();
        if shown {
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
            sweep: None,
            clock: Instant::now(),
            shown,
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

/// `seconds` as a duration, capped at 10⁹ s; zero for a value that is
/// not a non-negative number.
fn seconds(seconds: f64) -> Duration {
    match seconds >= 0.0 {
        true => Duration::try_from_secs_f64(seconds.min(1e9)).unwrap_or_default(),
        false => Duration::ZERO,
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
    fn any_number_of_seconds_is_a_duration() {
        assert_eq!(seconds(1.5), Duration::from_millis(1500));
        assert_eq!(seconds(f64::INFINITY), Duration::from_secs(1_000_000_000));
        for odd in [f64::NAN, -1.0, f64::NEG_INFINITY] {
            assert_eq!(seconds(odd), Duration::ZERO, "{odd}");
        }
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
