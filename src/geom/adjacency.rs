//! Edge adjacency of the shadow casters: vertices welded by position, each
//! edge with the faces that use it and the direction they traverse it.
//! Open boundaries and non-manifold edges are kept as they are; shadow
//! volumes count them with signed edge multiplicities.

use super::SceneGeometry;
use glam::Vec3;
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

/// An undirected edge between two welded vertices, `v[0] < v[1]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Edge {
    /// Welded vertex ids (indices into [`EdgeAdjacency::positions`]).
    pub v: [u32; 2],
    /// Every face using the edge.
    pub uses: Vec<EdgeUse>,
}

/// Welded vertices, edges and per-component closedness of a set of faces.
#[derive(Debug, Clone, Default)]
pub struct EdgeAdjacency {
    /// Welded vertex positions.
    pub positions: Vec<Vec3>,
    /// The faces included (triangle indices into [`SceneGeometry`]).
    pub faces: Vec<u32>,
    /// Each included face's welded corners, parallel to `faces`.
    pub face_vertices: Vec<[u32; 3]>,
    /// All edges.
    pub edges: Vec<Edge>,
    /// Per included face: is its object's surface a closed 2-cycle (every
    /// edge's directions sum to zero)?
    pub face_closed: Vec<bool>,
}

/// Relative welding tolerance: positions in the same cell of a grid of
/// side `WELD_TOLERANCE × scene diagonal` are one vertex.
pub const WELD_TOLERANCE: f32 = 1e-6;

impl EdgeAdjacency {
    /// Builds adjacency over the faces `include` accepts. Welding happens
    /// per object, so objects never share edges.
    pub fn build(geometry: &SceneGeometry, include: impl Fn(u32) -> bool) -> Self {
        let (lo, hi) = geometry.positions.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let diagonal = (hi - lo).length();
        let cell = if diagonal.is_finite() && diagonal > 0.0 {
            diagonal * WELD_TOLERANCE
        } else {
            f32::MIN_POSITIVE
        };
        let mut adj = EdgeAdjacency::default();
        let mut welded: FastMap<(u32, [i64; 3]), u32> = FastMap::default();
        let mut edge_index: FastMap<(u32, u32), u32> = FastMap::default();
        for (f, tri) in geometry.triangles.iter().enumerate() {
            let f = f as u32;
            if !include(f) {
                continue;
            }
            let object = geometry.triangle_object[f as usize];
            let corners = tri.map(|i| {
                let p = geometry.positions[i as usize];
                let key = (p / cell).round().as_i64vec3().to_array();
                *welded.entry((object, key)).or_insert_with(|| {
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
                let (a, b) = (corners[k], corners[(k + 1) % 3]);
                let (key, direction) = if a < b { ((a, b), 1) } else { ((b, a), -1) };
                let e = *edge_index.entry(key).or_insert_with(|| {
                    adj.edges.push(Edge {
                        v: [key.0, key.1],
                        uses: Vec::with_capacity(2),
                    });
                    (adj.edges.len() - 1) as u32
                });
                adj.edges[e as usize].uses.push(EdgeUse {
                    face: f,
                    slot: (adj.faces.len() - 1) as u32,
                    direction,
                });
            }
        }
        // An object is closed when every one of its edges is used as often
        // in one direction as in the other.
        let mut open_objects = std::collections::HashSet::new();
        for e in &adj.edges {
            let sum: i32 = e.uses.iter().map(|u| u.direction as i32).sum();
            if sum != 0 {
                open_objects.insert(geometry.triangle_object[e.uses[0].face as usize]);
            }
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
        for e in &self.edges {
            let Some(first) = e.uses.first() else {
                continue;
            };
            if geometry.triangle_object[first.face as usize] != object {
                continue;
            }
            let sum: i32 = e.uses.iter().map(|u| u.direction as i32).sum();
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
