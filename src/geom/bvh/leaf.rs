//! Leaf triangles stored leaf by leaf as structure of arrays, and the
//! single-ray test of a whole leaf at once.
//!
//! A ray walking alone (most of a shadow bundle's node visits below the
//! top levels) tested a leaf's triangles one at a time with the scalar
//! watertight test: on the 278k-triangle bunny at 512², 64 samples that
//! test was about a quarter of the walk's time. Stored as nine runs per
//! leaf (corner a's x of every triangle, then a's y, … c's z), a leaf's
//! corners load as eight-lane vectors with no transposition, and one pass
//! of [`Ray::leaf_mask`] tests up to eight triangles: the same IEEE
//! operations per lane as [`Ray::intersect`], so the same verdicts.

use super::{Ray, MAX_LEAF};
use crate::simd::{f32x8, f64x4};
use glam::Vec3;
use rayon::prelude::*;

/// Floats after the last leaf: an eight-lane load of a leaf's last run
/// reads up to seven floats past it.
const SLACK: usize = 8;

// One eight-lane pass covers a whole leaf.
const _: () = assert!(MAX_LEAF <= 8);

/// The corners of every leaf's triangles, in leaf order: the leaf of
/// triangles `first..first + count` holds floats `9 first .. 9 (first +
/// count)`, as nine runs of `count` (run `3 v + axis` is corner `v`'s
/// coordinate `axis`), so every triangle keeps 36 bytes, as an array of
/// corners did.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct LeafCorners {
    data: Vec<f32>,
}

impl LeafCorners {
    /// The runs of `leaves` (`(first, count)`, tiling `0..n` in order of
    /// `first`), `corners(i)` giving triangle `i` of leaf order. Groups of
    /// leaves fill their own parts of the buffer in parallel.
    pub(super) fn build(
        leaves: &[(u32, u32)],
        corners: impl Fn(usize) -> [Vec3; 3] + Sync,
    ) -> LeafCorners {
        const GROUP: usize = 1024;
        let n = leaves.last().map_or(0, |&(f, c)| (f + c) as usize);
        let mut data = vec![0.0f32; 9 * n + SLACK];
        // Each group's slice of the buffer: the groups tile `0..n` too.
        let mut parts = Vec::with_capacity(leaves.len().div_ceil(GROUP));
        let mut rest = &mut data[..9 * n];
        for group in leaves.chunks(GROUP) {
            let end = group.last().map_or(0, |&(f, c)| (f + c) as usize);
            let start = group.first().map_or(0, |&(f, _)| f as usize);
            let (mine, tail) = std::mem::take(&mut rest).split_at_mut(9 * (end - start));
            rest = tail;
            parts.push((group, start, mine));
        }
        parts.into_par_iter().for_each(|(group, start, out)| {
            for &(first, count) in group {
                let (first, count) = (first as usize, count as usize);
                let base = 9 * (first - start);
                for i in 0..count {
                    let tri = corners(first + i);
                    for run in 0..9 {
                        if let Some(x) = out.get_mut(base + run * count + i) {
                            *x = tri[run / 3][run % 3];
                        }
                    }
                }
            }
        });
        LeafCorners { data }
    }

    /// The leaf of triangles `first..first + count`, if in the buffer.
    #[inline(always)]
    pub(super) fn leaf(&self, first: usize, count: usize) -> Option<Leaf<'_>> {
        let start = 9 * first;
        self.data
            .get(start..start + 9 * count + SLACK)
            .map(|runs| Leaf { runs, count })
    }

    /// Where the leaf starting at triangle `first` starts, for a prefetch
    /// (never dereferenced here; may point past the buffer).
    #[inline(always)]
    pub(super) fn leaf_ptr(&self, first: usize) -> *const f32 {
        self.data.as_ptr().wrapping_add(9 * first)
    }

    /// The buffer's floats (for tests comparing trees bit for bit).
    #[cfg(test)]
    pub(super) fn floats(&self) -> &[f32] {
        &self.data
    }
}

/// One leaf's triangles as nine runs (see [`LeafCorners`]), followed by
/// at least [`SLACK`] floats of whatever comes next.
#[derive(Clone, Copy)]
pub(super) struct Leaf<'a> {
    runs: &'a [f32],
    count: usize,
}

impl<'a> Leaf<'a> {
    /// Triangles in the leaf.
    #[inline(always)]
    pub(super) fn len(&self) -> usize {
        self.count
    }

    /// Triangle `i`'s corners (`i < len()`; else whatever lies there).
    #[inline(always)]
    pub(super) fn tri(&self, i: usize) -> [Vec3; 3] {
        let n = self.count;
        let at = |run: usize| self.runs.get(run * n + i).copied().unwrap_or(f32::NAN);
        [0, 1, 2].map(|v| Vec3::new(at(3 * v), at(3 * v + 1), at(3 * v + 2)))
    }

    /// The leaf's triangles in order.
    #[inline(always)]
    pub(super) fn iter(self) -> impl Iterator<Item = [Vec3; 3]> + 'a {
        (0..self.count).map(move |i| self.tri(i))
    }

    /// Eight floats from the start of run `run`: the run's `len()` values,
    /// then whatever follows them. A reference into the buffer, so the
    /// vector loads read it in place (an array returned by value was
    /// copied first: 1.2 % of the 278k bunny's render instructions at
    /// 512², 64 samples, callgrind).
    #[inline(always)]
    fn run8(&self, run: usize) -> &'a [f32; 8] {
        static MISSING: [f32; 8] = [f32::NAN; 8];
        let start = run * self.count;
        self.runs
            .get(start..start + 8)
            .and_then(|s| s.try_into().ok())
            .unwrap_or(&MISSING)
    }

    /// Bit mask of the leaf's triangles (lanes `0..len()`).
    #[inline(always)]
    fn lanes(&self) -> u32 {
        (1u32 << self.count.min(8)) - 1
    }
}

impl Ray {
    /// Whether the ray hits one of `leaf`'s triangles: a one-triangle
    /// leaf by [`Ray::intersect`] itself, larger ones by one pass of
    /// [`Ray::leaf_mask`] (its AVX copy when `avx`, which must be
    /// `simd::avx::available()`); the same answer each way.
    #[inline(always)]
    pub(super) fn hits_leaf(&self, leaf: Leaf, avx: bool) -> bool {
        if leaf.len() == 1 {
            return self.intersect(&leaf.tri(0)).is_some();
        }
        #[cfg(target_arch = "x86_64")]
        if avx {
            // SAFETY: `avx` is true only where `simd::avx::available()`
            // found AVX on this CPU, the one requirement of the
            // `target_feature` function.
            return unsafe { self.leaf_mask_avx(leaf) } != 0;
        }
        let _ = avx;
        self.leaf_mask(leaf) != 0
    }

    /// Bit `i` set where [`Ray::intersect`] finds a hit on the leaf's
    /// triangle `i`: lane `i` runs that test's operations in its order on
    /// its values (the corners relative to the origin in f32, the shear in
    /// f32, the edge functions, their sum and the scaled distance in f64),
    /// and `det = 0` fails both branches of the distance test as it
    /// returns `None` there.
    #[inline(always)]
    pub(super) fn leaf_mask(&self, leaf: Leaf) -> u32 {
        let [kx, ky, kz] = self.k;
        let o = self.origin;
        let rel = |v: usize| {
            [
                f32x8::new(*leaf.run8(3 * v)) - f32x8::splat(o.x),
                f32x8::new(*leaf.run8(3 * v + 1)) - f32x8::splat(o.y),
                f32x8::new(*leaf.run8(3 * v + 2)) - f32x8::splat(o.z),
            ]
        };
        let (a, b, c) = (rel(0), rel(1), rel(2));
        let (sx, sy) = (f32x8::splat(self.shear.x), f32x8::splat(self.shear.y));
        let ax = (a[kx] - sx * a[kz]).widen();
        let ay = (a[ky] - sy * a[kz]).widen();
        let bx = (b[kx] - sx * b[kz]).widen();
        let by = (b[ky] - sy * b[kz]).widen();
        let cx = (c[kx] - sx * c[kz]).widen();
        let cy = (c[ky] - sy * c[kz]).widen();
        let (akz, bkz, ckz) = (a[kz].widen(), b[kz].widen(), c[kz].widen());
        let sz = f64x4::splat(f64::from(self.shear.z));
        let t_max = f64x4::splat(f64::from(self.t_max));
        let lanes = leaf.lanes();
        let mut mask = 0;
        for h in 0..2 {
            if lanes >> (4 * h) == 0 {
                break;
            }
            let xy = [ax[h], ay[h], bx[h], by[h], cx[h], cy[h]];
            mask |= watertight_lanes(xy, [akz[h], bkz[h], ckz[h]], sz, t_max) << (4 * h);
            if mask & lanes != 0 {
                break;
            }
        }
        mask & lanes
    }

    /// [`Ray::leaf_mask`] in AVX registers: the same operations in the
    /// same order on the same values (each `simd::avx` operation is its
    /// facade namesake's IEEE operation), so the same bits; `tests` holds
    /// the two equal.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    pub(super) fn leaf_mask_avx(&self, leaf: Leaf) -> u32 {
        use crate::simd::avx::{F32x8, F64x4};
        let [kx, ky, kz] = self.k;
        let o = self.origin;
        let rel = |v: usize| {
            [
                F32x8::load(leaf.run8(3 * v)).sub(F32x8::splat(o.x)),
                F32x8::load(leaf.run8(3 * v + 1)).sub(F32x8::splat(o.y)),
                F32x8::load(leaf.run8(3 * v + 2)).sub(F32x8::splat(o.z)),
            ]
        };
        let (a, b, c) = (rel(0), rel(1), rel(2));
        let (sx, sy) = (F32x8::splat(self.shear.x), F32x8::splat(self.shear.y));
        let ax = a[kx].sub(sx.mul(a[kz])).widen();
        let ay = a[ky].sub(sy.mul(a[kz])).widen();
        let bx = b[kx].sub(sx.mul(b[kz])).widen();
        let by = b[ky].sub(sy.mul(b[kz])).widen();
        let cx = c[kx].sub(sx.mul(c[kz])).widen();
        let cy = c[ky].sub(sy.mul(c[kz])).widen();
        let (akz, bkz, ckz) = (a[kz].widen(), b[kz].widen(), c[kz].widen());
        let sz = F64x4::splat(f64::from(self.shear.z));
        let t_max = F64x4::splat(f64::from(self.t_max));
        let lanes = leaf.lanes();
        let mut mask = 0;
        for h in 0..2 {
            if lanes >> (4 * h) == 0 {
                break;
            }
            let xy = [ax[h], ay[h], bx[h], by[h], cx[h], cy[h]];
            mask |= watertight_lanes_avx(xy, [akz[h], bkz[h], ckz[h]], sz, t_max) << (4 * h);
            if mask & lanes != 0 {
                break;
            }
        }
        mask & lanes
    }
}

/// The watertight test's f64 stage on four lanes, `Ray::intersect`'s
/// steps after the shear: from the sheared corners' `[ax, ay, bx, by, cx,
/// cy]`, their depths `[a[kz], b[kz], c[kz]]` (before the shear), the
/// shear's `sz` and `t_max`, bit `i` set where lane `i` hits. The edge
/// functions are exact in sign (products of two f32 in f64), a point on an
/// edge counts as inside, and `det = 0` fails both branches of the
/// distance test as `intersect` returns `None` there. Shared by the
/// single-ray leaf test and the packets' eight-lane triangle test.
#[inline(always)]
pub(super) fn watertight_lanes(xy: [f64x4; 6], kz: [f64x4; 3], sz: f64x4, t_max: f64x4) -> u32 {
    let [ax, ay, bx, by, cx, cy] = xy;
    let [akz, bkz, ckz] = kz;
    let zero = f64x4::ZERO;
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let negative = u.cmp_lt(zero) | v.cmp_lt(zero) | w.cmp_lt(zero);
    let positive = u.cmp_gt(zero) | v.cmp_gt(zero) | w.cmp_gt(zero);
    let det = u + v + w;
    let t_scaled = u * (sz * akz) + v * (sz * bkz) + w * (sz * ckz);
    let limit = t_max * det;
    let ahead = det.cmp_gt(zero).blend(
        t_scaled.cmp_gt(zero) & t_scaled.cmp_lt(limit),
        t_scaled.cmp_lt(zero) & t_scaled.cmp_gt(limit),
    );
    (ahead & !(negative & positive)).move_mask()
}

/// [`watertight_lanes`] in AVX registers: the same operations in the same
/// order (each `simd::avx` operation is its facade namesake's), so the
/// same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
pub(super) fn watertight_lanes_avx(
    xy: [crate::simd::avx::F64x4; 6],
    kz: [crate::simd::avx::F64x4; 3],
    sz: crate::simd::avx::F64x4,
    t_max: crate::simd::avx::F64x4,
) -> u32 {
    use crate::simd::avx::F64x4;
    let [ax, ay, bx, by, cx, cy] = xy;
    let [akz, bkz, ckz] = kz;
    let zero = F64x4::splat(0.0);
    let u = cx.mul(by).sub(cy.mul(bx));
    let v = ax.mul(cy).sub(ay.mul(cx));
    let w = bx.mul(ay).sub(by.mul(ax));
    let negative = u.cmp_lt(zero).bitor(v.cmp_lt(zero)).bitor(w.cmp_lt(zero));
    let positive = u.cmp_gt(zero).bitor(v.cmp_gt(zero)).bitor(w.cmp_gt(zero));
    let det = u.add(v).add(w);
    let t_scaled = u
        .mul(sz.mul(akz))
        .add(v.mul(sz.mul(bkz)))
        .add(w.mul(sz.mul(ckz)));
    let limit = t_max.mul(det);
    let ahead = det.cmp_gt(zero).blend(
        t_scaled.cmp_gt(zero).bitand(t_scaled.cmp_lt(limit)),
        t_scaled.cmp_lt(zero).bitand(t_scaled.cmp_gt(limit)),
    );
    ahead.and_not(negative.bitand(positive)).move_mask()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::bvh::centred_units;

    /// Leaves of one to eight triangles, stored as the tree stores them
    /// (several leaves in one buffer, so a leaf's spare lanes read its
    /// neighbour's runs): the eight-lane test's bits are
    /// `Ray::intersect`'s triangle by triangle up to its first hit, at
    /// both levels, and `hits_leaf` its answer. Triangles of very
    /// different sizes, some through a point of the ray (edge and vertex
    /// ties), some degenerate; directions with zero components (other
    /// dominant axes) and every sign.
    #[test]
    fn leaf_test_is_the_scalar_test() {
        let mut unit = centred_units(0x5851_f42d_4c95_7f2d);
        let (mut hits, mut misses, mut ties) = (0u32, 0u32, 0u32);
        let avx = crate::simd::avx::available();
        for round in 0..20_000 {
            let origin = Vec3::new(unit(), unit(), unit()) * 8.0;
            let mut dir = Vec3::new(unit(), unit(), unit());
            match round % 13 {
                0 => dir.y = 0.0,
                1 => dir = Vec3::new(0.0, 0.0, dir.z),
                _ => {}
            }
            let t_max = [0.999_999, 2.0, 0.25][round % 3];
            let Some(ray) = Ray::new(origin, dir, t_max) else {
                continue;
            };
            // Three leaves; the middle one is tested.
            let counts = [1 + (round * 7) % 8, 1 + round % 8, 1 + (round * 3) % 8];
            let mut tris = Vec::new();
            for (l, &count) in counts.iter().enumerate() {
                let aim = origin + dir * (0.2 + unit().abs() * 1.5);
                for t in 0..count {
                    let size = [1.0, 0.05, 30.0, 1e-6][(round + t + l) % 4];
                    let mut tri = [0; 3].map(|_| aim + Vec3::new(unit(), unit(), unit()) * size);
                    match (round + t) % 11 {
                        0 => tri[0] = origin + dir * 0.5,
                        1 => tri[2] = tri[1],
                        2 => tri[1] = origin + dir * (0.5 + t as f32 * 0.01),
                        _ => {}
                    }
                    tris.push(tri);
                }
            }
            let mut leaves = Vec::new();
            let mut first = 0;
            for &count in &counts {
                leaves.push((first as u32, count as u32));
                first += count;
            }
            let store = LeafCorners::build(&leaves, |i| tris[i]);
            let (first, count) = (counts[0], counts[1]);
            let leaf = store.leaf(first, count).expect("in the buffer");
            let mut expected = 0u32;
            for i in 0..count {
                assert_eq!(
                    leaf.tri(i).map(|p| p.to_array()),
                    tris[first + i].map(|p| p.to_array())
                );
                if ray.intersect(&tris[first + i]).is_some() {
                    expected |= 1 << i;
                }
            }
            let facade = ray.leaf_mask(leaf);
            // Bits up to the first half with a hit (the test stops there).
            let upto = if expected & 0xf != 0 { 0xf } else { 0xff };
            assert_eq!(facade, expected & upto, "round {round}");
            assert_eq!(ray.hits_leaf(leaf, false), expected != 0);
            #[cfg(target_arch = "x86_64")]
            if avx {
                // SAFETY: AVX is available (checked above).
                assert_eq!(unsafe { ray.leaf_mask_avx(leaf) }, facade, "round {round}");
                assert_eq!(ray.hits_leaf(leaf, true), expected != 0);
            }
            for i in 0..count {
                let tri = tris[first + i];
                let tie = tri.iter().any(|&p| p == origin + dir * 0.5);
                ties += u32::from(tie && expected >> i & 1 == 1);
            }
            hits += u32::from(expected != 0);
            misses += u32::from(expected == 0);
        }
        // Both verdicts and hits on ties occur often: not vacuous.
        assert!(
            hits > 3_000 && misses > 3_000 && ties > 300,
            "{hits} {misses} {ties}"
        );
    }
}
