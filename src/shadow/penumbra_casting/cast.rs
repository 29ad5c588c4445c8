//! Casting blocker triangles into one chunk of receivers: the traversal of
//! Fig. 2 (basic) and Fig. 3 (optimised), each optimisation of §3.3
//! switchable.
//!
//! A chunk owns its receivers' state — group-umbra and full-umbra bits,
//! bit masks (on demand or all up front), its hierarchy — and sees every
//! blocker triangle in the same order; chunks share nothing, so they run
//! in parallel and the bits never depend on the thread count (a relation
//! is blocked iff some triangle's hard shadow volume holds it: an OR,
//! independent of order).

use super::hierarchy::{Hierarchy, Node};
use super::samples::{ReceiverSamples, SampleKey, SampleSets};
use super::volume::{
    ball_side_of_plane, chunks_left, cone_group, cone_slack, hard_bits_scalar, hard_bits_simd,
    light_side_of_plane, penumbra_volume, plane_sides, BoxTest, ChunkBoxes, Cone, GroupSoa,
    HardVolumes, PenumbraVolume,
};
#[cfg(target_arch = "x86_64")]
use crate::simd::level::runs_v3;
use glam::DVec3;
use std::time::{Duration, Instant};

/// No mask.
const NONE: u32 = u32::MAX;

/// Which parts of the algorithm run (§3.3; all on is Fig. 3, all off
/// Fig. 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Switches {
    /// A: umbra bits (and hierarchy rebuilds).
    pub umbra: bool,
    /// B: active plane sets.
    pub active_planes: bool,
    /// C: lazy construction of the group and hard shadow volumes.
    pub lazy: bool,
    /// D: masks allocated on demand, freed at full umbra.
    pub on_demand: bool,
    /// Point-in-hard-volume tests through the SIMD facade (else its
    /// scalar twin).
    pub simd: bool,
    /// The cone prefilter: chunks of four samples outside the cone from
    /// the receiver through the triangle skip the kernel (and, when every
    /// chunk of a group does, its hard volumes are not built).
    pub cone: bool,
    /// With `cone`: the cone decides each remaining sample where its
    /// value is clear of the rounding allowance (the kernel's answer,
    /// proved), and the kernel runs only for the samples within it (so
    /// almost no hard volumes are built).
    pub cone_decides: bool,
    /// With `cone_decides`: also for triangles whose plane splits the
    /// light, per sample by its side of the plane (the samples within the
    /// allowance of it go to the kernel).
    pub cone_split: bool,
    /// Rebuild the hierarchy when more than this percentage of its
    /// receivers is in full umbra (0: never; needs `umbra`).
    pub rebuild_percent: u32,
}

/// What a chunk measured.
#[derive(Debug, Clone, Default)]
pub struct ChunkStats {
    /// Hierarchy builds after the first.
    pub rebuilds: u32,
    /// Largest node count of its hierarchies.
    pub peak_nodes: usize,
    /// Largest bytes of its hierarchies.
    pub peak_hierarchy_bytes: u64,
    /// Most masks alive at once.
    pub peak_masks: usize,
    /// Receivers that ever got a mask.
    pub masked: usize,
    /// Time spent building hierarchies (first build and rebuilds).
    pub build_time: Duration,
    /// Triangles whose group and hard volumes were built (lazily).
    pub volumes_built: u64,
    /// Sphere lights: most receivers holding their own samples at once.
    pub peak_sample_receivers: usize,
}

/// One chunk of receivers.
pub struct Chunk<'a> {
    sets: &'a SampleSets,
    sw: Switches,
    slack: f64,
    /// Per receiver: its index in the input of [`Chunk::new`] (receivers
    /// are stored in the first hierarchy's leaf order, so a leaf's
    /// points are contiguous in memory).
    pub order: Vec<u32>,
    /// Per receiver: the shadow-ray origin relative to the light's centre.
    pub pos: Vec<[f64; 3]>,
    /// Per receiver: its sample set.
    pub set: Vec<u16>,
    /// Sphere lights: each receiver's own samples, made on first need
    /// (`None` for a rect light, whose receivers share their set's).
    own: Option<ReceiverSamples>,
    /// Per receiver: group-umbra bits.
    pub group_umbra: Vec<u128>,
    /// Per receiver: full umbra.
    pub full: Vec<bool>,
    /// Per receiver: blocker triangles that reached its leaf.
    pub leaf_triangles: Vec<u32>,
    /// Per receiver: sealed ([`Chunk::seal`]): the back faces of open
    /// casters can be skipped for it.
    sealed: Vec<bool>,
    /// Whether the triangle being cast is an open caster's back face.
    open_back: bool,
    slot: Vec<u32>,
    pool: Vec<u32>,
    free: Vec<u32>,
    live: usize,
    hier: Hierarchy,
    umbra_in_hier: usize,
    stack: Vec<(u16, u32)>,
    groups_vol: Vec<PenumbraVolume>,
    groups_built: bool,
    hard: Vec<HardVolumes>,
    hard_stamp: Vec<u32>,
    /// Per (set, group): the chunks of four built for the current stamp.
    hard_built: Vec<u8>,
    stamp: u32,
    tri: [DVec3; 3],
    /// Largest coordinate magnitude of the receivers.
    pos_extent: f64,
    /// The current triangle's cone allowance and the light's side of its
    /// plane (0: the plane splits the light), where the cone is used.
    cone_slack: Option<(f64, f64)>,
    /// Per (set, group): its samples' sides of a splitting plane, for
    /// the current stamp.
    sides: Vec<(u32, u32)>,
    sides_stamp: Vec<u32>,
    /// What it measured.
    pub stats: ChunkStats,
}

impl<'a> Chunk<'a> {
    /// A chunk over receivers at `pos` with sets `set` and sample keys
    /// `keys` (used only where each receiver has samples of its own,
    /// [`SampleSets::per_receiver`]; may be empty otherwise; with the
    /// projector's positions too where `projector`, for the translucent
    /// pass that takes them over, [`Chunk::take_samples`]); receiver `r`
    /// of the chunk is input receiver `order[r]`.
    pub fn new(
        sets: &'a SampleSets,
        sw: Switches,
        slack: f64,
        pos: Vec<[f64; 3]>,
        set: Vec<u16>,
        keys: Vec<SampleKey>,
        projector: bool,
    ) -> Chunk<'a> {
        let r = pos.len();
        let g = sets.groups;
        let (slot, pool) = if sw.on_demand {
            (vec![NONE; r], Vec::new())
        } else {
            ((0..r as u32).collect(), vec![0u32; r * g])
        };
        let t = Instant::now();
        let mut hier = Hierarchy::build(&pos, (0..r as u32).collect());
        // Relabel the receivers in leaf order; rebuilds break ties by the
        // input index, as this first build did.
        let order = std::mem::replace(&mut hier.points, (0..r as u32).collect());
        let pos: Vec<[f64; 3]> = order.iter().map(|&i| pos[i as usize]).collect();
        let set: Vec<u16> = order.iter().map(|&i| set[i as usize]).collect();
        let own = sets.per_receiver().then(|| {
            ReceiverSamples::new(order.iter().map(|&i| keys[i as usize]).collect(), projector)
        });
        // One scratch hard-volume set where no receivers share samples.
        let cache = if own.is_some() { 1 } else { sets.sets * g };
        let mut stats = ChunkStats {
            peak_nodes: hier.nodes.len(),
            peak_hierarchy_bytes: hier.bytes(),
            peak_masks: if sw.on_demand { 0 } else { r },
            masked: if sw.on_demand { 0 } else { r },
            ..ChunkStats::default()
        };
        stats.build_time = t.elapsed();
        let pos_extent = pos
            .iter()
            .flatten()
            .fold(0.0f64, |m: f64, v: &f64| m.max(v.abs()));
        Chunk {
            sets,
            sw,
            pos_extent,
            cone_slack: None,
            slack,
            group_umbra: vec![0; r],
            full: vec![false; r],
            leaf_triangles: vec![0; r],
            sealed: vec![false; r],
            open_back: false,
            order,
            pos,
            set,
            own,
            slot,
            pool,
            free: Vec::new(),
            live: 0,
            hier,
            umbra_in_hier: 0,
            stack: Vec::new(),
            groups_vol: vec![PenumbraVolume::default(); g],
            groups_built: false,
            hard: vec![HardVolumes::default(); cache],
            hard_stamp: vec![0; cache],
            hard_built: vec![0; cache],
            sides: vec![(0, 0); cache],
            sides_stamp: vec![0; cache],
            stamp: 0,
            tri: [DVec3::ZERO; 3],
            stats,
        }
    }

    /// The blocked-relation words of receiver `r` (group order), or
    /// `None` when it has no mask (nothing blocked) — a full-umbra
    /// receiver whose mask was freed gives every valid bit.
    pub fn words(&self, r: usize, out: &mut Vec<u32>) {
        out.clear();
        if self.full[r] {
            out.extend_from_slice(&self.sets.valid);
        } else if self.slot[r] == NONE {
            out.resize(self.sets.groups, 0);
        } else {
            let g = self.sets.groups;
            let s = self.slot[r] as usize * g;
            out.extend_from_slice(&self.pool[s..s + g]);
        }
    }

    /// Marks the receivers for which open casters behave as closed ones:
    /// those outside every open caster's box (`boxes`, relative to the
    /// light's centre, already widened) and outside the light penumbra
    /// volume of every triangle of the surfaces that close those casters
    /// (`caps`: no segment from the receiver to any light sample crosses
    /// a cap). Such a receiver's winding number about a closed-up caster
    /// is 0, as every sample's is (the light is outside the caster's box),
    /// so a segment crossing one of its faces front to back (a back face
    /// of the light: the whole light behind its plane) crosses one back
    /// to front as well, and that face is not a cap: one of the caster's
    /// kept faces blocks the relation too. Open casters' back faces are
    /// then skipped for it ([`Chunk::process`]).
    pub fn seal(&mut self, caps: &[PenumbraVolume], boxes: &[([f64; 3], [f64; 3])]) {
        let inside = |p: &[f64; 3], (lo, hi): &([f64; 3], [f64; 3])| {
            (0..3).all(|a| p[a] >= lo[a] && p[a] <= hi[a])
        };
        let mut sealed: Vec<bool> = self
            .pos
            .iter()
            .map(|p| !boxes.iter().any(|b| inside(p, b)))
            .collect();
        let mut stack = Vec::new();
        for v in caps {
            if self.hier.nodes.is_empty() {
                break;
            }
            stack.clear();
            stack.push((0usize, v.all()));
            while let Some((n, pl)) = stack.pop() {
                let node = &self.hier.nodes[n];
                let pl = match v.test_box(&node.lo, &node.hi, pl, self.slack, true) {
                    BoxTest::Outside => continue,
                    BoxTest::Active(p) => p,
                };
                let (first, count) = (node.first as usize, node.count as usize);
                if count == 0 {
                    stack.push((first, pl));
                    stack.push((first + 1, pl));
                    continue;
                }
                for &r in &self.hier.points[first..first + count] {
                    let r = r as usize;
                    if sealed[r] && v.contains(self.pos[r], pl, self.slack) {
                        sealed[r] = false;
                    }
                }
            }
        }
        self.hier.mark_sealed(&sealed);
        self.sealed = sealed;
    }

    /// Receivers sealed by [`Chunk::seal`].
    pub fn sealed_count(&self) -> usize {
        self.sealed.iter().filter(|&&s| s).count()
    }

    /// Casts triangle `t` (relative to the light's centre) with its light
    /// penumbra volume `vl`; `open_back`: it is a back face of an open
    /// caster, cast only into the receivers that are not sealed
    /// ([`Chunk::seal`]).
    pub fn process(&mut self, t: &[DVec3; 3], vl: &PenumbraVolume, open_back: bool) {
        let sw = self.sw;
        if sw.umbra
            && sw.rebuild_percent > 0
            && !self.hier.points.is_empty()
            && self.umbra_in_hier as u64 * 100
                > u64::from(sw.rebuild_percent) * self.hier.points.len() as u64
        {
            self.rebuild();
        }
        if self.hier.nodes.is_empty() {
            return;
        }
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.hard_stamp.iter_mut().for_each(|s| *s = u32::MAX);
            self.sides_stamp.iter_mut().for_each(|s| *s = u32::MAX);
            self.stamp = 1;
        }
        self.tri = *t;
        self.open_back = open_back;
        self.groups_built = false;
        if !sw.lazy && self.own.is_none() {
            self.build_groups();
            for s in 0..self.sets.sets {
                for k in 0..self.sets.groups {
                    self.hard_volumes(s, 0, k, 0xff);
                }
            }
        }
        self.stack.clear();
        for k in 0..self.sets.groups {
            self.stack.push((k as u16, u32::MAX));
        }
        let n = self.stack.len();
        self.recurse(0, vl, vl.all(), 0, n);
    }

    /// The traversal from `node` ([`Chunk::recurse_body`]), in its
    /// x86-64-v3 copy where the CPU has those features
    /// (`simd::level::runs_v3`).
    fn recurse(&mut self, node: usize, vl: &PenumbraVolume, pl: u32, s0: usize, s1: usize) {
        #[cfg(target_arch = "x86_64")]
        let v3 = runs_v3();
        #[cfg(not(target_arch = "x86_64"))]
        let v3 = false;
        self.descend(node, vl, pl, s0, s1, v3)
    }

    /// [`Chunk::recurse_body`] compiled for `Level::V3` (`simd::level`):
    /// the same code and bits (no FMA), with the volume and cone tests'
    /// AVX kernels inlined into it.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
    fn recurse_v3(&mut self, node: usize, vl: &PenumbraVolume, pl: u32, s0: usize, s1: usize) {
        self.recurse_body(node, vl, pl, s0, s1, true)
    }

    /// Down the hierarchy by the v3 copy where `v3` (set only where
    /// `runs_v3` found the CPU's features), else by the plain one.
    #[inline(always)]
    fn descend(
        &mut self,
        node: usize,
        vl: &PenumbraVolume,
        pl: u32,
        s0: usize,
        s1: usize,
        v3: bool,
    ) {
        #[cfg(target_arch = "x86_64")]
        if v3 {
            // SAFETY: `v3` is set only where `runs_v3` found every feature
            // the v3 copy enables, its one requirement.
            return unsafe { self.recurse_v3(node, vl, pl, s0, s1) };
        }
        let _ = v3;
        self.recurse_body(node, vl, pl, s0, s1, false)
    }

    fn rebuild(&mut self) {
        let t = Instant::now();
        let ids: Vec<u32> = (0..self.pos.len() as u32)
            .filter(|&r| !self.full[r as usize])
            .collect();
        self.hier = Hierarchy::build_keyed(&self.pos, ids, Some(&self.order));
        self.hier.mark_sealed(&self.sealed);
        self.umbra_in_hier = 0;
        self.stats.rebuilds += 1;
        self.stats.peak_nodes = self.stats.peak_nodes.max(self.hier.nodes.len());
        self.stats.peak_hierarchy_bytes = self.stats.peak_hierarchy_bytes.max(self.hier.bytes());
        self.stats.build_time += t.elapsed();
    }

    fn build_groups(&mut self) {
        self.groups_built = true;
        self.stats.volumes_built += 1;
        let t = self.tri;
        // With samples of its own per receiver every group's bound is the
        // light's: its volume would be `V_L`, already tested.
        if self.own.is_none() {
            for (k, v) in self.groups_vol.iter_mut().enumerate() {
                penumbra_volume(&self.sets.group_bounds[k], &t, v);
            }
        }
        self.cone_slack = None;
        if self.sw.cone {
            let m = t
                .iter()
                .fold(self.pos_extent.max(self.sets.extent), |m, v| {
                    m.max(v.abs().max_element())
                });
            let slack = cone_slack(m);
            if slack.is_finite() {
                let split = self.sw.cone_decides && self.sw.cone_split;
                // A sphere light: its ball, tighter than its box.
                let side = match self.sets.ball() {
                    Some(radius) => ball_side_of_plane(radius, &t, slack),
                    None => light_side_of_plane(&self.sets.light, &t, slack),
                };
                self.cone_slack = match side {
                    Some(side) => Some((slack, side)),
                    None if split => Some((slack, 0.0)),
                    None => None,
                };
            }
        }
    }

    /// The hard volumes of (set, group k) with at least the chunks of
    /// four in `need` built for the current triangle (built lazily, chunk
    /// by chunk: the cone prefilter leaves most chunks untested); where
    /// receivers have samples of their own, receiver `r`'s group, built
    /// afresh in the one scratch set.
    fn hard_volumes(&mut self, set: usize, r: usize, k: usize, need: u8) -> usize {
        if let Some(own) = &self.own {
            let (soa, _) = own.group(r, k, self.sets.groups);
            self.hard[0].build_chunks(soa, &self.tri, need);
            return 0;
        }
        let i = set * self.sets.groups + k;
        if self.hard_stamp[i] != self.stamp {
            self.hard_stamp[i] = self.stamp;
            self.hard_built[i] = 0;
        }
        let missing = need & !self.hard_built[i];
        if missing != 0 {
            self.hard_built[i] |= missing;
            self.hard[i].build_chunks(&self.sets.soa[set][k], &self.tri, missing);
        }
        i
    }

    /// The samples' sides of the current triangle's plane for (set,
    /// group k), computed on first need (receiver `r`'s own group, each
    /// time, where receivers have samples of their own).
    fn plane_sides(&mut self, set: usize, r: usize, k: usize) -> (u32, u32) {
        if let Some(own) = &self.own {
            let (slack, _) = self.cone_slack.expect("a cone");
            let (soa, boxes) = own.group(r, k, self.sets.groups);
            return plane_sides(soa, boxes, &self.tri, slack);
        }
        let i = set * self.sets.groups + k;
        if self.sides_stamp[i] != self.stamp {
            self.sides_stamp[i] = self.stamp;
            let (slack, _) = self.cone_slack.expect("a cone");
            let (soa, boxes) = (&self.sets.soa[set][k], &self.sets.boxes[set][k]);
            self.sides[i] = plane_sides(soa, boxes, &self.tri, slack);
        }
        self.sides[i]
    }

    fn alloc(&mut self, r: usize) {
        let g = self.sets.groups;
        let s = if let Some(s) = self.free.pop() {
            self.pool[s as usize * g..(s as usize + 1) * g].fill(0);
            s
        } else {
            let s = (self.pool.len() / g.max(1)) as u32;
            self.pool.resize(self.pool.len() + g, 0);
            s
        };
        self.slot[r] = s;
        self.live += 1;
        self.stats.masked += 1;
        self.stats.peak_masks = self.stats.peak_masks.max(self.live);
    }

    fn release(&mut self, r: usize) {
        let s = self.slot[r];
        if s != NONE {
            self.free.push(s);
            self.slot[r] = NONE;
            self.live -= 1;
        }
    }

    #[inline(always)]
    fn recurse_body(
        &mut self,
        node: usize,
        vl: &PenumbraVolume,
        pl: u32,
        s0: usize,
        s1: usize,
        v3: bool,
    ) {
        let sw = self.sw;
        let Node {
            lo,
            hi,
            first,
            count,
            group_umbra,
            full,
            sealed,
        } = self.hier.nodes[node].clone();
        if (sw.umbra && full) || (sealed && self.open_back) {
            return;
        }
        let pl2 = match vl.test_box(&lo, &hi, pl, self.slack, sw.active_planes) {
            BoxTest::Outside => return,
            BoxTest::Active(p) => p,
        };
        let c0 = self.stack.len();
        for i in s0..s1 {
            let (k, pk) = self.stack[i];
            if sw.umbra && (group_umbra >> k) & 1 == 1 {
                continue;
            }
            if self.groups_built && self.own.is_none() {
                let v = &self.groups_vol[k as usize];
                match v.test_box(&lo, &hi, pk & v.all(), self.slack, sw.active_planes) {
                    BoxTest::Outside => {}
                    BoxTest::Active(p) => self.stack.push((k, p)),
                }
            } else {
                self.stack.push((k, u32::MAX));
            }
        }
        let c1 = self.stack.len();
        if c1 == c0 {
            return;
        }
        if count == 0 {
            let left = first as usize;
            self.descend(left, vl, pl2, c0, c1, v3);
            self.descend(left + 1, vl, pl2, c0, c1, v3);
            if sw.umbra {
                let (l, r) = (&self.hier.nodes[left], &self.hier.nodes[left + 1]);
                let (gu, f) = (l.group_umbra & r.group_umbra, l.full && r.full);
                let n = &mut self.hier.nodes[node];
                n.group_umbra = gu;
                n.full = f;
            }
        } else {
            self.leaf(node, first as usize, count as usize, vl, pl2, c0, c1);
        }
        self.stack.truncate(c0);
    }

    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn leaf(
        &mut self,
        node: usize,
        first: usize,
        count: usize,
        vl: &PenumbraVolume,
        pl: u32,
        c0: usize,
        c1: usize,
    ) {
        let sw = self.sw;
        let all = self.sets.all_groups();
        let g = self.sets.groups;
        let skip_full = sw.umbra || sw.on_demand;
        let (mut and_gu, mut and_full) = (all, true);
        for idx in first..first + count {
            let r = self.hier.points[idx] as usize;
            if !(self.open_back && self.sealed[r]) {
                self.leaf_triangles[r] += 1;
                if !(skip_full && self.full[r]) && vl.contains(self.pos[r], pl, self.slack) {
                    self.point(r, c0, c1);
                }
            }
            let gu = if self.full[r] {
                all
            } else {
                self.group_umbra[r]
            };
            and_gu &= gu;
            and_full &= self.full[r];
        }
        if sw.umbra {
            let n = &mut self.hier.nodes[node];
            n.group_umbra = and_gu;
            n.full = and_full;
        }
        let _ = g;
    }

    #[inline(always)]
    fn point(&mut self, r: usize, c0: usize, c1: usize) {
        let sw = self.sw;
        if !self.groups_built {
            self.build_groups();
        }
        let o = self.pos[r];
        let (cone, decides, split) = match self.cone_slack {
            Some((s, side)) => match Cone::new(&self.tri, o, s) {
                // The receiver is on the light's side of the triangle's
                // plane (by more than the allowance): the kernel's
                // triangle plane rejects it for every sample.
                Some(c) if sw.cone_decides && side != 0.0 && c.orientation() != side => return,
                Some(c) => (Some(c), sw.cone_decides, side == 0.0),
                None => (None, false, false),
            },
            None => (None, false, false),
        };
        // A sphere light clear of the triangle's plane: a cone that misses
        // the light's ball marks nothing (no mask, no samples made).
        if let (Some(c), Some(radius), false) = (&cone, self.sets.ball(), split) {
            if c.misses_ball(radius) {
                return;
            }
        }
        if self.slot[r] == NONE {
            self.alloc(r);
        }
        if let Some(own) = &mut self.own {
            own.ensure(self.sets, r);
        }
        let per_receiver = self.own.is_some();
        let set = self.set[r] as usize;
        let g = self.sets.groups;
        let base = self.slot[r] as usize * g;
        for i in c0..c1 {
            let (k, pk) = self.stack[i];
            let k = k as usize;
            if sw.umbra && (self.group_umbra[r] >> k) & 1 == 1 {
                continue;
            }
            let v = &self.groups_vol[k];
            if !per_receiver && !v.contains(o, pk & v.all(), self.slack) {
                continue;
            }
            let valid = self.sets.valid[k];
            let word = self.pool[base + k];
            if word == valid {
                continue;
            }
            let mut skip = word | !valid;
            let bits = match &cone {
                Some(c) if decides => {
                    let sides = split.then(|| self.plane_sides(set, r, k));
                    let (soa, boxes) = self.group_samples(set, r, k);
                    let (sure, unsure) = cone_group(c, soa, boxes, skip, sides, sw.simd);
                    if sure | unsure == 0 {
                        continue;
                    }
                    if unsure == 0 {
                        sure
                    } else {
                        // Ties up to rounding: the kernel's own answer.
                        let skip = !unsure;
                        let hv = self.hard_volumes(set, r, k, chunks_left(skip));
                        sure | self.kernel(hv, o, skip)
                    }
                }
                Some(c) => {
                    skip |= c.outside_chunks(self.group_samples(set, r, k).1);
                    if skip == u32::MAX {
                        continue;
                    }
                    let hv = self.hard_volumes(set, r, k, chunks_left(skip));
                    self.kernel(hv, o, skip)
                }
                None => {
                    // The chunks of four with a sample left to test.
                    let hv = self.hard_volumes(set, r, k, chunks_left(skip));
                    self.kernel(hv, o, skip)
                }
            };
            let word = word | bits;
            self.pool[base + k] = word;
            if word == valid {
                self.group_umbra[r] |= 1u128 << k;
            }
        }
        if self.group_umbra[r] == self.sets.all_groups() && !self.full[r] {
            self.full[r] = true;
            self.umbra_in_hier += 1;
            if sw.on_demand {
                self.release(r);
            }
            if let Some(own) = &mut self.own {
                own.release(r);
            }
        }
    }

    /// Group `k`'s samples for receiver `r` of set `set`: positions and
    /// chunk boxes (its own where receivers have samples of their own).
    #[inline(always)]
    fn group_samples(&self, set: usize, r: usize, k: usize) -> (&GroupSoa, &ChunkBoxes) {
        match &self.own {
            Some(own) => own.group(r, k, self.sets.groups),
            None => (&self.sets.soa[set][k], &self.sets.boxes[set][k]),
        }
    }

    /// The receivers' own samples, where they have some, handed over
    /// after the opaque cast (the translucent pass goes on with them: the
    /// receivers not in full umbra keep theirs).
    pub fn take_samples(&mut self) -> Option<ReceiverSamples> {
        self.own.take()
    }

    /// Most receivers that held their own samples at once (0 where they
    /// share their set's).
    pub fn peak_sample_receivers(&self) -> usize {
        self.own.as_ref().map_or(0, |o| o.peak)
    }

    #[inline(always)]
    fn kernel(&self, hv: usize, o: [f64; 3], skip: u32) -> u32 {
        if self.sw.simd {
            hard_bits_simd(&self.hard[hv], o, skip)
        } else {
            hard_bits_scalar(&self.hard[hv], o, skip)
        }
    }

    /// Bytes of its hard shadow volume cache.
    pub fn volume_bytes(&self) -> u64 {
        (self.hard.len() * std::mem::size_of::<HardVolumes>()
            + self
                .groups_vol
                .iter()
                .map(|v| v.planes.capacity() * 32)
                .sum::<usize>()) as u64
    }

    /// Bytes of one mask.
    pub fn mask_bytes(&self) -> u64 {
        self.sets.groups as u64 * 4
    }
}
