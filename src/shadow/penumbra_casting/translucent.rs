//! The translucent pass: semi-opaque casters (constant opacity in
//! `(0, 1)`) and S-triangles (opacity-textured, the alpha matte of §5),
//! cast after the opaque triangles into the same receivers, giving each
//! (receiver, light sample) relation its exact float transmittance.
//!
//! Per chunk, once every opaque triangle is cast, the receivers not in
//! full umbra get a second hierarchy ([`Hierarchy`]); every translucent
//! triangle's `V_L` culls its nodes and at the leaves each receiver is
//! tested against the group volumes `V_Gk` and then per sample:
//!
//! - a **semi-opaque** triangle of opacity group `g` (the kit's
//!   [`semi_opaque_groups`](crate::shadow::kit::groups::semi_opaque_groups),
//!   as DCS counts them) through the same hard shadow volumes as the
//!   opaque pass: each relation it holds (and that no opaque triangle
//!   blocks) counts one more layer `n_g`;
//! - an **S-triangle** ([`STriangles`](crate::shadow::kit::stsv::STriangles)) through the
//!   [`SampleProjector`] of soft textured shadow volumes: the segment's
//!   crossing barycentrics, the opacity `d × map_d(uv)` there (nearest or
//!   bilinear, `--opacity-filter`), and its optical depth
//!   `−ln(1 − α)` (from `ln_1p`) added to the relation's sum; `α = 1`
//!   adds `+∞` (blocked).
//!
//! A relation's transmittance is then `exp(−(Σ_g n_g τ_g + Σ_s τ_s))`
//! ([`TransmittanceMode::Exact`], DCS's stable form: integer counts per
//! group, so `T = 1` exactly when nothing is crossed). The records are
//! allocated on demand, for the receivers some translucent relation
//! reaches: `2 G` bytes per sample for `G` opacity groups (`u16` counts,
//! saturating at 65535 layers) plus 8 bytes per sample when the scene has
//! S-triangles. Every chunk sees the triangles in the same order (groups,
//! then S-triangles, geometry order), so the sums never depend on the
//! thread count.
//!
//! What differs from the reference's walk (its merge rule counts
//! crossings closer than `MERGE_SCENE × D` along a segment once): a
//! segment through an edge shared by two triangles of one surface is a
//! tie here (the hard volumes are open, so it may count none; the
//! projector is closed, so it may count both), and two coincident
//! translucent surfaces count twice. Neither happens on the shipped
//! scenes beyond ties.

use super::cast::Chunk;
use super::hierarchy::Hierarchy;
use super::samples::{ReceiverSamples, SampleSets, GROUP};
use super::volume::PenumbraVolume;
use super::volume::{hard_bits_scalar, hard_bits_simd, penumbra_volume, BoxTest, HardVolumes};
use crate::scene::Scene;
use crate::shadow::kit::groups::{Attenuation, TransmittanceMode};
use crate::shadow::kit::stsv::{Filter, STriangle, SamplePositions, SampleProjector};
use crate::shadow::ShadowContext;
use glam::{DVec3, Vec3};
use std::time::Duration;

/// No record.
const NONE: u32 = u32::MAX;

/// What a translucent triangle is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// A semi-opaque layer of opacity group `g`.
    Layer(u16),
    /// S-triangle `s` of [`Casters::mattes`].
    Matte(u32),
}

/// The translucent casters of one light, relative to its centre.
#[derive(Debug, Clone, Default)]
pub struct Casters {
    /// Triangles (relative to the light's centre) and what they are.
    pub tris: Vec<([DVec3; 3], Kind)>,
    /// Per opacity group: its optical depth `−ln(1 − α)`.
    pub optical_depth: Vec<f64>,
    /// The S-triangles cast.
    pub mattes: Vec<STriangle>,
    /// Per set and group: the samples' `f32` positions for the projector.
    positions: Vec<Vec<SamplePositions>>,
}

impl Casters {
    /// The translucent casters of `ctx`'s scene (the kit's collections),
    /// relative to `centre`, with the projector's sample layout of `sets`.
    pub fn collect(ctx: &ShadowContext, sets: &SampleSets, centre: DVec3) -> Casters {
        let g = ctx.geometry;
        let mut out = Casters::default();
        let rel = |t: usize| g.triangles[t].map(|i| g.positions[i as usize].as_dvec3() - centre);
        let area = |t: &[DVec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).length_squared() > 0.0;
        for (att, adj) in ctx.cache.semi_opaque_groups() {
            let Attenuation::Partial { optical_depth, .. } = *att else {
                continue;
            };
            let gi = out.optical_depth.len();
            out.optical_depth.push(optical_depth);
            for &f in &adj.faces {
                let t = rel(f as usize);
                if area(&t) {
                    out.tris.push((t, Kind::Layer(gi as u16)));
                }
            }
        }
        for s in &ctx.cache.s_triangles().list {
            let t = s.corners.map(|c| c - centre);
            if area(&t) {
                out.tris.push((t, Kind::Matte(out.mattes.len() as u32)));
                out.mattes.push(*s);
            }
        }
        // (Where receivers have samples of their own, the pass makes
        // their positions per receiver.)
        if !out.mattes.is_empty() && !sets.per_receiver() {
            out.positions = (0..sets.sets)
                .map(|set| {
                    (0..sets.groups)
                        .map(|k| {
                            let slots = GROUP * k..(GROUP * (k + 1)).min(sets.n);
                            let s: Vec<_> = slots
                                .map(|slot| sets.samples[set][sets.order[set][slot] as usize])
                                .collect();
                            let mut p = SamplePositions::default();
                            p.set(&s);
                            p
                        })
                        .collect()
                })
                .collect();
        }
        out
    }

    /// Whether there is nothing to cast.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Opacity groups.
    pub fn groups(&self) -> usize {
        self.optical_depth.len()
    }

    /// Bytes of one receiver's record for `n` samples.
    pub fn record_bytes(&self, n: usize) -> u64 {
        (n * (2 * self.groups() + if self.mattes.is_empty() { 0 } else { 8 })) as u64
    }
}

/// What the translucent pass measured (summed over chunks).
#[derive(Debug, Clone, Default)]
pub struct Stats {
    /// Semi-opaque triangles cast.
    pub layers: usize,
    /// S-triangles cast.
    pub mattes: usize,
    /// Receivers that got a record.
    pub recorded: usize,
    /// Bytes of a record per light sample.
    pub bytes_per_sample: u64,
    /// Bytes of the records (per wave, the largest).
    pub record_bytes: u64,
    /// Hierarchy bytes (summed over the chunks of a wave, the largest).
    pub hierarchy_bytes: u64,
    /// CPU time of the pass, summed over chunks.
    pub time: Duration,
}

/// One chunk's translucent records, after its pass.
pub struct Records {
    n: usize,
    groups: usize,
    mattes: bool,
    slot: Vec<u32>,
    counts: Vec<u16>,
    depth: Vec<f64>,
    /// Receivers recorded.
    pub recorded: usize,
    /// Hierarchy bytes.
    pub hierarchy_bytes: u64,
    /// CPU time.
    pub time: Duration,
}

impl Records {
    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        (self.counts.capacity() * 2 + self.depth.capacity() * 8 + self.slot.capacity() * 4) as u64
    }

    /// The transmittance of receiver `r`'s relation `slot` (group order)
    /// by the translucent casters alone, and 1 when none is crossed:
    /// `exp(−(Σ_g n_g τ_g + Σ_s τ_s))`.
    pub fn transmittance(&self, casters: &Casters, r: usize, slot: usize) -> f64 {
        let rec = self.slot[r];
        if rec == NONE {
            return 1.0;
        }
        let rec = rec as usize;
        let mut acc = 0.0f64;
        let c = &self.counts[(rec * self.n + slot) * self.groups..][..self.groups];
        for (g, &n) in c.iter().enumerate() {
            if n > 0 {
                acc += f64::from(n) * casters.optical_depth[g];
            }
        }
        if self.mattes {
            acc += self.depth[rec * self.n + slot];
        }
        if acc == 0.0 {
            1.0
        } else {
            TransmittanceMode::Exact.transmittance(acc)
        }
    }

    fn record(&mut self, r: usize) -> usize {
        if self.slot[r] == NONE {
            self.slot[r] = self.recorded as u32;
            self.recorded += 1;
            self.counts
                .resize(self.counts.len() + self.n * self.groups, 0);
            if self.mattes {
                self.depth.resize(self.depth.len() + self.n, 0.0);
            }
        }
        self.slot[r] as usize
    }

    /// Receiver `r`'s `hits` by a triangle of `kind` (slots, and optical
    /// depths for S-triangles) added to its record, made on first need.
    fn add_hits(&mut self, r: usize, kind: Kind, hits: &[(usize, f64)]) {
        let base = self.record(r);
        match kind {
            Kind::Layer(group) => {
                let groups = self.groups;
                for &(slot, _) in hits {
                    let count = &mut self.counts[(base * self.n + slot) * groups + group as usize];
                    *count = count.saturating_add(1);
                }
            }
            Kind::Matte(_) => {
                for &(slot, tau) in hits {
                    self.depth[base * self.n + slot] += tau;
                }
            }
        }
    }
}

/// Casts every translucent triangle of `casters` into chunk `c` (after
/// its opaque pass; `own`: its receivers' own samples, where they have
/// some, [`Chunk::take_samples`]), the receivers' `f32` shadow-ray
/// origins `origin` (for the projector), with `slack` the penumbra
/// volumes' and `simd` the hard-volume kernel's switch.
#[allow(clippy::too_many_arguments)]
pub fn cast(
    c: &Chunk,
    own: Option<ReceiverSamples>,
    sets: &SampleSets,
    casters: &Casters,
    scene: &Scene,
    filter: Filter,
    origin: &[Vec3],
    slack: f64,
    simd: bool,
) -> Records {
    let start = std::time::Instant::now();
    let receivers = c.pos.len();
    let mut rec = Records {
        n: sets.n,
        groups: casters.groups(),
        mattes: !casters.mattes.is_empty(),
        slot: vec![NONE; receivers],
        counts: Vec::new(),
        depth: Vec::new(),
        recorded: 0,
        hierarchy_bytes: 0,
        time: Duration::ZERO,
    };
    let ids: Vec<u32> = (0..receivers as u32)
        .filter(|&i| !c.full[i as usize])
        .collect();
    if casters.is_empty() || ids.is_empty() {
        return rec;
    }
    let hier = Hierarchy::build_keyed(&c.pos, ids, Some(&c.order));
    rec.hierarchy_bytes = hier.bytes();
    // The projector decides the S-triangles' crossings in f32: its culling
    // gets a wider margin (culling only ever keeps more).
    let matte_slack = slack * 1e4;
    let groups = sets.groups;
    let mut light_volume = PenumbraVolume::default();
    let mut group_volumes = vec![PenumbraVolume::default(); groups];
    // The hard-volume cache (`sets × groups × 4 KiB`) only for layers.
    let layers = casters.tris.iter().any(|t| matches!(t.1, Kind::Layer(_)));
    // Sphere lights: each receiver's own samples (`own`, the opaque
    // pass's, made there with the projector's positions where there are
    // S-triangles; those it never reached are made here on first need),
    // one scratch hard-volume set, and no group volumes (every group's
    // bound is the light's).
    let cache = match (&own, layers) {
        (_, false) => 0,
        (Some(_), true) => 1,
        (None, true) => sets.sets * groups,
    };
    let mut pass = HitPass {
        chunk: c,
        sets,
        casters,
        scene,
        filter,
        origin,
        simd,
        own,
        hard: vec![HardVolumes::default(); cache],
        stamp: vec![0u32; cache],
        words: Vec::new(),
        hits: Vec::new(),
    };
    let mut stack: Vec<(u32, u32)> = Vec::new();
    for (index, (tri, kind)) in casters.tris.iter().enumerate() {
        let triangle_slack = match kind {
            Kind::Matte(_) => matte_slack,
            Kind::Layer(_) => slack,
        };
        penumbra_volume(&sets.light, tri, &mut light_volume);
        if pass.own.is_none() {
            for (k, volume) in group_volumes.iter_mut().enumerate() {
                penumbra_volume(&sets.group_bounds[k], tri, volume);
            }
        }
        let triangle = TriangleCast {
            tri,
            kind: *kind,
            stamp: index as u32 + 1,
            slack: triangle_slack,
            group_volumes: pass.own.is_none().then_some(&group_volumes[..]),
        };
        stack.clear();
        stack.push((0, light_volume.all()));
        while let Some((node, planes)) = stack.pop() {
            let node = &hier.nodes[node as usize];
            let planes =
                match light_volume.test_box(&node.lo, &node.hi, planes, triangle_slack, true) {
                    BoxTest::Outside => continue,
                    BoxTest::Active(planes) => planes,
                };
            if node.count == 0 {
                stack.push((node.first, planes));
                stack.push((node.first + 1, planes));
                continue;
            }
            for &p in &hier.points[node.first as usize..(node.first + node.count) as usize] {
                let p = p as usize;
                if !light_volume.contains(c.pos[p], planes, triangle_slack) {
                    continue;
                }
                pass.hits_of(p, &triangle);
                if !pass.hits.is_empty() {
                    rec.add_hits(p, triangle.kind, &pass.hits);
                }
            }
        }
    }
    rec.time = start.elapsed();
    rec
}

/// One translucent triangle as [`HitPass::hits_of`] tests it.
struct TriangleCast<'t> {
    tri: &'t [DVec3; 3],
    kind: Kind,
    /// Its number in [`Casters::tris`] plus one: the hard-volume cache's
    /// stamp.
    stamp: u32,
    /// The penumbra volumes' margin for its kind.
    slack: f64,
    /// Its group volumes; `None` where receivers have their own samples
    /// (every group's bound is the light's).
    group_volumes: Option<&'t [PenumbraVolume]>,
}

/// One chunk's translucent pass: what it reads and its scratch, reused
/// over the triangles and receivers.
struct HitPass<'c> {
    chunk: &'c Chunk<'c>,
    sets: &'c SampleSets,
    casters: &'c Casters,
    scene: &'c Scene,
    filter: Filter,
    /// The receivers' `f32` shadow-ray origins.
    origin: &'c [Vec3],
    simd: bool,
    /// The receivers' own samples, where they have some.
    own: Option<ReceiverSamples>,
    /// The hard-volume cache (one scratch set for own samples) and the
    /// triangle each entry was built for.
    hard: Vec<HardVolumes>,
    stamp: Vec<u32>,
    /// The receiver's opaque blocked bits.
    words: Vec<u32>,
    /// The receiver's relations the triangle crosses: slot and optical
    /// depth (layers: unused).
    hits: Vec<(usize, f64)>,
}

impl HitPass<'_> {
    /// Into `hits`, the relations of receiver `p` (inside the triangle's
    /// light penumbra volume) that `triangle` crosses and no opaque
    /// caster blocks.
    #[inline]
    fn hits_of(&mut self, p: usize, triangle: &TriangleCast) {
        self.chunk.words(p, &mut self.words);
        if let Some(own) = &mut self.own {
            own.ensure(self.sets, p);
        }
        self.hits.clear();
        match triangle.kind {
            Kind::Layer(_) => self.layer_hits(p, triangle),
            Kind::Matte(m) => self.matte_hits(p, m, triangle),
        }
    }

    /// Whether group `k`'s volume of `triangle` leaves out the receiver
    /// at `position` (the group is then skipped).
    #[inline]
    fn outside(triangle: &TriangleCast, k: usize, position: [f64; 3]) -> bool {
        triangle
            .group_volumes
            .is_some_and(|volumes| !volumes[k].contains(position, volumes[k].all(), triangle.slack))
    }

    /// A semi-opaque layer's crossings: each group's hard volumes of the
    /// triangle (cached per set and group, or built for the receiver's
    /// own samples) against the receiver.
    #[inline]
    fn layer_hits(&mut self, p: usize, triangle: &TriangleCast) {
        let groups = self.sets.groups;
        let position = self.chunk.pos[p];
        let set = self.chunk.set[p] as usize;
        for (k, (&word, &valid)) in self.words.iter().zip(&self.sets.valid).enumerate() {
            if word == valid || Self::outside(triangle, k, position) {
                continue;
            }
            let i = match &self.own {
                Some(own) => {
                    self.hard[0].build(own.group(p, k, groups).0, triangle.tri);
                    0
                }
                None => {
                    let i = set * groups + k;
                    if self.stamp[i] != triangle.stamp {
                        self.stamp[i] = triangle.stamp;
                        self.hard[i].build(&self.sets.soa[set][k], triangle.tri);
                    }
                    i
                }
            };
            let skip = word | !valid;
            let mut bits = if self.simd {
                hard_bits_simd(&self.hard[i], position, skip)
            } else {
                hard_bits_scalar(&self.hard[i], position, skip)
            };
            while bits != 0 {
                let j = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                self.hits.push((GROUP * k + j, 0.0));
            }
        }
    }

    /// S-triangle `matte`'s crossings: its opacity where the projector
    /// finds each unblocked sample's segment through it.
    #[inline]
    fn matte_hits(&mut self, p: usize, matte: u32, triangle: &TriangleCast) {
        let groups = self.sets.groups;
        let position = self.chunk.pos[p];
        let set = self.chunk.set[p] as usize;
        let stri = &self.casters.mattes[matte as usize];
        let Some(projector) = SampleProjector::new(stri, self.origin[p]) else {
            return;
        };
        for (k, (&word, &valid)) in self.words.iter().zip(&self.sets.valid).enumerate() {
            if word == valid || Self::outside(triangle, k, position) {
                continue;
            }
            let positions = match &self.own {
                Some(own) => own.projector(p, k, groups),
                None => &self.casters.positions[set][k],
            };
            let hits = &mut self.hits;
            projector.for_each_hit_in(positions, |j, b1, b2| {
                if (word >> j) & 1 == 1 {
                    return;
                }
                let opacity = stri.opacity_at(self.scene, b1, b2, self.filter);
                if opacity > 0.0 {
                    hits.push((GROUP * k + j, -(-f64::from(opacity)).ln_1p()));
                }
            });
        }
    }
}
