//! Edge adjacency of the shadow casters: vertices welded by position, each
//! edge with the faces that use it and the direction they traverse it.
//! Open boundaries and non-manifold edges are kept as they are; shadow
//! volumes count them with signed edge multiplicities.

use super::SceneGeometry;
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

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
    /// Triangle index in [`SceneGeometry`].
    pub face: u32,
    /// Index of the face in [`EdgeAdjacency::faces`].
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

/// Pieces of work for the parallel passes.
const PIECES: usize = 64;

impl EdgeAdjacency {
    /// The uses of edge `e`, in (face slot, edge of the face) order.
    #[inline]
    pub fn uses(&self, e: usize) -> &[EdgeUse] {
        &self.edge_uses[self.edge_offsets[e] as usize..self.edge_offsets[e + 1] as usize]
    }

    /// Builds adjacency over the faces `include` accepts. Welding happens
    /// per object, so objects never share edges.
    ///
    /// Linear passes and sorts, no hashing: the welding cells are grouped
    /// by one parallel sort of the used vertices, the edges by a counting
    /// sort on their lower vertex; both then are numbered in first-use
    /// order, which gives exactly the orders of one serial walk over the
    /// faces ([`EdgeAdjacency`]).
    pub fn build(geometry: &SceneGeometry, include: impl Fn(u32) -> bool) -> Self {
        let n_vertices = geometry.positions.len();
        let mut included = Vec::with_capacity(geometry.triangles.len());
        // Each vertex's object (the last included face's using it), to
        // weld per object with one key per vertex.
        let mut vertex_object = vec![u32::MAX; n_vertices];
        for (f, tri) in geometry.triangles.iter().enumerate() {
            let f = f as u32;
            if include(f) {
                included.push(f);
                let object = geometry.triangle_object[f as usize];
                for &v in tri {
                    vertex_object[v as usize] = object;
                }
            }
        }
        if included.len() >= (u32::MAX / 3) as usize {
            return Self::build_hashed(geometry, |f| included.binary_search(&f).is_ok());
        }
        let cell = weld_cell(&geometry.positions);
        // Welding classes: the used vertices sorted by (object, cell).
        let mut keys: Vec<(u32, [i64; 3], u32)> = vertex_object
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .filter(|(_, o)| **o != u32::MAX)
            .map(|(v, &o)| (o, cell_of(geometry.positions[v], cell), v as u32))
            .collect();
        keys.par_sort_unstable_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)));
        let mut class = vec![u32::MAX; n_vertices];
        let mut classes = 0u32;
        for (i, k) in keys.iter().enumerate() {
            if i > 0 && (keys[i - 1].0, keys[i - 1].1) != (k.0, k.1) {
                classes += 1;
            }
            class[k.2 as usize] = classes;
        }
        drop(keys);
        // Welded ids in first-corner-use order; faces collapsed by
        // welding are dropped (after their corners are numbered).
        let mut adj = EdgeAdjacency::default();
        let mut welded = vec![u32::MAX; classes as usize + 1];
        adj.faces.reserve_exact(included.len());
        adj.face_vertices.reserve_exact(included.len());
        for &f in &included {
            let object = geometry.triangle_object[f as usize];
            let mut shared = false;
            let corners = geometry.triangles[f as usize].map(|v| {
                shared |= vertex_object[v as usize] != object;
                let c = class[v as usize] as usize;
                if welded[c] == u32::MAX {
                    welded[c] = adj.positions.len() as u32;
                    adj.positions.push(geometry.positions[v as usize]);
                }
                welded[c]
            });
            if shared {
                // A vertex used by several objects' faces: weld per use.
                return Self::build_hashed(geometry, |f| included.binary_search(&f).is_ok());
            }
            if corners[0] == corners[1] || corners[1] == corners[2] || corners[0] == corners[2] {
                continue; // collapsed by welding: no area, no edges
            }
            adj.faces.push(f);
            adj.face_vertices.push(corners);
        }
        drop((welded, class, vertex_object, included));
        adj.build_edges(geometry);
        adj
    }

    /// Edges, their uses and closedness from `faces` and `face_vertices`.
    fn build_edges(&mut self, geometry: &SceneGeometry) {
        let n_welded = self.positions.len();
        let n_uses = self.face_vertices.len() * 3;
        // Counting sort of the uses (use index `3 slot + k`) on their lower
        // vertex, each entry `hi << 32 | use`.
        let mut start = vec![0u32; n_welded + 1];
        for &c in &self.face_vertices {
            for k in 0..3 {
                start[face_edge(c, k).0 as usize + 1] += 1;
            }
        }
        for i in 0..n_welded {
            start[i + 1] += start[i];
        }
        let mut cursor = start.clone();
        let mut bucket = vec![0u64; n_uses];
        for (slot, &c) in self.face_vertices.iter().enumerate() {
            for k in 0..3 {
                let (a, b, _) = face_edge(c, k);
                let at = &mut cursor[a as usize];
                bucket[*at as usize] = (b as u64) << 32 | (3 * slot + k) as u64;
                *at += 1;
            }
        }
        drop(cursor);
        // Each lower vertex's list sorted by (hi, use): an edge is a run
        // of equal `hi`, its first entry the edge's first use.
        let mut pieces = Vec::with_capacity(PIECES);
        let mut rest = &mut bucket[..];
        let mut done = 0usize;
        for p in 0..PIECES {
            let (v0, v1) = (n_welded * p / PIECES, n_welded * (p + 1) / PIECES);
            let (piece, tail) = rest.split_at_mut(start[v1] as usize - done);
            done = start[v1] as usize;
            rest = tail;
            pieces.push((v0, v1, piece));
        }
        let n_edges: usize = pieces
            .into_par_iter()
            .map(|(v0, v1, piece)| {
                let base = start[v0] as usize;
                let mut edges = 0;
                for v in v0..v1 {
                    let list = &mut piece[start[v] as usize - base..start[v + 1] as usize - base];
                    list.sort_unstable();
                    edges += list
                        .iter()
                        .enumerate()
                        .filter(|&(i, e)| i == 0 || list[i - 1] >> 32 != e >> 32)
                        .count();
                }
                edges
            })
            .sum();
        // Edges in first-use order, each with its uses in use order.
        self.edges.reserve_exact(n_edges);
        self.edge_offsets.reserve_exact(n_edges + 1);
        self.edge_uses.reserve_exact(n_uses);
        self.edge_offsets.push(0);
        let mut open_objects: Vec<bool> = Vec::new();
        for u in 0..n_uses {
            let (slot, k) = (u / 3, u % 3);
            let (a, b, _) = face_edge(self.face_vertices[slot], k);
            let list = &bucket[start[a as usize] as usize..start[a as usize + 1] as usize];
            let first = list.partition_point(|&e| e >> 32 < b as u64);
            if list[first] as u32 != u as u32 {
                continue; // not the edge's first use
            }
            self.edges.push(Edge { v: [a, b] });
            let mut sum = 0i32;
            for &e in list[first..].iter().take_while(|&&e| e >> 32 == b as u64) {
                let (s, k) = ((e as u32 / 3) as usize, (e as u32 % 3) as usize);
                let direction = face_edge(self.face_vertices[s], k).2;
                sum += direction as i32;
                self.edge_uses.push(EdgeUse {
                    face: self.faces[s],
                    slot: s as u32,
                    direction,
                });
            }
            self.edge_offsets.push(self.edge_uses.len() as u32);
            // An object is closed when every one of its edges is used as
            // often in one direction as in the other.
            if sum != 0 {
                let o = geometry.triangle_object[self.faces[slot] as usize] as usize;
                if open_objects.len() <= o {
                    open_objects.resize(o + 1, false);
                }
                open_objects[o] = true;
            }
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
                    face: f,
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
                open_objects.insert(geometry.triangle_object[u[0].face as usize]);
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
            if geometry.triangle_object[first.face as usize] != object {
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
                assert_eq!(adj.faces[u.slot as usize], u.face);
            }
        }
    }
}
