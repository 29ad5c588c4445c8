//! One scene's comparison in stages: [`scene_runs`] (the plan),
//! [`prepare_scene`] (the reference), [`run_planned`] per run and
//! [`finish_scene`] (Pareto front, charts). [`compare_scene`] runs them
//! all; shards run the same stages on their share and the merge finishes
//! with the same code.

use super::charts;
use super::model::{ReferenceSummary, RunResult, SceneComparison};
use super::reference::{interior_of, reference, NoiseFloors, ReferenceImages};
use super::run::{run_result, time_setting};
use super::settings::{quality_settings, CompareOptions};
use crate::error::{Error, Result};
use crate::output::write_png;
use crate::render::{verify_render, RenderOptions};
use crate::report::Progress;
use crate::scene::Scene;
use crate::shadow::technique::{has_semi_opaque_casters, QualitySetting};
use crate::shadow::verify::check_verifiable;
use std::path::Path;

/// Runs every technique and setting on `scene`, writes images, heat maps
/// and charts into `out` (created if missing) and returns the measurements.
/// Result tables are written by the caller ([`write_csv`], ...), which may
/// combine several scenes.
pub fn compare_scene(
    scene: &Scene,
    options: &CompareOptions,
    out: &Path,
    progress: &Progress,
) -> Result<SceneComparison> {
    options.validate()?;
    let planned = scene_runs(scene, options)?;
    let prepared = prepare_scene(scene, options, out, progress)?;
    let mut runs = Vec::new();
    for run in &planned {
        runs.push(run_planned(scene, &prepared, run, options, out, progress)?);
    }
    finish_scene(prepared.header, runs, out)
}

/// One (technique, setting) run of a scene, before it runs.
pub(crate) struct PlannedRun {
    /// The setting.
    pub setting: QualitySetting,
    /// Its render options.
    pub options: RenderOptions,
}

/// The runs `compare` makes on `scene`, in order: every technique's
/// quality settings. Cheap (no rendering): shards plan with it.
pub(crate) fn scene_runs(scene: &Scene, options: &CompareOptions) -> Result<Vec<PlannedRun>> {
    let view = crate::render::view_for(
        scene,
        &RenderOptions {
            width: options.width,
            height: options.height,
            ..RenderOptions::default()
        },
    )?;
    let base = RenderOptions {
        width: Some(view.width),
        height: Some(view.height),
        seed: options.seed,
        options: options.technique_options.clone(),
        ..RenderOptions::default()
    };
    let semi_opaque = has_semi_opaque_casters(scene);
    let mut runs = Vec::new();
    for &technique in &options.techniques {
        for (setting, setting_options) in quality_settings(
            technique,
            &options.samples,
            &options.patterns,
            semi_opaque,
            &base,
        ) {
            runs.push(PlannedRun {
                setting,
                options: setting_options,
            });
        }
    }
    Ok(runs)
}

/// A scene ready for its runs: the reference images and the scene's part
/// of the results (no runs yet).
pub(crate) struct PreparedScene {
    reference: ReferenceImages,
    /// The comparison without runs or charts.
    pub header: SceneComparison,
}

/// Computes (or reads from the cache) `scene`'s reference and, with
/// `options.images`, writes `out/images/reference.png`.
pub(crate) fn prepare_scene(
    scene: &Scene,
    options: &CompareOptions,
    out: &Path,
    progress: &Progress,
) -> Result<PreparedScene> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let (cached, key, from_cache) = reference(scene, options, progress)?;
    let reference = ReferenceImages::new(&cached, &interior_of(scene, options)?);
    let (width, height) = (key.width, key.height);
    let floors = NoiseFloors::new(&cached, &reference, (width, height));
    if options.images {
        let dir = out.join("images");
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        write_png(
            &dir.join("reference.png"),
            width,
            height,
            &reference.radiance,
        )?;
    }
    let header = SceneComparison {
        scene: scene.name.clone(),
        path: scene.path.display().to_string(),
        width,
        height,
        shading_points: reference.surface.iter().filter(|&&s| s).count() as u64,
        penumbra_points: reference
            .penumbra
            .iter()
            .map(|p| p.iter().filter(|&&b| b).count() as u64)
            .collect(),
        interior_points: reference.interior.iter().filter(|&&b| b).count() as u64,
        reference: ReferenceSummary {
            samples: options.reference_samples,
            seeds: key.seeds,
            seconds: cached.seconds,
            from_cache,
            cache_file: options
                .cache_dir
                .join(format!("{}.exr", key.stem()))
                .display()
                .to_string(),
            floor_vcoef: floors.vcoef,
            floor_vcoef_all_lights: floors.vcoef_all_lights,
            floor_radiance: floors.radiance,
            flip_halves: floors.flip_halves,
        },
        runs: Vec::new(),
        chart_flip: None,
        chart_flip_interior: None,
        chart_radiance: None,
        chart: None,
        chart_all: None,
    };
    Ok(PreparedScene { reference, header })
}

/// Times and measures one planned run of `scene` (images into `out`).
pub(crate) fn run_planned(
    scene: &Scene,
    prepared: &PreparedScene,
    run: &PlannedRun,
    options: &CompareOptions,
    out: &Path,
    progress: &Progress,
) -> Result<RunResult> {
    let setting = &run.setting;
    let size = (prepared.header.width, prepared.header.height);
    let timed = time_setting(scene, setting, &run.options, options.repeat, progress)?
        .ok_or_else(|| Error::param("--repeat", "no timed run"))?;
    let mut result = run_result(setting, timed, &prepared.reference, options, out, size)?;
    if let Some(k) = options.verify {
        let params = run.options.build_params();
        if check_verifiable(run.options.technique, &params, k).is_ok() {
            progress.stage(&format!("{} {} (verify)", setting.curve, setting.label));
            result.verify = Some(verify_render(scene, &run.options, k)?);
        }
    }
    Ok(result)
}

/// The scene's comparison from its `header` and every run in order: marks
/// the Pareto front and writes the charts into `out`. The one way results
/// are completed, for a whole run and for merged shards alike.
pub(crate) fn finish_scene(
    header: SceneComparison,
    mut runs: Vec<RunResult>,
    out: &Path,
) -> Result<SceneComparison> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    for r in &mut runs {
        r.pareto = false;
        r.pareto_flip = false;
    }
    let image = charts::image_charts(
        out,
        &header.scene,
        &mut runs,
        header.reference.floor_radiance.rmse_all,
    )?;
    let floor = header.reference.floor_vcoef_all_lights;
    let (chart, chart_all) = charts::pareto_and_charts(
        out,
        &header.scene,
        &mut runs,
        (floor.rmse_penumbra, floor.rmse_all),
    )?;
    Ok(SceneComparison {
        runs,
        chart_flip: image.flip,
        chart_flip_interior: image.flip_interior,
        chart_radiance: image.radiance,
        chart,
        chart_all,
        ..header
    })
}

/// The directory of scene `name`'s images and charts under `out`: `out`
/// itself for a single scene, a subdirectory per scene for several.
pub fn scene_dir(out: &Path, name: &str, scenes: usize) -> std::path::PathBuf {
    if scenes > 1 {
        out.join(slug_of(name))
    } else {
        out.to_path_buf()
    }
}

/// A directory name for a scene name.
fn slug_of(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() {
        "scene".into()
    } else {
        s
    }
}
