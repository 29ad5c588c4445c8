//! A cheap-to-build hierarchy over the caster groups' faces for
//! [`ExactStart`](super::ties::ExactStart)'s queries (the own-face
//! segments of `cap_near` and the few tie recount rays), which reports
//! exactly the triangles a brute-force loop with the BVH's watertight test
//! ([`intersect_triangle`]) reports.
//!
//! - **Build**: the faces sorted by the 30-bit Morton code of their box
//!   centres (ties by triangle index), then an implicit 4-wide tree over
//!   that order: a level-0 node holds the boxes of 4 consecutive
//!   triangles, a level-k node those of 4 consecutive level-(k − 1)
//!   nodes, up to one root. No SAH, no partitioning: a sort and linear
//!   passes (the scene BVH's binned SAH build was ~0.58 G instructions on
//!   `spheres.toml`, nearly all of the faces' cost; this one is a few %).
//! - **Boxes**: f32 (the corners' own bounds, exact), tested four at a
//!   time (`simd::f32x4` slabs on the boxes relative to the ray's
//!   origin), each enlarged at query time by [`MARGIN`] × its *reach*,
//!   the largest coordinate distance from the ray's origin to the box.
//!   The watertight test works on the corners translated to the origin
//!   and sheared, in f32: a triangle it accepts lies within about 20 f32
//!   roundings (≈ 1.2e-6) of its corners' largest distance from the
//!   origin of a point of the segment `t ∈ [0, t_max]` (the shear's
//!   factors are at most 1 in magnitude, so the errors of the sheared
//!   corners map back to world space without growth), and a box's reach
//!   bounds that distance for every face below it. [`MARGIN`] is ~100×
//!   that, far above the f32 rounding of the slab test itself (a few
//!   roundings of distances at most that large: the margin is added
//!   after subtracting the origin, so a scene far from the world origin
//!   keeps it), so no box on the way to an accepted triangle is ever
//!   rejected: the reported set is the brute-force set, whatever the
//!   tree's shape. (The scene BVH's f32 slab test is conservative for the
//!   exact segment, Ize 2013, without a margin for the triangle test's
//!   own rounding; the two agree unless a triangle is accepted only
//!   within rounding of its box, which `tests/it/reference.rs` never meets
//!   on 100k random segments and the same-bits renders never met either.)

use crate::geom::bvh::intersect_triangle;
use crate::geom::SceneGeometry;
use crate::simd::f32x4;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Box enlargement relative to the largest coordinate distance from a
/// query's origin to the faces' bounds (see the module doc).
pub const MARGIN: f64 = 1e-4;

/// Four child boxes, structure-of-arrays (`lo[axis]` lane `k` is child
/// `k`'s); lanes past the last child hold zeros and are not `valid`.
#[derive(Debug, Clone, Copy)]
struct Node4 {
    lo: [f32x4; 3],
    hi: [f32x4; 3],
    /// Bit `k`: child `k` exists.
    valid: u32,
}

impl Node4 {
    /// The node over `boxes` (at most four), and its own bounds.
    fn new(boxes: &[(Vec3, Vec3)]) -> (Node4, (Vec3, Vec3)) {
        let mut lo = [[0.0; 4]; 3];
        let mut hi = [[0.0; 4]; 3];
        let mut bounds = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for (k, &(l, h)) in boxes.iter().enumerate() {
            for axis in 0..3 {
                lo[axis][k] = l[axis];
                hi[axis][k] = h[axis];
            }
            bounds = (bounds.0.min(l), bounds.1.max(h));
        }
        let node = Node4 {
            lo: lo.map(f32x4::new),
            hi: hi.map(f32x4::new),
            valid: (1u32 << boxes.len()) - 1,
        };
        (node, bounds)
    }
}

/// The faces and their implicit 4-wide tree.
#[derive(Debug, Clone, Default)]
pub struct FaceTree {
    /// Triangle index in the scene of each face, in tree order.
    ids: Vec<u32>,
    /// Corners of each face, in tree order.
    tris: Vec<[Vec3; 3]>,
    /// `levels[0][i]`: the boxes of faces `4i..4i + 4`; `levels[k][i]`:
    /// those of nodes `4i..4i + 4` of `levels[k − 1]`. The last level has
    /// one node (the root).
    levels: Vec<Vec<Node4>>,
}

/// Traversal stack entries: each level pushes at most 4 and pops 1, over
/// at most 15 levels (node indices below 2^27, so at most 2^29 faces).
const STACK: usize = 3 * 15 + 2;

impl FaceTree {
    /// Bytes of the tree: face ids and corners, and the node levels.
    pub fn bytes(&self) -> u64 {
        let nodes: usize = self.levels.iter().map(Vec::capacity).sum();
        (self.ids.capacity() * 4
            + self.tris.capacity() * std::mem::size_of::<[Vec3; 3]>()
            + nodes * std::mem::size_of::<Node4>()) as u64
    }

    /// The tree over the triangles of `geometry` for which `keep` is true.
    pub fn build(geometry: &SceneGeometry, keep: impl Fn(u32) -> bool + Sync) -> FaceTree {
        // In parallel where it is per face (the sort's keys are unique, so
        // the order, hence the tree, is the same on any thread count).
        // Boxes are recomputed from the corners where needed rather than
        // stored beside the faces and gathered: each fresh list is page
        // faults (278k faces at 1024²: 36–56 → 18–24 ms).
        let corners =
            |t: u32| geometry.triangles[t as usize].map(|i| geometry.positions[i as usize]);
        let bounds_of = |[a, b, c]: [Vec3; 3]| (a.min(b).min(c), a.max(b).max(c));
        let kept: Vec<u32> = (0..geometry.triangles.len() as u32)
            .into_par_iter()
            .filter(|&t| keep(t))
            .collect();
        // More would overflow the stack entries' index bits (and is far
        // beyond any scene this renderer loads).
        assert!(kept.len() < 1 << (LEVEL_SHIFT + 2), "too many faces");
        if kept.is_empty() {
            return FaceTree::default();
        }
        let bounds = kept
            .iter()
            .map(|&t| bounds_of(corners(t)))
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), (a, b)| {
                (l.min(a), h.max(b))
            });
        let extent = (bounds.1 - bounds.0).as_dvec3();
        let scale = DVec3::select(
            extent.cmpgt(DVec3::ZERO),
            DVec3::splat(1023.0) / extent,
            DVec3::ZERO,
        );
        let mut keyed: Vec<(u32, u32)> = kept
            .par_iter()
            .enumerate()
            .map(|(k, &t)| {
                let (l, h) = bounds_of(corners(t));
                let q = (((l + h).as_dvec3() * 0.5 - bounds.0.as_dvec3()) * scale)
                    .clamp(DVec3::ZERO, DVec3::splat(1023.0))
                    .as_uvec3();
                (spread(q.x) | spread(q.y) << 1 | spread(q.z) << 2, k as u32)
            })
            .collect();
        keyed.par_sort_unstable();
        let ids: Vec<u32> = keyed.par_iter().map(|&(_, k)| kept[k as usize]).collect();
        drop(keyed);
        let tris: Vec<[Vec3; 3]> = ids.par_iter().map(|&t| corners(t)).collect();
        let mut levels = Vec::new();
        let (nodes, mut boxes): (Vec<Node4>, Vec<(Vec3, Vec3)>) = tris
            .par_chunks(4)
            .map(|four| {
                let mut faces = [(Vec3::ZERO, Vec3::ZERO); 4];
                for (slot, &tri) in faces.iter_mut().zip(four) {
                    *slot = bounds_of(tri);
                }
                Node4::new(&faces[..four.len()])
            })
            .unzip();
        levels.push(nodes);
        while boxes.len() > 1 {
            let (nodes, up): (Vec<Node4>, Vec<(Vec3, Vec3)>) =
                boxes.par_chunks(4).map(Node4::new).unzip();
            levels.push(nodes);
            boxes = up;
        }
        FaceTree { ids, tris, levels }
    }

    /// Number of faces.
    pub fn triangle_count(&self) -> usize {
        self.ids.len()
    }

    /// Calls `f` with the scene triangle index of every face the
    /// watertight test ([`intersect_triangle`]) hits at `t ∈ (0, t_max)`
    /// on `origin + t · dir`, in no particular order, until `f` returns
    /// false. A zero, infinite or NaN direction or origin, or `t_max ≤
    /// 0`, hits nothing (as in the BVH).
    pub fn for_each_hit(&self, origin: Vec3, dir: Vec3, t_max: f32, f: impl FnMut(u32) -> bool) {
        self.for_each_hit_of(origin, dir, t_max, |_| true, f);
    }

    /// [`FaceTree::for_each_hit`] over the faces for which `wanted` (given
    /// the scene triangle index) is true: the others are not tested.
    pub fn for_each_hit_of(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        wanted: impl Fn(u32) -> bool,
        mut f: impl FnMut(u32) -> bool,
    ) {
        if !(t_max > 0.0 && dir.is_finite() && origin.is_finite() && dir != Vec3::ZERO) {
            return;
        }
        let org = [
            f32x4::splat(origin.x),
            f32x4::splat(origin.y),
            f32x4::splat(origin.z),
        ];
        // As the BVH: a subnormal component's inverse clamped to a
        // finite value, so `0 · ∞` cannot occur.
        let inv = |d: f32| f32x4::splat((1.0 / d).clamp(-f32::MAX, f32::MAX));
        let inv = [inv(dir.x), inv(dir.y), inv(dir.z)];
        let parallel = [dir.x == 0.0, dir.y == 0.0, dir.z == 0.0];
        let any_parallel = parallel.iter().any(|&p| p);
        let t_max4 = f32x4::splat(t_max);
        let zero = f32x4::ZERO;
        // Written out per axis (a loop over the axes is not unrolled).
        let hit_boxes = |node: &Node4| -> u32 {
            // The enlarged boxes relative to the origin, per axis.
            let l = [0, 1, 2].map(|a| node.lo[a] - org[a]);
            let h = [0, 1, 2].map(|a| node.hi[a] - org[a]);
            // The node's own reach bounds every face's below it.
            let reach = [0, 1, 2]
                .map(|a| l[a].abs().max(h[a].abs()))
                .into_iter()
                .reduce(f32x4::max)
                .unwrap_or(zero);
            let margin = reach * f32x4::splat(MARGIN as f32);
            let (lx, ly, lz) = (l[0] - margin, l[1] - margin, l[2] - margin);
            let (hx, hy, hz) = (h[0] + margin, h[1] + margin, h[2] + margin);
            let slab = |l: f32x4, h: f32x4, a: usize| {
                let (t0, t1) = (l * inv[a], h * inv[a]);
                (t0.min(t1), t0.max(t1))
            };
            if !any_parallel {
                let (nx, fx) = slab(lx, hx, 0);
                let (ny, fy) = slab(ly, hy, 1);
                let (nz, fz) = slab(lz, hz, 2);
                let near = zero.max(nx).max(ny).max(nz);
                let far = t_max4.min(fx).min(fy).min(fz);
                return near.cmp_le(far).move_mask() & node.valid;
            }
            let (mut near, mut far, mut inside) = (zero, t_max4, node.valid);
            for (a, (l, h)) in [(lx, hx), (ly, hy), (lz, hz)].into_iter().enumerate() {
                if parallel[a] {
                    inside &= (l.cmp_le(zero) & zero.cmp_le(h)).move_mask();
                } else {
                    let (n, f) = slab(l, h, a);
                    near = near.max(n);
                    far = far.min(f);
                }
            }
            near.cmp_le(far).move_mask() & inside
        };
        self.walk(hit_boxes, |child| {
            let (Some(tri), Some(&id)) = (self.tris.get(child), self.ids.get(child)) else {
                return true;
            };
            !(wanted(id) && intersect_triangle(origin, dir, t_max, tri).is_some() && !f(id))
        });
    }

    /// Depth-first over the nodes whose child boxes `boxes` lets through
    /// (a lane mask per node), calling `leaf` with the tree index of each
    /// face reached until it returns `false`; whether it did.
    #[inline(always)]
    fn walk(&self, boxes: impl Fn(&Node4) -> u32, mut leaf: impl FnMut(usize) -> bool) -> bool {
        let Some(top) = self.levels.len().checked_sub(1) else {
            return false;
        };
        // Entries `level << LEVEL_SHIFT | index`.
        let mut stack = [0u32; STACK];
        stack[0] = (top as u32) << LEVEL_SHIFT;
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let (level, index) = (
                (stack[len] >> LEVEL_SHIFT) as usize,
                (stack[len] & INDEX_MASK) as usize,
            );
            let Some(node) = self.levels.get(level).and_then(|l| l.get(index)) else {
                continue;
            };
            let mut mask = boxes(node);
            while mask != 0 {
                let child = 4 * index + mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if level > 0 {
                    // At most 4 per level below the root: within `STACK`.
                    if len < STACK {
                        stack[len] = ((level - 1) as u32) << LEVEL_SHIFT | child as u32;
                        len += 1;
                    }
                } else if !leaf(child) {
                    return true;
                }
            }
        }
        false
    }

    /// The faces `wanted` accepts that come within twice the margin
    /// [`for_each_hit_of`](Self::for_each_hit_of) gives a segment with
    /// its origin anywhere in `[lo, hi]` of that box (their boxes overlap
    /// the box so enlarged, and so do the faces themselves,
    /// [`triangle_meets_box`]), each given to `f` as its index in this
    /// tree until `f` returns `false`; whether `f` stopped it (or the box
    /// is not finite: nothing can be ruled out).
    /// [`hits_any`](Self::hits_any) then tests segments against them
    /// alone.
    ///
    /// A superset of what those walks report: a segment inside `[lo, hi]`
    /// that hits a face crosses its enlarged box, so that box overlaps
    /// `[lo, hi]`; the doubled margin covers the f32 rounding of the
    /// walk's own slab test (a few roundings of distances the margin is
    /// 10⁴ times); and the face itself lies within far less than the
    /// margin of the segment (the module doc). No face found therefore
    /// proves that no such segment hits a wanted face.
    pub fn faces_near(
        &self,
        lo: Vec3,
        hi: Vec3,
        wanted: impl Fn(u32) -> bool,
        mut f: impl FnMut(u32) -> bool,
    ) -> bool {
        if !(lo.is_finite() && hi.is_finite()) {
            return true;
        }
        let lo4 = [lo.x, lo.y, lo.z].map(f32x4::splat);
        let hi4 = [hi.x, hi.y, hi.z].map(f32x4::splat);
        let twice = f32x4::splat((2.0 * MARGIN) as f32);
        let overlaps = |node: &Node4| -> u32 {
            // The walk's margin for an origin anywhere in the box: the
            // node's reach from the farthest of the box's corners.
            let reach = [0, 1, 2]
                .map(|a| {
                    let (l, h) = (node.lo[a], node.hi[a]);
                    (l - lo4[a])
                        .abs()
                        .max((l - hi4[a]).abs())
                        .max((h - lo4[a]).abs())
                        .max((h - hi4[a]).abs())
                })
                .into_iter()
                .reduce(f32x4::max)
                .unwrap_or(f32x4::ZERO);
            let margin = reach * twice;
            let mut mask = node.valid;
            for a in 0..3 {
                let below = (node.lo[a] - margin).cmp_le(hi4[a]);
                let above = lo4[a].cmp_le(node.hi[a] + margin);
                mask &= (below & above).move_mask();
            }
            mask
        };
        self.walk(overlaps, |child| {
            let (Some(&id), Some(tri)) = (self.ids.get(child), self.tris.get(child)) else {
                return true;
            };
            let reach = tri
                .iter()
                .map(|&c| (c - lo).abs().max((c - hi).abs()).max_element())
                .fold(0.0, f32::max);
            !(wanted(id)
                && triangle_meets_box(tri, lo, hi, 2.0 * MARGIN * f64::from(reach))
                && !f(child as u32))
        })
    }

    /// Whether the segment `origin + t dir`, `t ∈ [0, t_max]`, hits one
    /// of the faces `near` (indices in this tree, from
    /// [`faces_near`](Self::faces_near) on a box holding the segment):
    /// the walk's own triangle test on each, so the same answer as a walk
    /// over the faces those stand for — the walk's box tests only prune
    /// faces the triangle test rejects.
    pub fn hits_any(&self, near: &[u32], origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        if !(t_max > 0.0 && dir.is_finite() && origin.is_finite() && dir != Vec3::ZERO) {
            return false;
        }
        near.iter().any(|&c| {
            self.tris
                .get(c as usize)
                .is_some_and(|tri| intersect_triangle(origin, dir, t_max, tri).is_some())
        })
    }
}

/// Whether triangle `tri` meets the box `[lo, hi]` enlarged by `margin`
/// on every side: the separating-axis test (the box's three axes, the
/// triangle's normal, the nine crossings of its edges with the box's
/// axes; Akenine-Möller 2001) in f64, whose rounding on f32 inputs is
/// ~10⁻¹⁶ of their size, far below any margin it is given here.
/// Conservative: `false` only when an axis separates them.
pub fn triangle_meets_box(tri: &[Vec3; 3], lo: Vec3, hi: Vec3, margin: f64) -> bool {
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    let centre = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5 + DVec3::splat(margin);
    let v = tri.map(|c| c.as_dvec3() - centre);
    let separated = |axis: DVec3| {
        let p = v.map(|c| c.dot(axis));
        let r = half.dot(axis.abs());
        p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r
    };
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let boxes = [DVec3::X, DVec3::Y, DVec3::Z];
    if boxes.iter().any(|&u| separated(u)) || separated(edges[0].cross(edges[1])) {
        return false;
    }
    !edges
        .iter()
        .any(|e| boxes.iter().any(|&u| separated(e.cross(u))))
}

/// Stack entries hold a level above this bit and a node index below.
const LEVEL_SHIFT: u32 = 27;
const INDEX_MASK: u32 = (1 << LEVEL_SHIFT) - 1;

/// The low 10 bits of `v` spread to every third bit (Morton code).
fn spread(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | x << 16) & 0x0300_00ff;
    x = (x | x << 8) & 0x0300_f00f;
    x = (x | x << 4) & 0x030c_30c3;
    (x | x << 2) & 0x0924_9249
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::bvh::Bvh;

    /// Deterministic pseudo-random numbers in [0, 1).
    fn rng(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A closed-ish mesh (a UV sphere), a ground quad, and a few random
    /// triangles, most kept.
    fn geometry() -> SceneGeometry {
        let mut g = SceneGeometry::default();
        let (seg, rings) = (24u32, 16u32);
        for r in 0..=rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..seg {
                let phi = 2.0 * std::f32::consts::PI * s as f32 / seg as f32;
                g.positions.push(Vec3::new(
                    theta.sin() * phi.cos() + 0.3,
                    theta.cos() + 1.5,
                    theta.sin() * phi.sin() - 0.2,
                ));
            }
        }
        for r in 0..rings {
            for s in 0..seg {
                let (a, b) = (r * seg + s, r * seg + (s + 1) % seg);
                let (c, d) = (a + seg, b + seg);
                g.triangles.push([a, c, b]);
                g.triangles.push([b, c, d]);
            }
        }
        let base = g.positions.len() as u32;
        g.positions.extend([
            Vec3::new(-5.0, 0.0, -5.0),
            Vec3::new(5.0, 0.0, -5.0),
            Vec3::new(5.0, 0.0, 5.0),
            Vec3::new(-5.0, 0.0, 5.0),
        ]);
        g.triangles.push([base, base + 2, base + 1]);
        g.triangles.push([base, base + 3, base + 2]);
        let mut s = 5u64;
        for _ in 0..40 {
            let base = g.positions.len() as u32;
            let c = Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 6.0 - 3.0;
            for _ in 0..3 {
                g.positions
                    .push(c + Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) - 0.5);
            }
            g.triangles.push([base, base + 1, base + 2]);
        }
        g
    }

    /// The same hit set as the scene BVH and as a brute-force loop, on
    /// long rays, axis-parallel rays and tiny segments from points on the
    /// faces (at vertices, on edges, inside) as `cap_near` casts them.
    #[test]
    fn hits_equal_the_bvh_and_brute_force() {
        let g = geometry();
        let keep = |t: u32| t % 7 != 3;
        let tree = FaceTree::build(&g, keep);
        let bvh = Bvh::build(&g, keep);
        assert_eq!(tree.triangle_count(), bvh.triangle_count());
        let kept: Vec<u32> = (0..g.triangles.len() as u32).filter(|&t| keep(t)).collect();
        let corners = |t: u32| g.triangles[t as usize].map(|i| g.positions[i as usize]);
        let mut s = 77u64;
        let (mut hits, mut rays) = (0usize, 0usize);
        let mut brute_even: Vec<u32> = Vec::new();
        for i in 0..6000 {
            let (o, d, t_max) = if i % 2 == 0 {
                // A tiny segment across a face's point (vertex, edge
                // midpoint, or inside).
                let t = kept[(rng(&mut s) * kept.len() as f32) as usize % kept.len()];
                let [a, b, c] = corners(t);
                let p = match i % 6 {
                    0 => a,
                    2 => (a + b) * 0.5,
                    _ => (a + b + c) / 3.0,
                };
                let n = (b - a).cross(c - a).normalize_or_zero();
                let d = (n + (Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) - 0.5) * 0.2) * 1e-4;
                (p - d * 0.25, d * 1.5, 1.0)
            } else {
                let o = Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 8.0 - 4.0;
                let mut d = Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 8.0 - 4.0 - o;
                if i % 10 == 1 {
                    let axis = i / 10 % 3;
                    let len = d[axis];
                    d = Vec3::ZERO;
                    d[axis] = if len == 0.0 { 1.0 } else { len };
                }
                (o, d, 0.2 + rng(&mut s))
            };
            let mut brute: Vec<u32> = kept
                .iter()
                .copied()
                .filter(|&t| intersect_triangle(o, d, t_max, &corners(t)).is_some())
                .collect();
            let mut walked = Vec::new();
            bvh.for_each_hit(o, d, t_max, |h| walked.push(h.triangle));
            let mut ours = Vec::new();
            tree.for_each_hit(o, d, t_max, |t| {
                ours.push(t);
                true
            });
            brute.sort_unstable();
            walked.sort_unstable();
            ours.sort_unstable();
            assert_eq!(ours, brute, "ray {i}: {o} {d} {t_max}");
            let mut even = Vec::new();
            tree.for_each_hit_of(
                o,
                d,
                t_max,
                |t| t % 2 == 0,
                |t| {
                    even.push(t);
                    true
                },
            );
            even.sort_unstable();
            brute_even.clear();
            brute_even.extend(brute.iter().filter(|&&t| t % 2 == 0));
            assert_eq!(even, brute_even, "ray {i} (even faces)");
            assert_eq!(walked, brute, "ray {i} (bvh): {o} {d} {t_max}");
            hits += usize::from(!ours.is_empty());
            rays += 1;
        }
        assert!(hits > rays / 4 && hits < rays, "{hits} of {rays} rays hit");
        // Early stop: `f` returning false ends the walk.
        let mut calls = 0;
        tree.for_each_hit(
            Vec3::new(0.3, 5.0, -0.2),
            Vec3::new(0.0, -10.0, 0.0),
            1.0,
            |_| {
                calls += 1;
                false
            },
        );
        assert_eq!(calls, 1);
        // Degenerate queries and an empty tree hit nothing.
        let mut any = false;
        tree.for_each_hit(Vec3::ZERO, Vec3::ZERO, 1.0, |_| {
            any = true;
            true
        });
        tree.for_each_hit(Vec3::ZERO, Vec3::Y, 0.0, |_| {
            any = true;
            true
        });
        FaceTree::build(&g, |_| false).for_each_hit(Vec3::ZERO, Vec3::Y, 9.0, |_| {
            any = true;
            true
        });
        assert!(!any);
    }

    #[test]
    fn box_queries_cover_every_walk_inside_the_box() {
        let g = geometry();
        let keep = |t: u32| t % 7 != 3;
        let tree = FaceTree::build(&g, keep);
        let kept: Vec<u32> = (0..g.triangles.len() as u32).filter(|&t| keep(t)).collect();
        let corners = |t: u32| g.triangles[t as usize].map(|i| g.positions[i as usize]);
        let mut s = 91u64;
        let (mut cleared, mut hit_groups) = (0, 0);
        for i in 0..3000 {
            // A cluster of short segments along the normal of one face
            // (as the own-face segments of a pixel block), some at its
            // edges and corners where the neighbours come near.
            let own = kept[(rng(&mut s) * kept.len() as f32) as usize % kept.len()];
            let [a, b, c] = corners(own);
            let n = (b - a).cross(c - a).normalize_or_zero();
            let spread = [0.02, 0.2, 1.0][i % 3];
            let segments: Vec<(Vec3, Vec3)> = (0..6)
                .map(|_| {
                    let (mut u, mut v) = (rng(&mut s) * spread, rng(&mut s) * spread);
                    if u + v > 1.0 {
                        (u, v) = (1.0 - u, 1.0 - v);
                    }
                    let p = a + (b - a) * u + (c - a) * v;
                    let d = n * (1e-4 * (0.5 + rng(&mut s)));
                    (p - d * 0.25, d * 1.5)
                })
                .collect();
            let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
            for &(o, d) in &segments {
                lo = lo.min(o).min(o + d);
                hi = hi.max(o).max(o + d);
            }
            let wanted = |t: u32| t != own;
            let any_hit = segments.iter().any(|&(o, d)| {
                let mut hit = false;
                tree.for_each_hit_of(o, d, 1.0, wanted, |_| {
                    hit = true;
                    false
                });
                hit
            });
            let near = tree.faces_near(lo, hi, wanted, |_| false);
            assert!(
                near || !any_hit,
                "cluster {i}: a walk hits but the box query clears it"
            );
            cleared += usize::from(!near);
            hit_groups += usize::from(any_hit);
        }
        // Both answers occur: the query clears most clusters, and some
        // clusters do hit another face.
        assert!(
            cleared > 1000 && hit_groups > 0,
            "{cleared} cleared, {hit_groups} hit"
        );
    }

    #[test]
    fn triangle_box_test_is_conservative_and_separates() {
        let mut s = 3u64;
        let mut v = || Vec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 2.0 - 1.0;
        let (mut met, mut apart) = (0, 0);
        for _ in 0..20000 {
            let tri = [v(), v(), v()];
            let (c, e) = (v(), v().abs() * 0.3);
            let (lo, hi) = (c - e, c + e);
            let meets = triangle_meets_box(&tri, lo, hi, 0.0);
            // A point of the triangle inside the box forces `true`.
            for k in 0..64 {
                let (mut u, mut w) = ((k % 8) as f32 / 7.0, (k / 8) as f32 / 7.0);
                if u + w > 1.0 {
                    (u, w) = (1.0 - u, 1.0 - w);
                }
                let p = tri[0] + (tri[1] - tri[0]) * u + (tri[2] - tri[0]) * w;
                if p.cmpge(lo).all() && p.cmple(hi).all() {
                    assert!(meets, "{tri:?} has {p} inside [{lo}, {hi}]");
                }
            }
            met += usize::from(meets);
            apart += usize::from(!meets);
            // A margin only ever adds a `true`.
            assert!(!meets || triangle_meets_box(&tri, lo, hi, 0.1));
        }
        assert!(met > 1000 && apart > 1000, "{met} met, {apart} apart");
    }
}
