//! Shadow rays from one origin, eight at a time.
//!
//! The reference's rays of one receiver share their origin and point at
//! one light, so they are coherent: [`Bvh::occluded_bundle`] walks the tree
//! once per packet of [`PACKET`] rays, the stack carrying lane masks: at
//! each node every live lane runs its own single-ray test of the four
//! child boxes (`Ray::hit_boxes_rel`, the bounds minus the shared origin
//! computed once), and a leaf is tested lane by lane with the single-ray
//! triangle test when few lanes reach it, else against all eight in
//! `f32x8` / `f64x4` lanes. A node's inner children are entered nearest
//! first, by their box centres along the sum of the packet's directions:
//! an occluded lane tends to meet its occluder sooner (callgrind, light
//! pass at 256², 64 samples: spheres −3.1 %, bunny −3.3 %). Lanes whose
//! direction signs match the packet's first lane (nearly all: a packet
//! spans an eighth of the light) take the slab test with each axis's
//! near and far bound picked once per node by those signs, so no min /
//! max per axis (`Ray::hit_boxes_signed`; same verdicts bit for bit).
//! A node reached by few lanes (`SINGLE_LANES`) hands each of them to a
//! single-ray walk of its subtree (`Bvh::lane_occluded`), which enters
//! the children nearest first by the slab test's own entry distances:
//! the packet loop's masks, keys and entries cost more than they share
//! among one or two rays. `Packet::load` writes each lane's own
//! constants (inverse, shear) for every packet, but the origin, `t_max`,
//! the zero-component flags and the axes `k` to all eight rays only when
//! they change (a bundle's packets share the first two and nearly always
//! the others): 9 % of the light pass was `load`, and this saves a
//! quarter of it (callgrind, reference at 256², 64 samples, one thread:
//! spheres −2.4 %, bunny −2.3 %, 1.0M triangles −1.8 %).
//!
//! Leaves stay arrays of corners, tested triangle by triangle: a
//! structure-of-arrays layout with one ray against a whole leaf in
//! `f32x4` / `f64x4` lanes (as Embree's triangle4) was measured and
//! dropped. 95 % of the leaves a ray tests held one or two triangles
//! (1.8 triangles tested per leaf on spheres, with leaves of at most
//! four and an SAH traversal cost of 1, when this was measured), where the scalar test,
//! which stops at the first failed edge sign, costs about 45
//! instructions per triangle and the four-lane test about 95 per leaf:
//! +5 % on every scene with AVX (callgrind, reference at 256², 64
//! samples: spheres 1,672M → 1,754M instructions, bunny 820M → 863M,
//! 1.0M triangles 2,075M → 2,197M), +11–14 % with a scalar path for
//! leaves of one or two triangles.
//!
//! **Same answer as one ray at a time, bit for bit.** Every lane performs
//! exactly the arithmetic [`Bvh::occluded`] performs for that ray: the
//! per-ray constants are `Ray::new`'s, computed eight lanes at a time by
//! the same IEEE operations (`Packet::load`, held to `Ray::new` bit for
//! bit by this module's test); a child box's slab
//! distances are `(lo − origin) · inv` with the same operands (the
//! subtraction is shared by the lanes because the origin is); the
//! parallel-axis rule and the conservative far scale are the same; the
//! watertight triangle test picks each lane's own axes `kx, ky, kz` by
//! blends and runs the same f32 shear and the same f64 edge functions and
//! depth test. A lane tests a leaf's triangles only if every box above the
//! leaf passed for that lane (the stack carries lane masks), so each lane
//! tests the triangles its own walk would test; only the order differs,
//! which an "any hit" answer does not see. A lane handed to its own walk
//! at a node has passed every box above it (the same masks), and from
//! there runs its own walk's tests on the subtree: `Ray::hit_boxes_rel`,
//! or for a lane of `signed` `Ray::hit_boxes_signed`'s expressions on
//! `Rel::new`'s differences, and `Ray::intersect`. `tests/it/reference.rs` holds the
//! two against each other ray by ray.

use super::leaf::watertight_lanes;
#[cfg(target_arch = "x86_64")]
use super::leaf::watertight_lanes_avx;
use super::{Bvh, Node, Ray, Rel, FAR_SCALE, STACK};
use crate::simd::level::{level, Level};
use crate::simd::{f32x4, f32x8, f64x4};
use glam::Vec3;

/// Sorts the first `n` of the four `items` by their `keys`, largest
/// first, so that the nearest child is pushed last and popped first: a
/// comparator network with selects instead of an insertion loop, whose
/// exits the branch predictor missed; one comparator for two items, three
/// for three, five for four (most nodes have two or three children to
/// enter). With the mask-picked bounds of `Bvh::lane_occluded_signed`
/// (callgrind, `occluded_bundle_v3`, reference at 256², 64 samples): 1.0M
/// triangles −1.6 %, spheres −0.8 %, bunny −0.8 %. The order only
/// changes the time, never an any-hit answer.
#[inline(always)]
fn farthest_first<T: Copy>(keys: &mut [f32; 4], items: &mut [T; 4], n: usize) {
    let mut exchange = |a: usize, b: usize| {
        let swap = keys[a] < keys[b];
        let (ka, kb) = (keys[a], keys[b]);
        let (ia, ib) = (items[a], items[b]);
        keys[a] = if swap { kb } else { ka };
        keys[b] = if swap { ka } else { kb };
        items[a] = if swap { ib } else { ia };
        items[b] = if swap { ia } else { ib };
    };
    match n {
        0 | 1 => {}
        2 => exchange(0, 1),
        3 => {
            exchange(0, 1);
            exchange(1, 2);
            exchange(0, 1);
        }
        _ => {
            exchange(0, 1);
            exchange(2, 3);
            exchange(0, 2);
            exchange(1, 3);
            exchange(1, 2);
        }
    }
}

/// A node reached by at least this many lanes tests its four boxes
/// against all of them at once (`Packet::hit_boxes_lanes`), box by box;
/// fewer lanes test ray by ray. Measured (spheres and bunny, 512², 64
/// samples, one thread, interleaved runs): 6 is 2–4 % faster than ray by
/// ray throughout; 4 and 2 are slower (callgrind +0 % and +5 %).
const BOX_MAJOR_LANES: u32 = 6;

/// Rays per packet.
pub const PACKET: usize = 8;

/// A node reached by at most this many lanes hands each of them to its
/// own single-ray walk of the subtree (`Bvh::lane_occluded`): the packet
/// loop's per-node work (lane masks, sort keys, entries) serves one or
/// two rays there. Half the packets' node visits have one lane, another
/// eighth two (1.0M triangles, 512², 64 samples: 13.3M and 3.2M of
/// 25.4M). Callgrind, reference light pass at 256², 64 samples, the
/// walks only: 1 lane −9.8 %, 2 lanes −10.4 % on 1.0M triangles (81
/// spheres at 80 segments, instrumented build); as committed, against
/// the packet loop alone: 1.0M triangles −13.5 %, spheres −5.3 %, bunny
/// −8.1 %.
const SINGLE_LANES: u32 = 2;

/// All eight lanes.
const ALL: u32 = (1 << PACKET) - 1;

/// A leaf reached by at most this many lanes is tested with the
/// single-ray triangle test lane by lane; the eight-lane test costs about
/// as much as four single ones.
const SCALAR_LANES: u32 = 3;

/// Up to eight rays from one origin, as lanes.
pub(super) struct Packet {
    origin: Vec3,
    /// Lanes holding a usable ray (finite, non-zero direction).
    pub(super) valid: u32,
    t_max: f32,
    /// The eight-lane triangle test's constants.
    woop: Woop,
    /// Each valid lane's own single-ray constants (those `Ray::new`
    /// computes; invalid lanes hold `Ray::UNUSED` and are never read): the
    /// box test runs ray by ray against a node's four children, and leaves
    /// reached by few lanes use the single-ray triangle test itself.
    rays: [Ray; PACKET],
    /// The origin splatted per axis.
    org: [f32x4; 3],
    /// The lanes' slab inverses per axis (`Ray::inv`, one lane per ray)
    /// and `t_max` in every lane, for the box-major test.
    inv: [f32x8; 3],
    t_max8: f32x8,
    /// Valid lanes with a zero direction component (`Ray::any_parallel`):
    /// they always take the ray-by-ray test.
    parallel: u32,
    /// The sum of the valid lanes' directions, splatted per axis: the
    /// walk enters the children nearest the origin along it first.
    mean: [f32x4; 3],
    /// Per axis, whether the first non-parallel lane's direction is
    /// positive there; `signed` are the non-parallel lanes whose signs
    /// all agree with it, which take `Ray::hit_boxes_signed`.
    signs: [bool; 3],
    signed: u32,
    /// Whether the CPU has AVX (`simd::avx::available`): the box-major
    /// and the eight-lane triangle tests then run in AVX registers.
    avx: bool,
    /// What all eight `rays` hold, so that `load` writes it only when it
    /// changes (a bundle's packets share the origin and `t_max`, and
    /// nearly always have the same axes and no zero component): the bits
    /// of `origin` and `t_max`; whether any ray's `parallel` may be set
    /// (false: all clear); the axes `k` of every ray, if the same.
    rays_shared: Option<([u32; 3], u32)>,
    rays_parallel: bool,
    rays_k: Option<[usize; 3]>,
}

impl Packet {
    /// An empty packet (no valid lane), to be filled by [`Packet::load`]:
    /// the bundle loops reuse one packet rather than move a new one (over
    /// a kilobyte) into place for every eight rays.
    pub(super) fn empty() -> Packet {
        Packet {
            origin: Vec3::ZERO,
            valid: 0,
            t_max: 0.0,
            woop: Woop::new(&[[1.0; PACKET]; 3], 0),
            rays: [Ray::UNUSED; PACKET],
            org: [f32x4::ZERO; 3],
            inv: [f32x8::ZERO; 3],
            t_max8: f32x8::ZERO,
            parallel: 0,
            mean: [f32x4::ZERO; 3],
            signs: [true; 3],
            signed: 0,
            avx: crate::simd::avx::available(),
            rays_shared: None,
            rays_parallel: true,
            rays_k: None,
        }
    }

    /// Makes this the packet of `dirs` (at most [`PACKET`]) from `origin`.
    /// Every valid lane's constants are those `Ray::new` computes for its
    /// ray, by the same IEEE operations done eight lanes at a time
    /// (divisions, the clamp as a max and a min, the dominant-axis rule as
    /// compares); `tests` holds the two lane by lane on zero, subnormal,
    /// huge and non-finite components. Invalid lanes keep stale constants,
    /// which nothing reads.
    #[inline(always)]
    pub(super) fn load(&mut self, origin: Vec3, dirs: &[Vec3], t_max: f32) {
        let n = dirs.len().min(PACKET);
        let mut d = [[1.0f32; PACKET]; 3];
        for (lane, dir) in dirs.iter().take(n).enumerate() {
            for axis in 0..3 {
                d[axis][lane] = dir[axis];
            }
        }
        let [dx, dy, dz] = d.map(f32x8::new);
        // `Ray::new`'s refusal: a zero or non-finite direction or origin.
        let max = f32x8::splat(f32::MAX);
        let zero = f32x8::ZERO;
        let finite = dx.abs().cmp_le(max) & dy.abs().cmp_le(max) & dz.abs().cmp_le(max);
        let nonzero = !(dx.cmp_eq(zero) & dy.cmp_eq(zero) & dz.cmp_eq(zero));
        let mut valid = (finite & nonzero).move_mask() & ((1u32 << n) - 1);
        if !origin.is_finite() {
            valid = 0;
        }
        // The slab inverses: `(1 / d).clamp(−MAX, MAX)`, no NaN (d finite).
        let one = f32x8::splat(1.0);
        let lowest = f32x8::splat(-f32::MAX);
        let inv = |c: f32x8| (one / c).max(lowest).min(max);
        let inv8 = [inv(dx), inv(dy), inv(dz)];
        let inv = inv8.map(f32x8::to_array);
        let parallel = [dx, dy, dz].map(|c| c.cmp_eq(zero).move_mask());
        self.inv = inv8;
        self.t_max8 = f32x8::splat(t_max);
        self.parallel = (parallel[0] | parallel[1] | parallel[2]) & valid;
        // Lanes whose direction signs match the first non-parallel lane's.
        let positive = [dx, dy, dz].map(|c| c.cmp_gt(zero).move_mask());
        let sloped = valid & !self.parallel;
        self.signed = 0;
        if sloped != 0 {
            let first = sloped.trailing_zeros();
            self.signs = positive.map(|m| (m >> first) & 1 == 1);
            let mut agree = sloped;
            for (axis, &m) in positive.iter().enumerate() {
                agree &= if self.signs[axis] { m } else { !m };
            }
            self.signed = agree;
        }
        let woop = Woop::new(&d, valid);
        // Each lane's axes as `Woop::new` evaluated `Ray::new`'s rule: the
        // uniform axes every valid lane shares (the usual case), else per
        // lane 0 where "is 0", 1 where "is 1", 2 otherwise.
        let picks = woop
            .pick
            .map(|[is0, is1]| [is0.move_mask(), is1.move_mask()]);
        let shear = woop.shear.map(f32x8::to_array);
        let any_parallel = parallel[0] | parallel[1] | parallel[2];
        // The constants every ray shares, and those that rarely change,
        // written to all eight rays only when they differ from what the
        // rays hold (`rays_*`); the lanes' own below.
        let shared = (origin.to_array().map(f32::to_bits), t_max.to_bits());
        if self.rays_shared != Some(shared) {
            for ray in &mut self.rays {
                ray.origin = origin;
                ray.t_max = t_max;
            }
            self.rays_shared = Some(shared);
        }
        if any_parallel != 0 || self.rays_parallel {
            for (lane, ray) in self.rays.iter_mut().enumerate() {
                ray.parallel = [0, 1, 2].map(|axis| (parallel[axis] >> lane) & 1 == 1);
                ray.any_parallel = (any_parallel >> lane) & 1 == 1;
            }
            self.rays_parallel = any_parallel != 0;
        }
        if let Some(axes) = woop.uniform {
            if self.rays_k != Some(axes) {
                for ray in &mut self.rays {
                    ray.k = axes;
                }
                self.rays_k = Some(axes);
            }
        } else {
            self.rays_k = None;
        }
        let mut lanes = valid;
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let ray = &mut self.rays[lane];
            if woop.uniform.is_none() {
                ray.k = picks.map(|[is0, is1]| {
                    if (is0 >> lane) & 1 == 1 {
                        0
                    } else if (is1 >> lane) & 1 == 1 {
                        1
                    } else {
                        2
                    }
                });
            }
            ray.inv = [
                f32x4::splat(inv[0][lane]),
                f32x4::splat(inv[1][lane]),
                f32x4::splat(inv[2][lane]),
            ];
            ray.shear = Vec3::new(shear[0][lane], shear[1][lane], shear[2][lane]);
        }
        let mut mean = [0.0f32; 3];
        let mut lanes = valid;
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            for axis in 0..3 {
                mean[axis] += d[axis][lane];
            }
        }
        self.mean = mean.map(f32x4::splat);
        self.origin = origin;
        self.valid = valid;
        self.t_max = t_max;
        self.woop = woop;
        self.org = [
            f32x4::splat(origin.x),
            f32x4::splat(origin.y),
            f32x4::splat(origin.z),
        ];
    }

    /// The eight-lane triangle test's constants.
    #[inline]
    fn woop(&self) -> &Woop {
        &self.woop
    }
}

/// The watertight test's per-lane constants, as `Ray::new` computes them
/// (the same IEEE operations, the same dominant-axis rule).
struct Woop {
    /// For `kx`, `ky`, `kz`, the masks "k = 0" and "k = 1" (else 2).
    pick: [[f32x8; 2]; 3],
    /// `Some([kx, ky, kz])` when every valid lane has the same axes (the
    /// usual case): the picks are then plain indexing, no blends.
    uniform: Option<[usize; 3]>,
    shear: [f32x8; 3],
}

impl Woop {
    /// The constants of the lanes `valid` of directions `d`.
    #[inline(always)]
    fn new(d: &[[f32; PACKET]; 3], valid: u32) -> Woop {
        let [dx, dy, dz] = d.map(f32x8::new);
        let one = f32x8::splat(1.0);
        let zero = f32x8::ZERO;
        // kz: x if |x| ≥ |y| and |x| ≥ |z|, else y if |y| ≥ |z|, else z.
        let (ax, ay, az) = (dx.abs(), dy.abs(), dz.abs());
        let z0 = ax.cmp_ge(ay) & ax.cmp_ge(az);
        let z1 = !z0 & ay.cmp_ge(az);
        let z2 = !(z0 | z1);
        let pick = |m0: f32x8, m1: f32x8| m0.blend(dx, m1.blend(dy, dz));
        let dkz = pick(z0, z1);
        // kx, ky = kz + 1, kz + 2 (mod 3), swapped when dir[kz] < 0.
        let neg = dkz.cmp_lt(zero);
        let x0 = (z1 & neg) | (z2 & !neg);
        let x1 = (z0 & !neg) | (z2 & neg);
        let y0 = (z1 & !neg) | (z2 & neg);
        let y1 = (z0 & neg) | (z2 & !neg);
        let shear = [pick(x0, x1) / dkz, pick(y0, y1) / dkz, one / dkz];
        let pick = [[x0, x1], [y0, y1], [z0, z1]];
        let uniform = (|| {
            let mut k = [0usize; 3];
            for (axis, [is0, is1]) in pick.iter().enumerate() {
                let (m0, m1) = (is0.move_mask() & valid, is1.move_mask() & valid);
                k[axis] = match (m0, m1) {
                    (m, 0) if m == valid => 0,
                    (0, m) if m == valid => 1,
                    (0, 0) => 2,
                    _ => return None,
                };
            }
            Some(k)
        })();
        Woop {
            pick,
            uniform,
            shear,
        }
    }
}

impl Packet {
    /// `Ray::hit_boxes_rel` for every lane of `lanes` at once, box by box:
    /// byte `slot` of the result holds the lanes passing child `slot`.
    /// Each lane's verdict is its own test's bit for bit: the same
    /// products `(bound − origin) · inv` (the operands swapped, which IEEE
    /// multiplication does not see), the same min / max in the same order
    /// from the same starting values, the same far scale and compare.
    /// Lanes with a zero direction component must not be in `lanes`.
    #[inline(always)]
    fn hit_boxes_lanes(&self, rel: &Rel, lanes: u32) -> u32 {
        let lo = rel.lo.map(f32x4::to_array);
        let hi = rel.hi.map(f32x4::to_array);
        let scale = f32x8::splat(FAR_SCALE);
        let mut through = 0u32;
        for slot in 0..4 {
            let mut near = f32x8::ZERO;
            let mut far = self.t_max8;
            for axis in 0..3 {
                let t0 = f32x8::splat(lo[axis][slot]) * self.inv[axis];
                let t1 = f32x8::splat(hi[axis][slot]) * self.inv[axis];
                near = near.max(t0.min(t1));
                far = far.min(t0.max(t1));
            }
            through |= (near.cmp_le(far * scale).move_mask() & lanes) << (8 * slot);
        }
        through
    }

    /// [`Packet::hit_boxes_lanes`] for lanes that all have the packet's
    /// direction signs (`signed`): each axis's entry and exit distances
    /// are the products of the bounds [`Rel::signed`] picks, with no min /
    /// max between them; the same verdicts bit for bit, by
    /// `Ray::hit_boxes_signed`'s argument.
    #[inline(always)]
    fn hit_boxes_lanes_signed(&self, rel: &Rel, lanes: u32) -> u32 {
        let (near_rel, far_rel) = rel.signed(self.signs);
        let near_rel = near_rel.map(|v| v.to_array());
        let far_rel = far_rel.map(|v| v.to_array());
        let scale = f32x8::splat(FAR_SCALE);
        let mut through = 0u32;
        for slot in 0..4 {
            let mut near = f32x8::ZERO;
            let mut far = self.t_max8;
            for axis in 0..3 {
                near = near.max(f32x8::splat(near_rel[axis][slot]) * self.inv[axis]);
                far = far.min(f32x8::splat(far_rel[axis][slot]) * self.inv[axis]);
            }
            through |= (near.cmp_le(far * scale).move_mask() & lanes) << (8 * slot);
        }
        through
    }

    /// [`Packet::hit_boxes_lanes_signed`] in AVX registers: the same
    /// operations in the same order on the same values (each `F32x8`
    /// operation is its facade namesake's, `simd::avx`), so the same bits;
    /// `tests` holds the two equal.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn hit_boxes_lanes_signed_avx(&self, rel: &Rel, lanes: u32) -> u32 {
        use crate::simd::avx::F32x8;
        let (near_rel, far_rel) = rel.signed(self.signs);
        let near_rel = near_rel.map(|v| v.to_array());
        let far_rel = far_rel.map(|v| v.to_array());
        let inv = [0, 1, 2].map(|axis| F32x8::from_lanes(self.inv[axis]));
        let t_max = F32x8::from_lanes(self.t_max8);
        let scale = F32x8::splat(FAR_SCALE);
        let mut through = 0u32;
        for slot in 0..4 {
            let mut near = F32x8::splat(0.0);
            let mut far = t_max;
            for axis in 0..3 {
                near = near.max(F32x8::splat(near_rel[axis][slot]).mul(inv[axis]));
                far = far.min(F32x8::splat(far_rel[axis][slot]).mul(inv[axis]));
            }
            through |= (near.le_mask(far.mul(scale)) & lanes) << (8 * slot);
        }
        through
    }

    /// [`Packet::hit_boxes_lanes_signed`], in AVX registers when the CPU
    /// has AVX (same bits either way).
    #[inline]
    fn hit_boxes_signed_best(&self, rel: &Rel, lanes: u32) -> u32 {
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: `avx` is set only when `simd::avx::available()`
            // found AVX on this CPU, the one requirement of the
            // `target_feature` function.
            return unsafe { self.hit_boxes_lanes_signed_avx(rel, lanes) };
        }
        self.hit_boxes_lanes_signed(rel, lanes)
    }

    /// Lanes that `Ray::intersect` would find hitting `tri`.
    #[inline(always)]
    fn hit_triangle(&self, tri: &[Vec3; 3]) -> u32 {
        let a = tri[0] - self.origin;
        let b = tri[1] - self.origin;
        let c = tri[2] - self.origin;
        // The same values either way on every valid lane (the only lanes
        // the caller reads).
        let woop = self.woop();
        let pick = |v: Vec3, k: usize| match woop.uniform {
            Some(axes) => f32x8::splat(v[axes[k]]),
            None => {
                let [is0, is1] = woop.pick[k];
                is0.blend(
                    f32x8::splat(v.x),
                    is1.blend(f32x8::splat(v.y), f32x8::splat(v.z)),
                )
            }
        };
        let [sx, sy, sz] = woop.shear;
        let (akz, bkz, ckz) = (pick(a, 2), pick(b, 2), pick(c, 2));
        let ax = (pick(a, 0) - sx * akz).widen();
        let ay = (pick(a, 1) - sy * akz).widen();
        let bx = (pick(b, 0) - sx * bkz).widen();
        let by = (pick(b, 1) - sy * bkz).widen();
        let cx = (pick(c, 0) - sx * ckz).widen();
        let cy = (pick(c, 1) - sy * ckz).widen();
        let (akz, bkz, ckz, sz) = (akz.widen(), bkz.widen(), ckz.widen(), sz.widen());
        let t_max = f64x4::splat(f64::from(self.t_max));
        let mut mask = 0;
        for h in 0..2 {
            let xy = [ax[h], ay[h], bx[h], by[h], cx[h], cy[h]];
            let kz = [akz[h], bkz[h], ckz[h]];
            mask |= watertight_lanes(xy, kz, sz[h], t_max) << (4 * h);
        }
        mask
    }
}

impl Packet {
    /// The lanes of `through` hitting one of `tris` ([`Packet::hit_triangle`]
    /// triangle by triangle, stopping once every lane of `through` hit), in
    /// AVX registers: the same operations in the same order on the same
    /// values (each `simd::avx` operation is its facade namesake's IEEE
    /// operation, and `F32x8::widen` the same exact conversion), so the
    /// same bits; `tests` holds the two equal.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn hit_triangles_avx(&self, tris: impl Iterator<Item = [Vec3; 3]>, through: u32) -> u32 {
        use crate::simd::avx::{F32x8, F64x4};
        let woop = self.woop();
        let [sx, sy, sz] = woop.shear.map(|v| F32x8::load(&v.to_array()));
        let picks = woop
            .pick
            .map(|[is0, is1]| [F32x8::from_lanes(is0), F32x8::from_lanes(is1)]);
        let sz = sz.widen();
        let t_max = F64x4::splat(f64::from(self.t_max));
        let mut hit = 0;
        for tri in tris {
            let a = tri[0] - self.origin;
            let b = tri[1] - self.origin;
            let c = tri[2] - self.origin;
            let pick = |v: Vec3, k: usize| match woop.uniform {
                Some(axes) => F32x8::splat(v[axes[k]]),
                None => {
                    let [is0, is1] = picks[k];
                    is0.blend(
                        F32x8::splat(v.x),
                        is1.blend(F32x8::splat(v.y), F32x8::splat(v.z)),
                    )
                }
            };
            let (akz, bkz, ckz) = (pick(a, 2), pick(b, 2), pick(c, 2));
            let ax = pick(a, 0).sub(sx.mul(akz)).widen();
            let ay = pick(a, 1).sub(sy.mul(akz)).widen();
            let bx = pick(b, 0).sub(sx.mul(bkz)).widen();
            let by = pick(b, 1).sub(sy.mul(bkz)).widen();
            let cx = pick(c, 0).sub(sx.mul(ckz)).widen();
            let cy = pick(c, 1).sub(sy.mul(ckz)).widen();
            let (akz, bkz, ckz) = (akz.widen(), bkz.widen(), ckz.widen());
            let mut mask = 0;
            for h in 0..2 {
                let xy = [ax[h], ay[h], bx[h], by[h], cx[h], cy[h]];
                let kz = [akz[h], bkz[h], ckz[h]];
                mask |= watertight_lanes_avx(xy, kz, sz[h], t_max) << (4 * h);
            }
            hit |= mask & through;
            if through & !hit == 0 {
                break;
            }
        }
        hit
    }
}

impl Bvh {
    /// Whether each segment `origin + t · dirs[i]`, `t ∈ (0, t_max)`, hits
    /// a triangle: `out[i]` is exactly [`Bvh::occluded`]`(origin, dirs[i],
    /// t_max)` (see the module docs), computed [`PACKET`] rays at a time.
    /// `out` must be as long as `dirs`.
    pub fn occluded_bundle(&self, origin: Vec3, dirs: &[Vec3], t_max: f32, out: &mut [bool]) {
        self.occluded_bundle_at(level(), origin, dirs, t_max, out);
    }

    /// [`Bvh::occluded_bundle`] compiled for `level` (`simd::level`; the
    /// baseline copy where this CPU lacks it): the same answers at every
    /// level.
    pub fn occluded_bundle_at(
        &self,
        level: Level,
        origin: Vec3,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
    ) {
        #[cfg(target_arch = "x86_64")]
        if level == Level::V3 && level.supported() {
            // SAFETY: the CPU has every feature the v3 copy enables
            // (`Level::supported`), its one requirement.
            return unsafe { self.occluded_bundle_v3(origin, dirs, t_max, out) };
        }
        let _ = level;
        self.occluded_bundle_body(origin, dirs, t_max, out);
    }

    /// [`Bvh::occluded_bundle_body`] compiled for `Level::V3`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
    fn occluded_bundle_v3(&self, origin: Vec3, dirs: &[Vec3], t_max: f32, out: &mut [bool]) {
        self.occluded_bundle_body(origin, dirs, t_max, out);
    }

    /// The bundle walk itself, inlined into each level's copy.
    #[inline(always)]
    pub(super) fn occluded_bundle_body(
        &self,
        origin: Vec3,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
    ) {
        out.fill(false);
        if self.nodes.is_empty() || !(t_max > 0.0) {
            return;
        }
        let mut last = None;
        let mut packet = Packet::empty();
        // One stack for the bundle's packets: zeroing its 1.7 kB for every
        // packet was 0.8 % of the reference's instructions (each walk
        // writes an entry before reading it).
        let mut stack = [(0u32, 0u32); STACK];
        for (chunk, res) in dirs.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
            packet.load(origin, chunk, t_max);
            if packet.valid == 0 {
                continue;
            }
            let hit = self.packet_occluded(&packet, &mut last, &mut stack);
            for (lane, r) in res.iter_mut().enumerate() {
                *r = hit >> lane & 1 == 1;
            }
        }
    }

    /// The lanes of `packet` whose ray hits a triangle. `last` is the
    /// leaf (node, slot) where the previous packet of the bundle found a
    /// hit, tried first: neighbouring rays tend to hit the same occluder.
    /// Trying it first changes no answer: a lane tests its triangles only
    /// if it passes the leaf's own box, and then it passes every box above
    /// it (each encloses the leaf's box, and the rounded slab distances
    /// are monotone in the bounds), so its own walk would test them too.
    /// `stack` is scratch space.
    #[inline(always)]
    fn packet_occluded(
        &self,
        packet: &Packet,
        last: &mut Option<(u32, usize)>,
        stack: &mut [(u32, u32); STACK],
    ) -> u32 {
        let mut hit = 0u32;
        if let Some((index, slot)) = *last {
            if let Some(node) = self.nodes.get(index as usize) {
                hit = self.leaf_hits(packet, node, slot, packet.valid);
                if hit == packet.valid {
                    return hit;
                }
            }
        }
        stack[0] = (0, packet.valid & !hit);
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let (index, lanes) = stack[top];
            let mut lanes = lanes & !hit;
            if lanes == 0 {
                continue;
            }
            if lanes.count_ones() <= SINGLE_LANES {
                // Each lane walks the subtree on its own, in the stack
                // above `top`: together they are the entries one ray's
                // depth-first walk would hold, so within `STACK`.
                while lanes != 0 {
                    let lane = lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    if let Some(leaf) = self.lane_occluded(packet, lane, index, stack, top) {
                        hit |= 1 << lane;
                        *last = Some(leaf);
                    }
                }
                if hit == packet.valid & ALL {
                    break;
                }
                continue;
            }
            let Some(node) = self.nodes.get(index as usize) else {
                continue;
            };
            // Ray by ray against the four children (exactly
            // `Ray::hit_boxes`, the bounds minus the shared origin computed
            // once); byte `slot` of `through` collects the lanes passing
            // child `slot`.
            let rel = Rel::new(node, &packet.org);
            let mut through = 0u32;
            if lanes.count_ones() >= BOX_MAJOR_LANES {
                let major = lanes & !packet.parallel;
                through = if major & !packet.signed == 0 {
                    packet.hit_boxes_signed_best(&rel, major)
                } else {
                    packet.hit_boxes_lanes(&rel, major)
                };
                lanes &= packet.parallel;
            }
            let mut fast = lanes & packet.signed;
            if fast != 0 {
                lanes &= !fast;
                let (near, far) = rel.signed(packet.signs);
                while fast != 0 {
                    let lane = fast.trailing_zeros();
                    fast &= fast - 1;
                    let m = packet.rays[lane as usize].hit_boxes_signed(near, far);
                    through |= ((m * 0x0020_4081) & 0x0101_0101) << lane;
                }
            }
            while lanes != 0 {
                let lane = lanes.trailing_zeros();
                lanes &= lanes - 1;
                let m = packet.rays[lane as usize].hit_boxes_rel(node, &rel);
                // Bit `s` of the 4-bit `m` to bit `8 s`.
                through |= ((m * 0x0020_4081) & 0x0101_0101) << lane;
            }
            // Inner children to enter: `(child << 32 | lanes)` and the
            // sort key; empty slots keep key −∞, below every real key.
            let mut inner = [0u64; 4];
            let mut inner_keys = [f32::NEG_INFINITY; 4];
            let mut n_inner = 0;
            let keys = ((rel.lo[0] + rel.hi[0]) * packet.mean[0]
                + (rel.lo[1] + rel.hi[1]) * packet.mean[1]
                + (rel.lo[2] + rel.hi[2]) * packet.mean[2])
                .to_array();
            while through != 0 {
                let slot = (through.trailing_zeros() / 8) as usize;
                let pass = (through >> (8 * slot)) & ALL & !hit;
                through &= !(0xff << (8 * slot));
                if pass == 0 {
                    continue;
                }
                let count = node.count[slot] as usize;
                if count == 0 {
                    // Sorted below; a NaN key counts as the lowest real
                    // one, so it never falls behind an empty slot.
                    inner[n_inner] = u64::from(node.child[slot]) << 32 | u64::from(pass);
                    inner_keys[n_inner] = keys[slot].max(f32::MIN);
                    n_inner += 1;
                    continue;
                }
                let found = self.triangle_hits(packet, node, slot, pass);
                if found != 0 {
                    hit |= found;
                    *last = Some((index, slot));
                }
            }
            if n_inner > 1 {
                farthest_first(&mut inner_keys, &mut inner, n_inner);
            }
            for &entry in &inner[..n_inner] {
                let (child, pass) = ((entry >> 32) as u32, entry as u32);
                // Cannot overflow (see `STACK`); the check only keeps the
                // index provably in bounds.
                if top < STACK {
                    stack[top] = (child, pass);
                    top += 1;
                }
            }
            if hit == packet.valid & ALL {
                break;
            }
        }
        hit & packet.valid
    }

    /// Lane `lane`'s own walk of the subtree under node `root` (which the
    /// lane reached): the leaf `(node, slot)` of the first triangle it
    /// hits, if any. The tests are the lane's own (see
    /// [`Bvh::lane_occluded_signed`] for the sign-picked slabs); children
    /// are entered nearest first by the packet's key. `stack[base..]` is
    /// scratch space.
    #[inline(always)]
    fn lane_occluded(
        &self,
        packet: &Packet,
        lane: usize,
        root: u32,
        stack: &mut [(u32, u32); STACK],
        base: usize,
    ) -> Option<(u32, usize)> {
        if packet.signed >> lane & 1 == 1 {
            return self.lane_occluded_signed(packet, lane, root, stack, base);
        }
        let ray = &packet.rays[lane];
        let mut top = base;
        if top < STACK {
            stack[top] = (root, 0);
            top += 1;
        }
        while top > base {
            top -= 1;
            let index = stack[top].0;
            let Some(node) = self.nodes.get(index as usize) else {
                continue;
            };
            let rel = Rel::new(node, &packet.org);
            let mask = ray.hit_boxes_rel(node, &rel);
            let keys = ((rel.lo[0] + rel.hi[0]) * packet.mean[0]
                + (rel.lo[1] + rel.hi[1]) * packet.mean[1]
                + (rel.lo[2] + rel.hi[2]) * packet.mean[2])
                .to_array()
                // A NaN key counts as the lowest real one.
                .map(|k| k.max(f32::MIN));
            if let Some(leaf) =
                self.lane_children(ray, packet.avx, node, index, mask, keys, stack, &mut top)
            {
                return Some(leaf);
            }
        }
        None
    }

    /// [`Bvh::lane_occluded`] for a lane of `packet.signed`: each node's
    /// four slab tests are `Ray::hit_boxes_signed`'s expressions on
    /// `Rel::new`'s differences (the same products `(bound − origin) ·
    /// inv`, the same `max` / `min` chains from 0 and `t_max` in axis
    /// order, the same far scale and compare), so the same verdicts bit
    /// for bit; their entry distances order the children, nearest first.
    #[inline(always)]
    fn lane_occluded_signed(
        &self,
        packet: &Packet,
        lane: usize,
        root: u32,
        stack: &mut [(u32, u32); STACK],
        base: usize,
    ) -> Option<(u32, usize)> {
        let ray = &packet.rays[lane];
        let (org, inv) = (&packet.org, ray.inv);
        // All ones along the axes where the direction is positive.
        let all_ones = f32x4::ZERO.cmp_eq(f32x4::ZERO);
        let positive = packet.signs.map(|p| if p { all_ones } else { !all_ones });
        let t_max = f32x4::splat(ray.t_max);
        let scale = f32x4::splat(FAR_SCALE);
        let mut top = base;
        if top < STACK {
            stack[top] = (root, 0);
            top += 1;
        }
        while top > base {
            top -= 1;
            let index = stack[top].0;
            let Some(node) = self.nodes.get(index as usize) else {
                continue;
            };
            // `Rel::new`'s differences, picked as `Rel::signed` picks.
            // Selected by masks (the same values), not by branches on
            // `signs`, one per axis and node (2 % of the walk's
            // instructions on 1.0M triangles).
            let pick = |axis: usize| {
                let lo = f32x4::new(node.lo[axis]) - org[axis];
                let hi = f32x4::new(node.hi[axis]) - org[axis];
                (positive[axis].blend(lo, hi), positive[axis].blend(hi, lo))
            };
            let ((n0, f0), (n1, f1), (n2, f2)) = (pick(0), pick(1), pick(2));
            let near = f32x4::splat(0.0)
                .max(n0 * inv[0])
                .max(n1 * inv[1])
                .max(n2 * inv[2]);
            let far = t_max.min(f0 * inv[0]).min(f1 * inv[1]).min(f2 * inv[2]);
            let mask = near.cmp_le(far * scale).move_mask();
            // Only the order: a NaN key (none is expected: `Ray::new`
            // leaves no `0 · ∞`) changes no answer.
            let keys = near.to_array();
            if let Some(leaf) =
                self.lane_children(ray, packet.avx, node, index, mask, keys, stack, &mut top)
            {
                return Some(leaf);
            }
        }
        None
    }

    /// One node of a lane's own walk: tests the triangles of the leaf
    /// children in `mask` (returning the first leaf with a hit) and
    /// pushes the inner ones onto `stack`, the one of least key last.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn lane_children(
        &self,
        ray: &Ray,
        avx: bool,
        node: &Node,
        index: u32,
        mut mask: u32,
        keys: [f32; 4],
        stack: &mut [(u32, u32); STACK],
        top: &mut usize,
    ) -> Option<(u32, usize)> {
        self.prefetch_children(node, mask);
        let mut inner = [0u32; 4];
        let mut inner_keys = [f32::NEG_INFINITY; 4];
        let mut n_inner = 0;
        while mask != 0 {
            let slot = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let count = node.count[slot] as usize;
            if count == 0 {
                inner[n_inner] = node.child[slot];
                inner_keys[n_inner] = keys[slot];
                n_inner += 1;
                continue;
            }
            let Some(leaf) = self.tris.leaf(node.child[slot] as usize, count) else {
                continue;
            };
            if ray.hits_leaf(leaf, avx) {
                return Some((index, slot));
            }
        }
        if n_inner > 1 {
            farthest_first(&mut inner_keys, &mut inner, n_inner);
        }
        for &child in &inner[..n_inner] {
            // Cannot overflow (see `STACK`); the check only keeps the
            // index provably in bounds.
            if *top < STACK {
                stack[*top] = (child, 0);
                *top += 1;
            }
        }
        None
    }

    /// Asks the cache for the children in `mask` before any is read: a
    /// leaf's triangles (tested at once) and an inner child's node (popped
    /// soon), so their misses overlap instead of following one another.
    #[inline(always)]
    pub(super) fn prefetch_children(&self, node: &Node, mask: u32) {
        #[cfg(target_arch = "x86_64")]
        let mut mask = mask;
        #[cfg(target_arch = "x86_64")]
        while mask != 0 {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let slot = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let child = node.child[slot] as usize;
            let line = if node.count[slot] == 0 {
                self.nodes.as_ptr().wrapping_add(child).cast::<i8>()
            } else {
                self.tris.leaf_ptr(child).cast::<i8>()
            };
            // SAFETY: a prefetch is a hint that never faults and reads
            // nothing into the program, whatever the address;
            // `wrapping_add` keeps the pointer arithmetic defined.
            unsafe {
                _mm_prefetch(line, _MM_HINT_T0);
                _mm_prefetch(line.wrapping_add(64), _MM_HINT_T0);
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (node, mask);
    }

    /// The lanes of `lanes` that pass leaf `slot`'s box and hit one of its
    /// triangles.
    #[inline(always)]
    pub(super) fn leaf_hits(&self, packet: &Packet, node: &Node, slot: usize, lanes: u32) -> u32 {
        if node.count[slot] == 0 {
            return 0;
        }
        // Each lane's own `Ray::hit_boxes`.
        let rel = Rel::new(node, &packet.org);
        let mut through = 0;
        let mut fast = lanes & packet.signed;
        if fast != 0 {
            let (near, far) = rel.signed(packet.signs);
            while fast != 0 {
                let lane = fast.trailing_zeros();
                fast &= fast - 1;
                let m = packet.rays[lane as usize].hit_boxes_signed(near, far);
                through |= (m >> slot & 1) << lane;
            }
        }
        let mut l = lanes & !packet.signed;
        while l != 0 {
            let lane = l.trailing_zeros();
            l &= l - 1;
            through |= (packet.rays[lane as usize].hit_boxes_rel(node, &rel) >> slot & 1) << lane;
        }
        if through == 0 {
            return 0;
        }
        self.triangle_hits(packet, node, slot, through)
    }

    /// The lanes of `through` that hit one of leaf `slot`'s triangles.
    #[inline(always)]
    fn triangle_hits(&self, packet: &Packet, node: &Node, slot: usize, through: u32) -> u32 {
        let first = node.child[slot] as usize;
        let count = node.count[slot] as usize;
        let Some(leaf) = self.tris.leaf(first, count) else {
            return 0;
        };
        let mut hit = 0;
        if through.count_ones() <= SCALAR_LANES {
            // Few lanes: the single-ray test itself, lane by lane.
            let mut lanes = through;
            while lanes != 0 {
                let lane = lanes.trailing_zeros();
                lanes &= lanes - 1;
                if packet.rays[lane as usize].hits_leaf(leaf, packet.avx) {
                    hit |= 1 << lane;
                }
            }
            return hit;
        }
        #[cfg(target_arch = "x86_64")]
        if packet.avx {
            // SAFETY: `avx` is set only when `simd::avx::available()`
            // found AVX on this CPU, the one requirement of the
            // `target_feature` function.
            return unsafe { packet.hit_triangles_avx(leaf.iter(), through) };
        }
        for tri in leaf.iter() {
            hit |= packet.hit_triangle(&tri) & through;
            if through & !hit == 0 {
                break;
            }
        }
        hit
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::bvh::centred_units;

    /// The bits of everything `Ray::new` computes.
    fn ray_bits(r: &Ray) -> Vec<u32> {
        let mut v = vec![r.t_max.to_bits()];
        v.extend(r.origin.to_array().map(f32::to_bits));
        for inv in r.inv {
            v.extend(inv.to_array().map(f32::to_bits));
        }
        v.extend(r.parallel.map(u32::from));
        v.push(u32::from(r.any_parallel));
        v.extend(r.k.map(|k| k as u32));
        v.extend(r.shear.to_array().map(f32::to_bits));
        v
    }

    /// A node with 1 to 4 random leaf boxes (flat ones every seventh
    /// round), the other slots empty (the point at +∞).
    fn random_node(round: usize, unit: &mut impl FnMut() -> f32) -> Node {
        let mut node = Node::EMPTY;
        for slot in 0..(1 + round % 4) {
            for axis in 0..3 {
                let (a, b) = (unit() * 6.0, unit() * 6.0);
                let flat = round.is_multiple_of(7);
                node.lo[axis][slot] = a.min(b);
                node.hi[axis][slot] = if flat { a.min(b) } else { a.max(b) };
            }
            node.count[slot] = 1;
        }
        node
    }

    /// The box-major test gives every lane its own ray-by-ray verdict, on
    /// boxes around, through, behind and beyond the origin, flat ones,
    /// empty slots (the point at +∞), and directions with tiny, huge and
    /// negative components.
    #[test]
    fn box_major_is_ray_by_ray() {
        let mut unit = centred_units(0x2545_f491_4f6c_dd1d);
        let mut packet = Packet::empty();
        let mut passes = 0;
        for round in 0..20_000 {
            let origin = Vec3::new(unit(), unit(), unit()) * 4.0;
            let dirs: Vec<Vec3> = (0..PACKET)
                .map(|i| {
                    let scale = [1.0, 1e-30, 1e30, 3.0][(round + i) % 4];
                    Vec3::new(unit(), unit(), unit()) * scale + Vec3::splat(1e-3)
                })
                .collect();
            packet.load(origin, &dirs, 0.999_999);
            let node = random_node(round, &mut unit);
            let rel = Rel::new(&node, &packet.org);
            let lanes = packet.valid & !packet.parallel;
            let major = packet.hit_boxes_lanes(&rel, lanes);
            let mut by_ray = 0u32;
            for lane in 0..PACKET {
                if lanes >> lane & 1 == 1 {
                    let m = packet.rays[lane].hit_boxes_rel(&node, &rel);
                    by_ray |= ((m * 0x0020_4081) & 0x0101_0101) << lane;
                }
            }
            assert_eq!(major, by_ray, "round {round}: {dirs:?} from {origin:?}");
            passes += major.count_ones();
        }
        // Both verdicts occur often: the test is not vacuous.
        assert!(passes > 20_000, "{passes}");
    }

    /// The sign-picked slab tests (`Ray::hit_boxes_signed`,
    /// `Packet::hit_boxes_lanes_signed`) give the general tests' verdicts
    /// on boxes around, through, behind and beyond the origin, flat ones
    /// and empty slots, for directions of every sign pattern with tiny,
    /// huge and ordinary components; `signed` holds exactly the lanes
    /// whose signs match the first lane's.
    #[test]
    fn sign_picked_slabs_are_the_general_test() {
        let mut unit = centred_units(0x6a09_e667_f3bc_c908);
        let mut packet = Packet::empty();
        let (mut passes, mut fast_lanes) = (0, 0);
        for round in 0..20_000 {
            let origin = Vec3::new(unit(), unit(), unit()) * 4.0;
            let sign = Vec3::new(unit(), unit(), unit()).signum();
            let dirs: Vec<Vec3> = (0..PACKET)
                .map(|i| {
                    let scale = [1.0, 1e-30, 1e30, 3.0][(round + i) % 4];
                    let d = (Vec3::new(unit(), unit(), unit()).abs() + Vec3::splat(1e-3)) * scale;
                    // Every fifth lane (not the first) flips one axis.
                    let flip = if i > 0 && (round + i) % 5 == 0 {
                        Vec3::AXES[(round + i) % 3] * -2.0 + Vec3::ONE
                    } else {
                        Vec3::ONE
                    };
                    d * sign * flip
                })
                .collect();
            packet.load(origin, &dirs, 0.999_999);
            let mut expect = 0;
            for (lane, d) in dirs.iter().enumerate() {
                if d.signum() == dirs[0].signum() {
                    expect |= 1 << lane;
                }
            }
            assert_eq!(packet.signed, expect & packet.valid, "round {round}");
            let node = random_node(round, &mut unit);
            let rel = Rel::new(&node, &packet.org);
            let (near, far) = rel.signed(packet.signs);
            for lane in 0..PACKET {
                if packet.signed >> lane & 1 == 1 {
                    let ray = &packet.rays[lane];
                    let general = ray.hit_boxes_rel(&node, &rel);
                    assert_eq!(
                        ray.hit_boxes_signed(near, far),
                        general,
                        "round {round} lane {lane}"
                    );
                    passes += general.count_ones();
                    fast_lanes += 1;
                }
            }
            if packet.signed != 0 {
                let signed = packet.hit_boxes_lanes_signed(&rel, packet.signed);
                assert_eq!(
                    signed,
                    packet.hit_boxes_lanes(&rel, packet.signed),
                    "round {round}"
                );
                #[cfg(target_arch = "x86_64")]
                if crate::simd::avx::available() {
                    // SAFETY: AVX is available (checked on the line above).
                    let avx = unsafe { packet.hit_boxes_lanes_signed_avx(&rel, packet.signed) };
                    assert_eq!(avx, signed, "round {round}");
                }
            }
        }
        // Both verdicts occur often: the test is not vacuous.
        assert!(
            passes > 20_000 && fast_lanes > 100_000,
            "{passes} {fast_lanes}"
        );
    }

    /// Each lane of a loaded packet holds exactly `Ray::new`'s constants,
    /// and the valid lanes are exactly those `Ray::new` accepts, on
    /// components that are zero (both signs), subnormal, tiny, huge,
    /// infinite or NaN, in every combination the generator reaches; the
    /// eight-lane triangle constants agree with each lane's.
    #[test]
    fn packet_lanes_are_ray_new() {
        let specials = [
            0.0f32,
            -0.0,
            1e-45,
            -1e-45,
            1e-38,
            -3e-39,
            1.0,
            -1.0,
            0.5,
            -2.75,
            3e38,
            -f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1e-20,
        ];
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        let mut packet = Packet::empty();
        let mut last_origin = Vec3::ONE;
        for round in 0..20_000 {
            let mut comp = || {
                let r = next();
                if r % 3 == 0 {
                    specials[(r / 3) as usize % specials.len()]
                } else {
                    (r as f32 / u32::MAX as f32 - 0.5) * 2f32.powi((r % 40) as i32 - 20)
                }
            };
            let n = 1 + round % PACKET;
            let dirs: Vec<Vec3> = (0..n).map(|_| Vec3::new(comp(), comp(), comp())).collect();
            // Runs of packets from one origin and `t_max` (as a bundle's),
            // of mixed and uniform axes, with and without zero components.
            let origin = if round % 97 == 0 {
                Vec3::new(f32::NAN, 0.0, 1.0)
            } else if round % 4 != 0 {
                last_origin
            } else {
                Vec3::new(comp(), 1.5, -0.25)
            };
            last_origin = origin;
            let t_max = [0.999_999, 0.5][(round / 8) % 2];
            packet.load(origin, &dirs, t_max);
            let mut valid = 0;
            for (lane, &dir) in dirs.iter().enumerate() {
                let Some(ray) = Ray::new(origin, dir, t_max) else {
                    continue;
                };
                valid |= 1 << lane;
                assert_eq!(
                    ray_bits(&packet.rays[lane]),
                    ray_bits(&ray),
                    "lane {lane} of {dirs:?} from {origin:?}"
                );
                let woop = packet.woop();
                for (axis, &k) in ray.k.iter().enumerate() {
                    let [is0, is1] = woop.pick[axis];
                    let picked = if is0.move_mask() >> lane & 1 == 1 {
                        0
                    } else if is1.move_mask() >> lane & 1 == 1 {
                        1
                    } else {
                        2
                    };
                    assert_eq!(picked, k);
                }
                for axis in 0..3 {
                    let s = woop.shear[axis].to_array()[lane];
                    assert_eq!(s.to_bits(), ray.shear[axis].to_bits());
                }
            }
            assert_eq!(packet.valid, valid, "{dirs:?} from {origin:?}");
        }
    }

    /// The AVX copy of the eight-lane triangle test gives the facade
    /// copy's lanes bit for bit: packets of one to eight rays with
    /// uniform and mixed dominant axes (a third of the packets mix axes
    /// and signs), parallel and zero components, against leaves of one to
    /// five triangles placed across the rays (hits, misses, edge and
    /// vertex ties, degenerate and huge triangles).
    #[test]
    fn avx_triangle_test_is_the_facade_test() {
        #[cfg(target_arch = "x86_64")]
        {
            if !crate::simd::avx::available() {
                eprintln!("no AVX on this CPU: nothing to check");
                return;
            }
            let mut unit = centred_units(0x9b05_688c_2b3e_6c1f);
            let mut packet = Packet::empty();
            let (mut hits, mut misses, mut mixed) = (0u32, 0u32, 0u32);
            for round in 0..30_000 {
                let origin = Vec3::new(unit(), unit(), unit()) * 8.0;
                let n = 1 + round % PACKET;
                let base = Vec3::new(unit(), unit(), unit()) * 4.0;
                let dirs: Vec<Vec3> = (0..n)
                    .map(|i| {
                        let d = if round % 3 == 0 {
                            Vec3::new(unit(), unit(), unit())
                        } else {
                            base + Vec3::new(unit(), unit(), unit()) * 0.3
                        };
                        match (round + i) % 23 {
                            0 => Vec3::new(d.x, 0.0, d.z),
                            1 => Vec3::new(0.0, 0.0, d.z),
                            _ => d,
                        }
                    })
                    .collect();
                packet.load(origin, &dirs, [0.999_999, 2.0, 0.25][round % 3]);
                if packet.valid == 0 {
                    continue;
                }
                mixed += u32::from(packet.woop.uniform.is_none());
                let aim = origin + dirs[0] * (0.2 + unit().abs() * 1.5);
                let tris: Vec<[Vec3; 3]> = (0..1 + round % 5)
                    .map(|t| {
                        let size = [1.0, 0.05, 30.0, 1e-6][(round + t) % 4];
                        let mut tri =
                            [0; 3].map(|_| aim + Vec3::new(unit(), unit(), unit()) * size);
                        match (round + t) % 11 {
                            // Through a ray's point: an edge or vertex tie.
                            0 => tri[0] = origin + dirs[t % n] * 0.5,
                            1 => tri[2] = tri[1],
                            _ => {}
                        }
                        tri
                    })
                    .collect();
                let through = packet.valid;
                let mut facade = 0;
                for tri in &tris {
                    facade |= packet.hit_triangle(tri) & through;
                    if through & !facade == 0 {
                        break;
                    }
                }
                // SAFETY: AVX is available (checked above).
                let avx = unsafe { packet.hit_triangles_avx(tris.iter().copied(), through) };
                assert_eq!(
                    avx, facade,
                    "round {round}: {dirs:?} from {origin:?} at {tris:?}"
                );
                hits += facade.count_ones();
                misses += (through & !facade).count_ones();
            }
            // Both verdicts and mixed axes occur often: not vacuous.
            assert!(
                hits > 10_000 && misses > 10_000 && mixed > 1_000,
                "{hits} {misses} {mixed}"
            );
        }
    }

    /// The bundle walk answers every ray as [`Bvh::occluded`] does, at
    /// both levels: bundles of 64 coherent rays (a receiver's samples of a
    /// rect light, some lanes with zero or flipped components, so the
    /// packets mix signed, unsigned and parallel lanes) against a soup of
    /// small triangles (sphere-like clusters: many nodes reached by one
    /// or two lanes, which take their own walks) and a few large ones.
    #[test]
    fn bundle_is_ray_by_ray() {
        use crate::geom::SceneGeometry;
        use crate::simd::level::Level;
        let mut unit = centred_units(0x3c6e_f372_fe94_f82b);
        let mut g = SceneGeometry::default();
        for i in 0..30_000 {
            let cluster = Vec3::new((i % 7) as f32, 0.0, ((i / 7) % 5) as f32) - Vec3::splat(2.5);
            let c = cluster + Vec3::new(unit(), unit(), unit());
            let size = if i % 3_000 == 0 { 1.5 } else { 0.04 };
            let base = g.positions.len() as u32;
            for _ in 0..3 {
                g.positions
                    .push(c + Vec3::new(unit(), unit(), unit()) * size);
            }
            g.triangles.push([base, base + 1, base + 2]);
        }
        let bvh = Bvh::build(&g, |_| true);
        let (mut hits, mut misses) = (0u32, 0u32);
        for round in 0..400 {
            let origin = Vec3::new(unit() * 8.0, -4.5 + unit(), unit() * 6.0);
            let center = Vec3::new(unit() * 4.0, 4.0, unit() * 4.0);
            let dirs: Vec<Vec3> = (0..64)
                .map(|i| {
                    let x = center + Vec3::new(unit(), 0.0, unit()) * 1.5;
                    let d = x - origin;
                    match (round + i) % 29 {
                        0 => Vec3::new(0.0, d.y, d.z),
                        1 => Vec3::new(-d.x, d.y, d.z),
                        _ => d,
                    }
                })
                .collect();
            let t_max = [0.999_999, 0.5][round % 2];
            for level in [Level::Baseline, Level::V3] {
                if !level.supported() {
                    continue;
                }
                let mut out = vec![false; dirs.len()];
                bvh.occluded_bundle_at(level, origin, &dirs, t_max, &mut out);
                for (i, (&d, &o)) in dirs.iter().zip(&out).enumerate() {
                    assert_eq!(
                        o,
                        bvh.occluded(origin, d, t_max),
                        "round {round} ray {i} at {level:?}: {d:?} from {origin:?}"
                    );
                    if o {
                        hits += 1;
                    } else {
                        misses += 1;
                    }
                }
            }
        }
        // Both verdicts occur often: the test is not vacuous.
        assert!(hits > 5_000 && misses > 5_000, "{hits} {misses}");
    }
}
