//! DCS's cost choice (`--dcs-rays auto`, the default): per light, count
//! edges or trace every receiver's shadow rays, whichever is estimated
//! cheaper (a leaf: the settings and the passes read it).
//!
//! Both answers are exact: a sample's visibility is the same whether its
//! occluders are counted (`D = 0`) or its shadow ray finds none, up to
//! ties, and both weigh each sample's light by it (the direct mode), so
//! the image stays the exact one either way. The choice is made from
//! counts alone (casting triangles, receivers, samples), never from
//! clocks or scheduling, so it is the same for any thread count and SIMD
//! level.
//!
//! Why per light and not per block of receivers: the counting path's
//! setup (stencil, start-count ties, candidate edges, wedge regions) and
//! its per-tile culling of the candidate edges grow with the triangles,
//! while inside a block whose edges are already culled counting is 3 to
//! 10 times cheaper than the same receivers' rays (measured per 4² block
//! on the tessellation series, 512², 64 samples: 8–64 µs for a penumbra
//! receiver's 64 rays against 150–500 ns per (receiver, edge) pair). So
//! the choice that pays is whether to build the counting path at all
//! (`docs/algorithms/dcs.md`, "Cost choice").

/// The cost model's calibration: 512² receivers at 64 samples.
const CALIBRATION_RECEIVERS: f64 = 512.0 * 512.0;
/// Samples per receiver of the calibration.
const CALIBRATION_SAMPLES: f64 = 64.0;
/// The counting path's setup per casting triangle, ns (stencil, ties,
/// candidate edges, wedge regions: 0.7–2.2 µs on the tessellation series
/// at 512², 2 threads; fitted with [`COUNT_NS`] and [`RAY_NS`], see
/// there).
const SETUP_NS: f64 = 700.0;
/// The counter pass per casting triangle at the calibration, ns (0.5–2.5
/// µs on the series). It grows with the receivers, and only a little
/// with the samples: the per-tile culling of the candidate edges, which
/// does not depend on them, is much of it (`dcs --dcs-rays never` on the
/// series, 64 → 256 samples: 1.0–1.3×).
const COUNT_NS: f64 = 900.0;
/// The counter pass's growth per calibration's worth of samples.
const COUNT_PER_SAMPLES: f64 = 0.1;
/// BVH build per casting triangle, ns (0.45 µs at 4.1M triangles, 2
/// threads).
const BVH_NS: f64 = 450.0;
/// The least estimated saving for which rays replace the counting the
/// user asked for, ms: smaller differences are within the estimate's
/// error, and below it every scene keeps the algorithm it names.
const MIN_SAVING_MS: f64 = 50.0;
/// One shadow ray on average over a frame's receivers at the
/// calibration's 64 samples, ns: 32–133 ns on the scaling benchmark's
/// three series at 512² and 1024² (AMD EPYC Zen 3, 2 threads: dearer
/// with more triangles, cheaper where more receivers are lit, since a
/// lit receiver's segment hull is empty). With [`SETUP_NS`] and
/// [`COUNT_NS`] it was chosen over a grid on the series' 28 measured
/// (scene, size, samples) points, both paths timed, for the least time
/// lost to a wrong choice, keeping every case of this module's test:
/// 0.94 s in all, against 4.6 s with the constants fitted before the
/// counting path's receivers were bounded by two boxes across depth gaps
/// (900 ns setup, 1.5 µs counter pass), which traced the 1.0M-triangle
/// spheres at 1024², 64 samples, where counting is now 1.5–2× faster.
/// Two misses are left, both on the subdivided bunny, whose counting
/// costs more per triangle than the spheres': 278k triangles at 512², 64
/// samples is counted (0.95 s, rays 0.52 s) and 1.1M at 512², 256
/// samples too (2.75 s, rays 2.24 s). More samples per receiver make
/// each ray cheaper (the receiver's segments share their cull): the
/// reference's trace per ray at 256 samples is about 0.7× its cost at
/// 64, so rays scale as `(64 / N)^¼`.
const RAY_NS: f64 = 60.0;

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
/// all. Rays when they save at least [`MIN_SAVING_MS`] by the estimate.
pub fn plan_light(eligible: bool, casters: usize, receivers: usize, samples: u32) -> LightPlan {
    if !eligible {
        return LightPlan::Count {
            count_ms: 0.0,
            rays_ms: 0.0,
        };
    }
    let (t, r, n) = (casters as f64, receivers as f64, f64::from(samples));
    let per_samples = (1.0 - COUNT_PER_SAMPLES) + COUNT_PER_SAMPLES * n / CALIBRATION_SAMPLES;
    let count_ms = t * (SETUP_NS + COUNT_NS * r / CALIBRATION_RECEIVERS * per_samples) * 1e-6;
    let per_ray = RAY_NS * (CALIBRATION_SAMPLES / n).powf(0.25);
    let rays_ms = (t * BVH_NS + r * n * per_ray) * 1e-6;
    if count_ms - rays_ms > MIN_SAVING_MS {
        LightPlan::AllRays { count_ms, rays_ms }
    } else {
        LightPlan::Count { count_ms, rays_ms }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_counts_small_scenes_and_traces_large_ones() {
        // The spheres scene's receivers at 512².
        let receivers = 188_250;
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
        // 256 samples: 1.0M counts (measured: counting 1.7 s, rays
        // 3.5 s), 4.1M traces.
        assert!(counted(plan_light(true, 1_023_842, receivers, 256)));
        assert!(!counted(plan_light(true, 4_121_282, receivers, 256)));
        // Many samples make every receiver's rays dearer than counting.
        assert!(counted(plan_light(true, 1_023_842, receivers, 4096)));
        // Small savings keep the counting: the 69k-triangle bunny at 40².
        assert!(counted(plan_light(true, 69_451, 40 * 40, 16)));
        // A 320k-triangle sphere at 40² saves far more.
        assert!(!counted(plan_light(true, 320_000, 40 * 40, 16)));
    }
}
