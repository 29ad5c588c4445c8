//! `compare`'s records: what a comparison measured, per run and per
//! scene. Kept apart from the code that fills them (`run`, `reference`,
//! `pipeline`) and the code that reads them (`results`, `charts`, `shard`,
//! `merge`) so that every other file of `compare` can depend on them
//! without depending on each other.

use crate::report::{ErrorMetrics, FlipRegions};
use crate::shadow::kit::verify::VerifyReport;
use serde::Serialize;

/// Errors over all shading points, over the penumbra only and over the
/// interior (shading points away from geometric edges).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct RegionMetrics {
    /// Every shading point.
    pub all: ErrorMetrics,
    /// Points whose reference Vcoef is strictly between 0 and 1 (for
    /// radiance: for some light).
    pub penumbra: ErrorMetrics,
    /// Points farther than 2 px from the background and from depth and
    /// normal discontinuities ([`crate::report::interior`]).
    pub interior: ErrorMetrics,
}

/// Median time of one pass over the repeats.
#[derive(Debug, Clone, Serialize)]
pub struct PassMedian {
    /// Pass name.
    pub name: String,
    /// Median wall-clock milliseconds.
    pub median_ms: f64,
}

/// One technique at one setting.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    /// Technique name.
    pub technique: String,
    /// Setting label.
    pub setting: String,
    /// Light samples, where the technique samples.
    pub samples: Option<u32>,
    /// Median wall-clock time of a whole render (scene loading excluded).
    pub median_ms: f64,
    /// Fastest run.
    pub min_ms: f64,
    /// Slowest run.
    pub max_ms: f64,
    /// Timed runs.
    pub runs: u32,
    /// The host that timed it (sharded sweeps run on many).
    pub host: String,
    /// Per-pass medians, in execution order.
    pub passes: Vec<PassMedian>,
    /// Vcoef error per light (`None` where the technique gives no Vcoef).
    pub vcoef: Vec<Option<RegionMetrics>>,
    /// Vcoef error over every light's values together.
    pub vcoef_all_lights: Option<RegionMetrics>,
    /// Radiance error over R, G and B values together.
    pub radiance: RegionMetrics,
    /// FLIP of the image (tone-mapped as the PNG output) against the
    /// reference's, over the whole frame and over the interior.
    pub flip: FlipRegions,
    /// On the Pareto front of (time, FLIP mean over the whole frame).
    pub pareto_flip: bool,
    /// On the Pareto front of (time, penumbra Vcoef RMSE).
    pub pareto: bool,
    /// Radiance image, relative to the output directory.
    pub image: Option<String>,
    /// Vcoef heat maps per light, relative to the output directory.
    pub heatmaps: Vec<String>,
    /// `--verify`: its exactness certificate (techniques that expose their
    /// decisions).
    pub verify: Option<VerifyReport>,
}

impl RunResult {
    /// Sum of the median times of passes whose name starts with `prefix`.
    pub fn pass_ms(&self, pred: impl Fn(&str) -> bool) -> f64 {
        self.passes
            .iter()
            .filter(|p| pred(&p.name))
            .map(|p| p.median_ms)
            .sum()
    }
}

/// The reference's own error, estimated from its two halves.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct NoiseFloor {
    /// Estimated RMSE of the reference over all shading points.
    pub rmse_all: f64,
    /// Estimated mean absolute error over all shading points.
    pub mae_all: f64,
    /// Estimated RMSE over the penumbra.
    pub rmse_penumbra: f64,
    /// Estimated mean absolute error over the penumbra.
    pub mae_penumbra: f64,
    /// Estimated RMSE over the interior.
    pub rmse_interior: f64,
    /// Estimated mean absolute error over the interior.
    pub mae_interior: f64,
}

/// The reference every run is measured against.
#[derive(Debug, Clone, Serialize)]
pub struct ReferenceSummary {
    /// Samples per light (both halves together).
    pub samples: u32,
    /// Seeds of the halves.
    pub seeds: [u64; 2],
    /// Wall-clock seconds it took when computed.
    pub seconds: f64,
    /// Read from the cache instead of computed.
    pub from_cache: bool,
    /// The cache file.
    pub cache_file: String,
    /// Noise floor of Vcoef per light.
    pub floor_vcoef: Vec<NoiseFloor>,
    /// Noise floor of Vcoef over all lights.
    pub floor_vcoef_all_lights: NoiseFloor,
    /// Noise floor of radiance.
    pub floor_radiance: NoiseFloor,
    /// FLIP of one half against the other (each with half the samples):
    /// how visible the reference's own noise is at half its samples. Not
    /// a floor (FLIP is not linear in the error), an indication.
    pub flip_halves: FlipRegions,
}

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
    /// Shading points in the interior (away from geometric edges).
    pub interior_points: u64,
    /// The reference.
    pub reference: ReferenceSummary,
    /// Every run, in order.
    pub runs: Vec<RunResult>,
    /// FLIP-vs-time chart (mean over the whole frame), relative to the
    /// output directory.
    pub chart_flip: Option<String>,
    /// FLIP-vs-time chart (mean over the interior).
    pub chart_flip_interior: Option<String>,
    /// Radiance-RMSE-vs-time chart (all shading points).
    pub chart_radiance: Option<String>,
    /// Vcoef-error-vs-time chart (penumbra).
    pub chart: Option<String>,
    /// Vcoef-error-vs-time chart (all shading points).
    pub chart_all: Option<String>,
}
