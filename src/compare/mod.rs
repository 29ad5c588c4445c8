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
mod results;

use crate::sampling::SamplePattern;
use crate::shadow::registry::Sweep;
pub use crate::shadow::registry::{has_semi_opaque_casters, QualitySetting};
use crate::shadow::TechniqueOptions;
pub use results::{write_csv, write_json, write_markdown};

use crate::error::{Error, Result};
use crate::output::write_png;
use crate::render::{render, Aov, RenderOptions, RenderOutput, Technique};
use crate::report::{
    error_metrics, pareto_front, write_error_heatmap, write_error_vs_time, ChartPoint,
    ErrorAccumulator, ErrorMetrics, Progress,
};
use crate::scene::Scene;
use cache::{CachedReference, ReferenceHalf, ReferenceKey, StableHasher, REFERENCE_VERSION};
use glam::Vec3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Errors at or above this show brightest in the Vcoef heat maps.
pub const HEATMAP_SCALE: f32 = 0.25;

/// What `compare` runs.
#[derive(Debug, Clone)]
pub struct CompareOptions {
    /// Techniques to measure, in order.
    pub techniques: Vec<Technique>,
    /// The techniques' options every quality setting starts from.
    pub technique_options: TechniqueOptions,
    /// Light-sample counts for techniques that sample.
    pub samples: Vec<u32>,
    /// Samples per light of the reference (even: two halves).
    pub reference_samples: u32,
    /// Timed runs per setting (the median is reported).
    pub repeat: u32,
    /// Image width override.
    pub width: Option<u32>,
    /// Image height override.
    pub height: Option<u32>,
    /// Seed of the techniques' samples (the reference derives its own).
    pub seed: u64,
    /// Where cached references live.
    pub cache_dir: PathBuf,
    /// Write per-run images and heat maps.
    pub images: bool,
    /// Sample patterns DCS is measured with (one curve each); the first
    /// is also the reference's and whole-light silhouettes' pattern.
    pub patterns: Vec<SamplePattern>,
}

impl CompareOptions {
    /// Checks the options before any work starts.
    pub fn validate(&self) -> Result<()> {
        if self.techniques.is_empty() {
            return Err(Error::param("--techniques", "name at least one technique"));
        }
        if self.samples.is_empty() {
            return Err(Error::param("--samples", "give at least one sample count"));
        }
        if self.patterns.is_empty() {
            return Err(Error::param(
                "--patterns",
                "give at least one sample pattern",
            ));
        }
        if let Some(&s) = self.samples.iter().find(|&&s| s == 0 || s > 1 << 20) {
            return Err(Error::param(
                "--samples",
                format!("{s} is outside 1..=1048576"),
            ));
        }
        let m = self.reference_samples;
        if m < 2 || !m.is_multiple_of(2) || m > 1 << 21 {
            return Err(Error::param(
                "--reference-samples",
                format!("{m} must be even and in 2..=2097152 (the reference is two halves)"),
            ));
        }
        if self.repeat == 0 || self.repeat > 1000 {
            return Err(Error::param(
                "--repeat",
                format!("{} is outside 1..=1000", self.repeat),
            ));
        }
        for (name, v) in [("--width", self.width), ("--height", self.height)] {
            if v == Some(0) {
                return Err(Error::param(name, "must be at least 1"));
            }
        }
        Ok(())
    }

    /// The two reference halves' seeds: distinct from each other and from
    /// the techniques' seed, so no technique shares the reference's noise.
    pub fn reference_seeds(&self) -> [u64; 2] {
        [
            splitmix(self.seed ^ 0x5245_4630),
            splitmix(self.seed ^ 0x5245_4631),
        ]
    }
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The quality settings `compare` runs for `technique`, from the
/// registry, as render options on top of `base`.
pub fn quality_settings(
    technique: Technique,
    samples: &[u32],
    patterns: &[SamplePattern],
    semi_opaque: bool,
    base: &RenderOptions,
) -> Vec<(QualitySetting, RenderOptions)> {
    let sweep = Sweep {
        samples,
        patterns,
        semi_opaque,
        base: &base.options,
    };
    technique
        .quality_settings(&sweep)
        .into_iter()
        .map(|q| {
            let options = RenderOptions {
                technique,
                samples: q.samples.unwrap_or(base.samples),
                pattern: q.pattern,
                options: q.options.clone(),
                ..base.clone()
            };
            (q, options)
        })
        .collect()
}

/// Errors over all shading points and over the penumbra only.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct RegionMetrics {
    /// Every shading point.
    pub all: ErrorMetrics,
    /// Points whose reference Vcoef is strictly between 0 and 1 (for
    /// radiance: for some light).
    pub penumbra: ErrorMetrics,
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
    /// Per-pass medians, in execution order.
    pub passes: Vec<PassMedian>,
    /// Vcoef error per light (`None` where the technique gives no Vcoef).
    pub vcoef: Vec<Option<RegionMetrics>>,
    /// Vcoef error over every light's values together.
    pub vcoef_all_lights: Option<RegionMetrics>,
    /// Radiance error over R, G and B values together.
    pub radiance: RegionMetrics,
    /// On the Pareto front of (time, penumbra Vcoef RMSE).
    pub pareto: bool,
    /// Radiance image, relative to the output directory.
    pub image: Option<String>,
    /// Vcoef heat maps per light, relative to the output directory.
    pub heatmaps: Vec<String>,
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
}

impl NoiseFloor {
    fn from_halves(m: RegionMetrics) -> Self {
        NoiseFloor {
            rmse_all: m.all.rmse / 2.0,
            mae_all: m.all.mean_abs / 2.0,
            rmse_penumbra: m.penumbra.rmse / 2.0,
            mae_penumbra: m.penumbra.mean_abs / 2.0,
        }
    }
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
    /// The reference.
    pub reference: ReferenceSummary,
    /// Every run, in order.
    pub runs: Vec<RunResult>,
    /// Error-vs-time chart (penumbra), relative to the output directory.
    pub chart: Option<String>,
    /// Error-vs-time chart (all shading points).
    pub chart_all: Option<String>,
}

/// The reference images a comparison measures against.
struct ReferenceImages {
    surface: Vec<bool>,
    radiance: Vec<Vec3>,
    vcoef: Vec<Vec<f32>>,
    /// Per light: reference Vcoef strictly inside (0, 1).
    penumbra: Vec<Vec<bool>>,
    /// Some light in penumbra.
    penumbra_any: Vec<bool>,
}

impl ReferenceImages {
    fn new(cached: &CachedReference) -> Self {
        let [a, b] = &cached.halves;
        let surface: Vec<bool> = cached.mask.iter().map(|&m| m > 0.5).collect();
        let radiance = a
            .radiance
            .iter()
            .zip(&b.radiance)
            .map(|(x, y)| (*x + *y) * 0.5)
            .collect();
        let vcoef: Vec<Vec<f32>> = a
            .vcoef
            .iter()
            .zip(&b.vcoef)
            .map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p + q) * 0.5).collect())
            .collect();
        let penumbra: Vec<Vec<bool>> = vcoef
            .iter()
            .map(|v| {
                v.iter()
                    .zip(&surface)
                    .map(|(&v, &s)| s && v > 0.0 && v < 1.0)
                    .collect()
            })
            .collect();
        let penumbra_any = (0..surface.len())
            .map(|i| penumbra.iter().any(|p| p[i]))
            .collect();
        ReferenceImages {
            surface,
            radiance,
            vcoef,
            penumbra,
            penumbra_any,
        }
    }

    fn vcoef_metrics(&self, k: usize, test: &[f32]) -> RegionMetrics {
        let (s, p) = (&self.surface, &self.penumbra[k]);
        RegionMetrics {
            all: error_metrics(test, &self.vcoef[k], |i| s[i]),
            penumbra: error_metrics(test, &self.vcoef[k], |i| p[i]),
        }
    }

    /// Vcoef error over every light's values together (`None` if some
    /// light has no Vcoef).
    fn vcoef_all_lights(
        &self,
        tests: &[Option<&[f32]>],
        against: &[Vec<f32>],
    ) -> Option<RegionMetrics> {
        let mut all = ErrorAccumulator::default();
        let mut pen = ErrorAccumulator::default();
        for (k, test) in tests.iter().enumerate() {
            let test = (*test)?;
            for (i, (&t, &r)) in test.iter().zip(&against[k]).enumerate() {
                if self.surface[i] {
                    all.add(t as f64, r as f64);
                }
                if self.penumbra[k][i] {
                    pen.add(t as f64, r as f64);
                }
            }
        }
        Some(RegionMetrics {
            all: all.finish(),
            penumbra: pen.finish(),
        })
    }

    fn radiance_metrics(&self, test: &[Vec3], against: &[Vec3]) -> RegionMetrics {
        let mut all = ErrorAccumulator::default();
        let mut pen = ErrorAccumulator::default();
        for (i, (t, r)) in test.iter().zip(against).enumerate() {
            for c in 0..3 {
                if self.surface[i] {
                    all.add(t[c] as f64, r[c] as f64);
                }
                if self.penumbra_any[i] {
                    pen.add(t[c] as f64, r[c] as f64);
                }
            }
        }
        RegionMetrics {
            all: all.finish(),
            penumbra: pen.finish(),
        }
    }
}

/// The Vcoef of light `k` of a render, background pixels 0 (as in the
/// `vcoef` AOV the cached references store).
fn vcoef_of(out: &RenderOutput, k: usize, surface: &[bool]) -> Option<Vec<f32>> {
    let term = out.lights.get(k)?;
    Some(
        term.vcoef()
            .iter()
            .zip(surface)
            .map(|(&v, &s)| if s { v } else { 0.0 })
            .collect(),
    )
}

/// A file-name-safe form of `s`.
fn slug(s: &str) -> String {
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

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Computes (or reads from the cache) the reference for `scene`.
fn reference(
    scene: &Scene,
    options: &CompareOptions,
    progress: &Progress,
) -> Result<(CachedReference, ReferenceKey, bool)> {
    let view_options = RenderOptions {
        width: options.width,
        height: options.height,
        ..RenderOptions::default()
    };
    let view = crate::render::view_for(scene, &view_options)?;
    let mut h = StableHasher::default();
    cache::hash_scene(&mut h, scene);
    let key = ReferenceKey {
        scene_hash: h.finish(),
        width: view.width,
        height: view.height,
        samples: options.reference_samples,
        seeds: options.reference_seeds(),
        version: REFERENCE_VERSION,
    };
    if let Some(hit) = cache::load(&options.cache_dir, &key, scene.lights.len()) {
        progress.step();
        progress.step();
        return Ok((hit, key, true));
    }
    let start = Instant::now();
    let mut halves = Vec::new();
    let mut mask = Vec::new();
    for (i, &seed) in key.seeds.iter().enumerate() {
        progress.stage(&format!("reference half {}/2", i + 1));
        let out = render(
            scene,
            &RenderOptions {
                aovs: vec![Aov::Mask],
                technique: Technique::named("reference")?,
                samples: options.reference_samples / 2,
                seed,
                ..view_options.clone()
            },
            &Progress::hidden(),
        )?;
        mask = out
            .layers
            .iter()
            .find(|l| l.name == "mask")
            .map(|l| l.channels[0].1.clone())
            .unwrap_or_default();
        let surface: Vec<bool> = mask.iter().map(|&m| m > 0.5).collect();
        let vcoef = (0..scene.lights.len())
            .map(|k| vcoef_of(&out, k, &surface).unwrap_or_default())
            .collect();
        halves.push(ReferenceHalf {
            radiance: out.radiance,
            vcoef,
        });
        progress.step();
    }
    let [a, b]: [ReferenceHalf; 2] = halves
        .try_into()
        .map_err(|_| Error::param("--reference-samples", "reference halves missing"))?;
    let cached = CachedReference {
        mask,
        halves: [a, b],
        seconds: start.elapsed().as_secs_f64(),
    };
    if let Err(e) = cache::store(&options.cache_dir, &key, &cached) {
        // A read-only cache costs time, not correctness.
        eprintln!("penumbra: warning: reference not cached: {e}");
    }
    Ok((cached, key, false))
}

/// Progress steps `compare_scene` takes with `options`.
pub fn progress_steps(options: &CompareOptions) -> u64 {
    let settings: usize = options
        .techniques
        .iter()
        .map(|&t| {
            quality_settings(
                t,
                &options.samples,
                &options.patterns,
                true,
                &RenderOptions {
                    options: options.technique_options.clone(),
                    ..RenderOptions::default()
                },
            )
            .len()
        })
        .sum();
    2 + settings as u64 * options.repeat as u64
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
    let lights = scene.lights.len();
    let (width, height) = (key.width, key.height);

    let halves = &cached.halves;
    let floor_vcoef: Vec<NoiseFloor> = (0..lights)
        .map(|k| {
            let m = RegionMetrics {
                all: error_metrics(&halves[0].vcoef[k], &halves[1].vcoef[k], |i| {
                    reference.surface[i]
                }),
                penumbra: error_metrics(&halves[0].vcoef[k], &halves[1].vcoef[k], |i| {
                    reference.penumbra[k][i]
                }),
            };
            NoiseFloor::from_halves(m)
        })
        .collect();
    let half_a: Vec<Option<&[f32]>> = halves[0].vcoef.iter().map(|v| Some(v.as_slice())).collect();
    let floor_vcoef_all_lights = reference
        .vcoef_all_lights(&half_a, &halves[1].vcoef)
        .map(NoiseFloor::from_halves)
        .unwrap_or_default();
    let floor_radiance = NoiseFloor::from_halves(
        reference.radiance_metrics(&halves[0].radiance, &halves[1].radiance),
    );

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
    let mut runs = Vec::new();
    for &technique in &options.techniques {
        let semi_opaque = has_semi_opaque_casters(scene);
        for (setting, setting_options) in quality_settings(
            technique,
            &options.samples,
            &options.patterns,
            semi_opaque,
            &base,
        ) {
            let name = setting.curve.as_str();
            let mut totals = Vec::new();
            let mut pass_times: Vec<Vec<f64>> = Vec::new();
            let mut pass_names: Vec<String> = Vec::new();
            let mut first: Option<RenderOutput> = None;
            for r in 0..options.repeat {
                progress.stage(&format!(
                    "{name} {} (run {}/{})",
                    setting.label,
                    r + 1,
                    options.repeat
                ));
                let start = Instant::now();
                let rendered = render(scene, &setting_options, &Progress::hidden())?;
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
                                format!("{name} ({}) gave different images in two runs of the same render", setting.label),
                            ));
                        }
                    }
                }
                progress.step();
            }
            let Some(rendered) = first else { continue };
            let owned: Vec<Option<Vec<f32>>> = (0..lights)
                .map(|k| vcoef_of(&rendered, k, &reference.surface))
                .collect();
            let tests: Vec<Option<&[f32]>> = owned.iter().map(|v| v.as_deref()).collect();
            let vcoef: Vec<Option<RegionMetrics>> = tests
                .iter()
                .enumerate()
                .map(|(k, t)| t.map(|t| reference.vcoef_metrics(k, t)))
                .collect();
            let stem = slug(&format!("{name}-{}", setting.label));
            let mut image = None;
            let mut heatmaps = Vec::new();
            if options.images {
                let rel = format!("images/{stem}.png");
                write_png(&out.join(&rel), width, height, &rendered.radiance)?;
                image = Some(rel);
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
                    write_error_heatmap(
                        &out.join(&rel),
                        width,
                        height,
                        &err,
                        &reference.surface,
                        HEATMAP_SCALE,
                    )?;
                    heatmaps.push(rel);
                }
            }
            runs.push(RunResult {
                technique: name.to_string(),
                setting: setting.label.clone(),
                samples: setting.samples,
                median_ms: median(totals.clone()),
                min_ms: totals.iter().copied().fold(f64::INFINITY, f64::min),
                max_ms: totals.iter().copied().fold(0.0, f64::max),
                runs: options.repeat,
                passes: pass_names
                    .into_iter()
                    .zip(pass_times)
                    .map(|(name, t)| PassMedian {
                        name,
                        median_ms: median(t),
                    })
                    .collect(),
                vcoef_all_lights: reference.vcoef_all_lights(&tests, &reference.vcoef),
                vcoef,
                radiance: reference.radiance_metrics(&rendered.radiance, &reference.radiance),
                pareto: false,
                image,
                heatmaps,
            });
        }
    }

    let chart_points = |runs: &[RunResult], all: bool| -> Vec<(usize, ChartPoint)> {
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
    };
    let penumbra_points = chart_points(&runs, false);
    let only: Vec<ChartPoint> = penumbra_points.iter().map(|(_, p)| p.clone()).collect();
    for ((i, _), front) in penumbra_points.iter().zip(pareto_front(&only)) {
        runs[*i].pareto = front;
    }
    let mut chart = None;
    let mut chart_all = None;
    if !only.is_empty() {
        write_error_vs_time(
            &out.join("error_vs_time.png"),
            &format!("{}: Vcoef error in the penumbra vs time", scene.name),
            "Vcoef RMSE (penumbra)",
            &only,
            Some(floor_vcoef_all_lights.rmse_penumbra),
        )?;
        chart = Some("error_vs_time.png".to_string());
        let all: Vec<ChartPoint> = chart_points(&runs, true)
            .into_iter()
            .map(|(_, p)| p)
            .collect();
        write_error_vs_time(
            &out.join("error_vs_time_all.png"),
            &format!(
                "{}: Vcoef error over all shading points vs time",
                scene.name
            ),
            "Vcoef RMSE (all shading points)",
            &all,
            Some(floor_vcoef_all_lights.rmse_all),
        )?;
        chart_all = Some("error_vs_time_all.png".to_string());
    }

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
            floor_vcoef,
            floor_vcoef_all_lights,
            floor_radiance,
        },
        runs,
        chart,
        chart_all,
    })
}
