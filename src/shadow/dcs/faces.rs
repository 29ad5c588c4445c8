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
//!   origin), each enlarged at query time by [`MARGIN`] × the largest
//!   coordinate distance from the ray's origin to the faces' bounds. The
//!   watertight
//!   test works on the corners translated to the origin and sheared, in
//!   f32: a triangle it accepts lies within about 20 f32 roundings
//!   (≈ 1.2e-6) of that distance of a point of the segment `t ∈ [0,
//!   t_max]` (the shear's factors are at most 1 in magnitude, so the
//!   errors of the sheared corners map back to world space without
//!   growth). [`MARGIN`] is ~100× that, far above the f32 rounding of the
//!   slab test itself (a few roundings of distances at most that large:
//!   the margin is added after subtracting the origin, so a scene far
//!   from the world origin keeps it), so no box on the way to an accepted
//!   triangle is
//!   ever rejected: the reported set is the brute-force set, whatever the
//!   tree's shape. (The scene BVH's f32 slab test is conservative for the
//!   exact segment, Ize 2013, without a margin for the triangle test's
//!   own rounding; the two agree unless a triangle is accepted only
//!   within rounding of its box, which `tests/reference.rs` never meets
//!   on 100k random segments and the same-bits renders never met either.)

use crate::geom::bvh::intersect_triangle;
use crate::geom::SceneGeometry;
use crate::simd::f32x4;
use glam::{DVec3, Vec3};

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
    /// Bounds of all faces.
    bounds: (Vec3, Vec3),
}

/// Traversal stack entries: each level pushes at most 4 and pops 1, over
/// at most 15 levels (node indices below 2^27, so at most 2^29 faces).
const STACK: usize = 3 * 15 + 2;

impl FaceTree {
    /// The tree over the triangles of `geometry` for which `keep` is true.
    pub fn build(geometry: &SceneGeometry, keep: impl Fn(u32) -> bool) -> FaceTree {
        let corners =
            |t: u32| geometry.triangles[t as usize].map(|i| geometry.positions[i as usize]);
        let faces: Vec<(u32, (Vec3, Vec3))> = (0..geometry.triangles.len() as u32)
            .filter(|&t| keep(t))
            .map(|t| {
                let [a, b, c] = corners(t);
                (t, (a.min(b).min(c), a.max(b).max(c)))
            })
            .collect();
        // More would overflow the stack entries' index bits (and is far
        // beyond any scene this renderer loads).
        assert!(faces.len() < 1 << (LEVEL_SHIFT + 2), "too many faces");
        if faces.is_empty() {
            return FaceTree::default();
        }
        let bounds = faces.iter().fold(
            (Vec3::INFINITY, Vec3::NEG_INFINITY),
            |(l, h), (_, (a, b))| (l.min(*a), h.max(*b)),
        );
        let extent = (bounds.1 - bounds.0).as_dvec3();
        let scale = DVec3::select(
            extent.cmpgt(DVec3::ZERO),
            DVec3::splat(1023.0) / extent,
            DVec3::ZERO,
        );
        let mut keyed: Vec<(u32, u32)> = faces
            .iter()
            .enumerate()
            .map(|(k, (_, (l, h)))| {
                let q = (((*l + *h).as_dvec3() * 0.5 - bounds.0.as_dvec3()) * scale)
                    .clamp(DVec3::ZERO, DVec3::splat(1023.0))
                    .as_uvec3();
                (spread(q.x) | spread(q.y) << 1 | spread(q.z) << 2, k as u32)
            })
            .collect();
        keyed.sort_unstable();
        let ids: Vec<u32> = keyed.iter().map(|&(_, k)| faces[k as usize].0).collect();
        let tris = ids.iter().map(|&t| corners(t)).collect();
        let mut boxes: Vec<(Vec3, Vec3)> =
            keyed.iter().map(|&(_, k)| faces[k as usize].1).collect();
        let mut levels = Vec::new();
        loop {
            let (nodes, up): (Vec<Node4>, Vec<(Vec3, Vec3)>) =
                boxes.chunks(4).map(Node4::new).unzip();
            levels.push(nodes);
            if up.len() == 1 {
                break;
            }
            boxes = up;
        }
        FaceTree {
            ids,
            tris,
            levels,
            bounds,
        }
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
        let Some(top) = self.levels.len().checked_sub(1) else {
            return;
        };
        if !(t_max > 0.0 && dir.is_finite() && origin.is_finite() && dir != Vec3::ZERO) {
            return;
        }
        let reach = (self.bounds.0 - origin)
            .as_dvec3()
            .abs()
            .max((self.bounds.1 - origin).as_dvec3().abs())
            .max_element();
        let margin = f32x4::splat((MARGIN * reach) as f32);
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
            let lo = |a: usize| (node.lo[a] - org[a]) - margin;
            let hi = |a: usize| (node.hi[a] - org[a]) + margin;
            let (lx, ly, lz) = (lo(0), lo(1), lo(2));
            let (hx, hy, hz) = (hi(0), hi(1), hi(2));
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
            let mut mask = hit_boxes(node);
            while mask != 0 {
                let child = 4 * index + mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if level > 0 {
                    // At most 4 per level below the root: within `STACK`.
                    if len < STACK {
                        stack[len] = ((level - 1) as u32) << LEVEL_SHIFT | child as u32;
                        len += 1;
                    }
                    continue;
                }
                let (Some(tri), Some(&id)) = (self.tris.get(child), self.ids.get(child)) else {
                    continue;
                };
                if wanted(id) && intersect_triangle(origin, dir, t_max, tri).is_some() && !f(id) {
                    return;
                }
            }
        }
    }
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
}
