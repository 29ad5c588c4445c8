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

pub mod bitfield;
pub mod chart;
pub mod counters;
pub mod edges;
pub mod region;
pub mod ties;

use super::kit::groups::Attenuation;
pub use super::kit::groups::TransmittanceMode;
use super::kit::membership::{draw_wedges, light_start, HalfWedgeMembership, LightStart};
use super::kit::rays::{scene_diagonal, EPS_POSITION, EPS_SCENE};
use super::kit::volumes::{build_volume, stencil_counts};
use super::kit::wedge_geometry::{HalfWedge, LightBound, SilhouetteQuad, WedgePrimitive, Wedges};
use super::registry::{Capabilities, Support, TechniqueInfo, TermKind};
use super::stsv::{
    membership as stsv_membership, Filter, STriangles, SamplePositions, ShadowOrigin,
};
use super::{BufferNote, LightTerm, PassTiming, ShadowContext, ShadowOutput, ShadowTechnique};
use crate::error::Result;
use crate::geom::silhouette::faces_point;
use crate::output::Layer;
use crate::raster::{FragmentBatch, FragmentStage};
use crate::raster::{TileGrid, TILE_PIXELS, TILE_SIZE};
use crate::sampling::{LightSampler, PatternSampler, SamplePattern};
use crate::scene::LightShape;
use crate::shade::gather::{gather_filter, GatherParams};
use crate::shade::{surface_point, LightSample, PreparedLight};
use bitfield::{CoverageTables, TableResolution};
use chart::ReceiverChart;
use counters::{add_covered, ChartSamples, OrientedEdge};
pub use edges::SilhouetteMode;
use edges::{side_of, CandidateEdges, LightShapeForSilhouettes};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use region::RegionBound;
use std::time::Instant;
use ties::{tied_pixels, ExactStart};

/// What the counters are turned into.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum DcsMode {
    /// A visibility coefficient modulating the unshadowed direct light
    /// (eq. 4.1).
    #[default]
    Vcoef,
    /// The direct light integrated over the samples, each weighted by its
    /// binary visibility (eq. 4.6).
    Direct,
}

impl DcsMode {
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            DcsMode::Vcoef => "vcoef",
            DcsMode::Direct => "direct",
        }
    }
}

/// Depth complexity sampling's command-line options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct DcsOptions {
    /// Depth complexity sampling: wedges on the silhouettes from the whole
    /// light (`light`, exact, the default) or from the light's centre
    /// (`centre`, faster, misses edges that are silhouettes only from
    /// other points of the light).
    #[arg(long, value_enum, default_value_t = SilhouetteMode::WholeLight)]
    pub silhouettes: SilhouetteMode,
    /// Depth complexity sampling: `vcoef` (modulate the unshadowed light,
    /// eq. 4.1) or `direct` (integrate the light per sample, eq. 4.6).
    #[arg(long = "dcs-mode", value_enum, default_value_t = DcsMode::Vcoef)]
    pub mode: DcsMode,
    /// Depth complexity sampling: semi-opaque casters' transmittance,
    /// `exact` (the product of `1 − opacity` per layer) or `summed` (the
    /// thesis's summed-opacity approximation).
    #[arg(long, value_enum, default_value_t = TransmittanceMode::Exact)]
    pub transmittance: TransmittanceMode,
    /// Depth complexity sampling: covered samples by the exact per-sample
    /// test (`exact`) or the thesis's precomputed bit fields (`bitfield`,
    /// approximate; correlated or interleaved patterns on rect lights).
    #[arg(long, value_enum, default_value_t = CoverageTest::Exact)]
    pub coverage: CoverageTest,
}

impl Default for DcsOptions {
    /// The command line's defaults (exact: whole-light silhouettes).
    fn default() -> Self {
        crate::shadow::TechniqueOptions::default().dcs
    }
}

/// Depth complexity sampling in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "dcs",
    summary: "depth complexity sampling: exact per-sample occluder counts from shadow volumes and wedges (thesis ch. 4)",
    module: "shadow/dcs/",
    page: Some("dcs.md"),
    capabilities: |o| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: match o.dcs.coverage {
            CoverageTest::Exact => Support::Yes,
            CoverageTest::BitField => Support::Refused {
                param: "--coverage",
                why: "the bit-field tables are built for rect lights (use --coverage exact)",
            },
        },
        textured_lights: Support::Yes,
        semi_opaque: Support::Yes,
        s_triangles: Support::Yes,
        output: match o.dcs.mode {
            DcsMode::Vcoef => TermKind::Vcoef,
            DcsMode::Direct => TermKind::Radiance,
        },
        exact: o.dcs.silhouettes == SilhouetteMode::WholeLight
            && o.dcs.coverage == CoverageTest::Exact
            && o.dcs.transmittance == TransmittanceMode::Exact,
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
        })
    },
};

/// The depth-complexity-sampling technique.
#[derive(Debug, Clone, Copy)]
pub struct DepthComplexitySampling {
    /// Light samples per receiver and light (any `N ≥ 1`).
    pub samples: u32,
    /// Seed of the light samples (the reference's, for the same pixel).
    pub seed: u64,
    /// Which edges get wedges.
    pub silhouettes: SilhouetteMode,
    /// Vcoef or direct-lighting output.
    pub mode: DcsMode,
    /// How samples are placed on the light (shared with the reference).
    pub pattern: SamplePattern,
    /// How semi-opaque casters' layer counts become transmittance.
    pub transmittance: TransmittanceMode,
    /// How covered samples are found.
    pub coverage: CoverageTest,
    /// Look-up of S-triangles' opacity textures.
    pub opacity_filter: Filter,
}

/// How the samples an edge covers are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum CoverageTest {
    /// The exact per-sample test, SIMD over samples.
    #[default]
    Exact,
    /// The thesis's precomputed bit fields (Fig. 4.9), approximate; only
    /// for sample sets shared by many pixels on rect lights.
    #[value(name = "bitfield")]
    BitField,
}

impl CoverageTest {
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            CoverageTest::Exact => "exact",
            CoverageTest::BitField => "bitfield",
        }
    }
}

/// One tile's (pixel, edge) pairs: `local << 33 | edge << 1 | outer`, so
/// that sorting groups them by pixel.
#[derive(Default)]
struct MembershipTile {
    membership: HalfWedgeMembership,
    entries: Vec<u64>,
}

/// Records, per tile, which pixels each half-wedge holds.
struct MembershipStage<'a> {
    primitives: &'a [WedgePrimitive],
    halves: &'a [HalfWedge],
    /// Candidate edge of each half.
    half_edge: &'a [u32],
    /// The set is counted z-pass.
    zpass: bool,
}

impl MembershipStage<'_> {
    fn flush(&self, tile: &mut MembershipTile) {
        let Some(h) = tile.membership.current() else {
            return;
        };
        let tag =
            u64::from(self.half_edge[h as usize]) << 1 | u64::from(self.halves[h as usize].outer);
        let MembershipTile {
            membership,
            entries,
        } = tile;
        membership.drain(|i| entries.push((i as u64) << 33 | tag));
    }
}

impl FragmentStage<0> for MembershipStage<'_> {
    type Target = MembershipTile;

    fn shade(&self, batch: &FragmentBatch<0>, tile: &mut MembershipTile) {
        let prim = self.primitives[batch.primitive as usize];
        if tile.membership.current() != Some(prim.half) {
            self.flush(tile);
        }
        tile.membership.count(batch, prim, self.zpass);
    }
}

/// One pixel's results.
#[derive(Debug, Clone, Copy, Default)]
struct PixelResult {
    vcoef: f32,
    radiance: Vec3,
    max_dc: f32,
    mean_dc: f32,
    edges: f32,
}

/// Per-worker buffers of the counter pass.
#[derive(Default)]
struct Scratch {
    samples: Vec<LightSample>,
    chart: ChartSamples,
    /// The opaque group's counters `D`.
    counters: Vec<i32>,
    /// One semi-opaque group's layer counts (reused per group).
    layers: Vec<i32>,
    /// Per sample: accumulated optical depth (or summed opacity) of the
    /// semi-opaque groups; empty when the scene has none.
    attenuation: Vec<f64>,
    /// Per sample: transmittance from `attenuation`.
    transmittance: Vec<f64>,
    /// Sample positions laid out for the S-triangle look-ups.
    positions: SamplePositions,
    /// One S-triangle's opacity per sample.
    opacities: Vec<f32>,
    /// Per recorded edge of the group being counted: the centre's side of
    /// the plane through the receiver and the edge.
    sides: Vec<i8>,
    visibility: Vec<f32>,
}

/// One caster group's state for a light: its candidate edges, its
/// shadow-volume start `D(O)` (or layer count at the centre) per pixel,
/// and where its edges sit in the light's global edge numbering.
struct GroupPass {
    /// What one layer adds to the per-sample accumulator.
    per_layer: f64,
    candidates: CandidateEdges,
    start: Vec<i32>,
    /// Global id of the group's first edge (ids are contiguous).
    first_edge: u32,
}

impl GroupPass {
    fn end_edge(&self) -> u32 {
        self.first_edge + self.candidates.edges.len() as u32
    }
}

/// Everything the counter pass of one light reads.
struct LightPass<'a, 'c> {
    ctx: &'a ShadowContext<'c>,
    technique: &'a DepthComplexitySampling,
    bound: LightBound,
    centre: DVec3,
    sampler: LightSampler,
    pattern: PatternSampler,
    prepared: PreparedLight<'a>,
    /// The opaque group first, then one group per semi-opaque opacity.
    groups: &'a [GroupPass],
    /// Bit-field tables (one per interleaved set) when the option is on.
    tables: &'a [CoverageTables],
    /// The scene's S-triangles, when it has any.
    s_triangles: Option<&'a STriangles>,
    /// Per pixel: the start counts were recounted at the shadow-ray
    /// origin (a depth tie), so no quad correction applies.
    exact_start: &'a [bool],
    /// `EPS_SCENE ×` the scene's diagonal.
    eps_scene: f64,
    /// Called with every surface pixel's samples and counters.
    inspect: Option<&'a CounterInspector<'a>>,
}

/// One receiver's per-sample state, as [`CounterInspector`]s see it.
#[derive(Debug, Clone, Copy)]
pub struct InspectedPixel<'a> {
    /// The light samples.
    pub samples: &'a [LightSample],
    /// The opaque depth complexity `D` per sample.
    pub counters: &'a [i32],
    /// The semi-opaque casters' transmittance per sample (empty when the
    /// scene has no semi-opaque caster).
    pub transmittance: &'a [f64],
}

/// A visitor of per-pixel state: `(pixel index, state)`.
pub type CounterInspector<'a> = dyn Fn(usize, &InspectedPixel) + Sync + 'a;

impl LightPass<'_, '_> {
    /// Transmittance of the semi-opaque groups at pixel `i` when every
    /// sample sees their start counts (no wedge of theirs holds `i`).
    fn constant_transmittance(&self, i: usize) -> f64 {
        let acc: f64 = self.groups[1..]
            .iter()
            .map(|g| f64::from(g.start[i].max(0)) * g.per_layer)
            .sum();
        self.technique.transmittance.transmittance(acc)
    }

    /// The results of global pixel `i` with its recorded `(edge, outer)`
    /// pairs (sorted, no duplicates) and the unbounded edges `extra`
    /// (sorted) that apply to it; edge ids are global over the groups.
    fn pixel(
        &self,
        i: usize,
        tags: &[u64],
        extra: &[u32],
        s_triangles: &[u32],
        scratch: &mut Scratch,
    ) -> PixelResult {
        let gbuffer = self.ctx.gbuffer;
        let d0 = self.groups[0].start[i];
        let g = gbuffer.sample(i);
        let eye = self.ctx.view.eye.as_vec3();
        let direct = self.technique.mode == DcsMode::Direct;
        let sp = || surface_point(self.ctx.scene, &g, eye);
        if tags.is_empty() && extra.is_empty() && s_triangles.is_empty() && self.inspect.is_none() {
            // Outside every wedge: D = D(O) and the layer counts are the
            // start counts for every sample.
            let t = if d0 <= 0 {
                self.constant_transmittance(i)
            } else {
                0.0
            };
            let needs_radiance = direct || self.prepared.is_textured();
            return PixelResult {
                vcoef: t as f32,
                radiance: if needs_radiance && t > 0.0 {
                    self.prepared.unshadowed_direct(&sp()) * t as f32
                } else {
                    Vec3::ZERO
                },
                max_dc: d0.max(0) as f32,
                mean_dc: d0.max(0) as f32,
                edges: 0.0,
            };
        }
        let width = gbuffer.width as usize;
        let pixel = ((i % width) as u32, (i / width) as u32);
        // Rect lights: the chart is the light's own `(2s − 1, 1 − 2t)`,
        // straight from the unit points; the world points are made only
        // when something reads them (the direct estimator, the texture,
        // an inspector). Sphere lights chart the world points.
        let rect = matches!(self.bound, LightBound::Rect(_));
        if !rect
            || direct
            || self.prepared.is_textured()
            || self.inspect.is_some()
            || !s_triangles.is_empty()
        {
            self.sampler
                .samples_with(&self.pattern, g.position, pixel, &mut scratch.samples);
        } else {
            scratch.samples.clear();
        }
        // The reference's shadow-ray origin (`p + ε n_g`, in f32 as it
        // rounds it): receivers on an occluder's own surface then see its
        // edges from the same side of its faces as the reference's rays.
        let eps = self
            .eps_scene
            .max(EPS_POSITION * f64::from(g.position.abs().max_element()));
        let p = (g.position.as_dvec3() + g.geo_normal.as_dvec3() * eps)
            .as_vec3()
            .as_dvec3();
        let chart = match ReceiverChart::new(&self.bound, p) {
            Some(c) if rect || !scratch.samples.is_empty() => c,
            // Inside a sphere light: no defined Vcoef (as the reference).
            _ => {
                return PixelResult {
                    vcoef: 1.0,
                    edges: tags.len() as f32,
                    ..PixelResult::default()
                }
            }
        };
        if rect {
            scratch.chart.clear();
            self.pattern
                .pixel_points(pixel)
                .for_each(self.pattern.len(), |(s, t)| {
                    scratch.chart.push([2.0 * s - 1.0, 1.0 - 2.0 * t])
                });
            scratch.chart.finish();
        } else {
            scratch
                .chart
                .set(scratch.samples.iter().map(|s| chart.point(s.x.as_dvec3())));
        }
        let count = scratch.chart.len();
        let semi_opaque = self.groups.len() > 1 || !s_triangles.is_empty();
        scratch.attenuation.clear();
        if semi_opaque {
            scratch.attenuation.resize(count, 0.0);
        }
        // Tags and extras are sorted by global edge id, and each group's
        // ids are contiguous: split them group by group.
        let (mut ti, mut xi) = (0, 0);
        for (k, group) in self.groups.iter().enumerate() {
            let end = group.end_edge();
            let t_end = ti + tags[ti..].partition_point(|&t| ((t >> 1) as u32) < end);
            let x_end = xi + extra[xi..].partition_point(|&e| e < end);
            let (group_tags, group_extra) = (&tags[ti..t_end], &extra[xi..x_end]);
            (ti, xi) = (t_end, x_end);
            if k == 0 {
                self.count_group(group, i, p, &chart, group_tags, group_extra, scratch, false);
                continue;
            }
            if group_tags.is_empty() && group_extra.is_empty() {
                let layers = group.start[i];
                if layers > 0 {
                    let add = f64::from(layers) * group.per_layer;
                    scratch.attenuation.iter_mut().for_each(|a| *a += add);
                }
                continue;
            }
            self.count_group(group, i, p, &chart, group_tags, group_extra, scratch, true);
            let Scratch {
                layers,
                attenuation,
                ..
            } = scratch;
            for (a, &n) in attenuation.iter_mut().zip(&layers[..count]) {
                // Counts are exact; a negative one is a tie at an edge
                // and means no layer.
                if n > 0 {
                    *a += f64::from(n) * group.per_layer;
                }
            }
        }
        let mode = self.technique.transmittance;
        if let (Some(stris), false) = (self.s_triangles, s_triangles.is_empty()) {
            // Soft textured shadow volumes (§5.2): per sample, the
            // opacity of each S-triangle the receiver's volume test
            // passed; a fully opaque texel is one more occluder in `D`, a
            // partial one a layer of transmittance.
            let Scratch {
                samples,
                positions,
                opacities,
                counters,
                attenuation,
                ..
            } = scratch;
            positions.set(samples);
            opacities.resize(count, 0.0);
            let origin = p.as_vec3();
            for &s in s_triangles {
                stris.sample_opacities_in(
                    self.ctx.scene,
                    s as usize,
                    origin,
                    positions,
                    self.technique.opacity_filter,
                    opacities,
                );
                for (k, &a) in opacities.iter().enumerate() {
                    if a >= 1.0 {
                        counters[k] += 1;
                    } else if a > 0.0 {
                        attenuation[k] += mode.per_layer(Attenuation::partial(f64::from(a)));
                    }
                }
            }
        }
        scratch.transmittance.clear();
        scratch
            .transmittance
            .extend(scratch.attenuation.iter().map(|&a| mode.transmittance(a)));
        let counters = &scratch.counters[..count];
        if let Some(inspect) = self.inspect {
            inspect(
                i,
                &InspectedPixel {
                    samples: &scratch.samples,
                    counters,
                    transmittance: &scratch.transmittance,
                },
            );
        }
        scratch.visibility.clear();
        scratch
            .visibility
            .extend(counters.iter().map(|&c| if c <= 0 { 1.0 } else { 0.0 }));
        if semi_opaque {
            for (v, &t) in scratch.visibility.iter_mut().zip(&scratch.transmittance) {
                *v *= t as f32;
            }
        }
        let visible: f32 = scratch.visibility.iter().sum();
        let radiance = if direct {
            self.prepared
                .direct_from_samples(&sp(), &scratch.samples, &scratch.visibility)
        } else if self.prepared.is_textured() {
            // Eq. 4.2: each sample's visibility weighted by its emitted
            // radiance, per channel, normalised so that a fully visible
            // light gives the unshadowed light exactly.
            let (mut seen, mut all) = (Vec3::ZERO, Vec3::ZERO);
            for (s, &v) in scratch.samples.iter().zip(&scratch.visibility) {
                let le = self.prepared.sample_radiance(s);
                seen += le * v;
                all += le;
            }
            let plain = visible / count as f32;
            let weighted = Vec3::select(all.cmpgt(Vec3::ZERO), seen / all, Vec3::splat(plain));
            self.prepared.unshadowed_direct(&sp()) * weighted
        } else {
            Vec3::ZERO
        };
        let max_dc = counters.iter().copied().max().unwrap_or(0).max(0);
        let sum_dc: i64 = counters.iter().map(|&c| i64::from(c.max(0))).sum();
        PixelResult {
            vcoef: visible / count as f32,
            radiance,
            max_dc: max_dc as f32,
            mean_dc: (sum_dc as f64 / count as f64) as f32,
            edges: tags.len() as f32,
        }
    }

    /// Counts one group at receiver `p'` (`p`) of pixel `i` into
    /// `scratch.counters` (opaque) or `scratch.layers` (semi-opaque):
    /// the start count, moved across the quads that pass between the
    /// raster's receiver and `p'`, plus every edge's signed change over
    /// the samples it covers.
    #[allow(clippy::too_many_arguments)]
    fn count_group(
        &self,
        group: &GroupPass,
        i: usize,
        p: DVec3,
        chart: &ReceiverChart,
        tags: &[u64],
        extra: &[u32],
        scratch: &mut Scratch,
        layers: bool,
    ) {
        let edges = &group.candidates.edges;
        let local = |global: u32| (global - group.first_edge) as usize;
        // The stencil decided `D(O)` at the raster's receiver `p`; the
        // counters follow the shadow-ray origin `p'`. Where a quad's
        // plane passes between them (a receiver on the occluder, at its
        // terminator) move the constant across that quad: +m entering the
        // volume, −m leaving it.
        // Each tag's side is computed once, here, and reused below.
        let mut d0 = group.start[i];
        scratch.sides.clear();
        for &t in tags {
            let e = &edges[local((t >> 1) as u32)];
            let geometric = side_of(p, e.v0, e.v1, self.centre);
            scratch.sides.push(geometric as i8);
            if e.quad_sign == 0 || self.exact_start[i] {
                continue;
            }
            let outer = t & 1 == 1;
            let raster = i32::from(e.quad_sign) * if outer { 1 } else { -1 };
            if geometric != 0 && geometric != raster {
                let m = e.quad_weight as i32;
                d0 += if outer { m } else { -m };
            }
        }
        let Scratch {
            chart: samples,
            counters,
            layers: layer_counts,
            sides,
            ..
        } = scratch;
        let counters = if layers { layer_counts } else { counters };
        let table = match self.tables {
            [] => None,
            [one] => Some(one),
            many => {
                let width = self.ctx.gbuffer.width as usize;
                let pixel = ((i % width) as u32, (i / width) as u32);
                let set = self.pattern.interleaved_set(pixel).unwrap_or(0) as usize;
                many.get(set)
            }
        };
        counters.clear();
        counters.resize(samples.padded(), d0);
        let from_wedges = tags
            .iter()
            .zip(sides.iter())
            .map(|(&t, &side)| ((t >> 1) as u32, Some(side)));
        for (id, side) in from_wedges.chain(extra.iter().map(|&id| (id, None))) {
            let e = &edges[local(id)];
            let side = match side {
                Some(side) => i32::from(side),
                None => side_of(p, e.v0, e.v1, self.centre),
            };
            if side == 0 {
                continue;
            }
            // Whole-light silhouettes: the exact change (see `edges`).
            // Centre silhouettes: the thesis's rule, ±m by the half the
            // receiver is in (outer adds), whether or not the edge is a
            // silhouette from p — the exact rule would drop those edges
            // and miss the ones that are silhouettes from p only, which
            // on tessellated curved occluders leaves almost hard shadows.
            let mu = match self.technique.silhouettes {
                SilhouetteMode::WholeLight => group.candidates.multiplicity_from(e, p),
                SilhouetteMode::Centre if e.quad_sign != 0 => {
                    e.quad_weight as i32 * i32::from(e.quad_sign)
                }
                SilhouetteMode::Centre => group.candidates.multiplicity_from(e, p),
            };
            if mu == 0 {
                continue;
            }
            let Some((a, b)) = chart.edge(e.v0, e.v1) else {
                continue;
            };
            if let Some(oriented) = OrientedEdge::new(a, b) {
                match table {
                    Some(t) => t.add_covered(counters, &oriented, side * mu),
                    None => add_covered(counters, samples, &oriented, side * mu),
                }
            }
        }
    }
}

/// The screen rectangle `[x0, y0, x1, y1)` (pixels) holding every
/// receiver from which edge `e` can be seen overlapping the light: such a
/// receiver lies on a ray from a light point `x` through the edge, beyond
/// it, i.e. in `conv({v0, v1}) + cone{v_i − x_j}` over the light's
/// bounding corners `x_j` — a convex set whose image is the hull of its
/// projected vertices (finite ones and vanishing points), when all are in
/// front of the eye; otherwise the whole screen. Used for the few edges
/// whose line pierces the light, where no bounded wedge exists.
fn fallback_rect(
    view: &crate::view::View,
    e: &edges::CandidateEdge,
    light: &LightBound,
) -> [usize; 4] {
    let whole = [0, 0, view.width as usize, view.height as usize];
    let corners = light_corners(light);
    let mut clip = vec![
        view.clip_point(e.v0.as_vec3()),
        view.clip_point(e.v1.as_vec3()),
    ];
    for q in [e.v0, e.v1] {
        for x in &corners {
            clip.push(view.clip_direction((q - *x).as_vec3()));
        }
    }
    let (w, h) = (f64::from(view.width), f64::from(view.height));
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for c in clip {
        if !(c.w > 1e-6 * c.truncate().length()) {
            return whole;
        }
        let iw = 1.0 / f64::from(c.w);
        let sx = (f64::from(c.x) * iw * 0.5 + 0.5) * w;
        let sy = (0.5 - f64::from(c.y) * iw * 0.5) * h;
        b = [b[0].min(sx), b[1].min(sy), b[2].max(sx), b[3].max(sy)];
    }
    // One pixel of slack covers the f32 clip coordinates' rounding.
    let lo = |v: f64, max: f64| (v - 1.0).floor().clamp(0.0, max) as usize;
    let hi = |v: f64, max: f64| (v + 2.0).floor().clamp(0.0, max) as usize;
    [lo(b[0], w), lo(b[1], h), hi(b[2], w), hi(b[3], h)]
}

/// Corners of a convex polytope holding the light: the rect's own, or a
/// sphere's bounding cube.
fn light_corners(light: &LightBound) -> Vec<DVec3> {
    match light {
        LightBound::Rect(frame) => frame.corners().to_vec(),
        LightBound::Sphere { center, radius } => (0..8)
            .map(|k| {
                let s = |b: usize| if k >> b & 1 == 1 { *radius } else { -*radius };
                *center + DVec3::new(s(0), s(1), s(2))
            })
            .collect(),
    }
}

/// An edge with no bounded wedge: its global id, the screen rectangle
/// `[x0, y0, x1, y1)` and the world-space half-spaces holding every
/// receiver it can affect.
struct UnboundedEdge {
    id: u32,
    rect: [usize; 4],
    region: RegionBound,
}

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

/// Per-light buffers for `--explain`.
#[derive(Debug, Clone, Default)]
pub struct DcsLightReport {
    /// Candidate edges (wedges requested), over all caster groups.
    pub candidate_edges: usize,
    /// Semi-opaque caster groups (one per distinct opacity).
    pub semi_opaque_groups: usize,
    /// Edges with no bounded wedge (applied to every receiver).
    pub unbounded_edges: usize,
    /// Half-wedge triangles drawn.
    pub wedge_triangles: usize,
    /// (pixel, edge) pairs recorded.
    pub pairs: usize,
    /// (pixel, edge) pairs from edges without a bounded wedge.
    pub unbounded_pairs: usize,
    /// Receivers that needed per-sample counters.
    pub sampled_pixels: usize,
}

impl DepthComplexitySampling {
    /// The bit-field tables of light `k` (none with the exact test): one
    /// per sample set, built from the chart of a pixel that uses it.
    fn coverage_tables(
        &self,
        ctx: &ShadowContext,
        k: usize,
        bound: &LightBound,
    ) -> Result<Vec<CoverageTables>> {
        if self.coverage == CoverageTest::Exact {
            return Ok(Vec::new());
        }
        let light = &ctx.scene.lights[k];
        let bad = |e: String| crate::error::Error::param("--coverage", e);
        let sets = CoverageTables::applicable(self.pattern, &light.shape).map_err(bad)?;
        let sampler = LightSampler::new(light);
        let pattern = PatternSampler::new(self.pattern, self.samples, self.seed, k);
        let n = match self.pattern {
            SamplePattern::Interleaved { n } => n.max(1),
            _ => 1,
        };
        let mut samples = Vec::new();
        let mut chart = ChartSamples::default();
        (0..sets)
            .map(|set| {
                let pixel = (set % n, set / n);
                // Rect lights: the chart does not depend on the receiver.
                let p = DVec3::ZERO;
                sampler.samples_with(&pattern, p.as_vec3(), pixel, &mut samples);
                let frame = ReceiverChart::new(bound, p).ok_or_else(|| bad("no chart".into()))?;
                chart.set(samples.iter().map(|s| frame.point(s.x.as_dvec3())));
                CoverageTables::from_chart(&chart, TableResolution::default()).map_err(bad)
            })
            .collect()
    }

    /// Runs light `k`: its term, AOV channels and report.
    fn light(
        &self,
        ctx: &ShadowContext,
        k: usize,
        casters: &SceneCasters,
        passes: &mut Vec<PassTiming>,
        inspect: Option<&CounterInspector>,
    ) -> Result<(LightTerm, [Vec<f32>; 3], DcsLightReport)> {
        let light = &ctx.scene.lights[k];
        let LightStart {
            adj,
            bound,
            point,
            counts: start,
            mut framebuffer,
            volume,
        } = light_start(ctx, k, passes)?;

        // Semi-opaque casters: one group per opacity, each with its own
        // shadow-volume start counts (the stencil pass reuses the depth).
        let t = Instant::now();
        let mut group_adjs = vec![(Attenuation::Opaque, adj, start)];
        let mut volumes = vec![volume];
        for (attenuation, adj) in casters.partial {
            let volume = build_volume(adj, ctx.view, point);
            let counts = stencil_counts(&mut framebuffer, &volume, false)?;
            group_adjs.push((*attenuation, adj, counts));
            volumes.push(volume);
        }
        if group_adjs.len() > 1 {
            passes.push(PassTiming {
                name: format!("semi-opaque shadow volumes light {k}"),
                time: t.elapsed(),
            });
        }

        // Depth ties of the start counts (`ties`): recounted exactly at
        // the shadow-ray origin by one ray to the centre. Only in the
        // exact mode (whole-light silhouettes), where per-sample counts
        // are meant to equal ray casting; the fast centre mode keeps the
        // thesis's approximations and the stencil's constant.
        let t = Instant::now();
        let mut tied = vec![false; ctx.gbuffer.len()];
        if self.silhouettes == SilhouetteMode::WholeLight {
            for ((_, _, counts), volume) in group_adjs.iter().zip(&volumes) {
                for (a, b) in tied
                    .iter_mut()
                    .zip(tied_pixels(ctx.depth, volume, counts, true)?)
                {
                    *a |= b;
                }
            }
        }
        let mut exact_start = vec![false; tied.len()];
        let tied_surface: Vec<usize> = (0..tied.len())
            .filter(|&i| tied[i] && ctx.gbuffer.is_surface(i))
            .collect();
        if !tied_surface.is_empty() {
            let lits: Vec<Vec<bool>> = group_adjs
                .iter()
                .map(|(_, adj, _)| faces_point(adj, point))
                .collect();
            let sets: Vec<(&crate::geom::EdgeAdjacency, &[bool])> = group_adjs
                .iter()
                .zip(&lits)
                .map(|((_, adj, _), lit)| (&**adj, lit.as_slice()))
                .collect();
            let exact = ExactStart::new(ctx.geometry, &sets);
            let origin = ShadowOrigin::new(ctx.scene, ctx.geometry);
            let n_groups = group_adjs.len();
            let fixes: Vec<(usize, Vec<i32>)> = tied_surface
                .par_iter()
                .map(|&i| {
                    let g = ctx.gbuffer.sample(i);
                    let mut counts = vec![0; n_groups];
                    exact.counts(origin.of(g.position, g.geo_normal), point, &mut counts);
                    (i, counts)
                })
                .collect();
            for (i, counts) in fixes {
                for (group, c) in group_adjs.iter_mut().zip(counts) {
                    group.2[i] = c;
                }
                exact_start[i] = true;
            }
        }
        passes.push(PassTiming {
            name: format!(
                "start-count ties light {k} ({} receivers)",
                tied_surface.len()
            ),
            time: t.elapsed(),
        });

        let t = Instant::now();
        let corners: Vec<Vec3>;
        let shape = match light.shape {
            LightShape::Rect { center, u, v, .. } => {
                corners = vec![
                    center - u - v,
                    center + u - v,
                    center + u + v,
                    center - u + v,
                ];
                LightShapeForSilhouettes::Polygon(&corners)
            }
            LightShape::Sphere { center, radius } => LightShapeForSilhouettes::Sphere {
                center: center.as_dvec3(),
                radius: f64::from(radius),
            },
        };
        let mut wedges = Wedges::default();
        let (mut zfail_edge, mut zpass_edge) = (Vec::new(), Vec::new());
        let mut always: Vec<UnboundedEdge> = Vec::new();
        let corners = light_corners(&bound);
        // Receivers' positions round at f32 and move by the shadow-ray
        // offset (≤ 1e-5 relative): a generous slack keeps the test
        // conservative.
        let slack = 1e-4 * scene_diagonal(ctx.scene, ctx.geometry);
        let mut groups = Vec::with_capacity(group_adjs.len());
        let mut next_edge = 0u32;
        for (attenuation, adj, start) in group_adjs {
            let lit = faces_point(&adj, point);
            let candidates = CandidateEdges::build(&adj, &lit, self.silhouettes, shape);
            let first_edge = next_edge;
            for e in &candidates.edges {
                let id = next_edge;
                next_edge += 1;
                // The quad as the stencil pass drew it, or (no quad) any
                // order.
                let (q0, q1) = if e.quad_sign < 0 {
                    (e.v1, e.v0)
                } else {
                    (e.v0, e.v1)
                };
                let quad = SilhouetteQuad {
                    q0: q0.as_vec3(),
                    q1: q1.as_vec3(),
                    weight: e.quad_weight,
                };
                // Edges that are no silhouette from the centre (whole-light
                // mode) matter only where they are silhouettes from the
                // receiver: a thin dihedral region inside their wedge. A
                // world-space test finds those receivers far more cheaply
                // than rasterizing a full wedge for each.
                let dihedral = (e.quad_sign == 0).then(|| candidates.dihedral(e)).flatten();
                if dihedral.is_some() || !wedges.add(ctx.view, &bound, point, quad, None) {
                    let mut region = RegionBound::new(e.v0, e.v1, &corners, slack);
                    if let Some(faces) = dihedral {
                        region = region.with_dihedral(faces, slack);
                    }
                    always.push(UnboundedEdge {
                        id,
                        rect: fallback_rect(ctx.view, e, &bound),
                        region,
                    });
                    continue;
                }
                zfail_edge.resize(wedges.zfail.halves.len(), id);
                zpass_edge.resize(wedges.zpass.halves.len(), id);
            }
            groups.push(GroupPass {
                per_layer: self.transmittance.per_layer(attenuation),
                candidates,
                start,
                first_edge,
            });
        }
        passes.push(PassTiming {
            name: format!("wedge build light {k}"),
            time: t.elapsed(),
        });

        let t = Instant::now();
        let grid: TileGrid = framebuffer.grid();
        let mut tiles: Vec<MembershipTile> = (0..grid.tile_count())
            .map(|_| MembershipTile::default())
            .collect();
        draw_wedges(
            &mut framebuffer,
            &mut tiles,
            &wedges,
            |set, zpass| MembershipStage {
                primitives: &set.primitives,
                halves: &set.halves,
                half_edge: if zpass { &zpass_edge } else { &zfail_edge },
                zpass,
            },
            |stage, t| stage.flush(t),
        )?;
        passes.push(PassTiming {
            name: format!("wedge membership light {k}"),
            time: t.elapsed(),
        });

        let tables = self.coverage_tables(ctx, k, &bound)?;
        // S-triangles: soft textured shadow volumes, only when the scene
        // has some.
        let s_triangles = casters.s_triangles;
        let stsv = if s_triangles.is_empty() {
            None
        } else {
            let t = Instant::now();
            let m = stsv_membership(ctx, k, s_triangles)?;
            passes.push(PassTiming {
                name: format!("soft textured shadow volumes light {k}"),
                time: t.elapsed(),
            });
            Some(m)
        };
        let t = Instant::now();
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
            s_triangles: (!s_triangles.is_empty()).then_some(s_triangles),
            exact_start: &exact_start,
            eps_scene: EPS_SCENE * scene_diagonal(ctx.scene, ctx.geometry),
            inspect,
        };
        let width = grid.width as usize;
        let height = grid.height as usize;
        let results: Vec<(Vec<PixelResult>, usize, usize, usize)> = tiles
            .par_iter_mut()
            .enumerate()
            .map_init(Scratch::default, |scratch, (tile, t)| {
                let (ox, oy) = grid.tile_origin(tile);
                let pairs = t.entries.len();
                let mut entries = std::mem::take(&mut t.entries);
                entries.sort_unstable();
                entries.dedup();
                let mut out = vec![PixelResult::default(); TILE_PIXELS];
                let mut sampled = 0;
                let mut unbounded = 0;
                let mut e = 0;
                let (tx1, ty1) = (ox as usize + TILE_SIZE, oy as usize + TILE_SIZE);
                let mut near: Vec<&UnboundedEdge> = always
                    .iter()
                    .filter(|u| {
                        let r = u.rect;
                        r[0] < tx1 && r[2] > ox as usize && r[1] < ty1 && r[3] > oy as usize
                    })
                    .collect();
                // Receivers' bounding boxes, tile, then 16² and 4² blocks,
                // against each edge's world-space region: per pixel only
                // the edges of its 4² block are tested.
                let bbox = |x0: usize, y0: usize, size: usize| {
                    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
                    for y in y0..(y0 + size).min(height) {
                        for x in x0..(x0 + size).min(width) {
                            let i = y * width + x;
                            if ctx.gbuffer.is_surface(i) {
                                let q = ctx.gbuffer.sample(i).position.as_dvec3();
                                (lo, hi) = (lo.min(q), hi.max(q));
                            }
                        }
                    }
                    (lo.x <= hi.x).then_some((lo, hi))
                };
                let keeps =
                    |u: &UnboundedEdge, x0: usize, y0: usize, size: usize, b: (DVec3, DVec3)| {
                        let r = u.rect;
                        r[0] < x0 + size
                            && r[2] > x0
                            && r[1] < y0 + size
                            && r[3] > y0
                            && !u.region.excludes_box(b.0, b.1)
                    };
                const OUTER: usize = 16;
                const INNER: usize = 4;
                const PER_ROW: usize = TILE_SIZE / INNER;
                let mut block_edges: Vec<Vec<u32>> = vec![Vec::new(); PER_ROW * PER_ROW];
                if !near.is_empty() {
                    match bbox(ox as usize, oy as usize, TILE_SIZE) {
                        Some(b) => near.retain(|u| !u.region.excludes_box(b.0, b.1)),
                        None => near.clear(),
                    }
                }
                if !near.is_empty() {
                    for by in 0..TILE_SIZE / OUTER {
                        for bx in 0..TILE_SIZE / OUTER {
                            let (x0, y0) = (ox as usize + bx * OUTER, oy as usize + by * OUTER);
                            let Some(b) = bbox(x0, y0, OUTER) else {
                                continue;
                            };
                            let outer: Vec<u32> = (0..near.len() as u32)
                                .filter(|&k| keeps(near[k as usize], x0, y0, OUTER, b))
                                .collect();
                            if outer.is_empty() {
                                continue;
                            }
                            for sy in 0..OUTER / INNER {
                                for sx in 0..OUTER / INNER {
                                    let (x1, y1) = (x0 + sx * INNER, y0 + sy * INNER);
                                    let Some(b) = bbox(x1, y1, INNER) else {
                                        continue;
                                    };
                                    let cell = (y1 - oy as usize) / INNER * PER_ROW
                                        + (x1 - ox as usize) / INNER;
                                    block_edges[cell] = outer
                                        .iter()
                                        .copied()
                                        .filter(|&k| keeps(near[k as usize], x1, y1, INNER, b))
                                        .collect();
                                }
                            }
                        }
                    }
                }
                let mut extra = Vec::new();
                let stsv_entries: &[u64] = stsv.as_ref().map_or(&[], |m| &m.tiles[tile]);
                let (mut si, mut here) = (0, Vec::new());
                for (local, r) in out.iter_mut().enumerate() {
                    let (x, y) = (
                        ox as usize + local % TILE_SIZE,
                        oy as usize + local / TILE_SIZE,
                    );
                    here.clear();
                    while si < stsv_entries.len() && (stsv_entries[si] >> 32) as usize == local {
                        here.push(stsv_entries[si] as u32);
                        si += 1;
                    }
                    let first = e;
                    while e < entries.len() && (entries[e] >> 33) as usize == local {
                        e += 1;
                    }
                    if x >= width || y >= height {
                        continue;
                    }
                    let i = y * width + x;
                    if !ctx.gbuffer.is_surface(i) {
                        continue;
                    }
                    let tags = &mut entries[first..e];
                    for tag in tags.iter_mut() {
                        *tag &= (1 << 33) - 1;
                    }
                    extra.clear();
                    let cell = (local / TILE_SIZE) / INNER * PER_ROW + (local % TILE_SIZE) / INNER;
                    if !block_edges[cell].is_empty() {
                        let q = ctx.gbuffer.sample(i).position.as_dvec3();
                        extra.extend(
                            block_edges[cell]
                                .iter()
                                .map(|&k| near[k as usize])
                                .filter(|u| {
                                    let r = u.rect;
                                    x >= r[0]
                                        && x < r[2]
                                        && y >= r[1]
                                        && y < r[3]
                                        && !u.region.excludes_point(q)
                                })
                                .map(|u| u.id),
                        );
                    }
                    sampled +=
                        usize::from(!tags.is_empty() || !extra.is_empty() || !here.is_empty());
                    unbounded += extra.len();
                    *r = pass.pixel(i, tags, &extra, &here, scratch);
                }
                (out, pairs, sampled, unbounded)
            })
            .collect();
        passes.push(PassTiming {
            name: format!("counters light {k}"),
            time: t.elapsed(),
        });

        let n = width * height;
        let mut vcoef = vec![0.0f32; n];
        let with_radiance = self.mode == DcsMode::Direct || pass.prepared.is_textured();
        let mut radiance = vec![Vec3::ZERO; if with_radiance { n } else { 0 }];
        let mut aovs = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
        let mut report = DcsLightReport {
            candidate_edges: groups.iter().map(|g| g.candidates.edges.len()).sum(),
            semi_opaque_groups: groups.len() - 1,
            unbounded_edges: always.len(),
            wedge_triangles: wedges.zfail.triangles.len() + wedges.zpass.triangles.len(),
            ..DcsLightReport::default()
        };
        for (tile, (out, pairs, sampled, unbounded)) in results.into_iter().enumerate() {
            report.unbounded_pairs += unbounded;
            report.pairs += pairs;
            report.sampled_pixels += sampled;
            let (ox, oy) = grid.tile_origin(tile);
            for (local, r) in out.into_iter().enumerate() {
                let (x, y) = (
                    ox as usize + local % TILE_SIZE,
                    oy as usize + local / TILE_SIZE,
                );
                if x >= width || y >= height {
                    continue;
                }
                let i = y * width + x;
                vcoef[i] = r.vcoef;
                if let Some(d) = radiance.get_mut(i) {
                    *d = r.radiance;
                }
                aovs[0][i] = r.max_dc;
                aovs[1][i] = r.mean_dc;
                aovs[2][i] = r.edges;
            }
        }
        if let SamplePattern::Interleaved { n: tile } = self.pattern {
            // Interleaved sampling: neighbours used different sample sets;
            // gather them back, not across depth or normal discontinuities.
            let t = Instant::now();
            let guide = |i: usize| {
                let g = ctx.gbuffer.sample(i);
                g.is_surface().then_some((g.depth, g.normal))
            };
            let params = GatherParams::default();
            let (w, h) = (grid.width, grid.height);
            vcoef = gather_filter(&vcoef, w, h, tile, &guide, params);
            if !radiance.is_empty() {
                radiance = gather_filter(&radiance, w, h, tile, &guide, params);
            }
            passes.push(PassTiming {
                name: format!("gather light {k}"),
                time: t.elapsed(),
            });
        }
        let term = if with_radiance {
            LightTerm::Radiance { radiance, vcoef }
        } else {
            LightTerm::Vcoef(vcoef)
        };
        Ok((term, aovs, report))
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
            bytes: workers * (n * std::mem::size_of::<LightSample>() as u64 + padded * 8 + n * 4),
        });
        let casters = SceneCasters::new(ctx);
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
        for k in 0..ctx.scene.lights.len() {
            let (term, aovs, report) = self.light(ctx, k, &casters, &mut out.passes, None)?;
            out.buffers.push(BufferNote {
                name: format!("wedge membership light {k}"),
                detail: format!(
                    "{} candidate edges in {} caster group(s) ({} silhouettes, {} without a \
                     bounded wedge), {} wedge triangles; (pixel, edge) pairs as u64, {} \
                     receivers sampled, {} outside every wedge with no per-sample work; {} \
                     (pixel, unbounded edge) pairs",
                    report.candidate_edges,
                    1 + report.semi_opaque_groups,
                    self.silhouettes.name(),
                    report.unbounded_edges,
                    report.wedge_triangles,
                    report.sampled_pixels,
                    pixels as usize - report.sampled_pixels,
                    report.unbounded_pairs,
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
        Ok(self.light(ctx, k, &casters, &mut passes, Some(inspect))?.0)
    }
}

impl ShadowTechnique for DepthComplexitySampling {
    fn name(&self) -> &'static str {
        "dcs"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        Ok(self.compute_with_report(ctx)?.0)
    }
}
