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
    ///
    /// In stages: the light's sample sets (`light_sets`), the blockers
    /// (`blockers`), the translucent casters, the chunks of receivers
    /// (`chunk_inputs`, split where heavy), their waves within the mask
    /// budget (`waves`), and per wave the cast (`LightCast::run_wave`).
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
        let (centre, sets) = self.light_sets(light, k);
        let mut report = LightReport::default();

        // Triangles: opaque casters, non-degenerate, relative to the light.
        let sort_start = std::time::Instant::now();
        let blockers = self.blockers(ctx, &sets, centre, &mut report);
        report.sort_time = sort_start.elapsed();
        report.triangles = blockers.tris.len();
        report.caps = blockers.cap_tris.len();

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
        let receivers = ReceiverInputs {
            gbuffer: ctx.gbuffer,
            origin: ShadowOrigin::new(ctx.scene, ctx.geometry),
            centre,
            sets: &sets,
            width: ctx.gbuffer.width.max(1),
        };
        let mut inputs = receivers.chunk_inputs(ctx, side);
        // Every blocker's light penumbra volume, made once (in parallel)
        // and held for all chunks of all waves: each chunk then runs
        // through the whole list on its own. (Batches of volumes with a
        // barrier after each let the chunk under a dense caster hold both
        // workers at every batch: on bunny.toml at 1280×960 one 256²
        // chunk took 10.4 s of the 17.8 s summed over all.)
        let volume_start = std::time::Instant::now();
        let volumes = penumbra_volumes(&sets, &blockers.tris);
        let caps = penumbra_volumes(&sets, &blockers.cap_tris);
        report.volume_list_bytes = volumes.iter().map(PenumbraVolume::bytes).sum();
        report.cast_time += volume_start.elapsed();
        let cast = LightCast {
            sets: &sets,
            switches: self.options.switches(),
            blockers: &blockers,
            volumes: &volumes,
            caps: &caps,
            casters: &casters,
            receivers: &receivers,
            projector,
            any_open_back: report.open_back > 0,
            opacity_filter: self.options.opacity_filter,
            scene: ctx.scene,
        };
        report.chunks_unsplit = inputs.len();
        if self.options.pc_split_work > 0 {
            let probe_start = std::time::Instant::now();
            inputs = split_heavy_chunks(
                inputs,
                receivers.width,
                self.options.pc_split_work,
                |pixels| cast.probe(pixels),
            );
            report.probe_time = probe_start.elapsed();
        }
        report.chunks = inputs.len();
        report.receivers = inputs.iter().map(|c| c.pixels.len()).sum();

        let waves = waves(inputs, per_receiver, budget);
        report.waves = waves.len();
        for wave in waves {
            // The render discards a cancelled pass: later waves are skipped.
            if ctx.observer.cancelled() {
                break;
            }
            cast.run_wave(wave, &mut report, &finish);
        }
        Ok((sets, report))
    }

    /// Light `light`'s (number `k`) centre and sample sets.
    fn light_sets(&self, light: &crate::scene::Light, k: usize) -> (DVec3, SampleSets) {
        let sampler = LightSampler::new(light);
        let pattern = PatternSampler::new(self.pattern, self.samples, self.seed, k);
        match light.shape {
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
        }
    }

    /// The opaque blocker triangles of the light of `sets` (relative to
    /// its `centre`), in cast order, with the surfaces closing the open
    /// casters whose back faces are cast only into sealed receivers; the
    /// culled, open-back and cap counts go to `report`.
    fn blockers(
        &self,
        ctx: &ShadowContext,
        sets: &SampleSets,
        centre: DVec3,
        report: &mut LightReport,
    ) -> Blockers {
        let geometry = ctx.geometry;
        let object_box = object_boxes(ctx, centre);
        let cullable = self.cullable_objects(ctx, sets, &object_box);
        // Opaque caster triangles with area: object, corners, and whether
        // the caster may be culled and the light is wholly behind it.
        let candidates: Vec<(usize, [DVec3; 3], bool)> = (0..geometry.triangles.len())
            .filter_map(|t| {
                let object = geometry.triangle_object[t] as usize;
                let casts = ctx
                    .scene
                    .objects
                    .get(object)
                    .is_some_and(|o| o.cast_shadows);
                let material = ctx
                    .scene
                    .materials
                    .get(geometry.triangle_material[t] as usize);
                if !(casts && material.is_some_and(|m| m.is_opaque())) {
                    return None;
                }
                let tri = geometry.triangles[t]
                    .map(|i| geometry.positions[i as usize].as_dvec3() - centre);
                let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
                if !(normal.length_squared() > 0.0) {
                    return None;
                }
                let back = cullable[object]
                    && sets
                        .light
                        .corners
                        .iter()
                        .all(|c| normal.dot(*c - tri[0]) < 0.0);
                Some((object, tri, back))
            })
            .collect();
        let slack = 1e-10 * scene_diagonal(ctx.scene, ctx.geometry);
        let closed = |o: usize| geometry.object_closed.get(o) == Some(&true);
        let open = open_casters(ctx, centre, &candidates, &object_box, slack);
        // Per triangle cast: it and whether it is an open caster's back
        // face (cast only where receivers are not sealed); closed
        // casters' back faces are left out.
        let tris: Vec<([DVec3; 3], bool)> = candidates
            .into_iter()
            .filter_map(|(object, tri, back)| {
                if back && closed(object) {
                    report.culled += 1;
                    return None;
                }
                let open_back = back && open.open[object];
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
        Blockers {
            tris,
            open_back,
            cap_tris: open.cap_tris,
            open_boxes: open.boxes,
            slack,
        }
    }

    /// Per object (boxes `object_box`, relative to the light's centre):
    /// whether its back faces may be culled. Back faces may be skipped
    /// only for closed casters the light is outside of (a sample on a
    /// caster's surface sees only its exit crossing): those whose
    /// bounding box is disjoint from the light's.
    fn cullable_objects(
        &self,
        ctx: &ShadowContext,
        sets: &SampleSets,
        object_box: &[(DVec3, DVec3)],
    ) -> Vec<bool> {
        let geometry = ctx.geometry;
        let cull = self.options.pc_cull_back_faces;
        let (light_lo, light_hi) = sets
            .light
            .corners
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), c| {
                (lo.min(*c), hi.max(*c))
            });
        let light_outside: Vec<bool> = object_box
            .iter()
            .map(|&(lo, hi)| {
                let margin = 1e-6
                    * (hi - lo)
                        .max_element()
                        .max((light_hi - light_lo).max_element());
                (lo - DVec3::splat(margin)).cmpgt(light_hi).any()
                    || (hi + DVec3::splat(margin)).cmplt(light_lo).any()
            })
            .collect();
        // The argument needs every face of the caster to block: one with a
        // see-through face (a semi-opaque or textured material) is never
        // culled, as its exit crossing may be that face.
        let mut all_opaque = vec![true; ctx.scene.objects.len()];
        for t in 0..geometry.triangles.len() {
            let material = ctx
                .scene
                .materials
                .get(geometry.triangle_material[t] as usize);
            if !material.is_some_and(|m| m.is_opaque()) {
                if let Some(a) = all_opaque.get_mut(geometry.triangle_object[t] as usize) {
                    *a = false;
                }
            }
        }
        (0..ctx.scene.objects.len())
            .map(|o| {
                cull && light_outside.get(o) == Some(&true) && all_opaque.get(o) == Some(&true)
            })
            .collect()
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

/// The blocker triangles of one light's pass ([`PenumbraCasting::blockers`]),
/// relative to the light's centre.
struct Blockers {
    /// The opaque caster triangles cast, in cast order.
    tris: Vec<[DVec3; 3]>,
    /// Per triangle: whether it is an open caster's back face (cast only
    /// into receivers that are not sealed).
    open_back: Vec<bool>,
    /// The surfaces closing the open casters.
    cap_tris: Vec<[DVec3; 3]>,
    /// The open casters' boxes, widened by `slack`.
    open_boxes: Vec<([f64; 3], [f64; 3])>,
    /// The penumbra volumes' margin (relative to the scene's diagonal).
    slack: f64,
}

/// Per object, its geometry's bounding box relative to the light's
/// `centre` (empty where it has no triangle).
fn object_boxes(ctx: &ShadowContext, centre: DVec3) -> Vec<(DVec3, DVec3)> {
    let geometry = ctx.geometry;
    let mut object_box = vec![(DVec3::INFINITY, DVec3::NEG_INFINITY); ctx.scene.objects.len()];
    for (t, tri) in geometry.triangles.iter().enumerate() {
        if let Some(b) = object_box.get_mut(geometry.triangle_object[t] as usize) {
            for &i in tri {
                let p = geometry.positions[i as usize].as_dvec3() - centre;
                *b = (b.0.min(p), b.1.max(p));
            }
        }
    }
    object_box
}

/// The open casters whose back faces are cast only into sealed
/// receivers ([`open_casters`]).
struct OpenCasters {
    /// Per object: whether it is one.
    open: Vec<bool>,
    /// The surfaces closing them.
    cap_tris: Vec<[DVec3; 3]>,
    /// Their boxes, widened.
    boxes: Vec<([f64; 3], [f64; 3])>,
}

/// Open casters: the surfaces closing them (a fan per boundary loop, in
/// welded positions) and their boxes (`object_box`, widened by `slack`).
/// Only where the caps are few against the back faces of `candidates`
/// they let skip (a sheet, whose cap is itself reversed, seals nothing).
fn open_casters(
    ctx: &ShadowContext,
    centre: DVec3,
    candidates: &[(usize, [DVec3; 3], bool)],
    object_box: &[(DVec3, DVec3)],
    slack: f64,
) -> OpenCasters {
    let geometry = ctx.geometry;
    let closed = |o: usize| geometry.object_closed.get(o) == Some(&true);
    let mut open_backs = vec![0usize; ctx.scene.objects.len()];
    for &(object, _, back) in candidates {
        open_backs[object] += usize::from(back && !closed(object));
    }
    let mut open = vec![false; ctx.scene.objects.len()];
    let mut cap_tris = Vec::new();
    let mut boxes = Vec::new();
    for (object, &backs) in open_backs.iter().enumerate().filter(|(_, &b)| b > 0) {
        let at = |v: u32| geometry.adjacency().positions[v as usize].as_dvec3() - centre;
        let mut caps = Vec::new();
        for boundary in geometry.adjacency().boundary_loops(geometry, object as u32) {
            for i in 1..boundary.len().saturating_sub(1) {
                let tri = [at(boundary[0]), at(boundary[i + 1]), at(boundary[i])];
                // A cap with no area is crossed by no segment.
                if (tri[1] - tri[0]).cross(tri[2] - tri[0]).length_squared() > 0.0 {
                    caps.push(tri);
                }
            }
        }
        if caps.len() * OPEN_CAPS_PER_BACK_FACE < backs {
            open[object] = true;
            cap_tris.extend(caps);
            let (lo, hi) = object_box[object];
            let (lo, hi) = (lo - DVec3::splat(slack), hi + DVec3::splat(slack));
            boxes.push((lo.to_array(), hi.to_array()));
        }
    }
    OpenCasters {
        open,
        cap_tris,
        boxes,
    }
}

/// The light penumbra volume of each of `tris` with the light of `sets`,
/// made in parallel.
fn penumbra_volumes(sets: &SampleSets, tris: &[[DVec3; 3]]) -> Vec<PenumbraVolume> {
    let mut volumes: Vec<PenumbraVolume> = Vec::new();
    volumes.resize_with(tris.len(), PenumbraVolume::default);
    tris.par_iter()
        .zip(volumes.par_iter_mut())
        .for_each(|(t, v)| penumbra_volume(&sets.light, t, v));
    volumes
}

/// `inputs` in waves, in order, each within `budget` bytes at
/// `per_receiver` bytes a receiver (a chunk alone above it is a wave).
fn waves(inputs: Vec<ChunkInput>, per_receiver: u64, budget: u64) -> Vec<Vec<ChunkInput>> {
    let mut waves: Vec<Vec<ChunkInput>> = Vec::new();
    let mut bytes = 0u64;
    for chunk in inputs {
        let chunk_bytes = chunk.pixels.len() as u64 * per_receiver;
        if waves.is_empty() || bytes + chunk_bytes > budget {
            waves.push(Vec::new());
            bytes = 0;
        }
        bytes += chunk_bytes;
        waves.last_mut().expect("a wave").push(chunk);
    }
    waves
}

/// Where one light's receivers are: the chunks' inputs.
struct ReceiverInputs<'s> {
    gbuffer: &'s crate::gbuffer::GBuffer,
    /// The shadow-ray origin rule (the reference's).
    origin: ShadowOrigin,
    /// The light's centre, the receivers' origin.
    centre: DVec3,
    sets: &'s SampleSets,
    /// The screen's width (at least 1).
    width: u32,
}

impl ReceiverInputs<'_> {
    /// Every receiver, by square screen chunk of `side` pixels (those
    /// without a receiver left out).
    fn chunk_inputs(&self, ctx: &ShadowContext, side: u32) -> Vec<ChunkInput> {
        let gbuffer = self.gbuffer;
        let (width, height) = (self.width, gbuffer.height);
        let (chunks_x, chunks_y) = (width.div_ceil(side), height.div_ceil(side));
        let mut inputs: Vec<ChunkInput> = (0..chunks_x * chunks_y)
            .map(|c| ChunkInput {
                pixels: Vec::new(),
                x0: c % chunks_x * side,
                y0: c / chunks_x * side,
                side,
            })
            .collect();
        for i in 0..gbuffer.len() {
            let Some(s) = gbuffer.get(i) else { continue };
            // (A receiver inside a sphere light has no samples: it is
            // finished with the non-receivers.)
            if !s.is_surface() || !receives(ctx, s.object) || !self.sets.has_samples(s.position) {
                continue;
            }
            let (x, y) = (i as u32 % width, i as u32 / width);
            inputs[((y / side) * chunks_x + x / side) as usize]
                .pixels
                .push(i as u32);
        }
        inputs.retain(|c| !c.pixels.is_empty());
        inputs
    }

    /// Pixel `i`'s shadow-ray origin, relative to the light's centre.
    fn position(&self, i: u32) -> [f64; 3] {
        let s = self.gbuffer.sample(i as usize);
        let o = self.origin.of(s.position, s.geo_normal).as_dvec3() - self.centre;
        [o.x, o.y, o.z]
    }

    /// Pixel `i`'s sample set.
    fn set(&self, i: u32) -> u16 {
        self.sets.set_of((i % self.width, i / self.width)) as u16
    }

    /// The sample keys of `pixels`, only where receivers have samples of
    /// their own.
    fn keys(&self, pixels: &[u32]) -> Vec<SampleKey> {
        if !self.sets.per_receiver() {
            return Vec::new();
        }
        pixels
            .iter()
            .map(|&i| SampleKey {
                position: self.gbuffer.sample(i as usize).position,
                pixel: (i % self.width, i / self.width),
            })
            .collect()
    }

    /// The `f32` shadow-ray origins of `pixels` (the translucent pass's
    /// projector reads them).
    fn origins(&self, pixels: &[u32]) -> Vec<Vec3> {
        pixels
            .iter()
            .map(|&i| {
                let s = self.gbuffer.sample(i as usize);
                self.origin.of(s.position, s.geo_normal)
            })
            .collect()
    }
}

/// What every chunk of one light's pass reads.
struct LightCast<'l> {
    sets: &'l SampleSets,
    switches: Switches,
    blockers: &'l Blockers,
    /// The blockers' light penumbra volumes.
    volumes: &'l [PenumbraVolume],
    /// The caps' light penumbra volumes.
    caps: &'l [PenumbraVolume],
    casters: &'l translucent::Casters,
    receivers: &'l ReceiverInputs<'l>,
    /// Whether the S-triangles' projector reads the samples' positions.
    projector: bool,
    /// Whether some open caster's back faces are cast.
    any_open_back: bool,
    opacity_filter: Filter,
    scene: &'l crate::scene::Scene,
}

impl LightCast<'_> {
    /// The probe of a chunk of `pixels`: every PROBE_STEP-th pixel's
    /// receiver in x and y, the first triangles in cast order; its work,
    /// the triangles that reached each receiver's leaf.
    fn probe(&self, pixels: &[u32]) -> Vec<(u32, u64)> {
        let (receivers, blockers) = (self.receivers, self.blockers);
        let width = receivers.width;
        let probe: Vec<u32> = pixels
            .iter()
            .copied()
            .filter(|&i| (i % width) % PROBE_STEP == 0 && (i / width) % PROBE_STEP == 0)
            .collect();
        let pos = probe.iter().map(|&i| receivers.position(i)).collect();
        let set = probe.iter().map(|&i| receivers.set(i)).collect();
        let keys = receivers.keys(&probe);
        let mut chunk = Chunk::new(
            self.sets,
            self.switches,
            blockers.slack,
            pos,
            set,
            keys,
            false,
        );
        let first = blockers.tris.len().div_ceil(PROBE_SHARE);
        for ((tri, volume), &open_back) in blockers.tris[..first]
            .iter()
            .zip(&self.volumes[..first])
            .zip(&blockers.open_back)
        {
            chunk.process(tri, volume, open_back);
        }
        // (The chunk keeps its receivers in leaf order: receiver `r` is
        // probe receiver `order[r]`.)
        chunk
            .order
            .iter()
            .zip(&chunk.leaf_triangles)
            .map(|(&o, &n)| (probe[o as usize], u64::from(n)))
            .collect()
    }

    /// One wave's chunks: built, cast into by every blocker, their
    /// translucent records made, then each handed to `finish`; measures
    /// into `report`.
    fn run_wave<F>(&self, wave: Vec<ChunkInput>, report: &mut LightReport, finish: &F)
    where
        F: Fn(&SampleSets, &[u32], &Chunk, &Tr) + Sync,
    {
        let build_start = std::time::Instant::now();
        let mut chunks = self.build_chunks(wave);
        report.build_time += build_start.elapsed();
        let cast_start = std::time::Instant::now();
        let blockers = self.blockers;
        chunks.par_iter_mut().for_each(|(_, chunk)| {
            for ((tri, volume), &open_back) in blockers
                .tris
                .iter()
                .zip(self.volumes)
                .zip(&blockers.open_back)
            {
                chunk.process(tri, volume, open_back);
            }
        });
        report.cast_time += cast_start.elapsed();
        let mut wave_masks = 0u64;
        for (_, chunk) in &chunks {
            let stats = &chunk.stats;
            report.stats.rebuilds += stats.rebuilds;
            report.stats.peak_nodes += stats.peak_nodes;
            report.stats.peak_hierarchy_bytes += stats.peak_hierarchy_bytes;
            report.stats.peak_masks += stats.peak_masks;
            report.stats.masked += stats.masked;
            report.stats.build_time += stats.build_time;
            report.stats.volumes_built += stats.volumes_built;
            report.stats.peak_sample_receivers += chunk.peak_sample_receivers();
            report.sealed += chunk.sealed_count();
            report.volume_bytes += chunk.volume_bytes();
            wave_masks += stats.peak_masks as u64 * chunk.mask_bytes();
        }
        report.peak_mask_bytes = report.peak_mask_bytes.max(wave_masks);
        let translucent_start = std::time::Instant::now();
        let records = self.translucent_records(&mut chunks);
        report.translucent_time += translucent_start.elapsed();
        let (mut record_bytes, mut hierarchy_bytes) = (0u64, 0u64);
        for records in records.iter().flatten() {
            report.translucent.recorded += records.recorded;
            report.translucent.time += records.time;
            record_bytes += records.bytes();
            hierarchy_bytes += records.hierarchy_bytes;
        }
        report.translucent.record_bytes = report.translucent.record_bytes.max(record_bytes);
        report.translucent.hierarchy_bytes =
            report.translucent.hierarchy_bytes.max(hierarchy_bytes);
        chunks
            .par_iter()
            .zip(records.par_iter())
            .for_each(|((pixels, chunk), records)| {
                let tr = Tr {
                    casters: self.casters,
                    records: records.as_ref(),
                };
                finish(self.sets, pixels, chunk, &tr)
            });
    }

    /// The wave's chunks (in parallel), each with its pixels in the
    /// chunk's receiver order, sealed where open casters' back faces are
    /// cast.
    fn build_chunks(&self, wave: Vec<ChunkInput>) -> Vec<(Vec<u32>, Chunk<'_>)> {
        let receivers = self.receivers;
        wave.into_par_iter()
            .map(|input| {
                let pos = input
                    .pixels
                    .iter()
                    .map(|&i| receivers.position(i))
                    .collect();
                let set = input.pixels.iter().map(|&i| receivers.set(i)).collect();
                let keys = receivers.keys(&input.pixels);
                let mut chunk = Chunk::new(
                    self.sets,
                    self.switches,
                    self.blockers.slack,
                    pos,
                    set,
                    keys,
                    self.projector,
                );
                if self.any_open_back {
                    chunk.seal(self.caps, &self.blockers.open_boxes);
                }
                let pixels = chunk
                    .order
                    .iter()
                    .map(|&o| input.pixels[o as usize])
                    .collect();
                (pixels, chunk)
            })
            .collect()
    }

    /// Every chunk's translucent records (in parallel; `None` where the
    /// scene has no translucent caster), taking the chunks' own samples.
    fn translucent_records(
        &self,
        chunks: &mut [(Vec<u32>, Chunk<'_>)],
    ) -> Vec<Option<translucent::Records>> {
        chunks
            .par_iter_mut()
            .map(|(pixels, chunk)| {
                let own = chunk.take_samples();
                (!self.casters.is_empty()).then(|| {
                    let origins = self.receivers.origins(pixels);
                    translucent::cast(
                        chunk,
                        own,
                        self.sets,
                        self.casters,
                        self.scene,
                        self.opacity_filter,
                        &origins,
                        self.blockers.slack,
                        self.switches.simd,
                    )
                })
            })
            .collect()
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
