//! Where counting edges would cost more than tracing the samples' shadow
//! rays, DCS traces them: the cost choice (`--dcs-rays auto`, the
//! default).
//!
//! Both answers are exact: a sample's visibility is the same whether its
//! occluders are counted (`D = 0`) or its shadow ray finds none, up to
//! ties, and both weigh each sample's light by it (the direct mode), so
//! the image stays the exact one either way. The choice is made per light
//! from counts alone (casting triangles, receivers, samples), never from
//! clocks or scheduling, so it is the same for any thread count and SIMD
//! level.
//!
//! Why per light and not per block of receivers: the counting path's
//! setup (stencil, start-count ties, candidate edges, wedge regions) and
//! its per-tile culling of the candidate edges grow with the triangles,
//! while inside a block whose edges are already culled counting is 3 to
//! 10 times cheaper than the same receivers' rays (measured per 4² block
//! on the tessellation series, 512², 64 samples: 130–700 ns per ray in a
//! penumbra against 150–500 ns per (receiver, edge) pair). So the choice
//! that pays is whether to build the counting path at all
//! (`docs/algorithms/dcs.md`, "Cost choice").
use super::receiver::PixelResult;
use crate::gbuffer::GSample;
use crate::sampling::{LightSampler, PatternSampler};
use crate::scene::LightShape;
use crate::shade::{surface_point, LightSample, PreparedLight};
use crate::shadow::kit::rays::{Scratch as TracerScratch, ShadowTracer};
use crate::shadow::ShadowContext;
use glam::Vec3;

/// The cost model's calibration: 512² receivers at 64 samples.
const CALIBRATION_RECEIVERS: f64 = 512.0 * 512.0;
/// Samples per receiver of the calibration.
const CALIBRATION_SAMPLES: f64 = 64.0;
/// The counting path's setup per casting triangle, ns (stencil, ties,
/// candidate edges, wedge regions: 0.9–2.2 µs on the tessellation series
/// at 512², 2 threads; the lowest is taken, so that counting is kept
/// unless rays are surely cheaper).
const SETUP_NS: f64 = 900.0;
/// The counter pass per casting triangle at the calibration, ns (1.2–5.5
/// µs on the series; the lowest is taken); it grows with the receivers
/// and, for its per-sample half, with the samples.
const COUNT_NS: f64 = 1200.0;
/// BVH build per casting triangle, ns.
const BVH_NS: f64 = 300.0;
/// One shadow ray on average over a frame's receivers, ns (0.09–0.11 µs
/// on the series at 512², 64 samples, 2 threads).
const RAY_NS: f64 = 100.0;

/// Per light: count edges, or trace every receiver's rays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightPlan {
    /// The counting path.
    Count {
        /// Its estimated time, ms (0 when rays were not an option).
        count_ms: f64,
        /// The rays' estimated time, ms (0 when they were not an option).
        rays_ms: f64,
    },
    /// Every receiver by rays: no stencil, wedge or counter is built.
    AllRays {
        /// The counting path's estimated time, ms.
        count_ms: f64,
        /// The BVH build and rays' estimated time, ms.
        rays_ms: f64,
    },
}

impl LightPlan {
    /// What `--explain` says of it.
    pub fn describe(&self) -> String {
        match *self {
            LightPlan::Count { rays_ms: 0.0, .. } => {
                "counted (rays not an option here: --dcs-rays never, or a light, caster or setting \
                 the ray path does not serve)"
                    .into()
            }
            LightPlan::Count { count_ms, rays_ms } => format!(
                "counted: estimated {count_ms:.0} ms against {rays_ms:.0} ms for every receiver's \
                 shadow rays"
            ),
            LightPlan::AllRays { count_ms, rays_ms } => format!(
                "every receiver traced by shadow rays: estimated {rays_ms:.0} ms against \
                 {count_ms:.0} ms for counting; no stencil, wedge or counter built"
            ),
        }
    }
}

/// The per-light choice from the casting triangles, the receivers and
/// the samples per receiver; `eligible` says whether rays may be used at
/// all.
pub fn plan_light(eligible: bool, casters: usize, receivers: usize, samples: u32) -> LightPlan {
    if !eligible {
        return LightPlan::Count {
            count_ms: 0.0,
            rays_ms: 0.0,
        };
    }
    let (t, r, n) = (casters as f64, receivers as f64, f64::from(samples));
    let per_sample = 0.5 + 0.5 * n / CALIBRATION_SAMPLES;
    let count_ms = t * (SETUP_NS + COUNT_NS * r / CALIBRATION_RECEIVERS * per_sample) * 1e-6;
    let rays_ms = (t * BVH_NS + r * n * RAY_NS) * 1e-6;
    if count_ms > rays_ms {
        LightPlan::AllRays { count_ms, rays_ms }
    } else {
        LightPlan::Count { count_ms, rays_ms }
    }
}

/// One light's receivers by shadow rays: the tracer and what the shading
/// reads, shared by the workers.
pub(super) struct RayPixels<'a, 'c> {
    ctx: &'a ShadowContext<'c>,
    tracer: &'a ShadowTracer<'c>,
    sampler: LightSampler,
    pattern: PatternSampler,
    prepared: &'a PreparedLight<'a>,
    rect: Option<(Vec3, Vec3, Vec3)>,
}

/// One worker's buffers for [`RayPixels::pixel`].
#[derive(Debug, Default)]
pub(super) struct RayScratch {
    samples: Vec<LightSample>,
    vt: Vec<f64>,
    visibility: Vec<f32>,
    tracer: TracerScratch,
}

impl<'a, 'c> RayPixels<'a, 'c> {
    /// Light `light`'s receivers under `pattern`, shaded by `prepared`.
    pub(super) fn new(
        ctx: &'a ShadowContext<'c>,
        tracer: &'a ShadowTracer<'c>,
        light: usize,
        pattern: PatternSampler,
        prepared: &'a PreparedLight<'a>,
    ) -> Self {
        let l = &ctx.scene.lights[light];
        let rect = match l.shape {
            LightShape::Rect { center, u, v, .. } => Some((center, u, v)),
            LightShape::Sphere { .. } => None,
        };
        RayPixels {
            ctx,
            tracer,
            sampler: LightSampler::new(l),
            pattern,
            prepared,
            rect,
        }
    }

    /// Pixel `i`'s result from its samples' shadow rays (the reference's
    /// origin and test), resolved as the counting path resolves opaque
    /// counts in the direct mode: Vcoef = visible / N; the direct light 0
    /// when no sample is seen, the exact unshadowed integral when all are,
    /// else the samples' estimate with their visibilities. The depth
    /// complexity AOVs get what rays know: `dc_max` 1 where a sample is
    /// hidden, `dc_mean` the hidden fraction (lower bounds of the counts);
    /// `edges` 0.
    pub(super) fn pixel(&self, i: usize, scratch: &mut RayScratch) -> PixelResult {
        let gbuffer = self.ctx.gbuffer;
        let g: GSample = gbuffer.get(i).unwrap_or(GSample::BACKGROUND);
        if !g.is_surface() {
            return PixelResult::default();
        }
        let width = (gbuffer.width as usize).max(1);
        let pixel = ((i % width) as u32, (i / width) as u32);
        self.sampler
            .samples_with(&self.pattern, g.position, pixel, &mut scratch.samples);
        let n = scratch.samples.len();
        if n == 0 {
            // Inside a sphere light: no defined Vcoef (as the counting
            // path and the reference).
            return PixelResult {
                vcoef: 1.0,
                ..PixelResult::default()
            };
        }
        self.tracer.visibility_with(
            &g,
            &scratch.samples,
            self.rect,
            &mut scratch.vt,
            &mut scratch.tracer,
        );
        scratch.visibility.clear();
        scratch
            .visibility
            .extend(scratch.vt.iter().map(|&v| v as f32));
        // Visibilities of 0 and 1 (opaque casters only) sum exactly in
        // f32 in any order, as the counting path's count.
        let visible = scratch.visibility.iter().filter(|&&v| v > 0.0).count() as f32;
        let hidden = n as f32 - visible;
        let radiance = if visible == 0.0 {
            Vec3::ZERO
        } else {
            let eye = self.ctx.view.eye.as_vec3();
            let point = surface_point(self.ctx.scene, &g, eye);
            if visible == n as f32 {
                self.prepared.unshadowed_direct(&point)
            } else {
                self.prepared
                    .direct_from_samples(&point, &scratch.samples, &scratch.visibility)
            }
        };
        PixelResult {
            vcoef: visible / n as f32,
            radiance,
            max_dc: if hidden > 0.0 { 1.0 } else { 0.0 },
            mean_dc: hidden / n as f32,
            edges: 0.0,
            recounted: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_counts_small_scenes_and_traces_large_ones() {
        let receivers = 512 * 512;
        let counted = |p: LightPlan| matches!(p, LightPlan::Count { .. });
        // 512², 64 samples: the tessellation series' 61k and 253k count,
        // 1.0M and 4.1M trace.
        assert!(counted(plan_light(true, 61_562, receivers, 64)));
        assert!(counted(plan_light(true, 252_722, receivers, 64)));
        assert!(!counted(plan_light(true, 1_023_842, receivers, 64)));
        assert!(!counted(plan_light(true, 4_121_282, receivers, 64)));
        // Not eligible: always counted.
        assert_eq!(
            plan_light(false, 4_121_282, receivers, 64),
            LightPlan::Count {
                count_ms: 0.0,
                rays_ms: 0.0
            }
        );
        // Many samples make every receiver's rays dearer than counting.
        assert!(counted(plan_light(true, 1_023_842, receivers, 4096)));
        // No receiver: nothing to trace, nothing to count per receiver.
        assert!(!counted(plan_light(true, 1_000, 0, 64)));
    }
}
