//! Which faces see a light, and which edges can be silhouettes.

use super::EdgeAdjacency;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Faces or edges per parallel task (each a few dot products).
const PAR_CHUNK: usize = 4096;

/// Whether each face of `adj` faces the point `light`: `n · (L − a) > 0`
/// with the normal from the winding, in f64 so that the sign is right for
/// points close to a face's plane. A point exactly in the plane is not in
/// front.
pub fn faces_point(adj: &EdgeAdjacency, light: Vec3) -> Vec<bool> {
    let l = light.as_dvec3();
    adj.face_vertices
        .par_iter()
        .with_min_len(PAR_CHUNK)
        .map(|f| {
            let [a, b, c] = f.map(|i| adj.positions[i as usize].as_dvec3());
            (b - a).cross(c - a).dot(l - a) > 0.0
        })
        .collect()
}

/// How a face's plane splits a convex light: +1 all in front, -1 all
/// behind, 0 straddling (or touching).
fn split(normal: DVec3, a: DVec3, light_points: &[DVec3]) -> i8 {
    let mut front = false;
    let mut back = false;
    for p in light_points {
        let d = normal.dot(*p - a);
        front |= d > 0.0;
        back |= d <= 0.0;
    }
    match (front, back) {
        (true, false) => 1,
        (false, true) => -1,
        _ => 0,
    }
}

/// Potential silhouette edges with respect to a whole convex light given
/// by its corner points (thesis §4.1.4): an edge qualifies when some part
/// of the light is in front of one adjacent face and behind another, i.e.
/// unless every adjacent face sees the whole light from the same side.
/// Boundary edges (one face) always qualify.
pub fn area_silhouettes(adj: &EdgeAdjacency, light_points: &[Vec3]) -> Vec<bool> {
    let lp: Vec<DVec3> = light_points.iter().map(|p| p.as_dvec3()).collect();
    let class: Vec<i8> = adj
        .face_vertices
        .par_iter()
        .with_min_len(PAR_CHUNK)
        .map(|f| {
            let [a, b, c] = f.map(|i| adj.positions[i as usize].as_dvec3());
            split((b - a).cross(c - a), a, &lp)
        })
        .collect();
    silhouettes_from_classes(adj, &class)
}

/// [`area_silhouettes`] for a sphere light: a face's plane splits the
/// sphere when the centre is closer to it than the radius.
pub fn sphere_silhouettes(adj: &EdgeAdjacency, center: DVec3, radius: f64) -> Vec<bool> {
    let class: Vec<i8> = adj
        .face_vertices
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| adj.positions[i as usize].as_dvec3());
            let n = (b - a).cross(c - a);
            let len = n.length();
            if !(len > 0.0) {
                return 0;
            }
            let d = n.dot(center - a) / len;
            if d > radius {
                1
            } else if d < -radius {
                -1
            } else {
                0
            }
        })
        .collect();
    silhouettes_from_classes(adj, &class)
}

/// Edges whose adjacent faces do not all see the whole light from the same
/// side, given each face's class (+1 / −1: the light wholly in front /
/// behind, 0: split). Boundary edges always qualify.
fn silhouettes_from_classes(adj: &EdgeAdjacency, class: &[i8]) -> Vec<bool> {
    (0..adj.edges.len())
        .into_par_iter()
        .with_min_len(PAR_CHUNK)
        .map(|e| {
            let uses = adj.uses(e);
            if uses.len() < 2 {
                return true;
            }
            let first = class[uses[0].slot as usize];
            first == 0 || uses.iter().any(|u| class[u.slot as usize] != first)
        })
        .collect()
}
