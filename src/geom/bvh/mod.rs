//! Bounding volume hierarchy for shadow rays.
//!
//! - **Build**: binned SAH (16 bins per axis over the centroid bounds,
//!   leaves of at most [`MAX_LEAF`] triangles) into a binary tree, then
//!   collapsed into a 4-wide tree (each node holds the boxes of up to four
//!   children, opened largest-surface-area first). Subtrees build in
//!   parallel with `rayon::join`, but every decision (bins, costs,
//!   partition) is made by one thread from the same data in the same
//!   order, so the tree is identical for any thread count.
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
//!   both miss a ray through it.

mod hull;
mod packet;

pub use hull::SegmentHull;

pub use packet::PACKET;

use crate::geom::SceneGeometry;
use crate::simd::f32x4;
use glam::Vec3;
use rayon::prelude::*;
use std::ops::Range;

/// Most triangles in a leaf.
pub const MAX_LEAF: usize = 4;

/// SAH bins per axis.
const BINS: usize = 16;

/// Subtrees with at least this many triangles build their children in
/// parallel; below it the `rayon::join` overhead outweighs the work.
const PARALLEL_BUILD: usize = 4096;

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

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Aabb {
    lo: Vec3,
    hi: Vec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        lo: Vec3::INFINITY,
        hi: Vec3::NEG_INFINITY,
    };

    #[inline]
    fn grow(&mut self, b: &Aabb) {
        self.lo = self.lo.min(b.lo);
        self.hi = self.hi.max(b.hi);
    }

    #[inline]
    fn grow_point(&mut self, p: Vec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }

    /// Half the surface area (the SAH only compares ratios); 0 when empty.
    #[inline]
    fn half_area(&self) -> f32 {
        let e = (self.hi - self.lo).max(Vec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

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
    /// Triangle corners in leaf order (copied, so a leaf reads one run).
    tris: Vec<[Vec3; 3]>,
    /// Index in the source geometry of each triangle of `tris`.
    ids: Vec<u32>,
}

/// The binary build tree, before collapsing.
enum Build {
    Leaf {
        bounds: Aabb,
        range: Range<usize>,
    },
    Inner {
        bounds: Aabb,
        children: Box<[Build; 2]>,
    },
}

impl Build {
    fn bounds(&self) -> &Aabb {
        match self {
            Build::Leaf { bounds, .. } | Build::Inner { bounds, .. } => bounds,
        }
    }
}

/// Per-triangle build input.
#[derive(Clone, Copy)]
struct Prim {
    bounds: Aabb,
    centroid: Vec3,
    id: u32,
}

impl Bvh {
    /// Builds a BVH over the triangles of `geometry` for which `keep`
    /// (given the triangle index) is true.
    pub fn build(geometry: &SceneGeometry, keep: impl Fn(u32) -> bool + Sync) -> Bvh {
        let mut prims: Vec<Prim> = (0..geometry.triangles.len() as u32)
            .into_par_iter()
            .filter(|&t| keep(t))
            .map(|t| {
                let mut bounds = Aabb::EMPTY;
                for p in corners(geometry, t) {
                    bounds.grow_point(p);
                }
                Prim {
                    bounds,
                    centroid: (bounds.lo + bounds.hi) * 0.5,
                    id: t,
                }
            })
            .collect();
        if prims.is_empty() {
            return Bvh::default();
        }
        let root = build_node(&mut prims, 0, 0);
        let mut bvh = Bvh {
            nodes: Vec::new(),
            tris: prims.iter().map(|p| corners(geometry, p.id)).collect(),
            ids: prims.iter().map(|p| p.id).collect(),
        };
        bvh.collapse(&[&root]);
        bvh
    }

    /// Number of triangles in the tree.
    pub fn triangle_count(&self) -> usize {
        self.ids.len()
    }

    /// Number of 4-wide nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Appends the 4-wide node whose children are `items` opened up to
    /// four wide (largest surface area first), then its inner children;
    /// returns its index. Nodes are numbered in depth-first order.
    fn collapse(&mut self, items: &[&Build]) -> u32 {
        let mut kids: Vec<&Build> = items.to_vec();
        while kids.len() < 4 {
            // The inner child with the largest area; ties: the first.
            let mut best: Option<(usize, f32)> = None;
            for (i, k) in kids.iter().enumerate() {
                if let Build::Inner { bounds, .. } = k {
                    let a = bounds.half_area();
                    if best.is_none_or(|(_, b)| a > b) {
                        best = Some((i, a));
                    }
                }
            }
            let Some((i, _)) = best else { break };
            if let Build::Inner { children, .. } = kids[i] {
                let [l, r] = &**children;
                kids.splice(i..=i, [l, r]);
            }
        }
        let index = self.nodes.len();
        self.nodes.push(Node::EMPTY);
        let mut node = Node::EMPTY;
        for (slot, kid) in kids.iter().enumerate() {
            let b = kid.bounds();
            for axis in 0..3 {
                node.lo[axis][slot] = b.lo[axis];
                node.hi[axis][slot] = b.hi[axis];
            }
            match kid {
                Build::Leaf { range, .. } => {
                    node.child[slot] = range.start as u32;
                    node.count[slot] = range.len() as u32;
                }
                Build::Inner { children, .. } => {
                    let [l, r] = &**children;
                    node.child[slot] = self.collapse(&[l, r]);
                }
            }
        }
        self.nodes[index] = node;
        index as u32
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
                let (Some(tris), Some(ids)) = (self.tris.get(leaf.clone()), self.ids.get(leaf))
                else {
                    return true;
                };
                for (tri, &id) in tris.iter().zip(ids) {
                    if let Some((t, b1, b2)) = ray.intersect(tri) {
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

/// The corners of triangle `t` of `geometry`.
#[inline]
fn corners(geometry: &SceneGeometry, t: u32) -> [Vec3; 3] {
    geometry.triangles[t as usize].map(|i| geometry.positions[i as usize])
}

/// Builds the binary subtree over `prims` (whose first element has index
/// `offset` in the whole array).
fn build_node(prims: &mut [Prim], offset: usize, depth: u32) -> Build {
    let mut bounds = Aabb::EMPTY;
    let mut cbounds = Aabb::EMPTY;
    for p in prims.iter() {
        bounds.grow(&p.bounds);
        cbounds.grow_point(p.centroid);
    }
    let n = prims.len();
    let leaf = |bounds| Build::Leaf {
        bounds,
        range: offset..offset + n,
    };
    if n == 1 {
        return leaf(bounds);
    }
    let split = if depth < SAH_MAX_DEPTH {
        sah_split(prims, &bounds, &cbounds)
    } else {
        None
    };
    let mid = match split {
        Some(Split::Bins { axis, bin }) => {
            let (lo, scale) = bin_mapping(&cbounds, axis);
            partition(prims, |p| bin_of(p.centroid[axis], lo, scale) <= bin)
        }
        Some(Split::Leaf) if n <= MAX_LEAF => return leaf(bounds),
        // No useful SAH split (all centroids in one bin, or too deep):
        // object median along the widest centroid axis, ties by id.
        _ => {
            let e = cbounds.hi - cbounds.lo;
            let axis = if e.x >= e.y && e.x >= e.z {
                0
            } else if e.y >= e.z {
                1
            } else {
                2
            };
            prims.sort_unstable_by(|a, b| {
                a.centroid[axis]
                    .total_cmp(&b.centroid[axis])
                    .then(a.id.cmp(&b.id))
            });
            n / 2
        }
    };
    let (left, right) = prims.split_at_mut(mid);
    let (l, r) = if n >= PARALLEL_BUILD {
        rayon::join(
            || build_node(left, offset, depth + 1),
            || build_node(right, offset + mid, depth + 1),
        )
    } else {
        (
            build_node(left, offset, depth + 1),
            build_node(right, offset + mid, depth + 1),
        )
    };
    Build::Inner {
        bounds,
        children: Box::new([l, r]),
    }
}

/// The SAH's verdict for a node.
enum Split {
    /// Split after bin `bin` along `axis`.
    Bins { axis: usize, bin: usize },
    /// Not splitting is cheaper.
    Leaf,
}

/// Bin mapping along `axis`: `(lower bound, bins per unit)`.
#[inline]
fn bin_mapping(cbounds: &Aabb, axis: usize) -> (f32, f32) {
    let extent = cbounds.hi[axis] - cbounds.lo[axis];
    (cbounds.lo[axis], BINS as f32 / extent)
}

#[inline]
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// Best binned-SAH split, `None` when the centroids cannot be separated.
/// Costs: traversal 1, triangle 1 (relative to the parent's area).
fn sah_split(prims: &[Prim], bounds: &Aabb, cbounds: &Aabb) -> Option<Split> {
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if !(cbounds.hi[axis] > cbounds.lo[axis]) {
            continue;
        }
        let (lo, scale) = bin_mapping(cbounds, axis);
        let mut boxes = [Aabb::EMPTY; BINS];
        let mut counts = [0usize; BINS];
        for p in prims {
            let b = bin_of(p.centroid[axis], lo, scale);
            boxes[b].grow(&p.bounds);
            counts[b] += 1;
        }
        // Right-to-left sweep: area × count of bins b+1.. for each split.
        let mut right_cost = [0.0f32; BINS];
        let (mut acc, mut count) = (Aabb::EMPTY, 0usize);
        for b in (1..BINS).rev() {
            acc.grow(&boxes[b]);
            count += counts[b];
            right_cost[b - 1] = acc.half_area() * count as f32;
        }
        let (mut acc, mut count) = (Aabb::EMPTY, 0usize);
        for b in 0..BINS - 1 {
            acc.grow(&boxes[b]);
            count += counts[b];
            if count == 0 || count == prims.len() {
                continue;
            }
            let cost = acc.half_area() * count as f32 + right_cost[b];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    let (cost, axis, bin) = best?;
    let area = bounds.half_area();
    // Leaf cost n vs split cost 1 + (A_l n_l + A_r n_r) / A.
    let leaf_cost = prims.len() as f32;
    if area > 0.0 && 1.0 + cost / area >= leaf_cost {
        return Some(Split::Leaf);
    }
    Some(Split::Bins { axis, bin })
}

/// Stable-order-independent in-place partition: elements satisfying
/// `left` first. Returns their count. Sequential, hence deterministic.
fn partition(prims: &mut [Prim], left: impl Fn(&Prim) -> bool) -> usize {
    let mut i = 0;
    for j in 0..prims.len() {
        if left(&prims[j]) {
            prims.swap(i, j);
            i += 1;
        }
    }
    i
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
