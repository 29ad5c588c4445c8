//! The three-level light-sample hierarchy (§3.1, §3.4): the light, groups
//! of 32 nearby samples, the samples; in `K` distinct sample sets, each
//! the points of the one sampling module at one "set pixel".
//!
//! Set `σ` of a rect light is `LightSampler::samples_with(pattern, _,
//! set_pixel(σ))`. With the `correlated` pattern every pixel of the
//! reference shares one set (so `K = 1`); with `interleaved:n` and
//! `K = n²` set `σ` is the reference's set number `σ` and each receiver
//! gets the set of its own pixel: in both cases every receiver's samples
//! are bit for bit the reference's. Otherwise set `σ` is the pattern's
//! points at the virtual pixel `(u32::MAX − σ, u32::MAX)` (outside every
//! image) and a receiver gets the set `pixel_key(seed, light, pixel) mod K`
//! (noise instead of the banding of a fixed assignment).
//!
//! Groups: each set's unit points are split by counts along the longer
//! side of a nominal region (the same splits for every set), so group `k`
//! covers the same part of the light in every set; with a jittered grid
//! the groups are blocks of strata (4 × 8 cells at 256 samples). A group's
//! bound is the box, in the light's frame, of its samples' `f32`
//! positions over every set (§3.4: it must bound all sets), widened by
//! rounding margins, so every position a hard shadow volume is built
//! from lies inside it.
//!
//! Sphere lights (§3.4 leaves volumetric lights open): the reference
//! samples the cone the sphere subtends from each receiver's surface
//! point, so a sample's position moves with the receiver and no set is
//! shared. [`SampleSets::sphere`] keeps one nominal set (every receiver's
//! samples in index order, so the masks' slots are the reference's
//! indices) and bounds the light and every group by the sphere's box,
//! widened by the `f32` rounding of the sample positions; each receiver's
//! own samples are computed on first need by [`ReceiverSamples`] — the
//! reference's samples at its pixel, for every pattern.

use super::volume::{ChunkBoxes, GroupSoa, LightBox};
use crate::sampling::{mix64, pixel_key, LightSampler, PatternSampler, SamplePattern};
use crate::shade::LightSample;
use crate::shadow::kit::stsv::SamplePositions;
use glam::{DVec3, Vec3};

/// Samples per group (the paper's 32: one `u32` mask word).
pub const GROUP: usize = 32;
/// Most groups: the umbra bits are one `u128`.
pub const MAX_GROUPS: usize = 128;

/// The sample sets of one light.
#[derive(Debug, Clone)]
pub struct SampleSets {
    /// Samples per set, `N`.
    pub n: usize,
    /// Groups, `⌈N / 32⌉`.
    pub groups: usize,
    /// Distinct sets.
    pub sets: usize,
    /// Per set: the samples in group order (`32 k + j`), relative to
    /// the light's centre, in `f64` (exact differences of `f32`).
    pub positions: Vec<Vec<DVec3>>,
    /// Per set and group: the positions as lanes.
    pub soa: Vec<Vec<GroupSoa>>,
    /// Per set and group: the boxes of its samples four by four (the
    /// cone prefilter's chunks).
    pub boxes: Vec<Vec<ChunkBoxes>>,
    /// The largest coordinate magnitude of the light's box corners
    /// (bounds every sample's, relative to the centre).
    pub extent: f64,
    /// Per set: group-order slot → the sample's index `k` in the
    /// pattern (its index in the reference's sample list).
    pub order: Vec<Vec<u32>>,
    /// Per set: the samples as the reference gets them (index order).
    pub samples: Vec<Vec<LightSample>>,
    /// The bound of every sample of every set (`Δ_L`).
    pub light: LightBox,
    /// Per group: the bound of its samples over every set (`Δ_Gk`).
    pub group_bounds: Vec<LightBox>,
    /// Per group: the valid bits of its mask word.
    pub valid: Vec<u32>,
    /// How receivers get their set.
    assign: Assign,
    seed: u64,
    light_index: usize,
    /// Sphere lights: how each receiver's own samples are made.
    sphere: Option<SphereSampling>,
}

/// A sphere light's sampler and pattern: a receiver's samples are
/// `sampler.samples_with(pattern, position, pixel)`, the reference's call.
#[derive(Debug, Clone)]
struct SphereSampling {
    sampler: LightSampler,
    pattern: PatternSampler,
    centre: DVec3,
}

/// What a receiver's samples are made from where they move with it
/// (sphere lights): the surface point the reference samples from (the
/// cone's apex; the shadow rays start at its offset origin) and its pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleKey {
    /// The G-buffer's surface position.
    pub position: Vec3,
    /// The pixel (the pattern's key).
    pub pixel: (u32, u32),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Assign {
    /// Every receiver set 0.
    One,
    /// The reference's interleaved set of the pixel.
    Interleaved(u32),
    /// A hash of the pixel, mod K.
    Hashed,
}

impl SampleSets {
    /// The sets of rect light `sampler` (index `light_index`) for
    /// `pattern` with `k` distinct sets (`k ≥ 1`); `n` must be ≥ 1 and at
    /// most `32 × MAX_GROUPS` (checked by the caller).
    pub fn new(
        sampler: &LightSampler,
        pattern: &PatternSampler,
        k: usize,
        centre: DVec3,
        axes: [DVec3; 3],
    ) -> SampleSets {
        let n = pattern.len() as usize;
        let (sets, assign) = match pattern.pattern() {
            SamplePattern::Correlated => (1, Assign::One),
            SamplePattern::Interleaved { n: side } if (side.max(1) * side.max(1)) as usize == k => {
                (k, Assign::Interleaved(side.max(1)))
            }
            _ if k <= 1 => (1, Assign::Hashed),
            _ => (k, Assign::Hashed),
        };
        let set_pixel = |s: usize| -> (u32, u32) {
            match assign {
                Assign::Interleaved(side) => (s as u32 % side, s as u32 / side),
                _ => (u32::MAX - s as u32, u32::MAX),
            }
        };
        let groups = n.div_ceil(GROUP);
        let mut positions: Vec<Vec<DVec3>> = Vec::with_capacity(sets);
        let mut order = Vec::with_capacity(sets);
        let mut samples_all = Vec::with_capacity(sets);
        let mut units = Vec::new();
        let mut samples = Vec::new();
        for s in 0..sets {
            let px = set_pixel(s);
            pattern.unit_points(px, &mut units);
            // A rect light's samples do not depend on the receiver.
            sampler.samples_with(pattern, Vec3::ZERO, px, &mut samples);
            let mut idx: Vec<u32> = (0..n as u32).collect();
            split(&units, &mut idx, [1.0, 1.0]);
            positions.push(
                idx.iter()
                    .map(|&i| samples[i as usize].x.as_dvec3() - centre)
                    .collect(),
            );
            order.push(idx);
            samples_all.push(samples.clone());
        }
        let frame = |p: DVec3| DVec3::new(p.dot(axes[0]), p.dot(axes[1]), p.dot(axes[2]));
        let mut lo = vec![DVec3::INFINITY; groups];
        let mut hi = vec![DVec3::NEG_INFINITY; groups];
        for set in &positions {
            for (slot, &p) in set.iter().enumerate() {
                let q = frame(p);
                lo[slot / GROUP] = lo[slot / GROUP].min(q);
                hi[slot / GROUP] = hi[slot / GROUP].max(q);
            }
        }
        let scale = positions
            .iter()
            .flatten()
            .fold(0.0f64, |m, p| m.max(p.abs().max_element()))
            + centre.abs().max_element();
        // The frame projection and back rounds at ~1e-16 relative; the
        // margin is far above it and far below any geometric feature.
        let margin = 1e-12 * scale.max(f64::MIN_POSITIVE);
        let make = |lo: DVec3, hi: DVec3| -> LightBox {
            let (lo, hi) = (lo - DVec3::splat(margin), hi + DVec3::splat(margin));
            let mut corners = [DVec3::ZERO; 8];
            for (i, c) in corners.iter_mut().enumerate() {
                let q = DVec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                *c = axes[0] * q.x + axes[1] * q.y + axes[2] * q.z;
            }
            LightBox { corners }
        };
        let all_lo = lo.iter().fold(DVec3::INFINITY, |a, &b| a.min(b));
        let all_hi = hi.iter().fold(DVec3::NEG_INFINITY, |a, &b| a.max(b));
        let valid = valid_bits(n, groups);
        let soa = positions
            .iter()
            .map(|set| set.chunks(GROUP).map(GroupSoa::new).collect())
            .collect();
        let boxes = positions
            .iter()
            .map(|set| set.chunks(GROUP).map(ChunkBoxes::new).collect())
            .collect();
        let light = make(all_lo, all_hi);
        let extent = light
            .corners
            .iter()
            .fold(0.0f64, |m, c| m.max(c.abs().max_element()));
        SampleSets {
            soa,
            boxes,
            extent,
            n,
            groups,
            sets,
            light,
            group_bounds: (0..groups).map(|g| make(lo[g], hi[g])).collect(),
            positions,
            order,
            samples: samples_all,
            valid,
            assign,
            seed: pattern.seed(),
            light_index: pattern.light_index(),
            sphere: None,
        }
    }

    /// The nominal set of sphere light `sampler` (centre `centre`, radius
    /// `radius`) for `pattern`: no shared positions (each receiver's are
    /// its own, [`ReceiverSamples`]), slots in sample index order, and the
    /// light and every group bounded by the sphere's box in world axes.
    /// The box's half side is the radius plus the `f32` rounding of a
    /// position on the sphere (`2⁻²³` of the largest coordinate
    /// magnitude, twice over) plus `1e-12` of the scale, so every sample
    /// position of every receiver lies inside it.
    pub fn sphere(
        sampler: &LightSampler,
        pattern: &PatternSampler,
        centre: DVec3,
        radius: f64,
    ) -> SampleSets {
        let n = pattern.len() as usize;
        let groups = n.div_ceil(GROUP);
        let scale = centre.abs().max_element() + radius;
        let half = radius + 2.0 * f64::from(f32::EPSILON) * scale + 1e-12 * scale.max(1.0);
        let mut corners = [DVec3::ZERO; 8];
        for (i, c) in corners.iter_mut().enumerate() {
            *c = DVec3::new(
                if i & 1 == 0 { -half } else { half },
                if i & 2 == 0 { -half } else { half },
                if i & 4 == 0 { -half } else { half },
            );
        }
        let light = LightBox { corners };
        SampleSets {
            n,
            groups,
            sets: 1,
            positions: Vec::new(),
            soa: Vec::new(),
            boxes: Vec::new(),
            extent: half,
            order: vec![(0..n as u32).collect()],
            samples: vec![Vec::new()],
            light,
            group_bounds: vec![light; groups],
            valid: valid_bits(n, groups),
            assign: Assign::One,
            seed: pattern.seed(),
            light_index: pattern.light_index(),
            sphere: Some(SphereSampling {
                sampler: *sampler,
                pattern: pattern.clone(),
                centre,
            }),
        }
    }

    /// Sphere lights: the radius of a ball about the light's centre that
    /// holds every receiver's every sample (the box's half side).
    pub fn ball(&self) -> Option<f64> {
        self.sphere.as_ref().map(|_| self.extent)
    }

    /// Whether each receiver has samples of its own (a sphere light): no
    /// set's positions are shared, and the group bounds are the light's.
    pub fn per_receiver(&self) -> bool {
        self.sphere.is_some()
    }

    /// Whether a receiver at surface `position` has samples: every one for
    /// a rect light; for a sphere light, exactly those outside the sphere
    /// (the reference gives one inside or on it none).
    pub fn has_samples(&self, position: Vec3) -> bool {
        match &self.sphere {
            None => true,
            Some(s) => s.sampler.cone_frame(position.as_dvec3()).is_some(),
        }
    }

    /// The samples (in index order) of the receiver of set `set` with
    /// key `key`: the set's shared list, or for a sphere light its own,
    /// written to `buf`.
    pub fn samples_for<'s>(
        &'s self,
        set: usize,
        key: SampleKey,
        buf: &'s mut Vec<LightSample>,
    ) -> &'s [LightSample] {
        match &self.sphere {
            None => &self.samples[set],
            Some(s) => {
                s.sampler
                    .samples_with(&s.pattern, key.position, key.pixel, buf);
                buf
            }
        }
    }

    /// The set of the receiver at `pixel`.
    pub fn set_of(&self, pixel: (u32, u32)) -> usize {
        match self.assign {
            Assign::One => 0,
            Assign::Interleaved(side) => {
                ((pixel.0 % side) + side * (pixel.1 % side)) as usize % self.sets
            }
            Assign::Hashed => {
                if self.sets <= 1 {
                    0
                } else {
                    (mix64(pixel_key(self.seed, self.light_index, pixel) ^ 0x5bd1_e995)
                        % self.sets as u64) as usize
                }
            }
        }
    }

    /// Whether every receiver's samples are the reference's at its pixel.
    pub fn matches_reference(&self) -> bool {
        matches!(self.assign, Assign::One | Assign::Interleaved(_))
    }

    /// The umbra bits of a receiver with every group in umbra.
    pub fn all_groups(&self) -> u128 {
        if self.groups == MAX_GROUPS {
            u128::MAX
        } else {
            (1u128 << self.groups) - 1
        }
    }

    /// Bytes of the sets (positions, orders, samples).
    pub fn bytes(&self) -> u64 {
        (self.sets * self.n * (24 + 4 + std::mem::size_of::<LightSample>())) as u64
    }
}

/// Per group of `n` samples: the valid bits of its mask word.
fn valid_bits(n: usize, groups: usize) -> Vec<u32> {
    (0..groups)
        .map(|g| {
            let len = (n - g * GROUP).min(GROUP);
            if len == GROUP {
                u32::MAX
            } else {
                (1u32 << len) - 1
            }
        })
        .collect()
}

/// Where each receiver has samples of its own (sphere lights): its
/// samples as the kernels take them, made on first need and dropped at
/// full umbra, in a pool of slots (so the memory is that of the receivers
/// being worked on, not of the chunk).
#[derive(Debug, Default)]
pub struct ReceiverSamples {
    /// Per receiver: its key.
    keys: Vec<SampleKey>,
    /// Per receiver: its slot in the pools, or `u32::MAX`.
    slot: Vec<u32>,
    /// Per slot and group: positions relative to the light's centre.
    soa: Vec<GroupSoa>,
    /// Per slot and group: the boxes of its samples four by four.
    boxes: Vec<ChunkBoxes>,
    /// Per slot and group, where asked for: the `f32` positions for the
    /// soft-textured projector.
    projector: Vec<SamplePositions>,
    with_projector: bool,
    free: Vec<u32>,
    live: usize,
    /// Most slots alive at once.
    pub peak: usize,
    scratch: Vec<LightSample>,
    rel: Vec<DVec3>,
}

impl ReceiverSamples {
    /// An empty cache over receivers with keys `keys` (with the
    /// projector's positions too where `projector`).
    pub fn new(keys: Vec<SampleKey>, projector: bool) -> ReceiverSamples {
        ReceiverSamples {
            slot: vec![u32::MAX; keys.len()],
            keys,
            with_projector: projector,
            ..ReceiverSamples::default()
        }
    }

    /// Makes receiver `r`'s samples of `sets` (a sphere light's) if it
    /// has none yet.
    pub fn ensure(&mut self, sets: &SampleSets, r: usize) {
        if self.slot[r] != u32::MAX {
            return;
        }
        let Some(sp) = &sets.sphere else { return };
        let g = sets.groups;
        sp.sampler.samples_with(
            &sp.pattern,
            self.keys[r].position,
            self.keys[r].pixel,
            &mut self.scratch,
        );
        self.rel.clear();
        self.rel
            .extend(self.scratch.iter().map(|s| s.x.as_dvec3() - sp.centre));
        let s = if let Some(s) = self.free.pop() {
            s
        } else {
            let s = (self.soa.len() / g.max(1)) as u32;
            self.soa.resize(self.soa.len() + g, GroupSoa::new(&[]));
            self.boxes
                .resize(self.boxes.len() + g, ChunkBoxes::new(&[]));
            if self.with_projector {
                self.projector
                    .resize(self.projector.len() + g, SamplePositions::default());
            }
            s
        };
        let base = s as usize * g;
        // A receiver inside the sphere has no samples (the chunks leave
        // such receivers out): its groups stay empty and hold nothing.
        for k in 0..g {
            let part = self
                .rel
                .get(GROUP * k..(GROUP * (k + 1)).min(self.rel.len()));
            let part = part.unwrap_or(&[]);
            self.soa[base + k] = GroupSoa::new(part);
            self.boxes[base + k] = ChunkBoxes::new(part);
            if self.with_projector {
                let lp = self
                    .scratch
                    .get(GROUP * k..(GROUP * (k + 1)).min(self.scratch.len()))
                    .unwrap_or(&[]);
                self.projector[base + k].set(lp);
            }
        }
        self.slot[r] = s;
        self.live += 1;
        self.peak = self.peak.max(self.live);
    }

    /// Receiver `r`'s group `k` (of `groups`): positions and chunk boxes.
    /// It must have been made ([`ReceiverSamples::ensure`]).
    #[inline(always)]
    pub fn group(&self, r: usize, k: usize, groups: usize) -> (&GroupSoa, &ChunkBoxes) {
        let i = self.slot[r] as usize * groups + k;
        (&self.soa[i], &self.boxes[i])
    }

    /// Receiver `r`'s group `k`: the projector's positions (made with
    /// `projector`).
    pub fn projector(&self, r: usize, k: usize, groups: usize) -> &SamplePositions {
        &self.projector[self.slot[r] as usize * groups + k]
    }

    /// Drops receiver `r`'s samples (its slot is reused).
    pub fn release(&mut self, r: usize) {
        let s = self.slot[r];
        if s != u32::MAX {
            self.free.push(s);
            self.slot[r] = u32::MAX;
            self.live -= 1;
        }
    }

    /// Bytes of one receiver's samples with `groups` groups (the
    /// projector's positions included where `projector`).
    pub fn bytes_per_receiver(groups: usize, projector: bool) -> u64 {
        let per_group = std::mem::size_of::<GroupSoa>()
            + std::mem::size_of::<ChunkBoxes>()
            + if projector { 3 * 4 * GROUP } else { 0 };
        (groups * per_group) as u64
    }
}

/// Orders `idx` so that consecutive runs of 32 are nearby groups: split
/// by count along the longer side of the nominal region `extent` (the
/// same decisions for every set), full groups on the left; within a
/// group, the same down to runs of 4.
fn split(units: &[(f64, f64)], idx: &mut [u32], extent: [f64; 2]) {
    let len = idx.len();
    // Runs of 32 (the groups), then within a group runs of 4 (the
    // kernel's lanes, so the cone prefilter's chunk boxes are compact).
    let unit = if len > GROUP { GROUP } else { 4 };
    if len <= unit {
        return;
    }
    let parts = len.div_ceil(unit);
    let left = unit * (parts / 2);
    let axis = usize::from(extent[1] > extent[0]);
    let key = |i: u32| {
        let p = units[i as usize];
        if axis == 0 {
            p.0
        } else {
            p.1
        }
    };
    idx.sort_unstable_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
    let f = left as f64 / len as f64;
    let (l, r) = idx.split_at_mut(left);
    let mut le = extent;
    le[axis] *= f;
    let mut re = extent;
    re[axis] *= 1.0 - f;
    split(units, l, le);
    split(units, r, re);
}
