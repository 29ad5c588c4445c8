//! Shadow rays from one origin, eight at a time.
//!
//! The reference's rays of one receiver share their origin and point at
//! one light, so they are coherent: [`Bvh::occluded_bundle`] walks the tree
//! once per packet of [`PACKET`] rays, the stack carrying lane masks: at
//! each node every live lane runs its own single-ray test of the four
//! child boxes (`Ray::hit_boxes_rel`, the bounds minus the shared origin
//! computed once), and a leaf is tested lane by lane with the single-ray
//! triangle test when few lanes reach it, else against all eight in
//! `f32x8` / `f64x4` lanes.
//!
//! **Same answer as one ray at a time, bit for bit.** Every lane performs
//! exactly the arithmetic [`Bvh::occluded`] performs for that ray: the
//! per-ray constants come from the same `Ray::new`; a child box's slab
//! distances are `(lo − origin) · inv` with the same operands (the
//! subtraction is shared by the lanes because the origin is); the
//! parallel-axis rule and the conservative far scale are the same; the
//! watertight triangle test picks each lane's own axes `kx, ky, kz` by
//! blends and runs the same f32 shear and the same f64 edge functions and
//! depth test. A lane tests a leaf's triangles only if every box above the
//! leaf passed for that lane (the stack carries lane masks), so each lane
//! tests the triangles its own walk would test; only the order differs,
//! which an "any hit" answer does not see. `tests/reference.rs` holds the
//! two against each other ray by ray.

use super::{Bvh, Node, Ray, Rel, STACK};
use crate::simd::{f32x4, f32x8, f64x4};
use glam::Vec3;
use std::cell::OnceCell;

/// Rays per packet.
pub const PACKET: usize = 8;

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
    /// The lanes' directions per axis (1 in unused lanes).
    d: [[f32; PACKET]; 3],
    /// The eight-lane triangle test's constants, built on first use (many
    /// packets reach only leaves that few lanes reach).
    woop: OnceCell<Woop>,
    /// Each valid lane's own single-ray constants (`Ray::new`; invalid
    /// lanes hold `Ray::UNUSED` and are never read): the box test
    /// runs ray by ray against a node's four children, and leaves reached
    /// by few lanes use the single-ray triangle test itself.
    rays: [Ray; PACKET],
    /// The origin splatted per axis (`Ray::org` of every lane).
    org: [f32x4; 3],
}

impl Packet {
    /// The packet of `dirs` (at most [`PACKET`]) from `origin`: lane by
    /// lane the constants `Ray::new` computes, with the same IEEE
    /// operations (divisions, the clamp, the dominant-axis rule).
    pub(super) fn new(origin: Vec3, dirs: &[Vec3], t_max: f32) -> Packet {
        let mut valid = 0;
        let mut d = [[1.0f32; PACKET]; 3];
        let rays: [Ray; PACKET] = std::array::from_fn(|lane| {
            // `Ray::new`'s refusal: a zero or non-finite direction or
            // origin.
            match dirs.get(lane).and_then(|&dir| Ray::new(origin, dir, t_max)) {
                Some(ray) => {
                    valid |= 1 << lane;
                    for axis in 0..3 {
                        d[axis][lane] = dirs[lane][axis];
                    }
                    ray
                }
                None => Ray::UNUSED,
            }
        });
        Packet {
            origin,
            valid,
            t_max,
            d,
            woop: OnceCell::new(),
            rays,
            org: [
                f32x4::splat(origin.x),
                f32x4::splat(origin.y),
                f32x4::splat(origin.z),
            ],
        }
    }

    /// The eight-lane triangle test's constants.
    #[inline]
    fn woop(&self) -> &Woop {
        self.woop.get_or_init(|| Woop::new(&self.d, self.valid))
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
    /// Lanes that `Ray::intersect` would find hitting `tri`.
    #[inline]
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
        let zero = f64x4::ZERO;
        let t_max = f64x4::splat(f64::from(self.t_max));
        let mut mask = 0;
        for h in 0..2 {
            let u = cx[h] * by[h] - cy[h] * bx[h];
            let v = ax[h] * cy[h] - ay[h] * cx[h];
            let w = bx[h] * ay[h] - by[h] * ax[h];
            let negative = u.cmp_lt(zero) | v.cmp_lt(zero) | w.cmp_lt(zero);
            let positive = u.cmp_gt(zero) | v.cmp_gt(zero) | w.cmp_gt(zero);
            let det = u + v + w;
            let t_scaled = u * (sz[h] * akz[h]) + v * (sz[h] * bkz[h]) + w * (sz[h] * ckz[h]);
            let limit = t_max * det;
            let ahead = det.cmp_gt(zero).blend(
                t_scaled.cmp_gt(zero) & t_scaled.cmp_lt(limit),
                t_scaled.cmp_lt(zero) & t_scaled.cmp_gt(limit),
            );
            // `det = 0` fails both branches of `ahead`: no separate test.
            let hit = ahead & !(negative & positive);
            mask |= hit.move_mask() << (4 * h);
        }
        mask
    }
}

impl Bvh {
    /// Whether each segment `origin + t · dirs[i]`, `t ∈ (0, t_max)`, hits
    /// a triangle: `out[i]` is exactly [`Bvh::occluded`]`(origin, dirs[i],
    /// t_max)` (see the module docs), computed [`PACKET`] rays at a time.
    /// `out` must be as long as `dirs`.
    pub fn occluded_bundle(&self, origin: Vec3, dirs: &[Vec3], t_max: f32, out: &mut [bool]) {
        out.fill(false);
        if self.nodes.is_empty() || !(t_max > 0.0) {
            return;
        }
        let mut last = None;
        for (chunk, res) in dirs.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
            let packet = Packet::new(origin, chunk, t_max);
            if packet.valid == 0 {
                continue;
            }
            let hit = self.packet_occluded(&packet, &mut last);
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
    fn packet_occluded(&self, packet: &Packet, last: &mut Option<(u32, usize)>) -> u32 {
        let mut hit = 0u32;
        if let Some((index, slot)) = *last {
            if let Some(node) = self.nodes.get(index as usize) {
                hit = self.leaf_hits(packet, node, slot, packet.valid);
                if hit == packet.valid {
                    return hit;
                }
            }
        }
        let mut stack = [(0u32, 0u32); STACK];
        stack[0] = (0, packet.valid & !hit);
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let (index, lanes) = stack[top];
            let mut lanes = lanes & !hit;
            if lanes == 0 {
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
            while lanes != 0 {
                let lane = lanes.trailing_zeros();
                lanes &= lanes - 1;
                let m = packet.rays[lane as usize].hit_boxes_rel(node, &rel);
                // Bit `s` of the 4-bit `m` to bit `8 s`.
                through |= ((m * 0x0020_4081) & 0x0101_0101) << lane;
            }
            while through != 0 {
                let slot = (through.trailing_zeros() / 8) as usize;
                let pass = (through >> (8 * slot)) & ALL & !hit;
                through &= !(0xff << (8 * slot));
                if pass == 0 {
                    continue;
                }
                let count = node.count[slot] as usize;
                if count == 0 {
                    // Cannot overflow (see `STACK`); the check only keeps
                    // the index provably in bounds.
                    if top < STACK {
                        stack[top] = (node.child[slot], pass);
                        top += 1;
                    }
                    continue;
                }
                let found = self.triangle_hits(packet, node, slot, pass);
                if found != 0 {
                    hit |= found;
                    *last = Some((index, slot));
                }
            }
            if hit == packet.valid & ALL {
                break;
            }
        }
        hit & packet.valid
    }

    /// The lanes of `lanes` that pass leaf `slot`'s box and hit one of its
    /// triangles.
    #[inline]
    pub(super) fn leaf_hits(&self, packet: &Packet, node: &Node, slot: usize, lanes: u32) -> u32 {
        if node.count[slot] == 0 {
            return 0;
        }
        // Each lane's own `Ray::hit_boxes`.
        let rel = Rel::new(node, &packet.org);
        let mut through = 0;
        let mut l = lanes;
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
    #[inline]
    fn triangle_hits(&self, packet: &Packet, node: &Node, slot: usize, through: u32) -> u32 {
        let first = node.child[slot] as usize;
        let count = node.count[slot] as usize;
        let Some(tris) = self.tris.get(first..first + count) else {
            return 0;
        };
        let mut hit = 0;
        if through.count_ones() <= SCALAR_LANES {
            // Few lanes: the single-ray test itself, lane by lane.
            let mut lanes = through;
            while lanes != 0 {
                let lane = lanes.trailing_zeros();
                lanes &= lanes - 1;
                let ray = &packet.rays[lane as usize];
                if tris.iter().any(|tri| ray.intersect(tri).is_some()) {
                    hit |= 1 << lane;
                }
            }
            return hit;
        }
        for tri in tris {
            hit |= packet.hit_triangle(tri) & through;
            if through & !hit == 0 {
                break;
            }
        }
        hit
    }
}
