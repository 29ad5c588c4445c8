//! The ray-traced reference: the contract's `V·T` by shadow rays, per light
//! sample, with the oracle's estimator definitions
//! (`docs/algorithms/reference.md`).
//!
//! Per light and surface pixel, `N` samples come from [`crate::sampling`]
//! (keyed by seed, light, pixel and sample index), laid out by the
//! reference's [`SamplePattern`] (default: stratified). Each sample's segment
//! from the offset receiver to the sample point is tested against a BVH of
//! the opaque casters (any hit); if it is clear and the scene has
//! non-opaque casters, a second BVH gives every crossing and the
//! transmittance `T = Π (1 − opacity)`. The outputs are
//! `Vcoef = (1/N) Σ V·T` and the radiance estimate
//! [`PreparedLight::direct_from_samples`](crate::shade::PreparedLight::direct_from_samples)
//! with the same per-sample `V·T`.
//!
//! **Shadow-ray offset** (the oracle's rule): origin
//! `o = p + ε_p n_g` with `n_g` the G-buffer's geometric normal (facing the
//! viewer, also when the sample is behind the surface: `V` is pure
//! visibility), `ε_p = max(1e-6 × D, 1e-5 × max_i |p_i|)`, `D` the diagonal
//! of the bounding box of all triangles and lights. The second term keeps
//! the origin about 80 f32 ulps off the surface far from the world origin.
//! The segment ends at `t_max = |x − o| (1 − 1e-6)`.

use crate::error::{Error, Result};
use crate::gbuffer::GSample;
use crate::sampling::{PatternSampler, SamplePattern};
use crate::shade::LightSample;
use crate::shadow::kit::timing::PassTimer;
use crate::shadow::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use crate::shadow::{ShadowContext, ShadowOutput, ShadowTechnique};
use std::time::Duration;

/// The reference technique: `samples` light samples per pixel and light,
/// keyed by `seed`, laid out by `pattern`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reference {
    /// Light samples per pixel and light (`N ≥ 1`).
    pub samples: u32,
    /// Seed of the light samples.
    pub seed: u64,
    /// Layout and per-pixel decorrelation of the light samples
    /// (default [`SamplePattern::Stratified`]).
    pub pattern: SamplePattern,
}

impl Reference {
    /// `samples` stratified samples per pixel and light under `seed`.
    pub fn new(samples: u32, seed: u64) -> Reference {
        Reference {
            samples,
            seed,
            pattern: SamplePattern::Stratified,
        }
    }
}

impl Default for Reference {
    /// 64 stratified samples, seed 0 (the render options' defaults).
    fn default() -> Reference {
        Reference::new(64, 0)
    }
}

/// Timings and ray counts of one [`Reference`] run.
#[derive(Debug, Clone, Default)]
pub struct ReferenceStats {
    /// Building both BVHs.
    pub bvh_time: Duration,
    /// Per light: wall-clock time of its pass.
    pub light_times: Vec<Duration>,
    /// Per light: BVH traversals (one per opaque any-hit query, one more
    /// per transmittance walk).
    pub light_rays: Vec<u64>,
}

impl ReferenceStats {
    /// Total BVH traversals over all lights.
    pub fn rays(&self) -> u64 {
        self.light_rays.iter().sum()
    }

    /// Traversals per second over all light passes (0 if no time passed).
    pub fn rays_per_second(&self) -> f64 {
        let secs: f64 = self.light_times.iter().map(Duration::as_secs_f64).sum();
        if secs > 0.0 {
            self.rays() as f64 / secs
        } else {
            0.0
        }
    }
}

/// The ray-traced reference in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "reference",
    summary: "the ray-traced reference: shadow rays through a BVH per light sample; Vcoef and direct light",
    module: "shadow/reference.rs",
    page: Some("reference.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Yes,
        textured_lights: Support::Yes,
        enclosed_lights: Support::Yes,
        reached_lights: Support::Yes,
        semi_opaque: Support::Yes,
        s_triangles: Support::Yes,
        output: TermKind::Radiance,
        exact: true,
        exact_image: true,
    },
    quality_settings: |s| s.per_sample_count("reference", "", s.first_pattern(), |_| {}),
    build: |p| {
        Box::new(Reference {
            samples: p.samples,
            seed: p.seed,
            pattern: p.pattern,
        })
    },
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[Samples, Pattern, Seed]
    },
    cost: crate::shadow::technique::CostClass::Rays,
};

impl Reference {
    /// Runs the reference and also returns its timings and ray counts.
    pub fn compute_with_stats(
        &self,
        ctx: &ShadowContext,
    ) -> Result<(ShadowOutput, ReferenceStats)> {
        if self.samples == 0 {
            return Err(Error::param(
                "--samples",
                "the reference needs at least 1 light sample",
            ));
        }
        let mut stats = ReferenceStats::default();
        let mut out = ShadowOutput::default();
        let t = PassTimer::start("reference bvh");
        let tracer = ctx.cache.tracer();
        stats.bvh_time = t.finish(&mut out.passes);
        for k in 0..ctx.scene.lights.len() {
            let t = PassTimer::start(format!("reference light {k}"));
            let pattern = PatternSampler::new(self.pattern, self.samples, self.seed, k);
            let (term, rays) = tracer.trace_light_with(ctx, k, &pattern);
            // The ray count in the name gives rays/s with the time.
            let time = t.finish_with(&mut out.passes, format!("{rays} rays"));
            stats.light_times.push(time);
            stats.light_rays.push(rays);
            out.lights.push(term);
        }
        Ok((out, stats))
    }
}

impl ShadowTechnique for Reference {
    fn name(&self) -> &'static str {
        "reference"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        Ok(self.compute_with_stats(ctx)?.0)
    }
}

/// Hard-shadow visibility from light `light`'s centre per pixel (see
/// [`ShadowTracer::hard_visibility`](crate::shadow::kit::rays::ShadowTracer::hard_visibility));
/// builds the BVHs first.
pub fn hard_visibility(ctx: &ShadowContext, light: usize) -> Vec<f32> {
    ctx.cache.tracer().hard_visibility(ctx.gbuffer, light)
}

/// Per-sample `V·T` of the reference at pixel `pixel` for `samples`,
/// written to `out` (see
/// [`ShadowTracer::sample_visibility`](crate::shadow::kit::rays::ShadowTracer::sample_visibility));
/// builds the BVHs first, so checks of many pixels should build one
/// [`ShadowTracer`](crate::shadow::kit::rays::ShadowTracer) instead. A pixel outside the G-buffer gives 0.
pub fn sample_visibility(
    ctx: &ShadowContext,
    pixel: (u32, u32),
    samples: &[LightSample],
    out: &mut [f32],
) {
    let g = if pixel.0 < ctx.gbuffer.width && pixel.1 < ctx.gbuffer.height {
        ctx.gbuffer
            .get(pixel.1 as usize * ctx.gbuffer.width as usize + pixel.0 as usize)
    } else {
        None
    };
    let g = g.unwrap_or(GSample::BACKGROUND);
    ctx.cache.tracer().sample_visibility(&g, samples, out);
}
