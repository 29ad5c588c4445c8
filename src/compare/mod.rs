//! `penumbra compare`: every technique at every quality setting, timed and
//! measured against a ray-traced reference at the same receiver points.
//!
//! Every render of a scene uses the same view, so the G-buffer — the
//! receiver points — is the same bit for bit in each; errors are therefore
//! differences of the shadow term alone (plus, for radiance, the error of
//! modulating unshadowed light by Vcoef).
//!
//! The headline error is the image's: radiance RMSE, and FLIP of the image
//! tone-mapped as the PNG output against the reference's
//! ([`crate::report::flip`]), over the whole frame and over the interior
//! (shading points away from geometric edges, [`crate::report::interior`],
//! from a shadowless render's G-buffer of the same view). Vcoef errors
//! follow as a second table.
//!
//! The reference is two independent half-sample references (different
//! seeds). Their mean is the reference every technique is measured
//! against; half their difference estimates the reference's own error (its
//! noise floor): for independent estimates `A`, `B` of variance `2σ²/M`
//! each, `(A − B)/2` has the variance `σ²/M` of the mean `(A + B)/2`.
//!
//! [`compare`] is the whole comparison as one call, returning the rows
//! of `results.csv` as [`Record`]s; the command goes through the same
//! sweep, so the two cannot drift.
//!
//! A sweep can be sharded over machines ([`shard`], `--shard I/N`) and
//! merged back ([`merge_partials`], `--merge`): [`compare_scene`] is
//! `scene_runs` (the plan), `prepare_scene` (the reference),
//! `run_planned` per run and `finish_scene` (Pareto front, charts), so
//! shards run the same steps on their share and the merge finishes with
//! the same code; results are deterministic, so merged errors are the
//! unsharded run's bit for bit.

pub mod cache;
mod charts;
mod host;
mod merge;
mod model;
mod pipeline;
mod record;
mod reference;
mod results;
mod run;
mod settings;
pub mod shard;
pub mod share;

pub use crate::shadow::technique::{has_semi_opaque_casters, QualitySetting};
pub use charts::{scene_charts, ChartSpec, HEATMAP_SCALE};
pub use host::host_name;
pub use merge::merge_partials;
pub use model::{
    NoiseFloor, PassMedian, ReferenceSummary, RegionMetrics, RunResult, SceneComparison,
};
pub use pipeline::{compare, compare_scene, compare_with, progress_steps, scene_dir};
pub(crate) use pipeline::{sweep, sweep_listing, sweep_work, SweepOutput};
pub use record::{records, Record, CSV_COLUMNS};
pub use reference::reference_only;
pub use results::{check_verified, write_csv, write_json, write_markdown, write_results};
pub use settings::{quality_settings, CompareOptions, SettingRun, SWEEP_SETTINGS};
