//! Bounding volume hierarchy for shadow rays.
//!
//! - **Build**: binned SAH (16 bins per axis over the centroid bounds,
//!   leaves of at most [`MAX_LEAF`] triangles, and every range of at
//!   most [`ALWAYS_LEAF`] a leaf) collapsed into a 4-wide
//!   tree (each node holds the boxes of up to four children, opened
//!   largest-surface-area first) without building the binary tree: a
//!   node's slots start as one range, and the inner slot of largest area
//!   is split (binned, partitioned) until there are four. Each triangle is
//!   32 bytes of build input (bounds and index in `f32x4` lanes); binning
//!   does the three axes in one pass, and a partition also bounds both
//!   sides, so a range is read twice per split. Most ranges are tiny
//!   (4.1M triangles: 3.6M of the 4.4M ranges classified hold at most 8),
//!   so ranges of at most [`SMALL`] triangles fill and sweep only the
//!   bins they occupy, and the three axes' sweeps of larger ones run in
//!   the lanes of one `f32x4`: the same decisions as sweeping every bin.
//!   Ranges of at least [`PARALLEL_SPLIT`] triangles bin, bound and
//!   partition over fixed chunks in parallel (each chunk in place, then
//!   the right triangles before the split swap with the left ones after
//!   it: no copy of the range, no allocation); subtrees of at least
//!   [`PARALLEL_BUILD`] build in parallel with `rayon::join`, each into a
//!   chunk of nodes of its own (laid out one after another at the end,
//!   the chunks copied in parallel).
//! - **Same tree for any thread count**: the chunks are fixed
//!   ([`CHUNK`] triangles) and their partial bins and bounds are merged in
//!   chunk order, so every value is computed by the same operations in
//!   the same order whatever the threads; the parallel partition's
//!   result depends only on the chunks. Bin counts are integers and
//!   bounds min / max, so the decisions (bins, costs, median splits
//!   ordered by centroid then index) even depend only on the set of
//!   triangles in a range, not on its order; leaves are sorted by
//!   triangle index; and the node numbering follows the chunks of nodes,
//!   which depend only on range sizes.
//! - **Boxes**: f32, tested four at a time with `simd::f32x4` slabs. The
//!   test is conservative (Ize 2013: the far distance is scaled by
//!   `1 + 2γ₃`). An axis along which the direction is exactly 0 is tested
//!   by comparing the origin with the slab (faces included); other axes
//!   use an inverse clamped to ±`f32::MAX`, so `0 · ∞` (NaN) never occurs.
//! - **Triangles**: the watertight test of Woop, Benthin and Wald
//!   ("Watertight Ray/Triangle Intersection", JCGT 2013): vertices are
//!   translated to the ray origin, sheared and scaled so the ray runs down
//!   +z; the 2D edge functions of a shared edge are then computed from the
//!   same two transformed vertices by both triangles, in f64, where the
//!   difference of two products of f32 values is exact in sign (Woop et al.
//!   recompute in f64 only when the f32 value is exactly 0; scalar f64
//!   costs the same on x86-64, so it is always used). A point on an edge
//!   counts as inside (inclusive), so two triangles sharing an edge never
//!   both miss a ray through it. Leaves keep their corners as structure
//!   of arrays (`leaf`): a ray walking alone tests a whole leaf (up to
//!   eight triangles) in one eight-lane pass with the same operations per
//!   lane, a packet of rays one triangle at a time across its lanes.

mod build;
mod hull;
mod leaf;
mod packet;

pub use hull::SegmentHull;

pub use packet::PACKET;

use crate::simd::f32x4;
use glam::Vec3;
use std::ops::Range;

/// Most triangles in a leaf. With [`SAH_TRAVERSAL`] 2, leaves of up to
/// eight against four with cost 1: the shadow-ray BVH builds 4–10 % faster
/// and its rays take 0–4 % less on 1M–4.1M triangles, the same on the
/// 278k bunny (512², 64 samples, two interleaved runs each).
pub const MAX_LEAF: usize = 8;

/// Ranges of at most this many triangles become leaves without asking
/// the SAH. Its cost model counts a leaf's triangle tests one by one,
/// but a lone ray tests up to eight of a leaf in one pass
/// (`Ray::leaf_mask`), so splitting three or four triangles into two
/// leaves under a node only adds a node visit. Callgrind, one thread, 64
/// samples, traced DCS: the 278k-triangle bunny at 512² −1.1 % in the
/// light pass and −10.5 % in the build, the 1.0M spheres at 384² −1.3 %
/// and −8.6 % (the same images); 3, 5, 6 and 8 gained less on the bunny.
pub(super) const ALWAYS_LEAF: usize = 4;
const _: () = assert!(ALWAYS_LEAF <= MAX_LEAF);

/// The SAH's cost of a traversal step, relative to one triangle test.
pub(super) const SAH_TRAVERSAL: f32 = 2.0;

/// Binary depth from which splits become object-median splits: bounds the
/// tree depth (hence the traversal stack) for any input, including
/// adversarial ones where SAH would peel one triangle per level.
const SAH_MAX_DEPTH: u32 = 40;

/// Traversal stack entries: a 4-wide node pushes at most 3 more entries
/// than it pops, and the depth is at most `SAH_MAX_DEPTH + 32` (median
/// splits halve the count; counts are below 2³²).
const STACK: usize = 3 * (SAH_MAX_DEPTH as usize + 32) + 4;

/// `1 + 2γ₃` with `γₙ = n ε / (1 − n ε)`, `ε = 2⁻²⁴`: enlarging every far
/// slab distance by this makes the f32 box test conservative (Ize,
/// "Robust BVH Ray Traversal", JCGT 2013).
const FAR_SCALE: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// One 4-wide node: the boxes of its children, structure-of-arrays so one
/// `f32x4` holds one bound of all four.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(16))]
struct Node {
    /// `lo[axis][child]`.
    lo: [[f32; 4]; 3],
    /// `hi[axis][child]`.
    hi: [[f32; 4]; 3],
    /// Inner child: node index. Leaf child: first triangle (in leaf order).
    child: [u32; 4],
    /// Triangle count of a leaf child; 0 for an inner child or an empty
    /// slot (whose box is the point at +∞, which no ray reaches).
    count: [u32; 4],
}

impl Node {
    const EMPTY: Node = Node {
        lo: [[f32::INFINITY; 4]; 3],
        hi: [[f32::INFINITY; 4]; 3],
        child: [u32::MAX; 4],
        count: [0; 4],
    };
}

/// A ray hit reported by [`Bvh::for_each_hit`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Triangle index in the [`SceneGeometry`] the BVH was built from.
    pub triangle: u32,
    /// Ray parameter: the hit is at `origin + t · dir`.
    pub t: f32,
    /// Barycentric weight of the triangle's second vertex.
    pub b1: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub b2: f32,
}

/// A BVH over a subset of a [`SceneGeometry`]'s triangles.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    /// Triangle corners in leaf order, each leaf as structure of arrays
    /// (copied, so a leaf reads one run).
    tris: leaf::LeafCorners,
    /// Index in the source geometry of each triangle of `tris`.
    ids: Vec<u32>,
}

impl Bvh {
    /// Number of triangles in the tree.
    pub fn triangle_count(&self) -> usize {
        self.ids.len()
    }

    /// Number of 4-wide nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Whether any triangle is hit at `t ∈ (0, t_max)` on the ray
    /// `origin + t · dir` (`dir` need not be unit). A zero, infinite or
    /// NaN direction, or `t_max ≤ 0`, hits nothing.
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let mut hit = false;
        self.traverse(origin, dir, t_max, |_| {
            hit = true;
            false
        });
        hit
    }

    /// Calls `f` for every triangle hit at `t ∈ (0, t_max)`, in traversal
    /// order (not sorted by `t`). A triangle containing the ray's crossing
    /// point on an edge or vertex reports it too, so a ray through an edge
    /// shared by two triangles is reported by both.
    pub fn for_each_hit(&self, origin: Vec3, dir: Vec3, t_max: f32, mut f: impl FnMut(Hit)) {
        self.traverse(origin, dir, t_max, |h| {
            f(h);
            true
        });
    }

    /// Walks the tree, calling `on_hit` for each hit until it returns false.
    #[inline]
    fn traverse(&self, origin: Vec3, dir: Vec3, t_max: f32, mut on_hit: impl FnMut(Hit) -> bool) {
        if self.nodes.is_empty() || !(t_max > 0.0) {
            return;
        }
        let Some(ray) = Ray::new(origin, dir, t_max) else {
            return;
        };
        self.walk(
            |node| ray.hit_boxes(node),
            |_, _, leaf| {
                let (Some(tris), Some(ids)) =
                    (self.tris.leaf(leaf.start, leaf.len()), self.ids.get(leaf))
                else {
                    return true;
                };
                for (tri, &id) in tris.iter().zip(ids) {
                    if let Some((t, b1, b2)) = ray.intersect(&tri) {
                        let more = on_hit(Hit {
                            triangle: id,
                            t,
                            b1,
                            b2,
                        });
                        if !more {
                            return false;
                        }
                    }
                }
                true
            },
        );
    }

    /// The depth-first walk every single query shares: `boxes(node)` is
    /// the mask of children to enter; `leaf(node index, slot, triangles)`
    /// is called for each leaf child entered (its range in leaf order) and
    /// returns false to stop the walk. Returns false when stopped.
    #[inline(always)]
    fn walk(
        &self,
        mut boxes: impl FnMut(&Node) -> u32,
        mut leaf: impl FnMut(u32, usize, Range<usize>) -> bool,
    ) -> bool {
        let mut stack = [0u32; STACK];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let index = stack[top];
            let Some(node) = self.nodes.get(index as usize) else {
                continue;
            };
            let mut mask = boxes(node);
            self.prefetch_children(node, mask);
            while mask != 0 {
                let slot = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let count = node.count[slot] as usize;
                if count == 0 {
                    // Cannot overflow (see `STACK`); the check only keeps
                    // the index provably in bounds.
                    if top < STACK {
                        stack[top] = node.child[slot];
                        top += 1;
                    }
                    continue;
                }
                let first = node.child[slot] as usize;
                if !leaf(index, slot, first..first + count) {
                    return false;
                }
            }
        }
        true
    }
}

/// A node's child bounds minus a ray origin, per axis: the first step of
/// the slab test, the same for every ray from that origin.
struct Rel {
    lo: [f32x4; 3],
    hi: [f32x4; 3],
}

impl Rel {
    /// `node.lo − org`, `node.hi − org` (`org` splatted per axis).
    #[inline]
    fn new(node: &Node, org: &[f32x4; 3]) -> Rel {
        Rel {
            // Written out: `[0, 1, 2].map` is not unrolled here.
            lo: [
                f32x4::new(node.lo[0]) - org[0],
                f32x4::new(node.lo[1]) - org[1],
                f32x4::new(node.lo[2]) - org[2],
            ],
            hi: [
                f32x4::new(node.hi[0]) - org[0],
                f32x4::new(node.hi[1]) - org[1],
                f32x4::new(node.hi[2]) - org[2],
            ],
        }
    }
}

impl Rel {
    /// The near and far bounds per axis for rays whose direction is
    /// positive along the axes where `positive` is set and negative along
    /// the others (see [`Ray::hit_boxes_signed`]).
    #[inline(always)]
    fn signed(&self, positive: [bool; 3]) -> ([&f32x4; 3], [&f32x4; 3]) {
        let pick = |axis: usize| {
            if positive[axis] {
                (&self.lo[axis], &self.hi[axis])
            } else {
                (&self.hi[axis], &self.lo[axis])
            }
        };
        let [(n0, f0), (n1, f1), (n2, f2)] = [pick(0), pick(1), pick(2)];
        ([n0, n1, n2], [f0, f1, f2])
    }
}

/// `v` splatted per axis.
#[inline(always)]
fn splat3(v: Vec3) -> [f32x4; 3] {
    [f32x4::splat(v.x), f32x4::splat(v.y), f32x4::splat(v.z)]
}

/// A ray prepared for box and watertight triangle tests.
#[derive(Clone, Copy)]
struct Ray {
    origin: Vec3,
    t_max: f32,
    /// Slab test: the inverse direction, splatted per axis.
    inv: [f32x4; 3],
    /// Axes along which the direction is exactly 0: there the slab is
    /// everything or nothing, decided by comparing the origin with the box.
    parallel: [bool; 3],
    /// Whether any of `parallel` is set (the slab-only loop otherwise).
    any_parallel: bool,
    /// Watertight test: the dominant axis `kz` and the two others
    /// (swapped when `dir[kz] < 0` to keep the winding), and the shear.
    k: [usize; 3],
    shear: Vec3,
}

impl Ray {
    /// A placeholder for unused packet lanes (never tested).
    const UNUSED: Ray = Ray {
        origin: Vec3::ZERO,
        t_max: 0.0,
        inv: [f32x4::ZERO; 3],
        parallel: [false; 3],
        any_parallel: false,
        k: [0, 1, 2],
        shear: Vec3::ZERO,
    };

    /// `None` for a direction that is zero or not finite.
    #[inline(always)]
    fn new(origin: Vec3, dir: Vec3, t_max: f32) -> Option<Ray> {
        if !(dir.is_finite() && origin.is_finite() && dir != Vec3::ZERO) {
            return None;
        }
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        // A subnormal component would give ±∞ and then `0 · ∞ = NaN` for a
        // box face through the origin; the largest finite value keeps the
        // slab test NaN-free (and `0 · MAX = 0` is then the right entry
        // distance). Zero components take the `parallel` path instead.
        let inv = |d: f32| (1.0 / d).clamp(-f32::MAX, f32::MAX);
        Some(Ray {
            origin,
            t_max,
            // Written out: `[0, 1, 2].map` is not unrolled here.
            inv: [
                f32x4::splat(inv(dir.x)),
                f32x4::splat(inv(dir.y)),
                f32x4::splat(inv(dir.z)),
            ],
            parallel: [dir.x == 0.0, dir.y == 0.0, dir.z == 0.0],
            any_parallel: dir.cmpeq(Vec3::ZERO).any(),
            k: [kx, ky, kz],
            shear: Vec3::new(dir[kx] / dir[kz], dir[ky] / dir[kz], 1.0 / dir[kz]),
        })
    }

    /// Bit mask of the node's children whose box the segment may touch.
    #[inline]
    fn hit_boxes(&self, node: &Node) -> u32 {
        self.hit_boxes_rel(node, &Rel::new(node, &splat3(self.origin)))
    }

    /// [`Ray::hit_boxes_rel`]'s verdicts for a ray with no zero direction
    /// component, given the bounds [`Rel::signed`] picks for the ray's
    /// direction signs: the slab's entry distance is the near bound's
    /// product, its exit the far bound's, so the min / max per axis fall
    /// away. The same verdicts bit for bit: the slab inverse has the
    /// direction's sign and is never zero, and `lo ≤ hi` (or both +∞, an
    /// empty slot), so the rounded products are ordered as the bounds are
    /// and `min(t0, t1)` is the near one's value; where the two are equal
    /// only a zero's sign may differ, which neither `max`, `min` nor the
    /// final `≤` sees. A slot whose box is inverted (`lo > hi`: only from
    /// triangles with NaN corners, which no ray hits) may be rejected
    /// where the general test passes it, which changes no answer.
    #[inline(always)]
    fn hit_boxes_signed(&self, near: [&f32x4; 3], far: [&f32x4; 3]) -> u32 {
        let mut n = f32x4::splat(0.0);
        let mut f = f32x4::splat(self.t_max);
        for axis in 0..3 {
            n = n.max(*near[axis] * self.inv[axis]);
            f = f.min(*far[axis] * self.inv[axis]);
        }
        n.cmp_le(f * f32x4::splat(FAR_SCALE)).move_mask()
    }

    /// [`Ray::hit_boxes`] given the node's bounds relative to the ray's
    /// origin (`Rel::new(node, &splat3(origin))`, or the same values computed
    /// once for several rays from this origin).
    #[inline(always)]
    fn hit_boxes_rel(&self, node: &Node, rel: &Rel) -> u32 {
        let mut near = f32x4::splat(0.0);
        let mut far = f32x4::splat(self.t_max);
        if !self.any_parallel {
            // The loop below with every `parallel[axis]` false.
            for axis in 0..3 {
                let t0 = rel.lo[axis] * self.inv[axis];
                let t1 = rel.hi[axis] * self.inv[axis];
                near = near.max(t0.min(t1));
                far = far.min(t0.max(t1));
            }
            return near.cmp_le(far * f32x4::splat(FAR_SCALE)).move_mask();
        }
        let mut inside = 0xf;
        for axis in 0..3 {
            if self.parallel[axis] {
                // The ray stays in the plane `origin[axis]`: the box's slab
                // contains all of it or none (faces included).
                let lo = f32x4::new(node.lo[axis]);
                let hi = f32x4::new(node.hi[axis]);
                let o = f32x4::splat(self.origin[axis]);
                inside &= (lo.cmp_le(o) & o.cmp_le(hi)).move_mask();
                continue;
            }
            let t0 = rel.lo[axis] * self.inv[axis];
            let t1 = rel.hi[axis] * self.inv[axis];
            // No NaN can occur (see `Ray::new`).
            near = near.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        near.cmp_le(far * f32x4::splat(FAR_SCALE)).move_mask() & inside
    }

    /// Watertight intersection with `tri` at `t ∈ (0, t_max)`:
    /// `(t, b1, b2)` with `b1`, `b2` the weights of the second and third
    /// vertex.
    #[inline(always)]
    fn intersect(&self, tri: &[Vec3; 3]) -> Option<(f32, f32, f32)> {
        let [kx, ky, kz] = self.k;
        let s = self.shear;
        // Arrays: indexing a `Vec3` by a run-time axis is a match.
        let a = (tri[0] - self.origin).to_array();
        let b = (tri[1] - self.origin).to_array();
        let c = (tri[2] - self.origin).to_array();
        // Shear into ray space: each vertex transformed on its own, so a
        // vertex shared by two triangles gets the same coordinates in both.
        let (ax, ay) = (a[kx] - s.x * a[kz], a[ky] - s.y * a[kz]);
        let (bx, by) = (b[kx] - s.x * b[kz], b[ky] - s.y * b[kz]);
        let (cx, cy) = (c[kx] - s.x * c[kz], c[ky] - s.y * c[kz]);
        // Edge functions in f64: the products of two f32 are exact there,
        // so each difference has the exact sign and is 0 only when the ray
        // passes exactly through the edge (Woop et al. fall back to f64
        // only for exact zeros; on scalar x86 f64 costs the same, and this
        // way no f32 rounding can flip a sign).
        let e = |p: f32, q: f32, r: f32, t: f32| {
            f64::from(p) * f64::from(q) - f64::from(r) * f64::from(t)
        };
        let u = e(cx, by, cy, bx);
        let v = e(ax, cy, ay, cx);
        let w = e(bx, ay, by, ax);
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None;
        }
        let sz = f64::from(s.z);
        let t_scaled =
            u * (sz * f64::from(a[kz])) + v * (sz * f64::from(b[kz])) + w * (sz * f64::from(c[kz]));
        let limit = f64::from(self.t_max) * det;
        let inside = if det > 0.0 {
            t_scaled > 0.0 && t_scaled < limit
        } else {
            t_scaled < 0.0 && t_scaled > limit
        };
        if !inside {
            return None;
        }
        let inv_det = 1.0 / det;
        Some((
            (t_scaled * inv_det) as f32,
            (v * inv_det) as f32,
            (w * inv_det) as f32,
        ))
    }
}

/// The watertight ray–triangle test the BVH uses, for one triangle: `(t,
/// b1, b2)` of a hit at `t ∈ (0, t_max)` on `origin + t · dir`. Exposed so
/// tests can check the BVH against a brute-force loop with the same test.
pub fn intersect_triangle(
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    tri: &[Vec3; 3],
) -> Option<(f32, f32, f32)> {
    if !(t_max > 0.0) {
        return None;
    }
    Ray::new(origin, dir, t_max)?.intersect(tri)
}

/// Uniform values in `[−0.5, 0.5]` from a seeded LCG (the tests' random
/// rays, boxes and triangles).
#[cfg(test)]
pub(super) fn centred_units(seed: u64) -> impl FnMut() -> f32 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 32) as u32 as f32 / u32::MAX as f32 - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::build::{corners, PARALLEL_SPLIT};
    use super::*;
    use crate::geom::SceneGeometry;

    /// Deterministic pseudo-random numbers in [0, 1).
    fn rng(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    /// `n` small random triangles in a unit cube (every 97th one with
    /// NaN corners, every 89th one degenerate) and a few huge ones.
    fn soup(n: usize) -> SceneGeometry {
        let mut g = SceneGeometry::default();
        let mut s = 11u64;
        for i in 0..n {
            let base = g.positions.len() as u32;
            let c = Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s));
            let size = if i % 1000 == 0 { 2.0 } else { 0.01 };
            for k in 0..3 {
                let mut p = c + (Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) - 0.5) * size;
                if i % 97 == 0 && k > 0 {
                    p = Vec3::NAN;
                }
                if i % 89 == 0 {
                    p = c;
                }
                g.positions.push(p);
            }
            g.triangles.push([base, base + 1, base + 2]);
        }
        g
    }

    /// The same tree for 1, 2 and 3 threads, large enough that the
    /// parallel binning and partition run; the same hit sets as a
    /// brute-force loop; leaves hold at most `MAX_LEAF` triangles, sorted
    /// by index, and every kept triangle exactly once.
    #[test]
    fn parallel_build_is_deterministic_and_exact() {
        let g = soup(3 * PARALLEL_SPLIT);
        let keep = |t: u32| t % 5 != 2;
        let build = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool")
                .install(|| Bvh::build(&g, keep))
        };
        // Bit patterns: the NaN corners would make `==` fail.
        let bits = |b: &Bvh| {
            let mut v: Vec<u32> = b.ids.clone();
            for n in &b.nodes {
                v.extend(n.lo.iter().chain(&n.hi).flatten().map(|x| x.to_bits()));
                v.extend(n.child.iter().chain(&n.count));
            }
            v.extend(b.tris.floats().iter().map(|x| x.to_bits()));
            v
        };
        let one = build(1);
        assert!(bits(&build(2)) == bits(&one), "2 threads differ from 1");
        assert!(bits(&build(3)) == bits(&one), "3 threads differ from 1");
        let mut ids = one.ids.clone();
        ids.sort_unstable();
        let kept: Vec<u32> = (0..g.triangles.len() as u32).filter(|&t| keep(t)).collect();
        assert_eq!(ids, kept);
        for node in &one.nodes {
            for slot in 0..4 {
                let n = node.count[slot] as usize;
                assert!(n <= MAX_LEAF);
                let first = node.child[slot] as usize;
                if n > 0 {
                    let leaf = &one.ids[first..first + n];
                    assert!(leaf.windows(2).all(|w| w[0] < w[1]), "{leaf:?}");
                } else if node.child[slot] != u32::MAX {
                    assert!((node.child[slot] as usize) < one.nodes.len());
                }
            }
        }
        let mut s = 3u64;
        let mut hits = 0;
        for i in 0..300 {
            let o = Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 1.4 - 0.2;
            let mut d = Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) - 0.5;
            if i % 10 == 0 {
                d = Vec3::new(0.0, d.y, 0.0);
            }
            let t_max = 0.5 + rng(&mut s);
            let mut brute: Vec<u32> = kept
                .iter()
                .copied()
                .filter(|&t| intersect_triangle(o, d, t_max, &corners(&g, t)).is_some())
                .collect();
            let mut walked = Vec::new();
            one.for_each_hit(o, d, t_max, |h| walked.push(h.triangle));
            brute.sort_unstable();
            walked.sort_unstable();
            assert_eq!(walked, brute, "ray {i}");
            assert_eq!(one.occluded(o, d, t_max), !brute.is_empty());
            hits += brute.len();
        }
        assert!(hits > 100, "{hits}");
    }
}
