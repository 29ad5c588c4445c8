//! `compare --shard I/N`: one share of a sweep's (scene, technique,
//! setting) runs, written as a partial result that `compare --merge`
//! (`merge`) joins with the others.
//!
//! The assignment is a function of the sweep alone (scenes, options, N):
//! every shard computes the same plan, runs its part, and records the
//! whole plan in its partial, so the merge knows every run that must be
//! there and which shard owes it. Balance comes from a static estimate of
//! each run's cost ([`estimated_cost`]), never from timings, so the plan
//! is the same on every machine and every attempt.
//!
//! A partial is `DIR/shard-I-of-N.json`, rewritten atomically after every
//! run (a killed shard leaves the runs it finished, marked incomplete);
//! run images and heat maps go under `DIR` exactly where an unsharded run
//! puts them under `--out`. Error figures are stored as shortest
//! round-trip decimals in strings (`f64`'s `Debug`, parsed back exactly,
//! also for `inf`), so merged tables are bit for bit an unsharded run's.
//!
//! Each scene's reference is computed once, by the first shard that needs
//! it, under the cache's lock ([`lock_reference`](super::cache::lock_reference)):
//! shards need no job to depend on, and a lost shard cannot leave the
//! others without a reference. `compare --references-only` computes the
//! references beforehand where a cluster prefers a dependency job.

use super::cache::{hash_scene, StableHasher};
use super::host::host_name;
use super::model::{
    NoiseFloor, PassMedian, ReferenceSummary, RegionMetrics, RunResult, SceneComparison,
};
use super::pipeline::{run_listing, run_scene, scene_dir, scene_runs, scene_work, PlannedRun};
use super::settings::CompareOptions;
use super::share::{parse_share, ShareError};
use crate::error::{Error, Result};
use crate::output::write_atomically;
use crate::report::{ErrorMetrics, FlipMetrics, FlipRegions, Progress};
use crate::scene::Scene;
use crate::shadow::kit::verify::{Disagreement, VerifyReport};
use crate::shadow::technique::CostClass;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Bumped whenever the partial format changes. 2: FLIP per run (whole
/// frame and interior), the interior region of every error, the interior
/// noise floors and FLIP between the reference's halves; a partial of
/// format 1 lacks them and is refused, never read with zeros.
pub const PARTIAL_FORMAT: u32 = 2;

/// `--shard I/N`: shard `index` (1-based) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShardSpec {
    /// 1..=count.
    pub index: u32,
    /// Shards in the sweep.
    pub count: u32,
}

impl ShardSpec {
    /// Parses `I/N` with `1 <= I <= N`; errors name `--shard`.
    pub fn parse(s: &str) -> Result<ShardSpec> {
        let why = |error: ShareError| match error {
            ShareError::NoSlash => "is not I/N (e.g. 2/8)".to_string(),
            ShareError::IndexNotNumber => "has no whole number for I".to_string(),
            ShareError::CountNotNumber => "has no whole number for N".to_string(),
            ShareError::NoShares => "has N = 0: a sweep needs at least one shard".to_string(),
            ShareError::IndexOutOfRange { count } => {
                format!("has I outside 1..={count} (shards are numbered from 1)")
            }
        };
        let (index, count) = parse_share(s)
            .map_err(|error| Error::param("--shard", format!("'{s}' {}", why(error))))?;
        Ok(ShardSpec { index, count })
    }

    /// The partial's file name.
    pub fn file_name(&self) -> String {
        format!("shard-{}-of-{}.json", self.index, self.count)
    }
}

impl std::fmt::Display for ShardSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Rough relative cost of one run: pixels × (a fixed part for geometry,
/// G-buffer and shading + a per-sample part by the technique's declared
/// [`CostClass`]). Only ratios matter (for balancing), and only the inputs,
/// never a timing.
pub fn estimated_cost(cost: CostClass, samples: Option<u32>, pixels: u64, repeat: u32) -> u64 {
    let per_pixel = 4 + cost.per_sample() * samples.unwrap_or(4) as u64;
    pixels
        .saturating_mul(per_pixel)
        .saturating_mul(repeat as u64)
}

/// The static cost estimate of `run` ([`estimated_cost`]): what shards
/// balance by (never a timing, so every shard plans alike).
fn run_cost(run: &PlannedRun, repeat: u32) -> u64 {
    let pixels = run.options.width.unwrap_or(1) as u64 * run.options.height.unwrap_or(1) as u64;
    estimated_cost(
        run.options.technique.info().cost,
        run.setting.samples,
        pixels,
        repeat,
    )
}

/// Assigns `costs` to `shards` shards: longest processing time first
/// (each run, costliest first, to the least-loaded shard; ties by order),
/// which is within 4/3 of the best makespan. Returns each run's shard,
/// 1-based.
pub fn assign(costs: &[u64], shards: u32) -> Vec<u32> {
    let mut order: Vec<usize> = (0..costs.len()).collect();
    order.sort_by(|&a, &b| costs[b].cmp(&costs[a]).then(a.cmp(&b)));
    let mut load = vec![0u64; shards as usize];
    let mut out = vec![0u32; costs.len()];
    for i in order {
        let s = (0..load.len())
            .min_by_key(|&s| (load[s], s))
            .unwrap_or_default();
        load[s] = load[s].saturating_add(costs[i]);
        out[i] = s as u32 + 1;
    }
    out
}

/// An `f64` stored exactly: its shortest round-trip decimal, as a string
/// (JSON numbers have no `inf`, and JSON readers need not round exactly).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Exact(pub f64);

impl Serialize for Exact {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{:?}", self.0))
    }
}

impl<'de> Deserialize<'de> for Exact {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse::<f64>()
            .map(Exact)
            .map_err(|_| serde::de::Error::custom(format!("'{s}' is not a number")))
    }
}

/// One scene of the sweep, as the partials identify it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct SceneId {
    /// Scene name.
    pub name: String,
    /// The scene file as given (may differ between hosts; not compared).
    pub path: String,
    /// Hash of the loaded contents: geometry, materials, texels, lights,
    /// camera (the reference cache's scene hash).
    pub hash: String,
    /// Its output directory relative to `--out` (empty: `--out` itself).
    pub dir: String,
}

/// One run of the sweep's plan.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct PlanEntry {
    /// Index into the sweep's scenes.
    pub scene: usize,
    /// Index of the run among the scene's runs (their order in results).
    pub index: usize,
    /// Technique (chart curve) name.
    pub technique: String,
    /// Setting label.
    pub setting: String,
    /// [`estimated_cost`].
    pub cost: u64,
    /// The shard that runs it, 1-based.
    pub shard: u32,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialMetrics {
    count: u64,
    rmse: Exact,
    mean_abs: Exact,
    max_abs: Exact,
    frac_over: Exact,
    non_finite: u64,
}

impl From<ErrorMetrics> for PartialMetrics {
    fn from(m: ErrorMetrics) -> Self {
        let ErrorMetrics {
            count,
            rmse,
            mean_abs,
            max_abs,
            frac_over,
            non_finite,
        } = m;
        PartialMetrics {
            count,
            rmse: Exact(rmse),
            mean_abs: Exact(mean_abs),
            max_abs: Exact(max_abs),
            frac_over: Exact(frac_over),
            non_finite,
        }
    }
}

impl From<&PartialMetrics> for ErrorMetrics {
    fn from(m: &PartialMetrics) -> Self {
        ErrorMetrics {
            count: m.count,
            rmse: m.rmse.0,
            mean_abs: m.mean_abs.0,
            max_abs: m.max_abs.0,
            frac_over: m.frac_over.0,
            non_finite: m.non_finite,
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialRegion {
    all: PartialMetrics,
    penumbra: PartialMetrics,
    interior: PartialMetrics,
}

impl From<RegionMetrics> for PartialRegion {
    fn from(m: RegionMetrics) -> Self {
        let RegionMetrics {
            all,
            penumbra,
            interior,
        } = m;
        PartialRegion {
            all: all.into(),
            penumbra: penumbra.into(),
            interior: interior.into(),
        }
    }
}

impl From<&PartialRegion> for RegionMetrics {
    fn from(m: &PartialRegion) -> Self {
        RegionMetrics {
            all: (&m.all).into(),
            penumbra: (&m.penumbra).into(),
            interior: (&m.interior).into(),
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialFlip {
    count: u64,
    mean: Exact,
    p50: Exact,
    p90: Exact,
    p99: Exact,
    max: Exact,
}

impl From<FlipMetrics> for PartialFlip {
    fn from(m: FlipMetrics) -> Self {
        let FlipMetrics {
            count,
            mean,
            p50,
            p90,
            p99,
            max,
        } = m;
        PartialFlip {
            count,
            mean: Exact(mean),
            p50: Exact(p50),
            p90: Exact(p90),
            p99: Exact(p99),
            max: Exact(max),
        }
    }
}

impl From<&PartialFlip> for FlipMetrics {
    fn from(m: &PartialFlip) -> Self {
        FlipMetrics {
            count: m.count,
            mean: m.mean.0,
            p50: m.p50.0,
            p90: m.p90.0,
            p99: m.p99.0,
            max: m.max.0,
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialFlipRegions {
    all: PartialFlip,
    interior: PartialFlip,
}

impl From<FlipRegions> for PartialFlipRegions {
    fn from(m: FlipRegions) -> Self {
        let FlipRegions { all, interior } = m;
        PartialFlipRegions {
            all: all.into(),
            interior: interior.into(),
        }
    }
}

impl From<&PartialFlipRegions> for FlipRegions {
    fn from(m: &PartialFlipRegions) -> Self {
        FlipRegions {
            all: (&m.all).into(),
            interior: (&m.interior).into(),
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialDisagreement {
    pixel: (u32, u32),
    light: usize,
    sample: usize,
    ours: Exact,
    reference: Exact,
    tie_distance: Exact,
    textured: bool,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialVerify {
    technique: String,
    declared_exact: bool,
    requested: u64,
    checked: u64,
    blocked: u64,
    disagreements: u64,
    beyond_tie: u64,
    textured: u64,
    max_tie_distance: Exact,
    tie_limit: Exact,
    worst: Option<PartialDisagreement>,
}

impl From<&VerifyReport> for PartialVerify {
    fn from(v: &VerifyReport) -> Self {
        let VerifyReport {
            technique,
            declared_exact,
            requested,
            checked,
            blocked,
            disagreements,
            beyond_tie,
            textured,
            max_tie_distance,
            tie_limit,
            worst,
        } = v.clone();
        PartialVerify {
            technique,
            declared_exact,
            requested,
            checked,
            blocked,
            disagreements,
            beyond_tie,
            textured,
            max_tie_distance: Exact(max_tie_distance),
            tie_limit: Exact(tie_limit),
            worst: worst.map(|d| {
                let Disagreement {
                    pixel,
                    light,
                    sample,
                    ours,
                    reference,
                    tie_distance,
                    textured,
                } = d;
                PartialDisagreement {
                    pixel,
                    light,
                    sample,
                    ours: Exact(ours),
                    reference: Exact(reference),
                    tie_distance: Exact(tie_distance),
                    textured,
                }
            }),
        }
    }
}

impl From<&PartialVerify> for VerifyReport {
    fn from(v: &PartialVerify) -> Self {
        VerifyReport {
            technique: v.technique.clone(),
            declared_exact: v.declared_exact,
            requested: v.requested,
            checked: v.checked,
            blocked: v.blocked,
            disagreements: v.disagreements,
            beyond_tie: v.beyond_tie,
            textured: v.textured,
            max_tie_distance: v.max_tie_distance.0,
            tie_limit: v.tie_limit.0,
            worst: v.worst.as_ref().map(|d| Disagreement {
                pixel: d.pixel,
                light: d.light,
                sample: d.sample,
                ours: d.ours.0,
                reference: d.reference.0,
                tie_distance: d.tie_distance.0,
                textured: d.textured,
            }),
        }
    }
}

/// One finished run in a partial: its [`RunResult`], exactly, and when
/// and where it ran.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialRun {
    /// Index into the sweep's scenes.
    pub scene: usize,
    /// Index among the scene's runs.
    pub index: usize,
    pub technique: String,
    pub setting: String,
    samples: Option<u32>,
    median_ms: Exact,
    min_ms: Exact,
    max_ms: Exact,
    runs: u32,
    /// The host that ran it.
    pub host: String,
    passes: Vec<(String, Exact)>,
    vcoef: Vec<Option<PartialRegion>>,
    vcoef_all_lights: Option<PartialRegion>,
    radiance: PartialRegion,
    flip: PartialFlipRegions,
    /// Radiance image, relative to the scene's directory.
    pub image: Option<String>,
    /// Heat maps, relative to the scene's directory.
    pub heatmaps: Vec<String>,
    verify: Option<PartialVerify>,
    /// Unix time the run started and ended (seconds).
    started_unix: Exact,
    finished_unix: Exact,
}

impl PartialRun {
    fn new(scene: usize, index: usize, r: &RunResult, started: f64, finished: f64) -> Self {
        let RunResult {
            technique,
            setting,
            samples,
            median_ms,
            min_ms,
            max_ms,
            runs,
            host,
            passes,
            vcoef,
            vcoef_all_lights,
            radiance,
            flip,
            pareto_flip: _, // decided by the merge, over every run
            pareto: _,
            image,
            heatmaps,
            verify,
        } = r.clone();
        PartialRun {
            scene,
            index,
            technique,
            setting,
            samples,
            median_ms: Exact(median_ms),
            min_ms: Exact(min_ms),
            max_ms: Exact(max_ms),
            runs,
            host,
            passes: passes
                .into_iter()
                .map(|p| (p.name, Exact(p.median_ms)))
                .collect(),
            vcoef: vcoef.into_iter().map(|m| m.map(Into::into)).collect(),
            vcoef_all_lights: vcoef_all_lights.map(Into::into),
            radiance: radiance.into(),
            flip: flip.into(),
            image,
            heatmaps,
            verify: verify.as_ref().map(Into::into),
            started_unix: Exact(started),
            finished_unix: Exact(finished),
        }
    }

    /// The run's result as the unsharded run would hold it.
    pub fn to_result(&self) -> RunResult {
        RunResult {
            technique: self.technique.clone(),
            setting: self.setting.clone(),
            samples: self.samples,
            median_ms: self.median_ms.0,
            min_ms: self.min_ms.0,
            max_ms: self.max_ms.0,
            runs: self.runs,
            host: self.host.clone(),
            passes: self
                .passes
                .iter()
                .map(|(name, ms)| PassMedian {
                    name: name.clone(),
                    median_ms: ms.0,
                })
                .collect(),
            vcoef: self
                .vcoef
                .iter()
                .map(|m| m.as_ref().map(Into::into))
                .collect(),
            vcoef_all_lights: self.vcoef_all_lights.as_ref().map(Into::into),
            radiance: (&self.radiance).into(),
            flip: (&self.flip).into(),
            pareto_flip: false,
            pareto: false,
            image: self.image.clone(),
            heatmaps: self.heatmaps.clone(),
            verify: self.verify.as_ref().map(Into::into),
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialFloor {
    rmse_all: Exact,
    mae_all: Exact,
    rmse_penumbra: Exact,
    mae_penumbra: Exact,
    rmse_interior: Exact,
    mae_interior: Exact,
}

impl From<NoiseFloor> for PartialFloor {
    fn from(f: NoiseFloor) -> Self {
        let NoiseFloor {
            rmse_all,
            mae_all,
            rmse_penumbra,
            mae_penumbra,
            rmse_interior,
            mae_interior,
        } = f;
        PartialFloor {
            rmse_all: Exact(rmse_all),
            mae_all: Exact(mae_all),
            rmse_penumbra: Exact(rmse_penumbra),
            mae_penumbra: Exact(mae_penumbra),
            rmse_interior: Exact(rmse_interior),
            mae_interior: Exact(mae_interior),
        }
    }
}

impl From<&PartialFloor> for NoiseFloor {
    fn from(f: &PartialFloor) -> Self {
        NoiseFloor {
            rmse_all: f.rmse_all.0,
            mae_all: f.mae_all.0,
            rmse_penumbra: f.rmse_penumbra.0,
            mae_penumbra: f.mae_penumbra.0,
            rmse_interior: f.rmse_interior.0,
            mae_interior: f.mae_interior.0,
        }
    }
}

/// A scene's part of the results (reference, regions), as a shard that
/// ran some of its runs found it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct PartialScene {
    scene: String,
    path: String,
    width: u32,
    height: u32,
    shading_points: u64,
    penumbra_points: Vec<u64>,
    interior_points: u64,
    reference_samples: u32,
    seeds: [u64; 2],
    reference_seconds: Exact,
    /// This shard read the reference from the cache.
    pub from_cache: bool,
    cache_file: String,
    floor_vcoef: Vec<PartialFloor>,
    floor_vcoef_all_lights: PartialFloor,
    floor_radiance: PartialFloor,
    flip_halves: PartialFlipRegions,
}

impl PartialScene {
    fn new(h: &SceneComparison) -> Self {
        let ReferenceSummary {
            samples,
            seeds,
            seconds,
            from_cache,
            cache_file,
            floor_vcoef,
            floor_vcoef_all_lights,
            floor_radiance,
            flip_halves,
        } = h.reference.clone();
        PartialScene {
            scene: h.scene.clone(),
            path: h.path.clone(),
            width: h.width,
            height: h.height,
            shading_points: h.shading_points,
            penumbra_points: h.penumbra_points.clone(),
            interior_points: h.interior_points,
            reference_samples: samples,
            seeds,
            reference_seconds: Exact(seconds),
            from_cache,
            cache_file,
            floor_vcoef: floor_vcoef.into_iter().map(Into::into).collect(),
            floor_vcoef_all_lights: floor_vcoef_all_lights.into(),
            floor_radiance: floor_radiance.into(),
            flip_halves: flip_halves.into(),
        }
    }

    /// The comparison without runs, as [`prepare_scene`] made it.
    pub fn to_header(&self) -> SceneComparison {
        SceneComparison {
            scene: self.scene.clone(),
            path: self.path.clone(),
            width: self.width,
            height: self.height,
            shading_points: self.shading_points,
            penumbra_points: self.penumbra_points.clone(),
            interior_points: self.interior_points,
            reference: ReferenceSummary {
                samples: self.reference_samples,
                seeds: self.seeds,
                seconds: self.reference_seconds.0,
                from_cache: self.from_cache,
                cache_file: self.cache_file.clone(),
                floor_vcoef: self.floor_vcoef.iter().map(Into::into).collect(),
                floor_vcoef_all_lights: (&self.floor_vcoef_all_lights).into(),
                floor_radiance: (&self.floor_radiance).into(),
                flip_halves: (&self.flip_halves).into(),
            },
            runs: Vec::new(),
            chart_flip: None,
            chart_flip_interior: None,
            chart_radiance: None,
            chart: None,
            chart_all: None,
        }
    }
}

/// What one shard wrote: `DIR/shard-I-of-N.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Partial {
    /// [`PARTIAL_FORMAT`].
    pub format: u32,
    /// The crate version that wrote it.
    pub version: String,
    /// This shard, 1-based.
    pub shard: u32,
    /// Shards in the sweep.
    pub shards: u32,
    /// Every option the results depend on, by its flag, with its value.
    pub options: Vec<(String, String)>,
    /// A hash of `options`, for a quick look.
    pub options_hash: String,
    /// The sweep's scenes.
    pub scenes: Vec<SceneId>,
    /// Every run of the sweep with its shard.
    pub plan: Vec<PlanEntry>,
    /// Per scene: its results header, if this shard ran any of its runs.
    pub headers: Vec<Option<PartialScene>>,
    /// The runs this shard finished, in the order they finished.
    pub runs: Vec<PartialRun>,
    /// Run images and heat maps were written.
    pub images: bool,
    /// The equivalent unsharded command (for the merged report).
    pub command: String,
    /// The host of the shard.
    pub host: String,
    /// All of this shard's runs are done.
    pub complete: bool,
}

/// The options the results depend on, by flag (not `--out`, the cache,
/// threads or images, which change no number).
fn option_entries(options: &CompareOptions) -> Vec<(String, String)> {
    let join = |v: Vec<String>| v.join(",");
    vec![
        (
            "--techniques".into(),
            join(
                options
                    .techniques
                    .iter()
                    .map(|t| t.name().to_string())
                    .collect(),
            ),
        ),
        (
            "--samples".into(),
            join(options.samples.iter().map(|s| s.to_string()).collect()),
        ),
        (
            "--reference-samples".into(),
            options.reference_samples.to_string(),
        ),
        (
            "--patterns".into(),
            join(options.patterns.iter().map(|p| format!("{p:?}")).collect()),
        ),
        ("--repeat".into(), options.repeat.to_string()),
        ("--width".into(), format!("{:?}", options.width)),
        ("--height".into(), format!("{:?}", options.height)),
        ("--seed".into(), options.seed.to_string()),
        ("--verify".into(), format!("{:?}", options.verify)),
        (
            "--sweep-settings".into(),
            options.sweep_settings.to_string(),
        ),
        (
            "technique options".into(),
            format!("{:?}", options.technique_options),
        ),
    ]
}

/// The sweep every shard plans.
pub(crate) struct Plan {
    /// The scenes' identities.
    pub ids: Vec<SceneId>,
    /// Every run with its shard.
    pub entries: Vec<PlanEntry>,
    /// Per scene, its runs ready to run.
    pub planned: Vec<Vec<PlannedRun>>,
}

/// The sweep every shard plans: scene identities and every run with its
/// shard.
pub(crate) fn plan(scenes: &[Scene], options: &CompareOptions, shards: u32) -> Result<Plan> {
    let mut ids = Vec::new();
    let mut entries = Vec::new();
    let mut planned = Vec::new();
    for (i, scene) in scenes.iter().enumerate() {
        let mut h = StableHasher::default();
        hash_scene(&mut h, scene);
        let dir = scene_dir(Path::new(""), &scene.name, scenes.len());
        ids.push(SceneId {
            name: scene.name.clone(),
            path: scene.path.display().to_string(),
            hash: format!("{:016x}", h.finish()),
            dir: dir.display().to_string(),
        });
        let runs = scene_runs(scene, options)?;
        for (index, run) in runs.iter().enumerate() {
            entries.push(PlanEntry {
                scene: i,
                index,
                technique: run.setting.curve.clone(),
                setting: run.setting.label.clone(),
                cost: run_cost(run, options.repeat),
                shard: 0,
            });
        }
        planned.push(runs);
    }
    let costs: Vec<u64> = entries.iter().map(|e| e.cost).collect();
    for (e, s) in entries.iter_mut().zip(assign(&costs, shards)) {
        e.shard = s;
    }
    Ok(Plan {
        ids,
        entries,
        planned,
    })
}

fn write_partial(path: &Path, partial: &Partial) -> Result<()> {
    let text = serde_json::to_string_pretty(partial)
        .map_err(|e| Error::param("--shard", e.to_string()))?;
    write_atomically(path, |tmp| {
        std::fs::write(tmp, (text + "\n").as_bytes()).map_err(|e| Error::io(tmp, e))
    })
}

/// What a shard did.
#[derive(Debug, Clone)]
pub struct ShardSummary {
    /// Its partial result.
    pub partial: PathBuf,
    /// Runs it made.
    pub runs: usize,
    /// Runs in the whole sweep.
    pub sweep_runs: usize,
}

/// Runs shard `shard` of the sweep over `scenes` with `options`, writing
/// its partial result and images into `out`. `command` is the equivalent
/// unsharded command line, for the merged report.
pub fn run_shard(
    scenes: &[Scene],
    options: &CompareOptions,
    shard: ShardSpec,
    out: &Path,
    command: &str,
    progress_bar: bool,
) -> Result<ShardSummary> {
    options.validate()?;
    let Plan {
        ids,
        entries: plan,
        planned,
    } = plan(scenes, options, shard.count)?;
    let mine: Vec<&PlanEntry> = plan.iter().filter(|e| e.shard == shard.index).collect();
    let entries = option_entries(options);
    let mut h = StableHasher::default();
    for (k, v) in &entries {
        h.str(k);
        h.str(v);
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let path = out.join(shard.file_name());
    let mut partial = Partial {
        format: PARTIAL_FORMAT,
        version: env!("CARGO_PKG_VERSION").to_string(),
        shard: shard.index,
        shards: shard.count,
        options: entries,
        options_hash: format!("{:016x}", h.finish()),
        scenes: ids,
        plan: plan.clone(),
        headers: vec![None; scenes.len()],
        runs: Vec::new(),
        images: options.images,
        command: command.to_string(),
        host: host_name(),
        complete: false,
    };
    // Written before any work: a shard that dies at once is still named
    // (incomplete) rather than absent, and a bad --out fails early.
    write_partial(&path, &partial)?;
    // Shard 1 also prepares any scene without runs, so that the merge
    // lists it as an unsharded run would.
    let needed: std::collections::BTreeSet<usize> = mine
        .iter()
        .map(|e| e.scene)
        .chain(
            (0..scenes.len()).filter(|&s| shard.index == 1 && !plan.iter().any(|e| e.scene == s)),
        )
        .collect();
    let mut work = Vec::new();
    for &s in &needed {
        let runs = mine
            .iter()
            .filter(|e| e.scene == s)
            .map(|e| (e.index, &planned[s][e.index]));
        work.extend(scene_work(s, &scenes[s], options, runs)?);
    }
    let progress = Progress::sweep(work, progress_bar);
    for &s in &needed {
        let scene = &scenes[s];
        let dir = out.join(&partial.scenes[s].dir);
        let here: Vec<usize> = (mine.iter())
            .filter(|e| e.scene == s)
            .map(|e| e.index)
            .collect();
        // Recorded in the partial as they finish (the merge finds runs by
        // their index).
        let prepared = run_scene(
            s,
            scene,
            &planned[s],
            &here,
            options,
            Some(&dir),
            &progress,
            |prepared, index, result, (started, finished)| {
                partial.headers[s] = Some(PartialScene::new(&prepared.header));
                (partial.runs).push(PartialRun::new(s, index, &result, started, finished));
                write_partial(&path, &partial)
            },
        )?;
        partial.headers[s] = Some(PartialScene::new(&prepared.header));
    }
    partial.complete = true;
    write_partial(&path, &partial)?;
    progress.finish();
    Ok(ShardSummary {
        partial: path,
        runs: mine.len(),
        sweep_runs: plan.len(),
    })
}

/// What shard `shard` of the sweep over `scenes` prints before any run
/// starts: per scene it prepares, its runs and the reference
/// ([`run_listing`]), out of the sweep's.
pub fn shard_listing(
    scenes: &[Scene],
    options: &CompareOptions,
    shard: ShardSpec,
) -> Result<Vec<String>> {
    let Plan {
        entries, planned, ..
    } = plan(scenes, options, shard.count)?;
    let mut lines = Vec::new();
    for (s, scene) in scenes.iter().enumerate() {
        let mine: Vec<&PlannedRun> = (entries.iter())
            .filter(|e| e.scene == s && e.shard == shard.index)
            .map(|e| &planned[s][e.index])
            .collect();
        let empty = !entries.iter().any(|e| e.scene == s);
        if mine.is_empty() && !(empty && shard.index == 1) {
            continue;
        }
        let prefix = format!(
            "compare shard {shard} ({} of the sweep's {} runs)",
            entries.iter().filter(|e| e.shard == shard.index).count(),
            entries.len()
        );
        lines.push(run_listing(&prefix, scene, options, mine)?);
    }
    Ok(lines)
}

/// The equivalent unsharded command of a command line: `args` (without
/// the program) minus `--shard I/N`, shell-quoted.
pub fn unsharded_command(args: &[String]) -> String {
    let mut kept = Vec::new();
    let mut skip = false;
    for a in args {
        if std::mem::take(&mut skip) {
            continue;
        }
        if a == "--shard" {
            skip = true;
            continue;
        }
        if a.starts_with("--shard=") {
            continue;
        }
        kept.push(a);
    }
    let quoted: Vec<String> = kept
        .iter()
        .map(|a| {
            if a.is_empty() || a.contains(|c: char| c.is_whitespace() || "'\"$`".contains(c)) {
                format!("'{}'", a.replace('\'', "'\\''"))
            } else {
                a.to_string()
            }
        })
        .collect();
    format!("penumbra {}", quoted.join(" "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_specs_parse_and_refuse() {
        assert_eq!(
            ShardSpec::parse("2/3").unwrap(),
            ShardSpec { index: 2, count: 3 }
        );
        for bad in ["0/3", "4/3", "1/0", "3", "a/b", "-1/3", ""] {
            let e = ShardSpec::parse(bad).unwrap_err().to_string();
            assert!(e.contains("--shard"), "{bad}: {e}");
        }
    }

    #[test]
    fn lpt_balances_and_is_deterministic() {
        let costs = [10, 7, 7, 5, 3, 3, 2, 1, 1, 1];
        let a = assign(&costs, 3);
        assert_eq!(a, assign(&costs, 3));
        let mut load = [0u64; 3];
        for (c, s) in costs.iter().zip(&a) {
            assert!((1..=3).contains(s));
            load[*s as usize - 1] += c;
        }
        // 40 in total: LPT reaches the best possible, 14/13/13.
        assert_eq!(*load.iter().max().unwrap(), 14, "{load:?}");
        // More shards than runs: every run alone, the rest idle.
        let b = assign(&[5, 5], 4);
        assert_ne!(b[0], b[1]);
    }

    #[test]
    fn exact_floats_round_trip_bit_for_bit() {
        for x in [
            0.1,
            1.0 / 3.0,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::INFINITY,
            -0.0,
            1e-7,
            123456.789e100,
        ] {
            let s = serde_json::to_string(&Exact(x)).unwrap();
            let y: Exact = serde_json::from_str(&s).unwrap();
            assert_eq!(x.to_bits(), y.0.to_bits(), "{x:e} via {s}");
        }
    }

    #[test]
    fn the_unsharded_command_drops_the_shard() {
        let args: Vec<String> = [
            "compare",
            "a b.toml",
            "--shard",
            "2/4",
            "--out",
            "d",
            "--shard=1/2",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        assert_eq!(
            unsharded_command(&args),
            "penumbra compare 'a b.toml' --out d"
        );
    }
}

#[cfg(test)]
mod plan_tests {
    use super::*;
    use crate::compare::pipeline::{progress_steps, sweep_work};
    use crate::render::Technique;

    /// The shards' plan, the progress steps, the time estimate's work and
    /// the listing are of one list of runs, with and without
    /// `--sweep-settings`.
    #[test]
    fn the_plan_the_steps_and_the_estimate_share_one_list() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/quad.toml");
        let scene = crate::scene::load_scene(&path).expect("quad loads");
        let scenes = [scene.clone(), scene];
        for sweep_settings in [false, true] {
            let options = CompareOptions {
                techniques: ["dcs", "shadow-map", "reference"]
                    .map(|t| Technique::named(t).expect("registered"))
                    .to_vec(),
                samples: vec![4, 16],
                width: Some(32),
                height: Some(24),
                repeat: 2,
                sweep_settings,
                ..CompareOptions::default()
            };
            let Plan { entries, .. } = plan(&scenes, &options, 3).expect("plans");
            let runs = scene_runs(&scenes[0], &options).expect("runs");
            assert_eq!(entries.len(), 2 * runs.len());
            assert_eq!(runs.len(), if sweep_settings { 10 } else { 5 });
            assert_eq!(
                progress_steps(&scenes, &options).expect("steps"),
                2 * 2 + entries.len() as u64 * 2
            );
            let work = sweep_work(&scenes, &options).expect("work");
            let timed: Vec<_> = work.iter().filter(|w| w.run.is_some()).collect();
            assert_eq!(timed.len(), entries.len());
            for (w, e) in timed.iter().zip(&entries) {
                assert_eq!(
                    (w.scene, w.run, &w.curve),
                    (e.scene, Some(e.index), &e.technique)
                );
            }
            assert_eq!(work.iter().filter(|w| w.run.is_none()).count(), 2);
            // Every shard's listing names its runs, and together they
            // are the sweep's.
            let (mut listed, mut marked) = (0, false);
            for index in 1..=3 {
                let shard = ShardSpec { index, count: 3 };
                for line in shard_listing(&scenes, &options, shard).expect("lists") {
                    let n: usize = line
                        .split(": ")
                        .nth(1)
                        .and_then(|l| l.split(' ').next())
                        .and_then(|n| n.parse().ok())
                        .expect("a count");
                    listed += n;
                    marked |= line.contains("[--sweep-settings]");
                }
            }
            assert_eq!(listed, entries.len());
            assert_eq!(marked, sweep_settings);
        }
    }
}
