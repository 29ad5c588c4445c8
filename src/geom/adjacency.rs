//! Edge adjacency of the shadow casters: vertices welded by position, each
//! edge with the faces that use it and the direction they traverse it.
//! Open boundaries and non-manifold edges are kept as they are; shadow
//! volumes count them with signed edge multiplicities.

use super::SceneGeometry;
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};

/// A multiply-rotate hasher for integer keys (the FxHash scheme): the
/// standard SipHash defends against adversarial keys we do not have, at
/// several times the cost. Iteration order is never used, so results do
/// not depend on it.
#[derive(Default)]
struct FastHasher(u64);

impl Hasher for FastHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u32(&mut self, v: u32) {
        self.write_u64(v as u64);
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<FastHasher>>;

/// One face's use of an edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EdgeUse {
    /// Index of the face in [`EdgeAdjacency::faces`] (its triangle is
    /// `faces[slot]`).
    pub slot: u32,
    /// +1 when the face traverses the edge from `v[0]` to `v[1]`, -1 for
    /// the reverse.
    pub direction: i8,
}

/// An undirected edge between two welded vertices, `v[0] < v[1]`; the
/// faces using edge `e` are [`EdgeAdjacency::uses`]`(e)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    /// Welded vertex ids (indices into [`EdgeAdjacency::positions`]).
    pub v: [u32; 2],
}

/// Welded vertices, edges and per-component closedness of a set of faces.
///
/// Orders (what every user iterating them sees, and the same for any
/// thread count): welded vertices by their first corner use (faces in
/// triangle order, corners in order), edges by their first use (face
/// slot, then the face's edge `k` from corner `k` to `k + 1`), and each
/// edge's uses by (slot, k).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EdgeAdjacency {
    /// Welded vertex positions.
    pub positions: Vec<Vec3>,
    /// The faces included (triangle indices into [`SceneGeometry`]).
    pub faces: Vec<u32>,
    /// Each included face's welded corners, parallel to `faces`.
    pub face_vertices: Vec<[u32; 3]>,
    /// All edges.
    pub edges: Vec<Edge>,
    /// Edge `e`'s uses are `edge_uses[edge_offsets[e]..edge_offsets[e + 1]]`
    /// (one more entry than `edges`; empty only in a default adjacency).
    pub edge_offsets: Vec<u32>,
    /// Every edge's uses, edge after edge.
    pub edge_uses: Vec<EdgeUse>,
    /// Per included face: is its object's surface a closed 2-cycle (every
    /// edge's directions sum to zero)?
    pub face_closed: Vec<bool>,
}

/// Relative welding tolerance: positions in the same cell of a grid of
/// side `WELD_TOLERANCE × scene diagonal` are one vertex.
pub const WELD_TOLERANCE: f32 = 1e-6;

/// The welding grid's cell side for `positions`.
fn weld_cell(positions: &[Vec3]) -> f32 {
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let diagonal = (hi - lo).length();
    if diagonal.is_finite() && diagonal > 0.0 {
        diagonal * WELD_TOLERANCE
    } else {
        f32::MIN_POSITIVE
    }
}

/// The welding grid cell of `p`.
#[inline]
fn cell_of(p: Vec3, cell: f32) -> [i64; 3] {
    (p / cell).round().as_i64vec3().to_array()
}

/// A hash of a welding key (object, cell): multiply-rotate mixing, as
/// [`FastHasher`], with a final avalanche.
#[inline]
fn key_hash((object, [x, y, z]): (u32, [i64; 3])) -> u64 {
    let mut h = FastHasher::default();
    for w in [object as u64, x as u64, y as u64, z as u64] {
        h.write_u64(w);
    }
    let h = h.finish();
    (h ^ (h >> 29)).wrapping_mul(0xbf58_476d_1ce4_e5b9) ^ (h >> 32)
}

/// Edge `k` of a face's welded corners: `(lo, hi, direction)`.
#[inline]
fn face_edge(corners: [u32; 3], k: usize) -> (u32, u32, i8) {
    let (a, b) = (corners[k], corners[(k + 1) % 3]);
    if a < b {
        (a, b, 1)
    } else {
        (b, a, -1)
    }
}

/// `s` cut into consecutive pieces of the given sizes (the rest dropped).
pub(super) fn split_sizes<T>(mut s: &mut [T], sizes: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    let mut out = Vec::new();
    for n in sizes {
        let (piece, rest) = std::mem::take(&mut s).split_at_mut(n);
        out.push(piece);
        s = rest;
    }
    out
}

/// Pieces of work for the parallel passes.
const PIECES: usize = 64;

impl EdgeAdjacency {
    /// Bytes its arrays hold (lengths, not capacities).
    pub fn memory_bytes(&self) -> u64 {
        use std::mem::size_of;
        (self.positions.len() * size_of::<Vec3>()
            + self.faces.len() * 4
            + self.face_vertices.len() * 12
            + self.edges.len() * size_of::<Edge>()
            + self.edge_offsets.len() * 4
            + self.edge_uses.len() * size_of::<EdgeUse>()
            + self.face_closed.len()) as u64
    }

    /// The uses of edge `e`, in (face slot, edge of the face) order.
    #[inline]
    pub fn uses(&self, e: usize) -> &[EdgeUse] {
        &self.edge_uses[self.edge_offsets[e] as usize..self.edge_offsets[e + 1] as usize]
    }

    /// Builds adjacency over the faces `include` accepts. Welding happens
    /// per object, so objects never share edges.
    ///
    /// Sorts and linear passes, mostly parallel, no hash maps: the welding
    /// cells are grouped by one parallel sort of the used vertices, the
    /// edges by a counting sort on their lower vertex; welded vertices and
    /// edges are then numbered by their first use, which gives exactly the
    /// orders of one serial walk over the faces ([`EdgeAdjacency`],
    /// [`EdgeAdjacency::build_hashed`]), for any thread count.
    pub fn build(geometry: &SceneGeometry, include: impl Fn(u32) -> bool) -> Self {
        let n_vertices = geometry.positions.len();
        // The included faces; per vertex its object (that of the last
        // included face using it) and its first corner use `3 i + k` (face
        // `included[i]`, corner `k`).
        let mut included = Vec::with_capacity(geometry.triangles.len());
        let mut vertex_object = vec![u32::MAX; n_vertices];
        let mut first_use = vec![u32::MAX; n_vertices];
        for (f, tri) in geometry.triangles.iter().enumerate() {
            let f = f as u32;
            if !include(f) {
                continue;
            }
            let corner = 3 * included.len();
            if corner + 3 > (u32::MAX / 2) as usize {
                return Self::build_hashed(geometry, include);
            }
            included.push(f);
            let object = geometry.triangle_object[f as usize];
            for (k, &v) in tri.iter().enumerate() {
                vertex_object[v as usize] = object;
                let first = &mut first_use[v as usize];
                if *first == u32::MAX {
                    *first = (corner + k) as u32;
                }
            }
        }
        let shared = included.par_iter().with_min_len(4096).any(|&f| {
            let object = geometry.triangle_object[f as usize];
            geometry.triangles[f as usize]
                .iter()
                .any(|&v| vertex_object[v as usize] != object)
        });
        if shared {
            // A vertex used by several objects' faces: weld per use.
            drop((vertex_object, first_use));
            return Self::build_hashed(geometry, |f| included.binary_search(&f).is_ok());
        }
        // Welding classes: the used vertices sorted by a hash of (object,
        // cell); a run of equal hashes holding several keys (a collision)
        // is sorted by the keys themselves.
        let cell = weld_cell(&geometry.positions);
        let key = |v: u32| {
            (
                vertex_object[v as usize],
                cell_of(geometry.positions[v as usize], cell),
            )
        };
        // Unused vertices sort last, under the largest hash.
        let mut keys: Vec<(u64, u32)> = (0..n_vertices as u32)
            .into_par_iter()
            .with_min_len(4096)
            .map(|v| match vertex_object[v as usize] {
                u32::MAX => (u64::MAX, v),
                _ => (key_hash(key(v)).min(u64::MAX - 1), v),
            })
            .collect();
        keys.par_sort_unstable();
        let used = keys.partition_point(|k| k.0 != u64::MAX);
        keys.truncate(used);
        // Per class, its first corner use; per vertex, its class.
        let mut class = vec![u32::MAX; n_vertices];
        let mut class_first: Vec<u32> = Vec::new();
        for run in keys.chunk_by_mut(|a, b| a.0 == b.0) {
            if run.len() > 1 && run.iter().any(|x| key(x.1) != key(run[0].1)) {
                run.sort_by_key(|x| key(x.1));
            }
            for (i, x) in run.iter().enumerate() {
                if i == 0 || (run.len() > 1 && key(x.1) != key(run[i - 1].1)) {
                    class_first.push(u32::MAX);
                }
                let c = class_first.len() - 1;
                class[x.1 as usize] = c as u32;
                class_first[c] = class_first[c].min(first_use[x.1 as usize]);
            }
        }
        drop((keys, first_use));
        // Welded ids: classes ranked by first use (a bit per corner use set
        // at each class's first); positions are those of the first uses.
        let n_corners = 3 * included.len();
        let mut firsts = vec![0u64; n_corners.div_ceil(64)];
        for &c in &class_first {
            firsts[c as usize / 64] |= 1 << (c % 64);
        }
        let mut rank_base = Vec::with_capacity(firsts.len());
        let mut count = 0u32;
        for &w in &firsts {
            rank_base.push(count);
            count += w.count_ones();
        }
        let rank = |c: u32| {
            let w = firsts[c as usize / 64] & ((1u64 << (c % 64)) - 1);
            rank_base[c as usize / 64] + w.count_ones()
        };
        let welded: Vec<u32> = class_first.par_iter().map(|&c| rank(c)).collect();
        // Per vertex its welded id (classes are numbered in hash order).
        let vertex_welded: Vec<u32> = class
            .par_iter()
            .with_min_len(4096)
            .map(|&c| welded.get(c as usize).copied().unwrap_or(u32::MAX))
            .collect();
        drop((welded, class));
        let mut adj = EdgeAdjacency {
            positions: Vec::with_capacity(count as usize),
            ..Default::default()
        };
        for (i, &w) in firsts.iter().enumerate() {
            let mut bits = w;
            while bits != 0 {
                let c = i * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let v = geometry.triangles[included[c / 3] as usize][c % 3];
                adj.positions.push(geometry.positions[v as usize]);
            }
        }
        drop((firsts, rank_base, class_first));
        // Faces collapsed by welding are dropped (after their corners are
        // numbered).
        (adj.faces, adj.face_vertices) = included
            .par_iter()
            .with_min_len(4096)
            .filter_map(|&f| {
                let c = geometry.triangles[f as usize].map(|v| vertex_welded[v as usize]);
                let collapsed = c[0] == c[1] || c[1] == c[2] || c[0] == c[2];
                (!collapsed).then_some((f, c))
            })
            .unzip();
        drop((vertex_welded, vertex_object, included));
        adj.build_edges(geometry);
        adj
    }

    /// Edges, their uses and closedness from `faces` and `face_vertices`.
    fn build_edges(&mut self, geometry: &SceneGeometry) {
        let n_welded = self.positions.len();
        let n_uses = self.face_vertices.len() * 3;
        let fv = &self.face_vertices;
        // Counting sort of the uses (use index `3 slot + k`) on their lower
        // vertex, each entry `hi << 32 | use << 1 | (direction < 0)`.
        let mut start = vec![0u32; n_welded + 1];
        for &c in fv {
            for k in 0..3 {
                start[face_edge(c, k).0 as usize + 1] += 1;
            }
        }
        for i in 0..n_welded {
            start[i + 1] += start[i];
        }
        let mut cursor = start.clone();
        let mut bucket = vec![0u64; n_uses];
        for (slot, &c) in fv.iter().enumerate() {
            for k in 0..3 {
                let (a, b, d) = face_edge(c, k);
                let at = &mut cursor[a as usize];
                bucket[*at as usize] =
                    (b as u64) << 32 | ((3 * slot + k) as u64) << 1 | (d < 0) as u64;
                *at += 1;
            }
        }
        drop(cursor);
        // Each lower vertex's list sorted by (hi, use): an edge is a run
        // of equal `hi`, its first entry the edge's first use, marked in
        // `heads`.
        let heads: Vec<AtomicU64> = (0..n_uses.div_ceil(64))
            .map(|_| AtomicU64::new(0))
            .collect();
        // Per head its edge's use count (saturated: 255 means "count").
        let head_uses: Vec<AtomicU8> = (0..n_uses).map(|_| AtomicU8::new(0)).collect();
        let sizes = (0..PIECES).map(|p| {
            let (v0, v1) = (n_welded * p / PIECES, n_welded * (p + 1) / PIECES);
            (start[v1] - start[v0]) as usize
        });
        split_sizes(&mut bucket, sizes)
            .into_par_iter()
            .enumerate()
            .for_each(|(p, piece)| {
                let (v0, v1) = (n_welded * p / PIECES, n_welded * (p + 1) / PIECES);
                let base = start[v0] as usize;
                for v in v0..v1 {
                    let list = &mut piece[start[v] as usize - base..start[v + 1] as usize - base];
                    list.sort_unstable();
                    for run in list.chunk_by(|x, y| x >> 32 == y >> 32) {
                        let u = (run[0] as u32 >> 1) as usize;
                        heads[u / 64].fetch_or(1 << (u % 64), Ordering::Relaxed);
                        head_uses[u].store(run.len().min(255) as u8, Ordering::Relaxed);
                    }
                }
            });
        let heads: Vec<u64> = heads.into_iter().map(AtomicU64::into_inner).collect();
        let head_uses: Vec<u8> = head_uses.into_iter().map(AtomicU8::into_inner).collect();
        // The uses of the edge whose first use is `u`.
        let group = |u: usize| {
            let (a, b, _) = face_edge(fv[u / 3], u % 3);
            let list = &bucket[start[a as usize] as usize..start[a as usize + 1] as usize];
            let first = list.partition_point(|&e| e >> 32 < b as u64);
            let len = list[first..]
                .iter()
                .take_while(|&&e| e >> 32 == b as u64)
                .count();
            ([a, b], &list[first..first + len])
        };
        let each_head = |words: &[u64], w0: usize, mut f: Box<dyn FnMut(usize) + '_>| {
            for (i, &w) in words.iter().enumerate() {
                let mut bits = w;
                while bits != 0 {
                    f((w0 + i) * 64 + bits.trailing_zeros() as usize);
                    bits &= bits - 1;
                }
            }
        };
        // Edges in first-use order, each with its uses in use order: chunks
        // of use indices counted, then written in parallel.
        const WORDS: usize = 1024;
        let counts: Vec<(usize, usize)> = heads
            .par_chunks(WORDS)
            .enumerate()
            .map(|(chunk, words)| {
                let (mut edges, mut uses) = (0, 0);
                each_head(
                    words,
                    chunk * WORDS,
                    Box::new(|u| {
                        edges += 1;
                        uses += match head_uses[u] {
                            255 => group(u).1.len(),
                            n => n as usize,
                        };
                    }),
                );
                (edges, uses)
            })
            .collect();
        let n_edges: usize = counts.iter().map(|c| c.0).sum();
        let mut edges = vec![Edge { v: [0, 0] }; n_edges];
        let mut offsets = vec![0u32; n_edges + 1];
        let mut uses = vec![
            EdgeUse {
                slot: 0,
                direction: 0
            };
            n_uses
        ];
        let mut use_base = Vec::with_capacity(counts.len());
        let mut total = 0;
        for c in &counts {
            use_base.push(total);
            total += c.1;
        }
        let edge_pieces = split_sizes(&mut edges, counts.iter().map(|c| c.0));
        let offset_pieces = split_sizes(&mut offsets[1..], counts.iter().map(|c| c.0));
        let use_pieces = split_sizes(&mut uses, counts.iter().map(|c| c.1));
        let open: Vec<u32> = heads
            .par_chunks(WORDS)
            .enumerate()
            .zip(edge_pieces)
            .zip(offset_pieces)
            .zip(use_pieces)
            .zip(use_base)
            .flat_map_iter(|(((((chunk, words), edges), offsets), uses), base)| {
                let mut open = Vec::new();
                let (mut e, mut n) = (0, 0);
                each_head(
                    words,
                    chunk * WORDS,
                    Box::new(|u| {
                        let (v, list) = group(u);
                        edges[e] = Edge { v };
                        let mut sum = 0i32;
                        for &x in list {
                            let s = (x as u32 >> 1) / 3;
                            let direction = if x & 1 == 0 { 1 } else { -1 };
                            sum += direction as i32;
                            uses[n] = EdgeUse { slot: s, direction };
                            n += 1;
                        }
                        offsets[e] = (base + n) as u32;
                        e += 1;
                        // An object is closed when every one of its edges
                        // is used as often in one direction as in the other.
                        if sum != 0 {
                            open.push(geometry.triangle_object[self.faces[u / 3] as usize]);
                        }
                    }),
                );
                open
            })
            .collect();
        (self.edges, self.edge_offsets, self.edge_uses) = (edges, offsets, uses);
        let mut open_objects: Vec<bool> = Vec::new();
        for o in open {
            if open_objects.len() <= o as usize {
                open_objects.resize(o as usize + 1, false);
            }
            open_objects[o as usize] = true;
        }
        self.face_closed = self
            .faces
            .par_iter()
            .with_min_len(4096)
            .map(|&f| {
                let o = geometry.triangle_object[f as usize] as usize;
                !open_objects.get(o).copied().unwrap_or(false)
            })
            .collect();
    }

    /// [`EdgeAdjacency::build`] by one serial walk over the faces with
    /// hash maps: welding per corner use, so it also serves geometry whose
    /// vertices several objects share (and is the reference the unit tests
    /// compare the sorting build against).
    pub fn build_hashed(geometry: &SceneGeometry, include: impl Fn(u32) -> bool) -> Self {
        let cell = weld_cell(&geometry.positions);
        let mut adj = EdgeAdjacency::default();
        let mut welded: FastMap<(u32, [i64; 3]), u32> = FastMap::default();
        let mut edge_index: FastMap<(u32, u32), u32> = FastMap::default();
        let mut uses: Vec<Vec<EdgeUse>> = Vec::new();
        for (f, tri) in geometry.triangles.iter().enumerate() {
            let f = f as u32;
            if !include(f) {
                continue;
            }
            let object = geometry.triangle_object[f as usize];
            let corners = tri.map(|i| {
                let p = geometry.positions[i as usize];
                *welded.entry((object, cell_of(p, cell))).or_insert_with(|| {
                    adj.positions.push(p);
                    (adj.positions.len() - 1) as u32
                })
            });
            if corners[0] == corners[1] || corners[1] == corners[2] || corners[0] == corners[2] {
                continue; // collapsed by welding: no area, no edges
            }
            adj.faces.push(f);
            adj.face_vertices.push(corners);
            for k in 0..3 {
                let (a, b, direction) = face_edge(corners, k);
                let e = *edge_index.entry((a, b)).or_insert_with(|| {
                    adj.edges.push(Edge { v: [a, b] });
                    uses.push(Vec::with_capacity(2));
                    (adj.edges.len() - 1) as u32
                });
                uses[e as usize].push(EdgeUse {
                    slot: (adj.faces.len() - 1) as u32,
                    direction,
                });
            }
        }
        let mut open_objects = std::collections::HashSet::new();
        adj.edge_offsets.push(0);
        for u in uses {
            let sum: i32 = u.iter().map(|u| u.direction as i32).sum();
            if sum != 0 {
                let f = adj.faces[u[0].slot as usize];
                open_objects.insert(geometry.triangle_object[f as usize]);
            }
            adj.edge_uses.extend(u);
            adj.edge_offsets.push(adj.edge_uses.len() as u32);
        }
        adj.face_closed = adj
            .faces
            .iter()
            .map(|&f| !open_objects.contains(&geometry.triangle_object[f as usize]))
            .collect();
        adj
    }

    /// The boundary of object `object`'s surface as closed loops of
    /// welded vertices, each in the direction its faces traverse it: an
    /// edge whose uses' directions sum to `s ≠ 0` appears `|s|` times,
    /// from `v[0]` to `v[1]` where `s > 0`. The boundary of a 2-chain is a
    /// 1-cycle (every vertex has as many boundary edges out as in), so
    /// the walk always closes; any surface spanning the loops with the
    /// reverse orientation (a fan per loop: `(v0, v[i+1], v[i])`) closes
    /// the object into a 2-cycle. Empty for a closed object. Loops and
    /// their vertices come in edge order: the same for the same input.
    pub fn boundary_loops(&self, geometry: &SceneGeometry, object: u32) -> Vec<Vec<u32>> {
        let mut out_edges: FastMap<u32, Vec<u32>> = FastMap::default();
        let mut starts = Vec::new();
        for (i, e) in self.edges.iter().enumerate() {
            let uses = self.uses(i);
            let Some(first) = uses.first() else {
                continue;
            };
            if geometry.triangle_object[self.faces[first.slot as usize] as usize] != object {
                continue;
            }
            let sum: i32 = uses.iter().map(|u| u.direction as i32).sum();
            let (a, b) = if sum > 0 {
                (e.v[0], e.v[1])
            } else {
                (e.v[1], e.v[0])
            };
            for _ in 0..sum.unsigned_abs() {
                out_edges.entry(a).or_default().push(b);
                starts.push(a);
            }
        }
        // Walked from the end of each vertex's list, so each edge once.
        for list in out_edges.values_mut() {
            list.reverse();
        }
        let mut loops = Vec::new();
        for &start in &starts {
            let mut walk = Vec::new();
            let mut v = start;
            while let Some(next) = out_edges.get_mut(&v).and_then(|l| l.pop()) {
                walk.push(v);
                v = next;
                if v == start {
                    break;
                }
            }
            if !walk.is_empty() {
                loops.push(walk);
            }
        }
        loops
    }
}

/// Per object (`0..objects`): is its surface closed, as
/// [`EdgeAdjacency::face_closed`] says of its faces, and has it a face
/// welding does not collapse? The same answer as the adjacency over all
/// triangles (welded per object at the same cells, collapsed faces
/// dropped, every edge's directions summing to zero), computed without
/// it: per object, its vertices welded into classes by a table of their
/// welding cells, and its edge uses counting-sorted on their lower class
/// (as [`EdgeAdjacency::build`] does), each list then checked for
/// balanced directions. Every render needs closedness (the G-buffer's
/// back faces, enclosed lights); the adjacency itself only techniques
/// that walk edges, so it is built when first asked for
/// ([`SceneGeometry::adjacency`]). The transient memory is one object's:
/// 4 bytes per edge use, about 40 per vertex.
pub fn closed_objects(geometry: &SceneGeometry, objects: usize) -> Vec<bool> {
    // Each object's triangles as runs of `triangle_object` (one run per
    // object for concatenated meshes; any order is accepted).
    let mut runs: Vec<Vec<std::ops::Range<usize>>> = vec![Vec::new(); objects];
    let mut start = 0;
    for run in geometry.triangle_object.chunk_by(|a, b| a == b) {
        if let Some(r) = runs.get_mut(run[0] as usize) {
            r.push(start..start + run.len());
        }
        start += run.len();
    }
    let cell = weld_cell(&geometry.positions);
    runs.into_par_iter()
        .map(|ranges| surface_closed(geometry, &ranges, cell))
        .collect()
}

/// Whether the triangles in `ranges` (one object's) form a closed surface
/// with at least one face, welded at `cell` ([`closed_objects`]).
fn surface_closed(geometry: &SceneGeometry, ranges: &[std::ops::Range<usize>], cell: f32) -> bool {
    let tris = || ranges.iter().flat_map(|r| &geometry.triangles[r.clone()]);
    let Some((lo, hi)) = tris().flatten().fold(None, |acc: Option<(u32, u32)>, &v| {
        Some(acc.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
    }) else {
        return false;
    };
    // The used vertices (ids `lo..=hi`, contiguous for one object's mesh)
    // welded into classes of equal cells, numbered in id order, through an
    // open-addressing table of cells (linear probing, at most half full):
    // one probe or two per vertex where sorting the cells' hashes cost a
    // third of this function.
    let span = (hi - lo) as usize + 1;
    let mut class = vec![u32::MAX; span];
    for &v in tris().flatten() {
        class[(v - lo) as usize] = 0;
    }
    let used = class.iter().filter(|&&c| c == 0).count();
    let mask = (2 * used).next_power_of_two().max(16) - 1;
    let mut slots = vec![u32::MAX; mask + 1];
    let mut class_cells: Vec<[i64; 3]> = Vec::with_capacity(used);
    for (i, c) in class.iter_mut().enumerate() {
        if *c == u32::MAX {
            continue;
        }
        let p = cell_of(geometry.positions[lo as usize + i], cell);
        let mut h = key_hash((0, p)) as usize & mask;
        *c = loop {
            match slots[h] {
                u32::MAX => {
                    slots[h] = class_cells.len() as u32;
                    class_cells.push(p);
                    break slots[h];
                }
                k if class_cells[k as usize] == p => break k,
                _ => h = (h + 1) & mask,
            }
        };
    }
    let classes = class_cells.len() as u32;
    drop((slots, class_cells));
    let corners = |t: &[u32; 3]| t.map(|v| class[(v - lo) as usize]);
    let collapsed = |c: [u32; 3]| c[0] == c[1] || c[1] == c[2] || c[0] == c[2];
    // The edge uses by a counting sort on their lower class, each entry
    // `hi << 1 | reversed`; an edge is a run of equal `hi` in its lower
    // class's list, balanced when as many uses are reversed as not.
    // Faces collapsed by welding have no edges.
    let n = classes as usize;
    let mut start = vec![0u32; n + 1];
    let mut faces = 0usize;
    for t in tris() {
        let c = corners(t);
        if collapsed(c) {
            continue;
        }
        faces += 1;
        for k in 0..3 {
            start[face_edge(c, k).0 as usize + 1] += 1;
        }
    }
    if faces == 0 {
        return false;
    }
    if classes >= 1 << 31 || 3 * faces >= u32::MAX as usize {
        // Too many for the packed entries (never for a mesh that fits in
        // memory): the adjacency answers instead.
        let adj = EdgeAdjacency::build_hashed(geometry, |f| {
            ranges.iter().any(|r| r.contains(&(f as usize)))
        });
        return !adj.faces.is_empty() && adj.face_closed.iter().all(|&c| c);
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut cursor = start.clone();
    let mut bucket = vec![0u32; 3 * faces];
    for t in tris() {
        let c = corners(t);
        if collapsed(c) {
            continue;
        }
        for k in 0..3 {
            let (a, b, d) = face_edge(c, k);
            let at = &mut cursor[a as usize];
            bucket[*at as usize] = b << 1 | (d < 0) as u32;
            *at += 1;
        }
    }
    drop((cursor, class));
    // Each lower class's uses summed per upper class (+1 forward, −1
    // reversed) in a scratch array, the classes touched checked and left
    // at zero: no sort of the lists.
    let mut balance = vec![0i32; n];
    let mut touched = Vec::new();
    (0..n).all(|a| {
        for &x in &bucket[start[a] as usize..start[a + 1] as usize] {
            let b = (x >> 1) as usize;
            touched.push(b);
            balance[b] += if x & 1 == 1 { -1 } else { 1 };
        }
        let balanced = touched.iter().all(|&b| balance[b] == 0);
        for b in touched.drain(..) {
            balance[b] = 0;
        }
        balanced
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rng(state: &mut u64) -> u32 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 33) as u32
    }

    /// Objects of random triangles over few, often coincident, positions
    /// (so welding merges vertices, collapses faces and makes non-manifold
    /// and open edges); `shared`: objects index each other's vertices.
    fn geometry(seed: u64, shared: bool) -> SceneGeometry {
        let mut s = seed;
        let mut g = SceneGeometry::default();
        let mut objects = Vec::new();
        for o in 0..4u32 {
            let base = g.positions.len() as u32;
            let n = 3 + rng(&mut s) % 40;
            for _ in 0..n {
                let q = |s: &mut u64| (rng(s) % 5) as f32 * 0.25;
                g.positions.push(Vec3::new(q(&mut s), q(&mut s), q(&mut s)));
            }
            for _ in 0..rng(&mut s) % 120 {
                let range = if shared { base + n } else { n };
                let off = if shared { 0 } else { base };
                g.triangles.push([0; 3].map(|_| off + rng(&mut s) % range));
                objects.push(o);
            }
        }
        g.triangle_object = objects.into();
        g
    }

    #[test]
    fn sorting_build_equals_the_serial_walk() {
        for seed in 0..200 {
            for shared in [false, true] {
                let g = geometry(seed, shared);
                for modulus in [1, 3] {
                    let include = |f: u32| f % modulus != 1;
                    let fast = EdgeAdjacency::build(&g, include);
                    let reference = EdgeAdjacency::build_hashed(&g, include);
                    assert_eq!(fast, reference, "seed {seed} shared {shared}");
                }
            }
        }
    }

    #[test]
    fn closedness_is_the_adjacency_s() {
        for seed in 0..300 {
            for shared in [false, true] {
                let g = geometry(seed, shared);
                let adj = EdgeAdjacency::build(&g, |_| true);
                let mut closed = [true; 4];
                let mut faces = [false; 4];
                for (slot, &f) in adj.faces.iter().enumerate() {
                    let o = g.triangle_object[f as usize] as usize;
                    faces[o] = true;
                    closed[o] &= adj.face_closed[slot];
                }
                let expected: Vec<bool> = (0..4).map(|o| closed[o] && faces[o]).collect();
                assert_eq!(
                    closed_objects(&g, 4),
                    expected,
                    "seed {seed} shared {shared}"
                );
            }
        }
        // The random objects are mostly open; a closed one must be seen.
        let mut g = SceneGeometry::default();
        let corners = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        g.positions = corners.iter().map(|&c| Vec3::from_array(c)).collect();
        g.triangles = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        g.triangle_object = vec![0; 4].into();
        assert_eq!(closed_objects(&g, 1), vec![true]);
        // Each face with its own copies of the corners: welded, closed.
        let mut welded = SceneGeometry::default();
        welded.positions = g
            .triangles
            .iter()
            .flatten()
            .map(|&i| g.positions[i as usize])
            .collect();
        welded.triangles = (0..4u32).map(|f| [3 * f, 3 * f + 1, 3 * f + 2]).collect();
        welded.triangle_object = vec![0; 4].into();
        assert_eq!(closed_objects(&welded, 1), vec![true]);
        // One face flipped: its edges run the same way as their neighbours'.
        let mut flipped = g.clone();
        flipped.triangles[3] = [1, 3, 2];
        assert_eq!(closed_objects(&flipped, 1), vec![false]);
        g.triangles.pop();
        g.triangle_object = vec![0; 3].into();
        assert_eq!(closed_objects(&g, 1), vec![false]);
    }

    #[test]
    fn uses_are_the_edge_slices() {
        let g = geometry(7, false);
        let adj = EdgeAdjacency::build(&g, |_| true);
        assert_eq!(adj.edge_offsets.len(), adj.edges.len() + 1);
        let total: usize = (0..adj.edges.len()).map(|e| adj.uses(e).len()).sum();
        assert_eq!(total, 3 * adj.faces.len());
        for (e, edge) in adj.edges.iter().enumerate() {
            for u in adj.uses(e) {
                let c = adj.face_vertices[u.slot as usize];
                assert!(c.contains(&edge.v[0]) && c.contains(&edge.v[1]));
            }
        }
    }
}
