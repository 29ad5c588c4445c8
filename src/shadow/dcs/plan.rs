//! DCS's cost choice (`--dcs-rays auto`, the default): per light, count
//! edges or trace every receiver's shadow rays, whichever is estimated
//! cheaper (a leaf: the settings and the passes read it).
//!
//! Both answers are exact: a sample's visibility is the same whether its
//! occluders are counted (`D = 0`) or its shadow ray finds none, up to
//! ties, and both weigh each sample's light by it (the direct mode), so
//! the image stays the exact one either way. The choice is made from
//! counts alone (casting triangles, receivers, samples, and where they
//! leave it open the [probe](super::probe)'s integer counts on a fixed
//! sample of receivers and edges), never from clocks or scheduling, so it
//! is the same for any thread count and SIMD level.
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

use super::options::RayChoice;

/// The counting path's cost per casting triangle, ns: its setup (stencil,
/// start-count ties, candidate edges, wedge regions) and the per-tile
/// culling of the candidate edges, which do not depend on the samples.
///
/// This and the other constants below were fitted together on the
/// scaling benchmark's 31 (scene, size, samples) points, both paths
/// timed (`--dcs-rays never` and `always`, 2 threads, AMD EPYC Zen 3)
/// and the probe's figures read at each: with them the choice is right at
/// every point, against 13.0 s lost to wrong choices by the estimate
/// before the probe, which saw only triangles, receivers and samples
/// (`docs/algorithms/dcs.md`, "Cost choice").
const COUNT_TRIANGLE_NS: f64 = 1200.0;
/// The counter pass per (receiver, edge) pair at 64 samples, ns; it grows
/// as the fourth root of the samples (the pair's setup is shared by them).
const COUNT_PAIR_NS: f64 = 56.0;
/// BVH build per casting triangle, ns.
const BVH_NS: f64 = 310.0;
/// One shadow ray of a penumbra receiver at 64 samples and 1M triangles,
/// ns. Rays grow dearer as the fourth root of the triangles (deeper
/// walks, more cache misses) and cheaper as the fourth root of the
/// samples (a receiver's packets share their culls).
const RAY_PENUMBRA_NS: f64 = 138.0;
/// The same for the other receivers: lit ones are answered by one walk of
/// the light's hull, umbra ones stop at their first hit.
const RAY_OTHER_NS: f64 = 23.0;
/// The probe's bounds when it is not run: penumbra receivers between
/// these fractions of the receivers (0.19–0.6 on the scaling series)...
const PENUMBRA_FRACTION: [f64; 2] = [0.15, 0.65];
/// ... and (receiver, edge) pairs between these multiples of the
/// receivers (7–200 on the series).
const PAIRS_PER_RECEIVER: [f64; 2] = [5.0, 250.0];
/// The least estimated saving for which rays replace the counting the
/// user asked for, ms: smaller differences are within the estimate's
/// error, and below it every scene keeps the algorithm it names.
const MIN_SAVING_MS: f64 = 50.0;

/// The counting path's estimated time, ms.
fn count_ms(casters: f64, samples: f64, pairs: f64) -> f64 {
    (casters * COUNT_TRIANGLE_NS + pairs * COUNT_PAIR_NS * (samples / 64.0).powf(0.25)) * 1e-6
}

/// The BVH build and every receiver's rays, estimated, ms.
fn rays_ms(casters: f64, receivers: f64, samples: f64, penumbra: f64) -> f64 {
    let per_ray = (64.0 / samples).powf(0.25) * (casters / 1e6).powf(0.25);
    let other = (receivers - penumbra).max(0.0);
    let rays = samples * per_ray * (penumbra * RAY_PENUMBRA_NS + other * RAY_OTHER_NS);
    (casters * BVH_NS + rays) * 1e-6
}

/// Whether the [probe](super::probe) can change the choice: the counting
/// path's and the rays' estimates, over the bounds the probe would
/// narrow ([`PENUMBRA_FRACTION`], [`PAIRS_PER_RECEIVER`]), fall on both
/// sides. Otherwise the choice holds whatever it would find, and it is
/// not run (nor the caster adjacency it reads, which rays do not need).
pub fn needs_probe(casters: usize, receivers: usize, samples: u32) -> bool {
    let (t, r, n) = (casters as f64, receivers as f64, f64::from(samples));
    let count = PAIRS_PER_RECEIVER.map(|k| count_ms(t, n, k * r));
    let rays = PENUMBRA_FRACTION.map(|f| rays_ms(t, r, n, f * r));
    let surely_rays = count[0] - rays[1] > MIN_SAVING_MS;
    let surely_count = count[1] - rays[0] <= MIN_SAVING_MS;
    !(surely_rays || surely_count)
}

pub use super::probe::ProbeEstimate;

/// Per light: count edges, or trace every receiver's rays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightPlan {
    /// The counting path.
    Count {
        /// Its estimated time, ms (0 when rays were not an option).
        count_ms: f64,
        /// The rays' estimated time, ms (0 when they were not an option).
        rays_ms: f64,
        /// What the probe found, when rays were an option.
        probe: Option<ProbeEstimate>,
    },
    /// Every receiver by rays: no stencil, wedge or counter is built.
    AllRays {
        /// The counting path's estimated time, ms.
        count_ms: f64,
        /// The BVH build and rays' estimated time, ms.
        rays_ms: f64,
        /// Asked for (`--dcs-rays always`) rather than estimated cheaper.
        forced: bool,
        /// What the probe found.
        probe: Option<ProbeEstimate>,
    },
}

impl LightPlan {
    /// What `--explain` says of it.
    pub fn describe(&self) -> String {
        let found = |probe: Option<ProbeEstimate>| {
            probe.map_or_else(
                || "no probe: the choice holds over its bounds".into(),
                |p| p.describe(),
            )
        };
        match *self {
            LightPlan::Count { rays_ms: 0.0, .. } => {
                "counted (rays not an option here: --dcs-rays never, or a light, caster or setting \
                 the ray path does not serve)"
                    .into()
            }
            LightPlan::Count {
                count_ms,
                rays_ms,
                probe,
            } => format!(
                "counted: estimated {count_ms:.0} ms against {rays_ms:.0} ms for every receiver's \
                 shadow rays ({})",
                found(probe)
            ),
            LightPlan::AllRays {
                count_ms,
                rays_ms,
                forced,
                probe,
            } => format!(
                "every receiver traced by shadow rays: {}; no stencil, wedge or counter built",
                if forced {
                    "--dcs-rays always".into()
                } else {
                    format!(
                        "estimated {rays_ms:.0} ms against {count_ms:.0} ms for counting ({})",
                        found(probe)
                    )
                }
            ),
        }
    }
}

/// The per-light choice from the casting triangles, the receivers, the
/// samples per receiver and the probe's findings (`None`: not run, see
/// [`needs_probe`]; the bounds' middle stands in); `eligible` says whether
/// rays may be used at all. Rays when they save at least
/// [`MIN_SAVING_MS`] by the estimate, or wherever they may be used with
/// [`RayChoice::Always`] (`forced` where the estimate would count).
pub fn plan_light(
    eligible: bool,
    choice: RayChoice,
    casters: usize,
    receivers: usize,
    samples: u32,
    probe: Option<ProbeEstimate>,
) -> LightPlan {
    if !eligible {
        return LightPlan::Count {
            count_ms: 0.0,
            rays_ms: 0.0,
            probe: None,
        };
    }
    let (t, r, n) = (casters as f64, receivers as f64, f64::from(samples));
    let (pairs, penumbra) = match probe {
        Some(p) => (p.pairs, p.penumbra),
        None => (
            r * PAIRS_PER_RECEIVER.iter().product::<f64>().sqrt(),
            r * PENUMBRA_FRACTION.iter().sum::<f64>() / 2.0,
        ),
    };
    let count_ms = count_ms(t, n, pairs);
    let rays_ms = rays_ms(t, r, n, penumbra);
    let saves = count_ms - rays_ms > MIN_SAVING_MS;
    if saves || choice == RayChoice::Always {
        LightPlan::AllRays {
            count_ms,
            rays_ms,
            forced: !saves,
            probe,
        }
    } else {
        LightPlan::Count {
            count_ms,
            rays_ms,
            probe,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the probe found on a scene of the scaling series (the spheres'
    /// receivers at 512²: 188,044; the bunny's: 170,138).
    fn found(pairs: f64, penumbra: f64) -> Option<ProbeEstimate> {
        Some(ProbeEstimate {
            pairs,
            penumbra,
            receivers_sampled: 256,
            edges_sampled: 13_000,
        })
    }

    fn counted(p: LightPlan) -> bool {
        matches!(p, LightPlan::Count { .. })
    }

    /// Whether the default choice (`--dcs-rays auto`, rays allowed)
    /// counts.
    fn auto_counts(
        casters: usize,
        receivers: usize,
        samples: u32,
        probe: Option<ProbeEstimate>,
    ) -> bool {
        let plan = plan_light(true, RayChoice::Auto, casters, receivers, samples, probe);
        counted(plan)
    }

    /// `--dcs-rays always` traces wherever rays may be used, saying so
    /// (`forced`) where the estimate would count, and never where they
    /// may not.
    #[test]
    fn always_traces_where_rays_may_be_used() {
        let small = (true, 7_800, 1_600, 64);
        let plan = |eligible, choice| plan_light(eligible, choice, small.1, small.2, small.3, None);
        assert!(counted(plan(small.0, RayChoice::Auto)));
        assert!(matches!(
            plan(true, RayChoice::Always),
            LightPlan::AllRays { forced: true, .. }
        ));
        assert!(counted(plan(false, RayChoice::Always)));
        let large = plan_light(true, RayChoice::Always, 4_043_552, 187_384, 64, None);
        assert!(matches!(large, LightPlan::AllRays { forced: false, .. }));
    }

    #[test]
    fn the_plan_follows_the_probe() {
        // 253k-triangle spheres and 278k-triangle bunny at 512², 64
        // samples: the same triangles and receivers, but the bunny's
        // pairs per penumbra receiver are five times the spheres' and its
        // penumbra a third: measured, the spheres count in 0.58 s against
        // 0.83 s of rays, the bunny traces in 0.42 s against 0.65 s.
        let spheres = found(2_323_027.0, 100_741.0);
        let bunny = found(3_685_737.0, 34_553.0);
        assert!(auto_counts(252_722, 188_044, 64, spheres));
        assert!(!auto_counts(277_806, 170_138, 64, bunny));
        // The 4.0M spheres at 1024², 256 samples: counted (10.2 s against
        // 15.2 s); at 512², 64 samples rays need no probe.
        let dense = found(156_417_251.0, 450_721.0);
        assert!(auto_counts(4_043_552, 749_387, 256, dense));
        assert!(!needs_probe(4_043_552, 187_384, 64));
        assert!(!auto_counts(4_043_552, 187_384, 64, None));
        // Not eligible: always counted, with no estimate.
        assert_eq!(
            plan_light(false, RayChoice::Auto, 4_121_282, 188_044, 64, None),
            LightPlan::Count {
                count_ms: 0.0,
                rays_ms: 0.0,
                probe: None,
            }
        );
        // Small savings keep the counting: 30k triangles at 40².
        assert!(auto_counts(30_000, 40 * 40, 16, found(8_000.0, 400.0)));
        // A 320k-triangle sphere at 40² saves far more.
        assert!(!auto_counts(320_000, 40 * 40, 16, found(8_000.0, 400.0)));
    }

    #[test]
    fn no_probe_where_its_bounds_agree() {
        // Every figure the probe could find within its bounds gives the
        // same choice as the bounds' middle, where it is not run.
        let mut checked = 0;
        // Large scenes at few receivers (rays whatever the probe finds) and
        // a tiny one (counted whatever it finds).
        for (t, r, n) in [
            (4_043_552, 187_384, 64),
            (10_000_000, 262_144, 16),
            (100_000, 40 * 40, 16),
            (1_000, 40 * 40, 16),
        ] {
            if needs_probe(t, r, n) {
                continue;
            }
            checked += 1;
            let middle = auto_counts(t, r, n, None);
            let rf = r as f64;
            for pairs in PAIRS_PER_RECEIVER {
                for penumbra in PENUMBRA_FRACTION {
                    let p = found(pairs * rf, penumbra * rf);
                    assert_eq!(auto_counts(t, r, n, p), middle, "{t} {r} {n}");
                }
            }
        }
        assert_eq!(checked, 4, "cases that needed a probe");
        assert!(needs_probe(277_806, 170_138, 64));
    }
}
