//! `penumbra compare`: every technique at every quality setting, timed and
//! measured against a ray-traced reference at the same receiver points.
//!
//! Every render of a scene uses the same view, so the G-buffer — the
//! receiver points — is the same bit for bit in each; errors are therefore
//! differences of the shadow term alone (plus, for radiance, the error of
//! modulating unshadowed light by Vcoef).
//!
//! The reference is two independent half-sample references (different
//! seeds). Their mean is the reference every technique is measured
//! against; half their difference estimates the reference's own error (its
//! noise floor): for independent estimates `A`, `B` of variance `2σ²/M`
//! each, `(A − B)/2` has the variance `σ²/M` of the mean `(A + B)/2`.

pub mod cache;
mod charts;
mod reference;
mod results;
mod run;
mod settings;

pub use crate::shadow::registry::{has_semi_opaque_casters, QualitySetting};
pub use charts::HEATMAP_SCALE;
pub use reference::{NoiseFloor, ReferenceSummary};
pub use results::{write_csv, write_json, write_markdown};
pub use run::{PassMedian, RegionMetrics, RunResult};
pub use settings::{progress_steps, quality_settings, CompareOptions};

use crate::error::{Error, Result};
use crate::output::write_png;
use crate::render::{verify_render, RenderOptions};
use crate::report::Progress;
use crate::scene::Scene;
use crate::shadow::kit::verify::check_verifiable;
use reference::{reference, NoiseFloors, ReferenceImages};
use run::{run_result, time_setting};
use serde::Serialize;
use std::path::Path;

/// Everything `compare` measured on one scene.
#[derive(Debug, Clone, Serialize)]
pub struct SceneComparison {
    /// Scene name.
    pub scene: String,
    /// Scene file.
    pub path: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Pixels that see a surface.
    pub shading_points: u64,
    /// Per light: shading points in the reference's penumbra.
    pub penumbra_points: Vec<u64>,
    /// The reference.
    pub reference: ReferenceSummary,
    /// Every run, in order.
    pub runs: Vec<RunResult>,
    /// Error-vs-time chart (penumbra), relative to the output directory.
    pub chart: Option<String>,
    /// Error-vs-time chart (all shading points).
    pub chart_all: Option<String>,
}

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
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let (cached, key, from_cache) = reference(scene, options, progress)?;
    let reference = ReferenceImages::new(&cached);
    let floors = NoiseFloors::new(&cached, &reference);
    let (width, height) = (key.width, key.height);

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

    let base = RenderOptions {
        width: Some(width),
        height: Some(height),
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
            let Some(timed) =
                time_setting(scene, &setting, &setting_options, options.repeat, progress)?
            else {
                continue;
            };
            let mut result =
                run_result(&setting, timed, &reference, options, out, (width, height))?;
            if let Some(k) = options.verify {
                let params = setting_options.build_params();
                if check_verifiable(technique, &params, k).is_ok() {
                    progress.stage(&format!("{} {} (verify)", setting.curve, setting.label));
                    result.verify = Some(verify_render(scene, &setting_options, k)?);
                }
            }
            runs.push(result);
        }
    }
    let floor = floors.vcoef_all_lights;
    let (chart, chart_all) = charts::pareto_and_charts(
        out,
        &scene.name,
        &mut runs,
        (floor.rmse_penumbra, floor.rmse_all),
    )?;

    Ok(SceneComparison {
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
        },
        runs,
        chart,
        chart_all,
    })
}
