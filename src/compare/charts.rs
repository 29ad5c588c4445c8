//! `compare`'s pictures: each run's image and Vcoef error heat maps, the
//! error-vs-time chart points, their Pareto fronts and the charts: the
//! image's error first (FLIP, radiance RMSE), then Vcoef's.

use super::model::RunResult;
use super::reference::ReferenceImages;
use crate::error::{Error, Result};
use crate::output::write_png;
use crate::render::Render;
use crate::report::{
    pareto_front, write_error_heatmap, write_error_vs_time, ChartPoint, HeatmapScale,
};
use std::path::Path;

/// Errors at or above this show brightest in the Vcoef heat maps (their
/// colour bars say so).
pub const HEATMAP_SCALE: f32 = 0.25;

/// A file-name-safe form of `s`.
pub(super) fn slug(s: &str) -> String {
    let mut out = String::new();
    for c in s.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('-') {
            out.push('-');
        }
    }
    out.trim_matches('-').to_string()
}

/// Writes a run's radiance image (`images/{stem}.png`) and, per light
/// with a Vcoef (`tests`), its error heat map against `reference`
/// (`heatmaps/{stem}.vcoef{k}.png`); returns their paths relative to `out`.
pub(super) fn write_run_images(
    out: &Path,
    stem: &str,
    (width, height): (u32, u32),
    rendered: &Render,
    tests: &[Option<&[f32]>],
    reference: &ReferenceImages,
) -> Result<(Option<String>, Vec<String>)> {
    let rel = format!("images/{stem}.png");
    write_png(&out.join(&rel), width, height, &rendered.radiance)?;
    let image = Some(rel);
    let mut heatmaps = Vec::new();
    let dir = out.join("heatmaps");
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    for (k, t) in tests.iter().enumerate() {
        let Some(t) = t else { continue };
        let err: Vec<f32> = t
            .iter()
            .zip(&reference.vcoef[k])
            .map(|(a, b)| (a - b).abs())
            .collect();
        let rel = format!("heatmaps/{stem}.vcoef{k}.png");
        let quantity = format!("|ΔVcoef|, light {k}");
        let scale = HeatmapScale {
            quantity: &quantity,
            unit: "unitless",
            max: HEATMAP_SCALE,
        };
        write_error_heatmap(
            &out.join(&rel),
            width,
            height,
            &err,
            &reference.surface,
            &scale,
        )?;
        heatmaps.push(rel);
    }
    Ok((image, heatmaps))
}

/// The image's error-vs-time charts, relative to the output directory
/// (`None` without a run).
pub(super) struct ImageCharts {
    /// FLIP mean over the whole frame.
    pub flip: Option<String>,
    /// FLIP mean over the interior.
    pub flip_interior: Option<String>,
    /// Radiance RMSE over all shading points.
    pub radiance: Option<String>,
}

/// Marks the runs on the Pareto front of (time, FLIP mean) and, given an
/// `out` directory, writes the image's error-vs-time charts there: FLIP
/// mean over the whole frame
/// (`flip_vs_time.png`) and over the interior (`flip_vs_time_interior.png`),
/// and radiance RMSE over all shading points (`radiance_vs_time.png`,
/// with the reference's noise floor `floor_radiance`). Every run has an
/// image, so every run is charted.
pub(super) fn image_charts(
    out: Option<&Path>,
    scene_name: &str,
    runs: &mut [RunResult],
    floor_radiance: f64,
) -> Result<ImageCharts> {
    let points = |error: &dyn Fn(&RunResult) -> f64| -> Vec<ChartPoint> {
        runs.iter()
            .map(|r| ChartPoint {
                technique: r.technique.clone(),
                label: r.setting.clone(),
                seconds: r.median_ms / 1e3,
                error: error(r),
            })
            .collect()
    };
    let flip = points(&|r| r.flip.all.mean);
    let flip_interior = points(&|r| r.flip.interior.mean);
    let radiance = points(&|r| r.radiance.all.rmse);
    for (r, front) in runs.iter_mut().zip(pareto_front(&flip)) {
        r.pareto_flip = front;
    }
    let Some(out) = out.filter(|_| !runs.is_empty()) else {
        return Ok(ImageCharts {
            flip: None,
            flip_interior: None,
            radiance: None,
        });
    };
    let charts = [
        (
            "flip_vs_time.png",
            format!("{scene_name}: FLIP (whole image) vs time"),
            "FLIP mean (whole image)",
            &flip,
            None,
        ),
        (
            "flip_vs_time_interior.png",
            format!("{scene_name}: FLIP away from geometric edges vs time"),
            "FLIP mean (interior)",
            &flip_interior,
            None,
        ),
        (
            "radiance_vs_time.png",
            format!("{scene_name}: radiance error vs time"),
            "radiance RMSE (all shading points)",
            &radiance,
            Some(floor_radiance),
        ),
    ];
    for (file, title, y_label, points, floor) in &charts {
        write_error_vs_time(&out.join(file), title, y_label, points, *floor)?;
    }
    Ok(ImageCharts {
        flip: Some(charts[0].0.to_string()),
        flip_interior: Some(charts[1].0.to_string()),
        radiance: Some(charts[2].0.to_string()),
    })
}

/// The error-vs-time points of the runs with a Vcoef for every light, with
/// their index in `runs`: the penumbra RMSE, or with `all` the RMSE over
/// all shading points.
fn chart_points(runs: &[RunResult], all: bool) -> Vec<(usize, ChartPoint)> {
    runs.iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let m = r.vcoef_all_lights?;
            Some((
                i,
                ChartPoint {
                    technique: r.technique.clone(),
                    label: r.setting.clone(),
                    seconds: r.median_ms / 1e3,
                    error: if all { m.all.rmse } else { m.penumbra.rmse },
                },
            ))
        })
        .collect()
}

/// Marks the runs on the Pareto front of (time, penumbra Vcoef RMSE) and,
/// given an `out` directory, writes the error-vs-time charts (penumbra, all
/// shading points) there, with the reference's noise floors `floor` (`(penumbra, all)`
/// RMSE) drawn; returns their paths relative to `out`, `None` without a
/// run to chart or without `out`.
pub(super) fn pareto_and_charts(
    out: Option<&Path>,
    scene_name: &str,
    runs: &mut [RunResult],
    (floor_penumbra, floor_all): (f64, f64),
) -> Result<(Option<String>, Option<String>)> {
    let penumbra_points = chart_points(runs, false);
    let only: Vec<ChartPoint> = penumbra_points.iter().map(|(_, p)| p.clone()).collect();
    for ((i, _), front) in penumbra_points.iter().zip(pareto_front(&only)) {
        runs[*i].pareto = front;
    }
    let Some(out) = out.filter(|_| !only.is_empty()) else {
        return Ok((None, None));
    };
    write_error_vs_time(
        &out.join("error_vs_time.png"),
        &format!("{scene_name}: Vcoef error in the penumbra vs time"),
        "Vcoef RMSE (penumbra)",
        &only,
        Some(floor_penumbra),
    )?;
    let all: Vec<ChartPoint> = chart_points(runs, true)
        .into_iter()
        .map(|(_, p)| p)
        .collect();
    write_error_vs_time(
        &out.join("error_vs_time_all.png"),
        &format!("{scene_name}: Vcoef error over all shading points vs time"),
        "Vcoef RMSE (all shading points)",
        &all,
        Some(floor_all),
    )?;
    Ok((
        Some("error_vs_time.png".to_string()),
        Some("error_vs_time_all.png".to_string()),
    ))
}
