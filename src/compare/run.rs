//! Timing one quality setting (repeated renders, per-pass medians, a
//! check that every run gave the same bits) and measuring it against the
//! reference.

use super::charts::{slug, write_run_images};
use super::host::host_name;
use super::model::{PassMedian, RegionMetrics, RunResult};
use super::reference::{vcoef_of, ReferenceImages};
use super::settings::CompareOptions;
use crate::error::{Error, Result};
use crate::output::srgb8;
use crate::render::{render_with, Render, RenderOptions};
use crate::report::{flip_rgb8, Progress};
use crate::shadow::technique::QualitySetting;
use std::path::Path;
use std::time::Instant;

/// One setting's timed renders.
pub(crate) struct TimedRuns {
    /// The first run's output (every run's is the same).
    pub rendered: Render,
    /// Each run's wall-clock milliseconds.
    pub totals: Vec<f64>,
    /// Per-pass medians, in execution order.
    pub passes: Vec<PassMedian>,
}

/// Renders `setting` (`setting_options`) `repeat` times, timing each run
/// and its passes; an error if two runs differ in any bit. `None` when
/// there was no run.
pub(super) fn time_setting(
    scene: &crate::scene::Scene,
    setting: &QualitySetting,
    setting_options: &RenderOptions,
    repeat: u32,
    progress: &Progress,
) -> Result<Option<TimedRuns>> {
    let name = setting.curve.as_str();
    let mut totals = Vec::new();
    let mut pass_times: Vec<Vec<f64>> = Vec::new();
    let mut pass_names: Vec<String> = Vec::new();
    let mut first: Option<Render> = None;
    for r in 0..repeat {
        progress.stage(&format!(
            "{name} {} (run {}/{})",
            setting.label,
            r + 1,
            repeat
        ));
        let start = Instant::now();
        let rendered = render_with(scene, setting_options, progress.cancel())?;
        totals.push(start.elapsed().as_secs_f64() * 1e3);
        if pass_names.is_empty() {
            pass_names = rendered.passes.iter().map(|p| p.name.clone()).collect();
            pass_times = vec![Vec::new(); pass_names.len()];
        }
        for (i, p) in rendered.passes.iter().enumerate().take(pass_names.len()) {
            pass_times[i].push(p.time.as_secs_f64() * 1e3);
        }
        match &first {
            None => first = Some(rendered),
            Some(f) => {
                // Free insurance: the renderer promises the same bits
                // every run; a comparison built on anything else
                // would be meaningless.
                if f.radiance != rendered.radiance
                    || f.layers != rendered.layers
                    || f.lights != rendered.lights
                {
                    return Err(Error::param(
                        "--technique",
                        format!(
                            "{name} ({}) gave different images in two runs of the same render",
                            setting.label
                        ),
                    ));
                }
            }
        }
        progress.step();
    }
    let Some(rendered) = first else {
        return Ok(None);
    };
    let passes = pass_names
        .into_iter()
        .zip(pass_times)
        .map(|(name, t)| PassMedian {
            name,
            median_ms: median(t),
        })
        .collect();
    Ok(Some(TimedRuns {
        rendered,
        totals,
        passes,
    }))
}

/// `setting`'s result from its timed `runs`: its errors against
/// `reference` and, with `options.images` and an `out` directory, its
/// image and Vcoef heat maps written there.
pub(super) fn run_result(
    setting: &QualitySetting,
    runs: TimedRuns,
    reference: &ReferenceImages,
    options: &CompareOptions,
    out: Option<&Path>,
    (width, height): (u32, u32),
) -> Result<RunResult> {
    let name = setting.curve.as_str();
    let TimedRuns {
        rendered,
        totals,
        passes,
    } = runs;
    let owned: Vec<Option<Vec<f32>>> = (0..reference.vcoef.len())
        .map(|k| vcoef_of(&rendered, k, &reference.surface))
        .collect();
    let tests: Vec<Option<&[f32]>> = owned.iter().map(|v| v.as_deref()).collect();
    let vcoef: Vec<Option<RegionMetrics>> = tests
        .iter()
        .enumerate()
        .map(|(k, t)| t.map(|t| reference.vcoef_metrics(k, t)))
        .collect();
    let (image, heatmaps) = match out.filter(|_| options.images) {
        Some(out) => {
            let stem = slug(&format!("{name}-{}", setting.label));
            write_run_images(out, &stem, (width, height), &rendered, &tests, reference)?
        }
        None => (None, Vec::new()),
    };
    // A progressive run (`--target-error`) says where it stopped: the
    // samples it took and its own estimate, beside the measured error.
    let (label, samples) = match &rendered.explain.convergence {
        Some(c) => (
            format!(
                "to RMSE {}: {}×{} spp, est. {}",
                c.target_error.map_or("-".into(), |e| format!("{e:.1e}")),
                c.sets,
                c.samples_per_set,
                c.error.map_or("-".into(), |e| format!("{e:.2e}"))
            ),
            Some(u32::try_from(c.samples()).unwrap_or(u32::MAX)),
        ),
        None => (setting.label.clone(), setting.samples),
    };
    Ok(RunResult {
        technique: name.to_string(),
        setting: label,
        samples,
        median_ms: median(totals.clone()),
        min_ms: totals.iter().copied().fold(f64::INFINITY, f64::min),
        max_ms: totals.iter().copied().fold(0.0, f64::max),
        runs: options.repeat,
        host: host_name(),
        passes,
        vcoef_all_lights: reference.vcoef_all_lights(&tests, &reference.vcoef),
        vcoef,
        radiance: reference.radiance_metrics(&rendered.radiance, &reference.radiance),
        flip: flip_rgb8(&reference.rgb8, &srgb8(&rendered.radiance), width, height)
            .map(|map| map.regions(&reference.interior))
            .ok_or_else(|| {
                Error::param(
                    "--technique",
                    format!(
                        "{name} ({}) gave an image of another size than the reference",
                        setting.label
                    ),
                )
            })?,
        pareto_flip: false,
        pareto: false,
        image,
        heatmaps,
        verify: None,
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}
