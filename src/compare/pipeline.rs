//! One scene's comparison in stages: [`scene_runs`] (the plan),
//! [`prepare_scene`] (the reference), [`run_planned`] per run and
//! [`finish_scene`] (Pareto front, charts). [`compare_scene`] runs them
//! all; shards run the same stages on their share and the merge finishes
//! with the same code.

use super::charts;
use super::model::{ReferenceSummary, RunResult, SceneComparison};
use super::record::{records, Record};
use super::reference::{
    cached_reference_seconds, interior_of, reference, reference_key, NoiseFloors, ReferenceImages,
};
use super::results::{verified, write_results};
use super::run::{run_result, time_setting, TimedRuns};
use super::settings::{quality_settings, CompareOptions, TARGET_SET_SAMPLES};
use crate::error::{Error, Result};
use crate::observe::Cancel;
use crate::output::write_png;
use crate::render::{verify_render, RenderOptions};
use crate::report::{Progress, Work};
use crate::scene::Scene;
use crate::shadow::technique::{has_semi_opaque_casters, CostClass, QualitySetting};
use crate::shadow::verify::check_verifiable;
use crate::shadow::TechniqueOptions;
use std::path::Path;
use std::time::Instant;

/// Runs every technique and setting on `scene`, writes images, heat maps
/// and charts into `out` (created if missing) and returns the measurements.
/// Result tables are written by the caller ([`write_csv`], ...), which may
/// combine several scenes.
///
/// [`write_csv`]: super::write_csv
pub fn compare_scene(
    scene: &Scene,
    options: &CompareOptions,
    out: &Path,
    progress: &Progress,
) -> Result<SceneComparison> {
    options.validate()?;
    measure_scene(0, scene, options, Some(out), progress)
}

/// [`compare_scene`] with its files optional: without `out` nothing is
/// written (but the reference cache) and the results name no files.
fn measure_scene(
    index: usize,
    scene: &Scene,
    options: &CompareOptions,
    out: Option<&Path>,
    progress: &Progress,
) -> Result<SceneComparison> {
    let planned = scene_runs(scene, options)?;
    let all: Vec<usize> = (0..planned.len()).collect();
    let mut runs: Vec<Option<RunResult>> = vec![None; planned.len()];
    let prepared = run_scene(
        index,
        scene,
        &planned,
        &all,
        options,
        out,
        progress,
        |_, i, result, _| {
            runs[i] = Some(result);
            Ok(())
        },
    )?;
    finish_scene(prepared.header, runs.into_iter().flatten().collect(), out)
}

/// Renders held in memory before the reference is ready: at most this
/// many bytes of them (the first run of each curve, timed before the
/// reference so that the time estimate knows every technique's cost
/// early; measured once the reference is there).
const EARLY_BYTES: u64 = 256 << 20;

/// Makes the runs `which` (indices into `planned`, scene `index`'s runs)
/// and its reference, handing each finished run to `done` with its index
/// and its start and end (Unix seconds); returns the prepared scene.
///
/// The runs are made in [`execution_order`]. Where the time estimate is
/// shown ([`Progress::estimate_shown`]), the first run of each curve is
/// timed before the reference is computed, as far as the renders held
/// fit in [`EARLY_BYTES`], and measured once the reference is ready.
/// Every render is timed as it would be otherwise; only the order
/// changes, and the results do not depend on it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_scene(
    index: usize,
    scene: &Scene,
    planned: &[PlannedRun],
    which: &[usize],
    options: &CompareOptions,
    out: Option<&Path>,
    progress: &Progress,
    mut done: impl FnMut(&PreparedScene, usize, RunResult, (f64, f64)) -> Result<()>,
) -> Result<PreparedScene> {
    let chosen: Vec<&PlannedRun> = which.iter().map(|&i| &planned[i]).collect();
    let order: Vec<usize> = execution_order(&chosen)
        .into_iter()
        .map(|k| which[k])
        .collect();
    let curves = {
        let mut c: Vec<&str> = chosen.iter().map(|r| r.setting.curve.as_str()).collect();
        c.sort_unstable();
        c.dedup();
        c.len()
    };
    let key = reference_key(scene, options)?;
    let pixels = u64::from(key.width) * u64::from(key.height);
    // Radiance and a term per light (at most 16 bytes a pixel), and
    // room for a technique's layers.
    let per_render = pixels.saturating_mul(12 + 16 * (scene.lights.len() as u64 + 1));
    let mut early = 0;
    if progress.estimate_shown() {
        early = curves.min((EARLY_BYTES / per_render.max(1)) as usize);
        if let Some(seconds) = cached_reference_seconds(scene, options)? {
            progress.reference_cached(index, seconds);
        }
    }
    let mut held = Vec::new();
    for &i in &order[..early] {
        let started = unix_now();
        progress.work_started(index, Some(i));
        held.push((i, started, time_run(scene, &planned[i], options, progress)?));
        progress.work_finished(index, Some(i), None);
    }
    let prepared = prepare_scene(index, scene, options, out, progress)?;
    for (i, started, timed) in held {
        let result = measure_run(scene, &prepared, &planned[i], timed, options, out, progress)?;
        done(&prepared, i, result, (started, unix_now()))?;
    }
    for &i in &order[early..] {
        let started = unix_now();
        progress.work_started(index, Some(i));
        let timed = time_run(scene, &planned[i], options, progress)?;
        let result = measure_run(scene, &prepared, &planned[i], timed, options, out, progress)?;
        progress.work_finished(index, Some(i), None);
        done(&prepared, i, result, (started, unix_now()))?;
    }
    Ok(prepared)
}

/// Now, in seconds since the Unix epoch.
pub(crate) fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// The order `runs` (one scene's, in plan order) are made in, as indices
/// into `runs`: round robin over the technique curves, each curve's runs
/// in their order (its cheapest first: the lowest sample count, the
/// smallest map). Early on every curve is timed, so the time estimate
/// knows each technique's cost before its dearest runs; the results keep
/// the plan's order.
pub(crate) fn execution_order(runs: &[&PlannedRun]) -> Vec<usize> {
    let mut rank = Vec::with_capacity(runs.len());
    for (i, run) in runs.iter().enumerate() {
        let before = runs[..i]
            .iter()
            .filter(|r| r.setting.curve == run.setting.curve)
            .count();
        rank.push((before, i));
    }
    rank.sort_unstable();
    rank.into_iter().map(|(_, i)| i).collect()
}

/// The pieces of work of scene `index` of a sweep, for the time estimate:
/// its reference, then the runs of `runs` (index into the scene's runs,
/// the run) in order.
pub(crate) fn scene_work<'a>(
    index: usize,
    scene: &Scene,
    options: &CompareOptions,
    runs: impl IntoIterator<Item = (usize, &'a PlannedRun)>,
) -> Result<Vec<Work>> {
    let key = reference_key(scene, options)?;
    let pixels = u64::from(key.width) * u64::from(key.height);
    // Two independent halves, each at half the samples.
    let half = options.reference_samples / 2;
    let mut work = vec![Work {
        scene: index,
        run: None,
        curve: "reference".into(),
        samples: Some(half),
        renders: 2,
        pixels,
        per_sample: CostClass::Rays.per_sample(),
    }];
    for (i, run) in runs {
        let info = run.options.technique.info();
        work.push(Work {
            scene: index,
            run: Some(i),
            curve: run.setting.curve.clone(),
            samples: run.setting.samples,
            renders: options.repeat,
            pixels: run.options.width.unwrap_or(1) as u64 * run.options.height.unwrap_or(1) as u64,
            per_sample: match run.setting.samples {
                Some(_) => info.cost.per_sample(),
                None => 0,
            },
        });
    }
    Ok(work)
}

/// Every piece of work of a sweep over `scenes`, in the order it runs.
pub(crate) fn sweep_work(scenes: &[Scene], options: &CompareOptions) -> Result<Vec<Work>> {
    let mut work = Vec::new();
    for (index, scene) in scenes.iter().enumerate() {
        let runs = scene_runs(scene, options)?;
        work.extend(scene_work(index, scene, options, runs.iter().enumerate())?);
    }
    Ok(work)
}

/// Progress steps a sweep over `scenes` takes with `options`: two for
/// each scene's reference, one per timed render of each run
/// ([`scene_runs`], the list the shards plan and the listing shows).
pub fn progress_steps(scenes: &[Scene], options: &CompareOptions) -> Result<u64> {
    let mut steps = 0;
    for scene in scenes {
        let runs = scene_runs(scene, options)?.len() as u64;
        steps += 2 + runs * u64::from(options.repeat);
    }
    Ok(steps)
}

/// What `compare` prints before any run starts: per scene, `prefix`, the
/// runs of `runs` (an index into the scene's runs, the run) and the
/// reference, each as technique and setting; whether the reference is in
/// the cache; for a run the user did not name, the option that added it.
/// Lines are wrapped at 100 columns, never inside a run's name.
pub(crate) fn run_listing<'a>(
    prefix: &str,
    scene: &Scene,
    options: &CompareOptions,
    runs: impl IntoIterator<Item = &'a PlannedRun>,
) -> Result<String> {
    let cached = cached_reference_seconds(scene, options)?.is_some();
    let mut items = vec![format!(
        "reference {} spp ({})",
        options.reference_samples,
        if cached { "cached" } else { "to compute" }
    )];
    let mut count = 0;
    for run in runs {
        count += 1;
        let mut item = format!("{} {}", run.setting.curve, run.setting.label);
        if let Some(option) = run.added_by {
            item += &format!(" [{option}]");
        }
        items.push(item);
    }
    let key = reference_key(scene, options)?;
    let head = format!(
        "{prefix}: {count} run{} and the reference on {} ({}×{}, {} timed render{} each):",
        if count == 1 { "" } else { "s" },
        scene.name,
        key.width,
        key.height,
        options.repeat,
        if options.repeat == 1 { "" } else { "s" },
    );
    let mut text = head;
    let mut line = text.chars().count();
    for (i, item) in items.iter().enumerate() {
        let piece = match i + 1 == items.len() {
            true => item.clone(),
            false => format!("{item};"),
        };
        let width = piece.chars().count();
        if line + 1 + width > 100 && line > 2 {
            text += "\n ";
            line = 1;
        }
        text += " ";
        text += &piece;
        line += 1 + width;
    }
    Ok(text)
}

/// [`run_listing`] of every scene of a whole sweep.
pub(crate) fn sweep_listing(scenes: &[Scene], options: &CompareOptions) -> Result<Vec<String>> {
    scenes
        .iter()
        .map(|scene| run_listing("compare", scene, options, &scene_runs(scene, options)?))
        .collect()
}

/// Compares every technique at every quality setting on each of `scenes`
/// against its ray-traced reference and returns the rows of
/// `results.csv` as [`Record`]s, in the file's order: the library's
/// `penumbra compare`.
///
/// With `out`, writes there what the command writes (`results.csv`,
/// `.json`, `.md`, charts and, with `options.images`, images and heat
/// maps; a subdirectory per scene when there are several). Without it
/// nothing is written but the reference cache (`options.cache_dir`), and
/// scenes built in code (with no file) work alike: the cache is keyed by
/// the scene's contents. Progress is not shown.
///
/// Errors: `options` out of range ([`CompareOptions::validate`], naming
/// the parameter), a scene a technique refuses, a file that cannot be
/// written, and, with `options.verify`, a technique that declares itself
/// exact disagreeing with the shadow rays (after the files are written,
/// as the command does).
///
/// ```no_run
/// use penumbra::{compare, CompareOptions, Technique};
///
/// let scene = penumbra::load_scene("scenes/quad.toml".as_ref())?;
/// let options = CompareOptions {
///     techniques: vec![Technique::named("dcs")?, Technique::named("reference")?],
///     samples: vec![4, 16],
///     width: Some(64),
///     height: Some(48),
///     ..CompareOptions::default()
/// };
/// for row in compare(&[scene], &options, None)? {
///     if row.quantity == "flip" && row.region == "all" {
///         println!("{} {}: {:?} ms, FLIP {}", row.technique, row.setting, row.median_ms, row.mean_abs);
///     }
/// }
/// # Ok::<(), penumbra::Error>(())
/// ```
pub fn compare(
    scenes: &[Scene],
    options: &CompareOptions,
    out: Option<&Path>,
) -> Result<Vec<Record>> {
    compare_with(scenes, options, out, &Cancel::new())
}

/// [`compare`], stopping with [`crate::Error::Cancelled`] (between runs
/// and inside each render) once `cancel` is raised; a cancelled sweep
/// writes no result tables (images of runs already done stay).
pub fn compare_with(
    scenes: &[Scene],
    options: &CompareOptions,
    out: Option<&Path>,
    cancel: &Cancel,
) -> Result<Vec<Record>> {
    let command = out.map(|dir| equivalent_command(scenes, options, dir));
    let files = out
        .zip(command.as_deref())
        .map(|(dir, command)| SweepOutput {
            dir,
            report: None,
            command,
        });
    let progress = Progress::hidden().with_cancel(cancel.clone());
    let results = crate::render::with_threads(options.threads, || {
        sweep(scenes, options, files.as_ref(), &progress)
    })??;
    verified(&results.iter().collect::<Vec<_>>())?;
    Ok(records(&results))
}

/// The `penumbra compare` command that reruns a library call, for the
/// report's "regenerate with" (scenes built in code or from text have no
/// file to name).
fn equivalent_command(scenes: &[Scene], options: &CompareOptions, out: &Path) -> String {
    let quote = |s: String| {
        if !s.is_empty()
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || "/._-,:+=".contains(c))
        {
            s
        } else {
            format!("'{}'", s.replace('\'', "'\\''"))
        }
    };
    let list = |items: Vec<String>| items.join(",");
    let mut words = vec!["penumbra".to_string(), "compare".to_string()];
    for scene in scenes {
        words.push(match scene.path.is_file() {
            true => quote(scene.path.display().to_string()),
            false => format!("'<{}: not from a file>'", scene.name),
        });
    }
    let mut option = |name: &str, value: String| words.push(format!("--{name} {value}"));
    option(
        "techniques",
        list(
            options
                .techniques
                .iter()
                .map(|t| t.name().to_string())
                .collect(),
        ),
    );
    option(
        "samples",
        list(options.samples.iter().map(u32::to_string).collect()),
    );
    option("reference-samples", options.reference_samples.to_string());
    option(
        "patterns",
        list(options.patterns.iter().map(|p| p.name()).collect()),
    );
    option("repeat", options.repeat.to_string());
    for (name, size) in [("width", options.width), ("height", options.height)] {
        if let Some(size) = size {
            option(name, size.to_string());
        }
    }
    option("seed", options.seed.to_string());
    option("out", quote(out.display().to_string()));
    option("cache-dir", quote(options.cache_dir.display().to_string()));
    if let Some(k) = options.verify {
        option("verify", k.to_string());
    }
    if !options.images {
        words.push("--no-images".to_string());
    }
    if options.sweep_settings {
        words.push("--sweep-settings".to_string());
    }
    if options.technique_options != TechniqueOptions::default() {
        words.push("# and the technique options given in code".to_string());
    }
    words.join(" ")
}

/// Where a sweep writes its files: every scene's images and charts
/// ([`scene_dir`]) and the result tables ([`write_results`]).
pub(crate) struct SweepOutput<'a> {
    /// The output directory.
    pub dir: &'a Path,
    /// Also the markdown report here (`--report`).
    pub report: Option<&'a Path>,
    /// The command that regenerates the results, for the report.
    pub command: &'a str,
}

/// The whole sweep over `scenes`: each scene compared in order and, with
/// `out`, every file written there. The one route of `penumbra compare`
/// and of [`compare`](super::compare), so that the two cannot drift.
pub(crate) fn sweep(
    scenes: &[Scene],
    options: &CompareOptions,
    out: Option<&SweepOutput<'_>>,
    progress: &Progress,
) -> Result<Vec<SceneComparison>> {
    options.validate()?;
    let mut results = Vec::new();
    for (index, scene) in scenes.iter().enumerate() {
        let dir = out.map(|out| scene_dir(out.dir, &scene.name, scenes.len()));
        let result = measure_scene(index, scene, options, dir.as_deref(), progress)?;
        results.push((result, dir.unwrap_or_default()));
    }
    if let Some(out) = out {
        write_results(out.dir, &results, out.report, out.command)?;
    }
    Ok(results.into_iter().map(|(result, _)| result).collect())
}

/// One (technique, setting) run of a scene, before it runs.
pub(crate) struct PlannedRun {
    /// The setting.
    pub setting: QualitySetting,
    /// Its render options.
    pub options: RenderOptions,
    /// For a run the user did not name, the option that added it.
    pub added_by: Option<&'static str>,
}

/// The runs `compare` makes on `scene`, in order: every technique's
/// default configuration at each sample count and pattern asked for and,
/// with `--sweep-settings`, its other quality settings
/// ([`quality_settings`]). Cheap (no rendering): the listing printed
/// before a sweep, the progress estimate and the shards' plan all come
/// from it.
pub(crate) fn scene_runs(scene: &Scene, options: &CompareOptions) -> Result<Vec<PlannedRun>> {
    let view = options.view(scene)?;
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
        for run in quality_settings(
            technique,
            &options.samples,
            &options.patterns,
            semi_opaque,
            &base,
            options.sweep_settings,
        ) {
            runs.push(PlannedRun {
                setting: run.setting,
                options: run.options,
                added_by: run.added_by,
            });
        }
        if let Some(run) = target_error_run(technique, options, &base) {
            runs.push(run);
        }
    }
    Ok(runs)
}

/// `--target-error E`'s run of `technique`, if it renders progressively:
/// sets of [`TARGET_SET_SAMPLES`] at the first pattern until the
/// estimated radiance RMSE is at most E, within the reference's samples.
fn target_error_run(
    technique: crate::render::Technique,
    options: &CompareOptions,
    base: &RenderOptions,
) -> Option<PlannedRun> {
    let target = options.target_error?;
    let rule = crate::render::StopRule {
        target_error: Some(target),
        max_samples: Some(u64::from(options.reference_samples.max(TARGET_SET_SAMPLES))),
        max_time: None,
    };
    rule.validate(technique, TARGET_SET_SAMPLES).ok()?;
    let pattern = options.patterns.first().copied().unwrap_or_default();
    Some(PlannedRun {
        setting: QualitySetting {
            curve: format!("{} to RMSE {target:.1e}", technique.name()),
            label: format!("in sets of {TARGET_SET_SAMPLES} spp"),
            samples: Some(TARGET_SET_SAMPLES),
            pattern,
            options: base.options.clone(),
        },
        options: RenderOptions {
            technique,
            samples: TARGET_SET_SAMPLES,
            pattern,
            progressive: Some(rule),
            ..base.clone()
        },
        added_by: Some("--target-error"),
    })
}

/// A scene ready for its runs: the reference images and the scene's part
/// of the results (no runs yet).
pub(crate) struct PreparedScene {
    reference: ReferenceImages,
    /// The comparison without runs or charts.
    pub header: SceneComparison,
}

/// Computes (or reads from the cache) `scene`'s reference and, with
/// `options.images` and an `out` directory, writes
/// `out/images/reference.png`: piece `(index, None)` of a sweep's work
/// for the time estimate, which also learns the time of a render without
/// shadows (the interior's G-buffer, made first) and, from a reference
/// read from the cache, the time its computation took.
pub(crate) fn prepare_scene(
    index: usize,
    scene: &Scene,
    options: &CompareOptions,
    out: Option<&Path>,
    progress: &Progress,
) -> Result<PreparedScene> {
    progress.work_started(index, None);
    if let Some(out) = out {
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    }
    let clock = Instant::now();
    let interior = interior_of(scene, options)?;
    progress.work_baseline(index, clock.elapsed().as_secs_f64());
    let (cached, key, from_cache) = reference(scene, options, progress)?;
    let reference = ReferenceImages::new(&cached, &interior);
    let (width, height) = (key.width, key.height);
    let floors = NoiseFloors::new(&cached, &reference, (width, height));
    if let Some(out) = out.filter(|_| options.images) {
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
    progress.work_finished(index, None, from_cache.then_some(cached.seconds));
    Ok(PreparedScene { reference, header })
}

/// Times one planned run of `scene`: its `--repeat` renders.
pub(crate) fn time_run(
    scene: &Scene,
    run: &PlannedRun,
    options: &CompareOptions,
    progress: &Progress,
) -> Result<TimedRuns> {
    time_setting(scene, &run.setting, &run.options, options.repeat, progress)?
        .ok_or_else(|| Error::param("--repeat", "no timed run"))
}

/// Measures a timed run against the prepared reference (images into
/// `out`, if given) and, with `--verify`, checks it.
pub(crate) fn measure_run(
    scene: &Scene,
    prepared: &PreparedScene,
    run: &PlannedRun,
    timed: TimedRuns,
    options: &CompareOptions,
    out: Option<&Path>,
    progress: &Progress,
) -> Result<RunResult> {
    let setting = &run.setting;
    let size = (prepared.header.width, prepared.header.height);
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
/// the Pareto front and writes the charts into `out`, if given. The one
/// way results are completed, for a whole run and for merged shards alike.
pub(crate) fn finish_scene(
    header: SceneComparison,
    mut runs: Vec<RunResult>,
    out: Option<&Path>,
) -> Result<SceneComparison> {
    if let Some(out) = out {
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    }
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
