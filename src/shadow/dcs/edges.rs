//! The edges depth complexity sampling projects, and the sign each one
//! gives the counters of a receiver.
//!
//! Write `D(x)` for the number of occluders between the receiver `p` and
//! a light point `x` — exactly what the shadow-volume stencil counts for
//! `x` (closed casters: lit faces crossed; open casters, Bergeron: every
//! face crossed). Moving `x` from the centre `O` to a sample `s`, `D`
//! changes only when the segment `p → x` sweeps over an edge, and then by
//!
//! ```text
//! ΔD = side(O) · μ_e(p),   μ_e(p) = Σ_faces d_f · h_f(p)
//! ```
//!
//! with `side(O)` the side of the plane `(p, v0, v1)` the centre is on,
//! `d_f = ±1` the direction the face runs along `v0 → v1`, and `h_f(p)`
//! the shadow-volume weight of the face *as seen from `p`* (closed: 1 when
//! `p` is in front, else 0; open: ±1 by facing) — the multiplicity
//! [`crate::shadow::kit::volumes::side_quad`] gives with the light
//! point replaced by `p`. It is non-zero only for silhouettes from `p`
//! (derivation in docs/algorithms/dcs.md).
//!
//! Everything is evaluated at the reference's shadow-ray origin
//! `p' = p + ε n_g`, so receivers on an occluder's own surface see its
//! faces from the same side as the reference's rays. The stencil decided
//! `D(O)` at the rasterized `p`; where a shadow-volume quad's plane passes
//! between `p` and `p'` (the half-wedge the rasterizer found `p` in says
//! which side the stencil took) the constant is moved across that quad.

pub use super::options::SilhouetteMode;
use crate::geom::silhouette::{area_silhouettes, sphere_silhouettes};
use crate::geom::EdgeAdjacency;
use crate::shadow::kit::volumes::side_quad;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Adjacency edges per parallel task of [`CandidateEdges::build`].
const CANDIDATE_CHUNK: usize = 4096;

/// One face next to a candidate edge.
#[derive(Debug, Clone, Copy)]
struct EdgeFace {
    /// Unnormalised normal from the winding.
    normal: DVec3,
    /// A vertex of the face.
    point: DVec3,
    /// +1 when the face runs `v0 → v1`, −1 for `v1 → v0`.
    direction: i8,
    /// Part of a closed caster (else open: Bergeron's two-sided rule).
    closed: bool,
}

/// One edge the technique projects.
#[derive(Debug, Clone, Copy)]
pub struct CandidateEdge {
    /// First welded vertex (`Edge::v[0]`).
    pub v0: DVec3,
    /// Second welded vertex.
    pub v1: DVec3,
    /// The shadow-volume quad from the centre: +1 when it runs
    /// `v0 → v1`, −1 when `v1 → v0`, 0 when the centre's volume has no
    /// quad on this edge.
    pub quad_sign: i8,
    /// The quad's copies (its multiplicity from the centre); 1 otherwise.
    pub quad_weight: u32,
    faces: (u32, u32),
}

/// The shape silhouettes are found against.
#[derive(Debug, Clone, Copy)]
pub enum LightShapeForSilhouettes<'a> {
    /// A convex polygon given by its corners.
    Polygon(&'a [Vec3]),
    /// A sphere.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius.
        radius: f64,
    },
}

/// Every candidate edge of one light, with its faces.
#[derive(Debug, Clone, Default)]
pub struct CandidateEdges {
    /// The edges, in adjacency order.
    pub edges: Vec<CandidateEdge>,
    faces: Vec<EdgeFace>,
}

impl CandidateEdges {
    /// The edges of `adj` that are silhouettes from the centre (`lit`:
    /// faces facing it) and, with [`SilhouetteMode::WholeLight`], those
    /// that are silhouettes from some point of `light`.
    pub fn build(
        adj: &EdgeAdjacency,
        lit: &[bool],
        mode: SilhouetteMode,
        light: LightShapeForSilhouettes,
    ) -> CandidateEdges {
        let whole = match mode {
            SilhouetteMode::Centre => None,
            SilhouetteMode::WholeLight => Some(match light {
                LightShapeForSilhouettes::Polygon(corners) => area_silhouettes(adj, corners),
                LightShapeForSilhouettes::Sphere { center, radius } => {
                    sphere_silhouettes(adj, center, radius)
                }
            }),
        };
        // Chunks of edges in parallel, then joined in order (face ranges
        // moved by the faces before): the same lists as one serial walk.
        let chunks: Vec<CandidateEdges> = adj
            .edges
            .par_chunks(CANDIDATE_CHUNK)
            .enumerate()
            .map(|(chunk, edges)| {
                let mut out = CandidateEdges::default();
                for (k, e) in edges.iter().enumerate() {
                    let i = chunk * CANDIDATE_CHUNK + k;
                    let quad = side_quad(adj, lit, i);
                    if quad.is_none() && !whole.as_ref().is_some_and(|w| w[i]) {
                        continue;
                    }
                    let (quad_sign, quad_weight) = match quad {
                        // side_quad orders [a, b] so that the quad faces out.
                        Some([a, _, m]) => (if a == e.v[0] { 1 } else { -1 }, m),
                        None => (0, 1),
                    };
                    let first = out.faces.len() as u32;
                    for u in adj.uses(i) {
                        let [a, b, c] = adj.face_vertices[u.slot as usize]
                            .map(|v| adj.positions[v as usize].as_dvec3());
                        out.faces.push(EdgeFace {
                            normal: (b - a).cross(c - a),
                            point: a,
                            direction: u.direction,
                            closed: adj.face_closed[u.slot as usize],
                        });
                    }
                    out.edges.push(CandidateEdge {
                        v0: adj.positions[e.v[0] as usize].as_dvec3(),
                        v1: adj.positions[e.v[1] as usize].as_dvec3(),
                        quad_sign,
                        quad_weight,
                        faces: (first, out.faces.len() as u32),
                    });
                }
                out
            })
            .collect();
        let mut out = CandidateEdges::default();
        out.edges
            .reserve(chunks.iter().map(|c| c.edges.len()).sum::<usize>());
        out.faces
            .reserve(chunks.iter().map(|c| c.faces.len()).sum::<usize>());
        for chunk in chunks {
            let base = out.faces.len() as u32;
            out.faces.extend(chunk.faces);
            out.edges.extend(chunk.edges.into_iter().map(|mut e| {
                e.faces = (e.faces.0 + base, e.faces.1 + base);
                e
            }));
        }
        out
    }

    /// For a manifold edge whose two faces run it in opposite directions:
    /// their unit normals and offsets `(n, n · point)`. `μ_e(p)` is then
    /// non-zero exactly when `p` is strictly in front of one face and not
    /// of the other (closed or open faces alike), so a receiver in front of
    /// both or behind both gets nothing from the edge. `None` otherwise.
    pub fn dihedral(&self, edge: &CandidateEdge) -> Option<[(DVec3, f64); 2]> {
        let faces = &self.faces[edge.faces.0 as usize..edge.faces.1 as usize];
        let [a, b] = faces else {
            return None;
        };
        if a.direction == b.direction {
            return None;
        }
        let plane = |f: &EdgeFace| {
            let len = f.normal.length();
            (len > 0.0 && len.is_finite()).then(|| {
                let n = f.normal / len;
                (n, n.dot(f.point))
            })
        };
        Some([plane(a)?, plane(b)?])
    }

    /// The faces of `edge` as `(normal, point, [weight behind, weight in
    /// front])`: [`CandidateEdges::multiplicity_from`] sums, per face, the
    /// weight for the side `normal · (p − point) > 0` says.
    pub fn face_terms(&self, edge: &CandidateEdge) -> impl Iterator<Item = FaceTerm> + '_ {
        self.faces[edge.faces.0 as usize..edge.faces.1 as usize]
            .iter()
            .map(|f| FaceTerm {
                normal: f.normal,
                point: f.point,
                weights: [face_weight(f, false), face_weight(f, true)],
            })
    }

    /// `μ_e(p)`: the edge's shadow-volume multiplicity with the light
    /// point at `p` (0 unless the edge is a silhouette from `p`).
    #[inline]
    pub fn multiplicity_from(&self, edge: &CandidateEdge, p: DVec3) -> i32 {
        self.faces[edge.faces.0 as usize..edge.faces.1 as usize]
            .iter()
            .map(|f| face_weight(f, f.normal.dot(p - f.point) > 0.0))
            .sum()
    }
}

/// One face's part of `μ_e(p)` ([`CandidateEdges::face_terms`]).
#[derive(Debug, Clone, Copy)]
pub struct FaceTerm {
    /// Unnormalised normal.
    pub normal: DVec3,
    /// A vertex of the face.
    pub point: DVec3,
    /// The term behind the face (`[0]`) and in front of it (`[1]`).
    pub weights: [i32; 2],
}

/// A face's term of `μ_e(p)`, with `front` whether `p` is in front of it.
#[inline(always)]
fn face_weight(f: &EdgeFace, front: bool) -> i32 {
    let h = match (f.closed, front) {
        (true, true) => 1,
        (true, false) => 0,
        (false, true) => 1,
        (false, false) => -1,
    };
    h * i32::from(f.direction)
}

/// The side of the plane `(p, v0, v1)` the point `o` is on: the sign of
/// `det(v0 − p, v1 − p, o − p)`, 0 in the plane.
#[inline]
pub fn side_of(p: DVec3, v0: DVec3, v1: DVec3, o: DVec3) -> i32 {
    let d = (v0 - p).cross(v1 - p).dot(o - p);
    if d > 0.0 {
        1
    } else if d < 0.0 {
        -1
    } else {
        0
    }
}
