//! The estimate of a render's time from small probe renders of the same
//! scene and technique, and the progress reporter of one render built
//! from it (printed first when `--samples` asks for far more than a scene
//! needs). Here and not in `report`: report takes plain numbers
//! ([`RenderCost::fit`]) and never calls a render.

use super::{render, view_for, RenderOptions};
use crate::error::Result;
use crate::report::{format_duration, Progress, RenderCost, MANY_SAMPLES};
use crate::scene::Scene;
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// The reporter of one render: when stderr is a terminal or `samples`
/// exceeds [`MANY_SAMPLES`], the render's time is first estimated by
/// [`estimate_render`]; with many samples the estimate is printed
/// before the work starts. Otherwise (a script, normal settings) there
/// is no probe and no output.
pub fn progress_for_render(scene: &Scene, options: &RenderOptions) -> Result<Progress> {
    let terminal = std::io::stderr().is_terminal();
    let many = options.samples > MANY_SAMPLES;
    if !terminal && !many {
        return Ok(Progress::hidden());
    }
    let expected = estimate_render(scene, options)?;
    if many {
        eprintln!(
            "penumbra: --samples {}: estimated render time {} (from small probe renders)",
            options.samples,
            format_duration(expected)
        );
    }
    Ok(Progress::timed(expected, true))
}

/// Probe time above the fixed part that makes a per-sample cost stand
/// out of the timing noise.
const SIGNAL: f64 = 0.25;

/// Estimates the wall time of `render(scene, options)` from probe renders
/// of the same scene and technique ([`RenderCost::fit`]): an 8×8 image
/// (the fixed part), then an image of 1/4 of the side at the requested
/// samples; with more than [`MANY_SAMPLES`] samples, 1/8 of the side at
/// 1, 16, 256, ... samples until the time doubles (or the requested count
/// is reached). The probes cost about two to six times the render's
/// fixed part plus a sixteenth of the rest; call it inside the thread
/// pool the render will use.
pub fn estimate_render(scene: &Scene, options: &RenderOptions) -> Result<Duration> {
    let view = view_for(scene, options)?;
    let (w, h) = (view.width, view.height);
    let size = |div: u32| ((w / div).clamp(8.min(w), w), (h / div).clamp(8.min(h), h));
    let probe = |(pw, ph): (u32, u32), samples: u32| -> Result<(f64, f64, f64)> {
        let o = RenderOptions {
            width: Some(pw),
            height: Some(ph),
            samples,
            aovs: Vec::new(),
            ..options.clone()
        };
        let t = Instant::now();
        render(scene, &o)?;
        let pixels = f64::from(pw) * f64::from(ph);
        Ok((pixels, f64::from(samples), t.elapsed().as_secs_f64()))
    };
    let target = options.samples;
    let cost = if target <= MANY_SAMPLES {
        let tiny = probe(size(w.max(h)), target)?;
        let quarter = probe(size(4), target)?;
        RenderCost::fit(tiny, quarter, quarter)
    } else {
        let tiny = probe(size(w.max(h)), 1)?;
        let first = probe(size(8), 1)?;
        let mut last = first;
        let mut s = 1u32;
        // Until the time at least doubles (timing noise on a busy machine
        // does not double it) and grows by SIGNAL.
        while s < target && last.2 - first.2 < SIGNAL.max(first.2) {
            s = s.saturating_mul(16).min(target);
            last = probe(size(8), s)?;
        }
        RenderCost::fit(tiny, first, last)
    };
    let pixels = f64::from(w) * f64::from(h);
    let seconds = cost.seconds(pixels, f64::from(target));
    Ok(Duration::from_secs_f64(seconds.clamp(0.0, 1e9)))
}
