//! Hierarchical penumbra casting (Laine & Aila 2005): exact per-sample
//! visibility by casting every blocker triangle into a hierarchy of
//! receiver points — ray casting transposed.
//!
//! Per light:
//!
//! 1. **Receivers**: the G-buffer's points, as the reference's shadow-ray
//!    origins ([`ShadowOrigin`]), in screen chunks ([`cast::Chunk`]), each
//!    with its own AABB hierarchy ([`hierarchy`]).
//! 2. **Light samples** in three levels ([`samples`]): the light, groups
//!    of 32, the samples; `K` sets from the one sampling module.
//! 3. **Casting** ([`cast`]): per opaque caster triangle (coarsely sorted
//!    by area, largest first), its penumbra volume with the whole light
//!    `V_L` ([`volume`]) culls hierarchy nodes, the group volumes `V_Gk`
//!    cull groups, and at the leaves each receiver is tested against the
//!    hard shadow volume of every remaining sample of its set (SIMD over
//!    four samples), setting its bits. The optimisations of §3.3 are
//!    switchable ([`PenumbraCastingOptions`]).
//! 4. **Shading**: the same per-sample visibility the reference computes
//!    (1 − bit), with the reference's estimator: a
//!    [`LightTerm::Radiance`] whose Vcoef and radiance are bit for bit the
//!    reference's where the sample sets are the reference's and no
//!    relation is a tie.
//!
//! See `docs/algorithms/penumbra-casting.md`.

pub mod cast;
#[forbid(unsafe_code)]
pub mod hierarchy;
#[forbid(unsafe_code)]
pub mod options;
#[forbid(unsafe_code)]
pub mod samples;
#[forbid(unsafe_code)]
pub mod translucent;
pub mod volume;

use super::kit::rays::{scene_diagonal, ShadowOrigin};
use super::kit::stsv::Filter;
use super::kit::timing::PassTimer;
use super::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use super::technique::{PixelVisibility, SampleDecisions};
use super::{BufferNote, LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};
use crate::error::{Error, Result};
use crate::output::Layer;
use crate::sampling::{LightSampler, PatternSampler, SamplePattern};
use crate::scene::LightShape;
use crate::shade::{surface_point, PreparedLight};
use cast::{Chunk, ChunkStats, Switches};
use glam::{DVec3, Vec3};
pub use options::PenumbraCastingOptions;
use rayon::prelude::*;
use samples::{ReceiverSamples, SampleKey, SampleSets, GROUP, MAX_GROUPS};
use std::time::Duration;
use volume::{penumbra_volume, PenumbraVolume};

impl PenumbraCastingOptions {
    fn switches(&self) -> Switches {
        Switches {
            umbra: self.pc_umbra_bits,
            active_planes: self.pc_active_planes,
            lazy: self.pc_lazy_volumes,
            on_demand: self.pc_on_demand_masks,
            simd: self.pc_simd,
            cone: self.pc_cone_prefilter,
            cone_decides: self.pc_cone_decides,
            cone_split: self.pc_cone_split,
            rebuild_percent: self.pc_rebuild_percent,
        }
    }
}

/// Penumbra casting in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "penumbra-casting",
    summary: "hierarchical penumbra casting: blocker triangles cast into a receiver hierarchy, exact per-sample bits (Laine & Aila 2005)",
    module: "shadow/penumbra_casting/",
    page: Some("penumbra-casting.md"),
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
    quality_settings: |s| s.per_sample_count("penumbra-casting", "", s.first_pattern(), |_| {}),
    build: |p| {
        Box::new(PenumbraCasting {
            samples: p.samples,
            seed: p.seed,
            pattern: p.pattern,
            options: PenumbraCastingOptions {
                opacity_filter: p.options.stsv.opacity_filter,
                ..p.options.penumbra_casting
            },
        })
    },
    // Receivers share a hierarchy per square screen chunk and the chunk's
    // rebuild decision counts its receivers, so the `pc_leaf_triangles`
    // layer depends on the whole chunk.
    bands: Bands::Chunks(|o| o.penumbra_casting.pc_chunk.max(1)),
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[Samples, Pattern, Seed, PenumbraCasting, Stsv]
    },
    cost: crate::shadow::technique::CostClass::Raster,
};

/// The penumbra-casting technique.
#[derive(Debug, Clone, Copy)]
pub struct PenumbraCasting {
    /// Light samples per receiver and light (1 ..= 4096).
    pub samples: u32,
    /// Seed of the light samples.
    pub seed: u64,
    /// How samples are placed on the light.
    pub pattern: SamplePattern,
    /// Its options.
    pub options: PenumbraCastingOptions,
}

/// Every receiver's blocked relations for one light (for checks).
#[derive(Debug, Clone)]
pub struct LightMasks {
    /// The sample sets.
    pub sets: SampleSets,
    /// Per pixel: its set, or `None` for background and non-receivers.
    pub set: Vec<Option<u16>>,
    /// Per pixel: `groups` words of blocked bits in group order (bit `j`
    /// of word `k` is sample `sets.order[set][32 k + j]`).
    pub words: Vec<u32>,
    /// Per pixel: group-umbra bits and the full-umbra bit as the
    /// traversal left them.
    pub umbra: Vec<(u128, bool)>,
    /// Per pixel and slot (group order, `sets.n` per pixel): the
    /// relation's `V·T` (0 where blocked); empty when the scene has no
    /// translucent casters.
    pub transmittance: Vec<f64>,
    /// What the light's pass measured.
    pub report: LightReport,
}

/// What one light's pass measured.
#[derive(Debug, Clone, Default)]
pub struct LightReport {
    /// Receivers cast into.
    pub receivers: usize,
    /// Blocker triangles cast.
    pub triangles: usize,
    /// Back faces of closed casters left out.
    pub culled: usize,
    /// Back faces of open casters, cast only into unsealed receivers.
    pub open_back: usize,
    /// Triangles of the surfaces closing the open casters.
    pub caps: usize,
    /// Receivers sealed against the open casters' holes.
    pub sealed: usize,
    /// The chunk side used (the option's, or a divisor of it within the
    /// memory budget).
    pub chunk_side: u32,
    /// Chunks and waves.
    pub chunks: usize,
    /// Waves of chunks (mask budget).
    pub waves: usize,
    /// Summed over chunks.
    pub stats: ChunkStats,
    /// Summed peak mask bytes of the chunks of the largest wave.
    pub peak_mask_bytes: u64,
    /// Hard-volume caches, summed over chunks.
    pub volume_bytes: u64,
    /// The blockers' light penumbra volumes, all held during the cast.
    pub volume_list_bytes: u64,
    /// Chunks before the heavy ones were split.
    pub chunks_unsplit: usize,
    /// The probe that decides the splits (wall clock).
    pub probe_time: Duration,
    /// Wall-clock times.
    pub sort_time: Duration,
    /// Light volumes of the triangles and hierarchy casting.
    pub cast_time: Duration,
    /// First hierarchy builds (wall clock).
    pub build_time: Duration,
    /// The translucent pass (semi-opaque layers and S-triangles).
    pub translucent: translucent::Stats,
    /// Its wall-clock time.
    pub translucent_time: Duration,
}

/// A finished chunk's translucent transmittances.
struct Tr<'a> {
    casters: &'a translucent::Casters,
    records: Option<&'a translucent::Records>,
}

impl Tr<'_> {
    /// Whether the scene has translucent casters.
    fn any(&self) -> bool {
        self.records.is_some()
    }

    /// Receiver `r`'s relation `slot`: `V·T` given its opaque bit.
    fn vt(&self, r: usize, slot: usize, blocked: bool) -> f64 {
        match self.records {
            _ if blocked => 0.0,
            None => 1.0,
            Some(rec) => rec.transmittance(self.casters, r, slot),
        }
    }
}

/// A chunk's receivers: pixel indices and sets.
struct ChunkInput {
    pixels: Vec<u32>,
    /// Its square of the screen: corner and side, in pixels.
    x0: u32,
    y0: u32,
    side: u32,
}

/// The largest divisor `d` of `chunk` whose `d × d` receivers of
/// `per_receiver` bytes fit in half of `budget` bytes (1 if none does).
fn chunk_side(chunk: u32, per_receiver: u64, budget: u64) -> u32 {
    (1..=chunk.max(1))
        .rev()
        .filter(|d| chunk.is_multiple_of(*d))
        .find(|&d| u64::from(d) * u64::from(d) * per_receiver * 2 <= budget)
        .unwrap_or(1)
}

/// An open caster's back faces are cast only into sealed-off receivers
/// when it has more than this many back faces per closing triangle.
const OPEN_CAPS_PER_BACK_FACE: usize = 4;

/// Smallest chunk side a heavy chunk is split down to.
const MIN_SPLIT_SIDE: u32 = 64;
/// Pixel step of the probe's receivers in x and y.
const PROBE_STEP: u32 = 4;
/// The probe casts this fraction (one in …) of the triangles, the first
/// in cast order.
const PROBE_SHARE: usize = 16;

/// `inputs` with every chunk whose probe work is above `limit` cut into
/// its four quarters, and so on while a quarter's is, down to
/// [`MIN_SPLIT_SIDE`]. `probe(pixels)` casts a chunk's probe and gives
/// each probe receiver's pixel and work (the triangles that reached its
/// leaf); a quarter's work is its probe receivers' sum. Work is a count,
/// the same on every machine and for every thread count or band, and the
/// result is in chunk order, so the chunks (and the leaf-triangle AOV)
/// are the same too.
fn split_heavy_chunks<P>(
    inputs: Vec<ChunkInput>,
    width: u32,
    limit: u64,
    probe: P,
) -> Vec<ChunkInput>
where
    P: Fn(&[u32]) -> Vec<(u32, u64)> + Sync,
{
    let works: Vec<Vec<(u32, u64)>> = inputs.par_iter().map(|c| probe(&c.pixels)).collect();
    let mut out = Vec::new();
    for (c, work) in inputs.into_iter().zip(works) {
        let mut stack = vec![(c, work)];
        while let Some((c, work)) = stack.pop() {
            let total: u64 = work.iter().map(|w| w.1).sum();
            let half = c.side / 2;
            if total <= limit || half < MIN_SPLIT_SIDE {
                out.push(c);
                continue;
            }
            let quarter = |i: u32| {
                let (x, y) = (i % width, i / width);
                usize::from(x >= c.x0 + half) + 2 * usize::from(y >= c.y0 + half)
            };
            let mut parts: [(ChunkInput, Vec<(u32, u64)>); 4] = std::array::from_fn(|q| {
                let q = q as u32;
                (
                    ChunkInput {
                        pixels: Vec::new(),
                        x0: c.x0 + (q % 2) * half,
                        y0: c.y0 + (q / 2) * half,
                        side: half,
                    },
                    Vec::new(),
                )
            });
            for &i in &c.pixels {
                parts[quarter(i)].0.pixels.push(i);
            }
            for &(i, v) in &work {
                parts[quarter(i)].1.push((i, v));
            }
            // Pushed last to first: popped (and emitted) in quarter order.
            for part in parts.into_iter().rev() {
                if !part.0.pixels.is_empty() {
                    stack.push(part);
                }
            }
        }
    }
    out
}

impl PenumbraCasting {
    fn check(&self) -> Result<()> {
        if self.samples == 0 || self.samples as usize > GROUP * MAX_GROUPS {
            return Err(Error::param(
                "--samples",
                format!(
                    "penumbra casting takes 1 to {} light samples, not {}",
                    GROUP * MAX_GROUPS,
                    self.samples
                ),
            ));
        }
        let o = &self.options;
        if o.pc_sample_sets > 4096 {
            return Err(Error::param(
                "--pc-sample-sets",
                format!("takes 0 (auto) to 4096 sets, not {}", o.pc_sample_sets),
            ));
        }
        if o.pc_chunk == 0 {
            return Err(Error::param(
                "--pc-chunk",
                "the chunk side must be at least 1 pixel",
            ));
        }
        if o.pc_rebuild_percent > 100 {
            return Err(Error::param("--pc-rebuild-percent", "takes 0 to 100"));
        }
        if o.pc_mask_budget_mib == 0 {
            return Err(Error::param("--pc-mask-budget-mib", "must be at least 1"));
        }
        Ok(())
    }

    /// The sample sets actually used: `--pc-sample-sets`, or for 0 the
    /// reference's own sets where the pattern has finitely many (see the
    /// option).
    pub fn sample_sets(&self) -> usize {
        let groups = (self.samples as usize).div_ceil(GROUP).max(1);
        match (self.options.pc_sample_sets, self.pattern) {
            (0, SamplePattern::Interleaved { n }) => {
                let k = (n.max(1) * n.max(1)) as usize;
                if k * groups <= 4096 {
                    k
                } else {
                    8
                }
            }
            (0, SamplePattern::Correlated | SamplePattern::Grid) => 1,
            (0, _) => 8,
            (k, _) => k as usize,
        }
    }

    /// Whether every receiver gets the reference's samples of its pixel.
    fn matches_reference(&self, sets: &SampleSets) -> bool {
        // Grid points do not depend on the pixel: every set is the grid.
        sets.matches_reference() || self.pattern == SamplePattern::Grid
    }

    /// Casts every opaque caster for light `k`, then the translucent
    /// ones, and calls `finish` with each finished chunk (its pixels,
    /// state and translucent records), chunks of a wave in parallel.
    fn run_light<F>(
        &self,
        ctx: &ShadowContext,
        k: usize,
        finish: F,
    ) -> Result<(SampleSets, LightReport)>
    where
        F: Fn(&SampleSets, &[u32], &Chunk, &Tr) + Sync,
    {
        self.check()?;
        let light = ctx
            .scene
            .lights
            .get(k)
            .ok_or_else(|| Error::param("--technique", format!("no light {k}")))?;
        let sampler = LightSampler::new(light);
        let pattern = PatternSampler::new(self.pattern, self.samples, self.seed, k);
        let (centre, sets) = match light.shape {
            LightShape::Rect { center, u, v, .. } => {
                let centre = center.as_dvec3();
                let e1 = u.as_dvec3().normalize_or_zero();
                let e3 = u.as_dvec3().cross(v.as_dvec3()).normalize_or_zero();
                let e2 = e3.cross(e1);
                let axes = [e1, e2, e3];
                let sets = SampleSets::new(&sampler, &pattern, self.sample_sets(), centre, axes);
                (centre, sets)
            }
            LightShape::Sphere { center, radius } => {
                let centre = center.as_dvec3();
                let sets = SampleSets::sphere(&sampler, &pattern, centre, f64::from(radius));
                (centre, sets)
            }
        };
        let mut report = LightReport::default();

        // Triangles: opaque casters, non-degenerate, relative to the light.
        let t0 = std::time::Instant::now();
        let g = ctx.geometry;
        let cull = self.options.pc_cull_back_faces;
        // Back faces may be skipped only for closed casters the light is
        // outside of (a sample on a caster's surface sees only its exit
        // crossing): those whose bounding box is disjoint from the light's.
        let (llo, lhi) = sets
            .light
            .corners
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), c| {
                (lo.min(*c), hi.max(*c))
            });
        let mut object_box = vec![(DVec3::INFINITY, DVec3::NEG_INFINITY); ctx.scene.objects.len()];
        for (t, tri) in g.triangles.iter().enumerate() {
            if let Some(b) = object_box.get_mut(g.triangle_object[t] as usize) {
                for &i in tri {
                    let p = g.positions[i as usize].as_dvec3() - centre;
                    *b = (b.0.min(p), b.1.max(p));
                }
            }
        }
        let light_outside: Vec<bool> = object_box
            .iter()
            .map(|&(lo, hi)| {
                let m = 1e-6 * (hi - lo).max_element().max((lhi - llo).max_element());
                (lo - DVec3::splat(m)).cmpgt(lhi).any() || (hi + DVec3::splat(m)).cmplt(llo).any()
            })
            .collect();
        // The argument needs every face of the caster to block: one with a
        // see-through face (a semi-opaque or textured material) is never
        // culled, as its exit crossing may be that face.
        let mut all_opaque = vec![true; ctx.scene.objects.len()];
        for t in 0..g.triangles.len() {
            let mat = ctx.scene.materials.get(g.triangle_material[t] as usize);
            if !mat.is_some_and(|m| m.is_opaque()) {
                if let Some(a) = all_opaque.get_mut(g.triangle_object[t] as usize) {
                    *a = false;
                }
            }
        }
        let cullable = |o: usize| {
            cull && light_outside.get(o) == Some(&true) && all_opaque.get(o) == Some(&true)
        };
        // Opaque caster triangles with area: object, corners, and whether
        // the caster may be culled and the light is wholly behind it.
        let candidates: Vec<(usize, [DVec3; 3], bool)> = (0..g.triangles.len())
            .filter_map(|t| {
                let o = g.triangle_object[t] as usize;
                let casts = ctx.scene.objects.get(o).is_some_and(|o| o.cast_shadows);
                let mat = ctx.scene.materials.get(g.triangle_material[t] as usize);
                if !(casts && mat.is_some_and(|m| m.is_opaque())) {
                    return None;
                }
                let tri = g.triangles[t].map(|i| g.positions[i as usize].as_dvec3() - centre);
                let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
                if !(n.length_squared() > 0.0) {
                    return None;
                }
                let back =
                    cullable(o) && sets.light.corners.iter().all(|c| n.dot(*c - tri[0]) < 0.0);
                Some((o, tri, back))
            })
            .collect();
        // Open casters: the surfaces closing them (a fan per boundary
        // loop, in welded positions) and their boxes, widened. Only where
        // the caps are few against the back faces they let skip (a sheet,
        // whose cap is itself reversed, seals nothing).
        let closed = |o: usize| g.object_closed.get(o) == Some(&true);
        let mut open_backs = vec![0usize; ctx.scene.objects.len()];
        for &(o, _, back) in &candidates {
            open_backs[o] += usize::from(back && !closed(o));
        }
        let slack = 1e-10 * scene_diagonal(ctx.scene, ctx.geometry);
        let mut open = vec![false; ctx.scene.objects.len()];
        let mut cap_tris = Vec::new();
        let mut open_boxes = Vec::new();
        for (o, &backs) in open_backs.iter().enumerate().filter(|(_, &b)| b > 0) {
            let at = |v: u32| g.adjacency.positions[v as usize].as_dvec3() - centre;
            let mut caps = Vec::new();
            for l in g.adjacency.boundary_loops(g, o as u32) {
                for i in 1..l.len().saturating_sub(1) {
                    let tri = [at(l[0]), at(l[i + 1]), at(l[i])];
                    // A cap with no area is crossed by no segment.
                    if (tri[1] - tri[0]).cross(tri[2] - tri[0]).length_squared() > 0.0 {
                        caps.push(tri);
                    }
                }
            }
            if caps.len() * OPEN_CAPS_PER_BACK_FACE < backs {
                open[o] = true;
                cap_tris.extend(caps);
                let (lo, hi) = object_box[o];
                let (lo, hi) = (lo - DVec3::splat(slack), hi + DVec3::splat(slack));
                open_boxes.push((lo.to_array(), hi.to_array()));
            }
        }
        // Per triangle cast: it and whether it is an open caster's back
        // face (cast only where receivers are not sealed); closed
        // casters' back faces are left out.
        let tris: Vec<([DVec3; 3], bool)> = candidates
            .into_iter()
            .filter_map(|(o, tri, back)| {
                if back && closed(o) {
                    report.culled += 1;
                    return None;
                }
                let open_back = back && open[o];
                report.open_back += usize::from(open_back);
                Some((tri, open_back))
            })
            .collect();
        let tris = if self.options.pc_sort_blockers {
            sort_by_area(tris)
        } else {
            tris
        };
        let (tris, open_back): (Vec<[DVec3; 3]>, Vec<bool>) = tris.into_iter().unzip();
        report.sort_time = t0.elapsed();
        report.triangles = tris.len();
        report.caps = cap_tris.len();
        let any_open_back = report.open_back > 0;

        // Translucent casters (semi-opaque layers, S-triangles).
        let casters = translucent::Casters::collect(ctx, &sets, centre);
        // The S-triangles' projector reads the samples' f32 positions.
        let projector = !casters.mattes.is_empty();
        report.translucent.layers = casters
            .tris
            .iter()
            .filter(|t| matches!(t.1, translucent::Kind::Layer(_)))
            .count();
        report.translucent.mattes = casters.mattes.len();
        report.translucent.bytes_per_sample = casters.record_bytes(1);

        // Waves of chunks within the mask budget (a translucent record
        // counted for every receiver: the worst case).
        let budget = u64::from(self.options.pc_mask_budget_mib) << 20;
        let per_receiver = sets.groups as u64 * 4
            + if casters.is_empty() {
                0
            } else {
                casters.record_bytes(sets.n)
            }
            + if sets.per_receiver() {
                // Its own samples (with the projector's positions where
                // the translucent pass needs them).
                ReceiverSamples::bytes_per_receiver(sets.groups, projector)
            } else {
                0
            };
        // The chunk side: the option's, or its largest divisor whose
        // chunk's worst case stays within half the budget (a sphere
        // light's receivers each hold their own samples: at 4096 samples
        // 151 KiB a receiver). A divisor keeps the bands' chunk alignment.
        let side = chunk_side(self.options.pc_chunk, per_receiver, budget);
        report.chunk_side = side;
        // Receivers, by screen chunk.
        let origin = ShadowOrigin::new(ctx.scene, ctx.geometry);
        let gb = ctx.gbuffer;
        let (w, h) = (gb.width.max(1), gb.height);
        let (cw, ch) = (w.div_ceil(side), h.div_ceil(side));
        let mut inputs: Vec<ChunkInput> = (0..cw * ch)
            .map(|c| ChunkInput {
                pixels: Vec::new(),
                x0: c % cw * side,
                y0: c / cw * side,
                side,
            })
            .collect();
        for i in 0..gb.len() {
            let Some(s) = gb.get(i) else { continue };
            // (A receiver inside a sphere light has no samples: it is
            // finished with the non-receivers.)
            if !s.is_surface() || !receives(ctx, s.object) || !sets.has_samples(s.position) {
                continue;
            }
            let (x, y) = (i as u32 % w, i as u32 / w);
            inputs[((y / side) * cw + x / side) as usize]
                .pixels
                .push(i as u32);
        }
        inputs.retain(|c| !c.pixels.is_empty());
        let sw = self.options.switches();
        // Every blocker's light penumbra volume, made once (in parallel)
        // and held for all chunks of all waves: each chunk then runs
        // through the whole list on its own. (Batches of volumes with a
        // barrier after each let the chunk under a dense caster hold both
        // workers at every batch: on bunny.toml at 1280×960 one 256²
        // chunk took 10.4 s of the 17.8 s summed over all.)
        let tv = std::time::Instant::now();
        let mut vl: Vec<PenumbraVolume> = Vec::new();
        vl.resize_with(tris.len(), PenumbraVolume::default);
        tris.par_iter()
            .zip(vl.par_iter_mut())
            .for_each(|(t, v)| penumbra_volume(&sets.light, t, v));
        let mut caps: Vec<PenumbraVolume> = Vec::new();
        caps.resize_with(cap_tris.len(), PenumbraVolume::default);
        cap_tris
            .par_iter()
            .zip(caps.par_iter_mut())
            .for_each(|(t, v)| penumbra_volume(&sets.light, t, v));
        report.volume_list_bytes = vl.iter().map(PenumbraVolume::bytes).sum();
        report.cast_time += tv.elapsed();
        let receiver_pos = |i: u32| {
            let s = gb.sample(i as usize);
            let o = origin.of(s.position, s.geo_normal).as_dvec3() - centre;
            [o.x, o.y, o.z]
        };
        let receiver_set = |i: u32| sets.set_of((i % w, i / w)) as u16;
        // Sample keys only where receivers have samples of their own.
        let receiver_keys = |pixels: &[u32]| -> Vec<SampleKey> {
            if !sets.per_receiver() {
                return Vec::new();
            }
            pixels
                .iter()
                .map(|&i| SampleKey {
                    position: gb.sample(i as usize).position,
                    pixel: (i % w, i / w),
                })
                .collect()
        };
        report.chunks_unsplit = inputs.len();
        if self.options.pc_split_work > 0 {
            let tp = std::time::Instant::now();
            inputs = split_heavy_chunks(inputs, w, self.options.pc_split_work, |pixels| {
                // The probe: every PROBE_STEP-th pixel's receiver in x and
                // y, the first triangles in cast order; its work, the
                // triangles that reached each receiver's leaf.
                let probe: Vec<u32> = pixels
                    .iter()
                    .copied()
                    .filter(|&i| (i % w) % PROBE_STEP == 0 && (i / w) % PROBE_STEP == 0)
                    .collect();
                let pos = probe.iter().map(|&i| receiver_pos(i)).collect();
                let set = probe.iter().map(|&i| receiver_set(i)).collect();
                let keys = receiver_keys(&probe);
                let mut chunk = Chunk::new(&sets, sw, slack, pos, set, keys, false);
                let first = tris.len().div_ceil(PROBE_SHARE);
                for ((t, v), &b) in tris[..first].iter().zip(&vl[..first]).zip(&open_back) {
                    chunk.process(t, v, b);
                }
                // (The chunk keeps its receivers in leaf order: receiver
                // `r` is probe receiver `order[r]`.)
                chunk
                    .order
                    .iter()
                    .zip(&chunk.leaf_triangles)
                    .map(|(&o, &n)| (probe[o as usize], u64::from(n)))
                    .collect()
            });
            report.probe_time = tp.elapsed();
        }
        report.chunks = inputs.len();
        report.receivers = inputs.iter().map(|c| c.pixels.len()).sum();

        let mut waves: Vec<Vec<ChunkInput>> = Vec::new();
        let mut bytes = 0u64;
        for c in inputs {
            let b = c.pixels.len() as u64 * per_receiver;
            if waves.is_empty() || bytes + b > budget {
                waves.push(Vec::new());
                bytes = 0;
            }
            bytes += b;
            waves.last_mut().expect("a wave").push(c);
        }
        report.waves = waves.len();

        for wave in waves {
            let tb = std::time::Instant::now();
            let mut chunks: Vec<(Vec<u32>, Chunk)> = wave
                .into_par_iter()
                .map(|c| {
                    let pos = c.pixels.iter().map(|&i| receiver_pos(i)).collect();
                    let set = c.pixels.iter().map(|&i| receiver_set(i)).collect();
                    let keys = receiver_keys(&c.pixels);
                    let mut chunk = Chunk::new(&sets, sw, slack, pos, set, keys, projector);
                    if any_open_back {
                        chunk.seal(&caps, &open_boxes);
                    }
                    let pixels = chunk.order.iter().map(|&o| c.pixels[o as usize]).collect();
                    (pixels, chunk)
                })
                .collect();
            report.build_time += tb.elapsed();
            let tc = std::time::Instant::now();
            chunks.par_iter_mut().for_each(|(_, c)| {
                for ((t, v), &b) in tris.iter().zip(&vl).zip(&open_back) {
                    c.process(t, v, b);
                }
            });
            report.cast_time += tc.elapsed();
            let mut wave_masks = 0u64;
            for (_, c) in &chunks {
                let s = &c.stats;
                report.stats.rebuilds += s.rebuilds;
                report.stats.peak_nodes += s.peak_nodes;
                report.stats.peak_hierarchy_bytes += s.peak_hierarchy_bytes;
                report.stats.peak_masks += s.peak_masks;
                report.stats.masked += s.masked;
                report.stats.build_time += s.build_time;
                report.stats.volumes_built += s.volumes_built;
                report.stats.peak_sample_receivers += c.peak_sample_receivers();
                report.sealed += c.sealed_count();
                report.volume_bytes += c.volume_bytes();
                wave_masks += s.peak_masks as u64 * c.mask_bytes();
            }
            report.peak_mask_bytes = report.peak_mask_bytes.max(wave_masks);
            let tt = std::time::Instant::now();
            let records: Vec<Option<translucent::Records>> = chunks
                .par_iter_mut()
                .map(|(px, c)| {
                    let own = c.take_samples();
                    (!casters.is_empty()).then(|| {
                        let origins: Vec<Vec3> = px
                            .iter()
                            .map(|&i| {
                                let s = gb.sample(i as usize);
                                origin.of(s.position, s.geo_normal)
                            })
                            .collect();
                        translucent::cast(
                            c,
                            own,
                            &sets,
                            &casters,
                            ctx.scene,
                            self.options.opacity_filter,
                            &origins,
                            slack,
                            sw.simd,
                        )
                    })
                })
                .collect();
            report.translucent_time += tt.elapsed();
            let (mut rb, mut hb) = (0u64, 0u64);
            for r in records.iter().flatten() {
                report.translucent.recorded += r.recorded;
                report.translucent.time += r.time;
                rb += r.bytes();
                hb += r.hierarchy_bytes;
            }
            report.translucent.record_bytes = report.translucent.record_bytes.max(rb);
            report.translucent.hierarchy_bytes = report.translucent.hierarchy_bytes.max(hb);
            chunks
                .par_iter()
                .zip(records.par_iter())
                .for_each(|((px, c), r)| {
                    let tr = Tr {
                        casters: &casters,
                        records: r.as_ref(),
                    };
                    finish(&sets, px, c, &tr)
                });
        }
        Ok((sets, report))
    }

    /// Every receiver's blocked relations for light `k` (checks and
    /// tests).
    pub fn light_masks(&self, ctx: &ShadowContext, k: usize) -> Result<LightMasks> {
        let n = ctx.gbuffer.len();
        type Row = (u32, u16, Vec<u32>, (u128, bool), Vec<f64>);
        let out = std::sync::Mutex::new(Vec::<Row>::new());
        let (sets, report) = self.run_light(ctx, k, |sets, px, c, tr| {
            let mut words = Vec::new();
            let mut local = Vec::with_capacity(px.len());
            for (r, &i) in px.iter().enumerate() {
                c.words(r, &mut words);
                let vt = if tr.any() {
                    (0..sets.n)
                        .map(|slot| {
                            tr.vt(r, slot, (words[slot / GROUP] >> (slot % GROUP)) & 1 == 1)
                        })
                        .collect()
                } else {
                    Vec::new()
                };
                local.push((
                    i,
                    c.set[r],
                    words.clone(),
                    (c.group_umbra[r], c.full[r]),
                    vt,
                ));
            }
            out.lock().expect("no panic").extend(local);
        })?;
        let g = sets.groups;
        let translucent = report.translucent.layers + report.translucent.mattes > 0;
        let mut masks = LightMasks {
            set: vec![None; n],
            words: vec![0; n * g],
            umbra: vec![(0, false); n],
            transmittance: if translucent {
                vec![1.0; n * sets.n]
            } else {
                Vec::new()
            },
            report,
            sets,
        };
        let sn = masks.sets.n;
        for (i, set, words, umbra, vt) in out.into_inner().expect("no panic") {
            let i = i as usize;
            masks.set[i] = Some(set);
            masks.words[i * g..(i + 1) * g].copy_from_slice(&words);
            masks.umbra[i] = umbra;
            if translucent {
                masks.transmittance[i * sn..(i + 1) * sn].copy_from_slice(&vt);
            }
        }
        Ok(masks)
    }

    /// Runs every light and reports each.
    pub fn compute_with_report(
        &self,
        ctx: &ShadowContext,
    ) -> Result<(ShadowOutput, Vec<LightReport>)> {
        self.check()?;
        let mut out = ShadowOutput::default();
        let mut layer = Layer {
            name: "pc_leaf_triangles".into(),
            channels: Vec::new(),
        };
        let mut reports = Vec::new();
        let len = ctx.gbuffer.len();
        let w = ctx.gbuffer.width.max(1) as usize;
        let eye = ctx.view.eye.as_vec3();
        for k in 0..ctx.scene.lights.len() {
            let t = PassTimer::start(format!("penumbra casting light {k}"));
            let light = &ctx.scene.lights[k];
            let prepared = PreparedLight::new(light, &ctx.scene.textures);
            type Px = (u32, f32, Vec3, u32);
            let results = std::sync::Mutex::new(Vec::<Vec<Px>>::new());
            let (sets, report) = self.run_light(ctx, k, |sets, px, c, tr| {
                let n = sets.n;
                let mut words = Vec::new();
                let mut vis = vec![1.0f32; n];
                let mut vt = vec![1.0f64; n];
                let mut buf = Vec::new();
                let mut local = Vec::with_capacity(px.len());
                for (r, &i) in px.iter().enumerate() {
                    let set = c.set[r] as usize;
                    c.words(r, &mut words);
                    vis.iter_mut().for_each(|v| *v = 1.0);
                    let vcoef = if tr.any() {
                        for (slot, &orig) in sets.order[set].iter().enumerate() {
                            let blocked = (words[slot / GROUP] >> (slot % GROUP)) & 1 == 1;
                            vt[orig as usize] = tr.vt(r, slot, blocked);
                            vis[orig as usize] = vt[orig as usize] as f32;
                        }
                        // The reference's sum: f64, in sample order.
                        let sum = vt.iter().fold(0.0f64, |a, &b| a + b);
                        (sum / n as f64) as f32
                    } else {
                        let mut visible = n;
                        for (slot, &orig) in sets.order[set].iter().enumerate() {
                            if (words[slot / GROUP] >> (slot % GROUP)) & 1 == 1 {
                                vis[orig as usize] = 0.0;
                                visible -= 1;
                            }
                        }
                        (visible as f64 / n as f64) as f32
                    };
                    let g = ctx.gbuffer.sample(i as usize);
                    let key = SampleKey {
                        position: g.position,
                        pixel: (i % w as u32, i / w as u32),
                    };
                    let rad = prepared.direct_from_samples(
                        &surface_point(ctx.scene, &g, eye),
                        sets.samples_for(set, key, &mut buf),
                        &vis,
                    );
                    local.push((i, vcoef, rad, c.leaf_triangles[r]));
                }
                results.lock().expect("no panic").push(local);
            })?;
            let mut vcoef = vec![0.0f32; len];
            let mut radiance = vec![Vec3::ZERO; len];
            let mut leaf = vec![0.0f32; len];
            for (i, v, r, l) in results
                .into_inner()
                .expect("no panic")
                .into_iter()
                .flatten()
            {
                vcoef[i as usize] = v;
                radiance[i as usize] = r;
                leaf[i as usize] = l as f32;
            }
            // Surface pixels that receive no shadows: every sample visible;
            // inside a sphere light: no samples, Vcoef 1 and no radiance,
            // as the reference leaves them.
            let all_visible = vec![1.0f32; sets.n];
            let mut buf = Vec::new();
            for i in 0..len {
                let Some(g) = ctx.gbuffer.get(i) else {
                    continue;
                };
                if !g.is_surface() {
                    continue;
                }
                if !sets.has_samples(g.position) {
                    vcoef[i] = 1.0;
                    radiance[i] = Vec3::ZERO;
                } else if !receives(ctx, g.object) {
                    let pixel = ((i % w) as u32, (i / w) as u32);
                    let set = sets.set_of(pixel);
                    let key = SampleKey {
                        position: g.position,
                        pixel,
                    };
                    vcoef[i] = 1.0;
                    radiance[i] = prepared.direct_from_samples(
                        &surface_point(ctx.scene, &g, eye),
                        sets.samples_for(set, key, &mut buf),
                        &all_visible,
                    );
                }
            }
            t.finish_with(
                &mut out.passes,
                format!(
                    "sort {:.3} s, probe {:.3} s, build {:.3} s, cast {:.3} s, translucent {:.3} s",
                    report.sort_time.as_secs_f64(),
                    report.probe_time.as_secs_f64(),
                    report.build_time.as_secs_f64(),
                    report.cast_time.as_secs_f64(),
                    report.translucent_time.as_secs_f64()
                ),
            );
            layer.channels.push((k.to_string(), leaf));
            self.notes(k, &sets, &report, &mut out.buffers);
            out.lights.push(LightTerm::Radiance { radiance, vcoef });
            reports.push(report);
        }
        out.layers.push(layer);
        Ok((out, reports))
    }

    fn notes(&self, k: usize, sets: &SampleSets, r: &LightReport, notes: &mut Vec<BufferNote>) {
        let o = &self.options;
        notes.push(BufferNote {
            name: format!("receiver hierarchy light {k}"),
            detail: format!(
                "{} receivers in {} chunks ({} of {}² px, {} after splitting the heavy ones by a \
                 probe of {:.3} s) in {} wave(s); {} nodes at peak (leaves ≤ {}, \
                 spatial median above {} points, least surface area below); {} rebuild(s) at > {} % \
                 in umbra, {:.3} s building (CPU)",
                r.receivers,
                r.chunks,
                r.chunks_unsplit,
                r.chunk_side,
                r.chunks,
                r.probe_time.as_secs_f64(),
                r.waves,
                r.stats.peak_nodes,
                hierarchy::LEAF,
                hierarchy::SPATIAL_ABOVE,
                r.stats.rebuilds,
                o.pc_rebuild_percent,
                r.stats.build_time.as_secs_f64()
            ),
            bytes: r.stats.peak_hierarchy_bytes + r.receivers as u64 * 64,
        });
        notes.push(BufferNote {
            name: format!("bit masks light {k}"),
            detail: format!(
                "{} bits per receiver ({} groups of ≤ 32), {}; {} receivers ever masked, {} at the \
                 chunks' summed peaks",
                sets.n,
                sets.groups,
                if o.pc_on_demand_masks {
                    "allocated on demand, freed at full umbra"
                } else {
                    "allocated for every receiver"
                },
                r.stats.masked,
                r.stats.peak_masks
            ),
            bytes: r.peak_mask_bytes,
        });
        notes.push(BufferNote {
            name: format!("light sample sets light {k}"),
            detail: format!(
                "{} set(s) of {} samples{}; {} triangles cast ({} back faces of closed casters \
                 skipped{}), {} volume builds; their light penumbra volumes {:.2} MiB, held for \
                 the whole cast",
                sets.sets,
                sets.n,
                if sets.per_receiver() {
                    format!(
                        " (sphere light: each receiver its own, the reference's, made on first \
                         need; {} receivers held theirs at the chunks' summed peaks, {} bytes \
                         each; the groups bounded by the light's box)",
                        r.stats.peak_sample_receivers,
                        ReceiverSamples::bytes_per_receiver(sets.groups, false)
                    )
                } else if self.matches_reference(sets) {
                    " (every receiver gets the reference's samples)".to_string()
                } else {
                    ", assigned per receiver by a pixel hash".to_string()
                },
                r.triangles,
                r.culled,
                if r.open_back > 0 {
                    format!(
                        "; {} of open casters cast only into the {} receivers not sealed \
                         against their holes, by {} closing triangles",
                        r.open_back,
                        r.receivers - r.sealed,
                        r.caps
                    )
                } else {
                    String::new()
                },
                r.stats.volumes_built,
                r.volume_list_bytes as f64 / f64::from(1 << 20)
            ),
            bytes: sets.bytes() + r.volume_bytes + r.volume_list_bytes,
        });
        let t = &r.translucent;
        if t.layers + t.mattes > 0 {
            notes.push(BufferNote {
                name: format!("translucent records light {k}"),
                detail: format!(
                    "{} semi-opaque triangles, {} S-triangles ({} look-ups) cast after the opaque \
                     ones; {} receivers got a record of {} bytes per sample (u16 layer counts per \
                     opacity group, f64 optical depth for S-triangles), the largest wave's shown; \
                     {:.3} s (wall), second hierarchy {} bytes",
                    t.layers,
                    t.mattes,
                    match o.opacity_filter {
                        Filter::Nearest => "nearest",
                        Filter::Bilinear => "bilinear",
                    },
                    t.recorded,
                    t.bytes_per_sample,
                    r.translucent_time.as_secs_f64(),
                    t.hierarchy_bytes
                ),
                bytes: t.record_bytes + t.hierarchy_bytes,
            });
        }
    }
}

impl SampleDecisions for PenumbraCasting {
    /// Per sample: 1 − its blocked bit, from the light's masks, or its
    /// `V·T` where the scene has translucent casters.
    fn sample_visibility(
        &self,
        ctx: &ShadowContext,
        light: usize,
        pixels: &[usize],
    ) -> Result<Vec<PixelVisibility>> {
        let m = self.light_masks(ctx, light)?;
        let g = m.sets.groups;
        let w = ctx.gbuffer.width.max(1) as usize;
        let mut buf = Vec::new();
        Ok(pixels
            .iter()
            .filter_map(|&i| {
                let set = usize::from((*m.set.get(i)?)?);
                let key = SampleKey {
                    position: ctx.gbuffer.sample(i).position,
                    pixel: ((i % w) as u32, (i / w) as u32),
                };
                let words = &m.words[i * g..(i + 1) * g];
                let mut visibility = vec![1.0; m.sets.n];
                let vt = m.transmittance.get(i * m.sets.n..(i + 1) * m.sets.n);
                for (slot, &orig) in m.sets.order[set].iter().enumerate() {
                    if let Some(vt) = vt {
                        visibility[orig as usize] = vt[slot];
                    } else if (words[slot / GROUP] >> (slot % GROUP)) & 1 == 1 {
                        visibility[orig as usize] = 0.0;
                    }
                }
                Some(PixelVisibility {
                    pixel: i,
                    samples: m.sets.samples_for(set, key, &mut buf).to_vec(),
                    visibility,
                })
            })
            .collect())
    }
}

impl ShadowTechnique for PenumbraCasting {
    fn name(&self) -> &'static str {
        "penumbra-casting"
    }

    fn sample_decisions(&self) -> Option<&dyn SampleDecisions> {
        Some(self)
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        Ok(self.compute_with_report(ctx)?.0)
    }
}

/// Whether object `object` receives shadows (unknown objects do, as for
/// the reference).
fn receives(ctx: &ShadowContext, object: u32) -> bool {
    ctx.scene
        .objects
        .get(object as usize)
        .is_none_or(|o| o.receive_shadows)
}

/// Coarse blocker sorting (§3.3): buckets by `⌊log2(max area / area)⌋`
/// (32 buckets, the last catching the rest), largest first, stable.
fn sort_by_area<T: Clone>(tris: Vec<([DVec3; 3], T)>) -> Vec<([DVec3; 3], T)> {
    const BUCKETS: usize = 32;
    let area = |t: &([DVec3; 3], T)| (t.0[1] - t.0[0]).cross(t.0[2] - t.0[0]).length();
    let max = tris.iter().map(area).fold(0.0f64, f64::max);
    if !(max > 0.0) {
        return tris;
    }
    let bucket = |t: &([DVec3; 3], T)| -> usize {
        let r = max / area(t);
        if !(r.is_finite()) {
            BUCKETS - 1
        } else {
            (r.log2().floor().max(0.0) as usize).min(BUCKETS - 1)
        }
    };
    let mut out: Vec<Vec<([DVec3; 3], T)>> = vec![Vec::new(); BUCKETS];
    for t in tris {
        out[bucket(&t)].push(t);
    }
    out.into_iter().flatten().collect()
}

#[cfg(test)]
mod tests {
    use super::chunk_side;

    /// The chunk side is the largest divisor of the option within half
    /// the budget, down to one pixel.
    #[test]
    fn chunk_side_is_the_largest_divisor_within_the_budget() {
        let gib = 1u64 << 30;
        assert_eq!(chunk_side(256, 36, gib), 256);
        // 4096 samples of a sphere light: 155,008 bytes a receiver.
        assert_eq!(chunk_side(256, 155_008, gib), 32);
        assert_eq!(chunk_side(100, 155_008, gib), 50);
        assert_eq!(chunk_side(7, 1 << 40, 1), 1);
        assert_eq!(chunk_side(0, 1, 1), 1);
    }
}
