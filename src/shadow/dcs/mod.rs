//! Depth complexity sampling (thesis ch. 4, after Laine et al. 2005):
//! exact per-light-sample occluder counts from shadow volumes and
//! penumbra wedges.
//!
//! Per light:
//!
//! 1. **Integration constant**: the hard shadow volumes from the light's
//!    centre give, per pixel, `D(O)`, the number of occluders between the
//!    receiver and the centre (the stencil count, exact `i32`).
//! 2. **Membership**: a wedge for every candidate edge (centre
//!    silhouettes, or whole-light silhouettes, [`SilhouetteMode`]) is
//!    rasterized through the pipeline exactly as for penumbra wedges; each
//!    tile records which (pixel, edge) pairs lie inside one — nothing per
//!    sample, so memory follows the wedge coverage, not width × height ×
//!    samples.
//! 3. **Counters**: tile by tile in parallel, each receiver with at least
//!    one wedge gets `N` `i32` counters (on the worker's stack of scratch
//!    buffers: 4 KiB for 1024 samples, in L1) set to `D(O)`; every
//!    recorded edge is projected from the receiver into the light's chart
//!    ([`chart`]) and adds its signed change to the samples it covers
//!    ([`counters`], SIMD over samples, exact test). Receivers outside
//!    every wedge have `D = D(O)` for all samples and do no per-sample
//!    work at all.
//! 4. **Shading**: Vcoef `= 1 − (1/N) Σ sat(D_i)` (eq. 4.1), or the
//!    direct light integrated per sample with `H(D_i)` as visibility
//!    (eq. 4.6), with the same estimator as the reference.
//!
//! This file holds the technique, its options and the per-light
//! orchestration; the passes themselves are in `passes.rs`, one
//! receiver's counting in `receiver.rs`.

#[forbid(unsafe_code)]
pub mod bitfield;
#[forbid(unsafe_code)]
pub mod block_extras;
pub mod blocks;
#[forbid(unsafe_code)]
pub mod chart;
mod chart_lanes;
pub mod counters;
mod edge_lanes;
#[forbid(unsafe_code)]
pub mod edges;
#[forbid(unsafe_code)]
pub mod faces;
#[forbid(unsafe_code)]
pub mod options;
mod passes;
pub mod plan;
pub mod probe;
pub mod rays;
mod receiver;
pub mod region;
mod sample_lanes;
#[forbid(unsafe_code)]
pub mod settings;
#[forbid(unsafe_code)]
pub mod ties;

use super::kit::groups::Attenuation;
pub use super::kit::groups::TransmittanceMode;
use super::kit::membership::{light_start, light_start_shifted};
use super::kit::rays::ShadowOrigin;
use super::kit::stsv::{Filter, STriangles};
use super::kit::timing::{timed, PassTimer};
use super::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use super::technique::{PixelVisibility, SampleDecisions};
use super::{BufferNote, LightTerm, PassTiming, ShadowContext, ShadowOutput, ShadowTechnique};
use crate::error::Result;
use crate::output::Layer;
use crate::sampling::{LightSampler, PatternSampler, SamplePattern};
use crate::shade::{LightSample, PreparedLight};
use blocks::BlockGrid;
use glam::Vec3;
pub use options::{CoverageTest, DcsMode, DcsOptions, RayChoice, SilhouetteMode};
use passes::{
    assemble, build_wedges, candidate_edges, count_tiles, coverage_tables, gather, group_starts,
    recount_ties, s_triangle_membership, wedge_membership,
};
use plan::LightPlan;
use rayon::prelude::*;
use rays::{RayPixels, RayScratch};
use receiver::LightPass;
pub use receiver::{CounterInspector, InspectedPixel};
pub use settings::{DcsLightReport, DepthComplexitySampling};
use ties::depth_shifts;

/// Depth complexity sampling in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "dcs",
    summary: "depth complexity sampling: exact per-sample occluder counts from shadow volumes and wedges (thesis ch. 4)",
    module: "shadow/dcs/",
    page: Some("dcs.md"),
    capabilities: |o| {
        let exact = o.dcs.silhouettes == SilhouetteMode::WholeLight
            && o.dcs.coverage == CoverageTest::Exact
            && o.dcs.transmittance == TransmittanceMode::Exact;
        Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: match o.dcs.coverage {
            CoverageTest::Exact => Support::Yes,
            CoverageTest::BitField => Support::Refused {
                param: "--coverage",
                why: "the bit-field tables are built for rect lights (use --coverage exact)",
            },
        },
        textured_lights: Support::Yes,
        enclosed_lights: crate::shadow::technique::SILHOUETTES_MISS_ENCLOSURE,
        reached_lights: crate::shadow::technique::COUNTS_MISS_REACHED_LIGHT,
        semi_opaque: Support::Yes,
        s_triangles: Support::Yes,
        output: match o.dcs.mode {
            DcsMode::Vcoef => TermKind::Vcoef,
            DcsMode::Direct => TermKind::Radiance,
        },
        exact,
        exact_image: exact && o.dcs.mode == DcsMode::Direct,
    }
    },
    quality_settings: |s| {
        // The default (exact) first, then the centre-silhouette
        // approximation with every pattern, then summed opacity.
        let mut out = s.per_sample_count("dcs", "", s.first_pattern(), |o| {
            o.dcs.silhouettes = SilhouetteMode::WholeLight
        });
        for (j, &pattern) in s.patterns.iter().enumerate() {
            let (curve, suffix) = if j == 0 {
                ("dcs centre".to_string(), ", centre silhouettes".to_string())
            } else {
                (format!("dcs centre {pattern}"), format!(", centre, {pattern}"))
            };
            out.extend(s.per_sample_count(&curve, &suffix, pattern, |o| {
                o.dcs.silhouettes = SilhouetteMode::Centre
            }));
        }
        if s.semi_opaque {
            out.extend(s.per_sample_count(
                "dcs summed-opacity",
                ", summed opacity",
                s.first_pattern(),
                |o| o.dcs.transmittance = TransmittanceMode::Summed,
            ));
        }
        out
    },
    build: |p| {
        Box::new(DepthComplexitySampling {
            samples: p.samples,
            seed: p.seed,
            silhouettes: p.options.dcs.silhouettes,
            mode: p.options.dcs.mode,
            pattern: p.pattern,
            transmittance: p.options.dcs.transmittance,
            coverage: p.options.dcs.coverage,
            opacity_filter: p.options.stsv.opacity_filter,
            rays: p.options.dcs.rays,
        })
    },
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[Samples, Pattern, Seed, Dcs, Stsv]
    },
    cost: crate::shadow::technique::CostClass::Raster,
};

/// What DCS counts besides the opaque casters, from the render's cache
/// (found once per render, not per light): the semi-opaque groups and the
/// S-triangles.
struct SceneCasters<'a> {
    partial: &'a [(Attenuation, crate::geom::EdgeAdjacency)],
    s_triangles: &'a STriangles,
}

impl<'a> SceneCasters<'a> {
    fn new(ctx: &ShadowContext<'a>) -> SceneCasters<'a> {
        SceneCasters {
            partial: ctx.cache.semi_opaque_groups(),
            s_triangles: ctx.cache.s_triangles(),
        }
    }
}

impl DepthComplexitySampling {
    /// Runs light `k` under its `plan` ([`DepthComplexitySampling::plan`]):
    /// its term, AOV channels and report, pass by pass (`passes.rs`).
    fn light(
        &self,
        ctx: &ShadowContext,
        (k, plan): (usize, LightPlan),
        casters: &SceneCasters,
        passes: &mut Vec<PassTiming>,
        inspect: Option<(&CounterInspector, Option<&[usize]>)>,
    ) -> Result<(LightTerm, [Vec<f32>; 3], DcsLightReport)> {
        let light = &ctx.scene.lights[k];
        if let LightPlan::AllRays { .. } = plan {
            return self.light_by_rays(ctx, k, plan, passes);
        }
        // The exact mode's tie test needs the counts under two depth
        // shifts: made with the stencil pass, from one setup of the volume.
        let (start, changes) = match self.silhouettes {
            SilhouetteMode::WholeLight => light_start_shifted(ctx, k, passes, depth_shifts(true))?,
            SilhouetteMode::Centre => (light_start(ctx, k, passes)?, Vec::new()),
        };
        let (bound, point) = (start.bound, start.point);
        let (mut starts, mut framebuffer) =
            group_starts(ctx, k, (start, changes), casters.partial, passes)?;
        let (ties, exact) = recount_ties(ctx, k, point, &mut starts, self.silhouettes, passes)?;
        let groups = timed(passes, format!("candidate edges light {k}"), || {
            candidate_edges(light, point, self, starts)
        });
        let wedges = timed(passes, format!("wedge build light {k}"), || {
            build_wedges(ctx, &bound, point, &groups, self.silhouettes)
        });
        let grid = framebuffer.grid();
        let mut tiles = timed(passes, format!("wedge membership light {k}"), || {
            wedge_membership(&mut framebuffer, &wedges)
        })?;
        let tables = coverage_tables(self, ctx, k, &bound)?;
        let s_triangles = casters.s_triangles;
        let stsv = s_triangle_membership(ctx, k, s_triangles, passes)?;
        let t = PassTimer::start(format!("counters light {k}"));
        let pass = LightPass {
            ctx,
            technique: self,
            bound,
            centre: point.as_dvec3(),
            sampler: LightSampler::new(light),
            pattern: PatternSampler::new(self.pattern, self.samples, self.seed, k),
            prepared: PreparedLight::new(light, &ctx.scene.textures),
            groups: &groups,
            tables: &tables,
            blocks: {
                let pattern = PatternSampler::new(self.pattern, self.samples, self.seed, k);
                pattern
                    .jittered((0, 0))
                    .and_then(|(strata, _)| BlockGrid::new(strata, self.samples))
            },
            s_triangles: (!s_triangles.is_empty()).then_some(s_triangles),
            ties: &ties,
            exact: &exact,
            origin: ShadowOrigin::new(ctx.scene, ctx.geometry),
            inspect: inspect.map(|i| i.0),
            inspect_pixels: inspect.and_then(|i| i.1),
        };
        let results = count_tiles(
            &pass,
            grid,
            &mut tiles,
            &wedges.unbounded,
            &wedges.clusters,
            stsv.as_ref(),
        );
        t.finish(passes);

        let with_radiance = self.mode == DcsMode::Direct || pass.prepared.is_textured();
        let mut report = DcsLightReport {
            candidate_edges: groups.iter().map(|g| g.candidates.edges.len()).sum(),
            semi_opaque_groups: groups.len() - 1,
            unbounded_edges: wedges.unbounded.len(),
            wedge_triangles: wedges.wedges.zfail.triangles.len()
                + wedges.wedges.zpass.triangles.len(),
            plan: Some(plan),
            region_bytes: wedges.region_bytes(),
            tie_bytes: exact.bytes(),
            tie_tree: exact.built(),
            ..DcsLightReport::default()
        };
        let (mut vcoef, mut radiance, aovs) = assemble(grid, results, with_radiance, &mut report);
        if let SamplePattern::Interleaved { n } = self.pattern {
            (vcoef, radiance) = timed(passes, format!("gather light {k}"), || {
                gather(ctx, grid, n, vcoef, radiance)
            });
        }
        let term = if with_radiance {
            LightTerm::Radiance { radiance, vcoef }
        } else {
            LightTerm::Vcoef(vcoef)
        };
        Ok((term, aovs, report))
    }

    /// Light `k`'s plan ([`rays::plan_light`]): rays may replace counting
    /// only for the exact configuration, whose image they reproduce (whole-
    /// light silhouettes, the exact coverage test, the direct mode), an
    /// untextured light, opaque casters only, samples keyed per pixel
    /// (not interleaved) and no inspector of the counters.
    fn plan(
        &self,
        ctx: &ShadowContext,
        k: usize,
        casters: &SceneCasters,
        inspected: bool,
        passes: &mut Vec<PassTiming>,
    ) -> LightPlan {
        let light = &ctx.scene.lights[k];
        let eligible = self.rays != RayChoice::Never
            && self.silhouettes == SilhouetteMode::WholeLight
            && self.coverage == CoverageTest::Exact
            && self.mode == DcsMode::Direct
            && light.texture.is_none()
            && casters.partial.is_empty()
            && casters.s_triangles.is_empty()
            && !matches!(self.pattern, SamplePattern::Interleaved { .. })
            && !inspected;
        // The receivers are counted only where rays are an option, over
        // the whole frame (a band of it must make the frame's choice).
        let receivers = if eligible {
            ctx.gbuffer.frame_surfaces().count()
        } else {
            0
        };
        let triangles = ctx.geometry.triangles.len();
        let probed = eligible
            && self.rays == RayChoice::Auto
            && plan::needs_probe(triangles, receivers, self.samples);
        let probe = probed.then(|| {
            timed(passes, format!("cost probe light {k}"), || {
                probe::probe(ctx.scene, ctx.geometry, light, ctx.gbuffer, receivers)
            })
        });
        plan::plan_light(
            eligible,
            self.rays,
            triangles,
            receivers,
            self.samples,
            probe,
        )
    }

    /// Light `k` with every receiver traced by rays (the plan's
    /// [`LightPlan::AllRays`]): no stencil, wedge or counter is built.
    fn light_by_rays(
        &self,
        ctx: &ShadowContext,
        k: usize,
        plan: LightPlan,
        passes: &mut Vec<PassTiming>,
    ) -> Result<(LightTerm, [Vec<f32>; 3], DcsLightReport)> {
        let light = &ctx.scene.lights[k];
        let tracer = timed(passes, "shadow-ray bvh", || ctx.cache.tracer());
        let t = PassTimer::start(format!("rays light {k}"));
        let prepared = PreparedLight::new(light, &ctx.scene.textures);
        let pattern = PatternSampler::new(self.pattern, self.samples, self.seed, k);
        let rays = RayPixels::new(ctx, tracer, k, pattern, &prepared);
        let width = (ctx.gbuffer.width as usize).max(1);
        let n = ctx.gbuffer.len();
        let rows: Vec<Vec<receiver::PixelResult>> = (0..n.div_ceil(width))
            .into_par_iter()
            .map_init(RayScratch::default, |scratch, y| {
                if ctx.observer.cancelled() {
                    // The render discards a cancelled pass.
                    return Vec::new();
                }
                (y * width..((y + 1) * width).min(n))
                    .map(|i| rays.pixel(i, scratch))
                    .collect()
            })
            .collect();
        t.finish(passes);
        let mut vcoef = vec![0.0f32; n];
        let mut radiance = vec![Vec3::ZERO; n];
        let mut aovs = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
        let mut traced = 0;
        for (y, row) in rows.iter().enumerate() {
            for (x, r) in row.iter().enumerate() {
                let i = y * width + x;
                traced += usize::from(ctx.gbuffer.is_surface(i));
                vcoef[i] = r.vcoef;
                radiance[i] = r.radiance;
                aovs[0][i] = r.max_dc;
                aovs[1][i] = r.mean_dc;
                aovs[2][i] = r.edges;
            }
        }
        let report = DcsLightReport {
            traced_pixels: traced,
            plan: Some(plan),
            ..DcsLightReport::default()
        };
        Ok((LightTerm::Radiance { radiance, vcoef }, aovs, report))
    }

    /// Runs every light, with each light's buffer report.
    pub fn compute_with_report(
        &self,
        ctx: &ShadowContext,
    ) -> Result<(ShadowOutput, Vec<DcsLightReport>)> {
        let mut out = ShadowOutput::default();
        let names = ["dc_max", "dc_mean", "wedges"];
        let mut layers: Vec<Layer> = names
            .iter()
            .map(|n| Layer {
                name: (*n).into(),
                channels: Vec::new(),
            })
            .collect();
        let mut reports = Vec::new();
        let pixels = ctx.gbuffer.len() as u64;
        let workers = rayon::current_num_threads() as u64;
        let n = u64::from(self.samples);
        let padded = n.div_ceil(counters::LANES as u64) * counters::LANES as u64;
        let casters = SceneCasters::new(ctx);
        let plans: Vec<LightPlan> = (0..ctx.scene.lights.len())
            .map(|k| self.plan(ctx, k, &casters, false, &mut out.passes))
            .collect();
        let counted = plans.iter().any(|p| matches!(p, LightPlan::Count { .. }));
        if !counted {
            // Every light traced by rays (the cost choice): none of the
            // counting path's buffers exists.
            out.buffers.push(BufferNote {
                name: "stencil, counters, wedges".into(),
                detail: "not allocated: every light's receivers are traced by shadow rays".into(),
                bytes: 0,
            });
        }
        if counted {
            out.buffers.push(BufferNote {
                name: "stencil".into(),
                detail: "i32 per pixel: D(O), exact (no 8-bit wrap)".into(),
                bytes: pixels * 4,
            });
            out.buffers.push(BufferNote {
                name: "depth-complexity counters".into(),
                detail: format!(
                    "i32 × {n} samples per receiver, one receiver at a time per worker ({workers}): \
                     never width × height × samples"
                ),
                bytes: workers * padded * 4,
            });
            out.buffers.push(BufferNote {
                name: "light samples".into(),
                detail: format!("{n} points + f32 chart coordinates per worker"),
                bytes: workers
                    * (n * std::mem::size_of::<LightSample>() as u64 + padded * 8 + n * 4),
            });
            let partial = casters.partial;
            let s_triangles_present = !casters.s_triangles.is_empty();
            let opacities: Vec<String> = partial
                .iter()
                .filter_map(|(a, _)| match a {
                    Attenuation::Partial { opacity, .. } => Some(format!("{}", *opacity as f32)),
                    Attenuation::Opaque => None,
                })
                .collect();
            out.buffers.push(BufferNote {
                name: "transmittance".into(),
                detail: if partial.is_empty() && s_triangles_present {
                    "per sample f64 accumulated optical depth and transmittance per worker, for \
                     S-triangles' partial texels only"
                        .into()
                } else if partial.is_empty() {
                    "not allocated: every caster is opaque".into()
                } else {
                    format!(
                        "{} semi-opaque group(s) (opacity {}), {}: i32 start count per pixel \
                         per group; per sample i32 layer count (reused by the groups), f64 \
                         accumulated {} and f64 transmittance, per worker",
                        partial.len(),
                        opacities.join(", "),
                        self.transmittance.name(),
                        match self.transmittance {
                            TransmittanceMode::Exact => "optical depth",
                            TransmittanceMode::Summed => "opacity",
                        }
                    )
                },
                bytes: if partial.is_empty() {
                    0
                } else {
                    partial.len() as u64 * pixels * 4 + workers * (padded * 4 + n * 16)
                },
            });
            let s_triangles = casters.s_triangles;
            out.buffers.push(BufferNote {
                name: "soft textured shadow volumes".into(),
                detail: if s_triangles.is_empty() {
                    "not used: no opacity-textured caster (S-triangle)".into()
                } else {
                    format!(
                        "{} S-triangles: one volume each per light, (pixel, S-triangle) pairs as \
                         u64 per tile; per sample f32 position and opacity per worker; {} \
                         texel look-up; opaque texels add to D, partial ones to the \
                         transmittance",
                        s_triangles.len(),
                        match self.opacity_filter {
                            Filter::Nearest => "nearest",
                            Filter::Bilinear => "bilinear",
                        }
                    )
                },
                bytes: if s_triangles.is_empty() {
                    0
                } else {
                    workers * (padded * 16 + n * 16)
                },
            });
            let textured = ctx.scene.lights.iter().any(|l| l.texture.is_some());
            out.buffers.push(BufferNote {
                name: "per-sample luminance".into(),
                detail: if textured && self.mode == DcsMode::Direct {
                    "evaluated per sample inside the direct-light estimator".into()
                } else if textured {
                    "looked up per sample and summed per receiver (eq. 4.2: luminance-weighted \
                     visibility modulating the unshadowed light), no buffer; the vcoef AOV stays \
                     plain visibility"
                        .into()
                } else {
                    "not allocated: no textured light".into()
                },
                bytes: 0,
            });
        }
        for (k, &plan) in plans.iter().enumerate() {
            let (term, aovs, report) =
                self.light(ctx, (k, plan), &casters, &mut out.passes, None)?;
            out.buffers.push(BufferNote {
                name: format!("cost choice light {k}"),
                detail: report
                    .plan
                    .map_or_else(|| "counted".to_string(), |p| p.describe()),
                bytes: 0,
            });
            if report.traced_pixels > 0 {
                out.buffers.push(BufferNote {
                    name: format!("shadow rays light {k}"),
                    detail: format!(
                        "{} receivers × {n} samples traced through the shared BVH (the \
                         reference's rays); dc_max and dc_mean there are 1 and the hidden \
                         fraction where a sample is hidden (rays stop at the first occluder)",
                        report.traced_pixels
                    ),
                    bytes: 0,
                });
                out.lights.push(term);
                for (layer, aov) in layers.iter_mut().zip(aovs) {
                    layer.channels.push((k.to_string(), aov));
                }
                reports.push(report);
                continue;
            }
            out.buffers.push(BufferNote {
                name: format!("start-count ties light {k}"),
                detail: if report.tie_tree {
                    "u32 caster group and weight per triangle; a face tree (f32 corners, 4-wide \
                     nodes) for the tied receivers' exact recounts"
                        .into()
                } else {
                    "u32 caster group and weight per triangle; no face tree: no receiver needed \
                     a recount"
                        .into()
                },
                bytes: report.tie_bytes,
            });
            out.buffers.push(BufferNote {
                name: format!("edge regions light {k}"),
                detail: format!(
                    "{} edges without a bounded wedge: each its f64 world-space region \
                     (planes in 4-lane groups, its two face planes) and screen rectangle, \
                     and their clusters' regions",
                    report.unbounded_edges
                ),
                bytes: report.region_bytes,
            });
            out.buffers.push(BufferNote {
                name: format!("wedge membership light {k}"),
                detail: format!(
                    "{} candidate edges in {} caster group(s) ({} silhouettes, {} without a \
                     bounded wedge), {} wedge triangles; (pixel, edge) pairs as u64, {} \
                     receivers sampled, {} outside every wedge with no per-sample work; {} \
                     (pixel, unbounded edge) pairs; {} start counts recounted across a quad",
                    report.candidate_edges,
                    1 + report.semi_opaque_groups,
                    self.silhouettes.name(),
                    report.unbounded_edges,
                    report.wedge_triangles,
                    report.sampled_pixels,
                    pixels as usize - report.sampled_pixels,
                    report.unbounded_pairs,
                    report.quad_recounts,
                ),
                bytes: report.pairs as u64 * 8,
            });
            out.lights.push(term);
            for (layer, aov) in layers.iter_mut().zip(aovs) {
                layer.channels.push((k.to_string(), aov));
            }
            reports.push(report);
        }
        out.layers = layers;
        Ok((out, reports))
    }
}

impl DepthComplexitySampling {
    /// Runs light `k` and calls `inspect` with every surface pixel's
    /// samples and final counters (pixels outside every wedge included),
    /// for tests and studies of the counters themselves.
    pub fn inspect_light(
        &self,
        ctx: &ShadowContext,
        k: usize,
        inspect: &CounterInspector,
    ) -> Result<LightTerm> {
        let mut passes = Vec::new();
        let casters = SceneCasters::new(ctx);
        Ok(self
            .light(
                ctx,
                (k, self.plan(ctx, k, &casters, true, &mut passes)),
                &casters,
                &mut passes,
                Some((inspect, None)),
            )?
            .0)
    }
}

impl SampleDecisions for DepthComplexitySampling {
    /// Per sample: `H(D)` (the opaque count says visible) times the
    /// semi-opaque casters' and S-triangles' transmittance, the values
    /// the shading uses.
    fn sample_visibility(
        &self,
        ctx: &ShadowContext,
        light: usize,
        pixels: &[usize],
    ) -> Result<Vec<PixelVisibility>> {
        let out = std::sync::Mutex::new(Vec::with_capacity(pixels.len()));
        let visit = |i: usize, px: &InspectedPixel| {
            let visibility = px
                .counters
                .iter()
                .enumerate()
                .map(|(s, &c)| {
                    let t = px.transmittance.get(s).copied().unwrap_or(1.0);
                    if c <= 0 {
                        t
                    } else {
                        0.0
                    }
                })
                .collect();
            out.lock().expect("no panic").push(PixelVisibility {
                pixel: i,
                samples: px.samples.to_vec(),
                visibility,
            });
        };
        let mut passes = Vec::new();
        let casters = SceneCasters::new(ctx);
        // An inspector reads counters: the plan counts.
        let plan = self.plan(ctx, light, &casters, true, &mut passes);
        self.light(
            ctx,
            (light, plan),
            &casters,
            &mut passes,
            Some((&visit, Some(pixels))),
        )?;
        Ok(out.into_inner().expect("no panic"))
    }
}

impl ShadowTechnique for DepthComplexitySampling {
    fn name(&self) -> &'static str {
        "dcs"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        Ok(self.compute_with_report(ctx)?.0)
    }

    fn sample_decisions(&self) -> Option<&dyn SampleDecisions> {
        Some(self)
    }
}
