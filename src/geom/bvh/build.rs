//! The BVH build: binned SAH collapsed into 4-wide nodes, the same tree
//! for any thread count (see the parent module's documentation).

use super::leaf::LeafCorners;
use super::{Bvh, Node, ALWAYS_LEAF, MAX_LEAF, SAH_MAX_DEPTH, SAH_TRAVERSAL};
use crate::geom::SceneGeometry;
use crate::simd::{f32x4, i32x4};
use glam::Vec3;
use rayon::prelude::*;

/// SAH bins per axis.
const BINS: usize = 16;

/// Subtrees with at least this many triangles build their children in
/// parallel; below it the `rayon::join` overhead outweighs the work.
const PARALLEL_BUILD: usize = 4096;

/// Ranges with at least this many triangles bin, partition and bound
/// their triangles over [`CHUNK`]-sized chunks in parallel.
pub(super) const PARALLEL_SPLIT: usize = 1 << 16;

/// Chunk size of the parallel binning, partition and bounds.
const CHUNK: usize = 1 << 14;

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

/// Per-triangle build input: the triangle's bounds in lanes x, y, z of
/// two `f32x4`; lane 3 of `lo_id` holds the bits of the triangle's index
/// (32 bytes, two aligned loads). [`Prim::lo`] clears that lane: small
/// indices are subnormal floats, which arithmetic would slow to a crawl.
#[derive(Debug, Clone, Copy)]
struct Prim {
    lo_id: f32x4,
    hi: f32x4,
}

impl Prim {
    #[inline]
    fn new(bounds: &Aabb, id: u32) -> Prim {
        let lo = f32x4::new([bounds.lo.x, bounds.lo.y, bounds.lo.z, 0.0]).cast_i32();
        let id = i32x4::new([0, 0, 0, id as i32]);
        Prim {
            lo_id: (lo | id).cast_f32(),
            hi: f32x4::new([bounds.hi.x, bounds.hi.y, bounds.hi.z, 0.0]),
        }
    }

    #[inline(always)]
    fn id(&self) -> u32 {
        self.lo_id.cast_i32().to_array()[3] as u32
    }

    /// The lower bounds (lane 3: 0).
    #[inline(always)]
    fn lo(&self) -> f32x4 {
        self.lo_id & i32x4::new([-1, -1, -1, 0]).cast_f32()
    }

    /// `(lo + hi) · 0.5` per axis (lane 3: 0).
    #[inline(always)]
    fn centroid(&self) -> f32x4 {
        (self.lo() + self.hi) * f32x4::splat(0.5)
    }
}

/// A box in lanes x, y, z (lane 3: unused), grown by SIMD min / max.
#[derive(Debug, Clone, Copy)]
struct Box4 {
    lo: f32x4,
    hi: f32x4,
}

impl Box4 {
    const EMPTY: Box4 = Box4 {
        lo: f32x4::new([f32::INFINITY; 4]),
        hi: f32x4::new([f32::NEG_INFINITY; 4]),
    };

    /// Grows the box by `[lo, hi]`. The new bounds are the left operands
    /// of `min` / `max` (`minps` rule: NaN gives the right one), so a NaN
    /// (a centroid of a triangle with NaN corners) leaves the box as is,
    /// as `f32::min` / `f32::max` did. Triangle bounds hold no NaN: they
    /// grow from ±∞ by `f32::min` / `f32::max`.
    #[inline(always)]
    fn grow(&mut self, lo: f32x4, hi: f32x4) {
        self.lo = lo.min(self.lo);
        self.hi = hi.max(self.hi);
    }

    #[inline(always)]
    fn merge(&mut self, other: &Box4) {
        self.grow(other.lo, other.hi);
    }

    /// [`Aabb::half_area`] of the box: the same operations in the same
    /// order (up to the sign of a zero), without the conversion.
    #[inline(always)]
    fn half_area(&self) -> f32 {
        let e = (self.hi - self.lo).max(f32x4::ZERO).to_array();
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }

    #[inline]
    fn aabb(&self) -> Aabb {
        let (lo, hi) = (self.lo.to_array(), self.hi.to_array());
        Aabb {
            lo: Vec3::new(lo[0], lo[1], lo[2]),
            hi: Vec3::new(hi[0], hi[1], hi[2]),
        }
    }
}

/// The bounds of a set of triangles and of their centroids.
#[derive(Debug, Clone, Copy)]
struct Extent {
    bounds: Box4,
    cbounds: Box4,
}

impl Extent {
    const EMPTY: Extent = Extent {
        bounds: Box4::EMPTY,
        cbounds: Box4::EMPTY,
    };

    #[inline(always)]
    fn add(&mut self, p: &Prim) {
        self.bounds.grow(p.lo(), p.hi);
        let c = p.centroid();
        self.cbounds.grow(c, c);
    }

    #[inline]
    fn merge(mut self, other: Extent) -> Extent {
        self.bounds.merge(&other.bounds);
        self.cbounds.merge(&other.cbounds);
        self
    }

    /// The extent of `prims`, over chunks in parallel when there are many
    /// (merged in chunk order: min / max are exact, but which zero a tie
    /// of −0 and +0 keeps depends on the order).
    fn of(prims: &[Prim]) -> Extent {
        let seq = |ps: &[Prim]| {
            let mut e = Extent::EMPTY;
            for p in ps {
                e.add(p);
            }
            e
        };
        if prims.len() >= PARALLEL_SPLIT {
            let parts: Vec<Extent> = prims.par_chunks(CHUNK).map(seq).collect();
            parts.into_iter().fold(Extent::EMPTY, Extent::merge)
        } else {
            seq(prims)
        }
    }
}

/// A range of triangles waiting for a slot of a 4-wide node: a leaf, or an
/// inner range already partitioned at `cut.mid` (its two halves not yet
/// looked at).
#[derive(Debug, Clone, Copy)]
struct Item {
    bounds: Aabb,
    len: usize,
    depth: u32,
    cut: Option<Cut>,
}

/// Where an inner range is split, and the extents of its two halves.
#[derive(Debug, Clone, Copy)]
struct Cut {
    mid: usize,
    left: Extent,
    right: Extent,
}

/// Nodes built by one task: numbered depth-first from 0 within the chunk;
/// the inner children built by other tasks (`subs`: node, slot, chunk) are
/// linked when the chunks are laid out one after another
/// ([`Chunk::flatten`]).
#[derive(Default)]
struct Chunk {
    nodes: Vec<Node>,
    subs: Vec<(u32, usize, Chunk)>,
}

impl Chunk {
    fn count(&self) -> usize {
        self.nodes.len() + self.subs.iter().map(|(_, _, c)| c.count()).sum::<usize>()
    }

    /// Writes this chunk's nodes to the start of `out` (`count()` nodes,
    /// the first numbered `base`), then its sub-chunks in order (each
    /// right after the previous one, written in parallel), linking the
    /// slots that lead to them.
    fn flatten(self, out: &mut [Node], base: u32) {
        let (own, mut rest) = out.split_at_mut(self.nodes.len());
        for (dst, mut node) in own.iter_mut().zip(self.nodes) {
            for slot in 0..4 {
                if node.count[slot] == 0 && node.child[slot] != u32::MAX {
                    node.child[slot] += base;
                }
            }
            *dst = node;
        }
        let mut next = base + own.len() as u32;
        let mut jobs = Vec::with_capacity(self.subs.len());
        for (index, slot, sub) in self.subs {
            own[index as usize].child[slot] = next;
            let size = sub.count();
            let (mine, tail) = std::mem::take(&mut rest).split_at_mut(size);
            rest = tail;
            jobs.push((mine, next, sub));
            next += size as u32;
        }
        jobs.into_par_iter()
            .for_each(|(mine, base, sub)| sub.flatten(mine, base));
    }
}

impl Bvh {
    /// Builds a BVH over the triangles of `geometry` for which `keep`
    /// (given the triangle index) is true.
    pub fn build(geometry: &SceneGeometry, keep: impl Fn(u32) -> bool + Sync) -> Bvh {
        let prim = |t: u32| {
            let mut bounds = Aabb::EMPTY;
            for p in corners(geometry, t) {
                bounds.grow_point(p);
            }
            Prim::new(&bounds, t)
        };
        let all = 0..geometry.triangles.len() as u32;
        // Usually every triangle is kept: then the prims come straight
        // from the indices (the kept list cost 26–38 ms of 4.1M
        // triangles' build). Otherwise the kept indices first (4 bytes
        // each), then the prims by an indexed collect: filtering the prims
        // themselves collected them into a list of vectors and copied
        // them once more.
        let mut prims: Vec<Prim> = if all.clone().into_par_iter().all(&keep) {
            all.into_par_iter().map(prim).collect()
        } else {
            let kept: Vec<u32> = all.into_par_iter().filter(|&t| keep(t)).collect();
            kept.into_par_iter().map(prim).collect()
        };
        if prims.is_empty() {
            return Bvh::default();
        }
        let extent = Extent::of(&prims);
        let root = classify(&mut prims, extent, 0);
        let mut chunk = Chunk::default();
        build_node(&mut prims, 0, root, &mut chunk);
        // Laid out in parallel: sequentially this was 0.15 s of 4.1M
        // triangles' build (1.1M nodes) that no other thread shared.
        let total = chunk.count();
        let mut nodes = Vec::with_capacity(total);
        nodes.par_extend(rayon::iter::repeat_n(Node::EMPTY, total));
        chunk.flatten(&mut nodes, 0);
        // The build input goes before the corners are copied: the peak
        // holds one of the two.
        let ids: Vec<u32> = prims.par_iter().map(Prim::id).collect();
        drop(prims);
        // The leaves in leaf order, each `(first, count)`: they tile it.
        let mut leaves: Vec<(u32, u32)> = nodes
            .par_iter()
            .flat_map_iter(|n: &Node| {
                (0..4)
                    .filter(|&s| n.count[s] > 0)
                    .map(move |s| (n.child[s], n.count[s]))
            })
            .collect();
        leaves.par_sort_unstable();
        let tris = LeafCorners::build(&leaves, |i| corners(geometry, ids[i]));
        Bvh { nodes, tris, ids }
    }
}

/// The corners of triangle `t` of `geometry`.
#[inline]
pub(super) fn corners(geometry: &SceneGeometry, t: u32) -> [Vec3; 3] {
    geometry.triangles[t as usize].map(|i| geometry.positions[i as usize])
}

/// Builds into `chunk` the 4-wide node for `item` (over all of `prims`,
/// whose first element has index `offset` in leaf order) and, depth
/// first, the nodes below it; returns its index in `chunk`.
///
/// The node's slots start as `[item]`; while fewer than four, the inner
/// one with the largest area (ties: the first) is replaced by its two
/// halves, each classified in turn: the 4-wide collapse of the binary SAH
/// tree, without building that tree. Inner slots of at least
/// [`PARALLEL_BUILD`] triangles become chunks of their own, built in
/// parallel; the others are built into `chunk`.
fn build_node(prims: &mut [Prim], offset: usize, item: Item, chunk: &mut Chunk) -> u32 {
    // (start in `prims`, item), in order: the slots tile `prims`.
    let mut kids = [(0usize, item); 4];
    let mut len = 1;
    while len < 4 {
        let mut best: Option<(usize, f32)> = None;
        for (i, (_, k)) in kids[..len].iter().enumerate() {
            if k.cut.is_some() {
                let a = k.bounds.half_area();
                if best.is_none_or(|(_, b)| a > b) {
                    best = Some((i, a));
                }
            }
        }
        let Some((i, _)) = best else { break };
        let (start, open) = kids[i];
        let Some(cut) = open.cut else { break };
        let (l, r) = prims[start..start + open.len].split_at_mut(cut.mid);
        let depth = open.depth + 1;
        let (left, right) = if open.len >= PARALLEL_BUILD {
            rayon::join(
                || classify(l, cut.left, depth),
                || classify(r, cut.right, depth),
            )
        } else {
            (classify(l, cut.left, depth), classify(r, cut.right, depth))
        };
        kids.copy_within(i + 1..len, i + 2);
        kids[i] = (start, left);
        kids[i + 1] = (start + cut.mid, right);
        len += 1;
    }
    let index = chunk.nodes.len();
    chunk.nodes.push(Node::EMPTY);
    let mut node = Node::EMPTY;
    // Each slot's triangles; the inner slots are built from these after
    // the loop (fixed arrays: no allocation per node, and the items stay
    // in `kids` rather than being moved through arrays of options).
    let mut parts: [&mut [Prim]; 4] = Default::default();
    let mut big = false;
    let mut rest = prims;
    for (slot, &(start, kid)) in kids[..len].iter().enumerate() {
        for axis in 0..3 {
            node.lo[axis][slot] = kid.bounds.lo[axis];
            node.hi[axis][slot] = kid.bounds.hi[axis];
        }
        let (mine, tail) = std::mem::take(&mut rest).split_at_mut(kid.len);
        rest = tail;
        if kid.cut.is_none() {
            // Leaf order: by triangle index, whatever the partitions did.
            mine.sort_unstable_by_key(Prim::id);
            node.child[slot] = (offset + start) as u32;
            node.count[slot] = kid.len as u32;
        } else {
            big |= kid.len >= PARALLEL_BUILD;
            parts[slot] = mine;
        }
    }
    let kids = &kids[..len];
    let inner = |slot: usize| kids[slot].1.cut.is_some();
    let is_big = |slot: usize| inner(slot) && kids[slot].1.len >= PARALLEL_BUILD;
    let subs = if big {
        let (mut small_parts, mut big_parts) = (Vec::new(), Vec::new());
        for (slot, part) in parts.iter_mut().enumerate().take(len) {
            let entry = (slot, std::mem::take(part));
            if is_big(slot) {
                big_parts.push(entry);
            } else if inner(slot) {
                small_parts.push(entry);
            }
        }
        let build_small = || {
            for (slot, part) in small_parts {
                let (start, kid) = kids[slot];
                node.child[slot] = build_node(part, offset + start, kid, chunk);
            }
        };
        rayon::join(
            || {
                big_parts
                    .into_par_iter()
                    .map(|(slot, part)| {
                        let (start, kid) = kids[slot];
                        let mut sub = Chunk::default();
                        build_node(part, offset + start, kid, &mut sub);
                        (slot, sub)
                    })
                    .collect::<Vec<_>>()
            },
            build_small,
        )
        .0
    } else {
        for (slot, part) in parts.iter_mut().enumerate().take(len) {
            if inner(slot) {
                let (start, kid) = kids[slot];
                node.child[slot] = build_node(std::mem::take(part), offset + start, kid, chunk);
            }
        }
        Vec::new()
    };
    chunk.nodes[index] = node;
    for (slot, sub) in subs {
        chunk.subs.push((index as u32, slot, sub));
    }
    index as u32
}

/// Decides whether `prims` (of extent `extent`, at binary depth `depth`)
/// is a leaf or splits, and if it splits, partitions it.
fn classify(prims: &mut [Prim], extent: Extent, depth: u32) -> Item {
    let n = prims.len();
    let bounds = extent.bounds.aabb();
    let leaf = Item {
        bounds,
        len: n,
        depth,
        cut: None,
    };
    if n <= ALWAYS_LEAF {
        return leaf;
    }
    let split = if depth < SAH_MAX_DEPTH {
        sah_split(prims, &extent)
    } else {
        None
    };
    let (mid, left, right) = match split {
        Some(Split::Bins { axis, bin }) => {
            // `bins(p)[axis] <= bin` on the one axis, without the clamps:
            // for `bin < BINS − 1` the same answer (see `BinMap::left_of`).
            let map = BinMap::new(&extent.cbounds);
            let edge = f32x4::splat((bin + 1) as f32);
            partition(prims, |p| map.left_of(p, edge, axis))
        }
        Some(Split::Leaf) if n <= MAX_LEAF => return leaf,
        // No useful SAH split (all centroids in one bin, or too deep):
        // object median along the widest centroid axis, ties by id.
        _ => {
            let cb = extent.cbounds.aabb();
            let e = cb.hi - cb.lo;
            let axis = if e.x >= e.y && e.x >= e.z {
                0
            } else if e.y >= e.z {
                1
            } else {
                2
            };
            let key = |p: &Prim| p.centroid().to_array()[axis];
            let order = |a: &Prim, b: &Prim| key(a).total_cmp(&key(b)).then(a.id().cmp(&b.id()));
            if n >= PARALLEL_SPLIT {
                prims.par_sort_unstable_by(order);
            } else {
                prims.sort_unstable_by(order);
            }
            let mid = n / 2;
            (mid, Extent::of(&prims[..mid]), Extent::of(&prims[mid..]))
        }
    };
    Item {
        bounds,
        len: n,
        depth,
        cut: Some(Cut { mid, left, right }),
    }
}

/// The SAH's verdict for a node.
enum Split {
    /// Split after bin `bin` along `axis`.
    Bins { axis: usize, bin: usize },
    /// Not splitting is cheaper.
    Leaf,
}

/// The bin mapping of a range, all three axes at once: bin
/// `trunc((c − lo) · BINS / (hi − lo))` of centroid `c`, clamped to
/// `[0, BINS − 1]` (NaN: 0; an axis of zero extent bins garbage that
/// [`sah_split`] skips). Binning and partition both use it, so they agree.
#[derive(Clone, Copy)]
struct BinMap {
    lo: f32x4,
    scale: f32x4,
}

impl BinMap {
    #[inline]
    fn new(cbounds: &Box4) -> BinMap {
        BinMap {
            lo: cbounds.lo,
            scale: f32x4::splat(BINS as f32) / (cbounds.hi - cbounds.lo),
        }
    }

    /// Whether `bins(p)[axis] <= b`, given `edge` = `b + 1` in every
    /// lane and `b < BINS − 1`: the scaled offset `v` is below `b + 1`, or
    /// NaN (bin 0). Below 0 the clamp gives bin 0, at least `b + 1` (≤
    /// `BINS − 1`) it gives a bin above `b`, and in between `trunc(v) ≤ b`.
    #[inline(always)]
    fn left_of(&self, p: &Prim, edge: f32x4, axis: usize) -> bool {
        let v = (p.centroid() - self.lo) * self.scale;
        (v.cmp_ge(edge).move_mask() >> axis) & 1 == 0
    }

    /// The bins of `p`'s centroid along x, y, z (lane 3: unused).
    /// Clamped as floats before the truncation (NaN to 0 by `max`'s
    /// rule), the same bins as truncating then clamping the integers, in
    /// fewer instructions (baseline x86-64 has no `pmaxsd`).
    #[inline(always)]
    fn bins(&self, p: &Prim) -> [i32; 4] {
        ((p.centroid() - self.lo) * self.scale)
            .max(f32x4::ZERO)
            .min(f32x4::splat((BINS - 1) as f32))
            .trunc_int()
            .to_array()
    }
}

/// The triangles' bounds and counts per bin, for the three axes.
#[derive(Clone, Copy)]
struct Bins {
    boxes: [[Box4; BINS]; 3],
    counts: [[u32; BINS]; 3],
}

impl Bins {
    const EMPTY: Bins = Bins {
        boxes: [[Box4::EMPTY; BINS]; 3],
        counts: [[0; BINS]; 3],
    };

    #[inline(always)]
    fn add(&mut self, map: &BinMap, p: &Prim) {
        let k = map.bins(p);
        for axis in 0..3 {
            let k = k[axis] as usize & (BINS - 1);
            self.boxes[axis][k].grow(p.lo(), p.hi);
            self.counts[axis][k] += 1;
        }
    }

    #[inline(always)]
    fn merge(&mut self, other: &Bins) {
        for axis in 0..3 {
            for k in 0..BINS {
                self.boxes[axis][k].merge(&other.boxes[axis][k]);
                self.counts[axis][k] += other.counts[axis][k];
            }
        }
    }

    /// Bins `prims` along the three axes at once.
    fn of(prims: &[Prim], cbounds: &Box4) -> Bins {
        let map = BinMap::new(cbounds);
        let seq = |ps: &[Prim]| {
            let mut bins = Bins::EMPTY;
            if ps.len() < PAIRED {
                for p in ps {
                    bins.add(&map, p);
                }
                return bins;
            }
            // Neighbouring triangles mostly fall in the same bins, so one
            // set of bins makes each update wait for the previous one's
            // store; two sets (even and odd triangles) halve that chain.
            // Min / max are exact, so the merged bins are the same.
            let mut odd = Bins::EMPTY;
            let mut pairs = ps.chunks_exact(2);
            for pair in &mut pairs {
                bins.add(&map, &pair[0]);
                odd.add(&map, &pair[1]);
            }
            for p in pairs.remainder() {
                bins.add(&map, p);
            }
            bins.merge(&odd);
            bins
        };
        if prims.len() >= PARALLEL_SPLIT {
            // Merged in chunk order, as `Extent::of`.
            let parts: Vec<Bins> = prims.par_chunks(CHUNK).map(seq).collect();
            parts.iter().fold(Bins::EMPTY, |mut a, b| {
                a.merge(b);
                a
            })
        } else {
            seq(prims)
        }
    }
}

/// Ranges of at least this many triangles bin into two sets of bins (see
/// [`Bins::of`]); below, merging them costs more than it saves.
const PAIRED: usize = 128;

/// Best binned-SAH split, `None` when the centroids cannot be separated.
/// Costs: traversal [`SAH_TRAVERSAL`], triangle 1 (relative to the
/// parent's area).
fn sah_split(prims: &[Prim], extent: &Extent) -> Option<Split> {
    let (cost, axis, bin) = if prims.len() <= SMALL {
        sah_small(prims, extent)
    } else {
        sah_binned(prims, extent)
    }?;
    let area = extent.bounds.aabb().half_area();
    // Leaf cost n vs split cost t + (A_l n_l + A_r n_r) / A.
    let leaf_cost = prims.len() as f32;
    if area > 0.0 && SAH_TRAVERSAL + cost / area >= leaf_cost {
        return Some(Split::Leaf);
    }
    Some(Split::Bins { axis, bin })
}

/// Ranges of at most this many triangles find their SAH split over the
/// bins they occupy rather than filling and sweeping all [`BINS`] bins
/// per axis: the same candidates (splits between non-empty bins), the same
/// costs, the same choice, hence the same tree. Nearly all classified
/// ranges are this small (4.1M triangles: 3.6M of 4.4M ranges hold at
/// most 8), and for them the fixed cost of 48 bins dominated the build.
const SMALL: usize = 16;

/// The best split of a range of at most [`SMALL`] triangles as
/// `(cost, axis, bin)`, as [`sah_binned`] would find it: for each axis,
/// only the occupied bins are filled, then the same two sweeps over them
/// with the same arithmetic (the boxes grown in another order: min and
/// max are exact, so they are the same up to the sign of a zero, which
/// no area or cost sees).
fn sah_small(prims: &[Prim], extent: &Extent) -> Option<(f32, usize, usize)> {
    let n = prims.len();
    let map = BinMap::new(&extent.cbounds);
    let mut keys = [[0i32; 4]; SMALL];
    for (k, p) in keys.iter_mut().zip(prims) {
        *k = map.bins(p);
    }
    let cbounds = &extent.cbounds.aabb();
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if !(cbounds.hi[axis] > cbounds.lo[axis]) {
            continue;
        }
        // Only the bins that hold a triangle are reset and filled (no
        // branch per triangle: a sort by bin mispredicted most of its
        // compares and took an eighth of the build).
        let mut boxes = [Box4::EMPTY; BINS];
        let mut counts = [0u32; BINS];
        let mut occupied = 0u32;
        for key in &keys[..n] {
            let k = key[axis] as usize & (BINS - 1);
            boxes[k] = Box4::EMPTY;
            counts[k] = 0;
            occupied |= 1 << k;
        }
        for (key, p) in keys.iter().zip(prims) {
            let k = key[axis] as usize & (BINS - 1);
            boxes[k].grow(p.lo(), p.hi);
            counts[k] += 1;
        }
        if occupied.count_ones() < 2 {
            continue;
        }
        // Right to left over the occupied bins: `right_cost[b]`, area ×
        // count of the bins after the occupied bin `b`.
        let mut right_cost = [0.0f32; BINS];
        let top = 31 - occupied.leading_zeros() as usize;
        let (mut acc, mut count) = (boxes[top], counts[top] as usize);
        let mut rest = occupied & !(1 << top);
        while rest != 0 {
            let b = 31 - rest.leading_zeros() as usize;
            rest &= !(1 << b);
            right_cost[b] = acc.half_area() * count as f32;
            acc.merge(&boxes[b]);
            count += counts[b] as usize;
        }
        let (mut acc, mut count) = (Box4::EMPTY, 0usize);
        let mut rest = occupied & !(1 << top);
        while rest != 0 {
            let b = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            acc.merge(&boxes[b]);
            count += counts[b] as usize;
            let cost = acc.half_area() * count as f32 + right_cost[b];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    best
}

/// The best split of a range as `(cost, axis, bin)`: its triangles binned
/// along the three axes, then for each axis a right-to-left sweep (area ×
/// count of the bins after each split) and a left-to-right one, the three
/// axes at once in the lanes of `f32x4` (the bins transposed: lane = axis).
/// Candidates are the splits after each non-empty bin but the last (a
/// split after an empty bin has the sides, hence the cost, of one before
/// it), tried by axis then bin, the first of equal costs kept.
fn sah_binned(prims: &[Prim], extent: &Extent) -> Option<(f32, usize, usize)> {
    let n = prims.len();
    let bins = Bins::of(prims, &extent.cbounds);
    // Per bin, lanes = axes: the box's bounds along x, y, z.
    let mut lo = [[f32x4::ZERO; 3]; BINS];
    let mut hi = [[f32x4::ZERO; 3]; BINS];
    for k in 0..BINS {
        let b = |axis: usize| bins.boxes[axis][k];
        let [x, y, z, _] = f32x4::transpose([b(0).lo, b(1).lo, b(2).lo, f32x4::ZERO]);
        lo[k] = [x, y, z];
        let [x, y, z, _] = f32x4::transpose([b(0).hi, b(1).hi, b(2).hi, f32x4::ZERO]);
        hi[k] = [x, y, z];
    }
    // Triangles in the bins up to and including `k`, per axis.
    let mut left = [[0u32; 3]; BINS];
    let mut sum = [0u32; 3];
    for (k, l) in left.iter_mut().enumerate() {
        for (total, counts) in sum.iter_mut().zip(&bins.counts) {
            *total += counts[k];
        }
        *l = sum;
    }
    let counts = |c: [u32; 3]| f32x4::new([c[0] as f32, c[1] as f32, c[2] as f32, 0.0]);
    // `Aabb::half_area` lane by lane: the same operations in the same order.
    let area = |lo: &[f32x4; 3], hi: &[f32x4; 3]| {
        let e = [0, 1, 2].map(|d| (hi[d] - lo[d]).max(f32x4::ZERO));
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    };
    let grow = |acc: &mut ([f32x4; 3], [f32x4; 3]), k: usize| {
        for d in 0..3 {
            acc.0[d] = lo[k][d].min(acc.0[d]);
            acc.1[d] = hi[k][d].max(acc.1[d]);
        }
    };
    let empty = (
        [f32x4::splat(f32::INFINITY); 3],
        [f32x4::splat(f32::NEG_INFINITY); 3],
    );
    // `right_cost[k]`: area × count of the bins after `k`.
    let mut right_cost = [f32x4::ZERO; BINS];
    let mut acc = empty;
    for k in (1..BINS).rev() {
        grow(&mut acc, k);
        let right = [0, 1, 2].map(|axis| n as u32 - left[k - 1][axis]);
        right_cost[k - 1] = area(&acc.0, &acc.1) * counts(right);
    }
    let mut cost = [[0.0f32; 4]; BINS];
    let mut acc = empty;
    for k in 0..BINS - 1 {
        grow(&mut acc, k);
        cost[k] = (area(&acc.0, &acc.1) * counts(left[k]) + right_cost[k]).to_array();
    }
    let cbounds = &extent.cbounds.aabb();
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if !(cbounds.hi[axis] > cbounds.lo[axis]) {
            continue;
        }
        for k in 0..BINS - 1 {
            if bins.counts[axis][k] != 0 && (left[k][axis] as usize) < n {
                let c = cost[k][axis];
                if best.is_none_or(|(b, _, _)| c < b) {
                    best = Some((c, axis, k));
                }
            }
        }
    }
    best
}

/// Partitions `prims`, those satisfying `left` first; returns their count
/// and the extents of both sides. Which order each side ends in does not
/// matter: binning and bounds do not see it, median splits sort, and
/// leaves are sorted by triangle index. Large ranges partition over
/// fixed chunks in parallel, the order depending only on the chunks;
/// others in place by swaps.
fn partition(prims: &mut [Prim], left: impl Fn(&Prim) -> bool + Sync) -> (usize, Extent, Extent) {
    if prims.len() < PARALLEL_SPLIT {
        return hoare(prims, &left);
    }
    // Each chunk partitions itself in place (in parallel); then the
    // right triangles that lie before `mid` swap with the left ones after
    // it, run by run in ascending order. This moved each chunk through two
    // vectors and back, allocating (and faulting in) twice the range per
    // level; the result still depends only on the fixed chunks.
    let n = prims.len();
    let parts: Vec<(usize, Extent, Extent)> = prims
        .par_chunks_mut(CHUNK)
        .map(|ps| hoare(ps, &left))
        .collect();
    let mid: usize = parts.iter().map(|p| p.0).sum();
    let (mut l, mut r) = (Extent::EMPTY, Extent::EMPTY);
    for p in &parts {
        l = l.merge(p.1);
        r = r.merge(p.2);
    }
    // Misplaced runs (start, end): right triangles before `mid`, left
    // ones after it; both hold the same number of triangles.
    let (mut wrong_r, mut wrong_l) = (Vec::new(), Vec::new());
    for (c, p) in parts.iter().enumerate() {
        let (s, e) = (c * CHUNK, (c * CHUNK + CHUNK).min(n));
        if s + p.0 < e.min(mid) {
            wrong_r.push((s + p.0, e.min(mid)));
        }
        if s.max(mid) < s + p.0 {
            wrong_l.push((s.max(mid), s + p.0));
        }
    }
    // Paired in order into swaps of at most `CHUNK` triangles.
    let mut swaps = Vec::new();
    let (mut a, mut b) = (wrong_r.into_iter(), wrong_l.into_iter());
    let (mut ra, mut rb) = (a.next(), b.next());
    while let (Some((a0, a1)), Some((b0, b1))) = (ra, rb) {
        let len = (a1 - a0).min(b1 - b0).min(CHUNK);
        swaps.push((a0, b0, len));
        ra = if a0 + len < a1 {
            Some((a0 + len, a1))
        } else {
            a.next()
        };
        rb = if b0 + len < b1 {
            Some((b0 + len, b1))
        } else {
            b.next()
        };
    }
    debug_assert!(ra.is_none() && rb.is_none());
    // Disjoint slices for the swaps: both sides' runs ascend.
    let (mut before, mut after) = prims.split_at_mut(mid);
    let (mut at_a, mut at_b) = (0, mid);
    let mut jobs = Vec::with_capacity(swaps.len());
    for (a0, b0, len) in swaps {
        let (x, tail) = std::mem::take(&mut before)
            .split_at_mut(a0 - at_a)
            .1
            .split_at_mut(len);
        let (y, tail_b) = std::mem::take(&mut after)
            .split_at_mut(b0 - at_b)
            .1
            .split_at_mut(len);
        (before, after) = (tail, tail_b);
        (at_a, at_b) = (a0 + len, b0 + len);
        jobs.push((x, y));
    }
    jobs.into_par_iter().for_each(|(x, y)| x.swap_with_slice(y));
    (mid, l, r)
}

/// Partitions `prims` in place by Hoare's scheme: only misplaced pairs
/// move (a swap per left triangle before); each triangle is tested and
/// bounded once. Returns the left count and the extents of both sides.
#[inline]
fn hoare(prims: &mut [Prim], left: &impl Fn(&Prim) -> bool) -> (usize, Extent, Extent) {
    let (mut l, mut r) = (Extent::EMPTY, Extent::EMPTY);
    let (mut i, mut j) = (0, prims.len());
    loop {
        while i < j && left(&prims[i]) {
            l.add(&prims[i]);
            i += 1;
        }
        while i < j && !left(&prims[j - 1]) {
            r.add(&prims[j - 1]);
            j -= 1;
        }
        if i == j {
            return (i, l, r);
        }
        // `prims[i]` goes right, `prims[j - 1]` left.
        r.add(&prims[i]);
        l.add(&prims[j - 1]);
        prims.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
}
