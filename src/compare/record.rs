//! `compare`'s rows as data: one [`Record`] per row of `results.csv`.
//! [`records`] is the one place rows are made; `write_csv` prints these
//! records, so the file and the records a library caller gets cannot
//! differ.

use super::model::{NoiseFloor, RegionMetrics, RunResult, SceneComparison};
use crate::report::{ErrorMetrics, FlipMetrics};
use serde::Serialize;

/// The columns of `results.csv`, in order: [`Record`]'s fields.
pub const CSV_COLUMNS: [&str; 30] = [
    "scene",
    "technique",
    "setting",
    "samples",
    "median_ms",
    "min_ms",
    "max_ms",
    "runs",
    "host",
    "geometry_ms",
    "gbuffer_ms",
    "shadow_ms",
    "shading_ms",
    "quantity",
    "region",
    "count",
    "rmse",
    "mean_abs",
    "max_abs",
    "frac_over",
    "non_finite",
    "p50",
    "p90",
    "p99",
    "pareto_flip",
    "pareto",
    "verify_checked",
    "verify_disagreements",
    "verify_beyond_tie",
    "verify_max_tie",
];

/// One row of `results.csv`, as data: a run's (or the reference's) error
/// in one quantity over one region. `None` is an empty cell.
///
/// Rows come per scene: each run's (`radiance` and `flip`, then
/// `vcoef.<k>` per light and `vcoef` over all lights, each per region),
/// then the reference's noise floors (technique `reference-floor`) and
/// FLIP between its halves (technique `reference-halves`), which have no
/// times, host, Pareto or verify cells.
///
/// The values are the file's: times are rounded to 4 decimals (0.1 µs) as
/// the file prints them; every other number is exact (the file prints the
/// shortest decimal that reads back to the same `f64`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Record {
    /// Scene name.
    pub scene: String,
    /// Technique name, or `reference-floor` / `reference-halves`.
    pub technique: String,
    /// Quality setting label.
    pub setting: String,
    /// Light samples, where the technique samples (per half for
    /// `reference-halves`).
    pub samples: Option<u32>,
    /// Median wall-clock milliseconds of a whole render.
    pub median_ms: Option<f64>,
    /// Fastest run, milliseconds.
    pub min_ms: Option<f64>,
    /// Slowest run, milliseconds.
    pub max_ms: Option<f64>,
    /// Timed runs.
    pub runs: Option<u32>,
    /// The host that timed the run.
    pub host: Option<String>,
    /// Median milliseconds of the geometry pass.
    pub geometry_ms: Option<f64>,
    /// Median milliseconds of the G-buffer pass.
    pub gbuffer_ms: Option<f64>,
    /// Median milliseconds of the shadow technique's own passes.
    pub shadow_ms: Option<f64>,
    /// Median milliseconds of the shading pass.
    pub shading_ms: Option<f64>,
    /// `radiance`, `flip`, `vcoef.<k>` (light k) or `vcoef` (all lights).
    pub quantity: String,
    /// `all`, `penumbra` or `interior`.
    pub region: String,
    /// Values measured.
    pub count: Option<u64>,
    /// Root mean square error (not for `flip`).
    pub rmse: Option<f64>,
    /// Mean absolute error; for `flip` the FLIP mean.
    pub mean_abs: f64,
    /// Largest absolute error; for `flip` the FLIP maximum.
    pub max_abs: Option<f64>,
    /// Share of values off by more than 1/255.
    pub frac_over: Option<f64>,
    /// Values that were not finite.
    pub non_finite: Option<u64>,
    /// FLIP median.
    pub p50: Option<f64>,
    /// FLIP 90th percentile.
    pub p90: Option<f64>,
    /// FLIP 99th percentile.
    pub p99: Option<f64>,
    /// On the Pareto front of (time, FLIP mean over the whole frame).
    pub pareto_flip: Option<bool>,
    /// On the Pareto front of (time, penumbra Vcoef RMSE).
    pub pareto: Option<bool>,
    /// `--verify`: relations checked.
    pub verify_checked: Option<u64>,
    /// `--verify`: relations where the technique and the shadow rays
    /// disagree.
    pub verify_disagreements: Option<u64>,
    /// `--verify`: disagreements beyond the tie distance.
    pub verify_beyond_tie: Option<u64>,
    /// `--verify`: largest tie distance among the disagreements.
    pub verify_max_tie: Option<f64>,
}

impl Record {
    /// The row as `results.csv` prints it, one cell per [`CSV_COLUMNS`].
    pub fn csv_cells(&self) -> [String; 30] {
        let text = |v: &Option<String>| v.clone().unwrap_or_default();
        let int = |v: Option<u64>| v.map_or(String::new(), |v| v.to_string());
        let ms = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
        let exp = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
        let flag = |v: Option<bool>| v.map_or(String::new(), |v| v.to_string());
        [
            self.scene.clone(),
            self.technique.clone(),
            self.setting.clone(),
            int(self.samples.map(u64::from)),
            ms(self.median_ms),
            ms(self.min_ms),
            ms(self.max_ms),
            int(self.runs.map(u64::from)),
            text(&self.host),
            ms(self.geometry_ms),
            ms(self.gbuffer_ms),
            ms(self.shadow_ms),
            ms(self.shading_ms),
            self.quantity.clone(),
            self.region.clone(),
            int(self.count),
            exp(self.rmse),
            exp(Some(self.mean_abs)),
            exp(self.max_abs),
            exp(self.frac_over),
            int(self.non_finite),
            exp(self.p50),
            exp(self.p90),
            exp(self.p99),
            flag(self.pareto_flip),
            flag(self.pareto),
            int(self.verify_checked),
            int(self.verify_disagreements),
            int(self.verify_beyond_tie),
            exp(self.verify_max_tie),
        ]
    }
}

impl Record {
    /// A row of `scene` naming its run and nothing else.
    fn blank(
        scene: &SceneComparison,
        technique: &str,
        setting: String,
        samples: Option<u32>,
    ) -> Record {
        Record {
            scene: scene.scene.clone(),
            technique: technique.to_string(),
            setting,
            samples,
            median_ms: None,
            min_ms: None,
            max_ms: None,
            runs: None,
            host: None,
            geometry_ms: None,
            gbuffer_ms: None,
            shadow_ms: None,
            shading_ms: None,
            quantity: String::new(),
            region: String::new(),
            count: None,
            rmse: None,
            mean_abs: 0.0,
            max_abs: None,
            frac_over: None,
            non_finite: None,
            p50: None,
            p90: None,
            p99: None,
            pareto_flip: None,
            pareto: None,
            verify_checked: None,
            verify_disagreements: None,
            verify_beyond_tie: None,
            verify_max_tie: None,
        }
    }
}

/// `x` as the CSV prints it (4 decimals), read back: the records hold the
/// file's values, so that they equal the file read back.
fn ms(x: f64) -> f64 {
    format!("{x:.4}").parse().unwrap_or(x)
}

/// Passes that are not the shadow technique's own.
pub(super) fn is_common_pass(name: &str) -> bool {
    matches!(name, "geometry" | "gbuffer" | "shading")
}

/// Every row of `results.csv` for `scenes`, in the file's order: per
/// scene, each run's rows, then the reference's.
pub fn records(scenes: &[SceneComparison]) -> Vec<Record> {
    let mut rows = Vec::new();
    for scene in scenes {
        for run in &scene.runs {
            run_records(&mut rows, scene, run);
        }
        reference_records(&mut rows, scene);
    }
    rows
}

/// A row's error cells: those of a per-value error or of a FLIP error.
struct ErrorCells {
    count: Option<u64>,
    rmse: Option<f64>,
    mean_abs: f64,
    max_abs: Option<f64>,
    frac_over: Option<f64>,
    non_finite: Option<u64>,
    percentiles: Option<[f64; 3]>,
}

impl ErrorCells {
    fn of_error(m: &ErrorMetrics) -> Self {
        ErrorCells {
            count: Some(m.count),
            rmse: Some(m.rmse),
            mean_abs: m.mean_abs,
            max_abs: Some(m.max_abs),
            frac_over: Some(m.frac_over),
            non_finite: Some(m.non_finite),
            percentiles: None,
        }
    }

    /// FLIP's mean as `mean_abs`, its maximum as `max_abs`.
    fn of_flip(m: &FlipMetrics) -> Self {
        ErrorCells {
            count: Some(m.count),
            rmse: None,
            mean_abs: m.mean,
            max_abs: Some(m.max),
            frac_over: None,
            non_finite: None,
            percentiles: Some([m.p50, m.p90, m.p99]),
        }
    }

    /// A noise floor's: RMSE and mean absolute error only.
    fn of_floor(rmse: f64, mean_abs: f64) -> Self {
        ErrorCells {
            count: None,
            rmse: Some(rmse),
            mean_abs,
            max_abs: None,
            frac_over: None,
            non_finite: None,
            percentiles: None,
        }
    }

    /// The row of `quantity` over `region` with these cells, the others
    /// taken from `base`.
    fn row(self, base: &Record, quantity: &str, region: &str) -> Record {
        let [p50, p90, p99] = self.percentiles.map_or([None; 3], |p| p.map(Some));
        Record {
            quantity: quantity.to_string(),
            region: region.to_string(),
            count: self.count,
            rmse: self.rmse,
            mean_abs: self.mean_abs,
            max_abs: self.max_abs,
            frac_over: self.frac_over,
            non_finite: self.non_finite,
            p50,
            p90,
            p99,
            ..base.clone()
        }
    }
}

/// A run's rows: radiance and FLIP, then Vcoef per light and over all
/// lights, each per region.
fn run_records(rows: &mut Vec<Record>, scene: &SceneComparison, run: &RunResult) {
    let verify = run.verify.as_ref();
    let base = Record {
        median_ms: Some(ms(run.median_ms)),
        min_ms: Some(ms(run.min_ms)),
        max_ms: Some(ms(run.max_ms)),
        runs: Some(run.runs),
        host: Some(run.host.clone()),
        geometry_ms: Some(ms(run.pass_ms(|n| n == "geometry"))),
        gbuffer_ms: Some(ms(run.pass_ms(|n| n == "gbuffer"))),
        shadow_ms: Some(ms(run.pass_ms(|n| !is_common_pass(n)))),
        shading_ms: Some(ms(run.pass_ms(|n| n == "shading"))),
        pareto_flip: Some(run.pareto_flip),
        pareto: Some(run.pareto),
        verify_checked: verify.map(|v| v.checked),
        verify_disagreements: verify.map(|v| v.disagreements),
        verify_beyond_tie: verify.map(|v| v.beyond_tie),
        verify_max_tie: verify.map(|v| v.max_tie_distance),
        ..Record::blank(scene, &run.technique, run.setting.clone(), run.samples)
    };
    region_rows(rows, &base, "radiance", &run.radiance);
    for (region, m) in [("all", &run.flip.all), ("interior", &run.flip.interior)] {
        rows.push(ErrorCells::of_flip(m).row(&base, "flip", region));
    }
    for (light, metrics) in run.vcoef.iter().enumerate() {
        if let Some(metrics) = metrics {
            region_rows(rows, &base, &format!("vcoef.{light}"), metrics);
        }
    }
    if let Some(metrics) = &run.vcoef_all_lights {
        region_rows(rows, &base, "vcoef", metrics);
    }
}

/// `base`'s rows of `quantity` over each region of `metrics`.
fn region_rows(rows: &mut Vec<Record>, base: &Record, quantity: &str, metrics: &RegionMetrics) {
    for (region, m) in [
        ("all", &metrics.all),
        ("penumbra", &metrics.penumbra),
        ("interior", &metrics.interior),
    ] {
        rows.push(ErrorCells::of_error(m).row(base, quantity, region));
    }
}

/// The reference's rows: its noise floors (radiance, Vcoef per light and
/// over all lights, per region), then FLIP between its halves.
fn reference_records(rows: &mut Vec<Record>, scene: &SceneComparison) {
    let reference = &scene.reference;
    let floor_base = Record::blank(
        scene,
        "reference-floor",
        format!("{} spp", reference.samples),
        Some(reference.samples),
    );
    let mut floor_rows = |quantity: &str, floor: &NoiseFloor| {
        for (region, rmse, mae) in [
            ("all", floor.rmse_all, floor.mae_all),
            ("penumbra", floor.rmse_penumbra, floor.mae_penumbra),
            ("interior", floor.rmse_interior, floor.mae_interior),
        ] {
            rows.push(ErrorCells::of_floor(rmse, mae).row(&floor_base, quantity, region));
        }
    };
    floor_rows("radiance", &reference.floor_radiance);
    for (light, floor) in reference.floor_vcoef.iter().enumerate() {
        floor_rows(&format!("vcoef.{light}"), floor);
    }
    floor_rows("vcoef", &reference.floor_vcoef_all_lights);
    let half = reference.samples / 2;
    let halves_base = Record::blank(
        scene,
        "reference-halves",
        format!("{half} spp vs {half} spp"),
        Some(half),
    );
    for (region, m) in [
        ("all", &reference.flip_halves.all),
        ("interior", &reference.flip_halves.interior),
    ] {
        rows.push(ErrorCells::of_flip(m).row(&halves_base, "flip", region));
    }
}
