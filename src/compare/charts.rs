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

/// One error-vs-time chart of a scene, as `compare` draws it.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartSpec {
    /// Its file name in the scene's directory.
    pub file: &'static str,
    /// Its title.
    pub title: String,
    /// The y axis's label.
    pub y_label: &'static str,
    /// One point per charted run.
    pub points: Vec<ChartPoint>,
    /// The reference's noise floor drawn, if any.
    pub floor: Option<f64>,
}

/// The image's charts of `runs`: FLIP mean over the whole frame and over
/// the interior, radiance RMSE over all shading points (with the
/// reference's noise floor `floor_radiance`). Every run has an image, so
/// every run is charted.
fn image_chart_specs(scene_name: &str, runs: &[RunResult], floor_radiance: f64) -> [ChartSpec; 3] {
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
    [
        ChartSpec {
            file: "flip_vs_time.png",
            title: format!("{scene_name}: FLIP (whole image) vs time"),
            y_label: "FLIP mean (whole image)",
            points: points(&|r| r.flip.all.mean),
            floor: None,
        },
        ChartSpec {
            file: "flip_vs_time_interior.png",
            title: format!("{scene_name}: FLIP away from geometric edges vs time"),
            y_label: "FLIP mean (interior)",
            points: points(&|r| r.flip.interior.mean),
            floor: None,
        },
        ChartSpec {
            file: "radiance_vs_time.png",
            title: format!("{scene_name}: radiance error vs time"),
            y_label: "radiance RMSE (all shading points)",
            points: points(&|r| r.radiance.all.rmse),
            floor: Some(floor_radiance),
        },
    ]
}

/// The Vcoef charts of `runs` (those with a Vcoef for every light):
/// penumbra RMSE and RMSE over all shading points, with the reference's
/// noise floors `(penumbra, all)`.
fn vcoef_chart_specs(
    scene_name: &str,
    runs: &[RunResult],
    (floor_penumbra, floor_all): (f64, f64),
) -> [ChartSpec; 2] {
    let points = |all: bool| {
        chart_points(runs, all)
            .into_iter()
            .map(|(_, p)| p)
            .collect()
    };
    [
        ChartSpec {
            file: "error_vs_time.png",
            title: format!("{scene_name}: Vcoef error in the penumbra vs time"),
            y_label: "Vcoef RMSE (penumbra)",
            points: points(false),
            floor: Some(floor_penumbra),
        },
        ChartSpec {
            file: "error_vs_time_all.png",
            title: format!("{scene_name}: Vcoef error over all shading points vs time"),
            y_label: "Vcoef RMSE (all shading points)",
            points: points(true),
            floor: Some(floor_all),
        },
    ]
}

/// Every chart `compare` writes for `comparison` (a scene's results), in
/// the order it writes them: the image's three, then the Vcoef two where
/// some run has a Vcoef for every light. The charts the files hold, for
/// a program (or a test) that looks at what they draw.
pub fn scene_charts(comparison: &super::SceneComparison) -> Vec<ChartSpec> {
    let (name, runs) = (&comparison.scene, &comparison.runs);
    let floors = &comparison.reference;
    let mut specs = Vec::new();
    if !runs.is_empty() {
        specs.extend(image_chart_specs(
            name,
            runs,
            floors.floor_radiance.rmse_all,
        ));
    }
    let floor = floors.floor_vcoef_all_lights;
    let vcoef = vcoef_chart_specs(name, runs, (floor.rmse_penumbra, floor.rmse_all));
    if !vcoef[0].points.is_empty() {
        specs.extend(vcoef);
    }
    specs
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
/// `out` directory, writes the image's error-vs-time charts there
/// ([`image_chart_specs`]).
pub(super) fn image_charts(
    out: Option<&Path>,
    scene_name: &str,
    runs: &mut [RunResult],
    floor_radiance: f64,
) -> Result<ImageCharts> {
    let specs = image_chart_specs(scene_name, runs, floor_radiance);
    for (r, front) in runs.iter_mut().zip(pareto_front(&specs[0].points)) {
        r.pareto_flip = front;
    }
    let Some(out) = out.filter(|_| !runs.is_empty()) else {
        return Ok(ImageCharts {
            flip: None,
            flip_interior: None,
            radiance: None,
        });
    };
    for spec in &specs {
        write_chart(out, spec)?;
    }
    Ok(ImageCharts {
        flip: Some(specs[0].file.to_string()),
        flip_interior: Some(specs[1].file.to_string()),
        radiance: Some(specs[2].file.to_string()),
    })
}

fn write_chart(out: &Path, spec: &ChartSpec) -> Result<()> {
    write_error_vs_time(
        &out.join(spec.file),
        &spec.title,
        spec.y_label,
        &spec.points,
        spec.floor,
    )
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
    floor: (f64, f64),
) -> Result<(Option<String>, Option<String>)> {
    let penumbra_points = chart_points(runs, false);
    let only: Vec<ChartPoint> = penumbra_points.iter().map(|(_, p)| p.clone()).collect();
    for ((i, _), front) in penumbra_points.iter().zip(pareto_front(&only)) {
        runs[*i].pareto = front;
    }
    let Some(out) = out.filter(|_| !only.is_empty()) else {
        return Ok((None, None));
    };
    let specs = vcoef_chart_specs(scene_name, runs, floor);
    for spec in &specs {
        write_chart(out, spec)?;
    }
    Ok((
        Some(specs[0].file.to_string()),
        Some(specs[1].file.to_string()),
    ))
}
