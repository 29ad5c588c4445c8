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
}

/// Casts every translucent triangle of `casters` into chunk `c` (after
/// its opaque pass; `own`: its receivers' own samples, where they have
/// some, [`Chunk::take_samples`]), the receivers' `f32` shadow-ray
/// origins `origin` (for the projector), with `slack` the penumbra
/// volumes' and `simd` the hard-volume kernel's switch.
#[allow(clippy::too_many_arguments)]
pub fn cast(
    c: &Chunk,
    mut own: Option<ReceiverSamples>,
    sets: &SampleSets,
    casters: &Casters,
    scene: &Scene,
    filter: Filter,
    origin: &[Vec3],
    slack: f64,
    simd: bool,
) -> Records {
    let t0 = std::time::Instant::now();
    let r = c.pos.len();
    let mut rec = Records {
        n: sets.n,
        groups: casters.groups(),
        mattes: !casters.mattes.is_empty(),
        slot: vec![NONE; r],
        counts: Vec::new(),
        depth: Vec::new(),
        recorded: 0,
        hierarchy_bytes: 0,
        time: Duration::ZERO,
    };
    let ids: Vec<u32> = (0..r as u32).filter(|&i| !c.full[i as usize]).collect();
    if casters.is_empty() || ids.is_empty() {
        return rec;
    }
    let hier = Hierarchy::build_keyed(&c.pos, ids, Some(&c.order));
    rec.hierarchy_bytes = hier.bytes();
    // The projector decides the S-triangles' crossings in f32: its culling
    // gets a wider margin (culling only ever keeps more).
    let matte_slack = slack * 1e4;
    let g = sets.groups;
    let mut vl = PenumbraVolume::default();
    let mut gv = vec![PenumbraVolume::default(); g];
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
        (None, true) => sets.sets * g,
    };
    let mut hard = vec![HardVolumes::default(); cache];
    let mut stamp = vec![0u32; cache];
    let mut words = Vec::new();
    let mut stack: Vec<(u32, u32)> = Vec::new();
    let mut hits: Vec<(usize, f64)> = Vec::new();
    for (ti, (tri, kind)) in casters.tris.iter().enumerate() {
        let now = ti as u32 + 1;
        let s = match kind {
            Kind::Matte(_) => matte_slack,
            Kind::Layer(_) => slack,
        };
        penumbra_volume(&sets.light, tri, &mut vl);
        if own.is_none() {
            for (k, v) in gv.iter_mut().enumerate() {
                penumbra_volume(&sets.group_bounds[k], tri, v);
            }
        }
        let per_receiver = own.is_some();
        stack.clear();
        stack.push((0, vl.all()));
        while let Some((node, pl)) = stack.pop() {
            let n = &hier.nodes[node as usize];
            let pl = match vl.test_box(&n.lo, &n.hi, pl, s, true) {
                BoxTest::Outside => continue,
                BoxTest::Active(p) => p,
            };
            if n.count == 0 {
                stack.push((n.first, pl));
                stack.push((n.first + 1, pl));
                continue;
            }
            for &p in &hier.points[n.first as usize..(n.first + n.count) as usize] {
                let p = p as usize;
                let o = c.pos[p];
                if !vl.contains(o, pl, s) {
                    continue;
                }
                c.words(p, &mut words);
                let set = c.set[p] as usize;
                if let Some(own) = &mut own {
                    own.ensure(sets, p);
                }
                // A group whose volume leaves the receiver out is skipped
                // (no volumes where the groups' bounds are the light's).
                let outside = |k: usize| !per_receiver && !gv[k].contains(o, gv[k].all(), s);
                hits.clear();
                match *kind {
                    Kind::Layer(_) => {
                        for (k, (&word, &valid)) in words.iter().zip(&sets.valid).enumerate() {
                            if word == valid || outside(k) {
                                continue;
                            }
                            let i = match &own {
                                Some(own) => {
                                    hard[0].build(own.group(p, k, g).0, tri);
                                    0
                                }
                                None => {
                                    let i = set * g + k;
                                    if stamp[i] != now {
                                        stamp[i] = now;
                                        hard[i].build(&sets.soa[set][k], tri);
                                    }
                                    i
                                }
                            };
                            let skip = word | !valid;
                            let mut bits = if simd {
                                hard_bits_simd(&hard[i], o, skip)
                            } else {
                                hard_bits_scalar(&hard[i], o, skip)
                            };
                            while bits != 0 {
                                let j = bits.trailing_zeros() as usize;
                                bits &= bits - 1;
                                hits.push((GROUP * k + j, 0.0));
                            }
                        }
                    }
                    Kind::Matte(m) => {
                        let stri = &casters.mattes[m as usize];
                        let Some(proj) = SampleProjector::new(stri, origin[p]) else {
                            continue;
                        };
                        for (k, (&w, &valid)) in words.iter().zip(&sets.valid).enumerate() {
                            if w == valid || outside(k) {
                                continue;
                            }
                            let positions = match &own {
                                Some(own) => own.projector(p, k, g),
                                None => &casters.positions[set][k],
                            };
                            proj.for_each_hit_in(positions, |j, b1, b2| {
                                if (w >> j) & 1 == 1 {
                                    return;
                                }
                                let a = stri.opacity_at(scene, b1, b2, filter);
                                if a > 0.0 {
                                    hits.push((GROUP * k + j, -(-f64::from(a)).ln_1p()));
                                }
                            });
                        }
                    }
                }
                if hits.is_empty() {
                    continue;
                }
                let base = rec.record(p);
                match *kind {
                    Kind::Layer(gi) => {
                        let gs = rec.groups;
                        for &(slot, _) in &hits {
                            let c = &mut rec.counts[(base * rec.n + slot) * gs + gi as usize];
                            *c = c.saturating_add(1);
                        }
                    }
                    Kind::Matte(_) => {
                        for &(slot, tau) in &hits {
                            rec.depth[base * rec.n + slot] += tau;
                        }
                    }
                }
            }
        }
    }
    rec.time = t0.elapsed();
    rec
}
