//! One receiver's depth complexity: its counters `D` per light sample,
//! set to the start count `D(O)` and moved by every recorded edge's signed
//! change over the samples it covers ([`counters`](super::counters)), its
//! semi-opaque groups' layer counts and S-triangles' opacities turned
//! into transmittance, and from them its Vcoef or direct light.

use super::bitfield::CoverageTables;
use super::block_extras::{BlockExtras, MadeExtras, BLOCK};
use super::blocks::{BlockCounts, BlockGrid, BlockSamples};
use super::chart::ReceiverChart;
use super::chart_lanes::{chart_rows, chart_rows_apply};
use super::counters::{add_covered, ChartSamples, OrientedEdge, SectorSamples, LANES};
use super::edge_lanes::{self, EdgeSource, GroupInputs, GROUPS};
use super::edges::{side_of, CandidateEdge, CandidateEdges};
use super::options::{DcsMode, SilhouetteMode};
use super::settings::DepthComplexitySampling;
use super::ties::{ExactStart, Tie};
use crate::sampling::{LightSampler, PatternSampler};
use crate::shade::{surface_point, LightSample, PreparedLight, SurfacePoint};
use crate::shadow::kit::groups::Attenuation;
use crate::shadow::kit::light_frame::RectProjection;
use crate::shadow::kit::rays::ShadowOrigin;
use crate::shadow::kit::stsv::{STriangles, SamplePositions};
use crate::shadow::kit::wedge_geometry::LightBound;
use crate::shadow::ShadowContext;
use glam::{DVec3, Vec3};

/// Effective edges from which a receiver's samples are sorted into
/// sectors ([`SectorSamples`]): below it the sort costs more than the
/// tests it saves (counter pass at 1024², 64 and 256 samples: neutral on
/// `spheres.toml`, −17 % on `bunny.toml` at 256; a threshold of 8 cost
/// spheres 13–20 %).
const SECTOR_MIN: usize = 32;

/// One pixel's results.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct PixelResult {
    pub(super) vcoef: f32,
    pub(super) radiance: Vec3,
    pub(super) max_dc: f32,
    pub(super) mean_dc: f32,
    /// Edges that change `D` over part of the light (the AOV).
    pub(super) edges: f32,
    /// Whether a quad's plane between the raster's receiver and the
    /// shadow-ray origin had its start count recounted by a ray.
    pub(super) recounted: bool,
}

impl PixelResult {
    /// The results of a receiver whose only per-sample reads are its `n`
    /// samples' opaque counts `c` (no radiance).
    fn from_counts(c: BlockCounts, n: usize, edges: f32, recounted: bool) -> PixelResult {
        PixelResult {
            vcoef: c.visible as f32 / n as f32,
            radiance: Vec3::ZERO,
            max_dc: c.max as f32,
            mean_dc: (c.sum as f64 / n as f64) as f32,
            edges,
            recounted,
        }
    }
}

/// Per-worker buffers of the counter pass.
#[derive(Default)]
pub(super) struct Scratch {
    samples: Vec<LightSample>,
    chart: ChartSamples,
    /// The same samples sorted into angular sectors (opaque Vcoef only).
    sectors: SectorSamples,
    /// Only the samples some edge may cover, block by block (opaque
    /// Vcoef on the stratified grid only).
    blocks: BlockSamples,
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
    /// The receiver's effective edges, group after group: each projected
    /// edge that covers part of the light, with its signed change of `D`.
    effective: Vec<(OrientedEdge, i32)>,
    /// Per group: its start count at the shadow-ray origin and its run of
    /// `effective`.
    spans: Vec<GroupSpan>,
    visibility: Vec<f32>,
}

/// A receiver's unbounded edges: their ids, or what
/// [`LightPass::block_extras`] made of them.
#[derive(Debug, Clone, Copy)]
pub(super) enum Extras<'a> {
    /// Ids (sorted, global over the groups).
    Ids(&'a [u32]),
    /// The opaque group's, made for the receiver's block.
    Made(MadeExtras<'a>),
}

/// One group's edges at one receiver ([`LightPass::group_edges`]).
#[derive(Debug, Clone, Copy)]
struct GroupSpan {
    /// `D(O)` (or the layer count) at the shadow-ray origin.
    start: i32,
    /// Its edges in [`Scratch::effective`].
    first: usize,
    end: usize,
    /// Whether it had recorded edges at all (a group without keeps its
    /// start for every sample).
    recorded: bool,
}

/// What one receiver reads per sample ([`LightPass::reads`]).
#[derive(Debug, Clone, Copy)]
struct Reads {
    /// A rect light: the chart is its own coordinates.
    rect: bool,
    /// The direct light is estimated (not only the Vcoef).
    direct: bool,
    /// The light's radiance is textured.
    textured: bool,
    /// A [`CounterInspector`] reads the receiver.
    inspected: bool,
    /// Semi-opaque groups or S-triangles: a transmittance per sample.
    semi_opaque: bool,
    /// Anything but the opaque counts is read per sample.
    per_sample: bool,
    /// A rect light's world samples are read (the direct estimator, the
    /// texture, an inspector, the S-triangles).
    rect_samples: bool,
    /// The direct light of an untextured rect light straight from the
    /// chart points the counts use: no world points.
    chart_direct: bool,
}

/// One receiver as the stages of [`LightPass::pixel`] see it, once it
/// needs more than its start counts ([`LightPass::locate`]).
struct Receiver<'r> {
    /// Global pixel index.
    index: usize,
    /// The pixel, `(x, y)`.
    pixel: (u32, u32),
    /// The raster's receiver, where the light samples are made from.
    position: Vec3,
    /// The same in f64: where the stencil decided `D(O)`.
    raster: DVec3,
    /// The shadow-ray origin `p'`.
    origin: DVec3,
    chart: ReceiverChart,
    reads: Reads,
    inspect: Option<&'r CounterInspector<'r>>,
    /// The S-triangles whose volume test the receiver passed.
    s_triangles: &'r [u32],
}

/// How [`LightPass::count_groups`] moves a receiver's counters
/// ([`LightPass::counting`]).
struct Counting<'t> {
    /// The receiver's samples.
    count: usize,
    /// The bit-field table of its interleaved set, when the option is on.
    table: Option<&'t CoverageTables>,
    /// Whether its counters follow the sectors' order ([`SectorSamples`])
    /// rather than the samples'.
    sorted: bool,
}

/// One caster group's state for a light: its candidate edges, its
/// shadow-volume start `D(O)` (or layer count at the centre) per pixel,
/// and where its edges sit in the light's global edge numbering.
pub(super) struct GroupPass {
    /// What one layer adds to the per-sample accumulator.
    pub(super) per_layer: f64,
    pub(super) candidates: CandidateEdges,
    pub(super) start: Vec<i32>,
    /// Global id of the group's first edge (ids are contiguous).
    pub(super) first_edge: u32,
}

impl GroupPass {
    fn end_edge(&self) -> u32 {
        self.first_edge + self.candidates.edges.len() as u32
    }
}

/// Everything the counter pass of one light reads.
pub(super) struct LightPass<'a, 'c> {
    pub(super) ctx: &'a ShadowContext<'c>,
    pub(super) technique: &'a DepthComplexitySampling,
    pub(super) bound: LightBound,
    pub(super) centre: DVec3,
    pub(super) sampler: LightSampler,
    pub(super) pattern: PatternSampler,
    pub(super) prepared: PreparedLight<'a>,
    /// The opaque group first, then one group per semi-opaque opacity.
    pub(super) groups: &'a [GroupPass],
    /// Bit-field tables (one per interleaved set) when the option is on.
    pub(super) tables: &'a [CoverageTables],
    /// The sample grid's blocks, when the pattern is a square stratified
    /// grid ([`BlockGrid::new`]).
    pub(super) blocks: Option<BlockGrid>,
    /// The scene's S-triangles, when it has any.
    pub(super) s_triangles: Option<&'a STriangles>,
    /// Per pixel: the tie test's verdict on the start counts
    /// ([`Tie::Tied`]: recounted at the shadow-ray origin, so no quad
    /// correction applies).
    pub(super) ties: &'a [Tie],
    /// Exact start counts by a ray, for own-face ties at a quad.
    pub(super) exact: &'a ExactStart<'a>,
    /// The shadow-ray origin rule (the reference's).
    pub(super) origin: ShadowOrigin,
    /// Called with every surface pixel's samples and counters.
    pub(super) inspect: Option<&'a CounterInspector<'a>>,
    /// Only these pixels (sorted) are inspected, when given: the others
    /// keep their fast paths.
    pub(super) inspect_pixels: Option<&'a [usize]>,
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
        let accumulated: f64 = self.groups[1..]
            .iter()
            .map(|group| f64::from(group.start[i].max(0)) * group.per_layer)
            .sum();
        self.technique.transmittance.transmittance(accumulated)
    }

    /// The results of pixel `i` when every sample sees the opaque start
    /// count `opaque_start` and the semi-opaque groups' start counts
    /// (`shading_point` gives its surface point, read only for a
    /// radiance).
    fn uniform(
        &self,
        i: usize,
        opaque_start: i32,
        shading_point: impl Fn() -> SurfacePoint,
        edges: usize,
        recounted: bool,
    ) -> PixelResult {
        let transmittance = if opaque_start <= 0 {
            self.constant_transmittance(i)
        } else {
            0.0
        };
        let needs_radiance = self.technique.mode == DcsMode::Direct || self.prepared.is_textured();
        PixelResult {
            vcoef: transmittance as f32,
            radiance: if needs_radiance && transmittance > 0.0 {
                self.prepared.unshadowed_direct(&shading_point()) * transmittance as f32
            } else {
                Vec3::ZERO
            },
            max_dc: opaque_start.max(0) as f32,
            mean_dc: opaque_start.max(0) as f32,
            edges: edges as f32,
            recounted,
        }
    }

    /// The results of global pixel `i` with its recorded `(edge, outer)`
    /// pairs (sorted, no duplicates) and the unbounded edges `extra`
    /// (sorted) that apply to it; edge ids are global over the groups.
    ///
    /// In stages: the receivers outside every wedge at once (`uniform`);
    /// then the chart (`locate`), every group's start count and effective
    /// edges (`gather_edges`), the paths that need no per-sample counters
    /// (`without_samples`), the chart points (`fill_chart`), the counters
    /// (`count_groups`, `add_s_triangles`), the transmittance
    /// (`transmittance`) and the results (`resolve`).
    #[inline(always)]
    pub(super) fn pixel(
        &self,
        i: usize,
        tags: &[u64],
        extras: Extras,
        s_triangles: &[u32],
        scratch: &mut Scratch,
    ) -> PixelResult {
        let (extra, made): (&[u32], _) = match extras {
            Extras::Ids(ids) => (ids, None),
            Extras::Made(made) => (&[], Some(made)),
        };
        let admitted = made.map_or(extra.len(), |m| m.admitted);
        let inspect = self.inspect.filter(|_| {
            self.inspect_pixels
                .is_none_or(|p| p.binary_search(&i).is_ok())
        });
        if tags.is_empty() && admitted == 0 && s_triangles.is_empty() && inspect.is_none() {
            // Outside every wedge: D = D(O) and the layer counts are the
            // start counts for every sample.
            let opaque_start = self.groups[0].start[i];
            return self.uniform(i, opaque_start, || self.shading_point(i), 0, false);
        }
        let Some(receiver) = self.locate(i, inspect, s_triangles, &mut scratch.samples) else {
            // Inside a sphere light: no defined Vcoef (as the reference).
            return PixelResult {
                vcoef: 1.0,
                edges: tags.len() as f32,
                ..PixelResult::default()
            };
        };
        let recounted = self.gather_edges(&receiver, (tags, extra, made), scratch);
        if let Some(result) = self.without_samples(&receiver, recounted, scratch) {
            return result;
        }
        self.fill_chart(&receiver, scratch);
        // The shading point of the direct light from the chart points,
        // made once for the sectors' test and the estimate.
        let shading = receiver.reads.chart_direct.then(|| self.shading_point(i));
        let counting = self.counting(&receiver, shading.as_ref(), scratch);
        self.count_groups(&counting, receiver.reads.semi_opaque, scratch);
        self.add_s_triangles(&receiver, counting.count, scratch);
        self.transmittance(&receiver, counting.count, scratch);
        self.resolve(&receiver, &counting, shading, recounted, scratch)
    }

    /// Pixel `i`'s whole shading sample, read only where a radiance needs
    /// it.
    #[inline(always)]
    fn shading_point(&self, i: usize) -> SurfacePoint {
        let eye = self.ctx.view.eye.as_vec3();
        surface_point(self.ctx.scene, &self.ctx.gbuffer.sample(i), eye)
    }

    /// What a receiver reads per sample, given whether an inspector reads
    /// it and whether it has S-triangles.
    #[inline(always)]
    fn reads(&self, inspected: bool, has_s_triangles: bool) -> Reads {
        let rect = matches!(self.bound, LightBound::Rect(_));
        let direct = self.technique.mode == DcsMode::Direct;
        let textured = self.prepared.is_textured();
        let semi_opaque = self.groups.len() > 1 || has_s_triangles;
        Reads {
            rect,
            direct,
            textured,
            inspected,
            semi_opaque,
            per_sample: semi_opaque || direct || textured || inspected,
            rect_samples: direct || textured || inspected || has_s_triangles,
            chart_direct: rect && direct && !textured && !inspected && !has_s_triangles,
        }
    }

    /// [`LightPass::pixel`]'s first stage: the receiver of pixel `index`,
    /// its shadow-ray origin and chart, with a sphere light's samples
    /// made into `samples` (cleared); `None` inside a sphere light.
    #[inline(always)]
    fn locate<'r>(
        &self,
        index: usize,
        inspect: Option<&'r CounterInspector<'r>>,
        s_triangles: &'r [u32],
        samples: &mut Vec<LightSample>,
    ) -> Option<Receiver<'r>> {
        let gbuffer = self.ctx.gbuffer;
        // The position and geometric normal are read for every receiver;
        // the whole shading sample only where a radiance needs it.
        let (position, geo_normal) = position_normal(gbuffer, index);
        let width = gbuffer.width as usize;
        let pixel = ((index % width) as u32, (index / width) as u32);
        let reads = self.reads(inspect.is_some(), !s_triangles.is_empty());
        // Rect lights: the chart is the light's own `(2s − 1, 1 − 2t)`,
        // straight from the unit points; the world points are made only
        // when something reads them (the direct estimator, the texture,
        // an inspector), and only once the receiver is known to need
        // per-sample work. Sphere lights chart the world points.
        samples.clear();
        if !reads.rect {
            self.sampler
                .samples_with(&self.pattern, position, pixel, samples);
        }
        // The reference's shadow-ray origin (`p + ε n_g`, in f32 as it
        // rounds it): receivers on an occluder's own surface then see its
        // edges from the same side of its faces as the reference's rays.
        let origin = self.origin.of(position, geo_normal).as_dvec3();
        let chart = ReceiverChart::new(&self.bound, origin)
            .filter(|_| reads.rect || !samples.is_empty())?;
        Some(Receiver {
            index,
            pixel,
            position,
            raster: position.as_dvec3(),
            origin,
            chart,
            reads,
            inspect,
            s_triangles,
        })
    }

    /// [`LightPass::pixel`]'s second stage: every group's start count at
    /// the shadow-ray origin and its effective edges, into
    /// `scratch.spans` and `scratch.effective`; whether a ray recounted a
    /// start count. Done for every group first: a receiver none of whose
    /// recorded edges covers part of the light needs no per-sample work.
    #[inline(always)]
    fn gather_edges(
        &self,
        receiver: &Receiver,
        (tags, extra, made): (&[u64], &[u32], Option<MadeExtras>),
        scratch: &mut Scratch,
    ) -> bool {
        let (mut tags_at, mut extra_at) = (0, 0);
        let mut recounted = false;
        scratch.effective.clear();
        scratch.spans.clear();
        for (k, group) in self.groups.iter().enumerate() {
            let end = group.end_edge();
            let tags_end = tags_at + tags[tags_at..].partition_point(|&t| ((t >> 1) as u32) < end);
            let extra_end = extra_at + extra[extra_at..].partition_point(|&e| e < end);
            let (group_tags, group_extra) = (&tags[tags_at..tags_end], &extra[extra_at..extra_end]);
            (tags_at, extra_at) = (tags_end, extra_end);
            let first = scratch.effective.len();
            let recorded = k == 0 || !group_tags.is_empty() || !group_extra.is_empty();
            let start = if recorded {
                // The opaque group's unbounded edges, when made for the
                // whole block ([`LightPass::block_extras`]).
                let made = made.filter(|_| k == 0);
                let (start, recount) = self.group_edges(
                    k,
                    receiver.index,
                    (receiver.raster, receiver.origin),
                    &receiver.chart,
                    (group_tags, group_extra, made),
                    &mut scratch.effective,
                );
                recounted |= recount;
                start
            } else {
                group.start[receiver.index]
            };
            scratch.spans.push(GroupSpan {
                start,
                first,
                end: scratch.effective.len(),
                recorded,
            });
        }
        // A start count taken where a projected edge passes through the
        // light's centre is a tie between the stencil's (or the ray's)
        // rounding and the chart's: the chart puts the centre on one side
        // of the edge, the count may have taken the other, and half the
        // light would flip (dabrovic.toml at 768×512, pixel (94, 341)).
        // There the count is taken instead at a point of the chart clear
        // of every edge and carried back to the centre through the
        // chart's own test, so both sides agree by construction.
        for (k, span) in scratch.spans.iter_mut().enumerate() {
            let edges = &scratch.effective[span.first..span.end];
            if span.recorded && centre_tied(edges) {
                span.start = self.start_off_centre(k, &receiver.chart, receiver.origin, edges);
                recounted = true;
            }
        }
        recounted
    }

    /// [`LightPass::pixel`]'s third stage: the results of a receiver that
    /// needs no per-sample counters (every sample keeps its start count,
    /// or only the opaque counts are read and the sample grid's blocks
    /// give them); `None` for the others.
    #[inline(always)]
    fn without_samples(
        &self,
        receiver: &Receiver,
        recounted: bool,
        scratch: &mut Scratch,
    ) -> Option<PixelResult> {
        let reads = receiver.reads;
        // The edges that change `D` over part of the light: what the
        // receiver's shadow depends on, whatever the culling let through.
        let edge_count = scratch.effective.len() as f32;
        // The direct light needs no samples either where every sample
        // keeps the start count: the exact unshadowed integral, as for
        // the receivers outside every wedge.
        let uniform_direct =
            reads.direct && !reads.semi_opaque && !reads.textured && !reads.inspected;
        if scratch.effective.is_empty() && (!reads.per_sample || uniform_direct) {
            // Every sample keeps the (corrected) start count: the
            // per-sample path's results without the samples (with one
            // opaque group and no radiance, its sums of 0 and 1 over the
            // samples are exact, so the same bits).
            let start = scratch.spans[0].start;
            let index = receiver.index;
            let edges = scratch.effective.len();
            return Some(self.uniform(
                index,
                start,
                || self.shading_point(index),
                edges,
                recounted,
            ));
        }
        let plain = reads.rect && !reads.per_sample && self.tables.is_empty();
        // From SECTOR_MIN edges on, the sectors do better (counter pass
        // at 256 samples on bunny.toml: 653 ms with blocks for all
        // receivers, 623 ms with sectors above).
        if let (true, Some(grid)) = (plain && scratch.effective.len() < SECTOR_MIN, &self.blocks) {
            if let Some((_, key)) = self.pattern.jittered(receiver.pixel) {
                // Only the opaque counts are read: made and tested only
                // where an edge may change them.
                let span = scratch.spans[0];
                let edges = &scratch.effective[span.first..span.end];
                let counts = scratch.blocks.count(grid, key, span.start, edges);
                let n = self.pattern.len() as usize;
                return Some(PixelResult::from_counts(counts, n, edge_count, recounted));
            }
        }
        None
    }

    /// [`LightPass::pixel`]'s fourth stage: the chart points of the
    /// receiver's samples into `scratch.chart`, and a rect light's world
    /// samples where they are read.
    #[inline(always)]
    fn fill_chart(&self, receiver: &Receiver, scratch: &mut Scratch) {
        let reads = receiver.reads;
        let n = self.pattern.len();
        let rows = self
            .pattern
            .jittered(receiver.pixel)
            .filter(|(strata, _)| chart_rows_apply(*strata, n));
        if let (true, Some((strata, key))) = (reads.rect, rows) {
            // The same points, four cells at a time.
            let columns = strata.a;
            let inv = (1.0 / f64::from(columns), 1.0 / f64::from(strata.b));
            scratch.chart.fill_slices(n as usize, |xs, ys| {
                chart_rows(key, columns, (0, 0, columns as usize), inv, xs, ys)
            });
        } else if reads.rect {
            let points = self.pattern.pixel_points(receiver.pixel);
            scratch.chart.fill(n as usize, |writer| {
                points.for_each(n, |(s, t)| writer.push([2.0 * s - 1.0, 1.0 - 2.0 * t]))
            });
        } else {
            let chart = &receiver.chart;
            scratch
                .chart
                .set(scratch.samples.iter().map(|s| chart.point(s.x.as_dvec3())));
        }
        if reads.rect && reads.rect_samples && !reads.chart_direct {
            self.sampler.samples_with(
                &self.pattern,
                receiver.position,
                receiver.pixel,
                &mut scratch.samples,
            );
        }
    }

    /// How [`LightPass::count_groups`] moves the counters of a receiver
    /// whose chart points are filled (`shading`: the shading point of the
    /// direct light from the chart points, when that applies).
    #[inline(always)]
    fn counting(
        &self,
        receiver: &Receiver,
        shading: Option<&SurfacePoint>,
        scratch: &mut Scratch,
    ) -> Counting<'_> {
        let reads = receiver.reads;
        let table = match self.tables {
            [] => None,
            [one] => Some(one),
            many => {
                let set = self.pattern.interleaved_set(receiver.pixel).unwrap_or(0) as usize;
                many.get(set)
            }
        };
        // Only counts are read back where nothing else is per sample, so
        // the counters may follow the sectors' order there; so may the
        // direct light from the chart points, from the points in that
        // order (one opaque group, no lobe: where it applies).
        let sorted_direct =
            shading.is_some_and(|point| !reads.semi_opaque && point.specular == Vec3::ZERO);
        let sorted = (!reads.per_sample || sorted_direct)
            && table.is_none()
            && scratch.effective.len() >= SECTOR_MIN
            && scratch.sectors.set(&scratch.chart);
        Counting {
            count: scratch.chart.len(),
            table,
            sorted,
        }
    }

    /// [`LightPass::pixel`]'s fifth stage: every recorded group's
    /// counters from its start count and effective edges, the opaque
    /// group's into `scratch.counters`, each semi-opaque group's layers
    /// added to `scratch.attenuation` (sized to the samples where
    /// `semi_opaque`, else emptied).
    #[inline(always)]
    fn count_groups(&self, counting: &Counting, semi_opaque: bool, scratch: &mut Scratch) {
        let Scratch {
            chart: samples,
            sectors,
            counters,
            layers,
            attenuation,
            effective,
            spans,
            ..
        } = scratch;
        let count = counting.count;
        attenuation.clear();
        if semi_opaque {
            attenuation.resize(count, 0.0);
        }
        for (k, (span, group)) in spans.iter().zip(self.groups).enumerate() {
            let opaque = k == 0;
            if !span.recorded {
                if span.start > 0 {
                    let add = f64::from(span.start) * group.per_layer;
                    attenuation.iter_mut().for_each(|a| *a += add);
                }
                continue;
            }
            let counts = if opaque { &mut *counters } else { &mut *layers };
            counts.clear();
            counts.resize(samples.padded(), span.start);
            let edges = &effective[span.first..span.end];
            if counting.sorted {
                sectors.add_covered_all(counts, edges);
            } else {
                for (edge, delta) in edges {
                    match counting.table {
                        Some(table) => table.add_covered(counts, edge, *delta),
                        None => add_covered(counts, samples, edge, *delta),
                    }
                }
            }
            if !opaque {
                for (accumulated, &layer_count) in attenuation.iter_mut().zip(&layers[..count]) {
                    // Counts are exact; a negative one is a tie at an
                    // edge and means no layer.
                    if layer_count > 0 {
                        *accumulated += f64::from(layer_count) * group.per_layer;
                    }
                }
            }
        }
    }

    /// [`LightPass::pixel`]'s sixth stage, soft textured shadow volumes
    /// (§5.2): per sample, the opacity of each S-triangle the receiver's
    /// volume test passed; a fully opaque texel is one more occluder in
    /// `D`, a partial one a layer of transmittance.
    #[inline(always)]
    fn add_s_triangles(&self, receiver: &Receiver, count: usize, scratch: &mut Scratch) {
        let (Some(stris), false) = (self.s_triangles, receiver.s_triangles.is_empty()) else {
            return;
        };
        let mode = self.technique.transmittance;
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
        let origin = receiver.origin.as_vec3();
        for &s in receiver.s_triangles {
            stris.sample_opacities_in(
                self.ctx.scene,
                s as usize,
                origin,
                positions,
                self.technique.opacity_filter,
                opacities,
            );
            for (k, &opacity) in opacities.iter().enumerate() {
                if opacity >= 1.0 {
                    counters[k] += 1;
                } else if opacity > 0.0 {
                    attenuation[k] += mode.per_layer(Attenuation::partial(f64::from(opacity)));
                }
            }
        }
    }

    /// [`LightPass::pixel`]'s seventh stage: the transmittance per sample
    /// from `scratch.attenuation`, and the inspector's view of the
    /// receiver.
    #[inline(always)]
    fn transmittance(&self, receiver: &Receiver, count: usize, scratch: &mut Scratch) {
        let mode = self.technique.transmittance;
        scratch.transmittance.clear();
        scratch
            .transmittance
            .extend(scratch.attenuation.iter().map(|&a| mode.transmittance(a)));
        if let Some(inspect) = receiver.inspect {
            inspect(
                receiver.index,
                &InspectedPixel {
                    samples: &scratch.samples,
                    counters: &scratch.counters[..count],
                    transmittance: &scratch.transmittance,
                },
            );
        }
    }

    /// [`LightPass::pixel`]'s last stage: the results from the counters
    /// and transmittance per sample.
    #[inline(always)]
    fn resolve(
        &self,
        receiver: &Receiver,
        counting: &Counting,
        shading: Option<SurfacePoint>,
        recounted: bool,
        scratch: &mut Scratch,
    ) -> PixelResult {
        let reads = receiver.reads;
        let count = counting.count;
        let edge_count = scratch.effective.len() as f32;
        let counters = &scratch.counters[..count];
        let weighted = reads.semi_opaque || reads.direct || reads.textured || count > 1 << 24;
        if !weighted && counters.len().is_multiple_of(LANES) {
            // Only the opaque counts, in whole lanes: one pass. (Visible
            // samples, below 2²⁴, are exact in f32, as the count below.)
            let counts = BlockCounts::of(counters);
            return PixelResult::from_counts(counts, count, edge_count, recounted);
        }
        let visible = if weighted {
            weighted_visibility(
                counters,
                reads.semi_opaque.then_some(&scratch.transmittance[..]),
                &mut scratch.visibility,
            )
        } else {
            // Visibilities of 0 and 1 sum exactly in f32 (up to 2²⁴
            // samples) in any order: the count gives the same bits
            // without the serial chain of float adds.
            counters.iter().filter(|&&c| c <= 0).count() as f32
        };
        let radiance = if reads.direct {
            self.direct_radiance(receiver, counting, visible, shading, scratch)
        } else if reads.textured {
            self.textured_radiance(receiver.index, visible, count, scratch)
        } else {
            Vec3::ZERO
        };
        let counters = &scratch.counters[..count];
        let max_dc = counters.iter().copied().max().unwrap_or(0).max(0);
        let sum_dc: i64 = counters.iter().map(|&c| i64::from(c.max(0))).sum();
        PixelResult {
            vcoef: visible / count as f32,
            radiance,
            max_dc: max_dc as f32,
            mean_dc: (sum_dc as f64 / count as f64) as f32,
            edges: edge_count,
            recounted,
        }
    }

    /// The direct light's estimate at a receiver whose visibilities
    /// (`scratch.visibility`) sum to `visible`.
    #[inline(always)]
    fn direct_radiance(
        &self,
        receiver: &Receiver,
        counting: &Counting,
        visible: f32,
        shading: Option<SurfacePoint>,
        scratch: &mut Scratch,
    ) -> Vec3 {
        let reads = receiver.reads;
        if visible == 0.0 {
            // Every sample hidden (the visibilities are 0 and 1, or
            // products in [0, 1], so a zero sum is all zero): what the
            // per-sample sum gives, without shading the samples.
            return Vec3::ZERO;
        }
        if visible == counting.count as f32 && !reads.semi_opaque && !reads.textured {
            // Every sample seen, at full weight: the exact unshadowed
            // integral, as where no edge reaches the receiver (the samples'
            // estimate converges to it; this has no variance). The
            // shading point made for the chart estimate, if it was.
            return match &shading {
                Some(point) => self.prepared.unshadowed_direct(point),
                None => self
                    .prepared
                    .unshadowed_direct(&self.shading_point(receiver.index)),
            };
        }
        let point = shading.unwrap_or_else(|| self.shading_point(receiver.index));
        let points = if counting.sorted {
            scratch.sectors.points()
        } else {
            scratch.chart.padded_points()
        };
        let from_chart = reads
            .chart_direct
            .then(|| {
                self.prepared
                    .direct_from_rect_chart(&point, points, &scratch.visibility)
            })
            .flatten();
        if let Some(radiance) = from_chart {
            return radiance;
        }
        // A specular lobe, or a receiver the chart's units do not suit:
        // the samples, with their visibilities in the samples' order.
        if counting.sorted {
            visibility_in_sample_order(counting.count, scratch);
        }
        if scratch.samples.is_empty() {
            self.sampler.samples_with(
                &self.pattern,
                receiver.position,
                receiver.pixel,
                &mut scratch.samples,
            );
        }
        self.prepared
            .direct_from_samples(&point, &scratch.samples, &scratch.visibility)
    }

    /// Eq. 4.2 at pixel `index`: each sample's visibility weighted by its
    /// emitted radiance, per channel, normalised so that a fully visible
    /// light gives the unshadowed light exactly (`visible`: the
    /// visibilities' sum over the `count` samples).
    #[inline(always)]
    fn textured_radiance(
        &self,
        index: usize,
        visible: f32,
        count: usize,
        scratch: &Scratch,
    ) -> Vec3 {
        let (mut seen, mut all) = (Vec3::ZERO, Vec3::ZERO);
        for (sample, &visibility) in scratch.samples.iter().zip(&scratch.visibility) {
            let emitted = self.prepared.sample_radiance(sample);
            seen += emitted * visibility;
            all += emitted;
        }
        let plain = visible / count as f32;
        let weighted = Vec3::select(all.cmpgt(Vec3::ZERO), seen / all, Vec3::splat(plain));
        self.prepared.unshadowed_direct(&self.shading_point(index)) * weighted
    }

    /// Whether [`LightPass::block_extras`] can make the unbounded edges:
    /// one caster group and a rect light.
    pub(super) fn blocks_in_lanes(&self) -> bool {
        self.groups.len() == 1 && matches!(self.bound, LightBound::Rect(_))
    }

    /// The unbounded edges of the 4² block of receivers `pixels` (global
    /// indices, row by row; `None` where no receiver) into `out`: each
    /// of `edges` (its id and the mask of receivers it reached) tested
    /// against four receivers at a time, with [`LightPass::group_edges`]'s
    /// operations per lane (`side_of4`, `multiplicity4`,
    /// `RectProjection4`), so each receiver gets the effective edges, in
    /// the same order, and the recount verdict its own pass would.
    /// Only where [`LightPass::blocks_in_lanes`].
    #[inline(always)]
    pub(super) fn block_extras(
        &self,
        pixels: &[Option<usize>; BLOCK],
        edges: impl Iterator<Item = (u32, u16)>,
        out: &mut BlockExtras,
        avx: bool,
    ) {
        let group = &self.groups[0];
        let candidates = &group.candidates;
        let mut origins = [DVec3::ZERO; BLOCK];
        let mut rasters = [DVec3::ZERO; BLOCK];
        let mut projections: [Option<RectProjection>; BLOCK] = [None; BLOCK];
        let mut tied = [false; BLOCK];
        for (k, pixel) in pixels.iter().enumerate() {
            out.effective[k].clear();
            out.recount[k] = false;
            out.admitted[k] = 0;
            let Some(i) = *pixel else {
                continue;
            };
            let (position, geo_normal) = position_normal(self.ctx.gbuffer, i);
            let p = self.origin.of(position, geo_normal).as_dvec3();
            (origins[k], rasters[k]) = (p, position.as_dvec3());
            projections[k] =
                ReceiverChart::new(&self.bound, p).and_then(|c| c.rect_projection().copied());
            tied[k] = self.ties[i] == Tie::Tied;
        }
        let mut groups = [GroupInputs::default(); GROUPS];
        for (g, inputs) in groups.iter_mut().enumerate() {
            for l in 0..4 {
                let k = 4 * g + l;
                for a in 0..3 {
                    inputs.p[a][l] = origins[k][a];
                    inputs.raster[a][l] = rasters[k][a];
                }
                inputs.tied |= u32::from(tied[k]) << l;
            }
            // A lane without a projection borrows a neighbour's (its
            // results unread).
            let row = &projections[4 * g..4 * g + 4];
            let Some(any) = row.iter().flatten().next() else {
                continue;
            };
            for (l, projection) in row.iter().enumerate() {
                inputs.projected |= u32::from(projection.is_some()) << l;
                let (_, n, u, v, s_p, t_p) = projection.as_ref().unwrap_or(any).parts();
                for a in 0..3 {
                    (inputs.n[a][l], inputs.u_dual[a][l], inputs.v_dual[a][l]) = (n[a], u[a], v[a]);
                }
                (inputs.s_p[l], inputs.t_p[l]) = (s_p, t_p);
            }
        }
        let source = EdgeSource {
            candidates,
            first_edge: group.first_edge,
            centre: self.centre,
            silhouettes: self.technique.silhouettes,
        };
        #[cfg(target_arch = "x86_64")]
        if avx {
            // SAFETY: `avx` is set only where the CPU has AVX (the
            // caller's `simd::avx::available`), the kernel's one
            // requirement.
            unsafe { edge_lanes::run_avx(&groups, edges, &source, out) };
            return;
        }
        let _ = avx;
        edge_lanes::run_lanes(&groups, edges, &source, out);
    }

    /// One group's start count at the shadow-ray origin `p'` (`p`) of
    /// pixel `i`, and whether a ray recounted it: the stencil decided
    /// `D(O)` at the raster's receiver; where a quad's plane passes
    /// between the two, the count moves across that quad (+m entering
    /// the volume, −m leaving it) or, where that does not compose with
    /// the own-face rule, one ray gives it. Every recorded edge (`tags`,
    /// then `extra`) whose projection covers part of the light goes to
    /// `effective` with its signed change of `D`; then `made`'s, the
    /// unbounded edges [`LightPass::block_extras`] made for the receiver
    /// (with their recount verdict).
    #[inline(always)]
    fn group_edges(
        &self,
        k: usize,
        i: usize,
        (raster, p): (DVec3, DVec3),
        chart: &ReceiverChart,
        (tags, extra, made): (&[u64], &[u32], Option<MadeExtras>),
        effective: &mut Vec<(OrientedEdge, i32)>,
    ) -> (i32, bool) {
        let group = &self.groups[k];
        let edges = &group.candidates.edges;
        let local = |global: u32| (global - group.first_edge) as usize;
        let mut push = |edge: &CandidateEdge, side: i32| {
            if side == 0 {
                return;
            }
            // Whole-light silhouettes: the exact change (see `edges`).
            // Centre silhouettes: the thesis's rule, ±m by the half the
            // receiver is in (outer adds), whether or not the edge is a
            // silhouette from p — the exact rule would drop those edges
            // and miss the ones that are silhouettes from p only, which
            // on tessellated curved occluders leaves almost hard shadows.
            let multiplicity = match self.technique.silhouettes {
                SilhouetteMode::WholeLight => group.candidates.multiplicity_from(edge, p),
                SilhouetteMode::Centre if edge.quad_sign != 0 => {
                    edge.quad_weight as i32 * i32::from(edge.quad_sign)
                }
                SilhouetteMode::Centre => group.candidates.multiplicity_from(edge, p),
            };
            if multiplicity == 0 {
                return;
            }
            let oriented = chart
                .edge(edge.v0, edge.v1)
                .and_then(|(a, b)| OrientedEdge::new(a, b));
            if let Some(oriented) = oriented {
                effective.push((oriented, side * multiplicity));
            }
        };
        let mut start = group.start[i];
        let tie = self.ties[i];
        let mut crossed = false;
        // Edges drawn as wedges: the raster's half is the side of the
        // quad's plane the stencil saw the receiver on.
        for &tag in tags {
            let edge = &edges[local((tag >> 1) as u32)];
            let geometric = side_of(p, edge.v0, edge.v1, self.centre);
            push(edge, geometric);
            if edge.quad_sign == 0 || tie == Tie::Tied {
                continue;
            }
            let outer = tag & 1 == 1;
            let stencil_side = i32::from(edge.quad_sign) * if outer { 1 } else { -1 };
            if geometric != 0 && geometric != stencil_side {
                let weight = edge.quad_weight as i32;
                start += if outer { weight } else { -weight };
                crossed = true;
            }
        }
        // On its own face and across a quad's plane from the raster's
        // receiver, the two corrections do not compose.
        let mut recount = crossed && tie == Tie::OwnFace;
        // Edges found by their region: the stencil's side of the quad's
        // plane is its sign at the raster's receiver. A receiver the tie
        // test did not flag has no volume face within the tie band
        // (4e-6 of its depth) along its view ray, far above f64's
        // rounding of this sign, so the raster decided the same.
        for &id in extra {
            let edge = &edges[local(id)];
            let geometric = side_of(p, edge.v0, edge.v1, self.centre);
            push(edge, geometric);
            if edge.quad_sign != 0
                && tie != Tie::Tied
                && geometric != 0
                && side_of(raster, edge.v0, edge.v1, self.centre) != geometric
            {
                recount = true;
            }
        }
        if let Some(made) = made {
            effective.extend_from_slice(made.effective);
            recount |= made.recount;
        }
        if recount {
            // One ray gives the count at `p'`.
            let mut counts = vec![0; self.groups.len()];
            self.exact
                .counts(p.as_vec3(), self.centre.as_vec3(), &mut counts);
            start = counts[k];
        }
        (start, recount)
    }
}

/// The visibility of each sample with opaque `counters` (1 where `D ≤ 0`),
/// times its `transmittance` where the scene has semi-opaque casters,
/// into `visibility`; their sum.
#[inline(always)]
fn weighted_visibility(
    counters: &[i32],
    transmittance: Option<&[f64]>,
    visibility: &mut Vec<f32>,
) -> f32 {
    visibility.clear();
    visibility.extend(counters.iter().map(|&c| if c <= 0 { 1.0 } else { 0.0 }));
    if let Some(transmittance) = transmittance {
        for (v, &t) in visibility.iter_mut().zip(transmittance) {
            *v *= t as f32;
        }
    }
    visibility.iter().sum()
}

/// The opaque visibilities of the `count` samples in the samples' order
/// into `scratch.visibility`, where the counters followed the sectors'
/// order: the opaque group's counts made again in `scratch.layers`.
#[inline]
fn visibility_in_sample_order(count: usize, scratch: &mut Scratch) {
    let span = scratch.spans[0];
    let counts = &mut scratch.layers;
    counts.clear();
    counts.resize(scratch.chart.padded(), span.start);
    for (edge, delta) in &scratch.effective[span.first..span.end] {
        add_covered(counts, &scratch.chart, edge, *delta);
    }
    scratch.visibility.clear();
    scratch.visibility.extend(
        counts[..count]
            .iter()
            .map(|&c| if c <= 0 { 1.0 } else { 0.0 }),
    );
}

/// How close (in chart units, the light's half-width) to the light's
/// centre an edge's projection may pass before the start count there is
/// a tie: a hundred times the rounding of the chart's `f32` ends and of
/// the rays' `f32` positions, far below any sample's spacing.
const CENTRE_TIE: f64 = 1e-5;

/// Whether a projected edge of `edges` passes within [`CENTRE_TIE`] of
/// the chart's origin, the light's centre.
#[inline]
fn centre_tied(edges: &[(OrientedEdge, i32)]) -> bool {
    edges.iter().any(|(e, _)| {
        let (a, b) = (e.lo().map(f64::from), e.hi().map(f64::from));
        let d = [b[0] - a[0], b[1] - a[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let cross = a[0] * b[1] - a[1] * b[0];
        // The line first (one product per edge), then the segment.
        if cross * cross > CENTRE_TIE * CENTRE_TIE * len2 {
            return false;
        }
        let t = -(a[0] * d[0] + a[1] * d[1]);
        let closest = if t <= 0.0 {
            a
        } else if t >= len2 {
            b
        } else {
            [a[0] + d[0] * t / len2, a[1] + d[1] * t / len2]
        };
        closest[0] * closest[0] + closest[1] * closest[1] <= CENTRE_TIE * CENTRE_TIE
    })
}

/// Where [`LightPass::start_off_centre`] may take a start count: points
/// at 1e-3 of the light's half-width from its centre (a hundred times
/// [`CENTRE_TIE`]), in eight directions.
const OFF_CENTRE: [[f32; 2]; 8] = [
    [1e-3, 0.0],
    [0.0, 1e-3],
    [-1e-3, 0.0],
    [0.0, -1e-3],
    [7.071e-4, 7.071e-4],
    [-7.071e-4, 7.071e-4],
    [-7.071e-4, -7.071e-4],
    [7.071e-4, -7.071e-4],
];

impl LightPass<'_, '_> {
    /// Group `k`'s start count at the light's centre for a receiver (its
    /// shadow-ray origin `p`) one of whose projected `edges` passes
    /// through the centre: the count at a chart point `q` clear of every
    /// edge, by one ray ([`ExactStart::counts_towards`]), less the
    /// changes the chart's own test gives the edges between the centre
    /// and `q`. Every sample then gets the count the rays see on its side
    /// of that edge.
    fn start_off_centre(
        &self,
        k: usize,
        chart: &ReceiverChart,
        p: DVec3,
        edges: &[(OrientedEdge, i32)],
    ) -> i32 {
        let clear = |q: [f32; 2]| {
            let shifted: Vec<(OrientedEdge, i32)> = edges
                .iter()
                .filter_map(|(e, d)| {
                    let m = |v: [f32; 2]| [f64::from(v[0] - q[0]), f64::from(v[1] - q[1])];
                    OrientedEdge::new(m(e.lo()), m(e.hi())).map(|e| (e, *d))
                })
                .collect();
            !centre_tied(&shifted)
        };
        let q = OFF_CENTRE
            .iter()
            .copied()
            .find(|&q| clear(q))
            .unwrap_or(OFF_CENTRE[0]);
        let target = chart.light_point([f64::from(q[0]), f64::from(q[1])], self.centre);
        let mut counts = vec![0; self.groups.len()];
        self.exact.counts_towards(p.as_vec3(), target, &mut counts);
        let crossed: i32 = edges
            .iter()
            .filter(|(e, _)| e.covers(q))
            .map(|(_, d)| d)
            .sum();
        counts[k] - crossed
    }
}

/// Pixel `i`'s position and geometric normal, as its shading sample has
/// them (zero on the background), without reading the rest.
#[inline(always)]
fn position_normal(gbuffer: &crate::gbuffer::GBuffer, i: usize) -> (Vec3, Vec3) {
    let background = crate::gbuffer::GSample::BACKGROUND;
    gbuffer
        .surface_geometry(i)
        .map_or((background.position, background.geo_normal), |(p, n, _)| {
            (p, n)
        })
}
