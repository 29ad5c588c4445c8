//! Progressive rendering to a target error: independent sample sets of
//! one technique, their running mean, and an error estimate from their
//! spread (`render --target-error`, `--max-samples`, `--max-time`).
//!
//! **Sets.** Set `k` is the technique's whole render with `--samples N`
//! light samples at seed [`set_seed`]`(seed, k)`; set 0 uses the seed
//! itself, so a one-set render is bit for bit the ordinary render. Each
//! set is an unbiased estimate of the same image for the exact techniques
//! (their per-sample decisions are exact, and the seeds key independent
//! per-pixel sample placements), so the sets are independent and
//! identically distributed per pixel.
//!
//! **Estimator: batch means.** Per pixel and per value (R, G, B of the
//! shaded radiance; the Vcoef of each light), the sets' running mean `m`
//! and sum of squared deviations `M2` (Welford, in f64) give the variance
//! of the mean, `M2 / (n (n − 1))`. With two sets this is `((A − B)/2)²`,
//! the two-half estimate `compare` uses for the reference's noise floor.
//! The image's estimated RMSE is the square root of this variance's mean
//! over every shading point (and over R, G, B together, as `compare`'s
//! radiance RMSE): an unbiased estimate of the mean squared error of the
//! mean image against the exact image, whose square root is within a few
//! per cent once a few hundred pixels see noise. It measures noise only:
//! a technique's bias (a shadow map's resolution, an approximate option)
//! is not in it.
//!
//! **Determinism.** Each set's bits do not depend on the thread count,
//! sets are accumulated in order, and the stop test after each set reads
//! only those bits: `--target-error` and `--max-samples` give the same
//! image for any thread count and SIMD level the build targets.
//! `--max-time` stops by the clock; `--explain` and the EXR metadata say
//! how many sets it rendered, and `--max-samples` with that count
//! reproduces the image exactly.

use super::shade;
use crate::error::{Error, Result};
use crate::gbuffer::GBuffer;
use crate::observe::Observer;
use crate::output::Layer;
use crate::sampling::SplitMix64;
use crate::scene::Scene;
use crate::shadow::kit::PassTimer;
use crate::shadow::technique::BuildParams;
use crate::shadow::{run_technique, LightTerm, PassTiming, ShadowContext, ShadowOutput};
use crate::view::View;

pub use crate::report::convergence::SetPoint;
use glam::Vec3;
use rayon::prelude::*;
use std::time::{Duration, Instant};

use super::{unshadow_non_receivers, MAX_SAMPLES};
use crate::shadow::registry::Technique;

/// When a progressive render stops. At least one of the three is set.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StopRule {
    /// Stop once the image's estimated radiance RMSE is at most this.
    pub target_error: Option<f64>,
    /// Never more light samples per pixel and light than this (whole sets
    /// of `--samples`; rounded down to a multiple of it).
    pub max_samples: Option<u64>,
    /// Start no set that would end after this much time.
    pub max_time: Option<Duration>,
}

/// The techniques whose sets are independent estimates of one image:
/// those whose light samples move with the seed.
const SET_TECHNIQUES: [&str; 4] = ["reference", "dcs", "penumbra-casting", "multi-map"];

impl StopRule {
    /// Checks the rule against the technique and the set size.
    pub fn validate(&self, technique: Technique, samples: u32) -> Result<()> {
        if let Some(e) = self.target_error {
            if !(e.is_finite() && e > 0.0) {
                return Err(Error::param(
                    "--target-error",
                    format!("{e} is not a positive finite RMSE"),
                ));
            }
        }
        if let Some(m) = self.max_samples {
            if m < u64::from(samples) || m > u64::from(MAX_SAMPLES) {
                return Err(Error::param(
                    "--max-samples",
                    format!(
                        "{m} is outside {samples}..={MAX_SAMPLES} (at least one set of \
                         --samples {samples})"
                    ),
                ));
            }
        }
        if let Some(t) = self.max_time {
            if t.is_zero() {
                return Err(Error::param("--max-time", "must be more than 0 seconds"));
            }
        }
        if self.target_error.is_none() && self.max_samples.is_none() && self.max_time.is_none() {
            return Err(Error::param(
                "--target-error",
                "a progressive render needs --target-error, --max-samples or --max-time",
            ));
        }
        if !SET_TECHNIQUES.contains(&technique.name()) {
            return Err(Error::param(
                "--target-error",
                format!(
                    "{} does not sample the light with the seed, so independent sets of it \
                     would be the same image and have no spread to estimate an error from; \
                     progressive rendering takes {}",
                    technique.name(),
                    SET_TECHNIQUES.join(", ")
                ),
            ));
        }
        Ok(())
    }

    /// The sets this rule allows at most, with `samples` per set.
    fn max_sets(&self, samples: u32) -> u64 {
        let cap = self.max_samples.unwrap_or(u64::from(MAX_SAMPLES));
        (cap.min(u64::from(MAX_SAMPLES)) / u64::from(samples)).max(1)
    }
}

/// Why a progressive render stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    /// The estimated RMSE reached `--target-error`.
    TargetError,
    /// The next set would have passed `--max-samples`.
    MaxSamples,
    /// The next set would have ended after `--max-time`.
    MaxTime,
    /// The next set would have passed the renderer's sample limit.
    SampleLimit,
}

impl StopReason {
    /// The reason in the words of the option that caused it.
    pub fn name(self) -> &'static str {
        match self {
            StopReason::TargetError => "target-error",
            StopReason::MaxSamples => "max-samples",
            StopReason::MaxTime => "max-time",
            StopReason::SampleLimit => "sample-limit",
        }
    }
}

/// How a progressive render converged: what `--explain` prints and the
/// EXR metadata records.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Convergence {
    /// Sets rendered.
    pub sets: u32,
    /// Light samples per pixel and light in each set (`--samples`).
    pub samples_per_set: u32,
    /// The final estimated radiance RMSE (none with one set).
    pub error: Option<f64>,
    /// The final estimated Vcoef RMSE, over every light and shading point.
    pub vcoef_error: Option<f64>,
    /// The target, if one was set.
    pub target_error: Option<f64>,
    /// Why it stopped.
    pub stop: StopReason,
    /// One point per set.
    pub curve: Vec<SetPoint>,
}

impl Convergence {
    /// Light samples per pixel and light in all.
    pub fn samples(&self) -> u64 {
        u64::from(self.sets) * u64::from(self.samples_per_set)
    }

    /// `key = value` pairs for the EXR header (`penumbra.*`).
    pub fn metadata(&self) -> Vec<(String, String)> {
        let opt = |v: Option<f64>| v.map_or("none".to_string(), |v| format!("{v:e}"));
        vec![
            ("penumbra.sets".into(), self.sets.to_string()),
            (
                "penumbra.samplesPerSet".into(),
                self.samples_per_set.to_string(),
            ),
            ("penumbra.samples".into(), self.samples().to_string()),
            ("penumbra.estimatedRmse".into(), opt(self.error)),
            ("penumbra.estimatedVcoefRmse".into(), opt(self.vcoef_error)),
            ("penumbra.targetError".into(), opt(self.target_error)),
            ("penumbra.stopReason".into(), self.stop.name().into()),
            (
                "penumbra.errorEstimator".into(),
                "batch means over independent sample sets".into(),
            ),
        ]
    }

    /// One line in words.
    pub fn summary(&self) -> String {
        let err = match self.error {
            Some(e) => format!("estimated radiance RMSE {e:.3e}"),
            None => "no error estimate (one set)".to_string(),
        };
        let target = self
            .target_error
            .map_or(String::new(), |t| format!(" (target {t:.3e})"));
        let seconds = self.curve.last().map_or(0.0, |p| p.seconds);
        format!(
            "{} sets × {} = {} samples, {err}{target}, stopped by {} after {seconds:.2} s",
            self.sets,
            self.samples_per_set,
            self.samples(),
            self.stop.name()
        )
    }
}

/// The seed of set `k` of a render seeded `seed`: the seed itself for set
/// 0, then a SplitMix64 stream of its own (distinct from `compare`'s
/// reference-half seeds, which fold in other constants).
pub fn set_seed(seed: u64, k: u32) -> u64 {
    if k == 0 {
        return seed;
    }
    let mut g = SplitMix64::new(seed ^ 0x5345_5453_0000_0000);
    let mut s = 0;
    for _ in 0..k {
        s = g.next_u64();
    }
    s
}

/// Running per-pixel statistics of the sets (Welford, f64): the mean is
/// what the image shows, `M2` what the error estimate reads. 48 bytes per
/// pixel plus 16 per pixel and light: proportional to the pixels, never
/// to the samples.
pub(crate) struct Accumulator {
    sets: u32,
    /// Mean and M2 of R, G, B per pixel.
    radiance: Vec<[f64; 6]>,
    /// Mean and M2 of the Vcoef per light and pixel.
    vcoef: Vec<Vec<[f64; 2]>>,
    /// Whether each pixel is a shading point.
    surface: Vec<bool>,
    shading_points: usize,
}

/// Bytes per pixel the accumulator holds for `lights` lights.
pub(crate) fn accumulator_bytes_per_pixel(lights: usize) -> u64 {
    48 + 16 * lights as u64 + 1
}

impl Accumulator {
    fn new(gbuffer: &GBuffer, lights: usize) -> Self {
        let surface: Vec<bool> = (0..gbuffer.len()).map(|i| gbuffer.is_surface(i)).collect();
        Accumulator {
            sets: 0,
            radiance: vec![[0.0; 6]; surface.len()],
            vcoef: vec![vec![[0.0; 2]; surface.len()]; lights],
            shading_points: surface.iter().filter(|s| **s).count(),
            surface,
        }
    }

    fn add(&mut self, radiance: &[Vec3], terms: &[LightTerm]) {
        self.sets += 1;
        let n = f64::from(self.sets);
        let welford = |mean: &mut f64, m2: &mut f64, x: f64| {
            let d = x - *mean;
            *mean += d / n;
            *m2 += d * (x - *mean);
        };
        self.radiance
            .par_iter_mut()
            .zip(radiance.par_iter())
            .for_each(|(s, r)| {
                let [m0, m1, m2, q0, q1, q2] = s;
                welford(m0, q0, f64::from(r.x));
                welford(m1, q1, f64::from(r.y));
                welford(m2, q2, f64::from(r.z));
            });
        for (acc, term) in self.vcoef.iter_mut().zip(terms) {
            acc.par_iter_mut()
                .zip(term.vcoef().par_iter())
                .for_each(|([m, q], &v)| welford(m, q, f64::from(v)));
        }
    }

    /// Variance of the mean from `M2` after `n ≥ 2` sets.
    fn variance_of_mean(&self, m2: f64) -> f64 {
        let n = f64::from(self.sets);
        (m2 / (n * (n - 1.0))).max(0.0)
    }

    /// The estimated radiance RMSE of the mean image (R, G, B together,
    /// over the shading points), or none before two sets.
    fn radiance_rmse(&self) -> Option<f64> {
        if self.sets < 2 || self.shading_points == 0 {
            return None;
        }
        let sum: f64 = (self.radiance.iter().zip(&self.surface))
            .filter(|(_, s)| **s)
            .map(|(a, _)| {
                a[3..]
                    .iter()
                    .map(|&q| self.variance_of_mean(q))
                    .sum::<f64>()
            })
            .sum();
        Some((sum / (3 * self.shading_points) as f64).sqrt())
    }

    /// The estimated Vcoef RMSE over every light and shading point.
    fn vcoef_rmse(&self) -> Option<f64> {
        if self.sets < 2 || self.shading_points == 0 || self.vcoef.is_empty() {
            return None;
        }
        let sum: f64 = (self.vcoef.iter())
            .flat_map(|l| l.iter().zip(&self.surface))
            .filter(|(_, s)| **s)
            .map(|([_, q], _)| self.variance_of_mean(*q))
            .sum();
        Some((sum / (self.shading_points * self.vcoef.len()) as f64).sqrt())
    }

    /// The mean image so far.
    pub(crate) fn mean_radiance(&self) -> Vec<Vec3> {
        (self.radiance.iter())
            .map(|a| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32))
            .collect()
    }

    /// The mean Vcoef of each light so far.
    fn mean_vcoef(&self) -> Vec<Vec<f32>> {
        (self.vcoef.iter())
            .map(|l| l.iter().map(|[m, _]| *m as f32).collect())
            .collect()
    }

    /// Per pixel, the estimated standard error of the mean radiance (RMS
    /// over R, G, B); 0 off the shading points and before two sets.
    pub(crate) fn radiance_error_map(&self) -> Vec<f32> {
        (self.radiance.iter().zip(&self.surface))
            .map(|(a, &s)| {
                if !s || self.sets < 2 {
                    return 0.0;
                }
                let v: f64 = a[3..].iter().map(|&q| self.variance_of_mean(q)).sum();
                (v / 3.0).sqrt() as f32
            })
            .collect()
    }

    /// Per pixel, the estimated standard error of the mean Vcoef (RMS over
    /// the lights).
    fn vcoef_error_map(&self) -> Vec<f32> {
        let lights = self.vcoef.len().max(1) as f64;
        (0..self.surface.len())
            .map(|i| {
                if !self.surface[i] || self.sets < 2 {
                    return 0.0;
                }
                let v: f64 = (self.vcoef.iter())
                    .map(|l| self.variance_of_mean(l[i][1]))
                    .sum();
                (v / lights).sqrt() as f32
            })
            .collect()
    }

    /// Whether each pixel is a shading point.
    pub(crate) fn surface(&self) -> &[bool] {
        &self.surface
    }
}

/// What an [`Observer`] sees after each set of a progressive render.
pub struct SetStatus<'a> {
    /// Sets done.
    pub sets: u32,
    /// Light samples per pixel and light so far.
    pub samples: u64,
    /// Time since the first set started.
    pub elapsed: Duration,
    /// The estimated radiance RMSE so far (none after one set).
    pub error: Option<f64>,
    /// The target, if any.
    pub target_error: Option<f64>,
    /// Estimated time left, from the measured convergence rate and set
    /// cost, capped by `--max-samples` and `--max-time`.
    pub time_left: Option<Duration>,
    /// Whether this was the last set.
    pub last: bool,
    /// Image width and height.
    pub size: (u32, u32),
    acc: &'a Accumulator,
}

impl SetStatus<'_> {
    /// The mean image so far (linear radiance, row-major).
    pub fn mean_radiance(&self) -> Vec<Vec3> {
        self.acc.mean_radiance()
    }

    /// The per-pixel estimated standard error of the mean radiance.
    pub fn error_map(&self) -> Vec<f32> {
        self.acc.radiance_error_map()
    }

    /// Whether each pixel is a shading point.
    pub fn surface(&self) -> &[bool] {
        self.acc.surface()
    }
}

/// The result of the sets: mean light terms, the mean image, the error
/// layer, and the first set's buffers and notes.
pub(super) struct Converged {
    pub output: ShadowOutput,
    pub radiance: Vec<Vec3>,
    pub error_layer: Layer,
    pub convergence: Convergence,
}

/// The slope of log error against log samples from the curve's second
/// half (−0.5 for Monte Carlo noise), clamped to [−1, −0.25] so that one
/// noisy estimate cannot promise convergence much faster or slower than
/// sampling gives.
fn convergence_slope(curve: &[SetPoint]) -> f64 {
    let pts: Vec<(f64, f64)> = (curve.iter())
        .filter_map(|p| p.error.filter(|e| *e > 0.0).map(|e| (p.samples, e)))
        .map(|(s, e)| ((s as f64).ln(), e.ln()))
        .collect();
    let half = &pts[pts.len() / 2..];
    if half.len() < 2 {
        return -0.5;
    }
    let n = half.len() as f64;
    let (mx, my) = half
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = half.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    if sxx <= 0.0 {
        return -0.5;
    }
    (sxy / sxx).clamp(-1.0, -0.25)
}

/// Time left: sets still needed by the measured convergence rate (or by
/// the caps) times the mean set time.
fn time_left(rule: &StopRule, curve: &[SetPoint], samples_per_set: u32) -> Option<Duration> {
    let last = curve.last()?;
    let sets = curve.len() as f64;
    let per_set = last.seconds / sets;
    let mut need = rule.max_sets(samples_per_set) as f64;
    if let (Some(target), Some(err)) = (rule.target_error, last.error) {
        let slope = convergence_slope(curve);
        // error(s) = err · (s / s_now)^slope  ⇒  s = s_now · (target/err)^(1/slope)
        let samples = last.samples as f64 * (target / err).powf(1.0 / slope);
        // Less a hair, so an exact whole number of sets is not rounded up.
        need = need.min(
            (samples / f64::from(samples_per_set) - 1e-9)
                .ceil()
                .max(sets),
        );
    } else if rule.target_error.is_some() {
        return None;
    }
    let mut left = (need - sets).max(0.0) * per_set;
    if let Some(t) = rule.max_time {
        left = left.min((t.as_secs_f64() - last.seconds).max(0.0));
    }
    Some(Duration::from_secs_f64(left.clamp(0.0, 1e9)))
}

/// Renders sets of `technique` until `rule` stops it (see the module
/// docs), shading each set and accumulating its image and Vcoefs.
pub(super) fn converge(
    technique: Technique,
    params: &BuildParams,
    rule: &StopRule,
    ctx: &ShadowContext,
    observer: &dyn Observer,
) -> Result<Converged> {
    rule.validate(technique, params.samples)?;
    let (scene, view, gbuffer): (&Scene, &View, &GBuffer) = (ctx.scene, ctx.view, ctx.gbuffer);
    let mut acc = Accumulator::new(gbuffer, scene.lights.len());
    let mut first: Option<ShadowOutput> = None;
    let mut passes: Vec<PassTiming> = Vec::new();
    let mut curve = Vec::new();
    let start = Instant::now();
    let max_sets = rule.max_sets(params.samples);
    let stop = loop {
        let k = acc.sets;
        let set_params = BuildParams {
            seed: set_seed(params.seed, k),
            ..*params
        };
        let mut out = run_technique(technique, &set_params, ctx)?;
        if observer.cancelled() {
            return Err(Error::Cancelled);
        }
        unshadow_non_receivers(scene, gbuffer, &mut out.lights);
        let t = PassTimer::start("shading");
        let radiance = shade(scene, view, gbuffer, &out.lights);
        let mut set_passes = out.passes.clone();
        t.finish(&mut set_passes);
        let t = PassTimer::start("accumulate");
        acc.add(&radiance, &out.lights);
        t.finish(&mut set_passes);
        add_passes(&mut passes, &set_passes);
        if first.is_none() {
            first = Some(out);
        }
        let error = acc.radiance_rmse();
        let elapsed = start.elapsed();
        curve.push(SetPoint {
            samples: u64::from(acc.sets) * u64::from(params.samples),
            seconds: elapsed.as_secs_f64(),
            error,
        });
        let stop = stop_reason(rule, error, acc.sets, max_sets, elapsed);
        observer.set_done(&SetStatus {
            sets: acc.sets,
            samples: u64::from(acc.sets) * u64::from(params.samples),
            elapsed,
            error,
            target_error: rule.target_error,
            time_left: match stop {
                Some(_) => Some(Duration::ZERO),
                None => time_left(rule, &curve, params.samples),
            },
            last: stop.is_some(),
            size: (view.width, view.height),
            acc: &acc,
        });
        if observer.cancelled() {
            return Err(Error::Cancelled);
        }
        if let Some(stop) = stop {
            break stop;
        }
    };
    let Some(mut output) = first else {
        return Err(Error::Cancelled);
    };
    for (term, mean) in output.lights.iter_mut().zip(acc.mean_vcoef()) {
        match term {
            LightTerm::Vcoef(v) => *v = mean,
            LightTerm::Radiance { vcoef, .. } => *vcoef = mean,
        }
    }
    // The image is the sets' mean radiance, shaded per set; a technique's
    // own per-light radiance term (tinted casters) stays the first set's
    // and is not shaded again.
    output.passes = passes;
    let radiance = acc.mean_radiance();
    let error_layer = Layer {
        name: "error".into(),
        channels: vec![
            ("Y".into(), acc.radiance_error_map()),
            ("V".into(), acc.vcoef_error_map()),
        ],
    };
    let convergence = Convergence {
        sets: acc.sets,
        samples_per_set: params.samples,
        error: acc.radiance_rmse(),
        vcoef_error: acc.vcoef_rmse(),
        target_error: rule.target_error,
        stop,
        curve,
    };
    Ok(Converged {
        output,
        radiance,
        error_layer,
        convergence,
    })
}

/// Why to stop after `sets` sets, if it is time to: the target first,
/// then the sample caps, then the clock (the next set, at the mean set
/// time so far, would end after `--max-time`).
fn stop_reason(
    rule: &StopRule,
    error: Option<f64>,
    sets: u32,
    max_sets: u64,
    elapsed: Duration,
) -> Option<StopReason> {
    if let (Some(target), Some(e)) = (rule.target_error, error) {
        if e <= target {
            return Some(StopReason::TargetError);
        }
    }
    if u64::from(sets) >= max_sets {
        return Some(match rule.max_samples {
            Some(_) => StopReason::MaxSamples,
            None => StopReason::SampleLimit,
        });
    }
    let max = rule.max_time?;
    let per_set = elapsed.as_secs_f64() / f64::from(sets.max(1));
    (elapsed.as_secs_f64() + per_set > max.as_secs_f64()).then_some(StopReason::MaxTime)
}

/// Adds a set's pass times to the totals by name, keeping first-seen order.
fn add_passes(total: &mut Vec<PassTiming>, set: &[PassTiming]) {
    for p in set {
        match total.iter_mut().find(|t| t.name == p.name) {
            Some(t) => t.time += p.time,
            None => total.push(p.clone()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_seeds_are_distinct_and_set_zero_is_the_seed() {
        let seeds: Vec<u64> = (0..64).map(|k| set_seed(7, k)).collect();
        assert_eq!(seeds[0], 7);
        let mut sorted = seeds.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), seeds.len());
    }

    #[test]
    fn slope_of_exact_monte_carlo_curve_is_minus_half() {
        let curve: Vec<SetPoint> = (1..=16)
            .map(|k| SetPoint {
                samples: 16 * k,
                seconds: k as f64,
                error: (k > 1).then(|| 0.1 / ((16 * k) as f64).sqrt()),
            })
            .collect();
        assert!((convergence_slope(&curve) + 0.5).abs() < 1e-9);
        // From error e at s samples to e/2 takes 4 s samples: 3× the time
        // so far (16 s) at 1 s per set.
        let rule = StopRule {
            target_error: Some(curve[15].error.unwrap() / 2.0),
            ..StopRule::default()
        };
        let left = time_left(&rule, &curve, 16).unwrap().as_secs_f64();
        assert!((left - 48.0).abs() < 1e-6, "{left}");
    }

    #[test]
    fn two_set_estimate_is_the_two_half_estimate() {
        // Two sets A, B: the variance of the mean is ((A − B) / 2)².
        let mut acc = Accumulator {
            sets: 0,
            radiance: vec![[0.0; 6]; 1],
            vcoef: vec![vec![[0.0; 2]; 1]],
            surface: vec![true],
            shading_points: 1,
        };
        acc.add(&[Vec3::splat(0.25)], &[LightTerm::Vcoef(vec![0.25])]);
        acc.add(&[Vec3::splat(0.75)], &[LightTerm::Vcoef(vec![0.75])]);
        assert!((acc.radiance_rmse().unwrap() - 0.25).abs() < 1e-12);
        assert!((acc.vcoef_rmse().unwrap() - 0.25).abs() < 1e-12);
        assert_eq!(acc.mean_radiance(), vec![Vec3::splat(0.5)]);
    }

    #[test]
    fn rule_refuses_bad_values_by_name() {
        let t = Technique::default();
        let bad = [
            (
                StopRule {
                    target_error: Some(0.0),
                    ..StopRule::default()
                },
                "--target-error",
            ),
            (
                StopRule {
                    target_error: Some(f64::NAN),
                    ..StopRule::default()
                },
                "--target-error",
            ),
            (
                StopRule {
                    max_samples: Some(8),
                    ..StopRule::default()
                },
                "--max-samples",
            ),
            (
                StopRule {
                    max_time: Some(Duration::ZERO),
                    ..StopRule::default()
                },
                "--max-time",
            ),
            (StopRule::default(), "--target-error"),
        ];
        for (rule, name) in bad {
            let e = rule.validate(t, 16).unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
    }
}
