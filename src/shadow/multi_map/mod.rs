//! Many hard shadow maps per light, accumulated (Heckbert and Herf 1997;
//! the brute-force baseline of Schwärzler et al. 2012, §3.2): `--samples N`
//! points on the light, one hard map from each, and each receiver's Vcoef
//! the mean of its `N` map look-ups (eq. 2, as visibility `1 − ψ̂`).
//!
//! The points are the sampling module's: `--pattern`'s unit points of
//! pixel `(0, 0)`, used for every receiver (a map is one point for the
//! whole image). For `correlated` and `grid` (the regular grid including
//! the edges, Schwärzler's 17 × 17 ground truth at 289) these are exactly
//! the points the reference traces at every pixel; for the per-pixel
//! patterns they are one set of that layout. Rect lights map them as the
//! sampling module does; sphere lights get the receiver-independent
//! stand-in of [`point_on_light`] (stated in the docs).
//!
//! Maps are rendered and consumed a few at a time ([`BATCH`], one pass over
//! the receivers per batch): per receiver one `u64` accumulator, whatever `N` ([`crate::shadow::kit::many_maps`]).
//! Receivers facing away from the whole light get no look-ups (Vcoef 0),
//! a light no receiver faces no maps.

use crate::error::{Error, Result};
use crate::sampling::{PatternSampler, SamplePattern};
use crate::shadow::kit::light_view::{fully_lit, map_bounds};
use crate::shadow::kit::many_maps::{
    active_receivers, point_on_light, quantize, receiver_points, resolve, MapSetup,
};
use crate::shadow::kit::shadow_maps::ShadowMapOptions;
use crate::shadow::kit::shadow_maps::{poisson_disk, Pcf};
use crate::shadow::kit::PassTimer;
use crate::shadow::technique::{
    Bands, Capabilities, QualitySetting, Support, TechniqueInfo, TermKind,
};
use crate::shadow::{BufferNote, LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};

/// Largest `--samples` multi-map accepts: the `u64` accumulators then hold
/// `N · QSCALE` with room to spare, and 65536 full maps is hours of work.
pub const MAX_MAPS: u32 = 65536;

/// Maps rendered before one pass of look-ups consumes them all: the
/// G-buffer is read once per batch, and memory stays at `BATCH` maps
/// whatever `--samples` is.
pub const BATCH: usize = 4;

/// The multi-map technique.
#[derive(Debug, Clone, Copy)]
pub struct MultiMap {
    /// Maps per light.
    pub maps: u32,
    /// Where on the light they are.
    pub pattern: SamplePattern,
    /// Seed of the pattern and of the Poisson-PCF rotation.
    pub seed: u64,
    /// Map size, filter and biases.
    pub options: ShadowMapOptions,
}

/// Multi-map in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "multi-map",
    summary: "--samples hard shadow maps per light from the pattern's points, averaged per receiver (the brute-force image-based soft shadow)",
    module: "shadow/multi_map/",
    page: Some("shadow-maps.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Yes,
        textured_lights: Support::Ignored(
            "every map has the same weight: the light's radiance texture does not weight \
             the maps (the unshadowed light still uses it)",
        ),
        enclosed_lights: crate::shadow::technique::MAPS_MISS_ENCLOSURE,
        reached_lights: Support::Yes,
        semi_opaque: crate::shadow::technique::MAPS_OPAQUE_ONLY,
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| {
        let size = s.base.shadow_map.map_size;
        s.samples
            .iter()
            .map(|&n| QualitySetting {
                curve: "multi-map".into(),
                label: format!("{n} maps, {size}²"),
                samples: Some(n),
                pattern: s.first_pattern(),
                options: s.base.clone(),
            })
            .collect()
    },
    build: |p| {
        Box::new(MultiMap {
            maps: p.samples,
            pattern: p.pattern,
            seed: p.seed,
            options: p.options.shadow_map,
        })
    },
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[Samples, Pattern, Seed, ShadowMaps]
    },
    cost: crate::shadow::technique::CostClass::Raster,
};

impl ShadowTechnique for MultiMap {
    fn name(&self) -> &'static str {
        "multi-map"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        if !(1..=MAX_MAPS).contains(&self.maps) {
            return Err(Error::param(
                "--samples",
                format!(
                    "multi-map renders one map per sample: {} is outside 1..={MAX_MAPS}",
                    self.maps
                ),
            ));
        }
        let bias = self.options.bias();
        bias.validate()?;
        let mut out = ShadowOutput::default();
        let n = ctx.gbuffer.len();
        // Nothing casts or nothing receives: every light fully visible.
        let Some((casters, receivers)) = map_bounds(ctx.scene) else {
            return Ok(fully_lit(ctx));
        };
        let pcf = self.options.pcf;
        let size = self.options.map_size;
        let mut peak_map = 0u64;
        let mut resident = 0u64;
        let receivers_at = receiver_points(ctx.gbuffer);
        for (k, light) in ctx.scene.lights.iter().enumerate() {
            let t = PassTimer::start(format!("multi-map light {k}"));
            let active = active_receivers(ctx.gbuffer, light);
            let faced = active.iter().filter(|&&a| a).count();
            let mut points = Vec::new();
            if faced > 0 {
                PatternSampler::new(self.pattern, self.maps, self.seed, k)
                    .unit_points((0, 0), &mut points);
            }
            let setup = MapSetup {
                ctx,
                light: k,
                casters,
                receivers,
                size,
                bias,
                seed: self.seed,
                taps: match pcf {
                    Pcf::Poisson(m) => poisson_disk(m, 1.5),
                    _ => Vec::new(),
                },
                points: &receivers_at,
            };
            let mut acc = vec![0u64; n];
            let mut rendered = 0u32;
            // A few maps per pass over the receivers: each receiver is read
            // once per batch (the sum is exact and order-free, so batching
            // does not change a bit).
            for batch in points.chunks(BATCH) {
                let mut maps = Vec::with_capacity(batch.len());
                for &st in batch {
                    let map = setup.render(point_on_light(light, st, casters))?;
                    if let Some(m) = &map {
                        rendered += 1;
                        resident += m.map.memory_bytes();
                    }
                    maps.push(map);
                }
                peak_map = peak_map.max(resident);
                resident = 0;
                let refs: Vec<_> = maps.iter().map(Option::as_ref).collect();
                setup.consume_batch(&refs, pcf, &active, &mut acc, 1, |_, v, a| {
                    a[0] += quantize(v);
                });
            }
            let total = points.len() as u64;
            let vcoef: Vec<f32> = acc.iter().map(|&a| resolve(a, total)).collect();
            t.finish_with(&mut out.passes, format!("{rendered} maps"));
            out.buffers.push(BufferNote {
                name: "shadow maps".into(),
                detail: format!(
                    "{rendered} rendered for light {k} ({} points of pattern {}; {} of {n} \
                     receivers face the light, the others get no look-up), up to {BATCH} \
                     resident at a time ({size}² f32 linear depth), consumed in one pass",
                    points.len(),
                    self.pattern,
                    faced
                ),
                bytes: peak_map,
            });
            out.lights.push(LightTerm::Vcoef(vcoef));
        }
        out.buffers.push(BufferNote {
            name: "receiver points".into(),
            detail: "f32 position and geometric normal per pixel, expanded from the G-buffer \
                     once for every map's look-up"
                .into(),
            bytes: n as u64 * 24,
        });
        out.buffers.push(BufferNote {
            name: "map accumulators".into(),
            detail: format!(
                "u64 per receiver: Σ round(visibility · {}) over the maps (exact, order-free); \
                 one per light at a time",
                crate::shadow::kit::many_maps::QSCALE
            ),
            bytes: n as u64 * 8,
        });
        out.buffers.push(BufferNote {
            name: "receivers facing the light".into(),
            detail: "one byte per pixel, per light at a time".into(),
            bytes: n as u64,
        });
        Ok(out)
    }
}
